//! Instance, system, extension, handle, fault-injection, swapchain-protocol, visibility-mask and
//! action tests of the mock runtime, through the real loader.

mod common;

use std::ffi::CString;

use ash::vk;
use common::*;
use openxr_sys as xr;
use xr::pfn;
use xr::Handle as _;

#[test]
fn extension_functions_need_their_extension() {
    let _g = serial();
    let x = create_instance(&["XR_KHR_vulkan_enable2"]);
    assert!(x.try_f::<pfn::CreateVulkanInstanceKHR>("xrCreateVulkanInstanceKHR").is_ok());
    assert_eq!(x.try_f::<pfn::GetVisibilityMaskKHR>("xrGetVisibilityMaskKHR").err(), Some(xr::Result::ERROR_FUNCTION_UNSUPPORTED));
    assert_eq!(x.try_f::<pfn::GetVulkanGraphicsDeviceKHR>("xrGetVulkanGraphicsDeviceKHR").err(), Some(xr::Result::ERROR_FUNCTION_UNSUPPORTED));
    assert_eq!(x.try_f::<pfn::VoidFunction>("xrNoSuchFunction").err(), Some(xr::Result::ERROR_FUNCTION_UNSUPPORTED));
}

#[test]
fn unknown_or_disabled_extensions_are_refused() {
    let _g = serial();
    assert_eq!(try_create_instance(&["XR_KHR_no_such_thing"], xr::Version::new(1, 0, 0)).err(), Some(xr::Result::ERROR_EXTENSION_NOT_PRESENT));
    std::env::set_var("MOCK_XR_DISABLE_EXTENSIONS", "XR_KHR_visibility_mask");
    assert_eq!(
        try_create_instance(&["XR_KHR_vulkan_enable2", "XR_KHR_visibility_mask"], xr::Version::new(1, 0, 0)).err(),
        Some(xr::Result::ERROR_EXTENSION_NOT_PRESENT)
    );
    std::env::remove_var("MOCK_XR_DISABLE_EXTENSIONS");
    // API 1.1 is accepted too.
    drop(try_create_instance(&["XR_KHR_vulkan_enable2"], xr::Version::new(1, 1, 0)).map_err(|e| assert_eq!(e, xr::Result::ERROR_API_VERSION_UNSUPPORTED)));
}

#[test]
fn system_and_view_configuration() {
    let _g = serial();
    std::env::set_var("MOCK_XR_HMD", "quest3");
    std::env::set_var("MOCK_XR_EYE_TRACKER", "0");
    let x = create_instance(&["XR_KHR_vulkan_enable2", "XR_EXT_eye_gaze_interaction"]);
    let get_system: pfn::GetSystem = x.f("xrGetSystem");
    let gi = xr::SystemGetInfo { ty: xr::SystemGetInfo::TYPE, next: std::ptr::null(), form_factor: xr::FormFactor::HANDHELD_DISPLAY };
    let mut id = xr::SystemId::from_raw(0);
    // SAFETY: valid arguments.
    assert_eq!(unsafe { get_system(x.instance, &gi, &mut id) }, xr::Result::ERROR_FORM_FACTOR_UNSUPPORTED);
    let mut eye = xr::SystemEyeGazeInteractionPropertiesEXT { ty: xr::SystemEyeGazeInteractionPropertiesEXT::TYPE, next: std::ptr::null_mut(), supports_eye_gaze_interaction: xr::TRUE };
    // SAFETY: plain data.
    let mut props: xr::SystemProperties = unsafe { std::mem::zeroed() };
    props.ty = xr::SystemProperties::TYPE;
    props.next = &mut eye as *mut _ as *mut _;
    let f: pfn::GetSystemProperties = x.f("xrGetSystemProperties");
    // SAFETY: valid arguments.
    assert_eq!(unsafe { f(x.instance, x.system, &mut props) }, xr::Result::SUCCESS);
    assert_eq!(eye.supports_eye_gaze_interaction, xr::FALSE);
    // SAFETY: valid arguments.
    assert_eq!(unsafe { f(x.instance, xr::SystemId::from_raw(12345), &mut props) }, xr::Result::ERROR_SYSTEM_INVALID);
    let f: pfn::EnumerateViewConfigurationViews = x.f("xrEnumerateViewConfigurationViews");
    // SAFETY: plain data.
    let mut views: [xr::ViewConfigurationView; 2] = unsafe { std::mem::zeroed() };
    views.iter_mut().for_each(|v| v.ty = xr::ViewConfigurationView::TYPE);
    let mut n = 0;
    // SAFETY: valid arguments.
    unsafe {
        assert_eq!(f(x.instance, x.system, xr::ViewConfigurationType::PRIMARY_MONO, 0, &mut n, std::ptr::null_mut()), xr::Result::ERROR_VIEW_CONFIGURATION_TYPE_UNSUPPORTED);
        assert_eq!(f(x.instance, x.system, xr::ViewConfigurationType::PRIMARY_STEREO, 1, &mut n, views.as_mut_ptr()), xr::Result::ERROR_SIZE_INSUFFICIENT);
        assert_eq!(n, 2);
        views[1].ty = xr::StructureType::VIEW;
        assert_eq!(f(x.instance, x.system, xr::ViewConfigurationType::PRIMARY_STEREO, 2, &mut n, views.as_mut_ptr()), xr::Result::ERROR_VALIDATION_FAILURE);
        views[1].ty = xr::ViewConfigurationView::TYPE;
        assert_eq!(f(x.instance, x.system, xr::ViewConfigurationType::PRIMARY_STEREO, 2, &mut n, views.as_mut_ptr()), xr::Result::SUCCESS);
    }
    assert_eq!((views[0].recommended_image_rect_width, views[0].recommended_image_rect_height), (1680, 1760));
    // strings and paths
    let to_s: pfn::ResultToString = x.f("xrResultToString");
    let mut buf = [0 as std::ffi::c_char; xr::MAX_RESULT_STRING_SIZE];
    // SAFETY: buffer of the required size.
    unsafe { to_s(x.instance, xr::Result::ERROR_HANDLE_INVALID, buf.as_mut_ptr()) };
    // SAFETY: NUL-terminated.
    assert_eq!(unsafe { std::ffi::CStr::from_ptr(buf.as_ptr()) }.to_str().unwrap(), "XR_ERROR_HANDLE_INVALID");
    let sp: pfn::StringToPath = x.f("xrStringToPath");
    let ps: pfn::PathToString = x.f("xrPathToString");
    let mut p = xr::Path::NULL;
    let good = CString::new("/user/hand/left").unwrap();
    let bad = CString::new("/user//hand").unwrap();
    // SAFETY: valid arguments.
    unsafe {
        assert_eq!(sp(x.instance, bad.as_ptr(), &mut p), xr::Result::ERROR_PATH_FORMAT_INVALID);
        assert_eq!(sp(x.instance, good.as_ptr(), &mut p), xr::Result::SUCCESS);
        assert_eq!(ps(x.instance, xr::Path::from_raw(999_999), 0, &mut n, std::ptr::null_mut()), xr::Result::ERROR_PATH_INVALID);
    }
    // SAFETY: valid arguments.
    assert_eq!(two_call_string(|c, n, b| unsafe { ps(x.instance, p, c, n, b) }), "/user/hand/left");
}

