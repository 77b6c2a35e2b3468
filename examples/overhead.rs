//! CPU overhead of the pass-through layer, per frame: xr-scene run through the mock runtime with
//! and without stereoshim, alternated (ABBA) over several rounds, comparing the median CPU time the
//! app spends inside OpenXR calls and recording its command buffer. Processes rather than one
//! process: the OpenXR loader allows one instance per process.
//!
//! cargo build --release --workspace && cargo build --release --examples &&
//!   target/release/examples/overhead [rounds] [frames]

#[path = "../tests/common/mod.rs"]
mod common;

use common::Run;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    if v.is_empty() {
        return f64::NAN;
    }
    v[v.len() / 2]
}

/// Per-frame (xr µs, record µs) of one run, warm-up frames dropped.
fn sample(layout: &str, layer: bool, round: usize, frames: u64) -> (Vec<f64>, Vec<f64>) {
    let mut run = Run::new(&format!("overhead-{layout}-{}-{round}", if layer { "on" } else { "off" }))
        .args(["--layout", layout, "--scale", "0.1"])
        .env("MOCK_XR_EXIT_AFTER", &frames.to_string())
        .env("MOCK_XR_CAPTURE_FRAMES", "0");
    run.validation = false;
    if layer {
        run = run.with_layer().env("STEREOSHIM_LOG_LEVEL", "warn");
    }
    let out = run.run();
    out.assert_ok();
    let stats = out.stats.expect("stats");
    let path = common::target_dir().join("test-output").join(&out.name).join("stats.json");
    let raw: serde_json::Value = serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap();
    assert_eq!(stats.frames.len() as u64, frames);
    let col = |key: &str| -> Vec<f64> {
        raw["frames"].as_array().unwrap().iter().skip(10).map(|f| f[key].as_f64().unwrap()).collect()
    };
    (col("cpu_xr_us"), col("cpu_record_us"))
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let rounds: usize = args.get(1).and_then(|a| a.parse().ok()).unwrap_or(6);
    let frames: u64 = args.get(2).and_then(|a| a.parse().ok()).unwrap_or(300);
    println!("| layout | OpenXR calls, off (µs/frame) | on | Δ | command recording, off (µs/frame) | on | Δ |");
    println!("|---|---|---|---|---|---|---|");
    for layout in ["per-eye", "multiview", "side-by-side"] {
        let (mut xr_off, mut xr_on, mut rec_off, mut rec_on) = (vec![], vec![], vec![], vec![]);
        for round in 0..rounds {
            // ABBA: alternate which goes first so slow drift of the machine cancels out.
            let order = if round % 2 == 0 { [false, true] } else { [true, false] };
            for layer in order {
                let (xr, rec) = sample(layout, layer, round, frames);
                let (x, r) = if layer { (&mut xr_on, &mut rec_on) } else { (&mut xr_off, &mut rec_off) };
                x.push(median(xr));
                r.push(median(rec));
            }
        }
        let (a, b, c, d) = (median(xr_off), median(xr_on), median(rec_off), median(rec_on));
        println!("| {layout} | {a:.1} | {b:.1} | {:+.1} | {c:.1} | {d:.1} | {:+.1} |", b - a, d - c);
    }
    println!("\nmedians over {rounds} rounds of per-run medians ({frames} frames each, first 10 dropped)");
}
