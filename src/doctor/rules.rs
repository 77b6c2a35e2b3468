//! What `stereoshim doctor`'s gathered facts mean: each check turns facts (files read, libraries
//! loaded, what the loaders and the GPU reported, the resolved config) into findings, each ok,
//! warning or error with a one-line fix. Pure, so every rule is unit-tested without touching the
//! machine; the probing lives in `gather` and the FFI shells (`vk::probe`, `xr::probe`).
#![forbid(unsafe_code)]

use crate::features::upscale::UpscaleSettings;
use crate::features::foveation::FoveationSettings;
use crate::core::config::Config;
use crate::features::foveation::Method;
use crate::manifests::{DISABLE_ENV, VK_LAYER_NAME, VK_NEGOTIATE, XR_LAYER_NAME, XR_NEGOTIATE};
use crate::plugin::settings::Settings;
use crate::track::device_ext;
use crate::vk::probe::{DeviceFacts, LibraryFacts, VulkanFacts};
use std::path::{Path, PathBuf};

/// How bad a finding is. `Warning` never fails the command (exit 0): the layer works, perhaps
/// not as configured or not in this environment.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Status {
    Ok,
    Warning,
    Error,
}

impl Status {
    pub fn word(self) -> &'static str {
        match self {
            Status::Ok => "ok",
            Status::Warning => "warning",
            Status::Error => "error",
        }
    }
}

/// One line of the report.
#[derive(Clone, Debug, PartialEq)]
pub struct Finding {
    /// What was checked (`openxr.runtime`, `vulkan.device`, ...).
    pub check: String,
    pub status: Status,
    pub detail: String,
    /// What to do about it (warnings and errors).
    pub fix: Option<String>,
}

fn ok(check: &str, detail: impl Into<String>) -> Finding {
    Finding { check: check.into(), status: Status::Ok, detail: detail.into(), fix: None }
}

fn warning(check: &str, detail: impl Into<String>, fix: impl Into<String>) -> Finding {
    Finding { check: check.into(), status: Status::Warning, detail: detail.into(), fix: Some(fix.into()) }
}

fn error(check: &str, detail: impl Into<String>, fix: impl Into<String>) -> Finding {
    Finding { check: check.into(), status: Status::Error, detail: detail.into(), fix: Some(fix.into()) }
}

/// A library named by a manifest: as written, where it resolves, and what loading it showed.
#[derive(Clone, Debug, PartialEq)]
pub struct LibraryCheck {
    pub written: String,
    pub resolved: PathBuf,
    pub load: Result<LibraryFacts, String>,
}

/// Where a manifest's `library_path` points, by the loaders' rule: absolute as is, a path with a
/// `/` relative to the manifest's folder, a bare file name through the dynamic linker's search.
pub fn resolve_library(manifest: &Path, written: &str) -> PathBuf {
    let p = Path::new(written);
    if p.is_absolute() || !written.contains('/') {
        p.to_path_buf()
    } else {
        manifest.parent().unwrap_or(Path::new("")).join(p)
    }
}

fn json(text: &str) -> Result<serde_json::Value, String> {
    serde_json::from_str(text).map_err(|e| format!("not valid JSON ({e})"))
}

fn string_at<'a>(v: &'a serde_json::Value, key: &str) -> Option<&'a str> {
    v.get(key).and_then(|x| x.as_str())
}

/// The `library_path` of a runtime manifest, or why the manifest is unusable.
pub fn runtime_library(text: &str) -> Result<String, String> {
    let v = json(text)?;
    if string_at(&v, "file_format_version").is_none() {
        return Err("no string file_format_version".into());
    }
    let runtime = v.get("runtime").ok_or("no `runtime` object")?;
    string_at(runtime, "library_path").map(str::to_string).ok_or_else(|| "no string runtime.library_path".into())
}

/// An API-layer manifest's fields the checks look at.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LayerManifest {
    pub name: String,
    pub library_path: Option<String>,
    pub file_format_version: Option<String>,
    pub api_version: Option<String>,
    pub disable_environment: Option<String>,
    pub enable_environment: Option<String>,
    /// `functions.xrNegotiateLoaderApiLayerInterface` names the negotiation function (or the
    /// object is absent, and the loader looks the default name up).
    pub negotiate_ok: bool,
}

