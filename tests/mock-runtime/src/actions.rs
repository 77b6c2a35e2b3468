//! Minimal action system: enough of xrCreateActionSet … xrSyncActions … xrGetActionState* and
//! action spaces for an app's menu button and eye gaze (XR_EXT_eye_gaze_interaction), with the
//! spec's errors for misuse. Input is scripted by MOCK_XR_MENU_CLICK_AT and MOCK_XR_GAZE (or
//! MOCK_XR_GAZE_PATH, a gaze that moves with the frame number).
//! Suggested bindings are checked against every interaction profile of the spec (profiles.rs),
//! so real apps that suggest several profiles run; only the simple controller and eye gaze are
//! driven, bindings to the others are accepted and stay inactive.

use std::collections::HashMap;
use std::ffi::c_char;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use glam::{Quat, Vec3};
use openxr_sys as xr;
use xr::Handle as _;

use crate::handles::Registry;
use crate::profiles::{Avail, Kind, PROFILES};
use crate::instance::{self, Event, Instance};
use crate::session::{self, Session};
use crate::space::{head_pose, Pose};
use crate::util::{guard, input, out_ptr, output, read_fixed, two_call_copy, two_call_str, XrResult};
use crate::EXT_EYE_GAZE;

pub static ACTION_SETS: Registry<ActionSet> = Registry::new();
pub static ACTIONS: Registry<Action> = Registry::new();

pub const SIMPLE_CONTROLLER: &str = "/interaction_profiles/khr/simple_controller";
pub const EYE_GAZE_PROFILE: &str = "/interaction_profiles/ext/eye_gaze_interaction";
const GAZE_POSE: &str = "/user/eyes_ext/input/gaze_ext/pose";
const TOP_LEVEL: &[&str] = &["/user/hand/left", "/user/hand/right", "/user/head", "/user/gamepad", "/user/eyes_ext"];

pub struct ActionSet {
    pub handle: u64,
    pub instance: u64,
    pub name: String,
    pub localized: String,
    /// Once attached to a session its actions are frozen.
    pub attached: AtomicBool,
}

pub struct Action {
    pub handle: u64,
    pub set: u64,
    pub instance: u64,
    pub name: String,
    pub localized: String,
    pub ty: xr::ActionType,
    pub subactions: Vec<u64>,
}

/// A component's value as the scripted "user" produces it.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Source {
    Bool(bool),
    Pose,
    Haptic,
}

/// What decides which profiles and components exist: the instance's apiVersion (major, minor)
/// and its enabled extensions.
struct Has<'a> {
    version: (u16, u16),
    extension: &'a dyn Fn(&str) -> bool,
}

impl Has<'_> {
    fn ok(&self, a: &Avail) -> bool {
        match *a {
            Avail::Core(major, minor) => self.version >= (major, minor),
            Avail::Ext(e) => (self.extension)(e),
        }
    }
}

/// The valid binding paths of `profile` on `inst` (top-level user path + component subpath) and
/// their kinds; None when the profile does not exist there (`XR_ERROR_PATH_UNSUPPORTED`).
fn profile_paths(profile: &str, inst: &Instance) -> Option<Vec<(String, Kind)>> {
    let v = inst.api_version;
    profile_paths_with(profile, &Has { version: (v.major(), v.minor()), extension: &|e| inst.extension_enabled(e) })
}

fn profile_paths_with(profile: &str, has: &Has) -> Option<Vec<(String, Kind)>> {
    if profile == EYE_GAZE_PROFILE {
        return (has.extension)(EXT_EYE_GAZE).then(|| vec![(GAZE_POSE.to_string(), Kind::Pose)]);
    }
    let p = PROFILES.iter().find(|p| p.path == profile)?;
    if !p.avail.iter().any(|a| has.ok(a)) {
        return None;
    }
    let mut out = Vec::new();
    for up in p.user_paths {
        for c in p.components {
            if c.user_path.is_some_and(|u| u != *up) || !(c.extra.is_empty() || c.extra.iter().any(|a| has.ok(a))) {
                continue;
            }
            out.push((format!("{up}{}", c.subpath), c.kind));
        }
    }
    Some(out)
}

/// Profiles whose bindings this runtime drives; bindings to every other profile are accepted but
/// stay inactive (the spec lets a runtime ignore any suggested binding).
fn driven(profile: &str) -> bool {
    profile == SIMPLE_CONTROLLER || profile == EYE_GAZE_PROFILE
}

