//! Frustum culling and cropping of render regions (Brettell ch. 4).
//!
//! Each render rectangle is extruded by its height range into a world AABB
//! and classified with Greene's p/n-vertex test. A rectangle that straddles
//! the frustum is cropped to the grid-aligned xy bounds of box ∩ frustum, a
//! conservative version of Brettell's Algorithm 5: the bounds are exact for
//! the convex polytope, then widened to whole cells and by one cell for
//! rounding, so no visible cell is ever dropped.

use crate::camera::Frustum;
use crate::terrain::world::WorldMap;
use glam::{DVec3, DVec4};

/// Greene's classification of a box against a frustum.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Class {
    /// Wholly outside one plane: culled.
    Outside,
    /// Inside every plane: drawn without further tests.
    Inside,
    /// Crosses a plane: its children are tested.
    Intersecting,
}

/// Classifies an AABB with the p/n-vertex test.
pub fn classify(f: &Frustum, lo: DVec3, hi: DVec3) -> Class {
    let mut all_in = true;
    for p in &f.planes {
        let pv = DVec3::new(
            if p.x >= 0.0 { hi.x } else { lo.x },
            if p.y >= 0.0 { hi.y } else { lo.y },
            if p.z >= 0.0 { hi.z } else { lo.z },
        );
        if Frustum::distance(p, pv) < 0.0 {
            return Class::Outside;
        }
        let nv = DVec3::new(
            if p.x >= 0.0 { lo.x } else { hi.x },
            if p.y >= 0.0 { lo.y } else { hi.y },
            if p.z >= 0.0 { lo.z } else { hi.z },
        );
        if Frustum::distance(p, nv) < 0.0 {
            all_in = false;
        }
    }
    if all_in {
        Class::Inside
    } else {
        Class::Intersecting
    }
}

/// Clips a convex polygon against one plane (Sutherland–Hodgman).
pub fn clip_polygon(poly: &[DVec3], plane: &DVec4) -> Vec<DVec3> {
    let mut out = Vec::with_capacity(poly.len() + 2);
    for i in 0..poly.len() {
        let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
        let (da, db) = (Frustum::distance(plane, a), Frustum::distance(plane, b));
        if da >= 0.0 {
            out.push(a);
        }
        if (da >= 0.0) != (db >= 0.0) {
            out.push(a + (b - a) * (da / (da - db)));
        }
    }
    out
}

/// World-space xy bounds of box ∩ frustum, or `None` if they do not meet.
pub fn clipped_xy_bounds(f: &Frustum, lo: DVec3, hi: DVec3) -> Option<(DVec3, DVec3)> {
    let c = |i: usize| {
        DVec3::new(
            if i & 1 == 0 { lo.x } else { hi.x },
            if i & 2 == 0 { lo.y } else { hi.y },
            if i & 4 == 0 { lo.z } else { hi.z },
        )
    };
    let faces: [[usize; 4]; 6] = [
        [0, 1, 3, 2],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 3, 7, 6],
        [0, 2, 6, 4],
        [1, 3, 7, 5],
    ];
    let mut pts: Vec<DVec3> = vec![];
    for face in faces {
        let mut poly: Vec<DVec3> = face.iter().map(|&i| c(i)).collect();
        for p in &f.planes {
            poly = clip_polygon(&poly, p);
            if poly.is_empty() {
                break;
            }
        }
        pts.extend(poly);
    }
    // Vertices made of three frustum planes: the frustum's own corners.
    let eps = 1e-9 * (hi - lo).abs().max_element().max(1.0);
    pts.extend(f.corners.iter().copied().filter(|p| {
        p.cmpge(lo - DVec3::splat(eps)).all() && p.cmple(hi + DVec3::splat(eps)).all()
    }));
    if pts.is_empty() {
        return None;
    }
    let min = pts
        .iter()
        .fold(DVec3::splat(f64::INFINITY), |a, &p| a.min(p));
    let max = pts
        .iter()
        .fold(DVec3::splat(f64::NEG_INFINITY), |a, &p| a.max(p));
    Some((min, max))
}

