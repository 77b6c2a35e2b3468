//! Configuration resolved against the registry's keys: precedence, diagnostics, reload, docs.

use crate::core::config::*;
use std::path::{Path, PathBuf};
use crate::registry::keys;

fn resolve(file: Option<&str>, apps: &[&str], env: &[(&str, &str)]) -> (Config, Vec<String>) {
    let env: Vec<(String, String)> = env.iter().map(|(k, v)| (k.to_string(), v.to_string())).collect();
    let lookup = move |k: &str| env.iter().find(|(key, _)| key == k).map(|(_, v)| v.clone());
    let path = Path::new("/cfg/config.toml");
    Config::resolve(&Inputs { keys: keys(), file: file.map(|t| (path, t)), app_names: apps, env: &lookup })
}

#[test]
fn defaults_without_file_or_env() {
    let (c, d) = resolve(None, &[], &[]);
    assert!(d.is_empty());
    assert!(c.enabled());
    assert_eq!(c.choice("log.level"), "info");
    assert_eq!(c.source("enabled"), &Source::Default);
}

#[test]
fn env_var_names_follow_keys() {
    let names: Vec<String> = keys().iter().map(KeySpec::env_var).collect();
    assert!(names.contains(&"STEREOSHIM_LOG_LEVEL".to_string()));
    assert!(names.contains(&"STEREOSHIM_VULKAN_FRAGMENT_SHADING_RATE".to_string()));
    assert!(names.contains(&"STEREOSHIM_ENABLED".to_string()));
}

#[test]
fn file_then_app_section_then_env() {
    let file = "enabled = false\n[log]\nlevel = \"warn\"\n\n[app.\"My Game\"]\nlog.level = \"debug\"\nenabled = true\n";
    let (c, d) = resolve(Some(file), &["Other"], &[]);
    assert!(d.is_empty(), "{d:?}");
    assert!(!c.enabled());
    assert_eq!(c.choice("log.level"), "warn");
    assert_eq!(c.source("log.level"), &Source::File { path: "/cfg/config.toml".into(), line: 3 });

    let (c, _) = resolve(Some(file), &["My Game", "game.exe"], &[]);
    assert!(c.enabled());
    assert_eq!(c.choice("log.level"), "debug");
    assert!(matches!(c.source("log.level"), Source::App { line: 6, .. }));

    // The app picked its section; the user's environment still wins over it.
    let (c, _) = resolve(Some(file), &["My Game"], &[("STEREOSHIM_LOG_LEVEL", "TRACE"), ("STEREOSHIM_ENABLED", "0")]);
    assert_eq!(c.choice("log.level"), "trace");
    assert!(!c.enabled());
    assert_eq!(c.source("enabled"), &Source::Env("STEREOSHIM_ENABLED".into()));
}

#[test]
fn executable_name_is_the_fallback_section() {
    let file = "[app.\"xr-scene\"]\nenabled = false\n";
    let (c, _) = resolve(Some(file), &["Some Title", "xr-scene"], &[]);
    assert!(!c.enabled());
}

#[test]
fn syntax_error_reports_line_and_keeps_defaults() {
    let (c, d) = resolve(Some("enabled = true\nlog.level = \"warn\n"), &[], &[]);
    assert_eq!(d.len(), 1, "{d:?}");
    assert!(d[0].contains("/cfg/config.toml: line 2"), "{d:?}");
    assert_eq!(c.choice("log.level"), "info");
}

#[test]
fn bad_values_cost_only_their_key() {
    let file = "enabled = \"yes please\"\nlog.level = \"loud\"\nvulkan.fragment_shading_rate = \"on\"\nnot.a.key = 3\napp = 5\n";
    let (c, d) = resolve(Some(file), &[], &[]);
    assert!(c.enabled());
    assert_eq!(c.choice("log.level"), "info");
    assert_eq!(c.choice("vulkan.fragment_shading_rate"), "on");
    let joined = d.join("\n");
    assert!(joined.contains(":1: `enabled`: expected true or false"), "{joined}");
    assert!(joined.contains(":2: `log.level`: expected one of off|error|warn|info|debug|trace"), "{joined}");
    assert!(joined.contains(":4: unknown key `not.a.key`"), "{joined}");
    assert!(joined.contains(":5: `app` must be a table"), "{joined}");
    assert_eq!(d.len(), 4, "{joined}");
}

#[test]
fn bad_env_value_keeps_file_value() {
    let (c, d) = resolve(Some("log.level = \"warn\""), &[], &[("STEREOSHIM_LOG_LEVEL", "chatty")]);
    assert_eq!(c.choice("log.level"), "warn");
    assert_eq!(d.len(), 1);
    assert!(d[0].contains("$STEREOSHIM_LOG_LEVEL=\"chatty\""), "{d:?}");
}

#[test]
fn fail_in_lists_calls() {
    let (c, _) = resolve(None, &[], &[("STEREOSHIM_DEBUG_FAIL_IN", "xrEndFrame, vkCreateImage")]);
    assert!(c.fails_in("xrEndFrame"));
    assert!(c.fails_in("vkCreateImage"));
    assert!(!c.fails_in("xrBeginFrame"));
}

#[test]
fn config_path_precedence() {
    let env = |k: &str| match k {
        "XDG_CONFIG_HOME" => Some("/x".to_string()),
        "HOME" => Some("/home/u".to_string()),
        _ => None,
    };
    assert_eq!(default_path(&env), Some(PathBuf::from("/x/stereoshim/config.toml")));
    let env2 = |k: &str| if k == "HOME" { Some("/home/u".to_string()) } else { None };
    assert_eq!(default_path(&env2), Some(PathBuf::from("/home/u/.config/stereoshim/config.toml")));
    let env3 = |k: &str| if k == "STEREOSHIM_CONFIG" { Some("/etc/s.toml".to_string()) } else { None };
    assert_eq!(default_path(&env3), Some(PathBuf::from("/etc/s.toml")));
}

mod docs_tests {
    use crate::registry::keys;
    /// docs/configuration.md documents every key with its default; this keeps the two in step.
    #[test]
    fn every_key_is_documented() {
        let doc = include_str!("../../docs/configuration.md");
        for spec in keys() {
            let row = doc
                .lines()
                .find(|l| l.starts_with(&format!("| `{}` |", spec.key)))
                .unwrap_or_else(|| panic!("docs/configuration.md lacks a row for `{}`", spec.key));
            let default = if spec.default.is_empty() { "\"\"".to_string() } else { spec.default.to_string() };
            assert!(row.contains(&format!("| {default} |")), "docs/configuration.md: default of `{}` is not {default}", spec.key);
        }
    }
}
