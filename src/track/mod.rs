//! Per-device state the Vulkan half keeps about the app's objects and command buffers. Pure and
//! safe: the FFI shell (`crate::vk`) converts the app's create infos into the owned descriptions of
//! `resources` and reports recorded commands here, so all of it is unit-tested without a GPU.

pub mod caps;
pub mod cmd;
pub mod descriptors;
pub mod device_ext;
pub mod eye_pass;
pub mod eyes;
pub mod ext_state;
pub mod fallback;
pub mod flow;
pub mod resources;
pub mod traced;

use crate::core::handles::HandleMap;
use crate::bridge::Shared;
use ash::vk;
use cmd::{AttachmentUse, ClearValue, CmdState, DynamicRendering, PassInstance, PassKind, Rect};
use resources::{CommandPool, Framebuffer, FramebufferAttachments, GraphicsPipeline, Image, ImageView, RenderPass};
use std::sync::atomic::{AtomicU64, Ordering};
use std::collections::HashMap;
use std::sync::{Arc, Mutex, MutexGuard};

/// A command buffer and its recorded state. The app synchronizes use of a command buffer
/// externally, so the mutex is never contended; it exists because the state sits in a shared map.
#[derive(Debug)]
pub struct CommandBuffer {
    pub handle: u64,
    pub pool: u64,
    pub level: vk::CommandBufferLevel,
    state: Mutex<CmdState>,
}

impl CommandBuffer {
    pub fn new(handle: u64, pool: u64, level: vk::CommandBufferLevel) -> CommandBuffer {
        CommandBuffer { handle, pool, level, state: Mutex::new(CmdState::default()) }
    }
    /// Never held while calling down the chain.
    pub fn state(&self) -> MutexGuard<'_, CmdState> {
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }
}

/// Counters that show what the layer saw; logged at `vkDestroyDevice` (tests read the line).
#[derive(Debug, Default)]
pub struct Stats {
    pub render_pass_begins: AtomicU64,
    pub render_pass2_begins: AtomicU64,
    pub rendering_begins: AtomicU64,
    pub command_buffers_begun: AtomicU64,
    pub swapchain_attachments: AtomicU64,
    pub pipelines: AtomicU64,
}

impl Stats {
    fn bump(c: &AtomicU64, n: u64) {
        c.fetch_add(n, Ordering::Relaxed);
    }
    /// `key=value` pairs, stable names (tests parse them).
    pub fn summary(&self) -> String {
        let g = |c: &AtomicU64| c.load(Ordering::Relaxed);
        format!(
            "render_pass={} render_pass2={} dynamic_rendering={} command_buffers_begun={} swapchain_attachments={} pipelines={}",
            g(&self.render_pass_begins),
            g(&self.render_pass2_begins),
            g(&self.rendering_begins),
            g(&self.command_buffers_begun),
            g(&self.swapchain_attachments),
            g(&self.pipelines),
        )
    }
}

/// `vkCmdBeginRenderPass(2)` as recorded.
#[derive(Clone, Debug)]
pub struct RenderPassBegin {
    pub render_pass: u64,
    pub framebuffer: u64,
    pub render_area: Rect,
    pub clear_values: Vec<ClearValue>,
    /// `VkRenderPassAttachmentBeginInfo::pAttachments` (imageless framebuffers).
    pub attachment_views: Option<Vec<u64>>,
}

#[derive(Debug, Default)]
pub struct DeviceTracker {
    pub images: HandleMap<u64, Image>,
    pub views: HandleMap<u64, ImageView>,
    pub render_passes: HandleMap<u64, RenderPass>,
    pub framebuffers: HandleMap<u64, Framebuffer>,
    pub pipelines: HandleMap<u64, GraphicsPipeline>,
    pub pools: HandleMap<u64, CommandPool>,
    pub command_buffers: HandleMap<u64, CommandBuffer>,
    pub stats: Stats,
    /// Transfers (copy / resolve / blit) from other images into swapchain images, by source
    /// image: how intermediate eye targets are found.
    transfers: Mutex<HashMap<u64, Vec<Transfer>>>,
    /// Descriptor sets' images (what draws and dispatches read and write).
    pub descriptors: descriptors::Descriptors,
    /// What the data-flow walk learned (`traced`).
    pub traced: traced::Traced,
    /// What the eye decision logged, and the size fallback's order (`eyes`).
    pub eye_books: Mutex<eyes::EyeBooks>,
}

