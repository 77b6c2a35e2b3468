//! CPU overhead of the layer per intercepted call: xr-scene run through the mock runtime without
//! stereoshim, with it and every feature off, and with the mask, RDM and the far field on; the
//! three rotated round by round (so slow drift of the machine spreads over all three), comparing
//! per call the median CPU time the app spends inside it (xr-scene `--stats` `cpu_calls`) and
//! the time it spends recording its command buffer. Processes rather than one process: the
//! OpenXR loader allows one instance per process.
//!
//! cargo build --release --workspace && cargo build --release --examples &&
//!   target/release/examples/overhead [rounds] [frames] [layout]

#[path = "../tests/common/mod.rs"]
mod common;

use common::Run;
use std::collections::BTreeMap;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    if v.is_empty() {
        return f64::NAN;
    }
    v[v.len() / 2]
}

#[derive(Clone, Copy, PartialEq)]
enum Variant {
    NoLayer,
    FeaturesOff,
    EveryFeature,
}

/// Per call: the per-frame µs per call of one run (warm-up frames dropped), and the calls per
/// frame; "command recording" is the per-frame recording time.
fn sample(layout: &str, v: Variant, round: usize, frames: u64) -> (BTreeMap<String, Vec<f64>>, BTreeMap<String, u64>) {
    let tag = match v {
        Variant::NoLayer => "off",
        Variant::FeaturesOff => "passthrough",
        Variant::EveryFeature => "features",
    };
    let name = format!("overhead-{layout}-{tag}-{round}");
    let mut run = Run::new(&name)
        .args(["--layout", layout, "--scale", "0.1", "--submit-depth"])
        .env("MOCK_XR_EXIT_AFTER", &frames.to_string())
        .env("MOCK_XR_CAPTURE_FRAMES", "0");
    run.validation = false;
    run = match v {
        Variant::NoLayer => run,
        Variant::FeaturesOff => run.with_layer(),
        Variant::EveryFeature => common::every_feature(run, &name),
    };
    if v != Variant::NoLayer {
        run = run.env("STEREOSHIM_LOG_LEVEL", "warn");
    }
    let out = run.run();
    out.assert_ok();
    let path = common::target_dir().join("test-output").join(&out.name).join("stats.json");
    let raw: serde_json::Value = serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap();
    let frames_json = raw["frames"].as_array().unwrap();
    assert_eq!(frames_json.len() as u64, frames);
    let mut per_call: BTreeMap<String, Vec<f64>> = BTreeMap::new();
    let mut counts = BTreeMap::new();
    for f in frames_json.iter().skip(10) {
        for (call, t) in f["cpu_calls"].as_object().unwrap() {
            let n = t["calls"].as_u64().unwrap();
            per_call.entry(call.clone()).or_default().push(t["us"].as_f64().unwrap() / n as f64);
            counts.insert(call.clone(), n);
        }
        per_call.entry("command recording (per frame)".into()).or_default().push(f["cpu_record_us"].as_f64().unwrap());
    }
    (per_call, counts)
}

/// CPU time per intercepted call: no layer, layer with features off, every feature.
#[derive(clap::Parser)]
#[command(about, long_about = None)]
struct Args {
    /// Rounds; each runs the three variants, rotated.
    #[arg(default_value_t = 6, value_parser = clap::value_parser!(u64).range(1..))]
    rounds: u64,
    /// Frames per run (the first 10 are dropped).
    #[arg(default_value_t = 300, value_parser = clap::value_parser!(u64).range(11..))]
    frames: u64,
    /// xr-scene `--layout`.
    #[arg(default_value = "per-eye", value_parser = ["per-eye", "multiview", "side-by-side"])]
    layout: String,
}

fn main() {
    let args = <Args as clap::Parser>::parse();
    let (rounds, frames, layout) = (args.rounds as usize, args.frames, args.layout);
    let variants = [Variant::NoLayer, Variant::FeaturesOff, Variant::EveryFeature];
    // Per variant, per call: the per-run medians.
    let mut medians: [BTreeMap<String, Vec<f64>>; 3] = Default::default();
    let mut counts = BTreeMap::new();
    for round in 0..rounds {
        for k in 0..3 {
            let i = (k + round) % 3;
            let (per_call, c) = sample(&layout, variants[i], round, frames);
            for (call, v) in per_call {
                medians[i].entry(call).or_default().push(median(v));
            }
            counts.extend(c);
        }
    }
    println!("| call ({layout}) | calls per frame | no layer (µs/call) | layer, features off | Δ | layer, mask + RDM + far field | Δ |");
    println!("|---|---|---|---|---|---|---|");
    for (call, off) in &medians[0] {
        let m = |i: usize| medians[i].get(call).map_or(f64::NAN, |v| median(v.clone()));
        let (a, b, c) = (median(off.clone()), m(1), m(2));
        let n = counts.get(call).map_or("1".to_string(), |n| n.to_string());
        println!("| {call} | {n} | {a:.1} | {b:.1} | {:+.1} | {c:.1} | {:+.1} |", b - a, c - a);
    }
    println!("\nmedians over {rounds} rounds of per-run medians ({frames} frames each, first 10 dropped)");
}
