//! Per-command-buffer graphics state: what the app has bound and set, and which render pass
//! instance is open. An injected draw (hidden-area mask, later features) changes pipeline,
//! viewports and dynamic state mid-pass; `restore_commands` says exactly what to record afterwards
//! so the app's next draw sees the state it set, and the frame stays bit-identical.

use super::resources::{Framebuffer, ImageView, RenderPass};
use crate::bridge::SwapchainImage;
use ash::vk;
use std::collections::BTreeMap;
use std::sync::Arc;

#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Viewport {
    pub x: f32,
    pub y: f32,
    pub width: f32,
    pub height: f32,
    pub min_depth: f32,
    pub max_depth: f32,
}

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Rect {
    pub x: i32,
    pub y: i32,
    pub width: u32,
    pub height: u32,
}

/// `VkClearValue` as its raw 16 bytes: which member the app meant is only known from the
/// attachment's format, so both readings are offered.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ClearValue(pub [u32; 4]);

impl ClearValue {
    pub fn color_f32(&self) -> [f32; 4] {
        self.0.map(f32::from_bits)
    }
    pub fn depth(&self) -> f32 {
        f32::from_bits(self.0[0])
    }
    pub fn stencil(&self) -> u32 {
        self.0[1]
    }
}

/// One state-setting command, as recorded and as replayed. Stencil state is kept per face
/// (`face` is FRONT or BACK, never both) because the app may set the faces separately.
#[derive(Clone, Debug, PartialEq)]
pub enum StateCmd {
    BindPipeline(u64),
    SetViewport { first: u32, viewports: Vec<Viewport> },
    SetViewportWithCount(Vec<Viewport>),
    SetScissor { first: u32, scissors: Vec<Rect> },
    SetScissorWithCount(Vec<Rect>),
    LineWidth(f32),
    DepthBias { constant_factor: f32, clamp: f32, slope_factor: f32 },
    BlendConstants([f32; 4]),
    DepthBounds { min: f32, max: f32 },
    StencilCompareMask { face: vk::StencilFaceFlags, mask: u32 },
    StencilWriteMask { face: vk::StencilFaceFlags, mask: u32 },
    StencilReference { face: vk::StencilFaceFlags, reference: u32 },
    CullMode(vk::CullModeFlags),
    FrontFace(vk::FrontFace),
    PrimitiveTopology(vk::PrimitiveTopology),
    DepthTestEnable(bool),
    DepthWriteEnable(bool),
    DepthCompareOp(vk::CompareOp),
    DepthBoundsTestEnable(bool),
    StencilTestEnable(bool),
    StencilOp {
        face: vk::StencilFaceFlags,
        fail_op: vk::StencilOp,
        pass_op: vk::StencilOp,
        depth_fail_op: vk::StencilOp,
        compare_op: vk::CompareOp,
    },
    RasterizerDiscardEnable(bool),
    DepthBiasEnable(bool),
    PrimitiveRestartEnable(bool),
    LineStipple { factor: u32, pattern: u16 },
    ColorWriteEnable(Vec<bool>),
    LogicOp(vk::LogicOp),
    PatchControlPoints(u32),
    PushConstants { layout: u64, stages: vk::ShaderStageFlags, offset: u32, data: Vec<u8> },
    /// `vkCmdBindVertexBuffers` (sizes and strides None) or `vkCmdBindVertexBuffers2`. Not
    /// dynamic state, but an injected draw binds its own vertex buffer, so it is restored too.
    BindVertexBuffers { first: u32, bindings: Vec<VertexBinding> },
    /// `vkCmdBindDescriptorSets(GRAPHICS)`. Restored only after an injection that bound sets of
    /// its own (the layer's pipelines so far use none, which disturbs nothing).
    BindDescriptorSets { layout: u64, first: u32, sets: Vec<u64>, dynamic_offsets: Vec<u32> },
    /// Extended dynamic state 3 and vertex input dynamic state (`track::ext_state`).
    Ext(super::ext_state::ExtState),
    /// `vkCmdBindShadersEXT`: shader objects bound per stage (a null handle unbinds). Not dynamic
    /// state: binding a pipeline unbinds them, so the layer's pipeline needs them rebound.
    BindShaders { stages: Vec<vk::ShaderStageFlags>, shaders: Vec<u64> },
}

