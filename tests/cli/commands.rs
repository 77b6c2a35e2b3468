//! The `stereoshim` command end to end: install as an implicit layer into a private data folder,
//! see it picked up by an app that was told nothing, keep it out with the disable variable, show it
//! in `status`, remove it again; and `stereoshim run`.

use crate::common;

use common::{assert_same_captures, target_dir, Run};
use std::path::Path;
use std::process::Command;

fn stereoshim(args: &[&str], data_home: &Path, config_home: &Path) -> (i32, String) {
    let out = Command::new(target_dir().join("stereoshim"))
        .args(args)
        .env("XDG_DATA_HOME", data_home)
        .env("XDG_CONFIG_HOME", config_home)
        .env("XDG_CONFIG_DIRS", "/nonexistent")
        .env("XDG_DATA_DIRS", "/nonexistent")
        .env_remove("XR_API_LAYER_PATH")
        .env_remove("STEREOSHIM_DISABLE")
        .output()
        .expect("run stereoshim");
    let text = String::from_utf8_lossy(&out.stdout).into_owned() + &String::from_utf8_lossy(&out.stderr);
    (out.status.code().unwrap_or(-1), text)
}

#[test]
fn install_status_disable_uninstall() {
    let home = common::output_dir("cli-home");
    let (data, config) = (home.join("data"), home.join("config"));
    std::fs::create_dir_all(config.join("stereoshim")).unwrap();
    std::fs::write(config.join("stereoshim/config.toml"), "[app.\"xr-scene\"]\nlog.level = \"debug\"\n").unwrap();

    let (code, text) = stereoshim(&["install", "--user"], &data, &config);
    assert_eq!(code, 0, "{text}");
    let manifest = data.join("openxr/1/api_layers/implicit.d/stereoshim.json");
    assert!(manifest.is_file() && data.join("stereoshim/libstereoshim.so").is_file(), "{text}");

    let (code, text) = stereoshim(&["status", "--app", "xr-scene"], &data, &config);
    assert_eq!(code, 0, "{text}");
    assert!(text.contains(&format!("{} (implicit)", manifest.display())), "{text}");
    assert!(text.contains("log.level = debug") && text.contains("[app.\"xr-scene\"]"), "{text}");

    // An app told nothing about stereoshim gets it from the implicit manifest.
    let reference = Run::new("cli-reference").run();
    reference.assert_ok();
    let implicit = Run::new("cli-implicit").env("XDG_DATA_HOME", data.to_str().unwrap()).run();
    implicit.assert_ok();
    assert_eq!(implicit.log_lines("the Vulkan half tracks this device").len(), 1, "{}", implicit.log);
    assert_same_captures("cli-implicit", &implicit, &reference);

    let disabled = Run::new("cli-disabled").env("XDG_DATA_HOME", data.to_str().unwrap()).env("STEREOSHIM_DISABLE", "1").run();
    disabled.assert_ok();
    // STEREOSHIM_DISABLE must keep the layer out (the run before shows it is picked up otherwise).
    disabled.assert_layer_not_loaded();

    let (code, text) = stereoshim(&["uninstall", "--user"], &data, &config);
    assert_eq!(code, 0, "{text}");
    assert!(!manifest.exists() && !data.join("stereoshim/libstereoshim.so").exists());
    assert!(!data.join("stereoshim").exists(), "the library folder is left behind");
    let (_, text) = stereoshim(&["status"], &data, &config);
    assert!(text.contains("none (not installed"), "{text}");
}

#[test]
fn run_wraps_one_app() {
    let reference = Run::new("cli-run-reference").args(["--layout", "side-by-side"]).run();
    reference.assert_ok();
    let mut run = Run::new("cli-run").args(["--layout", "side-by-side"]);
    run.wrapper = vec![target_dir().join("stereoshim").into(), "run".into(), "--".into()];
    let out = run.run();
    out.assert_ok();
    assert_eq!(out.log_lines("the Vulkan half tracks this device").len(), 1, "{}", out.log);
    assert_same_captures("cli-run", &out, &reference);
    // At exit, a short summary on stderr: loaded, nothing enabled, where the log is.
    let log = out.capture.parent().unwrap().join("state/stereoshim/stereoshim.log");
    assert!(out.stderr.contains("stereoshim: xr-scene ran 2 frames with the layer (pid "), "{}", out.stderr);
    assert!(out.stderr.contains("no feature applied (none enabled"), "{}", out.stderr);
    assert!(out.stderr.contains(&format!("details: log {}", log.display())), "{}", out.stderr);
}

