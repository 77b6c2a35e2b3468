//! The `stereoshim` command: install or remove the layer, show what is registered and how it is
//! configured, or run one app with the layer (like `mangohud <app>`).

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use stereoshim::install::{self, Scope};
use stereoshim::manifest::{self, Kind};
use stereoshim::private_fs;

const USAGE: &str = "usage:
  stereoshim install [--user|--system] [--library PATH]   register the implicit OpenXR layer
  stereoshim uninstall [--user|--system]                  remove it
  stereoshim status [--app NAME]                          manifests, active runtime, effective config
  stereoshim run [--library PATH] -- APP [ARGS...]        run one app with the layer
  stereoshim manifest KIND [--library PATH]               print a manifest (KIND: openxr, openxr-implicit, vulkan)
  stereoshim manifest --shipped DIR                       write the manifests shipped in manifest/ into DIR";

fn env(key: &str) -> Option<String> {
    std::env::var(key).ok()
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let result = match args.first().map(String::as_str) {
        Some("install") => install_cmd(&args[1..]),
        Some("uninstall") => uninstall_cmd(&args[1..]),
        Some("status") => status_cmd(&args[1..]),
        Some("run") => run_cmd(&args[1..]),
        Some("manifest") => manifest_cmd(&args[1..]),
        Some("-h" | "--help") => {
            println!("{USAGE}");
            return ExitCode::SUCCESS;
        }
        _ => Err(USAGE.to_string()),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("stereoshim: {e}");
            ExitCode::from(2)
        }
    }
}

fn scope(args: &[String]) -> Result<Scope, String> {
    match (args.iter().any(|a| a == "--user"), args.iter().any(|a| a == "--system")) {
        (true, true) => Err("--user and --system exclude each other".into()),
        (_, true) => Ok(Scope::System),
        _ => Ok(Scope::User),
    }
}

fn option(args: &[String], name: &str) -> Option<String> {
    args.iter().position(|a| a == name).and_then(|i| args.get(i + 1)).cloned()
}

/// The library to register or run: `--library`, else the one next to this executable (a build
/// tree or an install), else the user's or the system's installed one.
fn find_library(args: &[String]) -> Result<PathBuf, String> {
    if let Some(p) = option(args, "--library") {
        let p = PathBuf::from(p);
        return if p.is_file() { Ok(p) } else { Err(format!("{}: no such library", p.display())) };
    }
    let beside = std::env::current_exe().ok().and_then(|e| e.parent().map(|d| d.join("libstereoshim.so")));
    let installed = [Scope::User, Scope::System].into_iter().filter_map(|s| install::layout(s, &env).map(|l| l.library));
    beside
        .into_iter()
        .chain(installed)
        .find(|p| p.is_file())
        .ok_or_else(|| "libstereoshim.so not found next to this program or installed; pass --library".into())
}

/// Writes through a temporary name and renames, so an app starting meanwhile never loads half a
/// file (and a running app keeps the old library it mapped); user-only permissions
/// (`private_fs::write_private`), since a loader maps whatever these files name.
fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), String> {
    let dir = path.parent().ok_or("no parent folder")?;
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    private_fs::write_private(path, bytes).map_err(|e| format!("{}: {e}", path.display()))
}

fn install_cmd(args: &[String]) -> Result<(), String> {
    let layout = install::layout(scope(args)?, &env).ok_or("neither XDG_DATA_HOME nor HOME is set")?;
    let library = find_library(args)?;
    let bytes = std::fs::read(&library).map_err(|e| format!("{}: {e}", library.display()))?;
    write_atomic(&layout.library, &bytes)?;
    write_atomic(&layout.manifest, manifest::json(Kind::OpenXrImplicit, &layout.library).as_bytes())?;
    println!("installed {}", layout.library.display());
    println!("registered implicit OpenXR layer {}", layout.manifest.display());
    println!("every OpenXR app now loads stereoshim; set {}=1 to keep it out of one", install::DISABLE_ENV);
    Ok(())
}

fn uninstall_cmd(args: &[String]) -> Result<(), String> {
    let layout = install::layout(scope(args)?, &env).ok_or("neither XDG_DATA_HOME nor HOME is set")?;
    for path in [&layout.manifest, &layout.library] {
        match std::fs::remove_file(path) {
            Ok(()) => println!("removed {}", path.display()),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => println!("not installed: {}", path.display()),
            Err(e) => return Err(format!("{}: {e}", path.display())),
        }
    }
    // The library's folder is stereoshim's own (`…/stereoshim/`): gone with its last file. The
    // manifest's folder is the loader's, shared with other layers, and stays.
    if let Some(dir) = layout.library.parent() {
        if std::fs::remove_dir(dir).is_ok() {
            println!("removed {}", dir.display());
        }
    }
    Ok(())
}