#[test]
fn handles_are_checked() {
    let _g = serial();
    let fx = fixture(&["XR_KHR_vulkan_enable2"]);
    let x = fx.xr();
    let begin: pfn::BeginSession = x.f("xrBeginSession");
    let bi = xr::SessionBeginInfo { ty: xr::SessionBeginInfo::TYPE, next: std::ptr::null(), primary_view_configuration_type: xr::ViewConfigurationType::PRIMARY_STEREO };
    let destroy_space: pfn::DestroySpace = x.f("xrDestroySpace");
    let destroy_sc: pfn::DestroySwapchain = x.f("xrDestroySwapchain");
    let space = reference_space(x, fx.session, xr::ReferenceSpaceType::LOCAL);
    // SAFETY: bogus handles on purpose; the runtime must reject them.
    unsafe {
        assert_eq!(begin(xr::Session::NULL, &bi), xr::Result::ERROR_HANDLE_INVALID);
        assert_eq!(begin(xr::Session::from_raw(0x1234_5678), &bi), xr::Result::ERROR_HANDLE_INVALID);
        // a space handle is not a session handle
        assert_eq!(begin(xr::Session::from_raw(space.into_raw()), &bi), xr::Result::ERROR_HANDLE_INVALID);
        assert_eq!(destroy_sc(xr::Swapchain::from_raw(space.into_raw())), xr::Result::ERROR_HANDLE_INVALID);
        assert_eq!(destroy_space(space), xr::Result::SUCCESS);
        assert_eq!(destroy_space(space), xr::Result::ERROR_HANDLE_INVALID);
    }
    // children die with their session
    let space = reference_space(x, fx.session, xr::ReferenceSpaceType::STAGE);
    let destroy_session: pfn::DestroySession = x.f("xrDestroySession");
    // SAFETY: valid session, then stale handles.
    unsafe {
        assert_eq!(destroy_session(fx.session), xr::Result::SUCCESS);
        assert_eq!(destroy_space(space), xr::Result::ERROR_HANDLE_INVALID);
        assert_eq!(begin(fx.session, &bi), xr::Result::ERROR_HANDLE_INVALID);
    }
}

#[test]
fn session_needs_graphics_requirements_and_a_binding() {
    let _g = serial();
    let x = create_instance(&["XR_KHR_vulkan_enable2"]);
    let mut gfx = create_gfx(&x, true);
    assert_eq!(try_create_session(&x, &gfx).err(), Some(xr::Result::ERROR_GRAPHICS_REQUIREMENTS_CALL_MISSING));
    x.graphics_requirements(true);
    // no binding
    let f: pfn::CreateSession = x.f("xrCreateSession");
    let ci = xr::SessionCreateInfo { ty: xr::SessionCreateInfo::TYPE, next: std::ptr::null(), create_flags: xr::SessionCreateFlags::EMPTY, system_id: x.system };
    let mut s = xr::Session::NULL;
    // SAFETY: valid arguments.
    assert_eq!(unsafe { f(x.instance, &ci, &mut s) }, xr::Result::ERROR_GRAPHICS_DEVICE_INVALID);
    // bad queue family
    let mut b = gfx.binding();
    b.queue_family_index = 99;
    let ci2 = xr::SessionCreateInfo { next: &b as *const _ as *const _, ..ci };
    // SAFETY: valid arguments.
    assert_eq!(unsafe { f(x.instance, &ci2, &mut s) }, xr::Result::ERROR_VALIDATION_FAILURE);
    let mut b = gfx.binding();
    b.device = std::ptr::null();
    let ci3 = xr::SessionCreateInfo { next: &b as *const _ as *const _, ..ci };
    // SAFETY: valid arguments.
    assert_eq!(unsafe { f(x.instance, &ci3, &mut s) }, xr::Result::ERROR_GRAPHICS_DEVICE_INVALID);
    let s = try_create_session(&x, &gfx).unwrap();
    assert_ne!(s, xr::Session::NULL);
    drop(x);
    gfx.destroy();
}

