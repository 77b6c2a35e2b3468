//! Foveation on the OpenXR side: each frame's fovea (rings from the settings, centres from the
//! gaze policy) is published for the Vulkan half at `xrBeginFrame`; colour swapchains get the
//! usage radial density masking's reconstruction needs.
//!
//! Eye tracking without the app knowing: when the runtime has `XR_EXT_eye_gaze_interaction` and
//! the app does not use it, the layer adds its own action set (one gaze pose action with its
//! binding suggestion) next to the app's at `xrAttachSessionActionSets` and `xrSyncActions`, and
//! locates the gaze each frame where the app locates its views. The app's own actions are
//! untouched.

use crate::features::foveation::FoveationSettings;
use super::rules::{fovea_views, CenterSource, GazeFilter};
use crate::core::fovea;
use crate::plugin::settings::Settings;
use crate::plugin::xr::{settings, Session, XrFeature, EYE_GAZE_EXT};
use openxr_sys as xr;
use openxr_sys::Handle as _;
use std::ffi::c_char;
use std::sync::Mutex;

/// Views of `XR_VIEW_CONFIGURATION_TYPE_PRIMARY_STEREO`.
const STEREO_VIEWS: usize = 2;

/// Foveation's OpenXR half (stateless; per-session state is `FoveationSession`).
pub(crate) struct FoveationXr;

/// Foveation's per-session state.
#[derive(Debug, Default)]
pub(crate) struct FoveationSession {
    pub gaze: Gaze,
    /// Fovea centre per view from the gaze policy (empty: optical axis).
    pub centers: Mutex<Vec<fovea::Tangent>>,
    /// The action set and action made for an attach in progress.
    attaching: Mutex<Option<(xr::ActionSet, xr::Action)>>,
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

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
    let settings = settings(inst);
    inst.layer_extensions.iter().any(|e| e == EYE_GAZE_EXT) && settings.of::<FoveationSettings>().enabled && settings.of::<FoveationSettings>().eye_tracking
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

impl XrFeature for FoveationXr {
    fn id(&self) -> &'static str {
        "foveation"
    }
    /// Whenever the layer is on and eye tracking is not off: foveation can be switched on live.
    fn wanted_extensions(&self, s: &Settings) -> Vec<&'static str> {
        if s.enabled && s.of::<FoveationSettings>().eye_tracking {
            vec![EYE_GAZE_EXT]
        } else {
            Vec::new()
        }
    }
    /// Colour swapchains get TRANSFER_SRC and TRANSFER_DST: radial density masking reconstructs
    /// skipped quads in a copy of the image and copies the reconstructed tiles back (without
    /// TRANSFER_DST it falls back to its full-screen fill). Added whenever RDM may run (the layer
    /// is on and the method is not pinned to VRS), since foveation can be switched on while the
    /// app runs; an extra usage bit changes nothing the app can see.
    fn swapchain_usage(&self, s: &Settings, usage: xr::SwapchainUsageFlags) -> xr::SwapchainUsageFlags {
        let rdm_possible = s.enabled && s.of::<FoveationSettings>().method != super::Method::Vrs;
        if rdm_possible && usage.contains(xr::SwapchainUsageFlags::COLOR_ATTACHMENT) {
            xr::SwapchainUsageFlags::TRANSFER_SRC | xr::SwapchainUsageFlags::TRANSFER_DST
        } else {
            xr::SwapchainUsageFlags::EMPTY
        }
    }
    fn action_sets(&self, s: &Session) -> Vec<xr::ActionSet> {
        if !wanted(s) {
            return Vec::new();
        }
        match create_actions(s) {
            Ok((set, action)) => {
                *lock(&s.feature::<FoveationSession>().attaching) = Some((set, action));
                vec![set]
            }
            Err(e) => {
                tracing::warn!("eye tracking unavailable: {e}; foveation stays fixed");
                Vec::new()
            }
        }
    }
    fn action_sets_attached(&self, s: &Session, r: xr::Result) {
        let Some((set, action)) = lock(&s.feature::<FoveationSession>().attaching).take() else { return };
        let inst = &s.instance;
        if r != xr::Result::SUCCESS {
            // The app's own attach failed (or ours made it fail): never leave anything behind.
            if let Some(destroy) = inst.next.destroy_action_set {
                // SAFETY: destroying the set we created.
                unsafe { destroy(set) };
            }
            tracing::warn!(?r, "xrAttachSessionActionSets failed with the layer's gaze set");
            return;
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
            Some(f) => (unsafe { f(s.handle, &space_info, &mut space) }) == xr::Result::SUCCESS,
            None => false,
        };
        if made {
            tracing::info!("eye tracking: the layer's gaze action set is attached to session {:#x}", s.handle.into_raw());
            *lock(&s.feature::<FoveationSession>().gaze.actions) = Some(GazeActions { action_set: set, space });
        } else {
            tracing::warn!("eye tracking: could not create the gaze space; foveation stays fixed");
        }
    }
    fn active_action_sets(&self, s: &Session) -> Vec<xr::ActiveActionSet> {
        lock(&s.feature::<FoveationSession>().gaze.actions).as_ref().map(|g| xr::ActiveActionSet { action_set: g.action_set, subaction_path: xr::Path::NULL }).into_iter().collect()
    }
    fn views_located(&self, s: &Session, info: &xr::ViewLocateInfo, views: &[xr::View]) {
        sample(s, info, views);
    }
    /// Publishes this frame's foveation from the live settings: rings from the preset or angles,
    /// centres from the gaze policy (the optical axis without eye tracking). An empty list when
    /// it is off.
    fn frame_begun(&self, s: &Session) {
        let settings = settings(&s.instance);
        let shared = crate::bridge::shared();
        if !settings.of::<FoveationSettings>().enabled {
            shared.update_foveation(Vec::new());
            return;
        }
        let rings = settings.of::<FoveationSettings>().rings;
        let centers = lock(&s.feature::<FoveationSession>().centers).clone();
        let centers = if centers.len() == STEREO_VIEWS { centers } else { vec![[0.0, 0.0]; STEREO_VIEWS] };
        if shared.update_foveation(fovea_views(&centers, rings)) {
            tracing::debug!("foveation: centres {centers:?}, rings {rings:?}");
        }
    }
}

