//! GPU proof of foveated rendering, for any machine with a Vulkan GPU and no Rust: xr-scene (scale
//! 1.0, the index profile) runs once without the layer, once with `foveation.method = vrs` and
//! once with `rdm`, for every layout × rendering asked for; frame 2 is compared:
//! (a) pixels inside the inner ring (from frames.json's FOV, fovea centre (0, 0) and the preset's
//!     angle, minus a one-texel margin): must be bit-identical — the count of differing pixels;
//! (b) periphery PSNR (outside that region);
//! (c) shaded fragments without / with;
//! (d) the layer's own stats for the frame (VRS passes, or why not).
//! Exits non-zero when a fovea is not bit-identical, when VRS did not engage in a VRS run (dynamic
//! rendering and render pass objects alike: `render-pass`, `render-pass2`), or when a run fails
//! (validation errors included: xr-scene `--validation` exits non-zero on one).
//!
//! Prebuilt binaries in a folder laid out like target/release (xr-scene, libmock_runtime.so,
//! libstereoshim.so, the manifests the harness writes there, examples/fovea_check):
//!   target/release/examples/fovea_check [--layouts per-eye,side-by-side,multiview]
//!     [--renderings dynamic,render-pass,render-pass2] [--methods vrs,rdm] [--preset balanced]
//!     [--texel 16] [--hmd index] [--scale 1.0] [--depth standard|reverse] [--no-validation]
//!     [--app-args "--vulkan-api 1.0 --secondary"] [--app hello_xr:Vulkan2]

#[path = "../tests/common/mod.rs"]
mod common;

use common::{Fov, Run, RunOutput};

/// GPU proof of foveated rendering: xr-scene (or hello_xr) without the layer, with VRS and with RDM.
#[derive(clap::Parser)]
#[command(about, long_about = None)]
struct Args {
    /// Layouts to run, comma separated.
    #[arg(long, value_delimiter = ',', default_value = "per-eye,side-by-side,multiview")]
    layouts: Vec<String>,
    /// xr-scene renderings to run, comma separated.
    #[arg(long, value_delimiter = ',', default_value = "dynamic,render-pass")]
    renderings: Vec<String>,
    /// Foveation methods to run, comma separated.
    #[arg(long, value_delimiter = ',', default_value = "vrs,rdm")]
    methods: Vec<String>,
    /// foveation.preset.
    #[arg(long, default_value = "balanced", value_parser = ["subtle", "balanced", "aggressive"])]
    preset: String,
    /// The VRS texel size assumed for the fovea's margin (pixels).
    #[arg(long, default_value_t = 16.0)]
    texel: f64,
    /// HMD profile of the mock runtime (MOCK_XR_HMD).
    #[arg(long, default_value = "index")]
    hmd: String,
    /// xr-scene `--scale`.
    #[arg(long, default_value = "1.0")]
    scale: String,
    /// xr-scene `--depth`.
    #[arg(long, default_value = "standard", value_parser = ["standard", "reverse"])]
    depth: String,
    /// Run without the Khronos validation layer.
    #[arg(long = "no-validation", action = clap::ArgAction::SetFalse)]
    validation: bool,
    /// More xr-scene arguments for every run, space separated (`--app-args "--vulkan-api 1.0 --secondary"`).
    #[arg(long = "app-args", default_value = "", allow_hyphen_values = true)]
    app_args_text: String,
    /// `hello_xr:Vulkan2` (or `:Vulkan`): run Khronos hello_xr (from PATH; a Vulkan 1.0 app that
    /// links libvulkan) with that graphics plugin instead of xr-scene. Layouts and renderings do
    /// not apply: hello_xr renders one per-eye render pass per view.
    #[arg(long = "app", value_name = "hello_xr:PLUGIN", value_parser = hello_xr_plugin)]
    hello_xr: Option<String>,
    #[arg(skip)]
    app_args: Vec<String>,
}

