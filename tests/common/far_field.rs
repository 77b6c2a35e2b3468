//! The monoscopic far field judged from captures, shared by tests/features/far_field.rs and the GPU proof
//! (examples/far_field_check.rs): a destination view of a run through the layer against the same
//! frame of a run without it, with the set of pixels to reuse computed here, independently of the
//! layer, from the reference run's submitted depth and the captured poses and FOVs.

use super::image::Image;
use super::{RunOutput, View};
use glam::{DQuat, DVec3};

/// How a run is judged.
#[derive(Clone, Debug)]
pub struct Analysis {
    pub name: String,
    pub split_m: f64,
    pub depth_shift: bool,
    /// Tinted runs (`far_field.debug`): reused pixels are counted, not compared.
    pub debug: bool,
    /// Fragments per pixel the app shades before the injection point (a sky drawn first without
    /// depth test): the far field cannot save those.
    pub shaded_before: u32,
}

/// What one comparison found in the destination view.
#[derive(Debug, Default)]
pub struct Outcome {
    /// Destination pixels the test expects the layer to reuse (independent computation).
    pub expected: usize,
    /// Destination pixels the reuse draw writes (before the app's near geometry covers some).
    pub written: usize,
    /// Of those, pixels the reference filled with far geometry (not the clear colour).
    pub expected_geometry: usize,
    /// Pixels the layer reused, as the debug tint shows them (debug runs only).
    pub tinted: Option<usize>,
    /// Pixels of the expected set's outline (a pixel with a neighbour on the other side).
    pub outline: usize,
    pub near_pixels: usize,
    pub far_pixels: usize,
    pub psnr_far: f64,
    /// Shaded fragments of the destination: reference minus layered.
    pub fragments_saved: i64,
}

/// Distance along the view axis of each pixel of a captured depth image.
pub fn distances(img: &Image, v: &View) -> Vec<f64> {
    let d = v.depth.as_ref().expect("submitted depth");
    let (n, f) = (d.near_z as f64, d.far_z as f64);
    let inv_f = if f.is_infinite() { 0.0 } else { 1.0 / f };
    (0..img.height)
        .flat_map(|y| (0..img.width).map(move |x| (x, y)))
        .map(|(x, y)| {
            let depth = img.pixel(x, y)[0] as f64 / 65535.0;
            let t = (depth - d.min_depth as f64) / (d.max_depth - d.min_depth) as f64;
            let inv_z = 1.0 / n + t * (inv_f - 1.0 / n);
            if inv_z <= 0.0 {
                f64::INFINITY
            } else {
                1.0 / inv_z
            }
        })
        .collect()
}

pub fn tangents(v: &View) -> (f64, f64, f64, f64) {
    let f = v.fov;
    (f.angle_left.tan() as f64, f.angle_right.tan() as f64, f.angle_up.tan() as f64, f.angle_down.tan() as f64)
}

pub fn orientation(v: &View) -> DQuat {
    let [x, y, z, w] = v.pose.orientation.map(f64::from);
    DQuat::from_xyzw(x, y, z, w).normalize()
}

pub fn position(v: &View) -> DVec3 {
    let [x, y, z] = v.pose.position.map(f64::from);
    DVec3::new(x, y, z)
}

/// The source pixel (continuous, rect-local) that destination pixel centre (x, y) sees at
/// infinity, or at distance `z` along the destination's axis.
pub fn source_pixel(dst: &View, src: &View, x: f64, y: f64, z: Option<f64>) -> Option<(f64, f64)> {
    let (l, r, u, d) = tangents(dst);
    let (w, h) = (dst.image_rect.width as f64, dst.image_rect.height as f64);
    let dir = DVec3::new(l + x / w * (r - l), u - y / h * (u - d), -1.0);
    let in_src = match z {
        None => orientation(src).inverse() * (orientation(dst) * dir),
        Some(z) => orientation(src).inverse() * (orientation(dst) * (dir * z) + position(dst) - position(src)),
    };
    if in_src.z >= 0.0 {
        return None;
    }
    let (tx, ty) = (in_src.x / -in_src.z, in_src.y / -in_src.z);
    let (l, r, u, d) = tangents(src);
    let (w, h) = (src.image_rect.width as f64, src.image_rect.height as f64);
    Some(((tx - l) / (r - l) * w, (u - ty) / (u - d) * h))
}

pub fn psnr(a: &Image, b: &Image, pixels: &[(u32, u32)]) -> f64 {
    if pixels.is_empty() {
        return f64::INFINITY;
    }
    let max = if a.bit_depth == 16 { 65535.0 } else { 255.0 };
    let mut se = 0.0;
    for &(x, y) in pixels {
        for c in 0..3 {
            let e = a.pixel(x, y)[c] as f64 - b.pixel(x, y)[c] as f64;
            se += e * e;
        }
    }
    let mse = se / (pixels.len() * 3) as f64;
    if mse == 0.0 {
        f64::INFINITY
    } else {
        10.0 * (max * max / mse).log10()
    }
}

pub fn is_black(img: &Image, x: u32, y: u32) -> bool {
    img.pixel(x, y)[..3].iter().all(|c| *c == 0)
}

