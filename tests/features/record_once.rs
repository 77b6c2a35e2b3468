//! Issue 9: the layer's objects live as long as the GPU needs them, and what changes while an app
//! runs reaches command buffers the app recorded long before. xr-scene `--record-once` records its
//! command buffers once per combination of acquired swapchain images (three: frames f, f + 3,
//! f + 6, … resubmit the buffers recorded in frame f mod 3) and resubmits them for 120 frames,
//! several frames in flight, under validation with synchronization validation. Through the layer:
//! - the hidden-area mask, with the runtime's mask shrinking at frame 60
//!   (`MOCK_XR_VISIBILITY_MASK_CHANGE_AT`): every checked frame is masked with that frame's mask
//!   (frames.json), outside it bit-identical to the same frame without the layer;
//! - radial density masking following a moving gaze (`MOCK_XR_GAZE_PATH`): every checked frame
//!   passes tests/features/foveation.rs's checks for the rings around that frame's gaze;
//! - live config changes (the layer re-reads its config file between frames): the mask switched
//!   off and on again, and the foveation preset changed, each frame judged by the configuration
//!   the layer reports live for it;
//! - variants re-recording one of the three sets every 6th frame (`--rerecord-every 6`): the
//!   layer then builds objects for new data while the other two sets' command buffers, still
//!   resubmitted, use the older ones.
//!
//! Each run must exit cleanly with validation silent (xr-scene exits 3 on any validation error),
//! after the log proved the layer was loaded. Problems are collected over every checked frame
//! and reported together, so a failure shows which frames and which checks go wrong.
//! Checked frames: 1 and 2 (recorded in that frame, the layer knowing the eye uses — what the
//! other end-to-end tests check), 3–5 (the first resubmissions, frame 3 running what was
//! recorded in frame 0, before the layer knew any eye use), frames more than 16 frames after
//! recording, and frames after each change. Only those are captured.

use crate::common;

use common::image::{self, Image};
use common::rdm::{self, Expected};
use common::{hidden_pixels, mask_edge_pixels, Half, Run, RunOutput};
use std::path::{Path, PathBuf};

/// Frames each run submits (`MOCK_XR_EXIT_AFTER`).
const FRAMES: u64 = 120;
/// Pixels this close to a mask's outline may go either way (vertex snapping, f32 vs f64 mapping).
const EDGE_MARGIN_PX: f64 = 1.0;

/// `MOCK_XR_CAPTURE_FRAMES` for exactly these frames.
fn frame_list(frames: &[u64]) -> String {
    frames.iter().map(u64::to_string).collect::<Vec<_>>().join(",")
}

/// The folder `Run` gives a run of this name (files placed there must be named after it starts:
/// it is emptied first; the layer creates its stats file itself).
fn run_dir(name: &str) -> PathBuf {
    common::target_dir().join("test-output").join(name)
}

/// The app and runtime setup every run shares; `name` names the run's folder.
fn base(name: &str, args: &[&str], capture: &[u64]) -> Run {
    Run::new(name)
        .args(["--record-once", "--animate"])
        .args(args.iter().copied())
        .env("MOCK_XR_EXIT_AFTER", &FRAMES.to_string())
        .env("MOCK_XR_CAPTURE_FRAMES", &frame_list(capture))
}

/// What went wrong, over all checked frames, reported at once.
#[derive(Default)]
struct Problems(Vec<String>);

impl Problems {
    fn check(&mut self, r: Result<(), String>) {
        if let Err(e) = r {
            self.0.push(e);
        }
    }

    fn finish(self, name: &str) {
        assert!(self.0.is_empty(), "{name}: {} problem(s):\n- {}", self.0.len(), self.0.join("\n- "));
    }
}

