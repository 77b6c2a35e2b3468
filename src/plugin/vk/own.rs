//! The layer's own Vulkan objects, counted. Everything the layer makes for itself goes through
//! `DeviceState::fns`, a dispatch table whose create and destroy entries for 15 kinds of object
//! are counting trampolines around the next layer's functions; the app's own create and destroy
//! calls go down through `DeviceState::next`, the plain table, and are not counted. So the
//! counts are what the layer holds at any moment: exposed in its device stats line (`own.*`) and
//! checked to be 0 once it destroyed everything at `vkDestroyDevice` (issue 11: a layer that
//! leaked per session would show there and in tests/hardening/vk_objects.rs).

use crate::core::handles::HandleMap;
use ash::vk;
use std::ffi::{c_void, CStr};
use std::sync::atomic::{AtomicI64, Ordering};
use std::sync::{Arc, OnceLock};

/// The kinds counted, in the stats line's order.
pub(crate) const KINDS: [&str; 15] = [
    "images",
    "memory",
    "image_views",
    "buffers",
    "shader_modules",
    "pipeline_layouts",
    "set_layouts",
    "pipelines",
    "render_passes",
    "framebuffers",
    "samplers",
    "descriptor_pools",
    "query_pools",
    "command_pools",
    "fences",
];

/// Live counts of one device's layer objects, and the next layer's table the trampolines call.
pub(crate) struct Counted {
    next: ash::Device,
    counts: [AtomicI64; KINDS.len()],
}

impl Counted {
    fn add(&self, kind: usize, n: i64) {
        self.counts[kind].fetch_add(n, Ordering::Relaxed);
    }
    /// ` own.images=N own.memory=M …` for the device stats line.
    pub(crate) fn summary(&self) -> String {
        KINDS.iter().zip(&self.counts).map(|(k, c)| format!(" own.{k}={}", c.load(Ordering::Relaxed))).collect()
    }
    /// The kinds with objects still alive (none once the layer destroyed everything).
    pub(crate) fn alive(&self) -> Vec<(&'static str, i64)> {
        KINDS.iter().zip(&self.counts).map(|(k, c)| (*k, c.load(Ordering::Relaxed))).filter(|(_, n)| *n != 0).collect()
    }
}

/// Per device (by dispatch key): what the trampolines need. A map of its own, filled before the
/// device's state exists, so that nothing the layer makes is ever uncounted.
fn tables() -> &'static HandleMap<usize, Counted> {
    static TABLES: OnceLock<HandleMap<usize, Counted>> = OnceLock::new();
    TABLES.get_or_init(HandleMap::default)
}

/// Registers `device` (its next layer's table `next`) and returns the counting table for the
/// layer's own calls.
///
/// # Safety
/// `next_gdpa` must be the next layer's `vkGetDeviceProcAddr` for `device`, which it created.
pub(crate) unsafe fn register(device: vk::Device, next: &ash::Device, next_gdpa: vk::PFN_vkGetDeviceProcAddr) -> (ash::Device, Arc<Counted>) {
    let counted = Arc::new(Counted { next: next.clone(), counts: Default::default() });
    tables().insert(super::dispatch_key(device), counted.clone());
    // SAFETY: every name resolves to a trampoline of the same signature or to the next layer's
    // function (the caller's contract).
    let fns = unsafe { ash::Device::load_with(|n| trampoline(n).unwrap_or_else(|| super::device_proc(next_gdpa, device, n)), device) };
    (fns, counted)
}

/// `vkDestroyDevice`, after the layer destroyed its objects and the call went down. Takes the
/// dispatch key read *before* that call: the `VkDevice` is freed memory now, and reading its
/// first word again would look up junk and leak the table (issue 23).
pub(crate) fn unregister(key: usize) {
    tables().remove(key);
}

/// How many devices have a counting table (0 once every device is destroyed; the
/// `vulkan layer tables` log line at `vkDestroyInstance`).
pub(crate) fn registered() -> usize {
    tables().len()
}

fn table(device: vk::Device) -> Option<Arc<Counted>> {
    tables().get(super::dispatch_key(device))
}

