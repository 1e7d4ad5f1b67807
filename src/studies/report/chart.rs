//! Scatter charts of error against time: one series per scheme, log time
//! axis, labelled axes and ticks, the Pareto front drawn as a dashed line.
//! The chart is drawn once through a small [`Canvas`] trait, which an SVG
//! writer and a tiny-skia PNG both implement, so the two files always show
//! the same thing.

pub use super::text::Anchor;
use crate::error::{Error, Result};

/// One named series of (x, y) points.
#[derive(Clone, Debug)]
pub struct Series {
    /// The legend's name.
    pub name: String,
    /// (x, y) in the axes' units.
    pub points: Vec<(f64, f64)>,
}

/// A scatter chart: series, axes, and the front drawn dashed.
#[derive(Clone, Debug)]
pub struct Chart {
    /// The line above the plot.
    pub title: String,
    /// The x axis's label, with its unit.
    pub x_label: String,
    /// The y axis's label, with its unit.
    pub y_label: String,
    /// The points, a colour and legend entry per series.
    pub series: Vec<Series>,
    /// Points of the Pareto front, in x order.
    pub front: Vec<(f64, f64)>,
    /// A linear x axis from 0 (a quantity per frame against the frame)
    /// instead of the log axis of times.
    pub linear_x: bool,
}

const W: f64 = 960.0;
const H: f64 = 600.0;
const LEFT: f64 = 80.0;
const RIGHT: f64 = 220.0;
const TOP: f64 = 50.0;
const BOTTOM: f64 = 70.0;

/// Series colours: Okabe–Ito's (colour-blind friendly) with grey for its
/// yellow, then Okabe–Ito's yellow and three of Paul Tol's muted scheme
/// (wine, green, olive), so that a chart of up to twelve series (the pack
/// bench draws ten) gives each its own colour.
const COLOURS: [[u8; 3]; 12] = [
    [0, 0, 0],
    [230, 159, 0],
    [86, 180, 233],
    [0, 158, 115],
    [213, 94, 0],
    [0, 114, 178],
    [204, 121, 167],
    [120, 120, 120],
    [240, 228, 66],
    [136, 34, 85],
    [17, 119, 51],
    [153, 153, 51],
];

/// What the chart needs from an output format.
pub trait Canvas {
    /// A line from `a` to `b`, `width` pixels wide.
    fn line(&mut self, a: (f64, f64), b: (f64, f64), rgb: [u8; 3], width: f64, dashed: bool);
    /// A circle of radius `r` at `c`.
    fn circle(&mut self, c: (f64, f64), r: f64, rgb: [u8; 3], filled: bool);
    /// Text with its baseline at `p`; `size` is the cap height in pixels.
    fn text(&mut self, p: (f64, f64), s: &str, size: f64, anchor: Anchor, vertical: bool);
}

/// Tick values for a log axis over [lo, hi]: 1, 2, 5 × powers of ten.
fn log_ticks(lo: f64, hi: f64) -> Vec<f64> {
    let mut out = Vec::new();
    let mut p = 10f64.powf(lo.log10().floor());
    while p <= hi * 1.0001 {
        for m in [1.0, 2.0, 5.0] {
            let v = p * m;
            if v >= lo * 0.9999 && v <= hi * 1.0001 {
                out.push(v);
            }
        }
        p *= 10.0;
    }
    out
}

/// About 6 round tick values over [lo, hi].
fn linear_ticks(lo: f64, hi: f64) -> Vec<f64> {
    let raw = (hi - lo) / 6.0;
    let mag = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 5.0, 10.0]
        .iter()
        .map(|m| m * mag)
        .find(|s| *s >= raw)
        .unwrap_or(mag * 10.0);
    let mut v = (lo / step).ceil() * step;
    let mut out = Vec::new();
    while v <= hi + step * 1e-9 {
        out.push(v);
        v += step;
    }
    out
}

