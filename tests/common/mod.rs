//! Shared end-to-end harness: runs `xr-scene` through the mock runtime (and, later, the layer),
//! collects what the runtime captured, and compares images with artifacts a person can look at.
#![allow(dead_code)] // each test binary uses a different subset

pub mod crash;
pub mod far_field;
pub mod geometry;
pub mod image;
pub mod post_chain;
pub mod rdm;
pub mod watchdog;

// The geometry helpers where the tests have always found them (`common::project`, …); each test
// binary uses a different subset, as with `dead_code` above.
#[allow(unused_imports)]
pub use geometry::{hidden_pixels, mask_edge_pixels, project, tangent_to_pixel, triangle_pixels};

use serde::Deserialize;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::atomic::{AtomicUsize, Ordering};

/// `target/<profile>/`, found from the running test executable (`target/<profile>/deps/<test>`),
/// so the harness works whatever `CARGO_TARGET_DIR` is.
pub fn target_dir() -> PathBuf {
    let exe = std::env::current_exe().expect("test executable path");
    exe.parent().and_then(Path::parent).expect("target/<profile>/deps/<exe>").to_path_buf()
}

pub fn xr_scene_exe() -> PathBuf {
    let p = target_dir().join("xr-scene");
    assert!(p.exists(), "{} missing: run `cargo build --workspace` first (scripts/test does)", p.display());
    p
}

/// A fresh directory under `target/test-output/` for one run; removed and recreated so stale
/// captures from an earlier run can never make a test pass.
pub fn output_dir(name: &str) -> PathBuf {
    let dir = target_dir().join("test-output").join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("create test output dir");
    dir
}

/// Writes a runtime manifest with the absolute path of the built mock runtime. The loader reads
/// `library_path` relative to the manifest, so an absolute one keeps it independent of the cwd.
pub fn runtime_manifest() -> PathBuf {
    let lib = target_dir().join("libmock_runtime.so");
    assert!(lib.exists(), "{} missing: run `cargo build --workspace` first", lib.display());
    let dir = target_dir().join("test-output");
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("mock-runtime.json");
    let json = serde_json::json!({
        "file_format_version": "1.0.0",
        "runtime": { "name": "stereoshim mock runtime", "library_path": lib },
    });
    // Written to a unique temp name and renamed, so concurrent tests never read a partial file.
    static N: AtomicUsize = AtomicUsize::new(0);
    let tmp = dir.join(format!(".mock-runtime.{}.{}", std::process::id(), N.fetch_add(1, Ordering::Relaxed)));
    std::fs::write(&tmp, serde_json::to_vec_pretty(&json).unwrap()).unwrap();
    std::fs::rename(&tmp, &path).unwrap();
    path
}

/// Held while a test reads, or reads and rewrites, a file of the repository that another test of
/// the same binary rewrites: docs/faults.md, whose `## OpenXR` table is tests/hardening/faults_xr.rs's
/// and whose `## Vulkan` table is tests/hardening/faults_vk.rs's (`STEREOSHIM_UPDATE_DOCS=1`). The
/// tests of one binary are threads of one process: without it one rewrite could drop the other's
/// table, or a comparison read the file half written.
pub static REPO_DOCS: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// The CPU time an xr-scene run may use before it counts as a hang (`Run::run`): far above the
/// longest run of the suite (seconds), and CPU time, so a loaded machine does not reach it.
pub const DEFAULT_CPU_BUDGET: std::time::Duration = std::time::Duration::from_secs(600);

/// One xr-scene invocation: app flags plus mock-runtime environment.
#[derive(Clone, Debug)]
pub struct Run {
    pub name: String,
    pub args: Vec<String>,
    pub env: Vec<(String, String)>,
    pub validation: bool,
    /// Text of `$XDG_CONFIG_HOME/stereoshim/config.toml` for this run.
    pub config_toml: Option<String>,
    /// Load stereoshim as an explicit OpenXR API layer.
    pub layer: bool,
    /// Run the app through this program (e.g. `stereoshim run --`), prepended to the command.
    pub wrapper: Vec<std::ffi::OsString>,
    /// Pass `--pixel-stats <run dir>/pixel-stats` (read back with `RunOutput::pixel_counts`).
    pub pixel_stats: bool,
}

impl Run {
    /// Small images (tests run on a 2-core software rasterizer), two frames, frame 1 captured
    /// (frame 0 is captured too: some tests compare frames), validation on.
    pub fn new(name: &str) -> Run {
        Run {
            name: name.to_string(),
            args: vec!["--scale".into(), "0.25".into()],
            env: vec![("MOCK_XR_EXIT_AFTER".into(), "2".into())],
            validation: true,
            config_toml: None,
            layer: false,
            wrapper: Vec::new(),
            pixel_stats: false,
        }
    }
    pub fn args<I: IntoIterator<Item = S>, S: Into<String>>(mut self, args: I) -> Run {
        self.args.extend(args.into_iter().map(Into::into));
        self
    }
    pub fn env(mut self, k: &str, v: &str) -> Run {
        self.env.retain(|(key, _)| key != k);
        self.env.push((k.into(), v.into()));
        self
    }

