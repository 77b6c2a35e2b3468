//! The view tricks' OpenXR half (docs/views.md). At the instance's first
//! `xrEnumerateViewConfigurationViews` that can know the views (a session's runtime meshes, or an
//! HMD profile) they are decided and latched for the instance (the app sizes its swapchains from
//! that answer; an app that sized them from an earlier one fails the checks below), from the lens
//! and views `source` finds:
//! - the FOV cut (`view.fov_cut = lens`): each view's cut on whole pixels of the runtime's
//!   recommended image;
//! - symmetric and parallel views (`view.symmetric`, `view.parallel`): the size that keeps the
//!   runtime's pixels per tangent over the widened views.
//!
//! `xrLocateViews` then hands the app the angles of exactly the cut pixels of each view's grid,
//! turned parallel (both views the mean orientation, each FOV the smallest holding its canted one)
//! and made symmetric, in that order, computed from each frame's located views. Per session, the
//! first located views are checked against the runtime's hidden-area mesh (the cut must hold every
//! pixel the lens shows), and every frame's submitted views against the ones given (angles, size,
//! and for parallel views their relative turn): any failing turns the tricks off for the session
//! (logged), and the app then gets the runtime's own views (its images, already made, show them at
//! another density). The padding symmetric and parallel views add beyond the runtime's FOV is
//! hidden by the mask (`core::reframe`), which comes on with them (`Settings`).

use crate::features::views::ViewSettings;
use super::rules::{self, Cut, Fov, Symmetric};
use super::source::{Lens, lens_from_profile, lens_from_runtime, profile_for, session_of, system_name, tangents, turns_from_profile};
use crate::core::reframe;
use crate::core::lens::hidden_pixels;
use crate::plugin::settings::Settings;
use glam::DQuat;
use crate::plugin::xr::{AmendedFrameEnd, Instance, Session, XrFeature, VISIBILITY_MASK_EXT};
use openxr_sys as xr;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Mutex, MutexGuard};

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// Views of `XR_VIEW_CONFIGURATION_TYPE_PRIMARY_STEREO`, the configuration the tricks apply to.
const STEREO_VIEWS: usize = 2;

/// How far a submitted angle may be from the one given (radians): the app's own float round trip.
const ANGLE_TOLERANCE: f32 = 1e-5;

/// How far the submitted views' relative turn may be from the given one's (radians): float round
/// trips through the app's pose math, far below the smallest cant (degrees).
const TURN_TOLERANCE: f64 = 1e-3;

/// The view tricks' OpenXR half.
pub(crate) struct ViewsXr;

/// Symmetric and parallel views as latched: the modes, the size each view is told, and the views
/// as decided (for a visibility mask asked before any view is located).
#[derive(Clone, Debug, PartialEq)]
struct Widened {
    symmetric: Symmetric,
    parallel: bool,
    sizes: Vec<(u32, u32)>,
    /// The runtime's views' FOVs.
    runtime: [Fov; 2],
    /// The views' FOVs as the app gets them.
    app: [Fov; 2],
    /// The runtime's views' orientation in the frame of the app's (parallel views of canted ones).
    turns: [Option<DQuat>; 2],
}

/// What an instance latched at its first `xrEnumerateViewConfigurationViews`.
#[derive(Clone, Debug, Default)]
struct Latched {
    /// The runtime's recommended sizes it was decided on.
    runtime_sizes: Vec<(u32, u32)>,
    /// Per view, its cut on the runtime's recommended grid (None: not cut).
    views: Vec<Option<Cut>>,
    /// Symmetric or parallel views (None: neither).
    widened: Option<Widened>,
}

impl Latched {
    /// The size view `i` is told.
    fn told(&self, i: usize) -> Option<(u32, u32)> {
        match &self.widened {
            Some(w) => w.sizes.get(i).copied(),
            None => self.views.get(i).copied().flatten().map(|c| c.size()),
        }
    }

    /// The tricks on, in words ("the cut and the parallel views").
    fn names(&self) -> String {
        let mut n = Vec::new();
        if self.views.iter().any(Option::is_some) {
            n.push("the cut");
        }
        if let Some(w) = &self.widened {
            if w.parallel {
                n.push("the parallel views");
            }
            if w.symmetric != Symmetric::Off {
                n.push("the symmetric views");
            }
        }
        n.join(" and ")
    }
}

/// The views given to the app in a frame, for the check of what it submits.
#[derive(Clone, Debug, Default)]
struct Given {
    /// Per view (XrFovf order: left, right, up, down).
    angles: Vec<[f32; 4]>,
    /// The right view's orientation in the left's frame (parallel views only).
    turn: Option<DQuat>,
}

