//! The Vulkan binding calls: how the Vulkan half gets into the app's process without the app
//! changing. With `XR_KHR_vulkan_enable2` the app's `VkInstanceCreateInfo` passes through us and the
//! layer is added to it; with `XR_KHR_vulkan_enable` the app creates its instance itself, after
//! asking for the runtime's instance extensions, so that request is where the layer is put into
//! `VK_INSTANCE_LAYERS`. Either way the loader finds the layer through `VK_ADD_LAYER_PATH`.

use crate::core::guard;
use crate::track::device_ext;
use crate::manifests::vulkan::{self as vk_manifest, VK_LAYER_NAME};
use ash::vk;
use openxr_sys as xr;
use std::ffi::{c_char, CStr, CString};
use std::sync::OnceLock;

/// Writes the Vulkan manifest for this very library file and adds its folder to
/// `VK_ADD_LAYER_PATH`, once per process. Returns false when that is impossible (logged once).
fn prepare_layer_path() -> bool {
    static READY: OnceLock<bool> = OnceLock::new();
    *READY.get_or_init(|| {
        let maps = std::fs::read_to_string("/proc/self/maps").unwrap_or_default();
        let Some(library) = vk_manifest::library_containing(&maps, prepare_layer_path as *const () as usize) else {
            tracing::error!("cannot find the file this layer was loaded from; the Vulkan half stays off");
            return false;
        };
        match vk_manifest::write_manifest(&library) {
            Ok(dir) => {
                let current = std::env::var("VK_ADD_LAYER_PATH").ok();
                if let Some(value) = vk_manifest::add_layer_path(current.as_deref(), &dir) {
                    // The loader reads this when an instance is created. Setting the environment
                    // is not thread-safe against concurrent getenv; it happens during the app's
                    // XR setup, before it creates its Vulkan instance.
                    std::env::set_var("VK_ADD_LAYER_PATH", value);
                }
                tracing::info!("vulkan layer manifest for {} in {}", library.display(), dir.display());
                true
            }
            Err(e) => {
                tracing::error!("cannot write the vulkan layer manifest: {e}; the Vulkan half stays off");
                false
            }
        }
    })
}

/// Whether the loader behind `gipa` lists our layer (a layer named in the create info but not
/// found fails instance creation, which must never happen because of us).
///
/// # Safety
/// `gipa` must be a valid `vkGetInstanceProcAddr`.
unsafe fn layer_available(gipa: xr::platform::VkGetInstanceProcAddr) -> bool {
    // SAFETY: global commands are queried with a null instance (Vulkan spec).
    let Some(f) = (unsafe { gipa(std::ptr::null(), c"vkEnumerateInstanceLayerProperties".as_ptr()) }) else {
        return false;
    };
    // SAFETY: the function for this name has this type.
    let enumerate: vk::PFN_vkEnumerateInstanceLayerProperties = unsafe { std::mem::transmute(f) };
    let mut count = 0u32;
    // SAFETY: two-call idiom with valid pointers.
    if unsafe { enumerate(&mut count, std::ptr::null_mut()) } != vk::Result::SUCCESS {
        return false;
    }
    let mut props = vec![vk::LayerProperties::default(); count as usize];
    // SAFETY: `props` holds `count` elements.
    let r = unsafe { enumerate(&mut count, props.as_mut_ptr()) };
    if r != vk::Result::SUCCESS && r != vk::Result::INCOMPLETE {
        return false;
    }
    props.iter().take(count as usize).any(|p| p.layer_name_as_c_str().is_ok_and(|n| n.to_bytes() == VK_LAYER_NAME.as_bytes()))
}

/// The instance extensions the loader behind `gipa` lists (empty when it cannot be asked).
///
/// # Safety
/// `gipa` must be a valid `vkGetInstanceProcAddr`.
unsafe fn instance_extensions(gipa: xr::platform::VkGetInstanceProcAddr) -> Vec<String> {
    // SAFETY: global commands are queried with a null instance (Vulkan spec).
    let Some(f) = (unsafe { gipa(std::ptr::null(), c"vkEnumerateInstanceExtensionProperties".as_ptr()) }) else {
        return Vec::new();
    };
    // SAFETY: the function for this name has this type.
    let enumerate: vk::PFN_vkEnumerateInstanceExtensionProperties = unsafe { std::mem::transmute(f) };
    let mut count = 0u32;
    // SAFETY: two-call idiom with valid pointers; a null layer name asks for the implementation's.
    if unsafe { enumerate(std::ptr::null(), &mut count, std::ptr::null_mut()) } != vk::Result::SUCCESS {
        return Vec::new();
    }
    let mut props = vec![vk::ExtensionProperties::default(); count as usize];
    // SAFETY: `props` holds `count` elements.
    let r = unsafe { enumerate(std::ptr::null(), &mut count, props.as_mut_ptr()) };
    if r != vk::Result::SUCCESS && r != vk::Result::INCOMPLETE {
        return Vec::new();
    }
    props.iter().take(count as usize).filter_map(|p| p.extension_name_as_c_str().ok().map(|n| n.to_string_lossy().into_owned())).collect()
}

