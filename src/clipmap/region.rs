//! Integer rectangles on the base vertex lattice, and the per-level clip,
//! active and render regions of a geometry clipmap (Losasso & Hoppe 2004,
//! §3; Brettell ch. 3 for finite maps).
//!
//! All coordinates are base-grid vertex indices (i64), inclusive on both ends,
//! so a level-l region's sides are multiples of its spacing 2^l.

use serde::Serialize;

/// A closed rectangle of lattice vertices `[x0, x1] × [y0, y1]`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
pub struct Rect {
    /// Least column.
    pub x0: i64,
    /// Least row.
    pub y0: i64,
    /// Greatest column (inclusive).
    pub x1: i64,
    /// Greatest row (inclusive).
    pub y1: i64,
}

impl Rect {
    /// The rectangle `[x0, x1] × [y0, y1]`.
    pub const fn new(x0: i64, y0: i64, x1: i64, y1: i64) -> Self {
        Rect { x0, y0, x1, y1 }
    }
    /// True when the rectangle encloses no cell (zero width or height).
    pub fn is_degenerate(&self) -> bool {
        self.x1 <= self.x0 || self.y1 <= self.y0
    }
    /// Cells across: x1 − x0.
    pub fn width(&self) -> i64 {
        self.x1 - self.x0
    }
    /// Cells down: y1 − y0.
    pub fn height(&self) -> i64 {
        self.y1 - self.y0
    }
    /// Overlap of two rectangles; `None` if it is not a proper rectangle.
    pub fn intersect(&self, o: &Rect) -> Option<Rect> {
        let r = Rect::new(
            self.x0.max(o.x0),
            self.y0.max(o.y0),
            self.x1.min(o.x1),
            self.y1.min(o.y1),
        );
        (!r.is_degenerate()).then_some(r)
    }
    /// Whether `o` lies wholly inside (edges may touch).
    pub fn contains(&self, o: &Rect) -> bool {
        o.x0 >= self.x0 && o.y0 >= self.y0 && o.x1 <= self.x1 && o.y1 <= self.y1
    }
    /// Whether vertex (x, y) lies inside or on the edge.
    pub fn contains_point(&self, x: i64, y: i64) -> bool {
        x >= self.x0 && x <= self.x1 && y >= self.y0 && y <= self.y1
    }
    /// Shrinks every side by `d`, except sides that lie on `bounds`' own
    /// sides: there is no coarser neighbour beyond a map edge to keep a margin
    /// from.
    pub fn erode_within(&self, d: i64, bounds: &Rect) -> Rect {
        let s = self.sides_on(bounds);
        Rect::new(
            self.x0 + if s[0] { 0 } else { d },
            self.y0 + if s[1] { 0 } else { d },
            self.x1 - if s[2] { 0 } else { d },
            self.y1 - if s[3] { 0 } else { d },
        )
    }
    /// Which sides (x0, y0, x1, y1) coincide with the same side of `bounds`.
    pub fn sides_on(&self, bounds: &Rect) -> [bool; 4] {
        [
            self.x0 == bounds.x0,
            self.y0 == bounds.y0,
            self.x1 == bounds.x1,
            self.y1 == bounds.y1,
        ]
    }
    /// `self` minus `hole` (which must lie inside) as at most 4 rectangles that
    /// share only boundary lines: a top and bottom band across the full width,
    /// and left and right bands between them.
    pub fn minus(&self, hole: Option<&Rect>) -> Vec<Rect> {
        let Some(h) = hole else {
            return vec![*self];
        };
        debug_assert!(self.contains(h));
        [
            Rect::new(self.x0, self.y0, self.x1, h.y0),
            Rect::new(self.x0, h.y1, self.x1, self.y1),
            Rect::new(self.x0, h.y0, h.x0, h.y1),
            Rect::new(h.x1, h.y0, self.x1, h.y1),
        ]
        .into_iter()
        .filter(|r| !r.is_degenerate())
        .collect()
    }
    /// Cells enclosed: width × height.
    pub fn cell_area(&self) -> i64 {
        self.width() * self.height()
    }
}

/// Parameters that fix a clipmap's region layout.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RegionParams {
    /// Grid size n = 2^k − 1 vertices per side.
    pub n: i64,
    /// Number of levels L.
    pub levels: usize,
    /// Usable map bounds (base vertices); `None` for an unbounded layout where
    /// active regions are the full clip regions (GPU Gems 2 footprints).
    pub map: Option<Rect>,
}