    /// Enables stereoshim as an explicit API layer (the way `stereoshim run` does).
    pub fn with_layer(mut self) -> Run {
        self.layer = true;
        self
    }
    pub fn pixel_stats(mut self) -> Run {
        self.pixel_stats = true;
        self
    }
    pub fn config(mut self, toml: &str) -> Run {
        self.config_toml = Some(toml.to_string());
        self
    }

    /// Runs the app to its end. A hang fails the test with every thread's backtrace
    /// ([`Run::run_while`] with [`DEFAULT_CPU_BUDGET`]).
    pub fn run(&self) -> RunOutput {
        self.run_while(DEFAULT_CPU_BUDGET, |_| {})
    }

    /// Like [`Run::run`], but calls `during(run dir)` every few milliseconds while the app runs,
    /// e.g. to rewrite the layer's config file ([`Run::config_file`]) after some frames. The app
    /// is a hang, killed after every thread's backtrace is taken (and the test fails), when its
    /// process tree uses more than `cpu_budget` of CPU time or none at all for
    /// [`watchdog::STALL`]: never because the machine is busy with other work.
    pub fn run_while(&self, cpu_budget: std::time::Duration, mut during: impl FnMut(&Path)) -> RunOutput {
        let (dir, mut cmd) = self.prepare();
        // To a file, not a pipe: nobody reads a pipe while the app runs, and a full one would
        // block it.
        let stderr_path = dir.join("stderr.txt");
        cmd.stdout(std::process::Stdio::null()).stderr(std::fs::File::create(&stderr_path).expect("stderr file"));
        let started = std::time::Instant::now();
        let mut child = cmd.spawn().expect("spawn xr-scene");
        let mut watchdog = watchdog::Watchdog::new(child.id(), cpu_budget);
        let status = loop {
            if let Some(status) = child.try_wait().expect("wait for xr-scene") {
                break status;
            }
            if let Some(why) = watchdog.hung() {
                let backtraces = crash::live_backtraces(child.id());
                let _ = child.kill();
                let _ = child.wait();
                let log = std::fs::read_to_string(dir.join("state/stereoshim/stereoshim.log")).unwrap_or_default();
                panic!(
                    "=== HANG: {}: xr-scene hung after {:.1?}: {why}; killed; run folder kept: {} ===\n\
                     --- stderr ---\n{}\n--- layer log, last 40 lines ---\n{}\n--- every thread's backtrace (gdb) ---\n{backtraces}",
                    self.name,
                    started.elapsed(),
                    dir.display(),
                    std::fs::read_to_string(&stderr_path).unwrap_or_default(),
                    crash::tail_lines(&log, 40)
                );
            }
            during(&dir);
            std::thread::sleep(std::time::Duration::from_millis(5));
        };
        let elapsed = started.elapsed();
        let stderr = std::fs::read_to_string(&stderr_path).unwrap_or_default();
        self.collect(&dir, &cmd, child.id(), status, stderr, elapsed)
    }

    /// The layer's config file of a run in `dir` (`$XDG_CONFIG_HOME/stereoshim/config.toml`).
    pub fn config_file(dir: &Path) -> PathBuf {
        dir.join("config/stereoshim/config.toml")
    }

    /// The run's fresh folder and the app's command, ready to start.
    fn prepare(&self) -> (PathBuf, Command) {
        let dir = output_dir(&self.name);
        let capture = dir.join("capture");
        let stats = dir.join("stats.json");
        if let Some(text) = &self.config_toml {
            std::fs::create_dir_all(dir.join("config/stereoshim")).unwrap();
            std::fs::write(Run::config_file(&dir), text).unwrap();
        }
        let mut cmd = match self.wrapper.split_first() {
            Some((program, rest)) => {
                let mut c = Command::new(program);
                c.args(rest).arg(xr_scene_exe());
                c
            }
            None => Command::new(xr_scene_exe()),
        };
        cmd.args(&self.args).arg("--stats").arg(&stats);
        if self.validation {
            cmd.arg("--validation");
        }
        if self.pixel_stats {
            cmd.arg("--pixel-stats").arg(dir.join("pixel-stats"));
        }
        isolate(&mut cmd, &dir, &capture, self.layer);
        crash::prepare(&mut cmd, &dir);
        for (k, v) in &self.env {
            cmd.env(k, v);
        }
        (dir, cmd)
    }