pub(super) unsafe extern "system" fn create_vulkan_instance(
    instance: xr::Instance,
    create_info: *const xr::VulkanInstanceCreateInfoKHR,
    vulkan_instance: *mut xr::platform::VkInstance,
    vulkan_result: *mut xr::platform::VkResult,
) -> xr::Result {
    let Some(inst) = super::instance_for(instance) else {
        return xr::Result::ERROR_HANDLE_INVALID;
    };
    let Some(next) = inst.next.create_vulkan_instance else { return xr::Result::ERROR_FUNCTION_UNSUPPORTED };
    // SAFETY: forwarding the app's arguments unchanged.
    let plain = || unsafe { next(instance, create_info, vulkan_instance, vulkan_result) };
    guard::run("xrCreateVulkanInstanceKHR", &inst.pass_through, |down| {
        inst.check_fault("xrCreateVulkanInstanceKHR")?;
        let _span = tracing::debug_span!("xrCreateVulkanInstanceKHR").entered();
        // SAFETY: the app's create info is valid for this call; null goes down for the runtime to reject.
        let Some(ci) = (unsafe { create_info.as_ref() }) else { return Ok(down.call(plain)) };
        // SAFETY: as above.
        let Some(vk_ci) = (unsafe { (ci.vulkan_create_info as *const vk::InstanceCreateInfo).as_ref() }) else {
            return Ok(down.call(plain));
        };
        let Some(gipa) = ci.pfn_get_instance_proc_addr else { return Ok(down.call(plain)) };
        // SAFETY: `gipa` is the app's loader entry point.
        if !prepare_layer_path() || !unsafe { layer_available(gipa) } {
            tracing::warn!("vulkan layer {VK_LAYER_NAME} not found by the loader; Vulkan half off for this instance");
            return Ok(down.call(plain));
        }
        // SAFETY: the app's layer names are valid for this call.
        let app_layers: Vec<*const c_char> = unsafe {
            if vk_ci.enabled_layer_count == 0 || vk_ci.pp_enabled_layer_names.is_null() {
                Vec::new()
            } else {
                std::slice::from_raw_parts(vk_ci.pp_enabled_layer_names, vk_ci.enabled_layer_count as usize).to_vec()
            }
        };
        let ours = CString::new(VK_LAYER_NAME)?;
        // SAFETY: each name is a valid NUL-terminated string from the app.
        let already = app_layers.iter().any(|&n| unsafe { CStr::from_ptr(n) }.to_bytes() == VK_LAYER_NAME.as_bytes());
        // First in the list is closest to the app: the app's own layers (validation) then sit
        // below us and see what we inject too.
        let mut layers = Vec::with_capacity(app_layers.len() + 1);
        if !already {
            layers.push(ours.as_ptr());
        }
        layers.extend(app_layers);
        // A Vulkan 1.0 app: the instance extension shading rate depends on, when it may be wanted.
        // SAFETY: the app's names are valid for this call; `gipa` is the app's loader entry point.
        let (app_extensions, available) = unsafe {
            (crate::plugin::vk::convert::names(vk_ci.pp_enabled_extension_names, vk_ci.enabled_extension_count), instance_extensions(gipa))
        };
        // SAFETY: the app's application info, valid for this call, or null.
        let api_version = unsafe { vk_ci.p_application_info.as_ref() }.map_or(vk::API_VERSION_1_0, |a| a.api_version);
        let config = &inst.config;
        let fsr_wanted = device_ext::config_wants_fsr(config.choice("vulkan.fragment_shading_rate"), config.choice("foveation.method"));
        let added: Vec<CString> = device_ext::instance_additions(api_version, &app_extensions, &available, fsr_wanted)
            .into_iter()
            .filter_map(|e| CString::new(e).ok())
            .collect();
        // SAFETY: as above.
        let mut extensions: Vec<*const c_char> = unsafe { crate::plugin::vk::convert::slice(vk_ci.pp_enabled_extension_names, vk_ci.enabled_extension_count) }.to_vec();
        extensions.extend(added.iter().map(|e| e.as_ptr()));
        if !added.is_empty() {
            tracing::info!("adding {added:?} to the app's Vulkan 1.0 instance (fragment shading rate depends on it)");
        }
        let mut vk_ci2 = *vk_ci;
        vk_ci2.enabled_layer_count = layers.len() as u32;
        vk_ci2.pp_enabled_layer_names = layers.as_ptr();
        vk_ci2.enabled_extension_count = extensions.len() as u32;
        vk_ci2.pp_enabled_extension_names = extensions.as_ptr();
        let mut ci2 = *ci;
        ci2.vulkan_create_info = &vk_ci2 as *const vk::InstanceCreateInfo as *const _;
        // SAFETY: the modified copies live until the call returns; everything else is the app's.
        let r = down.call(|| unsafe { next(instance, &ci2, vulkan_instance, vulkan_result) });
        // SAFETY: the runtime writes the VkResult on return.
        let vr = unsafe { vulkan_result.as_ref().copied() };
        tracing::info!(?r, vk_result = ?vr, "created the app's VkInstance with {VK_LAYER_NAME}");
        Ok(r)
    }, plain)
}

