//! End-to-end checks of the hidden-area mask's Vulkan side: xr-scene runs through the layer with
//! `mask.enabled`, and every captured frame is compared pixel by pixel with a run without the
//! layer. Outside the runtime's hidden mesh (frames.json `visibility_masks`, rasterized by the
//! harness itself) pixels must be bit-identical; inside they must be the clear colour (black) or,
//! with `mask.debug`, the tint; shaded fragments must drop by at least 98 % of the masked pixels;
//! validation (with synchronization validation) must stay silent.

use crate::common;

use common::image::{self, Image};
use common::{hidden_pixels, mask_edge_pixels, Half, Run, RunOutput};

/// The tint `mask.debug` paints (magenta, shaders/mask.frag), as 8-bit RGB.
const TINT: [u16; 3] = [255, 0, 255];
const BLACK: [u16; 3] = [0, 0, 0];
/// Pixels this close to the mask outline may go either way (vertex snapping, f32 vs f64 mapping).
const EDGE_MARGIN_PX: f64 = 1.0;

struct ViewCheck {
    view: u32,
    hidden: u64,
    shaded_drop: i64,
}

/// Runs one configuration with and without the layer; checks frame 1 (frame 0 renders before the
/// OpenXR half saw an eye use, so it is unmasked and must equal the plain run) and returns per-view
/// numbers.
fn check(name: &str, args: &[&str], debug: bool) -> Vec<ViewCheck> {
    check_env(name, args, debug, &[])
}

