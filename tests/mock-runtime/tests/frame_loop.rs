//! Session lifecycle, frame loop ordering, xrEndFrame layer validation and capture, through the
//! real loader.

mod common;

use ash::vk;
use common::*;
use openxr_sys as xr;
use xr::pfn;
use xr::Handle as _;
use xr::SessionState as S;

#[test]
fn state_sequence_with_exit_after_and_capture() {
    let _g = serial();
    let dir = scratch_dir("capture-basic");
    std::env::set_var("MOCK_XR_EXIT_AFTER", "3");
    std::env::set_var("MOCK_XR_CAPTURE", &dir);
    std::env::set_var("MOCK_XR_CAPTURE_FRAMES", "0,2");
    std::env::set_var("MOCK_XR_HMD", "index");
    let errors_before = VALIDATION_ERRORS.load(std::sync::atomic::Ordering::SeqCst);
    let fx = fixture(&["XR_KHR_vulkan_enable2"]);
    let x = fx.xr();
    let s = fx.session;
    assert_eq!(x.states(), vec![S::IDLE, S::READY]);
    let stage = reference_space(x, s, xr::ReferenceSpaceType::STAGE);
    let sc = try_create_swapchain(x, s, &swapchain_info(vk::Format::R8G8B8A8_SRGB, 64, 32, 1)).unwrap();
    let images = swapchain_images(x, sc);
    assert_eq!(images.len(), 3);
    // Not running yet.
    assert_eq!(wait_frame(x, s).0, xr::Result::ERROR_SESSION_NOT_RUNNING);
    assert_eq!(begin_session(x, s), xr::Result::SUCCESS);
    assert_eq!(begin_session(x, s), xr::Result::ERROR_SESSION_RUNNING);
    assert_eq!(x.states(), vec![S::SYNCHRONIZED, S::VISIBLE, S::FOCUSED]);
    let end_session: pfn::EndSession = x.f("xrEndSession");
    // SAFETY: valid session.
    assert_eq!(unsafe { end_session(s) }, xr::Result::ERROR_SESSION_NOT_STOPPING);
    let mut times = Vec::new();
    for frame in 0..3 {
        let (r, st) = wait_frame(x, s);
        assert_eq!(r, xr::Result::SUCCESS);
        assert_eq!(st.should_render, xr::TRUE);
        times.push(st.predicted_display_time.as_nanos());
        assert_eq!(begin_frame(x, s), xr::Result::SUCCESS);
        let i = acquire_wait(x, sc);
        // Left half red, right half green (stored bytes of an sRGB image: 255/0).
        fx.gfx.clear_color(images[i as usize], 0, if frame == 2 { [0.0, 0.0, 1.0, 1.0] } else { [1.0, 0.0, 0.0, 1.0] });
        assert_eq!(release(x, sc), xr::Result::SUCCESS);
        let views = [projection_view(sc, 0, 32, 32, 0), projection_view(sc, 32, 32, 32, 0)];
        let layer = projection_layer(stage, &views);
        assert_eq!(end_frame(x, s, st.predicted_display_time, &[&layer as *const _ as *const _]), xr::Result::SUCCESS);
    }
    // Deterministic display clock.
    assert_eq!(times[1] - times[0], times[2] - times[1]);
    assert_eq!(times[0], 1_000_000_000);
    assert_eq!(x.states(), vec![S::VISIBLE, S::SYNCHRONIZED, S::STOPPING]);
    // SAFETY: valid session.
    assert_eq!(unsafe { end_session(s) }, xr::Result::SUCCESS);
    assert_eq!(x.states(), vec![S::IDLE, S::EXITING]);
    // SAFETY: valid session.
    assert_eq!(unsafe { end_session(s) }, xr::Result::ERROR_SESSION_NOT_RUNNING);

    let json: serde_json::Value = serde_json::from_slice(&std::fs::read(dir.join("frames.json")).unwrap()).unwrap();
    assert_eq!(json["hmd"], "index");
    let frames = json["frames"].as_array().unwrap();
    assert_eq!(frames.iter().map(|f| f["frame"].as_u64().unwrap()).collect::<Vec<_>>(), vec![0, 2]);
    let v = &frames[0]["layers"][0]["views"][1];
    assert_eq!(frames[0]["layers"][0]["space"], "STAGE");
    assert_eq!(v["image_rect"]["x"], 32);
    assert_eq!(v["format"], vk::Format::R8G8B8A8_SRGB.as_raw());
    assert_eq!(v["file"], "frame-00000-view-1.png");
    assert_eq!(v["swapchain"].as_u64().unwrap(), sc.into_raw());
    assert!(v["depth"].is_null());
    // XR_KHR_visibility_mask is offered (the app did not enable it): the runtime's masks are listed.
    for f in frames {
        let masks = f["visibility_masks"].as_array().unwrap();
        assert_eq!(masks.len(), 2);
        for (i, m) in masks.iter().enumerate() {
            assert_eq!(m["view"], i);
            let n = m["hidden_triangles"].as_array().unwrap().len();
            assert!(n > 0 && n % 3 == 0, "{n}");
        }
    }
    for (file, rgb) in [("frame-00000-view-0.png", [255, 0, 0]), ("frame-00002-view-1.png", [0, 0, 255])] {
        let dec = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(dir.join(file)).unwrap()));
        let mut r = dec.read_info().unwrap();
        let mut buf = vec![0; r.output_buffer_size().unwrap()];
        let info = r.next_frame(&mut buf).unwrap();
        assert_eq!((info.width, info.height, info.color_type), (32, 32, png::ColorType::Rgb));
        assert_eq!(&buf[..3], &rgb, "{file}");
    }
    assert!(!dir.join("frame-00001-view-0.png").exists());
    drop(fx);
    assert_eq!(VALIDATION_ERRORS.load(std::sync::atomic::Ordering::SeqCst), errors_before, "Vulkan validation errors");
}

