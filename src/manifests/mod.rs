//! Every layer manifest stereoshim writes or ships comes from here: the explicit and the implicit
//! OpenXR API-layer manifest (`stereoshim run`, `stereoshim install`), the Vulkan layer manifest
//! the OpenXR half writes at run time (`vulkan`), and the files under `manifest/`, which are
//! this module's output for a library in the build tree (`stereoshim manifest --shipped manifest`
//! rewrites them; `tests/layer/manifests.rs` fails when they differ).
//!
//! The rules followed are those of both loaders' manifest readers (Vulkan-Loader
//! `docs/LoaderLayerInterface.md` "Layer Manifest File Format", OpenXR-SDK
//! `specification/loader/api_layer.adoc` "API Layer Manifest File Format"), which every Debian
//! loader in use enforces: every version field is a JSON **string** (the Vulkan loader 1.4 reads
//! `api_version`, `implementation_version` and `type` only as strings and, when one is not, lists a
//! layer without a library path), implicit layers name a `disable_environment`, and the only entry
//! point the loaders look up by name is declared in `functions`.

pub mod install;
pub mod private_fs;
pub mod steam;
pub mod vulkan;

use std::path::Path;

/// The Vulkan layer's name, used by the manifests, the OpenXR half and the tests.
pub const VK_LAYER_NAME: &str = "VK_LAYER_STEREOSHIM_stereoshim";
/// The OpenXR API layer's name.
pub const XR_LAYER_NAME: &str = "XR_APILAYER_STEREOSHIM_stereoshim";
/// Setting this variable (to anything) keeps the implicit layer out of a process.
pub const DISABLE_ENV: &str = "STEREOSHIM_DISABLE";
/// The file name of every manifest stereoshim writes.
pub const MANIFEST_FILE: &str = "stereoshim.json";
/// The one symbol each loader looks up in the library (the rest is handed over by negotiation);
/// the library exports exactly these two.
pub const XR_NEGOTIATE: &str = "xrNegotiateLoaderApiLayerInterface";
pub const VK_NEGOTIATE: &str = "vkNegotiateLoaderLayerInterfaceVersion";
/// `library_path` of the manifests shipped under `manifest/<kind>/`: the debug build of this tree.
pub const SHIPPED_LIBRARY: &str = "../../target/debug/libstereoshim.so";
/// The layer's own version as both loaders parse it (`atoi` of a string). Raise it when the layer's
/// behaviour changes in a way a user or a tool should be able to tell apart.
pub const IMPLEMENTATION_VERSION: u32 = 1;

const XR_DESCRIPTION: &str = "stereoshim: makes unmodified Vulkan VR apps render less";
const VK_DESCRIPTION: &str = "stereoshim Vulkan half: makes unmodified Vulkan VR apps render less (its OpenXR half brings it in)";

/// The manifests stereoshim produces.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Kind {
    /// OpenXR API layer, explicit: `XR_API_LAYER_PATH` + `XR_ENABLE_API_LAYERS` (`stereoshim run`).
    OpenXr,
    /// OpenXR API layer, implicit: `openxr/1/api_layers/implicit.d` (`stereoshim install`).
    OpenXrImplicit,
    /// Vulkan layer, explicit: written by the OpenXR half at run time, or used alone with
    /// `VK_LAYER_PATH` + `VK_INSTANCE_LAYERS`. stereoshim never installs an implicit Vulkan layer.
    Vulkan,
}

impl Kind {
    pub const ALL: [Kind; 3] = [Kind::OpenXr, Kind::OpenXrImplicit, Kind::Vulkan];

    /// The name on the command line and the folder under `manifest/`.
    pub fn name(self) -> &'static str {
        match self {
            Kind::OpenXr => "openxr",
            Kind::OpenXrImplicit => "openxr-implicit",
            Kind::Vulkan => "vulkan",
        }
    }

    pub fn parse(name: &str) -> Option<Kind> {
        Kind::ALL.into_iter().find(|k| k.name() == name)
    }

    pub fn is_implicit(self) -> bool {
        self == Kind::OpenXrImplicit
    }

    pub fn is_vulkan(self) -> bool {
        self == Kind::Vulkan
    }
}

