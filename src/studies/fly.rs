//! A camera path through a scene: each frame's LOD update statistics
//! (texels rewritten, update and mesh time), and popping against a
//! brute-force render of the same path.

use crate::error::{Error, Result};
use crate::frame::stats::Passes;
use crate::render::{Image, RenderOptions, Session};
use crate::scene::{LodScheme, Scene};
use crate::shard::Shard;
use crate::studies::gpu_side::{FrameGpu, GpuSide};
use crate::studies::metrics;
use serde::{Deserialize, Serialize};

/// One frame of a fly-through (`fly --json` `frames`).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct FlyFrame {
    /// Frame number from 0.
    pub frame: usize,
    /// Whole frame on the CPU (ms), and the LOD update and mesh passes.
    pub ms: f64,
    /// The LOD update pass (ms).
    pub update_ms: f64,
    /// The mesh pass (ms).
    pub mesh_ms: f64,
    /// Texels the update rewrote (clipmap).
    pub texels_updated: u64,
    /// Changes the update made: rectangles, splits and merges, or blocks re-levelled.
    pub changes: u64,
    /// Triangles drawn.
    pub triangles: usize,
    /// Clipmap levels drawn.
    pub levels_drawn: usize,
    /// Pyramid samples a lazy pyramid built, or a pack decoded, for the
    /// frame (0 for a whole pyramid).
    pub pyramid_samples: u64,
    /// The tiles they came in.
    pub pyramid_tiles: u64,
    /// Level-0 texels the eye moved since the previous frame
    /// (horizontally, in cells of level 0).
    #[serde(default)]
    pub texels_moved: f64,
    /// Against the previous frame (metrics::popping); 0 for the first
    /// frame, for brute force itself and with popping off.
    pub popping: f64,
    /// With `--gpu`: what the wgpu back end, drawing the same flight with
    /// its buffers and toroids resident, paid for the frame.
    #[serde(default)]
    pub gpu: Option<FrameGpu>,
}

/// A fly-through: per-frame costs and popping along a straight path.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct FlyReport {
    /// The scheme flown.
    pub lod: String,
    /// Every frame.
    pub frames: Vec<FlyFrame>,
    /// Mean update time over frames after the first (the first builds).
    pub mean_update_ms: f64,
    /// Texels rewritten over frames after the first.
    pub texels_updated: u64,
    /// The largest popping of any frame.
    pub popping_max: f64,
    /// The process's peak resident memory after the flight (bytes; 0 where
    /// the platform does not say).
    pub peak_rss_bytes: u64,
    /// What the pack's decoding lets a flight sustain (flights over a
    /// pack or a lazy pyramid that decoded while moving).
    #[serde(default)]
    pub update_budget: Option<UpdateBudget>,
    /// With `--gpu`: mean bytes uploaded per frame after the first.
    #[serde(default)]
    pub mean_upload_bytes: Option<f64>,
}

/// The fastest flight the decoder can feed, from the flight's own figures
/// over its moving frames after the first: how many samples it decodes
/// per level-0 texel moved, how fast the LOD update pass turns samples
/// out (decoding and toroid writes together, so a floor on the decoder's
/// rate), and the median frame. A flight at `v` texels a frame needs
/// `v × samples_per_texel / samples_per_ms` ms of update a frame: the
/// largest `v` whose update fits the whole frame, and 10 % of it. Valid
/// where every level is drawn (`every_level_drawn`): a budget that drops
/// levels decodes less than the motion asks for.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct UpdateBudget {
    /// Samples the update pass decoded per millisecond it took.
    pub samples_per_ms: f64,
    /// Samples decoded per level-0 texel the eye moved.
    pub samples_per_texel: f64,
    /// Median frame time of the moving frames (ms).
    pub frame_ms: f64,
    /// Level-0 texels a frame the update could feed in the whole frame.
    pub texels_per_frame: f64,
    /// The same with the update held to 10 % of the frame.
    pub texels_per_frame_at_10_percent: f64,
    /// Whether every moving frame drew as many levels as the most any
    /// frame drew.
    pub every_level_drawn: bool,
}

