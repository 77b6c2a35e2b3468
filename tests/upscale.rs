//! Upscaling (`upscale.*`, src/xr/upscale.rs) on the mock runtime and lavapipe: the app is told
//! the scaled size and renders at it into the layer's images; the runtime receives display-size
//! images whose pixels come close to a native-resolution run's (PSNR, SSIM), with EASU + RCAS
//! sharper at edges than a bilinear upscale; the feature off changes nothing.

mod common;

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

fn upscaled(run: Run, name: &str, method: &str) -> Run {
    let mut run = run.env("STEREOSHIM_UPSCALE_ENABLED", "1").env("STEREOSHIM_UPSCALE_METHOD", method);
    run.name = name.into();
    run
}

/// Per captured view of frame 1: (PSNR, SSIM, edge energy) of `on` against `native`.
fn quality_of(label: &str, on: &RunOutput, native: &RunOutput) -> Vec<(f64, f64, f64)> {
    let (a, b) = (on.views(1), native.views(1));
    assert_eq!(a.len(), b.len(), "{label}: views");
    a.iter()
        .zip(&b)
        .map(|(va, vb)| {
            let (ia, ib) = (on.image(&va.file), native.image(&vb.file));
            assert_eq!((ia.width, ia.height), (ib.width, ib.height), "{label}: view {} is not at the display size", va.view);
            let (fa, fb) = (as_filter_image(&ia), as_filter_image(&ib));
            let q = (quality::psnr(&fa, &fb), quality::ssim(&fa, &fb), quality::edge_energy(&fa, &fb, 0.1));
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
    for ((p, s, e), (_, _, e_bil)) in fsr.iter().zip(&lin) {
        assert!(*p >= 30.0, "PSNR {p:.2} dB under 30");
        assert!(*s >= 0.95, "SSIM {s:.4} under 0.95");
        assert!(e > e_bil, "EASU+RCAS edges ({e:.3}) not sharper than bilinear's ({e_bil:.3})");
    }
}
