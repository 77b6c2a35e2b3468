//! Symmetric and parallel views (`view.symmetric`, `view.parallel`, src/features/views) on the
//! mock runtime and lavapipe, validation with synchronization on: xr-scene's `--assume-symmetric`
//! (the right eye drawn with the left eye's projection mirrored) on the Vive, whose measured eyes
//! differ in y, and `--assume-parallel` (both eyes drawn looking the same way) on the canted
//! Pimax render wrongly without the feature and, with it, match the reference (the app drawing the
//! runtime's own views) after reprojection into the runtime's view, over what the lens shows.

use crate::common;

use common::{Run, RunOutput, View};
use glam::{DQuat, DVec3};

/// The threshold the feature's images must reach against the reference after reprojection.
const MATCH_DB: f64 = 40.0;

/// Images are compared as a display shows them: at a quarter of the headset's recommended density
/// in each direction (blocks of `BLOCK × scale` pixels averaged). Both images are point-sampled renders whose grids
/// differ by a fraction of a pixel (symmetric views keep the runtime's density, not its pixel
/// grid; parallel views turn it), so at the rendered density resampling alone leaves the
/// aliased edges of the scene about 30 dB apart whatever the geometry; a runtime's own
/// reprojection filters them the same way.
const BLOCK: u32 = 4;


/// `hmd` at `scale` of its recommended size, the app at that size itself, `frames` frames.
fn run(name: &str, hmd: &str, frames: u32, scale: f64) -> Run {
    Run::new(name).with_layer().env("MOCK_XR_HMD", hmd).env("MOCK_XR_EXIT_AFTER", &frames.to_string()).env("MOCK_XR_RECOMMENDED_SCALE", &scale.to_string()).args(["--scale", "1"])
}

fn named(run: &Run, name: &str) -> Run {
    let mut r = run.clone();
    r.name = name.into();
    r
}

fn quat(v: &View) -> DQuat {
    let [x, y, z, w] = v.pose.orientation;
    DQuat::from_xyzw(x as f64, y as f64, z as f64, w as f64).normalize()
}

fn tangents(v: &View) -> [f64; 4] {
    [v.fov.angle_left, v.fov.angle_right, v.fov.angle_up, v.fov.angle_down].map(|a| (a as f64).tan())
}

/// View `a` of one run seen from view `b` of the reference run (the runtime's view): bilinear
/// samples of `a`'s image, placed by its submitted angles and orientation.
struct Reprojected {
    ia: common::image::Image,
    ib: common::image::Image,
    /// Which pixels of `b` the runtime's lens hides.
    hidden: Vec<bool>,
    a_tan: [f64; 4],
    b_tan: [f64; 4],
    to_a: DQuat,
}

impl Reprojected {
    fn new(on: &RunOutput, a: &View, reference: &RunOutput, b: &View) -> Reprojected {
        let (ia, ib) = (on.image(&a.file), reference.image(&b.file));
        let hidden = match reference.frame(1).visibility_masks.iter().find(|m| m.view == b.view) {
            Some(m) => common::hidden_pixels(&m.hidden_triangles, &b.fov, ib.width, ib.height),
            None => vec![false; (ib.width * ib.height) as usize],
        };
        Reprojected { ia, ib, hidden, a_tan: tangents(a), b_tan: tangents(b), to_a: quat(a).inverse() * quat(b) }
    }

    /// `a`'s colour (channel `c`) where `b`'s pixel centre (x, y), moved by (dx, dy) pixels, looks;
    /// black past `a`'s image.
    fn sample(&self, x: f64, y: f64, c: usize) -> f64 {
        let ([bl, br, bu, bd], [al, ar, au, ad]) = (self.b_tan, self.a_tan);
        let tx = bl + (x + 0.5) / self.ib.width as f64 * (br - bl);
        let ty = bu - (y + 0.5) / self.ib.height as f64 * (bu - bd);
        let d = self.to_a * DVec3::new(tx, ty, -1.0);
        let (sx, sy) = (d.x / -d.z, d.y / -d.z);
        let (px, py) = ((sx - al) / (ar - al) * self.ia.width as f64 - 0.5, (au - sy) / (au - ad) * self.ia.height as f64 - 0.5);
        let (x0, y0) = (px.floor(), py.floor());
        let (fx, fy) = (px - x0, py - y0);
        let at = |xi: f64, yi: f64| -> f64 {
            if xi < 0.0 || yi < 0.0 || xi >= self.ia.width as f64 || yi >= self.ia.height as f64 {
                0.0
            } else {
                self.ia.pixel(xi as u32, yi as u32)[c] as f64
            }
        };
        (at(x0, y0) * (1.0 - fx) + at(x0 + 1.0, y0) * fx) * (1.0 - fy) + (at(x0, y0 + 1.0) * (1.0 - fx) + at(x0 + 1.0, y0 + 1.0) * fx) * fy
    }

