use super::*;

fn level(w: usize, h: usize, f: impl Fn(usize, usize) -> f32) -> PyramidLevel {
    let data = (0..w * h).map(|i| f(i % w, i / w)).collect();
    PyramidLevel::from_parts(w, h, data, vec![false; w * h])
}

/// The table is the seed's alone, and its values have the moments of a
/// standard Gaussian: over 4096 values the sample mean's standard error is
/// 1/64 and the variance's √(2/4096) ≈ 0.022, so ±0.08 and ±0.11 are five
/// standard errors.
#[test]
fn the_noise_table_is_the_seeds_and_gaussian() {
    let t = NoiseTable::new(7);
    assert_eq!(t, NoiseTable::new(7));
    assert_ne!(t, NoiseTable::new(8));
    let v: Vec<f64> = t.values().iter().map(|&x| x as f64).collect();
    assert_eq!(v.len(), TABLE * TABLE);
    let n = v.len() as f64;
    let mean = v.iter().sum::<f64>() / n;
    let var = v.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / n;
    assert!(mean.abs() < 0.08, "mean {mean}");
    assert!((var - 1.0).abs() < 0.11, "variance {var}");
    assert!(v.iter().all(|x| x.abs() <= 6.0));
    // Stretched coordinates: 64 texels apart is not the same value along a
    // whole row (the table's period does not show).
    let same = (0..1000)
        .filter(|&x| t.at(1, x, 5) == t.at(1, x + 64, 5))
        .count();
    assert!(same < 1000, "{same}");
    // The stretch is 98/97 rounded down, in integers: 97 lands on 98, -1
    // on -2; offsets 17 k and 51 k; wrapped to the table.
    assert_eq!(NoiseTable::cell(0, 97, 0), [98 % 64, 0]);
    assert_eq!(NoiseTable::cell(0, -1, 96), [62, 96 % 64]);
    assert_eq!(NoiseTable::cell(1, 0, 0), [17, 51]);
}

/// The coarse samples come through bit for bit, and the four-point scheme
/// reproduces a plane exactly (integer heights: every step is exact).
#[test]
fn subdivision_keeps_the_coarse_samples_and_reproduces_a_plane() {
    let c = level(9, 7, |x, y| (3 * x + 5 * y) as f32);
    let (up, nd) = subdivide(&c);
    let w = 17;
    assert_eq!(up.len(), w * 13);
    assert!(nd.iter().all(|&b| !b));
    for y in 0..13 {
        for x in 0..w {
            // Interior only: clamping bends the plane at the edges.
            if (2..w - 3).contains(&x) && (2..13 - 3).contains(&y) {
                let want = 1.5 * x as f32 + 2.5 * y as f32;
                assert_eq!(up[y * w + x], want, "({x}, {y})");
            }
            if x % 2 == 0 && y % 2 == 0 {
                assert_eq!(up[y * w + x], c.data[(y / 2) * 9 + x / 2]);
            }
        }
    }
}

/// No-data spreads to every sample whose stencil reads it, and no further.
#[test]
fn no_data_stays_no_data() {
    let mut c = level(9, 9, |x, y| (x * y) as f32);
    c.nodata[4 * 9 + 4] = true;
    let (_, nd) = subdivide(&c);
    let w = 17;
    assert!(nd[8 * w + 8], "the coarse sample itself");
    assert!(nd[8 * w + 9] && nd[9 * w + 9], "its neighbours");
    // Fine x = 11 lies between coarse 5 and 6, whose stencil reaches
    // coarse 4; x = 13 (between 6 and 7) reads 5 to 8 only.
    assert!(nd[8 * w + 11] && nd[11 * w + 8], "an outer tap");
    assert!(!nd[8 * w + 13] && !nd[13 * w + 8], "out of reach");
    assert!(!nd[0] && !nd[16 * w + 16], "far corners");
    let s = synthesize(&c, &NoiseTable::new(1), 1, 1.0);
    assert_eq!(s.nodata, nd);
}

