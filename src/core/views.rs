//! What the OpenXR side learns about views, images and eyes, as plain values: swapchain
//! descriptions, eye uses, view masks and FOVs, fovea views, located poses, depth ranges. Both
//! halves and every feature speak these; nothing here knows a feature or a shell.
#![forbid(unsafe_code)]

/// The part of `XrSwapchainCreateInfo` eye-pass detection needs, immutable after creation.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SwapchainDesc {
    pub usage_flags: u64,
    /// `VkFormat` as the app asked for it.
    pub format: i64,
    pub sample_count: u32,
    pub width: u32,
    pub height: u32,
    pub array_size: u32,
}

/// Rectangle of an image in pixels, as `XrRect2Di`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct ImageRect {
    pub x: i32,
    pub y: i32,
    pub width: i32,
    pub height: i32,
}

/// One use of a swapchain by a projection view, learned from `xrEndFrame`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct EyeUse {
    /// Index of the view in the view configuration (0 = left, 1 = right for stereo).
    pub view: u32,
    pub image_rect: ImageRect,
    pub image_array_index: u32,
    /// True when this swapchain was submitted as the view's depth (`XrCompositionLayerDepthInfoKHR`).
    pub depth: bool,
}

/// Where a hidden-area mask came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MaskSource {
    /// The runtime's `XR_KHR_visibility_mask` hidden triangle mesh.
    Runtime,
    /// Synthesized from the configured lens shape (the runtime has no mask).
    Synthesized,
    /// The published lens of the headset the runtime names, where the runtime's own mask is
    /// Monado's generic one (`u_visibility_mask_get_default`: the four corners cut, whatever the
    /// headset; WiVRn's streamed headsets get it) or missing.
    Headset,
}

/// One view's hidden area in that view's tangent plane (z = −1; x right, y up, i.e. tangents of
/// the angles), as a triangle list. Independent of any image: the Vulkan half maps it into each eye
/// pass with the view's FOV.
#[derive(Clone, Debug, PartialEq)]
pub struct ViewMask {
    pub view: u32,
    pub source: MaskSource,
    /// Three points per triangle.
    pub triangles: Vec<[f32; 2]>,
}

/// A view's field of view as submitted (tangents of `XrFovf`'s angles: left < 0 < right,
/// down < 0 < up), which maps tangent-plane points to the image rect.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ViewFov {
    pub tan_left: f32,
    pub tan_right: f32,
    pub tan_up: f32,
    pub tan_down: f32,
}

/// The masks and FOVs of all views; replaced as a whole, with a generation that increases on every
/// change so the Vulkan half can rebuild what it derived.
///
/// Two FOVs per view, kept apart for features that change what the app sees (a FOV tightened to
/// the lens): `app_fovs` is what the app renders its images with (from its submitted frames, before
/// the first one from the views it was given), and what everything drawn into those images is
/// placed by; `runtime_fovs` is what the runtime reported for the views, and expects back.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Views {
    pub generation: u64,
    pub masks: Vec<ViewMask>,
    pub app_fovs: Vec<ViewFov>,
    pub runtime_fovs: Vec<ViewFov>,
    /// Per view, the runtime view's orientation in the frame of the view the app was given (x y z
    /// w), where a feature turned it (parallel views); None: they look the same way.
    pub runtime_turns: Vec<Option<[f32; 4]>>,
}

/// One view's foveation: where full rate is needed and how fast the rate falls off, in angular
/// terms so a setting means the same on every HMD. Rings are angular distances from the centre
/// direction: within `inner_deg` full rate, up to `middle_deg` half rate, beyond that quarter rate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FoveaView {
    pub view: u32,
    /// The centre direction as a tangent-plane point (x right, y up) of that view: (0, 0) is the
    /// optical axis (fixed foveation), a gaze direction otherwise.
    pub center: [f32; 2],
    pub inner_deg: f32,
    pub middle_deg: f32,
}

/// Foveation of all views, replaced as a whole; `generation` increases on every change so the
/// Vulkan half rebuilds rate maps only when the centre or the rings move.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Foveation {
    pub generation: u64,
    pub views: Vec<FoveaView>,
}

/// One located view as the app renders it: pose in the app's locate space and FOV tangents.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ViewPose {
    /// Orientation quaternion (x, y, z, w).
    pub orientation: [f32; 4],
    pub position: [f32; 3],
    pub fov: ViewFov,
}

/// `XrCompositionLayerDepthInfoKHR`'s projection range: `near_z` is the distance stored as
/// `min_depth`, `far_z` the one stored as `max_depth` (near > far for reversed depth; far may be
/// infinite).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DepthRange {
    pub near_z: f32,
    pub far_z: f32,
    pub min_depth: f32,
    pub max_depth: f32,
}

/// What the monoscopic far field needs from the OpenXR side: the session's frame count (frames
/// begun), the views located for this frame and the previous one, and the app's depth range.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FarFieldViews {
    /// `xrBeginFrame` calls so far (the frame being recorded now).
    pub frame: u64,
    /// (frame, views) located for the current frame.
    pub current: Option<(u64, Vec<ViewPose>)>,
    /// (frame, views) of the latest earlier frame that located views.
    pub previous: Option<(u64, Vec<ViewPose>)>,
    /// From the app's last `xrEndFrame` with depth info on its projection views.
    pub depth: Option<DepthRange>,
}

/// What the upscale did in a frame: passes (one per view rect), pixels rendered by the app and
/// pixels the runtime got.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct UpscaleFrame {
    pub passes: u64,
    pub rendered_px: u64,
    pub display_px: u64,
    /// The GPU time of the last upscale read back (an earlier frame's), ms: its own commands,
    /// from the moment the app's work before it completed.
    pub gpu_ms: Option<f64>,
    /// Its phases: barriers in, EASU, the fragment pass, barriers out (ms).
    pub phases_ms: Vec<f64>,
}

/// `XR_KHR_visibility_mask`: the runtime's hidden-area meshes, which the layer reads for itself
/// and offers to the app when the runtime lacks them.
pub const VISIBILITY_MASK_EXT: &str = "XR_KHR_visibility_mask";
