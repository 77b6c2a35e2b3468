//! Upscaling (`upscale.*`, src/xr/upscale.rs) on the mock runtime and lavapipe: the app is told
//! the scaled size and renders at it into the layer's images; the runtime receives display-size
//! images whose pixels come close to a native-resolution run's (PSNR, SSIM), with EASU + RCAS
//! sharper at edges than a bilinear upscale; the feature off changes nothing.

use crate::common;

use common::image;
use common::{Run, RunOutput};
use stereoshim::features::upscale::filter::{self, quality, Rgb};

/// A captured PNG as the filters' image (values in [0, 1]).
fn as_filter_image(i: &image::Image) -> filter::Image {
    let max = ((1u32 << i.bit_depth) - 1) as f32;
    filter::Image::from_fn(i.width, i.height, |x, y| {
        let p = i.pixel(x, y);
        Rgb([p[0] as f32 / max, p[1] as f32 / max, p[2] as f32 / max])
    })
}

/// `size`×`size` crops at `at` of `images`, each magnified `zoom`× (nearest), side by side with a
/// 2-pixel gap.
fn crops(images: &[&image::Image], at: (u32, u32), size: u32, zoom: u32) -> image::Image {
    let (w, h) = (images.len() as u32 * (size * zoom + 2), size * zoom);
    let mut data = vec![255u16; (w * h * 3) as usize];
    for (k, img) in images.iter().enumerate() {
        for y in 0..h {
            for x in 0..size * zoom {
                let p = img.pixel((at.0 + x / zoom).min(img.width - 1), (at.1 + y / zoom).min(img.height - 1));
                let o = ((y * w + k as u32 * (size * zoom + 2) + x) * 3) as usize;
                for c in 0..3 {
                    data[o + c] = if img.bit_depth == 16 { p[c] >> 8 } else { p[c] };
                }
            }
        }
    }
    image::Image { width: w, height: h, channels: 3, bit_depth: 8, data }
}

fn upscaled(run: Run, name: &str, method: &str) -> Run {
    let mut run = run.env("STEREOSHIM_UPSCALE_ENABLED", "1").env("STEREOSHIM_UPSCALE_METHOD", method);
    run.name = name.into();
    run
}

/// The pixels of captured view `v` of frame 1 the runtime's hidden-area mesh covers (what the lens
/// never shows; none when the runtime has no mesh).
fn lens_hidden(run: &RunOutput, v: &common::View) -> Vec<bool> {
    let (w, h) = (v.image_rect.width, v.image_rect.height);
    match run.frame(1).visibility_masks.iter().find(|m| m.view == v.view) {
        Some(m) => common::hidden_pixels(&m.hidden_triangles, &v.fov, w, h),
        None => vec![false; (w * h) as usize],
    }
}

/// `i` with the pixels in `hidden` black.
fn shown(i: &filter::Image, hidden: &[bool]) -> filter::Image {
    filter::Image::from_fn(i.width, i.height, |x, y| if hidden[(y * i.width + x) as usize] { Rgb([0.0; 3]) } else { i.at(x as i64, y as i64) })
}

/// Per captured view of frame 1: (PSNR, SSIM, edge energy) of `on` against `native` over what the
/// runtime shows (the pixels the lens never shows are black in both: the upscale skips them,
/// `upscale.skip_hidden`).
fn quality_of(label: &str, on: &RunOutput, native: &RunOutput) -> Vec<(f64, f64, f64)> {
    let (a, b) = (on.views(1), native.views(1));
    assert_eq!(a.len(), b.len(), "{label}: views");
    a.iter()
        .zip(&b)
        .map(|(va, vb)| {
            let (ia, ib) = (on.image(&va.file), native.image(&vb.file));
            assert_eq!((ia.width, ia.height), (ib.width, ib.height), "{label}: view {} is not at the display size", va.view);
            let hidden = lens_hidden(on, va);
            let (fa, fb) = (as_filter_image(&ia), as_filter_image(&ib));
            // Edges where the pixel and the neighbours its gradient reads are all shown.
            let (w, h) = (ia.width as i64, ia.height as i64);
            let is_shown = |x: i64, y: i64| !hidden[(y.clamp(0, h - 1) * w + x.clamp(0, w - 1)) as usize];
            let edges = quality::edge_energy_where(&fa, &fb, 0.1, &|x, y| is_shown(x, y) && is_shown(x + 1, y) && is_shown(x, y + 1));
            let (fa, fb) = (shown(&fa, &hidden), shown(&fb, &hidden));
            let q = (quality::psnr(&fa, &fb), quality::ssim(&fa, &fb), edges);
            eprintln!("{label} view {}: {}x{} PSNR {:.2} dB, SSIM {:.4}, edge energy {:.3}", va.view, ia.width, ia.height, q.0, q.1, q.2);
            q
        })
        .collect()
}

