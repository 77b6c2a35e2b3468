//! Instance-level entry points: creating the layer's instance state (configuration, logging, the
//! next layer's dispatch), tearing it down, and the instance calls whose results later features use.

use super::session::sessions;
use super::{state, Instance, Next};
use crate::plugin::xr::Stats;
use crate::core::guard::{self, PassThrough};
use openxr_sys as xr;
use openxr_sys::Handle as _;
use std::ffi::{c_char, CStr, CString};
use std::sync::Arc;

/// Instance extensions the features use for themselves, if the runtime has them.
fn wanted_extensions(config: &crate::core::config::Config) -> Vec<&'static str> {
    let settings = crate::plugin::settings::Settings::from_config(config);
    let mut v: Vec<&'static str> = Vec::new();
    for f in crate::registry::XR_FEATURES {
        let wanted = f.wanted_extensions(&settings);
        tracing::debug!(feature = f.id(), ?wanted, "instance extensions a feature uses");
        for e in wanted {
            if !v.contains(&e) {
                v.push(e);
            }
        }
    }
    v
}

/// The instance extensions below us, when the next layer answers the global query (None: unknown,
/// then creation is tried with ours and retried without them).
///
/// # Safety
/// `gipa` must be the next layer's `xrGetInstanceProcAddr`.
unsafe fn runtime_extensions(gipa: xr::pfn::GetInstanceProcAddr) -> Option<Vec<String>> {
    let mut f: Option<xr::pfn::VoidFunction> = None;
    // SAFETY: querying a global function with a null instance (spec-allowed for this one).
    let r = unsafe { gipa(xr::Instance::NULL, c"xrEnumerateInstanceExtensionProperties".as_ptr(), &mut f) };
    let f = f.filter(|_| r == xr::Result::SUCCESS)?;
    // SAFETY: the function returned for this name has this type.
    let enumerate: xr::pfn::EnumerateInstanceExtensionProperties = unsafe { std::mem::transmute(f) };
    let mut count = 0u32;
    // SAFETY: two-call idiom.
    if unsafe { enumerate(std::ptr::null(), 0, &mut count, std::ptr::null_mut()) } != xr::Result::SUCCESS {
        return None;
    }
    let blank = xr::ExtensionProperties {
        ty: xr::ExtensionProperties::TYPE,
        next: std::ptr::null_mut(),
        extension_name: [0; xr::MAX_EXTENSION_NAME_SIZE],
        extension_version: 0,
    };
    let mut props = vec![blank; count as usize];
    // SAFETY: `props` holds `count` initialised structs.
    if unsafe { enumerate(std::ptr::null(), count, &mut count, props.as_mut_ptr()) } != xr::Result::SUCCESS {
        return None;
    }
    Some(props.iter().take(count as usize).map(|p| super::fixed_str(&p.extension_name)).collect())
}

/// Reads an array of C strings.
///
/// # Safety
/// `names` must point to `count` valid NUL-terminated strings (or be null with count 0).
unsafe fn c_strings(names: *const *const c_char, count: u32) -> Vec<String> {
    if names.is_null() {
        return Vec::new();
    }
    // SAFETY: caller's contract.
    unsafe { std::slice::from_raw_parts(names, count as usize) }
        .iter()
        .filter(|p| !p.is_null())
        // SAFETY: caller's contract: each is NUL-terminated.
        .map(|&p| unsafe { CStr::from_ptr(p) }.to_string_lossy().into_owned())
        .collect()
}

fn exe_name() -> String {
    std::env::current_exe()
        .ok()
        .and_then(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()))
        .unwrap_or_default()
}

