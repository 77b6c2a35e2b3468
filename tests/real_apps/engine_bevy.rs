//! A real engine through the layer: Bevy 0.19 + bevy_mod_openxr 0.6 (wgpu 29), built from the
//! crate registry (engines/bevy-scene, scripts/engine-bevy, cached by stamp), rendering a fixed
//! scene on the mock runtime on lavapipe, with the layer (mask + RDM + far field) and without it.
//!
//! Per frame structure (Bevy's default: MSAA 4× main pass with a resolve, tonemapped in its
//! shaders, then the upscaling pass into the swapchain; HDR + bloom; MSAA off), with the layer's
//! mask, RDM and far field on: the data-flow walk finds Bevy's main passes behind the upscaling
//! (and tonemapping, bloom) passes, and every eye pass of every compared frame is masked and
//! RDM-foveated, its reconstruction run when the main pass ends (before the upscaling reads it);
//! the far field reuses the source eye's far pixels in the other eye. What the runtime gets: the
//! source eye's fovea identical to the run without the layer (but for bloom, which carries changes
//! across the image), every view's visible pixels ≥ 30 dB (RDM's reconstructed periphery, the far
//! field's reused pixels). The scene is deterministic (a run's first and last captured frames are
//! identical, so that equality means something) and visible (many colours, sky and ground); no
//! crash, no hang (CPU-time watchdog), no Vulkan validation error that the run without the layer
//! lacks (validation proven loaded; Bevy's own errors under bookworm's validation layer are
//! reported). The same scene on Monado in the trixie root: `monado` below.
//!
//! Without the binary (no `STEREOSHIM_BEVY_SCENE`, and scripts/engine-bevy fails) the tests skip
//! loudly, or fail when `STEREOSHIM_REALWORLD_REQUIRED=1` (scripts/test) or `CI` is set.

use crate::common;

mod engine;
mod monado;

use common::image::Image;
use engine::{layer_counts, not_applied_lines, LayerCounts, SceneOutput, SceneRun};

/// Frames submitted per run (the mock runtime then ends the session and the scene exits).
const FRAMES: u64 = 8;
/// Frames left out of the comparison: the layer learns which image shows which eye from the
/// first frame's `xrEndFrame` and creates its pipelines at the first eye passes.
const WARM_UP: u64 = 3;
/// Per eye, at a quarter of the Index's recommended size (2016 × 2240): lavapipe on 2 cores.
const RESOLUTION: &str = "504x560";
/// Eye passes Bevy records per frame: one main pass per view (each camera renders its own).
pub const EYE_PASSES_PER_FRAME: u64 = 2;
/// The far field's source eye (`far_field.source_view`'s default): its pixels are its own.
const SOURCE_VIEW: u32 = 0;

