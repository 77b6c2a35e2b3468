//! What `stereoshim top` shows, computed from the frames' stats lines (the layer's stream, the
//! lines of `stats.file`): each frame read into a [`FrameView`], the last frames kept in a
//! [`Recent`] window, and the numbers of the screen (frame rate, GPU time, what each feature did
//! and saved in the last second, what was found and why passes were left alone) derived from it.
//! Pure: the screen (`ui`) only lays these out, and tests compare them with the file.
#![forbid(unsafe_code)]

use serde_json::Value;
use std::collections::{BTreeMap, VecDeque};

/// One frame's line, as `top` uses it.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FrameView {
    pub frame: u64,
    /// Seconds since the Unix epoch at its `xrEndFrame`.
    pub time: f64,
    /// The layer's end-to-end GPU busy time of the frame (every submission, the layer's own
    /// included), when the timer ran and the time came back.
    pub gpu_ms: Option<f64>,
    pub mask: bool,
    pub foveation: bool,
    pub far_field: bool,
    pub overlay: bool,
    pub upscale: bool,
    pub passes_masked: u64,
    /// Masked passes by how their target was tied to an eye (swapchain, transfer, walk,
    /// fallback).
    pub masked_by: BTreeMap<String, u64>,
    /// Pixels masked per view.
    pub pixels_masked: BTreeMap<String, u64>,
    pub rdm_passes: u64,
    pub rdm_pixels_skipped: u64,
    pub vrs_passes: u64,
    pub far_field_pixels_reused: u64,
    /// The upscale: pixels the app rendered and the runtime displayed, this frame.
    pub upscale_px: Option<(u64, u64)>,
    /// `feature.reason` → passes left alone for it (not `not_eye_pass`: other passes).
    pub not_applied: BTreeMap<String, u64>,
}

fn u(v: &Value, path: &[&str]) -> u64 {
    path.iter().try_fold(v, |v, k| v.get(k)).and_then(Value::as_u64).unwrap_or(0)
}

fn counts(v: &Value, path: &[&str]) -> BTreeMap<String, u64> {
    path.iter()
        .try_fold(v, |v, k| v.get(k))
        .and_then(Value::as_object)
        .map_or_else(BTreeMap::new, |m| m.iter().map(|(k, n)| (k.clone(), n.as_u64().unwrap_or(0))).collect())
}

impl FrameView {
    /// Reads a frame's line (None: not a frame line).
    pub fn parse(line: &str) -> Option<FrameView> {
        let v: Value = serde_json::from_str(line).ok()?;
        FrameView::from_value(&v)
    }

    pub fn from_value(v: &Value) -> Option<FrameView> {
        let frame = v.get("frame")?.as_u64()?;
        let time = v.get("time")?.as_f64()?;
        let b = |k: &str| v.get(k).and_then(Value::as_bool).unwrap_or(false);
        let mut not_applied = BTreeMap::new();
        for (feature, path) in [("mask", &["not_masked"][..]), ("rdm", &["rdm", "not_applied"]), ("vrs", &["vrs", "not_applied"]), ("far_field", &["far_field", "not_applied"])] {
            for (reason, n) in counts(v, path) {
                if reason != "not_eye_pass" && n > 0 {
                    not_applied.insert(format!("{feature}.{reason}"), n);
                }
            }
        }
        let upscale_px = v.get("upscale").filter(|u| u.is_object()).map(|up| (u(up, &["rendered_px"]), u(up, &["display_px"])));
        Some(FrameView {
            frame,
            time,
            gpu_ms: v.get("gpu_ms").and_then(|g| g.get("busy")).and_then(Value::as_f64),
            mask: b("mask_enabled"),
            foveation: b("foveation_enabled"),
            far_field: b("far_field_enabled"),
            overlay: b("overlay_enabled"),
            upscale: b("upscale_enabled"),
            passes_masked: u(v, &["passes_masked"]),
            masked_by: counts(v, &["mask_by_source"]),
            pixels_masked: counts(v, &["pixels_masked"]),
            rdm_passes: u(v, &["rdm", "passes"]),
            rdm_pixels_skipped: counts(v, &["rdm", "pixels_skipped"]).values().sum(),
            vrs_passes: u(v, &["vrs", "passes"]),
            far_field_pixels_reused: u(v, &["far_field", "pixels_reused"]),
            upscale_px,
            not_applied,
        })
    }

