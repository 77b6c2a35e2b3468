//! Screenshots end to end: xr-scene through the layer on the mock runtime, a screenshot asked for
//! mid-run (`stereoshim screenshot --wait`, or a touch of `screenshot.trigger`), and the PNGs the
//! layer wrote compared pixel for pixel with the mock runtime's capture of the same frame (the
//! frame number from the layer's JSON beside the pictures), for per-eye, multiview and
//! side-by-side swapchains; the `mask.debug` tint shows in them; no request, no files; a folder
//! that cannot be written is a log line and an error from the command, the app runs on; the app's
//! frames are the same with and without a screenshot. And the command's `--help` and errors.

use crate::common;

use common::image::{self, Image};
use common::{assert_same_captures, target_dir, Run, RunOutput};
use serde::Deserialize;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};
use stereoshim::features::screenshot::rules;

/// Frames a run makes after the test is done with it (the request answered): the app runs on.
const AFTER: u64 = 5;
/// The head turns (mock runtime), so every frame's images differ and a screenshot matches the
/// capture of its own frame only.
const YAW: &str = "30";

/// A run of xr-scene through the layer, the head turning, until the test touches the run's stop
/// file (`MOCK_XR_EXIT_ON`, [`Stop`]): a frame count could run out before a loaded machine got
/// the request to the layer.
fn run(name: &str) -> Run {
    let stop = stop_file(name);
    let _ = std::fs::remove_file(&stop);
    Run::new(name).with_layer().env("MOCK_XR_EXIT_AFTER", "").env("MOCK_XR_EXIT_ON", stop.to_str().unwrap()).env("MOCK_XR_HEAD_YAW_DEG_PER_S", YAW)
}

/// The file whose existence ends run `name`.
fn stop_file(name: &str) -> PathBuf {
    target_dir().join("test-output").join(format!("{name}.stop"))
}

/// Ends a run `AFTER` frames after the test is done with it.
struct Stop {
    file: PathBuf,
    at: Option<u64>,
}

impl Stop {
    fn new(name: &str) -> Stop {
        Stop { file: stop_file(name), at: None }
    }
    /// Called while the app runs (in `dir`): once `done`, the app makes `AFTER` more frames and
    /// ends.
    fn poll(&mut self, dir: &Path, done: bool) {
        let captured = captured_frames(dir);
        if done && self.at.is_none() {
            self.at = Some(captured + AFTER);
        }
        if self.at.is_some_and(|at| captured >= at) && !self.file.exists() {
            std::fs::write(&self.file, b"").unwrap();
        }
    }
}

/// How many frames the runtime has captured in run `dir`.
fn captured_frames(dir: &Path) -> u64 {
    std::fs::read_dir(dir.join("capture"))
        .map(|d| d.flatten().filter(|e| e.file_name().to_str().is_some_and(|n| n.starts_with("frame-") && n.ends_with("-view-0.png"))).count() as u64)
        .unwrap_or(0)
}
/// The tint `mask.debug` paints (magenta, shaders/mask.frag), as 8-bit RGB.
const TINT: [u16; 3] = [255, 0, 255];

#[derive(Debug, Deserialize)]
struct Sidecar {
    app: String,
    frame: u64,
    views: Vec<ShotView>,
}

#[derive(Debug, Deserialize)]
struct ShotView {
    view: u32,
    file: PathBuf,
    width: u32,
    height: u32,
    /// The upscale's display-size image (`upscale.enabled`), not the app's.
    #[serde(default)]
    display: bool,
}

/// `stereoshim ARGS` with the runtime folder of a run in `dir`.
fn stereoshim(args: &[&str], dir: &Path) -> (i32, String, String) {
    let out = Command::new(target_dir().join("stereoshim"))
        .args(args)
        .env("XDG_RUNTIME_DIR", dir.join("run"))
        .env("XDG_STATE_HOME", dir.join("state"))
        .output()
        .expect("run stereoshim");
    (out.status.code().unwrap_or(-1), String::from_utf8_lossy(&out.stdout).into_owned(), String::from_utf8_lossy(&out.stderr).into_owned())
}

