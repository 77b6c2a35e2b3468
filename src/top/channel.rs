//! `stereoshim top`'s side of the live folder (`core::live`): the running apps that announced
//! themselves, the heartbeat that keeps the layer streaming, the live settings file, and the
//! stream read as it grows.
#![forbid(unsafe_code)]

use crate::core::live;
use std::io::{Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

/// A running app with the layer.
#[derive(Clone, Debug, PartialEq)]
pub struct App {
    pub pid: u32,
    /// The name its config section is found by (`XrApplicationInfo::applicationName`).
    pub app: String,
    pub exe: String,
    /// The config file the layer in it reads (None: no HOME / XDG_CONFIG_HOME there).
    pub config: Option<PathBuf>,
}

/// The apps announced in `folder` whose process is alive, by pid.
pub fn running(folder: &Path) -> Vec<App> {
    live::announced(folder)
        .into_iter()
        .map(|(pid, json)| {
            let s = |k: &str| json[k].as_str().unwrap_or("").to_string();
            App { pid, app: s("app"), exe: s("exe"), config: json["config"].as_str().map(PathBuf::from) }
        })
        .collect()
}

/// The app to watch: the one with `pid`, else the one named `name` (app or executable), else the
/// only one; an error that lists them otherwise.
pub fn pick(apps: &[App], pid: Option<u32>, name: Option<&str>) -> Result<App, String> {
    let list = || apps.iter().map(|a| format!("{} (pid {})", a.app, a.pid)).collect::<Vec<_>>().join(", ");
    let chosen: Vec<&App> = apps.iter().filter(|a| pid.is_none_or(|p| a.pid == p) && name.is_none_or(|n| a.app == n || a.exe == n)).collect();
    match (chosen.as_slice(), apps.is_empty()) {
        ([one], _) => Ok((*one).clone()),
        (_, true) => Err("no running app with the stereoshim layer found (apps announce themselves while their XR session runs, with live.enabled)".into()),
        ([], false) => Err(format!("no running app with the layer matches; running: {}", list())),
        (_, false) => Err(format!("several apps run with the layer: pick one with --pid or --app; running: {}", list())),
    }
}

/// The live files of one app.
#[derive(Clone, Debug)]
pub struct Channel {
    pub folder: PathBuf,
    pub pid: u32,
}

impl Channel {
    /// Touches the heartbeat (writes it anew: its modification time is what the layer reads).
    pub fn beat(&self) -> std::io::Result<()> {
        crate::manifests::private_fs::write_private(&live::heartbeat_file(&self.folder, self.pid), b"stereoshim top\n")
    }

    /// Writes the live settings (`key = value` lines), atomically.
    pub fn write_settings(&self, lines: &[(String, String)]) -> std::io::Result<()> {
        let mut text = String::from("# stereoshim top's live settings for this app (removed when top exits)\n");
        for (k, v) in lines {
            text.push_str(&format!("{k} = {v}\n"));
        }
        crate::manifests::private_fs::write_private(&live::settings_file(&self.folder, self.pid), text.as_bytes())
    }

    /// Removes the heartbeat and the live settings: the app runs as its config says again.
    pub fn leave(&self) {
        let _ = std::fs::remove_file(live::settings_file(&self.folder, self.pid));
        let _ = std::fs::remove_file(live::heartbeat_file(&self.folder, self.pid));
    }

    /// Writes the last A/B's outcomes for the app's overlay (`core::live::ab_file`).
    pub fn write_ab(&self, lines: &[String]) -> std::io::Result<()> {
        crate::manifests::private_fs::write_private(&live::ab_file(&self.folder, self.pid), (lines.join("\n") + "\n").as_bytes())
    }

    pub fn alive(&self) -> bool {
        Path::new("/proc").join(self.pid.to_string()).exists()
    }

    pub fn stream(&self) -> PathBuf {
        live::stream_file(&self.folder, self.pid)
    }
}

/// A file read as it grows, line by line: what was read is remembered; a file shorter than that
/// (emptied by the layer at its cap, or made anew) is read from its start again.
#[derive(Debug, Default)]
pub struct Tail {
    offset: u64,
    partial: String,
}

impl Tail {
    /// A tail that starts at the file's end (older lines are not `top`'s business).
    pub fn at_end(path: &Path) -> Tail {
        Tail { offset: std::fs::metadata(path).map_or(0, |m| m.len()), partial: String::new() }
    }

    /// The complete lines appended since the last call.
    pub fn read(&mut self, path: &Path) -> Vec<String> {
        let Ok(mut f) = std::fs::File::open(path) else { return Vec::new() };
        let len = f.metadata().map_or(0, |m| m.len());
        if len < self.offset {
            self.offset = 0;
            self.partial.clear();
        }
        if len == self.offset || f.seek(SeekFrom::Start(self.offset)).is_err() {
            return Vec::new();
        }
        let mut buf = Vec::new();
        if f.take(len - self.offset).read_to_end(&mut buf).is_err() {
            return Vec::new();
        }
        self.offset += buf.len() as u64;
        self.partial.push_str(&String::from_utf8_lossy(&buf));
        let mut lines: Vec<String> = self.partial.split('\n').map(str::to_string).collect();
        self.partial = lines.pop().unwrap_or_default();
        lines.retain(|l| !l.trim().is_empty());
        lines
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn app(pid: u32, name: &str) -> App {
        App { pid, app: name.into(), exe: format!("{name}-bin"), config: None }
    }

    #[test]
    fn picking_an_app() {
        let apps = vec![app(10, "a"), app(20, "b")];
        assert_eq!(pick(&apps, Some(20), None).unwrap().app, "b");
        assert_eq!(pick(&apps, None, Some("a-bin")).unwrap().pid, 10);
        assert!(pick(&apps, None, None).unwrap_err().contains("several apps"));
        assert!(pick(&apps, Some(30), None).unwrap_err().contains("running: a (pid 10), b (pid 20)"));
        assert_eq!(pick(&apps[..1], None, None).unwrap().pid, 10);
        assert!(pick(&[], None, None).unwrap_err().contains("no running app"));
    }

    #[test]
    fn announcements_of_live_processes_only() {
        let dir = std::env::temp_dir().join(format!("stereoshim-top-apps-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let me = std::process::id();
        std::fs::write(live::announce_file(&dir, me), r#"{"pid":1,"app":"scene","exe":"xr-scene","config":"/c.toml"}"#).unwrap();
        std::fs::write(live::announce_file(&dir, 999_999_999), r#"{"app":"gone"}"#).unwrap();
        std::fs::write(dir.join("12.jsonl"), "").unwrap();
        let found = running(&dir);
        assert_eq!(found, vec![App { pid: me, app: "scene".into(), exe: "xr-scene".into(), config: Some("/c.toml".into()) }]);
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn tail_reads_whole_lines_and_starts_over_on_a_shorter_file() {
        let dir = std::env::temp_dir().join(format!("stereoshim-top-tail-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("s.jsonl");
        std::fs::write(&p, "old\n").unwrap();
        let mut t = Tail::at_end(&p);
        assert!(t.read(&p).is_empty());
        std::fs::write(&p, "old\none\ntw").unwrap();
        assert_eq!(t.read(&p), vec!["one"]);
        std::fs::write(&p, "old\none\ntwo\n").unwrap();
        assert_eq!(t.read(&p), vec!["two"]);
        std::fs::write(&p, "new\n").unwrap();
        assert_eq!(t.read(&p), vec!["new"]);
        std::fs::remove_file(&p).unwrap();
        assert!(t.read(&p).is_empty());
        std::fs::remove_dir_all(&dir).ok();
    }
}