/// The counter `key` of the log's last `vulkan device stats:` line.
fn device_counter(log: &str, key: &str) -> u64 {
    let line = log.lines().rev().find(|l| l.contains("vulkan device stats: ")).expect("a device stats line");
    line.split_whitespace().find_map(|t| t.strip_prefix(&format!("{key}="))).and_then(|v| v.parse().ok()).unwrap_or_else(|| panic!("no {key} in {line}"))
}

/// `stereoshim run -- %command%` as a Steam launch option: Steam's command line starts with the
/// Steam Linux Runtime's entry point (here a stand-in that records the environment the game gets
/// and runs it). The manifest must not be under XDG_RUNTIME_DIR (the container has its own
/// /run), and the library's and manifest's folders are listed for pressure-vessel to share. The
/// summary at exit says what the mask and RDM did, with the log's own numbers.
#[test]
fn run_as_a_steam_launch_option() {
    let runtime = common::output_dir("cli-steam-runtime").join("SteamLinuxRuntime_sniper");
    std::fs::create_dir_all(&runtime).unwrap();
    let entry = runtime.join("_v2-entry-point");
    let script = "#!/bin/sh\nenv > \"$(dirname \"$0\")/env.txt\"\nwhile [ \"$#\" -gt 0 ] && [ \"$1\" != \"--\" ]; do shift; done\nshift\nexec \"$@\"\n";
    std::fs::write(&entry, script).unwrap();
    std::fs::set_permissions(&entry, std::os::unix::fs::PermissionsExt::from_mode(0o755)).unwrap();
    // HOME holds the build (library) and the run folder (manifest), as a user's checkout under
    // their home would: shared by the container wherever the suite's checkout lives (the suite
    // runs from /run/stereoshim-suite, which the container never shares).
    let home = std::fs::canonicalize(target_dir()).unwrap();
    let mut run = Run::new("cli-steam")
        .env("HOME", home.to_str().unwrap())
        .env("STEREOSHIM_MASK_ENABLED", "1")
        .env("STEREOSHIM_FOVEATION_ENABLED", "1")
        .env("STEREOSHIM_FOVEATION_METHOD", "rdm");
    run.wrapper = vec![target_dir().join("stereoshim").into(), "run".into(), "--".into(), entry.clone().into(), "--verb=waitforexitandrun".into(), "--".into()];
    let out = run.run();
    out.assert_ok();
    assert_eq!(out.log_lines("the Vulkan half tracks this device").len(), 1, "{}", out.log);

    let dir = out.capture.parent().unwrap();
    let env = std::fs::read_to_string(runtime.join("env.txt")).expect("the entry point ran");
    let var = |k: &str| env.lines().find_map(|l| l.strip_prefix(&format!("{k}="))).unwrap_or_else(|| panic!("{k} not set:\n{env}")).to_string();
    let manifest_dir = var("XR_API_LAYER_PATH");
    assert!(manifest_dir.starts_with(dir.join("state").to_str().unwrap()), "manifest under XDG_STATE_HOME, not XDG_RUNTIME_DIR: {manifest_dir}");
    let library_dir = std::fs::canonicalize(target_dir()).unwrap();
    let shared: Vec<String> = var("PRESSURE_VESSEL_FILESYSTEMS_RO").split(':').map(str::to_string).collect();
    assert!(shared.contains(&library_dir.display().to_string()) && shared.contains(&manifest_dir), "{shared:?}");
    assert!(!std::path::Path::new(&manifest_dir).exists(), "removed after the run");

    let masked = device_counter(&out.log, "masked_passes");
    assert!(masked > 0, "{}", out.log);
    let expected = format!("hidden-area mask: {masked} eye passes masked (eye passes found by: swapchain {masked})");
    assert!(out.stderr.contains(&expected), "{expected:?} not in:\n{}", out.stderr);
    assert!(out.stderr.contains(&format!("foveation (RDM): {} eye passes", device_counter(&out.log, "rdm_passes"))), "{}", out.stderr);
    assert!(!out.stderr.contains("live.") && !out.stderr.contains("own."), "raw counters stay in the log:\n{}", out.stderr);
}

