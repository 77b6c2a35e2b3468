//! A real, unmodified OpenXR app through the layer: Debian bookworm's own Khronos `hello_xr`
//! 1.0.20 (package `libopenxr-utils`, installed by scripts/setup) on the mock runtime with
//! capture, with both Vulkan graphics plugins (`-g Vulkan2`: XR_KHR_vulkan_enable2, the runtime
//! creates instance and device; `-g Vulkan`: XR_KHR_vulkan_enable, the app does).
//!
//! hello_xr links libvulkan at build time (the symbol-interposition case of issue 8), asks for a
//! Vulkan 1.0 device, enables `VK_LAYER_KHRONOS_validation` itself when it is installed, and
//! renders one per-eye render pass per view (depth cleared by the pass's load op) into a
//! 1024 × 1024 swapchain image per eye (the `simple` HMD's recommended size).
//!
//! Determinism: hello_xr draws cubes at fixed reference-space poses and at the hand action
//! spaces, all of which the mock runtime reports without time dependence, and it clears to a
//! constant colour; so its frames are bit-identical frame to frame and between the two plugins.
//! `plain_runs_are_deterministic` checks exactly that, which is what lets the masked run be
//! compared with a run without the layer pixel by pixel.
//!
//! hello_xr waits on stdin for a key to quit: the harness keeps a pipe to it open (closed stdin
//! would quit it at once) and ends it with `MOCK_XR_EXIT_AFTER`. A run that does not finish in
//! time is killed and fails the test with a backtrace of every thread (gdb, when installed).

use crate::common;

use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use common::image::{self, Image};
use common::{hidden_pixels, mask_edge_pixels, Half, RunOutput};

/// Frames each run submits (frame 0 is never masked: the eye use of the images is not yet known).
const FRAMES: u64 = 3;
/// A run on lavapipe takes a few seconds of CPU time; more than this is a hang, as is a run that
/// uses none for `watchdog::STALL` (`HELLO_XR_CPU_BUDGET_S` overrides the budget).
fn cpu_budget() -> Duration {
    let s = std::env::var("HELLO_XR_CPU_BUDGET_S").ok().and_then(|v| v.parse().ok()).unwrap_or(120);
    Duration::from_secs(s)
}
/// Pixels this close to the mask outline may go either way (vertex snapping, f32 vs f64 mapping).
const EDGE_MARGIN_PX: f64 = 1.0;

fn hello_xr_exe() -> PathBuf {
    let found = std::env::var_os("PATH")
        .into_iter()
        .flat_map(|p| std::env::split_paths(&p).collect::<Vec<_>>())
        .map(|d| d.join("hello_xr"))
        .find(|p| p.is_file());
    found.unwrap_or_else(|| panic!("hello_xr not found: install Debian's libopenxr-utils (scripts/setup does)"))
}

struct HelloRun {
    out: RunOutput,
    /// The layer's `stats.file` records (one JSON object per frame); empty without the layer.
    stats: Vec<serde_json::Value>,
    /// Lines of hello_xr's output reporting a Vulkan validation error.
    validation_errors: Vec<String>,
}

