//! Where the hidden-area mask comes from, end to end: the runtime's `XR_KHR_visibility_mask`
//! (enabled by the layer for itself, hidden from the app), a synthesized lens when the runtime has
//! none, and a re-fetch when the runtime says the mask changed.

use crate::common;

use common::{Half, Run};

/// The layer's "enabled [...] for the layer's own use" log lines that name `extension` (it may enable
/// others with it, e.g. XR_EXT_eye_gaze_interaction).
fn enabled_for_itself(out: &common::RunOutput, extension: &str) -> usize {
    out.log_lines("for the layer's own use").iter().filter(|l| l.contains(&format!("\"{extension}\""))).count()
}

fn masked(name: &str) -> Run {
    Run::new(name).with_layer().env("STEREOSHIM_MASK_ENABLED", "1").env("MOCK_XR_EXIT_AFTER", "3")
}

#[test]
fn runtime_mask_is_used_when_present() {
    let out = masked("mask-source-runtime").run();
    out.assert_ok();
    assert_eq!(enabled_for_itself(&out, "XR_KHR_visibility_mask"), 1, "{}", out.log);
    assert_eq!(out.log_lines("hidden-area mask from Runtime").len(), 2, "{}", out.log);
}

#[test]
fn synthesized_mask_when_the_runtime_has_none() {
    let out = masked("mask-source-synthesized").env("MOCK_XR_DISABLE_EXTENSIONS", "XR_KHR_visibility_mask").run();
    out.assert_ok();
    // The layer asks only for extensions the runtime lists: this one is not even requested.
    assert_eq!(enabled_for_itself(&out, "XR_KHR_visibility_mask"), 0, "{}", out.log);
    assert_eq!(out.log_lines("hidden-area mask from Synthesized").len(), 2, "{}", out.log);

    let out = masked("mask-source-forced-synthesized").env("STEREOSHIM_MASK_SOURCE", "synthesized").run();
    out.assert_ok();
    assert_eq!(out.log_lines("hidden-area mask from Synthesized").len(), 2, "{}", out.log);

    let out = masked("mask-source-runtime-only")
        .env("MOCK_XR_DISABLE_EXTENSIONS", "XR_KHR_visibility_mask")
        .env("STEREOSHIM_MASK_SOURCE", "runtime")
        .run();
    out.assert_ok();
    assert_eq!(out.log_lines("no hidden-area mask").len(), 2, "{}", out.log);
}

#[test]
fn mask_change_event_refetches_and_stays_hidden() {
    let out = masked("mask-source-change").env("MOCK_XR_VISIBILITY_MASK_CHANGE_AT", "1").run();
    out.assert_ok();
    assert_eq!(out.log_lines("visibility mask of view").len(), 2, "{}", out.log);
    // Fetched at the start and once more after the change.
    assert_eq!(out.log_lines("hidden-area mask from Runtime").len(), 4, "{}", out.log);
    let stats = out.log_lines("openxr stats:");
    assert_eq!(stats.len(), 1, "{}", out.log);
    assert!(stats[0].contains("visibility_mask_events=2"), "{}", stats[0]);
}

/// With the mask off nothing is fetched; the extension is still enabled (hidden), so the mask can
/// be switched on while the app runs.
#[test]
fn mask_disabled_fetches_nothing() {
    let out = Run::new("mask-source-off").with_layer().run();
    out.assert_ok();
    assert_eq!(out.log_lines("for the layer's own use").len(), 1, "{}", out.log);
    out.assert_log_lacks(Half::OpenXr, "hidden-area mask");
}

/// A mask change reaches the pixels: after the runtime shrinks the visible area, later frames are
/// masked with the new mesh, and the layer's per-frame statistics (`stats.file`) show it.
#[test]
fn changed_mask_is_applied_to_later_frames() {
    let dir = common::output_dir("mask-change-stats");
    let stats_file = dir.join("layer-stats.jsonl");
    let out = masked("mask-change-applied")
        .env("MOCK_XR_EXIT_AFTER", "4")
        .env("MOCK_XR_VISIBILITY_MASK_CHANGE_AT", "2")
        .env("STEREOSHIM_STATS_FILE", stats_file.to_str().unwrap())
        .run();
    out.assert_ok();
    let records: Vec<serde_json::Value> =
        std::fs::read_to_string(&stats_file).unwrap().lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    assert_eq!(records.len(), 4, "one stats record per frame");
    let pixels = |f: usize| -> u64 { records[f]["pixels_masked"].as_object().unwrap().values().map(|v| v.as_u64().unwrap()).sum() };
    assert_eq!(pixels(0), 0, "frame 0 cannot be masked yet (eye uses unknown)");
    assert!(pixels(1) > 0 && pixels(3) > pixels(1), "masked pixels per frame: {records:?}");
    assert!(records.iter().all(|r| r["mask_enabled"] == true));

    for frame in [1u64, 3] {
        let masks = &out.frame(frame).visibility_masks;
        for v in out.views(frame) {
            let mask = &masks.iter().find(|m| m.view == v.view).expect("mask").hidden_triangles;
            let (w, h) = (v.image_rect.width, v.image_rect.height);
            let hidden = common::hidden_pixels(mask, &v.fov, w, h);
            let edge = common::mask_edge_pixels(mask, &v.fov, w, h, 1.0);
            let img = out.image(&v.file);
            let wrong = (0..w * h)
                .filter(|&i| hidden[i as usize] && !edge[i as usize])
                .filter(|&i| img.pixel(i % w, i / w).iter().any(|&c| c != 0))
                .count();
            assert_eq!(wrong, 0, "frame {frame} view {}: {wrong} hidden pixels not masked", v.view);
            let hidden_count = hidden.iter().filter(|&&b| b).count() as u64;
            let layer_count = records[frame as usize]["pixels_masked"][v.view.to_string()].as_u64().unwrap();
            assert!(hidden_count.abs_diff(layer_count) * 100 <= hidden_count, "frame {frame}: layer {layer_count}, harness {hidden_count}");
        }
    }
}

