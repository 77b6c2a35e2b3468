//! XR_KHR_vulkan_enable / XR_KHR_vulkan_enable2 and the runtime's own Vulkan access.
//!
//! The runtime does its Vulkan work (swapchain images, layout transitions, capture copies) on
//! the app's VkDevice and the binding's queue, through function pointers resolved from the
//! app's vkGetInstanceProcAddr (enable2) or the system loader (enable). That is exactly the
//! path a Vulkan layer sits on, so a layer that breaks the device breaks the runtime here too.

use std::ffi::{c_char, c_void, CString};
use std::sync::{Mutex, OnceLock};

use ash::vk;
use ash::vk::Handle;
use openxr_sys as xr;

use crate::instance::{self, Instance};
use crate::system::check_system;
use crate::util::{guard, input, out_ptr, output, two_call_str, XrResult};

/// Instance extensions a compositor sharing images across processes would need; lavapipe has them.
pub const INSTANCE_EXTENSIONS: &[&str] = &[
    "VK_KHR_external_memory_capabilities",
    "VK_KHR_external_semaphore_capabilities",
    "VK_KHR_external_fence_capabilities",
    "VK_KHR_get_physical_device_properties2",
];

/// `INSTANCE_EXTENSIONS` less those `MOCK_XR_DISABLE_EXTENSIONS` names (a runtime that lists
/// fewer, so an app or layer has to bring the rest itself).
fn instance_extensions(inst: &Instance) -> Vec<&'static str> {
    INSTANCE_EXTENSIONS.iter().copied().filter(|e| !inst.cfg.disabled_extensions.contains(*e)).collect()
}

/// `DEVICE_EXTENSIONS` likewise.
fn device_extensions(inst: &Instance) -> Vec<&'static str> {
    DEVICE_EXTENSIONS.iter().copied().filter(|e| !inst.cfg.disabled_extensions.contains(*e)).collect()
}

/// Device extensions likewise.
pub const DEVICE_EXTENSIONS: &[&str] = &[
    "VK_KHR_external_memory",
    "VK_KHR_external_memory_fd",
    "VK_KHR_external_semaphore",
    "VK_KHR_external_fence",
    "VK_KHR_dedicated_allocation",
    "VK_KHR_get_memory_requirements2",
];

pub fn vk_err(what: &str) -> impl Fn(vk::Result) -> xr::Result + '_ {
    move |e| {
        eprintln!("[mock-runtime] {what} failed: {e:?}");
        xr::Result::ERROR_RUNTIME_FAILURE
    }
}

fn system_entry() -> XrResult<&'static ash::Entry> {
    static ENTRY: OnceLock<Option<ash::Entry>> = OnceLock::new();
    // SAFETY: loading the system Vulkan loader library; it stays loaded for the process.
    ENTRY
        .get_or_init(|| unsafe { ash::Entry::load() }.ok())
        .as_ref()
        .ok_or(xr::Result::ERROR_RUNTIME_FAILURE)
}

fn to_ash_gipa(f: xr::platform::VkGetInstanceProcAddr) -> vk::PFN_vkGetInstanceProcAddr {
    // SAFETY: both are `vkGetInstanceProcAddr(VkInstance, const char*) -> PFN_vkVoidFunction`;
    // VkInstance is pointer-sized in both bindings.
    unsafe { std::mem::transmute::<xr::platform::VkGetInstanceProcAddr, vk::PFN_vkGetInstanceProcAddr>(f) }
}

/// vkGetInstanceProcAddr for `vk_instance`: the app's, when it created the instance through
/// xrCreateVulkanInstanceKHR, else the system loader's.
fn gipa_for(inst: &Instance, vk_instance: usize) -> XrResult<vk::PFN_vkGetInstanceProcAddr> {
    let recorded = inst.vk.lock().unwrap().created.iter().find(|(i, _)| *i == vk_instance).map(|(_, f)| *f);
    match recorded {
        Some(f) => Ok(to_ash_gipa(f)),
        None => Ok(system_entry()?.static_fn().get_instance_proc_addr),
    }
}

