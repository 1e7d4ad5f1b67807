//! Perspective camera in f64 world space, with frustum planes in the wgpu
//! clip convention (0 ≤ z ≤ w), and the straight camera paths that flights,
//! exports and popping measurements follow. It sits below every stage:
//! culling, LOD and the frame read it, and none of it reads a scene.

use glam::{DMat4, DVec3, DVec4};

/// A perspective camera in world metres (f64, so a view far from the origin keeps its
/// precision until the vertex stage subtracts the floating origin).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Eye position.
    pub eye: DVec3,
    /// The point looked at; z is up.
    pub target: DVec3,
    /// Vertical field of view in degrees.
    pub fov_y_deg: f64,
    /// Near plane distance (metres).
    pub near: f64,
    /// Far plane distance (metres).
    pub far: f64,
    /// Width ÷ height of the image.
    pub aspect: f64,
}

impl Camera {
    /// Up vector: world z, unless the view is (nearly) vertical, where the
    /// camera keeps north (+y) up so looking straight down still works.
    pub fn up(&self) -> DVec3 {
        let d = (self.target - self.eye).normalize_or_zero();
        if d.cross(DVec3::Z).length_squared() < 1e-12 {
            DVec3::Y
        } else {
            DVec3::Z
        }
    }
    /// Right-handed view matrix: the camera looks down its −z axis.
    pub fn view(&self) -> DMat4 {
        let f = (self.target - self.eye).normalize();
        let s = f.cross(self.up()).normalize();
        let u = s.cross(f);
        DMat4::from_cols(
            DVec4::new(s.x, u.x, -f.x, 0.0),
            DVec4::new(s.y, u.y, -f.y, 0.0),
            DVec4::new(s.z, u.z, -f.z, 0.0),
            DVec4::new(-s.dot(self.eye), -u.dot(self.eye), f.dot(self.eye), 1.0),
        )
    }
    /// Right-handed perspective with depth mapped to [0, 1] (wgpu/Vulkan).
    pub fn projection(&self) -> DMat4 {
        let h = 1.0 / (0.5 * self.fov_y_deg.to_radians()).tan();
        let w = h / self.aspect;
        let r = self.far / (self.near - self.far);
        DMat4::from_cols(
            DVec4::new(w, 0.0, 0.0, 0.0),
            DVec4::new(0.0, h, 0.0, 0.0),
            DVec4::new(0.0, 0.0, r, -1.0),
            DVec4::new(0.0, 0.0, r * self.near, 0.0),
        )
    }
    /// Projection × view: world to wgpu clip space (0 ≤ z ≤ w).
    pub fn view_projection(&self) -> DMat4 {
        self.projection() * self.view()
    }
    /// The unit direction of the ray from the eye through window position
    /// (wx, wy) of a `size` image (pixel centres at +0.5, y down), in f64.
    pub fn ray_through(&self, size: [u32; 2], wx: f64, wy: f64) -> DVec3 {
        let xn = wx / size[0] as f64 * 2.0 - 1.0;
        let yn = 1.0 - wy / size[1] as f64 * 2.0;
        let p = self.view_projection().inverse() * DVec4::new(xn, yn, 0.5, 1.0);
        (p.truncate() / p.w - self.eye).normalize()
    }
    /// The six inward-facing planes (left, right, bottom, top, near, far):
    /// a point p is inside when `plane.xyz · p + plane.w ≥ 0` for all six.
    pub fn frustum(&self) -> Frustum {
        let m = self.view_projection();
        let r = [m.row(0), m.row(1), m.row(2), m.row(3)];
        let planes = [
            r[3] + r[0],
            r[3] - r[0],
            r[3] + r[1],
            r[3] - r[1],
            r[2],
            r[3] - r[2],
        ]
        .map(|p| p / p.truncate().length());
        let inv = m.inverse();
        let mut corners = [DVec3::ZERO; 8];
        for (i, c) in corners.iter_mut().enumerate() {
            let x = if i & 1 == 0 { -1.0 } else { 1.0 };
            let y = if i & 2 == 0 { -1.0 } else { 1.0 };
            let z = if i & 4 == 0 { 0.0 } else { 1.0 };
            let h = inv * DVec4::new(x, y, z, 1.0);
            *c = h.truncate() / h.w;
        }
        Frustum { planes, corners }
    }
}

/// Frustum as planes plus its 8 corner points.
#[derive(Clone, Copy, Debug)]
pub struct Frustum {
    /// Left, right, bottom, top, near and far as (normal, d), normals inward.
    pub planes: [DVec4; 6],
    /// The corners, near plane first.
    pub corners: [DVec3; 8],
}

impl Frustum {
    /// Signed distance of `p` from `plane` (positive inside).
    #[inline]
    pub fn distance(plane: &DVec4, p: DVec3) -> f64 {
        plane.truncate().dot(p) + plane.w
    }
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