/// The view tricks' per-instance state.
#[derive(Debug, Default)]
pub(crate) struct ViewsInstance {
    latch: Mutex<Option<Latched>>,
}

/// The view tricks' per-session state.
#[derive(Debug, Default)]
pub(crate) struct ViewsSession {
    /// The tricks are off for this session (a check failed).
    off: AtomicBool,
    /// The runtime's mesh was checked against the cut.
    checked: AtomicBool,
    /// The views the app was last given.
    given: Mutex<Given>,
}

/// `q` as glam's (f64).
fn dquat(q: &xr::Quaternionf) -> DQuat {
    DQuat::from_xyzw(q.x as f64, q.y as f64, q.z as f64, q.w as f64).normalize()
}

fn fov_of(v: &xr::View) -> Fov {
    Fov::from_angles([v.fov.angle_left, v.fov.angle_right, v.fov.angle_up, v.fov.angle_down])
}

/// Decides the instance's view tricks for `views` (the runtime's answer); None while the views
/// cannot be known yet (no session whose runtime meshes tell them, no HMD profile): apps such as
/// hello_xr enumerate once to log before their session and again to size their swapchains.
fn decide(inst: &Instance, system: xr::SystemId, s: &Settings, views: &[xr::ViewConfigurationView]) -> Option<Latched> {
    let margin = s.of::<ViewSettings>().fov_cut_margin_deg;
    let sizes: Vec<(u32, u32)> = views.iter().map(|v| (v.recommended_image_rect_width, v.recommended_image_rect_height)).collect();
    let session = session_of(inst).filter(|_| inst.has_extension(VISIBILITY_MASK_EXT));
    let name = system_name(inst, system).unwrap_or_default();
    let profile = profile_for(&name);
    let (lenses, source): (Option<Vec<_>>, &str) = match (&session, profile) {
        (Some(sess), _) => (sizes.iter().enumerate().map(|(i, &size)| lens_from_runtime(sess, i as u32, size)).collect(), "the runtime's visibility mask"),
        (None, Some(p)) => (sizes.iter().enumerate().map(|(i, &size)| lens_from_profile(p, i, size)).collect(), "the HMD profile's lens"),
        (None, None) if session_of(inst).is_none() => {
            tracing::info!("view tricks: the views of {name:?} are not known before a session (no HMD profile matches it); decided at the next xrEnumerateViewConfigurationViews after xrCreateSession");
            return None;
        }
        (None, None) => (None, ""),
    };
    let mut latched = Latched { runtime_sizes: sizes.clone(), views: vec![None; sizes.len()], widened: None };
    if s.of::<ViewSettings>().fov_cut {
        // One size for every view (apps render them at one size), or no cut when a view has none.
        match lenses.as_ref().and_then(|l| rules::cuts(l, margin)) {
            Some(cuts) => {
                for (i, (cut, &size)) in cuts.into_iter().zip(&sizes).enumerate() {
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
                    latched.views[i] = Some(cut);
                }
            }
            None => tracing::warn!("view.fov_cut: no lens known for {name:?} (no runtime mesh of a session, no HMD profile matching it); the views are not cut"),
        }
    }
    if s.of::<ViewSettings>().widens() {
        let max = views.iter().map(|v| (v.max_image_rect_width, v.max_image_rect_height)).fold((u32::MAX, u32::MAX), |a, m| (a.0.min(m.0), a.1.min(m.1)));
        latched.widened = widen(s, &name, profile, lenses.as_deref(), &latched, max, source);
    }
    Some(latched)
}

