//! The `stereoshim` command: install or remove the layer, show what is registered and how it is
//! configured, or run one app with the layer (like `mangohud <app>`).

use clap::builder::PossibleValuesParser;
use clap::{ArgGroup, Parser, Subcommand};
use std::ffi::OsString;
use std::io::{BufRead, Write};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use stereoshim::install::{self, Scope};
use stereoshim::manifest::{self, Kind};
use stereoshim::private_fs;

/// Install or remove the layer, show what is registered and how it is configured, run one app
/// with it, print its manifests, or read its statistics.
#[derive(Parser)]
#[command(name = "stereoshim", version, about, arg_required_else_help = true)]
struct Cli {
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// Register the implicit OpenXR layer (every OpenXR app then loads stereoshim).
    Install {
        #[command(flatten)]
        scope: ScopeArgs,
        /// The library to install (default: the one next to this program, else installed).
        #[arg(long)]
        library: Option<PathBuf>,
    },
    /// Remove the registration and the installed library.
    Uninstall {
        #[command(flatten)]
        scope: ScopeArgs,
    },
    /// Manifests found, the active runtime and the effective config.
    Status {
        /// Show the config as it applies to this app (its `[app.NAME]` table).
        #[arg(long)]
        app: Option<String>,
    },
    /// Run one app with the layer, without installing it (like `mangohud APP`).
    Run {
        #[arg(long)]
        library: Option<PathBuf>,
        /// The app and its arguments, after `--`.
        #[arg(last = true, required = true, value_name = "APP")]
        app: Vec<OsString>,
    },
    /// Print a manifest for a library, or write the ones shipped in manifest/.
    #[command(group(ArgGroup::new("what").required(true).args(["kind", "shipped"])))]
    Manifest {
        #[arg(value_parser = PossibleValuesParser::new(Kind::ALL.iter().map(|k| k.name())))]
        kind: Option<String>,
        #[arg(long)]
        library: Option<PathBuf>,
        /// Write the manifests shipped in manifest/ into DIR.
        #[arg(long, value_name = "DIR")]
        shipped: Option<PathBuf>,
    },
    /// Summarise the layer's stats file (`stats.file`) per second, or convert it to CSV.
    Stats {
        /// The stats file (default: `stats.file` of the effective config).
        file: Option<PathBuf>,
        /// Keep reading as the layer appends (one line per finished second), until interrupted.
        #[arg(long)]
        follow: bool,
        /// One CSV row per frame instead of the per-second table.
        #[arg(long)]
        csv: bool,
        /// Read the config for this app (for the default file).
        #[arg(long)]
        app: Option<String>,
    },
    /// Ask running apps with the layer to save their next frame's eye images as PNGs (in
    /// `screenshot.dir`, else $XDG_PICTURES_DIR/stereoshim).
    Screenshot {
        /// Only the app with this process id (default: every running app with the layer).
        #[arg(long)]
        pid: Option<u32>,
        /// Wait until the pictures are written and print their paths.
        #[arg(long)]
        wait: bool,
        /// How long --wait waits, in seconds.
        #[arg(long, value_name = "SECONDS", default_value_t = 10, value_parser = clap::value_parser!(u64).range(1..=3600))]
        timeout: u64,
    },
}

#[derive(clap::Args)]
struct ScopeArgs {
    /// For this user (the default).
    #[arg(long, conflicts_with = "system")]
    user: bool,
    /// For every user of the machine.
    #[arg(long)]
    system: bool,
}

impl ScopeArgs {
    fn scope(&self) -> Scope {
        if self.system {
            Scope::System
        } else {
            Scope::User
        }
    }
}

fn env(key: &str) -> Option<String> {
    std::env::var(key).ok()
}

fn main() -> ExitCode {
    // clap prints help and usage errors itself (exit 0 and 2).
    let cli = Cli::parse();
    let result = match cli.cmd {
        Cmd::Install { scope, library } => install_cmd(scope.scope(), library),
        Cmd::Uninstall { scope } => uninstall_cmd(scope.scope()),
        Cmd::Status { app } => status_cmd(app),
        Cmd::Run { library, app } => run_cmd(library, &app),
        Cmd::Manifest { kind, library, shipped } => manifest_cmd(kind, library, shipped),
        Cmd::Stats { file, follow, csv, app } => stats_cmd(file, follow, csv, app),
        Cmd::Screenshot { pid, wait, timeout } => {
            stereoshim::features::screenshot::command::request(&env, pid, wait, std::time::Duration::from_secs(timeout)).map(|lines| lines.iter().for_each(|l| println!("{l}")))
        }
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("stereoshim: {e}");
            ExitCode::from(1)
        }
    }
}