/// The distinct validation messages of a run (by message id), with how often each came and the
/// first one's text.
fn validation_summary(stderr: &str) -> Vec<String> {
    let mut seen: Vec<(String, usize, String)> = Vec::new();
    for line in stderr.lines().filter(|l| l.starts_with("[vulkan validation error]")) {
        let id = line.split("[ ").nth(1).and_then(|r| r.split(" ]").next()).unwrap_or("?").to_string();
        match seen.iter_mut().find(|(i, _, _)| *i == id) {
            Some(entry) => entry.1 += 1,
            None => seen.push((id, 1, line.chars().take(600).collect())),
        }
    }
    seen.into_iter().map(|(id, n, first)| format!("{n} × {id}, first: {first}")).collect()
}

/// The layer was in the app (the log proves both halves, and that the Vulkan half is in the
/// session's device), the app exited cleanly (0: which under `--validation` means no validation
/// error, synchronization included), and the layer reported no internal failure and no error.
/// The load check comes first (`common::layer_loaded`, through `log_lacks`): only a log known to
/// be the layer's can show that something is absent from it.
fn check_run(out: &RunOutput, problems: &mut Problems) {
    out.assert_layer_loaded(Half::Both);
    assert!(
        !out.log_lines("the Vulkan half tracks this device").is_empty(),
        "{}: the Vulkan half is not in the session's device; log:\n{}\nstderr:\n{}",
        out.name,
        out.log,
        out.stderr
    );
    if out.code != Some(0) {
        let summary = validation_summary(&out.stderr);
        let tail: String = out.stderr.lines().rev().take(3).collect::<Vec<_>>().into_iter().rev().collect::<Vec<_>>().join(" | ");
        let how = match (out.code, out.signal) {
            (Some(3), _) => "exit code 3: Vulkan validation errors".to_string(),
            (Some(c), _) => format!("exit code {c}"),
            (None, Some(s)) => format!("killed by signal {s}"),
            (None, None) => "no exit status".to_string(),
        };
        problems.0.push(format!("{}: xr-scene did not exit cleanly ({how}); last lines of stderr: {tail}", out.name));
        problems.0.extend(summary.into_iter().map(|s| format!("{}: validation: {s}", out.name)));
    }
    if out.log_lines("vulkan device stats:").is_empty() {
        problems.0.push(format!("{}: the layer never logged `vulkan device stats:` (the device was not destroyed through it)", out.name));
    }
    for needle in ["internal failure", " ERROR "] {
        problems.check(common::log_lacks(&out.log, Half::Both, needle).map_err(|e| format!("{}: {}", out.name, e.lines().next().unwrap_or_default())));
    }
}

fn save_artifacts(name: &str, got: &Image, want: &Image) -> PathBuf {
    let dir = image::artifacts_dir(name);
    got.save(&dir.join("actual.png"));
    want.save(&dir.join("expected.png"));
    image::difference(got, want).save(&dir.join("difference.png"));
    dir
}

/// Whether frame `frame` was captured in both runs (a run that crashed or stopped early lacks it).
fn captured(frame: u64, runs: &[&RunOutput]) -> Result<(), String> {
    for r in runs {
        let ok = r.frames.as_ref().is_some_and(|f| f.frames.iter().any(|f| f.frame == frame));
        if !ok {
            return Err(format!("{}: frame {frame} was not captured", r.name));
        }
    }
    Ok(())
}

/// Frame `frame`'s views of `layered` paired with those of `plain` (`common::pair_frame`: both
/// runs captured it, with the same views, sizes and depth presence), or why not.
fn views<'a>(name: &str, layered: &'a RunOutput, plain: &'a RunOutput, frame: u64) -> Result<Vec<(&'a common::View, &'a common::View)>, String> {
    captured(frame, &[plain, layered])?;
    common::pair_frame(layered.frames(), frame, plain.frames(), frame, common::DepthCheck::Compare)
        .map_err(|e| format!("{name}: frame {frame} of {} and {} cannot be compared: {e}", layered.name, plain.name))
}

