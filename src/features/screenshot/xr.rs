//! Screenshots on the OpenXR side: where a screenshot is asked for and which frame it is. At
//! `xrBeginFrame` (at most every `rules::TRIGGER_INTERVAL_NS`) the layer looks for this process's
//! trigger file in the runtime folder (`stereoshim screenshot` writes it) and at the configured
//! `screenshot.trigger`; a request arms the frame being begun on the session's device
//! (`vk::request`), whose images are then copied as they are released, and the next
//! `xrBeginFrame` closes it (`vk::frame_begun`). The session announces itself with an instance
//! file (`<pid>.json`) for the command to find, removed when the session ends.

use crate::features::screenshot::ScreenshotSettings;
use super::rules::{self, TouchWatch};
use super::vk::{self as shot_vk, Request, Requested};
use crate::plugin::settings::Settings;
use crate::plugin::xr::{Session, XrFeature};
use openxr_sys as xr;
use std::path::PathBuf;
use std::sync::atomic::Ordering;
use std::sync::{Mutex, OnceLock};
use std::time::{Instant, SystemTime};

/// The screenshot's OpenXR half (stateless; per-session state is `ScreenshotSession`).
pub(crate) struct ScreenshotXr;

/// One session's trigger watch.
#[derive(Debug, Default)]
pub(crate) struct ScreenshotSession {
    watch: Mutex<Watch>,
}

#[derive(Debug, Default)]
struct Watch {
    /// The runtime folder, once made (None before, or when it could not be: then only
    /// `screenshot.trigger` works).
    folder: Option<PathBuf>,
    folder_tried: bool,
    /// The instance file this session wrote.
    instance_file: Option<PathBuf>,
    last_look_ns: Option<u64>,
    touch: TouchWatch,
    /// A touch of `screenshot.trigger` seen while a screenshot was still being written.
    touch_pending: bool,
    /// A frame is armed on the device (closed at the next `xrBeginFrame`).
    armed: bool,
    /// The request last said to wait (logged once per request).
    waiting_logged: Option<u64>,
}

impl Drop for ScreenshotSession {
    fn drop(&mut self) {
        let w = self.watch.get_mut().unwrap_or_else(|e| e.into_inner());
        if let Some(f) = w.instance_file.take() {
            let _ = std::fs::remove_file(f);
        }
    }
}

fn env(k: &str) -> Option<String> {
    std::env::var(k).ok()
}

/// Nanoseconds on a monotonic clock (since the first call).
fn now_ns() -> u64 {
    static START: OnceLock<Instant> = OnceLock::new();
    START.get_or_init(Instant::now).elapsed().as_nanos() as u64
}

fn mtime_ns(path: &str) -> Option<u128> {
    let m = std::fs::metadata(path).ok()?.modified().ok()?;
    m.duration_since(SystemTime::UNIX_EPOCH).ok().map(|d| d.as_nanos())
}