/// Begins a session and returns a STAGE space and a 64×32 colour swapchain with one released image.
fn running(fx: &Fixture) -> (xr::Space, xr::Swapchain) {
    let x = fx.xr();
    let stage = reference_space(x, fx.session, xr::ReferenceSpaceType::STAGE);
    let sc = try_create_swapchain(x, fx.session, &swapchain_info(vk::Format::B8G8R8A8_UNORM, 64, 32, 2)).unwrap();
    assert_eq!(begin_session(x, fx.session), xr::Result::SUCCESS);
    acquire_wait(x, sc);
    assert_eq!(release(x, sc), xr::Result::SUCCESS);
    (stage, sc)
}

#[test]
fn frame_ordering_errors() {
    let _g = serial();
    let fx = fixture(&["XR_KHR_vulkan_enable2"]);
    let (x, s) = (fx.xr(), fx.session);
    let (stage, sc) = running(&fx);
    let t = xr::Time::from_nanos(1);
    // begin without wait, end without begin
    assert_eq!(begin_frame(x, s), xr::Result::ERROR_CALL_ORDER_INVALID);
    assert_eq!(end_frame(x, s, t, &[]), xr::Result::ERROR_CALL_ORDER_INVALID);
    let (_, st1) = wait_frame(x, s);
    assert_eq!(begin_frame(x, s), xr::Result::SUCCESS);
    // a second begin needs its own wait; with it, the first frame is discarded
    assert_eq!(begin_frame(x, s), xr::Result::ERROR_CALL_ORDER_INVALID);
    let (_, st2) = wait_frame(x, s);
    assert_ne!(st1.predicted_display_time, st2.predicted_display_time);
    assert_eq!(begin_frame(x, s), xr::Result::FRAME_DISCARDED);
    // the discarded frame's time is no longer valid
    assert_eq!(end_frame(x, s, st1.predicted_display_time, &[]), xr::Result::ERROR_TIME_INVALID);
    let views = [projection_view(sc, 0, 32, 32, 0), projection_view(sc, 32, 32, 32, 1)];
    let layer = projection_layer(stage, &views);
    assert_eq!(end_frame(x, s, st2.predicted_display_time, &[&layer as *const _ as *const _]), xr::Result::SUCCESS);
    assert_eq!(end_frame(x, s, st2.predicted_display_time, &[]), xr::Result::ERROR_CALL_ORDER_INVALID);
}

