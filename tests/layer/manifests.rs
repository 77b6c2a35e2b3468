//! Every manifest stereoshim writes or ships (the files under `manifest/`, what `stereoshim run`,
//! `stereoshim install` and `stereoshim manifest` write, the Vulkan manifest the OpenXR half writes
//! at run time, the test harness's) is checked against the manifest rules of both loaders, and is
//! loaded by real loaders: Debian bookworm's (installed here: Vulkan 1.3.239, OpenXR 1.0.20) and,
//! when `STEREOSHIM_TRIXIE_ROOT` names a folder holding trixie's (Vulkan 1.4.309, OpenXR 1.1.47),
//! those too. A loader is proved to have loaded a manifest by a probe process (this test binary,
//! re-run as `loader_probe_child`) that enumerates the layers, creates an instance, and reports
//! whether the library the manifest names is mapped, together with the loader's own debug output.

use crate::common;

use common::target_dir;
use serde_json::Value;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;
use stereoshim::manifests::{self as manifest, Kind};

mod rules;

use rules::{api_of, assert_valid, check, Api};

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn library() -> PathBuf {
    let lib = target_dir().join("libstereoshim.so");
    assert!(lib.is_file(), "{} missing: run `cargo build --workspace` first", lib.display());
    std::fs::canonicalize(lib).unwrap()
}

fn write(path: &Path, text: &str) {
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    std::fs::write(path, text).unwrap();
}

#[test]
fn shipped_manifests_are_the_generated_ones() {
    let refresh = "refresh them with: cargo run -q --bin stereoshim -- manifest --shipped manifest";
    let mut expected = BTreeMap::new();
    for (rel, text) in manifest::shipped() {
        let path = repo().join("manifest").join(&rel);
        let on_disk = std::fs::read_to_string(&path).unwrap_or_default();
        assert!(on_disk == text, "{} differs from what stereoshim generates; {refresh}\n--- generated:\n{text}--- on disk:\n{on_disk}", path.display());
        expected.insert(path, ());
    }
    // Nothing under manifest/ that the generator does not produce.
    for dir in std::fs::read_dir(repo().join("manifest")).unwrap().flatten() {
        for f in std::fs::read_dir(dir.path()).into_iter().flatten().flatten() {
            assert!(expected.contains_key(&f.path()), "{} is not generated; remove it or generate it", f.path().display());
        }
    }
}

#[test]
fn every_written_or_shipped_manifest_follows_both_loaders_rules() {
    let lib = library();
    let out = common::output_dir("manifests-rules");
    // The shipped files, in place: their library_path points at this tree's debug build.
    for kind in Kind::ALL {
        let path = repo().join("manifest").join(kind.name()).join(manifest::MANIFEST_FILE);
        let text = std::fs::read_to_string(&path).unwrap();
        let (problems, _) = check(api_of(kind), kind.is_implicit(), &text, &path);
        let debug_lib = repo().join("target/debug/libstereoshim.so");
        // Without a debug build in this tree the path cannot resolve; every other rule still holds.
        let problems: Vec<_> = problems.into_iter().filter(|p| debug_lib.is_file() || !p.contains("does not exist")).collect();
        assert!(problems.is_empty(), "{}: {problems:?}", path.display());
    }
    // What `run` (explicit), `install` (implicit) and the OpenXR half (Vulkan) write, for this library.
    for kind in Kind::ALL {
        let path = out.join(kind.name()).join(manifest::MANIFEST_FILE);
        let text = manifest::json(kind, &lib);
        write(&path, &text);
        assert_eq!(assert_valid(kind.name(), api_of(kind), kind.is_implicit(), &text, &path), lib);
        // `stereoshim manifest KIND` prints the same.
        let printed = Command::new(target_dir().join("stereoshim")).args(["manifest", kind.name(), "--library"]).arg(&lib).output().unwrap();
        assert!(printed.status.success(), "{}", String::from_utf8_lossy(&printed.stderr));
        assert_eq!(String::from_utf8_lossy(&printed.stdout), text);
    }
    // The file `stereoshim install --user` writes.
    let data = out.join("install-data");
    let installed = Command::new(target_dir().join("stereoshim"))
        .args(["install", "--user", "--library"])
        .arg(&lib)
        .env("XDG_DATA_HOME", &data)
        .output()
        .unwrap();
    assert!(installed.status.success(), "{}", String::from_utf8_lossy(&installed.stderr));
    let path = data.join("openxr/1/api_layers/implicit.d").join(manifest::MANIFEST_FILE);
    let text = std::fs::read_to_string(&path).unwrap();
    assert_valid("installed implicit manifest", Api::OpenXr, true, &text, &path);
    // The test harness's manifests.
    let dir = common::layer_manifest_dir();
    let path = dir.join(manifest::MANIFEST_FILE);
    assert_valid("tests/common OpenXR manifest", Api::OpenXr, false, &std::fs::read_to_string(&path).unwrap(), &path);
    let dir = common::vulkan_layer_dir(manifest::VK_LAYER_NAME);
    let path = dir.join(manifest::MANIFEST_FILE);
    assert_valid("tests/common Vulkan manifest", Api::Vulkan, false, &std::fs::read_to_string(&path).unwrap(), &path);
}

