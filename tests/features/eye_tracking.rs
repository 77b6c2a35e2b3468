//! Eye-tracked foveation without the app knowing: the layer attaches its own gaze action set to
//! the app's session, the fovea follows the mock runtime's gaze, falls back to the optical axis
//! without a gaze, and the app's own actions keep working.

use crate::common;

use common::{Half, Run};

/// Runs xr-scene with foveation on and returns the layer's per-frame records.
fn run(name: &str, env: &[(&str, &str)]) -> (common::RunOutput, Vec<serde_json::Value>) {
    let stats = common::output_dir(&format!("{name}-stats")).join("layer.jsonl");
    let mut r = Run::new(name)
        .with_layer()
        .env("STEREOSHIM_FOVEATION_ENABLED", "1")
        .env("STEREOSHIM_STATS_FILE", stats.to_str().unwrap())
        .env("MOCK_XR_EXIT_AFTER", "4");
    for (k, v) in env {
        r = r.env(k, v);
    }
    let out = r.run();
    let records = std::fs::read_to_string(&stats)
        .unwrap_or_default()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    (out, records)
}

fn center(record: &serde_json::Value, view: usize) -> [f64; 2] {
    let c = &record["fovea"][view]["center"];
    [c[0].as_f64().unwrap(), c[1].as_f64().unwrap()]
}

#[test]
fn fovea_follows_the_gaze() {
    let (out, records) = run("gaze-tracked", &[("MOCK_XR_GAZE", "10,5")]);
    out.assert_ok();
    assert_eq!(out.log_lines("gaze action set is attached").len(), 1, "{}", out.log);
    let last = records.last().expect("records");
    assert_eq!(last["fovea_source"], "Gaze", "{last}");
    // Yaw 10° right, pitch 5° up, parallel views of the simple HMD: the gaze direction's tangent
    // point (tan yaw, tan pitch / cos yaw), the same in both eyes.
    let (yaw, pitch) = (10f64.to_radians(), 5f64.to_radians());
    let want = [yaw.tan(), pitch.tan() / yaw.cos()];
    for view in 0..2 {
        let c = center(last, view);
        assert!((c[0] - want[0]).abs() < 1e-3 && (c[1] - want[1]).abs() < 1e-3, "view {view}: {c:?}, want {want:?}");
    }
    assert_eq!(last["fovea"][0]["inner_deg"], 20.0, "balanced preset");
}

#[test]
fn canted_views_see_the_gaze_in_their_own_frame() {
    let (out, records) = run("gaze-canted", &[("MOCK_XR_GAZE", "0,0"), ("MOCK_XR_HMD", "pimax")]);
    out.assert_ok();
    let last = records.last().unwrap();
    // Straight ahead is 10° to the right of the left view's axis and 10° left of the right's.
    let (l, r) = (center(last, 0), center(last, 1));
    assert!((l[0] - 10f64.to_radians().tan()).abs() < 1e-3 && (r[0] + 10f64.to_radians().tan()).abs() < 1e-3, "{l:?} {r:?}");
}

#[test]
fn no_gaze_means_the_optical_axis() {
    for (name, env) in [
        ("gaze-not-tracking", vec![]),
        ("gaze-no-tracker", vec![("MOCK_XR_EYE_TRACKER", "0")]),
        ("gaze-tracking-off", vec![("MOCK_XR_GAZE", "10,5"), ("STEREOSHIM_FOVEATION_EYE_TRACKING", "off")]),
        ("gaze-runtime-lacks-it", vec![("MOCK_XR_GAZE", "10,5"), ("MOCK_XR_DISABLE_EXTENSIONS", "XR_EXT_eye_gaze_interaction")]),
    ] {
        let (out, records) = run(name, &env);
        out.assert_ok();
        let last = records.last().unwrap();
        assert_eq!(last["fovea_source"], "Fixed", "{name}: {last}");
        assert_eq!(center(last, 0), [0.0, 0.0], "{name}");
    }
}

/// The app's own input still works with the layer's action set attached beside it.
#[test]
fn app_actions_still_work() {
    let (out, _) = run("gaze-app-actions", &[("MOCK_XR_GAZE", "10,5"), ("MOCK_XR_EXIT_AFTER", "1000"), ("MOCK_XR_MENU_CLICK_AT", "2")]);
    out.assert_ok();
    assert_eq!(out.log_lines("gaze action set is attached").len(), 1, "{}", out.log);
    let last = out.frames().frames.last().expect("frames").frame;
    assert!(last < 10, "the app's quit action did not work: ran {last} frames");
}

#[test]
fn foveation_off_attaches_nothing() {
    let out = Run::new("gaze-foveation-off").with_layer().env("MOCK_XR_GAZE", "10,5").run();
    out.assert_ok();
    out.assert_log_lacks(Half::OpenXr, "gaze action set");
}