/// Reads an OpenXR API-layer manifest.
pub fn layer_manifest(text: &str) -> Result<LayerManifest, String> {
    let v = json(text)?;
    let layer = v.get("api_layer").filter(|l| l.is_object()).ok_or("no `api_layer` object")?;
    let negotiate_ok = match layer.get("functions") {
        None => true,
        Some(f) => f.get(XR_NEGOTIATE).map(|n| n.as_str() == Some(XR_NEGOTIATE)).unwrap_or(true),
    };
    Ok(LayerManifest {
        name: string_at(layer, "name").unwrap_or_default().to_string(),
        library_path: string_at(layer, "library_path").map(str::to_string),
        file_format_version: string_at(&v, "file_format_version").map(str::to_string),
        api_version: string_at(layer, "api_version").map(str::to_string),
        disable_environment: string_at(layer, "disable_environment").map(str::to_string),
        enable_environment: string_at(layer, "enable_environment").map(str::to_string),
        negotiate_ok,
    })
}

// ---------------------------------------------------------------------------------------------
// OpenXR: loader, runtime, instance

/// What the OpenXR probe gave (`xr::probe::probe`), or why it gave nothing.
pub type XrProbe = Result<crate::xr::probe::XrFacts, String>;

pub fn openxr_loader(xr: &XrProbe) -> Vec<Finding> {
    match xr {
        Ok(f) => vec![ok("openxr.loader", f.loader.as_ref().map(|p| p.display().to_string()).unwrap_or_else(|| crate::xr::probe::LOADER.into()))],
        Err(e) => vec![error(
            "openxr.loader",
            format!("{} does not load: {e}", crate::xr::probe::LOADER),
            "install the OpenXR loader (Debian/Ubuntu: libopenxr-loader1; Fedora/Arch: openxr)",
        )],
    }
}

/// The active runtime as the loader finds it.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RuntimeFacts {
    /// `XR_RUNTIME_JSON`, when set (then the only candidate).
    pub env: Option<PathBuf>,
    /// Every `active_runtime*.json` path the loader would try, in order.
    pub searched: Vec<PathBuf>,
    /// The manifest found and its text or why it could not be read.
    pub manifest: Option<(PathBuf, Result<String, String>)>,
    /// Its library, when the manifest names one.
    pub library: Option<LibraryCheck>,
}

const RUNTIME_NEGOTIATE: &str = "xrNegotiateLoaderRuntimeInterface";

pub fn runtime(r: &RuntimeFacts) -> Vec<Finding> {
    const C: &str = "openxr.runtime";
    let fix_select = "install an OpenXR runtime (Monado, WiVRn, SteamVR) and make it active (its own tool, or a link at ~/.config/openxr/1/active_runtime.json), or set XR_RUNTIME_JSON";
    let Some((path, text)) = &r.manifest else {
        return vec![match &r.env {
            Some(p) => error(C, format!("XR_RUNTIME_JSON={} does not exist", p.display()), "point XR_RUNTIME_JSON at the runtime's manifest, or unset it to use the active runtime"),
            None => error(
                C,
                format!("no active runtime: none of {} exists", r.searched.iter().map(|p| p.display().to_string()).collect::<Vec<_>>().join(", ")),
                fix_select,
            ),
        }];
    };
    let via = if r.env.is_some() { " (XR_RUNTIME_JSON)" } else { "" };
    let text = match text {
        Ok(t) => t,
        Err(e) => return vec![error(C, format!("{}{via}: cannot be read: {e}", path.display()), "fix the file's permissions, or select the runtime again")],
    };
    if let Err(e) = runtime_library(text) {
        return vec![error(C, format!("{}{via}: {e}", path.display()), "reinstall or reselect the runtime: its manifest is damaged")];
    }
    let Some(lib) = &r.library else {
        return vec![error(C, format!("{}{via}: library not checked", path.display()), fix_select)];
    };
    match &lib.load {
        Err(e) => vec![error(
            C,
            format!("{}{via}: library {} does not load: {e}", path.display(), lib.resolved.display()),
            "reinstall the runtime, or select one that is installed (the manifest points at a missing or broken library)",
        )],
        Ok(l) => {
            let file = l.file.as_ref().unwrap_or(&lib.resolved).display().to_string();
            if l.exports.iter().any(|(n, has)| n == RUNTIME_NEGOTIATE && !has) {
                vec![error(C, format!("{}{via}: {file} does not export {RUNTIME_NEGOTIATE}", path.display()), "this file is not an OpenXR runtime: select the runtime again")]
            } else {
                vec![ok(C, format!("{}{via} -> {file}", path.display()))]
            }
        }
    }
}

