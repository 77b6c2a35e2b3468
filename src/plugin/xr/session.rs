//! A session as features see it: its instance, its Vulkan binding, its last located views, each
//! feature's per-session state by type (made by the registry), and what may be asked of the
//! runtime for it (the visibility-mask meshes). The live sessions are kept here, in one map the
//! shell fills and empties, so a feature can reach a session by handle without the shell.

use super::instance::Instance;
use super::VISIBILITY_MASK_EXT;
use crate::core::handles::HandleMap;
use crate::core::parts::States;
use crate::core::views::ViewFov;
use openxr_sys as xr;
use openxr_sys::Handle as _;
use std::any::Any;
use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex, OnceLock};

/// The Vulkan objects of `XrGraphicsBindingVulkanKHR`, as handle values.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct VulkanBinding {
    pub instance: u64,
    pub physical_device: u64,
    pub device: u64,
    /// `device`'s dispatch key, read once here: every later lookup of the device's state uses
    /// it, never the app's handle again.
    pub device_key: crate::plugin::vk::DeviceKey,
    pub queue_family_index: u32,
    pub queue_index: u32,
}

/// A view as last located by the app.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct LocatedView {
    pub pose: xr::Posef,
    pub fov: xr::Fovf,
}

pub(crate) struct Session {
    pub handle: xr::Session,
    pub instance: Arc<Instance>,
    pub binding: Option<VulkanBinding>,
    pub views: Mutex<Vec<LocatedView>>,
    /// FOVs come from submitted frames once there are any (what the app really rendered with),
    /// before that from located views.
    pub fov_submitted: AtomicBool,
    /// Every feature's per-session state, one value per type (made by the registry).
    pub features: States,
    /// Whether the Vulkan half tracks the session's device (it can act on nothing otherwise).
    pub vulkan_half: bool,
    /// What the enabled features did over the session (`notices`): warnings once per reason, and a
    /// summary when the session ends.
    pub summary: Mutex<crate::report::notices::Summary>,
    /// The system the session was created for (the overlay asks for its `maxLayerCount`).
    pub system_id: xr::SystemId,
}

/// The live sessions by handle (the shell inserts at `xrCreateSession`, removes when they end).
pub(crate) fn sessions() -> &'static HandleMap<u64, Session> {
    static SESSIONS: OnceLock<HandleMap<u64, Session>> = OnceLock::new();
    SESSIONS.get_or_init(HandleMap::default)
}

pub(crate) fn fov_tangents(fov: &xr::Fovf) -> ViewFov {
    ViewFov {
        tan_left: fov.angle_left.tan(),
        tan_right: fov.angle_right.tan(),
        tan_up: fov.angle_up.tan(),
        tan_down: fov.angle_down.tan(),
    }
}

impl Session {
    /// The live session of `handle`.
    pub(crate) fn find(handle: xr::Session) -> Option<Arc<Session>> {
        sessions().get(handle.into_raw())
    }

    /// A feature's own per-session state. The registry makes every registered feature's, so a
    /// missing one is a registry error (its unit test checks every feature).
    pub(crate) fn feature<T: Any>(&self) -> &T {
        self.features.get::<T>().unwrap_or_else(|| panic!("no {} in the session: the feature is not registered", std::any::type_name::<T>()))
    }

    /// Fetches one view's hidden triangle mesh from the runtime (two-call idiom). None when the
    /// runtime offers no visibility mask or the call fails (logged).
    pub(crate) fn runtime_mask(&self, view: u32) -> Option<Vec<[f32; 2]>> {
        self.runtime_mesh(view, xr::VisibilityMaskTypeKHR::HIDDEN_TRIANGLE_MESH)
    }

    /// One view's triangle mesh of type `ty` (hidden or visible), three points per triangle.
    pub(crate) fn runtime_mesh(&self, view: u32, ty: xr::VisibilityMaskTypeKHR) -> Option<Vec<[f32; 2]>> {
        if !self.instance.has_extension(VISIBILITY_MASK_EXT) {
            return None;
        }
        let f = self.instance.next.get_visibility_mask?;
        let config = xr::ViewConfigurationType::PRIMARY_STEREO;
        let mut mask = super::empty_visibility_mask();
        // SAFETY: the two-call idiom: counts first, then arrays of the reported sizes.
        let r = unsafe { f(self.handle, config, view, ty, &mut mask) };
        if r != xr::Result::SUCCESS {
            tracing::warn!(?r, "xrGetVisibilityMaskKHR(view {view}) failed");
            return None;
        }
        let mut vertices = vec![xr::Vector2f { x: 0.0, y: 0.0 }; mask.vertex_count_output as usize];
        let mut indices = vec![0u32; mask.index_count_output as usize];
        mask.vertex_capacity_input = vertices.len() as u32;
        mask.index_capacity_input = indices.len() as u32;
        mask.vertices = vertices.as_mut_ptr();
        mask.indices = indices.as_mut_ptr();
        // SAFETY: the arrays hold the capacities given.
        let r = unsafe { f(self.handle, config, view, ty, &mut mask) };
        if r != xr::Result::SUCCESS {
            tracing::warn!(?r, "xrGetVisibilityMaskKHR(view {view}) failed");
            return None;
        }
        vertices.truncate(mask.vertex_count_output as usize);
        indices.truncate(mask.index_count_output as usize);
        let v: Vec<[f32; 2]> = vertices.iter().map(|p| [p.x, p.y]).collect();
        Some(crate::core::lens::expand(&v, &indices))
    }
}
