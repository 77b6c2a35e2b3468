//! A mock OpenXR runtime for testing stereoshim: loaded by the Khronos loader through a runtime
//! manifest, it validates what apps (and layers in between) submit as strictly as the spec
//! allows, owns real swapchain `VkImage`s on the app's device, and captures submitted frames.
//! See docs/testing.md for the contract (environment variables, capture format).
//!
//! This file holds the loader negotiation and the ONE table of exported functions.

#![allow(clippy::missing_safety_doc)]

use std::ffi::c_char;

use openxr_sys as xr;
use xr::pfn;
use xr::Handle as _;

pub mod actions;
pub mod capture;
pub mod config;
pub mod fault;
pub mod frame;
pub mod handles;
pub mod hmd;
pub mod instance;
pub mod profiles;
pub mod session;
pub mod space;
pub mod swapchain;
pub mod system;
pub mod util;
pub mod visibility_mask;
pub mod vulkan;

use util::{guard, read_cstr, XrResult};

/// The OpenXR version this runtime implements (apps may ask for 1.0.x or 1.1.x).
pub const RUNTIME_API_VERSION: xr::Version = xr::Version::new(1, 1, 0);

pub const EXT_VULKAN_ENABLE: &str = "XR_KHR_vulkan_enable";
pub const EXT_VULKAN_ENABLE2: &str = "XR_KHR_vulkan_enable2";
pub const EXT_VISIBILITY_MASK: &str = "XR_KHR_visibility_mask";
pub const EXT_DEPTH: &str = "XR_KHR_composition_layer_depth";
pub const EXT_EYE_GAZE: &str = "XR_EXT_eye_gaze_interaction";
/// Sessions without a graphics binding (`stereoshim preview --runtime`); hidden with
/// `MOCK_XR_DISABLE_EXTENSIONS=XR_MND_headless`.
pub const EXT_HEADLESS: &str = "XR_MND_headless";

/// Offered extensions and their spec versions.
pub const EXTENSIONS: &[(&str, u32)] = &[
    (EXT_VULKAN_ENABLE, 8),
    (EXT_VULKAN_ENABLE2, 2),
    (EXT_VISIBILITY_MASK, 2),
    (EXT_DEPTH, 6),
    (EXT_EYE_GAZE, 2),
    (EXT_HEADLESS, 2),
    // Controller-interaction extensions: each only adds an interaction profile (profiles.rs).
    ("XR_EXT_hp_mixed_reality_controller", 1),
    ("XR_EXT_samsung_odyssey_controller", 1),
    ("XR_HTC_vive_cosmos_controller_interaction", 1),
    ("XR_HTC_vive_focus3_controller_interaction", 2),
    ("XR_HUAWEI_controller_interaction", 1),
    ("XR_FB_touch_controller_pro", 1),
    ("XR_META_touch_controller_plus", 1),
    ("XR_BD_controller_interaction", 2),
    ("XR_ML_ml2_controller_interaction", 1),
    ("XR_VARJO_xr4_controller_interaction", 2),
    ("XR_YVR_controller_interaction", 1),
    ("XR_OPPO_controller_interaction", 1),
    ("XR_LOGITECH_mx_ink_stylus_interaction", 1),
];

/// One exported function: its name, the extension that must be enabled for it (None: core),
/// and its pointer (signature checked against openxr-sys's `pfn` type by `f!`).
pub struct Func {
    pub name: &'static str,
    pub extension: Option<&'static str>,
    pub ptr: pfn::VoidFunction,
}

macro_rules! f {
    ($name:literal, $pfn:ident, $path:path) => {
        f!($name, $pfn, $path, None)
    };
    ($name:literal, $pfn:ident, $path:path, $ext:expr) => {
        Func {
            name: $name,
            extension: $ext,
            // SAFETY: the `as pfn::$pfn` cast proves the signature; the loader casts it back to
            // the same type before calling, as with every xrGetInstanceProcAddr result.
            ptr: unsafe { std::mem::transmute::<pfn::$pfn, pfn::VoidFunction>($path as pfn::$pfn) },
        }
    };
}

