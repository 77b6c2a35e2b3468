//! Layer configuration: one registry of keys, resolved from defaults < the file's global section <
//! the app's section < environment, so that every key means the same wherever it is set and a bad
//! value only ever costs that one key (reported with file and line), never the app.

use std::collections::BTreeMap;
use std::fmt;
use std::path::{Path, PathBuf};

/// What values a key accepts.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Kind {
    Bool,
    Choice(&'static [&'static str]),
    Float { min: f64, max: f64 },
    /// Free text (names of calls, paths).
    Text,
}

/// One configuration key. The environment variable is derived from the name, never spelled out,
/// so the two cannot drift apart.
#[derive(Clone, Copy, Debug)]
pub struct KeySpec {
    pub key: &'static str,
    pub kind: Kind,
    pub default: &'static str,
    pub doc: &'static str,
}

impl KeySpec {
    /// `mask.enabled` → `STEREOSHIM_MASK_ENABLED`.
    pub fn env_var(&self) -> String {
        format!("STEREOSHIM_{}", self.key.replace('.', "_").to_ascii_uppercase())
    }
}

/// The chassis' own keys; each feature declares its own, and the registry lists them all
/// (the registry's `keys`): this module is given the list, it names no feature.
pub const CORE_KEYS: &[KeySpec] = &[
    KeySpec {
        key: "enabled",
        kind: Kind::Bool,
        default: "true",
        doc: "master switch: false makes the whole layer pure pass-through",
    },
    KeySpec {
        key: "log.level",
        kind: Kind::Choice(&["off", "error", "warn", "info", "debug", "trace"]),
        default: "info",
        doc: "verbosity of the log file",
    },
    KeySpec {
        key: "vulkan.fragment_shading_rate",
        kind: Kind::Choice(&["auto", "on", "off"]),
        default: "auto",
        doc: "enable VK_KHR_fragment_shading_rate on the app's device: auto = only when an enabled feature uses it and the device has it; on = whenever the device has it",
    },
    KeySpec {
        key: "mask.intermediate",
        kind: Kind::Choice(&["auto", "off"]),
        default: "auto",
        doc: "auto: also mask passes that render into an intermediate image the app later copies / resolves / blits 1:1 into a swapchain image; off: only passes rendering into swapchain images",
    },
    KeySpec {
        key: "eyes.walk",
        kind: Kind::Bool,
        default: "true",
        doc: "follow each frame's data flow back from the swapchain to the eye passes behind post-processing (tonemap, upscale, TAA, compute, scaled blits); false: only swapchain targets, 1:1 copies into them and eyes.fallback",
    },
    KeySpec {
        key: "eyes.fallback",
        kind: Kind::Choice(&["off", "size"]),
        default: "off",
        doc: "for eye passes the data-flow walk cannot trace (descriptor buffers, bindless): size = take a depth-tested pass into an image of an eye's aspect and size (0.5-2x) as an eye pass, the eye by the order such passes come in a frame; a guess, so off by default (set it per app)",
    },
    KeySpec {
        key: "eyes.fallback_order",
        kind: Kind::Choice(&["LR", "RL"]),
        default: "LR",
        doc: "eyes.fallback = size: the first eye-sized pass of a frame is the left eye (LR) or the right one (RL)",
    },
    KeySpec {
        key: "stats.file",
        kind: Kind::Text,
        default: "",
        doc: "append the layer's per-frame statistics (JSON lines) to this file",
    },
    KeySpec {
        key: "stats.gpu_time",
        kind: Kind::Bool,
        default: "false",
        doc: "time every queue submission on the GPU (the app's and the layer's own) and write each frame's busy time and span to stats.file as gpu_ms",
    },
    KeySpec {
        key: "debug.fail_in",
        kind: Kind::Text,
        default: "",
        doc: "names of intercepted calls (comma separated) whose layer logic fails on purpose, to prove the fallback to pass-through; `stats.gpu_time` makes the GPU timer fail to set up",
    },
];