/// `install` tells a Steam user whether games in Steam's container see the installation.
#[test]
fn install_tells_steam_users_what_to_do() {
    let home = common::output_dir("cli-install-steam");
    let install = |home_var: &Path| {
        let out = Command::new(target_dir().join("stereoshim"))
            .args(["install", "--user"])
            .env("HOME", home_var)
            .env("XDG_DATA_HOME", home.join("data"))
            .output()
            .expect("run stereoshim");
        assert!(out.status.success(), "{out:?}");
        String::from_utf8_lossy(&out.stdout).into_owned()
    };
    let text = install(&home);
    assert!(text.contains("Steam: games in the Steam Linux Runtime container (native games and Proton) see this registration too"), "{text}");
    assert!(text.contains("`stereoshim run -- %command%`"), "{text}");
    // A data folder outside the home directory: listed for pressure-vessel to share it, or, where
    // the container never shares it (the suite's checkout under /run), said so.
    let text = install(Path::new("/nonexistent-home"));
    let data = home.join("data");
    let library = data.join("stereoshim/libstereoshim.so");
    match stereoshim::manifests::steam::visibility(&library, None) {
        stereoshim::manifests::steam::Visibility::Never(why) => {
            let expected = format!("do not see {}: {why}", library.display());
            assert!(text.contains(&expected), "{expected:?} not in:\n{text}");
        }
        _ => {
            let expected = format!("PRESSURE_VESSEL_FILESYSTEMS_RO={}:{} %command%", data.join("stereoshim").display(), data.join("openxr/1/api_layers/implicit.d").display());
            assert!(text.contains(&expected), "{expected:?} not in:\n{text}");
        }
    }
}

#[test]
fn bad_usage_is_reported() {
    let home = common::output_dir("cli-usage");
    let (code, text) = stereoshim(&["frobnicate"], &home, &home);
    assert_eq!(code, 2);
    assert!(text.contains("Usage:"), "{text}");
    let (code, text) = stereoshim(&["run"], &home, &home);
    assert_eq!(code, 2);
    assert!(text.contains("-- <APP>"), "{text}");
    // --help of the command and of every subcommand it lists: exit 0, never a panic.
    let (code, text) = stereoshim(&["--help"], &home, &home);
    assert_eq!(code, 0, "{text}");
    let subcommands = listed_subcommands(&text);
    for expected in ["install", "uninstall", "status", "run", "manifest", "stats"] {
        assert!(subcommands.iter().any(|s| s == expected), "{expected} missing from --help: {text}");
    }
    for sub in &subcommands {
        let (code, text) = stereoshim(&[sub, "--help"], &home, &home);
        assert_eq!(code, 0, "{sub} --help: {text}");
        assert!(text.contains(&format!("Usage: stereoshim {sub}")), "{sub} --help: {text}");
        let (code, text) = stereoshim(&[sub, "--no-such-option"], &home, &home);
        assert_eq!(code, 2, "{sub} --no-such-option: {text}");
        assert!(!text.contains("panicked"), "{sub}: {text}");
    }
    let (code, text) = stereoshim(&["install", "--user", "--system"], &home, &home);
    assert_eq!(code, 2, "{text}");
}

/// The subcommands clap lists under "Commands:" (without its own `help`).
fn listed_subcommands(help: &str) -> Vec<String> {
    help.lines()
        .skip_while(|l| !l.starts_with("Commands:"))
        .skip(1)
        .take_while(|l| l.starts_with("  "))
        .filter_map(|l| l.split_whitespace().next())
        .filter(|s| *s != "help")
        .map(String::from)
        .collect()
}

