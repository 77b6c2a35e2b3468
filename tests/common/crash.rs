//! Crash and hang reports for the apps the tests start: every app runs with its run folder as
//! working directory and its core-size limit raised, so a death by signal leaves a core dump
//! there; the report names the signal and the time, keeps the run folder, shows the tails of
//! stderr and of the layer's log, and every thread's backtrace read from the core by gdb in
//! batch mode. One CI log is then enough to diagnose a crash that happens once in thousands of
//! runs (issue 23), as the real-world driver's gdb backtraces already made hangs.

use std::path::{Path, PathBuf};
use std::process::{Command, ExitStatus};
use std::time::Duration;

/// How long gdb may take over one core or process before the report goes without it (gdb loads
/// the symbols of lavapipe and LLVM: seconds, more on a loaded machine). Only the report is cut
/// short; no test result depends on it.
const GDB_LIMIT: Duration = Duration::from_secs(300);

/// Lines of each tail in a report.
const TAIL_LINES: usize = 40;

/// Prepares `cmd` so that a crash can be diagnosed: `dir` (the run folder) becomes its working
/// directory, where a relative `kernel.core_pattern` (Linux's default `core`) puts the core, and
/// its soft core-size limit is raised to the hard limit (shells default to 0: no core at all).
pub fn prepare(cmd: &mut Command, dir: &Path) {
    use std::os::unix::process::CommandExt;
    cmd.current_dir(dir);
    // SAFETY: the closure runs in the forked child before exec and only calls getrlimit and
    // setrlimit, which are async-signal-safe; it allocates nothing and takes no lock.
    unsafe {
        cmd.pre_exec(|| {
            let mut lim = libc::rlimit { rlim_cur: 0, rlim_max: 0 };
            if libc::getrlimit(libc::RLIMIT_CORE, &mut lim) == 0 {
                lim.rlim_cur = lim.rlim_max;
                // A failure leaves the limit as it was: the report then says why no core exists.
                libc::setrlimit(libc::RLIMIT_CORE, &lim);
            }
            Ok(())
        })
    };
}

/// What a report needs to know about a finished app.
pub struct Ended<'a> {
    /// The test's name of the run.
    pub name: &'a str,
    /// The run folder (kept: nothing here removes it).
    pub dir: &'a Path,
    /// The program that ran (for gdb's symbols).
    pub program: &'a Path,
    pub pid: u32,
    pub status: ExitStatus,
    pub elapsed: Duration,
    pub stderr: &'a str,
    /// The layer's log of the run (empty without the layer).
    pub log: &'a str,
}

/// The report of an app that died by a signal, or None when it exited by itself. Printed to the
/// test's stderr at once (libtest shows it with the failing test's output) and kept in the
/// `RunOutput` for the test's own assertion messages.
pub fn report(e: &Ended) -> Option<String> {
    use std::os::unix::process::ExitStatusExt;
    let signal = e.status.signal()?;
    let mut r = format!(
        "=== CRASH: {}: {} (pid {}) killed by {} after {:.2} s{} ===\nrun folder kept: {}\n",
        e.name,
        e.program.display(),
        e.pid,
        signal_name(signal),
        e.elapsed.as_secs_f64(),
        if e.status.core_dumped() { ", core dumped" } else { "" },
        e.dir.display()
    );
    r += &format!("--- stderr, last {TAIL_LINES} lines ---\n{}\n", tail_lines(e.stderr, TAIL_LINES));
    if e.log.is_empty() {
        r += "--- no layer log (the layer was not loaded, or died before writing) ---\n";
    } else {
        r += &format!("--- layer log, last {TAIL_LINES} lines ---\n{}\n", tail_lines(e.log, TAIL_LINES));
    }
    match find_core(e.dir, e.pid, e.program) {
        Ok(core) => {
            r += &format!("--- every thread's backtrace, from the core dump {} ---\n", core.display());
            r += &gdb(&[e.program.as_os_str(), core.as_os_str()]);
        }
        Err(why) => r += &format!("--- no backtrace: {why} ---\n"),
    }
    r += &format!("=== end of crash report ({}) ===\n", e.name);
    eprintln!("{r}");
    Some(r)
}

