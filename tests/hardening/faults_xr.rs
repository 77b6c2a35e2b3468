//! Faults below the layer, at every OpenXR call it intercepts (issue 11): the mock runtime fails one
//! call with a chosen error (`MOCK_XR_FAIL=xrFunc@K=XR_ERROR_…`), and xr-scene, with every feature
//! of the layer on, must see exactly what it sees without the layer: the same exit code and the
//! same error line, the same frames before the fault, a layer log without internal failure or
//! panic, and a process that exits. The outcomes are a table, written to the test's output folder
//! and kept in docs/faults.md (`## OpenXR`); `STEREOSHIM_UPDATE_DOCS=1` rewrites that section.

use crate::common;

use common::{Half, Run, RunOutput};
use std::path::Path;
use std::time::Duration;

/// One fault: the `at`-th call (0-based, counted by the runtime) of `call` fails with `error`.
struct Case {
    call: &'static str,
    at: u64,
    error: &'static str,
    /// xr-scene's Vulkan binding for this case (`enable2` creates the Vulkan instance and device
    /// through the runtime, `enable` asks for extension lists).
    vulkan: &'static str,
    /// The layer's configuration (every feature on, in one of two ways).
    config: &'static str,
    /// Frames the app ends before the fault hits (those are compared with a run without fault).
    frames_before: u64,
    seen: Seen,
    /// More `MOCK_XR_FAIL` items of the same run ("": none).
    also: &'static str,
    /// A line the layer must log in this case ("": none).
    layer_logs: &'static str,
    /// More xr-scene flags.
    app_args: &'static [&'static str],
}

/// Who meets the fault.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Seen {
    /// The app's call fails, with or without the layer.
    ByApp,
    /// The app's call fails in the runtime, but the loader answers XR_SUCCESS (its
    /// `xrDestroyInstance` always does): the app goes on as if nothing happened.
    LoaderHides,
    /// Only the layer makes that call (for itself): without the layer nothing fails, with it the
    /// layer must do without and the app must not notice.
    LayerOnly,
}

const RUNTIME_FAILURE: &str = "XR_ERROR_RUNTIME_FAILURE";
const SESSION_LOST: &str = "XR_ERROR_SESSION_LOST";
const INSTANCE_LOST: &str = "XR_ERROR_INSTANCE_LOST";

/// Frames of every run: the fault of a frame-loop call at frame 2 hits the last one.
const FRAMES: u64 = 3;

/// xr-scene acquires, waits for and releases 4 images a frame (per-eye colour and depth).
const IMAGES_PER_FRAME: u64 = 4;

