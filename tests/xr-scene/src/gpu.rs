//! Vulkan instance and device creation, through the runtime (XR_KHR_vulkan_enable2) or by the app
//! itself with the runtime's extension lists (XR_KHR_vulkan_enable), plus the validation messenger.

use crate::cli::{Layout, Options, Rendering, VulkanApi, VulkanPath};
use crate::error::{fail, Ctx, Error, Result};
use ash::vk::{self, Handle};
use std::ffi::{c_void, CStr, CString};
use std::sync::atomic::{AtomicU64, Ordering};

const VALIDATION_LAYER: &CStr = c"VK_LAYER_KHRONOS_validation";

// The app links the Vulkan loader the way C and C++ apps do: `libvulkan.so.1` is a DT_NEEDED of
// the executable and `vkGetInstanceProcAddr` is bound by the dynamic linker into the global
// scope, where a layer exporting the same name could interpose on it (or be interposed on). This is
// what ash's `linked` feature does; it is declared here instead because Cargo unifies features
// across the workspace, so `ash/linked` would also link the loader into libstereoshim.so and the
// mock runtime, and because `-lvulkan` needs the unversioned development symlink (libvulkan-dev)
// while `+verbatim` names the runtime library itself.
#[link(name = "libvulkan.so.1", kind = "dylib", modifiers = "+verbatim")]
extern "system" {
    fn vkGetInstanceProcAddr(instance: vk::Instance, name: *const std::ffi::c_char) -> vk::PFN_vkVoidFunction;
}

/// `vk::make_api_version(0, 1, minor, 0)` of the app's `--vulkan-api`.
pub fn api_version(api: VulkanApi) -> u32 {
    vk::make_api_version(0, 1, api.minor(), 0)
}

/// Validation errors seen so far, from any thread (the runtime's own Vulkan work included).
static VALIDATION_ERRORS: AtomicU64 = AtomicU64::new(0);

pub fn validation_error_count() -> u64 {
    VALIDATION_ERRORS.load(Ordering::SeqCst)
}

unsafe extern "system" fn debug_callback(
    severity: vk::DebugUtilsMessageSeverityFlagsEXT,
    _types: vk::DebugUtilsMessageTypeFlagsEXT,
    data: *const vk::DebugUtilsMessengerCallbackDataEXT<'_>,
    _user: *mut c_void,
) -> vk::Bool32 {
    // SAFETY: the validation layer passes a valid callback-data struct whose p_message, when not
    // null, is a NUL-terminated string living for the duration of the call.
    let msg = unsafe {
        data.as_ref()
            .filter(|d| !d.p_message.is_null())
            .map(|d| CStr::from_ptr(d.p_message).to_string_lossy().into_owned())
            .unwrap_or_default()
    };
    if severity.contains(vk::DebugUtilsMessageSeverityFlagsEXT::ERROR) {
        VALIDATION_ERRORS.fetch_add(1, Ordering::SeqCst);
        eprintln!("[vulkan validation error] {msg}");
    } else {
        eprintln!("[vulkan validation warning] {msg}");
    }
    vk::FALSE
}

/// Vulkan functions whose entry points depend on the device's API version.
pub enum DynamicRendering {
    Core,
    Khr(ash::khr::dynamic_rendering::Device),
}

pub enum RenderPass2 {
    Core,
    Khr(ash::khr::create_renderpass2::Device),
}

pub struct Gpu {
    pub entry: ash::Entry,
    pub instance: ash::Instance,
    debug: Option<(ash::ext::debug_utils::Instance, vk::DebugUtilsMessengerEXT)>,
    pub physical: vk::PhysicalDevice,
    pub device: ash::Device,
    pub queue_family: u32,
    pub queue: vk::Queue,
    pub props: vk::PhysicalDeviceProperties,
    pub mem_props: vk::PhysicalDeviceMemoryProperties,
    pub timestamp_valid_bits: u32,
    /// `--submit2`: frames go down with vkQueueSubmit2 (synchronization2 enabled).
    pub submit2: bool,
    pub dynamic_rendering: Option<DynamicRendering>,
    pub render_pass2: Option<RenderPass2>,
}

