//! `stereoshim doctor`'s Vulkan probe: a short-lived instance of the system's Vulkan loader that
//! reads what each physical device offers the layer's features (version, multiview, attachment
//! shading rates, dynamic rendering, pipeline statistics) and which layers the loader can see, and
//! a check that a layer library loads and negotiates. Only facts come out of here; what they mean
//! is decided by the pure `crate::doctor::rules`. Never used inside an app's process.

use crate::track::device_ext::{FsrSupport, FRAGMENT_SHADING_RATE};
use ash::vk;
use std::ffi::{c_void, CStr};
use std::path::{Path, PathBuf};

/// What one physical device reports.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DeviceFacts {
    pub name: String,
    /// `VkPhysicalDeviceProperties::apiVersion`.
    pub api_version: u32,
    /// `VK_PHYSICAL_DEVICE_TYPE_CPU` (lavapipe, SwiftShader).
    pub cpu: bool,
    pub device_type: String,
    pub extensions: Vec<String>,
    pub multiview: bool,
    pub dynamic_rendering: bool,
    pub pipeline_statistics: bool,
    /// `VkPhysicalDeviceFragmentShadingRateFeaturesKHR`; None without the extension.
    pub fsr: Option<FsrSupport>,
    /// `minFragmentShadingRateAttachmentTexelSize` (0×0 without attachment rates).
    pub fsr_texel: (u32, u32),
    /// `layeredShadingRateAttachments`.
    pub fsr_layered: bool,
}

/// What the Vulkan loader reports.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct VulkanFacts {
    /// The loader file mapped (from `/proc/self/maps`).
    pub loader: Option<PathBuf>,
    /// `vkEnumerateInstanceVersion` (1.0 when the loader lacks it).
    pub instance_version: u32,
    /// `vkEnumerateInstanceLayerProperties` names.
    pub layers: Vec<String>,
    /// Why no instance could be made (no driver, bad ICD files), if so.
    pub instance_error: Option<String>,
    pub devices: Vec<DeviceFacts>,
}

/// A fixed-size name of a Vulkan struct (ash checks the NUL within the array); empty when bad.
fn name(c: Result<&CStr, std::ffi::FromBytesUntilNulError>) -> String {
    c.map(|c| c.to_string_lossy().into_owned()).unwrap_or_default()
}

/// The file a loaded address belongs to.
pub fn mapped_file(address: usize) -> Option<PathBuf> {
    let maps = std::fs::read_to_string("/proc/self/maps").ok()?;
    crate::manifests::vulkan::library_containing(&maps, address)
}

/// Loads `libvulkan.so.1`, makes an instance with no layers and no extensions, and reads every
/// physical device. Err: no loader at all.
pub fn probe() -> Result<VulkanFacts, String> {
    // SAFETY: loading the system's Vulkan loader runs its initialisers, which is what every
    // Vulkan app does; the `Entry` keeps the library loaded while it is used.
    let entry = unsafe { ash::Entry::load() }.map_err(|e| e.to_string())?;
    let mut facts = VulkanFacts { loader: mapped_file(entry.static_fn().get_instance_proc_addr as usize), ..Default::default() };
    // SAFETY: a global command of a loaded loader.
    facts.instance_version = match unsafe { entry.try_enumerate_instance_version() } {
        Ok(Some(v)) => v,
        _ => vk::API_VERSION_1_0,
    };
    // SAFETY: a global command of a loaded loader.
    if let Ok(layers) = unsafe { entry.enumerate_instance_layer_properties() } {
        facts.layers = layers.iter().map(|l| name(l.layer_name_as_c_str())).collect();
    }
    let api_version = facts.instance_version.min(vk::API_VERSION_1_3);
    let app = vk::ApplicationInfo::default().application_name(c"stereoshim-doctor").api_version(api_version);
    let info = vk::InstanceCreateInfo::default().application_info(&app);
    // SAFETY: a valid create info with no layers and no extensions.
    let instance = match unsafe { entry.create_instance(&info, None) } {
        Ok(i) => i,
        Err(e) => {
            facts.instance_error = Some(format!("vkCreateInstance: {e:?}"));
            return Ok(facts);
        }
    };
    // SAFETY: the instance just created.
    match unsafe { instance.enumerate_physical_devices() } {
        Ok(pds) => facts.devices = pds.into_iter().map(|pd| device(&instance, api_version, pd)).collect(),
        Err(e) => facts.instance_error = Some(format!("vkEnumeratePhysicalDevices: {e:?}")),
    }
    // SAFETY: nothing made from the instance is alive.
    unsafe { instance.destroy_instance(None) };
    Ok(facts)
}

