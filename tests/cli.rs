//! The `stereoshim` command end to end: install as an implicit layer into a private data folder,
//! see it picked up by an app that was told nothing, keep it out with the disable variable, show it
//! in `status`, remove it again; and `stereoshim run`.

mod common;

use common::{assert_same_captures, target_dir, Run};
use std::path::Path;
use std::process::Command;

fn stereoshim(args: &[&str], data_home: &Path, config_home: &Path) -> (i32, String) {
    let out = Command::new(target_dir().join("stereoshim"))
        .args(args)
        .env("XDG_DATA_HOME", data_home)
        .env("XDG_CONFIG_HOME", config_home)
        .env("XDG_CONFIG_DIRS", "/nonexistent")
        .env("XDG_DATA_DIRS", "/nonexistent")
        .env_remove("XR_API_LAYER_PATH")
        .env_remove("STEREOSHIM_DISABLE")
        .output()
        .expect("run stereoshim");
    let text = String::from_utf8_lossy(&out.stdout).into_owned() + &String::from_utf8_lossy(&out.stderr);
    (out.status.code().unwrap_or(-1), text)
}

#[test]
fn install_status_disable_uninstall() {
    let home = common::output_dir("cli-home");
    let (data, config) = (home.join("data"), home.join("config"));
    std::fs::create_dir_all(config.join("stereoshim")).unwrap();
    std::fs::write(config.join("stereoshim/config.toml"), "[app.\"xr-scene\"]\nlog.level = \"debug\"\n").unwrap();

    let (code, text) = stereoshim(&["install", "--user"], &data, &config);
    assert_eq!(code, 0, "{text}");
    let manifest = data.join("openxr/1/api_layers/implicit.d/stereoshim.json");
    assert!(manifest.is_file() && data.join("stereoshim/libstereoshim.so").is_file(), "{text}");

    let (code, text) = stereoshim(&["status", "--app", "xr-scene"], &data, &config);
    assert_eq!(code, 0, "{text}");
    assert!(text.contains(&format!("{} (implicit)", manifest.display())), "{text}");
    assert!(text.contains("log.level = debug") && text.contains("[app.\"xr-scene\"]"), "{text}");

    // An app told nothing about stereoshim gets it from the implicit manifest.
    let reference = Run::new("cli-reference").run();
    reference.assert_ok();
    let implicit = Run::new("cli-implicit").env("XDG_DATA_HOME", data.to_str().unwrap()).run();
    implicit.assert_ok();
    assert_eq!(implicit.log_lines("the Vulkan half tracks this device").len(), 1, "{}", implicit.log);
    assert_same_captures("cli-implicit", &implicit, &reference);

    let disabled = Run::new("cli-disabled").env("XDG_DATA_HOME", data.to_str().unwrap()).env("STEREOSHIM_DISABLE", "1").run();
    disabled.assert_ok();
    // STEREOSHIM_DISABLE must keep the layer out (the run before shows it is picked up otherwise).
    disabled.assert_layer_not_loaded();

    let (code, text) = stereoshim(&["uninstall", "--user"], &data, &config);
    assert_eq!(code, 0, "{text}");
    assert!(!manifest.exists() && !data.join("stereoshim/libstereoshim.so").exists());
    assert!(!data.join("stereoshim").exists(), "the library folder is left behind");
    let (_, text) = stereoshim(&["status"], &data, &config);
    assert!(text.contains("none (not installed"), "{text}");
}

#[test]
fn run_wraps_one_app() {
    let reference = Run::new("cli-run-reference").args(["--layout", "side-by-side"]).run();
    reference.assert_ok();
    let mut run = Run::new("cli-run").args(["--layout", "side-by-side"]);
    run.wrapper = vec![target_dir().join("stereoshim").into(), "run".into(), "--".into()];
    let out = run.run();
    out.assert_ok();
    assert_eq!(out.log_lines("the Vulkan half tracks this device").len(), 1, "{}", out.log);
    assert_same_captures("cli-run", &out, &reference);
}

#[test]
fn bad_usage_is_reported() {
    let home = common::output_dir("cli-usage");
    let (code, text) = stereoshim(&["frobnicate"], &home, &home);
    assert_eq!(code, 2);
    assert!(text.contains("usage:"), "{text}");
    let (code, text) = stereoshim(&["run"], &home, &home);
    assert_eq!(code, 2);
    assert!(text.contains("-- APP"), "{text}");
}

#[test]
fn manifest_prints_and_regenerates() {
    let home = common::output_dir("cli-manifest");
    let (code, text) = stereoshim(&["manifest", "bogus"], &home, &home);
    assert_eq!(code, 2);
    assert!(text.contains("openxr, openxr-implicit, vulkan"), "{text}");
    let (code, text) = stereoshim(&["manifest"], &home, &home);
    assert_eq!(code, 2, "{text}");
    // The printed manifest names the library next to the command.
    let (code, text) = stereoshim(&["manifest", "openxr-implicit"], &home, &home);
    assert_eq!(code, 0, "{text}");
    let json: serde_json::Value = serde_json::from_str(&text).unwrap();
    let lib = std::fs::canonicalize(target_dir().join("libstereoshim.so")).unwrap();
    assert_eq!(json["api_layer"]["library_path"], lib.to_str().unwrap());
    assert_eq!(json["api_layer"]["disable_environment"], "STEREOSHIM_DISABLE");
    // --shipped writes the files of manifest/, byte for byte.
    let out = home.join("shipped");
    let (code, text) = stereoshim(&["manifest", "--shipped", out.to_str().unwrap()], &home, &home);
    assert_eq!(code, 0, "{text}");
    let repo = Path::new(env!("CARGO_MANIFEST_DIR")).join("manifest");
    for kind in ["openxr", "openxr-implicit", "vulkan"] {
        let ours = std::fs::read(out.join(kind).join("stereoshim.json")).unwrap();
        assert_eq!(ours, std::fs::read(repo.join(kind).join("stereoshim.json")).unwrap(), "{kind}");
    }
}
