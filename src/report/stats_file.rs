//! The layer's own per-frame statistics (`stats.file`): one JSON line per `xrEndFrame`, so that a
//! benchmark or a test can check what the layer did in each frame against what the app measured
//! (shaded fragments, GPU time) for the same frame number.
//!
//! With `stats.gpu_time` on, a frame's line waits (`core::gpu_time::Waiting`) until the layer's
//! GPU timer has read back that frame's timestamps, so every line carries its own frame's
//! `gpu_ms`; lines stay in frame order, and one whose time does not come within `GPU_WAIT_FRAMES`
//! frames, or by the end of the session, is written with `"gpu_ms": null`.
#![forbid(unsafe_code)]

use crate::core::gpu_time::{GpuFrameTime, Waiting};
use crate::core::stats::FrameStats;
use std::fs::File;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// One frame as written to the file.
#[derive(Clone, Debug)]
pub struct FrameRecord {
    /// 0-based number of the frame (count of successful `xrEndFrame`s before it).
    pub frame: u64,
    /// Seconds since the Unix epoch at the frame's `xrEndFrame` (`stereoshim stats` groups frames
    /// by it).
    pub time: f64,
    /// The live `mask.enabled` the frame was recorded under.
    pub mask_enabled: bool,
    /// The live `foveation.enabled` (benchmarks switch it as `{feature}_enabled`).
    pub foveation_enabled: bool,
    /// The live `far_field.enabled`.
    pub far_field_enabled: bool,
    /// The live `overlay.enabled` (so `examples/bench --feature overlay` can time it A/B).
    pub overlay_enabled: bool,
    /// Every feature's counters (each writes its own fields).
    pub stats: FrameStats,
    /// The foveation the frame was recorded with (empty when off).
    pub fovea: Vec<crate::core::views::FoveaView>,
    /// Where the fovea centres came from: "Fixed", "Gaze" or "Held" (None when off).
    pub fovea_source: Option<String>,
    /// Whether the layer's Vulkan half tracks the session's device (None: no session known).
    /// False means nothing enabled can be applied.
    pub vulkan_half: Option<bool>,
    /// `stats.gpu_time`: None when the timer was off (no field), Some(None) when the frame's time
    /// could not be had (`null`), else the layer-side GPU time of the frame.
    pub gpu_ms: Option<Option<GpuFrameTime>>,
    /// The upscale this frame (None: no swapchain of the session is interposed).
    pub upscale: Option<crate::core::views::UpscaleFrame>,
    /// The OpenXR features' own fields (`XrFeature::frame_stats`).
    pub extra: Vec<(&'static str, serde_json::Value)>,
}

impl FrameRecord {
    pub fn to_json(&self) -> String {
        let mut record = serde_json::Map::new();
        record.insert("frame".into(), self.frame.into());
        record.insert("time".into(), self.time.into());
        record.insert("mask_enabled".into(), self.mask_enabled.into());
        record.insert("foveation_enabled".into(), self.foveation_enabled.into());
        record.insert("far_field_enabled".into(), self.far_field_enabled.into());
        record.insert("overlay_enabled".into(), self.overlay_enabled.into());
        record.insert(
            "fovea".into(),
            self.fovea.iter().map(|f| serde_json::json!({"view": f.view, "center": f.center, "inner_deg": f.inner_deg, "middle_deg": f.middle_deg})).collect::<Vec<_>>().into(),
        );
        record.insert("fovea_source".into(), self.fovea_source.clone().into());
        record.insert("vulkan_half".into(), self.vulkan_half.into());
        self.stats.write_json(&mut record);
        // Whether this frame was upscaled (`examples/bench --feature upscale` switches on it).
        record.insert("upscale_enabled".into(), self.upscale.is_some().into());
        for (k, v) in &self.extra {
            record.insert((*k).into(), v.clone());
        }
        if let Some(u) = &self.upscale {
            record.insert("upscale".into(), serde_json::json!({"passes": u.passes, "rendered_px": u.rendered_px, "display_px": u.display_px, "gpu_ms": u.gpu_ms, "phases_ms": u.phases_ms}));
        }
        if let Some(gpu) = &self.gpu_ms {
            let value = gpu.map_or(serde_json::Value::Null, |t| {
                serde_json::json!({"busy": t.busy_ms, "span": t.span_ms, "submissions": t.submissions, "untimed": t.untimed})
            });
            record.insert("gpu_ms".into(), value);
        }
        serde_json::Value::Object(record).to_string()
    }
}

/// Appends records to the configured file; the file is (re)opened when the configured path
/// changes, and a file that cannot be written is reported once and then left alone.
#[derive(Debug, Default)]
pub struct Writer {
    open: Mutex<Option<(PathBuf, Option<File>)>>,
}

/// Appends `line` to a capped stream file (`stereoshim top`'s): opened for each line, so a file
/// removed when the watching stopped is made anew when it starts again, and emptied first when
/// it has grown past `max_bytes` (its reader starts over when the file is shorter than it read).
fn append_capped(path: &Path, line: &str, max_bytes: u64) -> std::io::Result<()> {
    let mut file = std::fs::OpenOptions::new().create(true).append(true).open(path)?;
    if file.metadata()?.len() > max_bytes {
        file.set_len(0)?;
    }
    file.write_all(line.as_bytes())
}

impl Writer {
    pub fn write(&self, path: &str, record: &FrameRecord) {
        if path.is_empty() {
            return;
        }
        let mut open = self.open.lock().unwrap_or_else(|e| e.into_inner());
        if open.as_ref().is_none_or(|(p, _)| p != Path::new(path)) {
            let file = std::fs::OpenOptions::new().create(true).append(true).open(path);
            if let Err(e) = &file {
                tracing::warn!("stats.file {path}: {e}; no statistics written");
            }
            *open = Some((PathBuf::from(path), file.ok()));
        }
        if let Some((_, Some(file))) = open.as_mut() {
            // One write per line: readers tailing the file never see half a record.
            let line = record.to_json() + "\n";
            if let Err(e) = file.write_all(line.as_bytes()) {
                tracing::warn!("stats.file {path}: {e}; no further statistics written");
                *open = Some((PathBuf::from(path), None));
            }
        }
    }
}

/// How many frames a line waits for its GPU time at most (results normally arrive one to three
/// frames later).
pub const GPU_WAIT_FRAMES: u64 = 16;

/// Where a frame's line goes: the configured `stats.file` (empty: none) and the streams the
/// features asked for (`XrFeature::stats_stream`).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Outputs {
    pub stats_file: String,
    pub streams: Vec<PathBuf>,
}

