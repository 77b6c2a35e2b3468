//! Sessions ended and created again in one process (issue 11, "lifecycles with flat memory"):
//! with every feature on, the layer keeps working in each new session and the process's memory
//! stays flat. xr-scene `--sessions N` prints each session's frames and resident memory; the
//! validation layer (on in every run) reports any Vulkan object still alive at device
//! destruction, the layer's own included.

use crate::common;

use common::{assert_nothing_tracked, every_feature, Half, Run, RunOutput};

const SESSIONS: usize = 100;
const FRAMES: u64 = 3;

/// (frames, rss kB) of each session, from xr-scene's stderr.
fn sessions(out: &RunOutput) -> Vec<(u64, u64)> {
    out.stderr
        .lines()
        .filter_map(|l| l.strip_prefix("xr-scene: session "))
        .map(|l| {
            let words: Vec<&str> = l.split_whitespace().collect();
            // "<k> ended after <n> frames, rss <kb> kB"
            (words[3].parse().unwrap(), words[6].parse().unwrap())
        })
        .collect()
}

/// RSS growth (kB) from the end of the first third of the sessions to the end of the last: the
/// first sessions warm caches (shader compilers, allocator pools) in any app.
fn growth(s: &[(u64, u64)]) -> i64 {
    let settled = s[s.len() / 3].1 as i64;
    s.iter().skip(s.len() / 3).map(|x| x.1 as i64).max().unwrap() - settled
}

#[test]
fn sessions_recreated_with_every_feature_on_keep_memory_flat() {
    let base = Run::new("lifecycle-sessions")
        .args(["--sessions", &SESSIONS.to_string(), "--frames", &FRAMES.to_string(), "--submit-depth"])
        .env("MOCK_XR_EXIT_AFTER", "1000")
        .env("MOCK_XR_CAPTURE_FRAMES", "0");
    let plain = base.clone().run();
    plain.assert_ok();
    // Upscaling too: every session's swapchains are interposed (the layer's images and objects
    // made and destroyed each time).
    let layered = every_feature(base, "lifecycle-sessions-layer").env("STEREOSHIM_UPSCALE_ENABLED", "1");
    let with = layered.run();
    with.assert_ok().assert_layer_loaded(Half::Both).assert_log_lacks(Half::Both, "internal failure");
    assert_nothing_tracked(&with);
    let (a, b) = (sessions(&plain), sessions(&with));
    assert_eq!(a.len(), SESSIONS, "{}", plain.stderr);
    assert_eq!(b.len(), SESSIONS, "{}", with.stderr);
    assert!(b.iter().all(|s| s.0 == FRAMES), "every session ran its frames: {b:?}");
    // The features kept applying in later sessions: per session, both eyes' passes were masked
    // and foveated (the device's totals count every session).
    let line = with.log_lines("vulkan device stats").last().copied().unwrap_or_default().to_string();
    let count = |key: &str| -> u64 {
        line.split_whitespace().find_map(|w| w.strip_prefix(key)).and_then(|v| v.parse().ok()).unwrap_or(0)
    };
    assert!(count("rdm_passes=") >= SESSIONS as u64 * (FRAMES - 1), "RDM stopped in later sessions: {line}");
    let interposed = with.log_lines("the runtime shows").len();
    assert!(interposed >= SESSIONS, "the upscale stopped interposing in later sessions: {interposed} swapchains over {SESSIONS} sessions");
    let (ga, gb) = (growth(&a), growth(&b));
    eprintln!("rss growth over the last two thirds: {ga} kB without the layer, {gb} kB with; sessions with: {b:?}");
    // The app alone grows by ~20-30 kB a session here (mock runtime, loader, lavapipe), and the
    // allocator hands memory back now and then, so two runs differ by a megabyte or so (measured:
    // 1724 vs 1892 kB on a quiet machine, 3280 vs 1972 kB in a clean CI clone). 4 MB over the
    // last 66 sessions is a leak of ~60 kB per session: what a per-session image or buffer of the
    // layer would cost.
    assert!(gb - ga.max(0) <= 4096, "the layer's memory grows with sessions: {gb} kB vs {ga} kB without it\n{b:?}");
}

/// New swapchains of other sizes every 3 frames within a session (as an app changing its render
/// scale): under validation nothing the layer sized for the old swapchains is used with the new
/// ones, and every feature applies again once the new swapchains' eyes are known.
#[test]
fn swapchains_recreated_with_other_sizes_keep_every_feature_working() {
    let stats = common::target_dir().join("test-output").join("lifecycle-swapchains.layer-stats.jsonl");
    let _ = std::fs::remove_file(&stats);
    let base = Run::new("lifecycle-swapchains")
        .args(["--recreate-swapchains", "3", "--frames", "12", "--submit-depth"])
        .env("MOCK_XR_EXIT_AFTER", "1000")
        .env("MOCK_XR_CAPTURE_FRAMES", "0");
    let out = every_feature(base, "lifecycle-swapchains").env("STEREOSHIM_STATS_FILE", stats.to_str().unwrap()).run();
    out.assert_ok().assert_layer_loaded(Half::Both).assert_log_lacks(Half::Both, "internal failure");
    assert_nothing_tracked(&out);
    let lines: Vec<serde_json::Value> = std::fs::read_to_string(&stats).unwrap().lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    assert_eq!(lines.len(), 12, "one stats line per frame");
    // The last frame of each swapchain set (frames 2, 5, 8, 11): its eyes are known since the
    // set's first frame, so mask, RDM and far field all applied.
    // The sizes did change (x1, x0.8, x1.2, x1): the masked pixel counts follow them.
    let masked = |f: usize| lines[f]["pixels_masked"]["0"].as_u64().unwrap_or(0);
    assert!(masked(5) < masked(2) && masked(8) > masked(2) && masked(11) == masked(2), "{} {} {} {}", masked(2), masked(5), masked(8), masked(11));
    for f in [2usize, 5, 8, 11] {
        let l = &lines[f];
        let sum = |v: &serde_json::Value| v.as_object().map_or(0, |m| m.values().filter_map(|x| x.as_u64()).sum::<u64>());
        assert!(l["passes_masked"].as_u64().unwrap_or(0) >= 2, "frame {f}: mask not applied: {l}");
        assert!(sum(&l["rdm"]["reconstructed"]) >= 2, "frame {f}: RDM not applied: {l}");
        assert!(sum(&l["far_field"]["views_reused"]) >= 1, "frame {f}: far field not applied: {l}");
    }
}