fn load_instance(inst: &Instance, vk_instance: usize) -> XrResult<ash::Instance> {
    let gipa = gipa_for(inst, vk_instance)?;
    // SAFETY: `vk_instance` is a live VkInstance of the app (validity is the app's contract);
    // ash only resolves function pointers here.
    Ok(unsafe { ash::Instance::load(&ash::StaticFn { get_instance_proc_addr: gipa }, vk::Instance::from_raw(vk_instance as u64)) })
}

/// The session's view of the app's Vulkan objects plus the runtime's own command pool.
pub struct VkContext {
    pub instance: ash::Instance,
    pub device: ash::Device,
    pub physical: vk::PhysicalDevice,
    pub queue: vk::Queue,
    pub queue_family: u32,
    pub mem_props: vk::PhysicalDeviceMemoryProperties,
    /// The runtime's command pool. Its lock also serialises the runtime's own queue use; it is
    /// the only lock held across Vulkan calls and no entry point takes another lock inside it.
    pool: Mutex<Option<vk::CommandPool>>,
}

impl VkContext {
    pub fn new(inst: &Instance, b: &xr::GraphicsBindingVulkanKHR) -> XrResult<VkContext> {
        if b.instance.is_null() || b.physical_device.is_null() || b.device.is_null() {
            crate::log!("xrCreateSession: null Vulkan handle in the binding");
            return Err(xr::Result::ERROR_GRAPHICS_DEVICE_INVALID);
        }
        let vk_inst = b.instance as usize;
        let instance = load_instance(inst, vk_inst)?;
        let phys = vk::PhysicalDevice::from_raw(b.physical_device as u64);
        // SAFETY: valid instance per the app's contract.
        let devices = unsafe { instance.enumerate_physical_devices() }.map_err(vk_err("vkEnumeratePhysicalDevices"))?;
        if !devices.contains(&phys) {
            crate::log!("xrCreateSession: physical device is not one of the instance's");
            return Err(xr::Result::ERROR_GRAPHICS_DEVICE_INVALID);
        }
        if let Some((i, p)) = inst.vk.lock().unwrap().graphics_device {
            if i == vk_inst && p != b.physical_device as usize {
                crate::log!("xrCreateSession: not the physical device xrGetVulkanGraphicsDevice returned");
                return Err(xr::Result::ERROR_GRAPHICS_DEVICE_INVALID);
            }
        }
        // SAFETY: `phys` belongs to `instance` (checked above).
        let families = unsafe { instance.get_physical_device_queue_family_properties(phys) };
        let family = families.get(b.queue_family_index as usize).ok_or_else(|| {
            crate::log!("xrCreateSession: queue family {} does not exist", b.queue_family_index);
            xr::Result::ERROR_VALIDATION_FAILURE
        })?;
        if b.queue_index >= family.queue_count {
            crate::log!("xrCreateSession: queue index {} out of range", b.queue_index);
            return Err(xr::Result::ERROR_VALIDATION_FAILURE);
        }
        // SAFETY: as above.
        let mem_props = unsafe { instance.get_physical_device_memory_properties(phys) };
        // SAFETY: the app's live VkDevice created from `phys`.
        let device = unsafe { ash::Device::load(instance.fp_v1_0(), vk::Device::from_raw(b.device as u64)) };
        // SAFETY: the family/index exist on the device (the app created its queues there).
        let queue = unsafe { device.get_device_queue(b.queue_family_index, b.queue_index) };
        let pool_info = vk::CommandPoolCreateInfo::default()
            .queue_family_index(b.queue_family_index)
            .flags(vk::CommandPoolCreateFlags::TRANSIENT);
        // SAFETY: valid device and create info.
        let pool = unsafe { device.create_command_pool(&pool_info, None) }.map_err(vk_err("vkCreateCommandPool"))?;
        Ok(VkContext {
            instance,
            device,
            physical: phys,
            queue,
            queue_family: b.queue_family_index,
            mem_props,
            pool: Mutex::new(Some(pool)),
        })
    }