/// The component a binding path names: the path itself when it is a component of the profile;
/// for an identifier given without its component (`/input/select`, `/input/trigger`), the
/// component the action's type reads (boolean: click, then value; float: value, then click;
/// pose: pose), else its first component.
fn canonical(path: &str, allowed: &[(String, Kind)], ty: xr::ActionType) -> Option<String> {
    if allowed.iter().any(|(a, _)| a == path) {
        return Some(path.to_string());
    }
    // Only `…/input/<identifier>` (or `/output/`) may leave its component out.
    let parent = path.rsplit_once('/').map_or("", |(p, _)| p);
    if !(parent.ends_with("/input") || parent.ends_with("/output")) {
        return None;
    }
    let children: Vec<&str> = allowed.iter().map(|(a, _)| a.as_str()).filter(|a| a.strip_prefix(path).is_some_and(|r| r.starts_with('/') && !r[1..].contains('/'))).collect();
    use xr::ActionType as T;
    let preferred: &[&str] = match ty {
        T::BOOLEAN_INPUT => &["/click", "/value"],
        T::FLOAT_INPUT => &["/value", "/click"],
        T::POSE_INPUT => &["/pose"],
        _ => &[],
    };
    preferred
        .iter()
        .map(|s| format!("{path}{s}"))
        .find(|p| children.contains(&p.as_str()))
        .or_else(|| children.first().map(|c| c.to_string()))
}

fn source_value(s: &Session, path: &str, frame: u64) -> Source {
    if path.ends_with("/pose") {
        Source::Pose
    } else if path.ends_with("/haptic") {
        Source::Haptic
    } else if path == "/user/hand/left/input/menu/click" {
        Source::Bool(s.instance.cfg.menu_click_at.is_some_and(|n| frame >= n))
    } else {
        Source::Bool(false)
    }
}

#[derive(Debug, Clone, Copy, Default)]
struct State {
    active: bool,
    value: bool,
    changed: bool,
    last_change: i64,
}

#[derive(Debug, Default)]
pub struct SessionActions {
    attached: Option<Vec<u64>>,
    /// Interaction profiles in effect after attach.
    profiles: Vec<u64>,
    /// After the last xrSyncActions: (action, subaction path or 0) → state.
    states: HashMap<(u64, u64), State>,
}

pub fn get_action(h: xr::Action) -> XrResult<Arc<Action>> {
    ACTIONS.get(h.into_raw())
}

pub fn destroy_instance_children(instance: u64) {
    ACTIONS.remove_where(|a| a.instance == instance);
    ACTION_SETS.remove_where(|a| a.instance == instance);
}

fn name_ok(n: &str) -> bool {
    !n.is_empty() && n.bytes().all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || b"-_.".contains(&b))
}

fn path_of(inst: &Instance, p: u64) -> XrResult<String> {
    inst.path_str(xr::Path::from_raw(p))
}

/// Bound source paths of `action` restricted to `sub` (0: all), under the session's profiles.
fn bound_sources(s: &Session, sa: &SessionActions, action: &Action, sub: u64) -> Vec<String> {
    let inst = &s.instance;
    let prefix = if sub == 0 { None } else { path_of(inst, sub).ok().map(|p| p + "/") };
    let bindings = inst.bindings.lock().unwrap();
    let mut out = Vec::new();
    for prof in &sa.profiles {
        for (a, b) in bindings.get(prof).into_iter().flatten() {
            if *a != action.handle {
                continue;
            }
            let Ok(p) = path_of(inst, *b) else { continue };
            // The gaze source only exists with an eye tracker.
            if p == GAZE_POSE && !crate::system::eye_gaze_supported(inst) {
                continue;
            }
            if prefix.as_ref().is_none_or(|pre| p.starts_with(pre)) && !out.contains(&p) {
                out.push(p);
            }
        }
    }
    out
}

fn attached_to(sa: &SessionActions, set: u64) -> bool {
    sa.attached.as_ref().is_some_and(|v| v.contains(&set))
}

/// The pose of an action space's action in STAGE, None when not locatable.
pub fn action_pose(s: &Session, action: u64, sub: u64) -> Option<Pose> {
    let a = ACTIONS.get(action).ok()?;
    // Taken before the actions lock: xrSyncActions takes the core lock first, then that one.
    let frame = s.core.lock().unwrap().frames_ended;
    let sa = s.actions.lock().unwrap();
    if !sa.states.get(&(action, sub)).is_some_and(|st| st.active) {
        return None;
    }
    let src = bound_sources(s, &sa, &a, sub).into_iter().next()?;
    if src == GAZE_POSE {
        let (yaw, pitch) = s.instance.cfg.gaze.as_ref()?.at(frame);
        // yaw > 0 looks right (a negative turn about +y), pitch > 0 looks up.
        let q = Quat::from_rotation_y(-yaw.to_radians()) * Quat::from_rotation_x(pitch.to_radians());
        return Some(head_pose().mul(&Pose::new(Vec3::ZERO, q)));
    }
    let x = if src.starts_with("/user/hand/left") { -0.2 } else { 0.2 };
    let q = if src.ends_with("aim/pose") { Quat::from_rotation_x(-0.3) } else { Quat::IDENTITY };
    Some(Pose::new(Vec3::new(x, 1.3, -0.35), q))
}

