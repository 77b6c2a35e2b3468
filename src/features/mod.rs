//! The feature registry: the one list of what the layer can do to an app's frames, in the order
//! the chassis calls them (the mask's depth goes down before radial density masking's
//! checkerboard over the same cleared depth; variable-rate shading amends passes the others leave
//! untouched). Hooks learn about features only through this list: each entry is a folder with a
//! pure rule module and its Vulkan part, declaring its config keys, its statistics and the events
//! it handles (`crate::vk::feature::VkFeature`).
//!
//! Adding a feature: a folder here, and one line in `registry!` below.

pub mod far_field;
pub mod foveation;
pub mod mask;
/// Not a registry plug-in: the overlay draws nothing into the app's passes (its shell is
/// `crate::xr::overlay`).
pub mod overlay;
pub mod screenshot;
/// Not a registry plug-in: the upscale changes no app pass (its shell is `crate::xr::upscale`).
pub mod upscale;
pub mod views;

use crate::config::KeySpec;
use crate::core::stats::FrameStats;

/// Declares the registered features: `field: Type` per feature, where `Type` implements
/// `VkFeature` and `Plugin`. Generates the per-device feature set, the config keys and the empty
/// statistics of a frame.
macro_rules! registry {
    (vulkan { $($field:ident: $ty:ty,)* } openxr { $($xfield:ident: $xty:path => $xsession:ty, $xinstance:ty,)* }) => {
        /// Every OpenXR feature object, in registry order.
        pub(crate) static XR_FEATURES: &[&dyn crate::xr::feature::XrFeature] = &[$(&$xty,)*];

        /// One session's per-feature state (OpenXR side).
        #[derive(Debug, Default)]
        pub(crate) struct XrSessionFeatures {
            $(pub(crate) $xfield: $xsession,)*
        }

        /// One XR instance's per-feature state (what is decided before any session exists); `()`
        /// for a feature without any.
        #[derive(Debug, Default)]
        #[allow(dead_code)]
        pub(crate) struct XrInstanceFeatures {
            $(pub(crate) $xfield: $xinstance,)*
        }

        /// One device's feature objects, in registry order.
        pub(crate) struct DeviceFeatures {
            $(pub(crate) $field: $ty,)*
        }

        impl DeviceFeatures {
            pub(crate) fn new(init: &crate::vk::feature::DeviceInit<'_>) -> DeviceFeatures {
                DeviceFeatures { $($field: <$ty as crate::vk::feature::Plugin>::new(init),)* }
            }
            /// Every feature, in registry order (the chassis dispatches events over this).
            pub(crate) fn all(&self) -> [&dyn crate::vk::feature::VkFeature; registry!(@count $($field)*)] {
                [$(&self.$field,)*]
            }
        }

        /// Every feature's config keys, in registry order.
        pub const KEYS: &[&[KeySpec]] = &[$(<$ty as crate::vk::feature::Plugin>::KEYS,)*];

        /// A frame's statistics with every feature present (and empty).
        pub fn empty_stats() -> FrameStats {
            FrameStats::new(vec![$(<$ty as crate::vk::feature::Plugin>::empty_stats(),)*])
        }

        /// (feature id, whether the user has it on) for a frame recorded under `s`.
        pub fn enabled(s: &crate::settings::Settings, frame: &FrameStats) -> Vec<(&'static str, bool)> {
            let ids = empty_stats();
            let on = [$(<$ty as crate::vk::feature::Plugin>::enabled(s, frame),)*];
            ids.iter().map(|f| f.id()).zip(on).collect()
        }
    };
    (@count) => { 0 };
    (@count $head:ident $($tail:ident)*) => { 1 + registry!(@count $($tail)*) };
}

registry! {
    vulkan {
        mask: mask::vk::MaskDevice,
        rdm: foveation::rdm::vk::RdmDevice,
        vrs: foveation::vrs::vk::VrsDevice,
        far_field: far_field::vk::FarFieldDevice,
        // Last: it copies the images as the runtime gets them, after RDM's reconstruction.
        screenshot: screenshot::vk::ScreenshotDevice,
    }
    // OpenXR features: `field: object => per-session state, per-instance state,`. First the view
    // tricks: they check each frame's angles at `amend_frame_end`, which stops at the first
    // feature that amends.
    openxr {
        views: views::xr::ViewsXr => views::xr::ViewsSession, views::xr::ViewsInstance,
        mask: mask::xr::MaskXr => mask::xr::MaskSession, (),
        foveation: foveation::xr::FoveationXr => foveation::xr::FoveationSession, (),
        far_field: far_field::xr::FarFieldXr => far_field::xr::FarFieldSession, (),
        screenshot: screenshot::xr::ScreenshotXr => screenshot::xr::ScreenshotSession, (),
    }
}