#[test]
fn the_rules_reject_what_the_loaders_reject() {
    let lib = library();
    let path = common::output_dir("manifests-bad").join("m.json");
    let edit = |kind: Kind, f: &dyn Fn(&mut Value)| {
        let mut v: Value = serde_json::from_str(&manifest::json(kind, &lib)).unwrap();
        f(&mut v);
        v.to_string()
    };
    let bad: Vec<(&str, Api, bool, String)> = vec![
        // Issue 8: Vulkan loader 1.4 lists this layer without its library path.
        ("numeric implementation_version", Api::Vulkan, false, edit(Kind::Vulkan, &|v| v["layer"]["implementation_version"] = 1.into())),
        ("numeric api_version", Api::Vulkan, false, edit(Kind::Vulkan, &|v| v["layer"]["api_version"] = 1.3.into())),
        ("two-part Vulkan api_version", Api::Vulkan, false, edit(Kind::Vulkan, &|v| v["layer"]["api_version"] = "1.3".into())),
        ("Vulkan file format 1.3.0", Api::Vulkan, false, edit(Kind::Vulkan, &|v| v["file_format_version"] = "1.3.0".into())),
        ("no type", Api::Vulkan, false, edit(Kind::Vulkan, &|v| drop(v["layer"].as_object_mut().unwrap().remove("type")))),
        ("Vulkan disable_environment as a string", Api::Vulkan, true, edit(Kind::Vulkan, &|v| v["layer"]["disable_environment"] = "X".into())),
        ("implicit Vulkan layer without disable_environment", Api::Vulkan, true, edit(Kind::Vulkan, &|_| {})),
        ("missing library", Api::Vulkan, false, edit(Kind::Vulkan, &|v| v["layer"]["library_path"] = "/nonexistent/libx.so".into())),
        ("unexported entry point", Api::Vulkan, false, edit(Kind::Vulkan, &|v| v["layer"]["functions"][manifest::VK_NEGOTIATE] = "vkGetInstanceProcAddr".into())),
        ("OpenXR file format 1.0.1", Api::OpenXr, false, edit(Kind::OpenXr, &|v| v["file_format_version"] = "1.0.1".into())),
        ("numeric OpenXR implementation_version", Api::OpenXr, false, edit(Kind::OpenXr, &|v| v["api_layer"]["implementation_version"] = 1.into())),
        ("three-part OpenXR api_version", Api::OpenXr, false, edit(Kind::OpenXr, &|v| v["api_layer"]["api_version"] = "1.0.0".into())),
        ("implicit OpenXR layer without disable_environment", Api::OpenXr, true, edit(Kind::OpenXr, &|_| {})),
        ("disable_environment on an explicit layer", Api::OpenXr, false, edit(Kind::OpenXrImplicit, &|_| {})),
        ("bad layer name", Api::OpenXr, false, edit(Kind::OpenXr, &|v| v["api_layer"]["name"] = "stereoshim".into())),
        ("relative library name", Api::OpenXr, false, edit(Kind::OpenXr, &|v| v["api_layer"]["library_path"] = "libstereoshim.so".into())),
    ];
    for (what, api, implicit, text) in bad {
        let (problems, _) = check(api, implicit, &text, &path);
        assert!(!problems.is_empty(), "the rules accept a manifest with {what}:\n{text}");
    }
}

// ---------------------------------------------------------------------------------------------
// Real loaders.
// ---------------------------------------------------------------------------------------------

const LIBDIR: &str = "usr/lib/x86_64-linux-gnu";

/// One set of loaders: bookworm's (this machine's, `root` = `/`) or those under another root,
/// run through that root's own dynamic linker (trixie's loaders need its newer libc).
struct Loaders {
    label: &'static str,
    root: PathBuf,
}

impl Loaders {
    fn vulkan(&self) -> PathBuf {
        self.root.join(LIBDIR).join("libvulkan.so.1")
    }
    fn openxr(&self) -> PathBuf {
        self.root.join(LIBDIR).join("libopenxr_loader.so.1")
    }

