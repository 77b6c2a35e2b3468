//! `stereoshim screenshot`'s side of the runtime folder: find the running apps with the layer
//! (their instance files, whose process is alive), write each one's trigger file with a request
//! number, and with `wait` read their result files until each answers that number. Kept here,
//! beside the layer's side of the same files, so the two cannot drift; it returns what to print
//! (the command prints, never the layer).
#![forbid(unsafe_code)]

use super::rules;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// A running app with the layer.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Instance {
    pub pid: u32,
    pub app: String,
}

/// The instances announced in `folder` whose process is alive (sorted by pid).
pub fn running(folder: &Path) -> Vec<Instance> {
    crate::core::live::announced(folder).into_iter().map(|(pid, json)| Instance { pid, app: json["app"].as_str().unwrap_or("").to_string() }).collect()
}

/// Asks the running instances (or the one with `pid`) for a screenshot; with `wait`, waits up to
/// `timeout` for their pictures. Returns the lines to print (the pictures' paths with `wait`).
pub fn request(env: &dyn Fn(&str) -> Option<String>, pid: Option<u32>, wait: bool, timeout: Duration) -> Result<Vec<String>, String> {
    let folder = rules::runtime_folder(env).ok_or("none of XDG_RUNTIME_DIR, XDG_STATE_HOME, HOME is set")?;
    let all = running(&folder);
    let targets: Vec<Instance> = all.iter().filter(|i| pid.is_none_or(|p| p == i.pid)).cloned().collect();
    if targets.is_empty() {
        let hint = format!("apps announce themselves in {} while they run with screenshot.enabled", folder.display());
        return Err(match (pid, all.is_empty()) {
            (Some(p), false) => format!("no running app with the stereoshim layer has pid {p} (running: {}); {hint}", all.iter().map(|i| format!("{} ({})", i.pid, i.app)).collect::<Vec<_>>().join(", ")),
            _ => format!("no running app with the stereoshim layer found; {hint}"),
        });
    }
    // A request number no earlier request of this folder used.
    let token = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map(|d| d.as_nanos() as u64).unwrap_or(1).max(1);
    for i in &targets {
        crate::manifests::private_fs::write_private(&rules::trigger_file(&folder, i.pid), token.to_string().as_bytes())
            .map_err(|e| format!("{}: {e}", rules::trigger_file(&folder, i.pid).display()))?;
    }
    if !wait {
        return Ok(targets.iter().map(|i| format!("asked {} (pid {}) for a screenshot", i.app, i.pid)).collect());
    }
    let deadline = Instant::now() + timeout;
    let mut lines = Vec::new();
    let mut errors = Vec::new();
    let mut left = targets;
    while !left.is_empty() {
        left.retain(|i| match answer(&rules::done_file(&folder, i.pid), token) {
            Some(Ok(files)) => {
                lines.extend(files.into_iter().map(|f| f.display().to_string()));
                false
            }
            Some(Err(e)) => {
                errors.push(format!("{} (pid {}): {e}", i.app, i.pid));
                false
            }
            None if !Path::new("/proc").join(i.pid.to_string()).exists() => {
                errors.push(format!("{} (pid {}) ended before its screenshot was written", i.app, i.pid));
                false
            }
            None => true,
        });
        if left.is_empty() {
            break;
        }
        if Instant::now() >= deadline {
            let names: Vec<String> = left.iter().map(|i| format!("{} (pid {})", i.app, i.pid)).collect();
            errors.push(format!("no screenshot after {:.1} s from {} (is the app rendering frames?)", timeout.as_secs_f64(), names.join(", ")));
            break;
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    if errors.is_empty() {
        Ok(lines)
    } else {
        Err(errors.join("; "))
    }
}

/// The result file's answer to request `token`: the pictures, or the layer's error; None while it
/// has not answered (no file, or one for an earlier request).
fn answer(path: &Path, token: u64) -> Option<Result<Vec<PathBuf>, String>> {
    let json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(path).ok()?).ok()?;
    if json["request"].as_u64() != Some(token) {
        return None;
    }
    if let Some(e) = json["error"].as_str() {
        return Some(Err(e.to_string()));
    }
    let views = json["views"].as_array()?;
    Some(Ok(views.iter().filter_map(|v| v["file"].as_str().map(PathBuf::from)).collect()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_live_instances_and_reads_answers() {
        let dir = std::env::temp_dir().join(format!("stereoshim-shot-cmd-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let me = std::process::id();
        std::fs::write(rules::instance_file(&dir, me), r#"{"pid":1,"app":"scene"}"#).unwrap();
        // A pid no process has (above the kernel's maximum).
        std::fs::write(rules::instance_file(&dir, 999_999_999), r#"{"app":"gone"}"#).unwrap();
        std::fs::write(dir.join("notes.json"), "{}").unwrap();
        assert_eq!(running(&dir), vec![Instance { pid: me, app: "scene".into() }]);
        let done = rules::done_file(&dir, me);
        assert_eq!(answer(&done, 5), None);
        std::fs::write(&done, r#"{"request":4,"views":[]}"#).unwrap();
        assert_eq!(answer(&done, 5), None, "an earlier request's answer");
        std::fs::write(&done, r#"{"request":5,"views":[{"file":"/p/a-view-0.png"},{"file":"/p/a-view-1.png"}]}"#).unwrap();
        assert_eq!(answer(&done, 5), Some(Ok(vec![PathBuf::from("/p/a-view-0.png"), PathBuf::from("/p/a-view-1.png")])));
        std::fs::write(&done, r#"{"request":5,"error":"read-only"}"#).unwrap();
        assert_eq!(answer(&done, 5), Some(Err("read-only".into())));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
