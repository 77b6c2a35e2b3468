//! Where each view's hidden-area mask comes from: the runtime's `XR_KHR_visibility_mask` mesh, or,
//! when the runtime has none, a lens shape synthesized from configuration in angular terms (so one
//! config means the same on every HMD). Pure; the OpenXR shell fetches and publishes.
#![forbid(unsafe_code)]

use crate::core::views::{MaskSource, ViewFov};
/// The runtime mesh's expansion is the base's (`core::lens`), shared with the OpenXR contract's
/// fetch; re-exported for the tests and the preview.
pub use crate::core::lens::expand;
use std::f64::consts::PI;

/// The configured lens: visible where the direction's angle from the optical axis, split into its
/// horizontal and vertical parts in an azimuthal-equidistant projection, lies inside the ellipse
/// with these half-angles. A circle (equal half-angles) is exactly a cone around the axis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LensShape {
    pub horizontal_deg: f64,
    pub vertical_deg: f64,
}

/// Polygon resolution of the synthesized outline.
const SEGMENTS: usize = 64;
/// The hidden region reaches this far out in the tangent plane (beyond any real FOV: tan 89.4°);
/// the rasterizer clips it to the eye's viewport.
const FAR: f64 = 100.0;

impl LensShape {
    /// Tangent-plane radius of the lens outline in direction `phi` (radians, from +x towards +y).
    fn radius(&self, phi: f64) -> f64 {
        let (a, b) = (self.horizontal_deg.to_radians(), self.vertical_deg.to_radians());
        let alpha = 1.0 / ((phi.cos() / a).powi(2) + (phi.sin() / b).powi(2)).sqrt();
        alpha.min(89.0f64.to_radians()).tan()
    }

    /// The hidden area as tangent-plane triangles (CCW, 3 points each): everything outside a
    /// polygon that contains the lens outline. Conservative by construction: each polygon vertex
    /// sits outside the outline by the circumscribing factor 1/cos(π/n) plus a margin for the
    /// outline's curvature, so no triangle covers a direction the lens shows.
    pub fn hidden_triangles(&self) -> Vec<[f32; 2]> {
        let margin = 1.0 / (PI / SEGMENTS as f64).cos() * 1.01;
        let dir = |i: usize| {
            let phi = 2.0 * PI * (i % SEGMENTS) as f64 / SEGMENTS as f64;
            (phi, [phi.cos(), phi.sin()])
        };
        let mut out = Vec::with_capacity(SEGMENTS * 6);
        for i in 0..SEGMENTS {
            let (p0, d0) = dir(i);
            let (p1, d1) = dir(i + 1);
            let (r0, r1) = (self.radius(p0) * margin, self.radius(p1) * margin);
            let inner0 = [d0[0] * r0, d0[1] * r0];
            let inner1 = [d1[0] * r1, d1[1] * r1];
            let outer0 = [d0[0] * FAR, d0[1] * FAR];
            let outer1 = [d1[0] * FAR, d1[1] * FAR];
            // CCW in the tangent plane (y up): inner0 → outer0 → outer1, inner0 → outer1 → inner1.
            for p in [inner0, outer0, outer1, inner0, outer1, inner1] {
                out.push([p[0] as f32, p[1] as f32]);
            }
        }
        out
    }

    /// The polygon `hidden_triangles` leaves open, CCW from +x (`XR_KHR_visibility_mask`'s line
    /// loop, when the layer offers the extension).
    pub fn outline(&self) -> Vec<[f32; 2]> {
        let margin = 1.0 / (PI / SEGMENTS as f64).cos() * 1.01;
        (0..SEGMENTS)
            .map(|i| {
                let phi = 2.0 * PI * i as f64 / SEGMENTS as f64;
                let r = self.radius(phi) * margin;
                [(phi.cos() * r) as f32, (phi.sin() * r) as f32]
            })
            .collect()
    }

    /// The open polygon as triangles (a fan from the axis, CCW): the visible triangle mesh.
    pub fn visible_triangles(&self) -> Vec<[f32; 2]> {
        let o = self.outline();
        (0..o.len()).flat_map(|i| [[0.0, 0.0], o[i], o[(i + 1) % o.len()]]).collect()
    }

    /// Whether a tangent-plane point lies inside the lens outline (tests, diagnostics).
    pub fn contains(&self, t: [f64; 2]) -> bool {
        let rho = (t[0] * t[0] + t[1] * t[1]).sqrt();
        rho <= self.radius(t[1].atan2(t[0]))
    }
}