/// The level texels a closed rectangle's triangles can reach: stitching
/// moves boundary vertices one texel toward lower x or y
/// ([`super::morph::MorphParams::stitch`]), so a triangle of the
/// rectangle's first row or column can cover part of the cell below it.
/// Boxes for culling are built from this reach, never from the rectangle.
pub fn stitch_reach(r: [i64; 4]) -> [i64; 4] {
    [r[0] - 1, r[1] - 1, r[2], r[3]]
}

/// The world box of the texels rectangle `r` of a level of spacing `g`
/// can reach ([`stitch_reach`]), over heights `[zlo, zhi]`.
fn reach_box(world: &WorldMap, r: [i64; 4], g: i64, zlo: f32, zhi: f32) -> (DVec3, DVec3) {
    let s = g as f64;
    let reach = stitch_reach(r);
    world.aabb(
        reach[0] as f64 * s,
        reach[1] as f64 * s,
        r[2] as f64 * s,
        r[3] as f64 * s,
        zlo as f64,
        zhi as f64,
    )
}

/// Culls and crops a closed rectangle of level-l texels `[x0,y0,x1,y1]`
/// (level spacing `g` base texels) whose heights lie in `[zlo, zhi]`.
/// Returns the cropped rectangle, or `None` if nothing of it is visible.
pub fn cull_rect(
    f: &Frustum,
    world: &WorldMap,
    r: [i64; 4],
    g: i64,
    zlo: f32,
    zhi: f32,
) -> Option<[i64; 4]> {
    let s = g as f64;
    let (lo, hi) = reach_box(world, r, g, zlo, zhi);
    match classify(f, lo, hi) {
        Class::Outside => None,
        Class::Inside => Some(r),
        Class::Intersecting => {
            let (a, b) = clipped_xy_bounds(f, lo, hi)?;
            let ga = world.to_grid(a);
            let gb = world.to_grid(b);
            let (c0, c1) = (ga[0].min(gb[0]) / s, ga[0].max(gb[0]) / s);
            let (r0, r1) = (ga[1].min(gb[1]) / s, ga[1].max(gb[1]) / s);
            let out = [
                r[0].max(c0.floor() as i64 - 1),
                r[1].max(r0.floor() as i64 - 1),
                r[2].min(c1.ceil() as i64 + 1),
                r[3].min(r1.ceil() as i64 + 1),
            ];
            (out[0] < out[2] && out[1] < out[3]).then_some(out)
        }
    }
}

/// [`cull_rect`] in blocks: a rectangle that straddles the frustum is cut
/// in two across its longer side, and each half culled again with the
/// height bounds `range` gives for its reach, down to sides of `block`
/// texels, which are cropped as [`cull_rect`] crops. A narrow view looking
/// across a level sees a thin wedge of it, whose bounding rectangle (what
/// one crop keeps) can hold tens of times the wedge's cells. The halves
/// share their cut row or column, so they tile the rectangle's cells.
pub fn cull_blocks(
    f: &Frustum,
    world: &WorldMap,
    r: [i64; 4],
    g: i64,
    block: i64,
    range: &impl Fn([i64; 4]) -> (f32, f32),
    out: &mut Vec<[i64; 4]>,
) {
    let (zlo, zhi) = range(stitch_reach(r));
    let (lo, hi) = reach_box(world, r, g, zlo, zhi);
    match classify(f, lo, hi) {
        Class::Outside => {}
        Class::Inside => out.push(r),
        Class::Intersecting => {
            let (w, h) = (r[2] - r[0], r[3] - r[1]);
            if w.max(h) <= block {
                out.extend(cull_rect(f, world, r, g, zlo, zhi));
            } else if w >= h {
                let m = r[0] + w / 2;
                cull_blocks(f, world, [r[0], r[1], m, r[3]], g, block, range, out);
                cull_blocks(f, world, [m, r[1], r[2], r[3]], g, block, range, out);
            } else {
                let m = r[1] + h / 2;
                cull_blocks(f, world, [r[0], r[1], r[2], m], g, block, range, out);
                cull_blocks(f, world, [r[0], m, r[2], r[3]], g, block, range, out);
            }
        }
    }
}
