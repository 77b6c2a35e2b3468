//! `stereoshim doctor` inside Steam's game container (the Steam Linux Runtime, run by
//! pressure-vessel): says that it runs there, and whether what the OpenXR loader needs is visible
//! from inside — stereoshim's manifests and the library each names, the folders of
//! `XR_API_LAYER_PATH`, the OpenXR runtime's manifest and library — with fixes that work for the
//! container (`manifests::steam` has its sharing rules). Facts are read under a root folder (`/`
//! on the machine, a fake tree in tests), so detection and checks are unit-tested.

use super::rules::{resolve_library, runtime_library, Finding, Status};
use crate::manifests::install::{self, Env};
use crate::manifests::steam::{visibility, Visibility};
use std::path::{Component, Path, PathBuf};

/// The file pressure-vessel writes into every container (steam-runtime-tools,
/// `docs/slr-for-game-developers.md`, "Detecting the container environment"): `pressure-vessel`
/// (Flatpak ≥ 1.10 writes `flatpak`).
pub const CONTAINER_MANAGER: &str = "/run/host/container-manager";

/// One of stereoshim's manifests as seen from here.
#[derive(Clone, Debug, PartialEq)]
pub struct LayerSeen {
    pub manifest: PathBuf,
    pub implicit: bool,
    pub library: PathBuf,
    pub library_exists: bool,
}

/// The OpenXR runtime the loader would use here.
#[derive(Clone, Debug, PartialEq)]
pub enum RuntimeSeen {
    /// No manifest: `XR_RUNTIME_JSON` missing here, or none of the searched files exists.
    Missing { env: Option<PathBuf>, searched: Vec<PathBuf> },
    /// The manifest, and its library with whether it exists (None: no readable `library_path`).
    Found { manifest: PathBuf, library: Option<(PathBuf, bool)> },
}

/// What doctor knows about the container it runs in.
#[derive(Clone, Debug, PartialEq)]
pub struct ContainerFacts {
    /// `pressure-vessel`, `flatpak`, ...; None outside a container (no findings then).
    pub manager: Option<String>,
    /// What showed it.
    pub marker: String,
    /// The runtime's name from `/etc/os-release` when it is a Steam Runtime (`ID=steamrt`).
    pub runtime: Option<String>,
    pub layers: Vec<LayerSeen>,
    /// `XR_API_LAYER_PATH` folders that do not exist here.
    pub missing_layer_dirs: Vec<PathBuf>,
    pub xr_runtime: RuntimeSeen,
    pub home: Option<PathBuf>,
}

/// `path` (absolute, as the container sees it) under `root`.
fn at(root: &Path, path: &Path) -> PathBuf {
    root.join(path.strip_prefix("/").unwrap_or(path))
}

/// `a/b/../c` as `a/c`, for the report: a manifest's relative `library_path` reads better as
/// the place it names (existence is checked on the path as the loader forms it).
fn lexical(path: &Path) -> PathBuf {
    let mut out = PathBuf::new();
    for c in path.components() {
        match c {
            Component::ParentDir if out.file_name().is_some() => {
                out.pop();
            }
            Component::CurDir => {}
            c => out.push(c),
        }
    }
    out
}

/// The container managers Steam's games run under: pressure-vessel, and Flatpak for Steam's
/// Flatpak app. Others (a CI job's podman, say) are not where a game runs: no findings there.
const STEAM_MANAGERS: [&str; 2] = ["pressure-vessel", "flatpak"];

/// Which container this is, and the marker that said so: pressure-vessel's file first (the
/// documented marker), then the `container` variable pressure-vessel and Flatpak set, then
/// Flatpak's older `/.flatpak-info`.
pub fn detect(root: &Path, env: Env<'_>) -> Option<(String, String)> {
    if let Ok(text) = std::fs::read_to_string(at(root, Path::new(CONTAINER_MANAGER))) {
        let name = text.lines().next().unwrap_or("").trim().to_string();
        if STEAM_MANAGERS.contains(&name.as_str()) {
            return Some((name, CONTAINER_MANAGER.into()));
        }
    }
    if let Some(name) = env("container").filter(|v| STEAM_MANAGERS.contains(&v.as_str())) {
        return Some((name, "the `container` environment variable".into()));
    }
    at(root, Path::new("/.flatpak-info")).exists().then(|| ("flatpak".into(), "/.flatpak-info".into()))
}

/// `PRETTY_NAME` of `/etc/os-release` when `ID` is `steamrt`.
fn steam_runtime_name(os_release: &str) -> Option<String> {
    let field = |k: &str| os_release.lines().find_map(|l| l.strip_prefix(k)?.strip_prefix('=')).map(|v| v.trim_matches(&['"', '\''][..]).to_string());
    (field("ID").as_deref() == Some("steamrt")).then(|| field("PRETTY_NAME").or_else(|| field("VERSION_CODENAME")).unwrap_or_else(|| "Steam Runtime".into()))
}