/// A runtime without `XR_KHR_visibility_mask` (WiVRn, SteamVR's for some headsets): the layer lists
/// the extension beside the runtime's (its manifest's `instance_extensions`), keeps it away from
/// the runtime, and answers `xrGetVisibilityMaskKHR` itself with the lens it knows (the
/// headset's published one, else `mask.synthesized.*`), the layer's own mask on or off. What an OpenVR game's
/// `GetHiddenAreaMesh` gets through xrizer. Without the layer the app finds no extension.
#[test]
fn the_layer_offers_the_visibility_mask_the_runtime_lacks() {
    let base = Run::new("mask-offered-plain").args(["--visibility-mask"]).env("MOCK_XR_DISABLE_EXTENSIONS", "XR_KHR_visibility_mask").env("MOCK_XR_EXIT_AFTER", "3");
    let plain = base.clone().run();
    assert_ne!(plain.code, Some(0), "the app found the extension without the layer:\n{}", plain.stderr);
    assert!(plain.stderr.contains("does not offer XR_KHR_visibility_mask"), "{}", plain.stderr);
    for (name, mask_on) in [("mask-offered-layer", false), ("mask-offered-with-mask", true)] {
        let mut run = base.clone().with_layer().env("STEREOSHIM_MASK_ENABLED", if mask_on { "1" } else { "0" });
        run.name = name.into();
        let out = run.run();
        out.assert_ok();
        out.assert_layer_loaded(Half::OpenXr);
        assert_eq!(out.log_lines("which the app enabled: the layer implements them").len(), 1, "{}", out.log);
        // Both views: the synthesized lens's ring, 2 triangles per outline segment, hiding a
        // real part of the view.
        let lines: Vec<&str> = out.stderr.lines().filter(|l| l.starts_with("xr-scene: visibility mask view")).collect();
        assert_eq!(lines.len(), 2, "{}", out.stderr);
        for l in &lines {
            assert!(l.contains(": 128 triangles,"), "{l}");
            let area: f64 = l.rsplit(' ').next().unwrap().parse().unwrap();
            assert!(area > 1.0, "{l}");
        }
        if mask_on {
            assert_eq!(out.log_lines("hidden-area mask from Synthesized").len(), 2, "{}", out.log);
        }
    }
    // The layer switched off by its config: the manifest listed the extension all the same, so
    // the app still gets its instance and the mask.
    let mut run = base.clone().with_layer().env("STEREOSHIM_ENABLED", "false");
    run.name = "mask-offered-layer-off".into();
    let out = run.run();
    out.assert_ok();
    assert_eq!(out.stderr.lines().filter(|l| l.starts_with("xr-scene: visibility mask view")).count(), 2, "{}", out.stderr);
    // A headset with a published lens (the mock's Index): the app gets that lens instead, as the
    // runtime that has the extension would give it (the mock's own mesh, 60 and 59 triangles).
    let mut run = base.with_layer().env("MOCK_XR_HMD", "index");
    run.name = "mask-offered-index".into();
    let out = run.run();
    out.assert_ok();
    let lines: Vec<&str> = out.stderr.lines().filter(|l| l.starts_with("xr-scene: visibility mask view")).collect();
    assert!(lines.len() == 2 && lines[0].contains(": 60 triangles,") && lines[1].contains(": 59 triangles,"), "{}", out.stderr);
}

/// A runtime that answers with Monado's generic mask (the four corners cut, ~3 % of the view,
/// whatever the lens: WiVRn's streamed headsets get it) for a headset the layer knows (the mock's
/// Index): the layer recognises it and masks with the Index's published lens instead, logged;
/// `mask.source = runtime` keeps the runtime's; a headset whose lens is not published (the
/// mock's synthetic one) keeps the runtime's generic mask too.
#[test]
fn a_generic_runtime_mask_gives_way_to_the_headsets_lens() {
    let run = |name: &str, hmd: &str, source: &str| {
        masked(name).env("MOCK_XR_VISIBILITY_MASK", "generic").env("MOCK_XR_HMD", hmd).env("STEREOSHIM_MASK_SOURCE", source).run()
    };
    let out = run("mask-source-generic-index", "index", "auto");
    out.assert_ok();
    assert_eq!(out.log_lines("Monado's generic one").len(), 2, "{}", out.log);
    assert_eq!(out.log_lines("hidden-area mask from Headset").len(), 2, "{}", out.log);
    let out = run("mask-source-generic-index-runtime", "index", "runtime");
    out.assert_ok();
    assert_eq!(out.log_lines("hidden-area mask from Runtime, 4 triangles").len(), 2, "{}", out.log);
    let out = run("mask-source-generic-simple", "simple", "auto");
    out.assert_ok();
    assert_eq!(out.log_lines("the layer knows no published lens for this headset").len(), 2, "{}", out.log);
    assert_eq!(out.log_lines("hidden-area mask from Runtime, 4 triangles").len(), 2, "{}", out.log);
}
