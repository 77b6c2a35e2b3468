//! Where the OpenXR loader looks for layers and runtimes, and what stereoshim installs there. The
//! `stereoshim` command uses it; kept pure (paths from an environment function) so every rule is
//! unit-tested without touching the machine.

use std::path::{Path, PathBuf};

pub use crate::manifests::{DISABLE_ENV, MANIFEST_FILE, XR_LAYER_NAME};

pub type Env<'a> = &'a dyn Fn(&str) -> Option<String>;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Scope {
    User,
    System,
}

/// The installed library and implicit-layer manifest of one scope.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Layout {
    pub library: PathBuf,
    pub manifest: PathBuf,
}

fn non_empty(env: Env<'_>, key: &str) -> Option<String> {
    env(key).filter(|v| !v.is_empty())
}

fn data_home(env: Env<'_>) -> Option<PathBuf> {
    non_empty(env, "XDG_DATA_HOME").map(PathBuf::from).or_else(|| non_empty(env, "HOME").map(|h| Path::new(&h).join(".local/share")))
}

fn config_home(env: Env<'_>) -> Option<PathBuf> {
    non_empty(env, "XDG_CONFIG_HOME").map(PathBuf::from).or_else(|| non_empty(env, "HOME").map(|h| Path::new(&h).join(".config")))
}

pub fn layout(scope: Scope, env: Env<'_>) -> Option<Layout> {
    match scope {
        Scope::User => {
            let data = data_home(env)?;
            Some(Layout {
                library: data.join("stereoshim").join("libstereoshim.so"),
                manifest: data.join("openxr/1/api_layers/implicit.d").join(MANIFEST_FILE),
            })
        }
        Scope::System => Some(Layout {
            library: PathBuf::from("/usr/local/lib/stereoshim/libstereoshim.so"),
            manifest: PathBuf::from("/usr/local/share/openxr/1/api_layers/implicit.d").join(MANIFEST_FILE),
        }),
    }
}

/// Folders the OpenXR loader searches for layer manifests on Linux, in its order, each with
/// whether it holds implicit layers. `XR_API_LAYER_PATH` replaces the explicit search.
pub fn layer_search_dirs(env: Env<'_>) -> Vec<(PathBuf, bool)> {
    let mut bases: Vec<PathBuf> = Vec::new();
    bases.extend(config_home(env));
    let config_dirs = non_empty(env, "XDG_CONFIG_DIRS").unwrap_or_else(|| "/etc/xdg".into());
    bases.extend(config_dirs.split(':').filter(|d| !d.is_empty()).map(PathBuf::from));
    bases.push(PathBuf::from("/etc"));
    bases.extend(data_home(env));
    let data_dirs = non_empty(env, "XDG_DATA_DIRS").unwrap_or_else(|| "/usr/local/share:/usr/share".into());
    bases.extend(data_dirs.split(':').filter(|d| !d.is_empty()).map(PathBuf::from));
    let mut dirs = Vec::new();
    for base in &bases {
        dirs.push((base.join("openxr/1/api_layers/implicit.d"), true));
    }
    match non_empty(env, "XR_API_LAYER_PATH") {
        Some(p) => dirs.extend(p.split(':').filter(|d| !d.is_empty()).map(|d| (PathBuf::from(d), false))),
        None => dirs.extend(bases.iter().map(|b| (b.join("openxr/1/api_layers/explicit.d"), false))),
    }
    dirs
}

/// The runtime manifest the loader will use: `XR_RUNTIME_JSON`, else the first
/// `openxr/1/active_runtime.json` in the config folders.
pub fn active_runtime(env: Env<'_>, exists: &dyn Fn(&Path) -> bool) -> Option<PathBuf> {
    if let Some(p) = non_empty(env, "XR_RUNTIME_JSON") {
        return Some(PathBuf::from(p));
    }
    let mut bases: Vec<PathBuf> = config_home(env).into_iter().collect();
    let config_dirs = non_empty(env, "XDG_CONFIG_DIRS").unwrap_or_else(|| "/etc/xdg".into());
    bases.extend(config_dirs.split(':').filter(|d| !d.is_empty()).map(PathBuf::from));
    bases.push(PathBuf::from("/etc"));
    bases.into_iter().map(|b| b.join("openxr/1/active_runtime.json")).find(|p| exists(p))
}

