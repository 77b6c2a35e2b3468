//! The layer on engine-like frame structures (xr-scene's post chains, `tests/common/post_chain.rs`):
//! the data-flow walk finds every eye pass behind tonemap, bloom, TAA, compute and subpass
//! tonemaps, render and viewport scales, dynamic resolution (a sub-rect changing every frame), a
//! double-wide texture and command buffers recorded once, and the mask applies to each from the
//! second frame on (frame 0 renders before the eyes are known; frame 1's passes, recorded before
//! any walk, are filled at their submission after its walk); the post passes themselves are
//! refused (`post_pass`), never masked. What the
//! runtime gets: outside the mask bit-identical for per-pixel chains; for bloom, every differing
//! visible pixel within the chain's filter radius of the mask edge (count and PSNR reported).
//! Every run has validation with synchronization validation on.

use crate::common;

use common::post_chain::{matrix, run_post_chain_pair, LayerConfig, PostMode};
use common::rdm::layer_records;
use common::{hidden_pixels, mask_edge_pixels, views_to_compare, RunOutput};

const FRAMES: u64 = 5;
/// The first frame every eye pass must be masked in: frame 0 renders before the OpenXR half knows
/// the eyes; frame 1's passes, recorded before any walk, get draws filled at its submission, after
/// the walk of that submission.
const FIRST_MASKED: u64 = 1;

/// Eye passes per frame: one per eye per-eye, one in multiview and side by side.
fn eye_passes(mode: &PostMode) -> u64 {
    if mode.value("--layout") == Some("per-eye") {
        2
    } else {
        1
    }
}

/// Pixels a per-pixel chain may blend across the mask edge: the resampling of a scaled target
/// (bilinear: one source texel each side) and MSAA's partly covered edge pixels.
fn edge_margin(mode: &PostMode) -> f64 {
    2.0 / scale(mode) + 1.0
}

/// The scene's smallest scale relative to the swapchain (render scale × viewport scale, ×
/// `--dynamic-resolution`'s smallest part, ¾).
fn scale(mode: &PostMode) -> f64 {
    let s = |flag| mode.value(flag).and_then(|v| v.parse::<f64>().ok()).unwrap_or(1.0);
    let dynamic = if mode.has("--dynamic-resolution") { 0.75 } else { 1.0 };
    s("--render-scale") * s("--viewport-scale") * dynamic
}

/// Bloom's reach in the scene's pixels: down-samples to ⅛ with a small blur, then bilinear
/// up-samples; a change at one pixel moves its ⅛ texel and its neighbours' (±2 texels of 8 px)
/// plus the up-sampling's texel. In the swapchain it grows by 1 / the scene's scale.
const BLOOM_RADIUS_PX: f64 = 40.0;

/// What the mask did to one view of one frame.
struct ViewDiff {
    /// Visible pixels (outside the mask and its edge band) that differ from the plain run.
    outside: usize,
    /// Visible pixels that differ but lie within `radius` of the mask edge, and their PSNR.
    near_edge: usize,
    near_edge_psnr: f64,
    hidden: usize,
}

fn diff_view(mode: &PostMode, masked: &RunOutput, plain: &RunOutput, frame: u64, radius: f64) -> Vec<(u32, ViewDiff)> {
    let mut out = Vec::new();
    let masks = &masked.frame(frame).visibility_masks;
    for (a, b) in views_to_compare(&mode.name, masked, frame, plain, frame) {
        let mask = &masks.iter().find(|m| m.view == a.view).expect("the view's mask").hidden_triangles;
        let (w, h) = (a.image_rect.width, a.image_rect.height);
        let hidden = hidden_pixels(mask, &a.fov, w, h);
        let edge = mask_edge_pixels(mask, &a.fov, w, h, edge_margin(mode));
        let near = mask_edge_pixels(mask, &a.fov, w, h, radius);
        let (got, want) = (masked.image(&a.file), plain.image(&b.file));
        let mut d = ViewDiff { outside: 0, near_edge: 0, near_edge_psnr: f64::INFINITY, hidden: hidden.iter().filter(|h| **h).count() };
        let mut sq = 0.0f64;
        let mut n = 0u64;
        for y in 0..h {
            for x in 0..w {
                let i = (y * w + x) as usize;
                if hidden[i] || edge[i] {
                    continue;
                }
                let (g, p) = (&got.pixel(x, y)[..3], &want.pixel(x, y)[..3]);
                n += 1;
                sq += g.iter().zip(p).map(|(a, b)| (*a as f64 - *b as f64).powi(2)).sum::<f64>() / 3.0;
                if g == p {
                    continue;
                }
                if near[i] {
                    d.near_edge += 1;
                } else {
                    d.outside += 1;
                }
            }
        }
        if sq > 0.0 {
            d.near_edge_psnr = 10.0 * (255.0f64 * 255.0 / (sq / n as f64)).log10();
        }
        out.push((a.view, d));
    }
    out
}