/// The sizes of symmetric and parallel views: each view's size (the cut's, else the runtime's)
/// grown with its FOV at the same pixels per tangent, one size for both (the larger of each side,
/// so neither eye loses density). None (logged) when the views' FOVs are not known.
#[allow(clippy::too_many_arguments)]
fn widen(s: &Settings, name: &str, profile: Option<&hmd_profiles::profile::HmdProfile>, lenses: Option<&[Lens]>, latched: &Latched, max: (u32, u32), source: &str) -> Option<Widened> {
    let (symmetric, parallel) = (s.of::<ViewSettings>().symmetric, s.of::<ViewSettings>().parallel);
    let Some(lenses) = lenses.filter(|l| l.len() == STEREO_VIEWS) else {
        tracing::warn!("view.symmetric / view.parallel: the views of {name:?} are not known before they are located (no runtime mesh of a session, no HMD profile matching it); the views are not widened");
        return None;
    };
    let base: Vec<(Fov, (u32, u32))> = lenses.iter().zip(&latched.views).map(|((fov, size, _), c)| c.map_or((*fov, *size), |c| (c.fov, c.size()))).collect();
    let fovs = [base[0].0, base[1].0];
    // The displays' cant from the profile; a runtime without one is taken as parallel until its
    // views are located (each frame's views are widened from what the runtime locates).
    let turns = profile.map(turns_from_profile).unwrap_or([DQuat::IDENTITY; 2]);
    let Some((mean, wide)) = rules::widen(fovs, turns, symmetric, parallel) else {
        tracing::warn!("view.parallel: a canted view of {name:?} reaches behind the parallel one; the views are not widened");
        return None;
    };
    let grown: Vec<(u32, u32)> = base.iter().zip(&wide).map(|((fov, size), w)| rules::size_for(*size, fov, w)).collect();
    let needed = grown.iter().fold((0, 0), |a, g| (a.0.max(g.0), a.1.max(g.1)));
    // Within the runtime's largest image: past it the views keep their angles at a lower density.
    let one = (needed.0.min(max.0).max(1), needed.1.min(max.1).max(1));
    if one != needed {
        tracing::warn!("view.symmetric / view.parallel: the widened views need {}x{}, more than the runtime's largest image {}x{}; they get {}x{} (fewer pixels per degree than the runtime's)", needed.0, needed.1, max.0, max.1, one.0, one.1);
    }
    let pixels = |v: &[(u32, u32)]| v.iter().map(|&(w, h)| w as f64 * h as f64).sum::<f64>();
    let before = pixels(&base.iter().map(|b| b.1).collect::<Vec<_>>());
    let turned = if parallel { [DQuat::IDENTITY; 2] } else { turns };
    let overlap = |f: &[Fov; 2], t: [DQuat; 2]| rules::seen_overlap(f, t).map_or("unknown".to_string(), |o| format!("{:.1} %", 100.0 * o));
    tracing::info!(
        "view.symmetric = {}, view.parallel = {}: views {} -> {}x{} each, {:+.1} % pixels; overlap of the views {} -> {}; the views from {source}; the hidden-area mask hides what the runtime does not show",
        symmetric.name(),
        if parallel { "on" } else { "off" },
        base.iter().map(|b| format!("{}x{}", b.1 .0, b.1 .1)).collect::<Vec<_>>().join(", "),
        one.0,
        one.1,
        100.0 * (2.0 * one.0 as f64 * one.1 as f64 / before - 1.0),
        overlap(&fovs, turns),
        overlap(&wide, turned),
    );
    let runtime = [lenses[0].0, lenses[1].0];
    let turns = mean.map_or([None; 2], |m| turns.map(|t| Some(m.inverse() * t)));
    Some(Widened { symmetric, parallel, sizes: vec![one; STEREO_VIEWS], runtime, app: wide, turns })
}

impl ViewsXr {
    fn latched(s: &Session) -> Option<Latched> {
        lock(&s.instance.feature::<ViewsInstance>().latch).clone().filter(|l| l.views.iter().any(Option::is_some) || l.widened.is_some())
    }

    /// Turns the tricks off for session `s`, saying why (once).
    fn turn_off(s: &Session, l: &Latched, why: &str) {
        if !s.feature::<ViewsSession>().off.swap(true, Ordering::AcqRel) {
            let names = l.names();
            let verb = if names.contains(" and ") { "are" } else { "is" };
            tracing::warn!("view tricks: {why}; {names} {verb} off for this session (the app gets the runtime's views)");
        }
    }

