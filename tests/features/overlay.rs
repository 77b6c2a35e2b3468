//! The in-headset stats overlay (`overlay.enabled`, src/xr/overlay.rs) on the mock runtime, which
//! captures quad layers (docs/testing.md): the app's own layers reach the runtime bit-identical,
//! one quad follows them in a VIEW space where the settings put it, its text is the layer's
//! rasterisation of what is on (and, once a second completed, of what it saved), the system's
//! `maxLayerCount` is respected, and the overlay's objects die with each session.

use crate::common;

use common::image::{self, Image};
use common::{assert_nothing_tracked, fault_layer_data_dir, Half, Run, RunOutput, FAULT_LAYER};
use stereoshim::features::overlay::rules;
use std::collections::BTreeMap;
use std::time::Duration;

/// `XR_COMPOSITION_LAYER_BLEND_TEXTURE_SOURCE_ALPHA_BIT`.
const BLEND_TEXTURE_SOURCE_ALPHA: u64 = 2;

fn with_overlay(run: Run, name: &str) -> Run {
    let mut run = run.env("STEREOSHIM_OVERLAY_ENABLED", "1");
    run.name = name.into();
    run
}

/// The image the layer draws for `lines`, as the runtime's capture stores it (RGB, alpha dropped;
/// a BGRA swapchain is reordered by the capture, so the RGBA rasterisation is what it shows).
fn expected(lines: &[String]) -> Image {
    let (w, h) = rules::texture_size();
    let data = rules::rasterise(lines, &[], false).chunks(4).flat_map(|p| [p[0], p[1], p[2]]).map(u16::from).collect();
    Image { width: w, height: h, channels: 3, bit_depth: 8, data }
}

/// Texels of the text colour.
fn ink(img: &Image) -> usize {
    img.data.chunks(img.channels as usize).filter(|p| p.iter().all(|&c| c == 255)).count()
}

/// Asserts that every captured frame of `on` is `off`'s layers plus one quad, last, and that the
/// app's projection views are bit-identical; returns the quads, by frame.
fn quads<'a>(label: &str, on: &'a RunOutput, off: &RunOutput) -> Vec<(u64, &'a common::Quad)> {
    let (a, b) = (on.frames(), off.frames());
    let numbers = |f: &common::Frames| f.frames.iter().map(|x| x.frame).collect::<Vec<_>>();
    assert_eq!(numbers(a), numbers(b), "{label}: captured frames differ");
    assert!(!a.frames.is_empty(), "{label}: nothing captured");
    let mut out = Vec::new();
    for (fa, fb) in a.frames.iter().zip(&b.frames) {
        let kinds = |f: &common::Frame| f.layers.iter().map(|l| l.kind.clone()).collect::<Vec<_>>();
        assert!(kinds(fb).iter().all(|k| k == "projection") && !fb.layers.is_empty(), "{label}: without the overlay: {:?}", kinds(fb));
        let mut want = kinds(fb);
        want.push("quad".into());
        assert_eq!(kinds(fa), want, "{label}: frame {}: the overlay's quad is not the one layer after the app's", fa.frame);
        for (li, (la, lb)) in fa.layers.iter().zip(&fb.layers).enumerate() {
            assert_eq!((la.space.as_str(), la.layer_flags, la.views.len()), (lb.space.as_str(), lb.layer_flags, lb.views.len()), "{label}: layer {li}");
            for (va, vb) in la.views.iter().zip(&lb.views) {
                assert_eq!((va.image_rect, va.pose.position, va.fov.angle_left), (vb.image_rect, vb.pose.position, vb.fov.angle_left));
                image::assert_identical(&format!("{label}-f{}-layer{li}-view{}", fa.frame, va.view), &on.image(&va.file), &off.image(&vb.file));
            }
        }
        let last = fa.layers.last().unwrap();
        assert_eq!((last.space.as_str(), last.layer_flags), ("VIEW", BLEND_TEXTURE_SOURCE_ALPHA), "{label}");
        out.push((fa.frame, last.quad.as_ref().unwrap_or_else(|| panic!("{label}: a quad layer without its capture"))));
    }
    out
}

