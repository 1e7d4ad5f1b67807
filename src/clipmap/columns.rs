//! A level's source columns, copied out a block at a time.
//!
//! Walking east or west rewrites a column of the toroid: n texels from n
//! different rows of a row-major pyramid level. On a wide level every row is
//! its own page, so each texel costs a TLB miss; on the 32768-wide map of the
//! update test that made a column several times dearer per texel than a row.
//! The cache copies a block of 32 columns (two cache lines of each row) over the
//! window's rows plus a margin, column-major, once; the next 31 one-texel
//! steps read it contiguously. The values are copies, so the toroid's bits do
//! not change.

use super::toroid::{Column, Source};
use crate::pyramid::PyramidLevel;

/// Columns per block: two 64-byte lines of f32s (the second comes nearly
/// free with the first; wider blocks measured no better).
pub const BLOCK: i64 = 32;
/// Rows kept beyond the window on either side, so a diagonal walk reuses a
/// block for this many rows of drift.
const MARGIN: i64 = 32;

/// Columns `[x0, x0 + BLOCK)` × rows `[y0, y0 + rows)` of one level, sampled
/// with clamping like [`PyramidLevel::get_clamped`], column-major.
#[derive(Clone, Debug, Default)]
pub struct ColumnCache {
    x0: i64,
    y0: i64,
    rows: i64,
    data: Vec<f32>,
}

impl ColumnCache {
    /// Forgets the block (the source changed).
    pub fn clear(&mut self) {
        self.rows = 0;
    }

    /// Makes sure the block holding column `x` covers rows `[y0, y1)`,
    /// copying it from `src` if not.
    pub fn ensure(&mut self, src: &PyramidLevel, x: i64, y0: i64, y1: i64) {
        let bx = x.div_euclid(BLOCK) * BLOCK;
        if self.rows > 0 && bx == self.x0 && y0 >= self.y0 && y1 <= self.y0 + self.rows {
            return;
        }
        let (top, rows) = (y0 - MARGIN, y1 - y0 + 2 * MARGIN);
        self.data.resize((BLOCK * rows) as usize, 0.0);
        let inside = bx >= 0 && bx + BLOCK <= src.width as i64;
        let mut line = [0f32; BLOCK as usize];
        for r in 0..rows {
            let y = (top + r).clamp(0, src.height as i64 - 1) as usize;
            if inside {
                // A fixed-size copy, inlined: a memcpy call per row kept
                // fewer of the rows' cache misses in flight.
                let at = y * src.width + bx as usize;
                line.copy_from_slice(&src.data[at..at + BLOCK as usize]);
            } else {
                src.copy_clamped(bx, y as i64, &mut line);
            }
            for (c, v) in line.iter().enumerate() {
                self.data[c * rows as usize + r as usize] = *v;
            }
        }
        (self.x0, self.y0, self.rows) = (bx, top, rows);
    }

    /// Column `x`, rows `[y, y + len)`, where the block holds them.
    #[inline]
    fn column(&self, x: i64, y: i64, len: usize) -> Option<&[f32]> {
        let (c, r) = (x - self.x0, y - self.y0);
        let inside = (0..BLOCK).contains(&c) && r >= 0 && r + len as i64 <= self.rows;
        inside.then(|| {
            let at = (c * self.rows + r) as usize;
            &self.data[at..at + len]
        })
    }
}

/// A level as a toroid's source: rows copied from the level, columns from
/// its [`ColumnCache`] where it holds them.
pub struct LevelSource<'a> {
    pub level: &'a PyramidLevel,
    pub cache: &'a ColumnCache,
}

impl Source<f32> for LevelSource<'_> {
    fn row(&self, wx: i64, wy: i64, run: &mut [f32]) {
        self.level.copy_clamped(wx, wy, run);
    }
    fn column(&self, wx: i64, wy: i64, column: Column<'_, f32>) {
        match self.cache.column(wx, wy, column.len()) {
            Some(c) => column.zip(c).for_each(|(d, s)| *d = *s),
            None => {
                for (i, d) in column.enumerate() {
                    *d = self.level.get_clamped(wx, wy + i as i64);
                }
            }
        }
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
                let col = cache.column(c, -10, 70).expect("block covers the rows");
                for (i, v) in col.iter().enumerate() {
                    assert_eq!(v.to_bits(), lv.get_clamped(c, i as i64 - 10).to_bits());
                }
            }
            // Outside the block or beyond its rows: not held.
            assert!(cache.column(bx - 1, 0, 1).is_none());
            assert!(cache.column(bx + BLOCK, 0, 1).is_none());
            assert!(cache.column(bx, -10 - MARGIN - 1, 1).is_none());
            assert!(cache.column(bx, 60 + MARGIN - 3, 4).is_none());
        }
    }

    #[test]
    fn ensure_refills_only_when_needed_and_clear_forgets() {
        let lv = level(100, 100);
        let mut cache = ColumnCache::default();
        assert!(cache.column(0, 0, 1).is_none());
        cache.ensure(&lv, 33, 10, 40);
        let (x0, y0) = (cache.x0, cache.y0);
        // Same block, rows within the margin: kept.
        cache.ensure(&lv, 40, 10 - MARGIN, 40);
        assert_eq!((cache.x0, cache.y0), (x0, y0));
        // Rows past the margin: refilled around them.
        cache.ensure(&lv, 40, 10 - MARGIN - 1, 40);
        assert_eq!(cache.y0, 10 - 2 * MARGIN - 1);
        cache.clear();
        assert!(cache.column(40, 10, 1).is_none());
    }
}
