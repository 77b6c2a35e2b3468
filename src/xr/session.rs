//! Session-level entry points: which Vulkan device a session renders with and where its views
//! are; the features' per-session state (the registry's `xr_session_states`) is made here and
//! their `views_located` event raised.

use crate::features::mask::MaskSettings;
use crate::features::foveation::FoveationSettings;
use super::Instance;
use crate::core::guard;
use crate::core::views::{ViewFov, VISIBILITY_MASK_EXT};
use std::sync::atomic::{AtomicBool, Ordering};
use openxr_sys as xr;
use openxr_sys::Handle as _;
use std::sync::{Arc, Mutex};

// What features see of a session is the contract's; the shell makes it and keeps it in the
// contract's map of live sessions.
pub(crate) use crate::plugin::xr::{fov_tangents, sessions, LocatedView, Session, VulkanBinding};

/// The runtime view's orientation `runtime` in the frame of the view the app was given (`given`),
/// rounded so that tracking's float noise does not count as a change; None when they look the
/// same way (no feature turned the view).
fn runtime_turn(runtime: &xr::Quaternionf, given: &xr::Quaternionf) -> Option<[f32; 4]> {
    let q = |o: &xr::Quaternionf| glam::DQuat::from_xyzw(o.x as f64, o.y as f64, o.z as f64, o.w as f64).normalize();
    let rel = q(given).inverse() * q(runtime);
    let rel = if rel.w < 0.0 { -rel } else { rel };
    let round = |v: f64| ((v * 1e5).round() / 1e5) as f32;
    let t = [round(rel.x), round(rel.y), round(rel.z), round(rel.w)];
    (rel.is_finite() && t != [0.0, 0.0, 0.0, 1.0]).then_some(t)
}

/// Finds the session's state, or the instance to forward an unknown handle through.
pub(super) fn lookup(session: xr::Session) -> Result<Arc<Session>, Option<Arc<Instance>>> {
    sessions().get(session.into_raw()).ok_or_else(super::sole_instance)
}

/// Finds `XrGraphicsBindingVulkanKHR` in a session create info's chain.
///
/// # Safety
/// `next` must be a valid OpenXR structure chain, and the runtime must have accepted it (the
/// session was created): its `VkDevice` is then live and its dispatch key is read.
unsafe fn vulkan_binding(mut next: *const xr::BaseInStructure) -> Option<VulkanBinding> {
    // SAFETY: walking a valid chain (caller's contract); each `ty` tells the struct's layout.
    unsafe {
        while let Some(s) = next.as_ref() {
            if s.ty == xr::StructureType::GRAPHICS_BINDING_VULKAN_KHR {
                let b = &*(next as *const xr::GraphicsBindingVulkanKHR);
                return Some(VulkanBinding {
                    instance: b.instance as u64,
                    physical_device: b.physical_device as u64,
                    device: b.device as u64,
                    device_key: crate::plugin::vk::DeviceKey::of_live(b.device as u64),
                    queue_family_index: b.queue_family_index,
                    queue_index: b.queue_index,
                });
            }
            next = s.next;
        }
    }
    None
}

pub(super) unsafe extern "system" fn create_session(
    instance: xr::Instance,
    create_info: *const xr::SessionCreateInfo,
    session: *mut xr::Session,
) -> xr::Result {
    let Some(inst) = super::instance_for(instance) else {
        return xr::Result::ERROR_HANDLE_INVALID;
    };
    let Some(next) = inst.next.create_session else { return xr::Result::ERROR_FUNCTION_UNSUPPORTED };
    // SAFETY: forwarding the app's arguments unchanged.
    let plain = || unsafe { next(instance, create_info, session) };
    guard::run("xrCreateSession", &inst.pass_through, |down| {
        inst.check_fault("xrCreateSession")?;
        let _span = tracing::debug_span!("xrCreateSession").entered();
        let r = down.call(plain);
        if r != xr::Result::SUCCESS {
            return Ok(r);
        }
        // SAFETY: the app's create info is valid for this call, and the runtime accepted it (the
        // call succeeded), so the binding's device is live.
        let binding = unsafe { create_info.as_ref().and_then(|ci| vulkan_binding(ci.next.cast())) };
        // SAFETY: as above.
        let system_id = unsafe { create_info.as_ref() }.map_or(xr::SystemId::NULL, |ci| ci.system_id);
        // SAFETY: success means the runtime wrote the new handle.
        let handle = unsafe { *session };
        let vulkan_half = binding.as_ref().is_some_and(|b| crate::plugin::vk::device_is_tracked(b.device_key));
        match &binding {
            Some(b) => tracing::info!(
                "session {:#x} renders on VkDevice {:#x} (queue family {}, index {}); the Vulkan half {}",
                handle.into_raw(),
                b.device,
                b.queue_family_index,
                b.queue_index,
                if vulkan_half { "tracks this device" } else { "does NOT see this device" }
            ),
            None => tracing::warn!("session {:#x} has no Vulkan binding: nothing to do for it", handle.into_raw()),
        }
        let settings = super::settings(&inst);
        if binding.is_some() && !vulkan_half && (settings.of::<MaskSettings>().enabled || settings.of::<FoveationSettings>().enabled) {
            tracing::warn!(
                "the hidden-area mask / foveation is enabled, but stereoshim's Vulkan layer is not in the app's Vulkan \
                 device, so nothing will be applied. Likely causes: the app created its VkInstance before asking the \
                 runtime for its Vulkan extensions (XR_KHR_vulkan_enable), or the Vulkan loader did not load \
                 {} (run with VK_LOADER_DEBUG=layer; `stereoshim status` shows what is registered)",
                crate::vk::VK_LAYER_NAME
            );
        }
        let s = Session {
            handle,
            instance: inst.clone(),
            binding,
            views: Mutex::new(Vec::new()),
            fov_submitted: AtomicBool::new(false),
            features: crate::registry::xr_session_states(),
            vulkan_half,
            summary: Default::default(),
            system_id,
        };
        sessions().insert(handle.into_raw(), Arc::new(s));
        Ok(r)
    }, plain)
}

