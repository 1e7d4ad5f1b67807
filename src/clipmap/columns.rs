//! A level's source columns, copied out a block at a time.
//!
//! Walking east or west rewrites a column of the toroid: n texels from n
//! different rows of a row-major pyramid level. On a wide level every row is
//! its own page, so each texel costs a TLB miss; on the 32768-wide map of the
//! update test that made a column several times dearer per texel than a row.
//! The cache copies a block of 32 columns (two cache lines of each row) over
//! the window's rows plus a margin, once; the next 31 one-texel steps read
//! it from cache. The block keeps the rows' layout (32 texels per row, 128
//! bytes apart): a fill then stores two lines per source row, few enough
//! stores that many rows' misses are in flight at once, where transposing
//! it to columns stored 32 scattered texels per row and stalled on them.
//! The values are copies, so the toroid's bits do not change.

use super::toroid::{narrow_by_rows, Narrow, Source};
use crate::pyramid::PyramidLevel;

/// Columns per block: two 64-byte lines of f32s (the second comes nearly
/// free with the first; wider blocks measured no better).
pub const BLOCK: i64 = 32;
/// Rows kept beyond the window on either side when the window's vertical
/// motion is unknown (a block's first fill), so a diagonal walk reuses a
/// block for this many rows of drift.
pub const MARGIN: i64 = 32;
/// Rows always kept beyond the window once its motion is known: a walk
/// that has not drifted vertically pays for these few, not for
/// [`MARGIN`] on both sides (a fifth of the rows a block reads).
pub const MIN_MARGIN: i64 = 4;

/// Columns `[x0, x0 + BLOCK)` × rows `[y0, y0 + rows)` of one level, sampled
/// with clamping like [`PyramidLevel::get_clamped`], row by row.
#[derive(Clone, Debug, Default)]
pub struct ColumnCache {
    x0: i64,
    y0: i64,
    rows: i64,
    /// The window's first row when the block was filled: the next fill
    /// takes the drift since then as the coming one, and keeps its margin
    /// on that side.
    filled_at: Option<i64>,
    data: Vec<f32>,
}

impl ColumnCache {
    /// Forgets the block (the source changed).
    pub fn clear(&mut self) {
        self.rows = 0;
        self.filled_at = None;
    }

    /// Rows to keep above and below window rows starting at `y0`: the full
    /// [`MARGIN`] on the side the window drifted to since the last fill,
    /// [`MIN_MARGIN`] on a side it did not.
    fn margins(&self, y0: i64) -> (i64, i64) {
        match self.filled_at {
            None => (MARGIN, MARGIN),
            Some(at) => {
                let drift = y0 - at;
                let side = |toward: bool| if toward { MARGIN } else { MIN_MARGIN };
                (side(drift < 0), side(drift > 0))
            }
        }
    }

    /// Makes sure the block holding column `x` covers rows `[y0, y1)`,
    /// copying it from `src` if not; returns the rows copied.
    pub fn ensure(&mut self, src: &PyramidLevel, x: i64, y0: i64, y1: i64) -> u64 {
        let bx = x.div_euclid(BLOCK) * BLOCK;
        if self.rows > 0 && bx == self.x0 && y0 >= self.y0 && y1 <= self.y0 + self.rows {
            return 0;
        }
        let (above, below) = self.margins(y0);
        let (top, rows) = (y0 - above, y1 - y0 + above + below);
        let b = BLOCK as usize;
        self.data.resize(b * rows as usize, 0.0);
        let inside = bx >= 0 && bx + BLOCK <= src.width as i64;
        for (r, line) in self.data.chunks_exact_mut(b).enumerate() {
            let y = (top + r as i64).clamp(0, src.height as i64 - 1) as usize;
            if inside {
                // A fixed-size copy, inlined: a memcpy call per row kept
                // fewer of the rows' cache misses in flight.
                let at = y * src.width + bx as usize;
                let line: &mut [f32; BLOCK as usize] = line.try_into().expect("BLOCK wide");
                line.copy_from_slice(&src.data[at..at + b]);
            } else {
                src.copy_clamped(bx, y as i64, line);
            }
        }
        (self.x0, self.y0, self.rows) = (bx, top, rows);
        self.filled_at = Some(y0);
        rows as u64
    }

