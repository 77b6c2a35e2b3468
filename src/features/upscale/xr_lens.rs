//! The upscale's knowledge of the lens (`upscale.skip_hidden`): each view's hidden-area mesh from
//! the runtime (`XR_KHR_visibility_mask`, fetched when a session first needs it and again after
//! the runtime says it changed), and per projection view's display-size rect and angles the tile
//! classes `lens` computes, kept while they apply. Only the runtime's own mesh
//! counts: it is what the runtime says the lens never shows (a mesh synthesized from config is a
//! guess, and the mask feature's business).

use crate::plugin::xr::{fov_tangents, Session};
use crate::core::rect::PixelRect;
use super::{gpu, lens};
use openxr_sys as xr;
use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex, MutexGuard};

/// Views whose meshes are fetched (`XR_VIEW_CONFIGURATION_TYPE_PRIMARY_STEREO`).
const VIEWS: u32 = 2;

/// Distinct (view, rect size, angles) whose classes are kept. A runtime whose angles change
/// every frame would otherwise cost a classification per frame: past this many, the session
/// stops skipping (logged).
const MAX_KEPT: usize = 16;

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// View, destination size, the app's angles, and the runtime's view (tangents and turn) that the
/// app's view is reframed from.
type Key = (u32, (u32, u32), [u32; 4], [u32; 8]);

/// A session's lens state.
#[derive(Default)]
pub(crate) struct LensCache {
    inner: Mutex<Inner>,
}

#[derive(Default)]
struct Inner {
    /// The instance's visibility-mask events seen when the meshes were fetched.
    events: Option<u64>,
    /// Per view, its hidden triangles (None: the runtime has none).
    meshes: Vec<Option<Arc<Vec<[f32; 2]>>>>,
    tiles: Vec<(Key, Option<Arc<lens::Tiles>>)>,
    /// Too many distinct keys: nothing is skipped any more in this session.
    given_up: bool,
}

impl LensCache {
    /// The tile classes of projection view `view` shown at `dst` with `fov` (the angles the app
    /// submitted); None: nothing is skipped there.
    pub(crate) fn tiles(&self, s: &Session, view: u32, fov: &xr::Fovf, dst: PixelRect) -> Option<Arc<lens::Tiles>> {
        if view >= VIEWS {
            return None;
        }
        let events = s.instance.stats.visibility_mask_events.load(Ordering::Relaxed);
        let fov_tan = fov_tangents(fov);
        // The runtime's own view, where the app's differs from it (view tricks: docs/views.md).
        let shared = crate::bridge::shared().views();
        let runtime = shared.runtime_fovs.get(view as usize).copied().unwrap_or(fov_tan);
        let turn = shared.runtime_turns.get(view as usize).copied().flatten();
        let [tx, ty, tz, tw] = turn.unwrap_or([0.0, 0.0, 0.0, 1.0]);
        let reframe = [runtime.tan_left, runtime.tan_right, runtime.tan_up, runtime.tan_down, tx, ty, tz, tw].map(f32::to_bits);
        let key: Key = (view, (dst.width, dst.height), [fov.angle_left, fov.angle_right, fov.angle_up, fov.angle_down].map(f32::to_bits), reframe);
        let stale = {
            let g = lock(&self.inner);
            if g.given_up {
                return None;
            }
            if g.events == Some(events) {
                if let Some((_, t)) = g.tiles.iter().find(|(k, _)| *k == key) {
                    return t.clone();
                }
            }
            g.events != Some(events)
        };
        if stale {
            // Fetched with no lock of the layer's held: the call goes down to the runtime.
            let meshes: Vec<_> = (0..VIEWS).map(|v| s.runtime_mask(v).map(Arc::new)).collect();
            let mut g = lock(&self.inner);
            *g = Inner { events: Some(events), meshes, tiles: Vec::new(), given_up: false };
        }
        let mesh = lock(&self.inner).meshes.get(view as usize).cloned().flatten();
        // Classified with no lock held (a few milliseconds for an Index eye).
        let tiles = mesh
            .and_then(|m| lens::tiles(&crate::core::reframe::in_app_view(&m, &runtime, turn, &fov_tan), &fov_tan, (dst.width, dst.height), gpu::GROUP))
            .map(Arc::new);
        if let Some(t) = &tiles {
            tracing::info!(
                "upscale: view {view} at {}x{}: the lens never shows {:.1} % of the upscale's {}x{} tiles; they are skipped",
                dst.width,
                dst.height,
                100.0 * t.skipped_share(),
                t.cols,
                t.rows
            );
        }
        let mut g = lock(&self.inner);
        if g.tiles.len() >= MAX_KEPT {
            tracing::warn!("upscale: the views' angles or sizes keep changing ({MAX_KEPT} seen); the pixels the lens never shows are upscaled from now on");
            g.given_up = true;
            g.tiles.clear();
            return None;
        }
        g.tiles.push((key, tiles.clone()));
        tiles
    }
}