/// The instance the probe created through the loader (with every implicit layer, stereoshim's
/// included, in its chain). Nothing to say without a runtime (`runtime` reported that).
pub fn instance(xr: &XrProbe, runtime: &RuntimeFacts) -> Vec<Finding> {
    const C: &str = "openxr.instance";
    let Ok(f) = xr else { return Vec::new() };
    if runtime.manifest.is_none() {
        return Vec::new();
    }
    match &f.instance {
        Ok((name, version)) => vec![ok(C, format!("{name} {version}"))],
        Err(code) if code.contains("RUNTIME_UNAVAILABLE") => {
            vec![warning(C, format!("xrCreateInstance: {code}: the runtime is installed but not running"), "start the runtime's service (monado-service, wivrn-server, SteamVR) and run doctor again")]
        }
        Err(code) => vec![error(
            C,
            format!("xrCreateInstance: {code}"),
            format!("start the runtime's service if it has one (monado-service, wivrn-server, SteamVR); if it runs, `{DISABLE_ENV}=1 stereoshim doctor` tells whether the layer is the cause"),
        )],
    }
}

/// What the runtime offers the layer: a Vulkan binding (required: stereoshim works on Vulkan apps
/// only), hidden-area masks and eye gaze (optional, each feature has a fallback).
pub fn extensions(xr: &XrProbe, runtime: &RuntimeFacts) -> Vec<Finding> {
    const C: &str = "openxr.extensions";
    let Ok(f) = xr else { return Vec::new() };
    if runtime.manifest.is_none() {
        return Vec::new();
    }
    let list = match &f.extensions {
        Ok(l) => l,
        Err(code) => return vec![error(C, format!("xrEnumerateInstanceExtensionProperties: {code}"), "check the runtime: it does not list its extensions")],
    };
    let has = |e: &str| list.iter().any(|x| x == e);
    let vulkan: Vec<&str> = ["XR_KHR_vulkan_enable2", "XR_KHR_vulkan_enable"].into_iter().filter(|e| has(e)).collect();
    if vulkan.is_empty() {
        return vec![error(C, "the runtime offers neither XR_KHR_vulkan_enable2 nor XR_KHR_vulkan_enable: stereoshim works on Vulkan apps only", "use a runtime with Vulkan support (Monado, WiVRn, SteamVR)")];
    }
    let mask = if has("XR_KHR_visibility_mask") { "XR_KHR_visibility_mask (the runtime's hidden-area masks)" } else { "no XR_KHR_visibility_mask (mask.source auto: a synthesized lens outline)" };
    let gaze = if has("XR_EXT_eye_gaze_interaction") { "XR_EXT_eye_gaze_interaction (gaze-following foveation)" } else { "no XR_EXT_eye_gaze_interaction (foveation on the optical axis)" };
    vec![ok(C, format!("{}; {mask}; {gaze}", vulkan.join(", ")))]
}

// ---------------------------------------------------------------------------------------------
// stereoshim's manifests and library

/// One manifest file that is, or looks like, stereoshim's (its name, file name or text).
#[derive(Clone, Debug, PartialEq)]
pub struct ManifestFacts {
    pub path: PathBuf,
    pub implicit: bool,
    pub text: Result<String, String>,
    pub library: Option<LibraryCheck>,
    /// The library's bytes equal the build next to this program (None: nothing to compare with).
    pub same_as_build: Option<bool>,
}

fn reinstall_fix(implicit: bool, path: &Path) -> String {
    if implicit {
        format!("run `stereoshim install` again (rewrites it), or delete {}", path.display())
    } else {
        format!("delete or regenerate {} (`stereoshim manifest openxr`)", path.display())
    }
}

