//! Recording the post chain into a frame's primary command buffer, with every barrier between
//! the eye pass, bloom's passes, the tonemap (draw, dispatch + copy, or subpass) and TAA's history
//! copy (the tests run under synchronization validation). Each slot's final image (the swapchain
//! image or the double-wide texture) starts and ends in COLOR_ATTACHMENT_OPTIMAL; every image of
//! the chain starts each frame undefined except TAA's history, which stays SHADER_READ_ONLY_OPTIMAL
//! between frames (so command buffers recorded once stay valid).

use super::images::{EyeRect, Level, PostImages};
use super::{PostChain, PostPush, FLAG_MANUAL_SRGB, MODE_DOWN, MODE_FINAL, MODE_UP};
use super::{COMPUTE, GRAPHICS, SUBPASS};
use crate::cli::PostEffect;
use crate::error::Result;
use crate::gpu::Gpu;
use crate::passes::Passes;
use crate::renderer::{image_barrier, range, Acquired, PassTarget};
use crate::targets::{Slot, Targets};
use ash::vk;

use vk::AccessFlags as A;
use vk::ImageLayout as L;
use vk::PipelineStageFlags as S;

const CA: L = L::COLOR_ATTACHMENT_OPTIMAL;
const READ: L = L::SHADER_READ_ONLY_OPTIMAL;

/// The push constants of a draw or dispatch writing `dst` from `src` (a rect of an image of the
/// given extent) and `aux`.
fn push(mode: u32, flags: u32, dst: EyeRect, src: (EyeRect, vk::Extent2D), aux: (EyeRect, vk::Extent2D)) -> PostPush {
    let size = |r: &EyeRect| [r.1.width as f32, r.1.height as f32];
    let (ds, ss, as_) = (size(&dst), size(&src.0), size(&aux.0));
    let inv = |e: vk::Extent2D| [1.0 / e.width as f32, 1.0 / e.height as f32];
    PostPush {
        dst_origin: [dst.0 as f32, 0.0],
        dst_size: ds,
        src_origin: [src.0 .0 as f32, 0.0],
        src_size: ss,
        // Exactly 1 where the sizes are equal: the tonemap then reads each texel unfiltered.
        src_scale: [ss[0] / ds[0], ss[1] / ds[1]],
        src_inv_extent: inv(src.1),
        aux_origin: [aux.0 .0 as f32, 0.0],
        aux_size: as_,
        aux_scale: [as_[0] / ds[0], as_[1] / ds[1]],
        aux_inv_extent: inv(aux.1),
        mode,
        flags,
    }
}

fn bytes(p: &PostPush) -> &[u8] {
    // SAFETY: PostPush is repr(C) plain data, viewed as its bytes.
    unsafe { std::slice::from_raw_parts(p as *const PostPush as *const u8, std::mem::size_of::<PostPush>()) }
}

impl PostChain {
    fn barrier(&self, cmd: vk::CommandBuffer, src: S, dst: S, images: &[vk::ImageMemoryBarrier]) {
        // SAFETY: recording, outside any pass.
        unsafe { self.device.cmd_pipeline_barrier(cmd, src, dst, vk::DependencyFlags::empty(), &[], &[], images) };
    }

    /// Once, before the first frame (in the scene upload's command buffer): TAA's histories
    /// cleared to black and left SHADER_READ_ONLY_OPTIMAL, where each frame expects them.
    pub fn record_init(&self, cmd: vk::CommandBuffer) {
        let black = vk::ClearColorValue { float32: [0.0, 0.0, 0.0, 1.0] };
        for &(image, layers) in &self.histories {
            let r = range(vk::ImageAspectFlags::COLOR, layers);
            self.barrier(cmd, S::TOP_OF_PIPE, S::TRANSFER, &[image_barrier(image, r, L::UNDEFINED, L::TRANSFER_DST_OPTIMAL, A::empty(), A::TRANSFER_WRITE)]);
            // SAFETY: recording, outside any pass; the image is in TRANSFER_DST_OPTIMAL.
            unsafe { self.device.cmd_clear_color_image(cmd, image, L::TRANSFER_DST_OPTIMAL, &black, &[r]) };
            self.barrier(cmd, S::TRANSFER, S::FRAGMENT_SHADER, &[image_barrier(image, r, L::TRANSFER_DST_OPTIMAL, READ, A::TRANSFER_WRITE, A::SHADER_READ)]);
        }
    }

