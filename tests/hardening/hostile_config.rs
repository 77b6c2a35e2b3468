//! Hostile configuration (issue 11): random bytes and random TOML as the config file, random text
//! in every environment override. The layer reads these inside the app's process, so whatever they
//! hold: no panic, every key ends with a valid value, and every rejected input is named in a
//! diagnostic line (the layer logs those) while the key keeps the lower-precedence value.

use proptest::prelude::*;
use std::collections::BTreeMap;
use std::path::Path;
use stereoshim::core::config::{Config, Inputs};
use stereoshim::registry::keys;
use stereoshim::plugin::settings::Settings;

/// Random text shaped like TOML: known and unknown keys, sections, values of every type, broken
/// lines.
fn tomlish() -> impl Strategy<Value = String> {
    let key = prop_oneof![
        4 => prop::sample::select(keys().iter().map(|k| k.key.to_string()).collect::<Vec<_>>()),
        1 => "[a-z_.]{1,12}",
    ];
    let value = prop_oneof![
        Just("true".to_string()),
        Just("false".to_string()),
        any::<i64>().prop_map(|i| i.to_string()),
        any::<f64>().prop_map(|f| format!("{f:?}")),
        Just("nan".to_string()),
        Just("inf".to_string()),
        Just("-inf".to_string()),
        "\"[ -~]{0,12}\"",
        Just("[1, 2]".to_string()),
        Just("{ x = 1 }".to_string()),
        "[ -~]{0,10}",
    ];
    let line = prop_oneof![
        6 => (key, value).prop_map(|(k, v)| format!("{k} = {v}")),
        1 => "\\[[ -~]{0,16}\\]",
        1 => Just("[apps.\"x\"]".to_string()),
        1 => "[ -~]{0,20}",
    ];
    prop::collection::vec(line, 0..12).prop_map(|l| l.join("\n"))
}

fn resolve(file: Option<&str>, env: &BTreeMap<String, String>) -> (Config, Vec<String>) {
    let get = |k: &str| env.get(k).cloned();
    let inputs = Inputs { keys: keys(), file: file.map(|t| (Path::new("/c/config.toml"), t)), app_names: &["x", "xr-scene"], env: &get };
    Config::resolve(&inputs)
}

/// Every key holds a value a fresh default of the same key could hold (its type), and the typed
/// settings build from it.
fn assert_usable(c: &Config) {
    let defaults = Config::defaults(keys());
    for spec in keys() {
        assert_eq!(std::mem::discriminant(c.value(spec.key)), std::mem::discriminant(defaults.value(spec.key)), "{}", spec.key);
    }
    let _ = Settings::from_config(c);
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 512, ..ProptestConfig::default() })]

    #[test]
    fn random_bytes_as_the_config_file(bytes in prop::collection::vec(any::<u8>(), 0..400)) {
        let text = String::from_utf8_lossy(&bytes);
        let (c, _) = resolve(Some(&text), &BTreeMap::new());
        assert_usable(&c);
    }

    #[test]
    fn random_toml_as_the_config_file(text in tomlish()) {
        let (c, diagnostics) = resolve(Some(&text), &BTreeMap::new());
        assert_usable(&c);
        // A key that kept its default although the file set it was rejected, and said so.
        for spec in keys() {
            let set = text.lines().any(|l| l.split('=').next().is_some_and(|k| k.trim() == spec.key));
            if set && c.value(spec.key) == Config::defaults(keys()).value(spec.key) && !matches!(c.source(spec.key), stereoshim::core::config::Source::File { .. } | stereoshim::core::config::Source::App { .. }) {
                prop_assert!(!diagnostics.is_empty(), "{} set in\n{}\nbut neither applied nor reported", spec.key, text);
            }
        }
    }

    #[test]
    fn random_environment_overrides(values in prop::collection::btree_map(prop::sample::select(keys().iter().map(|k| k.env_var()).collect::<Vec<_>>()), "[ -~]{0,16}|\\PC{0,8}", 0..8)) {
        let (c, diagnostics) = resolve(None, &values);
        assert_usable(&c);
        for spec in keys() {
            let var = spec.env_var();
            if let Some(text) = values.get(&var) {
                let applied = matches!(c.source(spec.key), stereoshim::core::config::Source::Env(v) if *v == var);
                let reported = diagnostics.iter().any(|d| d.contains(&var));
                prop_assert!(applied != reported, "${}={:?}: applied {} reported {}: {:?}", var, text, applied, reported, diagnostics);
            }
        }
    }
}
