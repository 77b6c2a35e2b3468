//! The preview's pictures: a neutral angle grid (or the user's image) per view, each feature's
//! answer blended over it in a fixed colour per class, and a legend strip under the view with
//! swatches and words (8×8 bitmap glyphs of `font8x8`: no system font needed). The colours are
//! fixed and listed in `preview.json` (`legend`), so a picture can be checked against its numbers
//! by counting pixels.
#![forbid(unsafe_code)]

use super::{rate_name, Preview, RATES};
use crate::core::views::ViewFov;

pub type Rgb = [u8; 3];

/// The grid's background and its lines (every 10° of angle; the optical axis is the 0° line).
pub const GRID_BACKGROUND: Rgb = [58, 62, 68];
pub const GRID_LINE: Rgb = [112, 118, 126];
pub const GRID_STEP_DEG: f64 = 10.0;

/// A class of pixels and how it is painted: `tint` blended over the picture with `alpha` / 255.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Class {
    pub name: &'static str,
    pub tint: Rgb,
    pub alpha: u8,
}

pub const MASKED: Class = Class { name: "masked", tint: [210, 30, 130], alpha: 170 };
/// VRS rates, in the order of `RATES`.
pub const VRS: [Class; 3] = [
    Class { name: "1x1", tint: [40, 200, 80], alpha: 110 },
    Class { name: "2x1", tint: [235, 200, 40], alpha: 140 },
    Class { name: "2x2", tint: [225, 60, 40], alpha: 150 },
];
/// RDM: the ring of a shaded quad (inner, middle, outer) and a skipped pixel.
pub const RDM_RINGS: [Class; 3] = [
    Class { name: "inner", tint: [40, 200, 80], alpha: 90 },
    Class { name: "middle", tint: [235, 200, 40], alpha: 90 },
    Class { name: "outer", tint: [225, 60, 40], alpha: 90 },
];
pub const RDM_SKIPPED: Class = Class { name: "skipped", tint: [0, 0, 0], alpha: 255 };
pub const FAR_REUSED: Class = Class { name: "reused", tint: [40, 200, 235], alpha: 150 };
/// The FOV cut: pixels outside it (the app no longer renders them).
pub const CUT_OFF: Class = Class { name: "cut off", tint: [150, 90, 230], alpha: 180 };

/// Rows under each view holding the legend (three lines of text).
pub const LEGEND_HEIGHT: u32 = 44;
const LEGEND_BACKGROUND: Rgb = [24, 24, 26];
const TEXT: Rgb = [236, 236, 236];

/// `tint` over `base` at `alpha` / 255, rounded.
pub fn blend(base: Rgb, c: &Class) -> Rgb {
    let a = c.alpha as u32;
    [0, 1, 2].map(|i| ((base[i] as u32 * (255 - a) + c.tint[i] as u32 * a + 127) / 255) as u8)
}

/// The legend as JSON: every class's name, tint and alpha, and the grid's colours.
pub fn legend_json() -> serde_json::Value {
    let class = |c: &Class| serde_json::json!({ "name": c.name, "tint": c.tint, "alpha": c.alpha });
    serde_json::json!({
        "grid": { "background": GRID_BACKGROUND, "line": GRID_LINE, "step_deg": GRID_STEP_DEG },
        "legend_height": LEGEND_HEIGHT,
        "mask": [class(&MASKED)],
        "vrs": VRS.iter().map(class).collect::<Vec<_>>(),
        "rdm": RDM_RINGS.iter().chain([&RDM_SKIPPED]).map(class).collect::<Vec<_>>(),
        "far_field": [class(&FAR_REUSED)],
        "fov_cut": [class(&CUT_OFF)],
    })
}

/// An RGB picture.
#[derive(Clone, Debug, PartialEq)]
pub struct Canvas {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<Rgb>,
}

impl Canvas {
    pub fn new(width: u32, height: u32, fill: Rgb) -> Canvas {
        Canvas { width, height, pixels: vec![fill; (width * height) as usize] }
    }

