//! No lock of the layer is held while it calls down (issue 11): whatever sits below may call back
//! up into the app-facing chain from inside the call — an OpenXR runtime calls Vulkan on the
//! app's device (through stereoshim's Vulkan half) from inside `xrEndFrame` and the swapchain
//! calls, and a Vulkan layer below may call functions it got from the top of the chain.
//!
//! xr-scene runs with every feature on, validation on, and both kinds of callers below the layer:
//! - the fault layer of the test tree (tests/vk-fault-layer, below stereoshim) with
//!   `VK_FAULT_REENTER` naming every call it can re-enter from: inside each, before passing it
//!   down, it makes, records, submits (from submissions only) and destroys objects through the
//!   loader's top of the chain, so through stereoshim's hooks, which then run nested inside
//!   stereoshim's own hook of the outer call (or inside stereoshim's own call down, for the
//!   calls stereoshim makes for its objects);
//! - the mock runtime with `MOCK_XR_REENTER=1`: from inside `xrBeginFrame`, `xrEndFrame`,
//!   `xrAcquireSwapchainImage` and `xrReleaseSwapchainImage` it submits an empty command buffer on
//!   the app's queue and waits for it, from `xrWaitSwapchainImage` and `xrLocateViews` it makes and
//!   destroys an image and a command buffer — nested inside stereoshim's OpenXR hooks.
//!
//! A lock held across a call down that the nested call also takes deadlocks (the run's time limit
//! turns that into a failure), a `RefCell` borrowed across it panics (an internal failure in the
//! layer's log), state recorded inconsistently shows as validation errors (xr-scene exits 3) or
//! features no longer applying. Each run also proves the re-entries happened: both callers count
//! them per call, and every call named for the run must have re-entered at least once.

use crate::common;

use common::{fault_layer_data_dir, Half, Run, RunOutput, FAULT_LAYER};
use std::time::Duration;

/// Every call the fault layer can re-enter from: the creation calls it can also fail, the
/// recording, submission and destruction calls it hooks for re-entry only.
const REENTER_FROM: &[&str] = &[
    "vkCreateImage",
    "vkAllocateMemory",
    "vkCreateImageView",
    "vkCreateBuffer",
    "vkCreateShaderModule",
    "vkCreatePipelineLayout",
    "vkCreateDescriptorSetLayout",
    "vkCreateGraphicsPipelines",
    "vkCreateComputePipelines",
    "vkCreateRenderPass",
    "vkCreateRenderPass2",
    "vkCreateFramebuffer",
    "vkCreateSampler",
    "vkCreateDescriptorPool",
    "vkAllocateDescriptorSets",
    "vkCreateQueryPool",
    "vkCreateCommandPool",
    "vkAllocateCommandBuffers",
    "vkCreateFence",
    "vkQueueSubmit",
    "vkQueueSubmit2",
    "vkBeginCommandBuffer",
    "vkEndCommandBuffer",
    "vkCmdBeginRenderPass",
    "vkCmdBeginRenderPass2",
    "vkCmdBeginRendering",
    "vkCmdExecuteCommands",
    "vkCmdDraw",
    "vkCmdDrawIndexed",
    "vkDestroyImage",
];

/// The mock runtime's calls that re-enter Vulkan.
const MOCK_REENTERS: &[&str] = &["xrBeginFrame", "xrEndFrame", "xrAcquireSwapchainImage", "xrWaitSwapchainImage", "xrReleaseSwapchainImage", "xrLocateViews"];

/// Frames per run: frame 0's eyes are unknown to the layer until its `xrEndFrame`; the far field
/// of a multiview app reuses the previous frame's source. The last frame has every feature.
const FRAMES: u64 = 4;

/// One run's layout and what it must show.
struct Case {
    name: &'static str,
    args: &'static [&'static str],
    /// The calls (of `REENTER_FROM`) this layout makes and that must have re-entered.
    reentered: &'static [&'static str],
    /// Whether the far field applies (not to eye passes recorded in secondaries).
    far_field: bool,
}

/// Calls every layout makes (the app, the runtime or the layer for its objects;
/// `vkCreateComputePipelines` only the layer, for RDM's reconstruction).
const COMMON: &[&str] = &[
    "vkCreateImage",
    "vkAllocateMemory",
    "vkCreateImageView",
    "vkCreateBuffer",
    "vkCreateShaderModule",
    "vkCreatePipelineLayout",
    "vkCreateDescriptorSetLayout",
    "vkCreateGraphicsPipelines",
    "vkCreateComputePipelines",
    "vkCreateDescriptorPool",
    "vkAllocateDescriptorSets",
    "vkCreateCommandPool",
    "vkAllocateCommandBuffers",
    "vkCreateFence",
    "vkQueueSubmit",
    "vkBeginCommandBuffer",
    "vkEndCommandBuffer",
    "vkCmdDrawIndexed",
    "vkDestroyImage",
];

