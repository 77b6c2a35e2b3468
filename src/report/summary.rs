//! `stereoshim stats`: the layer's stats file (`stats.file`, one JSON line per frame) summarised
//! per second of the session (frames, what each feature did and saved, why it did not apply), or
//! flattened to CSV, one row per frame. Pure: the command reads the file and prints.
#![forbid(unsafe_code)]

use serde_json::Value;
use std::collections::BTreeMap;

/// What the layer did in one second of frames (by the frames' `time`).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Second {
    /// Whole seconds since the first frame read.
    pub second: u64,
    pub frames: u64,
    pub passes_masked: u64,
    pub pixels_masked: u64,
    pub rdm_passes: u64,
    pub rdm_pixels_skipped: u64,
    pub vrs_passes: u64,
    pub far_field_pixels_reused: u64,
    /// `feature.reason` → passes not applied for it.
    pub not_applied: BTreeMap<String, u64>,
    /// Masked passes by how their target was tied to an eye (`mask_by_source`: swapchain,
    /// transfer, walk, fallback).
    pub masked_by: BTreeMap<String, u64>,
    /// Mean layer-side GPU busy time of the timed frames (`stats.gpu_time`), ms.
    pub gpu_busy_ms: Option<f64>,
    gpu_sum: f64,
    gpu_n: u64,
}

/// One frame's line, read: its time and its counters.
#[derive(Clone, Debug)]
pub struct Frame {
    pub frame: u64,
    /// Seconds since the Unix epoch at its `xrEndFrame`.
    pub time: f64,
    pub value: Value,
}

fn u(v: &Value, path: &[&str]) -> u64 {
    path.iter().try_fold(v, |v, k| v.get(k)).and_then(Value::as_u64).unwrap_or(0)
}

/// The sum of a `{view: n}` map.
fn sum_map(v: &Value, path: &[&str]) -> u64 {
    path.iter().try_fold(v, |v, k| v.get(k)).and_then(Value::as_object).map_or(0, |m| m.values().filter_map(Value::as_u64).sum())
}

/// Every not-applied reason of a frame, as `feature.reason` → count.
fn reasons(v: &Value) -> BTreeMap<String, u64> {
    let mut out = BTreeMap::new();
    for (feature, path) in [("mask", &["not_masked"][..]), ("rdm", &["rdm", "not_applied"]), ("vrs", &["vrs", "not_applied"]), ("far_field", &["far_field", "not_applied"])] {
        if let Some(m) = path.iter().try_fold(v, |v, k| v.get(k)).and_then(Value::as_object) {
            for (reason, n) in m {
                *out.entry(format!("{feature}.{reason}")).or_insert(0) += n.as_u64().unwrap_or(0);
            }
        }
    }
    out
}

/// Masked passes by source (`mask_by_source`).
fn sources(v: &Value) -> BTreeMap<String, u64> {
    v.get("mask_by_source").and_then(Value::as_object).map_or_else(BTreeMap::new, |m| m.iter().map(|(k, n)| (k.clone(), n.as_u64().unwrap_or(0))).collect())
}

/// `k=n` pairs joined by `sep`, or `-` when there are none.
fn pairs(m: &BTreeMap<String, u64>, sep: &str, none: &str) -> String {
    if m.is_empty() {
        return none.to_string();
    }
    m.iter().map(|(k, n)| format!("{k}={n}")).collect::<Vec<_>>().join(sep)
}

/// Reads one line; an empty line is none, anything else unreadable is an error naming why.
pub fn parse_line(line: &str) -> Result<Option<Frame>, String> {
    if line.trim().is_empty() {
        return Ok(None);
    }
    let value: Value = serde_json::from_str(line).map_err(|e| format!("not a JSON line: {e}"))?;
    let frame = value.get("frame").and_then(Value::as_u64).ok_or("no \"frame\" number")?;
    let time = value.get("time").and_then(Value::as_f64).ok_or("no \"time\" (written by stereoshim from this version on)")?;
    Ok(Some(Frame { frame, time, value }))
}

/// Adds frames to per-second totals, in file order.
#[derive(Debug, Default)]
pub struct Summary {
    start: Option<f64>,
    pub seconds: Vec<Second>,
}

impl Summary {
    pub fn add(&mut self, f: &Frame) {
        let start = *self.start.get_or_insert(f.time);
        let second = (f.time - start).max(0.0) as u64;
        if !matches!(self.seconds.last(), Some(s) if s.second == second) {
            self.seconds.push(Second { second, ..Default::default() });
        }
        let s = self.seconds.last_mut().expect("pushed above");
        let v = &f.value;
        s.frames += 1;
        s.passes_masked += u(v, &["passes_masked"]);
        s.pixels_masked += sum_map(v, &["pixels_masked"]);
        s.rdm_passes += u(v, &["rdm", "passes"]);
        s.rdm_pixels_skipped += sum_map(v, &["rdm", "pixels_skipped"]);
        s.vrs_passes += u(v, &["vrs", "passes"]);
        s.far_field_pixels_reused += u(v, &["far_field", "pixels_reused"]);
        for (k, n) in reasons(v) {
            *s.not_applied.entry(k).or_insert(0) += n;
        }
        for (k, n) in sources(v) {
            *s.masked_by.entry(k).or_insert(0) += n;
        }
        if let Some(busy) = v.get("gpu_ms").and_then(|g| g.get("busy")).and_then(Value::as_f64) {
            s.gpu_sum += busy;
            s.gpu_n += 1;
            s.gpu_busy_ms = Some(s.gpu_sum / s.gpu_n as f64);
        }
    }
}