    /// `--post-subpass`, inside the eye pass after its scene subpass: the tonemap subpass, one
    /// draw over the whole render area (multiview: both views).
    pub fn record_subpass(&self, gpu: &Gpu, passes: &Passes, cmd: vk::CommandBuffer, pass: &PassTarget) {
        let d = &self.device;
        passes.next_subpass(gpu, cmd);
        let e = pass.extent;
        let p = PostPush { flags: self.flags & FLAG_MANUAL_SRGB, ..Default::default() };
        // SAFETY: recording in subpass 1 of the eye pass, whose layout the pipeline was made for.
        unsafe {
            d.cmd_bind_pipeline(cmd, vk::PipelineBindPoint::GRAPHICS, self.subpass_pipeline);
            d.cmd_bind_descriptor_sets(cmd, vk::PipelineBindPoint::GRAPHICS, self.layouts[SUBPASS], 0, &[self.sets[pass.slot].subpass], &[]);
            d.cmd_push_constants(cmd, self.layouts[SUBPASS], vk::ShaderStageFlags::FRAGMENT, 0, bytes(&p));
            d.cmd_set_viewport(cmd, 0, &[vk::Viewport { x: 0.0, y: 0.0, width: e.width as f32, height: e.height as f32, min_depth: 0.0, max_depth: 1.0 }]);
            d.cmd_set_scissor(cmd, 0, &[vk::Rect2D { offset: vk::Offset2D::default(), extent: e }]);
            d.cmd_draw(cmd, 3, 1, 0, 0);
        }
    }

    /// After every eye pass: each slot's chain. `--post-subpass` has done its work inside the pass.
    /// `frame_scale`: the part of each scene eye rect the eye passes drew this frame
    /// (`--dynamic-resolution`; else 1).
    pub fn record(&mut self, gpu: &Gpu, cmd: vk::CommandBuffer, targets: &Targets, acquired: &[Acquired], frame_scale: f32) -> Result<()> {
        if self.subpass {
            return Ok(());
        }
        self.frame_scale = frame_scale;
        for (i, a) in acquired.iter().enumerate() {
            self.record_slot(gpu, cmd, i, &targets.slots[i], &targets.slots[i], a.color)?;
        }
        Ok(())
    }

    /// `--one-target`, right after eye `eye`'s pass: the first slot's chain (whose scene target
    /// every eye renders into) into eye `eye`'s final image; then, before the next eye's pass
    /// renders into the scene target again, the scene target back to an attachment after this
    /// chain's reads.
    pub fn record_eye(&mut self, gpu: &Gpu, cmd: vk::CommandBuffer, targets: &Targets, eye: usize, color: u32, frame_scale: f32) -> Result<()> {
        self.frame_scale = frame_scale;
        let chain = &targets.slots[0];
        self.record_slot(gpu, cmd, 0, chain, &targets.slots[eye], color)?;
        if eye + 1 < targets.slots.len() {
            let p = chain.post.as_ref().expect("post images");
            let r = range(vk::ImageAspectFlags::COLOR, p.geometry.layers);
            let mut images = vec![image_barrier(p.scene.image, r, READ, CA, A::SHADER_READ, A::COLOR_ATTACHMENT_READ | A::COLOR_ATTACHMENT_WRITE)];
            // The multisampled colour is written again by the next eye's pass.
            images.extend(p.scene_msaa.as_ref().map(|ms| image_barrier(ms.image, r, CA, CA, A::COLOR_ATTACHMENT_WRITE, A::COLOR_ATTACHMENT_READ | A::COLOR_ATTACHMENT_WRITE)));
            self.barrier(cmd, S::FRAGMENT_SHADER | S::COLOR_ATTACHMENT_OUTPUT, S::COLOR_ATTACHMENT_OUTPUT, &images);
        }
        Ok(())
    }

