//! Faults below the layer, the Vulkan half (issue 11): the fault-injecting layer of the test tree
//! (tests/vk-fault-layer) sits below stereoshim and fails chosen Vulkan calls; xr-scene runs with
//! it, without and with stereoshim (every feature on, depth submitted), and:
//! - a failed call the **app** makes (or the runtime, on the app's device: both are above
//!   stereoshim) gives the app the same result with and without stereoshim;
//! - a failed call **stereoshim** makes for its own objects never reaches the app: it runs to
//!   completion, validation clean, and every captured image is one a run without a fault produces
//!   with all features on or with one of them off (the feature turned off for the object whose
//!   creation failed — see `layer_fault` for why that is the right outcome).
//!
//! The outcome table is the `## Vulkan` section of docs/faults.md (`STEREOSHIM_UPDATE_DOCS=1`
//! rewrites it).

use crate::common;

use common::{fault_layer_data_dir, Run, RunOutput, FAULT_LAYER};
use std::path::PathBuf;
use std::time::Duration;

/// Every feature on, with the objects each creates: the mask (pipeline), RDM (checkerboard
/// pipeline; reconstruction's compute pipeline, buffers, images, descriptor pools and sets,
/// command pool and buffers, fences, queue submissions), the far field (copies, images, views,
/// descriptor sets, query pools). `auto` foveation is nothing on lavapipe, so `rdm` is named.
const FEATURES: &str = "[mask]\nenabled = true\n[foveation]\nenabled = true\nmethod = \"rdm\"\n[far_field]\nenabled = true\n";

/// The commands failed, each with its representative fault: out of device memory for creations
/// and allocations, device lost for a submission.
const CALLS: &[(&str, &str)] = &[
    ("vkCreateImage", "VK_ERROR_OUT_OF_DEVICE_MEMORY"),
    ("vkAllocateMemory", "VK_ERROR_OUT_OF_DEVICE_MEMORY"),
    ("vkCreateImageView", "VK_ERROR_OUT_OF_DEVICE_MEMORY"),
    ("vkCreateBuffer", "VK_ERROR_OUT_OF_DEVICE_MEMORY"),
    ("vkCreateShaderModule", "VK_ERROR_OUT_OF_DEVICE_MEMORY"),
    ("vkCreatePipelineLayout", "VK_ERROR_OUT_OF_DEVICE_MEMORY"),
    ("vkCreateDescriptorSetLayout", "VK_ERROR_OUT_OF_DEVICE_MEMORY"),
    ("vkCreateGraphicsPipelines", "VK_ERROR_OUT_OF_DEVICE_MEMORY"),
    ("vkCreateComputePipelines", "VK_ERROR_OUT_OF_DEVICE_MEMORY"),
    ("vkCreateRenderPass", "VK_ERROR_OUT_OF_DEVICE_MEMORY"),
    ("vkCreateRenderPass2", "VK_ERROR_OUT_OF_DEVICE_MEMORY"),
    ("vkCreateFramebuffer", "VK_ERROR_OUT_OF_DEVICE_MEMORY"),
    ("vkCreateSampler", "VK_ERROR_OUT_OF_DEVICE_MEMORY"),
    ("vkCreateDescriptorPool", "VK_ERROR_OUT_OF_DEVICE_MEMORY"),
    ("vkAllocateDescriptorSets", "VK_ERROR_OUT_OF_DEVICE_MEMORY"),
    ("vkCreateQueryPool", "VK_ERROR_OUT_OF_DEVICE_MEMORY"),
    ("vkCreateCommandPool", "VK_ERROR_OUT_OF_DEVICE_MEMORY"),
    ("vkAllocateCommandBuffers", "VK_ERROR_OUT_OF_DEVICE_MEMORY"),
    ("vkCreateFence", "VK_ERROR_OUT_OF_DEVICE_MEMORY"),
    ("vkQueueSubmit", "VK_ERROR_DEVICE_LOST"),
    ("vkQueueSubmit", "VK_ERROR_OUT_OF_HOST_MEMORY"),
];

