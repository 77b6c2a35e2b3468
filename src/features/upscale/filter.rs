//! The upscale's filters on the CPU, written from the published description of AMD's FidelityFX
//! Super Resolution 1 (EASU: edge-adaptive spatial upsampling; RCAS: robust contrast-adaptive
//! sharpening) and plain bilinear: the reference the GPU shaders are held to, and what the quality
//! measures (`quality`) are computed with. Pure: images are linear RGB `f32` triples in [0, 1].
//!
//! EASU, per output pixel: the source position `p = (x + ½) · in/out − ½` is split into its
//! texel `F = ⌊p⌋` and fraction `f`. Twelve source texels around it (the 4×4 block without its
//! corners) are read; from their luma (`½r + g + ½b`), the four "+" shapes centred on the 2×2
//! texels nearest `p` give, weighted bilinearly by `f`, an edge direction (the luma gradient) and
//! an edge strength (how much steeper the gradient is than each one-sided step). Each tap is then
//! weighted by a Lanczos-2-like polynomial window, evaluated on its offset from `p` rotated into
//! the edge's frame and scaled along and across it (stretched along a strong edge, narrowed
//! across it), and the weighted mean is clamped to the range of the 2×2 nearest texels, which
//! removes the kernel's ringing.
//!
//! RCAS, per pixel of the upscaled image: a "+" of the pixel and its four neighbours; the
//! sharpening lobe (a negative weight on the neighbours) is the largest that keeps every channel
//! of the result inside [0, 1] given the neighbours' minimum and maximum, capped at −3/16 and
//! scaled by `sharpness` (1: full, 0: none).

use std::ops::{Add, Mul, Sub};

/// A linear RGB colour.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Rgb(pub [f32; 3]);

impl Add for Rgb {
    type Output = Rgb;
    fn add(self, o: Rgb) -> Rgb {
        Rgb([self.0[0] + o.0[0], self.0[1] + o.0[1], self.0[2] + o.0[2]])
    }
}

impl Sub for Rgb {
    type Output = Rgb;
    fn sub(self, o: Rgb) -> Rgb {
        Rgb([self.0[0] - o.0[0], self.0[1] - o.0[1], self.0[2] - o.0[2]])
    }
}

impl Mul<f32> for Rgb {
    type Output = Rgb;
    fn mul(self, k: f32) -> Rgb {
        Rgb([self.0[0] * k, self.0[1] * k, self.0[2] * k])
    }
}

impl Rgb {
    fn map2(self, o: Rgb, f: impl Fn(f32, f32) -> f32) -> Rgb {
        Rgb([f(self.0[0], o.0[0]), f(self.0[1], o.0[1]), f(self.0[2], o.0[2])])
    }
    /// The luma EASU analyses edges with (green counted twice, as in the published algorithm).
    fn luma(self) -> f32 {
        0.5 * self.0[0] + self.0[1] + 0.5 * self.0[2]
    }
}

/// An image of linear RGB texels, row by row.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    pub width: u32,
    pub height: u32,
    pub texels: Vec<Rgb>,
}

impl Image {
    /// A `width`×`height` image of `f(x, y)`.
    pub fn from_fn(width: u32, height: u32, f: impl Fn(u32, u32) -> Rgb) -> Image {
        let texels = (0..height).flat_map(|y| (0..width).map(move |x| (x, y))).map(|(x, y)| f(x, y)).collect();
        Image { width, height, texels }
    }
    /// The texel at (x, y), clamped to the edge (as a sampler with CLAMP_TO_EDGE reads).
    pub fn at(&self, x: i64, y: i64) -> Rgb {
        let x = x.clamp(0, self.width as i64 - 1) as usize;
        let y = y.clamp(0, self.height as i64 - 1) as usize;
        self.texels[y * self.width as usize + x]
    }
}