/// One vertex buffer binding slot as the app set it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct VertexBinding {
    pub buffer: u64,
    pub offset: u64,
    /// `vkCmdBindVertexBuffers2` only (`pSizes`; None = whole size / not given).
    pub size: Option<u64>,
    /// `vkCmdBindVertexBuffers2` only (`pStrides`).
    pub stride: Option<u64>,
    /// Bound with `vkCmdBindVertexBuffers2` (replayed the same way).
    pub v2: bool,
}

impl StateCmd {
    /// The `VkDynamicState` a pipeline must list for this command's value to survive binding it;
    /// None for commands that are not dynamic state (pipeline, push constants).
    pub fn dynamic_state(&self) -> Option<vk::DynamicState> {
        use vk::DynamicState as D;
        Some(match self {
            StateCmd::BindPipeline(_)
            | StateCmd::PushConstants { .. }
            | StateCmd::BindVertexBuffers { .. }
            | StateCmd::BindDescriptorSets { .. }
            | StateCmd::BindShaders { .. } => return None,
            StateCmd::Ext(e) => e.dynamic_state(),
            StateCmd::SetViewport { .. } => D::VIEWPORT,
            StateCmd::SetViewportWithCount(_) => D::VIEWPORT_WITH_COUNT,
            StateCmd::SetScissor { .. } => D::SCISSOR,
            StateCmd::SetScissorWithCount(_) => D::SCISSOR_WITH_COUNT,
            StateCmd::LineWidth(_) => D::LINE_WIDTH,
            StateCmd::DepthBias { .. } => D::DEPTH_BIAS,
            StateCmd::BlendConstants(_) => D::BLEND_CONSTANTS,
            StateCmd::DepthBounds { .. } => D::DEPTH_BOUNDS,
            StateCmd::StencilCompareMask { .. } => D::STENCIL_COMPARE_MASK,
            StateCmd::StencilWriteMask { .. } => D::STENCIL_WRITE_MASK,
            StateCmd::StencilReference { .. } => D::STENCIL_REFERENCE,
            StateCmd::CullMode(_) => D::CULL_MODE,
            StateCmd::FrontFace(_) => D::FRONT_FACE,
            StateCmd::PrimitiveTopology(_) => D::PRIMITIVE_TOPOLOGY,
            StateCmd::DepthTestEnable(_) => D::DEPTH_TEST_ENABLE,
            StateCmd::DepthWriteEnable(_) => D::DEPTH_WRITE_ENABLE,
            StateCmd::DepthCompareOp(_) => D::DEPTH_COMPARE_OP,
            StateCmd::DepthBoundsTestEnable(_) => D::DEPTH_BOUNDS_TEST_ENABLE,
            StateCmd::StencilTestEnable(_) => D::STENCIL_TEST_ENABLE,
            StateCmd::StencilOp { .. } => D::STENCIL_OP,
            StateCmd::RasterizerDiscardEnable(_) => D::RASTERIZER_DISCARD_ENABLE,
            StateCmd::DepthBiasEnable(_) => D::DEPTH_BIAS_ENABLE,
            StateCmd::PrimitiveRestartEnable(_) => D::PRIMITIVE_RESTART_ENABLE,
            StateCmd::LineStipple { .. } => D::LINE_STIPPLE_EXT,
            StateCmd::ColorWriteEnable(_) => D::COLOR_WRITE_ENABLE_EXT,
            StateCmd::LogicOp(_) => D::LOGIC_OP_EXT,
            StateCmd::PatchControlPoints(_) => D::PATCH_CONTROL_POINTS_EXT,
        })
    }