/// The whole app several times in one process: XR instance, Vulkan instance and device, and two
/// sessions each, with every feature on. Each instance gets the layer's Vulkan half again (its
/// device state made and destroyed with the device), validation finds nothing alive at each
/// device's destruction, and the layer tracks nothing of the app's objects afterwards.
#[test]
fn instances_recreated_with_every_feature_on() {
    const INSTANCES: usize = 12;
    let base = Run::new("lifecycle-instances")
        .args(["--instances", &INSTANCES.to_string(), "--sessions", "2", "--frames", &FRAMES.to_string(), "--submit-depth"])
        .env("MOCK_XR_EXIT_AFTER", "1000")
        .env("MOCK_XR_CAPTURE_FRAMES", "0");
    let plain = base.clone().run();
    plain.assert_ok();
    let layered = every_feature(base, "lifecycle-instances-layer");
    let with = layered.run();
    with.assert_ok().assert_log_lacks(Half::Both, "internal failure");
    assert_nothing_tracked(&with);
    let rss = |out: &RunOutput| -> Vec<(u64, u64)> {
        out.stderr
            .lines()
            .filter_map(|l| l.strip_prefix("xr-scene: instance "))
            .map(|l| (0, l.split_whitespace().nth(3).and_then(|v| v.parse().ok()).unwrap()))
            .collect()
    };
    let (a, b) = (rss(&plain), rss(&with));
    assert_eq!((a.len(), b.len()), (INSTANCES, INSTANCES), "{}", with.stderr);
    // One device stats line per device: the Vulkan half was in every instance's device, and each
    // applied RDM.
    let lines = with.log_lines("vulkan device stats");
    assert_eq!(lines.len(), INSTANCES, "{}", with.log);
    assert!(lines.iter().all(|l| l.split_whitespace().any(|w| w.strip_prefix("rdm_passes=").and_then(|v| v.parse::<u64>().ok()).is_some_and(|n| n > 0))), "{lines:?}");
    // Memory is reported, not bounded: over a dozen instances the loader's and lavapipe's own
    // growth varies by several megabytes between runs (7752 kB without the layer in one run, half
    // that in another), more than a leak of the layer's per-device state would add. What the
    // layer keeps per device is checked exactly above (`live.*`) and by validation.
    let (ga, gb) = (growth(&a), growth(&b));
    eprintln!("rss growth over the last two thirds: {ga} kB without the layer, {gb} kB with; with: {b:?}");
}

/// Every order OpenXR allows for tearing down (xr-scene `--teardown`): children first; the
/// session destroyed with its swapchains still alive (the runtime destroys them, and their
/// `VkImage`s, with it); the last session and its swapchains left to `xrDestroyInstance`, and the
/// Vulkan device destroyed after the XR instance. With every feature on, each run must end
/// cleanly under validation (which reports any Vulkan object still alive at device destruction,
/// the layer's and the runtime's included), with the layer tracking nothing of the app's objects
/// afterwards, though the swapchains it followed were never destroyed by their own call.
#[test]
fn every_destruction_order_is_handled() {
    for teardown in ["children", "session", "instance"] {
        let name = format!("lifecycle-teardown-{teardown}");
        let base = Run::new(&name)
            .args(["--teardown", teardown, "--sessions", "2", "--frames", &FRAMES.to_string(), "--submit-depth"])
            .env("MOCK_XR_EXIT_AFTER", "1000")
            .env("MOCK_XR_CAPTURE_FRAMES", "0")
            // glibc fills freed memory: a handle read after the call that destroyed it (issue
            // 23: the dispatch key of a freed VkDevice) yields junk, and the table removal
            // keyed by it misses, which `assert_nothing_tracked` sees.
            .env("MALLOC_PERTURB_", "165");
        let out = every_feature(base, &name).run();
        out.assert_ok().assert_layer_loaded(Half::Both).assert_log_lacks(Half::Both, "internal failure");
        assert_nothing_tracked(&out);
        // The layer saw the swapchains go with their parent, and the order asked for.
        let with_session = out.log_lines("swapchain(s) not destroyed by the app go with the session").len();
        let with_instance = out.log_lines("swapchain(s) not destroyed by the app go with the instance").len();
        assert_eq!((with_session, with_instance), match teardown { "children" => (0, 0), "session" => (2, 0), _ => (0, 1) }, "{teardown}:\n{}", out.log);
        let at = |needle: &str| out.log.find(needle).unwrap_or_else(|| panic!("{teardown}: no {needle:?}"));
        assert_eq!(at("openxr stats") < at("vulkan device stats"), teardown == "instance", "{teardown}: the Vulkan device goes after the XR instance only with --teardown instance");
        // The features were on in both sessions: RDM reconstructed in each.
        let lines = out.log_lines("vulkan device stats");
        assert!(lines.iter().all(|l| l.split_whitespace().any(|w| w.strip_prefix("rdm_passes=").and_then(|v| v.parse::<u64>().ok()).is_some_and(|n| n > 0))), "{teardown}: {lines:?}");
    }
}
