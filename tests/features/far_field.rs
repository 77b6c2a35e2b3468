//! Monoscopic far field on xr-scene + the mock runtime (lavapipe, validation with synchronization
//! checks): the source eye is bit-identical to a run without the layer; in the destination eye
//! every pixel nearer than the split is bit-identical, the far pixels are close (PSNR over the far
//! pixels only) and no pixel is left unrendered; the pixels the layer reuses match a set computed
//! here, independently, from the reference run's submitted depth and view poses; the drop in the
//! destination's shaded fragments is counted from xr-scene's per-pixel counters.

use crate::common;

use common::far_field::{analyse, distances, psnr, Analysis, Outcome};
use common::{Half, Run, RunOutput};

/// How a case is run and judged.
#[derive(Clone)]
struct Case {
    name: String,
    args: Vec<String>,
    env: Vec<(String, String)>,
    /// The frame compared (earlier frames are captured too: previous-frame sources).
    frame: u64,
    split_m: f64,
    depth_shift: bool,
    /// The source copy is the previous frame's (multiview, side-by-side).
    previous_frame: bool,
    debug: bool,
    /// Fragments per pixel the app shades before the injection point (a sky drawn first without
    /// depth test): the far field cannot save those.
    shaded_before: u32,
    /// Vulkan validation on (bookworm's layer does not know shader objects).
    validation: bool,
}

impl Case {
    fn analysis(&self) -> Analysis {
        Analysis { name: self.name.clone(), split_m: self.split_m, depth_shift: self.depth_shift, debug: self.debug, shaded_before: self.shaded_before }
    }
    fn new(name: &str, args: &[&str]) -> Case {
        Case {
            name: name.into(),
            args: args.iter().map(|s| s.to_string()).collect(),
            env: Vec::new(),
            frame: 1,
            split_m: 40.0,
            depth_shift: false,
            previous_frame: false,
            debug: false,
            shaded_before: 0,
            validation: true,
        }
    }
    fn env(mut self, k: &str, v: &str) -> Case {
        self.env.push((k.into(), v.into()));
        self
    }
    fn frame(mut self, f: u64) -> Case {
        self.frame = f;
        self
    }

    fn base(&self) -> Run {
        let frames = self.frame + 1;
        let mut run = Run::new(&self.name).args(["--submit-depth"]).args(self.args.iter().cloned()).pixel_stats().env("MOCK_XR_EXIT_AFTER", &frames.to_string());
        for (k, v) in &self.env {
            run = run.env(k, v);
        }
        run.validation = self.validation;
        run
    }

    /// The reference run (no layer) and the layered one.
    fn run(&self) -> (RunOutput, RunOutput) {
        let mut plain = self.base();
        plain.name = format!("{}-plain", self.name);
        let plain = plain.run();
        plain.assert_ok();
        let mut far = self
            .base()
            .with_layer()
            .env("STEREOSHIM_FAR_FIELD_ENABLED", "1")
            .env("STEREOSHIM_FAR_FIELD_SPLIT_M", &self.split_m.to_string())
            .env("STEREOSHIM_FAR_FIELD_SHIFT", if self.depth_shift { "depth" } else { "infinity" })
            .env("STEREOSHIM_FAR_FIELD_DEBUG", if self.debug { "1" } else { "0" });
        far.name = format!("{}-far", self.name);
        let far = far.run();
        far.assert_ok();
        far.assert_layer_loaded(Half::Both);
        far.assert_log_lacks(Half::Both, "internal failure");
        (plain, far)
    }
}

/// Runs a case and applies the thresholds.
fn check(case: Case, min_psnr: f64) -> Outcome {
    let (plain, far) = case.run();
    let src_frame = if case.previous_frame { case.frame - 1 } else { case.frame };
    let out = analyse(&case.analysis(), &plain, &far, case.frame, 1, 0, src_frame);
    judge(&case, &out, min_psnr);
    // The layer's own count (occlusion queries, totalled over the run) against the pixels the
    // test expects the reuse draw to write in every frame that reuses.
    let first = if case.previous_frame { 2 } else { 1 };
    let (mut written, mut outline) = (0, 0);
    for f in first..=case.frame {
        let o = analyse(&case.analysis(), &plain, &far, f, 1, 0, if case.previous_frame { f - 1 } else { f });
        written += o.written;
        outline += o.outline;
    }
    let counted = layer_count(&far);
    eprintln!("{}: layer counted {counted}, expected {written} (outline {outline})", case.name);
    assert!(counted.abs_diff(written as u64) <= outline as u64, "{}: the layer counted {counted} reused pixels, the test expects {written} (outline {outline})", case.name);
    out
}