    /// Reads what a finished run (process `pid` of `cmd`) left in `dir`; a death by signal is
    /// reported at once (`crash::report`).
    fn collect(&self, dir: &Path, cmd: &Command, pid: u32, status: std::process::ExitStatus, stderr: String, elapsed: std::time::Duration) -> RunOutput {
        use std::os::unix::process::ExitStatusExt;
        let capture = dir.join("capture");
        std::fs::write(dir.join("stderr.txt"), &stderr).ok();
        let frames = std::fs::read(capture.join("frames.json"))
            .ok()
            .map(|b| serde_json::from_slice::<Frames>(&b).expect("frames.json parses"));
        let stats = std::fs::read(dir.join("stats.json"))
            .ok()
            .map(|b| serde_json::from_slice::<Stats>(&b).expect("stats.json parses"));
        let log = std::fs::read_to_string(dir.join("state/stereoshim/stereoshim.log")).unwrap_or_default();
        let program = PathBuf::from(cmd.get_program());
        let crash = crash::report(&crash::Ended { name: &self.name, dir, program: &program, pid, status, elapsed, stderr: &stderr, log: &log });
        RunOutput { name: self.name.clone(), code: status.code(), signal: status.signal(), crash, stderr, capture, frames, stats, elapsed, log }
    }
}

/// `base` through the layer with the mask, RDM and the far field on, as run `name` (every
/// feature there is: tests/hardening/lifecycle.rs, tests/hardening/threads.rs).
pub fn every_feature(base: Run, name: &str) -> Run {
    let mut run = base
        .with_layer()
        .env("STEREOSHIM_MASK_ENABLED", "1")
        .env("STEREOSHIM_FOVEATION_ENABLED", "1")
        .env("STEREOSHIM_FOVEATION_METHOD", "rdm")
        .env("STEREOSHIM_FAR_FIELD_ENABLED", "1");
    run.name = name.into();
    run
}

/// Every device stats line says the layer tracks nothing of the app's objects any more (the app
/// destroyed them all before its device): no state kept across sessions, swapchains or instances.
/// And none of the layer's own Vulkan objects outlives its teardown at `vkDestroyDevice`.
pub fn assert_nothing_tracked(out: &RunOutput) {
    assert!(!out.log.contains("the layer's own objects still alive"), "{}", out.log);
    let lines = out.log_lines("vulkan device stats");
    assert!(!lines.is_empty(), "no device stats line:\n{}", out.log);
    for l in lines {
        let live: Vec<&str> = l.split_whitespace().filter(|w| w.starts_with("live.")).collect();
        assert_eq!(live.len(), 8, "{l}");
        assert!(live.iter().all(|w| w.ends_with("=0")), "the layer still tracks destroyed objects: {live:?}");
        // The layer's own Vulkan objects (`own.*`, src/vk/own.rs) are listed there too, and all
        // destroyed right after it.
        assert_eq!(l.split_whitespace().filter(|w| w.starts_with("own.")).count(), 15, "{l}");
    }
    assert_tables_empty(out);
}

/// After each `vkDestroyInstance` and `xrDestroyInstance` (the app destroyed its devices and
/// sessions before, or with, their instance) the layer keys nothing by a handle any more: no
/// instance, device, own-object counting table, session or swapchain outlives its object. A
/// removal that looked up the wrong key (issue 23: the dispatch key read from a freed `VkDevice`)
/// shows here as a count above 0.
pub fn assert_tables_empty(out: &RunOutput) {
    for prefix in ["vulkan layer tables:", "openxr layer tables:"] {
        let lines = out.log_lines(prefix);
        assert!(!lines.is_empty(), "{}: no {prefix:?} line:\n{}", out.name, out.log);
        for l in lines {
            let counts: Vec<&str> = l.split_once(prefix).map(|(_, r)| r).unwrap_or_default().split_whitespace().collect();
            assert!(counts.len() >= 3, "{l}");
            assert!(counts.iter().all(|w| w.ends_with("=0")), "{}: the layer still keys state by a handle that is gone: {l}", out.name);
        }
    }
}

/// Prepares an app's command for one run in `dir`: the mock runtime capturing into `capture`,
/// nothing from the developer's own setup (layers, layer paths, config) leaking in, per-run XDG
/// folders (the generated Vulkan manifest goes to `$XDG_RUNTIME_DIR`, the layer's log to
/// `$XDG_STATE_HOME`), and stereoshim as an explicit API layer when `layer`. Shared by every
/// launcher (xr-scene's `Run`, hello_xr's), so none can drift.
pub fn isolate(cmd: &mut Command, dir: &Path, capture: &Path, layer: bool) {
    cmd.env("XR_RUNTIME_JSON", runtime_manifest())
        .env("MOCK_XR_CAPTURE", capture)
        .env_remove("XR_ENABLE_API_LAYERS")
        .env_remove("XR_API_LAYER_PATH")
        .env_remove("VK_INSTANCE_LAYERS")
        .env_remove("VK_ADD_LAYER_PATH")
        .env("XDG_RUNTIME_DIR", dir.join("run"))
        .env("XDG_DATA_HOME", dir.join("data"))
        .env("XDG_CONFIG_HOME", dir.join("config"))
        .env("XDG_STATE_HOME", dir.join("state"));
    // The developer's own STEREOSHIM_* settings (STEREOSHIM_CONFIG, STEREOSHIM_ENABLED=0, a
    // feature switched on, STEREOSHIM_DISABLE, …) would change what every run tests, or let a
    // check pass because the layer did nothing: a run sets the ones it wants after this.
    for (key, _) in std::env::vars_os() {
        if key.to_string_lossy().starts_with("STEREOSHIM_") {
            cmd.env_remove(key);
        }
    }
    if layer {
        cmd.env("XR_API_LAYER_PATH", layer_manifest_dir()).env("XR_ENABLE_API_LAYERS", XR_LAYER_NAME);
    }
}