/// Every implemented function, in one place.
pub static FUNCTIONS: &[Func] = &[
    f!("xrGetInstanceProcAddr", GetInstanceProcAddr, xr_get_instance_proc_addr),
    f!("xrEnumerateInstanceExtensionProperties", EnumerateInstanceExtensionProperties, instance::xr_enumerate_instance_extension_properties),
    f!("xrCreateInstance", CreateInstance, instance::xr_create_instance),
    f!("xrDestroyInstance", DestroyInstance, instance::xr_destroy_instance),
    f!("xrGetInstanceProperties", GetInstanceProperties, instance::xr_get_instance_properties),
    f!("xrPollEvent", PollEvent, instance::xr_poll_event),
    f!("xrResultToString", ResultToString, instance::xr_result_to_string),
    f!("xrStructureTypeToString", StructureTypeToString, instance::xr_structure_type_to_string),
    f!("xrStringToPath", StringToPath, instance::xr_string_to_path),
    f!("xrPathToString", PathToString, instance::xr_path_to_string),
    f!("xrGetSystem", GetSystem, system::xr_get_system),
    f!("xrGetSystemProperties", GetSystemProperties, system::xr_get_system_properties),
    f!("xrEnumerateEnvironmentBlendModes", EnumerateEnvironmentBlendModes, system::xr_enumerate_environment_blend_modes),
    f!("xrEnumerateViewConfigurations", EnumerateViewConfigurations, system::xr_enumerate_view_configurations),
    f!("xrGetViewConfigurationProperties", GetViewConfigurationProperties, system::xr_get_view_configuration_properties),
    f!("xrEnumerateViewConfigurationViews", EnumerateViewConfigurationViews, system::xr_enumerate_view_configuration_views),
    f!("xrCreateSession", CreateSession, session::xr_create_session),
    f!("xrDestroySession", DestroySession, session::xr_destroy_session),
    f!("xrBeginSession", BeginSession, session::xr_begin_session),
    f!("xrEndSession", EndSession, session::xr_end_session),
    f!("xrRequestExitSession", RequestExitSession, session::xr_request_exit_session),
    f!("xrEnumerateReferenceSpaces", EnumerateReferenceSpaces, space::xr_enumerate_reference_spaces),
    f!("xrCreateReferenceSpace", CreateReferenceSpace, space::xr_create_reference_space),
    f!("xrGetReferenceSpaceBoundsRect", GetReferenceSpaceBoundsRect, space::xr_get_reference_space_bounds_rect),
    f!("xrCreateActionSpace", CreateActionSpace, space::xr_create_action_space),
    f!("xrLocateSpace", LocateSpace, space::xr_locate_space),
    f!("xrDestroySpace", DestroySpace, space::xr_destroy_space),
    f!("xrWaitFrame", WaitFrame, frame::xr_wait_frame),
    f!("xrBeginFrame", BeginFrame, frame::xr_begin_frame),
    f!("xrEndFrame", EndFrame, frame::xr_end_frame),
    f!("xrLocateViews", LocateViews, frame::xr_locate_views),
    f!("xrEnumerateSwapchainFormats", EnumerateSwapchainFormats, swapchain::xr_enumerate_swapchain_formats),
    f!("xrCreateSwapchain", CreateSwapchain, swapchain::xr_create_swapchain),
    f!("xrDestroySwapchain", DestroySwapchain, swapchain::xr_destroy_swapchain),
    f!("xrEnumerateSwapchainImages", EnumerateSwapchainImages, swapchain::xr_enumerate_swapchain_images),
    f!("xrAcquireSwapchainImage", AcquireSwapchainImage, swapchain::xr_acquire_swapchain_image),
    f!("xrWaitSwapchainImage", WaitSwapchainImage, swapchain::xr_wait_swapchain_image),
    f!("xrReleaseSwapchainImage", ReleaseSwapchainImage, swapchain::xr_release_swapchain_image),
    f!("xrCreateActionSet", CreateActionSet, actions::xr_create_action_set),
    f!("xrDestroyActionSet", DestroyActionSet, actions::xr_destroy_action_set),
    f!("xrCreateAction", CreateAction, actions::xr_create_action),
    f!("xrDestroyAction", DestroyAction, actions::xr_destroy_action),
    f!("xrSuggestInteractionProfileBindings", SuggestInteractionProfileBindings, actions::xr_suggest_interaction_profile_bindings),
    f!("xrAttachSessionActionSets", AttachSessionActionSets, actions::xr_attach_session_action_sets),
    f!("xrGetCurrentInteractionProfile", GetCurrentInteractionProfile, actions::xr_get_current_interaction_profile),
    f!("xrSyncActions", SyncActions, actions::xr_sync_actions),
    f!("xrGetActionStateBoolean", GetActionStateBoolean, actions::xr_get_action_state_boolean),
    f!("xrGetActionStateFloat", GetActionStateFloat, actions::xr_get_action_state_float),
    f!("xrGetActionStateVector2f", GetActionStateVector2f, actions::xr_get_action_state_vector2f),
    f!("xrGetActionStatePose", GetActionStatePose, actions::xr_get_action_state_pose),
    f!("xrEnumerateBoundSourcesForAction", EnumerateBoundSourcesForAction, actions::xr_enumerate_bound_sources_for_action),
    f!("xrGetInputSourceLocalizedName", GetInputSourceLocalizedName, actions::xr_get_input_source_localized_name),
    f!("xrApplyHapticFeedback", ApplyHapticFeedback, actions::xr_apply_haptic_feedback),
    f!("xrStopHapticFeedback", StopHapticFeedback, actions::xr_stop_haptic_feedback),
    f!("xrGetVulkanInstanceExtensionsKHR", GetVulkanInstanceExtensionsKHR, vulkan::xr_get_vulkan_instance_extensions_khr, Some(EXT_VULKAN_ENABLE)),
    f!("xrGetVulkanDeviceExtensionsKHR", GetVulkanDeviceExtensionsKHR, vulkan::xr_get_vulkan_device_extensions_khr, Some(EXT_VULKAN_ENABLE)),
    f!("xrGetVulkanGraphicsDeviceKHR", GetVulkanGraphicsDeviceKHR, vulkan::xr_get_vulkan_graphics_device_khr, Some(EXT_VULKAN_ENABLE)),
    f!("xrGetVulkanGraphicsRequirementsKHR", GetVulkanGraphicsRequirementsKHR, vulkan::xr_get_vulkan_graphics_requirements_khr, Some(EXT_VULKAN_ENABLE)),
    f!("xrCreateVulkanInstanceKHR", CreateVulkanInstanceKHR, vulkan::xr_create_vulkan_instance_khr, Some(EXT_VULKAN_ENABLE2)),
    f!("xrCreateVulkanDeviceKHR", CreateVulkanDeviceKHR, vulkan::xr_create_vulkan_device_khr, Some(EXT_VULKAN_ENABLE2)),
    f!("xrGetVulkanGraphicsDevice2KHR", GetVulkanGraphicsDevice2KHR, vulkan::xr_get_vulkan_graphics_device2_khr, Some(EXT_VULKAN_ENABLE2)),
    f!("xrGetVulkanGraphicsRequirements2KHR", GetVulkanGraphicsRequirements2KHR, vulkan::xr_get_vulkan_graphics_requirements2_khr, Some(EXT_VULKAN_ENABLE2)),
    f!("xrGetVisibilityMaskKHR", GetVisibilityMaskKHR, visibility_mask::xr_get_visibility_mask_khr, Some(EXT_VISIBILITY_MASK)),
];