fn check_env(name: &str, args: &[&str], debug: bool, env: &[(&str, &str)]) -> Vec<ViewCheck> {
    // Run folders of this module's own: tests/features/foveation.rs runs configurations under the
    // same names, at the same time (the tests of one binary are threads of one process).
    let name = &format!("mask-{name}");
    let mut base = Run::new(name).args(args.iter().copied());
    no_validation_for_libraries(&mut base, args);
    for (k, v) in env {
        base = base.env(k, v);
    }
    let plain = base.clone().run();
    plain.assert_ok();
    let mut layered = base.with_layer().env("STEREOSHIM_MASK_ENABLED", "1");
    if debug {
        layered = layered.env("STEREOSHIM_MASK_DEBUG", "1");
    }
    layered.name = format!("{name}-masked");
    let masked = layered.run();
    masked.assert_ok();
    masked.assert_log_lacks(Half::Both, "internal failure");
    assert!(!masked.log_lines("masking ").is_empty(), "{name}: the layer never masked a pass:\n{}", masked.log);
    // Frame 0: eye uses unknown, nothing masked.
    common::assert_same_frame(&format!("{name}-f0"), &masked, 0, &plain, 0);
    let frame = masked.frame(1);
    assert_eq!(frame.visibility_masks.len(), 2, "{name}: frames.json has no visibility_masks");
    let mut out = Vec::new();
    for (a, b) in common::views_to_compare(name, &masked, 1, &plain, 1) {
        let mask = &frame.visibility_masks.iter().find(|m| m.view == a.view).expect("mask of view").hidden_triangles;
        let (w, h) = (a.image_rect.width, a.image_rect.height);
        let hidden = hidden_pixels(mask, &a.fov, w, h);
        let edge = mask_edge_pixels(mask, &a.fov, w, h, EDGE_MARGIN_PX);
        let (got, want) = (masked.image(&a.file), plain.image(&b.file));
        let inside = if debug { TINT } else { BLACK };
        // Multisampled targets resolve partly covered edge pixels to a blend of both.
        let msaa = args.contains(&"--intermediate") && !args.windows(2).any(|w| w == ["--samples", "1"]);
        let mut bad = Vec::new();
        for y in 0..h {
            for x in 0..w {
                let i = (y * w + x) as usize;
                let g = &got.pixel(x, y)[..3];
                if edge[i] {
                    // Either the app's pixel or the mask's (or, multisampled, a blend).
                    if !msaa && g != want.pixel(x, y) && g != inside {
                        bad.push((x, y, "edge"));
                    }
                } else if hidden[i] {
                    if g != inside {
                        bad.push((x, y, "inside"));
                    }
                } else if g != &want.pixel(x, y)[..3] {
                    bad.push((x, y, "outside"));
                }
            }
        }
        if !bad.is_empty() {
            let dir = image::artifacts_dir(&format!("{name}-view{}", a.view));
            got.save(&dir.join("actual.png"));
            want.save(&dir.join("expected.png"));
            image::difference(&got, &want).save(&dir.join("difference.png"));
            save_coverage(&hidden, w, h, &dir.join("hidden.png"));
            panic!("{name} view {}: {} wrong pixels, first {:?}; artifacts in {}", a.view, bad.len(), &bad[..bad.len().min(8)], dir.display());
        }
        let hidden_count = hidden.iter().filter(|&&b| b).count() as u64;
        assert!(hidden_count > 0, "{name}: empty mask for view {}", a.view);
        let shaded = |o: &RunOutput| {
            let f = o.stats.as_ref().expect("stats").frames.iter().find(|f| f.frame == 1).expect("stats of frame 1");
            f.views.iter().find(|v| v.view == a.view).expect("view stats").shaded_fragments as i64
        };
        out.push(ViewCheck { view: a.view, hidden: hidden_count, shaded_drop: shaded(&plain) - shaded(&masked) });
    }
    for v in &out {
        assert!(
            v.shaded_drop as f64 >= 0.98 * v.hidden as f64,
            "{name} view {}: shaded fragments dropped by {} but {} pixels are masked",
            v.view,
            v.shaded_drop,
            v.hidden
        );
        eprintln!("{name} view {}: masked {} px, shaded fragments -{}", v.view, v.hidden, v.shaded_drop);
    }
    // The layer's own count (rasterizer-exact coverage) agrees with the harness's within edges.
    let line = masked.log_lines("vulkan device stats:");
    assert!(!line.is_empty(), "{name}: no `vulkan device stats:` line:\n{}", masked.log);
    let px: u64 = line
        .iter()
        .flat_map(|l| l.split_whitespace())
        .filter_map(|f| f.strip_prefix("masked_pixels="))
        .filter_map(|v| v.parse::<u64>().ok())
        .sum();
    let expected: u64 = out.iter().map(|v| v.hidden).sum();
    assert!(px.abs_diff(expected) * 100 <= expected, "{name}: layer counted {px} masked pixels in frame 1, harness {expected}");
    // Every pass's depth is cleared (by its load op, vkCmdClearAttachments or an image clear), so
    // none may be counted as not cleared — a pass masked at its vkCmdClearAttachments is counted
    // once, as masked, not also as unmasked at its beginning.
    let stats = line.join("\n");
    assert!(!stats.contains("not_masked.depth_not_cleared"), "{name}: {stats}");
    masked.assert_log_lacks(Half::Vulkan, "pass not masked: depth_not_cleared");
    out
}

/// Debian bookworm's validation layer (1.3.239) reports VUID-VkGraphicsPipelineCreateInfo-
/// renderPass-06053/06054 for a link of graphics pipeline libraries made for dynamic rendering,
/// which defines no state of its own (the rule as trixie's layer, 1.4.309, applies it: clean, with
/// synchronization validation, on xr-scene's `--pipeline-library --rendering dynamic`). Those runs
/// go without it here; their frames are still compared with the run without the layer, pixel for
/// pixel. With render pass objects validation stays on.
/// It does not know `VK_EXT_shader_object` either (`--shader-object`). Both kinds are validated
/// with trixie's layer by tests/realworld/dxvk_state.rs.
pub fn no_validation_for_libraries(run: &mut Run, args: &[&str]) {
    let library_for_dynamic_rendering = args.contains(&"--pipeline-library") && args.windows(2).any(|w| w == ["--rendering", "dynamic"]);
    if library_for_dynamic_rendering || args.contains(&"--shader-object") {
        run.validation = false;
    }
}

