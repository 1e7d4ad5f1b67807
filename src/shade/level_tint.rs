//! `level-tint`: a flat colour per clipmap level, so the nested rings (and
//! their transition bands under lighting) can be seen.

/// The 8 level colours, repeating every 8 levels (export writes them to
/// `frame.json` as `level_palette`).
pub const PALETTE: [[u8; 3]; 8] = [
    [230, 25, 75],
    [60, 180, 75],
    [255, 225, 25],
    [0, 130, 200],
    [245, 130, 48],
    [145, 30, 180],
    [70, 240, 240],
    [240, 50, 230],
];

/// The colour of level `l` (8 distinct colours, repeating).
pub fn level_colour(l: usize) -> [u8; 3] {
    PALETTE[l % PALETTE.len()]
}

/// The albedo that replaces the height ramp under `level-tint`.
pub fn albedo(level: u32) -> [f32; 3] {
    level_colour(level as usize).map(|c| c as f32 / 255.0)
}
