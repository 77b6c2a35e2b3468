//! Foveation method 1, variable-rate shading, on lavapipe — which has no
//! `attachmentFragmentShadingRate`: `foveation.method = vrs` must report itself unsupported and
//! change nothing (captures bit-identical to a run without the layer, validation silent), and
//! `auto` must not fall back to radial density masking on a CPU implementation, where it makes
//! frames slower (docs/benchmarks.md): it too changes nothing and says why. (The GPU proof is
//! `examples/fovea_check`.)

use crate::common;

use common::{Half, Run};

fn stats_lines(path: &std::path::Path) -> Vec<serde_json::Value> {
    std::fs::read_to_string(path).unwrap_or_default().lines().map(|l| serde_json::from_str(l).expect("stats line parses")).collect()
}

fn foveated(name: &str, args: &[&str], method: &str) -> (common::RunOutput, Vec<serde_json::Value>) {
    let stats = common::target_dir().join("test-output").join(format!("{name}.layer-stats.jsonl"));
    let _ = std::fs::remove_file(&stats);
    let mut run = Run::new(name)
        .args(args.iter().copied())
        .with_layer()
        .env("MOCK_XR_EYE_TRACKER", "0")
        .env("STEREOSHIM_FOVEATION_ENABLED", "1")
        .env("STEREOSHIM_FOVEATION_METHOD", method)
        .env("STEREOSHIM_STATS_FILE", stats.to_str().unwrap());
    run.name = name.to_string();
    let out = run.run();
    out.assert_ok();
    out.assert_log_lacks(Half::Both, "internal failure");
    (out, stats_lines(&stats))
}

#[test]
fn vrs_is_unsupported_on_lavapipe_and_changes_nothing() {
    for (layout, rendering) in [("per-eye", "dynamic"), ("multiview", "dynamic"), ("side-by-side", "render-pass")] {
        let args = ["--layout", layout, "--rendering", rendering];
        let plain = Run::new(&format!("vrs-plain-{layout}-{rendering}")).args(args).env("MOCK_XR_EYE_TRACKER", "0").run();
        plain.assert_ok();
        let (out, stats) = foveated(&format!("vrs-lavapipe-{layout}-{rendering}"), &args, "vrs");
        common::assert_same_captures(&out.name, &out, &plain);
        let frames = |o: &common::RunOutput| o.stats.as_ref().map_or(0, |s| s.frames.len());
        assert!(frames(&plain) > 0, "{}: no app stats", plain.name);
        assert_eq!(frames(&out), frames(&plain), "{}: app stats of another number of frames", out.name);
        // The device never got the extension (lavapipe lacks attachment rates), nothing went in.
        assert!(!out.log_lines("vrs unsupported on this device").is_empty(), "{}: {}", out.name, out.log);
        out.assert_log_lacks(Half::Vulkan, "vrs on ").assert_log_lacks(Half::Vulkan, "radial density masking ");
        let f1 = stats.iter().find(|v| v["frame"] == 1).unwrap_or_else(|| panic!("{}: no stats for frame 1", out.name));
        assert_eq!(f1["foveation_enabled"], true, "{f1}");
        assert_eq!(f1["vrs"]["passes"], 0, "{f1}");
        assert!(f1["vrs"]["not_applied"]["unsupported"].as_u64().unwrap_or(0) >= 1, "{f1}");
        assert_eq!(f1["rdm"]["passes"], 0, "{f1}");
    }
}

#[test]
fn auto_declines_rdm_on_lavapipe() {
    let args = ["--layout", "per-eye", "--rendering", "dynamic"];
    let plain = Run::new("vrs-auto-plain").args(args).env("MOCK_XR_EYE_TRACKER", "0").run();
    plain.assert_ok();
    let (out, stats) = foveated("vrs-auto-lavapipe", &args, "auto");
    common::assert_same_captures(&out.name, &out, &plain);
    assert!(!out.log_lines("foveation.method = auto: no foveation on this CPU Vulkan implementation").is_empty(), "auto did not say why: {}", out.log);
    out.assert_log_lacks(Half::Vulkan, "vrs unsupported").assert_log_lacks(Half::Vulkan, "radial density masking ");
    let f1 = stats.iter().find(|v| v["frame"] == 1).expect("stats of frame 1");
    assert_eq!(f1["rdm"]["passes"], 0, "{f1}");
    assert_eq!(f1["vrs"]["passes"], 0, "{f1}");
    assert!(f1["vrs"]["not_applied"].as_object().is_none_or(|m| m.is_empty()), "{f1}");
}

/// A Vulkan 1.0 app on a runtime that does not list `VK_KHR_get_physical_device_properties2`
/// (which shading rate needs on a 1.0 instance): with `enable2` the layer adds it to the app's
/// create info, with `enable` it lists it in `xrGetVulkanInstanceExtensionsKHR`'s answer, which the
/// app enables. Either way the app runs as before (validation silent, captures identical).
#[test]
fn vulkan_1_0_instances_get_what_shading_rate_needs() {
    for (binding, logged) in [("enable2", "adding [\"VK_KHR_get_physical_device_properties2\"]"), ("enable", "listing VK_KHR_get_physical_device_properties2")] {
        let args = ["--layout", "per-eye", "--rendering", "render-pass", "--vulkan-api", "1.0", "--vulkan", binding];
        // The mock's external-memory instance and device extensions go too: they need properties2
        // on a 1.0 instance themselves.
        let omit = (
            "MOCK_XR_DISABLE_EXTENSIONS",
            "VK_KHR_get_physical_device_properties2,VK_KHR_external_memory_capabilities,VK_KHR_external_semaphore_capabilities,\
             VK_KHR_external_fence_capabilities,VK_KHR_external_memory,VK_KHR_external_memory_fd,VK_KHR_external_semaphore,VK_KHR_external_fence",
        );
        let plain = Run::new(&format!("props2-plain-{binding}")).args(args).env(omit.0, omit.1).run();
        plain.assert_ok();
        let mut layered = Run::new(&format!("props2-layer-{binding}")).args(args).env(omit.0, omit.1).with_layer();
        layered = layered.env("STEREOSHIM_FOVEATION_METHOD", "vrs");
        let out = layered.run();
        out.assert_ok();
        out.assert_layer_loaded(Half::Both);
        assert_eq!(out.log_lines(logged).len(), 1, "{binding}:\n{}", out.log);
        common::assert_same_captures(&out.name, &out, &plain);
    }
}