#[test]
fn the_overlay_is_one_head_locked_quad_after_the_apps_unchanged_layers() {
    let base = Run::new("overlay-off").with_layer().env("STEREOSHIM_MASK_ENABLED", "1");
    let off = base.run();
    off.assert_ok();
    let on = with_overlay(base.clone(), "overlay-on").run();
    on.assert_ok().assert_layer_loaded(Half::Both).assert_log_lacks(Half::Both, "internal failure");
    let mask_quads = quads("overlay-mask", &on, &off);
    let (w, h) = rules::texture_size();
    let want = rules::placement(rules::Position::Top, 1.0, 1.0);
    let first = expected(&rules::lines(&[("mask", true)], None, None));
    assert!(ink(&first) > 500, "the expected text has ink");
    for (frame, q) in &mask_quads {
        assert_eq!((q.image_rect.width, q.image_rect.height, q.eye_visibility), (w, h, 0), "frame {frame}");
        assert_eq!(q.pose.orientation, [0.0, 0.0, 0.0, 1.0]);
        let p = q.pose.position;
        assert!((p[0] - want.position.x).abs() < 1e-6 && (p[1] - want.position.y).abs() < 1e-6 && (p[2] - want.position.z).abs() < 1e-6, "frame {frame}: {p:?}");
        assert!(p[1] > 0.3, "top of the view: {p:?}");
        assert!((q.size[0] - want.width_m).abs() < 1e-6 && (q.size[1] - want.height_m).abs() < 1e-6, "{:?}", q.size);
        // Both frames of this short run show the features on (no second has completed).
        image::assert_identical(&format!("overlay-text-f{frame}"), &on.image(&q.file), &first);
    }
    assert_eq!(on.log_lines("overlay: objects of session").len(), 1, "{}", on.log);
    assert_nothing_tracked(&on);

    // What is on is what it says: without the mask the first line differs, and is the layer's
    // rasterisation of "on: -".
    let plain = Run::new("overlay-plain-off").with_layer();
    let plain_off = plain.run();
    let plain_on = with_overlay(plain, "overlay-plain-on").run();
    plain_on.assert_ok();
    let (_, q) = quads("overlay-plain", &plain_on, &plain_off)[0];
    let shown = plain_on.image(&q.file);
    image::assert_identical("overlay-text-nothing-on", &shown, &expected(&rules::lines(&[], None, None)));
    assert!(shown.count_different(&first) > 50, "the text does not change with the mask");
}

#[test]
fn the_text_shows_the_last_second_once_one_completed() {
    // Paced at 60 Hz for 90 frames: at least 1.5 s, so the text is redrawn with the first second.
    let base = Run::new("overlay-second-off")
        .with_layer()
        .env("STEREOSHIM_MASK_ENABLED", "1")
        .env("MOCK_XR_PACE_HZ", "60")
        .env("MOCK_XR_EXIT_AFTER", "90")
        .env("MOCK_XR_CAPTURE_FRAMES", "0,89");
    let on = with_overlay(base.clone(), "overlay-second")
        .env("STEREOSHIM_OVERLAY_POSITION", "bottom")
        .env("STEREOSHIM_OVERLAY_DISTANCE", "2")
        .run();
    on.assert_ok();
    assert!(on.elapsed > Duration::from_millis(1400), "{:?}", on.elapsed);
    let off = base.run();
    off.assert_ok();
    let second_quads = quads("overlay-second", &on, &off);
    assert_eq!(second_quads.len(), 2);
    let want = rules::placement(rules::Position::Bottom, 2.0, 1.0);
    for (_, q) in &second_quads {
        assert!((q.pose.position[1] - want.position.y).abs() < 1e-6 && q.pose.position[1] < -0.7 && q.pose.position[2] == -2.0, "{:?}", q.pose);
    }
    let (first, last) = (on.image(&second_quads[0].1.file), on.image(&second_quads[1].1.file));
    image::assert_identical("overlay-second-f0", &first, &expected(&rules::lines(&[("mask", true)], None, None)));
    // The features line stays; the second line now has frame numbers, and two more lines appear.
    let (w, _) = rules::texture_size();
    let rows = |img: &Image, from: u32, to: u32| img.data[(from * w * 3) as usize..(to * w * 3) as usize].to_vec();
    assert_eq!(rows(&first, 0, 14), rows(&last, 0, 14), "the features line changed");
    assert!(ink(&last) > ink(&first) + 300, "no more text after a second: {} vs {}", ink(&last), ink(&first));
    let third_line = |img: &Image| rows(img, 24, 32).iter().filter(|&&c| c == 255).count();
    assert_eq!(third_line(&first), 0);
    assert!(third_line(&last) > 50, "the savings line is empty");
    // Kept for a person to look at (docs/images/overlay.png is one of these).
    image::Image::save(&last, &image::artifacts_dir("overlay").join("overlay-after-one-second.png"));
}