#[test]
fn the_runtime_gets_display_size_images_close_to_native() {
    let base = Run::new("upscale-native").with_layer();
    let native = base.run();
    native.assert_ok();
    let on = upscaled(base.clone(), "upscale-easu", "easu_rcas").run();
    on.assert_ok();
    let told = on.log_lines("upscale: told the app");
    assert!(!told.is_empty(), "the app was not told a scaled size");
    assert!(!on.log_lines("the runtime shows").is_empty(), "no swapchain was interposed");
    let fsr = quality_of("easu_rcas", &on, &native);
    let bil = upscaled(base, "upscale-bilinear", "bilinear").run();
    bil.assert_ok();
    let lin = quality_of("bilinear", &bil, &native);
    // docs/upscaling.md's picture: a crop of view 0 from each run, side by side, magnified 3×
    // (nearest), written next to the captures.
    let (n, b, f) = (native.image(&native.views(1)[0].file), bil.image(&bil.views(1)[0].file), on.image(&on.views(1)[0].file));
    crops(&[&n, &b, &f], (n.width / 2 - 40, n.height / 2 - 30), 64, 3).save(&common::output_dir("upscale-easu").join("crops.png"));
    for ((p, s, e), (_, _, e_bil)) in fsr.iter().zip(&lin) {
        assert!(*p >= 30.0, "PSNR {p:.2} dB under 30");
        assert!(*s >= 0.95, "SSIM {s:.4} under 0.95");
        assert!(e > e_bil, "EASU+RCAS edges ({e:.3}) not sharper than bilinear's ({e_bil:.3})");
    }
    // CAS (upscale.method = cas): close to native, and sharper than bilinear too.
    let cas = upscaled(Run::new("upscale-native").with_layer(), "upscale-cas", "cas").run();
    cas.assert_ok();
    for ((p, s, e), (_, _, e_bil)) in quality_of("cas", &cas, &native).iter().zip(&lin) {
        // Sharper than EASU + RCAS at the same sharpness, a little further from native.
        assert!(*p >= 30.0 && *s >= 0.94, "CAS: PSNR {p:.2} dB, SSIM {s:.4}");
        assert!(e > e_bil, "CAS edges ({e:.3}) not sharper than bilinear's ({e_bil:.3})");
    }
}

/// Every layout × rendering, validation (with synchronization) on: the swapchains are interposed,
/// the runtime gets display-size images at every view's full size, close to native, and the app's
/// frame count is unchanged.
#[test]
fn every_layout_and_rendering() {
    let cases = ["per-eye", "multiview", "side-by-side"].into_iter().flat_map(|l| ["render-pass", "dynamic"].map(|r| (l, r, "enable2")));
    // XR_KHR_vulkan_enable too: the app makes its Vulkan instance and device itself.
    for (layout, rendering, vulkan) in cases.chain([("per-eye", "render-pass", "enable")]) {
        {
            let label = format!("{layout}-{rendering}-{vulkan}");
            let base = Run::new(&format!("upscale-native-{label}")).with_layer().args(["--layout", layout, "--rendering", rendering, "--vulkan", vulkan]);
            let native = base.run();
            native.assert_ok();
            let on = upscaled(base, &format!("upscale-{label}"), "easu_rcas").run();
            on.assert_ok();
            assert!(!on.log_lines("the runtime shows").is_empty(), "{label}: no swapchain was interposed");
            assert_eq!(on.frames().frames.len(), native.frames().frames.len(), "{label}: captured frames");
            for (p, s, _) in quality_of(&label, &on, &native) {
                assert!(p >= 30.0 && s >= 0.95, "{label}: PSNR {p:.2} dB, SSIM {s:.4}");
            }
        }
    }
}

