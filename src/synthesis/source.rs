//! Synthesised levels as a pyramid's tile source: `[terrain] synthesis`.
//!
//! The levels finer than the map are made a tile at a time from the next
//! coarser level, as the clipmap's windows reach them, and evicted behind
//! them like a pack's decoded tiles (`pyramid::decoded`): a
//! synthesised level of any size costs only the tiles around the viewer.
//! Each sample is a function of its position and the coarser level's
//! samples alone, so the levels are the same bits whichever tiles are
//! made in whichever order, and the same as [`super::synthesize`] made whole.

use super::{
    amplitude, detail_rms_window, roughness_between, synthesize_window, NoiseTable, MAX_ROUGHNESS,
};
use crate::pyramid::{Pyramid, PyramidLevel, TileSource};
use crate::terrain::world::WorldMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// The most levels synthesis adds (16 times finer than the map).
pub const MAX_LEVELS: usize = 4;

/// The most samples a synthesised level made in tiles may have: its tile
/// and height-bound bookkeeping stays under 200 MB (2^34 samples, a
/// 131,071² level: one level finer than a 65,536² map).
pub const MAX_TILED_SAMPLES: u64 = 1 << 34;

/// Tile side of the synthesised levels over a map held whole.
const TILE: usize = 128;

/// The side of the window of the map's finest level whose detail a pack
/// is measured in (decoded for the purpose): a map held whole is measured
/// over all of it.
const MEASURE: usize = 1024;

/// What `[terrain] synthesis = { levels, roughness, seed }` asks for (data
/// the terrain's spec holds).
pub use crate::terrain::SynthesisSpec as Spec;

/// Checks the values serde's types cannot; errors name the key.
pub fn validate(spec: &Spec) -> Result<(), (&'static str, String)> {
    if !(1..=MAX_LEVELS).contains(&spec.levels) {
        return Err((
            "terrain.synthesis.levels",
            format!("{}: must be within 1..={MAX_LEVELS}", spec.levels),
        ));
    }
    if let Some(h) = spec.roughness {
        super::check_roughness(h).map_err(|r| ("terrain.synthesis.roughness", r))?;
    }
    Ok(())
}

/// How the synthesised levels continue the map: its finest detail, the
/// roughness, and each level's noise amplitude, finest level last.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Continuation {
    /// RMS of the map's finest level less its coarser level's subdivision.
    pub detail: f64,
    /// The roughness exponent used.
    pub roughness: f64,
    /// Whether it was measured from the map (not given).
    pub measured: bool,
    /// The same RMS one step coarser (levels 1 and 2), when the roughness
    /// was measured from the two.
    pub next_detail: Option<f64>,
    /// Amplitude of synthesised level k (1 = just finer than the map) at
    /// index k − 1.
    pub amplitudes: Vec<f64>,
    /// The noise table's seed.
    pub seed: u64,
}

/// The synthesised levels of one map, as a [`TileSource`].
#[derive(Debug)]
pub struct Synthesised {
    path: PathBuf,
    table: NoiseTable,
    amplitudes: Vec<f64>,
    sizes: Vec<[usize; 2]>,
    ranges: Vec<[f32; 2]>,
    tile: usize,
}

/// The map's finest detail and the next step's over `base`'s levels 0 to
/// 2 (the second only when `want_next`): a map held whole over all of it,
/// a pack's in a central window decoded for it.
fn measure(base: &mut Pyramid, want_next: bool) -> Result<(f64, Option<f64>), String> {
    let need = if want_next { 3 } else { 2 };
    if base.levels.len() < need {
        return Err(format!(
            "a {}×{} map has {} levels, and measuring its detail{} needs {need}",
            base.levels[0].width,
            base.levels[0].height,
            base.levels.len(),
            if want_next { " and roughness" } else { "" }
        ));
    }
    let rect = |l: &PyramidLevel, c: &PyramidLevel, side: usize| {
        // The samples of `l` that lie over `c` (2 · c − 1 across).
        let (w, h) = (l.width.min(2 * c.width - 1), l.height.min(2 * c.height - 1));
        let (sw, sh) = (w.min(side), h.min(side));
        [(w - sw) / 2, (h - sh) / 2, sw, sh]
    };
    let whole = base.is_complete();
    let side = if whole { usize::MAX } else { MEASURE };
    let r0 = rect(&base.levels[0], &base.levels[1], side);
    if !whole {
        // The window's tiles, and with them what each was predicted from:
        // a pack's tile is predicted from the four-point stencils of the
        // coarser level around it, the samples the subdivision reads, so
        // levels 1 and 2 under the window come decoded too
        // (tests/synthesis.rs holds the figures to the map's own).
        let w = [
            r0[0] as i64,
            r0[1] as i64,
            (r0[0] + r0[2]) as i64 - 1,
            (r0[1] + r0[3]) as i64 - 1,
        ];
        base.decode_window(0, w).map_err(|e| e.to_string())?;
    }
    let lv = &base.levels;
    let flat = || "the map has no detail to continue (it is flat)".to_string();
    let finest = detail_rms_window(&lv[0], &lv[1], r0)
        .filter(|&d| d > 0.0)
        .ok_or_else(flat)?;
    let next = if want_next {
        // Level 1's samples under the window, within what lies over level 2.
        let all = rect(&lv[1], &lv[2], usize::MAX);
        let (x, y) = (r0[0] / 2, r0[1] / 2);
        let r1 = [
            x,
            y,
            r0[2].div_ceil(2).min(all[2] - x),
            r0[3].div_ceil(2).min(all[3] - y),
        ];
        Some(detail_rms_window(&lv[1], &lv[2], r1).ok_or_else(flat)?)
    } else {
        None
    };
    Ok((finest, next))
}

