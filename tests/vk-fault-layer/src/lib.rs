//! A fault-injecting Vulkan layer for stereoshim's tests (docs/testing.md, tests/faults_vk.rs).
//!
//! One library, two layers, told apart by the negotiation function their manifests name:
//! - the **lower** instance (`vkfault_negotiate_lower`, an explicit layer the app enables last in
//!   its own `VkInstanceCreateInfo`, so it sits below stereoshim and next to the driver) passes
//!   every call through except those `VK_FAULT` names, which it fails without calling down
//!   (output handles set to `VK_NULL_HANDLE`), printing one line to stderr per failed call;
//! - the **marker** instance (`vkfault_negotiate_upper`, an implicit layer: the loader puts
//!   implicit layers nearest the app, above stereoshim) only notes, per thread, which intercepted
//!   call the app (or the runtime, which calls on the app's device) is making.
//!
//! Both instances are one loaded image (the loader `dlopen`s one file), so the lower one knows
//! whether a call it sees was made by the app — the marker is inside the same call on the same
//! thread — or by the layer in between for its own objects (`spec::Origin`).
//!
//! With `VK_FAULT_COUNT=1` the lower instance also keeps the live handles of the objects it sees
//! created, by origin, and prints their counts (`count`).
//!
//! With `VK_FAULT_REENTER` the lower instance also calls back up to the top of the chain from
//! inside chosen calls (`reenter`), proving that the layers above hold no lock across their calls
//! down.
//!
//! Written from the loader's documented layer interface (LoaderLayerInterface.md, `vk_layer.h`).

pub mod spec;
mod count;
mod hooks;
mod reenter;

use ash::vk;
use std::collections::HashMap;
use std::ffi::{c_char, c_void, CStr};
use std::sync::{Arc, Mutex, OnceLock};

// ---------------------------------------------------------------------------------------------
// The loader's interface structs (vk_layer.h), only what this layer reads.

const LOADER_INSTANCE_CREATE_INFO: vk::StructureType = vk::StructureType::from_raw(47);
const LOADER_DEVICE_CREATE_INFO: vk::StructureType = vk::StructureType::from_raw(48);
/// `VK_LAYER_LINK_INFO`: the create info's union holds the list of layers below.
const LAYER_LINK_INFO: i32 = 0;
const LAYER_NEGOTIATE_INTERFACE_STRUCT: i32 = 1;

/// `VkNegotiateLayerInterface`.
#[repr(C)]
pub struct NegotiateLayerInterface {
    s_type: i32,
    p_next: *mut c_void,
    loader_layer_interface_version: u32,
    pfn_get_instance_proc_addr: Option<vk::PFN_vkGetInstanceProcAddr>,
    pfn_get_device_proc_addr: Option<vk::PFN_vkGetDeviceProcAddr>,
    pfn_get_physical_device_proc_addr: *const c_void,
}

/// `VkLayerInstanceLink`.
#[repr(C)]
struct InstanceLink {
    p_next: *mut InstanceLink,
    next_gipa: vk::PFN_vkGetInstanceProcAddr,
    next_gpdpa: *const c_void,
}

/// `VkLayerDeviceLink`.
#[repr(C)]
struct DeviceLink {
    p_next: *mut DeviceLink,
    next_gipa: vk::PFN_vkGetInstanceProcAddr,
    next_gdpa: vk::PFN_vkGetDeviceProcAddr,
}

/// The common head of `VkLayerInstanceCreateInfo` and `VkLayerDeviceCreateInfo` up to the first
/// union member, which is the link pointer when `function` is `VK_LAYER_LINK_INFO`.
#[repr(C)]
struct LayerCreateInfo<L> {
    s_type: vk::StructureType,
    p_next: *const c_void,
    function: i32,
    p_layer_info: *mut L,
}

// ---------------------------------------------------------------------------------------------
// Per-role state

/// The next layer's entry points for one instance.
struct Instance {
    handle: vk::Instance,
    next_gipa: vk::PFN_vkGetInstanceProcAddr,
    destroy: vk::PFN_vkDestroyInstance,
}

