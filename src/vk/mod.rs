//! The Vulkan layer half: the loader's entry points, the instance and device chains, and the hooks
//! that track the app's objects and command buffers. The only place with `unsafe` for Vulkan; the
//! hooks turn the app's pointers into owned descriptions at once and hand them to `crate::track`.
//!
//! State is keyed by the loader's dispatch key (the first pointer-sized word of a dispatchable
//! handle, which the loader shares between an instance and its physical devices, and between a
//! device and its queues and command buffers), so any handle finds its instance or device state.

mod chain;
pub(crate) mod chassis;
mod device_line;
mod hooks;
pub mod loader;
pub mod probe;

use crate::core::config::Config;
use crate::core::guard::{self, PassThrough};
use crate::core::handles::HandleMap;
use ash::vk::{self, Handle};
use std::ffi::{c_char, CStr};
use std::sync::{Arc, OnceLock};
use crate::plugin::vk::{dispatch_key, gpu_time, lifetime, DeviceKey, DeviceState};

pub use crate::manifests::vulkan::VK_LAYER_NAME;

/// What the layer keeps per `VkInstance`.
pub(crate) struct InstanceState {
    pub handle: vk::Instance,
    pub next_gipa: vk::PFN_vkGetInstanceProcAddr,
    /// The next layer's instance-level functions.
    pub fns: ash::Instance,
    /// `VkApplicationInfo::apiVersion` (1.0 when absent).
    pub api_version: u32,
    pub extensions: Vec<String>,
    /// Shared with the instance's devices: a fault anywhere turns the whole instance to
    /// pass-through.
    pub pass_through: Arc<PassThrough>,
    pub config: Arc<Config>,
    /// `VkApplicationInfo::pEngineName` (engine defaults such as the far field's depth range).
    pub engine: Option<String>,
}

pub(crate) fn check_fault(config: &Config, call: &'static str) -> Result<(), guard::Fault> {
    if config.fails_in(call) {
        return Err(guard::Fault(format!("{call}: failing on purpose (debug.fail_in)")));
    }
    Ok(())
}

#[derive(Default)]
pub(crate) struct Layer {
    pub instances: HandleMap<usize, InstanceState>,
}

pub(crate) fn layer() -> &'static Layer {
    static LAYER: OnceLock<Layer> = OnceLock::new();
    LAYER.get_or_init(Layer::default)
}

pub(crate) fn instance_of<H: Handle>(handle: H) -> Option<Arc<InstanceState>> {
    layer().instances.get(dispatch_key(handle))
}

pub(crate) fn device_of<H: Handle>(handle: H) -> Option<Arc<DeviceState>> {
    let state = crate::plugin::vk::devices().get(dispatch_key(handle));
    if state.is_none() {
        report_unknown_handle();
    }
    state
}

/// Logs the stats line of the session's device, still live (`at` says when).
pub(crate) fn log_device_stats(device: DeviceKey, at: &str) {
    if let Some(d) = device.state() {
        device_line::log_live(&d, at);
    }
}

/// A session on `device` ended (`xrDestroySession` succeeded): the layer lets go of what only
/// served that session's frames (`lifetime::session_ended`).
pub(crate) fn session_ended(device: DeviceKey) {
    if let Some(d) = device.state() {
        lifetime::session_ended(&d);
    }
}

/// Every feature's statistics of the frame that just ended, summed over devices (each device
/// starts its next frame). The OpenXR half calls this once per `xrEndFrame`; it is also where
/// completed submissions release what they held.
pub fn take_frame_stats() -> crate::core::stats::FrameStats {
    let mut all = crate::registry::empty_stats();
    for (_, d) in crate::plugin::vk::devices().values() {
        lifetime::poll(&d);
        d.track.eyes_new_frame();
        let device = crate::core::stats::FrameStats::new(d.features.all().iter().map(|f| f.take_frame()).collect());
        all.add(&device);
    }
    all
}

/// `xrEndFrame` closed frame `frame` (`stats.gpu_time`): every device's submissions since the last
/// close belong to it. Returns the frames whose GPU times are complete now, summed over devices
/// (usually earlier frames: results are read back without waiting).
pub fn end_gpu_frame(frame: u64) -> Vec<(u64, crate::core::gpu_time::GpuFrameTime)> {
    merge_gpu_times(crate::plugin::vk::devices().values().into_iter().flat_map(|(_, d)| gpu_time::end_frame(&d, frame)))
        .into_iter()
        .collect()
}

/// The frames whose GPU times completed since the last frame end (at the end of a session).
pub fn completed_gpu_frames() -> Vec<(u64, crate::core::gpu_time::GpuFrameTime)> {
    merge_gpu_times(crate::plugin::vk::devices().values().into_iter().flat_map(|(_, d)| gpu_time::complete(&d))).into_iter().collect()
}

