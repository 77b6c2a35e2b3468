//! Variable-rate shading (foveation method 1): the rate map a `VK_KHR_fragment_shading_rate`
//! attachment holds for an eye pass, the encoding of its texels, which passes get one and the
//! per-frame counters. Pure; `vrs::vk` turns a map into a layer-owned image and chains it into the
//! app's pass.
//!
//! Rates: full (1×1) within `inner_deg` of the fovea centre, half in the middle ring, quarter
//! (2×2) beyond. Half is **2×1** (two pixels wide, one high): the rates 1×1, 1×2, 2×1 and 2×2 are
//! required of every implementation with `attachmentFragmentShadingRate` (Vulkan spec,
//! "Fragment Shading Rates", the required rates table), so no rate needs querying; 2×1 keeps full
//! vertical resolution, where HMD lenses smear least. The pipeline state the layer chains
//! (`fragmentSize` 1×1, combiner ops KEEP, REPLACE) uses only trivial combiner ops, so
//! `fragmentShadingRateNonTrivialCombinerOps` is not needed either.
//!
//! Conservative: a texel takes the ring of its *most central* point (the point of its pixel area,
//! inside the eye's rect, with the smallest angle to the fovea centre), so no pixel inside the
//! inner ring is ever shaded at less than full rate. Texels that hold no pixel of any eye get full
//! rate (nothing is saved there, nothing can go wrong).
#![forbid(unsafe_code)]

use crate::track::caps::DeviceRates;
use crate::core::pass::NotMasked;
use crate::core::rect::PixelRect;
use crate::track::eye_pass::EyeSource;
use crate::core::stats::{json_counts, Counters};
use crate::core::views::{FoveaView, ViewFov};
use std::collections::BTreeMap;

/// A shading rate as its fragment size in pixels.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct FragmentSize {
    pub width: u32,
    pub height: u32,
}

pub const FULL: FragmentSize = FragmentSize { width: 1, height: 1 };
pub const HALF: FragmentSize = FragmentSize { width: 2, height: 1 };
pub const QUARTER: FragmentSize = FragmentSize { width: 2, height: 2 };

/// The attachment texel of a rate, as the spec defines it ("Attachment Fragment Shading Rate"):
/// `log2(width) << 2 | log2(height)`.
pub fn encode(size: FragmentSize) -> u8 {
    let l = |v: u32| v.max(1).ilog2() as u8;
    (l(size.width) << 2) | l(size.height)
}

/// Decodes a texel (for tests and diagnostics).
pub fn decode(texel: u8) -> FragmentSize {
    FragmentSize { width: 1 << ((texel >> 2) & 3), height: 1 << (texel & 3) }
}

/// Which rate a ring gets.
pub fn rate_of(ring: crate::core::fovea::Ring) -> FragmentSize {
    match ring {
        crate::core::fovea::Ring::Inner => FULL,
        crate::core::fovea::Ring::Middle => HALF,
        crate::core::fovea::Ring::Outer => QUARTER,
    }
}

/// Whether `foveation.method` resolves to VRS on a device where the layer enabled
/// `attachmentFragmentShadingRate` (`fsr_enabled`). The complement of `rdm::method_is_rdm` except
/// for `vrs` on a device without it, which is neither (reported as unsupported).
pub fn method_is_vrs(method: &str, fsr_enabled: bool) -> bool {
    match method {
        "vrs" | "auto" => fsr_enabled,
        _ => false,
    }
}


/// One eye as the rate map sees it: the image rect that shows `fov`, foveated by `fovea`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EyeRates {
    /// Layer of the rate image (multiview: the view index in the pass; else 0).
    pub layer: u32,
    pub rect: PixelRect,
    pub fov: ViewFov,
    pub fovea: FoveaView,
}

