//! The intercepted commands. Every hook runs the same prologue (`hook`): find the device state by
//! dispatch key, open a span, then *decide → call down → record* inside `guard::run`, so a fault
//! in layer logic turns the instance to pass-through and the app still gets the driver's result.
//! With all features off (this stage) no hook changes what reaches the driver, except
//! `vkCreateDevice`, whose additions are decided by `track::device_ext`.

use super::mask::{self, Trigger};
use super::{check_fault, convert, device_of, dispatch_key, instance_of, layer, loader, DeviceState, ExtFns, InstanceState};
use crate::guard::{self, Fault, PassThrough};
use crate::track::cmd::{PassKind, StateCmd};
use crate::track::{caps, device_ext};
use ash::vk::{self, Handle};
use std::ffi::{c_char, c_void, CStr};
use std::sync::Arc;

/// The prologue shared by all device-level hooks. `next` is the plain call down; `record` runs
/// after it with its result (and must itself check for success before recording).
fn hook<H: Handle + Copy, R: Copy>(
    call: &'static str,
    handle: H,
    unknown: R,
    next: impl Fn(&DeviceState) -> R,
    record: impl FnOnce(&DeviceState, R) -> Result<(), Fault>,
) -> R {
    hook_decided(call, handle, unknown, |_| (), |dev, _| next(dev), record)
}

/// Like `hook`, for calls whose arguments the layer may change: `decide` runs first (layered path
/// only) and `next` calls down with its decision (None: the app's arguments, unchanged).
fn hook_decided<H: Handle + Copy, R: Copy, D>(
    call: &'static str,
    handle: H,
    unknown: R,
    decide: impl FnOnce(&DeviceState) -> D,
    next: impl Fn(&DeviceState, Option<&D>) -> R,
    record: impl FnOnce(&DeviceState, R) -> Result<(), Fault>,
) -> R {
    let Some(dev) = device_of(handle) else {
        // No dispatch table: there is nothing to call down to.
        return unknown;
    };
    let span = if call.starts_with("vkCmd") {
        tracing::trace_span!("vk", call)
    } else {
        tracing::debug_span!("vk", call)
    };
    let _entered = span.entered();
    guard::run(
        call,
        &dev.pass_through,
        |down| {
            dev.check(call)?;
            let decision = decide(&dev);
            let r = down.call(|| next(&dev, Some(&decision)));
            record(&dev, r)?;
            Ok(r)
        },
        || next(&dev, None),
    )
}

/// Command-buffer hooks that only record state.
fn cmd<R: Copy>(call: &'static str, cb: vk::CommandBuffer, unknown: R, next: impl Fn(&DeviceState) -> R, record: impl FnOnce(&DeviceState, u64)) -> R {
    hook(call, cb, unknown, next, |dev, _| {
        record(dev, cb.as_raw());
        Ok(())
    })
}

fn state(dev: &DeviceState, cb: u64, c: StateCmd) {
    dev.track.with_cb(cb, |s| s.record(c));
}

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
unsafe fn loader_data_callback(mut p_next: *const c_void) -> Option<super::rdm::PfnSetDeviceLoaderData> {
    while !p_next.is_null() {
        // SAFETY: every struct in a valid chain starts with sType, pNext.
        let base = unsafe { &*(p_next as *const vk::BaseInStructure<'_>) };
        if base.s_type == loader::LOADER_DEVICE_CREATE_INFO {
            // SAFETY: the loader's struct (its sType); the union holds the callback when
            // `function` says so.
            let info = unsafe { &*(p_next as *const loader::LayerDeviceCreateInfo) };
            if info.function == loader::LayerFunction::LOADER_DATA_CALLBACK && !info.p_layer_info.is_null() {
                // SAFETY: the union member is `PFN_vkSetDeviceLoaderData` for this function value.
                return Some(unsafe { std::mem::transmute::<*mut loader::LayerDeviceLink, super::rdm::PfnSetDeviceLoaderData>(info.p_layer_info) });
            }
        }
        p_next = base.p_next as *const c_void;
    }
    None
}

fn resolve_config() -> Arc<crate::config::Config> {
    if let Some(c) = crate::shared::shared().config() {
        return c;
    }
    let exe = std::env::current_exe().ok().and_then(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()));
    let names: Vec<&str> = exe.as_deref().into_iter().collect();
    let (config, diagnostics) = crate::config::load(&names);
    crate::log::init(config.choice("log.level"));
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
        tracing::info!(api_version = %version(api_version), pass_through = pass_through.is_on(), "vulkan instance created");
        let state = InstanceState { handle: instance, next_gipa, fns, api_version, extensions, pass_through, config };
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
        layer().instances.remove(key);
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
        let fns = unsafe { ash::Device::load_with(|n| super::device_proc(next_gdpa, device, n), device) };
        let ext = load_ext(next_gdpa, device);
        // SAFETY: a physical device of this instance; the next layer's instance functions.
        let memory = unsafe { inst.fns.get_physical_device_memory_properties(pd) };
        tracing::info!(decision = %decision.reason, pass_through = inst.pass_through.is_on(), "vulkan device created");
        // Attachment rates enabled by the layer (or kept from the app's own request): foveation
        // can use VRS on this device; `auto` then means vrs, not rdm.
        let fsr_attachment = decision.enable_fsr.is_some_and(|f| f.attachment);
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
        let state = DeviceState {
            caps,
            handle: device,
            next_gdpa,
            fns,
            ext,
            pass_through: inst.pass_through.clone(),
            config: inst.config.clone(),
            track: Default::default(),
            extension_decision: decision,
            mask: super::mask::MaskDevice::new(&inst.config, memory, rates.is_some()),
            vrs: super::vrs::VrsDevice::new(&inst.config, memory, rates),
            rdm: super::rdm::RdmDevice::new(memory, set_loader_data),
            secondary: Default::default(),
        };
        layer().devices.insert(dispatch_key(device), Arc::new(state));
        r
    })
}

