//! Interaction profiles through the real loader: every profile of the OpenXR spec is accepted by
//! `xrSuggestInteractionProfileBindings` with each of its valid binding paths, paths a profile
//! does not have stay `XR_ERROR_PATH_UNSUPPORTED`, profiles of 1.1 and of extensions only exist
//! where the instance has them, and bindings the mock cannot drive stay inactive.

mod common;

use std::ffi::CString;

use common::*;
use mock_runtime::profiles::{Avail, Kind, PROFILES};
use openxr_sys as xr;
use xr::pfn;
use xr::Handle as _;

fn path(x: &Xr, s: &str) -> xr::Path {
    let f: pfn::StringToPath = x.f("xrStringToPath");
    let c = CString::new(s).unwrap();
    let mut p = xr::Path::NULL;
    // SAFETY: valid arguments.
    assert_eq!(unsafe { f(x.instance, c.as_ptr(), &mut p) }, xr::Result::SUCCESS, "{s}");
    p
}

fn fixed<const N: usize>(s: &str) -> [std::ffi::c_char; N] {
    let mut out = [0; N];
    for (d, c) in out.iter_mut().zip(s.bytes()) {
        *d = c as _;
    }
    out
}

fn action_set(x: &Xr, name: &str) -> xr::ActionSet {
    let f: pfn::CreateActionSet = x.f("xrCreateActionSet");
    let ci = xr::ActionSetCreateInfo {
        ty: xr::ActionSetCreateInfo::TYPE,
        next: std::ptr::null(),
        action_set_name: fixed(name),
        localized_action_set_name: fixed(&name.to_uppercase()),
        priority: 0,
    };
    let mut set = xr::ActionSet::NULL;
    // SAFETY: valid arguments.
    assert_eq!(unsafe { f(x.instance, &ci, &mut set) }, xr::Result::SUCCESS);
    set
}

fn action(x: &Xr, set: xr::ActionSet, name: &str, ty: xr::ActionType, subs: &[xr::Path]) -> xr::Action {
    let f: pfn::CreateAction = x.f("xrCreateAction");
    let ci = xr::ActionCreateInfo {
        ty: xr::ActionCreateInfo::TYPE,
        next: std::ptr::null(),
        action_name: fixed(name),
        action_type: ty,
        count_subaction_paths: subs.len() as u32,
        subaction_paths: subs.as_ptr(),
        localized_action_name: fixed(&name.to_uppercase()),
    };
    let mut a = xr::Action::NULL;
    // SAFETY: valid arguments.
    assert_eq!(unsafe { f(set, &ci, &mut a) }, xr::Result::SUCCESS);
    a
}

/// One action of each type.
struct Actions([xr::Action; 5]);

impl Actions {
    fn new(x: &Xr, set: xr::ActionSet) -> Actions {
        use xr::ActionType as T;
        Actions([
            action(x, set, "boolean", T::BOOLEAN_INPUT, &[]),
            action(x, set, "float", T::FLOAT_INPUT, &[]),
            action(x, set, "vector2f", T::VECTOR2F_INPUT, &[]),
            action(x, set, "pose", T::POSE_INPUT, &[]),
            action(x, set, "haptic", T::VIBRATION_OUTPUT, &[]),
        ])
    }
    fn of(&self, k: Kind) -> xr::Action {
        self.0[match k {
            Kind::Boolean => 0,
            Kind::Float => 1,
            Kind::Vector2f => 2,
            Kind::Pose => 3,
            Kind::Vibration => 4,
        }]
    }
}

fn suggest(x: &Xr, profile: &str, bindings: &[(xr::Action, &str)]) -> xr::Result {
    let f: pfn::SuggestInteractionProfileBindings = x.f("xrSuggestInteractionProfileBindings");
    let b: Vec<xr::ActionSuggestedBinding> = bindings.iter().map(|(a, p)| xr::ActionSuggestedBinding { action: *a, binding: path(x, p) }).collect();
    let info = xr::InteractionProfileSuggestedBinding {
        ty: xr::InteractionProfileSuggestedBinding::TYPE,
        next: std::ptr::null(),
        interaction_profile: path(x, profile),
        count_suggested_bindings: b.len() as u32,
        suggested_bindings: b.as_ptr(),
    };
    // SAFETY: valid arguments.
    unsafe { f(x.instance, &info) }
}

