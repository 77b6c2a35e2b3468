//! Frame entry points. `xrEndFrame` is where the layer learns which swapchain shows which eye: the
//! submitted projection views are read here and published for the Vulkan half.

use crate::features::overlay::OverlaySettings;
use crate::features::mask::MaskSettings;
use crate::features::foveation::FoveationSettings;
use crate::features::far_field::FarFieldSettings;
use super::session;
use crate::core::guard;
use crate::bridge;
use crate::core::views::ImageRect;
use crate::bridge::eye_uses::{self, SubImage, SubmittedView};
use openxr_sys as xr;
use openxr_sys::Handle as _;
use std::sync::atomic::Ordering;

pub(super) unsafe extern "system" fn begin_frame(session: xr::Session, frame_begin_info: *const xr::FrameBeginInfo) -> xr::Result {
    let inst = match session::lookup(session) {
        Ok(s) => s.instance.clone(),
        Err(Some(inst)) => inst,
        Err(None) => return xr::Result::ERROR_HANDLE_INVALID,
    };
    let Some(next) = inst.next.begin_frame else { return xr::Result::ERROR_FUNCTION_UNSUPPORTED };
    // SAFETY: forwarding the app's arguments unchanged.
    let plain = || unsafe { next(session, frame_begin_info) };
    let sess = session::lookup(session).ok();
    guard::run("xrBeginFrame", &inst.pass_through, |down| {
        inst.check_fault("xrBeginFrame")?;
        let r = down.call(plain);
        // The app records its eye passes after this; masks must be there by then.
        if let (Some(s), true) = (&sess, r.into_raw() >= 0) {
            for f in crate::registry::XR_FEATURES {
                f.frame_begun(s);
            }
        }
        Ok(r)
    }, plain)
}

/// Closes the frame's statistics: what the Vulkan half did since the last `xrEndFrame`, under the
/// configuration that was live while the frame was recorded (reloads apply after this).
fn write_frame_stats(inst: &super::Instance, session: Option<&session::Session>, frame: u64) {
    let stats = crate::vk::take_frame_stats();
    let settings = super::settings(inst);
    let fovea = bridge::shared().foveation().views.clone();
    let fovea_source = if fovea.is_empty() {
        None
    } else {
        session::sessions()
            .values()
            .into_iter()
            .find_map(|(_, s)| *s.feature::<crate::features::foveation::xr::FoveationSession>().gaze.source.lock().unwrap_or_else(|e| e.into_inner()))
            .or(Some(crate::features::foveation::rules::CenterSource::Fixed))
            .map(|src| format!("{src:?}"))
    };
    let vulkan_half = session.map(|s| s.vulkan_half);
    let record = crate::report::stats_file::FrameRecord {
        frame,
        time: std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0.0, |d| d.as_secs_f64()),
        mask_enabled: settings.of::<MaskSettings>().enabled,
        foveation_enabled: settings.of::<FoveationSettings>().enabled,
        far_field_enabled: settings.of::<FarFieldSettings>().enabled,
        overlay_enabled: settings.of::<OverlaySettings>().enabled,
        stats,
        fovea,
        fovea_source,
        vulkan_half,
        gpu_ms: None,
        upscale: bridge::shared().take_upscale(),
        extra: session.map(|s| crate::registry::XR_FEATURES.iter().flat_map(|f| f.frame_stats(s)).collect()).unwrap_or_default(),
    };
    if let Some(s) = session {
        let enabled = crate::registry::enabled(&settings, &record.stats);
        for w in s.summary.lock().unwrap_or_else(|e| e.into_inner()).add_frame(&enabled, &record.stats) {
            tracing::warn!("{w}");
        }
        super::overlay::frame_ended(s, &settings, &record, &shown(&enabled, &record));
    }
    if frame == 0 || !record.stats.is_empty() {
        tracing::debug!("frame stats: {}", record.to_json());
    }
    // `stats.gpu_time`: the GPU work submitted since the last frame end is this frame's; the
    // times that came back meanwhile (usually of earlier frames) go to their own lines.
    let times = crate::vk::end_gpu_frame(frame);
    let streams = session.map(|s| crate::registry::XR_FEATURES.iter().filter_map(|f| f.stats_stream(s)).collect()).unwrap_or_default();
    let outputs = crate::report::stats_file::Outputs { stats_file: settings.stats_file.clone(), streams };
    crate::report::stats_file::sink().frame(outputs, record, settings.stats_gpu_time, &times);
}