/// The regions of one level.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct LevelRegions {
    /// Window origin in level-l units: the clip region starts at origin·2^l.
    pub origin: [i64; 2],
    /// The n×n window held in the level's toroid.
    pub clip: Rect,
    /// What this level covers when rendered; `None` if the level is inactive.
    pub active: Option<Rect>,
    /// Sides of `active` (x0, y0, x1, y1) on the map edge: no coarser level
    /// lies beyond them, so they get neither morphing nor a stitching ring.
    pub map_sides: [bool; 4],
}

/// m = (n + 1) / 4: the GPU Gems 2 block size.
pub fn block_size(n: i64) -> i64 {
    (n + 1) / 4
}

/// Window origins of all levels, finest first, for a viewer at `v` (base-grid
/// units). Level 0 is the even origin that centres its window within one
/// texel of the viewer; each coarser origin is then f − m or f − m + 1
/// (f = finer origin / 2), whichever is even. The finer window so sits m − 1 or
/// m coarse cells inside the coarser one (the four trim positions of GPU
/// Gems 2), every centre stays within one level texel of the viewer, and the
/// boundaries lie on even vertices of the next coarser level.
fn first_origin(n: i64, v: [f64; 2]) -> [i64; 2] {
    let h = ((n - 1) / 2) as f64;
    [0usize, 1].map(|a| 2 * floor_i64((v[a] - h) / 2.0 + 0.5))
}

/// `x.floor() as i64`, without the call to libm's `floor` that x86-64
/// without SSE4.1 makes (every update asks for level 0's origin two or
/// three times): truncate, then step down where that rounded up. The same
/// value for every input, saturation and NaN (0) included.
#[inline]
fn floor_i64(x: f64) -> i64 {
    let t = x as i64;
    if (t as f64) > x {
        t.saturating_sub(1)
    } else {
        t
    }
}

/// The next coarser level's origin, see `first_origin`.
pub fn coarser_origin(o: [i64; 2], m: i64) -> [i64; 2] {
    o.map(|c| {
        let f = c / 2;
        if (f - m).rem_euclid(2) == 0 {
            f - m
        } else {
            f - m + 1
        }
    })
}

/// The viewer position the windows centre on: clamped into the usable map,
/// so a viewer beyond an edge still sees every level.
pub fn clamp_viewer(map: Option<&Rect>, v: [f64; 2]) -> [f64; 2] {
    match map {
        Some(m) => [
            v[0].clamp(m.x0 as f64, m.x1 as f64),
            v[1].clamp(m.y0 as f64, m.y1 as f64),
        ],
        None => v,
    }
}

/// Clip, active and render regions for every level, finest first.
///
/// Active regions are built coarse to fine: the coarsest is its clip region
/// cropped to the map; each finer one is its clip region ∩ map ∩ the coarser
/// active region eroded by 2 coarse texels (not on map sides). A level whose
/// active region has no cell, and every level finer than it, is inactive.
pub fn compute(p: &RegionParams, viewer: [f64; 2]) -> Vec<LevelRegions> {
    let mut out = Vec::with_capacity(p.levels);
    compute_into(p, viewer, &mut out);
    out
}

/// Level 0's window origin for a viewer. Every level's regions follow from
/// it, so while it stays put they do too.
pub fn level0_origin(p: &RegionParams, viewer: [f64; 2]) -> [i64; 2] {
    first_origin(p.n, clamp_viewer(p.map.as_ref(), viewer))
}

/// [`compute`] into a list kept from frame to frame, so an update
/// allocates nothing.
pub fn compute_into(p: &RegionParams, viewer: [f64; 2], out: &mut Vec<LevelRegions>) {
    out.clear();
    let mut o = level0_origin(p, viewer);
    for l in 0..p.levels {
        out.push(unactivated(p.n, o, l));
        o = coarser_origin(o, block_size(p.n));
    }
    activate(p, out, p.levels);
}