pub fn check_pose_action(s: &Session, a: &Action, sub: xr::Path) -> XrResult<()> {
    if a.instance != s.instance.handle {
        return Err(xr::Result::ERROR_HANDLE_INVALID);
    }
    if a.ty != xr::ActionType::POSE_INPUT {
        return Err(xr::Result::ERROR_ACTION_TYPE_MISMATCH);
    }
    check_subaction(a, sub)
}

fn check_subaction(a: &Action, sub: xr::Path) -> XrResult<()> {
    if sub == xr::Path::NULL || a.subactions.contains(&sub.into_raw()) {
        Ok(())
    } else {
        Err(xr::Result::ERROR_PATH_UNSUPPORTED)
    }
}

pub unsafe extern "system" fn xr_create_action_set(
    instance: xr::Instance,
    info: *const xr::ActionSetCreateInfo,
    out: *mut xr::ActionSet,
) -> xr::Result {
    guard("xrCreateActionSet", || {
        let inst = instance::get(instance)?;
        inst.fail_point("xrCreateActionSet")?;
        // SAFETY: app pointers.
        let (info, out) = unsafe { (input(info)?, out_ptr(out)?) };
        let name = read_fixed(&info.action_set_name)?;
        let localized = read_fixed(&info.localized_action_set_name)?;
        if !name_ok(&name) {
            return Err(xr::Result::ERROR_NAME_INVALID);
        }
        if localized.is_empty() {
            return Err(xr::Result::ERROR_LOCALIZED_NAME_INVALID);
        }
        let existing = ACTION_SETS.find(|a| a.instance == inst.handle);
        if existing.iter().any(|a| a.name == name) {
            return Err(xr::Result::ERROR_NAME_DUPLICATED);
        }
        if existing.iter().any(|a| a.localized == localized) {
            return Err(xr::Result::ERROR_LOCALIZED_NAME_DUPLICATED);
        }
        let (h, _) = ACTION_SETS.insert_with(|handle| ActionSet { handle, instance: inst.handle, name, localized, attached: AtomicBool::new(false) });
        *out = xr::ActionSet::from_raw(h);
        Ok(xr::Result::SUCCESS)
    })
}

pub unsafe extern "system" fn xr_destroy_action_set(set: xr::ActionSet) -> xr::Result {
    guard("xrDestroyActionSet", || {
        let set = ACTION_SETS.get(set.into_raw())?;
        instance::get(xr::Instance::from_raw(set.instance))?.fail_point("xrDestroyActionSet")?;
        ACTIONS.remove_where(|a| a.set == set.handle);
        ACTION_SETS.remove(set.handle);
        Ok(xr::Result::SUCCESS)
    })
}

pub unsafe extern "system" fn xr_create_action(set: xr::ActionSet, info: *const xr::ActionCreateInfo, out: *mut xr::Action) -> xr::Result {
    guard("xrCreateAction", || {
        let set = ACTION_SETS.get(set.into_raw())?;
        let inst = instance::get(xr::Instance::from_raw(set.instance))?;
        inst.fail_point("xrCreateAction")?;
        // SAFETY: app pointers.
        let (info, out) = unsafe { (input(info)?, out_ptr(out)?) };
        if set.attached.load(Ordering::SeqCst) {
            return Err(xr::Result::ERROR_ACTIONSETS_ALREADY_ATTACHED);
        }
        use xr::ActionType as T;
        if ![T::BOOLEAN_INPUT, T::FLOAT_INPUT, T::VECTOR2F_INPUT, T::POSE_INPUT, T::VIBRATION_OUTPUT].contains(&info.action_type) {
            return Err(xr::Result::ERROR_VALIDATION_FAILURE);
        }
        let name = read_fixed(&info.action_name)?;
        let localized = read_fixed(&info.localized_action_name)?;
        if !name_ok(&name) {
            return Err(xr::Result::ERROR_NAME_INVALID);
        }
        if localized.is_empty() {
            return Err(xr::Result::ERROR_LOCALIZED_NAME_INVALID);
        }
        let siblings = ACTIONS.find(|a| a.set == set.handle);
        if siblings.iter().any(|a| a.name == name) {
            return Err(xr::Result::ERROR_NAME_DUPLICATED);
        }
        if siblings.iter().any(|a| a.localized == localized) {
            return Err(xr::Result::ERROR_LOCALIZED_NAME_DUPLICATED);
        }
        let mut subactions = Vec::new();
        // SAFETY: count/array from the app.
        for p in unsafe { crate::util::slice(info.subaction_paths, info.count_subaction_paths) }? {
            let s = inst.path_str(*p)?;
            if !TOP_LEVEL.contains(&s.as_str()) || subactions.contains(&p.into_raw()) {
                return Err(xr::Result::ERROR_PATH_UNSUPPORTED);
            }
            subactions.push(p.into_raw());
        }
        let (h, _) = ACTIONS.insert_with(|handle| Action { handle, set: set.handle, instance: inst.handle, name, localized, ty: info.action_type, subactions });
        *out = xr::Action::from_raw(h);
        Ok(xr::Result::SUCCESS)
    })
}

