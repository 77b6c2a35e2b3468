//! `stereoshim top` end to end: xr-scene through the layer on the mock runtime (its frames also in
//! `stats.file`), `top` in a tmux terminal of 80×24 watching it. The screen's numbers are the
//! stats file's for the frame it names; a key press changes the app's config section and the
//! layer's behaviour (the frames' lines show the feature off); a live A/B reports the speed-up
//! the stats file's frames give when sorted as `examples/bench` sorts them; `q` leaves the config
//! as the keys left it, removes `top`'s live settings, and the layer stops streaming.

use crate::common;

use common::{target_dir, Run};
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Command;

/// A tmux server of the test's own (its socket in the run folder), killed when dropped.
struct Tmux {
    socket: PathBuf,
}

impl Tmux {
    fn cmd(&self) -> Command {
        let mut c = Command::new("tmux");
        c.arg("-S").arg(&self.socket);
        c
    }

    /// Starts `top` in a detached 80×24 session, in the app's runtime folder.
    fn start(dir: &Path, pid: u32) -> Tmux {
        let t = Tmux { socket: dir.join("tmux.sock") };
        let top = target_dir().join("stereoshim");
        // The pane stays after top exits, showing what it printed on leaving.
        let shell = format!("XDG_RUNTIME_DIR={} {} top --pid {pid} --ab-period 16 --ab-cycles 3; echo top-exit=$?; sleep 600", dir.join("run").display(), top.display());
        let st = t.cmd().args(["new-session", "-d", "-x", "80", "-y", "24", "-s", "top", &shell]).status().expect("tmux runs");
        assert!(st.success(), "tmux new-session failed");
        t
    }

    fn screen(&self) -> String {
        let out = self.cmd().args(["capture-pane", "-p", "-t", "top"]).output().expect("tmux capture-pane");
        String::from_utf8_lossy(&out.stdout).into_owned()
    }

    fn keys(&self, k: &str) {
        self.cmd().args(["send-keys", "-t", "top", k]).status().expect("tmux send-keys");
    }
}

impl Drop for Tmux {
    fn drop(&mut self) {
        let _ = self.cmd().arg("kill-server").status();
    }
}

fn stats_lines(path: &Path) -> Vec<Value> {
    std::fs::read_to_string(path).unwrap_or_default().lines().filter_map(|l| serde_json::from_str(l).ok()).collect()
}

fn sum_views(v: &Value, key: &str) -> u64 {
    v.get(key).and_then(Value::as_object).map_or(0, |m| m.values().filter_map(Value::as_u64).sum())
}

/// The number after the first `label` on the screen that has one.
fn number_after(screen: &str, label: &str) -> Option<f64> {
    screen.match_indices(label).find_map(|(at, _)| {
        let s: String = screen[at + label.len()..].trim_start().chars().take_while(|c| c.is_ascii_digit() || *c == '.').collect();
        s.parse().ok()
    })
}

/// `h`uman numbers (`12.3k`) back to a count (to that precision).
fn human_after(screen: &str, label: &str) -> Option<(f64, f64)> {
    let at = screen.find(label)? + label.len();
    let word: String = screen[at..].trim_start().chars().take_while(|c| !c.is_whitespace()).collect();
    let (num, unit) = match word.chars().last()? {
        'k' => (&word[..word.len() - 1], 1e3),
        'M' => (&word[..word.len() - 1], 1e6),
        'G' => (&word[..word.len() - 1], 1e9),
        _ => (word.as_str(), 1.0),
    };
    let v: f64 = num.parse().ok()?;
    // The value and how far the rounding to one decimal may be off.
    Some((v * unit, if unit > 1.0 { 0.05 * unit } else { 0.0 }))
}

/// The median of `v`.
fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    let n = v.len();
    assert!(n > 0, "no values");
    if n % 2 == 1 {
        v[n / 2]
    } else {
        (v[n / 2 - 1] + v[n / 2]) / 2.0
    }
}

#[derive(Debug, PartialEq)]
enum Step {
    WaitApp,
    WaitScreen,
    MaskOff { config_before: String },
    MaskOn,
    Ab,
    Quit,
    Stopped,
    Done,
}