fn one_manifest(m: &ManifestFacts) -> Finding {
    const C: &str = "layer.manifest";
    let kind = if m.implicit { "implicit" } else { "explicit" };
    let at = format!("{} ({kind})", m.path.display());
    let fix = reinstall_fix(m.implicit, &m.path);
    let text = match &m.text {
        Ok(t) => t,
        Err(e) => return error(C, format!("{at}: cannot be read: {e}"), fix),
    };
    let lm = match layer_manifest(text) {
        Ok(lm) => lm,
        Err(e) => return error(C, format!("{at}: {e}"), fix),
    };
    if lm.name != XR_LAYER_NAME {
        return error(C, format!("{at}: api_layer.name is {:?}, not {XR_LAYER_NAME}", lm.name), fix);
    }
    if lm.file_format_version.is_none() || lm.api_version.is_none() {
        return error(C, format!("{at}: file_format_version and api_version must be strings"), fix);
    }
    if !lm.negotiate_ok {
        return error(C, format!("{at}: functions.{XR_NEGOTIATE} names another function"), fix);
    }
    if m.implicit && lm.disable_environment.is_none() {
        return error(C, format!("{at}: an implicit layer without disable_environment is ignored by the loader"), fix);
    }
    let Some(written) = &lm.library_path else {
        return error(C, format!("{at}: no string library_path"), fix);
    };
    let Some(lib) = &m.library else {
        return error(C, format!("{at}: library {written} not checked"), fix);
    };
    let facts = match &lib.load {
        Err(e) => return error(C, format!("{at}: library {} does not load: {e}", lib.resolved.display()), fix),
        Ok(f) => f,
    };
    if let Some((missing, _)) = facts.exports.iter().find(|(_, has)| !has) {
        return error(C, format!("{at}: {} does not export {missing}: not a stereoshim library", lib.resolved.display()), fix);
    }
    if let Some(var) = &lm.enable_environment {
        return warning(C, format!("{at}: loads only where {var} is set (enable_environment)"), fix);
    }
    if m.same_as_build == Some(false) {
        return warning(C, format!("{at}: {} is not this build's library (an older or other version)", lib.resolved.display()), fix);
    }
    let same = if m.same_as_build == Some(true) { ", this build" } else { "" };
    ok(C, format!("{at} -> {}{same}", lib.resolved.display()))
}

pub fn manifests(ms: &[ManifestFacts], disabled: bool) -> Vec<Finding> {
    let mut out: Vec<Finding> = ms.iter().map(one_manifest).collect();
    let implicit: Vec<&ManifestFacts> = ms.iter().filter(|m| m.implicit).collect();
    if implicit.is_empty() {
        out.push(warning(
            "layer.manifest",
            "not installed: no implicit OpenXR layer manifest names stereoshim",
            "`stereoshim install --user` (every OpenXR app), or start one app with `stereoshim run -- APP`",
        ));
    } else if implicit.len() > 1 {
        out.push(warning(
            "layer.manifest",
            format!("registered {} times; the loader uses the first it reads ({})", implicit.len(), implicit[0].path.display()),
            format!("keep one: delete {}", implicit[1..].iter().map(|m| m.path.display().to_string()).collect::<Vec<_>>().join(", ")),
        ));
    }
    if disabled && !implicit.is_empty() {
        out.push(warning("env", format!("{DISABLE_ENV} is set: the implicit layer stays out of apps started from here"), format!("unset {DISABLE_ENV}")));
    }
    out
}

/// The library the OpenXR half runs from (installed, else next to this program) and the
/// Vulkan loader's view of the manifest it writes.
#[derive(Clone, Debug, PartialEq)]
pub struct VulkanHalfFacts {
    pub library: Option<LibraryCheck>,
    /// The folder the Vulkan manifest was written to, or why it could not be.
    pub manifest_dir: Result<PathBuf, String>,
}

