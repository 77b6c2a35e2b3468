//! xr-scene's post-processing frame structures (`--post tonemap|bloom|taa`, `--post-compute`,
//! `--post-subpass`, `--post-depth-attachment`, `--render-scale`, `--viewport-scale`,
//! `--submit-texture double-wide`), without stereoshim's features: every mode runs clean under
//! validation (with synchronization validation) in every layout and rendering path, its captures
//! are what the chain should make of the scene (a tonemap computed here from a plain run's
//! capture; variants that must agree do), and the layer with every feature off changes none of
//! it. What the layer achieves on these frames is asserted elsewhere, through
//! `common::post_chain::run_post_chain`.

use crate::common;

use common::image::Image;
use common::post_chain::{self, run_post_chain, LayerConfig, PostMode};
use common::RunOutput;

/// The captured image of `view` in frame `frame`.
fn view_image(out: &RunOutput, frame: u64, view: u32) -> Image {
    let v = out.views(frame).into_iter().find(|v| v.view == view).unwrap_or_else(|| panic!("{}: frame {frame} has no view {view}", out.name));
    out.image(&v.file)
}

fn distinct_colours(img: &Image) -> usize {
    let mut seen: Vec<&[u16]> = img.data.chunks_exact(img.channels as usize).map(|p| &p[..3]).collect();
    seen.sort_unstable();
    seen.dedup();
    seen.len()
}

/// Per pixel and channel (RGB), `rule(a, b)` holds everywhere; returns how many samples differ.
fn compare(label: &str, a: &Image, b: &Image, rule: impl Fn(u16, u16) -> bool) -> usize {
    assert_eq!((a.width, a.height), (b.width, b.height), "{label}: sizes differ");
    let mut differ = 0;
    for y in 0..a.height {
        for x in 0..a.width {
            for c in 0..3 {
                let (p, q) = (a.pixel(x, y)[c], b.pixel(x, y)[c]);
                assert!(rule(p, q), "{label}: pixel ({x},{y}) channel {c}: {p} vs {q}");
                differ += (p != q) as usize;
            }
        }
    }
    differ
}

/// A frame of a post-chain run looks like a frame: both views captured in every frame, neither
/// one colour, the eyes different (they look from two places), and the same in every frame for a
/// static scene, except TAA's, which converges towards the scene from a black history (each frame
/// at least as bright as the one before, and different).
fn assert_sane(mode: &PostMode, out: &RunOutput) {
    let frames: Vec<u64> = out.frames().frames.iter().map(|f| f.frame).collect();
    assert_eq!(frames.len() as u64, mode.frames, "{}: captured frames {frames:?}", mode.name);
    for &f in &frames {
        let ids: Vec<u32> = out.views(f).iter().map(|v| v.view).collect();
        assert_eq!(ids, [0, 1], "{}: frame {f}", mode.name);
        let (left, right) = (view_image(out, f, 0), view_image(out, f, 1));
        for (v, img) in [(0, &left), (1, &right)] {
            assert!(distinct_colours(img) > 64, "{}: frame {f} view {v} has {} colours", mode.name, distinct_colours(img));
        }
        assert!(left.count_different(&right) > 0, "{}: frame {f}: both eyes identical", mode.name);
    }
    let taa = mode.value("--post") == Some("taa");
    for pair in frames.windows(2) {
        for v in 0..2 {
            let (a, b) = (view_image(out, pair[0], v), view_image(out, pair[1], v));
            let label = format!("{} view {v} frames {pair:?}", mode.name);
            if taa {
                assert!(compare(&label, &b, &a, |later, earlier| later >= earlier) > 0, "{label}: TAA's history changed nothing");
            } else if mode.has("--dynamic-resolution") {
                // Each frame's eye is drawn at another resolution and upscaled: not the same pixels.
                assert!(b.count_different(&a) > 0, "{label}: the resolution did not change");
            } else {
                common::image::assert_identical(&label, &b, &a);
            }
        }
    }
}

/// Every mode of the matrix: clean under validation, sane captures, and through the layer with
/// every feature off the same captures and shaded-fragment counts.
#[test]
fn every_mode_runs_clean_and_the_layer_off_changes_nothing() {
    let modes = post_chain::matrix();
    // 13 options in each of 3 layouts, 3 double-wide modes, 2 one-target modes into a
    // swapchain per eye and 2 into one 2-layer swapchain.
    assert_eq!(modes.len(), 13 * 3 + 3 + 2 + 2, "{:?}", modes.iter().map(|m| &m.name).collect::<Vec<_>>());
    for mode in &modes {
        let (without, with) = post_chain::run_post_chain_pair(mode, &LayerConfig::off());
        assert_sane(mode, &without);
        common::assert_same_captures(&mode.name, &with, &without);
        common::assert_same_stats(&mode.name, &with, &without);
        with.assert_log_lacks(common::Half::Both, "internal failure");
    }
}