macro_rules! counted_create {
    ($name:ident, $kind:expr, $f:ident, $info:ty, $handle:ty) => {
        unsafe extern "system" fn $name(device: vk::Device, info: *const $info, alloc: *const vk::AllocationCallbacks<'_>, out: *mut $handle) -> vk::Result {
            let Some(t) = table(device) else { return vk::Result::ERROR_INITIALIZATION_FAILED };
            // SAFETY: the layer's own call with valid arguments, forwarded to the next layer's
            // entry point of the same signature.
            let r = unsafe { (t.next.fp_v1_0().$f)(device, info, alloc, out) };
            if r == vk::Result::SUCCESS {
                t.add($kind, 1);
            }
            r
        }
    };
}

macro_rules! counted_destroy {
    ($name:ident, $kind:expr, $f:ident, $handle:ty) => {
        unsafe extern "system" fn $name(device: vk::Device, handle: $handle, alloc: *const vk::AllocationCallbacks<'_>) {
            let Some(t) = table(device) else { return };
            if handle != <$handle>::null() {
                t.add($kind, -1);
            }
            // SAFETY: the layer's own call with valid arguments, forwarded as above.
            unsafe { (t.next.fp_v1_0().$f)(device, handle, alloc) }
        }
    };
}

counted_create!(create_image, 0, create_image, vk::ImageCreateInfo<'_>, vk::Image);
counted_destroy!(destroy_image, 0, destroy_image, vk::Image);
counted_create!(allocate_memory, 1, allocate_memory, vk::MemoryAllocateInfo<'_>, vk::DeviceMemory);
counted_destroy!(free_memory, 1, free_memory, vk::DeviceMemory);
counted_create!(create_image_view, 2, create_image_view, vk::ImageViewCreateInfo<'_>, vk::ImageView);
counted_destroy!(destroy_image_view, 2, destroy_image_view, vk::ImageView);
counted_create!(create_buffer, 3, create_buffer, vk::BufferCreateInfo<'_>, vk::Buffer);
counted_destroy!(destroy_buffer, 3, destroy_buffer, vk::Buffer);
counted_create!(create_shader_module, 4, create_shader_module, vk::ShaderModuleCreateInfo<'_>, vk::ShaderModule);
counted_destroy!(destroy_shader_module, 4, destroy_shader_module, vk::ShaderModule);
counted_create!(create_pipeline_layout, 5, create_pipeline_layout, vk::PipelineLayoutCreateInfo<'_>, vk::PipelineLayout);
counted_destroy!(destroy_pipeline_layout, 5, destroy_pipeline_layout, vk::PipelineLayout);
counted_create!(create_descriptor_set_layout, 6, create_descriptor_set_layout, vk::DescriptorSetLayoutCreateInfo<'_>, vk::DescriptorSetLayout);
counted_destroy!(destroy_descriptor_set_layout, 6, destroy_descriptor_set_layout, vk::DescriptorSetLayout);
counted_destroy!(destroy_pipeline, 7, destroy_pipeline, vk::Pipeline);
counted_create!(create_render_pass, 8, create_render_pass, vk::RenderPassCreateInfo<'_>, vk::RenderPass);
counted_destroy!(destroy_render_pass, 8, destroy_render_pass, vk::RenderPass);
counted_create!(create_framebuffer, 9, create_framebuffer, vk::FramebufferCreateInfo<'_>, vk::Framebuffer);
counted_destroy!(destroy_framebuffer, 9, destroy_framebuffer, vk::Framebuffer);
counted_create!(create_sampler, 10, create_sampler, vk::SamplerCreateInfo<'_>, vk::Sampler);
counted_destroy!(destroy_sampler, 10, destroy_sampler, vk::Sampler);
counted_create!(create_descriptor_pool, 11, create_descriptor_pool, vk::DescriptorPoolCreateInfo<'_>, vk::DescriptorPool);
counted_destroy!(destroy_descriptor_pool, 11, destroy_descriptor_pool, vk::DescriptorPool);
counted_create!(create_query_pool, 12, create_query_pool, vk::QueryPoolCreateInfo<'_>, vk::QueryPool);
counted_destroy!(destroy_query_pool, 12, destroy_query_pool, vk::QueryPool);
counted_create!(create_command_pool, 13, create_command_pool, vk::CommandPoolCreateInfo<'_>, vk::CommandPool);
counted_destroy!(destroy_command_pool, 13, destroy_command_pool, vk::CommandPool);
counted_create!(create_fence, 14, create_fence, vk::FenceCreateInfo<'_>, vk::Fence);
counted_destroy!(destroy_fence, 14, destroy_fence, vk::Fence);

/// Graphics and compute pipelines: each pipeline written counts, also when the call fails for
/// others of the batch (the spec lets the others be made).
macro_rules! counted_pipelines {
    ($name:ident, $f:ident, $info:ty) => {
        unsafe extern "system" fn $name(device: vk::Device, cache: vk::PipelineCache, count: u32, infos: *const $info, alloc: *const vk::AllocationCallbacks<'_>, out: *mut vk::Pipeline) -> vk::Result {
            let Some(t) = table(device) else { return vk::Result::ERROR_INITIALIZATION_FAILED };
            // SAFETY: forwarded as above.
            let r = unsafe { (t.next.fp_v1_0().$f)(device, cache, count, infos, alloc, out) };
            // SAFETY: `out` has `count` elements, each written (a handle or null) by the call.
            let made = unsafe { super::convert::slice(out, count) }.iter().filter(|p| **p != vk::Pipeline::null()).count();
            t.add(7, made as i64);
            r
        }
    };
}

counted_pipelines!(create_graphics_pipelines, create_graphics_pipelines, vk::GraphicsPipelineCreateInfo<'_>);
counted_pipelines!(create_compute_pipelines, create_compute_pipelines, vk::ComputePipelineCreateInfo<'_>);

/// The trampoline for a device function name, if it is counted.
fn trampoline(name: &CStr) -> Option<*const c_void> {
    macro_rules! table {
        ($($n:literal => $f:ident),* $(,)?) => {
            match name.to_bytes() {
                $($n => Some($f as *const c_void),)*
                _ => None,
            }
        };
    }
    table! {
        b"vkCreateImage" => create_image,
        b"vkDestroyImage" => destroy_image,
        b"vkAllocateMemory" => allocate_memory,
        b"vkFreeMemory" => free_memory,
        b"vkCreateImageView" => create_image_view,
        b"vkDestroyImageView" => destroy_image_view,
        b"vkCreateBuffer" => create_buffer,
        b"vkDestroyBuffer" => destroy_buffer,
        b"vkCreateShaderModule" => create_shader_module,
        b"vkDestroyShaderModule" => destroy_shader_module,
        b"vkCreatePipelineLayout" => create_pipeline_layout,
        b"vkDestroyPipelineLayout" => destroy_pipeline_layout,
        b"vkCreateDescriptorSetLayout" => create_descriptor_set_layout,
        b"vkDestroyDescriptorSetLayout" => destroy_descriptor_set_layout,
        b"vkCreateGraphicsPipelines" => create_graphics_pipelines,
        b"vkCreateComputePipelines" => create_compute_pipelines,
        b"vkDestroyPipeline" => destroy_pipeline,
        b"vkCreateRenderPass" => create_render_pass,
        b"vkDestroyRenderPass" => destroy_render_pass,
        b"vkCreateFramebuffer" => create_framebuffer,
        b"vkDestroyFramebuffer" => destroy_framebuffer,
        b"vkCreateSampler" => create_sampler,
        b"vkDestroySampler" => destroy_sampler,
        b"vkCreateDescriptorPool" => create_descriptor_pool,
        b"vkDestroyDescriptorPool" => destroy_descriptor_pool,
        b"vkCreateQueryPool" => create_query_pool,
        b"vkDestroyQueryPool" => destroy_query_pool,
        b"vkCreateCommandPool" => create_command_pool,
        b"vkDestroyCommandPool" => destroy_command_pool,
        b"vkCreateFence" => create_fence,
        b"vkDestroyFence" => destroy_fence,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_kind_has_both_trampolines() {
        let names: Vec<&str> = KINDS.to_vec();
        assert_eq!(names.len(), 15);
        for n in ["vkCreateImage", "vkFreeMemory", "vkCreateComputePipelines", "vkDestroyFence"] {
            let c = std::ffi::CString::new(n).unwrap();
            assert!(trampoline(&c).is_some(), "{n}");
        }
        let c = std::ffi::CString::new("vkCmdDraw").unwrap();
        assert!(trampoline(&c).is_none(), "only creation and destruction are counted");
    }
}