/// More calls the app makes: a later index where the first call of a command is the runtime's
/// (its swapchain images' memory, its command pool), and a command the app makes only on
/// another rendering path. (call, fault, app call index, extra xr-scene arguments).
const MORE_APP_CALLS: &[(&str, &str, u32, &[&str])] = &[
    ("vkAllocateMemory", "VK_ERROR_OUT_OF_DEVICE_MEMORY", 12, &[]),
    ("vkCreateCommandPool", "VK_ERROR_OUT_OF_DEVICE_MEMORY", 1, &[]),
    ("vkCreateRenderPass2", "VK_ERROR_OUT_OF_DEVICE_MEMORY", 0, &["--rendering", "render-pass2"]),
];

/// xr-scene with the fault layer (`VK_FAULT` = `fault`), three frames (frame 0's eyes are unknown
/// to the layer until its `xrEndFrame`, so frames 1 and 2 carry the features), depth submitted
/// (the far field's depth range), and with stereoshim and every feature when `layer`.
fn run(name: &str, fault: &str, layer: bool, args: &[&str]) -> RunOutput {
    let data = fault_layer_data_dir();
    let layer_submit = fault.starts_with("vkQueueSubmit@layer");
    let mut r = Run::new(name)
        .args(["--submit-depth", "--vk-layer", FAULT_LAYER])
        .args(args.iter().copied())
        .env("MOCK_XR_EXIT_AFTER", "3")
        .env("VK_FAULT", fault)
        .env("XDG_DATA_DIRS", &format!("{}:/usr/local/share:/usr/share", data.display()));
    if layer {
        r = r.with_layer().config(FEATURES);
    }
    // Validation sits between stereoshim and the fault layer: it records a submission of the
    // layer's as gone to the device before the fault layer fails it, and its fence bookkeeping
    // then aborts the process (`std::future_error`) when the layer waits on or reuses the fence
    // the device never saw. Such runs go without validation; exit code and frames still judge.
    r.validation = !layer_submit;
    // The limit makes a hang a failure, never a stuck suite.
    r.run_while(Duration::from_secs(90), |_| {})
}

/// What a run showed the app's user: exit status and xr-scene's error line.
fn result(o: &RunOutput) -> String {
    let code = match (o.code, o.signal) {
        (Some(c), _) => format!("exit {c}"),
        (None, s) => format!("killed by signal {s:?}"),
    };
    match o.stderr.lines().find_map(|l| l.strip_prefix("xr-scene: error: ")) {
        Some(e) => format!("{code}: {e}"),
        None => code,
    }
}

/// The fault layer's lines for the calls it failed.
fn fired(o: &RunOutput) -> Vec<&str> {
    o.stderr.lines().filter(|l| l.starts_with("vk-fault-layer: ") && l.contains("failed on purpose")).collect()
}

/// Problems no run may show, fault or not: the fault layer's own failures (panic, unknown device,
/// bad `VK_FAULT`) and, with stereoshim, an internal failure or panic of the layer.
fn hard_failures(o: &RunOutput) -> Vec<String> {
    let mut bad: Vec<String> = o
        .stderr
        .lines()
        .filter(|l| l.starts_with("vk-fault-layer: ") && !l.contains("failed on purpose"))
        .map(|l| format!("{}: {l}", o.name))
        .collect();
    bad.extend(o.log.lines().filter(|l| l.contains("internal failure") || l.contains("panicked")).map(|l| format!("{}: layer log: {l}", o.name)));
    if o.signal.is_some() {
        bad.push(format!("{}: killed by signal {:?}\n{}", o.name, o.signal, o.crash.as_deref().unwrap_or(&o.stderr)));
    }
    bad
}

/// The layer's WARN and ERROR lines (its message only), hex numbers elided so the table is stable.
fn layer_warnings(o: &RunOutput) -> Vec<String> {
    o.log
        .lines()
        .filter(|l| l.contains(" WARN ") || l.contains(" ERROR "))
        .filter_map(|l| l.split_once(": ").map(|(_, m)| m))
        // Handles and URLs differ run to run or only make the table long.
        .map(|m| m.split(" key=").next().unwrap_or(m).split(" See <").next().unwrap_or(m).trim_end_matches('.').to_string())
        .map(|m| m.split(' ').map(|w| if w.starts_with("0x") || w.chars().filter(char::is_ascii_digit).count() >= 8 { "…" } else { w }).collect::<Vec<_>>().join(" "))
        .collect()
}

struct Row {
    call: &'static str,
    fault: &'static str,
    who: String,
    without: String,
    with: String,
    equal: bool,
    /// A documented, expected difference (the one case `layer_fault` explains).
    note: Option<String>,
}