/// The budget over `frames` ([`UpdateBudget`]): the moving frames after
/// the first, where samples were decoded; `None` where none were.
fn update_budget(frames: &[FlyFrame]) -> Option<UpdateBudget> {
    let moving: Vec<&FlyFrame> = frames
        .iter()
        .filter(|f| f.frame > 0 && f.texels_moved > 0.0)
        .collect();
    let samples: u64 = moving.iter().map(|f| f.pyramid_samples).sum();
    let update_ms: f64 = moving
        .iter()
        .filter(|f| f.pyramid_samples > 0)
        .map(|f| f.update_ms)
        .sum();
    let texels: f64 = moving.iter().map(|f| f.texels_moved).sum();
    if samples == 0 || update_ms <= 0.0 || texels <= 0.0 {
        return None;
    }
    let mut ms: Vec<f64> = moving.iter().map(|f| f.ms).collect();
    ms.sort_by(f64::total_cmp);
    let frame_ms = ms[ms.len() / 2];
    let samples_per_ms = samples as f64 / update_ms;
    let samples_per_texel = samples as f64 / texels;
    let texels_per_frame = frame_ms * samples_per_ms / samples_per_texel;
    let most = frames.iter().map(|f| f.levels_drawn).max().unwrap_or(0);
    Some(UpdateBudget {
        samples_per_ms,
        samples_per_texel,
        frame_ms,
        texels_per_frame,
        texels_per_frame_at_10_percent: texels_per_frame * 0.1,
        every_level_drawn: moving.iter().all(|f| f.levels_drawn == most),
    })
}

/// Flies `frames` frames from the scene's camera, `step` metres per frame
/// ([`crate::camera::path`]), then holds the last camera for `still` frames (where a
/// budget-limited update catches up). `each` gets every frame's image.
/// A `shard` draws its run of the frames ([`Shard::run_of`]); before it,
/// the LOD scheme is only updated, and the frame just before is drawn
/// unreported, for its popping.
pub fn fly(
    scene: &Scene,
    flight: (usize, usize),
    step: f64,
    popping: bool,
    shard: Shard,
    each: impl FnMut(usize, &Image) -> Result<()>,
) -> Result<FlyReport> {
    fly_with(scene, flight, step, popping, shard, false, each)
}

/// [`fly`], and with `gpu` each frame drawn by the wgpu back end too (a
/// session of its own, so its toroids follow every update), its costs in
/// [`FlyFrame::gpu`].
pub fn fly_with(
    scene: &Scene,
    (frames, still): (usize, usize),
    step: f64,
    popping: bool,
    shard: Shard,
    gpu: bool,
    mut each: impl FnMut(usize, &Image) -> Result<()>,
) -> Result<FlyReport> {
    let opts = RenderOptions::default();
    let mut session = Session::new(scene, &mut Passes::default())?;
    let mut gpu = GpuSide::open(gpu)?;
    let mut gpu_session = match gpu.adapter() {
        Some(_) => Some(Session::new(scene, &mut Passes::default())?),
        None => None,
    };
    let mut brute = if popping && scene.lod.scheme != LodScheme::BruteForce {
        Some(Session::new(
            &scene.with_lod("brute-force")?,
            &mut Passes::default(),
        )?)
    } else {
        None
    };
    let mut out = Vec::new();
    let mut prev: Option<(Image, Option<Image>)> = None;
    let mut cams = crate::camera::path(&scene.camera(), frames, step);
    if let Some(&last) = cams.last() {
        cams.extend(std::iter::repeat_n(last, still));
    }
    let mine = shard.run_of(cams.len());
    for (i, cam) in cams.iter().enumerate().take(mine.end) {
        if i + 1 < mine.start {
            session.update(cam, &mut Passes::default());
            if let Some(g) = &mut gpu_session {
                g.update(cam, &mut Passes::default());
            }
            continue;
        }
        let (img, stats) = session.render(cam, &opts, Passes::default())?;
        let frame_gpu = match &mut gpu_session {
            Some(g) => gpu.frame(g, cam)?,
            None => None,
        };
        let reference = match &mut brute {
            Some(b) => Some(b.render(cam, &opts, Passes::default())?.0),
            None => None,
        };
        // Brute force cannot pop against itself; without references there
        // is nothing to measure.
        let pop = match (&prev, &reference) {
            (Some((p, Some(pr))), Some(r)) => metrics::popping([p, &img], [pr, r]),
            _ => 0.0,
        };
        if i < mine.start {
            prev = Some((img, reference));
            continue;
        }
        let texels_moved = match i.checked_sub(1).and_then(|j| cams.get(j)) {
            Some(p) if p.eye != cam.eye => {
                let d = cam.eye - p.eye;
                (d.x / session.world.cell[0]).hypot(d.y / session.world.cell[1])
            }
            _ => 0.0,
        };
        out.push(FlyFrame {
            frame: i,
            texels_moved,
            ms: stats.ms_total,
            update_ms: stats.pass_ms(&["lod"]),
            mesh_ms: stats.pass_ms(&["mesh"]),
            texels_updated: session.last_update.texels_updated,
            changes: session.last_update.changes,
            triangles: stats.triangles,
            levels_drawn: stats.levels_drawn,
            pyramid_samples: stats.lazy.as_ref().map_or(0, |z| z.samples_this_frame),
            pyramid_tiles: stats.lazy.as_ref().map_or(0, |z| z.tiles_this_frame),
            popping: pop,
            gpu: frame_gpu,
        });
        each(i, &img)?;
        prev = Some((img, reference));
    }
    summary(
        session.lod.name().to_string(),
        out,
        crate::studies::scaling::peak_rss().unwrap_or(0),
    )
    .map_err(|why| Error::value("fly", why))
}

