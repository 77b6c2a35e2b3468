//! View tricks (docs/views.md): the field of view cut to the lens (`view.fov_cut`), so the app
//! renders only the pixels the lens can show; symmetric views (`view.symmetric`) and parallel
//! views (`view.parallel`) for apps that assume them. `rules` holds the geometry (pure),
//! `source` where a headset's views and lens come from, `xr` the OpenXR half (the recommended
//! size, the located views' angles and orientations, the check of the submitted ones).

pub mod rules;
pub(crate) mod source;
pub(crate) mod xr;

use crate::core::config::{Config, KeySpec, Kind};

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
    KeySpec {
        key: "view.symmetric",
        kind: Kind::Choice(&["off", "horizontal", "full"]),
        default: "off",
        doc: "horizontal: both eyes get the same vertical angles (their union) and mirrored horizontal ones, for apps that draw one eye with the other's projection shifted; full: each eye symmetric about its axis. The padding the runtime does not show is masked (the hidden-area mask is switched on with it); sizes latched per XR instance",
    },
    KeySpec {
        key: "view.parallel",
        kind: Kind::Choice(&["off", "on"]),
        default: "off",
        doc: "on: canted views (Pimax) are reported parallel, turned to their mean, each widened to contain the canted one (the runtime reprojects); the hidden-area mask is switched on with it",
    },
];

/// The view tricks' typed settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ViewSettings {
    pub fov_cut: bool,
    pub fov_cut_margin_deg: f64,
    pub symmetric: rules::Symmetric,
    pub parallel: bool,
}

impl ViewSettings {
    pub fn from_config(c: &Config) -> ViewSettings {
        let symmetric = match c.choice("view.symmetric") {
            "horizontal" => rules::Symmetric::Horizontal,
            "full" => rules::Symmetric::Full,
            _ => rules::Symmetric::Off,
        };
        ViewSettings {
            fov_cut: c.choice("view.fov_cut") == "lens",
            fov_cut_margin_deg: c.float("view.fov_cut_margin_deg").clamp(0.0, 10.0),
            symmetric,
            parallel: c.choice("view.parallel") == "on",
        }
    }

    /// Symmetric or parallel views: the app's views reach outside the runtime's, whose padding the
    /// hidden-area mask hides.
    pub fn widens(&self) -> bool {
        self.symmetric != rules::Symmetric::Off || self.parallel
    }
}
