//! The four Losasso–Hoppe region constraints, for random viewers, n, level
//! counts and finite map sizes, viewers at and beyond the map edges included.

use proptest::prelude::*;
use terraclip::clipmap::region::{self, block_size, map_bounds, max_levels, Rect, RegionParams};

fn case() -> impl Strategy<Value = (i64, usize, usize, usize, [f64; 2])> {
    (
        prop::sample::select(vec![15i64, 31, 63, 127]),
        20usize..3000,
        20usize..3000,
    )
        .prop_flat_map(|(n, w, h)| {
            let max = max_levels(w, h, n);
            (
                Just(n),
                Just(w),
                Just(h),
                1..=max,
                [-(w as f64)..2.0 * w as f64, -(h as f64)..2.0 * h as f64],
            )
        })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(3000))]

    #[test]
    fn constraints_hold((n, w, h, levels, viewer) in case(), on_edge in 0u8..4) {
        // Sometimes put the viewer exactly on a map edge or corner.
        let viewer = match on_edge {
            0 => [0.0, viewer[1]],
            1 => [(w - 1) as f64, (h - 1) as f64],
            _ => viewer,
        };
        let map = map_bounds(w, h, levels);
        let p = RegionParams { n, levels, map: Some(map) };
        let r = region::compute(&p, viewer);
        let m = block_size(n);
        for l in 0..levels {
            let g = 1i64 << l;
            let lv = &r[l];
            // No level collapses below the maximum level count.
            let a = lv.active.unwrap_or_else(|| panic!("level {l} of {levels} inactive"));
            prop_assert!(!a.is_degenerate());
            prop_assert_eq!(lv.clip.width(), (n - 1) * g);
            // Active ⊆ clip, and inside the usable map.
            prop_assert!(lv.clip.contains(&a), "active {a:?} ⊄ clip {:?}", lv.clip);
            prop_assert!(map.contains(&a));
            if l + 1 < levels {
                let gc = g * 2;
                let coarse = &r[l + 1];
                // Clip regions nest with a margin of at least m − 1 coarse texels.
                let margin = Rect::new(
                    coarse.clip.x0 + (m - 1) * gc,
                    coarse.clip.y0 + (m - 1) * gc,
                    coarse.clip.x1 - (m - 1) * gc,
                    coarse.clip.y1 - (m - 1) * gc,
                );
                prop_assert!(margin.contains(&lv.clip), "clip {l} {:?} not inside {margin:?}", lv.clip);
                // Active perimeters lie on even vertices of the coarser level.
                for c in [a.x0, a.y0, a.x1, a.y1] {
                    prop_assert_eq!(c.rem_euclid(gc), 0, "level {} side {} not on coarse even vertex", l, c);
                }
                // Active(l) inside active(l+1) eroded by 2 coarse texels
                // (except on map edges, which have no coarser neighbour).
                // Written out here, not through `erode_within`, which the
                // code under test uses.
                let ca = coarse.active.unwrap();
                let d = 2 * gc;
                let eroded = Rect::new(
                    if ca.x0 == map.x0 { ca.x0 } else { ca.x0 + d },
                    if ca.y0 == map.y0 { ca.y0 } else { ca.y0 + d },
                    if ca.x1 == map.x1 { ca.x1 } else { ca.x1 - d },
                    if ca.y1 == map.y1 { ca.y1 } else { ca.y1 - d },
                );
                prop_assert!(eroded.contains(&a), "active {l} {a:?} ⊄ eroded {eroded:?}");
                // A side is only exempt when it really is on the map edge.
                let sides = a.sides_on(&map);
                prop_assert_eq!(sides, lv.map_sides);
            }
        }
    }

    #[test]
    fn unbounded_layout_centres_every_window_within_one_texel(n in prop::sample::select(vec![15i64, 31, 63, 255]), levels in 1usize..12, v in [-1e7f64..1e7, -1e7f64..1e7]) {
        let r = region::compute(&RegionParams { n, levels, map: None }, v);
        for (l, lv) in r.iter().enumerate() {
            let g = (1i64 << l) as f64;
            let cx = (lv.clip.x0 + lv.clip.x1) as f64 / 2.0;
            let cy = (lv.clip.y0 + lv.clip.y1) as f64 / 2.0;
            prop_assert!((cx - v[0]).abs() <= g && (cy - v[1]).abs() <= g, "level {l}");
            prop_assert_eq!(lv.active, Some(lv.clip));
        }
    }
}

#[test]
fn too_many_levels_is_an_error() {
    let n = 31;
    let (w, h) = (403, 344);
    let max = max_levels(w, h, n);
    let map =
        terraclip::terrain::Heightmap::from_values(w, h, vec![0.0; w * h], None, [1.0, 1.0], "t")
            .unwrap();
    let p = std::sync::Arc::new(terraclip::pyramid::Pyramid::build(
        &map,
        terraclip::pyramid::Filter::Point,
        max + 1,
    ));
    let cfg = |levels| terraclip::clipmap::ClipmapConfig {
        n,
        levels: Some(levels),
        ..Default::default()
    };
    assert!(terraclip::clipmap::Clipmap::new(p.clone(), cfg(max)).is_ok());
    let e = terraclip::clipmap::Clipmap::new(p, cfg(max + 1))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("lod.levels") && e.contains(&format!("1..={max}")),
        "{e}"
    );
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(1000))]

    /// Updating only the levels whose origin moved gives `compute`'s regions
    /// exactly: over walks of small steps and jumps, with and without a map,
    /// and with more levels than the map allows, so that some are inactive.
    #[test]
    fn incremental_regions_equal_computed(
        (n, w, h, levels, start) in case(),
        extra in 0usize..3,
        bounded in any::<bool>(),
        steps in prop::collection::vec(prop_oneof![
            6 => [-3.0f64..3.0, -3.0f64..3.0],
            1 => [-3000.0f64..3000.0, -3000.0f64..3000.0],
        ], 1..40),
    ) {
        let levels = levels + extra;
        let map = bounded.then(|| map_bounds(w, h, levels));
        let p = RegionParams { n, levels, map };
        let mut v = start;
        let mut kept = region::compute(&p, v);
        for (i, d) in steps.iter().enumerate() {
            v = [v[0] + d[0], v[1] + d[1]];
            region::update_into(&p, v, &mut kept);
            let want = region::compute(&p, v);
            prop_assert_eq!(&kept, &want, "step {} to {:?}", i, v);
        }
    }
}
