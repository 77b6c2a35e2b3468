//! Compiles the layer's GLSL shaders (`shaders/`) to SPIR-V at build time with glslangValidator, so
//! no generated binaries live in the repository; `src/vk/mask.rs` and `src/vk/rdm.rs` embed them
//! (`rdm_rule.glsl` is included by the RDM fragment and compute shaders).

use std::path::{Path, PathBuf};
use std::process::Command;

/// (source file, output name, extra glslang arguments).
const SHADERS: &[(&str, &str, &[&str])] = &[
    ("mask.vert", "mask.vert.spv", &[]),
    ("mask.vert", "mask_mv.vert.spv", &["-DMULTIVIEW"]),
    ("mask.frag", "mask.frag.spv", &[]),
    ("rdm.vert", "rdm.vert.spv", &[]),
    ("rdm.vert", "rdm_mv.vert.spv", &["-DMULTIVIEW"]),
    ("rdm.frag", "rdm.frag.spv", &[]),
    ("rdm_fill.vert", "rdm_fill.vert.spv", &[]),
    ("rdm_fill.frag", "rdm_fill.frag.spv", &[]),
    ("rdm_fill.vert", "rdm_fill_buffer.vert.spv", &["-DFROM_BUFFER"]),
    ("rdm_fill.frag", "rdm_fill_buffer.frag.spv", &["-DFROM_BUFFER"]),
    ("rdm_recon.comp", "rdm_recon.comp.spv", &[]),
    ("rdm_recon.comp", "rdm_recon_link.comp.spv", &["-DFROM_LINK"]),
    ("rdm_recon.comp", "rdm_recon_link_half.comp.spv", &["-DFROM_LINK", "-DHALF"]),
    ("far_field.vert", "far_field.vert.spv", &[]),
    ("far_field.vert", "far_field_mv.vert.spv", &["-DMULTIVIEW"]),
    ("far_field.frag", "far_field.frag.spv", &[]),
    ("far_field.frag", "far_field_msaa.frag.spv", &["-DMSAA"]),
    ("far_field_copy.comp", "far_field_copy.comp.spv", &[]),
    ("upscale_easu.comp", "upscale_easu.comp.spv", &[]),
    ("upscale_cas.comp", "upscale_cas.comp.spv", &[]),
    ("upscale_rcas.comp", "upscale_rcas.comp.spv", &[]),
    ("upscale_rcas.comp", "upscale_rcas_rgba8.comp.spv", &["-DOUT_RGBA8"]),
    ("upscale_rcas.frag", "upscale_rcas.frag.spv", &[]),
    ("upscale_bilinear.frag", "upscale_bilinear.frag.spv", &[]),
    ("upscale.vert", "upscale.vert.spv", &[]),
];

fn main() {
    let manifest = PathBuf::from(std::env::var_os("CARGO_MANIFEST_DIR").expect("CARGO_MANIFEST_DIR"));
    let out = PathBuf::from(std::env::var_os("OUT_DIR").expect("OUT_DIR"));
    let shader_dir = manifest.join("shaders");
    println!("cargo:rerun-if-changed=build.rs");
    // Bind every reference from inside the library to its own definitions at link time. Without
    // this, a process that links libvulkan.so.1 or libopenxr_loader.so.1 resolves any symbol the
    // library shares with them to the loader's copy (ELF interposition), and the loader ends up
    // calling itself through the layer. tests/layer/symbols.rs checks the built library.
    println!("cargo:rustc-cdylib-link-arg=-Wl,-Bsymbolic");
    println!("cargo:rerun-if-changed={}", shader_dir.display());
    for (src, dst, extra) in SHADERS {
        let src_path = shader_dir.join(src);
        println!("cargo:rerun-if-changed={}", src_path.display());
        compile(&src_path, &out.join(dst), extra);
    }
    println!("cargo:rerun-if-changed={}", shader_dir.join("rdm_rule.glsl").display());
    println!("cargo:rerun-if-changed={}", shader_dir.join("upscale_rcas.glsl").display());
}

/// Every shader is SPIR-V 1.0 (`--target-env vulkan1.0`): the layer's modules are created on the
/// app's device, which may be a Vulkan 1.0 device; a module may only use what that device has
/// (VUID-VkShaderModuleCreateInfo-pCode-08737). The multiview variants additionally declare the
/// `MultiView` capability and are only created on devices that enabled `multiview`.
fn compile(src: &Path, dst: &Path, extra: &[&str]) {
    let result = Command::new("glslangValidator")
        .args(["-V", "--target-env", "vulkan1.0"])
        .args(extra)
        .arg("-o")
        .arg(dst)
        .arg(src)
        .output();
    match result {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => panic!(
            "glslangValidator not found in PATH: it is needed to compile stereoshim's shaders \
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
