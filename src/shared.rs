//! State the two halves share. Both live in the same `libstereoshim.so`, loaded once per process,
//! so plain statics are shared: the OpenXR half knows which `VkImage`s are swapchain images and,
//! from `xrEndFrame`, which eye each one shows; the Vulkan half needs exactly that to find eye
//! passes. Only the OpenXR half writes here.

use crate::registry::HandleMap;
use std::sync::{Arc, OnceLock, RwLock};

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

#[derive(Debug)]
pub struct Swapchain {
    /// The `XrSwapchain` handle value.
    pub handle: u64,
    pub desc: SwapchainDesc,
    /// `VkImage` handle values in `xrEnumerateSwapchainImages` order.
    pub images: Vec<u64>,
    /// How the app submitted the swapchain in the latest frame that used it.
    uses: RwLock<Vec<EyeUse>>,
    /// The upscale interposes it: `images` are the layer's, the runtime's are at the display size.
    pub upscaled: bool,
}

impl Swapchain {
    pub fn new(handle: u64, desc: SwapchainDesc, images: Vec<u64>) -> Swapchain {
        Swapchain { handle, desc, images, uses: RwLock::new(Vec::new()), upscaled: false }
    }
    /// The same, marked as interposed by the upscale.
    pub fn upscaled(mut self) -> Swapchain {
        self.upscaled = true;
        self
    }
    pub fn uses(&self) -> Vec<EyeUse> {
        self.uses.read().unwrap_or_else(|e| e.into_inner()).clone()
    }
    /// Replaces the uses when they changed; returns whether they did (worth a log line).
    pub fn set_uses(&self, uses: Vec<EyeUse>) -> bool {
        let mut cur = self.uses.write().unwrap_or_else(|e| e.into_inner());
        if *cur == uses {
            return false;
        }
        *cur = uses;
        true
    }
}

/// Where a hidden-area mask came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MaskSource {
    /// The runtime's `XR_KHR_visibility_mask` hidden triangle mesh.
    Runtime,
    /// Synthesized from the configured lens shape (the runtime has no mask).
    Synthesized,
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

/// A swapchain image as the Vulkan half sees it.
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

#[derive(Debug, Clone)]
pub struct SwapchainImage {
    pub swapchain: Arc<Swapchain>,
    pub index: u32,
}