    /// Columns `[x, x + width)`, rows `[y, y + rows)` as the block's slice
    /// from (x, y) on, its rows [`BLOCK`] apart, where the block holds them.
    #[inline]
    fn rect(&self, x: i64, y: i64, width: usize, rows: usize) -> Option<&[f32]> {
        let (c, r) = (x - self.x0, y - self.y0);
        let inside = c >= 0
            && c + width as i64 <= BLOCK
            && r >= 0
            && r + rows as i64 <= self.rows
            && rows > 0;
        inside.then(|| {
            let at = (r * BLOCK + c) as usize;
            &self.data[at..at + (rows - 1) * BLOCK as usize + width]
        })
    }
}

/// A level as a toroid's source: rows copied from the level, narrow
/// rectangles from its [`ColumnCache`] where it holds them.
pub struct LevelSource<'a> {
    /// The pyramid level the toroid mirrors.
    pub level: &'a PyramidLevel,
    /// Its column blocks, for east and west steps.
    pub cache: &'a ColumnCache,
}

impl Source<f32> for LevelSource<'_> {
    fn row(&self, wx: i64, wy: i64, run: &mut [f32]) {
        self.level.copy_clamped(wx, wy, run);
    }
    fn narrow(&self, wx: i64, wy: i64, dst: Narrow<'_, f32>) {
        let Some(block) = self.cache.rect(wx, wy, dst.width, dst.rows) else {
            return narrow_by_rows(self, wx, wy, dst);
        };
        let b = BLOCK as usize;
        let out = &mut dst.data[dst.at..];
        // One or two texels a row (a one-texel step, level 0's two): fixed
        // widths, so each row is a load and a store, not a copy loop.
        match dst.width {
            1 => copy_runs::<1>(block, b, out, dst.stride, dst.rows),
            2 => copy_runs::<2>(block, b, out, dst.stride, dst.rows),
            w => {
                for j in 0..dst.rows {
                    out[j * dst.stride..j * dst.stride + w]
                        .copy_from_slice(&block[j * b..j * b + w]);
                }
            }
        }
    }
}