/// The spec's xrWaitFrame: "A subsequent xrWaitFrame call must block until the previous frame
/// has been begun with xrBeginFrame and must unblock independently of the corresponding call to
/// xrEndFrame". An engine's frame-pacing thread waits for frame N+1 while frame N is rendered
/// (xr-scene `--threads`): that wait returns at once when N is begun, before N is ended, and one
/// made before N is begun returns only once it is.
#[test]
fn wait_frame_blocks_until_the_previous_frame_is_begun() {
    let _g = serial();
    let fx = fixture(&["XR_KHR_vulkan_enable2"]);
    let (x, s) = (fx.xr(), fx.session);
    let (stage, sc) = running(&fx);
    let views = [projection_view(sc, 0, 32, 32, 0), projection_view(sc, 32, 32, 32, 1)];
    let layer = projection_layer(stage, &views);
    // Pipelined: frame 1's wait after frame 0's begin, before its end.
    let (r, st0) = wait_frame(x, s);
    assert_eq!(r, xr::Result::SUCCESS);
    assert_eq!(begin_frame(x, s), xr::Result::SUCCESS);
    let (r, st1) = wait_frame(x, s);
    assert_eq!(r, xr::Result::SUCCESS);
    assert_eq!(end_frame(x, s, st0.predicted_display_time, &[&layer as *const _ as *const _]), xr::Result::SUCCESS);
    // Frame 2's wait on another thread before frame 1 is begun: it blocks until the begin.
    let begun = std::sync::atomic::AtomicBool::new(false);
    std::thread::scope(|scope| {
        let waiter = scope.spawn(|| {
            let (r, st) = wait_frame(x, s);
            // FrameState holds a pointer (its `next`): only the values leave the thread.
            ((r, st.predicted_display_time.as_nanos()), begun.load(std::sync::atomic::Ordering::SeqCst))
        });
        std::thread::sleep(std::time::Duration::from_millis(200));
        assert!(!waiter.is_finished(), "xrWaitFrame returned before the previous frame was begun");
        begun.store(true, std::sync::atomic::Ordering::SeqCst);
        assert_eq!(begin_frame(x, s), xr::Result::SUCCESS);
        let ((r, t2), after_begin) = waiter.join().unwrap();
        assert_eq!(r, xr::Result::SUCCESS);
        assert!(after_begin);
        assert!(t2 > st1.predicted_display_time.as_nanos());
        assert_eq!(end_frame(x, s, st1.predicted_display_time, &[&layer as *const _ as *const _]), xr::Result::SUCCESS);
    });
}