/// Smallest angle, degrees, between the direction `c` (tangent-plane point) and any direction
/// whose tangent-plane point lies in the rectangle [x0, x1] × [y0, y1] (x0 ≤ x1, y0 ≤ y1).
///
/// Inside: 0. Outside, the minimum lies on the boundary; along one edge, a + t·d (t ∈ [0, 1]),
/// cos(angle) = c'·(a' + t·d') / (|c'| |a' + t·d'|) with primes the 3-D directions (x, y, −1);
/// its derivative vanishes at exactly one t (the numerator of the derivative is linear in t), so
/// the minimum over an edge is at an end or at that t clamped to the edge.
pub fn min_angle_deg(x0: f64, x1: f64, y0: f64, y1: f64, c: [f64; 2]) -> f64 {
    if c[0] >= x0 && c[0] <= x1 && c[1] >= y0 && c[1] <= y1 {
        return 0.0;
    }
    let cp = [c[0], c[1], -1.0];
    let cn = (cp[0] * cp[0] + cp[1] * cp[1] + 1.0).sqrt();
    let angle = |p: [f64; 2]| {
        let n = (p[0] * p[0] + p[1] * p[1] + 1.0).sqrt();
        ((cp[0] * p[0] + cp[1] * p[1] + 1.0) / (n * cn)).clamp(-1.0, 1.0).acos().to_degrees()
    };
    let edges = [([x0, y0], [x1 - x0, 0.0]), ([x0, y1], [x1 - x0, 0.0]), ([x0, y0], [0.0, y1 - y0]), ([x1, y0], [0.0, y1 - y0])];
    let mut best = f64::INFINITY;
    for (a, d) in edges {
        let (ap, dp) = ([a[0], a[1], -1.0], [d[0], d[1], 0.0]);
        let dot = |u: [f64; 3], v: [f64; 3]| u[0] * v[0] + u[1] * v[1] + u[2] * v[2];
        let (alpha, beta) = (dot(cp, ap), dot(cp, dp));
        let (aa, ad, dd) = (dot(ap, ap), dot(ap, dp), dot(dp, dp));
        let den = beta * ad - alpha * dd;
        let mut ts = vec![0.0, 1.0];
        if den.abs() > 1e-300 {
            let t = (alpha * ad - beta * aa) / den;
            if t.is_finite() {
                ts.push(t.clamp(0.0, 1.0));
            }
        }
        for t in ts {
            best = best.min(angle([a[0] + t * d[0], a[1] + t * d[1]]));
        }
    }
    best
}

/// The rate of the pixel area [px0, px1) × [py0, py1) (image pixels; already clipped to the
/// eye's rect) of an eye: the ring of its most central point.
fn rate_of_area(eye: &EyeRates, px0: i64, px1: i64, py0: i64, py1: i64) -> FragmentSize {
    let r = &eye.rect;
    let (sx, sy) = (
        (eye.fov.tan_right as f64 - eye.fov.tan_left as f64) / r.width as f64,
        (eye.fov.tan_up as f64 - eye.fov.tan_down as f64) / r.height as f64,
    );
    let tx = |px: i64| eye.fov.tan_left as f64 + (px - r.x as i64) as f64 * sx;
    // Image y grows downwards, tangent y upwards.
    let ty = |py: i64| eye.fov.tan_up as f64 - (py - r.y as i64) as f64 * sy;
    let a = min_angle_deg(tx(px0), tx(px1), ty(py1), ty(py0), [eye.fovea.center[0] as f64, eye.fovea.center[1] as f64]);
    let inner = eye.fovea.inner_deg as f64;
    let middle = (eye.fovea.middle_deg as f64).max(inner);
    if a <= inner {
        FULL
    } else if a <= middle {
        HALF
    } else {
        QUARTER
    }
}

/// The finer of two rates (per axis).
fn finer(a: FragmentSize, b: FragmentSize) -> FragmentSize {
    FragmentSize { width: a.width.min(b.width), height: a.height.min(b.height) }
}