impl Outputs {
    fn is_empty(&self) -> bool {
        self.stats_file.is_empty() && self.streams.is_empty()
    }
}

/// The process's `stats.file` output: records waiting for their GPU time, then the writer.
#[derive(Debug)]
pub struct Sink {
    writer: Writer,
    waiting: Mutex<Waiting<(Outputs, FrameRecord)>>,
}

/// The one sink of the process (both halves feed it).
pub fn sink() -> &'static Sink {
    static SINK: std::sync::OnceLock<Sink> = std::sync::OnceLock::new();
    SINK.get_or_init(|| Sink { writer: Writer::default(), waiting: Mutex::new(Waiting::new(GPU_WAIT_FRAMES)) })
}

impl Sink {
    /// Frame `record.frame` ended; `times`: GPU times that completed meanwhile (of it or earlier
    /// frames); `wants_time`: the timer ran while the frame was recorded. Writes every line that
    /// is ready, in frame order.
    pub fn frame(&self, outputs: Outputs, mut record: FrameRecord, wants_time: bool, times: &[(u64, GpuFrameTime)]) {
        let ready = {
            let mut w = self.waiting.lock().unwrap_or_else(|e| e.into_inner());
            if w.is_empty() && !wants_time && times.is_empty() {
                // The common case (timer off): straight through.
                drop(w);
                self.emit(&outputs, &record);
                return;
            }
            if wants_time {
                record.gpu_ms = Some(None);
            }
            // Pushed before the times go in: the frame's own time may be among them (an idle GPU
            // finishes a frame before its xrEndFrame).
            w.push(record.frame, wants_time, (outputs, record));
            w.times(times);
            w.ready(false)
        };
        self.write(ready);
    }

    /// The session ends: times that completed meanwhile, then every waiting line.
    pub fn finish(&self, times: &[(u64, GpuFrameTime)]) {
        let ready = {
            let mut w = self.waiting.lock().unwrap_or_else(|e| e.into_inner());
            w.times(times);
            w.ready(true)
        };
        self.write(ready);
    }

