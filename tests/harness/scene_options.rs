//! End-to-end checks of the test ground's far-field scene options (issue 10's test vehicle):
//! xr-scene's `--sky`, `--sky-first`, `--translucent`, `--far-movers` and the mock runtime's
//! `MOCK_XR_HEAD_YAW_DEG_PER_S`, through the mock runtime, no layer (tests/harness/xr_scene.rs checks the
//! rest of the test ground).

use crate::common;

use common::image::Image;
use common::{assert_same_captures, assert_same_colour_captures, assert_same_stats, project, Run};

/// Centre of the red near cube (docs/testing.md).
const NEAR_CUBE: [f32; 3] = [0.0, 1.45, -1.5];

/// The captured frame the checks look at (frame 0 is captured too; 1 shows steady state).
const FRAME: u64 = 1;

/// xr-scene's `--translucent` pane (scene::PANE_MIN / PANE_MAX): a quad at z = −2.5.
const PANE: [[f32; 3]; 4] = [[-1.4, 1.25, -2.5], [-0.55, 1.25, -2.5], [-0.55, 1.95, -2.5], [-1.4, 1.95, -2.5]];
/// xr-scene's `--far-movers` box (scene::MOVER_CENTRE, MOVER_SIZE, MOVER_RAD_PER_FRAME).
const MOVER_CENTRE: [f32; 3] = [0.0, 40.0, -250.0];
const MOVER_SIZE: f32 = 20.0;
const MOVER_RAD_PER_FRAME: f32 = 0.01;

/// The pixel box (x0, y0, x1, y1, inclusive, clamped to the image) that holds the projections
/// of `points` grown by `margin` pixels; every point must be in the view.
fn pixel_box(view: &common::View, points: &[[f32; 3]], margin: f32) -> (u32, u32, u32, u32) {
    let (mut x0, mut y0, mut x1, mut y1) = (f32::MAX, f32::MAX, f32::MIN, f32::MIN);
    for &p in points {
        let (x, y) = project(view, p).unwrap_or_else(|| panic!("view {}: {p:?} outside the view", view.view));
        (x0, y0, x1, y1) = (x0.min(x), y0.min(y), x1.max(x), y1.max(y));
    }
    let (w, h) = (view.image_rect.width as f32, view.image_rect.height as f32);
    let clamp = |v: f32, hi: f32| v.clamp(0.0, hi - 1.0) as u32;
    (clamp((x0 - margin).floor(), w), clamp((y0 - margin).floor(), h), clamp((x1 + margin).ceil(), w), clamp((y1 + margin).ceil(), h))
}

/// Pixels where two images differ, as (x, y).
fn differing_pixels(a: &Image, b: &Image) -> Vec<(u32, u32)> {
    assert_eq!((a.width, a.height), (b.width, b.height));
    let mut out = Vec::new();
    for y in 0..a.height {
        for x in 0..a.width {
            if a.pixel(x, y) != b.pixel(x, y) {
                out.push((x, y));
            }
        }
    }
    out
}

fn inside(p: (u32, u32), b: (u32, u32, u32, u32)) -> bool {
    p.0 >= b.0 && p.0 <= b.2 && p.1 >= b.1 && p.1 <= b.3
}

/// The mover's 8 corners at `frame` (rotated about +y as glam's `Mat4::from_rotation_y`).
fn mover_corners(frame: u64) -> Vec<[f32; 3]> {
    let a = frame as f32 * MOVER_RAD_PER_FRAME;
    let (s, c) = a.sin_cos();
    let h = MOVER_SIZE / 2.0;
    let mut out = Vec::new();
    for dx in [-h, h] {
        for dy in [-h, h] {
            for dz in [-h, h] {
                let [x, y, z] = [MOVER_CENTRE[0] + dx, MOVER_CENTRE[1] + dy, MOVER_CENTRE[2] + dz];
                out.push([c * x + s * z, y, -s * x + c * z]);
            }
        }
    }
    out
}