fn merge_gpu_times(times: impl Iterator<Item = (u64, crate::core::gpu_time::GpuFrameTime)>) -> std::collections::BTreeMap<u64, crate::core::gpu_time::GpuFrameTime> {
    let mut all = std::collections::BTreeMap::new();
    for (frame, t) in times {
        all.entry(frame).and_modify(|a: &mut crate::core::gpu_time::GpuFrameTime| a.add(&t)).or_insert(t);
    }
    all
}

/// A handle whose dispatch key we never saw means a broken chain; logged once, never per call.
fn report_unknown_handle() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| tracing::error!("a device-level call arrived for a device this layer never saw created"));
}

/// Whether a hook belongs to the instance or the device dispatch chain.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Level {
    Instance,
    Device,
}

/// Declares every intercepted command in one place: name → hook, checked against ash's `PFN_*`
/// type so a wrong signature does not compile. Both proc-addr functions use this table.
macro_rules! intercepts {
    ($($level:ident $name:literal => $hook:path as $pfn:ty;)*) => {
        /// Names of all intercepted commands (documentation and tests).
        pub const INTERCEPTED: &[&str] = &[$($name),*];

        pub(crate) fn intercept(name: &[u8]) -> Option<(Level, unsafe extern "system" fn())> {
            match name {
                $(n if n == $name.as_bytes() => {
                    let hook: $pfn = $hook;
                    // SAFETY: the loader and the app call a `PFN_vkVoidFunction` only after
                    // casting it back to the command's own type, which `hook` has.
                    Some((Level::$level, unsafe { std::mem::transmute::<$pfn, unsafe extern "system" fn()>(hook) }))
                })*
                _ => None,
            }
        }
    };
}

