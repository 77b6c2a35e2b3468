//! HMD profiles: the per-eye geometry a real headset reports (FOVs, eye poses, recommended sizes,
//! lens outlines). One copy, used by the mock runtime (`MOCK_XR_HMD`, so that a layer that assumes
//! symmetric, parallel, identical-eye views fails there as it would on hardware) and by
//! `stereoshim preview --hmd` (so a preview shows what the layer would do on that headset).
//!
//! All angles are degrees for the LEFT eye in that eye's own view frame; the right eye is the
//! mirror image (a real headset's optics are mirror-symmetric) unless the profile carries the
//! right eye's own measured frustum (`right_fov`): real units' eyes differ by a few pixels in y,
//! which is what breaks an app that draws the right eye with the left eye's vertical angles. Positive x is to the right,
//! positive y is up, the view looks down −z (OpenXR conventions).
//!
//! Sources (public):
//! - Valve Index: the per-eye frustum and the lens outline are SteamVR's, as its OpenXR runtime
//!   reports them for an Index: the hidden-area line loop published by Rune Berg in
//!   `1runeberg/VRHiddenAreaMaskPreviewer` (file `Vertices.pde`, "Left Eye (Index HMD, OpenXR)",
//!   MIT licence, © 2020 Rune Berg): 27 points in the left eye's tangent plane (z = −1, x right,
//!   y up), transcribed below as published. The frustum is the rectangle the same file's hidden
//!   mesh fills (left eye tangents: left −1.542221, right 1.052831, up 1.410448, down −1.412249).
//!   The right eye is the mirror image of the left (the published right eye agrees with it to
//!   within 0.003). The line loop is triangulated (mask.rs) into the hidden and
//!   visible meshes, clipped to the frustum (its top edge lies 0.003 above it). Recommended size
//!   is SteamVR's 100 % render resolution for the Index at 90 Hz (2016×2240), as shown in
//!   SteamVR's video settings.
//! - HTC Vive: the OpenVR `IVRSystem::GetProjectionRaw` tangents of both eyes of one unit,
//!   recorded with risa2000's `hmdq` tool and published in risa2000's `hmdgdb`
//!   (`hmd_cfgs/Vive_Native_R90.md`, recorded 2020-04-18): left eye left −1.397283, right
//!   1.250510, top 1.464221, bottom −1.477517; right eye left −1.247887, right 1.394608, top
//!   1.460934, bottom −1.475235. The right eye is not the left's mirror image: its vertical
//!   angles are 0.003 tangent lower (about 2 pixels at 100 %). Recommended size: SteamVR's 100 %
//!   (1512×1680).
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
//! Lens outlines (for XR_KHR_visibility_mask): only the Index's is real (above). For `vive`,
//! `quest3` and `pimax` NO hidden-area mesh is publicly available in machine-readable form, so
//! their outline is an APPROXIMATION: an ellipse in angle space centred on the frustum and sized
//! relative to it, which hides the frustum corners as real lens masks do but is not the vendor's
//! shape. `HmdProfile::lens_source` says which is which (frames.json `lens`, scripts/demo).
#![forbid(unsafe_code)]

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

/// A lens outline: where the view's visible area ends.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Lens {
    /// An ellipse in angle space (an approximation standing in for an unpublished mesh).
    Ellipse(LensEllipse),
    /// A published line loop of the LEFT eye in its tangent plane (z = −1), counter-clockwise,
    /// star-shaped around the view axis; the right eye's is its mirror image.
    LineLoop(&'static [[f32; 2]]),
}

/// SteamVR's hidden-area line loop of a Valve Index's left eye, as its OpenXR runtime returns it
/// (`XR_VISIBILITY_MASK_TYPE_LINE_LOOP_KHR`), tangent plane, counter-clockwise: 27 points,
/// transcribed from `1runeberg/VRHiddenAreaMaskPreviewer`, `Vertices.pde`,
/// `verts_lineloop_left` (MIT licence, © 2020 Rune Berg).
#[rustfmt::skip]
#[allow(clippy::excessive_precision)] // digits as published
pub const INDEX_LINE_LOOP_LEFT: [[f32; 2]; 27] = [
    [0.913920, -0.402731], [0.900955, -0.154579], [0.898362, 0.090753], [0.911327, 0.321986],
    [0.929479, 0.561678], [0.828349, 0.812650], [0.652021, 1.049523], [0.457541, 1.215897],
    [0.195641, 1.348433], [-0.087003, 1.413291], [-0.460405, 1.413291], [-0.779352, 1.314594],
    [-1.043845, 1.142580], [-1.207208, 0.987485], [-1.357606, 0.761892], [-1.432805, 0.547579],
    [-1.414653, 0.212010], [-1.409467, 0.011796], [-1.417246, -0.132019], [-1.430212, -0.332233],
    [-1.440584, -0.532447], [-1.318710, -0.814438], [-1.095706, -1.090789], [-0.810469, -1.282543],
    [-0.408544, -1.406619], [-0.084410, -1.406619], [0.405679, -1.248704],
];