fn split_ext_list(list: &str) -> Vec<CString> {
    list.split_whitespace().map(|s| CString::new(s).expect("extension name")).collect()
}

fn push_unique(list: &mut Vec<CString>, name: &CStr) {
    if !list.iter().any(|e| e.as_c_str() == name) {
        list.push(name.to_owned());
    }
}

impl Gpu {
    /// The graphics binding of a session on this instance, device and queue (queue 0 of the
    /// graphics family).
    pub fn session_binding(&self) -> openxr::vulkan::SessionCreateInfo {
        openxr::vulkan::SessionCreateInfo {
            instance: self.instance.handle().as_raw() as _,
            physical_device: self.physical.as_raw() as _,
            device: self.device.handle().as_raw() as _,
            queue_family_index: self.queue_family,
            queue_index: 0,
        }
    }

    pub fn new(opts: &Options, xr: &openxr::Instance, system: openxr::SystemId) -> Result<Gpu> {
        // The binding extensions require the requirements query before anything else.
        let reqs = xr
            .graphics_requirements::<openxr::Vulkan>(system)
            .ctx("xrGetVulkanGraphicsRequirements(2)KHR")?;
        let want = openxr::Version::new(1, opts.vulkan_api.minor() as u16, 0);
        if reqs.min_api_version_supported > want {
            return fail(format!(
                "runtime needs Vulkan {} or newer; this app asks for {want} (--vulkan-api)",
                reqs.min_api_version_supported
            ));
        }

        // SAFETY: vkGetInstanceProcAddr is the linked loader's (see its declaration above), which
        // stays loaded for the whole process and follows Vulkan 1.0's semantics.
        let entry = unsafe { ash::Entry::from_static_fn(ash::StaticFn { get_instance_proc_addr: vkGetInstanceProcAddr }) };

        let mut layers: Vec<*const i8> = Vec::new();
        let mut instance_exts: Vec<CString> = Vec::new();
        if opts.validation {
            // SAFETY: plain enumeration call.
            let available = unsafe { entry.enumerate_instance_layer_properties() }
                .ctx("vkEnumerateInstanceLayerProperties")?;
            if !available.iter().any(|l| l.layer_name_as_c_str() == Ok(VALIDATION_LAYER)) {
                return fail("--validation: VK_LAYER_KHRONOS_validation is not installed (apt-get install vulkan-validationlayers)");
            }
            layers.push(VALIDATION_LAYER.as_ptr());
            push_unique(&mut instance_exts, ash::ext::debug_utils::NAME);
            // VkValidationFeaturesEXT (to turn on synchronization validation) belongs to this
            // extension, which the layer itself provides.
            // SAFETY: plain enumeration call.
            let layer_exts = unsafe { entry.enumerate_instance_extension_properties(Some(VALIDATION_LAYER)) }
                .ctx("vkEnumerateInstanceExtensionProperties(validation layer)")?;
            if !layer_exts.iter().any(|e| e.extension_name_as_c_str() == Ok(ash::ext::validation_features::NAME)) {
                return fail("--validation: the validation layer lacks VK_EXT_validation_features");
            }
            push_unique(&mut instance_exts, ash::ext::validation_features::NAME);
        }
        let extra_layers: Vec<CString> = opts.vk_layers.iter().map(|n| CString::new(n.as_str())).collect::<std::result::Result<_, _>>().ctx("--vk-layer")?;
        if !extra_layers.is_empty() {
            // SAFETY: plain enumeration call.
            let available = unsafe { entry.enumerate_instance_layer_properties() }.ctx("vkEnumerateInstanceLayerProperties")?;
            for name in &extra_layers {
                if !available.iter().any(|l| l.layer_name_as_c_str() == Ok(name.as_c_str())) {
                    return fail(format!("--vk-layer: {name:?} is not installed"));
                }
                layers.push(name.as_ptr());
            }
        }
        if opts.vulkan == VulkanPath::Enable {
            let list = xr
                .vulkan_legacy_instance_extensions(system)
                .ctx("xrGetVulkanInstanceExtensionsKHR")?;
            for e in split_ext_list(&list) {
                push_unique(&mut instance_exts, &e);
            }
        }
        let ext_ptrs: Vec<*const i8> = instance_exts.iter().map(|e| e.as_ptr()).collect();

        let app_name = c"xr-scene";
        let app_info = vk::ApplicationInfo::default()
            .application_name(app_name)
            .application_version(1)
            .engine_name(app_name)
            .engine_version(1)
            .api_version(api_version(opts.vulkan_api));
        let enabled_validation = [vk::ValidationFeatureEnableEXT::SYNCHRONIZATION_VALIDATION];
        // The shader validation cache ($HOME/.cache/shader_validation_cache-*.bin) remembers a
        // module as valid by its hash alone: one validated on a Vulkan 1.3 device would then pass
        // unchecked on a 1.0 device (SPIR-V 1.3 on Vulkan 1.0), depending on earlier runs.
        let disabled_validation = [vk::ValidationFeatureDisableEXT::SHADER_VALIDATION_CACHE];
        let mut validation_features = vk::ValidationFeaturesEXT::default()
            .enabled_validation_features(&enabled_validation)
            .disabled_validation_features(&disabled_validation);
        let mut messenger_info = vk::DebugUtilsMessengerCreateInfoEXT::default()
            .message_severity(
                vk::DebugUtilsMessageSeverityFlagsEXT::ERROR | vk::DebugUtilsMessageSeverityFlagsEXT::WARNING,
            )
            .message_type(
                vk::DebugUtilsMessageTypeFlagsEXT::GENERAL
                    | vk::DebugUtilsMessageTypeFlagsEXT::VALIDATION
                    | vk::DebugUtilsMessageTypeFlagsEXT::PERFORMANCE,
            )
            .pfn_user_callback(Some(debug_callback));
        let mut instance_info = vk::InstanceCreateInfo::default()
            .application_info(&app_info)
            .enabled_layer_names(&layers)
            .enabled_extension_names(&ext_ptrs);
        if opts.validation {
            // Chained so that instance creation and destruction are validated as well.
            instance_info = instance_info.push_next(&mut messenger_info).push_next(&mut validation_features);
        }

        let gipa = entry.static_fn().get_instance_proc_addr;
        let instance = match opts.vulkan {
            VulkanPath::Enable2 => {
                // SAFETY: the create info and everything it points to outlive the call; the
                // function pointer is the loader's vkGetInstanceProcAddr with the matching ABI.
                let raw = unsafe {
                    xr.create_vulkan_instance(
                        system,
                        std::mem::transmute::<vk::PFN_vkGetInstanceProcAddr, openxr::sys::platform::VkGetInstanceProcAddr>(gipa),
                        &instance_info as *const _ as *const _,
                    )
                }
                .ctx("xrCreateVulkanInstanceKHR")?
                .map_err(|r| Error(format!("xrCreateVulkanInstanceKHR: vkCreateInstance returned {:?}", vk::Result::from_raw(r))))?;
                // SAFETY: the runtime created this instance through our loader.
                unsafe { ash::Instance::load(entry.static_fn(), vk::Instance::from_raw(raw as u64)) }
            }
            VulkanPath::Enable => {
                // SAFETY: valid create info; see above.
                unsafe { entry.create_instance(&instance_info, None) }.ctx("vkCreateInstance")?
            }
        };

        // From here on, a failure must destroy what exists: build the struct step by step.
        let mut gpu = Gpu {
            entry,
            instance,
            debug: None,
            physical: vk::PhysicalDevice::null(),
            device: unsafe_null_device(),
            queue_family: 0,
            queue: vk::Queue::null(),
            props: vk::PhysicalDeviceProperties::default(),
            mem_props: vk::PhysicalDeviceMemoryProperties::default(),
            timestamp_valid_bits: 0,
            submit2: false,
            dynamic_rendering: None,
            render_pass2: None,
        };
        if opts.validation {
            let du = ash::ext::debug_utils::Instance::new(&gpu.entry, &gpu.instance);
            let info = vk::DebugUtilsMessengerCreateInfoEXT { p_next: std::ptr::null(), ..messenger_info };
            // SAFETY: valid create info with a static callback.
            let m = unsafe { du.create_debug_utils_messenger(&info, None) }
                .ctx("vkCreateDebugUtilsMessengerEXT")?;
            gpu.debug = Some((du, m));
        }
        gpu.create_device(opts, xr, system)?;
        Ok(gpu)
    }

