//! End-to-end checks of foveation method 2, radial density masking: xr-scene runs through the layer
//! with `foveation.enabled`, `foveation.method = rdm`, and frame 1 (frame 0 renders before the
//! OpenXR half saw an eye use) is compared with a run without the layer:
//! - pixels of quads the rule keeps are bit-identical, and so — computed independently here, in
//!   f64 from frames.json's FOV and the preset's angle — is every pixel well inside the inner ring;
//! - the skipped quads are reconstructed: every skipped pixel is the weighted mean of the shaded
//!   pixels around its quad, recomputed here from the capture (no holes; `holes_are_caught` shows
//!   the check fails without reconstruction), by the compute pass over periphery tiles unless the
//!   fill is configured (`fill_per_eye`); periphery PSNR is reported (and ≥ 30 dB for `balanced`);
//! - shaded fragments drop by exactly the fragments the skipped pixels had in the plain run: both
//!   runs write xr-scene's `--pixel-stats`, and per view
//!   shaded_rdm == shaded_plain − Σ_{p skipped by the rule} plain_counts[p] holds exactly (RDM's
//!   depth makes every fragment of a skipped pixel fail early-Z; kept pixels keep all of theirs).
//!   The older bounds stay as a cross-check of the per-view totals alone: every skipped pixel had
//!   at least one fragment (the scene covers every pixel) and at most one plus its share of the
//!   plain run's overdraw (plain fragments − pixels): skipped ≤ drop ≤ skipped + overdraw. The
//!   skipped count itself is exact: the layer's `stats.file` reports the rule's count per view,
//!   and every pixel the rule keeps is bit-identical to the plain run;
//! - validation (with synchronization validation) stays silent.

use crate::common;

use common::rdm::{self, Expected};
use common::{Half, Run};

/// Runs one configuration with and without the layer and checks frame 1; returns per-view numbers.
pub fn check(name: &str, args: &[&str], preset_name: &str, extra_env: &[(&str, &str)]) -> Vec<rdm::ViewResult> {
    check_with(name, args, preset_name, extra_env, false)
}