/// The next layer's entry points for one device: `fns[i]` is command `spec::FUNCS[i]`,
/// `reenter_fns[i]` command `spec::REENTER_ONLY[i]`, `count_fns[i]` command `count::next_names()[i]`.
struct Device {
    handle: vk::Device,
    next_gdpa: vk::PFN_vkGetDeviceProcAddr,
    destroy: vk::PFN_vkDestroyDevice,
    fns: Vec<vk::PFN_vkVoidFunction>,
    reenter_fns: Vec<vk::PFN_vkVoidFunction>,
    count_fns: Vec<vk::PFN_vkVoidFunction>,
    /// Re-entry (`VK_FAULT_REENTER`, lower instance only): the device's queues (handle → family),
    /// the family of its first queue create info, the top of the chain's functions and the
    /// re-entries made so far.
    reenter: reenter::DeviceReentry,
}

#[derive(Default)]
struct Role {
    instances: Mutex<HashMap<usize, Arc<Instance>>>,
    devices: Mutex<HashMap<usize, Arc<Device>>>,
}

/// The state of the marker (`upper`) or the lower instance: each is its own layer in the chain,
/// with its own next layer, though both see the same dispatch keys.
fn role(upper: bool) -> &'static Role {
    static ROLES: OnceLock<[Role; 2]> = OnceLock::new();
    &ROLES.get_or_init(Default::default)[upper as usize]
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    // A panic is caught at the entry point and leaves the maps consistent (inserts and removes
    // are single calls), so a poisoned lock is still usable.
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// The loader's dispatch key of a dispatchable handle (its first word); 0 for null.
fn dispatch_key<H: vk::Handle>(h: H) -> usize {
    let raw = h.as_raw();
    if raw == 0 {
        return 0;
    }
    // SAFETY: a dispatchable handle the loader passes to a layer points at an object whose first
    // word is the loader's dispatch table pointer (LoaderLayerInterface.md, "Dispatch table").
    unsafe { *(raw as usize as *const usize) }
}

fn device_state<const U: bool>(key: usize) -> Option<Arc<Device>> {
    lock(&role(U).devices).get(&key).cloned()
}

fn instance_state<const U: bool>(key: usize) -> Option<Arc<Instance>> {
    lock(&role(U).instances).get(&key).cloned()
}

/// Runs an entry point's body with no panic crossing the FFI boundary: a panic is reported on
/// stderr (the tests fail on that line) and `fallback` returned.
fn entry<R>(call: &str, fallback: R, f: impl FnOnce() -> R) -> R {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)).unwrap_or_else(|_| {
        eprintln!("vk-fault-layer: panic in {call}");
        fallback
    })
}

/// `VK_FAULT`, parsed once. A malformed value fails instance creation of the lower instance, so
/// a typo in a test can never pass as "no fault".
fn rules() -> &'static Result<Vec<spec::Rule>, String> {
    static RULES: OnceLock<Result<Vec<spec::Rule>, String>> = OnceLock::new();
    RULES.get_or_init(|| spec::parse(&std::env::var("VK_FAULT").unwrap_or_default()))
}

fn counters() -> &'static spec::Counters {
    static COUNTERS: OnceLock<spec::Counters> = OnceLock::new();
    COUNTERS.get_or_init(Default::default)
}

