//! Eye tracking without the app knowing: when the runtime has `XR_EXT_eye_gaze_interaction` and
//! the app does not use it, the layer adds its own action set (one gaze pose action with its
//! binding suggestion) to the app's `xrAttachSessionActionSets` and `xrSyncActions`, and locates the
//! gaze each frame where the app locates its views. The app's own actions are untouched.

use super::session::{self, Session};
use crate::core::fovea;
use crate::features::foveation::rules::{CenterSource, GazeFilter};
use crate::guard;
use openxr_sys as xr;
use openxr_sys::Handle as _;
use std::ffi::c_char;
use std::sync::Mutex;

/// The layer's gaze action objects of one session.
#[derive(Debug)]
pub(crate) struct GazeActions {
    pub action_set: xr::ActionSet,
    pub space: xr::Space,
}

/// Per-session gaze state.
#[derive(Debug, Default)]
pub(crate) struct Gaze {
    pub actions: Mutex<Option<GazeActions>>,
    pub filters: Mutex<Vec<GazeFilter>>,
    pub source: Mutex<Option<CenterSource>>,
}

fn fixed<const N: usize>(s: &str) -> [c_char; N] {
    let mut out = [0 as c_char; N];
    for (o, b) in out.iter_mut().zip(s.bytes().take(N - 1)) {
        *o = b as c_char;
    }
    out
}

/// Whether this session should get the layer's gaze action: the layer enabled the extension
/// itself (an app that enabled it may suggest its own eye-gaze bindings, which ours would replace),
/// and the config at attach time asks for eye-tracked foveation.
fn wanted(s: &Session) -> bool {
    let inst = &s.instance;
    let settings = super::settings(inst);
    inst.layer_extensions.iter().any(|e| e == super::EYE_GAZE_EXT) && settings.foveation.enabled && settings.foveation.eye_tracking
}

/// Creates the action set, the pose action, its binding suggestion and its space. Any failure
/// undoes what was made and leaves the app's attach alone.
fn create_actions(s: &Session) -> Result<(xr::ActionSet, xr::Action), String> {
    let n = &s.instance.next;
    let (Some(string_to_path), Some(create_set), Some(create_action), Some(suggest), Some(destroy_set)) =
        (n.string_to_path, n.create_action_set, n.create_action, n.suggest_interaction_profile_bindings, n.destroy_action_set)
    else {
        return Err("the runtime lacks an action function".into());
    };
    let instance = s.instance.handle;
    let path = |p: &str| -> Result<xr::Path, String> {
        let c = std::ffi::CString::new(p).map_err(|e| e.to_string())?;
        let mut out = xr::Path::NULL;
        // SAFETY: valid instance, NUL-terminated string, valid out pointer.
        let r = unsafe { string_to_path(instance, c.as_ptr(), &mut out) };
        if r == xr::Result::SUCCESS { Ok(out) } else { Err(format!("xrStringToPath({p}): {r:?}")) }
    };
    let profile = path("/interaction_profiles/ext/eye_gaze_interaction")?;
    let binding = path("/user/eyes_ext/input/gaze_ext/pose")?;
    let set_info = xr::ActionSetCreateInfo {
        ty: xr::ActionSetCreateInfo::TYPE,
        next: std::ptr::null(),
        action_set_name: fixed("stereoshim_gaze"),
        localized_action_set_name: fixed("stereoshim gaze"),
        priority: 0,
    };
    let mut set = xr::ActionSet::NULL;
    // SAFETY: valid instance and create info.
    let r = unsafe { create_set(instance, &set_info, &mut set) };
    if r != xr::Result::SUCCESS {
        return Err(format!("xrCreateActionSet: {r:?}"));
    }
    let action_info = xr::ActionCreateInfo {
        ty: xr::ActionCreateInfo::TYPE,
        next: std::ptr::null(),
        action_name: fixed("gaze"),
        action_type: xr::ActionType::POSE_INPUT,
        count_subaction_paths: 0,
        subaction_paths: std::ptr::null(),
        localized_action_name: fixed("gaze"),
    };
    let mut action = xr::Action::NULL;
    // SAFETY: the action set was just created.
    let r = unsafe { create_action(set, &action_info, &mut action) };
    let undo = |msg: String| {
        // SAFETY: destroying the set we created (and its action with it).
        unsafe { destroy_set(set) };
        msg
    };
    if r != xr::Result::SUCCESS {
        return Err(undo(format!("xrCreateAction: {r:?}")));
    }
    let bindings = [xr::ActionSuggestedBinding { action, binding }];
    let suggested = xr::InteractionProfileSuggestedBinding {
        ty: xr::InteractionProfileSuggestedBinding::TYPE,
        next: std::ptr::null(),
        interaction_profile: profile,
        count_suggested_bindings: 1,
        suggested_bindings: bindings.as_ptr(),
    };
    // SAFETY: valid instance; the bindings array lives until the call returns.
    let r = unsafe { suggest(instance, &suggested) };
    if r != xr::Result::SUCCESS {
        return Err(undo(format!("xrSuggestInteractionProfileBindings: {r:?}")));
    }
    Ok((set, action))
}

