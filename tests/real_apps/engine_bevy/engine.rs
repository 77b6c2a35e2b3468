//! The Bevy scene as an app under test: finding (or building) its binary, running it on the mock
//! runtime with the harness's isolation, crash reports and CPU-time watchdog, and reading what a
//! run left: captures, Vulkan validation errors, the layer's per-frame stats and its log's
//! not-applied reasons.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

use serde_json::Value;

use crate::common::{self, RunOutput};

/// CI (or anyone setting STEREOSHIM_REALWORLD_REQUIRED=1, as scripts/test does) must run these
/// tests: an engine that cannot be built or found fails them instead of skipping them.
pub fn required() -> bool {
    std::env::var_os("CI").is_some() || std::env::var("STEREOSHIM_REALWORLD_REQUIRED").is_ok_and(|v| v == "1")
}

/// The scene's binary: `STEREOSHIM_BEVY_SCENE`, else what scripts/engine-bevy builds (cached by
/// stamp; a cold build takes ~25 min on 2 cores). None (after a loud note) when it cannot
/// be had and the tests are not [`required`].
pub fn scene_exe() -> Option<PathBuf> {
    static EXE: OnceLock<Result<PathBuf, String>> = OnceLock::new();
    match EXE.get_or_init(find_or_build) {
        Ok(p) => Some(p.clone()),
        Err(why) if required() => panic!("the real-engine tests are required but cannot run: {why}"),
        Err(why) => {
            eprintln!("\n################ SKIPPED: real-engine test (Bevy scene) NOT RUN ################");
            eprintln!("# {why}");
            eprintln!("# (with CI or STEREOSHIM_REALWORLD_REQUIRED=1 set in the environment this is a failure)");
            eprintln!("#################################################################################\n");
            None
        }
    }
}

fn find_or_build() -> Result<PathBuf, String> {
    if let Some(p) = std::env::var_os("STEREOSHIM_BEVY_SCENE").filter(|p| !p.is_empty()) {
        let p = PathBuf::from(p);
        return if p.is_file() { Ok(p) } else { Err(format!("STEREOSHIM_BEVY_SCENE={} is not a file", p.display())) };
    }
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts/engine-bevy");
    let started = Instant::now();
    let path = PathBuf::from(run_script(&script)?);
    eprintln!("bevy-scene {} ready after {:.1} s", path.display(), started.elapsed().as_secs_f64());
    Ok(path)
}

/// Runs a script that builds something into a cache and prints its path (scripts/engine-bevy,
/// tests/realworld/trixie-root): its trimmed stdout, or why not. A cold build is long CPU work,
/// never a hang: judged by CPU time (4 h) and by a stall of 20 minutes (downloads wait on the
/// network, not the CPU); a hung one is killed.
pub fn run_script(script: &Path) -> Result<String, String> {
    let mut child = Command::new(script)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .map_err(|e| format!("{}: {e}", script.display()))?;
    let (out, err) = (child.stdout.take().map(drain), child.stderr.take().map(drain));
    let mut watchdog = common::watchdog::Watchdog::new(child.id(), Duration::from_secs(4 * 3600)).with_stall(Duration::from_secs(20 * 60));
    let status = loop {
        if let Some(s) = child.try_wait().map_err(|e| e.to_string())? {
            break s;
        }
        if let Some(why) = watchdog.hung() {
            let _ = child.kill();
            let _ = child.wait();
            return Err(format!("{} hung: {why}", script.display()));
        }
        std::thread::sleep(Duration::from_millis(200));
    };
    let stdout = out.map(|t| t.join().unwrap_or_default()).unwrap_or_default();
    let stderr = err.map(|t| t.join().unwrap_or_default()).unwrap_or_default();
    if !status.success() {
        return Err(format!("{} failed ({status}):\n{}", script.display(), common::crash::tail_lines(&stderr, 60)));
    }
    Ok(stdout.trim().to_string())
}

pub fn drain(mut r: impl std::io::Read + Send + 'static) -> std::thread::JoinHandle<String> {
    std::thread::spawn(move || {
        let mut buf = Vec::new();
        let _ = r.read_to_end(&mut buf);
        String::from_utf8_lossy(&buf).into_owned()
    })
}

/// The layer's configuration in every layered run: every feature the layer has, as issue 20 asks
/// for, and Bevy's projection (near plane 0.1 m, infinite far plane; it submits no
/// `XrCompositionLayerDepthInfoKHR`), which the far field needs and never guesses.
pub const LAYER_CONFIG: &str = "\
[mask]
enabled = true
[foveation]
enabled = true
method = \"rdm\"
eye_tracking = \"off\"
[far_field]
enabled = true
";

