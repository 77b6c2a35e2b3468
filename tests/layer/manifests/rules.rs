//! The manifest rules of both loaders.
//!
//! Vulkan: Vulkan-Loader docs/LoaderLayerInterface.md ("Layer Manifest File Format"), the readers in
//! loader/loader.c of v1.3.239 and v1.4.309 (loader_add_layer_properties, loader_read_layer_json),
//! and the pattern rules of the published layer manifest JSON schema
//! (LunarG/VulkanTools vkconfig_core/layers/layers_schema.json: version patterns, name pattern).
//! OpenXR: OpenXR-SDK specification/loader/api_layer.adoc ("API Layer Manifest File Format") and
//! src/loader/manifest_file.cpp of release-1.0.20 and release-1.1.47 (ManifestFile::IsValidJson,
//! ApiLayerManifestFile::CreateIfValid). Neither repository publishes a JSON schema of its own, so
//! the few rules are written out here.

use std::path::{Path, PathBuf};
use serde_json::Value;
use stereoshim::manifests::{self as manifest, Kind};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Api {
    Vulkan,
    OpenXr,
}

/// Where a manifest is found decides implicit or explicit; `kind` of a shipped/generated one.
pub fn api_of(kind: Kind) -> Api {
    if kind.is_vulkan() {
        Api::Vulkan
    } else {
        Api::OpenXr
    }
}

pub fn all_digits(s: &str) -> bool {
    !s.is_empty() && s.bytes().all(|b| b.is_ascii_digit())
}

/// `n` dot-separated decimal numbers.
pub fn numbers(s: &str, n: usize) -> Option<Vec<u32>> {
    let parts: Vec<&str> = s.split('.').collect();
    (parts.len() == n && parts.iter().all(|p| all_digits(p))).then(|| parts.iter().map(|p| p.parse().unwrap_or(u32::MAX)).collect())
}

pub fn env_name(s: &str) -> bool {
    let mut b = s.bytes();
    matches!(b.next(), Some(c) if c.is_ascii_alphabetic() || c == b'_') && b.all(|c| c.is_ascii_alphanumeric() || c == b'_')
}

/// `PREFIX` + `VENDOR` (upper case / digits) + `_` + name (lower case / digits / `_`, upper case
/// too where `upper_name`).
pub fn layer_name(s: &str, prefix: &str, upper_name: bool) -> bool {
    let Some(rest) = s.strip_prefix(prefix) else { return false };
    let Some((vendor, name)) = rest.split_once('_') else { return false };
    !vendor.is_empty()
        && vendor.bytes().all(|c| c.is_ascii_uppercase() || c.is_ascii_digit())
        && !name.is_empty()
        && name.bytes().all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == b'_' || (upper_name && c.is_ascii_uppercase()))
}

/// Every key whose name contains "version", anywhere in the document, must hold a string (both
/// loaders read versions only as strings).
pub fn versions_are_strings(v: &Value, at: &str, problems: &mut Vec<String>) {
    match v {
        Value::Object(m) => {
            for (k, x) in m {
                if k.contains("version") && !x.is_string() {
                    problems.push(format!("{at}.{k} is {x}, not a string"));
                }
                versions_are_strings(x, &format!("{at}.{k}"), problems);
            }
        }
        Value::Array(a) => a.iter().enumerate().for_each(|(i, x)| versions_are_strings(x, &format!("{at}[{i}]"), problems)),
        _ => {}
    }
}

/// The library a manifest names, as the loaders resolve it: absolute, or relative to the
/// manifest's folder. A bare file name (system search path) is not something stereoshim writes.
pub fn resolve_library(library_path: &str, manifest_path: &Path) -> Result<PathBuf, String> {
    if !library_path.contains('/') {
        return Err(format!("library_path {library_path:?} is a bare file name (searched on the system library path)"));
    }
    let p = Path::new(library_path);
    let p = if p.is_absolute() { p.to_path_buf() } else { manifest_path.parent().unwrap_or(Path::new(".")).join(p) };
    if p.is_file() {
        Ok(p)
    } else {
        Err(format!("library_path {library_path:?} resolves to {}, which does not exist", p.display()))
    }
}