/// The Vulkan half: the library loads and negotiates, and the Vulkan loader lists the layer
/// with the manifest the OpenXR half writes (`vk_layers`: the loader's list; None without one).
pub fn vulkan_half(h: &VulkanHalfFacts, vk_layers: Option<&[String]>, env: &dyn Fn(&str) -> Option<String>) -> Vec<Finding> {
    let mut out = Vec::new();
    const C: &str = "layer.vulkan";
    match &h.library {
        None => out.push(error(C, "no libstereoshim.so installed or next to this program", "`stereoshim install --user`, or build the project (cargo build)")),
        Some(lib) => match &lib.load {
            Err(e) => out.push(error(C, format!("{} does not load: {e}", lib.resolved.display()), "reinstall: `stereoshim install --user`")),
            Ok(f) => {
                let missing: Vec<&str> = f.exports.iter().filter(|(_, has)| !has).map(|(n, _)| n.as_str()).collect();
                if !missing.is_empty() {
                    out.push(error(C, format!("{} does not export {}", lib.resolved.display(), missing.join(", ")), "reinstall: `stereoshim install --user`"));
                } else if f.vk_negotiates != Some(true) {
                    out.push(error(C, format!("{}: {VK_NEGOTIATE} refused the loader's interface version 2", lib.resolved.display()), "reinstall: `stereoshim install --user`"));
                } else {
                    out.push(ok(C, format!("{} loads; exports {XR_NEGOTIATE} and {VK_NEGOTIATE}; negotiates Vulkan loader interface 2", lib.resolved.display())));
                }
            }
        },
    }
    const M: &str = "vulkan.manifest";
    match &h.manifest_dir {
        Err(e) => out.push(error(M, format!("the Vulkan layer manifest cannot be written: {e}"), "set XDG_RUNTIME_DIR to a folder of your own (mode 0700), as a login session does")),
        Ok(dir) => {
            let listed = vk_layers.map(|l| l.iter().any(|n| n == VK_LAYER_NAME));
            let layer_path = env("VK_LAYER_PATH").filter(|v| !v.is_empty());
            match (listed, layer_path) {
                (Some(true), _) => out.push(ok(M, format!("{}: the Vulkan loader lists {VK_LAYER_NAME}", dir.display()))),
                (None, _) => {}
                (Some(false), Some(p)) => out.push(warning(
                    M,
                    format!("VK_LAYER_PATH={p} hides {} (the Vulkan loader ignores VK_ADD_LAYER_PATH while VK_LAYER_PATH is set): the Vulkan half stays off", dir.display()),
                    "unset VK_LAYER_PATH (add your own layer folders with VK_ADD_LAYER_PATH instead)",
                )),
                (Some(false), None) => out.push(error(
                    M,
                    format!("the Vulkan loader does not list {VK_LAYER_NAME} with {} in VK_ADD_LAYER_PATH", dir.display()),
                    "check VK_LOADER_LAYERS_DISABLE and the loader's messages (VK_LOADER_DEBUG=layer stereoshim doctor)",
                )),
            }
        }
    }
    out
}

// ---------------------------------------------------------------------------------------------
// Vulkan and the GPU

pub fn vk_version(v: u32) -> String {
    use ash::vk;
    format!("{}.{}.{}", vk::api_version_major(v), vk::api_version_minor(v), vk::api_version_patch(v))
}

/// The foveation method the layer would use on this device with this config, as the layer
/// decides it (`device_ext::decide` at device creation, then `Method::resolve`).
pub fn foveation_on(d: &DeviceFacts, instance_version: u32, config: &Config) -> (Option<Method>, bool) {
    let decision = device_ext::decide(&device_ext::Inputs {
        available: &d.extensions,
        requested: &[],
        api_version: d.api_version.min(instance_version),
        // The layer adds VK_KHR_get_physical_device_properties2 to 1.0 instances that need it.
        instance_has_properties2: true,
        fsr_mode: config.choice("vulkan.fragment_shading_rate"),
        feature_wants_fsr: device_ext::foveation_wants_fsr(config.choice("foveation.method")),
        fsr_support: d.fsr,
    });
    let attachment = decision.enable_fsr.is_some_and(|f| f.attachment) && d.fsr_texel.0 > 0 && d.fsr_texel.1 > 0;
    (Settings::from_config(config).of::<FoveationSettings>().method.resolve(attachment, d.cpu), attachment)
}

fn yes(b: bool) -> &'static str {
    if b {
        "yes"
    } else {
        "no"
    }
}

