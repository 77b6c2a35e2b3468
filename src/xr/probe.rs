//! `stereoshim doctor`'s OpenXR probe: loads the system's OpenXR loader as an app would, lists the
//! API layers it finds, and creates (and at once destroys) an instance with no extensions and no
//! session, to learn which runtime answers. Only facts come out of here; what they mean is decided
//! by the pure `crate::doctor::rules`. Never used inside an app's process.

use openxr_sys as xr;
use openxr_sys::Handle as _;
use std::ffi::c_char;
use std::path::PathBuf;

/// The loader's soname, as apps link it.
pub const LOADER: &str = "libopenxr_loader.so.1";

/// What the OpenXR loader reports.
#[derive(Clone, Debug, PartialEq)]
pub struct XrFacts {
    /// The loader file mapped.
    pub loader: Option<PathBuf>,
    /// `xrEnumerateApiLayerProperties`: every layer the loader found (implicit and explicit), or
    /// why the call failed.
    pub layers: Result<Vec<String>, String>,
    /// `xrEnumerateInstanceExtensionProperties`: the runtime's extensions (and implicit layers'),
    /// or why the call failed.
    pub extensions: Result<Vec<String>, String>,
    /// `xrCreateInstance` + `xrGetInstanceProperties`: the runtime's name and version, or the
    /// result code of the failed call.
    pub instance: Result<(String, String), String>,
}

fn text(chars: &[c_char]) -> String {
    let bytes: Vec<u8> = chars.iter().take_while(|&&c| c != 0).map(|&c| c as u8).collect();
    String::from_utf8_lossy(&bytes).into_owned()
}

fn fixed<const N: usize>(s: &str) -> [c_char; N] {
    let mut out = [0 as c_char; N];
    for (o, b) in out.iter_mut().zip(s.bytes().take(N - 1)) {
        *o = b as c_char;
    }
    out
}

