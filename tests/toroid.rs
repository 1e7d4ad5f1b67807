//! Toroidal updates: contents always equal a rebuild, exactly the exposed
//! texels are rewritten, in at most 4 non-overlapping, non-wrapping rects.

mod common;
use proptest::prelude::*;
use terraclip::clipmap::columns::{BLOCK, MARGIN, MIN_MARGIN};
use terraclip::clipmap::toroid::{update_rects, Toroid};
use terraclip::clipmap::Layout;

fn value(x: i64, y: i64) -> i64 {
    x.wrapping_mul(1_000_003) ^ y.wrapping_mul(7919)
}

fn exposed_area(old: Option<[i64; 2]>, new: [i64; 2], s: i64) -> i64 {
    match old {
        None => s * s,
        Some(o) => {
            let (dx, dy) = ((new[0] - o[0]).abs(), (new[1] - o[1]).abs());
            if dx >= s || dy >= s {
                s * s
            } else {
                s * s - (s - dx) * (s - dy)
            }
        }
    }
}

fn step() -> impl Strategy<Value = [i64; 2]> {
    prop_oneof![
        6 => [-3i64..=3, -3i64..=3],
        3 => [-40i64..=40, -40i64..=40],
        1 => [-1_000_000_000i64..=1_000_000_000, -1_000_000_000i64..=1_000_000_000],
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    #[test]
    fn random_walks_match_rebuild_and_rewrite_only_exposed(
        s in 1usize..40,
        start in [-100i64..100, -100i64..100],
        steps in prop::collection::vec(step(), 1..25),
    ) {
        let mut t = Toroid::<i64>::new(s);
        let mut origin = start;
        let mut old = None;
        for (i, d) in std::iter::once([0, 0]).chain(steps).enumerate() {
            origin = [origin[0] + d[0], origin[1] + d[1]];
            let before = t.texels().to_vec();
            let rects = t.move_to(origin, value);
            // At most 4 rects, non-empty, in range, pairwise disjoint.
            prop_assert!(rects.len() <= 4, "step {i}: {} rects", rects.len());
            for (a, r) in rects.iter().enumerate() {
                prop_assert!(r.x0 < r.x1 && r.y0 < r.y1 && r.x1 <= s && r.y1 <= s);
                for q in &rects[a + 1..] {
                    prop_assert!(!r.overlaps(q));
                }
            }
            let written: i64 = rects.iter().map(|r| r.area() as i64).sum();
            prop_assert_eq!(written, exposed_area(old, origin, s as i64));
            for ty in 0..s {
                for tx in 0..s {
                    let wx = Toroid::<i64>::world_of(tx, origin[0], s);
                    let wy = Toroid::<i64>::world_of(ty, origin[1], s);
                    let idx = ty * s + tx;
                    // Contents equal a from-scratch rebuild.
                    prop_assert_eq!(t.texels()[idx], value(wx, wy));
                    let in_rect = rects.iter().any(|r| tx >= r.x0 && tx < r.x1 && ty >= r.y0 && ty < r.y1);
                    let was_kept = old.is_some_and(|o: [i64; 2]| {
                        wx >= o[0] && wx < o[0] + s as i64 && wy >= o[1] && wy < o[1] + s as i64
                    }) && written < (s * s) as i64;
                    // Update rects never touch the kept region...
                    prop_assert!(!(in_rect && was_kept), "kept texel rewritten");
                    // ...and texels outside them are untouched.
                    if !in_rect {
                        prop_assert_eq!(t.texels()[idx], before[idx]);
                    }
                }
            }
            old = Some(origin);
        }
    }

    #[test]
    fn diagonal_move_by_m_rewrites_2ms_minus_m2(
        (s, m) in (2usize..200).prop_flat_map(|s| (Just(s), 1..s)),
        sx in prop::sample::select(vec![-1i64, 1]),
        sy in prop::sample::select(vec![-1i64, 1]),
        o in [-500i64..500, -500i64..500],
    ) {
        let new = [o[0] + sx * m as i64, o[1] + sy * m as i64];
        let area: usize = update_rects(Some(o), new, s).iter().map(|r| r.area()).sum();
        prop_assert_eq!(area, 2 * m * s - m * m);
    }

}

fn base_clipmap() -> terraclip::clipmap::Clipmap {
    static BASE: std::sync::OnceLock<terraclip::clipmap::Clipmap> = std::sync::OnceLock::new();
    BASE.get_or_init(|| common::clipmap(&common::terrain(3, 420, 380), 15, None, Layout::Strips))
        .clone()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    #[test]
    fn clipmap_levels_match_rebuild_after_walks(
        viewers in prop::collection::vec([-300.0f64..700.0, -300.0f64..700.0], 1..12),
        jump in any::<bool>(),
    ) {
        let mut cm = base_clipmap();
        for v in &viewers {
            cm.update(*v);
        }
        if jump {
            cm.update([1e9, -1e9]);
        }
        let mut fresh = base_clipmap();
        let last = if jump { [1e9, -1e9] } else { *viewers.last().unwrap() };
        fresh.update(last);
        for (a, b) in cm.levels().iter().zip(fresh.levels()) {
            prop_assert_eq!(a.heights.origin(), b.heights.origin());
            prop_assert_eq!(a.heights.texels(), b.heights.texels());
            prop_assert_eq!(a.regions, b.regions);
        }
    }
}

/// Small steps: mostly one texel east or west (a column each, read through
/// the level's column cache), with some vertical drift past the cache's
/// margin, some steps off the map, where the cached blocks clamp, and
/// fractions of a texel that leave level 0's origin put.
fn small_step() -> impl Strategy<Value = [f64; 2]> {
    prop_oneof![
        8 => (-2i64..=2).prop_map(|d| [d as f64, 0.0]),
        2 => [-0.75f64..0.75, -0.75f64..0.75],
        2 => (-3i64..=3, -40i64..=40).prop_map(|(x, y)| [x as f64, y as f64]),
        1 => (-20i64..=20, -3i64..=3).prop_map(|(x, y)| [x as f64, y as f64]),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn column_walks_match_rebuild_bit_for_bit(
        start in [-120.0f64..540.0, -120.0f64..500.0],
        steps in prop::collection::vec(small_step(), 1..120),
    ) {
        let mut cm = base_clipmap();
        let mut v = start;
        cm.update(v);
        for (i, d) in steps.iter().enumerate() {
            v = [v[0] + d[0], v[1] + d[1]];
            let before: Vec<_> = cm.levels().iter().map(|l| l.heights.origin()).collect();
            let st = cm.update(v).clone();
            // The statistics name exactly this step's rectangles: nothing
            // left over from an earlier step (an update clears only the
            // levels the last one wrote).
            let mut total = 0;
            for (l, lv) in cm.levels().iter().enumerate() {
                let after = lv.heights.origin().expect("filled");
                let want = update_rects(before[l], after, lv.heights.size());
                let area: u64 = want.iter().map(|r| r.area() as u64).sum();
                prop_assert_eq!(&st.rects_per_level[l][..], &want[..], "level {} step {}", l, i);
                prop_assert_eq!(st.texels_per_level[l], area);
                total += area;
            }
            prop_assert_eq!(st.texels_total, total);
            if i % 7 != 6 && i + 1 != steps.len() {
                continue;
            }
            let mut fresh = base_clipmap();
            fresh.update(v);
            for (l, (a, b)) in cm.levels().iter().zip(fresh.levels()).enumerate() {
                prop_assert_eq!(a.heights.origin(), b.heights.origin());
                prop_assert_eq!(a.regions, b.regions);
                prop_assert_eq!(a.morph, b.morph);
                let bits = |t: &[f32]| t.iter().map(|h| h.to_bits()).collect::<Vec<_>>();
                prop_assert!(
                    bits(a.heights.texels()) == bits(b.heights.texels()),
                    "level {} differs after step {} at {:?}", l, i, v
                );
            }
        }
    }
}

#[test]
fn texel_budget_updates_coarse_to_fine_and_deactivates_the_rest() {
    let map = common::terrain(5, 500, 500);
    let pyramid = std::sync::Arc::new(terraclip::pyramid::Pyramid::build(
        &map,
        terraclip::pyramid::Filter::Box,
        4,
    ));
    let cfg = terraclip::clipmap::ClipmapConfig {
        n: 31,
        levels: Some(4),
        texel_budget: Some(31 * 31 * 2),
        ..Default::default()
    };
    let mut cm = terraclip::clipmap::Clipmap::new(pyramid, cfg).unwrap();
    let st = cm.update([250.0, 250.0]);
    // First fill: each level needs 31² texels; the budget covers the two
    // coarsest levels only.
    assert_eq!(st.texels_per_level, vec![0, 0, 961, 961]);
    assert_eq!(st.levels_deferred, 2);
    let active: Vec<bool> = cm.levels().iter().map(|l| l.is_active()).collect();
    assert_eq!(active, vec![false, false, true, true]);
    // Next frame (same viewer): the two finer levels fill and become active.
    let st = cm.update([250.0, 250.0]);
    assert_eq!(st.texels_per_level, vec![961, 961, 0, 0]);
    assert!(cm.levels().iter().all(|l| l.is_active()));
}

/// Walks of 256 one-texel frames copy each level's column blocks about
/// once per [`BLOCK`] columns travelled: with the least margin on a side
/// the window does not drift to, the full one on a side it does, and at
/// most one refill per level for that drift. A level that moves only
/// vertically in a frame (coarse levels of a diagonal walk, every other
/// step) keeps its block: refilling it there copied 2.5 times the rows.
#[test]
fn walks_copy_each_column_block_about_once() {
    let frames = 256u64;
    for (name, dir) in [
        ("east", [1.0, 0.0]),
        ("diagonal", [1.0, 1.0]),
        ("west and south", [-1.0, 0.5]),
    ] {
        let mut cm = base_clipmap();
        let start = [37.0, 61.0];
        cm.update(start);
        let mut rows = 0;
        for f in 1..=frames {
            let v = [start[0] + dir[0] * f as f64, start[1] + dir[1] * f as f64];
            rows += cm.update(v).column_rows_copied;
        }
        let n = cm.levels()[0].heights.size() as u64;
        let (block, margin, least) = (BLOCK as u64, MARGIN as u64, MIN_MARGIN as u64);
        // Blocks a level enters: its columns travelled over BLOCK, plus the
        // one it starts in and one it may end in.
        let blocks = |l: usize| (frames >> l) / block + 2;
        // Each level's first block has both full margins (no motion known).
        let first = n + 2 * margin;
        let levels = 0..cm.levels().len();
        let bound: u64 = if name == "east" {
            levels
                .map(|l| first + (blocks(l) - 1) * (n + 2 * least))
                .sum()
        } else {
            levels
                .map(|l| first + blocks(l) * (n + margin + least))
                .sum()
        };
        assert!(rows > 0, "{name}: no column block copied");
        assert!(
            rows <= bound,
            "{name}: {rows} rows copied, at most {bound} expected"
        );
    }
}