/// `xrCreateApiLayerInstance`: resolve the app's configuration, call down the chain with the next
/// layer's info, and record the instance with the next layer's dispatch.
pub(super) unsafe extern "system" fn create_api_layer_instance(
    info: *const xr::InstanceCreateInfo,
    layer_info: *const xr::ApiLayerCreateInfo,
    instance: *mut xr::Instance,
) -> xr::Result {
    // SAFETY: the loader passes a valid create info chain; null is rejected.
    let Some(layer_info) = (unsafe { layer_info.as_ref() }) else { return xr::Result::ERROR_INITIALIZATION_FAILED };
    // SAFETY: as above; `next_info` is the list of layers below us.
    let Some(next_info) = (unsafe { layer_info.next_info.as_ref() }) else {
        return xr::Result::ERROR_INITIALIZATION_FAILED;
    };
    let (Some(next_gipa), Some(next_create)) =
        (next_info.next_get_instance_proc_addr, next_info.next_create_api_layer_instance)
    else {
        return xr::Result::ERROR_INITIALIZATION_FAILED;
    };
    // The layers below us see the chain advanced past us.
    let mut down_info = *layer_info;
    down_info.next_info = next_info.next;
    let plain = || {
        // SAFETY: forwarding the loader's arguments with the chain advanced, as the loader
        // interface requires.
        unsafe { next_create(info, &down_info, instance) }
    };
    // No instance exists yet whose pass-through could be engaged; a failure here only costs
    // this call's layer logic.
    let creating = PassThrough::default();
    guard::run("xrCreateApiLayerInstance", &creating, |down| {
        // SAFETY: `info` is the app's create info, valid for this call.
        let app_name = unsafe { info.as_ref() }.map(|i| super::fixed_str(&i.application_info.application_name)).unwrap_or_default();
        let exe = exe_name();
        let (config, diagnostics) = crate::core::config::load(crate::registry::keys(), &[app_name.as_str(), exe.as_str()]);
        crate::core::log::init(config.choice("log.level"));
        for d in &diagnostics {
            tracing::warn!("config: {d}");
        }
        let _span = tracing::info_span!("xrCreateApiLayerInstance", app = %app_name).entered();
        // SAFETY: the app's create info and its extension names are valid for this call.
        let app_extensions = unsafe { info.as_ref().map(|i| c_strings(i.enabled_extension_names, i.enabled_extension_count)) }
            .unwrap_or_default();
        // Extensions the layer needs for itself; the app never sees them (hidden in
        // xrGetInstanceProcAddr and xrPollEvent).
        // SAFETY: `next_gipa` is the next layer's; global functions are queried with a null instance.
        let available = unsafe { runtime_extensions(next_gipa) };
        let wanted: Vec<&str> = wanted_extensions(&config)
            .into_iter()
            .filter(|e| !app_extensions.iter().any(|a| a == e))
            .filter(|e| available.as_ref().is_none_or(|list| list.iter().any(|a| a == e)))
            .collect();
        // Extensions the app asked for that the runtime lacks and the layer implements itself:
        // they do not go down (the runtime would refuse the instance).
        // Whatever the config says: the manifest lists the extension for every app, so an app
        // that enables it must get an instance, the layer on or off.
        let offered: Vec<String> = offerable(&app_extensions, available.as_deref());
        let mut added = Vec::new();
        let r = down.call(|| {
            if (wanted.is_empty() && offered.is_empty()) || info.is_null() {
                return plain();
            }
            let names: Vec<CString> = wanted.iter().filter_map(|e| CString::new(*e).ok()).collect();
            // SAFETY: `info` is non-null (checked above) and valid for this call.
            let mut ext_ptrs: Vec<*const c_char> = unsafe {
                let i = &*info;
                if i.enabled_extension_count == 0 || i.enabled_extension_names.is_null() {
                    Vec::new()
                } else {
                    std::slice::from_raw_parts(i.enabled_extension_names, i.enabled_extension_count as usize).to_vec()
                }
            };
            // SAFETY: the app's NUL-terminated names, valid for this call.
            ext_ptrs.retain(|&p| !offered.iter().any(|o| unsafe { std::ffi::CStr::from_ptr(p) }.to_bytes() == o.as_bytes()));
            ext_ptrs.extend(names.iter().map(|n| n.as_ptr()));
            // SAFETY: as above; the copy and the names live until the call returns.
            let mut with = unsafe { *info };
            with.enabled_extension_count = ext_ptrs.len() as u32;
            with.enabled_extension_names = ext_ptrs.as_ptr();
            // SAFETY: forwarding the modified copy with the chain advanced.
            let r = unsafe { next_create(&with, &down_info, instance) };
            if r == xr::Result::ERROR_EXTENSION_NOT_PRESENT && offered.is_empty() {
                // The runtime lacks one of ours: go on exactly as the app asked.
                tracing::info!("runtime lacks {wanted:?}; features needing them fall back");
                return plain();
            }
            if r == xr::Result::SUCCESS {
                added = wanted.iter().map(|e| e.to_string()).collect();
            }
            r
        });
        if r != xr::Result::SUCCESS {
            tracing::info!(?r, "instance creation failed below the layer");
            return Ok(r);
        }
        // SAFETY: the call down succeeded, so `*instance` holds the new handle.
        let handle = unsafe { *instance };
        // SAFETY: `next_gipa` belongs to the layer that created `handle`.
        let next = unsafe { Next::load(next_gipa, handle) };
        let config = Arc::new(config);
        let app_name_for_watch = app_name.clone();
        super::publish_config(config.clone());
        tracing::info!(
            enabled = config.enabled(),
            exe,
            "instance {:#x} for app {app_name:?}{}",
            handle.into_raw(),
            if config.enabled() { "" } else { ": layer disabled by config, pure pass-through" }
        );
        for (key, value, source) in config.entries() {
            tracing::debug!("config {key} = {value} ({source})");
        }
        if !added.is_empty() {
            tracing::info!("enabled {added:?} for the layer's own use (hidden from the app)");
        }
        if !offered.is_empty() {
            tracing::info!("the runtime lacks {offered:?}, which the app enabled: the layer implements them (the lens it knows)");
        }
        let inst = Instance {
            handle,
            next,
            config,
            pass_through: PassThrough::default(),
            app_name,
            stats: Stats::default(),
            app_extensions,
            layer_extensions: added,
            offered_extensions: offered,
            watch: live_watch(crate::core::config::Watch::new(crate::registry::keys(), &[app_name_for_watch.as_str(), exe.as_str()], std::time::Duration::from_millis(100))),
            told_sizes: Default::default(),
            features: crate::registry::xr_instance_states(),
        };
        state().instances.insert(handle.into_raw(), Arc::new(inst));
        Ok(r)
    }, plain)
}