#[test]
fn end_frame_layer_validation() {
    let _g = serial();
    let fx = fixture(&["XR_KHR_vulkan_enable2"]);
    let (x, s) = (fx.xr(), fx.session);
    let (stage, sc) = running(&fx);
    let never_released = try_create_swapchain(x, s, &swapchain_info(vk::Format::R8G8B8A8_SRGB, 16, 16, 1)).unwrap();
    let (_, st) = wait_frame(x, s);
    assert_eq!(begin_frame(x, s), xr::Result::SUCCESS);
    let t = st.predicted_display_time;
    let good = [projection_view(sc, 0, 32, 32, 0), projection_view(sc, 32, 32, 32, 1)];
    let check = |views: &[xr::CompositionLayerProjectionView], space: xr::Space, want: xr::Result| {
        let layer = projection_layer(space, views);
        assert_eq!(end_frame(x, s, t, &[&layer as *const _ as *const _]), want);
    };
    check(&good[..1], stage, xr::Result::ERROR_VALIDATION_FAILURE); // one view for stereo
    check(&[good[0], projection_view(sc, 33, 32, 32, 0)], stage, xr::Result::ERROR_SWAPCHAIN_RECT_INVALID);
    check(&[good[0], projection_view(sc, -1, 32, 32, 0)], stage, xr::Result::ERROR_SWAPCHAIN_RECT_INVALID);
    check(&[good[0], projection_view(sc, 0, 0, 32, 0)], stage, xr::Result::ERROR_SWAPCHAIN_RECT_INVALID);
    check(&[good[0], projection_view(sc, 32, 32, 32, 2)], stage, xr::Result::ERROR_VALIDATION_FAILURE);
    check(&[good[0], projection_view(never_released, 0, 16, 16, 0)], stage, xr::Result::ERROR_LAYER_INVALID);
    check(&[good[0], projection_view(xr::Swapchain::from_raw(0xdead), 0, 16, 16, 0)], stage, xr::Result::ERROR_HANDLE_INVALID);
    check(&good, xr::Space::from_raw(0xdead), xr::Result::ERROR_HANDLE_INVALID);
    check(&good, xr::Space::NULL, xr::Result::ERROR_HANDLE_INVALID);
    let mut wrong_type = good;
    wrong_type[1].ty = xr::StructureType::VIEW;
    check(&wrong_type, stage, xr::Result::ERROR_VALIDATION_FAILURE);
    let mut bad_pose = good;
    bad_pose[0].pose.orientation.w = 0.0;
    check(&bad_pose, stage, xr::Result::ERROR_POSE_INVALID);
    // a NULL layer pointer and an unsupported layer type
    assert_eq!(end_frame(x, s, t, &[std::ptr::null()]), xr::Result::ERROR_LAYER_INVALID);
    let bogus = xr::CompositionLayerBaseHeader { ty: xr::StructureType::COMPOSITION_LAYER_CUBE_KHR, next: std::ptr::null(), layer_flags: xr::CompositionLayerFlags::EMPTY, space: stage };
    assert_eq!(end_frame(x, s, t, &[&bogus]), xr::Result::ERROR_LAYER_INVALID);
    // blend mode
    let f: pfn::EndFrame = x.f("xrEndFrame");
    let info = xr::FrameEndInfo { ty: xr::FrameEndInfo::TYPE, next: std::ptr::null(), display_time: t, environment_blend_mode: xr::EnvironmentBlendMode::ADDITIVE, layer_count: 0, layers: std::ptr::null() };
    // SAFETY: valid arguments.
    assert_eq!(unsafe { f(s, &info) }, xr::Result::ERROR_ENVIRONMENT_BLEND_MODE_UNSUPPORTED);
    // wrong struct type of the end info itself
    let info = xr::FrameEndInfo { ty: xr::StructureType::FRAME_BEGIN_INFO, environment_blend_mode: xr::EnvironmentBlendMode::OPAQUE, ..info };
    // SAFETY: valid pointer, wrong type on purpose.
    assert_eq!(unsafe { f(s, &info) }, xr::Result::ERROR_VALIDATION_FAILURE);
    // after all that, the frame can still be ended properly
    check(&good, stage, xr::Result::SUCCESS);
}

