//! OpenXR API-layer shell: the loader negotiation, `xrCreateApiLayerInstance`, and the hook lookup
//! over the contract's one list of calls (`crate::plugin::xr::xr_calls!`). The unsafe FFI of the
//! OpenXR side lives here, in the contract (`crate::plugin::xr`) and in the features' OpenXR
//! halves that call the runtime; what the hooks decide is in the safe modules of the crate.

mod actions;
mod frame;
pub mod headless;
mod instance;
pub(crate) mod session;
mod swapchain;
pub mod probe;
mod vulkan;

use crate::core::config::Config;
use crate::core::handles::HandleMap;
use openxr_sys as xr;
use openxr_sys::Handle as _;
use std::ffi::{c_char, CStr};
use std::sync::{Arc, OnceLock};

// What features see of an instance, and the dispatch table, are the contract's
// (`crate::plugin::xr`); the shell makes and keeps them. The upscale and the overlay are OpenXR
// features that are no plug-ins: the shell calls them at their places.
use crate::features::overlay::xr as overlay;
use crate::features::upscale::xr as upscale;
pub(crate) use crate::plugin::xr::{settings, Instance, Next, VISIBILITY_MASK_EXT};

/// The hooks, by the field name the call list (`crate::plugin::xr::xr_calls!`) gives each
/// intercepted call: a hook missing here is a compile error in `hook`.
mod hooks {
    pub(super) use super::actions::{attach_session_action_sets, sync_actions};
    pub(super) use super::frame::{begin_frame, end_frame};
    pub(super) use super::instance::{destroy_instance, enumerate_view_configuration_views, poll_event};
    pub(super) use super::session::{create_session, destroy_session, get_visibility_mask, locate_views};
    pub(super) use super::swapchain::{acquire_swapchain_image, create_swapchain, destroy_swapchain, enumerate_swapchain_images, release_swapchain_image, wait_swapchain_image};
    pub(super) use super::vulkan::{create_vulkan_device, create_vulkan_instance, get_vulkan_device_extensions, get_vulkan_instance_extensions};
}

/// The shell's half of the one call list: the hook lookup and the names of the intercepted calls.
macro_rules! hook_lookup {
    (
        hooks { $($name:literal => $field:ident: $pfn:ident,)* }
        calls { $($calls:tt)* }
    ) => {
        /// Our hook for `name`, if we intercept it and the next layer has it.
        fn hook(next: &Next, name: &str) -> Option<xr::pfn::VoidFunction> {
            match name {
                // SAFETY: transmuting between function pointer types; the loader casts the
                // pointer back to the type the spec gives `name`, which is `$pfn`.
                $($name => next.$field.map(|_| unsafe {
                    std::mem::transmute::<xr::pfn::$pfn, xr::pfn::VoidFunction>(hooks::$field as xr::pfn::$pfn)
                }),)*
                _ => None,
            }
        }

        /// Names of all intercepted calls (documentation, `stereoshim status`, tests).
        pub const INTERCEPTED: &[&str] = &[$($name),*];
    };
}

crate::plugin::xr::xr_calls!(hook_lookup);

/// The extension an extension function belongs to, for those the layer may enable for itself.
fn extension_of(function: &str) -> Option<&'static str> {
    match function {
        "xrGetVisibilityMaskKHR" => Some(VISIBILITY_MASK_EXT),
        _ => None,
    }
}

/// The shell's tables; the live sessions are the contract's (`crate::plugin::xr::sessions`), where
/// features reach them.
#[derive(Default)]
pub(crate) struct XrState {
    pub instances: HandleMap<u64, Instance>,
    pub swapchains: HandleMap<u64, swapchain::Swapchain>,
}

/// Makes `config` the process's live configuration, and its typed settings the live settings
/// (`crate::plugin::settings::current`), in that order of publication.
pub(crate) fn publish_config(config: Arc<Config>) {
    crate::plugin::settings::publish(crate::plugin::settings::Settings::from_config(&config));
    crate::bridge::shared().set_config(config);
}

pub(crate) fn state() -> &'static XrState {
    static STATE: OnceLock<XrState> = OnceLock::new();
    STATE.get_or_init(XrState::default)
}

/// The instance to call down through for a handle the layer never saw created (the app passed a
/// bad handle): the loader allows one instance per process, so that one is the only candidate,
/// and the runtime gets to report the error the spec asks for.
fn sole_instance() -> Option<Arc<Instance>> {
    let all = state().instances.values();
    match all.as_slice() {
        [(_, only)] => Some(only.clone()),
        _ => None,
    }
}

