//! The overlay's pure decisions: what the panel says (from the per-second summary that
//! `stereoshim stats` prints too), how it is drawn (an 8×8 bitmap font, public-domain glyphs of
//! the `font8x8` crate, into RGBA texels), where it sits in the VIEW space, which swapchain format
//! it uses, and when its text is redrawn (once per completed second, so the overlay costs one
//! small upload a second). Below the text, a graph of the last frames' times, as `stereoshim top`
//! draws it, and the last A/B's speed-up that `top` measured.
#![forbid(unsafe_code)]

use crate::report::summary::{Frame, Second, Summary};
use ash::vk;
use glam::Vec3;

/// `overlay.position`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Position {
    Top,
    Bottom,
    Center,
}

/// Characters per line and lines of the panel.
pub const COLUMNS: u32 = 48;
pub const LINES: u32 = 6;
/// The frame-time graph under the text: this many texels high, one frame per two texels of
/// width (the newest at the right).
pub const GRAPH_HEIGHT: u32 = 24;
const BAR: u32 = 2;
/// Glyph cell (the font's 8×8 plus two rows between lines) and the border, texels.
const GLYPH: u32 = 8;
const LINE_HEIGHT: u32 = 10;
const PAD: u32 = 4;

/// The panel's texture size, texels (fixed: the swapchain is made once).
pub const fn texture_size() -> (u32, u32) {
    (COLUMNS * GLYPH + 2 * PAD, LINES * LINE_HEIGHT + GRAPH_HEIGHT + 2 * PAD)
}

/// How many frames the graph shows.
pub const fn graph_frames() -> usize {
    ((COLUMNS * GLYPH) / BAR) as usize
}

/// Premultiplied RGBA of the background (translucent black) and of the text (white).
pub const BACKGROUND: [u8; 4] = [0, 0, 0, 176];
pub const INK: [u8; 4] = [255, 255, 255, 255];
/// The graph's bars (green, opaque: unlike the text's white).
pub const BARS: [u8; 4] = [64, 200, 96, 255];

/// The panel's half width at 1 m and scale 1 (tan 13°: about 26° wide), and the elevation of its
/// centre for `top` / `bottom`, degrees.
const HALF_WIDTH_AT_1M: f32 = 0.2309;
const ELEVATION_DEG: f32 = 20.0;

/// Where the quad goes in the layer's VIEW space (x right, y up, −z ahead) and its size, metres.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Placement {
    pub position: Vec3,
    pub width_m: f32,
    pub height_m: f32,
}

/// The quad's place: `distance` ahead, its centre `ELEVATION_DEG` above (top) or below (bottom)
/// the view axis, its size growing with the distance so that the angular size is the scale's.
pub fn placement(position: Position, distance_m: f32, scale: f32) -> Placement {
    let d = distance_m.max(0.01);
    let elevation = match position {
        Position::Top => ELEVATION_DEG,
        Position::Bottom => -ELEVATION_DEG,
        Position::Center => 0.0,
    };
    let (tw, th) = texture_size();
    let width_m = 2.0 * HALF_WIDTH_AT_1M * d * scale;
    Placement { position: Vec3::new(0.0, d * elevation.to_radians().tan(), -d), width_m, height_m: width_m * th as f32 / tw as f32 }
}

/// The swapchain format: 8-bit RGBA or BGRA, sRGB preferred (the texels are sRGB values), from
/// what the runtime offers (`xrEnumerateSwapchainFormats`, in its order of preference).
pub fn choose_format(offered: &[i64]) -> Option<vk::Format> {
    let wanted = [vk::Format::R8G8B8A8_SRGB, vk::Format::B8G8R8A8_SRGB, vk::Format::R8G8B8A8_UNORM, vk::Format::B8G8R8A8_UNORM];
    wanted.into_iter().find(|f| offered.contains(&(f.as_raw() as i64)))
}

/// Whether `format`'s texels are stored blue first.
pub fn is_bgra(format: vk::Format) -> bool {
    matches!(format, vk::Format::B8G8R8A8_SRGB | vk::Format::B8G8R8A8_UNORM)
}