fn srgb_decode(v: u16) -> f64 {
    let c = v as f64 / 255.0;
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

fn srgb_encode(c: f64) -> f64 {
    if c <= 0.0031308 {
        c * 12.92
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    }
}

/// The tonemap of shaders/post_common.glsl (Narkowicz's ACES fit, exposure 1), in f64.
fn aces(x: f64) -> f64 {
    ((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14)).clamp(0.0, 1.0)
}

/// `--post tonemap` is the tonemap of what the eye pass rendered: computed here from the capture
/// of the same scene without the chain (sRGB bytes decoded, tonemapped, encoded), within 2 steps
/// (the plain capture is the scene rounded to 8 bits, the chain tonemaps its 16-bit float
/// values), in every layout; and it changes most of the image.
#[test]
fn tonemap_matches_its_reference() {
    for (layout, rendering) in [("per-eye", "dynamic"), ("multiview", "render-pass"), ("side-by-side", "render-pass2")] {
        let base = ["--layout", layout, "--rendering", rendering];
        let plain = run_post_chain(&PostMode::new(&format!("reference-{layout}-plain"), &base), None);
        let tone = run_post_chain(&PostMode::new(&format!("reference-{layout}-tonemap"), &[&base[..], &["--post", "tonemap"]].concat()), None);
        for v in 0..2 {
            let (p, t) = (view_image(&plain, 1, v), view_image(&tone, 1, v));
            let mut expected = p.clone();
            for px in expected.data.chunks_exact_mut(p.channels as usize) {
                for s in &mut px[..3] {
                    *s = (srgb_encode(aces(srgb_decode(*s))) * 255.0).round() as u16;
                }
            }
            let label = format!("tonemap-{layout}-view{v}");
            compare(&label, &t, &expected, |a, b| a.abs_diff(b) <= 2);
            let changed = compare(&label, &t, &p, |_, _| true);
            let samples = (p.width * p.height * 3) as usize;
            assert!(changed * 2 > samples, "{label}: the tonemap changed only {changed} of {samples} samples");
        }
    }
}

/// Runs `args` (plus `extra`) as mode `name` without the layer.
fn run(name: &str, args: &[&str], extra: &[&str]) -> RunOutput {
    run_post_chain(&PostMode::new(name, &[args, extra].concat()), None)
}

/// Variants of one chain that must agree: the tonemap as a subpass is the tonemap draw, bit for
/// bit; as a compute dispatch (which encodes sRGB itself) within one step; with an untested depth
/// attachment, bit for bit; `--render-scale F` and `--viewport-scale F` render the same pixels
/// (the same size, the same filter arithmetic), bit for bit, and look like the full-size image
/// (PSNR); one target for both eyes (`--one-target`) is a target per eye, bit for bit; bloom only brightens; TAA's first frame blends a black history (never brighter than the
/// tonemap alone); MSAA changes only edge pixels. In every layout.
#[test]
fn post_variants_agree() {
    let psnr = |a: &Image, b: &Image| {
        let all: Vec<(u32, u32)> = (0..a.height).flat_map(|y| (0..a.width).map(move |x| (x, y))).collect();
        common::far_field::psnr(a, b, &all)
    };
    for (layout, rendering, depth) in [("per-eye", "render-pass2", "reverse"), ("multiview", "render-pass", "standard"), ("side-by-side", "render-pass", "reverse")] {
        let base = ["--layout", layout, "--rendering", rendering, "--depth", depth, "--post", "tonemap"];
        let name = |tag: &str| format!("agree-{layout}-{tag}");
        let tone = run(&name("tonemap"), &base, &[]);
        let subpass = run(&name("subpass"), &base, &["--post-subpass"]);
        let compute = run(&name("compute"), &base, &["--post-compute"]);
        let depth_att = run(&name("depth-attachment"), &base, &["--post-depth-attachment"]);
        let render_scale = run(&name("render-scale"), &base, &["--render-scale", "0.5"]);
        let viewport_scale = run(&name("viewport-scale"), &base, &["--viewport-scale", "0.5"]);
        let bloom = run(&name("bloom"), &base, &["--post", "bloom"]);
        let taa = run(&name("taa"), &base, &["--post", "taa"]);
        let msaa = run(&name("msaa"), &base, &["--samples", "4"]);
        common::assert_same_captures(&name("subpass"), &subpass, &tone);
        if layout == "per-eye" {
            // One scene target and depth for both eyes, each eye's chain run before the other
            // eye renders: the same pictures as a target per eye.
            let one_target = run(&name("one-target"), &base, &["--one-target"]);
            common::assert_same_captures(&name("one-target"), &one_target, &tone);
            // The same eyes into the layers of ONE 2-layer swapchain, a target per eye or one
            // for both: still the same pictures.
            let array = run(&name("array"), &base, &["--eye-swapchain", "array"]);
            common::assert_same_captures(&name("array"), &array, &tone);
            let one_target_array = run(&name("one-target-array"), &base, &["--one-target", "--eye-swapchain", "array"]);
            common::assert_same_captures(&name("one-target-array"), &one_target_array, &tone);
        }
        common::assert_same_captures(&name("depth-attachment"), &depth_att, &tone);
        common::assert_same_captures(&name("scales"), &viewport_scale, &render_scale);
        for f in 0..2 {
            for v in 0..2 {
                let t = view_image(&tone, f, v);
                let label = |tag: &str| format!("{}-f{f}-view{v}", name(tag));
                compare(&label("compute"), &view_image(&compute, f, v), &t, |a, b| a.abs_diff(b) <= 1);
                let scaled = view_image(&render_scale, f, v);
                let db = psnr(&scaled, &t);
                assert!(db.is_finite() && db >= 20.0, "{}: PSNR {db:.1} dB against the full-size tonemap", label("render-scale"));
                let brighter = compare(&label("bloom"), &view_image(&bloom, f, v), &t, |b, t| b >= t);
                assert!(brighter > 0, "{}: bloom added nothing", label("bloom"));
                let edges = view_image(&msaa, f, v).count_different(&t);
                let pixels = (t.width * t.height) as usize;
                assert!(edges > 0 && edges * 10 < pixels, "{}: {edges} of {pixels} pixels differ", label("msaa"));
            }
        }
        for v in 0..2 {
            let darker = compare(&format!("{}-view{v}", name("taa")), &view_image(&taa, 0, v), &view_image(&tone, 0, v), |a, t| a <= t);
            assert!(darker > 0, "{}: the black history changed nothing", name("taa"));
        }
    }
}

/// `--submit-texture double-wide`: both eyes rendered side by side into the app's texture and
/// blitted into the layers of a 2-layer swapchain are the side-by-side layout's views, bit for bit
/// (the blits have the eye's size: copies with bounds), with and without a post chain.
#[test]
fn double_wide_blits_are_the_side_by_side_views() {
    for (tag, extra) in [("plain", &[][..]), ("tonemap", &["--post", "tonemap"]), ("taa-scaled", &["--post", "taa", "--render-scale", "0.5", "--samples", "4"])] {
        let base = [&["--layout", "side-by-side", "--rendering", "dynamic"][..], extra].concat();
        let sbs = run(&format!("dw-{tag}-sbs"), &base, &[]);
        let dw = run(&format!("dw-{tag}-texture"), &base, &["--submit-texture", "double-wide"]);
        // Submitted differently: one double-wide image, or one layer each of an array.
        let layers = |o: &RunOutput| o.views(1).iter().map(|v| (v.image_array_index, v.image_rect.x)).collect::<Vec<_>>();
        assert_eq!(layers(&sbs), [(0, 0), (0, sbs.views(1)[0].image_rect.width as i32)], "dw-{tag}");
        assert_eq!(layers(&dw), [(0, 0), (1, 0)], "dw-{tag}");
        common::assert_same_captures(&format!("dw-{tag}"), &dw, &sbs);
    }
}

/// The full cross product of layouts, rendering paths, depth conventions, options and sample
/// counts (`common::post_chain::full_matrix`), each without the layer and through it with every
/// feature off: clean, sane, unchanged. Several hundred runs: `scripts/post-chain-matrix`.
#[test]
#[ignore = "the full cross product (several hundred runs, minutes on lavapipe): scripts/post-chain-matrix"]
fn full_matrix_runs_clean_and_the_layer_off_changes_nothing() {
    let modes = post_chain::full_matrix();
    assert!(modes.len() >= 250, "{} modes", modes.len());
    for mode in &modes {
        let mode = PostMode { name: format!("full-{}", mode.name), ..mode.clone() };
        let (without, with) = post_chain::run_post_chain_pair(&mode, &LayerConfig::off());
        assert_sane(&mode, &without);
        common::assert_same_captures(&mode.name, &with, &without);
    }
}
