//! Why the eye-pass test leaves a render pass instance alone: the shared vocabulary of the pass
//! classifier (`track::eye_pass`) that every feature maps to its own "not applied" reasons.
#![forbid(unsafe_code)]

/// Why a render pass instance got no mask. Stable names: they appear in statistics and logs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum NotMasked {
    /// Nothing of the pass renders into a swapchain image or a known intermediate target.
    NotEyePass,
    /// It renders into a swapchain image whose eye use the OpenXR half has not seen yet, or into a
    /// target not (yet) known to be copied into one.
    EyeUnknown,
    NoDepthAttachment,
    /// The depth attachment is loaded, not cleared, at the start of the pass (and no clear of it
    /// was seen).
    DepthNotCleared,
    /// Cleared to something other than 0 or 1: which value fails the app's test is unknown.
    DepthClearNot01,
    /// `SECONDARY_COMMAND_BUFFERS` contents or a secondary command buffer: draws cannot be
    /// recorded there by the layer.
    Secondary,
    /// The OpenXR half has no mask or FOV for the eye's view.
    NoMask,
    /// A shape the layer does not handle (e.g. multiview layers not in view order, rects that
    /// differ between views of one multiview pass).
    Unsupported,
    /// `mask.intermediate = off` and the pass renders into an intermediate target.
    IntermediateOff,
    /// The layer could not create its pipeline or vertex buffer.
    LayerError,
    /// The app's device was created without what the layer's draw needs for this pass (e.g.
    /// `multiview`, `dynamicRendering`): the layer never creates an object the device cannot
    /// legally have.
    DeviceLacks,
    /// A post-process pass (its draws never test depth: tonemap, upscale, TAA resolve) writes
    /// the eye's image; the eye pass is behind it (the data-flow walk finds it).
    PostPass,
    /// The data-flow walk saw the eye's rect in the target change from frame to frame (dynamic
    /// resolution into a sub-rect): the learned rect is last frame's, so the pass is left alone.
    RectChanging,
    /// One target the eyes take turns in (each eye rendered into it, then carried on by its own
    /// post chain): which eye a pass shows is known only from the walk of the submission that
    /// carries it, and that walk did not reach this pass.
    SharedTarget,
}

impl NotMasked {
    pub const ALL: [NotMasked; 14] = [
        NotMasked::NotEyePass,
        NotMasked::EyeUnknown,
        NotMasked::NoDepthAttachment,
        NotMasked::DepthNotCleared,
        NotMasked::DepthClearNot01,
        NotMasked::Secondary,
        NotMasked::NoMask,
        NotMasked::Unsupported,
        NotMasked::IntermediateOff,
        NotMasked::LayerError,
        NotMasked::DeviceLacks,
        NotMasked::PostPass,
        NotMasked::RectChanging,
        NotMasked::SharedTarget,
    ];
    pub fn name(&self) -> &'static str {
        match self {
            NotMasked::NotEyePass => "not_eye_pass",
            NotMasked::EyeUnknown => "eye_unknown",
            NotMasked::NoDepthAttachment => "no_depth_attachment",
            NotMasked::DepthNotCleared => "depth_not_cleared",
            NotMasked::DepthClearNot01 => "depth_clear_not_0_1",
            NotMasked::Secondary => "secondary",
            NotMasked::NoMask => "no_mask",
            NotMasked::Unsupported => "unsupported",
            NotMasked::IntermediateOff => "intermediate_off",
            NotMasked::LayerError => "layer_error",
            NotMasked::DeviceLacks => "device_lacks",
            NotMasked::PostPass => "post_pass",
            NotMasked::RectChanging => "rect_changing",
            NotMasked::SharedTarget => "shared_target",
        }
    }
}