/// `lists` joined in order, each key once (features sharing a folder declare its keys each).
pub fn join_keys(lists: &[&[KeySpec]]) -> Vec<KeySpec> {
    let mut all: Vec<KeySpec> = Vec::new();
    for spec in lists.iter().flat_map(|l| l.iter()) {
        if !all.iter().any(|k| k.key == spec.key) {
            all.push(*spec);
        }
    }
    all
}

#[derive(Clone, Debug, PartialEq)]
pub enum Value {
    Bool(bool),
    Choice(&'static str),
    Float(f64),
    Text(String),
}

impl fmt::Display for Value {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Value::Bool(b) => write!(f, "{b}"),
            Value::Choice(c) => write!(f, "{c}"),
            Value::Float(x) => write!(f, "{x}"),
            Value::Text(t) => write!(f, "{t:?}"),
        }
    }
}

/// Where a value came from; shown by `stereoshim status` so a user can tell why a key has its value.
#[derive(Clone, Debug, PartialEq)]
pub enum Source {
    Default,
    File { path: PathBuf, line: usize },
    App { app: String, path: PathBuf, line: usize },
    Env(String),
    /// `stereoshim top`'s live settings file (`core::live::settings_file`), while it watches.
    Live { path: PathBuf, line: usize },
}

impl fmt::Display for Source {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Source::Default => write!(f, "default"),
            Source::File { path, line } => write!(f, "{}:{line}", path.display()),
            Source::App { app, path, line } => write!(f, "{}:{line} [app.\"{app}\"]", path.display()),
            Source::Env(var) => write!(f, "${var}"),
            Source::Live { path, line } => write!(f, "stereoshim top ({}:{line})", path.display()),
        }
    }
}

/// The resolved configuration of one application.
#[derive(Clone, Debug)]
pub struct Config {
    /// The keys it was resolved against (the caller's list).
    keys: &'static [KeySpec],
    values: BTreeMap<&'static str, (Value, Source)>,
}

/// What the resolution is given; the environment is a function so tests need not touch the
/// process environment.
pub struct Inputs<'a> {
    /// Every key there is (the registry's `keys`); anything else is reported unknown.
    pub keys: &'static [KeySpec],
    /// The config file's path and text, if one exists.
    pub file: Option<(&'a Path, &'a str)>,
    /// Names the app's section may be keyed by: `XrApplicationInfo::applicationName`, then the
    /// executable's file name.
    pub app_names: &'a [&'a str],
    pub env: &'a dyn Fn(&str) -> Option<String>,
}

impl Config {
    /// All defaults, as the layer runs when nothing is configured.
    pub fn defaults(keys: &'static [KeySpec]) -> Config {
        let values = keys
            .iter()
            .map(|k| (k.key, (parse_value(k, &RawValue::Text(k.default.into())).expect("valid default"), Source::Default)))
            .collect();
        Config { keys, values }
    }

    /// Resolves the configuration; every problem found is returned as one diagnostic line and the
    /// affected key keeps the value of the lower-precedence source.
    pub fn resolve(inputs: &Inputs<'_>) -> (Config, Vec<String>) {
        let mut config = Config::defaults(inputs.keys);
        let mut diagnostics = Vec::new();
        if let Some((path, text)) = inputs.file {
            match parse_file(text) {
                Err(msg) => diagnostics.push(format!("{}: {msg}; using defaults for the whole file", path.display())),
                Ok(file) => {
                    for entry in &file.global {
                        config.apply(entry, Source::File { path: path.into(), line: entry.line }, path, &mut diagnostics);
                    }
                    // The first name that has a section wins: applicationName is what the app
                    // chose to be called, the executable name is the fallback.
                    if let Some((app, entries)) =
                        inputs.app_names.iter().find_map(|n| file.apps.iter().find(|(a, _)| a == n))
                    {
                        for entry in entries {
                            let source = Source::App { app: app.clone(), path: path.into(), line: entry.line };
                            config.apply(entry, source, path, &mut diagnostics);
                        }
                    }
                    diagnostics.extend(file.problems.iter().map(|p| format!("{}:{}: {}", path.display(), p.0, p.1)));
                }
            }
        }
        for spec in inputs.keys {
            let var = spec.env_var();
            if let Some(text) = (inputs.env)(&var) {
                match parse_value(spec, &RawValue::Text(text.clone())) {
                    Ok(v) => {
                        config.values.insert(spec.key, (v, Source::Env(var)));
                    }
                    Err(e) => diagnostics.push(format!("${var}={text:?}: {e}; keeping {}", config.values[spec.key].0)),
                }
            }
        }
        (config, diagnostics)
    }

