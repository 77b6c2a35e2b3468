//! What `stereoshim run` tells a person when the app exits: whether the layer was loaded, which
//! eye passes it found and how, what each feature applied and saved, and where the details are.
//! Built from the part of the layer's log this run appended (its device stats lines, whose raw
//! counters stay in the log) and, when `stats.file` is set, that file's lines for GPU time. Pure
//! but for `at_exit`, which reads the two files; the command prints the lines to stderr (the
//! app's stdout stays the app's).
#![forbid(unsafe_code)]

use std::collections::BTreeMap;
use std::path::Path;

/// What one run's log lines say.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RunLog {
    /// `pid` and executable of each process the layer was loaded into.
    pub loaded: Vec<(u64, String)>,
    /// The app's name as it told OpenXR (`openxr stats: ... (app "NAME")`).
    pub app: Option<String>,
    pub frames: u64,
    /// Every device's last counters (a device's lines are cumulative), summed over devices.
    pub counters: BTreeMap<String, u64>,
    /// `reason` → views the far field did not apply to (its counters are one map, not pairs).
    pub far_field_not_applied: BTreeMap<String, u64>,
    /// The upscale's sizes (`upscale: told the app [..] for display sizes [..] (scale s)`).
    pub upscale: Option<String>,
    /// WARN and ERROR lines' messages, in order (the layer says there why a feature did not apply).
    pub warnings: Vec<String>,
}

/// The counters of a device stats line (`key=n` pairs; other tokens skipped), its device, and the
/// far field's not-applied map.
fn device_counters(pairs: &str) -> (String, BTreeMap<String, u64>, BTreeMap<String, u64>) {
    let mut device = String::new();
    let mut counters = BTreeMap::new();
    for token in pairs.split_whitespace() {
        let Some((k, v)) = token.split_once('=') else { continue };
        if k == "device" {
            device = v.to_string();
        } else if let Ok(n) = v.parse::<u64>() {
            counters.insert(k.to_string(), n);
        }
    }
    // `far_field_not_applied={"reason": n, ...}`: the map's Debug text, which is JSON here.
    let far = pairs
        .split_once("far_field_not_applied=")
        .and_then(|(_, rest)| rest.find('}').map(|end| &rest[..=end]))
        .and_then(|map| serde_json::from_str::<BTreeMap<String, u64>>(map).ok())
        .unwrap_or_default();
    (device, counters, far)
}

/// Reads the log text a run appended.
pub fn read_log(text: &str) -> RunLog {
    let mut r = RunLog::default();
    // Device → its counters and far-field reasons.
    type Totals = (BTreeMap<String, u64>, BTreeMap<String, u64>);
    let mut devices: BTreeMap<String, Totals> = BTreeMap::new();
    for line in text.lines() {
        if let Some(rest) = line.split_once("stereoshim loaded pid=").map(|(_, r)| r) {
            let pid = rest.split_whitespace().next().and_then(|p| p.parse().ok()).unwrap_or(0);
            let exe = rest.split_once("exe=\"").and_then(|(_, e)| e.split_once('"')).map_or(String::new(), |(e, _)| e.to_string());
            r.loaded.push((pid, exe));
        } else if let Some(rest) = line.split_once("openxr stats: ").map(|(_, r)| r) {
            r.frames += rest.split_whitespace().find_map(|t| t.strip_prefix("frames_ended=")).and_then(|n| n.parse::<u64>().ok()).unwrap_or(0);
            if let Some((_, name)) = rest.rsplit_once("(app \"") {
                r.app = Some(name.trim_end_matches(&[')', '"'][..]).to_string());
            }
        } else if let Some(pairs) = line.split_once("vulkan device stats: ").or_else(|| line.split_once("its stats so far: ")).map(|(_, p)| p) {
            // The last line of a device has its totals (a live device's lines come first).
            let (device, counters, far) = device_counters(pairs);
            devices.insert(device, (counters, far));
        } else if let Some(rest) = line.split_once("upscale: told the app ").map(|(_, r)| r) {
            r.upscale = Some(rest.to_string());
        } else if line.contains(" WARN ") || line.contains(" ERROR ") {
            // After the target (`stereoshim::module: `), past any span prefix before it.
            let from = line.find(" stereoshim::").map_or(line, |i| &line[i..]);
            let message = from.split_once(": ").map_or(from, |(_, m)| m);
            r.warnings.push(message.to_string());
        }
    }
    for (counters, far) in devices.into_values() {
        for (k, n) in counters {
            *r.counters.entry(k).or_insert(0) += n;
        }
        for (k, n) in far {
            *r.far_field_not_applied.entry(k).or_insert(0) += n;
        }
    }
    r
}

