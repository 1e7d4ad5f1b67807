//! Pyramid filters, measured on a narrow peak and a pit.

use terraclip::heightmap::Heightmap;
use terraclip::pyramid::{Filter, Pyramid};

fn bump(amplitude: f64, sigma: f64) -> Heightmap {
    let n = 129;
    let v = (0..n * n)
        .map(|i| {
            let (x, y) = ((i % n) as f64 - 64.0, (i / n) as f64 - 64.0);
            (amplitude * (-(x * x + y * y) / (2.0 * sigma * sigma)).exp()) as f32
        })
        .collect();
    Heightmap::from_values(n, n, v, None, [1.0, 1.0], "bump").unwrap()
}

/// Height kept at the feature's centre, three levels down (spacing 8).
fn kept(map: &Heightmap, f: Filter) -> f32 {
    let p = Pyramid::build(map, f, 4);
    let l = &p.levels[3];
    l.data[8 * l.width + 8]
}

#[test]
fn sinc_blackman_keeps_peaks_better_than_box() {
    for (amp, sigma) in [(100.0, 4.0), (100.0, 6.0), (100.0, 10.0), (-100.0, 6.0)] {
        let map = bump(amp, sigma);
        let b = kept(&map, Filter::Box);
        let s = kept(&map, Filter::SincBlackman { taps: 11 });
        let p = kept(&map, Filter::Point);
        println!(
            "feature {amp} m, σ = {sigma}: point {p:.2}, box {b:.2}, sinc-blackman {s:.2} (true {amp})"
        );
        assert_eq!(p, amp as f32, "point sampling keeps the centre sample");
        let (eb, es) = ((b as f64 - amp).abs(), (s as f64 - amp).abs());
        assert!(es < eb, "sinc-blackman error {es} must beat box error {eb}");
        assert!(es < 0.9 * eb, "and by a clear margin: {es} vs {eb}");
    }
}

#[test]
fn nodata_takes_no_part_in_filtering() {
    let n = 33;
    let mut v = vec![10.0f32; n * n];
    for (i, x) in v.iter_mut().enumerate() {
        if i % 2 == 1 {
            *x = f32::NAN;
        }
    }
    let map = Heightmap::from_values(n, n, v, None, [1.0, 1.0], "t").unwrap();
    let p = Pyramid::build(&map, Filter::SincBlackman { taps: 11 }, 3);
    for l in &p.levels {
        assert!(
            l.data.iter().all(|&x| x == 10.0),
            "no-data must not pull heights"
        );
    }
}

#[test]
fn build_is_identical_for_any_thread_count() {
    let map = bump(300.0, 5.0);
    let run = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| Pyramid::build(&map, Filter::SincBlackman { taps: 11 }, 5))
    };
    let (a, b) = (run(1), run(4));
    for (x, y) in a.levels.iter().zip(&b.levels) {
        assert_eq!(x.data, y.data);
    }
}
