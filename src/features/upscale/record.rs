//! The upscale's recording (Vulkan): a frame's upscales into one command buffer of the layer's,
//! on the session's queue at `xrEndFrame`. A multisampled swapchain's images are first resolved
//! (`record_resolves`), and the resolve is read in their place. Swapchains whose runtime image takes a copy
//! (`Output::Copy`) go first, each phase batched across them (one barrier per phase, so the GPU
//! overlaps the eyes): the app's images to a shader-read layout, EASU (or its bilinear mode, or CAS) into
//! the RGBA16F intermediate, RCAS into texels of the runtime image's encoding, a copy into the
//! runtime's image, layouts back. The others (`Output::Fragment`) follow, one by one: EASU, then a
//! fragment pass drawing the runtime's image as a colour attachment. The app's images come back in
//! COLOR_ATTACHMENT_OPTIMAL (the layout the OpenXR Vulkan binding has at release and acquire), and
//! so do the runtime's.

use super::gpu::{self, EasuParams, RcasParams};
use super::lens::Tiles;
use std::sync::Arc;
use super::vk::{image_barrier, rect4, Job, Output, Pipelines, Prep, Target, PUSH_STAGES};
use super::Method;
use crate::plugin::vk::DeviceState;
use ash::vk;

/// One swapchain's upscale in a frame.
pub(crate) struct Work<'a> {
    pub target: &'a Target,
    /// The app image (and the runtime image: the runtime's acquire picks both).
    pub index: usize,
    pub jobs: &'a [Job],
    /// Per job: where EASU runs and RCAS sharpens (`EasuParams::fovea`; radius 0: everywhere).
    pub fovea: &'a [[f32; 4]],
    /// Per job: its tiles (`upscale.skip_hidden`; uploaded by `Target::record_tile_uploads`).
    pub tiles: &'a [Option<Arc<Tiles>>],
    /// How the frame finds the target's intermediates.
    pub prep: Prep,
    pub sharpness: f32,
}