/// The source position of output pixel `o` when `in_len` texels are stretched over `out_len`.
fn source_pos(o: u32, in_len: u32, out_len: u32) -> f32 {
    (o as f32 + 0.5) * in_len as f32 / out_len as f32 - 0.5
}

/// Bilinear upscale of `src` to `width`×`height` (the cheap reference).
pub fn bilinear(src: &Image, width: u32, height: u32) -> Image {
    Image::from_fn(width, height, |x, y| {
        let (px, py) = (source_pos(x, src.width, width), source_pos(y, src.height, height));
        let (fx, fy) = (px.floor(), py.floor());
        let (tx, ty) = (px - fx, py - fy);
        let (ix, iy) = (fx as i64, fy as i64);
        let top = src.at(ix, iy) * (1.0 - tx) + src.at(ix + 1, iy) * tx;
        let bottom = src.at(ix, iy + 1) * (1.0 - tx) + src.at(ix + 1, iy + 1) * tx;
        top * (1.0 - ty) + bottom * ty
    })
}

/// One "+" shape of EASU's analysis: centre `c` with left `l`, right `r`, up `u`, down `d` (luma),
/// weighted `w`: adds its gradient to `dir` and its edge strength to `len`.
fn plus(dir: &mut [f32; 2], len: &mut f32, w: f32, (l, c, r, u, d): (f32, f32, f32, f32, f32)) {
    let axis = |a: f32, b: f32| {
        // The gradient across the shape relative to its larger one-sided step: 1 where the luma
        // rises through the centre (an edge, a ramp), 0 at a one-texel peak or pit (noise).
        let steep = (c - a).abs().max((b - c).abs());
        let grad = b - a;
        let strength = if steep > 0.0 { (grad.abs() / steep).clamp(0.0, 1.0) } else { 0.0 };
        (grad, strength * strength)
    };
    let (gx, sx) = axis(l, r);
    let (gy, sy) = axis(u, d);
    dir[0] += gx * w;
    dir[1] += gy * w;
    *len += (sx + sy) * w;
}

/// EASU upscale of `src` to `width`×`height`.
pub fn easu(src: &Image, width: u32, height: u32) -> Image {
    Image::from_fn(width, height, |x, y| {
        let (px, py) = (source_pos(x, src.width, width), source_pos(y, src.height, height));
        let (fx, fy) = (px.floor(), py.floor());
        let (tx, ty) = (px - fx, py - fy);
        let (ix, iy) = (fx as i64, fy as i64);
        let t = |dx: i64, dy: i64| src.at(ix + dx, iy + dy);
        let lum = |dx: i64, dy: i64| t(dx, dy).luma();
        // The four "+" shapes centred on the 2×2 nearest texels, bilinearly weighted.
        let mut dir = [0.0f32; 2];
        let mut len = 0.0f32;
        for (cx, cy, w) in [(0, 0, (1.0 - tx) * (1.0 - ty)), (1, 0, tx * (1.0 - ty)), (0, 1, (1.0 - tx) * ty), (1, 1, tx * ty)] {
            plus(&mut dir, &mut len, w, (lum(cx - 1, cy), lum(cx, cy), lum(cx + 1, cy), lum(cx, cy - 1), lum(cx, cy + 1)));
        }
        // Direction normalized (none: along x); strength in [0, 1], squared to favour strong
        // edges.
        let d2 = dir[0] * dir[0] + dir[1] * dir[1];
        let (dx, dy) = if d2 < 1.0 / 32768.0 { (1.0, 0.0) } else { (dir[0] / d2.sqrt(), dir[1] / d2.sqrt()) };
        let len = (len * 0.5).powi(2);
        // Along a diagonal edge the kernel's square footprint reaches √2 further.
        let stretch = (dx * dx + dy * dy) / dx.abs().max(dy.abs());
        let (scale_x, scale_y) = (1.0 + (stretch - 1.0) * len, 1.0 - 0.5 * len);
        // The window's second lobe: 1/2 on no edge (smooth), towards 0.21 on a strong one.
        let lobe = 0.5 + ((1.0 / 4.0 - 0.04) - 0.5) * len;
        let clip = 1.0 / lobe;
        let mut sum = Rgb::default();
        let mut wsum = 0.0f32;
        const TAPS: [(i64, i64); 12] = [(0, -1), (1, -1), (-1, 0), (0, 0), (1, 0), (2, 0), (-1, 1), (0, 1), (1, 1), (2, 1), (0, 2), (1, 2)];
        for (ox, oy) in TAPS {
            let (vx, vy) = (ox as f32 - tx, oy as f32 - ty);
            // Into the edge's frame: along it (x) and across it (y), scaled.
            let (rx, ry) = ((vx * dx + vy * dy) * scale_x, (vx * -dy + vy * dx) * scale_y);
            let d = (rx * rx + ry * ry).min(clip);
            // Lanczos 2 approximated by polynomials: (25/16 (2/5 d − 1)² − 9/16) · (lobe d − 1)².
            let base = 25.0 / 16.0 * (2.0 / 5.0 * d - 1.0).powi(2) - (25.0 / 16.0 - 1.0);
            let window = (lobe * d - 1.0).powi(2);
            let w = base * window;
            sum = sum + t(ox, oy) * w;
            wsum += w;
        }
        let mean = if wsum.abs() > 1e-12 { sum * (1.0 / wsum) } else { t(0, 0) };
        // No ringing: within the range of the 2×2 nearest texels.
        let near = [t(0, 0), t(1, 0), t(0, 1), t(1, 1)];
        let lo = near.iter().fold(near[0], |a, b| a.map2(*b, f32::min));
        let hi = near.iter().fold(near[0], |a, b| a.map2(*b, f32::max));
        mean.map2(lo, f32::max).map2(hi, f32::min)
    })
}

