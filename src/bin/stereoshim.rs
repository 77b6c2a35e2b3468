//! The `stereoshim` command: install or remove the layer, show what is registered and how it is
//! configured, or run one app with the layer (like `mangohud <app>`).

use clap::builder::PossibleValuesParser;
use clap::{ArgGroup, Parser, Subcommand};
use std::ffi::OsString;
use std::io::{BufRead, Write};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use stereoshim::manifests::install::{self, Scope};
use stereoshim::manifests::{self as manifest, Kind};
use stereoshim::manifests::private_fs;

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
    /// Check that the layer can work here; each check is ok, warning or error with a fix.
    ///
    /// Checks the OpenXR loader and the active runtime (an instance is created through the
    /// loader, no session), stereoshim's manifests, the Vulkan half, the GPU's capabilities for
    /// each feature (a short Vulkan probe), the effective config and its problems, and known
    /// conflicts (other implicit OpenXR layers, VK_LAYER_PATH, VK_LOADER_LAYERS_DISABLE,
    /// STEREOSHIM_DISABLE). Exit status: 0 when no check is an error (warnings allowed), 1 when
    /// any is.
    Doctor {
        /// Check the config as it applies to this app (its `[app.NAME]` table).
        #[arg(long)]
        app: Option<String>,
        /// Read this config file instead of the default one.
        #[arg(long, value_name = "FILE")]
        config: Option<PathBuf>,
        /// Print the findings as JSON.
        #[arg(long)]
        json: bool,
    },
    /// Summarise the layer's stats file (`stats.file`) per second, convert it to CSV, or plot it.
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
        /// Draw the run into this PNG instead of printing the table: GPU time per frame, each
        /// feature's pixels saved and passes, and a line where a live setting changed.
        #[arg(long, value_name = "PNG", conflicts_with_all = ["follow", "csv"])]
        plot: Option<PathBuf>,
        /// The plot's size in pixels.
        #[arg(long, value_name = "WIDTHxHEIGHT", default_value = "1280x720", value_parser = stereoshim::report::plot::parse_size, requires = "plot")]
        plot_size: (u32, u32),
        /// A TrueType or OpenType font for the plot's text (default: DejaVu Sans, else any .ttf
        /// under /usr/share/fonts; none found: the plot is drawn without text).
        #[arg(long, value_name = "FILE", requires = "plot")]
        font: Option<PathBuf>,
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
    /// A live dashboard of one running app with the layer: frame time, what each feature saves,
    /// keys that switch features in its config section, and a live A/B in the running app.
    Top {
        /// The app with this process id (default: the only running app with the layer).
        #[arg(long)]
        pid: Option<u32>,
        /// The app with this name (its applicationName or executable).
        #[arg(long)]
        app: Option<String>,
        /// A/B: frames per stretch with the features off, then on.
        #[arg(long, value_name = "FRAMES", value_parser = clap::value_parser!(u64).range(6..=100000))]
        ab_period: Option<u64>,
        /// A/B: off/on cycles per comparison.
        #[arg(long, value_name = "N", value_parser = clap::value_parser!(u64).range(1..=1000))]
        ab_cycles: Option<u64>,
    },
    /// Pictures and numbers of what the effective config would do on a headset: the hidden-area
    /// mask, the VRS rate map, the RDM skip pattern and the far field's reuse region, per view.
    #[command(group(ArgGroup::new("headset").required(true).args(["hmd", "runtime"])))]
    Preview(PreviewArgs),
}

#[derive(clap::Args)]
struct PreviewArgs {
    /// A headset profile (the mock runtime's data: FOVs, resolution, lens masks).
    #[arg(long, value_parser = PossibleValuesParser::new(hmd_profiles::profile::HMD_NAMES))]
    hmd: Option<String>,
    /// Ask the active OpenXR runtime for its views and masks (needs XR_MND_headless).
    #[arg(long)]
    runtime: bool,
    /// The config file (default: the one the layer reads).
    #[arg(long, value_name = "FILE")]
    config: Option<PathBuf>,
    /// Apply this app's `[app.NAME]` section.
    #[arg(long, value_name = "NAME")]
    app: Option<String>,
    /// Draw over this PNG (scaled to each view) instead of the angle grid.
    #[arg(long, value_name = "PNG")]
    image: Option<PathBuf>,
    /// The far field's pixel budget (default: far_field.split_px).
    #[arg(long, value_name = "N", value_parser = number_in(0.0, 64.0))]
    split_px: Option<f64>,
    /// Render at this fraction of the recommended resolution (the numbers are for that size).
    #[arg(long, default_value_t = 1.0, value_parser = number_in(0.01, 4.0))]
    scale: f64,
    /// The GPU's shading-rate texel size in pixels (minFragmentShadingRateAttachmentTexelSize).
    #[arg(long, default_value_t = stereoshim::preview::DEFAULT_VRS_TEXEL, value_parser = clap::value_parser!(u32).range(1..=64))]
    vrs_texel: u32,
    /// Where the PNGs and preview.json go (created if missing).
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
}

