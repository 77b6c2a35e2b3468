//! Radial density masking (foveation method 2), pure and GPU-free: which 2×2 pixel quads of an eye
//! the layer rejects by depth (so the app shades none of their fragments) and which pixels the
//! reconstruction later fills. The rule is written once here in f32 operations that the shaders
//! (`shaders/rdm_rule.glsl`) repeat in the same order without fused multiply-adds, so the layer's
//! statistics and the tests' predictions match what the GPU skips exactly.
#![forbid(unsafe_code)]

pub use crate::core::fovea::Ring;
use crate::core::rect::PixelRect;
use crate::track::eye_pass::TransferRegion;
use crate::core::stats::{json_counts, Counters};
use crate::core::views::{FoveaView, ViewFov};
use std::collections::BTreeMap;

/// Everything the rule needs for one eye, as the shaders receive it (vertex attributes of the
/// injected draw, push constants of the reconstruction): f32 values computed once on the CPU.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RdmParams {
    /// The eye's image rect in the pass's framebuffer; quads are aligned to its origin.
    pub rect: PixelRect,
    /// Tangent of the left edge and of the top edge of the rect.
    pub tan_left: f32,
    pub tan_up: f32,
    /// Tangent per pixel, horizontally (to the right) and vertically (downwards).
    pub step_x: f32,
    pub step_y: f32,
    /// Fovea centre direction as a tangent-plane point (x right, y up).
    pub center: [f32; 2],
    /// cos²(inner_deg) · |centre|² and cos²(middle_deg) · |centre|², |centre| = |(cx, cy, −1)|:
    /// a direction t is within the angle when dot(t, c) > 0 and dot(t, c)² ≥ k · |t|².
    pub k_inner: f32,
    pub k_middle: f32,
}

impl RdmParams {
    /// The parameters of an eye whose image rect `rect` shows `fov`, foveated by `fovea`; None for
    /// an empty rect or a FOV without extent.
    pub fn new(fov: &ViewFov, fovea: &FoveaView, rect: PixelRect) -> Option<RdmParams> {
        if rect.width == 0 || rect.height == 0 || !(fov.tan_right > fov.tan_left && fov.tan_up > fov.tan_down) {
            return None;
        }
        let [cx, cy] = fovea.center;
        if !(cx.is_finite() && cy.is_finite()) {
            return None;
        }
        let c2 = cx as f64 * cx as f64 + cy as f64 * cy as f64 + 1.0;
        let k = |deg: f32| {
            let c = (deg.clamp(0.0, 90.0) as f64).to_radians().cos();
            (c * c * c2) as f32
        };
        let middle = fovea.middle_deg.max(fovea.inner_deg);
        Some(RdmParams {
            rect,
            tan_left: fov.tan_left,
            tan_up: fov.tan_up,
            step_x: (fov.tan_right - fov.tan_left) / rect.width as f32,
            step_y: (fov.tan_up - fov.tan_down) / rect.height as f32,
            center: [cx, cy],
            k_inner: k(fovea.inner_deg),
            k_middle: k(middle),
        })
    }

    /// The ring of quad (qx, qy) (rect-relative quad coordinates), judged at the quad's centre,
    /// the pixel corner (2qx + 1, 2qy + 1) of the rect. Every operation is a single f32 add or
    /// multiply in the order `shaders/rdm_rule.glsl` uses (`precise` there: no fused multiply-add).
    pub fn ring(&self, qx: u32, qy: u32) -> Ring {
        let fx = (2 * qx + 1) as f32;
        let fy = (2 * qy + 1) as f32;
        let tx = self.tan_left + fx * self.step_x;
        let ty = self.tan_up - fy * self.step_y;
        let d = tx * self.center[0] + ty * self.center[1] + 1.0;
        let n2 = tx * tx + ty * ty + 1.0;
        let d2 = d * d;
        if d > 0.0 && d2 >= self.k_inner * n2 {
            Ring::Inner
        } else if d > 0.0 && d2 >= self.k_middle * n2 {
            Ring::Middle
        } else {
            Ring::Outer
        }
    }

    /// Whether the layer skips quad (qx, qy).
    pub fn quad_skipped(&self, qx: u32, qy: u32) -> bool {
        skipped(self.ring(qx, qy), qx, qy)
    }

    /// Whether framebuffer pixel (x, y) lies in a skipped quad (false outside the rect).
    pub fn pixel_skipped(&self, x: i32, y: i32) -> bool {
        let (rx, ry) = (x as i64 - self.rect.x as i64, y as i64 - self.rect.y as i64);
        if rx < 0 || ry < 0 || rx >= self.rect.width as i64 || ry >= self.rect.height as i64 {
            return false;
        }
        self.quad_skipped((rx / 2) as u32, (ry / 2) as u32)
    }

