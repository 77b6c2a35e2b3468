//! The harness's crash report (tests/common/crash.rs): an app killed on purpose (the mock
//! runtime's `MOCK_XR_CRASH_AT`: SIGSEGV inside `xrEndFrame`, stereoshim loaded) must leave a
//! report in the test's output that names the signal and the time, keeps the run folder, shows
//! the tails of stderr and of the layer's log, and every thread's backtrace from the core dump,
//! reaching the faulting function. A crash seen once in thousands of runs is then diagnosable
//! from one CI log (issue 23).

use crate::common;

use common::crash::{core_path, glob_matches, signal_name};
use common::{Half, Run};
use std::path::{Path, PathBuf};

#[test]
fn an_app_killed_on_purpose_is_reported_with_every_threads_backtrace() {
    let out = Run::new("crash-on-purpose")
        .with_layer()
        .env("STEREOSHIM_MASK_ENABLED", "1")
        .env("MOCK_XR_LOG", "1")
        .env("MOCK_XR_EXIT_AFTER", "4")
        .env("MOCK_XR_CRASH_AT", "1")
        .run();
    assert_eq!((out.code, out.signal), (None, Some(libc::SIGSEGV)), "{}: {}", out.name, out.stderr);
    let report = out.crash.as_deref().expect("a death by signal has a crash report");
    let dir = common::target_dir().join("test-output/crash-on-purpose");

    // Signal, time, the folder kept.
    let head = report.lines().next().unwrap();
    assert!(head.starts_with("=== CRASH: crash-on-purpose: ") && head.contains("killed by SIGSEGV (11) after "), "{head}");
    let secs: f64 = head.split(" after ").nth(1).and_then(|t| t.split(" s").next()).and_then(|t| t.parse().ok()).expect("elapsed seconds");
    assert!((secs - out.elapsed.as_secs_f64()).abs() < 0.01, "{secs} s reported, {:?} measured", out.elapsed);
    assert!(report.contains(&format!("run folder kept: {}", dir.display())), "{report}");
    assert!(dir.join("capture").is_dir(), "the run folder is kept");

    // The tails of the app's stderr and of the layer's log.
    assert!(report.contains("crashing on purpose (MOCK_XR_CRASH_AT)"), "stderr tail missing:\n{report}");
    out.assert_layer_loaded(Half::Both);
    let last_log_line = out.log.lines().last().expect("the layer logged");
    assert!(report.contains("--- layer log, last 40 lines ---") && report.contains(last_log_line), "layer log tail missing:\n{report}");

    // Every thread's backtrace from the core, down to the faulting function. Lavapipe runs
    // worker threads, so there are several.
    let pattern = std::fs::read_to_string("/proc/sys/kernel/core_pattern").unwrap();
    assert!(
        !pattern.starts_with('|'),
        "kernel.core_pattern is {pattern:?}: cores go to a program, so no backtrace can be read here; the report says:\n{report}"
    );
    assert!(report.contains("every thread's backtrace, from the core dump"), "{report}");
    let core = report.split("from the core dump ").nth(1).and_then(|r| r.split(" ---").next()).map(PathBuf::from).unwrap();
    assert!(core.starts_with(&dir) && core.is_file(), "the core lies in the run folder: {}", core.display());
    let threads = report.lines().filter(|l| l.starts_with("Thread ") && l.contains(" (")).count();
    assert!(threads >= 2, "every thread's backtrace, not one ({threads}):\n{report}");
    let crashed = report.lines().position(|l| l.contains("crash_on_purpose")).unwrap_or_else(|| panic!("no frame of crash_on_purpose:\n{report}"));
    assert!(report.lines().skip(crashed).take(8).any(|l| l.contains("xrEndFrame") || l.contains("end_frame")), "the faulting thread came from xrEndFrame:\n{report}");

    // A test that asserts a clean run fails with the report in its message.
    let message = std::panic::catch_unwind(|| {
        out.assert_ok();
    })
    .expect_err("assert_ok fails on a crash");
    let message = message.downcast_ref::<String>().cloned().unwrap_or_default();
    assert!(message.contains("the app crashed") && message.contains("killed by SIGSEGV"), "{message}");
    let _ = std::fs::remove_file(core);
}

/// A run that ends by itself has no report.
#[test]
fn a_clean_run_has_no_report() {
    let out = Run::new("crash-none").run();
    out.assert_ok();
    assert!(out.crash.is_none());
    assert!(!std::fs::read_dir(common::target_dir().join("test-output/crash-none")).unwrap().flatten().any(|e| e.file_name().to_string_lossy().starts_with("core")));
}

/// Where the report looks for the core under every `kernel.core_pattern` a machine may have.
#[test]
fn core_names_follow_the_pattern() {
    let d = Path::new("/run");
    assert_eq!(core_path(d, "core", 42, "xr-scene", false), d.join("core"));
    assert_eq!(core_path(d, "core", 42, "xr-scene", true), d.join("core.42"));
    assert_eq!(core_path(d, "core.%e.%p.%t", 42, "xr-scene", true), d.join("core.xr-scene.42.*"));
    assert_eq!(core_path(d, "/var/crash/%%%p", 7, "a", false), PathBuf::from("/var/crash/%7"));
    assert!(glob_matches("core.x.42.*", "core.x.42.1700000000"));
    assert!(!glob_matches("core.x.42.*", "core.x.43.1"));
    assert!(glob_matches("core", "core") && !glob_matches("core", "core.1"));
    assert!(glob_matches("a*b*c", "aXbYc") && !glob_matches("a*b*c", "aXc"));
    assert_eq!(signal_name(libc::SIGKILL), "SIGKILL (9)");
}
