//! Deterministic camera sets for the surveys: random views above the
//! terrain (cracks), the wide and low-FOV view sets ATLOD measured error on
//! (tradeoff), and straight camera paths (fly, popping).

use crate::error::Result;
use crate::render::Session;
use crate::scene::camera::Camera;
use crate::scene::Scene;
use crate::terrain::world::WorldMap;
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

/// Points the scene's camera at its terrain: an oblique overview from the
/// south, placed from the map's extent and relief, with the far plane, the
/// near plane and the fog scaled to the map. For a map given on the command
/// line without a camera (`render --heightmap`), whose scene placed its
/// camera, far plane and fog for another terrain.
pub fn frame_terrain(scene: &mut Scene) -> Result<()> {
    let named = |e| scene.named(e);
    // A pack's header holds its size and relief: nothing is decoded.
    let (cell, [w, r], [min, max]) =
        match crate::pack::file::pack_path(&scene.terrain, &scene.base_dir) {
            Some(path) => {
                let h = crate::pack::file::read_header(&path).map_err(named)?;
                (
                    crate::pack::file::cell_size(&scene.terrain, &h),
                    h.size(),
                    h.range(),
                )
            }
            None => {
                let h = crate::terrain::load(&scene.terrain, &scene.base_dir).map_err(named)?;
                let (lo, hi) = h.min_max();
                (h.cell_size, [h.width(), h.height()], [lo, hi])
            }
        };
    let world = WorldMap::for_terrain(&scene.terrain, cell);
    let (w, r) = ((w - 1) as f64, (r - 1) as f64);
    let (lo, hi) = world.aabb(0.0, 0.0, w, r, min as f64, max as f64);
    let size = hi - lo;
    let span = size.x.max(size.y);
    let centre = DVec3::new(
        (lo.x + hi.x) / 2.0,
        (lo.y + hi.y) / 2.0,
        (lo.z + hi.z) / 2.0,
    );
    // From the south, 35° down, at the nearest distance (to 1 %) from
    // which the map's eight bounding-box corners all project inside 90 %
    // of the frame.
    let down = 35f64.to_radians();
    let dir = DVec3::new(0.0, -down.cos(), down.sin());
    let aspect = scene.image.width as f64 / scene.image.height as f64;
    let camera_at = |dist: f64| Camera {
        eye: centre + dir * dist,
        target: centre,
        fov_y_deg: scene.camera.fov,
        near: dist * 1e-3,
        far: 4.0 * (dist + span),
        aspect,
    };
    let fits = |dist: f64| {
        let m = camera_at(dist).view_projection();
        (0..8).all(|i| {
            let corner = DVec3::new(
                if i & 1 == 0 { lo.x } else { hi.x },
                if i & 2 == 0 { lo.y } else { hi.y },
                if i & 4 == 0 { lo.z } else { hi.z },
            );
            let c = m * corner.extend(1.0);
            c.w > 0.0 && (c.x / c.w).abs() <= 0.9 && (c.y / c.w).abs() <= 0.9
        })
    };
    let mut dist = span;
    for _ in 0..64 {
        if fits(dist) {
            break;
        }
        dist *= 1.5;
    }
    while dist > 1e-3 * span && fits(dist / 1.01) {
        dist /= 1.01;
    }
    let view = camera_at(dist);
    let c = &mut scene.camera;
    c.position = view.eye.to_array();
    c.look_at = Some(centre.to_array());
    (c.yaw, c.pitch) = (None, None);
    c.far = 2.0 * (dist + span);
    // Depth32Float keeps about 2^-23 of depth, so the near plane scales
    // with the far one: 1e-5 of it keeps the map's nearest edge resolved.
    c.near = (c.far * 1e-5).max(0.01);
    // At least 80 % of the colour left at the map's far edge.
    scene.shading.fog_density = 1.0 / (5.0 * (dist + span));
    scene.validate()
}

/// Frame `i` of a straight path from `base`: `step` metres per frame along
/// the view direction's horizontal part plus 0.37·step sideways (so the
/// path crosses texel boundaries at varying phases), looking the same way.
pub fn path_camera(base: &Camera, i: usize, step: f64) -> Camera {
    let d = base.target - base.eye;
    let fwd = DVec3::new(d.x, d.y, 0.0).normalize_or(DVec3::X);
    let side = DVec3::new(-fwd.y, fwd.x, 0.0);
    let t = i as f64 * step;
    let off = fwd * t + side * (0.37 * t);
    Camera {
        eye: base.eye + off,
        target: base.target + off,
        ..*base
    }
}

/// The first `frames` cameras of [`path_camera`]'s path.
pub fn path(start: &Camera, frames: usize, step: f64) -> Vec<Camera> {
    (0..frames).map(|i| path_camera(start, i, step)).collect()
}
