//! Radial density masking judged from captures, shared by tests/features/foveation.rs (frame 1 of apps
//! that record every frame) and tests/features/record_once.rs (many frames of an app that records once):
//! one frame of a run through the layer against the same frame of a run without RDM.

use super::image::{self, Image};
use super::{Fov, RunOutput};
use stereoshim::core::rect::PixelRect;
use stereoshim::features::foveation::rdm::rules::RdmParams;
use stereoshim::core::views::{FoveaView, ViewFov};

/// With the hidden-area mask: how far from its outline the periphery PSNR starts (the filter reads
/// up to 2 px beyond a skipped quad).
pub const MASK_MARGIN_PX: f64 = 3.0;

/// (inner, middle) ring angles of a preset, degrees (src/foveation.rs `Rings::preset`, restated).
pub fn preset(name: &str) -> (f32, f32) {
    match name {
        "subtle" => (30.0, 45.0),
        "aggressive" => (12.0, 25.0),
        _ => (20.0, 35.0),
    }
}

/// The layer's tangents: f32 `tan` of the submitted f32 angles (src/xr/session.rs fov_tangents).
pub fn view_fov(f: &Fov) -> ViewFov {
    ViewFov { tan_left: f.angle_left.tan(), tan_right: f.angle_right.tan(), tan_up: f.angle_up.tan(), tan_down: f.angle_down.tan() }
}

/// The mock runtime's gaze (yaw right, pitch up, degrees) as a tangent-plane point of views
/// parallel to the head's forward axis: (tan yaw, tan pitch / cos yaw).
pub fn gaze_center(yaw_deg: f64, pitch_deg: f64) -> [f32; 2] {
    let (yaw, pitch) = (yaw_deg.to_radians(), pitch_deg.to_radians());
    [yaw.tan() as f32, (pitch.tan() / yaw.cos()) as f32]
}

/// Angle (degrees) between the fovea centre direction (a tangent-plane point; (0, 0) is the optical
/// axis) and the view direction through image point (px, py) of a `w` × `h` rect (pixels, y down),
/// in f64 — independent of the layer's f32 rule.
pub fn angle_deg(f: &Fov, w: u32, h: u32, px: f64, py: f64, center: [f32; 2]) -> f64 {
    let (l, r) = ((f.angle_left as f64).tan(), (f.angle_right as f64).tan());
    let (u, d) = ((f.angle_up as f64).tan(), (f.angle_down as f64).tan());
    let tx = l + px / w as f64 * (r - l);
    let ty = u - py / h as f64 * (u - d);
    let (cx, cy) = (center[0] as f64, center[1] as f64);
    let dot = tx * cx + ty * cy + 1.0;
    let norms = (tx * tx + ty * ty + 1.0).sqrt() * (cx * cx + cy * cy + 1.0).sqrt();
    (dot / norms).clamp(-1.0, 1.0).acos().to_degrees()
}

pub struct ViewResult {
    pub view: u32,
    pub pixels: u64,
    pub skipped: u64,
    pub shaded_drop: i64,
    /// The plain run's fragments at the pixels the rule skips (`--pixel-stats`).
    pub skipped_fragments: i64,
    /// Plain run's fragments beyond one per pixel.
    pub overdraw: i64,
    pub psnr_db: f64,
    /// Skipped pixels whose colour is not the reconstruction of the shaded pixels around their
    /// quad ([`reconstruction_holes`]); must be 0.
    pub holes: u64,
}

/// A skipped pixel reconstructed wrong: x, y, its colour, the colour it should have.
pub type Hole = (u32, u32, Vec<u16>, Vec<f64>);