#[test]
fn fault_injection() {
    let _g = serial();
    std::env::set_var("MOCK_XR_FAIL", "xrWaitFrame@1,xrCreateReferenceSpace");
    let fx = fixture(&["XR_KHR_vulkan_enable2"]);
    let (x, s) = (fx.xr(), fx.session);
    let f: pfn::CreateReferenceSpace = x.f("xrCreateReferenceSpace");
    let ci = xr::ReferenceSpaceCreateInfo { ty: xr::ReferenceSpaceCreateInfo::TYPE, next: std::ptr::null(), reference_space_type: xr::ReferenceSpaceType::STAGE, pose_in_reference_space: identity_pose() };
    let mut sp = xr::Space::NULL;
    // SAFETY: valid arguments; then an invalid handle, which is checked before the injected failure.
    unsafe {
        assert_eq!(f(s, &ci, &mut sp), xr::Result::ERROR_RUNTIME_FAILURE);
        assert_eq!(f(xr::Session::NULL, &ci, &mut sp), xr::Result::ERROR_HANDLE_INVALID);
    }
    assert_eq!(begin_session(x, s), xr::Result::SUCCESS);
    assert_eq!(wait_frame(x, s).0, xr::Result::SUCCESS);
    // Begun, so the next wait does not block on it (tests/frame_loop.rs).
    assert_eq!(begin_frame(x, s), xr::Result::SUCCESS);
    assert_eq!(wait_frame(x, s).0, xr::Result::ERROR_RUNTIME_FAILURE);
    assert_eq!(wait_frame(x, s).0, xr::Result::SUCCESS);
}

#[test]
fn swapchain_protocol() {
    let _g = serial();
    let fx = fixture(&["XR_KHR_vulkan_enable2"]);
    let (x, s) = (fx.xr(), fx.session);
    let enum_formats: pfn::EnumerateSwapchainFormats = x.f("xrEnumerateSwapchainFormats");
    let mut n = 0;
    // SAFETY: valid arguments.
    assert_eq!(unsafe { enum_formats(s, 0, &mut n, std::ptr::null_mut()) }, xr::Result::SUCCESS);
    let mut formats = vec![0i64; n as usize];
    // SAFETY: valid arguments.
    assert_eq!(unsafe { enum_formats(s, n, &mut n, formats.as_mut_ptr()) }, xr::Result::SUCCESS);
    assert_eq!(formats[0], vk::Format::R8G8B8A8_SRGB.as_raw() as i64);
    assert!(formats.contains(&(vk::Format::D32_SFLOAT.as_raw() as i64)));
    assert_eq!(try_create_swapchain(x, s, &swapchain_info(vk::Format::R5G6B5_UNORM_PACK16, 8, 8, 1)).err(), Some(xr::Result::ERROR_SWAPCHAIN_FORMAT_UNSUPPORTED));
    let mut mips = swapchain_info(vk::Format::R8G8B8A8_SRGB, 8, 8, 1);
    // Beyond 8×8's full chain of 4 levels (tests/swapchain_geometry.rs has the accepted ones).
    mips.mip_count = 5;
    assert_eq!(try_create_swapchain(x, s, &mips).err(), Some(xr::Result::ERROR_VALIDATION_FAILURE));
    let sc = try_create_swapchain(x, s, &swapchain_info(vk::Format::R8G8B8A8_SRGB, 8, 8, 1)).unwrap();
    let acq: pfn::AcquireSwapchainImage = x.f("xrAcquireSwapchainImage");
    let wait: pfn::WaitSwapchainImage = x.f("xrWaitSwapchainImage");
    let wi = xr::SwapchainImageWaitInfo { ty: xr::SwapchainImageWaitInfo::TYPE, next: std::ptr::null(), timeout: xr::Duration::INFINITE };
    let mut i = 0;
    // SAFETY: valid arguments throughout.
    unsafe {
        assert_eq!(release(x, sc), xr::Result::ERROR_CALL_ORDER_INVALID); // nothing acquired
        assert_eq!(wait(sc, &wi), xr::Result::ERROR_CALL_ORDER_INVALID); // nothing acquired
        assert_eq!(acq(sc, std::ptr::null(), &mut i), xr::Result::SUCCESS);
        assert_eq!(release(x, sc), xr::Result::ERROR_CALL_ORDER_INVALID); // not waited
        assert_eq!(wait(sc, &wi), xr::Result::SUCCESS);
        assert_eq!(wait(sc, &wi), xr::Result::ERROR_CALL_ORDER_INVALID); // already waited
        assert_eq!(acq(sc, std::ptr::null(), &mut i), xr::Result::SUCCESS);
        assert_eq!(acq(sc, std::ptr::null(), &mut i), xr::Result::SUCCESS);
        assert_eq!(acq(sc, std::ptr::null(), &mut i), xr::Result::ERROR_CALL_ORDER_INVALID); // all 3 out
        assert_eq!(release(x, sc), xr::Result::SUCCESS);
        assert_eq!(acq(sc, std::ptr::null(), &mut i), xr::Result::SUCCESS);
        assert_eq!(i, 0, "round robin");
        let bad_wi = xr::SwapchainImageWaitInfo { ty: xr::StructureType::FRAME_WAIT_INFO, ..wi };
        assert_eq!(wait(sc, &bad_wi), xr::Result::ERROR_VALIDATION_FAILURE);
    }
    // image enumeration checks the element type
    let f: pfn::EnumerateSwapchainImages = x.f("xrEnumerateSwapchainImages");
    let mut imgs = vec![xr::SwapchainImageVulkanKHR { ty: xr::StructureType::SWAPCHAIN_IMAGE_OPENGL_KHR, next: std::ptr::null_mut(), image: 0 }; 3];
    // SAFETY: valid arguments.
    unsafe {
        assert_eq!(f(sc, 2, &mut n, imgs.as_mut_ptr() as *mut _), xr::Result::ERROR_SIZE_INSUFFICIENT);
        assert_eq!(f(sc, 3, &mut n, imgs.as_mut_ptr() as *mut _), xr::Result::ERROR_VALIDATION_FAILURE);
    }
    assert_eq!(swapchain_images(x, sc).len(), 3);
}

