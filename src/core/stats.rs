//! The per-feature statistics registry: every feature keeps its own counters for the frame that is
//! being recorded, behind one trait, so the frame's record (`stats.file`), the device's stats line
//! and the never-silent notices handle any feature without naming it.
#![forbid(unsafe_code)]

use std::any::Any;
use std::fmt::Debug;

/// One feature's counters of one frame (or of a whole session, summed).
pub trait FeatureStats: Any + Debug + Send + Sync {
    /// The feature's registry id.
    fn id(&self) -> &'static str;
    /// What the user calls the feature in warnings.
    fn label(&self) -> &'static str;
    /// Features of one group are alternatives: a device uses at most one of them (e.g. the two
    /// foveation methods, chosen per device by `auto`).
    fn group(&self) -> Option<&'static str> {
        None
    }
    /// Adds another frame's (or device's) counters of the same feature; others are ignored.
    fn add(&mut self, other: &dyn FeatureStats);
    fn is_empty(&self) -> bool;
    /// Passes the feature applied to.
    fn passes(&self) -> u64;
    /// Passes (or images) it left alone, by reason name.
    fn not_applied(&self) -> Vec<(&'static str, u64)>;
    /// What the user can do about `reason` (reason names as in `stats.file`).
    fn hint(&self, reason: &str) -> &'static str;
    /// `key=value` pairs for the `vulkan device stats:` line.
    fn summary(&self) -> String;
    /// Writes the feature's fields into the frame's JSON record.
    fn write_json(&self, record: &mut serde_json::Map<String, serde_json::Value>);
    fn clone_box(&self) -> Box<dyn FeatureStats>;
    fn as_any(&self) -> &dyn Any;
    fn as_any_mut(&mut self) -> &mut dyn Any;
}

/// Every feature's counters, in registry order.
#[derive(Debug, Default)]
pub struct FrameStats {
    features: Vec<Box<dyn FeatureStats>>,
}

impl Clone for FrameStats {
    fn clone(&self) -> Self {
        FrameStats { features: self.features.iter().map(|f| f.clone_box()).collect() }
    }
}

impl FrameStats {
    pub fn new(features: Vec<Box<dyn FeatureStats>>) -> FrameStats {
        FrameStats { features }
    }
    pub fn iter(&self) -> impl Iterator<Item = &dyn FeatureStats> {
        self.features.iter().map(|f| f.as_ref())
    }
    /// The counters of the feature whose stats type is `T`.
    pub fn get<T: FeatureStats>(&self) -> Option<&T> {
        self.features.iter().find_map(|f| f.as_any().downcast_ref::<T>())
    }
    pub fn get_mut<T: FeatureStats>(&mut self) -> Option<&mut T> {
        self.features.iter_mut().find_map(|f| f.as_any_mut().downcast_mut::<T>())
    }
    /// Adds `other` feature by feature (a feature missing here is appended).
    pub fn add(&mut self, other: &FrameStats) {
        for o in &other.features {
            match self.features.iter_mut().find(|f| f.id() == o.id()) {
                Some(f) => f.add(o.as_ref()),
                None => self.features.push(o.clone_box()),
            }
        }
    }
    pub fn is_empty(&self) -> bool {
        self.features.iter().all(|f| f.is_empty())
    }
    /// The non-empty features' summaries, space separated.
    pub fn summary(&self) -> String {
        self.features.iter().filter(|f| !f.is_empty()).map(|f| f.summary()).collect::<Vec<_>>().join(" ")
    }
    pub fn write_json(&self, record: &mut serde_json::Map<String, serde_json::Value>) {
        for f in &self.features {
            f.write_json(record);
        }
    }
}

/// What a feature's statistics type says of itself. Every such type is a `FeatureStats` (the
/// type-erased form the frame record, the device line and the notices handle) through the one
/// implementation below, so a feature writes only what is its own.
pub trait Counters: Clone + Debug + Default + PartialEq + Send + Sync + 'static {
    /// The feature's registry id.
    const ID: &'static str;
    /// What the user calls the feature in warnings.
    const LABEL: &'static str;
    /// The group of alternatives the feature belongs to (`FeatureStats::group`).
    const GROUP: Option<&'static str> = None;
    /// Adds another frame's (or device's) counters of the feature.
    fn merge(&mut self, other: &Self);
    /// Passes the feature applied to.
    fn applied(&self) -> u64;
    /// Passes (or images) it left alone, by reason name.
    fn left_alone(&self) -> Vec<(&'static str, u64)>;
    /// What the user can do about `reason`; the reasons every feature may give are answered by
    /// `common_hint`.
    fn hint_for(&self, reason: &str) -> &'static str;
    /// `key=value` pairs for the `vulkan device stats:` line.
    fn line(&self) -> String;
    /// Writes the feature's fields into the frame's JSON record.
    fn json(&self, record: &mut serde_json::Map<String, serde_json::Value>);
}