/// Runs hello_xr with graphics plugin `plugin` through the mock runtime, capturing every frame;
/// `layer`: stereoshim as an explicit API layer with the hidden-area mask on.
fn run(name: &str, plugin: &str, layer: bool, env: &[(&str, &str)]) -> HelloRun {
    let dir = common::output_dir(name);
    let capture = dir.join("capture");
    let stats_file = dir.join("layer-stats.jsonl");
    let mut cmd = Command::new(hello_xr_exe());
    common::isolate(&mut cmd, &dir, &capture, layer);
    common::crash::prepare(&mut cmd, &dir);
    cmd.args(["-g", plugin])
        // Runtime diagnostics: every OpenXR call the mock refuses is logged ("xrFunc -> ERROR_…").
        .env("MOCK_XR_LOG", "1")
        .env("MOCK_XR_EXIT_AFTER", FRAMES.to_string())
        // hello_xr writes its validation layer's cache here.
        .env("HOME", &dir)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    if layer {
        cmd.env("STEREOSHIM_MASK_ENABLED", "1")
            .env("STEREOSHIM_STATS_FILE", &stats_file);
    }
    for (k, v) in env {
        cmd.env(k, v);
    }
    let started = Instant::now();
    let mut child = cmd.spawn().expect("spawn hello_xr");
    // Kept open until hello_xr exits: end of input would be its "key pressed, quit".
    let stdin = child.stdin.take();
    let readers = [child.stdout.take().map(drain), child.stderr.take().map(drain)];
    let mut watchdog = common::watchdog::Watchdog::new(child.id(), cpu_budget());
    let status = loop {
        if let Some(s) = child.try_wait().expect("wait for hello_xr") {
            break s;
        }
        if let Some(why) = watchdog.hung() {
            let backtrace = common::crash::live_backtraces(child.id());
            let _ = child.kill();
            let _ = child.wait();
            let output: String = readers.into_iter().flatten().map(|r| r.join().unwrap_or_default()).collect();
            std::fs::write(dir.join("output.txt"), &output).ok();
            panic!(
                "{name}: hello_xr -g {plugin} hung after {:.1?}: {why}; killed.\n\
                 backtrace of every thread:\n{backtrace}\noutput (last 4000 bytes):\n{}",
                started.elapsed(),
                tail(&output, 4000)
            );
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    drop(stdin);
    let output: String = readers.into_iter().flatten().map(|r| r.join().unwrap_or_default()).collect();
    std::fs::write(dir.join("output.txt"), &output).ok();
    let frames = std::fs::read(capture.join("frames.json")).ok().map(|b| serde_json::from_slice(&b).expect("frames.json parses"));
    let log = std::fs::read_to_string(dir.join("state/stereoshim/stereoshim.log")).unwrap_or_default();
    let stats = std::fs::read_to_string(&stats_file)
        .map(|t| t.lines().map(|l| serde_json::from_str(l).expect("stats line parses")).collect())
        .unwrap_or_default();
    let validation_errors = output.lines().filter(|l| l.contains("Validation Error")).map(str::to_string).collect();
    let elapsed = started.elapsed();
    let crash = common::crash::report(&common::crash::Ended { name, dir: &dir, program: &hello_xr_exe(), pid: child.id(), status, elapsed, stderr: &output, log: &log });
    let out = RunOutput { name: name.to_string(), code: status.code(), signal: std::os::unix::process::ExitStatusExt::signal(&status), crash, stderr: output, capture, frames, stats: None, elapsed, log };
    HelloRun { out, stats, validation_errors }
}

fn drain(mut r: impl Read + Send + 'static) -> std::thread::JoinHandle<String> {
    std::thread::spawn(move || {
        let mut buf = Vec::new();
        let _ = r.read_to_end(&mut buf);
        String::from_utf8_lossy(&buf).into_owned()
    })
}

fn tail(s: &str, n: usize) -> &str {
    let mut start = s.len().saturating_sub(n);
    while !s.is_char_boundary(start) {
        start += 1;
    }
    &s[start..]
}

/// `thread apply all bt` of a live process through gdb (attached in batch mode), or why not.
impl HelloRun {
    fn assert_clean_exit(&self) {
        if let Some(report) = &self.out.crash {
            panic!("{}: hello_xr crashed\n{report}", self.out.name);
        }
        assert_eq!(self.out.code, Some(0), "{}: hello_xr failed; output:\n{}", self.out.name, tail(&self.out.stderr, 6000));
        let n = self.out.frames().frames.len() as u64;
        assert_eq!(n, FRAMES, "{}: {n} frames captured", self.out.name);
    }
}

/// The plain runs are bit-identical frame to frame and between the two plugins, and silent under
/// the validation layer hello_xr enables itself.
#[test]
fn plain_runs_are_deterministic() {
    let v2 = run("hello-xr-plain-vulkan2", "Vulkan2", false, &[]);
    v2.assert_clean_exit();
    let v1 = run("hello-xr-plain-vulkan", "Vulkan", false, &[]);
    v1.assert_clean_exit();
    for r in [&v2, &v1] {
        assert!(r.validation_errors.is_empty(), "{}: {:#?}", r.out.name, r.validation_errors);
        // hello_xr's every OpenXR call succeeds on the mock (interaction profiles, action spaces,
        // reference spaces, the frame loop).
        let refused: Vec<&str> = r.out.stderr.lines().filter(|l| l.contains("[mock-runtime]") && l.contains("-> ERROR_")).collect();
        assert!(refused.is_empty(), "{}: the runtime refused calls:\n{}", r.out.name, refused.join("\n"));
        for f in 1..FRAMES {
            common::assert_same_frame(&format!("{}-f0-f{f}", r.out.name), &r.out, 0, &r.out, f);
        }
    }
    common::assert_same_frame("hello-xr-plain-vulkan-vs-vulkan2", &v1.out, 1, &v2.out, 1);
}

/// hello_xr's input reaches it through the mock's interaction profiles: of the five profiles it
/// suggests, the simple controller's menu click (`MOCK_XR_MENU_CLICK_AT`) fires its quit action,
/// and it ends the session itself long before the runtime would.
#[test]
fn menu_click_quits_hello_xr() {
    let r = run("hello-xr-menu-click", "Vulkan2", false, &[("MOCK_XR_EXIT_AFTER", "1000"), ("MOCK_XR_MENU_CLICK_AT", "2")]);
    assert_eq!(r.out.code, Some(0), "{}", tail(&r.out.stderr, 6000));
    assert!(r.out.stderr.contains("Quit action is bound to 'Mock /user/hand/left/input/menu/click'"), "{}", tail(&r.out.stderr, 6000));
    let frames = r.out.frames().frames.len();
    assert!((3..10).contains(&frames), "hello_xr submitted {frames} frames after a menu click at frame 2");
}

/// With the layer and `mask.enabled`: from frame 1 on, pixels outside the runtime's hidden mesh
/// (frames.json, rasterized by the harness) are bit-identical to the run without the layer;
/// inside it every pixel is hello_xr's clear colour (the app's fragments there fail the depth
/// test against the mask); the mask hides some of what the app draws (the hand cubes reach into
/// the lens corners); the layer's stats show both eye passes of every frame after the first
/// masked, with its masked-pixel counts matching the harness's within the outline.
fn check_masked(plugin: &str, hmd: &str) {
    let tag = format!("hello-xr-{}-{hmd}", plugin.to_lowercase());
    let env = [("MOCK_XR_HMD", hmd)];
    let plain = run(&format!("{tag}-plain"), plugin, false, &env);
    plain.assert_clean_exit();
    let masked = run(&format!("{tag}-masked"), plugin, true, &env);
    masked.assert_clean_exit();
    let name = &masked.out.name;
    masked.out.assert_log_lacks(Half::Both, "internal failure");
    // hello_xr's own validation layer (in its create info, below the layer) stays silent about
    // what the layer creates on its Vulkan 1.0 device.
    assert!(masked.validation_errors.is_empty(), "{name}: {} validation errors:\n{}", masked.validation_errors.len(), masked.validation_errors.join("\n"));

    // Frame 0: eye uses unknown, nothing masked.
    common::assert_same_frame(&format!("{tag}-f0"), &masked.out, 0, &plain.out, 0);
    for f in 1..FRAMES {
        let frame = masked.out.frame(f);
        assert_eq!(frame.visibility_masks.len(), 2, "{name}: frames.json has no visibility_masks");
        let record = masked.stats.iter().find(|r| r["frame"] == f).unwrap_or_else(|| panic!("{name}: no stats for frame {f}: {:?}", masked.stats));
        assert_eq!(record["mask_enabled"], true, "{name} frame {f}: {record}");
        assert_eq!(record["passes_masked"], 2, "{name} frame {f}: both eye passes masked: {record}");
        assert!(record["not_masked"].as_object().is_some_and(|o| o.is_empty()), "{name} frame {f}: {record}");
        let mut hidden_by_mask = 0;
        for (a, b) in common::views_to_compare(name, &masked.out, f, &plain.out, f) {
            let mask = &frame.visibility_masks.iter().find(|m| m.view == a.view).expect("mask of view").hidden_triangles;
            let (w, h) = (a.image_rect.width, a.image_rect.height);
            let hidden = hidden_pixels(mask, &a.fov, w, h);
            let edge = mask_edge_pixels(mask, &a.fov, w, h, EDGE_MARGIN_PX);
            let (got, want) = (masked.out.image(&a.file), plain.out.image(&b.file));
            // hello_xr's clear colour: the top-left corner is hidden on every profile and hello_xr
            // draws nothing there.
            assert!(hidden[0], "{name}: corner not hidden");
            let clear = want.pixel(0, 0).to_vec();
            let mut bad = Vec::new();
            for y in 0..h {
                for x in 0..w {
                    let i = (y * w + x) as usize;
                    let g = got.pixel(x, y);
                    if edge[i] {
                        if g != want.pixel(x, y) && g != clear.as_slice() {
                            bad.push((x, y, "edge"));
                        }
                    } else if hidden[i] {
                        if g != clear.as_slice() {
                            bad.push((x, y, "inside"));
                        }
                        if want.pixel(x, y) != clear.as_slice() {
                            hidden_by_mask += 1;
                        }
                    } else if g != want.pixel(x, y) {
                        bad.push((x, y, "outside"));
                    }
                }
            }
            if !bad.is_empty() {
                let dir = image::artifacts_dir(&format!("{tag}-f{f}-view{}", a.view));
                got.save(&dir.join("actual.png"));
                want.save(&dir.join("expected.png"));
                image::difference(&got, &want).save(&dir.join("difference.png"));
                save_coverage(&hidden, w, h, &dir.join("hidden.png"));
                panic!("{name} frame {f} view {}: {} wrong pixels, first {:?}; artifacts in {}", a.view, bad.len(), &bad[..bad.len().min(8)], dir.display());
            }
            let hidden_count = hidden.iter().filter(|&&b| b).count() as u64;
            let layer_count = record["pixels_masked"][a.view.to_string()].as_u64().unwrap_or_else(|| panic!("{name}: {record}"));
            assert!(hidden_count.abs_diff(layer_count) * 100 <= hidden_count, "{name} frame {f} view {}: layer masked {layer_count}, harness {hidden_count}", a.view);
            eprintln!("{name} frame {f} view {}: {hidden_count} px hidden ({:.1} %)", a.view, 100.0 * hidden_count as f64 / (w * h) as f64);
        }
        assert!(hidden_by_mask > 0, "{name} frame {f}: the mask hid nothing hello_xr drew");
    }
}

fn save_coverage(c: &[bool], w: u32, h: u32, path: &Path) {
    let data = c.iter().flat_map(|&b| if b { [255u16; 3] } else { [0; 3] }).collect();
    Image { width: w, height: h, channels: 3, bit_depth: 8, data }.save(path);
}

#[test]
fn vulkan2_masked_outside_bit_identical() {
    check_masked("Vulkan2", "simple");
}

#[test]
fn vulkan_masked_outside_bit_identical() {
    check_masked("Vulkan", "simple");
}

/// The Index profile: the published SteamVR hidden-area mesh, asymmetric FOV, 2016 × 2240.
#[test]
fn vulkan2_masked_index_hmd() {
    check_masked("Vulkan2", "index");
}

#[test]
fn vulkan_masked_index_hmd() {
    check_masked("Vulkan", "index");
}

/// Mask and radial density masking together, both plugins: from frame 1 on both eye passes are
/// masked and RDM-applied (one reconstruction per view), and validation stays silent.
#[test]
fn mask_and_rdm_apply_validation_clean() {
    for plugin in ["Vulkan2", "Vulkan"] {
        let env = [("STEREOSHIM_FOVEATION_ENABLED", "1"), ("STEREOSHIM_FOVEATION_METHOD", "rdm")];
        let r = run(&format!("hello-xr-mask-rdm-{}", plugin.to_lowercase()), plugin, true, &env);
        r.assert_clean_exit();
        assert!(r.validation_errors.is_empty(), "{}: {} validation errors:\n{}", r.out.name, r.validation_errors.len(), r.validation_errors.join("\n"));
        for f in 1..FRAMES {
            let record = r.stats.iter().find(|x| x["frame"] == f).unwrap_or_else(|| panic!("{}: no stats for frame {f}", r.out.name));
            assert_eq!(record["passes_masked"], 2, "{} frame {f}: {record}", r.out.name);
            assert_eq!(record["rdm"]["passes"], 2, "{} frame {f}: {record}", r.out.name);
            for view in ["0", "1"] {
                assert_eq!(record["rdm"]["reconstructed"][view], 1, "{} frame {f}: {record}", r.out.name);
                assert!(record["rdm"]["pixels_skipped"][view].as_u64().is_some_and(|n| n > 0), "{} frame {f}: {record}", r.out.name);
            }
        }
    }
}

/// Validation enabled the usual way, through `VK_INSTANCE_LAYERS` (a handle-wrapping layer that
/// may sit above the layer): the eye passes are still recognised and masked, both plugins.
#[test]
fn masked_under_validation_from_vk_instance_layers() {
    for plugin in ["Vulkan2", "Vulkan"] {
        let r = run(&format!("hello-xr-vk-instance-layers-{}", plugin.to_lowercase()), plugin, true, &[("VK_INSTANCE_LAYERS", "VK_LAYER_KHRONOS_validation")]);
        r.assert_clean_exit();
        assert!(r.validation_errors.is_empty(), "{}: {} validation errors:\n{}", r.out.name, r.validation_errors.len(), r.validation_errors.join("\n"));
        for f in 1..FRAMES {
            let record = r.stats.iter().find(|x| x["frame"] == f).unwrap_or_else(|| panic!("{}: no stats for frame {f}", r.out.name));
            assert_eq!(record["passes_masked"], 2, "{} frame {f}: {record}", r.out.name);
        }
    }
}

/// The monoscopic far field on a real app: hello_xr submits no depth info, so its projection
/// range comes from config (it renders with near 0.05 m, far 100 m); its passes store no depth,
/// so the layer keeps it. hello_xr's scene is all near cubes over its clear colour: the reused
/// far field is the clear colour, and every frame is bit-identical to the run without the layer
/// (both plugins: Vulkan 1.0 render passes), validation clean, with destination views reused.
#[test]
fn far_field_on_hello_xr_is_bit_identical() {
    for plugin in ["Vulkan2", "Vulkan"] {
        let tag = format!("hello-xr-far-{}", plugin.to_lowercase());
        let plain = run(&format!("{tag}-plain"), plugin, false, &[]);
        plain.assert_clean_exit();
        let env = [("STEREOSHIM_MASK_ENABLED", "0"), ("STEREOSHIM_FAR_FIELD_ENABLED", "1"), ("STEREOSHIM_FAR_FIELD_NEAR_Z", "0.05"), ("STEREOSHIM_FAR_FIELD_FAR_Z", "100")];
        let far = run(&format!("{tag}-far"), plugin, true, &env);
        far.assert_clean_exit();
        far.out.assert_log_lacks(Half::Both, "internal failure");
        assert!(far.validation_errors.is_empty(), "{tag}: {} validation errors:\n{}", far.validation_errors.len(), far.validation_errors.join("\n"));
        common::assert_same_captures(&tag, &far.out, &plain.out);
        let reused: u64 = far.stats.iter().filter_map(|r| r["far_field"]["views_reused"]["1"].as_u64()).sum();
        assert!(reused >= FRAMES - 2, "{tag}: the destination view reused the far field in {reused} frames: {:?}\n{}", far.stats, far.out.log);
    }
}

/// A screenshot of hello_xr (its own swapchain format, per-eye swapchains and frame loop) asked
/// for mid-run with `stereoshim screenshot --wait`: each view's picture equals the runtime's
/// capture of the frame the layer names, and the app ends cleanly.
#[test]
fn screenshot_of_hello_xr_equals_the_capture() {
    let name = "hello-xr-screenshot";
    let dir = common::target_dir().join("test-output").join(name);
    // Nothing of an earlier run may look like this one's progress to the asker.
    let _ = std::fs::remove_dir_all(&dir);
    let pictures = common::target_dir().join("test-output/hello-xr-screenshot-pictures");
    let _ = std::fs::remove_dir_all(&pictures);
    // hello_xr runs until the asker is done (`MOCK_XR_EXIT_ON`), not for a frame count a loaded
    // machine could use up before the request reached the layer.
    let stop = common::target_dir().join("test-output/hello-xr-screenshot.stop");
    let _ = std::fs::remove_file(&stop);
    let asker = {
        let (dir, stop) = (dir.clone(), stop.clone());
        std::thread::spawn(move || {
            let folder = dir.join("run/stereoshim/screenshot");
            let answer = loop {
                let announced = std::fs::read_dir(&folder).is_ok_and(|d| {
                    d.flatten().any(|e| e.file_name().to_str().and_then(stereoshim::features::screenshot::rules::instance_pid).is_some())
                });
                if announced && dir.join("capture/frame-00003-view-0.png").exists() {
                    let out = Command::new(common::target_dir().join("stereoshim"))
                        .args(["screenshot", "--wait", "--timeout", "600"])
                        .env("XDG_RUNTIME_DIR", dir.join("run"))
                        .output()
                        .expect("run stereoshim");
                    break Some((out.status.code(), String::from_utf8_lossy(&out.stdout).into_owned(), String::from_utf8_lossy(&out.stderr).into_owned()));
                }
                // hello_xr ended (or never started) without the layer announcing itself.
                if dir.join("output.txt").exists() {
                    break None;
                }
                std::thread::sleep(Duration::from_millis(20));
            };
            std::fs::write(&stop, b"").unwrap();
            answer
        })
    };
    let r = run(
        name,
        "Vulkan2",
        true,
        &[("MOCK_XR_EXIT_AFTER", ""), ("MOCK_XR_EXIT_ON", stop.to_str().unwrap()), ("STEREOSHIM_SCREENSHOT_DIR", pictures.to_str().unwrap())],
    );
    let asked = asker.join().expect("asker");
    assert_eq!(r.out.code, Some(0), "{name}: hello_xr failed; output:\n{}", tail(&r.out.stderr, 6000));
    assert!(r.validation_errors.is_empty(), "{name}: {:#?}", r.validation_errors);
    let (code, stdout, stderr) = asked.unwrap_or_else(|| panic!("{name}: never asked; log:\n{}", r.out.log));
    assert_eq!(code, Some(0), "{stdout}{stderr}\nlog:\n{}", r.out.log);
    let sidecar = std::fs::read_dir(&pictures).unwrap().flatten().map(|e| e.path()).find(|p| p.extension().is_some_and(|x| x == "json")).expect("the screenshot's JSON");
    let shot: serde_json::Value = serde_json::from_slice(&std::fs::read(&sidecar).unwrap()).unwrap();
    let frame = shot["frame"].as_u64().expect("frame");
    assert!(frame >= 3, "{shot}");
    let views = r.out.views(frame);
    assert_eq!(stdout.lines().count(), views.len(), "{stdout}");
    for v in views {
        let file = shot["views"].as_array().unwrap().iter().find(|x| x["view"] == v.view).and_then(|x| x["file"].as_str()).unwrap_or_else(|| panic!("no view {} in {shot}", v.view));
        assert!(stdout.lines().any(|l| l == file), "{stdout}");
        image::assert_identical(&format!("{name}-view-{}", v.view), &Image::load(Path::new(file)), &r.out.image(&v.file));
    }
}

/// The FOV cut (`view.fov_cut = lens`) with hello_xr, on the mock's Index profile at a quarter of
/// its recommended size (hello_xr renders at the recommended size itself). Each view is the crop
/// of the run without the cut, bit for bit, at the cut size; validation clean, the cut kept on.
/// (xr-scene's differ in a few pixels: docs/views.md.)
#[test]
fn fov_cut_on_hello_xr() {
    for plugin in ["Vulkan2", "Vulkan"] {
        let tag = format!("hello-xr-cut-{}", plugin.to_lowercase());
        let base = [("MOCK_XR_HMD", "index"), ("MOCK_XR_RECOMMENDED_SCALE", "0.25"), ("STEREOSHIM_MASK_ENABLED", "0")];
        let uncut = run(&format!("{tag}-uncut"), plugin, true, &base);
        uncut.assert_clean_exit();
        let with_cut: Vec<(&str, &str)> = base.iter().copied().chain([("STEREOSHIM_VIEW_FOV_CUT", "lens")]).collect();
        let cut = run(&format!("{tag}-cut"), plugin, true, &with_cut);
        cut.assert_clean_exit();
        cut.out.assert_log_lacks(Half::Both, "internal failure");
        assert!(cut.validation_errors.is_empty(), "{tag}: {} validation errors:\n{}", cut.validation_errors.len(), cut.validation_errors.join("\n"));
        let lines = cut.out.log_lines("view.fov_cut");
        assert!(lines.iter().any(|l| l.contains("the lens from")), "{tag}: not cut: {lines:?}");
        assert!(cut.out.log_lines("the cut is off").is_empty(), "{tag}: the cut was turned off: {lines:?}");
        let cut_of = |v: u32| -> (u32, u32, u32, u32) {
            let line = lines.iter().find(|l| l.contains(&format!("view.fov_cut: view {v}:"))).expect("cut line");
            let pixels = line.split("(pixels ").nth(1).and_then(|s| s.split(')').next()).expect("pixels");
            let n: Vec<u32> = pixels.split(|c: char| !c.is_ascii_digit()).filter(|s| !s.is_empty()).map(|s| s.parse().unwrap()).collect();
            (n[0], n[2], n[1] - n[0], n[3] - n[2])
        };
        for f in 1..FRAMES {
            for (a, b) in cut.out.views(f).iter().zip(uncut.out.views(f)) {
                let (x0, y0, w, h) = cut_of(a.view);
                assert_eq!((a.image_rect.width, a.image_rect.height), (w, h), "{tag} frame {f} view {}: not the cut size", a.view);
                assert!(w < b.image_rect.width || h < b.image_rect.height, "{tag} view {}: nothing cut", a.view);
                let (ia, ib) = (cut.out.image(&a.file), uncut.out.image(&b.file));
                let differ = (0..h).flat_map(|y| (0..w).map(move |x| (x, y))).filter(|&(x, y)| ia.pixel(x, y) != ib.pixel(x0 + x, y0 + y)).count() as u32;
                eprintln!("{tag} frame {f} view {}: {}x{} -> {w}x{h}, {differ} pixels differ from the crop at ({x0}, {y0})", a.view, b.image_rect.width, b.image_rect.height);
                assert_eq!(differ, 0, "{tag} frame {f} view {}: {differ} pixels differ from the crop", a.view);
            }
        }
    }
}
