//! The FOV cut's OpenXR half (`view.fov_cut = lens`). At the instance's first
//! `xrEnumerateViewConfigurationViews` each view's cut is decided on whole pixels of the runtime's
//! recommended image and latched for the instance (the app sizes its swapchains from it): from the
//! runtime's own hidden and visible meshes when a session already exists (their union spans the
//! view's FOV), else from the HMD profile the runtime's system name matches; else nothing is cut.
//! `xrLocateViews` then hands the app the angles of exactly the cut pixels of each view's grid.
//! Per session, the first located views are checked against the runtime's hidden-area mesh (the
//! cut must hold every pixel the lens shows), and every frame's submitted angles against the ones
//! given: either failing turns the cut off for the session (logged), and the app then gets the
//! runtime's own angles (its images, already made, show the whole view at a lower density).

use super::rules::{self, Cut, Fov};
use crate::features::mask::rules::hidden_pixels;
use crate::features::mask::xr::runtime_mask;
use crate::settings::Settings;
use crate::shared::ViewFov;
use crate::xr::feature::{AmendedFrameEnd, XrFeature};
use crate::xr::session::Session;
use crate::xr::{Instance, VISIBILITY_MASK_EXT};
use openxr_sys as xr;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Mutex, MutexGuard};

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// Views of `XR_VIEW_CONFIGURATION_TYPE_PRIMARY_STEREO`, the configuration the cut applies to.
const STEREO_VIEWS: usize = 2;

/// How far a submitted angle may be from the one given (radians): the app's own float round trip.
const ANGLE_TOLERANCE: f32 = 1e-5;

/// The view tricks' OpenXR half.
pub(crate) struct ViewsXr;

/// One view's cut on the runtime's recommended grid (`size`).
#[derive(Clone, Copy, Debug, PartialEq)]
struct ViewCut {
    size: (u32, u32),
    cut: Cut,
}

/// What an instance latched at its first `xrEnumerateViewConfigurationViews`.
#[derive(Clone, Debug, Default)]
struct Latched {
    /// Per view (None: not cut).
    views: Vec<Option<ViewCut>>,
}

/// The FOV cut's per-instance state.
#[derive(Debug, Default)]
pub(crate) struct ViewsInstance {
    latch: Mutex<Option<Latched>>,
}

/// The FOV cut's per-session state.
#[derive(Debug, Default)]
pub(crate) struct ViewsSession {
    /// The cut is off for this session (a check failed).
    off: AtomicBool,
    /// The runtime's mesh was checked against the cut.
    checked: AtomicBool,
    /// The angles the app was last given per view (XrFovf order: left, right, up, down).
    given: Mutex<Vec<[f32; 4]>>,
}

fn tangents(fov: &Fov) -> ViewFov {
    ViewFov { tan_left: fov.left as f32, tan_right: fov.right as f32, tan_up: fov.up as f32, tan_down: fov.down as f32 }
}

/// The runtime's system name.
fn system_name(inst: &Instance, system: xr::SystemId) -> Option<String> {
    let f = inst.next.get_system_properties?;
    // SAFETY: a zeroed output struct with its type set (every field is plain data).
    let mut p: xr::SystemProperties = unsafe { std::mem::zeroed() };
    p.ty = xr::SystemProperties::TYPE;
    // SAFETY: the instance's own system, an output struct of the right type.
    if unsafe { f(inst.handle, system, &mut p) } != xr::Result::SUCCESS {
        return None;
    }
    // SAFETY: the runtime wrote a NUL-terminated name into the fixed array.
    let name = unsafe { std::ffi::CStr::from_ptr(p.system_name.as_ptr()) };
    Some(name.to_string_lossy().into_owned())
}

