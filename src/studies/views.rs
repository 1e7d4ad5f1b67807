//! Deterministic camera sets for the surveys: random views above the
//! terrain (cracks), the wide and low-FOV view sets ATLOD measured error on
//! (tradeoff); the straight paths are [`crate::camera::path`].

use crate::camera::Camera;
use crate::render::Session;
use glam::DVec3;

/// xorshift64*, so view sets are the same on every machine.
pub struct Rng(u64);

impl Rng {
    /// A generator started from `seed`: the same views on every machine.
    pub fn new(seed: u64) -> Self {
        Rng(seed.max(1))
    }
    /// Uniform in [0, 1).
    pub fn uniform(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// A named view.
#[derive(Clone, Debug)]
pub struct NamedView {
    /// The view's name in reports (`wide-3`, `low-fov-20`).
    pub name: String,
    /// "wide" or "low-fov".
    pub kind: &'static str,
    /// The camera.
    pub camera: Camera,
}

/// `count` views from above the terrain looking at random points on it.
pub fn random_views(session: &Session, template: &Camera, count: usize, seed: u64) -> Vec<Camera> {
    let (lo, hi) = session.extent();
    let size = hi - lo;
    let relief = size.z.max(0.05 * size.x.min(size.y));
    let mut rng = Rng::new(seed);
    (0..count)
        .map(|_| {
            let x = lo.x + size.x * (0.1 + 0.8 * rng.uniform());
            let y = lo.y + size.y * (0.1 + 0.8 * rng.uniform());
            let z = session.ground(x, y) + relief * (0.05 + 0.5 * rng.uniform());
            let (tx, ty) = (lo.x + size.x * rng.uniform(), lo.y + size.y * rng.uniform());
            let target = DVec3::new(tx, ty, session.ground(tx, ty));
            Camera {
                eye: DVec3::new(x, y, z),
                target,
                ..*template
            }
        })
        .collect()
}

/// ATLOD's two view sets: four wide views (60°) from above the terrain
/// looking across it, and four low-FOV views (1°, 2°, 4°, 6°) from one
/// side looking at distant points, where LOD error is magnified.
pub fn atlod_views(session: &Session, template: &Camera) -> Vec<NamedView> {
    let (lo, hi) = session.extent();
    let size = hi - lo;
    // The far plane reaches across the whole map (a continent-sized DEM
    // needs more than a scene's default).
    let far = template.far.max(2.0 * size.length());
    let template = &Camera {
        far,
        near: template.near.max(far * 1e-6),
        ..*template
    };
    let relief = size.z.max(0.02 * size.x.min(size.y));
    let at = |fx: f64, fy: f64, up: f64| {
        let (x, y) = (lo.x + size.x * fx, lo.y + size.y * fy);
        DVec3::new(x, y, session.ground(x, y) + up)
    };
    // Heights and distances scale with the map's horizontal extent too, so
    // a continent-sized DEM is seen from an aircraft, not from a hill.
    let span = size.x.min(size.y.abs());
    let lift = 0.01 * span;
    let mut out = Vec::new();
    let wide = [(0.2, 0.2), (0.8, 0.2), (0.8, 0.8), (0.2, 0.8)];
    for (i, &(fx, fy)) in wide.iter().enumerate() {
        let eye = at(fx, fy, 0.4 * relief + lift);
        // Toward the centre, 0.15 of the map's width away.
        let d = DVec3::new(0.5 - fx, 0.5 - fy, 0.0).normalize() * 0.15;
        let target = at(fx + d.x, fy + d.y, 0.0);
        out.push(NamedView {
            name: format!("wide-{i}"),
            kind: "wide",
            camera: Camera {
                eye,
                target,
                fov_y_deg: 60.0,
                ..*template
            },
        });
    }
    let narrow = [
        (1.0, 0.7, 0.3),
        (2.0, 0.5, 0.5),
        (4.0, 0.3, 0.7),
        (6.0, 0.6, 0.6),
    ];
    for &(fov, tx, ty) in &narrow {
        let eye = at(0.05, 0.05, 0.3 * relief + lift);
        let target = at(tx, ty, 0.0);
        out.push(NamedView {
            name: format!("low-fov-{fov}"),
            kind: "low-fov",
            camera: Camera {
                eye,
                target,
                fov_y_deg: fov,
                ..*template
            },
        });
    }
    out
}
