//! The harness's own checks, on synthetic data (no app is run): a comparison of two runs' captures
//! fails when the runs differ in frames, views, image sizes or depth, or captured nothing; an
//! assertion that a line is absent from the layer's log fails when the layer never loaded.

use crate::common;

use common::image::Image;
use common::{layer_loaded, log_lacks, pair_captures, pair_frame, DepthCheck, Frames, Half, RunOutput};
use serde_json::json;

/// One view of a synthetic capture: id, image size, whether depth was submitted.
type ViewSpec = (u32, (u32, u32), bool);

/// frames.json of a capture with one projection layer per frame.
fn frames(spec: &[(u64, &[ViewSpec])]) -> Frames {
    let frames: Vec<_> = spec
        .iter()
        .map(|(n, views)| {
            let views: Vec<_> = views
                .iter()
                .map(|&(view, (width, height), depth)| {
                    let rect = json!({ "x": 0, "y": 0, "width": width, "height": height });
                    let depth = depth.then(|| {
                        json!({ "swapchain": 2, "format": 126, "image_rect": rect, "image_array_index": 0, "image_index": 0,
                            "min_depth": 0.0, "max_depth": 1.0, "near_z": 0.05, "far_z": 2000.0,
                            "file": format!("frame-{n:05}-view-{view}-depth.png") })
                    });
                    json!({ "view": view,
                        "pose": { "orientation": [0.0, 0.0, 0.0, 1.0], "position": [0.0, 1.6, 0.0] },
                        "fov": { "angle_left": -0.8, "angle_right": 0.8, "angle_up": 0.8, "angle_down": -0.8 },
                        "swapchain": 1, "format": 43, "image_rect": rect, "image_array_index": 0, "image_index": 0,
                        "file": format!("frame-{n:05}-view-{view}.png"), "depth": depth })
                })
                .collect();
            json!({ "frame": n, "layers": [ { "type": "projection", "layer_flags": 0, "space": "STAGE", "views": views } ] })
        })
        .collect();
    serde_json::from_value(json!({ "hmd": "simple", "frames": frames })).expect("synthetic frames.json")
}

const STEREO: &[ViewSpec] = &[(0, (4, 3), false), (1, (4, 3), false)];
const STEREO_DEPTH: &[ViewSpec] = &[(0, (4, 3), true), (1, (4, 3), true)];

fn err<T>(r: Result<T, String>) -> String {
    match r {
        Ok(_) => panic!("the comparison was accepted"),
        Err(e) => e,
    }
}

#[test]
fn equal_captures_pair_every_view() {
    let a = frames(&[(0, STEREO_DEPTH), (1, STEREO_DEPTH)]);
    let pairs = pair_captures(&a, &a, DepthCheck::Compare).expect("same captures");
    assert_eq!(pairs.iter().map(|(n, p)| (*n, p.len())).collect::<Vec<_>>(), [(0, 2), (1, 2)]);
}

#[test]
fn different_view_count_fails() {
    let (two, one) = (frames(&[(0, STEREO)]), frames(&[(0, &[(0, (4, 3), false)])]));
    assert!(err(pair_captures(&two, &one, DepthCheck::Compare)).contains("views differ"));
    assert!(err(pair_captures(&one, &two, DepthCheck::Ignore)).contains("views differ"));
    assert!(err(pair_frame(&two, 0, &one, 0, DepthCheck::Compare)).contains("views differ"));
}

#[test]
fn different_view_ids_fail() {
    let swapped = frames(&[(0, &[(1, (4, 3), false), (0, (4, 3), false)])]);
    assert!(err(pair_captures(&frames(&[(0, STEREO)]), &swapped, DepthCheck::Compare)).contains("views differ"));
}