#[test]
fn every_eye_pass_behind_a_post_chain_is_masked_and_the_rest_stays_identical() {
    let mut report = Vec::new();
    for mode in matrix() {
        let mode = mode.frames(FRAMES).owned_by("post-chain-layer");
        let stats = std::env::temp_dir().join(format!("stereoshim-{}-{}.jsonl", std::process::id(), mode.name));
        let _ = std::fs::remove_file(&stats);
        let cfg = LayerConfig::off().env("STEREOSHIM_MASK_ENABLED", "1").env("STEREOSHIM_STATS_FILE", stats.to_str().unwrap());
        let (plain, masked) = run_post_chain_pair(&mode, &cfg);
        masked.assert_log_lacks(common::Half::Both, "internal failure");
        let records = layer_records(&masked, &stats);
        let _ = std::fs::remove_file(&stats);
        let want = eye_passes(&mode);
        for f in FIRST_MASKED..FRAMES {
            let r = records.iter().find(|r| r["frame"] == f).unwrap_or_else(|| panic!("{}: no stats of frame {f}", mode.name));
            assert_eq!(r["passes_masked"].as_u64(), Some(want), "{}: frame {f}: {want} eye passes, masked {}:\n{r}\n{}", mode.name, r["passes_masked"], masked.log);
            // Frame 1's post passes were recorded before the first walk: they count as what they
            // looked like then (a swapchain pass without depth, a colour target nothing tied to
            // an eye yet); from frame 2 on the walk knows them.
            let first_walk = ["no_depth_attachment", "eye_unknown"];
            for reason in ["eye_unknown", "no_depth_attachment", "depth_not_cleared", "unsupported", "rect_changing"] {
                assert!(f < 2 && first_walk.contains(&reason) || r["not_masked"].get(reason).is_none(), "{}: frame {f}: a pass not masked as {reason}: {r}", mode.name);
            }
        }
        assert!(!masked.log_lines("data-flow walk: colour target").is_empty() || mode.name.ends_with("-dw"), "{}: nothing traced:\n{}", mode.name, masked.log);
        let bloom = mode.value("--post") == Some("bloom");
        let radius = if bloom { BLOOM_RADIUS_PX / scale(&mode) } else { edge_margin(&mode) };
        for f in FIRST_MASKED..FRAMES {
            for (view, d) in diff_view(&mode, &masked, &plain, f, radius) {
                assert!(d.hidden > 0, "{}: view {view}: an empty mask", mode.name);
                assert_eq!(d.outside, 0, "{}: frame {f} view {view}: {} visible pixels beyond {radius} px of the mask edge differ", mode.name, d.outside);
                if !bloom {
                    assert_eq!(d.near_edge, 0, "{}: frame {f} view {view}: a per-pixel chain changed {} visible pixels", mode.name, d.near_edge);
                }
                if f == FRAMES - 1 {
                    report.push(format!("{}: view {view}: hidden {} px; visible pixels differing near the edge {} (PSNR of visible pixels {:.1} dB)", mode.name, d.hidden, d.near_edge, d.near_edge_psnr));
                }
            }
        }
    }
    for r in report {
        eprintln!("{r}");
    }
}

/// `eyes.fallback = size` (off by default) where the walk is off: per-eye targets of the eye's
/// size are taken as eyes in the order their passes come, LR; the same pixels as the walk's
/// result. With RL the first pass is taken as the right eye: still masked, with the other eye's
/// mask, which is why it is opt-in and per app.
#[test]
fn the_size_fallback_takes_eye_sized_targets_by_order() {
    let mode = PostMode::new("fallback-per-eye-tonemap", &["--post", "tonemap", "--layout", "per-eye"]).frames(FRAMES);
    for order in ["LR", "RL"] {
        let stats = std::env::temp_dir().join(format!("stereoshim-{}-fallback-{order}.jsonl", std::process::id()));
        let _ = std::fs::remove_file(&stats);
        let cfg = LayerConfig::off()
            .env("STEREOSHIM_MASK_ENABLED", "1")
            .env("STEREOSHIM_EYES_WALK", "0")
            .env("STEREOSHIM_EYES_FALLBACK", "size")
            .env("STEREOSHIM_EYES_FALLBACK_ORDER", order)
            .env("STEREOSHIM_STATS_FILE", stats.to_str().unwrap());
        let (plain, masked) = run_post_chain_pair(&mode, &cfg);
        let records = layer_records(&masked, &stats);
        let _ = std::fs::remove_file(&stats);
        assert!(masked.log_lines("data-flow walk: colour target").is_empty(), "eyes.walk = off: no walk");
        let taken: Vec<&str> = masked.log_lines("eyes.fallback = size: an untraced pass's target").into_iter().filter(|l| l.contains("taken as an eye target")).collect();
        assert_eq!(taken.len(), 2, "{order}: two targets taken:\n{}", masked.log);
        let first_view = if order == "LR" { "): view 0" } else { "): view 1" };
        assert!(taken.iter().any(|l| l.contains("pass 0 of the frame") && l.contains(first_view)), "{order}: {taken:?}");
        for f in 1..FRAMES {
            let r = records.iter().find(|r| r["frame"] == f).expect("stats of the frame");
            assert_eq!(r["passes_masked"].as_u64(), Some(2), "{order}: frame {f}: {r}");
            assert_eq!(r["mask_by_source"]["fallback"].as_u64(), Some(2), "{order}: frame {f}: {r}");
        }
        if order == "LR" {
            for (view, d) in diff_view(&mode, &masked, &plain, FRAMES - 1, edge_margin(&mode)) {
                assert_eq!(d.outside + d.near_edge, 0, "LR: view {view}: visible pixels changed");
            }
        }
    }
}
