//! End-to-end checks of the test ground itself: xr-scene through the mock runtime, no layer.
//! Every later claim about stereoshim compares against captures like these, so they must be
//! deterministic, show the expected scene, and be identical across equivalent app code paths.

use crate::common;

use common::image::Image;
use common::{assert_same_captures, assert_same_stats, project, Run, RunOutput};

/// Centre of the red near cube (docs/testing.md).
const NEAR_CUBE: [f32; 3] = [0.0, 1.45, -1.5];

/// The captured frame the checks look at (frame 0 is captured too; 1 shows steady state).
const FRAME: u64 = 1;

fn is_red(c: &[f32]) -> bool {
    c[0] > 2.0 * c[1] && c[0] > 2.0 * c[2] && c[0] > 80.0
}

/// Mean x of the red (near cube) pixels.
fn red_centroid_x(img: &Image) -> Option<f32> {
    let (mut sum, mut n) = (0f64, 0u64);
    for y in 0..img.height {
        for x in 0..img.width {
            let p = img.pixel(x, y);
            if is_red(&[p[0] as f32, p[1] as f32, p[2] as f32]) {
                sum += x as f64;
                n += 1;
            }
        }
    }
    (n > 0).then(|| (sum / n as f64) as f32)
}

/// The content every capture of xr-scene must show: two different eyes, sky above, ground below,
/// the near cube where each eye's projection puts it, and no pixel left at the black clear colour.
fn check_scene(out: &RunOutput) {
    let views = out.views(FRAME);
    assert_eq!(views.len(), 2, "{}: stereo needs two projection views", out.name);
    let images: Vec<Image> = views.iter().map(|v| out.image(&v.file)).collect();
    for (view, img) in views.iter().zip(&images) {
        let name = format!("{} view {}", out.name, view.view);
        assert_eq!((img.width, img.height), (view.image_rect.width, view.image_rect.height), "{name}: capture size");
        let (w, h) = (img.width, img.height);
        let sky = img.mean(w / 2, 2, 2);
        assert!(sky[2] > sky[0] && sky[2] > sky[1], "{name}: top centre is not sky-blue: {sky:?}");
        let ground = img.mean(w / 2, h - 3, 2);
        assert!(ground[1] > ground[2] && ground[1] >= ground[0], "{name}: bottom centre is not ground: {ground:?}");
        let (cx, cy) = project(view, NEAR_CUBE).unwrap_or_else(|| panic!("{name}: near cube outside the view"));
        let cube = img.mean(cx as u32, cy as u32, 1);
        assert!(is_red(&cube), "{name}: near cube not at its projection ({cx:.1},{cy:.1}): {cube:?}");
        let black = img.data.chunks_exact(3).filter(|p| p.iter().all(|&c| c == 0)).count();
        assert_eq!(black, 0, "{name}: {black} pixels left at the clear colour");
    }
    // Stereo: the eyes differ, and the near cube sits further right in the left eye than in the
    // right one by the disparity the two projections predict (within a pixel and a half).
    let differing = images[0].count_different(&images[1]);
    let total = (images[0].width * images[0].height) as usize;
    assert!(differing > total / 200, "{}: left and right eyes barely differ ({differing} of {total})", out.name);
    let centroids: Vec<f32> = images.iter().map(|img| red_centroid_x(img).expect("red cube pixels")).collect();
    let predicted: Vec<f32> = views.iter().map(|v| project(v, NEAR_CUBE).unwrap().0).collect();
    let (disparity, expected) = (centroids[0] - centroids[1], predicted[0] - predicted[1]);
    assert!(expected > 1.0, "{}: the profile predicts no disparity ({expected})", out.name);
    // The centroid of the visible faces is not the projected centre: allow a pixel and a half,
    // plus 2 % for canted views that see the cube from the side.
    assert!(
        (disparity - expected).abs() < 1.5 + 0.02 * expected,
        "{}: near cube disparity {disparity:.2} px, projections predict {expected:.2} px",
        out.name
    );
    let stats = out.stats.as_ref().unwrap_or_else(|| panic!("{}: no stats", out.name));
    let frame = stats.frames.iter().find(|f| f.frame == FRAME).expect("stats for the checked frame");
    let (stat_ids, view_ids): (Vec<u32>, Vec<u32>) = (frame.views.iter().map(|v| v.view).collect(), views.iter().map(|v| v.view).collect());
    assert_eq!(stat_ids, view_ids, "{}: stats and capture disagree on the views", out.name);
    for (v, img) in frame.views.iter().zip(&images) {
        let pixels = (img.width * img.height) as u64;
        assert!(
            v.shaded_fragments >= pixels && v.shaded_fragments < 4 * pixels,
            "{}: view {} shaded {} fragments for {pixels} pixels",
            out.name,
            v.view,
            v.shaded_fragments
        );
    }
}