fn save_coverage(c: &[bool], w: u32, h: u32, path: &std::path::Path) {
    let data = c.iter().flat_map(|&b| if b { [255u16; 3] } else { [0; 3] }).collect();
    Image { width: w, height: h, channels: 3, bit_depth: 8, data }.save(path);
}

macro_rules! mask_tests {
    ($($name:ident: [$($arg:literal),*];)*) => {$(
        #[test]
        fn $name() {
            check(stringify!($name), &[$($arg),*], false);
        }
    )*};
}

mask_tests! {
    per_eye_render_pass: ["--layout", "per-eye", "--rendering", "render-pass"];
    per_eye_render_pass2_reverse: ["--layout", "per-eye", "--rendering", "render-pass2", "--depth", "reverse"];
    per_eye_dynamic: ["--layout", "per-eye", "--rendering", "dynamic"];
    per_eye_render_pass_reverse: ["--layout", "per-eye", "--rendering", "render-pass", "--depth", "reverse"];
    multiview_render_pass: ["--layout", "multiview", "--rendering", "render-pass"];
    multiview_render_pass2: ["--layout", "multiview", "--rendering", "render-pass2"];
    multiview_dynamic_reverse: ["--layout", "multiview", "--rendering", "dynamic", "--depth", "reverse"];
    side_by_side_render_pass: ["--layout", "side-by-side", "--rendering", "render-pass"];
    side_by_side_render_pass2: ["--layout", "side-by-side", "--rendering", "render-pass2", "--depth", "reverse"];
    side_by_side_dynamic: ["--layout", "side-by-side", "--rendering", "dynamic"];
    intermediate_per_eye_msaa: ["--layout", "per-eye", "--rendering", "render-pass", "--intermediate"];
    intermediate_multiview_copy_reverse: ["--layout", "multiview", "--rendering", "dynamic", "--intermediate", "--samples", "1", "--depth", "reverse"];
    intermediate_side_by_side_msaa: ["--layout", "side-by-side", "--rendering", "render-pass2", "--intermediate"];
    submit_depth_per_eye: ["--layout", "per-eye", "--rendering", "dynamic", "--submit-depth"];
    state_set_before_the_pass_per_eye: ["--layout", "per-eye", "--rendering", "render-pass", "--bind-before-pass"];
    state_set_before_the_pass_multiview: ["--layout", "multiview", "--rendering", "dynamic", "--bind-before-pass"];
    state_set_before_the_pass_side_by_side: ["--layout", "side-by-side", "--rendering", "render-pass2", "--bind-before-pass"];
}

// State set as DXVK sets it (`--dynamic-state`: extended dynamic state 1-3 and vertex input by
// commands; `--pipeline-library`: pipelines linked from graphics pipeline libraries), bound before
// the pass begins: the layer's injected draws replace the bound pipeline, so everything the app
// set must be replayed after them for its own draws to come out bit-identical. The layer once
// vetoed these command buffers (nothing masked: `check` fails on that too).
mask_tests! {
    dxvk_dynamic_state_per_eye_dynamic: ["--layout", "per-eye", "--rendering", "dynamic", "--dynamic-state", "--bind-before-pass"];
    dxvk_dynamic_state_multiview_dynamic: ["--layout", "multiview", "--rendering", "dynamic", "--dynamic-state", "--bind-before-pass", "--translucent"];
    dxvk_dynamic_state_side_by_side_render_pass: ["--layout", "side-by-side", "--rendering", "render-pass", "--dynamic-state"];
    dxvk_pipeline_library_side_by_side_dynamic: ["--layout", "side-by-side", "--rendering", "dynamic", "--pipeline-library", "--bind-before-pass"];
    dxvk_both_per_eye_render_pass2: ["--layout", "per-eye", "--rendering", "render-pass2", "--dynamic-state", "--pipeline-library", "--bind-before-pass", "--translucent"];
    shader_objects_per_eye: ["--layout", "per-eye", "--rendering", "dynamic", "--shader-object", "--bind-before-pass"];
    shader_objects_side_by_side: ["--layout", "side-by-side", "--rendering", "dynamic", "--shader-object", "--translucent"];
}

