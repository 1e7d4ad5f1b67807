//! The crack survey: renders over a red background from many random views.
//! A candidate is a background pixel enclosed by terrain that a brute-force
//! render of the same view covers ([`metrics::crack_pixels`]). On steep
//! relief at grazing angles that is also true of sky seen past a ridge the
//! LOD made lower, which no hole made, so each candidate is classified
//! against the LOD's own surface (the frame's triangles, [`Surface`]):
//!
//! - a **hole** when the ray through the pixel centre meets that surface
//!   before the far plane (the surface is there and was not drawn), or,
//!   over the map and below the terrain's top, crosses a place no triangle
//!   covers (a missing triangle) or runs under the surface without having
//!   met it (through a T-junction's slit);
//! - **far depth** when, with no hole before it, the ray first meets the
//!   surface within 16 ULP of the far plane's depth: the depth buffer,
//!   cleared to 1.0, cannot keep it (steep relief seen over 10^7 m with
//!   near = 1 m);
//! - an **LOD difference** otherwise: the ray passes above the LOD's
//!   surface everywhere, and brute force's finer ridges hide that sky.
//!
//! `crack_pixels` counts holes only; `lod_sky_pixels` and
//! `far_depth_pixels` the others. Brute-force renders are shared by all
//! schemes of one run.

use crate::camera::Camera;
use crate::clipmap::Layout;
use crate::error::{Error, Result};
use crate::frame::stats::Passes;
use crate::frame::surface::Surface;
use crate::render::{Image, RenderOptions, Session};
use crate::scene::{Effect, LodScheme, Scene};
use crate::shard::Shard;
use crate::studies::metrics;
use crate::studies::views;
use glam::DVec3;
use serde::{Deserialize, Serialize};

/// Schemes `--lod all` surveys: every scheme but brute force (the
/// reference), the clipmap in each layout (`clipmap/strips`, …) and
/// nested around the view (`clipmap/view`).
pub fn all() -> Vec<String> {
    LodScheme::ALL
        .iter()
        .flat_map(|&s| match s {
            LodScheme::BruteForce => vec![],
            LodScheme::Clipmap => Layout::ALL
                .iter()
                .map(|l| format!("{s}/{l}"))
                .chain([format!("{s}/view")])
                .collect(),
            _ => vec![s.to_string()],
        })
        .collect()
}

/// One scheme's crack survey over every view (`cracks --json` `schemes`).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct SchemeCracks {
    /// The scheme.
    pub lod: String,
    /// Candidates classified as holes.
    pub crack_pixels: usize,
    /// Candidates classified as sky past a ridge the LOD made lower.
    pub lod_sky_pixels: usize,
    /// Candidates whose ray meets the LOD's surface only at a depth the
    /// depth buffer cannot tell from the far plane ([`Candidate::FarDepth`]).
    pub far_depth_pixels: usize,
    /// Triangles drawn over the surveyed views: what the scheme drew, so
    /// that a part surveyed in another state than one run shows it (a
    /// texel budget's waiting levels, ROAM's queues) where no crack does.
    pub triangles: usize,
    /// Views with at least one hole.
    pub views_with_cracks: usize,
    /// Views with at least one LOD-sky pixel.
    pub views_with_lod_sky: usize,
    /// The view with the most hole pixels.
    pub worst_view: usize,
    /// Its hole pixels.
    pub worst_pixels: usize,
    /// The worst view's eye and look-at point (for `render --camera
    /// --look-at`).
    pub worst_camera: [f64; 6],
    /// The worst view's render and its brute-force reference.
    #[serde(skip)]
    pub worst_images: Option<(Image, Image)>,
}

/// The crack survey: each scheme against brute force over many seeded views.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct CrackReport {
    /// Views in the sweep.
    pub views: usize,
    /// Views this run surveyed per scheme: all of them, or a shard's share.
    pub views_surveyed: usize,
    /// Holes over all surveyed schemes.
    pub crack_pixels: usize,
    /// LOD-sky pixels over all surveyed schemes.
    pub lod_sky_pixels: usize,
    /// Far-depth pixels over all surveyed schemes.
    pub far_depth_pixels: usize,
    /// The view with the most hole pixels over all schemes.
    pub worst_view: usize,
    /// Per scheme.
    pub schemes: Vec<SchemeCracks>,
}