/// `with_mask`: both runs go through the layer with the hidden-area mask on (the baseline is the
/// mask alone), so RDM is judged on top of it.
pub fn check_with(name: &str, args: &[&str], preset_name: &str, extra_env: &[(&str, &str)], with_mask: bool) -> Vec<rdm::ViewResult> {
    // Run folders of this module's own: tests/features/mask.rs runs configurations under the same
    // names, at the same time (the tests of one binary are threads of one process).
    let name = &format!("foveation-{name}");
    // With `MOCK_XR_GAZE=yaw,pitch` among the env, the fovea follows that gaze (eye tracking on);
    // otherwise there is no eye tracker and the fovea sits on the optical axis.
    let gaze: Option<(f64, f64)> = extra_env.iter().find(|(k, _)| *k == "MOCK_XR_GAZE").map(|(_, v)| {
        let (y, p) = v.split_once(',').expect("yaw,pitch");
        (y.trim().parse().unwrap(), p.trim().parse().unwrap())
    });
    let mut base = Run::new(name).args(args.iter().copied()).pixel_stats();
    super::mask::no_validation_for_libraries(&mut base, args);
    if gaze.is_none() {
        base = base.env("MOCK_XR_EYE_TRACKER", "0");
    }
    for (k, v) in extra_env {
        base = base.env(k, v);
    }
    if with_mask {
        base = base.with_layer().env("STEREOSHIM_MASK_ENABLED", "1");
    }
    let plain = base.clone().run();
    plain.assert_ok();
    let mut layered = base
        .with_layer()
        .env("STEREOSHIM_FOVEATION_ENABLED", "1")
        .env("STEREOSHIM_FOVEATION_METHOD", "rdm")
        .env("STEREOSHIM_FOVEATION_PRESET", preset_name)
        .env("STEREOSHIM_FOVEATION_EYE_TRACKING", if gaze.is_some() { "auto" } else { "off" });
    for (k, v) in extra_env.iter().filter(|(k, _)| k.starts_with("STEREOSHIM_FOVEATION_")) {
        layered = layered.env(k, v);
    }
    layered.name = format!("{name}-rdm");
    let stats_path = common::target_dir().join("test-output").join(format!("{name}-rdm.layer-stats.jsonl"));
    let _ = std::fs::remove_file(&stats_path);
    layered = layered.env("STEREOSHIM_STATS_FILE", stats_path.to_str().unwrap());
    let rdm = layered.run();
    rdm.assert_ok();
    // Kept beside the run's captures (the layer's own log goes with its state folder).
    let _ = std::fs::write(common::target_dir().join("test-output").join(format!("{name}-rdm")).join("layer.log"), &rdm.log);
    rdm.assert_log_lacks(Half::Both, "internal failure");
    assert!(!rdm.log_lines("radial density masking ").is_empty(), "{name}: the layer never applied RDM:\n{}", rdm.log);
    // Frame 0: eye uses unknown, nothing skipped.
    common::assert_same_frame(&format!("{name}-f0"), &rdm, 0, &plain, 0);
    let (mut inner_deg, mut middle_deg) = rdm::preset(preset_name);
    // Explicit angles override the preset (as the layer's config does).
    for (k, v) in extra_env {
        match *k {
            "STEREOSHIM_FOVEATION_INNER_DEG" => inner_deg = v.parse().unwrap(),
            "STEREOSHIM_FOVEATION_MIDDLE_DEG" => middle_deg = v.parse().unwrap(),
            _ => {}
        }
    }
    let stats1 = rdm::layer_stats(&rdm, &stats_path, 1);
    // The gaze direction of the mock runtime as a tangent-plane point of these parallel views.
    let center = gaze.map_or([0.0, 0.0], |(yaw, pitch)| rdm::gaze_center(yaw, pitch));
    let expected = Expected { center, inner_deg, middle_deg, with_mask };
    let out = rdm::check_frame(name, &plain, &rdm, 1, &expected).unwrap_or_else(|e| panic!("{e}"));
    rdm::check_layer_record(name, &stats1, &out).unwrap_or_else(|e| panic!("{e}"));
    // The compute pass did every reconstruction (xr-scene's swapchains are 8-bit sRGB and get
    // TRANSFER_DST), unless the fill was asked for.
    let fill = extra_env.iter().any(|(k, v)| *k == "STEREOSHIM_FOVEATION_RDM_RECONSTRUCTION" && *v == "fill");
    let reconstructed: u64 = stats1["rdm"]["reconstructed"].as_object().map_or(0, |m| m.values().filter_map(|v| v.as_u64()).sum());
    let (compute, fallback) = (stats1["rdm"]["compute"].as_u64().unwrap_or(0), &stats1["rdm"]["fill_fallback"]);
    if fill {
        assert!(compute == 0 && fallback["configured"].as_u64() == Some(reconstructed), "{name}: the fill was configured: {stats1}");
    } else {
        assert!(compute == reconstructed && compute > 0, "{name}: not every reconstruction was the compute pass: {stats1}");
    }
    rdm::check_results(name, preset_name == "balanced", with_mask, &out).unwrap_or_else(|e| panic!("{e}"));
    // No app call waited on the GPU: every release found a free reconstruction slot
    // (`rules::slot_choice`; issue 11, "no blocking in the app's calls").
    let summaries = rdm.log_lines("release_waits=");
    assert!(!summaries.is_empty(), "{name}: no RDM summary in the device stats line:\n{}", rdm.log);
    assert!(summaries.iter().all(|l| l.contains("release_waits=0")), "{name}: a release waited for the GPU: {summaries:?}");
    out
}

macro_rules! rdm_tests {
    ($($name:ident: [$($arg:literal),*];)*) => {$(
        #[test]
        fn $name() {
            check(stringify!($name), &[$($arg),*], "balanced", &[]);
        }
    )*};
}

rdm_tests! {
    per_eye_render_pass: ["--layout", "per-eye", "--rendering", "render-pass"];
    per_eye_dynamic_reverse: ["--layout", "per-eye", "--rendering", "dynamic", "--depth", "reverse"];
    multiview_render_pass2: ["--layout", "multiview", "--rendering", "render-pass2"];
    multiview_dynamic: ["--layout", "multiview", "--rendering", "dynamic"];
    side_by_side_render_pass: ["--layout", "side-by-side", "--rendering", "render-pass"];
    side_by_side_dynamic_reverse: ["--layout", "side-by-side", "--rendering", "dynamic", "--depth", "reverse"];
    intermediate_per_eye_msaa: ["--layout", "per-eye", "--rendering", "render-pass", "--intermediate"];
    intermediate_multiview_copy: ["--layout", "multiview", "--rendering", "dynamic", "--intermediate", "--samples", "1"];
}