fn mask(x: &Xr, s: xr::Session, view: u32, ty: xr::VisibilityMaskTypeKHR) -> (Vec<[f32; 2]>, Vec<u32>) {
    let f: pfn::GetVisibilityMaskKHR = x.f("xrGetVisibilityMaskKHR");
    let mut m = xr::VisibilityMaskKHR { ty: xr::VisibilityMaskKHR::TYPE, next: std::ptr::null_mut(), vertex_capacity_input: 0, vertex_count_output: 0, vertices: std::ptr::null_mut(), index_capacity_input: 0, index_count_output: 0, indices: std::ptr::null_mut() };
    let st = xr::ViewConfigurationType::PRIMARY_STEREO;
    // SAFETY: valid arguments.
    assert_eq!(unsafe { f(s, st, view, ty, &mut m) }, xr::Result::SUCCESS);
    let (nv, ni) = (m.vertex_count_output as usize, m.index_count_output as usize);
    assert!(nv >= 3 && ni >= 3);
    let mut v = vec![xr::Vector2f { x: 0.0, y: 0.0 }; nv];
    let mut i = vec![0u32; ni];
    m.vertices = v.as_mut_ptr();
    m.indices = i.as_mut_ptr();
    m.vertex_capacity_input = nv as u32 - 1;
    m.index_capacity_input = ni as u32;
    // SAFETY: arrays of the stated capacities.
    assert_eq!(unsafe { f(s, st, view, ty, &mut m) }, xr::Result::ERROR_SIZE_INSUFFICIENT);
    m.vertex_capacity_input = nv as u32;
    // SAFETY: as above.
    assert_eq!(unsafe { f(s, st, view, ty, &mut m) }, xr::Result::SUCCESS);
    // SAFETY: bad view index.
    assert_eq!(unsafe { f(s, st, 2, ty, &mut m) }, xr::Result::ERROR_VALIDATION_FAILURE);
    (v.iter().map(|p| [p.x, p.y]).collect(), i)
}

fn area(v: &[[f32; 2]], idx: &[u32]) -> f32 {
    idx.chunks(3)
        .map(|t| {
            let (a, b, c) = (v[t[0] as usize], v[t[1] as usize], v[t[2] as usize]);
            let a2 = ((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])) / 2.0;
            assert!(a2 > 0.0, "triangles must be counter-clockwise");
            a2
        })
        .sum()
}

#[test]
fn visibility_mask_geometry_and_change_event() {
    let _g = serial();
    std::env::set_var("MOCK_XR_HMD", "vive");
    std::env::set_var("MOCK_XR_VISIBILITY_MASK_CHANGE_AT", "1");
    let fx = fixture(&["XR_KHR_vulkan_enable2", "XR_KHR_visibility_mask"]);
    let (x, s) = (fx.xr(), fx.session);
    let stage = reference_space(x, s, xr::ReferenceSpaceType::STAGE);
    // the FOV rectangle in tangent space, from xrLocateViews
    let locate: pfn::LocateViews = x.f("xrLocateViews");
    let info = xr::ViewLocateInfo { ty: xr::ViewLocateInfo::TYPE, next: std::ptr::null(), view_configuration_type: xr::ViewConfigurationType::PRIMARY_STEREO, display_time: xr::Time::from_nanos(1), space: stage };
    let mut vs = xr::ViewState { ty: xr::ViewState::TYPE, next: std::ptr::null_mut(), view_state_flags: xr::ViewStateFlags::EMPTY };
    let blank = xr::View { ty: xr::View::TYPE, next: std::ptr::null_mut(), pose: identity_pose(), fov: xr::Fovf { angle_left: 0.0, angle_right: 0.0, angle_up: 0.0, angle_down: 0.0 } };
    let mut views = [blank; 2];
    let mut n = 0;
    // SAFETY: valid arguments.
    assert_eq!(unsafe { locate(s, &info, &mut vs, 2, &mut n, views.as_mut_ptr()) }, xr::Result::SUCCESS);
    let mut hidden_before = 0.0;
    for view in 0..2u32 {
        let f = views[view as usize].fov;
        let rect = (f.angle_right.tan() - f.angle_left.tan()) * (f.angle_up.tan() - f.angle_down.tan());
        let (hv, hi) = mask(x, s, view, xr::VisibilityMaskTypeKHR::HIDDEN_TRIANGLE_MESH);
        let (vv, vi) = mask(x, s, view, xr::VisibilityMaskTypeKHR::VISIBLE_TRIANGLE_MESH);
        let (lv, li) = mask(x, s, view, xr::VisibilityMaskTypeKHR::LINE_LOOP);
        let (h, v) = (area(&hv, &hi), area(&vv, &vi));
        assert!(h > 0.0 && v > h, "view {view}: hidden {h} visible {v}");
        assert!((h + v - rect).abs() < 1e-3 * rect, "view {view}: {h} + {v} != {rect}");
        assert_eq!(li.len(), lv.len());
        for p in hv.iter().chain(&vv).chain(&lv) {
            assert!(p[0] >= f.angle_left.tan() - 1e-4 && p[0] <= f.angle_right.tan() + 1e-4);
            assert!(p[1] >= f.angle_down.tan() - 1e-4 && p[1] <= f.angle_up.tan() + 1e-4);
        }
        if view == 0 {
            hidden_before = h;
        }
    }
    // left and right masks mirror each other (x → −x), up to the Vive's measured eyes, whose
    // frusta differ by 0.003 tangent from each other's mirror image
    let (l, _) = mask(x, s, 0, xr::VisibilityMaskTypeKHR::LINE_LOOP);
    let (r, _) = mask(x, s, 1, xr::VisibilityMaskTypeKHR::LINE_LOOP);
    let lmin = l.iter().map(|p| p[0]).fold(f32::MAX, f32::min);
    let rmax = r.iter().map(|p| p[0]).fold(f32::MIN, f32::max);
    assert!((lmin + rmax).abs() < 4e-3, "{lmin} {rmax}");

    // the change at frame 1: one event per view after the first xrEndFrame
    assert_eq!(begin_session(x, s), xr::Result::SUCCESS);
    x.events();
    let (_, st) = wait_frame(x, s);
    assert_eq!(begin_frame(x, s), xr::Result::SUCCESS);
    assert_eq!(end_frame(x, s, st.predicted_display_time, &[]), xr::Result::SUCCESS);
    let ev: Vec<_> = x.events().into_iter().map(|(t, _)| t).collect();
    assert_eq!(ev, vec![xr::StructureType::EVENT_DATA_VISIBILITY_MASK_CHANGED_KHR; 2]);
    let (hv, hi) = mask(x, s, 0, xr::VisibilityMaskTypeKHR::HIDDEN_TRIANGLE_MESH);
    assert!(area(&hv, &hi) > hidden_before * 1.1, "mask did not shrink");
}