/// The scene prepared for the survey: red background, no shading effects
/// (colour is the height ramp), morph kept as the scene says.
pub fn survey_scene(scene: &Scene, size: [u32; 2]) -> Scene {
    let mut s = scene.clone();
    s.image.background = [1.0, 0.0, 0.0];
    s.image.width = size[0];
    s.image.height = size[1];
    s.effects.retain(|e| *e == Effect::Morph);
    s
}

/// Surveys `schemes` over the views of `count` random ones that `shard`
/// owns; `tick` is called after each view. Every view still moves each
/// scheme (its frame is made and dropped), so schemes that keep state
/// from frame to frame, ROAM's queues and the clipmap's toroids, are in
/// the same state at a shard's views as in one run of them all.
pub fn survey(
    scene: &Scene,
    schemes: &[String],
    count: usize,
    size: [u32; 2],
    shard: Shard,
    mut tick: impl FnMut(),
) -> Result<CrackReport> {
    let base = survey_scene(scene, size);
    let opts = RenderOptions::default();
    // The map is loaded (or generated) once for every scheme.
    let map = Session::load_map(&base)?;
    let mut brute = Session::with_map(
        &base.with_scheme(LodScheme::BruteForce, None)?,
        map.as_ref(),
        &mut Passes::default(),
    )?;
    let mut sessions = schemes
        .iter()
        .map(|s| Session::with_map(&base.with_lod(s)?, map.as_ref(), &mut Passes::default()))
        .collect::<Result<Vec<_>>>()?;
    drop(map);
    let cams = views::random_views(&brute, &base.camera(), count, 0x5EED_CAFE);
    let mut out: Vec<SchemeCracks> = schemes
        .iter()
        .map(|s| SchemeCracks {
            lod: s.clone(),
            crack_pixels: 0,
            lod_sky_pixels: 0,
            far_depth_pixels: 0,
            triangles: 0,
            views_with_cracks: 0,
            views_with_lod_sky: 0,
            worst_view: 0,
            worst_pixels: 0,
            worst_camera: [0.0; 6],
            worst_images: None,
        })
        .collect();
    let mut surveyed = 0;
    for (i, cam) in cams.iter().enumerate() {
        if !shard.owns(i) {
            for s in sessions.iter_mut() {
                s.frame(cam, &mut Passes::default())?;
            }
            tick();
            continue;
        }
        surveyed += 1;
        let (reference, _) = brute.render(cam, &opts, Passes::default())?;
        for (s, r) in sessions.iter_mut().zip(out.iter_mut()) {
            let (frame, _) = s.frame(cam, &mut Passes::default())?;
            r.triangles += frame.triangle_count();
            let (img, _) = s.draw(&frame, &opts, &mut Passes::default());
            let candidates = metrics::crack_candidates(&img, &reference, [255, 0, 0]);
            let (mut c, mut sky, mut far) = (0, 0, 0);
            if !candidates.is_empty() {
                let domain = Domain::of(s);
                let surface = Surface::new(&frame, &s.world);
                for &p in &candidates {
                    let (px, py) = (p % img.width as usize, p / img.width as usize);
                    let dir = cam.ray_through(size, px as f64 + 0.5, py as f64 + 0.5);
                    match classify(&surface, cam, dir, &domain) {
                        Candidate::Hole => c += 1,
                        Candidate::LodSky => sky += 1,
                        Candidate::FarDepth => far += 1,
                    }
                }
            }
            r.crack_pixels += c;
            r.lod_sky_pixels += sky;
            r.far_depth_pixels += far;
            r.views_with_cracks += usize::from(c > 0);
            r.views_with_lod_sky += usize::from(sky > 0);
            if c > r.worst_pixels {
                r.worst_pixels = c;
                r.worst_view = i;
                let (e, t) = (cam.eye, cam.target);
                r.worst_camera = [e.x, e.y, e.z, t.x, t.y, t.z];
                r.worst_images = Some((img, reference.clone()));
            }
        }
        tick();
    }
    report(count, surveyed, out).map_err(|why| Error::value("cracks", why))
}

/// The report over the schemes' tallies.
fn report(
    views: usize,
    views_surveyed: usize,
    schemes: Vec<SchemeCracks>,
) -> std::result::Result<CrackReport, &'static str> {
    let worst = schemes.iter().max_by_key(|r| r.worst_pixels);
    Ok(CrackReport {
        views,
        views_surveyed,
        crack_pixels: sum(schemes.iter().map(|r| r.crack_pixels))?,
        lod_sky_pixels: sum(schemes.iter().map(|r| r.lod_sky_pixels))?,
        far_depth_pixels: sum(schemes.iter().map(|r| r.far_depth_pixels))?,
        worst_view: worst.map_or(0, |r| r.worst_view),
        schemes,
    })
}