/// The Index's left-eye frustum as tangents (left, right, up, down): the rectangle the same
/// source's hidden-area mesh fills.
pub const INDEX_TANGENTS_LEFT: [f32; 4] = [-1.542221, 1.052831, 1.410448, -1.412249];

#[derive(Debug, Clone, PartialEq)]
pub struct HmdProfile {
    pub name: &'static str,
    pub system_name: &'static str,
    /// Metres between the two eye positions.
    pub ipd: f32,
    /// Rotation of each view about the head's y axis, outward, degrees.
    pub cant_deg: f32,
    pub fov: FovDeg,
    /// The right eye's own frustum (degrees, its own view frame) where the headset's eyes are
    /// measured apart; None: the mirror image of `fov`.
    pub right_fov: Option<FovDeg>,
    pub recommended: (u32, u32),
    pub max: (u32, u32),
    pub lens: Lens,
    /// Where the lens outline comes from, in words (published data, or an approximation).
    pub lens_source: &'static str,
    pub refresh_hz: u32,
}

fn tan_deg(t: f32) -> f32 {
    t.atan().to_degrees()
}

pub const HMD_NAMES: &[&str] = &["simple", "index", "vive", "quest3", "pimax"];

/// Ellipse centred on the frustum, `k` × its half extents (k > 1 keeps the edges' middles
/// visible and hides the corners, as lens masks do).
const fn ellipse_for(fov: FovDeg, kx: f32, ky: f32) -> Lens {
    Lens::Ellipse(LensEllipse {
        cx: (fov.left + fov.right) / 2.0,
        cy: (fov.up + fov.down) / 2.0,
        rx: (fov.right - fov.left) / 2.0 * kx,
        ry: (fov.up - fov.down) / 2.0 * ky,
    })
}

const NO_PUBLIC_MASK: &str = "approximation: no public hidden-area mesh for this headset; an ellipse in angle space that hides the frustum corners";

const SIMPLE_FOV: FovDeg = FovDeg { left: -45.0, right: 45.0, up: 45.0, down: -45.0 };
const QUEST3_FOV: FovDeg = FovDeg { left: -55.0, right: 44.0, up: 47.0, down: -49.0 };
const PIMAX_FOV: FovDeg = FovDeg { left: -65.0, right: 50.0, up: 52.0, down: -52.0 };

