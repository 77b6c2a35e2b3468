//! xr-scene: a plain OpenXR + Vulkan stereo app, the unmodified subject of stereoshim's end-to-end
//! tests. `main` parses the command line and drives the session lifecycle; see docs/testing.md.

mod camera;
mod cli;
mod error;
mod gpu;
mod passes;
mod post;
mod quad;
mod renderer;
mod scene;
mod stats;
mod targets;
mod threads;
mod xr;

use error::{Ctx, Result};
use glam::{Mat4, Quat, Vec3, Vec4};
use openxr as oxr;
use std::process::ExitCode;

fn main() -> ExitCode {
    // clap prints the help (exit 0) or the usage error (exit 2) itself.
    let opts = cli::parse(std::env::args().skip(1)).unwrap_or_else(|e| e.exit());
    let result = run(&opts);
    // Everything is destroyed by now, so validation messages about teardown are counted too.
    let errors = gpu::validation_error_count();
    match result {
        Err(e) => {
            eprintln!("xr-scene: error: {e}");
            ExitCode::from(1)
        }
        Ok(frames) if errors > 0 => {
            eprintln!("xr-scene: {frames} frames, {errors} Vulkan validation error(s)");
            ExitCode::from(3)
        }
        Ok(frames) => {
            eprintln!("xr-scene: {frames} frames, clean shutdown");
            ExitCode::SUCCESS
        }
    }
}

/// Runs `--instances` times an XR instance with its Vulkan device and `--sessions` sessions;
/// returns the number of frames submitted.
fn run(opts: &cli::Options) -> Result<u64> {
    let mut frames = 0;
    for instance in 0..opts.instances {
        frames += run_instance(opts)?;
        if opts.instances > 1 {
            eprintln!("xr-scene: instance {instance} ended, rss {} kB", rss_kb().unwrap_or(0));
        }
    }
    Ok(frames)
}

/// `--temporary-session`: what xrizer does at an OpenVR game's `VR_Init`, before the game's first
/// submission hands it the game's device: a Vulkan instance and device made through the runtime,
/// a session on them, then the session, the device and the instance destroyed.
fn temporary_session(opts: &cli::Options, xri: &xr::XrInstance) -> Result<()> {
    let gpu = gpu::Gpu::new(opts, &xri.instance, xri.system)?;
    let binding = gpu.session_binding();
    // SAFETY: the handles come from the runtime's system; the session and its frame objects are
    // dropped (xrDestroySession) before the device and instance they use.
    let (session, waiter, stream) = unsafe { xri.instance.create_session::<oxr::Vulkan>(xri.system, &binding) }.ctx("xrCreateSession(temporary)")?;
    drop((stream, waiter, session));
    drop(gpu);
    eprintln!("xr-scene: temporary session made and destroyed");
    Ok(())
}

/// One XR instance, its Vulkan instance and device, and `--sessions` sessions, each until the
/// runtime ends it. Locals drop in reverse order: the Vulkan device/instance, then the XR instance.
fn run_instance(opts: &cli::Options) -> Result<u64> {
    let xri = xr::XrInstance::new(opts)?;
    if opts.temporary_session {
        temporary_session(opts, &xri)?;
    }
    let gpu = gpu::Gpu::new(opts, &xri.instance, xri.system)?;
    let mut stats = opts.stats.clone().map(stats::StatsLog::new);
    if let Some(dir) = &opts.pixel_stats {
        std::fs::create_dir_all(dir).map_err(|e| error::Error(format!("creating {}: {e}", dir.display())))?;
    }
    if let Some(s) = &stats {
        s.write()?;
    }
    let mut frame: u64 = 0;
    for session in 0..opts.sessions {
        let first = frame;
        let (next, mut errors) = run_session(opts, &xri, &gpu, &mut stats, frame, session + 1 == opts.sessions)?;
        frame = next;
        if !errors.is_empty() {
            // The runtime may still hold objects on the Vulkan device (a session it failed to
            // destroy): destroying the instance, which takes its children with it, comes first.
            errors.extend(xri.destroy().err().map(|e| e.0));
            drop(gpu);
            return error::fail(errors.join("; "));
        }
        if opts.sessions > 1 {
            // Between sessions, as an app waits before it tears down or rebuilds its rendering:
            // the fault layer's `VK_FAULT_COUNT` prints the live Vulkan objects at this call, when
            // the session and everything made for it are gone (tests/vk_objects.rs).
            // SAFETY: the device outlives the sessions; nothing else uses it on another thread.
            let _ = unsafe { gpu.device.device_wait_idle() };
            // What a leak across sessions would show: the process's resident memory after each
            // session's objects are gone (tests/lifecycle.rs).
            eprintln!("xr-scene: session {session} ended after {} frames, rss {} kB", frame - first, rss_kb().unwrap_or(0));
        }
    }
    if opts.teardown == cli::Teardown::Instance {
        // The runtime's objects on the device (the last session's swapchain images) go with the
        // XR instance; the app's Vulkan device after it.
        let r = xri.destroy();
        drop(gpu);
        r?;
    } else {
        drop(gpu);
        xri.destroy()?;
    }
    Ok(frame)
}