fn find_library(library: Option<PathBuf>) -> Result<PathBuf, String> {
    if let Some(p) = library {
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

fn install_cmd(scope: Scope, library: Option<PathBuf>) -> Result<(), String> {
    let layout = install::layout(scope, &env).ok_or("neither XDG_DATA_HOME nor HOME is set")?;
    let library = find_library(library)?;
    let bytes = std::fs::read(&library).map_err(|e| format!("{}: {e}", library.display()))?;
    write_atomic(&layout.library, &bytes)?;
    write_atomic(&layout.manifest, manifest::json(Kind::OpenXrImplicit, &layout.library).as_bytes())?;
    println!("installed {}", layout.library.display());
    println!("registered implicit OpenXR layer {}", layout.manifest.display());
    println!("every OpenXR app now loads stereoshim; set {}=1 to keep it out of one", install::DISABLE_ENV);
    Ok(())
}

fn uninstall_cmd(scope: Scope) -> Result<(), String> {
    let layout = install::layout(scope, &env).ok_or("neither XDG_DATA_HOME nor HOME is set")?;
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

fn status_cmd(app: Option<String>) -> Result<(), String> {
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
    let app = app.unwrap_or_default();
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

fn run_cmd(library: Option<PathBuf>, app: &[OsString]) -> Result<(), String> {
    let program = app.first().ok_or("run needs an app after `--`")?;
    let library = std::fs::canonicalize(find_library(library)?).map_err(|e| e.to_string())?;
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
    let status = cmd.status().map_err(|e| format!("{}: {e}", program.to_string_lossy()))?;
    let _ = std::fs::remove_dir_all(&dir);
    std::process::exit(status.code().unwrap_or(1));
}

/// Prints one manifest for a library (the one `install`/`run` would use unless `--library`), or
/// regenerates the files shipped under `manifest/` (their `library_path` is the debug build of
/// the tree, relative to each file).
fn manifest_cmd(kind: Option<String>, library: Option<PathBuf>, shipped: Option<PathBuf>) -> Result<(), String> {
    if let Some(dir) = shipped {
        for (path, text) in manifest::shipped() {
            let path = dir.join(path);
            write_atomic(&path, text.as_bytes())?;
            println!("wrote {}", path.display());
        }
        return Ok(());
    }
    // clap allows only the names of `Kind::ALL` and requires a kind without --shipped.
    let kind = kind.as_deref().and_then(Kind::parse).ok_or("manifest needs a KIND or --shipped DIR")?;
    let library = std::fs::canonicalize(find_library(library)?).map_err(|e| e.to_string())?;
    print!("{}", manifest::json(kind, &library));
    Ok(())
}

/// Reads the stats file's lines, summarised per second (or one CSV row per frame). With
/// `follow`, keeps reading what the layer appends; a second is printed once a later frame shows
/// it is complete.
fn stats_cmd(file: Option<PathBuf>, follow: bool, csv: bool, app: Option<String>) -> Result<(), String> {
    use stereoshim::stats_summary::{self as summary, Summary};
    let path = match file {
        Some(f) => f,
        None => {
            let names: Vec<&str> = app.iter().map(String::as_str).collect();
            let (config, _) = stereoshim::config::load(&names);
            let configured = stereoshim::settings::Settings::from_config(&config).stats_file;
            if configured.is_empty() {
                return Err("no stats file: pass FILE, or set stats.file in the config".into());
            }
            PathBuf::from(configured)
        }
    };
    let f = std::fs::File::open(&path).map_err(|e| format!("{}: {e}", path.display()))?;
    let mut reader = std::io::BufReader::new(f);
    let out = std::io::stdout();
    let mut out = out.lock();
    let mut write = |s: &str| writeln!(out, "{s}").and_then(|_| out.flush()).map_err(|e| e.to_string());
    write(if csv { summary::CSV_HEADER } else { summary::TABLE_HEADER })?;
    let mut sum = Summary::default();
    // Seconds already printed (all but the last, which may still grow).
    let mut printed = 0;
    let (mut line, mut number, mut bad) = (String::new(), 0u64, 0u64);
    loop {
        line.clear();
        let n = reader.read_line(&mut line).map_err(|e| format!("{}: {e}", path.display()))?;
        if n == 0 && !follow {
            break;
        }
        if follow && !line.ends_with('\n') {
            // At the end, or inside a line the layer is still writing: read it again whole.
            reader.seek_relative(-(n as i64)).map_err(|e| e.to_string())?;
            std::thread::sleep(std::time::Duration::from_millis(200));
            continue;
        }
        number += 1;
        match summary::parse_line(&line) {
            Ok(Some(frame)) if csv => write(&summary::csv_row(&frame))?,
            Ok(Some(frame)) => {
                sum.add(&frame);
                while printed + 1 < sum.seconds.len() {
                    write(&summary::table_line(&sum.seconds[printed]))?;
                    printed += 1;
                }
            }
            Ok(None) => {}
            Err(e) => {
                bad += 1;
                eprintln!("stereoshim: {}:{number}: {e}", path.display());
            }
        }
    }
    for s in &sum.seconds[printed..] {
        write(&summary::table_line(s))?;
    }
    if bad > 0 {
        return Err(format!("{bad} line(s) of {} could not be read", path.display()));
    }
    Ok(())
}
