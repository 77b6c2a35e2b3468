//! The far field's per-frame counters (`stats.file`, the device's stats line).
#![forbid(unsafe_code)]

use crate::core::stats::{json_counts, Counters};
use std::collections::BTreeMap;

/// Counted per submission: a command buffer recorded once counts every time it runs.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct FarFieldStats {
    /// Destination views that reused the source's far field, by view.
    pub views_reused: BTreeMap<u32, u64>,
    /// Copies of eye images the layer made (sources for later reuse).
    pub copies: u64,
    /// Eye passes (or destination views) left alone, by reason.
    pub not_applied: BTreeMap<&'static str, u64>,
    /// Destination views that had no fresh source this time.
    pub no_fresh_source: u64,
    /// Pixels reused (counted by occlusion queries as their submissions complete).
    pub pixels_reused: u64,
}

impl FarFieldStats {
    pub fn count_not_applied(&mut self, why: &'static str) {
        *self.not_applied.entry(why).or_insert(0) += 1;
    }
}

impl Counters for FarFieldStats {
    const ID: &'static str = "far_field";
    const LABEL: &'static str = "monoscopic far field";
    fn merge(&mut self, o: &Self) {
        for (k, v) in &o.views_reused {
            *self.views_reused.entry(*k).or_insert(0) += v;
        }
        for (k, v) in &o.not_applied {
            *self.not_applied.entry(*k).or_insert(0) += v;
        }
        self.copies += o.copies;
        self.no_fresh_source += o.no_fresh_source;
        self.pixels_reused += o.pixels_reused;
    }
    fn applied(&self) -> u64 {
        self.views_reused.values().sum()
    }
    fn left_alone(&self) -> Vec<(&'static str, u64)> {
        self.not_applied.iter().map(|(k, v)| (*k, *v)).collect()
    }
    fn hint_for(&self, reason: &str) -> &'static str {
        match reason {
            "no_depth_range" => "the app submits no XrCompositionLayerDepthInfoKHR and its engine (VkApplicationInfo::pEngineName) has no documented default: set far_field.near_z and far_field.far_z to its projection range",
            "several_colour_attachments" => "the pass writes several colour attachments (a G-buffer): the far field only reuses a lit eye image",
            "unsupported" => "a pass shape the far field does not handle (suspended rendering, mixed sample counts)",
            "depth_range_mismatch" => "the configured or submitted depth range has the other depth convention than the pass's clear: check far_field.near_z / far_z",
            "not_stored" => "the pass does not store its colour or depth: there is nothing to reuse",
            "no_transfer_src" => "the eye or depth image was created before the layer could add TRANSFER_SRC to its usage",
            "no_sampled_usage" => "the eye or depth image was created before the layer could add SAMPLED to its usage, or its format cannot be sampled",
            "vetoed" => "the command buffer set state the layer does not restore (the app's own shading rate, NVIDIA's extended dynamic state, local-read attachment remapping)",
            "not_depth_tested" => "the pass has no depth-tested draw: nothing to save",
            _ => crate::core::stats::common_hint(reason),
        }
    }
    fn line(&self) -> String {
        format!(
            "far_field_views_reused={} far_field_pixels_reused={} far_field_copies={} far_field_no_fresh_source={} far_field_not_applied={:?}",
            self.applied(),
            self.pixels_reused,
            self.copies,
            self.no_fresh_source,
            self.not_applied
        )
    }
    fn json(&self, record: &mut serde_json::Map<String, serde_json::Value>) {
        let mut o = serde_json::Map::new();
        o.insert("views_reused".into(), json_counts(self.views_reused.iter().map(|(k, v)| (*k, *v))));
        o.insert("copies".into(), self.copies.into());
        o.insert("pixels_reused".into(), self.pixels_reused.into());
        o.insert("no_fresh_source".into(), self.no_fresh_source.into());
        o.insert("not_applied".into(), json_counts(self.not_applied.iter().map(|(k, v)| (*k, *v))));
        record.insert("far_field".into(), o.into());
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::stats::FeatureStats;

    #[test]
    fn adds_and_writes() {
        let mut a = FarFieldStats::default();
        assert!(a.is_empty());
        let mut b = FarFieldStats { copies: 2, ..Default::default() };
        b.views_reused.insert(1, 3);
        b.count_not_applied("not_stored");
        a.add(&b);
        a.add(&b);
        assert_eq!((a.passes(), a.copies, a.not_applied()), (6, 4, vec![("not_stored", 2)]));
        let mut rec = serde_json::Map::new();
        a.write_json(&mut rec);
        assert_eq!(rec["far_field"]["views_reused"]["1"], 6);
    }
}