/// The process's resident set size (`VmRSS` of /proc/self/status), in kB.
fn rss_kb() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    status.lines().find_map(|l| l.strip_prefix("VmRSS:")).and_then(|v| v.split_whitespace().next()).and_then(|v| v.parse().ok())
}

/// One session until the runtime ends it, its frames numbered from `frame`; returns the next
/// frame number. Locals drop in reverse order: GPU objects, swapchains, session.
/// Also returns the session's teardown errors (failed `xrDestroySwapchain` / `xrDestroySession`).
/// `last`: the instance's last session (`--teardown instance` leaves it to `xrDestroyInstance`).
fn run_session(opts: &cli::Options, xri: &xr::XrInstance, gpu: &gpu::Gpu, stats: &mut Option<stats::StatsLog>, mut frame: u64, last: bool) -> Result<(u64, Vec<String>)> {
    let first_frame = frame;
    let binding = gpu.session_binding();
    // SAFETY: the handles come from the runtime's system and outlive the session (dropped later).
    let mut xs = unsafe { xr::XrSession::new(xri, binding) }?;
    let masks = if opts.visibility_mask { xs.fetch_visibility_masks()? } else { Vec::new() };
    let hidden_area = if opts.draw_hidden_area { masks } else { Vec::new() };
    let mut targets = targets::Targets::new(opts, gpu, xri, &xs)?;
    let mut renderer = renderer::Renderer::new(opts, gpu, &targets, &hidden_area)?;
    let quad = if opts.quad { Some(quad::Quad::new(gpu, &xs, targets.color_format, targets.views[0].extent)?) } else { None };
    // `--threads`: xrWaitFrame on the frame-pacing thread (dropped, and so joined, before the
    // session on every path; joined explicitly below).
    let mut pacer = threads::Pacer::new(&mut xs, opts.threads)?;
    let reversed = opts.depth == cli::DepthMode::Reverse;
    // CPU time in OpenXR calls per frame, kept until the frame's GPU work is measured (with
    // `--record-once` that is when its frame set is needed again, or at the end).
    let mut xr_us: std::collections::HashMap<u64, stats::CallTimes> = std::collections::HashMap::new();

    // What the last frame drew with (`--teardown in-flight` draws it once more).
    let mut last_uniforms = None;
    loop {
        if xs.poll_events(&xri.instance, &mut || pacer.stop())? == xr::Flow::Exit {
            break;
        }
        if !xs.running {
            // Idle/synchronized-but-not-ready: nothing to render, don't spin.
            std::thread::sleep(std::time::Duration::from_millis(5));
            continue;
        }
        // CPU time inside OpenXR calls, per call: what an API layer's overhead adds to.
        let mut calls = stats::CallTimes::default();
        let state = calls.time("xrWaitFrame", || pacer.wait(&mut xs))?;
        calls.time("xrBeginFrame", || xs.stream.begin()).ctx("xrBeginFrame")?;
        // `--threads`: the next frame's xrWaitFrame may start now (this frame is begun).
        pacer.begun()?;
        calls.time("xrSyncActions", || xs.sync_input(state.predicted_display_time))?;

        if !state.should_render {
            end_frame(xri, &xs, state.predicted_display_time, None, None)?;
        } else {
            let (_, views) = calls
                .time("xrLocateViews", || xs.session.locate_views(oxr::ViewConfigurationType::PRIMARY_STEREO, state.predicted_display_time, &xs.stage))
                .ctx("xrLocateViews")?;
            if views.len() != 2 {
                return error::fail(format!("xrLocateViews returned {} views", views.len()));
            }
            // `--widen-fov`: the app renders (and submits) more than it was given.
            let mut views = views;
            let widen = opts.widen_fov_deg.to_radians();
            for v in &mut views {
                v.fov.angle_left -= widen;
                v.fov.angle_right += widen;
                v.fov.angle_up += widen;
                v.fov.angle_down -= widen;
            }
            let mut acquired = Vec::new();
            for slot in &mut targets.slots {
                let color = match &mut slot.color.swapchain {
                    Some(sc) => {
                        let i = calls.time("xrAcquireSwapchainImage", || sc.acquire_image()).ctx("xrAcquireSwapchainImage")?;
                        calls.time("xrWaitSwapchainImage", || sc.wait_image(oxr::Duration::INFINITE)).ctx("xrWaitSwapchainImage")?;
                        i
                    }
                    None => shared_image(&acquired)?,
                };
                let depth = match &mut slot.depth {
                    Some(d) => {
                        let i = calls.time("xrAcquireSwapchainImage", || d.owned().acquire_image()).ctx("xrAcquireSwapchainImage(depth)")?;
                        calls.time("xrWaitSwapchainImage", || d.owned().wait_image(oxr::Duration::INFINITE)).ctx("xrWaitSwapchainImage(depth)")?;
                        Some(i)
                    }
                    None => None,
                };
                acquired.push(renderer::Acquired { color, depth });
            }
            let uniforms = frame_uniforms(&assumed(opts, &views), reversed, opts.animate, opts.far_movers, frame);
            let finished = renderer.render(gpu, &targets, &acquired, &uniforms, frame)?;
            last_uniforms = Some(uniforms);
            for slot in &mut targets.slots {
                if let Some(sc) = &mut slot.color.swapchain {
                    calls.time("xrReleaseSwapchainImage", || sc.release_image()).ctx("xrReleaseSwapchainImage")?;
                }
                if let Some(d) = &mut slot.depth {
                    calls.time("xrReleaseSwapchainImage", || d.owned().release_image()).ctx("xrReleaseSwapchainImage(depth)")?;
                }
            }
            calls.time("xrEndFrame", || end_frame(xri, &xs, state.predicted_display_time, Some((&targets, &views, reversed)), quad.as_ref()))?;
            xr_us.insert(frame, calls);
            push_stats(stats, &mut xr_us, finished)?;
        }
        frame += 1;
        if opts.frames.is_some_and(|n| frame - first_frame >= n) {
            xs.request_exit()?;
        } else if let Some(k) = opts.recreate_swapchains.filter(|k| (frame - first_frame).is_multiple_of(*k)) {
            // New swapchains of another size, as an app does when the user changes its render
            // scale: the old frames finish, everything sized by the swapchains is made again.
            let finished = renderer.finish()?;
            push_stats(stats, &mut xr_us, finished)?;
            drop(renderer);
            targets.destroy()?;
            let sized = cli::Options { scale: opts.scale * [1.0, 0.8, 1.2][((frame - first_frame) / k % 3) as usize], ..opts.clone() };
            targets = targets::Targets::new(&sized, gpu, xri, &xs)?;
            renderer = renderer::Renderer::new(&sized, gpu, &targets, &hidden_area)?;
        }
    }
    // `--teardown in-flight`: one more frame drawn into the swapchains, which go before anything
    // waits for it.
    let early = match (opts.teardown, &last_uniforms) {
        (cli::Teardown::InFlight, Some(u)) => match in_flight_frame(gpu, &mut targets, &mut renderer, u, frame) {
            Ok(finished) => {
                push_stats(stats, &mut xr_us, finished)?;
                targets.destroy_swapchains_in_flight().err()
            }
            Err(e) => Some(e),
        },
        _ => None,
    };
    // Frames still in flight (`--record-once`) are measured before anything is torn down.
    let finished = renderer.finish()?;
    push_stats(stats, &mut xr_us, finished)?;
    if let Some((recorded, overlapped)) = renderer.worker_frames() {
        // What tests/threads.rs reads: the passes really were recorded on workers at once.
        eprintln!("xr-scene: threads: {recorded} frames recorded on workers, {overlapped} with passes recorded concurrently");
    }
    drop(renderer);
    pacer.join(&mut xs)?;
    // Torn down explicitly, in the order the locals would drop, so that a failing destroy call
    // reaches the error path like every other call; a failure does not stop the rest. The caller
    // decides what goes next (`run_instance`).
    let results = match opts.teardown {
        cli::Teardown::Children => vec![targets.destroy(), xs.destroy()],
        // The runtime destroys the swapchains with their session.
        cli::Teardown::Session => {
            targets.leave_swapchains();
            vec![xs.destroy()]
        }
        // The last session goes with the instance (`run_instance`).
        cli::Teardown::Instance if last => {
            targets.leave_swapchains();
            xs.leave();
            vec![]
        }
        cli::Teardown::Instance | cli::Teardown::InFlight => vec![targets.destroy(), xs.destroy()],
    };
    let errors: Vec<String> = early.into_iter().map(|e| e.0).chain(results.into_iter().filter_map(|r| r.err().map(|e| e.0))).collect();
    Ok((frame, errors))
}