impl Work<'_> {
    /// The image the upscale reads (the app's, or its resolve when multisampled) and the runtime's.
    fn images(&self) -> Option<(vk::Image, vk::Image)> {
        let app = self.target.app.get(self.index)?.ours;
        let source = if self.target.resolve.0 == vk::Image::null() { app } else { self.target.resolve.0 };
        Some((source, *self.target.desc.runtime_images.get(self.index)?))
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
    /// Job `k`'s pass (EASU's, or RCAS's): its push constants' `skip` and its workgroups (the
    /// tiles it runs, or the whole rect).
    fn pass(&self, k: usize, j: &Job, rcas: bool) -> ([i32; 4], (u32, u32)) {
        match self.target.tile_params(k, self.tiles.get(k).and_then(Option::as_ref), rcas) {
            Some((skip, n)) => (skip, (n, 1)),
            None => ([0; 4], gpu::groups(j.dst.width, j.dst.height)),
        }
    }
    /// The layout the frame finds an intermediate in: what the last upscale left (`last`), or
    /// UNDEFINED; TRANSFER_DST after this frame's clear.
    fn old_layout(&self, last: vk::ImageLayout) -> vk::ImageLayout {
        match (self.prep.clear, self.prep.defined) {
            (true, _) => vk::ImageLayout::TRANSFER_DST_OPTIMAL,
            (false, true) => last,
            (false, false) => vk::ImageLayout::UNDEFINED,
        }
    }
    /// The first pass's parameters for job `k`: EASU's (its bilinear mode everywhere for the
    /// bilinear method), or CAS's (its sharpness in the third vector).
    fn easu(&self, k: usize, j: &Job) -> EasuParams {
        let fovea = match self.target.desc.method {
            Method::Bilinear => [0.0, 0.0, -1.0, -1.0],
            Method::Cas => [self.sharpness, 0.0, 0.0, 0.0],
            Method::EasuRcas => self.fovea(k),
        };
        EasuParams { src_rect: rect4(j.src), dst_rect: rect4(j.dst), fovea, skip: self.pass(k, j, false).0 }
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

/// What earlier upscales (and this frame's clear) did to the intermediates.
const INTER: vk::AccessFlags = vk::AccessFlags::from_raw(
    vk::AccessFlags::SHADER_READ.as_raw() | vk::AccessFlags::SHADER_WRITE.as_raw() | vk::AccessFlags::TRANSFER_READ.as_raw() | vk::AccessFlags::TRANSFER_WRITE.as_raw(),
);

const COLOR: vk::AccessFlags = vk::AccessFlags::from_raw(vk::AccessFlags::COLOR_ATTACHMENT_WRITE.as_raw() | vk::AccessFlags::COLOR_ATTACHMENT_READ.as_raw());

/// Records `work` into `cb`; `mark(k)` writes the phase timestamps 1..3 (`slots::Slots::mark`).
///
/// # Safety
/// `cb` is recording (allocated through `d.fns`, for the session's queue family); each app image
/// was released by the app (its rendering submitted before) and each runtime image is acquired
/// and waited for; `p` and the targets are live objects of `d`'s device.
pub(crate) unsafe fn record_frame(d: &DeviceState, p: &Pipelines, cb: vk::CommandBuffer, work: &[Work<'_>], mark: &dyn Fn(u32)) {
    let copy: Vec<&Work<'_>> = work.iter().filter(|w| matches!(w.target.desc.output, Output::Copy { .. }) && w.images().is_some()).collect();
    // SAFETY: per the contract.
    unsafe {
        record_resolves(d, cb, work);
        record_clears(d, cb, work);
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

/// The multisampled swapchains' jobs resolved into their `Target::resolve` (all of them batched:
/// one barrier before, one after). The resolve is left in COLOR_ATTACHMENT_OPTIMAL, where the
/// upscale's phases take a single-sampled app image from; the app's image is back in it too.
///
/// # Safety
/// As for `record_frame`.
unsafe fn record_resolves(d: &DeviceState, cb: vk::CommandBuffer, work: &[Work<'_>]) {
    let msaa: Vec<(&Work<'_>, vk::Image)> = work.iter().filter(|w| w.target.resolve.0 != vk::Image::null()).filter_map(|w| Some((w, w.target.app.get(w.index)?.ours))).collect();
    if msaa.is_empty() {
        return;
    }
    let f = &d.fns;
    let (any, transfer) = (vk::PipelineStageFlags::ALL_COMMANDS, vk::PipelineStageFlags::TRANSFER);
    // SAFETY: per `record_frame`'s contract; every handle is a live object of `d`'s device.
    unsafe {
        let pre: Vec<_> = msaa
            .iter()
            .flat_map(|&(w, app)| {
                [
                    image_barrier(app, vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL, vk::ImageLayout::TRANSFER_SRC_OPTIMAL, COLOR, vk::AccessFlags::TRANSFER_READ, w.layers(), 1),
                    // Earlier upscales on this queue are done reading it (the barrier waits for
                    // every earlier command); its old contents are not needed.
                    image_barrier(w.target.resolve.0, vk::ImageLayout::UNDEFINED, vk::ImageLayout::TRANSFER_DST_OPTIMAL, vk::AccessFlags::SHADER_READ, vk::AccessFlags::TRANSFER_WRITE, w.layers(), 1),
                ]
            })
            .collect();
        f.cmd_pipeline_barrier(cb, any, transfer, vk::DependencyFlags::empty(), &[], &[], &pre);
        for &(w, app) in &msaa {
            let regions: Vec<vk::ImageResolve> = w
                .jobs
                .iter()
                .map(|j| {
                    let sub = vk::ImageSubresourceLayers { aspect_mask: vk::ImageAspectFlags::COLOR, mip_level: 0, base_array_layer: w.layer(j) as u32, layer_count: 1 };
                    let at = vk::Offset3D { x: j.src.x, y: j.src.y, z: 0 };
                    vk::ImageResolve { src_subresource: sub, src_offset: at, dst_subresource: sub, dst_offset: at, extent: vk::Extent3D { width: j.src.width, height: j.src.height, depth: 1 } }
                })
                .collect();
            f.cmd_resolve_image(cb, app, vk::ImageLayout::TRANSFER_SRC_OPTIMAL, w.target.resolve.0, vk::ImageLayout::TRANSFER_DST_OPTIMAL, &regions);
        }
        let post: Vec<_> = msaa
            .iter()
            .flat_map(|&(w, app)| {
                [
                    image_barrier(app, vk::ImageLayout::TRANSFER_SRC_OPTIMAL, vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL, vk::AccessFlags::empty(), COLOR, w.layers(), 1),
                    image_barrier(w.target.resolve.0, vk::ImageLayout::TRANSFER_DST_OPTIMAL, vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL, vk::AccessFlags::TRANSFER_WRITE, COLOR, w.layers(), 1),
                ]
            })
            .collect();
        f.cmd_pipeline_barrier(cb, transfer, any, vk::DependencyFlags::empty(), &[], &[], &post);
    }
}

/// The intermediates of the targets whose frame runs tile lists cleared black (`Prep::clear`):
/// the tiles no pass runs stay so. They are left in TRANSFER_DST_OPTIMAL (`Work::old_layout`).
///
/// # Safety
/// As for `record_frame`.
unsafe fn record_clears(d: &DeviceState, cb: vk::CommandBuffer, work: &[Work<'_>]) {
    let images: Vec<(vk::Image, vk::ImageLayout, u32)> = work
        .iter()
        .filter(|w| w.prep.clear)
        .flat_map(|w| {
            let last = |l| if w.prep.defined { l } else { vk::ImageLayout::UNDEFINED };
            [(w.target.a.0, last(vk::ImageLayout::GENERAL), w.layers()), (w.target.b.0, last(vk::ImageLayout::TRANSFER_SRC_OPTIMAL), w.layers())]
        })
        .filter(|(image, _, _)| *image != vk::Image::null())
        .collect();
    if images.is_empty() {
        return;
    }
    let f = &d.fns;
    let (any, transfer) = (vk::PipelineStageFlags::ALL_COMMANDS, vk::PipelineStageFlags::TRANSFER);
    let black = vk::ClearColorValue { float32: [0.0, 0.0, 0.0, 1.0] };
    // SAFETY: per `record_frame`'s contract; the intermediates are ours, made with TRANSFER_DST.
    unsafe {
        let pre: Vec<_> = images.iter().map(|&(image, old, layers)| image_barrier(image, old, vk::ImageLayout::TRANSFER_DST_OPTIMAL, INTER, vk::AccessFlags::TRANSFER_WRITE, layers, 1)).collect();
        f.cmd_pipeline_barrier(cb, any, transfer, vk::DependencyFlags::empty(), &[], &[], &pre);
        for &(image, _, layers) in &images {
            let range = vk::ImageSubresourceRange { aspect_mask: vk::ImageAspectFlags::COLOR, base_mip_level: 0, level_count: 1, base_array_layer: 0, layer_count: layers };
            f.cmd_clear_color_image(cb, image, vk::ImageLayout::TRANSFER_DST_OPTIMAL, &black, &[range]);
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
        // Earlier upscales on this queue are done with the intermediates (the barrier waits for
        // every earlier command); their contents are kept where no tile runs (`Prep`).
        let pre: Vec<_> = work
            .iter()
            .flat_map(|w| {
                let (t, (app, _)) = (w.target, images(w));
                [
                    image_barrier(app, vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL, vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL, COLOR, vk::AccessFlags::SHADER_READ, w.layers(), t.desc.mips),
                    image_barrier(t.a.0, w.old_layout(vk::ImageLayout::GENERAL), vk::ImageLayout::GENERAL, INTER, vk::AccessFlags::SHADER_WRITE | vk::AccessFlags::SHADER_READ, w.layers(), 1),
                    image_barrier(t.b.0, w.old_layout(vk::ImageLayout::TRANSFER_SRC_OPTIMAL), vk::ImageLayout::GENERAL, INTER, vk::AccessFlags::SHADER_WRITE, w.layers(), 1),
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
                let (gx, gy) = w.pass(k, j, false).1;
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
                let (skip, (gx, gy)) = w.pass(k, j, true);
                let params = RcasParams { rect: rect4(j.dst), sharpness: [sharpness, srgb as u32 as f32, swap_rb as u32 as f32, 0.0], fovea: w.fovea(k), skip };
                f.cmd_push_constants(cb, p.layout, PUSH_STAGES, 0, &params.bytes());
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
            pre.push(image_barrier(t.a.0, w.old_layout(vk::ImageLayout::GENERAL), vk::ImageLayout::GENERAL, INTER, vk::AccessFlags::SHADER_WRITE | vk::AccessFlags::SHADER_READ, layers, 1));
        }
        f.cmd_pipeline_barrier(cb, any, compute | fragment | output, vk::DependencyFlags::empty(), &[], &[], &pre);
        if easu {
            f.cmd_bind_pipeline(cb, vk::PipelineBindPoint::COMPUTE, w.first(p));
            for (k, j) in w.jobs.iter().enumerate() {
                f.cmd_bind_descriptor_sets(cb, vk::PipelineBindPoint::COMPUTE, p.layout, 0, &[t.easu_sets[w.index][w.layer(j)]], &[]);
                f.cmd_push_constants(cb, p.layout, PUSH_STAGES, 0, &w.easu(k, j).bytes());
                let (gx, gy) = w.pass(k, j, false).1;
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
                    (t.rcas_sets[layer as usize], RcasParams { rect: rect4(j.dst), sharpness: [w.rcas_sharpness(), 0.0, 0.0, 0.0], fovea: w.fovea(k), skip: [0; 4] }.bytes())
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