pub(super) unsafe extern "system" fn create_vulkan_device(
    instance: xr::Instance,
    create_info: *const xr::VulkanDeviceCreateInfoKHR,
    vulkan_device: *mut xr::platform::VkDevice,
    vulkan_result: *mut xr::platform::VkResult,
) -> xr::Result {
    let Some(inst) = super::instance_for(instance) else {
        return xr::Result::ERROR_HANDLE_INVALID;
    };
    let Some(next) = inst.next.create_vulkan_device else { return xr::Result::ERROR_FUNCTION_UNSUPPORTED };
    // SAFETY: forwarding the app's arguments unchanged.
    let plain = || unsafe { next(instance, create_info, vulkan_device, vulkan_result) };
    guard::run("xrCreateVulkanDeviceKHR", &inst.pass_through, |down| {
        inst.check_fault("xrCreateVulkanDeviceKHR")?;
        let r = down.call(plain);
        if r == xr::Result::SUCCESS {
            // SAFETY: success means the device handle was written.
            let device = unsafe { *vulkan_device } as u64;
            tracing::info!("the runtime created the app's VkDevice {device:#x}");
        }
        Ok(r)
    }, plain)
}

/// Puts the layer into `VK_INSTANCE_LAYERS` for an app that creates its own instance. Apps must
/// ask for these extensions before creating their instance (they have to enable them), so the
/// variable is set in time.
pub(super) unsafe extern "system" fn get_vulkan_instance_extensions(
    instance: xr::Instance,
    system_id: xr::SystemId,
    buffer_capacity_input: u32,
    buffer_count_output: *mut u32,
    buffer: *mut c_char,
) -> xr::Result {
    let Some(inst) = super::instance_for(instance) else {
        return xr::Result::ERROR_HANDLE_INVALID;
    };
    let Some(next) = inst.next.get_vulkan_instance_extensions else { return xr::Result::ERROR_FUNCTION_UNSUPPORTED };
    // SAFETY: forwarding the app's arguments unchanged.
    let plain = || unsafe { next(instance, system_id, buffer_capacity_input, buffer_count_output, buffer) };
    guard::run("xrGetVulkanInstanceExtensionsKHR", &inst.pass_through, |down| {
        inst.check_fault("xrGetVulkanInstanceExtensionsKHR")?;
        static ONCE: OnceLock<()> = OnceLock::new();
        ONCE.get_or_init(|| {
            if prepare_layer_path() {
                let current = std::env::var("VK_INSTANCE_LAYERS").ok();
                if let Some(value) = vk_manifest::add_instance_layer(current.as_deref()) {
                    // See prepare_layer_path on setting the environment.
                    std::env::set_var("VK_INSTANCE_LAYERS", value);
                }
                tracing::info!("app creates its own VkInstance (XR_KHR_vulkan_enable): {VK_LAYER_NAME} added to VK_INSTANCE_LAYERS");
            }
        });
        // Shading rate on a Vulkan 1.0 app's device needs VK_KHR_get_physical_device_properties2
        // on its instance; the app enables what this call lists, so the layer lists it too (when
        // the machine's Vulkan loader offers it).
        let config = &inst.config;
        let fsr_wanted = device_ext::config_wants_fsr(config.choice("vulkan.fragment_shading_rate"), config.choice("foveation.method"));
        if !fsr_wanted || !loader_offers(device_ext::PROPERTIES_2) {
            return Ok(down.call(plain));
        }
        // The runtime's list first (its size, then its text), then the app's call answered with
        // the longer list by the two-call idiom.
        let mut needed = 0u32;
        // SAFETY: a size query with a valid output pointer.
        let r = unsafe { next(instance, system_id, 0, &mut needed, std::ptr::null_mut()) };
        if r != xr::Result::SUCCESS {
            // This query is the runtime's answer to the app's call (the layer only asks first):
            // the app gets its error, as it would without the layer. Calling down again instead
            // would hide a runtime failure behind a second try that may succeed (issue 11).
            return Ok(r);
        }
        let mut runtime = vec![0u8; needed as usize];
        let mut written = 0u32;
        // SAFETY: `runtime` holds `needed` bytes.
        let r = down.call(|| unsafe { next(instance, system_id, needed, &mut written, runtime.as_mut_ptr().cast()) });
        if r != xr::Result::SUCCESS {
            return Ok(r);
        }
        let list = CStr::from_bytes_until_nul(&runtime).map(|c| c.to_string_lossy().into_owned()).unwrap_or_default();
        let answer = match device_ext::with_listed_extension(&list, device_ext::PROPERTIES_2) {
            Some(longer) => {
                static LOGGED: OnceLock<()> = OnceLock::new();
                LOGGED.get_or_init(|| tracing::info!("listing {} for the app's own VkInstance (fragment shading rate depends on it on Vulkan 1.0)", device_ext::PROPERTIES_2));
                longer
            }
            None => list,
        };
        let bytes = CString::new(answer)?.into_bytes_with_nul();
        if buffer_count_output.is_null() {
            return Ok(xr::Result::ERROR_VALIDATION_FAILURE);
        }
        // SAFETY: checked non-null; the app's output.
        unsafe { *buffer_count_output = bytes.len() as u32 };
        if buffer_capacity_input == 0 {
            return Ok(xr::Result::SUCCESS);
        }
        if (buffer_capacity_input as usize) < bytes.len() || buffer.is_null() {
            return Ok(xr::Result::ERROR_SIZE_INSUFFICIENT);
        }
        // SAFETY: the app's buffer holds `buffer_capacity_input` ≥ `bytes.len()` bytes.
        unsafe { std::ptr::copy_nonoverlapping(bytes.as_ptr().cast::<c_char>(), buffer, bytes.len()) };
        Ok(xr::Result::SUCCESS)
    }, plain)
}

