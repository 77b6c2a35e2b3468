//! Never silent: when a feature the user enabled is not applied to an app's eye passes, the user is
//! told once per reason at WARN level, with what they can do about it, and a session in which an
//! enabled feature applied to no pass at all ends with a WARN summary. The rules are pure: the
//! OpenXR half feeds every frame's statistics in at `xrEndFrame` and logs what comes out. Features
//! are known only through their statistics (`FeatureStats`: label, reasons, hints).
#![forbid(unsafe_code)]

use crate::core::stats::FrameStats;
use std::collections::{BTreeMap, BTreeSet};

/// Accumulates one session's frames; tells what to log.
#[derive(Clone, Debug, Default)]
pub struct Summary {
    /// Passes each enabled feature applied to, over the session.
    applied: BTreeMap<&'static str, u64>,
    /// Reasons each feature was not applied, over the session (while enabled).
    not_applied: BTreeMap<&'static str, BTreeMap<&'static str, u64>>,
    /// Features that were enabled in at least one frame, with their labels.
    enabled: BTreeMap<&'static str, &'static str>,
    /// (feature, reason) pairs already warned about.
    warned: BTreeSet<(&'static str, &'static str)>,
    frames: u64,
}

impl Summary {
    /// Adds a frame; returns the warnings to log now: each (feature, reason) the first time it
    /// shows up while the feature is enabled (`enabled`: feature id → on in this frame).
    /// `not_eye_pass` is no reason (other passes). The session's first frame is counted but warns
    /// about nothing: its passes are recorded before the layer has seen which swapchain shows
    /// which eye (the first `xrEndFrame`), so they are all `eye_unknown` in every app.
    pub fn add_frame(&mut self, enabled: &[(&'static str, bool)], s: &FrameStats) -> Vec<String> {
        self.frames += 1;
        let first = self.frames == 1;
        let mut warnings = Vec::new();
        for f in s.iter() {
            if !enabled.iter().any(|(id, on)| *id == f.id() && *on) {
                continue;
            }
            let id = f.id();
            self.enabled.insert(id, f.label());
            *self.applied.entry(id).or_default() += f.passes();
            for (reason, n) in f.not_applied().into_iter().filter(|(r, n)| *n > 0 && *r != "not_eye_pass") {
                *self.not_applied.entry(id).or_default().entry(reason).or_default() += n;
                if !first && self.warned.insert((id, reason)) {
                    warnings.push(format!(
                        "{} not applied to a pass: {reason} — {} (logged once per reason; counted per frame in stats.file)",
                        f.label(),
                        f.hint(reason)
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
            .filter(|(id, _)| self.applied.get(*id).copied().unwrap_or(0) == 0)
            .map(|(id, label)| {
                let reasons = self.not_applied.get(id).map(|r| format!("{r:?}")).unwrap_or_else(|| "none counted".into());
                format!(
                    "{label} was enabled but applied to no pass in this session ({} frames; reasons: {reasons}). \
                     If no reasons were counted, the layer's Vulkan half never saw the app's eye passes: \
                     see the session's first lines in this log and run `stereoshim status`",
                    self.frames
                )
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::pass::NotMasked;
    use crate::core::stats::FeatureStats;
    use crate::features::foveation::vrs::rules::VrsFrameStats;
    use crate::features::mask::rules::MaskFrameStats;

    fn frame(masked: u64, reasons: &[(&'static str, u64)]) -> FrameStats {
        let mut f = crate::registry::empty_stats();
        *f.get_mut::<MaskFrameStats>().unwrap() = MaskFrameStats { passes_masked: masked, not_masked: reasons.iter().copied().collect(), ..Default::default() };
        f
    }
    const MASK: &[(&str, bool)] = &[("mask", true), ("rdm", false), ("vrs", false)];

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
            assert!(s.add_frame(&[], &frame(0, &[("eye_unknown", 2)])).is_empty());
        }
        assert!(s.end().is_empty());
    }

    #[test]
    fn a_session_without_any_applied_pass_ends_with_a_warning() {
        let mut s = Summary::default();
        let on = [("mask", true), ("rdm", true), ("vrs", false)];
        s.add_frame(&on, &frame(0, &[("secondary", 2)]));
        s.add_frame(&on, &frame(0, &[]));
        let end = s.end();
        assert_eq!(end.len(), 2, "{end:?}");
        assert!(end[0].contains("hidden-area mask") && end[0].contains("secondary") && end[0].contains("2 frames"), "{}", end[0]);
        assert!(end[1].contains("radial density") && end[1].contains("none counted"), "{}", end[1]);
    }

    #[test]
    fn vrs_reasons_have_their_own_hints() {
        let (vrs, mask) = (VrsFrameStats::default(), MaskFrameStats::default());
        assert!(vrs.hint("unsupported").contains("fragment shading rate"));
        assert_ne!(vrs.hint("unsupported"), mask.hint("unsupported"));
    }

    #[test]
    fn every_reason_has_a_specific_hint() {
        let mask = MaskFrameStats::default();
        for r in NotMasked::ALL.iter().filter(|r| **r != NotMasked::NotEyePass) {
            assert_ne!(mask.hint(r.name()), mask.hint("?"), "{}", r.name());
        }
    }
}