/// A bound on how far a level synthesised from heights within a range
/// `r` wide reaches past it: the four-point rows and columns overshoot
/// by r / 8, a centre's row through the column midpoints by 2.25 r / 8,
/// and the noise by six times its amplitude (the table's values lie
/// within ±6); widened by a part in a thousand for the f32 rounding.
fn reach(r: f64, amp: f64) -> f64 {
    (2.25 * r / 8.0 + 6.0 * amp) * 1.001 + 1e-3
}

impl Synthesised {
    /// The `spec.levels` levels finer than `base`'s finest, continuing the
    /// detail measured from it, with `path` (the map's file) for errors.
    pub fn new(
        base: &mut Pyramid,
        spec: &Spec,
        path: &Path,
    ) -> Result<(Synthesised, Continuation), String> {
        validate(spec).map_err(|(k, r)| format!("{k}: {r}"))?;
        if base.finer_levels() > 0 {
            return Err("the map's levels are synthesised already".into());
        }
        let (detail, next) = measure(base, spec.roughness.is_none())?;
        let (roughness, measured) = match (spec.roughness, next) {
            (Some(h), _) => (h, false),
            (None, Some(n)) => (
                roughness_between(detail, n)
                    .ok_or("the map has no detail to measure a roughness from")?,
                true,
            ),
            (None, None) => unreachable!("measured when not given"),
        };
        debug_assert!(roughness <= MAX_ROUGHNESS);
        let amplitudes: Vec<f64> = (1..=spec.levels)
            .map(|k| amplitude(detail, roughness, k))
            .collect();
        // Sizes and bounds from the map's finest level down, then finest first.
        let l0 = &base.levels[0];
        let (mut size, mut lo, mut hi) = ([l0.width, l0.height], l0.min as f64, l0.max as f64);
        let (mut sizes, mut ranges) = (Vec::new(), Vec::new());
        for &a in &amplitudes {
            size = [2 * size[0] - 1, 2 * size[1] - 1];
            let e = reach(hi - lo, a);
            (lo, hi) = (lo - e, hi + e);
            sizes.push(size);
            ranges.push([lo as f32, hi as f32]);
        }
        let [w, h] = size;
        if w as u64 * h as u64 > MAX_TILED_SAMPLES {
            return Err(format!(
                "{} levels over a {}×{} map make a finest level of {w}×{h} samples, over the {MAX_TILED_SAMPLES} synthesis can hold in tiles; ask for fewer levels",
                spec.levels, l0.width, l0.height
            ));
        }
        sizes.reverse();
        ranges.reverse();
        let src = Synthesised {
            path: path.to_path_buf(),
            table: NoiseTable::new(spec.seed),
            amplitudes: amplitudes.clone(),
            sizes,
            ranges,
            tile: base.tile_side().unwrap_or(TILE),
        };
        let how = Continuation {
            detail,
            next_detail: next,
            roughness,
            measured,
            amplitudes,
            seed: spec.seed,
        };
        Ok((src, how))
    }
}