    pub fn memory_type(&self, bits: u32, flags: vk::MemoryPropertyFlags) -> XrResult<u32> {
        (0..self.mem_props.memory_type_count)
            .find(|&i| bits & (1 << i) != 0 && self.mem_props.memory_types[i as usize].property_flags.contains(flags))
            .ok_or_else(|| {
                eprintln!("[mock-runtime] no memory type with {flags:?}");
                xr::Result::ERROR_RUNTIME_FAILURE
            })
    }

    /// Records one command buffer, submits it on the binding's queue and waits for its fence.
    /// Only called from functions the Vulkan binding spec lets touch the queue.
    pub fn submit_and_wait(&self, record: impl FnOnce(&ash::Device, vk::CommandBuffer)) -> XrResult<()> {
        let pool_guard = self.pool.lock().unwrap();
        let pool = pool_guard.ok_or(xr::Result::ERROR_SESSION_LOST)?;
        let d = &self.device;
        let alloc = vk::CommandBufferAllocateInfo::default()
            .command_pool(pool)
            .level(vk::CommandBufferLevel::PRIMARY)
            .command_buffer_count(1);
        // SAFETY: the pool is externally synchronised by `pool_guard`; all handles are valid.
        unsafe {
            let cb = d.allocate_command_buffers(&alloc).map_err(vk_err("vkAllocateCommandBuffers"))?[0];
            let result = (|| {
                d.begin_command_buffer(cb, &vk::CommandBufferBeginInfo::default().flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT))
                    .map_err(vk_err("vkBeginCommandBuffer"))?;
                record(d, cb);
                d.end_command_buffer(cb).map_err(vk_err("vkEndCommandBuffer"))?;
                let fence = d.create_fence(&vk::FenceCreateInfo::default(), None).map_err(vk_err("vkCreateFence"))?;
                let cbs = [cb];
                let submit = vk::SubmitInfo::default().command_buffers(&cbs);
                let r = d
                    .queue_submit(self.queue, &[submit], fence)
                    .map_err(vk_err("vkQueueSubmit"))
                    .and_then(|_| d.wait_for_fences(&[fence], true, u64::MAX).map_err(vk_err("vkWaitForFences")));
                d.destroy_fence(fence, None);
                r
            })();
            d.free_command_buffers(pool, &[cb]);
            result
        }
    }

    /// Waits until the runtime's and the app's work on the queue is done.
    pub fn queue_wait_idle(&self) {
        let _g = self.pool.lock().unwrap();
        // SAFETY: valid queue; our own use is serialised by the pool lock.
        if let Err(e) = unsafe { self.device.queue_wait_idle(self.queue) } {
            eprintln!("[mock-runtime] vkQueueWaitIdle failed: {e:?}");
        }
    }

    /// `MOCK_XR_REENTER=1`: from inside `call`, the runtime calls Vulkan on the app's device
    /// (through the top of the app's Vulkan chain, as all its calls do), as real runtimes do. Where
    /// the Vulkan binding lets it use the app's queue (`queue`: xrBeginFrame, xrEndFrame,
    /// xrAcquireSwapchainImage, xrReleaseSwapchainImage) it submits an empty command buffer and
    /// waits for its fence; elsewhere (xrWaitSwapchainImage, xrLocateViews) it makes and destroys
    /// an image and a command buffer, which need no queue. A layer above the runtime whose
    /// OpenXR half held a lock across its call down that its Vulkan half also takes would
    /// deadlock here (tests/reentry.rs). Counted per call; `report_reentries` prints the counts.
    pub fn reenter(&self, call: &'static str, queue: bool) -> XrResult<()> {
        if queue {
            self.submit_and_wait(|_, _| {})?;
        } else {
            let info = vk::ImageCreateInfo::default()
                .image_type(vk::ImageType::TYPE_2D)
                .format(vk::Format::R8G8B8A8_UNORM)
                .extent(vk::Extent3D { width: 4, height: 4, depth: 1 })
                .mip_levels(1)
                .array_layers(1)
                .samples(vk::SampleCountFlags::TYPE_1)
                .tiling(vk::ImageTiling::OPTIMAL)
                .usage(vk::ImageUsageFlags::COLOR_ATTACHMENT)
                .initial_layout(vk::ImageLayout::UNDEFINED);
            // SAFETY: a valid create info on the app's live device; the image is never used and
            // destroyed at once.
            unsafe {
                let image = self.device.create_image(&info, None).map_err(vk_err("vkCreateImage"))?;
                self.device.destroy_image(image, None);
            }
            let pool = self.pool.lock().unwrap();
            let pool = pool.ok_or(xr::Result::ERROR_SESSION_LOST)?;
            let alloc = vk::CommandBufferAllocateInfo::default().command_pool(pool).level(vk::CommandBufferLevel::PRIMARY).command_buffer_count(1);
            // SAFETY: the runtime's pool, synchronised by its lock (held); the buffer is never
            // recorded and freed at once.
            unsafe {
                let cbs = self.device.allocate_command_buffers(&alloc).map_err(vk_err("vkAllocateCommandBuffers"))?;
                self.device.free_command_buffers(pool, &cbs);
            }
        }
        *reentries().lock().unwrap().entry(call).or_insert(0) += 1;
        Ok(())
    }

    pub fn destroy_own_objects(&self) {
        let mut pool = self.pool.lock().unwrap();
        if let Some(p) = pool.take() {
            // SAFETY: every submission from this pool was waited on; the device is alive
            // (the app must destroy the session before its device).
            unsafe { self.device.destroy_command_pool(p, None) };
        }
    }
}

