//! Instance and device chain creation and destruction: the loader's link info is advanced, the next
//! layer called, and only on success is the instance's or device's state recorded (ash tables
//! loaded through the next layer). `vkCreateDevice` is the one hook that may change what reaches
//! the driver: the extensions and features `track::device_ext` decides (fragment shading rate and
//! what it depends on), retried exactly as the app asked if the driver refuses them; the device's
//! capabilities (`track::caps`) are recorded for every object the layer later creates on it.

use super::{check_fault, instance_of, layer, loader, InstanceState};
use crate::plugin::vk::{convert, dispatch_key, DeviceState, ExtFns};
use crate::core::guard::{self, PassThrough};
use crate::track::{caps, device_ext};
use ash::vk;
use std::ffi::{c_char, c_void, CStr};
use std::sync::Arc;
// ---------------------------------------------------------------------------------------------
// Instance chain

/// The loader's link info in a create info's chain (function `VK_LAYER_LINK_INFO`).
///
/// # Safety
/// `p_next` must be a valid chain.
unsafe fn link_info<T>(mut p_next: *const c_void, s_type: vk::StructureType, function_of: impl Fn(*const T) -> loader::LayerFunction) -> Option<*mut T> {
    while !p_next.is_null() {
        // SAFETY: every struct in a valid chain starts with sType, pNext.
        let base = unsafe { &*(p_next as *const vk::BaseInStructure<'_>) };
        if base.s_type == s_type && function_of(p_next as *const T) == loader::LayerFunction::LINK_INFO {
            // The loader owns this struct and expects the layer to advance it in place.
            return Some(p_next as *mut T);
        }
        p_next = base.p_next as *const c_void;
    }
    None
}

/// The loader's `pfnSetDeviceLoaderData` from the `VK_LOADER_DATA_CALLBACK` struct of a device
/// create info chain: layers call it on dispatchable objects they create themselves.
///
/// # Safety
/// `p_next` must be a valid structure chain.
unsafe fn loader_data_callback(mut p_next: *const c_void) -> Option<crate::plugin::vk::PfnSetDeviceLoaderData> {
    while !p_next.is_null() {
        // SAFETY: every struct in a valid chain starts with sType, pNext.
        let base = unsafe { &*(p_next as *const vk::BaseInStructure<'_>) };
        if base.s_type == loader::LOADER_DEVICE_CREATE_INFO {
            // SAFETY: the loader's struct (its sType); the union holds the callback when
            // `function` says so.
            let info = unsafe { &*(p_next as *const loader::LayerDeviceCreateInfo) };
            if info.function == loader::LayerFunction::LOADER_DATA_CALLBACK && !info.p_layer_info.is_null() {
                // SAFETY: the union member is `PFN_vkSetDeviceLoaderData` for this function value.
                return Some(unsafe { std::mem::transmute::<*mut loader::LayerDeviceLink, crate::plugin::vk::PfnSetDeviceLoaderData>(info.p_layer_info) });
            }
        }
        p_next = base.p_next as *const c_void;
    }
    None
}

fn resolve_config() -> Arc<crate::core::config::Config> {
    if let Some(c) = crate::bridge::shared().config() {
        return c;
    }
    let exe = std::env::current_exe().ok().and_then(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()));
    let names: Vec<&str> = exe.as_deref().into_iter().collect();
    let (config, diagnostics) = crate::core::config::load(crate::registry::keys(), &names);
    crate::core::log::init(config.choice("log.level"));
    for d in diagnostics {
        tracing::warn!("config: {d}");
    }
    Arc::new(config)
}

pub(super) unsafe extern "system" fn create_instance(
    ci: *const vk::InstanceCreateInfo<'_>,
    allocator: *const vk::AllocationCallbacks<'_>,
    p_instance: *mut vk::Instance,
) -> vk::Result {
    guard::catch("vkCreateInstance", vk::Result::ERROR_INITIALIZATION_FAILED, || {
        // SAFETY: the loader passes a valid create info.
        let ci_ref = unsafe { &*ci };
        // SAFETY: a valid chain; the function field is read from the loader's struct.
        let Some(chain) = (unsafe {
            link_info::<loader::LayerInstanceCreateInfo>(ci_ref.p_next, loader::LOADER_INSTANCE_CREATE_INFO, |p| (*p).function)
        }) else {
            return vk::Result::ERROR_INITIALIZATION_FAILED;
        };
        // SAFETY: the loader's struct; its link list is valid for this call.
        let Some(link) = (unsafe { (*chain).p_layer_info.as_ref() }) else {
            return vk::Result::ERROR_INITIALIZATION_FAILED;
        };
        let next_gipa = link.pfn_next_get_instance_proc_addr;
        // SAFETY: as the loader documents: advance the link for the next layer before calling down.
        unsafe { (*chain).p_layer_info = link.p_next };
        // SAFETY: the next layer's gipa with a null instance, for a global command.
        let Some(create) = (unsafe { next_gipa(vk::Instance::null(), c"vkCreateInstance".as_ptr()) }) else {
            return vk::Result::ERROR_INITIALIZATION_FAILED;
        };
        // SAFETY: the pointer returned for "vkCreateInstance" has that command's type.
        let create: vk::PFN_vkCreateInstance = unsafe { std::mem::transmute(create) };
        let config = resolve_config();
        let pass_through = Arc::new(PassThrough::new(!config.enabled()));
        // SAFETY: forwarding the app's arguments unchanged.
        let next = || unsafe { create(ci, allocator, p_instance) };
        let r = guard::run(
            "vkCreateInstance",
            &pass_through,
            |down| {
                check_fault(&config, "vkCreateInstance")?;
                Ok(down.call(next))
            },
            next,
        );
        if r != vk::Result::SUCCESS {
            return r;
        }
        // The dispatch bookkeeping is recorded even in pass-through: without it no later call of
        // this instance could reach the next layer.
        // SAFETY: on success the driver wrote the instance.
        let instance = unsafe { *p_instance };
        // SAFETY: the next layer's gipa for the instance it just created.
        let fns = unsafe { ash::Instance::load_with(|n| std::mem::transmute(next_gipa(instance, n.as_ptr())), instance) };
        // SAFETY: the app's create info is still valid during this call.
        let (api_version, extensions) = unsafe {
            (
                ci_ref.p_application_info.as_ref().map_or(vk::API_VERSION_1_0, |a| a.api_version.max(vk::API_VERSION_1_0)),
                convert::names(ci_ref.pp_enabled_extension_names, ci_ref.enabled_extension_count),
            )
        };
        // SAFETY: the application info and its engine name, when given, are valid during this call.
        let engine = unsafe { ci_ref.p_application_info.as_ref().and_then(|a| a.p_engine_name.as_ref().map(|_| std::ffi::CStr::from_ptr(a.p_engine_name).to_string_lossy().into_owned())) };
        tracing::info!(api_version = %version(api_version), pass_through = pass_through.is_on(), engine = engine.as_deref().unwrap_or("(none)"), "vulkan instance created");
        let state = InstanceState { handle: instance, next_gipa, fns, api_version, extensions, pass_through, config, engine };
        layer().instances.insert(dispatch_key(instance), Arc::new(state));
        r
    })
}

fn version(v: u32) -> String {
    format!("{}.{}.{}", vk::api_version_major(v), vk::api_version_minor(v), vk::api_version_patch(v))
}

pub(super) unsafe extern "system" fn destroy_instance(instance: vk::Instance, allocator: *const vk::AllocationCallbacks<'_>) {
    guard::catch("vkDestroyInstance", (), || {
        let key = dispatch_key(instance);
        let Some(state) = layer().instances.get(key) else { return };
        // SAFETY: forwarding the app's arguments to the next layer.
        unsafe { (state.fns.fp_v1_0().destroy_instance)(instance, allocator) };
        // Only after the call down: the next layer may still call back during destruction.
        // `instance` is freed memory now: only the key read above is used (issue 23).
        layer().instances.remove(key);
        // What the layer still keys by dispatch key: an app that destroyed its devices before
        // its last instance leaves 0 of each (tests/hardening/lifecycle.rs checks every teardown order).
        tracing::info!(
            "vulkan layer tables: instances={} devices={} own_tables={}",
            layer().instances.len(),
            crate::plugin::vk::devices().len(),
            crate::plugin::vk::own::registered()
        );
    })
}

// ---------------------------------------------------------------------------------------------
// Device chain

/// What the FSR decision needs to know about a physical device, queried from the next layer.
fn device_inputs(inst: &InstanceState, pd: vk::PhysicalDevice) -> (Vec<String>, u32, Option<device_ext::FsrSupport>) {
    // SAFETY: valid physical device of this instance; the next layer's instance functions.
    let available = unsafe { inst.fns.enumerate_device_extension_properties(pd) }
        .unwrap_or_default()
        .iter()
        .filter_map(|e| e.extension_name_as_c_str().ok().map(|n| n.to_string_lossy().into_owned()))
        .collect::<Vec<_>>();
    // SAFETY: as above.
    let props = unsafe { inst.fns.get_physical_device_properties(pd) };
    let api_version = props.api_version.min(inst.api_version);
    let query = available.iter().any(|e| e == device_ext::FRAGMENT_SHADING_RATE).then(|| properties2_fns(inst, pd)).flatten();
    let fsr = if let Some((features2, _)) = query {
        let mut f = vk::PhysicalDeviceFragmentShadingRateFeaturesKHR::default();
        let mut f2 = vk::PhysicalDeviceFeatures2::default().push_next(&mut f);
        // SAFETY: a physical device of this instance; a correctly chained output struct.
        unsafe { features2(pd, &mut f2) };
        Some(device_ext::FsrSupport {
            pipeline: f.pipeline_fragment_shading_rate != 0,
            primitive: f.primitive_fragment_shading_rate != 0,
            attachment: f.attachment_fragment_shading_rate != 0,
        })
    } else {
        None
    };
    (available, api_version, fsr)
}

/// `vkGetPhysicalDeviceFeatures2` / `vkGetPhysicalDeviceProperties2` as this instance may call
/// them: the core commands on a 1.1 instance and device, the KHR commands where the instance
/// enabled `VK_KHR_get_physical_device_properties2` (a Vulkan 1.0 app), else none.
fn properties2_fns(
    inst: &InstanceState,
    pd: vk::PhysicalDevice,
) -> Option<(vk::PFN_vkGetPhysicalDeviceFeatures2, vk::PFN_vkGetPhysicalDeviceProperties2)> {
    // SAFETY: a physical device of this instance; the next layer's instance functions.
    let device_version = unsafe { inst.fns.get_physical_device_properties(pd) }.api_version;
    if inst.api_version.min(device_version) >= vk::API_VERSION_1_1 {
        let f = inst.fns.fp_v1_1();
        return Some((f.get_physical_device_features2, f.get_physical_device_properties2));
    }
    if !inst.extensions.iter().any(|e| e == "VK_KHR_get_physical_device_properties2") {
        return None;
    }
    // SAFETY: the next layer's gipa for our instance, with NUL-terminated names.
    let (f, p) = unsafe {
        (
            (inst.next_gipa)(inst.handle, c"vkGetPhysicalDeviceFeatures2KHR".as_ptr())?,
            (inst.next_gipa)(inst.handle, c"vkGetPhysicalDeviceProperties2KHR".as_ptr())?,
        )
    };
    // SAFETY: the pointers returned for these names have the (alias-identical) core types.
    let features2 = unsafe { std::mem::transmute::<unsafe extern "system" fn(), vk::PFN_vkGetPhysicalDeviceFeatures2>(f) };
    // SAFETY: as above.
    let properties2 = unsafe { std::mem::transmute::<unsafe extern "system" fn(), vk::PFN_vkGetPhysicalDeviceProperties2>(p) };
    Some((features2, properties2))
}

/// A copy of the app's `VkDeviceCreateInfo` with our extensions and features; owns everything the
/// copy points to that is not the app's.
struct ModifiedDeviceCreateInfo {
    ci: vk::DeviceCreateInfo<'static>,
    _names: Vec<*const c_char>,
    _fsr: Box<vk::PhysicalDeviceFragmentShadingRateFeaturesKHR<'static>>,
    _copies: Vec<Box<[u64]>>,
}

/// Size of the structs that may precede an app-chained shading-rate struct (and must then be
/// copied to splice in our copy of it). Unknown ones make us decline instead of guessing.
fn chained_struct_size(s_type: vk::StructureType) -> Option<usize> {
    use std::mem::size_of;
    use vk::StructureType as S;
    Some(match s_type {
        loader::LOADER_DEVICE_CREATE_INFO => size_of::<loader::LayerDeviceCreateInfo>(),
        S::PHYSICAL_DEVICE_FEATURES_2 => size_of::<vk::PhysicalDeviceFeatures2<'_>>(),
        S::PHYSICAL_DEVICE_VULKAN_1_1_FEATURES => size_of::<vk::PhysicalDeviceVulkan11Features<'_>>(),
        S::PHYSICAL_DEVICE_VULKAN_1_2_FEATURES => size_of::<vk::PhysicalDeviceVulkan12Features<'_>>(),
        S::PHYSICAL_DEVICE_VULKAN_1_3_FEATURES => size_of::<vk::PhysicalDeviceVulkan13Features<'_>>(),
        S::PHYSICAL_DEVICE_MULTIVIEW_FEATURES => size_of::<vk::PhysicalDeviceMultiviewFeatures<'_>>(),
        S::PHYSICAL_DEVICE_DYNAMIC_RENDERING_FEATURES => size_of::<vk::PhysicalDeviceDynamicRenderingFeatures<'_>>(),
        S::PHYSICAL_DEVICE_SYNCHRONIZATION_2_FEATURES => size_of::<vk::PhysicalDeviceSynchronization2Features<'_>>(),
        S::PHYSICAL_DEVICE_IMAGELESS_FRAMEBUFFER_FEATURES => size_of::<vk::PhysicalDeviceImagelessFramebufferFeatures<'_>>(),
        S::PHYSICAL_DEVICE_TIMELINE_SEMAPHORE_FEATURES => size_of::<vk::PhysicalDeviceTimelineSemaphoreFeatures<'_>>(),
        S::PHYSICAL_DEVICE_BUFFER_DEVICE_ADDRESS_FEATURES => size_of::<vk::PhysicalDeviceBufferDeviceAddressFeatures<'_>>(),
        S::PHYSICAL_DEVICE_DESCRIPTOR_INDEXING_FEATURES => size_of::<vk::PhysicalDeviceDescriptorIndexingFeatures<'_>>(),
        _ => return None,
    })
}

/// Builds the modified create info, or explains why it cannot.
///
/// # Safety
/// `ci` must be a valid `VkDeviceCreateInfo` whose chain stays valid while the result is used.
unsafe fn modify_device_create_info(ci: &vk::DeviceCreateInfo<'_>, d: &device_ext::Decision) -> Result<ModifiedDeviceCreateInfo, String> {
    // SAFETY: lifetimes are erased: the copy lives only during the call down, within the app's call.
    let mut new: vk::DeviceCreateInfo<'static> = unsafe { std::mem::transmute(*ci) };
    // SAFETY: the app's names array is valid with its count.
    let mut names: Vec<*const c_char> = unsafe { convert::slice(ci.pp_enabled_extension_names, ci.enabled_extension_count) }.to_vec();
    for e in &d.add_extensions {
        names.push(match *e {
            device_ext::FRAGMENT_SHADING_RATE => c"VK_KHR_fragment_shading_rate".as_ptr(),
            device_ext::CREATE_RENDERPASS_2 => c"VK_KHR_create_renderpass2".as_ptr(),
            "VK_KHR_multiview" => c"VK_KHR_multiview".as_ptr(),
            "VK_KHR_maintenance2" => c"VK_KHR_maintenance2".as_ptr(),
            other => return Err(format!("no static name for {other}")),
        });
    }
    new.enabled_extension_count = names.len() as u32;
    new.pp_enabled_extension_names = names.as_ptr();
    let mut copies: Vec<Box<[u64]>> = Vec::new();
    let enable = d.enable_fsr.unwrap_or_default();
    let set = |f: &mut vk::PhysicalDeviceFragmentShadingRateFeaturesKHR<'_>| {
        f.attachment_fragment_shading_rate |= enable.attachment as u32;
        f.pipeline_fragment_shading_rate |= enable.pipeline as u32;
    };
    // SAFETY: a valid chain.
    let app_fsr = unsafe {
        convert::find_in_chain::<vk::PhysicalDeviceFragmentShadingRateFeaturesKHR<'_>>(
            ci.p_next,
            vk::StructureType::PHYSICAL_DEVICE_FRAGMENT_SHADING_RATE_FEATURES_KHR,
        )
    };
    let mut fsr = Box::new(vk::PhysicalDeviceFragmentShadingRateFeaturesKHR::default());
    match app_fsr {
        None => {
            // Ours goes first, the app's chain follows unchanged.
            set(&mut fsr);
            fsr.p_next = ci.p_next as *mut c_void;
            new.p_next = &*fsr as *const _ as *const c_void;
        }
        Some(app) => {
            // Replace the app's struct by a copy: copy every struct before it (their pNext must
            // change) and link the copies.
            // SAFETY: a valid struct of that type.
            *fsr = unsafe { std::mem::transmute::<vk::PhysicalDeviceFragmentShadingRateFeaturesKHR<'_>, vk::PhysicalDeviceFragmentShadingRateFeaturesKHR<'static>>(*app) };
            set(&mut fsr);
            let mut prev: *mut *const c_void = &mut new.p_next;
            let mut p = ci.p_next;
            while p != app as *const c_void {
                // SAFETY: a valid chain member.
                let base = unsafe { &*(p as *const vk::BaseInStructure<'_>) };
                let size = chained_struct_size(base.s_type).ok_or_else(|| format!("unknown struct {:?} precedes the app's shading-rate features", base.s_type))?;
                let mut copy = vec![0u64; size.div_ceil(8)].into_boxed_slice();
                // SAFETY: `size` bytes of a struct of that type, into a buffer at least as large and 8-aligned.
                unsafe { std::ptr::copy_nonoverlapping(p as *const u8, copy.as_mut_ptr() as *mut u8, size) };
                // SAFETY: `prev` points at the pNext of the previous copy (or of `new`).
                unsafe { *prev = copy.as_ptr() as *const c_void };
                let copy_base = copy.as_mut_ptr() as *mut vk::BaseOutStructure<'_>;
                // SAFETY: the copy starts with sType, pNext like every chained struct; the boxed
                // buffer does not move when the box is pushed.
                prev = unsafe { std::ptr::addr_of_mut!((*copy_base).p_next) } as *mut *const c_void;
                copies.push(copy);
                p = base.p_next as *const c_void;
            }
            // SAFETY: as above.
            unsafe { *prev = &*fsr as *const _ as *const c_void };
        }
    }
    Ok(ModifiedDeviceCreateInfo { ci: new, _names: names, _fsr: fsr, _copies: copies })
}

pub(super) unsafe extern "system" fn create_device(
    pd: vk::PhysicalDevice,
    ci: *const vk::DeviceCreateInfo<'_>,
    allocator: *const vk::AllocationCallbacks<'_>,
    p_device: *mut vk::Device,
) -> vk::Result {
    guard::catch("vkCreateDevice", vk::Result::ERROR_INITIALIZATION_FAILED, || {
        let Some(inst) = instance_of(pd) else {
            tracing::error!("vkCreateDevice for a physical device of an unknown instance");
            return vk::Result::ERROR_INITIALIZATION_FAILED;
        };
        let _span = tracing::debug_span!("vk", call = "vkCreateDevice").entered();
        // SAFETY: the loader passes a valid create info.
        let ci_ref = unsafe { &*ci };
        // SAFETY: a valid chain; the function field is read from the loader's struct.
        let Some(chain) = (unsafe {
            link_info::<loader::LayerDeviceCreateInfo>(ci_ref.p_next, loader::LOADER_DEVICE_CREATE_INFO, |p| (*p).function)
        }) else {
            return vk::Result::ERROR_INITIALIZATION_FAILED;
        };
        // SAFETY: the loader's struct; its link list is valid for this call.
        let Some(link) = (unsafe { (*chain).p_layer_info.as_ref() }) else {
            return vk::Result::ERROR_INITIALIZATION_FAILED;
        };
        let (next_gipa, next_gdpa, rest) = (link.pfn_next_get_instance_proc_addr, link.pfn_next_get_device_proc_addr, link.p_next);
        // SAFETY: as the loader documents: advance the link before calling down.
        unsafe { (*chain).p_layer_info = rest };
        // SAFETY: the next layer's gipa for our instance.
        let Some(create) = (unsafe { next_gipa(inst.handle, c"vkCreateDevice".as_ptr()) }) else {
            return vk::Result::ERROR_INITIALIZATION_FAILED;
        };
        // SAFETY: the pointer returned for "vkCreateDevice" has that command's type.
        let create: vk::PFN_vkCreateDevice = unsafe { std::mem::transmute(create) };
        // SAFETY: forwarding the app's arguments unchanged.
        let plain = || unsafe { create(pd, ci, allocator, p_device) };
        let mut decision = device_ext::Decision { reason: "pass-through".into(), ..Default::default() };
        // SAFETY: the loader's create info chain, valid for this call.
        let set_loader_data = unsafe { loader_data_callback(ci_ref.p_next) };
        let r = guard::run(
            "vkCreateDevice",
            &inst.pass_through,
            |down| {
                check_fault(&inst.config, "vkCreateDevice")?;
                let (available, api_version, fsr_support) = device_inputs(&inst, pd);
                // SAFETY: the app's names array is valid with its count.
                let requested = unsafe { convert::names(ci_ref.pp_enabled_extension_names, ci_ref.enabled_extension_count) };
                let has_props2 = inst.api_version >= vk::API_VERSION_1_1
                    || inst.extensions.iter().any(|e| e == "VK_KHR_get_physical_device_properties2");
                decision = device_ext::decide(&device_ext::Inputs {
                    available: &available,
                    requested: &requested,
                    api_version,
                    instance_has_properties2: has_props2,
                    fsr_mode: inst.config.choice("vulkan.fragment_shading_rate"),
                    feature_wants_fsr: device_ext::foveation_wants_fsr(inst.config.choice("foveation.method")),
                    fsr_support,
                });
                if decision.enable_fsr.is_none() {
                    return Ok(down.call(plain));
                }
                // SAFETY: the app's create info, valid during this call.
                let modified = match unsafe { modify_device_create_info(ci_ref, &decision) } {
                    Ok(m) => m,
                    Err(why) => {
                        decision = device_ext::Decision { reason: format!("fragment shading rate: not added: {why}"), ..Default::default() };
                        return Ok(down.call(plain));
                    }
                };
                // SAFETY: the modified copy points at the app's data and ours, all alive here.
                let r = down.call(|| unsafe { create(pd, &modified.ci, allocator, p_device) });
                if r == vk::Result::SUCCESS {
                    return Ok(r);
                }
                // Never break the app's device: retry exactly as the app asked, with the link
                // rewound to where the next layer expects it.
                tracing::warn!(?r, "vkCreateDevice failed with our additions; retrying without them");
                decision = device_ext::Decision { reason: format!("additions refused by the driver ({r:?})"), ..Default::default() };
                // SAFETY: the loader's struct, still valid.
                unsafe { (*chain).p_layer_info = rest };
                Ok(down.call(plain))
            },
            plain,
        );
        if r != vk::Result::SUCCESS {
            return r;
        }
        // SAFETY: on success the driver wrote the device.
        let device = unsafe { *p_device };
        // SAFETY: the next layer's gdpa for the device it just created.
        let next = unsafe { ash::Device::load_with(|n| crate::plugin::vk::device_proc(next_gdpa, device, n), device) };
        // SAFETY: as above.
        let (fns, own) = unsafe { crate::plugin::vk::own::register(device, &next, next_gdpa) };
        let ext = load_ext(next_gdpa, device);
        // SAFETY: a physical device of this instance; the next layer's instance functions.
        let memory = unsafe { inst.fns.get_physical_device_memory_properties(pd) };
        tracing::info!(decision = %decision.reason, pass_through = inst.pass_through.is_on(), "vulkan device created");
        // Attachment rates enabled by the layer (or kept from the app's own request): foveation
        // can use VRS on this device; `auto` then means vrs, not rdm.
        let fsr_attachment = decision.enable_fsr.is_some_and(|f| f.attachment);
        // SAFETY: a physical device of this instance; the next layer's instance functions.
        let software = unsafe { inst.fns.get_physical_device_properties(pd) }.device_type == vk::PhysicalDeviceType::CPU;
        let rates = if fsr_attachment { fsr_rates(&inst, pd) } else { None };
        if let Some(r) = rates {
            tracing::info!(texel_width = r.texel_width, texel_height = r.texel_height, layered = r.layered, "fragment shading rate attachment available for foveation");
        }
        // What the device may be asked to do: the app's features and extensions plus the layer's.
        let caps = {
            // SAFETY: the app's names array is valid with its count; a valid pNext chain.
            let (mut enabled, features) = unsafe {
                (convert::names(ci_ref.pp_enabled_extension_names, ci_ref.enabled_extension_count), convert::device_features(ci_ref.p_next))
            };
            enabled.extend(decision.add_extensions.iter().map(|e| e.to_string()));
            // SAFETY: a physical device of this instance; the next layer's instance functions.
            let device_version = unsafe { inst.fns.get_physical_device_properties(pd) }.api_version;
            caps::from_create_info(device_version.min(inst.api_version), &enabled, features, fsr_attachment)
        };
        tracing::info!(?caps, "vulkan device capabilities the layer's objects are checked against");
        let device_settings = Arc::new(crate::plugin::settings::Settings::from_config(&inst.config));
        // SAFETY: the app's queue create infos, valid with their count during this call.
        let queue_infos = unsafe { convert::slice(ci_ref.p_queue_create_infos, ci_ref.queue_create_info_count) }
            .iter()
            .map(|q| (q.queue_family_index, q.queue_count, q.flags))
            .collect();
        let state = DeviceState {
            engine: inst.engine.clone(),
            caps,
            handle: device,
            key: dispatch_key(device),
            next_gdpa,
            fns,
            next,
            own,
            ext,
            pass_through: inst.pass_through.clone(),
            track: Default::default(),
            extension_decision: decision,
            features: crate::registry::device_features(&crate::plugin::vk::feature::DeviceInit { settings: &device_settings, memory, rates, set_loader_data, software }),
            settings: device_settings.clone(),
            set_loader_data,
            memory,
            inject: Default::default(),
            lifetime: Default::default(),
            secondary: Default::default(),
            gpu_time: crate::plugin::vk::gpu_time::GpuTimeDevice::new(inst.fns.clone(), pd, queue_infos),
            repeats: Default::default(),
        };
        crate::plugin::vk::devices().insert(state.key, Arc::new(state));
        super::device_line::log_at_exit();
        r
    })
}

/// `VkPhysicalDeviceFragmentShadingRatePropertiesKHR`: the finest rate-map texel and whether
/// multiview passes can have one layer per view. None when the instance cannot query it.
fn fsr_rates(inst: &InstanceState, pd: vk::PhysicalDevice) -> Option<crate::track::caps::DeviceRates> {
    let (_, properties2) = properties2_fns(inst, pd)?;
    let mut fsr = vk::PhysicalDeviceFragmentShadingRatePropertiesKHR::default();
    let mut p2 = vk::PhysicalDeviceProperties2::default().push_next(&mut fsr);
    // SAFETY: a physical device of this instance; a correctly chained output struct.
    unsafe { properties2(pd, &mut p2) };
    let t = fsr.min_fragment_shading_rate_attachment_texel_size;
    (t.width > 0 && t.height > 0).then_some(crate::track::caps::DeviceRates {
        texel_width: t.width,
        texel_height: t.height,
        layered: fsr.layered_shading_rate_attachments != 0,
    })
}

fn load_ext(gdpa: vk::PFN_vkGetDeviceProcAddr, device: vk::Device) -> ExtFns {
    let get = |name: &CStr| {
        // SAFETY: the next layer's gdpa for its device.
        let p = unsafe { gdpa(device, name.as_ptr()) };
        p.map(|f| f as *const c_void)
    };
    // SAFETY (all four): the pointer returned for a name has that command's type.
    ExtFns {
        cmd_set_line_stipple: get(c"vkCmdSetLineStippleKHR")
            .or_else(|| get(c"vkCmdSetLineStippleEXT"))
            // SAFETY: see above.
            .map(|p| unsafe { std::mem::transmute::<*const c_void, vk::PFN_vkCmdSetLineStippleKHR>(p) }),
        // SAFETY: see above.
        cmd_set_color_write_enable: get(c"vkCmdSetColorWriteEnableEXT").map(|p| unsafe { std::mem::transmute(p) }),
        // SAFETY: see above.
        cmd_set_logic_op: get(c"vkCmdSetLogicOpEXT").map(|p| unsafe { std::mem::transmute(p) }),
        // SAFETY: see above.
        cmd_set_patch_control_points: get(c"vkCmdSetPatchControlPointsEXT").map(|p| unsafe { std::mem::transmute(p) }),
        // Loaded whole when the device has the extension's commands: those it lacks (another
        // extension's interactions) stay ash's stubs, never called, since the app reaches a hook
        // only for a command the next layer has.
        eds3: get(c"vkCmdSetPolygonModeEXT").map(|_| ash::ext::extended_dynamic_state3::DeviceFn::load(|name| get(name).unwrap_or(std::ptr::null()))),
        // SAFETY: see above.
        cmd_set_vertex_input: get(c"vkCmdSetVertexInputEXT").map(|p| unsafe { std::mem::transmute(p) }),
        // SAFETY: see above.
        cmd_bind_shaders: get(c"vkCmdBindShadersEXT").map(|p| unsafe { std::mem::transmute(p) }),
        // SAFETY: see above.
        cmd_set_fragment_shading_rate: get(c"vkCmdSetFragmentShadingRateKHR").map(|p| unsafe { std::mem::transmute(p) }),
        cmd_set_rendering_attachment_locations: get(c"vkCmdSetRenderingAttachmentLocations")
            .or_else(|| get(c"vkCmdSetRenderingAttachmentLocationsKHR"))
            // SAFETY: see above (the core 1.4 name and the KHR one have the same type).
            .map(|p| unsafe { std::mem::transmute(p) }),
        cmd_set_rendering_input_attachment_indices: get(c"vkCmdSetRenderingInputAttachmentIndices")
            .or_else(|| get(c"vkCmdSetRenderingInputAttachmentIndicesKHR"))
            // SAFETY: see above.
            .map(|p| unsafe { std::mem::transmute(p) }),
        // SAFETY: see above (the core 1.4 name and the KHR one have the same type).
        cmd_push_descriptor_set: get(c"vkCmdPushDescriptorSet").or_else(|| get(c"vkCmdPushDescriptorSetKHR")).map(|p| unsafe { std::mem::transmute(p) }),
        // SAFETY: see above.
        cmd_push_descriptor_set_with_template: get(c"vkCmdPushDescriptorSetWithTemplate")
            .or_else(|| get(c"vkCmdPushDescriptorSetWithTemplateKHR"))
            // SAFETY: see above.
            .map(|p| unsafe { std::mem::transmute(p) }),
        // SAFETY: see above.
        cmd_bind_descriptor_buffers: get(c"vkCmdBindDescriptorBuffersEXT").map(|p| unsafe { std::mem::transmute(p) }),
    }
}

pub(super) unsafe extern "system" fn destroy_device(device: vk::Device, allocator: *const vk::AllocationCallbacks<'_>) {
    guard::catch("vkDestroyDevice", (), || {
        let key = dispatch_key(device);
        let Some(dev) = crate::plugin::vk::devices().get(key) else { return };
        // The app waited for the device to go idle: every recording's holds go now, so what
        // they counted on completion (e.g. the far field's reused pixels) is in the stats line.
        crate::plugin::vk::lifetime::release_holds(&dev);
        let line = super::device_line::line(&dev);
        tracing::info!(device = ?dev.handle, extensions = %dev.extension_decision.reason, "vulkan device stats: {line}");
        let repeats = dev.repeats.summary();
        if !repeats.is_empty() {
            let list: Vec<String> = repeats.iter().map(|(kind, n)| format!("{kind} ×{n}")).collect();
            tracing::warn!(device = ?dev.handle, "failures of the layer's own objects, logged once each, happened: {}", list.join(", "));
        }
        // The app waited for the device to go idle before destroying it.
        for f in dev.features.all() {
            f.destroy(&dev);
        }
        crate::plugin::vk::inject::pipeline::destroy(&dev);
        crate::plugin::vk::secondary::destroy(&dev);
        crate::plugin::vk::gpu_time::destroy(&dev);
        crate::plugin::vk::lifetime::destroy(&dev);
        let alive = dev.own.alive();
        if !alive.is_empty() {
            tracing::warn!(device = ?dev.handle, "the layer's own objects still alive after it destroyed everything: {alive:?}");
        }
        // SAFETY: forwarding the app's arguments.
        unsafe { (dev.next.fp_v1_0().destroy_device)(device, allocator) };
        // From here `device` is freed memory: only the key read above is used.
        crate::plugin::vk::devices().remove(key);
        crate::plugin::vk::own::unregister(key);
    })
}

#[cfg(test)]
#[path = "chain_props.rs"]
mod props;

#[cfg(test)]
mod tests {
    use super::*;

    fn decision() -> device_ext::Decision {
        device_ext::Decision {
            add_extensions: vec![device_ext::FRAGMENT_SHADING_RATE],
            enable_fsr: Some(device_ext::FsrSupport { pipeline: true, primitive: false, attachment: true }),
            reason: String::new(),
        }
    }

    fn chain_types(mut p: *const c_void) -> Vec<(vk::StructureType, *const c_void)> {
        let mut out = Vec::new();
        while !p.is_null() {
            // SAFETY: test chains are built from valid structs.
            let base = unsafe { &*(p as *const vk::BaseInStructure<'_>) };
            out.push((base.s_type, p));
            p = base.p_next as *const c_void;
        }
        out
    }

    #[test]
    fn our_features_go_first_when_the_app_has_none() {
        let mut v12 = vk::PhysicalDeviceVulkan12Features::default();
        let names = [c"VK_KHR_swapchain".as_ptr()];
        let ci = vk::DeviceCreateInfo::default().push_next(&mut v12).enabled_extension_names(&names);
        // SAFETY: a valid create info, alive while `m` is used.
        let m = unsafe { modify_device_create_info(&ci, &decision()) }.unwrap();
        let types = chain_types(m.ci.p_next);
        assert_eq!(types[0].0, vk::StructureType::PHYSICAL_DEVICE_FRAGMENT_SHADING_RATE_FEATURES_KHR);
        assert_eq!(types[1].1, ci.p_next, "the app's chain follows unchanged");
        assert_eq!(m.ci.enabled_extension_count, 2);
        // SAFETY: our own struct.
        let fsr = unsafe { &*(types[0].1 as *const vk::PhysicalDeviceFragmentShadingRateFeaturesKHR<'_>) };
        assert_eq!((fsr.attachment_fragment_shading_rate, fsr.pipeline_fragment_shading_rate, fsr.primitive_fragment_shading_rate), (1, 1, 0));
        assert_eq!(ci.enabled_extension_count, 1, "the app's create info is untouched");
    }

    #[test]
    fn the_apps_features_struct_is_replaced_by_a_copy() {
        let mut app_fsr = vk::PhysicalDeviceFragmentShadingRateFeaturesKHR::default().primitive_fragment_shading_rate(true);
        let mut v11 = vk::PhysicalDeviceVulkan11Features::default().multiview(true);
        let mut v13 = vk::PhysicalDeviceVulkan13Features::default().dynamic_rendering(true);
        // Chain: v13 → app_fsr → v11 (push_next prepends).
        let ci = vk::DeviceCreateInfo::default().push_next(&mut v11).push_next(&mut app_fsr).push_next(&mut v13);
        let original = chain_types(ci.p_next);
        // SAFETY: a valid create info, alive while `m` is used.
        let m = unsafe { modify_device_create_info(&ci, &decision()) }.unwrap();
        let types = chain_types(m.ci.p_next);
        let kinds: Vec<_> = types.iter().map(|t| t.0).collect();
        assert_eq!(kinds, original.iter().map(|t| t.0).collect::<Vec<_>>(), "same structs, once each");
        assert_ne!(types[0].1, original[0].1, "the prefix is a copy");
        assert_ne!(types[1].1, original[1].1, "the shading-rate struct is a copy");
        assert_eq!(types[2].1, original[2].1, "the rest is the app's own");
        // SAFETY: our copies.
        let (v13c, fsr) = unsafe {
            (&*(types[0].1 as *const vk::PhysicalDeviceVulkan13Features<'_>), &*(types[1].1 as *const vk::PhysicalDeviceFragmentShadingRateFeaturesKHR<'_>))
        };
        assert_eq!(v13c.dynamic_rendering, 1);
        assert_eq!((fsr.attachment_fragment_shading_rate, fsr.primitive_fragment_shading_rate), (1, 1), "app's choice kept");
        assert_eq!(app_fsr.attachment_fragment_shading_rate, 0, "the app's struct is untouched");
    }

    #[test]
    fn every_extension_the_decision_may_add_gets_a_name() {
        // A Vulkan 1.0 device: shading rate and everything it depends on below 1.2.
        let mut d = decision();
        d.add_extensions = vec![device_ext::CREATE_RENDERPASS_2, "VK_KHR_multiview", "VK_KHR_maintenance2", device_ext::FRAGMENT_SHADING_RATE];
        let ci = vk::DeviceCreateInfo::default();
        // SAFETY: a valid create info, alive while `m` is used.
        let m = unsafe { modify_device_create_info(&ci, &d) }.unwrap();
        // SAFETY: the copy's names, alive with `m`.
        let names = unsafe { convert::names(m.ci.pp_enabled_extension_names, m.ci.enabled_extension_count) };
        assert_eq!(names, d.add_extensions.iter().map(|e| e.to_string()).collect::<Vec<_>>());
    }

    #[test]
    fn unknown_prefix_structs_decline() {
        let mut app_fsr = vk::PhysicalDeviceFragmentShadingRateFeaturesKHR::default();
        let mut odd = vk::PhysicalDeviceMeshShaderFeaturesEXT::default();
        let ci = vk::DeviceCreateInfo::default().push_next(&mut app_fsr).push_next(&mut odd);
        // SAFETY: a valid create info.
        assert!(unsafe { modify_device_create_info(&ci, &decision()) }.is_err());
    }
}