fn action_set(x: &Xr) -> xr::ActionSet {
    let f: pfn::CreateActionSet = x.f("xrCreateActionSet");
    // SAFETY: plain data.
    let mut ci: xr::ActionSetCreateInfo = unsafe { std::mem::zeroed() };
    ci.ty = xr::ActionSetCreateInfo::TYPE;
    for (d, c) in ci.action_set_name.iter_mut().zip(b"gameplay") {
        *d = *c as _;
    }
    for (d, c) in ci.localized_action_set_name.iter_mut().zip(b"Gameplay") {
        *d = *c as _;
    }
    let mut set = xr::ActionSet::NULL;
    // SAFETY: valid arguments.
    assert_eq!(unsafe { f(x.instance, &ci, &mut set) }, xr::Result::SUCCESS);
    // SAFETY: duplicate name.
    assert_eq!(unsafe { f(x.instance, &ci, &mut set.clone()) }, xr::Result::ERROR_NAME_DUPLICATED);
    set
}

fn action(x: &Xr, set: xr::ActionSet, name: &str, ty: xr::ActionType, subs: &[xr::Path]) -> xr::Action {
    let f: pfn::CreateAction = x.f("xrCreateAction");
    // SAFETY: plain data.
    let mut ci: xr::ActionCreateInfo = unsafe { std::mem::zeroed() };
    ci.ty = xr::ActionCreateInfo::TYPE;
    for (d, c) in ci.action_name.iter_mut().zip(name.bytes()) {
        *d = c as _;
    }
    for (d, c) in ci.localized_action_name.iter_mut().zip(name.to_uppercase().bytes()) {
        *d = c as _;
    }
    ci.action_type = ty;
    ci.count_subaction_paths = subs.len() as u32;
    ci.subaction_paths = subs.as_ptr();
    let mut a = xr::Action::NULL;
    // SAFETY: valid arguments.
    assert_eq!(unsafe { f(set, &ci, &mut a) }, xr::Result::SUCCESS);
    a
}

fn path(x: &Xr, s: &str) -> xr::Path {
    let f: pfn::StringToPath = x.f("xrStringToPath");
    let c = CString::new(s).unwrap();
    let mut p = xr::Path::NULL;
    // SAFETY: valid arguments.
    assert_eq!(unsafe { f(x.instance, c.as_ptr(), &mut p) }, xr::Result::SUCCESS);
    p
}