    /// Chain `index` (its descriptor sets), reading `chain`'s images, into `out`'s final image
    /// (the same slot but with `--one-target`).
    fn record_slot(&mut self, gpu: &Gpu, cmd: vk::CommandBuffer, index: usize, chain: &Slot, out: &Slot, color: u32) -> Result<()> {
        let p = chain.post.as_ref().expect("a slot without post images");
        let g = &p.geometry;
        let reader = if self.compute { S::COMPUTE_SHADER } else { S::FRAGMENT_SHADER };
        // The eye pass's colour (written, or resolved into, as an attachment) is read next.
        let scene_range = range(vk::ImageAspectFlags::COLOR, g.layers);
        self.barrier(cmd, S::COLOR_ATTACHMENT_OUTPUT, reader, &[image_barrier(p.scene.image, scene_range, CA, READ, A::COLOR_ATTACHMENT_WRITE, A::SHADER_READ)]);
        if self.effect == PostEffect::Bloom {
            self.record_bloom(gpu, cmd, index, p)?;
        }
        if self.compute {
            self.record_compute(cmd, index, chain, out, color);
        } else {
            self.record_tonemap_draw(gpu, cmd, index, chain, out, color)?;
        }
        Ok(())
    }

    /// Full-screen draws into `level` (one per view rect; multiview: one for both), reading
    /// through `set`, with the push constants `push_of(rect index)`.
    fn level_pass(&mut self, gpu: &Gpu, cmd: vk::CommandBuffer, level: &Level, set: vk::DescriptorSet, push_of: impl Fn(usize) -> PostPush) -> Result<()> {
        let pass = self.bloom_pass.as_mut().expect("bloom pass");
        pass.begin(gpu, cmd, level.image.view, vk::ImageView::null(), level.extent)?;
        self.draws(cmd, self.bloom_pipeline, set, &level.eyes, push_of);
        self.bloom_pass.as_ref().expect("bloom pass").end(gpu, cmd);
        let r = range(vk::ImageAspectFlags::COLOR, level.layers);
        self.barrier(cmd, S::COLOR_ATTACHMENT_OUTPUT, S::FRAGMENT_SHADER, &[image_barrier(level.image.image, r, CA, READ, A::COLOR_ATTACHMENT_WRITE, A::SHADER_READ)]);
        Ok(())
    }

    fn draws(&self, cmd: vk::CommandBuffer, pipeline: vk::Pipeline, set: vk::DescriptorSet, rects: &[EyeRect], push_of: impl Fn(usize) -> PostPush) {
        let d = &self.device;
        // SAFETY: recording inside a pass the pipeline was made for; the set's images are in
        // SHADER_READ_ONLY_OPTIMAL (barriers before the pass).
        unsafe {
            d.cmd_bind_pipeline(cmd, vk::PipelineBindPoint::GRAPHICS, pipeline);
            d.cmd_bind_descriptor_sets(cmd, vk::PipelineBindPoint::GRAPHICS, self.layouts[GRAPHICS], 0, &[set], &[]);
            for (i, (x, e)) in rects.iter().enumerate() {
                d.cmd_set_viewport(cmd, 0, &[vk::Viewport { x: *x as f32, y: 0.0, width: e.width as f32, height: e.height as f32, min_depth: 0.0, max_depth: 1.0 }]);
                d.cmd_set_scissor(cmd, 0, &[vk::Rect2D { offset: vk::Offset2D { x: *x, y: 0 }, extent: *e }]);
                d.cmd_push_constants(cmd, self.layouts[GRAPHICS], vk::ShaderStageFlags::FRAGMENT, 0, bytes(&push_of(i)));
                d.cmd_draw(cmd, 3, 1, 0, 0);
            }
        }
    }