#[derive(Debug, Default)]
pub struct Shared {
    /// The configuration the OpenXR half resolved for the app (it knows the app's name first); the
    /// Vulkan half uses it for devices created after it, else resolves its own.
    pub config: RwLock<Option<Arc<crate::config::Config>>>,
    /// Hidden-area masks and FOVs per view (written by the OpenXR half).
    pub views: RwLock<Arc<Views>>,
    /// Foveation centre and rings per view (written by the OpenXR half; empty when off).
    pub foveation: RwLock<Arc<Foveation>>,
    /// Views and depth range for the far field.
    pub far_field: RwLock<Arc<FarFieldViews>>,
    /// `XrSwapchain` → swapchain.
    pub swapchains: HandleMap<u64, Swapchain>,
    /// `VkImage` → the swapchain image it is.
    pub images: HandleMap<u64, SwapchainImage>,
    /// The upscale's work since the last frame end (`take_upscale`).
    pub upscale: std::sync::Mutex<Option<UpscaleFrame>>,
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

impl Shared {
    /// Counts an upscale submission.
    pub fn upscale_counts(&self, passes: u64, rendered_px: u64, display_px: u64, gpu_ms: Option<f64>, phases_ms: &[f64]) {
        let mut u = self.upscale.lock().unwrap_or_else(|e| e.into_inner());
        let f = u.get_or_insert_with(UpscaleFrame::default);
        f.gpu_ms = gpu_ms.or(f.gpu_ms);
        if !phases_ms.is_empty() {
            f.phases_ms = phases_ms.to_vec();
        }
        f.passes += passes;
        f.rendered_px += rendered_px;
        f.display_px += display_px;
    }
    /// The upscale's counts since the last call.
    pub fn take_upscale(&self) -> Option<UpscaleFrame> {
        self.upscale.lock().unwrap_or_else(|e| e.into_inner()).take()
    }
    pub fn config(&self) -> Option<Arc<crate::config::Config>> {
        self.config.read().unwrap_or_else(|e| e.into_inner()).clone()
    }
    /// Makes `config` the live configuration, and its typed settings the live settings
    /// (`crate::settings::current`).
    pub fn set_config(&self, config: Arc<crate::config::Config>) {
        crate::settings::publish(crate::settings::Settings::from_config(&config));
        *self.config.write().unwrap_or_else(|e| e.into_inner()) = Some(config);
    }
    pub fn views(&self) -> Arc<Views> {
        self.views.read().unwrap_or_else(|e| e.into_inner()).clone()
    }
    /// Replaces masks and/or FOVs; bumps the generation only when something changed.
    pub fn update_views(&self, masks: Option<Vec<ViewMask>>, app_fovs: Option<Vec<ViewFov>>) -> bool {
        self.update(|next| {
            if let Some(m) = masks {
                next.masks = m;
            }
            if let Some(f) = app_fovs {
                next.app_fovs = f;
            }
        })
    }
    /// Replaces the FOVs the runtime reported and how its views are turned from the app's;
    /// bumps the generation only when they changed.
    pub fn update_runtime_fovs(&self, fovs: Vec<ViewFov>, turns: Vec<Option<[f32; 4]>>) -> bool {
        self.update(|next| {
            next.runtime_fovs = fovs;
            next.runtime_turns = turns;
        })
    }
    fn update(&self, change: impl FnOnce(&mut Views)) -> bool {
        let mut cur = self.views.write().unwrap_or_else(|e| e.into_inner());
        let mut next = (**cur).clone();
        change(&mut next);
        if next == **cur {
            return false;
        }
        next.generation = cur.generation + 1;
        *cur = Arc::new(next);
        true
    }
    pub fn far_field(&self) -> Arc<FarFieldViews> {
        self.far_field.read().unwrap_or_else(|e| e.into_inner()).clone()
    }
    /// Changes the far field's views (copy on write: readers keep the snapshot they took).
    pub fn update_far_field(&self, change: impl FnOnce(&mut FarFieldViews)) {
        let mut cur = self.far_field.write().unwrap_or_else(|e| e.into_inner());
        let mut next = (**cur).clone();
        change(&mut next);
        if next != **cur {
            *cur = Arc::new(next);
        }
    }
    pub fn foveation(&self) -> Arc<Foveation> {
        self.foveation.read().unwrap_or_else(|e| e.into_inner()).clone()
    }
    /// Replaces the per-view foveation; bumps the generation only when something changed.
    pub fn update_foveation(&self, views: Vec<FoveaView>) -> bool {
        let mut cur = self.foveation.write().unwrap_or_else(|e| e.into_inner());
        if cur.views == views {
            return false;
        }
        *cur = Arc::new(Foveation { generation: cur.generation + 1, views });
        true
    }
    pub fn add_swapchain(&self, swapchain: Arc<Swapchain>) {
        for (index, &image) in swapchain.images.iter().enumerate() {
            self.images.insert(image, Arc::new(SwapchainImage { swapchain: swapchain.clone(), index: index as u32 }));
        }
        self.swapchains.insert(swapchain.handle, swapchain);
    }
    pub fn remove_swapchain(&self, handle: u64) {
        if let Some(sc) = self.swapchains.remove(handle) {
            for image in &sc.images {
                self.images.remove(*image);
            }
        }
    }
}

pub fn shared() -> &'static Shared {
    static SHARED: OnceLock<Shared> = OnceLock::new();
    SHARED.get_or_init(Shared::default)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn views_generation_moves_only_on_change() {
        let s = Shared::default();
        let fov = ViewFov { tan_left: -1.0, tan_right: 1.0, tan_up: 1.0, tan_down: -1.0 };
        assert!(s.update_views(None, Some(vec![fov, fov])));
        assert_eq!(s.views().generation, 1);
        assert!(!s.update_views(None, Some(vec![fov, fov])));
        let mask = ViewMask { view: 0, source: MaskSource::Runtime, triangles: vec![[0.0, 0.0]; 3] };
        assert!(s.update_views(Some(vec![mask]), None));
        assert_eq!(s.views().generation, 2);
        assert_eq!(s.views().app_fovs.len(), 2);
        assert!(s.update_runtime_fovs(vec![fov], vec![None]));
        assert!(!s.update_runtime_fovs(vec![fov], vec![None]));
        assert_eq!((s.views().generation, s.views().runtime_fovs.len()), (3, 1));
    }

    #[test]
    fn swapchain_images_are_found_and_forgotten() {
        let s = Shared::default();
        let desc = SwapchainDesc { usage_flags: 1, format: 43, sample_count: 1, width: 8, height: 8, array_size: 2 };
        s.add_swapchain(Arc::new(Swapchain::new(5, desc, vec![100, 101])));
        let img = s.images.get(101).unwrap();
        assert_eq!((img.index, img.swapchain.handle), (1, 5));
        let rect = ImageRect { x: 0, y: 0, width: 8, height: 8 };
        let uses = vec![
            EyeUse { view: 0, image_rect: rect, image_array_index: 0, depth: false },
            EyeUse { view: 1, image_rect: rect, image_array_index: 1, depth: false },
        ];
        assert!(img.swapchain.set_uses(uses.clone()));
        assert!(!img.swapchain.set_uses(uses.clone()));
        assert_eq!(s.images.get(100).unwrap().swapchain.uses(), uses);
        s.remove_swapchain(5);
        assert!(s.images.get(100).is_none() && s.swapchains.get(5).is_none());
    }
}