fn reentries() -> &'static Mutex<std::collections::BTreeMap<&'static str, u64>> {
    static COUNTS: OnceLock<Mutex<std::collections::BTreeMap<&'static str, u64>>> = OnceLock::new();
    COUNTS.get_or_init(Default::default)
}

/// Prints the re-entries made so far in this process (`MOCK_XR_REENTER`), one stderr line per
/// call, at each xrDestroySession.
pub fn report_reentries() {
    for (call, n) in reentries().lock().unwrap().iter() {
        eprintln!("[mock-runtime] re-entered Vulkan from {call}: {n} times");
    }
}

fn check_vk_ext(inst: &Instance, system_id: xr::SystemId, func: &'static str) -> XrResult<()> {
    check_system(system_id)?;
    inst.fail_point(func)
}

fn requirements(instance: xr::Instance, system_id: xr::SystemId, req: *mut xr::GraphicsRequirementsVulkanKHR, func: &'static str) -> XrResult {
    let inst = instance::get(instance)?;
    check_vk_ext(&inst, system_id, func)?;
    // SAFETY: app output struct, type-checked (VULKAN2 has the same type value).
    let r = unsafe { output(req) }?;
    r.min_api_version_supported = xr::Version::new(1, 0, 0);
    r.max_api_version_supported = xr::Version::new(1, 3, 0);
    inst.vk.lock().unwrap().requirements_called = true;
    Ok(xr::Result::SUCCESS)
}

pub unsafe extern "system" fn xr_get_vulkan_graphics_requirements_khr(
    instance: xr::Instance,
    system_id: xr::SystemId,
    req: *mut xr::GraphicsRequirementsVulkanKHR,
) -> xr::Result {
    guard("xrGetVulkanGraphicsRequirementsKHR", || requirements(instance, system_id, req, "xrGetVulkanGraphicsRequirementsKHR"))
}