/// A recording made once and submitted every frame (record-once), and dynamic resolution (a
/// smaller rect each frame: the upscale follows the submitted rect and fills the view).
#[test]
fn record_once_and_dynamic_resolution() {
    let cases: [(&str, &[&str]); 2] = [("record-once", &["--record-once"]), ("dynamic", &["--post", "tonemap", "--viewport-scale", "0.8", "--dynamic-resolution"])];
    for (label, args) in cases {
        let base = Run::new(&format!("upscale-native-{label}")).with_layer().args(args.iter().copied()).env("MOCK_XR_EXIT_AFTER", "4");
        let native = base.run();
        native.assert_ok();
        let on = upscaled(base, &format!("upscale-{label}"), "easu_rcas").run();
        on.assert_ok();
        for (va, vb) in on.views(1).iter().zip(native.views(1)) {
            assert_eq!((va.image_rect.width, va.image_rect.height), (vb.image_rect.width, vb.image_rect.height), "{label}: the runtime's rect is not the view's display size");
        }
        for (p, s, _) in quality_of(label, &on, &native) {
            assert!(p >= 28.0 && s >= 0.9, "{label}: PSNR {p:.2} dB, SSIM {s:.4}");
        }
    }
}

/// The OpenVR submission path (`--submit-via openvr`): the app renders the size it was told into
/// textures of its own, which a second component copies (or blits, from a double-wide texture)
/// into the interposed swapchain in a submission of its own; the runtime still gets display-size
/// images close to native.
#[test]
fn openvr_submission() {
    let cases: [(&str, &[&str]); 3] = [
        ("openvr-intermediate", &["--intermediate", "--samples", "1", "--submit-via", "openvr"]),
        ("openvr-double-wide", &["--layout", "side-by-side", "--submit-texture", "double-wide", "--submit-via", "openvr"]),
        // xrizer's order: a temporary session on a device of its own first, then the real one on
        // the app's device with the legacy XR_KHR_vulkan_enable.
        ("openvr-temporary", &["--intermediate", "--samples", "1", "--submit-via", "openvr", "--vulkan", "enable", "--temporary-session"]),
    ];
    for (label, args) in cases {
        let base = Run::new(&format!("upscale-native-{label}")).with_layer().args(args.iter().copied()).env("MOCK_XR_EXIT_AFTER", "4");
        let native = base.run();
        native.assert_ok();
        let on = upscaled(base, &format!("upscale-{label}"), "easu_rcas").run();
        on.assert_ok();
        assert!(!on.log_lines("the runtime shows").is_empty(), "{label}: no swapchain was interposed");
        if args.contains(&"--temporary-session") {
            // The temporary session's device (its stats line comes first) gets nothing of the
            // layer's: no image, no pass, no object.
            let lines = on.log_lines("vulkan device stats:");
            assert_eq!(lines.len(), 2, "{label}: one stats line per device:\n{}", on.log);
            let own: u64 = lines[0].split_whitespace().filter(|w| w.starts_with("own.")).filter_map(|w| w.split('=').nth(1)?.parse::<u64>().ok()).sum();
            assert_eq!(own, 0, "{label}: the layer made objects on the temporary device: {}", lines[0]);
            assert!(!lines[0].contains(" upscale"), "{label}: {}", lines[0]);
        }
        for (p, s, _) in quality_of(label, &on, &native) {
            assert!(p >= 30.0 && s >= 0.95, "{label}: PSNR {p:.2} dB, SSIM {s:.4}");
        }
    }
}