intercepts! {
    Instance "vkCreateInstance" => chain::create_instance as vk::PFN_vkCreateInstance;
    Instance "vkDestroyInstance" => chain::destroy_instance as vk::PFN_vkDestroyInstance;
    Instance "vkCreateDevice" => chain::create_device as vk::PFN_vkCreateDevice;
    Device "vkDestroyDevice" => chain::destroy_device as vk::PFN_vkDestroyDevice;
    Device "vkCreateImage" => hooks::create_image as vk::PFN_vkCreateImage;
    Device "vkCreateSampler" => hooks::create_sampler as vk::PFN_vkCreateSampler;
    Device "vkDestroyImage" => hooks::destroy_image as vk::PFN_vkDestroyImage;
    Device "vkCreateImageView" => hooks::create_image_view as vk::PFN_vkCreateImageView;
    Device "vkDestroyImageView" => hooks::destroy_image_view as vk::PFN_vkDestroyImageView;
    Device "vkCreateRenderPass" => hooks::create_render_pass as vk::PFN_vkCreateRenderPass;
    Device "vkCreateRenderPass2" => hooks::create_render_pass2 as vk::PFN_vkCreateRenderPass2;
    Device "vkCreateRenderPass2KHR" => hooks::create_render_pass2 as vk::PFN_vkCreateRenderPass2;
    Device "vkDestroyRenderPass" => hooks::destroy_render_pass as vk::PFN_vkDestroyRenderPass;
    Device "vkCreateFramebuffer" => hooks::create_framebuffer as vk::PFN_vkCreateFramebuffer;
    Device "vkDestroyFramebuffer" => hooks::destroy_framebuffer as vk::PFN_vkDestroyFramebuffer;
    Device "vkCreateGraphicsPipelines" => hooks::create_graphics_pipelines as vk::PFN_vkCreateGraphicsPipelines;
    Device "vkDestroyPipeline" => hooks::destroy_pipeline as vk::PFN_vkDestroyPipeline;
    Device "vkCreateCommandPool" => hooks::create_command_pool as vk::PFN_vkCreateCommandPool;
    Device "vkDestroyCommandPool" => hooks::destroy_command_pool as vk::PFN_vkDestroyCommandPool;
    Device "vkResetCommandPool" => hooks::reset_command_pool as vk::PFN_vkResetCommandPool;
    Device "vkAllocateCommandBuffers" => hooks::allocate_command_buffers as vk::PFN_vkAllocateCommandBuffers;
    Device "vkFreeCommandBuffers" => hooks::free_command_buffers as vk::PFN_vkFreeCommandBuffers;
    Device "vkBeginCommandBuffer" => hooks::begin_command_buffer as vk::PFN_vkBeginCommandBuffer;
    Device "vkResetCommandBuffer" => hooks::reset_command_buffer as vk::PFN_vkResetCommandBuffer;
    Device "vkCmdExecuteCommands" => hooks::cmd_execute_commands as vk::PFN_vkCmdExecuteCommands;
    Device "vkCmdDraw" => hooks::cmd_draw as vk::PFN_vkCmdDraw;
    Device "vkCmdDrawIndexed" => hooks::cmd_draw_indexed as vk::PFN_vkCmdDrawIndexed;
    Device "vkCmdDrawIndirect" => hooks::cmd_draw_indirect as vk::PFN_vkCmdDrawIndirect;
    Device "vkCmdDrawIndexedIndirect" => hooks::cmd_draw_indexed_indirect as vk::PFN_vkCmdDrawIndexedIndirect;
    Device "vkCmdDrawIndirectCount" => hooks::cmd_draw_indirect_count as vk::PFN_vkCmdDrawIndirectCount;
    Device "vkCmdDrawIndirectCountKHR" => hooks::cmd_draw_indirect_count as vk::PFN_vkCmdDrawIndirectCount;
    Device "vkCmdDrawIndexedIndirectCount" => hooks::cmd_draw_indexed_indirect_count as vk::PFN_vkCmdDrawIndexedIndirectCount;
    Device "vkCmdDrawIndexedIndirectCountKHR" => hooks::cmd_draw_indexed_indirect_count as vk::PFN_vkCmdDrawIndexedIndirectCount;
    Device "vkCmdBindPipeline" => hooks::cmd_bind_pipeline as vk::PFN_vkCmdBindPipeline;
    Device "vkCmdPushConstants" => hooks::cmd_push_constants as vk::PFN_vkCmdPushConstants;
    Device "vkCmdBindDescriptorSets" => hooks::cmd_bind_descriptor_sets as vk::PFN_vkCmdBindDescriptorSets;
    Device "vkCmdSetViewport" => hooks::cmd_set_viewport as vk::PFN_vkCmdSetViewport;
    Device "vkCmdSetScissor" => hooks::cmd_set_scissor as vk::PFN_vkCmdSetScissor;
    Device "vkCmdSetViewportWithCount" => hooks::cmd_set_viewport_with_count as vk::PFN_vkCmdSetViewportWithCount;
    Device "vkCmdSetViewportWithCountEXT" => hooks::cmd_set_viewport_with_count as vk::PFN_vkCmdSetViewportWithCount;
    Device "vkCmdSetScissorWithCount" => hooks::cmd_set_scissor_with_count as vk::PFN_vkCmdSetScissorWithCount;
    Device "vkCmdSetScissorWithCountEXT" => hooks::cmd_set_scissor_with_count as vk::PFN_vkCmdSetScissorWithCount;
    Device "vkCmdSetLineWidth" => hooks::cmd_set_line_width as vk::PFN_vkCmdSetLineWidth;
    Device "vkCmdSetDepthBias" => hooks::cmd_set_depth_bias as vk::PFN_vkCmdSetDepthBias;
    Device "vkCmdSetBlendConstants" => hooks::cmd_set_blend_constants as vk::PFN_vkCmdSetBlendConstants;
    Device "vkCmdSetDepthBounds" => hooks::cmd_set_depth_bounds as vk::PFN_vkCmdSetDepthBounds;
    Device "vkCmdSetStencilCompareMask" => hooks::cmd_set_stencil_compare_mask as vk::PFN_vkCmdSetStencilCompareMask;
    Device "vkCmdSetStencilWriteMask" => hooks::cmd_set_stencil_write_mask as vk::PFN_vkCmdSetStencilWriteMask;
    Device "vkCmdSetStencilReference" => hooks::cmd_set_stencil_reference as vk::PFN_vkCmdSetStencilReference;
    Device "vkCmdSetCullMode" => hooks::cmd_set_cull_mode as vk::PFN_vkCmdSetCullMode;
    Device "vkCmdSetCullModeEXT" => hooks::cmd_set_cull_mode as vk::PFN_vkCmdSetCullMode;
    Device "vkCmdSetFrontFace" => hooks::cmd_set_front_face as vk::PFN_vkCmdSetFrontFace;
    Device "vkCmdSetFrontFaceEXT" => hooks::cmd_set_front_face as vk::PFN_vkCmdSetFrontFace;
    Device "vkCmdSetPrimitiveTopology" => hooks::cmd_set_primitive_topology as vk::PFN_vkCmdSetPrimitiveTopology;
    Device "vkCmdSetPrimitiveTopologyEXT" => hooks::cmd_set_primitive_topology as vk::PFN_vkCmdSetPrimitiveTopology;
    Device "vkCmdSetDepthTestEnable" => hooks::cmd_set_depth_test_enable as vk::PFN_vkCmdSetDepthTestEnable;
    Device "vkCmdSetDepthTestEnableEXT" => hooks::cmd_set_depth_test_enable as vk::PFN_vkCmdSetDepthTestEnable;
    Device "vkCmdSetDepthWriteEnable" => hooks::cmd_set_depth_write_enable as vk::PFN_vkCmdSetDepthWriteEnable;
    Device "vkCmdSetDepthWriteEnableEXT" => hooks::cmd_set_depth_write_enable as vk::PFN_vkCmdSetDepthWriteEnable;
    Device "vkCmdSetDepthCompareOp" => hooks::cmd_set_depth_compare_op as vk::PFN_vkCmdSetDepthCompareOp;
    Device "vkCmdSetDepthCompareOpEXT" => hooks::cmd_set_depth_compare_op as vk::PFN_vkCmdSetDepthCompareOp;
    Device "vkCmdSetDepthBoundsTestEnable" => hooks::cmd_set_depth_bounds_test_enable as vk::PFN_vkCmdSetDepthBoundsTestEnable;
    Device "vkCmdSetDepthBoundsTestEnableEXT" => hooks::cmd_set_depth_bounds_test_enable as vk::PFN_vkCmdSetDepthBoundsTestEnable;
    Device "vkCmdSetStencilTestEnable" => hooks::cmd_set_stencil_test_enable as vk::PFN_vkCmdSetStencilTestEnable;
    Device "vkCmdSetStencilTestEnableEXT" => hooks::cmd_set_stencil_test_enable as vk::PFN_vkCmdSetStencilTestEnable;
    Device "vkCmdSetStencilOp" => hooks::cmd_set_stencil_op as vk::PFN_vkCmdSetStencilOp;
    Device "vkCmdSetStencilOpEXT" => hooks::cmd_set_stencil_op as vk::PFN_vkCmdSetStencilOp;
    Device "vkCmdSetRasterizerDiscardEnable" => hooks::cmd_set_rasterizer_discard_enable as vk::PFN_vkCmdSetRasterizerDiscardEnable;
    Device "vkCmdSetRasterizerDiscardEnableEXT" => hooks::cmd_set_rasterizer_discard_enable as vk::PFN_vkCmdSetRasterizerDiscardEnable;
    Device "vkCmdSetDepthBiasEnable" => hooks::cmd_set_depth_bias_enable as vk::PFN_vkCmdSetDepthBiasEnable;
    Device "vkCmdSetDepthBiasEnableEXT" => hooks::cmd_set_depth_bias_enable as vk::PFN_vkCmdSetDepthBiasEnable;
    Device "vkCmdSetPrimitiveRestartEnable" => hooks::cmd_set_primitive_restart_enable as vk::PFN_vkCmdSetPrimitiveRestartEnable;
    Device "vkCmdSetPrimitiveRestartEnableEXT" => hooks::cmd_set_primitive_restart_enable as vk::PFN_vkCmdSetPrimitiveRestartEnable;
    Device "vkCmdSetLineStippleEXT" => hooks::cmd_set_line_stipple as vk::PFN_vkCmdSetLineStippleKHR;
    Device "vkCmdSetLineStippleKHR" => hooks::cmd_set_line_stipple as vk::PFN_vkCmdSetLineStippleKHR;
    Device "vkCmdSetColorWriteEnableEXT" => hooks::cmd_set_color_write_enable as vk::PFN_vkCmdSetColorWriteEnableEXT;
    Device "vkCmdSetLogicOpEXT" => hooks::cmd_set_logic_op as vk::PFN_vkCmdSetLogicOpEXT;
    Device "vkCmdSetPatchControlPointsEXT" => hooks::cmd_set_patch_control_points as vk::PFN_vkCmdSetPatchControlPointsEXT;
    Device "vkCmdBeginRenderPass" => hooks::cmd_begin_render_pass as vk::PFN_vkCmdBeginRenderPass;
    Device "vkCmdNextSubpass" => hooks::cmd_next_subpass as vk::PFN_vkCmdNextSubpass;
    Device "vkCmdEndRenderPass" => hooks::cmd_end_render_pass as vk::PFN_vkCmdEndRenderPass;
    Device "vkCmdBeginRenderPass2" => hooks::cmd_begin_render_pass2 as vk::PFN_vkCmdBeginRenderPass2;
    Device "vkCmdBeginRenderPass2KHR" => hooks::cmd_begin_render_pass2 as vk::PFN_vkCmdBeginRenderPass2;
    Device "vkCmdNextSubpass2" => hooks::cmd_next_subpass2 as vk::PFN_vkCmdNextSubpass2;
    Device "vkCmdNextSubpass2KHR" => hooks::cmd_next_subpass2 as vk::PFN_vkCmdNextSubpass2;
    Device "vkCmdEndRenderPass2" => hooks::cmd_end_render_pass2 as vk::PFN_vkCmdEndRenderPass2;
    Device "vkCmdEndRenderPass2KHR" => hooks::cmd_end_render_pass2 as vk::PFN_vkCmdEndRenderPass2;
    Device "vkCmdBeginRendering" => hooks::cmd_begin_rendering as vk::PFN_vkCmdBeginRendering;
    Device "vkCmdBeginRenderingKHR" => hooks::cmd_begin_rendering as vk::PFN_vkCmdBeginRendering;
    Device "vkCmdEndRendering" => hooks::cmd_end_rendering as vk::PFN_vkCmdEndRendering;
    Device "vkCmdEndRenderingKHR" => hooks::cmd_end_rendering as vk::PFN_vkCmdEndRendering;
    Device "vkCmdBindVertexBuffers" => hooks::cmd_bind_vertex_buffers as vk::PFN_vkCmdBindVertexBuffers;
    Device "vkCmdBindVertexBuffers2" => hooks::cmd_bind_vertex_buffers2 as vk::PFN_vkCmdBindVertexBuffers2;
    Device "vkCmdBindVertexBuffers2EXT" => hooks::cmd_bind_vertex_buffers2 as vk::PFN_vkCmdBindVertexBuffers2;
    Device "vkCmdCopyImage" => hooks::cmd_copy_image as vk::PFN_vkCmdCopyImage;
    Device "vkCmdCopyImage2" => hooks::cmd_copy_image2 as vk::PFN_vkCmdCopyImage2;
    Device "vkCmdCopyImage2KHR" => hooks::cmd_copy_image2 as vk::PFN_vkCmdCopyImage2;
    Device "vkCmdResolveImage" => hooks::cmd_resolve_image as vk::PFN_vkCmdResolveImage;
    Device "vkCmdResolveImage2" => hooks::cmd_resolve_image2 as vk::PFN_vkCmdResolveImage2;
    Device "vkCmdResolveImage2KHR" => hooks::cmd_resolve_image2 as vk::PFN_vkCmdResolveImage2;
    Device "vkCmdBlitImage" => hooks::cmd_blit_image as vk::PFN_vkCmdBlitImage;
    Device "vkCmdBlitImage2" => hooks::cmd_blit_image2 as vk::PFN_vkCmdBlitImage2;
    Device "vkCmdBlitImage2KHR" => hooks::cmd_blit_image2 as vk::PFN_vkCmdBlitImage2;
    Device "vkCmdClearAttachments" => hooks::cmd_clear_attachments as vk::PFN_vkCmdClearAttachments;
    Device "vkCmdClearDepthStencilImage" => hooks::cmd_clear_depth_stencil_image as vk::PFN_vkCmdClearDepthStencilImage;
    Device "vkCmdSetTessellationDomainOriginEXT" => hooks::cmd_set_tessellation_domain_origin as vk::PFN_vkCmdSetTessellationDomainOriginEXT;
    Device "vkCmdSetDepthClampEnableEXT" => hooks::cmd_set_depth_clamp_enable as vk::PFN_vkCmdSetDepthClampEnableEXT;
    Device "vkCmdSetPolygonModeEXT" => hooks::cmd_set_polygon_mode as vk::PFN_vkCmdSetPolygonModeEXT;
    Device "vkCmdSetRasterizationSamplesEXT" => hooks::cmd_set_rasterization_samples as vk::PFN_vkCmdSetRasterizationSamplesEXT;
    Device "vkCmdSetSampleMaskEXT" => hooks::cmd_set_sample_mask as vk::PFN_vkCmdSetSampleMaskEXT;
    Device "vkCmdSetAlphaToCoverageEnableEXT" => hooks::cmd_set_alpha_to_coverage_enable as vk::PFN_vkCmdSetAlphaToCoverageEnableEXT;
    Device "vkCmdSetAlphaToOneEnableEXT" => hooks::cmd_set_alpha_to_one_enable as vk::PFN_vkCmdSetAlphaToOneEnableEXT;
    Device "vkCmdSetLogicOpEnableEXT" => hooks::cmd_set_logic_op_enable as vk::PFN_vkCmdSetLogicOpEnableEXT;
    Device "vkCmdSetColorBlendEnableEXT" => hooks::cmd_set_color_blend_enable as vk::PFN_vkCmdSetColorBlendEnableEXT;
    Device "vkCmdSetColorBlendEquationEXT" => hooks::cmd_set_color_blend_equation as vk::PFN_vkCmdSetColorBlendEquationEXT;
    Device "vkCmdSetColorWriteMaskEXT" => hooks::cmd_set_color_write_mask as vk::PFN_vkCmdSetColorWriteMaskEXT;
    Device "vkCmdSetColorBlendAdvancedEXT" => hooks::cmd_set_color_blend_advanced as vk::PFN_vkCmdSetColorBlendAdvancedEXT;
    Device "vkCmdSetRasterizationStreamEXT" => hooks::cmd_set_rasterization_stream as vk::PFN_vkCmdSetRasterizationStreamEXT;
    Device "vkCmdSetConservativeRasterizationModeEXT" => hooks::cmd_set_conservative_rasterization_mode as vk::PFN_vkCmdSetConservativeRasterizationModeEXT;
    Device "vkCmdSetExtraPrimitiveOverestimationSizeEXT" => hooks::cmd_set_extra_primitive_overestimation_size as vk::PFN_vkCmdSetExtraPrimitiveOverestimationSizeEXT;
    Device "vkCmdSetDepthClipEnableEXT" => hooks::cmd_set_depth_clip_enable as vk::PFN_vkCmdSetDepthClipEnableEXT;
    Device "vkCmdSetSampleLocationsEnableEXT" => hooks::cmd_set_sample_locations_enable as vk::PFN_vkCmdSetSampleLocationsEnableEXT;
    Device "vkCmdSetProvokingVertexModeEXT" => hooks::cmd_set_provoking_vertex_mode as vk::PFN_vkCmdSetProvokingVertexModeEXT;
    Device "vkCmdSetLineRasterizationModeEXT" => hooks::cmd_set_line_rasterization_mode as vk::PFN_vkCmdSetLineRasterizationModeEXT;
    Device "vkCmdSetLineStippleEnableEXT" => hooks::cmd_set_line_stipple_enable as vk::PFN_vkCmdSetLineStippleEnableEXT;
    Device "vkCmdSetDepthClipNegativeOneToOneEXT" => hooks::cmd_set_depth_clip_negative_one_to_one as vk::PFN_vkCmdSetDepthClipNegativeOneToOneEXT;
    Device "vkCmdSetViewportWScalingEnableNV" => hooks::cmd_set_viewport_w_scaling_enable_nv as vk::PFN_vkCmdSetViewportWScalingEnableNV;
    Device "vkCmdSetViewportSwizzleNV" => hooks::cmd_set_viewport_swizzle_nv as vk::PFN_vkCmdSetViewportSwizzleNV;
    Device "vkCmdSetCoverageToColorEnableNV" => hooks::cmd_set_coverage_to_color_enable_nv as vk::PFN_vkCmdSetCoverageToColorEnableNV;
    Device "vkCmdSetCoverageToColorLocationNV" => hooks::cmd_set_coverage_to_color_location_nv as vk::PFN_vkCmdSetCoverageToColorLocationNV;
    Device "vkCmdSetCoverageModulationModeNV" => hooks::cmd_set_coverage_modulation_mode_nv as vk::PFN_vkCmdSetCoverageModulationModeNV;
    Device "vkCmdSetCoverageModulationTableEnableNV" => hooks::cmd_set_coverage_modulation_table_enable_nv as vk::PFN_vkCmdSetCoverageModulationTableEnableNV;
    Device "vkCmdSetCoverageModulationTableNV" => hooks::cmd_set_coverage_modulation_table_nv as vk::PFN_vkCmdSetCoverageModulationTableNV;
    Device "vkCmdSetShadingRateImageEnableNV" => hooks::cmd_set_shading_rate_image_enable_nv as vk::PFN_vkCmdSetShadingRateImageEnableNV;
    Device "vkCmdSetRepresentativeFragmentTestEnableNV" => hooks::cmd_set_representative_fragment_test_enable_nv as vk::PFN_vkCmdSetRepresentativeFragmentTestEnableNV;
    Device "vkCmdSetCoverageReductionModeNV" => hooks::cmd_set_coverage_reduction_mode_nv as vk::PFN_vkCmdSetCoverageReductionModeNV;
    Device "vkCmdSetVertexInputEXT" => hooks::cmd_set_vertex_input as vk::PFN_vkCmdSetVertexInputEXT;
    Device "vkCmdBindShadersEXT" => hooks::cmd_bind_shaders as vk::PFN_vkCmdBindShadersEXT;
    Device "vkCmdSetFragmentShadingRateKHR" => hooks::cmd_set_fragment_shading_rate as vk::PFN_vkCmdSetFragmentShadingRateKHR;
    Device "vkCmdSetRenderingAttachmentLocations" => hooks::cmd_set_rendering_attachment_locations as vk::PFN_vkCmdSetRenderingAttachmentLocationsKHR;
    Device "vkCmdSetRenderingAttachmentLocationsKHR" => hooks::cmd_set_rendering_attachment_locations as vk::PFN_vkCmdSetRenderingAttachmentLocationsKHR;
    Device "vkCmdSetRenderingInputAttachmentIndices" => hooks::cmd_set_rendering_input_attachment_indices as vk::PFN_vkCmdSetRenderingInputAttachmentIndicesKHR;
    Device "vkCmdSetRenderingInputAttachmentIndicesKHR" => hooks::cmd_set_rendering_input_attachment_indices as vk::PFN_vkCmdSetRenderingInputAttachmentIndicesKHR;
    Device "vkCreateDescriptorSetLayout" => hooks::create_descriptor_set_layout as vk::PFN_vkCreateDescriptorSetLayout;
    Device "vkDestroyDescriptorSetLayout" => hooks::destroy_descriptor_set_layout as vk::PFN_vkDestroyDescriptorSetLayout;
    Device "vkAllocateDescriptorSets" => hooks::allocate_descriptor_sets as vk::PFN_vkAllocateDescriptorSets;
    Device "vkFreeDescriptorSets" => hooks::free_descriptor_sets as vk::PFN_vkFreeDescriptorSets;
    Device "vkResetDescriptorPool" => hooks::reset_descriptor_pool as vk::PFN_vkResetDescriptorPool;
    Device "vkDestroyDescriptorPool" => hooks::destroy_descriptor_pool as vk::PFN_vkDestroyDescriptorPool;
    Device "vkUpdateDescriptorSets" => hooks::update_descriptor_sets as vk::PFN_vkUpdateDescriptorSets;
    Device "vkCreateDescriptorUpdateTemplate" => hooks::create_descriptor_update_template as vk::PFN_vkCreateDescriptorUpdateTemplate;
    Device "vkCreateDescriptorUpdateTemplateKHR" => hooks::create_descriptor_update_template as vk::PFN_vkCreateDescriptorUpdateTemplate;
    Device "vkDestroyDescriptorUpdateTemplate" => hooks::destroy_descriptor_update_template as vk::PFN_vkDestroyDescriptorUpdateTemplate;
    Device "vkDestroyDescriptorUpdateTemplateKHR" => hooks::destroy_descriptor_update_template as vk::PFN_vkDestroyDescriptorUpdateTemplate;
    Device "vkUpdateDescriptorSetWithTemplate" => hooks::update_descriptor_set_with_template as vk::PFN_vkUpdateDescriptorSetWithTemplate;
    Device "vkUpdateDescriptorSetWithTemplateKHR" => hooks::update_descriptor_set_with_template as vk::PFN_vkUpdateDescriptorSetWithTemplate;
    Device "vkCmdPushDescriptorSetKHR" => hooks::cmd_push_descriptor_set as vk::PFN_vkCmdPushDescriptorSetKHR;
    Device "vkCmdPushDescriptorSet" => hooks::cmd_push_descriptor_set as vk::PFN_vkCmdPushDescriptorSetKHR;
    Device "vkCmdPushDescriptorSetWithTemplateKHR" => hooks::cmd_push_descriptor_set_with_template as vk::PFN_vkCmdPushDescriptorSetWithTemplateKHR;
    Device "vkCmdPushDescriptorSetWithTemplate" => hooks::cmd_push_descriptor_set_with_template as vk::PFN_vkCmdPushDescriptorSetWithTemplateKHR;
    Device "vkCmdBindDescriptorBuffersEXT" => hooks::cmd_bind_descriptor_buffers as vk::PFN_vkCmdBindDescriptorBuffersEXT;
    Device "vkCmdDispatch" => hooks::cmd_dispatch as vk::PFN_vkCmdDispatch;
    Device "vkCmdDispatchIndirect" => hooks::cmd_dispatch_indirect as vk::PFN_vkCmdDispatchIndirect;
    Device "vkCmdDispatchBase" => hooks::cmd_dispatch_base as vk::PFN_vkCmdDispatchBase;
    Device "vkCmdDispatchBaseKHR" => hooks::cmd_dispatch_base as vk::PFN_vkCmdDispatchBase;
    Device "vkQueueSubmit" => hooks::queue_submit as vk::PFN_vkQueueSubmit;
    Device "vkQueueSubmit2" => hooks::queue_submit2 as vk::PFN_vkQueueSubmit2;
    Device "vkQueueSubmit2KHR" => hooks::queue_submit2 as vk::PFN_vkQueueSubmit2;
}