/// The HMD profile a runtime's system name names (the mock's exactly, real headsets by product).
fn profile_for(name: &str) -> Option<&'static hmd_profiles::profile::HmdProfile> {
    use hmd_profiles::profile::{HmdProfile, HMD_NAMES};
    if let Some(p) = HMD_NAMES.iter().filter_map(|n| HmdProfile::by_name(n)).find(|p| p.system_name == name) {
        return Some(p);
    }
    let lower = name.to_lowercase();
    [("index", "index"), ("vive", "vive"), ("quest 3", "quest3"), ("pimax", "pimax")].iter().find(|(k, _)| lower.contains(k)).and_then(|(_, n)| HmdProfile::by_name(n))
}

/// A live session of `inst`, whose runtime meshes can be asked for.
fn session_of(inst: &Instance) -> Option<std::sync::Arc<Session>> {
    crate::xr::state().sessions.values().into_iter().map(|(_, s)| s).find(|s| s.instance.handle == inst.handle)
}

/// One view's FOV and hidden pixels on a `size` grid from the runtime's meshes (a session
/// exists): the FOV is the box of the hidden and visible meshes together (they tile it).
fn lens_from_runtime(s: &Session, view: u32, size: (u32, u32)) -> Option<(Fov, (u32, u32), Vec<bool>)> {
    let hidden = runtime_mask(s, view)?;
    let visible = crate::features::mask::xr::runtime_mesh(s, view, xr::VisibilityMaskTypeKHR::VISIBLE_TRIANGLE_MESH)?;
    let fov = hidden.iter().chain(&visible).fold(None, |acc: Option<Fov>, p| {
        let q = Fov { left: p[0] as f64, right: p[0] as f64, up: p[1] as f64, down: p[1] as f64 };
        Some(acc.map_or(q, |a| a.union(&q)))
    })?;
    Some((fov, size, hidden_pixels(&hidden, &tangents(&fov), size)?))
}

/// One view's FOV and hidden pixels on a `size` grid from an HMD profile.
fn lens_from_profile(p: &hmd_profiles::profile::HmdProfile, view: usize, size: (u32, u32)) -> Option<(Fov, (u32, u32), Vec<bool>)> {
    let fov = Fov::from_angles(p.fov_rad(view));
    let hidden: Vec<[f32; 2]> = hmd_profiles::mask::hidden_triangle_points(p, view, 1.0).iter().map(|v| [v[0], v[1]]).collect();
    Some((fov, size, hidden_pixels(&hidden, &tangents(&fov), size)?))
}

/// Decides the instance's cuts for `views` (the runtime's answer).
fn decide(inst: &Instance, system: xr::SystemId, s: &Settings, views: &[xr::ViewConfigurationView]) -> Latched {
    let margin = s.views.fov_cut_margin_deg;
    let sizes: Vec<(u32, u32)> = views.iter().map(|v| (v.recommended_image_rect_width, v.recommended_image_rect_height)).collect();
    let session = session_of(inst).filter(|_| inst.has_extension(VISIBILITY_MASK_EXT));
    let name = system_name(inst, system).unwrap_or_default();
    let profile = profile_for(&name);
    let (lenses, source): (Option<Vec<_>>, &str) = match (&session, profile) {
        (Some(sess), _) => (sizes.iter().enumerate().map(|(i, &size)| lens_from_runtime(sess, i as u32, size)).collect(), "the runtime's visibility mask"),
        (None, Some(p)) => (sizes.iter().enumerate().map(|(i, &size)| lens_from_profile(p, i, size)).collect(), "the HMD profile's lens"),
        (None, None) => (None, ""),
    };
    // One size for every view (apps render them at one size), or no cut when a view has none.
    let cuts = lenses.and_then(|l| rules::cuts(&l, margin));
    if cuts.is_none() {
        tracing::warn!("view.fov_cut: no lens known for {name:?} (no runtime mesh of a session, no HMD profile matching it); the views are not cut");
    }
    let cuts: Vec<Option<(Cut, &str)>> = match cuts {
        Some(c) => c.into_iter().map(|c| Some((c, source))).collect(),
        None => vec![None; sizes.len()],
    };
    let views = cuts
        .into_iter()
        .zip(&sizes)
        .enumerate()
        .map(|(i, (c, &size))| {
            let (cut, source) = c?;
            tracing::info!(
                "view.fov_cut: view {i}: {}x{} -> {}x{} (pixels {}..{} x {}..{}), {:.1} % fewer pixels; the lens from {source}",
                size.0,
                size.1,
                cut.size().0,
                cut.size().1,
                cut.x0,
                cut.x1,
                cut.y0,
                cut.y1,
                100.0 * cut.saved_share(size)
            );
            Some(ViewCut { size, cut })
        })
        .collect();
    Latched { views }
}