pub unsafe extern "system" fn xr_destroy_action(action: xr::Action) -> xr::Result {
    guard("xrDestroyAction", || {
        let a = get_action(action)?;
        instance::get(xr::Instance::from_raw(a.instance))?.fail_point("xrDestroyAction")?;
        ACTIONS.remove(a.handle);
        Ok(xr::Result::SUCCESS)
    })
}

pub unsafe extern "system" fn xr_suggest_interaction_profile_bindings(
    instance: xr::Instance,
    info: *const xr::InteractionProfileSuggestedBinding,
) -> xr::Result {
    guard("xrSuggestInteractionProfileBindings", || {
        let inst = instance::get(instance)?;
        inst.fail_point("xrSuggestInteractionProfileBindings")?;
        // SAFETY: app input struct.
        let info = unsafe { input(info) }?;
        let profile = inst.path_str(info.interaction_profile)?;
        let allowed = profile_paths(&profile, &inst).ok_or(xr::Result::ERROR_PATH_UNSUPPORTED)?;
        if info.count_suggested_bindings == 0 {
            return Err(xr::Result::ERROR_VALIDATION_FAILURE);
        }
        // SAFETY: count/array from the app.
        let list = unsafe { crate::util::slice(info.suggested_bindings, info.count_suggested_bindings) }?;
        let mut out = Vec::new();
        for b in list {
            let a = get_action(b.action)?;
            if a.instance != inst.handle {
                return Err(xr::Result::ERROR_HANDLE_INVALID);
            }
            if ACTION_SETS.get(a.set).is_ok_and(|s| s.attached.load(Ordering::SeqCst)) {
                return Err(xr::Result::ERROR_ACTIONSETS_ALREADY_ATTACHED);
            }
            let path = inst.path_str(b.binding)?;
            let c = canonical(&path, &allowed, a.ty).ok_or_else(|| {
                crate::log!("binding {path} not in {profile}");
                xr::Result::ERROR_PATH_UNSUPPORTED
            })?;
            out.push((a.handle, inst.path(&c)));
        }
        let pid = info.interaction_profile.into_raw();
        inst.bindings.lock().unwrap().insert(pid, out);
        Ok(xr::Result::SUCCESS)
    })
}

pub unsafe extern "system" fn xr_attach_session_action_sets(session: xr::Session, info: *const xr::SessionActionSetsAttachInfo) -> xr::Result {
    guard("xrAttachSessionActionSets", || {
        let s = session::get(session)?;
        s.fail_point("xrAttachSessionActionSets")?;
        // SAFETY: app input struct.
        let info = unsafe { input(info) }?;
        if info.count_action_sets == 0 {
            return Err(xr::Result::ERROR_VALIDATION_FAILURE);
        }
        // SAFETY: count/array from the app.
        let sets = unsafe { crate::util::slice(info.action_sets, info.count_action_sets) }?;
        let sets: Vec<Arc<ActionSet>> = sets.iter().map(|h| ACTION_SETS.get(h.into_raw())).collect::<XrResult<_>>()?;
        if sets.iter().any(|x| x.instance != s.instance.handle) {
            return Err(xr::Result::ERROR_HANDLE_INVALID);
        }
        let mut sa = s.actions.lock().unwrap();
        if sa.attached.is_some() {
            return Err(xr::Result::ERROR_ACTIONSETS_ALREADY_ATTACHED);
        }
        for x in &sets {
            x.attached.store(true, Ordering::SeqCst);
        }
        let handles: Vec<u64> = sets.iter().map(|x| x.handle).collect();
        let bindings = s.instance.bindings.lock().unwrap();
        sa.profiles = bindings
            .iter()
            .filter(|(p, _)| s.instance.path_str(xr::Path::from_raw(**p)).is_ok_and(|p| driven(&p)))
            .filter(|(_, bs)| bs.iter().any(|(a, _)| ACTIONS.get(*a).is_ok_and(|a| handles.contains(&a.set))))
            .map(|(p, _)| *p)
            .collect();
        sa.profiles.sort();
        drop(bindings);
        sa.attached = Some(handles);
        if !sa.profiles.is_empty() {
            s.instance.push_event(Event::InteractionProfileChanged { session: s.handle });
        }
        Ok(xr::Result::SUCCESS)
    })
}