/// Skipped pixels of `got` (the layer's capture of one view) that the reconstruction left wrong:
/// each skipped pixel must be the inverse-squared-distance weighted mean of the shaded pixels
/// among the 12 bordering its quad (`rules::reconstruction_weight`), computed here from `got`'s own
/// shaded pixels (bit-identical to the plain run, checked separately) in linear light when the
/// swapchain is sRGB (`srgb`), within `TOLERANCE` per channel (the compute pass approximates the
/// sRGB encode by square roots, the fill rounds in the GPU's attachment). A quad left unreconstructed
/// keeps what the app left under the skipped depth (its clear colour), which fails this wherever
/// that differs from its neighbours. Returns the count and the first few (x, y, got, want).
pub fn reconstruction_holes(params: &RdmParams, got: &Image, srgb: bool) -> (u64, Vec<Hole>) {
    const TOLERANCE: f64 = 3.0;
    let decode = |v: u16| {
        let c = v as f64 / 255.0;
        if !srgb {
            c
        } else if c <= 0.04045 {
            c / 12.92
        } else {
            ((c + 0.055) / 1.055).powf(2.4)
        }
    };
    let encode = |l: f64| {
        let c = if !srgb {
            l
        } else if l <= 0.0031308 {
            l * 12.92
        } else {
            1.055 * l.powf(1.0 / 2.4) - 0.055
        };
        c * 255.0
    };
    let (w, h) = (params.rect.width, params.rect.height);
    let shaded = |x: i64, y: i64| x >= 0 && y >= 0 && x < w as i64 && y < h as i64 && !params.pixel_skipped(x as i32, y as i32);
    let (mut n, mut first) = (0u64, Vec::new());
    for y in 0..h {
        for x in 0..w {
            if !params.pixel_skipped(x as i32, y as i32) {
                continue;
            }
            let (bx, by) = ((x / 2 * 2) as i64, (y / 2 * 2) as i64);
            let (mut sum, mut wsum) = ([0.0f64; 3], 0.0);
            for dy in -1..=2i64 {
                for dx in -1..=2i64 {
                    let (sx, sy) = (bx + dx, by + dy);
                    if (0..=1).contains(&dx) && (0..=1).contains(&dy) || !shaded(sx, sy) {
                        continue;
                    }
                    let wt = stereoshim::features::foveation::rdm::rules::reconstruction_weight((sx - x as i64) as i32, (sy - y as i64) as i32) as f64;
                    let px = got.pixel(sx as u32, sy as u32);
                    for c in 0..3 {
                        // Alpha is never decoded; colour is.
                        sum[c] += wt * decode(px[c]);
                    }
                    wsum += wt;
                }
            }
            if wsum == 0.0 {
                continue;
            }
            let want: Vec<f64> = sum.iter().map(|s| encode(s / wsum)).collect();
            let g = &got.pixel(x, y)[..3];
            if g.iter().zip(&want).any(|(&g, &e)| (g as f64 - e).abs() > TOLERANCE) {
                n += 1;
                if first.len() < 8 {
                    first.push((x, y, g.to_vec(), want));
                }
            }
        }
    }
    (n, first)
}

pub fn psnr(pairs: &[(f64, f64)]) -> f64 {
    if pairs.is_empty() {
        return f64::INFINITY;
    }
    let mse = pairs.iter().map(|(a, b)| (a - b) * (a - b)).sum::<f64>() / pairs.len() as f64;
    if mse == 0.0 {
        f64::INFINITY
    } else {
        10.0 * (255.0f64 * 255.0 / mse).log10()
    }
}

/// Every record of the layer's `stats.file` at `path` (one JSON object per frame).
pub fn layer_records(out: &RunOutput, path: &std::path::Path) -> Vec<serde_json::Value> {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: no stats.file {}: {e}\n{}", out.name, path.display(), out.log));
    text.lines().map(|l| serde_json::from_str::<serde_json::Value>(l).expect("stats line parses")).collect()
}

/// The layer's `stats.file` record of `frame`.
pub fn layer_stats(out: &RunOutput, path: &std::path::Path, frame: u64) -> serde_json::Value {
    layer_records(out, path)
        .into_iter()
        .find(|v| v["frame"] == frame)
        .unwrap_or_else(|| panic!("{}: no layer stats for frame {frame}", out.name))
}

/// What one captured frame is judged against.
pub struct Expected {
    /// The fovea centre of every view (tangent plane).
    pub center: [f32; 2],
    pub inner_deg: f32,
    pub middle_deg: f32,
    /// Both runs had the hidden-area mask on (the baseline is the mask alone).
    pub with_mask: bool,
}