/// One layer of a rate image: `width` × `height` texels of `texel_w` × `texel_h` pixels, texel
/// (0, 0) at pixel (0, 0) of the attachment; every eye of `eyes` whose `layer` is `layer`
/// contributes where its rect lies, others are ignored. Row-major, encoded (`encode`).
pub fn rate_layer(width: u32, height: u32, texel_w: u32, texel_h: u32, layer: u32, eyes: &[EyeRates]) -> Vec<u8> {
    let mut out = vec![encode(FULL); width as usize * height as usize];
    let (tw, th) = (texel_w.max(1) as i64, texel_h.max(1) as i64);
    for ty in 0..height as i64 {
        for tx in 0..width as i64 {
            let (x0, y0, x1, y1) = (tx * tw, ty * th, tx * tw + tw, ty * th + th);
            let mut rate: Option<FragmentSize> = None;
            for e in eyes.iter().filter(|e| e.layer == layer && e.rect.width > 0 && e.rect.height > 0) {
                let r = &e.rect;
                let (ex0, ey0) = (r.x as i64, r.y as i64);
                let (ex1, ey1) = (ex0 + r.width as i64, ey0 + r.height as i64);
                let (ix0, iy0, ix1, iy1) = (x0.max(ex0), y0.max(ey0), x1.min(ex1), y1.min(ey1));
                if ix0 >= ix1 || iy0 >= iy1 {
                    continue;
                }
                let here = rate_of_area(e, ix0, ix1, iy0, iy1);
                rate = Some(rate.map_or(here, |r| finer(r, here)));
            }
            out[(ty * width as i64 + tx) as usize] = encode(rate.unwrap_or(FULL));
        }
    }
    out
}

/// Texels needed to cover `pixels` with texels of `texel` pixels.
pub fn texels(pixels: u32, texel: u32) -> u32 {
    pixels.div_ceil(texel.max(1))
}

/// Whether the layer appends its shading-rate attachment to a render pass the app creates:
/// only on a device where it enabled attachment rates, and never to a pass that has its own rate
/// attachment or uses a fragment density map (the two must not meet), nor to one without a
/// graphics subpass.
pub fn adds_rate_attachment(enabled: bool, app_has_rate_attachment: bool, app_uses_density_map: bool, graphics_subpasses: usize) -> bool {
    enabled && !app_has_rate_attachment && !app_uses_density_map && graphics_subpasses > 0
}

/// Layers of the rate image attached to a framebuffer of a render pass object: one per view
/// (up to the highest view of any subpass) for multiview passes on a device that reads layered
/// rate attachments; else 1, which the spec accepts for any framebuffer (every view and layer
/// then reads layer 0).
pub fn pass_rate_layers(view_masks: &[u32], layered: bool) -> u32 {
    let all = view_masks.iter().fold(0u32, |a, m| a | m);
    if all == 0 || !layered {
        1
    } else {
        32 - all.leading_zeros()
    }
}

/// (width, height, layers) in texels of the rate image for a framebuffer of `width` × `height`
/// pixels: covers every pixel (`ceil(extent / texel)`).
pub fn pass_rate_extent(width: u32, height: u32, view_masks: &[u32], rates: DeviceRates) -> (u32, u32, u32) {
    (texels(width, rates.texel_width), texels(height, rates.texel_height), pass_rate_layers(view_masks, rates.layered))
}

/// What of an eye pass decides its rate image's layers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PassShape {
    /// The first array layer of the attachment that shows the eyes.
    pub base_layer: u32,
    pub view_mask: u32,
    /// The pass renders more than one layer without multiview.
    pub layered: bool,
}

/// The eyes an eye pass's rate image carries (their rate-image layer, rect, FOV and fovea) and
/// its layer count: one layer per view of a multiview pass (needs `layered` rates), else one.
pub fn pass_eyes(
    sources: &[EyeSource],
    shape: PassShape,
    rates: DeviceRates,
    fov_of: &dyn Fn(u32) -> Option<ViewFov>,
    fovea_of: &dyn Fn(u32) -> Option<FoveaView>,
) -> Result<(Vec<EyeRates>, u32), NotApplied> {
    let eye = |layer: u32, s: &EyeSource| -> Result<EyeRates, NotApplied> {
        Ok(EyeRates { layer, rect: s.rect, fov: fov_of(s.view).ok_or(NotApplied::NoFovea)?, fovea: fovea_of(s.view).ok_or(NotApplied::NoFovea)? })
    };
    let mut eyes = Vec::new();
    let layers = if shape.view_mask != 0 {
        if !rates.layered {
            return Err(NotApplied::MultiviewNotLayered);
        }
        for i in (0..32).filter(|i| shape.view_mask & (1 << i) != 0) {
            for s in sources.iter().filter(|s| s.layer == shape.base_layer + i) {
                eyes.push(eye(i, s)?);
            }
        }
        32 - shape.view_mask.leading_zeros()
    } else {
        // A layered pass without multiview: one rate layer (the spec's only choice for a render
        // pass object) cannot carry per-layer eyes.
        if shape.layered {
            return Err(NotApplied::Layered);
        }
        for s in sources.iter().filter(|s| s.layer == shape.base_layer) {
            eyes.push(eye(0, s)?);
        }
        1
    };
    if eyes.is_empty() {
        return Err(NotApplied::EyeUnknown);
    }
    Ok((eyes, layers))
}

