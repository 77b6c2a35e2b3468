//! The command line's rules: what parses, what is refused, and what each option implies.
use super::*;

/// `Ok(None)`: the help text was asked for.
fn p(args: &[&str]) -> Result<Option<Options>, String> {
    match parse(args.iter().map(|s| s.to_string())) {
        Ok(o) => Ok(Some(o)),
        Err(e) if e.kind() == clap::error::ErrorKind::DisplayHelp => Ok(None),
        Err(e) => Err(e.to_string()),
    }
}

#[test]
fn defaults() {
    let o = p(&[]).unwrap().unwrap();
    assert_eq!(o.layout, Layout::PerEye);
    assert_eq!(o.vulkan, VulkanPath::Enable2);
    assert_eq!(o.samples, 1, "no intermediate target means single-sampled");
    assert_eq!(o.color_format, ColorFamily::Srgb);
    assert_eq!(o.depth_clear, DepthClear::LoadOp);
    assert_eq!(o.vulkan_api, VulkanApi::V1_3);
    assert!(!o.secondary);
}

#[test]
fn vulkan_api_and_secondary() {
    assert_eq!(p(&["--vulkan-api", "1.0"]).unwrap().unwrap().vulkan_api, VulkanApi::V1_0);
    assert_eq!(p(&["--vulkan-api=1.1"]).unwrap().unwrap().vulkan_api, VulkanApi::V1_1);
    assert!(p(&["--vulkan-api", "1.2"]).is_err());
    assert!(p(&["--vulkan-api", "1.0", "--layout", "multiview"]).is_err());
    assert!(p(&["--vulkan-api", "1.0", "--rendering", "dynamic"]).is_err());
    assert!(p(&["--vulkan-api", "1.0", "--rendering", "render-pass2", "--layout", "side-by-side"]).is_ok());
    assert!(p(&["--vulkan-api", "1.1", "--rendering", "dynamic", "--layout", "multiview"]).is_ok());
    assert!(p(&["--secondary"]).unwrap().unwrap().secondary);
    assert!(p(&["--submit2"]).unwrap().unwrap().submit2);
    assert!(p(&["--submit2", "--vulkan-api", "1.1"]).is_err());
    assert!(p(&["--secondary=1"]).is_err());
    assert!(p(&["--secondary", "--bind-before-pass"]).is_err());
}

/// `--dynamic-state` and `--pipeline-library` need Vulkan 1.3.
#[test]
fn dxvk_styles() {
    let o = p(&["--dynamic-state", "--pipeline-library"]).unwrap().unwrap();
    assert!(o.dynamic_state && o.pipeline_library);
    assert!(p(&["--dynamic-state", "--vulkan-api", "1.1"]).is_err());
    assert!(p(&["--pipeline-library", "--vulkan-api", "1.0"]).is_err());
    let o = p(&["--shader-object", "--rendering", "dynamic"]).unwrap().unwrap();
    assert!(o.shader_object && o.dynamic_state);
    assert!(p(&["--shader-object", "--rendering", "render-pass"]).is_err());
    assert!(p(&["--shader-object", "--rendering", "dynamic", "--pipeline-library"]).is_err());
}

/// `--teardown`: the four orders, nothing else.
#[test]
fn teardown_orders() {
    assert_eq!(p(&[]).unwrap().unwrap().teardown, Teardown::Children);
    assert_eq!(p(&["--teardown", "session"]).unwrap().unwrap().teardown, Teardown::Session);
    assert_eq!(p(&["--teardown=instance"]).unwrap().unwrap().teardown, Teardown::Instance);
    assert_eq!(p(&["--teardown", "in-flight"]).unwrap().unwrap().teardown, Teardown::InFlight);
    assert!(p(&["--teardown", "device"]).is_err());
}