/// Runs `args` without and with the layer; both clean, the scene deterministic and visible, the
/// captured frames after warm-up identical. Returns what the layer did, for the report.
fn same_frames(tag: &str, args: &[&str]) -> Option<LayerCounts> {
    let exe = engine::scene_exe()?;
    let mut full: Vec<&str> = vec!["--resolution", RESOLUTION];
    full.extend_from_slice(args);
    let run = |name: &str, layer: bool| {
        SceneRun::new(name, &full, layer)
            .env("MOCK_XR_HMD", "index")
            .env("MOCK_XR_EXIT_AFTER", &FRAMES.to_string())
            .env("MOCK_XR_CAPTURE_FRAMES", &format!("{WARM_UP}-{}", FRAMES - 1))
            .run(&exe)
    };
    let plain = run(&format!("bevy-{tag}-plain"), false);
    let layered = run(&format!("bevy-{tag}-layer"), true);
    for o in [&plain, &layered] {
        o.assert_clean();
        let captured: Vec<u64> = o.out.frames().frames.iter().map(|f| f.frame).collect();
        assert_eq!(captured, (WARM_UP..FRAMES).collect::<Vec<_>>(), "{}: frames captured", o.out.name);
        for view in o.out.views(WARM_UP) {
            assert_shows_scene(&o.out.name, &o.out.image(&view.file));
        }
    }
    let added = engine::errors_added(&plain.vk_errors, &layered.vk_errors);
    assert!(added.is_empty(), "bevy-{tag}: Vulkan validation errors the run without the layer does not have: {added:?}");
    plain.out.assert_layer_not_loaded();
    layered.out.assert_layer_loaded(common::Half::Both);
    // The scene renders the same pixels every frame: what makes the runs comparable.
    common::assert_same_frame(&format!("bevy-{tag}-deterministic"), &plain.out, WARM_UP, &plain.out, FRAMES - 1);
    // What the layer did, reported before the comparison so that a failing one shows it too.
    let counts = layer_counts(&layered.stats, WARM_UP..FRAMES);
    report(tag, &plain, &layered, &counts);
    assert_eq!(counts.frames, FRAMES - WARM_UP, "bevy-{tag}: the layer's stats records of the compared frames; records: {}", layered.stats.len());
    let eye_passes = counts.frames * EYE_PASSES_PER_FRAME;
    assert_eq!(counts.passes_masked, eye_passes, "bevy-{tag}: every eye pass of the compared frames masked: {counts:?}");
    assert_eq!(counts.rdm_passes, eye_passes, "bevy-{tag}: RDM in every eye pass, reconstructed when it ends: {counts:?}");
    assert!(!counts.rdm_not_applied.contains_key("post_chain"), "bevy-{tag}: {counts:?}");
    // Reconstructed by the compute pass over periphery tiles (Bevy's main textures are 8-bit sRGB
    // or, with HDR, 16-bit float), not the fragment fill.
    assert_eq!(counts.rdm_compute, eye_passes, "bevy-{tag}: every eye reconstructed by the compute pass: {counts:?}");
    assert!(counts.far_field_views_reused > 0, "bevy-{tag}: the far field reused nothing: {counts:?}");
    // Bevy submits no depth info and nothing is configured: the range is the engine's default.
    assert!(!layered.out.log_lines("far field depth range: the engine's documented default").is_empty(), "bevy-{tag}: the depth range's source:\n{}", layered.out.log);
    let bloom = args.contains(&"--bloom");
    let diffs = engine::diff_by_mask(&plain.out, &layered.out);
    assert_eq!(diffs.len() as u64, counts.frames * 2, "bevy-{tag}: both views of every compared frame");
    for d in &diffs {
        // RDM's inner ring of the source eye reaches the runtime untouched (bloom spreads the
        // mask's and the periphery's changes across the image).
        if d.view == SOURCE_VIEW && !bloom {
            assert_eq!(d.fovea, 0, "bevy-{tag}: frame {} source view {}: {} pixels inside the fovea differ", d.frame, d.view, d.fovea);
        }
        // RDM's reconstructed periphery (and the far field's reused pixels): xr-scene's criterion.
        assert!(d.visible_psnr >= 30.0, "bevy-{tag}: frame {} view {}: visible pixels at {:.1} dB ({} differ)", d.frame, d.view, d.visible_psnr, d.outside);
    }
    eprintln!("bevy {tag}: frames {WARM_UP}..{FRAMES}: every eye pass masked and RDM-foveated; the source eye's fovea identical{}; visible pixels ≥ 30 dB", if bloom { " but for bloom" } else { "" });
    Some(counts)
}

/// A captured view shows the scene, not a clear colour or a blank image: many colours, and the
/// most common one (the sky) neither everything nor nothing.
fn assert_shows_scene(name: &str, img: &Image) {
    let ch = img.channels as usize;
    let mut counts = std::collections::HashMap::<&[u16], usize>::new();
    for px in img.data.chunks_exact(ch) {
        *counts.entry(&px[..ch.min(3)]).or_default() += 1;
    }
    let total = (img.width * img.height) as usize;
    let top = counts.values().copied().max().unwrap_or(0);
    assert!(counts.len() >= 200, "{name}: only {} distinct colours: the scene did not render", counts.len());
    assert!(top * 100 < total * 80 && top * 100 > total * 2, "{name}: the most common colour covers {top} of {total} pixels");
}

fn report(tag: &str, plain: &SceneOutput, layered: &SceneOutput, c: &LayerCounts) {
    eprintln!(
        "bevy {tag}: plain {:.1} s ({:.1} s CPU), layer {:.1} s ({:.1} s CPU); \
         Vulkan validation errors without the layer {:?}, with it {:?} (none added)",
        plain.out.elapsed.as_secs_f64(),
        plain.cpu.as_secs_f64(),
        layered.out.elapsed.as_secs_f64(),
        layered.cpu.as_secs_f64(),
        plain.vk_errors,
        layered.vk_errors
    );
    eprintln!(
        "bevy {tag}: over {} frames ({} eye passes): masked {}, RDM {}, far-field views reused {}; not masked {:?}; RDM not applied {:?}; far field not applied {:?}",
        c.frames,
        c.frames * EYE_PASSES_PER_FRAME,
        c.passes_masked,
        c.rdm_passes,
        c.far_field_views_reused,
        c.not_masked,
        c.rdm_not_applied,
        c.far_field_not_applied
    );
    for l in not_applied_lines(&layered.out.log) {
        eprintln!("bevy {tag}: layer log: {l}");
    }
    // Where the frames differ, if they do: inside the hidden area is the mask's doing, outside it
    // RDM's, the far field's or a post chain's spreading the mask edge.
    for d in engine::diff_by_mask(&plain.out, &layered.out).iter().filter(|d| d.inside + d.edge + d.outside > 0) {
        eprintln!("bevy {tag}: frame {} view {}: pixels differ inside the hidden area {}, at its edge {}, outside {}", d.frame, d.view, d.inside, d.edge, d.outside);
    }
}