#[test]
fn depth_submission_and_enable1_capture() {
    let _g = serial();
    let dir = scratch_dir("capture-depth");
    std::env::set_var("MOCK_XR_CAPTURE", &dir);
    let errors_before = VALIDATION_ERRORS.load(std::sync::atomic::Ordering::SeqCst);
    let fx = fixture(&["XR_KHR_vulkan_enable", "XR_KHR_composition_layer_depth"]);
    let (x, s) = (fx.xr(), fx.session);
    let (stage, sc) = running(&fx);
    let dsc = try_create_swapchain(x, s, &swapchain_info(vk::Format::D32_SFLOAT, 64, 32, 2)).unwrap();
    let (_, st) = wait_frame(x, s);
    assert_eq!(begin_frame(x, s), xr::Result::SUCCESS);
    acquire_wait(x, dsc);
    assert_eq!(release(x, dsc), xr::Result::SUCCESS);
    let depth = |min: f32, max: f32, near: f32, far: f32, layer: u32| xr::CompositionLayerDepthInfoKHR {
        ty: xr::CompositionLayerDepthInfoKHR::TYPE,
        next: std::ptr::null(),
        sub_image: projection_view(dsc, 0, 32, 32, layer).sub_image,
        min_depth: min,
        max_depth: max,
        near_z: near,
        far_z: far,
    };
    let end_with = |d: &xr::CompositionLayerDepthInfoKHR| {
        let mut views = [projection_view(sc, 0, 32, 32, 0), projection_view(sc, 32, 32, 32, 1)];
        views[0].next = d as *const _ as *const _;
        let layer = projection_layer(stage, &views);
        end_frame(x, s, st.predicted_display_time, &[&layer as *const _ as *const _])
    };
    assert_eq!(end_with(&depth(1.0, 0.0, 0.1, 100.0, 0)), xr::Result::ERROR_VALIDATION_FAILURE);
    assert_eq!(end_with(&depth(0.0, 1.0, 0.1, 0.1, 0)), xr::Result::ERROR_VALIDATION_FAILURE);
    assert_eq!(end_with(&depth(0.0, 1.5, 0.1, 100.0, 0)), xr::Result::ERROR_VALIDATION_FAILURE);
    assert_eq!(end_with(&depth(0.0, 1.0, 0.1, 100.0, 2)), xr::Result::ERROR_VALIDATION_FAILURE);
    // reversed Z with an infinite far plane is fine
    assert_eq!(end_with(&depth(0.0, 1.0, f32::INFINITY, 0.1, 1)), xr::Result::SUCCESS);
    let json: serde_json::Value = serde_json::from_slice(&std::fs::read(dir.join("frames.json")).unwrap()).unwrap();
    let d = &json["frames"][0]["layers"][0]["views"][0]["depth"];
    assert_eq!(d["file"], "frame-00000-view-0-depth.png");
    assert_eq!(d["image_array_index"], 1);
    assert!(d["near_z"].is_null() && d["far_z"].as_f64() == Some(0.1f32 as f64).map(|_| 0.1));
    assert!(dir.join("frame-00000-view-0-depth.png").exists());
    drop(fx);
    assert_eq!(VALIDATION_ERRORS.load(std::sync::atomic::Ordering::SeqCst), errors_before, "Vulkan validation errors");
}