#[test]
fn missing_depth_fails() {
    let (with, without) = (frames(&[(0, STEREO_DEPTH)]), frames(&[(0, STEREO)]));
    assert!(err(pair_captures(&with, &without, DepthCheck::Compare)).contains("left has depth, right has no depth"));
    assert!(err(pair_captures(&without, &with, DepthCheck::Compare)).contains("left has no depth, right has depth"));
    // Depth in one view only.
    let one_eye = frames(&[(0, &[(0, (4, 3), true), (1, (4, 3), false)])]);
    assert!(err(pair_frame(&with, 0, &one_eye, 0, DepthCheck::Compare)).contains("view 1"));
    // Only a colour comparison, asked for by name, accepts it.
    assert_eq!(pair_captures(&with, &without, DepthCheck::Ignore).expect("colour only").len(), 1);
}

#[test]
fn different_image_size_fails() {
    let small = frames(&[(0, &[(0, (4, 2), false), (1, (4, 3), false)])]);
    assert!(err(pair_captures(&frames(&[(0, STEREO)]), &small, DepthCheck::Ignore)).contains("image sizes differ"));
}

#[test]
fn different_frames_fail() {
    let (two, one) = (frames(&[(0, STEREO), (1, STEREO)]), frames(&[(0, STEREO)]));
    assert!(err(pair_captures(&two, &one, DepthCheck::Compare)).contains("captured frames differ"));
    assert!(err(pair_captures(&one, &frames(&[(1, STEREO)]), DepthCheck::Compare)).contains("captured frames differ"));
    assert!(err(pair_frame(&one, 0, &one, 1, DepthCheck::Compare)).contains("frame 1 not captured"));
}

#[test]
fn empty_capture_fails() {
    let none = frames(&[]);
    assert!(err(pair_captures(&none, &none, DepthCheck::Compare)).contains("nothing to compare"));
    assert!(err(pair_captures(&frames(&[(0, STEREO)]), &none, DepthCheck::Compare)).contains("nothing to compare"));
    // Frames, but no view in them.
    let no_views = frames(&[(0, &[])]);
    assert!(err(pair_captures(&no_views, &no_views, DepthCheck::Compare)).contains("nothing to compare"));
    let zero_size = frames(&[(0, &[(0, (0, 3), false)])]);
    assert!(err(pair_captures(&zero_size, &zero_size, DepthCheck::Compare)).contains("nothing to compare"));
}

/// A run's output over a folder of tiny PNGs written here (colour 4 × 3, depth 16-bit grey).
fn run_output(name: &str, frames_spec: &[(u64, &[ViewSpec])], colour: u16) -> RunOutput {
    let capture = common::output_dir(&format!("harness-helpers-{name}"));
    let frames = frames(frames_spec);
    for f in &frames.frames {
        for v in f.layers.iter().flat_map(|l| &l.views) {
            let (w, h) = (v.image_rect.width, v.image_rect.height);
            Image { width: w, height: h, channels: 3, bit_depth: 8, data: vec![colour; (w * h * 3) as usize] }.save(&capture.join(&v.file));
            if let Some(d) = &v.depth {
                Image { width: w, height: h, channels: 1, bit_depth: 16, data: vec![40000; (w * h) as usize] }.save(&capture.join(&d.file));
            }
        }
    }
    RunOutput {
        name: name.into(),
        code: Some(0),
        signal: None,
        crash: None,
        stderr: String::new(),
        capture,
        frames: Some(frames),
        stats: None,
        elapsed: Default::default(),
        log: String::new(),
    }
}

#[test]
fn assert_same_captures_compares_images() {
    let a = run_output("same-a", &[(0, STEREO_DEPTH)], 200);
    let b = run_output("same-b", &[(0, STEREO_DEPTH)], 200);
    common::assert_same_captures("harness-helpers-same", &a, &b);
    common::assert_same_frame("harness-helpers-same-frame", &a, 0, &b, 0);
}

#[test]
#[should_panic(expected = "pixels differ")]
fn assert_same_captures_fails_on_different_pixels() {
    let a = run_output("pixels-a", &[(0, STEREO)], 200);
    let b = run_output("pixels-b", &[(0, STEREO)], 100);
    common::assert_same_captures("harness-helpers-pixels", &a, &b);
}

#[test]
#[should_panic(expected = "right has no depth")]
fn assert_same_captures_fails_on_missing_depth() {
    let a = run_output("depth-a", &[(0, STEREO_DEPTH)], 200);
    let b = run_output("depth-b", &[(0, STEREO)], 200);
    common::assert_same_captures("harness-helpers-depth", &a, &b);
}

