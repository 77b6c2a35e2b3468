//! The frame loop (xrWaitFrame / xrBeginFrame / xrEndFrame) with the spec's ordering rules, the
//! validation of submitted composition layers, and xrLocateViews from the HMD profile.

use std::sync::Arc;

use glam::Vec3;
use openxr_sys as xr;

use crate::capture::{self, SubmittedDepth, SubmittedLayer, SubmittedQuad, SubmittedView};
use crate::session::{self, Session};
use crate::space::{self, Pose};
use crate::swapchain::{self, Swapchain};
use crate::system::check_view_config;
use crate::util::{find_in_chain, guard, input, input_opt, output, two_call, XrResult};
use crate::EXT_DEPTH;

pub unsafe extern "system" fn xr_wait_frame(
    session: xr::Session,
    info: *const xr::FrameWaitInfo,
    state: *mut xr::FrameState,
) -> xr::Result {
    guard("xrWaitFrame", || {
        let s = session::get(session)?;
        s.fail_point("xrWaitFrame")?;
        // SAFETY: app pointers (the wait info may be NULL).
        let (_, out) = unsafe { (input_opt(info)?, output(state)?) };
        // The spec: "A subsequent xrWaitFrame call must block until the previous frame has been
        // begun with xrBeginFrame and must unblock independently of the corresponding call to
        // xrEndFrame". So an app may wait for frame N+1 on its pacing thread as soon as frame N is
        // begun (while N is still recorded and ended, tests/threads.rs), but a wait before that
        // blocks. A real runtime would block for ever; here a wait blocked for 10 s fails with
        // XR_ERROR_CALL_ORDER_INVALID (and says why), so an app waiting twice on one thread is a
        // test failure rather than a hung test.
        {
            let mut core = s.core.lock().unwrap();
            let limit = std::time::Instant::now() + std::time::Duration::from_secs(10);
            while core.running && core.waited.is_some() {
                let left = limit.saturating_duration_since(std::time::Instant::now());
                if left.is_zero() {
                    eprintln!("[mock-runtime] xrWaitFrame: blocked 10 s on the previous frame's xrBeginFrame (waited twice without beginning?)");
                    return Err(xr::Result::ERROR_CALL_ORDER_INVALID);
                }
                core = s.frame_begun.wait_timeout(core, left).unwrap().0;
            }
        }
        if let Some(period) = s.instance.cfg.pace {
            // Paced like a compositor: return at the next vsync; an app that falls behind gets
            // the next one after now (a missed frame), never a burst to catch up.
            let wake = {
                let mut core = s.core.lock().unwrap();
                let now = std::time::Instant::now();
                let wake = core.next_wake.filter(|w| *w > now).unwrap_or(now);
                core.next_wake = Some(wake + period);
                wake
            };
            std::thread::sleep(wake.saturating_duration_since(std::time::Instant::now()));
        }
        let mut core = s.core.lock().unwrap();
        if !core.running {
            return Err(xr::Result::ERROR_SESSION_NOT_RUNNING);
        }
        // The display clock advances one period per xrWaitFrame (wall-clock pacing is separate).
        let t = s.now(&core);
        core.waits += 1;
        core.waited = Some(t);
        out.predicted_display_time = xr::Time::from_nanos(t);
        out.predicted_display_period = xr::Duration::from_nanos(s.period());
        // A headless session (XR_MND_headless) never renders.
        out.should_render = (s.vk.is_some() && matches!(core.state, xr::SessionState::VISIBLE | xr::SessionState::FOCUSED)).into();
        Ok(xr::Result::SUCCESS)
    })
}

pub unsafe extern "system" fn xr_begin_frame(session: xr::Session, info: *const xr::FrameBeginInfo) -> xr::Result {
    guard("xrBeginFrame", || {
        let s = session::get(session)?;
        s.fail_point("xrBeginFrame")?;
        // SAFETY: app input struct (may be NULL).
        unsafe { input_opt(info) }?;
        if s.instance.cfg.reenter {
            if let Some(vk) = &s.vk {
                vk.reenter("xrBeginFrame", true)?;
            }
        }
        let mut core = s.core.lock().unwrap();
        if !core.running {
            return Err(xr::Result::ERROR_SESSION_NOT_RUNNING);
        }
        let t = core.waited.take().ok_or(xr::Result::ERROR_CALL_ORDER_INVALID)?;
        // An xrWaitFrame of the next frame may be blocked on this one being begun.
        s.frame_begun.notify_all();
        // A frame begun and never ended is discarded by the next begin.
        let discarded = core.begun.replace(t).is_some();
        Ok(if discarded { xr::Result::FRAME_DISCARDED } else { xr::Result::SUCCESS })
    })
}