/// One layout × depth convention: all three ways of starting a pass must give the same pixels,
/// and a repeated run must give the same pixels and the same shaded-fragment counts.
fn layout_depth(layout: &str, depth: &str) {
    let base = |rendering: &str, tag: &str| {
        Run::new(&format!("{layout}-{depth}-{rendering}{tag}"))
            .args(["--layout", layout, "--depth", depth, "--rendering", rendering])
            .run()
    };
    let first = base("render-pass", "");
    first.assert_ok();
    check_scene(&first);
    let again = base("render-pass", "-again");
    again.assert_ok();
    assert_same_captures(&format!("{layout}-{depth}-determinism"), &first, &again);
    assert_same_stats(&format!("{layout}-{depth}-determinism"), &first, &again);
    for rendering in ["render-pass2", "dynamic"] {
        let other = base(rendering, "");
        other.assert_ok();
        check_scene(&other);
        assert_same_captures(&format!("{layout}-{depth}-{rendering}-vs-render-pass"), &other, &first);
    }
}

macro_rules! layout_depth_tests {
    ($($name:ident: $layout:literal, $depth:literal;)*) => {$(
        #[test]
        fn $name() {
            layout_depth($layout, $depth);
        }
    )*};
}

layout_depth_tests! {
    per_eye_standard: "per-eye", "standard";
    per_eye_reverse: "per-eye", "reverse";
    multiview_standard: "multiview", "standard";
    multiview_reverse: "multiview", "reverse";
    side_by_side_standard: "side-by-side", "standard";
    side_by_side_reverse: "side-by-side", "reverse";
}

/// `--depth-clear attachments|image` (the depth buffer loaded by the pass and cleared by
/// vkCmdClearAttachments inside it, or by vkCmdClearDepthStencilImage before it) is the same frame
/// as the load-op clear: for one layout, every way of starting a pass × both depth conventions
/// gives the load-op captures bit for bit, and the same shaded-fragment counts. The load-op
/// baseline is rendered with render-pass only: `layout_depth` shows the other shapes equal it.
/// Validation (synchronization included) must stay silent.
fn depth_clear_modes(layout: &str) {
    for depth in ["standard", "reverse"] {
        let run = |rendering: &str, clear: &str, extra: &[&str]| {
            let tag = if extra.is_empty() { String::new() } else { format!("-{}", extra.join("").trim_start_matches('-')) };
            let out = Run::new(&format!("depth-clear-{layout}-{depth}-{rendering}-{clear}{tag}"))
                .args(["--layout", layout, "--depth", depth, "--rendering", rendering, "--depth-clear", clear])
                .args(extra.iter().copied())
                .run();
            out.assert_ok();
            out
        };
        let baseline = run("render-pass", "load-op", &[]);
        for rendering in ["render-pass", "render-pass2", "dynamic"] {
            for clear in ["attachments", "image"] {
                let other = run(rendering, clear, &[]);
                let label = format!("depth-clear-{layout}-{depth}-{rendering}-{clear}-vs-load-op");
                assert_same_captures(&label, &other, &baseline);
                assert_same_stats(&label, &other, &baseline);
            }
        }
        // Submitted depth (a swapchain image the runtime made with the usage asked for, TRANSFER_DST
        // for the image clear) holds the same depth too.
        let rendering = if depth == "standard" { "dynamic" } else { "render-pass2" };
        let baseline = run(rendering, "load-op", &["--submit-depth"]);
        for clear in ["attachments", "image"] {
            let other = run(rendering, clear, &["--submit-depth"]);
            assert!(other.views(FRAME).iter().all(|v| v.depth.is_some()), "{layout}: depth not submitted");
            assert_same_captures(&format!("depth-clear-{layout}-{depth}-{clear}-submitted"), &other, &baseline);
        }
    }
}

#[test]
fn depth_clear_per_eye() {
    depth_clear_modes("per-eye");
}

#[test]
fn depth_clear_multiview() {
    depth_clear_modes("multiview");
}

