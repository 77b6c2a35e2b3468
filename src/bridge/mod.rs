//! State the two halves share. Both live in the same `libstereoshim.so`, loaded once per process,
//! so plain statics are shared: the OpenXR half knows which `VkImage`s are swapchain images and,
//! from `xrEndFrame`, which eye each one shows; the Vulkan half needs exactly that to find eye
//! passes. Only the OpenXR half writes here.

pub mod eye_uses;
pub mod swapchain_images;

use crate::core::handles::HandleMap;
use crate::core::views::{EyeUse, FarFieldViews, FoveaView, Foveation, SwapchainDesc, UpscaleFrame, ViewFov, ViewMask, Views};
use std::sync::{Arc, OnceLock, RwLock};

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

#[derive(Debug, Clone)]
pub struct SwapchainImage {
    pub swapchain: Arc<Swapchain>,
    pub index: u32,
}

#[derive(Debug, Default)]
pub struct Shared {
    /// The configuration the OpenXR half resolved for the app (it knows the app's name first); the
    /// Vulkan half uses it for devices created after it, else resolves its own.
    pub config: RwLock<Option<Arc<crate::core::config::Config>>>,
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
    pub fn config(&self) -> Option<Arc<crate::core::config::Config>> {
        self.config.read().unwrap_or_else(|e| e.into_inner()).clone()
    }
    /// Makes `config` the live configuration (the OpenXR half publishes its typed settings
    /// beside it: `crate::plugin::settings::publish`).
    pub fn set_config(&self, config: Arc<crate::core::config::Config>) {
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
    use crate::core::views::{ImageRect, MaskSource};

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
