//! Screenshots: a person asks (`stereoshim screenshot`, or a touch of `screenshot.trigger`) and the
//! layer writes the next submitted frame's eye images as PNGs, as the runtime gets them (with
//! every feature's work in them, the debug tints included), without stalling the app's frame: the
//! copy runs on the GPU in a layer submission at the image's release, the read-back and the PNG
//! encoding on a thread of the layer's. `rules` holds the decisions, `xr` the trigger (looked at
//! from `xrBeginFrame`, throttled), `vk` the copies and `write` the files.

pub mod command;
pub mod rules;
pub(crate) mod vk;
mod write;
pub(crate) mod xr;

use crate::core::config::{Config, Kind, KeySpec};
use crate::core::stats::{json_counts, Counters};
use std::collections::BTreeMap;

/// Screenshot keys.
pub const KEYS: &[KeySpec] = &[
    KeySpec {
        key: "screenshot.enabled",
        kind: Kind::Bool,
        default: "true",
        doc: "let `stereoshim screenshot` (and screenshot.trigger) ask for screenshots: the layer looks at its trigger files at most every 100 ms",
    },
    KeySpec { key: "screenshot.dir", kind: Kind::Text, default: "", doc: "folder for screenshots (empty: $XDG_PICTURES_DIR/stereoshim, else ~/Pictures/stereoshim)" },
    KeySpec { key: "screenshot.trigger", kind: Kind::Text, default: "", doc: "a file whose every touch (new modification time) takes a screenshot (empty: none besides `stereoshim screenshot`)" },
];

/// Screenshot settings.
#[derive(Clone, Debug, PartialEq)]
pub struct ScreenshotSettings {
    pub enabled: bool,
    pub dir: String,
    pub trigger: String,
}

impl ScreenshotSettings {
    pub fn from_config(c: &Config) -> ScreenshotSettings {
        ScreenshotSettings { enabled: c.bool("screenshot.enabled"), dir: c.text("screenshot.dir").to_string(), trigger: c.text("screenshot.trigger").to_string() }
    }
}

/// A frame's screenshot counters: views copied for a screenshot, and views left out by reason.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ScreenshotStats {
    pub views: u64,
    pub not_applied: BTreeMap<&'static str, u64>,
}

impl Counters for ScreenshotStats {
    const ID: &'static str = "screenshot";
    const LABEL: &'static str = "screenshot";
    fn merge(&mut self, o: &Self) {
        self.views += o.views;
        for (k, v) in &o.not_applied {
            *self.not_applied.entry(*k).or_insert(0) += v;
        }
    }
    fn applied(&self) -> u64 {
        self.views
    }
    fn left_alone(&self) -> Vec<(&'static str, u64)> {
        self.not_applied.iter().map(|(k, v)| (*k, *v)).collect()
    }
    fn hint_for(&self, reason: &str) -> &'static str {
        match reason {
            "format" => "the swapchain's format is not one the layer converts (8-bit RGBA/BGRA, A2B10G10R10, RGBA16F)",
            "usage" => "the app's swapchain image lacks TRANSFER_SRC usage",
            "multisampled" => "multisampled swapchain images are not copied",
            _ => crate::core::stats::common_hint(reason),
        }
    }
    fn line(&self) -> String {
        format!("screenshot.views={}", self.views)
    }
    /// Only frames that had a screenshot get the field: stats files stay as they were otherwise.
    fn json(&self, record: &mut serde_json::Map<String, serde_json::Value>) {
        if *self == ScreenshotStats::default() {
            return;
        }
        let mut o = serde_json::Map::new();
        o.insert("views".into(), self.views.into());
        o.insert("not_applied".into(), json_counts(self.not_applied.iter().map(|(k, v)| (*k, *v))));
        record.insert("screenshot".into(), o.into());
    }
}
