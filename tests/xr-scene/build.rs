//! Compiles the GLSL shaders to SPIR-V at build time, so no generated binaries live in the repository.

use std::path::{Path, PathBuf};
use std::process::Command;

/// (source file, output name, glslang target environment, extra glslang arguments). The multiview
/// variants differ only in where the view index comes from (`gl_ViewIndex` instead of a push
/// constant). `--vulkan-api 1.0` gets SPIR-V 1.0 builds of the single-view shaders (a Vulkan 1.0
/// device accepts no later SPIR-V); the others keep SPIR-V 1.3 (vulkan1.1).
const SHADERS: &[(&str, &str, &str, &[&str])] = &[
    ("scene.vert", "scene.vert.spv", "vulkan1.1", &[]),
    ("scene.frag", "scene.frag.spv", "vulkan1.1", &[]),
    ("scene.vert", "scene_mv.vert.spv", "vulkan1.1", &["-DMULTIVIEW"]),
    ("scene.frag", "scene_mv.frag.spv", "vulkan1.1", &["-DMULTIVIEW"]),
    ("scene.vert", "scene_vk10.vert.spv", "vulkan1.0", &[]),
    ("scene.frag", "scene_vk10.frag.spv", "vulkan1.0", &[]),
    // The post chain (`--post`): SPIR-V 1.0 wherever no multiview is needed, so one build serves
    // every `--vulkan-api`.
    ("fullscreen.vert", "fullscreen.vert.spv", "vulkan1.0", &[]),
    ("post.frag", "post.frag.spv", "vulkan1.0", &[]),
    ("post.frag", "post_mv.frag.spv", "vulkan1.1", &["-DMULTIVIEW"]),
    ("post_compute.comp", "post.comp.spv", "vulkan1.0", &[]),
    ("post_compute.comp", "post_array.comp.spv", "vulkan1.0", &["-DARRAY"]),
    ("post_subpass.frag", "post_subpass.frag.spv", "vulkan1.0", &[]),
];

/// Files the shaders `#include`: a change to one rebuilds them all.
const INCLUDED: &[&str] = &["post_common.glsl"];

fn main() {
    let manifest = PathBuf::from(std::env::var_os("CARGO_MANIFEST_DIR").expect("CARGO_MANIFEST_DIR"));
    let out = PathBuf::from(std::env::var_os("OUT_DIR").expect("OUT_DIR"));
    let shader_dir = manifest.join("shaders");
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-changed={}", shader_dir.display());
    for inc in INCLUDED {
        println!("cargo:rerun-if-changed={}", shader_dir.join(inc).display());
    }
    for (src, dst, env, extra) in SHADERS {
        let src_path = shader_dir.join(src);
        println!("cargo:rerun-if-changed={}", src_path.display());
        compile(&src_path, &out.join(dst), env, extra);
    }
}

fn compile(src: &Path, dst: &Path, env: &str, extra: &[&str]) {
    let result = Command::new("glslangValidator")
        .args(["-V", "--target-env", env])
        .args(extra)
        .arg("-o")
        .arg(dst)
        .arg(src)
        .output();
    match result {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => panic!(
            "glslangValidator not found in PATH: it is needed to compile xr-scene's shaders \
             (Debian: apt-get install glslang-tools)"
        ),
        Err(e) => panic!("could not run glslangValidator: {e}"),
        Ok(o) if !o.status.success() => panic!(
            "glslangValidator failed on {} ({extra:?}):\n{}{}",
            src.display(),
            String::from_utf8_lossy(&o.stdout),
            String::from_utf8_lossy(&o.stderr)
        ),
        Ok(_) => {}
    }
}