/// Every call the layer intercepts (`src/xr/mod.rs`, `INTERCEPTED`, plus instance creation),
/// with the call index that fails: the first call for set-up and tear-down calls, a call of frame
/// 2 (or 1) for the frame loop, so frames before the fault can be compared. The frame loop's and
/// the swapchains' calls also fail with the two losses a runtime reports.
fn cases() -> Vec<Case> {
    use Seen::*;
    let case = |call, at, error, vulkan, frames_before, seen| Case { call, at, error, vulkan, config: ALL_FEATURES, frames_before, seen, also: "", layer_logs: "", app_args: &[] };
    let mut v = vec![
        case("xrCreateInstance", 0, RUNTIME_FAILURE, "enable2", 0, ByApp),
        case("xrEnumerateViewConfigurationViews", 0, RUNTIME_FAILURE, "enable2", 0, ByApp),
        case("xrGetVulkanInstanceExtensionsKHR", 0, RUNTIME_FAILURE, "enable", 0, ByApp),
        // With foveation's method `auto` the layer may add an instance extension for shading
        // rate, so it asks the runtime for the list itself during the app's call.
        Case { config: FSR_FEATURES, ..case("xrGetVulkanInstanceExtensionsKHR", 0, RUNTIME_FAILURE, "enable", 0, ByApp) },
        Case { config: FSR_FEATURES, ..case("xrGetVulkanInstanceExtensionsKHR", 1, RUNTIME_FAILURE, "enable", 0, ByApp) },
        case("xrGetVulkanDeviceExtensionsKHR", 0, RUNTIME_FAILURE, "enable", 0, ByApp),
        case("xrCreateVulkanInstanceKHR", 0, RUNTIME_FAILURE, "enable2", 0, ByApp),
        case("xrCreateVulkanDeviceKHR", 0, RUNTIME_FAILURE, "enable2", 0, ByApp),
        case("xrCreateSession", 0, RUNTIME_FAILURE, "enable2", 0, ByApp),
        case("xrAttachSessionActionSets", 0, RUNTIME_FAILURE, "enable2", 0, ByApp),
        case("xrPollEvent", 0, RUNTIME_FAILURE, "enable2", 0, ByApp),
        // The app's own call (`--visibility-mask`: the layer fetches its masks later, at the
        // first frame), and the layer's alone (the mask's runtime mesh).
        Case { app_args: &["--visibility-mask"], ..case("xrGetVisibilityMaskKHR", 0, RUNTIME_FAILURE, "enable2", 0, ByApp) },
        case("xrGetVisibilityMaskKHR", 0, RUNTIME_FAILURE, "enable2", 0, LayerOnly),
        case("xrSyncActions", 2, RUNTIME_FAILURE, "enable2", 2, ByApp),
        case("xrDestroySession", 0, RUNTIME_FAILURE, "enable2", FRAMES, ByApp),
        case("xrDestroyInstance", 0, RUNTIME_FAILURE, "enable2", FRAMES, LoaderHides),
        // A swapchain and its session the runtime would not destroy go with the instance: the
        // layer must drop what it knew of them (their images) there too.
        Case {
            also: "xrDestroySession@0",
            layer_logs: "1 swapchain(s) not destroyed by the app go with the instance",
            ..case("xrDestroySwapchain", 0, RUNTIME_FAILURE, "enable2", FRAMES, ByApp)
        },
        // Calls the layer makes for its own gaze action, after the app's own calls of the same
        // function (xr-scene makes 4 paths, 1 action set, 2 actions, 1 suggestion).
        case("xrStringToPath", 4, RUNTIME_FAILURE, "enable2", 0, LayerOnly),
        case("xrCreateActionSet", 1, RUNTIME_FAILURE, "enable2", 0, LayerOnly),
        case("xrCreateAction", 2, RUNTIME_FAILURE, "enable2", 0, LayerOnly),
        case("xrSuggestInteractionProfileBindings", 1, RUNTIME_FAILURE, "enable2", 0, LayerOnly),
    ];
    for error in [RUNTIME_FAILURE, SESSION_LOST, INSTANCE_LOST] {
        v.extend([
            case("xrCreateSwapchain", 0, error, "enable2", 0, ByApp),
            case("xrEnumerateSwapchainImages", 0, error, "enable2", 0, ByApp),
            case("xrBeginFrame", 2, error, "enable2", 2, ByApp),
            // The app asks twice a frame (count, then views).
            case("xrLocateViews", 4, error, "enable2", 2, ByApp),
            case("xrAcquireSwapchainImage", IMAGES_PER_FRAME, error, "enable2", 1, ByApp),
            case("xrWaitSwapchainImage", IMAGES_PER_FRAME, error, "enable2", 1, ByApp),
            case("xrReleaseSwapchainImage", IMAGES_PER_FRAME, error, "enable2", 1, ByApp),
            case("xrEndFrame", 2, error, "enable2", 2, ByApp),
            case("xrDestroySwapchain", 0, error, "enable2", FRAMES, ByApp),
        ]);
    }
    v
}

/// Every feature on, on a path lavapipe runs (RDM: `auto` picks nothing on a CPU device).
const ALL_FEATURES: &str = "[mask]\nenabled = true\n[foveation]\nenabled = true\nmethod = \"rdm\"\n[far_field]\nenabled = true\n";
/// Every feature on, foveation's method left to the layer (it then wants shading rate).
const FSR_FEATURES: &str = "[mask]\nenabled = true\n[foveation]\nenabled = true\nmethod = \"auto\"\n[far_field]\nenabled = true\n";

/// A run of xr-scene with depth submitted (the far field takes its depth range from it).
fn base(name: &str, vulkan: &str, layer: Option<&str>) -> Run {
    let run = Run::new(name).args(["--submit-depth", "--vulkan", vulkan]).env("MOCK_XR_EXIT_AFTER", &FRAMES.to_string());
    match layer {
        Some(config) => run.with_layer().config(config),
        None => run,
    }
}

/// A run with the fault, and the runtime's log on stderr: it says where the fault was injected.
fn faulty(case: &Case, name: &str, layer: Option<&str>) -> Run {
    let mut spec = format!("{}@{}={}", case.call, case.at, case.error);
    if !case.also.is_empty() {
        spec = format!("{spec},{}", case.also);
    }
    base(name, case.vulkan, layer).args(case.app_args.iter().copied()).env("MOCK_XR_FAIL", &spec).env("MOCK_XR_LOG", "1")
}

/// Runs with a time limit: a run that does not end is a failure (a hang), not a stuck test.
fn run(r: &Run) -> RunOutput {
    r.run_while(Duration::from_secs(90), |_| {})
}