fn label(v: f64) -> String {
    if v == 0.0 {
        "0".into()
    } else if v.abs() >= 100.0 {
        format!("{v:.0}")
    } else if v.abs() >= 1.0 {
        format!("{v:.1}").trim_end_matches(".0").to_string()
    } else {
        format!("{v:.3}").trim_end_matches('0').to_string()
    }
}

impl Chart {
    /// Draws the chart on `c` (W×H pixels).
    pub fn draw(&self, c: &mut dyn Canvas) {
        let pts = self.series.iter().flat_map(|s| s.points.iter());
        let (mut x0, mut x1, mut y1) = (f64::INFINITY, 0.0f64, 0.0f64);
        for &(x, y) in pts {
            if (x > 0.0 || self.linear_x && x >= 0.0) && x.is_finite() && y.is_finite() {
                x0 = x0.min(x);
                x1 = x1.max(x);
                y1 = y1.max(y);
            }
        }
        if !x0.is_finite() {
            (x0, x1) = (1.0, 10.0);
        }
        let y1 = if y1 > 0.0 { y1 * 1.1 } else { 1.0 };
        let (pw, ph) = (W - LEFT - RIGHT, H - TOP - BOTTOM);
        let (lx0, lx1) = match self.linear_x {
            true => (0.0, if x1 > 0.0 { x1 } else { 1.0 }),
            false => ((x0 / 1.5).log10(), (x1 * 1.5).log10()),
        };
        let linear = self.linear_x;
        let px = |x: f64| {
            let v = if linear { x } else { x.max(1e-12).log10() };
            LEFT + (v - lx0) / (lx1 - lx0) * pw
        };
        let py = |y: f64| TOP + ph - y / y1 * ph;
        let grey = [200, 200, 200];
        let ink = [40, 40, 40];
        let x_ticks = match linear {
            true => linear_ticks(lx0, lx1),
            false => log_ticks(10f64.powf(lx0), 10f64.powf(lx1)),
        };
        // Dense series (a value per frame) are drawn as lines alone.
        let dot = |n: usize| if n > 60 { 0.0 } else { 4.0 };
        // Frame, ticks and grid.
        for t in x_ticks {
            c.line((px(t), TOP), (px(t), TOP + ph), grey, 1.0, false);
            c.text(
                (px(t), TOP + ph + 18.0),
                &label(t),
                8.0,
                Anchor::Middle,
                false,
            );
        }
        for t in linear_ticks(0.0, y1) {
            c.line((LEFT, py(t)), (LEFT + pw, py(t)), grey, 1.0, false);
            c.text(
                (LEFT - 8.0, py(t) + 4.0),
                &label(t),
                8.0,
                Anchor::End,
                false,
            );
        }
        let corners = [
            (LEFT, TOP),
            (LEFT + pw, TOP),
            (LEFT + pw, TOP + ph),
            (LEFT, TOP + ph),
        ];
        for k in 0..4 {
            c.line(corners[k], corners[(k + 1) % 4], ink, 1.5, false);
        }
        c.text(
            (W / 2.0 - RIGHT / 2.0, 30.0),
            &self.title,
            12.0,
            Anchor::Middle,
            false,
        );
        c.text(
            (LEFT + pw / 2.0, H - 20.0),
            &self.x_label,
            10.0,
            Anchor::Middle,
            false,
        );
        c.text(
            (24.0, TOP + ph / 2.0),
            &self.y_label,
            10.0,
            Anchor::Middle,
            true,
        );
        // Pareto front.
        for w in self.front.windows(2) {
            c.line(
                (px(w[0].0), py(w[0].1)),
                (px(w[1].0), py(w[1].1)),
                ink,
                1.5,
                true,
            );
        }
        for &(x, y) in &self.front {
            c.circle((px(x), py(y)), 8.0, ink, false);
        }
        // Series and legend.
        for (i, s) in self.series.iter().enumerate() {
            let rgb = COLOURS[i % COLOURS.len()];
            let mut p: Vec<(f64, f64)> = s.points.clone();
            p.sort_by(|a, b| a.0.total_cmp(&b.0));
            for w in p.windows(2) {
                c.line(
                    (px(w[0].0), py(w[0].1)),
                    (px(w[1].0), py(w[1].1)),
                    rgb,
                    1.0,
                    false,
                );
            }
            if dot(p.len()) > 0.0 {
                for &(x, y) in &p {
                    c.circle((px(x), py(y)), dot(p.len()), rgb, true);
                }
            }
            let ly = TOP + 20.0 + 22.0 * i as f64;
            c.circle((W - RIGHT + 24.0, ly - 4.0), 4.0, rgb, true);
            c.text((W - RIGHT + 36.0, ly), &s.name, 8.0, Anchor::Start, false);
        }
        if !self.front.is_empty() {
            let ly = TOP + 20.0 + 22.0 * self.series.len() as f64;
            c.circle((W - RIGHT + 24.0, ly - 4.0), 8.0, ink, false);
            c.text(
                (W - RIGHT + 36.0, ly),
                "pareto front",
                8.0,
                Anchor::Start,
                false,
            );
        }
    }