/// Mean GPU busy time per frame and the frames it covers, from stats-file lines (`gpu_ms.busy`,
/// written when `stats.gpu_time` is on); None when no frame was timed.
pub fn gpu_busy(stats_lines: &str) -> Option<(f64, u64)> {
    let busy: Vec<f64> = stats_lines
        .lines()
        .filter_map(|l| serde_json::from_str::<serde_json::Value>(l).ok())
        .filter_map(|v| v.get("gpu_ms").and_then(|g| g.get("busy")).and_then(serde_json::Value::as_f64))
        .collect();
    (!busy.is_empty()).then(|| (busy.iter().sum::<f64>() / busy.len() as f64, busy.len() as u64))
}

/// `1 234 567`: counts people read at a glance.
fn count(n: u64) -> String {
    let digits: Vec<char> = n.to_string().chars().collect();
    digits.rchunks(3).rev().map(|group| group.iter().collect::<String>()).collect::<Vec<_>>().join(" ")
}

/// `k1 n1, k2 n2` of the counters under `prefix.`, or None when there are none.
fn listed(counters: &BTreeMap<String, u64>, prefix: &str) -> Option<String> {
    let items: Vec<String> = counters.iter().filter_map(|(k, n)| k.strip_prefix(prefix).map(|k| format!("{k} {n}"))).collect();
    (!items.is_empty()).then(|| items.join(", "))
}

/// The lines printed at exit. `program`: what was run; `gpu`: from `gpu_busy`.
pub fn lines(program: &str, log: &RunLog, gpu: Option<(f64, u64)>, log_path: &Path, stats_path: Option<&Path>) -> Vec<String> {
    let c = &log.counters;
    let get = |k: &str| c.get(k).copied();
    let mut out = Vec::new();
    if log.loaded.is_empty() {
        out.push(format!("stereoshim: the layer was not loaded into {program} (no line of this run in its log); `stereoshim doctor` checks why"));
        out.push(format!("  log: {}", log_path.display()));
        return out;
    }
    let app = log.app.clone().unwrap_or_else(|| program.to_string());
    let processes = if log.loaded.len() == 1 { format!("pid {}", log.loaded[0].0) } else { format!("{} processes", log.loaded.len()) };
    out.push(format!("stereoshim: {app} ran {} frame{} with the layer ({processes})", log.frames, if log.frames == 1 { "" } else { "s" }));
    let mut applied = Vec::new();
    if let Some(masked) = get("masked_passes") {
        let how = listed(c, "masked_by.").map_or(String::new(), |h| format!(" (eye passes found by: {h})"));
        applied.push(format!("  hidden-area mask: {} eye passes masked{how}, {} pixels never shaded", count(masked), count(get("masked_pixels").unwrap_or(0))));
        if let Some(why) = listed(c, "not_masked.") {
            applied.push(format!("    passes not masked, by reason: {why}"));
        }
    }
    if let Some(passes) = get("rdm_passes") {
        applied.push(format!("  foveation (RDM): {} eye passes, {} pixels skipped and reconstructed", count(passes), count(get("rdm_pixels_skipped").unwrap_or(0))));
        if let Some(why) = listed(c, "rdm_not_applied.") {
            applied.push(format!("    passes not foveated, by reason: {why}"));
        }
    }
    if let Some(passes) = get("vrs_passes") {
        applied.push(format!("  foveation (VRS): {} eye passes shaded at reduced rates in the periphery", count(passes)));
        if let Some(why) = listed(c, "vrs_not_applied.") {
            applied.push(format!("    passes not foveated, by reason: {why}"));
        }
    }
    if let Some(views) = get("far_field_views_reused") {
        applied.push(format!("  far field: {} views reused the other eye's far pixels, {} pixels", count(views), count(get("far_field_pixels_reused").unwrap_or(0))));
        if !log.far_field_not_applied.is_empty() {
            let why: Vec<String> = log.far_field_not_applied.iter().map(|(k, n)| format!("{k} {n}")).collect();
            applied.push(format!("    views not reused, by reason: {}", why.join(", ")));
        }
    }
    if let Some(sizes) = &log.upscale {
        applied.push(format!("  upscale: told the app {sizes}"));
    }
    if applied.is_empty() {
        out.push("  no feature applied (none enabled: set mask.enabled, foveation.enabled, far_field.enabled or upscale.enabled in the config, or STEREOSHIM_MASK_ENABLED=1 etc.)".into());
    }
    out.extend(applied);
    if let Some((ms, frames)) = gpu {
        out.push(format!("  GPU time: {ms:.3} ms per frame (mean of {frames} timed frames)"));
    }
    if !log.warnings.is_empty() {
        out.push(format!("  {} warning{} in the log, the first: {}", log.warnings.len(), if log.warnings.len() == 1 { "" } else { "s" }, log.warnings[0]));
    }
    out.push(format!("  details: log {}", log_path.display()));
    if let Some(p) = stats_path {
        out.push(format!("  per frame: {} (`stereoshim stats {}`)", p.display(), p.display()));
    }
    out
}

