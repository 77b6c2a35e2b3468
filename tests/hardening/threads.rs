//! A multi-threaded app through the layer (issue 11, "Hardening: threads"). xr-scene `--threads`
//! calls `xrWaitFrame` on a frame-pacing thread (frame N+1's wait overlapping frame N's recording,
//! submission and `xrEndFrame`), records each eye pass into a secondary command buffer on a worker
//! thread of its own (its own command pool; the per-eye layout's two workers record at the same
//! time) and submits on a submit thread, while the render thread handles session state, records
//! the primary, and acquires, releases and ends frames. With every feature on, under the Khronos
//! validation layer (its thread-safety checks are on by default: `thread_safety_checks_are_on`
//! proves it), 1000 frames per layout must run without a validation error or a deadlock, apply
//! the mask and RDM to every eye pass of every frame (the far field, also on, leaves passes
//! recorded in secondaries alone and must say so), and give exactly the frames, shaded-fragment
//! counts and layer statistics of the same app recording on one thread. See docs/testing.md.

use crate::common;

use common::{assert_nothing_tracked, every_feature, Half, Run, RunOutput};
use std::time::Duration;

const FRAMES: u64 = 1000;
/// Frames captured and compared: the first ones (frame 0's passes are recorded before the layer
/// knows the eyes; from frame 2 on every feature applies), some in the middle, the last.
const CAPTURED: &str = "0-3,500,998,999";
/// A 1000-frame run takes 5–10 s here (measured: docs/testing.md); longer means a deadlock, or something
/// close enough to one.
const LIMIT: Duration = Duration::from_secs(150);

/// (frames recorded on workers, frames whose passes were recorded concurrently), from xr-scene's
/// line at each session's end, summed over sessions.
fn worker_frames(out: &RunOutput) -> (u64, u64) {
    let lines: Vec<&str> = out.stderr.lines().filter_map(|l| l.strip_prefix("xr-scene: threads: ")).collect();
    assert!(!lines.is_empty(), "{}: no worker line; stderr:\n{}", out.name, out.stderr);
    lines.iter().fold((0, 0), |(r, o), l| {
        // "<n> frames recorded on workers, <m> with passes recorded concurrently"
        let w: Vec<&str> = l.split_whitespace().collect();
        (r + w[0].parse::<u64>().unwrap(), o + w[5].parse::<u64>().unwrap())
    })
}

/// The layer's `stats.file` of a run: one JSON line per `xrEndFrame`.
fn layer_stats(path: &std::path::Path) -> Vec<serde_json::Value> {
    std::fs::read_to_string(path).unwrap_or_default().lines().map(|l| serde_json::from_str(l).unwrap()).collect()
}