/// `NAME=value` for `run`: our layer prepended to `XR_ENABLE_API_LAYERS` (first = closest to the
/// app), the manifest folder prepended to `XR_API_LAYER_PATH`.
pub fn run_environment(env: Env<'_>, manifest_dir: &Path) -> Vec<(String, String)> {
    let join = |first: &str, rest: Option<String>| match rest {
        Some(r) if r.split(':').any(|p| p == first) => r,
        Some(r) => format!("{first}:{r}"),
        None => first.to_string(),
    };
    vec![
        ("XR_API_LAYER_PATH".into(), join(&manifest_dir.to_string_lossy(), non_empty(env, "XR_API_LAYER_PATH"))),
        ("XR_ENABLE_API_LAYERS".into(), join(XR_LAYER_NAME, non_empty(env, "XR_ENABLE_API_LAYERS"))),
    ]
}

/// The `library_path` of a manifest file's text when it is an OpenXR API-layer manifest naming
/// stereoshim (`stereoshim status`); None for anything else. Manifest folders are shared with
/// every other layer and may hold anything (other layers' files, editor leftovers, truncated or
/// hostile JSON): no input makes this fail in any other way (tests: property over random bytes
/// and random JSON). A manifest naming stereoshim without a string `library_path` gives `"?"`.
pub fn our_manifest_library(text: &str) -> Option<String> {
    let json: serde_json::Value = serde_json::from_str(text).ok()?;
    let layer = json.get("api_layer")?;
    if layer.get("name")?.as_str()? != XR_LAYER_NAME {
        return None;
    }
    Some(layer.get("library_path").and_then(|l| l.as_str()).unwrap_or("?").to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    mod hostile_manifests {
        use super::*;
        use proptest::prelude::*;

        /// Random JSON values, nested a few levels.
        fn json() -> impl Strategy<Value = serde_json::Value> {
            let leaf = prop_oneof![
                Just(serde_json::Value::Null),
                any::<bool>().prop_map(serde_json::Value::from),
                any::<f64>().prop_map(serde_json::Value::from),
                any::<i64>().prop_map(serde_json::Value::from),
                ".{0,12}".prop_map(serde_json::Value::from),
                Just(serde_json::Value::from(XR_LAYER_NAME)),
            ];
            leaf.prop_recursive(4, 32, 6, |inner| {
                prop_oneof![
                    prop::collection::vec(inner.clone(), 0..6).prop_map(serde_json::Value::from),
                    prop::collection::btree_map(prop_oneof![Just("api_layer".to_string()), Just("name".to_string()), Just("library_path".to_string()), ".{0,8}"], inner, 0..6)
                        .prop_map(|m| serde_json::Value::Object(m.into_iter().collect())),
                ]
            })
        }

        proptest! {
            #[test]
            fn random_bytes_are_not_ours(bytes in prop::collection::vec(any::<u8>(), 0..512)) {
                prop_assert_eq!(our_manifest_library(&String::from_utf8_lossy(&bytes)), None);
            }

            /// Any JSON: ours exactly when `api_layer.name` is stereoshim's name.
            #[test]
            fn random_json_is_ours_only_by_name(v in json()) {
                let named = v.get("api_layer").and_then(|l| l.get("name")).and_then(|n| n.as_str()) == Some(XR_LAYER_NAME);
                prop_assert_eq!(our_manifest_library(&v.to_string()).is_some(), named);
            }
        }

        #[test]
        fn deep_nesting_and_truncation_are_refused() {
            let deep = "[".repeat(100_000);
            assert_eq!(our_manifest_library(&deep), None, "serde_json's recursion limit, not a stack overflow");
            let ours = format!(r#"{{"file_format_version": "1.0.0", "api_layer": {{"name": "{XR_LAYER_NAME}", "library_path": "lib.so"}}}}"#);
            assert_eq!(our_manifest_library(&ours).as_deref(), Some("lib.so"));
            for cut in 0..ours.len() - 1 {
                assert_eq!(our_manifest_library(&ours[..cut]), None, "truncated at {cut}");
            }
            let odd = format!(r#"{{"api_layer": {{"name": "{XR_LAYER_NAME}", "library_path": 7}}}}"#);
            assert_eq!(our_manifest_library(&odd).as_deref(), Some("?"));
        }
    }

    fn env(pairs: &'static [(&'static str, &'static str)]) -> impl Fn(&str) -> Option<String> {
        move |k| pairs.iter().find(|(key, _)| *key == k).map(|(_, v)| v.to_string())
    }

    #[test]
    fn user_layout_follows_xdg_data_home() {
        let e = env(&[("HOME", "/home/u")]);
        let l = layout(Scope::User, &e).unwrap();
        assert_eq!(l.library, PathBuf::from("/home/u/.local/share/stereoshim/libstereoshim.so"));
        assert_eq!(l.manifest, PathBuf::from("/home/u/.local/share/openxr/1/api_layers/implicit.d/stereoshim.json"));
        let e = env(&[("XDG_DATA_HOME", "/d")]);
        assert_eq!(layout(Scope::User, &e).unwrap().manifest, PathBuf::from("/d/openxr/1/api_layers/implicit.d/stereoshim.json"));
        assert!(layout(Scope::User, &env(&[])).is_none());
    }

    #[test]
    fn search_dirs_cover_user_and_system() {
        let e = env(&[("HOME", "/h")]);
        let dirs = layer_search_dirs(&e);
        assert!(dirs.contains(&(PathBuf::from("/h/.local/share/openxr/1/api_layers/implicit.d"), true)));
        assert!(dirs.contains(&(PathBuf::from("/usr/local/share/openxr/1/api_layers/implicit.d"), true)));
        assert!(dirs.contains(&(PathBuf::from("/etc/openxr/1/api_layers/explicit.d"), false)));
        let e = env(&[("HOME", "/h"), ("XR_API_LAYER_PATH", "/a:/b")]);
        let explicit: Vec<_> = layer_search_dirs(&e).into_iter().filter(|d| !d.1).map(|d| d.0).collect();
        assert_eq!(explicit, vec![PathBuf::from("/a"), PathBuf::from("/b")]);
    }

    #[test]
    fn active_runtime_precedence() {
        let e = env(&[("XR_RUNTIME_JSON", "/r.json"), ("HOME", "/h")]);
        assert_eq!(active_runtime(&e, &|_| false), Some(PathBuf::from("/r.json")));
        let e = env(&[("HOME", "/h")]);
        assert_eq!(
            active_runtime(&e, &|p| p.starts_with("/etc/xdg")),
            Some(PathBuf::from("/etc/xdg/openxr/1/active_runtime.json"))
        );
        assert_eq!(active_runtime(&e, &|_| false), None);
    }

    #[test]
    fn run_environment_prepends_once() {
        let e = env(&[("XR_ENABLE_API_LAYERS", "XR_APILAYER_other")]);
        let vars = run_environment(&e, Path::new("/m"));
        assert_eq!(vars[0], ("XR_API_LAYER_PATH".into(), "/m".into()));
        assert_eq!(vars[1], ("XR_ENABLE_API_LAYERS".into(), format!("{XR_LAYER_NAME}:XR_APILAYER_other")));
        let e = env(&[("XR_API_LAYER_PATH", "/m:/x")]);
        assert_eq!(run_environment(&e, Path::new("/m"))[0].1, "/m:/x");
    }
}
