//! An app that draws the hidden-area mesh itself (as many OpenVR games draw
//! `IVRSystem::GetHiddenAreaMesh`, which xrizer answers from `xrGetVisibilityMaskKHR`), under the
//! layer's own mask (xr-scene `--draw-hidden-area`): the picture stays the app's, and the layer's
//! mask adds no shaded fragment anywhere. Its draw has no fragment shader, and it lies at the
//! depth the app's mesh is then rejected at by the early depth test, so the app's own mask
//! fragments are what the layer's saves.

use crate::common;

use common::{Half, Run, RunOutput};

const FRAMES: u64 = 3;

fn shaded(out: &RunOutput, frame: u64, view: u32) -> u64 {
    let stats = out.stats.as_ref().unwrap_or_else(|| panic!("{}: no stats", out.name));
    let f = stats.frames.iter().find(|f| f.frame == frame).unwrap_or_else(|| panic!("{}: no stats for frame {frame}", out.name));
    f.views.iter().find(|v| v.view == view).unwrap_or_else(|| panic!("{}: frame {frame} has no view {view}", out.name)).shaded_fragments
}

fn count(out: &RunOutput, key: &str) -> u64 {
    let stats = out.log_lines("vulkan device stats:").join("\n");
    stats.split_whitespace().find_map(|w| w.strip_prefix(key)).and_then(|v| v.parse().ok()).unwrap_or(0)
}

/// Runs `args` as the app alone, the app drawing its mesh, and that under the layer's mask, and
/// checks what the app shows and what each pixel shades.
fn check(name: &str, args: &[&str], passes_per_frame: u64) {
    let base = Run::new(&format!("{name}-scene")).args(args.iter().copied()).env("MOCK_XR_EXIT_AFTER", &FRAMES.to_string()).pixel_stats();
    let scene = base.clone().run();
    scene.assert_ok();
    let mut app = base.clone().args(["--draw-hidden-area"]);
    app.name = format!("{name}-app");
    let app = app.run();
    app.assert_ok();
    let mut both = base.args(["--draw-hidden-area"]).with_layer().env("STEREOSHIM_MASK_ENABLED", "1");
    both.name = format!("{name}-both");
    let both = both.run();
    both.assert_ok();
    both.assert_log_lacks(Half::Both, "internal failure");
    assert_eq!(count(&both, "masked_passes="), passes_per_frame * (FRAMES - 1), "{name}: every eye pass after frame 0 is masked:\n{}", both.log);

    // The app's mask is the runtime's mesh, the layer's too: what the runtime gets is the same.
    common::assert_same_captures(name, &both, &app);
    for frame in 1..FRAMES {
        for view in 0..2 {
            let (s, a, b) = (shaded(&scene, frame, view), shaded(&app, frame, view), shaded(&both, frame, view));
            // Drawing its own mask already saves the app the scene behind it...
            assert!(a < s, "{name}: frame {frame} view {view}: the app's own mask shades {a} fragments, the scene alone {s}");
            // ... and the layer's mask under it shades nothing: the app's mask fragments are gone.
            assert!(b < a, "{name}: frame {frame} view {view}: with the layer's mask too {b} fragments, the app's mask alone {a}");
            let (pa, pb) = (app.pixel_counts(frame, view), both.pixel_counts(frame, view));
            assert_eq!(pa.len(), pb.len(), "{name}: frame {frame} view {view}: pixel counts of another size");
            let more: Vec<usize> = (0..pa.len()).filter(|&i| pb[i] > pa[i]).collect();
            assert!(more.is_empty(), "{name}: frame {frame} view {view}: {} pixels shade more with the layer's mask than with the app's alone (first at index {})", more.len(), more[0]);
            // The saving is the app's mask: pixels where it shaded once and nothing else did.
            let saved = (0..pa.len()).filter(|&i| pb[i] < pa[i]).count() as u64;
            assert_eq!(a - b, (0..pa.len()).map(|i| (pa[i] - pb[i]) as u64).sum::<u64>(), "{name}: frame {frame} view {view}: counters and per-pixel counts disagree");
            assert!(saved > 0, "{name}: frame {frame} view {view}: no pixel saved");
        }
    }
}

#[test]
fn app_drawn_mask_per_eye_render_pass() {
    check("app-mask-per-eye", &["--layout", "per-eye", "--rendering", "render-pass"], 2);
}

#[test]
fn app_drawn_mask_multiview_dynamic() {
    check("app-mask-multiview", &["--layout", "multiview", "--rendering", "dynamic"], 1);
}

#[test]
fn app_drawn_mask_reversed_depth_side_by_side() {
    check("app-mask-sbs-reversed", &["--layout", "side-by-side", "--rendering", "render-pass2", "--depth", "reverse"], 1);
}

/// A runtime without `XR_KHR_visibility_mask`: the layer offers it, so the app that draws the
/// mesh itself (an OpenVR game's `GetHiddenAreaMesh` through xrizer) gets the lens the layer
/// knows, and draws the same area the layer masks.
#[test]
fn app_drawn_mask_from_the_layers_offered_extension() {
    let base = Run::new("app-mask-offered")
        .args(["--layout", "per-eye", "--draw-hidden-area"])
        .env("MOCK_XR_EXIT_AFTER", &FRAMES.to_string())
        .env("MOCK_XR_DISABLE_EXTENSIONS", "XR_KHR_visibility_mask")
        // A headset whose lens the layer knows (for an unnamed one it synthesizes a circle that
        // hides nothing inside the view).
        .env("MOCK_XR_HMD", "index");
    // Without the layer the app cannot have the mesh.
    let without = base.clone().run();
    assert_ne!(without.code, Some(0), "the app drew a mask the runtime does not offer:\n{}", without.stderr);
    assert!(without.stderr.contains("XR_KHR_visibility_mask"), "{}", without.stderr);
    let mut app = base.clone().with_layer();
    app.name = "app-mask-offered-app".into();
    let app = app.run();
    app.assert_ok();
    let mut both = base.with_layer().env("STEREOSHIM_MASK_ENABLED", "1");
    both.name = "app-mask-offered-both".into();
    let both = both.run();
    both.assert_ok();
    assert!(app.stderr.contains("visibility mask view 1:"), "{}", app.stderr);
    common::assert_same_captures("app-mask-offered", &both, &app);
    assert!(count(&both, "masked_pixels=") > 0, "{}", both.log);
    for frame in 1..FRAMES {
        for view in 0..2 {
            assert!(shaded(&both, frame, view) < shaded(&app, frame, view), "frame {frame} view {view}");
        }
    }
}