    /// What tells apart values of one dynamic state kept side by side: the colour attachment of
    /// a per-attachment state (stencil faces are split by `face`).
    fn attachment(&self) -> u32 {
        match self {
            StateCmd::Ext(e) => e.attachment(),
            _ => 0,
        }
    }

    fn face(&self) -> Option<vk::StencilFaceFlags> {
        match self {
            StateCmd::StencilCompareMask { face, .. }
            | StateCmd::StencilWriteMask { face, .. }
            | StateCmd::StencilReference { face, .. }
            | StateCmd::StencilOp { face, .. } => Some(*face),
            _ => None,
        }
    }

    fn with_face(&self, face: vk::StencilFaceFlags) -> StateCmd {
        let mut c = self.clone();
        match &mut c {
            StateCmd::StencilCompareMask { face: f, .. }
            | StateCmd::StencilWriteMask { face: f, .. }
            | StateCmd::StencilReference { face: f, .. }
            | StateCmd::StencilOp { face: f, .. } => *f = face,
            _ => {}
        }
        c
    }
}

/// How a render pass instance was begun.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PassKind {
    /// `vkCmdBeginRenderPass`
    RenderPass,
    /// `vkCmdBeginRenderPass2`
    RenderPass2,
    /// `vkCmdBeginRendering`
    Dynamic,
}

/// An attachment of the open pass, resolved down to the image: what eye-pass detection and the
/// mask need (which swapchain image and layer, which depth buffer is cleared to what).
#[derive(Clone, Debug)]
pub struct AttachmentUse {
    pub view: u64,
    /// Resolved from the tracked view; None if the view was never seen (created before the layer).
    pub image_view: Option<Arc<ImageView>>,
    /// Swapchain image behind the view, looked up when the pass began.
    pub swapchain: Option<Arc<SwapchainImage>>,
    pub layout: vk::ImageLayout,
    pub load_op: vk::AttachmentLoadOp,
    pub store_op: vk::AttachmentStoreOp,
    pub clear: Option<ClearValue>,
}

impl PartialEq for AttachmentUse {
    fn eq(&self, o: &Self) -> bool {
        self.view == o.view && self.layout == o.layout && self.load_op == o.load_op && self.store_op == o.store_op && self.clear == o.clear
    }
}

/// `VkRenderingAttachmentInfo` of `vkCmdBeginRendering`.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderingAttachment {
    pub attachment: AttachmentUse,
    pub resolve_mode: vk::ResolveModeFlags,
    pub resolve_view: u64,
    pub resolve_layout: vk::ImageLayout,
}

#[derive(Clone, Debug, PartialEq)]
pub struct DynamicRendering {
    pub flags: vk::RenderingFlags,
    pub layer_count: u32,
    pub view_mask: u32,
    pub color: Vec<RenderingAttachment>,
    pub depth: Option<RenderingAttachment>,
    pub stencil: Option<RenderingAttachment>,
}

impl DynamicRendering {
    pub fn suspending(&self) -> bool {
        self.flags.contains(vk::RenderingFlags::SUSPENDING)
    }
    pub fn resuming(&self) -> bool {
        self.flags.contains(vk::RenderingFlags::RESUMING)
    }
}

/// The open render pass instance of a command buffer.
#[derive(Clone, Debug)]
pub struct PassInstance {
    pub kind: PassKind,
    pub render_area: Rect,
    pub subpass: u32,
    pub render_pass: Option<Arc<RenderPass>>,
    pub framebuffer: Option<Arc<Framebuffer>>,
    /// Render-pass attachments in attachment order (from the framebuffer or the
    /// `VkRenderPassAttachmentBeginInfo` of an imageless one), with load ops and clear values.
    pub attachments: Vec<AttachmentUse>,
    pub clear_values: Vec<ClearValue>,
    pub rendering: Option<DynamicRendering>,
    /// Where its (current subpass's) record is in the command buffer's data flow, when that is
    /// recorded: a target both eyes take turns in is tied to an eye per use, by this.
    pub flow_at: Option<super::flow::FlowAt>,
}