fn void_fn<F: Copy>(f: F) -> unsafe extern "system" fn() {
    assert_eq!(std::mem::size_of::<F>(), std::mem::size_of::<unsafe extern "system" fn()>());
    // SAFETY: only called with the `extern "system"` fn pointers of the exported proc-addr
    // functions (same size, checked); callers cast them back to their own types before calling.
    unsafe { std::mem::transmute_copy::<F, unsafe extern "system" fn()>(&f) }
}

/// The loader's first call: agree on interface version 2 and hand over our proc-addr functions.
///
/// # Safety
/// Called by the Vulkan loader with a valid `VkNegotiateLayerInterface`.
#[no_mangle]
pub unsafe extern "system" fn vkNegotiateLoaderLayerInterfaceVersion(
    p_version: *mut loader::NegotiateLayerInterface,
) -> vk::Result {
    guard::catch("vkNegotiateLoaderLayerInterfaceVersion", vk::Result::ERROR_INITIALIZATION_FAILED, || {
        // SAFETY: the loader passes a valid, writable struct or null (checked).
        let Some(v) = (unsafe { p_version.as_mut() }) else {
            return vk::Result::ERROR_INITIALIZATION_FAILED;
        };
        if v.s_type != loader::LAYER_NEGOTIATE_INTERFACE_STRUCT || v.loader_layer_interface_version < 2 {
            return vk::Result::ERROR_INITIALIZATION_FAILED;
        }
        v.loader_layer_interface_version = loader::LAYER_INTERFACE_VERSION;
        v.pfn_get_instance_proc_addr = Some(get_instance_proc_addr);
        v.pfn_get_device_proc_addr = Some(get_device_proc_addr);
        v.pfn_get_physical_device_proc_addr = None;
        vk::Result::SUCCESS
    })
}

