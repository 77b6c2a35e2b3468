//! Inspects the built `libstereoshim.so` the way the dynamic linker sees it: the library exports only
//! what the loaders look up, and nothing inside it is bound through the GOT/PLT to one of its own
//! exported names. Such a binding is interposable: in a process that links `libvulkan.so.1` (most
//! real apps) an exported `vkGetInstanceProcAddr` resolves to the loader's, the layer hands the loader
//! its own trampoline and the loader deadlocks on its non-recursive lock.

use crate::common;

use std::process::Command;

/// The only dynamic symbols the loaders need: the OpenXR loader's and the Vulkan loader's
/// negotiation functions (both manifests name no other entry point).
const NEEDED_EXPORTS: &[&str] = &["vkNegotiateLoaderLayerInterfaceVersion", "xrNegotiateLoaderApiLayerInterface"];

fn tool(name: &str, args: &[&str]) -> String {
    let out = Command::new(name)
        .args(args)
        .output()
        .unwrap_or_else(|e| panic!("{name} (binutils) is needed to inspect the library: {e}"));
    assert!(out.status.success(), "{name} {args:?} failed: {}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8(out.stdout).expect("utf-8 output")
}

fn library() -> String {
    let lib = common::target_dir().join("libstereoshim.so");
    assert!(lib.exists(), "{} not built", lib.display());
    lib.to_string_lossy().into_owned()
}

/// `nm -D --defined-only`: (type, name) of every symbol the library defines for others.
fn exported(lib: &str) -> Vec<(String, String)> {
    tool("nm", &["-D", "--defined-only", lib])
        .lines()
        .filter_map(|l| {
            let f: Vec<&str> = l.split_whitespace().collect();
            (f.len() == 3).then(|| (f[1].to_string(), f[2].split('@').next().unwrap_or(f[2]).to_string()))
        })
        .collect()
}

#[test]
fn exports_only_what_the_loaders_need() {
    let lib = library();
    let functions: Vec<String> = exported(&lib)
        .into_iter()
        // Code and data symbols; the linker's own markers (absolute `A`) are not entry points.
        .filter(|(t, _)| t != "A")
        .map(|(_, n)| n)
        .collect();
    for needed in NEEDED_EXPORTS {
        assert!(functions.iter().any(|f| f == needed), "{needed} is not exported (exports: {functions:?})");
    }
    let extra: Vec<&String> = functions.iter().filter(|f| !NEEDED_EXPORTS.contains(&f.as_str())).collect();
    assert!(extra.is_empty(), "exported symbols the loaders do not need (each is interposable): {extra:?}");
}

#[test]
fn no_relocation_against_an_own_exported_symbol() {
    let lib = library();
    let own: Vec<String> = exported(&lib).into_iter().map(|(_, n)| n).collect();
    assert!(!own.is_empty(), "nm found no exported symbol at all: the check below would pass vacuously");
    let relocs = tool("readelf", &["-rW", &lib]);
    assert!(relocs.contains("R_X86_64_"), "readelf printed no relocation table: cannot check");
    // Relocation lines: offset info type symbol-value symbol-name[@version] + addend.
    let bad: Vec<&str> = relocs
        .lines()
        .filter(|l| {
            let f: Vec<&str> = l.split_whitespace().collect();
            f.len() >= 5 && {
                let name = f[4].split('@').next().unwrap_or(f[4]);
                own.iter().any(|o| o == name)
            }
        })
        .collect();
    assert!(bad.is_empty(), "relocations against the library's own exported symbols (interposable):\n{}", bad.join("\n"));
}

#[test]
fn symbolic_binding_is_on() {
    // -Bsymbolic (build.rs) binds every internal reference at link time; DT_FLAGS carries SYMBOLIC.
    let dynamic = tool("readelf", &["-dW", &library()]);
    assert!(dynamic.contains("SYMBOLIC"), "the library was not linked with -Bsymbolic:\n{dynamic}");
}
