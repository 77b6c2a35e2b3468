//! The hidden-area mask's statistics: what it did in a frame. Its geometry (where a view's hidden
//! triangles land and which pixels they cover) is shared with other features and lives in the
//! base, `crate::core::lens`; re-exported here for the mask's own code and the tests.
#![forbid(unsafe_code)]

pub use crate::core::lens::{coverage, coverage_bitmap, hidden_pixels, masked_pixels, tangent_to_ndc, triangles_to_ndc, MAX_COUNTED_PIXELS};
use crate::core::pass::NotMasked;
use crate::core::stats::{json_counts, Counters};
use std::collections::BTreeMap;

/// What the mask did in one frame (between two `xrEndFrame`s), summed over devices. Plain fields:
/// the OpenXR half writes them to `stats.file`.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct MaskFrameStats {
    /// Eye passes (render pass instances or explicit depth clears) that got a mask.
    pub passes_masked: u64,
    /// Masked passes by how their target was tied to the eyes: swapchain, transfer (1:1 into
    /// one), walk (the data-flow walk), fallback (size and order).
    pub by_source: BTreeMap<&'static str, u64>,
    /// Render pass instances with a depth or swapchain attachment that got none, by reason
    /// (`NotMasked::name`).
    pub not_masked: BTreeMap<&'static str, u64>,
    /// Pixels covered by the drawn mask, per OpenXR view index.
    pub pixels_masked: BTreeMap<u32, u64>,
}

impl MaskFrameStats {
    pub fn add(&mut self, o: &MaskFrameStats) {
        self.passes_masked += o.passes_masked;
        for (k, v) in &o.by_source {
            *self.by_source.entry(k).or_insert(0) += v;
        }
        for (k, v) in &o.not_masked {
            *self.not_masked.entry(k).or_insert(0) += v;
        }
        for (k, v) in &o.pixels_masked {
            *self.pixels_masked.entry(*k).or_insert(0) += v;
        }
    }
    pub fn count_not_masked(&mut self, why: NotMasked) {
        *self.not_masked.entry(why.name()).or_insert(0) += 1;
    }
    pub fn pixels_total(&self) -> u64 {
        self.pixels_masked.values().sum()
    }
    /// `key=value` pairs for the `vulkan device stats:` line.
    pub fn summary(&self) -> String {
        let mut s = format!("masked_passes={} masked_pixels={}", self.passes_masked, self.pixels_total());
        for (k, v) in &self.by_source {
            s.push_str(&format!(" masked_by.{k}={v}"));
        }
        for (k, v) in &self.not_masked {
            s.push_str(&format!(" not_masked.{k}={v}"));
        }
        s
    }
}

impl Counters for MaskFrameStats {
    const ID: &'static str = "mask";
    const LABEL: &'static str = "hidden-area mask";
    fn merge(&mut self, o: &Self) {
        MaskFrameStats::add(self, o);
    }
    fn applied(&self) -> u64 {
        self.passes_masked
    }
    fn left_alone(&self) -> Vec<(&'static str, u64)> {
        self.not_masked.iter().map(|(k, v)| (*k, *v)).collect()
    }
    fn hint_for(&self, reason: &str) -> &'static str {
        match reason {
            "no_mask" => "the runtime offers no visibility mask for the view: set mask.source = \"synthesized\" (or \"auto\")",
            _ => crate::core::stats::common_hint(reason),
        }
    }
    fn line(&self) -> String {
        MaskFrameStats::summary(self)
    }
    /// The mask's fields sit at the top level of the record (the first feature, kept as it was).
    fn json(&self, record: &mut serde_json::Map<String, serde_json::Value>) {
        record.insert("passes_masked".into(), self.passes_masked.into());
        record.insert("mask_by_source".into(), json_counts(self.by_source.iter().map(|(k, v)| (*k, *v))));
        record.insert("not_masked".into(), json_counts(self.not_masked.iter().map(|(k, v)| (*k, *v))));
        record.insert("pixels_masked".into(), json_counts(self.pixels_masked.iter().map(|(k, v)| (*k, *v))));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stats_add_and_summarise() {
        let mut a = MaskFrameStats { passes_masked: 2, ..Default::default() };
        a.pixels_masked.insert(0, 10);
        a.count_not_masked(NotMasked::NoDepthAttachment);
        let mut b = MaskFrameStats::default();
        b.add(&a);
        b.add(&a);
        assert_eq!(b.passes_masked, 4);
        assert_eq!(b.pixels_masked[&0], 20);
        assert_eq!(b.summary(), "masked_passes=4 masked_pixels=20 not_masked.no_depth_attachment=2");
        let names: std::collections::BTreeSet<_> = NotMasked::ALL.iter().map(|n| n.name()).collect();
        assert_eq!(names.len(), NotMasked::ALL.len());
    }
}