    /// What runs a program with this set's libraries first (nothing for this machine's).
    fn wrapper(&self) -> Vec<std::ffi::OsString> {
        if self.root == Path::new("/") {
            return Vec::new();
        }
        let ld = self.root.join(LIBDIR).join("ld-linux-x86-64.so.2");
        vec![ld.into(), "--library-path".into(), self.root.join(LIBDIR).into()]
    }

    /// The probe: this test binary's `loader_probe_child`, with the root's libraries first.
    fn probe(&self, mode: &str, env: &[(&str, &Path)], extra: &[(&str, &str)]) -> Probe {
        let exe = std::env::current_exe().unwrap();
        let wrapper = self.wrapper();
        let mut cmd = match wrapper.split_first() {
            None => Command::new(&exe),
            Some((ld, rest)) => {
                assert!(Path::new(ld).is_file(), "{}: no dynamic linker {:?}", self.label, ld);
                let mut c = Command::new(ld);
                c.args(rest).arg(&exe);
                c
            }
        };
        // Its full name in the test binary (`--exact`): the probe is a test of this module.
        cmd.args(["--exact", "manifests::loader_probe_child", "--nocapture", "--test-threads=1"]);
        // Nothing from the developer's setup; lavapipe only.
        for k in ["VK_INSTANCE_LAYERS", "VK_ADD_LAYER_PATH", "VK_LAYER_PATH", "XR_API_LAYER_PATH", "XR_ENABLE_API_LAYERS", "STEREOSHIM_DISABLE", "VK_DRIVER_FILES"] {
            cmd.env_remove(k);
        }
        let icd = [self.root.join("usr/share/vulkan/icd.d/lvp_icd.json"), self.root.join("usr/share/vulkan/icd.d/lvp_icd.x86_64.json")]
            .into_iter()
            .chain([PathBuf::from("/usr/share/vulkan/icd.d/lvp_icd.json"), PathBuf::from("/usr/share/vulkan/icd.d/lvp_icd.x86_64.json")])
            .find(|p| p.is_file())
            .expect("a lavapipe ICD manifest");
        // Private XDG folders: no manifest of the developer's, the layer's log and generated
        // manifest inside the test's output.
        static N: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
        let dir = common::output_dir(&format!("manifests-{}-probe-{}", self.label, N.fetch_add(1, std::sync::atomic::Ordering::Relaxed)));
        for (k, sub) in [("XDG_DATA_HOME", "data"), ("XDG_CONFIG_HOME", "config"), ("XDG_STATE_HOME", "state"), ("XDG_RUNTIME_DIR", "run")] {
            cmd.env(k, dir.join(sub));
        }
        cmd.env("VK_ICD_FILENAMES", icd)
            .env("VK_LOADER_DEBUG", "all")
            .env("XR_LOADER_DEBUG", "all")
            .env("XR_RUNTIME_JSON", common::runtime_manifest())
            .env("XDG_CONFIG_DIRS", "/nonexistent")
            .env("XDG_DATA_DIRS", "/nonexistent")
            .env("STEREOSHIM_PROBE", mode)
            .env("STEREOSHIM_PROBE_VULKAN", self.vulkan())
            .env("STEREOSHIM_PROBE_OPENXR", self.openxr());
        for (k, v) in env {
            cmd.env(k, v);
        }
        for (k, v) in extra {
            cmd.env(k, v);
        }
        let out = run_with_watchdog(cmd, &dir, Duration::from_secs(60));
        let log = std::fs::read_to_string(dir.join("state/stereoshim/stereoshim.log")).unwrap_or_default();
        let probe = Probe { label: format!("{} {mode} {env:?} {extra:?}", self.label), out, log };
        // The loaders in the process are this set's, not whatever the system has.
        let ours: Vec<PathBuf> = [self.vulkan(), self.openxr()].iter().filter_map(|p| std::fs::canonicalize(p).ok()).collect();
        let loaders = probe.values("loader");
        assert!(!loaders.is_empty(), "{}: no loader mapped:\n{}", probe.label, probe.out);
        for l in loaders {
            assert!(ours.iter().any(|o| o == Path::new(l)), "{}: loader {l} is not one of {ours:?}:\n{}", probe.label, probe.out);
        }
        let version = probe.vulkan_loader_version();
        eprintln!("{}: loaders {:?}, Vulkan loader version {}", probe.label, probe.values("loader"), version.as_deref().unwrap_or("(not reported)"));
        probe
    }
}

