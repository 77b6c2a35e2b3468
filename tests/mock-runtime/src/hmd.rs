//! HMD profiles (`MOCK_XR_HMD`): the per-eye geometry a real headset reports, so that a layer
//! that assumes symmetric, parallel, identical-eye views fails here as it would on hardware.
//!
//! All angles are degrees for the LEFT eye in that eye's own view frame; the right eye is the
//! mirror image (a real headset's optics are mirror-symmetric). Positive x is to the right,
//! positive y is up, the view looks down −z (OpenXR conventions).
//!
//! Sources (public):
//! - Valve Index and HTC Vive: the OpenVR `IVRSystem::GetProjectionRaw` tangents collected with
//!   risa2000's `hmdq` tool and published in risa2000's `hmd_geometry_database`
//!   (github.com/risa2000/hmdq, "hmd_geometry_database"). This environment is offline, so the
//!   tangents below are transcribed from those published tables as rounded values; treat the
//!   third decimal as approximate. Recommended sizes are SteamVR's 100 % render resolution for
//!   these headsets at 90 Hz (2016×2240 Index, 1512×1680 Vive), as shown in SteamVR's video
//!   settings.
//! - Meta Quest 3: Meta's published field of view (110° horizontal, 96° vertical) split into an
//!   asymmetric per-eye frustum (outer half-angle larger than inner, as the Quest's OpenXR
//!   runtime reports); the split is an approximation fitted to those totals. Recommended size:
//!   the Quest 3 OpenXR default per-eye recommendation (1680×1760) at pixel density 1.0.
//! - Pimax (8K X class, "normal" FOV): Pimax's canted displays, whose views are rotated by 10°
//!   outward per eye (the reason Pimax offers a "parallel projections" compatibility mode);
//!   the per-eye frustum is an approximation fitted to Pimax's published ~150° horizontal FOV at
//!   normal FOV. Recommended size is approximate.
//! - `simple`: synthetic — symmetric ±45°, 1024×1024, parallel views, circular 45° lens.
//!
//! Lens outlines (for XR_KHR_visibility_mask) are APPROXIMATIONS for every profile: an ellipse in
//! angle space centred on the frustum and sized relative to it, standing in for the vendor's
//! hidden-area mesh (which is not published in machine-readable form). They hide the frustum
//! corners as real lens masks do.

use glam::{Quat, Vec3};

/// Per-eye frustum in degrees (left < 0 < right, down < 0 < up), left eye.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FovDeg {
    pub left: f32,
    pub right: f32,
    pub up: f32,
    pub down: f32,
}

/// An ellipse in angle space (degrees), left eye: centre and semi-axes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LensEllipse {
    pub cx: f32,
    pub cy: f32,
    pub rx: f32,
    pub ry: f32,
}

#[derive(Debug, Clone, PartialEq)]
pub struct HmdProfile {
    pub name: &'static str,
    pub system_name: &'static str,
    /// Metres between the two eye positions.
    pub ipd: f32,
    /// Rotation of each view about the head's y axis, outward, degrees.
    pub cant_deg: f32,
    pub fov: FovDeg,
    pub recommended: (u32, u32),
    pub max: (u32, u32),
    pub lens: LensEllipse,
    pub refresh_hz: u32,
}

fn tan_deg(t: f32) -> f32 {
    t.atan().to_degrees()
}

pub const HMD_NAMES: &[&str] = &["simple", "index", "vive", "quest3", "pimax"];

/// Ellipse centred on the frustum, `k` × its half extents (k > 1 keeps the edges' middles
/// visible and hides the corners, as lens masks do).
const fn ellipse_for(fov: FovDeg, kx: f32, ky: f32) -> LensEllipse {
    LensEllipse {
        cx: (fov.left + fov.right) / 2.0,
        cy: (fov.up + fov.down) / 2.0,
        rx: (fov.right - fov.left) / 2.0 * kx,
        ry: (fov.up - fov.down) / 2.0 * ky,
    }
}

const SIMPLE_FOV: FovDeg = FovDeg { left: -45.0, right: 45.0, up: 45.0, down: -45.0 };
const QUEST3_FOV: FovDeg = FovDeg { left: -55.0, right: 44.0, up: 47.0, down: -49.0 };
const PIMAX_FOV: FovDeg = FovDeg { left: -65.0, right: 50.0, up: 52.0, down: -52.0 };