// The OpenVR submission path (`--submit-via openvr`): the app renders into textures of its own
// and a second component — xrizer or OpenComposite for an OpenVR game — copies, resolves or
// blits them into the swapchain in a command buffer and a vkQueueSubmit of its own, after the
// app's, without fence or semaphore. The eye passes are found through that other submission.
mask_tests! {
    openvr_intermediate_msaa_per_eye: ["--layout", "per-eye", "--rendering", "render-pass", "--intermediate", "--submit-via", "openvr"];
    openvr_intermediate_copy_multiview: ["--layout", "multiview", "--rendering", "dynamic", "--intermediate", "--samples", "1", "--submit-via", "openvr"];
    openvr_double_wide: ["--layout", "side-by-side", "--rendering", "dynamic", "--submit-texture", "double-wide", "--submit-via", "openvr"];
}

// One intermediate target for both eyes (`--one-target`), as engines with post effects render:
// eye 0 into it, copied into eye 0's swapchain image, then eye 1 into the same image, copied into
// eye 1's. An image is not an eye: each pass into it is the eye its copy reaches.
mask_tests! {
    one_target_per_eye_msaa: ["--layout", "per-eye", "--rendering", "render-pass", "--intermediate", "--one-target"];
    one_target_per_eye_copy: ["--layout", "per-eye", "--rendering", "dynamic", "--intermediate", "--samples", "1", "--one-target"];
}

// Per-eye passes into ONE 2-layer swapchain (`--eye-swapchain array`), as many engines and xrizer
// submit: eye v's picture is array layer v of the one image, each layer written through its own
// view (by the pass, its copy or resolve). Layer v of the image is eye v, not the image as a whole.
mask_tests! {
    array_swapchain_per_eye: ["--layout", "per-eye", "--rendering", "render-pass2", "--eye-swapchain", "array"];
    array_swapchain_per_eye_msaa: ["--layout", "per-eye", "--rendering", "render-pass", "--intermediate", "--eye-swapchain", "array"];
    array_swapchain_per_eye_copy: ["--layout", "per-eye", "--rendering", "dynamic", "--intermediate", "--samples", "1", "--eye-swapchain", "array"];
    one_target_array_msaa: ["--layout", "per-eye", "--rendering", "render-pass", "--intermediate", "--one-target", "--eye-swapchain", "array"];
    one_target_array_copy: ["--layout", "per-eye", "--rendering", "dynamic", "--intermediate", "--samples", "1", "--one-target", "--eye-swapchain", "array"];
}