fn profiles() -> &'static [HmdProfile] {
    use std::sync::OnceLock;
    static P: OnceLock<Vec<HmdProfile>> = OnceLock::new();
    P.get_or_init(|| {
        // Index, left eye: SteamVR's OpenXR frustum (the published hidden mesh's rectangle).
        let [l, r, u, d] = INDEX_TANGENTS_LEFT;
        let index_fov = FovDeg { left: tan_deg(l), right: tan_deg(r), up: tan_deg(u), down: tan_deg(d) };
        // Vive, both eyes of one unit, GetProjectionRaw tangents (hmdgdb), digits as published.
        #[allow(clippy::excessive_precision)]
        let vive_fov = FovDeg { left: -tan_deg(1.397283), right: tan_deg(1.250510), up: tan_deg(1.464221), down: -tan_deg(1.477517) };
        #[allow(clippy::excessive_precision)]
        let vive_right = FovDeg { left: -tan_deg(1.247887), right: tan_deg(1.394608), up: tan_deg(1.460934), down: -tan_deg(1.475235) };
        vec![
            HmdProfile {
                name: "simple",
                system_name: "Mock HMD (simple, synthetic)",
                ipd: 0.063,
                cant_deg: 0.0,
                fov: SIMPLE_FOV,
                right_fov: None,
                recommended: (1024, 1024),
                max: (4096, 4096),
                // Exactly the inscribed 45° circle.
                lens: Lens::Ellipse(LensEllipse { cx: 0.0, cy: 0.0, rx: 45.0, ry: 45.0 }),
                lens_source: "synthetic: the circle of 45° inscribed in the frustum",
                refresh_hz: 90,
            },
            HmdProfile {
                name: "index",
                system_name: "Mock HMD (Valve Index)",
                ipd: 0.0635,
                cant_deg: 0.0,
                fov: index_fov,
                right_fov: None,
                recommended: (2016, 2240),
                max: (4032, 4480),
                lens: Lens::LineLoop(&INDEX_LINE_LOOP_LEFT),
                lens_source: "published: SteamVR's Valve Index hidden-area line loop (1runeberg/VRHiddenAreaMaskPreviewer, Vertices.pde), triangulated",
                refresh_hz: 90,
            },
            HmdProfile {
                name: "vive",
                system_name: "Mock HMD (HTC Vive)",
                ipd: 0.063,
                cant_deg: 0.0,
                fov: vive_fov,
                right_fov: Some(vive_right),
                recommended: (1512, 1680),
                max: (3024, 3360),
                lens: ellipse_for(vive_fov, 1.08, 1.06),
                lens_source: NO_PUBLIC_MASK,
                refresh_hz: 90,
            },
            HmdProfile {
                name: "quest3",
                system_name: "Mock HMD (Meta Quest 3)",
                ipd: 0.064,
                cant_deg: 0.0,
                fov: QUEST3_FOV,
                right_fov: None,
                recommended: (1680, 1760),
                max: (3360, 3520),
                lens: ellipse_for(QUEST3_FOV, 1.12, 1.12),
                lens_source: NO_PUBLIC_MASK,
                refresh_hz: 90,
            },
            HmdProfile {
                name: "pimax",
                system_name: "Mock HMD (Pimax, canted)",
                ipd: 0.064,
                cant_deg: 10.0,
                fov: PIMAX_FOV,
                right_fov: None,
                recommended: (3200, 2528),
                max: (6400, 5056),
                lens: ellipse_for(PIMAX_FOV, 1.06, 1.1),
                lens_source: NO_PUBLIC_MASK,
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
        let (l, r, u, d) = match (view, self.right_fov) {
            (0, _) => (f.left, f.right, f.up, f.down),
            (_, Some(g)) => (g.left, g.right, g.up, g.down),
            (_, None) => (-f.right, -f.left, f.up, f.down),
        };
        [l.to_radians(), r.to_radians(), u.to_radians(), d.to_radians()]
    }

    /// The view's pose relative to the head: ±IPD/2 on x, rotated outward by the cant.
    pub fn eye_in_head(&self, view: usize) -> (Vec3, Quat) {
        let s = if view == 0 { -1.0 } else { 1.0 };
        // Outward for the left eye is a turn to the left: positive rotation about +y.
        let rot = Quat::from_rotation_y((-s * self.cant_deg).to_radians());
        (Vec3::new(s * self.ipd / 2.0, 0.0, 0.0), rot)
    }

    /// Lens outline of `view` in its tangent plane (z = −1), counter-clockwise, star-shaped
    /// around the view axis, scaled by `scale` (an ellipse about its centre in angle space,
    /// with `n` points; a line loop about the view axis).
    pub fn lens_outline_tangent(&self, view: usize, scale: f32, n: usize) -> Vec<[f32; 2]> {
        match self.lens {
            Lens::Ellipse(e) => {
                let cx = if view == 0 { e.cx } else { -e.cx };
                (0..n)
                    .map(|i| {
                        let t = i as f32 / n as f32 * std::f32::consts::TAU;
                        let (ax, ay) = ((cx + scale * e.rx * t.cos()).to_radians(), (e.cy + scale * e.ry * t.sin()).to_radians());
                        [ax.tan(), ay.tan()]
                    })
                    .collect()
            }
            Lens::LineLoop(left) => {
                let pts = left.iter().map(|p| [p[0] * scale, p[1] * scale]);
                if view == 0 {
                    pts.collect()
                } else {
                    // Mirrored in x, and reversed to stay counter-clockwise.
                    let mut v: Vec<[f32; 2]> = pts.map(|[x, y]| [-x, y]).collect();
                    v.reverse();
                    v
                }
            }
        }
    }
}
