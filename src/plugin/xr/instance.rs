//! An XR instance as features see it: what it was created with (the next layer's dispatch, the
//! configuration, the extensions), its traffic counters, and each feature's instance-level state
//! by type (made by the registry).

use super::next::Next;
use super::session::{sessions, Session};
use crate::core::config::Config;
use crate::core::parts::States;
use crate::core::guard::PassThrough;
use openxr_sys as xr;
use std::any::Any;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

/// Counters that show, in the log, that the layer really saw the app's traffic.
#[derive(Debug, Default)]
pub(crate) struct Stats {
    pub frames_ended: AtomicU64,
    pub swapchains_created: AtomicU64,
    pub swapchain_images: AtomicU64,
    pub eye_use_changes: AtomicU64,
    pub visibility_mask_events: AtomicU64,
}

impl Stats {
    pub(crate) fn line(&self) -> String {
        format!(
            "frames_ended={} swapchains_created={} swapchain_images={} eye_use_changes={} visibility_mask_events={}",
            self.frames_ended.load(Ordering::Relaxed),
            self.swapchains_created.load(Ordering::Relaxed),
            self.swapchain_images.load(Ordering::Relaxed),
            self.eye_use_changes.load(Ordering::Relaxed),
            self.visibility_mask_events.load(Ordering::Relaxed),
        )
    }
}

/// Per-instance state; creation data is immutable.
pub(crate) struct Instance {
    pub handle: xr::Instance,
    pub next: Next,
    /// The configuration at instance creation: decides what cannot change later (the master
    /// switch: hooks are handed out once; extensions). Features read the live one,
    /// `shared().config()`.
    pub config: Arc<Config>,
    pub pass_through: PassThrough,
    pub app_name: String,
    pub stats: Stats,
    /// Extensions the app enabled.
    pub app_extensions: Vec<String>,
    /// Extensions the layer enabled for itself; their functions and events stay hidden from the app.
    pub layer_extensions: Vec<String>,
    /// Extensions the app enabled that the runtime lacks and the layer implements itself
    /// (`XR_KHR_visibility_mask`: the lens the layer knows); they never reach the runtime.
    pub offered_extensions: Vec<String>,
    /// The config file, re-read when it changes; feature settings then apply from the next frame.
    pub watch: crate::core::config::Watch,
    /// Per view, the recommended size the app was told to render at when a feature scaled it
    /// after the view features (the upscale, latched for the instance's life); None while none
    /// does. The view features check the submitted sizes against it.
    pub told_sizes: Mutex<Option<Vec<(u32, u32)>>>,
    /// The features' per-instance state, one value per type (made by the registry).
    pub features: States,
}

impl Instance {
    /// The runtime's name for `system` (`xrGetSystemProperties`).
    pub fn system_name(&self, system: xr::SystemId) -> Option<String> {
        let f = self.next.get_system_properties?;
        // SAFETY: a zeroed output struct with its type set (every field is plain data).
        let mut p: xr::SystemProperties = unsafe { std::mem::zeroed() };
        p.ty = xr::SystemProperties::TYPE;
        // SAFETY: the instance's own system, an output struct of the right type.
        if unsafe { f(self.handle, system, &mut p) } != xr::Result::SUCCESS {
            return None;
        }
        // SAFETY: the runtime wrote a NUL-terminated name into the fixed array.
        let name = unsafe { std::ffi::CStr::from_ptr(p.system_name.as_ptr()) };
        Some(name.to_string_lossy().into_owned())
    }
    /// Whether the app (not only the layer) enabled `ext`.
    pub fn app_enabled(&self, ext: &str) -> bool {
        self.app_extensions.iter().any(|e| e == ext)
    }
    /// Whether the layer, not the runtime, implements `ext` for the app.
    pub fn offers(&self, ext: &str) -> bool {
        self.offered_extensions.iter().any(|e| e == ext)
    }
    /// Whether the layer enabled `ext` for itself or the app did.
    pub fn has_extension(&self, ext: &str) -> bool {
        self.app_enabled(ext) || self.layer_extensions.iter().any(|e| e == ext)
    }

    /// Layer logic of `call` fails on purpose when the config says so (`debug.fail_in`), to prove
    /// the fallback to pass-through end to end.
    pub(crate) fn check_fault(&self, call: &str) -> Result<(), crate::core::guard::Fault> {
        if self.config.fails_in(call) {
            return Err(crate::core::guard::Fault(format!("forced by debug.fail_in for {call}")));
        }
        Ok(())
    }

    /// A feature's own instance-level state. The registry makes every registered feature's, so a
    /// missing one is a registry error (its unit test checks every feature).
    pub(crate) fn feature<T: Any>(&self) -> &T {
        self.features.get::<T>().unwrap_or_else(|| panic!("no {} in the instance: the feature is not registered", std::any::type_name::<T>()))
    }

    /// The live sessions of this instance.
    pub(crate) fn sessions(&self) -> Vec<Arc<Session>> {
        sessions().values().into_iter().map(|(_, s)| s).filter(|s| s.instance.handle == self.handle).collect()
    }
}