/// What a file gained since it was `from` bytes long (empty when it is missing or shorter: a
/// log rotated or removed meanwhile has nothing of this run's that can be told apart).
fn appended(path: &Path, from: u64) -> String {
    use std::io::{Read, Seek, SeekFrom};
    let mut text = String::new();
    if let Ok(mut f) = std::fs::File::open(path) {
        if f.seek(SeekFrom::Start(from)).is_ok() {
            let mut bytes = Vec::new();
            let _ = f.read_to_end(&mut bytes);
            text = String::from_utf8_lossy(&bytes).into_owned();
        }
    }
    text
}

/// The length of a file now (0 when missing): where this run's lines will start.
pub fn length(path: &Path) -> u64 {
    std::fs::metadata(path).map_or(0, |m| m.len())
}

/// The lines for a run whose log lines start at byte `log_from` of `log` (and stats lines at
/// `stats.1` of `stats.0`). Lines other processes append to the same log meanwhile are counted
/// too: the log is shared, and the layer's lines carry no run id.
pub fn at_exit(program: &str, log: &Path, log_from: u64, stats: Option<(&Path, u64)>) -> Vec<String> {
    let run = read_log(&appended(log, log_from));
    let gpu = stats.and_then(|(p, from)| gpu_busy(&appended(p, from)));
    lines(program, &run, gpu, log, stats.map(|(p, _)| p).filter(|p| p.is_file()))
}

#[cfg(test)]
mod tests {
    use super::*;

    const LOG: &str = r#"2026-11-28T08:11:22.354997Z  INFO ThreadId(01) stereoshim::core::log: stereoshim loaded pid=3649 exe="/t/xr-scene" version="0.1.0"
2026-11-28T08:11:24.0Z  WARN ThreadId(01) stereoshim::features::far_field::vk: far field: no depth range for view 1
2026-11-28T08:11:25.1Z  INFO ThreadId(01) stereoshim::vk::device_line: vulkan device still live at xrDestroySession; its stats so far: render_pass=3 masked_passes=2 masked_pixels=1000 masked_by.swapchain=2 live.images=4 device=0xA
2026-11-28T08:11:25.2Z  INFO ThreadId(01) stereoshim::vk::chain: vulkan device stats: render_pass=6 masked_passes=4 masked_pixels=554444 masked_by.swapchain=4 not_masked.eye_unknown=2 rdm_passes=4 rdm_pixels_skipped=1479632 rdm_not_applied.eye_unknown=2 far_field_views_reused=2 far_field_pixels_reused=458218 far_field_not_applied={"eye_unknown": 2} live.images=0 own.images=4 device=0xA extensions=fragment shading rate: device lacks VK_KHR_fragment_shading_rate
2026-11-28T08:11:25.3Z  INFO ThreadId(01) stereoshim::vk::chain: vulkan device stats: render_pass=1 masked_passes=1 masked_pixels=6 device=0xB
2026-11-28T08:11:25.4Z  INFO ThreadId(01) stereoshim::xr::instance: openxr stats: frames_ended=3 swapchains_created=2 (app "xr-scene")
"#;

