//! xr-scene's post-processing frame structures (`--post`, `--post-compute`, `--post-subpass`,
//! `--post-depth-attachment`, `--render-scale`, `--viewport-scale`, `--submit-texture
//! double-wide`; docs/testing.md) as named modes, the matrices the tests run them in, and one
//! call that runs a mode with or without the layer (and a layer configuration) and returns its
//! captures, stats and the layer's log ([`run_post_chain`]).

use super::{Run, RunOutput};

/// One post-chain configuration of xr-scene: a name (the run folder's, and the label of every
/// failure) and the app's arguments.
#[derive(Clone, Debug, PartialEq)]
pub struct PostMode {
    pub name: String,
    pub args: Vec<String>,
    /// Frames the mock runtime lets the app render (`MOCK_XR_EXIT_AFTER`; every frame is
    /// captured). Default 2, as every [`Run`].
    pub frames: u64,
    /// The mock runtime's headset (`MOCK_XR_HMD`); None: its default, whose two eyes' masks are
    /// mirror images of each other.
    pub hmd: Option<&'static str>,
}

impl PostMode {
    pub fn new(name: &str, args: &[&str]) -> PostMode {
        PostMode { name: name.to_string(), args: args.iter().map(|s| s.to_string()).collect(), frames: 2, hmd: None }
    }

    /// The same mode on the mock runtime's `hmd` profile.
    pub fn hmd(mut self, hmd: &'static str) -> PostMode {
        self.hmd = Some(hmd);
        self
    }

    /// The same mode rendering `n` frames (e.g. to look past a layer's warm-up frames).
    pub fn frames(mut self, n: u64) -> PostMode {
        self.frames = n;
        self
    }

    /// The same mode under `owner`'s name (`<owner>-<mode>`), so that its run folders are that
    /// test module's alone: the modules of one test binary run the same modes at the same time
    /// (tests/features/post_chain*.rs).
    pub fn owned_by(mut self, owner: &str) -> PostMode {
        self.name = format!("{owner}-{}", self.name);
        self
    }

    /// The same mode with more arguments (the last value of an option wins).
    pub fn with_args(mut self, suffix: &str, args: &[&str]) -> PostMode {
        self.name = format!("{}-{suffix}", self.name);
        self.args.extend(args.iter().map(|s| s.to_string()));
        self
    }

    pub fn has(&self, arg: &str) -> bool {
        self.args.iter().any(|a| a == arg)
    }

    /// The value of option `flag` (`--layout`, `--post`, …), if given.
    pub fn value(&self, flag: &str) -> Option<&str> {
        self.args.windows(2).rev().find(|w| w[0] == flag).map(|w| w[1].as_str())
    }

    /// The base run of this mode (validation with synchronization validation on, as every `Run`).
    pub fn run_spec(&self) -> Run {
        let run = Run::new(&self.name).args(self.args.iter().cloned()).env("MOCK_XR_EXIT_AFTER", &self.frames.to_string());
        match self.hmd {
            Some(hmd) => run.env("MOCK_XR_HMD", hmd),
            None => run,
        }
    }
}

/// What the layer gets in a run: its config file (`config.toml` text) and `STEREOSHIM_*`
/// environment. [`LayerConfig::off`] is the layer with every feature off (its defaults).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LayerConfig {
    pub toml: Option<String>,
    pub env: Vec<(String, String)>,
}

impl LayerConfig {
    pub fn off() -> LayerConfig {
        LayerConfig::default()
    }

    /// The mask, RDM foveation and the far field on (as `super::every_feature`).
    pub fn every_feature() -> LayerConfig {
        LayerConfig::off()
            .env("STEREOSHIM_MASK_ENABLED", "1")
            .env("STEREOSHIM_FOVEATION_ENABLED", "1")
            .env("STEREOSHIM_FOVEATION_METHOD", "rdm")
            .env("STEREOSHIM_FAR_FIELD_ENABLED", "1")
    }

    pub fn env(mut self, key: &str, value: &str) -> LayerConfig {
        self.env.retain(|(k, _)| k != key);
        self.env.push((key.to_string(), value.to_string()));
        self
    }