pub(super) unsafe extern "system" fn attach_session_action_sets(
    session: xr::Session,
    attach_info: *const xr::SessionActionSetsAttachInfo,
) -> xr::Result {
    let (inst, sess) = match session::lookup(session) {
        Ok(s) => (s.instance.clone(), Some(s)),
        Err(Some(inst)) => (inst, None),
        Err(None) => return xr::Result::ERROR_HANDLE_INVALID,
    };
    let Some(next) = inst.next.attach_session_action_sets else { return xr::Result::ERROR_FUNCTION_UNSUPPORTED };
    // SAFETY: forwarding the app's arguments unchanged.
    let plain = || unsafe { next(session, attach_info) };
    guard::run("xrAttachSessionActionSets", &inst.pass_through, |down| {
        inst.check_fault("xrAttachSessionActionSets")?;
        // SAFETY: the app's attach info, valid for this call (null goes down for the runtime).
        let Some((s, info)) = sess.as_ref().zip(unsafe { attach_info.as_ref() }) else { return Ok(down.call(plain)) };
        if !wanted(s) {
            return Ok(down.call(plain));
        }
        let (set, action) = match create_actions(s) {
            Ok(a) => a,
            Err(e) => {
                tracing::warn!("eye tracking unavailable: {e}; foveation stays fixed");
                return Ok(down.call(plain));
            }
        };
        // SAFETY: the app's array of `count_action_sets` handles.
        let mut sets: Vec<xr::ActionSet> = unsafe {
            if info.count_action_sets == 0 || info.action_sets.is_null() {
                Vec::new()
            } else {
                std::slice::from_raw_parts(info.action_sets, info.count_action_sets as usize).to_vec()
            }
        };
        sets.push(set);
        let mut with = *info;
        with.count_action_sets = sets.len() as u32;
        with.action_sets = sets.as_ptr();
        // SAFETY: the copy and the array live until the call returns.
        let r = down.call(|| unsafe { next(session, &with) });
        if r != xr::Result::SUCCESS {
            // The app's own attach failed (or ours made it fail): never leave it changed.
            if let Some(destroy) = inst.next.destroy_action_set {
                // SAFETY: destroying the set we created.
                unsafe { destroy(set) };
            }
            tracing::warn!(?r, "xrAttachSessionActionSets failed with the layer's gaze set");
            return Ok(r);
        }
        let space_info = xr::ActionSpaceCreateInfo {
            ty: xr::ActionSpaceCreateInfo::TYPE,
            next: std::ptr::null(),
            action,
            subaction_path: xr::Path::NULL,
            pose_in_action_space: xr::Posef::IDENTITY,
        };
        let mut space = xr::Space::NULL;
        let made = match inst.next.create_action_space {
            // SAFETY: valid session and action.
            Some(f) => (unsafe { f(session, &space_info, &mut space) }) == xr::Result::SUCCESS,
            None => false,
        };
        if made {
            tracing::info!("eye tracking: the layer's gaze action set is attached to session {:#x}", session.into_raw());
            *s.gaze.actions.lock().unwrap_or_else(|e| e.into_inner()) = Some(GazeActions { action_set: set, space });
        } else {
            tracing::warn!("eye tracking: could not create the gaze space; foveation stays fixed");
        }
        Ok(r)
    }, plain)
}