    /// Applies `stereoshim top`'s live settings (plain global keys; above every other source: the
    /// user changed them while the app runs). A file that does not parse changes nothing.
    pub fn apply_live(&mut self, path: &Path, text: &str, diagnostics: &mut Vec<String>) {
        match parse_file(text) {
            Err(msg) => diagnostics.push(format!("{}: {msg}; live settings ignored", path.display())),
            Ok(file) => {
                for entry in &file.global {
                    self.apply(entry, Source::Live { path: path.into(), line: entry.line }, path, diagnostics);
                }
            }
        }
    }

    fn apply(&mut self, entry: &Entry, source: Source, path: &Path, diagnostics: &mut Vec<String>) {
        let Some(spec) = self.keys.iter().find(|k| k.key == entry.key) else {
            diagnostics.push(format!("{}:{}: unknown key `{}` ignored", path.display(), entry.line, entry.key));
            return;
        };
        match parse_value(spec, &entry.value) {
            Ok(v) => {
                self.values.insert(spec.key, (v, source));
            }
            Err(e) => diagnostics.push(format!(
                "{}:{}: `{}`: {e}; keeping {}",
                path.display(),
                entry.line,
                entry.key,
                self.values[spec.key].0
            )),
        }
    }

    pub fn value(&self, key: &str) -> &Value {
        &self.values.get(key).unwrap_or_else(|| panic!("config key `{key}` is not a registered key")).0
    }

    pub fn source(&self, key: &str) -> &Source {
        &self.values.get(key).unwrap_or_else(|| panic!("config key `{key}` is not a registered key")).1
    }

    pub fn bool(&self, key: &str) -> bool {
        matches!(self.value(key), Value::Bool(true))
    }

    pub fn choice(&self, key: &str) -> &'static str {
        match self.value(key) {
            Value::Choice(c) => c,
            other => panic!("config key `{key}` is not a choice: {other:?}"),
        }
    }

    pub fn float(&self, key: &str) -> f64 {
        match self.value(key) {
            Value::Float(x) => *x,
            other => panic!("config key `{key}` is not a number: {other:?}"),
        }
    }

    pub fn text(&self, key: &str) -> &str {
        match self.value(key) {
            Value::Text(t) => t,
            other => panic!("config key `{key}` is not text: {other:?}"),
        }
    }

    /// The keys it was resolved against.
    pub fn keys(&self) -> &'static [KeySpec] {
        self.keys
    }

    /// The master switch.
    pub fn enabled(&self) -> bool {
        self.bool("enabled")
    }

    /// Whether the layer logic of `call` must fail on purpose (`debug.fail_in`).
    pub fn fails_in(&self, call: &str) -> bool {
        self.text("debug.fail_in").split(',').any(|c| c.trim() == call)
    }

    /// Every key with its value and source, in key order.
    pub fn entries(&self) -> impl Iterator<Item = (&'static str, &Value, &Source)> {
        self.values.iter().map(|(k, (v, s))| (*k, v, s))
    }
}