/// Whether a comparison of two captures also requires their submitted depth to agree.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DepthCheck {
    /// Depth is submitted for the same views in both (or in neither), with the same image sizes,
    /// and its images are compared too.
    Compare,
    /// Only colour is compared: for runs that differ in `--submit-depth` on purpose.
    Ignore,
}

/// The projection views of frame `fa` of `a` paired with those of frame `fb` of `b` (every
/// projection layer, in order), for an image-by-image comparison; `Err` says why the two frames
/// cannot be compared that way, so that a comparison never passes by comparing less than both
/// runs captured: a frame is missing; the frames' layers differ in number or type; a projection
/// layer's view ids differ (count or order); a view's image size differs or is empty; with
/// [`DepthCheck::Compare`], depth is present in one view and not in the other, or its size
/// differs; or there is no projection view at all (nothing to compare). "left" is `a`, "right" `b`.
pub fn pair_frame<'a>(a: &'a Frames, fa: u64, b: &'a Frames, fb: u64, depth: DepthCheck) -> Result<Vec<(&'a View, &'a View)>, String> {
    let find = |f: &'a Frames, n: u64, side: &str| f.frames.iter().find(|x| x.frame == n).ok_or_else(|| format!("frame {n} not captured on the {side}"));
    let (x, y) = (find(a, fa, "left")?, find(b, fb, "right")?);
    let kinds = |f: &Frame| f.layers.iter().map(|l| l.kind.clone()).collect::<Vec<_>>();
    if kinds(x) != kinds(y) {
        return Err(format!("layers differ: left frame {fa} {:?}, right frame {fb} {:?}", kinds(x), kinds(y)));
    }
    let mut pairs = Vec::new();
    for (i, (la, lb)) in x.layers.iter().zip(&y.layers).enumerate().filter(|(_, (l, _))| l.kind == "projection") {
        let ids = |l: &Layer| l.views.iter().map(|v| v.view).collect::<Vec<_>>();
        if ids(la) != ids(lb) {
            return Err(format!("layer {i}: views differ: left frame {fa} {:?}, right frame {fb} {:?}", ids(la), ids(lb)));
        }
        for (va, vb) in la.views.iter().zip(&lb.views) {
            let v = va.view;
            let size = |r: &Rect| (r.width, r.height);
            if size(&va.image_rect) != size(&vb.image_rect) {
                return Err(format!("layer {i} view {v}: image sizes differ: left {:?}, right {:?}", size(&va.image_rect), size(&vb.image_rect)));
            }
            if va.image_rect.width == 0 || va.image_rect.height == 0 {
                return Err(format!("layer {i} view {v}: empty image {:?}: nothing to compare", size(&va.image_rect)));
            }
            if depth == DepthCheck::Compare {
                match (&va.depth, &vb.depth) {
                    (Some(da), Some(db)) if size(&da.image_rect) != size(&db.image_rect) => {
                        return Err(format!(
                            "layer {i} view {v}: depth image sizes differ: left {:?}, right {:?}",
                            size(&da.image_rect),
                            size(&db.image_rect)
                        ));
                    }
                    (Some(_), None) | (None, Some(_)) => {
                        let side = |d: &Option<DepthInfo>| if d.is_some() { "depth" } else { "no depth" };
                        return Err(format!("layer {i} view {v}: left has {}, right has {}", side(&va.depth), side(&vb.depth)));
                    }
                    _ => {}
                }
            }
            pairs.push((va, vb));
        }
    }
    if pairs.is_empty() {
        return Err(format!("no projection view captured in left frame {fa} / right frame {fb}: nothing to compare"));
    }
    Ok(pairs)
}