    fn write(&self, ready: Vec<((Outputs, FrameRecord), Option<GpuFrameTime>)>) {
        for ((outputs, mut record), time) in ready {
            if record.gpu_ms.is_some() || time.is_some() {
                record.gpu_ms = Some(time);
            }
            self.emit(&outputs, &record);
        }
    }

    fn emit(&self, outputs: &Outputs, record: &FrameRecord) {
        if outputs.is_empty() {
            return;
        }
        self.writer.write(&outputs.stats_file, record);
        if outputs.streams.is_empty() {
            return;
        }
        let line = record.to_json() + "\n";
        for stream in &outputs.streams {
            if let Err(e) = append_capped(stream, &line, crate::core::live::STREAM_MAX_BYTES) {
                // Every frame would say it again: the stream's reader notices the silence.
                tracing::debug!("live stream {}: {e}", stream.display());
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn records_are_json_lines() {
        use crate::features::foveation::{rdm::rules::RdmFrameStats, vrs::rules::VrsFrameStats};
        use crate::features::mask::rules::MaskFrameStats;
        let mut stats = crate::registry::empty_stats();
        *stats.get_mut::<MaskFrameStats>().unwrap() = MaskFrameStats {
            passes_masked: 2,
            not_masked: [("no_depth_attachment", 1)].into_iter().collect(),
            pixels_masked: [(0, 1234)].into_iter().collect(),
            by_source: [("walk", 2)].into_iter().collect(),
        };
        *stats.get_mut::<RdmFrameStats>().unwrap() = RdmFrameStats { passes: 1, quads_skipped: [(1, 77)].into_iter().collect(), ..Default::default() };
        *stats.get_mut::<VrsFrameStats>().unwrap() = VrsFrameStats { passes: 3, ..Default::default() };
        let r = FrameRecord { frame: 7, time: 1.5, mask_enabled: true, foveation_enabled: true, far_field_enabled: false, overlay_enabled: false, stats, fovea: Vec::new(), fovea_source: None, vulkan_half: Some(true), gpu_ms: None, upscale: None, extra: vec![("view_fov_cut", true.into())] };
        let v: serde_json::Value = serde_json::from_str(&r.to_json()).unwrap();
        assert_eq!(v["frame"], 7);
        assert_eq!(v["vulkan_half"], true);
        assert_eq!(v["overlay_enabled"], false);
        assert_eq!(v["passes_masked"], 2);
        assert_eq!(v["not_masked"]["no_depth_attachment"], 1);
        assert_eq!(v["pixels_masked"]["0"], 1234);
        assert_eq!(v["rdm"]["passes"], 1);
        assert_eq!(v["rdm"]["quads_skipped"]["1"], 77);
        assert_eq!((v["vrs"]["passes"].as_u64(), v["foveation_enabled"].as_bool()), (Some(3), Some(true)));
        assert!(v.get("gpu_ms").is_none(), "timer off: no field");
        let t = GpuFrameTime { busy_ms: 1.5, span_ms: 2.0, submissions: 3, untimed: 0 };
        assert_eq!(serde_json::from_str::<serde_json::Value>(&r.to_json()).unwrap()["view_fov_cut"], true);
        let timed: serde_json::Value = serde_json::from_str(&FrameRecord { gpu_ms: Some(Some(t)), ..r.clone() }.to_json()).unwrap();
        assert_eq!((timed["gpu_ms"]["busy"].as_f64(), timed["gpu_ms"]["span"].as_f64(), timed["gpu_ms"]["submissions"].as_u64()), (Some(1.5), Some(2.0), Some(3)));
        let lost: serde_json::Value = serde_json::from_str(&FrameRecord { gpu_ms: Some(None), ..r.clone() }.to_json()).unwrap();
        assert!(lost["gpu_ms"].is_null());

        let dir = std::env::temp_dir().join(format!("stereoshim-stats-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("s.jsonl");
        let w = Writer::default();
        w.write(path.to_str().unwrap(), &r);
        w.write(path.to_str().unwrap(), &FrameRecord { frame: 8, ..r.clone() });
        let text = std::fs::read_to_string(&path).unwrap();
        assert_eq!(text.lines().count(), 2);
        std::fs::remove_dir_all(&dir).ok();
    }
}