fn hello_xr_plugin(v: &str) -> Result<String, String> {
    v.strip_prefix("hello_xr:").map(String::from).ok_or_else(|| format!("expected hello_xr:PLUGIN, got {v:?}"))
}

fn parse_args() -> Args {
    let mut a = <Args as clap::Parser>::parse();
    a.app_args = a.app_args_text.split_whitespace().map(String::from).collect();
    a
}

fn preset(name: &str) -> (f64, f64) {
    match name {
        "subtle" => (30.0, 45.0),
        "aggressive" => (12.0, 25.0),
        _ => (20.0, 35.0),
    }
}

/// Angle (degrees) between the optical axis and the direction through image point (px, py) of a
/// `w` × `h` rect (pixels, y down).
fn angle_deg(f: &Fov, w: u32, h: u32, px: f64, py: f64) -> f64 {
    let (l, r) = ((f.angle_left as f64).tan(), (f.angle_right as f64).tan());
    let (u, d) = ((f.angle_up as f64).tan(), (f.angle_down as f64).tan());
    let tx = l + px / w as f64 * (r - l);
    let ty = u - py / h as f64 * (u - d);
    (1.0 / (tx * tx + ty * ty + 1.0).sqrt()).acos().to_degrees()
}

fn psnr(se: f64, n: u64) -> f64 {
    if n == 0 || se == 0.0 {
        return f64::INFINITY;
    }
    10.0 * (255.0f64 * 255.0 / (se / n as f64)).log10()
}

const FRAME: u64 = 2;

fn shaded(o: &RunOutput, view: u32) -> u64 {
    o.stats
        .as_ref()
        .and_then(|s| s.frames.iter().find(|f| f.frame == FRAME))
        .and_then(|f| f.views.iter().find(|v| v.view == view))
        .map_or(0, |v| v.shaded_fragments)
}

fn layer_stats(path: &std::path::Path) -> serde_json::Value {
    std::fs::read_to_string(path)
        .unwrap_or_default()
        .lines()
        .filter_map(|l| serde_json::from_str::<serde_json::Value>(l).ok())
        .find(|v| v["frame"] == FRAME)
        .unwrap_or(serde_json::Value::Null)
}