    fn max(&self) -> f64 {
        ((1u32 << self.ib.bit_depth) - 1) as f64
    }

    /// PSNR (dB) against `b`'s image over the blocks of `k` × `k` pixels the lens shows whole,
    /// each block's mean compared.
    fn psnr(&self, k: u32) -> f64 {
        let (w, h) = (self.ib.width / k, self.ib.height / k);
        let mut sums = vec![([0.0f64; 3], [0.0f64; 3], true); (w * h) as usize];
        for y in 0..h * k {
            for x in 0..w * k {
                let block = &mut sums[((y / k) * w + x / k) as usize];
                if self.hidden[(y * self.ib.width + x) as usize] {
                    block.2 = false;
                    continue;
                }
                for (c, &pb) in self.ib.pixel(x, y).iter().take(3).enumerate() {
                    block.0[c] += self.sample(x as f64, y as f64, c);
                    block.1[c] += pb as f64;
                }
            }
        }
        let (mut se, mut n) = (0.0, 0u64);
        for (a, b, _) in sums.iter().filter(|s| s.2) {
            se += (0..3).map(|c| ((a[c] - b[c]) / (self.max() * (k * k) as f64)).powi(2)).sum::<f64>();
            n += 1;
        }
        let mse = se / (3.0 * n.max(1) as f64);
        if mse == 0.0 { f64::INFINITY } else { -10.0 * mse.log10() }
    }
}

/// The layer's report of the widened views: `+X %` pixels, from its log line.
fn extra_pixels(run: &RunOutput) -> f64 {
    let lines = run.log_lines("view.symmetric = ");
    let line = lines.first().unwrap_or_else(|| panic!("no widened views reported: {:?}", run.log_lines("view.")));
    let p = line.split(" each, ").nth(1).and_then(|s| s.split(" % pixels").next()).expect("pixels");
    p.trim().parse().unwrap_or_else(|_| panic!("{line}"))
}

/// PSNR (dB) of two images on the same pixel grid (view `a` of `x`, view `b` of `y`), over the
/// pixels the runtime's lens shows in `y`'s view, and how many pixels differ at all.
fn same_grid(x: &RunOutput, a: &View, y: &RunOutput, b: &View) -> (f64, u64) {
    let (ia, ib) = (x.image(&a.file), y.image(&b.file));
    assert_eq!((ia.width, ia.height), (ib.width, ib.height), "not one grid");
    let r = Reprojected::new(y, b, y, b);
    let (mut se, mut n, mut differ) = (0.0, 0u64, 0u64);
    for yy in 0..ib.height {
        for xx in 0..ib.width {
            let (pa, pb) = (ia.pixel(xx, yy), ib.pixel(xx, yy));
            differ += (pa[..3] != pb[..3]) as u64;
            if !r.hidden[(yy * ib.width + xx) as usize] {
                se += (0..3).map(|c| ((pa[c] as f64 - pb[c] as f64) / r.max()).powi(2)).sum::<f64>();
                n += 1;
            }
        }
    }
    let mse = se / (3.0 * n.max(1) as f64);
    (if mse == 0.0 { f64::INFINITY } else { -10.0 * mse.log10() }, differ)
}

