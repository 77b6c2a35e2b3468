//! The XrInstance: enabled extensions, configuration snapshot, event queue and path table.
//! Everything else hangs off an instance, and destroying it destroys its children.

use std::collections::{HashMap, HashSet, VecDeque};
use std::ffi::c_char;
use std::sync::{Arc, Mutex};

use openxr_sys as xr;
use xr::Handle as _;

use crate::config::Config;
use crate::fault::{self, result_name, FailCounters};
use crate::handles::Registry;
use crate::util::{self, guard, input, out_ptr, output, two_call, write_fixed, XrResult};
use crate::{EXTENSIONS, RUNTIME_API_VERSION};

pub static INSTANCES: Registry<Instance> = Registry::new();

/// Events as queued; converted to the app's XrEventDataBuffer by xrPollEvent.
#[derive(Debug, Clone, PartialEq)]
pub enum Event {
    SessionState { session: u64, state: xr::SessionState, time: i64 },
    VisibilityMaskChanged { session: u64, view: u32 },
    InteractionProfileChanged { session: u64 },
}

impl Event {
    pub fn session(&self) -> u64 {
        match *self {
            Event::SessionState { session, .. }
            | Event::VisibilityMaskChanged { session, .. }
            | Event::InteractionProfileChanged { session } => session,
        }
    }
}

/// Vulkan-related per-instance state of XR_KHR_vulkan_enable(2).
#[derive(Debug, Default)]
pub struct VkInstanceState {
    pub requirements_called: bool,
    /// VkInstances created through xrCreateVulkanInstanceKHR and the app's vkGetInstanceProcAddr.
    pub created: Vec<(usize, xr::platform::VkGetInstanceProcAddr)>,
    /// (VkInstance, VkPhysicalDevice) handed out by xrGetVulkanGraphicsDevice(2)KHR.
    pub graphics_device: Option<(usize, usize)>,
}

#[derive(Debug, Default)]
pub struct PathTable {
    strings: Vec<String>,
    ids: HashMap<String, u64>,
}

impl PathTable {
    pub fn intern(&mut self, s: &str) -> u64 {
        if let Some(&id) = self.ids.get(s) {
            return id;
        }
        self.strings.push(s.to_string());
        let id = self.strings.len() as u64;
        self.ids.insert(s.to_string(), id);
        id
    }

    pub fn get(&self, id: u64) -> Option<&str> {
        id.checked_sub(1).and_then(|i| self.strings.get(i as usize)).map(String::as_str)
    }
}

/// Path syntax of the spec's "well-formed path string" rules.
pub fn path_is_well_formed(s: &str) -> bool {
    s.len() < xr::MAX_PATH_LENGTH
        && s.starts_with('/')
        && !s.ends_with('/')
        && s[1..].split('/').all(|c| {
            !c.is_empty()
                && c != "."
                && c != ".."
                && c.bytes().all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || b"-_.".contains(&b))
        })
}

pub struct Instance {
    pub handle: u64,
    pub cfg: Config,
    pub extensions: HashSet<String>,
    pub api_version: xr::Version,
    pub events: Mutex<VecDeque<Event>>,
    pub paths: Mutex<PathTable>,
    pub vk: Mutex<VkInstanceState>,
    /// Suggested bindings per interaction profile path: (action handle, binding path).
    pub bindings: Mutex<HashMap<u64, Vec<(u64, u64)>>>,
    fail: FailCounters,
}

impl Instance {
    pub fn extension_enabled(&self, ext: &str) -> bool {
        self.extensions.contains(ext)
    }

    /// `MOCK_XR_FAIL`: called by each entry point after its handles were validated and before it
    /// changes anything; returns the error the spec selects for this call.
    pub fn fail_point(&self, func: &'static str) -> XrResult<()> {
        match self.fail.hit(&self.cfg.fail, func) {
            Some(e) => {
                crate::log!("{func}: injected {}", result_name(e));
                Err(e)
            }
            None => Ok(()),
        }
    }

