//! Fovea geometry shared by the foveation methods and the gaze policy: view directions as
//! tangent-plane points, the angle between two of them, the rings around a fovea centre, and the
//! rotation of a gaze direction into a view (glam does the quaternion and vector work).
#![forbid(unsafe_code)]

use glam::{DVec3, Quat, Vec3};

/// A direction as a tangent-plane point of a view (x right, y up; z = −1).
pub type Tangent = [f32; 2];

/// Angle between two view directions given as tangent-plane points, degrees (in f64: the rate
/// maps compare it against ring radii at texel corners, where f32 rounding would flip rings).
pub fn angle_between_deg(a: Tangent, b: Tangent) -> f32 {
    let a = DVec3::new(a[0] as f64, a[1] as f64, -1.0);
    let b = DVec3::new(b[0] as f64, b[1] as f64, -1.0);
    (a.dot(b) / (a.length() * b.length())).clamp(-1.0, 1.0).acos().to_degrees() as f32
}

/// How far a quad's view direction lies from the fovea centre direction.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Ring {
    /// Within `inner_deg`: every quad shaded.
    Inner,
    /// Up to `middle_deg`: a checkerboard of quads, half of them skipped.
    Middle,
    /// Beyond: one quad in four shaded (both quad coordinates even).
    Outer,
}

/// A gaze direction (in the space the views were located in) as a tangent-plane point of a view
/// with orientation `q_space_view` (x, y, z, w); None when it points behind the view.
pub fn gaze_in_view(q_space_view: [f32; 4], gaze_dir_space: [f32; 3]) -> Option<Tangent> {
    let t_view_space = Quat::from_array(q_space_view).inverse();
    let d = t_view_space * Vec3::from_array(gaze_dir_space);
    // Directions more than ~85° off the view axis cannot be a fovea on any HMD.
    (d.z < -0.08).then(|| [d.x / -d.z, d.y / -d.z])
}

/// The forward direction (−z) of an orientation (x, y, z, w).
pub fn forward(q: [f32; 4]) -> [f32; 3] {
    (Quat::from_array(q) * Vec3::NEG_Z).to_array()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn angles() {
        assert!((angle_between_deg([0.0, 0.0], [1.0, 0.0]) - 45.0).abs() < 1e-4);
        assert!(angle_between_deg([0.3, 0.2], [0.3, 0.2]) < 1e-3);
    }

    #[test]
    fn gaze_rotates_into_the_view() {
        // A view yawed 90° left (about +y) sees a gaze pointing left (−x) straight ahead.
        let h = std::f32::consts::FRAC_1_SQRT_2;
        let q = [0.0, h, 0.0, h];
        let t = gaze_in_view(q, [-1.0, 0.0, 0.0]).unwrap();
        assert!(t[0].abs() < 1e-5 && t[1].abs() < 1e-5, "{t:?}");
        let f = forward(q);
        assert!((f[0] + 1.0).abs() < 1e-5 && f[1].abs() < 1e-5 && f[2].abs() < 1e-5, "{f:?}");
        assert!(gaze_in_view([0.0, 0.0, 0.0, 1.0], [0.0, 0.0, 1.0]).is_none(), "behind the view");
    }
}
