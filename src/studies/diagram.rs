//! Top-down diagrams of a clipmap (after Brettell fig. 3.2b): each level's
//! render region filled in its own colour, transition bands shaded, clip
//! regions outlined thin, active regions outlined thick, the usable map
//! bounds in grey and the viewer as a black dot with its view direction.

use crate::clipmap::{region, Clipmap, ClipmapConfig};
use crate::error::{Error, Result};
use crate::lod::LodConfig;
use crate::pyramid::Pyramid;
use crate::scene::camera::Camera;
use crate::scene::{Effect, Scene};
use crate::terrain::world::WorldMap;
use glam::DVec3;
use std::sync::Arc;
use tiny_skia::{Color, FillRule, Paint, PathBuilder, Pixmap, Rect as SkRect, Stroke, Transform};

/// Colour for level l (cycled), also used by the `level-tint` effect.
pub use crate::shade::level_tint::level_colour;

/// The scene's clipmap, built (heightmap, pyramid, clipmap) and updated for
/// its camera, with the world placement the diagram draws in.
pub fn clipmap(scene: &Scene) -> Result<(Clipmap, WorldMap)> {
    let build = || -> Result<(Clipmap, WorldMap)> {
        let h = crate::terrain::load(&scene.terrain, &scene.base_dir)?;
        let world = WorldMap::for_terrain(&scene.terrain, h.cell_size);
        let cfg = ClipmapConfig::from_spec(&scene.lod, scene.has(Effect::Morph));
        let levels = LodConfig::Clipmap(cfg.clone()).pyramid_levels(h.width(), h.height());
        let pyramid = Arc::new(Pyramid::build(&h, scene.pyramid.filter, levels));
        let mut cm = Clipmap::new(pyramid, cfg)?;
        cm.update(world.to_grid(DVec3::from_array(scene.camera.position)));
        Ok((cm, world))
    };
    build().map_err(|e| scene.named(e))
}

/// Draws the diagram at `size`×`size` pixels and returns PNG bytes.
pub fn draw(cm: &Clipmap, camera: Option<(&Camera, &WorldMap)>, size: u32) -> Result<Vec<u8>> {
    let bad = |r: &str| Error::value("diagram", r.to_string());
    let mut pm = Pixmap::new(size, size).ok_or_else(|| bad("image size must be > 0"))?;
    pm.fill(Color::WHITE);
    let levels = cm.levels();
    // Frame the map and everything rendered; coarse clip windows that
    // reach far beyond the map are cut at the image border.
    let bounds = levels
        .iter()
        .filter_map(|l| l.regions.active)
        .chain(cm.map_bounds())
        .reduce(|a, b| {
            region::Rect::new(
                a.x0.min(b.x0),
                a.y0.min(b.y0),
                a.x1.max(b.x1),
                a.y1.max(b.y1),
            )
        })
        .ok_or_else(|| bad("clipmap has no active level"))?;
    let span = bounds.width().max(bounds.height()) as f32;
    let scale = size as f32 * 0.94 / span;
    let off = size as f32 * 0.03;
    let tf = Transform::from_row(
        scale,
        0.0,
        0.0,
        scale,
        off - bounds.x0 as f32 * scale,
        off - bounds.y0 as f32 * scale,
    );
    let paint = |rgb: [u8; 3], a: u8| {
        let mut p = Paint::default();
        p.set_color_rgba8(rgb[0], rgb[1], rgb[2], a);
        p.anti_alias = true;
        p
    };
    let rect = |r: &region::Rect| {
        SkRect::from_ltrb(r.x0 as f32, r.y0 as f32, r.x1 as f32, r.y1 as f32)
            .ok_or_else(|| bad("degenerate region"))
    };
    let outline = |pm: &mut Pixmap, r: &region::Rect, rgb, width: f32| -> Result<()> {
        let path = PathBuilder::from_rect(rect(r)?);
        let stroke = Stroke {
            width: width / scale,
            ..Stroke::default()
        };
        pm.stroke_path(&path, &paint(rgb, 255), &stroke, tf, None);
        Ok(())
    };
    let regions: Vec<_> = levels.iter().map(|l| l.regions).collect();
    for (l, lv) in levels.iter().enumerate().rev() {
        for r in region::render_rects(&regions, l) {
            pm.fill_rect(rect(&r)?, &paint(level_colour(l), 150), tf, None);
        }
        // Transition band: where α > 0, i.e. beyond half − w − 1 texels from
        // the viewer, inside the active region.
        if let (true, Some(a)) = (lv.morph.enabled, lv.regions.active) {
            let g = lv.spacing() as f32;
            let o = lv.regions.origin;
            let t = lv.morph.half - lv.morph.width - 1.0;
            let inner = [
                (o[0] as f32 + lv.morph.viewer[0] - t) * g,
                (o[1] as f32 + lv.morph.viewer[1] - t) * g,
                (o[0] as f32 + lv.morph.viewer[0] + t) * g,
                (o[1] as f32 + lv.morph.viewer[1] + t) * g,
            ];
            let mut pb = PathBuilder::new();
            pb.push_rect(rect(&a)?);
            let clipped = SkRect::from_ltrb(
                inner[0].max(a.x0 as f32),
                inner[1].max(a.y0 as f32),
                inner[2].min(a.x1 as f32),
                inner[3].min(a.y1 as f32),
            );
            if let Some(ir) = clipped {
                pb.push_rect(ir);
            }
            if let Some(path) = pb.finish() {
                pm.fill_path(&path, &paint([0, 0, 0], 40), FillRule::EvenOdd, tf, None);
            }
        }
    }
    for (l, lv) in levels.iter().enumerate() {
        outline(&mut pm, &lv.regions.clip, level_colour(l), 1.0)?;
        if let Some(a) = lv.regions.active {
            outline(&mut pm, &a, [0, 0, 0], 2.0)?;
        }
    }
    if let Some(m) = cm.map_bounds() {
        outline(&mut pm, &m, [120, 120, 120], 3.0)?;
    }
    let v = cm.viewer();
    if v[0].is_finite() {
        let (vx, vy) = (v[0] as f32, v[1] as f32);
        if let Some((cam, world)) = camera {
            let t = world.to_grid(cam.target);
            let d = [t[0] as f32 - vx, t[1] as f32 - vy];
            let len = (d[0] * d[0] + d[1] * d[1]).sqrt().max(1e-6);
            let reach = span * 0.08;
            let mut pb = PathBuilder::new();
            pb.move_to(vx, vy);
            pb.line_to(vx + d[0] / len * reach, vy + d[1] / len * reach);
            if let Some(path) = pb.finish() {
                let stroke = Stroke {
                    width: 3.0 / scale,
                    ..Stroke::default()
                };
                pm.stroke_path(&path, &paint([0, 0, 0], 255), &stroke, tf, None);
            }
        }
        if let Some(c) = PathBuilder::from_circle(vx, vy, 5.0 / scale) {
            pm.fill_path(&c, &paint([0, 0, 0], 255), FillRule::Winding, tf, None);
        }
    }
    pm.encode_png()
        .map_err(|e| Error::value("diagram", format!("PNG encoding failed: {e}")))
}