/// Runs `cmd` with its output in `dir`, killing it when it hangs: more than `cpu_budget` of CPU
/// time, or none for a minute (`common::watchdog`: load beside the suite cannot fake a hang).
fn run_with_watchdog(mut cmd: Command, dir: &Path, cpu_budget: Duration) -> String {
    use std::process::Stdio;
    let (o, e) = (dir.join("stdout"), dir.join("stderr"));
    cmd.stdout(Stdio::from(std::fs::File::create(&o).unwrap())).stderr(Stdio::from(std::fs::File::create(&e).unwrap()));
    let mut child = cmd.spawn().expect("spawn the probe");
    let mut watchdog = common::watchdog::Watchdog::new(child.id(), cpu_budget);
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break Ok(s);
        }
        if let Some(why) = watchdog.hung() {
            let _ = child.kill(); // our own child, by its handle
            let _ = child.wait();
            break Err(why);
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    let text = std::fs::read_to_string(&o).unwrap_or_default() + &std::fs::read_to_string(&e).unwrap_or_default();
    match status {
        Err(why) => panic!("the probe hung: {why} (killed):\n{text}"),
        Ok(s) if !s.success() => panic!("the probe failed ({s}):\n{text}"),
        Ok(_) => text,
    }
}

struct Probe {
    label: String,
    out: String,
    /// The layer's log file in the probe (empty: the layer's code never ran).
    log: String,
}

impl Probe {
    /// The value of `PROBE key value` lines.
    fn values(&self, key: &str) -> Vec<&str> {
        let prefix = format!("PROBE {key} ");
        self.out.lines().filter_map(|l| l.strip_prefix(&prefix)).collect()
    }
    fn value(&self, key: &str) -> &str {
        self.values(key).first().copied().unwrap_or_else(|| panic!("{}: no `PROBE {key}` line:\n{}", self.label, self.out))
    }
    fn expect(&self, key: &str, want: &str) {
        assert_eq!(self.value(key), want, "{}: {key}\n{}", self.label, self.out);
    }
    /// The loader put the layer into the instance chain with `library` (not `(null)`), and the
    /// library is mapped in the process.
    fn assert_vulkan_layer_loaded(&self, library: &Path) {
        self.assert_inserted(library);
        self.assert_mapped(library);
    }
    fn assert_inserted(&self, library: &Path) {
        let insert = format!("Insert instance layer \"{}\" (", manifest::VK_LAYER_NAME);
        let shown: Vec<&str> = self.out.lines().filter_map(|l| l.split_once(&insert)).filter_map(|(_, rest)| rest.strip_suffix(')')).collect();
        assert!(
            !shown.is_empty() && shown.iter().all(|p| std::fs::canonicalize(p).ok().as_deref() == Some(library)),
            "{}: the Vulkan loader's debug output must show `{insert}{})` (got {shown:?}):\n{}",
            self.label,
            library.display(),
            self.out
        );
        assert!(!self.out.contains("((null))"), "{}: a layer without library path:\n{}", self.label, self.out);
    }
    /// The version the Vulkan loader reports in its debug output.
    fn vulkan_loader_version(&self) -> Option<String> {
        self.out.lines().find_map(|l| l.split_once("Vulkan Loader Version ").map(|(_, v)| v.trim().to_string()))
    }
    fn assert_mapped(&self, library: &Path) {
        assert!(self.log.contains("stereoshim loaded"), "{}: the layer wrote no log:\n{}", self.label, self.out);
        let mapped = self.values("mapped");
        assert!(mapped.contains(&library.to_str().unwrap()), "{}: {} not mapped (mapped: {mapped:?}):\n{}", self.label, library.display(), self.out);
    }
    fn assert_not_mapped(&self) {
        assert!(self.log.is_empty(), "{}: the layer ran:\n{}", self.label, self.log);
        assert!(self.values("mapped").is_empty(), "{}: the layer was loaded:\n{}", self.label, self.out);
    }
    /// None of the loaders' complaints (their wording in loader.c and manifest_file.cpp) about our
    /// manifests or library.
    fn assert_no_loader_complaint(&self) {
        const COMPLAINTS: &[&str] = &[
            // Vulkan loader
            "skipping this layer",
            "Skipping layer",
            "didn't find required",
            "unknown layer manifest file version",
            "does not conform to naming standard",
            "((null))",
            "Problem accessing",
            "Failed to find",
            // OpenXR loader
            "is missing required fields",
            "is missing \"disable_environment\"",
            "is not supported",
            "has invalid API Version",
            "does not appear to exist",
            "failed to parse",
            "contains non-string values",
            "is not a valid manifest file",
        ];
        // Lines about our manifests or library (file stereoshim.json, libstereoshim.so, our names).
        for line in self.out.lines().filter(|l| l.to_ascii_lowercase().contains("stereoshim")) {
            if let Some(c) = COMPLAINTS.iter().find(|c| line.contains(*c)) {
                panic!("{}: a loader complains ({c:?}): {line}\n{}", self.label, self.out);
            }
        }
    }
    /// The OpenXR loader reports loading our API layer.
    fn assert_openxr_layer_loaded(&self, library: &Path) {
        let line = format!("succeeded loading layer {}", manifest::XR_LAYER_NAME);
        assert!(self.out.contains(&line), "{}: the OpenXR loader's debug output lacks `{line}`:\n{}", self.label, self.out);
        self.assert_mapped(library);
    }
}