/// Functions the loader may look up before an instance exists.
const PRE_INSTANCE: &[&str] = &["xrEnumerateInstanceExtensionProperties", "xrCreateInstance", "xrGetInstanceProcAddr"];

fn lookup(instance: xr::Instance, name: &str) -> XrResult<pfn::VoidFunction> {
    let func = FUNCTIONS.iter().find(|f| f.name == name);
    if instance == xr::Instance::NULL {
        fault::global_fail_point("xrGetInstanceProcAddr")?;
        return match func {
            Some(f) if PRE_INSTANCE.contains(&f.name) => Ok(f.ptr),
            _ => Err(xr::Result::ERROR_HANDLE_INVALID),
        };
    }
    let inst = instance::get(instance)?;
    inst.fail_point("xrGetInstanceProcAddr")?;
    let f = func.ok_or(xr::Result::ERROR_FUNCTION_UNSUPPORTED)?;
    match f.extension {
        Some(ext) if !inst.extension_enabled(ext) => Err(xr::Result::ERROR_FUNCTION_UNSUPPORTED),
        _ => Ok(f.ptr),
    }
}

unsafe extern "system" fn xr_get_instance_proc_addr(
    instance: xr::Instance,
    name: *const c_char,
    function: *mut Option<pfn::VoidFunction>,
) -> xr::Result {
    guard("xrGetInstanceProcAddr", || {
        // SAFETY: the loader passes a writable pointer; NULL is rejected.
        let out = unsafe { util::out_ptr(function) }?;
        *out = None;
        // SAFETY: NUL-terminated name from the caller.
        let name = unsafe { read_cstr(name) }?;
        *out = Some(lookup(instance, &name)?);
        Ok(xr::Result::SUCCESS)
    })
}