#[test]
fn request_exit_and_locate_views() {
    let _g = serial();
    std::env::set_var("MOCK_XR_HMD", "pimax");
    let fx = fixture(&["XR_KHR_vulkan_enable2"]);
    let (x, s) = (fx.xr(), fx.session);
    let exit: pfn::RequestExitSession = x.f("xrRequestExitSession");
    // SAFETY: valid session.
    assert_eq!(unsafe { exit(s) }, xr::Result::ERROR_SESSION_NOT_RUNNING);
    let (stage, _) = running(&fx);
    let locate: pfn::LocateViews = x.f("xrLocateViews");
    let info = xr::ViewLocateInfo { ty: xr::ViewLocateInfo::TYPE, next: std::ptr::null(), view_configuration_type: xr::ViewConfigurationType::PRIMARY_STEREO, display_time: xr::Time::from_nanos(1_000_000_000), space: stage };
    let mut vs = xr::ViewState { ty: xr::ViewState::TYPE, next: std::ptr::null_mut(), view_state_flags: xr::ViewStateFlags::EMPTY };
    let blank = xr::View { ty: xr::View::TYPE, next: std::ptr::null_mut(), pose: identity_pose(), fov: xr::Fovf { angle_left: 0.0, angle_right: 0.0, angle_up: 0.0, angle_down: 0.0 } };
    let mut views = [blank; 2];
    let mut n = 0;
    // SAFETY: valid arguments.
    unsafe {
        assert_eq!(locate(s, &info, &mut vs, 0, &mut n, std::ptr::null_mut()), xr::Result::SUCCESS);
        assert_eq!(n, 2);
        assert_eq!(locate(s, &info, &mut vs, 1, &mut n, views.as_mut_ptr()), xr::Result::ERROR_SIZE_INSUFFICIENT);
        assert_eq!(locate(s, &info, &mut vs, 2, &mut n, views.as_mut_ptr()), xr::Result::SUCCESS);
        let bad = xr::ViewLocateInfo { display_time: xr::Time::from_nanos(0), ..info };
        assert_eq!(locate(s, &bad, &mut vs, 2, &mut n, views.as_mut_ptr()), xr::Result::ERROR_TIME_INVALID);
    }
    assert!(vs.view_state_flags.contains(xr::ViewStateFlags::ORIENTATION_VALID | xr::ViewStateFlags::POSITION_TRACKED));
    let (l, r) = (views[0].pose, views[1].pose);
    assert!((r.position.x - l.position.x - 0.064).abs() < 1e-5);
    assert!((l.position.y - 1.6).abs() < 1e-5);
    // canted: the left view is turned left (positive yaw about +y), the right one right
    assert!(l.orientation.y > 0.08 && r.orientation.y < -0.08);
    assert!(views[0].fov.angle_left < -views[0].fov.angle_right);
    // SAFETY: valid session.
    assert_eq!(unsafe { exit(s) }, xr::Result::SUCCESS);
    let st = x.states();
    assert_eq!(&st[st.len() - 3..], &[S::VISIBLE, S::SYNCHRONIZED, S::STOPPING]);
}

/// An app (or layer) that hands the image back in the wrong layout must be caught: the capture's
/// barrier names the layout the spec promises, so the validation layer reports the mismatch.
#[test]
fn wrong_layout_on_release_is_reported_by_validation() {
    let _g = serial();
    let dir = scratch_dir("capture-bad-layout");
    std::env::set_var("MOCK_XR_CAPTURE", &dir);
    let fx = fixture(&["XR_KHR_vulkan_enable2"]);
    if !fx.gfx.validation {
        eprintln!("VK_LAYER_KHRONOS_validation not installed: skipping");
        return;
    }
    let (x, s) = (fx.xr(), fx.session);
    let stage = reference_space(x, s, xr::ReferenceSpaceType::STAGE);
    let sc = try_create_swapchain(x, s, &swapchain_info(vk::Format::R8G8B8A8_UNORM, 16, 16, 1)).unwrap();
    let images = swapchain_images(x, sc);
    assert_eq!(begin_session(x, s), xr::Result::SUCCESS);
    let (_, st) = wait_frame(x, s);
    assert_eq!(begin_frame(x, s), xr::Result::SUCCESS);
    let i = acquire_wait(x, sc);
    let before = VALIDATION_ERRORS.load(std::sync::atomic::Ordering::SeqCst);
    fx.gfx.clear_color_ex(images[i as usize], 0, [1.0, 1.0, 1.0, 1.0], false);
    assert_eq!(release(x, sc), xr::Result::SUCCESS);
    let views = [projection_view(sc, 0, 16, 16, 0), projection_view(sc, 0, 16, 16, 0)];
    let layer = projection_layer(stage, &views);
    assert_eq!(end_frame(x, s, st.predicted_display_time, &[&layer as *const _ as *const _]), xr::Result::SUCCESS);
    assert!(VALIDATION_ERRORS.load(std::sync::atomic::Ordering::SeqCst) > before, "layout bug went unnoticed");
}