pub(super) unsafe extern "system" fn destroy_session(session: xr::Session) -> xr::Result {
    let (inst, known) = match lookup(session) {
        Ok(s) => (s.instance.clone(), true),
        Err(Some(inst)) => (inst, false),
        Err(None) => return xr::Result::ERROR_HANDLE_INVALID,
    };
    let Some(next) = inst.next.destroy_session else { return xr::Result::ERROR_FUNCTION_UNSUPPORTED };
    // SAFETY: forwarding the app's handle.
    let plain = || unsafe { next(session) };
    guard::run("xrDestroySession", &inst.pass_through, |down| {
        // The overlay's objects are the layer's own children of the session: they go first,
        // while the session (and its device) are alive.
        if let Ok(s) = lookup(session) {
            super::overlay::destroy(&s);
            // Interposed swapchains the app did not destroy: their images go while the device is
            // sure to be alive, then the session's upscale objects.
            for (_, sc) in super::state().swapchains.values() {
                if let (true, Some(i)) = (sc.session.handle == session, sc.upscale.as_ref()) {
                    super::upscale::destroy(&s, i);
                }
            }
            super::upscale::session_destroyed(&s);
        }
        let r = down.call(plain);
        if r == xr::Result::SUCCESS && known {
            let st = super::state();
            if let Some(s) = sessions().get(session.into_raw()) {
                tracing::info!("session {:#x} destroyed (binding {:?})", session.into_raw(), s.binding);
                if let Some(b) = &s.binding {
                    crate::vk::log_device_stats(b.device_key, "xrDestroySession");
                    crate::vk::session_ended(b.device_key);
                }
                for w in s.summary.lock().unwrap_or_else(|e| e.into_inner()).end() {
                    tracing::warn!("{w}");
                }
            }
            let orphans: Vec<u64> = st.swapchains.values().into_iter().filter(|(_, s)| s.session.handle == session).map(|(h, _)| h).collect();
            if !orphans.is_empty() {
                tracing::info!("{} swapchain(s) not destroyed by the app go with the session", orphans.len());
            }
            for handle in orphans {
                crate::bridge::shared().remove_swapchain(handle);
            }
            st.swapchains.retain(|_, s| s.session.handle != session);
            sessions().remove(session.into_raw());
            // The app has waited for its GPU work by now (it may not destroy a session whose
            // images are in use): the last frames' GPU times are in, and every waiting
            // `stats.file` line is written.
            crate::report::stats_file::sink().finish(&crate::vk::completed_gpu_frames());
        }
        Ok(r)
    }, plain)
}