/// `far_field_pixels_reused` of the run's device stats line.
fn layer_count(run: &RunOutput) -> u64 {
    let lines = run.log_lines("far_field_pixels_reused=");
    let line = lines.last().unwrap_or_else(|| panic!("{}: no far field counters in the log:\n{}", run.name, run.log));
    let v = line.split("far_field_pixels_reused=").nth(1).unwrap().split(' ').next().unwrap();
    v.parse().unwrap()
}

fn judge(case: &Case, out: &Outcome, min_psnr: f64) {
    eprintln!("{}: {out:?}", case.name);
    assert!(out.expected > 1000, "{}: the scene has too little far field to test: {out:?}", case.name);
    assert!(out.near_pixels > 500, "{}: the scene has too little near geometry to test: {out:?}", case.name);
    if !case.debug {
        assert!(out.psnr_far >= min_psnr, "{}: far-pixel PSNR {:.1} dB < {min_psnr} dB", case.name, out.psnr_far);
    }
    assert!(
        out.fragments_saved as f64 >= 0.95 * out.expected_geometry as f64,
        "{}: {} fragments saved, want ≥ 0.95 × {} reused pixels the reference filled with far geometry",
        case.name,
        out.fragments_saved,
        out.expected_geometry
    );
}

#[test]
fn per_eye_infinity_matches_the_reference() {
    for (rendering, depth) in ["render-pass", "render-pass2", "dynamic"].into_iter().flat_map(|r| ["standard", "reverse"].map(|d| (r, d))) {
        check(Case::new(&format!("ff-per-eye-{rendering}-{depth}"), &["--layout", "per-eye", "--rendering", rendering, "--depth", depth]), 35.0);
    }
}

/// State set as DXVK sets it (`--dynamic-state`, `--pipeline-library` with render pass objects,
/// where bookworm's validation layer checks them) and shader objects (`--shader-object`, validated
/// by tests/realworld/dxvk_state.rs; here without validation): the far field's reuse draws and
/// its compute copy leave the app's dynamic state, linked pipelines and shader objects as they
/// were, with the state bound before the pass.
#[test]
fn dxvk_state_and_shader_objects() {
    let cases: [(&str, &[&str]); 3] = [
        ("ff-dxvk-dynamic-state", &["--layout", "per-eye", "--rendering", "render-pass2", "--dynamic-state", "--pipeline-library", "--bind-before-pass"]),
        ("ff-dxvk-dynamic-rendering", &["--layout", "per-eye", "--rendering", "dynamic", "--dynamic-state", "--bind-before-pass"]),
        ("ff-shader-objects", &["--layout", "per-eye", "--rendering", "dynamic", "--shader-object", "--bind-before-pass"]),
    ];
    for (name, args) in cases {
        let mut case = Case::new(name, args);
        case.validation = !args.contains(&"--shader-object");
        check(case, 35.0);
    }
}

/// The OpenVR submission path (`--submit-via openvr`): the eyes reach the swapchain through a
/// second component's copy in a submission of its own; the far field reuses as when the app
/// copies them itself.
#[test]
fn openvr_submission() {
    check(Case::new("ff-openvr", &["--layout", "per-eye", "--rendering", "dynamic", "--intermediate", "--samples", "1", "--submit-via", "openvr"]), 35.0);
    // xrizer's order: a temporary session on a device of its own first, then the legacy
    // XR_KHR_vulkan_enable on the app's.
    check(Case::new("ff-openvr-temporary", &["--layout", "per-eye", "--rendering", "render-pass", "--intermediate", "--samples", "1", "--submit-via", "openvr", "--vulkan", "enable", "--temporary-session"]), 35.0);
}

#[test]
fn per_eye_depth_shift_matches_the_reference() {
    let mut case = Case::new("ff-per-eye-depth-shift", &["--layout", "per-eye"]);
    case.depth_shift = true;
    case.split_m = 15.0;
    check(case, 40.0);
}

