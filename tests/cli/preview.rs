//! `stereoshim preview` end to end (target/debug/stereoshim): the pictures and `preview.json` of
//! a headset profile hold what the features' own rules decide, pixel for pixel (each picture's
//! classes are read back from its colours and compared with a map built from the rules here, with
//! actual / expected / difference PNGs under target/test-artifacts/ on failure); `--runtime` on
//! the mock runtime (XR_MND_headless) gives what `--hmd` gives for the same profile; a runtime
//! without headless sessions and bad arguments are refused with the documented exit codes.

use crate::common;

use common::image::{assert_identical, Image};
use common::{output_dir, runtime_manifest, target_dir};
use serde_json::Value;
use std::path::Path;
use std::process::Command;
use stereoshim::core::rect::PixelRect;
use stereoshim::features::far_field::rules::{footprint_inside, split_distance, PixelMap, ViewGeometry};
use stereoshim::features::foveation::rdm::rules::RdmParams;
use stereoshim::features::foveation::vrs::rules as vrs;
use stereoshim::features::mask::{rules as mask_rules, source as mask_source};
use stereoshim::core::views::{FoveaView, ViewFov, ViewPose};

/// Runs `stereoshim preview ARGS` with nothing of the developer's setup (config, layers, runtime)
/// leaking in; `env` adds variables. Returns the exit code and stdout + stderr.
fn preview(args: &[&str], env: &[(&str, &str)], home: &Path) -> (i32, String) {
    let mut cmd = Command::new(target_dir().join("stereoshim"));
    cmd.arg("preview").args(args);
    for (key, _) in std::env::vars_os() {
        let k = key.to_string_lossy();
        if k.starts_with("STEREOSHIM_") || k.starts_with("MOCK_XR_") || k.starts_with("XR_") {
            cmd.env_remove(key);
        }
    }
    cmd.env("XDG_CONFIG_HOME", home.join("config")).env("XDG_DATA_HOME", home.join("data")).env("XDG_CONFIG_DIRS", "/nonexistent").env("XDG_DATA_DIRS", "/nonexistent");
    for (k, v) in env {
        cmd.env(k, v);
    }
    let out = cmd.output().expect("run stereoshim");
    (out.status.code().unwrap_or(-1), String::from_utf8_lossy(&out.stdout).into_owned() + &String::from_utf8_lossy(&out.stderr))
}

fn read_json(dir: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(dir.join("preview.json")).expect("preview.json")).expect("valid JSON")
}

fn rgb(v: &Value) -> [u8; 3] {
    let a = v.as_array().expect("colour");
    [0, 1, 2].map(|i| a[i].as_u64().unwrap() as u8)
}

/// The colour of a class (its legend entry) over a base colour, as the preview documents it:
/// `(base·(255 − alpha) + tint·alpha + 127) / 255`.
fn over(base: [u8; 3], class: &Value) -> [u8; 3] {
    let (t, a) = (rgb(&class["tint"]), class["alpha"].as_u64().unwrap() as u32);
    [0, 1, 2].map(|i| ((base[i] as u32 * (255 - a) + t[i] as u32 * a + 127) / 255) as u8)
}

/// The view part of a preview picture as a map of class indices (255: no class): a pixel is of
/// class k when its colour is class k's colour over one of the grid's two colours.
fn classes_of(png: &Path, json: &Value, feature: &str, w: u32, h: u32) -> Vec<u8> {
    let img = Image::load(png);
    let legend = &json["legend"];
    assert_eq!((img.width, img.height), (w, h + legend["legend_height"].as_u64().unwrap() as u32), "{}", png.display());
    let grid = [rgb(&legend["grid"]["background"]), rgb(&legend["grid"]["line"])];
    let classes = legend[feature].as_array().unwrap();
    let mut out = Vec::with_capacity((w * h) as usize);
    for y in 0..h {
        for x in 0..w {
            let p = img.pixel(x, y);
            let p = [p[0] as u8, p[1] as u8, p[2] as u8];
            let k = classes.iter().position(|c| grid.iter().any(|g| over(*g, c) == p));
            out.push(k.map_or(255, |k| k as u8));
        }
    }
    out
}

