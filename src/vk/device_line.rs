//! The device's stats line: what the layer saw and did on a `VkDevice`. Written when the app
//! destroys the device, and also at `xrDestroySession` and at process exit, because some apps
//! (wgpu: Bevy) never call `vkDestroyDevice` and would otherwise leave no line at all.

use crate::plugin::vk::DeviceState;
use std::sync::Once;

/// `key=value` pairs of everything the layer counted on `dev` (tests parse them).
pub(crate) fn line(dev: &DeviceState) -> String {
    let mut line = dev.track.stats.summary();
    for summary in dev.features.all().iter().filter_map(|f| f.summary()) {
        line.push(' ');
        line.push_str(&summary);
    }
    if let Some(summary) = crate::plugin::vk::gpu_time::summary(dev) {
        line.push(' ');
        line.push_str(&summary);
    }
    for (reason, n) in dev.inject.vetoed() {
        line.push_str(&format!(" vetoed.{reason}={n}"));
    }
    let (walks, traced, post) = dev.track.traced.counts();
    line.push_str(&format!(" flow.walks={walks} flow.traced_images={traced} flow.post_images={post}"));
    // What the layer still tracks of the app's objects: an app that destroyed everything
    // leaves 0 of each when the device goes (tests/hardening/lifecycle.rs checks it).
    let t = &dev.track;
    line.push_str(&format!(
        " live.images={} live.views={} live.render_passes={} live.framebuffers={} live.pipelines={} live.command_pools={} live.command_buffers={} live.descriptor_sets={}",
        t.images.len(),
        t.views.len(),
        t.render_passes.len(),
        t.framebuffers.len(),
        t.pipelines.len(),
        t.pools.len(),
        t.command_buffers.len(),
        t.descriptors.set_count()
    ));
    line.push_str(&dev.own.summary());
    line
}

/// Logs the line of a device that is still live, saying when (`at`: "xrDestroySession", "exit").
pub(crate) fn log_live(dev: &DeviceState, at: &str) {
    // Not "vulkan device stats:": that line is the device's last word, with nothing left alive.
    tracing::info!(device = ?dev.handle, "vulkan device still live at {at}; its stats so far: {}", line(dev));
}

/// At process exit, the lines of every device the app never destroyed. Registered once, when
/// the first device is created.
pub(crate) fn log_at_exit() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        extern "C" {
            fn atexit(f: extern "C" fn()) -> std::ffi::c_int;
        }
        // SAFETY: `at_exit` is a plain function of this library; glibc runs handlers a shared
        // object registers when it is unloaded or at exit, whichever comes first, so the code
        // is still mapped when it runs.
        if unsafe { atexit(at_exit) } != 0 {
            tracing::debug!("atexit failed: no device stats at process exit");
        }
    });
}

extern "C" fn at_exit() {
    // Never unwind into libc. No `tracing` here: at exit the subscriber's thread-locals may be
    // gone already (seen with Bevy on an H100), and touching them panics.
    let _ = std::panic::catch_unwind(|| {
        for (_, dev) in crate::plugin::vk::devices().values() {
            crate::core::log::append_at_exit("stereoshim::vk::device_stats", &format!("vulkan device still live at exit; its stats so far: {}", line(&dev)));
        }
    });
}