/// CAS (contrast-adaptive sharpening) with scaling, `upscale.method = cas`, written from its
/// published description: each of the four source texels nearest the output's position is
/// sharpened by the CAS rule over its cross — per channel, the amplitude √(min(lo, 1 − hi) / hi)
/// from the cross's range (soft where the neighbourhood is near black or white, so nothing
/// clips), a neighbour weight of amplitude × −1/(8 − 3 × sharpness) — and the four are blended
/// bilinearly. One pass; its sharpening is milder than RCAS's and it has no edge-directed
/// interpolation.
pub fn cas(src: &Image, width: u32, height: u32, sharpness: f32) -> Image {
    let peak = -1.0 / (8.0 - 3.0 * sharpness.clamp(0.0, 1.0));
    Image::from_fn(width, height, |x, y| {
        let (px, py) = (source_pos(x, src.width, width), source_pos(y, src.height, height));
        let (fx, fy) = (px.floor(), py.floor());
        let (tx, ty) = (px - fx, py - fy);
        let (ix, iy) = (fx as i64, fy as i64);
        let sharp = |cx: i64, cy: i64| {
            let e = src.at(cx, cy);
            let n = [src.at(cx, cy - 1), src.at(cx - 1, cy), src.at(cx + 1, cy), src.at(cx, cy + 1)];
            let mut out = [0.0f32; 3];
            for (c, o) in out.iter_mut().enumerate() {
                let lo = n.iter().fold(e.0[c], |a, v| a.min(v.0[c]));
                let hi = n.iter().fold(e.0[c], |a, v| a.max(v.0[c]));
                let amp = if hi > 0.0 { (lo.min(1.0 - hi) / hi).clamp(0.0, 1.0).sqrt() } else { 0.0 };
                let w = amp * peak;
                let sum: f32 = n.iter().map(|v| v.0[c]).sum();
                *o = ((sum * w + e.0[c]) / (1.0 + 4.0 * w)).clamp(0.0, 1.0);
            }
            Rgb(out)
        };
        let top = sharp(ix, iy) * (1.0 - tx) + sharp(ix + 1, iy) * tx;
        let bottom = sharp(ix, iy + 1) * (1.0 - tx) + sharp(ix + 1, iy + 1) * tx;
        top * (1.0 - ty) + bottom * ty
    })
}