/// Reads the facts under `root`; `manager` None (and nothing else read) outside a container.
pub fn gather(root: &Path, env: Env<'_>) -> ContainerFacts {
    let non_empty = |k: &str| env(k).filter(|v| !v.is_empty());
    let Some((manager, marker)) = detect(root, env) else {
        return ContainerFacts { manager: None, marker: String::new(), runtime: None, layers: vec![], missing_layer_dirs: vec![], xr_runtime: RuntimeSeen::Missing { env: None, searched: vec![] }, home: None };
    };
    let runtime = std::fs::read_to_string(at(root, Path::new("/etc/os-release"))).ok().and_then(|t| steam_runtime_name(&t));
    let mut layers = Vec::new();
    for (dir, implicit) in install::layer_search_dirs(env) {
        let Ok(entries) = std::fs::read_dir(at(root, &dir)) else { continue };
        let mut names: Vec<_> = entries.flatten().map(|e| e.file_name()).collect();
        names.sort();
        for name in names {
            let manifest = dir.join(name);
            let Some(written) = std::fs::read_to_string(at(root, &manifest)).ok().and_then(|t| install::our_manifest_library(&t)) else { continue };
            let library = resolve_library(&manifest, &written);
            // A bare file name goes through the dynamic linker's search: not a path to check.
            let library_exists = (!library.is_absolute() && !written.contains('/')) || at(root, &library).is_file();
            layers.push(LayerSeen { manifest, implicit, library: lexical(&library), library_exists });
        }
    }
    let missing_layer_dirs = non_empty("XR_API_LAYER_PATH").map_or_else(Vec::new, |p| p.split(':').filter(|d| !d.is_empty()).map(PathBuf::from).filter(|d| !at(root, d).is_dir()).collect());
    let env_runtime = non_empty("XR_RUNTIME_JSON").map(PathBuf::from);
    let searched = if env_runtime.is_some() { vec![] } else { super::gather::runtime_candidates(env) };
    let found = env_runtime.iter().chain(searched.iter()).find(|p| at(root, p).is_file()).cloned();
    let xr_runtime = match found {
        None => RuntimeSeen::Missing { env: env_runtime, searched },
        Some(manifest) => {
            // The loader reads `library_path` relative to the file a link points at.
            let real = std::fs::canonicalize(at(root, &manifest)).ok().and_then(|r| std::fs::canonicalize(root).ok().and_then(|base| r.strip_prefix(base).ok().map(|p| Path::new("/").join(p)))).unwrap_or_else(|| manifest.clone());
            let library = std::fs::read_to_string(at(root, &real)).ok().and_then(|t| runtime_library(&t).ok()).map(|w| {
                let p = resolve_library(&real, &w);
                let exists = !w.contains('/') || at(root, &p).is_file();
                (lexical(&p), exists)
            });
            RuntimeSeen::Found { manifest, library }
        }
    };
    ContainerFacts { manager: Some(manager), marker, runtime, layers, missing_layer_dirs, xr_runtime, home: non_empty("HOME").map(PathBuf::from) }
}

fn finding(check: &str, status: Status, detail: String, fix: Option<String>) -> Finding {
    Finding { check: check.into(), status, detail, fix }
}

/// How to make a host path visible in the container, by pressure-vessel's rules.
fn share_fix(path: &Path, home: Option<&Path>) -> String {
    let dir = path.parent().unwrap_or(path).display();
    match visibility(path, home) {
        Visibility::Never(why) => format!("{why}: on the host, keep it under your home directory (`stereoshim install --user`, or `stereoshim run --library` from there)"),
        _ => format!("share it: on the host, launch options `PRESSURE_VESSEL_FILESYSTEMS_RO={dir} %command%`, or keep it under your home directory"),
    }
}

