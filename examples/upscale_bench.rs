//! GPU time of the upscale's passes (EASU, then RCAS) at a headset's per-eye size, on the machine's
//! Vulkan device, for the device machine (no Rust there): the input is a synthetic scene at
//! `--scale` of the output; the passes run `--runs` times, each timed by the device's timestamps;
//! the medians are printed, per eye and for two eyes.
//!   target/release/examples/upscale_bench [--width 2016] [--height 2240] [--scale 0.77] [--runs 15] [--repeat 50]
//!     [--cas] [--easu-spv F --rcas-spv F --group N]   (a variant of the same interface, alternated with
//!                                               the layer's passes run by run and compared)

#[path = "../tests/upscale_gpu/mod.rs"]
mod upscale_gpu;

use clap::Parser;
use stereoshim::features::upscale::filter::{Image, Rgb};

#[derive(Parser)]
#[command(about, long_about = None)]
struct Args {
    #[arg(long, default_value_t = 2016)]
    width: u32,
    #[arg(long, default_value_t = 2240)]
    height: u32,
    #[arg(long, default_value_t = 0.77)]
    scale: f32,
    #[arg(long, default_value_t = 15)]
    runs: usize,
    /// Back-to-back runs of each pass per submission (their mean is a run's time).
    #[arg(long, default_value_t = 50)]
    repeat: u32,
    /// Variants to compare with the layer's passes: SPIR-V files of the same interface, and their
    /// workgroup's side.
    #[arg(long)]
    easu_spv: Option<std::path::PathBuf>,
    #[arg(long)]
    rcas_spv: Option<std::path::PathBuf>,
    /// The variants' workgroup side (default: the layer's).
    #[arg(long)]
    group: Option<u32>,
    /// The layer's first pass is CAS (`upscale.method = cas`) instead of EASU.
    #[arg(long)]
    cas: bool,
    /// The input's format: rgba8 (what apps render) or rgba32f.
    #[arg(long, default_value = "rgba8")]
    input: String,
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let a = Args::parse();
    let (w, h) = (((a.width as f32) * a.scale).round() as u32, ((a.height as f32) * a.scale).round() as u32);
    // Edges in every direction over a ramp: what the analysis branches on.
    let low = Image::from_fn(w, h, |x, y| {
        let (u, v) = (x as f32 / w as f32, y as f32 / h as f32);
        let ring = (((u - 0.5).powi(2) + (v - 0.5).powi(2)).sqrt() * 40.0) as i32 % 2 == 0;
        if ring {
            Rgb([0.8, 0.7, 0.2])
        } else {
            Rgb([u, v, 0.3])
        }
    });
    let gpu = upscale_gpu::Gpu::new();
    let read = |p: &Option<std::path::PathBuf>| p.as_ref().map(|p| std::fs::read(p).unwrap_or_else(|e| panic!("{}: {e}", p.display())));
    let (easu_v, rcas_v) = (read(&a.easu_spv), read(&a.rcas_spv));
    let product = upscale_gpu::Shaders::product();
    let input = if a.input == "rgba32f" { ash::vk::Format::R32G32B32A32_SFLOAT } else { ash::vk::Format::R8G8B8A8_UNORM };
    let easu = if a.cas { stereoshim::features::upscale::gpu::CAS } else { product.easu };
    let product = upscale_gpu::Shaders { input, easu, ..product };
    let variant = (easu_v.is_some() || rcas_v.is_some() || a.group.is_some()).then(|| upscale_gpu::Shaders {
        easu: easu_v.as_deref().unwrap_or(product.easu),
        rcas: rcas_v.as_deref().unwrap_or(product.rcas),
        group: a.group.unwrap_or(product.group),
        input,
        tiles: &[],
    });
    // The layer's passes and the variant alternate run by run in this process (A/B).
    let mut times: Vec<(Vec<f64>, Vec<f64>)> = vec![Default::default(); 1 + variant.is_some() as usize];
    for _ in 0..a.runs.max(1) {
        for (k, shaders) in std::iter::once(product).chain(variant).enumerate() {
            let run = gpu.upscale_with(shaders, &low, (a.width, a.height), 0.8, a.repeat);
            if !run.texels.iter().all(|t| t.iter().all(|c| c.is_finite())) {
                eprintln!("the upscale wrote non-finite values");
                std::process::exit(1);
            }
            let Some((e, r)) = run.times_ms else {
                eprintln!("the device's queue has no timestamps");
                std::process::exit(1);
            };
            times[k].0.push(e);
            times[k].1.push(r);
        }
    }
    for (k, (easu, rcas)) in times.into_iter().enumerate() {
        let (e, r) = (median(easu), median(rcas));
        let name = if k == 0 { "layer" } else { "variant" };
        println!("{name}: {} {w}x{h} -> {}x{} per eye, {} runs: EASU {e:.3} ms, RCAS {r:.3} ms, both {:.3} ms per eye, {:.3} ms for two eyes", a.input, a.width, a.height, a.runs, e + r, 2.0 * (e + r));
    }
}
