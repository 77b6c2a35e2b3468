//! Never silent: when a feature the user enabled is not applied to an app's eye passes, the user is
//! told once per reason at WARN level, with what they can do about it, and a session in which an
//! enabled feature applied to no pass at all ends with a WARN summary. The rules are pure: the
//! OpenXR half feeds every frame's statistics in at `xrEndFrame` and logs what comes out.

use crate::mask::MaskFrameStats;
use std::collections::{BTreeMap, BTreeSet};

/// The features whose application is tracked.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Feature {
    Mask,
    /// Foveation by radial density masking.
    Rdm,
    /// Foveation by variable-rate shading.
    Vrs,
}

impl Feature {
    pub fn name(&self) -> &'static str {
        match self {
            Feature::Mask => "hidden-area mask",
            Feature::Rdm => "foveation (radial density masking)",
            Feature::Vrs => "foveation (variable-rate shading)",
        }
    }
}

/// What the user can do about a reason a pass was left alone (reason names as in `stats.file`).
pub fn hint(reason: &str) -> &'static str {
    match reason {
        "eye_unknown" => {
            "the pass renders into an image the layer cannot tie to an eye (not a swapchain image, nor copied into one 1:1); \
             frame 0 is always so. If it persists, a layer above stereoshim may create the swapchain images elsewhere: \
             report the app and runtime"
        }
        "no_depth_attachment" => "the app renders its eyes without a depth buffer: the mask and RDM need one; nothing to do",
        "depth_not_cleared" => "the app loads depth instead of clearing it: the layer cannot know the depth to fail against",
        "depth_clear_not_0_1" => "the app clears depth to a value other than 0 or 1: not supported",
        "secondary" => "the pass's contents are in secondary command buffers the layer could not reach",
        "no_mask" => "the runtime has no hidden-area mask for the view: set mask.source = \"synthesized\" (or \"auto\")",
        "unsupported" => "a pass shape the layer does not handle (e.g. per-view rects differing in one multiview pass)",
        "intermediate_off" => "the pass renders to an offscreen target: set mask.intermediate = \"on\" to include such passes",
        "layer_error" => "the layer could not create its objects on this device: see the errors above in this log",
        "device_lacks" => {
            "the app's Vulkan device lacks a capability the layer's draw needs for this pass (named above in this log)"
        }
        "no_fovea" => "no fovea yet for the view (the first frame): nothing to do unless it persists",
        "not_one_to_one" => "the app copies the eye image to the swapchain scaled or offset: RDM cannot reconstruct it; use foveation.method = \"vrs\" where the GPU has it",
        "swapchain_usage" => "the swapchain image lacks the usage RDM's reconstruction needs",
        "multiview_not_layered" => "the GPU cannot use one rate layer per view: use foveation.method = \"rdm\"",
        "app_uses_fsr" => "the app sets its own shading rate: the layer leaves it alone",
        "render_pass" => "a render pass created before the layer could add its rate attachment",
        "layered" => "a non-multiview pass renders several layers: not supported by VRS",
        _ => "see docs/configuration.md",
    }
}