/// `mask.source`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SourcePolicy {
    Auto,
    Runtime,
    Synthesized,
}

impl SourcePolicy {
    pub fn from_config(choice: &str) -> SourcePolicy {
        match choice {
            "runtime" => SourcePolicy::Runtime,
            "synthesized" => SourcePolicy::Synthesized,
            _ => SourcePolicy::Auto,
        }
    }
}

/// The source policy and the synthesized lens the mask's settings ask for (the OpenXR half and
/// `stereoshim preview` both start here).
pub fn from_settings(settings: &super::MaskSettings) -> (SourcePolicy, LensShape) {
    let policy = match settings.source {
        super::SourceSetting::Runtime => SourcePolicy::Runtime,
        super::SourceSetting::Synthesized => SourcePolicy::Synthesized,
        super::SourceSetting::Auto => SourcePolicy::Auto,
    };
    let radius = settings.synthesized_radius_deg;
    (policy, LensShape { horizontal_deg: radius, vertical_deg: (radius * settings.synthesized_aspect).min(89.0) })
}

/// Monado's generic mask for a view of `fov`, as `is_generic` recognises it: each corner of the
/// FOV rectangle cut by a triangle whose legs run from ±0.75 to ±1 of it in normalised
/// coordinates, counter-clockwise (what `stereoshim preview` shows a WiVRn headset getting).
pub fn generic(fov: &ViewFov) -> Vec<[f32; 2]> {
    let x = |n: f32| fov.tan_left + (n + 1.0) / 2.0 * (fov.tan_right - fov.tan_left);
    let y = |n: f32| fov.tan_down + (n + 1.0) / 2.0 * (fov.tan_up - fov.tan_down);
    let mut out = Vec::with_capacity(12);
    for (sx, sy) in [(-1.0f32, -1.0f32), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
        let corner = [x(sx), y(sy)];
        let along_x = [x(0.75 * sx), y(sy)];
        let along_y = [x(sx), y(0.75 * sy)];
        // Counter-clockwise: from the corner along x first where the corner's signs agree.
        if sx * sy > 0.0 {
            out.extend([corner, along_x, along_y]);
        } else {
            out.extend([corner, along_y, along_x]);
        }
    }
    out
}

/// Whether a runtime's hidden triangle mesh is Monado's generic one
/// (`u_visibility_mask_get_default`): four triangles, each cutting one corner of the view's
/// FOV rectangle with legs an eighth of its width and height (from ±0.75 to ±1 in coordinates
/// normalised to the rectangle), the same for every headset that gets it. The rectangle is the
/// mesh's own bounding box.
pub fn is_generic(hidden: &[[f32; 2]]) -> bool {
    if hidden.len() != 12 {
        return false;
    }
    let (mut lo, mut hi) = ([f32::MAX; 2], [f32::MIN; 2]);
    for p in hidden {
        for a in 0..2 {
            lo[a] = lo[a].min(p[a]);
            hi[a] = hi[a].max(p[a]);
        }
    }
    if hi[0] <= lo[0] || hi[1] <= lo[1] {
        return false;
    }
    let norm = |p: &[f32; 2]| [0, 1].map(|a| (2.0 * (p[a] - lo[a]) / (hi[a] - lo[a]) - 1.0) as f64);
    let near = |v: f64, want: f64| (v.abs() - want).abs() < 0.02;
    let mut corners = Vec::new();
    for t in hidden.chunks_exact(3) {
        let n: Vec<[f64; 2]> = t.iter().map(norm).collect();
        // One vertex in a corner, the two others on its two edges, a quarter in from it.
        let Some(c) = n.iter().find(|p| near(p[0], 1.0) && near(p[1], 1.0)) else { return false };
        let legs = n.iter().filter(|p| (near(p[0], 1.0) && near(p[1], 0.75) || near(p[0], 0.75) && near(p[1], 1.0)) && p[0].signum() == c[0].signum() && p[1].signum() == c[1].signum()).count();
        if legs != 2 {
            return false;
        }
        corners.push((c[0].signum() as i32, c[1].signum() as i32));
    }
    corners.sort_unstable();
    corners.dedup();
    corners.len() == 4
}

