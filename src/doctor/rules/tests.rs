//! Unit tests of the doctor's rules: gathered facts in, findings (status, words, fix) out.

use super::*;
use crate::core::config::Inputs;
use crate::track::device_ext::FsrSupport;

fn cfg(toml: &str) -> (Config, Vec<String>) {
    Config::resolve(&Inputs { keys: crate::registry::keys(), file: Some((Path::new("/c/config.toml"), toml)), app_names: &[], env: &|_| None })
}

fn only(findings: &[Finding], status: Status) -> Vec<&Finding> {
    findings.iter().filter(|f| f.status == status).collect()
}

fn loaded(exports: &[(&str, bool)], negotiates: Option<bool>) -> Result<LibraryFacts, String> {
    Ok(LibraryFacts { file: None, exports: exports.iter().map(|(n, b)| (n.to_string(), *b)).collect(), vk_negotiates: negotiates })
}

#[test]
fn library_paths_resolve_like_the_loaders() {
    let m = Path::new("/etc/openxr/1/active_runtime.json");
    assert_eq!(resolve_library(m, "/usr/lib/libx.so"), PathBuf::from("/usr/lib/libx.so"));
    assert_eq!(resolve_library(m, "../../lib/libx.so"), PathBuf::from("/etc/openxr/1/../../lib/libx.so"));
    assert_eq!(resolve_library(m, "libx.so"), PathBuf::from("libx.so"), "a bare name goes to the dynamic linker");
}

#[test]
fn runtime_manifests_are_read_strictly() {
    let good = r#"{"file_format_version": "1.0.0", "runtime": {"library_path": "libr.so"}}"#;
    assert_eq!(runtime_library(good).as_deref(), Ok("libr.so"));
    assert!(runtime_library(&good[..20]).unwrap_err().contains("not valid JSON"));
    assert!(runtime_library(r#"{"file_format_version": "1.0.0"}"#).is_err());
    assert!(runtime_library(r#"{"runtime": {"library_path": "x"}}"#).is_err());
}

fn runtime_facts(text: &str, load: Result<LibraryFacts, String>) -> RuntimeFacts {
    let path = PathBuf::from("/h/.config/openxr/1/active_runtime.json");
    RuntimeFacts {
        env: None,
        searched: vec![path.clone()],
        manifest: Some((path, Ok(text.into()))),
        library: Some(LibraryCheck { written: "libr.so".into(), resolved: "libr.so".into(), load }),
    }
}

#[test]
fn runtime_findings() {
    let good = r#"{"file_format_version": "1.0.0", "runtime": {"library_path": "libr.so"}}"#;
    let f = runtime(&runtime_facts(good, loaded(&[(RUNTIME_NEGOTIATE, true)], None)));
    assert_eq!(f[0].status, Status::Ok, "{f:?}");
    let f = runtime(&runtime_facts(good, Err("libr.so: cannot open shared object file".into())));
    assert_eq!(f[0].status, Status::Error);
    assert!(f[0].detail.contains("does not load") && f[0].fix.as_ref().unwrap().contains("reinstall"), "{f:?}");
    let f = runtime(&runtime_facts(good, loaded(&[(RUNTIME_NEGOTIATE, false)], None)));
    assert!(f[0].status == Status::Error && f[0].detail.contains(RUNTIME_NEGOTIATE));
    let f = runtime(&runtime_facts("{\"file_format", loaded(&[], None)));
    assert!(f[0].status == Status::Error && f[0].detail.contains("not valid JSON"), "{f:?}");

    let f = runtime(&RuntimeFacts { env: Some("/nowhere.json".into()), ..Default::default() });
    assert!(f[0].status == Status::Error && f[0].detail.contains("XR_RUNTIME_JSON=/nowhere.json does not exist"), "{f:?}");
    let f = runtime(&RuntimeFacts { searched: vec!["/a.json".into(), "/b.json".into()], ..Default::default() });
    assert!(f[0].detail.contains("no active runtime: none of /a.json, /b.json"), "{f:?}");
    assert!(f[0].fix.as_ref().unwrap().contains("XR_RUNTIME_JSON"));
}

#[test]
fn instance_findings() {
    use crate::xr::probe::XrFacts;
    let rt = runtime_facts("{}", loaded(&[], None));
    let probe = |instance: Result<(String, String), String>| -> XrProbe { Ok(XrFacts { loader: None, layers: Ok(vec![]), extensions: Ok(vec![]), instance }) };
    let f = instance(&probe(Ok(("Monado".into(), "25.0.0".into()))), &rt);
    assert_eq!((f[0].status, f[0].detail.as_str()), (Status::Ok, "Monado 25.0.0"));
    assert_eq!(instance(&probe(Err("ERROR_RUNTIME_UNAVAILABLE".into())), &rt)[0].status, Status::Warning);
    assert_eq!(instance(&probe(Err("ERROR_INITIALIZATION_FAILED".into())), &rt)[0].status, Status::Error);
    assert!(instance(&probe(Err("ERROR_RUNTIME_UNAVAILABLE".into())), &RuntimeFacts::default()).is_empty(), "no runtime: said once, by `runtime`");
    assert!(instance(&Err("no loader".into()), &rt).is_empty());
}

fn ours_text(extra: &str) -> String {
    format!(
        r#"{{"file_format_version": "1.0.0", "api_layer": {{"name": "{XR_LAYER_NAME}", "library_path": "/l/libstereoshim.so", "api_version": "1.1",
           "functions": {{"{XR_NEGOTIATE}": "{XR_NEGOTIATE}"}}{extra}}}}}"#
    )
}

