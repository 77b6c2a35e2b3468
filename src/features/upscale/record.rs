//! The upscale's recording (Vulkan): a frame's upscales into one command buffer of the layer's,
//! on the session's queue at `xrEndFrame`. Swapchains whose runtime image takes a copy
//! (`Output::Copy`) go first, each phase batched across them (one barrier per phase, so the GPU
//! overlaps the eyes): the app's images to a shader-read layout, EASU (or its bilinear mode, or CAS) into
//! the RGBA16F intermediate, RCAS into texels of the runtime image's encoding, a copy into the
//! runtime's image, layouts back. The others (`Output::Fragment`) follow, one by one: EASU, then a
//! fragment pass drawing the runtime's image as a colour attachment. The app's images come back in
//! COLOR_ATTACHMENT_OPTIMAL (the layout the OpenXR Vulkan binding has at release and acquire), and
//! so do the runtime's.

use super::gpu::{self, EasuParams, RcasParams};
use super::vk::{image_barrier, rect4, Job, Output, Pipelines, Target, PUSH_STAGES};
use super::Method;
use crate::vk::DeviceState;
use ash::vk;

/// One swapchain's upscale in a frame.
pub(crate) struct Work<'a> {
    pub target: &'a Target,
    /// The app image (and the runtime image: the runtime's acquire picks both).
    pub index: usize,
    pub jobs: &'a [Job],
    /// Per job: where EASU runs and RCAS sharpens (`EasuParams::fovea`; radius 0: everywhere).
    pub fovea: &'a [[f32; 4]],
    pub sharpness: f32,
}

impl Work<'_> {
    fn images(&self) -> Option<(vk::Image, vk::Image)> {
        Some((self.target.app.get(self.index)?.ours, *self.target.desc.runtime_images.get(self.index)?))
    }
    fn layers(&self) -> u32 {
        self.target.desc.layers.max(1)
    }
    fn layer(&self, j: &Job) -> usize {
        j.layer.min(self.layers() - 1) as usize
    }
    fn fovea(&self, k: usize) -> [f32; 4] {
        self.fovea.get(k).copied().unwrap_or_default()
    }
    /// The first pass's parameters for job `k`: EASU's (its bilinear mode everywhere for the
    /// bilinear method), or CAS's (its sharpness in the third vector).
    fn easu(&self, k: usize, j: &Job) -> EasuParams {
        let fovea = match self.target.desc.method {
            Method::Bilinear => [0.0, 0.0, -1.0, -1.0],
            Method::Cas => [self.sharpness, 0.0, 0.0, 0.0],
            Method::EasuRcas => self.fovea(k),
        };
        EasuParams { src_rect: rect4(j.src), dst_rect: rect4(j.dst), fovea }
    }
    /// The first pass's pipeline: CAS's for the CAS method, else EASU's.
    fn first(&self, p: &Pipelines) -> vk::Pipeline {
        if self.target.desc.method == Method::Cas {
            p.cas
        } else {
            p.easu
        }
    }
    /// RCAS's sharpness: none after CAS or bilinear (RCAS then only encodes).
    fn rcas_sharpness(&self) -> f32 {
        if self.target.desc.method == Method::EasuRcas {
            self.sharpness
        } else {
            0.0
        }
    }
}

const COLOR: vk::AccessFlags = vk::AccessFlags::from_raw(vk::AccessFlags::COLOR_ATTACHMENT_WRITE.as_raw() | vk::AccessFlags::COLOR_ATTACHMENT_READ.as_raw());