// Depth cleared by the app itself, not by the pass's load op (`--depth-clear`): the mask must go
// in right after vkCmdClearAttachments (the pass's first command; side-by-side clears the whole
// double-wide area in one rect), or at the beginning of a pass that loads an image
// vkCmdClearDepthStencilImage cleared, at the depth that fails against that clear. A covering
// subset: every layout with both conventions and every pass shape per clear method.
mask_tests! {
    clear_attachments_per_eye_render_pass: ["--layout", "per-eye", "--rendering", "render-pass", "--depth-clear", "attachments"];
    clear_attachments_per_eye_dynamic_reverse: ["--layout", "per-eye", "--rendering", "dynamic", "--depth", "reverse", "--depth-clear", "attachments"];
    clear_attachments_multiview_render_pass2: ["--layout", "multiview", "--rendering", "render-pass2", "--depth-clear", "attachments"];
    clear_attachments_multiview_dynamic_reverse: ["--layout", "multiview", "--rendering", "dynamic", "--depth", "reverse", "--depth-clear", "attachments"];
    clear_attachments_side_by_side_render_pass_reverse: ["--layout", "side-by-side", "--rendering", "render-pass", "--depth", "reverse", "--depth-clear", "attachments"];
    clear_attachments_side_by_side_dynamic: ["--layout", "side-by-side", "--rendering", "dynamic", "--depth-clear", "attachments"];
    clear_attachments_state_set_before_the_pass: ["--layout", "per-eye", "--rendering", "render-pass2", "--depth-clear", "attachments", "--bind-before-pass"];
    clear_attachments_intermediate_side_by_side_msaa: ["--layout", "side-by-side", "--rendering", "dynamic", "--intermediate", "--depth-clear", "attachments"];
    clear_image_per_eye_render_pass2: ["--layout", "per-eye", "--rendering", "render-pass2", "--depth-clear", "image"];
    clear_image_per_eye_dynamic_reverse: ["--layout", "per-eye", "--rendering", "dynamic", "--depth", "reverse", "--depth-clear", "image"];
    clear_image_multiview_render_pass_reverse: ["--layout", "multiview", "--rendering", "render-pass", "--depth", "reverse", "--depth-clear", "image"];
    clear_image_multiview_dynamic: ["--layout", "multiview", "--rendering", "dynamic", "--depth-clear", "image"];
    clear_image_side_by_side_render_pass2: ["--layout", "side-by-side", "--rendering", "render-pass2", "--depth-clear", "image"];
    clear_image_side_by_side_dynamic_reverse: ["--layout", "side-by-side", "--rendering", "dynamic", "--depth", "reverse", "--depth-clear", "image"];
    clear_image_submit_depth_side_by_side: ["--layout", "side-by-side", "--rendering", "render-pass", "--submit-depth", "--depth-clear", "image"];
    clear_image_intermediate_multiview_msaa_reverse: ["--layout", "multiview", "--rendering", "render-pass2", "--intermediate", "--depth", "reverse", "--depth-clear", "image"];
}

/// Real HMD profiles: other mask shapes, FOVs and (non-square) image sizes.
#[test]
fn hmd_profiles() {
    for hmd in ["index", "quest3"] {
        check_env(&format!("hmd_{hmd}_per_eye"), &["--layout", "per-eye", "--rendering", "dynamic"], false, &[("MOCK_XR_HMD", hmd)]);
        check_env(&format!("hmd_{hmd}_multiview"), &["--layout", "multiview", "--rendering", "render-pass"], false, &[("MOCK_XR_HMD", hmd)]);
    }
}

#[test]
fn debug_tint_paints_the_masked_area() {
    check("debug_tint_per_eye", &["--layout", "per-eye", "--rendering", "dynamic"], true);
    check("debug_tint_multiview", &["--layout", "multiview", "--rendering", "render-pass"], true);
}

/// `mask.intermediate = off`: a pass into an offscreen target is left alone (bit-identical) and
/// the reason is counted.
#[test]
fn intermediate_off_leaves_offscreen_passes_alone() {
    let args = ["--layout", "per-eye", "--intermediate", "--samples", "1"];
    let plain = Run::new("mask-intermediate-off").args(args).run();
    plain.assert_ok();
    let mut run = Run::new("mask-intermediate-off").args(args).with_layer().env("STEREOSHIM_MASK_ENABLED", "1").env("STEREOSHIM_MASK_INTERMEDIATE", "off");
    run.name = "mask-intermediate-off-layered".into();
    let out = run.run();
    out.assert_ok();
    common::assert_same_captures("mask-intermediate-off", &out, &plain);
    common::assert_same_stats("mask-intermediate-off", &out, &plain);
    out.assert_layer_loaded(Half::Vulkan);
    let line = out.log_lines("vulkan device stats:").join("\n");
    assert!(line.contains("masked_passes=0") && line.contains("not_masked.intermediate_off="), "{line}");
}