pub unsafe extern "system" fn xr_get_vulkan_graphics_requirements2_khr(
    instance: xr::Instance,
    system_id: xr::SystemId,
    req: *mut xr::GraphicsRequirementsVulkanKHR,
) -> xr::Result {
    guard("xrGetVulkanGraphicsRequirements2KHR", || requirements(instance, system_id, req, "xrGetVulkanGraphicsRequirements2KHR"))
}

pub unsafe extern "system" fn xr_get_vulkan_instance_extensions_khr(
    instance: xr::Instance,
    system_id: xr::SystemId,
    capacity: u32,
    count_out: *mut u32,
    buffer: *mut c_char,
) -> xr::Result {
    guard("xrGetVulkanInstanceExtensionsKHR", || {
        let inst = instance::get(instance)?;
        check_vk_ext(&inst, system_id, "xrGetVulkanInstanceExtensionsKHR")?;
        // SAFETY: app buffer of `capacity` chars.
        unsafe { two_call_str(capacity, count_out, buffer, &instance_extensions(&inst).join(" ")) }?;
        Ok(xr::Result::SUCCESS)
    })
}

pub unsafe extern "system" fn xr_get_vulkan_device_extensions_khr(
    instance: xr::Instance,
    system_id: xr::SystemId,
    capacity: u32,
    count_out: *mut u32,
    buffer: *mut c_char,
) -> xr::Result {
    guard("xrGetVulkanDeviceExtensionsKHR", || {
        let inst = instance::get(instance)?;
        check_vk_ext(&inst, system_id, "xrGetVulkanDeviceExtensionsKHR")?;
        // SAFETY: app buffer of `capacity` chars.
        unsafe { two_call_str(capacity, count_out, buffer, &device_extensions(&inst).join(" ")) }?;
        Ok(xr::Result::SUCCESS)
    })
}

fn graphics_device(inst: &Instance, vk_instance: *const c_void) -> XrResult<*const c_void> {
    if vk_instance.is_null() {
        return Err(xr::Result::ERROR_VALIDATION_FAILURE);
    }
    let i = load_instance(inst, vk_instance as usize)?;
    // SAFETY: the app's live VkInstance.
    let devices = unsafe { i.enumerate_physical_devices() }.map_err(vk_err("vkEnumeratePhysicalDevices"))?;
    let phys = *devices.first().ok_or(xr::Result::ERROR_RUNTIME_FAILURE)?;
    inst.vk.lock().unwrap().graphics_device = Some((vk_instance as usize, phys.as_raw() as usize));
    Ok(phys.as_raw() as usize as *const c_void)
}

pub unsafe extern "system" fn xr_get_vulkan_graphics_device_khr(
    instance: xr::Instance,
    system_id: xr::SystemId,
    vk_instance: xr::platform::VkInstance,
    phys: *mut xr::platform::VkPhysicalDevice,
) -> xr::Result {
    guard("xrGetVulkanGraphicsDeviceKHR", || {
        let inst = instance::get(instance)?;
        check_vk_ext(&inst, system_id, "xrGetVulkanGraphicsDeviceKHR")?;
        // SAFETY: app output pointer.
        let out = unsafe { out_ptr(phys) }?;
        *out = graphics_device(&inst, vk_instance)?;
        Ok(xr::Result::SUCCESS)
    })
}

pub unsafe extern "system" fn xr_get_vulkan_graphics_device2_khr(
    instance: xr::Instance,
    info: *const xr::VulkanGraphicsDeviceGetInfoKHR,
    phys: *mut xr::platform::VkPhysicalDevice,
) -> xr::Result {
    guard("xrGetVulkanGraphicsDevice2KHR", || {
        let inst = instance::get(instance)?;
        // SAFETY: app pointers.
        let (info, out) = unsafe { (input(info)?, out_ptr(phys)?) };
        check_vk_ext(&inst, info.system_id, "xrGetVulkanGraphicsDevice2KHR")?;
        *out = graphics_device(&inst, info.vulkan_instance)?;
        Ok(xr::Result::SUCCESS)
    })
}