    /// What the injected draw skips within `clip` (framebuffer pixels, e.g. rect ∩ render area).
    pub fn count(&self, clip: PixelRect) -> SkipCount {
        let area = self.rect.intersect(&clip);
        let mut n = SkipCount::default();
        if area.area() == 0 {
            return n;
        }
        let (x0, y0) = ((area.x - self.rect.x) as u32, (area.y - self.rect.y) as u32);
        let (x1, y1) = (x0 + area.width, y0 + area.height);
        for qy in y0 / 2..y1.div_ceil(2) {
            let rows = (2 * qy + 2).min(y1) - (2 * qy).max(y0);
            for qx in x0 / 2..x1.div_ceil(2) {
                let cols = (2 * qx + 2).min(x1) - (2 * qx).max(x0);
                n.quads += 1;
                if self.quad_skipped(qx, qy) {
                    n.quads_skipped += 1;
                    n.pixels_skipped += (rows * cols) as u64;
                }
            }
        }
        n
    }
}

/// Quads per side of a reconstruction tile: one compute workgroup of `shaders/rdm_recon.comp`
/// (8×8 invocations, 2×2 quads each: 32×32 pixels). Large, because a software rasterizer pays a
/// fixed cost per workgroup (measured on lavapipe: 8×8-quad tiles spent more on that than on the
/// fill); the fovea's tiles are few either way.
pub const TILE_QUADS: u32 = 16;

impl RdmParams {
    /// The tiles (`TILE_QUADS`² quads, counted from the rect's origin) that the reconstruction
    /// visits: every tile of the rect meeting `clip` (image pixels) that may hold a skipped quad,
    /// packed `x | y << 16`, row by row. A tile is left out only when it is certainly inside the
    /// inner ring, where nothing is skipped; that is what makes the pass proportional to the
    /// periphery instead of the eye.
    ///
    /// Certainly inside: the inner ring is a cone of directions within `inner_deg` of the centre
    /// (≤ 90°, so convex), and quad centres map affinely onto the tangent plane, so when the four
    /// corners of the tile *grown by one quad* are inside (in f64), every quad of the tile is at
    /// least a quad's step inside — far beyond the f32 rounding of the rule the GPU evaluates
    /// (`ring`), which therefore calls all of them inner too. Tiles across the ring's edge are
    /// kept; the GPU judges each of their quads exactly.
    pub fn periphery_tiles(&self, clip: PixelRect) -> Vec<u32> {
        let area = self.rect.intersect(&clip);
        if area.area() == 0 {
            return Vec::new();
        }
        let tile_px = 2 * TILE_QUADS;
        let (x0, y0) = ((area.x - self.rect.x) as u32 / tile_px, (area.y - self.rect.y) as u32 / tile_px);
        let x1 = ((area.x - self.rect.x) as u32 + area.width).div_ceil(tile_px);
        let y1 = ((area.y - self.rect.y) as u32 + area.height).div_ceil(tile_px);
        let mut out = Vec::new();
        for ty in y0..y1.min(1 << 16) {
            for tx in x0..x1.min(1 << 16) {
                let (qx, qy) = ((tx * TILE_QUADS) as i64, (ty * TILE_QUADS) as i64);
                let last = TILE_QUADS as i64 - 1;
                if !self.surely_inner(qx - 1, qy - 1, qx + last + 1, qy + last + 1) {
                    out.push(tx | (ty << 16));
                }
            }
        }
        out
    }

    /// Whether every quad centre of quads (qx0..=qx1, qy0..=qy1) lies in the inner cone, judged in
    /// f64 at the box's four corner quads (the cone is convex).
    fn surely_inner(&self, qx0: i64, qy0: i64, qx1: i64, qy1: i64) -> bool {
        let inner = |qx: i64, qy: i64| {
            let tx = self.tan_left as f64 + (2 * qx + 1) as f64 * self.step_x as f64;
            let ty = self.tan_up as f64 - (2 * qy + 1) as f64 * self.step_y as f64;
            let d = tx * self.center[0] as f64 + ty * self.center[1] as f64 + 1.0;
            let n2 = tx * tx + ty * ty + 1.0;
            d > 0.0 && d * d >= self.k_inner as f64 * n2
        };
        // k_inner ≤ 0 would be an inner angle past 90°: not a convex cone, never "surely".
        self.k_inner > 0.0 && inner(qx0, qy0) && inner(qx1, qy0) && inner(qx0, qy1) && inner(qx1, qy1)
    }
}

/// How the compute reconstruction reads an image's pixels, copied into a storage buffer: one
/// 32-bit word per texel for 4 × 8-bit channels (BGRA and RGBA alike, since the filter treats
/// every channel the same and alpha is the fourth byte in both), decoded from sRGB by the shader
/// where the format is sRGB; two words per texel for 16-bit float channels (the HDR targets
/// engines render their eyes into behind a tonemap). Other formats (10-bit, 11-bit float, …)
/// take the fill.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ComputeStorage {
    Rgba8 { srgb: bool },
    Rgba16F,
}

