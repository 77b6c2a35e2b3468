//! The feature benchmark: xr-scene, fragment-bound (`--shading-cost`), through the mock runtime
//! and stereoshim, with the layer's config switched live between "features off" (A) and "features
//! on" (B) every `--period` frames within ONE run, so both halves see the same machine state. Per
//! frame, the layer's `stats.file` says which mode the frame ran in and what it masked; xr-scene's
//! `--stats` gives the GPU time and the exactly counted shaded fragments of the same frame.
//! The layer's own GPU timer (`stats.gpu_time`, on in both modes) adds the frame's end-to-end GPU
//! busy time: every submission of the frame, the layer's own work (RDM's reconstruction) included,
//! which the app's timestamps around its command buffer cannot see.
//!
//! cargo build --release --workspace && cargo build --release --examples &&
//!   target/release/examples/bench [--hmd index] [--layout per-eye] [--scale 0.5]
//!   [--shading-cost 64] [--frames 400] [--period 40] [--feature mask]
//!   [--app-args "--empty"] [--config 'mask.source = "synthesized"; mask.synthesized.radius_deg = 89']

#[path = "../tests/common/mod.rs"]
mod common;

use std::collections::BTreeMap;
use std::path::Path;
use std::process::Command;
use std::time::Duration;

/// A/B benchmark of stereoshim's features within one xr-scene run on the mock runtime.
#[derive(clap::Parser)]
#[command(about, long_about = None)]
struct Args {
    /// HMD profile of the mock runtime (MOCK_XR_HMD).
    #[arg(long, default_value = "index")]
    hmd: String,
    /// xr-scene `--layout`.
    #[arg(long, default_value = "per-eye")]
    layout: String,
    /// xr-scene `--scale`.
    #[arg(long, default_value = "0.5")]
    scale: String,
    /// xr-scene `--shading-cost`: how fragment-bound the frame is.
    #[arg(long, default_value = "64")]
    shading_cost: String,
    /// Frames of the run.
    #[arg(long, default_value_t = 400)]
    frames: u64,
    /// Frames per mode before switching between features off (A) and on (B).
    #[arg(long, default_value_t = 40)]
    period: u64,
    /// The feature(s) switched, comma separated (`mask,foveation,far_field`; `fov_cut` is
    /// `view.fov_cut = "lens"`, `symmetric` `view.symmetric = "horizontal"` (`symmetric_full`:
    /// `"full"`), `parallel` `view.parallel = "on"`).
    #[arg(long, default_value = "mask")]
    feature: String,
    /// Extra xr-scene arguments, space separated (`--app-args "--empty"`).
    #[arg(long, default_value = "", allow_hyphen_values = true)]
    app_args: String,
    /// Extra config lines for both modes, `;` separated (`--config 'mask.source = "synthesized"'`).
    #[arg(long, default_value = "")]
    config: String,
}

impl Args {
    fn app_args(&self) -> Vec<String> {
        self.app_args.split_whitespace().map(String::from).collect()
    }

    fn config(&self) -> String {
        self.config.replace(';', "\n")
    }
}

/// The config text for mode B (features on) or A (off); `feature` may list several, comma
/// separated (`mask,foveation,far_field`), switched together.
fn config_text(feature: &str, on: bool, stats: &Path, extra: &str) -> String {
    // The view tricks are `view.*` choices; every other feature its `.enabled`.
    let switches: String = feature
        .split(',')
        .map(|f| match f {
            "fov_cut" => format!("view.fov_cut = {:?}\n", if on { "lens" } else { "off" }),
            "symmetric" => format!("view.symmetric = {:?}\n", if on { "horizontal" } else { "off" }),
            "symmetric_full" => format!("view.symmetric = {:?}\n", if on { "full" } else { "off" }),
            "parallel" => format!("view.parallel = {:?}\n", if on { "on" } else { "off" }),
            f => format!("{f}.enabled = {on}\n"),
        })
        .collect();
    format!("stats.file = {:?}\nstats.gpu_time = true\n{switches}{extra}\n", stats.to_string_lossy())
}

/// Rewrites the config through a rename, so the layer never reads half a file and sees a new
/// modification time.
fn write_config(path: &Path, text: &str) {
    let tmp = path.with_extension("tmp");
    std::fs::write(&tmp, text).unwrap();
    std::fs::rename(&tmp, path).unwrap();
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    if v.is_empty() {
        f64::NAN
    } else {
        v[v.len() / 2]
    }
}