/// Every binary of the workspace and every example (found in `examples/`, so a new one is covered
/// without touching this test) answers `--help` with its usage (exit 0) and an unknown option
/// with a usage error (exit 2), never with a panic.
#[test]
fn every_binary_and_example_answers_help() {
    let examples = std::fs::read_dir(Path::new(env!("CARGO_MANIFEST_DIR")).join("examples")).unwrap();
    let mut programs: Vec<std::path::PathBuf> = examples
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "rs"))
        .map(|p| target_dir().join("examples").join(p.file_stem().unwrap()))
        .collect();
    assert!(programs.len() >= 4, "{programs:?}");
    programs.extend([target_dir().join("stereoshim"), target_dir().join("xr-scene")]);
    for program in &programs {
        let run = |arg: &str| {
            let out = Command::new(program).arg(arg).output().unwrap_or_else(|e| panic!("{}: {e} (cargo build --workspace --all-targets first)", program.display()));
            (out.status.code(), String::from_utf8_lossy(&out.stdout).into_owned(), String::from_utf8_lossy(&out.stderr).into_owned())
        };
        let (code, stdout, stderr) = run("--help");
        assert_eq!(code, Some(0), "{} --help: {stdout}{stderr}", program.display());
        assert!(stdout.contains("Usage:"), "{} --help: {stdout}", program.display());
        let (code, stdout, stderr) = run("--no-such-option");
        assert_eq!(code, Some(2), "{} --no-such-option: {stdout}{stderr}", program.display());
        assert!(stderr.contains("error:") && !stderr.contains("panicked"), "{}: {stderr}", program.display());
    }
}

#[test]
fn manifest_prints_and_regenerates() {
    let home = common::output_dir("cli-manifest");
    let (code, text) = stereoshim(&["manifest", "bogus"], &home, &home);
    assert_eq!(code, 2);
    assert!(text.contains("openxr, openxr-implicit, vulkan"), "{text}");
    let (code, text) = stereoshim(&["manifest"], &home, &home);
    assert_eq!(code, 2, "{text}");
    // The printed manifest names the library next to the command.
    let (code, text) = stereoshim(&["manifest", "openxr-implicit"], &home, &home);
    assert_eq!(code, 0, "{text}");
    let json: serde_json::Value = serde_json::from_str(&text).unwrap();
    let lib = std::fs::canonicalize(target_dir().join("libstereoshim.so")).unwrap();
    assert_eq!(json["api_layer"]["library_path"], lib.to_str().unwrap());
    assert_eq!(json["api_layer"]["disable_environment"], "STEREOSHIM_DISABLE");
    // --shipped writes the files of manifest/, byte for byte.
    let out = home.join("shipped");
    let (code, text) = stereoshim(&["manifest", "--shipped", out.to_str().unwrap()], &home, &home);
    assert_eq!(code, 0, "{text}");
    let repo = Path::new(env!("CARGO_MANIFEST_DIR")).join("manifest");
    for kind in ["openxr", "openxr-implicit", "vulkan"] {
        let ours = std::fs::read(out.join(kind).join("stereoshim.json")).unwrap();
        assert_eq!(ours, std::fs::read(repo.join(kind).join("stereoshim.json")).unwrap(), "{kind}");
    }
}