pub unsafe extern "system" fn xr_sync_actions(session: xr::Session, info: *const xr::ActionsSyncInfo) -> xr::Result {
    guard("xrSyncActions", || {
        let s = session::get(session)?;
        s.fail_point("xrSyncActions")?;
        // SAFETY: app input struct.
        let info = unsafe { input(info) }?;
        // SAFETY: count/array from the app.
        let active = unsafe { crate::util::slice(info.active_action_sets, info.count_active_action_sets) }?;
        let (focused, frame, now) = {
            let core = s.core.lock().unwrap();
            (core.state == xr::SessionState::FOCUSED, core.frames_ended, s.now(&core))
        };
        let mut sa = s.actions.lock().unwrap();
        let mut sets = Vec::new();
        for a in active {
            let set = ACTION_SETS.get(a.action_set.into_raw())?;
            if !attached_to(&sa, set.handle) {
                return Err(xr::Result::ERROR_ACTIONSET_NOT_ATTACHED);
            }
            if a.subaction_path != xr::Path::NULL {
                let p = s.instance.path_str(a.subaction_path)?;
                if !TOP_LEVEL.contains(&p.as_str()) {
                    return Err(xr::Result::ERROR_PATH_UNSUPPORTED);
                }
            }
            sets.push(set.handle);
        }
        let actions = ACTIONS.find(|a| attached_to(&sa, a.set));
        let mut states = HashMap::new();
        for a in &actions {
            for sub in std::iter::once(0).chain(a.subactions.iter().copied()) {
                let sources = bound_sources(&s, &sa, a, sub);
                let is_active = focused && sets.contains(&a.set) && !sources.is_empty();
                let value = is_active && sources.iter().any(|p| source_value(&s, p, frame) == Source::Bool(true));
                let prev = sa.states.get(&(a.handle, sub)).copied().unwrap_or_default();
                let changed = is_active && prev.active && prev.value != value;
                let last_change = if changed || (is_active && !prev.active) { now } else { prev.last_change };
                states.insert((a.handle, sub), State { active: is_active, value, changed, last_change });
            }
        }
        sa.states = states;
        Ok(if focused { xr::Result::SUCCESS } else { xr::Result::SESSION_NOT_FOCUSED })
    })
}

/// Common checks of xrGetActionState*: returns the synced state.
fn action_state(s: &Session, info: &xr::ActionStateGetInfo, ty: xr::ActionType) -> XrResult<State> {
    let a = get_action(info.action)?;
    if a.instance != s.instance.handle {
        return Err(xr::Result::ERROR_HANDLE_INVALID);
    }
    let sa = s.actions.lock().unwrap();
    if !attached_to(&sa, a.set) {
        return Err(xr::Result::ERROR_ACTIONSET_NOT_ATTACHED);
    }
    // The getter must match the action's type exactly (the spec's ACTION_TYPE_MISMATCH).
    if a.ty != ty {
        return Err(xr::Result::ERROR_ACTION_TYPE_MISMATCH);
    }
    check_subaction(&a, info.subaction_path)?;
    Ok(sa.states.get(&(a.handle, info.subaction_path.into_raw())).copied().unwrap_or_default())
}

macro_rules! state_fn {
    ($fn:ident, $name:literal, $out:ty, $ty:expr, |$st:ident, $o:ident| $body:block) => {
        pub unsafe extern "system" fn $fn(session: xr::Session, info: *const xr::ActionStateGetInfo, state: *mut $out) -> xr::Result {
            guard($name, || {
                let s = session::get(session)?;
                s.fail_point($name)?;
                // SAFETY: app pointers.
                let (info, $o) = unsafe { (input(info)?, output(state)?) };
                let $st = action_state(&s, info, $ty)?;
                $body
                Ok(xr::Result::SUCCESS)
            })
        }
    };
}

