//! `stereoshim preview --runtime`: the layer's OpenXR *client* side, asking the active runtime
//! (through the Khronos loader) for its real view configuration, the views' FOVs and poses
//! (`xrLocateViews` in VIEW space) and the visibility masks (`XR_KHR_visibility_mask`). Both need a
//! session; without rendering anything that is an `XR_MND_headless` session (no graphics
//! binding). A runtime without that extension is reported, not worked around: a Vulkan session
//! would need a device only to ask for numbers. The two unsafe calls are the loader's load and
//! the session's creation; the `openxr` crate does the rest.

use crate::preview::{Headset, View};
use crate::core::views::ViewFov;
use openxr as oxr;
use std::time::{Duration, Instant};

/// Why the runtime could not be asked.
#[derive(Debug, PartialEq)]
pub enum ProbeError {
    /// No loader, no runtime, or a call failed: the words say which.
    Failed(String),
    /// The runtime offers no `XR_MND_headless`.
    NeedsGraphics,
}

impl std::fmt::Display for ProbeError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ProbeError::Failed(s) => write!(f, "{s}"),
            ProbeError::NeedsGraphics => {
                write!(f, "this runtime needs a graphics session; use --hmd (it offers no XR_MND_headless, the session without graphics the preview asks for)")
            }
        }
    }
}

fn failed(what: &str) -> impl Fn(oxr::sys::Result) -> ProbeError + '_ {
    move |r| ProbeError::Failed(format!("{what}: {r}"))
}

/// The active runtime's stereo views, recommended size and hidden-area meshes.
pub fn runtime_headset() -> Result<Headset, ProbeError> {
    // SAFETY: the library loaded is the Khronos OpenXR loader (libopenxr_loader.so.1), which
    // implements the OpenXR API it is loaded for; the entry points are resolved by name from it.
    let entry = unsafe { oxr::Entry::load(&()) }.map_err(|e| ProbeError::Failed(format!("no OpenXR loader (libopenxr_loader.so.1): {e}")))?;
    let available = entry.enumerate_extensions().map_err(failed("no OpenXR runtime (xrEnumerateInstanceExtensionProperties)"))?;
    if !available.mnd_headless {
        return Err(ProbeError::NeedsGraphics);
    }
    let mut exts = oxr::ExtensionSet::default();
    exts.mnd_headless = true;
    exts.khr_visibility_mask = available.khr_visibility_mask;
    exts.khr_convert_timespec_time = available.khr_convert_timespec_time;
    let app = oxr::ApplicationInfo {
        application_name: "stereoshim preview",
        application_version: 1,
        engine_name: "stereoshim",
        engine_version: 1,
        api_version: oxr::Version::new(1, 0, 0),
    };
    let instance = entry.create_instance(&app, &exts, &[], &()).map_err(failed("xrCreateInstance"))?;
    let system = instance.system(oxr::FormFactor::HEAD_MOUNTED_DISPLAY).map_err(failed("xrGetSystem"))?;
    let name = instance.system_properties(system).map(|p| p.system_name).unwrap_or_default();
    let stereo = oxr::ViewConfigurationType::PRIMARY_STEREO;
    let config_views = instance.enumerate_view_configuration_views(system, stereo).map_err(failed("xrEnumerateViewConfigurationViews"))?;
    let first = config_views.first().ok_or_else(|| ProbeError::Failed("the runtime reports no stereo views".into()))?;
    let (width, height) = (first.recommended_image_rect_width, first.recommended_image_rect_height);
    // SAFETY: a headless session takes no graphics objects; the instance enabled XR_MND_headless,
    // which allows xrCreateSession without a graphics binding.
    let (session, mut waiter, _stream) = unsafe { instance.create_session::<oxr::Headless>(system, &oxr::headless::SessionCreateInfo {}) }
        .map_err(failed("xrCreateSession (headless)"))?;
    // A time to locate the views at: now, where the runtime converts clock times
    // (XR_KHR_convert_timespec_time; Monado's headless xrWaitFrame predicts no usable time), else
    // the first frame's predicted display time, once the session runs.
    let time = if exts.khr_convert_timespec_time {
        instance.now().map_err(failed("xrConvertTimespecTimeToTimeKHR"))?
    } else {
        wait_ready(&instance)?;
        session.begin(stereo).map_err(failed("xrBeginSession"))?;
        waiter.wait().map_err(failed("xrWaitFrame"))?.predicted_display_time
    };
    let space = session.create_reference_space(oxr::ReferenceSpaceType::VIEW, oxr::Posef::IDENTITY).map_err(failed("xrCreateReferenceSpace"))?;
    let (_, located) = session.locate_views(stereo, time, &space).map_err(failed("xrLocateViews"))?;
    let views = located
        .iter()
        .enumerate()
        .map(|(i, v)| {
            let hidden = exts.khr_visibility_mask.then(|| {
                session.get_visibility_mask_khr(stereo, i as u32, oxr::VisibilityMaskTypeKHR::HIDDEN_TRIANGLE_MESH).ok().map(|m| {
                    let vertices: Vec<[f32; 2]> = m.vertices.iter().map(|p| [p.x, p.y]).collect();
                    crate::core::lens::expand(&vertices, &m.indices)
                })
            });
            let f = v.fov;
            View {
                fov: ViewFov { tan_left: f.angle_left.tan(), tan_right: f.angle_right.tan(), tan_up: f.angle_up.tan(), tan_down: f.angle_down.tan() },
                orientation: [v.pose.orientation.x, v.pose.orientation.y, v.pose.orientation.z, v.pose.orientation.w],
                position: [v.pose.position.x, v.pose.position.y, v.pose.position.z],
                hidden: hidden.flatten(),
            }
        })
        .collect();
    Ok(Headset { name, width, height, views })
}

/// Polls events until the session is READY (a headless session gets there from IDLE at once).
fn wait_ready(instance: &oxr::Instance) -> Result<(), ProbeError> {
    let deadline = Instant::now() + Duration::from_secs(5);
    let mut buffer = oxr::EventDataBuffer::new();
    loop {
        while let Some(event) = instance.poll_event(&mut buffer).map_err(failed("xrPollEvent"))? {
            if let oxr::Event::SessionStateChanged(e) = event {
                if e.state() == oxr::SessionState::READY {
                    return Ok(());
                }
            }
        }
        if Instant::now() > deadline {
            return Err(ProbeError::Failed("the headless session did not become READY within 5 s".into()));
        }
        std::thread::sleep(Duration::from_millis(10));
    }
}