#[test]
fn debug_tint_marks_the_expected_pixels() {
    let mut case = Case::new("ff-debug", &["--layout", "per-eye"]);
    case.debug = true;
    let out = check(case, 0.0);
    let tinted = out.tinted.unwrap() as i64;
    assert!((tinted - out.expected as i64).abs() <= out.outline as i64, "tinted {tinted} vs expected {} (outline {})", out.expected, out.outline);
}

/// Both eyes in one pass: the source is the previous frame's copy, reprojected with the head's
/// rotation between the frames (the mock turns the head at a fixed rate).
#[test]
fn multiview_and_side_by_side_use_the_previous_frame() {
    let renderings = ["render-pass", "render-pass2", "dynamic"];
    let cases = ["multiview", "side-by-side"].into_iter().flat_map(|l| renderings.into_iter().flat_map(move |r| ["standard", "reverse"].map(|d| (l, r, d))));
    for (layout, rendering, depth) in cases {
        let mut case = Case::new(&format!("ff-{layout}-{rendering}-{depth}"), &["--layout", layout, "--rendering", rendering, "--depth", depth]).env("MOCK_XR_HEAD_YAW_DEG_PER_S", "20").frame(2);
        case.previous_frame = true;
        check(case, 35.0);
    }
}

/// Alternate eye: source and destination swap every frame; the first eye pass of a frame reuses
/// its own previous image (the source then), the second the first's of this frame. Over 300 frames
/// of a far object that moves, every captured frame's far pixels stay close to the reference
/// (nothing freezes, nothing is a copy of a copy).
#[test]
fn alternate_eye_keeps_moving_far_objects_in_place() {
    for layout in ["per-eye", "multiview"] {
        let mut case = Case::new(&format!("ff-alternate-{layout}"), &["--layout", layout, "--far-movers"])
            .env("STEREOSHIM_FAR_FIELD_ALTERNATE", "1")
            .env("MOCK_XR_HEAD_YAW_DEG_PER_S", "10")
            .env("MOCK_XR_CAPTURE_FRAMES", "99-101,199-201,297-299")
            .frame(299);
        case.previous_frame = layout == "multiview";
        let (plain, far) = case.run();
        for f in [100, 101, 200, 201, 298, 299] {
            // Even frames: view 0 is the source; odd: view 1.
            let (src, dst) = if f % 2 == 0 { (0, 1) } else { (1, 0) };
            // Same frame where the source's pass came first; else the destination's own image of
            // the previous frame (it was the source then).
            let (src_view, src_frame) = match (layout, dst) {
                ("per-eye", 1) => (src, f),
                _ => (dst, f - 1),
            };
            let out = analyse(&case.analysis(), &plain, &far, f, dst, src_view, src_frame);
            judge(&Case { name: format!("{}-frame{f}", case.name), ..case.clone() }, &out, 35.0);
        }
    }
}

/// A sky drawn first without depth test, a translucent pane over the far field and a far object
/// that moves: the reuse goes in front of the first depth-tested draw, so the sky cannot paint over
/// it, and the pane blends over the reused background as over the app's own.
#[test]
fn sky_first_translucent_and_movers() {
    for (extra, layout) in [("--sky-first", "per-eye"), ("--translucent", "per-eye"), ("--far-movers", "per-eye"), ("--sky-first", "multiview")] {
        let mut case = Case::new(&format!("ff-{}-{layout}", extra.trim_start_matches('-')), &["--layout", layout, extra]).env("MOCK_XR_HEAD_YAW_DEG_PER_S", "20").frame(2);
        case.previous_frame = layout == "multiview";
        case.shaded_before = u32::from(extra == "--sky-first");
        let (plain, far) = case.run();
        let src_frame = if case.previous_frame { 1 } else { 2 };
        if extra == "--translucent" {
            // The pane is translucent: behind it the reused far field shows through, so the pixels it
            // covers are judged as far pixels (PSNR), not bit-exact.
            let out = analyse_translucent(&case, &plain, &far, src_frame);
            judge(&case, &out, 35.0);
        } else {
            let out = analyse(&case.analysis(), &plain, &far, 2, 1, 0, src_frame);
            judge(&case, &out, 35.0);
        }
    }
}