impl ComputeStorage {
    /// The compute path's storage for a colour format; None: the fill (fragment) path only.
    pub fn for_format(format: ash::vk::Format) -> Option<ComputeStorage> {
        use ash::vk::Format as F;
        match format {
            F::R8G8B8A8_UNORM | F::B8G8R8A8_UNORM => Some(ComputeStorage::Rgba8 { srgb: false }),
            F::R8G8B8A8_SRGB | F::B8G8R8A8_SRGB => Some(ComputeStorage::Rgba8 { srgb: true }),
            F::R16G16B16A16_SFLOAT => Some(ComputeStorage::Rgba16F),
            _ => None,
        }
    }
    /// Bytes per texel in the pixel buffer (what a buffer ↔ image copy of the format moves).
    pub fn texel_bytes(&self) -> u64 {
        match self {
            ComputeStorage::Rgba8 { .. } => 4,
            ComputeStorage::Rgba16F => 8,
        }
    }
    /// Whether the shader decodes and encodes sRGB.
    pub fn srgb(&self) -> bool {
        matches!(self, ComputeStorage::Rgba8 { srgb: true })
    }
}

/// Which reconstruction a swapchain image of `format` gets: the compute pass over periphery
/// tiles when its format has a storage equivalent and the image can be written back by a copy
/// (`transfer_dst`), else why the fragment fill runs instead.
///
/// At the release only 8-bit swapchains: no runtime the suite runs offers 16-bit float colour
/// swapchains, so that variant is proven only where engines use it, at an eye pass's end
/// (`pass_end_compute`).
pub fn compute_path(format: ash::vk::Format, transfer_dst: bool) -> Result<ComputeStorage, FillFallback> {
    let storage = ComputeStorage::for_format(format).filter(|s| s.texel_bytes() == 4).ok_or(FillFallback::Format)?;
    if !transfer_dst {
        return Err(FillFallback::TransferDst);
    }
    Ok(storage)
}

/// Why a reconstruction took the fragment fill instead of the compute pass. Stable names
/// (statistics: `rdm_fill_fallback.<name>`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FillFallback {
    /// The swapchain format is not one the compute pass handles (`ComputeStorage::for_format`).
    Format,
    /// The swapchain image lacks TRANSFER_DST (the runtime refused the layer's usage bit), so
    /// the reconstructed copy cannot be written back.
    TransferDst,
    /// The compute objects could not be created.
    LayerError,
    /// `foveation.rdm_reconstruction = fill`.
    Configured,
    /// Behind a post chain: reconstructed when the eye pass ended, in the app's command buffer.
    PassEnd,
}

impl FillFallback {
    pub fn name(&self) -> &'static str {
        match self {
            FillFallback::Format => "format",
            FillFallback::TransferDst => "transfer_dst",
            FillFallback::LayerError => "layer_error",
            FillFallback::Configured => "configured",
            FillFallback::PassEnd => "pass_end",
        }
    }
}

/// The skip rule per ring: middle: (qx + qy) odd; outer: all but qx, qy both even; inner: none.
pub fn skipped(ring: Ring, qx: u32, qy: u32) -> bool {
    match ring {
        Ring::Inner => false,
        Ring::Middle => (qx + qy) & 1 == 1,
        Ring::Outer => qx & 1 == 1 || qy & 1 == 1,
    }
}

/// Whether `foveation.method` means radial density masking on a device: rdm always, vrs never,
/// auto on a GPU that lacks `attachmentFragmentShadingRate` (older GPUs), never on a CPU
/// implementation (`software`: lavapipe; `foveation::Method::resolve` says why).
pub fn method_is_rdm(method: &str, fsr_attachment: bool, software: bool) -> bool {
    match method {
        "rdm" => true,
        "vrs" => false,
        _ => !fsr_attachment && !software,
    }
}

/// Quads of an area (touching it), skipped quads, and skipped pixels inside it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SkipCount {
    pub quads: u64,
    pub quads_skipped: u64,
    pub pixels_skipped: u64,
}

/// Reconstruction weight of a shaded neighbour at pixel offset (dx, dy) from the skipped pixel:
/// the filter averages the pixels of the shaded quads bordering the skipped quad (the ring of 12
/// pixels around it), weighted by inverse squared distance — nearest neighbours dominate, as in
/// Vlachos' reconstruction, and the outer ring's isolated quads fall back to their diagonal
/// neighbours. `shaders/rdm_fill.frag` implements this.
pub fn reconstruction_weight(dx: i32, dy: i32) -> f32 {
    1.0 / (dx * dx + dy * dy) as f32
}

