//! Top-down diagrams of a clipmap (after Brettell fig. 3.2b): each level's
//! render region filled in its own colour, transition bands shaded, clip
//! regions outlined thin, active regions outlined thick, the usable map
//! bounds in grey and the viewer as a black dot with its view direction.
//! A panel to the right of the map is the key: each level with its grid
//! spacing in metres, what each shade and outline means, and a scale bar.

use crate::camera::Camera;
use crate::clipmap::{region, Clipmap};
use crate::error::{Error, Result};
use crate::frame::stats::Passes;
use crate::render::Session;
use crate::scene::{LodScheme, Scene};
use crate::studies::report::text::{self, Anchor};
use crate::terrain::world::WorldMap;
use tiny_skia::{Color, FillRule, Paint, PathBuilder, Pixmap, Rect as SkRect, Stroke, Transform};

/// Colour for level l (cycled), also used by the `level-tint` effect.
pub use crate::shade::level_tint::level_colour;

/// Opacity of a render region's fill, and of the transition band's shade
/// over it.
const FILL_ALPHA: u8 = 150;
const BAND_ALPHA: u8 = 40;
const INK: [u8; 3] = [40, 40, 40];
const FADED: [u8; 3] = [150, 150, 150];
const MAP_GREY: [u8; 3] = [120, 120, 120];

/// The scene's terrain in a clipmap session (whatever LOD scheme the scene
/// names: the diagram draws a clipmap over its terrain), moved to the
/// scene's camera. Built by [`Session::new`], so lazy pyramids and errors
/// behave as in `render`.
pub fn session(scene: &Scene) -> Result<Session> {
    let scene = scene.with_scheme(LodScheme::Clipmap, None)?;
    let mut passes = Passes::default();
    let mut s = Session::new(&scene, &mut passes)?;
    s.update(&scene.camera(), &mut passes);
    Ok(s)
}

/// One row of the key: a sample of the mark and what it stands for.
#[derive(Clone, Debug, PartialEq)]
pub enum Mark {
    /// A level: its colour, and whether it is active.
    Level(usize, bool),
    /// A render region's fill.
    Fill,
    /// The transition band's shade over the fill.
    Band,
    /// A clip region's thin outline in its level's colour.
    Clip,
    /// An active region's thick black outline.
    Active,
    /// The map bounds' grey outline.
    Map,
    /// The viewer and its view direction.
    Viewer,
    /// A section heading.
    Heading,
}

/// The key beside the map: rows of marks and labels, and the scale bar.
#[derive(Clone, Debug, PartialEq)]
pub struct Legend {
    /// Each row's mark and label, top to bottom.
    pub rows: Vec<(Mark, String)>,
    /// The scale bar's length in metres (1, 2 or 5 × 10^k), its label,
    /// and its length in pixels.
    pub scale_m: f64,
    /// The bar's length as a label ("2 km").
    pub scale_label: String,
    /// The bar's length in pixels.
    pub scale_px: f32,
}

/// A length in metres as a short label: "40 m", "1.28 km", "0.5 m".
pub fn metres(v: f64) -> String {
    let trim = |s: String| {
        if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            s
        }
    };
    if v.abs() >= 1000.0 {
        format!("{} km", trim(format!("{:.3}", v / 1000.0)))
    } else {
        format!("{} m", trim(format!("{v:.2}")))
    }
}

/// The largest 1, 2 or 5 × 10^k not above `max` (for `max` > 0).
fn round_down_125(max: f64) -> f64 {
    let p = 10f64.powf(max.log10().floor());
    [5.0, 2.0, 1.0]
        .into_iter()
        .map(|m| m * p)
        .find(|&v| v <= max * (1.0 + 1e-12))
        .unwrap_or(p)
}