/// [`compute_into`] with each level placed on its own centre where
/// `wants[l]` gives one (base-grid units; a view-dependent clipmap's), as
/// near to it as nesting allows. The coarsest level keeps the viewer's
/// window; each finer one is then placed coarse to fine, its window origin
/// `f` the even origin nearest to centring it on its want (on the viewer
/// where it has none), clamped for the coarser origin `c` to
/// `[2c + 2⌈w⌉ + 2, 2c + 2⌊(n − 1)/2 − w − 1⌋]`, `w` the morph's
/// transition width. There the finer window lies where the coarser
/// level's morph, centred on its own window, is 0: |x − centre| ≤
/// (n − 1)/2 − w − 1 coarse texels, so the coarser vertices the finer
/// boundary meets keep their own heights and the finer boundary, whose
/// morph is 1, meets them exactly. That range also lies inside the coarser
/// window eroded by 2 coarse texels (w ≥ 1), where the active regions keep
/// finer regions, and holds the viewer's own chain (f − m or f − m + 1 for
/// w ≤ m − 3), so wants of `None` everywhere give [`compute_into`]'s
/// regions.
pub fn placed_into(
    p: &RegionParams,
    viewer: [f64; 2],
    width: f32,
    wants: &[Option<[f64; 2]>],
    out: &mut Vec<LevelRegions>,
) {
    out.clear();
    let viewer = clamp_viewer(p.map.as_ref(), viewer);
    let mut chain = Vec::with_capacity(p.levels);
    let mut o = first_origin(p.n, viewer);
    for _ in 0..p.levels {
        chain.push(o);
        o = coarser_origin(o, block_size(p.n));
    }
    let half = ((p.n - 1) / 2) as f32;
    let (lo, hi) = (
        2 * width.ceil() as i64 + 2,
        2 * (half - width - 1.0).floor() as i64,
    );
    let mut origins = chain.clone();
    for l in (0..p.levels.saturating_sub(1)).rev() {
        let c = origins[l + 1];
        let scale = 0.5f64.powi(l as i32);
        let want = wants.get(l).copied().flatten().map_or(chain[l], |w| {
            let w = clamp_viewer(p.map.as_ref(), w);
            first_origin(p.n, [w[0] * scale, w[1] * scale])
        });
        origins[l] = [0, 1].map(|a| want[a].clamp(2 * c[a] + lo, 2 * c[a] + hi.max(lo)));
    }
    for (l, &o) in origins.iter().enumerate() {
        out.push(unactivated(p.n, o, l));
    }
    activate(p, out, p.levels);
}

/// [`compute_into`] for a list that holds `compute`'s result for an earlier
/// viewer: only the levels up to the coarsest whose origin moved are
/// recomputed, since a level's regions depend on its origin and on the
/// coarser levels alone. A one-texel walk moves level l every 2^(l+1)
/// frames, so most frames touch one or two levels. Same result, bit for bit.
pub fn update_into(p: &RegionParams, viewer: [f64; 2], out: &mut [LevelRegions]) {
    debug_assert_eq!(out.len(), p.levels);
    let mut o = level0_origin(p, viewer);
    let mut moved = 0;
    for (l, r) in out.iter_mut().enumerate() {
        if r.origin == o {
            // Coarser origins follow from this one, so they stay put too.
            break;
        }
        *r = unactivated(p.n, o, l);
        moved = l + 1;
        o = coarser_origin(o, block_size(p.n));
    }
    activate(p, out, moved);
}

/// Level `l`'s regions for window origin `o` before [`activate`] sets its
/// active region: its clip region, in base vertices.
fn unactivated(n: i64, o: [i64; 2], l: usize) -> LevelRegions {
    let g = 1i64 << l;
    LevelRegions {
        origin: o,
        clip: Rect::new(o[0] * g, o[1] * g, (o[0] + n - 1) * g, (o[1] + n - 1) * g),
        active: None,
        map_sides: [false; 4],
    }
}

/// Active regions of levels `[0, upto)`, coarse to fine, from their clip
/// regions and the active region of level `upto` (if there is one). The
/// coarsest is its clip region cropped to the map; each finer one is its
/// clip region ∩ map ∩ the coarser active region eroded by 2 coarse texels.
/// Below an inactive level every level is inactive.
fn activate(p: &RegionParams, out: &mut [LevelRegions], upto: usize) {
    let mut coarser: Option<Rect> = out.get(upto).and_then(|r| r.active);
    if upto < p.levels && coarser.is_none() {
        return;
    }
    for l in (0..upto).rev() {
        let clip = out[l].clip;
        let active = match (&p.map, l + 1 == p.levels) {
            (None, _) => Some(clip),
            (Some(map), true) => clip.intersect(map),
            (Some(map), false) => coarser.and_then(|c| {
                let eroded = c.erode_within(2 << (l + 1), map);
                clip.intersect(map).and_then(|r| r.intersect(&eroded))
            }),
        };
        let Some(a) = active else { break };
        out[l].active = Some(a);
        out[l].map_sides = p.map.map(|m| a.sides_on(&m)).unwrap_or([false; 4]);
        coarser = Some(a);
    }
}

/// Render region of level l: its active region minus the finer active region.
pub fn render_rects(levels: &[LevelRegions], l: usize) -> Vec<Rect> {
    match levels[l].active {
        None => vec![],
        Some(a) => a.minus(l.checked_sub(1).and_then(|f| levels[f].active).as_ref()),
    }
}