// State set as DXVK sets it (see tests/features/mask.rs): RDM's checkerboard and its
// reconstruction leave the app's dynamic state and linked pipelines as they were.
rdm_tests! {
    dxvk_dynamic_state_library_per_eye: ["--layout", "per-eye", "--rendering", "dynamic", "--dynamic-state", "--pipeline-library", "--bind-before-pass"];
    dxvk_dynamic_state_side_by_side: ["--layout", "side-by-side", "--rendering", "render-pass", "--dynamic-state"];
    shader_objects_multiview: ["--layout", "multiview", "--rendering", "dynamic", "--shader-object", "--bind-before-pass"];
}

// The OpenVR submission path (see tests/features/mask.rs): RDM's reconstruction reaches the
// swapchain through the compositor's own copy.
rdm_tests! {
    openvr_intermediate_msaa_per_eye: ["--layout", "per-eye", "--rendering", "dynamic", "--intermediate", "--submit-via", "openvr"];
    openvr_double_wide: ["--layout", "side-by-side", "--rendering", "render-pass", "--submit-texture", "double-wide", "--submit-via", "openvr"];
    // xrizer's order: a temporary session on a device of its own first, then the legacy
    // XR_KHR_vulkan_enable on the app's.
    openvr_temporary_session_legacy_enable: ["--layout", "per-eye", "--rendering", "dynamic", "--intermediate", "--samples", "1", "--submit-via", "openvr", "--vulkan", "enable", "--temporary-session"];
}

/// An app's own target copied 1:1 into the swapchain (an OpenVR game's eye texture, which its
/// desktop mirror draws too): RDM fills its skipped quads when the eye pass ends, in that target,
/// so every reader of it sees it whole; a multisampled target resolved by the copy cannot be
/// filled there, and its skipped quads follow the copy and are filled at the release. Both give
/// the runtime the same reconstruction (`check`).
#[test]
fn a_copied_target_is_reconstructed_before_its_copy() {
    check("copied-target-single", &["--layout", "per-eye", "--rendering", "dynamic", "--intermediate", "--samples", "1", "--submit-via", "openvr"], "balanced", &[]);
    let log = |name: &str| std::fs::read_to_string(common::target_dir().join("test-output").join(format!("foveation-{name}-rdm")).join("layer.log")).unwrap_or_default();
    let at_release = "are reconstructed in the swapchain image at the release";
    let l = log("copied-target-single");
    assert!(!l.is_empty() && !l.contains(at_release), "a single-sampled copied target is filled at its pass's end:\n{l}");
    check("copied-target-msaa", &["--layout", "per-eye", "--rendering", "dynamic", "--intermediate", "--samples", "4", "--submit-via", "openvr"], "balanced", &[]);
    let l = log("copied-target-msaa");
    assert!(l.contains(at_release), "a multisampled target resolved by the copy is filled at the release:\n{l}");
}