/// The app's extension list plus `extra` names it lacks, as a new array (the app's create info
/// is never modified).
///
/// # Safety
/// `names` must hold `count` NUL-terminated strings.
unsafe fn merged_extensions(names: *const *const c_char, count: u32, extra: &[&str]) -> XrResult<(Vec<CString>, Vec<*const c_char>)> {
    // SAFETY: per contract.
    let app: Vec<*const c_char> = unsafe { crate::util::slice(names, count) }?.to_vec();
    let mut present = Vec::new();
    for &p in &app {
        // SAFETY: per contract.
        present.push(unsafe { crate::util::read_cstr(p) }?);
    }
    let owned: Vec<CString> = extra
        .iter()
        .filter(|e| !present.iter().any(|p| p == *e))
        .map(|e| CString::new(*e).unwrap())
        .collect();
    let mut ptrs = app;
    ptrs.extend(owned.iter().map(|c| c.as_ptr()));
    Ok((owned, ptrs))
}

pub unsafe extern "system" fn xr_create_vulkan_instance_khr(
    instance: xr::Instance,
    info: *const xr::VulkanInstanceCreateInfoKHR,
    vk_instance: *mut xr::platform::VkInstance,
    vk_result: *mut xr::platform::VkResult,
) -> xr::Result {
    guard("xrCreateVulkanInstanceKHR", || {
        let inst = instance::get(instance)?;
        // SAFETY: app pointers.
        let (info, out, res) = unsafe { (input(info)?, out_ptr(vk_instance)?, out_ptr(vk_result)?) };
        check_vk_ext(&inst, info.system_id, "xrCreateVulkanInstanceKHR")?;
        if info.create_flags != xr::VulkanInstanceCreateFlagsKHR::EMPTY || info.vulkan_create_info.is_null() {
            return Err(xr::Result::ERROR_VALIDATION_FAILURE);
        }
        let app_gipa = info.pfn_get_instance_proc_addr.ok_or(xr::Result::ERROR_VALIDATION_FAILURE)?;
        // SAFETY: the app's VkInstanceCreateInfo.
        let app_ci = unsafe { *(info.vulkan_create_info as *const vk::InstanceCreateInfo) };
        if app_ci.s_type != vk::StructureType::INSTANCE_CREATE_INFO {
            return Err(xr::Result::ERROR_VALIDATION_FAILURE);
        }
        // SAFETY: the app's extension array.
        let (_keep, names) = unsafe { merged_extensions(app_ci.pp_enabled_extension_names, app_ci.enabled_extension_count, &instance_extensions(&inst)) }?;
        let mut ci = app_ci;
        ci.enabled_extension_count = names.len() as u32;
        ci.pp_enabled_extension_names = names.as_ptr();
        let gipa = to_ash_gipa(app_gipa);
        // SAFETY: global-level lookup through the app's loader entry point.
        let create = unsafe { gipa(vk::Instance::null(), c"vkCreateInstance".as_ptr()) }.ok_or(xr::Result::ERROR_RUNTIME_FAILURE)?;
        // SAFETY: vkCreateInstance's signature.
        let create: vk::PFN_vkCreateInstance = unsafe { std::mem::transmute(create) };
        let mut handle = vk::Instance::null();
        // SAFETY: `ci` and everything it points to outlive the call; allocator is the app's.
        let r = unsafe { create(&ci, info.vulkan_allocator as *const vk::AllocationCallbacks, &mut handle) };
        *res = r.as_raw();
        crate::log!("xrCreateVulkanInstanceKHR: vkCreateInstance -> {r:?}");
        if r == vk::Result::SUCCESS {
            inst.vk.lock().unwrap().created.push((handle.as_raw() as usize, app_gipa));
            *out = handle.as_raw() as usize as *const c_void;
        }
        Ok(xr::Result::SUCCESS)
    })
}