/// Why a pass or a swapchain image got no radial density masking. Stable names (statistics).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum NotApplied {
    /// The OpenXR half publishes no foveation for the view (or no FOV).
    NoFovea,
    /// The device cannot give the layer what it needs (pipeline, buffer, queue, usage).
    LayerError,
    /// The target's pixels do not reach a swapchain image 1:1 (reconstruction impossible).
    NotOneToOne,
    /// The swapchain image lacks TRANSFER_SRC / COLOR_ATTACHMENT usage for the reconstruction.
    SwapchainUsage,
    /// The app's device was created without what the layer's draw needs for this pass (e.g.
    /// `multiview`): the layer never creates an object the device cannot legally have.
    DeviceLacks,
    /// The eye pass's target is read by a post-process chain (found by the data-flow walk)
    /// before the runtime sees it, and RDM was not asked for by name: its reconstruction at the
    /// pass's end costs more than it saves at moderate loads (`vk::pass_end_wanted`).
    PostChain,
    /// Behind a post chain, the eye pass is followed by a subpass of its own render pass (or its
    /// rendering is suspended): no reconstruction can run between them.
    SubpassChain,
    /// Behind a post chain, the multisampled eye is resolved after its pass (a transfer), not by
    /// the pass itself: nothing single-sampled to reconstruct when it ends.
    MsaaUnresolved,
    /// Behind a post chain, the target the pass leaves the eye in cannot be copied from or drawn
    /// into (usage, layout), or the reconstruction's objects could not be made for it.
    TargetUsage,
}

impl NotApplied {
    pub fn name(&self) -> &'static str {
        match self {
            NotApplied::NoFovea => "no_fovea",
            NotApplied::LayerError => "layer_error",
            NotApplied::NotOneToOne => "not_one_to_one",
            NotApplied::SwapchainUsage => "swapchain_usage",
            NotApplied::DeviceLacks => "device_lacks",
            NotApplied::PostChain => "post_chain",
            NotApplied::SubpassChain => "subpass_chain",
            NotApplied::MsaaUnresolved => "msaa_unresolved",
            NotApplied::TargetUsage => "target_usage",
        }
    }
}

/// What radial density masking did in one frame, summed over devices (`stats.file`).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct RdmFrameStats {
    /// Eye passes (or explicit depth clears) that got the checkerboard draw.
    pub passes: u64,
    /// Quads and pixels the draws skipped, per OpenXR view index.
    pub quads_skipped: BTreeMap<u32, u64>,
    pub pixels_skipped: BTreeMap<u32, u64>,
    /// Eye rects filled in by the reconstruction before the runtime saw them, per view.
    pub reconstructed: BTreeMap<u32, u64>,
    /// Passes / images left alone, by reason (`NotApplied::name`).
    pub not_applied: BTreeMap<&'static str, u64>,
    /// Eye rects reconstructed by the compute pass over periphery tiles, and the tiles it ran.
    pub compute: u64,
    pub compute_tiles: u64,
    /// Reconstructions that took the fragment fill, by reason (`FillFallback::name`).
    pub fill_fallback: BTreeMap<&'static str, u64>,
}

impl RdmFrameStats {
    pub fn add(&mut self, o: &RdmFrameStats) {
        self.passes += o.passes;
        for (dst, src) in [(&mut self.quads_skipped, &o.quads_skipped), (&mut self.pixels_skipped, &o.pixels_skipped), (&mut self.reconstructed, &o.reconstructed)] {
            for (k, v) in src {
                *dst.entry(*k).or_insert(0) += v;
            }
        }
        for (k, v) in &o.not_applied {
            *self.not_applied.entry(k).or_insert(0) += v;
        }
        self.compute += o.compute;
        self.compute_tiles += o.compute_tiles;
        for (k, v) in &o.fill_fallback {
            *self.fill_fallback.entry(k).or_insert(0) += v;
        }
    }
    pub fn count_not_applied(&mut self, why: NotApplied) {
        *self.not_applied.entry(why.name()).or_insert(0) += 1;
    }
    pub fn is_empty(&self) -> bool {
        *self == RdmFrameStats::default()
    }
    /// `key=value` pairs for the `vulkan device stats:` line.
    pub fn summary(&self) -> String {
        let sum = |m: &BTreeMap<u32, u64>| m.values().sum::<u64>();
        let mut s = format!(
            "rdm_passes={} rdm_quads_skipped={} rdm_pixels_skipped={} rdm_reconstructed={}",
            self.passes,
            sum(&self.quads_skipped),
            sum(&self.pixels_skipped),
            sum(&self.reconstructed)
        );
        for (k, v) in &self.not_applied {
            s.push_str(&format!(" rdm_not_applied.{k}={v}"));
        }
        if self.compute > 0 {
            s.push_str(&format!(" rdm_compute={} rdm_compute_tiles={}", self.compute, self.compute_tiles));
        }
        for (k, v) in &self.fill_fallback {
            s.push_str(&format!(" rdm_fill_fallback.{k}={v}"));
        }
        s
    }
}

