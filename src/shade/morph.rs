//! `morph`: geomorphing is a geometry effect, done by the clipmap's vertex
//! stage (see `clipmap::morph`). Listing it turns it on; leaving it out
//! renders the raw nested grids, so the cracks and pops it hides show. Its
//! α also weights the normal-map and lightmap blends, which read it here.

/// Blend of a fine and a coarse sample by α, (1 − α)·f + α·c, no FMA.
#[inline]
pub fn blend3(f: [f32; 3], c: [f32; 3], alpha: f32) -> [f32; 3] {
    let k = 1.0 - alpha;
    [
        k * f[0] + alpha * c[0],
        k * f[1] + alpha * c[1],
        k * f[2] + alpha * c[2],
    ]
}