/// (width, height) in texels of a rate image for an attachment of `image` extent: it covers the
/// whole attachment (so one image serves every pass on images of that size), at least the render
/// area.
pub fn map_extent(image: Option<(u32, u32)>, area: PixelRect, rates: DeviceRates) -> (u32, u32) {
    let w = image.map_or(0, |i| i.0).max((area.x.max(0) as u32).saturating_add(area.width));
    let h = image.map_or(0, |i| i.1).max((area.y.max(0) as u32).saturating_add(area.height));
    (texels(w, rates.texel_width), texels(h, rates.texel_height))
}

/// Why a pass got no rate attachment.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum NotApplied {
    /// `foveation.method = vrs` on a device without `attachmentFragmentShadingRate` enabled by
    /// the layer (e.g. lavapipe).
    Unsupported,
    /// A multiview pass on a device without `layeredShadingRateAttachments`.
    MultiviewNotLayered,
    /// The app chains its own fragment shading rate attachment.
    AppUsesFsr,
    /// A render pass object (`vkCmdBeginRenderPass(2)`) without the layer's rate attachment
    /// (created before the layer, or one it left alone: its own rate attachment, a density map).
    RenderPass,
    /// Contents recorded in secondary command buffers.
    Secondary,
    /// A non-multiview pass rendering more than one layer.
    Layered,
    /// No fovea or FOV for an eye's view (yet).
    NoFovea,
    /// The eye pass test said no (`NotMasked` reasons other than "not an eye pass").
    EyeUnknown,
    IntermediateOff,
    /// The layer could not create or upload its rate image.
    LayerError,
}

impl NotApplied {
    pub fn name(&self) -> &'static str {
        match self {
            NotApplied::Unsupported => "unsupported",
            NotApplied::MultiviewNotLayered => "multiview_not_layered",
            NotApplied::AppUsesFsr => "app_uses_fsr",
            NotApplied::RenderPass => "render_pass",
            NotApplied::Secondary => "secondary",
            NotApplied::Layered => "layered",
            NotApplied::NoFovea => "no_fovea",
            NotApplied::EyeUnknown => "eye_unknown",
            NotApplied::IntermediateOff => "intermediate_off",
            NotApplied::LayerError => "layer_error",
        }
    }
    /// The eye-pass test's reasons, mapped (None: not an eye pass, nothing to count).
    pub fn from_not_masked(n: NotMasked) -> Option<NotApplied> {
        match n {
            // A post pass is no candidate: VRS applies to the eye passes behind it.
            NotMasked::NotEyePass | NotMasked::PostPass => None,
            NotMasked::IntermediateOff => Some(NotApplied::IntermediateOff),
            NotMasked::Secondary => Some(NotApplied::Secondary),
            NotMasked::LayerError => Some(NotApplied::LayerError),
            _ => Some(NotApplied::EyeUnknown),
        }
    }
}

/// What VRS did in one frame, summed over devices (`stats.file`'s `vrs` object).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct VrsFrameStats {
    /// Eye passes that got the rate attachment.
    pub passes: u64,
    /// Rate images built (never per frame: only when the fovea, the FOV or the extent changes).
    pub maps_built: u64,
    pub not_applied: BTreeMap<&'static str, u64>,
}

