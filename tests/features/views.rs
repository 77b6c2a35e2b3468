//! The FOV cut (`view.fov_cut = lens`, src/features/views) on the mock runtime and lavapipe,
//! validation with synchronization on: the app is told the cut size, renders the cut angles, and
//! each captured view is the crop of the uncut run's, bit for bit; its shaded fragments drop by
//! the cut's share.

use crate::common;

use common::Run;

/// (x0, y0, width, height) of view `v`'s cut, from the layer's log line
/// `view.fov_cut: view V: WxH -> wxh (pixels x0..x1 x y0..y1)`.
fn cut_of(log: &[&str], v: u32) -> (u32, u32, u32, u32) {
    let line = log.iter().find(|l| l.contains(&format!("view.fov_cut: view {v}:"))).unwrap_or_else(|| panic!("no cut of view {v}: {log:?}"));
    let pixels = line.split("(pixels ").nth(1).and_then(|s| s.split(')').next()).expect("pixels");
    let nums: Vec<u32> = pixels.split(|c: char| !c.is_ascii_digit()).filter(|s| !s.is_empty()).map(|s| s.parse().unwrap()).collect();
    let [x0, x1, y0, y1] = nums[..] else { panic!("{line}") };
    (x0, y0, x1 - x0, y1 - y0)
}

/// The Index profile at a quarter of its recommended size, the app at that size itself (the crop
/// is on its pixel grid), `frames` frames.
fn index_run(name: &str, frames: u32) -> Run {
    Run::new(name).with_layer().env("MOCK_XR_HMD", "index").env("MOCK_XR_EXIT_AFTER", &frames.to_string()).env("MOCK_XR_RECOMMENDED_SCALE", "0.25").args(["--scale", "1"])
}

fn cut(run: &Run, name: &str) -> Run {
    let mut r = run.clone().env("STEREOSHIM_VIEW_FOV_CUT", "lens");
    r.name = name.into();
    r
}

/// PSNR (dB) of view `a`'s capture in `on` against the crop of view `b`'s in `off` at (x0, y0),
/// over the pixels the lens shows (the runtime's hidden-area mesh at `a`'s angles left out).
fn crop_psnr(on: &common::RunOutput, a: &common::View, off: &common::RunOutput, b: &common::View, (x0, y0): (u32, u32)) -> f64 {
    let (ia, ib) = (on.image(&a.file), off.image(&b.file));
    let max = ((1u32 << ia.bit_depth) - 1) as f64;
    let hidden = match on.frame(1).visibility_masks.iter().find(|m| m.view == a.view) {
        Some(m) => common::hidden_pixels(&m.hidden_triangles, &a.fov, ia.width, ia.height),
        None => vec![false; (ia.width * ia.height) as usize],
    };
    let mut se = 0.0;
    for y in 0..ia.height {
        for x in 0..ia.width {
            if hidden[(y * ia.width + x) as usize] {
                continue;
            }
            let (pa, pb) = (ia.pixel(x, y), ib.pixel(x0 + x, y0 + y));
            se += (0..3).map(|c| ((pa[c] as f64 - pb[c] as f64) / max).powi(2)).sum::<f64>();
        }
    }
    let mse = se / (3.0 * ia.width as f64 * ia.height as f64);
    if mse == 0.0 { f64::INFINITY } else { -10.0 * mse.log10() }
}

/// Every layout × rendering on the Index profile (the mock serves SteamVR's published Index mask):
/// the cut views are the crops of the uncut ones, bit for bit, and shade that many fewer
/// fragments.
#[test]
fn the_cut_image_is_the_crop_of_the_uncut_one() {
    let cases = ["per-eye", "multiview", "side-by-side"].into_iter().flat_map(|l| ["render-pass", "dynamic"].map(move |r| (l, r)));
    for (layout, rendering) in cases {
        let label = format!("{layout}-{rendering}");
        let base = index_run(&format!("views-uncut-{label}"), 3).pixel_stats().args(["--layout", layout, "--rendering", rendering]);
        let uncut = base.run();
        uncut.assert_ok();
        let cut = cut(&base, &format!("views-cut-{label}")).run();
        cut.assert_ok();
        let log = cut.log_lines("view.fov_cut: view");
        assert!(cut.log_lines("the cut is off").is_empty(), "{label}: the cut was turned off: {:?}", cut.log_lines("view.fov_cut"));
        for (a, b) in cut.views(1).iter().zip(uncut.views(1)) {
            let (x0, y0, w, h) = cut_of(&log, a.view);
            assert_eq!((a.image_rect.width, a.image_rect.height), (w, h), "{label} view {}: not the cut size", a.view);
            let (ia, ib) = (cut.image(&a.file), uncut.image(&b.file));
            let mut differ = 0;
            for y in 0..h {
                for x in 0..w {
                    let (pa, pb) = (ia.pixel(x, y), ib.pixel(x0 + x, y0 + y));
                    if pa != pb && differ < 10 {
                        eprintln!("{label} view {}: ({x}, {y}) cut {pa:?} uncut {pb:?}", a.view);
                    }
                    differ += (pa != pb) as u32;
                }
            }
            // Not bit for bit: the app's projection of the cut angles rounds differently from the
            // uncut one's (last bits of clip coordinates), which moves a rare interpolated value
            // by 1 and a rare edge pixel's coverage (docs/views.md).
            let limit = (w * h) / 10_000 + 1;
            eprintln!("{label} view {}: {differ} of {} pixels differ from the crop at ({x0}, {y0})", a.view, w * h);
            assert!(differ <= limit, "{label} view {}: {differ} pixels differ from the crop at ({x0}, {y0})", a.view);
            let shaded = |run: &common::RunOutput| run.pixel_counts(1, a.view).iter().map(|&c| c as u64).sum::<u64>();
            let (on, off) = (shaded(&cut), shaded(&uncut));
            let share = 1.0 - (w as f64 * h as f64) / (b.image_rect.width as f64 * b.image_rect.height as f64);
            eprintln!("{label} view {}: {}x{} -> {w}x{h} ({:.1} % of the pixels cut), fragments {off} -> {on}", a.view, b.image_rect.width, b.image_rect.height, 100.0 * share);
            assert!(on < off && share > 0.0, "{label} view {}: nothing saved", a.view);
        }
    }
}