impl ViewsXr {
    fn latched(s: &Session) -> Option<Latched> {
        lock(&s.instance.features.views.latch).clone().filter(|l| l.views.iter().any(Option::is_some))
    }

    /// Turns the cut off for session `s`, saying why (once).
    fn turn_off(s: &Session, why: &str) {
        if !s.features.views.off.swap(true, Ordering::AcqRel) {
            tracing::warn!("view.fov_cut: {why}; the cut is off for this session (the app gets the runtime's angles)");
        }
    }

    /// The session's first located views against the runtime's mesh: every pixel the lens shows
    /// must be inside the cut.
    fn check_runtime_mesh(s: &Session, l: &Latched, views: &[xr::View]) {
        if !s.instance.has_extension(VISIBILITY_MASK_EXT) {
            return;
        }
        for (i, (vc, v)) in l.views.iter().zip(views).enumerate() {
            let Some(vc) = vc else { continue };
            let Some(hidden) = runtime_mask(s, i as u32) else { continue };
            let fov = Fov::from_angles([v.fov.angle_left, v.fov.angle_right, v.fov.angle_up, v.fov.angle_down]);
            let Some(bits) = hidden_pixels(&hidden, &tangents(&fov), vc.size) else { continue };
            let w = vc.size.0 as usize;
            let inside = |k: usize| (vc.cut.x0..vc.cut.x1).contains(&((k % w) as u32)) && (vc.cut.y0..vc.cut.y1).contains(&((k / w) as u32));
            let outside = bits.iter().enumerate().any(|(k, &hidden)| !hidden && !inside(k));
            if outside {
                Self::turn_off(s, &format!("view {i}: the runtime's lens shows pixels outside the cut"));
                return;
            }
        }
    }
}

