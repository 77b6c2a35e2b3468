//! The live channel's OpenXR half: at `xrBeginFrame` (at most every [`LOOK_EVERY`]) the session
//! announces itself once and looks at `top`'s heartbeat; while it is fresh, the frame's stats line
//! goes to the stream too (`XrFeature::stats_stream`). The announcement and the stream go when
//! the session ends.

use super::LiveSettings;
use crate::core::live;
use crate::plugin::xr::{Session, XrFeature};
use std::path::PathBuf;
use std::sync::Mutex;
use std::time::{Duration, Instant, SystemTime};

/// How often the heartbeat is looked at: a key press in `top` shows within a frame or two of this.
const LOOK_EVERY: Duration = Duration::from_millis(100);

/// The live channel's OpenXR half (stateless; per-session state is `LiveSession`).
pub(crate) struct LiveXr;

/// One session's announcement and watch state.
#[derive(Debug, Default)]
pub(crate) struct LiveSession {
    state: Mutex<State>,
}

#[derive(Debug, Default)]
struct State {
    /// The live folder, once made (None before, or when it could not be).
    folder: Option<PathBuf>,
    folder_tried: bool,
    announced: Option<PathBuf>,
    last_look: Option<Instant>,
    /// The stream file while `top` watches.
    stream: Option<PathBuf>,
}

impl Drop for LiveSession {
    fn drop(&mut self) {
        let st = self.state.get_mut().unwrap_or_else(|e| e.into_inner());
        for f in [st.announced.take(), st.stream.take()].into_iter().flatten() {
            let _ = std::fs::remove_file(f);
        }
        if let Some(folder) = &st.folder {
            let pid = std::process::id();
            let _ = std::fs::remove_file(live::stream_file(folder, pid));
            let _ = std::fs::remove_file(live::ab_file(folder, pid));
        }
    }
}

fn env(k: &str) -> Option<String> {
    std::env::var(k).ok()
}

impl XrFeature for LiveXr {
    fn id(&self) -> &'static str {
        "live"
    }

    fn frame_begun(&self, s: &Session) {
        let settings = crate::plugin::xr::settings(&s.instance);
        let mut st = s.feature::<LiveSession>().state.lock().unwrap_or_else(|e| e.into_inner());
        if !(settings.enabled && settings.of::<LiveSettings>().enabled) {
            if st.stream.take().is_some() {
                tracing::info!("live: live.enabled is off; no longer streaming to stereoshim top");
            }
            return;
        }
        let now = Instant::now();
        if st.last_look.is_some_and(|t| now.duration_since(t) < LOOK_EVERY) {
            return;
        }
        st.last_look = Some(now);
        if !st.folder_tried {
            st.folder_tried = true;
            announce(&mut st, &s.instance.app_name);
        }
        let Some(folder) = st.folder.clone() else { return };
        let pid = std::process::id();
        let watched = live::fresh(live::heartbeat_mtime(&folder, pid), SystemTime::now());
        match (watched, st.stream.is_some()) {
            (true, false) => {
                let stream = live::stream_file(&folder, pid);
                tracing::info!("live: stereoshim top is watching; each frame's stats line also goes to {}", stream.display());
                st.stream = Some(stream);
            }
            (false, true) => {
                tracing::info!("live: stereoshim top stopped watching (no heartbeat for {} s)", live::HEARTBEAT_FRESH.as_secs());
                if let Some(f) = st.stream.take() {
                    let _ = std::fs::remove_file(f);
                }
            }
            _ => {}
        }
    }

    fn stats_stream(&self, s: &Session) -> Option<PathBuf> {
        s.feature::<LiveSession>().state.lock().unwrap_or_else(|e| e.into_inner()).stream.clone()
    }
}

/// Makes the live folder and writes this process's announcement; logs why not otherwise.
fn announce(st: &mut State, app: &str) {
    let Some(base) = crate::manifests::private_fs::private_base(&env) else {
        tracing::warn!("live: none of XDG_RUNTIME_DIR, XDG_STATE_HOME, HOME is set: stereoshim top cannot find this app");
        return;
    };
    let rel = live::folder(std::path::Path::new(""));
    let folder = match crate::manifests::private_fs::private_dir(&base, &rel) {
        Ok(f) => f,
        Err(e) => {
            let e = e.to_string();
            let reason = e.split(": refusing").next().unwrap_or(&e);
            tracing::warn!("live: no private runtime folder ({reason}): stereoshim top cannot find this app");
            return;
        }
    };
    let pid = std::process::id();
    let exe = std::env::current_exe().ok().and_then(|p| p.file_name().map(|n| n.to_string_lossy().into_owned())).unwrap_or_default();
    let config = crate::core::config::default_path(&env).map(|p| p.display().to_string());
    let started = SystemTime::now().duration_since(SystemTime::UNIX_EPOCH).map(|d| d.as_secs_f64()).unwrap_or(0.0);
    let json = serde_json::json!({ "pid": pid, "app": app, "exe": exe, "config": config, "started": started });
    let file = live::announce_file(&folder, pid);
    match crate::manifests::private_fs::write_private(&file, json.to_string().as_bytes()) {
        Ok(()) => st.announced = Some(file),
        Err(e) => tracing::warn!("live: cannot write {}: {e}", file.display()),
    }
    st.folder = Some(folder);
}