fn main() {
    let a = parse_args();
    let (inner_deg, _) = preset(&a.preset);
    let mut failures = Vec::new();
    println!("| layout | rendering | method | view | inner px | inner differing | periphery PSNR dB | shaded off | shaded on | saved | layer stats (frame {FRAME}) |");
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    let (layouts, renderings) = match a.hello_xr {
        Some(_) => (vec!["per-eye".to_string()], vec!["render-pass".to_string()]),
        None => (a.layouts.clone(), a.renderings.clone()),
    };
    for layout in &layouts {
        for rendering in &renderings {
            let name = format!("fovea-check-{layout}-{rendering}-{}{}", a.depth, a.app_args.concat());
            let mut base = Run::new(&name).env("MOCK_XR_HMD", &a.hmd).env("MOCK_XR_EXIT_AFTER", &(FRAME + 1).to_string()).env("MOCK_XR_EYE_TRACKER", "0");
            base.args = vec![
                "--scale".into(),
                a.scale.clone(),
                "--layout".into(),
                layout.clone(),
                "--rendering".into(),
                rendering.clone(),
                "--depth".into(),
                a.depth.clone(),
            ];
            base.args.extend(a.app_args.iter().cloned());
            base.validation = a.validation;
            if a.hello_xr.is_some() {
                base.name = format!("fovea-check-hello_xr-{}", a.hello_xr.as_deref().unwrap_or_default());
            }
            let run_app = |r: &Run| match &a.hello_xr {
                Some(plugin) => run_hello_xr(r, plugin),
                None => r.run(),
            };
            let plain = run_app(&base);
            if plain.code != Some(0) {
                failures.push(format!("{name}: plain run failed: {}", plain.stderr));
                continue;
            }
            for method in &a.methods {
                let stats_path = common::target_dir().join("test-output").join(format!("{name}-{method}.layer-stats.jsonl"));
                let _ = std::fs::remove_file(&stats_path);
                let mut run = base
                    .clone()
                    .with_layer()
                    .env("STEREOSHIM_FOVEATION_ENABLED", "1")
                    .env("STEREOSHIM_FOVEATION_METHOD", method)
                    .env("STEREOSHIM_FOVEATION_PRESET", &a.preset)
                    .env("STEREOSHIM_FOVEATION_EYE_TRACKING", "off")
                    .env("STEREOSHIM_STATS_FILE", stats_path.to_str().unwrap());
                run.name = format!("{}-{method}", base.name);
                let out = run_app(&run);
                if out.code != Some(0) {
                    failures.push(format!("{}: run failed (validation?): {}", run.name, out.stderr));
                    continue;
                }
                let stats = layer_stats(&stats_path);
                let summary = format!("vrs {} rdm {}", stats["vrs"], stats["rdm"]["passes"]);
                if method == "vrs" && stats["vrs"]["passes"].as_u64().unwrap_or(0) == 0 {
                    failures.push(format!("{}: VRS did not engage: {}", run.name, stats["vrs"]));
                }
                // Every view of both runs, paired; a run that captured other views, sizes or
                // depth (or none) is a failure, not a shorter table.
                let pairs = match common::pair_frame(out.frames(), FRAME, plain.frames(), FRAME, common::DepthCheck::Compare) {
                    Ok(pairs) => pairs,
                    Err(e) => {
                        failures.push(format!("{}: frame {FRAME} cannot be compared with the plain run's: {e}", run.name));
                        continue;
                    }
                };
                for (got_v, want_v) in pairs {
                    let (w, h) = (got_v.image_rect.width, got_v.image_rect.height);
                    let (got, want) = (out.image(&got_v.file), plain.image(&want_v.file));
                    let m = a.texel;
                    let (mut inner, mut differing, mut se, mut n) = (0u64, 0u64, 0f64, 0u64);
                    for y in 0..h {
                        for x in 0..w {
                            let (px, py) = (x as f64, y as f64);
                            // The pixel grown by one texel lies inside the inner ring (with the
                            // centre on the axis the angle grows with the distance, so corners
                            // bound it).
                            let is_inner = [(px - m, py - m), (px + 1.0 + m, py - m), (px - m, py + 1.0 + m), (px + 1.0 + m, py + 1.0 + m)]
                                .iter()
                                .all(|&(qx, qy)| angle_deg(&got_v.fov, w, h, qx, qy) < inner_deg);
                            let (g, e) = (&got.pixel(x, y)[..3], &want.pixel(x, y)[..3]);
                            if is_inner {
                                inner += 1;
                                differing += (g != e) as u64;
                            } else {
                                se += g.iter().zip(e).map(|(&p, &q)| (p as f64 - q as f64).powi(2)).sum::<f64>();
                                n += 3;
                            }
                        }
                    }
                    if differing > 0 {
                        let dir = common::image::artifacts_dir(&format!("{}-view{}", run.name, got_v.view));
                        got.save(&dir.join("actual.png"));
                        want.save(&dir.join("expected.png"));
                        common::image::difference(&got, &want).save(&dir.join("difference.png"));
                        failures.push(format!("{} view {}: {differing} of {inner} inner-ring pixels differ; artifacts in {}", run.name, got_v.view, dir.display()));
                    }
                    let (s_off, s_on) = (shaded(&plain, got_v.view), shaded(&out, got_v.view));
                    // hello_xr has no fragment counter.
                    let saved = if s_off == 0 { "n/a".to_string() } else { format!("{:.1} %", 100.0 * (1.0 - s_on as f64 / s_off as f64)) };
                    println!(
                        "| {layout} | {rendering} | {method} | {} | {inner} | {differing} | {:.2} | {s_off} | {s_on} | {saved} | {summary} |",
                        got_v.view,
                        psnr(se, n),
                    );
                }
            }
        }
    }
    if failures.is_empty() {
        println!("fovea_check: OK");
    } else {
        for f in &failures {
            eprintln!("FAIL {f}");
        }
        std::process::exit(1);
    }
}