/// Every captured frame of `a` paired with the same frame of `b` ([`pair_frame`] each); `Err`
/// when the runs captured different frames (count or numbers), different HMD profiles, or no
/// frame at all.
#[allow(clippy::type_complexity)]
pub fn pair_captures<'a>(a: &'a Frames, b: &'a Frames, depth: DepthCheck) -> Result<Vec<(u64, Vec<(&'a View, &'a View)>)>, String> {
    let numbers = |f: &Frames| f.frames.iter().map(|x| x.frame).collect::<Vec<_>>();
    let (na, nb) = (numbers(a), numbers(b));
    if na.is_empty() || nb.is_empty() {
        return Err(format!("nothing to compare: left captured frames {na:?}, right {nb:?}"));
    }
    if na != nb {
        return Err(format!("captured frames differ: left {na:?}, right {nb:?}"));
    }
    if a.hmd != b.hmd {
        return Err(format!("HMD profiles differ: left {:?}, right {:?}", a.hmd, b.hmd));
    }
    na.into_iter().map(|n| pair_frame(a, n, b, n, depth).map(|p| (n, p)).map_err(|e| format!("frame {n}: {e}"))).collect()
}

/// Asserts that `a` and `b` captured the same frames with the same views, image sizes and depth
/// presence (see [`pair_captures`]), and that every image (colour and depth, every frame) of `a`
/// equals the one of the same frame and view in `b`.
pub fn assert_same_captures(label: &str, a: &RunOutput, b: &RunOutput) {
    compare_captures(label, a, b, DepthCheck::Compare);
}

/// [`assert_same_captures`] for colour only: for runs that differ in submitting depth on purpose.
pub fn assert_same_colour_captures(label: &str, a: &RunOutput, b: &RunOutput) {
    compare_captures(label, a, b, DepthCheck::Ignore);
}

fn compare_captures(label: &str, a: &RunOutput, b: &RunOutput, depth: DepthCheck) {
    let frames = pair_captures(a.frames(), b.frames(), depth)
        .unwrap_or_else(|e| panic!("{label}: the captures of {} (left) and {} (right) cannot be compared: {e}", a.name, b.name));
    for (frame, pairs) in frames {
        compare_views(&format!("{label}-f{frame}"), a, b, &pairs, depth);
    }
}

/// Asserts that frame `fa` of `a` and frame `fb` of `b` have the same views, image sizes and depth
/// presence ([`pair_frame`]) and identical images, colour and depth.
pub fn assert_same_frame(label: &str, a: &RunOutput, fa: u64, b: &RunOutput, fb: u64) {
    let pairs = views_to_compare(label, a, fa, b, fb);
    compare_views(label, a, b, &pairs, DepthCheck::Compare);
}

/// [`pair_frame`] of two runs' frames, for a comparison written by hand (pixel rules other than
/// equality): panics when the frames cannot be compared view by view, so such a loop never runs
/// over fewer views than were captured, or over none.
pub fn views_to_compare<'a>(label: &str, a: &'a RunOutput, fa: u64, b: &'a RunOutput, fb: u64) -> Vec<(&'a View, &'a View)> {
    pair_frame(a.frames(), fa, b.frames(), fb, DepthCheck::Compare)
        .unwrap_or_else(|e| panic!("{label}: frame {fa} of {} (left) and frame {fb} of {} (right) cannot be compared: {e}", a.name, b.name))
}

fn compare_views(label: &str, a: &RunOutput, b: &RunOutput, pairs: &[(&View, &View)], depth: DepthCheck) {
    for (va, vb) in pairs {
        let name = format!("{label}-view{}", va.view);
        image::assert_identical(&name, &a.image(&va.file), &b.image(&vb.file));
        if let (DepthCheck::Compare, Some(da), Some(db)) = (depth, &va.depth, &vb.depth) {
            image::assert_identical(&format!("{name}-depth"), &a.image(&da.file), &b.image(&db.file));
        }
    }
}

/// Asserts that two runs' `--stats` report the same shaded fragments per frame and view. Fails
/// when either run has no stats, no frame in them, or a frame without views: two empty reports are
/// equal and prove nothing.
pub fn assert_same_stats(label: &str, a: &RunOutput, b: &RunOutput) {
    for o in [a, b] {
        let stats = o.stats.as_ref().unwrap_or_else(|| panic!("{label}: {} wrote no stats", o.name));
        assert!(!stats.frames.is_empty(), "{label}: {}'s stats have no frame", o.name);
        assert!(stats.frames.iter().all(|f| !f.views.is_empty()), "{label}: {}'s stats have a frame without views: {stats:?}", o.name);
    }
    assert_eq!(a.stats, b.stats, "{label}: shaded fragments differ (left {}, right {})", a.name, b.name);
}

/// Which half of the layer a log assertion is about.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Half {
    /// The OpenXR API layer: it logged the instance it created for the app.
    OpenXr,
    /// The Vulkan layer: it logged a device it is in the chain of (where it sees the app's passes).
    Vulkan,
    Both,
}

/// The line the OpenXR half writes when `xrCreateApiLayerInstance` succeeded:
/// `<target>: instance 0x… for app "…"` (src/xr/instance.rs), also when disabled by config. The
/// message is matched where the log format puts it, right after `<target>: `, so a line that only
/// mentions it does not count.
fn xr_half_loaded(line: &str) -> bool {
    line.contains(": instance 0x") && line.contains(" for app ")
}

