//! Typed settings: every key the layer acts on, parsed once per configuration (re)load into plain
//! fields and shared as an `Arc`, so a misspelt key is a compile error and the hot paths (pass
//! begin, depth clear, transfers) neither look strings up nor take the configuration lock.
//!
//! The OpenXR half publishes the live settings (`publish`) when it resolves or reloads the
//! configuration; `current` costs one atomic load per call and reads a per-thread copy that is
//! refreshed only after a publish.
#![forbid(unsafe_code)]

use crate::core::config::Config;
use crate::core::parts::{Part, Parts};
use std::cell::RefCell;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, RwLock};

/// `vulkan.fragment_shading_rate`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FsrSetting {
    Auto,
    On,
    Off,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Settings {
    /// The master switch (`enabled`); only read at startup.
    pub enabled: bool,
    /// `mask.intermediate` != off: eye passes include intermediate targets copied 1:1 into a
    /// swapchain image (shared by every feature's eye-pass test).
    pub intermediate: bool,
    /// `eyes.walk`: the data-flow walk runs at submissions.
    pub eyes_walk: bool,
    /// `eyes.fallback = size` with its `eyes.fallback_order`; None when off.
    pub eyes_fallback: Option<crate::track::fallback::Order>,
    pub fragment_shading_rate: FsrSetting,
    pub stats_file: String,
    /// `stats.gpu_time`: the submit hooks bracket submissions with timestamps (`plugin::vk::gpu_time`).
    pub stats_gpu_time: bool,
    /// `debug.fail_in`, split.
    pub fail_in: Vec<String>,
    /// Every feature's own settings, by type (the registry, `src/registry.rs`, adds one per feature).
    pub features: Parts,
}

impl Settings {
    /// The chassis' settings from `c`, with no feature's: the registry adds those
    /// (`Settings::from_config`).
    pub fn chassis(c: &Config) -> Settings {
        Settings {
            enabled: c.enabled(),
            intermediate: c.choice("mask.intermediate") != "off",
            eyes_walk: c.bool("eyes.walk"),
            eyes_fallback: (c.choice("eyes.fallback") == "size").then(|| {
                if c.choice("eyes.fallback_order") == "RL" {
                    crate::track::fallback::Order::RightLeft
                } else {
                    crate::track::fallback::Order::LeftRight
                }
            }),
            fragment_shading_rate: match c.choice("vulkan.fragment_shading_rate") {
                "on" => FsrSetting::On,
                "off" => FsrSetting::Off,
                _ => FsrSetting::Auto,
            },
            stats_file: c.text("stats.file").to_string(),
            stats_gpu_time: c.bool("stats.gpu_time"),
            fail_in: c.text("debug.fail_in").split(',').map(|s| s.trim().to_string()).filter(|s| !s.is_empty()).collect(),
            features: Parts::default(),
        }
    }

    /// A feature's own settings. `Settings::from_config` (the registry) adds every registered
    /// feature's, so a missing one is a registry error (its unit test checks every feature).
    pub fn of<T: Part>(&self) -> &T {
        self.features.get::<T>().unwrap_or_else(|| panic!("no {} in the settings: the feature is not registered", std::any::type_name::<T>()))
    }

    /// `debug.fail_in` names `call`.
    pub fn fails_in(&self, call: &str) -> bool {
        !self.fail_in.is_empty() && self.fail_in.iter().any(|c| c == call)
    }
}

static PUBLISHED: RwLock<Option<Arc<Settings>>> = RwLock::new(None);
static GENERATION: AtomicU64 = AtomicU64::new(0);

thread_local! {
    static CACHED: RefCell<(u64, Option<Arc<Settings>>)> = const { RefCell::new((0, None)) };
}

/// Makes `s` the live settings of the process (the OpenXR half, at instance creation and reload).
pub fn publish(s: Settings) {
    *PUBLISHED.write().unwrap_or_else(|e| e.into_inner()) = Some(Arc::new(s));
    GENERATION.fetch_add(1, Ordering::Release);
}

/// The live settings, or None before the OpenXR half published any (a Vulkan-only process then
/// uses its device's own).
pub fn current() -> Option<Arc<Settings>> {
    let generation = GENERATION.load(Ordering::Acquire);
    if generation == 0 {
        return None;
    }
    CACHED.with(|c| {
        let mut c = c.borrow_mut();
        if c.0 != generation {
            *c = (generation, PUBLISHED.read().unwrap_or_else(|e| e.into_inner()).clone());
        }
        c.1.clone()
    })
}