/// A sum of counts, which parts read from files can push past `usize`.
fn sum(mut counts: impl Iterator<Item = usize>) -> std::result::Result<usize, &'static str> {
    counts
        .try_fold(0usize, |a, c| a.checked_add(c))
        .ok_or("a count past the largest whole number")
}

/// Joins the surveys of a sweep's shards ([`crate::studies::merge::merge`]
/// checks they are its parts): counts summed, and each scheme's worst view
/// the one with the most holes, the earliest on a tie, as one run picks it.
/// Parts read from files may disagree or hold counts past `usize`: those
/// are errors that say why, never a partial sum.
pub fn merge(parts: &[CrackReport]) -> std::result::Result<CrackReport, String> {
    let first = parts.first().ok_or("no parts")?;
    if let Some(k) = parts.iter().position(|p| {
        p.views != first.views
            || p.schemes.len() != first.schemes.len()
            || p.schemes
                .iter()
                .zip(&first.schemes)
                .any(|(a, b)| a.lod != b.lod)
    }) {
        return Err(format!(
            "part {k} surveyed other views or schemes than part 0"
        ));
    }
    let schemes = (0..first.schemes.len())
        .map(|j| {
            let all: Vec<&SchemeCracks> = parts.iter().map(|r| &r.schemes[j]).collect();
            let worst = all
                .iter()
                .max_by(|a, b| {
                    a.worst_pixels
                        .cmp(&b.worst_pixels)
                        .then(b.worst_view.cmp(&a.worst_view))
                })
                .copied()
                .unwrap_or(&first.schemes[j]);
            let total = |f: fn(&SchemeCracks) -> usize| sum(all.iter().map(|s| f(s)));
            Ok(SchemeCracks {
                crack_pixels: total(|s| s.crack_pixels)?,
                lod_sky_pixels: total(|s| s.lod_sky_pixels)?,
                far_depth_pixels: total(|s| s.far_depth_pixels)?,
                triangles: total(|s| s.triangles)?,
                views_with_cracks: total(|s| s.views_with_cracks)?,
                views_with_lod_sky: total(|s| s.views_with_lod_sky)?,
                worst_images: None,
                ..worst.clone()
            })
        })
        .collect::<std::result::Result<Vec<_>, &str>>()?;
    let surveyed = sum(parts.iter().map(|r| r.views_surveyed))?;
    Ok(report(first.views, surveyed, schemes)?)
}

/// What explains a candidate pixel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Candidate {
    /// The LOD's surface is there (or missing inside the map) and was not
    /// drawn.
    Hole,
    /// The ray passes above the LOD's surface everywhere.
    LodSky,
    /// The ray meets the LOD's surface only where its depth is within
    /// [`FAR_DEPTH_BAND`] of 1.0: a Depth32Float buffer cleared to 1.0 and
    /// tested LESS cannot keep it (brute force's nearer, higher ridge
    /// covers the pixel at a depth it can keep).
    FarDepth,
}

/// 16 ULP of depth just below 1.0 (2^-20): the f32 error of the depth
/// stage (`check::compare::TOLERANCE_DEPTH_ULP` derives it).
pub const FAR_DEPTH_BAND: f64 = 1.0 / 1_048_576.0;

/// Where the terrain is: the map's world rectangle, the top of its
/// heights, and the step the ray is sampled at over it (a quarter cell).
#[derive(Clone, Copy, Debug)]
pub struct Domain {
    /// (x0, y0, x1, y1) in world metres.
    pub rect: [f64; 4],
    /// The highest terrain point, metres.
    pub top: f64,
    /// Sampling step along the ray's ground track, metres.
    pub step: f64,
}

impl Domain {
    /// The session's map, cut to what its LOD scheme covers: a clipmap
    /// draws nothing beyond its coarsest level's active region.
    pub fn of(s: &Session) -> Domain {
        let base = &s.pyramid().levels[0];
        let w = &s.world;
        let (mut c0, mut r0, mut c1, mut r1) = (
            0.0f64,
            0.0f64,
            (base.width - 1) as f64,
            (base.height - 1) as f64,
        );
        if let Some(a) = s
            .lod
            .clipmap()
            .and_then(|cm| cm.levels().iter().rev().find_map(|l| l.regions.active))
        {
            c0 = c0.max(a.x0 as f64);
            r0 = r0.max(a.y0 as f64);
            c1 = c1.min(a.x1 as f64);
            r1 = r1.min(a.y1 as f64);
        }
        let a = w.to_world(c0, r0, 0.0);
        let b = w.to_world(c1, r1, 0.0);
        Domain {
            rect: [a.x.min(b.x), a.y.min(b.y), a.x.max(b.x), a.y.max(b.y)],
            top: base.max as f64 * w.vertical_scale,
            step: 0.25 * w.cell[0].min(w.cell[1]),
        }
    }

