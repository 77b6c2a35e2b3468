//! Steam's game container (the Steam Linux Runtime, run by pressure-vessel): which host paths a
//! game inside it sees, what `stereoshim run -- %command%` must change so the layer's manifest,
//! library and the OpenXR runtime's manifest are visible in there, and what `install` tells a
//! Steam user. Pure (paths and an environment function in, decisions out), so every rule is
//! unit-tested.
//!
//! The facts, from steam-runtime-tools' `docs/shared-paths.md`, `pressure-vessel/wrap.1.md` and
//! `pressure-vessel/runtime.c`: the home directory (and `/home`, `/opt`, `/media`, `/mnt`, `/srv`,
//! `/var/tmp`, `/run/media`), `/tmp`, `/nix` and `/gnu` are shared by default; the container's
//! `/usr` (with `/usr/local`), `/bin`, `/lib*`, `/sbin` and `/etc` are the runtime's (the host's
//! are diverted to `/run/host/...`), and its `/run` is its own, `XDG_RUNTIME_DIR` a fresh
//! `/run/user/UID`; any other top-level folder is shared only when listed in
//! `PRESSURE_VESSEL_FILESYSTEMS_RO` / `_RW` (or `STEAM_COMPAT_MOUNTS`), which cannot share the
//! never-shared ones. `XR_API_LAYER_PATH`, `XR_ENABLE_API_LAYERS` and `XR_RUNTIME_JSON` pass
//! through unchanged; OpenXR API layers are not imported the way Vulkan layers are.
#![forbid(unsafe_code)]

use super::install::{Env, Layout};
use std::ffi::OsString;
use std::path::{Component, Path, PathBuf};

/// Whether a host path is the same path inside Steam's container.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Visibility {
    /// Shared by default (home, `/tmp`, ...).
    Shared,
    /// Not shared unless listed in `PRESSURE_VESSEL_FILESYSTEMS_RO` (a custom top-level folder).
    IfListed,
    /// Never the host's: the reason.
    Never(&'static str),
}

/// The top-level folder of an absolute path, and the one below it.
fn first_two(path: &Path) -> (Option<String>, Option<String>) {
    let mut names = path.components().filter_map(|c| match c {
        Component::Normal(n) => Some(n.to_string_lossy().into_owned()),
        _ => None,
    });
    (names.next(), names.next())
}

/// Where `path` stands in the container (`home`: the user's home directory, shared by default).
pub fn visibility(path: &Path, home: Option<&Path>) -> Visibility {
    if home.is_some_and(|h| h.is_absolute() && path.starts_with(h)) {
        return Visibility::Shared;
    }
    let (top, second) = first_two(path);
    match (top.as_deref(), second.as_deref()) {
        (Some("usr" | "bin" | "sbin"), _) => Visibility::Never("the container's /usr is the Steam Runtime's (the host's is at /run/host/usr; /usr/local is never shared)"),
        (Some(lib), _) if lib.starts_with("lib") => Visibility::Never("the container's /lib* is the Steam Runtime's (the host's is under /run/host)"),
        (Some("etc"), _) => Visibility::Never("the container's /etc is the Steam Runtime's (the host's is at /run/host/etc)"),
        (Some("run"), Some("media")) => Visibility::Shared,
        (Some("run"), _) => Visibility::Never("the container's /run is its own (XDG_RUNTIME_DIR there is a fresh /run/user/UID)"),
        (Some("var"), Some("tmp")) => Visibility::Shared,
        (Some("var"), _) => Visibility::Never("the container's /var is the Steam Runtime's"),
        (Some("app" | "boot" | "root" | "overrides"), _) => Visibility::Never("pressure-vessel never shares it"),
        (Some("home" | "tmp" | "opt" | "media" | "mnt" | "srv" | "nix" | "gnu"), _) => Visibility::Shared,
        _ => Visibility::IfListed,
    }
}