impl PassInstance {
    /// The view mask in effect for the current subpass / rendering.
    pub fn view_mask(&self) -> u32 {
        match (&self.rendering, &self.render_pass) {
            (Some(r), _) => r.view_mask,
            (None, Some(rp)) => rp.subpasses.get(self.subpass as usize).map_or(0, |s| s.view_mask),
            _ => 0,
        }
    }
    /// Attachments that are views of OpenXR swapchain images.
    pub fn swapchain_attachments(&self) -> usize {
        let rendering = self.rendering.iter().flat_map(|r| r.color.iter().chain(&r.depth).chain(&r.stencil));
        self.attachments
            .iter()
            .chain(rendering.map(|r| &r.attachment))
            .filter(|a| a.swapchain.is_some())
            .count()
    }
}

/// What a command buffer has recorded that a draw depends on.
#[derive(Clone, Debug, Default)]
pub struct CmdState {
    pub recording: bool,
    pub usage: vk::CommandBufferUsageFlags,
    pub pipeline: Option<Arc<super::resources::GraphicsPipeline>>,
    pub pipeline_handle: Option<u64>,
    /// Viewport slots set by `vkCmdSetViewport` / `WithCount` (latest value per slot).
    viewports: Vec<Option<Viewport>>,
    viewport_count: Option<u32>,
    scissors: Vec<Option<Rect>>,
    scissor_count: Option<u32>,
    /// Other dynamic state, keyed by (`VkDynamicState`, stencil face) so restoring is ordered and
    /// deterministic.
    dynamic: BTreeMap<(i32, u32), StateCmd>,
    /// Push constant updates still in effect, oldest first; ones fully covered by a later update of
    /// the same stages and layout are dropped.
    push_constants: Vec<StateCmd>,
    /// Vertex buffer binding slots.
    vertex_buffers: Vec<Option<VertexBinding>>,
    pub pass: Option<PassInstance>,
    /// Depth values written by `vkCmdClearDepthStencilImage` since the image was last used as an
    /// attachment in this command buffer: image → depth. A later pass that loads the image starts
    /// from that clear.
    pub depth_image_clears: Vec<(u64, f32)>,
    /// The first command the app recorded whose state the layer cannot restore after an injected
    /// draw (the app's own shading rate, NVIDIA's extended dynamic state 3 commands, attachment
    /// remapping of `VK_KHR_dynamic_rendering_local_read`): injections into this command buffer
    /// are vetoed (`vk::chassis`).
    pub veto: Option<&'static str>,
    /// Shader objects bound per stage (`vkCmdBindShadersEXT`; null: bound as none), in the order
    /// first bound; cleared by binding a graphics pipeline, which unbinds them.
    shaders: Vec<(vk::ShaderStageFlags, u64)>,
    /// Shader objects, not a pipeline, are what draws use now.
    shader_objects: bool,
    /// Descriptor set bindings still in effect, oldest first (a bind fully covered by a later
    /// one of the same sets is dropped).
    descriptor_sets: Vec<StateCmd>,
    /// The compute bind point's state, which a dispatch of the layer's outside passes replaces.
    pub compute: ComputeState,
    /// Whether this recording feeds the data-flow walk (something injects): decided at begin.
    pub flow_on: bool,
    /// What the recording reads and writes, for the data-flow walk (`track::flow`).
    pub flow: super::flow::Recorder,
    /// Push descriptors' images in effect: (bind point, set number) → images.
    pub pushed: Vec<((i32, u32), Vec<super::descriptors::BoundImage>)>,
}

