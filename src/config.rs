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

/// Every key the layer reads. Features add their keys here.
/// The chassis' own keys; each feature declares its own (`crate::features::KEYS`).
const CORE_KEYS: &[KeySpec] = &[
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

/// Every key: the chassis' and every registered feature's, in that order.
pub fn keys() -> &'static [KeySpec] {
    static ALL: std::sync::OnceLock<Vec<KeySpec>> = std::sync::OnceLock::new();
    ALL.get_or_init(|| {
        let mut all: Vec<KeySpec> = Vec::new();
        // Features sharing a folder (both foveation methods) declare the folder's keys each.
        for spec in CORE_KEYS.iter().chain(crate::features::KEYS.iter().flat_map(|k| k.iter())).chain(crate::features::overlay::KEYS).chain(crate::features::upscale::KEYS).chain(crate::features::views::KEYS) {
            if !all.iter().any(|k| k.key == spec.key) {
                all.push(*spec);
            }
        }
        all
    })
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
}

impl fmt::Display for Source {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Source::Default => write!(f, "default"),
            Source::File { path, line } => write!(f, "{}:{line}", path.display()),
            Source::App { app, path, line } => write!(f, "{}:{line} [app.\"{app}\"]", path.display()),
            Source::Env(var) => write!(f, "${var}"),
        }
    }
}

/// The resolved configuration of one application.
#[derive(Clone, Debug)]
pub struct Config {
    values: BTreeMap<&'static str, (Value, Source)>,
}

/// What the resolution is given; the environment is a function so tests need not touch the
/// process environment.
pub struct Inputs<'a> {
    /// The config file's path and text, if one exists.
    pub file: Option<(&'a Path, &'a str)>,
    /// Names the app's section may be keyed by: `XrApplicationInfo::applicationName`, then the
    /// executable's file name.
    pub app_names: &'a [&'a str],
    pub env: &'a dyn Fn(&str) -> Option<String>,
}

impl Config {
    /// All defaults, as the layer runs when nothing is configured.
    pub fn defaults() -> Config {
        let values = keys()
            .iter()
            .map(|k| (k.key, (parse_value(k, &RawValue::Text(k.default.into())).expect("valid default"), Source::Default)))
            .collect();
        Config { values }
    }