pub(super) unsafe extern "system" fn sync_actions(session: xr::Session, sync_info: *const xr::ActionsSyncInfo) -> xr::Result {
    let (inst, sess) = match session::lookup(session) {
        Ok(s) => (s.instance.clone(), Some(s)),
        Err(Some(inst)) => (inst, None),
        Err(None) => return xr::Result::ERROR_HANDLE_INVALID,
    };
    let Some(next) = inst.next.sync_actions else { return xr::Result::ERROR_FUNCTION_UNSUPPORTED };
    // SAFETY: forwarding the app's arguments unchanged.
    let plain = || unsafe { next(session, sync_info) };
    guard::run("xrSyncActions", &inst.pass_through, |down| {
        inst.check_fault("xrSyncActions")?;
        let ours = sess.as_ref().and_then(|s| s.gaze.actions.lock().unwrap_or_else(|e| e.into_inner()).as_ref().map(|g| g.action_set));
        // SAFETY: the app's sync info, valid for this call.
        let (Some(set), Some(info)) = (ours, unsafe { sync_info.as_ref() }) else { return Ok(down.call(plain)) };
        // SAFETY: the app's array of `count_active_action_sets` entries.
        let mut active: Vec<xr::ActiveActionSet> = unsafe {
            if info.count_active_action_sets == 0 || info.active_action_sets.is_null() {
                Vec::new()
            } else {
                std::slice::from_raw_parts(info.active_action_sets, info.count_active_action_sets as usize).to_vec()
            }
        };
        active.push(xr::ActiveActionSet { action_set: set, subaction_path: xr::Path::NULL });
        let mut with = *info;
        with.count_active_action_sets = active.len() as u32;
        with.active_action_sets = active.as_ptr();
        // SAFETY: the copy and the array live until the call returns.
        Ok(down.call(|| unsafe { next(session, &with) }))
    }, plain)
}

/// Samples the gaze at the time and in the space the app just located its views, and feeds each
/// view's gaze policy. Views without a usable sample run the policy with `None` (hold, then the
/// optical axis).
pub(crate) fn sample(s: &Session, info: &xr::ViewLocateInfo, views: &[xr::View]) {
    let settings = super::settings(&s.instance);
    let tracked = settings.foveation.enabled && settings.foveation.eye_tracking;
    let space = s.gaze.actions.lock().unwrap_or_else(|e| e.into_inner()).as_ref().map(|g| g.space);
    let direction = match (tracked, space, s.instance.next.locate_space) {
        (true, Some(space), Some(locate)) => {
            let mut loc = xr::SpaceLocation {
                ty: xr::SpaceLocation::TYPE,
                next: std::ptr::null_mut(),
                location_flags: xr::SpaceLocationFlags::EMPTY,
                pose: xr::Posef::IDENTITY,
            };
            // SAFETY: our space and the app's space, both live in this session.
            let r = unsafe { locate(space, info.space, info.display_time, &mut loc) };
            let valid = xr::SpaceLocationFlags::ORIENTATION_VALID | xr::SpaceLocationFlags::ORIENTATION_TRACKED;
            (r == xr::Result::SUCCESS && loc.location_flags.contains(valid)).then(|| {
                let q = loc.pose.orientation;
                fovea::forward([q.x, q.y, q.z, q.w])
            })
        }
        _ => None,
    };
    let mut filters = s.gaze.filters.lock().unwrap_or_else(|e| e.into_inner());
    filters.resize_with(views.len(), GazeFilter::default);
    let mut source = CenterSource::Fixed;
    let centers: Vec<fovea::Tangent> = views
        .iter()
        .zip(filters.iter_mut())
        .map(|(v, f)| {
            let q = v.pose.orientation;
            let sample = direction.and_then(|d| fovea::gaze_in_view([q.x, q.y, q.z, q.w], d));
            let (c, src) = f.update(sample, info.display_time.as_nanos());
            source = src;
            c
        })
        .collect();
    drop(filters);
    let mut last = s.gaze.source.lock().unwrap_or_else(|e| e.into_inner());
    if *last != Some(source) {
        tracing::info!("foveation centre now from {source:?}");
        *last = Some(source);
    }
    *s.gaze_centers.lock().unwrap_or_else(|e| e.into_inner()) = centers;
}