impl TileSource for Synthesised {
    fn path(&self) -> &Path {
        &self.path
    }
    fn sizes(&self) -> Vec<[usize; 2]> {
        self.sizes.clone()
    }
    fn ranges(&self) -> Vec<[f32; 2]> {
        self.ranges.clone()
    }
    fn tile(&self) -> usize {
        self.tile
    }
    fn reads(&self, l: usize, [i, j]: [usize; 2]) -> Option<[i64; 4]> {
        let [w, h] = self.sizes[l];
        let t = self.tile;
        let (x0, y0) = (i * t, j * t);
        let (x1, y1) = (((i + 1) * t).min(w) - 1, ((j + 1) * t).min(h) - 1);
        // The four-point stencils reach one coarse sample before and two
        // after the cells the tile lies in.
        Some([
            (x0 / 2) as i64 - 1,
            (y0 / 2) as i64 - 1,
            (x1 / 2) as i64 + 2,
            (y1 / 2) as i64 + 2,
        ])
    }
    fn decode(
        &self,
        l: usize,
        [i, j]: [usize; 2],
        coarse: &PyramidLevel,
    ) -> Result<(Vec<f32>, Vec<bool>), String> {
        let [w, h] = self.sizes[l];
        let t = self.tile;
        let (x0, y0) = (i * t, j * t);
        let rect = [x0, y0, t.min(w - x0), t.min(h - y0)];
        // Level l is synthesised level k counted from the map.
        let k = self.sizes.len() - l;
        let amp = self.amplitudes[k - 1];
        Ok(synthesize_window(coarse, &self.table, k, amp, None, rect))
    }
}

/// A scene's pyramid and placement with `spec`'s levels before the map's:
/// made a tile at a time as [`refine`] makes them, or, with `whole`, made
/// whole for the schemes and effects that read whole levels (up to
/// [`crate::terrain::MAX_TEXELS`] samples); the world's cell shrinks by
/// 2^levels.
pub fn apply(
    base: Pyramid,
    world: WorldMap,
    spec: &Spec,
    path: &Path,
    budget: u64,
    whole: bool,
) -> Result<(Pyramid, WorldMap, Continuation), String> {
    let (p, how) = refine(base, spec, path, budget)?;
    let p = if whole {
        let l = &p.levels[0];
        if (l.width as u64) * (l.height as u64) > crate::terrain::MAX_TEXELS {
            return Err(format!(
                "its finest level of {}×{} samples is over the {} held whole for a scheme other than the clipmap or for shadows or normal-map; ask for fewer levels",
                l.width,
                l.height,
                crate::terrain::MAX_TEXELS
            ));
        }
        p.whole().map_err(|e| e.to_string())?
    } else {
        p
    };
    let scale = (1u64 << spec.levels) as f64;
    let cell = [world.cell[0] / scale, world.cell[1] / scale];
    Ok((p, WorldMap { cell, ..world }, how))
}

/// `base` with `spec.levels` synthesised levels before its own, made a
/// tile at a time within `budget` samples an update (a pack's pyramid
/// keeps its own budget), and how they continue the map.
pub fn refine(
    mut base: Pyramid,
    spec: &Spec,
    path: &Path,
    budget: u64,
) -> Result<(Pyramid, Continuation), String> {
    let (src, how) = Synthesised::new(&mut base, spec, path)?;
    Ok((base.with_finer(Arc::new(src), budget)?, how))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pyramid::Filter;

    /// What a tile reads is exactly its four-point stencils' reach: one
    /// coarse sample before the cells it lies in and two after (clamped
    /// by the pyramid, not here); an edge tile is made at its own size.
    #[test]
    fn a_tile_reads_its_stencils_and_is_its_own_size() {
        let map = crate::terrain::procedural::Procedural::new(3, 200, 150)
            .generate()
            .unwrap();
        let mut base = Pyramid::from_heightmap(map, Filter::default(), 4);
        let spec = Spec {
            levels: 1,
            roughness: Some(0.5),
            seed: 1,
        };
        let (s, _) = Synthesised::new(&mut base, &spec, Path::new("t")).unwrap();
        assert_eq!(s.sizes(), vec![[399, 299]]);
        // Tile (1, 2): fine samples 128..=255 × 256..=298.
        assert_eq!(s.reads(0, [1, 2]), Some([63, 127, 129, 151]));
        assert_eq!(s.reads(0, [0, 0]), Some([-1, -1, 65, 65]));
        let (v, nd) = s.decode(0, [3, 2], &base.levels[0]).unwrap();
        // The corner tile: 399 − 384 = 15 across, 299 − 256 = 43 down.
        assert_eq!((v.len(), nd.len()), (15 * 43, 15 * 43));
    }
}