/// Usable map bounds for `levels` levels on a `width`×`height` map: each axis
/// is cut down to a multiple of the coarsest spacing, so every active
/// boundary lies on even vertices of the next coarser level (Brettell's
/// finite-map bounds). At most 2^(L−1) − 1 texels are lost per axis.
pub fn map_bounds(width: usize, height: usize, levels: usize) -> Rect {
    let g = 1i64 << (levels - 1);
    Rect::new(
        0,
        0,
        (width as i64 - 1) / g * g,
        (height as i64 - 1) / g * g,
    )
}

/// The most levels a `width`×`height` map supports with grid size n: beyond
/// it, either the map cropped to the coarsest spacing has fewer than 2 coarse
/// cells per axis, or one level's half-window already spans the whole map, so
/// a coarser one would add nothing from any viewer position.
pub fn max_levels(width: usize, height: usize, n: i64) -> usize {
    let (w, h) = (width as i64 - 1, height as i64 - 1);
    let mut l = 1usize;
    loop {
        let g = 1i64 << l; // spacing of a candidate extra level
        let fits = (w / g) * g >= 2 * g && (h / g) * g >= 2 * g;
        let half_window_prev = (n - 1) / 2 * (g / 2);
        if !fits || half_window_prev >= w.max(h) || l >= 30 {
            return l;
        }
        l += 1;
    }
}