impl XrFeature for ViewsXr {
    fn id(&self) -> &'static str {
        "views"
    }

    fn views_enumerated(&self, inst: &Instance, system: xr::SystemId, config: xr::ViewConfigurationType, s: &Settings, views: &mut [xr::ViewConfigurationView]) {
        if config != xr::ViewConfigurationType::PRIMARY_STEREO || views.len() != STEREO_VIEWS {
            return;
        }
        // Decided once per instance: the app sizes its swapchains from the first answer. Decided
        // with no lock held (it asks the runtime), kept by the first call to finish.
        if lock(&inst.features.views.latch).is_none() {
            let decided = if s.views.fov_cut { decide(inst, system, s, views) } else { Latched::default() };
            lock(&inst.features.views.latch).get_or_insert(decided);
        }
        let latch = lock(&inst.features.views.latch);
        let Some(l) = latch.as_ref() else { return };
        for (v, c) in views.iter_mut().zip(&l.views) {
            // Only where the runtime still answers the size the cut was made on.
            if let Some(c) = c.filter(|c| c.size == (v.recommended_image_rect_width, v.recommended_image_rect_height)) {
                (v.recommended_image_rect_width, v.recommended_image_rect_height) = c.cut.size();
            }
        }
    }

    fn amend_views(&self, s: &Session, info: &xr::ViewLocateInfo, views: &mut [xr::View]) {
        if info.view_configuration_type != xr::ViewConfigurationType::PRIMARY_STEREO || views.len() != STEREO_VIEWS {
            return;
        }
        let Some(l) = Self::latched(s) else { return };
        if !s.features.views.checked.swap(true, Ordering::AcqRel) {
            Self::check_runtime_mesh(s, &l, views);
        }
        if s.features.views.off.load(Ordering::Acquire) {
            return;
        }
        let mut given = Vec::with_capacity(views.len());
        for (v, c) in views.iter_mut().zip(&l.views) {
            if let Some(c) = c {
                let fov = Fov::from_angles([v.fov.angle_left, v.fov.angle_right, v.fov.angle_up, v.fov.angle_down]);
                if fov.is_valid() {
                    // The tangents of the cut's pixel boundaries on the runtime's grid of this FOV.
                    let (px, py) = (fov.width() / c.size.0 as f64, fov.height() / c.size.1 as f64);
                    let cut = Fov { left: fov.left + c.cut.x0 as f64 * px, right: fov.left + c.cut.x1 as f64 * px, up: fov.up - c.cut.y0 as f64 * py, down: fov.up - c.cut.y1 as f64 * py };
                    let [left, right, up, down] = cut.angles();
                    v.fov = xr::Fovf { angle_left: left, angle_right: right, angle_up: up, angle_down: down };
                }
            }
            given.push([v.fov.angle_left, v.fov.angle_right, v.fov.angle_up, v.fov.angle_down]);
        }
        *lock(&s.features.views.given) = given;
    }

    /// `view_fov_cut`: whether the session's views are cut (`examples/bench --feature fov_cut`
    /// switches on it).
    fn frame_stats(&self, s: &Session) -> Vec<(&'static str, serde_json::Value)> {
        let on = !s.features.views.off.load(Ordering::Acquire) && Self::latched(s).is_some();
        vec![("view_fov_cut", on.into())]
    }

    /// Checks the frame's projection views against the angles and sizes given (never amends).
    fn amend_frame_end(&self, s: &Session, info: &xr::FrameEndInfo) -> Option<AmendedFrameEnd> {
        if s.features.views.off.load(Ordering::Acquire) || info.layer_count == 0 || info.layers.is_null() {
            return None;
        }
        let l = Self::latched(s)?;
        let given = lock(&s.features.views.given).clone();
        // The size each view was told: the cut's, or the upscale's share of it.
        let upscale = s.instance.upscale.latched().filter(|u| u.settings.enabled);
        let told = |i: usize| -> Option<(u32, u32)> {
            match &upscale {
                Some(u) => u.views.get(i).map(|v| v.render),
                None => l.views.get(i).copied().flatten().map(|c| c.cut.size()),
            }
        };
        // SAFETY: the app's layers, valid for this call (non-null, counted).
        let layers = unsafe { crate::vk::convert::slice(info.layers, info.layer_count) };
        for &layer in layers {
            // SAFETY: the app's layer; its type tells its layout.
            let Some(base) = (unsafe { layer.as_ref() }) else { continue };
            if base.ty != xr::StructureType::COMPOSITION_LAYER_PROJECTION {
                continue;
            }
            // SAFETY: a projection layer (its type says so), valid for this call.
            let p = unsafe { &*(layer as *const xr::CompositionLayerProjection) };
            // SAFETY: its views array as counted, valid for this call.
            let views = unsafe { crate::vk::convert::slice(p.views, p.view_count) };
            for (i, (v, g)) in views.iter().zip(&given).enumerate() {
                let a = [v.fov.angle_left, v.fov.angle_right, v.fov.angle_up, v.fov.angle_down];
                if a.iter().zip(g).any(|(a, g)| (a - g).abs() > ANGLE_TOLERANCE) {
                    Self::turn_off(s, &format!("the app submitted view {i} with angles {a:?}, not the {g:?} it was given"));
                    return None;
                }
                let size = (v.sub_image.image_rect.extent.width.max(0) as u32, v.sub_image.image_rect.extent.height.max(0) as u32);
                if let Some(t) = told(i).filter(|&t| t != size) {
                    Self::turn_off(s, &format!("the app renders view {i} at {}x{}, not the {}x{} it was told", size.0, size.1, t.0, t.1));
                    return None;
                }
            }
        }
        None
    }
}