/// What the probe reports about our layer in the enumeration: `spec=… impl=…`.
fn expected_vk_listing() -> String {
    format!("spec={} impl={}", manifest::vk_api_version(), manifest::IMPLEMENTATION_VERSION)
}
fn expected_xr_listing() -> String {
    format!("spec={}.0 impl={}", manifest::xr_api_version(), manifest::IMPLEMENTATION_VERSION)
}

fn check_loaders(loaders: &Loaders) {
    for lib in [loaders.vulkan(), loaders.openxr()] {
        assert!(lib.exists(), "{}: {} missing", loaders.label, lib.display());
    }
    let lib = library();
    let out = common::output_dir(&format!("manifests-{}", loaders.label));

    // 1. The Vulkan manifest, explicit (VK_LAYER_PATH, named in the create info).
    let dir = out.join("vulkan");
    write(&dir.join(manifest::MANIFEST_FILE), &manifest::json(Kind::Vulkan, &lib));
    let p = loaders.probe("vulkan", &[("VK_LAYER_PATH", &dir)], &[("STEREOSHIM_PROBE_ENABLE", "1")]);
    p.expect("vk-layer", &expected_vk_listing());
    p.expect("vk-instance", "ok");
    p.assert_vulkan_layer_loaded(&lib);
    p.assert_no_loader_complaint();
    let vulkan_version = p.vulkan_loader_version().expect("the Vulkan loader reports its version");

    // 2. The shipped Vulkan manifest, in place, where this tree has a debug build.
    let debug_lib = repo().join("target/debug/libstereoshim.so");
    if debug_lib.is_file() {
        let p = loaders.probe("vulkan", &[("VK_LAYER_PATH", &repo().join("manifest/vulkan"))], &[("STEREOSHIM_PROBE_ENABLE", "1")]);
        p.expect("vk-instance", "ok");
        p.assert_vulkan_layer_loaded(&std::fs::canonicalize(&debug_lib).unwrap());
        p.assert_no_loader_complaint();
    }

    // 3. The explicit OpenXR manifest (`stereoshim run`), named in the create info.
    let dir = out.join("openxr");
    write(&dir.join(manifest::MANIFEST_FILE), &manifest::json(Kind::OpenXr, &lib));
    let p = loaders.probe("openxr", &[("XR_API_LAYER_PATH", &dir)], &[("STEREOSHIM_PROBE_ENABLE", "1")]);
    p.expect("xr-layer", &expected_xr_listing());
    p.expect("xr-instance", "SUCCESS");
    p.assert_openxr_layer_loaded(&lib);
    p.assert_no_loader_complaint();

    // 4. The shipped explicit OpenXR manifest, in place.
    if debug_lib.is_file() {
        let p = loaders.probe("openxr", &[("XR_API_LAYER_PATH", &repo().join("manifest/openxr"))], &[("STEREOSHIM_PROBE_ENABLE", "1")]);
        p.expect("xr-instance", "SUCCESS");
        p.assert_openxr_layer_loaded(&std::fs::canonicalize(&debug_lib).unwrap());
        p.assert_no_loader_complaint();
    }

    // 5. The implicit OpenXR manifest as `stereoshim install --user` writes it: loaded without
    // being named; kept out by the disable variable.
    let data = out.join("data");
    let installed = Command::new(target_dir().join("stereoshim")).args(["install", "--user", "--library"]).arg(&lib).env("XDG_DATA_HOME", &data).output().unwrap();
    assert!(installed.status.success(), "{}", String::from_utf8_lossy(&installed.stderr));
    let installed_lib = std::fs::canonicalize(data.join("stereoshim/libstereoshim.so")).unwrap();
    let p = loaders.probe("openxr", &[("XDG_DATA_HOME", &data)], &[]);
    p.expect("xr-layer", &expected_xr_listing());
    p.expect("xr-instance", "SUCCESS");
    p.assert_openxr_layer_loaded(&installed_lib);
    p.assert_no_loader_complaint();
    let p = loaders.probe("openxr", &[("XDG_DATA_HOME", &data)], &[(manifest::DISABLE_ENV, "1")]);
    assert!(p.values("xr-layer").is_empty(), "{}: listed although disabled:\n{}", p.label, p.out);
    p.expect("xr-instance", "SUCCESS");
    p.assert_not_mapped();

    // 6. The Vulkan manifest the OpenXR half writes at run time: an XR_KHR_vulkan_enable app asks
    // for the instance extensions, then creates its VkInstance naming no layer.
    let run = out.join("run");
    let p = loaders.probe("openxr-vulkan", &[("XR_API_LAYER_PATH", &out.join("openxr")), ("XDG_RUNTIME_DIR", &run)], &[("STEREOSHIM_PROBE_ENABLE", "1")]);
    p.expect("xr-instance", "SUCCESS");
    p.expect("vk-instance", "ok");
    p.assert_vulkan_layer_loaded(&lib);
    p.assert_no_loader_complaint();
    let generated_dir = PathBuf::from(p.value("VK_ADD_LAYER_PATH").split(':').next().unwrap());
    assert!(generated_dir.starts_with(&run), "{}: {} is not under XDG_RUNTIME_DIR", p.label, generated_dir.display());
    let path = generated_dir.join(manifest::MANIFEST_FILE);
    let text = std::fs::read_to_string(&path).unwrap();
    assert_valid("the Vulkan manifest the OpenXR half wrote", Api::Vulkan, false, &text, &path);
    assert_eq!(text, manifest::json(Kind::Vulkan, &lib));

    // 7. The manifest of issue 8 (numeric implementation_version): the rules reject it, and the
    // loaders misread it (1.3.239 lists version 0; 1.4.309 "skips" it but lists it without a
    // library, and an instance with it then hangs). Enumeration only: creating the instance would
    // hang the probe.
    let dir = out.join("numeric");
    let mut v: Value = serde_json::from_str(&manifest::json(Kind::Vulkan, &lib)).unwrap();
    v["layer"]["implementation_version"] = 1.into();
    let text = serde_json::to_string_pretty(&v).unwrap();
    let path = dir.join(manifest::MANIFEST_FILE);
    write(&path, &text);
    assert!(!check(Api::Vulkan, false, &text, &path).0.is_empty(), "the rules accept a numeric implementation_version");
    let p = loaders.probe("vulkan-enumerate", &[("VK_LAYER_PATH", &dir)], &[]);
    assert_ne!(p.value("vk-layer"), expected_vk_listing(), "{}: the loader read a numeric implementation_version right", p.label);

    // 8. An app: xr-scene (validation on) with the layer as `stereoshim run` gives it, both Vulkan
    // bindings, through these loaders: the Vulkan half joins through the generated manifest.
    for vulkan in ["enable", "enable2"] {
        let name = format!("manifests-{}-xr-scene-{vulkan}", loaders.label);
        let mut run = common::Run::new(&name).args(["--vulkan", vulkan]).with_layer().env("VK_LOADER_DEBUG", "info,layer");
        run.wrapper = loaders.wrapper();
        let out = run.run();
        out.assert_ok();
        let p = Probe { label: name.clone(), out: out.stderr.clone(), log: out.log.clone() };
        assert_eq!(p.vulkan_loader_version().as_deref(), Some(vulkan_version.as_str()), "{name}: another Vulkan loader:\n{}", out.stderr);
        p.assert_inserted(&lib);
        p.assert_no_loader_complaint();
        assert_eq!(out.log_lines("the Vulkan half tracks this device").len(), 1, "{name}: {}", out.log);
    }
}

