//! The files a running app with the layer and `stereoshim top` meet in, under
//! `<private base>/stereoshim/live/` (`$XDG_RUNTIME_DIR` first): the app announces itself
//! (`<pid>.json`); `top` keeps a heartbeat (`<pid>.watch`, touched every half second) while it
//! watches; while the heartbeat is fresh the layer streams every frame's stats line to
//! `<pid>.jsonl` and applies `top`'s live settings (`<pid>.toml`, above every other source) —
//! so a `top` that dies leaves the app as its config says within [`HEARTBEAT_FRESH`].
//! Names and the freshness rule only; the layer's side is `features::live`, `top`'s `crate::top`.
#![forbid(unsafe_code)]

use std::path::{Path, PathBuf};
use std::time::{Duration, SystemTime};

/// How old the heartbeat may be for `top` to count as watching: six of its beats, so a loaded
/// machine's late beat does not stop the stream.
pub const HEARTBEAT_FRESH: Duration = Duration::from_secs(3);

/// How often `top` touches the heartbeat.
pub const HEARTBEAT_EVERY: Duration = Duration::from_millis(500);

/// The stream is emptied when it grows past this (`top` reads from its start again when the file
/// is shorter than what it read): a day of watching costs the runtime folder (RAM) no more.
pub const STREAM_MAX_BYTES: u64 = 8 << 20;

/// The live folder under a private base (`crate::manifests::private_fs::private_base`).
pub fn folder(base: &Path) -> PathBuf {
    base.join("stereoshim").join("live")
}

/// `<pid>.json`: the app's announcement (pid, app name, executable, config file).
pub fn announce_file(folder: &Path, pid: u32) -> PathBuf {
    folder.join(format!("{pid}.json"))
}

/// `<pid>.watch`: `top`'s heartbeat (its modification time is what counts).
pub fn heartbeat_file(folder: &Path, pid: u32) -> PathBuf {
    folder.join(format!("{pid}.watch"))
}

/// `<pid>.toml`: `top`'s live settings for this app (plain `key = value` lines of the config's
/// keys), applied above the environment while the heartbeat is fresh.
pub fn settings_file(folder: &Path, pid: u32) -> PathBuf {
    folder.join(format!("{pid}.toml"))
}

/// `<pid>.jsonl`: the frames' stats lines (as `stats.file`'s) while `top` watches.
pub fn stream_file(folder: &Path, pid: u32) -> PathBuf {
    folder.join(format!("{pid}.jsonl"))
}

/// `<pid>.ab`: the outcomes of the last A/B `top` ran in this app, one per line (the overlay
/// shows the first); left by `top` when it exits, removed by the layer when the session ends.
pub fn ab_file(folder: &Path, pid: u32) -> PathBuf {
    folder.join(format!("{pid}.ab"))
}

/// The pid of an announcement's file name (`1234.json`).
pub fn announced_pid(file_name: &str) -> Option<u32> {
    let stem = file_name.strip_suffix(".json")?;
    if stem.is_empty() || !stem.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    stem.parse().ok()
}

/// The announcements (`<pid>.json`, read as JSON) in `folder` whose process is alive, by pid:
/// what `stereoshim top` and `stereoshim screenshot` list (each folder has its own files).
pub fn announced(folder: &Path) -> Vec<(u32, serde_json::Value)> {
    let Ok(entries) = std::fs::read_dir(folder) else { return Vec::new() };
    let mut found: Vec<(u32, serde_json::Value)> = entries
        .flatten()
        .filter_map(|e| {
            let pid = announced_pid(e.file_name().to_str()?)?;
            if !Path::new("/proc").join(pid.to_string()).exists() {
                return None;
            }
            let json = serde_json::from_str(&std::fs::read_to_string(e.path()).ok()?).ok()?;
            Some((pid, json))
        })
        .collect();
    found.sort_by_key(|(pid, _)| *pid);
    found
}

/// Whether a heartbeat last touched at `touched` still counts at `now`. A heartbeat from the
/// future (a clock step back) counts: `top` touches it again within half a second anyway.
pub fn fresh(touched: Option<SystemTime>, now: SystemTime) -> bool {
    match touched {
        None => false,
        Some(t) => now.duration_since(t).map_or(true, |age| age <= HEARTBEAT_FRESH),
    }
}

/// The heartbeat's modification time, if the file exists.
pub fn heartbeat_mtime(folder: &Path, pid: u32) -> Option<SystemTime> {
    std::fs::metadata(heartbeat_file(folder, pid)).and_then(|m| m.modified()).ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_and_pids() {
        let f = folder(Path::new("/run/user/7"));
        assert_eq!(f, PathBuf::from("/run/user/7/stereoshim/live"));
        assert_eq!(announce_file(&f, 42), f.join("42.json"));
        assert_eq!(announced_pid("42.json"), Some(42));
        for bad in ["42.jsonl", ".json", "4x.json", "42.watch", "42.toml"] {
            assert_eq!(announced_pid(bad), None, "{bad}");
        }
        assert_ne!(stream_file(&f, 1), settings_file(&f, 1));
    }

    #[test]
    fn freshness() {
        let now = SystemTime::UNIX_EPOCH + Duration::from_secs(1000);
        assert!(!fresh(None, now));
        assert!(fresh(Some(now), now));
        assert!(fresh(Some(now - HEARTBEAT_FRESH), now));
        assert!(!fresh(Some(now - HEARTBEAT_FRESH - Duration::from_millis(1)), now));
        assert!(fresh(Some(now + Duration::from_secs(5)), now), "a clock step back");
    }
}