fn check_sub_image(s: &Session, sub: &xr::SwapchainSubImage) -> XrResult<(Arc<Swapchain>, u32)> {
    let sc = swapchain::get(sub.swapchain)?;
    if sc.session != s.handle {
        return Err(xr::Result::ERROR_HANDLE_INVALID);
    }
    let released = sc.state.lock().unwrap().last_released.ok_or_else(|| {
        crate::log!("xrEndFrame: swapchain {} has no released image", sc.handle);
        xr::Result::ERROR_LAYER_INVALID
    })?;
    let r = sub.image_rect;
    let fits = r.offset.x >= 0
        && r.offset.y >= 0
        && r.extent.width > 0
        && r.extent.height > 0
        && r.offset.x as i64 + r.extent.width as i64 <= sc.width as i64
        && r.offset.y as i64 + r.extent.height as i64 <= sc.height as i64;
    if !fits {
        crate::log!("xrEndFrame: rect {r:?} outside {}x{}", sc.width, sc.height);
        return Err(xr::Result::ERROR_SWAPCHAIN_RECT_INVALID);
    }
    if sub.image_array_index >= sc.array_size {
        crate::log!("xrEndFrame: imageArrayIndex {} >= {}", sub.image_array_index, sc.array_size);
        return Err(xr::Result::ERROR_VALIDATION_FAILURE);
    }
    Ok((sc, released))
}

fn check_depth(s: &Session, d: &xr::CompositionLayerDepthInfoKHR) -> XrResult<SubmittedDepth> {
    let (sc, image_index) = check_sub_image(s, &d.sub_image)?;
    if !swapchain::is_depth(sc.format) {
        crate::log!("xrEndFrame: depth info references a colour swapchain");
        return Err(xr::Result::ERROR_VALIDATION_FAILURE);
    }
    let range_ok = (0.0..=1.0).contains(&d.min_depth) && (0.0..=1.0).contains(&d.max_depth) && d.min_depth < d.max_depth;
    // Reversed Z (near > far) and an infinite far plane are allowed; equal planes are not.
    let planes_ok = d.near_z != d.far_z && !d.near_z.is_nan() && !d.far_z.is_nan() && d.near_z >= 0.0 && d.far_z >= 0.0;
    if !range_ok || !planes_ok {
        crate::log!("xrEndFrame: bad depth info {}..{} near {} far {}", d.min_depth, d.max_depth, d.near_z, d.far_z);
        return Err(xr::Result::ERROR_VALIDATION_FAILURE);
    }
    Ok(SubmittedDepth {
        swapchain: sc,
        image_index,
        rect: d.sub_image.image_rect,
        array_index: d.sub_image.image_array_index,
        min_depth: d.min_depth,
        max_depth: d.max_depth,
        near_z: d.near_z,
        far_z: d.far_z,
    })
}

fn check_layer_flags(f: xr::CompositionLayerFlags) -> XrResult<()> {
    use xr::CompositionLayerFlags as F;
    let known = F::CORRECT_CHROMATIC_ABERRATION | F::BLEND_TEXTURE_SOURCE_ALPHA | F::UNPREMULTIPLIED_ALPHA;
    if (f & !known).is_empty() {
        Ok(())
    } else {
        Err(xr::Result::ERROR_VALIDATION_FAILURE)
    }
}