state_fn!(xr_get_action_state_boolean, "xrGetActionStateBoolean", xr::ActionStateBoolean, xr::ActionType::BOOLEAN_INPUT, |st, o| {
    o.current_state = st.value.into();
    o.changed_since_last_sync = st.changed.into();
    o.last_change_time = xr::Time::from_nanos(st.last_change);
    o.is_active = st.active.into();
});

state_fn!(xr_get_action_state_float, "xrGetActionStateFloat", xr::ActionStateFloat, xr::ActionType::FLOAT_INPUT, |st, o| {
    o.current_state = if st.value { 1.0 } else { 0.0 };
    o.changed_since_last_sync = st.changed.into();
    o.last_change_time = xr::Time::from_nanos(st.last_change);
    o.is_active = st.active.into();
});

state_fn!(xr_get_action_state_vector2f, "xrGetActionStateVector2f", xr::ActionStateVector2f, xr::ActionType::VECTOR2F_INPUT, |st, o| {
    o.current_state = xr::Vector2f { x: 0.0, y: 0.0 };
    o.changed_since_last_sync = xr::FALSE;
    o.last_change_time = xr::Time::from_nanos(st.last_change);
    o.is_active = st.active.into();
});

state_fn!(xr_get_action_state_pose, "xrGetActionStatePose", xr::ActionStatePose, xr::ActionType::POSE_INPUT, |st, o| {
    o.is_active = st.active.into();
});

pub unsafe extern "system" fn xr_get_current_interaction_profile(
    session: xr::Session,
    top: xr::Path,
    state: *mut xr::InteractionProfileState,
) -> xr::Result {
    guard("xrGetCurrentInteractionProfile", || {
        let s = session::get(session)?;
        s.fail_point("xrGetCurrentInteractionProfile")?;
        // SAFETY: app output struct.
        let o = unsafe { output(state) }?;
        let top = s.instance.path_str(top)?;
        let sa = s.actions.lock().unwrap();
        if sa.attached.is_none() {
            return Err(xr::Result::ERROR_ACTIONSET_NOT_ATTACHED);
        }
        if !TOP_LEVEL.contains(&top.as_str()) || (top == "/user/eyes_ext" && !s.instance.extension_enabled(EXT_EYE_GAZE)) {
            return Err(xr::Result::ERROR_PATH_UNSUPPORTED);
        }
        let want = match top.as_str() {
            "/user/hand/left" | "/user/hand/right" => Some(SIMPLE_CONTROLLER),
            "/user/eyes_ext" if crate::system::eye_gaze_supported(&s.instance) => Some(EYE_GAZE_PROFILE),
            _ => None,
        };
        let p = want.map(|w| s.instance.path(w)).filter(|p| sa.profiles.contains(p)).unwrap_or(0);
        o.interaction_profile = xr::Path::from_raw(p);
        Ok(xr::Result::SUCCESS)
    })
}

pub unsafe extern "system" fn xr_enumerate_bound_sources_for_action(
    session: xr::Session,
    info: *const xr::BoundSourcesForActionEnumerateInfo,
    capacity: u32,
    count_out: *mut u32,
    sources: *mut xr::Path,
) -> xr::Result {
    guard("xrEnumerateBoundSourcesForAction", || {
        let s = session::get(session)?;
        s.fail_point("xrEnumerateBoundSourcesForAction")?;
        // SAFETY: app input struct.
        let info = unsafe { input(info) }?;
        let a = get_action(info.action)?;
        let sa = s.actions.lock().unwrap();
        if !attached_to(&sa, a.set) {
            return Err(xr::Result::ERROR_ACTIONSET_NOT_ATTACHED);
        }
        let paths: Vec<xr::Path> = bound_sources(&s, &sa, &a, 0).iter().map(|p| xr::Path::from_raw(s.instance.path(p))).collect();
        // SAFETY: app array of `capacity` paths.
        unsafe { two_call_copy(capacity, count_out, sources, &paths) }?;
        Ok(xr::Result::SUCCESS)
    })
}

pub unsafe extern "system" fn xr_get_input_source_localized_name(
    session: xr::Session,
    info: *const xr::InputSourceLocalizedNameGetInfo,
    capacity: u32,
    count_out: *mut u32,
    buffer: *mut c_char,
) -> xr::Result {
    guard("xrGetInputSourceLocalizedName", || {
        let s = session::get(session)?;
        s.fail_point("xrGetInputSourceLocalizedName")?;
        // SAFETY: app input struct.
        let info = unsafe { input(info) }?;
        if info.which_components.is_empty() {
            return Err(xr::Result::ERROR_VALIDATION_FAILURE);
        }
        if s.actions.lock().unwrap().attached.is_none() {
            return Err(xr::Result::ERROR_ACTIONSET_NOT_ATTACHED);
        }
        let p = s.instance.path_str(info.source_path)?;
        // SAFETY: app buffer of `capacity` chars.
        unsafe { two_call_str(capacity, count_out, buffer, &format!("Mock {p}")) }?;
        Ok(xr::Result::SUCCESS)
    })
}