/// Whether the machine's Vulkan loader lists an instance extension (asked once per process: the
/// loader is loaded, or found already loaded, for that).
fn loader_offers(extension: &str) -> bool {
    static EXTENSIONS: OnceLock<Vec<String>> = OnceLock::new();
    if EXTENSIONS.get().is_none() {
        // Asked outside `get_or_init`: the loader calls into the layers it loads (implicit ones
        // included), and a call back into this function from there would wait on its own
        // initialisation. Two threads asking at once both ask; the first answer is kept.
        // SAFETY: loads libvulkan.so.1 (the same image when the app links it); its global
        // command is called as the spec allows, outside any loader call.
        let listed = unsafe { ash::Entry::load() }
            .map_err(|e| e.to_string())
            // SAFETY: a global command of the loader just loaded.
            .and_then(|e| unsafe { e.enumerate_instance_extension_properties(None) }.map_err(|e| e.to_string()));
        if let Err(e) = &listed {
            tracing::warn!("cannot ask the Vulkan loader for its instance extensions ({e}): nothing added for XR_KHR_vulkan_enable apps");
        }
        let names = listed.unwrap_or_default().iter().filter_map(|p| p.extension_name_as_c_str().ok().map(|n| n.to_string_lossy().into_owned())).collect();
        let _ = EXTENSIONS.set(names);
    }
    EXTENSIONS.get().is_some_and(|all| all.iter().any(|e| e == extension))
}

pub(super) unsafe extern "system" fn get_vulkan_device_extensions(
    instance: xr::Instance,
    system_id: xr::SystemId,
    buffer_capacity_input: u32,
    buffer_count_output: *mut u32,
    buffer: *mut c_char,
) -> xr::Result {
    let Some(inst) = super::instance_for(instance) else {
        return xr::Result::ERROR_HANDLE_INVALID;
    };
    let Some(next) = inst.next.get_vulkan_device_extensions else { return xr::Result::ERROR_FUNCTION_UNSUPPORTED };
    // SAFETY: forwarding the app's arguments unchanged.
    let plain = || unsafe { next(instance, system_id, buffer_capacity_input, buffer_count_output, buffer) };
    guard::run("xrGetVulkanDeviceExtensionsKHR", &inst.pass_through, |down| {
        inst.check_fault("xrGetVulkanDeviceExtensionsKHR")?;
        Ok(down.call(plain))
    }, plain)
}
