//! Per-eye camera maths: OpenXR hands us an asymmetric field of view and a pose per view; Vulkan
//! wants clip space with y pointing down and depth in 0..1. Pure functions, unit-tested.

use glam::{Mat4, Quat, Vec3, Vec4};

pub const NEAR: f32 = 0.05;
pub const FAR: f32 = 2000.0;

/// The four half-angles of an `XrFovf`, in radians (left and down are normally negative).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fov {
    pub left: f32,
    pub right: f32,
    pub up: f32,
    pub down: f32,
}

/// Off-axis perspective projection for a right-handed view space looking down −Z.
/// Standard depth maps near→0, far→1; reversed maps near→1, far→0 (better float precision far away).
pub fn projection(fov: Fov, near: f32, far: f32, reversed: bool) -> Mat4 {
    let (tl, tr) = (fov.left.tan(), fov.right.tan());
    let (tu, td) = (fov.up.tan(), fov.down.tan());
    let sx = 2.0 / (tr - tl);
    let ox = (tr + tl) / (tr - tl);
    // Vulkan's y axis points down: the top edge (tan up) must land on −1.
    let sy = 2.0 / (td - tu);
    let oy = (tu + td) / (td - tu);
    // z_ndc = (a·z + b) / −z; swapping near and far gives the reversed mapping.
    let (n, f) = if reversed { (far, near) } else { (near, far) };
    let a = f / (n - f);
    let b = n * f / (n - f);
    // Rows written out, then transposed into glam's column-major storage.
    Mat4::from_cols(
        Vec4::new(sx, 0.0, 0.0, 0.0),
        Vec4::new(0.0, sy, 0.0, 0.0),
        Vec4::new(ox, oy, a, -1.0),
        Vec4::new(0.0, 0.0, b, 0.0),
    )
}

/// World (STAGE) → view transform: the inverse of the eye's pose.
pub fn view_matrix(orientation: Quat, position: Vec3) -> Mat4 {
    Mat4::from_rotation_translation(orientation, position).inverse()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fov() -> Fov {
        Fov { left: -0.9, right: 0.8, up: 0.7, down: -0.95 }
    }

    fn ndc(m: Mat4, p: Vec3) -> Vec3 {
        let c = m * p.extend(1.0);
        c.truncate() / c.w
    }

    #[test]
    fn optical_axis_hits_projection_centre() {
        let f = fov();
        let m = projection(f, NEAR, FAR, false);
        // The point straight ahead lands where the asymmetric frustum puts the centre.
        let p = ndc(m, Vec3::new(0.0, 0.0, -3.0));
        let (tl, tr, tu, td) = (f.left.tan(), f.right.tan(), f.up.tan(), f.down.tan());
        assert!((p.x - (-(tr + tl) / (tr - tl))).abs() < 1e-5);
        assert!((p.y - (-(tu + td) / (td - tu))).abs() < 1e-5);
        // A symmetric frustum puts it at the origin.
        let s = projection(Fov { left: -0.7, right: 0.7, up: 0.6, down: -0.6 }, NEAR, FAR, false);
        let q = ndc(s, Vec3::new(0.0, 0.0, -7.0));
        assert!(q.x.abs() < 1e-6 && q.y.abs() < 1e-6);
    }

    #[test]
    fn frustum_edges_map_to_ndc_edges_with_y_down() {
        let f = fov();
        let m = projection(f, NEAR, FAR, false);
        let z = -2.0;
        let left = ndc(m, Vec3::new(f.left.tan() * 2.0, 0.0, z));
        let right = ndc(m, Vec3::new(f.right.tan() * 2.0, 0.0, z));
        let up = ndc(m, Vec3::new(0.0, f.up.tan() * 2.0, z));
        let down = ndc(m, Vec3::new(0.0, f.down.tan() * 2.0, z));
        assert!((left.x + 1.0).abs() < 1e-5 && (right.x - 1.0).abs() < 1e-5);
        assert!((up.y + 1.0).abs() < 1e-5, "up must be −1 in Vulkan");
        assert!((down.y - 1.0).abs() < 1e-5);
    }

    #[test]
    fn depth_ranges() {
        let m = projection(fov(), NEAR, FAR, false);
        assert!(ndc(m, Vec3::new(0.0, 0.0, -NEAR)).z.abs() < 1e-5);
        assert!((ndc(m, Vec3::new(0.0, 0.0, -FAR)).z - 1.0).abs() < 1e-4);
        let r = projection(fov(), NEAR, FAR, true);
        assert!((ndc(r, Vec3::new(0.0, 0.0, -NEAR)).z - 1.0).abs() < 1e-5, "reversed: near → 1");
        assert!(ndc(r, Vec3::new(0.0, 0.0, -FAR)).z.abs() < 1e-5, "reversed: far → 0");
        // Monotonic in the expected direction.
        let a = ndc(r, Vec3::new(0.0, 0.0, -1.0)).z;
        let b = ndc(r, Vec3::new(0.0, 0.0, -10.0)).z;
        assert!(a > b);
    }

    #[test]
    fn view_matrix_inverts_pose() {
        let q = Quat::from_rotation_y(0.3);
        let pos = Vec3::new(-0.032, 1.6, 0.0);
        let v = view_matrix(q, pos);
        assert!(v.transform_point3(pos).length() < 1e-6);
        // A point ahead of the rotated eye is on the view's −Z axis.
        let ahead = pos + q * Vec3::new(0.0, 0.0, -5.0);
        let p = v.transform_point3(ahead);
        assert!((p - Vec3::new(0.0, 0.0, -5.0)).length() < 1e-5);
    }
}