#[test]
fn depth_clear_side_by_side() {
    depth_clear_modes("side-by-side");
}

/// The three layouts are the same scene through different plumbing: identical pixels per eye.
#[test]
fn layouts_agree() {
    let run = |layout: &str| Run::new(&format!("layouts-agree-{layout}")).args(["--layout", layout]).run();
    let per_eye = run("per-eye");
    per_eye.assert_ok();
    for layout in ["multiview", "side-by-side"] {
        let other = run(layout);
        other.assert_ok();
        assert_same_captures(&format!("layouts-agree-{layout}-vs-per-eye"), &other, &per_eye);
    }
}

/// An offscreen target copied 1:1 gives the direct image; a multisampled one resolved still shows
/// the scene (edges differ, by design).
#[test]
fn intermediate_targets() {
    for layout in ["per-eye", "multiview", "side-by-side"] {
        let direct = Run::new(&format!("intermediate-{layout}-direct")).args(["--layout", layout]).run();
        direct.assert_ok();
        let copied = Run::new(&format!("intermediate-{layout}-copy"))
            .args(["--layout", layout, "--intermediate", "--samples", "1", "--rendering", "dynamic"])
            .run();
        copied.assert_ok();
        check_scene(&copied);
        assert_same_captures(&format!("intermediate-{layout}-copy-vs-direct"), &copied, &direct);
        let resolved = Run::new(&format!("intermediate-{layout}-msaa"))
            .args(["--layout", layout, "--intermediate", "--samples", "4"])
            .run();
        resolved.assert_ok();
        check_scene(&resolved);
    }
}

/// Submitted depth is captured, orders near before far in the app's convention, and submitting
/// it leaves the colour image unchanged.
#[test]
fn submitted_depth() {
    for (layout, depth) in [("per-eye", "standard"), ("multiview", "reverse"), ("side-by-side", "standard")] {
        let plain = Run::new(&format!("depth-{layout}-{depth}-plain")).args(["--layout", layout, "--depth", depth]).run();
        plain.assert_ok();
        let with = Run::new(&format!("depth-{layout}-{depth}-submitted"))
            .args(["--layout", layout, "--depth", depth, "--submit-depth"])
            .run();
        with.assert_ok();
        check_scene(&with);
        // Colour only: `plain` submits no depth.
        common::assert_same_colour_captures(&format!("depth-{layout}-{depth}-colour"), &with, &plain);
        for view in with.views(FRAME) {
            let info = view.depth.as_ref().unwrap_or_else(|| panic!("{layout}: view {} has no depth", view.view));
            let reversed = depth == "reverse";
            assert_eq!(info.near_z > info.far_z, reversed, "{layout}: nearZ/farZ must tell reversed depth");
            let img = with.image(&info.file);
            assert_eq!((img.width, img.height), (info.image_rect.width, info.image_rect.height));
            let (cx, cy) = project(view, NEAR_CUBE).expect("cube visible");
            let cube = img.pixel(cx as u32, cy as u32)[0];
            let sky = img.pixel(img.width / 2, 1)[0];
            if reversed {
                assert!(cube > sky, "{layout}: reversed depth must be larger near: cube {cube}, sky {sky}");
            } else {
                assert!(cube < sky, "{layout}: depth must be smaller near: cube {cube}, sky {sky}");
            }
        }
    }
}

/// Both Vulkan bindings give the same frames.
#[test]
fn vulkan_enable_paths_agree() {
    let enable2 = Run::new("vulkan-enable2").args(["--vulkan", "enable2", "--layout", "multiview"]).run();
    enable2.assert_ok();
    let enable = Run::new("vulkan-enable").args(["--vulkan", "enable", "--layout", "multiview"]).run();
    enable.assert_ok();
    check_scene(&enable);
    assert_same_captures("vulkan-enable-vs-enable2", &enable, &enable2);
}

/// Every HMD profile, canted and asymmetric ones included, gives a correct stereo scene.
#[test]
fn hmd_profiles() {
    for hmd in ["simple", "index", "vive", "quest3", "pimax"] {
        let out = Run::new(&format!("hmd-{hmd}")).env("MOCK_XR_HMD", hmd).args(["--scale", "0.15"]).run();
        out.assert_ok();
        assert_eq!(out.frames().hmd, hmd);
        check_scene(&out);
    }
}