/// The layer's `vkGetInstanceProcAddr`. Deliberately not exported: the loader gets it from
/// `vkNegotiateLoaderLayerInterfaceVersion`, and an exported `vkGetInstanceProcAddr` would be
/// interposed by `libvulkan.so.1`'s own symbol in apps that link the loader, handing the loader its
/// own trampoline and deadlocking it.
///
/// # Safety
/// Called by the loader or the app with a valid (or null) instance and a NUL-terminated name.
pub(crate) unsafe extern "system" fn get_instance_proc_addr(instance: vk::Instance, p_name: *const c_char) -> vk::PFN_vkVoidFunction {
    guard::catch("vkGetInstanceProcAddr", None, || {
        if p_name.is_null() {
            return None;
        }
        // SAFETY: the caller passes a NUL-terminated string (checked non-null).
        let name = unsafe { CStr::from_ptr(p_name) }.to_bytes();
        match name {
            b"vkGetInstanceProcAddr" => return Some(void_fn(get_instance_proc_addr as vk::PFN_vkGetInstanceProcAddr)),
            b"vkGetDeviceProcAddr" => return Some(void_fn(get_device_proc_addr as vk::PFN_vkGetDeviceProcAddr)),
            b"vkCreateInstance" => return intercept(name).map(|(_, f)| f),
            _ => {}
        }
        let state = instance_of(instance)?;
        // SAFETY: the next layer's vkGetInstanceProcAddr, called as the spec allows.
        let next = unsafe { (state.next_gipa)(instance, p_name) }?;
        // An intercepted command the next layer lacks stays absent: we never hand out a hook
        // with nothing below it.
        Some(intercept(name).map_or(next, |(_, hook)| hook))
    })
}