pub fn gpu(vk: &Result<VulkanFacts, String>, config: &Config) -> Vec<Finding> {
    let driver_fix = "install the GPU's Vulkan driver (Mesa: mesa-vulkan-drivers; NVIDIA: its driver), and check VK_ICD_FILENAMES / VK_DRIVER_FILES if set";
    let v = match vk {
        Err(e) => return vec![error("vulkan.loader", format!("libvulkan.so.1 does not load: {e}"), "install the Vulkan loader (Debian/Ubuntu: libvulkan1) and the GPU's Vulkan driver")],
        Ok(v) => v,
    };
    let mut out = vec![ok(
        "vulkan.loader",
        format!("{} (Vulkan {})", v.loader.as_ref().map(|p| p.display().to_string()).unwrap_or_else(|| "libvulkan.so.1".into()), vk_version(v.instance_version)),
    )];
    if let Some(e) = &v.instance_error {
        out.push(error("vulkan.device", format!("no Vulkan driver answers: {e}"), driver_fix));
        return out;
    }
    if v.devices.is_empty() {
        out.push(error("vulkan.device", "no Vulkan device", driver_fix));
        return out;
    }
    let s = Settings::from_config(config);
    for (i, d) in v.devices.iter().enumerate() {
        let check = format!("vulkan.device.{i}");
        let rates = match d.fsr {
            Some(f) if f.attachment => format!("yes ({}×{} texels{})", d.fsr_texel.0, d.fsr_texel.1, if d.fsr_layered { ", layered" } else { "" }),
            Some(f) => format!("no (pipeline {}, primitive {})", yes(f.pipeline), yes(f.primitive)),
            None => "no (no VK_KHR_fragment_shading_rate)".into(),
        };
        let detail = format!(
            "{}{}, Vulkan {}: multiview {}, shading rate attachment {rates}, dynamic rendering {}, pipeline statistics {}",
            d.name,
            if d.cpu { " (CPU implementation)" } else { "" },
            vk_version(d.api_version),
            yes(d.multiview),
            yes(d.dynamic_rendering),
            yes(d.pipeline_statistics),
        );
        out.push(if d.api_version < ash::vk::API_VERSION_1_1 || !d.multiview {
            warning(&check, format!("{detail}; apps rendering both eyes in one multiview pass get no features here"), "update the driver (multiview is core in Vulkan 1.1)")
        } else {
            ok(&check, detail)
        });
        let (method, attachment) = foveation_on(d, v.instance_version, config);
        let picked = match method {
            Some(Method::Vrs) if attachment => "vrs (shading rate attachment)".to_string(),
            Some(Method::Vrs) => "vrs requested, but the device has no shading rate attachment: not applied".to_string(),
            Some(Method::Rdm) => "rdm (radial density masking)".to_string(),
            Some(Method::Auto) | None => "none (auto does not foveate on a CPU implementation)".to_string(),
        };
        let c = format!("foveation.{i}");
        let detail = format!("foveation.method = {} -> {picked}{}", config.choice("foveation.method"), if s.of::<FoveationSettings>().enabled { "" } else { "; foveation.enabled = false" });
        out.push(match method {
            Some(Method::Vrs) if !attachment && s.of::<FoveationSettings>().enabled => warning(&c, detail, "set foveation.method = auto (rdm where there are no attachment rates)"),
            None | Some(Method::Auto) if s.of::<FoveationSettings>().enabled => warning(&c, detail, "set foveation.method = rdm to foveate anyway (slower than none on most CPU-rendered apps)"),
            _ => ok(&c, detail),
        });
    }
    if v.devices.iter().all(|d| d.cpu) {
        out.push(warning("vulkan.device", "only a CPU implementation: fine for tests, far too slow for VR", driver_fix));
    }
    out
}

// ---------------------------------------------------------------------------------------------
// Configuration

/// The configuration as the layer would resolve it for one app.
#[derive(Clone, Debug)]
pub struct ConfigFacts {
    /// The file read (`--config`, else the default path), and whether `--config` named it.
    pub path: Option<PathBuf>,
    pub explicit: bool,
    pub exists: bool,
    pub app: Option<String>,
    pub config: Config,
    /// `config::load_from`'s diagnostics, as the layer logs them.
    pub diagnostics: Vec<String>,
}

/// The text `config::Config::resolve` gives a file it could not parse at all.
const WHOLE_FILE: &str = "using defaults for the whole file";

