//! The barriers of a frame's primary command buffer, outside the passes: the attachments put in
//! their layouts before the passes (and `--depth-clear image`'s clears), and `--intermediate`'s
//! resolve or copy into the swapchain images after them.

use super::{FrameSet, Renderer};
use crate::cli::DepthClear;
use crate::renderer::Acquired;
use crate::targets::{depth_aspect, Targets};
use ash::vk;

impl Renderer {
    /// Everything the passes write, ordered after its previous use and put in attachment layout.
    pub(super) fn pre_pass_barriers(&self, cmd: vk::CommandBuffer, set: &FrameSet, targets: &Targets, acquired: &[Acquired]) {
        let mut images = Vec::new();
        for (i, a) in acquired.iter().enumerate() {
            let slot = &targets.slots[i];
            let color_range = range(vk::ImageAspectFlags::COLOR, slot.layers);
            let depth_range = range(depth_aspect(targets.depth_format), slot.layers);
            let color_rw = vk::AccessFlags::COLOR_ATTACHMENT_READ | vk::AccessFlags::COLOR_ATTACHMENT_WRITE;
            let depth_rw = vk::AccessFlags::DEPTH_STENCIL_ATTACHMENT_READ | vk::AccessFlags::DEPTH_STENCIL_ATTACHMENT_WRITE;
            match &slot.offscreen {
                // Last frame's resolve/copy read it; its contents are cleared anyway.
                Some(o) => images.push(image_barrier(
                    o.image,
                    color_range,
                    vk::ImageLayout::UNDEFINED,
                    vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL,
                    vk::AccessFlags::empty(),
                    color_rw,
                )),
                // The runtime hands swapchain images out in COLOR_ATTACHMENT_OPTIMAL.
                None => images.push(image_barrier(
                    slot.color.images[a.color as usize],
                    color_range,
                    vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL,
                    vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL,
                    vk::AccessFlags::COLOR_ATTACHMENT_WRITE,
                    color_rw,
                )),
            }
            // `--depth-clear image`: depth goes to TRANSFER_DST_OPTIMAL for its clear first.
            let (depth_layout, depth_access) = if self.draw.depth_clear == DepthClear::Image {
                (vk::ImageLayout::TRANSFER_DST_OPTIMAL, vk::AccessFlags::TRANSFER_WRITE)
            } else {
                (vk::ImageLayout::DEPTH_STENCIL_ATTACHMENT_OPTIMAL, depth_rw)
            };
            match (&slot.depth, a.depth, &slot.own_depth) {
                (Some(chain), Some(di), _) => images.push(image_barrier(
                    chain.images[di as usize],
                    depth_range,
                    vk::ImageLayout::DEPTH_STENCIL_ATTACHMENT_OPTIMAL,
                    depth_layout,
                    vk::AccessFlags::DEPTH_STENCIL_ATTACHMENT_WRITE,
                    depth_access,
                )),
                (_, _, Some(own)) => images.push(image_barrier(
                    own.image,
                    depth_range,
                    vk::ImageLayout::UNDEFINED,
                    depth_layout,
                    vk::AccessFlags::DEPTH_STENCIL_ATTACHMENT_WRITE,
                    depth_access,
                )),
                _ => {}
            }
        }
        let mut buffers = vec![set.counters.after_fill_barrier()];
        buffers.extend(set.pixels.as_ref().map(|p| p.after_fill_barrier()));
        if self.sync_hazard {
            // `--sync-hazard`: the fragment shader's atomics then race the fill (write after
            // write), which only synchronization validation notices.
            buffers.clear();
        }
        let fragment_tests = vk::PipelineStageFlags::EARLY_FRAGMENT_TESTS | vk::PipelineStageFlags::LATE_FRAGMENT_TESTS;
        let mut dst_stages = vk::PipelineStageFlags::FRAGMENT_SHADER | vk::PipelineStageFlags::COLOR_ATTACHMENT_OUTPUT | fragment_tests;
        if self.draw.depth_clear == DepthClear::Image {
            dst_stages |= vk::PipelineStageFlags::TRANSFER;
        }
        // SAFETY: recording state, outside any render pass.
        unsafe {
            self.device.cmd_pipeline_barrier(
                cmd,
                vk::PipelineStageFlags::TRANSFER | vk::PipelineStageFlags::COLOR_ATTACHMENT_OUTPUT | fragment_tests,
                dst_stages,
                vk::DependencyFlags::empty(),
                &[],
                &buffers,
                &images,
            );
        }
        if self.draw.depth_clear == DepthClear::Image {
            self.clear_depth_images(cmd, targets, acquired);
        }
    }

