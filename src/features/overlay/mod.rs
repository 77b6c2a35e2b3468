//! The in-headset stats overlay (`overlay.enabled`): a small head-locked quad the layer submits
//! after the app's layers at `xrEndFrame`, saying which features are on and what they saved in
//! the last second. Not a Vulkan plug-in (it never touches the app's passes): its settings and
//! pure rules live here, its OpenXR/Vulkan half in `xr` (called by the shell at `xrEndFrame` and when
//! sessions end).

pub mod rules;
pub(crate) mod xr;

use crate::core::config::{Config, Kind, KeySpec};

/// The overlay's config keys.
pub const KEYS: &[KeySpec] = &[
    KeySpec { key: "overlay.enabled", kind: Kind::Bool, default: "false", doc: "show a small head-locked stats panel in the headset (features on, what they saved last second, frame time)" },
    KeySpec { key: "overlay.position", kind: Kind::Choice(&["top", "bottom", "center"]), default: "top", doc: "where the panel sits in the view" },
    KeySpec { key: "overlay.distance", kind: Kind::Float { min: 0.25, max: 10.0 }, default: "1", doc: "distance of the panel from the eyes, metres (its angular size does not change with it)" },
    KeySpec { key: "overlay.scale", kind: Kind::Float { min: 0.25, max: 4.0 }, default: "1", doc: "size of the panel (1: about 26 degrees wide)" },
];

/// The overlay's typed settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OverlaySettings {
    pub enabled: bool,
    pub position: rules::Position,
    pub distance_m: f32,
    pub scale: f32,
}

impl OverlaySettings {
    pub fn from_config(c: &Config) -> OverlaySettings {
        OverlaySettings {
            enabled: c.bool("overlay.enabled"),
            position: match c.choice("overlay.position") {
                "bottom" => rules::Position::Bottom,
                "center" => rules::Position::Center,
                _ => rules::Position::Top,
            },
            distance_m: c.float("overlay.distance") as f32,
            scale: c.float("overlay.scale") as f32,
        }
    }
}