pub fn config(c: &ConfigFacts) -> Vec<Finding> {
    const C: &str = "config";
    let mut out = Vec::new();
    let for_app = c.app.as_ref().map(|a| format!(" for app {a:?}")).unwrap_or_default();
    let file = c.path.as_ref().map(|p| p.display().to_string()).unwrap_or_else(|| "none".into());
    if c.explicit && !c.exists {
        out.push(error(C, format!("{file} does not exist"), "pass an existing file to --config"));
    } else {
        let set: Vec<String> = c
            .config
            .entries()
            .filter(|(_, _, s)| !matches!(s, crate::core::config::Source::Default))
            .map(|(k, v, _)| format!("{k} = {v}"))
            .collect();
        let file = if c.exists { file } else { format!("{file} (absent: defaults)") };
        let set = if set.is_empty() { "no key set".to_string() } else { set.join(", ") };
        out.push(ok(C, format!("{file}{for_app}: {set}")));
    }
    if !c.config.enabled() {
        out.push(warning(C, format!("enabled = false ({}): the layer passes everything through", c.config.source("enabled")), "set enabled = true, or remove the key"));
    }
    out.extend(upscale(&Settings::from_config(&c.config)));
    for d in &c.diagnostics {
        out.push(if d.contains(WHOLE_FILE) {
            error(C, d.clone(), "fix the TOML syntax at the place named (the whole file is ignored until then)")
        } else if d.contains("unknown key") {
            warning(C, d.clone(), "correct or remove the key (`stereoshim status` lists every key)")
        } else {
            warning(C, d.clone(), "use a value the key accepts (docs/configuration.md)")
        });
    }
    out
}

/// The upscale as configured: what the app will render, and a mip bias the layer cannot read.
pub fn upscale(s: &Settings) -> Vec<Finding> {
    const C: &str = "upscale";
    let u = &s.of::<UpscaleSettings>();
    if !u.enabled {
        return Vec::new();
    }
    let bias = u.sampler_bias().map_or("off".to_string(), |b| format!("{b:+.2} levels"));
    let mut out = vec![ok(
        C,
        format!("on: the app renders {:.0} % of the pixels (scale {} per axis), {:?}, mip bias {bias}; new XR instances only (the size is latched per instance)", u.scale * u.scale * 100.0, u.scale, u.method),
    )];
    if !u.mip_bias_valid {
        out.push(warning(C, "upscale.mip_bias is not auto, off or a number in -4..4: auto is used", "set upscale.mip_bias = \"auto\", \"off\" or a number such as -0.5"));
    }
    out
}

// ---------------------------------------------------------------------------------------------
// Eyes of the last session

/// Which pass got which eye in the last session the layer logged (from `vulkan instance created`
/// on): the data-flow walk's eye targets, the size fallback's guesses, and what the walk could not
/// trace. `log`: the layer's log file, None when there is none.
pub fn eyes(log: Option<&str>) -> Vec<Finding> {
    const C: &str = "eyes";
    let Some(log) = log else { return vec![ok(C, "no layer log yet: run an app once to see which pass got which eye")] };
    let last = log.rfind("vulkan instance created").map_or(0, |i| log[..i].rfind('\n').map_or(0, |n| n + 1));
    let after = |l: &str, marker: &str| l.find(marker).map(|i| l[i + marker.len()..].trim().to_string());
    let mut out = Vec::new();
    let (mut traced, mut guessed, mut untraced) = (0, 0, 0);
    for l in log[last..].lines() {
        if let Some(m) = after(l, "data-flow walk: ") {
            if m.starts_with("colour target") || m.starts_with("depth image") {
                traced += 1;
                if traced <= 8 {
                    out.push(ok(C, m));
                }
            } else {
                untraced += 1;
                out.push(warning(C, format!("not traced: {m}"), "set eyes.fallback = \"size\" for this app (a guess by size and order), or report the app"));
            }
        } else if let Some(m) = after(l, "eyes.fallback = size: ") {
            guessed += 1;
            out.push(warning(C, format!("by size (eyes.fallback): {m}"), "a guess: check the eyes with mask.debug = true, or set eyes.fallback_order / eyes.fallback = \"off\""));
        }
    }
    if traced + guessed + untraced == 0 {
        out.push(ok(C, "the last session logged no eye target behind post-processing: its eye passes render into swapchain images (or no pass was seen)"));
    } else if traced > 8 {
        out.push(ok(C, format!("… and {} more traced targets in the log", traced - 8)));
    }
    out
}