/// Frame `frame` through the layer with the mask on, against the same frame without the layer:
/// inside the runtime's hidden-area mask of that frame (frames.json, rasterized by the harness)
/// black, outside it bit-identical, pixels along its outline either; the layer's `stats.file`
/// record counts the mask's pixels per view within 1 % (tests/features/mask_source.rs
/// `changed_mask_is_applied_to_later_frames`).
fn check_masked(name: &str, plain: &RunOutput, masked: &RunOutput, frame: u64, record: Option<&serde_json::Value>) -> Result<(), String> {
    let pairs = views(name, masked, plain, frame)?;
    let masks = &masked.frame(frame).visibility_masks;
    if masks.len() != 2 {
        return Err(format!("{name} frame {frame}: frames.json has no visibility_masks"));
    }
    for (a, b) in pairs {
        let mask = &masks.iter().find(|m| m.view == a.view).expect("mask of view").hidden_triangles;
        let (w, h) = (a.image_rect.width, a.image_rect.height);
        let hidden = hidden_pixels(mask, &a.fov, w, h);
        let edge = mask_edge_pixels(mask, &a.fov, w, h, EDGE_MARGIN_PX);
        let (got, want) = (masked.image(&a.file), plain.image(&b.file));
        let (mut not_masked, mut changed) = (Vec::new(), Vec::new());
        for y in 0..h {
            for x in 0..w {
                let i = (y * w + x) as usize;
                let g = &got.pixel(x, y)[..3];
                if edge[i] {
                    continue;
                }
                if hidden[i] {
                    if g.iter().any(|&c| c != 0) {
                        not_masked.push((x, y));
                    }
                } else if g != &want.pixel(x, y)[..3] {
                    changed.push((x, y));
                }
            }
        }
        if !not_masked.is_empty() || !changed.is_empty() {
            let dir = save_artifacts(&format!("{name}-f{frame}-view{}", a.view), &got, &want);
            return Err(format!(
                "{name} frame {frame} view {}: {} hidden pixels not masked (first {:?}), {} visible pixels differ from the run without the layer (first {:?}); artifacts in {}",
                a.view,
                not_masked.len(),
                &not_masked[..not_masked.len().min(4)],
                changed.len(),
                &changed[..changed.len().min(4)],
                dir.display()
            ));
        }
        let hidden_count = hidden.iter().filter(|&&b| b).count() as u64;
        if hidden_count == 0 {
            return Err(format!("{name} frame {frame} view {}: the runtime's mask covers no pixel", a.view));
        }
        let r = record.ok_or_else(|| format!("{name} frame {frame}: the layer wrote no stats.file record"))?;
        let layer = r["pixels_masked"][a.view.to_string()].as_u64().unwrap_or(0);
        if hidden_count.abs_diff(layer) * 100 > hidden_count {
            return Err(format!("{name} frame {frame} view {}: the layer's stats.file counts {layer} masked pixels, the mask covers {hidden_count}: {r}", a.view));
        }
    }
    Ok(())
}

/// Frame `frame` through the layer with nothing enabled for it is bit-identical to the run without.
fn check_untouched(name: &str, plain: &RunOutput, layered: &RunOutput, frame: u64) -> Result<(), String> {
    for (a, b) in views(name, layered, plain, frame)? {
        let (got, want) = (layered.image(&a.file), plain.image(&b.file));
        let n = got.count_different(&want);
        if n > 0 {
            let dir = save_artifacts(&format!("{name}-f{frame}-view{}", a.view), &got, &want);
            return Err(format!("{name} frame {frame} view {}: {n} pixels differ from the run without the layer; artifacts in {}", a.view, dir.display()));
        }
    }
    Ok(())
}

/// One frame with radial density masking, judged as tests/features/foveation.rs judges frame 1: the
/// pixels (kept quads and the inner ring bit-identical), then the shaded fragments (down by
/// exactly the plain run's fragments at the skipped pixels) and periphery PSNR (`balanced`), then
/// the layer's own record of the frame.
fn check_rdm_frame(name: &str, plain: &RunOutput, layered: &RunOutput, frame: u64, expected: &Expected, balanced: bool, record: &serde_json::Value) -> Result<(), String> {
    let results = rdm::check_frame(name, plain, layered, frame, expected)?;
    rdm::check_results(name, balanced, false, &results)?;
    rdm::check_layer_record(name, record, &results)
}

