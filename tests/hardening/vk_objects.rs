//! The Vulkan objects stereoshim creates for itself stay flat across sessions (issue 11: "100
//! cycles with every feature on keep … the count of live layer objects and Vulkan objects flat").
//! tests/hardening/lifecycle.rs checks the process's memory and the app objects the layer tracks (`live.*`);
//! this checks the layer's own far-field slots, RDM reconstruction slots, pipelines, buffers,
//! query pools, fences, pools… The fault layer of the test tree sits below stereoshim with
//! `VK_FAULT_COUNT=1` (and no fault): it tells the layer's creations from the app's (its marker
//! instance sits above stereoshim) and prints the live handles of each kind, by origin, at each of
//! the app's `vkDeviceWaitIdle` calls — xr-scene makes one after each session, once the session is
//! destroyed — and at `vkDestroyDevice`. The layer's own count of them (`own.*` in its device
//! stats line, src/vk/own.rs) must equal what the layer below saw.

use crate::common;

use common::{every_feature, fault_layer_data_dir, Half, Run, RunOutput, FAULT_LAYER};
use std::collections::BTreeMap;
use std::time::Duration;

const SESSIONS: usize = 100;
const FRAMES: u64 = 3;
/// The session from whose end on the layer's counts must not change any more (0-based). The first
/// session's end already: what the layer keeps between sessions is made in the first session
/// and then reused (measured on lavapipe: the same 51 objects after every session).
const SETTLED: usize = 0;

/// The counts of one `vk-fault-layer: live objects at <call>: layer k=n … app k=n …` line:
/// (layer, app).
type Counts = (BTreeMap<String, u64>, BTreeMap<String, u64>);

/// Parses the part of such a line after `<call>:`.
fn parse(line: &str) -> Counts {
    let (mut layer, mut app) = (BTreeMap::new(), BTreeMap::new());
    let mut into = &mut layer;
    for w in line.split_whitespace() {
        match w {
            "layer" => into = &mut layer,
            "app" => into = &mut app,
            _ => {
                let (k, v) = w.split_once('=').unwrap_or_else(|| panic!("{line}"));
                into.insert(k.to_string(), v.parse().unwrap_or_else(|_| panic!("{line}")));
            }
        }
    }
    assert!(!layer.is_empty() && !app.is_empty(), "{line}");
    (layer, app)
}

/// The counts after each session (the last `vkDeviceWaitIdle` line before xr-scene's "session k
/// ended"), those of every `vkDeviceWaitIdle` line, and those at `vkDestroyDevice`.
fn counts(out: &RunOutput) -> (Vec<Counts>, Vec<Counts>, Vec<Counts>) {
    let (mut after, mut all, mut destroy) = (Vec::new(), Vec::new(), Vec::new());
    let mut last = None;
    for l in out.stderr.lines() {
        if let Some(rest) = l.strip_prefix("vk-fault-layer: live objects at vkDeviceWaitIdle:") {
            let c = parse(rest);
            all.push(c.clone());
            last = Some(c);
        } else if let Some(rest) = l.strip_prefix("vk-fault-layer: live objects at vkDestroyDevice:") {
            destroy.push(parse(rest));
        } else if l.starts_with("xr-scene: session ") {
            after.push(last.take().unwrap_or_else(|| panic!("no vkDeviceWaitIdle line before {l:?}")));
        }
    }
    (after, all, destroy)
}

fn total(m: &BTreeMap<String, u64>) -> u64 {
    m.values().sum()
}

