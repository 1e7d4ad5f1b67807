//! `fog`: exponential fog, f = exp(−density · distance), as ATLOD uses. The
//! factor is computed per vertex in f64 (classic per-vertex fog) and
//! interpolated, so no transcendental function runs per pixel and a GPU
//! back end can take the same factor as a vertex attribute.

/// The fog factor at `distance` metres (1 = clear, 0 = fully fogged).
pub fn factor(density: f64, distance: f64) -> f32 {
    (-density * distance).exp() as f32
}

/// c · f + fog · (1 − f).
#[inline]
pub fn apply(c: [f32; 3], fog: [f32; 3], f: f32) -> [f32; 3] {
    let g = 1.0 - f;
    [
        c[0] * f + fog[0] * g,
        c[1] * f + fog[1] * g,
        c[2] * f + fog[2] * g,
    ]
}