pub(super) unsafe extern "system" fn locate_views(
    session: xr::Session,
    view_locate_info: *const xr::ViewLocateInfo,
    view_state: *mut xr::ViewState,
    view_capacity_input: u32,
    view_count_output: *mut u32,
    views: *mut xr::View,
) -> xr::Result {
    let s = match lookup(session) {
        Ok(s) => s,
        Err(inst) => {
            return match inst.and_then(|i| i.next.locate_views) {
                // SAFETY: forwarding an unknown handle so the runtime reports it.
                Some(f) => unsafe { f(session, view_locate_info, view_state, view_capacity_input, view_count_output, views) },
                None => xr::Result::ERROR_HANDLE_INVALID,
            }
        }
    };
    let Some(next) = s.instance.next.locate_views else { return xr::Result::ERROR_FUNCTION_UNSUPPORTED };
    // SAFETY: forwarding the app's arguments unchanged.
    let plain = || unsafe { next(session, view_locate_info, view_state, view_capacity_input, view_count_output, views) };
    guard::run("xrLocateViews", &s.instance.pass_through, |down| {
        s.instance.check_fault("xrLocateViews")?;
        let r = down.call(plain);
        if r == xr::Result::SUCCESS && view_capacity_input > 0 && !views.is_null() && !view_count_output.is_null() {
            // SAFETY: on success the runtime wrote `*view_count_output` (≤ capacity) views into the
            // app's array, which is the app's to change until the call returns.
            let located = unsafe { std::slice::from_raw_parts_mut(views, (*view_count_output).min(view_capacity_input) as usize) };
            let runtime_fovs: Vec<ViewFov> = located.iter().map(|v| fov_tangents(&v.fov)).collect();
            let runtime_orientations: Vec<xr::Quaternionf> = located.iter().map(|v| v.pose.orientation).collect();
            // SAFETY: the app's locate info, valid for this call (the call succeeded).
            if let Some(info) = unsafe { view_locate_info.as_ref() } {
                for f in crate::registry::XR_FEATURES {
                    f.amend_views(&s, info, located);
                }
            }
            let located: &[xr::View] = located;
            let mut last = s.views.lock().unwrap_or_else(|e| e.into_inner());
            last.clear();
            last.extend(located.iter().map(|v| LocatedView { pose: v.pose, fov: v.fov }));
            let fovs: Vec<ViewFov> = located.iter().map(|v| fov_tangents(&v.fov)).collect();
            // The views as the app got them (the features' changes included): until the app
            // submits a frame, they are also what it renders with.
            if !s.fov_submitted.load(Ordering::Acquire) {
                crate::bridge::shared().update_views(None, Some(fovs));
            }
            let turns = runtime_orientations.iter().zip(located.iter()).map(|(r, v)| runtime_turn(r, &v.pose.orientation)).collect();
            crate::bridge::shared().update_runtime_fovs(runtime_fovs, turns);
            drop(last);
            // SAFETY: the app's locate info, valid for this call (the call succeeded).
            if let Some(info) = unsafe { view_locate_info.as_ref() } {
                for f in crate::registry::XR_FEATURES {
                    f.views_located(&s, info, located);
                }
            }
        }
        Ok(r)
    }, plain)
}

pub(super) unsafe extern "system" fn get_visibility_mask(
    session: xr::Session,
    view_configuration_type: xr::ViewConfigurationType,
    view_index: u32,
    visibility_mask_type: xr::VisibilityMaskTypeKHR,
    visibility_mask: *mut xr::VisibilityMaskKHR,
) -> xr::Result {
    let (inst, sess) = match lookup(session) {
        Ok(s) => (s.instance.clone(), Some(s)),
        Err(Some(inst)) => (inst, None),
        Err(None) => return xr::Result::ERROR_HANDLE_INVALID,
    };
    if inst.offers(VISIBILITY_MASK_EXT) {
        // SAFETY: the app's output struct for this call.
        return unsafe { offered_visibility_mask(&inst, sess.as_deref(), view_configuration_type, view_index, visibility_mask_type, visibility_mask) };
    }
    let Some(next) = inst.next.get_visibility_mask else { return xr::Result::ERROR_FUNCTION_UNSUPPORTED };
    // SAFETY: forwarding the app's arguments unchanged.
    let plain = || unsafe { next(session, view_configuration_type, view_index, visibility_mask_type, visibility_mask) };
    guard::run("xrGetVisibilityMaskKHR", &inst.pass_through, |down| {
        inst.check_fault("xrGetVisibilityMaskKHR")?;
        // A feature that changed the app's views answers with the mesh as they see it.
        let amended = sess.as_ref().filter(|_| view_configuration_type == xr::ViewConfigurationType::PRIMARY_STEREO).and_then(|s| {
            crate::registry::XR_FEATURES.iter().find_map(|f| f.amend_visibility_mask(s, view_index, visibility_mask_type))
        });
        if let Some(points) = amended {
            // SAFETY: the app's output struct for this call, or null (refused below).
            return Ok(unsafe { write_visibility_mask(&points, visibility_mask) });
        }
        let r = down.call(plain);
        // SAFETY: on return the runtime filled the counts of the app's struct.
        if let Some(m) = unsafe { visibility_mask.as_ref() } {
            tracing::debug!(
                ?r,
                "visibility mask view {view_index} {visibility_mask_type:?}: {} vertices, {} indices",
                m.vertex_count_output,
                m.index_count_output
            );
        }
        Ok(r)
    }, plain)
}

