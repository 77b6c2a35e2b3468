//! View tricks (docs/views.md): the field of view cut to the lens (`view.fov_cut`), so the app
//! renders only the pixels the lens can show. `rules` holds the geometry (pure, with symmetric
//! and parallel views' too), `xr` the OpenXR half (the recommended size, the located views' angles,
//! the check of the submitted ones).

pub mod rules;
pub(crate) mod xr;

use crate::config::{Config, KeySpec, Kind};

/// The view tricks' config keys.
pub const KEYS: &[KeySpec] = &[
    KeySpec {
        key: "view.fov_cut",
        kind: Kind::Choice(&["off", "lens"]),
        default: "off",
        doc: "lens: cut each view's field of view to the box around what the lens shows (on whole pixels of the runtime's image, so the app's image is the crop of the uncut one) and the recommended size with it (latched per XR instance)",
    },
    KeySpec {
        key: "view.fov_cut_margin_deg",
        kind: Kind::Float { min: 0.0, max: 10.0 },
        default: "0.5",
        doc: "degrees kept around the lens's visible area on each side when cutting",
    },
];

/// The view tricks' typed settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ViewSettings {
    pub fov_cut: bool,
    pub fov_cut_margin_deg: f64,
}

impl ViewSettings {
    pub fn from_config(c: &Config) -> ViewSettings {
        ViewSettings { fov_cut: c.choice("view.fov_cut") == "lens", fov_cut_margin_deg: c.float("view.fov_cut_margin_deg").clamp(0.0, 10.0) }
    }
}