    pub fn push_event(&self, e: Event) {
        crate::log!("event {e:?}");
        self.events.lock().unwrap().push_back(e);
    }

    pub fn path(&self, s: &str) -> u64 {
        self.paths.lock().unwrap().intern(s)
    }

    pub fn path_str(&self, p: xr::Path) -> XrResult<String> {
        self.paths.lock().unwrap().get(p.into_raw()).map(str::to_owned).ok_or(xr::Result::ERROR_PATH_INVALID)
    }
}

pub fn get(h: xr::Instance) -> XrResult<Arc<Instance>> {
    INSTANCES.get(h.into_raw())
}

/// Extensions offered under the current environment.
fn offered_extensions() -> Vec<(&'static str, u32)> {
    let disabled: HashSet<String> = std::env::var("MOCK_XR_DISABLE_EXTENSIONS")
        .unwrap_or_default()
        .split(',')
        .map(|s| s.trim().to_string())
        .collect();
    EXTENSIONS.iter().copied().filter(|(n, _)| !disabled.contains(*n)).collect()
}

pub unsafe extern "system" fn xr_enumerate_instance_extension_properties(
    layer_name: *const c_char,
    capacity: u32,
    count_out: *mut u32,
    props: *mut xr::ExtensionProperties,
) -> xr::Result {
    guard("xrEnumerateInstanceExtensionProperties", || {
        if !layer_name.is_null() {
            return Err(xr::Result::ERROR_API_LAYER_NOT_PRESENT);
        }
        fault::global_fail_point("xrEnumerateInstanceExtensionProperties")?;
        let exts = offered_extensions();
        if capacity > 0 && props.is_null() {
            return Err(xr::Result::ERROR_VALIDATION_FAILURE);
        }
        // SAFETY: `props` holds `capacity` elements; each is type-checked before writing.
        unsafe {
            two_call(capacity, count_out, exts.len(), |i| {
                let p = output(props.add(i))?;
                write_fixed(&mut p.extension_name, exts[i].0);
                p.extension_version = exts[i].1;
                Ok(())
            })
        }?;
        Ok(xr::Result::SUCCESS)
    })
}

pub unsafe extern "system" fn xr_create_instance(
    info: *const xr::InstanceCreateInfo,
    instance: *mut xr::Instance,
) -> xr::Result {
    guard("xrCreateInstance", || {
        // SAFETY: app-provided pointers, checked by the helpers.
        let (info, out) = unsafe { (input(info)?, out_ptr(instance)?) };
        let cfg = Config::from_env().map_err(|e| {
            eprintln!("[mock-runtime] configuration error: {e}");
            xr::Result::ERROR_INITIALIZATION_FAILED
        })?;
        // Counted per process: `xrCreateInstance@1` fails the second instance.
        fault::global_fail_point("xrCreateInstance")?;
        if info.create_flags != xr::InstanceCreateFlags::EMPTY {
            return Err(xr::Result::ERROR_VALIDATION_FAILURE);
        }
        let app = &info.application_info;
        let name = util::read_fixed(&app.application_name)?;
        if name.is_empty() {
            return Err(xr::Result::ERROR_NAME_INVALID);
        }
        util::read_fixed(&app.engine_name)?;
        let v = app.api_version;
        if v.major() != 1 || v.minor() > 1 {
            return Err(xr::Result::ERROR_API_VERSION_UNSUPPORTED);
        }
        let offered = offered_extensions();
        let mut extensions = HashSet::new();
        // SAFETY: count/array pair from the app.
        for &p in unsafe { util::slice(info.enabled_extension_names, info.enabled_extension_count) }? {
            // SAFETY: NUL-terminated extension name.
            let e = unsafe { util::read_cstr(p) }?;
            if !offered.iter().any(|(n, _)| *n == e) {
                crate::log!("xrCreateInstance: extension {e} not present");
                return Err(xr::Result::ERROR_EXTENSION_NOT_PRESENT);
            }
            extensions.insert(e);
        }
        let (h, _) = INSTANCES.insert_with(|handle| Instance {
            handle,
            cfg,
            extensions,
            api_version: v,
            events: Mutex::default(),
            paths: Mutex::default(),
            vk: Mutex::default(),
            bindings: Mutex::default(),
            fail: FailCounters::default(),
        });
        crate::log!("xrCreateInstance: {name:?} api {v:?} -> {h}");
        *out = xr::Instance::from_raw(h);
        Ok(xr::Result::SUCCESS)
    })
}

