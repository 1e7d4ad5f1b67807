//! Pyramid filters, measured on a narrow peak and a pit.

mod common;

use terraclip::pyramid::{Filter, Pyramid};
use terraclip::terrain::Heightmap;

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

mod lazy {
    use proptest::prelude::*;
    use terraclip::pyramid::{Filter, LazyBase, Pyramid, TILE};
    use terraclip::terrain::procedural::Procedural;

    fn bits(v: &[f32]) -> Vec<u32> {
        v.iter().map(|x| x.to_bits()).collect()
    }

    /// Every sample a lazy pyramid has built equals the eager pyramid's,
    /// bit for bit, wherever it was built from and in whatever order; once
    /// the windows cover everything, the pyramid is whole and equal to the
    /// eager one, bounds included.
    fn lazy_equals_eager(w: usize, h: usize, filter: Filter, budget: u64, windows: &[[i64; 4]]) {
        let p = Procedural {
            wavelength: 37.0,
            octaves: 5,
            ..Procedural::new(99, w, h)
        };
        let eager = Pyramid::from_heightmap(p.generate().unwrap(), filter, 6);
        let mut lazy = Pyramid::lazy(LazyBase::Procedural(p), filter, 6, budget).unwrap();
        assert_eq!(lazy.levels.len(), eager.levels.len());
        // Each call asks for one window on every level, as a clipmap would.
        for win in windows {
            let per_level: Vec<[i64; 4]> = (0..lazy.levels.len())
                .map(|l| win.map(|v| v >> l))
                .collect();
            let ready = lazy.build_around(&per_level).ready.end;
            assert!(ready >= 1, "level 0 is always built");
            for (l, w) in per_level.iter().enumerate().take(ready) {
                crate::common::same_window(&lazy.levels[l], &eager.levels[l], l, *w);
                assert_eq!(
                    lazy.range_in(l, *w),
                    eager.range_in(l, *w),
                    "level {l} bounds of {w:?}"
                );
            }
        }
        let everything = [0, 0, w as i64, h as i64];
        let per_level: Vec<[i64; 4]> = (0..lazy.levels.len()).map(|_| everything).collect();
        while !lazy.is_complete() {
            lazy.build_around(&per_level);
        }
        for (a, b) in lazy.levels.iter().zip(&eager.levels) {
            assert_eq!(bits(&a.data), bits(&b.data));
            assert_eq!(a.nodata, b.nodata);
            assert_eq!((a.min, a.max), (b.min, b.max));
        }
    }

    #[test]
    fn a_lazy_pyramid_grows_to_the_eager_one() {
        let windows = [[100, 80, 160, 140], [-30, -30, 20, 400], [300, 0, 333, 20]];
        lazy_equals_eager(333, 301, Filter::SincBlackman { taps: 11 }, 5_000, &windows);
        lazy_equals_eager(200, 129, Filter::Box, u64::MAX, &windows);
        lazy_equals_eager(129, 200, Filter::Point, 1, &windows);
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(24))]
        /// Random sizes, filters, budgets and windows.
        #[test]
        fn lazy_tiles_have_the_eager_bits(
            w in 40usize..300, h in 40usize..300, budget in 1u64..40_000,
            taps in prop::sample::select(vec![3usize, 11, 21]),
            windows in prop::collection::vec((-50i64..350, -50i64..350, 0i64..120, 0i64..120), 1..5),
        ) {
            let windows: Vec<[i64; 4]> =
                windows.iter().map(|&(x, y, a, b)| [x, y, x + a, y + b]).collect();
            lazy_equals_eager(w, h, Filter::SincBlackman { taps }, budget, &windows);
        }
    }

    /// Only what a frame needs is built: a 128-sample window on each of 3
    /// levels around one point of a 4097² map (the coarsest covers 512²
    /// base texels) builds under 10 % of the eager pyramid's samples.
    #[test]
    fn a_window_builds_only_the_tiles_under_it() {
        let p = Procedural::new(5, 4097, 4097);
        let mut lazy =
            Pyramid::lazy(LazyBase::Procedural(p), Filter::default(), 3, u64::MAX).unwrap();
        let windows: Vec<[i64; 4]> = (0..3)
            .map(|l| [2000 >> l, 2000 >> l, (2000 >> l) + 127, (2000 >> l) + 127])
            .collect();
        let b = lazy.build_around(&windows);
        let (ready, samples) = (b.ready.end, b.samples);
        let s = lazy.lazy_stats().unwrap();
        let eager: u64 = lazy
            .levels
            .iter()
            .map(|l| (l.width * l.height) as u64)
            .sum();
        println!("{s:?}: {samples} of {eager} samples");
        assert_eq!(ready, 3);
        assert_eq!(s.samples_built, samples);
        assert!(samples * 10 < eager, "{samples} of {eager}");
        assert!(!lazy.is_complete());
    }

    /// A budget too small for the coarse levels defers them and builds them
    /// over later calls, overrunning the budget past level 0 by less than
    /// one tile.
    #[test]
    fn a_small_budget_defers_coarse_levels() {
        let p = Procedural::new(5, 1025, 1025);
        let budget = 20_000;
        let mut lazy =
            Pyramid::lazy(LazyBase::Procedural(p), Filter::default(), 5, budget).unwrap();
        let windows: Vec<[i64; 4]> = (0..5).map(|l| [0, 0, 1024 >> l, 1024 >> l]).collect();
        let first = lazy.build_around(&windows);
        assert!(first.ready.end < 5, "{first:?}");
        let level0 = 1025u64 * 1025;
        let tile = (TILE * TILE) as u64;
        assert!(first.samples < level0 + budget + tile, "{first:?}");
        let mut calls = 1;
        loop {
            let b = lazy.build_around(&windows);
            let (ready, samples) = (b.ready.end, b.samples);
            assert!(samples > 0 && samples < budget + tile, "{samples}");
            calls += 1;
            if ready == 5 {
                break;
            }
            assert!(calls < 1000, "progress stalled at {ready} levels");
        }
        assert!(lazy.is_complete());
        println!("whole after {calls} calls");
    }

    #[test]
    fn bad_lazy_settings_are_refused() {
        let p = Procedural::new(5, 65, 65);
        let e =
            Pyramid::lazy(LazyBase::Procedural(p.clone()), Filter::default(), 3, 0).unwrap_err();
        assert!(e.contains("budget"), "{e}");
        let bad = Procedural { octaves: 0, ..p };
        let e = Pyramid::lazy(LazyBase::Procedural(bad), Filter::default(), 3, 10).unwrap_err();
        assert!(e.contains("octaves"), "{e}");
    }
}