/// Samples the gaze at the time and in the space the app just located its views, and feeds each
/// view's gaze policy. Views without a usable sample run the policy with `None` (hold, then the
/// optical axis).
fn sample(s: &Session, info: &xr::ViewLocateInfo, views: &[xr::View]) {
    let settings = settings(&s.instance);
    let tracked = settings.of::<FoveationSettings>().enabled && settings.of::<FoveationSettings>().eye_tracking;
    let space = lock(&s.feature::<FoveationSession>().gaze.actions).as_ref().map(|g| g.space);
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
    let mut filters = lock(&s.feature::<FoveationSession>().gaze.filters);
    filters.resize_with(views.len(), GazeFilter::default);
    let mut source = CenterSource::Fixed;
    // The lens's axis in each view the app was given: the runtime view's, which parallel views
    // turn away from the app's (docs/views.md); the app's own axis otherwise.
    let turns = crate::bridge::shared().views().runtime_turns.clone();
    let lens_axis = |i: usize| turns.get(i).copied().flatten().and_then(|t| fovea::gaze_in_view([0.0, 0.0, 0.0, 1.0], fovea::forward(t))).unwrap_or([0.0, 0.0]);
    let centers: Vec<fovea::Tangent> = views
        .iter()
        .zip(filters.iter_mut())
        .enumerate()
        .map(|(i, (v, f))| {
            let q = v.pose.orientation;
            let sample = direction.and_then(|d| fovea::gaze_in_view([q.x, q.y, q.z, q.w], d));
            let (c, src) = f.update(sample, info.display_time.as_nanos());
            source = src;
            if src == CenterSource::Fixed { lens_axis(i) } else { c }
        })
        .collect();
    drop(filters);
    let mut last = lock(&s.feature::<FoveationSession>().gaze.source);
    if *last != Some(source) {
        tracing::info!("foveation centre now from {source:?}");
        *last = Some(source);
    }
    *lock(&s.feature::<FoveationSession>().centers) = centers;
}