// Vulkan validation enabled the way most developers do, through `VK_INSTANCE_LAYERS` (every other
// test enables it through the app's create info). With `enable2` the loader puts it above the
// layers the app's create info names, stereoshim included, and it wraps every non-dispatchable
// handle: the swapchain images the runtime reports are then the validation layer's wrapped
// handles, and the layer must still recognise its eye passes (it identifies the images at their
// creation) and mask exactly as without it. With `enable`, stereoshim puts itself first in
// `VK_INSTANCE_LAYERS`, above the user's layers.
macro_rules! wrapped_tests {
    ($($name:ident: [$($arg:literal),*];)*) => {$(
        #[test]
        fn $name() {
            check_env(stringify!($name), &[$($arg),*], false, &[("VK_INSTANCE_LAYERS", "VK_LAYER_KHRONOS_validation")]);
        }
    )*};
}

wrapped_tests! {
    validation_env_per_eye_enable2: ["--layout", "per-eye", "--rendering", "render-pass"];
    validation_env_side_by_side_enable2: ["--layout", "side-by-side", "--rendering", "dynamic"];
    validation_env_multiview_enable2: ["--layout", "multiview", "--rendering", "render-pass2"];
    validation_env_per_eye_enable: ["--layout", "per-eye", "--rendering", "dynamic", "--vulkan", "enable"];
    validation_env_side_by_side_enable: ["--layout", "side-by-side", "--rendering", "render-pass2", "--vulkan", "enable"];
    validation_env_multiview_enable: ["--layout", "multiview", "--rendering", "render-pass", "--vulkan", "enable"];
}

// Eye passes recorded into secondary command buffers (`--secondary`: the app's passes have
// secondary contents, its clears and draws are in its secondaries): the mask goes into the layer's
// own secondary, executed ahead of the app's. And Vulkan 1.0 apps (no multiview, no dynamic
// rendering, no 1.1 structs): everything the layer creates must be valid for that device.
mask_tests! {
    secondary_per_eye_render_pass: ["--layout", "per-eye", "--rendering", "render-pass", "--secondary"];
    secondary_per_eye_dynamic_reverse: ["--layout", "per-eye", "--rendering", "dynamic", "--depth", "reverse", "--secondary"];
    secondary_multiview_render_pass2: ["--layout", "multiview", "--rendering", "render-pass2", "--secondary"];
    secondary_multiview_dynamic: ["--layout", "multiview", "--rendering", "dynamic", "--secondary"];
    secondary_side_by_side_render_pass: ["--layout", "side-by-side", "--rendering", "render-pass", "--depth", "reverse", "--secondary"];
    secondary_side_by_side_dynamic: ["--layout", "side-by-side", "--rendering", "dynamic", "--secondary"];
    secondary_intermediate_side_by_side_copy: ["--layout", "side-by-side", "--rendering", "render-pass2", "--intermediate", "--samples", "1", "--secondary"];
    vulkan_1_0_per_eye_render_pass: ["--layout", "per-eye", "--rendering", "render-pass", "--vulkan-api", "1.0"];
    vulkan_1_0_per_eye_render_pass2_reverse: ["--layout", "per-eye", "--rendering", "render-pass2", "--depth", "reverse", "--vulkan-api", "1.0"];
    vulkan_1_0_side_by_side_render_pass: ["--layout", "side-by-side", "--rendering", "render-pass", "--vulkan-api", "1.0"];
    vulkan_1_0_side_by_side_render_pass2_enable: ["--layout", "side-by-side", "--rendering", "render-pass2", "--vulkan-api", "1.0", "--vulkan", "enable"];
    vulkan_1_0_intermediate_per_eye_msaa: ["--layout", "per-eye", "--rendering", "render-pass", "--intermediate", "--vulkan-api", "1.0"];
    vulkan_1_1_multiview_render_pass2: ["--layout", "multiview", "--rendering", "render-pass2", "--vulkan-api", "1.1"];
}