fn device(instance: &ash::Instance, instance_version: u32, pd: vk::PhysicalDevice) -> DeviceFacts {
    // SAFETY: `pd` is a physical device of `instance`, which is alive.
    let props = unsafe { instance.get_physical_device_properties(pd) };
    // SAFETY: `pd` of the live `instance`; no layer name (null), ash sizes the output array.
    let extensions: Vec<String> = unsafe { instance.enumerate_device_extension_properties(pd) }
        .unwrap_or_default()
        .iter()
        .map(|e| name(e.extension_name_as_c_str()))
        .collect();
    // SAFETY: `pd` of the live `instance`; the output struct is written by value.
    let core = unsafe { instance.get_physical_device_features(pd) };
    let has = |e: &str| extensions.iter().any(|x| x == e);
    let version = props.api_version.min(instance_version);
    let mut facts = DeviceFacts {
        name: name(props.device_name_as_c_str()),
        api_version: props.api_version,
        cpu: props.device_type == vk::PhysicalDeviceType::CPU,
        device_type: format!("{:?}", props.device_type),
        pipeline_statistics: core.pipeline_statistics_query != 0,
        ..Default::default()
    };
    // Features2 is core in 1.1; a 1.0 instance gets only the core features above.
    if version >= vk::API_VERSION_1_1 {
        let mut multiview = vk::PhysicalDeviceMultiviewFeatures::default();
        let mut dynamic = vk::PhysicalDeviceDynamicRenderingFeatures::default();
        let mut fsr = vk::PhysicalDeviceFragmentShadingRateFeaturesKHR::default();
        let with_dynamic = version >= vk::API_VERSION_1_3 || has("VK_KHR_dynamic_rendering");
        let with_fsr = has(FRAGMENT_SHADING_RATE);
        let mut f2 = vk::PhysicalDeviceFeatures2::default().push_next(&mut multiview);
        if with_dynamic {
            f2 = f2.push_next(&mut dynamic);
        }
        if with_fsr {
            f2 = f2.push_next(&mut fsr);
        }
        // SAFETY: `pd` of the live `instance`, whose version is at least 1.1 (checked above);
        // every chained struct belongs to that version or to an extension the device lists.
        unsafe { instance.get_physical_device_features2(pd, &mut f2) };
        facts.multiview = multiview.multiview != 0;
        facts.dynamic_rendering = with_dynamic && dynamic.dynamic_rendering != 0;
        if with_fsr {
            facts.fsr = Some(FsrSupport {
                pipeline: fsr.pipeline_fragment_shading_rate != 0,
                primitive: fsr.primitive_fragment_shading_rate != 0,
                attachment: fsr.attachment_fragment_shading_rate != 0,
            });
            let mut fsr_props = vk::PhysicalDeviceFragmentShadingRatePropertiesKHR::default();
            let mut p2 = vk::PhysicalDeviceProperties2::default().push_next(&mut fsr_props);
            // SAFETY: `pd` of the live `instance` (1.1 or later); the chained properties struct
            // belongs to VK_KHR_fragment_shading_rate, which the device lists.
            unsafe { instance.get_physical_device_properties2(pd, &mut p2) };
            let t = fsr_props.min_fragment_shading_rate_attachment_texel_size;
            facts.fsr_texel = (t.width, t.height);
            facts.fsr_layered = fsr_props.layered_shading_rate_attachments != 0;
        }
    }
    facts.extensions = extensions;
    facts
}

/// What loading a layer or runtime library showed.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LibraryFacts {
    /// The file the loader's `dlopen` mapped.
    pub file: Option<PathBuf>,
    /// Each symbol asked for, and whether the library exports it.
    pub exports: Vec<(String, bool)>,
    /// `vkNegotiateLoaderLayerInterfaceVersion` answered interface ≥ 2 with a
    /// `vkGetInstanceProcAddr` (None: not asked, or not exported).
    pub vk_negotiates: Option<bool>,
}

/// `dlopen`s `library` (a path, or a bare name found the way a loader finds it) and looks up
/// `symbols`; with `negotiate_vk`, calls the Vulkan negotiation entry point as the Vulkan loader
/// would. Err: the library does not load (missing, wrong architecture, missing dependencies).
pub fn load_library(library: &Path, symbols: &[&str], negotiate_vk: bool) -> Result<LibraryFacts, String> {
    // SAFETY: loading a layer or runtime library runs its initialisers, exactly as the loaders do
    // in every app; stereoshim's own library has none. The handle outlives every use below.
    let lib = unsafe { libloading::Library::new(library) }.map_err(|e| e.to_string())?;
    let mut facts = LibraryFacts::default();
    for name in symbols {
        // SAFETY: only the symbol's address is read, never called through this type.
        let sym = unsafe { lib.get::<*const c_void>(name.as_bytes()) };
        if let (Ok(s), None) = (&sym, &facts.file) {
            facts.file = mapped_file(**s as usize);
        }
        facts.exports.push((name.to_string(), sym.is_ok()));
    }
    if negotiate_vk {
        type Negotiate = unsafe extern "system" fn(*mut super::loader::NegotiateLayerInterface) -> vk::Result;
        // SAFETY: the loader interface gives this symbol this signature (vk_layer.h).
        if let Ok(f) = unsafe { lib.get::<Negotiate>(crate::manifests::VK_NEGOTIATE.as_bytes()) } {
            let mut v = super::loader::NegotiateLayerInterface {
                s_type: super::loader::LAYER_NEGOTIATE_INTERFACE_STRUCT,
                p_next: std::ptr::null_mut(),
                loader_layer_interface_version: super::loader::LAYER_INTERFACE_VERSION,
                pfn_get_instance_proc_addr: None,
                pfn_get_device_proc_addr: None,
                pfn_get_physical_device_proc_addr: None,
            };
            // SAFETY: a valid, writable struct as the loader passes it; negotiation only fills it.
            let r = unsafe { f(&mut v) };
            facts.vk_negotiates = Some(r == vk::Result::SUCCESS && v.loader_layer_interface_version >= 2 && v.pfn_get_instance_proc_addr.is_some());
        }
    }
    // Kept loaded: a runtime or layer may have registered thread-local destructors or atexit
    // handlers that must not outlive its code (the loaders never unload them mid-process either).
    std::mem::forget(lib);
    Ok(facts)
}