/// xrizer with a multisampled game texture (the OpenVR SDK's `hellovr_vulkan` at its default 4×
/// MSAA): its swapchain has the texture's sample count and its compositor resolves into it, which
/// Vulkan forbids (VUID-vkCmdResolveImage-dstImage-00259: validation is off in both runs; lavapipe
/// runs it). A skipped pixel of the texture is then not a pixel of what the runtime gets, so the
/// layer must not leave RDM's holes there: the eye passes are tied to their eyes by the data-flow
/// walk, not by the resolve, and left unfoveated with the reason counted, every frame; what the
/// runtime gets is the run without the layer's, bit for bit. The mask still applies. (Before, the
/// resolve counted as a 1:1 transfer and the skipped quads were reconstructed in the 4-sample
/// swapchain image, which lavapipe reads one sample of: a grid of quads at a quarter of their
/// brightness, found with the real xrizer and hellovr_vulkan.)
#[test]
fn openvr_resolve_into_a_multisampled_swapchain_leaves_no_holes() {
    let args = ["--layout", "per-eye", "--rendering", "dynamic", "--intermediate", "--samples", "4", "--swapchain-samples", "4", "--submit-via", "openvr"];
    let frames = 4u64;
    let mut plain = Run::new("rdm-openvr-msaa-swapchain").args(args).env("MOCK_XR_EXIT_AFTER", &frames.to_string());
    plain.validation = false;
    let plain = plain.run();
    plain.assert_ok();
    let stats = common::target_dir().join("test-output").join("rdm-openvr-msaa-swapchain.layer-stats.jsonl");
    let _ = std::fs::remove_file(&stats);
    let mut layered = Run::new("rdm-openvr-msaa-swapchain")
        .args(args)
        .env("MOCK_XR_EXIT_AFTER", &frames.to_string())
        .with_layer()
        .env("STEREOSHIM_FOVEATION_ENABLED", "1")
        .env("STEREOSHIM_FOVEATION_METHOD", "rdm")
        .env("STEREOSHIM_FOVEATION_EYE_TRACKING", "off")
        .env("STEREOSHIM_STATS_FILE", stats.to_str().unwrap());
    layered.name = "rdm-openvr-msaa-swapchain-rdm".into();
    layered.validation = false;
    let rdm_run = layered.run();
    rdm_run.assert_ok();
    rdm_run.assert_log_lacks(Half::Both, "internal failure");
    common::assert_same_captures("rdm-openvr-msaa-swapchain", &rdm_run, &plain);
    let records = rdm::layer_records(&rdm_run, &stats);
    for f in 1..frames {
        let r = records.iter().find(|r| r["frame"] == f).unwrap_or_else(|| panic!("no stats of frame {f}"));
        assert_eq!(r["rdm"]["passes"].as_u64().unwrap_or(0), 0, "frame {f}: {r}");
        let why: u64 = r["rdm"]["not_applied"].as_object().map_or(0, |m| m.values().filter_map(|v| v.as_u64()).sum());
        assert!(why >= 2, "frame {f}: both eye passes left alone with their reason: {r}");
    }
    // The same run with the mask: both eye passes masked through the walk from frame 2 on. The
    // walk sees where the eye goes only in the compositor's submission, after the app's: frame 0's
    // precedes the first xrEndFrame (no eye uses yet), frame 1's comes after frame 1's eye passes
    // were submitted.
    let mut masked = Run::new("rdm-openvr-msaa-swapchain-mask").args(args).env("MOCK_XR_EXIT_AFTER", &frames.to_string()).with_layer().env("STEREOSHIM_MASK_ENABLED", "1");
    masked.validation = false;
    let masked = masked.run();
    masked.assert_ok();
    let line = masked.log_lines("vulkan device stats:").join("\n");
    assert!(line.contains(&format!("masked_passes={}", 2 * (frames - 2))) && line.contains("masked_by.walk="), "{line}");
}

// Eye passes recorded into secondary command buffers (as engines do): the checkerboard goes into
// the layer's own secondary, executed ahead of the app's. Vulkan 1.0 apps get RDM too.
rdm_tests! {
    secondary_per_eye_render_pass: ["--layout", "per-eye", "--rendering", "render-pass", "--secondary"];
    secondary_multiview_dynamic: ["--layout", "multiview", "--rendering", "dynamic", "--secondary"];
    secondary_side_by_side_render_pass2_reverse: ["--layout", "side-by-side", "--rendering", "render-pass2", "--depth", "reverse", "--secondary"];
    vulkan_1_0_per_eye_render_pass: ["--layout", "per-eye", "--rendering", "render-pass", "--vulkan-api", "1.0"];
    vulkan_1_0_side_by_side_secondary: ["--layout", "side-by-side", "--rendering", "render-pass2", "--vulkan-api", "1.0", "--secondary"];
}

/// Every preset on two layouts: the skipped fraction and periphery PSNR per preset (reported), PSNR
/// ≥ 30 dB asserted for `balanced` only.
#[test]
fn presets() {
    for preset in ["subtle", "balanced", "aggressive"] {
        check(&format!("preset_{preset}_per_eye"), &["--layout", "per-eye", "--rendering", "dynamic"], preset, &[]);
        check(&format!("preset_{preset}_side_by_side"), &["--layout", "side-by-side", "--rendering", "render-pass2"], preset, &[]);
    }
}

/// Explicit angles override the preset (foveation.inner_deg / middle_deg).
#[test]
fn explicit_ring_angles() {
    // The preset says subtle (30°/45°); the angles win.
    let env = [("STEREOSHIM_FOVEATION_INNER_DEG", "15"), ("STEREOSHIM_FOVEATION_MIDDLE_DEG", "28")];
    check("explicit_angles_per_eye", &["--layout", "per-eye", "--rendering", "render-pass"], "subtle", &env);
}