/// Whether the command line `stereoshim run` was given goes through Steam's container: Steam
/// substitutes `%command%` with a line holding the runtime's entry point
/// (`.../SteamLinuxRuntime_sniper/_v2-entry-point --verb=waitforexitandrun -- ...`, for native
/// games and for Proton alike), or a launcher may call pressure-vessel itself.
pub fn goes_through_steam_runtime(app: &[OsString]) -> bool {
    app.iter().any(|arg| {
        let path = Path::new(arg);
        let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        name == "_v2-entry-point"
            || name.starts_with("pressure-vessel-")
            || path.components().any(|c| matches!(c, Component::Normal(n) if n.to_string_lossy().starts_with("SteamLinuxRuntime")))
    })
}

/// Where `run` writes its explicit manifest when the app goes through the container: not under
/// `XDG_RUNTIME_DIR` (the container has its own `/run`), but `$XDG_STATE_HOME`, else
/// `$HOME/.local/state` (absolute values only, as the XDG spec says).
pub fn manifest_base(env: Env<'_>) -> Option<PathBuf> {
    let absolute = |k: &str| env(k).map(PathBuf::from).filter(|p| p.is_absolute());
    absolute("XDG_STATE_HOME").or_else(|| absolute("HOME").map(|h| h.join(".local/state")))
}

/// What `run` adds to the app's environment for the container, and what it must tell the user.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ContainerPlan {
    pub env: Vec<(String, String)>,
    pub warnings: Vec<String>,
}

/// `PRESSURE_VESSEL_FILESYSTEMS_RO` with the folders the game must read inside the container: the
/// library's, the manifest's, the runtime manifest named by `XR_RUNTIME_JSON` and the config file
/// named by `STEREOSHIM_CONFIG`. They are listed even when under the home directory, which is
/// shared by default: Steam can give a game a private home instead, and listing a shared path
/// changes nothing. A path the container never shares cannot be listed: a warning says so.
pub fn container_plan(env: Env<'_>, library: &Path, manifest_dir: &Path) -> ContainerPlan {
    let home = env("HOME").filter(|h| !h.is_empty()).map(PathBuf::from);
    let mut wanted: Vec<(PathBuf, &str)> = Vec::new();
    if let Some(dir) = library.parent() {
        wanted.push((dir.to_path_buf(), "the layer's library"));
    }
    wanted.push((manifest_dir.to_path_buf(), "the layer's manifest"));
    for (key, what) in [("XR_RUNTIME_JSON", "the OpenXR runtime's manifest (XR_RUNTIME_JSON)"), ("STEREOSHIM_CONFIG", "the config file (STEREOSHIM_CONFIG)")] {
        if let Some(p) = env(key).filter(|p| Path::new(p).is_absolute()) {
            wanted.push((PathBuf::from(p), what));
        }
    }
    let current = env("PRESSURE_VESSEL_FILESYSTEMS_RO").filter(|v| !v.is_empty());
    let mut list: Vec<String> = current.iter().flat_map(|c| c.split(':')).filter(|p| !p.is_empty()).map(str::to_string).collect();
    let mut plan = ContainerPlan::default();
    for (path, what) in wanted {
        match visibility(&path, home.as_deref()) {
            Visibility::Never(why) => plan.warnings.push(format!(
                "{what} {} is not visible inside Steam's container: {why}; keep it under your home directory (`stereoshim install --user`, or `--library` from there)",
                path.display()
            )),
            _ => {
                let p = path.to_string_lossy().into_owned();
                if !list.contains(&p) {
                    list.push(p);
                }
            }
        }
    }
    if !list.is_empty() && current.as_deref() != Some(list.join(":").as_str()) {
        plan.env.push(("PRESSURE_VESSEL_FILESYSTEMS_RO".into(), list.join(":")));
    }
    plan
}

