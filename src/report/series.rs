//! What `stereoshim stats --plot` draws, taken from the stats file's frames: per frame its GPU
//! time, each feature's savings and passes, and the frames where a live setting changed (so an
//! A/B run shows its phases). Pure: `report::plot` draws it.
#![forbid(unsafe_code)]

use super::summary::Frame;
use serde_json::Value;

/// The pixel savings drawn, by legend, in the order of `Series::pixels`. VRS saves shading, not
/// pixels, and records no pixel count (only its passes), so it is among `PASS_LINES` only.
pub const PIXEL_LINES: [&str; 4] = ["masked (mask)", "skipped (RDM)", "reused (far field)", "not rendered (upscale: displayed - rendered)"];

/// The per-frame pass counts drawn.
pub const PASS_LINES: [&str; 4] = ["masked", "RDM", "VRS (lower shading rate)", "upscaled"];

/// A live setting switched at a frame.
#[derive(Clone, Debug, PartialEq)]
pub struct Change {
    /// Seconds since the first frame.
    pub x: f64,
    pub frame: u64,
    /// What changed, e.g. "mask on, foveation off", or "new session" when the frame numbers
    /// start again (a file appended by several runs).
    pub label: String,
}

/// The series of a stats file, one entry per frame read, in file order.
#[derive(Clone, Debug, Default)]
pub struct Series {
    /// Seconds since the first frame (x of every series). Time, not frame numbers: a file
    /// appended by several sessions numbers each from 0 again.
    pub x: Vec<f64>,
    /// `gpu_ms.busy`: None where the frame was not timed (`stats.gpu_time` off, or `null`).
    pub gpu_ms: Vec<Option<f64>>,
    /// Pixels per frame, in `PIXEL_LINES` order.
    pub pixels: [Vec<f64>; 4],
    /// Passes per frame, in `PASS_LINES` order.
    pub passes: [Vec<f64>; 4],
    /// The settings on at the first frame (by their short name, e.g. "mask").
    pub start_on: Vec<String>,
    pub changes: Vec<Change>,
    start: Option<f64>,
    last_frame: Option<u64>,
    /// The live settings of the last frame, by key (`mask_enabled`, ...), as last seen.
    settings: Vec<(String, bool)>,
}

fn num(v: &Value, path: &[&str]) -> Option<f64> {
    path.iter().try_fold(v, |v, k| v.get(k)).and_then(Value::as_f64)
}

fn u(v: &Value, path: &[&str]) -> f64 {
    num(v, path).unwrap_or(0.0)
}

/// The sum of a `{view: n}` map (per-view pixel counts).
fn sum_map(v: &Value, path: &[&str]) -> f64 {
    path.iter().try_fold(v, |v, k| v.get(k)).and_then(Value::as_object).map_or(0.0, |m| m.values().filter_map(Value::as_f64).sum())
}

/// The frame's live settings: every top-level boolean `*_enabled` field (`mask_enabled`,
/// `foveation_enabled`, `far_field_enabled`, `overlay_enabled`, `upscale_enabled`, and whatever
/// a later version records the same way), sorted by key.
fn settings(v: &Value) -> Vec<(String, bool)> {
    let mut out: Vec<(String, bool)> = v
        .as_object()
        .into_iter()
        .flatten()
        .filter_map(|(k, v)| Some((k.strip_suffix("_enabled")?.to_string(), v.as_bool()?)))
        .collect();
    out.sort();
    out
}