impl VrsFrameStats {
    pub fn add(&mut self, o: &VrsFrameStats) {
        self.passes += o.passes;
        self.maps_built += o.maps_built;
        for (k, v) in &o.not_applied {
            *self.not_applied.entry(k).or_insert(0) += v;
        }
    }
    pub fn count_not_applied(&mut self, why: NotApplied) {
        *self.not_applied.entry(why.name()).or_insert(0) += 1;
    }
    pub fn is_empty(&self) -> bool {
        *self == VrsFrameStats::default()
    }
    /// `key=value` pairs for the `vulkan device stats:` line.
    pub fn summary(&self) -> String {
        let mut s = format!("vrs_passes={} vrs_maps_built={}", self.passes, self.maps_built);
        for (k, v) in &self.not_applied {
            s.push_str(&format!(" vrs_not_applied.{k}={v}"));
        }
        s
    }
}

impl Counters for VrsFrameStats {
    const ID: &'static str = "vrs";
    const LABEL: &'static str = "foveation (variable-rate shading)";
    const GROUP: Option<&'static str> = Some("foveation");
    fn merge(&mut self, o: &Self) {
        VrsFrameStats::add(self, o);
    }
    fn applied(&self) -> u64 {
        self.passes
    }
    fn left_alone(&self) -> Vec<(&'static str, u64)> {
        self.not_applied.iter().map(|(k, v)| (*k, *v)).collect()
    }
    fn hint_for(&self, reason: &str) -> &'static str {
        match reason {
            "unsupported" => {
                "the device has no attachment fragment shading rate enabled by the layer (the GPU lacks it, or the layer could not \
                 enable it at vkCreateDevice: see \"vulkan device created\" in this log): use foveation.method = \"auto\" or \"rdm\""
            }
            "secondary" => "VRS does not reach passes whose contents are secondary command buffers: use foveation.method = \"rdm\"",
            "no_fovea" => "no fovea yet for the view (the first frame): nothing to do unless it persists",
            "multiview_not_layered" => "the GPU cannot use one rate layer per view: use foveation.method = \"rdm\"",
            "app_uses_fsr" => "the app sets its own shading rate: the layer leaves it alone",
            "render_pass" => "a render pass created before the layer could add its rate attachment",
            "layered" => "a non-multiview pass renders several layers: not supported by VRS",
            _ => crate::core::stats::common_hint(reason),
        }
    }
    fn line(&self) -> String {
        VrsFrameStats::summary(self)
    }
    fn json(&self, record: &mut serde_json::Map<String, serde_json::Value>) {
        record.insert(
            "vrs".into(),
            serde_json::json!({
                "passes": self.passes,
                "maps_built": self.maps_built,
                "not_applied": json_counts(self.not_applied.iter().map(|(k, v)| (*k, *v))),
            }),
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn render_pass_rate_attachment_shape() {
        assert!(adds_rate_attachment(true, false, false, 1));
        assert!(!adds_rate_attachment(false, false, false, 1), "not on a device without layer-enabled rates");
        assert!(!adds_rate_attachment(true, true, false, 1), "not beside the app's own");
        assert!(!adds_rate_attachment(true, false, true, 1), "not with a fragment density map");
        assert!(!adds_rate_attachment(true, false, false, 0));
        let r = DeviceRates { texel_width: 16, texel_height: 8, layered: true };
        // ceil(fb / texel); one layer without multiview.
        assert_eq!(pass_rate_extent(1000, 1001, &[0], r), (63, 126, 1));
        assert_eq!(pass_rate_extent(16, 8, &[], r), (1, 1, 1));
        // Multiview: up to the highest view of any subpass, only when layered.
        assert_eq!(pass_rate_extent(32, 32, &[0b11, 0b01], r), (2, 4, 2));
        assert_eq!(pass_rate_extent(32, 32, &[0b100], r), (2, 4, 3));
        assert_eq!(pass_rate_extent(32, 32, &[0b11], DeviceRates { layered: false, ..r }), (2, 4, 1));
    }

    const FOV: ViewFov = ViewFov { tan_left: -1.0, tan_right: 1.0, tan_up: 1.0, tan_down: -1.0 };

    fn fovea(center: [f32; 2], inner: f32, middle: f32) -> FoveaView {
        FoveaView { view: 0, center, inner_deg: inner, middle_deg: middle }
    }

    fn eye(rect: PixelRect, f: FoveaView) -> EyeRates {
        EyeRates { layer: 0, rect, fov: FOV, fovea: f }
    }

    #[test]
    fn encoding_follows_the_spec() {
        assert_eq!(encode(FULL), 0);
        assert_eq!(encode(FragmentSize { width: 1, height: 2 }), 1);
        assert_eq!(encode(HALF), 4);
        assert_eq!(encode(QUARTER), 5);
        assert_eq!(encode(FragmentSize { width: 4, height: 4 }), 10);
        for t in [0u8, 1, 4, 5, 6, 9, 10] {
            assert_eq!(encode(decode(t)), t);
        }
        assert!(method_is_vrs("vrs", true) && method_is_vrs("auto", true));
        assert!(!method_is_vrs("vrs", false) && !method_is_vrs("auto", false) && !method_is_vrs("rdm", true));
        assert_eq!(texels(1000, 16), 63);
    }

    #[test]
    fn min_angle_is_exact_on_edges_and_zero_inside() {
        assert_eq!(min_angle_deg(-0.1, 0.1, -0.1, 0.1, [0.0, 0.0]), 0.0);
        // Straight right of the axis: the nearest point is (0.5, 0).
        let a = min_angle_deg(0.5, 1.0, -0.2, 0.2, [0.0, 0.0]);
        assert!((a - 0.5f64.atan().to_degrees()).abs() < 1e-9, "{a}");
        // An off-axis centre: brute force over a fine grid never beats the analytic minimum.
        let c = [0.6, -0.3];
        let (x0, x1, y0, y1) = (-0.4, 0.1, 0.2, 0.9);
        let m = min_angle_deg(x0, x1, y0, y1, c);
        let mut brute = f64::INFINITY;
        for i in 0..=400 {
            for j in 0..=400 {
                let p = [x0 + (x1 - x0) * i as f64 / 400.0, y0 + (y1 - y0) * j as f64 / 400.0];
                brute = brute.min(crate::core::fovea::angle_between_deg([p[0] as f32, p[1] as f32], [c[0] as f32, c[1] as f32]) as f64);
            }
        }
        assert!(m <= brute + 1e-4 && brute - m < 0.05, "analytic {m}, brute {brute}");
    }

    #[test]
    fn rings_map_to_rates_conservatively() {
        // 90° FOV, 256 px, 16 px texels: 16×16 texels; fovea on the axis, 20° / 35°.
        let e = eye(PixelRect { x: 0, y: 0, width: 256, height: 256 }, fovea([0.0, 0.0], 20.0, 35.0));
        let map = rate_layer(16, 16, 16, 16, 0, &[e]);
        let at = |tx: usize, ty: usize| decode(map[ty * 16 + tx]);
        assert_eq!(at(7, 7), FULL);
        assert_eq!(at(8, 8), FULL);
        assert_eq!(at(0, 0), QUARTER);
        assert_eq!(at(15, 8), QUARTER);
        // Every pixel whose centre is within 20° lies in a full-rate texel; every texel that is
        // not full rate has no point within 20°.
        for py in 0..256 {
            for px in 0..256 {
                let t = [-1.0 + (px as f32 + 0.5) / 128.0, 1.0 - (py as f32 + 0.5) / 128.0];
                let a = crate::core::fovea::angle_between_deg(t, [0.0, 0.0]);
                let r = at(px / 16, py / 16);
                if a <= 20.0 {
                    assert_eq!(r, FULL, "pixel {px},{py} at {a}°");
                }
                if a <= 35.0 {
                    assert_ne!(r, QUARTER, "pixel {px},{py} at {a}°");
                }
            }
        }
        let counts = |r: FragmentSize| map.iter().filter(|&&t| decode(t) == r).count();
        assert!(counts(HALF) > 0 && counts(QUARTER) > counts(FULL), "{} {} {}", counts(FULL), counts(HALF), counts(QUARTER));
    }

    #[test]
    fn side_by_side_eyes_follow_their_own_centre_and_texels_outside_stay_full() {
        // Two 100 px eyes side by side at x 0 and 100, texels of 16 straddle the seam at x 96..112.
        let l = EyeRates { layer: 0, rect: PixelRect { x: 0, y: 0, width: 100, height: 100 }, fov: FOV, fovea: fovea([0.9, 0.0], 10.0, 20.0) };
        let r = EyeRates { rect: PixelRect { x: 100, y: 0, width: 100, height: 100 }, fovea: fovea([-0.9, 0.0], 10.0, 20.0), ..l };
        let w = texels(200, 16);
        let h = texels(130, 16);
        let map = rate_layer(w, h, 16, 16, 0, &[l, r]);
        let at = |tx: u32, ty: u32| decode(map[(ty * w + tx) as usize]);
        // Both centres sit near the seam: the seam texel is full rate.
        assert_eq!(at(6, 3), FULL);
        assert_eq!(at(0, 3), QUARTER, "far left of the left eye");
        // Rows below the eyes (y ≥ 100) hold no eye pixel: full.
        assert_eq!(at(0, h - 1), FULL);
        // Another layer's eyes are ignored.
        let other = rate_layer(w, h, 16, 16, 1, &[l, r]);
        assert!(other.iter().all(|&t| t == 0));
    }

    #[test]
    fn stats_add_and_summarize() {
        let mut a = VrsFrameStats { passes: 2, ..Default::default() };
        a.count_not_applied(NotApplied::Unsupported);
        let mut b = VrsFrameStats::default();
        b.add(&a);
        b.add(&a);
        assert_eq!(b.passes, 4);
        assert_eq!(b.summary(), "vrs_passes=4 vrs_maps_built=0 vrs_not_applied.unsupported=2");
        assert_eq!(NotApplied::from_not_masked(NotMasked::NotEyePass), None);
        assert_eq!(NotApplied::from_not_masked(NotMasked::PostPass), None, "post passes are no candidates");
    }

    #[test]
    fn pass_eyes_by_layout() {
        let fov = ViewFov { tan_left: -1.0, tan_right: 1.0, tan_up: 1.0, tan_down: -1.0 };
        let fov_of = |_: u32| Some(fov);
        let fovea_of = |view: u32| Some(FoveaView { view, center: [0.0, 0.0], inner_deg: 20.0, middle_deg: 35.0 });
        let rect = |x: i32| PixelRect { x, y: 0, width: 64, height: 64 };
        let src = |view: u32, layer: u32, x: i32| EyeSource { view, layer, rect: rect(x) };
        let rates = DeviceRates { texel_width: 16, texel_height: 16, layered: true };
        let flat = PassShape { base_layer: 0, view_mask: 0, layered: false };
        // Side by side: both eyes in one layer.
        let (eyes, layers) = pass_eyes(&[src(0, 0, 0), src(1, 0, 64)], flat, rates, &fov_of, &fovea_of).unwrap();
        assert_eq!((eyes.len(), layers), (2, 1));
        // Multiview: a layer per view, on a device with layered rates only.
        let mv = PassShape { base_layer: 0, view_mask: 0b11, layered: false };
        let (eyes, layers) = pass_eyes(&[src(0, 0, 0), src(1, 1, 0)], mv, rates, &fov_of, &fovea_of).unwrap();
        assert_eq!((eyes.iter().map(|e| e.layer).collect::<Vec<_>>(), layers), (vec![0, 1], 2));
        assert_eq!(pass_eyes(&[src(0, 0, 0)], mv, DeviceRates { layered: false, ..rates }, &fov_of, &fovea_of), Err(NotApplied::MultiviewNotLayered));
        assert_eq!(pass_eyes(&[src(0, 0, 0)], PassShape { layered: true, ..flat }, rates, &fov_of, &fovea_of), Err(NotApplied::Layered));
        assert_eq!(pass_eyes(&[src(0, 1, 0)], flat, rates, &fov_of, &fovea_of), Err(NotApplied::EyeUnknown));
        assert_eq!(pass_eyes(&[src(0, 0, 0)], flat, rates, &fov_of, &|_| None), Err(NotApplied::NoFovea));
        assert_eq!(map_extent(Some((100, 50)), rect(0), rates), (7, 4));
        assert_eq!(map_extent(None, PixelRect { x: 10, y: 0, width: 64, height: 64 }, rates), (5, 4));
    }
}