    fn create_device(&mut self, opts: &Options, xr: &openxr::Instance, system: openxr::SystemId) -> Result<()> {
        // SAFETY: the instance came from xrCreateVulkanInstanceKHR (enable2) or was created with the
        // runtime's required extensions (enable).
        let raw_pd = unsafe { xr.vulkan_graphics_device(system, self.instance.handle().as_raw() as _) }
            .ctx("xrGetVulkanGraphicsDevice(2)KHR")?;
        let physical = vk::PhysicalDevice::from_raw(raw_pd as u64);
        self.physical = physical;
        let inst = &self.instance;
        // SAFETY: physical is a valid handle of this instance.
        let props = unsafe { inst.get_physical_device_properties(physical) };
        // SAFETY: as above.
        self.mem_props = unsafe { inst.get_physical_device_memory_properties(physical) };
        self.props = props;
        // What the app may use: the lower of the version it asked for and the device's.
        let api = opts.vulkan_api;
        let dev_minor = if vk::api_version_major(props.api_version) > 1 { u32::MAX } else { vk::api_version_minor(props.api_version) };
        if dev_minor < api.minor() {
            return fail(format!(
                "the runtime's Vulkan device supports Vulkan 1.{dev_minor} only; --vulkan-api asks for 1.{}",
                api.minor()
            ));
        }
        let at_least = |minor: u32| api.minor() >= minor;

        // SAFETY: as above.
        let families = unsafe { inst.get_physical_device_queue_family_properties(physical) };
        let (family, fam_props) = families
            .iter()
            .enumerate()
            .find(|(_, f)| f.queue_flags.contains(vk::QueueFlags::GRAPHICS))
            .ok_or_else(|| Error("no graphics queue family".into()))?;
        self.queue_family = family as u32;
        self.timestamp_valid_bits = fam_props.timestamp_valid_bits;

        // SAFETY: as above.
        let available = unsafe { inst.enumerate_device_extension_properties(physical) }
            .ctx("vkEnumerateDeviceExtensionProperties")?;
        let has = |name: &CStr| available.iter().any(|e| e.extension_name_as_c_str() == Ok(name));
        let mut exts: Vec<CString> = Vec::new();
        if opts.vulkan == VulkanPath::Enable {
            let list = xr.vulkan_legacy_device_extensions(system).ctx("xrGetVulkanDeviceExtensionsKHR")?;
            for e in split_ext_list(&list) {
                push_unique(&mut exts, &e);
            }
        }
        // Below 1.2, render pass 2 is VK_KHR_create_renderpass2, which needs VK_KHR_multiview and
        // VK_KHR_maintenance2 (core in 1.1); VK_KHR_dynamic_rendering (1.1 only: refused at 1.0 by
        // the command line) also needs VK_KHR_depth_stencil_resolve.
        let need_rp2 = matches!(opts.rendering, Rendering::RenderPass2 | Rendering::Dynamic);
        if need_rp2 && !at_least(2) {
            if !at_least(1) {
                push_unique(&mut exts, ash::khr::multiview::NAME);
                push_unique(&mut exts, ash::khr::maintenance2::NAME);
            }
            push_unique(&mut exts, ash::khr::create_renderpass2::NAME);
            if opts.rendering == Rendering::Dynamic {
                push_unique(&mut exts, ash::khr::depth_stencil_resolve::NAME);
            }
        }
        if opts.rendering == Rendering::Dynamic && !at_least(3) {
            push_unique(&mut exts, ash::khr::dynamic_rendering::NAME);
        }
        // `--dynamic-state` / `--pipeline-library` (Vulkan 1.3, so extended dynamic state 1 and 2
        // are core): the extensions DXVK builds its pipelines with.
        if opts.dynamic_state {
            push_unique(&mut exts, ash::ext::extended_dynamic_state3::NAME);
            push_unique(&mut exts, ash::ext::vertex_input_dynamic_state::NAME);
        }
        if opts.shader_object {
            push_unique(&mut exts, ash::ext::shader_object::NAME);
        }
        if opts.pipeline_library {
            push_unique(&mut exts, ash::khr::pipeline_library::NAME);
            push_unique(&mut exts, ash::ext::graphics_pipeline_library::NAME);
        }
        for e in &exts {
            if !has(e) {
                return fail(format!("device extension {e:?} is not supported"));
            }
        }
        let ext_ptrs: Vec<*const i8> = exts.iter().map(|e| e.as_ptr()).collect();

        // Check, then enable, the features the app needs: through VkPhysicalDeviceFeatures2 and its
        // chain from 1.1 on, plain VkPhysicalDeviceFeatures at 1.0 (whose device has no multiview).
        let dynamic = opts.rendering == Rendering::Dynamic;
        if at_least(1) {
            let mut mv_q = vk::PhysicalDeviceMultiviewFeatures::default();
            let mut dr_q = vk::PhysicalDeviceDynamicRenderingFeatures::default();
            let mut s2_q = vk::PhysicalDeviceSynchronization2Features::default();
            let mut eds3_q = vk::PhysicalDeviceExtendedDynamicState3FeaturesEXT::default();
            let mut vi_q = vk::PhysicalDeviceVertexInputDynamicStateFeaturesEXT::default();
            let mut gpl_q = vk::PhysicalDeviceGraphicsPipelineLibraryFeaturesEXT::default();
            let mut so_q = vk::PhysicalDeviceShaderObjectFeaturesEXT::default();
            let mut f2_q = vk::PhysicalDeviceFeatures2::default().push_next(&mut mv_q);
            if dynamic {
                f2_q = f2_q.push_next(&mut dr_q);
            }
            if opts.submit2 {
                f2_q = f2_q.push_next(&mut s2_q);
            }
            if opts.dynamic_state {
                f2_q = f2_q.push_next(&mut eds3_q).push_next(&mut vi_q);
            }
            if opts.pipeline_library {
                f2_q = f2_q.push_next(&mut gpl_q);
            }
            if opts.shader_object {
                f2_q = f2_q.push_next(&mut so_q);
            }
            // SAFETY: valid chain of output structs; vkGetPhysicalDeviceFeatures2 is core in 1.1.
            unsafe { inst.get_physical_device_features2(physical, &mut f2_q) };
            if f2_q.features.fragment_stores_and_atomics == vk::FALSE {
                return fail("the device lacks fragmentStoresAndAtomics (needed for the shaded-fragment counter)");
            }
            if mv_q.multiview == vk::FALSE {
                return fail("the device lacks the multiview feature");
            }
            if dynamic && dr_q.dynamic_rendering == vk::FALSE {
                return fail("the device lacks dynamic rendering");
            }
            if opts.submit2 && s2_q.synchronization2 == vk::FALSE {
                return fail("the device lacks synchronization2 (--submit2)");
            }
            let e = &eds3_q;
            let eds3 = [
                e.extended_dynamic_state3_polygon_mode,
                e.extended_dynamic_state3_rasterization_samples,
                e.extended_dynamic_state3_sample_mask,
                e.extended_dynamic_state3_alpha_to_coverage_enable,
                e.extended_dynamic_state3_depth_clamp_enable,
                e.extended_dynamic_state3_color_blend_enable,
                e.extended_dynamic_state3_color_blend_equation,
                e.extended_dynamic_state3_color_write_mask,
            ];
            if opts.dynamic_state && (eds3.contains(&vk::FALSE) || vi_q.vertex_input_dynamic_state == vk::FALSE) {
                return fail("the device lacks extended dynamic state 3 or vertex input dynamic state (--dynamic-state)");
            }
            if opts.shader_object && so_q.shader_object == vk::FALSE {
                return fail("the device lacks shaderObject (--shader-object)");
            }
            if opts.pipeline_library && gpl_q.graphics_pipeline_library == vk::FALSE {
                return fail("the device lacks graphicsPipelineLibrary (--pipeline-library)");
            }
        } else {
            debug_assert!(opts.layout != Layout::Multiview && !dynamic, "refused by the command line");
            // SAFETY: valid physical device.
            let f = unsafe { inst.get_physical_device_features(physical) };
            if f.fragment_stores_and_atomics == vk::FALSE {
                return fail("the device lacks fragmentStoresAndAtomics (needed for the shaded-fragment counter)");
            }
        }

        let priorities = [1.0f32];
        let queue_info = [vk::DeviceQueueCreateInfo::default()
            .queue_family_index(self.queue_family)
            .queue_priorities(&priorities)];
        let features = vk::PhysicalDeviceFeatures::default().fragment_stores_and_atomics(true);
        let mut mv = vk::PhysicalDeviceMultiviewFeatures::default().multiview(true);
        let mut dr = vk::PhysicalDeviceDynamicRenderingFeatures::default().dynamic_rendering(true);
        let mut s2 = vk::PhysicalDeviceSynchronization2Features::default().synchronization2(true);
        let mut eds3 = vk::PhysicalDeviceExtendedDynamicState3FeaturesEXT::default()
            .extended_dynamic_state3_polygon_mode(true)
            .extended_dynamic_state3_rasterization_samples(true)
            .extended_dynamic_state3_sample_mask(true)
            .extended_dynamic_state3_alpha_to_coverage_enable(true)
            .extended_dynamic_state3_depth_clamp_enable(true)
            .extended_dynamic_state3_color_blend_enable(true)
            .extended_dynamic_state3_color_blend_equation(true)
            .extended_dynamic_state3_color_write_mask(true);
        let mut vi = vk::PhysicalDeviceVertexInputDynamicStateFeaturesEXT::default().vertex_input_dynamic_state(true);
        let mut gpl = vk::PhysicalDeviceGraphicsPipelineLibraryFeaturesEXT::default().graphics_pipeline_library(true);
        let mut so = vk::PhysicalDeviceShaderObjectFeaturesEXT::default().shader_object(true);
        let mut f2 = vk::PhysicalDeviceFeatures2::default().features(features).push_next(&mut mv);
        if dynamic {
            f2 = f2.push_next(&mut dr);
        }
        if opts.submit2 {
            f2 = f2.push_next(&mut s2);
        }
        if opts.dynamic_state {
            f2 = f2.push_next(&mut eds3).push_next(&mut vi);
        }
        if opts.pipeline_library {
            f2 = f2.push_next(&mut gpl);
        }
        if opts.shader_object {
            f2 = f2.push_next(&mut so);
        }
        self.submit2 = opts.submit2;
        let mut device_info = vk::DeviceCreateInfo::default()
            .queue_create_infos(&queue_info)
            .enabled_extension_names(&ext_ptrs);
        if at_least(1) {
            device_info = device_info.push_next(&mut f2);
        } else {
            device_info = device_info.enabled_features(&features);
        }

        let device = match opts.vulkan {
            VulkanPath::Enable2 => {
                let gipa = self.entry.static_fn().get_instance_proc_addr;
                // SAFETY: the create info outlives the call; the physical device is the one the
                // runtime chose; gipa has the matching ABI.
                let raw = unsafe {
                    xr.create_vulkan_device(
                        system,
                        std::mem::transmute::<vk::PFN_vkGetInstanceProcAddr, openxr::sys::platform::VkGetInstanceProcAddr>(gipa),
                        physical.as_raw() as _,
                        &device_info as *const _ as *const _,
                    )
                }
                .ctx("xrCreateVulkanDeviceKHR")?
                .map_err(|r| Error(format!("xrCreateVulkanDeviceKHR: vkCreateDevice returned {:?}", vk::Result::from_raw(r))))?;
                // SAFETY: the runtime created this device through our loader, on our instance.
                unsafe { ash::Device::load(self.instance.fp_v1_0(), vk::Device::from_raw(raw as u64)) }
            }
            VulkanPath::Enable => {
                // SAFETY: valid create info.
                unsafe { self.instance.create_device(physical, &device_info, None) }.ctx("vkCreateDevice")?
            }
        };
        // SAFETY: family/index were requested in the create info.
        self.queue = unsafe { device.get_device_queue(self.queue_family, 0) };
        // The 2-variants' entry points: core ones from 1.2 / 1.3, else the extensions'.
        self.dynamic_rendering = match (opts.rendering, at_least(3)) {
            (Rendering::Dynamic, true) => Some(DynamicRendering::Core),
            (Rendering::Dynamic, false) => {
                Some(DynamicRendering::Khr(ash::khr::dynamic_rendering::Device::new(&self.instance, &device)))
            }
            _ => None,
        };
        self.render_pass2 = match (opts.rendering, at_least(2)) {
            (Rendering::RenderPass2, true) => Some(RenderPass2::Core),
            (Rendering::RenderPass2, false) => {
                Some(RenderPass2::Khr(ash::khr::create_renderpass2::Device::new(&self.instance, &device)))
            }
            _ => None,
        };
        self.device = device;
        Ok(())
    }