/// The problems of one manifest (none: valid for both loaders). `implicit`: it lies where the
/// loader looks for implicit layers. `library`: the resolved library (when the path resolves).
pub fn check(api: Api, implicit: bool, text: &str, manifest_path: &Path) -> (Vec<String>, Option<PathBuf>) {
    let mut problems = Vec::new();
    let root: Value = match serde_json::from_str(text) {
        Ok(v) => v,
        Err(e) => return (vec![format!("not JSON: {e}")], None),
    };
    let Some(top) = root.as_object() else { return (vec!["top level is not an object".into()], None) };
    versions_are_strings(&root, "", &mut problems);
    let str_of = |o: &serde_json::Map<String, Value>, k: &str, problems: &mut Vec<String>| -> Option<String> {
        match o.get(k) {
            Some(Value::String(s)) => Some(s.clone()),
            Some(x) => {
                problems.push(format!("{k} is {x}, not a string"));
                None
            }
            None => {
                problems.push(format!("required {k} missing"));
                None
            }
        }
    };
    let (layer_key, known_top, known_layer): (&str, &[&str], &[&str]) = match api {
        Api::Vulkan => (
            "layer",
            &["file_format_version", "layer", "layers"],
            &[
                "name", "type", "library_path", "library_arch", "api_version", "implementation_version", "description",
                "functions", "instance_extensions", "device_extensions", "enable_environment", "disable_environment",
                "component_layers", "override_paths", "blacklisted_layers", "app_keys", "pre_instance_functions",
                "introduction", "url", "platforms", "status", "settings", "presets",
            ],
        ),
        Api::OpenXr => (
            "api_layer",
            &["file_format_version", "api_layer"],
            &[
                "name", "library_path", "api_version", "implementation_version", "description", "functions",
                "instance_extensions", "enable_environment", "disable_environment",
            ],
        ),
    };
    for k in top.keys().filter(|k| !known_top.contains(&k.as_str())) {
        problems.push(format!("unknown top-level key {k:?}"));
    }
    let file_version = str_of(top, "file_format_version", &mut problems);
    let file_version = file_version.as_deref().and_then(|v| {
        let n = numbers(v, 3);
        if n.is_none() {
            problems.push(format!("file_format_version {v:?} is not major.minor.patch"));
        }
        n
    });
    if let Some(v) = &file_version {
        let ok = match api {
            // loader.c is_valid_layer_json_version, identical in 1.3.239 and 1.4.309.
            Api::Vulkan => matches!((v[0], v[1], v[2]), (1, 0, 0..=1) | (1, 1, 0..=2) | (1, 2, 0..=1)),
            // manifest_file.cpp IsValidJson: exactly 1.0.0.
            Api::OpenXr => v[..] == [1, 0, 0],
        };
        if !ok {
            problems.push(format!("file_format_version {v:?} is not one the loaders accept"));
        }
    }
    let at_least = |want: [u32; 3]| file_version.as_ref().is_some_and(|v| v[..] >= want[..]);
    let Some(layer) = top.get(layer_key).and_then(Value::as_object) else {
        problems.push(format!("required object {layer_key} missing (stereoshim writes one layer per file)"));
        return (problems, None);
    };
    for k in layer.keys().filter(|k| !known_layer.contains(&k.as_str())) {
        problems.push(format!("unknown key {layer_key}.{k}"));
    }
    let name = str_of(layer, "name", &mut problems);
    let api_version = str_of(layer, "api_version", &mut problems);
    let implementation = str_of(layer, "implementation_version", &mut problems);
    let description = str_of(layer, "description", &mut problems);
    let library_path = str_of(layer, "library_path", &mut problems);
    if let Some(n) = &name {
        let ok = match api {
            Api::Vulkan => layer_name(n, "VK_LAYER_", false),
            Api::OpenXr => layer_name(n, "XR_APILAYER_", true),
        };
        if !ok || n.len() >= 256 {
            problems.push(format!("name {n:?} is not well-formed"));
        }
    }
    if let Some(v) = &api_version {
        let ok = match api {
            // Parsed as major.minor.patch (variant 0); schema pattern ^1.[0-9]+.[0-9]+.
            Api::Vulkan => numbers(v, 3).is_some_and(|n| n[0] == 1),
            // sscanf("%u.%u"), not 0.0, major no higher than the loader's.
            Api::OpenXr => numbers(v, 2).is_some_and(|n| n[0] == 1),
        };
        if !ok {
            problems.push(format!("api_version {v:?} is not {}", if api == Api::Vulkan { "1.minor.patch" } else { "1.minor" }));
        }
    }
    if let Some(v) = &implementation {
        if !all_digits(v) {
            problems.push(format!("implementation_version {v:?} is not a decimal number (the loaders atoi it)"));
        }
    }
    if let Some(d) = &description {
        if d.len() >= 256 {
            problems.push(format!("description is {} bytes; the properties hold 255", d.len()));
        }
    }
    if api == Api::Vulkan {
        if let Some(t) = str_of(layer, "type", &mut problems) {
            if t != "GLOBAL" && t != "INSTANCE" {
                problems.push(format!("type {t:?} is neither GLOBAL nor INSTANCE"));
            }
        }
        if let Some(arch) = layer.get("library_arch") {
            let want = if cfg!(target_pointer_width = "64") { "64" } else { "32" };
            if arch.as_str() != Some(want) {
                problems.push(format!("library_arch {arch} is not {want:?}"));
            }
            if !at_least([1, 2, 1]) {
                problems.push("library_arch needs file_format_version 1.2.1".into());
            }
        }
        if layer.contains_key("component_layers") {
            problems.push("component_layers: stereoshim is not a meta-layer".into());
        }
    }
    // functions: renames of the entry points the loader looks up by name.
    let negotiate = match api {
        Api::Vulkan => manifest::VK_NEGOTIATE,
        Api::OpenXr => manifest::XR_NEGOTIATE,
    };
    let mut entry_points = vec![negotiate.to_string()];
    if let Some(f) = layer.get("functions") {
        match f.as_object() {
            None => problems.push("functions is not an object".into()),
            Some(f) => {
                for (k, v) in f {
                    let allowed: &[&str] = match api {
                        Api::Vulkan => &[manifest::VK_NEGOTIATE, "vkGetInstanceProcAddr", "vkGetDeviceProcAddr"],
                        Api::OpenXr => &[manifest::XR_NEGOTIATE],
                    };
                    if !allowed.contains(&k.as_str()) {
                        problems.push(format!("functions.{k} is not a loader entry point"));
                    }
                    if api == Api::Vulkan && k == manifest::VK_NEGOTIATE && !at_least([1, 1, 0]) {
                        problems.push("functions.vkNegotiateLoaderLayerInterfaceVersion needs file_format_version 1.1.0".into());
                    }
                    match v.as_str() {
                        Some(s) if k == negotiate => entry_points = vec![s.to_string()],
                        Some(_) => {}
                        None => problems.push(format!("functions.{k} is {v}, not a string")),
                    }
                }
            }
        }
    }
    // Environment variables: implicit layers only; the disable variable is required there.
    for key in ["disable_environment", "enable_environment"] {
        match (layer.get(key), implicit) {
            (None, true) if key == "disable_environment" => problems.push("implicit layer without disable_environment".into()),
            (None, _) => {}
            (Some(_), false) => problems.push(format!("{key} on an explicit layer (implicit layers only)")),
            (Some(v), true) => {
                let var = match api {
                    // An object with one member: {"VARIABLE": "value"}.
                    Api::Vulkan => v.as_object().filter(|o| o.len() == 1 && o.values().all(Value::is_string)).and_then(|o| o.keys().next().cloned()),
                    // A string naming the variable.
                    Api::OpenXr => v.as_str().map(str::to_string),
                };
                match var {
                    Some(var) if env_name(&var) => {}
                    _ => problems.push(format!("{key} {v} does not name an environment variable the loader can read")),
                }
            }
        }
    }
    for key in ["instance_extensions", "device_extensions"] {
        let version_key = if api == Api::Vulkan { "spec_version" } else { "extension_version" };
        for e in layer.get(key).and_then(Value::as_array).into_iter().flatten() {
            if !e.get("name").is_some_and(Value::is_string) || !e.get(version_key).and_then(Value::as_str).is_some_and(all_digits) {
                problems.push(format!("{key} entry {e} lacks a string name and {version_key}"));
            }
        }
    }
    let library = library_path.and_then(|p| resolve_library(&p, manifest_path).map_err(|e| problems.push(e)).ok());
    if let Some(lib) = &library {
        // SAFETY: loading the layer library runs no code of its own until a loader negotiates.
        match unsafe { libloading::Library::new(lib) } {
            Err(e) => problems.push(format!("{}: cannot be loaded: {e}", lib.display())),
            Ok(l) => {
                for sym in &entry_points {
                    // SAFETY: only the address is looked up, nothing is called.
                    if unsafe { l.get::<*const ()>(sym.as_bytes()) }.is_err() {
                        problems.push(format!("{} does not export the entry point {sym}", lib.display()));
                    }
                }
            }
        }
    }
    (problems, library)
}

/// Asserts `text` (found at `path`, or to be written there) is valid, naming `what` on failure.
pub fn assert_valid(what: &str, api: Api, implicit: bool, text: &str, path: &Path) -> PathBuf {
    let (problems, library) = check(api, implicit, text, path);
    assert!(problems.is_empty(), "{what} ({}) breaks the loaders' manifest rules:\n  {}\n{text}", path.display(), problems.join("\n  "));
    library.expect("library resolved")
}