    /// The session's first located views against the runtime's mesh: every pixel the lens shows
    /// must be inside the cut.
    fn check_runtime_mesh(s: &Session, l: &Latched, views: &[xr::View]) {
        if !s.instance.has_extension(VISIBILITY_MASK_EXT) {
            return;
        }
        for (i, ((c, &size), v)) in l.views.iter().zip(&l.runtime_sizes).zip(views).enumerate() {
            let Some(c) = c else { continue };
            let Some(hidden) = s.runtime_mask(i as u32) else { continue };
            let Some(bits) = hidden_pixels(&hidden, &tangents(&fov_of(v)), size) else { continue };
            let w = size.0 as usize;
            let inside = |k: usize| (c.x0..c.x1).contains(&((k % w) as u32)) && (c.y0..c.y1).contains(&((k / w) as u32));
            let outside = bits.iter().enumerate().any(|(k, &hidden)| !hidden && !inside(k));
            if outside {
                Self::turn_off(s, l, &format!("view {i}: the runtime's lens shows pixels outside the cut"));
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
        if lock(&inst.feature::<ViewsInstance>().latch).is_none() {
            let decided = if s.of::<ViewSettings>().fov_cut || s.of::<ViewSettings>().widens() { decide(inst, system, s, views) } else { Some(Latched::default()) };
            match decided {
                Some(d) => {
                    lock(&inst.feature::<ViewsInstance>().latch).get_or_insert(d);
                }
                // Not yet: this answer goes to the app unchanged.
                None => return,
            }
        }
        let latch = lock(&inst.feature::<ViewsInstance>().latch);
        let Some(l) = latch.as_ref() else { return };
        for (i, v) in views.iter_mut().enumerate() {
            // Only where the runtime still answers the size the tricks were decided on.
            let answered = (v.recommended_image_rect_width, v.recommended_image_rect_height);
            if let Some(told) = l.told(i).filter(|_| l.runtime_sizes.get(i) == Some(&answered)) {
                (v.recommended_image_rect_width, v.recommended_image_rect_height) = told;
            }
        }
    }

    fn amend_views(&self, s: &Session, info: &xr::ViewLocateInfo, views: &mut [xr::View]) {
        if info.view_configuration_type != xr::ViewConfigurationType::PRIMARY_STEREO || views.len() != STEREO_VIEWS {
            return;
        }
        let Some(l) = Self::latched(s) else { return };
        if !s.feature::<ViewsSession>().checked.swap(true, Ordering::AcqRel) {
            Self::check_runtime_mesh(s, &l, views);
        }
        if s.feature::<ViewsSession>().off.load(Ordering::Acquire) {
            return;
        }
        let located: Vec<xr::View> = views.to_vec();
        for ((v, c), &size) in views.iter_mut().zip(&l.views).zip(&l.runtime_sizes) {
            let Some(c) = c else { continue };
            let fov = fov_of(v);
            if fov.is_valid() {
                // The cut's pixels on the runtime's grid of this frame's FOV.
                let [left, right, up, down] = fov.pixels(size, (c.x0, c.x1, c.y0, c.y1)).angles();
                v.fov = xr::Fovf { angle_left: left, angle_right: right, angle_up: up, angle_down: down };
            }
        }
        let mut turn = None;
        if let Some(w) = &l.widened {
            // From this frame's views: the runtime's own angles and cant rule, the latch only sized.
            let (fovs, orientations) = ([fov_of(&views[0]), fov_of(&views[1])], [dquat(&views[0].pose.orientation), dquat(&views[1].pose.orientation)]);
            match rules::widen(fovs, orientations, w.symmetric, w.parallel).filter(|_| fovs.iter().all(Fov::is_valid)) {
                Some((mean, wide)) => {
                    for (v, f) in views.iter_mut().zip(wide) {
                        let [left, right, up, down] = f.angles();
                        v.fov = xr::Fovf { angle_left: left, angle_right: right, angle_up: up, angle_down: down };
                        if let Some(m) = mean {
                            v.pose.orientation = xr::Quaternionf { x: m.x as f32, y: m.y as f32, z: m.z as f32, w: m.w as f32 };
                        }
                    }
                    if w.parallel {
                        turn = Some(dquat(&views[0].pose.orientation).inverse() * dquat(&views[1].pose.orientation));
                    }
                }
                None => {
                    Self::turn_off(s, &l, "the located views cannot be widened (a canted view reaches behind the parallel one, or an angle is not finite)");
                    views.copy_from_slice(&located);
                    return;
                }
            }
        }
        let angles = views.iter().map(|v| [v.fov.angle_left, v.fov.angle_right, v.fov.angle_up, v.fov.angle_down]).collect();
        *lock(&s.feature::<ViewsSession>().given) = Given { angles, turn };
    }

    /// Symmetric and parallel views: the runtime's mesh as the app's views see it (a hidden mesh
    /// with the padding outside the runtime's views added; visible meshes and line loops turned
    /// with parallel views). From this frame's views once located, else the latched ones.
    fn amend_visibility_mask(&self, s: &Session, view: u32, ty: xr::VisibilityMaskTypeKHR) -> Option<Vec<[f32; 2]>> {
        if s.feature::<ViewsSession>().off.load(Ordering::Acquire) {
            return None;
        }
        let w = Self::latched(s)?.widened?;
        let i = view as usize;
        if i >= STEREO_VIEWS {
            return None;
        }
        let shared = crate::bridge::shared().views();
        let q = |t: DQuat| [t.x as f32, t.y as f32, t.z as f32, t.w as f32];
        let (runtime, app, turn) = match (shared.runtime_fovs.get(i), shared.app_fovs.get(i)) {
            (Some(r), Some(a)) => (*r, *a, shared.runtime_turns.get(i).copied().flatten()),
            _ => (tangents(&w.runtime[i]), tangents(&w.app[i]), w.turns[i].map(q)),
        };
        let mesh = s.runtime_mesh(view, ty)?;
        match ty {
            xr::VisibilityMaskTypeKHR::HIDDEN_TRIANGLE_MESH => Some(reframe::in_app_view(&mesh, &runtime, turn, &app)),
            // What the runtime shows stays where it is: only a turn moves it.
            xr::VisibilityMaskTypeKHR::VISIBLE_TRIANGLE_MESH => turn.map(|t| reframe::turned(&mesh, t, 3)),
            xr::VisibilityMaskTypeKHR::LINE_LOOP => turn.map(|t| reframe::turned(&mesh, t, mesh.len())),
            _ => None,
        }
    }

    /// `view_fov_cut`, `view_symmetric`, `view_parallel`: which tricks the session's views have
    /// (`examples/bench --feature fov_cut` switches on the first).
    fn frame_stats(&self, s: &Session) -> Vec<(&'static str, serde_json::Value)> {
        let l = Self::latched(s).filter(|_| !s.feature::<ViewsSession>().off.load(Ordering::Acquire));
        let cut = l.as_ref().is_some_and(|l| l.views.iter().any(Option::is_some));
        let w = l.and_then(|l| l.widened);
        let symmetric = w.as_ref().map_or("off", |w| w.symmetric.name());
        vec![("view_fov_cut", cut.into()), ("view_symmetric", symmetric.into()), ("view_parallel", w.is_some_and(|w| w.parallel).into())]
    }

    /// Checks the frame's projection views against the views and sizes given (never amends).
    fn amend_frame_end(&self, s: &Session, info: &xr::FrameEndInfo) -> Option<AmendedFrameEnd> {
        if s.feature::<ViewsSession>().off.load(Ordering::Acquire) || info.layer_count == 0 || info.layers.is_null() {
            return None;
        }
        let l = Self::latched(s)?;
        let given = lock(&s.feature::<ViewsSession>().given).clone();
        // The size each view was told: the tricks', or the upscale's share of it.
        let upscale = lock(&s.instance.told_sizes).clone();
        let told = |i: usize| -> Option<(u32, u32)> {
            match &upscale {
                Some(u) => u.get(i).copied(),
                None => l.told(i),
            }
        };
        // SAFETY: the app's layers, valid for this call (non-null, counted).
        let layers = unsafe { crate::plugin::vk::convert::slice(info.layers, info.layer_count) };
        for &layer in layers {
            // SAFETY: the app's layer; its type tells its layout.
            let Some(base) = (unsafe { layer.as_ref() }) else { continue };
            if base.ty != xr::StructureType::COMPOSITION_LAYER_PROJECTION {
                continue;
            }
            // SAFETY: a projection layer (its type says so), valid for this call.
            let p = unsafe { &*(layer as *const xr::CompositionLayerProjection) };
            // SAFETY: its views array as counted, valid for this call.
            let views = unsafe { crate::plugin::vk::convert::slice(p.views, p.view_count) };
            for (i, (v, g)) in views.iter().zip(&given.angles).enumerate() {
                let a = [v.fov.angle_left, v.fov.angle_right, v.fov.angle_up, v.fov.angle_down];
                if a.iter().zip(g).any(|(a, g)| (a - g).abs() > ANGLE_TOLERANCE) {
                    Self::turn_off(s, &l, &format!("the app submitted view {i} with angles {a:?}, not the {g:?} it was given"));
                    return None;
                }
                let size = (v.sub_image.image_rect.extent.width.max(0) as u32, v.sub_image.image_rect.extent.height.max(0) as u32);
                if let Some(t) = told(i).filter(|&t| t != size) {
                    Self::turn_off(s, &l, &format!("the app renders view {i} at {}x{}, not the {}x{} it was told", size.0, size.1, t.0, t.1));
                    return None;
                }
            }
            // Parallel views: the views' turn against each other, which no choice of the app's
            // space changes (a canted submission would be composited as parallel).
            if let (Some(g), [v0, v1, ..]) = (given.turn, views) {
                let turn = dquat(&v0.pose.orientation).inverse() * dquat(&v1.pose.orientation);
                if turn.angle_between(g) > TURN_TOLERANCE {
                    Self::turn_off(s, &l, &format!("the app submitted views turned {:.2}° apart, not the {:.2}° it was given", turn.angle_between(DQuat::IDENTITY).to_degrees(), g.angle_between(DQuat::IDENTITY).to_degrees()));
                    return None;
                }
            }
        }
        None
    }
}