/// What the app saw: its exit, the frames the runtime received, and its own lines (xr-scene
/// names the failing call and the XrResult).
fn outcome(o: &RunOutput) -> String {
    let code = match (o.code, o.signal) {
        (Some(c), _) => format!("exit {c}"),
        (None, s) => format!("signal {s:?}"),
    };
    let lines: Vec<&str> = o.stderr.lines().filter_map(|l| l.strip_prefix("xr-scene: error: ")).collect();
    let frames = captured(o).len();
    if lines.is_empty() {
        format!("{code}, {frames} frames")
    } else {
        format!("{code}, {frames} frames: `{}`", lines.join("` `"))
    }
}

fn captured(o: &RunOutput) -> Vec<u64> {
    o.frames.as_ref().map(|f| f.frames.iter().map(|x| x.frame).collect()).unwrap_or_default()
}

/// The checks of one case; each problem is returned, not panicked on, so one run reports all.
fn check(case: &Case, without: &RunOutput, with: &RunOutput, ref_without: &RunOutput, ref_with: &RunOutput) -> Vec<String> {
    let label = format!("{}@{}={}", case.call, case.at, case.error);
    let mut problems = Vec::new();
    let mut expect = |ok: bool, what: String| {
        if !ok {
            problems.push(format!("{label}: {what}"));
        }
    };
    let short = case.error.trim_start_matches("XR_");
    // The runtime says where it injected the fault: exactly once, in each run that makes the call.
    let injected = format!("[mock-runtime] {}: injected {}", case.call, case.error);
    let times = |o: &RunOutput| o.stderr.lines().filter(|l| l.contains(&injected)).count();
    expect(times(with) == 1, format!("with the layer, the fault was injected {} times, not once", times(with)));
    let without_times = if case.seen == Seen::LayerOnly { 0 } else { 1 };
    expect(times(without) == without_times, format!("without the layer, the fault was injected {} times, not {without_times}", times(without)));
    if case.seen == Seen::ByApp {
        // The fault reached the app as the error it is (not another one), where it was meant to.
        expect(without.stderr.contains(&format!("{} failed: {short}", case.call)), format!("without the layer, the app did not report {short} from {}:\n{}", case.call, without.stderr));
        expect(captured(without) == (0..case.frames_before).collect::<Vec<_>>(), format!("without the layer, frames {:?} were ended, expected 0..{}", captured(without), case.frames_before));
    } else {
        expect(without.code == Some(0), format!("the app failed without the layer:\n{}", without.stderr));
    }
    expect(outcome(with) == outcome(without), format!("the app saw a different result: without the layer {:?}, with it {:?}\nstderr with the layer:\n{}", outcome(without), outcome(with), with.stderr));
    for needle in ["internal failure", "panic"] {
        let found: Vec<&str> = with.log.lines().filter(|l| l.contains(needle)).collect();
        expect(found.is_empty(), format!("the layer logged {needle:?}: {found:?}"));
    }
    if !case.layer_logs.is_empty() {
        expect(with.log.contains(case.layer_logs), format!("the layer did not log {:?}:\n{}", case.layer_logs, with.log));
    }
    // The layer's instance exists unless creating it was the fault.
    if case.call != "xrCreateInstance" {
        expect(common::layer_loaded(&with.log, Half::OpenXr).is_ok(), format!("the layer did not load:\n{}", with.log));
    }
    // Frames before the fault: as in the run without fault (only `enable2` cases get to frames).
    for (o, reference) in [(without, ref_without), (with, ref_with)] {
        for n in captured(o).into_iter().filter(|&n| n < case.frames_before) {
            let same = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| common::assert_same_frame(&format!("{}-f{n}", o.name), o, n, reference, n)));
            expect(same.is_ok(), format!("{}: frame {n} differs from {} (images under target/debug/test-artifacts)", o.name, reference.name));
        }
    }
    problems
}

/// The table of outcomes, as it stands in docs/faults.md.
fn table(rows: &[(String, String, String, String)]) -> String {
    let mut t = String::from("| call | fault | without the layer | with the layer | same |\n|---|---|---|---|---|\n");
    for (call, fault, without, with) in rows {
        let same = if without == with { "yes" } else { "**no**" };
        t.push_str(&format!("| `{call}` | {fault} | {without} | {with} | {same} |\n"));
    }
    t
}

const BEGIN: &str = "<!-- generated by tests/hardening/faults_xr.rs: begin -->\n";
const END: &str = "<!-- generated by tests/hardening/faults_xr.rs: end -->";

