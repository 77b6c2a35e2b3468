//! Foveated shading: a lower shading rate away from the fovea, by variable-rate shading (`vrs`,
//! where the GPU has attachment rates) or radial density masking with reconstruction (`rdm`,
//! everywhere else). `rules` holds what both share: ring sizes and the gaze policy.

pub mod rdm;
pub mod rules;
pub mod vrs;
pub(crate) mod xr;

use crate::core::config::{Config, Kind, KeySpec};
pub use rules::Rings;

/// Foveation's config keys (shared by both methods).
pub const KEYS: &[KeySpec] = &[
    KeySpec {
        key: "foveation.enabled",
        kind: Kind::Bool,
        default: "false",
        doc: "foveated shading: lower shading rate in the periphery of every eye pass",
    },
    KeySpec {
        key: "foveation.method",
        kind: Kind::Choice(&["auto", "vrs", "rdm"]),
        default: "auto",
        doc: "vrs: VK_KHR_fragment_shading_rate attachment; rdm: radial density masking with reconstruction; auto: vrs where the GPU has it, else rdm on a GPU, none on a CPU implementation (lavapipe: RDM is slower there for most apps)",
    },
    KeySpec {
        key: "foveation.preset",
        kind: Kind::Choice(&["subtle", "balanced", "aggressive"]),
        default: "balanced",
        doc: "ring sizes: subtle (full rate within 30°, half to 45°), balanced (20°, 35°), aggressive (12°, 25°)",
    },
    KeySpec {
        key: "foveation.inner_deg",
        kind: Kind::Float { min: 0.0, max: 90.0 },
        default: "0",
        doc: "full-rate radius around the centre, degrees (0: from the preset)",
    },
    KeySpec {
        key: "foveation.middle_deg",
        kind: Kind::Float { min: 0.0, max: 90.0 },
        default: "0",
        doc: "half-rate ring's outer radius, degrees; quarter rate beyond (0: from the preset)",
    },
    KeySpec {
        key: "foveation.rdm_reconstruction",
        kind: Kind::Choice(&["auto", "fill", "off"]),
        default: "auto",
        doc: "how RDM fills its skipped quads: auto = a compute pass over the periphery tiles where the swapchain image allows it, else the full-screen fill; fill = always the full-screen fill; off = not at all (leaves holes: only for measuring the masking alone)",
    },
    KeySpec {
        key: "foveation.eye_tracking",
        kind: Kind::Choice(&["auto", "off"]),
        default: "auto",
        doc: "auto: follow the gaze when the runtime has XR_EXT_eye_gaze_interaction and a valid gaze, else the optical axis; off: always the optical axis",
    },
];

/// `foveation.method`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Method {
    Auto,
    Vrs,
    Rdm,
}

impl Method {
    /// The method in effect on a device with (`fsr_attachment`) or without attachment rates, a
    /// CPU implementation (`software`) or a GPU; None: no foveation.
    ///
    /// `auto` never picks a method that is known to make frames slower: VRS where the device has
    /// attachment rates (it costs almost nothing); RDM on a GPU without them (its depth draw and
    /// reconstruction are a few full-rate passes, small against fragment-bound shading); nothing
    /// on a CPU implementation, where RDM's own passes cost as much per pixel as a cheap app's
    /// shading (lavapipe, docs/benchmarks.md "RDM reconstruction as compute": hello_xr is 1.5–2.4×
    /// slower with it; only shading-heavy frames gain). `rdm` forces it there.
    pub fn resolve(self, fsr_attachment: bool, software: bool) -> Option<Method> {
        match self {
            Method::Auto if fsr_attachment => Some(Method::Vrs),
            Method::Auto if software => None,
            Method::Auto => Some(Method::Rdm),
            m => Some(m),
        }
    }
}

/// Foveation's typed settings.
#[derive(Clone, Debug, PartialEq)]
pub struct FoveationSettings {
    pub enabled: bool,
    pub method: Method,
    /// The rings, presets and explicit angles resolved.
    pub rings: Rings,
    /// `foveation.eye_tracking = auto`.
    pub eye_tracking: bool,
    /// `foveation.rdm_reconstruction`.
    pub rdm_reconstruction: Reconstruction,
}

/// `foveation.rdm_reconstruction`: how radial density masking fills its skipped quads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Reconstruction {
    /// The compute pass over periphery tiles where possible, else the full-screen fill.
    Auto,
    /// Always the full-screen fragment fill (the pre-compute behaviour, for comparison).
    Fill,
    /// None: skipped quads stay as the app left them (benchmarks of the masking alone).
    Off,
}

impl FoveationSettings {
    pub fn from_config(c: &Config) -> FoveationSettings {
        FoveationSettings {
            enabled: c.bool("foveation.enabled"),
            method: match c.choice("foveation.method") {
                "vrs" => Method::Vrs,
                "rdm" => Method::Rdm,
                _ => Method::Auto,
            },
            rings: Rings::from_config(c),
            eye_tracking: c.choice("foveation.eye_tracking") == "auto",
            rdm_reconstruction: match c.choice("foveation.rdm_reconstruction") {
                "fill" => Reconstruction::Fill,
                "off" => Reconstruction::Off,
                _ => Reconstruction::Auto,
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn auto_resolves_by_device() {
        assert_eq!(Method::Auto.resolve(true, false), Some(Method::Vrs));
        assert_eq!(Method::Auto.resolve(false, false), Some(Method::Rdm));
        // A CPU implementation: never RDM by itself (measured slower), VRS if it had rates.
        assert_eq!(Method::Auto.resolve(false, true), None);
        assert_eq!(Method::Auto.resolve(true, true), Some(Method::Vrs));
        assert_eq!(Method::Rdm.resolve(true, true), Some(Method::Rdm));
        assert_eq!(Method::Vrs.resolve(false, false), Some(Method::Vrs));
    }
}