/// The layer's `stats.file` record of `frame`, if it wrote one.
fn record(records: &[serde_json::Value], frame: u64) -> Option<&serde_json::Value> {
    records.iter().find(|r| r["frame"] == frame)
}

/// (a) The hidden-area mask of a record-once app, the runtime's mask shrinking at frame 60.
fn mask_change(name: &str, args: &[&str]) {
    const CHANGE_AT: u64 = 60;
    let frames = [1, 2, 3, 4, 5, 30, 31, 32, 60, 61, 62, 90, 91, 92, 117, 118, 119];
    let stats = run_dir(&format!("{name}-masked")).join("layer-stats.jsonl");
    let plain = base(name, args, &frames).env("MOCK_XR_VISIBILITY_MASK_CHANGE_AT", &CHANGE_AT.to_string()).run();
    plain.assert_ok();
    let mut layered = base(name, args, &frames)
        .env("MOCK_XR_VISIBILITY_MASK_CHANGE_AT", &CHANGE_AT.to_string())
        .with_layer()
        .env("STEREOSHIM_MASK_ENABLED", "1")
        .env("STEREOSHIM_STATS_FILE", stats.to_str().unwrap());
    layered.name = format!("{name}-masked");
    let masked = layered.run();
    let mut problems = Problems::default();
    check_run(&masked, &mut problems);
    let records = std::fs::read_to_string(&stats).map(|t| t.lines().filter_map(|l| serde_json::from_str(l).ok()).collect::<Vec<serde_json::Value>>()).unwrap_or_default();
    // The change is real: later frames hide more (the runtime's own masks, not the layer's).
    if let (Ok(()), Ok(())) = (captured(1, &[&masked]), captured(CHANGE_AT, &[&masked])) {
        let before = &masked.frame(1).visibility_masks;
        let after = &masked.frame(CHANGE_AT).visibility_masks;
        assert_ne!(before, after, "{name}: the runtime's masks did not change at frame {CHANGE_AT}");
    }
    for &f in &frames {
        problems.check(check_masked(name, &plain, &masked, f, record(&records, f)));
    }
    problems.finish(name);
}

macro_rules! mask_change_tests {
    ($($name:ident: [$($arg:literal),*];)*) => {$(
        #[test]
        fn $name() {
            mask_change(concat!("record-once-", stringify!($name)), &[$($arg),*]);
        }
    )*};
}

mask_change_tests! {
    mask_change_per_eye_render_pass: ["--layout", "per-eye", "--rendering", "render-pass"];
    mask_change_multiview_dynamic: ["--layout", "multiview", "--rendering", "dynamic"];
    mask_change_side_by_side_render_pass2_secondary: ["--layout", "side-by-side", "--rendering", "render-pass2", "--secondary"];
    // Every 6th frame re-records the set it submits (always the same one of the three, as an
    // engine re-records one command buffer now and then), so the layer records new draws while
    // the other command buffers, still resubmitted, hold its earlier objects.
    mask_change_rerecorded_multiview_render_pass: ["--layout", "multiview", "--rendering", "render-pass", "--rerecord-every", "6"];
}

/// The moving gaze: four points, each more than 5° from the one before (stereoshim's gaze policy
/// jumps to each exactly), held 10 frames each, cycling.
const GAZE_PATH: [(f64, f64); 4] = [(0.0, 0.0), (12.0, -6.0), (-10.0, 8.0), (8.0, 10.0)];
const GAZE_HOLD: u64 = 10;

/// The gaze point of frame `frame`, when frames `frame − 2 ..= frame` all had it: the layer's
/// fovea of a frame follows the gaze it sampled the frame before (docs/testing.md), so only such
/// frames have one fovea whatever the sampling lag.
fn settled_gaze(frame: u64) -> Option<(f64, f64)> {
    (frame % GAZE_HOLD >= 2 || (1..GAZE_HOLD).contains(&frame)).then(|| GAZE_PATH[((frame / GAZE_HOLD) % GAZE_PATH.len() as u64) as usize])
}

