//! The far field on the OpenXR side: the views the app located, numbered by frame (a new
//! predicted display time is a new frame, whichever call the app makes first), so the Vulkan side
//! can map between the eyes of one frame and between frames; and SAMPLED + TRANSFER_SRC on eye swapchains,
//! so the source eye can be copied.

use crate::plugin::settings::Settings;
use crate::bridge::shared;
use crate::core::views::ViewPose;
use crate::plugin::xr::{Session, XrFeature};
use openxr_sys as xr;

/// The far field's OpenXR feature object.
pub(crate) struct FarFieldXr;

/// Per-session state: the display time of the frame whose views were located last.
#[derive(Debug, Default)]
pub(crate) struct FarFieldSession {
    last_display_time: std::sync::atomic::AtomicI64,
}

impl XrFeature for FarFieldXr {
    fn id(&self) -> &'static str {
        "far_field"
    }
    /// Colour and depth swapchains get SAMPLED and TRANSFER_SRC whenever the layer is on (the far
    /// field can be switched on while the app runs; an extra usage bit changes nothing the app
    /// sees).
    fn swapchain_usage(&self, s: &Settings, usage: xr::SwapchainUsageFlags) -> xr::SwapchainUsageFlags {
        let attachment = usage.intersects(xr::SwapchainUsageFlags::COLOR_ATTACHMENT | xr::SwapchainUsageFlags::DEPTH_STENCIL_ATTACHMENT);
        if s.enabled && attachment {
            xr::SwapchainUsageFlags::TRANSFER_SRC | xr::SwapchainUsageFlags::SAMPLED
        } else {
            xr::SwapchainUsageFlags::EMPTY
        }
    }
    fn views_located(&self, s: &Session, info: &xr::ViewLocateInfo, views: &[xr::View]) {
        let poses: Vec<ViewPose> = views
            .iter()
            .map(|v| {
                let (o, p) = (v.pose.orientation, v.pose.position);
                ViewPose { orientation: [o.x, o.y, o.z, o.w], position: [p.x, p.y, p.z], fov: crate::plugin::xr::fov_tangents(&v.fov) }
            })
            .collect();
        let time = info.display_time.as_nanos();
        let new_frame = s.feature::<FarFieldSession>().last_display_time.swap(time, std::sync::atomic::Ordering::AcqRel) != time;
        shared().update_far_field(|f| {
            // The first located frame is frame 0.
            if new_frame && f.current.is_some() {
                f.frame += 1;
                f.previous = f.current.take();
            }
            f.current = Some((f.frame, poses));
        });
    }
}