#[test]
fn bookworm_loaders_load_every_manifest() {
    check_loaders(&Loaders { label: "bookworm", root: PathBuf::from("/") });
}

/// `STEREOSHIM_TRIXIE_ROOT`: a folder with trixie's `usr/lib/x86_64-linux-gnu/libvulkan.so.1`,
/// `libopenxr_loader.so.1`, and what they need (`ld-linux-x86-64.so.2`, `libc.so.6`,
/// `libstdc++.so.6`, `libgcc_s.so.1`, `libjsoncpp.so.26`), e.g. the trixie root of
/// `tests/realworld/`. Unset: the test says it was skipped, and fails when
/// `STEREOSHIM_REQUIRE_TRIXIE` is set (CI sets it where the root is built).
#[test]
fn trixie_loaders_load_every_manifest() {
    match std::env::var_os("STEREOSHIM_TRIXIE_ROOT").filter(|r| !r.is_empty()) {
        Some(root) => check_loaders(&Loaders { label: "trixie", root: PathBuf::from(root) }),
        None if std::env::var_os("STEREOSHIM_REQUIRE_TRIXIE").is_some() => {
            panic!("STEREOSHIM_REQUIRE_TRIXIE is set but STEREOSHIM_TRIXIE_ROOT is not")
        }
        None => eprintln!("SKIPPED trixie_loaders_load_every_manifest: STEREOSHIM_TRIXIE_ROOT is not set"),
    }
}