    /// The angle grid of a view: a line where a pixel column (row) crosses a multiple of
    /// `GRID_STEP_DEG` horizontally (vertically), so the grid shows the view's own angles.
    pub fn grid(width: u32, height: u32, fov: &ViewFov) -> Canvas {
        let mut c = Canvas::new(width, height, GRID_BACKGROUND);
        let step = GRID_STEP_DEG.to_radians();
        // The index of the 10° band each pixel centre lies in; a line where it changes.
        let band = |t: f64| (t.atan() / step).floor() as i64;
        let sx = (fov.tan_right - fov.tan_left) as f64 / width as f64;
        let sy = (fov.tan_up - fov.tan_down) as f64 / height as f64;
        let col: Vec<i64> = (0..width).map(|x| band(fov.tan_left as f64 + (x as f64 + 0.5) * sx)).collect();
        let row: Vec<i64> = (0..height).map(|y| band(fov.tan_up as f64 - (y as f64 + 0.5) * sy)).collect();
        for y in 0..height as usize {
            for x in 0..width as usize {
                let line = (x > 0 && col[x] != col[x - 1]) || (y > 0 && row[y] != row[y - 1]);
                if line {
                    c.pixels[y * width as usize + x] = GRID_LINE;
                }
            }
        }
        c
    }

    /// An image (RGB8) scaled to `width`×`height` by nearest neighbour.
    pub fn resized(src: &Canvas, width: u32, height: u32) -> Canvas {
        let mut c = Canvas::new(width, height, GRID_BACKGROUND);
        for y in 0..height {
            let sy = ((y as u64 * src.height as u64) / height as u64) as u32;
            for x in 0..width {
                let sx = ((x as u64 * src.width as u64) / width as u64) as u32;
                c.pixels[(y * width + x) as usize] = src.pixels[(sy * src.width + sx) as usize];
            }
        }
        c
    }

    /// Blends the class of each pixel (`class_of` gives its index into `classes`, or None) over
    /// the picture.
    pub fn paint(&mut self, classes: &[Class], class_of: impl Fn(usize) -> Option<usize>) {
        for (i, p) in self.pixels.iter_mut().enumerate() {
            if let Some(k) = class_of(i) {
                *p = blend(*p, &classes[k]);
            }
        }
    }

    fn fill_rect(&mut self, x0: u32, y0: u32, w: u32, h: u32, c: Rgb) {
        for y in y0..(y0 + h).min(self.height) {
            for x in x0..(x0 + w).min(self.width) {
                self.pixels[(y * self.width + x) as usize] = c;
            }
        }
    }

    /// Draws `text` (ASCII; others as '?') at (x, y) with 8×8 glyphs; returns the x after it.
    /// Clipped at the canvas' edges.
    fn text(&mut self, x: u32, y: u32, text: &str, c: Rgb) -> u32 {
        let mut cx = x;
        for ch in text.chars() {
            let code = if ch.is_ascii() { ch as usize } else { '?' as usize };
            let glyph = font8x8::legacy::BASIC_LEGACY[code];
            for (gy, bits) in glyph.iter().enumerate() {
                for gx in 0..8 {
                    // Bit 0 is the leftmost column.
                    if bits & (1 << gx) != 0 {
                        let (px, py) = (cx + gx, y + gy as u32);
                        if px < self.width && py < self.height {
                            self.pixels[(py * self.width + px) as usize] = c;
                        }
                    }
                }
            }
            cx += 8;
        }
        cx
    }

    /// The picture with a legend strip under it: a title line, then `entries` (a swatch of the
    /// class over the grid background, and its words) flowing over two lines.
    pub fn with_legend(&self, title: &str, entries: &[(Class, String)]) -> Canvas {
        let mut out = Canvas::new(self.width, self.height + LEGEND_HEIGHT, LEGEND_BACKGROUND);
        out.pixels[..self.pixels.len()].copy_from_slice(&self.pixels);
        let top = self.height;
        out.text(4, top + 4, title, TEXT);
        let (mut x, mut line) = (4u32, 0u32);
        for (class, words) in entries {
            let need = 14 + 8 * words.chars().count() as u32 + 10;
            if x > 4 && x + need > self.width && line == 0 {
                x = 4;
                line = 1;
            }
            let y = top + 18 + line * 13;
            out.fill_rect(x, y - 1, 10, 10, blend(GRID_BACKGROUND, class));
            x = out.text(x + 14, y, words, TEXT) + 10;
        }
        out
    }