/// Records `work` into `cb`; `mark(k)` writes the phase timestamps 1..3 (`vk::Slots::mark`).
///
/// # Safety
/// `cb` is recording (allocated through `d.fns`, for the session's queue family); each app image
/// was released by the app (its rendering submitted before) and each runtime image is acquired
/// and waited for; `p` and the targets are live objects of `d`'s device.
pub(crate) unsafe fn record_frame(d: &DeviceState, p: &Pipelines, cb: vk::CommandBuffer, work: &[Work<'_>], mark: &dyn Fn(u32)) {
    let copy: Vec<&Work<'_>> = work.iter().filter(|w| matches!(w.target.desc.output, Output::Copy { .. }) && w.images().is_some()).collect();
    // SAFETY: per the contract.
    unsafe {
        if copy.is_empty() {
            (1..4).for_each(mark);
        } else {
            record_copies(d, p, cb, &copy, mark);
        }
        for w in work.iter().filter(|w| w.target.desc.output == Output::Fragment) {
            record_fragment(d, p, cb, w);
        }
    }
}

/// The swapchains of `Output::Copy`, phase by phase.
///
/// # Safety
/// As for `record_frame`.
unsafe fn record_copies(d: &DeviceState, p: &Pipelines, cb: vk::CommandBuffer, work: &[&Work<'_>], mark: &dyn Fn(u32)) {
    let f = &d.fns;
    let (any, compute, transfer) = (vk::PipelineStageFlags::ALL_COMMANDS, vk::PipelineStageFlags::COMPUTE_SHADER, vk::PipelineStageFlags::TRANSFER);
    let images = |w: &Work<'_>| w.images().expect("filtered");
    // SAFETY: per `record_frame`'s contract; every handle is a live object of `d`'s device.
    unsafe {
        // The intermediates' old contents are not needed: earlier upscales on this queue are done
        // with them (the barrier waits for every earlier command).
        let pre: Vec<_> = work
            .iter()
            .flat_map(|w| {
                let (t, (app, _)) = (w.target, images(w));
                [
                    image_barrier(app, vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL, vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL, COLOR, vk::AccessFlags::SHADER_READ, w.layers(), t.desc.mips),
                    image_barrier(t.a.0, vk::ImageLayout::UNDEFINED, vk::ImageLayout::GENERAL, vk::AccessFlags::SHADER_READ, vk::AccessFlags::SHADER_WRITE, w.layers(), 1),
                    image_barrier(t.b.0, vk::ImageLayout::UNDEFINED, vk::ImageLayout::GENERAL, vk::AccessFlags::TRANSFER_READ, vk::AccessFlags::SHADER_WRITE, w.layers(), 1),
                ]
            })
            .collect();
        f.cmd_pipeline_barrier(cb, any, compute, vk::DependencyFlags::empty(), &[], &[], &pre);
        mark(1);
        for w in work {
            f.cmd_bind_pipeline(cb, vk::PipelineBindPoint::COMPUTE, w.first(p));
            for (k, j) in w.jobs.iter().enumerate() {
                f.cmd_bind_descriptor_sets(cb, vk::PipelineBindPoint::COMPUTE, p.layout, 0, &[w.target.easu_sets[w.index][w.layer(j)]], &[]);
                f.cmd_push_constants(cb, p.layout, PUSH_STAGES, 0, &w.easu(k, j).bytes());
                let (gx, gy) = gpu::groups(j.dst.width, j.dst.height);
                f.cmd_dispatch(cb, gx, gy, 1);
            }
        }
        let mid: Vec<_> = work.iter().map(|w| image_barrier(w.target.a.0, vk::ImageLayout::GENERAL, vk::ImageLayout::GENERAL, vk::AccessFlags::SHADER_WRITE, vk::AccessFlags::SHADER_READ, w.layers(), 1)).collect();
        f.cmd_pipeline_barrier(cb, compute, compute, vk::DependencyFlags::empty(), &[], &[], &mid);
        mark(2);
        for w in work {
            let Output::Copy { inter, srgb, swap_rb } = w.target.desc.output else { continue };
            f.cmd_bind_pipeline(cb, vk::PipelineBindPoint::COMPUTE, if inter == vk::Format::R8G8B8A8_UNORM { p.rcas8 } else { p.rcas16 });
            let sharpness = w.rcas_sharpness();
            for (k, j) in w.jobs.iter().enumerate() {
                f.cmd_bind_descriptor_sets(cb, vk::PipelineBindPoint::COMPUTE, p.layout, 0, &[w.target.rcas_sets[w.layer(j)]], &[]);
                let params = RcasParams { rect: rect4(j.dst), sharpness: [sharpness, srgb as u32 as f32, swap_rb as u32 as f32, 0.0], fovea: w.fovea(k) };
                f.cmd_push_constants(cb, p.layout, PUSH_STAGES, 0, &params.bytes());
                let (gx, gy) = gpu::groups(j.dst.width, j.dst.height);
                f.cmd_dispatch(cb, gx, gy, 1);
            }
        }
        let to_copy: Vec<_> = work
            .iter()
            .flat_map(|w| {
                let (_, runtime) = images(w);
                [
                    image_barrier(w.target.b.0, vk::ImageLayout::GENERAL, vk::ImageLayout::TRANSFER_SRC_OPTIMAL, vk::AccessFlags::SHADER_WRITE, vk::AccessFlags::TRANSFER_READ, w.layers(), 1),
                    image_barrier(runtime, vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL, vk::ImageLayout::TRANSFER_DST_OPTIMAL, vk::AccessFlags::MEMORY_READ | COLOR, vk::AccessFlags::TRANSFER_WRITE, w.layers(), 1),
                ]
            })
            .collect();
        f.cmd_pipeline_barrier(cb, compute | any, transfer, vk::DependencyFlags::empty(), &[], &[], &to_copy);
        for w in work {
            let regions: Vec<vk::ImageCopy> = w
                .jobs
                .iter()
                .map(|j| {
                    let sub = vk::ImageSubresourceLayers { aspect_mask: vk::ImageAspectFlags::COLOR, mip_level: 0, base_array_layer: w.layer(j) as u32, layer_count: 1 };
                    let at = vk::Offset3D { x: j.dst.x, y: j.dst.y, z: 0 };
                    vk::ImageCopy { src_subresource: sub, src_offset: at, dst_subresource: sub, dst_offset: at, extent: vk::Extent3D { width: j.dst.width, height: j.dst.height, depth: 1 } }
                })
                .collect();
            f.cmd_copy_image(cb, w.target.b.0, vk::ImageLayout::TRANSFER_SRC_OPTIMAL, images(w).1, vk::ImageLayout::TRANSFER_DST_OPTIMAL, &regions);
        }
        mark(3);
        let post: Vec<_> = work
            .iter()
            .flat_map(|w| {
                let (app, runtime) = images(w);
                [
                    image_barrier(runtime, vk::ImageLayout::TRANSFER_DST_OPTIMAL, vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL, vk::AccessFlags::TRANSFER_WRITE, vk::AccessFlags::MEMORY_READ | COLOR, w.layers(), 1),
                    image_barrier(app, vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL, vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL, vk::AccessFlags::empty(), COLOR, w.layers(), w.target.desc.mips),
                ]
            })
            .collect();
        f.cmd_pipeline_barrier(cb, transfer | compute, any, vk::DependencyFlags::empty(), &[], &[], &post);
    }
}

/// One swapchain of `Output::Fragment`.
///
/// # Safety
/// As for `record_frame`.
unsafe fn record_fragment(d: &DeviceState, p: &Pipelines, cb: vk::CommandBuffer, w: &Work<'_>) {
    let (Some((app, runtime)), Some(fbs)) = (w.images(), w.target.framebuffers.get(w.index)) else { return };
    let t = w.target;
    let layers = w.layers();
    let f = &d.fns;
    let (any, compute, fragment, output) =
        (vk::PipelineStageFlags::ALL_COMMANDS, vk::PipelineStageFlags::COMPUTE_SHADER, vk::PipelineStageFlags::FRAGMENT_SHADER, vk::PipelineStageFlags::COLOR_ATTACHMENT_OUTPUT);
    let easu = t.desc.method != Method::Bilinear;
    // SAFETY: per `record_frame`'s contract; every handle is a live object of `d`'s device.
    unsafe {
        let mut pre = vec![
            image_barrier(app, vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL, vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL, COLOR, vk::AccessFlags::SHADER_READ, layers, t.desc.mips),
            // The runtime's image: whatever used it before (the compositor's reads) is done before
            // the pass writes it; it stays in its layout.
            image_barrier(runtime, vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL, vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL, vk::AccessFlags::MEMORY_READ | COLOR, COLOR, layers, 1),
        ];
        if easu {
            pre.push(image_barrier(t.a.0, vk::ImageLayout::UNDEFINED, vk::ImageLayout::GENERAL, vk::AccessFlags::SHADER_READ, vk::AccessFlags::SHADER_WRITE, layers, 1));
        }
        f.cmd_pipeline_barrier(cb, any, compute | fragment | output, vk::DependencyFlags::empty(), &[], &[], &pre);
        if easu {
            f.cmd_bind_pipeline(cb, vk::PipelineBindPoint::COMPUTE, w.first(p));
            for (k, j) in w.jobs.iter().enumerate() {
                f.cmd_bind_descriptor_sets(cb, vk::PipelineBindPoint::COMPUTE, p.layout, 0, &[t.easu_sets[w.index][w.layer(j)]], &[]);
                f.cmd_push_constants(cb, p.layout, PUSH_STAGES, 0, &w.easu(k, j).bytes());
                let (gx, gy) = gpu::groups(j.dst.width, j.dst.height);
                f.cmd_dispatch(cb, gx, gy, 1);
            }
            let mid = [image_barrier(t.a.0, vk::ImageLayout::GENERAL, vk::ImageLayout::GENERAL, vk::AccessFlags::SHADER_WRITE, vk::AccessFlags::SHADER_READ, layers, 1)];
            f.cmd_pipeline_barrier(cb, compute, fragment, vk::DependencyFlags::empty(), &[], &[], &mid);
        }
        let (width, height) = t.desc.runtime_extent;
        for layer in 0..layers {
            let mine: Vec<(usize, &Job)> = w.jobs.iter().enumerate().filter(|(_, j)| w.layer(j) == layer as usize).collect();
            let Some(&(_, fb)) = fbs.get(layer as usize) else { continue };
            if mine.is_empty() {
                continue;
            }
            let area = vk::Rect2D { offset: vk::Offset2D { x: 0, y: 0 }, extent: vk::Extent2D { width, height } };
            f.cmd_begin_render_pass(cb, &vk::RenderPassBeginInfo::default().render_pass(t.render_pass).framebuffer(fb).render_area(area), vk::SubpassContents::INLINE);
            f.cmd_bind_pipeline(cb, vk::PipelineBindPoint::GRAPHICS, t.pipeline);
            for (k, j) in mine {
                let r = j.dst;
                f.cmd_set_viewport(cb, 0, &[vk::Viewport { x: r.x as f32, y: r.y as f32, width: r.width as f32, height: r.height as f32, min_depth: 0.0, max_depth: 1.0 }]);
                f.cmd_set_scissor(cb, 0, &[vk::Rect2D { offset: vk::Offset2D { x: r.x, y: r.y }, extent: vk::Extent2D { width: r.width, height: r.height } }]);
                let (set, bytes) = if easu {
                    (t.rcas_sets[layer as usize], RcasParams { rect: rect4(j.dst), sharpness: [w.rcas_sharpness(), 0.0, 0.0, 0.0], fovea: w.fovea(k) }.bytes())
                } else {
                    (t.easu_sets[w.index][layer as usize], w.easu(k, j).bytes())
                };
                f.cmd_bind_descriptor_sets(cb, vk::PipelineBindPoint::GRAPHICS, p.layout, 0, &[set], &[]);
                f.cmd_push_constants(cb, p.layout, PUSH_STAGES, 0, &bytes);
                f.cmd_draw(cb, 3, 1, 0, 0);
            }
            f.cmd_end_render_pass(cb);
        }
        let post = [
            image_barrier(runtime, vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL, vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL, vk::AccessFlags::COLOR_ATTACHMENT_WRITE, vk::AccessFlags::MEMORY_READ | COLOR, layers, 1),
            image_barrier(app, vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL, vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL, vk::AccessFlags::empty(), COLOR, layers, t.desc.mips),
        ];
        f.cmd_pipeline_barrier(cb, output | compute | fragment, any, vk::DependencyFlags::empty(), &[], &[], &post);
    }
}