/// One recorded transfer region into a swapchain image.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Transfer {
    pub dst_image: u64,
    pub region: eye_pass::TransferRegion,
}

/// Distinct regions kept per source image (the newest win); apps transfer each target a few ways
/// at most.
const MAX_TRANSFERS: usize = 8;

impl DeviceTracker {
    /// Runs `f` on a tracked command buffer's state; None for one allocated before the layer saw it.
    pub fn with_cb<R>(&self, cb: u64, f: impl FnOnce(&mut CmdState) -> R) -> Option<R> {
        let cb = self.command_buffers.get(cb)?;
        let mut state = cb.state();
        Some(f(&mut state))
    }

    /// A created graphics pipeline (or library); one linked from libraries takes their state.
    pub fn add_pipeline(&self, mut p: GraphicsPipeline) {
        Stats::bump(&self.stats.pipelines, 1);
        if !p.libraries.is_empty() {
            let libs: Vec<Arc<GraphicsPipeline>> = p.libraries.iter().filter_map(|l| self.pipelines.get(*l)).collect();
            p.link(&libs.iter().map(|l| l.as_ref()).collect::<Vec<_>>());
        }
        self.pipelines.insert(p.handle, Arc::new(p));
    }

    /// `vkBeginCommandBuffer`; `flow`: the recording feeds the data-flow walk.
    pub fn begin_command_buffer(&self, cb: u64, usage: vk::CommandBufferUsageFlags, flow: bool) {
        if self.with_cb(cb, |s| {
            s.begin(usage);
            s.flow_on = flow;
        })
        .is_some()
        {
            Stats::bump(&self.stats.command_buffers_begun, 1);
        }
    }

    pub fn bind_graphics_pipeline(&self, cb: u64, pipeline: u64) {
        let desc = self.pipelines.get(pipeline);
        self.with_cb(cb, |s| s.bind_pipeline(pipeline, desc));
    }

    pub fn free_command_buffers(&self, cbs: &[u64]) {
        for cb in cbs {
            self.command_buffers.remove(*cb);
        }
    }

    /// The command buffers allocated from `pool`.
    pub fn buffers_of_pool(&self, pool: u64) -> Vec<u64> {
        self.command_buffers.values().into_iter().filter(|(_, cb)| cb.pool == pool).map(|(h, _)| h).collect()
    }

    /// `vkResetCommandPool`: every buffer of the pool goes back to the initial state.
    pub fn reset_pool(&self, pool: u64) {
        for (_, cb) in self.command_buffers.values() {
            if cb.pool == pool {
                cb.state().reset();
            }
        }
    }

    /// `vkDestroyCommandPool` frees its buffers.
    pub fn destroy_pool(&self, pool: u64) {
        self.pools.remove(pool);
        self.command_buffers.retain(|_, cb| cb.pool != pool);
    }

    /// Resolves an attachment's view down to its image and, if it is one, its swapchain image.
    pub fn attachment(
        &self,
        shared: &Shared,
        view: u64,
        layout: vk::ImageLayout,
        load_op: vk::AttachmentLoadOp,
        store_op: vk::AttachmentStoreOp,
        clear: Option<ClearValue>,
    ) -> AttachmentUse {
        let image_view = self.views.get(view);
        let swapchain = image_view.as_ref().and_then(|v| shared.images.get(v.image));
        AttachmentUse { view, image_view, swapchain, layout, load_op, store_op, clear }
    }

