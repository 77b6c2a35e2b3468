//! The facts `stereoshim doctor` judges, read from this machine: the environment, manifest files,
//! libraries loaded the way the loaders load them, and the two loaders' own answers (`xr::probe`,
//! `vk::probe`, each on a thread of its own with a time limit, so a runtime that hangs or a
//! driver that crashes the probe becomes a finding, not a hung or aborted command).

use super::rules::{self, ConfigFacts, LibraryCheck, ManifestFacts, OtherLayer, RuntimeFacts, VulkanHalfFacts};
use crate::manifests::install::{self, Scope};
use crate::manifests::{MANIFEST_FILE, VK_NEGOTIATE, XR_LAYER_NAME, XR_NEGOTIATE};
use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::time::Duration;

/// How long one probe (a loader creating an instance) may take before it counts as hung.
pub const PROBE_LIMIT: Duration = Duration::from_secs(20);

fn env(key: &str) -> Option<String> {
    std::env::var(key).ok()
}

/// Runs `f` on a thread of its own and waits at most `limit`: a probe that panics or hangs
/// inside a driver or runtime is reported, and a hung thread is left behind (the command exits).
pub fn bounded<T: Send + 'static>(what: &str, limit: Duration, f: impl FnOnce() -> Result<T, String> + Send + 'static) -> Result<T, String> {
    let (tx, rx) = mpsc::channel();
    let spawned = std::thread::Builder::new().name(format!("doctor-{what}")).spawn(move || {
        let _ = tx.send(f());
    });
    if let Err(e) = spawned {
        return Err(format!("cannot start the {what} probe: {e}"));
    }
    match rx.recv_timeout(limit) {
        Ok(r) => r,
        Err(mpsc::RecvTimeoutError::Timeout) => Err(format!("the {what} probe did not finish within {} s", limit.as_secs())),
        Err(mpsc::RecvTimeoutError::Disconnected) => Err(format!("the {what} probe failed (panicked)")),
    }
}

/// Loads the library a manifest names, looking `symbols` up (and negotiating like the Vulkan
/// loader with `negotiate_vk`).
pub fn check_library(manifest: &Path, written: &str, symbols: &'static [&'static str], negotiate_vk: bool) -> LibraryCheck {
    let resolved = rules::resolve_library(manifest, written);
    let load = if resolved.is_absolute() && !resolved.exists() {
        Err("no such file".to_string())
    } else {
        let path = resolved.clone();
        bounded("library", PROBE_LIMIT, move || crate::vk::probe::load_library(&path, symbols, negotiate_vk))
    };
    LibraryCheck { written: written.to_string(), resolved, load }
}

const LAYER_SYMBOLS: &[&str] = &[XR_NEGOTIATE, VK_NEGOTIATE];

/// Every `active_runtime` candidate the OpenXR loader tries, in its order (OpenXR loader spec,
/// "Linux Active Runtime Location": per folder `active_runtime.<arch>.json`, then
/// `active_runtime.json`; folders `$XDG_CONFIG_HOME`, `$XDG_CONFIG_DIRS`, `/etc`).
pub fn runtime_candidates(env: install::Env<'_>) -> Vec<PathBuf> {
    let arch = match std::env::consts::ARCH {
        "x86" => "i686",
        a => a,
    };
    let mut bases = Vec::new();
    // `install::active_runtime` with an "exists" that records every path asked for.
    let asked = std::cell::RefCell::new(Vec::new());
    install::active_runtime(env, &|p| {
        asked.borrow_mut().push(p.to_path_buf());
        false
    });
    for p in asked.into_inner() {
        if let Some(dir) = p.parent() {
            bases.push(dir.join(format!("active_runtime.{arch}.json")));
            bases.push(p);
        }
    }
    bases
}

pub fn runtime() -> RuntimeFacts {
    let e = |k: &str| env(k).filter(|v| !v.is_empty());
    let mut r = RuntimeFacts::default();
    let found = match e("XR_RUNTIME_JSON") {
        Some(p) => {
            let p = PathBuf::from(p);
            r.env = Some(p.clone());
            p.exists().then_some(p)
        }
        None => {
            r.searched = runtime_candidates(&e);
            r.searched.iter().find(|p| p.exists()).cloned()
        }
    };
    let Some(path) = found else { return r };
    let text = std::fs::read_to_string(&path).map_err(|e| e.to_string());
    if let Ok(written) = text.as_deref().map_err(|e| e.clone()).and_then(rules::runtime_library) {
        // `canonicalize`: the file is often a link to the runtime's own manifest, and the loader
        // reads library_path relative to the file it points at.
        let real = std::fs::canonicalize(&path).unwrap_or_else(|_| path.clone());
        r.library = Some(check_library(&real, &written, &["xrNegotiateLoaderRuntimeInterface"], false));
    }
    r.manifest = Some((path, text));
    r
}

/// Whether a manifest file in a layer folder is, or looks like, stereoshim's: its layer name, or
/// (for a damaged file) its file name or a mention of the name.
fn looks_ours(file: &Path, text: &Result<String, String>) -> bool {
    match text {
        Ok(t) => match rules::layer_manifest(t) {
            Ok(m) => m.name == XR_LAYER_NAME,
            Err(_) => file.file_name().is_some_and(|n| n == MANIFEST_FILE) || t.contains(XR_LAYER_NAME),
        },
        Err(_) => file.file_name().is_some_and(|n| n == MANIFEST_FILE),
    }
}

