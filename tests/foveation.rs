//! End-to-end checks of foveation method 2, radial density masking: xr-scene runs through the layer
//! with `foveation.enabled`, `foveation.method = rdm`, and frame 1 (frame 0 renders before the
//! OpenXR half saw an eye use) is compared with a run without the layer:
//! - pixels of quads the rule keeps are bit-identical, and so — computed independently here, in
//!   f64 from frames.json's FOV and the preset's angle — is every pixel well inside the inner ring;
//! - the skipped quads are reconstructed: periphery PSNR is reported (and ≥ 30 dB for `balanced`);
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

mod common;

use common::image;
use common::{Fov, Half, Run, RunOutput};
use stereoshim::core::rect::PixelRect;
use stereoshim::features::foveation::rdm::rules::RdmParams;
use stereoshim::shared::{FoveaView, ViewFov};

/// With the hidden-area mask: how far from its outline the periphery PSNR starts (the filter reads
/// up to 2 px beyond a skipped quad).
const MASK_MARGIN_PX: f64 = 3.0;

fn preset(name: &str) -> (f32, f32) {
    match name {
        "subtle" => (30.0, 45.0),
        "aggressive" => (12.0, 25.0),
        _ => (20.0, 35.0),
    }
}

/// The layer's tangents: f32 `tan` of the submitted f32 angles (src/xr/session.rs fov_tangents).
fn view_fov(f: &Fov) -> ViewFov {
    ViewFov { tan_left: f.angle_left.tan(), tan_right: f.angle_right.tan(), tan_up: f.angle_up.tan(), tan_down: f.angle_down.tan() }
}

/// Angle (degrees) between the fovea centre direction (a tangent-plane point; (0, 0) is the optical
/// axis) and the view direction through image point (px, py) of a `w` × `h` rect (pixels, y down),
/// in f64 — independent of the layer's f32 rule.
fn angle_deg(f: &Fov, w: u32, h: u32, px: f64, py: f64, center: [f32; 2]) -> f64 {
    let (l, r) = ((f.angle_left as f64).tan(), (f.angle_right as f64).tan());
    let (u, d) = ((f.angle_up as f64).tan(), (f.angle_down as f64).tan());
    let tx = l + px / w as f64 * (r - l);
    let ty = u - py / h as f64 * (u - d);
    let (cx, cy) = (center[0] as f64, center[1] as f64);
    let dot = tx * cx + ty * cy + 1.0;
    let norms = (tx * tx + ty * ty + 1.0).sqrt() * (cx * cx + cy * cy + 1.0).sqrt();
    (dot / norms).clamp(-1.0, 1.0).acos().to_degrees()
}

pub struct ViewResult {
    pub view: u32,
    pub pixels: u64,
    pub skipped: u64,
    pub shaded_drop: i64,
    /// The plain run's fragments at the pixels the rule skips (`--pixel-stats`).
    pub skipped_fragments: i64,
    /// Plain run's fragments beyond one per pixel.
    pub overdraw: i64,
    pub psnr_db: f64,
}

fn psnr(pairs: &[(f64, f64)]) -> f64 {
    if pairs.is_empty() {
        return f64::INFINITY;
    }
    let mse = pairs.iter().map(|(a, b)| (a - b) * (a - b)).sum::<f64>() / pairs.len() as f64;
    if mse == 0.0 {
        f64::INFINITY
    } else {
        10.0 * (255.0f64 * 255.0 / mse).log10()
    }
}

fn layer_stats(out: &RunOutput, path: &std::path::Path, frame: u64) -> serde_json::Value {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: no stats.file {}: {e}\n{}", out.name, path.display(), out.log));
    text.lines()
        .map(|l| serde_json::from_str::<serde_json::Value>(l).expect("stats line parses"))
        .find(|v| v["frame"] == frame)
        .unwrap_or_else(|| panic!("{}: no layer stats for frame {frame}", out.name))
}

/// Runs one configuration with and without the layer and checks frame 1; returns per-view numbers.
pub fn check(name: &str, args: &[&str], preset_name: &str, extra_env: &[(&str, &str)]) -> Vec<ViewResult> {
    check_with(name, args, preset_name, extra_env, false)
}