/// What the app bound at `VK_PIPELINE_BIND_POINT_COMPUTE` (restored after the layer's own
/// dispatches in its command buffer, `plugin::vk::inject::restore::RestoreCompute`).
#[derive(Clone, Debug, Default)]
pub struct ComputeState {
    pub pipeline: Option<u64>,
    /// The compute shader object bound after `pipeline` (`vkCmdBindShadersEXT` with the compute
    /// stage; 0: bound as none), which replaces it: what is rebound then.
    pub shader: Option<u64>,
    /// `StateCmd::BindDescriptorSets` at the compute bind point still in effect, oldest first.
    pub sets: Vec<StateCmd>,
}

impl ComputeState {
    pub fn bind_sets(&mut self, cmd: StateCmd) {
        keep_binding(&mut self.sets, cmd);
    }
}

/// Adds a descriptor set binding to `list`, dropping earlier ones it fully covers.
fn keep_binding(list: &mut Vec<StateCmd>, cmd: StateCmd) {
    if let StateCmd::BindDescriptorSets { first, ref sets, .. } = cmd {
        let end = first + sets.len() as u32;
        list.retain(|b| match b {
            StateCmd::BindDescriptorSets { first: f, sets: s, .. } => !(*f >= first && *f + s.len() as u32 <= end),
            _ => true,
        });
    }
    if list.len() >= MAX_PUSHES {
        list.remove(0);
    }
    list.push(cmd);
}

const MAX_PUSHES: usize = 64;

fn put<T: Clone>(slots: &mut Vec<Option<T>>, first: u32, values: &[T]) {
    let end = first as usize + values.len();
    if slots.len() < end {
        slots.resize(end, None);
    }
    for (i, v) in values.iter().enumerate() {
        slots[first as usize + i] = Some(v.clone());
    }
}

/// Contiguous runs of known slots at or after `from`: (first, values).
fn runs<T: Clone>(slots: &[Option<T>], from: usize) -> Vec<(u32, Vec<T>)> {
    let mut out: Vec<(u32, Vec<T>)> = Vec::new();
    let mut cur: Option<(u32, Vec<T>)> = None;
    for (i, s) in slots.iter().enumerate().skip(from) {
        match (s, &mut cur) {
            (Some(v), Some((_, vs))) => vs.push(v.clone()),
            (Some(v), None) => cur = Some((i as u32, vec![v.clone()])),
            (None, _) => out.extend(cur.take()),
        }
    }
    out.extend(cur);
    out
}

impl CmdState {
    /// `vkBeginCommandBuffer`: implicit reset, then recording.
    pub fn begin(&mut self, usage: vk::CommandBufferUsageFlags) {
        *self = CmdState { recording: true, usage, ..CmdState::default() };
    }
    /// `vkResetCommandBuffer` / pool reset.
    pub fn reset(&mut self) {
        *self = CmdState::default();
    }

