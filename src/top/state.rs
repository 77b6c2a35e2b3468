//! What `stereoshim top` knows and does between two screens: the app watched, its frames, the
//! config as the app sees it, the keys' effects (config edits, live A/B settings) and the
//! messages for the person. No terminal here: `ui` draws a [`State`], `mod.rs` feeds it keys and
//! frames, and tests drive it directly.
#![forbid(unsafe_code)]

use super::ab::{self, AbRun, Outcome};
use super::channel::{App, Channel, Tail};
use super::config_edit::{self, Setting};
use super::model::{FrameView, Recent};
use crate::core::config::{Config, Inputs};
use std::path::PathBuf;

/// Frames kept for the screen (the graph and the last second).
const KEPT_FRAMES: usize = 2048;

/// A/B defaults: stretches of this many frames, this many off/on cycles per comparison.
pub const AB_PERIOD: u64 = 30;
pub const AB_CYCLES: usize = 4;

/// A key press's meaning.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Action {
    ToggleMask,
    ToggleFoveation,
    NextPreset,
    NextMethod,
    ToggleFarField,
    NextUpscale,
    ToggleOverlay,
    AbAll,
    AbEach,
    KeepPaying,
    StopAb,
    Quit,
}

impl Action {
    /// The key for a character typed.
    pub fn of_key(c: char) -> Option<Action> {
        Some(match c {
            'm' => Action::ToggleMask,
            'f' => Action::ToggleFoveation,
            'p' => Action::NextPreset,
            'r' => Action::NextMethod,
            'd' => Action::ToggleFarField,
            'u' => Action::NextUpscale,
            'o' => Action::ToggleOverlay,
            'b' => Action::AbAll,
            'e' => Action::AbEach,
            'k' => Action::KeepPaying,
            'x' => Action::StopAb,
            'q' => Action::Quit,
            _ => return None,
        })
    }
}

/// The upscale scales `u` steps through (off first).
pub const UPSCALE_STEPS: [Option<f64>; 4] = [None, Some(0.77), Some(0.67), Some(0.59)];

pub struct State {
    pub app: App,
    pub channel: Channel,
    tail: Tail,
    pub recent: Recent,
    /// The app's `STEREOSHIM_*` environment (it wins over the config file).
    pub env: Vec<(String, String)>,
    /// The config as the app's layer resolves it (file and environment; not the live settings).
    pub config: Config,
    pub ab: Option<AbRun>,
    /// The outcomes of the last A/B that finished.
    pub outcomes: Vec<Outcome>,
    /// Whether the last finished A/B compared each feature (so `k` may act on it).
    outcomes_each: bool,
    pub ab_period: u64,
    pub ab_cycles: usize,
    /// The last thing a key did, or why it did nothing.
    pub message: String,
    /// Lines read from the stream that were not frame lines.
    pub bad_lines: u64,
}

impl State {
    pub fn new(app: App, channel: Channel, env: Vec<(String, String)>) -> State {
        let tail = Tail::at_end(&channel.stream());
        let mut s = State {
            app,
            channel,
            tail,
            recent: Recent::new(KEPT_FRAMES),
            env,
            config: Config::defaults(crate::registry::keys()),
            ab: None,
            outcomes: Vec::new(),
            outcomes_each: false,
            ab_period: AB_PERIOD,
            ab_cycles: AB_CYCLES,
            message: String::new(),
            bad_lines: 0,
        };
        s.reload_config();
        s
    }

    pub fn config_path(&self) -> Option<&PathBuf> {
        self.app.config.as_ref()
    }

    /// Resolves the config as the app's layer does (its file, its section, its environment).
    pub fn reload_config(&mut self) {
        let text = self.config_path().and_then(|p| std::fs::read_to_string(p).ok()).unwrap_or_default();
        let path = self.config_path().cloned().unwrap_or_default();
        let env = self.env.clone();
        let lookup = move |k: &str| env.iter().find(|(n, _)| n == k).map(|(_, v)| v.clone());
        let names = [self.app.app.as_str(), self.app.exe.as_str()];
        let (c, _) = Config::resolve(&Inputs { keys: crate::registry::keys(), file: Some((&path, &text)), app_names: &names, env: &lookup });
        self.config = c;
    }