wrapped_tests! {
    validation_env_vulkan_1_0_per_eye: ["--layout", "per-eye", "--rendering", "render-pass", "--vulkan-api", "1.0"];
    validation_env_secondary_side_by_side: ["--layout", "side-by-side", "--rendering", "dynamic", "--secondary"];
}

/// xrizer's temporary session (`--temporary-session`): before the app's device exists, a session
/// on a Vulkan instance and device of their own, destroyed at once; then the real session on the
/// app's device through the legacy `XR_KHR_vulkan_enable`, the eyes copied by a second component
/// (`--submit-via openvr`). The layer applies nothing to the temporary device (its stats line shows
/// no pass and no object of the layer's) and masks every eye pass of the real one after frame 0.
#[test]
fn openvr_temporary_session_on_another_device() {
    let frames = 4u64;
    let args = ["--layout", "per-eye", "--rendering", "render-pass", "--intermediate", "--samples", "1", "--submit-via", "openvr", "--vulkan", "enable", "--temporary-session"];
    let plain = Run::new("mask-temporary-session").args(args).env("MOCK_XR_EXIT_AFTER", &frames.to_string()).run();
    plain.assert_ok();
    let mut run = Run::new("mask-temporary-session").args(args).env("MOCK_XR_EXIT_AFTER", &frames.to_string()).with_layer().env("STEREOSHIM_MASK_ENABLED", "1");
    run.name = "mask-temporary-session-layered".into();
    let out = run.run();
    out.assert_ok();
    out.assert_log_lacks(Half::Both, "internal failure");
    assert!(out.stderr.contains("temporary session made and destroyed"), "{}", out.stderr);
    let lines = out.log_lines("vulkan device stats:");
    assert_eq!(lines.len(), 2, "one line per device, the temporary one first:\n{}", out.log);
    let count = |line: &str, key: &str| -> u64 { line.split_whitespace().find_map(|w| w.strip_prefix(key)).and_then(|v| v.parse().ok()).unwrap_or(0) };
    let (temporary, real) = (&lines[0], &lines[1]);
    for key in ["render_pass=", "render_pass2=", "dynamic_rendering=", "masked_passes=", "pipelines="] {
        assert_eq!(count(temporary, key), 0, "{key} on the temporary device: {temporary}");
    }
    let own: u64 = temporary.split_whitespace().filter(|w| w.starts_with("own.")).filter_map(|w| w.split('=').nth(1)?.parse::<u64>().ok()).sum();
    assert_eq!(own, 0, "the layer made objects on the temporary device: {temporary}");
    assert_eq!(count(real, "masked_passes="), 2 * (frames - 1), "{real}");
    // Outside the mask, what the runtime gets is the run without the layer's.
    common::assert_same_frame("mask-temporary-session-f0", &out, 0, &plain, 0);
}

/// `--one-target` over many frames: every eye pass after frame 0 is masked, each with the eye its
/// copy reaches (the per-frame check is `one_target_*` above), none counted as anything else.
#[test]
fn one_target_every_frame() {
    let frames = 8u64;
    let out = Run::new("mask-one-target-frames")
        .args(["--layout", "per-eye", "--intermediate", "--one-target"])
        .env("MOCK_XR_EXIT_AFTER", &frames.to_string())
        .with_layer()
        .env("STEREOSHIM_MASK_ENABLED", "1")
        .run();
    out.assert_ok();
    let stats = out.log_lines("vulkan device stats:").join("\n");
    let count = |key: &str| -> u64 { stats.split_whitespace().find_map(|w| w.strip_prefix(key)).and_then(|v| v.parse().ok()).unwrap_or(0) };
    assert_eq!(count("masked_passes="), 2 * (frames - 1), "{stats}");
    // Frame 0's two passes, before anything is known; nothing else goes unmasked.
    let unmasked: u64 = stats.split_whitespace().filter(|w| w.starts_with("not_masked.")).filter_map(|w| w.split('=').nth(1)?.parse::<u64>().ok()).sum();
    assert_eq!(unmasked, 2, "{stats}");
}