    pub fn has_device(&self) -> bool {
        self.device.handle() != vk::Device::null()
    }

    pub fn memory_type(&self, bits: u32, flags: vk::MemoryPropertyFlags) -> Result<u32> {
        (0..self.mem_props.memory_type_count)
            .find(|&i| bits & (1 << i) != 0 && self.mem_props.memory_types[i as usize].property_flags.contains(flags))
            .ok_or_else(|| Error(format!("no memory type with {flags:?} in {bits:#b}")))
    }

    pub fn format_supports(&self, format: vk::Format, features: vk::FormatFeatureFlags) -> bool {
        // SAFETY: valid physical device.
        let p = unsafe { self.instance.get_physical_device_format_properties(self.physical, format) };
        p.optimal_tiling_features.contains(features)
    }
}

/// A placeholder device table whose handle is null, so `Drop` can tell "no device yet".
fn unsafe_null_device() -> ash::Device {
    // SAFETY: every function pointer of a device loaded from a null handle is a stub that panics
    // if called; we never call through it because `has_device` is checked first.
    unsafe {
        ash::Device::load_with(|_| std::ptr::null(), vk::Device::null())
    }
}

impl Drop for Gpu {
    fn drop(&mut self) {
        // SAFETY: everything created on the device was destroyed by its owners (which are dropped
        // before the Gpu); the messenger goes last-but-one so destruction messages still arrive.
        unsafe {
            if self.has_device() {
                let _ = self.device.device_wait_idle();
                self.device.destroy_device(None);
            }
            if let Some((du, m)) = self.debug.take() {
                du.destroy_debug_utils_messenger(m, None);
            }
            self.instance.destroy_instance(None);
        }
    }
}