    /// The live settings `top` hands the layer now: its GPU timer on (the frame time `top`
    /// shows), and the running A/B's stretch.
    pub fn live_settings(&self) -> Vec<(String, String)> {
        let mut v = vec![("stats.gpu_time".to_string(), "true".to_string())];
        if let Some(s) = self.ab.as_ref().and_then(|a| a.settings()) {
            v.extend(s.iter().map(|(k, on)| (k.to_string(), on.to_string())));
        }
        v
    }

    /// Reads the stream's new frames; returns true when the A/B's settings changed (write them).
    pub fn poll_frames(&mut self) -> bool {
        let mut changed = false;
        for line in self.tail.read(&self.channel.stream()) {
            let Some(f) = FrameView::parse(&line) else {
                self.bad_lines += 1;
                continue;
            };
            if let Some(ab) = &mut self.ab {
                changed |= ab.frame(&f);
            }
            self.recent.push(f);
        }
        if self.ab.as_ref().is_some_and(AbRun::finished) {
            let ab = self.ab.take().expect("checked");
            self.message = match &ab.failed {
                Some(e) => format!("A/B stopped: {e}"),
                None => "A/B done: the features are back as the config says".to_string(),
            };
            self.outcomes = ab.outcomes;
            if !self.outcomes.is_empty() {
                // The headset's overlay shows it too.
                let lines: Vec<String> = self.outcomes.iter().map(Outcome::line).collect();
                if let Err(e) = self.channel.write_ab(&lines) {
                    self.message.push_str(&format!(" (the overlay cannot show it: {e})"));
                }
            }
            changed = true;
        }
        changed
    }

