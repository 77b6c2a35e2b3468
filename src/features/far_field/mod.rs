//! Monoscopic far field: beyond the distance where the two eyes' views differ by less than a pixel
//! budget, one eye's pixels are the other's up to a rotation, so the layer copies the source eye's
//! far pixels into the destination eye's pass (with the split plane's depth, so the app's own far
//! fragments there fail early-Z) instead of letting the app shade them twice. `rules` holds the
//! geometry and the schedule (which eye is the source, which frame it comes from); `vk` records the
//! copies and the reuse draw; `xr` gathers the view poses and the app's depth range.

pub mod rules;
mod compute;
mod copy;
mod count;
pub mod stats;
pub(crate) mod vk;
pub(crate) mod xr;

use crate::core::config::{Config, Kind, KeySpec};

/// Far field's config keys.
pub const KEYS: &[KeySpec] = &[
    KeySpec { key: "far_field.enabled", kind: Kind::Bool, default: "false", doc: "monoscopic far field: reuse the source eye's far pixels in the destination eye's pass" },
    KeySpec {
        key: "far_field.split_px",
        kind: Kind::Float { min: 0.0, max: 64.0 },
        default: "1",
        doc: "largest disparity error allowed, pixels: the split distance is where the eyes' disparity drops to this",
    },
    KeySpec { key: "far_field.split_m", kind: Kind::Float { min: 0.0, max: 1.0e6 }, default: "0", doc: "split distance in metres (0: from split_px)" },
    KeySpec {
        key: "far_field.shift",
        kind: Kind::Choice(&["infinity", "depth"]),
        default: "infinity",
        doc: "infinity: map directions only (rotation between the views); depth: also shift each sample by the disparity of the source's own depth",
    },
    KeySpec { key: "far_field.alternate", kind: Kind::Bool, default: "false", doc: "swap source and destination eye every frame" },
    KeySpec {
        key: "far_field.source",
        kind: Kind::Choice(&["auto", "same_frame", "previous_frame"]),
        default: "auto",
        doc: "which source image: auto (this frame's where its pass precedes the destination's, else the previous frame's), same_frame, previous_frame",
    },
    KeySpec { key: "far_field.source_view", kind: Kind::Choice(&["0", "1"]), default: "0", doc: "the source eye (view index) when not alternating" },
    KeySpec {
        key: "far_field.near_z",
        kind: Kind::Float { min: 0.0, max: 1.0e9 },
        default: "0",
        doc: "the app's projection: distance of min depth, metres (0: from XrCompositionLayerDepthInfoKHR)",
    },
    KeySpec {
        key: "far_field.far_z",
        kind: Kind::Float { min: 0.0, max: 1.0e30 },
        default: "0",
        doc: "the app's projection: distance of max depth, metres (0: from the depth info; 1e30: infinite)",
    },
    KeySpec { key: "far_field.debug", kind: Kind::Bool, default: "false", doc: "tint reused pixels" },
];

/// `far_field.shift`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Shift {
    Infinity,
    Depth,
}

/// `far_field.source`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SourceTiming {
    Auto,
    SameFrame,
    PreviousFrame,
}

/// Far field's typed settings.
#[derive(Clone, Debug, PartialEq)]
pub struct FarFieldSettings {
    pub enabled: bool,
    pub split_px: f64,
    pub split_m: Option<f64>,
    pub shift: Shift,
    pub alternate: bool,
    pub source: SourceTiming,
    pub source_view: u32,
    /// `far_field.near_z` / `far_z` when both are set: the projection range, used when the app
    /// submits no depth info.
    pub configured_range: Option<(f64, f64)>,
    pub debug: bool,
}

impl FarFieldSettings {
    pub fn from_config(c: &Config) -> FarFieldSettings {
        let positive = |k: &str| Some(c.float(k)).filter(|v| *v > 0.0);
        let far = positive("far_field.far_z").map(|f| if f >= 1.0e30 { f64::INFINITY } else { f });
        FarFieldSettings {
            enabled: c.bool("far_field.enabled"),
            split_px: c.float("far_field.split_px"),
            split_m: positive("far_field.split_m"),
            shift: if c.choice("far_field.shift") == "depth" { Shift::Depth } else { Shift::Infinity },
            alternate: c.bool("far_field.alternate"),
            source: match c.choice("far_field.source") {
                "same_frame" => SourceTiming::SameFrame,
                "previous_frame" => SourceTiming::PreviousFrame,
                _ => SourceTiming::Auto,
            },
            source_view: u32::from(c.choice("far_field.source_view") == "1"),
            configured_range: positive("far_field.near_z").zip(far),
            debug: c.bool("far_field.debug"),
        }
    }
}