/// Runs xr-scene with `args` single-threaded (`--secondary`, which `--threads` implies) and with
/// `--threads`, both with every feature on, and judges both. `passes`: eye passes per frame.
/// `sessions` × `frames` per session (one session: it runs until the runtime stops it after
/// `frames`; several: each asks to end after `frames`).
fn threaded_matches_single_threaded(name: &str, args: &[&str], passes: u64, sessions: u64, frames: u64) {
    let record_once = args.contains(&"--record-once");
    let total = sessions * frames;
    let started = std::time::Instant::now();
    let run = |threads: bool| {
        let label = format!("threads-{name}{}", if threads { "" } else { "-single" });
        let stats = common::target_dir().join("test-output").join(format!("{label}.layer-stats.jsonl"));
        let _ = std::fs::remove_file(&stats);
        let base = Run::new(&label)
            .args(["--scale", "0.1", "--animate", "--secondary"])
            .args(args.iter().copied())
            .args(threads.then_some("--threads"))
            .args(if sessions > 1 { vec!["--sessions".to_string(), sessions.to_string(), "--frames".to_string(), frames.to_string()] } else { vec![] })
            .env("MOCK_XR_EXIT_AFTER", &if sessions > 1 { FRAMES } else { frames }.to_string())
            .env("MOCK_XR_CAPTURE_FRAMES", CAPTURED);
        // The layer's GPU frame timer too: it brackets every submission, on the submit thread.
        let out = every_feature(base, &label)
            .env("STEREOSHIM_STATS_FILE", stats.to_str().unwrap())
            .env("STEREOSHIM_STATS_GPU_TIME", "1")
            .run_while(LIMIT, |_| {});
        // Exit 0 under --validation: no validation error (xr-scene exits 3 on any).
        out.assert_ok().assert_layer_loaded(Half::Both).assert_log_lacks(Half::Both, "internal failure");
        assert!(!out.stderr.contains("Validation Error"), "{label}: {}", out.stderr);
        assert_nothing_tracked(&out);
        // Every frame submitted, and from frame 2 on the mask and RDM applied to every eye pass.
        let lines = layer_stats(&stats);
        assert_eq!(lines.len() as u64, total, "{label}: one layer stats line per frame");
        let sum = |v: &serde_json::Value| v.as_object().map_or(0, |m| m.values().filter_map(|x| x.as_u64()).sum::<u64>());
        for (f, l) in lines.iter().enumerate().filter(|(f, _)| *f as u64 % frames >= 2) {
            assert_eq!(l["passes_masked"].as_u64(), Some(passes), "{label}: frame {f}: mask not applied to every eye pass: {l}");
            assert_eq!(sum(&l["rdm"]["reconstructed"]), 2, "{label}: frame {f}: RDM not applied to both views: {l}");
            assert!(l["gpu_ms"]["busy"].as_f64().is_some_and(|ms| ms > 0.0), "{label}: frame {f}: no GPU time: {l}");
            assert_eq!(l["gpu_ms"]["untimed"].as_u64(), Some(0), "{label}: frame {f}: a submission went untimed: {l}");
            // The far field leaves passes whose contents are secondaries alone (docs/far-field.md:
            // its reuse draw must come after the pass's first depth-tested draw, inside the app's
            // secondary), and --threads implies them: it must say so for every pass it sees
            // recorded (`--record-once` resubmits frames recorded earlier: no reason, no reuse).
            let not_applied = &l["far_field"]["not_applied"];
            if record_once {
                assert!(not_applied.as_object().is_some_and(|m| m.keys().all(|k| k == "secondary")), "{label}: frame {f}: {l}");
                assert_eq!(sum(&l["far_field"]["views_reused"]), 0, "{label}: frame {f}: {l}");
            } else {
                assert_eq!(*not_applied, serde_json::json!({ "secondary": passes }), "{label}: frame {f}: {l}");
            }
        }
        eprintln!("{label}: {total} frames in {:.1} s", out.elapsed.as_secs_f64());
        (out, lines)
    };
    let (single, single_stats) = run(false);
    let (threaded, threaded_stats) = run(true);
    // The passes were recorded on the workers in every frame (`--record-once`: in the first frame
    // of each of the runtime's 3 image combinations per session); with two passes (per-eye) over
    // 1000 frames, the two workers recorded at the same time at least in some frames (the
    // machine is shared).
    let (recorded, concurrent) = worker_frames(&threaded);
    eprintln!("threads-{name}: {recorded} frames recorded on workers, {concurrent} of them with two passes recorded at once");
    assert_eq!(recorded, if record_once { 3 * sessions } else { total }, "threads-{name}: every recording on the workers");
    if passes == 2 && !record_once {
        assert!(concurrent > 0, "threads-{name}: the two workers never recorded at the same time");
    }
    // Threads change nothing the app or the runtime sees: the same frames, the same shaded
    // fragments, and the same work done by the layer in every frame.
    common::assert_same_captures(&format!("threads-{name}"), &single, &threaded);
    common::assert_same_stats(&format!("threads-{name}"), &single, &threaded);
    for (f, (a, b)) in single_stats.iter().zip(&threaded_stats).enumerate() {
        for key in ["passes_masked", "pixels_masked", "rdm", "far_field"] {
            assert_eq!(a[key], b[key], "threads-{name}: frame {f}: the layer's {key} differs with threads");
        }
    }
    eprintln!("threads-{name}: both runs in {:.1} s", started.elapsed().as_secs_f64());
}

#[test]
fn per_eye_threads_match_one_thread() {
    threaded_matches_single_threaded("per-eye", &["--layout", "per-eye"], 2, 1, FRAMES);
}

#[test]
fn multiview_threads_match_one_thread() {
    threaded_matches_single_threaded("multiview", &["--layout", "multiview", "--rendering", "dynamic"], 1, 1, FRAMES);
}

#[test]
fn side_by_side_threads_match_one_thread() {
    threaded_matches_single_threaded("side-by-side", &["--layout", "side-by-side", "--rendering", "render-pass2"], 1, 1, FRAMES);
}

/// Dynamic rendering (the secondaries inherit formats, not a render pass) and a multisampled
/// intermediate target resolved into the swapchain image: the layer follows the pass into the
/// copy. (A depth clear by `vkCmdClearAttachments` inside the app's secondaries is left alone by
/// the layer, threads or not: docs/compatibility.md.)
#[test]
fn per_eye_dynamic_msaa_threads_match_one_thread() {
    let args = ["--layout", "per-eye", "--rendering", "dynamic", "--intermediate", "--samples", "4"];
    threaded_matches_single_threaded("per-eye-dynamic-msaa", &args, 2, 1, 300);
}

/// Command buffers recorded once (on the workers) and resubmitted, and sessions ended and begun
/// again: each session's frame-pacing thread stops before `xrEndSession` and is joined before the
/// session is destroyed, and the next session starts its own.
#[test]
fn per_eye_record_once_sessions_threads_match_one_thread() {
    threaded_matches_single_threaded("per-eye-record-once", &["--layout", "per-eye", "--record-once"], 2, 3, 100);
}

/// The validation layer of this machine (Debian's 1.3.239) checks thread safety unless told not
/// to, as xr-scene's runs leave it: with `--thread-hazard` the two workers' secondaries come from
/// one command pool, which they then use at once, and validation must report it (else a clean
/// run above would prove nothing about threads).
#[test]
fn thread_safety_checks_are_on() {
    let out = Run::new("threads-hazard")
        .args(["--scale", "0.1", "--layout", "per-eye", "--threads", "--thread-hazard"])
        .env("MOCK_XR_EXIT_AFTER", "100")
        .env("MOCK_XR_CAPTURE_FRAMES", "0")
        .run_while(LIMIT, |_| {});
    assert_eq!(out.code, Some(3), "validation must fail the run; stderr:\n{}", out.stderr);
    assert!(out.stderr.contains("UNASSIGNED-Threading-MultipleThreads"), "{}", out.stderr);
}