/// Every binding path of `profile` whose component exists under `has` (the instance's version
/// and extensions), each bound to the action of its type.
fn all_bindings(acts: &Actions, profile: &str, has: impl Fn(&Avail) -> bool) -> Vec<(xr::Action, String)> {
    let p = PROFILES.iter().find(|p| p.path == profile).unwrap();
    let mut out = Vec::new();
    for up in p.user_paths {
        for c in p.components {
            if c.user_path.is_some_and(|u| u != *up) || !(c.extra.is_empty() || c.extra.iter().any(&has)) {
                continue;
            }
            out.push((acts.of(c.kind), format!("{up}{}", c.subpath)));
        }
    }
    out
}

fn suggest_all(x: &Xr, acts: &Actions, profile: &str, has: impl Fn(&Avail) -> bool) -> xr::Result {
    let b = all_bindings(acts, profile, has);
    assert!(!b.is_empty(), "{profile}");
    let b: Vec<(xr::Action, &str)> = b.iter().map(|(a, p)| (*a, p.as_str())).collect();
    suggest(x, profile, &b)
}

#[test]
fn every_core_profile_accepts_its_paths_and_only_those() {
    let _g = serial();
    let x = create_instance(&["XR_KHR_vulkan_enable2"]);
    let acts = Actions::new(&x, action_set(&x, "all"));
    let core_1_0 = |a: &Avail| *a == Avail::Core(1, 0);
    let mut n = 0;
    for p in PROFILES {
        let r = suggest_all(&x, &acts, p.path, core_1_0);
        if p.avail.iter().any(core_1_0) {
            assert_eq!(r, xr::Result::SUCCESS, "{}", p.path);
            n += 1;
        } else {
            // 1.1 and extension profiles do not exist on a 1.0 instance without their extension.
            assert_eq!(r, xr::Result::ERROR_PATH_UNSUPPORTED, "{}", p.path);
        }
    }
    assert_eq!(n, 9, "the nine interaction profiles of OpenXR 1.0");

    let b = acts.of(Kind::Boolean);
    let f = acts.of(Kind::Float);
    let unsupported = [
        // Paths the profile does not have.
        ("/interaction_profiles/valve/index_controller", (b, "/user/hand/left/input/x/click")),
        ("/interaction_profiles/valve/index_controller", (b, "/user/hand/left/input/menu/click")),
        ("/interaction_profiles/khr/simple_controller", (f, "/user/hand/left/input/trigger/value")),
        ("/interaction_profiles/htc/vive_controller", (f, "/user/hand/left/input/squeeze/value")),
        // x / y exist only on the left Touch controller, a / b only on the right.
        ("/interaction_profiles/oculus/touch_controller", (b, "/user/hand/right/input/x/click")),
        ("/interaction_profiles/oculus/touch_controller", (b, "/user/hand/left/input/a/click")),
        // Top-level paths the profile does not have.
        ("/interaction_profiles/microsoft/xbox_controller", (b, "/user/hand/left/input/a/click")),
        ("/interaction_profiles/htc/vive_pro", (b, "/user/hand/left/input/volume_up/click")),
        ("/interaction_profiles/khr/simple_controller", (b, "/user/gamepad/input/menu/click")),
        // 1.1's grip_surface on a 1.0 instance.
        ("/interaction_profiles/valve/index_controller", (acts.of(Kind::Pose), "/user/hand/left/input/grip_surface/pose")),
        // Not a profile.
        ("/interaction_profiles/acme/controller", (b, "/user/hand/left/input/select/click")),
        ("/interaction_profiles/khr/simple_controller/extra", (b, "/user/hand/left/input/select/click")),
    ];
    for (profile, binding) in unsupported {
        assert_eq!(suggest(&x, profile, &[binding]), xr::Result::ERROR_PATH_UNSUPPORTED, "{profile} {}", binding.1);
    }
    // The short forms: an identifier without its component.
    for (profile, binding) in [
        ("/interaction_profiles/valve/index_controller", (f, "/user/hand/right/input/trigger")),
        ("/interaction_profiles/oculus/touch_controller", (b, "/user/hand/left/input/x")),
        ("/interaction_profiles/microsoft/xbox_controller", (acts.of(Kind::Vector2f), "/user/gamepad/input/thumbstick_left")),
        ("/interaction_profiles/htc/vive_pro", (b, "/user/head/input/mute_mic")),
    ] {
        assert_eq!(suggest(&x, profile, &[binding]), xr::Result::SUCCESS, "{profile} {}", binding.1);
    }
}