/// `xrGetVisibilityMaskKHR` where the runtime lacks the extension and the layer offers it: the
/// lens the layer knows, from the feature that knows it (`XrFeature::offered_visibility_mask`).
///
/// # Safety
/// `mask` is null or the app's output struct, as for `write_visibility_mask`.
unsafe fn offered_visibility_mask(
    inst: &Instance,
    sess: Option<&Session>,
    config: xr::ViewConfigurationType,
    view: u32,
    ty: xr::VisibilityMaskTypeKHR,
    mask: *mut xr::VisibilityMaskKHR,
) -> xr::Result {
    if config != xr::ViewConfigurationType::PRIMARY_STEREO {
        return xr::Result::ERROR_VIEW_CONFIGURATION_TYPE_UNSUPPORTED;
    }
    if view >= 2 {
        return xr::Result::ERROR_VALIDATION_FAILURE;
    }
    let points = crate::core::guard::catch("xrGetVisibilityMaskKHR", None, || crate::registry::XR_FEATURES.iter().find_map(|f| f.offered_visibility_mask(inst, sess, view, ty)));
    match points {
        // SAFETY: per this function's contract.
        Some(points) => unsafe { write_visibility_mask(&points, mask) },
        None => xr::Result::ERROR_RUNTIME_FAILURE,
    }
}

/// Writes `points` (indexed in order) into the app's `XrVisibilityMaskKHR` by the two-call idiom:
/// the counts always, the arrays when both capacities are given and large enough.
///
/// # Safety
/// `mask` is null or the app's output struct, its arrays holding the capacities it gives.
unsafe fn write_visibility_mask(points: &[[f32; 2]], mask: *mut xr::VisibilityMaskKHR) -> xr::Result {
    // SAFETY: the caller's contract: null or the app's struct, valid for this call.
    let Some(m) = (unsafe { mask.as_mut() }) else { return xr::Result::ERROR_VALIDATION_FAILURE };
    let n = points.len() as u32;
    m.vertex_count_output = n;
    m.index_count_output = n;
    if m.vertex_capacity_input == 0 && m.index_capacity_input == 0 {
        return xr::Result::SUCCESS;
    }
    if m.vertex_capacity_input < n || m.index_capacity_input < n {
        return xr::Result::ERROR_SIZE_INSUFFICIENT;
    }
    if (n > 0) && (m.vertices.is_null() || m.indices.is_null()) {
        return xr::Result::ERROR_VALIDATION_FAILURE;
    }
    for (i, p) in points.iter().enumerate() {
        // SAFETY: within the capacities the app gave (checked above), its arrays.
        unsafe {
            *m.vertices.add(i) = xr::Vector2f { x: p[0], y: p[1] };
            *m.indices.add(i) = i as u32;
        }
    }
    xr::Result::SUCCESS
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The amended mask goes to the app by the two-call idiom: counts, too small, filled.
    #[test]
    fn an_amended_mask_follows_the_two_call_idiom() {
        let points = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]];
        let mut m = crate::plugin::xr::empty_visibility_mask();
        // SAFETY: a local struct with no arrays (capacities 0).
        assert_eq!(unsafe { write_visibility_mask(&points, &mut m) }, xr::Result::SUCCESS);
        assert_eq!((m.vertex_count_output, m.index_count_output), (3, 3));
        let (mut v, mut i) = (vec![xr::Vector2f { x: 9.0, y: 9.0 }; 2], vec![9u32; 2]);
        (m.vertex_capacity_input, m.index_capacity_input, m.vertices, m.indices) = (2, 2, v.as_mut_ptr(), i.as_mut_ptr());
        // SAFETY: the arrays hold the capacities given.
        assert_eq!(unsafe { write_visibility_mask(&points, &mut m) }, xr::Result::ERROR_SIZE_INSUFFICIENT);
        assert_eq!(i, [9, 9], "nothing written past a short capacity");
        let (mut v, mut i) = (vec![xr::Vector2f { x: 9.0, y: 9.0 }; 3], vec![9u32; 3]);
        (m.vertex_capacity_input, m.index_capacity_input, m.vertices, m.indices) = (3, 3, v.as_mut_ptr(), i.as_mut_ptr());
        // SAFETY: as above.
        assert_eq!(unsafe { write_visibility_mask(&points, &mut m) }, xr::Result::SUCCESS);
        assert_eq!((v[1].x, v[2].y, i.clone()), (1.0, 1.0, vec![0, 1, 2]));
        // SAFETY: null is refused.
        assert_eq!(unsafe { write_visibility_mask(&points, std::ptr::null_mut()) }, xr::Result::ERROR_VALIDATION_FAILURE);
    }
}
