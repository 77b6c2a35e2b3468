//! Logging to a file under `$XDG_STATE_HOME/stereoshim/`: the layer lives in someone else's process
//! and must never write to its stdout, and the log must outlive a crash of that process, so every
//! line goes straight to the file (no buffering).

use std::collections::HashMap;
use std::fs::{File, OpenOptions};
use std::path::{Path, PathBuf};
use std::sync::{Mutex, OnceLock};

static LOG_PATH: OnceLock<Option<PathBuf>> = OnceLock::new();

/// `$XDG_STATE_HOME/stereoshim/stereoshim.log`, else `~/.local/state/stereoshim/stereoshim.log`.
pub fn default_path(env: &dyn Fn(&str) -> Option<String>) -> Option<PathBuf> {
    let base = env("XDG_STATE_HOME")
        .filter(|p| !p.is_empty())
        .map(PathBuf::from)
        .or_else(|| env("HOME").map(|h| Path::new(&h).join(".local").join("state")))?;
    Some(base.join("stereoshim").join("stereoshim.log"))
}

/// Installs the file logger once per process; later calls return the path chosen the first time.
/// `level` is one of the `log.level` choices. Without a writable log file the layer stays silent.
pub fn init(level: &str) -> Option<&'static Path> {
    LOG_PATH
        .get_or_init(|| {
            let path = default_path(&|k| std::env::var(k).ok())?;
            let file = open(&path)?;
            let filter = match level {
                "off" => tracing_subscriber::filter::LevelFilter::OFF,
                "error" => tracing_subscriber::filter::LevelFilter::ERROR,
                "warn" => tracing_subscriber::filter::LevelFilter::WARN,
                "debug" => tracing_subscriber::filter::LevelFilter::DEBUG,
                "trace" => tracing_subscriber::filter::LevelFilter::TRACE,
                _ => tracing_subscriber::filter::LevelFilter::INFO,
            };
            // `File` is unbuffered: each event is one write(2), so lines survive the app's exit or
            // crash. Several processes may append to the same file; O_APPEND keeps lines whole.
            let installed = tracing_subscriber::fmt()
                .with_writer(Mutex::new(file))
                .with_ansi(false)
                .with_max_level(filter)
                .with_thread_ids(true)
                .try_init()
                .is_ok();
            if installed {
                let exe = std::env::current_exe().map(|p| p.display().to_string()).unwrap_or_default();
                tracing::info!(pid = std::process::id(), exe, version = env!("CARGO_PKG_VERSION"), "stereoshim loaded");
            }
            Some(path)
        })
        .as_deref()
}

/// Appends one INFO line to the log file without `tracing`: for code that runs at process exit,
/// when the subscriber's thread-locals may already be destroyed (using them there panics).
pub fn append_at_exit(target: &str, message: &str) {
    let Some(Some(path)) = LOG_PATH.get() else { return };
    let since = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).unwrap_or_default();
    let line = format!("{}.{:06}s  INFO {target}: {message}\n", since.as_secs(), since.subsec_micros());
    if let Some(mut f) = open(path) {
        use std::io::Write;
        let _ = f.write_all(line.as_bytes());
    }
}

fn open(path: &Path) -> Option<File> {
    std::fs::create_dir_all(path.parent()?).ok()?;
    OpenOptions::new().create(true).append(true).open(path).ok()
}

/// Failures that repeat: a device out of memory makes the layer's attempt for every pass fail
/// the same way, and a WARN line per pass would flood the log (and cost the app a write per
/// pass). The first failure of each kind is logged, the rest only counted; `summary` gives the
/// counts for one line when the device goes.
#[derive(Debug, Default)]
pub(crate) struct Repeats {
    seen: Mutex<HashMap<&'static str, u64>>,
}

impl Repeats {
    /// Counts a failure of `kind`; true for the first one, the one to log.
    pub(crate) fn first(&self, kind: &'static str) -> bool {
        let mut seen = self.seen.lock().unwrap_or_else(|e| e.into_inner());
        let n = seen.entry(kind).or_insert(0);
        *n += 1;
        *n == 1
    }
    /// The kinds that failed more than once, with their counts, sorted by kind.
    pub(crate) fn summary(&self) -> Vec<(&'static str, u64)> {
        let seen = self.seen.lock().unwrap_or_else(|e| e.into_inner());
        let mut v: Vec<_> = seen.iter().filter(|(_, n)| **n > 1).map(|(k, n)| (*k, *n)).collect();
        v.sort_unstable();
        v
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn repeats_log_the_first_and_count_the_rest() {
        let r = Repeats::default();
        assert!(r.first("mask buffer"));
        assert!(!r.first("mask buffer"));
        assert!(!r.first("mask buffer"));
        assert!(r.first("far field slots"), "another kind is logged on its own");
        assert_eq!(r.summary(), vec![("mask buffer", 3)], "kinds seen once need no summary");
    }

    #[test]
    fn path_from_xdg_state_home_or_home() {
        let env = |k: &str| (k == "XDG_STATE_HOME").then(|| "/s".to_string());
        assert_eq!(default_path(&env), Some(PathBuf::from("/s/stereoshim/stereoshim.log")));
        let env = |k: &str| (k == "HOME").then(|| "/h".to_string());
        assert_eq!(default_path(&env), Some(PathBuf::from("/h/.local/state/stereoshim/stereoshim.log")));
        assert_eq!(default_path(&|_| None), None);
    }
}