/// The generated part of docs/faults.md, and the file with `fresh` in its place.
fn doc_section(doc: &str, fresh: &str) -> Result<(String, String), String> {
    let start = doc.find(BEGIN).ok_or("docs/faults.md lacks the begin marker of tests/hardening/faults_xr.rs")? + BEGIN.len();
    let end = doc[start..].find(END).ok_or("docs/faults.md lacks the end marker of tests/hardening/faults_xr.rs")? + start;
    Ok((doc[start..end].to_string(), format!("{}{fresh}{}", &doc[..start], &doc[end..])))
}

#[test]
fn every_intercepted_call_fails_below_the_layer_as_without_it() {
    let started = std::time::Instant::now();
    // References without fault: the frames before a fault must be these.
    let (ref_without, ref_with) = std::thread::scope(|s| {
        let a = s.spawn(|| run(&base("faults-xr-reference", "enable2", None)));
        let b = s.spawn(|| run(&base("faults-xr-reference-layer", "enable2", Some(ALL_FEATURES))));
        (a.join().unwrap(), b.join().unwrap())
    });
    ref_without.assert_ok();
    ref_with.assert_ok().assert_log_lacks(Half::Both, "internal failure");
    assert_eq!(captured(&ref_without), (0..FRAMES).collect::<Vec<_>>(), "{}", ref_without.stderr);
    assert_eq!(captured(&ref_with), captured(&ref_without), "{}", ref_with.stderr);
    let mut rows = Vec::new();
    let mut problems = Vec::new();
    for case in cases() {
        let fsr = if case.config == FSR_FEATURES { "-fsr" } else { "" };
        let also = if case.also.is_empty() && case.app_args.is_empty() { "" } else { "-and-more" };
        let name = format!("faults-xr-{}-{}-{}{fsr}{also}", case.call, case.at, case.error.trim_start_matches("XR_ERROR_").to_lowercase());
        // Without and with the layer side by side: the machine has two cores.
        let (without, with) = std::thread::scope(|s| {
            let a = s.spawn(|| run(&faulty(&case, &name, None)));
            let b = s.spawn(|| run(&faulty(&case, &format!("{name}-layer"), Some(case.config))));
            (a.join().unwrap(), b.join().unwrap())
        });
        problems.extend(check(&case, &without, &with, &ref_without, &ref_with));
        let mut fault = format!("{}, call {}", case.error, case.at);
        if case.seen == Seen::LayerOnly {
            fault.push_str(" (the layer's own)");
        }
        for arg in case.app_args {
            fault.push_str(&format!(", xr-scene `{arg}`"));
        }
        if case.vulkan == "enable" {
            fault.push_str(", XR_KHR_vulkan_enable");
        }
        if case.config == FSR_FEATURES {
            fault.push_str(", foveation method auto");
        }
        if !case.also.is_empty() {
            fault.push_str(&format!(", and {}", case.also));
        }
        rows.push((case.call.to_string(), fault, outcome(&without), outcome(&with)));
    }
    let fresh = table(&rows);
    let out = common::output_dir("faults-xr");
    std::fs::write(out.join("faults-openxr.md"), &fresh).unwrap();
    eprintln!("{} cases in {:.0?}; table in {}", rows.len(), started.elapsed(), out.join("faults-openxr.md").display());

    let doc_path = Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/faults.md");
    let _docs = common::REPO_DOCS.lock().unwrap_or_else(|e| e.into_inner());
    let doc = std::fs::read_to_string(&doc_path).unwrap_or_default();
    match doc_section(&doc, &fresh) {
        Ok((committed, _)) if committed == fresh => {}
        Ok((_, updated)) if std::env::var_os("STEREOSHIM_UPDATE_DOCS").is_some() => {
            std::fs::write(&doc_path, updated).unwrap();
            eprintln!("rewrote the OpenXR table of {}", doc_path.display());
        }
        Ok(_) => problems.push(format!(
            "the table in docs/faults.md is not the one this run produced; run with STEREOSHIM_UPDATE_DOCS=1 to rewrite it, or paste:\n{fresh}"
        )),
        Err(e) => problems.push(e),
    }
    assert!(problems.is_empty(), "{} problem(s):\n{}", problems.len(), problems.join("\n\n"));
}

#[test]
fn the_doc_section_is_found_and_replaced() {
    let doc = format!("# x\n## OpenXR\n{BEGIN}old\n{END}\n## Vulkan\nv\n");
    let (committed, updated) = doc_section(&doc, "new\n").unwrap();
    assert_eq!(committed, "old\n");
    assert_eq!(updated, format!("# x\n## OpenXR\n{BEGIN}new\n{END}\n## Vulkan\nv\n"));
    assert!(doc_section("## OpenXR\nno markers\n", "new").is_err());
}