/// The library this program belongs to (`target/debug/libstereoshim.so` next to `stereoshim`).
pub fn build_library() -> Option<PathBuf> {
    std::env::current_exe().ok()?.parent().map(|d| d.join("libstereoshim.so")).filter(|p| p.is_file())
}

fn same_file_contents(a: &Path, b: &Path) -> Option<bool> {
    let (ma, mb) = (std::fs::metadata(a).ok()?, std::fs::metadata(b).ok()?);
    if ma.len() != mb.len() {
        return Some(false);
    }
    Some(std::fs::read(a).ok()? == std::fs::read(b).ok()?)
}

/// stereoshim's manifests in the loader's layer folders, and every other implicit layer.
pub fn layers() -> (Vec<ManifestFacts>, Vec<OtherLayer>) {
    let build = build_library();
    let (mut ours, mut others) = (Vec::new(), Vec::new());
    let mut seen = std::collections::HashSet::new();
    for (dir, implicit) in install::layer_search_dirs(&env) {
        let Ok(entries) = std::fs::read_dir(&dir) else { continue };
        let mut files: Vec<PathBuf> = entries.flatten().map(|e| e.path()).filter(|p| p.extension().is_some_and(|x| x == "json")).collect();
        files.sort();
        for path in files {
            // The same folder may be reached twice (XDG_DATA_DIRS repeating a folder).
            if !seen.insert(std::fs::canonicalize(&path).unwrap_or_else(|_| path.clone())) {
                continue;
            }
            let text = std::fs::read_to_string(&path).map_err(|e| e.to_string());
            if looks_ours(&path, &text) {
                let written = text.as_ref().ok().and_then(|t| rules::layer_manifest(t).ok()).and_then(|m| m.library_path);
                let library = written.map(|w| check_library(&path, &w, LAYER_SYMBOLS, false));
                let same_as_build = match (&library, &build) {
                    (Some(l), Some(b)) if l.load.is_ok() && implicit => same_file_contents(&l.resolved, b),
                    _ => None,
                };
                ours.push(ManifestFacts { path, implicit, text, library, same_as_build });
            } else if implicit {
                if let Some(m) = text.as_ref().ok().and_then(|t| rules::layer_manifest(t).ok()) {
                    others.push(OtherLayer { name: m.name, path, disable_environment: m.disable_environment });
                }
            }
        }
    }
    (ours, others)
}

/// The library the OpenXR half runs from: the first installed implicit manifest's that loads,
/// else the one next to this program (what `stereoshim run` uses); its Vulkan manifest written
/// as the OpenXR half writes it, and that folder added to `VK_ADD_LAYER_PATH` of this process
/// (before any probe thread starts) so the Vulkan probe sees what an app would.
pub fn vulkan_half(ours: &[ManifestFacts]) -> VulkanHalfFacts {
    let installed = ours.iter().filter(|m| m.implicit).find_map(|m| m.library.as_ref().filter(|l| l.load.is_ok())).map(|l| l.resolved.clone());
    let Some(path) = installed.or_else(build_library).or_else(|| install::layout(Scope::User, &env).map(|l| l.library).filter(|p| p.is_file())) else {
        return VulkanHalfFacts { library: None, manifest_dir: Err("no library to write a manifest for".into()) };
    };
    let path = std::fs::canonicalize(&path).unwrap_or(path);
    let library = Some(check_library(Path::new("/"), &path.to_string_lossy(), LAYER_SYMBOLS, true));
    let manifest_dir = crate::manifests::vulkan::write_manifest(&path).map_err(|e| e.to_string());
    if let Ok(dir) = &manifest_dir {
        if let Some(value) = crate::manifests::vulkan::add_layer_path(env("VK_ADD_LAYER_PATH").as_deref(), dir) {
            // Only this process, and before the probe threads exist: the Vulkan loader reads it
            // when the probe enumerates layers, as it does in an app after the OpenXR half set it.
            std::env::set_var("VK_ADD_LAYER_PATH", value);
        }
    }
    VulkanHalfFacts { library, manifest_dir }
}

/// The configuration for `app` from `file` (or the default file), with the layer's own loader.
/// The layer's log file, if there is one (for which pass got which eye).
pub fn layer_log() -> Option<String> {
    crate::core::log::default_path(&env).and_then(|p| std::fs::read_to_string(p).ok())
}

pub fn config(file: Option<&Path>, app: Option<&str>) -> ConfigFacts {
    let path = file.map(Path::to_path_buf).or_else(|| crate::core::config::default_path(&env));
    let names: Vec<&str> = app.into_iter().collect();
    let (config, diagnostics) = crate::core::config::load_from(crate::registry::keys(), path.as_deref(), &names);
    let exists = path.as_ref().is_some_and(|p| p.is_file());
    let mut diagnostics = diagnostics;
    if exists {
        if let Some(Err(e)) = path.as_ref().map(std::fs::read_to_string) {
            diagnostics.insert(0, format!("{}: cannot be read: {e}; using defaults for the whole file", path.as_ref().map(|p| p.display().to_string()).unwrap_or_default()));
        }
    }
    ConfigFacts { path, explicit: file.is_some(), exists, app: app.map(str::to_string), config, diagnostics }
}
