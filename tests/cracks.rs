//! Watertightness of the morphed mesh, both index layouts, checked exactly on
//! integer positions and f32 height bits:
//! - every triangle has strictly positive orientation: a zero-area triangle
//!   would get attribute planes extrapolated from a near-zero area wherever
//!   snapping gives it a pixel (the GPU Gems ring did: colour 3.2 on a 0–1
//!   ramp, seen as 1-px "cracks" by the survey);
//! - every directed edge is matched by exactly one reverse edge, except the
//!   edges on the perimeter of the rendered area, which appear once, in
//!   order, and add up to the perimeter;
//! - the triangle areas add up to the rendered area.
//!
//! Together these mean the triangles cover the area once, with no gap, no
//! overlap and no T-junction whose heights disagree (the winding number of
//! the edge chain is 1 inside and 0 outside). Morph off must break it.

mod common;
use proptest::prelude::*;
use terraclip::clipmap::{Clipmap, Layout};

fn base(layout: Layout, n: i64) -> Clipmap {
    common::clipmap(&common::terrain(11, 700, 530), n, None, layout)
}

/// Viewers over the 700×530 map and up to 300 texels beyond its edges
/// (footprints) or 200 (strips), where the coarsest level's window still
/// meets the map, so every case draws part of it and checks a non-empty
/// mesh. Viewers so far off that nothing is drawn are
/// checked in `tests/stability.rs` (camera jumps).
fn cases(layout: Layout) -> impl Strategy<Value = (i64, [f64; 2])> {
    let range = match layout {
        Layout::Strips => -200.0..900.0,
        Layout::Footprints => -300.0..1000.0,
    };
    (
        prop::sample::select(vec![15i64, 31]),
        [range.clone(), range],
    )
}

/// Runs `cases` watertightness cases; each must check a non-empty mesh.
/// Returns (cases that checked triangles, all cases) and asserts the first
/// is at least 95 % of the second, printing both.
fn survey<S: Strategy>(
    name: &str,
    strategy: S,
    build: impl Fn(&S::Value) -> Clipmap,
) -> (usize, usize) {
    use proptest::test_runner::{Config, TestRunner};
    use std::cell::Cell;
    let (checked, total, triangles) = (Cell::new(0usize), Cell::new(0usize), Cell::new(0usize));
    let mut runner = TestRunner::new(Config::with_cases(150));
    let result = runner.run(&strategy, |v| {
        total.set(total.get() + 1);
        let cm = build(&v);
        match common::watertight(&cm) {
            Err(e) => Err(TestCaseError::fail(format!("viewer {v:?}: {e}"))),
            Ok(0) => Err(TestCaseError::fail(format!(
                "viewer {v:?}: nothing drawn, nothing checked"
            ))),
            Ok(t) => {
                checked.set(checked.get() + 1);
                triangles.set(triangles.get() + t);
                Ok(())
            }
        }
    });
    if let Err(e) = result {
        panic!("{name}: {e}");
    }
    let (c, n) = (checked.get(), total.get());
    println!(
        "{name}: {c} of {n} cases checked a non-empty mesh ({} triangles)",
        triangles.get()
    );
    assert!(n >= 150 && c * 100 >= 95 * n, "{name}: {c} of {n}");
    (c, n)
}

#[test]
fn strips_are_watertight() {
    let s = (cases(Layout::Strips), [-200.0f64..900.0, -200.0f64..900.0]);
    survey("strips", s, |&((n, v), prev)| {
        let mut cm = cached(Layout::Strips, n);
        cm.update(prev);
        cm.update(v);
        cm
    });
}

/// A view-dependent clipmap places each level on its own want
/// (`Clipmap::update_placed`), as far from the viewer's chain as nesting
/// allows, and centres each level's morph on its window: random wants (a
/// third of them none) over the map and beyond it, after a placement from
/// other wants, stay watertight.
#[test]
fn placed_strips_are_watertight() {
    let want = prop::option::weighted(0.67, [-300.0f64..1000.0, -300.0f64..1000.0]);
    let wants = prop::collection::vec(want, 0..6);
    let s = (
        cases(Layout::Strips),
        [-200.0f64..900.0, -200.0f64..900.0],
        wants.clone(),
        wants,
    );
    let (checked, _) = survey("placed strips", s, |((n, v), prev, before, now)| {
        let mut cm = cached(Layout::Strips, *n);
        cm.update_placed(*prev, before);
        cm.update_placed(*v, now);
        cm
    });
    assert!(checked > 0);
}