    /// The chart as an SVG document.
    pub fn svg(&self) -> String {
        let mut s = SvgCanvas(String::new());
        self.draw(&mut s);
        format!(
            "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{W}\" height=\"{H}\" viewBox=\"0 0 {W} {H}\" font-family=\"DejaVu Sans, sans-serif\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n{}</svg>\n",
            s.0
        )
    }

    /// The chart as PNG bytes (tiny-skia, the same drawing as the SVG).
    pub fn png(&self) -> Result<Vec<u8>> {
        let pixmap = tiny_skia::Pixmap::new(W as u32, H as u32)
            .ok_or_else(|| Error::value("chart", "cannot allocate the image"))?;
        let mut c = PngCanvas(pixmap);
        c.0.fill(tiny_skia::Color::WHITE);
        self.draw(&mut c);
        c.0.encode_png()
            .map_err(|e| Error::value("chart", e.to_string()))
    }
}

struct SvgCanvas(String);

fn hex(rgb: [u8; 3]) -> String {
    format!("#{:02x}{:02x}{:02x}", rgb[0], rgb[1], rgb[2])
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

impl Canvas for SvgCanvas {
    fn line(&mut self, a: (f64, f64), b: (f64, f64), rgb: [u8; 3], width: f64, dashed: bool) {
        let dash = if dashed {
            " stroke-dasharray=\"6 4\""
        } else {
            ""
        };
        self.0 += &format!(
            "<line x1=\"{:.1}\" y1=\"{:.1}\" x2=\"{:.1}\" y2=\"{:.1}\" stroke=\"{}\" stroke-width=\"{width}\"{dash}/>\n",
            a.0, a.1, b.0, b.1, hex(rgb)
        );
    }
    fn circle(&mut self, c: (f64, f64), r: f64, rgb: [u8; 3], filled: bool) {
        let paint = if filled {
            format!("fill=\"{}\"", hex(rgb))
        } else {
            format!("fill=\"none\" stroke=\"{}\" stroke-width=\"1.5\"", hex(rgb))
        };
        self.0 += &format!(
            "<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"{r}\" {paint}/>\n",
            c.0, c.1
        );
    }
    fn text(&mut self, p: (f64, f64), s: &str, size: f64, anchor: Anchor, vertical: bool) {
        let a = match anchor {
            Anchor::Start => "start",
            Anchor::Middle => "middle",
            Anchor::End => "end",
        };
        let rot = if vertical {
            format!(" transform=\"rotate(-90 {:.1} {:.1})\"", p.0, p.1)
        } else {
            String::new()
        };
        self.0 += &format!(
            "<text x=\"{:.1}\" y=\"{:.1}\" font-size=\"{:.0}\" text-anchor=\"{a}\"{rot}>{}</text>\n",
            p.0,
            p.1,
            size * 1.4,
            escape(s)
        );
    }
}

struct PngCanvas(tiny_skia::Pixmap);

fn paint(rgb: [u8; 3]) -> tiny_skia::Paint<'static> {
    let mut p = tiny_skia::Paint::default();
    p.set_color_rgba8(rgb[0], rgb[1], rgb[2], 255);
    p.anti_alias = true;
    p
}