    /// Resolves the configuration; every problem found is returned as one diagnostic line and the
    /// affected key keeps the value of the lower-precedence source.
    pub fn resolve(inputs: &Inputs<'_>) -> (Config, Vec<String>) {
        let mut config = Config::defaults();
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
        for spec in keys() {
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

    fn apply(&mut self, entry: &Entry, source: Source, path: &Path, diagnostics: &mut Vec<String>) {
        let Some(spec) = keys().iter().find(|k| k.key == entry.key) else {
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
        &self.values.get(key).unwrap_or_else(|| panic!("config key `{key}` is not in config::keys()")).0
    }

    pub fn source(&self, key: &str) -> &Source {
        &self.values.get(key).unwrap_or_else(|| panic!("config key `{key}` is not in config::keys()")).1
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
pub fn load(app_names: &[&str]) -> (Config, Vec<String>) {
    load_from(default_path(&|k| std::env::var(k).ok()).as_deref(), app_names)
}

/// Resolves the configuration from the process environment and the file at `path`.
pub fn load_from(path: Option<&Path>, app_names: &[&str]) -> (Config, Vec<String>) {
    let env = |k: &str| std::env::var(k).ok();
    let text = path.and_then(|p| std::fs::read_to_string(p).ok());
    let file = match (path, &text) {
        (Some(p), Some(t)) => Some((p, t.as_str())),
        _ => None,
    };
    Config::resolve(&Inputs { file, app_names, env: &env })
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

#[cfg(test)]
mod tests {
    use super::*;

    fn resolve(file: Option<&str>, apps: &[&str], env: &[(&str, &str)]) -> (Config, Vec<String>) {
        let env: Vec<(String, String)> = env.iter().map(|(k, v)| (k.to_string(), v.to_string())).collect();
        let lookup = move |k: &str| env.iter().find(|(key, _)| key == k).map(|(_, v)| v.clone());
        let path = Path::new("/cfg/config.toml");
        Config::resolve(&Inputs { file: file.map(|t| (path, t)), app_names: apps, env: &lookup })
    }

    #[test]
    fn defaults_without_file_or_env() {
        let (c, d) = resolve(None, &[], &[]);
        assert!(d.is_empty());
        assert!(c.enabled());
        assert_eq!(c.choice("log.level"), "info");
        assert_eq!(c.source("enabled"), &Source::Default);
    }

    #[test]
    fn env_var_names_follow_keys() {
        let names: Vec<String> = keys().iter().map(KeySpec::env_var).collect();
        assert!(names.contains(&"STEREOSHIM_LOG_LEVEL".to_string()));
        assert!(names.contains(&"STEREOSHIM_VULKAN_FRAGMENT_SHADING_RATE".to_string()));
        assert!(names.contains(&"STEREOSHIM_ENABLED".to_string()));
    }

    #[test]
    fn file_then_app_section_then_env() {
        let file = "enabled = false\n[log]\nlevel = \"warn\"\n\n[app.\"My Game\"]\nlog.level = \"debug\"\nenabled = true\n";
        let (c, d) = resolve(Some(file), &["Other"], &[]);
        assert!(d.is_empty(), "{d:?}");
        assert!(!c.enabled());
        assert_eq!(c.choice("log.level"), "warn");
        assert_eq!(c.source("log.level"), &Source::File { path: "/cfg/config.toml".into(), line: 3 });

        let (c, _) = resolve(Some(file), &["My Game", "game.exe"], &[]);
        assert!(c.enabled());
        assert_eq!(c.choice("log.level"), "debug");
        assert!(matches!(c.source("log.level"), Source::App { line: 6, .. }));

        // The app picked its section; the user's environment still wins over it.
        let (c, _) = resolve(Some(file), &["My Game"], &[("STEREOSHIM_LOG_LEVEL", "TRACE"), ("STEREOSHIM_ENABLED", "0")]);
        assert_eq!(c.choice("log.level"), "trace");
        assert!(!c.enabled());
        assert_eq!(c.source("enabled"), &Source::Env("STEREOSHIM_ENABLED".into()));
    }

    #[test]
    fn executable_name_is_the_fallback_section() {
        let file = "[app.\"xr-scene\"]\nenabled = false\n";
        let (c, _) = resolve(Some(file), &["Some Title", "xr-scene"], &[]);
        assert!(!c.enabled());
    }

    #[test]
    fn syntax_error_reports_line_and_keeps_defaults() {
        let (c, d) = resolve(Some("enabled = true\nlog.level = \"warn\n"), &[], &[]);
        assert_eq!(d.len(), 1, "{d:?}");
        assert!(d[0].contains("/cfg/config.toml: line 2"), "{d:?}");
        assert_eq!(c.choice("log.level"), "info");
    }

    #[test]
    fn bad_values_cost_only_their_key() {
        let file = "enabled = \"yes please\"\nlog.level = \"loud\"\nvulkan.fragment_shading_rate = \"on\"\nnot.a.key = 3\napp = 5\n";
        let (c, d) = resolve(Some(file), &[], &[]);
        assert!(c.enabled());
        assert_eq!(c.choice("log.level"), "info");
        assert_eq!(c.choice("vulkan.fragment_shading_rate"), "on");
        let joined = d.join("\n");
        assert!(joined.contains(":1: `enabled`: expected true or false"), "{joined}");
        assert!(joined.contains(":2: `log.level`: expected one of off|error|warn|info|debug|trace"), "{joined}");
        assert!(joined.contains(":4: unknown key `not.a.key`"), "{joined}");
        assert!(joined.contains(":5: `app` must be a table"), "{joined}");
        assert_eq!(d.len(), 4, "{joined}");
    }

    #[test]
    fn bad_env_value_keeps_file_value() {
        let (c, d) = resolve(Some("log.level = \"warn\""), &[], &[("STEREOSHIM_LOG_LEVEL", "chatty")]);
        assert_eq!(c.choice("log.level"), "warn");
        assert_eq!(d.len(), 1);
        assert!(d[0].contains("$STEREOSHIM_LOG_LEVEL=\"chatty\""), "{d:?}");
    }

    #[test]
    fn wrong_types_and_ranges() {
        let spec = KeySpec { key: "x", kind: Kind::Float { min: 0.0, max: 90.0 }, default: "1", doc: "" };
        assert_eq!(parse_value(&spec, &RawValue::Number(45.0)), Ok(Value::Float(45.0)));
        assert!(parse_value(&spec, &RawValue::Number(91.0)).is_err());
        assert!(parse_value(&spec, &RawValue::Text("nan".into())).is_err());
        assert!(parse_value(&spec, &RawValue::Bool(true)).unwrap_err().contains("got a boolean"));
        assert_eq!(parse_value(&spec, &RawValue::Text(" 12.5 ".into())), Ok(Value::Float(12.5)));
    }

    #[test]
    fn fail_in_lists_calls() {
        let (c, _) = resolve(None, &[], &[("STEREOSHIM_DEBUG_FAIL_IN", "xrEndFrame, vkCreateImage")]);
        assert!(c.fails_in("xrEndFrame"));
        assert!(c.fails_in("vkCreateImage"));
        assert!(!c.fails_in("xrBeginFrame"));
    }

    #[test]
    fn config_path_precedence() {
        let env = |k: &str| match k {
            "XDG_CONFIG_HOME" => Some("/x".to_string()),
            "HOME" => Some("/home/u".to_string()),
            _ => None,
        };
        assert_eq!(default_path(&env), Some(PathBuf::from("/x/stereoshim/config.toml")));
        let env2 = |k: &str| if k == "HOME" { Some("/home/u".to_string()) } else { None };
        assert_eq!(default_path(&env2), Some(PathBuf::from("/home/u/.config/stereoshim/config.toml")));
        let env3 = |k: &str| if k == "STEREOSHIM_CONFIG" { Some("/etc/s.toml".to_string()) } else { None };
        assert_eq!(default_path(&env3), Some(PathBuf::from("/etc/s.toml")));
    }
}

#[cfg(test)]
mod watch_tests {
    use super::*;

    #[test]
    fn reload_sees_a_changed_file_once() {
        let dir = std::env::temp_dir().join(format!("stereoshim-watch-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("config.toml");
        std::fs::write(&path, "mask.enabled = false\n").unwrap();
        let watch = Watch {
            path: Some(path.clone()),
            app_names: vec![],
            interval: std::time::Duration::ZERO,
            state: std::sync::Mutex::new(WatchState {
                modified: std::fs::metadata(&path).and_then(|m| m.modified()).ok(),
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
        let (a, _) = Config::resolve(&Inputs { file: Some((&path, "mask.enabled = true")), app_names: &[], env: &|_| None });
        assert_eq!(changed_keys(&Config::defaults(), &a), vec!["mask.enabled"]);
        std::fs::remove_dir_all(&dir).ok();
    }
}

#[cfg(test)]
mod docs_tests {
    /// docs/configuration.md documents every key with its default; this keeps the two in step.
    #[test]
    fn every_key_is_documented() {
        let doc = include_str!("../docs/configuration.md");
        for spec in super::keys() {
            let row = doc
                .lines()
                .find(|l| l.starts_with(&format!("| `{}` |", spec.key)))
                .unwrap_or_else(|| panic!("docs/configuration.md lacks a row for `{}`", spec.key));
            let default = if spec.default.is_empty() { "\"\"".to_string() } else { spec.default.to_string() };
            assert!(row.contains(&format!("| {default} |")), "docs/configuration.md: default of `{}` is not {default}", spec.key);
        }
    }
}

/// Watches the config file so feature settings apply while the app runs (tuning in the headset,
/// A/B benchmarks). Checks the file's modification time at most every `interval`; cheap enough to
/// ask once per frame.
#[derive(Debug)]
pub struct Watch {
    path: Option<PathBuf>,
    app_names: Vec<String>,
    interval: std::time::Duration,
    state: std::sync::Mutex<WatchState>,
}

#[derive(Debug)]
struct WatchState {
    modified: Option<std::time::SystemTime>,
    checked: std::time::Instant,
}

impl Watch {
    pub fn new(app_names: &[&str], interval: std::time::Duration) -> Watch {
        let path = default_path(&|k| std::env::var(k).ok());
        let modified = path.as_ref().and_then(|p| std::fs::metadata(p).and_then(|m| m.modified()).ok());
        Watch {
            path,
            app_names: app_names.iter().map(|s| s.to_string()).collect(),
            interval,
            state: std::sync::Mutex::new(WatchState { modified, checked: std::time::Instant::now() }),
        }
    }

    /// The newly resolved configuration when the file changed since the last look.
    pub fn poll(&self) -> Option<(Config, Vec<String>)> {
        let path = self.path.as_ref()?;
        let mut st = self.state.lock().unwrap_or_else(|e| e.into_inner());
        if st.checked.elapsed() < self.interval {
            return None;
        }
        st.checked = std::time::Instant::now();
        let modified = std::fs::metadata(path).and_then(|m| m.modified()).ok();
        if modified == st.modified {
            return None;
        }
        st.modified = modified;
        drop(st);
        let names: Vec<&str> = self.app_names.iter().map(String::as_str).collect();
        Some(load_from(Some(path), &names))
    }
}

/// Keys whose values differ between two configurations (for the reload log line).
pub fn changed_keys(a: &Config, b: &Config) -> Vec<&'static str> {
    keys().iter().map(|k| k.key).filter(|k| a.value(k) != b.value(k)).collect()
}
