//! GPU proof of the monoscopic far field, for any machine with a Vulkan GPU and no Rust: xr-scene
//! (the index profile, scale 1.0, submitting its depth) runs once without the layer and once per
//! far-field setting, for every layout asked for; one frame of the destination view is compared
//! with the reference (tests/common/far_field.rs): the source view bit-identical, every pixel
//! nearer than the split bit-identical, the far pixels' PSNR, the pixels reused (computed from the
//! reference's depth and poses), the shaded fragments without / with. Exits non-zero when a
//! comparison fails or a run fails (validation errors included).
//!
//!   target/release/examples/far_field_check [--layouts per-eye,multiview,side-by-side]
//!     [--settings infinity:1,infinity:4,depth:1,depth:4] [--hmd index] [--scale 1.0]
//!     [--frame 3] [--app-args "--shading-cost 64"] [--no-validation]

#[path = "../tests/common/mod.rs"]
mod common;

use common::far_field::{analyse, split_from_px, Analysis};
use common::Run;

/// GPU proof of the monoscopic far field: xr-scene without and with the layer, frames compared.
#[derive(clap::Parser)]
#[command(about, long_about = None)]
struct Args {
    /// Layouts to run, comma separated.
    #[arg(long, value_delimiter = ',', default_value = "per-eye")]
    layouts: Vec<String>,
    /// Far-field settings `shift:split_px`, comma separated (shift: infinity or depth).
    #[arg(long, value_delimiter = ',', default_value = "infinity:1,infinity:4,depth:1,depth:4")]
    settings: Vec<String>,
    /// HMD profile of the mock runtime (MOCK_XR_HMD).
    #[arg(long, default_value = "index")]
    hmd: String,
    /// xr-scene `--scale`.
    #[arg(long, default_value = "1.0")]
    scale: String,
    /// The frame compared (at least 1: multiview and side-by-side reuse the frame before).
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u64).range(1..))]
    frame: u64,
    /// Extra xr-scene arguments, space separated (`--app-args "--shading-cost 64"`).
    #[arg(long, default_value = "", allow_hyphen_values = true)]
    app_args: String,
    /// Run without the Khronos validation layer.
    #[arg(long)]
    no_validation: bool,
}

fn main() {
    let a = <Args as clap::Parser>::parse();
    let (layouts, settings, hmd, scale, frame, validation) = (a.layouts, a.settings, a.hmd, a.scale, a.frame, !a.no_validation);
    let app_args: Vec<String> = a.app_args.split_whitespace().map(String::from).collect();
    println!("| layout | shift | split px | split m | reused px | of the view | near px (all identical) | far px | far PSNR dB | shaded off | shaded on | saved | layer: views reused / pixels counted |");
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    for layout in &layouts {
        let base = |name: &str| {
            let mut r = Run::new(name)
                .args(["--layout", layout.as_str(), "--scale", scale.as_str(), "--submit-depth"])
                .args(app_args.iter().cloned())
                .pixel_stats()
                .env("MOCK_XR_HMD", &hmd)
                .env("MOCK_XR_EXIT_AFTER", &(frame + 1).to_string())
                .env("MOCK_XR_CAPTURE_FRAMES", &format!("{}-{frame}", frame - 1));
            r.validation = validation;
            r
        };
        let plain = base(&format!("ffc-{layout}-plain")).run();
        plain.assert_ok();
        let previous = layout != "per-eye";
        let src_frame = if previous { frame - 1 } else { frame };
        for s in &settings {
            let (shift, px) = s.split_once(':').unwrap_or_else(|| panic!("--settings shift:px, not {s}"));
            let px: f64 = px.parse().expect("split_px");
            let name = format!("ffc-{layout}-{shift}-{px}");
            let far = base(&name)
                .with_layer()
                .env("STEREOSHIM_FAR_FIELD_ENABLED", "1")
                .env("STEREOSHIM_FAR_FIELD_SHIFT", shift)
                .env("STEREOSHIM_FAR_FIELD_SPLIT_PX", &px.to_string())
                .env("STEREOSHIM_STATS_FILE", "/dev/null")
                .run();
            far.assert_ok();
            let views = plain.views(frame);
            let split_m = split_from_px(views[0], views[1], px);
            let a = Analysis { name: name.clone(), split_m, depth_shift: shift == "depth", debug: false, shaded_before: 0 };
            let o = analyse(&a, &plain, &far, frame, 1, 0, src_frame);
            let w = views[1].image_rect.width as f64 * views[1].image_rect.height as f64;
            let sum = |r: &common::RunOutput| r.pixel_counts(frame, 1).iter().map(|c| *c as u64).sum::<u64>();
            let (off, on) = (sum(&plain), sum(&far));
            let line = far.log_lines("far_field_views_reused=").last().map(|l| l.split("far_field_views_reused=").nth(1).unwrap_or("").split(" far_field_copies").next().unwrap_or("").to_string()).unwrap_or_default();
            println!(
                "| {layout} | {shift} | {px} | {split_m:.1} | {} | {:.1} % | {} | {} | {:.1} | {off} | {on} | {:.1} % | {line} |",
                o.expected,
                100.0 * o.expected as f64 / w,
                o.near_pixels,
                o.far_pixels,
                o.psnr_far,
                100.0 * (1.0 - on as f64 / off as f64)
            );
        }
    }
    println!("far_field_check: OK");
}
