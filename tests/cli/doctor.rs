//! `stereoshim doctor` end to end, in a controlled environment (HOME and the XDG folders in a
//! fresh folder, the mock runtime as the active runtime, the layer installed with
//! `stereoshim install --user`, lavapipe as the Vulkan device): a healthy setup exits 0 with ok
//! lines; each broken setup (no runtime, damaged manifest, no Vulkan device, bad config, a
//! conflicting variable) gives the right finding and fix, and exit 1 exactly when it is an error.

use crate::common;

use common::target_dir;
use serde_json::Value;
use std::os::unix::fs::PermissionsExt;
use std::path::{Path, PathBuf};
use std::process::Command;

/// A private home for one test: XDG folders inside it, none of the developer's own settings.
/// `XDG_DATA_DIRS` / `XDG_CONFIG_DIRS` stay the system's: the Vulkan loader finds its drivers there.
struct Home {
    dir: PathBuf,
}

impl Home {
    fn new(name: &str) -> Home {
        let dir = common::output_dir(name);
        for sub in ["config", "data", "state", "run"] {
            std::fs::create_dir_all(dir.join(sub)).unwrap();
        }
        // XDG_RUNTIME_DIR must be the user's alone for the layer to write its Vulkan manifest.
        std::fs::set_permissions(dir.join("run"), std::fs::Permissions::from_mode(0o700)).unwrap();
        Home { dir }
    }

    fn command(&self, args: &[&str]) -> Command {
        let mut cmd = Command::new(target_dir().join("stereoshim"));
        cmd.args(args)
            .env("HOME", &self.dir)
            .env("XDG_CONFIG_HOME", self.dir.join("config"))
            .env("XDG_DATA_HOME", self.dir.join("data"))
            .env("XDG_STATE_HOME", self.dir.join("state"))
            .env("XDG_RUNTIME_DIR", self.dir.join("run"))
            .env("XR_RUNTIME_JSON", common::runtime_manifest())
            .env("NO_COLOR", "1");
        for var in ["XR_API_LAYER_PATH", "XR_ENABLE_API_LAYERS", "VK_LAYER_PATH", "VK_ADD_LAYER_PATH", "VK_INSTANCE_LAYERS", "VK_LOADER_LAYERS_DISABLE"] {
            cmd.env_remove(var);
        }
        for (key, _) in std::env::vars_os() {
            if key.to_string_lossy().starts_with("STEREOSHIM_") {
                cmd.env_remove(key);
            }
        }
        cmd
    }

    fn install(&self) -> PathBuf {
        let out = self.command(&["install", "--user"]).output().unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        self.dir.join("data/openxr/1/api_layers/implicit.d/stereoshim.json")
    }

    fn config(&self, toml: &str) {
        std::fs::create_dir_all(self.dir.join("config/stereoshim")).unwrap();
        std::fs::write(self.dir.join("config/stereoshim/config.toml"), toml).unwrap();
    }
}

/// One `doctor --json` run: exit code and findings.
struct Doctor {
    code: i32,
    findings: Vec<Value>,
    text: String,
}