/// Bevy's defaults: MSAA 4× main pass resolved into `main_texture_a` (TonyMcMapface tonemapping in
/// its shaders, no HDR), then the upscaling pass that draws it into the swapchain.
#[test]
fn default_structure_same_frames_with_and_without_the_layer() {
    same_frames("default", &[]);
}

/// HDR main pass with bloom: a tonemapping draw and bloom's mip chain between the main pass and
/// the upscaling pass.
#[test]
fn hdr_bloom_same_frames_with_and_without_the_layer() {
    same_frames("hdr-bloom", &["--hdr", "--bloom"]);
}

/// MSAA off: the main pass renders straight into `main_texture_a`, no resolve.
#[test]
fn msaa_off_same_frames_with_and_without_the_layer() {
    same_frames("msaa-off", &["--msaa", "off"]);
}

/// HDR on, MSAA off: the main pass renders straight into an RGBA16F target, then tonemapping,
/// then the upscaling pass into the swapchain (issue 33: RDM applied to 2 of 120 eye passes here,
/// `post_chain`).
#[test]
fn hdr_msaa_off_same_frames_with_and_without_the_layer() {
    same_frames("hdr-msaa-off", &["--hdr", "--msaa", "off"]);
}

/// Upscaling with every other feature (mask, RDM, far field): Bevy asks for 388×431 per eye (the
/// Index's told size at `upscale.scale = 0.77`, at this test's quarter size), renders its frame
/// graph into the layer's images, and the runtime gets 504×560 per eye, the size the run without
/// the layer renders at. Every eye pass is still masked and RDM-foveated (in the smaller images),
/// every frame is upscaled, no validation error is added, and the visible pixels stay close to the
/// native run's (RDM's periphery and the far field's reuse, both at the lower resolution, then
/// magnified, are what differs most).
#[test]
fn upscaled_with_every_feature() {
    let Some(exe) = engine::scene_exe() else { return };
    let run = |name: &str, resolution: &str, layer: bool| {
        SceneRun::new(name, &["--resolution", resolution], layer)
            .env("MOCK_XR_HMD", "index")
            .env("MOCK_XR_EXIT_AFTER", &FRAMES.to_string())
            .env("MOCK_XR_CAPTURE_FRAMES", &format!("{WARM_UP}-{}", FRAMES - 1))
            .env("STEREOSHIM_UPSCALE_ENABLED", "true")
            .run(&exe)
    };
    let plain = run("bevy-upscale-plain", RESOLUTION, false);
    let layered = run("bevy-upscale-layer", "388x431", true);
    plain.assert_clean();
    layered.assert_clean();
    let added = engine::errors_added(&plain.vk_errors, &layered.vk_errors);
    assert!(added.is_empty(), "bevy-upscale: Vulkan validation errors the run without the layer does not have: {added:?}");
    assert!(!layered.out.log_lines("the runtime shows 504x560").is_empty(), "bevy-upscale: the swapchains were not interposed at the display size:\n{}", layered.out.log);
    let counts = layer_counts(&layered.stats, WARM_UP..FRAMES);
    let eye_passes = counts.frames * EYE_PASSES_PER_FRAME;
    assert_eq!(counts.frames, FRAMES - WARM_UP, "bevy-upscale: records {}", layered.stats.len());
    assert_eq!(counts.passes_masked, eye_passes, "bevy-upscale: every eye pass masked: {counts:?}");
    assert_eq!(counts.rdm_passes, eye_passes, "bevy-upscale: RDM in every eye pass: {counts:?}");
    let upscaled = layered.stats.iter().filter(|s| s["frame"].as_u64().is_some_and(|f| f >= WARM_UP) && s["upscale"]["passes"].as_u64() == Some(2)).count() as u64;
    assert_eq!(upscaled, counts.frames, "bevy-upscale: both views of every compared frame upscaled");
    for view in layered.out.views(WARM_UP) {
        assert_shows_scene("bevy-upscale-layer", &layered.out.image(&view.file));
    }
    let diffs = engine::diff_by_mask(&plain.out, &layered.out);
    assert_eq!(diffs.len() as u64, counts.frames * 2, "bevy-upscale: both views of every compared frame");
    for d in &diffs {
        eprintln!("bevy-upscale: frame {} view {}: visible pixels {:.1} dB", d.frame, d.view, d.visible_psnr);
        assert!(d.visible_psnr >= 30.0, "bevy-upscale: frame {} view {}: visible pixels at {:.1} dB", d.frame, d.view, d.visible_psnr);
    }
}