#[test]
fn footprints_are_watertight() {
    survey("footprints", cases(Layout::Footprints), |&(n, v)| {
        let mut cm = cached(Layout::Footprints, n);
        cm.update(v);
        cm
    });
}

fn cached(layout: Layout, n: i64) -> Clipmap {
    use std::sync::OnceLock;
    static CACHE: OnceLock<Vec<((Layout, i64), Clipmap)>> = OnceLock::new();
    CACHE
        .get_or_init(|| {
            let mut v = vec![];
            for layout in [Layout::Strips, Layout::Footprints] {
                for n in [15, 31] {
                    v.push(((layout, n), base(layout, n)));
                }
            }
            v
        })
        .iter()
        .find(|(k, _)| *k == (layout, n))
        .expect("cached")
        .1
        .clone()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(150))]

    /// α is 0 well inside, 1 on stitched boundaries (so z′ = z_c there), and
    /// moves continuously: a sub-texel viewer move that does not shift the
    /// windows changes no α by more than the move over w.
    #[test]
    fn morph_weights((n, v) in cases(Layout::Strips), d in [-0.02f64..0.02, -0.02f64..0.02]) {
        let mut cm = cached(Layout::Strips, n);
        cm.update(v);
        let mut moved = cm.clone();
        moved.update([v[0] + d[0], v[1] + d[1]]);
        for (l, lv) in cm.levels().iter().enumerate() {
            let Some(a) = lv.regions.active else { continue };
            let g = lv.spacing();
            let mp = &lv.morph;
            for y in a.y0 / g..=a.y1 / g {
                for x in a.x0 / g..=a.x1 / g {
                    let vx = cm.vertex(l, x, y);
                    if !mp.enabled {
                        prop_assert_eq!(vx.alpha, 0.0);
                        continue;
                    }
                    let rx = (x - lv.regions.origin[0]) as f32 - mp.viewer[0];
                    let ry = (y - lv.regions.origin[1]) as f32 - mp.viewer[1];
                    let inner = mp.half - mp.width - 1.0;
                    if rx.abs() <= inner && ry.abs() <= inner {
                        prop_assert_eq!(vx.alpha, 0.0);
                    }
                    let b = mp.boundary;
                    let rel = [x - lv.regions.origin[0], y - lv.regions.origin[1]];
                    let on = (mp.stitched[0] && rel[0] == b[0] as i64) || (mp.stitched[2] && rel[0] == b[2] as i64)
                        || (mp.stitched[1] && rel[1] == b[1] as i64) || (mp.stitched[3] && rel[1] == b[3] as i64);
                    if on {
                        prop_assert_eq!(vx.alpha, 1.0);
                        prop_assert_eq!(vx.zm.to_bits(), vx.zc.to_bits());
                    }
                    if moved.levels()[l].regions == lv.regions {
                        let va = moved.vertex(l, x, y).alpha;
                        let bound = (d[0].abs().max(d[1].abs()) / g as f64) as f32 / mp.width + 1e-5;
                        prop_assert!((va - vx.alpha).abs() <= bound, "α jumped {} → {va}", vx.alpha);
                    }
                }
            }
        }
    }
}

#[test]
fn morph_off_leaves_cracks_that_the_check_finds() {
    let map = common::terrain(11, 700, 530);
    let p = std::sync::Arc::new(terraclip::pyramid::Pyramid::build(
        &map,
        terraclip::pyramid::Filter::SincBlackman { taps: 7 },
        4,
    ));
    let cfg = terraclip::clipmap::ClipmapConfig {
        n: 31,
        levels: Some(4),
        morph: false,
        ..Default::default()
    };
    let mut cm = Clipmap::new(p, cfg).unwrap();
    cm.update([350.0, 260.0]);
    let e = common::watertight(&cm).expect_err("morph off must not be watertight");
    assert!(e.contains("unmatched") || e.contains("overlap"), "{e}");
}