/// One run of the scene on the mock runtime.
#[derive(Clone, Debug)]
pub struct SceneRun {
    pub name: String,
    /// The scene's options (the frame structure).
    pub args: Vec<String>,
    pub layer: bool,
    pub env: Vec<(String, String)>,
    pub cpu_budget: Duration,
}

/// What a finished run left.
#[derive(Debug)]
pub struct SceneOutput {
    pub out: RunOutput,
    /// The layer's `stats.file` records, one per frame; empty without the layer.
    pub stats: Vec<Value>,
    /// VK_LAYER_KHRONOS_validation's errors: VUID → how many times it was reported.
    pub vk_errors: BTreeMap<String, usize>,
    /// The loader inserted the validation layer into the instance (its own debug output says so):
    /// without it "0 validation errors" would mean nothing.
    pub validation_loaded: bool,
    pub cpu: Duration,
}

impl SceneRun {
    pub fn new(name: &str, args: &[&str], layer: bool) -> SceneRun {
        SceneRun {
            name: name.to_string(),
            args: args.iter().map(|s| s.to_string()).collect(),
            layer,
            env: Vec::new(),
            // Seconds of CPU time per run here (lavapipe compiles Bevy's pipelines, then draws);
            // far above it is a livelock.
            cpu_budget: Duration::from_secs(900),
        }
    }

    pub fn env(mut self, k: &str, v: &str) -> SceneRun {
        self.env.retain(|(key, _)| key != k);
        self.env.push((k.into(), v.into()));
        self
    }

    /// Runs the scene to its end; a hang (by CPU time, `common::watchdog`) fails the test with
    /// every thread's backtrace.
    pub fn run(&self, exe: &Path) -> SceneOutput {
        let dir = common::output_dir(&self.name);
        let capture = dir.join("capture");
        let stats_file = dir.join("layer-stats.jsonl");
        let mut cmd = Command::new(exe);
        common::isolate(&mut cmd, &dir, &capture, self.layer);
        common::crash::prepare(&mut cmd, &dir);
        cmd.args(&self.args)
            // Validation through VK_INSTANCE_LAYERS: the scene's instance is created by the runtime
            // (XR_KHR_vulkan_enable2) from bevy_mod_openxr's create info, which names no layer.
            // The loader puts it above stereoshim: it checks everything Bevy records. Its
            // messages go to stdout (bookworm's 1.3.239 ignores a log file name).
            .env("VK_INSTANCE_LAYERS", "VK_LAYER_KHRONOS_validation")
            .env("VK_KHRONOS_VALIDATION_REPORT_FLAGS", "error,warn")
            // The loader names every layer it inserts: proof that validation ran.
            .env("VK_LOADER_DEBUG", "layer")
            .env("HOME", &dir)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped());
        if self.layer {
            std::fs::create_dir_all(dir.join("config/stereoshim")).unwrap();
            let config = format!("{LAYER_CONFIG}[stats]\nfile = {:?}\n", stats_file.display().to_string());
            std::fs::write(dir.join("config/stereoshim/config.toml"), config).unwrap();
        }
        for (k, v) in &self.env {
            cmd.env(k, v);
        }
        let started = Instant::now();
        let mut child = cmd.spawn().unwrap_or_else(|e| panic!("{}: spawn {}: {e}", self.name, exe.display()));
        let readers = [child.stdout.take().map(drain), child.stderr.take().map(drain)];
        let mut watchdog = common::watchdog::Watchdog::new(child.id(), self.cpu_budget);
        let status = loop {
            if let Some(s) = child.try_wait().expect("wait for bevy-scene") {
                break s;
            }
            if let Some(why) = watchdog.hung() {
                let backtraces = common::crash::live_backtraces(child.id());
                let _ = child.kill();
                let _ = child.wait();
                let output: String = readers.into_iter().flatten().map(|r| r.join().unwrap_or_default()).collect();
                std::fs::write(dir.join("output.txt"), &output).ok();
                panic!(
                    "=== HANG: {}: bevy-scene hung after {:.1?}: {why}; killed; run folder kept: {} ===\n--- output, last 60 lines ---\n{}\n--- every thread's backtrace (gdb) ---\n{backtraces}",
                    self.name,
                    started.elapsed(),
                    dir.display(),
                    common::crash::tail_lines(&output, 60)
                );
            }
            std::thread::sleep(Duration::from_millis(20));
        };
        let elapsed = started.elapsed();
        let cpu = watchdog.cpu_used();
        let output: String = readers.into_iter().flatten().map(|r| r.join().unwrap_or_default()).collect();
        std::fs::write(dir.join("output.txt"), &output).ok();
        let frames = std::fs::read(capture.join("frames.json")).ok().map(|b| serde_json::from_slice(&b).expect("frames.json parses"));
        let log = std::fs::read_to_string(dir.join("state/stereoshim/stereoshim.log")).unwrap_or_default();
        let crash = common::crash::report(&common::crash::Ended { name: &self.name, dir: &dir, program: exe, pid: child.id(), status, elapsed, stderr: &output, log: &log });
        let stats = std::fs::read_to_string(&stats_file)
            .map(|t| t.lines().map(|l| serde_json::from_str(l).expect("stats line parses")).collect())
            .unwrap_or_default();
        let vk_errors = validation_errors(&output);
        let validation_loaded = output.lines().any(|l| l.contains("Insert instance layer") && l.contains("VK_LAYER_KHRONOS_validation"));
        let out = RunOutput {
            name: self.name.clone(),
            code: status.code(),
            signal: std::os::unix::process::ExitStatusExt::signal(&status),
            crash,
            stderr: output,
            capture,
            frames,
            stats: None,
            elapsed,
            log,
        };
        SceneOutput { out, stats, vk_errors, validation_loaded, cpu }
    }
}