/// Reference captures without a fault: the plain app, stereoshim with each subset of the
/// features on, and with RDM's fill reconstruction.
struct References {
    runs: Vec<RunOutput>,
}

impl References {
    fn new() -> References {
        let data = fault_layer_data_dir();
        let base = |name: &str| {
            Run::new(name)
                .args(["--submit-depth", "--vk-layer", FAULT_LAYER])
                .env("MOCK_XR_EXIT_AFTER", "3")
                .env("VK_FAULT", "")
                .env("XDG_DATA_DIRS", &format!("{}:/usr/local/share:/usr/share", data.display()))
        };
        let plain = base("vkf-ref-plain").run_while(Duration::from_secs(90), |_| {});
        let mut runs = vec![plain];
        // Every subset of the features on: a fault may turn off several (a failed buffer is
        // the mask's, and the far field's next attempt fails too when every call does).
        for on in 0..8u32 {
            let config = ["mask", "foveation", "far_field"]
                .iter()
                .enumerate()
                .fold(FEATURES.to_string(), |c, (i, f)| if on & (1 << i) == 0 { c.replace(&format!("[{f}]\nenabled = true"), &format!("[{f}]\nenabled = false")) } else { c });
            runs.push(base(&format!("vkf-ref-{on}")).with_layer().config(&config).run_while(Duration::from_secs(90), |_| {}));
            // RDM's own fallback when its compute reconstruction cannot be made: the fill.
            if on & 2 != 0 {
                let fill = config.replace("method = \"rdm\"", "method = \"rdm\"\nrdm_reconstruction = \"fill\"");
                runs.push(base(&format!("vkf-ref-{on}-fill")).with_layer().config(&fill).run_while(Duration::from_secs(90), |_| {}));
            }
        }
        for r in &runs {
            r.assert_ok();
            assert!(fired(r).is_empty(), "{}: a fault fired without VK_FAULT", r.name);
        }
        References { runs }
    }

    /// `Err` names the first view of `o` whose colour or depth equals no reference's same view
    /// of the same frame (or a frame structure that differs from the references').
    /// Every captured view of `o` is one a fault-free run produces, except in the frames of
    /// `spared`; returns the spared frames that did differ.
    fn check(&self, o: &RunOutput, spared: &[u64]) -> Result<Vec<u64>, String> {
        let plain = &self.runs[0];
        let frames = common::pair_captures(o.frames(), plain.frames(), common::DepthCheck::Compare)?;
        let mut differed = Vec::new();
        for (frame, pairs) in frames {
            for (v, _) in pairs {
                let colour = o.image(&v.file);
                let depth = v.depth.as_ref().map(|d| o.image(&d.file));
                let matches = self.runs.iter().any(|r| {
                    r.views(frame).into_iter().find(|rv| rv.view == v.view).is_some_and(|rv| {
                        r.image(&rv.file) == colour && rv.depth.as_ref().map(|d| r.image(&d.file)) == depth
                    })
                });
                if !matches && spared.contains(&frame) {
                    if !differed.contains(&frame) {
                        differed.push(frame);
                    }
                } else if !matches {
                    return Err(format!("frame {frame} view {}: the image is none a fault-free run produces", v.view));
                }
            }
        }
        Ok(differed)
    }
}

/// (a) The app's call `index` of `call` fails below stereoshim: the same result with and without it.
fn app_fault(call: &'static str, fault: &'static str, index: u32, args: &[&str], errors: &mut Vec<String>) -> Row {
    let spec = format!("{call}@app:{index}={fault}");
    let without = run(&format!("vkf-{call}-app{index}-plain"), &spec, false, args);
    let with = run(&format!("vkf-{call}-app{index}-layered"), &spec, true, args);
    errors.extend(hard_failures(&without));
    errors.extend(hard_failures(&with));
    if let Err(e) = common::layer_loaded(&with.log, common::Half::Both) {
        errors.push(format!("{call} (app): {e}"));
    }
    let (a, b) = (result(&without), result(&with));
    let (fa, fb) = (fired(&without), fired(&with));
    let mut equal = a == b;
    if fa.len() != fb.len() {
        errors.push(format!("{call} (app): the fault fired {} time(s) without stereoshim, {} with it", fa.len(), fb.len()));
        equal = false;
    }
    if !equal {
        errors.push(format!("{call} (app): without stereoshim {a:?}, with it {b:?}\n--- without:\n{}\n--- with:\n{}", without.stderr, with.stderr));
    }
    let describe = |r: String, f: &[&str]| if f.is_empty() { format!("no app call; {r}") } else { r };
    let who = match (index, args.is_empty()) {
        (0, true) => "app, 1st call".to_string(),
        (i, true) => format!("app, call {}", i + 1),
        (i, false) => format!("app, call {} with `{}`", i + 1, args.join(" ")),
    };
    Row { call, fault, who, without: describe(a, &fa), with: describe(b, &fb), equal, note: None }
}