/// The largest sharpening lobe RCAS uses (a neighbour weight of −3/16).
const RCAS_LIMIT: f32 = 0.25 - 1.0 / 16.0;

/// RCAS sharpening of `img` with `sharpness` in [0, 1] (0: unchanged).
pub fn rcas(img: &Image, sharpness: f32) -> Image {
    let sharpness = sharpness.clamp(0.0, 1.0);
    Image::from_fn(img.width, img.height, |x, y| {
        let (x, y) = (x as i64, y as i64);
        let e = img.at(x, y);
        let n = [img.at(x, y - 1), img.at(x - 1, y), img.at(x + 1, y), img.at(x, y + 1)];
        let mn = n.iter().fold(n[0], |a, b| a.map2(*b, f32::min));
        let mx = n.iter().fold(n[0], |a, b| a.map2(*b, f32::max));
        // Per channel, the most negative lobe that keeps the result ≥ 0 (from the minimum) and
        // ≤ 1 (from the maximum); the weakest channel decides.
        let mut lobe = f32::NEG_INFINITY;
        for c in 0..3 {
            let low = if mx.0[c] > 0.0 { -(mn.0[c].min(e.0[c])) / (4.0 * mx.0[c]) } else { 0.0 };
            let high = if mn.0[c] < 1.0 { (1.0 - mx.0[c].max(e.0[c])) / (4.0 * mn.0[c] - 4.0) } else { 0.0 };
            lobe = lobe.max(low.max(high));
        }
        let lobe = lobe.clamp(-RCAS_LIMIT, 0.0) * sharpness;
        let sum = n[0] + n[1] + n[2] + n[3];
        (sum * lobe + e) * (1.0 / (4.0 * lobe + 1.0))
    })
}

/// Quality measures of an upscaled image against the native one.
pub mod quality {
    use super::Image;

    /// PSNR in dB over the colour channels (values in [0, 1]); infinite when identical.
    pub fn psnr(a: &Image, b: &Image) -> f64 {
        let (mut se, mut n) = (0.0f64, 0u64);
        for (p, q) in a.texels.iter().zip(&b.texels) {
            for c in 0..3 {
                se += (p.0[c] as f64 - q.0[c] as f64).powi(2);
                n += 1;
            }
        }
        if se == 0.0 {
            f64::INFINITY
        } else {
            10.0 * (1.0 / (se / n as f64)).log10()
        }
    }

    /// Mean SSIM of the luma (Wang et al. 2004: 8×8 windows stepped by 4, C1 = (0.01)², C2 =
    /// (0.03)² for values in [0, 1]); 1 when identical. Images of different sizes are compared
    /// over their common top-left part.
    pub fn ssim(a: &Image, b: &Image) -> f64 {
        const WIN: i64 = 8;
        const STEP: usize = 4;
        let (c1, c2) = (0.01f64 * 0.01, 0.03f64 * 0.03);
        let (w, h) = (a.width.min(b.width) as i64, a.height.min(b.height) as i64);
        if w < WIN || h < WIN {
            return if psnr(a, b).is_infinite() { 1.0 } else { 0.0 };
        }
        let (mut sum, mut n) = (0.0f64, 0u64);
        for y0 in (0..=h - WIN).step_by(STEP) {
            for x0 in (0..=w - WIN).step_by(STEP) {
                let (mut ma, mut mb, mut va, mut vb, mut cov) = (0.0f64, 0.0f64, 0.0f64, 0.0f64, 0.0f64);
                let count = (WIN * WIN) as f64;
                for y in y0..y0 + WIN {
                    for x in x0..x0 + WIN {
                        let (p, q) = (a.at(x, y).luma() as f64 * 0.5, b.at(x, y).luma() as f64 * 0.5);
                        ma += p;
                        mb += q;
                        va += p * p;
                        vb += q * q;
                        cov += p * q;
                    }
                }
                ma /= count;
                mb /= count;
                va = va / count - ma * ma;
                vb = vb / count - mb * mb;
                cov = cov / count - ma * mb;
                sum += ((2.0 * ma * mb + c1) * (2.0 * cov + c2)) / ((ma * ma + mb * mb + c1) * (va + vb + c2));
                n += 1;
            }
        }
        sum / n as f64
    }