    #[test]
    fn reads_each_devices_last_counters() {
        let r = read_log(LOG);
        assert_eq!(r.loaded, vec![(3649, "/t/xr-scene".to_string())]);
        assert_eq!(r.app.as_deref(), Some("xr-scene"));
        assert_eq!(r.frames, 3);
        assert_eq!(r.counters["masked_passes"], 5, "device A's last line (4) and device B's (1), not A's earlier one");
        assert_eq!(r.counters["masked_pixels"], 554_450);
        assert_eq!(r.counters["masked_by.swapchain"], 4);
        assert_eq!(r.far_field_not_applied["eye_unknown"], 2);
        assert!(!r.counters.contains_key("device"));
        assert_eq!(r.warnings, vec!["far field: no depth range for view 1".to_string()]);
    }

    #[test]
    fn says_what_was_found_applied_and_saved_and_where_the_details_are() {
        let text = lines("xr-scene", &read_log(LOG), Some((1.25, 3)), Path::new("/s/stereoshim.log"), Some(Path::new("/s/stats.jsonl"))).join("\n");
        for expected in [
            "stereoshim: xr-scene ran 3 frames with the layer (pid 3649)",
            "hidden-area mask: 5 eye passes masked (eye passes found by: swapchain 4), 554 450 pixels never shaded",
            "passes not masked, by reason: eye_unknown 2",
            "foveation (RDM): 4 eye passes, 1 479 632 pixels skipped and reconstructed",
            "far field: 2 views reused the other eye's far pixels, 458 218 pixels",
            "views not reused, by reason: eye_unknown 2",
            "GPU time: 1.250 ms per frame (mean of 3 timed frames)",
            "1 warning in the log, the first: far field: no depth range",
            "details: log /s/stereoshim.log",
            "per frame: /s/stats.jsonl",
        ] {
            assert!(text.contains(expected), "{expected:?} missing from:\n{text}");
        }
        assert!(!text.contains("live.") && !text.contains("own."), "raw counters stay in the log:\n{text}");
        assert!(!text.contains("VRS"), "no VRS line without its counters:\n{text}");
    }

    #[test]
    fn a_run_without_features_or_without_the_layer_says_so() {
        let plain = "x  INFO ThreadId(01) stereoshim::core::log: stereoshim loaded pid=7 exe=\"/a\" version=\"0.1.0\"\n\
                     x  INFO ThreadId(01) stereoshim::vk::chain: vulkan device stats: render_pass=6 live.images=0 device=0x1\n";
        let text = lines("/a", &read_log(plain), None, Path::new("/l"), None).join("\n");
        assert!(text.contains("ran 0 frames") && text.contains("no feature applied"), "{text}");
        assert!(!text.contains("GPU time") && !text.contains("per frame"), "{text}");
        let text = lines("/a", &read_log(""), None, Path::new("/l"), None).join("\n");
        assert!(text.contains("the layer was not loaded into /a") && text.contains("stereoshim doctor"), "{text}");
    }

    #[test]
    fn gpu_time_is_the_mean_of_the_timed_frames() {
        let stats = "{\"frame\":1,\"gpu_ms\":{\"busy\":1.0}}\n{\"frame\":2,\"gpu_ms\":null}\n{\"frame\":3,\"gpu_ms\":{\"busy\":2.0}}\nnot json\n";
        assert_eq!(gpu_busy(stats), Some((1.5, 2)));
        assert_eq!(gpu_busy("{\"frame\":1}\n"), None);
        assert_eq!(count(1_479_632), "1 479 632");
        assert_eq!(count(999), "999");
    }
}