    pub fn toml(mut self, text: &str) -> LayerConfig {
        self.toml = Some(text.to_string());
        self
    }
}

/// Runs `mode` without the layer (`None`) or through it with `layer` (run folder
/// `<mode>-layer`), asserts a clean run (exit 0, so no validation error either) and, with the
/// layer, that both of its halves loaded; returns the run's captures (`frames()`, `image()`),
/// `--stats` and the layer's log.
pub fn run_post_chain(mode: &PostMode, layer: Option<&LayerConfig>) -> RunOutput {
    let mut run = mode.run_spec();
    if let Some(cfg) = layer {
        run = run.with_layer();
        run.name = format!("{}-layer", mode.name);
        for (k, v) in &cfg.env {
            run = run.env(k, v);
        }
        if let Some(t) = &cfg.toml {
            run = run.config(t);
        }
    }
    let out = run.run();
    out.assert_ok();
    if layer.is_some() {
        out.assert_layer_loaded(super::Half::Both);
    }
    out
}

/// [`run_post_chain`] without and with the layer: (without, with).
pub fn run_post_chain_pair(mode: &PostMode, layer: &LayerConfig) -> (RunOutput, RunOutput) {
    (run_post_chain(mode, None), run_post_chain(mode, Some(layer)))
}

const LAYOUTS: [&str; 3] = ["per-eye", "multiview", "side-by-side"];
const RENDERINGS: [&str; 3] = ["render-pass", "render-pass2", "dynamic"];

/// A mode named from its parts: `post-<layout>-<rendering>-<depth>-<tag>`.
fn mode(layout: &str, rendering: &str, depth: &str, tag: &str, extra: &[&str]) -> PostMode {
    let base = ["--layout", layout, "--rendering", rendering, "--depth", depth];
    let args: Vec<&str> = base.iter().chain(extra).copied().collect();
    PostMode::new(&format!("post-{layout}-{rendering}-{depth}-{tag}"), &args)
}

/// Each post-chain option in every layout where it applies and in every rendering path at least
/// once (rotating through them), both depth conventions, some with 4× MSAA: the modest matrix the
/// suite runs (tests/features/post_chain.rs). Rendering paths an option does not support (`--post-subpass`
/// with dynamic rendering) are skipped in the rotation.
pub fn matrix() -> Vec<PostMode> {
    let options: [(&str, &[&str]); 13] = [
        ("tonemap", &["--post", "tonemap"]),
        ("tonemap-msaa", &["--post", "tonemap", "--samples", "4"]),
        ("bloom", &["--post", "bloom"]),
        ("taa-msaa", &["--post", "taa", "--samples", "4"]),
        ("compute", &["--post", "tonemap", "--post-compute"]),
        ("subpass", &["--post", "tonemap", "--post-subpass"]),
        ("depth-attachment", &["--post", "bloom", "--post-depth-attachment"]),
        ("render-scale", &["--post", "tonemap", "--render-scale", "0.5"]),
        ("viewport-scale", &["--post", "taa", "--viewport-scale", "0.75"]),
        ("both-scales-msaa", &["--post", "bloom", "--render-scale", "0.8", "--viewport-scale", "0.7", "--samples", "4"]),
        ("compute-scaled", &["--post", "tonemap", "--post-compute", "--render-scale", "0.7"]),
        // The eye rect changes every frame (engines' dynamic resolution).
        ("dynamic-res", &["--post", "tonemap", "--viewport-scale", "0.8", "--dynamic-resolution"]),
        // Command buffers recorded before the walk knew their targets, resubmitted later.
        ("record-once-msaa", &["--post", "bloom", "--samples", "4", "--record-once"]),
    ];
    let mut modes = Vec::new();
    let mut turn = 0;
    for (tag, extra) in options {
        for layout in LAYOUTS {
            let renderings: Vec<&str> = RENDERINGS.iter().copied().filter(|r| !(tag == "subpass" && *r == "dynamic")).collect();
            let rendering = renderings[turn % renderings.len()];
            let depth = ["standard", "reverse"][(turn / 3) % 2];
            turn += 1;
            modes.push(mode(layout, rendering, depth, tag, extra));
        }
    }
    // The double-wide texture: side by side only, blitted into a 2-layer swapchain.
    let dw = ["--submit-texture", "double-wide"];
    for (i, (tag, extra)) in [("dw", &[][..]), ("dw-tonemap", &["--post", "tonemap"]), ("dw-taa-scaled", &["--post", "taa", "--render-scale", "0.5"])].into_iter().enumerate() {
        let args: Vec<&str> = dw.iter().chain(extra).copied().collect();
        modes.push(mode("side-by-side", RENDERINGS[i], ["standard", "reverse"][i % 2], tag, &args));
    }
    // One scene target and depth for both eyes, as engines render them: each eye's pass followed
    // by its own chain into its swapchain image before the other eye renders into the same
    // target. On the Index, whose eyes' masks differ: a pass given the other eye's mask shows.
    for (i, (tag, extra)) in [("one-target", &["--post", "tonemap", "--one-target"][..]), ("one-target-bloom-msaa", &["--post", "bloom", "--samples", "4", "--one-target"])].into_iter().enumerate() {
        modes.push(mode("per-eye", RENDERINGS[(i + 1) % RENDERINGS.len()], ["reverse", "standard"][i % 2], tag, extra).hmd("index"));
    }
    // The same into ONE 2-layer swapchain (`--eye-swapchain array`: eye v's chain writes layer v
    // of the one image): the walk from that swapchain reaches both uses of the shared target.
    let array = [("one-target-array", &["--post", "tonemap", "--one-target", "--eye-swapchain", "array"][..]), ("one-target-array-bloom-msaa", &["--post", "bloom", "--samples", "4", "--one-target", "--eye-swapchain", "array"])];
    for (i, (tag, extra)) in array.into_iter().enumerate() {
        modes.push(mode("per-eye", RENDERINGS[i % RENDERINGS.len()], ["standard", "reverse"][i % 2], tag, extra).hmd("index"));
    }
    // While working on one shape: `STEREOSHIM_POST_MODES=one-target cargo test … post_chain_`
    // runs only the modes whose name contains it (never set by the suite).
    if let Ok(only) = std::env::var("STEREOSHIM_POST_MODES") {
        modes.retain(|m| m.name.contains(&only));
    }
    modes
}