/// Whether the app of run `dir` is well into its run: the runtime captured its frame 10 (so a
/// request lands mid-run, not at the start) and the layer announced itself.
fn rendering(dir: &Path) -> bool {
    dir.join("capture/frame-00010-view-0.png").exists() && announced(dir)
}

/// Whether the layer in the app of run `dir` announced itself (its first frame began).
fn announced(dir: &Path) -> bool {
    std::fs::read_dir(dir.join("run/stereoshim/screenshot"))
        .map(|d| d.flatten().any(|e| e.file_name().to_str().and_then(rules::instance_pid).is_some()))
        .unwrap_or(false)
}

/// Runs `run`, asking for one screenshot with `stereoshim screenshot --wait` once the app is
/// rendering; returns the run and the command's (exit code, stdout, stderr).
fn run_with_screenshot(run: &Run) -> (RunOutput, (i32, String, String)) {
    let mut answer = None;
    let mut stop = Stop::new(&run.name);
    let out = run.run_while(Duration::from_secs(240), |dir| {
        if answer.is_none() && rendering(dir) {
            answer = Some(stereoshim(&["screenshot", "--wait", "--timeout", "600"], dir));
        }
        stop.poll(dir, answer.is_some());
    });
    let answer = answer.unwrap_or_else(|| panic!("{}: the layer never announced itself; log:\n{}", run.name, out.log));
    (out, answer)
}

/// The screenshots (their JSON files) in `dir`.
fn sidecars(dir: &Path) -> Vec<Sidecar> {
    let Ok(entries) = std::fs::read_dir(dir) else { return Vec::new() };
    entries
        .flatten()
        .filter(|e| e.path().extension().is_some_and(|x| x == "json"))
        .map(|e| serde_json::from_slice(&std::fs::read(e.path()).unwrap()).unwrap_or_else(|err| panic!("{}: {err}", e.path().display())))
        .collect()
}

/// Every PNG (or leftover temporary) in `dir`.
fn files(dir: &Path) -> Vec<PathBuf> {
    std::fs::read_dir(dir).map(|d| d.flatten().map(|e| e.path()).collect()).unwrap_or_default()
}

/// The one screenshot in `pictures`, each view identical to the runtime's capture of its frame.
fn assert_matches_capture(name: &str, out: &RunOutput, pictures: &Path) -> Sidecar {
    let mut shots = sidecars(pictures);
    assert_eq!(shots.len(), 1, "{name}: one screenshot expected in {}: {:?}; log:\n{}", pictures.display(), files(pictures), out.log);
    let shot = shots.remove(0);
    assert_eq!(shot.app, "xr-scene");
    assert!(shot.frame >= 10, "{name}: frame {} was shot, but the request came after frame 10", shot.frame);
    let captured = out.views(shot.frame);
    assert_eq!(shot.views.len(), captured.len(), "{name}: views of frame {}", shot.frame);
    for v in captured {
        let mine = shot.views.iter().find(|s| s.view == v.view).unwrap_or_else(|| panic!("{name}: no view {}", v.view));
        assert!(mine.file.starts_with(pictures) && mine.file.file_name().unwrap().to_string_lossy().starts_with("xr-scene-"), "{}", mine.file.display());
        assert_eq!((mine.width, mine.height), (v.image_rect.width, v.image_rect.height));
        let picture = Image::load(&mine.file);
        image::assert_identical(&format!("screenshot-{name}-view-{}", v.view), &picture, &out.image(&v.file));
        // Not any frame's: the neighbours' captures differ (the head turns).
        for other in [shot.frame.wrapping_sub(1), shot.frame + 1] {
            if let Some(o) = out.frames().frames.iter().find(|f| f.frame == other) {
                let file = &o.layers[0].views.iter().find(|x| x.view == v.view).expect("same views").file;
                assert!(picture.count_different(&out.image(file)) > 0, "{name}: view {} of frame {} equals frame {other}'s", v.view, shot.frame);
            }
        }
    }
    assert!(!files(pictures).iter().any(|f| f.to_string_lossy().ends_with(".tmp")), "{name}: a temporary file is left");
    shot
}

fn tinted(img: &Image) -> usize {
    (0..img.height).flat_map(|y| (0..img.width).map(move |x| (x, y))).filter(|&(x, y)| img.pixel(x, y) == TINT).count()
}