pub(super) unsafe extern "system" fn destroy_instance(instance: xr::Instance) -> xr::Result {
    let Some(inst) = state().instances.get(instance.into_raw()) else {
        return match super::sole_instance().and_then(|i| i.next.destroy_instance) {
            // SAFETY: forwarding an unknown handle so the runtime reports it.
            Some(f) => unsafe { f(instance) },
            None => xr::Result::ERROR_HANDLE_INVALID,
        };
    };
    let Some(next) = inst.next.destroy_instance else { return xr::Result::ERROR_FUNCTION_UNSUPPORTED };
    // SAFETY: forwarding the app's valid handle.
    let plain = || unsafe { next(instance) };
    guard::run("xrDestroyInstance", &inst.pass_through, |down| {
        let _span = tracing::debug_span!("xrDestroyInstance").entered();
        // Sessions the app did not destroy take the overlay's objects with them: its Vulkan
        // objects are the layer's to destroy, while the session's device is still alive.
        for s in inst.sessions() {
            super::overlay::destroy(&s);
        }
        let r = down.call(plain);
        if r == xr::Result::SUCCESS {
            // Children die with their instance (spec): drop their state too.
            let st = state();
            // Swapchains still alive here (the app destroyed the instance directly, or its
            // xrDestroySwapchain / xrDestroySession failed) must leave the Vulkan half's image
            // table as well: the driver may hand their VkImage handles out again, and a new image
            // must not be taken for a swapchain image of a dead instance (issue 11).
            let orphans: Vec<u64> = st.swapchains.values().into_iter().filter(|(_, s)| s.session.instance.handle == instance).map(|(h, _)| h).collect();
            if !orphans.is_empty() {
                tracing::info!("{} swapchain(s) not destroyed by the app go with the instance", orphans.len());
            }
            for handle in orphans {
                crate::bridge::shared().remove_swapchain(handle);
            }
            st.swapchains.retain(|_, s| s.session.instance.handle != instance);
            sessions().retain(|_, s| s.instance.handle != instance);
            st.instances.remove(instance.into_raw());
            tracing::info!("openxr stats: {} (app {:?})", inst.stats.line(), inst.app_name);
            // What the layer still keys by handle after the instance went with its children: 0
            // of each once the app's last instance is gone (tests/hardening/lifecycle.rs, every teardown order).
            tracing::info!(
                "openxr layer tables: instances={} sessions={} swapchains={} shared_swapchains={}",
                st.instances.len(),
                sessions().len(),
                st.swapchains.len(),
                crate::bridge::shared().swapchains.len()
            );
        }
        Ok(r)
    }, plain)
}