/// `--threads` implies `--secondary` and combines with what matters for threading, but not
/// with state bound before the pass (secondaries inherit none).
#[test]
fn threads_imply_secondary() {
    let o = p(&["--threads"]).unwrap().unwrap();
    assert!(o.threads && o.secondary);
    assert!(!p(&[]).unwrap().unwrap().threads);
    assert!(p(&["--threads=1"]).is_err());
    assert!(p(&["--threads", "--thread-hazard"]).unwrap().unwrap().thread_hazard);
    assert!(p(&["--thread-hazard"]).is_err());
    let e = p(&["--threads", "--bind-before-pass"]).unwrap_err();
    assert!(e.contains("--threads"), "{e}");
    for layout in ["per-eye", "multiview", "side-by-side"] {
        let o = p(&["--threads", "--layout", layout, "--record-once", "--sessions", "2", "--frames", "5"]).unwrap().unwrap();
        assert!(o.threads && o.record_once && o.secondary);
    }
}

/// `--record-once` works with every layout, way of starting a pass, secondary contents,
/// intermediate target, animation and Vulkan binding (nothing it needs varies per frame
/// except through memory); only the flag's own misuse is refused.
#[test]
fn record_once_combines_with_everything() {
    assert!(!p(&[]).unwrap().unwrap().record_once);
    for layout in ["per-eye", "multiview", "side-by-side"] {
        for rendering in ["render-pass", "render-pass2", "dynamic"] {
            for extra in [&[][..], &["--secondary"], &["--intermediate"], &["--intermediate", "--samples", "1", "--submit-depth"], &["--animate", "--vulkan", "enable"], &["--bind-before-pass", "--depth-clear", "image"]] {
                let args = [&["--record-once", "--layout", layout, "--rendering", rendering][..], extra].concat();
                let o = p(&args).unwrap_or_else(|e| panic!("{args:?}: {e}")).unwrap();
                assert!(o.record_once, "{args:?}");
            }
        }
    }
    assert!(p(&["--record-once", "--vulkan-api", "1.0", "--secondary"]).unwrap().unwrap().record_once);
    assert!(p(&["--record-once=1"]).is_err());
    assert_eq!(p(&["--record-once", "--rerecord-every", "7"]).unwrap().unwrap().rerecord_every, Some(7));
    assert_eq!(p(&["--record-once"]).unwrap().unwrap().rerecord_every, None);
    let e = p(&["--rerecord-every", "7"]).unwrap_err();
    assert!(e.contains("--record-once"), "{e}");
    assert!(p(&["--record-once", "--rerecord-every", "0"]).is_err());
    assert!(p(&["--record-once", "--rerecord-every"]).is_err());
}

#[test]
fn sync_hazard_needs_draws() {
    assert!(p(&["--sync-hazard"]).unwrap().unwrap().sync_hazard);
    assert!(!p(&[]).unwrap().unwrap().sync_hazard);
    let e = p(&["--sync-hazard", "--empty"]).unwrap_err();
    assert!(e.contains("--empty"), "{e}");
    assert!(p(&["--sync-hazard=yes"]).is_err());
}

#[test]
fn far_field_scene_options() {
    let o = p(&[]).unwrap().unwrap();
    assert_eq!(o.sky, Sky::Geometry);
    assert!(!o.sky_first && !o.translucent && !o.far_movers);
    let o = p(&["--sky", "geometry", "--sky-first", "--translucent", "--far-movers"]).unwrap().unwrap();
    assert_eq!(o.sky, Sky::Geometry);
    assert!(o.sky_first && o.translucent && o.far_movers);
    assert_eq!(p(&["--sky=clear"]).unwrap().unwrap().sky, Sky::Clear);
    assert!(p(&["--sky", "box"]).is_err());
    assert!(p(&["--sky"]).is_err());
    let e = p(&["--sky", "clear", "--sky-first"]).unwrap_err();
    assert!(e.contains("--sky clear"), "{e}");
    assert!(p(&["--translucent=1"]).is_err());
    assert!(p(&["--far-movers=yes"]).is_err());
    assert!(p(&["--sky-first=1"]).is_err());
}