    fn contains(&self, p: DVec3) -> bool {
        let [x0, y0, x1, y1] = self.rect;
        p.x >= x0 && p.x <= x1 && p.y >= y0 && p.y <= y1
    }
}

/// Classifies the background pixel whose centre ray is `dir` from
/// `camera`'s eye, against `surface`, the LOD's own triangles (see the
/// module documentation). The ray counts between the near and the far
/// plane.
pub fn classify(surface: &Surface, camera: &Camera, dir: DVec3, domain: &Domain) -> Candidate {
    let forward = (camera.target - camera.eye).normalize();
    let cos = dir.dot(forward);
    if cos <= 0.0 {
        return Candidate::LodSky;
    }
    // Ray parameters of the near and far planes.
    let (t_near, t_far) = (camera.near / cos, camera.far / cos);
    let hit = surface
        .ray_hit(camera.eye, dir)
        .filter(|h| h.t >= t_near && h.t <= t_far);
    if let Some(h) = hit {
        // The depth the hit has in exact arithmetic. Within the f32 error
        // of the depth stage (16 ULP below 1.0, the bound `check::parity`
        // derives) of the clear value, the surface is too close to the far
        // plane for a depth buffer to keep; anywhere nearer it is a hole.
        let z_view = h.t * cos;
        let depth = camera.far * (z_view - camera.near) / (z_view * (camera.far - camera.near));
        if depth < 1.0 - FAR_DEPTH_BAND {
            return Candidate::Hole;
        }
    }
    // Along the ray up to that hit (or the far plane), over the map and
    // below the terrain's top: a place with no triangle, or the ray under
    // the surface (it got there through a slit, since it met nothing).
    let end = hit.map_or(t_far, |h| h.t);
    let ground = (dir.x * dir.x + dir.y * dir.y).sqrt();
    let dt = if ground > 0.0 {
        domain.step / ground
    } else {
        end
    };
    let mut t = t_near;
    while t < end {
        let p = camera.eye + dir * t;
        if p.z <= domain.top && domain.contains(p) {
            match surface.height_at(p.x, p.y) {
                None => return Candidate::Hole,
                Some(h) if p.z < h => return Candidate::Hole,
                Some(_) => {}
            }
        }
        // Past the top with the ray rising: nothing more to meet.
        if p.z > domain.top && dir.z >= 0.0 {
            break;
        }
        t += dt;
    }
    if hit.is_some() {
        Candidate::FarDepth
    } else {
        Candidate::LodSky
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn all_is_every_scheme_but_brute_force_with_both_clipmap_layouts_and_centres() {
        assert_eq!(
            all(),
            [
                "clipmap/strips",
                "clipmap/footprints",
                "clipmap/view",
                "geomipmap",
                "roam",
                "cdlod",
                "annulus",
                "cbt"
            ]
        );
    }

    /// A flat 4×4-cell grid of 1 m cells at height 0 (two triangles a
    /// cell), optionally without one triangle or with its right half
    /// raised, seen from above and to the south-west.
    fn grid(skip: Option<usize>, step_up: f64) -> Surface {
        let mut tris = vec![];
        for y in 0..4 {
            for x in 0..4 {
                let (x, y) = (x as f64, y as f64);
                // The last column of cells is raised: it does not share the
                // line x = 3 with the low cells (a slit, as an unstitched
                // T-junction leaves: two surfaces over one line).
                let zl = if x >= 3.0 { step_up } else { 0.0 };
                let a = DVec3::new(x, y, zl);
                let b = DVec3::new(x + 1.0, y, zl);
                let c = DVec3::new(x + 1.0, y + 1.0, zl);
                let d = DVec3::new(x, y + 1.0, zl);
                tris.push([a, b, c]);
                tris.push([a, c, d]);
            }
        }
        if let Some(k) = skip {
            tris.remove(k);
        }
        Surface::from_triangles(DVec3::ZERO, tris)
    }

    fn camera() -> Camera {
        Camera {
            eye: DVec3::new(-3.0, -3.0, 3.0),
            target: DVec3::new(2.0, 2.0, 0.0),
            fov_y_deg: 60.0,
            near: 0.01,
            far: 100.0,
            aspect: 1.0,
        }
    }

    fn domain() -> Domain {
        Domain {
            rect: [0.0, 0.0, 4.0, 4.0],
            top: 2.0,
            step: 0.25,
        }
    }

    #[test]
    fn a_ray_that_meets_the_surface_is_a_hole() {
        let cam = camera();
        let dir = (DVec3::new(1.5, 1.5, 0.0) - cam.eye).normalize();
        assert_eq!(
            classify(&grid(None, 0.0), &cam, dir, &domain()),
            Candidate::Hole
        );
    }

    /// The same ray with a near plane so close that every depth past it
    /// lies within 16 ULP of 1.0: the surface is there but no depth buffer
    /// keeps it.
    #[test]
    fn a_surface_at_the_far_planes_depth_is_far_depth() {
        let mut cam = camera();
        cam.near = 1e-7;
        let dir = (DVec3::new(1.5, 1.5, 0.0) - cam.eye).normalize();
        let s = grid(None, 0.0);
        assert_eq!(classify(&s, &cam, dir, &domain()), Candidate::FarDepth);
        cam.near = 0.01;
        assert_eq!(classify(&s, &cam, dir, &domain()), Candidate::Hole);
    }

    #[test]
    fn a_removed_triangle_is_a_hole() {
        let cam = camera();
        // Triangle 2·(4·1 + 1) + 1 is the upper half of cell (1, 1); aim
        // at its centroid and drop it: the ray meets the cell below it?
        // No cell is below, so only the coverage walk finds the hole.
        let k = 2 * (4 + 1) + 1;
        let centre = DVec3::new(1.0 + 1.0 / 3.0, 1.0 + 2.0 / 3.0, 0.0);
        let dir = (centre - cam.eye).normalize();
        let s = grid(Some(k), 0.0);
        assert!(s.height_at(centre.x, centre.y).is_none());
        assert_eq!(classify(&s, &cam, dir, &domain()), Candidate::Hole);
    }

    #[test]
    fn a_slit_between_two_heights_is_a_hole() {
        // Low cells up to x = 3 at height 0, the last column at 1: a ray
        // through the vertical slit at x = 3, between heights 0 and 1, ends
        // inside the raised column, which it meets.
        let cam = camera();
        let slit = DVec3::new(3.0, 2.0, 0.5);
        let dir = (slit - cam.eye).normalize();
        assert_eq!(
            classify(&grid(None, 1.0), &cam, dir, &domain()),
            Candidate::Hole
        );
    }

    #[test]
    fn sky_above_the_surface_everywhere_is_an_lod_difference() {
        let cam = camera();
        // Level over the grid at a height of 1.5: above everything.
        let dir = (DVec3::new(6.0, 6.0, 1.5) - cam.eye).normalize();
        let s = grid(None, 1.0);
        assert_eq!(classify(&s, &cam, dir, &domain()), Candidate::LodSky);
        // Straight up.
        assert_eq!(classify(&s, &cam, DVec3::Z, &domain()), Candidate::LodSky);
    }

    fn part(surveyed: usize, cracks: usize, lod: &str) -> CrackReport {
        let scheme = SchemeCracks {
            lod: lod.into(),
            crack_pixels: cracks,
            lod_sky_pixels: 1,
            far_depth_pixels: 0,
            triangles: 7,
            views_with_cracks: usize::from(cracks > 0),
            views_with_lod_sky: 1,
            worst_view: surveyed,
            worst_pixels: cracks,
            worst_camera: [0.0; 6],
            worst_images: None,
        };
        report(10, surveyed, vec![scheme]).unwrap()
    }

    #[test]
    fn merged_parts_sum_and_refuse_what_cannot_be_summed() {
        let m = merge(&[part(5, 3, "clipmap"), part(5, 7, "clipmap")]).unwrap();
        assert_eq!((m.views, m.views_surveyed, m.crack_pixels), (10, 10, 10));
        assert_eq!((m.lod_sky_pixels, m.schemes[0].views_with_cracks), (2, 2));
        assert_eq!(m.schemes[0].worst_view, 5);
        let big = part(5, usize::MAX, "clipmap");
        let e = merge(&[part(5, 3, "clipmap"), big]).unwrap_err();
        assert!(e.contains("largest whole number"), "{e}");
        let e = merge(&[part(5, 3, "clipmap"), part(5, 3, "roam")]).unwrap_err();
        assert!(e.contains("part 1"), "{e}");
    }
}