/// The message the Vulkan half logs for every device it is in the chain of (src/vk/chain.rs), as
/// it starts after `<target>: ` (a warning that quotes it, `see "vulkan device created"`, does
/// not count).
const VK_HALF_LOADED: &str = ": vulkan device created";

/// `Ok` when `log` (a run's layer log) shows that `half` loaded; else why not. An assertion that a
/// line is absent from the log means nothing unless this holds: a run the layer never loaded into
/// has an empty log, which lacks every line.
pub fn layer_loaded(log: &str, half: Half) -> Result<(), String> {
    let xr = log.lines().any(xr_half_loaded);
    let vk = log.lines().any(|l| l.contains(VK_HALF_LOADED));
    let missing: Vec<&str> = [
        (matches!(half, Half::OpenXr | Half::Both) && !xr, "the OpenXR half (no `instance 0x… for app` line)"),
        (matches!(half, Half::Vulkan | Half::Both) && !vk, "the Vulkan half (no `vulkan device created` line)"),
    ]
    .into_iter()
    .filter_map(|(m, what)| m.then_some(what))
    .collect();
    if missing.is_empty() {
        Ok(())
    } else {
        Err(format!("the layer did not load: {}; log:\n{log}", missing.join(", ")))
    }
}

/// `Ok` when `half` loaded ([`layer_loaded`]) and no line of `log` contains `needle`.
pub fn log_lacks(log: &str, half: Half, needle: &str) -> Result<(), String> {
    layer_loaded(log, half)?;
    let found: Vec<&str> = log.lines().filter(|l| l.contains(needle)).collect();
    if found.is_empty() {
        Ok(())
    } else {
        Err(format!("{} log line(s) contain {needle:?}, first: {}\nlog:\n{log}", found.len(), found[0]))
    }
}

pub const XR_LAYER_NAME: &str = stereoshim::manifests::XR_LAYER_NAME;

/// A folder holding an explicit OpenXR layer manifest for the built `libstereoshim.so`.
pub fn layer_manifest_dir() -> PathBuf {
    let lib = target_dir().join("libstereoshim.so");
    assert!(lib.exists(), "{} missing: run `cargo build --workspace` first", lib.display());
    let dir = target_dir().join("test-output").join("openxr-layer");
    std::fs::create_dir_all(&dir).unwrap();
    // The manifest `stereoshim run` writes (tests/layer/manifests.rs checks it against both loaders).
    let json = stereoshim::manifests::json(stereoshim::manifests::Kind::OpenXr, &lib);
    static N: AtomicUsize = AtomicUsize::new(0);
    let tmp = dir.join(format!(".m.{}.{}", std::process::id(), N.fetch_add(1, Ordering::Relaxed)));
    std::fs::write(&tmp, json).unwrap();
    std::fs::rename(&tmp, dir.join("stereoshim.json")).unwrap();
    dir
}

#[derive(Debug)]
pub struct RunOutput {
    pub name: String,
    pub code: Option<i32>,
    /// The signal that killed the app, if one did (then `code` is None).
    pub signal: Option<i32>,
    /// The crash report of a death by signal (`crash::report`): signal, time, log tails, every
    /// thread's backtrace.
    pub crash: Option<String>,
    pub stderr: String,
    pub capture: PathBuf,
    pub frames: Option<Frames>,
    pub stats: Option<Stats>,
    pub elapsed: std::time::Duration,
    /// The layer's log file of this run (empty without the layer).
    pub log: String,
}