/// `--teardown in-flight`: after the session's last frame, one more is begun as an engine that
/// renders ahead does (Bevy): images acquired and drawn into, its work submitted, and then
/// neither released nor ended, so that it may still run when the swapchains are destroyed.
/// Returns the frames whose GPU work finished meanwhile.
fn in_flight_frame(gpu: &gpu::Gpu, targets: &mut targets::Targets, renderer: &mut renderer::Renderer, uniforms: &renderer::FrameUniforms, frame: u64) -> Result<Vec<renderer::FrameResult>> {
    let mut acquired = Vec::new();
    for slot in &mut targets.slots {
        let color = match &mut slot.color.swapchain {
            Some(sc) => {
                let i = sc.acquire_image().ctx("xrAcquireSwapchainImage")?;
                sc.wait_image(oxr::Duration::INFINITE).ctx("xrWaitSwapchainImage")?;
                i
            }
            None => shared_image(&acquired)?,
        };
        let depth = match &mut slot.depth {
            Some(d) => {
                let i = d.owned().acquire_image().ctx("xrAcquireSwapchainImage(depth)")?;
                d.owned().wait_image(oxr::Duration::INFINITE).ctx("xrWaitSwapchainImage(depth)")?;
                Some(i)
            }
            None => None,
        };
        acquired.push(renderer::Acquired { color, depth });
    }
    renderer.render(gpu, targets, &acquired, uniforms, frame)
}