/// Every thread's backtrace of a live process (a hang), by gdb attached in batch mode.
pub fn live_backtraces(pid: u32) -> String {
    gdb(&["-p".as_ref(), pid.to_string().as_ref()])
}

/// `gdb -batch` over `target` (a program and its core, or `-p PID`): the thread list and every
/// thread's backtrace, or why there is none.
fn gdb(target: &[&std::ffi::OsStr]) -> String {
    let mut cmd = Command::new("gdb");
    cmd.args(["-batch", "-nx", "-ex", "set pagination off", "-ex", "info threads", "-ex", "thread apply all bt"])
        .args(target)
        .stdin(std::process::Stdio::null());
    let out = std::env::temp_dir().join(format!("stereoshim-gdb-{}-{}.txt", std::process::id(), unique()));
    let Ok(file) = std::fs::File::create(&out) else { return format!("(no backtrace: cannot write {})\n", out.display()) };
    let Ok(err) = file.try_clone() else { return "(no backtrace: cannot duplicate a file handle)\n".into() };
    let mut child = match cmd.stdout(file).stderr(err).spawn() {
        Ok(c) => c,
        Err(e) => return format!("(no backtrace: gdb not runnable: {e}; scripts/setup installs it)\n"),
    };
    let started = std::time::Instant::now();
    let finished = loop {
        match child.try_wait() {
            Ok(Some(_)) => break true,
            Ok(None) if started.elapsed() < GDB_LIMIT => std::thread::sleep(Duration::from_millis(50)),
            _ => {
                let _ = child.kill();
                let _ = child.wait();
                break false;
            }
        }
    };
    let text = std::fs::read_to_string(&out).unwrap_or_default();
    let _ = std::fs::remove_file(&out);
    // gdb's chatter about missing debug info and new threads says nothing about the crash.
    let mut kept: String = text
        .lines()
        .filter(|l| !l.starts_with("[New LWP") && !l.starts_with("warning: ") && !l.contains("debug info"))
        .map(|l| format!("{l}\n"))
        .collect();
    if !finished {
        kept += &format!("(gdb did not finish within {GDB_LIMIT:?}; its output so far is above)\n");
    }
    kept
}

fn unique() -> usize {
    use std::sync::atomic::{AtomicUsize, Ordering};
    static N: AtomicUsize = AtomicUsize::new(0);
    N.fetch_add(1, Ordering::Relaxed)
}

/// The core file the kernel wrote for `pid`, which ran `program` in `dir`, or why there is none.
fn find_core(dir: &Path, pid: u32, program: &Path) -> Result<PathBuf, String> {
    let pattern = std::fs::read_to_string("/proc/sys/kernel/core_pattern").map_err(|e| format!("kernel.core_pattern unreadable ({e})"))?;
    let pattern = pattern.trim();
    if let Some(handler) = pattern.strip_prefix('|') {
        let program = handler.split_whitespace().next().unwrap_or(handler);
        return Err(format!(
            "kernel.core_pattern pipes cores to {program}, so none is written here; `sysctl kernel.core_pattern=core` \
             (the kernel's default) lets the harness read them"
        ));
    }
    let uses_pid = std::fs::read_to_string("/proc/sys/kernel/core_uses_pid").is_ok_and(|s| s.trim() == "1");
    let comm: String = program.file_name().map(|n| n.to_string_lossy().chars().take(15).collect()).unwrap_or_default();
    let expected = core_path(dir, pattern, pid, &comm, uses_pid);
    let (folder, glob) = (expected.parent().unwrap_or(dir).to_path_buf(), expected.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default());
    let entries = std::fs::read_dir(&folder).map_err(|e| format!("core folder {} unreadable ({e})", folder.display()))?;
    let mut found: Vec<PathBuf> = entries.flatten().map(|e| e.path()).filter(|p| p.file_name().is_some_and(|n| glob_matches(&glob, &n.to_string_lossy()))).collect();
    found.sort();
    found.pop().ok_or_else(|| {
        let mut lim = libc::rlimit { rlim_cur: 0, rlim_max: 0 };
        // SAFETY: getrlimit writes the struct it is given.
        let hard = if unsafe { libc::getrlimit(libc::RLIMIT_CORE, &mut lim) } == 0 { lim.rlim_max.to_string() } else { "unknown".into() };
        format!(
            "no core matching {} (kernel.core_pattern {pattern:?}); the signal may not dump core (SIGKILL and SIGTERM never do: \
             then something outside killed the app, e.g. the kernel's OOM killer — see `dmesg`), or the hard core limit ({hard}) is 0",
            folder.join(&glob).display()
        )
    })
}