impl PngCanvas {
    fn stroke(
        &mut self,
        path: &tiny_skia::Path,
        rgb: [u8; 3],
        width: f64,
        dash: Option<tiny_skia::StrokeDash>,
    ) {
        let stroke = tiny_skia::Stroke {
            width: width as f32,
            dash,
            ..Default::default()
        };
        self.0.stroke_path(
            path,
            &paint(rgb),
            &stroke,
            tiny_skia::Transform::identity(),
            None,
        );
    }
}

impl Canvas for PngCanvas {
    fn line(&mut self, a: (f64, f64), b: (f64, f64), rgb: [u8; 3], width: f64, dashed: bool) {
        let mut pb = tiny_skia::PathBuilder::new();
        pb.move_to(a.0 as f32, a.1 as f32);
        pb.line_to(b.0 as f32, b.1 as f32);
        let Some(path) = pb.finish() else { return };
        let dash = if dashed {
            tiny_skia::StrokeDash::new(vec![6.0, 4.0], 0.0)
        } else {
            None
        };
        self.stroke(&path, rgb, width, dash);
    }
    fn circle(&mut self, c: (f64, f64), r: f64, rgb: [u8; 3], filled: bool) {
        let Some(path) = tiny_skia::PathBuilder::from_circle(c.0 as f32, c.1 as f32, r as f32)
        else {
            return;
        };
        if filled {
            self.0.fill_path(
                &path,
                &paint(rgb),
                tiny_skia::FillRule::Winding,
                tiny_skia::Transform::identity(),
                None,
            );
        } else {
            self.stroke(&path, rgb, 1.5, None);
        }
    }
    fn text(&mut self, p: (f64, f64), s: &str, size: f64, anchor: Anchor, vertical: bool) {
        let at = (p.0 as f32, p.1 as f32);
        super::text::draw(
            &mut self.0,
            at,
            s,
            size as f32,
            anchor,
            vertical,
            [40, 40, 40],
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_are_round_and_cover_the_range() {
        assert_eq!(log_ticks(0.8, 60.0), vec![1.0, 2.0, 5.0, 10.0, 20.0, 50.0]);
        assert_eq!(linear_ticks(0.0, 11.0), vec![0.0, 2.0, 4.0, 6.0, 8.0, 10.0]);
    }

    #[test]
    fn svg_and_png_show_every_series() {
        let chart = Chart {
            title: "t".into(),
            x_label: "ms".into(),
            y_label: "rmse".into(),
            series: vec![
                Series {
                    name: "a".into(),
                    points: vec![(1.0, 2.0), (10.0, 1.0)],
                },
                Series {
                    name: "b".into(),
                    points: vec![(3.0, 0.5)],
                },
            ],
            front: vec![(1.0, 2.0), (3.0, 0.5)],
            linear_x: false,
        };
        let svg = chart.svg();
        // 3 series points + 2 legend dots + 2 front rings + 1 legend ring.
        assert_eq!(svg.matches("<circle").count(), 8);
        assert!(svg.contains(">a</text>") && svg.contains(">b</text>"));
        let png = chart.png().unwrap();
        let img = image::load_from_memory(&png).unwrap().to_rgb8();
        assert_eq!(img.dimensions(), (W as u32, H as u32));
        // Series b's colour is in the image.
        assert!(img.pixels().any(|p| p.0 == COLOURS[1]));
    }
}