/// Each HMD profile (per-eye): the share of the pixels the cut leaves out, and the crop.
#[test]
fn the_cut_per_headset() {
    for hmd in ["index", "vive", "quest3", "pimax"] {
        let base = index_run(&format!("views-uncut-{hmd}"), 2).env("MOCK_XR_HMD", hmd);
        let uncut = base.run();
        uncut.assert_ok();
        let on = cut(&base, &format!("views-cut-{hmd}")).run();
        on.assert_ok();
        let log = on.log_lines("view.fov_cut: view");
        for (a, b) in on.views(1).iter().zip(uncut.views(1)) {
            let (x0, y0, w, h) = cut_of(&log, a.view);
            let share = 1.0 - (w as f64 * h as f64) / (b.image_rect.width as f64 * b.image_rect.height as f64);
            let p = crop_psnr(&on, a, &uncut, b, (x0, y0));
            eprintln!("{hmd} view {}: {}x{} -> {w}x{h}, {:.1} % of the pixels cut; PSNR against the crop {p:.1} dB", a.view, b.image_rect.width, b.image_rect.height, 100.0 * share);
            // The profiles without published mask data approximate the lens by an ellipse wider
            // than the FOV (its edges' middles visible): nothing to cut there.
            assert!(p >= 50.0 && (hmd != "index" || share > 0.0), "{hmd} view {}: share {share}, PSNR {p}", a.view);
        }
    }
}

/// An app that renders other angles than it was given (`--widen-fov`), or at another size than it
/// was told (`--scale 0.5`): the cut is turned off for the session, logged, and the app is then
/// given the runtime's own angles.
#[test]
fn apps_that_do_not_follow_the_cut_get_it_turned_off() {
    let reference = index_run("views-runtime-angles", 3).run();
    reference.assert_ok();
    let cases: [(&str, &[&str], &str); 2] = [("widened", &["--widen-fov", "2"], "with angles"), ("scaled", &["--scale", "0.5"], "renders view 0 at")];
    for (label, args, why) in cases {
        let run = cut(&index_run("", 3).args(args.iter().copied()), &format!("views-off-{label}")).run();
        run.assert_ok();
        assert!(!run.log_lines(why).is_empty() && !run.log_lines("the cut is off for this session").is_empty(), "{label}: the cut stayed on");
        // The last frame's views carry the runtime's angles again (widened by the app's 2°).
        let widen = if label == "widened" { 2f32.to_radians() } else { 0.0 };
        let (got, want) = (run.views(2), reference.views(2));
        for (a, b) in got.iter().zip(&want) {
            assert!((a.fov.angle_left - (b.fov.angle_left - widen)).abs() < 1e-5 && (a.fov.angle_right - (b.fov.angle_right + widen)).abs() < 1e-5, "{label} view {}: {:?} against {:?}", a.view, a.fov, b.fov);
        }
    }
}

/// With the mask, foveation (RDM) and the far field on: they follow the cut angles, so the cut
/// views are still the crops of the uncut ones over what the lens shows (RDM's reconstruction
/// and the far field's reuse included, up to rounding: the cut starts on a multiple of 16 pixels,
/// where RDM's pattern repeats).
#[test]
fn with_mask_foveation_and_far_field() {
    let base = common::every_feature(index_run("views-features-uncut", 3), "views-features-uncut");
    let uncut = base.run();
    uncut.assert_ok();
    let on = cut(&base, "views-features-cut").run();
    on.assert_ok();
    assert!(on.log_lines("the cut is off").is_empty(), "the cut was turned off");
    let log = on.log_lines("view.fov_cut: view");
    for (a, b) in on.views(2).iter().zip(uncut.views(2)) {
        let (x0, y0, _, _) = cut_of(&log, a.view);
        let p = crop_psnr(&on, a, &uncut, b, (x0, y0));
        eprintln!("every feature, view {}: PSNR against the crop {p:.1} dB", a.view);
        assert!(p >= 50.0, "view {}: PSNR {p:.1} dB against the crop", a.view);
    }
}

/// With the upscale on: the cut first, then the scale. The app is told 0.77 of the cut size, the
/// runtime gets the cut size, close to the cut run's images.
#[test]
fn with_the_upscale() {
    let base = index_run("views-upscale-cut", 3);
    let cut_only = cut(&base, "views-upscale-cut").run();
    cut_only.assert_ok();
    let both = cut(&base, "views-upscale-both").env("STEREOSHIM_UPSCALE_ENABLED", "1").run();
    both.assert_ok();
    assert!(both.log_lines("the cut is off").is_empty(), "the cut was turned off");
    assert!(!both.log_lines("the runtime shows").is_empty(), "nothing upscaled");
    for (a, b) in both.views(2).iter().zip(cut_only.views(2)) {
        assert_eq!((a.image_rect.width, a.image_rect.height), (b.image_rect.width, b.image_rect.height), "view {}: not the cut size", a.view);
        let p = crop_psnr(&both, a, &cut_only, b, (0, 0));
        eprintln!("cut + upscale, view {}: PSNR against the cut run {p:.1} dB", a.view);
        assert!(p >= 28.0, "view {}: PSNR {p:.1}", a.view);
    }
}