    /// `vkCmdBeginRenderPass` / `vkCmdBeginRenderPass2`.
    pub fn begin_render_pass(&self, shared: &Shared, cb: u64, kind: PassKind, begin: RenderPassBegin) {
        let pass = self.render_pass_instance(shared, kind, begin);
        self.open_pass(cb, pass, true);
    }

    /// The pass instance `vkCmdBeginRenderPass(2)` with `begin` opens (the app's attachments).
    pub fn render_pass_instance(&self, shared: &Shared, kind: PassKind, begin: RenderPassBegin) -> PassInstance {
        let render_pass = self.render_passes.get(begin.render_pass);
        let framebuffer = self.framebuffers.get(begin.framebuffer);
        let views: Vec<u64> = match (&begin.attachment_views, framebuffer.as_deref()) {
            (Some(v), _) => v.clone(),
            (None, Some(Framebuffer { attachments: FramebufferAttachments::Views(v), .. })) => v.clone(),
            _ => Vec::new(),
        };
        let attachments: Vec<AttachmentUse> = views
            .iter()
            .enumerate()
            .map(|(i, &view)| {
                let desc = render_pass.as_ref().and_then(|rp| rp.attachments.get(i).copied());
                let (layout, load, store) = desc.map_or(
                    (vk::ImageLayout::UNDEFINED, vk::AttachmentLoadOp::LOAD, vk::AttachmentStoreOp::STORE),
                    |d| (d.initial_layout, d.load_op, d.store_op),
                );
                let clears = desc.is_some_and(|d| {
                    d.load_op == vk::AttachmentLoadOp::CLEAR || d.stencil_load_op == vk::AttachmentLoadOp::CLEAR
                });
                let clear = if clears { begin.clear_values.get(i).copied() } else { None };
                self.attachment(shared, view, layout, load, store, clear)
            })
            .collect();
        PassInstance {
            kind,
            render_area: begin.render_area,
            subpass: 0,
            render_pass,
            framebuffer,
            attachments,
            clear_values: begin.clear_values,
            rendering: None,
            flow_at: None,
        }
    }

    /// `vkCmdBeginRendering`; attachments already resolved with [`Self::attachment`]. A resuming
    /// begin continues the instance a suspending one left open, so it is not counted again.
    pub fn begin_rendering(&self, cb: u64, render_area: Rect, rendering: DynamicRendering) {
        let count = !rendering.resuming();
        let pass = PassInstance {
            kind: PassKind::Dynamic,
            render_area,
            subpass: 0,
            render_pass: None,
            framebuffer: None,
            attachments: Vec::new(),
            clear_values: Vec::new(),
            rendering: Some(rendering),
            flow_at: None,
        };
        self.open_pass(cb, pass, count);
    }

    fn open_pass(&self, cb: u64, mut pass: PassInstance, count: bool) {
        let (kind, swapchain) = (pass.kind, pass.swapchain_attachments() as u64);
        let opened = self.with_cb(cb, |s| {
            if s.flow_on {
                let mut record = self.pass_record(&pass);
                if !record.depth_cleared && eye_pass::depth_loads(&pass) {
                    // Loaded from an image cleared by vkCmdClearDepthStencilImage just before.
                    let depth = record.depth.map(|d| d.image);
                    record.depth_cleared = s.depth_image_clears.iter().any(|(i, _)| Some(*i) == depth);
                }
                s.flow.begin_pass(record);
                pass.flow_at = s.flow.open_index().map(|op| flow::FlowAt { cb, op });
            }
            s.pass = Some(pass);
        });
        if opened.is_none() || !count {
            return;
        }
        let counter = match kind {
            PassKind::RenderPass => &self.stats.render_pass_begins,
            PassKind::RenderPass2 => &self.stats.render_pass2_begins,
            PassKind::Dynamic => &self.stats.rendering_begins,
        };
        Stats::bump(counter, 1);
        Stats::bump(&self.stats.swapchain_attachments, swapchain);
    }

