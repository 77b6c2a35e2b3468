//! The live channel to `stereoshim top`: the layer's side. While a session runs the app announces
//! itself in the private runtime folder (`core::live`); while `top`'s heartbeat is fresh every
//! frame's stats line also goes to the app's stream file (the config watch applies `top`'s live
//! settings: `core::config::Watch::with_live`). Costs the app one `stat` every 100 ms at
//! `xrBeginFrame` and, while watched, one line written per frame.

pub(crate) mod xr;

use crate::core::config::{Config, KeySpec, Kind};

/// The live channel's keys.
pub const KEYS: &[KeySpec] = &[KeySpec {
    key: "live.enabled",
    kind: Kind::Bool,
    default: "true",
    doc: "let `stereoshim top` find this app, stream its frames' stats and apply live settings while it watches (false: no announcement, nothing streamed)",
}];

/// The live channel's settings.
#[derive(Clone, Debug, PartialEq)]
pub struct LiveSettings {
    pub enabled: bool,
}

impl LiveSettings {
    pub fn from_config(c: &Config) -> LiveSettings {
        LiveSettings { enabled: c.bool("live.enabled") }
    }
}