    /// Records a state-setting command the app recorded.
    pub fn record(&mut self, cmd: StateCmd) {
        match cmd {
            StateCmd::BindPipeline(_) => unreachable_bind(),
            StateCmd::SetViewport { first, viewports } => put(&mut self.viewports, first, &viewports),
            StateCmd::SetViewportWithCount(v) => {
                put(&mut self.viewports, 0, &v);
                self.viewport_count = Some(v.len() as u32);
            }
            StateCmd::SetScissor { first, scissors } => put(&mut self.scissors, first, &scissors),
            StateCmd::BindVertexBuffers { first, bindings } => put(&mut self.vertex_buffers, first, &bindings),
            StateCmd::SetScissorWithCount(s) => {
                put(&mut self.scissors, 0, &s);
                self.scissor_count = Some(s.len() as u32);
            }
            StateCmd::BindDescriptorSets { .. } => keep_binding(&mut self.descriptor_sets, cmd),
            StateCmd::BindShaders { stages, shaders } => {
                for (stage, shader) in stages.into_iter().zip(shaders) {
                    if stage == vk::ShaderStageFlags::COMPUTE {
                        // The compute bind point's: it replaces the compute pipeline.
                        self.compute.shader = Some(shader);
                        continue;
                    }
                    match self.shaders.iter_mut().find(|(s, _)| *s == stage) {
                        Some(slot) => slot.1 = shader,
                        None => self.shaders.push((stage, shader)),
                    }
                    self.shader_objects = true;
                }
            }
            StateCmd::PushConstants { layout, stages, offset, ref data } => {
                let end = offset + data.len() as u32;
                self.push_constants.retain(|p| match p {
                    StateCmd::PushConstants { layout: l, stages: s, offset: o, data: d } => {
                        !(*l == layout && *s == stages && *o >= offset && *o + d.len() as u32 <= end)
                    }
                    _ => true,
                });
                if self.push_constants.len() >= MAX_PUSHES {
                    self.push_constants.remove(0);
                }
                self.push_constants.push(cmd);
            }
            other => {
                let ds = other.dynamic_state().expect("dynamic state").as_raw();
                match other.face() {
                    Some(face) => {
                        for f in [vk::StencilFaceFlags::FRONT, vk::StencilFaceFlags::BACK] {
                            if face.contains(f) {
                                self.dynamic.insert((ds, f.as_raw()), other.with_face(f));
                            }
                        }
                    }
                    None => {
                        self.dynamic.insert((ds, other.attachment()), other);
                    }
                }
            }
        }
    }

    /// `vkCmdBindPipeline(GRAPHICS)`. Binding a pipeline overwrites every piece of state it does
    /// not declare dynamic with its own static value, so that state no longer needs restoring
    /// (rebinding the pipeline restores it). An untracked pipeline keeps everything: replaying
    /// state the pipeline treats as static is harmless, forgetting state it needs is not.
    pub fn bind_pipeline(&mut self, handle: u64, pipeline: Option<Arc<super::resources::GraphicsPipeline>>) {
        if let Some(p) = &pipeline {
            self.dynamic.retain(|(ds, _), _| p.is_dynamic(vk::DynamicState::from_raw(*ds)));
            if !p.is_dynamic(vk::DynamicState::VIEWPORT) && !p.is_dynamic(vk::DynamicState::VIEWPORT_WITH_COUNT) {
                self.viewports.clear();
            }
            if !p.is_dynamic(vk::DynamicState::VIEWPORT_WITH_COUNT) {
                self.viewport_count = None;
            }
            if !p.is_dynamic(vk::DynamicState::SCISSOR) && !p.is_dynamic(vk::DynamicState::SCISSOR_WITH_COUNT) {
                self.scissors.clear();
            }
            if !p.is_dynamic(vk::DynamicState::SCISSOR_WITH_COUNT) {
                self.scissor_count = None;
            }
        }
        self.pipeline_handle = Some(handle);
        self.pipeline = pipeline;
        self.shaders.clear();
        self.shader_objects = false;
    }

    /// `vkCmdExecuteCommands`: afterwards the primary's bound pipeline and dynamic state are
    /// undefined, so nothing of it may be restored.
    pub fn forget_graphics_state(&mut self) {
        let (recording, usage, pass) = (self.recording, self.usage, self.pass.take());
        let depth_image_clears = std::mem::take(&mut self.depth_image_clears);
        let (flow_on, flow) = (self.flow_on, std::mem::take(&mut self.flow));
        // Secondaries may use state the layer cannot restore; the veto stays as it was.
        let veto = self.veto;
        *self = CmdState { recording, usage, pass, depth_image_clears, veto, flow_on, flow, ..CmdState::default() };
    }

    /// The descriptor sets bound now at the graphics (or compute) bind point, by set number.
    pub fn bound_sets(&self, compute: bool) -> Vec<u64> {
        let list = if compute { &self.compute.sets } else { &self.descriptor_sets };
        let mut slots: Vec<u64> = Vec::new();
        for b in list {
            if let StateCmd::BindDescriptorSets { first, sets, .. } = b {
                let end = *first as usize + sets.len();
                if slots.len() < end {
                    slots.resize(end, 0);
                }
                slots[*first as usize..end].copy_from_slice(sets);
            }
        }
        slots.retain(|s| *s != 0);
        slots
    }