/// The table's header line.
pub const TABLE_HEADER: &str = "second  frames  passes_masked  pixels_masked  rdm_passes  rdm_pixels_skipped  vrs_passes  far_field_pixels_reused  gpu_busy_ms  masked_by  not_applied";

/// One second as a table line.
pub fn table_line(s: &Second) -> String {
    let reasons: Vec<String> = s.not_applied.iter().map(|(k, n)| format!("{k}={n}")).collect();
    format!(
        "{:>6}  {:>6}  {:>13}  {:>13}  {:>10}  {:>18}  {:>10}  {:>23}  {:>11}  {}  {}",
        s.second,
        s.frames,
        s.passes_masked,
        s.pixels_masked,
        s.rdm_passes,
        s.rdm_pixels_skipped,
        s.vrs_passes,
        s.far_field_pixels_reused,
        s.gpu_busy_ms.map_or("-".to_string(), |g| format!("{g:.3}")),
        pairs(&s.masked_by, ",", "-"),
        if reasons.is_empty() { "-".to_string() } else { reasons.join(",") }
    )
}

/// The CSV header (one row per frame).
pub const CSV_HEADER: &str = "frame,time,mask_enabled,foveation_enabled,far_field_enabled,passes_masked,pixels_masked,rdm_passes,rdm_pixels_skipped,vrs_passes,far_field_pixels_reused,gpu_busy_ms,masked_by,not_applied";

/// One frame as a CSV row; the reasons in one field, `feature.reason=n` joined by `;` (no commas
/// or quotes appear in reason names, so the field needs no quoting).
pub fn csv_row(f: &Frame) -> String {
    let v = &f.value;
    let b = |k: &str| v.get(k).and_then(Value::as_bool).map_or(String::new(), |b| b.to_string());
    let reasons: Vec<String> = reasons(v).into_iter().map(|(k, n)| format!("{k}={n}")).collect();
    format!(
        "{},{:.6},{},{},{},{},{},{},{},{},{},{},{},{}",
        f.frame,
        f.time,
        b("mask_enabled"),
        b("foveation_enabled"),
        b("far_field_enabled"),
        u(v, &["passes_masked"]),
        sum_map(v, &["pixels_masked"]),
        u(v, &["rdm", "passes"]),
        sum_map(v, &["rdm", "pixels_skipped"]),
        u(v, &["vrs", "passes"]),
        u(v, &["far_field", "pixels_reused"]),
        v.get("gpu_ms").and_then(|g| g.get("busy")).and_then(Value::as_f64).map_or(String::new(), |g| format!("{g}")),
        pairs(&sources(v), ";", ""),
        reasons.join(";")
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn line(frame: u64, time: f64, masked: u64, reason: Option<&str>) -> String {
        let not = reason.map_or(serde_json::json!({}), |r| serde_json::json!({ r: 2 }));
        serde_json::json!({
            "frame": frame, "time": time, "mask_enabled": true, "foveation_enabled": true, "far_field_enabled": false,
            "passes_masked": 2, "pixels_masked": {"0": masked, "1": masked}, "not_masked": not, "mask_by_source": {"walk": 2},
            "rdm": {"passes": 2, "pixels_skipped": {"0": 10, "1": 10}, "not_applied": {}},
            "vrs": {"passes": 0, "not_applied": {}},
            "far_field": {"pixels_reused": 5, "not_applied": {}},
            "gpu_ms": {"busy": 2.0, "span": 2.5, "submissions": 2, "untimed": 0},
        })
        .to_string()
    }

    #[test]
    fn frames_are_summed_per_second() {
        let mut s = Summary::default();
        for (i, t) in [100.0, 100.4, 100.99, 101.0, 102.5].iter().enumerate() {
            s.add(&parse_line(&line(i as u64, *t, 100, (i == 4).then_some("eye_unknown"))).unwrap().unwrap());
        }
        let sec: Vec<(u64, u64, u64)> = s.seconds.iter().map(|x| (x.second, x.frames, x.pixels_masked)).collect();
        assert_eq!(sec, vec![(0, 3, 600), (1, 1, 200), (2, 1, 200)]);
        assert_eq!(s.seconds[0].rdm_pixels_skipped, 60);
        assert_eq!(s.seconds[0].far_field_pixels_reused, 15);
        assert_eq!(s.seconds[0].gpu_busy_ms, Some(2.0));
        assert_eq!(s.seconds[2].not_applied, BTreeMap::from([("mask.eye_unknown".to_string(), 2)]));
        assert!(table_line(&s.seconds[2]).ends_with("walk=2  mask.eye_unknown=2"), "{}", table_line(&s.seconds[2]));
        assert_eq!(s.seconds[0].masked_by, BTreeMap::from([("walk".to_string(), 6)]));
    }

    #[test]
    fn csv_rows_flatten_a_frame() {
        let f = parse_line(&line(7, 12.5, 3, Some("no_depth"))).unwrap().unwrap();
        assert_eq!(csv_row(&f), "7,12.500000,true,true,false,2,6,2,20,0,5,2,walk=2,mask.no_depth=2");
        assert_eq!(CSV_HEADER.split(',').count(), csv_row(&f).split(',').count());
    }

    #[test]
    fn bad_lines_say_why() {
        assert_eq!(parse_line("  ").unwrap().map(|f| f.frame), None);
        assert!(parse_line("{").unwrap_err().contains("JSON"));
        assert!(parse_line(r#"{"time": 1.0}"#).unwrap_err().contains("frame"));
        assert!(parse_line(r#"{"frame": 1}"#).unwrap_err().contains("time"));
    }
}