/// Runs hello_xr (from PATH) with graphics plugin `plugin` under `r`'s environment (runtime,
/// capture, layer and its settings), as `Run::run` runs xr-scene. hello_xr quits on a key press,
/// so its stdin stays an open pipe; `MOCK_XR_EXIT_AFTER` ends the session. Its own validation
/// layer (enabled by hello_xr when installed) reports on its output: any "Validation Error" fails
/// the run (exit code 3, like xr-scene's `--validation`).
fn run_hello_xr(r: &Run, plugin: &str) -> RunOutput {
    use std::process::{Command, Stdio};
    let dir = common::output_dir(&r.name);
    let capture = dir.join("capture");
    let mut cmd = Command::new("hello_xr");
    common::isolate(&mut cmd, &dir, &capture, r.layer);
    cmd.args(["-g", plugin])
        // hello_xr writes its validation layer's cache here (a stale cache hides errors).
        .env("HOME", &dir)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    for (k, v) in &r.env {
        cmd.env(k, v);
    }
    let started = std::time::Instant::now();
    let mut child = cmd.spawn().expect("spawn hello_xr (is it on PATH?)");
    let stdin = child.stdin.take();
    let drain = |r: Option<Box<dyn std::io::Read + Send>>| {
        std::thread::spawn(move || {
            let mut buf = Vec::new();
            if let Some(mut r) = r {
                let _ = r.read_to_end(&mut buf);
            }
            String::from_utf8_lossy(&buf).into_owned()
        })
    };
    let readers = [
        drain(child.stdout.take().map(|r| Box::new(r) as Box<dyn std::io::Read + Send>)),
        drain(child.stderr.take().map(|r| Box::new(r) as Box<dyn std::io::Read + Send>)),
    ];
    // hello_xr 1.0.20 on NVIDIA's driver did not exit after the session reached EXITING (in its
    // teardown, with or without the layer); the frames are captured by then, so a run that stalls
    // there is ended and judged on its captures, and says so.
    let limit = std::time::Duration::from_secs(45);
    let (status, signal, stalled) = loop {
        if let Some(s) = child.try_wait().expect("wait for hello_xr") {
            break (s.code(), std::os::unix::process::ExitStatusExt::signal(&s), false);
        }
        if started.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            break (None, None, true);
        }
        std::thread::sleep(std::time::Duration::from_millis(50));
    };
    drop(stdin);
    let text: String = readers.into_iter().map(|r| r.join().unwrap_or_default()).collect();
    std::fs::write(dir.join("output.txt"), &text).ok();
    let errors = text.lines().filter(|l| l.contains("Validation Error")).count();
    let frames: Option<common::Frames> = std::fs::read(capture.join("frames.json")).ok().map(|b| serde_json::from_slice(&b).expect("frames.json parses"));
    let exited_session = text.contains("XR_SESSION_STATE_EXITING");
    let complete = frames.as_ref().is_some_and(|f| f.frames.len() as u64 > FRAME) && exited_session;
    if stalled {
        eprintln!("{}: hello_xr did not exit within {limit:?}; killed ({})", r.name, if complete { "its session had ended with every frame captured" } else { "incomplete" });
    }
    let code = match (errors > 0, stalled) {
        (true, _) => Some(3),
        (false, true) => complete.then_some(0),
        (false, false) => status,
    };
    let log = std::fs::read_to_string(dir.join("state/stereoshim/stereoshim.log")).unwrap_or_default();
    RunOutput { name: r.name.clone(), code, signal, crash: None, stderr: text, capture, frames, stats: None, elapsed: started.elapsed(), log }
}