/// The loader's link struct of the given type in a create info's chain.
///
/// # Safety
/// `p_next` must be a valid structure chain.
unsafe fn link_info<L>(mut p_next: *const c_void, s_type: vk::StructureType) -> Option<*mut LayerCreateInfo<L>> {
    while !p_next.is_null() {
        // SAFETY: every struct of a valid chain starts with sType and pNext.
        let base = unsafe { &*(p_next as *const vk::BaseInStructure<'_>) };
        if base.s_type == s_type {
            let info = p_next as *mut LayerCreateInfo<L>;
            // SAFETY: a loader struct (its sType), whose head has this layout.
            if unsafe { (*info).function } == LAYER_LINK_INFO {
                return Some(info);
            }
        }
        p_next = base.p_next as *const c_void;
    }
    None
}

// ---------------------------------------------------------------------------------------------
// Negotiation and proc-addr functions

/// # Safety
/// Called by the loader with a valid `VkNegotiateLayerInterface`.
unsafe fn negotiate<const U: bool>(p: *mut NegotiateLayerInterface) -> vk::Result {
    entry("vkNegotiateLoaderLayerInterfaceVersion", vk::Result::ERROR_INITIALIZATION_FAILED, || {
        // SAFETY: the loader passes a valid, writable struct (or null, checked).
        let Some(v) = (unsafe { p.as_mut() }) else { return vk::Result::ERROR_INITIALIZATION_FAILED };
        if v.s_type != LAYER_NEGOTIATE_INTERFACE_STRUCT || v.loader_layer_interface_version < 2 {
            return vk::Result::ERROR_INITIALIZATION_FAILED;
        }
        v.loader_layer_interface_version = 2;
        v.pfn_get_instance_proc_addr = Some(get_instance_proc_addr::<U>);
        v.pfn_get_device_proc_addr = Some(get_device_proc_addr::<U>);
        v.pfn_get_physical_device_proc_addr = std::ptr::null();
        vk::Result::SUCCESS
    })
}

/// The lower (fault-injecting) layer's negotiation function, named in its manifest.
///
/// # Safety
/// Called by the Vulkan loader with a valid `VkNegotiateLayerInterface`.
#[no_mangle]
pub unsafe extern "system" fn vkfault_negotiate_lower(p: *mut NegotiateLayerInterface) -> vk::Result {
    // SAFETY: forwarded from the loader unchanged.
    unsafe { negotiate::<false>(p) }
}

/// The marker layer's negotiation function, named in its manifest.
///
/// # Safety
/// Called by the Vulkan loader with a valid `VkNegotiateLayerInterface`.
#[no_mangle]
pub unsafe extern "system" fn vkfault_negotiate_upper(p: *mut NegotiateLayerInterface) -> vk::Result {
    // SAFETY: forwarded from the loader unchanged.
    unsafe { negotiate::<true>(p) }
}

fn void<F: Copy>(f: F) -> vk::PFN_vkVoidFunction {
    assert_eq!(std::mem::size_of::<F>(), std::mem::size_of::<unsafe extern "system" fn()>());
    // SAFETY: only called with `extern "system"` function pointers (same size, checked); the
    // caller casts them back to their own type before calling.
    Some(unsafe { std::mem::transmute_copy::<F, unsafe extern "system" fn()>(&f) })
}

unsafe extern "system" fn get_instance_proc_addr<const U: bool>(instance: vk::Instance, name: *const c_char) -> vk::PFN_vkVoidFunction {
    entry("vkGetInstanceProcAddr", None, || {
        if name.is_null() {
            return None;
        }
        // SAFETY: a NUL-terminated name (checked non-null).
        let n = unsafe { CStr::from_ptr(name) }.to_bytes();
        match n {
            b"vkGetInstanceProcAddr" => return void(get_instance_proc_addr::<U> as vk::PFN_vkGetInstanceProcAddr),
            b"vkGetDeviceProcAddr" => return void(get_device_proc_addr::<U> as vk::PFN_vkGetDeviceProcAddr),
            b"vkCreateInstance" => return void(create_instance::<U> as vk::PFN_vkCreateInstance),
            _ => {}
        }
        let inst = instance_state::<U>(dispatch_key(instance))?;
        // SAFETY: the next layer's gipa with its own instance and a valid name.
        let next = unsafe { (inst.next_gipa)(instance, name) }?;
        Some(match n {
            b"vkDestroyInstance" => void(destroy_instance::<U> as vk::PFN_vkDestroyInstance)?,
            b"vkCreateDevice" => void(create_device::<U> as vk::PFN_vkCreateDevice)?,
            b"vkDestroyDevice" => void(destroy_device::<U> as vk::PFN_vkDestroyDevice)?,
            _ => hooks::lookup::<U>(n).or_else(|| count::lookup::<U>(n)).or_else(|| reenter::lookup::<U>(n)).unwrap_or(next),
        })
    })
}

unsafe extern "system" fn get_device_proc_addr<const U: bool>(device: vk::Device, name: *const c_char) -> vk::PFN_vkVoidFunction {
    entry("vkGetDeviceProcAddr", None, || {
        if name.is_null() {
            return None;
        }
        // SAFETY: a NUL-terminated name (checked non-null).
        let n = unsafe { CStr::from_ptr(name) }.to_bytes();
        if n == b"vkGetDeviceProcAddr" {
            return void(get_device_proc_addr::<U> as vk::PFN_vkGetDeviceProcAddr);
        }
        let dev = device_state::<U>(dispatch_key(device))?;
        // SAFETY: the next layer's gdpa with its own device and a valid name.
        let next = unsafe { (dev.next_gdpa)(device, name) }?;
        Some(match n {
            b"vkDestroyDevice" => void(destroy_device::<U> as vk::PFN_vkDestroyDevice)?,
            _ => hooks::lookup::<U>(n).or_else(|| count::lookup::<U>(n)).or_else(|| reenter::lookup::<U>(n)).unwrap_or(next),
        })
    })
}

// ---------------------------------------------------------------------------------------------
// Instance and device chains

unsafe extern "system" fn create_instance<const U: bool>(
    ci: *const vk::InstanceCreateInfo<'_>,
    allocator: *const vk::AllocationCallbacks<'_>,
    p_instance: *mut vk::Instance,
) -> vk::Result {
    entry("vkCreateInstance", vk::Result::ERROR_INITIALIZATION_FAILED, || {
        if !U {
            if let Err(e) = rules() {
                eprintln!("vk-fault-layer: VK_FAULT: {e}");
                return vk::Result::ERROR_INITIALIZATION_FAILED;
            }
            if let Err(e) = reenter::names() {
                eprintln!("vk-fault-layer: VK_FAULT_REENTER: {e}");
                return vk::Result::ERROR_INITIALIZATION_FAILED;
            }
        }
        // SAFETY: the loader passes a valid create info with a valid chain.
        let Some(chain) = (unsafe { link_info::<InstanceLink>((*ci).p_next, LOADER_INSTANCE_CREATE_INFO) }) else {
            return vk::Result::ERROR_INITIALIZATION_FAILED;
        };
        // SAFETY: the loader's struct and link list, valid for this call.
        let Some(link) = (unsafe { (*chain).p_layer_info.as_ref() }) else { return vk::Result::ERROR_INITIALIZATION_FAILED };
        let next_gipa = link.next_gipa;
        // SAFETY: the loader expects each layer to advance the link before calling down.
        unsafe { (*chain).p_layer_info = link.p_next };
        // SAFETY: the next gipa with a null instance, for a global command.
        let Some(create) = (unsafe { next_gipa(vk::Instance::null(), c"vkCreateInstance".as_ptr()) }) else {
            return vk::Result::ERROR_INITIALIZATION_FAILED;
        };
        // SAFETY: the pointer returned for "vkCreateInstance" has that command's type.
        let create: vk::PFN_vkCreateInstance = unsafe { std::mem::transmute(create) };
        // SAFETY: the app's arguments, unchanged.
        let r = unsafe { create(ci, allocator, p_instance) };
        if r != vk::Result::SUCCESS {
            return r;
        }
        // SAFETY: on success the instance was written.
        let handle = unsafe { *p_instance };
        // SAFETY: the next gipa for the instance it just created.
        let destroy = unsafe { next_gipa(handle, c"vkDestroyInstance".as_ptr()) };
        let Some(destroy) = destroy else {
            eprintln!("vk-fault-layer: the next layer has no vkDestroyInstance");
            return vk::Result::ERROR_INITIALIZATION_FAILED;
        };
        // SAFETY: the pointer returned for "vkDestroyInstance" has that command's type.
        let destroy: vk::PFN_vkDestroyInstance = unsafe { std::mem::transmute(destroy) };
        lock(&role(U).instances).insert(dispatch_key(handle), Arc::new(Instance { handle, next_gipa, destroy }));
        r
    })
}

unsafe extern "system" fn destroy_instance<const U: bool>(instance: vk::Instance, allocator: *const vk::AllocationCallbacks<'_>) {
    entry("vkDestroyInstance", (), || {
        let key = dispatch_key(instance);
        let Some(inst) = instance_state::<U>(key) else { return };
        // SAFETY: the app's arguments, to the next layer.
        unsafe { (inst.destroy)(instance, allocator) };
        lock(&role(U).instances).remove(&key);
    })
}

unsafe extern "system" fn create_device<const U: bool>(
    pd: vk::PhysicalDevice,
    ci: *const vk::DeviceCreateInfo<'_>,
    allocator: *const vk::AllocationCallbacks<'_>,
    p_device: *mut vk::Device,
) -> vk::Result {
    entry("vkCreateDevice", vk::Result::ERROR_INITIALIZATION_FAILED, || {
        // A physical device shares its instance's dispatch key.
        let Some(inst) = instance_state::<U>(dispatch_key(pd)) else { return vk::Result::ERROR_INITIALIZATION_FAILED };
        // SAFETY: the loader passes a valid create info with a valid chain.
        let Some(chain) = (unsafe { link_info::<DeviceLink>((*ci).p_next, LOADER_DEVICE_CREATE_INFO) }) else {
            return vk::Result::ERROR_INITIALIZATION_FAILED;
        };
        // SAFETY: the loader's struct and link list, valid for this call.
        let Some(link) = (unsafe { (*chain).p_layer_info.as_ref() }) else { return vk::Result::ERROR_INITIALIZATION_FAILED };
        let (next_gipa, next_gdpa) = (link.next_gipa, link.next_gdpa);
        // SAFETY: advanced before calling down, as the loader expects.
        unsafe { (*chain).p_layer_info = link.p_next };
        // SAFETY: the next gipa with the instance this physical device belongs to.
        let Some(create) = (unsafe { next_gipa(inst.handle, c"vkCreateDevice".as_ptr()) }) else {
            return vk::Result::ERROR_INITIALIZATION_FAILED;
        };
        // SAFETY: the pointer returned for "vkCreateDevice" has that command's type.
        let create: vk::PFN_vkCreateDevice = unsafe { std::mem::transmute(create) };
        // SAFETY: the app's arguments, unchanged.
        let r = unsafe { create(pd, ci, allocator, p_device) };
        if r != vk::Result::SUCCESS {
            return r;
        }
        // SAFETY: on success the device was written.
        let handle = unsafe { *p_device };
        // SAFETY: the next gdpa for the device it just created, with NUL-terminated names.
        let get = |name: &CStr| unsafe { next_gdpa(handle, name.as_ptr()) };
        let Some(destroy) = get(c"vkDestroyDevice") else {
            eprintln!("vk-fault-layer: the next layer has no vkDestroyDevice");
            return vk::Result::ERROR_INITIALIZATION_FAILED;
        };
        // SAFETY: the pointer returned for "vkDestroyDevice" has that command's type.
        let destroy: vk::PFN_vkDestroyDevice = unsafe { std::mem::transmute(destroy) };
        let resolve = |list: &[&[&str]]| -> Vec<vk::PFN_vkVoidFunction> {
            list.iter()
                .map(|names| {
                    names.iter().find_map(|n| {
                        let c = std::ffi::CString::new(*n).ok()?;
                        get(&c)
                    })
                })
                .collect()
        };
        let (fns, reenter_fns, count_fns) = (resolve(spec::FUNCS), resolve(spec::REENTER_ONLY), resolve(&count::next_names()));
        // Only the lower instance re-enters, and only when asked to: the marker's next layer is
        // stereoshim, which must not see calls of the marker's own.
        let get_queue = if !U && reenter::names().as_ref().is_ok_and(|n| !n.is_empty()) { get(c"vkGetDeviceQueue") } else { None };
        // SAFETY: the app's valid create info, read during its call; the queue getter the next
        // layer returned for this device.
        let reenter = unsafe { reenter::DeviceReentry::new(&*ci, get_queue, handle) };
        lock(&role(U).devices).insert(dispatch_key(handle), Arc::new(Device { handle, next_gdpa, destroy, fns, reenter_fns, count_fns, reenter }));
        r
    })
}

unsafe extern "system" fn destroy_device<const U: bool>(device: vk::Device, allocator: *const vk::AllocationCallbacks<'_>) {
    entry("vkDestroyDevice", (), || {
        let key = dispatch_key(device);
        let Some(dev) = device_state::<U>(key) else { return };
        if !U {
            dev.reenter.report();
            // Before calling down: the layer above destroyed its objects before its call reached
            // this one, and nothing can be destroyed on the device after it.
            if count::enabled() {
                count::report(key, "vkDestroyDevice", true);
            }
        }
        // SAFETY: the app's arguments, to the next layer.
        unsafe { (dev.destroy)(device, allocator) };
        lock(&role(U).devices).remove(&key);
    })
}