/// A synthesised level's detail over the subdivision is the amplitude asked
/// for times the table's RMS (the ~12,500 texels draw the table's 4,096
/// values about three times each, nearly evenly, so their RMS is the
/// table's to about 1 %; 3 % is the bound), and the level is the same bits
/// on one thread and on two.
#[test]
fn synthesis_adds_noise_of_the_asked_amplitude_on_any_thread_count() {
    let c = level(65, 49, |x, y| ((x * 7 + y * 3) % 11) as f32 * 10.0);
    let t = NoiseTable::new(20041);
    let amp = amplitude(8.0, 1.0, 2);
    assert_eq!(amp, 2.0);
    let table_rms = (t.values().iter().map(|&v| v as f64 * v as f64).sum::<f64>()
        / (TABLE * TABLE) as f64)
        .sqrt();
    let s = synthesize(&c, &t, 1, amp);
    let (up, _) = subdivide(&c);
    let n = up.len() as f64;
    let rms = (s
        .data
        .iter()
        .zip(&up)
        .map(|(&a, &b)| (a as f64 - b as f64) * (a as f64 - b as f64))
        .sum::<f64>()
        / n)
        .sqrt();
    assert!((rms / (amp * table_rms) - 1.0).abs() < 0.03, "rms {rms}");
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let single = one.install(|| synthesize(&c, &t, 1, amp));
    assert!(single
        .data
        .iter()
        .zip(&s.data)
        .all(|(a, b)| a.to_bits() == b.to_bits()));
}

/// The map's own detail: zero for a map that is its coarser level's
/// subdivision, and the noise's amplitude for one synthesised from it.
#[test]
fn detail_is_measured_against_the_subdivision() {
    let c = level(33, 33, |x, y| (x * x + y) as f32);
    let (up, _) = subdivide(&c);
    let fine = level(65, 65, |x, y| up[y * 65 + x]);
    assert_eq!(detail_rms(&fine, &c), Some(0.0));
    let s = synthesize(&c, &NoiseTable::new(3), 1, 2.0);
    let d = detail_rms(&s, &c).unwrap();
    // The RMS of N ≈ 3,168 noise samples (the three phases of 65² that
    // are not the coarse level's) estimates the amplitude with a relative
    // standard error of about 1/√(2N) = 1.26 % for Gaussian-like noise;
    // 5 % is four of them.
    assert!((d / 2.0 - 1.0).abs() < 0.05, "{d}");
}

/// 2^x from square roots and doublings: exact at whole and half powers,
/// and between them 2^(q/1024) for x rounded to q/1024: within the ten
/// roundings of its square roots and products (16 ulps) of the library's
/// 2^(q/1024), and within half a step, 2^x·(2^(1/2048) − 1), of 2^x.
#[test]
fn pow2_is_exact_where_it_can_be() {
    assert_eq!(pow2(0.0), 1.0);
    assert_eq!(pow2(3.0), 8.0);
    assert_eq!(pow2(-2.0), 0.25);
    assert_eq!(pow2(0.5), std::f64::consts::SQRT_2);
    for x in [-0.3, 0.7, 1.9, -2.45, 0.001] {
        let q = (x * 1024.0f64).round();
        let on_grid = 2f64.powf(q / 1024.0);
        assert!(
            (pow2(x) - on_grid).abs() <= 16.0 * f64::EPSILON * on_grid,
            "{x}"
        );
        let half_step = 2f64.powf(x) * (2f64.powf(1.0 / 2048.0) - 1.0);
        assert!((pow2(x) - 2f64.powf(x)).abs() <= half_step, "{x}");
    }
}

/// The local gain is large where the map has detail and small where it
/// has none, and averages 1 in the mean square over the level.
#[test]
fn local_gain_follows_the_maps_detail() {
    let c = level(33, 33, |x, y| (x + y) as f32);
    // The left half of the fine level is its coarser level's subdivision
    // (no detail), the right half adds ±3 on alternate samples.
    let (up, _) = subdivide(&c);
    let fine = level(65, 65, |x, y| {
        let v = up[y * 65 + x];
        if x > 40 {
            v + if (x + y) % 2 == 0 { 3.0 } else { -3.0 }
        } else {
            v
        }
    });
    let g = detail_gain(&fine, &c, 2);
    assert_eq!(g[10 * 65 + 10], 0.0, "no detail, no noise");
    assert!(g[10 * 65 + 55] > 1.0, "{}", g[10 * 65 + 55]);
    // Exactly 1 but for rounding: the squared detail is 9 on columns
    // 41..=64 and 0 elsewhere, uniform down each column, so the 5-wide
    // boxes' means over the level sum to the same 24 columns of 9 as the
    // level's own mean (the boxes clipped at the edges lie wholly on one
    // side). The square roots and sums round at 1e-16 a sample.
    let ms = g.iter().map(|v| v * v).sum::<f64>() / g.len() as f64;
    assert!((ms - 1.0).abs() < 1e-12, "{ms}");
}