/// Judges frame `frame` of `rdm` (through the layer with RDM) against the same frame of `plain`:
/// pixels of every quad the rule keeps (`RdmParams`, fed the f32 tangents of frames.json's FOV as
/// the layer computes them) and, computed independently in f64, every pixel whose quad grown by a
/// pixel lies inside the inner ring are bit-identical. Prints one line per view and returns its
/// numbers for [`check_results`] and [`check_layer_record`]; `Err` says what is wrong (images
/// saved under `test-artifacts/{name}-view{V}`). Both runs need `--pixel-stats`.
pub fn check_frame(name: &str, plain: &RunOutput, rdm: &RunOutput, frame: u64, expected: &Expected) -> Result<Vec<ViewResult>, String> {
    let mut out = Vec::new();
    // Every view both runs captured, or an error: a frame that cannot be compared view by view
    // (missing, different views or sizes) never passes by comparing less.
    let pairs = super::pair_frame(rdm.frames(), frame, plain.frames(), frame, super::DepthCheck::Compare)
        .map_err(|e| format!("{name}: frame {frame} of {} and {} cannot be compared: {e}", rdm.name, plain.name))?;
    for (a, b) in pairs {
        let (w, h) = (a.image_rect.width, a.image_rect.height);
        let center = expected.center;
        let fovea = FoveaView { view: a.view, center, inner_deg: expected.inner_deg, middle_deg: expected.middle_deg };
        let params = RdmParams::new(&view_fov(&a.fov), &fovea, PixelRect { x: 0, y: 0, width: w, height: h }).expect("params");
        let (got, want) = (rdm.image(&a.file), plain.image(&b.file));
        // With the mask, its hidden area is never shown, and skipped quads along its outline are
        // reconstructed partly from the hidden (black) side: PSNR counts the visible periphery
        // from MASK_MARGIN_PX inwards.
        let lens_hidden: Vec<bool> = if expected.with_mask {
            let captured = rdm.frame(frame);
            let mask = &captured.visibility_masks.iter().find(|m| m.view == a.view).expect("mask of view").hidden_triangles;
            let hidden = super::hidden_pixels(mask, &a.fov, w, h);
            let edge = super::mask_edge_pixels(mask, &a.fov, w, h, MASK_MARGIN_PX);
            hidden.iter().zip(&edge).map(|(a, b)| *a || *b).collect()
        } else {
            vec![false; (w * h) as usize]
        };
        let plain_counts = plain.pixel_counts(frame, b.view);
        let mut bad = Vec::new();
        let (mut skipped, mut periphery) = (0u64, Vec::new());
        // Σ over the pixels the rule skips of the plain run's fragments there.
        let mut skipped_fragments = 0i64;
        for y in 0..h {
            for x in 0..w {
                let (g, e) = (&got.pixel(x, y)[..3], &want.pixel(x, y)[..3]);
                let is_skipped = params.pixel_skipped(x as i32, y as i32);
                skipped += is_skipped as u64;
                if is_skipped {
                    skipped_fragments += plain_counts[(y * w + x) as usize] as i64;
                }
                // Independently: the whole quad, grown by a pixel, lies inside the inner ring.
                let (qx, qy) = ((x / 2 * 2) as f64, (y / 2 * 2) as f64);
                let deep_inside = [(qx - 1.0, qy - 1.0), (qx + 3.0, qy - 1.0), (qx - 1.0, qy + 3.0), (qx + 3.0, qy + 3.0)]
                    .iter()
                    .all(|&(px, py)| angle_deg(&a.fov, w, h, px, py, center) < expected.inner_deg as f64);
                if deep_inside && g != e {
                    bad.push((x, y, "inner ring"));
                } else if !is_skipped && g != e {
                    bad.push((x, y, "kept quad"));
                }
                if !deep_inside && !lens_hidden[(y * w + x) as usize] {
                    periphery.extend(g.iter().zip(e).map(|(&p, &q)| (p as f64, q as f64)));
                }
            }
        }
        if !bad.is_empty() {
            let dir = image::artifacts_dir(&format!("{name}-view{}", a.view));
            got.save(&dir.join("actual.png"));
            want.save(&dir.join("expected.png"));
            image::difference(&got, &want).save(&dir.join("difference.png"));
            return Err(format!("{name} view {}: {} wrong pixels, first {:?}; artifacts in {}", a.view, bad.len(), &bad[..bad.len().min(8)], dir.display()));
        }
        // A run that crashed may have captured frames whose numbers it never wrote.
        let shaded = |o: &RunOutput| -> Result<i64, String> {
            let f = o.stats.as_ref().and_then(|s| s.frames.iter().find(|f| f.frame == frame)).ok_or_else(|| format!("{}: no --stats of frame {frame}", o.name))?;
            Ok(f.views.iter().find(|v| v.view == a.view).expect("view stats").shaded_fragments as i64)
        };
        let (shaded_plain, shaded_rdm) = (shaded(plain)?, shaded(rdm)?);
        let overdraw = (shaded_plain - (w as i64 * h as i64)).max(0);
        // VK_FORMAT_R8G8B8A8_SRGB / VK_FORMAT_B8G8R8A8_SRGB.
        let (holes, first_holes) = reconstruction_holes(&params, &got, matches!(a.format, 43 | 50));
        if holes > 0 {
            let dir = image::artifacts_dir(&format!("{name}-view{}-holes", a.view));
            got.save(&dir.join("actual.png"));
            want.save(&dir.join("plain.png"));
            eprintln!("{name} view {}: {holes} skipped pixels not reconstructed, first (x, y, got, want) {first_holes:?}; artifacts in {}", a.view, dir.display());
        }
        let r = ViewResult {
            view: a.view,
            pixels: w as u64 * h as u64,
            skipped,
            shaded_drop: shaded_plain - shaded_rdm,
            skipped_fragments,
            overdraw,
            psnr_db: psnr(&periphery),
            holes,
        };
        eprintln!(
            "{name} view {}: {}x{} px, skipped {} px ({:.1} %, {} plain fragments), shaded fragments -{} (plain {}), periphery PSNR {:.2} dB, {} holes",
            a.view,
            w,
            h,
            r.skipped,
            100.0 * r.skipped as f64 / r.pixels as f64,
            r.skipped_fragments,
            r.shaded_drop,
            shaded_plain,
            r.psnr_db,
            r.holes
        );
        out.push(r);
    }
    Ok(out)
}