impl<T: Counters> FeatureStats for T {
    fn id(&self) -> &'static str {
        T::ID
    }
    fn label(&self) -> &'static str {
        T::LABEL
    }
    fn group(&self) -> Option<&'static str> {
        T::GROUP
    }
    fn add(&mut self, other: &dyn FeatureStats) {
        if let Some(o) = other.as_any().downcast_ref::<T>() {
            self.merge(o);
        }
    }
    fn is_empty(&self) -> bool {
        *self == T::default()
    }
    fn passes(&self) -> u64 {
        self.applied()
    }
    fn not_applied(&self) -> Vec<(&'static str, u64)> {
        self.left_alone()
    }
    fn hint(&self, reason: &str) -> &'static str {
        self.hint_for(reason)
    }
    fn summary(&self) -> String {
        self.line()
    }
    fn write_json(&self, record: &mut serde_json::Map<String, serde_json::Value>) {
        self.json(record)
    }
    fn clone_box(&self) -> Box<dyn FeatureStats> {
        Box::new(self.clone())
    }
    fn as_any(&self) -> &dyn Any {
        self
    }
    fn as_any_mut(&mut self) -> &mut dyn Any {
        self
    }
}

/// What the user can do about a reason any feature may report (names as in `stats.file`); a
/// feature answers its own reasons first.
pub fn common_hint(reason: &str) -> &'static str {
    match reason {
        "eye_unknown" => {
            "the pass renders into an image the layer cannot tie to an eye: not a swapchain image, nor reached from one by \
             the data-flow walk (why is logged once as \"data-flow walk: …\"); frame 0 is always so, and frame 1 for targets only the walk finds. If no walk \
             reason is logged, the cause is unknown: report the app and runtime"
        }
        "no_depth_attachment" => "a pass into an eye's image has no depth buffer: an app that renders its eyes without depth (the mask and RDM need one), or a post-process pass before the data-flow walk has seen a frame",
        "shared_target" => "the app renders both eyes into one target, one after the other, each carried on by its own post chain: a pass into it gets the eye its own use reaches, known only from the data-flow walk of the submission that carries it; these passes were not reached by it",
        "rect_changing" => "the app draws its eyes into a sub-rect of its target that changes from frame to frame (dynamic resolution): the data-flow walk learns each frame's rect one frame late, so such passes are left alone until the rect holds still",
        "post_pass" => "a post-process pass (tonemap, upscale, TAA: its draws never test depth) writes the eye's image; the eye passes behind it are found by the data-flow walk and counted on their own: nothing to do",
        "depth_not_cleared" => "the app loads depth instead of clearing it: the layer cannot know the depth to fail against",
        "depth_clear_not_0_1" => "the app clears depth to a value other than 0 or 1: not supported",
        "secondary" => "the pass's contents are in secondary command buffers the layer could not reach",
        "unsupported" => "a pass shape the layer does not handle (e.g. per-view rects differing in one multiview pass), or a command buffer using state the layer cannot restore (see \"injection vetoed\" in this log)",
        "intermediate_off" => "the pass renders to an offscreen target: set mask.intermediate = \"on\" to include such passes",
        "layer_error" => "the layer could not create its objects on this device: see the errors above in this log",
        "device_lacks" => "the app's Vulkan device lacks a capability the layer's draw needs for this pass (named above in this log)",
        _ => "see docs/configuration.md",
    }
}

/// A reason → count map as a JSON object.
pub fn json_counts<K: ToString, I: IntoIterator<Item = (K, u64)>>(counts: I) -> serde_json::Value {
    serde_json::Value::Object(counts.into_iter().map(|(k, v)| (k.to_string(), v.into())).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Clone, Debug, Default, PartialEq)]
    struct Demo {
        passes: u64,
    }

    impl Counters for Demo {
        const ID: &'static str = "demo";
        const LABEL: &'static str = "demo feature";
        fn merge(&mut self, o: &Self) {
            self.passes += o.passes;
        }
        fn applied(&self) -> u64 {
            self.passes
        }
        fn left_alone(&self) -> Vec<(&'static str, u64)> {
            Vec::new()
        }
        fn hint_for(&self, _: &str) -> &'static str {
            ""
        }
        fn line(&self) -> String {
            format!("demo_passes={}", self.passes)
        }
        fn json(&self, record: &mut serde_json::Map<String, serde_json::Value>) {
            record.insert("demo".into(), self.passes.into());
        }
    }

    #[test]
    fn registry_adds_by_feature() {
        let mut a = FrameStats::new(vec![Box::new(Demo::default())]);
        assert!(a.is_empty());
        a.get_mut::<Demo>().unwrap().passes = 2;
        let mut total = FrameStats::default();
        total.add(&a);
        total.add(&a);
        assert_eq!(total.get::<Demo>().unwrap().passes, 4);
        assert_eq!(total.summary(), "demo_passes=4");
        let mut json = serde_json::Map::new();
        total.write_json(&mut json);
        assert_eq!(json["demo"], 4);
    }
}