#[test]
fn actions_menu_click_and_gaze() {
    let _g = serial();
    std::env::set_var("MOCK_XR_MENU_CLICK_AT", "2");
    std::env::set_var("MOCK_XR_GAZE", "10,5");
    let fx = fixture(&["XR_KHR_vulkan_enable2", "XR_EXT_eye_gaze_interaction"]);
    let (x, s) = (fx.xr(), fx.session);
    let set = action_set(x);
    let left = path(x, "/user/hand/left");
    let menu = action(x, set, "menu", xr::ActionType::BOOLEAN_INPUT, &[left]);
    let gaze = action(x, set, "gaze", xr::ActionType::POSE_INPUT, &[]);
    let suggest: pfn::SuggestInteractionProfileBindings = x.f("xrSuggestInteractionProfileBindings");
    let sb = |profile: &str, b: &[xr::ActionSuggestedBinding]| {
        let info = xr::InteractionProfileSuggestedBinding { ty: xr::InteractionProfileSuggestedBinding::TYPE, next: std::ptr::null(), interaction_profile: path(x, profile), count_suggested_bindings: b.len() as u32, suggested_bindings: b.as_ptr() };
        // SAFETY: valid arguments.
        unsafe { suggest(x.instance, &info) }
    };
    let bind = |a, p: &str| xr::ActionSuggestedBinding { action: a, binding: path(x, p) };
    assert_eq!(sb("/interaction_profiles/khr/simple_controller", &[bind(menu, "/user/hand/left/input/trigger/value")]), xr::Result::ERROR_PATH_UNSUPPORTED);
    assert_eq!(sb("/interaction_profiles/valve/index_controller", &[bind(menu, "/user/hand/left/input/menu/click")]), xr::Result::ERROR_PATH_UNSUPPORTED);
    assert_eq!(sb("/interaction_profiles/khr/simple_controller", &[bind(menu, "/user/hand/left/input/menu/click")]), xr::Result::SUCCESS);
    assert_eq!(sb("/interaction_profiles/ext/eye_gaze_interaction", &[bind(gaze, "/user/eyes_ext/input/gaze_ext/pose")]), xr::Result::SUCCESS);

    let sync: pfn::SyncActions = x.f("xrSyncActions");
    let active = [xr::ActiveActionSet { action_set: set, subaction_path: xr::Path::NULL }];
    let si = xr::ActionsSyncInfo { ty: xr::ActionsSyncInfo::TYPE, next: std::ptr::null(), count_active_action_sets: 1, active_action_sets: active.as_ptr() };
    // SAFETY: valid arguments.
    assert_eq!(unsafe { sync(s, &si) }, xr::Result::ERROR_ACTIONSET_NOT_ATTACHED);
    let attach: pfn::AttachSessionActionSets = x.f("xrAttachSessionActionSets");
    let sets = [set];
    let ai = xr::SessionActionSetsAttachInfo { ty: xr::SessionActionSetsAttachInfo::TYPE, next: std::ptr::null(), count_action_sets: 1, action_sets: sets.as_ptr() };
    // SAFETY: valid arguments.
    unsafe {
        assert_eq!(attach(s, &ai), xr::Result::SUCCESS);
        assert_eq!(attach(s, &ai), xr::Result::ERROR_ACTIONSETS_ALREADY_ATTACHED);
    }
    let space_f: pfn::CreateActionSpace = x.f("xrCreateActionSpace");
    let asci = xr::ActionSpaceCreateInfo { ty: xr::ActionSpaceCreateInfo::TYPE, next: std::ptr::null(), action: gaze, subaction_path: xr::Path::NULL, pose_in_action_space: identity_pose() };
    let mut gaze_space = xr::Space::NULL;
    // SAFETY: valid arguments.
    assert_eq!(unsafe { space_f(s, &asci, &mut gaze_space) }, xr::Result::SUCCESS);
    let view = reference_space(x, s, xr::ReferenceSpaceType::VIEW);
    let get_bool: pfn::GetActionStateBoolean = x.f("xrGetActionStateBoolean");
    let get_float: pfn::GetActionStateFloat = x.f("xrGetActionStateFloat");
    let gi = xr::ActionStateGetInfo { ty: xr::ActionStateGetInfo::TYPE, next: std::ptr::null(), action: menu, subaction_path: xr::Path::NULL };
    let mut st = xr::ActionStateBoolean { ty: xr::ActionStateBoolean::TYPE, next: std::ptr::null_mut(), current_state: xr::FALSE, changed_since_last_sync: xr::FALSE, last_change_time: xr::Time::from_nanos(0), is_active: xr::FALSE };
    // SAFETY: valid arguments.
    unsafe {
        // not focused yet: synced but inactive
        assert_eq!(sync(s, &si), xr::Result::SESSION_NOT_FOCUSED);
        assert_eq!(get_bool(s, &gi, &mut st), xr::Result::SUCCESS);
        assert_eq!(st.is_active, xr::FALSE);
        let mut fs: xr::ActionStateFloat = std::mem::zeroed();
        fs.ty = xr::ActionStateFloat::TYPE;
        assert_eq!(get_float(s, &gi, &mut fs), xr::Result::ERROR_ACTION_TYPE_MISMATCH);
    }
    assert_eq!(begin_session(x, s), xr::Result::SUCCESS);
    let mut clicks = Vec::new();
    for _ in 0..4 {
        // SAFETY: valid arguments.
        unsafe {
            assert_eq!(sync(s, &si), xr::Result::SUCCESS);
            assert_eq!(get_bool(s, &gi, &mut st), xr::Result::SUCCESS);
        }
        assert_eq!(st.is_active, xr::TRUE);
        clicks.push(st.current_state == xr::TRUE);
        let (_, fst) = wait_frame(x, s);
        assert_eq!(begin_frame(x, s), xr::Result::SUCCESS);
        assert_eq!(end_frame(x, s, fst.predicted_display_time, &[]), xr::Result::SUCCESS);
    }
    assert_eq!(clicks, vec![false, false, true, true]);
    let locate: pfn::LocateSpace = x.f("xrLocateSpace");
    let mut loc = xr::SpaceLocation { ty: xr::SpaceLocation::TYPE, next: std::ptr::null_mut(), location_flags: xr::SpaceLocationFlags::EMPTY, pose: identity_pose() };
    // SAFETY: valid arguments.
    assert_eq!(unsafe { locate(gaze_space, view, xr::Time::from_nanos(1), &mut loc) }, xr::Result::SUCCESS);
    assert!(loc.location_flags.contains(xr::SpaceLocationFlags::ORIENTATION_TRACKED));
    let o = loc.pose.orientation;
    let fwd = glam::Quat::from_xyzw(o.x, o.y, o.z, o.w) * glam::Vec3::NEG_Z;
    assert!((fwd.x.atan2(-fwd.z).to_degrees() - 10.0).abs() < 0.01, "yaw {fwd}");
    assert!((fwd.y.asin().to_degrees() - 5.0).abs() < 0.01, "pitch {fwd}");
}