    pub fn next_subpass(&self, cb: u64) {
        self.with_cb(cb, |s| {
            if let Some(p) = &mut s.pass {
                p.subpass += 1;
                if s.flow_on {
                    let record = self.pass_record(p);
                    s.flow.begin_pass(record);
                    p.flow_at = s.flow.open_index().map(|op| flow::FlowAt { cb, op });
                }
            }
        });
    }

    /// Records transfers from `src` into `dst` when `dst` is a swapchain image (the only ones that
    /// make `src` an intermediate eye target). The eye mapping is resolved at pass time against the
    /// swapchain's current eye uses, so a transfer recorded before the first `xrEndFrame` counts.
    pub fn record_transfer(&self, shared: &Shared, src: u64, dst: u64, regions: &[eye_pass::TransferRegion]) {
        if src == dst || shared.images.get(dst).is_none() || regions.is_empty() {
            return;
        }
        let mut t = self.transfers.lock().unwrap_or_else(|e| e.into_inner());
        let list = t.entry(src).or_default();
        for r in regions {
            // Per destination too: one target copied to each eye's own swapchain in turn keeps
            // both copies (its eyes share its pixels: `eyes::eyes_share_pixels`).
            list.retain(|x| x.region != *r || x.dst_image != dst);
            list.push(Transfer { dst_image: dst, region: *r });
        }
        let excess = list.len().saturating_sub(MAX_TRANSFERS);
        list.drain(..excess);
    }

    /// Forgets what was learned about a destroyed image.
    pub fn forget_image(&self, image: u64) {
        self.images.remove(image);
        self.traced.forget_image(image);
        self.transfers.lock().unwrap_or_else(|e| e.into_inner()).remove(&image);
    }

    /// What transfers say about the eyes `image` shows: None when it was never transferred into a
    /// swapchain image.
    pub fn intermediate_eyes(&self, shared: &Shared, image: u64) -> Option<eye_pass::Learned> {
        let transfers = self.transfers.lock().unwrap_or_else(|e| e.into_inner()).get(&image).cloned()?;
        let img = self.images.get(image)?;
        let mut eyes = Vec::new();
        let mut rejected = Vec::new();
        for t in &transfers {
            let Some(sc) = shared.images.get(t.dst_image) else { continue };
            match eye_pass::learn_intermediate(&[t.region], &sc.swapchain.uses(), (img.extent.width, img.extent.height), sc.swapchain.desc.sample_count) {
                eye_pass::Learned::Eyes(e) => eyes.extend(e),
                eye_pass::Learned::Rejected(w) => rejected.push(w),
            }
        }
        eyes.sort_by_key(|s| (s.layer, s.rect.x, s.rect.y, s.view));
        eyes.dedup();
        Some(if eyes.is_empty() { eye_pass::Learned::Rejected(rejected.join("; ")) } else { eye_pass::Learned::Eyes(eyes) })
    }

    pub fn end_pass(&self, cb: u64) {
        self.with_cb(cb, |s| {
            s.pass = None;
            s.flow.end_pass();
        });
    }

    /// A transfer (copy, blit, resolve) for the data-flow walk.
    pub fn flow_transfer(&self, cb: u64, src: u64, dst: u64, regions: &[eye_pass::TransferRegion]) {
        self.with_cb(cb, |s| {
            if s.flow_on && !regions.is_empty() {
                s.flow.transfer(src, dst, regions.to_vec());
            }
        });
    }

    /// What an attachment's view shows, for the data-flow walk.
    fn image_use(&self, a: &AttachmentUse) -> Option<flow::ImageUse> {
        self.view_use(a.image_view.as_ref()?)
    }