/// One `--assume-*` case in one layout × rendering, four runs: the reference (the app drawing the
/// views it is given, no feature), the assuming app without and with the feature, and the
/// reference app with the feature. Asserted here: with the feature the assuming app draws what an
/// app drawing its given views draws (its assumption holds), and that matches the reference after
/// reprojection into the runtime's view. Returns, per view, the PSNR of the assuming app without
/// the feature against the reference on the same pixel grid (what the assumption breaks).
/// `scale`: of the headset's recommended size.
fn assume_case(hmd: &str, scale: f64, assume: &str, key: &str, value: &str, layout: &str, rendering: &str) -> Vec<f64> {
    let label = format!("{hmd}{assume}-{layout}-{rendering}");
    let base = run("", hmd, 2, scale).args(["--layout", layout, "--rendering", rendering]);
    let block = (BLOCK as f64 * scale).round() as u32;
    let reference = named(&base, &format!("widened-ref-{label}")).run();
    reference.assert_ok();
    let wrong = named(&base, &format!("widened-wrong-{label}")).args([assume]).run();
    wrong.assert_ok();
    let fixed = named(&base, &format!("widened-fixed-{label}")).args([assume]).env(key, value).run();
    fixed.assert_ok();
    let given = named(&base, &format!("widened-given-{label}")).env(key, value).run();
    given.assert_ok();
    for r in [&fixed, &given] {
        assert!(r.log_lines("off for this session").is_empty(), "{label}: turned off: {:?}", r.log_lines("view tricks"));
    }
    let mut out = Vec::new();
    for (((w, f), g), r) in wrong.views(1).iter().zip(fixed.views(1)).zip(given.views(1)).zip(reference.views(1)) {
        let (broken, _) = same_grid(&wrong, w, &reference, r);
        let (_, differ) = same_grid(&fixed, f, &given, g);
        let matched = Reprojected::new(&fixed, f, &reference, r).psnr(block);
        eprintln!(
            "{label} view {}: {}x{} -> {}x{}; {assume} without the feature {broken:.1} dB against the reference; with {key}={value} {differ} pixels differ from the views drawn as given, {matched:.1} dB against the reference after reprojection",
            r.view, r.image_rect.width, r.image_rect.height, f.image_rect.width, f.image_rect.height
        );
        let pixels = f.image_rect.width as u64 * f.image_rect.height as u64;
        assert!(differ <= pixels / 10_000, "{label} view {}: {differ} pixels differ from the views drawn as given", r.view);
        assert!(matched >= MATCH_DB, "{label} view {}: {matched:.1} dB with the feature", r.view);
        out.push(broken);
    }
    eprintln!("{label}: {:+.1} % pixels", extra_pixels(&fixed));
    out
}

fn layouts() -> impl Iterator<Item = (&'static str, &'static str)> {
    ["per-eye", "multiview", "side-by-side"].into_iter().flat_map(|l| ["render-pass", "dynamic"].map(move |r| (l, r)))
}

/// `--assume-symmetric` on the Vive (its right eye's angles 0.003 tangent from the left's mirror
/// image, up to 1.5 pixels at the edges): without `view.symmetric` the right eye is not the
/// reference (the left is, bit for bit); with it both are, in every layout × rendering.
#[test]
fn an_app_assuming_symmetric_eyes_needs_symmetric_views() {
    for (layout, rendering) in layouts() {
        let p = assume_case("vive", 1.0, "--assume-symmetric", "STEREOSHIM_VIEW_SYMMETRIC", "horizontal", layout, rendering);
        assert!(p[0].is_infinite() && p[1] < MATCH_DB, "{layout}-{rendering}: without the feature {p:?} dB: the break does not show");
    }
}

/// `--assume-parallel` on the Pimax (views canted 10° outward each): both eyes are wrong without
/// `view.parallel`, right with it, in every layout × rendering.
#[test]
fn an_app_assuming_parallel_eyes_needs_parallel_views() {
    for (layout, rendering) in layouts() {
        let p = assume_case("pimax", 1.0, "--assume-parallel", "STEREOSHIM_VIEW_PARALLEL", "on", layout, rendering);
        assert!(p.iter().all(|&db| db < MATCH_DB - 10.0), "{layout}-{rendering}: without the feature {p:?} dB: the break does not show");
    }
}


/// With RDM on, the views are compared against RDM on the runtime's views: RDM shades a pattern
/// of the pixel grid and reconstructs the rest, so on two grids the periphery differs by about
/// what RDM itself changes (printed), a little below `MATCH_DB`.
const EVERY_FEATURE_DB: f64 = 35.0;

/// The shaded fragments of view `v` in frame 1 (`--pixel-stats`).
fn shaded(run: &RunOutput, v: u32) -> u64 {
    run.pixel_counts(1, v).iter().map(|&c| c as u64).sum()
}