// ---------------------------------------------------------------------------------------------
// Conflicts

/// An implicit OpenXR layer that is not stereoshim.
#[derive(Clone, Debug, PartialEq)]
pub struct OtherLayer {
    pub name: String,
    pub path: PathBuf,
    pub disable_environment: Option<String>,
}

/// Implicit layers known to change what stereoshim changes, with why.
const KNOWN_CONFLICTS: &[(&str, &str)] = &[
    ("XR_APILAYER_NOVENDOR_toolkit", "OpenXR Toolkit: its own foveated rendering and resolution changes on the same frames"),
    ("XR_APILAYER_MBUCCHIA_quad_views_foveated", "adds foveated inset views: the eye passes stereoshim sees are not the app's two views"),
];

/// `VK_LOADER_LAYERS_DISABLE` globs (`*` anywhere) that match `name`, or the special values that
/// disable every (explicit) layer.
pub fn disables_layer(filter: &str, name: &str) -> bool {
    // The classic greedy matcher (back to the last `*` on a mismatch): O(pattern × name), so no
    // filter, however many stars it has, makes the check slow.
    fn glob(p: &[u8], s: &[u8]) -> bool {
        let (mut pi, mut si, mut star, mut mark) = (0, 0, None, 0);
        while si < s.len() {
            if pi < p.len() && p[pi] != b'*' && p[pi].eq_ignore_ascii_case(&s[si]) {
                pi += 1;
                si += 1;
            } else if pi < p.len() && p[pi] == b'*' {
                star = Some(pi);
                mark = si;
                pi += 1;
            } else if let Some(sp) = star {
                pi = sp + 1;
                mark += 1;
                si = mark;
            } else {
                return false;
            }
        }
        p[pi..].iter().all(|&c| c == b'*')
    }
    filter.split(',').map(str::trim).any(|f| f == "~all~" || f == "~explicit~" || glob(f.as_bytes(), name.as_bytes()))
}

pub fn conflicts(others: &[OtherLayer], xr_layers: Option<&[String]>, installed: bool, env: &dyn Fn(&str) -> Option<String>) -> Vec<Finding> {
    let mut out = Vec::new();
    for o in others {
        let off = o.disable_environment.as_ref().map(|v| format!(" (disable: {v}=1)")).unwrap_or_default();
        match KNOWN_CONFLICTS.iter().find(|(n, _)| *n == o.name) {
            Some((_, why)) => out.push(warning(
                "openxr.layer",
                format!("{} ({}): {why}", o.name, o.path.display()),
                format!("keep one of the two per app{off}"),
            )),
            None => out.push(ok("openxr.layer", format!("also implicit: {} ({})", o.name, o.path.display()))),
        }
    }
    let disabled = env(DISABLE_ENV).is_some();
    if let Some(layers) = xr_layers {
        if installed && !disabled && !layers.iter().any(|l| l == XR_LAYER_NAME) {
            out.push(warning(
                "openxr.layer",
                format!("the OpenXR loader does not list {XR_LAYER_NAME}, although a manifest is installed"),
                "check the manifest finding above and the loader's messages (XR_LOADER_DEBUG=all stereoshim doctor)",
            ));
        }
    }
    if let Some(filter) = env("VK_LOADER_LAYERS_DISABLE").filter(|f| disables_layer(f, VK_LAYER_NAME)) {
        out.push(warning(
            "env",
            format!("VK_LOADER_LAYERS_DISABLE={filter} disables {VK_LAYER_NAME}: the Vulkan half stays off"),
            format!("leave {VK_LAYER_NAME} (and ~all~ / ~explicit~) out of VK_LOADER_LAYERS_DISABLE"),
        ));
    }
    if let Some(p) = env("XR_API_LAYER_PATH").filter(|p| !p.is_empty()) {
        out.push(ok("env", format!("XR_API_LAYER_PATH={p}: explicit OpenXR layers come only from there (implicit ones and `stereoshim run` are not affected)")));
    }
    out
}

#[cfg(test)]
mod tests;