pub unsafe extern "system" fn xr_destroy_instance(instance: xr::Instance) -> xr::Result {
    guard("xrDestroyInstance", || {
        let inst = get(instance)?;
        inst.fail_point("xrDestroyInstance")?;
        for s in crate::session::SESSIONS.find(|s| s.instance.handle == inst.handle) {
            crate::session::destroy(&s);
        }
        crate::actions::destroy_instance_children(inst.handle);
        INSTANCES.remove(inst.handle);
        Ok(xr::Result::SUCCESS)
    })
}

pub unsafe extern "system" fn xr_get_instance_properties(
    instance: xr::Instance,
    props: *mut xr::InstanceProperties,
) -> xr::Result {
    guard("xrGetInstanceProperties", || {
        let inst = get(instance)?;
        inst.fail_point("xrGetInstanceProperties")?;
        // SAFETY: app-provided output struct.
        let p = unsafe { output(props) }?;
        p.runtime_version = xr::Version::new(0, 1, 0);
        write_fixed(&mut p.runtime_name, "stereoshim mock runtime");
        let _ = RUNTIME_API_VERSION;
        Ok(xr::Result::SUCCESS)
    })
}

/// Writes `e` into the app's event buffer as the struct its type calls for.
fn write_event(buf: &mut xr::EventDataBuffer, e: &Event) {
    let p = buf as *mut xr::EventDataBuffer;
    // SAFETY: XrEventDataBuffer is large enough for every event struct (4000 bytes of payload)
    // and suitably aligned (it is an OpenXR struct of 8-byte alignment).
    unsafe {
        match *e {
            Event::SessionState { session, state, time } => {
                (p as *mut xr::EventDataSessionStateChanged).write(xr::EventDataSessionStateChanged {
                    ty: xr::EventDataSessionStateChanged::TYPE,
                    next: std::ptr::null(),
                    session: xr::Session::from_raw(session),
                    state,
                    time: xr::Time::from_nanos(time),
                })
            }
            Event::VisibilityMaskChanged { session, view } => {
                (p as *mut xr::EventDataVisibilityMaskChangedKHR).write(xr::EventDataVisibilityMaskChangedKHR {
                    ty: xr::EventDataVisibilityMaskChangedKHR::TYPE,
                    next: std::ptr::null(),
                    session: xr::Session::from_raw(session),
                    view_configuration_type: xr::ViewConfigurationType::PRIMARY_STEREO,
                    view_index: view,
                })
            }
            Event::InteractionProfileChanged { session } => {
                (p as *mut xr::EventDataInteractionProfileChanged).write(xr::EventDataInteractionProfileChanged {
                    ty: xr::EventDataInteractionProfileChanged::TYPE,
                    next: std::ptr::null(),
                    session: xr::Session::from_raw(session),
                })
            }
        }
    }
}

pub unsafe extern "system" fn xr_poll_event(instance: xr::Instance, event: *mut xr::EventDataBuffer) -> xr::Result {
    guard("xrPollEvent", || {
        let inst = get(instance)?;
        inst.fail_point("xrPollEvent")?;
        // SAFETY: app-provided output struct, type-checked.
        let buf = unsafe { output(event) }?;
        let Some(e) = inst.events.lock().unwrap().pop_front() else {
            return Ok(xr::Result::EVENT_UNAVAILABLE);
        };
        write_event(buf, &e);
        Ok(xr::Result::SUCCESS)
    })
}