#[test]
fn no_room_for_the_overlay_when_the_app_uses_every_layer() {
    let base = Run::new("overlay-full-off").with_layer().env("MOCK_XR_MAX_LAYERS", "1");
    let off = base.run();
    off.assert_ok();
    let on = with_overlay(base, "overlay-full").run();
    on.assert_ok();
    for (fa, fb) in on.frames().frames.iter().zip(&off.frames().frames) {
        assert_eq!(fa.layers.len(), 1, "frame {}: the overlay went past maxLayerCount", fa.frame);
        assert_eq!(fa.layers[0].kind, fb.layers[0].kind);
    }
    common::assert_same_captures("overlay-full", &on, &off);
    assert_eq!(on.log_lines("no room for the overlay").len(), 1, "said once: {}", on.log);
}

/// (layer, app) live objects per kind, after each session, from the fault layer below stereoshim
/// (as tests/hardening/vk_objects.rs reads them).
fn counts_after_sessions(out: &RunOutput) -> Vec<BTreeMap<String, u64>> {
    let mut after = Vec::new();
    let mut last = None;
    for l in out.stderr.lines() {
        if let Some(rest) = l.strip_prefix("vk-fault-layer: live objects at vkDeviceWaitIdle:") {
            let layer = rest.split(" app ").next().unwrap_or("").trim().strip_prefix("layer").unwrap_or("").to_string();
            let m = layer.split_whitespace().map(|w| w.split_once('=').unwrap_or_else(|| panic!("{l}"))).map(|(k, v)| (k.to_string(), v.parse().unwrap())).collect();
            last = Some(m);
        } else if l.starts_with("xr-scene: session ") {
            after.push(last.take().unwrap_or_else(|| panic!("no vkDeviceWaitIdle line before {l:?}")));
        }
    }
    after
}

#[test]
fn the_overlays_objects_go_with_each_session() {
    let data = fault_layer_data_dir();
    let base = Run::new("overlay-sessions-off")
        .with_layer()
        .args(["--sessions", "3", "--frames", "3", "--vk-layer", FAULT_LAYER])
        .env("MOCK_XR_EXIT_AFTER", "1000")
        .env("MOCK_XR_CAPTURE_FRAMES", "0")
        .env("VK_FAULT_COUNT", "1")
        .env("XDG_DATA_DIRS", &format!("{}:/usr/local/share:/usr/share", data.display()));
    let off = base.run_while(Duration::from_secs(120), |_| {});
    off.assert_ok();
    let on = with_overlay(base, "overlay-sessions").run_while(Duration::from_secs(120), |_| {});
    on.assert_ok().assert_log_lacks(Half::Both, "internal failure");
    let (a, b) = (counts_after_sessions(&on), counts_after_sessions(&off));
    assert_eq!((a.len(), b.len()), (3, 3), "{}", on.stderr);
    // After every session the layer holds exactly what it holds without the overlay: the
    // overlay's buffer, memory, command pool and fence were destroyed with each session.
    assert_eq!(a, b, "the overlay's objects outlive their session");
    assert_eq!(on.log_lines("overlay: objects of session").len(), 3, "{}", on.log);
    assert_eq!(on.log_lines("overlay: 392x92 swapchain").len(), 3, "one overlay per session: {}", on.log);
    assert_nothing_tracked(&on);
}