/// A clap value parser for a finite number in [min, max].
fn number_in(min: f64, max: f64) -> impl Fn(&str) -> Result<f64, String> + Clone {
    move |s| match s.parse::<f64>() {
        Ok(v) if v.is_finite() && (min..=max).contains(&v) => Ok(v),
        _ => Err(format!("expected a number from {min} to {max}")),
    }
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
        Cmd::Stats { file, follow, csv, app, plot: None, .. } => stats_cmd(file, follow, csv, app),
        Cmd::Stats { file, app, plot: Some(png), plot_size, font, .. } => plot_cmd(file, app, &png, plot_size, font),
        Cmd::Preview(args) => preview_cmd(args),
        Cmd::Top { pid, app, ab_period, ab_cycles } => {
            let opts = stereoshim::top::Options { pid, app, ab_period, ab_cycles: ab_cycles.map(|c| c as usize) };
            stereoshim::top::run(&env, &opts).map(|summary| println!("{summary}"))
        }
        Cmd::Doctor { app, config, json } => return doctor_cmd(app, config, json),
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
    stereoshim::manifests::steam::install_note(&layout, &env).iter().for_each(|l| println!("{l}"));
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
    let (config, diagnostics) = stereoshim::core::config::load(stereoshim::registry::keys(), &names);
    let path = stereoshim::core::config::default_path(&env);
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
    // Steam's container has a /run of its own: the manifest then goes where the game sees it.
    let steam = stereoshim::manifests::steam::goes_through_steam_runtime(app);
    let base = if steam { stereoshim::manifests::steam::manifest_base(&env) } else { private_fs::private_base(&env) };
    let base = base.ok_or("none of XDG_RUNTIME_DIR, XDG_STATE_HOME, HOME is set")?;
    let dir = private_fs::private_dir(&base, Path::new(&format!("stereoshim/openxr-{}", std::process::id()))).map_err(|e| e.to_string())?;
    private_fs::write_private(&dir.join(install::MANIFEST_FILE), manifest::json(Kind::OpenXr, &library).as_bytes()).map_err(|e| format!("{}: {e}", dir.display()))?;
    let mut cmd = std::process::Command::new(program);
    cmd.args(&app[1..]);
    for (k, v) in install::run_environment(&env, &dir) {
        cmd.env(k, v);
    }
    if steam {
        let plan = stereoshim::manifests::steam::container_plan(&env, &library, &dir);
        plan.warnings.iter().for_each(|w| eprintln!("stereoshim: {w}"));
        cmd.envs(plan.env);
    }
    // Where this run's log and stats lines will start, for the summary at exit.
    use stereoshim::report::run_summary;
    let log = stereoshim::core::log::default_path(&env);
    let stats = run_stats_file().map(|p| (run_summary::length(&p), p));
    let log_from = log.as_deref().map_or(0, run_summary::length);
    let status = cmd.status().map_err(|e| format!("{}: {e}", program.to_string_lossy()))?;
    let _ = std::fs::remove_dir_all(&dir);
    if let Some(log) = log {
        let stats = stats.as_ref().map(|(from, p)| (p.as_path(), *from));
        run_summary::at_exit(&program.to_string_lossy(), &log, log_from, stats).iter().for_each(|l| eprintln!("{l}"));
    }
    std::process::exit(status.code().unwrap_or(1));
}