    /// What an image view shows, its `VK_REMAINING_ARRAY_LAYERS` resolved against the image.
    fn view_use(&self, v: &ImageView) -> Option<flow::ImageUse> {
        let layers = self.images.get(v.image).map_or(v.range.layer_count, |i| v.range.layers_of(i.array_layers));
        Some(flow::ImageUse { image: v.image, base_layer: v.range.base_array_layer, layers, mip: v.range.base_mip_level })
    }

    /// The data-flow record of the pass's current subpass / rendering.
    pub fn pass_record(&self, pass: &PassInstance) -> flow::PassRecord {
        let a = pass.render_area;
        let depth = eye_pass::depth_attachment(pass);
        let mut r = flow::PassRecord {
            view_mask: pass.view_mask(),
            render_area: crate::core::rect::PixelRect { x: a.x, y: a.y, width: a.width, height: a.height },
            depth_cleared: depth.is_some_and(|(_, starts, _)| starts),
            depth: depth.and_then(|(d, _, _)| self.image_use(d)),
            ..Default::default()
        };
        if let Some(dr) = &pass.rendering {
            for c in &dr.color {
                let Some(u) = self.image_use(&c.attachment) else { continue };
                r.colors.push(u);
                r.color_loads.push(c.attachment.load_op == vk::AttachmentLoadOp::LOAD || dr.resuming());
                if c.resolve_view != 0 && c.resolve_mode != vk::ResolveModeFlags::NONE {
                    if let Some(u) = self.views.get(c.resolve_view).and_then(|v| self.view_use(&v)) {
                        r.resolves.push((r.colors.len() - 1, u));
                    }
                }
            }
            return r;
        }
        let Some(rp) = pass.render_pass.as_ref() else { return r };
        let Some(sub) = rp.subpasses.get(pass.subpass as usize) else { return r };
        for (j, c) in sub.color.iter().enumerate() {
            let Some(i) = c.used() else { continue };
            let Some(u) = pass.attachments.get(i as usize).and_then(|a| self.image_use(a)) else { continue };
            r.colors.push(u);
            let load = rp.attachments.get(i as usize).is_some_and(|d| d.load_op == vk::AttachmentLoadOp::LOAD);
            r.color_loads.push(!eye_pass::first_use(rp, pass.subpass, i) || load);
            if let Some(ri) = sub.resolve.get(j).and_then(|x| x.used()) {
                if let Some(ru) = pass.attachments.get(ri as usize).and_then(|a| self.image_use(a)) {
                    r.resolves.push((r.colors.len() - 1, ru));
                }
            }
        }
        r.inputs = sub.input.iter().filter_map(|x| x.used()).filter_map(|i| pass.attachments.get(i as usize)).filter_map(|a| self.image_use(a)).collect();
        r
    }
}

#[cfg(test)]
mod tests {
    use super::resources::*;
    use super::*;
    use crate::bridge::Swapchain;
use crate::core::views::SwapchainDesc;