/// Reasons a feature left passes alone in one frame, with their counts.
type Reasons = Vec<(&'static str, u64)>;

/// Accumulates one session's frames; tells what to log.
#[derive(Clone, Debug, Default)]
pub struct Summary {
    /// Passes each enabled feature applied to, over the session.
    applied: BTreeMap<Feature, u64>,
    /// Reasons each feature was not applied, over the session (while enabled).
    not_applied: BTreeMap<Feature, BTreeMap<&'static str, u64>>,
    /// Features that were enabled in at least one frame.
    enabled: BTreeSet<Feature>,
    /// (feature, reason) pairs already warned about.
    warned: BTreeSet<(Feature, &'static str)>,
    frames: u64,
}

/// Which features were enabled while a frame was recorded.
#[derive(Clone, Copy, Debug, Default)]
pub struct Enabled {
    pub mask: bool,
    /// Foveation on with RDM as the method in effect (`rdm`, or `auto` without VRS).
    pub rdm: bool,
    pub vrs: bool,
}

impl Summary {
    /// Adds a frame; returns the warnings to log now: each (feature, reason) the first time it
    /// shows up while the feature is enabled. `not_eye_pass` is no reason (other passes). The
    /// session's first frame is counted but warns about nothing: its passes are recorded before the
    /// layer has seen which swapchain shows which eye (the first `xrEndFrame`), so they are all
    /// `eye_unknown` in every app.
    pub fn add_frame(&mut self, enabled: Enabled, s: &MaskFrameStats) -> Vec<String> {
        self.frames += 1;
        let first = self.frames == 1;
        let features: [(Feature, bool, u64, Reasons); 3] = [
            (Feature::Mask, enabled.mask, s.passes_masked, s.not_masked.iter().map(|(k, v)| (*k, *v)).collect()),
            (Feature::Rdm, enabled.rdm, s.rdm.passes, s.rdm.not_applied.iter().map(|(k, v)| (*k, *v)).collect()),
            (Feature::Vrs, enabled.vrs, s.vrs.passes, s.vrs.not_applied.iter().map(|(k, v)| (*k, *v)).collect()),
        ];
        let mut warnings = Vec::new();
        for (feature, on, passes, reasons) in features {
            if !on {
                continue;
            }
            self.enabled.insert(feature);
            *self.applied.entry(feature).or_default() += passes;
            for (reason, n) in reasons.into_iter().filter(|(r, n)| *n > 0 && *r != "not_eye_pass") {
                *self.not_applied.entry(feature).or_default().entry(reason).or_default() += n;
                if !first && self.warned.insert((feature, reason)) {
                    warnings.push(format!(
                        "{} not applied to a pass: {reason} — {} (logged once per reason; counted per frame in stats.file)",
                        feature.name(),
                        hint(reason)
                    ));
                }
            }
        }
        warnings
    }

    /// At the end of the session: one warning per enabled feature that applied to no pass at all.
    pub fn end(&self) -> Vec<String> {
        self.enabled
            .iter()
            .filter(|f| self.applied.get(f).copied().unwrap_or(0) == 0)
            .map(|f| {
                let reasons = self.not_applied.get(f).map(|r| format!("{r:?}")).unwrap_or_else(|| "none counted".into());
                format!(
                    "{} was enabled but applied to no pass in this session ({} frames; reasons: {reasons}). \
                     If no reasons were counted, the layer's Vulkan half never saw the app's eye passes: \
                     see the session's first lines in this log and run `stereoshim status`",
                    f.name(),
                    self.frames
                )
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(masked: u64, reasons: &[(&'static str, u64)]) -> MaskFrameStats {
        MaskFrameStats { passes_masked: masked, not_masked: reasons.iter().copied().collect(), ..Default::default() }
    }
    const MASK: Enabled = Enabled { mask: true, rdm: false, vrs: false };

    #[test]
    fn each_reason_warns_once_with_a_hint() {
        let mut s = Summary::default();
        assert!(s.add_frame(MASK, &frame(0, &[("eye_unknown", 2)])).is_empty(), "the first frame warns about nothing");
        let w = s.add_frame(MASK, &frame(0, &[("eye_unknown", 2), ("not_eye_pass", 5)]));
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(w[0].contains("eye_unknown") && w[0].contains("hidden-area mask") && w[0].contains("frame 0"), "{}", w[0]);
        assert!(s.add_frame(MASK, &frame(2, &[("eye_unknown", 1)])).is_empty(), "once per reason");
        let w = s.add_frame(MASK, &frame(1, &[("no_mask", 1)]));
        assert!(w.len() == 1 && w[0].contains("mask.source"), "{w:?}");
        assert!(s.end().is_empty(), "the mask applied to passes");
    }

    #[test]
    fn disabled_features_say_nothing() {
        let mut s = Summary::default();
        for _ in 0..2 {
            assert!(s.add_frame(Enabled::default(), &frame(0, &[("eye_unknown", 2)])).is_empty());
        }
        assert!(s.end().is_empty());
    }

    #[test]
    fn a_session_without_any_applied_pass_ends_with_a_warning() {
        let mut s = Summary::default();
        s.add_frame(Enabled { mask: true, rdm: true, vrs: false }, &frame(0, &[("secondary", 2)]));
        s.add_frame(Enabled { mask: true, rdm: true, vrs: false }, &frame(0, &[]));
        let end = s.end();
        assert_eq!(end.len(), 2, "{end:?}");
        assert!(end[0].contains("hidden-area mask") && end[0].contains("secondary") && end[0].contains("2 frames"), "{}", end[0]);
        assert!(end[1].contains("radial density") && end[1].contains("none counted"), "{}", end[1]);
    }

    #[test]
    fn every_reason_has_a_specific_hint() {
        for r in crate::mask::NotMasked::ALL.iter().filter(|r| **r != crate::mask::NotMasked::NotEyePass) {
            assert_ne!(hint(r.name()), hint("?"), "{}", r.name());
        }
    }
}