/// `stats.file` as configured for every app (the app's name is not known before it runs).
fn run_stats_file() -> Option<PathBuf> {
    let (config, _) = stereoshim::core::config::load(stereoshim::registry::keys(), &[]);
    Some(PathBuf::from(stereoshim::plugin::settings::Settings::from_config(&config).stats_file)).filter(|p| !p.as_os_str().is_empty())
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

/// Runs every check and prints the findings (a table, or JSON); exit 1 when any is an error.
fn doctor_cmd(app: Option<String>, config: Option<PathBuf>, json: bool) -> ExitCode {
    use std::io::IsTerminal;
    let report = stereoshim::doctor::run(&stereoshim::doctor::Options { app, config });
    let out = std::io::stdout();
    let colour = !json && out.is_terminal() && std::env::var_os("NO_COLOR").is_none();
    let text = if json { report.json() } else { report.table(colour) };
    let mut out = out.lock();
    // A closed pipe (`doctor | head`) is not worth a panic.
    let _ = out.write_all(text.as_bytes()).and_then(|_| out.flush());
    ExitCode::from(report.exit_code())
}

/// Reads the stats file's lines, summarised per second (or one CSV row per frame). With
/// `follow`, keeps reading what the layer appends; a second is printed once a later frame shows
/// it is complete.
fn stats_cmd(file: Option<PathBuf>, follow: bool, csv: bool, app: Option<String>) -> Result<(), String> {
    use stereoshim::report::summary::{self as summary, Summary};
    let path = stats_path(file, app)?;
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

/// The stats file named, else `stats.file` of the effective config (for `app`).
fn stats_path(file: Option<PathBuf>, app: Option<String>) -> Result<PathBuf, String> {
    if let Some(f) = file {
        return Ok(f);
    }
    let names: Vec<&str> = app.iter().map(String::as_str).collect();
    let (config, _) = stereoshim::core::config::load(stereoshim::registry::keys(), &names);
    let configured = stereoshim::plugin::settings::Settings::from_config(&config).stats_file;
    if configured.is_empty() {
        return Err("no stats file: pass FILE, or set stats.file in the config".into());
    }
    Ok(PathBuf::from(configured))
}

/// `stats --plot`: reads the whole stats file into series and draws them into `png`.
fn plot_cmd(file: Option<PathBuf>, app: Option<String>, png: &Path, (width, height): (u32, u32), font: Option<PathBuf>) -> Result<(), String> {
    use stereoshim::report::{plot, series::Series, summary};
    let path = stats_path(file, app)?;
    let f = std::fs::File::open(&path).map_err(|e| format!("{}: {e}", path.display()))?;
    let mut series = Series::default();
    let mut bad = 0u64;
    // Line by line: the series keep a few numbers per frame, not the frames' JSON.
    for (i, line) in std::io::BufReader::new(f).lines().enumerate() {
        let line = line.map_err(|e| format!("{}: {e}", path.display()))?;
        match summary::parse_line(&line) {
            Ok(Some(frame)) => series.add(&frame),
            Ok(None) => {}
            Err(e) => {
                bad += 1;
                eprintln!("stereoshim: {}:{}: {e}", path.display(), i + 1);
            }
        }
    }
    let title = path.file_name().map_or_else(|| path.display().to_string(), |n| n.to_string_lossy().into_owned());
    let options = plot::Options { width, height, title, font };
    if let Some(note) = plot::write(&series, &options, png).map_err(|e| format!("{}: {e}", path.display()))? {
        eprintln!("stereoshim: {note}");
    }
    println!("{}: {} frames over {:.1} s, {} setting change(s)", png.display(), series.len(), series.duration(), series.changes.len());
    if bad > 0 {
        // The plot shows the lines that could be read; the status still says some could not.
        return Err(format!("{bad} line(s) of {} could not be read", path.display()));
    }
    Ok(())
}

/// Computes the preview (`stereoshim::preview`), writes one PNG per feature and view and
/// `preview.json` into the output folder, and prints the numbers.
fn preview_cmd(a: PreviewArgs) -> Result<(), String> {
    use stereoshim::preview::{self, draw::Canvas};
    let names: Vec<&str> = a.app.iter().map(String::as_str).collect();
    let (config, diagnostics) = match &a.config {
        Some(path) if !path.is_file() => return Err(format!("{}: no such config file", path.display())),
        Some(path) => stereoshim::core::config::load_from(stereoshim::registry::keys(), Some(path), &names),
        None => stereoshim::core::config::load(stereoshim::registry::keys(), &names),
    };
    for d in &diagnostics {
        eprintln!("stereoshim: config: {d}");
    }
    let settings = stereoshim::plugin::settings::Settings::from_config(&config);
    let mut headset = match &a.hmd {
        Some(name) => {
            let profile = hmd_profiles::profile::HmdProfile::by_name(name).ok_or("unknown headset")?;
            preview::Headset::from_profile(profile, a.scale)
        }
        None => {
            let mut h = stereoshim::xr::headless::runtime_headset().map_err(|e| e.to_string())?;
            (h.width, h.height) = preview::scaled((h.width, h.height), a.scale);
            h
        }
    };
    if headset.views.len() != 2 {
        return Err(format!("{} reports {} views; the preview needs two", headset.name, headset.views.len()));
    }
    headset.name = headset.name.trim().to_string();
    let image = match &a.image {
        Some(p) => Some(Canvas::from_png(&std::fs::read(p).map_err(|e| format!("{}: {e}", p.display()))?).map_err(|e| format!("{}: {e}", p.display()))?),
        None => None,
    };
    let options = preview::Options { split_px: a.split_px, vrs_texel: a.vrs_texel };
    let p = preview::compute(&headset, &settings, &options);
    std::fs::create_dir_all(&a.out).map_err(|e| format!("{}: {e}", a.out.display()))?;
    let file_name = |feature: &str, view: usize| format!("{}-view-{view}.png", feature.replace('_', "-"));
    let mut written = 0;
    for (i, view) in headset.views.iter().enumerate() {
        let base = match &image {
            Some(img) => Canvas::resized(img, p.width, p.height),
            None => Canvas::grid(p.width, p.height, &view.fov),
        };
        for (feature, picture) in preview::draw::view_pictures(&p, i, &base) {
            let path = a.out.join(file_name(feature, i));
            std::fs::write(&path, picture.png()?).map_err(|e| format!("{}: {e}", path.display()))?;
            written += 1;
        }
    }
    let mut report = preview::report(&headset, &settings, &p, &file_name);
    // A named headset: its mask under each kind of runtime, and what the layer makes of it.
    let profile = a.hmd.as_deref().and_then(hmd_profiles::profile::HmdProfile::by_name);
    if let Some(profile) = profile {
        report["mask_sources"] = preview::mask_sources::report(profile, &headset, &settings);
    }
    let json_path = a.out.join("preview.json");
    let text = serde_json::to_string_pretty(&report).map_err(|e| e.to_string())?;
    std::fs::write(&json_path, text + "\n").map_err(|e| format!("{}: {e}", json_path.display()))?;
    print!("{}", preview_summary(&report));
    if report["mask_sources"].is_object() {
        print!("{}", preview::mask_sources::summary(&report["mask_sources"]));
    }
    println!("wrote {written} PNGs and {}", json_path.display());
    Ok(())
}

/// The numbers of `preview.json` in lines for a person.
fn preview_summary(r: &serde_json::Value) -> String {
    let pct = |v: &serde_json::Value| format!("{:.1}%", v.as_f64().unwrap_or(0.0) * 100.0);
    let on = |k: &str| if r["enabled"][k].as_bool() == Some(true) { "" } else { " [disabled in the config]" };
    let mut s = format!("{}: {}x{} per view\n", r["headset"].as_str().unwrap_or("?"), r["width"], r["height"]);
    for v in r["views"].as_array().into_iter().flatten() {
        let i = &v["view"];
        let m = &v["mask"];
        s += &format!(
            "view {i} mask ({}): {} px masked ({}){}\n",
            m["source"].as_str().unwrap_or("none"),
            m["pixels_masked"],
            pct(&m["fraction"]),
            on("mask")
        );
        let vrs = &v["vrs"];
        let rates: Vec<String> = ["1x1", "2x1", "2x2"].iter().map(|k| format!("{k} {}", pct(&vrs["fractions"][k]))).collect();
        s += &format!(
            "view {i} VRS ({} px texels): {}; fragments saved: 2x1 {}, 2x2 {} (total {}){}\n",
            vrs["texel"],
            rates.join(", "),
            vrs["fragments_saved"]["2x1"],
            vrs["fragments_saved"]["2x2"],
            vrs["fragments_saved_total"],
            on("foveation")
        );
        if v["rdm"].is_object() {
            s += &format!("view {i} RDM: {} px skipped ({}){}\n", v["rdm"]["pixels_skipped"], pct(&v["rdm"]["skipped_fraction"]), on("foveation"));
        }
        if let Some(c) = v["fov_cut"].as_object() {
            s += &format!("view {i} FOV cut: the app renders {}x{} (pixels {}..{} x {}..{}), {} fewer pixels{}\n", c["width"], c["height"], c["x0"], c["x1"], c["y0"], c["y1"], pct(&c["saved_fraction"]), on("fov_cut"));
        }
        let f = &v["far_field"];
        if f["role"] == "destination" {
            s += &format!("view {i} far field: {} px reusable ({}) beyond the split{}\n", f["pixels_reusable"], pct(&f["share"]), on("far_field"));
        } else {
            s += &format!("view {i} far field: the source (renders everything){}\n", on("far_field"));
        }
    }
    let u = &r["upscale"];
    s += &format!(
        "upscale (scale {}): the app renders {}x{} per view, {} of the display's {} px ({}){}\n",
        u["scale"],
        u["told"][0],
        u["told"][1],
        u["rendered_px"],
        u["display_px"],
        pct(&u["rendered_fraction"]),
        on("upscale")
    );
    let ff = &r["far_field"];
    let split = ff["split_m"].as_f64().map_or("none (no baseline or pixel budget)".to_string(), |m| format!("{m:.2} m"));
    s += &format!("far field split: {split} at {} px (shift {})\n", ff["split_px"], ff["shift"].as_str().unwrap_or("?"));
    s
}
