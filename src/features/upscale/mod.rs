//! Upscaling (`upscale.*`): the app is told a smaller recommended size, renders into images the
//! layer owns at that size, and the layer upscales them into the runtime's display-size swapchain
//! at `xrEndFrame` (EASU + RCAS as compute, or a bilinear blit), rewriting the submitted
//! `imageRect`s. Not a registry plug-in: it changes no app pass. Its parts: the filters on the CPU
//! (`filter`: the reference and the quality measures), the GPU passes (`gpu`: SPIR-V and push
//! constants), the geometry and the interposition decisions (`rules`, pure), the Vulkan work
//! (`vk`: pipelines, per-swapchain images and descriptors, the recorded upscale) and its OpenXR
//! half (`xr`: the swapchain calls and the frame's upscale, which the shell calls at its places;
//! `xr_layers`: a frame's composition layers; `xr_lens`: the runtime's lens for skipped tiles).

pub mod filter;
pub mod gpu;
pub mod lens;
pub(crate) mod record;
pub mod rules;
pub(crate) mod slots;
pub(crate) mod vk;
pub(crate) mod xr;
mod xr_layers;
mod xr_lens;

use crate::core::config::{Config, KeySpec, Kind};

/// The upscale's config keys.
pub const KEYS: &[KeySpec] = &[
    KeySpec {
        key: "upscale.enabled",
        kind: Kind::Bool,
        default: "false",
        doc: "tell the app a smaller recommended size and upscale its eye images into the runtime's display-size swapchain (latched when a session starts)",
    },
    KeySpec {
        key: "upscale.scale",
        kind: Kind::Float { min: 0.5, max: 1.0 },
        default: "0.77",
        doc: "rendered size per axis as a fraction of the runtime's recommended size (0.77: 59 % of the pixels)",
    },
    KeySpec {
        key: "upscale.method",
        kind: Kind::Choice(&["easu_rcas", "cas", "bilinear"]),
        default: "easu_rcas",
        doc: "easu_rcas: edge-adaptive upsampling then robust contrast-adaptive sharpening (FSR 1's two passes) as compute; cas: contrast-adaptive sharpening with scaling (one pass, milder); bilinear: bilinear filtering",
    },
    KeySpec {
        key: "upscale.sharpness",
        kind: Kind::Float { min: 0.0, max: 1.0 },
        default: "0.4",
        doc: "RCAS sharpening strength, 0 (none) .. 1 (full); 0.4 keeps PSNR at bilinear's while edges keep about twice its energy (docs/upscaling.md)",
    },
    KeySpec {
        key: "upscale.mip_bias",
        kind: Kind::Text,
        default: "auto",
        doc: "texture LOD bias added to the app's samplers (vkCreateSampler): auto (log2 of the scale, so textures keep the detail of the display size), off, or a number of levels (-4 .. 4)",
    },
    KeySpec {
        key: "upscale.fovea_only",
        kind: Kind::Bool,
        default: "false",
        doc: "the costly filter only inside the foveation's inner region, bilinear outside (cheaper, softer periphery)",
    },
    KeySpec {
        key: "upscale.skip_hidden",
        kind: Kind::Bool,
        default: "true",
        doc: "skip the upscale where the runtime's hidden-area mesh says the lens never shows (written black); every pixel within 2 of a visible one is upscaled as without it",
    },
];

/// How the app's pixels become the display's.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Method {
    EasuRcas,
    /// Contrast-adaptive sharpening with scaling (`filter::cas`).
    Cas,
    Bilinear,
}

/// `upscale.mip_bias`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum MipBias {
    Auto,
    Off,
    Levels(f32),
}

impl MipBias {
    /// Parses `auto`, `off` or a number in [-4, 4]; None for anything else.
    pub fn parse(text: &str) -> Option<MipBias> {
        match text.trim() {
            "auto" | "" => Some(MipBias::Auto),
            "off" => Some(MipBias::Off),
            t => t.parse::<f32>().ok().filter(|v| v.is_finite() && (-4.0..=4.0).contains(v)).map(MipBias::Levels),
        }
    }
}

/// The upscale's typed settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UpscaleSettings {
    pub enabled: bool,
    pub scale: f32,
    pub method: Method,
    pub sharpness: f32,
    /// `upscale.mip_bias` as parsed; `mip_bias_valid` false when the text was not understood
    /// (then `Auto`, and the shell logs it).
    pub mip_bias: MipBias,
    pub mip_bias_valid: bool,
    pub fovea_only: bool,
    pub skip_hidden: bool,
    /// The foveation's inner ring (degrees), where `fovea_only` runs EASU around the fixed centre
    /// when foveation publishes no fovea. The foveation's setting, given by the registry
    /// (`Settings::from_config`): a feature reads no other feature's settings.
    pub fovea_inner_deg: f32,
}

impl UpscaleSettings {
    pub fn from_config(c: &Config) -> UpscaleSettings {
        let parsed = MipBias::parse(c.text("upscale.mip_bias"));
        UpscaleSettings {
            enabled: c.bool("upscale.enabled"),
            scale: rules::clamp_scale(c.float("upscale.scale") as f32),
            method: match c.choice("upscale.method") {
                "bilinear" => Method::Bilinear,
                "cas" => Method::Cas,
                _ => Method::EasuRcas,
            },
            sharpness: c.float("upscale.sharpness").clamp(0.0, 1.0) as f32,
            mip_bias: parsed.unwrap_or(MipBias::Auto),
            mip_bias_valid: parsed.is_some(),
            fovea_only: c.bool("upscale.fovea_only"),
            skip_hidden: c.bool("upscale.skip_hidden"),
            // The registry puts the foveation's ring here; 0 only where no registry built these.
            fovea_inner_deg: 0.0,
        }
    }

    /// Whether `self` differs from `latched` in what the upscale latches for an instance (the
    /// foveation's ring is read live, every frame).
    pub fn changed_from(&self, latched: &UpscaleSettings) -> bool {
        UpscaleSettings { fovea_inner_deg: latched.fovea_inner_deg, ..*self } != *latched
    }

    /// The LOD bias the app's samplers get: none when the upscale is off.
    pub fn sampler_bias(&self) -> Option<f32> {
        if !self.enabled || self.scale >= 1.0 {
            return None;
        }
        match self.mip_bias {
            MipBias::Off => None,
            MipBias::Levels(v) => Some(v),
            MipBias::Auto => Some(self.scale.log2()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mip_bias_parses() {
        assert_eq!(MipBias::parse("auto"), Some(MipBias::Auto));
        assert_eq!(MipBias::parse(" off "), Some(MipBias::Off));
        assert_eq!(MipBias::parse("-0.5"), Some(MipBias::Levels(-0.5)));
        assert_eq!(MipBias::parse("9"), None);
        assert_eq!(MipBias::parse("NaN"), None);
        assert_eq!(MipBias::parse("sharp"), None);
    }
}