/// Depth cleared by vkCmdClearAttachments inside the pass / vkCmdClearDepthStencilImage before it.
#[test]
fn explicit_depth_clears() {
    check("depth_clear_attachments_multiview", &["--layout", "multiview", "--rendering", "render-pass", "--depth-clear", "attachments"], "balanced", &[]);
    check("depth_clear_image_side_by_side", &["--layout", "side-by-side", "--rendering", "dynamic", "--depth-clear", "image", "--depth", "reverse"], "balanced", &[]);
}

/// Real HMD profiles: other FOVs (asymmetric) and image sizes.
#[test]
fn hmd_profiles() {
    check("hmd_index_multiview", &["--layout", "multiview", "--rendering", "dynamic"], "balanced", &[("MOCK_XR_HMD", "index")]);
    check("hmd_quest3_per_eye", &["--layout", "per-eye", "--rendering", "render-pass"], "balanced", &[("MOCK_XR_HMD", "quest3")]);
}

/// RDM on top of the hidden-area mask: judged against the mask alone.
#[test]
fn with_hidden_area_mask() {
    check_with("mask_and_rdm_per_eye", &["--layout", "per-eye", "--rendering", "dynamic"], "balanced", &[], true);
    check_with("mask_and_rdm_multiview", &["--layout", "multiview", "--rendering", "render-pass"], "balanced", &[], true);
}

/// Off by default: with the layer but without `foveation.enabled`, frames equal the plain run's.
/// With an eye tracker the full-rate region follows the gaze: the fovea around the gaze point is
/// bit-identical, and the skipped quads are exactly the rule's for the gaze-centred rings (so the
/// optical axis, 15° away, now lies in the half-rate ring).
#[test]
fn follows_the_gaze() {
    for (layout, gaze) in [("per-eye", "15,-5"), ("multiview", "-12,8")] {
        check(&format!("gaze-{layout}"), &["--layout", layout, "--rendering", "dynamic"], "balanced", &[("MOCK_XR_GAZE", gaze)]);
    }
}

/// The fill (the full-screen fragment reconstruction, the compute pass's fallback) meets the same
/// checks, holes included.
#[test]
fn fill_per_eye() {
    check("fill_per_eye", &["--layout", "per-eye", "--rendering", "render-pass"], "balanced", &[("STEREOSHIM_FOVEATION_RDM_RECONSTRUCTION", "fill")]);
}

/// The hole check can fail: with the reconstruction off, skipped quads keep the clear colour and
/// are reported as holes (everything else still holds: kept quads bit-identical).
#[test]
fn holes_are_caught() {
    let name = "holes_are_caught";
    let args = ["--layout", "side-by-side", "--rendering", "dynamic"];
    let base = Run::new(name).args(args).pixel_stats().env("MOCK_XR_EYE_TRACKER", "0");
    let plain = base.clone().run();
    plain.assert_ok();
    let mut layered = base
        .with_layer()
        .env("STEREOSHIM_FOVEATION_ENABLED", "1")
        .env("STEREOSHIM_FOVEATION_METHOD", "rdm")
        .env("STEREOSHIM_FOVEATION_EYE_TRACKING", "off")
        .env("STEREOSHIM_FOVEATION_RDM_RECONSTRUCTION", "off");
    layered.name = format!("{name}-rdm");
    let out = layered.run();
    out.assert_ok();
    let (inner_deg, middle_deg) = rdm::preset("balanced");
    let expected = Expected { center: [0.0, 0.0], inner_deg, middle_deg, with_mask: false };
    let results = rdm::check_frame(name, &plain, &out, 1, &expected).unwrap_or_else(|e| panic!("{e}"));
    for r in &results {
        assert!(r.holes > r.skipped / 4, "{name} view {}: only {} of {} skipped pixels reported as holes", r.view, r.holes, r.skipped);
    }
    let err = rdm::check_results(name, true, false, &results).expect_err("holes must fail the check");
    assert!(err.contains("holes"), "{err}");
}

#[test]
fn off_by_default() {
    let args = ["--layout", "per-eye", "--rendering", "dynamic"];
    let plain = Run::new("rdm-off").args(args).run();
    plain.assert_ok();
    let mut run = Run::new("rdm-off").args(args).with_layer().env("STEREOSHIM_FOVEATION_METHOD", "rdm");
    run.name = "rdm-off-layered".into();
    let out = run.run();
    out.assert_ok();
    common::assert_same_captures("rdm-off", &out, &plain);
    common::assert_same_stats("rdm-off", &out, &plain);
    out.assert_log_lacks(Half::Vulkan, "radial density masking");
}