// ---------------------------------------------------------------------------------------------
// The probe process (does nothing unless STEREOSHIM_PROBE is set).
// ---------------------------------------------------------------------------------------------

fn report_mapped() {
    let maps = std::fs::read_to_string("/proc/self/maps").unwrap_or_default();
    let mut seen = std::collections::BTreeSet::new();
    for path in maps.lines().filter_map(|l| l.split_whitespace().nth(5)) {
        let name = Path::new(path).file_name().and_then(|n| n.to_str()).unwrap_or("");
        let key = if name == "libstereoshim.so" {
            "mapped"
        } else if name.starts_with("libvulkan.so") || name.starts_with("libopenxr_loader.so") {
            "loader"
        } else {
            continue;
        };
        if seen.insert(path.to_string()) {
            println!("PROBE {key} {path}");
        }
    }
}

/// Loads a loader library into the global symbol scope, as a program linked against it has it
/// (so a manifest the loader half-reads, whose entry points it then looks up globally, finds the
/// loader's own functions: the hang of issue 8, caught by the probe's time limit).
fn load_global(path: &std::ffi::OsStr) -> libloading::os::unix::Library {
    use libloading::os::unix::{Library, RTLD_GLOBAL, RTLD_NOW};
    // SAFETY: a loader library; its initialisers are safe to run.
    unsafe { Library::open(Some(path), RTLD_NOW | RTLD_GLOBAL) }.unwrap_or_else(|e| panic!("load {path:?}: {e}"))
}

fn probe_vulkan(enable: bool, create: bool) {
    use ash::vk;
    let path = std::env::var_os("STEREOSHIM_PROBE_VULKAN").expect("STEREOSHIM_PROBE_VULKAN");
    let lib = load_global(&path);
    // SAFETY: the loader's exported entry point, with this type.
    let gipa = unsafe { *lib.get::<vk::PFN_vkGetInstanceProcAddr>(b"vkGetInstanceProcAddr").expect("vkGetInstanceProcAddr") };
    // SAFETY: a loader's vkGetInstanceProcAddr; the library stays loaded (leaked below).
    let entry = unsafe { ash::Entry::from_static_fn(ash::StaticFn { get_instance_proc_addr: gipa }) };
    std::mem::forget(lib);
    // SAFETY: global command.
    for p in unsafe { entry.enumerate_instance_layer_properties() }.expect("vkEnumerateInstanceLayerProperties") {
        if p.layer_name_as_c_str().is_ok_and(|n| n.to_bytes() == manifest::VK_LAYER_NAME.as_bytes()) {
            let s = p.spec_version;
            println!("PROBE vk-layer spec={}.{}.{} impl={}", vk::api_version_major(s), vk::api_version_minor(s), vk::api_version_patch(s), p.implementation_version);
        }
    }
    if !create {
        report_mapped();
        return;
    }
    let layer = std::ffi::CString::new(manifest::VK_LAYER_NAME).unwrap();
    let layers = [layer.as_ptr()];
    let app = vk::ApplicationInfo::default().api_version(vk::API_VERSION_1_1);
    let mut ci = vk::InstanceCreateInfo::default().application_info(&app);
    if enable {
        ci = ci.enabled_layer_names(&layers);
    }
    // SAFETY: valid create info.
    match unsafe { entry.create_instance(&ci, None) } {
        Ok(instance) => {
            println!("PROBE vk-instance ok");
            report_mapped();
            // SAFETY: created above, nothing derived from it.
            unsafe { instance.destroy_instance(None) };
        }
        Err(e) => println!("PROBE vk-instance {e:?}"),
    }
}