/// Per-eye swapchains, the folder from `$XDG_CONFIG_HOME/user-dirs.dirs`; the app's frames are
/// those of a run without a screenshot, and a run without a request writes nothing.
#[test]
fn per_eye_screenshot_equals_the_capture() {
    let base = run("screenshot-per-eye");
    let home = target_dir().join("test-output/screenshot-home");
    let _ = std::fs::remove_dir_all(&home);
    // The user-dirs file goes where the run's XDG_CONFIG_HOME is (the run folder, made fresh by
    // the run itself): written from the first poll, before the layer reads it at the request.
    let run = base.clone().env("HOME", home.to_str().unwrap());
    let mut answer = None;
    let mut stop = Stop::new(&run.name);
    let out = run.run_while(Duration::from_secs(240), |dir| {
        let dirs = dir.join("config/user-dirs.dirs");
        if !dirs.exists() {
            std::fs::create_dir_all(dir.join("config")).unwrap();
            std::fs::write(&dirs, "# xdg-user-dirs\nXDG_PICTURES_DIR=\"$HOME/Bilder\"\n").unwrap();
        }
        if answer.is_none() && rendering(dir) {
            answer = Some(stereoshim(&["screenshot", "--wait", "--timeout", "600"], dir));
        }
        stop.poll(dir, answer.is_some());
    });
    out.assert_ok();
    let (code, stdout, stderr) = answer.expect("asked");
    assert_eq!(code, 0, "{stdout}{stderr}\nlog:\n{}", out.log);
    let pictures = home.join("Bilder/stereoshim");
    let shot = assert_matches_capture("per-eye", &out, &pictures);
    // Every object of the copies was freed by the device's end.
    common::assert_nothing_tracked(&out);
    // The command printed the pictures' paths, one per view.
    let printed: Vec<PathBuf> = stdout.lines().map(PathBuf::from).collect();
    assert_eq!(printed, shot.views.iter().map(|v| v.file.clone()).collect::<Vec<_>>());
    assert_eq!(out.log_lines("screenshot of frame").len(), 1, "{}", out.log);
    // What the app's xrReleaseSwapchainImage calls spent on the copies (reported, not judged: a
    // loaded 2-core test machine).
    // Both copies went into buffers made ahead on the layer's thread, not inside the release.
    let submitted = out.log_lines("copies submitted");
    for l in &submitted {
        eprintln!("{l}");
    }
    assert_eq!(submitted.len(), 1, "{}", out.log);
    assert!(submitted[0].contains("2 copies submitted (2 into buffers made ahead)"), "{}", submitted[0]);
    // The instance file is gone with the session.
    assert!(!announced(out.capture.parent().unwrap()), "the instance file outlived the app");

    // Without a request: no picture; and the app's frames are the same as with one (the copy
    // changed nothing the runtime got, nor how many frames the app made).
    let home2 = target_dir().join("test-output/screenshot-home-none");
    let _ = std::fs::remove_dir_all(&home2);
    // As many frames as the run with the request made.
    let frames = out.frames().frames.len().to_string();
    let mut quiet = base
        .env("HOME", home2.to_str().unwrap())
        .env("XDG_PICTURES_DIR", home2.join("pics").to_str().unwrap())
        .env("MOCK_XR_EXIT_ON", "")
        .env("MOCK_XR_EXIT_AFTER", &frames);
    quiet.name = "screenshot-none".into();
    let none = quiet.run();
    none.assert_ok();
    none.assert_log_lacks(common::Half::Vulkan, "screenshot of frame");
    assert!(!home2.join("pics").exists(), "pictures written without a request: {:?}", files(&home2.join("pics/stereoshim")));
    assert_eq!(out.frames().frames.len(), none.frames().frames.len());
    assert_same_captures("screenshot-per-eye vs none", &out, &none);
}