/// Every new scene option renders deterministically: two runs give identical captures and
/// shaded-fragment counts, in every layout (the options together) and per option (per-eye).
/// Validation (synchronization included) stays silent throughout.
#[test]
fn far_field_options_are_deterministic() {
    let mut cases: Vec<(String, Vec<&str>)> = vec![
        ("sky-clear".into(), vec!["--sky", "clear"]),
        ("sky-first".into(), vec!["--sky-first"]),
        ("translucent".into(), vec!["--translucent"]),
        ("far-movers".into(), vec!["--far-movers"]),
    ];
    for layout in ["per-eye", "multiview", "side-by-side"] {
        cases.push((format!("all-{layout}"), vec!["--layout", layout, "--sky-first", "--translucent", "--far-movers"]));
    }
    for (name, args) in cases {
        let run = |tag: &str| {
            let out = Run::new(&format!("far-field-det-{name}{tag}")).args(args.iter().copied()).run();
            out.assert_ok();
            out
        };
        let (a, b) = (run(""), run("-again"));
        assert_same_captures(&format!("far-field-det-{name}"), &a, &b);
        assert_same_stats(&format!("far-field-det-{name}"), &a, &b);
    }
}

/// The sky drawn first in each eye pass (own draw, depth test and depth write off) and then
/// covered by the depth-tested scene gives the same pixels as the sky drawn last and
/// depth-tested, bit for bit: every pixel ends up with the nearest scenery or, where there is
/// none, the sky, and no sky fragment ever wrote depth the scene could fail against. Holds per
/// sample, so also with a multisampled intermediate target. `--sky geometry` is the default.
/// Only the shaded-fragment counts differ (the sky is shaded under the scenery too).
#[test]
fn sky_first_matches_sky_last() {
    for (layout, depth, extra) in [
        ("per-eye", "standard", &[][..]),
        ("multiview", "reverse", &[][..]),
        ("side-by-side", "standard", &["--rendering", "dynamic"][..]),
        ("per-eye", "reverse", &["--intermediate", "--samples", "4"][..]),
    ] {
        let tag = format!("{layout}-{depth}{}", extra.join(""));
        let run = |name: &str, args: &[&str]| {
            let out = Run::new(&format!("sky-first-{tag}-{name}"))
                .args(["--layout", layout, "--depth", depth])
                .args(extra.iter().copied())
                .args(args.iter().copied())
                .run();
            out.assert_ok();
            out
        };
        let last = run("last", &[]);
        let explicit = run("geometry", &["--sky", "geometry"]);
        assert_same_captures(&format!("sky-geometry-{tag}"), &explicit, &last);
        assert_same_stats(&format!("sky-geometry-{tag}"), &explicit, &last);
        let first = run("first", &["--sky-first"]);
        assert_same_captures(&format!("sky-first-{tag}"), &first, &last);
        // And with the other options, which draw after the sky either way.
        let both = ["--translucent", "--far-movers"];
        let last_all = run("last-all", &both);
        let first_all = run("first-all", &[&both[..], &["--sky-first"]].concat());
        assert_same_captures(&format!("sky-first-all-{tag}"), &first_all, &last_all);
    }
}

/// `--sky clear`: where only sky was, the clear colour (black) shows; the scenery is unchanged.
#[test]
fn sky_clear_leaves_the_clear_colour() {
    let sky = Run::new("sky-clear-geometry").run();
    sky.assert_ok();
    let clear = Run::new("sky-clear-clear").args(["--sky", "clear"]).run();
    clear.assert_ok();
    for (a, b) in sky.views(FRAME).iter().zip(clear.views(FRAME)) {
        let (with, without) = (sky.image(&a.file), clear.image(&b.file));
        let black = |img: &Image, x: u32, y: u32| img.pixel(x, y).iter().all(|&c| c == 0);
        let (w, h) = (with.width, with.height);
        assert!(black(&without, w / 2, 1), "view {}: top centre not at the clear colour", a.view);
        // Every pixel that changed is now black (the sky was all it had), and the cube stays.
        for (x, y) in differing_pixels(&with, &without) {
            assert!(black(&without, x, y), "view {}: ({x},{y}) changed but is not the clear colour", a.view);
        }
        let (cx, cy) = project(a, NEAR_CUBE).unwrap();
        assert_eq!(with.pixel(cx as u32, cy as u32), without.pixel(cx as u32, cy as u32));
        assert!(!black(&without, w / 2, h - 2), "view {}: ground gone", a.view);
    }
}

