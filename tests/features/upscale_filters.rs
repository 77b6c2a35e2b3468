//! The upscale's GPU passes (`shaders/upscale_easu.comp`, `shaders/upscale_rcas.comp`) against
//! their CPU reference (`src/features/upscale/filter.rs`) on the machine's Vulkan device
//! (lavapipe in CI): a synthetic scene rendered at scale 0.77 is upscaled by EASU and sharpened
//! by RCAS on the device and on the CPU, and every texel agrees within the RGBA16F images'
//! rounding (RCAS amplifies its input's rounding by up to 4 × 3/16 / (1 − 4 × 3/16) = 3×).

use crate::upscale_gpu;

use stereoshim::features::upscale::filter::{self, Image, Rgb};
use stereoshim::features::upscale::gpu as passes;
use upscale_gpu::{Gpu, Shaders};

/// A native scene with hard straight, slanted and curved edges over a smooth ramp, and the same
/// rendered at `scale` (each texel the mean of 4×4 samples of its footprint).
fn low_res_scene(size: u32, scale: f32) -> Image {
    let s = size as f32;
    let native = Image::from_fn(size, size, |x, y| {
        let (u, v) = ((x as f32 + 0.5) / s, (y as f32 + 0.5) / s);
        if (u - 0.35).powi(2) + (v - 0.4).powi(2) < 0.05 {
            return Rgb([0.9, 0.25, 0.1]);
        }
        if ((u - 0.6) * 0.8 - (v - 0.5) * 0.6).abs() < 0.05 {
            return Rgb([0.1, 0.8, 0.3]);
        }
        Rgb([u * 0.7, v * 0.7, 0.35])
    });
    let w = (s * scale).round() as u32;
    Image::from_fn(w, w, |x, y| {
        let mut sum = Rgb::default();
        for sy in 0..4 {
            for sx in 0..4 {
                let nx = ((x as f32 + (sx as f32 + 0.5) / 4.0) / scale) as i64;
                let ny = ((y as f32 + (sy as f32 + 0.5) / 4.0) / scale) as i64;
                sum = sum + native.at(nx, ny);
            }
        }
        sum * (1.0 / 16.0)
    })
}

/// The largest per-channel difference between the device's result and the CPU reference's.
fn max_diff(gpu: &[[f32; 4]], cpu: &Image) -> f32 {
    gpu.iter().zip(&cpu.texels).flat_map(|(g, c)| (0..3).map(move |k| (g[k] - c.0[k]).abs())).fold(0.0, f32::max)
}

#[test]
fn the_gpu_passes_match_the_cpu_reference() {
    let gpu = Gpu::new();
    let low = low_res_scene(128, 0.77);
    // Scales on both sides of what the shaders' shared-memory block holds (99 → 200 and 251:
    // block; 99 → 60: a source larger than the destination in y, taps straight from the image),
    // and sizes that are not multiples of the workgroup.
    for (w, h) in [(128, 128), (150, 131), (99, 99), (200, 60), (251, 197)] {
        // EASU alone (RCAS at no sharpness copies): within the RGBA16F output's rounding.
        let easu = filter::easu(&low, w, h);
        let got = gpu.upscale_with(Shaders::product(), &low, (w, h), 0.0, 1).texels;
        let d = max_diff(&got, &easu);
        eprintln!("{}x{} → {w}x{h}: EASU max difference {d:.5}", low.width, low.height);
        assert!(d < 2.0e-3, "EASU on the device differs from the reference by {d}");
        // With RCAS at full sharpness: its input's rounding amplified (at most 3×).
        let full = filter::rcas(&easu, 1.0);
        let run = gpu.upscale_with(Shaders::product(), &low, (w, h), 1.0, 1);
        if let Some((e, r)) = run.times_ms {
            eprintln!("{}x{} → {w}x{h}: device time EASU {e:.3} ms, RCAS {r:.3} ms", low.width, low.height);
        }
        let got = run.texels;
        let d = max_diff(&got, &full);
        eprintln!("{}x{} → {w}x{h}: EASU + RCAS max difference {d:.5}", low.width, low.height);
        assert!(d < 8.0e-3, "EASU + RCAS on the device differ from the reference by {d}");
    }
}