/// VK_LAYER_KHRONOS_validation's errors in `text` (its `Validation Error: [ VUID ] …` messages,
/// on stdout or in a log file): VUID → count.
pub fn validation_errors(text: &str) -> BTreeMap<String, usize> {
    let mut errors = BTreeMap::new();
    for l in text.lines() {
        if let Some((_, rest)) = l.split_once("Validation Error: [") {
            let vuid = rest.split_once(']').map_or(rest, |(v, _)| v).trim();
            *errors.entry(vuid.to_string()).or_default() += 1;
        }
    }
    errors
}

/// The VUIDs of `layered` that `plain` (the same app without the layer) does not report: the
/// validation errors the layer causes. The app's own errors (Bevy on bookworm's validation layer
/// has some, docs/testing.md) are in both runs.
pub fn errors_added(plain: &BTreeMap<String, usize>, layered: &BTreeMap<String, usize>) -> Vec<String> {
    layered.keys().filter(|k| !plain.contains_key(*k)).cloned().collect()
}

impl SceneOutput {
    /// Exit 0 (the scene ended by itself when the runtime ended the session), no crash, validation
    /// loaded (its errors are judged against the run without the layer: [`errors_added`]).
    pub fn assert_clean(&self) -> &Self {
        let name = &self.out.name;
        if let Some(report) = &self.out.crash {
            panic!("{name}: bevy-scene crashed\n{report}");
        }
        assert_eq!(self.out.code, Some(0), "{name}: bevy-scene failed; output (last 60 lines):\n{}", common::crash::tail_lines(&self.out.stderr, 60));
        assert!(self.validation_loaded, "{name}: the loader never inserted VK_LAYER_KHRONOS_validation (vulkan-validationlayers installed?); output:\n{}", common::crash::tail_lines(&self.out.stderr, 60));
        self
    }
}

/// What the layer did to the scene's passes over some frames, from its `stats.file` records
/// (wgpu never destroys its device, so the device stats line that other tests read never comes).
/// Sums over the frames counted.
#[derive(Debug, Default, Clone, PartialEq, Eq)]
pub struct LayerCounts {
    /// Frames whose record was counted.
    pub frames: u64,
    /// Frames whose record says the Vulkan half saw the frame's device.
    pub frames_with_vulkan_half: u64,
    pub passes_masked: u64,
    pub rdm_passes: u64,
    /// Eyes RDM's compute pass reconstructed (at the main pass's end).
    pub rdm_compute: u64,
    /// Views whose far field was filled from the other eye.
    pub far_field_views_reused: u64,
    pub not_masked: BTreeMap<String, u64>,
    pub rdm_not_applied: BTreeMap<String, u64>,
    pub far_field_not_applied: BTreeMap<String, u64>,
}

/// [`LayerCounts`] of the records of frames `frames` (xrEndFrame numbers, as the records' `frame`).
pub fn layer_counts(stats: &[Value], frames: std::ops::Range<u64>) -> LayerCounts {
    let mut c = LayerCounts::default();
    let add = |map: &mut BTreeMap<String, u64>, v: &Value| {
        for (k, n) in v.as_object().into_iter().flatten() {
            *map.entry(k.clone()).or_default() += n.as_u64().unwrap_or(0);
        }
    };
    for s in stats.iter().filter(|s| s["frame"].as_u64().is_some_and(|f| frames.contains(&f))) {
        c.frames += 1;
        c.frames_with_vulkan_half += u64::from(s["vulkan_half"].as_bool() == Some(true));
        c.passes_masked += s["passes_masked"].as_u64().unwrap_or(0);
        c.rdm_passes += s["rdm"]["passes"].as_u64().unwrap_or(0);
        c.rdm_compute += s["rdm"]["compute"].as_u64().unwrap_or(0);
        c.far_field_views_reused += s["far_field"]["views_reused"].as_object().map_or(0, |m| m.values().filter_map(Value::as_u64).sum());
        add(&mut c.not_masked, &s["not_masked"]);
        add(&mut c.rdm_not_applied, &s["rdm"]["not_applied"]);
        add(&mut c.far_field_not_applied, &s["far_field"]["not_applied"]);
    }
    c
}