/// `1234567` → `1.23M`: counts short enough for the panel.
pub fn short_count(n: u64) -> String {
    match n {
        0..=9_999 => n.to_string(),
        10_000..=999_999 => format!("{:.1}k", n as f64 / 1e3),
        1_000_000..=999_999_999 => format!("{:.2}M", n as f64 / 1e6),
        _ => format!("{:.2}G", n as f64 / 1e9),
    }
}

/// The panel's lines: the features on (registry ids, as `features::enabled` gives them), then the
/// last complete second, or that the first is still being counted.
/// Then the last A/B `stereoshim top` measured (`ab`), and the key that hides the panel.
pub fn lines(enabled: &[(&str, bool)], last: Option<&Second>, ab: Option<&str>) -> Vec<String> {
    let on: Vec<&str> = enabled.iter().filter(|(_, on)| *on).map(|(id, _)| *id).collect();
    let mut v = vec![format!("stereoshim  on: {}", if on.is_empty() { "-".to_string() } else { on.join(" ") })];
    match last {
        None => v.push("last second: counting...".into()),
        Some(s) => {
            let ms = if s.frames > 0 { 1000.0 / s.frames as f64 } else { 0.0 };
            let gpu = s.gpu_busy_ms.map_or(String::new(), |g| format!("  gpu {g:.2} ms"));
            v.push(format!("{} fps  {ms:.1} ms/frame{gpu}", s.frames));
            v.push(format!("masked {} px  rdm skipped {} px", short_count(s.pixels_masked), short_count(s.rdm_pixels_skipped)));
            v.push(format!("vrs {} passes  far field {} px", short_count(s.vrs_passes), short_count(s.far_field_pixels_reused)));
        }
    }
    while v.len() < LINES as usize - 2 {
        v.push(String::new());
    }
    v.push(match ab {
        Some(a) => format!("A/B {a}"),
        None => "A/B: none yet (b in stereoshim top)".to_string(),
    });
    v.push("o in stereoshim top hides this panel".to_string());
    v
}

/// Draws `lines` (clipped to the panel) into texels of the panel's size, 4 bytes each, in RGBA
/// or, with `bgra`, BGRA order. Characters outside ASCII are drawn as `?`.
/// `graph`: the frame times to draw under the text, oldest first (the last
/// [`graph_frames`]), scaled so the tallest fills the graph.
pub fn rasterise(lines: &[String], graph: &[f32], bgra: bool) -> Vec<u8> {
    let (w, h) = texture_size();
    let order = |c: [u8; 4]| if bgra { [c[2], c[1], c[0], c[3]] } else { c };
    let (bg, ink) = (order(BACKGROUND), order(INK));
    let mut texels: Vec<u8> = std::iter::repeat_n(bg, (w * h) as usize).flatten().collect();
    for (row, line) in lines.iter().take(LINES as usize).enumerate() {
        for (col, ch) in line.chars().take(COLUMNS as usize).enumerate() {
            let glyph = font8x8::legacy::BASIC_LEGACY[if ch.is_ascii() { ch as usize } else { '?' as usize }];
            let (x0, y0) = (PAD + col as u32 * GLYPH, PAD + row as u32 * LINE_HEIGHT);
            for (gy, bits) in glyph.iter().enumerate() {
                for gx in 0..GLYPH {
                    // The font's rows are bytes with the leftmost pixel in bit 0.
                    if bits & (1 << gx) != 0 {
                        let i = (((y0 + gy as u32) * w + x0 + gx) * 4) as usize;
                        texels[i..i + 4].copy_from_slice(&ink);
                    }
                }
            }
        }
    }
    let bars = order(BARS);
    let shown = &graph[graph.len().saturating_sub(graph_frames())..];
    let max = shown.iter().copied().fold(0.0f32, f32::max);
    if max > 0.0 {
        let (x_end, y_bottom) = (PAD + COLUMNS * GLYPH, PAD + LINES * LINE_HEIGHT + GRAPH_HEIGHT);
        for (i, v) in shown.iter().rev().enumerate() {
            let tall = ((v / max) * GRAPH_HEIGHT as f32).round().clamp(0.0, GRAPH_HEIGHT as f32) as u32;
            let x0 = x_end - (i as u32 + 1) * BAR;
            for y in y_bottom - tall..y_bottom {
                for x in x0..x0 + BAR {
                    let t = ((y * w + x) * 4) as usize;
                    texels[t..t + 4].copy_from_slice(&bars);
                }
            }
        }
    }
    texels
}