/// `stereoshim stats`: the layer's stats file of a real run summarised per second and as CSV,
/// an unreadable line named with its number, and `--follow` printing what is appended.
#[test]
fn stats_summarises_the_layers_file() {
    const FRAMES: u64 = 12;
    let home = common::output_dir("cli-stats");
    let stats = home.join("layer-stats.jsonl");
    let _ = std::fs::remove_file(&stats);
    let run = Run::new("cli-stats")
        .with_layer()
        .env("MOCK_XR_EXIT_AFTER", &FRAMES.to_string())
        .env("MOCK_XR_CAPTURE_FRAMES", "0")
        .env("STEREOSHIM_MASK_ENABLED", "1")
        .env("STEREOSHIM_STATS_FILE", stats.to_str().unwrap())
        .run();
    run.assert_ok();
    let file = stats.to_str().unwrap();
    let (code, text) = stereoshim(&["stats", file], &home, &home);
    assert_eq!(code, 0, "{text}");
    let rows: Vec<Vec<&str>> = text.lines().skip(1).map(|l| l.split_whitespace().collect()).collect();
    assert!(!rows.is_empty(), "{text}");
    let frames: u64 = rows.iter().map(|r| r[1].parse::<u64>().unwrap()).sum();
    assert_eq!(frames, FRAMES, "every frame in one second or another:\n{text}");
    let masked: u64 = rows.iter().map(|r| r[2].parse::<u64>().unwrap()).sum();
    assert!(masked > 0, "the mask's passes are counted:\n{text}");
    assert!(text.contains("mask.eye_unknown"), "frame 0's reason is listed:\n{text}");

    let (code, csv) = stereoshim(&["stats", "--csv", file], &home, &home);
    assert_eq!(code, 0, "{csv}");
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(lines.len() as u64, FRAMES + 1, "a header and a row per frame:\n{csv}");
    assert!(lines[1..].iter().enumerate().all(|(i, l)| l.starts_with(&format!("{i},"))), "{csv}");

    let mut bad = std::fs::read_to_string(&stats).unwrap();
    bad.push_str("{not json\n");
    let broken = home.join("broken.jsonl");
    std::fs::write(&broken, bad).unwrap();
    let (code, text) = stereoshim(&["stats", broken.to_str().unwrap()], &home, &home);
    assert_eq!(code, 1, "{text}");
    assert!(text.contains(&format!("broken.jsonl:{}: not a JSON line", FRAMES + 1)), "{text}");

    // --follow: lines appended later (a second apart) are summarised as they come.
    let growing = home.join("growing.jsonl");
    let first: Vec<String> = std::fs::read_to_string(&stats).unwrap().lines().map(String::from).collect();
    let shifted = |l: &str, dt: f64| {
        let mut v: serde_json::Value = serde_json::from_str(l).unwrap();
        v["time"] = (v["time"].as_f64().unwrap() + dt).into();
        v.to_string() + "\n"
    };
    std::fs::write(&growing, shifted(&first[0], 0.0)).unwrap();
    let mut child = Command::new(target_dir().join("stereoshim"))
        .args(["stats", "--follow", growing.to_str().unwrap()])
        .stdout(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    {
        use std::io::Write;
        let mut f = std::fs::OpenOptions::new().append(true).open(&growing).unwrap();
        // Frame 1 in the next second completes second 0; frame 2 two seconds later completes 1.
        f.write_all(shifted(&first[1], 1.0).as_bytes()).unwrap();
        f.write_all(shifted(&first[2], 3.0).as_bytes()).unwrap();
    }
    let mut out = std::io::BufReader::new(child.stdout.take().unwrap());
    let mut got = Vec::new();
    for _ in 0..3 {
        let mut l = String::new();
        std::io::BufRead::read_line(&mut out, &mut l).unwrap();
        got.push(l);
    }
    child.kill().unwrap();
    let _ = child.wait();
    assert!(got[0].starts_with("second"), "{got:?}");
    let seconds: Vec<&str> = got[1..].iter().map(|l| l.split_whitespace().next().unwrap()).collect();
    assert_eq!(seconds, ["0", "1"], "{got:?}");
}

/// A synthetic stats file: 200 frames at 90 Hz, GPU busy 10 ms until frame 100 turns the mask on,
/// 5 ms after.
fn step_stats(path: &Path) {
    let mut text = String::new();
    for n in 0..200u64 {
        let on = n >= 100;
        let line = serde_json::json!({
            "frame": n, "time": 5000.0 + n as f64 / 90.0, "mask_enabled": on, "foveation_enabled": false, "far_field_enabled": false,
            "passes_masked": if on { 2 } else { 0 }, "pixels_masked": {"0": if on { 30000 } else { 0 }, "1": if on { 30000 } else { 0 }},
            "gpu_ms": {"busy": if on { 5.0 } else { 10.0 }, "span": 11.0, "submissions": 2, "untimed": 0},
        });
        text += &(line.to_string() + "\n");
    }
    std::fs::write(path, text).unwrap();
}

/// Checks the plot of `step_stats` by its pixels: the GPU time line (found by its colour) sits,
/// above the panel's x axis, twice as high before frame 100 as after, and the one change line
/// stands at frame 100's x.
fn assert_step_plot(png: &Path) {
    use stereoshim::report::plot::{CHANGE_COLOR, GPU_COLOR};
    let img = common::image::Image::load(png);
    let (gpu, change) = ([GPU_COLOR.0, GPU_COLOR.1, GPU_COLOR.2], [CHANGE_COLOR.0, CHANGE_COLOR.1, CHANGE_COLOR.2]);
    let is = |x: u32, y: u32, c: [u8; 3]| img.pixel(x, y)[..3] == c.map(u16::from);
    // Per column, the GPU line's topmost pixel.
    let line: Vec<(u32, u32)> = (0..img.width).filter_map(|x| (0..img.height).find(|&y| is(x, y, gpu)).map(|y| (x, y))).collect();
    assert!(line.len() as u32 > img.width / 2, "{}: the GPU time line spans the plot ({} columns)", png.display(), line.len());
    let (x0, x1) = (line[0].0, line[line.len() - 1].0);
    let span = (x1 - x0) as f64;
    // Frame 100 of 0..=199, by time; each half measured away from its ends.
    let change_x = x0 as f64 + span * 100.0 / 199.0;
    let row = |from: f64, to: f64| {
        let mut ys: Vec<u32> = line.iter().filter(|(x, _)| (*x as f64) >= x0 as f64 + span * from && (*x as f64) <= x0 as f64 + span * to).map(|p| p.1).collect();
        ys.sort();
        (ys[ys.len() / 2], ys.len())
    };
    let ((before, n0), (after, n1)) = (row(0.05, 0.45), row(0.55, 0.95));
    assert!(n0 > 50 && n1 > 50, "{n0} {n1}");
    // The x axis: the first black pixel below the line in a column of the first half.
    let col = x0 + (span * 0.25) as u32;
    let axis = (before..img.height).find(|&y| is(col, y, [0, 0, 0])).expect("the GPU panel's x axis under the line");
    let ratio = (axis - before) as f64 / (axis - after) as f64;
    assert!((ratio - 2.0).abs() < 0.05, "10 ms stands {ratio:.3} times as high as 5 ms (line rows {before}, {after}, axis {axis})");
    // Change lines: columns of the GPU panel holding the change colour.
    let marks: Vec<u32> = (0..img.width).filter(|&x| (before..axis).any(|y| is(x, y, change))).collect();
    assert!(!marks.is_empty(), "no change line");
    assert!(marks.iter().all(|&x| (x as f64 - change_x).abs() <= 3.0), "change lines at x {marks:?}, frame 100 is at {change_x:.1}");
}

/// `stereoshim stats --plot`: the PNG follows the stats (GPU time, where the setting changed),
/// with or without a font for its text; refused with --follow and --csv.
#[test]
fn stats_plot_follows_the_file() {
    let home = common::output_dir("cli-stats-plot");
    let stats = home.join("step.jsonl");
    step_stats(&stats);
    let png = home.join("step.png");
    let (code, text) = stereoshim(&["stats", "--plot", png.to_str().unwrap(), stats.to_str().unwrap()], &home, &home);
    assert_eq!(code, 0, "{text}");
    assert!(text.contains("200 frames over 2.2 s, 1 setting change(s)"), "{text}");
    assert_step_plot(&png);

    // No font: the same curves, no text, and a line saying so.
    let bare = home.join("no-font.png");
    let (code, text) = stereoshim(&["stats", "--plot", bare.to_str().unwrap(), "--font", "/nonexistent.ttf", "--plot-size", "800x600", stats.to_str().unwrap()], &home, &home);
    assert_eq!(code, 0, "{text}");
    assert!(text.contains("drawn without text"), "{text}");
    assert_eq!(common::image::Image::load(&bare).width, 800);
    assert_step_plot(&bare);

    for other in ["--follow", "--csv"] {
        let (code, text) = stereoshim(&["stats", "--plot", png.to_str().unwrap(), other, stats.to_str().unwrap()], &home, &home);
        assert_eq!(code, 2, "{text}");
        assert!(text.contains(&format!("'--plot <PNG>' cannot be used with '{other}'")), "{text}");
    }
}