/// Picks a view's mask. `runtime` is the runtime's hidden mesh (None: the runtime offers no
/// visibility mask; an empty mesh means "no mask" per the spec).
/// `headset`: the published lens of the headset the runtime names, when the layer knows one; it
/// wins over the runtime's mask only where that is generic (`is_generic`) or missing.
pub fn choose(policy: SourcePolicy, runtime: Option<Vec<[f32; 2]>>, headset: Option<Vec<[f32; 2]>>, lens: &LensShape) -> Option<(MaskSource, Vec<[f32; 2]>)> {
    let runtime = runtime.filter(|t| t.len() >= 3);
    let headset = headset.filter(|t| t.len() >= 3);
    match (policy, runtime, headset) {
        (SourcePolicy::Synthesized, _, _) => Some((MaskSource::Synthesized, lens.hidden_triangles())),
        (SourcePolicy::Runtime, t, _) => t.map(|t| (MaskSource::Runtime, t)),
        (SourcePolicy::Auto, Some(t), Some(h)) if is_generic(&t) => Some((MaskSource::Headset, h)),
        (SourcePolicy::Auto, Some(t), _) => Some((MaskSource::Runtime, t)),
        (SourcePolicy::Auto, None, Some(h)) => Some((MaskSource::Headset, h)),
        (SourcePolicy::Auto, None, None) => Some((MaskSource::Synthesized, lens.hidden_triangles())),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn inside_triangle(p: [f64; 2], t: &[[f32; 2]]) -> bool {
        let cross = |a: [f32; 2], b: [f32; 2]| {
            (b[0] as f64 - a[0] as f64) * (p[1] - a[1] as f64) - (b[1] as f64 - a[1] as f64) * (p[0] - a[0] as f64)
        };
        let (c0, c1, c2) = (cross(t[0], t[1]), cross(t[1], t[2]), cross(t[2], t[0]));
        c0 >= 0.0 && c1 >= 0.0 && c2 >= 0.0
    }

    #[test]
    fn synthesized_mask_never_covers_the_lens_and_covers_what_is_far_outside() {
        for lens in [LensShape { horizontal_deg: 55.0, vertical_deg: 55.0 }, LensShape { horizontal_deg: 50.0, vertical_deg: 40.0 }] {
            let tris = lens.hidden_triangles();
            assert_eq!(tris.len(), SEGMENTS * 6);
            for tri in tris.chunks_exact(3) {
                let area = (tri[1][0] - tri[0][0]) * (tri[2][1] - tri[0][1]) - (tri[2][0] - tri[0][0]) * (tri[1][1] - tri[0][1]);
                assert!(area > 0.0, "triangle not CCW: {tri:?}");
            }
            // A dense grid of tangent-plane points: inside the lens → in no triangle; clearly
            // outside (5 % further out than the outline) → in some triangle.
            for iy in -60..=60 {
                for ix in -60..=60 {
                    let p = [ix as f64 * 0.05, iy as f64 * 0.05];
                    let covered = tris.chunks_exact(3).any(|t| inside_triangle(p, t));
                    if lens.contains(p) {
                        assert!(!covered, "{lens:?}: visible point {p:?} is masked");
                    }
                    let rho = (p[0] * p[0] + p[1] * p[1]).sqrt();
                    if rho > lens.radius(p[1].atan2(p[0])) * 1.05 {
                        assert!(covered, "{lens:?}: hidden point {p:?} is not masked");
                    }
                }
            }
        }
    }

    /// The three mesh types the layer offers describe one polygon: the visible fan and the
    /// hidden ring meet on the outline, and the loop is that outline.
    #[test]
    fn offered_meshes_share_one_outline() {
        let lens = LensShape { horizontal_deg: 50.0, vertical_deg: 45.0 };
        let (outline, visible, hidden) = (lens.outline(), lens.visible_triangles(), lens.hidden_triangles());
        assert_eq!(outline.len(), SEGMENTS);
        assert_eq!(visible.len(), SEGMENTS * 3);
        for (i, p) in outline.iter().enumerate() {
            // Each outline point is an inner vertex of the hidden ring and a fan vertex.
            assert!(hidden.iter().any(|h| (h[0] - p[0]).abs() < 1e-5 && (h[1] - p[1]).abs() < 1e-5), "outline point {i}");
            assert_eq!(visible[i * 3 + 1], *p);
            assert!(!lens.contains([p[0] as f64, p[1] as f64]), "the outline lies just outside the lens");
        }
    }

    #[test]
    fn circle_is_a_cone() {
        let lens = LensShape { horizontal_deg: 45.0, vertical_deg: 45.0 };
        assert!(lens.contains([0.70, 0.70]));
        assert!(!lens.contains([0.72, 0.72]));
        assert!((lens.radius(1.0) - 1.0).abs() < 1e-9);
    }

    #[test]
    fn source_choice() {
        let lens = LensShape { horizontal_deg: 50.0, vertical_deg: 50.0 };
        let mesh = vec![[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]];
        assert_eq!(choose(SourcePolicy::Auto, Some(mesh.clone()), None, &lens).unwrap().0, MaskSource::Runtime);
        assert_eq!(choose(SourcePolicy::Auto, None, None, &lens).unwrap().0, MaskSource::Synthesized);
        assert_eq!(choose(SourcePolicy::Auto, Some(vec![]), None, &lens).unwrap().0, MaskSource::Synthesized);
        assert!(choose(SourcePolicy::Runtime, None, None, &lens).is_none());
        assert_eq!(choose(SourcePolicy::Synthesized, Some(mesh.clone()), None, &lens).unwrap().0, MaskSource::Synthesized);
        // A headset the layer knows: its lens where the runtime has none or only the generic one,
        // never over a real runtime mask; `runtime` keeps even the generic one.
        let headset = Some(vec![[0.5, 0.5], [1.0, 0.5], [0.5, 1.0]]);
        let generic = monado_default(&[-1.4, 1.2, 1.3, -1.5]);
        assert_eq!(choose(SourcePolicy::Auto, Some(mesh), headset.clone(), &lens).unwrap().0, MaskSource::Runtime);
        assert_eq!(choose(SourcePolicy::Auto, Some(generic.clone()), headset.clone(), &lens).unwrap().0, MaskSource::Headset);
        assert_eq!(choose(SourcePolicy::Auto, None, headset.clone(), &lens).unwrap().0, MaskSource::Headset);
        assert_eq!(choose(SourcePolicy::Auto, Some(generic.clone()), None, &lens).unwrap().0, MaskSource::Runtime);
        assert_eq!(choose(SourcePolicy::Runtime, Some(generic), headset, &lens).unwrap().0, MaskSource::Runtime);
    }

    /// Monado's `u_visibility_mask_get_default` hidden mesh for a view of FOV tangents
    /// (left, right, up, down): its four corner triangles in normalised coordinates, scaled.
    fn monado_default(fov: &[f32; 4]) -> Vec<[f32; 2]> {
        let n: [[f32; 2]; 12] = [
            [1.0, 0.75], [1.0, 1.0], [0.75, 1.0], [-1.0, 1.0], [-1.0, 0.75], [-0.75, 1.0],
            [-1.0, -0.75], [-1.0, -1.0], [-0.75, -1.0], [0.75, -1.0], [1.0, -1.0], [1.0, -0.75],
        ];
        let [l, r, u, d] = *fov;
        n.iter().map(|p| [l + (p[0] + 1.0) / 2.0 * (r - l), d + (p[1] + 1.0) / 2.0 * (u - d)]).collect()
    }

    #[test]
    fn monado_generic_mask_is_recognised() {
        for fov in [[-1.0, 1.0, 1.0, -1.0], [-1.542, 1.053, 1.410, -1.412], [-0.9, 1.3, 0.8, -1.1]] {
            assert!(is_generic(&monado_default(&fov)), "{fov:?}");
        }
        // A real lens (the synthesized one), one corner moved, fewer triangles: not generic.
        assert!(!is_generic(&LensShape { horizontal_deg: 50.0, vertical_deg: 45.0 }.hidden_triangles()));
        let mut moved = monado_default(&[-1.0, 1.0, 1.0, -1.0]);
        moved[0] = [1.0, 0.5];
        assert!(!is_generic(&moved));
        assert!(!is_generic(&monado_default(&[-1.0, 1.0, 1.0, -1.0])[..9]));
    }

    #[test]
    fn settings_pick_the_policy_and_the_lens() {
        let mut m = super::super::MaskSettings { enabled: true, source: super::super::SourceSetting::Synthesized, synthesized_radius_deg: 60.0, synthesized_aspect: 2.0, debug: false };
        assert_eq!(from_settings(&m), (SourcePolicy::Synthesized, LensShape { horizontal_deg: 60.0, vertical_deg: 89.0 }));
        m.source = super::super::SourceSetting::Auto;
        m.synthesized_aspect = 0.5;
        assert_eq!(from_settings(&m), (SourcePolicy::Auto, LensShape { horizontal_deg: 60.0, vertical_deg: 30.0 }));
    }
}
