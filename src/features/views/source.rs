//! Where a headset's views and lens come from, for the view tricks' decisions at the first
//! `xrEnumerateViewConfigurationViews` (before any view is located): the runtime's own meshes when
//! a session already exists (their union spans the view's FOV), else the HMD profile the runtime's
//! system name names (the mock's exactly, real headsets by product).

use super::rules::Fov;
use crate::core::lens::hidden_pixels;
use crate::core::views::ViewFov;
use crate::plugin::xr::{Instance, Session};
use openxr_sys as xr;

/// One view's lens on a pixel grid: its FOV, the grid's size, and which of the grid's pixels the
/// lens hides (row-major).
pub(crate) type Lens = (Fov, (u32, u32), Vec<bool>);

pub(crate) fn tangents(fov: &Fov) -> ViewFov {
    ViewFov { tan_left: fov.left as f32, tan_right: fov.right as f32, tan_up: fov.up as f32, tan_down: fov.down as f32 }
}

/// The runtime's system name.
pub(crate) fn system_name(inst: &Instance, system: xr::SystemId) -> Option<String> {
    inst.system_name(system)
}

/// The HMD profile a runtime's system name names (the mock's exactly, real headsets by product).
pub(crate) fn profile_for(name: &str) -> Option<&'static hmd_profiles::profile::HmdProfile> {
    crate::core::hmd::profile_for(name)
}

/// A live session of `inst`, whose runtime meshes can be asked for.
pub(crate) fn session_of(inst: &Instance) -> Option<std::sync::Arc<Session>> {
    inst.sessions().into_iter().next()
}

/// One view's FOV and hidden pixels on a `size` grid from the runtime's meshes (a session
/// exists): the FOV is the box of the hidden and visible meshes together (they tile it).
pub(crate) fn lens_from_runtime(s: &Session, view: u32, size: (u32, u32)) -> Option<Lens> {
    let hidden = s.runtime_mask(view)?;
    let visible = s.runtime_mesh(view, xr::VisibilityMaskTypeKHR::VISIBLE_TRIANGLE_MESH)?;
    let fov = hidden.iter().chain(&visible).fold(None, |acc: Option<Fov>, p| {
        let q = Fov { left: p[0] as f64, right: p[0] as f64, up: p[1] as f64, down: p[1] as f64 };
        Some(acc.map_or(q, |a| a.union(&q)))
    })?;
    Some((fov, size, hidden_pixels(&hidden, &tangents(&fov), size)?))
}

/// One view's FOV and hidden pixels on a `size` grid from an HMD profile.
pub(crate) fn lens_from_profile(p: &hmd_profiles::profile::HmdProfile, view: usize, size: (u32, u32)) -> Option<Lens> {
    let fov = Fov::from_angles(p.fov_rad(view));
    let hidden: Vec<[f32; 2]> = hmd_profiles::mask::hidden_triangle_points(p, view, 1.0).iter().map(|v| [v[0], v[1]]).collect();
    Some((fov, size, hidden_pixels(&hidden, &tangents(&fov), size)?))
}


/// Each view's orientation in the head's frame from an HMD profile (its displays' cant).
pub(crate) fn turns_from_profile(p: &hmd_profiles::profile::HmdProfile) -> [glam::DQuat; 2] {
    [0, 1].map(|v| {
        let r = p.eye_in_head(v).1;
        glam::DQuat::from_xyzw(r.x as f64, r.y as f64, r.z as f64, r.w as f64)
    })
}