#[test]
fn top_watches_tunes_and_ab_tests_a_running_app() {
    let name = "top-live";
    let stop = target_dir().join("test-output").join(format!("{name}.stop"));
    let _ = std::fs::remove_file(&stop);
    let dir = common::output_dir(name);
    let stats = dir.join("layer-stats.jsonl");
    let config = format!("# the test's config: the mask pays on the Index at this shading cost\nstats.file = \"{}\"\n\n[app.\"xr-scene\"]\nmask.enabled = true # on from the start\n", stats.display());
    let run = Run::new(name)
        .args(["--shading-cost", "96"])
        .with_layer()
        .config(&config)
        .env("MOCK_XR_HMD", "index")
        .env("MOCK_XR_EXIT_AFTER", "")
        .env("MOCK_XR_CAPTURE_FRAMES", "0")
        .env("MOCK_XR_EXIT_ON", stop.to_str().unwrap());
    let config_file = Run::config_file(&dir);
    let mut step = Step::WaitApp;
    let mut tmux: Option<Tmux> = None;
    let mut checked_screen = false;
    let mut mask_off_at: Option<(std::time::SystemTime, u64)> = None;
    let mut ab_line = String::new();
    let mut config_after_keys = String::new();
    let mut summary = String::new();
    let out = run.run_while(std::time::Duration::from_secs(900), |d| {
        let live = d.join("run/stereoshim/live");
        match &step {
            Step::WaitApp => {
                let pid = std::fs::read_dir(&live).ok().and_then(|r| r.flatten().find_map(|e| stereoshim::core::live::announced_pid(e.file_name().to_str()?)));
                if let Some(pid) = pid {
                    tmux = Some(Tmux::start(d, pid));
                    step = Step::WaitScreen;
                }
            }
            Step::WaitScreen => {
                let screen = tmux.as_ref().unwrap().screen();
                // A frame with a GPU time, and the last second's masked pixels, on the screen.
                let Some(frame) = number_after(&screen, "- frame") else { return };
                let (Some(gpu), Some((masked, tolerance))) = (number_after(&screen, "GPU"), human_after(&screen, "masked")) else { return };
                if gpu <= 0.0 || masked == 0.0 {
                    return;
                }
                let lines = stats_lines(&stats);
                let Some(newest) = lines.iter().find(|l| l["frame"].as_u64() == Some(frame as u64)) else { return };
                // The screen's last second, recomputed from the file.
                let t = newest["time"].as_f64().unwrap();
                let window: Vec<&Value> = lines.iter().filter(|l| l["frame"].as_u64().unwrap() <= frame as u64 && t - l["time"].as_f64().unwrap() < 1.0).collect();
                let want_masked: u64 = window.iter().map(|l| sum_views(l, "pixels_masked")).sum();
                assert!((masked - want_masked as f64).abs() <= tolerance, "screen masked {masked} px/s, file {want_masked}:\n{screen}");
                let want_gpu = median(window.iter().filter_map(|l| l["gpu_ms"]["busy"].as_f64()).collect());
                assert!((gpu - want_gpu).abs() < 0.0015, "screen GPU {gpu} ms, file {want_gpu:.4}:\n{screen}");
                let passes = newest["passes_masked"].as_u64().unwrap();
                assert!(screen.contains(&format!("this frame: {passes} eye passes masked")), "file: {passes} passes masked in frame {frame}:\n{screen}");
                assert!(screen.contains("[m] mask ON"), "{screen}");
                checked_screen = true;
                let before = std::fs::read_to_string(&config_file).unwrap();
                tmux.as_ref().unwrap().keys("m");
                step = Step::MaskOff { config_before: before };
            }
            Step::MaskOff { config_before } => {
                let now = std::fs::read_to_string(&config_file).unwrap_or_default();
                if now == *config_before {
                    return;
                }
                // The key's edit: the value, in place, its comment kept, the rest unchanged.
                assert_eq!(now, config_before.replace("mask.enabled = true # on from the start", "mask.enabled = false # on from the start"));
                let changed = std::fs::metadata(&config_file).unwrap().modified().unwrap();
                let last = stats_lines(&stats).last().and_then(|l| l["frame"].as_u64()).unwrap_or(0);
                mask_off_at = Some((changed, last));
                step = Step::MaskOn;
            }
            Step::MaskOn => {
                // Wait until the layer's frames show the mask off, then turn it on for the A/B.
                let (_, after) = mask_off_at.unwrap();
                let lines = stats_lines(&stats);
                if !lines.iter().any(|l| l["frame"].as_u64().unwrap() > after && l["mask_enabled"] == false) {
                    return;
                }
                tmux.as_ref().unwrap().keys("m");
                std::thread::sleep(std::time::Duration::from_millis(300));
                config_after_keys = std::fs::read_to_string(&config_file).unwrap();
                assert!(config_after_keys.contains("mask.enabled = true # on from the start"), "{config_after_keys}");
                tmux.as_ref().unwrap().keys("b");
                step = Step::Ab;
            }
            Step::Ab => {
                let screen = tmux.as_ref().unwrap().screen();
                if let Some(l) = screen.lines().find(|l| l.starts_with("A/B mask:")) {
                    ab_line = l.to_string();
                    // Kept for a person to look at (docs/configuration.md shows one).
                    std::fs::write(common::image::artifacts_dir("top").join("top-after-ab.txt"), &screen).unwrap();
                    tmux.as_ref().unwrap().keys("q");
                    step = Step::Quit;
                } else if screen.contains("A/B stopped") {
                    panic!("the A/B stopped:\n{screen}");
                }
            }
            Step::Quit => {
                let screen = tmux.as_ref().unwrap().screen();
                if screen.contains("top-exit=") {
                    summary = screen;
                    step = Step::Stopped;
                }
            }
            Step::Stopped => {
                // The heartbeat goes stale a few seconds after top left: the layer stops streaming.
                let log = std::fs::read_to_string(d.join("state/stereoshim/stereoshim.log")).unwrap_or_default();
                if log.contains("stereoshim top stopped watching") {
                    std::fs::write(&stop, b"").unwrap();
                    step = Step::Done;
                }
            }
            Step::Done => {}
        }
    });
    out.assert_ok();
    drop(tmux);
    assert!(checked_screen);
    assert_eq!(step, Step::Done, "{}", out.log);

    // The key press's effect: every frame from the one after the config changed, plus the
    // layer's 100 ms look and a frame in flight, has the mask off.
    let lines = stats_lines(&stats);
    let (changed, _) = mask_off_at.unwrap();
    let changed = changed.duration_since(std::time::UNIX_EPOCH).unwrap().as_secs_f64();
    let intervals: Vec<f64> = lines.windows(2).map(|w| w[1]["time"].as_f64().unwrap() - w[0]["time"].as_f64().unwrap()).collect();
    let frame_s = median(intervals);
    let first_off = lines.iter().find(|l| l["time"].as_f64().unwrap() > changed && l["mask_enabled"] == false).expect("the mask went off");
    let latency = first_off["time"].as_f64().unwrap() - changed;
    eprintln!("top: mask off {latency:.3} s after the key's config edit (median frame {:.1} ms)", frame_s * 1e3);
    assert!(latency < 1.0 + 3.0 * frame_s, "the mask went off {latency:.3} s after the key press (frames every {frame_s:.3} s)");

    // The A/B's figure against the frames it ran on, sorted as examples/bench does (by what
    // each frame was recorded with), without the settle frames.
    let speedup: f64 = ab_line.split(": ").nth(1).and_then(|s| s.split('x').next()).and_then(|s| s.parse().ok()).unwrap_or_else(|| panic!("{ab_line}"));
    let ab_frames: Vec<&Value> = lines.iter().skip_while(|l| l["mask_enabled"] != false || l["time"].as_f64().unwrap() < changed + 0.2).collect();
    let mut runs: Vec<(bool, Vec<f64>)> = Vec::new();
    for l in &ab_frames {
        let on = l["mask_enabled"] == true;
        if runs.last().is_none_or(|r| r.0 != on) {
            runs.push((on, Vec::new()));
        }
        if let Some(ms) = l["gpu_ms"]["busy"].as_f64() {
            runs.last_mut().unwrap().1.push(ms);
        }
    }
    let pick = |on: bool| -> Vec<f64> { runs.iter().filter(|r| r.0 == on && r.1.len() > 8).flat_map(|r| r.1[3..].to_vec()).collect() };
    let bench = median(pick(false)) / median(pick(true));
    eprintln!("top: {ab_line}; the same frames as examples/bench sorts them: {bench:.3}x");
    assert!(speedup > 1.0, "the mask did not pay in the A/B: {ab_line}");
    assert!((speedup / bench - 1.0).abs() < 0.1, "top says {speedup}x, the frames {bench:.3}x");

    // `q`: the config is as the keys left it (the A/B never wrote it), top's files are gone,
    // and the layer stopped streaming.
    assert_eq!(std::fs::read_to_string(&config_file).unwrap(), config_after_keys);
    let live = dir.join("run/stereoshim/live");
    let left: Vec<String> = std::fs::read_dir(&live).map(|r| r.flatten().map(|e| e.file_name().to_string_lossy().into_owned()).collect()).unwrap_or_default();
    assert!(left.iter().all(|f| !f.ends_with(".toml") && !f.ends_with(".watch")), "top's files left behind: {left:?}");
    assert!(out.log.contains("stereoshim top is watching") && out.log.contains("stereoshim top stopped watching"), "{}", out.log);
    assert!(summary.contains("top-exit=0") && summary.contains("its live settings are removed") && summary.contains("A/B mask:"), "{summary}");
}