    pub fn pixels_masked_total(&self) -> u64 {
        self.pixels_masked.values().sum()
    }
}

/// The median of `v` (None when empty); sorts `v`.
pub fn median(v: &mut [f64]) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    v.sort_by(|a, b| a.total_cmp(b));
    let n = v.len();
    Some(if n % 2 == 1 { v[n / 2] } else { (v[n / 2 - 1] + v[n / 2]) / 2.0 })
}

/// What the last second of frames did (the frames whose `time` is within one second of the
/// newest's).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LastSecond {
    pub frames: u64,
    /// Frames per second over the window (frames after the first / their time span).
    pub fps: Option<f64>,
    /// Median GPU busy time of the window's timed frames, ms.
    pub gpu_ms: Option<f64>,
    pub pixels_masked: u64,
    pub rdm_pixels_skipped: u64,
    pub vrs_passes: u64,
    pub far_field_pixels_reused: u64,
    /// The upscale's rendered and displayed pixels.
    pub upscale_px: Option<(u64, u64)>,
}

/// The last frames read, oldest first, at most `capacity`.
#[derive(Debug)]
pub struct Recent {
    frames: VecDeque<FrameView>,
    capacity: usize,
}

impl Recent {
    pub fn new(capacity: usize) -> Recent {
        Recent { frames: VecDeque::with_capacity(capacity), capacity: capacity.max(1) }
    }

    /// Adds a frame. A frame number at or below the newest's starts a new session's frames:
    /// what was kept is dropped (the numbers of two sessions do not mix).
    pub fn push(&mut self, f: FrameView) {
        if self.frames.back().is_some_and(|last| f.frame <= last.frame) {
            self.frames.clear();
        }
        if self.frames.len() == self.capacity {
            self.frames.pop_front();
        }
        self.frames.push_back(f);
    }

    pub fn latest(&self) -> Option<&FrameView> {
        self.frames.back()
    }

    pub fn len(&self) -> usize {
        self.frames.len()
    }

    pub fn is_empty(&self) -> bool {
        self.frames.is_empty()
    }

    /// The newest `n` frames' GPU times (0 where a frame has none), oldest first: the graph.
    pub fn gpu_series(&self, n: usize) -> Vec<f64> {
        let skip = self.frames.len().saturating_sub(n);
        self.frames.iter().skip(skip).map(|f| f.gpu_ms.unwrap_or(0.0)).collect()
    }

    /// The window of frames within one second of the newest.
    pub fn last_second(&self) -> LastSecond {
        let Some(newest) = self.frames.back() else { return LastSecond::default() };
        let window: Vec<&FrameView> = self.frames.iter().rev().take_while(|f| newest.time - f.time < 1.0).collect();
        let mut out = LastSecond { frames: window.len() as u64, ..Default::default() };
        if let (Some(first), true) = (window.last(), window.len() > 1) {
            let span = newest.time - first.time;
            if span > 0.0 {
                out.fps = Some((window.len() - 1) as f64 / span);
            }
        }
        let mut gpu: Vec<f64> = window.iter().filter_map(|f| f.gpu_ms).collect();
        out.gpu_ms = median(&mut gpu);
        for f in &window {
            out.pixels_masked += f.pixels_masked_total();
            out.rdm_pixels_skipped += f.rdm_pixels_skipped;
            out.vrs_passes += f.vrs_passes;
            out.far_field_pixels_reused += f.far_field_pixels_reused;
            if let Some((r, d)) = f.upscale_px {
                let (sr, sd) = out.upscale_px.unwrap_or((0, 0));
                out.upscale_px = Some((sr + r, sd + d));
            }
        }
        out
    }
}

