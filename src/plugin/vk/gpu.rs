//! The GPU helpers every feature's own work is recorded with: the memory barriers and subresource
//! ranges of the layer's transfers, compute dispatches and draws. One builder each, so every
//! barrier the layer records says the same things the same way (no queue family transfer: the
//! layer's work runs on the queue of the app's work it follows).

use ash::vk;

/// The colour aspect of `layers` array layers from `base_layer`, `mips` mip levels from 0.
pub(crate) fn color_range(base_layer: u32, layers: u32, mips: u32) -> vk::ImageSubresourceRange {
    vk::ImageSubresourceRange { aspect_mask: vk::ImageAspectFlags::COLOR, base_mip_level: 0, level_count: mips, base_array_layer: base_layer, layer_count: layers }
}

/// A layout transition of `range` of `image` from `old` to `new`, making `src` accesses before it
/// visible to `dst` accesses after it.
pub(crate) fn image_barrier(image: vk::Image, range: vk::ImageSubresourceRange, (old, new): (vk::ImageLayout, vk::ImageLayout), (src, dst): (vk::AccessFlags, vk::AccessFlags)) -> vk::ImageMemoryBarrier<'static> {
    vk::ImageMemoryBarrier::default()
        .src_access_mask(src)
        .dst_access_mask(dst)
        .old_layout(old)
        .new_layout(new)
        .src_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
        .dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
        .image(image)
        .subresource_range(range)
}

/// A barrier on the whole of `buffer` between `src` and `dst` accesses.
pub(crate) fn buffer_barrier(buffer: vk::Buffer, src: vk::AccessFlags, dst: vk::AccessFlags) -> vk::BufferMemoryBarrier<'static> {
    vk::BufferMemoryBarrier::default().src_access_mask(src).dst_access_mask(dst).src_queue_family_index(vk::QUEUE_FAMILY_IGNORED).dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED).buffer(buffer).offset(0).size(vk::WHOLE_SIZE)
}
