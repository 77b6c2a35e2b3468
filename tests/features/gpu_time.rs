//! The layer's GPU frame timer (`stats.gpu_time`), end to end on lavapipe: with it on, every frame
//! of xr-scene's `stats.file` carries a plausible `gpu_ms` (after warm-up: busy > 0, busy ≤ span)
//! that includes the layer's own work (RDM's reconstruction is a submission of the layer's: busy
//! covers at least the app's own timestamped command buffer, and there are more submissions than
//! the app's one per frame); with it off, nothing of it reaches the driver or the file. Validation
//! (with synchronization validation) stays silent either way.

use crate::common;

use common::{Half, Run};

const FRAMES: u64 = 8;

/// xr-scene with RDM on (so the layer submits work of its own every frame), through the layer,
/// writing `stats.file`; `gpu_time`: the timer's setting.
fn run(name: &str, gpu_time: bool, args: &[&str]) -> (common::RunOutput, Vec<serde_json::Value>) {
    run_env(name, gpu_time, args, &[])
}

fn run_env(name: &str, gpu_time: bool, args: &[&str], env: &[(&str, &str)]) -> (common::RunOutput, Vec<serde_json::Value>) {
    let stats = common::target_dir().join("test-output").join(format!("{name}.layer-stats.jsonl"));
    let _ = std::fs::remove_file(&stats);
    let out = Run::new(name)
        .args(["--layout", "per-eye", "--rendering", "render-pass"])
        .args(args.iter().copied())
        .with_layer()
        .env("MOCK_XR_EXIT_AFTER", &FRAMES.to_string())
        .env("MOCK_XR_EYE_TRACKER", "0")
        .env("STEREOSHIM_FOVEATION_ENABLED", "1")
        .env("STEREOSHIM_FOVEATION_METHOD", "rdm")
        .env("STEREOSHIM_FOVEATION_EYE_TRACKING", "off")
        .env("STEREOSHIM_STATS_GPU_TIME", if gpu_time { "true" } else { "false" })
        .env("STEREOSHIM_STATS_FILE", stats.to_str().unwrap());
    let out = env.iter().fold(out, |r, (k, v)| r.env(k, v)).run();
    out.assert_ok();
    out.assert_layer_loaded(Half::Both);
    out.assert_log_lacks(Half::Both, "internal failure");
    let records = std::fs::read_to_string(&stats)
        .unwrap_or_else(|e| panic!("{name}: no stats.file: {e}\n{}", out.log))
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    (out, records)
}

#[test]
fn every_frame_has_its_gpu_time_including_the_layers_work() {
    let (out, records) = run("gpu-time-on", true, &[]);
    check_timed(&out, &records);
}

/// The `vkQueueSubmit2` hook, with several frames in flight (`--record-once` does not wait for a
/// frame before recording the next): results come back late and still land on their frames.
#[test]
fn submit2_with_frames_in_flight() {
    let (out, records) = run("gpu-time-submit2", true, &["--submit2", "--record-once"]);
    check_timed(&out, &records);
}

fn check_timed(out: &common::RunOutput, records: &[serde_json::Value]) {
    let frames: Vec<u64> = records.iter().map(|r| r["frame"].as_u64().unwrap()).collect();
    assert_eq!(frames, (0..FRAMES).collect::<Vec<_>>(), "one line per frame, in order:\n{records:#?}");
    let app = out.stats.as_ref().expect("xr-scene --stats");
    assert!(!out.log_lines("gpu time: timing the submissions of queue").is_empty(), "{}", out.log);
    out.assert_log_lacks(Half::Both, " WARN ");
    for r in records {
        let n = r["frame"].as_u64().unwrap();
        let g = &r["gpu_ms"];
        assert!(g.is_object(), "frame {n}: no gpu_ms: {r}");
        // Frame 0 renders before the layer knows the eyes (no RDM yet) and creates everything.
        if n < 2 {
            continue;
        }
        let (busy, span) = (g["busy"].as_f64().unwrap(), g["span"].as_f64().unwrap());
        let submissions = g["submissions"].as_u64().unwrap();
        assert!(busy > 0.0 && busy <= span + 1e-9, "frame {n}: busy {busy} ms, span {span} ms: {r}");
        assert_eq!(g["untimed"].as_u64(), Some(0), "frame {n}: {r}");
        // The app submits one command buffer per frame; RDM reconstructs each released eye image
        // in a submission of the layer's.
        let reconstructed: u64 = r["rdm"]["reconstructed"].as_object().map_or(0, |m| m.values().filter_map(|v| v.as_u64()).sum());
        assert!(reconstructed > 0, "frame {n}: RDM reconstructed nothing: {r}");
        assert!(submissions > 1, "frame {n}: the layer's reconstruction was not timed ({submissions} submissions): {r}");
        let own = app.frames.iter().find(|f| f.frame == n).unwrap_or_else(|| panic!("xr-scene has no frame {n}")).gpu_time_ms;
        assert!(own > 0.0, "frame {n}: xr-scene timed nothing");
        // The app's timestamps are inside the layer's bracket of the same submission.
        assert!(busy >= own, "frame {n}: the layer's busy time {busy} ms is below the app's own {own} ms: {r}");
    }
    let device = out.log_lines("vulkan device stats:");
    assert!(device.iter().any(|l| l.contains("gpu_timed=") && l.contains("gpu_untimed=0")), "{device:?}");
}