    /// `--post bloom`: the down-sample chain from the scene (half, quarter, eighth), then the
    /// up-sample chain back to half size, each level read by the next.
    fn record_bloom(&mut self, gpu: &Gpu, cmd: vk::CommandBuffer, index: usize, p: &PostImages) -> Result<()> {
        let g = &p.geometry;
        // Last frame's draws read them: an execution dependency before they are written again.
        let to_attachment: Vec<_> = p
            .levels()
            .map(|l| image_barrier(l.image.image, range(vk::ImageAspectFlags::COLOR, g.layers), L::UNDEFINED, CA, A::empty(), A::COLOR_ATTACHMENT_READ | A::COLOR_ATTACHMENT_WRITE))
            .collect();
        self.barrier(cmd, S::FRAGMENT_SHADER, S::COLOR_ATTACHMENT_OUTPUT, &to_attachment);
        for k in 0..p.down.len() {
            let (src_eyes, src_extent) = if k == 0 { (&g.scene_eyes, g.scene_extent) } else { (&p.down[k - 1].eyes, p.down[k - 1].extent) };
            let dst = &p.down[k];
            let set = self.sets[index].down[k];
            self.level_pass(gpu, cmd, dst, set, |i| push(MODE_DOWN, 0, dst.eyes[i], (src_eyes[i], src_extent), (src_eyes[i], src_extent)))?;
        }
        for k in (0..p.up.len()).rev() {
            let src = if k + 1 == p.up.len() { &p.down[k + 1] } else { &p.up[k + 1] };
            let (dst, same) = (&p.up[k], &p.down[k]);
            let set = self.sets[index].up[k];
            self.level_pass(gpu, cmd, dst, set, |i| push(MODE_UP, 0, dst.eyes[i], (src.eyes[i], src.extent), (same.eyes[i], same.extent)))?;
        }
        Ok(())
    }

    /// The tonemap as a full-screen draw into the slot's final image (per view rect; multiview:
    /// one draw), then `--post taa`'s copy of the result into the history.
    fn record_tonemap_draw(&mut self, gpu: &Gpu, cmd: vk::CommandBuffer, index: usize, chain: &Slot, out: &Slot, color: u32) -> Result<()> {
        let p = chain.post.as_ref().expect("post images");
        let g = &p.geometry;
        let (image, view, extent, layers) = out.final_image(color);
        let depth_view = match &p.final_depth {
            Some(fd) => {
                // Cleared by the pass, never tested: only last frame's clear came before.
                let r = range(vk::ImageAspectFlags::DEPTH, layers);
                let tests = S::EARLY_FRAGMENT_TESTS | S::LATE_FRAGMENT_TESTS;
                let rw = A::DEPTH_STENCIL_ATTACHMENT_READ | A::DEPTH_STENCIL_ATTACHMENT_WRITE;
                self.barrier(cmd, tests, tests, &[image_barrier(fd.image, r, L::UNDEFINED, L::DEPTH_STENCIL_ATTACHMENT_OPTIMAL, A::DEPTH_STENCIL_ATTACHMENT_WRITE, rw)]);
                fd.view
            }
            None => vk::ImageView::null(),
        };
        self.final_pass.as_mut().expect("final pass").begin(gpu, cmd, view, depth_view, extent)?;
        let aux_of = |i: usize| match self.effect {
            PostEffect::Bloom => (p.up[0].eyes[i], p.up[0].extent),
            PostEffect::Taa => (g.final_eyes[i], g.final_extent),
            PostEffect::Tonemap => (g.scene_eyes[i], g.scene_extent),
        };
        let flags = self.flags & !super::FLAG_BGRA;
        let scene = |i: usize| (scaled_eye(g.scene_eyes[i], self.frame_scale), g.scene_extent);
        self.draws(cmd, self.final_pipeline, self.sets[index].final_set, &g.final_eyes, |i| push(MODE_FINAL, flags, g.final_eyes[i], scene(i), aux_of(i)));
        self.final_pass.as_ref().expect("final pass").end(gpu, cmd);
        if let Some(h) = &p.history {
            let r = range(vk::ImageAspectFlags::COLOR, layers);
            self.barrier(
                cmd,
                S::FRAGMENT_SHADER | S::COLOR_ATTACHMENT_OUTPUT,
                S::TRANSFER,
                &[
                    image_barrier(h.image, r, READ, L::TRANSFER_DST_OPTIMAL, A::empty(), A::TRANSFER_WRITE),
                    image_barrier(image, r, CA, L::TRANSFER_SRC_OPTIMAL, A::COLOR_ATTACHMENT_WRITE, A::TRANSFER_READ),
                ],
            );
            copy(&self.device, cmd, image, h.image, extent, layers);
            self.barrier(
                cmd,
                S::TRANSFER,
                S::FRAGMENT_SHADER | S::COLOR_ATTACHMENT_OUTPUT,
                &[
                    image_barrier(h.image, r, L::TRANSFER_DST_OPTIMAL, READ, A::TRANSFER_WRITE, A::SHADER_READ),
                    image_barrier(image, r, L::TRANSFER_SRC_OPTIMAL, CA, A::empty(), A::COLOR_ATTACHMENT_READ | A::COLOR_ATTACHMENT_WRITE),
                ],
            );
        }
        Ok(())
    }