/// UNORM swapchains hold the same scene (values differ from sRGB by encoding, not content).
#[test]
fn unorm_swapchain() {
    let out = Run::new("unorm").args(["--color-format", "unorm", "--layout", "side-by-side"]).run();
    out.assert_ok();
    check_scene(&out);
}

/// The app's own input works: the runtime's menu click makes xr-scene request exit, and the
/// session ends long before the runtime would have stopped it.
#[test]
fn menu_click_quits_app() {
    let out = Run::new("menu-click").env("MOCK_XR_EXIT_AFTER", "1000").env("MOCK_XR_MENU_CLICK_AT", "2").run();
    out.assert_ok();
    let last = out.frames().frames.last().expect("frames").frame;
    assert!(last < 10, "app ran {last} frames after the menu click");
}

/// `--frames N` ends the session by the app's own request.
#[test]
fn app_requests_exit() {
    let out = Run::new("frames-limit").env("MOCK_XR_EXIT_AFTER", "1000").args(["--frames", "3"]).run();
    out.assert_ok();
    let last = out.frames().frames.last().expect("frames").frame;
    assert!(last < 6, "app ran {last} frames with --frames 3");
}

/// Animation is deterministic per frame: two runs agree, and consecutive frames differ.
#[test]
fn animation_is_deterministic() {
    let a = Run::new("animate-a").args(["--animate"]).run();
    a.assert_ok();
    let b = Run::new("animate-b").args(["--animate"]).run();
    b.assert_ok();
    assert_same_captures("animate-determinism", &a, &b);
    let f0 = a.image(&a.views(0)[0].file);
    let f1 = a.image(&a.views(1)[0].file);
    assert!(f0.count_different(&f1) > 0, "--animate: frames 0 and 1 are identical");
}

/// `--pixel-stats`: in every layout × way of starting a pass (and through intermediate targets,
/// copied and MSAA-resolved) the per-pixel counts of each view sum to the view's
/// `shaded_fragments`, every pixel was shaded at least once (the scene covers the image), the run
/// stays validation-clean, and the flag changes neither the captures nor the per-view counts.
#[test]
fn pixel_stats_sum_to_view_counts() {
    for layout in ["per-eye", "multiview", "side-by-side"] {
        let plain = Run::new(&format!("pixel-stats-{layout}-plain")).args(["--layout", layout]).run();
        plain.assert_ok();
        let variants: [&[&str]; 5] = [
            &["--rendering", "render-pass"],
            &["--rendering", "render-pass2"],
            &["--rendering", "dynamic"],
            &["--rendering", "dynamic", "--intermediate", "--samples", "1"],
            &["--rendering", "render-pass", "--intermediate", "--samples", "4"],
        ];
        for (i, extra) in variants.iter().enumerate() {
            let name = format!("pixel-stats-{layout}-{i}");
            let out = Run::new(&name).args(["--layout", layout]).args(extra.iter().copied()).pixel_stats().run();
            out.assert_ok();
            let stats = out.stats.as_ref().expect("stats");
            assert_eq!(stats.frames.len(), out.frames().frames.len(), "{name}: stats of every captured frame");
            for f in &stats.frames {
                assert_eq!(f.views.len(), out.views(f.frame).len(), "{name}: frame {}: stats of every view", f.frame);
                for v in &f.views {
                    let counts = out.pixel_counts(f.frame, v.view);
                    let sum: u64 = counts.iter().map(|&c| c as u64).sum();
                    assert_eq!(sum, v.shaded_fragments, "{name}: frame {} view {}: per-pixel counts sum to {sum}", f.frame, v.view);
                    let empty = counts.iter().filter(|&&c| c == 0).count();
                    assert_eq!(empty, 0, "{name}: frame {} view {}: {empty} pixels never shaded", f.frame, v.view);
                }
            }
            if i == 0 {
                assert_same_captures(&format!("{name}-vs-plain"), &out, &plain);
                assert_eq!(out.stats.as_ref().map(|s| s.frames.iter().map(|f| f.views.iter().map(|v| v.shaded_fragments).collect::<Vec<_>>()).collect::<Vec<_>>()),
                    plain.stats.as_ref().map(|s| s.frames.iter().map(|f| f.views.iter().map(|v| v.shaded_fragments).collect::<Vec<_>>()).collect::<Vec<_>>()),
                    "{name}: --pixel-stats changed the per-view counts");
            }
        }
    }
}