/// `analyse` for the translucent pane: its pixels are compared with PSNR.
fn analyse_translucent(case: &Case, plain: &RunOutput, far: &RunOutput, src_frame: u64) -> Outcome {
    // The pane writes no depth: the near/far split from depth puts its pixels on the far side,
    // where the PSNR check covers them.
    analyse(&case.analysis(), plain, far, case.frame, 1, 0, src_frame)
}

/// Without the app's depth info and without `far_field.near_z` / `far_z`, the distance of a depth
/// value is unknown: not applied (one log line, counted), captures byte-identical. With the range
/// configured, the same app gets the far field.
#[test]
fn depth_range_from_depth_info_or_config_never_guessed() {
    let plain = Run::new("ff-no-range-plain").args(["--layout", "per-eye"]).run();
    plain.assert_ok();
    let far = Run::new("ff-no-range").args(["--layout", "per-eye"]).with_layer().env("STEREOSHIM_FAR_FIELD_ENABLED", "1").run();
    far.assert_ok();
    far.assert_layer_loaded(Half::Both);
    common::assert_same_captures("ff-no-range", &far, &plain);
    let lines = far.log_lines("far field not applied to an eye pass: no_depth_range");
    assert_eq!(lines.len(), 1, "want one log line:\n{}", far.log);
    let configured = Run::new("ff-configured-range")
        .args(["--layout", "per-eye"])
        .with_layer()
        .env("STEREOSHIM_FAR_FIELD_ENABLED", "1")
        .env("STEREOSHIM_FAR_FIELD_DEBUG", "1")
        .config("[far_field]\nnear_z = 0.05\nfar_z = 2000.0\n")
        .run();
    configured.assert_ok();
    let differing: usize = common::views_to_compare("ff-configured", &configured, 1, &plain, 1).iter().map(|(a, b)| configured.image(&a.file).count_different(&plain.image(&b.file))).sum();
    assert!(differing > 10_000, "the configured range did not apply the far field ({differing} tinted pixels):\n{}", configured.log);
}

/// `far_field.enabled = false` with the layer on: byte-identical captures.
#[test]
fn disabled_is_byte_identical() {
    for layout in ["per-eye", "multiview"] {
        let plain = Run::new(&format!("ff-off-{layout}-plain")).args(["--layout", layout, "--submit-depth"]).run();
        plain.assert_ok();
        let off = Run::new(&format!("ff-off-{layout}")).args(["--layout", layout, "--submit-depth"]).with_layer().env("STEREOSHIM_FAR_FIELD_ENABLED", "0").run();
        off.assert_ok();
        off.assert_layer_loaded(Half::Both);
        common::assert_same_captures(&format!("ff-off-{layout}"), &off, &plain);
    }
}