    /// The edge-sharpness measure the upscaling is judged by: the image's gradient energy (the
    /// mean squared luma difference to the right and below neighbours) at the pixels where the
    /// native image has an edge (its own gradient above `threshold`), as a fraction of the native
    /// image's there. 1: edges as crisp as native; a blurring upscale gives less.
    pub fn edge_energy(img: &Image, native: &Image, threshold: f32) -> f64 {
        edge_energy_where(img, native, threshold, &|_, _| true)
    }

    /// `edge_energy` over the pixels `counted` (x, y) says: the others (a lens's hidden area, whose
    /// outline is an edge in both images) are left out.
    pub fn edge_energy_where(img: &Image, native: &Image, threshold: f32, counted: &dyn Fn(i64, i64) -> bool) -> f64 {
        let grad = |im: &Image, x: i64, y: i64| {
            let c = im.at(x, y).luma();
            let dx = im.at(x + 1, y).luma() - c;
            let dy = im.at(x, y + 1).luma() - c;
            (dx * dx + dy * dy) as f64
        };
        let (mut got, mut want) = (0.0f64, 0.0f64);
        for y in 0..native.height as i64 {
            for x in 0..native.width as i64 {
                let g = grad(native, x, y);
                if g > (threshold * threshold) as f64 && counted(x, y) {
                    want += g;
                    got += grad(img, x, y);
                }
            }
        }
        if want == 0.0 {
            1.0
        } else {
            got / want
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A native image with what upscaling must keep: straight and slanted hard edges, a circle,
    /// thin lines and a smooth ramp.
    fn scene(size: u32) -> Image {
        let s = size as f32;
        Image::from_fn(size, size, |x, y| {
            let (u, v) = ((x as f32 + 0.5) / s, (y as f32 + 0.5) / s);
            let ramp = Rgb([u * 0.6, v * 0.6, 0.3]);
            let mut c = ramp;
            if (u - 0.3).powi(2) + (v - 0.3).powi(2) < 0.04 {
                c = Rgb([0.9, 0.2, 0.1]);
            }
            // A slanted bar.
            let d = (u - 0.55) * 0.8 - (v - 0.6) * 0.6;
            if d.abs() < 0.04 {
                c = Rgb([0.1, 0.8, 0.2]);
            }
            // Thin lines every 8 native pixels in a corner.
            if u > 0.7 && v > 0.7 && x % 8 == 0 {
                c = Rgb([1.0, 1.0, 1.0]);
            }
            c
        })
    }

    /// The native image rendered at `scale`: each low-resolution texel the mean of a 4×4 grid of
    /// native-resolution samples over its footprint (what an antialiased render at that size
    /// shows).
    fn render_at(native: &Image, scale: f32) -> Image {
        let (w, h) = (((native.width as f32) * scale).round() as u32, ((native.height as f32) * scale).round() as u32);
        Image::from_fn(w, h, |x, y| {
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

    #[test]
    fn identity_scale_stays_close_and_flat_stays_flat() {
        let img = scene(64);
        // 1:1, the window is 1 at the texel and 0 at its neighbours only where there is no edge;
        // across an edge it is shaped along it, and the 2×2 clamp bounds the change.
        let up = easu(&img, 64, 64);
        let db = quality::psnr(&up, &img);
        assert!(db > 38.0, "1:1 EASU: {db:.1} dB");
        let smooth = Image::from_fn(64, 64, |x, y| Rgb([x as f32 / 80.0, y as f32 / 80.0, 0.5]));
        assert!(quality::psnr(&easu(&smooth, 64, 64), &smooth) > 60.0, "1:1 EASU on a ramp is the ramp");
        let flat = Image::from_fn(20, 20, |_, _| Rgb([0.25, 0.5, 0.75]));
        for out in [easu(&flat, 31, 27), bilinear(&flat, 31, 27), rcas(&easu(&flat, 31, 27), 1.0)] {
            assert!(out.texels.iter().all(|t| t.0.iter().zip([0.25, 0.5, 0.75]).all(|(a, b)| (a - b).abs() < 1e-5)));
        }
        // RCAS with no sharpness changes nothing.
        assert_eq!(rcas(&img, 0.0), img);
    }

    #[test]
    fn outputs_stay_in_range_and_never_ring_past_the_nearest_texels() {
        let img = scene(48);
        let up = easu(&img, 97, 61);
        let sharp = rcas(&up, 1.0);
        for t in up.texels.iter().chain(&sharp.texels) {
            assert!(t.0.iter().all(|c| (-1e-5..=1.0 + 1e-5).contains(c)), "{t:?}");
        }
        // A hard black/white step: EASU stays within [0, 1] (the 2×2 clamp), and so does RCAS.
        let step = Image::from_fn(16, 16, |x, _| if x < 8 { Rgb([0.0; 3]) } else { Rgb([1.0; 3]) });
        let up = rcas(&easu(&step, 37, 37), 1.0);
        assert!(up.texels.iter().all(|t| t.0.iter().all(|c| (-1e-5..=1.0 + 1e-5).contains(c))));
    }

    #[test]
    fn at_the_default_scale_easu_rcas_is_close_to_native_and_sharper_than_bilinear() {
        let native = scene(256);
        let low = render_at(&native, 0.77);
        assert_eq!((low.width, low.height), (197, 197));
        let bil = bilinear(&low, 256, 256);
        let fsr = rcas(&easu(&low, 256, 256), 0.8);
        let (p_bil, p_fsr) = (quality::psnr(&bil, &native), quality::psnr(&fsr, &native));
        let (e_bil, e_fsr) = (quality::edge_energy(&bil, &native, 0.1), quality::edge_energy(&fsr, &native, 0.1));
        eprintln!("scale 0.77: bilinear {p_bil:.2} dB, edge energy {e_bil:.3}; EASU+RCAS {p_fsr:.2} dB, edge energy {e_fsr:.3}");
        assert!(p_fsr >= 25.0, "EASU+RCAS {p_fsr:.2} dB");
        assert!(e_fsr > e_bil * 1.05, "EASU+RCAS edges ({e_fsr:.3}) not sharper than bilinear's ({e_bil:.3})");
        // CAS: sharper than bilinear too, and close to native; flat stays flat.
        let c = cas(&low, native.width, native.height, 0.5);
        let (p_cas, e_cas) = (quality::psnr(&c, &native), quality::edge_energy(&c, &native, 0.1));
        eprintln!("scale 0.77: CAS {p_cas:.2} dB, edge energy {e_cas:.3}");
        assert!(e_cas > e_bil && p_cas > 25.0, "CAS: {p_cas:.2} dB, edge energy {e_cas:.3} (bilinear {e_bil:.3})");
        let flat = Image::from_fn(20, 20, |_, _| Rgb([0.3, 0.5, 0.7]));
        assert!(cas(&flat, 31, 31, 1.0).texels.iter().all(|t| (t.0[0] - 0.3).abs() < 1e-6 && (t.0[2] - 0.7).abs() < 1e-6));
        assert!(quality::ssim(&native, &native) > 0.9999);
    }
}