impl XrFeature for ScreenshotXr {
    fn id(&self) -> &'static str {
        "screenshot"
    }
    /// The copy reads the swapchain image: TRANSFER_SRC on colour swapchains whenever screenshots
    /// may be asked for (an extra usage bit changes nothing the app can see).
    fn swapchain_usage(&self, s: &Settings, usage: xr::SwapchainUsageFlags) -> xr::SwapchainUsageFlags {
        if s.enabled && s.of::<ScreenshotSettings>().enabled && usage.contains(xr::SwapchainUsageFlags::COLOR_ATTACHMENT) {
            xr::SwapchainUsageFlags::TRANSFER_SRC
        } else {
            xr::SwapchainUsageFlags::EMPTY
        }
    }
    fn frame_begun(&self, s: &Session) {
        let Some(binding) = s.binding else { return };
        // The frame being begun is the one the next xrEndFrame submits: the runtime's count.
        let frame = s.instance.stats.frames_ended.load(Ordering::Relaxed);
        let mut w = s.feature::<ScreenshotSession>().watch.lock().unwrap_or_else(|e| e.into_inner());
        if w.armed {
            w.armed = shot_vk::frame_begun(binding.device_key, frame);
        }
        let settings = crate::plugin::xr::settings(&s.instance);
        if !(settings.enabled && settings.of::<ScreenshotSettings>().enabled) {
            return;
        }
        let now = now_ns();
        if !rules::trigger_due(w.last_look_ns, now) {
            return;
        }
        w.last_look_ns = Some(now);
        if !w.folder_tried {
            w.folder_tried = true;
            register(&mut w, &s.instance.app_name);
        }
        // This process's trigger file (`stereoshim screenshot`), then the configured touch file.
        let pid = std::process::id();
        let file = w.folder.as_ref().map(|f| rules::trigger_file(f, pid));
        let mut ask: Option<(u64, Option<PathBuf>)> = file.and_then(|f| std::fs::read_to_string(&f).ok().map(|t| (rules::request_number(&t), Some(f))));
        if !settings.of::<ScreenshotSettings>().trigger.is_empty() && w.touch.fired(mtime_ns(&settings.of::<ScreenshotSettings>().trigger)) {
            w.touch_pending = true;
        }
        if ask.is_none() && w.touch_pending {
            ask = Some((0, None));
        }
        let Some((token, trigger)) = ask else { return };
        if w.armed {
            return;
        }
        let request = Request {
            token,
            app: s.instance.app_name.clone(),
            dir: output_folder(&settings),
            done: w.folder.as_ref().map(|f| rules::done_file(f, pid)),
        };
        match shot_vk::request(binding.device_key, frame, request) {
            Requested::Armed => {
                w.armed = true;
                w.touch_pending = false;
                w.waiting_logged = None;
                if let Some(t) = trigger {
                    let _ = std::fs::remove_file(t);
                }
                tracing::info!("screenshot: taking frame {frame}");
            }
            Requested::Busy => {
                if w.waiting_logged != Some(token) {
                    w.waiting_logged = Some(token);
                    tracing::warn!("screenshot: the previous screenshot is still being encoded; this one is taken once it is written");
                }
            }
            Requested::NoDevice => {
                tracing::warn!("screenshot: the session's Vulkan device is not tracked by the layer; no screenshot");
                w.touch_pending = false;
                if let Some(t) = trigger {
                    let _ = std::fs::remove_file(t);
                }
            }
        }
    }
}

/// Makes the runtime folder and writes this session's instance file; logs why not otherwise.
fn register(w: &mut Watch, app: &str) {
    let Some(base) = crate::manifests::private_fs::private_base(&env) else {
        tracing::warn!("screenshot: none of XDG_RUNTIME_DIR, XDG_STATE_HOME, HOME is set: `stereoshim screenshot` cannot reach this app");
        return;
    };
    let folder = match crate::manifests::private_fs::private_dir(&base, std::path::Path::new("stereoshim/screenshot")) {
        Ok(f) => f,
        Err(e) => {
            // The folder checks speak of manifests; the reason is what matters here.
            let e = e.to_string();
            let reason = e.split(": refusing").next().unwrap_or(&e);
            tracing::warn!("screenshot: no private runtime folder ({reason}): `stereoshim screenshot` cannot reach this app");
            return;
        }
    };
    let file = rules::instance_file(&folder, std::process::id());
    let json = serde_json::json!({ "pid": std::process::id(), "app": app });
    match crate::manifests::private_fs::write_private(&file, json.to_string().as_bytes()) {
        Ok(()) => w.instance_file = Some(file),
        Err(e) => tracing::warn!("screenshot: cannot write {}: {e}", file.display()),
    }
    w.folder = Some(folder);
}

/// `screenshot.dir`, else the XDG pictures folder (read when a screenshot is asked for).
fn output_folder(s: &Settings) -> Option<PathBuf> {
    let user_dirs = rules::user_dirs_file(&env).and_then(|p| std::fs::read_to_string(p).ok());
    rules::output_folder(&s.of::<ScreenshotSettings>().dir, &env, user_dirs.as_deref())
}