/// The Vulkan layer manifest format version: 1.2.1 is the first that defines every field written
/// here (`functions` with `vkNegotiateLoaderLayerInterfaceVersion`: 1.1.0; `library_arch`: 1.2.1);
/// loaders 1.3.239 and 1.4.309 both accept 1.0.0 to 1.2.1.
pub const VK_FILE_FORMAT_VERSION: &str = "1.2.1";
/// The OpenXR API-layer manifest format version; 1.0.0 is the only one the loaders accept.
pub const XR_FILE_FORMAT_VERSION: &str = "1.0.0";

/// The Vulkan API version the layer handles functions up to: the headers it is built against
/// (instance and device functions of later versions pass through it unseen).
pub fn vk_api_version() -> String {
    use ash::vk;
    let v = vk::HEADER_VERSION_COMPLETE;
    format!("{}.{}.{}", vk::api_version_major(v), vk::api_version_minor(v), vk::api_version_patch(v))
}

/// The OpenXR API version (major.minor, the format the loader parses) the layer is built against,
/// the one it reports at negotiation.
pub fn xr_api_version() -> String {
    let v = openxr_sys::CURRENT_API_VERSION;
    format!("{}.{}", v.major(), v.minor())
}

/// A JSON value with its keys in the order written (the manifest readers do not care; people do).
enum Json {
    Str(String),
    Obj(Vec<(&'static str, Json)>),
    Arr(Vec<Json>),
}

impl Json {
    fn s(text: impl Into<String>) -> Json {
        Json::Str(text.into())
    }

    fn write(&self, out: &mut String, indent: usize) {
        match self {
            // serde_json writes a JSON string literal with all required escapes.
            Json::Str(s) => out.push_str(&serde_json::to_string(s).unwrap_or_default()),
            Json::Obj(fields) => {
                out.push('{');
                for (i, (key, value)) in fields.iter().enumerate() {
                    out.push_str(if i == 0 { "\n" } else { ",\n" });
                    out.push_str(&" ".repeat(indent + 4));
                    out.push_str(&serde_json::to_string(key).unwrap_or_default());
                    out.push_str(": ");
                    value.write(out, indent + 4);
                }
                out.push('\n');
                out.push_str(&" ".repeat(indent));
                out.push('}');
            }
            Json::Arr(items) => {
                out.push('[');
                for (i, item) in items.iter().enumerate() {
                    out.push_str(if i == 0 { "\n" } else { ",\n" });
                    out.push_str(&" ".repeat(indent + 4));
                    item.write(out, indent + 4);
                }
                out.push('\n');
                out.push_str(&" ".repeat(indent));
                out.push(']');
            }
        }
    }
}

/// The manifest text of `kind` for the library at `library_path` (absolute, or relative to the
/// folder the manifest is written to), ending in a newline.
pub fn json(kind: Kind, library_path: &Path) -> String {
    let library = Json::s(library_path.to_string_lossy());
    let version = Json::s(IMPLEMENTATION_VERSION.to_string());
    let root = match kind {
        Kind::OpenXr | Kind::OpenXrImplicit => {
            let mut layer = vec![
                ("name", Json::s(XR_LAYER_NAME)),
                ("library_path", library),
                ("api_version", Json::s(xr_api_version())),
                ("implementation_version", version),
                ("description", Json::s(XR_DESCRIPTION)),
                ("functions", Json::Obj(vec![(XR_NEGOTIATE, Json::s(XR_NEGOTIATE))])),
                // Offered to the app when the runtime lacks it (the lens the layer knows), so that
                // OpenVR games through xrizer get a hidden-area mesh; the loader lists an enabled
                // layer's extensions beside the runtime's.
                (
                    "instance_extensions",
                    Json::Arr(vec![Json::Obj(vec![("name", Json::s(crate::core::views::VISIBILITY_MASK_EXT)), ("extension_version", Json::s("2"))])]),
                ),
            ];
            if kind.is_implicit() {
                // No `enable_environment`: an installed layer is meant for every app; a user who
                // wants it for one app uses `stereoshim run` instead of installing.
                layer.push(("disable_environment", Json::s(DISABLE_ENV)));
            }
            Json::Obj(vec![("file_format_version", Json::s(XR_FILE_FORMAT_VERSION)), ("api_layer", Json::Obj(layer))])
        }
        Kind::Vulkan => Json::Obj(vec![
            ("file_format_version", Json::s(VK_FILE_FORMAT_VERSION)),
            (
                "layer",
                Json::Obj(vec![
                    ("name", Json::s(VK_LAYER_NAME)),
                    ("type", Json::s("GLOBAL")),
                    ("library_path", library),
                    ("library_arch", Json::s(if cfg!(target_pointer_width = "64") { "64" } else { "32" })),
                    ("api_version", Json::s(vk_api_version())),
                    ("implementation_version", version),
                    ("description", Json::s(VK_DESCRIPTION)),
                    ("functions", Json::Obj(vec![(VK_NEGOTIATE, Json::s(VK_NEGOTIATE))])),
                ]),
            ),
        ]),
    };
    let mut out = String::new();
    root.write(&mut out, 0);
    out.push('\n');
    out
}

/// The manifests shipped in the repository: (path under `manifest/`, text).
pub fn shipped() -> Vec<(String, String)> {
    Kind::ALL.into_iter().map(|k| (format!("{}/{MANIFEST_FILE}", k.name()), json(k, Path::new(SHIPPED_LIBRARY)))).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(kind: Kind) -> serde_json::Value {
        serde_json::from_str(&json(kind, Path::new("/x/lib \"s\".so"))).expect("valid JSON")
    }

    #[test]
    fn names_layer_and_library() {
        let v = parse(Kind::Vulkan);
        assert_eq!(v["layer"]["name"], VK_LAYER_NAME);
        assert_eq!(v["layer"]["library_path"], "/x/lib \"s\".so");
        assert_eq!(v["layer"]["functions"][VK_NEGOTIATE], VK_NEGOTIATE);
        let v = parse(Kind::OpenXr);
        assert_eq!(v["api_layer"]["name"], XR_LAYER_NAME);
        assert_eq!(v["api_layer"]["library_path"], "/x/lib \"s\".so");
        assert_eq!(v["api_layer"]["functions"][XR_NEGOTIATE], XR_NEGOTIATE);
    }

    #[test]
    fn only_the_implicit_manifest_has_the_disable_variable() {
        assert_eq!(parse(Kind::OpenXrImplicit)["api_layer"]["disable_environment"], DISABLE_ENV);
        assert!(parse(Kind::OpenXr)["api_layer"].get("disable_environment").is_none());
        assert!(parse(Kind::Vulkan)["layer"].get("disable_environment").is_none());
    }

    #[test]
    fn every_version_is_a_string() {
        for kind in Kind::ALL {
            let v = parse(kind);
            let layer = if kind.is_vulkan() { &v["layer"] } else { &v["api_layer"] };
            for key in ["api_version", "implementation_version"] {
                assert!(layer[key].is_string(), "{kind:?} {key}: {}", layer[key]);
            }
            assert!(v["file_format_version"].is_string());
        }
        assert_eq!(vk_api_version().split('.').count(), 3);
        assert_eq!(xr_api_version().split('.').count(), 2);
    }

    #[test]
    fn kinds_round_trip_their_names() {
        for kind in Kind::ALL {
            assert_eq!(Kind::parse(kind.name()), Some(kind));
        }
        assert_eq!(Kind::parse("x"), None);
    }
}