impl Series {
    pub fn add(&mut self, f: &Frame) {
        let v = &f.value;
        let start = *self.start.get_or_insert(f.time);
        let x = (f.time - start).max(0.0);
        self.x.push(x);
        self.gpu_ms.push(num(v, &["gpu_ms", "busy"]));
        let upscale_saved = (u(v, &["upscale", "display_px"]) - u(v, &["upscale", "rendered_px"])).max(0.0);
        let pixels = [sum_map(v, &["pixels_masked"]), sum_map(v, &["rdm", "pixels_skipped"]), u(v, &["far_field", "pixels_reused"]), upscale_saved];
        let passes = [u(v, &["passes_masked"]), u(v, &["rdm", "passes"]), u(v, &["vrs", "passes"]), u(v, &["upscale", "passes"])];
        for (s, p) in self.pixels.iter_mut().zip(pixels) {
            s.push(p);
        }
        for (s, p) in self.passes.iter_mut().zip(passes) {
            s.push(p);
        }

        let now = settings(v);
        let mut label = Vec::new();
        if self.last_frame.is_some_and(|last| f.frame <= last) {
            label.push("new session".to_string());
        }
        if self.last_frame.is_none() {
            self.start_on = now.iter().filter(|(_, on)| *on).map(|(k, _)| k.clone()).collect();
        }
        for (k, on) in now {
            // A key a frame lacks (an older writer) keeps its last value: no change is invented.
            match self.settings.iter_mut().find(|(known, _)| *known == k) {
                Some((_, was)) if *was != on => {
                    label.push(format!("{k} {}", if on { "on" } else { "off" }));
                    *was = on;
                }
                Some(_) => {}
                None => self.settings.push((k, on)),
            }
        }
        if !label.is_empty() {
            self.changes.push(Change { x, frame: f.frame, label: label.join(", ") });
        }
        self.last_frame = Some(f.frame);
    }

    pub fn len(&self) -> usize {
        self.x.len()
    }

    pub fn is_empty(&self) -> bool {
        self.x.is_empty()
    }

    /// Seconds from the first frame to the last.
    pub fn duration(&self) -> f64 {
        self.x.last().copied().unwrap_or(0.0)
    }
}

/// A stretch of frames between two setting changes (or the file's ends) and its mean GPU time,
/// so an A/B run's phases compare at a glance however noisy the frames are.
#[derive(Clone, Debug, PartialEq)]
pub struct Phase {
    /// Seconds since the first frame: the phase's first frame and the next phase's first (or the
    /// last frame).
    pub from: f64,
    pub to: f64,
    /// Mean `gpu_ms.busy` of its timed frames; None when none was timed.
    pub gpu_ms: Option<f64>,
}

impl Series {
    /// The phases between the setting changes, in order.
    pub fn phases(&self) -> Vec<Phase> {
        let mut out = Vec::new();
        let mut start = 0;
        let bounds = self.changes.iter().map(|c| self.x.partition_point(|x| *x < c.x)).chain(std::iter::once(self.len()));
        for end in bounds {
            if end <= start {
                continue;
            }
            let timed: Vec<f64> = self.gpu_ms[start..end].iter().flatten().copied().collect();
            let gpu_ms = (!timed.is_empty()).then(|| timed.iter().sum::<f64>() / timed.len() as f64);
            let to = self.x.get(end).copied().unwrap_or_else(|| self.duration());
            out.push(Phase { from: self.x[start], to, gpu_ms });
            start = end;
        }
        out
    }
}

/// Splits a series with gaps into runs of points `(x, y)` where y is known, so a line is not
/// drawn across frames that were not measured.
pub fn runs(x: &[f64], y: &[Option<f64>]) -> Vec<Vec<(f64, f64)>> {
    let mut out: Vec<Vec<(f64, f64)>> = Vec::new();
    let mut open = false;
    for (x, y) in x.iter().zip(y) {
        match y {
            Some(y) if open => out.last_mut().expect("open run").push((*x, *y)),
            Some(y) => {
                out.push(vec![(*x, *y)]);
                open = true;
            }
            None => open = false,
        }
    }
    out
}

/// A unit for pixel counts whose largest value is `max`: the divisor and its name, so the axis
/// reads "12.5 Mpx" rather than "12500000".
pub fn pixel_unit(max: f64) -> (f64, &'static str) {
    if max >= 1e6 {
        (1e6, "Mpx")
    } else if max >= 1e3 {
        (1e3, "kpx")
    } else {
        (1.0, "px")
    }
}

