//! Draw hooks: only so an armed eye pass gets its waiting features' draws in front of its first
//! depth-tested draw (`crate::vk::chassis::before_draw`). Every draw command the app can record into a pass
//! is hooked — one the layer missed could be drawn before an injection that then paints over it.
//! Draw commands of extensions the layer does not forward (mesh shaders, multi-draw, transform
//! feedback) veto injections instead (`record::veto_hook`).

use super::hook_decided;
use ash::vk::{self, Handle};

/// Hooks a draw: `before_draw` first, then the app's call unchanged.
macro_rules! draw_hook {
    ($name:ident, $call:literal, ($cb:ident, $($arg:ident : $ty:ty),*), |$d:ident| $next:expr) => {
        pub(in crate::vk) unsafe extern "system" fn $name($cb: vk::CommandBuffer, $($arg: $ty),*) {
            hook_decided(
                $call,
                $cb,
                (),
                |d| {
                    // What the draw reads, for the data-flow walk; then the armed injection.
                    d.track.with_cb($cb.as_raw(), |s| s.flow_draw());
                    crate::vk::chassis::before_draw(d, $cb)
                },
                // SAFETY: forwarding the app's arguments unchanged to the next layer's command.
                |$d, _| unsafe { $next },
                |_, ()| Ok(()),
            )
        }
    };
}

draw_hook!(cmd_draw, "vkCmdDraw", (cb, vertices: u32, instances: u32, first_vertex: u32, first_instance: u32),
    |d| (d.fns.fp_v1_0().cmd_draw)(cb, vertices, instances, first_vertex, first_instance));
draw_hook!(cmd_draw_indexed, "vkCmdDrawIndexed", (cb, indices: u32, instances: u32, first_index: u32, vertex_offset: i32, first_instance: u32),
    |d| (d.fns.fp_v1_0().cmd_draw_indexed)(cb, indices, instances, first_index, vertex_offset, first_instance));
draw_hook!(cmd_draw_indirect, "vkCmdDrawIndirect", (cb, buffer: vk::Buffer, offset: vk::DeviceSize, count: u32, stride: u32),
    |d| (d.fns.fp_v1_0().cmd_draw_indirect)(cb, buffer, offset, count, stride));
draw_hook!(cmd_draw_indexed_indirect, "vkCmdDrawIndexedIndirect", (cb, buffer: vk::Buffer, offset: vk::DeviceSize, count: u32, stride: u32),
    |d| (d.fns.fp_v1_0().cmd_draw_indexed_indirect)(cb, buffer, offset, count, stride));
draw_hook!(cmd_draw_indirect_count, "vkCmdDrawIndirectCount",
    (cb, buffer: vk::Buffer, offset: vk::DeviceSize, count_buffer: vk::Buffer, count_offset: vk::DeviceSize, max: u32, stride: u32),
    |d| (d.fns.fp_v1_2().cmd_draw_indirect_count)(cb, buffer, offset, count_buffer, count_offset, max, stride));
draw_hook!(cmd_draw_indexed_indirect_count, "vkCmdDrawIndexedIndirectCount",
    (cb, buffer: vk::Buffer, offset: vk::DeviceSize, count_buffer: vk::Buffer, count_offset: vk::DeviceSize, max: u32, stride: u32),
    |d| (d.fns.fp_v1_2().cmd_draw_indexed_indirect_count)(cb, buffer, offset, count_buffer, count_offset, max, stride));
