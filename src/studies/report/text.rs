//! Text for charts and diagrams. tiny-skia fills shapes but sets no type,
//! so glyph outlines of DejaVu Sans (embedded by the `dejavu` crate) are
//! read with `ab_glyph` and filled as tiny-skia paths: text is then
//! antialiased like the lines around it, takes any transform (the rotated
//! y-axis label), and looks the same on every machine.

use ab_glyph::{Font, FontRef, OutlineCurve};
use std::sync::OnceLock;
use tiny_skia::{FillRule, Paint, PathBuilder, Pixmap, Transform};

/// Where the reference point sits along the text.
#[derive(Clone, Copy, PartialEq, Debug)]
pub enum Anchor {
    /// The text starts at the point.
    Start,
    /// The text is centred on the point.
    Middle,
    /// The text ends at the point.
    End,
}

/// The embedded face and its cap height in font units.
struct Face {
    font: FontRef<'static>,
    cap: f32,
}

fn face() -> Option<&'static Face> {
    static FACE: OnceLock<Option<Face>> = OnceLock::new();
    FACE.get_or_init(|| {
        let font = FontRef::try_from_slice(dejavu::sans::regular()).ok()?;
        // Font units are y-up, so the top of "H" is its bounds' min.y.
        let cap = font.outline(font.glyph_id('H'))?.bounds.min.y;
        (cap > 0.0).then_some(Face { font, cap })
    })
    .as_ref()
}

/// The advance width in pixels of `s` at cap height `size`, with kerning.
pub fn width(s: &str, size: f32) -> f32 {
    let Some(f) = face() else { return 0.0 };
    let k = size / f.cap;
    let mut w = 0.0;
    let mut prev = None;
    for c in s.chars() {
        let id = f.font.glyph_id(c);
        if let Some(p) = prev {
            w += f.font.kern_unscaled(p, id);
        }
        w += f.font.h_advance_unscaled(id);
        prev = Some(id);
    }
    w * k
}

/// The outlines of `s` at cap height `size` pixels, baseline on y = 0 and
/// starting at x = 0, y down; `None` for text with no ink (blanks).
pub fn path(s: &str, size: f32) -> Option<tiny_skia::Path> {
    let f = face()?;
    let k = size / f.cap;
    let mut pb = PathBuilder::new();
    let (mut pen, mut prev) = (0.0f32, None);
    for c in s.chars() {
        let id = f.font.glyph_id(c);
        if let Some(p) = prev {
            pen += f.font.kern_unscaled(p, id);
        }
        prev = Some(id);
        let at = |p: ab_glyph::Point| ((pen + p.x) * k, -p.y * k);
        if let Some(o) = f.font.outline(id) {
            // Curves come in contour order; a curve that does not start
            // where the last ended opens the next contour.
            let mut last = None;
            for curve in &o.curves {
                let (start, end) = match *curve {
                    OutlineCurve::Line(a, b) => (a, b),
                    OutlineCurve::Quad(a, _, b) => (a, b),
                    OutlineCurve::Cubic(a, _, _, b) => (a, b),
                };
                if last != Some(start) {
                    if last.is_some() {
                        pb.close();
                    }
                    let (x, y) = at(start);
                    pb.move_to(x, y);
                }
                match *curve {
                    OutlineCurve::Line(_, b) => {
                        let (x, y) = at(b);
                        pb.line_to(x, y);
                    }
                    OutlineCurve::Quad(_, c, b) => {
                        let ((cx, cy), (x, y)) = (at(c), at(b));
                        pb.quad_to(cx, cy, x, y);
                    }
                    OutlineCurve::Cubic(_, c0, c1, b) => {
                        let ((ax, ay), (bx, by), (x, y)) = (at(c0), at(c1), at(b));
                        pb.cubic_to(ax, ay, bx, by, x, y);
                    }
                }
                last = Some(end);
            }
            if last.is_some() {
                pb.close();
            }
        }
        pen += f.font.h_advance_unscaled(id);
    }
    pb.finish()
}

/// Draws `s` with its baseline through `p`, `size` pixels of cap height,
/// placed along the baseline by `anchor`; `vertical` turns it a quarter
/// anticlockwise about `p` (reading bottom to top).
pub fn draw(
    pm: &mut Pixmap,
    p: (f32, f32),
    s: &str,
    size: f32,
    anchor: Anchor,
    vertical: bool,
    rgb: [u8; 3],
) {
    let Some(path) = path(s, size) else { return };
    let shift = match anchor {
        Anchor::Start => 0.0,
        Anchor::Middle => -width(s, size) / 2.0,
        Anchor::End => -width(s, size),
    };
    let turn = if vertical {
        Transform::from_rotate(-90.0)
    } else {
        Transform::identity()
    };
    let tf = Transform::from_translate(p.0, p.1)
        .pre_concat(turn)
        .pre_translate(shift, 0.0);
    let mut paint = Paint::default();
    paint.set_color_rgba8(rgb[0], rgb[1], rgb[2], 255);
    paint.anti_alias = true;
    pm.fill_path(&path, &paint, FillRule::Winding, tf, None);
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ink(pm: &Pixmap) -> (usize, [u32; 4]) {
        let (mut n, mut b) = (0, [u32::MAX, u32::MAX, 0, 0]);
        for (i, px) in pm.pixels().iter().enumerate() {
            if px.alpha() > 0 {
                let (x, y) = (i as u32 % pm.width(), i as u32 / pm.width());
                n += 1;
                b = [b[0].min(x), b[1].min(y), b[2].max(x), b[3].max(y)];
            }
        }
        (n, b)
    }

    #[test]
    fn cap_height_and_width_are_the_fonts() {
        // "H" at cap height 20 px stands 20 px above the baseline.
        let mut pm = Pixmap::new(100, 60).unwrap();
        draw(
            &mut pm,
            (10.0, 40.0),
            "H",
            20.0,
            Anchor::Start,
            false,
            [0; 3],
        );
        let (_, b) = ink(&pm);
        assert_eq!((b[1], b[3]), (20, 39), "{b:?}");
        // DejaVu Sans: "H" advances 1,540 units of a 1,493-unit cap.
        assert!((width("H", 20.0) - 20.0 * 1540.0 / 1493.0).abs() < 1e-3);
        assert_eq!(width("HH", 20.0), 2.0 * width("H", 20.0));
        assert!(path(" ", 20.0).is_none());
    }

    #[test]
    fn anchors_and_rotation_place_the_text() {
        let w = width("level 0", 12.0);
        for (anchor, x0) in [(Anchor::Start, 100.0), (Anchor::Middle, 100.0 - w / 2.0)] {
            let mut pm = Pixmap::new(300, 300).unwrap();
            draw(
                &mut pm,
                (100.0, 150.0),
                "level 0",
                12.0,
                anchor,
                false,
                [0; 3],
            );
            let (n, b) = ink(&pm);
            assert!(n > 50);
            // The left side bearing of "l" is under 2 px at this size.
            assert!((b[0] as f32 - x0).abs() < 2.0, "{anchor:?}: {b:?}");
            assert!(b[3] <= 150);
        }
        // Turned: the ink runs up from the point, left of it.
        let mut pm = Pixmap::new(300, 300).unwrap();
        draw(
            &mut pm,
            (150.0, 200.0),
            "level 0",
            12.0,
            Anchor::Start,
            true,
            [0; 3],
        );
        let (_, b) = ink(&pm);
        assert!(
            b[2] <= 150 && b[3] <= 200 && b[1] as f32 >= 200.0 - w - 2.0,
            "{b:?}"
        );
    }
}
