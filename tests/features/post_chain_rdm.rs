//! Radial density masking behind post-processing chains (xr-scene's `--post` modes): the eye
//! passes the data-flow walk finds get the checkerboard, and the reconstruction runs when each
//! eye pass ends, in the app's command buffer, before the tonemap, bloom, TAA or compute pass
//! reads the target (`src/features/foveation/rdm/pass_end*.rs`); behind a tonemap subpass of the
//! same render pass (an input attachment, read per pixel), in that subpass's output when the render
//! pass ends. Every run has validation with synchronization validation on.

use crate::common;

use common::post_chain::{matrix, run_post_chain, LayerConfig};
use common::rdm::{self, layer_records, Expected};
use common::Run;

const FRAMES: u64 = 4;

/// RDM only, fixed foveation at the projection centre.
fn rdm_config() -> LayerConfig {
    LayerConfig::off()
        .env("STEREOSHIM_FOVEATION_ENABLED", "1")
        .env("STEREOSHIM_FOVEATION_METHOD", "rdm")
        .env("STEREOSHIM_FOVEATION_EYE_TRACKING", "off")
}

/// From frame 1 on (its passes, recorded before the first walk, are filled at their submission
/// from its walk), every eye pass of every mode gets the checkerboard and its reconstruction at
/// the pass's end (behind the tonemap subpass, when its render pass ends), command buffers
/// recorded once and dynamic resolution included.
#[test]
fn every_eye_pass_behind_a_post_chain_is_foveated_and_reconstructed_at_its_end() {
    for mode in matrix() {
        let mode = mode.frames(FRAMES).owned_by("post-chain-rdm");
        let stats = std::env::temp_dir().join(format!("stereoshim-rdm-{}-{}.jsonl", std::process::id(), mode.name));
        let _ = std::fs::remove_file(&stats);
        let cfg = rdm_config().env("STEREOSHIM_STATS_FILE", stats.to_str().unwrap());
        let out = run_post_chain(&mode, Some(&cfg));
        out.assert_log_lacks(common::Half::Both, "internal failure");
        let records = layer_records(&out, &stats);
        let _ = std::fs::remove_file(&stats);
        let want = if mode.value("--layout") == Some("per-eye") { 2 } else { 1 };
        for f in 1..FRAMES {
            let r = records.iter().find(|r| r["frame"] == f).unwrap_or_else(|| panic!("{}: no stats of frame {f}", mode.name));
            let rdm = &r["rdm"];
            // Dynamic resolution: the frame whose rect first moves was recorded with the last
            // one (frame 2) and is refused at submission; from then on the rect is known to move
            // and each submission fills the checkerboard and the fill for its own rect.
            if mode.has("--dynamic-resolution") && f == 2 {
                assert!(rdm["not_applied"]["rect_changing"].as_u64().unwrap_or(0) >= want, "{}: frame {f}: {r}", mode.name);
                continue;
            }
            assert_eq!(rdm["passes"].as_u64(), Some(want), "{}: frame {f}: {want} eye passes:\n{r}\n{}", mode.name, out.log);
            let reconstructed: u64 = rdm["reconstructed"].as_object().map_or(0, |m| m.values().filter_map(|v| v.as_u64()).sum());
            assert_eq!(reconstructed, 2, "{}: frame {f}: both views reconstructed: {r}", mode.name);
            // Without a post chain (the double-wide texture alone, blitted into the swapchain)
            // the reconstruction runs at the release, as for any transfer. Behind one it runs at
            // the pass's end, as the compute pass over periphery tiles (the RGBA16F scene target
            // has a compute storage, and the layer gave it TRANSFER_SRC | TRANSFER_DST).
            if mode.has("--post") {
                assert_eq!(rdm["compute"].as_u64(), Some(2), "{}: frame {f}: both eyes reconstructed by the compute pass at their pass's end: {r}", mode.name);
                assert!(rdm["fill_fallback"].as_object().is_none_or(|m| m.is_empty()), "{}: frame {f}: no fill: {r}", mode.name);
            }
            // The post passes themselves count as such; nothing else is left alone.
            let others = rdm["not_applied"].as_object().map_or(0, |m| m.iter().filter(|(k, _)| !["post_pass", "eye_unknown", "no_depth_attachment"].contains(&k.as_str())).count());
            assert_eq!(others, 0, "{}: frame {f}: {r}", mode.name);
        }
    }
}