/// The FOV cut (`view.fov_cut = lens`) with Bevy at a quarter of the Index's recommended size:
/// Bevy makes its swapchains at the told (cut) size and renders the cut angles, through its
/// MSAA main pass, tonemapping and upscaling pass; the cut stays on, and every compared view is
/// the crop of the uncut run's over what the lens shows (the cut on whole pixels of the uncut
/// grid).
#[test]
fn fov_cut() {
    let Some(exe) = engine::scene_exe() else { return };
    let run = |name: &str, cut: bool| {
        SceneRun::new(name, &[], true)
            .env("MOCK_XR_HMD", "index")
            .env("MOCK_XR_RECOMMENDED_SCALE", "0.25")
            .env("MOCK_XR_EXIT_AFTER", &FRAMES.to_string())
            .env("MOCK_XR_CAPTURE_FRAMES", &format!("{WARM_UP}-{}", FRAMES - 1))
            .env("STEREOSHIM_VIEW_FOV_CUT", if cut { "lens" } else { "off" })
            .run(&exe)
    };
    let uncut = run("bevy-fov-cut-off", false);
    let cut = run("bevy-fov-cut-on", true);
    uncut.assert_clean();
    cut.assert_clean();
    let added = engine::errors_added(&uncut.vk_errors, &cut.vk_errors);
    assert!(added.is_empty(), "bevy-fov-cut: Vulkan validation errors the uncut run does not have: {added:?}");
    assert!(cut.out.log_lines("off for this session").is_empty(), "bevy-fov-cut: the cut was turned off:\n{}", cut.out.log);
    // Each view's cut (x0, y0, width, height) from the layer's log line.
    let cuts: Vec<(u32, u32, u32, u32)> = (0..2)
        .map(|v| {
            let line = cut.out.log_lines(&format!("view.fov_cut: view {v}:")).first().copied().unwrap_or_else(|| panic!("bevy-fov-cut: no cut of view {v}:\n{}", cut.out.log)).to_string();
            let px = line.split("(pixels ").nth(1).and_then(|s| s.split(')').next()).expect("pixels");
            let n: Vec<u32> = px.split(|c: char| !c.is_ascii_digit()).filter(|s| !s.is_empty()).map(|s| s.parse().unwrap()).collect();
            (n[0], n[2], n[1] - n[0], n[3] - n[2])
        })
        .collect();
    for frame in WARM_UP..FRAMES {
        for (a, b) in cut.out.views(frame).iter().zip(uncut.out.views(frame)) {
            let (x0, y0, w, h) = cuts[a.view as usize];
            assert_eq!((a.image_rect.width, a.image_rect.height), (w, h), "bevy-fov-cut: frame {frame} view {}: not the cut size", a.view);
            let (ia, ib) = (cut.out.image(&a.file), uncut.out.image(&b.file));
            assert_shows_scene("bevy-fov-cut-on", &ia);
            let hidden = match cut.out.frame(frame).visibility_masks.iter().find(|m| m.view == a.view) {
                Some(m) => common::hidden_pixels(&m.hidden_triangles, &a.fov, w, h),
                None => vec![false; (w * h) as usize],
            };
            let max = ((1u32 << ia.bit_depth) - 1) as f64;
            let (mut se, mut n, mut differ) = (0.0, 0u64, 0u64);
            for y in 0..h {
                for x in 0..w {
                    if hidden[(y * w + x) as usize] {
                        continue;
                    }
                    let (pa, pb) = (ia.pixel(x, y), ib.pixel(x0 + x, y0 + y));
                    differ += (pa[..3] != pb[..3]) as u64;
                    se += (0..3).map(|c| ((pa[c] as f64 - pb[c] as f64) / max).powi(2)).sum::<f64>();
                    n += 1;
                }
            }
            let mse = se / (3.0 * n as f64);
            let psnr = if mse == 0.0 { f64::INFINITY } else { -10.0 * mse.log10() };
            eprintln!("bevy-fov-cut: frame {frame} view {}: {}x{} -> {w}x{h}; against the crop at ({x0}, {y0}) {psnr:.1} dB, {differ} of {n} visible pixels differ", a.view, b.image_rect.width, b.image_rect.height);
            assert!(psnr >= 45.0, "bevy-fov-cut: frame {frame} view {}: {psnr:.1} dB against the crop", a.view);
        }
    }
}
