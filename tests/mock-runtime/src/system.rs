//! The one system (an HMD described by the active profile) and its view configuration.

use openxr_sys as xr;

use crate::instance::{self, Instance};
use crate::util::{find_in_chain, guard, input, out_ptr, output, two_call, two_call_copy, write_fixed, XrResult};
use crate::EXT_EYE_GAZE;

/// The largest swapchain image side, as Monado reports it (16 × 1024): an image holds every
/// view side by side at up to the largest image rect each (`maxImageRect*`, the profile's).
pub const MAX_SWAPCHAIN_EXTENT: u32 = 16 * 1024;

pub const SYSTEM_ID: u64 = 0x5EED;
pub const MAX_LAYERS: u32 = 16;
/// `maxSwapchainSampleCount` of both views (see xrEnumerateViewConfigurationViews).
pub const MAX_SWAPCHAIN_SAMPLE_COUNT: u32 = 8;

pub fn check_system(id: xr::SystemId) -> XrResult<()> {
    if id.into_raw() == SYSTEM_ID {
        Ok(())
    } else {
        Err(xr::Result::ERROR_SYSTEM_INVALID)
    }
}

pub fn check_view_config(ty: xr::ViewConfigurationType) -> XrResult<()> {
    if ty == xr::ViewConfigurationType::PRIMARY_STEREO {
        Ok(())
    } else {
        Err(xr::Result::ERROR_VIEW_CONFIGURATION_TYPE_UNSUPPORTED)
    }
}

pub fn eye_gaze_supported(inst: &Instance) -> bool {
    inst.extension_enabled(EXT_EYE_GAZE) && inst.cfg.eye_tracker
}

pub unsafe extern "system" fn xr_get_system(
    instance: xr::Instance,
    info: *const xr::SystemGetInfo,
    system_id: *mut xr::SystemId,
) -> xr::Result {
    guard("xrGetSystem", || {
        let inst = instance::get(instance)?;
        inst.fail_point("xrGetSystem")?;
        // SAFETY: app pointers, checked by the helpers.
        let (info, out) = unsafe { (input(info)?, out_ptr(system_id)?) };
        match info.form_factor {
            xr::FormFactor::HEAD_MOUNTED_DISPLAY => {
                *out = xr::SystemId::from_raw(SYSTEM_ID);
                Ok(xr::Result::SUCCESS)
            }
            xr::FormFactor::HANDHELD_DISPLAY => Err(xr::Result::ERROR_FORM_FACTOR_UNSUPPORTED),
            _ => Err(xr::Result::ERROR_VALIDATION_FAILURE),
        }
    })
}

pub unsafe extern "system" fn xr_get_system_properties(
    instance: xr::Instance,
    system_id: xr::SystemId,
    props: *mut xr::SystemProperties,
) -> xr::Result {
    guard("xrGetSystemProperties", || {
        let inst = instance::get(instance)?;
        check_system(system_id)?;
        inst.fail_point("xrGetSystemProperties")?;
        // SAFETY: app output struct, type-checked.
        let p = unsafe { output(props) }?;
        let hmd = inst.cfg.hmd;
        p.system_id = system_id;
        p.vendor_id = 0x5E5E;
        write_fixed(&mut p.system_name, hmd.system_name);
        p.graphics_properties = xr::SystemGraphicsProperties {
            max_swapchain_image_height: MAX_SWAPCHAIN_EXTENT,
            max_swapchain_image_width: MAX_SWAPCHAIN_EXTENT,
            max_layer_count: inst.cfg.max_layers,
        };
        p.tracking_properties = xr::SystemTrackingProperties { orientation_tracking: xr::TRUE, position_tracking: xr::TRUE };
        if inst.extension_enabled(EXT_EYE_GAZE) {
            // SAFETY: the app's output chain; a found struct has the eye-gaze layout.
            let eg = unsafe { find_in_chain(p.next, xr::SystemEyeGazeInteractionPropertiesEXT::TYPE) }
                as *mut xr::SystemEyeGazeInteractionPropertiesEXT;
            if !eg.is_null() {
                // SAFETY: found in the app's writable chain.
                unsafe { (*eg).supports_eye_gaze_interaction = eye_gaze_supported(&inst).into() };
            }
        }
        Ok(xr::Result::SUCCESS)
    })
}

