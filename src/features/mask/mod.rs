//! The hidden-area mask: pixels the lens never shows are rejected by early depth test. `rules` is
//! the pure geometry and statistics; `vk` draws the mask's depth at the chassis' injection point.

pub mod rules;
pub mod source;
pub(crate) mod vk;
pub(crate) mod xr;

use crate::core::config::{Config, Kind, KeySpec};

/// The mask's config keys.
pub const KEYS: &[KeySpec] = &[
    KeySpec {
        key: "mask.enabled",
        kind: Kind::Bool,
        default: "false",
        doc: "hidden-area mask: reject the pixels the lens never shows by early depth test in every eye pass",
    },
    KeySpec {
        key: "mask.source",
        kind: Kind::Choice(&["auto", "runtime", "synthesized"]),
        default: "auto",
        doc: "auto: the runtime's XR_KHR_visibility_mask when it has one, else synthesized; runtime: only the runtime's; synthesized: always the configured lens shape",
    },
    KeySpec {
        key: "mask.synthesized.radius_deg",
        kind: Kind::Float { min: 10.0, max: 89.0 },
        default: "55",
        doc: "synthesized lens: horizontal half-angle of the visible ellipse around the view's optical axis, degrees",
    },
    KeySpec {
        key: "mask.synthesized.aspect",
        kind: Kind::Float { min: 0.25, max: 4.0 },
        default: "1",
        doc: "synthesized lens: vertical / horizontal half-angle of the visible ellipse",
    },
    KeySpec {
        key: "mask.debug",
        kind: Kind::Bool,
        default: "false",
        doc: "paint the masked area in a tint instead of leaving it at the clear colour (to see it in the headset and in captures)",
    },
];

/// `mask.source`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SourceSetting {
    Auto,
    Runtime,
    Synthesized,
}

/// The mask's typed settings (`mask.*` but `mask.intermediate`, which the chassis owns).
#[derive(Clone, Debug, PartialEq)]
pub struct MaskSettings {
    pub enabled: bool,
    pub source: SourceSetting,
    pub synthesized_radius_deg: f64,
    pub synthesized_aspect: f64,
    pub debug: bool,
}

impl MaskSettings {
    pub fn from_config(c: &Config) -> MaskSettings {
        MaskSettings {
            enabled: c.bool("mask.enabled"),
            source: match c.choice("mask.source") {
                "runtime" => SourceSetting::Runtime,
                "synthesized" => SourceSetting::Synthesized,
                _ => SourceSetting::Auto,
            },
            synthesized_radius_deg: c.float("mask.synthesized.radius_deg"),
            synthesized_aspect: c.float("mask.synthesized.aspect"),
            debug: c.bool("mask.debug"),
        }
    }
}