    /// Which of the switchable features the app's config has on.
    pub fn features_on(&self) -> Vec<&'static str> {
        ab::SWITCHABLE.iter().filter(|(k, _)| self.config.bool(k)).map(|(k, _)| *k).collect()
    }

    /// The environment variable that overrides `key` in the app, if any.
    pub fn env_override(&self, key: &str) -> Option<String> {
        let var = format!("STEREOSHIM_{}", key.replace('.', "_").to_uppercase());
        self.env.iter().any(|(k, _)| *k == var).then_some(var)
    }

    /// Applies a key; returns (the config changed, the live settings changed, quit).
    pub fn act(&mut self, a: Action) -> (bool, bool, bool) {
        let flip = |s: &State, k: &str| Setting::Bool(!s.config.bool(k));
        let cycle = |s: &State, k: &str, all: &[&str]| {
            let now = s.config.choice(k);
            let i = all.iter().position(|v| *v == now).map_or(0, |i| (i + 1) % all.len());
            Setting::Text(all[i].to_string())
        };
        match a {
            Action::Quit => return (false, false, true),
            Action::ToggleMask => return (self.edit(&[("mask.enabled", flip(self, "mask.enabled"))]), false, false),
            Action::ToggleFoveation => return (self.edit(&[("foveation.enabled", flip(self, "foveation.enabled"))]), false, false),
            Action::ToggleFarField => return (self.edit(&[("far_field.enabled", flip(self, "far_field.enabled"))]), false, false),
            Action::ToggleOverlay => return (self.edit(&[("overlay.enabled", flip(self, "overlay.enabled"))]), false, false),
            Action::NextPreset => return (self.edit(&[("foveation.preset", cycle(self, "foveation.preset", &["subtle", "balanced", "aggressive"]))]), false, false),
            Action::NextMethod => return (self.edit(&[("foveation.method", cycle(self, "foveation.method", &["auto", "vrs", "rdm"]))]), false, false),
            Action::NextUpscale => {
                let now = self.config.bool("upscale.enabled").then(|| self.config.float("upscale.scale"));
                let i = UPSCALE_STEPS.iter().position(|s| s.zip(now).is_some_and(|(a, b)| (a - b).abs() < 0.005) || (s.is_none() && now.is_none())).map_or(0, |i| (i + 1) % UPSCALE_STEPS.len());
                let edits = match UPSCALE_STEPS[i] {
                    None => vec![("upscale.enabled", Setting::Bool(false))],
                    Some(scale) => vec![("upscale.enabled", Setting::Bool(true)), ("upscale.scale", Setting::Float(scale))],
                };
                let changed = self.edit(&edits);
                if changed {
                    // The app is told its image size when it makes its swapchains.
                    self.message.push_str(" - the upscale changes the app's image size: it applies at the app's next session");
                }
                return (changed, false, false);
            }
            Action::AbAll | Action::AbEach => {
                let on = self.features_on();
                if on.is_empty() {
                    self.message = "A/B: no feature that can be switched live is on (m, f, d turn them on)".into();
                    return (false, false, false);
                }
                let each = a == Action::AbEach;
                if each && on.len() < 2 {
                    self.message = "A/B per feature needs two features on or more (b compares the one that is on)".into();
                    return (false, false, false);
                }
                self.ab = Some(AbRun::new(ab::plan(&on, each), each, self.ab_period, self.ab_cycles));
                self.outcomes_each = each;
                self.outcomes.clear();
                self.message = format!("A/B started: {} frames off, then on, {} cycles per comparison", self.ab_period, self.ab_cycles);
            }
            Action::StopAb => {
                if self.ab.take().is_some() {
                    self.message = "A/B stopped: the features are back as the config says".into();
                } else {
                    return (false, false, false);
                }
            }
            Action::KeepPaying => {
                if !self.outcomes_each || self.outcomes.is_empty() {
                    self.message = "k keeps what pays after a per-feature A/B (e)".into();
                    return (false, false, false);
                }
                let off: Vec<&'static str> = self.outcomes.iter().filter(|o| !o.pays()).filter_map(|o| o.feature).collect();
                if off.is_empty() {
                    self.message = "every feature paid in every cycle: nothing turned off".into();
                    return (false, false, false);
                }
                let edits: Vec<(&str, Setting)> = off.iter().map(|k| (*k, Setting::Bool(false))).collect();
                let changed = self.edit(&edits);
                return (changed, false, false);
            }
        }
        (false, true, false)
    }

    /// Writes `edits` into the app's section of the config file (atomically); says what it did.
    fn edit(&mut self, edits: &[(&str, Setting)]) -> bool {
        let Some(path) = self.config_path().cloned() else {
            self.message = "the app's layer reads no config file (no HOME or XDG_CONFIG_HOME in its environment)".into();
            return false;
        };
        let text = std::fs::read_to_string(&path).unwrap_or_default();
        let mut out = text.clone();
        for (k, v) in edits {
            match config_edit::set(&out, &self.app.app, k, v) {
                Ok(t) => out = t,
                Err(e) => {
                    self.message = format!("{}: {e}", path.display());
                    return false;
                }
            }
        }
        if let Some(dir) = path.parent() {
            let _ = std::fs::create_dir_all(dir);
        }
        let tmp = path.with_extension("toml.stereoshim-top");
        if let Err(e) = std::fs::write(&tmp, &out).and_then(|()| std::fs::rename(&tmp, &path)) {
            self.message = format!("{}: {e}", path.display());
            return false;
        }
        let said: Vec<String> = edits.iter().map(|(k, v)| format!("{k} = {}", v.toml())).collect();
        self.message = format!("{} in [app.\"{}\"] of {}", said.join(", "), self.app.app, path.display());
        let env: Vec<String> = edits.iter().filter_map(|(k, _)| self.env_override(k)).collect();
        if !env.is_empty() {
            self.message.push_str(&format!(" - but the app's environment sets {}, which wins", env.join(", ")));
        }
        if self.ab.is_some() {
            self.message.push_str(" - the running A/B decides these until it ends");
        }
        self.reload_config();
        true
    }
}

/// The app's `STEREOSHIM_*` environment, from `/proc/<pid>/environ` (empty when unreadable).
pub fn app_environment(pid: u32) -> Vec<(String, String)> {
    let Ok(bytes) = std::fs::read(format!("/proc/{pid}/environ")) else { return Vec::new() };
    bytes
        .split(|b| *b == 0)
        .filter_map(|kv| {
            let kv = String::from_utf8_lossy(kv);
            let (k, v) = kv.split_once('=')?;
            k.starts_with("STEREOSHIM_").then(|| (k.to_string(), v.to_string()))
        })
        .collect()
}