/// The default config file: `$STEREOSHIM_CONFIG`, else `$XDG_CONFIG_HOME/stereoshim/config.toml`,
/// else `~/.config/stereoshim/config.toml`.
pub fn default_path(env: &dyn Fn(&str) -> Option<String>) -> Option<PathBuf> {
    if let Some(p) = env("STEREOSHIM_CONFIG").filter(|p| !p.is_empty()) {
        return Some(p.into());
    }
    let base = env("XDG_CONFIG_HOME")
        .filter(|p| !p.is_empty())
        .map(PathBuf::from)
        .or_else(|| env("HOME").map(|h| Path::new(&h).join(".config")))?;
    Some(base.join("stereoshim").join("config.toml"))
}

/// Loads and resolves the configuration from the process environment and the default file.
pub fn load(keys: &'static [KeySpec], app_names: &[&str]) -> (Config, Vec<String>) {
    load_from(keys, default_path(&|k| std::env::var(k).ok()).as_deref(), app_names)
}

/// Resolves the configuration from the process environment and the file at `path`.
pub fn load_from(keys: &'static [KeySpec], path: Option<&Path>, app_names: &[&str]) -> (Config, Vec<String>) {
    let env = |k: &str| std::env::var(k).ok();
    let text = path.and_then(|p| std::fs::read_to_string(p).ok());
    let file = match (path, &text) {
        (Some(p), Some(t)) => Some((p, t.as_str())),
        _ => None,
    };
    Config::resolve(&Inputs { keys, file, app_names, env: &env })
}