/// The upscale and the FOV cut are latched per XR instance (the told size cannot change under an
/// app's swapchains): their A/B alternates whole instances of xr-scene (`--instances`), switching the
/// config between them, and takes each frame's mode and end-to-end GPU time (every submission,
/// the upscale's included) from the layer's own record, whose frame numbers restart per instance.
fn bench_per_instance(a: &Args) {
    let instances = a.frames.div_ceil(a.period).max(2);
    let (app_args, extra_config) = (a.app_args(), a.config());
    let tag: String = (app_args.concat() + &extra_config).chars().filter(|c| c.is_ascii_alphanumeric()).collect();
    let dir = common::output_dir(&format!("bench-{}-{}-{}-{tag}", a.feature, a.hmd, a.layout));
    let layer_stats = dir.join("layer-stats.jsonl");
    let _ = std::fs::remove_file(&layer_stats);
    let config = dir.join("config/stereoshim/config.toml");
    std::fs::create_dir_all(config.parent().unwrap()).unwrap();
    write_config(&config, &config_text(&a.feature, false, &layer_stats, &extra_config));
    let mut child = Command::new(common::xr_scene_exe())
        .args(["--layout", &a.layout, "--scale", &a.scale, "--shading-cost", &a.shading_cost, "--instances", &instances.to_string()])
        .args(&app_args)
        .env("XR_RUNTIME_JSON", common::runtime_manifest())
        .env("XR_API_LAYER_PATH", common::layer_manifest_dir())
        .env("XR_ENABLE_API_LAYERS", common::XR_LAYER_NAME)
        .env("XDG_CONFIG_HOME", dir.join("config"))
        .env("XDG_STATE_HOME", dir.join("state"))
        .env("XDG_RUNTIME_DIR", dir.join("run"))
        .env("MOCK_XR_HMD", &a.hmd)
        .env("MOCK_XR_EXIT_AFTER", a.period.to_string())
        .env_remove("STEREOSHIM_CONFIG")
        .spawn()
        .expect("spawn xr-scene");
    // A new instance reads the config when it starts: switch as soon as an instance's frames are
    // all in (its last frame number is `period - 1`).
    let (mut on, mut seen) = (false, 0usize);
    loop {
        if let Some(status) = child.try_wait().unwrap() {
            assert!(status.success(), "xr-scene failed: {status}");
            break;
        }
        let text = std::fs::read_to_string(&layer_stats).unwrap_or_default();
        let lines: Vec<&str> = text.lines().collect();
        for line in &lines[seen.min(lines.len())..] {
            if line.contains(&format!("\"frame\":{},", a.period - 1)) {
                on = !on;
                write_config(&config, &config_text(&a.feature, on, &layer_stats, &extra_config));
            }
        }
        seen = lines.len();
        std::thread::sleep(Duration::from_millis(1));
    }
    let (mut busy, mut px, mut own) = ([vec![], vec![]], [vec![], vec![]], vec![]);
    for line in std::fs::read_to_string(&layer_stats).unwrap().lines() {
        let v: serde_json::Value = serde_json::from_str(line).unwrap();
        // Warm-up of each instance (pipelines, images and buffers are made lazily).
        if v["frame"].as_u64().unwrap_or(0) < 10 {
            continue;
        }
        let on = |k: &str| v[k].as_bool().unwrap_or(false);
        let i = (on("upscale_enabled") || on("view_fov_cut") || on("view_parallel") || v["view_symmetric"].as_str().is_some_and(|m| m != "off")) as usize;
        if let Some(b) = v["gpu_ms"]["busy"].as_f64() {
            busy[i].push(b);
        }
        if let Some(ms) = v["upscale"]["gpu_ms"].as_f64() {
            own.push(ms);
            if own.len() == 20 {
                println!("upscale phases (barriers in and resolves, EASU, RCAS and the copy or the fragment pass, barriers out), ms: {}", v["upscale"]["phases_ms"]);
            }
        }
        if let Some(r) = v["upscale"]["rendered_px"].as_u64() {
            px[1].push(r as f64);
            px[0].push(v["upscale"]["display_px"].as_u64().unwrap_or(0) as f64);
        }
    }
    let (off, on) = (median(busy[0].clone()), median(busy[1].clone()));
    println!("| hmd | layout | feature | frames off/on | frame GPU ms off | frame GPU ms on | speed-up | rendered / display px | upscale's own GPU ms |");
    println!("|---|---|---|---|---|---|---|---|---|");
    println!(
        "| {} | {} | {} | {}/{} | {off:.3} | {on:.3} | {:.2}x | {:.0} / {:.0} | {:.3} |",
        a.hmd,
        a.layout,
        a.feature,
        busy[0].len(),
        busy[1].len(),
        off / on,
        median(px[1].clone()),
        median(px[0].clone()),
        median(own)
    );
}