impl Counters for RdmFrameStats {
    const ID: &'static str = "rdm";
    const LABEL: &'static str = "foveation (radial density masking)";
    const GROUP: Option<&'static str> = Some("foveation");
    fn merge(&mut self, o: &Self) {
        RdmFrameStats::add(self, o);
    }
    fn applied(&self) -> u64 {
        self.passes
    }
    fn left_alone(&self) -> Vec<(&'static str, u64)> {
        self.not_applied.iter().map(|(k, v)| (*k, *v)).collect()
    }
    fn hint_for(&self, reason: &str) -> &'static str {
        match reason {
            "no_fovea" => "no fovea yet for the view (the first frame): nothing to do unless it persists",
            "post_chain" => "the eye pass renders into a target a post-process chain reads: with foveation.method = auto RDM leaves it whole, since its reconstruction there (the fragment fill at the pass's end) costs more than it saves at moderate loads; foveation.method = \"rdm\" applies it",
            "subpass_chain" => "behind a post chain, the eye pass is followed by more than one subpass of its render pass, or by one that does not read the eye as an input attachment, or its rendering is suspended: no reconstruction can run in between, so it is left whole; use foveation.method = \"vrs\" where the GPU has it",
            "msaa_unresolved" => "the multisampled eye is resolved after its pass by a transfer the layer cannot follow pixel by pixel (behind a post chain, or into a multisampled swapchain image, as xrizer does for an MSAA game texture): RDM reconstructs only single-sampled targets when the pass ends, so it leaves the pass whole; use foveation.method = \"vrs\" where the GPU has it",
            "target_usage" => "behind a post chain, the eye's target cannot be copied from or drawn into by the reconstruction (usage or layout), or its objects could not be made: the pass is left whole",
            "not_one_to_one" => "the app copies the eye image to the swapchain scaled or offset: RDM cannot reconstruct it; use foveation.method = \"vrs\" where the GPU has it",
            "swapchain_usage" => "the swapchain image lacks the usage RDM's reconstruction needs",
            _ => crate::core::stats::common_hint(reason),
        }
    }
    fn line(&self) -> String {
        RdmFrameStats::summary(self)
    }
    fn json(&self, record: &mut serde_json::Map<String, serde_json::Value>) {
        let per_view = |m: &BTreeMap<u32, u64>| json_counts(m.iter().map(|(k, v)| (*k, *v)));
        record.insert(
            "rdm".into(),
            serde_json::json!({
                "passes": self.passes,
                "quads_skipped": per_view(&self.quads_skipped),
                "pixels_skipped": per_view(&self.pixels_skipped),
                "reconstructed": per_view(&self.reconstructed),
                "not_applied": json_counts(self.not_applied.iter().map(|(k, v)| (*k, *v))),
                "compute": self.compute,
                "compute_tiles": self.compute_tiles,
                "fill_fallback": json_counts(self.fill_fallback.iter().map(|(k, v)| (*k, *v))),
            }),
        );
    }
}

/// One eye of an image whose skipped quads await reconstruction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pending {
    pub view: u32,
    pub layer: u32,
    /// The rule as drawn; `params.rect` is in the image's pixels.
    pub params: RdmParams,
}

/// Where the eyes awaiting reconstruction in an image go when the app transfers that image.
#[derive(Debug, Default, PartialEq)]
pub struct HandOff {
    /// Carried 1:1 into the destination (in its layers and pixels).
    pub moved: Vec<Pending>,
    /// Not touched by any region: still the source's.
    pub kept: Vec<Pending>,
    /// Touched by a scaled or partial region: their skipped quads cannot be reconstructed.
    pub scaled: u64,
}

/// The hand-off of `pending` (the source image's eyes) through a transfer's `regions`.
pub fn hand_off(pending: Vec<Pending>, regions: &[TransferRegion]) -> HandOff {
    let mut out = HandOff::default();
    for p in pending {
        let hit = regions.iter().find(|r| p.layer >= r.src_layer && p.layer < r.src_layer + r.layer_count && r.src.intersect(&p.params.rect).area() > 0);
        match hit {
            Some(r) if (r.src.width, r.src.height) == (r.dst.width, r.dst.height) && r.src.contains(&p.params.rect) => {
                let mut q = p;
                q.layer = p.layer - r.src_layer + r.dst_layer;
                q.params.rect.x = p.params.rect.x - r.src.x + r.dst.x;
                q.params.rect.y = p.params.rect.y - r.src.y + r.dst.y;
                out.moved.push(q);
            }
            Some(_) => out.scaled += 1,
            None => out.kept.push(p),
        }
    }
    out
}

/// Where a reconstruction's command buffer comes from, at `xrReleaseSwapchainImage`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SlotChoice {
    /// The oldest slot's submission completed: reuse it.
    ReuseOldest,
    /// All are in flight and the cap allows another: make one (no wait).
    New,
    /// All `max` are in flight: wait for the oldest. The GPU is then `max` reconstructions
    /// behind, more than a runtime's `xrWaitFrame` lets an app run ahead, so the app's own next
    /// frame would wait at least as long.
    WaitOldest,
}