/// The loader's entry point into the runtime (openxr_loader_negotiation.h).
///
/// # Safety
/// Called by the loader with valid (or NULL) struct pointers.
#[no_mangle]
pub unsafe extern "system" fn xrNegotiateLoaderRuntimeInterface(
    loader_info: *const xr::NegotiateLoaderInfo,
    request: *mut xr::NegotiateRuntimeRequest,
) -> xr::Result {
    guard("xrNegotiateLoaderRuntimeInterface", || {
        if loader_info.is_null() || request.is_null() {
            return Err(xr::Result::ERROR_INITIALIZATION_FAILED);
        }
        // SAFETY: checked non-null; the loader owns both structs for this call.
        let (li, rq) = unsafe { (&*loader_info, &mut *request) };
        use xr::{NegotiateLoaderInfo as Li, NegotiateRuntimeRequest as Rq};
        if li.struct_type != Li::TYPE
            || li.struct_version != Li::VERSION
            || li.struct_size != std::mem::size_of::<Li>()
            || rq.struct_type != Rq::TYPE
            || rq.struct_version != Rq::VERSION
            || rq.struct_size != std::mem::size_of::<Rq>()
        {
            return Err(xr::Result::ERROR_INITIALIZATION_FAILED);
        }
        if li.min_interface_version > 1 || li.max_interface_version < 1 {
            return Err(xr::Result::ERROR_INITIALIZATION_FAILED);
        }
        // Any 1.x the loader can handle; we implement 1.0 and 1.1.
        if li.min_api_version.major() > 1 || li.max_api_version.major() < 1 {
            return Err(xr::Result::ERROR_INITIALIZATION_FAILED);
        }
        fault::global_fail_point("xrNegotiateLoaderRuntimeInterface")?;
        rq.runtime_interface_version = 1;
        // An older loader (1.0.x) must not be told about a newer API than it knows.
        rq.runtime_api_version = RUNTIME_API_VERSION.min(li.max_api_version);
        rq.get_instance_proc_addr = Some(xr_get_instance_proc_addr);
        crate::log!("negotiated with loader");
        Ok(xr::Result::SUCCESS)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_names_unique_and_extensions_known() {
        let mut names: Vec<_> = FUNCTIONS.iter().map(|f| f.name).collect();
        names.sort();
        let n = names.len();
        names.dedup();
        assert_eq!(n, names.len());
        for f in FUNCTIONS {
            if let Some(e) = f.extension {
                assert!(EXTENSIONS.iter().any(|(x, _)| *x == e), "{}", f.name);
            }
        }
    }
}