/// Validates one layer.
///
/// # Safety
/// `p` must point to a composition layer struct (or be NULL).
unsafe fn check_layer(s: &Session, p: *const xr::CompositionLayerBaseHeader) -> XrResult<SubmittedLayer> {
    if p.is_null() {
        return Err(xr::Result::ERROR_LAYER_INVALID);
    }
    // SAFETY: non-null layer header.
    let base = unsafe { &*p };
    match base.ty {
        xr::StructureType::COMPOSITION_LAYER_PROJECTION => {
            // SAFETY: its type says so.
            let l = unsafe { &*(p as *const xr::CompositionLayerProjection) };
            check_layer_flags(l.layer_flags)?;
            let sp = space::get_in(s, l.space)?;
            if l.view_count != 2 {
                crate::log!("xrEndFrame: projection layer with {} views", l.view_count);
                return Err(xr::Result::ERROR_VALIDATION_FAILURE);
            }
            // SAFETY: count/array from the app.
            let views = unsafe { crate::util::slice(l.views, l.view_count) }?;
            let mut out = Vec::new();
            for v in views {
                if v.ty != xr::CompositionLayerProjectionView::TYPE {
                    return Err(xr::Result::ERROR_VALIDATION_FAILURE);
                }
                Pose::from_xr(&v.pose)?;
                let (sc, image_index) = check_sub_image(s, &v.sub_image)?;
                if swapchain::is_depth(sc.format) {
                    return Err(xr::Result::ERROR_VALIDATION_FAILURE);
                }
                let mut depth = None;
                if s.instance.extension_enabled(EXT_DEPTH) {
                    // SAFETY: the app's chain on the view.
                    let d = unsafe { find_in_chain(v.next, xr::CompositionLayerDepthInfoKHR::TYPE) } as *const xr::CompositionLayerDepthInfoKHR;
                    if !d.is_null() {
                        // SAFETY: found with the depth-info type.
                        depth = Some(check_depth(s, unsafe { &*d })?);
                    }
                }
                out.push(SubmittedView { pose: v.pose, fov: v.fov, swapchain: sc, image_index, rect: v.sub_image.image_rect, array_index: v.sub_image.image_array_index, depth });
            }
            Ok(SubmittedLayer { kind: "projection", flags: l.layer_flags.into_raw(), space: sp.name(), views: out, quad: None })
        }
        xr::StructureType::COMPOSITION_LAYER_QUAD => {
            // SAFETY: its type says so.
            let l = unsafe { &*(p as *const xr::CompositionLayerQuad) };
            check_layer_flags(l.layer_flags)?;
            let sp = space::get_in(s, l.space)?;
            Pose::from_xr(&l.pose)?;
            if !matches!(l.eye_visibility, xr::EyeVisibility::BOTH | xr::EyeVisibility::LEFT | xr::EyeVisibility::RIGHT) {
                return Err(xr::Result::ERROR_VALIDATION_FAILURE);
            }
            if !(l.size.width > 0.0 && l.size.height > 0.0 && l.size.width.is_finite() && l.size.height.is_finite()) {
                crate::log!("xrEndFrame: quad size {}x{}", l.size.width, l.size.height);
                return Err(xr::Result::ERROR_VALIDATION_FAILURE);
            }
            let (sc, image_index) = check_sub_image(s, &l.sub_image)?;
            if swapchain::is_depth(sc.format) {
                return Err(xr::Result::ERROR_VALIDATION_FAILURE);
            }
            let quad = SubmittedQuad {
                pose: l.pose,
                size: [l.size.width, l.size.height],
                eye_visibility: l.eye_visibility.into_raw(),
                swapchain: sc,
                image_index,
                rect: l.sub_image.image_rect,
                array_index: l.sub_image.image_array_index,
            };
            Ok(SubmittedLayer { kind: "quad", flags: l.layer_flags.into_raw(), space: sp.name(), views: Vec::new(), quad: Some(quad) })
        }
        other => {
            crate::log!("xrEndFrame: unsupported layer type {other:?}");
            Err(xr::Result::ERROR_LAYER_INVALID)
        }
    }
}

pub unsafe extern "system" fn xr_end_frame(session: xr::Session, info: *const xr::FrameEndInfo) -> xr::Result {
    guard("xrEndFrame", || {
        let s = session::get(session)?;
        s.fail_point("xrEndFrame")?;
        // SAFETY: app input struct.
        let info = unsafe { input(info) }?;
        if s.instance.cfg.reenter {
            if let Some(vk) = &s.vk {
                vk.reenter("xrEndFrame", true)?;
            }
        }
        let frame = {
            let core = s.core.lock().unwrap();
            if !core.running {
                return Err(xr::Result::ERROR_SESSION_NOT_RUNNING);
            }
            let begun = core.begun.ok_or(xr::Result::ERROR_CALL_ORDER_INVALID)?;
            if info.display_time.as_nanos() != begun {
                crate::log!("xrEndFrame: displayTime {} != predicted {begun}", info.display_time.as_nanos());
                return Err(xr::Result::ERROR_TIME_INVALID);
            }
            core.frames_ended
        };
        if info.environment_blend_mode != xr::EnvironmentBlendMode::OPAQUE {
            return Err(xr::Result::ERROR_ENVIRONMENT_BLEND_MODE_UNSUPPORTED);
        }
        if info.layer_count > s.instance.cfg.max_layers {
            return Err(xr::Result::ERROR_LAYER_LIMIT_EXCEEDED);
        }
        // SAFETY: count/array from the app.
        let layer_ptrs = unsafe { crate::util::slice(info.layers, info.layer_count) }?;
        let mut layers = Vec::new();
        for &p in layer_ptrs {
            // SAFETY: the app's layer pointers.
            layers.push(unsafe { check_layer(&s, p) }?);
        }
        if s.instance.cfg.captures(frame) {
            capture::capture_frame(&s, frame, info.display_time.as_nanos(), info.environment_blend_mode.into_raw(), &layers)?;
        }
        if s.instance.cfg.crash_at == Some(frame) {
            crash_on_purpose(frame);
        }
        let mut core = s.core.lock().unwrap();
        core.begun = None;
        core.frames_ended += 1;
        let cfg = &s.instance.cfg;
        if cfg.exit_after.is_some_and(|n| core.frames_ended >= n) || cfg.exit_on.as_ref().is_some_and(|f| f.exists()) {
            s.stop(&mut core);
        }
        s.maybe_change_mask(&mut core);
        Ok(xr::Result::SUCCESS)
    })
}