/// Compares destination view `dst_view` of frame `f` of the layered run with the reference,
/// reading the source from view `src_view` of frame `src_frame` of the reference (the source's
/// pixels are the app's own, so the reference has them).
pub fn analyse(case: &Analysis, plain: &RunOutput, far: &RunOutput, f: u64, dst_view: u32, src_view: u32, src_frame: u64) -> Outcome {
    let views = plain.views(f);
    let dst = *views.iter().find(|v| v.view == dst_view).expect("destination view");
    let src = *plain.views(src_frame).iter().find(|v| v.view == src_view).expect("source view");
    let fviews = far.views(f);
    let far_dst = *fviews.iter().find(|v| v.view == dst.view).expect("layered destination view");
    let label = &format!("{}-frame{f}", case.name);
    // The eye that is not the destination renders everything itself: bit-identical.
    if !case.debug {
        for (a, b) in fviews.iter().zip(&views).filter(|(a, _)| a.view != dst_view) {
            super::image::assert_identical(&format!("{label}-source"), &far.image(&a.file), &plain.image(&b.file));
        }
    }
    let (ref_img, got) = (plain.image(&dst.file), far.image(&far_dst.file));
    let ref_z = distances(&plain.image(&dst.depth.as_ref().unwrap().file), dst);
    let src_z = distances(&plain.image(&src.depth.as_ref().unwrap().file), src);
    let (w, h) = (ref_img.width, ref_img.height);
    let (sw, sh) = (src.image_rect.width as i64, src.image_rect.height as i64);
    let far_at = |tx: i64, ty: i64| tx >= 0 && ty >= 0 && tx < sw && ty < sh && src_z[(ty * sw + tx) as usize] > case.split_m;
    let mut reused = vec![false; (w * h) as usize];
    let ref_counts = plain.pixel_counts(f, dst.view);
    let mut out = Outcome::default();
    let (mut near, mut far_px) = (Vec::new(), Vec::new());
    for y in 0..h {
        for x in 0..w {
            let i = (y * w + x) as usize;
            let (cx, cy) = (x as f64 + 0.5, y as f64 + 0.5);
            let mut uv = source_pixel(dst, src, cx, cy, None);
            if case.depth_shift {
                uv = uv.and_then(|(u, v)| {
                    let (tx, ty) = (u.floor() as i64, v.floor() as i64);
                    far_at(tx, ty).then(|| src_z[(ty * sw + tx) as usize]).and_then(|z| source_pixel(dst, src, cx, cy, Some(z.min(1.0e9))))
                });
            }
            if let Some((u, v)) = uv {
                let (tx, ty) = ((u - 0.5).floor() as i64, (v - 0.5).floor() as i64);
                reused[i] = far_at(tx, ty) && far_at(tx + 1, ty) && far_at(tx, ty + 1) && far_at(tx + 1, ty + 1);
            }
            out.written += reused[i] as usize;
            // The reference's own near geometry wins over any reuse.
            if ref_z[i] < case.split_m {
                reused[i] = false;
                near.push((x, y));
            } else {
                far_px.push((x, y));
            }
            if reused[i] {
                out.expected += 1;
                if !is_black(&ref_img, x, y) && ref_counts[i] > case.shaded_before {
                    out.expected_geometry += 1;
                }
            }
            assert!(!is_black(&got, x, y) || is_black(&ref_img, x, y), "{label}: ({x},{y}) of view {} is left at the clear colour", dst.view);
        }
    }
    for y in 0..h {
        for x in 0..w {
            let i = (y * w + x) as usize;
            let neighbours = [(x.wrapping_sub(1), y), (x + 1, y), (x, y.wrapping_sub(1)), (x, y + 1)];
            if neighbours.iter().any(|&(nx, ny)| nx < w && ny < h && reused[(ny * w + nx) as usize] != reused[i]) {
                out.outline += 1;
            }
        }
    }
    out.near_pixels = near.len();
    out.far_pixels = far_px.len();
    if case.debug {
        let tinted = (0..h).flat_map(|y| (0..w).map(move |x| (x, y))).filter(|&(x, y)| got.pixel(x, y) != ref_img.pixel(x, y)).count();
        out.tinted = Some(tinted);
    } else {
        let differing: Vec<_> = near.iter().filter(|&&(x, y)| got.pixel(x, y) != ref_img.pixel(x, y)).collect();
        assert!(differing.is_empty(), "{label}: {} of {} near pixels of view {} differ, e.g. {:?}", differing.len(), near.len(), dst.view, &differing[..differing.len().min(5)]);
        out.psnr_far = psnr(&got, &ref_img, &far_px);
    }
    let sum = |r: &RunOutput| r.pixel_counts(f, dst.view).iter().map(|c| *c as i64).sum::<i64>();
    out.fragments_saved = sum(plain) - sum(far);
    out
}


/// The split distance for a pixel budget, from two captured views: the baseline between their
/// positions over `split_px` times the finer eye's pixel angle at the image centre (the layer's
/// rule, restated here from the captured poses).
pub fn split_from_px(a: &View, b: &View, split_px: f64) -> f64 {
    let baseline = (position(a) - position(b)).length();
    let pixel = |v: &View| {
        let (l, r, u, d) = tangents(v);
        ((r - l) / v.image_rect.width as f64).min((u - d) / v.image_rect.height as f64)
    };
    baseline / (split_px * pixel(a).min(pixel(b)))
}
