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