    /// The picture as PNG bytes (8-bit RGB).
    pub fn png(&self) -> Result<Vec<u8>, String> {
        let mut out = Vec::new();
        {
            let mut enc = png::Encoder::new(&mut out, self.width, self.height);
            enc.set_color(png::ColorType::Rgb);
            enc.set_depth(png::BitDepth::Eight);
            enc.set_compression(png::Compression::High);
            let mut w = enc.write_header().map_err(|e| e.to_string())?;
            let bytes: Vec<u8> = self.pixels.iter().flatten().copied().collect();
            w.write_image_data(&bytes).map_err(|e| e.to_string())?;
        }
        Ok(out)
    }

    /// Decodes a PNG (any colour type and depth, made 8-bit RGB; alpha dropped).
    pub fn from_png(bytes: &[u8]) -> Result<Canvas, String> {
        let mut dec = png::Decoder::new(std::io::Cursor::new(bytes));
        dec.set_transformations(png::Transformations::normalize_to_color8());
        let mut reader = dec.read_info().map_err(|e| e.to_string())?;
        let mut buf = vec![0; reader.output_buffer_size().ok_or("image too large")?];
        let info = reader.next_frame(&mut buf).map_err(|e| e.to_string())?;
        let ch = match info.color_type {
            png::ColorType::Grayscale => 1,
            png::ColorType::GrayscaleAlpha => 2,
            png::ColorType::Rgb => 3,
            png::ColorType::Rgba => 4,
            png::ColorType::Indexed => return Err("indexed colour left unexpanded".into()),
        };
        if info.width == 0 || info.height == 0 {
            return Err("empty image".into());
        }
        let pixels = buf[..info.buffer_size()]
            .chunks_exact(ch)
            .map(|p| if ch < 3 { [p[0]; 3] } else { [p[0], p[1], p[2]] })
            .collect();
        Ok(Canvas { width: info.width, height: info.height, pixels })
    }
}

fn percent(n: u64, area: u64) -> String {
    format!("{:.1}%", if area == 0 { 0.0 } else { 100.0 * n as f64 / area as f64 })
}