impl RunOutput {
    /// Asserts a clean run: exit 0 (which under `--validation` also means no validation error).
    pub fn assert_ok(&self) -> &Self {
        if let Some(report) = &self.crash {
            panic!("{}: the app crashed\n{report}", self.name);
        }
        assert_eq!(self.code, Some(0), "{}: xr-scene failed; stderr:\n{}", self.name, self.stderr);
        self
    }
    pub fn frames(&self) -> &Frames {
        self.frames.as_ref().unwrap_or_else(|| panic!("{}: no frames.json; stderr:\n{}", self.name, self.stderr))
    }
    pub fn frame(&self, n: u64) -> &Frame {
        self.frames().frames.iter().find(|f| f.frame == n).unwrap_or_else(|| panic!("{}: frame {n} not captured", self.name))
    }
    /// The projection views of captured frame `n` (its first projection layer), in view order;
    /// never empty (a loop over them must not pass by running zero times).
    pub fn views(&self, n: u64) -> Vec<&View> {
        let frame = self.frame(n);
        let layer = frame.layers.iter().find(|l| l.kind == "projection").unwrap_or_else(|| panic!("{}: frame {n} has no projection layer", self.name));
        assert!(!layer.views.is_empty(), "{}: frame {n}'s projection layer has no view", self.name);
        layer.views.iter().collect()
    }
    /// `--pixel-stats` of frame `n`, view `view`: shaded fragments per pixel of the view's image
    /// rect, row-major (`width` × `height` of the captured view).
    pub fn pixel_counts(&self, n: u64, view: u32) -> Vec<u32> {
        let dir = self.capture.parent().expect("run dir").join("pixel-stats");
        let path = dir.join(format!("frame-{n:05}-view-{view}.u32"));
        let bytes = std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {}: {e}; stderr:\n{}", self.name, path.display(), self.stderr));
        let v = self.views(n).into_iter().find(|v| v.view == view).unwrap_or_else(|| panic!("{}: no view {view}", self.name));
        let expected = v.image_rect.width as usize * v.image_rect.height as usize * 4;
        assert_eq!(bytes.len(), expected, "{}: {} has {} bytes, not width × height × 4", self.name, path.display(), bytes.len());
        bytes.chunks_exact(4).map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect()
    }
    /// Asserts that `half` of the layer loaded in this run ([`layer_loaded`]).
    pub fn assert_layer_loaded(&self, half: Half) -> &Self {
        if let Err(e) = layer_loaded(&self.log, half) {
            panic!("{}: {e}", self.name);
        }
        self
    }
    /// Asserts that `half` of the layer loaded and that no line of its log contains `needle`
    /// ([`log_lacks`]): every assertion that something is absent from the log goes through here,
    /// so none can pass because the layer never ran.
    pub fn assert_log_lacks(&self, half: Half, needle: &str) -> &Self {
        if let Err(e) = log_lacks(&self.log, half, needle) {
            panic!("{}: {e}", self.name);
        }
        self
    }
    /// Asserts that the layer did not load at all in this run (it wrote no log): for runs that
    /// keep it out on purpose.
    pub fn assert_layer_not_loaded(&self) -> &Self {
        assert!(self.log.is_empty(), "{}: the layer was meant to stay out but logged:\n{}", self.name, self.log);
        self
    }
    /// Log lines containing `needle`.
    pub fn log_lines(&self, needle: &str) -> Vec<&str> {
        self.log.lines().filter(|l| l.contains(needle)).collect()
    }
    pub fn image(&self, file: &str) -> image::Image {
        image::Image::load(&self.capture.join(file))
    }
}

#[derive(Debug, Deserialize)]
pub struct Frames {
    pub hmd: String,
    pub frames: Vec<Frame>,
}

#[derive(Debug, Deserialize)]
pub struct Frame {
    pub frame: u64,
    pub layers: Vec<Layer>,
    /// The runtime's hidden-area mask of each view while this frame was rendered (frames.json's
    /// `visibility_masks`, docs/testing.md); empty in captures written before the field existed.
    #[serde(default)]
    pub visibility_masks: Vec<VisibilityMask>,
}

/// One view's `XR_VISIBILITY_MASK_TYPE_HIDDEN_TRIANGLE_MESH_KHR` as the runtime returns it:
/// tangent-plane points (z = −1, x right, y up), 3 per triangle, CCW. Empty when the runtime
/// does not offer `XR_KHR_visibility_mask`.
#[derive(Debug, Deserialize, Clone, PartialEq)]
pub struct VisibilityMask {
    pub view: u32,
    pub hidden_triangles: Vec<[f32; 2]>,
}

#[derive(Debug, Deserialize)]
pub struct Layer {
    #[serde(rename = "type")]
    pub kind: String,
    pub layer_flags: u64,
    pub space: String,
    pub views: Vec<View>,
    /// A quad layer's own fields (docs/testing.md); None for projection layers.
    #[serde(default)]
    pub quad: Option<Quad>,
}

/// A captured quad layer: pose and size (metres) in its space, its sub-image and PNG.
#[derive(Debug, Deserialize, Clone)]
pub struct Quad {
    pub pose: Pose,
    pub size: [f32; 2],
    pub eye_visibility: i32,
    pub swapchain: u64,
    pub format: i32,
    pub image_rect: Rect,
    pub image_array_index: u32,
    pub file: String,
}

#[derive(Debug, Deserialize, Clone)]
pub struct View {
    pub view: u32,
    pub pose: Pose,
    pub fov: Fov,
    pub swapchain: u64,
    pub format: i32,
    pub image_rect: Rect,
    pub image_array_index: u32,
    pub file: String,
    pub depth: Option<DepthInfo>,
}

#[derive(Debug, Deserialize, Clone, Copy)]
pub struct Pose {
    pub orientation: [f32; 4],
    pub position: [f32; 3],
}

#[derive(Debug, Deserialize, Clone, Copy)]
pub struct Fov {
    pub angle_left: f32,
    pub angle_right: f32,
    pub angle_up: f32,
    pub angle_down: f32,
}

#[derive(Debug, Deserialize, Clone, Copy, PartialEq, Eq)]
pub struct Rect {
    pub x: i32,
    pub y: i32,
    pub width: u32,
    pub height: u32,
}