/// `--translucent` changes pixels only where its pane projects (its projected corners' box, a
/// pixel of margin), and most of that box; the pane lies over the far field (its top row of
/// pixels over sky or far scenery). Per layout, since the pane is drawn per pass.
#[test]
fn translucent_changes_only_its_pixels() {
    for layout in ["per-eye", "multiview", "side-by-side"] {
        let base = Run::new(&format!("translucent-{layout}-off")).args(["--layout", layout]).run();
        base.assert_ok();
        let pane = Run::new(&format!("translucent-{layout}-on")).args(["--layout", layout, "--translucent"]).run();
        pane.assert_ok();
        for (a, b) in base.views(FRAME).iter().zip(pane.views(FRAME)) {
            let name = format!("translucent-{layout} view {}", a.view);
            let (off, on) = (base.image(&a.file), pane.image(&b.file));
            let bx = pixel_box(a, &PANE, 1.0);
            let changed = differing_pixels(&off, &on);
            let outside: Vec<_> = changed.iter().filter(|&&p| !inside(p, bx)).collect();
            assert!(outside.is_empty(), "{name}: {} pixels changed outside the pane's box {bx:?}: {:?}", outside.len(), &outside[..outside.len().min(8)]);
            let area = ((bx.2 - bx.0 + 1) * (bx.3 - bx.1 + 1)) as usize;
            assert!(changed.len() * 2 > area, "{name}: only {} of the box's {area} pixels changed", changed.len());
            // Blended, not opaque: the same background under the pane shows through, so two
            // different background colours stay different under it.
            let inner = pixel_box(a, &PANE, -2.0);
            let top = (inner.0..=inner.2).map(|x| on.pixel(x, inner.1).to_vec()).collect::<std::collections::HashSet<_>>();
            assert!(top.len() > 1, "{name}: the pane's top row is one colour: not translucent");
        }
    }
}

/// `--far-movers`: the far box moves with the frame number (frames 0 and 1 differ) and changes
/// only the pixels of its projected boxes at those frames.
#[test]
fn far_mover_moves_with_the_frame_number() {
    let base = Run::new("far-movers-off").run();
    base.assert_ok();
    let moving = Run::new("far-movers-on").args(["--far-movers"]).run();
    moving.assert_ok();
    for view in 0..2usize {
        let v0 = moving.views(0)[view];
        let v1 = moving.views(1)[view];
        let (f0, f1) = (moving.image(&v0.file), moving.image(&v1.file));
        let (b0, b1) = (pixel_box(v0, &mover_corners(0), 1.0), pixel_box(v1, &mover_corners(1), 1.0));
        let changed = differing_pixels(&f0, &f1);
        assert!(!changed.is_empty(), "view {view}: frames 0 and 1 are identical: the mover did not move");
        for p in &changed {
            assert!(inside(*p, b0) || inside(*p, b1), "view {view}: {p:?} changed between frames, outside the mover's boxes {b0:?} {b1:?}");
        }
        // Against the scene without the mover: only its own box differs.
        let plain = base.image(&base.views(1)[view].file);
        let added = differing_pixels(&plain, &f1);
        assert!(!added.is_empty(), "view {view}: the mover is not visible");
        assert!(added.iter().all(|&p| inside(p, b1)), "view {view}: pixels outside the mover's box {b1:?} changed");
    }
    // The scene without the option does not move.
    let (a, b) = (base.views(0), base.views(1));
    for (x, y) in a.iter().zip(b) {
        assert_eq!(base.image(&x.file).count_different(&base.image(&y.file)), 0, "frames of the still scene differ");
    }
}

/// Yaw (radians about +y) of an orientation that is a pure rotation about +y.
fn yaw(q: [f32; 4]) -> f64 {
    let [x, y, z, w] = q.map(|c| c as f64);
    assert!(x.abs() < 1e-4 && z.abs() < 1e-4, "not a rotation about +y: {q:?}");
    2.0 * y.atan2(w)
}