/// CAS with scaling (`upscale.method = cas`; sharpness 0 here: the harness pushes EASU's
/// parameters with a zero third vector) against its reference, RCAS at no sharpness copying.
#[test]
fn cas_on_the_gpu_matches_the_cpu_reference() {
    let gpu = Gpu::new();
    let low = low_res_scene(128, 0.77);
    for (w, h) in [(128, 128), (150, 131), (99, 99), (200, 60), (251, 197)] {
        let cpu = filter::cas(&low, w, h, 0.0);
        let got = gpu.upscale_with(Shaders { easu: passes::CAS, ..Shaders::product() }, &low, (w, h), 0.0, 1).texels;
        let d = max_diff(&got, &cpu);
        eprintln!("{}x{} → {w}x{h}: CAS max difference {d:.5}", low.width, low.height);
        assert!(d < 2.0e-3, "CAS on the device differs from the reference by {d}");
    }
}

/// `upscale.skip_hidden` on the device: tiles classed as skipped by a pass come out black; every
/// pixel of a running tile that reads no skipped EASU tile is exactly what the full upscale gives.
#[test]
fn skipped_tiles_are_black_and_the_rest_unchanged() {
    use stereoshim::features::upscale::lens::{BOTH_SKIP, RCAS_SKIPS, RUN};
    let gpu = Gpu::new();
    let low = low_res_scene(128, 0.77);
    let (w, h) = (150u32, 131u32);
    let g = passes::GROUP;
    let (cols, rows) = (w.div_ceil(g), h.div_ceil(g));
    // The outer ring of tiles: both passes skip the corners, RCAS alone the rest of the ring.
    let classes: Vec<u32> = (0..rows)
        .flat_map(|ty| (0..cols).map(move |tx| (tx, ty)))
        .map(|(tx, ty)| {
            let (edge_x, edge_y) = (tx == 0 || tx == cols - 1, ty == 0 || ty == rows - 1);
            match (edge_x, edge_y) {
                (true, true) => BOTH_SKIP,
                (true, false) | (false, true) => RCAS_SKIPS,
                _ => RUN,
            }
        })
        .collect();
    let full = gpu.upscale_with(Shaders::product(), &low, (w, h), 1.0, 1).texels;
    let skipped = gpu.upscale_with(Shaders { tiles: &classes, ..Shaders::product() }, &low, (w, h), 1.0, 1).texels;
    let class = |x: u32, y: u32| classes[((y / g) * cols + x / g) as usize];
    let (mut black, mut same) = (0, 0);
    for y in 0..h {
        for x in 0..w {
            let (a, b) = (full[(y * w + x) as usize], skipped[(y * w + x) as usize]);
            match class(x, y) {
                RUN => {
                    // RCAS reads one pixel around: those must not be in a tile EASU skipped.
                    let near_skipped = [(-1i32, 0i32), (1, 0), (0, -1), (0, 1)].iter().any(|&(dx, dy)| {
                        let (nx, ny) = ((x as i32 + dx).clamp(0, w as i32 - 1) as u32, (y as i32 + dy).clamp(0, h as i32 - 1) as u32);
                        class(nx, ny) == BOTH_SKIP
                    });
                    if !near_skipped {
                        assert_eq!(a, b, "pixel ({x}, {y}) of a running tile changed");
                        same += 1;
                    }
                }
                _ => {
                    assert_eq!(&b[..3], &[0.0, 0.0, 0.0], "pixel ({x}, {y}) of a skipped tile is not black");
                    black += 1;
                }
            }
        }
    }
    eprintln!("{black} pixels skipped (black), {same} identical to the full upscale");
    assert!(black > 0 && same > 0);
}