impl Doctor {
    fn run(mut cmd: Command) -> Doctor {
        let out = cmd.arg("--json").output().expect("run stereoshim doctor");
        let text = format!("{}{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
        let v: Value = serde_json::from_slice(&out.stdout).unwrap_or_else(|e| panic!("doctor --json is not JSON ({e}): {text}"));
        let findings = v["findings"].as_array().cloned().unwrap_or_default();
        let code = out.status.code().unwrap_or(-1);
        assert_eq!(v["exit_code"].as_i64(), Some(code as i64), "{text}");
        Doctor { code, findings, text }
    }

    /// Findings of `check` (exact, or `check.N`).
    fn of(&self, check: &str) -> Vec<&Value> {
        self.findings
            .iter()
            .filter(|f| f["check"].as_str().is_some_and(|c| c == check || c.strip_prefix(check).is_some_and(|r| r.starts_with('.') && r[1..].parse::<u32>().is_ok())))
            .collect()
    }

    fn has(&self, check: &str, status: &str, detail: &str) -> bool {
        self.of(check).iter().any(|f| f["status"] == status && f["detail"].as_str().is_some_and(|d| d.contains(detail)))
    }

    fn fix(&self, check: &str, status: &str) -> String {
        self.of(check).iter().find(|f| f["status"] == status).and_then(|f| f["fix"].as_str()).unwrap_or_default().to_string()
    }

    fn statuses(&self, status: &str) -> Vec<&Value> {
        self.findings.iter().filter(|f| f["status"] == status).collect()
    }
}

fn doctor(home: &Home, args: &[&str]) -> Doctor {
    let mut all = vec!["doctor"];
    all.extend_from_slice(args);
    Doctor::run(home.command(&all))
}

#[test]
fn healthy_setup_is_all_ok() {
    let home = Home::new("doctor-healthy");
    home.install();
    let d = doctor(&home, &[]);
    assert_eq!(d.code, 0, "{}", d.text);
    assert!(d.statuses("error").is_empty(), "{}", d.text);
    assert!(d.has("openxr.loader", "ok", "libopenxr_loader.so"), "{}", d.text);
    assert!(d.has("openxr.runtime", "ok", "(XR_RUNTIME_JSON) -> "), "{}", d.text);
    assert!(d.has("openxr.runtime", "ok", "libmock_runtime.so"), "{}", d.text);
    // The instance went through the OpenXR loader with the installed layer in its chain.
    assert!(d.has("openxr.instance", "ok", "mock"), "{}", d.text);
    assert!(d.has("openxr.extensions", "ok", "XR_KHR_vulkan_enable2, XR_KHR_vulkan_enable; XR_KHR_visibility_mask"), "{}", d.text);
    assert!(d.has("layer.manifest", "ok", ", this build"), "{}", d.text);
    assert!(d.has("layer.vulkan", "ok", "negotiates Vulkan loader interface 2"), "{}", d.text);
    assert!(d.has("vulkan.manifest", "ok", "the Vulkan loader lists VK_LAYER_STEREOSHIM_stereoshim"), "{}", d.text);
    assert!(d.has("vulkan.loader", "ok", "libvulkan.so"), "{}", d.text);
    assert!(d.has("vulkan.device", "ok", "multiview yes"), "{}", d.text);
    assert!(d.has("foveation", "ok", "foveation.method = auto -> "), "{}", d.text);
    assert!(d.has("config", "ok", "(absent: defaults): no key set"), "{}", d.text);
    // Only lavapipe here: the one warning allowed says so.
    for w in d.statuses("warning") {
        assert!(w["detail"].as_str().unwrap().contains("CPU implementation"), "unexpected warning: {w}\n{}", d.text);
    }

    // The same as a table: aligned words, no colour codes when not a terminal, a summary.
    let out = home.command(&["doctor", "--app", "xr-scene"]).output().unwrap();
    let table = String::from_utf8_lossy(&out.stdout);
    assert_eq!(out.status.code(), Some(0), "{table}");
    assert!(!table.contains('\x1b'), "{table}");
    // Status word in 7 columns, two spaces, the check padded to the longest, two spaces, detail.
    let lines: Vec<&str> = table.lines().filter(|l| ["ok ", "warning ", "error "].iter().any(|w| l.starts_with(w))).collect();
    let width = lines.iter().map(|l| l[9..].split(' ').next().unwrap().len()).max().unwrap();
    for line in &lines {
        assert!(line.as_bytes()[8] == b' ' && line.as_bytes()[9] != b' ', "misaligned: {line}\n{table}");
        let detail = 9 + width + 2;
        assert!(line.as_bytes()[detail - 1] == b' ' && line.as_bytes()[detail] != b' ', "misaligned: {line}\n{table}");
    }
    assert!(lines.len() >= 8, "{table}");
    assert!(table.lines().last().unwrap().contains(" ok, "), "{table}");
    println!("{table}");
}

#[test]
fn missing_runtime_is_an_error() {
    let home = Home::new("doctor-no-runtime");
    home.install();
    let missing = home.dir.join("missing.json");
    let d = Doctor::run({
        let mut c = home.command(&["doctor"]);
        c.env("XR_RUNTIME_JSON", &missing);
        c
    });
    assert_eq!(d.code, 1, "{}", d.text);
    assert!(d.has("openxr.runtime", "error", &format!("XR_RUNTIME_JSON={} does not exist", missing.display())), "{}", d.text);
    assert!(d.fix("openxr.runtime", "error").contains("XR_RUNTIME_JSON"), "{}", d.text);

    // No XR_RUNTIME_JSON and no active_runtime.json in the (private) config folders.
    let d = Doctor::run({
        let mut c = home.command(&["doctor"]);
        c.env_remove("XR_RUNTIME_JSON").env("XDG_CONFIG_DIRS", "/nonexistent");
        c
    });
    assert_eq!(d.code, 1, "{}", d.text);
    let system = ["/etc/openxr/1/active_runtime.json", "/etc/openxr/1/active_runtime.x86_64.json"].iter().any(|p| Path::new(p).exists());
    if !system {
        assert!(d.has("openxr.runtime", "error", "no active runtime: none of "), "{}", d.text);
        assert!(d.has("openxr.runtime", "error", &home.dir.join("config/openxr/1/active_runtime.json").display().to_string()), "{}", d.text);
        assert!(d.fix("openxr.runtime", "error").contains("active_runtime.json"), "{}", d.text);
    }

    // A runtime manifest whose library is gone.
    let runtime = home.dir.join("runtime.json");
    std::fs::write(&runtime, r#"{"file_format_version": "1.0.0", "runtime": {"library_path": "./libgone.so"}}"#).unwrap();
    let d = Doctor::run({
        let mut c = home.command(&["doctor"]);
        c.env("XR_RUNTIME_JSON", &runtime);
        c
    });
    assert_eq!(d.code, 1, "{}", d.text);
    assert!(d.has("openxr.runtime", "error", "libgone.so does not load"), "{}", d.text);
}

#[test]
fn bad_manifests_are_errors() {
    let home = Home::new("doctor-bad-manifest");
    let manifest = home.install();
    let good = std::fs::read_to_string(&manifest).unwrap();

    std::fs::write(&manifest, &good[..good.len() / 2]).unwrap();
    let d = doctor(&home, &[]);
    assert_eq!(d.code, 1, "{}", d.text);
    assert!(d.has("layer.manifest", "error", "not valid JSON"), "{}", d.text);
    assert!(d.fix("layer.manifest", "error").contains("stereoshim install"), "{}", d.text);

    let gone = home.dir.join("data/stereoshim/libgone.so");
    let mut v: Value = serde_json::from_str(&good).unwrap();
    v["api_layer"]["library_path"] = Value::from(gone.to_str().unwrap());
    std::fs::write(&manifest, serde_json::to_string_pretty(&v).unwrap()).unwrap();
    let d = doctor(&home, &[]);
    assert_eq!(d.code, 1, "{}", d.text);
    assert!(d.has("layer.manifest", "error", &format!("library {} does not load: no such file", gone.display())), "{}", d.text);

    // A stale copy: the installed library is not this build's.
    std::fs::write(&manifest, &good).unwrap();
    let library = home.dir.join("data/stereoshim/libstereoshim.so");
    let mut bytes = std::fs::read(&library).unwrap();
    bytes.extend_from_slice(b"stale");
    std::fs::write(&library, bytes).unwrap();
    let d = doctor(&home, &[]);
    assert!(d.has("layer.manifest", "warning", "is not this build's library"), "{}", d.text);
}

#[test]
fn no_vulkan_device_is_an_error() {
    let home = Home::new("doctor-no-vulkan");
    home.install();
    let icd = home.dir.join("bogus_icd.json");
    std::fs::write(&icd, r#"{"file_format_version": "1.0.0", "ICD": {"library_path": "/nonexistent/libvulkan_bogus.so", "api_version": "1.3.0"}}"#).unwrap();
    let d = Doctor::run({
        let mut c = home.command(&["doctor"]);
        c.env("VK_ICD_FILENAMES", &icd).env("VK_DRIVER_FILES", &icd);
        c
    });
    assert_eq!(d.code, 1, "{}", d.text);
    let errors: Vec<&Value> = d.of("vulkan.device").into_iter().filter(|f| f["status"] == "error").collect();
    assert_eq!(errors.len(), 1, "{}", d.text);
    let detail = errors[0]["detail"].as_str().unwrap();
    assert!(detail.contains("no Vulkan driver answers") || detail == "no Vulkan device", "{}", d.text);
    assert!(d.fix("vulkan.device", "error").contains("VK_ICD_FILENAMES"), "{}", d.text);
}

#[test]
fn config_problems_are_reported() {
    let home = Home::new("doctor-config");
    home.install();
    home.config("mask.enabled = true\nmask.enabeld = false\n\n[app.\"xr-scene\"]\nfoveation.method = \"fastest\"\n");
    let d = doctor(&home, &["--app", "xr-scene"]);
    assert_eq!(d.code, 0, "unknown keys and bad values are warnings: {}", d.text);
    assert!(d.has("config", "ok", "for app \"xr-scene\": mask.enabled = true"), "{}", d.text);
    assert!(d.has("config", "warning", "unknown key `mask.enabeld` ignored"), "{}", d.text);
    assert!(d.has("config", "warning", "`foveation.method`"), "{}", d.text);

    home.config("mask.enabled = = true\n");
    let d = doctor(&home, &[]);
    assert_eq!(d.code, 1, "a file that does not parse is ignored whole: {}", d.text);
    assert!(d.has("config", "error", "using defaults for the whole file"), "{}", d.text);

    // --config names the file; one that does not exist is an error.
    let other = home.dir.join("other.toml");
    std::fs::write(&other, "foveation.enabled = true\n").unwrap();
    let d = doctor(&home, &["--config", other.to_str().unwrap()]);
    assert!(d.has("config", "ok", "foveation.enabled = true"), "{}", d.text);
    let d = doctor(&home, &["--config", "/nonexistent/config.toml"]);
    assert_eq!(d.code, 1, "{}", d.text);
    assert!(d.has("config", "error", "does not exist"), "{}", d.text);
}

#[test]
fn conflicting_variables_are_warnings() {
    let home = Home::new("doctor-conflicts");
    home.install();
    let d = Doctor::run({
        let mut c = home.command(&["doctor"]);
        c.env("VK_LAYER_PATH", home.dir.join("layers"));
        c
    });
    assert_eq!(d.code, 0, "{}", d.text);
    assert!(d.has("vulkan.manifest", "warning", "VK_LAYER_PATH="), "{}", d.text);
    assert!(d.fix("vulkan.manifest", "warning").contains("unset VK_LAYER_PATH"), "{}", d.text);

    let d = Doctor::run({
        let mut c = home.command(&["doctor"]);
        c.env("STEREOSHIM_DISABLE", "1").env("VK_LOADER_LAYERS_DISABLE", "~all~");
        c
    });
    assert!(d.has("env", "warning", "STEREOSHIM_DISABLE is set"), "{}", d.text);
    assert!(d.has("env", "warning", "VK_LOADER_LAYERS_DISABLE=~all~"), "{}", d.text);
}

#[test]
fn help_and_bad_arguments() {
    let home = Home::new("doctor-help");
    let out = home.command(&["doctor", "--help"]).output().unwrap();
    let help = String::from_utf8_lossy(&out.stdout);
    assert_eq!(out.status.code(), Some(0), "{help}");
    assert!(help.contains("--json") && help.contains("--app") && help.contains("--config"), "{help}");
    assert!(help.contains("warnings allowed"), "{help}");
    let out = home.command(&["doctor", "--frobnicate"]).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    let out = home.command(&["doctor", "--app"]).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
}

/// On Monado inside the trixie root of the real-world tests (tests/realworld/main.rs,
/// tests/realworld/run): healthy with its service running, an error naming the service without.
/// Runs where that ground must run (`STEREOSHIM_REALWORLD_REQUIRED=1` or CI, as root; the root is
/// cached), skipped loudly elsewhere.
#[test]
fn doctor_on_monado_in_the_trixie_root() {
    let required = std::env::var_os("CI").is_some() || std::env::var("STEREOSHIM_REALWORLD_REQUIRED").is_ok_and(|v| v == "1");
    if !required {
        eprintln!("SKIPPED: stereoshim doctor on Monado in the trixie root (set STEREOSHIM_REALWORLD_REQUIRED=1, as root)");
        return;
    }
    let realworld = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/realworld");
    let out = Command::new(realworld.join("trixie-root")).output().expect("tests/realworld/trixie-root");
    assert!(out.status.success(), "the trixie root: {}", String::from_utf8_lossy(&out.stderr));
    let root = String::from_utf8_lossy(&out.stdout).trim().to_string();
    for (name, monado) in [("doctor-monado", true), ("doctor-monado-stopped", false)] {
        let dir = common::output_dir(name);
        std::fs::write(dir.join("pre.sh"), "/opt/stereoshim install --user\n").unwrap();
        std::fs::write(dir.join("app.env"), "").unwrap();
        // Inside the root: the run folder is /tmp, target/<profile> is /opt.
        let mut cmd = Command::new(realworld.join("run"));
        cmd.arg(&root).arg(&dir).arg(target_dir()).args(["--", "/opt/stereoshim", "doctor", "--json"]);
        cmd.env("RW_DURATION", "0").env("RW_TIMEOUT", "60");
        if !monado {
            cmd.env("RW_NO_MONADO", "1");
        }
        let out = cmd.output().expect("tests/realworld/run");
        let runner = format!("{}{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
        let log = std::fs::read_to_string(dir.join("app.log")).unwrap_or_default();
        // Monado and the loader write their own lines first; the JSON document is the rest.
        let json = log.find("\n{\n").map(|i| &log[i + 1..]).unwrap_or_else(|| panic!("no JSON in the output:\n{runner}\n{log}"));
        let v: Value = serde_json::from_str(json).unwrap_or_else(|e| panic!("{e}:\n{log}"));
        let d = Doctor { code: v["exit_code"].as_i64().unwrap_or(-1) as i32, findings: v["findings"].as_array().cloned().unwrap_or_default(), text: log.clone() };
        assert_eq!(out.status.code(), Some(d.code), "the run's status is doctor's: {runner}\n{log}");
        assert!(d.has("openxr.runtime", "ok", "libopenxr_monado.so"), "{log}");
        assert!(d.has("layer.manifest", "ok", ", this build"), "{log}");
        assert!(d.has("vulkan.manifest", "ok", "the Vulkan loader lists VK_LAYER_STEREOSHIM_stereoshim"), "{log}");
        if monado {
            assert_eq!(d.code, 0, "{log}");
            assert!(d.has("openxr.instance", "ok", "Monado"), "{log}");
            assert!(d.has("openxr.extensions", "ok", "XR_KHR_vulkan_enable2"), "{log}");
            assert!(d.has("openxr.loader", "ok", "libopenxr_loader.so.1.1"), "trixie's loader: {log}");
        } else {
            assert_eq!(d.code, 1, "{log}");
            assert!(d.has("openxr.instance", "error", "xrCreateInstance: ERROR_RUNTIME_FAILURE"), "{log}");
            assert!(d.fix("openxr.instance", "error").contains("monado-service"), "{log}");
        }
        println!("{name}:\n{json}");
    }
}