fn haptic_checks(s: &Session, info: &xr::HapticActionInfo) -> XrResult<()> {
    let a = get_action(info.action)?;
    if a.ty != xr::ActionType::VIBRATION_OUTPUT {
        return Err(xr::Result::ERROR_ACTION_TYPE_MISMATCH);
    }
    if !attached_to(&s.actions.lock().unwrap(), a.set) {
        return Err(xr::Result::ERROR_ACTIONSET_NOT_ATTACHED);
    }
    check_subaction(&a, info.subaction_path)
}

fn focus_result(s: &Session) -> xr::Result {
    if s.core.lock().unwrap().state == xr::SessionState::FOCUSED {
        xr::Result::SUCCESS
    } else {
        xr::Result::SESSION_NOT_FOCUSED
    }
}

pub unsafe extern "system" fn xr_apply_haptic_feedback(
    session: xr::Session,
    info: *const xr::HapticActionInfo,
    feedback: *const xr::HapticBaseHeader,
) -> xr::Result {
    guard("xrApplyHapticFeedback", || {
        let s = session::get(session)?;
        s.fail_point("xrApplyHapticFeedback")?;
        // SAFETY: app input structs.
        let (info, _) = unsafe { (input(info)?, input(feedback as *const xr::HapticVibration)?) };
        haptic_checks(&s, info)?;
        Ok(focus_result(&s))
    })
}

