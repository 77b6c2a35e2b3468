//! The Bevy scene on Monado (simulated HMD, null compositor, lavapipe) inside the trixie root of
//! tests/realworld/main.rs, through the same runner (`tests/realworld/run`: private mount and PID
//! namespace, CPU-time watchdogs, gdb backtraces): without the layer and with mask + RDM + far
//! field. Monado captures nothing, so pixels are compared on the mock runtime only; here each run
//! must exit 0 after its frames, validation proven loaded, with no Vulkan validation or OpenXR
//! core_validation error beyond those of the run without the layer; the layer's counts are
//! reported.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

use serde_json::Value;

use crate::common;
use super::engine::{self, layer_counts, not_applied_lines, LAYER_CONFIG};

/// Frames the scene renders before it asks Monado to end the session (`--frames`).
const FRAMES: u64 = 40;
const WARM_UP: u64 = 3;
/// The scene's CPU-time budget inside the root (the driver's watchdog), seconds.
const LIMIT_S: u64 = 900;
const CORE_VALIDATION: &str = "XR_APILAYER_LUNARG_core_validation";

fn realworld_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/realworld")
}

/// The trixie root (tests/realworld/trixie-root builds it once, cached); None after a loud note
/// when it cannot be built here and the tests are not required.
fn root() -> Option<PathBuf> {
    static ROOT: OnceLock<Result<PathBuf, String>> = OnceLock::new();
    let r = ROOT.get_or_init(|| {
        let uid = Command::new("id").arg("-u").output().map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string());
        if uid.ok().as_deref() != Some("0") {
            return Err("needs root (mount namespaces, chroot)".into());
        }
        engine::run_script(&realworld_dir().join("trixie-root")).map(PathBuf::from)
    });
    match r {
        Ok(p) => Some(p.clone()),
        Err(why) if engine::required() => panic!("the real-engine Monado test is required but cannot run: {why}"),
        Err(why) => {
            eprintln!("\n######## SKIPPED: Bevy on Monado NOT RUN: {why} ########\n");
            None
        }
    }
}

struct MonadoRun {
    name: String,
    status: Option<i32>,
    result: String,
    runner: String,
    app_log: String,
    /// Vulkan validation errors: VUID → count (the log file and the app's output).
    vk_errors: std::collections::BTreeMap<String, usize>,
    cv_errors: Vec<String>,
    stats: Vec<Value>,
    log: String,
    elapsed: Duration,
}