/// The pixels of the widened view `w` (of run `on`) clearly outside the runtime's view `r` (more
/// than 1.5 pixels past its edge), and how many of them were shaded at all in frame 1.
fn padding_shaded(on: &RunOutput, w: &View, r: &View) -> (u64, u64) {
    let counts = on.pixel_counts(1, w.view);
    let ([wl, wr, wu, wd], [rl, rr, ru, rd]) = (tangents(w), tangents(r));
    let to_r = quat(r).inverse() * quat(w);
    let (ww, wh) = (w.image_rect.width, w.image_rect.height);
    let margin = 1.5 * ((wr - wl) / ww as f64).max((wu - wd) / wh as f64);
    let (mut padding, mut shaded) = (0, 0);
    for y in 0..wh {
        for x in 0..ww {
            let d = to_r * DVec3::new(wl + (x as f64 + 0.5) / ww as f64 * (wr - wl), wu - (y as f64 + 0.5) / wh as f64 * (wu - wd), -1.0);
            let (tx, ty) = (d.x / -d.z, d.y / -d.z);
            if d.z >= 0.0 || tx < rl - margin || tx > rr + margin || ty > ru + margin || ty < rd - margin {
                padding += 1;
                shaded += (counts[(y * ww + x) as usize] > 0) as u64;
            }
        }
    }
    (padding, shaded)
}

/// Each view trick with the mask, foveation (RDM) and the far field on, and with the upscale (the
/// widening first, then the scale): the assuming app's views match the same features' views of the
/// app drawing the runtime's own views after reprojection; no pixel of the padding outside the
/// runtime's views is shaded (the mask comes on with the tricks).
#[test]
fn with_every_feature_and_the_upscale() {
    // The last: the mode whose padding is checked (`full` symmetry pads the Vive's views by 5 %).
    let cases = [("vive", "--assume-symmetric", "STEREOSHIM_VIEW_SYMMETRIC", "horizontal", "full"), ("pimax", "--assume-parallel", "STEREOSHIM_VIEW_PARALLEL", "on", "on")];
    for (hmd, assume, key, value, padded) in cases {
        let base = run("", hmd, 3, 1.0);
        // Counted (`--pixel-stats`: 4 bytes a pixel, 72 MB a Pimax view a frame) over two frames.
        let counted = run("", hmd, 2, 1.0).pixel_stats();
        let reference = common::every_feature(base.clone(), &format!("widened-all-ref-{hmd}")).run();
        reference.assert_ok();
        let widened = common::every_feature(base.clone(), &format!("widened-all-{hmd}")).args([assume]).env(key, value).run();
        widened.assert_ok();
        let plain = named(&base, &format!("widened-plain-{hmd}")).run();
        plain.assert_ok();
        let plain_masked = named(&counted, &format!("widened-plain-masked-{hmd}")).env("STEREOSHIM_MASK_ENABLED", "1").run();
        plain_masked.assert_ok();
        let masked = named(&counted, &format!("widened-masked-{hmd}")).env(key, padded).run();
        masked.assert_ok();
        let upscaled = named(&base, &format!("widened-upscaled-{hmd}")).args([assume]).env(key, value).env("STEREOSHIM_UPSCALE_ENABLED", "1").run();
        upscaled.assert_ok();
        for r in [&widened, &masked, &upscaled] {
            assert!(r.log_lines("off for this session").is_empty(), "{hmd}: turned off: {:?}", r.log_lines("view tricks"));
        }
        assert!(!upscaled.log_lines("the runtime shows").is_empty(), "{hmd}: nothing upscaled");
        let (w, r, u, m, pm) = (widened.views(2), reference.views(2), upscaled.views(2), masked.views(1), plain_masked.views(1));
        for i in 0..2 {
            let all = Reprojected::new(&widened, w[i], &reference, r[i]).psnr(BLOCK);
            // What RDM's reconstruction itself changes, on one grid: the two runs' grids differ,
            // so their reconstructions differ by about as much.
            let own = Reprojected::new(&reference, r[i], &plain, plain.views(2)[i]).psnr(BLOCK);
            let up = Reprojected::new(&upscaled, u[i], &plain, plain.views(2)[i]).psnr(BLOCK);
            // The widened views' fragments against the runtime's views' with the mask (it comes
            // on with the trick).
            let (fm, fp) = (shaded(&masked, i as u32), shaded(&plain_masked, i as u32));
            let area = |v: &View| v.image_rect.width as f64 * v.image_rect.height as f64;
            eprintln!(
                "{hmd} view {i}: every feature {all:.1} dB against the same features on the runtime's views (RDM's own change {own:.1} dB); with the upscale {up:.1} dB; fragments {fp} -> {fm} ({:+.1} %) for {:+.1} % pixels",
                100.0 * (fm as f64 / fp as f64 - 1.0),
                100.0 * (area(m[i]) / area(pm[i]) - 1.0)
            );
            assert!(all >= EVERY_FEATURE_DB, "{hmd} view {i}: every feature {all:.1} dB");
            assert!(up >= 28.0, "{hmd} view {i}: with the upscale {up:.1} dB");
            let (padding, shaded_padding) = padding_shaded(&masked, m[i], pm[i]);
            eprintln!("{hmd} view {i}: {padding} pixels of padding outside the runtime's view, {shaded_padding} of them shaded");
            assert!(padding > 0 && shaded_padding == 0, "{hmd} view {i}: {shaded_padding} of {padding} padding pixels shaded");
        }
        // Passed: the counts go (they are most of what the suite writes); the images stay.
        for run in [&masked, &plain_masked] {
            let _ = std::fs::remove_dir_all(run.capture.parent().expect("run dir").join("pixel-stats"));
        }
    }
}