/// The layer's log lines that say why something was not applied (each logged once per reason),
/// without their time stamps, deduplicated.
pub fn not_applied_lines(log: &str) -> Vec<String> {
    let mut lines: Vec<String> = log
        .lines()
        .filter(|l| l.contains("not masked:") || l.contains("not applied") || l.contains("hint"))
        .map(|l| l.split_once(" stereoshim::").map_or(l, |(_, rest)| rest).to_string())
        .collect();
    lines.sort();
    lines.dedup();
    lines
}

/// Where the layered run's pixels differ from the plain run's, per captured frame and view,
/// against the runtime's hidden area of that frame (frames.json `visibility_masks`, rasterized by
/// the harness): inside it, within `EDGE_MARGIN_PX` of its outline, and outside (what the user
/// sees).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct MaskDiff {
    pub frame: u64,
    pub view: u32,
    pub inside: usize,
    pub edge: usize,
    pub outside: usize,
    /// PSNR of the pixels outside the hidden area and its edge (infinite when identical).
    pub visible_psnr: f64,
    /// Differing pixels well inside RDM's inner ring (fixed fovea at the projection centre,
    /// `FOVEA_INNER_DEG` less a degree), where RDM skips nothing.
    pub fovea: usize,
}

/// RDM's inner ring in the layered runs (`balanced`, fixed at the projection centre).
pub const FOVEA_INNER_DEG: f64 = 20.0;

/// Pixels this close to the mask outline may go either way (vertex snapping, rounding).
pub const EDGE_MARGIN_PX: f64 = 1.0;

/// [`MaskDiff`] of every view of every frame the two runs captured (the same frames and views:
/// `common::pair_captures`, which panics here when they cannot be compared).
pub fn diff_by_mask(plain: &RunOutput, layered: &RunOutput) -> Vec<MaskDiff> {
    let frames = common::pair_captures(plain.frames(), layered.frames(), common::DepthCheck::Ignore)
        .unwrap_or_else(|e| panic!("{} and {} cannot be compared: {e}", plain.name, layered.name));
    let mut out = Vec::new();
    for (f, pairs) in frames {
        let masks = &layered.frame(f).visibility_masks;
        for (a, b) in pairs {
            let (w, h) = (a.image_rect.width, a.image_rect.height);
            let mask = masks.iter().find(|m| m.view == a.view).map_or(&[][..], |m| &m.hidden_triangles[..]);
            let hidden = common::hidden_pixels(mask, &a.fov, w, h);
            let edge = common::mask_edge_pixels(mask, &a.fov, w, h, EDGE_MARGIN_PX);
            let (pa, pb) = (plain.image(&a.file), layered.image(&b.file));
            let mut d = MaskDiff { frame: f, view: a.view, ..MaskDiff::default() };
            let (mut sq, mut n) = (0.0f64, 0u64);
            for y in 0..h {
                for x in 0..w {
                    let i = (y * w + x) as usize;
                    if !edge[i] && !hidden[i] {
                        n += 1;
                        sq += pa.pixel(x, y)[..3].iter().zip(&pb.pixel(x, y)[..3]).map(|(p, q)| (*p as f64 - *q as f64).powi(2)).sum::<f64>() / 3.0;
                    }
                    if pa.pixel(x, y) == pb.pixel(x, y) {
                        continue;
                    }
                    if common::rdm::angle_deg(&a.fov, w, h, x as f64 + 0.5, y as f64 + 0.5, [0.0, 0.0]) < FOVEA_INNER_DEG - 1.0 {
                        d.fovea += 1;
                    }
                    match (edge[i], hidden[i]) {
                        (true, _) => d.edge += 1,
                        (false, true) => d.inside += 1,
                        (false, false) => d.outside += 1,
                    }
                }
            }
            d.visible_psnr = if sq == 0.0 { f64::INFINITY } else { 10.0 * (255.0f64 * 255.0 / (sq / n.max(1) as f64)).log10() };
            out.push(d);
        }
    }
    out
}