#[test]
fn visibility_mask_flag() {
    assert!(!p(&[]).unwrap().unwrap().visibility_mask);
    assert!(p(&["--visibility-mask"]).unwrap().unwrap().visibility_mask);
    assert!(p(&["--visibility-mask=1"]).is_err());
}

#[test]
fn depth_clear() {
    assert_eq!(p(&["--depth-clear", "attachments"]).unwrap().unwrap().depth_clear, DepthClear::Attachments);
    assert_eq!(p(&["--depth-clear=image"]).unwrap().unwrap().depth_clear, DepthClear::Image);
    assert_eq!(p(&["--depth-clear", "load-op"]).unwrap().unwrap().depth_clear, DepthClear::LoadOp);
    assert!(p(&["--depth-clear", "shader"]).is_err());
    assert!(p(&["--depth-clear"]).is_err());
}

#[test]
fn full_set() {
    let o = p(&[
        "--layout", "multiview", "--rendering=dynamic", "--depth", "reverse", "--intermediate",
        "--vulkan", "enable", "--frames", "5", "--scale", "0.25", "--color-format", "unorm",
        "--shading-cost", "10", "--animate", "--stats", "/tmp/s.json", "--validation",
        "--pixel-stats", "/tmp/px",
    ])
    .unwrap()
    .unwrap();
    assert_eq!(o.layout, Layout::Multiview);
    assert_eq!(o.rendering, Rendering::Dynamic);
    assert_eq!(o.depth, DepthMode::Reverse);
    assert!(o.intermediate && o.animate && o.validation);
    let layers = p(&["--vk-layer", "A", "--vk-layer=B"]).unwrap().unwrap();
    assert_eq!(layers.vk_layers, ["A", "B"]);
    assert_eq!(o.samples, 4);
    assert_eq!(o.vulkan, VulkanPath::Enable);
    assert_eq!(o.frames, Some(5));
    assert_eq!(o.scale, 0.25);
    assert_eq!(o.shading_cost, 10);
    assert_eq!(o.stats.as_deref(), Some(std::path::Path::new("/tmp/s.json")));
    assert_eq!(o.pixel_stats.as_deref(), Some(std::path::Path::new("/tmp/px")));
    assert_eq!(p(&[]).unwrap().unwrap().pixel_stats, None);
}

/// An option given twice takes its last value (the harness appends a test's own arguments to
/// its defaults); a repeatable one (`--vk-layer`) collects them all.
#[test]
fn last_value_wins() {
    assert_eq!(p(&["--scale", "0.5", "--scale", "0.25"]).unwrap().unwrap().scale, 0.25);
    assert_eq!(p(&["--layout", "multiview", "--layout=side-by-side"]).unwrap().unwrap().layout, Layout::SideBySide);
    assert!(p(&["--secondary", "--secondary"]).unwrap().unwrap().secondary);
    assert_eq!(p(&["--vk-layer", "A", "--vk-layer", "B"]).unwrap().unwrap().vk_layers, ["A", "B"]);
}

#[test]
fn errors() {
    assert!(p(&["--layout", "quad"]).is_err());
    assert!(p(&["--layout"]).is_err());
    assert!(p(&["--bogus"]).is_err());
    assert!(p(&["--scale", "-1"]).is_err());
    assert!(p(&["--frames", "0"]).is_err());
    assert!(p(&["--sessions", "0"]).is_err());
    assert_eq!(p(&["--sessions", "3"]).unwrap().map(|o| o.sessions), Some(3));
    assert!(p(&["--samples", "3", "--intermediate"]).is_err());
    assert!(p(&["--samples", "4"]).is_err());
    assert!(p(&["--submit-depth", "--intermediate"]).is_err());
    assert!(p(&["--submit-depth", "--intermediate", "--samples", "1"]).is_ok());
    assert!(p(&["--submit-depth"]).is_ok());
    assert_eq!(p(&["--help"]).unwrap(), None);
}