pub(super) unsafe extern "system" fn enumerate_view_configuration_views(
    instance: xr::Instance,
    system_id: xr::SystemId,
    view_configuration_type: xr::ViewConfigurationType,
    view_capacity_input: u32,
    view_count_output: *mut u32,
    views: *mut xr::ViewConfigurationView,
) -> xr::Result {
    let Some(inst) = super::instance_for(instance) else {
        return xr::Result::ERROR_HANDLE_INVALID;
    };
    let Some(next) = inst.next.enumerate_view_configuration_views else { return xr::Result::ERROR_FUNCTION_UNSUPPORTED };
    // SAFETY: forwarding the app's arguments unchanged.
    let plain = || unsafe { next(instance, system_id, view_configuration_type, view_capacity_input, view_count_output, views) };
    guard::run("xrEnumerateViewConfigurationViews", &inst.pass_through, |down| {
        inst.check_fault("xrEnumerateViewConfigurationViews")?;
        let r = down.call(plain);
        if r == xr::Result::SUCCESS && view_capacity_input > 0 && !views.is_null() && !view_count_output.is_null() {
            // SAFETY: on success the runtime wrote `*view_count_output` (≤ capacity) entries into
            // the app's array, which is the app's to change until the call returns.
            let written = unsafe { std::slice::from_raw_parts_mut(views, (*view_count_output).min(view_capacity_input) as usize) };
            let settings = super::settings(&inst);
            // The features' changes (the FOV cut) first; the upscale scales what they tell.
            for f in crate::registry::XR_FEATURES {
                f.views_enumerated(&inst, system_id, view_configuration_type, &settings, written);
            }
            super::upscale::views_enumerated(&inst, &settings, written);
            for (i, v) in written.iter().enumerate() {
                tracing::info!(
                    "view {i} of {view_configuration_type:?}: recommended {}x{}, max {}x{}",
                    v.recommended_image_rect_width,
                    v.recommended_image_rect_height,
                    v.max_image_rect_width,
                    v.max_image_rect_height
                );
            }
        }
        Ok(r)
    }, plain)
}

pub(super) unsafe extern "system" fn poll_event(instance: xr::Instance, event_data: *mut xr::EventDataBuffer) -> xr::Result {
    let Some(inst) = super::instance_for(instance) else {
        return xr::Result::ERROR_HANDLE_INVALID;
    };
    let Some(next) = inst.next.poll_event else { return xr::Result::ERROR_FUNCTION_UNSUPPORTED };
    // SAFETY: forwarding the app's arguments unchanged.
    let plain = || unsafe { next(instance, event_data) };
    guard::run("xrPollEvent", &inst.pass_through, |down| {
        inst.check_fault("xrPollEvent")?;
        loop {
            let r = down.call(plain);
            if r != xr::Result::SUCCESS || event_data.is_null() {
                return Ok(r);
            }
            // SAFETY: on success the runtime filled the event buffer.
            let event = unsafe { &*event_data };
            let ty = event.ty;
            // Every feature sees every event; one that is the layer's own is hidden from the app:
            // poll again with the buffer restored to what the app passed in.
            // Not `any`: every feature must see the event, whoever owns it.
            let ours = crate::registry::XR_FEATURES.iter().map(|f| f.event(&inst, event)).fold(false, |a, b| a | b);
            if ours {
                // SAFETY: the app's event buffer, valid for this call.
                unsafe {
                    (*event_data).ty = xr::StructureType::EVENT_DATA_BUFFER;
                    (*event_data).next = std::ptr::null();
                }
                continue;
            }
            if ty == xr::StructureType::EVENT_DATA_SESSION_STATE_CHANGED {
                // SAFETY: as above.
                let e = unsafe { &*(event_data as *const xr::EventDataSessionStateChanged) };
                tracing::debug!("session {:#x} state {:?}", e.session.into_raw(), e.state);
            }
            return Ok(r);
        }
    }, plain)
}

/// The app's extensions the layer implements itself because the runtime lacks them (only when
/// the runtime's list is known): `XR_KHR_visibility_mask`.
fn offerable(app: &[String], runtime: Option<&[String]>) -> Vec<String> {
    let Some(runtime) = runtime else { return Vec::new() };
    [super::VISIBILITY_MASK_EXT]
        .into_iter()
        .filter(|e| app.iter().any(|a| a == e) && !runtime.iter().any(|r| r == e))
        .map(str::to_string)
        .collect()
}

/// The config watch, also applying `stereoshim top`'s live settings when there is a private
/// runtime folder for them (`core::live`).
fn live_watch(watch: crate::core::config::Watch) -> crate::core::config::Watch {
    let env = |k: &str| std::env::var(k).ok();
    match crate::manifests::private_fs::private_base(&env) {
        Some(base) => watch.with_live(crate::core::live::folder(&base), std::process::id()),
        None => watch,
    }
}

#[cfg(test)]
mod offer_tests {
    use super::*;

    #[test]
    fn the_mask_extension_is_offered_only_where_the_runtime_lacks_it() {
        let app = vec!["XR_KHR_vulkan_enable2".to_string(), "XR_KHR_visibility_mask".to_string()];
        let without = vec!["XR_KHR_vulkan_enable2".to_string()];
        let with = app.clone();
        assert_eq!(offerable(&app, Some(&without)), vec!["XR_KHR_visibility_mask".to_string()]);
        assert!(offerable(&app, Some(&with)).is_empty(), "the runtime's own");
        assert!(offerable(&app, None).is_empty(), "unknown runtime list: nothing is taken away");
        assert!(offerable(&without, Some(&without)).is_empty(), "not asked for");
    }
}

