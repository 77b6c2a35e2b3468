//! End-to-end checks of stereoshim's Vulkan half on its own (loaded by the Vulkan loader as an
//! explicit layer, no OpenXR layer): with every feature off it must be invisible — bit-identical
//! frames, no validation error — while its log proves it was in the chain and saw the app's
//! render pass instances of the right kind.

use crate::common;

use common::{assert_same_captures, vulkan_layer_dir, Half, Run, RunOutput};
use std::collections::BTreeMap;
use stereoshim::vk::VK_LAYER_NAME;

/// `VK_LAYER_PATH` replaces the loader's default search for explicit layers, so the system folders
/// (where `VK_LAYER_KHRONOS_validation` lives) are listed after ours.
fn layer_path() -> String {
    let ours = vulkan_layer_dir(VK_LAYER_NAME);
    format!("{}:/usr/local/share/vulkan/explicit_layer.d:/usr/share/vulkan/explicit_layer.d", ours.display())
}

fn with_layer(run: Run) -> Run {
    run.env("VK_LAYER_PATH", &layer_path()).env("VK_INSTANCE_LAYERS", VK_LAYER_NAME)
}

/// The counters of every `vulkan device stats:` line of the run's log, summed.
fn device_stats(out: &RunOutput) -> BTreeMap<String, u64> {
    let log = out.log.clone();
    let mut stats = BTreeMap::new();
    let mut lines = 0;
    for line in log.lines() {
        let Some((_, rest)) = line.split_once("vulkan device stats: ") else { continue };
        lines += 1;
        for kv in rest.split_whitespace() {
            if let Some((k, v)) = kv.split_once('=') {
                if let Ok(n) = v.parse::<u64>() {
                    *stats.entry(k.to_string()).or_insert(0) += n;
                }
            }
        }
    }
    assert!(lines > 0, "{}: no `vulkan device stats:` line: the Vulkan half was not loaded or saw no device; log:\n{log}", out.name);
    stats
}

fn expected_kind(rendering: &str) -> &'static str {
    match rendering {
        "render-pass" => "render_pass",
        "render-pass2" => "render_pass2",
        _ => "dynamic_rendering",
    }
}

/// One layout × rendering path: the layered run equals the plain one and counted its passes.
fn pass_through_is_exact(layout: &str, rendering: &str) {
    let base = |tag: &str| Run::new(&format!("vk-{layout}-{rendering}-{tag}")).args(["--layout", layout, "--rendering", rendering]);
    let plain = base("plain").run();
    plain.assert_ok();
    let layered = with_layer(base("layered")).run();
    layered.assert_ok();
    assert_same_captures(&format!("vk-{layout}-{rendering}"), &layered, &plain);
    common::assert_same_stats(&format!("vk-{layout}-{rendering}"), &layered, &plain);
    let stats = device_stats(&layered);
    let kind = expected_kind(rendering);
    // Two frames, each with at least one eye pass of the app's kind; no pass of another kind.
    assert!(stats[kind] >= 2, "{layout}/{rendering}: {kind} = {} in {stats:?}", stats[kind]);
    for other in ["render_pass", "render_pass2", "dynamic_rendering"].into_iter().filter(|k| *k != kind) {
        assert_eq!(stats[other], 0, "{layout}/{rendering}: unexpected {other} in {stats:?}");
    }
    assert!(stats["command_buffers_begun"] >= 2 && stats["pipelines"] >= 1, "{stats:?}");
    layered.assert_log_lacks(Half::Vulkan, "internal failure");
}

macro_rules! exact_tests {
    ($($name:ident: $layout:literal, $rendering:literal;)*) => {$(
        #[test]
        fn $name() {
            pass_through_is_exact($layout, $rendering);
        }
    )*};
}

exact_tests! {
    per_eye_render_pass: "per-eye", "render-pass";
    per_eye_render_pass2: "per-eye", "render-pass2";
    per_eye_dynamic: "per-eye", "dynamic";
    multiview_render_pass: "multiview", "render-pass";
    multiview_render_pass2: "multiview", "render-pass2";
    multiview_dynamic: "multiview", "dynamic";
    side_by_side_render_pass: "side-by-side", "render-pass";
    side_by_side_render_pass2: "side-by-side", "render-pass2";
    side_by_side_dynamic: "side-by-side", "dynamic";
}

/// The app creating its own instance and device (`XR_KHR_vulkan_enable`) with an offscreen MSAA
/// target resolved into the swapchain, and submitted depth: more objects and passes, still exact.
#[test]
fn app_created_device_intermediate_and_depth() {
    let cases: [(&str, &[&str]); 2] = [
        ("enable-msaa", &["--vulkan", "enable", "--layout", "per-eye", "--intermediate", "--samples", "4", "--depth", "reverse"]),
        ("enable-depth", &["--vulkan", "enable", "--layout", "multiview", "--submit-depth", "--rendering", "render-pass2"]),
    ];
    for (tag, args) in cases {
        let plain = Run::new(&format!("vk-{tag}-plain")).args(args.iter().copied()).run();
        plain.assert_ok();
        let layered = with_layer(Run::new(&format!("vk-{tag}-layered")).args(args.iter().copied())).run();
        layered.assert_ok();
        assert_same_captures(&format!("vk-{tag}"), &layered, &plain);
        let stats = device_stats(&layered);
        assert!(stats["render_pass"] + stats["render_pass2"] >= 2, "{tag}: {stats:?}");
    }
}

/// A forced internal failure in a hook (`debug.fail_in`) turns the instance to pass-through: the
/// app still runs cleanly with identical frames, and the failure is logged once.
#[test]
fn internal_fault_falls_back_to_pass_through() {
    let args = ["--layout", "multiview", "--rendering", "render-pass"];
    let plain = Run::new("vk-fault-plain").args(args).run();
    plain.assert_ok();
    let faulty = with_layer(Run::new("vk-fault-layered").args(args))
        .env("STEREOSHIM_DEBUG_FAIL_IN", "vkCmdBeginRenderPass")
        .run();
    faulty.assert_ok();
    assert_same_captures("vk-fault", &faulty, &plain);
    let log = faulty.log.clone();
    let failures = log.lines().filter(|l| l.contains("internal failure")).count();
    assert_eq!(failures, 1, "expected exactly one logged fault:\n{log}");
    assert!(log.contains("vkCmdBeginRenderPass") && log.contains("pass-through"), "{log}");
    // Nothing was counted after the fault.
    assert_eq!(device_stats(&faulty)["render_pass"], 0);
}

/// `enabled = false` keeps the layer in the chain but makes it do nothing.
#[test]
fn disabled_layer_is_pure_pass_through() {
    let args = ["--layout", "side-by-side", "--rendering", "dynamic"];
    let plain = Run::new("vk-disabled-plain").args(args).run();
    plain.assert_ok();
    let off = with_layer(Run::new("vk-disabled-layered").args(args)).env("STEREOSHIM_ENABLED", "false").run();
    off.assert_ok();
    assert_same_captures("vk-disabled", &off, &plain);
    assert!(off.log.contains("pass_through=true"), "{}", off.log);
    assert_eq!(device_stats(&off)["dynamic_rendering"], 0);
}