/// A value as written, before it is checked against its key.
#[derive(Clone, Debug, PartialEq)]
enum RawValue {
    Bool(bool),
    Number(f64),
    Text(String),
    Other(&'static str),
}

#[derive(Debug)]
struct Entry {
    key: String,
    value: RawValue,
    line: usize,
}

#[derive(Debug, Default)]
struct File {
    global: Vec<Entry>,
    apps: Vec<(String, Vec<Entry>)>,
    /// (line, message) for structure the file should not have.
    problems: Vec<(usize, String)>,
}

fn line_of(text: &str, offset: usize) -> usize {
    text[..offset.min(text.len())].bytes().filter(|&b| b == b'\n').count() + 1
}

fn parse_file(text: &str) -> Result<File, String> {
    let root = toml::de::DeTable::parse(text).map_err(|e| {
        let line = e.span().map(|s| line_of(text, s.start));
        match line {
            Some(l) => format!("line {l}: {}", e.message()),
            None => e.message().to_string(),
        }
    })?;
    let mut file = File::default();
    for (key, value) in root.get_ref() {
        let line = line_of(text, key.span().start);
        if key.get_ref().as_ref() == "app" {
            let toml::de::DeValue::Table(apps) = value.get_ref() else {
                file.problems.push((line, "`app` must be a table of per-application sections".into()));
                continue;
            };
            for (name, section) in apps {
                let line = line_of(text, name.span().start);
                match section.get_ref() {
                    toml::de::DeValue::Table(t) => {
                        let mut entries = Vec::new();
                        flatten(text, "", t, &mut entries, &mut file.problems);
                        file.apps.push((name.get_ref().to_string(), entries));
                    }
                    _ => file.problems.push((line, format!("`app.{}` must be a table", name.get_ref()))),
                }
            }
        } else {
            flatten_one(text, "", key.get_ref(), value, line, &mut file.global, &mut file.problems);
        }
    }
    Ok(file)
}

fn flatten(
    text: &str,
    prefix: &str,
    table: &toml::de::DeTable<'_>,
    out: &mut Vec<Entry>,
    problems: &mut Vec<(usize, String)>,
) {
    for (key, value) in table {
        let line = line_of(text, key.span().start);
        flatten_one(text, prefix, key.get_ref(), value, line, out, problems);
    }
}

fn flatten_one(
    text: &str,
    prefix: &str,
    key: &str,
    value: &toml::Spanned<toml::de::DeValue<'_>>,
    line: usize,
    out: &mut Vec<Entry>,
    problems: &mut Vec<(usize, String)>,
) {
    use toml::de::DeValue;
    let full = if prefix.is_empty() { key.to_string() } else { format!("{prefix}.{key}") };
    let raw = match value.get_ref() {
        DeValue::Table(t) => return flatten(text, &full, t, out, problems),
        DeValue::Boolean(b) => RawValue::Bool(*b),
        DeValue::String(s) => RawValue::Text(s.to_string()),
        DeValue::Integer(i) => match i64::from_str_radix(&i.as_str().replace('_', ""), i.radix()) {
            Ok(n) => RawValue::Number(n as f64),
            Err(_) => {
                problems.push((line, format!("`{full}`: integer out of range")));
                return;
            }
        },
        DeValue::Float(f) => match f.as_str().replace('_', "").parse::<f64>() {
            Ok(x) => RawValue::Number(x),
            Err(_) => {
                problems.push((line, format!("`{full}`: unreadable number")));
                return;
            }
        },
        DeValue::Datetime(_) => RawValue::Other("a date"),
        DeValue::Array(_) => RawValue::Other("an array"),
    };
    out.push(Entry { key: full, value: raw, line });
}

fn parse_value(spec: &KeySpec, raw: &RawValue) -> Result<Value, String> {
    match (spec.kind, raw) {
        (Kind::Bool, RawValue::Bool(b)) => Ok(Value::Bool(*b)),
        (Kind::Bool, RawValue::Text(t)) => match t.trim().to_ascii_lowercase().as_str() {
            "true" | "1" | "on" | "yes" => Ok(Value::Bool(true)),
            "false" | "0" | "off" | "no" => Ok(Value::Bool(false)),
            _ => Err(format!("expected true or false, got {t:?}")),
        },
        (Kind::Choice(options), RawValue::Text(t)) => options
            .iter()
            .find(|o| o.eq_ignore_ascii_case(t.trim()))
            .map(|o| Value::Choice(o))
            .ok_or_else(|| format!("expected one of {}, got {t:?}", options.join("|"))),
        (Kind::Float { min, max }, RawValue::Number(x)) => check_range(*x, min, max),
        (Kind::Float { min, max }, RawValue::Text(t)) => match t.trim().parse::<f64>() {
            Ok(x) => check_range(x, min, max),
            Err(_) => Err(format!("expected a number, got {t:?}")),
        },
        (Kind::Text, RawValue::Text(t)) => Ok(Value::Text(t.clone())),
        (kind, raw) => Err(format!("expected {}, got {}", kind_name(kind), raw_name(raw))),
    }
}

fn check_range(x: f64, min: f64, max: f64) -> Result<Value, String> {
    if x.is_finite() && (min..=max).contains(&x) {
        Ok(Value::Float(x))
    } else {
        Err(format!("{x} is outside {min}..={max}"))
    }
}

fn kind_name(kind: Kind) -> String {
    match kind {
        Kind::Bool => "true or false".into(),
        Kind::Choice(o) => format!("one of {}", o.join("|")),
        Kind::Float { min, max } => format!("a number in {min}..={max}"),
        Kind::Text => "a string".into(),
    }
}

fn raw_name(raw: &RawValue) -> &'static str {
    match raw {
        RawValue::Bool(_) => "a boolean",
        RawValue::Number(_) => "a number",
        RawValue::Text(_) => "a string",
        RawValue::Other(what) => what,
    }
}

/// Watches the config file so feature settings apply while the app runs (tuning in the headset,
/// A/B benchmarks). Checks the file's modification time at most every `interval`; cheap enough to
/// ask once per frame.
#[derive(Debug)]
pub struct Watch {
    keys: &'static [KeySpec],
    path: Option<PathBuf>,
    app_names: Vec<String>,
    interval: std::time::Duration,
    /// `stereoshim top`'s folder and this process's pid (`core::live`), when there is a folder.
    live: Option<(PathBuf, u32)>,
    state: std::sync::Mutex<WatchState>,
}