/// The layer's `vkGetDeviceProcAddr`; not exported, for the reason given at
/// [`get_instance_proc_addr`].
///
/// # Safety
/// Called by the loader or the app with a valid device and a NUL-terminated name.
pub(crate) unsafe extern "system" fn get_device_proc_addr(device: vk::Device, p_name: *const c_char) -> vk::PFN_vkVoidFunction {
    guard::catch("vkGetDeviceProcAddr", None, || {
        if p_name.is_null() {
            return None;
        }
        // SAFETY: the caller passes a NUL-terminated string (checked non-null).
        let name = unsafe { CStr::from_ptr(p_name) }.to_bytes();
        if name == b"vkGetDeviceProcAddr" {
            return Some(void_fn(get_device_proc_addr as vk::PFN_vkGetDeviceProcAddr));
        }
        let state = device_of(device)?;
        // SAFETY: the next layer's vkGetDeviceProcAddr for the device it created.
        let next = unsafe { (state.next_gdpa)(device, p_name) }?;
        match intercept(name) {
            Some((Level::Device, hook)) => Some(hook),
            _ => Some(next),
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_lookup() {
        assert_eq!(intercept(b"vkCmdBeginRenderingKHR").map(|(l, _)| l), Some(Level::Device));
        assert_eq!(intercept(b"vkCreateDevice").map(|(l, _)| l), Some(Level::Instance));
        assert_eq!(intercept(b"vkQueueSubmit").map(|(l, _)| l), Some(Level::Device));
        assert!(intercept(b"vkQueuePresentKHR").is_none());
        // Aliases share one hook.
        let a = intercept(b"vkCmdSetCullMode").unwrap().1 as usize;
        let b = intercept(b"vkCmdSetCullModeEXT").unwrap().1 as usize;
        assert_eq!(a, b);
        let mut names = INTERCEPTED.to_vec();
        names.sort();
        names.dedup();
        assert_eq!(names.len(), INTERCEPTED.len(), "a command is listed twice");
    }

    #[test]
    fn unknown_instance_gets_nothing_but_entry_points() {
        let name = c"vkCreateDevice";
        // SAFETY: a null instance and a valid name.
        assert!(unsafe { get_instance_proc_addr(vk::Instance::null(), name.as_ptr()) }.is_none());
        // SAFETY: as above.
        assert!(unsafe { get_instance_proc_addr(vk::Instance::null(), c"vkCreateInstance".as_ptr()) }.is_some());
    }
}