#[test]
#[should_panic(expected = "views differ")]
fn assert_same_captures_fails_on_view_count() {
    let a = run_output("views-a", &[(0, STEREO)], 200);
    let b = run_output("views-b", &[(0, &[(0, (4, 3), false)])], 200);
    common::assert_same_captures("harness-helpers-views", &a, &b);
}

#[test]
#[should_panic(expected = "nothing to compare")]
fn assert_same_captures_fails_on_empty_capture() {
    let a = run_output("empty-a", &[], 200);
    common::assert_same_captures("harness-helpers-empty", &a, &a);
}

#[test]
#[should_panic(expected = "nothing to compare")]
fn views_to_compare_fails_without_views() {
    let a = run_output("no-views", &[(0, &[])], 200);
    common::views_to_compare("harness-helpers-no-views", &a, 0, &a, 0);
}

#[test]
#[should_panic(expected = "has no view")]
fn views_is_never_empty() {
    run_output("views-empty", &[(0, &[])], 200).views(0);
}

const XR_LINE: &str = "2026-01-01T00:00:00Z  INFO ThreadId(01) xrCreateApiLayerInstance{app=xr-scene}: stereoshim::xr::instance: instance 0x1 for app \"xr-scene\" enabled=true exe=\"xr-scene\"";
const VK_LINE: &str = "2026-01-01T00:00:00Z  INFO ThreadId(01) stereoshim::vk::chain: vulkan device created decision=x pass_through=false";
const VK_QUOTED: &str = "2026-01-01T00:00:00Z  WARN ThreadId(01) stereoshim::features::foveation::vrs::rules: vrs unsupported (see \"vulkan device created\" in this log)";
const FAILURE: &str = "2026-01-01T00:00:00Z ERROR ThreadId(01) stereoshim::core::guard: internal failure: boom call=\"xrEndFrame\"";

#[test]
fn absence_needs_the_layer_loaded() {
    // Without the layer the log is empty: it lacks every line, and that proves nothing.
    assert!(layer_loaded("", Half::OpenXr).is_err());
    assert!(err(log_lacks("", Half::Both, "internal failure")).contains("the layer did not load"));
    // Each half by its own line.
    let xr_only = format!("{XR_LINE}\n");
    assert!(log_lacks(&xr_only, Half::OpenXr, "internal failure").is_ok());
    assert!(err(log_lacks(&xr_only, Half::Vulkan, "internal failure")).contains("the Vulkan half"));
    assert!(err(log_lacks(&xr_only, Half::Both, "internal failure")).contains("the Vulkan half"));
    assert!(err(log_lacks(VK_LINE, Half::OpenXr, "internal failure")).contains("the OpenXR half"));
    // A line that only mentions the Vulkan half's message is no proof.
    let quoted = format!("{XR_LINE}\n{VK_QUOTED}\n");
    assert!(err(log_lacks(&quoted, Half::Vulkan, "internal failure")).contains("the Vulkan half"));
    let both = format!("{XR_LINE}\n{VK_LINE}\n");
    assert!(log_lacks(&both, Half::Both, "internal failure").is_ok());
    // Loaded, and the line is there.
    let failed = format!("{both}{FAILURE}\n");
    assert!(err(log_lacks(&failed, Half::Both, "internal failure")).contains("1 log line(s)"));
}

#[test]
#[should_panic(expected = "the layer did not load")]
fn assert_log_lacks_fails_when_the_layer_never_loaded() {
    run_output("log-empty", &[(0, STEREO)], 0).assert_log_lacks(Half::OpenXr, "internal failure");
}

#[test]
fn assert_layer_not_loaded_wants_an_empty_log() {
    let mut out = run_output("log-none", &[(0, STEREO)], 0);
    out.assert_layer_not_loaded();
    out.log = format!("{XR_LINE}\n");
    assert!(std::panic::catch_unwind(|| out.assert_layer_not_loaded()).is_err());
    out.assert_layer_loaded(Half::OpenXr).assert_log_lacks(Half::OpenXr, "internal failure");
}