/// (b) Radial density masking of a record-once app with a moving gaze.
fn moving_gaze(name: &str, args: &[&str]) {
    let frames = [1, 2, 3, 4, 5, 6, 7, 15, 16, 17, 25, 26, 27, 35, 36, 37, 55, 56, 57, 95, 96, 97, 115, 116, 117];
    let path = GAZE_PATH.iter().map(|(y, p)| format!("{y},{p}")).collect::<Vec<_>>().join(";");
    let run = |tag: &str| {
        let mut r = base(name, args, &frames).pixel_stats().env("MOCK_XR_GAZE_PATH", &path).env("MOCK_XR_GAZE_HOLD", &GAZE_HOLD.to_string());
        r.name = format!("{name}{tag}");
        r
    };
    let plain = run("").run();
    plain.assert_ok();
    let stats = run_dir(&format!("{name}-rdm")).join("layer-stats.jsonl");
    let layered = run("-rdm")
        .with_layer()
        .env("STEREOSHIM_FOVEATION_ENABLED", "1")
        .env("STEREOSHIM_FOVEATION_METHOD", "rdm")
        .env("STEREOSHIM_FOVEATION_PRESET", "balanced")
        .env("STEREOSHIM_FOVEATION_EYE_TRACKING", "auto")
        .env("STEREOSHIM_STATS_FILE", stats.to_str().unwrap())
        .run();
    let mut problems = Problems::default();
    check_run(&layered, &mut problems);
    if layered.log_lines("foveation centre now from Gaze").is_empty() {
        problems.0.push(format!("{name}: the layer never followed the gaze; log:\n{}", layered.log));
    }
    let records = std::fs::read_to_string(&stats).map(|t| t.lines().filter_map(|l| serde_json::from_str(l).ok()).collect::<Vec<serde_json::Value>>()).unwrap_or_default();
    let (inner_deg, middle_deg) = rdm::preset("balanced");
    for &f in &frames {
        let (yaw, pitch) = settled_gaze(f).unwrap_or_else(|| panic!("{name}: frame {f} is not inside a gaze hold"));
        let center = rdm::gaze_center(yaw, pitch);
        let frame_name = format!("{name}-f{f}");
        if let Err(e) = captured(f, &[&plain, &layered]) {
            problems.0.push(e);
            continue;
        }
        let Some(rec) = record(&records, f) else {
            problems.0.push(format!("{frame_name}: no stats.file record"));
            continue;
        };
        // The layer's own account of its fovea agrees with the gaze the runtime showed.
        for view in 0..2 {
            let c = &rec["fovea"][view]["center"];
            let got = [c[0].as_f64().unwrap_or(f64::NAN), c[1].as_f64().unwrap_or(f64::NAN)];
            if (got[0] - center[0] as f64).abs() > 1e-3 || (got[1] - center[1] as f64).abs() > 1e-3 {
                problems.0.push(format!("{frame_name} view {view}: the layer reports fovea centre {got:?}, the gaze ({yaw}°, {pitch}°) is {center:?}"));
            }
        }
        let expected = Expected { center, inner_deg, middle_deg, with_mask: false };
        problems.check(check_rdm_frame(&frame_name, &plain, &layered, f, &expected, true, rec));
    }
    problems.finish(name);
}

macro_rules! moving_gaze_tests {
    ($($name:ident: [$($arg:literal),*];)*) => {$(
        #[test]
        fn $name() {
            moving_gaze(concat!("record-once-", stringify!($name)), &[$($arg),*]);
        }
    )*};
}

moving_gaze_tests! {
    moving_gaze_per_eye_dynamic: ["--layout", "per-eye", "--rendering", "dynamic"];
    moving_gaze_multiview_render_pass2: ["--layout", "multiview", "--rendering", "render-pass2"];
    moving_gaze_side_by_side_render_pass_secondary: ["--layout", "side-by-side", "--rendering", "render-pass", "--secondary"];
    // Re-recording every 6th frame (always the same set): each new fovea generation gets new
    // layer objects there while the other two sets keep running the ones they were recorded with,
    // which the layer retires when it builds a newer one and destroys 16 frames later.
    moving_gaze_rerecorded_per_eye_render_pass: ["--layout", "per-eye", "--rendering", "render-pass", "--rerecord-every", "6"];
}