/// Behind a per-pixel tonemap (single-sampled and 4× MSAA with the pass's own resolve), in each
/// layout: the kept quads and the inner ring reach the runtime bit-identical, the scene pass's
/// shaded fragments drop by exactly what the skipped pixels had, and the reconstructed periphery
/// (filled in HDR, then tonemapped) keeps ≥ 30 dB — by the compute pass, and by the fragment fill
/// (`foveation.rdm_reconstruction = "fill"`, the fallback for formats the compute pass cannot
/// read), which reconstruct the same pixels.
#[test]
fn behind_a_tonemap_the_fovea_is_identical_and_the_fragments_drop() {
    let (inner_deg, middle_deg) = rdm::preset("balanced");
    let expected = Expected { center: [0.0, 0.0], inner_deg, middle_deg, with_mask: false };
    let runs = [
        ("per-eye", "render-pass", "1", "auto", ""),
        ("multiview", "dynamic", "4", "auto", ""),
        ("side-by-side", "render-pass2", "1", "auto", ""),
        ("per-eye", "dynamic", "4", "auto", ""),
        ("side-by-side", "dynamic", "4", "fill", ""),
        ("multiview", "render-pass", "1", "fill", ""),
        // The tonemap as the render pass's second subpass: reconstructed in its output.
        ("per-eye", "render-pass", "1", "auto", "--post-subpass"),
        ("multiview", "render-pass2", "1", "auto", "--post-subpass"),
        ("side-by-side", "render-pass", "1", "fill", "--post-subpass"),
    ];
    let mut psnr: Vec<(String, u32, f64)> = Vec::new();
    for (layout, rendering, samples, reconstruction, subpass) in runs {
        let name = format!("rdm-post-{layout}-{rendering}-s{samples}-{reconstruction}{subpass}");
        let mut args = vec!["--layout", layout, "--rendering", rendering, "--post", "tonemap", "--samples", samples];
        if !subpass.is_empty() {
            args.push(subpass);
        }
        let base = Run::new(&name).args(args).pixel_stats().env("MOCK_XR_EYE_TRACKER", "0").env("MOCK_XR_EXIT_AFTER", "3");
        let plain = base.clone().run();
        plain.assert_ok();
        let mut layered = base.with_layer();
        for (k, v) in &rdm_config().env {
            layered = layered.env(k, v);
        }
        layered = layered.env("STEREOSHIM_FOVEATION_RDM_RECONSTRUCTION", reconstruction);
        layered.name = format!("{name}-rdm");
        let out = layered.run();
        out.assert_ok();
        let results = rdm::check_frame(&name, &plain, &out, 2, &expected).unwrap_or_else(|e| panic!("{e}"));
        for r in &results {
            assert!(r.skipped > 0, "{name} view {}: nothing skipped", r.view);
            assert_eq!(r.shaded_drop, r.skipped_fragments, "{name} view {}: shaded fragments dropped by {}, the skipped pixels had {}", r.view, r.shaded_drop, r.skipped_fragments);
            assert!(r.psnr_db >= 30.0, "{name} view {}: periphery PSNR {:.2} dB < 30", r.view, r.psnr_db);
            psnr.push((name.clone(), r.view, r.psnr_db));
        }
        let want = if reconstruction == "fill" { "the fragment fill reconstructs" } else { "radial density masking" };
        assert!(out.log.contains(want), "{name}: the log does not say {want:?}:\n{}", out.log);
        if reconstruction == "auto" {
            assert!(!out.log.contains("the fragment fill reconstructs"), "{name}: the compute pass should reconstruct:\n{}", out.log);
        }
    }
    for (name, view, db) in &psnr {
        eprintln!("{name} view {view}: periphery {db:.2} dB");
    }
}