/// (b) stereoshim's first own call of `call` fails. The right outcome: the feature that needed the
/// object does without it (for that object, or until the next attempt), logged at WARN, and the
/// app never notices — its call that led to the layer's work succeeds and its frames are those of
/// a run with that feature on or off. Failing the app's call instead would turn an optimisation
/// the app never asked for into a crash of the app.
///
/// `every`: every call stereoshim makes of the command fails (the device stays out of memory),
/// so each feature's later attempts fail too and the features needing it stay off.
fn layer_fault(call: &'static str, fault: &'static str, every: bool, refs: &References, errors: &mut Vec<String>) -> Row {
    let (spec, tag) = if every { (format!("{call}@layer={fault}"), "every") } else { (format!("{call}@layer:0={fault}"), "first") };
    let without = run(&format!("vkf-{call}-layer-{tag}-plain"), &spec, false, &[]);
    let with = run(&format!("vkf-{call}-layer-{tag}-layered"), &spec, true, &[]);
    errors.extend(hard_failures(&without));
    errors.extend(hard_failures(&with));
    // Without stereoshim nothing lies between the marker and the fault layer: no call is the
    // layer's. This is what proves the order (marker above stereoshim, fault layer below it).
    if !fired(&without).is_empty() {
        errors.push(format!("{call} (layer): a call counted as the layer's without stereoshim: {:?}", fired(&without)));
    }
    let (a, b) = (result(&without), result(&with));
    let fb = fired(&with);
    let mut equal = a == b && a == "exit 0";
    let mut note = None;
    if !equal {
        errors.push(format!("{call} (layer): without stereoshim {a:?}, with it {b:?}; stderr:\n{}\nlog warnings: {:?}", with.stderr, layer_warnings(&with)));
    }
    let with_text = if fb.is_empty() {
        format!("no layer call; {b}")
    } else {
        // RDM's reconstruction is made ready before its checkerboard is drawn
        // (`reconstruct::ready`): a failure there skips RDM for the pass, never leaves holes.
        //
        // One exception, with every submission of the layer's refused: RDM's reconstruction is
        // submitted at `xrReleaseSwapchainImage`, after the app's pass drew the checkerboard, so
        // the image whose reconstruction is refused goes to the runtime with holes. Nothing can
        // run on the GPU instead; the layer then stops drawing checkerboards on the device, so
        // that frame (the first with the features, frame 1) is the only one that differs.
        let refused_reconstruction = every && call == "vkQueueSubmit" && with.log.contains("radial density masking: no reconstruction");
        let spared: &[u64] = if refused_reconstruction { &[1] } else { &[] };
        match refs.check(&with, spared) {
            Err(e) => {
                errors.push(format!("{call} (layer): {e}"));
                equal = false;
            }
            Ok(differed) if !differed.is_empty() => note = Some(format!("frame {} keeps RDM's holes (its reconstruction was refused), later frames equal", differed.iter().map(u64::to_string).collect::<Vec<_>>().join(", "))),
            Ok(_) => {}
        }
        let warnings = layer_warnings(&with);
        if warnings.is_empty() {
            errors.push(format!("{call} (layer): the failure was not logged at WARN"));
        }
        // A single failure is logged once.
        if !every && warnings.len() != 1 {
            errors.push(format!("{call} (layer): one failure, {} WARN/ERROR lines: {warnings:?}", warnings.len()));
        }
        // A failure that repeats at every pass is logged once too (then counted: the device's
        // last line says how often each kind happened).
        let mut seen = std::collections::HashSet::new();
        if let Some(again) = warnings.iter().find(|w| !seen.insert(w.as_str())) {
            errors.push(format!("{call} (layer): the same WARN line twice: {again:?}"));
        }
        format!("{b}; layer: {}", warnings.first().map(String::as_str).unwrap_or("(nothing logged)"))
    };
    let who = if every { "layer, every call" } else { "layer, 1st call" };
    Row { call, fault, who: who.into(), without: format!("no such call; {a}"), with: with_text, equal, note }
}