/// The feature off, with the layer loaded: the runtime gets exactly what it gets without the
/// layer, and the app is told the runtime's own sizes.
#[test]
fn off_is_byte_identical() {
    let base = Run::new("upscale-off-plain");
    let plain = base.clone().run();
    plain.assert_ok();
    let mut off = base.with_layer().env("STEREOSHIM_UPSCALE_ENABLED", "0");
    off.name = "upscale-off-layer".into();
    let off = off.run();
    off.assert_ok();
    assert!(off.log_lines("upscale: told").is_empty());
    common::assert_same_captures("upscale off", &plain, &off);
}

/// With mask, RDM and the far field on, the features work in the app's smaller images: the mask
/// and RDM apply to every eye pass, the far field reuses, and the runtime still gets display-size
/// images close to the native run with the same features.
#[test]
fn with_every_other_feature() {
    let base = common::every_feature(Run::new("upscale-features-native"), "upscale-features-native").env("MOCK_XR_EXIT_AFTER", "4");
    let native = base.run();
    native.assert_ok();
    let on = upscaled(base, "upscale-features", "easu_rcas").run();
    on.assert_ok();
    let line = on.log_lines("vulkan device stats").last().copied().unwrap_or_default().to_string();
    let count = |key: &str| -> u64 { line.split_whitespace().find_map(|w| w.strip_prefix(key)).and_then(|v| v.parse().ok()).unwrap_or(0) };
    assert!(count("masked_passes=") >= 6 && count("rdm_passes=") >= 6, "the features did not apply in the upscaled images: {line}");
    // Lower than the plain runs' 32 dB: RDM's periphery, reconstructed in the smaller image,
    // is magnified by the upscale (its checkerboard quads become 2.6 display pixels wide).
    for (p, s, _) in quality_of("features", &on, &native) {
        assert!(p >= 25.0 && s >= 0.9, "PSNR {p:.2} dB, SSIM {s:.4}");
    }
}

/// The app destroys its swapchains while its last frame's work still runs (Bevy at exit), with
/// validation on: the layer's app-facing images go only after that work, and the layers above it
/// see them retired (a wait on the layer's own upscales alone left validation reporting
/// `VUID-vkDestroyImage-image-01000`, and the driver freeing images still being drawn).
#[test]
fn swapchains_destroyed_with_work_in_flight() {
    // `--record-once`: xr-scene then leaves its frames in flight instead of waiting for each.
    for args in [&["--teardown", "in-flight", "--record-once"][..], &["--teardown", "in-flight", "--record-once", "--post", "tonemap"]] {
        let label = args.join(" ");
        // Validation through `VK_INSTANCE_LAYERS`, above the layer as developers enable it: it
        // sees the app's work and the layer's destruction of the app-facing images, not the
        // layer's own waits.
        let base = Run::new("upscale-in-flight-native").with_layer().args(args.iter().copied()).env("MOCK_XR_EXIT_AFTER", "3").env("VK_INSTANCE_LAYERS", "VK_LAYER_KHRONOS_validation");
        let native = base.run();
        native.assert_ok();
        let on = upscaled(base, "upscale-in-flight", "easu_rcas").run();
        on.assert_ok();
        assert!(!on.log_lines("the runtime shows").is_empty(), "{label}: no swapchain was interposed");
        assert!(on.log_lines("waiting for the session's queue").is_empty(), "{label}: {}", on.log);
    }
}

/// The runtime failing its own (display-size) swapchain: the app gets the runtime's error.
#[test]
fn the_runtimes_swapchain_failure_reaches_the_app() {
    let run = upscaled(Run::new("upscale-fail"), "upscale-fail", "easu_rcas").with_layer().env("MOCK_XR_FAIL", "xrCreateSwapchain=XR_ERROR_LIMIT_REACHED");
    let out = run.run();
    assert!(out.stderr.contains("LIMIT_REACHED"), "the app did not see the runtime's error: {}", out.stderr);
    assert!(!out.log_lines("the runtime refused its").is_empty());
}