/// Picks the slot for a reconstruction: `oldest_done` is whether the oldest slot's fence
/// signalled (None: no slot yet), `count` the slots made so far.
pub fn slot_choice(oldest_done: Option<bool>, count: usize, max: usize) -> SlotChoice {
    match oldest_done {
        Some(true) => SlotChoice::ReuseOldest,
        _ if count < max => SlotChoice::New,
        Some(false) => SlotChoice::WaitOldest,
        // No slot in the queue although `count` reached the cap: every slot is being recorded on
        // another thread right now; one more keeps this release from waiting on them.
        None => SlotChoice::New,
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn a_release_waits_only_when_every_slot_is_in_flight() {
        use super::{slot_choice, SlotChoice::*};
        assert_eq!(slot_choice(None, 0, 8), New);
        assert_eq!(slot_choice(Some(true), 3, 8), ReuseOldest);
        assert_eq!(slot_choice(Some(true), 8, 8), ReuseOldest);
        assert_eq!(slot_choice(Some(false), 3, 8), New);
        assert_eq!(slot_choice(Some(false), 7, 8), New);
        assert_eq!(slot_choice(Some(false), 8, 8), WaitOldest);
        assert_eq!(slot_choice(None, 8, 8), New);
    }

    use super::*;
    use std::collections::HashSet;

    const FOV: ViewFov = ViewFov { tan_left: -1.0, tan_right: 1.0, tan_up: 1.0, tan_down: -1.0 };

    fn fovea(inner: f32, middle: f32) -> FoveaView {
        FoveaView { view: 0, center: [0.0, 0.0], inner_deg: inner, middle_deg: middle }
    }

    fn rect(w: u32, h: u32) -> PixelRect {
        PixelRect { x: 0, y: 0, width: w, height: h }
    }

    #[test]
    fn skip_pattern_per_ring() {
        // Inner: nothing; middle: checkerboard, half; outer: only (even, even) kept, 3 of 4.
        let all = |ring| (0..4).flat_map(|y| (0..4).map(move |x| (x, y))).filter(|&(x, y)| skipped(ring, x, y)).count();
        assert_eq!(all(Ring::Inner), 0);
        assert!(method_is_rdm("rdm", true, true) && !method_is_rdm("vrs", false, false) && method_is_rdm("auto", false, false) && !method_is_rdm("auto", true, false));
        assert!(!method_is_rdm("auto", false, true));
        assert_eq!(all(Ring::Middle), 8);
        assert_eq!(all(Ring::Outer), 12);
        assert!(!skipped(Ring::Middle, 0, 0) && skipped(Ring::Middle, 1, 0) && !skipped(Ring::Middle, 1, 1));
        assert!(!skipped(Ring::Outer, 2, 4) && skipped(Ring::Outer, 1, 0) && skipped(Ring::Outer, 0, 1) && skipped(Ring::Outer, 1, 1));
    }

    #[test]
    fn rings_follow_the_angle_from_the_centre() {
        // 90° FOV square, 200 px: tangent at pixel corner u is −1 + u/100.
        let p = RdmParams::new(&FOV, &fovea(20.0, 35.0), rect(200, 200)).unwrap();
        // The quad at the centre: inner.
        assert_eq!(p.ring(50, 50), Ring::Inner);
        // Quad centre x-corner 2q+1; tan 20° = 0.364 → corner ≈ 136.4 → q ≈ 67.7; tan 35° = 0.700
        // → corner 170 → q 84.5.
        assert_eq!(p.ring(67, 49), Ring::Inner, "corner 135, tan 0.35 < tan 20°");
        assert_eq!(p.ring(68, 49), Ring::Middle);
        assert_eq!(p.ring(84, 49), Ring::Middle);
        assert_eq!(p.ring(85, 49), Ring::Outer);
        // Symmetric to the left: corner 2q+1 = 200 − 137 → q 31 is middle, 32 inner.
        assert_eq!(p.ring(31, 49), Ring::Middle);
        assert_eq!(p.ring(32, 49), Ring::Inner);
        // Corners are far out.
        assert_eq!(p.ring(0, 0), Ring::Outer);
    }

    #[test]
    fn an_off_axis_centre_moves_the_rings() {
        let mut f = fovea(10.0, 20.0);
        f.center = [0.5, 0.0];
        let p = RdmParams::new(&FOV, &f, rect(200, 200)).unwrap();
        // tan = 0.5 at corner 150 → quad 74.
        assert_eq!(p.ring(74, 49), Ring::Inner);
        assert_eq!(p.ring(50, 49), Ring::Outer, "the optical axis is ~26.6° from the centre");
        // The angle is what counts, not the tangent distance: 10° from atan(0.5) = 26.57° is
        // 36.57° (tan 0.7417) outwards but 16.57° (tan 0.2976) inwards.
        let angle = |q: u32| crate::core::fovea::angle_between_deg([-1.0 + (2 * q + 1) as f32 / 100.0, 0.0], [0.5, 0.0]);
        for q in 50..100 {
            let want = if angle(q) <= 10.0 { Ring::Inner } else if angle(q) <= 20.0 { Ring::Middle } else { Ring::Outer };
            if (angle(q) - 10.0).abs() > 0.05 && (angle(q) - 20.0).abs() > 0.05 {
                assert_eq!(p.ring(q, 49), want, "quad {q} at {}°", angle(q));
            }
        }
    }

    #[test]
    fn counts_clip_to_the_area_and_partial_quads() {
        let p = RdmParams::new(&FOV, &fovea(0.0, 0.0), PixelRect { x: 10, y: 0, width: 7, height: 3 }).unwrap();
        // All outer: quads (x 0..4) × (y 0..2); kept (even, even): (0,0), (2,0); the rest skipped.
        let n = p.count(PixelRect { x: 0, y: 0, width: 100, height: 100 });
        assert_eq!(n.quads, 8);
        assert_eq!(n.quads_skipped, 6);
        // Kept pixels: quads (0,0) and (2,0), 2×2 each = 8; skipped = 21 − 8.
        assert_eq!(n.pixels_skipped, 13);
        let by_pixel = (0..3).flat_map(|y| (10..17).map(move |x| (x, y))).filter(|&(x, y)| p.pixel_skipped(x, y)).count();
        assert_eq!(by_pixel, 13);
        assert!(!p.pixel_skipped(9, 0) && !p.pixel_skipped(17, 0));
        // Clipped to the first 3 columns: quads 0 and 1 (partly), rows 0..3.
        let c = p.count(PixelRect { x: 10, y: 0, width: 3, height: 3 });
        assert_eq!((c.quads, c.quads_skipped, c.pixels_skipped), (4, 3, 9 - 4));
        assert_eq!(p.count(PixelRect { x: 0, y: 0, width: 5, height: 5 }), SkipCount::default());
    }

    #[test]
    fn balanced_skips_a_plausible_fraction() {
        let p = RdmParams::new(&FOV, &fovea(20.0, 35.0), rect(400, 400)).unwrap();
        let n = p.count(p.rect);
        let f = n.pixels_skipped as f64 / p.rect.area() as f64;
        // Inner disc r ≈ 0.364·200 px, middle to 0.70·200: ≈ 0.13 inner, ≈ 0.25 middle (half),
        // ≈ 0.62 outer (¾): about 0.59.
        assert!((0.5..0.7).contains(&f), "{f}");
        assert!(RdmParams::new(&FOV, &fovea(20.0, 35.0), rect(0, 4)).is_none());
    }

    #[test]
    fn stats_add_and_summarise() {
        let mut a = RdmFrameStats { passes: 1, ..Default::default() };
        a.quads_skipped.insert(1, 5);
        a.pixels_skipped.insert(1, 20);
        a.count_not_applied(NotApplied::NotOneToOne);
        let mut b = RdmFrameStats::default();
        assert!(b.is_empty());
        b.add(&a);
        b.add(&a);
        assert_eq!(b.summary(), "rdm_passes=2 rdm_quads_skipped=10 rdm_pixels_skipped=40 rdm_reconstructed=0 rdm_not_applied.not_one_to_one=2");
        assert_eq!(reconstruction_weight(1, 0), 1.0);
        assert_eq!(reconstruction_weight(2, 1), 0.2);
    }

    /// Every skipped quad, judged by the f32 rule the GPU evaluates, lies in a tile the
    /// reconstruction visits; `clip` drops only tiles outside it. Pseudo-random rects (odd sizes
    /// and offsets), asymmetric FOVs, off-axis centres and ring angles from 0° to 90°.
    #[test]
    fn periphery_tiles_cover_every_skipped_quad() {
        let mut seed = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        for case in 0..160 {
            let fov = ViewFov { tan_left: -0.6 - next() as f32 * 0.8, tan_right: 0.6 + next() as f32 * 0.8, tan_up: 0.5 + next() as f32 * 0.9, tan_down: -0.5 - next() as f32 * 0.9 };
            let inner = if case % 10 == 0 { 0.0 } else if case % 10 == 1 { 90.0 } else { (next() * 40.0) as f32 };
            let fovea = FoveaView { view: 0, center: [(next() - 0.5) as f32, (next() - 0.5) as f32], inner_deg: inner, middle_deg: inner + (next() * 20.0) as f32 };
            let r = PixelRect { x: (next() * 40.0) as i32, y: (next() * 40.0) as i32, width: 1 + (next() * 300.0) as u32, height: 1 + (next() * 300.0) as u32 };
            let p = RdmParams::new(&fov, &fovea, r).unwrap();
            let tiles: HashSet<u32> = p.periphery_tiles(r).into_iter().collect();
            for qy in 0..r.height.div_ceil(2) {
                for qx in 0..r.width.div_ceil(2) {
                    if p.quad_skipped(qx, qy) {
                        let t = (qx / TILE_QUADS) | ((qy / TILE_QUADS) << 16);
                        assert!(tiles.contains(&t), "case {case}: skipped quad ({qx}, {qy}) in tile {t:#x} not visited ({p:?})");
                    }
                }
            }
            // Clipped to the left half: only tiles meeting it, still every skipped quad there.
            let half = PixelRect { width: r.width.div_ceil(2), ..r };
            let clipped = p.periphery_tiles(half);
            assert!(clipped.iter().all(|t| tiles.contains(t) && (t & 0xffff) * 2 * TILE_QUADS < half.width));
        }
    }

    #[test]
    fn periphery_tiles_leave_out_the_fovea() {
        // 2016×2240 (Index at 100 %), balanced rings on the axis: the tiles of the inner disc
        // (20° of a ~±55° view) are left out, about the disc's share of the eye.
        let fov = ViewFov { tan_left: -1.39, tan_right: 1.24, tan_up: 1.39, tan_down: -1.47 };
        let p = RdmParams::new(&fov, &fovea(20.0, 35.0), rect(2016, 2240)).unwrap();
        let tile_px = 2 * TILE_QUADS;
        let all = 2016u32.div_ceil(tile_px) * 2240u32.div_ceil(tile_px);
        let tiles = p.periphery_tiles(p.rect);
        let left_out = all as usize - tiles.len();
        assert!(left_out > all as usize / 40 && left_out < all as usize / 5, "{left_out} of {all}");
        // No quad of a left-out tile is skipped (the whole rect, exhaustively).
        let visited: HashSet<u32> = tiles.iter().copied().collect();
        let n = p.count(p.rect);
        let in_tiles: u64 = (0..1120u32).flat_map(|qy| (0..1008u32).map(move |qx| (qx, qy))).filter(|&(qx, qy)| visited.contains(&((qx / TILE_QUADS) | ((qy / TILE_QUADS) << 16))) && p.quad_skipped(qx, qy)).count() as u64;
        assert_eq!(in_tiles, n.quads_skipped);
        // Packing: row by row, x in the low half.
        assert_eq!(tiles[0], 0);
        assert!(tiles.windows(2).all(|w| (w[0] >> 16, w[0] & 0xffff) < (w[1] >> 16, w[1] & 0xffff)));
        // Nothing inner (0°): every tile; an empty clip: none.
        let everything = RdmParams::new(&fov, &fovea(0.0, 10.0), rect(100, 50)).unwrap();
        assert_eq!(everything.periphery_tiles(everything.rect).len(), (100u32.div_ceil(tile_px) * 50u32.div_ceil(tile_px)) as usize);
        assert!(p.periphery_tiles(PixelRect { x: 5000, y: 0, width: 10, height: 10 }).is_empty());
    }

    #[test]
    fn compute_storage_per_format() {
        use ash::vk::Format as F;
        assert_eq!(ComputeStorage::for_format(F::R8G8B8A8_SRGB), Some(ComputeStorage::Rgba8 { srgb: true }));
        assert_eq!(ComputeStorage::for_format(F::B8G8R8A8_SRGB), Some(ComputeStorage::Rgba8 { srgb: true }));
        assert_eq!(ComputeStorage::for_format(F::B8G8R8A8_UNORM), Some(ComputeStorage::Rgba8 { srgb: false }));
        assert_eq!(ComputeStorage::for_format(F::R16G16B16A16_SFLOAT), Some(ComputeStorage::Rgba16F));
        assert_eq!(ComputeStorage::Rgba16F.texel_bytes(), 8);
        assert!(!ComputeStorage::Rgba16F.srgb() && ComputeStorage::Rgba8 { srgb: true }.srgb());
        assert_eq!(ComputeStorage::for_format(F::A2B10G10R10_UNORM_PACK32), None);
        assert_eq!(FillFallback::TransferDst.name(), "transfer_dst");
        assert_eq!(compute_path(F::R8G8B8A8_SRGB, true), Ok(ComputeStorage::Rgba8 { srgb: true }));
        assert_eq!(compute_path(F::R8G8B8A8_SRGB, false), Err(FillFallback::TransferDst));
        assert_eq!(compute_path(F::B10G11R11_UFLOAT_PACK32, true), Err(FillFallback::Format));
        assert_eq!(compute_path(F::R16G16B16A16_SFLOAT, true), Err(FillFallback::Format), "16-bit float only at a pass end");
    }

    #[test]
    fn hand_off_moves_one_to_one_and_counts_scaled() {
        let fov = ViewFov { tan_left: -1.0, tan_right: 1.0, tan_up: 1.0, tan_down: -1.0 };
        let fovea = FoveaView { view: 0, center: [0.0, 0.0], inner_deg: 20.0, middle_deg: 35.0 };
        let eye = |view: u32, x: i32| Pending { view, layer: 0, params: RdmParams::new(&fov, &FoveaView { view, ..fovea }, PixelRect { x, y: 0, width: 8, height: 8 }).unwrap() };
        let region = |src_x: i32, dst_x: i32, w: u32| TransferRegion {
            src: PixelRect { x: src_x, y: 0, width: w, height: 8 },
            dst: PixelRect { x: dst_x, y: 0, width: 8, height: 8 },
            src_layer: 0,
            dst_layer: 1,
            layer_count: 1,
        };
        // Eye 0 copied 1:1 to x 100 of layer 1, eye 1 (x 8) scaled, a third eye (x 16) untouched.
        let out = hand_off(vec![eye(0, 0), eye(1, 8), eye(1, 16)], &[region(0, 100, 8), region(8, 0, 4)]);
        assert_eq!(out.moved.len(), 1);
        assert_eq!((out.moved[0].layer, out.moved[0].params.rect.x), (1, 100));
        assert_eq!(out.scaled, 1);
        assert_eq!(out.kept.len(), 1);
        assert_eq!(out.kept[0].params.rect.x, 16);
    }
}