/// The views of the active profile in `base` at display time `t_ns` (STAGE-relative head
/// composition; the head turns with `MOCK_XR_HEAD_YAW_DEG_PER_S`).
pub fn views_in(s: &Session, base: &Pose, t_ns: i64) -> [(Pose, [f32; 4]); 2] {
    let hmd = s.instance.cfg.hmd;
    let head = crate::space::head_pose_at(s.instance.cfg.head_yaw_deg_per_s, t_ns);
    let inv = base.inverse();
    [0, 1].map(|v| {
        let (p, q) = hmd.eye_in_head(v);
        let eye: Pose = head.mul(&Pose::new(p, q));
        (inv.mul(&eye), hmd.fov_rad(v))
    })
}

pub unsafe extern "system" fn xr_locate_views(
    session: xr::Session,
    info: *const xr::ViewLocateInfo,
    state: *mut xr::ViewState,
    capacity: u32,
    count_out: *mut u32,
    views: *mut xr::View,
) -> xr::Result {
    guard("xrLocateViews", || {
        let s = session::get(session)?;
        // SAFETY: app pointers.
        let (info, st) = unsafe { (input(info)?, output(state)?) };
        let base = space::get_in(&s, info.space)?;
        s.fail_point("xrLocateViews")?;
        check_view_config(info.view_configuration_type)?;
        if s.instance.cfg.reenter {
            if let Some(vk) = &s.vk {
                vk.reenter("xrLocateViews", false)?;
            }
        }
        if info.display_time.as_nanos() <= 0 {
            return Err(xr::Result::ERROR_TIME_INVALID);
        }
        if capacity > 0 && views.is_null() {
            return Err(xr::Result::ERROR_VALIDATION_FAILURE);
        }
        let base_pose = base.in_stage(&s);
        use xr::ViewStateFlags as V;
        let located = base_pose.map(|b| views_in(&s, &b, info.display_time.as_nanos()));
        st.view_state_flags = if located.is_some() {
            V::ORIENTATION_VALID | V::POSITION_VALID | V::ORIENTATION_TRACKED | V::POSITION_TRACKED
        } else {
            V::EMPTY
        };
        // SAFETY: app array of `capacity` views, each type-checked.
        unsafe {
            two_call(capacity, count_out, 2, |i| {
                let v = output(views.add(i))?;
                let (pose, [l, r, u, d]) = located.map(|l| l[i]).unwrap_or((Pose::new(Vec3::ZERO, glam::Quat::IDENTITY), s.instance.cfg.hmd.fov_rad(i)));
                v.pose = pose.to_xr();
                v.fov = xr::Fovf { angle_left: l, angle_right: r, angle_up: u, angle_down: d };
                Ok(())
            })
        }?;
        Ok(xr::Result::SUCCESS)
    })
}

/// `MOCK_XR_CRASH_AT`: dies by SIGSEGV inside the app's `xrEndFrame`, as a runtime or layer bug
/// would; not inlined, so the crash report's backtrace names it.
#[inline(never)]
fn crash_on_purpose(frame: u64) {
    crate::log!("xrEndFrame of frame {frame}: crashing on purpose (MOCK_XR_CRASH_AT)");
    let null = std::hint::black_box(std::ptr::null_mut::<u64>());
    // SAFETY: none: this write is meant to fault (SIGSEGV), which is all the function is for.
    unsafe { null.write_volatile(frame) };
}