#[test]
fn extension_profiles_need_their_extension() {
    let _g = serial();
    let x = create_instance(&["XR_KHR_vulkan_enable2", "XR_EXT_hp_mixed_reality_controller", "XR_FB_touch_controller_pro"]);
    let acts = Actions::new(&x, action_set(&x, "ext"));
    let has = |a: &Avail| matches!(a, Avail::Core(1, 0) | Avail::Ext("XR_EXT_hp_mixed_reality_controller" | "XR_FB_touch_controller_pro"));
    for profile in ["/interaction_profiles/hp/mixed_reality_controller", "/interaction_profiles/facebook/touch_controller_pro"] {
        assert_eq!(suggest_all(&x, &acts, profile, has), xr::Result::SUCCESS, "{profile}");
    }
    // Promoted to 1.1 under a new name: not on a 1.0 instance, whatever it enabled.
    assert_eq!(suggest_all(&x, &acts, "/interaction_profiles/meta/touch_pro_controller", has), xr::Result::ERROR_PATH_UNSUPPORTED);
    assert_eq!(suggest_all(&x, &acts, "/interaction_profiles/samsung/odyssey_controller", has), xr::Result::ERROR_PATH_UNSUPPORTED);
}

#[test]
fn openxr_1_1_profiles_on_a_1_1_instance() {
    let _g = serial();
    let x = match try_create_instance(&["XR_KHR_vulkan_enable2"], xr::Version::new(1, 1, 0)) {
        Ok(x) => x,
        Err(xr::Result::ERROR_API_VERSION_UNSUPPORTED) => {
            // The loader itself is older than 1.1 (bookworm's 1.0.20): nothing to test here.
            eprintln!("skipped: this OpenXR loader cannot create a 1.1 instance");
            return;
        }
        Err(e) => panic!("xrCreateInstance(1.1): {e:?}"),
    };
    let acts = Actions::new(&x, action_set(&x, "v11"));
    let v11 = |a: &Avail| matches!(a, Avail::Core(..));
    let mut n = 0;
    for p in PROFILES.iter().filter(|p| p.avail.iter().any(v11)) {
        assert_eq!(suggest_all(&x, &acts, p.path, v11), xr::Result::SUCCESS, "{}", p.path);
        n += 1;
    }
    assert_eq!(n, 9 + 13);
    let pose = acts.of(Kind::Pose);
    assert_eq!(suggest(&x, "/interaction_profiles/valve/index_controller", &[(pose, "/user/hand/left/input/grip_surface/pose")]), xr::Result::SUCCESS);
}

