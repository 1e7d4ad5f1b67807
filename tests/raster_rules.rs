//! The rasterisation rules (docs/reference/raster-rules.md), pinned by hand-computed cases
//! and property tests: exact tiling, shared edges, snap ties, and identical
//! bits for any thread count and for the scalar and 8-lane paths.

use proptest::prelude::*;
use terraclip::raster::setup::Viewport;
use terraclip::raster::{fate, rasterise, Fate, Mesh, Options, Path, Raster, Target, NONE};

/// Window position (pixels, y down) to clip space with w = 1, for a target
/// whose half sizes are powers of two so the viewport FMA is exact.
fn to_clip(x: f32, y: f32, z: f32, w: u32, h: u32) -> [f32; 4] {
    let (hw, hh) = (w as f32 / 2.0, h as f32 / 2.0);
    [(x - hw) / hw, (hh - y) / hh, z, 1.0]
}

fn draw(tris: &[[(f32, f32, f32); 3]], w: u32, h: u32, path: Path) -> Raster {
    let clip: Vec<[f32; 4]> = tris
        .iter()
        .flatten()
        .map(|&(x, y, z)| to_clip(x, y, z, w, h))
        .collect();
    let idx: Vec<[u32; 3]> = (0..tris.len() as u32)
        .map(|i| [3 * i, 3 * i + 1, 3 * i + 2])
        .collect();
    let flat = vec![0; tris.len()];
    let mesh = Mesh {
        clip: &clip,
        attrs: &[],
        linear: &[],
        triangles: &idx,
        flat: &flat,
    };
    rasterise(&mesh, w, h, &Options { path })
}

/// How many of `tris` cover each pixel, drawing them one at a time.
fn coverage(tris: &[[(f32, f32, f32); 3]], w: u32, h: u32) -> Vec<u32> {
    let mut count = vec![0; (w * h) as usize];
    for t in tris {
        let r = draw(std::slice::from_ref(t), w, h, Path::Scalar);
        for (c, p) in count.iter_mut().zip(&r.prim) {
            *c += u32::from(*p != NONE);
        }
    }
    count
}

#[test]
fn top_left_rule_gives_the_diagonal_to_the_upper_triangle() {
    // A 4×4-pixel square whose edges and diagonal run through pixel centres.
    let (a, b, c, d) = ((0.5, 0.5), (4.5, 0.5), (4.5, 4.5), (0.5, 4.5));
    let z = |p: (f32, f32)| (p.0, p.1, 0.5);
    let upper = [z(a), z(b), z(c)];
    let lower = [z(a), z(c), z(d)];
    let ru = draw(&[upper], 16, 16, Path::Scalar);
    let rl = draw(&[lower], 16, 16, Path::Scalar);
    let count = |r: &Raster| r.prim.iter().filter(|&&p| p != NONE).count();
    // Left and top edges are in, right and bottom out; the down-right
    // diagonal's inward normal points right for the upper triangle.
    assert_eq!(count(&ru), 4 + 3 + 2 + 1);
    assert_eq!(count(&rl), 3 + 2 + 1);
    for k in 0..4 {
        assert_ne!(ru.prim[k * 16 + k], NONE, "diagonal pixel {k}");
        assert_eq!(rl.prim[k * 16 + k], NONE, "diagonal pixel {k}");
    }
    assert_eq!(ru.prim[4], NONE, "right edge excluded");
    assert_eq!(rl.prim[4 * 16], NONE, "bottom edge excluded");
}

#[test]
fn snap_ties_round_to_even() {
    // Left edge at (x − 0.5)·256 = 512.5 snaps to 512, exactly on the centre
    // of pixel 2, and the left edge owns it. Rounding half away from zero
    // would give 513 and miss it. At 513.5 it snaps to 514 and misses.
    for (frac, covered) in [(0.5f32, true), (1.5, false)] {
        let x = 2.5 + frac / 256.0;
        let quad = [
            [(x, 0.0, 0.5), (8.0, 0.0, 0.5), (8.0, 8.0, 0.5)],
            [(x, 0.0, 0.5), (8.0, 8.0, 0.5), (x, 8.0, 0.5)],
        ];
        let r = draw(&quad, 16, 16, Path::Scalar);
        assert_eq!(r.prim[3 * 16 + 2] != NONE, covered, "frac {frac}");
        assert_ne!(r.prim[3 * 16 + 3], NONE);
    }
}