/// Runs the scene (`args`) on Monado in the root; `layer`: stereoshim with every feature.
fn run(root: &Path, exe: &Path, name: &str, args: &[&str], layer: bool) -> MonadoRun {
    let dir = common::target_dir().join("test-output").join("realworld").join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("bevy")).unwrap();
    // The run folder is the root's /tmp: the binary and its loader link go there (a hard link
    // where the cache shares the file system, else a copy).
    let inside = dir.join("bevy/bevy-scene");
    if std::fs::hard_link(exe, &inside).is_err() {
        std::fs::copy(exe, &inside).unwrap_or_else(|e| panic!("{name}: copy {} into the run folder: {e}", exe.display()));
    }
    std::os::unix::fs::symlink("/usr/lib/x86_64-linux-gnu/libopenxr_loader.so.1", dir.join("bevy/libopenxr_loader.so")).unwrap();
    let mut layers = vec![];
    let mut env: Vec<(String, String)> = vec![
        ("XR_CORE_VALIDATION_EXPORT_TYPE".into(), "text".into()),
        ("XR_CORE_VALIDATION_FILE_NAME".into(), "/tmp/core_validation.txt".into()),
        ("VK_INSTANCE_LAYERS".into(), "VK_LAYER_KHRONOS_validation".into()),
        ("VK_KHRONOS_VALIDATION_DEBUG_ACTION".into(), "VK_DBG_LAYER_ACTION_LOG_MSG".into()),
        ("VK_KHRONOS_VALIDATION_LOG_FILENAME".into(), "/tmp/vk_validation.txt".into()),
        ("VK_KHRONOS_VALIDATION_REPORT_FLAGS".into(), "error,warn".into()),
        ("VK_LOADER_DEBUG".into(), "layer".into()),
    ];
    if layer {
        layers.push("XR_APILAYER_STEREOSHIM_stereoshim");
        std::fs::create_dir_all(dir.join("xr-layers")).unwrap();
        let json = stereoshim::manifests::json(stereoshim::manifests::Kind::OpenXr, Path::new("/opt/libstereoshim.so"));
        std::fs::write(dir.join("xr-layers/stereoshim.json"), json).unwrap();
        env.push(("XR_API_LAYER_PATH".into(), "/tmp/xr-layers:/usr/share/openxr/1/api_layers/explicit.d".into()));
        std::fs::create_dir_all(dir.join("config/stereoshim")).unwrap();
        std::fs::write(dir.join("config/stereoshim/config.toml"), format!("{LAYER_CONFIG}[stats]\nfile = \"/tmp/stats.jsonl\"\n")).unwrap();
    }
    // core_validation below stereoshim: it checks what reaches Monado.
    layers.push(CORE_VALIDATION);
    env.push(("XR_ENABLE_API_LAYERS".into(), layers.join(":")));
    std::fs::write(dir.join("app.env"), env.iter().map(|(k, v)| format!("{k}={v}\n")).collect::<String>()).unwrap();

    let mut cmd = Command::new(realworld_dir().join("run"));
    cmd.arg(root).arg(&dir).arg(common::target_dir()).args(["--", "/tmp/bevy/bevy-scene", "--frames", &FRAMES.to_string()]).args(args);
    // No key press (the scene ends itself); the driver judges the app by CPU time.
    cmd.env("RW_DURATION", "0").env("RW_TIMEOUT", LIMIT_S.to_string()).stdout(Stdio::piped()).stderr(Stdio::piped());
    let started = Instant::now();
    let mut child = cmd.spawn().unwrap_or_else(|e| panic!("{name}: {e}"));
    let readers = [child.stdout.take().map(engine::drain), child.stderr.take().map(engine::drain)];
    // Backstop only: the driver's own watchdogs (app, Monado) come first.
    let mut watchdog = common::watchdog::Watchdog::new(child.id(), Duration::from_secs(LIMIT_S + 420));
    let status = loop {
        if let Some(s) = child.try_wait().expect("wait for the runner") {
            break s;
        }
        if let Some(why) = watchdog.hung() {
            // The runner's namespace dies with it (unshare --kill-child).
            let _ = child.kill();
            let _ = child.wait();
            panic!("{name}: the real-world runner hung (backstop): {why}");
        }
        std::thread::sleep(Duration::from_millis(200));
    };
    let runner: String = readers.into_iter().flatten().map(|r| r.join().unwrap_or_default()).collect();
    let read = |f: &str| std::fs::read_to_string(dir.join(f)).unwrap_or_default();
    let app_log = read("app.log");
    let mut vk_errors = engine::validation_errors(&read("vk_validation.txt"));
    for (vuid, n) in engine::validation_errors(&app_log) {
        *vk_errors.entry(vuid).or_default() += n;
    }
    let cv_errors = read("core_validation.txt").lines().filter(|l| l.starts_with('[') && l.contains("VALID_ERROR")).map(str::to_string).collect();
    MonadoRun {
        name: name.to_string(),
        status: status.code(),
        result: read("result"),
        runner,
        vk_errors,
        cv_errors,
        stats: read("stats.jsonl").lines().filter_map(|l| serde_json::from_str(l).ok()).collect(),
        log: read("state/stereoshim/stereoshim.log"),
        app_log,
        elapsed: started.elapsed(),
    }
}