/// Writes the layer's config file so that the layer's watch (modification time) sees one complete
/// new file: written beside it, then renamed over it.
fn write_config(dir: &Path, text: &str) {
    let path = Run::config_file(dir);
    let tmp = path.with_extension("toml.new");
    std::fs::write(&tmp, text).unwrap();
    std::fs::rename(&tmp, &path).unwrap();
}

/// The last frame number the layer's `stats.file` holds so far.
fn last_frame(stats: &Path) -> Option<u64> {
    let text = std::fs::read_to_string(stats).ok()?;
    text.lines().filter_map(|l| serde_json::from_str::<serde_json::Value>(l).ok()).filter_map(|v| v["frame"].as_u64()).max()
}

/// Runs `run` and rewrites its config file to `configs[i]` once the layer has reported frame
/// `switch_at[i]`, in order. The app is paced (`MOCK_XR_PACE_HZ`) so that the change lands many
/// frames before the windows that are judged; which configuration each frame really had is the
/// layer's own per-frame record.
fn run_with_config_changes(run: Run, stats: &Path, changes: &[(u64, &str)]) -> RunOutput {
    let mut next = 0;
    run.env("MOCK_XR_PACE_HZ", "30").run_while(std::time::Duration::from_secs(300), |dir| {
        if let (Some(&(at, text)), Some(frame)) = (changes.get(next), last_frame(stats)) {
            if frame >= at {
                write_config(dir, text);
                next += 1;
            }
        }
    })
}

/// Which window of frames is judged under which configuration: the window's frames (and the two
/// before each) must all have been recorded by the layer under that configuration, else the
/// config change came too late or too early for this test (a harness problem, not the layer's).
fn assert_window(name: &str, records: &[serde_json::Value], frames: &[u64], live: impl Fn(&serde_json::Value) -> bool, what: &str) {
    for &f in frames {
        for g in f.saturating_sub(2)..=f {
            let r = record(records, g).unwrap_or_else(|| panic!("{name}: no stats.file record of frame {g}"));
            assert!(live(r), "{name}: frame {g} was not under {what} by the layer's account, so frame {f} cannot be judged (the config change came at the wrong time): {r}");
        }
    }
}

/// (c) Live config: the mask on, switched off after frame 40, on again after frame 80.
#[test]
fn live_config_switches_the_mask_off_and_on() {
    let name = "record-once-live-mask";
    let args = ["--layout", "per-eye", "--rendering", "render-pass2"];
    let (on, off) = ([30, 31, 32, 33, 34, 35], [70, 71, 72, 73, 74, 75]);
    let on_again = [110, 111, 112, 113, 114, 115];
    let frames: Vec<u64> = [&[1, 2, 3, 4, 5][..], &on, &off, &on_again].concat();
    let plain = base(name, &args, &frames).run();
    plain.assert_ok();
    let stats = run_dir(&format!("{name}-layered")).join("layer-stats.jsonl");
    let mut run = base(name, &args, &frames).with_layer().config("mask.enabled = true\n").env("STEREOSHIM_STATS_FILE", stats.to_str().unwrap());
    run.name = format!("{name}-layered");
    let layered = run_with_config_changes(run, &stats, &[(40, "mask.enabled = false\n"), (80, "mask.enabled = true\n")]);
    let mut problems = Problems::default();
    check_run(&layered, &mut problems);
    if layered.log_lines("config reloaded").len() != 2 {
        problems.0.push(format!("{name}: the layer did not log two config reloads:\n{}", layered.log));
    }
    let records = rdm::layer_records(&layered, &stats);
    let mask_on = |r: &serde_json::Value| r["mask_enabled"] == true;
    assert_window(name, &records, &on, mask_on, "mask.enabled = true");
    assert_window(name, &records, &off, |r| r["mask_enabled"] == false, "mask.enabled = false");
    assert_window(name, &records, &on_again, mask_on, "mask.enabled = true");
    for &f in [&[1, 2, 3, 4, 5][..], &on, &on_again].concat().iter() {
        problems.check(check_masked(name, &plain, &layered, f, record(&records, f)));
    }
    for &f in &off {
        problems.check(check_untouched(name, &plain, &layered, f));
    }
    problems.finish(name);
}