/// Validates n = 2^k − 1 with k ≥ 4 (n ≥ 15, so the transition band never
/// reaches a level's inner boundary) and n ≤ 4095.
pub fn check_n(n: i64) -> Result<(), String> {
    let ok = (15..=4095).contains(&n) && (n + 1) & n == 0;
    if ok {
        Ok(())
    } else {
        Err(format!(
            "grid size n must be 2^k − 1 with 15 ≤ n ≤ 4095 (e.g. 15, 31, 63, 127, 255), got {n}"
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Containment is inclusive on every side and fails when any one side
    /// of the inner rectangle crosses the outer one's (`minus` asserts it).
    #[test]
    fn contains_checks_every_side() {
        let r = Rect::new(0, 10, 20, 40);
        assert!(r.contains(&r));
        assert!(r.contains(&Rect::new(5, 15, 10, 30)));
        for o in [
            Rect::new(-1, 15, 10, 30),
            Rect::new(5, 9, 10, 30),
            Rect::new(5, 15, 21, 30),
            Rect::new(5, 15, 10, 41),
        ] {
            assert!(!r.contains(&o), "{o:?}");
        }
    }

    /// The map cropped to the coarsest spacing: (w − 1) and (h − 1) rounded
    /// down to a multiple of 2^(L−1), with sizes on both sides of a multiple.
    #[test]
    fn map_bounds_round_down_to_the_coarsest_spacing() {
        assert_eq!(map_bounds(700, 530, 8), Rect::new(0, 0, 640, 512));
        assert_eq!(map_bounds(256, 128, 8), Rect::new(0, 0, 128, 0));
        assert_eq!(map_bounds(257, 129, 8), Rect::new(0, 0, 256, 128));
        assert_eq!(map_bounds(5, 5, 1), Rect::new(0, 0, 4, 4));
    }

    /// Points on every side count; one step past any side does not.
    #[test]
    fn contains_point_is_inclusive() {
        let r = Rect::new(0, 10, 20, 40);
        for (x, y) in [(0, 10), (20, 40), (0, 40), (20, 10), (7, 23)] {
            assert!(r.contains_point(x, y), "({x}, {y})");
        }
        for (x, y) in [(-1, 20), (21, 20), (5, 9), (5, 41)] {
            assert!(!r.contains_point(x, y), "({x}, {y})");
        }
    }

    /// Each side moves in by d, except the sides that lie on the bounds'.
    #[test]
    fn erode_within_keeps_the_sides_on_the_bounds() {
        let r = Rect::new(0, 10, 20, 40);
        let inside = Rect::new(-100, -100, 100, 100);
        assert_eq!(r.erode_within(3, &inside), Rect::new(3, 13, 17, 37));
        assert_eq!(r.erode_within(3, &r), r);
        let left_top = Rect::new(0, 10, 100, 100);
        assert_eq!(r.erode_within(3, &left_top), Rect::new(0, 10, 17, 37));
        let right_bottom = Rect::new(-100, -100, 20, 40);
        assert_eq!(r.erode_within(3, &right_bottom), Rect::new(3, 13, 20, 40));
    }

    #[test]
    fn n_validation() {
        for n in [15, 31, 63, 127, 255, 4095] {
            assert!(check_n(n).is_ok(), "{n}");
        }
        for n in [0, 7, 16, 64, 100, 257, 8191] {
            assert!(check_n(n).is_err(), "{n}");
        }
    }

    #[test]
    fn minus_gives_four_bands_with_the_right_area() {
        let a = Rect::new(0, 0, 20, 20);
        let h = Rect::new(4, 6, 12, 14);
        let parts = a.minus(Some(&h));
        assert_eq!(parts.len(), 4);
        let area: i64 = parts.iter().map(|r| r.cell_area()).sum();
        assert_eq!(area, a.cell_area() - h.cell_area());
    }

    #[test]
    fn jacksboro_level_limits() {
        assert_eq!(max_levels(403, 344, 63), 5);
        assert_eq!(map_bounds(403, 344, 5), Rect::new(0, 0, 400, 336));
    }

    #[test]
    fn floor_i64_matches_floor_then_cast() {
        let mut cases = vec![
            0.0,
            -0.0,
            0.5,
            -0.5,
            1.0,
            -1.0,
            2.5e-300,
            -2.5e-300,
            4503599627370495.5,
            -4503599627370495.5,
            9.3e18,
            -9.3e18,
            1e300,
            -1e300,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
            f64::MAX,
            f64::MIN,
        ];
        // Every 0.25 step around zero, and neighbours of integers.
        cases.extend((-40..40).map(|i| i as f64 * 0.25));
        cases.extend((-5..5).flat_map(|i| {
            let f = i as f64 * 1e6;
            [f.next_up(), f.next_down()]
        }));
        for x in cases {
            assert_eq!(floor_i64(x), x.floor() as i64, "x = {x:e}");
        }
    }

    fn params(n: i64) -> RegionParams {
        RegionParams {
            n,
            levels: 5,
            map: Some(map_bounds(700, 530, 5)),
        }
    }

    /// With no wants, placing is the viewer's chain: `compute`'s regions.
    #[test]
    fn placing_without_wants_is_the_viewers_chain() {
        for n in [15, 31, 63] {
            for v in [[350.0, 260.0], [3.0, 520.0], [-80.0, 900.0]] {
                let mut placed = Vec::new();
                // The default transition width, n/10 capped at m − 3.
                let w = (n as f32 / 10.0).min((block_size(n) - 3) as f32);
                placed_into(&params(n), v, w, &[None; 5], &mut placed);
                assert_eq!(placed, compute(&params(n), v), "n = {n}, viewer {v:?}");
            }
        }
    }

    /// Each level goes as near its want as the coarser window allows:
    /// inside it eroded by 2 coarse texels, on even origins, and within a
    /// texel of the want where that fits.
    #[test]
    fn placed_levels_nest_and_follow_their_wants() {
        let p = params(31);
        let viewer = [100.0, 100.0];
        // Level 0 wants a point 4 texels off the viewer: within the slack
        // that level 1's morph leaves it with w = 3, f in [2c + 8, 2c + 22]
        // about the chain's 2c + 14 or 2c + 16.
        let mut out = Vec::new();
        placed_into(
            &p,
            viewer,
            3.0,
            &[Some([104.0, 96.0]), None, None, None, None],
            &mut out,
        );
        let c0 = [out[0].clip.x0 + 15, out[0].clip.y0 + 15];
        assert!(
            (c0[0] - 104).abs() <= 1 && (c0[1] - 96).abs() <= 1,
            "{c0:?}"
        );
        // Every level wants a point far off: each is clamped into its
        // coarser window, which stays on the viewer's chain at the top.
        placed_into(&p, viewer, 3.0, &[Some([600.0, 500.0]); 5], &mut out);
        let chain = compute(&p, viewer);
        assert_eq!(out[4].origin, chain[4].origin);
        for l in 0..4 {
            let (f, c) = (out[l].origin, out[l + 1].origin);
            assert!(f.iter().all(|x| x % 2 == 0), "level {l}: {f:?}");
            for a in 0..2 {
                assert!(
                    (2 * c[a] + 4..=2 * c[a] + p.n - 5).contains(&f[a]),
                    "level {l}, axis {a}: {f:?} in {c:?}"
                );
            }
            // Pushed to the far end of the slack, toward the want: the
            // window's far side 11 − 4 − 1 = 6 coarse texels past the
            // coarser centre, where its morph is still 0.
            assert_eq!(f, [2 * c[0] + 22, 2 * c[1] + 22], "level {l}");
        }
    }
}