impl MonadoRun {
    /// Frames the scene says it rendered before the session ended.
    fn frames(&self) -> Option<u64> {
        let line = self.app_log.lines().find(|l| l.contains("bevy-scene: the session ended after"))?;
        line.split_whitespace().rev().nth(1)?.parse().ok()
    }

    fn assert_clean(&self) {
        let n = &self.name;
        let details = || format!("--- runner:\n{}\n--- result:\n{}\n--- app.log (last 40 lines):\n{}", self.runner, self.result, common::crash::tail_lines(&self.app_log, 40));
        assert_eq!(self.status, Some(0), "{n}: the run failed\n{}", details());
        assert!(self.frames().is_some_and(|f| f >= FRAMES), "{n}: the scene did not render its {FRAMES} frames\n{}", details());
        assert!(self.app_log.lines().any(|l| l.contains("Insert instance layer") && l.contains("VK_LAYER_KHRONOS_validation")), "{n}: validation never loaded\n{}", details());
    }
}

/// Bevy's default frame structure on Monado, without and with the layer.
#[test]
fn bevy_on_monado_with_and_without_the_layer() {
    let Some(exe) = engine::scene_exe() else { return };
    let Some(root) = root() else { return };
    let args = ["--resolution", "504x560"];
    let plain = run(&root, &exe, "bevy-monado-plain", &args, false);
    plain.assert_clean();
    let layered = run(&root, &exe, "bevy-monado-layer", &args, true);
    layered.assert_clean();
    common::layer_loaded(&layered.log, common::Half::Both).unwrap_or_else(|e| panic!("{}: {e}", layered.name));
    let added = engine::errors_added(&plain.vk_errors, &layered.vk_errors);
    assert!(added.is_empty(), "{}: Vulkan validation errors the run without the layer does not have: {added:?}", layered.name);
    // OpenXR usage errors the scene makes itself show in the plain run too; the layer adds none.
    let vuid = |l: &String| l.split('|').nth(1).map(str::trim).unwrap_or("").to_string();
    let own: Vec<String> = plain.cv_errors.iter().map(vuid).collect();
    let added: Vec<&String> = layered.cv_errors.iter().filter(|l| !own.contains(&vuid(l))).collect();
    assert!(added.is_empty(), "{}: core_validation errors the plain run does not have: {added:#?}", layered.name);
    let counts = layer_counts(&layered.stats, WARM_UP..FRAMES);
    assert!(counts.frames >= FRAMES - WARM_UP - 1, "{}: {} layer stats records in frames {WARM_UP}..{FRAMES}", layered.name, counts.frames);
    for r in [&plain, &layered] {
        eprintln!("{}: {} frames in {:.1} s, Vulkan validation errors {:?}, {} core_validation errors", r.name, r.frames().unwrap_or(0), r.elapsed.as_secs_f64(), r.vk_errors, r.cv_errors.len());
    }
    eprintln!(
        "bevy on Monado: over {} frames: masked {}, RDM {}, far-field views reused {}; not masked {:?}; RDM not applied {:?}; far field not applied {:?}",
        counts.frames, counts.passes_masked, counts.rdm_passes, counts.far_field_views_reused, counts.not_masked, counts.rdm_not_applied, counts.far_field_not_applied
    );
    for l in not_applied_lines(&layered.log) {
        eprintln!("bevy on Monado: layer log: {l}");
    }
    // On the real runtime too: the data-flow walk finds both eyes' main passes every frame.
    assert_eq!(counts.passes_masked, counts.frames * super::EYE_PASSES_PER_FRAME, "{}: every eye pass masked: {counts:?}", layered.name);
    assert_eq!(counts.rdm_passes, counts.frames * super::EYE_PASSES_PER_FRAME, "{}: RDM in every eye pass: {counts:?}", layered.name);
    assert!(counts.far_field_views_reused > 0, "{}: the far field reused nothing: {counts:?}", layered.name);
}