fn main() {
    let a = <Args as clap::Parser>::parse();
    // Features latched per XR instance are switched between instances.
    if a.feature.split(',').any(|f| ["upscale", "fov_cut", "symmetric", "symmetric_full", "parallel"].contains(&f)) {
        return bench_per_instance(&a);
    }
    let (app_args, extra_config) = (a.app_args(), a.config());
    let tag: String = (app_args.concat() + &extra_config).chars().filter(|c| c.is_ascii_alphanumeric()).collect();
    let name = format!("bench-{}-{}-{}-{tag}", a.feature, a.hmd, a.layout);
    let dir = common::output_dir(&name);
    let (layer_stats, app_stats, capture) = (dir.join("layer-stats.jsonl"), dir.join("app-stats.json"), dir.join("capture"));
    let config = dir.join("config/stereoshim/config.toml");
    std::fs::create_dir_all(config.parent().unwrap()).unwrap();
    write_config(&config, &config_text(&a.feature, false, &layer_stats, &extra_config));

    let mut child = Command::new(common::xr_scene_exe())
        .args(["--layout", &a.layout, "--scale", &a.scale, "--shading-cost", &a.shading_cost])
        .args(&app_args)
        .arg("--stats")
        .arg(&app_stats)
        .env("XR_RUNTIME_JSON", common::runtime_manifest())
        .env("XR_API_LAYER_PATH", common::layer_manifest_dir())
        .env("XR_ENABLE_API_LAYERS", common::XR_LAYER_NAME)
        .env("XDG_CONFIG_HOME", dir.join("config"))
        .env("XDG_STATE_HOME", dir.join("state"))
        .env("XDG_RUNTIME_DIR", dir.join("run"))
        .env("MOCK_XR_HMD", &a.hmd)
        .env("MOCK_XR_EXIT_AFTER", a.frames.to_string())
        .env("MOCK_XR_CAPTURE", &capture)
        .env("MOCK_XR_CAPTURE_FRAMES", "0")
        .env_remove("STEREOSHIM_CONFIG")
        .spawn()
        .expect("spawn xr-scene");

    // Switch modes by the layer's own account: once it has reported `period` frames in the
    // requested mode, request the other one (the layer applies a config change at a frame
    // boundary, within its reload interval).
    let first = a.feature.split(',').next().unwrap_or_default().to_string();
    let key = format!("\"{first}_enabled\":");
    let (mut on, mut in_mode) = (false, 0u64);
    let mut seen = 0usize;
    loop {
        if let Some(status) = child.try_wait().unwrap() {
            assert!(status.success(), "xr-scene failed: {status}");
            break;
        }
        let text = std::fs::read_to_string(&layer_stats).unwrap_or_default();
        let lines: Vec<&str> = text.lines().collect();
        for line in &lines[seen.min(lines.len())..] {
            if line.contains(&format!("{key}{on}")) {
                in_mode += 1;
            }
        }
        seen = lines.len();
        if in_mode >= a.period {
            on = !on;
            in_mode = 0;
            write_config(&config, &config_text(&a.feature, on, &layer_stats, &extra_config));
        }
        std::thread::sleep(Duration::from_millis(2));
    }

    // Join the layer's per-frame record with the app's by frame number.
    let mut mode: BTreeMap<u64, (bool, u64)> = BTreeMap::new();
    // The layer's end-to-end GPU busy time per frame (None: not measured for that frame).
    let mut layer_busy: BTreeMap<u64, f64> = BTreeMap::new();
    // Pixels the far field reused per frame (counted as submissions complete).
    let mut reused: BTreeMap<u64, u64> = BTreeMap::new();
    for line in std::fs::read_to_string(&layer_stats).unwrap().lines() {
        let v: serde_json::Value = serde_json::from_str(line).unwrap();
        let pixels: u64 = v["pixels_masked"].as_object().map(|m| m.values().filter_map(|x| x.as_u64()).sum()).unwrap_or(0);
        let n = v["frame"].as_u64().unwrap();
        mode.insert(n, (v[format!("{first}_enabled")].as_bool().unwrap_or(false), pixels));
        if let Some(p) = v["far_field"]["pixels_reused"].as_u64() {
            reused.insert(n, p);
        }
        if let Some(busy) = v["gpu_ms"]["busy"].as_f64() {
            layer_busy.insert(n, busy);
        }
    }
    let app: serde_json::Value = serde_json::from_slice(&std::fs::read(&app_stats).unwrap()).unwrap();
    let frames_json: serde_json::Value = serde_json::from_slice(&std::fs::read(capture.join("frames.json")).unwrap()).unwrap();
    let pixels_total: u64 = frames_json["frames"][0]["layers"][0]["views"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v["image_rect"]["width"].as_u64().unwrap() * v["image_rect"]["height"].as_u64().unwrap())
        .sum();
    let (mut gpu, mut shaded, mut masked, mut busy, mut reused_on) = ([vec![], vec![]], [vec![], vec![]], vec![], [vec![], vec![]], vec![]);
    for f in app["frames"].as_array().unwrap() {
        let n = f["frame"].as_u64().unwrap();
        let Some(&(is_on, pixels)) = mode.get(&n) else { continue };
        // Warm-up, and the first frame of each mode (pipelines and buffers are made lazily).
        if n < 10 || mode.get(&(n - 1)).is_none_or(|p| p.0 != is_on) {
            continue;
        }
        let i = is_on as usize;
        gpu[i].push(f["gpu_time_ms"].as_f64().unwrap());
        if let Some(&b) = layer_busy.get(&n) {
            busy[i].push(b);
        }
        shaded[i].push(f["views"].as_array().unwrap().iter().map(|v| v["shaded_fragments"].as_u64().unwrap()).sum::<u64>() as f64);
        if is_on {
            masked.push(pixels as f64);
            if let Some(&r) = reused.get(&n) {
                reused_on.push(r as f64);
            }
        }
    }
    let (g_off, g_on) = (median(gpu[0].clone()), median(gpu[1].clone()));
    let (s_off, s_on) = (median(shaded[0].clone()), median(shaded[1].clone()));
    let (b_off, b_on) = (median(busy[0].clone()), median(busy[1].clone()));
    let masked_fraction = median(masked) / pixels_total as f64;
    let time_saved = 1.0 - g_on / g_off;
    let shaded_saved = 1.0 - s_on / s_off;
    // "GPU ms": xr-scene's timestamps around its own command buffer. "frame GPU ms": the layer's
    // timer, the union of every submission of the frame (the layer's own work included).
    println!("| hmd | layout | frames off/on | GPU ms off | GPU ms on | saved | frame GPU ms off | frame GPU ms on | saved | shaded off | shaded on | saved | masked fraction | time saved / masked |");
    // (With `--app-args --empty` nothing is shaded: "GPU ms on − off" is then the layer's own cost.)
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    println!(
        "| {} | {} | {}/{} | {g_off:.3} | {g_on:.3} | {:.1} % | {b_off:.3} | {b_on:.3} | {:.1} % | {s_off:.0} | {s_on:.0} | {:.1} % | {:.1} % | {:.2} |",
        a.hmd,
        a.layout,
        gpu[0].len(),
        gpu[1].len(),
        time_saved * 100.0,
        (1.0 - b_on / b_off) * 100.0,
        shaded_saved * 100.0,
        masked_fraction * 100.0,
        time_saved / masked_fraction
    );
    if !reused_on.is_empty() {
        // The far field reuses pixels of the destination view: its share of one eye's pixels.
        println!("far field: reused {:.1} % of the destination view (median {:.0} pixels per frame)", 100.0 * median(reused_on.clone()) * 2.0 / pixels_total as f64, median(reused_on));
    }
}