/// The pictures of one view: (feature, picture) for the mask, VRS, RDM (when the FOV allows
/// it), the far field and the FOV cut (when there is one), each over `base`.
pub fn view_pictures(p: &Preview, i: usize, base: &Canvas) -> Vec<(&'static str, Canvas)> {
    let v = &p.views[i];
    let area = p.width as u64 * p.height as u64;
    let mut out = Vec::new();

    let mut c = base.clone();
    c.paint(&[MASKED], |k| v.mask.masked[k].then_some(0));
    let source = match v.mask.source {
        Some(crate::core::views::MaskSource::Runtime) => "runtime mesh",
        Some(crate::core::views::MaskSource::Synthesized) => "synthesized lens",
        Some(crate::core::views::MaskSource::Headset) => "the headset's published lens",
        None => "none",
    };
    out.push(("mask", c.with_legend(&format!("mask, view {i}: {source}"), &[(MASKED, format!("masked {}", percent(v.mask.pixels_masked, area)))])));

    let mut c = base.clone();
    c.paint(&VRS, |k| Some(v.vrs.rate[k] as usize));
    let entries: Vec<(Class, String)> =
        VRS.iter().zip(RATES).zip(v.vrs.pixels).map(|((c, r), n)| (*c, format!("{} {}", rate_name(r), percent(n, area)))).collect();
    let saved = v.vrs.saved().iter().sum::<u64>();
    out.push(("vrs", c.with_legend(&format!("VRS, view {i}: saves {}", percent(saved, area)), &entries)));

    if let Some(r) = &v.rdm {
        let mut c = base.clone();
        let mut classes = RDM_RINGS.to_vec();
        classes.push(RDM_SKIPPED);
        c.paint(&classes, |k| Some(if r.skipped[k] { 3 } else { r.ring[k] as usize }));
        let mut entries = vec![(RDM_SKIPPED, format!("skipped {}", percent(r.pixels_skipped, area)))];
        entries.extend(RDM_RINGS.iter().map(|c| (*c, c.name.to_string())));
        out.push(("rdm", c.with_legend(&format!("RDM, view {i}: shaded quads by ring"), &entries)));
    }

    let mut c = base.clone();
    c.paint(&[FAR_REUSED], |k| v.far_field.reusable[k].then_some(0));
    let split = if p.split_m.is_finite() { format!("{:.1} m", p.split_m) } else { "none".into() };
    let (title, entries) = if v.far_field.destination {
        (format!("far field, view {i}: beyond {split}"), vec![(FAR_REUSED, format!("reused {}", percent(v.far_field.pixels_reusable, area)))])
    } else {
        (format!("far field, view {i}: the source"), Vec::new())
    };
    out.push(("far_field", c.with_legend(&title, &entries)));

    if let Some(cut) = p.cuts.get(i).copied().flatten() {
        let mut c = base.clone();
        let w = p.width as usize;
        let outside = |k: usize| !((cut.x0..cut.x1).contains(&((k % w) as u32)) && (cut.y0..cut.y1).contains(&((k / w) as u32)));
        // The cut over the lens: what it leaves out, and inside it what the mask hides.
        c.paint(&[MASKED, CUT_OFF], |k| if outside(k) { Some(1) } else { v.mask.masked[k].then_some(0) });
        let left_out = area - cut.size().0 as u64 * cut.size().1 as u64;
        let title = format!("FOV cut, view {i}: {}x{} of {}x{}", cut.size().0, cut.size().1, p.width, p.height);
        out.push(("fov_cut", c.with_legend(&title, &[(CUT_OFF, format!("cut off {}", percent(left_out, area))), (MASKED, "hidden by the lens".into())])));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blend_ends_and_middle() {
        assert_eq!(blend([10, 20, 30], &Class { name: "", tint: [200, 0, 0], alpha: 0 }), [10, 20, 30]);
        assert_eq!(blend([10, 20, 30], &Class { name: "", tint: [200, 0, 0], alpha: 255 }), [200, 0, 0]);
        assert_eq!(blend([0, 0, 0], &Class { name: "", tint: [255, 255, 255], alpha: 128 }), [128, 128, 128]);
    }

    #[test]
    fn every_class_is_told_apart_over_the_grid() {
        // A pixel's class must be readable back from its colour (the tests count them).
        let mut seen = std::collections::HashSet::new();
        let all: Vec<Class> = [MASKED, RDM_SKIPPED, FAR_REUSED, CUT_OFF].into_iter().chain(VRS).chain(RDM_RINGS).collect();
        for base in [GRID_BACKGROUND, GRID_LINE] {
            assert!(seen.insert(base));
        }
        for c in &all {
            for base in [GRID_BACKGROUND, GRID_LINE] {
                let b = blend(base, c);
                // The same class over both grid colours may coincide (opaque); different classes never.
                if !seen.insert(b) {
                    assert_eq!(c.alpha, 255, "{} collides", c.name);
                }
            }
        }
    }

    #[test]
    fn grid_lines_follow_the_angles() {
        let fov = ViewFov { tan_left: -1.0, tan_right: 1.0, tan_up: 1.0, tan_down: -1.0 };
        let g = Canvas::grid(200, 100, &fov);
        // ±45° each way: lines at −40..40 in 10° steps (9) per axis; the 0° line in the middle.
        let cols = (0..200).filter(|&x| g.pixels[(45 * 200 + x) as usize] == GRID_LINE).count();
        assert_eq!(cols, 9);
        assert!((0..200).all(|x| g.pixels[(50 * 200 + x) as usize] == GRID_LINE), "the 0° row");
        assert_eq!(g.pixels[(10 * 200 + 100) as usize], GRID_LINE, "the optical axis");
    }

    #[test]
    fn png_round_trip_and_legend_size() {
        let c = Canvas::new(30, 20, [1, 2, 3]);
        let l = c.with_legend("title", &[(MASKED, "masked 1%".into())]);
        assert_eq!((l.width, l.height), (30, 20 + LEGEND_HEIGHT));
        let back = Canvas::from_png(&l.png().unwrap()).unwrap();
        assert_eq!(back, l);
        assert!(Canvas::from_png(b"not a png").is_err());
    }
}