/// `MOCK_XR_GAZE_PATH` + `MOCK_XR_GAZE_HOLD`: the gaze located during frame f (after f
/// successful xrEndFrame calls) is the path's point (f / hold) mod len, whatever the locate time.
#[test]
fn gaze_path_moves_with_the_frame_number() {
    let _g = serial();
    std::env::set_var("MOCK_XR_GAZE_PATH", "10,5;-20,0");
    std::env::set_var("MOCK_XR_GAZE_HOLD", "2");
    let fx = fixture(&["XR_KHR_vulkan_enable2", "XR_EXT_eye_gaze_interaction"]);
    let (x, s) = (fx.xr(), fx.session);
    let set = action_set(x);
    let gaze = action(x, set, "gaze", xr::ActionType::POSE_INPUT, &[]);
    let suggest: pfn::SuggestInteractionProfileBindings = x.f("xrSuggestInteractionProfileBindings");
    let b = [xr::ActionSuggestedBinding { action: gaze, binding: path(x, "/user/eyes_ext/input/gaze_ext/pose") }];
    let info = xr::InteractionProfileSuggestedBinding { ty: xr::InteractionProfileSuggestedBinding::TYPE, next: std::ptr::null(), interaction_profile: path(x, "/interaction_profiles/ext/eye_gaze_interaction"), count_suggested_bindings: 1, suggested_bindings: b.as_ptr() };
    let attach: pfn::AttachSessionActionSets = x.f("xrAttachSessionActionSets");
    let sets = [set];
    let ai = xr::SessionActionSetsAttachInfo { ty: xr::SessionActionSetsAttachInfo::TYPE, next: std::ptr::null(), count_action_sets: 1, action_sets: sets.as_ptr() };
    let space_f: pfn::CreateActionSpace = x.f("xrCreateActionSpace");
    let asci = xr::ActionSpaceCreateInfo { ty: xr::ActionSpaceCreateInfo::TYPE, next: std::ptr::null(), action: gaze, subaction_path: xr::Path::NULL, pose_in_action_space: identity_pose() };
    let mut gaze_space = xr::Space::NULL;
    // SAFETY: valid arguments.
    unsafe {
        assert_eq!(suggest(x.instance, &info), xr::Result::SUCCESS);
        assert_eq!(attach(s, &ai), xr::Result::SUCCESS);
        assert_eq!(space_f(s, &asci, &mut gaze_space), xr::Result::SUCCESS);
    }
    let view = reference_space(x, s, xr::ReferenceSpaceType::VIEW);
    assert_eq!(begin_session(x, s), xr::Result::SUCCESS);
    let sync: pfn::SyncActions = x.f("xrSyncActions");
    let active = [xr::ActiveActionSet { action_set: set, subaction_path: xr::Path::NULL }];
    let si = xr::ActionsSyncInfo { ty: xr::ActionsSyncInfo::TYPE, next: std::ptr::null(), count_active_action_sets: 1, active_action_sets: active.as_ptr() };
    let locate: pfn::LocateSpace = x.f("xrLocateSpace");
    let mut seen = Vec::new();
    for _ in 0..5 {
        let (_, fst) = wait_frame(x, s);
        assert_eq!(begin_frame(x, s), xr::Result::SUCCESS);
        let mut loc = xr::SpaceLocation { ty: xr::SpaceLocation::TYPE, next: std::ptr::null_mut(), location_flags: xr::SpaceLocationFlags::EMPTY, pose: identity_pose() };
        // SAFETY: valid arguments.
        unsafe {
            assert_eq!(sync(s, &si), xr::Result::SUCCESS);
            assert_eq!(locate(gaze_space, view, fst.predicted_display_time, &mut loc), xr::Result::SUCCESS);
        }
        let o = loc.pose.orientation;
        let fwd = glam::Quat::from_xyzw(o.x, o.y, o.z, o.w) * glam::Vec3::NEG_Z;
        seen.push((fwd.x.atan2(-fwd.z).to_degrees().round(), fwd.y.asin().to_degrees().round()));
        assert_eq!(end_frame(x, s, fst.predicted_display_time, &[]), xr::Result::SUCCESS);
    }
    assert_eq!(seen, [(10.0, 5.0), (10.0, 5.0), (-20.0, 0.0), (-20.0, 0.0), (10.0, 5.0)]);
}

/// frames.json's `visibility_masks` of each captured frame, per view: the hidden triangles' points.
fn captured_masks(dir: &std::path::Path) -> Vec<Vec<Vec<[f32; 2]>>> {
    let json: serde_json::Value = serde_json::from_slice(&std::fs::read(dir.join("frames.json")).unwrap()).unwrap();
    json["frames"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| {
            let masks = f["visibility_masks"].as_array().expect("visibility_masks");
            assert_eq!(masks.len(), 2);
            masks
                .iter()
                .enumerate()
                .map(|(v, m)| {
                    assert_eq!(m["view"].as_u64(), Some(v as u64));
                    m["hidden_triangles"]
                        .as_array()
                        .unwrap()
                        .iter()
                        .map(|p| [p[0].as_f64().unwrap() as f32, p[1].as_f64().unwrap() as f32])
                        .collect()
                })
                .collect()
        })
        .collect()
}

/// Runs `frames` captured frames of a 2-view projection layer; before each xrEndFrame, `during`
/// sees the session (to ask for what the runtime reports during that frame).
fn capture_frames(fx: &Fixture, frames: u32, mut during: impl FnMut(&Xr, xr::Session)) {
    let (x, s) = (fx.xr(), fx.session);
    let stage = reference_space(x, s, xr::ReferenceSpaceType::STAGE);
    let sc = try_create_swapchain(x, s, &swapchain_info(vk::Format::R8G8B8A8_SRGB, 64, 32, 1)).unwrap();
    let images = swapchain_images(x, sc);
    assert_eq!(begin_session(x, s), xr::Result::SUCCESS);
    for _ in 0..frames {
        let (r, st) = wait_frame(x, s);
        assert_eq!(r, xr::Result::SUCCESS);
        assert_eq!(begin_frame(x, s), xr::Result::SUCCESS);
        let i = acquire_wait(x, sc);
        fx.gfx.clear_color(images[i as usize], 0, [1.0, 0.0, 0.0, 1.0]);
        assert_eq!(release(x, sc), xr::Result::SUCCESS);
        during(x, s);
        let views = [projection_view(sc, 0, 32, 32, 0), projection_view(sc, 32, 32, 32, 0)];
        let layer = projection_layer(stage, &views);
        assert_eq!(end_frame(x, s, st.predicted_display_time, &[&layer as *const _ as *const _]), xr::Result::SUCCESS);
        x.events();
    }
}

