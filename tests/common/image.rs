//! Captured images and their comparison. A failed comparison leaves actual / expected / difference
//! PNGs under `target/test-artifacts/` so a person can see what went wrong, not just that it did.

use std::path::{Path, PathBuf};

/// A decoded capture: 8-bit RGB colour or 16-bit grey depth, stored as u16 samples either way.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Image {
    pub width: u32,
    pub height: u32,
    pub channels: u32,
    pub bit_depth: u8,
    pub data: Vec<u16>,
}

impl Image {
    pub fn load(path: &Path) -> Image {
        let file = std::fs::File::open(path).unwrap_or_else(|e| panic!("open {}: {e}", path.display()));
        let decoder = png::Decoder::new(std::io::BufReader::new(file));
        let mut reader = decoder.read_info().unwrap_or_else(|e| panic!("decode {}: {e}", path.display()));
        let mut buf = vec![0; reader.output_buffer_size().expect("png size")];
        let info = reader.next_frame(&mut buf).expect("png frame");
        let channels = match info.color_type {
            png::ColorType::Grayscale => 1,
            png::ColorType::Rgb => 3,
            png::ColorType::Rgba => 4,
            other => panic!("{}: unexpected colour type {other:?}", path.display()),
        };
        let bytes = &buf[..info.buffer_size()];
        let data = match info.bit_depth {
            png::BitDepth::Eight => bytes.iter().map(|&b| b as u16).collect(),
            png::BitDepth::Sixteen => bytes.chunks_exact(2).map(|c| u16::from_be_bytes([c[0], c[1]])).collect(),
            other => panic!("{}: unexpected bit depth {other:?}", path.display()),
        };
        Image { width: info.width, height: info.height, channels, bit_depth: info.bit_depth as u8, data }
    }

    pub fn pixel(&self, x: u32, y: u32) -> &[u16] {
        assert!(x < self.width && y < self.height, "pixel ({x},{y}) outside {}x{}", self.width, self.height);
        let i = ((y * self.width + x) * self.channels) as usize;
        &self.data[i..i + self.channels as usize]
    }

    /// Mean colour over a (2r+1)² window, clamped to the image; robust against single edge pixels.
    pub fn mean(&self, x: u32, y: u32, r: u32) -> Vec<f32> {
        let mut sum = vec![0f32; self.channels as usize];
        let mut n = 0f32;
        for yy in y.saturating_sub(r)..=(y + r).min(self.height - 1) {
            for xx in x.saturating_sub(r)..=(x + r).min(self.width - 1) {
                for (s, &v) in sum.iter_mut().zip(self.pixel(xx, yy)) {
                    *s += v as f32;
                }
                n += 1.0;
            }
        }
        sum.iter().map(|s| s / n).collect()
    }

    /// Number of pixels whose samples differ at all.
    pub fn count_different(&self, other: &Image) -> usize {
        assert_eq!((self.width, self.height, self.channels), (other.width, other.height, other.channels));
        self.data
            .chunks_exact(self.channels as usize)
            .zip(other.data.chunks_exact(other.channels as usize))
            .filter(|(a, b)| a != b)
            .count()
    }

    pub fn save(&self, path: &Path) {
        let file = std::fs::File::create(path).unwrap_or_else(|e| panic!("create {}: {e}", path.display()));
        let mut enc = png::Encoder::new(std::io::BufWriter::new(file), self.width, self.height);
        enc.set_color(match self.channels {
            1 => png::ColorType::Grayscale,
            3 => png::ColorType::Rgb,
            _ => png::ColorType::Rgba,
        });
        let bytes: Vec<u8> = if self.bit_depth == 16 {
            enc.set_depth(png::BitDepth::Sixteen);
            self.data.iter().flat_map(|v| v.to_be_bytes()).collect()
        } else {
            enc.set_depth(png::BitDepth::Eight);
            self.data.iter().map(|&v| v as u8).collect()
        };
        enc.write_header().and_then(|mut w| w.write_image_data(&bytes)).expect("write png");
    }
}

/// Where a failed comparison leaves its pictures.
pub fn artifacts_dir(name: &str) -> PathBuf {
    let dir = super::target_dir().join("test-artifacts").join(name);
    std::fs::create_dir_all(&dir).expect("create artifacts dir");
    dir
}

/// Asserts bit-identical images; on failure writes actual, expected and a difference image (black
/// where equal, red scaled by the largest channel difference elsewhere) and panics naming them.
pub fn assert_identical(name: &str, actual: &Image, expected: &Image) {
    assert_eq!(
        (actual.width, actual.height, actual.channels),
        (expected.width, expected.height, expected.channels),
        "{name}: image shapes differ"
    );
    let different = actual.count_different(expected);
    if different == 0 {
        return;
    }
    let dir = artifacts_dir(name);
    actual.save(&dir.join("actual.png"));
    expected.save(&dir.join("expected.png"));
    difference(actual, expected).save(&dir.join("difference.png"));
    panic!(
        "{name}: {different} of {} pixels differ; see {}/{{actual,expected,difference}}.png",
        actual.width * actual.height,
        dir.display()
    );
}

/// Black where equal; red with intensity of the largest channel difference (at least 64 so that
/// one-step differences are still visible).
pub fn difference(a: &Image, b: &Image) -> Image {
    let max = if a.bit_depth == 16 { 65535.0 } else { 255.0 };
    let mut data = Vec::with_capacity((a.width * a.height * 3) as usize);
    for (pa, pb) in a.data.chunks_exact(a.channels as usize).zip(b.data.chunks_exact(b.channels as usize)) {
        let d = pa.iter().zip(pb).map(|(x, y)| x.abs_diff(*y)).max().unwrap_or(0) as f32 / max;
        let v = if d == 0.0 { 0 } else { (64.0 + d * 191.0).min(255.0) as u16 };
        data.extend_from_slice(&[v, 0, 0]);
    }
    Image { width: a.width, height: a.height, channels: 3, bit_depth: 8, data }
}