/// The report over `frames`; the first frame of the flight builds, so the
/// update figures leave it out. Frames read from a part's file may count
/// texels past `u64`: an error, never a wrapped sum.
fn summary(
    lod: String,
    frames: Vec<FlyFrame>,
    peak_rss_bytes: u64,
) -> std::result::Result<FlyReport, String> {
    let later: Vec<&FlyFrame> = frames.iter().filter(|f| f.frame > 0).collect();
    let texels_updated = later
        .iter()
        .try_fold(0u64, |a, f| a.checked_add(f.texels_updated))
        .ok_or("texels rewritten past the largest whole number")?;
    let uploads: Vec<f64> = later
        .iter()
        .filter_map(|f| f.gpu.map(|g| g.upload_bytes as f64))
        .collect();
    Ok(FlyReport {
        mean_upload_bytes: (!uploads.is_empty())
            .then(|| uploads.iter().sum::<f64>() / uploads.len() as f64),
        update_budget: update_budget(&frames),
        lod,
        mean_update_ms: later.iter().map(|f| f.update_ms).sum::<f64>() / later.len().max(1) as f64,
        texels_updated,
        popping_max: frames.iter().map(|f| f.popping).fold(0.0, f64::max),
        peak_rss_bytes,
        frames,
    })
}

/// The parts' reports (in part order) as one flight's: their runs of
/// frames one after another, the peak memory the largest part's.
pub fn merge(parts: &[FlyReport]) -> std::result::Result<FlyReport, String> {
    let first = parts.first().ok_or("no parts")?;
    let frames: Vec<FlyFrame> = parts.iter().flat_map(|p| p.frames.clone()).collect();
    if let Some((k, f)) = frames.iter().enumerate().find(|(k, f)| f.frame != *k) {
        return Err(format!(
            "frame {} is where frame {k} should be: parts missing or out of order",
            f.frame
        ));
    }
    if let Some(p) = parts.iter().find(|p| p.lod != first.lod) {
        return Err(format!("parts flew {} and {}", first.lod, p.lod));
    }
    let rss = parts.iter().map(|p| p.peak_rss_bytes).max().unwrap_or(0);
    summary(first.lod.clone(), frames, rss)
}

/// Writes the [`charts`] into `dir` as SVG and PNG (each atomically).
pub fn write_charts(r: &FlyReport, dir: &std::path::Path) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    for (name, chart) in charts(r) {
        let w = |ext: &str, bytes: &[u8]| {
            crate::error::write_atomic(&dir.join(format!("{name}.{ext}")), bytes)
        };
        w("svg", chart.svg().as_bytes())?;
        w("png", &chart.png()?)?;
    }
    Ok(())
}

/// Charts of a flight against the frame: each frame's time (the whole
/// frame and the LOD update), and the clipmap levels drawn; named
/// `fly-ms` and `fly-levels`.
pub fn charts(r: &FlyReport) -> Vec<(&'static str, crate::studies::report::chart::Chart)> {
    use crate::studies::report::chart::{Chart, Series};
    let series = |name: &str, f: &dyn Fn(&FlyFrame) -> f64| Series {
        name: name.into(),
        points: r.frames.iter().map(|x| (x.frame as f64, f(x))).collect(),
    };
    let chart = |title: &str, y: &str, series| Chart {
        title: format!("{title} ({}, {} frames)", r.lod, r.frames.len()),
        x_label: "frame".into(),
        y_label: y.into(),
        series,
        front: vec![],
        linear_x: true,
    };
    vec![
        (
            "fly-ms",
            chart(
                "frame time",
                "ms",
                vec![
                    series("frame", &|x| x.ms),
                    series("LOD update", &|x| x.update_ms),
                ],
            ),
        ),
        (
            "fly-levels",
            chart(
                "clipmap levels drawn",
                "levels",
                vec![series("levels drawn", &|x| x.levels_drawn as f64)],
            ),
        ),
    ]
}