fn status_cmd(args: &[String]) -> Result<(), String> {
    println!("OpenXR layer manifests naming {}:", install::XR_LAYER_NAME);
    let mut found = 0;
    for (dir, implicit) in install::layer_search_dirs(&env) {
        let Ok(entries) = std::fs::read_dir(&dir) else { continue };
        for entry in entries.flatten() {
            let path = entry.path();
            let Ok(text) = std::fs::read_to_string(&path) else { continue };
            let Some(lib) = install::our_manifest_library(&text) else { continue };
            found += 1;
            let lib_path = dir.join(&lib);
            println!(
                "  {} ({}) -> {} {}",
                path.display(),
                if implicit { "implicit" } else { "explicit" },
                lib,
                if lib_path.is_file() { "" } else { "[library missing]" }
            );
        }
    }
    if found == 0 {
        println!("  none (not installed; `stereoshim run -- APP` works without installing)");
    }
    if env(install::DISABLE_ENV).is_some() {
        println!("  {} is set: the implicit layer is disabled in this environment", install::DISABLE_ENV);
    }
    match install::active_runtime(&env, &|p| p.is_file()) {
        Some(p) => println!("active OpenXR runtime: {}", p.display()),
        None => println!("active OpenXR runtime: none found"),
    }
    let app = option(args, "--app").unwrap_or_default();
    let names: Vec<&str> = if app.is_empty() { vec![] } else { vec![app.as_str()] };
    let (config, diagnostics) = stereoshim::config::load(&names);
    let path = stereoshim::config::default_path(&env);
    println!(
        "effective config{} (file {}):",
        if app.is_empty() { String::new() } else { format!(" for app {app:?}") },
        path.as_ref().map(|p| p.display().to_string()).unwrap_or_else(|| "none".into())
    );
    for (key, value, source) in config.entries() {
        println!("  {key} = {value}    ({source})");
    }
    for d in diagnostics {
        println!("  problem: {d}");
    }
    Ok(())
}

fn run_cmd(args: &[String]) -> Result<(), String> {
    let split = args.iter().position(|a| a == "--").ok_or("run needs `-- APP [ARGS...]`")?;
    let (ours, app) = (&args[..split], &args[split + 1..]);
    let program = app.first().ok_or("run needs an app after `--`")?;
    let library = std::fs::canonicalize(find_library(ours)?).map_err(|e| e.to_string())?;
    // An explicit manifest of our own, so `run` needs no installation and always uses this library.
    // In a folder of the user's own (`private_fs`), never a shared temporary one: the OpenXR
    // loader loads whatever library a manifest there names.
    let base = private_fs::private_base(&env).ok_or("none of XDG_RUNTIME_DIR, XDG_STATE_HOME, HOME is set")?;
    let dir = private_fs::private_dir(&base, Path::new(&format!("stereoshim/openxr-{}", std::process::id()))).map_err(|e| e.to_string())?;
    private_fs::write_private(&dir.join(install::MANIFEST_FILE), manifest::json(Kind::OpenXr, &library).as_bytes()).map_err(|e| format!("{}: {e}", dir.display()))?;
    let mut cmd = std::process::Command::new(program);
    cmd.args(&app[1..]);
    for (k, v) in install::run_environment(&env, &dir) {
        cmd.env(k, v);
    }
    let status = cmd.status().map_err(|e| format!("{program}: {e}"))?;
    let _ = std::fs::remove_dir_all(&dir);
    std::process::exit(status.code().unwrap_or(1));
}

/// Prints one manifest for a library (the one `install`/`run` would use unless `--library`), or
/// regenerates the files shipped under `manifest/` (their `library_path` is the debug build of
/// the tree, relative to each file).
fn manifest_cmd(args: &[String]) -> Result<(), String> {
    if let Some(dir) = option(args, "--shipped") {
        for (path, text) in manifest::shipped() {
            let path = Path::new(&dir).join(path);
            write_atomic(&path, text.as_bytes())?;
            println!("wrote {}", path.display());
        }
        return Ok(());
    }
    let names: Vec<&str> = Kind::ALL.iter().map(|k| k.name()).collect();
    let kind = args.first().ok_or_else(|| format!("manifest needs a KIND ({}) or --shipped DIR", names.join(", ")))?;
    let kind = Kind::parse(kind).ok_or_else(|| format!("{kind}: not a manifest kind ({})", names.join(", ")))?;
    let library = std::fs::canonicalize(find_library(args)?).map_err(|e| e.to_string())?;
    print!("{}", manifest::json(kind, &library));
    Ok(())
}