#[derive(Debug, Deserialize, Clone)]
pub struct DepthInfo {
    pub swapchain: u64,
    pub image_rect: Rect,
    pub image_array_index: u32,
    pub min_depth: f32,
    pub max_depth: f32,
    pub near_z: f32,
    pub far_z: f32,
    pub file: String,
}

#[derive(Debug, Deserialize, PartialEq)]
pub struct Stats {
    pub frames: Vec<StatsFrame>,
}

#[derive(Debug, Deserialize)]
pub struct StatsFrame {
    pub frame: u64,
    pub gpu_time_ms: f64,
    pub views: Vec<StatsView>,
}

// GPU time differs run to run; equality of stats means equal work.
impl PartialEq for StatsFrame {
    fn eq(&self, other: &Self) -> bool {
        self.frame == other.frame && self.views == other.views
    }
}

#[derive(Debug, Deserialize, PartialEq, Eq)]
pub struct StatsView {
    pub view: u32,
    pub shaded_fragments: u64,
}

/// Writes a Vulkan layer manifest for the built `libstereoshim.so` (absolute path) into its own
/// folder and returns that folder, for `VK_LAYER_PATH`.
pub fn vulkan_layer_dir(layer_name: &str) -> PathBuf {
    let lib = target_dir().join("libstereoshim.so");
    assert!(lib.exists(), "{} missing: run `cargo build --workspace` first", lib.display());
    let dir = target_dir().join("test-output").join("vulkan-layer-manifest");
    std::fs::create_dir_all(&dir).unwrap();
    // The manifest the OpenXR half generates (tests/layer/manifests.rs checks it against both loaders).
    assert_eq!(layer_name, stereoshim::manifests::VK_LAYER_NAME, "the Vulkan manifest names stereoshim's layer");
    let json = stereoshim::manifests::json(stereoshim::manifests::Kind::Vulkan, &lib);
    static N: AtomicUsize = AtomicUsize::new(0);
    let tmp = dir.join(format!(".stereoshim.{}.{}", std::process::id(), N.fetch_add(1, Ordering::Relaxed)));
    std::fs::write(&tmp, json).unwrap();
    std::fs::rename(&tmp, dir.join("stereoshim.json")).unwrap();
    dir
}

/// The fault-injecting layer of the test tree (tests/vk-fault-layer), below stereoshim: the app
/// enables it with xr-scene `--vk-layer`.
pub const FAULT_LAYER: &str = "VK_LAYER_STEREOSHIM_TEST_fault";
/// Its marker instance, an implicit layer above stereoshim.
pub const FAULT_MARKER_LAYER: &str = "VK_LAYER_STEREOSHIM_TEST_fault_marker";

/// Writes the fault layer's two manifests (docs/testing.md) under a folder of the loader's
/// `XDG_DATA_DIRS` search and returns that folder: the lower layer explicit (the app enables it
/// last, so it sits below stereoshim, next to the driver), the marker implicit (the loader puts
/// implicit layers nearest the app, above stereoshim).
pub fn fault_layer_data_dir() -> PathBuf {
    let lib = target_dir().join("libvk_fault_layer.so");
    assert!(lib.exists(), "{} missing: run `cargo build --workspace` first", lib.display());
    let dir = target_dir().join("test-output").join("vk-fault-layer");
    let manifest = |name: &str, negotiate: &str, implicit: bool| {
        let mut layer = serde_json::json!({
            "name": name,
            "type": "GLOBAL",
            "library_path": lib,
            "api_version": "1.3.239",
            "implementation_version": "1",
            "description": "stereoshim tests: fault injection below the layer",
            "functions": { "vkNegotiateLoaderLayerInterfaceVersion": negotiate },
        });
        if implicit {
            layer["disable_environment"] = serde_json::json!({ "VK_FAULT_MARKER_DISABLE": "1" });
        }
        let sub = if implicit { "implicit_layer.d" } else { "explicit_layer.d" };
        let folder = dir.join("vulkan").join(sub);
        std::fs::create_dir_all(&folder).unwrap();
        let json = serde_json::json!({ "file_format_version": "1.2.0", "layer": layer });
        // A name of its own per write: the tests of one binary run in parallel threads.
        static N: AtomicUsize = AtomicUsize::new(0);
        let tmp = folder.join(format!(".{name}.{}.{}", std::process::id(), N.fetch_add(1, Ordering::Relaxed)));
        std::fs::write(&tmp, serde_json::to_vec_pretty(&json).unwrap()).unwrap();
        std::fs::rename(&tmp, folder.join(format!("{name}.json"))).unwrap();
    };
    manifest(FAULT_LAYER, "vkfault_negotiate_lower", false);
    manifest(FAULT_MARKER_LAYER, "vkfault_negotiate_upper", true);
    dir
}