/// An animated GIF of RGBA frames (10 frames per second).
pub fn gif(frames: &[Image]) -> Result<Vec<u8>> {
    use image::codecs::gif::{GifEncoder, Repeat};
    let mut bytes = Vec::new();
    {
        let mut enc = GifEncoder::new_with_speed(&mut bytes, 10);
        enc.set_repeat(Repeat::Infinite)
            .map_err(|e| Error::value("gif", e.to_string()))?;
        for f in frames {
            let buf = image::RgbaImage::from_raw(f.width, f.height, f.rgba.clone())
                .ok_or_else(|| Error::value("gif", "frame size mismatch"))?;
            let frame =
                image::Frame::from_parts(buf, 0, 0, image::Delay::from_numer_denom_ms(100, 1));
            enc.encode_frame(frame)
                .map_err(|e| Error::value("gif", e.to_string()))?;
        }
    }
    Ok(bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frames(run: std::ops::Range<usize>, texels: u64) -> FlyReport {
        let frames = run
            .map(|frame| FlyFrame {
                frame,
                ms: 1.0,
                update_ms: 0.5,
                mesh_ms: 0.1,
                texels_updated: texels,
                changes: 0,
                triangles: 2,
                levels_drawn: 1,
                pyramid_samples: 0,
                pyramid_tiles: 0,
                texels_moved: 0.0,
                popping: 0.0,
                gpu: None,
            })
            .collect();
        summary("clipmap".into(), frames, 0).unwrap()
    }

    /// Frames 1–4 move 10 texels each and decode 20,000 samples in 4 ms
    /// of update (5,000 a ms, 2,000 a texel); the median moving frame (of
    /// 40, 50, 55, 60, the upper one) is 55 ms, so 55 × 5,000 / 2,000 =
    /// 137.5 texels a frame, 13.75 at 10 %.
    /// Frame 0 (the build) and the still frame 5 do not count.
    #[test]
    fn the_update_budget_is_the_flights_own_rate_over_its_frame() {
        let f =
            |frame: usize, ms: f64, update_ms: f64, samples: u64, moved: f64, levels| FlyFrame {
                frame,
                ms,
                update_ms,
                mesh_ms: 0.0,
                texels_updated: 0,
                changes: 0,
                triangles: 0,
                levels_drawn: levels,
                pyramid_samples: samples,
                pyramid_tiles: 0,
                texels_moved: moved,
                popping: 0.0,
                gpu: None,
            };
        let mut run = vec![
            f(0, 900.0, 800.0, 9_000_000, 0.0, 10),
            f(1, 40.0, 4.0, 20_000, 10.0, 10),
            f(2, 50.0, 4.0, 20_000, 10.0, 10),
            f(3, 60.0, 4.0, 20_000, 10.0, 10),
            f(4, 55.0, 4.0, 20_000, 10.0, 10),
            f(5, 10.0, 0.0, 0, 0.0, 10),
        ];
        let b = summary("clipmap".into(), run.clone(), 0)
            .unwrap()
            .update_budget
            .unwrap();
        assert_eq!(
            b,
            UpdateBudget {
                samples_per_ms: 5_000.0,
                samples_per_texel: 2_000.0,
                frame_ms: 55.0,
                texels_per_frame: 137.5,
                texels_per_frame_at_10_percent: 13.75,
                every_level_drawn: true,
            }
        );
        run[3].levels_drawn = 8;
        let b = summary("clipmap".into(), run, 0).unwrap();
        assert!(!b.update_budget.unwrap().every_level_drawn);
        assert_eq!(frames(0..3, 1).update_budget, None);
    }

    #[test]
    fn merged_parts_sum_in_order_and_refuse_counts_past_u64() {
        let m = merge(&[frames(0..2, 3), frames(2..4, 4)]).unwrap();
        assert_eq!((m.frames.len(), m.texels_updated), (4, 11));
        let e = merge(&[frames(2..4, 4), frames(0..2, 3)]).unwrap_err();
        assert!(e.contains("out of order"), "{e}");
        let e = merge(&[frames(0..2, 3), frames(2..3, u64::MAX)]).unwrap_err();
        assert!(e.contains("largest whole number"), "{e}");
    }
}