/// A multisampled intermediate target (4×, resolved into the swapchain image by the app): the
/// copies are multisampled, a source pixel counts as far only if all its samples are, and the
/// reused colour is the samples' mean. The app submits no depth here (the range comes from
/// config); near/far is classified from a single-sampled run of the same scene that submits depth,
/// leaving out pixels next to a depth edge (their samples straddle it).
#[test]
fn msaa_intermediate() {
    for layout in ["per-eye", "multiview"] {
        let name = format!("ff-msaa-{layout}");
        let frames = "3";
        let base = |n: &str| Run::new(&format!("{name}-{n}")).args(["--layout", layout, "--intermediate"]).env("MOCK_XR_EXIT_AFTER", frames).env("MOCK_XR_HEAD_YAW_DEG_PER_S", "20");
        let plain = base("plain").run();
        plain.assert_ok();
        let depth_ref = base("depth").args(["--samples", "1", "--submit-depth"]).run();
        depth_ref.assert_ok();
        let far = base("far")
            .with_layer()
            .env("STEREOSHIM_FAR_FIELD_ENABLED", "1")
            .env("STEREOSHIM_FAR_FIELD_SPLIT_M", "40")
            .config("[far_field]\nnear_z = 0.05\nfar_z = 2000.0\n")
            .run();
        far.assert_ok();
        far.assert_layer_loaded(Half::Both);
        let f = 2;
        let views = plain.views(f);
        let (src, dst) = (views.iter().find(|v| v.view == 0).unwrap(), views.iter().find(|v| v.view == 1).unwrap());
        let fviews = far.views(f);
        let far_src = fviews.iter().find(|v| v.view == 0).unwrap();
        common::image::assert_identical(&format!("{name}-source"), &far.image(&far_src.file), &plain.image(&src.file));
        let far_dst = fviews.iter().find(|v| v.view == 1).unwrap();
        let dref = depth_ref.views(f).into_iter().find(|v| v.view == 1).unwrap();
        let z = distances(&depth_ref.image(&dref.depth.as_ref().unwrap().file), dref);
        let (got, want) = (far.image(&far_dst.file), plain.image(&dst.file));
        let (w, h) = (want.width, want.height);
        let near_at = |x: u32, y: u32| z[(y * w + x) as usize] < 40.0;
        let (mut near, mut far_px) = (Vec::new(), Vec::new());
        for y in 1..h - 1 {
            for x in 1..w - 1 {
                let around: Vec<bool> = [(x - 1, y), (x + 1, y), (x, y - 1), (x, y + 1), (x, y)].iter().map(|&(a, b)| near_at(a, b)).collect();
                if around.iter().all(|n| *n) {
                    near.push((x, y));
                } else if around.iter().all(|n| !*n) {
                    far_px.push((x, y));
                }
            }
        }
        let differing = near.iter().filter(|&&(x, y)| got.pixel(x, y) != want.pixel(x, y)).count();
        assert_eq!(differing, 0, "{name}: {differing} of {} near pixels differ", near.len());
        let reused = far_px.iter().filter(|&&(x, y)| got.pixel(x, y) != want.pixel(x, y)).count();
        let p = psnr(&got, &want, &far_px);
        eprintln!("{name}: near {} far {} (differing {reused}) PSNR {p:.1} dB", near.len(), far_px.len());
        assert!(p >= 35.0, "{name}: far-pixel PSNR {p:.1} dB");
        let st = far.log_lines("far_field_views_reused=");
        assert!(st.iter().any(|l| !l.contains("far_field_views_reused=0")), "{name}: nothing reused:\n{}", far.log);
    }
}

/// Command buffers recorded once and resubmitted: the reuse draws' sources, poses and activity
/// are refreshed at every submission, so every frame whose recording saw its eyes matches the
/// reference — also the set recorded in the session's first frame, before the eyes were known
/// (xr-scene records one set per swapchain-image combination: frames 3 and 6 run the set of
/// frame 0, frames 4 and 5 those of frames 1 and 2).
#[test]
fn record_once() {
    for layout in ["per-eye", "multiview"] {
        for f in [4, 5, 6] {
            let mut case = Case::new(&format!("ff-record-once-{layout}-f{f}"), &["--layout", layout, "--record-once"]).env("MOCK_XR_HEAD_YAW_DEG_PER_S", "20").frame(f);
            case.previous_frame = layout == "multiview";
            check(case, 35.0);
        }
    }
}

/// Behind a post chain (the data-flow walk finds the eye passes in the tonemap's input, from the
/// third frame on): the source eye identical, the destination's near pixels identical and its
/// far pixels ≥ 35 dB after the tonemap, in every layout and behind a compute tonemap + copy;
/// per-eye reuses this frame's source, multiview and side by side the previous frame's (which the
/// walk had also traced).
#[test]
fn behind_a_post_chain() {
    let cases = [("per-eye", "dynamic", "standard", None), ("multiview", "render-pass2", "reverse", None), ("side-by-side", "render-pass", "standard", None), ("per-eye", "render-pass", "reverse", Some("--post-compute"))];
    for (layout, rendering, depth, compute) in cases {
        let previous = layout != "per-eye";
        let mut args = vec!["--post", "tonemap", "--layout", layout, "--rendering", rendering, "--depth", depth];
        args.extend(compute);
        let tag = if compute.is_some() { "-compute" } else { "" };
        let mut case = Case::new(&format!("ff-post-{layout}-{rendering}-{depth}{tag}"), &args).frame(if previous { 4 } else { 3 });
        if previous {
            case = case.env("MOCK_XR_HEAD_YAW_DEG_PER_S", "20");
        }
        case.previous_frame = previous;
        let (plain, far) = case.run();
        let src_frame = if previous { case.frame - 1 } else { case.frame };
        let out = analyse(&case.analysis(), &plain, &far, case.frame, 1, 0, src_frame);
        judge(&case, &out, 35.0);
        assert!(!far.log_lines("data-flow walk: colour target").is_empty(), "{}: not traced:\n{}", case.name, far.log);
    }
}