/// The state of an instance the app passed, or the one to forward an unknown handle through.
fn instance_for(instance: xr::Instance) -> Option<Arc<Instance>> {
    state().instances.get(instance.into_raw()).or_else(sole_instance)
}

/// Reads a fixed-size, NUL-terminated C string field.
fn fixed_str(chars: &[c_char]) -> String {
    let bytes: Vec<u8> = chars.iter().take_while(|&&c| c != 0).map(|&c| c as u8).collect();
    String::from_utf8_lossy(&bytes).into_owned()
}

/// The loader's first call into the layer.
///
/// # Safety
/// Called by the OpenXR loader with pointers valid per the loader interface.
#[no_mangle]
pub unsafe extern "system" fn xrNegotiateLoaderApiLayerInterface(
    loader_info: *const xr::NegotiateLoaderInfo,
    _layer_name: *const c_char,
    request: *mut xr::NegotiateApiLayerRequest,
) -> xr::Result {
    crate::core::guard::catch("xrNegotiateLoaderApiLayerInterface", xr::Result::ERROR_INITIALIZATION_FAILED, || {
        // SAFETY: the loader passes valid pointers or null; null is rejected before use.
        let (Some(info), Some(req)) = (unsafe { loader_info.as_ref() }, unsafe { request.as_mut() }) else {
            return xr::Result::ERROR_INITIALIZATION_FAILED;
        };
        if info.struct_type != xr::NegotiateLoaderInfo::TYPE
            || info.struct_version != xr::NegotiateLoaderInfo::VERSION
            || info.struct_size != std::mem::size_of::<xr::NegotiateLoaderInfo>()
            || req.struct_type != xr::NegotiateApiLayerRequest::TYPE
            || req.struct_version != xr::NegotiateApiLayerRequest::VERSION
            || req.struct_size != std::mem::size_of::<xr::NegotiateApiLayerRequest>()
            || !(info.min_interface_version..=info.max_interface_version).contains(&1)
        {
            return xr::Result::ERROR_INITIALIZATION_FAILED;
        }
        req.layer_interface_version = 1;
        req.layer_api_version = xr::CURRENT_API_VERSION;
        req.get_instance_proc_addr = Some(get_instance_proc_addr);
        req.create_api_layer_instance = Some(instance::create_api_layer_instance);
        xr::Result::SUCCESS
    })
}

/// Our hooks for intercepted names, the next layer's functions for everything else.
unsafe extern "system" fn get_instance_proc_addr(
    instance: xr::Instance,
    name: *const c_char,
    function: *mut Option<xr::pfn::VoidFunction>,
) -> xr::Result {
    crate::core::guard::catch("xrGetInstanceProcAddr", xr::Result::ERROR_RUNTIME_FAILURE, || {
        if name.is_null() || function.is_null() {
            return xr::Result::ERROR_VALIDATION_FAILURE;
        }
        // SAFETY: non-null, NUL-terminated per the spec.
        let name_str = unsafe { CStr::from_ptr(name) }.to_str().unwrap_or("");
        if name_str == "xrGetInstanceProcAddr" {
            // SAFETY: `function` checked non-null above.
            unsafe { *function = Some(std::mem::transmute::<xr::pfn::GetInstanceProcAddr, xr::pfn::VoidFunction>(get_instance_proc_addr)) };
            return xr::Result::SUCCESS;
        }
        let Some(inst) = state().instances.get(instance.into_raw()) else {
            return xr::Result::ERROR_HANDLE_INVALID;
        };
        // Functions of extensions the layer implements for the app: its own, whatever the
        // runtime has.
        if name_str == "xrGetVisibilityMaskKHR" && inst.offers(VISIBILITY_MASK_EXT) {
            // SAFETY: `function` checked non-null above; the loader casts the pointer back to the
            // type the spec gives the name.
            unsafe { *function = Some(std::mem::transmute::<xr::pfn::GetVisibilityMaskKHR, xr::pfn::VoidFunction>(hooks::get_visibility_mask)) };
            return xr::Result::SUCCESS;
        }
        // Functions of extensions only the layer enabled do not exist for the app.
        if extension_of(name_str).is_some_and(|ext| !inst.app_enabled(ext)) {
            // SAFETY: `function` checked non-null above.
            unsafe { *function = None };
            return xr::Result::ERROR_FUNCTION_UNSUPPORTED;
        }
        // SAFETY: forwarding the caller's valid arguments to the next layer.
        let r = unsafe { (inst.next.get_instance_proc_addr)(instance, name, function) };
        if r == xr::Result::SUCCESS && inst.config.enabled() {
            if let Some(hook) = hook(&inst.next, name_str) {
                // SAFETY: `function` checked non-null above.
                unsafe { *function = Some(hook) };
            }
        }
        r
    })
}