/// `upscale.mip_bias`: the app's samplers get log2(scale) added (auto), nothing with `off`.
#[test]
fn samplers_get_the_mip_bias() {
    let base = Run::new("upscale-mip-bias").with_layer().args(["--post", "tonemap"]);
    let on = upscaled(base.clone(), "upscale-mip-bias-auto", "easu_rcas").env("STEREOSHIM_UPSCALE_SCALE", "0.5").run();
    on.assert_ok();
    let line = on.log_lines("LOD bias").first().copied().unwrap_or_else(|| panic!("no sampler got a bias: {}", on.log)).to_string();
    assert!(line.contains("0 -> -1"), "log2(0.5) is -1: {line}");
    let off = upscaled(base, "upscale-mip-bias-off", "easu_rcas").env("STEREOSHIM_UPSCALE_MIP_BIAS", "off").run();
    off.assert_ok();
    assert!(off.log_lines("LOD bias").is_empty());
}

/// A quad layer from a static swapchain (acquired and released once, submitted every frame): with
/// the upscale on, the static swapchain (a view's aspect) is interposed too, its one image
/// upscaled at the frame end after its release, and the quad's rect rewritten; the runtime's quad
/// shows the same pattern at the native run's size.
#[test]
fn quad_layers_and_static_swapchains() {
    let base = Run::new("upscale-quad-native").with_layer().args(["--quad"]).env("MOCK_XR_EXIT_AFTER", "3");
    let native = base.run();
    native.assert_ok();
    let on = upscaled(base, "upscale-quad", "easu_rcas").run();
    on.assert_ok();
    for frame in [1, 2] {
        let quad = |o: &RunOutput| {
            let f = o.frame(frame);
            assert_eq!(f.layers.iter().map(|l| l.kind.as_str()).collect::<Vec<_>>(), ["projection", "quad"], "{}", o.name);
            f.layers[1].quad.clone().expect("the quad's capture")
        };
        let (qa, qb) = (quad(&on), quad(&native));
        let (ia, ib) = (on.image(&qa.file), native.image(&qb.file));
        assert_eq!((ia.width, ia.height), (ib.width, ib.height), "frame {frame}: the quad is not at the native size");
        assert_eq!((qa.image_rect.width, qa.image_rect.height), (ib.width, ib.height));
        let p = quality::psnr(&as_filter_image(&ia), &as_filter_image(&ib));
        eprintln!("quad frame {frame}: {}x{} PSNR {p:.2} dB", ia.width, ia.height);
        assert!(p >= 25.0, "frame {frame}: the quad's pattern at {p:.2} dB");
    }
    assert_eq!(on.log_lines("the runtime shows").len(), 3, "both eyes' swapchains and the quad's interposed");
}

/// The in-headset overlay with the upscale: its quad is the layer's own swapchain (made below the
/// interposition), drawn at its own size after the app's upscaled projection layer.
#[test]
fn the_overlay_stays_at_its_own_size() {
    let run = upscaled(Run::new("upscale-overlay"), "upscale-overlay", "easu_rcas").with_layer().env("STEREOSHIM_OVERLAY_ENABLED", "1");
    let out = run.run();
    out.assert_ok();
    let f = out.frame(1);
    assert_eq!(f.layers.iter().map(|l| l.kind.as_str()).collect::<Vec<_>>(), ["projection", "quad"]);
    let (w, h) = stereoshim::features::overlay::rules::texture_size();
    let q = f.layers[1].quad.as_ref().expect("the overlay's quad");
    assert_eq!((q.image_rect.width, q.image_rect.height), (w, h));
    assert_eq!(out.log_lines("the runtime shows").len(), 2, "only the app's two eye swapchains are interposed");
    for v in &f.layers[0].views {
        assert_eq!((v.image_rect.width, v.image_rect.height), (256, 256), "the projection views at the display size");
    }
}