/// xr-scene at `--vulkan-api 1.0` (a Vulkan 1.0 instance and device: no 1.1+ structs or entry
/// points, SPIR-V 1.0 shaders, render pass 2 through VK_KHR_create_renderpass2) renders the same
/// frames and shaded-fragment counts as the default 1.3 app, validation-clean: one layout, both
/// ways of starting a pass a 1.0 device has × both depth conventions, and (standard depth) the
/// XR_KHR_vulkan_enable binding, where the app creates instance and device itself.
fn vulkan_api_1_0(layout: &str) {
    for depth in ["standard", "reverse"] {
        let run = |tag: &str, extra: &[&str]| {
            let out = Run::new(&format!("vk10-{layout}-{depth}-{tag}"))
                .args(["--layout", layout, "--depth", depth])
                .args(extra.iter().copied())
                .run();
            out.assert_ok();
            out
        };
        let baseline = run("baseline-1.3", &["--rendering", "render-pass"]);
        let mut variants: Vec<(&str, &[&str])> =
            vec![("render-pass", &["--rendering", "render-pass"]), ("render-pass2", &["--rendering", "render-pass2"])];
        if depth == "standard" {
            variants.push(("enable", &["--rendering", "render-pass", "--vulkan", "enable"]));
        }
        for (tag, extra) in variants {
            let other = run(&format!("1.0-{tag}"), &[&["--vulkan-api", "1.0"][..], extra].concat());
            check_scene(&other);
            let label = format!("vk10-{layout}-{depth}-{tag}-vs-1.3");
            assert_same_captures(&label, &other, &baseline);
            assert_same_stats(&label, &other, &baseline);
        }
    }
}

#[test]
fn vulkan_api_1_0_per_eye() {
    vulkan_api_1_0("per-eye");
}

#[test]
fn vulkan_api_1_0_side_by_side() {
    vulkan_api_1_0("side-by-side");
}

/// `--vulkan-api 1.1` (multiview core; render pass 2 and dynamic rendering through their KHR
/// extensions) gives the 1.3 frames in the multiview layout.
#[test]
fn vulkan_api_1_1_multiview() {
    let run = |name: &str, extra: &[&str]| {
        let out = Run::new(name).args(["--layout", "multiview"]).args(extra.iter().copied()).run();
        out.assert_ok();
        out
    };
    let baseline = run("vk11-multiview-baseline-1.3", &["--rendering", "render-pass"]);
    for rendering in ["render-pass", "render-pass2", "dynamic"] {
        let other = run(&format!("vk11-multiview-{rendering}"), &["--vulkan-api", "1.1", "--rendering", rendering]);
        let label = format!("vk11-multiview-{rendering}-vs-1.3");
        assert_same_captures(&label, &other, &baseline);
        assert_same_stats(&label, &other, &baseline);
    }
}

/// What a Vulkan 1.0 app cannot do is refused on the command line (exit 2) with a reason, before
/// any OpenXR or Vulkan call.
#[test]
fn vulkan_api_1_0_refuses_multiview_and_dynamic() {
    for (args, needle) in [
        (&["--vulkan-api", "1.0", "--layout", "multiview"][..], "multiview needs Vulkan 1.1"),
        (&["--vulkan-api", "1.0", "--rendering", "dynamic"][..], "dynamic needs Vulkan 1.1"),
        (&["--vulkan-api", "1.2"][..], "invalid value '1.2' for '--vulkan-api"),
        (&["--secondary", "--bind-before-pass"][..], "exclude each other"),
    ] {
        let out = std::process::Command::new(common::xr_scene_exe()).args(args).output().expect("spawn xr-scene");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: stderr:\n{stderr}");
        assert!(stderr.contains(needle), "{args:?}: no {needle:?} in stderr:\n{stderr}");
    }
}