    fn tracker_with_pass() -> (DeviceTracker, Shared) {
        let t = DeviceTracker::default();
        let shared = Shared::default();
        let desc = SwapchainDesc { usage_flags: 0, format: 43, sample_count: 1, width: 64, height: 64, array_size: 2 };
        shared.add_swapchain(Arc::new(Swapchain::new(77, desc, vec![100])));
        for (handle, format) in [(100u64, vk::Format::R8G8B8A8_SRGB), (101, vk::Format::D32_SFLOAT)] {
            t.images.insert(
                handle,
                Arc::new(Image {
                    handle,
                    image_type: vk::ImageType::TYPE_2D,
                    format,
                    extent: vk::Extent3D { width: 64, height: 64, depth: 1 },
                    mip_levels: 1,
                    array_layers: 2,
                    samples: vk::SampleCountFlags::TYPE_1,
                    usage: vk::ImageUsageFlags::COLOR_ATTACHMENT,
                    flags: vk::ImageCreateFlags::empty(),
                }),
            );
            t.views.insert(
                handle + 100,
                Arc::new(ImageView {
                    handle: handle + 100,
                    image: handle,
                    view_type: vk::ImageViewType::TYPE_2D_ARRAY,
                    format,
                    range: SubresourceRange {
                        aspect_mask: vk::ImageAspectFlags::COLOR,
                        base_mip_level: 0,
                        level_count: 1,
                        base_array_layer: 0,
                        layer_count: 2,
                    },
                }),
            );
        }
        let att = |format, load_op| AttachmentDesc {
            format,
            samples: vk::SampleCountFlags::TYPE_1,
            load_op,
            store_op: vk::AttachmentStoreOp::STORE,
            stencil_load_op: vk::AttachmentLoadOp::DONT_CARE,
            stencil_store_op: vk::AttachmentStoreOp::DONT_CARE,
            initial_layout: vk::ImageLayout::UNDEFINED,
            final_layout: vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL,
        };
        t.render_passes.insert(
            1,
            Arc::new(RenderPass {
                handle: 1,
                version: RenderPassVersion::V1,
                attachments: vec![
                    att(vk::Format::R8G8B8A8_SRGB, vk::AttachmentLoadOp::CLEAR),
                    att(vk::Format::D32_SFLOAT, vk::AttachmentLoadOp::CLEAR),
                ],
                subpasses: vec![Subpass { view_mask: 0b11, ..Subpass::default() }],
                correlation_masks: vec![],
                layer_rate_attachment: None,
            }),
        );
        t.framebuffers.insert(
            2,
            Arc::new(Framebuffer {
                handle: 2,
                render_pass: 1,
                attachments: FramebufferAttachments::Views(vec![200, 201]),
                width: 64,
                height: 64,
                layers: 1,
            }),
        );
        t.pools.insert(5, Arc::new(CommandPool { handle: 5, flags: vk::CommandPoolCreateFlags::empty(), queue_family_index: 0 }));
        t.command_buffers.insert(9, Arc::new(CommandBuffer::new(9, 5, vk::CommandBufferLevel::PRIMARY)));
        (t, shared)
    }

    #[test]
    fn render_pass_begin_resolves_swapchain_attachments_and_clears() {
        let (t, shared) = tracker_with_pass();
        t.begin_command_buffer(9, vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT, false);
        let clears = vec![ClearValue([0; 4]), ClearValue([1.0f32.to_bits(), 0, 0, 0])];
        let area = Rect { x: 0, y: 0, width: 64, height: 64 };
        let begin = RenderPassBegin { render_pass: 1, framebuffer: 2, render_area: area, clear_values: clears, attachment_views: None };
        t.begin_render_pass(&shared, 9, PassKind::RenderPass, begin);
        t.with_cb(9, |s| {
            let p = s.pass.as_ref().unwrap();
            assert_eq!(p.view_mask(), 0b11);
            assert_eq!(p.swapchain_attachments(), 1);
            assert_eq!(p.attachments[0].swapchain.as_ref().unwrap().swapchain.handle, 77);
            assert_eq!(p.attachments[1].clear.unwrap().depth(), 1.0);
            assert_eq!(p.attachments[1].image_view.as_ref().unwrap().range.layer_count, 2);
        });
        t.end_pass(9);
        assert!(t.with_cb(9, |s| s.pass.is_none()).unwrap());
        assert!(t.stats.summary().contains("render_pass=1 render_pass2=0 dynamic_rendering=0 command_buffers_begun=1 swapchain_attachments=1"));
    }

    #[test]
    fn imageless_framebuffer_takes_views_from_begin() {
        let (t, shared) = tracker_with_pass();
        let begin = RenderPassBegin {
            render_pass: 1,
            framebuffer: 99,
            render_area: Rect::default(),
            clear_values: vec![],
            attachment_views: Some(vec![201, 200]),
        };
        t.begin_render_pass(&shared, 9, PassKind::RenderPass2, begin);
        t.with_cb(9, |s| {
            let p = s.pass.as_ref().unwrap();
            assert!(p.attachments[0].swapchain.is_none() && p.attachments[1].swapchain.is_some());
            // Clear requested but no clear value given: none recorded.
            assert_eq!(p.attachments[0].clear, None);
        });
        assert!(t.stats.summary().contains("render_pass2=1"));
    }

