//! The feature registry: the one file that names every feature, in the order the chassis calls
//! them (the mask's depth goes down before radial density masking's checkerboard over the same
//! cleared depth; variable-rate shading amends passes the others leave untouched). The shells
//! learn about features only through what this file generates: the per-device and per-session
//! feature sets, the key list the configuration is resolved against, the empty statistics.
//!
//! Adding a feature: a folder under `src/features/` (with its `pub mod` line in
//! `src/features/mod.rs`), and one entry in `registry!` here.

use crate::features::*;
use crate::core::config::{self, Config, KeySpec};
use crate::plugin::settings::Settings;
use crate::plugin::vk::feature::{DeviceFeatures, DeviceInit, Plugin};
use crate::core::stats::FrameStats;

/// Declares the registered features, one entry each, in dispatch order (the same for both halves):
/// its config keys and settings type, and what it has of `vulkan` (its per-device objects, each a
/// `VkFeature` + `Plugin`), `openxr` (its `XrFeature` object with its per-session and
/// per-instance state types) and `states` (the state of an OpenXR half the shell calls directly).
/// Generates every list the shells and the configuration use.
macro_rules! registry {
    ($(
        $name:ident {
            keys: $keys:expr,
            settings: $settings:ty,
            $(vulkan: [$($vk:ty),*],)?
            $(openxr: $xr:path => $xsession:ty, $xinstance:ty,)?
            $(states: $ssession:ty, $sinstance:ty,)?
        }
    )*) => {
        /// Every OpenXR feature object, in registry order.
        pub(crate) static XR_FEATURES: &[&dyn crate::plugin::xr::XrFeature] = &[$($(&$xr,)?)*];

        /// One session's per-feature state (OpenXR side), one value per type. A feature reads its
        /// own with `Session::feature`.
        pub(crate) fn xr_session_states() -> crate::core::parts::States {
            crate::core::parts::States::default()
                $($(.with(<$xsession>::default()))?)*
                $($(.with(<$ssession>::default()))?)*
        }

        /// One XR instance's per-feature state (what is decided before any session exists); `()`
        /// for a feature without any. Read with `Instance::feature`.
        pub(crate) fn xr_instance_states() -> crate::core::parts::States {
            crate::core::parts::States::default()
                $($(.with(<$xinstance>::default()))?)*
                $($(.with(<$sinstance>::default()))?)*
        }

        /// One new device's feature objects, in registry order.
        pub(crate) fn device_features(init: &DeviceInit<'_>) -> DeviceFeatures {
            DeviceFeatures::new(vec![$($($(Box::new(<$vk as Plugin>::new(init)),)*)?)*])
        }

        /// Every feature's config keys, in registry order.
        pub const KEYS: &[&[KeySpec]] = &[$($keys,)*];

        /// A frame's statistics with every feature's Vulkan objects present (and empty).
        pub fn empty_stats() -> FrameStats {
            FrameStats::new(vec![$($($(<$vk as Plugin>::empty_stats(),)*)?)*])
        }

        /// (feature id, whether the user has it on) for a frame recorded under `s`.
        pub fn enabled(s: &crate::plugin::settings::Settings, frame: &FrameStats) -> Vec<(&'static str, bool)> {
            let ids = empty_stats();
            let on = [$($($(<$vk as Plugin>::enabled(s, frame),)*)?)*];
            ids.iter().map(|f| f.id()).zip(on).collect()
        }

        impl Settings {
            /// The typed settings of `c`: the chassis' and every feature's.
            pub fn from_config(c: &Config) -> Settings {
                let mut s = Settings::chassis(c);
                $(s.features = s.features.with(<$settings>::from_config(c));)*
                implied(&mut s);
                s
            }
        }
    };
}

registry! {
    // First the view tricks: they check each frame's angles at `amend_frame_end`, which stops at
    // the first feature that amends.
    views { keys: views::KEYS, settings: views::ViewSettings, openxr: views::xr::ViewsXr => views::xr::ViewsSession, views::xr::ViewsInstance, }
    // The mask's depth goes down before RDM's checkerboard over the same cleared depth.
    mask { keys: mask::KEYS, settings: mask::MaskSettings, vulkan: [mask::vk::MaskDevice], openxr: mask::xr::MaskXr => mask::xr::MaskSession, (), }
    foveation { keys: foveation::KEYS, settings: foveation::FoveationSettings, vulkan: [foveation::rdm::vk::RdmDevice, foveation::vrs::vk::VrsDevice], openxr: foveation::xr::FoveationXr => foveation::xr::FoveationSession, (), }
    far_field { keys: far_field::KEYS, settings: far_field::FarFieldSettings, vulkan: [far_field::vk::FarFieldDevice], openxr: far_field::xr::FarFieldXr => far_field::xr::FarFieldSession, (), }
    // The upscale and the overlay change no app pass: the shell calls their OpenXR halves at their
    // places; here are only their keys, settings and state.
    upscale { keys: upscale::KEYS, settings: upscale::UpscaleSettings, states: upscale::xr::SessionUpscale, upscale::xr::InstanceUpscale, }
    overlay { keys: overlay::KEYS, settings: overlay::OverlaySettings, states: overlay::xr::OverlaySession, (), }
    // Last: it copies the images as the runtime gets them, after RDM's reconstruction.
    screenshot { keys: screenshot::KEYS, settings: screenshot::ScreenshotSettings, vulkan: [screenshot::vk::ScreenshotDevice], openxr: screenshot::xr::ScreenshotXr => screenshot::xr::ScreenshotSession, (), }
    // `stereoshim top`'s channel: changes nothing the app or the runtime sees.
    live { keys: live::KEYS, settings: live::LiveSettings, openxr: live::xr::LiveXr => live::xr::LiveSession, (), }
}