/// `--secondary`: each eye pass's contents recorded into a secondary command buffer
/// (SECONDARY_COMMAND_BUFFERS contents / CONTENTS_SECONDARY_COMMAND_BUFFERS_BIT with inheritance)
/// give the primary-recorded frames and shaded-fragment counts in every way of starting a pass,
/// validation-clean; plus one combination per layout with another habit (Vulkan 1.0 / 1.1, the
/// depth clear inside the secondary, an intermediate target).
fn secondary(layout: &str, combo: &[&str]) {
    let run = |name: String, extra: &[&str]| {
        let out = Run::new(&name).args(["--layout", layout]).args(extra.iter().copied()).run();
        out.assert_ok();
        out
    };
    let baseline = run(format!("secondary-{layout}-primary"), &["--rendering", "render-pass"]);
    let mut variants: Vec<(String, Vec<&str>)> = ["render-pass", "render-pass2", "dynamic"]
        .iter()
        .map(|r| (r.to_string(), vec!["--secondary", "--rendering", r]))
        .collect();
    variants.push(("combo".into(), [&["--secondary"][..], combo].concat()));
    for (tag, extra) in variants {
        let other = run(format!("secondary-{layout}-{tag}"), &extra);
        if tag == "dynamic" {
            check_scene(&other);
        }
        let label = format!("secondary-{layout}-{tag}-vs-primary");
        assert_same_captures(&label, &other, &baseline);
        assert_same_stats(&format!("{label} ({extra:?})"), &other, &baseline);
    }
}

#[test]
fn secondary_per_eye() {
    secondary("per-eye", &["--vulkan-api", "1.0", "--rendering", "render-pass2", "--depth-clear", "attachments"]);
}

#[test]
fn secondary_multiview() {
    secondary("multiview", &["--vulkan-api", "1.1", "--rendering", "dynamic", "--depth-clear", "attachments"]);
}

#[test]
fn secondary_side_by_side() {
    secondary("side-by-side", &["--vulkan-api", "1.0", "--vulkan", "enable", "--intermediate", "--samples", "1"]);
}

/// xr-scene links the Vulkan loader as C and C++ apps do (libvulkan.so.1 a DT_NEEDED entry,
/// vkGetInstanceProcAddr an undefined dynamic symbol bound by the dynamic linker), so every test
/// exercises symbol interposition between a layer and the loader.
#[test]
fn xr_scene_links_libvulkan() {
    let exe = common::xr_scene_exe();
    let readelf = |args: &[&str]| {
        let out = std::process::Command::new("readelf").args(args).arg(&exe).output().expect("run readelf (binutils)");
        assert!(out.status.success(), "readelf {args:?} failed");
        String::from_utf8_lossy(&out.stdout).into_owned()
    };
    let dynamic = readelf(&["-d", "-W"]);
    assert!(
        dynamic.lines().any(|l| l.contains("(NEEDED)") && l.contains("[libvulkan.so.1]")),
        "xr-scene does not link libvulkan.so.1:\n{dynamic}"
    );
    let symbols = readelf(&["--dyn-syms", "-W"]);
    assert!(
        symbols.lines().any(|l| l.split_whitespace().last() == Some("vkGetInstanceProcAddr") && l.contains(" UND ")),
        "vkGetInstanceProcAddr is not an undefined dynamic symbol of xr-scene:\n{symbols}"
    );
}