/// Loads the OpenXR loader and asks it. Err: no loader.
pub fn probe() -> Result<XrFacts, String> {
    // SAFETY: loading the system's OpenXR loader runs its initialisers, which every OpenXR app
    // does. It stays loaded (forgotten below): runtimes it loads may leave thread-local
    // destructors or atexit handlers behind.
    let lib = unsafe { libloading::Library::new(LOADER) }.map_err(|e| e.to_string())?;
    // SAFETY: the OpenXR loader exports every core command under its name, with the signature of
    // `openxr_sys::pfn` (here xrCreateInstance's).
    let create = unsafe { lib.get::<xr::pfn::CreateInstance>(b"xrCreateInstance") }.map_err(|e| e.to_string())?;
    // SAFETY: a core command the loader exports, typed as `openxr_sys::pfn::DestroyInstance`.
    let destroy = unsafe { lib.get::<xr::pfn::DestroyInstance>(b"xrDestroyInstance") }.map_err(|e| e.to_string())?;
    // SAFETY: a core command the loader exports, typed as `openxr_sys::pfn::GetInstanceProperties`.
    let properties = unsafe { lib.get::<xr::pfn::GetInstanceProperties>(b"xrGetInstanceProperties") }.map_err(|e| e.to_string())?;
    // SAFETY: a core command the loader exports, typed as `openxr_sys::pfn::EnumerateApiLayerProperties`.
    let layers = unsafe { lib.get::<xr::pfn::EnumerateApiLayerProperties>(b"xrEnumerateApiLayerProperties") }.map_err(|e| e.to_string())?;
    // SAFETY: a core command the loader exports, typed as `openxr_sys::pfn::EnumerateInstanceExtensionProperties`.
    let extensions = unsafe { lib.get::<xr::pfn::EnumerateInstanceExtensionProperties>(b"xrEnumerateInstanceExtensionProperties") }.map_err(|e| e.to_string())?;
    let (create, destroy, properties, layers, extensions) = (*create, *destroy, *properties, *layers, *extensions);
    std::mem::forget(lib);
    let mut facts = XrFacts { loader: crate::vk::probe::mapped_file(create as usize), layers: Ok(Vec::new()), extensions: Ok(Vec::new()), instance: Err(String::new()) };
    facts.layers = (|| {
        let mut count = 0u32;
        // SAFETY: the two-call idiom: a count query with no array.
        let r = unsafe { layers(0, &mut count, std::ptr::null_mut()) };
        if r != xr::Result::SUCCESS {
            return Err(format!("{r:?}"));
        }
        let blank = xr::ApiLayerProperties {
            ty: xr::ApiLayerProperties::TYPE,
            next: std::ptr::null_mut(),
            layer_name: [0; xr::MAX_API_LAYER_NAME_SIZE],
            spec_version: xr::Version::new(0, 0, 0),
            layer_version: 0,
            description: [0; xr::MAX_API_LAYER_DESCRIPTION_SIZE],
        };
        let mut out = vec![blank; count as usize];
        // SAFETY: an array of `count` initialised structs with their type set.
        let r = unsafe { layers(count, &mut count, out.as_mut_ptr()) };
        if r != xr::Result::SUCCESS {
            return Err(format!("{r:?}"));
        }
        out.truncate(count as usize);
        Ok(out.iter().map(|l| text(&l.layer_name)).collect())
    })();
    facts.extensions = (|| {
        let mut count = 0u32;
        // SAFETY: the two-call idiom: a count query with no layer name and no array.
        let r = unsafe { extensions(std::ptr::null(), 0, &mut count, std::ptr::null_mut()) };
        if r != xr::Result::SUCCESS {
            return Err(format!("{r:?}"));
        }
        let blank = xr::ExtensionProperties {
            ty: xr::ExtensionProperties::TYPE,
            next: std::ptr::null_mut(),
            extension_name: [0; xr::MAX_EXTENSION_NAME_SIZE],
            extension_version: 0,
        };
        let mut out = vec![blank; count as usize];
        // SAFETY: an array of `count` initialised structs with their type set; no layer name.
        let r = unsafe { extensions(std::ptr::null(), count, &mut count, out.as_mut_ptr()) };
        if r != xr::Result::SUCCESS {
            return Err(format!("{r:?}"));
        }
        out.truncate(count as usize);
        Ok(out.iter().map(|e| text(&e.extension_name)).collect())
    })();
    let info = xr::InstanceCreateInfo {
        ty: xr::InstanceCreateInfo::TYPE,
        next: std::ptr::null(),
        create_flags: xr::InstanceCreateFlags::EMPTY,
        application_info: xr::ApplicationInfo {
            application_name: fixed("stereoshim-doctor"),
            application_version: 1,
            engine_name: fixed("stereoshim"),
            engine_version: 1,
            // 1.0: every runtime in use accepts it.
            api_version: xr::Version::new(1, 0, 0),
        },
        enabled_api_layer_count: 0,
        enabled_api_layer_names: std::ptr::null(),
        enabled_extension_count: 0,
        enabled_extension_names: std::ptr::null(),
    };
    let mut instance = xr::Instance::NULL;
    // SAFETY: a valid create info without layers or extensions; a writable handle.
    let r = unsafe { create(&info, &mut instance) };
    facts.instance = if r != xr::Result::SUCCESS {
        Err(format!("{r:?}"))
    } else {
        let mut p = xr::InstanceProperties {
            ty: xr::InstanceProperties::TYPE,
            next: std::ptr::null_mut(),
            runtime_version: xr::Version::new(0, 0, 0),
            runtime_name: [0; xr::MAX_RUNTIME_NAME_SIZE],
        };
        // SAFETY: the instance just created; a writable struct with its type set.
        let r = unsafe { properties(instance, &mut p) };
        // SAFETY: the instance just created, nothing made from it.
        unsafe { destroy(instance) };
        if r == xr::Result::SUCCESS {
            let v = p.runtime_version;
            Ok((text(&p.runtime_name), format!("{}.{}.{}", v.major(), v.minor(), v.patch())))
        } else {
            Err(format!("xrGetInstanceProperties: {r:?}"))
        }
    };
    Ok(facts)
}