/// `rows` runs of `W` texels from `src` (`from` apart) to `dst` (`to` apart).
#[inline]
fn copy_runs<const W: usize>(src: &[f32], from: usize, dst: &mut [f32], to: usize, rows: usize) {
    for j in 0..rows {
        let s: &[f32; W] = src[j * from..j * from + W].try_into().expect("W wide");
        dst[j * to..j * to + W].copy_from_slice(s);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn level(w: usize, h: usize) -> PyramidLevel {
        let data = (0..w * h).map(|i| i as f32 * 0.5 - 7.0).collect();
        PyramidLevel {
            width: w,
            height: h,
            data,
            nodata: vec![false; w * h],
            min: 0.0,
            max: 0.0,
        }
    }

    #[test]
    fn cached_columns_equal_clamped_samples_on_and_off_the_map() {
        let lv = level(70, 50);
        let mut cache = ColumnCache::default();
        // Blocks inside, straddling each side, and wholly off the map.
        for x in [-40, -5, 0, 31, 40, 64, 69, 75, 200] {
            cache.ensure(&lv, x, -10, 60);
            let bx = x.div_euclid(BLOCK) * BLOCK;
            for c in bx..bx + BLOCK {
                let col = cache.rect(c, -10, 1, 70).expect("block covers the rows");
                for i in 0..70 {
                    let v = col[i * BLOCK as usize];
                    assert_eq!(v.to_bits(), lv.get_clamped(c, i as i64 - 10).to_bits());
                }
            }
            // Outside the block or beyond its rows: not held.
            assert!(cache.rect(bx - 1, 0, 1, 1).is_none());
            assert!(cache.rect(bx + BLOCK, 0, 1, 1).is_none());
            assert!(cache.rect(bx + BLOCK - 1, 0, 2, 1).is_none());
            assert!(cache.rect(bx, -10 - MARGIN - 1, 1, 1).is_none());
            assert!(cache.rect(bx, 60 + MARGIN - 3, 1, 4).is_none());
            assert!(cache.rect(bx, 0, 1, 0).is_none());
        }
    }

    #[test]
    fn ensure_refills_only_when_needed_and_clear_forgets() {
        let lv = level(100, 100);
        let mut cache = ColumnCache::default();
        assert!(cache.rect(0, 0, 1, 1).is_none());
        cache.ensure(&lv, 33, 10, 40);
        let (x0, y0) = (cache.x0, cache.y0);
        // Same block, rows within the margin: kept.
        cache.ensure(&lv, 40, 10 - MARGIN, 40);
        assert_eq!((cache.x0, cache.y0), (x0, y0));
        // Rows past the margin: refilled around them, with the full margin
        // above (the window drifted up) and the least below.
        cache.ensure(&lv, 40, 10 - MARGIN - 1, 40);
        assert_eq!(cache.y0, 10 - 2 * MARGIN - 1);
        assert_eq!(cache.rows, 30 + 2 * MARGIN + 1 + MIN_MARGIN);
        cache.clear();
        assert!(cache.rect(40, 10, 1, 1).is_none());
    }

    #[test]
    fn margins_follow_the_window_drift_since_the_last_fill() {
        let lv = level(400, 300);
        let mut cache = ColumnCache::default();
        // Unknown motion: the full margin on both sides.
        cache.ensure(&lv, 0, 100, 150);
        assert_eq!((cache.y0, cache.rows), (100 - MARGIN, 50 + 2 * MARGIN));
        // A straight walk east: the next blocks keep only MIN_MARGIN.
        for b in 1..4 {
            cache.ensure(&lv, b * BLOCK, 100, 150);
            assert_eq!(
                (cache.y0, cache.rows),
                (100 - MIN_MARGIN, 50 + 2 * MIN_MARGIN)
            );
        }
        // Drifting down: the full margin below, the least above.
        for b in 4..7 {
            let y = 100 + 10 * (b - 3);
            cache.ensure(&lv, b * BLOCK, y, y + 50);
            assert_eq!(
                (cache.y0, cache.rows),
                (y - MIN_MARGIN, 50 + MIN_MARGIN + MARGIN)
            );
        }
        // Turning up: the full margin above.
        cache.ensure(&lv, 7 * BLOCK, 0, 50);
        assert_eq!((cache.y0, cache.rows), (-MARGIN, 50 + MARGIN + MIN_MARGIN));
        // Forgetting the block forgets the motion too.
        cache.clear();
        cache.ensure(&lv, 8 * BLOCK, 0, 50);
        assert_eq!((cache.y0, cache.rows), (-MARGIN, 50 + 2 * MARGIN));
    }

    #[test]
    fn narrow_writes_equal_clamped_samples_with_and_without_the_block() {
        let lv = level(70, 50);
        let mut cache = ColumnCache::default();
        cache.ensure(&lv, 40, 0, 30);
        let stride = 9;
        // Widths 1..=3 inside the block, one crossing its edge (read row by
        // row), and rows past its margin.
        for (wx, wy, width, rows) in [
            (40, 0, 1, 30),
            (41, -5, 2, 12),
            (61, 3, 3, 7),
            (63, 0, 2, 5),
            (33, 50, 2, 20),
        ] {
            let src = LevelSource {
                level: &lv,
                cache: &cache,
            };
            let mut data = vec![f32::NAN; stride * rows + 4];
            src.narrow(
                wx,
                wy,
                Narrow {
                    data: &mut data,
                    at: 3,
                    stride,
                    width,
                    rows,
                },
            );
            for (k, v) in data.iter().enumerate() {
                let (j, i) = (
                    (k as i64 - 3).div_euclid(stride as i64),
                    (k as i64 - 3).rem_euclid(stride as i64),
                );
                if k >= 3 && j < rows as i64 && i < width as i64 {
                    assert_eq!(v.to_bits(), lv.get_clamped(wx + i, wy + j).to_bits());
                } else {
                    assert!(v.is_nan(), "wrote outside the rectangle at {k}");
                }
            }
        }
    }
}