/// `--record-once` (each combination of acquired swapchain images gets its command buffers
/// recorded once and resubmitted, several frames in flight, the per-frame view and animation in
/// a per-frame-set uniform buffer) gives the captures and shaded-fragment counts of recording every
/// frame, frame for frame, validation-clean (synchronization validation included), in every
/// layout and way of starting a pass, with secondaries, intermediate targets (MSAA and copied),
/// submitted depth, both depth clears done by the app, both Vulkan bindings and Vulkan 1.0, and
/// with `--rerecord-every` re-recording some sets. Seven frames over three swapchain images:
/// frames 3–6 run command buffers recorded for frames 0–2 (or re-recorded), which the app's own
/// numbers confirm (recording time exactly in the frames that record).
#[test]
fn record_once_matches_recording_every_frame() {
    let variants: [(&[&str], Option<u64>); 8] = [
        (&["--layout", "per-eye", "--rendering", "render-pass"], None),
        (&["--layout", "multiview", "--rendering", "dynamic", "--secondary"], None),
        (&["--layout", "side-by-side", "--rendering", "render-pass2", "--intermediate"], None),
        (&["--layout", "per-eye", "--rendering", "dynamic", "--submit-depth", "--depth-clear", "image", "--vulkan", "enable"], None),
        (&["--layout", "multiview", "--rendering", "render-pass2", "--intermediate", "--samples", "1", "--depth", "reverse", "--depth-clear", "attachments"], None),
        (&["--layout", "side-by-side", "--rendering", "render-pass", "--secondary", "--vulkan-api", "1.0"], None),
        (&["--layout", "per-eye", "--rendering", "render-pass2", "--secondary"], Some(2)),
        // The far-field options: a far mover moved through the uniforms, extra pipelines and draws.
        (&["--layout", "multiview", "--rendering", "dynamic", "--far-movers", "--sky-first", "--translucent"], None),
    ];
    const FRAMES: u64 = 7;
    for (i, (args, rerecord)) in variants.iter().enumerate() {
        let run = |tag: &str, extra: &[&str]| {
            let mut r = Run::new(&format!("record-once-{i}-{tag}")).args(["--animate"]).args(args.iter().copied()).args(extra.iter().copied()).env("MOCK_XR_EXIT_AFTER", &FRAMES.to_string());
            // One variant also compares the per-pixel counts of every frame.
            if i == 0 {
                r = r.pixel_stats();
            }
            let out = r.run();
            out.assert_ok();
            out
        };
        let every = run("every-frame", &[]);
        let n = rerecord.map(|n| n.to_string());
        let once = match &n {
            Some(n) => run("once", &["--record-once", "--rerecord-every", n]),
            None => run("once", &["--record-once"]),
        };
        // Artifact folders are named after the label; the flags go into the messages.
        let label = format!("record-once-{i}");
        assert_eq!(once.frames().frames.len() as u64, FRAMES, "{label} {args:?}: frames captured");
        assert_same_captures(&label, &once, &every);
        assert_same_stats(&format!("{label} {args:?}"), &once, &every);
        if i == 0 {
            for f in 0..FRAMES {
                for v in 0..2 {
                    assert_eq!(once.pixel_counts(f, v), every.pixel_counts(f, v), "{label}: frame {f} view {v}: per-pixel counts differ");
                }
            }
        }
        // The app's own account: recording time only while a set is new (three swapchain
        // images: frames 0–2) and in the frames `--rerecord-every` names; every frame when
        // recording every frame.
        let record_us = |o: &RunOutput| -> Vec<f64> {
            let path = o.capture.parent().unwrap().join("stats.json");
            let v: serde_json::Value = serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap();
            v["frames"].as_array().unwrap().iter().map(|f| f["cpu_record_us"].as_f64().unwrap()).collect()
        };
        let (once_us, every_us) = (record_us(&once), record_us(&every));
        let recorded: Vec<bool> = once_us.iter().map(|&t| t > 0.0).collect();
        let expected: Vec<bool> = (0..FRAMES).map(|f| f < 3 || rerecord.is_some_and(|n| f.is_multiple_of(n))).collect();
        assert_eq!(recorded, expected, "{label} {args:?} (re-record every {rerecord:?}): which frames recorded; times {once_us:?}");
        assert!(every_us.iter().all(|&t| t > 0.0), "{label} {args:?}: recording times {every_us:?}");
        // Frames differ (the cube spins), so a resubmitted buffer that drew a stale frame shows.
        let (a, b) = (once.views(3)[0], once.views(4)[0]);
        assert!(once.image(&a.file).count_different(&once.image(&b.file)) > 0, "{label} {args:?}: frames 3 and 4 are identical");
    }
}

/// xr-scene's `--validation` really runs synchronization validation, and an error makes the run
/// fail (exit 3), through both Vulkan bindings (with `enable2` the runtime creates the instance
/// from the app's create info, which must keep its VkValidationFeaturesEXT): `--sync-hazard`
/// leaves out one barrier, a hazard only synchronization validation reports. Without
/// `--validation` the same run succeeds, so it is validation that fails it.
#[test]
fn validation_reports_synchronization_hazards() {
    for vulkan in ["enable2", "enable"] {
        for record_once in [false, true] {
            let mut args = vec!["--vulkan", vulkan, "--sync-hazard"];
            if record_once {
                args.push("--record-once");
            }
            let name = format!("sync-hazard-{vulkan}-{}", if record_once { "once" } else { "every" });
            let out = Run::new(&name).args(args.iter().copied()).run();
            assert_eq!(out.code, Some(3), "{name}: a hazard under --validation must fail the run; stderr:\n{}", out.stderr);
            assert!(out.stderr.contains("SYNC-HAZARD-"), "{name}: no synchronization hazard reported; stderr:\n{}", out.stderr);
            let mut plain = Run::new(&format!("{name}-unvalidated")).args(args.iter().copied());
            plain.validation = false;
            plain.run().assert_ok();
        }
    }
}