#[test]
fn off_adds_no_query_no_submission_and_no_field() {
    let (off, records) = run("gpu-time-off", false, &[]);
    assert_eq!(records.len() as u64, FRAMES);
    assert!(records.iter().all(|r| r.get("gpu_ms").is_none()), "{records:#?}");
    off.assert_log_lacks(Half::Both, "gpu time");
    let device = off.log_lines("vulkan device stats:");
    assert!(!device.is_empty() && device.iter().all(|l| !l.contains("gpu_timed")), "{device:?}");
    // Timing changes nothing the app renders.
    let (on, _) = run("gpu-time-on-captures", true, &[]);
    common::assert_same_captures("gpu time on vs off", &off, &on);
    common::assert_same_stats("gpu time on vs off", &off, &on);
}

/// A timer that cannot be set up stops, says so once, and leaves the app alone: every line says
/// `"gpu_ms": null`, the frames are the same as without it.
#[test]
fn a_failing_timer_stops_and_changes_nothing_else() {
    let (out, records) = run_env("gpu-time-failing", true, &[], &[("STEREOSHIM_DEBUG_FAIL_IN", "stats.gpu_time")]);
    assert_eq!(records.len() as u64, FRAMES);
    assert!(records.iter().all(|r| r["gpu_ms"].is_null()), "{records:#?}");
    let failed = out.log_lines("no more GPU times on this device");
    assert_eq!(failed.len(), 1, "logged once:\n{}", out.log);
    let (off, _) = run("gpu-time-failing-off", false, &[]);
    common::assert_same_captures("failing gpu time vs off", &off, &out);
}

/// The far field's one-time set-up (slot image layouts, the first reset of new query pools) goes
/// at the head of the app's first batch (`VkFeature::queue_submitting`), inside the app's timed
/// submission: with the far field on, every frame is timed and counts as many submissions as
/// without it. That the set-up did run is validation's part (on in every run): a slot copied
/// into in an undefined layout or a query begun without a reset is an error there.
#[test]
fn the_far_fields_setup_rides_in_the_apps_submission() {
    let submissions = |name: &str, far_field: bool| {
        let stats = common::target_dir().join("test-output").join(format!("{name}.layer-stats.jsonl"));
        let _ = std::fs::remove_file(&stats);
        let out = Run::new(name)
            .args(["--submit-depth"])
            .with_layer()
            .env("MOCK_XR_EXIT_AFTER", &FRAMES.to_string())
            .env("STEREOSHIM_FAR_FIELD_ENABLED", if far_field { "1" } else { "0" })
            .env("STEREOSHIM_STATS_GPU_TIME", "true")
            .env("STEREOSHIM_STATS_FILE", stats.to_str().unwrap())
            .run();
        out.assert_ok();
        out.assert_log_lacks(Half::Both, "internal failure");
        // The set-up exists only where the far field made its slots.
        assert_eq!(out.log.contains("far field source slots created"), far_field, "{name}:\n{}", out.log);
        let records: Vec<serde_json::Value> = std::fs::read_to_string(&stats).unwrap().lines().map(|l| serde_json::from_str(l).unwrap()).collect();
        assert_eq!(records.len() as u64, FRAMES, "{name}");
        for r in &records {
            let g = &r["gpu_ms"];
            let (busy, span) = (g["busy"].as_f64().unwrap_or(-1.0), g["span"].as_f64().unwrap_or(-1.0));
            assert!(busy > 0.0 && busy <= span + 1e-9 && g["untimed"] == 0, "{name}: {r}");
        }
        records.iter().map(|r| r["gpu_ms"]["submissions"].as_u64().unwrap()).collect::<Vec<u64>>()
    };
    let (off, on) = (submissions("gpu-time-no-far-field", false), submissions("gpu-time-far-field", true));
    assert_eq!(on, off, "no submission of the layer's own for the set-up: {on:?} vs {off:?}");
}