/// The findings; none outside a container.
pub fn findings(f: &ContainerFacts) -> Vec<Finding> {
    let Some(manager) = &f.manager else { return vec![] };
    let home = f.home.as_deref();
    let what = match (manager.as_str(), &f.runtime) {
        ("pressure-vessel", Some(rt)) => format!("inside Steam's game container (pressure-vessel, {rt})"),
        ("pressure-vessel", None) => "inside Steam's game container (pressure-vessel)".to_string(),
        (other, _) => format!("inside a {other} container"),
    };
    let mut out = vec![finding("container", Status::Ok, format!("{what}, from {}: the checks here see what a game sees", f.marker), None)];
    for dir in &f.missing_layer_dirs {
        out.push(finding(
            "container.layer_path",
            Status::Error,
            format!("XR_API_LAYER_PATH names {}, which does not exist in the container", dir.display()),
            Some(format!("{} (a `stereoshim run` of this version writes its manifest where the container sees it and shares it)", share_fix(dir, home))),
        ));
    }
    if f.layers.is_empty() {
        out.push(finding(
            "container.layer",
            Status::Error,
            "no stereoshim manifest is visible in the container: games here run without the layer".into(),
            Some("on the host, `stereoshim install --user` (your home is shared with the container), or set the game's launch options to `stereoshim run -- %command%`".into()),
        ));
    }
    for l in &f.layers {
        let kind = if l.implicit { "implicit" } else { "explicit" };
        if l.library_exists {
            out.push(finding("container.layer", Status::Ok, format!("{} ({kind}) -> {}, visible here", l.manifest.display(), l.library.display()), None));
        } else {
            out.push(finding(
                "container.layer",
                Status::Error,
                format!("{} ({kind}) names {}, which is not visible in the container", l.manifest.display(), l.library.display()),
                Some(share_fix(&l.library, home)),
            ));
        }
    }
    // Importing the host's runtime is pressure-vessel's opt-in (experimental in its 2025 releases).
    let import = "or set PRESSURE_VESSEL_IMPORT_OPENXR_1_RUNTIMES=1 in the launch options (pressure-vessel then imports the host's active OpenXR runtime)";
    match &f.xr_runtime {
        RuntimeSeen::Found { manifest, library: Some((lib, true)) } => out.push(finding("container.runtime", Status::Ok, format!("{} -> {}, visible here", manifest.display(), lib.display()), None)),
        RuntimeSeen::Found { manifest, library: Some((lib, false)) } => out.push(finding(
            "container.runtime",
            Status::Error,
            format!("the OpenXR runtime {} names {}, which is not visible in the container", manifest.display(), lib.display()),
            Some(format!("{}; {import}", share_fix(lib, home))),
        )),
        RuntimeSeen::Found { manifest, library: None } => {
            out.push(finding("container.runtime", Status::Warning, format!("{} is visible but names no library the checks could read", manifest.display()), Some("see the openxr.runtime check".into())))
        }
        RuntimeSeen::Missing { env: Some(p), .. } => out.push(finding(
            "container.runtime",
            Status::Error,
            format!("XR_RUNTIME_JSON names {}, which is not visible in the container", p.display()),
            Some(format!("{}; {import}", share_fix(p, home))),
        )),
        RuntimeSeen::Missing { env: None, searched } => out.push(finding(
            "container.runtime",
            Status::Error,
            format!("no active OpenXR runtime is visible in the container (searched {})", searched.iter().map(|p| p.display().to_string()).collect::<Vec<_>>().join(", ")),
            Some(format!("the host's /etc/xdg is not the container's: on the host, set XR_RUNTIME_JSON to a runtime manifest under your home directory, {import}")),
        )),
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A fake container root, removed when dropped.
    struct Root(PathBuf);
    impl Root {
        fn new(name: &str) -> Root {
            let p = std::env::temp_dir().join(format!("stereoshim-container-{name}-{}", std::process::id()));
            let _ = std::fs::remove_dir_all(&p);
            std::fs::create_dir_all(&p).unwrap();
            Root(p)
        }
        fn file(&self, path: &str, text: &str) -> &Root {
            let p = at(&self.0, Path::new(path));
            std::fs::create_dir_all(p.parent().unwrap()).unwrap();
            std::fs::write(p, text).unwrap();
            self
        }
    }
    impl Drop for Root {
        fn drop(&mut self) {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }

    fn env(pairs: &'static [(&'static str, &'static str)]) -> impl Fn(&str) -> Option<String> {
        move |k| pairs.iter().find(|(key, _)| *key == k).map(|(_, v)| v.to_string())
    }

    const OURS: &str = r#"{"file_format_version":"1.0.0","api_layer":{"name":"XR_APILAYER_STEREOSHIM_stereoshim","library_path":"../../../../stereoshim/libstereoshim.so","api_version":"1.0","implementation_version":"1","description":"x","disable_environment":"STEREOSHIM_DISABLE"}}"#;
    const HOME: &[(&str, &str)] = &[("HOME", "/home/u")];

    #[test]
    fn detects_the_container_by_its_documented_markers() {
        let r = Root::new("detect");
        assert_eq!(detect(&r.0, &env(&[])), None, "a plain machine");
        assert_eq!(detect(&r.0, &env(&[("container", "podman")])), None, "not a container Steam runs games in");
        assert_eq!(detect(&r.0, &env(&[("container", "pressure-vessel")])).map(|d| d.0), Some("pressure-vessel".into()));
        r.file("/.flatpak-info", "[Application]\n");
        assert_eq!(detect(&r.0, &env(&[])).map(|d| d.0), Some("flatpak".into()));
        r.file(CONTAINER_MANAGER, "pressure-vessel\n");
        assert_eq!(detect(&r.0, &env(&[])), Some(("pressure-vessel".into(), CONTAINER_MANAGER.into())), "the file wins");
        assert_eq!(findings(&gather(&Root::new("plain").0, &env(HOME))), vec![], "no findings outside a container");
    }

    #[test]
    fn a_healthy_container_is_all_ok() {
        let r = Root::new("healthy");
        r.file(CONTAINER_MANAGER, "pressure-vessel\n")
            .file("/etc/os-release", "PRETTY_NAME=\"Steam Runtime 3 (sniper)\"\nID=steamrt\n")
            .file("/home/u/.local/share/openxr/1/api_layers/implicit.d/stereoshim.json", OURS)
            .file("/home/u/.local/share/stereoshim/libstereoshim.so", "elf")
            .file("/home/u/.config/openxr/1/active_runtime.json", r#"{"file_format_version":"1.0.0","runtime":{"library_path":"/home/u/rt/librt.so"}}"#)
            .file("/home/u/rt/librt.so", "elf");
        let f = findings(&gather(&r.0, &env(HOME)));
        assert!(f.iter().all(|x| x.status == Status::Ok), "{f:#?}");
        assert!(f[0].detail.starts_with("inside Steam's game container (pressure-vessel, Steam Runtime 3 (sniper)), from /run/host/container-manager"), "{}", f[0].detail);
        assert_eq!(f[1].detail, "/home/u/.local/share/openxr/1/api_layers/implicit.d/stereoshim.json (implicit) -> /home/u/.local/share/stereoshim/libstereoshim.so, visible here");
        assert_eq!(f[2].detail, "/home/u/.config/openxr/1/active_runtime.json -> /home/u/rt/librt.so, visible here");
    }

    #[test]
    fn what_the_container_does_not_show_is_an_error_with_its_fix() {
        let r = Root::new("broken");
        r.file(CONTAINER_MANAGER, "pressure-vessel\n")
            // A system install: the manifest is reached through XDG_DATA_DIRS, its library is not.
            .file("/usr/local/share/openxr/1/api_layers/implicit.d/stereoshim.json", &OURS.replace("../../../../stereoshim/libstereoshim.so", "/usr/local/lib/stereoshim/libstereoshim.so"))
            .file("/etc/xdg/openxr/1/active_runtime.json", r#"{"file_format_version":"1.0.0","runtime":{"library_path":"/usr/lib/x86_64-linux-gnu/libopenxr_monado.so"}}"#);
        let e = env(&[("HOME", "/home/u"), ("XR_API_LAYER_PATH", "/run/user/1000/stereoshim/openxr-9")]);
        let f = findings(&gather(&r.0, &e));
        let get = |check: &str| f.iter().filter(|x| x.check == check).collect::<Vec<_>>();
        let dir = get("container.layer_path");
        assert_eq!(dir.len(), 1);
        assert_eq!(dir[0].status, Status::Error);
        assert!(dir[0].fix.as_deref().unwrap().contains("/run is its own"), "{:?}", dir[0].fix);
        let layer = get("container.layer");
        assert_eq!(layer[0].status, Status::Error);
        assert!(layer[0].detail.contains("names /usr/local/lib/stereoshim/libstereoshim.so, which is not visible"), "{}", layer[0].detail);
        assert!(layer[0].fix.as_deref().unwrap().contains("install --user"), "{:?}", layer[0].fix);
        let rt = get("container.runtime");
        assert_eq!(rt[0].status, Status::Error);
        assert!(rt[0].detail.contains("libopenxr_monado.so, which is not visible"), "{}", rt[0].detail);
        assert!(rt[0].fix.as_deref().unwrap().contains("PRESSURE_VESSEL_IMPORT_OPENXR_1_RUNTIMES=1"), "{:?}", rt[0].fix);
    }

    #[test]
    fn nothing_visible_says_how_to_bring_the_layer_in() {
        let r = Root::new("empty");
        r.file(CONTAINER_MANAGER, "pressure-vessel\n");
        let f = findings(&gather(&r.0, &env(&[("HOME", "/home/u"), ("XR_RUNTIME_JSON", "/work/rt.json")])));
        let layer = f.iter().find(|x| x.check == "container.layer").unwrap();
        assert!(layer.status == Status::Error && layer.fix.as_deref().unwrap().contains("stereoshim run -- %command%"), "{layer:?}");
        let rt = f.iter().find(|x| x.check == "container.runtime").unwrap();
        assert!(rt.detail.contains("XR_RUNTIME_JSON names /work/rt.json"), "{}", rt.detail);
        assert!(rt.fix.as_deref().unwrap().contains("PRESSURE_VESSEL_FILESYSTEMS_RO=/work %command%"), "{:?}", rt.fix);
    }
}