/// `VkPhysicalDeviceFragmentShadingRatePropertiesKHR`: the finest rate-map texel and whether
/// multiview passes can have one layer per view. None when the instance cannot query it.
fn fsr_rates(inst: &InstanceState, pd: vk::PhysicalDevice) -> Option<crate::vrs::DeviceRates> {
    let (_, properties2) = properties2_fns(inst, pd)?;
    let mut fsr = vk::PhysicalDeviceFragmentShadingRatePropertiesKHR::default();
    let mut p2 = vk::PhysicalDeviceProperties2::default().push_next(&mut fsr);
    // SAFETY: a physical device of this instance; a correctly chained output struct.
    unsafe { properties2(pd, &mut p2) };
    let t = fsr.min_fragment_shading_rate_attachment_texel_size;
    (t.width > 0 && t.height > 0).then_some(crate::vrs::DeviceRates {
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
    }
}

pub(super) unsafe extern "system" fn destroy_device(device: vk::Device, allocator: *const vk::AllocationCallbacks<'_>) {
    guard::catch("vkDestroyDevice", (), || {
        let key = dispatch_key(device);
        let Some(dev) = layer().devices.get(key) else { return };
        if dev.mask.used() {
            tracing::info!(device = ?dev.handle, extensions = %dev.extension_decision.reason, "vulkan device stats: {} {}", dev.track.stats.summary(), dev.mask.summary());
            // The app waited for the device to go idle before destroying it.
            super::mask::destroy(&dev);
            super::rdm::destroy(&dev);
            super::secondary::destroy(&dev);
        } else {
            tracing::info!(device = ?dev.handle, extensions = %dev.extension_decision.reason, "vulkan device stats: {}", dev.track.stats.summary());
        }
        super::vrs::destroy(&dev);
        // SAFETY: forwarding the app's arguments.
        unsafe { (dev.fns.fp_v1_0().destroy_device)(device, allocator) };
        layer().devices.remove(key);
    })
}

// ---------------------------------------------------------------------------------------------
// Resources

/// Creation hooks: record `make(handle)` only when the call down succeeded.
macro_rules! create_hook {
    ($name:ident, $call:literal, $info:ty, $handle:ty, $fp:ident . $f:ident, $map:ident, |$h:ident, $ci:ident| $make:expr) => {
        pub(super) unsafe extern "system" fn $name(
            device: vk::Device,
            ci: *const $info,
            allocator: *const vk::AllocationCallbacks<'_>,
            out: *mut $handle,
        ) -> vk::Result {
            hook(
                $call,
                device,
                vk::Result::ERROR_INITIALIZATION_FAILED,
                // SAFETY: forwarding the app's arguments unchanged.
                |d| unsafe { (d.fns.$fp().$f)(device, ci, allocator, out) },
                |d, r| {
                    if r == vk::Result::SUCCESS {
                        // SAFETY: on success the handle was written; the create info is valid
                        // during the app's call.
                        let ($h, $ci) = unsafe { (*out, &*ci) };
                        d.track.$map.insert($h.as_raw(), Arc::new($make));
                    }
                    Ok(())
                },
            )
        }
    };
}

macro_rules! destroy_hook {
    ($name:ident, $call:literal, $handle:ty, $fp:ident . $f:ident, |$d:ident, $h:ident| $forget:expr) => {
        pub(super) unsafe extern "system" fn $name(device: vk::Device, handle: $handle, allocator: *const vk::AllocationCallbacks<'_>) {
            hook(
                $call,
                device,
                (),
                // SAFETY: forwarding the app's arguments unchanged.
                |d| unsafe { (d.fns.$fp().$f)(device, handle, allocator) },
                |$d, _| {
                    let $h = handle.as_raw();
                    $forget;
                    Ok(())
                },
            )
        }
    };
}

/// Like the other create hooks, and also notes the image for `swapchain_images`: a runtime creating
/// swapchain images inside `xrCreateSwapchain` is recognised by the handle seen here, whatever
/// layer above wraps it.
pub(super) unsafe extern "system" fn create_image(
    device: vk::Device,
    ci: *const vk::ImageCreateInfo<'_>,
    allocator: *const vk::AllocationCallbacks<'_>,
    out: *mut vk::Image,
) -> vk::Result {
    hook(
        "vkCreateImage",
        device,
        vk::Result::ERROR_INITIALIZATION_FAILED,
        // SAFETY: forwarding the app's arguments unchanged.
        |d| unsafe { (d.fns.fp_v1_0().create_image)(device, ci, allocator, out) },
        |d, r| {
            if r == vk::Result::SUCCESS {
                // SAFETY: on success the handle was written; the create info is valid during the
                // app's call.
                let (h, ci) = unsafe { (*out, &*ci) };
                crate::swapchain_images::note_created(crate::swapchain_images::CreatedImage {
                    image: h.as_raw(),
                    format: ci.format.as_raw(),
                    width: ci.extent.width,
                    height: ci.extent.height,
                    array_layers: ci.array_layers,
                    samples: ci.samples.as_raw(),
                    mip_levels: ci.mip_levels,
                });
                d.track.images.insert(h.as_raw(), Arc::new(convert::image(h, ci)));
            }
            Ok(())
        },
    )
}
destroy_hook!(destroy_image, "vkDestroyImage", vk::Image, fp_v1_0.destroy_image, |d, h| {
    d.track.forget_image(h);
    super::rdm::forget_image(d, h)
});
create_hook!(create_image_view, "vkCreateImageView", vk::ImageViewCreateInfo<'_>, vk::ImageView, fp_v1_0.create_image_view, views, |h, ci| convert::image_view(h, ci));
destroy_hook!(destroy_image_view, "vkDestroyImageView", vk::ImageView, fp_v1_0.destroy_image_view, |d, h| d.track.views.remove(h));
/// `vkCreateRenderPass` / `vkCreateRenderPass2(KHR)`: with variable-rate shading's attachment
/// appended where the layer enabled attachment rates (`vk::vrs`; v1 infos go down translated to
/// `vkCreateRenderPass2`); the tracked description is the app's, with the appended index.
fn create_render_pass_common(
    call: &'static str,
    device: vk::Device,
    allocator: *const vk::AllocationCallbacks<'_>,
    out: *mut vk::RenderPass,
    decide: impl FnOnce(&DeviceState) -> Option<super::vrs::RatePass>,
    app: impl Fn(&DeviceState) -> vk::Result,
    describe: impl FnOnce(vk::RenderPass) -> crate::track::resources::RenderPass,
) -> vk::Result {
    let appended = std::cell::Cell::new(None);
    hook_decided(
        call,
        device,
        vk::Result::ERROR_INITIALIZATION_FAILED,
        decide,
        |d, decided| {
            if let Some(Some(rp)) = decided {
                // SAFETY: the app's pass with only the rate attachment added (see `vk::vrs`), with
                // the app's allocator (the app destroys the pass).
                let r = unsafe { (d.fns.fp_v1_2().create_render_pass2)(device, &rp.info, allocator, out) };
                if r == vk::Result::SUCCESS {
                    appended.set(Some(rp.index));
                    return r;
                }
                tracing::warn!(?r, "{call} failed with the shading-rate attachment; retrying as the app asked");
            }
            appended.set(None);
            app(d)
        },
        |d, r| {
            if r == vk::Result::SUCCESS {
                // SAFETY: on success the handle was written.
                let h = unsafe { *out };
                let mut desc = describe(h);
                desc.layer_rate_attachment = appended.get();
                d.track.render_passes.insert(h.as_raw(), Arc::new(desc));
            }
            Ok(())
        },
    )
}

pub(super) unsafe extern "system" fn create_render_pass(
    device: vk::Device,
    ci: *const vk::RenderPassCreateInfo<'_>,
    allocator: *const vk::AllocationCallbacks<'_>,
    out: *mut vk::RenderPass,
) -> vk::Result {
    create_render_pass_common(
        "vkCreateRenderPass",
        device,
        allocator,
        out,
        // SAFETY: the app's info, valid during its call; the copies live in the decision.
        |d| unsafe { super::vrs::render_pass_v1(d, ci) },
        // SAFETY: forwarding the app's arguments unchanged.
        |d| unsafe { (d.fns.fp_v1_0().create_render_pass)(device, ci, allocator, out) },
        // SAFETY: the create info is valid during the app's call.
        |h| unsafe { convert::render_pass(h, &*ci) },
    )
}

pub(super) unsafe extern "system" fn create_render_pass2(
    device: vk::Device,
    ci: *const vk::RenderPassCreateInfo2<'_>,
    allocator: *const vk::AllocationCallbacks<'_>,
    out: *mut vk::RenderPass,
) -> vk::Result {
    create_render_pass_common(
        "vkCreateRenderPass2",
        device,
        allocator,
        out,
        // SAFETY: the app's info, valid during its call; the copies live in the decision.
        |d| unsafe { super::vrs::render_pass_v2(d, ci) },
        // SAFETY: forwarding the app's arguments unchanged.
        |d| unsafe { (d.fns.fp_v1_2().create_render_pass2)(device, ci, allocator, out) },
        // SAFETY: the create info is valid during the app's call.
        |h| unsafe { convert::render_pass2(h, &*ci) },
    )
}

destroy_hook!(destroy_render_pass, "vkDestroyRenderPass", vk::RenderPass, fp_v1_0.destroy_render_pass, |d, h| {
    d.track.render_passes.remove(h);
    super::mask::forget_render_pass(d, h)
});
/// `vkCreateFramebuffer`: a framebuffer of a pass with variable-rate shading's attachment gets
/// the layer's rate image as that attachment (`vk::vrs`); tracked as the app described it.
pub(super) unsafe extern "system" fn create_framebuffer(
    device: vk::Device,
    ci: *const vk::FramebufferCreateInfo<'_>,
    allocator: *const vk::AllocationCallbacks<'_>,
    out: *mut vk::Framebuffer,
) -> vk::Result {
    let pending = std::cell::Cell::new(None);
    hook_decided(
        "vkCreateFramebuffer",
        device,
        vk::Result::ERROR_INITIALIZATION_FAILED,
        // SAFETY: the app's info, valid during its call; the copies live in the decision.
        |d| match unsafe { super::vrs::framebuffer_info(d, ci) } {
            Ok(Some((info, rate))) => {
                pending.set(Some(rate));
                Some(info)
            }
            Ok(None) => None,
            Err(e) => {
                tracing::warn!("vrs rate image for a framebuffer: {e}");
                None
            }
        },
        |d, decided| match decided {
            // SAFETY: the app's info with only the rate attachment added.
            Some(Some(f)) => unsafe { (d.fns.fp_v1_0().create_framebuffer)(device, &f.info, allocator, out) },
            // SAFETY: forwarding the app's arguments unchanged.
            _ => unsafe { (d.fns.fp_v1_0().create_framebuffer)(device, ci, allocator, out) },
        },
        |d, r| {
            let ok = r == vk::Result::SUCCESS;
            if let Some(rate) = pending.take() {
                // SAFETY: on success the handle was written.
                super::vrs::framebuffer_created(d, ok.then(|| unsafe { *out }), rate);
            }
            if ok {
                // SAFETY: on success the handle was written; the create info is valid during the
                // app's call.
                let (h, ci) = unsafe { (*out, &*ci) };
                // SAFETY: as above.
                d.track.framebuffers.insert(h.as_raw(), Arc::new(unsafe { convert::framebuffer(h, ci) }));
            }
            Ok(())
        },
    )
}
destroy_hook!(destroy_framebuffer, "vkDestroyFramebuffer", vk::Framebuffer, fp_v1_0.destroy_framebuffer, |d, h| {
    d.track.framebuffers.remove(h);
    super::vrs::forget_framebuffer(d, h)
});
destroy_hook!(destroy_pipeline, "vkDestroyPipeline", vk::Pipeline, fp_v1_0.destroy_pipeline, |d, h| d.track.pipelines.remove(h));
create_hook!(create_command_pool, "vkCreateCommandPool", vk::CommandPoolCreateInfo<'_>, vk::CommandPool, fp_v1_0.create_command_pool, pools, |h, ci| {
    crate::track::resources::CommandPool { handle: h.as_raw(), flags: ci.flags, queue_family_index: ci.queue_family_index }
});
destroy_hook!(destroy_command_pool, "vkDestroyCommandPool", vk::CommandPool, fp_v1_0.destroy_command_pool, |d, h| {
    super::secondary::release(d, &d.track.buffers_of_pool(h));
    d.track.destroy_pool(h)
});

pub(super) unsafe extern "system" fn create_graphics_pipelines(
    device: vk::Device,
    cache: vk::PipelineCache,
    count: u32,
    infos: *const vk::GraphicsPipelineCreateInfo<'_>,
    allocator: *const vk::AllocationCallbacks<'_>,
    out: *mut vk::Pipeline,
) -> vk::Result {
    hook_decided(
        "vkCreateGraphicsPipelines",
        device,
        vk::Result::ERROR_INITIALIZATION_FAILED,
        // SAFETY: the app's infos, valid during its call; the copies live in the decision.
        |d| unsafe { super::vrs::pipeline_infos(d, infos, count) },
        |d, decided| {
            let create = d.fns.fp_v1_0().create_graphics_pipelines;
            if let Some(Some(m)) = decided.filter(|m| m.as_ref().is_some_and(|m| m.changed > 0)) {
                // SAFETY: the app's infos with only the shading-rate state added (see `vk::vrs`).
                let r = unsafe { create(device, cache, count, m.infos.as_ptr(), allocator, out) };
                if r == vk::Result::SUCCESS || r == vk::Result::PIPELINE_COMPILE_REQUIRED {
                    return r;
                }
                tracing::warn!(?r, "vkCreateGraphicsPipelines failed with the shading-rate state; retrying as the app asked");
            }
            // SAFETY: forwarding the app's arguments unchanged.
            unsafe { create(device, cache, count, infos, allocator, out) }
        },
        |d, r| {
            if r != vk::Result::SUCCESS {
                return Ok(());
            }
            // SAFETY: `count` infos and, on success, `count` written pipelines.
            let (infos, pipelines) = unsafe { (convert::slice(infos, count), convert::slice(out as *const vk::Pipeline, count)) };
            for (ci, &p) in infos.iter().zip(pipelines) {
                if p != vk::Pipeline::null() {
                    // SAFETY: the create info is valid during the app's call.
                    d.track.add_pipeline(unsafe { convert::graphics_pipeline(p, ci) });
                }
            }
            Ok(())
        },
    )
}

pub(super) unsafe extern "system" fn reset_command_pool(device: vk::Device, pool: vk::CommandPool, flags: vk::CommandPoolResetFlags) -> vk::Result {
    hook(
        "vkResetCommandPool",
        device,
        vk::Result::ERROR_INITIALIZATION_FAILED,
        // SAFETY: forwarding the app's arguments unchanged.
        |d| unsafe { (d.fns.fp_v1_0().reset_command_pool)(device, pool, flags) },
        |d, r| {
            if r == vk::Result::SUCCESS {
                super::secondary::release(d, &d.track.buffers_of_pool(pool.as_raw()));
                d.track.reset_pool(pool.as_raw());
            }
            Ok(())
        },
    )
}

pub(super) unsafe extern "system" fn allocate_command_buffers(
    device: vk::Device,
    info: *const vk::CommandBufferAllocateInfo<'_>,
    out: *mut vk::CommandBuffer,
) -> vk::Result {
    hook(
        "vkAllocateCommandBuffers",
        device,
        vk::Result::ERROR_INITIALIZATION_FAILED,
        // SAFETY: forwarding the app's arguments unchanged.
        |d| unsafe { (d.fns.fp_v1_0().allocate_command_buffers)(device, info, out) },
        |d, r| {
            if r != vk::Result::SUCCESS {
                return Ok(());
            }
            // SAFETY: a valid allocate info; on success `count` buffers were written. They are
            // keyed by handle: their dispatch key is only set by the loader after we return.
            let (info, cbs) = unsafe { (&*info, convert::slice(out as *const vk::CommandBuffer, (*info).command_buffer_count)) };
            for cb in cbs {
                let state = crate::track::CommandBuffer::new(cb.as_raw(), info.command_pool.as_raw(), info.level);
                d.track.command_buffers.insert(cb.as_raw(), Arc::new(state));
            }
            Ok(())
        },
    )
}

pub(super) unsafe extern "system" fn free_command_buffers(device: vk::Device, pool: vk::CommandPool, count: u32, cbs: *const vk::CommandBuffer) {
    hook(
        "vkFreeCommandBuffers",
        device,
        (),
        // SAFETY: forwarding the app's arguments unchanged.
        |d| unsafe { (d.fns.fp_v1_0().free_command_buffers)(device, pool, count, cbs) },
        |d, _| {
            // SAFETY: `count` handles (some may be null, which match nothing).
            let handles: Vec<u64> = unsafe { convert::slice(cbs, count) }.iter().map(|c| c.as_raw()).collect();
            super::secondary::release(d, &handles);
            d.track.free_command_buffers(&handles);
            Ok(())
        },
    )
}

// ---------------------------------------------------------------------------------------------
// Command buffers

pub(super) unsafe extern "system" fn begin_command_buffer(cb: vk::CommandBuffer, info: *const vk::CommandBufferBeginInfo<'_>) -> vk::Result {
    hook(
        "vkBeginCommandBuffer",
        cb,
        vk::Result::ERROR_INITIALIZATION_FAILED,
        // SAFETY: forwarding the app's arguments unchanged.
        |d| unsafe { (d.fns.fp_v1_0().begin_command_buffer)(cb, info) },
        |d, r| {
            if r == vk::Result::SUCCESS {
                // Not pending (re-recording requires it): the layer's secondaries in it are free.
                super::secondary::release(d, &[cb.as_raw()]);
                // SAFETY: a valid begin info.
                d.track.begin_command_buffer(cb.as_raw(), unsafe { (*info).flags });
            }
            Ok(())
        },
    )
}

pub(super) unsafe extern "system" fn reset_command_buffer(cb: vk::CommandBuffer, flags: vk::CommandBufferResetFlags) -> vk::Result {
    hook(
        "vkResetCommandBuffer",
        cb,
        vk::Result::ERROR_INITIALIZATION_FAILED,
        // SAFETY: forwarding the app's arguments unchanged.
        |d| unsafe { (d.fns.fp_v1_0().reset_command_buffer)(cb, flags) },
        |d, r| {
            if r == vk::Result::SUCCESS {
                super::secondary::release(d, &[cb.as_raw()]);
                d.track.with_cb(cb.as_raw(), |s| s.reset());
            }
            Ok(())
        },
    )
}

pub(super) unsafe extern "system" fn cmd_execute_commands(cb: vk::CommandBuffer, n: u32, cbs: *const vk::CommandBuffer) {
    hook_decided(
        "vkCmdExecuteCommands",
        cb,
        (),
        // An eye pass with secondary contents: the layer's draws, in its own secondary.
        |d| mask::on_execute_commands(d, cb),
        |d, ours| {
            let execute = d.fns.fp_v1_0().cmd_execute_commands;
            if let Some(Some(ours)) = ours {
                let mut all = vec![*ours];
                // SAFETY: `n` app handles, valid during its call.
                all.extend_from_slice(unsafe { convert::slice(cbs, n) });
                // SAFETY: the app's secondaries behind the layer's, which inherits the same pass.
                return unsafe { execute(cb, all.len() as u32, all.as_ptr()) };
            }
            // SAFETY: forwarding the app's arguments unchanged.
            unsafe { execute(cb, n, cbs) }
        },
        |d, ()| {
            d.track.with_cb(cb.as_raw(), |s| s.forget_graphics_state());
            Ok(())
        },
    )
}

pub(super) unsafe extern "system" fn cmd_bind_pipeline(cb: vk::CommandBuffer, bind_point: vk::PipelineBindPoint, pipeline: vk::Pipeline) {
    // SAFETY: forwarding the app's arguments unchanged.
    cmd("vkCmdBindPipeline", cb, (), |d| unsafe { (d.fns.fp_v1_0().cmd_bind_pipeline)(cb, bind_point, pipeline) }, |d, cb| {
        if bind_point == vk::PipelineBindPoint::GRAPHICS {
            d.track.bind_graphics_pipeline(cb, pipeline.as_raw());
        }
    })
}

pub(super) unsafe extern "system" fn cmd_push_constants(
    cb: vk::CommandBuffer,
    layout: vk::PipelineLayout,
    stages: vk::ShaderStageFlags,
    offset: u32,
    size: u32,
    values: *const c_void,
) {
    // SAFETY: forwarding the app's arguments unchanged.
    cmd("vkCmdPushConstants", cb, (), |d| unsafe { (d.fns.fp_v1_0().cmd_push_constants)(cb, layout, stages, offset, size, values) }, |d, cb| {
        // SAFETY: `values` holds `size` bytes during the app's call.
        state(d, cb, unsafe { convert::push_constants(layout, stages, offset, size, values) })
    })
}

/// Hooks for dynamic-state commands: call down unchanged, record one `StateCmd`.
macro_rules! state_hook {
    ($name:ident, $call:literal, ($cb:ident, $($arg:ident : $ty:ty),*), |$d:ident| $next:expr, $cmd:expr) => {
        // Only some commands read app memory while recording; the shared `unsafe` covers those.
        #[allow(unused_unsafe)]
        pub(super) unsafe extern "system" fn $name($cb: vk::CommandBuffer, $($arg: $ty),*) {
            cmd(
                $call,
                $cb,
                (),
                // SAFETY: forwarding the app's arguments unchanged to the next layer's command.
                |$d| unsafe { $next },
                // SAFETY: array arguments are valid with their counts during the app's call.
                |d, cb| state(d, cb, unsafe { $cmd }),
            )
        }
    };
}

state_hook!(cmd_set_viewport, "vkCmdSetViewport", (cb, first: u32, n: u32, p: *const vk::Viewport), |d| (d.fns.fp_v1_0().cmd_set_viewport)(cb, first, n, p),
    StateCmd::SetViewport { first, viewports: convert::slice(p, n).iter().map(convert::viewport).collect() });
state_hook!(cmd_set_scissor, "vkCmdSetScissor", (cb, first: u32, n: u32, p: *const vk::Rect2D), |d| (d.fns.fp_v1_0().cmd_set_scissor)(cb, first, n, p),
    StateCmd::SetScissor { first, scissors: convert::slice(p, n).iter().map(convert::rect).collect() });
state_hook!(cmd_set_viewport_with_count, "vkCmdSetViewportWithCount", (cb, n: u32, p: *const vk::Viewport), |d| (d.fns.fp_v1_3().cmd_set_viewport_with_count)(cb, n, p),
    StateCmd::SetViewportWithCount(convert::slice(p, n).iter().map(convert::viewport).collect()));
state_hook!(cmd_set_scissor_with_count, "vkCmdSetScissorWithCount", (cb, n: u32, p: *const vk::Rect2D), |d| (d.fns.fp_v1_3().cmd_set_scissor_with_count)(cb, n, p),
    StateCmd::SetScissorWithCount(convert::slice(p, n).iter().map(convert::rect).collect()));
state_hook!(cmd_set_line_width, "vkCmdSetLineWidth", (cb, w: f32), |d| (d.fns.fp_v1_0().cmd_set_line_width)(cb, w), StateCmd::LineWidth(w));
state_hook!(cmd_set_depth_bias, "vkCmdSetDepthBias", (cb, c: f32, clamp: f32, s: f32), |d| (d.fns.fp_v1_0().cmd_set_depth_bias)(cb, c, clamp, s),
    StateCmd::DepthBias { constant_factor: c, clamp, slope_factor: s });
state_hook!(cmd_set_blend_constants, "vkCmdSetBlendConstants", (cb, c: *const [f32; 4]), |d| (d.fns.fp_v1_0().cmd_set_blend_constants)(cb, c),
    StateCmd::BlendConstants(*c));
state_hook!(cmd_set_depth_bounds, "vkCmdSetDepthBounds", (cb, min: f32, max: f32), |d| (d.fns.fp_v1_0().cmd_set_depth_bounds)(cb, min, max),
    StateCmd::DepthBounds { min, max });
state_hook!(cmd_set_stencil_compare_mask, "vkCmdSetStencilCompareMask", (cb, face: vk::StencilFaceFlags, mask: u32),
    |d| (d.fns.fp_v1_0().cmd_set_stencil_compare_mask)(cb, face, mask), StateCmd::StencilCompareMask { face, mask });
state_hook!(cmd_set_stencil_write_mask, "vkCmdSetStencilWriteMask", (cb, face: vk::StencilFaceFlags, mask: u32),
    |d| (d.fns.fp_v1_0().cmd_set_stencil_write_mask)(cb, face, mask), StateCmd::StencilWriteMask { face, mask });
state_hook!(cmd_set_stencil_reference, "vkCmdSetStencilReference", (cb, face: vk::StencilFaceFlags, reference: u32),
    |d| (d.fns.fp_v1_0().cmd_set_stencil_reference)(cb, face, reference), StateCmd::StencilReference { face, reference });
state_hook!(cmd_set_cull_mode, "vkCmdSetCullMode", (cb, m: vk::CullModeFlags), |d| (d.fns.fp_v1_3().cmd_set_cull_mode)(cb, m), StateCmd::CullMode(m));
state_hook!(cmd_set_front_face, "vkCmdSetFrontFace", (cb, f: vk::FrontFace), |d| (d.fns.fp_v1_3().cmd_set_front_face)(cb, f), StateCmd::FrontFace(f));
state_hook!(cmd_set_primitive_topology, "vkCmdSetPrimitiveTopology", (cb, t: vk::PrimitiveTopology),
    |d| (d.fns.fp_v1_3().cmd_set_primitive_topology)(cb, t), StateCmd::PrimitiveTopology(t));
state_hook!(cmd_set_depth_test_enable, "vkCmdSetDepthTestEnable", (cb, e: vk::Bool32),
    |d| (d.fns.fp_v1_3().cmd_set_depth_test_enable)(cb, e), StateCmd::DepthTestEnable(e != 0));
state_hook!(cmd_set_depth_write_enable, "vkCmdSetDepthWriteEnable", (cb, e: vk::Bool32),
    |d| (d.fns.fp_v1_3().cmd_set_depth_write_enable)(cb, e), StateCmd::DepthWriteEnable(e != 0));
state_hook!(cmd_set_depth_compare_op, "vkCmdSetDepthCompareOp", (cb, op: vk::CompareOp),
    |d| (d.fns.fp_v1_3().cmd_set_depth_compare_op)(cb, op), StateCmd::DepthCompareOp(op));
state_hook!(cmd_set_depth_bounds_test_enable, "vkCmdSetDepthBoundsTestEnable", (cb, e: vk::Bool32),
    |d| (d.fns.fp_v1_3().cmd_set_depth_bounds_test_enable)(cb, e), StateCmd::DepthBoundsTestEnable(e != 0));
state_hook!(cmd_set_stencil_test_enable, "vkCmdSetStencilTestEnable", (cb, e: vk::Bool32),
    |d| (d.fns.fp_v1_3().cmd_set_stencil_test_enable)(cb, e), StateCmd::StencilTestEnable(e != 0));
state_hook!(cmd_set_stencil_op, "vkCmdSetStencilOp",
    (cb, face: vk::StencilFaceFlags, fail_op: vk::StencilOp, pass_op: vk::StencilOp, depth_fail_op: vk::StencilOp, compare_op: vk::CompareOp),
    |d| (d.fns.fp_v1_3().cmd_set_stencil_op)(cb, face, fail_op, pass_op, depth_fail_op, compare_op),
    StateCmd::StencilOp { face, fail_op, pass_op, depth_fail_op, compare_op });
state_hook!(cmd_set_rasterizer_discard_enable, "vkCmdSetRasterizerDiscardEnable", (cb, e: vk::Bool32),
    |d| (d.fns.fp_v1_3().cmd_set_rasterizer_discard_enable)(cb, e), StateCmd::RasterizerDiscardEnable(e != 0));
state_hook!(cmd_set_depth_bias_enable, "vkCmdSetDepthBiasEnable", (cb, e: vk::Bool32),
    |d| (d.fns.fp_v1_3().cmd_set_depth_bias_enable)(cb, e), StateCmd::DepthBiasEnable(e != 0));
state_hook!(cmd_set_primitive_restart_enable, "vkCmdSetPrimitiveRestartEnable", (cb, e: vk::Bool32),
    |d| (d.fns.fp_v1_3().cmd_set_primitive_restart_enable)(cb, e), StateCmd::PrimitiveRestartEnable(e != 0));

/// Extension-only commands: the hook is handed out only when the next layer has the command, so
/// the `Option` is always `Some` when these run.
macro_rules! ext_state_hook {
    ($name:ident, $call:literal, $field:ident, ($($arg:ident : $ty:ty),*), $cmd:expr) => {
        // Only some commands read app memory while recording; the shared `unsafe` covers those.
        #[allow(unused_unsafe)]
        pub(super) unsafe extern "system" fn $name(cb: vk::CommandBuffer, $($arg: $ty),*) {
            cmd(
                $call,
                cb,
                (),
                |d| {
                    if let Some(f) = d.ext.$field {
                        // SAFETY: forwarding the app's arguments unchanged to the next layer's command.
                        unsafe { f(cb, $($arg),*) }
                    }
                },
                // SAFETY: array arguments are valid with their counts during the app's call.
                |d, cb| state(d, cb, unsafe { $cmd }),
            )
        }
    };
}

ext_state_hook!(cmd_set_line_stipple, "vkCmdSetLineStippleEXT", cmd_set_line_stipple, (factor: u32, pattern: u16), StateCmd::LineStipple { factor, pattern });
ext_state_hook!(cmd_set_color_write_enable, "vkCmdSetColorWriteEnableEXT", cmd_set_color_write_enable, (n: u32, p: *const vk::Bool32),
    StateCmd::ColorWriteEnable(convert::slice(p, n).iter().map(|&b| b != 0).collect()));
ext_state_hook!(cmd_set_logic_op, "vkCmdSetLogicOpEXT", cmd_set_logic_op, (op: vk::LogicOp), StateCmd::LogicOp(op));
ext_state_hook!(cmd_set_patch_control_points, "vkCmdSetPatchControlPointsEXT", cmd_set_patch_control_points, (n: u32), StateCmd::PatchControlPoints(n));

// ---------------------------------------------------------------------------------------------
// Render pass instances

fn begin_pass(d: &DeviceState, cb: u64, kind: PassKind, info: *const vk::RenderPassBeginInfo<'_>) {
    // SAFETY: a valid begin info during the app's call.
    let begin = unsafe { convert::render_pass_begin(&*info) };
    d.track.begin_render_pass(crate::shared::shared(), cb, kind, begin);
}

pub(super) unsafe extern "system" fn cmd_begin_render_pass(cb: vk::CommandBuffer, info: *const vk::RenderPassBeginInfo<'_>, contents: vk::SubpassContents) {
    let secondary = contents == vk::SubpassContents::SECONDARY_COMMAND_BUFFERS;
    hook_decided(
        "vkCmdBeginRenderPass",
        cb,
        (),
        // SAFETY: the app's valid info; `cb` is recording outside a pass (it is about to begin one).
        |d| unsafe { super::vrs::for_render_pass_begin(d, cb, PassKind::RenderPass, info) },
        |d, decided| {
            let begin = d.fns.fp_v1_0().cmd_begin_render_pass;
            match decided {
                // SAFETY: the app's info with the rate view appended (imageless framebuffer).
                Some(Some(v)) => unsafe { begin(cb, &v.info, contents) },
                // SAFETY: forwarding the app's arguments unchanged.
                _ => unsafe { begin(cb, info, contents) },
            }
        },
        |d, _| {
            begin_pass(d, cb.as_raw(), PassKind::RenderPass, info);
            super::vrs::on_render_pass_begin(d, cb, secondary);
            mask::on_trigger(d, cb, Trigger::Begin { secondary });
            Ok(())
        },
    )
}

pub(super) unsafe extern "system" fn cmd_next_subpass(cb: vk::CommandBuffer, contents: vk::SubpassContents) {
    // SAFETY: forwarding the app's arguments unchanged.
    cmd("vkCmdNextSubpass", cb, (), |d| unsafe { (d.fns.fp_v1_0().cmd_next_subpass)(cb, contents) }, |d, raw| {
        d.track.next_subpass(raw);
        mask::on_trigger(d, cb, Trigger::NextSubpass { secondary: contents == vk::SubpassContents::SECONDARY_COMMAND_BUFFERS });
    })
}

pub(super) unsafe extern "system" fn cmd_end_render_pass(cb: vk::CommandBuffer) {
    // SAFETY: forwarding the app's arguments unchanged.
    cmd("vkCmdEndRenderPass", cb, (), |d| unsafe { (d.fns.fp_v1_0().cmd_end_render_pass)(cb) }, |d, raw| {
        mask::on_trigger(d, cb, Trigger::End);
        d.track.end_pass(raw)
    })
}

pub(super) unsafe extern "system" fn cmd_begin_render_pass2(
    cb: vk::CommandBuffer,
    info: *const vk::RenderPassBeginInfo<'_>,
    subpass_info: *const vk::SubpassBeginInfo<'_>,
) {
    hook_decided(
        "vkCmdBeginRenderPass2",
        cb,
        (),
        // SAFETY: the app's valid info; `cb` is recording outside a pass (it is about to begin one).
        |d| unsafe { super::vrs::for_render_pass_begin(d, cb, PassKind::RenderPass2, info) },
        |d, decided| {
            let begin = d.fns.fp_v1_2().cmd_begin_render_pass2;
            match decided {
                // SAFETY: the app's info with the rate view appended (imageless framebuffer).
                Some(Some(v)) => unsafe { begin(cb, &v.info, subpass_info) },
                // SAFETY: forwarding the app's arguments unchanged.
                _ => unsafe { begin(cb, info, subpass_info) },
            }
        },
        |d, _| {
            begin_pass(d, cb.as_raw(), PassKind::RenderPass2, info);
            super::vrs::on_render_pass_begin(d, cb, secondary_contents(subpass_info));
            mask::on_trigger(d, cb, Trigger::Begin { secondary: secondary_contents(subpass_info) });
            Ok(())
        },
    )
}

pub(super) unsafe extern "system" fn cmd_next_subpass2(cb: vk::CommandBuffer, begin: *const vk::SubpassBeginInfo<'_>, end: *const vk::SubpassEndInfo<'_>) {
    // SAFETY: forwarding the app's arguments unchanged.
    cmd("vkCmdNextSubpass2", cb, (), |d| unsafe { (d.fns.fp_v1_2().cmd_next_subpass2)(cb, begin, end) }, |d, raw| {
        d.track.next_subpass(raw);
        mask::on_trigger(d, cb, Trigger::NextSubpass { secondary: secondary_contents(begin) });
    })
}

pub(super) unsafe extern "system" fn cmd_end_render_pass2(cb: vk::CommandBuffer, end: *const vk::SubpassEndInfo<'_>) {
    // SAFETY: forwarding the app's arguments unchanged.
    cmd("vkCmdEndRenderPass2", cb, (), |d| unsafe { (d.fns.fp_v1_2().cmd_end_render_pass2)(cb, end) }, |d, raw| {
        mask::on_trigger(d, cb, Trigger::End);
        d.track.end_pass(raw)
    })
}

pub(super) unsafe extern "system" fn cmd_begin_rendering(cb: vk::CommandBuffer, info: *const vk::RenderingInfo<'_>) {
    hook_decided(
        "vkCmdBeginRendering",
        cb,
        (),
        // SAFETY: the app's valid info; `cb` is recording outside a pass (it is about to begin one).
        |d| unsafe { super::vrs::for_rendering(d, cb, info) },
        |d, decided| {
            let begin = d.fns.fp_v1_3().cmd_begin_rendering;
            match decided {
                // SAFETY: the app's info with variable-rate shading's attachment chained first.
                Some(Some(v)) => unsafe { begin(cb, &v.info) },
                // SAFETY: forwarding the app's arguments unchanged.
                _ => unsafe { begin(cb, info) },
            }
        },
        |d, _| {
            let raw = cb.as_raw();
            // SAFETY: a valid rendering info during the app's call.
            let (area, rendering) = unsafe { convert::rendering(&d.track, &*info) };
            let secondary = rendering.flags.contains(vk::RenderingFlags::CONTENTS_SECONDARY_COMMAND_BUFFERS);
            d.track.begin_rendering(raw, area, rendering);
            mask::on_trigger(d, cb, Trigger::Begin { secondary });
            Ok(())
        },
    )
}

pub(super) unsafe extern "system" fn cmd_end_rendering(cb: vk::CommandBuffer) {
    // SAFETY: forwarding the app's arguments unchanged.
    cmd("vkCmdEndRendering", cb, (), |d| unsafe { (d.fns.fp_v1_3().cmd_end_rendering)(cb) }, |d, raw| {
        mask::on_trigger(d, cb, Trigger::End);
        d.track.end_pass(raw)
    })
}

fn secondary_contents(info: *const vk::SubpassBeginInfo<'_>) -> bool {
    // SAFETY: null or a valid struct during the app's call.
    unsafe { info.as_ref() }.is_some_and(|i| i.contents == vk::SubpassContents::SECONDARY_COMMAND_BUFFERS)
}

// ---------------------------------------------------------------------------------------------
// Vertex buffers (restored after a mask draw), transfers (intermediate eye targets), clears

pub(super) unsafe extern "system" fn cmd_bind_vertex_buffers(cb: vk::CommandBuffer, first: u32, n: u32, buffers: *const vk::Buffer, offsets: *const vk::DeviceSize) {
    // SAFETY: forwarding the app's arguments unchanged.
    cmd("vkCmdBindVertexBuffers", cb, (), |d| unsafe { (d.fns.fp_v1_0().cmd_bind_vertex_buffers)(cb, first, n, buffers, offsets) }, |d, cb| {
        // SAFETY: arrays valid with their counts during the app's call.
        let bindings = unsafe { convert::vertex_bindings(n, buffers, offsets, std::ptr::null(), std::ptr::null(), false) };
        state(d, cb, StateCmd::BindVertexBuffers { first, bindings })
    })
}

pub(super) unsafe extern "system" fn cmd_bind_vertex_buffers2(
    cb: vk::CommandBuffer,
    first: u32,
    n: u32,
    buffers: *const vk::Buffer,
    offsets: *const vk::DeviceSize,
    sizes: *const vk::DeviceSize,
    strides: *const vk::DeviceSize,
) {
    cmd(
        "vkCmdBindVertexBuffers2",
        cb,
        (),
        // SAFETY: forwarding the app's arguments unchanged.
        |d| unsafe { (d.fns.fp_v1_3().cmd_bind_vertex_buffers2)(cb, first, n, buffers, offsets, sizes, strides) },
        |d, cb| {
            // SAFETY: arrays valid with their counts (optional ones null) during the app's call.
            let bindings = unsafe { convert::vertex_bindings(n, buffers, offsets, sizes, strides, true) };
            state(d, cb, StateCmd::BindVertexBuffers { first, bindings })
        },
    )
}

fn transfer(d: &DeviceState, src: vk::Image, dst: vk::Image, regions: Vec<crate::track::eye_pass::TransferRegion>) {
    let settings = d.mask.settings(&d.config);
    if settings.enabled || settings.rdm {
        d.track.record_transfer(crate::shared::shared(), src.as_raw(), dst.as_raw(), &regions);
    }
    if settings.rdm {
        super::rdm::on_transfer(d, src.as_raw(), dst.as_raw(), &regions);
    }
}

pub(super) unsafe extern "system" fn cmd_copy_image(
    cb: vk::CommandBuffer,
    src: vk::Image,
    src_layout: vk::ImageLayout,
    dst: vk::Image,
    dst_layout: vk::ImageLayout,
    n: u32,
    regions: *const vk::ImageCopy,
) {
    cmd(
        "vkCmdCopyImage",
        cb,
        (),
        // SAFETY: forwarding the app's arguments unchanged.
        |d| unsafe { (d.fns.fp_v1_0().cmd_copy_image)(cb, src, src_layout, dst, dst_layout, n, regions) },
        // SAFETY: the region array is valid with its count.
        |d, _| transfer(d, src, dst, unsafe { convert::slice(regions, n) }.iter().map(convert::copy_region).collect()),
    )
}

pub(super) unsafe extern "system" fn cmd_copy_image2(cb: vk::CommandBuffer, info: *const vk::CopyImageInfo2<'_>) {
    // SAFETY: forwarding the app's arguments unchanged.
    cmd("vkCmdCopyImage2", cb, (), |d| unsafe { (d.fns.fp_v1_3().cmd_copy_image2)(cb, info) }, |d, _| {
        // SAFETY: a valid info with a valid region array.
        let (i, regions) = unsafe { (&*info, convert::slice((*info).p_regions, (*info).region_count)) };
        let regions = regions
            .iter()
            .map(|r| convert::copy_region(&vk::ImageCopy { src_subresource: r.src_subresource, src_offset: r.src_offset, dst_subresource: r.dst_subresource, dst_offset: r.dst_offset, extent: r.extent }))
            .collect();
        transfer(d, i.src_image, i.dst_image, regions)
    })
}

pub(super) unsafe extern "system" fn cmd_resolve_image(
    cb: vk::CommandBuffer,
    src: vk::Image,
    src_layout: vk::ImageLayout,
    dst: vk::Image,
    dst_layout: vk::ImageLayout,
    n: u32,
    regions: *const vk::ImageResolve,
) {
    cmd(
        "vkCmdResolveImage",
        cb,
        (),
        // SAFETY: forwarding the app's arguments unchanged.
        |d| unsafe { (d.fns.fp_v1_0().cmd_resolve_image)(cb, src, src_layout, dst, dst_layout, n, regions) },
        |d, _| {
            // SAFETY: the region array is valid with its count.
            let regions = unsafe { convert::slice(regions, n) }
                .iter()
                .map(|r| convert::copy_region(&vk::ImageCopy { src_subresource: r.src_subresource, src_offset: r.src_offset, dst_subresource: r.dst_subresource, dst_offset: r.dst_offset, extent: r.extent }))
                .collect();
            transfer(d, src, dst, regions)
        },
    )
}

pub(super) unsafe extern "system" fn cmd_resolve_image2(cb: vk::CommandBuffer, info: *const vk::ResolveImageInfo2<'_>) {
    // SAFETY: forwarding the app's arguments unchanged.
    cmd("vkCmdResolveImage2", cb, (), |d| unsafe { (d.fns.fp_v1_3().cmd_resolve_image2)(cb, info) }, |d, _| {
        // SAFETY: a valid info with a valid region array.
        let (i, regions) = unsafe { (&*info, convert::slice((*info).p_regions, (*info).region_count)) };
        let regions = regions
            .iter()
            .map(|r| convert::copy_region(&vk::ImageCopy { src_subresource: r.src_subresource, src_offset: r.src_offset, dst_subresource: r.dst_subresource, dst_offset: r.dst_offset, extent: r.extent }))
            .collect();
        transfer(d, i.src_image, i.dst_image, regions)
    })
}

#[allow(clippy::too_many_arguments)]
pub(super) unsafe extern "system" fn cmd_blit_image(
    cb: vk::CommandBuffer,
    src: vk::Image,
    src_layout: vk::ImageLayout,
    dst: vk::Image,
    dst_layout: vk::ImageLayout,
    n: u32,
    regions: *const vk::ImageBlit,
    filter: vk::Filter,
) {
    cmd(
        "vkCmdBlitImage",
        cb,
        (),
        // SAFETY: forwarding the app's arguments unchanged.
        |d| unsafe { (d.fns.fp_v1_0().cmd_blit_image)(cb, src, src_layout, dst, dst_layout, n, regions, filter) },
        |d, _| {
            // SAFETY: the region array is valid with its count.
            let regions = unsafe { convert::slice(regions, n) }
                .iter()
                .filter_map(|r| convert::blit_region(r.src_subresource, r.src_offsets, r.dst_subresource, r.dst_offsets))
                .collect();
            transfer(d, src, dst, regions)
        },
    )
}

pub(super) unsafe extern "system" fn cmd_blit_image2(cb: vk::CommandBuffer, info: *const vk::BlitImageInfo2<'_>) {
    // SAFETY: forwarding the app's arguments unchanged.
    cmd("vkCmdBlitImage2", cb, (), |d| unsafe { (d.fns.fp_v1_3().cmd_blit_image2)(cb, info) }, |d, _| {
        // SAFETY: a valid info with a valid region array.
        let (i, regions) = unsafe { (&*info, convert::slice((*info).p_regions, (*info).region_count)) };
        let regions = regions
            .iter()
            .filter_map(|r| convert::blit_region(r.src_subresource, r.src_offsets, r.dst_subresource, r.dst_offsets))
            .collect();
        transfer(d, i.src_image, i.dst_image, regions)
    })
}

pub(super) unsafe extern "system" fn cmd_clear_attachments(
    cb: vk::CommandBuffer,
    n: u32,
    attachments: *const vk::ClearAttachment,
    rect_count: u32,
    rects: *const vk::ClearRect,
) {
    cmd(
        "vkCmdClearAttachments",
        cb,
        (),
        // SAFETY: forwarding the app's arguments unchanged.
        |d| unsafe { (d.fns.fp_v1_0().cmd_clear_attachments)(cb, n, attachments, rect_count, rects) },
        |d, _| {
            if !d.mask.settings(&d.config).any() {
                return;
            }
            // SAFETY: arrays valid with their counts during the app's call.
            let (atts, rects) = unsafe { (convert::slice(attachments, n), convert::slice(rects, rect_count)) };
            let depth = atts.iter().find(|a| a.aspect_mask.contains(vk::ImageAspectFlags::DEPTH));
            if let Some(a) = depth {
                // SAFETY: a depth clear's value is the depthStencil member.
                let value = unsafe { a.clear_value.depth_stencil.depth };
                let rects = rects.iter().map(|r| crate::mask::PixelRect { x: r.rect.offset.x, y: r.rect.offset.y, width: r.rect.extent.width, height: r.rect.extent.height }).collect();
                mask::on_trigger(d, cb, Trigger::Clear { depth: value, rects });
            }
        },
    )
}

pub(super) unsafe extern "system" fn cmd_clear_depth_stencil_image(
    cb: vk::CommandBuffer,
    image: vk::Image,
    layout: vk::ImageLayout,
    value: *const vk::ClearDepthStencilValue,
    n: u32,
    ranges: *const vk::ImageSubresourceRange,
) {
    cmd(
        "vkCmdClearDepthStencilImage",
        cb,
        (),
        // SAFETY: forwarding the app's arguments unchanged.
        |d| unsafe { (d.fns.fp_v1_0().cmd_clear_depth_stencil_image)(cb, image, layout, value, n, ranges) },
        |d, raw| {
            if !d.mask.settings(&d.config).any() {
                return;
            }
            // SAFETY: valid pointers during the app's call.
            let (value, ranges) = unsafe { ((*value).depth, convert::slice(ranges, n)) };
            if ranges.iter().any(|r| r.aspect_mask.contains(vk::ImageAspectFlags::DEPTH)) {
                d.track.with_cb(raw, |s| {
                    s.depth_image_clears.retain(|(i, _)| *i != image.as_raw());
                    if s.depth_image_clears.len() < 64 {
                        s.depth_image_clears.push((image.as_raw(), value));
                    }
                });
            }
        },
    )
}

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
    fn unknown_prefix_structs_decline() {
        let mut app_fsr = vk::PhysicalDeviceFragmentShadingRateFeaturesKHR::default();
        let mut odd = vk::PhysicalDeviceMeshShaderFeaturesEXT::default();
        let ci = vk::DeviceCreateInfo::default().push_next(&mut app_fsr).push_next(&mut odd);
        // SAFETY: a valid create info.
        assert!(unsafe { modify_device_create_info(&ci, &decision()) }.is_err());
    }
}