fn profiles() -> &'static [HmdProfile] {
    use std::sync::OnceLock;
    static P: OnceLock<Vec<HmdProfile>> = OnceLock::new();
    P.get_or_init(|| {
        // Index, left eye, GetProjectionRaw tangents (left, right, up, down).
        let index_fov = FovDeg {
            left: -tan_deg(1.3961),
            right: tan_deg(1.2394),
            up: tan_deg(1.4678),
            down: -tan_deg(1.4688),
        };
        // Vive, left eye, GetProjectionRaw tangents.
        let vive_fov = FovDeg {
            left: -tan_deg(1.3636),
            right: tan_deg(1.2210),
            up: tan_deg(1.4670),
            down: -tan_deg(1.4681),
        };
        vec![
            HmdProfile {
                name: "simple",
                system_name: "Mock HMD (simple, synthetic)",
                ipd: 0.063,
                cant_deg: 0.0,
                fov: SIMPLE_FOV,
                recommended: (1024, 1024),
                max: (4096, 4096),
                // Exactly the inscribed 45° circle.
                lens: LensEllipse { cx: 0.0, cy: 0.0, rx: 45.0, ry: 45.0 },
                refresh_hz: 90,
            },
            HmdProfile {
                name: "index",
                system_name: "Mock HMD (Valve Index)",
                ipd: 0.0635,
                cant_deg: 0.0,
                fov: index_fov,
                recommended: (2016, 2240),
                max: (4032, 4480),
                lens: ellipse_for(index_fov, 1.08, 1.08),
                refresh_hz: 90,
            },
            HmdProfile {
                name: "vive",
                system_name: "Mock HMD (HTC Vive)",
                ipd: 0.063,
                cant_deg: 0.0,
                fov: vive_fov,
                recommended: (1512, 1680),
                max: (3024, 3360),
                lens: ellipse_for(vive_fov, 1.08, 1.06),
                refresh_hz: 90,
            },
            HmdProfile {
                name: "quest3",
                system_name: "Mock HMD (Meta Quest 3)",
                ipd: 0.064,
                cant_deg: 0.0,
                fov: QUEST3_FOV,
                recommended: (1680, 1760),
                max: (3360, 3520),
                lens: ellipse_for(QUEST3_FOV, 1.12, 1.12),
                refresh_hz: 90,
            },
            HmdProfile {
                name: "pimax",
                system_name: "Mock HMD (Pimax, canted)",
                ipd: 0.064,
                cant_deg: 10.0,
                fov: PIMAX_FOV,
                recommended: (3200, 2528),
                max: (6400, 5056),
                lens: ellipse_for(PIMAX_FOV, 1.06, 1.1),
                refresh_hz: 90,
            },
        ]
    })
}

impl HmdProfile {
    pub fn by_name(name: &str) -> Option<&'static HmdProfile> {
        profiles().iter().find(|p| p.name == name)
    }

    /// Nanoseconds between displayed frames (deterministic, integer).
    pub fn frame_period_ns(&self) -> i64 {
        1_000_000_000 / self.refresh_hz as i64
    }

    /// Frustum of `view` (0 = left, 1 = right) in radians, OpenXR's (left, right, up, down).
    pub fn fov_rad(&self, view: usize) -> [f32; 4] {
        let f = self.fov;
        let (l, r) = if view == 0 { (f.left, f.right) } else { (-f.right, -f.left) };
        [l.to_radians(), r.to_radians(), f.up.to_radians(), f.down.to_radians()]
    }

    /// The view's pose relative to the head: ±IPD/2 on x, rotated outward by the cant.
    pub fn eye_in_head(&self, view: usize) -> (Vec3, Quat) {
        let s = if view == 0 { -1.0 } else { 1.0 };
        // Outward for the left eye is a turn to the left: positive rotation about +y.
        let rot = Quat::from_rotation_y((-s * self.cant_deg).to_radians());
        (Vec3::new(s * self.ipd / 2.0, 0.0, 0.0), rot)
    }

    /// Lens outline of `view` in angle space (radians), CCW, `n` points, scaled about its centre.
    pub fn lens_outline_angles(&self, view: usize, scale: f32, n: usize) -> Vec<[f32; 2]> {
        let e = self.lens;
        let cx = if view == 0 { e.cx } else { -e.cx };
        (0..n)
            .map(|i| {
                let t = i as f32 / n as f32 * std::f32::consts::TAU;
                [
                    (cx + scale * e.rx * t.cos()).to_radians(),
                    (e.cy + scale * e.ry * t.sin()).to_radians(),
                ]
            })
            .collect()
    }
}

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
}