#[test]
fn capture_lists_the_hidden_masks_of_each_frame() {
    let _g = serial();
    let dir = scratch_dir("capture-masks");
    std::env::set_var("MOCK_XR_HMD", "index");
    std::env::set_var("MOCK_XR_CAPTURE", &dir);
    std::env::set_var("MOCK_XR_VISIBILITY_MASK_CHANGE_AT", "1");
    let fx = fixture(&["XR_KHR_vulkan_enable2", "XR_KHR_visibility_mask"]);
    // What xrGetVisibilityMaskKHR returns during each frame, expanded to 3 points per triangle.
    let mut expected: Vec<Vec<Vec<[f32; 2]>>> = Vec::new();
    capture_frames(&fx, 3, |x, s| {
        expected.push(
            (0..2)
                .map(|view| {
                    let (v, i) = mask(x, s, view, xr::VisibilityMaskTypeKHR::HIDDEN_TRIANGLE_MESH);
                    i.iter().map(|&k| v[k as usize]).collect()
                })
                .collect(),
        );
    });
    let captured = captured_masks(&dir);
    assert_eq!(captured.len(), 3);
    // Bit-exact: the f32 values survive the shortest-decimal round trip.
    assert_eq!(captured, expected);
    for frame in &captured {
        for view in frame {
            assert!(!view.is_empty() && view.len() % 3 == 0);
        }
    }
    // The change at frame 1 shows in frames.json: frame 0 has the original masks, 1 and 2 the shrunk ones.
    assert_ne!(captured[0], captured[1]);
    assert_eq!(captured[1], captured[2]);
    // Views differ (mirror images).
    assert_ne!(captured[0][0], captured[0][1]);
}

#[test]
fn capture_lists_no_masks_without_the_extension() {
    let _g = serial();
    let dir = scratch_dir("capture-no-masks");
    std::env::set_var("MOCK_XR_CAPTURE", &dir);
    std::env::set_var("MOCK_XR_DISABLE_EXTENSIONS", "XR_KHR_visibility_mask");
    std::env::set_var("MOCK_XR_VISIBILITY_MASK_CHANGE_AT", "1");
    let fx = fixture(&["XR_KHR_vulkan_enable2"]);
    capture_frames(&fx, 2, |_, _| {});
    let captured = captured_masks(&dir);
    assert_eq!(captured, vec![vec![Vec::<[f32; 2]>::new(); 2]; 2]);
}

#[test]
fn headless_session_without_a_binding() {
    // XR_MND_headless: with the extension enabled, xrCreateSession without a graphics binding makes
    // a session that renders nothing (no swapchain formats, shouldRender false) but answers for
    // its views and masks; without it, the same call is refused.
    let _g = serial();
    let x = create_instance(&["XR_MND_headless", "XR_KHR_visibility_mask"]);
    let f: pfn::CreateSession = x.f("xrCreateSession");
    let ci = xr::SessionCreateInfo { ty: xr::SessionCreateInfo::TYPE, next: std::ptr::null(), create_flags: xr::SessionCreateFlags::EMPTY, system_id: x.system };
    let mut s = xr::Session::NULL;
    // SAFETY: valid arguments.
    assert_eq!(unsafe { f(x.instance, &ci, &mut s) }, xr::Result::SUCCESS);
    let formats: pfn::EnumerateSwapchainFormats = x.f("xrEnumerateSwapchainFormats");
    let mut n = 99;
    // SAFETY: valid arguments; a count-only call.
    assert_eq!(unsafe { formats(s, 0, &mut n, std::ptr::null_mut()) }, xr::Result::SUCCESS);
    assert_eq!(n, 0, "a headless session has no swapchain formats");
    let (v, i) = mask(&x, s, 0, xr::VisibilityMaskTypeKHR::HIDDEN_TRIANGLE_MESH);
    assert!(area(&v, &i) > 0.0);
    // The view configuration of a headless session's xrBeginSession is ignored (may be 0).
    let begin: pfn::BeginSession = x.f("xrBeginSession");
    let bi = xr::SessionBeginInfo { ty: xr::SessionBeginInfo::TYPE, next: std::ptr::null(), primary_view_configuration_type: xr::ViewConfigurationType::from_raw(0) };
    // SAFETY: valid arguments.
    assert_eq!(unsafe { begin(s, &bi) }, xr::Result::SUCCESS);
    let wait: pfn::WaitFrame = x.f("xrWaitFrame");
    // SAFETY: plain data.
    let mut state: xr::FrameState = unsafe { std::mem::zeroed() };
    state.ty = xr::FrameState::TYPE;
    // SAFETY: valid arguments.
    assert_eq!(unsafe { wait(s, std::ptr::null(), &mut state) }, xr::Result::SUCCESS);
    assert_eq!(state.should_render, xr::FALSE);
    drop(x);

    std::env::set_var("MOCK_XR_DISABLE_EXTENSIONS", "XR_MND_headless");
    assert_eq!(try_create_instance(&["XR_MND_headless"], xr::Version::new(1, 0, 0)).err(), Some(xr::Result::ERROR_EXTENSION_NOT_PRESENT));
    std::env::remove_var("MOCK_XR_DISABLE_EXTENSIONS");
}