fn table(rows: &[Row]) -> String {
    let mut t = String::from(
        "## Vulkan\n\n\
         Generated by `tests/hardening/faults_vk.rs` (`STEREOSHIM_UPDATE_DOCS=1 cargo test --test hardening faults_vk` \
         rewrites this section). The fault layer of the test tree (`tests/vk-fault-layer`) sits \
         below stereoshim and fails one call of a command: made by the app (or by the runtime \
         on the app's device: both are above stereoshim), or the first one stereoshim itself \
         makes for its own objects, or every one it makes. xr-scene runs with `--submit-depth` for three frames; with stereoshim \
         the mask, RDM and the far field are on. \"equal\": the app saw the same result, and \
         its frames are those of a fault-free run with some of the features on; \"no: …\" \
         is the one difference that cannot be avoided, explained in the cell. `vkQueueSubmit` \
         rows with the fault in a call of stereoshim's run without the validation layer \
         (docs/testing.md).\n\n\
         | call | fault | made by | without stereoshim | with stereoshim | equal |\n\
         |---|---|---|---|---|---|\n",
    );
    for r in rows {
        let cell = |s: &str| s.replace('|', "\\|");
        t.push_str(&format!(
            "| {} | {} | {} | {} | {} | {} |\n",
            r.call,
            r.fault,
            r.who,
            cell(&r.without),
            cell(&r.with),
            match (&r.note, r.equal) {
                (Some(n), true) => format!("no: {n}"),
                (None, true) => "yes".into(),
                (_, false) => "**no**".into(),
            }
        ));
    }
    t
}

/// The `## Vulkan` section of docs/faults.md: compared, or rewritten with
/// `STEREOSHIM_UPDATE_DOCS=1` (the file's other sections are kept).
fn check_docs(section: &str) -> Result<(), String> {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("docs/faults.md");
    let _docs = common::REPO_DOCS.lock().unwrap_or_else(|e| e.into_inner());
    let text = std::fs::read_to_string(&path).unwrap_or_default();
    let start = text.find("## Vulkan\n");
    let end = start.map(|s| text[s + 1..].find("\n## ").map_or(text.len(), |e| s + 1 + e + 1));
    let current = start.zip(end).map(|(s, e)| &text[s..e]);
    if current == Some(section) {
        return Ok(());
    }
    if std::env::var_os("STEREOSHIM_UPDATE_DOCS").is_some_and(|v| v == "1") {
        let new = match start.zip(end) {
            Some((s, e)) => format!("{}{section}{}", &text[..s], &text[e..]),
            None if text.is_empty() => format!("# Faults below the layer\n\n{section}"),
            None => format!("{}\n{section}", text.trim_end_matches('\n').to_string() + "\n"),
        };
        std::fs::write(&path, new).map_err(|e| e.to_string())?;
        return Ok(());
    }
    Err(format!(
        "docs/faults.md's `## Vulkan` section differs from this run's table (STEREOSHIM_UPDATE_DOCS=1 rewrites it); this run's:\n{section}"
    ))
}

#[test]
fn faults_below_the_layer() {
    let refs = References::new();
    let mut errors = Vec::new();
    let mut rows = Vec::new();
    for &(call, fault) in CALLS {
        rows.push(app_fault(call, fault, 0, &[], &mut errors));
        for &(c, f, index, args) in MORE_APP_CALLS.iter().filter(|m| m.0 == call) {
            rows.push(app_fault(c, f, index, args, &mut errors));
        }
        rows.push(layer_fault(call, fault, false, &refs, &mut errors));
        rows.push(layer_fault(call, fault, true, &refs, &mut errors));
    }
    let section = table(&rows);
    std::fs::write(common::target_dir().join("test-output").join("faults-vk.md"), &section).unwrap();
    if let Err(e) = check_docs(&section) {
        errors.push(e);
    }
    assert!(errors.is_empty(), "{} problem(s):\n{}", errors.len(), errors.join("\n\n"));
}