#[test]
fn sessions_recreated_with_every_feature_on_keep_the_layers_vulkan_objects_flat() {
    let data = fault_layer_data_dir();
    let base = Run::new("vk-objects")
        .args(["--sessions", &SESSIONS.to_string(), "--frames", &FRAMES.to_string(), "--submit-depth", "--vk-layer", FAULT_LAYER])
        .env("MOCK_XR_EXIT_AFTER", "1000")
        .env("MOCK_XR_CAPTURE_FRAMES", "0")
        .env("VK_FAULT_COUNT", "1")
        .env("XDG_DATA_DIRS", &format!("{}:/usr/local/share:/usr/share", data.display()));
    let out = every_feature(base, "vk-objects").run_while(Duration::from_secs(300), |_| {});
    let bad: Vec<&str> = out.stderr.lines().filter(|l| l.starts_with("vk-fault-layer: ") && !l.contains("live objects at")).collect();
    assert!(bad.is_empty(), "the fault layer failed: {bad:?}");
    let (after, all, destroy) = counts(&out);
    assert_eq!(after.len(), SESSIONS, "{}", out.stderr);
    for (k, (layer, app)) in after.iter().enumerate() {
        eprintln!("after session {k}: layer {} {layer:?}; app {}", total(layer), total(app));
    }
    // The counting sees the layer's objects at all: inside a session (xr-scene's own waits before
    // it destroys its renderer and targets) the layer has its pipelines, slots and pools.
    let busiest = all.iter().map(|c| total(&c.0)).max().unwrap_or(0);
    assert!(busiest > total(&after[SETTLED].0), "no layer object seen inside a session: {all:?}");
    // Between sessions the layer keeps only what belongs to the device, made on first use and kept
    // for the device's lifetime (measured: 4 images, 9 allocations, 4 views, 5 buffers, 6 shader
    // modules, 5 pipeline and 3 set layouts, 2 pipelines, 2 samplers, 3 descriptor pools, 2 query
    // pools, 3 command pools, 3 fences: the far field's and RDM's slots, pipelines and pools; the
    // pool of host buffers is emptied when a session ends, since how many it held depended on how
    // many the session had in flight at once, which timing decides), so
    // from the first session's end on every kind stays exactly where it is: nothing is cached per
    // session that a later one would add to, so no bound is needed. Any growth is an object made
    // per session and never destroyed (a pipeline for the app's render pass kept after the app
    // destroyed that render pass shows as +3 pipelines a session).
    let settled = &after[SETTLED].0;
    for (k, (layer, _)) in after.iter().enumerate().skip(SETTLED + 1) {
        assert_eq!(layer, settled, "the layer's live Vulkan objects changed after session {k} (vs session {SETTLED})");
    }
    // The app's (xr-scene and the mock runtime) are flat too, or the origins would be mixed up.
    for (k, (_, app)) in after.iter().enumerate().skip(SETTLED + 1) {
        assert_eq!(app, &after[SETTLED].1, "the app's live Vulkan objects changed after session {k}");
    }
    // At vkDestroyDevice, before the fault layer calls down (stereoshim has destroyed what it
    // destroys by then: nothing can be destroyed after the device), nothing of the layer's lives.
    assert_eq!(destroy.len(), 1, "{}", out.stderr);
    let (layer, app) = &destroy[0];
    assert!(layer.values().all(|n| *n == 0), "the layer's objects outlive its device: {layer:?}");
    eprintln!("at vkDestroyDevice: layer {layer:?}; app {app:?}; run took {:?}", out.elapsed);
    // The layer's own count (`own.*` in its device stats line, kept by counting trampolines in
    // its dispatch table: src/vk/own.rs) is what the layer below saw it make: the line is written
    // at vkDestroyDevice before the layer destroys its objects, when it holds what it held after
    // the last session.
    let line = out.log_lines("vulkan device stats");
    assert_eq!(line.len(), 1, "{}", out.log);
    let own: BTreeMap<String, u64> = line[0]
        .split_whitespace()
        .filter_map(|w| w.strip_prefix("own."))
        .map(|w| {
            let (k, v) = w.split_once('=').unwrap();
            let k = match k {
                "memory" => "memory",
                "render_passes" => "render_pass",
                k => k.strip_suffix('s').unwrap_or(k),
            };
            (k.to_string(), v.parse().unwrap())
        })
        .collect();
    assert_eq!(own.len(), 15, "{}", line[0]);
    let below = &after[SESSIONS - 1].0;
    for (k, n) in &own {
        assert_eq!(below.get(k).copied().unwrap_or(0), *n, "own.{k}: the layer counts {n}, the layer below saw {below:?}");
    }
    out.assert_log_lacks(Half::Vulkan, "the layer's own objects still alive");
    // Checked after the counts, so a leak fails with the counts rather than with validation's
    // objects alive at vkDestroyDevice (which it reports too).
    out.assert_ok().assert_layer_loaded(Half::Both).assert_log_lacks(Half::Both, "internal failure");
}