    #[test]
    fn dynamic_rendering_counts_resumed_instances_once() {
        let (t, shared) = tracker_with_pass();
        let color = |flags| DynamicRendering {
            flags,
            layer_count: 1,
            view_mask: 0b11,
            color: vec![cmd::RenderingAttachment {
                attachment: t.attachment(&shared, 200, vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL, vk::AttachmentLoadOp::CLEAR, vk::AttachmentStoreOp::STORE, Some(ClearValue::default())),
                resolve_mode: vk::ResolveModeFlags::NONE,
                resolve_view: 0,
                resolve_layout: vk::ImageLayout::UNDEFINED,
            }],
            depth: None,
            stencil: None,
        };
        t.begin_rendering(9, Rect::default(), color(vk::RenderingFlags::SUSPENDING));
        t.end_pass(9);
        t.begin_rendering(9, Rect::default(), color(vk::RenderingFlags::RESUMING));
        t.with_cb(9, |s| assert!(s.pass.as_ref().unwrap().rendering.as_ref().unwrap().resuming()));
        assert!(t.stats.summary().contains("dynamic_rendering=1"), "{}", t.stats.summary());
        assert!(t.stats.summary().contains("swapchain_attachments=1"));
    }

    #[test]
    fn transfers_into_swapchain_images_make_intermediate_targets() {
        use crate::core::views::{EyeUse, ImageRect};
        let (t, shared) = tracker_with_pass();
        // Image 101 (64×64) copied 1:1 into swapchain image 100: eyes known once uses are.
        let whole = crate::core::rect::PixelRect { x: 0, y: 0, width: 64, height: 64 };
        let region = eye_pass::TransferRegion { src_layer: 0, dst_layer: 0, layer_count: 2, src: whole, dst: whole };
        t.record_transfer(&shared, 101, 100, &[region]);
        t.record_transfer(&shared, 101, 100, &[region]);
        t.record_transfer(&shared, 101, 555, &[region]); // not a swapchain image: ignored
        assert_eq!(t.intermediate_eyes(&shared, 101), Some(eye_pass::Learned::Rejected("no eye use of the destination".into())));
        let rect = ImageRect { x: 0, y: 0, width: 64, height: 64 };
        shared.images.get(100).unwrap().swapchain.set_uses(vec![
            EyeUse { view: 0, image_rect: rect, image_array_index: 0, depth: false },
            EyeUse { view: 1, image_rect: rect, image_array_index: 1, depth: false },
        ]);
        let Some(eye_pass::Learned::Eyes(eyes)) = t.intermediate_eyes(&shared, 101) else { panic!("not learned") };
        assert_eq!(eyes.iter().map(|e| (e.view, e.layer)).collect::<Vec<_>>(), vec![(0, 0), (1, 1)]);
        assert_eq!(t.intermediate_eyes(&shared, 100), None, "never a transfer source");
        t.forget_image(101);
        assert_eq!(t.intermediate_eyes(&shared, 101), None);
    }

    #[test]
    fn pool_reset_and_destroy_reach_their_buffers() {
        let (t, _) = tracker_with_pass();
        t.begin_command_buffer(9, vk::CommandBufferUsageFlags::empty(), false);
        t.reset_pool(5);
        assert_eq!(t.with_cb(9, |s| s.recording), Some(false));
        t.destroy_pool(5);
        assert!(t.command_buffers.get(9).is_none() && t.pools.get(5).is_none());
        // Unknown command buffers are ignored, never invented.
        t.begin_command_buffer(9, vk::CommandBufferUsageFlags::empty(), false);
        assert!(t.command_buffers.is_empty());
        assert!(t.stats.summary().contains("command_buffers_begun=1"));
    }
}
