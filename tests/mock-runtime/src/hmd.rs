//! HMD profiles (`MOCK_XR_HMD`): the per-eye geometry a real headset reports, so that a layer
//! that assumes symmetric, parallel, identical-eye views fails here as it would on hardware. The
//! data (and where each value comes from) is `hmd_profiles::profile`, shared with
//! `stereoshim preview --hmd`, so the preview and the mock runtime cannot drift apart.

pub use hmd_profiles::profile::*;

#[cfg(test)]
use glam::{Quat, Vec3};

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn all_profiles_exist_and_are_sane() {
        for n in HMD_NAMES {
            let p = HmdProfile::by_name(n).unwrap();
            for v in 0..2 {
                let [l, r, u, d] = p.fov_rad(v);
                assert!(l < 0.0 && r > 0.0 && u > 0.0 && d < 0.0, "{n}");
                assert!(l > -1.5 && r < 1.5 && u < 1.5 && d > -1.5);
            }
            assert!((0.063..=0.064).contains(&p.ipd), "{n}");
            assert!(p.recommended.0 <= p.max.0 && p.recommended.1 <= p.max.1);
        }
        assert!(HmdProfile::by_name("nope").is_none());
    }

    #[test]
    fn right_eye_mirrors_left() {
        let p = HmdProfile::by_name("index").unwrap();
        let [l0, r0, u0, d0] = p.fov_rad(0);
        let [l1, r1, u1, d1] = p.fov_rad(1);
        assert_eq!((l1, r1, u1, d1), (-r0, -l0, u0, d0));
        // Index's raw projection is asymmetric: more field outward.
        assert!(-l0 > r0);
        let (p0, _) = p.eye_in_head(0);
        let (p1, _) = p.eye_in_head(1);
        assert!((p1.x - p0.x - p.ipd).abs() < 1e-6 && p0.x < 0.0);
    }

    /// The Vive's eyes are measured apart (hmdgdb): the right eye is not the left's mirror image,
    /// its vertical angles differ (what breaks an app assuming symmetric eyes).
    #[test]
    fn vive_eyes_are_measured_apart() {
        let p = HmdProfile::by_name("vive").unwrap();
        let ([l0, r0, u0, d0], [l1, r1, u1, d1]) = (p.fov_rad(0), p.fov_rad(1));
        assert!((u0.tan() - 1.464221).abs() < 1e-5 && (u1.tan() - 1.460934).abs() < 1e-5 && (d1.tan() + 1.475235).abs() < 1e-5);
        assert!((u0 - u1).abs() > 5e-4 && (d0 - d1).abs() > 5e-4 && (l1 + r0).abs() > 5e-4 && (r1 + l0).abs() > 5e-4);
    }

    #[test]
    fn pimax_views_are_canted_outward() {
        let p = HmdProfile::by_name("pimax").unwrap();
        let (_, q0) = p.eye_in_head(0);
        let (_, q1) = p.eye_in_head(1);
        let f0 = q0 * Vec3::NEG_Z;
        let f1 = q1 * Vec3::NEG_Z;
        assert!(f0.x < -0.17 && f1.x > 0.17, "{f0} {f1}");
        assert!((f0.angle_between(f1).to_degrees() - 20.0).abs() < 0.01);
        let s = HmdProfile::by_name("simple").unwrap();
        assert_eq!(s.eye_in_head(0).1, Quat::IDENTITY);
    }

    #[test]
    fn index_uses_the_published_line_loop() {
        let p = HmdProfile::by_name("index").unwrap();
        assert_eq!(p.lens, Lens::LineLoop(&INDEX_LINE_LOOP_LEFT));
        assert!(p.lens_source.starts_with("published"));
        let [l, r, u, d] = p.fov_rad(0);
        for (got, want) in [l, r, u, d].iter().zip(INDEX_TANGENTS_LEFT) {
            assert!((got.tan() - want).abs() < 1e-5, "{got} {want}");
        }
        for view in 0..2 {
            let o = p.lens_outline_tangent(view, 1.0, 0);
            assert_eq!(o.len(), 27);
            // Counter-clockwise and star-shaped around the view axis: every edge turns left of it.
            for i in 0..o.len() {
                let (a, b) = (o[i], o[(i + 1) % o.len()]);
                assert!(a[0] * b[1] - a[1] * b[0] > 0.0, "view {view} edge {i}");
            }
        }
        let (o0, o1) = (p.lens_outline_tangent(0, 1.0, 0), p.lens_outline_tangent(1, 1.0, 0));
        assert!(o1.iter().rev().zip(&o0).all(|(a, b)| a[0] == -b[0] && a[1] == b[1]));
        // The mask change shrinks the loop about the view axis.
        assert_eq!(p.lens_outline_tangent(0, 0.5, 0)[3], [INDEX_LINE_LOOP_LEFT[3][0] * 0.5, INDEX_LINE_LOOP_LEFT[3][1] * 0.5]);
    }

    #[test]
    fn profiles_without_public_masks_say_so() {
        for n in ["vive", "quest3", "pimax"] {
            let p = HmdProfile::by_name(n).unwrap();
            assert!(matches!(p.lens, Lens::Ellipse(_)) && p.lens_source.starts_with("approximation"), "{n}");
        }
    }
}