/// A class map as a grey picture (for the artifacts of a failed comparison).
fn class_image(map: &[u8], w: u32, h: u32) -> Image {
    Image { width: w, height: h, channels: 1, bit_depth: 8, data: map.iter().map(|&k| if k == 255 { 0 } else { 60 + k as u16 * 60 }).collect() }
}

fn view_fov(v: &Value) -> ViewFov {
    let f = |k: &str| v["fov"][k].as_f64().unwrap() as f32;
    ViewFov { tan_left: f("tan_left"), tan_right: f("tan_right"), tan_up: f("tan_up"), tan_down: f("tan_down") }
}

/// Checks one profile's preview against the rules, number by number and pixel by pixel.
fn check_profile(name: &str, scale: f64) {
    let home = output_dir(&format!("preview-{name}"));
    let out = home.join("out");
    let (code, text) = preview(&["--hmd", name, "--scale", &scale.to_string(), "--out", out.to_str().unwrap()], &[], &home);
    assert_eq!(code, 0, "{text}");
    let j = read_json(&out);
    let p = hmd_profiles::profile::HmdProfile::by_name(name).unwrap();
    let (w, h) = ((p.recommended.0 as f64 * scale).round() as u32, (p.recommended.1 as f64 * scale).round() as u32);
    assert_eq!((j["width"].as_u64(), j["height"].as_u64()), (Some(w as u64), Some(h as u64)));
    let rect = PixelRect { x: 0, y: 0, width: w, height: h };
    let area = rect.area();
    // The default config: balanced rings (20°, 35°), a one-pixel far-field budget, source view 0.
    let fovea = FoveaView { view: 0, center: [0.0, 0.0], inner_deg: 20.0, middle_deg: 35.0 };
    let geometry: Vec<ViewGeometry> = (0..2)
        .map(|v| {
            let (pos, q) = p.eye_in_head(v);
            let [l, r, u, d] = p.fov_rad(v);
            let fov = ViewFov { tan_left: l.tan(), tan_right: r.tan(), tan_up: u.tan(), tan_down: d.tan() };
            ViewGeometry::of(&ViewPose { orientation: q.to_array(), position: pos.to_array(), fov }, rect)
        })
        .collect();
    let split = split_distance(1.0, None, &geometry[0], &geometry[1]);
    assert!((j["far_field"]["split_m"].as_f64().unwrap() - split).abs() < 1e-9 * split, "{}", j["far_field"]);
    for (v, jv) in j["views"].as_array().unwrap().iter().enumerate() {
        let fov = view_fov(jv);
        assert_eq!(fov, geometry[v].fov, "view {v}: the profile's FOV");
        let png = |feature: &str| out.join(jv[feature]["png"].as_str().unwrap());
        let compare = |what: &str, actual: &[u8], expected: &[u8]| {
            assert_identical(&format!("preview-{name}-{what}-view{v}"), &class_image(actual, w, h), &class_image(expected, w, h));
        };

        // Mask: the runtime's hidden mesh (the profile's, as the mock runtime serves it).
        let (hidden, _, _) = hmd_profiles::mask::build(p, v, 1.0);
        let tris = mask_source::expand(&hidden.vertices, &hidden.indices);
        let masked = mask_rules::masked_pixels(&tris, &fov, rect);
        assert_eq!(jv["mask"]["pixels_masked"].as_u64(), Some(masked), "view {v}");
        assert_eq!(jv["mask"]["source"], "runtime");
        assert!((jv["mask"]["fraction"].as_f64().unwrap() - masked as f64 / area as f64).abs() < 1e-12);
        let (_, bits) = mask_rules::coverage_bitmap(&mask_rules::triangles_to_ndc(&tris, &fov), rect.viewport(), rect);
        let expected: Vec<u8> = bits.iter().map(|&b| if b { 0 } else { 255 }).collect();
        compare("mask", &classes_of(&png("mask"), &j, "mask", w, h), &expected);

        // VRS: the rate map of 16-pixel texels.
        let eye = vrs::EyeRates { layer: 0, rect, fov, fovea: FoveaView { view: v as u32, ..fovea } };
        let (tw, th) = (vrs::texels(w, 16), vrs::texels(h, 16));
        let map = vrs::rate_layer(tw, th, 16, 16, 0, &[eye]);
        let rates = [vrs::FULL, vrs::HALF, vrs::QUARTER];
        let expected: Vec<u8> = (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .map(|(x, y)| rates.iter().position(|r| *r == vrs::decode(map[((y / 16) * tw + x / 16) as usize])).unwrap() as u8)
            .collect();
        for (k, n) in ["1x1", "2x1", "2x2"].iter().enumerate() {
            let count = expected.iter().filter(|&&c| c == k as u8).count() as u64;
            assert_eq!(jv["vrs"]["pixels"][n].as_u64(), Some(count), "view {v} rate {n}");
            assert!((jv["vrs"]["fractions"][n].as_f64().unwrap() - count as f64 / area as f64).abs() < 1e-12);
        }
        compare("vrs", &classes_of(&png("vrs"), &j, "vrs", w, h), &expected);

        // RDM: the skip rule's own count, and the skipped pixels are the black ones.
        let rdm = RdmParams::new(&fov, &FoveaView { view: v as u32, ..fovea }, rect).unwrap();
        let n = rdm.count(rect);
        assert_eq!(jv["rdm"]["pixels_skipped"].as_u64(), Some(n.pixels_skipped), "view {v}");
        assert_eq!(jv["rdm"]["quads_skipped"].as_u64(), Some(n.quads_skipped));
        assert!((jv["rdm"]["skipped_fraction"].as_f64().unwrap() - n.pixels_skipped as f64 / area as f64).abs() < 1e-12);
        let skipped_class = 3; // inner, middle, outer, skipped
        let actual: Vec<u8> = classes_of(&png("rdm"), &j, "rdm", w, h).iter().map(|&k| if k == skipped_class { 1 } else { 0 }).collect();
        let expected: Vec<u8> = (0..h).flat_map(|y| (0..w).map(move |x| (x, y))).map(|(x, y)| rdm.pixel_skipped(x as i32, y as i32) as u8).collect();
        compare("rdm", &actual, &expected);

        // Far field: view 1 reuses view 0's pixels where its footprint lands in view 0.
        let expected: Vec<u8> = if v == 1 {
            let m = PixelMap::new(&geometry[0], &geometry[1]);
            (0..h).flat_map(|y| (0..w).map(move |x| (x, y))).map(|(x, y)| if footprint_inside(&m, x, y, 0.0, w, h) { 0 } else { 255 }).collect()
        } else {
            vec![255; area as usize]
        };
        let reusable = expected.iter().filter(|&&c| c == 0).count() as u64;
        assert_eq!(jv["far_field"]["pixels_reusable"].as_u64(), Some(reusable), "view {v}");
        assert_eq!(jv["far_field"]["role"], if v == 1 { "destination" } else { "source" });
        compare("far_field", &classes_of(&png("far_field"), &j, "far_field", w, h), &expected);
    }
    // The numbers are printed as well; the FOV cut's picture is the fifth per view.
    assert!(text.contains("view 0 mask (runtime)") && text.contains("px skipped") && text.contains("view 1 FOV cut: the app renders") && text.contains("wrote 10 PNGs"), "{text}");
}

#[test]
fn index_preview_is_what_the_rules_decide() {
    check_profile("index", 0.125);
    // `--hmd`: the mask under each kind of runtime. Monado's generic corners hide ~3 %; the layer
    // uses the Index's published lens instead, as where the runtime has none.
    let j = read_json(&target_dir().join("test-output/preview-index/out"));
    let m = &j["mask_sources"];
    assert_eq!(m["published_lens"], true, "{m}");
    for v in 0..2 {
        let cases = m["views"][v]["cases"].as_array().unwrap_or_else(|| panic!("{m}"));
        let case = |name: &str| cases.iter().find(|c| c["runtime"] == name).unwrap_or_else(|| panic!("{name}: {m}"));
        let (own, generic, none) = (case("headset_mesh"), case("monado_generic"), case("none"));
        assert_eq!(own["layer_uses"], "runtime");
        assert!(generic["runtime_fraction"].as_f64().unwrap() < 0.05, "{generic}");
        assert_eq!(generic["layer_uses"], "headset");
        assert_eq!(generic["fraction"], own["runtime_fraction"], "the lens, as a runtime with the mesh gives it");
        assert_eq!((none["runtime_fraction"].clone(), none["layer_uses"].clone()), (serde_json::Value::Null, serde_json::json!("headset")));
        assert_eq!(j["views"][v]["mask"]["fraction"], own["fraction"], "what the preview draws is the headset-mesh case");
    }
}

#[test]
fn simple_preview_is_what_the_rules_decide() {
    check_profile("simple", 0.25);
    // The simple profile's numbers, to be plain about what they are: the 45° lens hides about a
    // third, the balanced rings leave a fifth at full rate.
    let j = read_json(&target_dir().join("test-output/preview-simple/out"));
    let f = j["views"][0]["mask"]["fraction"].as_f64().unwrap();
    assert!((0.25..0.40).contains(&f), "{f}");
}

#[test]
fn runtime_views_equal_the_profile() {
    let home = output_dir("preview-runtime");
    let manifest = runtime_manifest();
    let (hmd_dir, rt_dir) = (home.join("hmd"), home.join("runtime"));
    let (code, text) = preview(&["--hmd", "index", "--scale", "0.1", "--out", hmd_dir.to_str().unwrap()], &[], &home);
    assert_eq!(code, 0, "{text}");
    let env = [("XR_RUNTIME_JSON", manifest.to_str().unwrap()), ("MOCK_XR_HMD", "index")];
    let (code, text) = preview(&["--runtime", "--scale", "0.1", "--out", rt_dir.to_str().unwrap()], &env, &home);
    assert_eq!(code, 0, "{text}");
    let (a, b) = (read_json(&hmd_dir), read_json(&rt_dir));
    assert_eq!(b["headset"], "Mock HMD (Valve Index)", "the runtime's system name");
    assert_eq!((a["width"].clone(), a["height"].clone()), (b["width"].clone(), b["height"].clone()));
    for v in 0..2 {
        let (va, vb) = (&a["views"][v], &b["views"][v]);
        for k in ["tan_left", "tan_right", "tan_up", "tan_down"] {
            let (x, y) = (va["fov"][k].as_f64().unwrap(), vb["fov"][k].as_f64().unwrap());
            assert!((x - y).abs() < 1e-6, "view {v} {k}: {x} vs {y}");
        }
        // The runtime's masks (XR_KHR_visibility_mask) are the profile's: the same pixels.
        assert_eq!(va["mask"], vb["mask"], "view {v}");
        assert_eq!(va["vrs"], vb["vrs"], "view {v}");
        assert_eq!(va["rdm"], vb["rdm"], "view {v}");
        assert_eq!(va["far_field"]["pixels_reusable"], vb["far_field"]["pixels_reusable"], "view {v}");
        let png = |dir: &Path| Image::load(&dir.join(format!("mask-view-{v}.png")));
        assert_identical(&format!("preview-runtime-mask-view{v}"), &png(&rt_dir), &png(&hmd_dir));
    }
    let (sa, sb) = (a["far_field"]["split_m"].as_f64().unwrap(), b["far_field"]["split_m"].as_f64().unwrap());
    assert!((sa - sb).abs() < 1e-4 * sa, "{sa} vs {sb}");
}

#[test]
fn a_runtime_without_headless_sessions_is_reported() {
    let home = output_dir("preview-no-headless");
    let manifest = runtime_manifest();
    let out = home.join("out");
    let env = [("XR_RUNTIME_JSON", manifest.to_str().unwrap()), ("MOCK_XR_DISABLE_EXTENSIONS", "XR_MND_headless")];
    let (code, text) = preview(&["--runtime", "--out", out.to_str().unwrap()], &env, &home);
    assert_eq!(code, 1, "{text}");
    assert!(text.contains("this runtime needs a graphics session; use --hmd"), "{text}");
    assert!(!out.join("preview.json").exists());
    // No runtime at all: a runtime error too, saying so.
    let (code, text) = preview(&["--runtime", "--out", out.to_str().unwrap()], &[("XR_RUNTIME_JSON", "/nonexistent/runtime.json")], &home);
    assert_eq!(code, 1, "{text}");
    assert!(text.contains("no OpenXR runtime"), "{text}");
}

#[test]
fn config_app_section_split_and_image() {
    let home = output_dir("preview-config");
    let config = home.join("preview.toml");
    std::fs::write(&config, "far_field.split_px = 2\n[app.\"game\"]\nmask.source = \"synthesized\"\nmask.synthesized.radius_deg = 30\n").unwrap();
    // A 4×2 picture of eight colours, scaled up to each view (nearest neighbour).
    let image = home.join("scene.png");
    let colours: Vec<[u8; 3]> = (0..8u8).map(|i| [i * 30, 255 - i * 30, 100]).collect();
    {
        let mut enc = png::Encoder::new(std::fs::File::create(&image).unwrap(), 4, 2);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        enc.write_header().unwrap().write_image_data(&colours.concat()).unwrap();
    }
    let run = |extra: &[&str], dir: &str| {
        let out = home.join(dir);
        let mut args = vec!["--hmd", "simple", "--scale", "0.125", "--config", config.to_str().unwrap(), "--out", out.to_str().unwrap()];
        args.extend_from_slice(extra);
        let (code, text) = preview(&args, &[], &home);
        assert_eq!(code, 0, "{text}");
        (read_json(&out), out)
    };
    let (plain, _) = run(&[], "plain");
    let (game, out) = run(&["--app", "game", "--image", image.to_str().unwrap()], "game");
    let (split4, _) = run(&["--split-px", "4"], "split4");
    assert_eq!(plain["views"][0]["mask"]["source"], "runtime");
    assert_eq!(game["views"][0]["mask"]["source"], "synthesized", "the app's section applies");
    assert!(game["views"][0]["mask"]["pixels_masked"].as_u64() > plain["views"][0]["mask"]["pixels_masked"].as_u64());
    assert_eq!(plain["far_field"]["split_px"], 2.0, "far_field.split_px from the file");
    let (s2, s4) = (plain["far_field"]["split_m"].as_f64().unwrap(), split4["far_field"]["split_m"].as_f64().unwrap());
    assert!((s4 - s2 / 2.0).abs() < 1e-9 * s2, "--split-px 4 halves the distance of 2: {s2} {s4}");
    // Over the image: the far field's source view paints nothing, so it is the image itself,
    // scaled to the view by nearest neighbour.
    let img = Image::load(&out.join("far-field-view-0.png"));
    for (x, y, c) in [(10u32, 10u32, colours[0]), (127, 127, colours[7]), (70, 20, colours[2])] {
        assert_eq!(img.pixel(x, y), c.map(|v| v as u16), "({x}, {y})");
    }
}

#[test]
fn help_and_bad_arguments() {
    let home = output_dir("preview-args");
    let (code, text) = preview(&["--help"], &[], &home);
    assert_eq!(code, 0, "{text}");
    assert!(text.contains("--hmd") && text.contains("--runtime") && text.contains("--split-px"), "{text}");
    let out = home.join("out");
    let out = out.to_str().unwrap();
    for args in [
        vec!["--out", out],
        vec!["--hmd", "nope", "--out", out],
        vec!["--hmd", "index", "--runtime", "--out", out],
        vec!["--hmd", "index"],
        vec!["--hmd", "index", "--scale", "0", "--out", out],
        vec!["--hmd", "index", "--split-px", "-1", "--out", out],
        vec!["--hmd", "index", "--vrs-texel", "0", "--out", out],
        vec!["--hmd", "index", "--bogus", "--out", out],
    ] {
        let (code, text) = preview(&args, &[], &home);
        assert_eq!(code, 2, "{args:?}: {text}");
        assert!(!text.contains("panicked"), "{text}");
    }
    // Runtime errors exit 1: a missing config file, an unreadable image.
    let (code, text) = preview(&["--hmd", "simple", "--config", "/nonexistent.toml", "--out", out], &[], &home);
    assert_eq!(code, 1, "{text}");
    let (code, text) = preview(&["--hmd", "simple", "--image", "/nonexistent.png", "--out", out], &[], &home);
    assert_eq!(code, 1, "{text}");
}
