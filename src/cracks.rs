//! The crack survey: renders over a red background from many random views
//! and counts background pixels enclosed by terrain that a brute-force
//! render of the same view covers ([`metrics::crack_pixels`]), for any LOD
//! scheme. Brute-force renders are shared by all schemes of one run.

use crate::error::Result;
use crate::metrics;
use crate::render::{Image, RenderOptions, Session};
use crate::scene::Scene;
use crate::stats::Passes;
use crate::views;
use serde::Serialize;

/// Schemes `--lod all` surveys (brute force is the reference).
pub const ALL: &[&str] = &[
    "clipmap/strips",
    "clipmap/footprints",
    "geomipmap",
    "roam",
    "cdlod",
    "annulus",
];

#[derive(Clone, Debug, Serialize)]
pub struct SchemeCracks {
    pub lod: String,
    pub crack_pixels: usize,
    /// Views with at least one crack pixel.
    pub views_with_cracks: usize,
    pub worst_view: usize,
    pub worst_pixels: usize,
    /// The worst view's eye and look-at point (for `render --camera
    /// --look-at`).
    pub worst_camera: [f64; 6],
    /// The worst view's render and its brute-force reference.
    #[serde(skip)]
    pub worst_images: Option<(Image, Image)>,
}

#[derive(Clone, Debug, Serialize)]
pub struct CrackReport {
    pub views: usize,
    /// Over all surveyed schemes.
    pub crack_pixels: usize,
    pub worst_view: usize,
    pub schemes: Vec<SchemeCracks>,
}

/// The scene prepared for the survey: red background, no shading effects
/// (colour is the height ramp), morph kept as the scene says.
pub fn survey_scene(scene: &Scene, size: [u32; 2]) -> Scene {
    let mut s = scene.clone();
    s.image.background = [1.0, 0.0, 0.0];
    s.image.width = size[0];
    s.image.height = size[1];
    s.effects.retain(|e| e == "morph");
    s
}

/// Surveys `schemes` over `count` random views; `tick` is called after
/// each view.
pub fn survey(
    scene: &Scene,
    schemes: &[String],
    count: usize,
    size: [u32; 2],
    mut tick: impl FnMut(),
) -> Result<CrackReport> {
    let base = survey_scene(scene, size);
    let opts = RenderOptions::default();
    let mut brute = Session::new(&base.with_lod("brute-force")?, &mut Passes::default())?;
    let mut sessions = schemes
        .iter()
        .map(|s| Session::new(&base.with_lod(s)?, &mut Passes::default()))
        .collect::<Result<Vec<_>>>()?;
    let cams = views::random_views(&brute, &base.camera(), count, 0x5EED_CAFE);
    let mut out: Vec<SchemeCracks> = schemes
        .iter()
        .map(|s| SchemeCracks {
            lod: s.clone(),
            crack_pixels: 0,
            views_with_cracks: 0,
            worst_view: 0,
            worst_pixels: 0,
            worst_camera: [0.0; 6],
            worst_images: None,
        })
        .collect();
    for (i, cam) in cams.iter().enumerate() {
        let (reference, _) = brute.render(cam, &opts, Passes::default())?;
        for (s, r) in sessions.iter_mut().zip(out.iter_mut()) {
            let (img, _) = s.render(cam, &opts, Passes::default())?;
            let c = metrics::crack_pixels(&img, &reference, [255, 0, 0]);
            r.crack_pixels += c;
            r.views_with_cracks += usize::from(c > 0);
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
    let worst = out.iter().max_by_key(|r| r.worst_pixels);
    Ok(CrackReport {
        views: count,
        crack_pixels: out.iter().map(|r| r.crack_pixels).sum(),
        worst_view: worst.map_or(0, |r| r.worst_view),
        schemes: out,
    })
}