/// Multisampled swapchains (the app renders its eyes straight into 4-sample swapchain images:
/// resolved before the upscale; the runtime's swapchain is single-sampled) and swapchains with a
/// mip chain (the app renders level 0; the runtime's has one level), in each layout: interposed,
/// and the runtime's images as close to the native run's as a single-sampled app's.
#[test]
fn multisampled_and_mip_chain_swapchains() {
    let cases: [(&str, &[&str], &str); 5] = [
        ("msaa-per-eye", &["--swapchain-samples", "4", "--layout", "per-eye", "--rendering", "render-pass"], "(4 samples, 1 mip levels)"),
        ("msaa-multiview", &["--swapchain-samples", "4", "--layout", "multiview", "--rendering", "dynamic"], "(4 samples, 1 mip levels)"),
        ("msaa-side-by-side", &["--swapchain-samples", "4", "--layout", "side-by-side", "--rendering", "render-pass"], "(4 samples, 1 mip levels)"),
        ("mips-per-eye", &["--swapchain-mips", "3", "--layout", "per-eye", "--rendering", "dynamic"], "(1 samples, 3 mip levels)"),
        ("mips-multiview", &["--swapchain-mips", "3", "--layout", "multiview", "--rendering", "render-pass"], "(1 samples, 3 mip levels)"),
    ];
    for (label, args, interposed) in cases {
        let base = Run::new(&format!("upscale-native-{label}")).with_layer().args(args.iter().copied()).env("MOCK_XR_EXIT_AFTER", "4");
        let native = base.run();
        native.assert_ok();
        let on = upscaled(base, &format!("upscale-{label}"), "easu_rcas").run();
        on.assert_ok();
        let lines = on.log_lines("the runtime shows");
        assert!(lines.iter().any(|l| l.contains(interposed)), "{label}: no swapchain interposed {interposed}: {lines:?}");
        assert_eq!(on.frames().frames.len(), native.frames().frames.len(), "{label}: captured frames");
        for (p, s, _) in quality_of(label, &on, &native) {
            assert!(p >= 30.0 && s >= 0.95, "{label}: PSNR {p:.2} dB, SSIM {s:.4}");
        }
    }
}

/// `upscale.skip_hidden`: the upscale skips the tiles the runtime's hidden-area mesh covers. Every
/// pixel the lens shows is bit for bit what the upscale gives without skipping; the skipped ones
/// are black; the log says what share was skipped.
#[test]
fn the_pixels_the_lens_never_shows_are_skipped() {
    for layout in ["per-eye", "multiview", "side-by-side"] {
        let base = Run::new(&format!("upscale-skip-{layout}")).with_layer().args(["--layout", layout]).env("MOCK_XR_EXIT_AFTER", "4");
        let on = upscaled(base.clone(), &format!("upscale-skip-on-{layout}"), "easu_rcas").run();
        on.assert_ok();
        let off = upscaled(base, &format!("upscale-skip-off-{layout}"), "easu_rcas").env("STEREOSHIM_UPSCALE_SKIP_HIDDEN", "0").run();
        off.assert_ok();
        assert!(!on.log_lines("the lens never shows").is_empty(), "{layout}: nothing skipped");
        assert!(off.log_lines("the lens never shows").is_empty(), "{layout}: skipped while off");
        for (va, vb) in on.views(1).iter().zip(off.views(1)) {
            let (ia, ib) = (on.image(&va.file), off.image(&vb.file));
            let hidden = lens_hidden(&on, va);
            assert!(hidden.iter().any(|&h| h), "{layout}: the runtime has no hidden area here");
            let (mut black, mut differ_hidden) = (0, 0);
            for y in 0..ia.height {
                for x in 0..ia.width {
                    let (pa, pb) = (ia.pixel(x, y), ib.pixel(x, y));
                    if hidden[(y * ia.width + x) as usize] {
                        black += (pa[..3] == [0, 0, 0]) as u32;
                        differ_hidden += (pa[..3] != pb[..3]) as u32;
                    } else {
                        assert_eq!(&pa[..3], &pb[..3], "{layout} view {}: visible pixel ({x}, {y}) changed", va.view);
                    }
                }
            }
            eprintln!("{layout} view {}: {black} hidden pixels black, {differ_hidden} differ from the full upscale", va.view);
            assert!(black > 0 && differ_hidden > 0, "{layout} view {}: no hidden pixel was skipped", va.view);
        }
    }
}