/// The top of an axis for data up to `max`: a little headroom above it, and a visible range when
/// everything is 0.
pub fn axis_top(max: f64) -> f64 {
    if max > 0.0 && max.is_finite() {
        max * 1.1
    } else {
        1.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::report::summary::parse_line;

    fn frame(n: u64, mask: bool, fov: bool, gpu: Option<f64>) -> Frame {
        let mut v = serde_json::json!({
            "frame": n, "time": 100.0 + n as f64 / 90.0, "mask_enabled": mask, "foveation_enabled": fov, "far_field_enabled": false,
            "passes_masked": if mask { 2 } else { 0 }, "pixels_masked": {"0": if mask { 1000 } else { 0 }, "1": if mask { 500 } else { 0 }},
            "rdm": {"passes": 1, "pixels_skipped": {"0": 40}}, "vrs": {"passes": 3},
            "far_field": {"pixels_reused": 7},
            "upscale": {"passes": 2, "rendered_px": 600, "display_px": 1000},
        });
        v["gpu_ms"] = gpu.map_or(Value::Null, |g| serde_json::json!({"busy": g, "span": g}));
        parse_line(&v.to_string()).unwrap().unwrap()
    }

    #[test]
    fn frames_become_points() {
        let mut s = Series::default();
        s.add(&frame(0, true, false, Some(10.0)));
        s.add(&frame(1, true, false, None));
        assert_eq!(s.len(), 2);
        assert!((s.x[1] - 1.0 / 90.0).abs() < 1e-9, "{:?}", s.x);
        assert_eq!(s.gpu_ms, [Some(10.0), None]);
        assert_eq!(s.pixels.each_ref().map(|p| p[0]), [1500.0, 40.0, 7.0, 400.0]);
        assert_eq!(s.passes.each_ref().map(|p| p[0]), [2.0, 1.0, 3.0, 2.0]);
        assert_eq!(s.start_on, ["mask"]);
        assert!(s.changes.is_empty());
    }

    #[test]
    fn setting_changes_are_marked_once_where_they_happen() {
        let mut s = Series::default();
        for n in 0..10 {
            s.add(&frame(n, n >= 4, (4..7).contains(&n), Some(1.0)));
        }
        let got: Vec<(u64, &str)> = s.changes.iter().map(|c| (c.frame, c.label.as_str())).collect();
        assert_eq!(got, [(4, "foveation on, mask on"), (7, "foveation off")]);
        assert!(s.start_on.is_empty());
        assert!((s.changes[0].x - 4.0 / 90.0).abs() < 1e-9);
    }

    #[test]
    fn a_missing_setting_is_no_change_and_a_restart_is_one() {
        let mut s = Series::default();
        s.add(&frame(0, true, false, None));
        let mut old = serde_json::json!({"frame": 1, "time": 101.0});
        s.add(&parse_line(&old.to_string()).unwrap().unwrap());
        assert!(s.changes.is_empty(), "{:?}", s.changes);
        old["frame"] = 0.into();
        old["time"] = 200.0.into();
        old["mask_enabled"] = false.into();
        s.add(&parse_line(&old.to_string()).unwrap().unwrap());
        assert_eq!(s.changes.len(), 1);
        assert_eq!(s.changes[0].label, "new session, mask off");
        assert_eq!(s.duration(), 100.0);
    }

    #[test]
    fn phases_average_between_changes() {
        let mut s = Series::default();
        for n in 0..10 {
            let gpu = match n {
                0..4 => Some(10.0 + n as f64),
                7 => None,
                _ => Some(4.0),
            };
            s.add(&frame(n, n >= 4, false, gpu));
        }
        let p = s.phases();
        assert_eq!(p.len(), 2, "{p:?}");
        assert_eq!(p[0].gpu_ms, Some(11.5));
        assert_eq!(p[1].gpu_ms, Some(4.0), "the untimed frame 7 is left out");
        assert!((p[0].to - 4.0 / 90.0).abs() < 1e-9 && p[1].from == p[0].to && p[1].to == s.duration(), "{p:?}");
        let mut untimed = Series::default();
        untimed.add(&frame(0, false, false, None));
        assert_eq!(untimed.phases(), [Phase { from: 0.0, to: 0.0, gpu_ms: None }]);
    }

    #[test]
    fn gaps_split_lines() {
        let x = [0.0, 1.0, 2.0, 3.0, 4.0];
        let y = [Some(1.0), Some(2.0), None, Some(4.0), None];
        assert_eq!(runs(&x, &y), vec![vec![(0.0, 1.0), (1.0, 2.0)], vec![(3.0, 4.0)]]);
        assert!(runs(&x, &[None; 5]).is_empty());
    }

    #[test]
    fn units_and_axes() {
        assert_eq!(pixel_unit(999.0), (1.0, "px"));
        assert_eq!(pixel_unit(25_000.0), (1e3, "kpx"));
        assert_eq!(pixel_unit(3e6), (1e6, "Mpx"));
        assert_eq!(axis_top(0.0), 1.0);
        assert_eq!(axis_top(f64::NAN), 1.0);
        assert!((axis_top(10.0) - 11.0).abs() < 1e-9);
    }
}