impl Legend {
    /// The key of `cm` over `world`, with a scale bar of at most `bar_px`
    /// pixels at `px_per_texel` (the map's scale, finest-level texels).
    pub fn of(
        cm: &Clipmap,
        world: &WorldMap,
        viewer: bool,
        px_per_texel: f64,
        bar_px: f64,
    ) -> Legend {
        let levels = cm.levels();
        let active = levels.iter().filter(|l| l.is_active()).count();
        let mut rows = vec![(
            Mark::Heading,
            format!("{} levels, {active} active, n = {}", levels.len(), cm.n()),
        )];
        for (l, lv) in levels.iter().enumerate() {
            let g = lv.spacing() as f64;
            let [cx, cy] = world.cell;
            let spacing = if cx == cy {
                metres(cx * g)
            } else {
                format!("{} × {}", metres(cx * g), metres(cy * g))
            };
            let idle = if lv.is_active() { "" } else { " (inactive)" };
            rows.push((
                Mark::Level(l, lv.is_active()),
                format!("level {l}: {spacing} grid{idle}"),
            ));
        }
        rows.push((Mark::Heading, "regions".into()));
        rows.push((Mark::Fill, "render region".into()));
        if levels.iter().any(|l| l.morph.enabled) {
            rows.push((Mark::Band, "transition band (geomorph)".into()));
        }
        rows.push((Mark::Clip, "clip region".into()));
        rows.push((Mark::Active, "active region".into()));
        if cm.map_bounds().is_some() {
            rows.push((Mark::Map, "map bounds".into()));
        }
        if viewer && cm.viewer()[0].is_finite() {
            rows.push((Mark::Viewer, "viewer, view direction".into()));
        }
        let m_per_px = world.cell[0] / px_per_texel;
        let scale_m = round_down_125(bar_px * m_per_px);
        Legend {
            rows,
            scale_label: metres(scale_m),
            scale_px: (scale_m / m_per_px) as f32,
            scale_m,
        }
    }
}

fn paint(rgb: [u8; 3], a: u8) -> Paint<'static> {
    let mut p = Paint::default();
    p.set_color_rgba8(rgb[0], rgb[1], rgb[2], a);
    p.anti_alias = true;
    p
}

fn stroke(width: f32) -> Stroke {
    Stroke {
        width,
        ..Stroke::default()
    }
}

/// Fills `rects` as one path. Filled one by one, two rectangles that share
/// an edge between pixel centres each cover the edge pixels partly, and
/// blending the two partial, translucent covers leaves a visible seam along
/// the edge; one path covers them once.
pub fn fill_rects(
    pm: &mut Pixmap,
    rects: &[SkRect],
    paint: &Paint,
    tf: Transform,
    mask: Option<&tiny_skia::Mask>,
) {
    let mut pb = PathBuilder::new();
    for r in rects {
        pb.push_rect(*r);
    }
    if let Some(path) = pb.finish() {
        pm.fill_path(&path, paint, FillRule::Winding, tf, mask);
    }
}

/// Draws the diagram: the map in a `size`×`size` square (the camera's view
/// direction when given) and the key to its right. Returns PNG bytes.
pub fn draw(cm: &Clipmap, world: &WorldMap, camera: Option<&Camera>, size: u32) -> Result<Vec<u8>> {
    let bad = |r: &str| Error::value("diagram", r.to_string());
    let levels = cm.levels();
    // Frame the map and everything rendered; coarse clip windows that
    // reach far beyond the map are cut at the map's border.
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
    let side = size as f32;
    let span = bounds.width().max(bounds.height()) as f32;
    let scale = side * 0.94 / span;
    let off = side * 0.03;
    // The key's type size follows the image; 6 px is the least readable.
    let cap = (side / 64.0).max(6.0);
    let row_h = 2.0 * cap;
    let swatch = 1.6 * cap;
    let margin = 1.5 * cap;
    let bar_max = 12.0 * cap;
    let legend = Legend::of(cm, world, camera.is_some(), scale as f64, bar_max as f64);
    let text_w = legend
        .rows
        .iter()
        .map(|(_, s)| text::width(s, cap))
        .fold(0.0f32, f32::max);
    let panel = (margin + swatch + cap + text_w + margin).max(bar_max + 2.0 * margin);
    let rows_h = margin + row_h * (legend.rows.len() as f32 + 3.0) + margin;
    let width = size + panel.ceil() as u32;
    let height = size.max(rows_h.ceil() as u32);
    let mut pm = Pixmap::new(width, height).ok_or_else(|| bad("image size must be > 0"))?;
    pm.fill(Color::WHITE);
    let tf = Transform::from_row(
        scale,
        0.0,
        0.0,
        scale,
        off - bounds.x0 as f32 * scale,
        off - bounds.y0 as f32 * scale,
    );
    // Grid rectangles are drawn inside the map's square only.
    let frame = SkRect::from_xywh(0.0, 0.0, side, side).ok_or_else(|| bad("empty map"))?;
    let mut clip = tiny_skia::Mask::new(width, height).ok_or_else(|| bad("empty map"))?;
    clip.fill_path(
        &PathBuilder::from_rect(frame),
        FillRule::Winding,
        false,
        Transform::identity(),
    );
    let rect = |r: &region::Rect| {
        SkRect::from_ltrb(r.x0 as f32, r.y0 as f32, r.x1 as f32, r.y1 as f32)
            .ok_or_else(|| bad("degenerate region"))
    };
    let outline = |pm: &mut Pixmap, r: &region::Rect, rgb, width: f32| -> Result<()> {
        let path = PathBuilder::from_rect(rect(r)?);
        pm.stroke_path(
            &path,
            &paint(rgb, 255),
            &stroke(width / scale),
            tf,
            Some(&clip),
        );
        Ok(())
    };
    let regions: Vec<_> = levels.iter().map(|l| l.regions).collect();
    for (l, lv) in levels.iter().enumerate().rev() {
        let rects = region::render_rects(&regions, l)
            .iter()
            .map(rect)
            .collect::<Result<Vec<_>>>()?;
        let fill = paint(level_colour(l), FILL_ALPHA);
        fill_rects(&mut pm, &rects, &fill, tf, Some(&clip));
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
                let shade = paint([0, 0, 0], BAND_ALPHA);
                pm.fill_path(&path, &shade, FillRule::EvenOdd, tf, Some(&clip));
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
        outline(&mut pm, &m, MAP_GREY, 3.0)?;
    }
    let v = cm.viewer();
    if v[0].is_finite() {
        let (vx, vy) = (v[0] as f32, v[1] as f32);
        if let Some(cam) = camera {
            let t = world.to_grid(cam.target);
            let d = [t[0] as f32 - vx, t[1] as f32 - vy];
            let len = (d[0] * d[0] + d[1] * d[1]).sqrt().max(1e-6);
            let reach = span * 0.08;
            let mut pb = PathBuilder::new();
            pb.move_to(vx, vy);
            pb.line_to(vx + d[0] / len * reach, vy + d[1] / len * reach);
            if let Some(path) = pb.finish() {
                let ink = paint([0, 0, 0], 255);
                pm.stroke_path(&path, &ink, &stroke(3.0 / scale), tf, Some(&clip));
            }
        }
        if let Some(c) = PathBuilder::from_circle(vx, vy, 5.0 / scale) {
            let ink = paint([0, 0, 0], 255);
            pm.fill_path(&c, &ink, FillRule::Winding, tf, Some(&clip));
        }
    }
    draw_legend(&mut pm, &legend, side, cap);
    pm.encode_png()
        .map_err(|e| Error::value("diagram", format!("PNG encoding failed: {e}")))
}