/// The layer's own account of the frame (its `stats.file` record): `rdm.pixels_skipped`, summed
/// over its passes, is the rule's count over each eye's rect, and each view was reconstructed once.
pub fn check_layer_record(name: &str, record: &serde_json::Value, results: &[ViewResult]) -> Result<(), String> {
    for r in results {
        let layer_px = record["rdm"]["pixels_skipped"][r.view.to_string()].as_u64().unwrap_or(0);
        if layer_px != r.skipped {
            return Err(format!("{name} view {}: the layer's stats.file says {layer_px} pixels skipped, the rule {}: {record}", r.view, r.skipped));
        }
        if record["rdm"]["reconstructed"][r.view.to_string()].as_u64() != Some(1) {
            return Err(format!("{name} view {}: the layer's stats.file does not report one reconstruction: {record}", r.view));
        }
    }
    Ok(())
}

/// The per-view numbers of one frame ([`check_frame`]) against what RDM must achieve: something
/// skipped; shaded fragments down by exactly the plain run's fragments at the skipped pixels
/// (RDM's depth makes every fragment of a skipped pixel fail early-Z, kept pixels keep theirs),
/// within the older bounds (skipped ≤ drop ≤ skipped + overdraw; without the mask every skipped
/// pixel had a fragment); every skipped pixel reconstructed (no holes); periphery PSNR ≥ 30 dB
/// for `balanced` rings.
pub fn check_results(name: &str, balanced: bool, with_mask: bool, results: &[ViewResult]) -> Result<(), String> {
    for r in results {
        if r.skipped == 0 {
            return Err(format!("{name} view {}: nothing skipped", r.view));
        }
        if !with_mask && r.shaded_drop < r.skipped as i64 {
            return Err(format!("{name} view {}: shaded fragments dropped by {} but {} pixels were skipped", r.view, r.shaded_drop, r.skipped));
        }
        if r.shaded_drop > r.skipped as i64 + r.overdraw {
            return Err(format!(
                "{name} view {}: shaded fragments dropped by {}, more than the {} skipped pixels plus all {} overdraw fragments",
                r.view, r.shaded_drop, r.skipped, r.overdraw
            ));
        }
        if r.shaded_drop != r.skipped_fragments {
            return Err(format!(
                "{name} view {}: shaded fragments dropped by {}, but the skipped pixels had {} fragments in the plain run",
                r.view, r.shaded_drop, r.skipped_fragments
            ));
        }
        if r.holes > 0 {
            return Err(format!("{name} view {}: {} skipped pixels are not the reconstruction of their quad's shaded neighbours (holes)", r.view, r.holes));
        }
        if balanced && r.psnr_db < 30.0 {
            return Err(format!("{name} view {}: periphery PSNR {:.2} dB < 30", r.view, r.psnr_db));
        }
    }
    Ok(())
}