#[test]
fn depth_is_the_fma_plane_tested_less() {
    // Two coplanar copies: the first drawn keeps every pixel (LESS, not
    // LEQUAL) on every path, and the stored depth is the plane value at the
    // centre.
    let t = [(1.0, 1.0, 0.25), (9.0, 1.0, 0.75), (1.0, 9.0, 0.5)];
    for path in [Path::Scalar, Path::Simd, Path::Portable] {
        let r = draw(&[t, t], 16, 16, path);
        let first = r.prim.iter().filter(|&&p| p == 0).count();
        assert_eq!(first, 28, "{path:?}");
        assert!(r.prim.iter().all(|&p| p == NONE || p == 0), "{path:?}");
    }
    let r = draw(&[t, t], 16, 16, Path::Scalar);
    let i = 2 * 16 + 3;
    let plane = r.tris[0].z;
    assert_eq!(
        r.depth[i],
        plane.dady.mul_add(2.0, plane.dadx.mul_add(3.0, plane.a00))
    );
    // dz/dx = 0.5/8, dz/dy = 0.25/8, centre (3.5, 2.5).
    assert!((r.depth[i] - (0.25 + 2.5 * 0.0625 + 1.5 * 0.03125)).abs() < 1e-6);
}

/// A jittered grid mesh tiling the rectangle [x0, x1] × [y0, y1].
fn tiling(
    x0: f32,
    y0: f32,
    cells: (usize, usize),
    cell: f32,
    jitter: &[(f32, f32)],
    diag: &[bool],
) -> Vec<[(f32, f32, f32); 3]> {
    let (gx, gy) = cells;
    let at = |i: usize, j: usize| {
        let mut x = x0 + i as f32 * cell;
        let mut y = y0 + j as f32 * cell;
        let (jx, jy) = jitter[j * (gx + 1) + i];
        // Boundary vertices slide only along the boundary.
        if i > 0 && i < gx {
            x += jx;
        }
        if j > 0 && j < gy {
            y += jy;
        }
        (x, y, 0.5)
    };
    let mut tris = vec![];
    for j in 0..gy {
        for i in 0..gx {
            let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
            if diag[j * gx + i] {
                tris.push([a, b, c]);
                tris.push([a, c, d]);
            } else {
                tris.push([a, b, d]);
                tris.push([b, c, d]);
            }
        }
    }
    tris
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(96))]

    /// Every pixel centre inside the rectangle is covered exactly once, none
    /// outside, with the left/top sides in and right/bottom out.
    #[test]
    fn a_tiling_mesh_covers_each_centre_once(
        x0q in prop_oneof![(0u32..4).prop_map(|k| k * 256), 0u32..1024],
        y0q in prop_oneof![(0u32..4).prop_map(|k| k * 256), 0u32..1024],
        gx in 1usize..5, gy in 1usize..5,
        cellq in 6u32..10,
        jit in prop::collection::vec((-1.0f32..1.0, -1.0f32..1.0), 36),
        diag in prop::collection::vec(any::<bool>(), 25),
    ) {
        // Coordinates on a 1/512 grid, so snap ties (·5 after ×256) occur,
        // and often exactly on pixel centres, where the top-left rule decides.
        let q = |v: u32| v as f32 / 512.0;
        let (x0, y0) = (4.0 + q(x0q), 4.0 + q(y0q));
        let cell = cellq as f32;
        let jitter: Vec<(f32, f32)> = jit
            .iter()
            .map(|&(a, b)| ((a * 0.2 * cell * 512.0).round() / 512.0, (b * 0.2 * cell * 512.0).round() / 512.0))
            .collect();
        let tris = tiling(x0, y0, (gx, gy), cell, &jitter, &diag);
        let (w, h) = (64, 64);
        let count = coverage(&tris, w, h);
        let snap = |v: f32| ((v - 0.5) * 256.0).round_ties_even() as i64;
        let (sx0, sy0) = (snap(x0), snap(y0));
        let (sx1, sy1) = (snap(x0 + gx as f32 * cell), snap(y0 + gy as f32 * cell));
        for py in 0..h as i64 {
            for px in 0..w as i64 {
                let (cx, cy) = (256 * px, 256 * py);
                let want = u32::from(sx0 <= cx && cx < sx1 && sy0 <= cy && cy < sy1);
                prop_assert_eq!(count[(py * w as i64 + px) as usize], want, "pixel ({}, {})", px, py);
            }
        }
    }

    /// Random overlapping triangles, some crossing the near plane and the
    /// sides, some with w < 0: the same bits for 1, 2 and 8 threads and for
    /// both paths.
    #[test]
    fn thread_count_and_path_do_not_change_bits(
        verts in prop::collection::vec(
            (-1.6f32..1.6, -1.6f32..1.6, -0.3f32..1.2, -0.2f32..2.0), 3..90),
        w in 1u32..200, h in 1u32..150,
    ) {
        let n = verts.len() / 3 * 3;
        let clip: Vec<[f32; 4]> = verts[..n].iter().map(|&(x, y, z, w)| [x, y, z, w]).collect();
        let attrs: Vec<f32> = clip.iter().flat_map(|c| [c[0] * 0.5 + 0.5, c[1]]).collect();
        let tris: Vec<[u32; 3]> = (0..n as u32 / 3).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect();
        let flat = vec![0; tris.len()];
        let mesh = Mesh { clip: &clip, attrs: &attrs, linear: &[false, true], triangles: &tris, flat: &flat };
        let run = |threads: usize, path: Path| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| rasterise(&mesh, w, h, &Options { path }))
        };
        let reference = run(1, Path::Scalar);
        let bits = |r: &Raster| {
            let mut v: Vec<u32> = r.depth.iter().map(|d| d.to_bits()).collect();
            v.extend(&r.prim);
            let mut out = [0.0f32; 2];
            for (i, &p) in r.prim.iter().enumerate() {
                if p != NONE {
                    r.interpolate(p, i as u32 % w, i as u32 / w, &mut out);
                    v.extend(out.map(f32::to_bits));
                }
            }
            v
        };
        let want = bits(&reference);
        for (threads, path) in [(2, Path::Scalar), (8, Path::Scalar), (1, Path::Simd), (2, Path::Simd), (8, Path::Simd)] {
            prop_assert!(bits(&run(threads, path)) == want, "{} threads, {:?}", threads, path);
        }
    }

    /// The same triangles drawn in consecutive batches, with the target
    /// compacted after any of them, leave every pixel's depth, varyings
    /// and flat value as one draw of them all: what lets brute force of a
    /// large map be drawn a batch at a time. Compaction keeps at most one
    /// triangle per pixel.
    #[test]
    fn batches_and_compaction_do_not_change_bits(
        verts in prop::collection::vec(
            (-1.6f32..1.6, -1.6f32..1.6, -0.3f32..1.2, -0.2f32..2.0), 3..150),
        cuts in prop::collection::vec((0usize..50, any::<bool>()), 0..6),
        w in 1u32..140, h in 1u32..100,
        simd in any::<bool>(),
    ) {
        let n = verts.len() / 3 * 3;
        let clip: Vec<[f32; 4]> = verts[..n].iter().map(|&(x, y, z, w)| [x, y, z, w]).collect();
        let attrs: Vec<f32> = clip.iter().flat_map(|c| [c[0] * 0.5 + 0.5, c[1]]).collect();
        let count = n as u32 / 3;
        let tris: Vec<[u32; 3]> = (0..count).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect();
        let flat: Vec<u32> = (0..count).collect();
        let linear = [false, true];
        let opts = Options { path: if simd { Path::Simd } else { Path::Scalar } };
        let whole = rasterise(
            &Mesh { clip: &clip, attrs: &attrs, linear: &linear, triangles: &tris, flat: &flat },
            w, h, &opts,
        );
        let mut bounds: Vec<(usize, bool)> = cuts.iter().map(|&(c, k)| (c.min(tris.len()), k)).collect();
        bounds.sort();
        bounds.push((tris.len(), false));
        let mut target = Target::new(w, h, &linear, opts);
        let mut from = 0;
        for (to, compact) in bounds {
            target.draw(&Mesh {
                clip: &clip,
                attrs: &attrs,
                linear: &linear,
                triangles: &tris[from..to],
                flat: &flat[from..to],
            });
            if compact {
                target.compact();
                prop_assert!(target.triangles_held() <= (w * h) as usize);
            }
            from = to;
        }
        let batched = target.finish();
        // Triangle ids differ after compaction; what a pixel shows must not.
        let shown = |r: &Raster| {
            let mut v: Vec<u32> = r.depth.iter().map(|d| d.to_bits()).collect();
            let mut out = [0.0f32; 2];
            for (i, &p) in r.prim.iter().enumerate() {
                if p == NONE {
                    v.push(NONE);
                    continue;
                }
                r.interpolate(p, i as u32 % w, i as u32 / w, &mut out);
                v.extend(out.map(f32::to_bits));
                v.push(r.tris[p as usize].flat);
            }
            v
        };
        prop_assert!(shown(&batched) == shown(&whole));
        prop_assert_eq!(&batched.stats, &whole.stats);
    }
}