pub unsafe extern "system" fn xr_create_vulkan_device_khr(
    instance: xr::Instance,
    info: *const xr::VulkanDeviceCreateInfoKHR,
    vk_device: *mut xr::platform::VkDevice,
    vk_result: *mut xr::platform::VkResult,
) -> xr::Result {
    guard("xrCreateVulkanDeviceKHR", || {
        let inst = instance::get(instance)?;
        // SAFETY: app pointers.
        let (info, out, res) = unsafe { (input(info)?, out_ptr(vk_device)?, out_ptr(vk_result)?) };
        check_vk_ext(&inst, info.system_id, "xrCreateVulkanDeviceKHR")?;
        if info.create_flags != xr::VulkanDeviceCreateFlagsKHR::EMPTY
            || info.vulkan_create_info.is_null()
            || info.vulkan_physical_device.is_null()
        {
            return Err(xr::Result::ERROR_VALIDATION_FAILURE);
        }
        let app_gipa = info.pfn_get_instance_proc_addr.ok_or(xr::Result::ERROR_VALIDATION_FAILURE)?;
        let (vk_inst, phys) = inst.vk.lock().unwrap().graphics_device.ok_or_else(|| {
            crate::log!("xrCreateVulkanDeviceKHR before xrGetVulkanGraphicsDevice2KHR");
            xr::Result::ERROR_CALL_ORDER_INVALID
        })?;
        if phys != info.vulkan_physical_device as usize {
            return Err(xr::Result::ERROR_GRAPHICS_DEVICE_INVALID);
        }
        // SAFETY: the app's VkDeviceCreateInfo.
        let app_ci = unsafe { *(info.vulkan_create_info as *const vk::DeviceCreateInfo) };
        if app_ci.s_type != vk::StructureType::DEVICE_CREATE_INFO {
            return Err(xr::Result::ERROR_VALIDATION_FAILURE);
        }
        let gipa = to_ash_gipa(app_gipa);
        let ash_inst =
            // SAFETY: the instance the physical device came from; ash only resolves pointers.
            unsafe { ash::Instance::load(&ash::StaticFn { get_instance_proc_addr: gipa }, vk::Instance::from_raw(vk_inst as u64)) };
        let pd = vk::PhysicalDevice::from_raw(phys as u64);
        // SAFETY: valid physical device of that instance.
        let available = unsafe { ash_inst.enumerate_device_extension_properties(pd) }.map_err(vk_err("vkEnumerateDeviceExtensionProperties"))?;
        let wanted: Vec<&str> = device_extensions(&inst)
            .into_iter()
            .filter(|e| available.iter().any(|a| a.extension_name_as_c_str().is_ok_and(|n| n.to_str() == Ok(*e))))
            .collect();
        // SAFETY: the app's extension array.
        let (_keep, names) = unsafe { merged_extensions(app_ci.pp_enabled_extension_names, app_ci.enabled_extension_count, &wanted) }?;
        let mut ci = app_ci;
        ci.enabled_extension_count = names.len() as u32;
        ci.pp_enabled_extension_names = names.as_ptr();
        let mut handle = vk::Device::null();
        // SAFETY: `ci` and what it points to outlive the call; through the app's dispatch.
        let r = unsafe { (ash_inst.fp_v1_0().create_device)(pd, &ci, info.vulkan_allocator as *const vk::AllocationCallbacks, &mut handle) };
        *res = r.as_raw();
        crate::log!("xrCreateVulkanDeviceKHR: vkCreateDevice -> {r:?}");
        if r == vk::Result::SUCCESS {
            *out = handle.as_raw() as usize as *const c_void;
        }
        Ok(xr::Result::SUCCESS)
    })
}