/// `with_mask`: both runs go through the layer with the hidden-area mask on (the baseline is the
/// mask alone), so RDM is judged on top of it.
pub fn check_with(name: &str, args: &[&str], preset_name: &str, extra_env: &[(&str, &str)], with_mask: bool) -> Vec<ViewResult> {
    // With `MOCK_XR_GAZE=yaw,pitch` among the env, the fovea follows that gaze (eye tracking on);
    // otherwise there is no eye tracker and the fovea sits on the optical axis.
    let gaze: Option<(f64, f64)> = extra_env.iter().find(|(k, _)| *k == "MOCK_XR_GAZE").map(|(_, v)| {
        let (y, p) = v.split_once(',').expect("yaw,pitch");
        (y.trim().parse().unwrap(), p.trim().parse().unwrap())
    });
    let mut base = Run::new(name).args(args.iter().copied()).pixel_stats();
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
    rdm.assert_log_lacks(Half::Both, "internal failure");
    assert!(!rdm.log_lines("radial density masking ").is_empty(), "{name}: the layer never applied RDM:\n{}", rdm.log);
    // Frame 0: eye uses unknown, nothing skipped.
    common::assert_same_frame(&format!("{name}-f0"), &rdm, 0, &plain, 0);
    let (mut inner_deg, mut middle_deg) = preset(preset_name);
    // Explicit angles override the preset (as the layer's config does).
    for (k, v) in extra_env {
        match *k {
            "STEREOSHIM_FOVEATION_INNER_DEG" => inner_deg = v.parse().unwrap(),
            "STEREOSHIM_FOVEATION_MIDDLE_DEG" => middle_deg = v.parse().unwrap(),
            _ => {}
        }
    }
    let stats1 = layer_stats(&rdm, &stats_path, 1);
    let mut out = Vec::new();
    for (a, b) in common::views_to_compare(name, &rdm, 1, &plain, 1) {
        let (w, h) = (a.image_rect.width, a.image_rect.height);
        // The gaze direction of the mock runtime (yaw right, pitch up) as a tangent-plane point of
        // these parallel views: (tan yaw, tan pitch / cos yaw).
        let center = gaze.map_or([0.0, 0.0], |(yaw, pitch)| {
            let (yaw, pitch) = (yaw.to_radians(), pitch.to_radians());
            [yaw.tan() as f32, (pitch.tan() / yaw.cos()) as f32]
        });
        let fovea = FoveaView { view: a.view, center, inner_deg, middle_deg };
        let params = RdmParams::new(&view_fov(&a.fov), &fovea, PixelRect { x: 0, y: 0, width: w, height: h }).expect("params");
        let (got, want) = (rdm.image(&a.file), plain.image(&b.file));
        // With the mask, its hidden area is never shown, and skipped quads along its outline are
        // reconstructed partly from the hidden (black) side: PSNR counts the visible periphery
        // from MASK_MARGIN_PX inwards.
        let lens_hidden: Vec<bool> = if with_mask {
            let frame = rdm.frame(1);
            let mask = &frame.visibility_masks.iter().find(|m| m.view == a.view).expect("mask of view").hidden_triangles;
            let hidden = common::hidden_pixels(mask, &a.fov, w, h);
            let edge = common::mask_edge_pixels(mask, &a.fov, w, h, MASK_MARGIN_PX);
            hidden.iter().zip(&edge).map(|(a, b)| *a || *b).collect()
        } else {
            vec![false; (w * h) as usize]
        };
        let plain_counts = plain.pixel_counts(1, b.view);
        let mut bad = Vec::new();
        let (mut skipped, mut periphery) = (0u64, Vec::new());
        // Σ over the pixels the rule skips of the plain run's fragments there.
        let mut skipped_fragments = 0i64;
        for y in 0..h {
            for x in 0..w {
                let (g, e) = (&got.pixel(x, y)[..3], &want.pixel(x, y)[..3]);
                let is_skipped = params.pixel_skipped(x as i32, y as i32);
                skipped += is_skipped as u64;
                if is_skipped {
                    skipped_fragments += plain_counts[(y * w + x) as usize] as i64;
                }
                // Independently: the whole quad, grown by a pixel, lies inside the inner ring.
                let (qx, qy) = ((x / 2 * 2) as f64, (y / 2 * 2) as f64);
                let deep_inside = [(qx - 1.0, qy - 1.0), (qx + 3.0, qy - 1.0), (qx - 1.0, qy + 3.0), (qx + 3.0, qy + 3.0)]
                    .iter()
                    .all(|&(px, py)| angle_deg(&a.fov, w, h, px, py, center) < inner_deg as f64);
                if deep_inside && g != e {
                    bad.push((x, y, "inner ring"));
                } else if !is_skipped && g != e {
                    bad.push((x, y, "kept quad"));
                }
                if !deep_inside && !lens_hidden[(y * w + x) as usize] {
                    periphery.extend(g.iter().zip(e).map(|(&p, &q)| (p as f64, q as f64)));
                }
            }
        }
        if !bad.is_empty() {
            let dir = image::artifacts_dir(&format!("{name}-view{}", a.view));
            got.save(&dir.join("actual.png"));
            want.save(&dir.join("expected.png"));
            image::difference(&got, &want).save(&dir.join("difference.png"));
            panic!("{name} view {}: {} wrong pixels, first {:?}; artifacts in {}", a.view, bad.len(), &bad[..bad.len().min(8)], dir.display());
        }
        let shaded = |o: &RunOutput| {
            let f = o.stats.as_ref().expect("stats").frames.iter().find(|f| f.frame == 1).expect("stats of frame 1");
            f.views.iter().find(|v| v.view == a.view).expect("view stats").shaded_fragments as i64
        };
        let overdraw = (shaded(&plain) - (w as i64 * h as i64)).max(0);
        let r = ViewResult {
            view: a.view,
            pixels: w as u64 * h as u64,
            skipped,
            shaded_drop: shaded(&plain) - shaded(&rdm),
            skipped_fragments,
            overdraw,
            psnr_db: psnr(&periphery),
        };
        // The layer's own count of frame 1 (rdm.pixels_skipped, summed over its passes) is the
        // rule's count over the eye's rect.
        let layer_px = stats1["rdm"]["pixels_skipped"][a.view.to_string()].as_u64().unwrap_or(0);
        assert_eq!(layer_px, skipped, "{name} view {}: layer stats {}", a.view, stats1);
        assert_eq!(stats1["rdm"]["reconstructed"][a.view.to_string()].as_u64(), Some(1), "{name} view {}: {}", a.view, stats1);
        eprintln!(
            "{name} [{preset_name}] view {}: {}x{} px, skipped {} px ({:.1} %, {} plain fragments), shaded fragments -{} (plain {}), periphery PSNR {:.2} dB",
            a.view,
            w,
            h,
            r.skipped,
            100.0 * r.skipped as f64 / r.pixels as f64,
            r.skipped_fragments,
            r.shaded_drop,
            shaded(&plain),
            r.psnr_db
        );
        out.push(r);
    }
    for r in &out {
        assert!(r.skipped > 0, "{name} view {}: nothing skipped", r.view);
        // Every skipped pixel had at least one fragment (xr-scene covers every pixel) and loses
        // all of them; kept pixels keep theirs. (Behind the mask, skipped pixels had none.)
        assert!(with_mask || r.shaded_drop >= r.skipped as i64, "{name} view {}: shaded fragments dropped by {} but {} pixels were skipped", r.view, r.shaded_drop, r.skipped);
        assert!(
            r.shaded_drop <= r.skipped as i64 + r.overdraw,
            "{name} view {}: shaded fragments dropped by {}, more than the {} skipped pixels plus all {} overdraw fragments",
            r.view,
            r.shaded_drop,
            r.skipped,
            r.overdraw
        );
        // Exact: the skipped pixels lose every fragment they had in the plain run, the kept ones
        // keep all of theirs.
        assert_eq!(
            r.shaded_drop, r.skipped_fragments,
            "{name} view {}: shaded fragments dropped by {}, but the skipped pixels had {} fragments in the plain run",
            r.view, r.shaded_drop, r.skipped_fragments
        );
        if preset_name == "balanced" {
            assert!(r.psnr_db >= 30.0, "{name} view {}: periphery PSNR {:.2} dB < 30", r.view, r.psnr_db);
        }
    }
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