/// Rasterises the one triangle at `c` and checks that [`fate`] said what
/// the rasteriser did: `Nothing` is set up to nothing and counted
/// nowhere, `Rejected` is counted as rejected, and an unclipped finite
/// triangle it would `Draw` is set up.
fn fate_agrees(c: [[f32; 4]; 3], w: u32, h: u32) -> Fate {
    let mesh = Mesh {
        clip: &c,
        attrs: &[],
        linear: &[],
        triangles: &[[0, 1, 2]],
        flat: &[0],
    };
    let s = rasterise(&mesh, w, h, &Options { path: Path::Scalar }).stats;
    let f = fate(c, &Viewport::new(w, h));
    let ok = match f {
        Fate::Nothing => s.setup == 0 && s.rejected == 0 && s.clipped == 0,
        Fate::Rejected => s.rejected == 1 && s.setup == 0,
        Fate::Draw => s.clipped == 1 || s.setup == 1 || s.non_finite_vertices > 0,
    };
    assert!(ok, "{f:?} for {c:?} in {w}x{h}: {s:?}");
    f
}

/// Triangles from a pixel's size down to far below it, in and around the
/// clip volume, some non-finite: every fate occurs, each as the
/// rasteriser decides.
#[test]
fn fate_is_what_the_rasteriser_does() {
    let mut seed = 0x9E37_79B9_7F4A_7C15u64;
    let mut next = move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 40) as f32 / (1u64 << 24) as f32
    };
    let mut seen = [0usize; 3];
    for i in 0..6000 {
        let (w, h) = (1 + (next() * 150.0) as u32, 1 + (next() * 100.0) as u32);
        let scale = [1.0, 0.2, 0.01, 0.001][i % 4];
        let v = |next: &mut dyn FnMut() -> f32| {
            [
                next() * 2.8 - 1.4,
                next() * 2.8 - 1.4,
                next() * 1.5 - 0.3,
                next() * 2.2 - 0.2,
            ]
        };
        let c0 = v(&mut next);
        let mut c = [c0, v(&mut next), v(&mut next)];
        for p in &mut c[1..] {
            *p = std::array::from_fn(|k| c0[k] + (p[k] - c0[k]) * scale);
        }
        if i % 97 == 0 {
            c[1][i % 4] = f32::NAN;
        }
        seen[fate_agrees(c, w, h) as usize] += 1;
    }
    assert!(
        seen.iter().all(|&n| n > 300),
        "Draw, Rejected, Nothing: {seen:?}"
    );
}
