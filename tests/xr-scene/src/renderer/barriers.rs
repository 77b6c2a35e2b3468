//! The barriers of a frame's primary command buffer, outside the passes: the attachments put in
//! their layouts before the passes (and `--depth-clear image`'s clears), `--intermediate`'s
//! resolve or copy into the swapchain images (or the double-wide texture) after them, and
//! `--submit-texture double-wide`'s blits into the swapchain's layers at the end.

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
            // `--eye-swapchain array`: each slot's own layer of the image both slots acquired, so
            // the image is ordered once per layer, never twice over the same subresource.
            let color_range = layer_range(vk::ImageAspectFlags::COLOR, slot.color_layer, slot.layers);
            let depth_range = range(depth_aspect(targets.depth_format), slot.scene_layers);
            let scene_range = range(vk::ImageAspectFlags::COLOR, slot.scene_layers);
            let color_rw = vk::AccessFlags::COLOR_ATTACHMENT_READ | vk::AccessFlags::COLOR_ATTACHMENT_WRITE;
            let depth_rw = vk::AccessFlags::DEPTH_STENCIL_ATTACHMENT_READ | vk::AccessFlags::DEPTH_STENCIL_ATTACHMENT_WRITE;
            // The app's own colour targets: last frame's resolve, copy, blit or post-processing
            // read them (an execution dependency on those stages, below); their contents are
            // cleared or overwritten anyway.
            let discard = |image: vk::Image, r| image_barrier(image, r, vk::ImageLayout::UNDEFINED, vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL, vk::AccessFlags::empty(), color_rw);
            match (&slot.post, &slot.offscreen) {
                (Some(p), _) => {
                    images.push(discard(p.scene.image, scene_range));
                    images.extend(p.scene_msaa.as_ref().map(|ms| discard(ms.image, scene_range)));
                }
                (None, Some(o)) => images.push(discard(o.image, scene_range)),
                (None, None) => {}
            }
            match &slot.double_wide {
                Some(dw) => images.push(discard(dw.image, range(vk::ImageAspectFlags::COLOR, 1))),
                // The runtime hands swapchain images out in COLOR_ATTACHMENT_OPTIMAL. With the
                // double-wide texture only the blits at the end write them.
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
        let mut src_stages = vk::PipelineStageFlags::TRANSFER | vk::PipelineStageFlags::COLOR_ATTACHMENT_OUTPUT | fragment_tests;
        if self.post.is_some() {
            // Last frame's post-processing read the HDR target (a draw, a subpass or a dispatch).
            src_stages |= vk::PipelineStageFlags::FRAGMENT_SHADER | vk::PipelineStageFlags::COMPUTE_SHADER;
        }
        // SAFETY: recording state, outside any render pass.
        unsafe {
            self.device.cmd_pipeline_barrier(
                cmd,
                src_stages,
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

    /// `--one-target`, between the eyes' passes: the next eye's pass clears and tests the depth
    /// the last one wrote.
    pub(super) fn shared_depth_barrier(&self, cmd: vk::CommandBuffer, targets: &Targets) {
        let Some(depth) = targets.own_depth_of(0) else { return };
        let slot = &targets.slots[0];
        let rw = vk::AccessFlags::DEPTH_STENCIL_ATTACHMENT_READ | vk::AccessFlags::DEPTH_STENCIL_ATTACHMENT_WRITE;
        let l = vk::ImageLayout::DEPTH_STENCIL_ATTACHMENT_OPTIMAL;
        let b = image_barrier(depth.image, range(depth_aspect(targets.depth_format), slot.scene_layers), l, l, vk::AccessFlags::DEPTH_STENCIL_ATTACHMENT_WRITE, rw);
        let tests = vk::PipelineStageFlags::EARLY_FRAGMENT_TESTS | vk::PipelineStageFlags::LATE_FRAGMENT_TESTS;
        // SAFETY: recording state, outside any render pass; the depth is in the layout named.
        unsafe { self.device.cmd_pipeline_barrier(cmd, tests, tests, vk::DependencyFlags::empty(), &[], &[], &[b]) };
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
            let r = range(depth_aspect(targets.depth_format), slot.scene_layers);
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
    /// image (or the double-wide texture), then hand that back in COLOR_ATTACHMENT_OPTIMAL as the
    /// binding requires.
    /// `only`: that slot's alone (`--one-target`, right after its pass), its offscreen target
    /// handed back to COLOR_ATTACHMENT_OPTIMAL for the next eye's pass.
    pub(super) fn resolve_to_swapchains(&self, cmd: vk::CommandBuffer, targets: &Targets, acquired: &[Acquired], only: Option<usize>) {
        let d = &self.device;
        let mut to_transfer = Vec::new();
        let mut back = Vec::new();
        let chosen = |i: usize| only.is_none_or(|o| o == i);
        for (i, a) in acquired.iter().enumerate() {
            let slot = &targets.slots[i];
            let Some(off) = targets.offscreen_of(i).filter(|_| chosen(i)) else { continue };
            let r = range(vk::ImageAspectFlags::COLOR, slot.scene_layers);
            // The destination's layers: its own layer of a shared array image (`--eye-swapchain
            // array`), so that eye 1's copy is not ordered against (nor transitions) eye 0's.
            let dst_r = layer_range(vk::ImageAspectFlags::COLOR, slot.final_layer(), slot.scene_layers);
            let (sc, ..) = slot.final_image(a.color);
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
                dst_r,
                vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL,
                vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                vk::AccessFlags::COLOR_ATTACHMENT_WRITE,
                vk::AccessFlags::TRANSFER_WRITE,
            ));
            back.push(image_barrier(
                sc,
                dst_r,
                vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL,
                vk::AccessFlags::TRANSFER_WRITE,
                vk::AccessFlags::COLOR_ATTACHMENT_READ | vk::AccessFlags::COLOR_ATTACHMENT_WRITE,
            ));
            if only.is_some() {
                back.push(image_barrier(
                    off.image,
                    r,
                    vk::ImageLayout::TRANSFER_SRC_OPTIMAL,
                    vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL,
                    vk::AccessFlags::TRANSFER_READ,
                    vk::AccessFlags::COLOR_ATTACHMENT_READ | vk::AccessFlags::COLOR_ATTACHMENT_WRITE,
                ));
            }
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
                let Some(off) = targets.offscreen_of(i).filter(|_| chosen(i)) else { continue };
                let layers = vk::ImageSubresourceLayers {
                    aspect_mask: vk::ImageAspectFlags::COLOR,
                    mip_level: 0,
                    base_array_layer: 0,
                    layer_count: slot.scene_layers,
                };
                let dst_layers = vk::ImageSubresourceLayers { base_array_layer: slot.final_layer(), ..layers };
                let extent = vk::Extent3D { width: slot.scene_extent.width, height: slot.scene_extent.height, depth: 1 };
                let (sc, ..) = slot.final_image(a.color);
                if self.samples == vk::SampleCountFlags::TYPE_1 {
                    let region = vk::ImageCopy {
                        src_subresource: layers,
                        src_offset: vk::Offset3D::default(),
                        dst_subresource: dst_layers,
                        dst_offset: vk::Offset3D::default(),
                        extent,
                    };
                    d.cmd_copy_image(cmd, off.image, vk::ImageLayout::TRANSFER_SRC_OPTIMAL, sc, vk::ImageLayout::TRANSFER_DST_OPTIMAL, &[region]);
                } else {
                    let region = vk::ImageResolve {
                        src_subresource: layers,
                        src_offset: vk::Offset3D::default(),
                        dst_subresource: dst_layers,
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

    /// `--submit-texture double-wide`: each half of the double-wide texture blitted (same size,
    /// nearest: a copy with bounds) into its layer of the swapchain image, as xrizer and
    /// OpenComposite submit an OpenVR game's texture.
    pub(super) fn blit_double_wide(&self, cmd: vk::CommandBuffer, targets: &Targets, acquired: &[Acquired]) {
        let d = &self.device;
        type S = vk::PipelineStageFlags;
        type A = vk::AccessFlags;
        type L = vk::ImageLayout;
        for (i, a) in acquired.iter().enumerate() {
            let slot = &targets.slots[i];
            let Some(dw) = &slot.double_wide else { continue };
            let sc = slot.color.images[a.color as usize];
            let to_transfer = [
                image_barrier(dw.image, range(vk::ImageAspectFlags::COLOR, 1), L::COLOR_ATTACHMENT_OPTIMAL, L::TRANSFER_SRC_OPTIMAL, A::COLOR_ATTACHMENT_WRITE, A::TRANSFER_READ),
                image_barrier(sc, range(vk::ImageAspectFlags::COLOR, slot.layers), L::COLOR_ATTACHMENT_OPTIMAL, L::TRANSFER_DST_OPTIMAL, A::COLOR_ATTACHMENT_WRITE, A::TRANSFER_WRITE),
            ];
            let back = [image_barrier(sc, range(vk::ImageAspectFlags::COLOR, slot.layers), L::TRANSFER_DST_OPTIMAL, L::COLOR_ATTACHMENT_OPTIMAL, A::TRANSFER_WRITE, A::COLOR_ATTACHMENT_READ | A::COLOR_ATTACHMENT_WRITE)];
            let (w, h) = (slot.extent.width as i32, slot.extent.height as i32);
            let regions: Vec<vk::ImageBlit> = (0..slot.layers)
                .map(|layer| vk::ImageBlit {
                    src_subresource: vk::ImageSubresourceLayers { aspect_mask: vk::ImageAspectFlags::COLOR, mip_level: 0, base_array_layer: 0, layer_count: 1 },
                    src_offsets: [vk::Offset3D { x: layer as i32 * w, y: 0, z: 0 }, vk::Offset3D { x: (layer as i32 + 1) * w, y: h, z: 1 }],
                    dst_subresource: vk::ImageSubresourceLayers { aspect_mask: vk::ImageAspectFlags::COLOR, mip_level: 0, base_array_layer: layer, layer_count: 1 },
                    dst_offsets: [vk::Offset3D { x: 0, y: 0, z: 0 }, vk::Offset3D { x: w, y: h, z: 1 }],
                })
                .collect();
            // SAFETY: recording outside any pass; the images are in the layouts named.
            unsafe {
                // Whatever wrote last (the eye pass, the tonemap draw, or a copy or resolve that
                // handed it back to COLOR_ATTACHMENT_OPTIMAL) is before the blit.
                d.cmd_pipeline_barrier(cmd, S::COLOR_ATTACHMENT_OUTPUT | S::TRANSFER, S::TRANSFER, vk::DependencyFlags::empty(), &[], &[], &to_transfer);
                d.cmd_blit_image(cmd, dw.image, L::TRANSFER_SRC_OPTIMAL, sc, L::TRANSFER_DST_OPTIMAL, &regions, vk::Filter::NEAREST);
                d.cmd_pipeline_barrier(cmd, S::TRANSFER, S::COLOR_ATTACHMENT_OUTPUT, vk::DependencyFlags::empty(), &[], &[], &back);
            }
        }
    }
}

pub(crate) fn range(aspect: vk::ImageAspectFlags, layers: u32) -> vk::ImageSubresourceRange {
    layer_range(aspect, 0, layers)
}

/// Level 0's `layers` array layers from `base`.
pub(crate) fn layer_range(aspect: vk::ImageAspectFlags, base: u32, layers: u32) -> vk::ImageSubresourceRange {
    vk::ImageSubresourceRange { aspect_mask: aspect, base_mip_level: 0, level_count: 1, base_array_layer: base, layer_count: layers }
}

pub(crate) fn image_barrier(
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