/// `--submit-via openvr` copies a texture of the app's, every frame.
#[test]
fn openvr_submission() {
    assert_eq!(p(&[]).unwrap().unwrap().submit_via, SubmitVia::App);
    let o = p(&["--submit-via", "openvr", "--intermediate"]).unwrap().unwrap();
    assert_eq!(o.submit_via, SubmitVia::Openvr);
    assert!(p(&["--submit-via", "openvr", "--layout", "side-by-side", "--submit-texture", "double-wide"]).is_ok());
    assert!(p(&["--submit-via", "openvr"]).is_err());
    assert!(p(&["--submit-via", "openvr", "--intermediate", "--record-once"]).is_err());
}

/// `--temporary-session`: any shape (it comes before the app's device).
#[test]
fn temporary_session() {
    assert!(!p(&[]).unwrap().unwrap().temporary_session);
    assert!(p(&["--temporary-session", "--submit-via", "openvr", "--intermediate", "--vulkan", "enable"]).unwrap().unwrap().temporary_session);
}

/// `--one-target`: per eye, through one intermediate copied by the app between the eyes.
#[test]
fn one_target_for_both_eyes() {
    assert!(p(&["--one-target", "--intermediate"]).unwrap().unwrap().one_target);
    assert!(p(&["--one-target"]).is_err());
    assert!(p(&["--one-target", "--intermediate", "--layout", "multiview"]).is_err());
    assert!(p(&["--one-target", "--intermediate", "--submit-via", "openvr"]).is_err());
    // Behind a drawn post chain: each eye's chain runs before the other eye renders.
    for post in ["tonemap", "bloom"] {
        assert!(p(&["--one-target", "--post", post]).unwrap().unwrap().one_target, "{post}");
        assert!(p(&["--one-target", "--post", post, "--samples", "4"]).unwrap().unwrap().one_target, "{post}");
    }
    assert!(p(&["--one-target", "--post", "taa"]).is_err(), "one history per eye");
    assert!(p(&["--one-target", "--post", "tonemap", "--post-compute"]).is_err());
    assert!(p(&["--one-target", "--post", "tonemap", "--post-subpass"]).is_err());
    assert!(p(&["--one-target", "--post", "tonemap", "--layout", "side-by-side"]).is_err());
}

/// `--eye-swapchain array`: per-eye passes into the layers of one 2-layer swapchain.
#[test]
fn eye_swapchain_array() {
    assert_eq!(p(&[]).unwrap().unwrap().eye_swapchain, EyeSwapchain::PerEye);
    let array = |extra: &[&str]| p(&[&["--eye-swapchain", "array"][..], extra].concat());
    assert_eq!(array(&[]).unwrap().unwrap().eye_swapchain, EyeSwapchain::Array);
    for ok in [
        &["--intermediate"][..],
        &["--intermediate", "--samples", "1"],
        &["--intermediate", "--one-target"],
        &["--post", "tonemap", "--one-target"],
        &["--post", "bloom", "--samples", "4", "--one-target"],
        &["--post", "bloom"],
    ] {
        assert_eq!(array(ok).unwrap().unwrap().eye_swapchain, EyeSwapchain::Array, "{ok:?}");
    }
    for layout in ["multiview", "side-by-side"] {
        let e = array(&["--layout", layout]).unwrap_err();
        assert!(e.contains("needs --layout per-eye"), "{layout}: {e}");
    }
    for (refused, name) in [
        (&["--intermediate", "--submit-via", "openvr"][..], "--submit-via openvr"),
        (&["--submit-depth"], "--submit-depth"),
        (&["--post", "taa"], "--post taa"),
        (&["--post", "tonemap", "--post-compute"], "--post-compute"),
        (&["--post", "tonemap", "--post-subpass"], "--post-subpass"),
        (&["--threads"], "--threads"),
        (&["--secondary"], "--secondary"),
        (&["--record-once"], "--record-once"),
        (&["--swapchain-samples", "4"], "--swapchain-samples"),
    ] {
        let e = array(refused).unwrap_err();
        assert!(e.contains(&format!("not supported with {name}")), "{refused:?}: {e}");
    }
    assert!(p(&["--eye-swapchain", "both"]).is_err());
}