fn run(case: &Case) -> RunOutput {
    let data = fault_layer_data_dir();
    let stats = common::target_dir().join("test-output").join(format!("{}.layer-stats.jsonl", case.name));
    let _ = std::fs::remove_file(&stats);
    Run::new(case.name)
        .args(["--vk-layer", FAULT_LAYER, "--submit-depth"])
        .args(case.args.iter().copied())
        .env("MOCK_XR_EXIT_AFTER", &FRAMES.to_string())
        .env("MOCK_XR_REENTER", "1")
        .env("VK_FAULT", "")
        .env("VK_FAULT_REENTER", &REENTER_FROM.join(","))
        .env("XDG_DATA_DIRS", &format!("{}:/usr/local/share:/usr/share", data.display()))
        .env("STEREOSHIM_STATS_FILE", stats.to_str().unwrap())
        .with_layer()
        .config("[mask]\nenabled = true\n[foveation]\nenabled = true\nmethod = \"rdm\"\n[far_field]\nenabled = true\n")
        // A deadlock is a hang: the limit turns it into a failure (a run takes about a second).
        .run_while(Duration::from_secs(60), |_| {})
}

/// `prefix CALL: N times` lines of stderr, summed per call (one line per device or session).
fn counts(stderr: &str, prefix: &str) -> std::collections::BTreeMap<String, u64> {
    let mut all = std::collections::BTreeMap::new();
    for l in stderr.lines() {
        let Some(rest) = l.strip_prefix(prefix) else { continue };
        let Some((call, n)) = rest.split_once(": ") else { continue };
        let n: u64 = n.trim_end_matches(" times").parse().unwrap_or_else(|_| panic!("unreadable count line {l:?}"));
        *all.entry(call.to_string()).or_insert(0) += n;
    }
    all
}

fn check(case: &Case) {
    let out = run(case);
    let name = case.name;
    out.assert_ok().assert_layer_loaded(Half::Both).assert_log_lacks(Half::Both, "internal failure").assert_log_lacks(Half::Both, "panicked");
    let problems: Vec<&str> = out
        .stderr
        .lines()
        .filter(|l| (l.starts_with("vk-fault-layer: ") && !l.contains("re-entered the top of the chain from")) || l.contains("panic"))
        .collect();
    assert!(problems.is_empty(), "{name}: {problems:#?}");
    // The re-entries happened, from every call this layout makes.
    let fault = counts(&out.stderr, "vk-fault-layer: re-entered the top of the chain from ");
    let missing: Vec<&str> = case.reentered.iter().copied().filter(|c| fault.get(*c).copied().unwrap_or(0) == 0).collect();
    assert!(missing.is_empty(), "{name}: no re-entry from {missing:?}; re-entries: {fault:?}\nstderr:\n{}", out.stderr);
    let mock = counts(&out.stderr, "[mock-runtime] re-entered Vulkan from ");
    let missing: Vec<&str> = MOCK_REENTERS.iter().copied().filter(|c| mock.get(*c).copied().unwrap_or(0) < FRAMES.min(2)).collect();
    assert!(missing.is_empty(), "{name}: the runtime did not re-enter from {missing:?}; re-entries: {mock:?}\nstderr:\n{}", out.stderr);
    // The features still apply, on the last frame.
    let stats = common::target_dir().join("test-output").join(format!("{name}.layer-stats.jsonl"));
    let lines: Vec<serde_json::Value> = std::fs::read_to_string(&stats).unwrap_or_else(|e| panic!("{name}: {}: {e}", stats.display())).lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    assert_eq!(lines.len() as u64, FRAMES, "{name}: one stats line per frame");
    let last = &lines[FRAMES as usize - 1];
    let sum = |v: &serde_json::Value| v.as_object().map_or(0, |m| m.values().filter_map(|x| x.as_u64()).sum::<u64>());
    assert!(last["passes_masked"].as_u64().unwrap_or(0) >= 1, "{name}: mask not applied: {last}");
    assert!(sum(&last["rdm"]["reconstructed"]) >= 1, "{name}: RDM not applied: {last}");
    if case.far_field {
        assert!(sum(&last["far_field"]["views_reused"]) >= 1, "{name}: far field not applied: {last}");
    }
    eprintln!("{name}: {:.1} s, fault layer re-entries {fault:?}, runtime re-entries {mock:?}", out.elapsed.as_secs_f64());
}

#[test]
fn per_eye_render_pass() {
    // The far field's samplers are only ever the layer's own: a re-entry from inside its call down.
    let reentered: Vec<&str> = COMMON.iter().copied().chain(["vkCreateRenderPass", "vkCreateFramebuffer", "vkCmdBeginRenderPass", "vkCreateSampler"]).collect();
    check(&Case { name: "reentry-per-eye", args: &["--layout", "per-eye"], reentered: reentered.leak(), far_field: true });
}

#[test]
fn multiview_render_pass2_secondaries_submit2() {
    // The app submits with vkQueueSubmit2; the runtime and the layer still use vkQueueSubmit.
    let reentered: Vec<&str> = COMMON.iter().copied().chain(["vkQueueSubmit2", "vkCreateRenderPass2", "vkCreateFramebuffer", "vkCmdBeginRenderPass2", "vkCmdExecuteCommands"]).collect();
    check(&Case {
        name: "reentry-multiview-secondary",
        args: &["--layout", "multiview", "--rendering", "render-pass2", "--secondary", "--submit2"],
        reentered: reentered.leak(),
        far_field: false,
    });
}

#[test]
fn dynamic_rendering_secondaries() {
    let reentered: Vec<&str> = COMMON.iter().copied().chain(["vkCmdBeginRendering", "vkCmdExecuteCommands"]).collect();
    check(&Case { name: "reentry-dynamic-secondary", args: &["--layout", "per-eye", "--rendering", "dynamic", "--secondary"], reentered: reentered.leak(), far_field: false });
}