/// `MOCK_XR_HEAD_YAW_DEG_PER_S`: the located (and so submitted) view poses turn about +y by
/// rate × display time since the first frame, the head's rate per frame period (simple profile:
/// 90 Hz); the eyes turn about the head's centre, so their midpoint stays. Unset: still poses.
#[test]
fn head_yaw_turns_the_located_views() {
    const RATE_DEG: f64 = 45.0;
    let frames = 4u64;
    let turning = Run::new("head-yaw-on").env("MOCK_XR_EXIT_AFTER", &frames.to_string()).env("MOCK_XR_HEAD_YAW_DEG_PER_S", &RATE_DEG.to_string()).run();
    turning.assert_ok();
    let still = Run::new("head-yaw-off").env("MOCK_XR_EXIT_AFTER", &frames.to_string()).run();
    still.assert_ok();
    let per_frame = (RATE_DEG / 90.0).to_radians();
    for f in 0..frames {
        let (tv, sv) = (turning.views(f), still.views(f));
        for (t, s) in tv.iter().zip(&sv) {
            let turned = yaw(t.pose.orientation) - yaw(s.pose.orientation);
            let expected = per_frame * f as f64;
            assert!((turned - expected).abs() < 1e-4, "frame {f} view {}: turned {turned} rad, expected {expected}", t.view);
            assert_eq!(yaw(s.pose.orientation), yaw(still.views(0)[t.view as usize].pose.orientation), "still poses changed");
        }
        let mid = |v: &[&common::View]| [0, 1, 2].map(|i| (v[0].pose.position[i] + v[1].pose.position[i]) / 2.0);
        let (mt, ms) = (mid(&tv), mid(&sv));
        assert!((0..3).all(|i| (mt[i] - ms[i]).abs() < 1e-5), "frame {f}: head centre moved {mt:?} vs {ms:?}");
        if f > 0 {
            let (a, b) = (turning.image(&turning.views(f - 1)[0].file), turning.image(&tv[0].file));
            assert!(a.count_different(&b) > 0, "frame {f}: the turning head's image did not change");
        }
    }
}

/// What `--sky-first` and `--translucent` leave in the submitted depth (what a layer reusing
/// far pixels reads): the sky drawn first writes no depth, so where only sky shows the depth is
/// still the clear value (the sky drawn last writes its own 1500 m depth there), with the same
/// colour; the translucent pane writes no depth at all (depth identical to the run without it).
#[test]
fn sky_first_and_translucent_write_no_depth() {
    for depth in ["standard", "reverse"] {
        let run = |name: &str, args: &[&str]| {
            let out = Run::new(&format!("no-depth-{depth}-{name}")).args(["--depth", depth, "--submit-depth"]).args(args.iter().copied()).run();
            out.assert_ok();
            out
        };
        let last = run("sky-last", &[]);
        let first = run("sky-first", &["--sky-first"]);
        assert_same_colour_captures(&format!("no-depth-{depth}-sky-first-colour"), &first, &last);
        let clear = if depth == "standard" { u16::MAX } else { 0 };
        for (a, b) in last.views(FRAME).iter().zip(first.views(FRAME)) {
            let (dl, df) = (last.image(&a.depth.as_ref().unwrap().file), first.image(&b.depth.as_ref().unwrap().file));
            let sky = differing_pixels(&dl, &df);
            let (w, _) = (dl.width, dl.height);
            assert!(sky.contains(&(w / 2, 1)), "{depth} view {}: the sky's depth at the top centre did not differ", a.view);
            for (x, y) in sky {
                assert_eq!(df.pixel(x, y)[0], clear, "{depth} view {}: ({x},{y}) with --sky-first is not at the clear depth", a.view);
            }
        }
        let pane = run("translucent", &["--translucent"]);
        for (a, b) in last.views(FRAME).iter().zip(pane.views(FRAME)) {
            let (dl, dp) = (last.image(&a.depth.as_ref().unwrap().file), pane.image(&b.depth.as_ref().unwrap().file));
            assert_eq!(dl.count_different(&dp), 0, "{depth} view {}: the translucent pane changed depth", a.view);
            assert!(last.image(&a.file).count_different(&pane.image(&b.file)) > 0, "{depth} view {}: no pane", a.view);
        }
    }
}
