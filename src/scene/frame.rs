//! Framing a map: the camera a scene gets when it names none.

use super::Scene;
use crate::camera::Camera;
use crate::error::Result;
use crate::terrain::world::WorldMap;
use glam::DVec3;

/// Points the scene's camera at its terrain: an oblique overview from the
/// south, placed from the map's extent and relief, with the far plane and
/// the near plane scaled to the map. For a scene without a `[camera]`, and
/// for a map given on the command line without one (`render --heightmap`),
/// whose scene placed its camera for another terrain. The fog follows the
/// new far plane where the caller says so ([`Scene::fog_from_far`]).
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
    scene.validate()
}