/// One multiview swapchain (a view per array layer), the folder from `$XDG_PICTURES_DIR`, asked
/// for by touching `screenshot.trigger`; with radial density masking, whose reconstruction at the
/// same release must be in the picture (the screenshot comes last in the registry).
#[test]
fn multiview_screenshot_by_touch_equals_the_capture() {
    let name = "screenshot-multiview";
    let pics = target_dir().join("test-output/screenshot-multiview-pictures");
    let _ = std::fs::remove_dir_all(&pics);
    let touch = target_dir().join("test-output/screenshot-multiview-touch");
    let _ = std::fs::remove_file(&touch);
    let stats_file = target_dir().join("test-output").join(name).join("layer-stats.jsonl");
    let run = run(name)
        .env("STEREOSHIM_STATS_FILE", stats_file.to_str().unwrap())
        .args(["--layout", "multiview"])
        .env("STEREOSHIM_FOVEATION_ENABLED", "1")
        .env("STEREOSHIM_FOVEATION_METHOD", "rdm")
        .env("XDG_PICTURES_DIR", pics.to_str().unwrap())
        .env("STEREOSHIM_SCREENSHOT_TRIGGER", touch.to_str().unwrap());
    let mut seen: Option<Instant> = None;
    let mut stop = Stop::new(&run.name);
    let out = run.run_while(Duration::from_secs(240), |dir| {
        if seen.is_none() && rendering(dir) {
            seen = Some(Instant::now());
        }
        stop.poll(dir, !sidecars(&pics.join("stereoshim")).is_empty());
        // The layer noted the file's absence at its first look (when it announced itself); a
        // touch after that is a request.
        if seen.is_some_and(|t| t.elapsed() > Duration::from_millis(50)) && !touch.exists() {
            std::fs::write(&touch, b"").unwrap();
        }
    });
    out.assert_ok();
    assert!(touch.exists(), "{name}: never touched; log:\n{}", out.log);
    let shot = assert_matches_capture("multiview", &out, &pics.join("stereoshim"));
    // RDM reconstructed both views of that frame (else the comparison would not show the order),
    // and the frame's stats line counts the screenshot's views.
    let stats = std::fs::read_to_string(&stats_file).expect("stats.file");
    let line: serde_json::Value = stats
        .lines()
        .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap())
        .find(|l| l["frame"].as_u64() == Some(shot.frame))
        .unwrap_or_else(|| panic!("no stats line for frame {}", shot.frame));
    let reconstructed: u64 = line["rdm"]["reconstructed"].as_object().map(|m| m.values().filter_map(|v| v.as_u64()).sum()).unwrap_or(0);
    assert_eq!(reconstructed, 2, "{line}");
    assert_eq!(line["screenshot"]["views"], 2, "{line}");
    assert_eq!(stats.lines().filter(|l| l.contains("\"screenshot\"")).count(), 1, "one frame had a screenshot");
}

/// One side-by-side swapchain (two rects) of a UNORM format, `screenshot.dir`, with `mask.debug`:
/// the tint is in the pictures as in the capture.
#[test]
fn side_by_side_screenshot_with_mask_tint_equals_the_capture() {
    let pics = target_dir().join("test-output/screenshot-sbs-pictures");
    let _ = std::fs::remove_dir_all(&pics);
    let run = run("screenshot-side-by-side")
        .args(["--layout", "side-by-side", "--color-format", "unorm"])
        .env("STEREOSHIM_MASK_ENABLED", "1")
        .env("STEREOSHIM_MASK_DEBUG", "1")
        .env("STEREOSHIM_SCREENSHOT_DIR", pics.to_str().unwrap());
    let (out, (code, stdout, stderr)) = run_with_screenshot(&run);
    out.assert_ok();
    assert_eq!(code, 0, "{stdout}{stderr}\nlog:\n{}", out.log);
    let shot = assert_matches_capture("side-by-side", &out, &pics);
    common::assert_nothing_tracked(&out);
    for v in &shot.views {
        let n = tinted(&Image::load(&v.file));
        assert!(n > 100, "view {}: only {n} tinted pixels", v.view);
    }
}