#[derive(Debug)]
struct WatchState {
    modified: Option<std::time::SystemTime>,
    /// The live settings file's modification time while `top`'s heartbeat is fresh, else None.
    live: Option<std::time::SystemTime>,
    checked: std::time::Instant,
}

impl Watch {
    pub fn new(keys: &'static [KeySpec], app_names: &[&str], interval: std::time::Duration) -> Watch {
        let path = default_path(&|k| std::env::var(k).ok());
        let modified = path.as_ref().and_then(|p| std::fs::metadata(p).and_then(|m| m.modified()).ok());
        Watch {
            keys,
            path,
            app_names: app_names.iter().map(|s| s.to_string()).collect(),
            interval,
            live: None,
            state: std::sync::Mutex::new(WatchState { modified, live: None, checked: std::time::Instant::now() }),
        }
    }

    /// Also applies `stereoshim top`'s live settings for process `pid` from `folder`
    /// (`core::live::folder`) while its heartbeat is fresh.
    pub fn with_live(mut self, folder: PathBuf, pid: u32) -> Watch {
        self.live = Some((folder, pid));
        self
    }

    /// The live settings file and its modification time, while `top` watches.
    fn live_settings(&self) -> Option<(PathBuf, std::time::SystemTime)> {
        let (folder, pid) = self.live.as_ref()?;
        if !crate::core::live::fresh(crate::core::live::heartbeat_mtime(folder, *pid), std::time::SystemTime::now()) {
            return None;
        }
        let path = crate::core::live::settings_file(folder, *pid);
        let modified = std::fs::metadata(&path).and_then(|m| m.modified()).ok()?;
        Some((path, modified))
    }

    /// The newly resolved configuration when the file changed since the last look.
    pub fn poll(&self) -> Option<(Config, Vec<String>)> {
        if self.path.is_none() && self.live.is_none() {
            return None;
        }
        let mut st = self.state.lock().unwrap_or_else(|e| e.into_inner());
        if st.checked.elapsed() < self.interval {
            return None;
        }
        st.checked = std::time::Instant::now();
        let modified = self.path.as_ref().and_then(|p| std::fs::metadata(p).and_then(|m| m.modified()).ok());
        let live = self.live_settings();
        let live_modified = live.as_ref().map(|(_, m)| *m);
        if modified == st.modified && live_modified == st.live {
            return None;
        }
        st.modified = modified;
        st.live = live_modified;
        drop(st);
        let names: Vec<&str> = self.app_names.iter().map(String::as_str).collect();
        let (mut config, mut diagnostics) = load_from(self.keys, self.path.as_deref(), &names);
        if let Some((path, _)) = live {
            // Read now: a file replaced since its time was taken is read again at the next poll.
            if let Ok(text) = std::fs::read_to_string(&path) {
                config.apply_live(&path, &text, &mut diagnostics);
            }
        }
        Some((config, diagnostics))
    }
}

/// Keys whose values differ between two configurations (for the reload log line).
pub fn changed_keys(a: &Config, b: &Config) -> Vec<&'static str> {
    a.keys.iter().map(|k| k.key).filter(|k| b.values.contains_key(k) && a.value(k) != b.value(k)).collect()
}

#[cfg(test)]
mod watch_tests {
    use super::*;

    #[test]
    fn wrong_types_and_ranges() {
        let spec = KeySpec { key: "x", kind: Kind::Float { min: 0.0, max: 90.0 }, default: "1", doc: "" };
        assert_eq!(parse_value(&spec, &RawValue::Number(45.0)), Ok(Value::Float(45.0)));
        assert!(parse_value(&spec, &RawValue::Number(91.0)).is_err());
        assert!(parse_value(&spec, &RawValue::Text("nan".into())).is_err());
        assert!(parse_value(&spec, &RawValue::Bool(true)).unwrap_err().contains("got a boolean"));
        assert_eq!(parse_value(&spec, &RawValue::Text(" 12.5 ".into())), Ok(Value::Float(12.5)));
    }