    /// Push descriptors' images in effect at a bind point.
    pub fn pushed_images(&self, bind_point: vk::PipelineBindPoint) -> Vec<super::descriptors::BoundImage> {
        self.pushed.iter().filter(|((bp, _), _)| *bp == bind_point.as_raw()).flat_map(|(_, i)| i.iter().copied()).collect()
    }

    /// `vkCmdPushDescriptorSetKHR`: replaces what was pushed to that set number.
    pub fn push_descriptors(&mut self, bind_point: vk::PipelineBindPoint, set: u32, images: Vec<super::descriptors::BoundImage>) {
        let key = (bind_point.as_raw(), set);
        self.pushed.retain(|(k, _)| *k != key);
        if self.pushed.len() < MAX_PUSHES {
            self.pushed.push((key, images));
        }
    }

    /// A draw is about to be recorded: its reads for the data-flow walk.
    pub fn flow_draw(&mut self) {
        if !self.flow_on {
            return;
        }
        let tested = self.depth_tested();
        let viewport = self.viewports.first().copied().flatten().map(|v| {
            let (x0, y0) = (v.x.min(v.x + v.width), v.y.min(v.y + v.height));
            crate::core::rect::PixelRect { x: x0.round() as i32, y: y0.round() as i32, width: v.width.abs().round() as u32, height: v.height.abs().round() as u32 }
        });
        let (sets, pushed) = if tested == Some(false) { (self.bound_sets(false), self.pushed_images(vk::PipelineBindPoint::GRAPHICS)) } else { (Vec::new(), Vec::new()) };
        self.flow.draw(tested, super::flow::DrawRecord { viewport, sets, pushed });
    }

    /// A dispatch is about to be recorded: its reads and writes for the data-flow walk.
    pub fn flow_dispatch(&mut self) {
        if self.flow_on {
            let (sets, pushed) = (self.bound_sets(true), self.pushed_images(vk::PipelineBindPoint::COMPUTE));
            self.flow.dispatch(sets, pushed);
        }
    }

    /// Whether a draw now would test depth: the bound pipeline's depth test (or its dynamic
    /// value), a compare op of ALWAYS counting as no test. None for an untracked pipeline.
    pub fn depth_tested(&self) -> Option<bool> {
        if self.shader_objects {
            // Shader objects take every state from the command buffer: the app set both.
            return match (self.dynamic.get(&(vk::DynamicState::DEPTH_TEST_ENABLE.as_raw(), 0)), self.dynamic.get(&(vk::DynamicState::DEPTH_COMPARE_OP.as_raw(), 0))) {
                (Some(StateCmd::DepthTestEnable(e)), Some(StateCmd::DepthCompareOp(op))) => Some(*e && *op != vk::CompareOp::ALWAYS),
                _ => None,
            };
        }
        let p = self.pipeline.as_ref()?;
        let dynamic = |ds: vk::DynamicState| if p.is_dynamic(ds) { self.dynamic.get(&(ds.as_raw(), 0)) } else { None };
        let enabled = match dynamic(vk::DynamicState::DEPTH_TEST_ENABLE) {
            Some(StateCmd::DepthTestEnable(e)) => *e,
            _ => p.depth_test_enable,
        };
        let op = match dynamic(vk::DynamicState::DEPTH_COMPARE_OP) {
            Some(StateCmd::DepthCompareOp(op)) => *op,
            _ => p.depth_compare_op,
        };
        Some(enabled && op != vk::CompareOp::ALWAYS)
    }