/// The per-second window of the overlay: frames go in as their stats lines; a second is
/// reported once the first frame of the next one arrives (a complete second only).
#[derive(Debug, Default)]
pub struct Window {
    summary: Summary,
}

impl Window {
    /// Adds a frame; returns the second it completed, if it started a new one.
    pub fn add(&mut self, frame: &Frame) -> Option<Second> {
        self.summary.add(frame);
        // Only the current and the completed second are kept.
        (self.summary.seconds.len() > 1).then(|| self.summary.seconds.remove(0))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn texture_is_the_font_grid() {
        assert_eq!(texture_size(), (392, 92));
        let t = rasterise(&[], &[], false);
        assert_eq!(t.len(), 392 * 92 * 4);
        assert!(t.chunks(4).all(|p| p == BACKGROUND));
    }

    /// Texels of the ink colour in the glyph cell of (row, col).
    fn cell(t: &[u8], row: u32, col: u32) -> Vec<bool> {
        let (w, _) = texture_size();
        let mut v = Vec::new();
        for y in 0..8 {
            for x in 0..8 {
                let i = (((PAD + row * LINE_HEIGHT + y) * w + PAD + col * GLYPH + x) * 4) as usize;
                v.push(t[i..i + 4] == INK);
            }
        }
        v
    }

    #[test]
    fn glyphs_land_in_their_cells() {
        let t = rasterise(&["I -".into(), "".into(), "".into(), "    l".into()], &[], false);
        // 'I' (0x1E, 0x0C ×5, 0x1E, 0): serifs in columns 1..=4, a bar in columns 2, 3.
        let i = cell(&t, 0, 0);
        assert!(i[8 + 2] && i[8 + 3] && !i[8] && !i[8 + 7], "{i:?}");
        assert_eq!(i.iter().filter(|&&b| b).count(), 4 + 5 * 2 + 4);
        assert!(cell(&t, 0, 1).iter().all(|b| !b), "a space draws nothing");
        // '-' (0x3F in row 3): columns 0..=5 of row 3 only.
        let dash = cell(&t, 0, 2);
        assert_eq!(dash.iter().enumerate().filter(|(_, b)| **b).map(|(i, _)| i).collect::<Vec<_>>(), (24..30).collect::<Vec<_>>());
        assert!(cell(&t, 3, 4).iter().any(|b| *b), "line 4 column 5 drawn");
        // BGRA swaps the background's channels, not the layout.
        let b = rasterise(&["I".into()], &[], true);
        assert_eq!(cell(&b, 0, 0), i);
    }

    #[test]
    fn long_lines_are_clipped_and_non_ascii_is_a_question_mark() {
        let long = "x".repeat(100);
        let t = rasterise(&[long], &[], false);
        assert_eq!(t.len(), 392 * 92 * 4);
        assert_eq!(rasterise(&["é".into()], &[], false), rasterise(&["?".into()], &[], false));
    }

    #[test]
    fn text_says_what_is_on_and_what_it_saved() {
        let on = [("mask", true), ("rdm", false), ("vrs", true), ("far_field", false)];
        let first = lines(&on, None, None);
        assert_eq!(first[..2], ["stereoshim  on: mask vrs".to_string(), "last second: counting...".into()]);
        assert_eq!(first.len(), LINES as usize);
        assert_eq!(first[4], "A/B: none yet (b in stereoshim top)");
        assert_eq!(first[5], "o in stereoshim top hides this panel");
        assert_eq!(lines(&on, None, Some("mask: 1.31x (1.28-1.35 over 4 cycles)"))[4], "A/B mask: 1.31x (1.28-1.35 over 4 cycles)");
        assert_eq!(lines(&[("mask", false)], None, None)[0], "stereoshim  on: -");
        let mut s = Second::default();
        (s.frames, s.pixels_masked, s.rdm_pixels_skipped, s.vrs_passes, s.gpu_busy_ms) = (72, 1_234_567, 45_600, 144, Some(1.5));
        let l = lines(&on, Some(&s), None);
        assert_eq!(l[1], "72 fps  13.9 ms/frame  gpu 1.50 ms");
        assert_eq!(l[2], "masked 1.23M px  rdm skipped 45.6k px");
        assert_eq!(l[3], "vrs 144 passes  far field 0 px");
        assert!(l.iter().all(|x| x.len() <= COLUMNS as usize), "{l:?}");
    }

    /// The graph: one bar per frame, two texels wide, newest at the right, the tallest filling it.
    #[test]
    fn the_graph_follows_the_frame_times() {
        let (w, h) = texture_size();
        let t = rasterise(&[], &[1.0, 2.0, 4.0], false);
        let bar = |x: u32| (0..h).filter(|&y| t[((y * w + x) * 4) as usize..][..4] == BARS).count() as u32;
        let right = PAD + COLUMNS * GLYPH;
        assert_eq!((bar(right - 1), bar(right - 2)), (GRAPH_HEIGHT, GRAPH_HEIGHT), "newest, the tallest");
        assert_eq!(bar(right - 3), GRAPH_HEIGHT / 2);
        assert_eq!(bar(right - 5), GRAPH_HEIGHT / 4);
        assert_eq!(bar(right - 7), 0, "nothing older");
        // Only the last graph_frames() frames fit.
        let many: Vec<f32> = (0..graph_frames() + 10).map(|i| if i < 10 { 100.0 } else { 1.0 }).collect();
        let t2 = rasterise(&[], &many, false);
        assert!(t2.chunks(4).filter(|p| *p == BARS).count() as u32 == graph_frames() as u32 * BAR * GRAPH_HEIGHT, "the older, taller frames scrolled out");
    }

    #[test]
    fn placement_follows_the_settings() {
        let top = placement(Position::Top, 1.0, 1.0);
        assert!(top.position.y > 0.3 && top.position.z == -1.0 && top.position.x == 0.0);
        assert!((top.width_m - 0.4618).abs() < 1e-3 && (top.height_m / top.width_m - 92.0 / 392.0).abs() < 1e-6);
        let bottom = placement(Position::Bottom, 2.0, 0.5);
        assert!(bottom.position.y < -0.7 && bottom.position.z == -2.0);
        // The size in metres is distance × scale (the angle depends on the scale only).
        assert!((bottom.width_m - top.width_m).abs() < 1e-6);
        assert_eq!(placement(Position::Center, 1.0, 1.0).position.y, 0.0);
    }

    #[test]
    fn formats_prefer_srgb_rgba() {
        let raw = |f: vk::Format| f.as_raw() as i64;
        assert_eq!(choose_format(&[raw(vk::Format::B8G8R8A8_UNORM), raw(vk::Format::B8G8R8A8_SRGB)]), Some(vk::Format::B8G8R8A8_SRGB));
        assert_eq!(choose_format(&[raw(vk::Format::R8G8B8A8_SRGB), raw(vk::Format::B8G8R8A8_SRGB)]), Some(vk::Format::R8G8B8A8_SRGB));
        assert_eq!(choose_format(&[raw(vk::Format::R16G16B16A16_SFLOAT), raw(vk::Format::D32_SFLOAT)]), None);
        assert!(is_bgra(vk::Format::B8G8R8A8_SRGB) && !is_bgra(vk::Format::R8G8B8A8_SRGB));
    }

    #[test]
    fn window_reports_each_completed_second_once() {
        let frame = |n: u64, t: f64| Frame { frame: n, time: t, value: serde_json::json!({"frame": n, "time": t, "pixels_masked": {"0": 10}}) };
        let mut w = Window::default();
        assert_eq!(w.add(&frame(0, 10.0)), None);
        assert_eq!(w.add(&frame(1, 10.5)), None);
        let s = w.add(&frame(2, 11.1)).expect("second 0 complete");
        assert_eq!((s.second, s.frames, s.pixels_masked), (0, 2, 20));
        assert_eq!(w.add(&frame(3, 11.9)), None);
        assert_eq!(w.add(&frame(4, 12.0)).map(|s| (s.second, s.frames)), Some((1, 2)));
    }

    #[test]
    fn short_counts() {
        assert_eq!([0, 9_999, 10_000, 1_500_000, 2_000_000_000].map(short_count), ["0", "9999", "10.0k", "1.50M", "2.00G"]);
    }
}