/// (c) Live config: radial density masking with the `balanced` preset, changed to `aggressive`
/// after frame 40 (fixed fovea on the optical axis: no eye tracker).
#[test]
fn live_config_changes_the_foveation_preset() {
    let name = "record-once-live-preset";
    let args = ["--layout", "side-by-side", "--rendering", "dynamic"];
    let (balanced, aggressive) = ([1, 2, 3, 4, 5, 30, 31, 32, 33, 34, 35], [70, 71, 72, 73, 74, 75, 110, 111, 112, 113, 114, 115]);
    let frames: Vec<u64> = [&balanced[..], &aggressive].concat();
    let config = |preset: &str| format!("foveation.enabled = true\nfoveation.method = \"rdm\"\nfoveation.preset = \"{preset}\"\n");
    let plain = base(name, &args, &frames).pixel_stats().env("MOCK_XR_EYE_TRACKER", "0").run();
    plain.assert_ok();
    let stats = run_dir(&format!("{name}-layered")).join("layer-stats.jsonl");
    let mut run = base(name, &args, &frames)
        .pixel_stats()
        .env("MOCK_XR_EYE_TRACKER", "0")
        .with_layer()
        .config(&config("balanced"))
        .env("STEREOSHIM_STATS_FILE", stats.to_str().unwrap());
    run.name = format!("{name}-layered");
    let aggressive_config = config("aggressive");
    let layered = run_with_config_changes(run, &stats, &[(40, &aggressive_config)]);
    let mut problems = Problems::default();
    check_run(&layered, &mut problems);
    if layered.log_lines("config reloaded").len() != 1 {
        problems.0.push(format!("{name}: the layer did not log one config reload:\n{}", layered.log));
    }
    let records = rdm::layer_records(&layered, &stats);
    let rings = |r: &serde_json::Value| (r["fovea"][0]["inner_deg"].as_f64(), r["fovea"][0]["middle_deg"].as_f64());
    for (preset, window) in [("balanced", &balanced[..]), ("aggressive", &aggressive[..])] {
        let (inner_deg, middle_deg) = rdm::preset(preset);
        let live = |r: &serde_json::Value| rings(r) == (Some(inner_deg as f64), Some(middle_deg as f64));
        assert_window(name, &records, window, live, &format!("foveation.preset = {preset}"));
        for &f in window {
            let frame_name = format!("{name}-f{f}");
            if let Err(e) = captured(f, &[&plain, &layered]) {
                problems.0.push(e);
                continue;
            }
            let rec = record(&records, f).expect("checked by assert_window");
            let expected = Expected { center: [0.0, 0.0], inner_deg, middle_deg, with_mask: false };
            problems.check(check_rdm_frame(&frame_name, &plain, &layered, f, &expected, preset == "balanced", rec));
        }
    }
    problems.finish(name);
}

/// The silence the tests above demand means something: a synchronization hazard in a record-once
/// app running through the layer (mask and RDM on) is reported and fails the run.
#[test]
fn synchronization_validation_is_on_through_the_layer() {
    let out = Run::new("record-once-sync-hazard")
        .args(["--record-once", "--sync-hazard"])
        .with_layer()
        .env("STEREOSHIM_MASK_ENABLED", "1")
        .env("STEREOSHIM_FOVEATION_ENABLED", "1")
        .env("STEREOSHIM_FOVEATION_METHOD", "rdm")
        .run();
    out.assert_layer_loaded(Half::Both);
    assert_eq!(out.code, Some(3), "a hazard under --validation must fail the run; stderr:\n{}", out.stderr);
    assert!(out.stderr.contains("SYNC-HAZARD-"), "no synchronization hazard reported; stderr:\n{}", out.stderr);
}
