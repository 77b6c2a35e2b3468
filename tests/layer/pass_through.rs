//! The layer with every feature off: loaded into xr-scene as an OpenXR API layer (which brings in
//! its Vulkan half), it must change nothing the app or the runtime sees, prove that both halves
//! really ran, and survive its own internal failures (runtime errors: tests/hardening/faults_xr.rs).

use crate::common;

use common::{assert_same_captures, Half, Run, RunOutput};

fn assert_layer_ran(out: &RunOutput, vulkan: &str) {
    out.assert_layer_loaded(Half::Both);
    let stats = out.log_lines("openxr stats:");
    assert_eq!(stats.len(), 1, "{}: expected one openxr stats line:\n{}", out.name, out.log);
    assert!(stats[0].contains("frames_ended=2"), "{}: {}", out.name, stats[0]);
    assert!(stats[0].contains("eye_use_changes="), "{}: {}", out.name, stats[0]);
    let injected = match vulkan {
        "enable2" => "created the app's VkInstance with VK_LAYER_STEREOSHIM_stereoshim",
        _ => "added to VK_INSTANCE_LAYERS",
    };
    assert_eq!(out.log_lines(injected).len(), 1, "{}: Vulkan half not requested:\n{}", out.name, out.log);
    let vk = out.log_lines("vulkan device stats:");
    assert_eq!(vk.len(), 1, "{}: the Vulkan half did not report a device:\n{}", out.name, out.log);
    let count = |key: &str| -> u64 {
        let field = vk[0].split_whitespace().find_map(|f| f.strip_prefix(&format!("{key}=")));
        field.and_then(|v| v.parse().ok()).unwrap_or_else(|| panic!("{}: no {key} in {}", out.name, vk[0]))
    };
    let passes = count("render_pass") + count("render_pass2") + count("dynamic_rendering");
    assert!(passes >= 2, "{}: the Vulkan half saw {passes} passes: {}", out.name, vk[0]);
    // Eye passes render into swapchain images (or resolve into them): the Vulkan half must have
    // recognised them through what the OpenXR half published.
    if !out.name.contains("msaa") {
        assert!(count("swapchain_attachments") >= 2, "{}: no swapchain attachment recognised: {}", out.name, vk[0]);
    }
    out.assert_log_lacks(Half::Both, "internal failure");
    assert_eq!(out.log_lines("the Vulkan half tracks this device").len(), 1, "{}: {}", out.name, out.log);
}

/// Captures and shaded-fragment counts with the layer equal those without, for every rendering
/// path and depth convention of one layout and Vulkan binding.
fn pass_through(layout: &str, vulkan: &str) {
    for rendering in ["render-pass", "render-pass2", "dynamic"] {
        for depth in ["standard", "reverse"] {
            let name = format!("layer-{layout}-{vulkan}-{rendering}-{depth}");
            let run = Run::new(&name).args(["--layout", layout, "--vulkan", vulkan, "--rendering", rendering, "--depth", depth]);
            let without = run.clone().run();
            without.assert_ok();
            let mut with = run.with_layer();
            with.name = format!("{name}-with-layer");
            let with = with.run();
            with.assert_ok();
            assert_layer_ran(&with, vulkan);
            assert_same_captures(&name, &with, &without);
            common::assert_same_stats(&name, &with, &without);
        }
    }
}

macro_rules! pass_through_tests {
    ($($name:ident: $layout:literal, $vulkan:literal;)*) => {$(
        #[test]
        fn $name() {
            pass_through($layout, $vulkan);
        }
    )*};
}

pass_through_tests! {
    pass_through_per_eye_enable2: "per-eye", "enable2";
    pass_through_per_eye_enable: "per-eye", "enable";
    pass_through_multiview_enable2: "multiview", "enable2";
    pass_through_multiview_enable: "multiview", "enable";
    pass_through_side_by_side_enable2: "side-by-side", "enable2";
    pass_through_side_by_side_enable: "side-by-side", "enable";
}

/// Intermediate targets and submitted depth go through unchanged as well.
#[test]
fn pass_through_intermediate_and_depth() {
    for (tag, extra) in [("msaa", vec!["--intermediate"]), ("depth", vec!["--submit-depth", "--layout", "multiview"])] {
        let run = Run::new(&format!("layer-{tag}")).args(extra);
        let without = run.clone().run();
        without.assert_ok();
        let mut with = run.with_layer();
        with.name = format!("layer-{tag}-with-layer");
        let with = with.run();
        with.assert_ok();
        assert_layer_ran(&with, "enable2");
        assert_same_captures(&format!("layer-{tag}"), &with, &without);
    }
}

/// An internal failure of the layer's own logic costs only the layer: one log line, that instance
/// goes to pass-through, and the app's frames are untouched.
#[test]
fn internal_failure_switches_to_pass_through() {
    let reference = Run::new("internal-failure-reference").run();
    reference.assert_ok();
    for call in ["xrEndFrame", "xrEnumerateSwapchainImages", "xrCreateSession"] {
        let out = Run::new(&format!("internal-failure-{call}")).with_layer().env("STEREOSHIM_DEBUG_FAIL_IN", call).run();
        out.assert_ok();
        let failures = out.log_lines("internal failure");
        assert_eq!(failures.len(), 1, "{call}: expected exactly one failure line:\n{}", out.log);
        assert!(failures[0].contains(call), "{call}: {}", failures[0]);
        assert_same_captures(&format!("internal-failure-{call}"), &out, &reference);
    }
}

/// The master switch makes the layer pure pass-through: nothing intercepted, no Vulkan half.
#[test]
fn master_switch_off() {
    let reference = Run::new("switch-off-reference").run();
    reference.assert_ok();
    for (tag, run) in [
        ("env", Run::new("switch-off-env").with_layer().env("STEREOSHIM_ENABLED", "0")),
        ("file", Run::new("switch-off-file").with_layer().config("enabled = false\n")),
        ("app", Run::new("switch-off-app").with_layer().config("[app.\"xr-scene\"]\nenabled = false\n")),
    ] {
        let out = run.run();
        out.assert_ok();
        assert_eq!(out.log_lines("pure pass-through").len(), 1, "{tag}: not disabled:\n{}", out.log);
        // The OpenXR half loaded (and said it is disabled); neither its hooks nor the Vulkan half ran.
        out.assert_log_lacks(Half::OpenXr, "openxr stats:");
        out.assert_log_lacks(Half::OpenXr, "vulkan device stats:");
        assert!(common::layer_loaded(&out.log, Half::Vulkan).is_err(), "{tag}: the Vulkan half loaded:\n{}", out.log);
        assert_same_captures(&format!("switch-off-{tag}"), &out, &reference);
    }
}

/// A malformed config file is reported with file and line, and the layer runs on defaults.
#[test]
fn malformed_config_is_reported() {
    let out = Run::new("malformed-config").with_layer().config("enabled = true\nlog.level = \"verbose\"\n[mask\n").run();
    out.assert_ok();
    let problems = out.log_lines("config:");
    assert_eq!(problems.len(), 1, "{}", out.log);
    assert!(problems[0].contains("config.toml: line 3"), "{}", problems[0]);
    assert_layer_ran(&out, "enable2");

    let out = Run::new("bad-config-value").with_layer().config("log.level = \"verbose\"\nunknown = 1\n").run();
    out.assert_ok();
    let problems = out.log_lines("config:");
    assert_eq!(problems.len(), 2, "{}", out.log);
    assert!(problems[0].contains("config.toml:1: `log.level`"), "{}", problems[0]);
    assert!(problems[1].contains("config.toml:2: unknown key `unknown`"), "{}", problems[1]);
}