    /// `--post-compute`: one dispatch per view rect (multiview: one, z over the layers) into the
    /// storage image, then a copy of all of it into the final image.
    fn record_compute(&self, cmd: vk::CommandBuffer, index: usize, chain: &Slot, out: &Slot, color: u32) {
        let d = &self.device;
        let p = chain.post.as_ref().expect("post images");
        let g = &p.geometry;
        let storage = p.storage.as_ref().expect("storage image");
        let (image, _, extent, layers) = out.final_image(color);
        let r = range(vk::ImageAspectFlags::COLOR, layers);
        // Last frame's copy read it.
        self.barrier(cmd, S::TRANSFER, S::COMPUTE_SHADER, &[image_barrier(storage.image, r, L::UNDEFINED, L::GENERAL, A::empty(), A::SHADER_WRITE)]);
        // SAFETY: recording outside any pass; the scene is SHADER_READ_ONLY_OPTIMAL, the storage
        // image GENERAL.
        unsafe {
            d.cmd_bind_pipeline(cmd, vk::PipelineBindPoint::COMPUTE, self.compute_pipeline);
            d.cmd_bind_descriptor_sets(cmd, vk::PipelineBindPoint::COMPUTE, self.layouts[COMPUTE], 0, &[self.sets[index].compute], &[]);
            for (i, dst) in g.final_eyes.iter().enumerate() {
                let src = (scaled_eye(g.scene_eyes[i], self.frame_scale), g.scene_extent);
                let pc = push(MODE_FINAL, self.flags, *dst, src, src);
                d.cmd_push_constants(cmd, self.layouts[COMPUTE], vk::ShaderStageFlags::COMPUTE, 0, bytes(&pc));
                d.cmd_dispatch(cmd, dst.1.width.div_ceil(8), dst.1.height.div_ceil(8), layers);
            }
        }
        self.barrier(
            cmd,
            S::COMPUTE_SHADER | S::COLOR_ATTACHMENT_OUTPUT,
            S::TRANSFER,
            &[
                image_barrier(storage.image, r, L::GENERAL, L::TRANSFER_SRC_OPTIMAL, A::SHADER_WRITE, A::TRANSFER_READ),
                image_barrier(image, r, CA, L::TRANSFER_DST_OPTIMAL, A::COLOR_ATTACHMENT_WRITE, A::TRANSFER_WRITE),
            ],
        );
        copy(d, cmd, storage.image, image, extent, layers);
        self.barrier(cmd, S::TRANSFER, S::COLOR_ATTACHMENT_OUTPUT, &[image_barrier(image, r, L::TRANSFER_DST_OPTIMAL, CA, A::TRANSFER_WRITE, A::COLOR_ATTACHMENT_READ | A::COLOR_ATTACHMENT_WRITE)]);
    }
}

/// All of `src` (TRANSFER_SRC_OPTIMAL) into `dst` (TRANSFER_DST_OPTIMAL), same size and layers.
fn copy(d: &ash::Device, cmd: vk::CommandBuffer, src: vk::Image, dst: vk::Image, extent: vk::Extent2D, layers: u32) {
    let sub = vk::ImageSubresourceLayers { aspect_mask: vk::ImageAspectFlags::COLOR, mip_level: 0, base_array_layer: 0, layer_count: layers };
    let region = vk::ImageCopy {
        src_subresource: sub,
        src_offset: vk::Offset3D::default(),
        dst_subresource: sub,
        dst_offset: vk::Offset3D::default(),
        extent: vk::Extent3D { width: extent.width, height: extent.height, depth: 1 },
    };
    // SAFETY: recording outside any pass; both images are in the layouts named, same size.
    unsafe { d.cmd_copy_image(cmd, src, L::TRANSFER_SRC_OPTIMAL, dst, L::TRANSFER_DST_OPTIMAL, &[region]) };
}

/// An eye rect's extent scaled by `f` from its top left (`--dynamic-resolution`).
fn scaled_eye((x, e): super::images::EyeRect, f: f32) -> super::images::EyeRect {
    (x, super::scale_extent(e, f))
}