/// `--eye-swapchain array`: a slot without a swapchain of its own writes another layer of the
/// image the slot before it acquired (acquired once per frame, as the runtime requires).
fn shared_image(acquired: &[renderer::Acquired]) -> Result<u32> {
    acquired.last().map(|a| a.color).ok_or_else(|| error::Error("internal: the first slot has no swapchain of its own".into()))
}

/// Adds the measurements of frames whose GPU work finished to `--stats`.
fn push_stats(stats: &mut Option<stats::StatsLog>, xr_us: &mut std::collections::HashMap<u64, stats::CallTimes>, finished: Vec<renderer::FrameResult>) -> Result<()> {
    for r in finished {
        let mut cpu_calls = xr_us.remove(&r.frame).unwrap_or_default();
        let cpu_xr_us = cpu_calls.total_us();
        cpu_calls.add("vkQueueSubmit", r.submit_us);
        if let Some(s) = stats {
            s.push(stats::FrameStats {
                frame: r.frame,
                gpu_time_ms: r.gpu_time_ms,
                cpu_xr_us,
                cpu_record_us: r.record_us,
                cpu_calls,
                views: (0..2).map(|v| stats::ViewStats { view: v, shaded_fragments: r.counts[v as usize] }).collect(),
            })?;
        }
    }
    Ok(())
}