    /// Commands that re-establish this state after an injected draw changed it: the pipeline
    /// first (it overwrites its static state), then every dynamic state still in effect, then push
    /// constants in their original order.
    pub fn restore_commands(&self) -> Vec<StateCmd> {
        let mut out = Vec::new();
        if self.shader_objects {
            // Every stage the app bound, null ones included: a draw with shader objects needs
            // each stage bound, and the layer's pipeline unbound them all.
            let (stages, shaders) = self.shaders.iter().copied().unzip();
            out.push(StateCmd::BindShaders { stages, shaders });
        } else if let Some(p) = self.pipeline_handle {
            out.push(StateCmd::BindPipeline(p));
        }
        restore_slots(&mut out, &self.viewports, self.viewport_count, StateCmd::SetViewportWithCount, |first, viewports| {
            StateCmd::SetViewport { first, viewports }
        });
        restore_slots(&mut out, &self.scissors, self.scissor_count, StateCmd::SetScissorWithCount, |first, scissors| {
            StateCmd::SetScissor { first, scissors }
        });
        let mut stencil_pending: Option<StateCmd> = None;
        for cmd in self.dynamic.values() {
            let face = cmd.face();
            if face == Some(vk::StencilFaceFlags::FRONT) {
                stencil_pending = Some(cmd.clone());
                continue;
            }
            if face == Some(vk::StencilFaceFlags::BACK) {
                // Front and back with equal values replay as one FRONT_AND_BACK command.
                match stencil_pending.take() {
                    Some(front) if front.with_face(vk::StencilFaceFlags::BACK) == *cmd => {
                        out.push(front.with_face(vk::StencilFaceFlags::FRONT_AND_BACK))
                    }
                    Some(front) => out.extend([front, cmd.clone()]),
                    None => out.push(cmd.clone()),
                }
                continue;
            }
            out.extend(stencil_pending.take());
            out.push(cmd.clone());
        }
        out.extend(stencil_pending);
        out.extend(self.push_constants.iter().cloned());
        // Vertex buffers: one command per run of consecutive slots bound the same way.
        for (first, bindings) in runs(&self.vertex_buffers, 0) {
            let mut start = 0;
            for i in 1..=bindings.len() {
                let same = |a: &VertexBinding, b: &VertexBinding| a.v2 == b.v2 && a.stride.is_some() == b.stride.is_some();
                if i == bindings.len() || !same(&bindings[i], &bindings[start]) {
                    out.push(StateCmd::BindVertexBuffers { first: first + start as u32, bindings: bindings[start..i].to_vec() });
                    start = i;
                }
            }
        }
        out
    }

    /// Commands that re-establish the app's descriptor set bindings, in their original order.
    pub fn descriptor_set_commands(&self) -> Vec<StateCmd> {
        self.descriptor_sets.clone()
    }

    /// Whether the app bound any vertex buffer (the mask binds one at binding 0).
    pub fn has_vertex_buffers(&self) -> bool {
        self.vertex_buffers.iter().any(Option::is_some)
    }
}

fn restore_slots<T: Clone>(
    out: &mut Vec<StateCmd>,
    slots: &[Option<T>],
    count: Option<u32>,
    with_count: impl Fn(Vec<T>) -> StateCmd,
    ranged: impl Fn(u32, Vec<T>) -> StateCmd,
) {
    let mut from = 0;
    if let Some(n) = count {
        let all: Option<Vec<T>> = slots.iter().take(n as usize).cloned().collect();
        if let Some(all) = all.filter(|a| a.len() == n as usize) {
            out.push(with_count(all));
            from = n as usize;
        }
    }
    for (first, values) in runs(slots, from) {
        out.push(ranged(first, values));
    }
}

#[cold]
fn unreachable_bind() {
    // Pipelines carry their description; `bind_pipeline` records them. Reaching this is a bug of
    // the FFI shell, caught by the entry point's guard.
    panic!("BindPipeline must be recorded with CmdState::bind_pipeline");
}

#[cfg(test)]
#[path = "cmd_tests.rs"]
mod tests;