    /// `--depth-clear image`: `vkCmdClearDepthStencilImage` on every depth image of the frame (in
    /// TRANSFER_DST_OPTIMAL), then the clear made visible to the passes that load it, in
    /// DEPTH_STENCIL_ATTACHMENT_OPTIMAL.
    fn clear_depth_images(&self, cmd: vk::CommandBuffer, targets: &Targets, acquired: &[Acquired]) {
        let value = vk::ClearDepthStencilValue { depth: self.draw.clear_depth, stencil: 0 };
        let mut to_attachment = Vec::new();
        for (i, a) in acquired.iter().enumerate() {
            let slot = &targets.slots[i];
            let image = match (&slot.depth, a.depth, &slot.own_depth) {
                (Some(chain), Some(di), _) => chain.images[di as usize],
                (_, _, Some(own)) => own.image,
                _ => continue,
            };
            let r = range(depth_aspect(targets.depth_format), slot.layers);
            // SAFETY: recording, outside any pass; the image was just put in TRANSFER_DST_OPTIMAL.
            unsafe { self.device.cmd_clear_depth_stencil_image(cmd, image, vk::ImageLayout::TRANSFER_DST_OPTIMAL, &value, &[r]) };
            to_attachment.push(image_barrier(
                image,
                r,
                vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                vk::ImageLayout::DEPTH_STENCIL_ATTACHMENT_OPTIMAL,
                vk::AccessFlags::TRANSFER_WRITE,
                vk::AccessFlags::DEPTH_STENCIL_ATTACHMENT_READ | vk::AccessFlags::DEPTH_STENCIL_ATTACHMENT_WRITE,
            ));
        }
        // SAFETY: recording state, outside any render pass.
        unsafe {
            self.device.cmd_pipeline_barrier(
                cmd,
                vk::PipelineStageFlags::TRANSFER,
                vk::PipelineStageFlags::EARLY_FRAGMENT_TESTS | vk::PipelineStageFlags::LATE_FRAGMENT_TESTS,
                vk::DependencyFlags::empty(),
                &[],
                &[],
                &to_attachment,
            );
        }
    }

    /// `--intermediate`: resolve (N > 1) or copy (N = 1) each offscreen target into its swapchain
    /// image, then hand the swapchain image back in COLOR_ATTACHMENT_OPTIMAL as the binding requires.
    pub(super) fn resolve_to_swapchains(&self, cmd: vk::CommandBuffer, targets: &Targets, acquired: &[Acquired]) {
        let d = &self.device;
        let mut to_transfer = Vec::new();
        let mut back = Vec::new();
        for (i, a) in acquired.iter().enumerate() {
            let slot = &targets.slots[i];
            let Some(off) = &slot.offscreen else { continue };
            let r = range(vk::ImageAspectFlags::COLOR, slot.layers);
            let sc = slot.color.images[a.color as usize];
            to_transfer.push(image_barrier(
                off.image,
                r,
                vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL,
                vk::ImageLayout::TRANSFER_SRC_OPTIMAL,
                vk::AccessFlags::COLOR_ATTACHMENT_WRITE,
                vk::AccessFlags::TRANSFER_READ,
            ));
            to_transfer.push(image_barrier(
                sc,
                r,
                vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL,
                vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                vk::AccessFlags::COLOR_ATTACHMENT_WRITE,
                vk::AccessFlags::TRANSFER_WRITE,
            ));
            back.push(image_barrier(
                sc,
                r,
                vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL,
                vk::AccessFlags::TRANSFER_WRITE,
                vk::AccessFlags::COLOR_ATTACHMENT_READ | vk::AccessFlags::COLOR_ATTACHMENT_WRITE,
            ));
        }
        // SAFETY: recording state, outside any render pass; images are in the layouts named.
        unsafe {
            d.cmd_pipeline_barrier(
                cmd,
                vk::PipelineStageFlags::COLOR_ATTACHMENT_OUTPUT,
                vk::PipelineStageFlags::TRANSFER,
                vk::DependencyFlags::empty(),
                &[],
                &[],
                &to_transfer,
            );
            for (i, a) in acquired.iter().enumerate() {
                let slot = &targets.slots[i];
                let Some(off) = &slot.offscreen else { continue };
                let layers = vk::ImageSubresourceLayers {
                    aspect_mask: vk::ImageAspectFlags::COLOR,
                    mip_level: 0,
                    base_array_layer: 0,
                    layer_count: slot.layers,
                };
                let extent = vk::Extent3D { width: slot.extent.width, height: slot.extent.height, depth: 1 };
                let sc = slot.color.images[a.color as usize];
                if self.samples == vk::SampleCountFlags::TYPE_1 {
                    let region = vk::ImageCopy {
                        src_subresource: layers,
                        src_offset: vk::Offset3D::default(),
                        dst_subresource: layers,
                        dst_offset: vk::Offset3D::default(),
                        extent,
                    };
                    d.cmd_copy_image(cmd, off.image, vk::ImageLayout::TRANSFER_SRC_OPTIMAL, sc, vk::ImageLayout::TRANSFER_DST_OPTIMAL, &[region]);
                } else {
                    let region = vk::ImageResolve {
                        src_subresource: layers,
                        src_offset: vk::Offset3D::default(),
                        dst_subresource: layers,
                        dst_offset: vk::Offset3D::default(),
                        extent,
                    };
                    d.cmd_resolve_image(cmd, off.image, vk::ImageLayout::TRANSFER_SRC_OPTIMAL, sc, vk::ImageLayout::TRANSFER_DST_OPTIMAL, &[region]);
                }
            }
            d.cmd_pipeline_barrier(
                cmd,
                vk::PipelineStageFlags::TRANSFER,
                vk::PipelineStageFlags::COLOR_ATTACHMENT_OUTPUT,
                vk::DependencyFlags::empty(),
                &[],
                &[],
                &back,
            );
        }
    }
}

fn range(aspect: vk::ImageAspectFlags, layers: u32) -> vk::ImageSubresourceRange {
    vk::ImageSubresourceRange { aspect_mask: aspect, base_mip_level: 0, level_count: 1, base_array_layer: 0, layer_count: layers }
}

fn image_barrier(
    image: vk::Image,
    range: vk::ImageSubresourceRange,
    old: vk::ImageLayout,
    new: vk::ImageLayout,
    src: vk::AccessFlags,
    dst: vk::AccessFlags,
) -> vk::ImageMemoryBarrier<'static> {
    vk::ImageMemoryBarrier::default()
        .image(image)
        .subresource_range(range)
        .old_layout(old)
        .new_layout(new)
        .src_access_mask(src)
        .dst_access_mask(dst)
        .src_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
        .dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
}