fn manifest(text: &str, implicit: bool, load: Result<LibraryFacts, String>, same: Option<bool>) -> ManifestFacts {
    ManifestFacts {
        path: "/d/openxr/1/api_layers/implicit.d/stereoshim.json".into(),
        implicit,
        text: Ok(text.into()),
        library: Some(LibraryCheck { written: "/l/libstereoshim.so".into(), resolved: "/l/libstereoshim.so".into(), load }),
        same_as_build: same,
    }
}

fn both() -> Result<LibraryFacts, String> {
    loaded(&[(XR_NEGOTIATE, true), (VK_NEGOTIATE, true)], None)
}

#[test]
fn a_healthy_manifest_is_ok() {
    let good = ours_text(&format!(r#", "disable_environment": "{DISABLE_ENV}""#));
    let f = manifests(&[manifest(&good, true, both(), Some(true))], false);
    assert_eq!(f.len(), 1, "{f:?}");
    assert_eq!(f[0].status, Status::Ok);
    assert!(f[0].detail.ends_with("-> /l/libstereoshim.so, this build"), "{f:?}");
}

#[test]
fn broken_manifests_are_errors_with_a_fix() {
    let good = ours_text(&format!(r#", "disable_environment": "{DISABLE_ENV}""#));
    let cases: Vec<(ManifestFacts, &str)> = vec![
        (manifest(&good[..good.len() / 2], true, both(), None), "not valid JSON"),
        (manifest(&good, true, Err("no such file".into()), None), "does not load: no such file"),
        (manifest(&good, true, loaded(&[(XR_NEGOTIATE, true), (VK_NEGOTIATE, false)], None), None), "does not export vkNegotiate"),
        (manifest(&ours_text(""), true, both(), None), "without disable_environment"),
        (manifest(&good.replace(r#""api_version": "1.1","#, ""), true, both(), None), "must be strings"),
        (manifest(&good.replace(r#""library_path": "/l/libstereoshim.so","#, ""), true, both(), None), "no string library_path"),
        (ManifestFacts { text: Err("permission denied".into()), ..manifest(&good, true, both(), None) }, "cannot be read"),
    ];
    for (m, expected) in cases {
        let f = manifests(&[m], false);
        assert_eq!(f[0].status, Status::Error, "{expected}: {f:?}");
        assert!(f[0].detail.contains(expected), "{expected}: {f:?}");
        assert!(f[0].fix.as_ref().unwrap().contains("stereoshim install"), "{f:?}");
    }
    // The explicit manifest (`stereoshim run`'s kind) needs no disable variable.
    assert_eq!(manifests(&[manifest(&ours_text(""), false, both(), None)], false)[0].status, Status::Ok);
}

#[test]
fn stale_duplicate_missing_and_disabled_are_warnings() {
    let good = ours_text(&format!(r#", "disable_environment": "{DISABLE_ENV}""#));
    let f = manifests(&[manifest(&good, true, both(), Some(false))], false);
    assert!(f[0].status == Status::Warning && f[0].detail.contains("not this build's library"), "{f:?}");
    let gated = ours_text(&format!(r#", "disable_environment": "{DISABLE_ENV}", "enable_environment": "ONLY_ME""#));
    assert!(manifests(&[manifest(&gated, true, both(), None)], false)[0].detail.contains("ONLY_ME"));

    let mut second = manifest(&good, true, both(), None);
    second.path = "/usr/share/openxr/1/api_layers/implicit.d/stereoshim.json".into();
    let f = manifests(&[manifest(&good, true, both(), None), second], false);
    let w = only(&f, Status::Warning);
    assert_eq!(w.len(), 1, "{f:?}");
    assert!(w[0].detail.contains("registered 2 times") && w[0].fix.as_ref().unwrap().contains("/usr/share/openxr"), "{f:?}");

    let f = manifests(&[], false);
    assert!(f[0].status == Status::Warning && f[0].detail.contains("not installed"), "{f:?}");
    let f = manifests(&[manifest(&good, true, both(), None)], true);
    assert!(f.iter().any(|x| x.status == Status::Warning && x.detail.contains(DISABLE_ENV)), "{f:?}");
}

fn half(negotiates: Option<bool>) -> VulkanHalfFacts {
    VulkanHalfFacts {
        library: Some(LibraryCheck { written: "/l/libstereoshim.so".into(), resolved: "/l/libstereoshim.so".into(), load: loaded(&[(XR_NEGOTIATE, true), (VK_NEGOTIATE, true)], negotiates) }),
        manifest_dir: Ok("/run/user/1/stereoshim/vulkan-1".into()),
    }
}

#[test]
fn vulkan_half_findings() {
    let listed = vec![VK_LAYER_NAME.to_string()];
    let none = |_: &str| None;
    let f = vulkan_half(&half(Some(true)), Some(&listed), &none);
    assert!(f.iter().all(|x| x.status == Status::Ok), "{f:?}");
    let f = vulkan_half(&half(Some(false)), Some(&listed), &none);
    assert!(f[0].status == Status::Error && f[0].detail.contains("refused"), "{f:?}");
    let f = vulkan_half(&half(Some(true)), Some(&[]), &none);
    assert_eq!(f[1].status, Status::Error, "not listed, nothing explains it: {f:?}");
    let layer_path = |k: &str| (k == "VK_LAYER_PATH").then(|| "/opt/layers".to_string());
    let f = vulkan_half(&half(Some(true)), Some(&[]), &layer_path);
    assert!(f[1].status == Status::Warning && f[1].detail.contains("VK_LAYER_PATH=/opt/layers"), "{f:?}");
    assert!(f[1].fix.as_ref().unwrap().contains("unset VK_LAYER_PATH"));
    let f = vulkan_half(&VulkanHalfFacts { library: None, manifest_dir: Err("none of XDG_RUNTIME_DIR, XDG_STATE_HOME, HOME is set".into()) }, None, &none);
    assert_eq!(only(&f, Status::Error).len(), 2, "{f:?}");
}

fn device(name: &str, cpu: bool, fsr: Option<FsrSupport>, texel: (u32, u32)) -> DeviceFacts {
    DeviceFacts {
        name: name.into(),
        api_version: ash::vk::API_VERSION_1_3,
        cpu,
        device_type: String::new(),
        extensions: if fsr.is_some() { vec![device_ext::FRAGMENT_SHADING_RATE.to_string()] } else { vec![] },
        multiview: true,
        dynamic_rendering: true,
        pipeline_statistics: true,
        fsr,
        fsr_texel: texel,
        fsr_layered: true,
    }
}

fn vulkan(devices: Vec<DeviceFacts>) -> Result<VulkanFacts, String> {
    Ok(VulkanFacts { loader: None, instance_version: ash::vk::API_VERSION_1_3, layers: vec![], instance_error: None, devices })
}

#[test]
fn foveation_auto_follows_the_layers_rule() {
    let rates = Some(FsrSupport { pipeline: true, primitive: true, attachment: true });
    let (c, _) = cfg("");
    let gpu_vrs = device("gpu", false, rates, (16, 16));
    assert_eq!(foveation_on(&gpu_vrs, ash::vk::API_VERSION_1_3, &c), (Some(Method::Vrs), true));
    assert_eq!(foveation_on(&device("gpu", false, None, (0, 0)), ash::vk::API_VERSION_1_3, &c), (Some(Method::Rdm), false));
    assert_eq!(foveation_on(&device("cpu", true, None, (0, 0)), ash::vk::API_VERSION_1_3, &c), (None, false));
    // Attachment rates reported but a 0×0 texel: the layer does not use them (`fsr_rates`).
    assert_eq!(foveation_on(&device("gpu", false, rates, (0, 0)), ash::vk::API_VERSION_1_3, &c).0, Some(Method::Rdm));
    // `vulkan.fragment_shading_rate = off`: the layer never enables rates, auto picks RDM.
    let (off, _) = cfg("vulkan.fragment_shading_rate = \"off\"\n");
    assert_eq!(foveation_on(&gpu_vrs, ash::vk::API_VERSION_1_3, &off), (Some(Method::Rdm), false));
}

#[test]
fn gpu_findings() {
    let (c, _) = cfg("");
    let f = gpu(&Err("libvulkan.so.1: cannot open shared object file".into()), &c);
    assert!(f[0].status == Status::Error && f[0].fix.as_ref().unwrap().contains("libvulkan1"), "{f:?}");
    let f = gpu(&Ok(VulkanFacts { instance_error: Some("vkCreateInstance: ERROR_INCOMPATIBLE_DRIVER".into()), ..vulkan(vec![]).unwrap() }), &c);
    assert!(f[1].status == Status::Error && f[1].detail.contains("ERROR_INCOMPATIBLE_DRIVER"), "{f:?}");
    let f = gpu(&vulkan(vec![]), &c);
    assert!(f[1].status == Status::Error && f[1].detail == "no Vulkan device", "{f:?}");

    let rates = Some(FsrSupport { pipeline: true, primitive: true, attachment: true });
    let f = gpu(&vulkan(vec![device("Radeon", false, rates, (8, 8)), device("llvmpipe", true, None, (0, 0))]), &c);
    assert!(only(&f, Status::Warning).is_empty() && only(&f, Status::Error).is_empty(), "a GPU next to lavapipe is fine: {f:?}");
    assert!(f[1].detail.contains("shading rate attachment yes (8×8 texels, layered)"), "{f:?}");
    assert!(f[2].detail.contains("-> vrs"), "{f:?}");
    assert!(f[4].detail.contains("-> none"), "{f:?}");

    let f = gpu(&vulkan(vec![device("llvmpipe", true, None, (0, 0))]), &c);
    assert_eq!(only(&f, Status::Warning).len(), 1, "{f:?}");
    // Foveation switched on where auto picks nothing: say so.
    let (on, _) = cfg("foveation.enabled = true\n");
    let f = gpu(&vulkan(vec![device("llvmpipe", true, None, (0, 0))]), &on);
    assert!(only(&f, Status::Warning).iter().any(|w| w.check == "foveation.0" && w.fix.as_ref().unwrap().contains("rdm")), "{f:?}");
    let (vrs, _) = cfg("foveation.enabled = true\nfoveation.method = \"vrs\"\n");
    let f = gpu(&vulkan(vec![device("old", false, None, (0, 0))]), &vrs);
    assert!(only(&f, Status::Warning).iter().any(|w| w.detail.contains("not applied")), "{f:?}");
    let mut no_mv = device("old", false, None, (0, 0));
    no_mv.multiview = false;
    assert_eq!(only(&gpu(&vulkan(vec![no_mv]), &c), Status::Warning).len(), 1);
}

fn config_facts(toml: &str) -> ConfigFacts {
    let (config, diagnostics) = cfg(toml);
    ConfigFacts { path: Some("/c/config.toml".into()), explicit: false, exists: true, app: None, config, diagnostics }
}

#[test]
fn config_diagnostics_are_classified() {
    let f = config(&config_facts("mask.enabled = true\n"));
    assert_eq!(f.len(), 1);
    assert!(f[0].status == Status::Ok && f[0].detail.contains("mask.enabled = true"), "{f:?}");
    // The texts come from the layer's own config loader: a change there fails here.
    let f = config(&config_facts("mask.enabeld = true\n"));
    assert!(f[1].status == Status::Warning && f[1].detail.contains("unknown key `mask.enabeld`"), "{f:?}");
    let f = config(&config_facts("foveation.method = \"fast\"\n"));
    assert!(f[1].status == Status::Warning && f[1].detail.contains("foveation.method"), "{f:?}");
    let f = config(&config_facts("mask.enabled = = true\n"));
    assert!(f[1].status == Status::Error && f[1].detail.contains(WHOLE_FILE), "{f:?}");
    let f = config(&config_facts("enabled = false\n"));
    assert!(f[1].status == Status::Warning && f[1].detail.contains("passes everything through"), "{f:?}");
    let f = config(&ConfigFacts { explicit: true, exists: false, ..config_facts("") });
    assert!(f[0].status == Status::Error && f[0].detail.contains("does not exist"), "{f:?}");
}

#[test]
fn layer_disable_filters() {
    assert!(disables_layer("~all~", VK_LAYER_NAME));
    assert!(disables_layer("VK_LAYER_KHRONOS_validation, ~explicit~", VK_LAYER_NAME));
    assert!(disables_layer("*stereoshim*", VK_LAYER_NAME));
    assert!(disables_layer("VK_LAYER_STEREOSHIM_*", VK_LAYER_NAME));
    assert!(!disables_layer("~implicit~", VK_LAYER_NAME), "the Vulkan half is an explicit layer");
    assert!(!disables_layer("VK_LAYER_KHRONOS_*", VK_LAYER_NAME));
    assert!(!disables_layer("", VK_LAYER_NAME));
    assert!(disables_layer("VK_*_STEREOSHIM_*shim", VK_LAYER_NAME));
    assert!(!disables_layer("VK_*_STEREOSHIM_*x", VK_LAYER_NAME));
    // Many stars and no match: answered at once (a backtracking matcher takes years here).
    let t = std::time::Instant::now();
    assert!(!disables_layer(&format!("{}x", "*".repeat(40)), VK_LAYER_NAME));
    assert!(t.elapsed() < std::time::Duration::from_secs(1));
}

#[test]
fn conflict_findings() {
    let none = |_: &str| None;
    let others = vec![
        OtherLayer { name: "XR_APILAYER_NOVENDOR_toolkit".into(), path: "/t.json".into(), disable_environment: Some("DISABLE_XR_APILAYER_NOVENDOR_toolkit".into()) },
        OtherLayer { name: "XR_APILAYER_harmless".into(), path: "/h.json".into(), disable_environment: None },
    ];
    let f = conflicts(&others, None, false, &none);
    assert_eq!(f[0].status, Status::Warning, "{f:?}");
    assert!(f[0].fix.as_ref().unwrap().contains("DISABLE_XR_APILAYER_NOVENDOR_toolkit=1"));
    assert_eq!(f[1].status, Status::Ok);
    let f = conflicts(&[], Some(&["XR_APILAYER_other".to_string()]), true, &none);
    assert!(f[0].status == Status::Warning && f[0].detail.contains("does not list"), "{f:?}");
    assert!(conflicts(&[], Some(&[XR_LAYER_NAME.to_string()]), true, &none).is_empty());
    let disable = |k: &str| (k == "VK_LOADER_LAYERS_DISABLE").then(|| "~all~".to_string());
    let f = conflicts(&[], None, false, &disable);
    assert!(f[0].status == Status::Warning && f[0].detail.contains("VK_LOADER_LAYERS_DISABLE=~all~"), "{f:?}");
}

#[test]
fn runtime_extensions() {
    use crate::xr::probe::XrFacts;
    let rt = runtime_facts("{}", loaded(&[], None));
    let probe = |ext: &[&str]| -> XrProbe {
        Ok(XrFacts { loader: None, layers: Ok(vec![]), extensions: Ok(ext.iter().map(|e| e.to_string()).collect()), instance: Err(String::new()) })
    };
    let f = extensions(&probe(&["XR_KHR_vulkan_enable2", "XR_KHR_visibility_mask"]), &rt);
    assert_eq!(f[0].status, Status::Ok, "{f:?}");
    assert!(f[0].detail.contains("runtime's hidden-area masks") && f[0].detail.contains("optical axis"), "{f:?}");
    let f = extensions(&probe(&["XR_KHR_opengl_enable"]), &rt);
    assert!(f[0].status == Status::Error && f[0].detail.contains("Vulkan apps only"), "{f:?}");
    assert!(extensions(&probe(&[]), &RuntimeFacts::default()).is_empty());
}

#[test]
fn eyes_of_the_last_session_come_from_the_log() {
    assert_eq!(eyes(None)[0].status, Status::Ok);
    let log = "\
x INFO stereoshim::vk::chain: vulkan instance created\n\
x INFO stereoshim::vk::inject: data-flow walk: colour target 0xa of an eye pass, reached from the swapchain through old: view 0 layer 0 8x8+0+0\n\
x INFO stereoshim::vk::chain: vulkan instance created\n\
x INFO stereoshim::vk::inject: data-flow walk: colour target 0xf of an eye pass, reached from the swapchain through resolve ← draw: view 0 layer 0 256x256+0+0\n\
x INFO stereoshim::vk::inject: data-flow walk: view 1: a pass on the way (no depth-tested draw) samples no eye-sized image written in this frame (logged once)\n\
x INFO stereoshim::vk::inject: eyes.fallback = size: an untraced pass's target 0x12 taken as an eye target by size and order (LeftRight, pass 0 of the frame): view 0 layer 0 256x256+0+0\n";
    let f = eyes(Some(log));
    assert_eq!(f.len(), 3, "{f:?}");
    assert!(f[0].status == Status::Ok && f[0].detail.contains("0xf") && f[0].detail.contains("resolve ← draw"), "only the last session: {f:?}");
    assert!(f[1].status == Status::Warning && f[1].detail.starts_with("not traced: view 1"));
    assert!(f[2].status == Status::Warning && f[2].detail.contains("by size"));
    let direct = eyes(Some("x vulkan instance created\nx masking per-eye pass on swapchain image 0x5\n"));
    assert!(direct.len() == 1 && direct[0].detail.contains("swapchain images"));
}

#[test]
fn the_upscale_as_configured() {
    let (off, _) = cfg("");
    assert!(upscale(&Settings::from_config(&off)).is_empty());
    let (on, _) = cfg("upscale.enabled = true\nupscale.scale = 0.7\nupscale.mip_bias = \"sharp\"\n");
    let f = upscale(&Settings::from_config(&on));
    assert_eq!(f[0].status, Status::Ok);
    assert!(f[0].detail.contains("49 %") && f[0].detail.contains("-0.51"), "{}", f[0].detail);
    assert_eq!(f[1].status, Status::Warning);
}