/// What the overlay names as on: the Vulkan features, then the upscale and the view tricks, which
/// change no app pass and are told by the frame's record.
fn shown(enabled: &[(&'static str, bool)], record: &crate::report::stats_file::FrameRecord) -> Vec<(&'static str, bool)> {
    let extra = |key: &str| record.extra.iter().find(|(k, _)| *k == key).map(|(_, v)| v);
    let mut v = enabled.to_vec();
    v.push(("upscale", record.upscale.is_some()));
    v.push(("fov_cut", extra("view_fov_cut").and_then(|v| v.as_bool()) == Some(true)));
    v.push(("symmetric", extra("view_symmetric").and_then(|v| v.as_str()).is_some_and(|m| m != "off")));
    v.push(("parallel", extra("view_parallel").and_then(|v| v.as_bool()) == Some(true)));
    v
}

/// Applies a changed config file from the next frame on (frame boundaries keep every frame's
/// work under one configuration).
fn reload_config(inst: &super::Instance) {
    let Some((config, diagnostics)) = inst.watch.poll() else { return };
    for d in &diagnostics {
        tracing::warn!("config: {d}");
    }
    let shared = bridge::shared();
    let old = shared.config().unwrap_or_else(|| inst.config.clone());
    let changed = crate::core::config::changed_keys(&old, &config);
    if changed.is_empty() {
        return;
    }
    tracing::info!("config reloaded, changed: {changed:?} (features apply from the next frame; `enabled` and `log.level` only at start)");
    for (_, s) in session::sessions().values() {
        for f in crate::registry::XR_FEATURES {
            f.config_reloaded(&s, &changed);
        }
    }
    super::publish_config(std::sync::Arc::new(config));
}

fn sub_image(s: &xr::SwapchainSubImage) -> SubImage {
    SubImage {
        swapchain: s.swapchain.into_raw(),
        image_rect: ImageRect {
            x: s.image_rect.offset.x,
            y: s.image_rect.offset.y,
            width: s.image_rect.extent.width,
            height: s.image_rect.extent.height,
        },
        image_array_index: s.image_array_index,
    }
}

/// Reads the FOVs of the first projection layer's views (tangents).
///
/// # Safety
/// As for `read_projection_layers`.
unsafe fn read_fovs(info: *const xr::FrameEndInfo) -> Option<Vec<crate::core::views::ViewFov>> {
    // SAFETY: per the caller's contract.
    unsafe {
        let info = info.as_ref()?;
        for i in 0..info.layer_count as usize {
            let base = (*info.layers.add(i)).as_ref()?;
            if base.ty == xr::StructureType::COMPOSITION_LAYER_PROJECTION {
                let proj = &*(base as *const xr::CompositionLayerBaseHeader as *const xr::CompositionLayerProjection);
                if proj.views.is_null() {
                    return None;
                }
                let views = std::slice::from_raw_parts(proj.views, proj.view_count as usize);
                return Some(views.iter().map(|v| session::fov_tangents(&v.fov)).collect());
            }
        }
        None
    }
}

/// Reads the depth range of the first projection view that carries `XrCompositionLayerDepthInfoKHR`.
///
/// # Safety
/// As for `read_projection_layers`.
unsafe fn read_depth_range(info: *const xr::FrameEndInfo) -> Option<crate::core::views::DepthRange> {
    // SAFETY: per the caller's contract, every non-null pointer is valid for its count.
    unsafe {
        let info = info.as_ref()?;
        if info.layers.is_null() {
            return None;
        }
        for i in 0..info.layer_count as usize {
            let base = (*info.layers.add(i)).as_ref()?;
            if base.ty != xr::StructureType::COMPOSITION_LAYER_PROJECTION {
                continue;
            }
            let proj = &*(base as *const xr::CompositionLayerBaseHeader as *const xr::CompositionLayerProjection);
            if proj.views.is_null() {
                return None;
            }
            for v in std::slice::from_raw_parts(proj.views, proj.view_count as usize) {
                let mut next = v.next as *const xr::BaseInStructure;
                while let Some(s) = next.as_ref() {
                    if s.ty == xr::StructureType::COMPOSITION_LAYER_DEPTH_INFO_KHR {
                        let d = &*(next as *const xr::CompositionLayerDepthInfoKHR);
                        return Some(crate::core::views::DepthRange { near_z: d.near_z, far_z: d.far_z, min_depth: d.min_depth, max_depth: d.max_depth });
                    }
                    next = s.next;
                }
            }
        }
        None
    }
}

/// Reads the projection layers of a frame. Anything malformed yields `None`: the runtime will
/// reject the frame, and the layer must not learn from it.
///
/// # Safety
/// `info` must be null or point to a frame end info whose pointers are valid as the app claims;
/// null and dangling-by-count cases are the runtime's to reject, so only null is checked here.
unsafe fn read_projection_layers(info: *const xr::FrameEndInfo) -> Option<Vec<Vec<SubmittedView>>> {
    // SAFETY: per the caller's contract, every non-null pointer is valid for its count.
    unsafe {
        let info = info.as_ref()?;
        if info.layer_count > 0 && info.layers.is_null() {
            return None;
        }
        let mut layers = Vec::new();
        for i in 0..info.layer_count as usize {
            let base = (*info.layers.add(i)).as_ref()?;
            if base.ty != xr::StructureType::COMPOSITION_LAYER_PROJECTION {
                continue;
            }
            let proj = &*(base as *const xr::CompositionLayerBaseHeader as *const xr::CompositionLayerProjection);
            if proj.view_count > 0 && proj.views.is_null() {
                return None;
            }
            let mut views = Vec::with_capacity(proj.view_count as usize);
            for v in std::slice::from_raw_parts(proj.views, proj.view_count as usize) {
                let mut depth = None;
                let mut next = v.next as *const xr::BaseInStructure;
                while let Some(s) = next.as_ref() {
                    if s.ty == xr::StructureType::COMPOSITION_LAYER_DEPTH_INFO_KHR {
                        depth = Some(sub_image(&(*(next as *const xr::CompositionLayerDepthInfoKHR)).sub_image));
                    }
                    next = s.next;
                }
                views.push(SubmittedView { color: sub_image(&v.sub_image), depth });
            }
            layers.push(views);
        }
        Some(layers)
    }
}

pub(super) unsafe extern "system" fn end_frame(session: xr::Session, frame_end_info: *const xr::FrameEndInfo) -> xr::Result {
    let (inst, known) = match session::lookup(session) {
        Ok(s) => (s.instance.clone(), true),
        Err(Some(inst)) => (inst, false),
        Err(None) => return xr::Result::ERROR_HANDLE_INVALID,
    };
    let Some(next) = inst.next.end_frame else { return xr::Result::ERROR_FUNCTION_UNSUPPORTED };
    // SAFETY: forwarding the app's arguments unchanged.
    let plain = || unsafe { next(session, frame_end_info) };
    guard::run("xrEndFrame", &inst.pass_through, |down| {
        inst.check_fault("xrEndFrame")?;
        // Read before calling down: the app's structs are only guaranteed valid during the call.
        // SAFETY: the app's frame end info, valid for this call (null is handled).
        let layers = if known { unsafe { read_projection_layers(frame_end_info) } } else { None };
        // SAFETY: as above.
        let fovs = if known { unsafe { read_fovs(frame_end_info) } } else { None };
        // SAFETY: as above.
        let depth_range = if known { unsafe { read_depth_range(frame_end_info) } } else { None };
        // What the app rendered (above) is what the Vulkan half works with; a feature may give the
        // runtime an amended frame.
        // SAFETY: the app's frame end info, valid for this call (null is handled).
        let app_info = unsafe { frame_end_info.as_ref() };
        let amended = match (session::lookup(session), app_info) {
            (Ok(s), Some(info)) => crate::registry::XR_FEATURES.iter().find_map(|f| f.amend_frame_end(&s, info)),
            _ => None,
        };
        // The upscale: held images upscaled and released, interposed rects in display pixels
        // (over the features' amendment, which it keeps alive).
        let upscaled = match (session::lookup(session), amended.as_ref().map(|a| a.info).or(app_info.copied())) {
            (Ok(s), Some(info)) => {
                let scs = super::swapchain::interposed_of(&s);
                let scs: Vec<_> = scs.iter().filter_map(|(handle, sc)| sc.upscale.as_ref().map(|i| super::upscale::Interposing { handle: *handle, desc: &sc.desc, i })).collect();
                super::upscale::frame_end(&s, &info, &scs)
            }
            _ => None,
        };
        let amended = match upscaled {
            Some(u) => Some(crate::plugin::xr::AmendedFrameEnd { info: u.info, _keep: Box::new((u._keep, amended.map(|a| a._keep))) }),
            None => amended,
        };
        // The overlay's quad goes after the app's (or the amended) layers, in a new array: the
        // app's own is never changed.
        let base = amended.as_ref().map(|a| a.info).or(app_info.copied());
        let quad = match (session::lookup(session), base) {
            (Ok(s), Some(b)) if b.layer_count == 0 || !b.layers.is_null() => {
                let settings = super::settings(&inst);
                super::overlay::quad(&s, &settings, b.layer_count, &|| crate::registry::enabled(&settings, &crate::registry::empty_stats()))
            }
            _ => None,
        };
        let with_overlay = quad.as_ref().zip(base).map(|(q, b)| {
            // SAFETY: the frame's layer pointers, valid for this call (non-null when counted, checked above).
            let mut layers: Vec<*const xr::CompositionLayerBaseHeader> = unsafe { crate::plugin::vk::convert::slice(b.layers, b.layer_count) }.to_vec();
            layers.push((q as *const xr::CompositionLayerQuad).cast());
            (layers, b)
        });
        let with_overlay = with_overlay.map(|(layers, b)| {
            let info = xr::FrameEndInfo { layer_count: layers.len() as u32, layers: layers.as_ptr(), ..b };
            (info, layers)
        });
        let call_app = |down: &mut guard::Down<xr::Result>| match &amended {
            // SAFETY: the app's frame with only the feature's changes; it lives until the call returns.
            Some(a) => down.call(|| unsafe { next(session, &a.info) }),
            None => down.call(plain),
        };
        let r = match &with_overlay {
            Some((info, _layers)) => {
                // SAFETY: the frame with the overlay's quad appended; `_layers` and the quad live
                // until the call returns.
                let r = down.call(|| unsafe { next(session, info) });
                if r.into_raw() < 0 && r != xr::Result::ERROR_SESSION_LOST && r != xr::Result::ERROR_INSTANCE_LOST {
                    // The runtime refused the frame with the quad: the app's frame goes down as it
                    // was, and the overlay stays off.
                    if let Ok(s) = session::lookup(session) {
                        super::overlay::refused(&s, r);
                    }
                    call_app(down)
                } else {
                    r
                }
            }
            None => call_app(down),
        };
        if r != xr::Result::SUCCESS {
            return Ok(r);
        }
        let frame = inst.stats.frames_ended.fetch_add(1, Ordering::Relaxed);
        write_frame_stats(&inst, session::lookup(session).ok().as_deref(), frame);
        reload_config(&inst);
        let shared = bridge::shared();
        if let Some(range) = depth_range {
            shared.update_far_field(|f| f.depth = Some(range));
        }
        if let (Some(fovs), Ok(s)) = (fovs, session::lookup(session)) {
            s.fov_submitted.store(true, Ordering::Release);
            shared.update_views(None, Some(fovs));
        }
        let Some(layers) = layers else { return Ok(r) };
        for (swapchain, uses) in eye_uses::eye_uses(&layers) {
            let Some(sc) = shared.swapchains.get(swapchain) else { continue };
            if sc.set_uses(uses.clone()) {
                inst.stats.eye_use_changes.fetch_add(1, Ordering::Relaxed);
                tracing::info!("swapchain {swapchain:#x} now shows {uses:?}");
            }
        }
        Ok(r)
    }, plain)
}