/// Twice the signed area of a polygon.
fn area2(p: &[[f64; 2]]) -> f64 {
    (0..p.len()).map(|i| p[i][0] * p[(i + 1) % p.len()][1] - p[(i + 1) % p.len()][0] * p[i][1]).sum()
}

/// An app that draws the runtime's hidden-area mesh itself (`--visibility-mask`) gets it as its
/// widened views see it: the runtime's hidden triangles turned into the parallel view, and the
/// padding outside the runtime's view added. Its hidden area (tangent plane, printed by
/// xr-scene) is what the geometry says: the app's view less the runtime's view's quadrilateral
/// in it, plus the runtime's hidden triangles there.
#[test]
fn an_app_drawing_the_visibility_mask_gets_it_in_its_views() {
    for (hmd, key, value) in [("pimax", "STEREOSHIM_VIEW_PARALLEL", "on"), ("vive", "STEREOSHIM_VIEW_SYMMETRIC", "full")] {
        let base = run("", hmd, 2, 0.25).args(["--visibility-mask"]);
        let reference = named(&base, &format!("widened-vismask-ref-{hmd}")).run();
        reference.assert_ok();
        let on = named(&base, &format!("widened-vismask-{hmd}")).env(key, value).run();
        on.assert_ok();
        for (a, r) in on.views(1).iter().zip(reference.views(1)) {
            let line = on.stderr.lines().find(|l| l.contains(&format!("visibility mask view {}:", a.view))).unwrap_or_else(|| panic!("{hmd}: no mask line:\n{}", on.stderr)).to_string();
            let got: f64 = line.rsplit(' ').next().and_then(|x| x.parse().ok()).unwrap_or_else(|| panic!("{line}"));
            // The runtime's view and hidden mesh, in the app's view's tangent plane.
            let to_app = quat(a).inverse() * quat(r);
            let map = |p: [f64; 2]| {
                let d = to_app * DVec3::new(p[0], p[1], -1.0);
                [d.x / -d.z, d.y / -d.z]
            };
            let ([al, ar, au, ad], [rl, rr, ru, rd]) = (tangents(a), tangents(r));
            let quad: Vec<[f64; 2]> = [[rl, rd], [rr, rd], [rr, ru], [rl, ru]].into_iter().map(map).collect();
            let hidden = &reference.frame(1).visibility_masks.iter().find(|m| m.view == r.view).expect("runtime mask").hidden_triangles;
            let hidden_area: f64 = hidden.chunks_exact(3).map(|t| area2(&t.iter().map(|p| map([p[0] as f64, p[1] as f64])).collect::<Vec<_>>()).abs() / 2.0).sum();
            let want = (ar - al) * (au - ad) - area2(&quad).abs() / 2.0 + hidden_area;
            let runtime_area: f64 = hidden.chunks_exact(3).map(|t| area2(&t.iter().map(|p| [p[0] as f64, p[1] as f64]).collect::<Vec<_>>()).abs() / 2.0).sum();
            eprintln!("{hmd} view {}: the app's hidden area {got:.4} (the runtime's own mesh {runtime_area:.4}), the geometry says {want:.4}", a.view);
            assert!((got - want).abs() <= 1e-3 * want, "{hmd} view {}: hidden area {got} against {want}", a.view);
            assert!(got > runtime_area * 1.01, "{hmd} view {}: no padding added", a.view);
        }
    }
}