/// The key in the panel that starts at x = `x0`, in type of cap height
/// `cap`: each row's mark in a swatch, its label, then the scale bar.
fn draw_legend(pm: &mut Pixmap, legend: &Legend, x0: f32, cap: f32) {
    let (row_h, sw, margin) = (2.0 * cap, 1.6 * cap, 1.5 * cap);
    let left = x0 + margin;
    let mut y = margin + row_h;
    let sample = |l: usize| paint(level_colour(l), FILL_ALPHA);
    for (mark, label) in &legend.rows {
        let top = y - cap - (sw - cap) / 2.0;
        let sq = SkRect::from_xywh(left, top, sw, sw);
        let id = Transform::identity();
        let framed = |pm: &mut Pixmap, rgb, w| {
            if let Some(r) = sq {
                pm.stroke_path(
                    &PathBuilder::from_rect(r),
                    &paint(rgb, 255),
                    &stroke(w),
                    id,
                    None,
                );
            }
        };
        let filled = |pm: &mut Pixmap, p: &Paint| {
            if let Some(r) = sq {
                pm.fill_rect(r, p, id, None);
            }
        };
        let mut colour = INK;
        match mark {
            Mark::Heading => {}
            Mark::Level(l, active) => {
                filled(pm, &sample(*l));
                if !active {
                    colour = FADED;
                }
            }
            Mark::Fill => filled(pm, &sample(0)),
            Mark::Band => {
                filled(pm, &sample(0));
                filled(pm, &paint([0, 0, 0], BAND_ALPHA));
            }
            Mark::Clip => framed(pm, level_colour(0), 1.0),
            Mark::Active => framed(pm, [0, 0, 0], 2.0),
            Mark::Map => framed(pm, MAP_GREY, 3.0),
            Mark::Viewer => {
                let (cx, cy) = (left + sw * 0.3, top + sw * 0.6);
                let mut pb = PathBuilder::new();
                pb.move_to(cx, cy);
                pb.line_to(left + sw, top);
                if let Some(p) = pb.finish() {
                    pm.stroke_path(&p, &paint([0, 0, 0], 255), &stroke(2.0), id, None);
                }
                if let Some(c) = PathBuilder::from_circle(cx, cy, sw * 0.22) {
                    pm.fill_path(&c, &paint([0, 0, 0], 255), FillRule::Winding, id, None);
                }
            }
        }
        let tx = if *mark == Mark::Heading {
            left
        } else {
            left + sw + cap
        };
        text::draw(pm, (tx, y), label, cap, Anchor::Start, false, colour);
        y += row_h;
    }
    // The scale bar: a bar with end ticks, its length under it.
    let y = y + row_h;
    let ink = paint([0, 0, 0], 255);
    let mut pb = PathBuilder::new();
    pb.move_to(left, y - cap * 0.6);
    pb.line_to(left, y);
    pb.line_to(left + legend.scale_px, y);
    pb.line_to(left + legend.scale_px, y - cap * 0.6);
    if let Some(p) = pb.finish() {
        pm.stroke_path(&p, &ink, &stroke(2.0), Transform::identity(), None);
    }
    let label_at = (left + legend.scale_px / 2.0, y + row_h);
    text::draw(
        pm,
        label_at,
        &legend.scale_label,
        cap,
        Anchor::Middle,
        false,
        INK,
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lengths_read_as_metres_and_kilometres() {
        assert_eq!(metres(40.0), "40 m");
        assert_eq!(metres(0.5), "0.5 m");
        assert_eq!(metres(1280.0), "1.28 km");
        assert_eq!(metres(2000.0), "2 km");
        assert_eq!(round_down_125(740.0), 500.0);
        assert_eq!(round_down_125(199.0), 100.0);
        assert_eq!(round_down_125(2.0), 2.0);
        assert_eq!(round_down_125(0.09), 0.05);
    }

    #[test]
    fn rectangles_sharing_an_edge_leave_no_seam() {
        // Two halves of one rectangle meet at y = 10.5, between pixel
        // centres; the row there must be the same colour as the rows
        // around it.
        let mut pm = Pixmap::new(20, 21).unwrap();
        pm.fill(Color::WHITE);
        let rects = [
            SkRect::from_ltrb(0.0, 0.0, 20.0, 10.5).unwrap(),
            SkRect::from_ltrb(0.0, 10.5, 20.0, 21.0).unwrap(),
        ];
        let orange = paint([245, 130, 48], FILL_ALPHA);
        fill_rects(&mut pm, &rects, &orange, Transform::identity(), None);
        let at = |y: u32| pm.pixel(5, y).unwrap();
        assert_eq!(at(10), at(5));
        assert_eq!(at(10), at(15));
    }

    #[test]
    fn the_bench_scene_has_a_key_for_every_level_and_mark() {
        let scene = Scene::bench_scene();
        let session = session(&scene).unwrap();
        let cm = session.lod.clipmap().unwrap();
        let png = draw(cm, &session.world, Some(&scene.camera()), 800).unwrap();
        let img = image::load_from_memory(&png).unwrap().to_rgba8();
        // The map's 800 px square, then the key's panel.
        assert_eq!(img.height(), 800);
        let panel = img.width() - 800;
        assert!((200..400).contains(&panel), "{panel}");
        // Dark text pixels in the panel: the key is drawn.
        let ink = (800..img.width())
            .flat_map(|x| (0..800).map(move |y| (x, y)))
            .filter(|&(x, y)| img.get_pixel(x, y).0[0] < 100)
            .count();
        assert!(ink > 2000, "{ink}");
        // 10 m cells; at 800 px the map is 0.94 × 800 px over the bounds.
        let scale = 0.94 * 800.0 / 1056.0;
        let legend = Legend::of(cm, &session.world, true, scale, 12.0 * 12.5);
        let rows: Vec<&str> = legend.rows.iter().map(|(_, s)| s.as_str()).collect();
        assert_eq!(
            rows,
            [
                "7 levels, 7 active, n = 63",
                "level 0: 10 m grid",
                "level 1: 20 m grid",
                "level 2: 40 m grid",
                "level 3: 80 m grid",
                "level 4: 160 m grid",
                "level 5: 320 m grid",
                "level 6: 640 m grid",
                "regions",
                "render region",
                "transition band (geomorph)",
                "clip region",
                "active region",
                "map bounds",
                "viewer, view direction",
            ]
        );
        // 150 px at 10 m ÷ 0.712 px per cell is 2,107 m: a 2 km bar.
        assert_eq!(
            (legend.scale_m, legend.scale_label.as_str()),
            (2000.0, "2 km")
        );
        assert!((legend.scale_px - 2000.0 / 10.0 * scale as f32).abs() < 1e-3);
    }
}