    /// The one key the test writes (the registry's full list is tested in the registry).
    const KEYS: &[KeySpec] = &[KeySpec { key: "mask.enabled", kind: Kind::Bool, default: "false", doc: "" }];

    #[test]
    fn reload_sees_a_changed_file_once() {
        let dir = std::env::temp_dir().join(format!("stereoshim-watch-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("config.toml");
        std::fs::write(&path, "mask.enabled = false\n").unwrap();
        let watch = Watch {
            keys: KEYS,
            path: Some(path.clone()),
            app_names: vec![],
            interval: std::time::Duration::ZERO,
            live: None,
            state: std::sync::Mutex::new(WatchState {
                modified: std::fs::metadata(&path).and_then(|m| m.modified()).ok(),
                live: None,
                checked: std::time::Instant::now(),
            }),
        };
        assert!(watch.poll().is_none());
        // A different modification time, as a later write has (coarse clocks can repeat one).
        let later = std::fs::metadata(&path).unwrap().modified().unwrap() + std::time::Duration::from_secs(2);
        std::fs::write(&path, "mask.enabled = true\n").unwrap();
        std::fs::File::options().write(true).open(&path).unwrap().set_modified(later).unwrap();
        let (reloaded, diagnostics) = watch.poll().expect("a changed file is reloaded");
        assert!(diagnostics.is_empty(), "{diagnostics:?}");
        assert!(reloaded.bool("mask.enabled"));
        assert!(watch.poll().is_none());
        let (a, _) = Config::resolve(&Inputs { keys: KEYS, file: Some((&path, "mask.enabled = true")), app_names: &[], env: &|_| None });
        assert_eq!(changed_keys(&Config::defaults(KEYS), &a), vec!["mask.enabled"]);
        std::fs::remove_dir_all(&dir).ok();
    }

    /// `stereoshim top`'s live settings apply above the file while its heartbeat is fresh, and
    /// go when it stops.
    #[test]
    fn live_settings_while_top_watches() {
        use crate::core::live;
        let dir = std::env::temp_dir().join(format!("stereoshim-watch-live-{}", std::process::id()));
        let folder = dir.join("live");
        std::fs::create_dir_all(&folder).unwrap();
        let path = dir.join("config.toml");
        std::fs::write(&path, "mask.enabled = false\n").unwrap();
        let pid = 4242;
        let watch = Watch::new(KEYS, &[], std::time::Duration::ZERO).with_live(folder.clone(), pid);
        let watch = Watch { path: Some(path.clone()), ..watch };
        // Settings without a heartbeat: not applied.
        std::fs::write(live::settings_file(&folder, pid), "mask.enabled = true\n").unwrap();
        let first = watch.poll();
        assert!(first.is_none_or(|(c, _)| !c.bool("mask.enabled")));
        std::fs::write(live::heartbeat_file(&folder, pid), "").unwrap();
        let (c, d) = watch.poll().expect("top's settings apply");
        assert!(d.is_empty(), "{d:?}");
        assert!(c.bool("mask.enabled"));
        assert!(matches!(c.source("mask.enabled"), Source::Live { line: 1, .. }), "{}", c.source("mask.enabled"));
        assert!(watch.poll().is_none(), "nothing changed");
        // A heartbeat older than HEARTBEAT_FRESH: top is gone, the file's value is back.
        let old = std::time::SystemTime::now() - live::HEARTBEAT_FRESH - std::time::Duration::from_secs(1);
        std::fs::File::options().write(true).open(live::heartbeat_file(&folder, pid)).unwrap().set_modified(old).unwrap();
        let (c, _) = watch.poll().expect("top stopped watching");
        assert!(!c.bool("mask.enabled"));
        std::fs::remove_dir_all(&dir).ok();
    }
}