/// A folder that cannot be made: the command says why (exit 1), the layer logs it, the app runs
/// to its end.
#[test]
fn unwritable_folder_is_reported_and_the_app_runs_on() {
    let blocker = target_dir().join("test-output/screenshot-blocker");
    let _ = std::fs::remove_dir_all(&blocker);
    std::fs::write(&blocker, b"a file, not a folder").unwrap();
    let run = run("screenshot-unwritable")
        .env("STEREOSHIM_SCREENSHOT_DIR", blocker.join("shots").to_str().unwrap());
    let (out, (code, stdout, stderr)) = run_with_screenshot(&run);
    out.assert_ok();
    // The app ran on past the failed request, to its end.
    assert!(out.frames().frames.len() as u64 > 10 + AFTER, "{} frames", out.frames().frames.len());
    assert_eq!(code, 1, "{stdout}{stderr}");
    assert!(stderr.contains("screenshot-blocker/shots"), "{stderr}");
    assert_eq!(out.log_lines("not written").len(), 1, "{}", out.log);
}

#[test]
fn command_help_and_errors() {
    let dir = common::output_dir("screenshot-cli");
    let (code, stdout, _) = stereoshim(&["screenshot", "--help"], &dir);
    assert_eq!(code, 0);
    assert!(stdout.contains("Usage: stereoshim screenshot") && stdout.contains("--wait") && stdout.contains("--pid"), "{stdout}");
    // No running app: a clear message, exit 1.
    let (code, _, stderr) = stereoshim(&["screenshot"], &dir);
    assert_eq!(code, 1, "{stderr}");
    assert!(stderr.contains("no running app with the stereoshim layer"), "{stderr}");
    // An announced app whose process is gone counts as not running.
    std::fs::create_dir_all(dir.join("run/stereoshim/screenshot")).unwrap();
    std::fs::write(dir.join("run/stereoshim/screenshot/999999999.json"), r#"{"pid":999999999,"app":"gone"}"#).unwrap();
    let (code, _, stderr) = stereoshim(&["screenshot", "--wait"], &dir);
    assert_eq!(code, 1, "{stderr}");
    assert!(stderr.contains("no running app"), "{stderr}");
    assert!(!dir.join("run/stereoshim/screenshot/999999999.trigger").exists());
    // Usage errors: exit 2.
    for bad in [&["screenshot", "--pid", "x"][..], &["screenshot", "--timeout", "0"], &["screenshot", "extra"]] {
        let (code, _, stderr) = stereoshim(bad, &dir);
        assert_eq!(code, 2, "{bad:?}: {stderr}");
        assert!(stderr.contains("error:") && stderr.contains("--help"), "{bad:?}: {stderr}");
    }
}

/// With the upscale on, a screenshot has both images of each view: the app's, at the size it
/// renders at, and the display-size one the upscale made (`-display.png`), which equals the
/// runtime's capture of the same frame.
#[test]
fn upscaled_screenshot_has_the_app_and_the_display_images() {
    let name = "screenshot-upscale";
    let pics = target_dir().join("test-output/screenshot-upscale-pictures");
    let _ = std::fs::remove_dir_all(&pics);
    let run = run(name).env("STEREOSHIM_UPSCALE_ENABLED", "1").env("XDG_PICTURES_DIR", pics.to_str().unwrap());
    let (out, (code, stdout, stderr)) = run_with_screenshot(&run);
    out.assert_ok();
    assert_eq!(code, 0, "{stdout}{stderr}\nlog:\n{}", out.log);
    let mut shots = sidecars(&pics.join("stereoshim"));
    assert_eq!(shots.len(), 1, "one screenshot: {:?}\nlog:\n{}", files(&pics.join("stereoshim")), out.log);
    let shot = shots.remove(0);
    let captured = out.views(shot.frame);
    assert_eq!(shot.views.len(), 2 * captured.len(), "the app's and the display's image of each view: {:?}", shot.views);
    for v in captured {
        let display = shot.views.iter().find(|s| s.view == v.view && s.display).unwrap_or_else(|| panic!("no display image of view {}", v.view));
        assert!(display.file.to_string_lossy().ends_with(&format!("-view-{}-display.png", v.view)), "{}", display.file.display());
        assert_eq!((display.width, display.height), (v.image_rect.width, v.image_rect.height));
        image::assert_identical(&format!("screenshot-upscale-view-{}", v.view), &Image::load(&display.file), &out.image(&v.file));
        let app = shot.views.iter().find(|s| s.view == v.view && !s.display).unwrap_or_else(|| panic!("no app image of view {}", v.view));
        assert!(app.width < display.width && app.height < display.height, "the app's image {}x{} is not the smaller one", app.width, app.height);
    }
}