/// As hello_xr does: the same actions suggested for several profiles. The mock drives the simple
/// controller's bindings; the others are accepted and stay inactive.
#[test]
fn only_simple_controller_bindings_are_driven() {
    let _g = serial();
    std::env::set_var("MOCK_XR_MENU_CLICK_AT", "0");
    let fx = fixture(&["XR_KHR_vulkan_enable2"]);
    std::env::remove_var("MOCK_XR_MENU_CLICK_AT");
    let (x, s) = (fx.xr(), fx.session);
    let set = action_set(x, "hello");
    let hands = [path(x, "/user/hand/left"), path(x, "/user/hand/right")];
    let quit = action(x, set, "quit", xr::ActionType::BOOLEAN_INPUT, &hands);
    let grab = action(x, set, "grab", xr::ActionType::FLOAT_INPUT, &hands);
    let hand_pose = action(x, set, "hand_pose", xr::ActionType::POSE_INPUT, &hands);
    let touch_only = action(x, set, "touch_only", xr::ActionType::BOOLEAN_INPUT, &[]);
    for (profile, b) in [
        (
            "/interaction_profiles/khr/simple_controller",
            vec![(quit, "/user/hand/left/input/menu/click"), (grab, "/user/hand/left/input/select/click"), (hand_pose, "/user/hand/left/input/grip/pose")],
        ),
        (
            "/interaction_profiles/oculus/touch_controller",
            vec![(quit, "/user/hand/left/input/menu/click"), (grab, "/user/hand/left/input/squeeze/value"), (touch_only, "/user/hand/right/input/a/click")],
        ),
        ("/interaction_profiles/valve/index_controller", vec![(quit, "/user/hand/left/input/b/click"), (grab, "/user/hand/right/input/squeeze/force")]),
        ("/interaction_profiles/microsoft/xbox_controller", vec![(touch_only, "/user/gamepad/input/a/click")]),
    ] {
        assert_eq!(suggest(x, profile, &b), xr::Result::SUCCESS, "{profile}");
    }
    let attach: pfn::AttachSessionActionSets = x.f("xrAttachSessionActionSets");
    let sets = [set];
    let ai = xr::SessionActionSetsAttachInfo { ty: xr::SessionActionSetsAttachInfo::TYPE, next: std::ptr::null(), count_action_sets: 1, action_sets: sets.as_ptr() };
    // SAFETY: valid arguments.
    assert_eq!(unsafe { attach(s, &ai) }, xr::Result::SUCCESS);
    assert_eq!(begin_session(x, s), xr::Result::SUCCESS);
    let sync: pfn::SyncActions = x.f("xrSyncActions");
    let active = [xr::ActiveActionSet { action_set: set, subaction_path: xr::Path::NULL }];
    let si = xr::ActionsSyncInfo { ty: xr::ActionsSyncInfo::TYPE, next: std::ptr::null(), count_active_action_sets: 1, active_action_sets: active.as_ptr() };
    // SAFETY: valid arguments.
    assert_eq!(unsafe { sync(s, &si) }, xr::Result::SUCCESS);

    let get_bool: pfn::GetActionStateBoolean = x.f("xrGetActionStateBoolean");
    let state = |a| {
        let gi = xr::ActionStateGetInfo { ty: xr::ActionStateGetInfo::TYPE, next: std::ptr::null(), action: a, subaction_path: xr::Path::NULL };
        // SAFETY: plain data.
        let mut st: xr::ActionStateBoolean = unsafe { std::mem::zeroed() };
        st.ty = xr::ActionStateBoolean::TYPE;
        // SAFETY: valid arguments.
        assert_eq!(unsafe { get_bool(s, &gi, &mut st) }, xr::Result::SUCCESS);
        (st.is_active == xr::TRUE, st.current_state == xr::TRUE)
    };
    assert_eq!(state(quit), (true, true), "quit: the simple controller's menu click (MOCK_XR_MENU_CLICK_AT=0)");
    assert_eq!(state(touch_only), (false, false), "bound only on profiles the mock does not drive");

    // Bound sources: the simple controller's only.
    let bound: pfn::EnumerateBoundSourcesForAction = x.f("xrEnumerateBoundSourcesForAction");
    let to_string: pfn::PathToString = x.f("xrPathToString");
    let sources = |a| {
        let info = xr::BoundSourcesForActionEnumerateInfo { ty: xr::BoundSourcesForActionEnumerateInfo::TYPE, next: std::ptr::null(), action: a };
        let mut n = 0;
        // SAFETY: valid arguments (two-call idiom).
        unsafe {
            assert_eq!(bound(s, &info, 0, &mut n, std::ptr::null_mut()), xr::Result::SUCCESS);
            let mut v = vec![xr::Path::NULL; n as usize];
            assert_eq!(bound(s, &info, n, &mut n, v.as_mut_ptr()), xr::Result::SUCCESS);
            v.into_iter().map(|p| two_call_string(|c, o, b| to_string(x.instance, p, c, o, b))).collect::<Vec<_>>()
        }
    };
    assert_eq!(sources(quit), ["/user/hand/left/input/menu/click"]);
    assert_eq!(sources(grab), ["/user/hand/left/input/select/click"]);
    assert!(sources(touch_only).is_empty());

    let current: pfn::GetCurrentInteractionProfile = x.f("xrGetCurrentInteractionProfile");
    let profile_of = |top: &str| {
        // SAFETY: plain data.
        let mut st: xr::InteractionProfileState = unsafe { std::mem::zeroed() };
        st.ty = xr::InteractionProfileState::TYPE;
        // SAFETY: valid arguments.
        assert_eq!(unsafe { current(s, path(x, top), &mut st) }, xr::Result::SUCCESS);
        st.interaction_profile
    };
    assert_eq!(profile_of("/user/hand/left"), path(x, "/interaction_profiles/khr/simple_controller"));
    assert_eq!(profile_of("/user/gamepad"), xr::Path::NULL);
}