/// What `install` tells a Steam user about the layout it just installed.
pub fn install_note(layout: &Layout, env: Env<'_>) -> Vec<String> {
    let home = env("HOME").filter(|h| !h.is_empty()).map(PathBuf::from);
    let paths = [&layout.library, &layout.manifest];
    let never = paths.iter().find_map(|p| match visibility(p, home.as_deref()) {
        Visibility::Never(why) => Some((p, why)),
        _ => None,
    });
    let listed: Vec<String> = paths.iter().filter(|p| visibility(p, home.as_deref()) == Visibility::IfListed).filter_map(|p| p.parent()).map(|d| d.display().to_string()).collect();
    let mut out = Vec::new();
    if let Some((p, why)) = never {
        out.push(format!("Steam: games in the Steam Linux Runtime container (native games and Proton) do not see {}: {why}.", p.display()));
        out.push("  Install with `stereoshim install --user` for them, or set a game's launch options to `stereoshim run -- %command%` (with the full path of stereoshim).".into());
    } else if !listed.is_empty() {
        out.push("Steam: the Steam Linux Runtime container shares only listed folders outside your home directory; set the game's launch options to".into());
        out.push(format!("  PRESSURE_VESSEL_FILESYSTEMS_RO={} %command%", listed.join(":")));
    } else {
        out.push("Steam: games in the Steam Linux Runtime container (native games and Proton) see this registration too (the container shares your home directory); nothing to set.".into());
    }
    out.push("  For one game only, without installing: launch options `stereoshim run -- %command%` (with the full path of stereoshim).".into());
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn env(pairs: &'static [(&'static str, &'static str)]) -> impl Fn(&str) -> Option<String> {
        move |k| pairs.iter().find(|(key, _)| *key == k).map(|(_, v)| v.to_string())
    }

    fn args(line: &str) -> Vec<OsString> {
        line.split(' ').map(OsString::from).collect()
    }

    #[test]
    fn recognises_steams_command_lines() {
        let steam = "/home/u/.local/share/Steam/ubuntu12_32/reaper SteamLaunch AppId=450390 -- /home/u/.local/share/Steam/ubuntu12_32/steam-launch-wrapper -- \
                     /home/u/.local/share/Steam/steamapps/common/SteamLinuxRuntime_sniper/_v2-entry-point --verb=waitforexitandrun -- \
                     /home/u/.local/share/Steam/steamapps/common/Proton 9.0 (Beta)/proton waitforexitandrun /games/Game/game.exe";
        assert!(goes_through_steam_runtime(&args(steam)));
        assert!(goes_through_steam_runtime(&args("/x/SteamLinuxRuntime_soldier/run -- ./game")));
        assert!(goes_through_steam_runtime(&args("/opt/pv/bin/pressure-vessel-wrap --runtime=/x -- ./game")));
        assert!(!goes_through_steam_runtime(&args("/usr/bin/hello_xr -g Vulkan2")));
        assert!(!goes_through_steam_runtime(&args("/home/u/.local/share/Steam/steamapps/common/Game/game.x86_64")), "a game Steam runs without the runtime");
    }

    #[test]
    fn visibility_follows_pressure_vessels_rules() {
        let home = Some(Path::new("/home/u"));
        assert_eq!(visibility(Path::new("/home/u/.local/share/stereoshim/libstereoshim.so"), home), Visibility::Shared);
        assert_eq!(visibility(Path::new("/tmp/x"), home), Visibility::Shared);
        assert_eq!(visibility(Path::new("/var/tmp/x"), home), Visibility::Shared);
        assert_eq!(visibility(Path::new("/run/media/u/disk/x"), home), Visibility::Shared);
        assert_eq!(visibility(Path::new("/work/stereoshim/target/debug/libstereoshim.so"), home), Visibility::IfListed);
        for never in ["/usr/local/lib/stereoshim/libstereoshim.so", "/usr/lib/x", "/lib64/x", "/etc/xdg/openxr/1/active_runtime.json", "/run/user/1000/stereoshim/x", "/var/lib/x", "/root/x"] {
            assert!(matches!(visibility(Path::new(never), home), Visibility::Never(_)), "{never}");
        }
        assert_eq!(visibility(Path::new("/data/home-elsewhere/x"), Some(Path::new("/data/home-elsewhere"))), Visibility::Shared, "a home outside /home");
    }

    #[test]
    fn the_plan_lists_every_folder_the_game_reads_once() {
        let e = env(&[("HOME", "/home/u"), ("XR_RUNTIME_JSON", "/work/rt/runtime.json"), ("PRESSURE_VESSEL_FILESYSTEMS_RO", "/games")]);
        let plan = container_plan(&e, Path::new("/work/s/target/release/libstereoshim.so"), Path::new("/home/u/.local/state/stereoshim/openxr-7"));
        assert_eq!(plan.warnings, Vec::<String>::new());
        assert_eq!(
            plan.env,
            vec![("PRESSURE_VESSEL_FILESYSTEMS_RO".to_string(), "/games:/work/s/target/release:/home/u/.local/state/stereoshim/openxr-7:/work/rt/runtime.json".to_string())]
        );
        // Already listed: nothing to change.
        let e = env(&[("HOME", "/home/u"), ("PRESSURE_VESSEL_FILESYSTEMS_RO", "/l:/m")]);
        assert_eq!(container_plan(&e, Path::new("/l/libstereoshim.so"), Path::new("/m")).env, vec![]);
    }

    #[test]
    fn the_plan_warns_about_paths_the_container_never_shows() {
        let e = env(&[("HOME", "/home/u"), ("XR_RUNTIME_JSON", "/usr/share/openxr/1/openxr_monado.json")]);
        let plan = container_plan(&e, Path::new("/usr/local/lib/stereoshim/libstereoshim.so"), Path::new("/home/u/.local/state/stereoshim/openxr-7"));
        assert_eq!(plan.env, vec![("PRESSURE_VESSEL_FILESYSTEMS_RO".to_string(), "/home/u/.local/state/stereoshim/openxr-7".to_string())]);
        assert_eq!(plan.warnings.len(), 2, "{:?}", plan.warnings);
        assert!(plan.warnings[0].starts_with("the layer's library /usr/local/lib/stereoshim is not visible"), "{}", plan.warnings[0]);
        assert!(plan.warnings[1].contains("XR_RUNTIME_JSON") && plan.warnings[1].contains("/run/host/usr"), "{}", plan.warnings[1]);
    }

    #[test]
    fn the_manifest_goes_where_the_container_sees_it() {
        let e = env(&[("XDG_RUNTIME_DIR", "/run/user/1000"), ("HOME", "/home/u")]);
        assert_eq!(manifest_base(&e), Some(PathBuf::from("/home/u/.local/state")));
        let e = env(&[("XDG_RUNTIME_DIR", "/run/user/1000"), ("XDG_STATE_HOME", "/home/u/state"), ("HOME", "/home/u")]);
        assert_eq!(manifest_base(&e), Some(PathBuf::from("/home/u/state")));
        assert_eq!(manifest_base(&env(&[("XDG_STATE_HOME", "relative")])), None);
    }

    #[test]
    fn install_tells_a_steam_user_what_to_do() {
        let e = env(&[("HOME", "/home/u")]);
        let user = Layout { library: "/home/u/.local/share/stereoshim/libstereoshim.so".into(), manifest: "/home/u/.local/share/openxr/1/api_layers/implicit.d/stereoshim.json".into() };
        let note = install_note(&user, &e).join("\n");
        assert!(note.contains("see this registration too") && note.contains("nothing to set"), "{note}");
        let system = Layout { library: "/usr/local/lib/stereoshim/libstereoshim.so".into(), manifest: "/usr/local/share/openxr/1/api_layers/implicit.d/stereoshim.json".into() };
        let note = install_note(&system, &e).join("\n");
        assert!(note.contains("do not see /usr/local/lib/stereoshim/libstereoshim.so") && note.contains("install --user"), "{note}");
        let elsewhere = Layout { library: "/data/share/stereoshim/libstereoshim.so".into(), manifest: "/data/share/openxr/1/api_layers/implicit.d/stereoshim.json".into() };
        let note = install_note(&elsewhere, &e).join("\n");
        assert!(note.contains("PRESSURE_VESSEL_FILESYSTEMS_RO=/data/share/stereoshim:/data/share/openxr/1/api_layers/implicit.d %command%"), "{note}");
    }
}