pub unsafe extern "system" fn xr_stop_haptic_feedback(session: xr::Session, info: *const xr::HapticActionInfo) -> xr::Result {
    guard("xrStopHapticFeedback", || {
        let s = session::get(session)?;
        s.fail_point("xrStopHapticFeedback")?;
        // SAFETY: app input struct.
        let info = unsafe { input(info) }?;
        haptic_checks(&s, info)?;
        Ok(focus_result(&s))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn short_binding_paths() {
        use xr::ActionType as T;
        let allowed: Vec<(String, Kind)> = [
            ("/user/hand/left/input/select/click", Kind::Boolean),
            ("/user/hand/left/input/grip/pose", Kind::Pose),
            ("/user/hand/left/input/trigger/value", Kind::Float),
            ("/user/hand/left/input/trigger/click", Kind::Boolean),
            ("/user/hand/left/input/thumbstick", Kind::Vector2f),
            ("/user/hand/left/input/thumbstick/x", Kind::Float),
        ]
        .iter()
        .map(|(p, k)| (p.to_string(), *k))
        .collect();
        let c = |p: &str, t| canonical(p, &allowed, t);
        assert_eq!(c("/user/hand/left/input/select", T::BOOLEAN_INPUT).as_deref(), Some("/user/hand/left/input/select/click"));
        assert_eq!(c("/user/hand/left/input/grip", T::POSE_INPUT).as_deref(), Some("/user/hand/left/input/grip/pose"));
        assert_eq!(c("/user/hand/left/input/trigger", T::BOOLEAN_INPUT).as_deref(), Some("/user/hand/left/input/trigger/click"));
        assert_eq!(c("/user/hand/left/input/trigger", T::FLOAT_INPUT).as_deref(), Some("/user/hand/left/input/trigger/value"));
        assert_eq!(c("/user/hand/left/input/thumbstick", T::VECTOR2F_INPUT).as_deref(), Some("/user/hand/left/input/thumbstick"));
        assert_eq!(c("/user/hand/left/input/squeeze/value", T::FLOAT_INPUT), None);
        assert_eq!(c("/user/hand/left/input/trig", T::FLOAT_INPUT), None);
        assert_eq!(c("/user/hand/left/input", T::FLOAT_INPUT), None);
        assert_eq!(c("/user/hand/right/input/select/click", T::BOOLEAN_INPUT), None);
        assert!(name_ok("menu_click-1.x") && !name_ok("Menu") && !name_ok(""));
    }

    #[test]
    fn profile_table_covers_the_spec() {
        let core_1_0 = [
            "khr/simple_controller",
            "google/daydream_controller",
            "htc/vive_controller",
            "htc/vive_pro",
            "microsoft/motion_controller",
            "microsoft/xbox_controller",
            "oculus/go_controller",
            "oculus/touch_controller",
            "valve/index_controller",
        ];
        for name in core_1_0 {
            let p = PROFILES.iter().find(|p| p.path == format!("/interaction_profiles/{name}")).unwrap_or_else(|| panic!("{name} missing"));
            assert!(p.avail.contains(&Avail::Core(1, 0)), "{name}");
        }
        let core_1_1 = PROFILES.iter().filter(|p| p.avail.contains(&Avail::Core(1, 1))).count();
        assert_eq!(core_1_1, 13, "{core_1_1} profiles promoted to 1.1");
        for p in PROFILES {
            assert!(!p.components.is_empty(), "{}", p.path);
            for up in p.user_paths {
                assert!(TOP_LEVEL.contains(up), "{}: {up}", p.path);
            }
            for a in p.avail.iter().chain(p.components.iter().flat_map(|c| c.extra)) {
                if let Avail::Ext(e) = a {
                    assert!(crate::EXTENSIONS.iter().any(|(x, _)| x == e), "{}: {e} not offered", p.path);
                }
            }
            let mut seen = std::collections::HashSet::new();
            for c in p.components {
                assert!(c.subpath.starts_with("/input/") || c.subpath.starts_with("/output/"), "{}: {}", p.path, c.subpath);
                assert!(c.user_path.is_none_or(|u| p.user_paths.contains(&u)), "{}", p.path);
                assert!(seen.insert((c.user_path, c.subpath)), "{}: {} twice", p.path, c.subpath);
            }
        }
        // The simple controller keeps exactly the components it always had (plus 1.1's grip_surface).
        let simple = PROFILES.iter().find(|p| p.path == SIMPLE_CONTROLLER).unwrap();
        let subs: Vec<&str> = simple.components.iter().filter(|c| c.extra.is_empty()).map(|c| c.subpath).collect();
        assert_eq!(subs, ["/input/select/click", "/input/menu/click", "/input/grip/pose", "/input/aim/pose", "/output/haptic"]);
        // Touch: x/y only on the left hand, a/b only on the right.
        let touch = PROFILES.iter().find(|p| p.path == "/interaction_profiles/oculus/touch_controller").unwrap();
        let x = touch.components.iter().find(|c| c.subpath == "/input/x/click").unwrap();
        assert_eq!(x.user_path, Some("/user/hand/left"));
    }

    #[test]
    fn profiles_by_version_and_extension() {
        let none = |_: &str| false;
        let hp = |e: &str| e == "XR_EXT_hp_mixed_reality_controller";
        let v10 = Has { version: (1, 0), extension: &none };
        let v11 = Has { version: (1, 1), extension: &none };
        let v10_hp = Has { version: (1, 0), extension: &hp };
        let paths = |p: &str, h: &Has| profile_paths_with(&format!("/interaction_profiles/{p}"), h).map(|v| v.into_iter().map(|(p, _)| p).collect::<Vec<_>>());
        let index = paths("valve/index_controller", &v10).unwrap();
        assert_eq!(index.len(), 2 * 24);
        assert!(!index.iter().any(|p| p.ends_with("grip_surface/pose")));
        let index = paths("valve/index_controller", &v11).unwrap();
        assert!(index.contains(&"/user/hand/right/input/grip_surface/pose".to_string()));
        assert_eq!(paths("meta/touch_controller_quest_2", &v10), None);
        assert!(paths("meta/touch_controller_quest_2", &v11).unwrap().contains(&"/user/hand/left/input/x/click".to_string()));
        assert_eq!(paths("hp/mixed_reality_controller", &v10), None);
        let hp10 = paths("hp/mixed_reality_controller", &v10_hp).unwrap();
        // Through the extension on a 1.0 instance: without 1.1's grip_surface.
        assert!(hp10.contains(&"/user/hand/left/input/x/click".to_string()) && !hp10.iter().any(|p| p.ends_with("grip_surface/pose")));
        assert!(paths("hp/mixed_reality_controller", &v11).unwrap().iter().any(|p| p.ends_with("grip_surface/pose")));
        assert_eq!(paths("facebook/touch_controller_pro", &v11), None);
        assert_eq!(paths("ext/eye_gaze_interaction", &v11), None);
        assert_eq!(paths("ext/eye_gaze_interaction", &Has { version: (1, 0), extension: &|e: &str| e == EXT_EYE_GAZE }).unwrap(), [GAZE_POSE]);
        let vive_pro = paths("htc/vive_pro", &v10).unwrap();
        assert_eq!(vive_pro, ["/user/head/input/system/click", "/user/head/input/volume_up/click", "/user/head/input/volume_down/click", "/user/head/input/mute_mic/click"]);
    }
}
