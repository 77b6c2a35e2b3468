//! State set as DXVK and newer engines set it, checked by the validation layer of the trixie root
//! (1.4.309): Debian bookworm's (1.3.239) does not know `VK_EXT_shader_object` and misreports a
//! link of graphics pipeline libraries made for dynamic rendering, so the host's tests
//! (tests/features/mask.rs, foveation.rs) compare those runs' frames without it. Here xr-scene runs
//! on the host with the root's dynamic linker and libraries first (its Vulkan loader, lavapipe and
//! validation layer), on the mock runtime, with synchronization validation: the runs without and
//! with the layer (mask + RDM) must exit clean, and the layer must mask and foveate the eye
//! passes, vetoing none.

use crate::common::{self, Run};
use crate::harness::root;
use std::path::Path;

const LIBDIR: &str = "usr/lib/x86_64-linux-gnu";

/// `run` with the trixie root's libraries first, its lavapipe as the only driver and its
/// validation layer found first.
fn in_trixie(mut run: Run, root: &Path) -> Run {
    let lib = root.join(LIBDIR);
    // One file per run: the tests of this binary run two at a time.
    let icd = common::target_dir().join("test-output").join(format!("{}.lavapipe.json", run.name));
    let json = serde_json::json!({ "file_format_version": "1.0.0", "ICD": { "library_path": lib.join("libvulkan_lvp.so"), "api_version": "1.4.305" } });
    std::fs::create_dir_all(icd.parent().unwrap()).unwrap();
    std::fs::write(&icd, json.to_string()).unwrap();
    run.wrapper = vec![lib.join("ld-linux-x86-64.so.2").into(), "--library-path".into(), lib.into()];
    run.env("VK_DRIVER_FILES", icd.to_str().unwrap()).env("VK_ADD_LAYER_PATH", root.join("usr/share/vulkan/explicit_layer.d").to_str().unwrap())
}

fn check(name: &str, args: &[&str]) {
    let Some(root) = root() else { return };
    let base = Run::new(&format!("trixie-{name}")).args(args.iter().copied()).env("MOCK_XR_EXIT_AFTER", "3");
    let plain = in_trixie(base.clone(), &root).run();
    plain.assert_ok();
    let mut layered = base.with_layer().env("STEREOSHIM_MASK_ENABLED", "1").env("STEREOSHIM_FOVEATION_ENABLED", "1").env("STEREOSHIM_FOVEATION_METHOD", "rdm");
    layered.name = format!("trixie-{name}-layer");
    let layered = in_trixie(layered, &root).run();
    layered.assert_ok();
    let stats = layered.log_lines("vulkan device stats:").join("\n");
    let count = |key: &str| -> u64 { stats.split_whitespace().find_map(|w| w.strip_prefix(key)).and_then(|v| v.parse().ok()).unwrap_or(0) };
    // Frames 1 and 2 (frame 0's eyes are not known yet), every view's pass.
    let passes = if args.contains(&"multiview") || args.contains(&"side-by-side") { 2 } else { 4 };
    assert!(count("masked_passes=") >= passes && count("rdm_passes=") >= passes, "{name}: the layer did not mask and foveate every eye pass: {stats}");
    assert!(!stats.contains("vetoed."), "{name}: an injection was vetoed: {stats}");
}

#[test]
fn shader_objects_per_eye_state_before_the_pass() {
    check("shader-object-per-eye", &["--layout", "per-eye", "--rendering", "dynamic", "--shader-object", "--bind-before-pass"]);
}

#[test]
fn shader_objects_multiview_translucent() {
    check("shader-object-multiview", &["--layout", "multiview", "--rendering", "dynamic", "--shader-object", "--translucent"]);
}

#[test]
fn pipeline_libraries_for_dynamic_rendering() {
    check("pipeline-library-dynamic", &["--layout", "side-by-side", "--rendering", "dynamic", "--pipeline-library", "--dynamic-state", "--bind-before-pass"]);
}