pub fn structure_type_name(t: xr::StructureType) -> String {
    let dbg = format!("{t:?}");
    if dbg.chars().all(|c| c.is_ascii_uppercase() || c == '_' || c.is_ascii_digit()) && !dbg.starts_with(|c: char| c.is_ascii_digit()) {
        format!("XR_TYPE_{dbg}")
    } else {
        format!("XR_UNKNOWN_STRUCTURE_TYPE_{}", t.into_raw())
    }
}

pub unsafe extern "system" fn xr_result_to_string(instance: xr::Instance, value: xr::Result, buffer: *mut c_char) -> xr::Result {
    guard("xrResultToString", || {
        let inst = get(instance)?;
        inst.fail_point("xrResultToString")?;
        if buffer.is_null() {
            return Err(xr::Result::ERROR_VALIDATION_FAILURE);
        }
        // SAFETY: the spec requires a buffer of XR_MAX_RESULT_STRING_SIZE chars.
        let dst = unsafe { std::slice::from_raw_parts_mut(buffer, xr::MAX_RESULT_STRING_SIZE) };
        write_fixed(dst, &result_name(value));
        Ok(xr::Result::SUCCESS)
    })
}

pub unsafe extern "system" fn xr_structure_type_to_string(
    instance: xr::Instance,
    value: xr::StructureType,
    buffer: *mut c_char,
) -> xr::Result {
    guard("xrStructureTypeToString", || {
        let inst = get(instance)?;
        inst.fail_point("xrStructureTypeToString")?;
        if buffer.is_null() {
            return Err(xr::Result::ERROR_VALIDATION_FAILURE);
        }
        // SAFETY: the spec requires a buffer of XR_MAX_STRUCTURE_NAME_SIZE chars.
        let dst = unsafe { std::slice::from_raw_parts_mut(buffer, xr::MAX_STRUCTURE_NAME_SIZE) };
        write_fixed(dst, &structure_type_name(value));
        Ok(xr::Result::SUCCESS)
    })
}

pub unsafe extern "system" fn xr_string_to_path(instance: xr::Instance, s: *const c_char, path: *mut xr::Path) -> xr::Result {
    guard("xrStringToPath", || {
        let inst = get(instance)?;
        inst.fail_point("xrStringToPath")?;
        // SAFETY: app-provided string and output pointer.
        let (s, out) = unsafe { (util::read_cstr(s)?, out_ptr(path)?) };
        if !path_is_well_formed(&s) {
            return Err(xr::Result::ERROR_PATH_FORMAT_INVALID);
        }
        *out = xr::Path::from_raw(inst.path(&s));
        Ok(xr::Result::SUCCESS)
    })
}

pub unsafe extern "system" fn xr_path_to_string(
    instance: xr::Instance,
    path: xr::Path,
    capacity: u32,
    count_out: *mut u32,
    buffer: *mut c_char,
) -> xr::Result {
    guard("xrPathToString", || {
        let inst = get(instance)?;
        inst.fail_point("xrPathToString")?;
        let s = inst.path_str(path)?;
        // SAFETY: buffer of `capacity` chars from the app.
        unsafe { util::two_call_str(capacity, count_out, buffer, &s) }?;
        Ok(xr::Result::SUCCESS)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paths() {
        assert!(path_is_well_formed("/user/hand/left/input/menu/click"));
        assert!(path_is_well_formed("/interaction_profiles/khr/simple_controller"));
        for bad in ["", "/", "user", "/user/", "/user//hand", "/User", "/a/./b", "/a/../b", "/a b"] {
            assert!(!path_is_well_formed(bad), "{bad}");
        }
        let mut t = PathTable::default();
        let a = t.intern("/a");
        assert_eq!(t.intern("/a"), a);
        assert_ne!(t.intern("/b"), a);
        assert_eq!(t.get(a), Some("/a"));
        assert_eq!(t.get(0), None);
    }

    #[test]
    fn names() {
        assert_eq!(structure_type_name(xr::StructureType::SESSION_CREATE_INFO), "XR_TYPE_SESSION_CREATE_INFO");
    }
}