/// An app that leaves its session to `xrDestroyInstance` (and destroys its device after it): the
/// overlay's Vulkan objects still go first, while the device lives (validation would report them
/// alive at `vkDestroyDevice` otherwise).
#[test]
fn the_overlays_objects_go_with_an_instance_destroyed_first() {
    let on = with_overlay(Run::new("overlay-teardown").with_layer().args(["--teardown", "instance"]), "overlay-teardown").run();
    on.assert_ok().assert_log_lacks(Half::Both, "internal failure");
    assert_eq!(on.log_lines("overlay: 392x92 swapchain").len(), 1, "{}", on.log);
    assert_eq!(on.log_lines("overlay: objects of session").len(), 1, "{}", on.log);
    assert_nothing_tracked(&on);
}

/// What `stereoshim top` shows, the overlay shows too: the frame-time graph under the text, and
/// the last A/B's speed-up that `top` left for the app (`core::live::ab_file`), with the key
/// that hides the panel.
#[test]
fn the_overlay_shows_the_frame_time_graph_and_the_last_ab() {
    let ab = "mask: 1.31x (1.28-1.35 over 4 cycles), 9.10 -> 6.95 ms";
    let base = Run::new("overlay-top-off")
        .with_layer()
        .env("STEREOSHIM_MASK_ENABLED", "1")
        .env("MOCK_XR_PACE_HZ", "60")
        .env("MOCK_XR_EXIT_AFTER", "150")
        .env("MOCK_XR_CAPTURE_FRAMES", "0,149");
    let mut written = false;
    let on = with_overlay(base, "overlay-top").run_while(common::DEFAULT_CPU_BUDGET, |dir| {
        let live = dir.join("run/stereoshim/live");
        if written {
            return;
        }
        let pid = std::fs::read_dir(&live).ok().and_then(|r| r.flatten().find_map(|e| stereoshim::core::live::announced_pid(e.file_name().to_str()?)));
        if let Some(pid) = pid {
            std::fs::write(stereoshim::core::live::ab_file(&live, pid), format!("{ab}\n")).unwrap();
            written = true;
        }
    });
    on.assert_ok();
    assert!(written, "the app never announced itself");
    let frame = on.frames().frames.last().unwrap();
    let q = frame.layers.last().and_then(|l| l.quad.as_ref()).expect("the overlay's quad");
    let shown = on.image(&q.file);
    let (w, h) = rules::texture_size();
    // The last two text lines: the A/B and the key, as the layer rasterises them.
    let want = expected(&rules::lines(&[("mask", true)], None, Some(ab)));
    let rows = |img: &Image, from: u32, to: u32| img.data[(from * w * 3) as usize..(to * w * 3) as usize].to_vec();
    let (ab_top, ab_bottom) = (4 + 4 * 10, 4 + 6 * 10);
    assert_eq!(rows(&shown, ab_top, ab_bottom), rows(&want, ab_top, ab_bottom), "the A/B line or the key line differs");
    // The graph: bars of the frames' times across the panel's width, in the graph's colour.
    let bars: Vec<u32> = (0..w)
        .map(|x| (ab_bottom..h).filter(|&y| { let i = ((y * w + x) * 3) as usize; shown.data[i..i + 3] == [64, 200, 96] }).count() as u32)
        .collect();
    let columns = bars.iter().filter(|&&b| b > 0).count();
    assert!(columns > 200, "the graph has {columns} columns of bars: {bars:?}");
    assert!(bars.contains(&rules::GRAPH_HEIGHT), "the tallest bar fills the graph");
    image::Image::save(&shown, &image::artifacts_dir("overlay").join("overlay-graph-and-ab.png"));
}