/// What one feature's settings imply for another's: the only place two features' settings meet.
fn implied(s: &mut Settings) {
    // The upscale's `fovea_only` runs EASU in the foveation's inner ring when foveation publishes
    // no fovea.
    let upscale = upscale::UpscaleSettings { fovea_inner_deg: s.of::<foveation::FoveationSettings>().rings.inner_deg, ..*s.of::<upscale::UpscaleSettings>() };
    s.features = std::mem::take(&mut s.features).with(upscale);
    // Symmetric and parallel views pad the app's views beyond what the runtime shows: the mask
    // hides the padding, so it comes on with them (docs/views.md).
    if s.of::<views::ViewSettings>().widens() {
        let mask = mask::MaskSettings { enabled: true, ..s.of::<mask::MaskSettings>().clone() };
        s.features = std::mem::take(&mut s.features).with(mask);
    }
}

/// Every key the layer reads: the chassis' (`config::CORE_KEYS`) and every feature's, each once,
/// in that order.
pub fn keys() -> &'static [KeySpec] {
    static ALL: std::sync::OnceLock<Vec<KeySpec>> = std::sync::OnceLock::new();
    ALL.get_or_init(|| {
        let mut lists: Vec<&[KeySpec]> = vec![config::CORE_KEYS];
        lists.extend(KEYS.iter().copied());
        config::join_keys(&lists)
    })
}

#[cfg(test)]
mod config_tests;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::config::Inputs;
    use crate::plugin::vk::feature::VkFeature;

    /// Each feature finds its own device object by type among the registry's (`RdmDevice::of`):
    /// through the trait object, never the box around it.
    #[test]
    fn every_device_object_is_found_by_type() {
        let (c, _) = Config::resolve(&Inputs { keys: keys(), file: None, app_names: &[], env: &|_| None });
        let s = Settings::from_config(&c);
        let init = DeviceInit { settings: &s, memory: Default::default(), rates: None, set_loader_data: None, software: true };
        let f = device_features(&init);
        let ids: Vec<&str> = f.all().iter().map(|f| f.id()).collect();
        assert_eq!(ids, ["mask", "rdm", "vrs", "far_field", "screenshot"]);
        assert_eq!(f.get::<mask::vk::MaskDevice>().id(), "mask");
        assert_eq!(f.get::<foveation::rdm::vk::RdmDevice>().id(), "rdm");
        assert_eq!(f.get::<foveation::vrs::vk::VrsDevice>().id(), "vrs");
        assert_eq!(f.get::<far_field::vk::FarFieldDevice>().id(), "far_field");
        assert_eq!(f.get::<screenshot::vk::ScreenshotDevice>().id(), "screenshot");
    }

    #[test]
    fn parsed_once_from_the_config() {
        let env = |k: &str| match k {
            "STEREOSHIM_MASK_ENABLED" => Some("true".to_string()),
            "STEREOSHIM_MASK_INTERMEDIATE" => Some("off".to_string()),
            "STEREOSHIM_FOVEATION_METHOD" => Some("rdm".to_string()),
            "STEREOSHIM_DEBUG_FAIL_IN" => Some("vkCmdDraw, xrEndFrame".to_string()),
            _ => None,
        };
        let (c, d) = Config::resolve(&Inputs { keys: crate::registry::keys(), file: None, app_names: &[], env: &env });
        assert!(d.is_empty(), "{d:?}");
        let s = Settings::from_config(&c);
        assert!(s.of::<mask::MaskSettings>().enabled && !s.intermediate && !s.of::<foveation::FoveationSettings>().enabled);
        assert_eq!(s.of::<foveation::FoveationSettings>().method, crate::features::foveation::Method::Rdm);
        assert!(s.fails_in("xrEndFrame") && !s.fails_in("xrBeginFrame"));
        assert_eq!(s.of::<upscale::UpscaleSettings>().fovea_inner_deg, s.of::<foveation::FoveationSettings>().rings.inner_deg);
    }

    /// Here rather than in `plugin::settings`: what is published must be whole (every feature's
    /// settings), since other tests of the process read the live settings meanwhile.
    #[test]
    fn publish_reaches_every_thread() {
        use crate::plugin::settings::{current, publish};
        let (c, _) = Config::resolve(&Inputs { keys: crate::registry::keys(), file: None, app_names: &[], env: &|_| None });
        let mut s = Settings::from_config(&c);
        s.stats_file = "first".into();
        publish(s.clone());
        assert_eq!(current().unwrap().stats_file, "first");
        s.stats_file = "second".into();
        publish(s);
        assert_eq!(std::thread::spawn(|| current().unwrap().stats_file.clone()).join().unwrap(), "second");
        assert_eq!(current().unwrap().stats_file, "second");
    }

    /// Every OpenXR feature's and OpenXR-only feature's state is made with each session and
    /// instance, so `Session::feature` / `Instance::feature` never miss one.
    #[test]
    fn every_xr_state_is_made() {
        let (s, i) = (xr_session_states(), xr_instance_states());
        assert!(s.get::<views::xr::ViewsSession>().is_some() && s.get::<mask::xr::MaskSession>().is_some());
        assert!(s.get::<foveation::xr::FoveationSession>().is_some() && s.get::<far_field::xr::FarFieldSession>().is_some());
        assert!(s.get::<screenshot::xr::ScreenshotSession>().is_some());
        assert!(s.get::<upscale::xr::SessionUpscale>().is_some() && s.get::<overlay::xr::OverlaySession>().is_some());
        assert!(i.get::<views::xr::ViewsInstance>().is_some() && i.get::<upscale::xr::InstanceUpscale>().is_some());
    }

}
