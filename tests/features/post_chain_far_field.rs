//! The monoscopic far field behind every post-processing chain of xr-scene's matrix
//! (`tests/common/post_chain.rs`): with the app's projection configured (`far_field.near_z`,
//! `far_z`: xr-scene submits no depth info behind a scaled or multisampled chain), the source
//! eye's far pixels are reused in the other eye every frame once the walk knows the passes, the
//! source eye reaches the runtime bit-identical, and the other eye's pixels stay ≥ 35 dB from the
//! run without the layer (whole image: the far field's reuse through the chain), command buffers
//! recorded once and dynamic resolution (passes tied to their eyes, and their rects, only at
//! submission) included. tests/features/far_field.rs
//! `behind_a_post_chain` judges far and near pixels separately where depth is submitted.

use crate::common;

use common::post_chain::{matrix, run_post_chain_pair, LayerConfig};
use common::rdm::layer_records;
use common::views_to_compare;

const FRAMES: u64 = 5;

/// PSNR of two equally sized RGB(A) images' colour channels (infinite when identical).
fn psnr(a: &common::image::Image, b: &common::image::Image) -> f64 {
    let ch = a.channels as usize;
    let (mut sq, mut n) = (0.0f64, 0u64);
    for (p, q) in a.data.chunks_exact(ch).zip(b.data.chunks_exact(ch)) {
        for k in 0..3.min(ch) {
            sq += (p[k] as f64 - q[k] as f64).powi(2);
            n += 1;
        }
    }
    let max = if a.bit_depth > 8 { 65535.0f64 } else { 255.0 };
    if sq == 0.0 {
        f64::INFINITY
    } else {
        10.0 * (max * max / (sq / n.max(1) as f64)).log10()
    }
}

#[test]
fn the_far_field_is_reused_behind_every_post_chain() {
    let mut report = Vec::new();
    for mode in matrix() {
        let mode = mode.frames(FRAMES).owned_by("post-chain-far-field");
        let stats = std::env::temp_dir().join(format!("stereoshim-ff-{}-{}.jsonl", std::process::id(), mode.name));
        let _ = std::fs::remove_file(&stats);
        let cfg = LayerConfig::off()
            .env("STEREOSHIM_FAR_FIELD_ENABLED", "1")
            .env("STEREOSHIM_FAR_FIELD_NEAR_Z", "0.05")
            .env("STEREOSHIM_FAR_FIELD_FAR_Z", "2000")
            .env("STEREOSHIM_STATS_FILE", stats.to_str().unwrap());
        let (plain, far) = run_post_chain_pair(&mode, &cfg);
        far.assert_log_lacks(common::Half::Both, "internal failure");
        let records = layer_records(&far, &stats);
        let _ = std::fs::remove_file(&stats);
        // Per-eye passes reuse this frame's source; one pass for both eyes, the previous frame's.
        let first = if mode.value("--layout") == Some("per-eye") { 2 } else { 3 };
        for f in first..FRAMES {
            let r = records.iter().find(|r| r["frame"] == f).unwrap_or_else(|| panic!("{}: no stats of frame {f}", mode.name));
            let ff = &r["far_field"];
            let reused: u64 = ff["views_reused"].as_object().map_or(0, |m| m.values().filter_map(|v| v.as_u64()).sum());
            // Dynamic resolution: the frame whose rect first moves (2) was recorded with the last
            // one's rect and is refused at submission (`rect_changing`), and a pass for both eyes
            // reuses the previous frame's source, which that frame could not copy
            // (`no_fresh_source` in frame 3); from then on the walk knows the rect moves, the
            // passes are planned at each submission and the reuse follows the rect.
            let count = |k: &str| ff["not_applied"][k].as_u64().unwrap_or(0) + ff[k].as_u64().unwrap_or(0);
            let moving = mode.has("--dynamic-resolution") && f <= 3 && reused == 0 && count("rect_changing") + count("no_fresh_source") > 0;
            if !moving {
                assert_eq!(reused, 1, "{}: frame {f}: one view reused:\n{r}\n{}", mode.name, far.log);
                let others = ff["not_applied"].as_object().map_or(0, |m| m.iter().filter(|(k, _)| *k != "post_pass").count());
                assert_eq!(others, 0, "{}: frame {f}: {r}", mode.name);
            }
            for (a, b) in views_to_compare(&mode.name, &far, f, &plain, f) {
                let (got, want) = (far.image(&a.file), plain.image(&b.file));
                let db = psnr(&got, &want);
                if a.view == 0 {
                    assert!(db.is_infinite(), "{}: frame {f}: the source eye changed ({db:.1} dB)", mode.name);
                } else {
                    assert!(db >= 35.0, "{}: frame {f} view {}: {db:.1} dB < 35", mode.name, a.view);
                    if f == FRAMES - 1 {
                        report.push(format!("{}: view {}: {db:.1} dB, far-field views reused in frame {f}: {reused}", mode.name, a.view));
                    }
                }
            }
        }
    }
    for r in report {
        eprintln!("{r}");
    }
}