/// A not-applied reason in words: the first clause of the feature's own hint for it (the log's
/// full hint says what to do).
pub fn reason_in_words(feature_reason: &str) -> String {
    let (feature, reason) = feature_reason.split_once('.').unwrap_or(("", feature_reason));
    let stats = crate::registry::empty_stats();
    let hint = stats.iter().find(|f| f.id() == feature).map(|f| f.hint(reason)).unwrap_or_else(|| crate::core::stats::common_hint(reason));
    let clause = hint.split([':', ';', '(']).next().unwrap_or(hint).trim();
    format!("{reason}: {clause}")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn line(frame: u64, time: f64, gpu: Option<f64>) -> String {
        let mut v = serde_json::json!({
            "frame": frame, "time": time, "mask_enabled": true, "foveation_enabled": true, "far_field_enabled": false,
            "overlay_enabled": false, "upscale_enabled": false,
            "passes_masked": 2, "pixels_masked": {"0": 100, "1": 120}, "mask_by_source": {"walk": 2},
            "not_masked": {"eye_unknown": 1, "not_eye_pass": 4},
            "rdm": {"passes": 2, "pixels_skipped": {"0": 10, "1": 11}, "not_applied": {}},
            "vrs": {"passes": 0, "not_applied": {"unsupported": 2}},
            "far_field": {"pixels_reused": 5, "not_applied": {}},
        });
        if let Some(g) = gpu {
            v["gpu_ms"] = serde_json::json!({"busy": g, "span": g, "submissions": 1, "untimed": 0});
        }
        v.to_string()
    }

    #[test]
    fn a_line_is_read() {
        let f = FrameView::parse(&line(7, 10.0, Some(2.5))).unwrap();
        assert_eq!((f.frame, f.gpu_ms, f.mask, f.far_field), (7, Some(2.5), true, false));
        assert_eq!((f.pixels_masked_total(), f.rdm_pixels_skipped, f.far_field_pixels_reused), (220, 21, 5));
        assert_eq!(f.masked_by, BTreeMap::from([("walk".to_string(), 2)]));
        // Other passes are no reason.
        assert_eq!(f.not_applied, BTreeMap::from([("mask.eye_unknown".to_string(), 1), ("vrs.unsupported".to_string(), 2)]));
        assert!(FrameView::parse("{").is_none());
        assert!(FrameView::parse(r#"{"frame": 1}"#).is_none());
    }

    #[test]
    fn the_last_second() {
        let mut r = Recent::new(100);
        for i in 0..30u64 {
            r.push(FrameView::parse(&line(i, 100.0 + i as f64 / 10.0, Some(i as f64))).unwrap());
        }
        let s = r.last_second();
        // Frames 20..=29 are within a second of frame 29 (2.9 s − 2.0 s = 0.9 s).
        assert_eq!(s.frames, 10);
        assert!((s.fps.unwrap() - 10.0).abs() < 1e-6, "{:?}", s.fps);
        assert_eq!(s.gpu_ms, Some(24.5));
        assert_eq!(s.pixels_masked, 2200);
        assert_eq!(r.gpu_series(3), vec![27.0, 28.0, 29.0]);
    }

    #[test]
    fn capacity_and_a_new_session() {
        let mut r = Recent::new(4);
        for i in 0..10u64 {
            r.push(FrameView::parse(&line(i, i as f64, None)).unwrap());
        }
        assert_eq!(r.len(), 4);
        assert_eq!(r.latest().unwrap().frame, 9);
        r.push(FrameView::parse(&line(0, 50.0, None)).unwrap());
        assert_eq!(r.len(), 1, "frame numbers start again: a new session");
        assert_eq!(r.gpu_series(5), vec![0.0]);
    }

    #[test]
    fn medians_and_words() {
        assert_eq!(median(&mut []), None);
        assert_eq!(median(&mut [3.0, 1.0, 2.0]), Some(2.0));
        assert_eq!(median(&mut [4.0, 1.0, 2.0, 3.0]), Some(2.5));
        let w = reason_in_words("mask.eye_unknown");
        assert!(w.starts_with("eye_unknown: the pass renders into an image the layer cannot tie to an eye"), "{w}");
        assert!(reason_in_words("vrs.unsupported").starts_with("unsupported: the device has no attachment fragment shading rate"));
    }
}