pub unsafe extern "system" fn xr_enumerate_environment_blend_modes(
    instance: xr::Instance,
    system_id: xr::SystemId,
    view_config: xr::ViewConfigurationType,
    capacity: u32,
    count_out: *mut u32,
    modes: *mut xr::EnvironmentBlendMode,
) -> xr::Result {
    guard("xrEnumerateEnvironmentBlendModes", || {
        let inst = instance::get(instance)?;
        check_system(system_id)?;
        inst.fail_point("xrEnumerateEnvironmentBlendModes")?;
        check_view_config(view_config)?;
        // SAFETY: app array of `capacity` elements.
        unsafe { two_call_copy(capacity, count_out, modes, &[xr::EnvironmentBlendMode::OPAQUE]) }?;
        Ok(xr::Result::SUCCESS)
    })
}

pub unsafe extern "system" fn xr_enumerate_view_configurations(
    instance: xr::Instance,
    system_id: xr::SystemId,
    capacity: u32,
    count_out: *mut u32,
    types: *mut xr::ViewConfigurationType,
) -> xr::Result {
    guard("xrEnumerateViewConfigurations", || {
        let inst = instance::get(instance)?;
        check_system(system_id)?;
        inst.fail_point("xrEnumerateViewConfigurations")?;
        // SAFETY: app array of `capacity` elements.
        unsafe { two_call_copy(capacity, count_out, types, &[xr::ViewConfigurationType::PRIMARY_STEREO]) }?;
        Ok(xr::Result::SUCCESS)
    })
}

pub unsafe extern "system" fn xr_get_view_configuration_properties(
    instance: xr::Instance,
    system_id: xr::SystemId,
    view_config: xr::ViewConfigurationType,
    props: *mut xr::ViewConfigurationProperties,
) -> xr::Result {
    guard("xrGetViewConfigurationProperties", || {
        let inst = instance::get(instance)?;
        check_system(system_id)?;
        inst.fail_point("xrGetViewConfigurationProperties")?;
        check_view_config(view_config)?;
        // SAFETY: app output struct.
        let p = unsafe { output(props) }?;
        p.view_configuration_type = view_config;
        p.fov_mutable = xr::FALSE;
        Ok(xr::Result::SUCCESS)
    })
}

pub unsafe extern "system" fn xr_enumerate_view_configuration_views(
    instance: xr::Instance,
    system_id: xr::SystemId,
    view_config: xr::ViewConfigurationType,
    capacity: u32,
    count_out: *mut u32,
    views: *mut xr::ViewConfigurationView,
) -> xr::Result {
    guard("xrEnumerateViewConfigurationViews", || {
        let inst = instance::get(instance)?;
        check_system(system_id)?;
        inst.fail_point("xrEnumerateViewConfigurationViews")?;
        check_view_config(view_config)?;
        if capacity > 0 && views.is_null() {
            return Err(xr::Result::ERROR_VALIDATION_FAILURE);
        }
        let hmd = inst.cfg.hmd;
        let recommended = inst.cfg.recommended();
        // SAFETY: app array of `capacity` elements, each type-checked.
        unsafe {
            two_call(capacity, count_out, 2, |i| {
                let v = output(views.add(i))?;
                (v.recommended_image_rect_width, v.recommended_image_rect_height) = recommended;
                v.max_image_rect_width = hmd.max.0;
                v.max_image_rect_height = hmd.max.1;
                v.recommended_swapchain_sample_count = 1;
                // Asked before any Vulkan device is known: the largest count common GPUs render
                // colour and depth at. xrCreateSwapchain accepts a count only where the session's
                // device supports it for the swapchain's format and usage (lavapipe: 1 and 4).
                v.max_swapchain_sample_count = MAX_SWAPCHAIN_SAMPLE_COUNT;
                Ok(())
            })
        }?;
        Ok(xr::Result::SUCCESS)
    })
}