/// The views as an app that assumes symmetric or parallel eyes draws them (`--assume-symmetric`,
/// `--assume-parallel`); it submits them as located.
fn assumed(opts: &cli::Options, views: &[oxr::View]) -> Vec<oxr::View> {
    let mut v = views.to_vec();
    if opts.assume_parallel {
        let q = |o: oxr::Quaternionf| Quat::from_xyzw(o.x, o.y, o.z, o.w);
        let m = q(v[0].pose.orientation).slerp(q(v[1].pose.orientation), 0.5).normalize();
        for e in &mut v {
            e.pose.orientation = oxr::Quaternionf { x: m.x, y: m.y, z: m.z, w: m.w };
        }
    }
    if opts.assume_symmetric {
        let l = v[0].fov;
        v[1].fov = oxr::Fovf { angle_left: -l.angle_right, angle_right: -l.angle_left, angle_up: l.angle_up, angle_down: l.angle_down };
    }
    v
}

fn frame_uniforms(views: &[oxr::View], reversed: bool, animate: bool, far_movers: bool, frame: u64) -> renderer::FrameUniforms {
    let proj = |v: &oxr::View| {
        let f = v.fov;
        camera::projection(camera::Fov { left: f.angle_left, right: f.angle_right, up: f.angle_up, down: f.angle_down }, camera::NEAR, camera::FAR, reversed)
    };
    let vp = |v: &oxr::View| {
        let o = v.pose.orientation;
        let p = v.pose.position;
        proj(v) * camera::view_matrix(Quat::from_xyzw(o.x, o.y, o.z, o.w), Vec3::new(p.x, p.y, p.z))
    };
    let eye = |v: &oxr::View| Vec4::new(v.pose.position.x, v.pose.position.y, v.pose.position.z, 1.0);
    let cube_model = if animate {
        // Deterministic per frame number, independent of timing.
        let angle = frame as f32 * 0.1;
        let c = scene::CUBE_CENTRE;
        Mat4::from_translation(c) * Mat4::from_rotation_y(angle) * Mat4::from_rotation_x(angle * 0.5) * Mat4::from_translation(-c)
    } else {
        Mat4::IDENTITY
    };
    let mover_model = if far_movers { scene::mover_model(frame) } else { Mat4::IDENTITY };
    renderer::FrameUniforms { view_proj: [vp(&views[0]), vp(&views[1])], cube_model, eye_pos: [eye(&views[0]), eye(&views[1])], mover_model, proj: [proj(&views[0]), proj(&views[1])] }
}