/// The full cross product: every layout × rendering path × depth convention × option × 1 or 4
/// samples where the command line accepts the combination (the ignored test of
/// tests/features/post_chain.rs, `scripts/post-chain-matrix`).
pub fn full_matrix() -> Vec<PostMode> {
    let options: [(&str, &[&str]); 12] = [
        ("tonemap", &["--post", "tonemap"]),
        ("bloom", &["--post", "bloom"]),
        ("taa", &["--post", "taa"]),
        ("compute", &["--post", "tonemap", "--post-compute"]),
        ("subpass", &["--post", "tonemap", "--post-subpass"]),
        ("depth-attachment", &["--post", "tonemap", "--post-depth-attachment"]),
        ("render-scale", &["--post", "bloom", "--render-scale", "0.6"]),
        ("viewport-scale", &["--post", "taa", "--viewport-scale", "0.6"]),
        ("dw", &["--submit-texture", "double-wide"]),
        ("dw-post", &["--submit-texture", "double-wide", "--post", "bloom", "--render-scale", "0.75"]),
        ("dynamic-res", &["--post", "taa", "--dynamic-resolution"]),
        ("record-once", &["--post", "taa", "--record-once"]),
    ];
    let mut modes = Vec::new();
    for layout in LAYOUTS {
        for rendering in RENDERINGS {
            for depth in ["standard", "reverse"] {
                for (tag, extra) in options {
                    for samples in ["1", "4"] {
                        let subpass = extra.contains(&"--post-subpass");
                        let dw = extra.contains(&"double-wide");
                        if (subpass && (rendering == "dynamic" || samples == "4")) || (dw && layout != "side-by-side") || (dw && samples == "4" && !extra.contains(&"--post")) {
                            continue;
                        }
                        let mut args = extra.to_vec();
                        if samples == "4" {
                            args.extend(["--samples", "4"]);
                        }
                        modes.push(mode(layout, rendering, depth, &format!("{tag}-s{samples}"), &args));
                    }
                }
            }
        }
    }
    modes
}