/// Where a core of `pid` lands under `pattern` (relative to the working directory `dir`), with
/// `*` for what the report cannot know in advance (times, host names, …).
pub fn core_path(dir: &Path, pattern: &str, pid: u32, comm: &str, uses_pid: bool) -> PathBuf {
    let mut name = String::new();
    let mut chars = pattern.chars();
    let mut has_pid = false;
    while let Some(c) = chars.next() {
        if c != '%' {
            name.push(c);
            continue;
        }
        match chars.next() {
            Some('%') => name.push('%'),
            Some('p') | Some('P') => {
                name += &pid.to_string();
                has_pid = true;
            }
            Some('e') => name += comm,
            Some(_) => name.push('*'),
            None => {}
        }
    }
    if uses_pid && !has_pid {
        name += &format!(".{pid}");
    }
    dir.join(name)
}

/// Whether `name` matches `glob`, whose only wildcard is `*`.
pub fn glob_matches(glob: &str, name: &str) -> bool {
    let parts: Vec<&str> = glob.split('*').collect();
    let (first, last) = (parts[0], parts[parts.len() - 1]);
    if parts.len() == 1 {
        return glob == name;
    }
    if !name.starts_with(first) || !name[first.len()..].ends_with(last) || name.len() < first.len() + last.len() {
        return false;
    }
    let mut rest = &name[first.len()..name.len() - last.len()];
    for p in &parts[1..parts.len() - 1] {
        match rest.find(p) {
            Some(i) => rest = &rest[i + p.len()..],
            None => return false,
        }
    }
    true
}

/// The last `n` lines of `text`.
pub fn tail_lines(text: &str, n: usize) -> String {
    let lines: Vec<&str> = text.lines().collect();
    lines[lines.len().saturating_sub(n)..].join("\n")
}

/// `SIGSEGV (11)` for 11.
pub fn signal_name(signal: i32) -> String {
    let name = match signal {
        libc::SIGHUP => "SIGHUP",
        libc::SIGINT => "SIGINT",
        libc::SIGQUIT => "SIGQUIT",
        libc::SIGILL => "SIGILL",
        libc::SIGTRAP => "SIGTRAP",
        libc::SIGABRT => "SIGABRT",
        libc::SIGBUS => "SIGBUS",
        libc::SIGFPE => "SIGFPE",
        libc::SIGKILL => "SIGKILL",
        libc::SIGUSR1 => "SIGUSR1",
        libc::SIGSEGV => "SIGSEGV",
        libc::SIGUSR2 => "SIGUSR2",
        libc::SIGPIPE => "SIGPIPE",
        libc::SIGALRM => "SIGALRM",
        libc::SIGTERM => "SIGTERM",
        libc::SIGSYS => "SIGSYS",
        libc::SIGXCPU => "SIGXCPU",
        libc::SIGXFSZ => "SIGXFSZ",
        _ => "signal",
    };
    format!("{name} ({signal})")
}