/// A level made window by window (tiles of odd and even sizes and
/// origins, as a pyramid decodes them) is the whole level's bits, no-data
/// included, with the coarse level holding only what each window's stencil
/// reads (the rest NaN, which would spread into any sample that read it).
#[test]
fn windows_give_the_whole_levels_bits() {
    let mut c = level(23, 19, |x, y| {
        ((x * 13 + y * 7) % 17) as f32 * 3.5 - (y as f32).sqrt()
    });
    c.nodata[9 * 23 + 4] = true;
    let t = NoiseTable::new(99);
    let whole = synthesize(&c, &t, 2, 1.25);
    let (w, h) = (whole.width, whole.height);
    for side in [7usize, 8, 16] {
        for ty in 0..h.div_ceil(side) {
            for tx in 0..w.div_ceil(side) {
                let (x0, y0) = (tx * side, ty * side);
                let rect = [x0, y0, side.min(w - x0), side.min(h - y0)];
                // Only the stencil's coarse samples are kept.
                let (i0, j0) = ((x0 / 2) as i64 - 1, (y0 / 2) as i64 - 1);
                let (i1, j1) = (
                    ((x0 + rect[2] - 1) / 2 + 2) as i64,
                    ((y0 + rect[3] - 1) / 2 + 2) as i64,
                );
                let mut part = c.clone();
                for j in 0..c.height as i64 {
                    for i in 0..c.width as i64 {
                        let inside = |v: i64, a: i64, b: i64, n: usize| {
                            (a.max(0)..=b.min(n as i64 - 1)).contains(&v)
                        };
                        if !(inside(i, i0, i1, c.width) && inside(j, j0, j1, c.height)) {
                            part.data[j as usize * c.width + i as usize] = f32::NAN;
                        }
                    }
                }
                let (v, nd) = synthesize_window(&part, &t, 2, 1.25, None, rect);
                for y in 0..rect[3] {
                    for x in 0..rect[2] {
                        let o = (y0 + y) * w + x0 + x;
                        assert_eq!(
                            v[y * rect[2] + x].to_bits(),
                            whole.data[o].to_bits(),
                            "side {side}, sample ({}, {})",
                            x0 + x,
                            y0 + y
                        );
                        assert_eq!(nd[y * rect[2] + x], whole.nodata[o]);
                    }
                }
            }
        }
    }
    // The detail measured in a window is the whole level's over it.
    let all = detail_rms(&whole, &c).unwrap();
    let win = detail_rms_window(&whole, &c, [0, 0, w, h]).unwrap();
    assert_eq!(all.to_bits(), win.to_bits());
}

/// The roughness between two steps' detail: 2^H = next / finest, to the
/// nearest 1/1024, clamped to 0..=2, and none without detail.
#[test]
fn roughness_is_the_ratio_of_the_steps_detail() {
    assert_eq!(roughness_between(1.0, 2.0), Some(1.0));
    assert_eq!(
        roughness_between(3.0, 3.0 * std::f64::consts::SQRT_2),
        Some(0.5)
    );
    // 0.7 is 716.8 / 1024: the nearest step is 717.
    assert_eq!(
        roughness_between(1.0, 1.624_504_792_712_471),
        Some(717.0 / 1024.0)
    );
    assert_eq!(
        roughness_between(2.0, 1.0),
        Some(0.0),
        "smoother when coarser: 0"
    );
    assert_eq!(roughness_between(1.0, 100.0), Some(2.0), "clamped");
    assert_eq!(roughness_between(0.0, 1.0), None);
    assert_eq!(roughness_between(1.0, f64::NAN), None);
    // Against log2, away from a rounding tie.
    for r in [1.1f64, 1.37, 2.9, 3.6] {
        let h = roughness_between(1.0, r).unwrap();
        assert!((h - r.log2()).abs() <= 0.5 / 1024.0 + 1e-12, "{r}: {h}");
    }
    assert!(check_roughness(-0.1).is_err() && check_roughness(f64::NAN).is_err());
    assert!(check_roughness(2.5).is_err() && check_roughness(0.0).is_ok());
}