/// xrEndFrame through the raw entry point: the `openxr` crate's safe layer types cannot chain
/// `XrCompositionLayerDepthInfoKHR` onto projection views.
fn end_frame(
    xri: &xr::XrInstance,
    xs: &xr::XrSession,
    display_time: oxr::Time,
    content: Option<(&targets::Targets, &[oxr::View], bool)>,
    quad: Option<&quad::Quad>,
) -> Result<()> {
    use oxr::sys;
    let mut depth_infos = Vec::new();
    let mut proj_views = Vec::new();
    if let Some((targets, views, reversed)) = content {
        for (v, view) in views.iter().enumerate() {
            let rect = targets.views[v];
            let slot = &targets.slots[rect.slot];
            let image_rect = sys::Rect2Di {
                offset: sys::Offset2Di { x: rect.offset_x, y: 0 },
                extent: sys::Extent2Di { width: rect.extent.width as i32, height: rect.extent.height as i32 },
            };
            if let Some(d) = slot.depth.as_ref().and_then(|d| d.swapchain.as_ref()) {
                // Reversed depth: near maps to 1, which OpenXR expresses as nearZ > farZ.
                let (near_z, far_z) = if reversed { (camera::FAR, camera::NEAR) } else { (camera::NEAR, camera::FAR) };
                depth_infos.push(sys::CompositionLayerDepthInfoKHR {
                    ty: sys::CompositionLayerDepthInfoKHR::TYPE,
                    next: std::ptr::null(),
                    sub_image: sys::SwapchainSubImage {
                        swapchain: d.as_raw(),
                        image_rect,
                        image_array_index: rect.array_index,
                    },
                    min_depth: 0.0,
                    max_depth: 1.0,
                    near_z,
                    far_z,
                });
            }
            proj_views.push(sys::CompositionLayerProjectionView {
                ty: sys::CompositionLayerProjectionView::TYPE,
                next: std::ptr::null(),
                pose: view.pose,
                fov: view.fov,
                sub_image: sys::SwapchainSubImage {
                    swapchain: targets.color_swapchain(rect.slot).as_raw(),
                    image_rect,
                    image_array_index: rect.array_index,
                },
            });
        }
        // Pointers into depth_infos are taken only after it stops growing.
        if depth_infos.len() == proj_views.len() {
            for (pv, di) in proj_views.iter_mut().zip(&depth_infos) {
                pv.next = di as *const _ as *const _;
            }
        }
    }
    let layer = sys::CompositionLayerProjection {
        ty: sys::CompositionLayerProjection::TYPE,
        next: std::ptr::null(),
        layer_flags: sys::CompositionLayerFlags::EMPTY,
        space: xs.stage.as_raw(),
        view_count: proj_views.len() as u32,
        views: proj_views.as_ptr(),
    };
    // `--quad`: 1.5 m ahead of the stage origin at eye height, 0.6 m wide, its aspect the image's.
    let quad_layer = quad.map(|q| sys::CompositionLayerQuad {
        ty: sys::CompositionLayerQuad::TYPE,
        next: std::ptr::null(),
        layer_flags: sys::CompositionLayerFlags::EMPTY,
        space: xs.stage.as_raw(),
        eye_visibility: sys::EyeVisibility::BOTH,
        sub_image: sys::SwapchainSubImage {
            swapchain: q.swapchain.as_raw(),
            image_rect: sys::Rect2Di { offset: sys::Offset2Di { x: 0, y: 0 }, extent: sys::Extent2Di { width: q.width as i32, height: q.height as i32 } },
            image_array_index: 0,
        },
        pose: sys::Posef { orientation: sys::Quaternionf { x: 0.0, y: 0.0, z: 0.0, w: 1.0 }, position: sys::Vector3f { x: 0.0, y: 1.6, z: -1.5 } },
        size: sys::Extent2Df { width: 0.6, height: 0.6 * q.height as f32 / q.width as f32 },
    });
    let mut layers = vec![&layer as *const sys::CompositionLayerProjection as *const sys::CompositionLayerBaseHeader];
    if let (Some(q), true) = (&quad_layer, content.is_some()) {
        layers.push(q as *const sys::CompositionLayerQuad as *const sys::CompositionLayerBaseHeader);
    }
    let info = sys::FrameEndInfo {
        ty: sys::FrameEndInfo::TYPE,
        next: std::ptr::null(),
        display_time,
        environment_blend_mode: xri.blend_mode,
        layer_count: if content.is_some() { layers.len() as u32 } else { 0 },
        layers: layers.as_ptr(),
    };
    // SAFETY: every struct and array referenced by `info` lives until the call returns; the
    // session's frame was begun with xrBeginFrame on this thread.
    let r = unsafe { (xri.instance.fp().end_frame)(xs.session.as_raw(), &info) };
    if r.into_raw() < 0 {
        return error::fail(format!("xrEndFrame failed: {r:?}"));
    }
    Ok(())
}