fn probe_openxr(enable: bool, vulkan: bool) {
    use openxr_sys as xr;
    use xr::Handle as _;
    use std::ffi::{c_char, CStr};
    let path = std::env::var_os("STEREOSHIM_PROBE_OPENXR").expect("STEREOSHIM_PROBE_OPENXR");
    let lib = load_global(&path);
    // SAFETY: exported core functions of the loader, with these types.
    let (enumerate, create, destroy, get_system, gipa) = unsafe {
        (
            *lib.get::<xr::pfn::EnumerateApiLayerProperties>(b"xrEnumerateApiLayerProperties").unwrap(),
            *lib.get::<xr::pfn::CreateInstance>(b"xrCreateInstance").unwrap(),
            *lib.get::<xr::pfn::DestroyInstance>(b"xrDestroyInstance").unwrap(),
            *lib.get::<xr::pfn::GetSystem>(b"xrGetSystem").unwrap(),
            *lib.get::<xr::pfn::GetInstanceProcAddr>(b"xrGetInstanceProcAddr").unwrap(),
        )
    };
    let mut count = 0;
    // SAFETY: two-call idiom with valid pointers.
    assert_eq!(unsafe { enumerate(0, &mut count, std::ptr::null_mut()) }, xr::Result::SUCCESS);
    // SAFETY: plain C structs; ty set below.
    let mut props: Vec<xr::ApiLayerProperties> = (0..count).map(|_| unsafe { std::mem::zeroed() }).collect();
    props.iter_mut().for_each(|p| p.ty = xr::ApiLayerProperties::TYPE);
    // SAFETY: as above.
    assert_eq!(unsafe { enumerate(count, &mut count, props.as_mut_ptr()) }, xr::Result::SUCCESS);
    for p in &props[..count as usize] {
        // SAFETY: the loader writes NUL-terminated names.
        if unsafe { CStr::from_ptr(p.layer_name.as_ptr()) }.to_bytes() == manifest::XR_LAYER_NAME.as_bytes() {
            println!("PROBE xr-layer spec={}.{}.{} impl={}", p.spec_version.major(), p.spec_version.minor(), p.spec_version.patch(), p.layer_version);
        }
    }
    let layer = std::ffi::CString::new(manifest::XR_LAYER_NAME).unwrap();
    let layers = [layer.as_ptr()];
    let exts = [c"XR_KHR_vulkan_enable".as_ptr()];
    // SAFETY: plain C struct.
    let mut app: xr::ApplicationInfo = unsafe { std::mem::zeroed() };
    for (d, s) in app.application_name.iter_mut().zip(b"manifest-probe") {
        *d = *s as c_char;
    }
    app.api_version = xr::Version::new(1, 0, 0);
    let ci = xr::InstanceCreateInfo {
        ty: xr::InstanceCreateInfo::TYPE,
        next: std::ptr::null(),
        create_flags: xr::InstanceCreateFlags::EMPTY,
        application_info: app,
        enabled_api_layer_count: if enable { 1 } else { 0 },
        enabled_api_layer_names: layers.as_ptr(),
        enabled_extension_count: if vulkan { 1 } else { 0 },
        enabled_extension_names: exts.as_ptr(),
    };
    let mut instance = xr::Instance::NULL;
    // SAFETY: valid create info.
    let r = unsafe { create(&ci, &mut instance) };
    println!("PROBE xr-instance {r:?}");
    if r != xr::Result::SUCCESS {
        return;
    }
    report_mapped();
    if vulkan {
        let info = xr::SystemGetInfo { ty: xr::SystemGetInfo::TYPE, next: std::ptr::null(), form_factor: xr::FormFactor::HEAD_MOUNTED_DISPLAY };
        let mut system = xr::SystemId::NULL;
        // SAFETY: valid arguments.
        assert_eq!(unsafe { get_system(instance, &info, &mut system) }, xr::Result::SUCCESS);
        let mut f = None;
        // SAFETY: valid arguments; the extension is enabled.
        assert_eq!(unsafe { gipa(instance, c"xrGetVulkanInstanceExtensionsKHR".as_ptr(), &mut f) }, xr::Result::SUCCESS);
        // SAFETY: the function for this name has this type.
        let get_exts: xr::pfn::GetVulkanInstanceExtensionsKHR = unsafe { std::mem::transmute(f.unwrap()) };
        let mut n = 0;
        // SAFETY: two-call idiom.
        assert_eq!(unsafe { get_exts(instance, system, 0, &mut n, std::ptr::null_mut()) }, xr::Result::SUCCESS);
        let mut buf = vec![0 as c_char; n as usize];
        // SAFETY: as above.
        assert_eq!(unsafe { get_exts(instance, system, n, &mut n, buf.as_mut_ptr()) }, xr::Result::SUCCESS);
        for k in ["VK_ADD_LAYER_PATH", "VK_INSTANCE_LAYERS"] {
            println!("PROBE {k} {}", std::env::var(k).unwrap_or_default());
        }
        // The app now creates its own instance, naming no layer.
        probe_vulkan(false, true);
    }
    // SAFETY: created above.
    unsafe { destroy(instance) };
}

#[test]
fn loader_probe_child() {
    let Ok(mode) = std::env::var("STEREOSHIM_PROBE") else { return };
    let enable = std::env::var_os("STEREOSHIM_PROBE_ENABLE").is_some();
    println!(); // libtest's "test loader_probe_child ... " has no newline
    match mode.as_str() {
        "vulkan" => probe_vulkan(enable, true),
        "vulkan-enumerate" => probe_vulkan(enable, false),
        "openxr" => probe_openxr(enable, false),
        "openxr-vulkan" => probe_openxr(enable, true),
        m => panic!("unknown probe mode {m}"),
    }
    println!("PROBE done 1");
}
