//! `VK_FAULT_REENTER=vkQueueSubmit,vkCreateImage,…`: when the lower instance receives one of
//! these calls, before passing it down, it calls back up to the **top** of the chain on the same
//! device — through the Vulkan loader's own `vkGetDeviceProcAddr` (`libvulkan.so.1`), so every
//! layer above, stereoshim included, sees the calls as the app's — with a small piece of work
//! that goes through the calls stereoshim intercepts: an image with memory and a view, a render
//! pass, a framebuffer, a graphics pipeline, a command pool and a command buffer recorded with
//! the pass and a draw, and (only when the outer call is a submission, whose queue its caller
//! holds) that command buffer submitted on the outer call's queue and waited for. Everything is
//! destroyed again before the outer call goes down.
//!
//! A layer above that holds a lock across its call down deadlocks here (or panics, for a
//! `RefCell`), which is what `tests/reentry.rs` proves it does not. A driver or layer below may do
//! exactly this: an OpenXR runtime calls Vulkan on the app's device, and a layer below may call
//! functions it got from the top of the chain.
//!
//! Only the outermost call re-enters (a thread-local flag), so the re-entered calls reaching this
//! layer again pass straight through. Each device counts its re-entries per command and prints
//! them at `vkDestroyDevice`; a re-entry that fails prints its error at once.

use crate::spec;
use ash::vk::{self, Handle};
use std::cell::Cell;
use std::collections::{BTreeMap, HashMap};
use std::ffi::{c_char, c_void, CStr};
use std::sync::{Mutex, OnceLock};

/// The commands named by `VK_FAULT_REENTER` (core names), parsed once; a malformed value fails
/// the lower instance's creation.
pub(crate) fn names() -> &'static Result<Vec<&'static str>, String> {
    static NAMES: OnceLock<Result<Vec<&'static str>, String>> = OnceLock::new();
    NAMES.get_or_init(|| spec::parse_reenter(&std::env::var("VK_FAULT_REENTER").unwrap_or_default()))
}

fn wanted(name: &str) -> bool {
    matches!(names(), Ok(n) if n.contains(&name))
}

thread_local! {
    /// This thread is inside a re-entry: calls reaching the layer now pass straight through.
    static ACTIVE: Cell<bool> = const { Cell::new(false) };
}

/// What a device needs for re-entry.
pub(crate) struct DeviceReentry {
    /// Queue handle → its family (the queues of the device's create info).
    queues: HashMap<u64, u32>,
    /// The family of the first queue create info: the command pool's when the outer call has no
    /// queue (nothing is submitted then).
    family: u32,
    /// The top of the chain's device functions, resolved at the first re-entry.
    top: OnceLock<ash::Device>,
    /// Re-entries made, per command.
    made: Mutex<BTreeMap<&'static str, u64>>,
}

impl DeviceReentry {
    /// # Safety
    /// `ci` is the device's valid create info; `get_queue` the next layer's `vkGetDeviceQueue` of
    /// `device` (or None).
    pub(crate) unsafe fn new(ci: &vk::DeviceCreateInfo<'_>, get_queue: vk::PFN_vkVoidFunction, device: vk::Device) -> DeviceReentry {
        // SAFETY: the create info's queue infos, valid during the app's call.
        let infos = unsafe { std::slice::from_raw_parts(ci.p_queue_create_infos, ci.queue_create_info_count as usize) };
        let mut queues = HashMap::new();
        if let Some(get_queue) = get_queue {
            // SAFETY: the pointer the next layer returned for "vkGetDeviceQueue".
            let get_queue: vk::PFN_vkGetDeviceQueue = unsafe { std::mem::transmute(get_queue) };
            // Queues created with flags are only reachable through vkGetDeviceQueue2.
            for q in infos.iter().filter(|q| q.flags.is_empty()) {
                for index in 0..q.queue_count {
                    let mut queue = vk::Queue::null();
                    // SAFETY: a family and index the device was created with.
                    unsafe { get_queue(device, q.queue_family_index, index, &mut queue) };
                    queues.insert(queue.as_raw(), q.queue_family_index);
                }
            }
        }
        DeviceReentry { queues, family: infos.first().map_or(0, |q| q.queue_family_index), top: OnceLock::new(), made: Mutex::default() }
    }

    /// Prints the re-entries made on this device (at its destruction), one line per command.
    pub(crate) fn report(&self) {
        for (name, n) in crate::lock(&self.made).iter() {
            eprintln!("vk-fault-layer: re-entered the top of the chain from {name}: {n} times");
        }
    }
}

/// The loader's exported `vkGetDeviceProcAddr`: it returns the first layer's functions, so calls
/// through them travel the whole chain, as the app's do.
fn loader_gdpa() -> Option<vk::PFN_vkGetDeviceProcAddr> {
    static GDPA: OnceLock<Option<vk::PFN_vkGetDeviceProcAddr>> = OnceLock::new();
    *GDPA.get_or_init(|| {
        // SAFETY: loading the Vulkan loader the process already has (the app linked or loaded
        // it); its initialisers ran then. Kept loaded for the process's life.
        let lib = unsafe { libloading::Library::new("libvulkan.so.1") }.ok()?;
        // SAFETY: the loader exports vkGetDeviceProcAddr with this type.
        let f = unsafe { lib.get::<vk::PFN_vkGetDeviceProcAddr>(b"vkGetDeviceProcAddr\0") }.ok().map(|s| *s);
        std::mem::forget(lib);
        f
    })
}

/// The top of the chain's device functions for `device`. Resolved outside any lock of this
/// layer: the loader asks the first layer's `vkGetDeviceProcAddr` for names it does not know.
fn top(r: &DeviceReentry, device: vk::Device) -> Result<&ash::Device, String> {
    if r.top.get().is_none() {
        let gdpa = loader_gdpa().ok_or("libvulkan.so.1 or its vkGetDeviceProcAddr not found")?;
        let load = |name: &CStr| -> *const c_void {
            // SAFETY: the loader's vkGetDeviceProcAddr with a live device of its own and a
            // NUL-terminated name.
            unsafe { gdpa(device, name.as_ptr() as *const c_char) }.map_or(std::ptr::null(), |f| f as *const c_void)
        };
        // SAFETY: `load` resolves each name for this device, null when absent.
        let dev = unsafe { ash::Device::load_with(load, device) };
        // Another thread may have set it meanwhile: the same functions.
        let _ = r.top.set(dev);
    }
    r.top.get().ok_or_else(|| "no device functions".into())
}

/// Re-enters the chain from the outer call `call` (its first handle `first`: a device, queue or
/// command buffer), if `VK_FAULT_REENTER` names it and this thread is not re-entering already.
pub(crate) fn from<H: Handle + Copy>(call: &'static str, first: H) {
    if !wanted(call) || ACTIVE.with(Cell::get) {
        return;
    }
    let Some(dev) = crate::device_state::<false>(crate::dispatch_key(first)) else { return };
    ACTIVE.with(|a| a.set(true));
    // Cleared by a guard, so a panic below (caught at the entry point) leaves no stale flag.
    struct Clear;
    impl Drop for Clear {
        fn drop(&mut self) {
            ACTIVE.with(|a| a.set(false));
        }
    }
    let _clear = Clear;
    let r = &dev.reenter;
    // Only a submission's queue is used: its caller holds that queue for the call (external
    // synchronization); during any other call the app may be submitting from another thread.
    let queue = (H::TYPE == vk::ObjectType::QUEUE).then(|| vk::Queue::from_raw(first.as_raw()));
    let family = match queue {
        Some(q) => r.queues.get(&q.as_raw()).copied(),
        None => Some(r.family),
    };
    let Some(family) = family else {
        eprintln!("vk-fault-layer: re-entry from {call} failed: the queue is not one of the device's create info");
        return;
    };
    // SAFETY: the top of the chain's functions of a live device (the outer call is on it) and a
    // queue family it has; `queue` is held by the outer call's caller.
    match top(r, dev.handle).and_then(|t| unsafe { work(t, family, queue) }) {
        Ok(()) => *crate::lock(&r.made).entry(call).or_insert(0) += 1,
        Err(e) => eprintln!("vk-fault-layer: re-entry from {call} failed: {e}"),
    }
}

/// A vertex shader that writes only `gl_Position` (SPIR-V 1.0 for Vulkan 1.0, from
/// `#version 450  void main() { gl_Position = vec4(0.0, 0.0, 0.0, 1.0); }`, glslangValidator -V,
/// spirv-opt --strip-debug): the pipeline rasterizes nothing, so it needs no fragment shader.
const VERT: [u32; 127] = [
    0x07230203, 0x00010000, 0x0008000b, 0x00000015, 0x00000000, 0x00020011, 0x00000001, 0x0006000b,
    0x00000001, 0x4c534c47, 0x6474732e, 0x3035342e, 0x00000000, 0x0003000e, 0x00000000, 0x00000001,
    0x0006000f, 0x00000000, 0x00000004, 0x6e69616d, 0x00000000, 0x0000000d, 0x00050048, 0x0000000b,
    0x00000000, 0x0000000b, 0x00000000, 0x00050048, 0x0000000b, 0x00000001, 0x0000000b, 0x00000001,
    0x00050048, 0x0000000b, 0x00000002, 0x0000000b, 0x00000003, 0x00050048, 0x0000000b, 0x00000003,
    0x0000000b, 0x00000004, 0x00030047, 0x0000000b, 0x00000002, 0x00020013, 0x00000002, 0x00030021,
    0x00000003, 0x00000002, 0x00030016, 0x00000006, 0x00000020, 0x00040017, 0x00000007, 0x00000006,
    0x00000004, 0x00040015, 0x00000008, 0x00000020, 0x00000000, 0x0004002b, 0x00000008, 0x00000009,
    0x00000001, 0x0004001c, 0x0000000a, 0x00000006, 0x00000009, 0x0006001e, 0x0000000b, 0x00000007,
    0x00000006, 0x0000000a, 0x0000000a, 0x00040020, 0x0000000c, 0x00000003, 0x0000000b, 0x0004003b,
    0x0000000c, 0x0000000d, 0x00000003, 0x00040015, 0x0000000e, 0x00000020, 0x00000001, 0x0004002b,
    0x0000000e, 0x0000000f, 0x00000000, 0x0004002b, 0x00000006, 0x00000010, 0x00000000, 0x0004002b,
    0x00000006, 0x00000011, 0x3f800000, 0x0007002c, 0x00000007, 0x00000012, 0x00000010, 0x00000010,
    0x00000010, 0x00000011, 0x00040020, 0x00000013, 0x00000003, 0x00000007, 0x00050036, 0x00000002,
    0x00000004, 0x00000000, 0x00000003, 0x000200f8, 0x00000005, 0x00050041, 0x00000013, 0x00000014,
    0x0000000d, 0x0000000f, 0x0003003e, 0x00000014, 0x00000012, 0x000100fd, 0x00010038,
];

/// The objects one re-entry makes, destroyed (through the top of the chain) when dropped.
struct Made<'a> {
    t: &'a ash::Device,
    image: vk::Image,
    memory: vk::DeviceMemory,
    view: vk::ImageView,
    render_pass: vk::RenderPass,
    framebuffer: vk::Framebuffer,
    layout: vk::PipelineLayout,
    module: vk::ShaderModule,
    pipeline: vk::Pipeline,
    pool: vk::CommandPool,
    fence: vk::Fence,
}

impl Drop for Made<'_> {
    fn drop(&mut self) {
        let t = self.t;
        // SAFETY: objects made by `work` on this device, none in use by the GPU any more (the
        // submission, if any, was waited for; a failed wait leaves the device lost or the work
        // unfinished, in which case the test fails on the error line anyway); destroying the
        // pool frees its command buffer.
        unsafe {
            if self.fence != vk::Fence::null() {
                t.destroy_fence(self.fence, None);
            }
            if self.pool != vk::CommandPool::null() {
                t.destroy_command_pool(self.pool, None);
            }
            if self.pipeline != vk::Pipeline::null() {
                t.destroy_pipeline(self.pipeline, None);
            }
            if self.module != vk::ShaderModule::null() {
                t.destroy_shader_module(self.module, None);
            }
            if self.layout != vk::PipelineLayout::null() {
                t.destroy_pipeline_layout(self.layout, None);
            }
            if self.framebuffer != vk::Framebuffer::null() {
                t.destroy_framebuffer(self.framebuffer, None);
            }
            if self.render_pass != vk::RenderPass::null() {
                t.destroy_render_pass(self.render_pass, None);
            }
            if self.view != vk::ImageView::null() {
                t.destroy_image_view(self.view, None);
            }
            if self.image != vk::Image::null() {
                t.destroy_image(self.image, None);
            }
            if self.memory != vk::DeviceMemory::null() {
                t.free_memory(self.memory, None);
            }
        }
    }
}

/// One re-entry's work, through the top of the chain.
///
/// # Safety
/// `t` holds the top of the chain's functions of a live device, which has queue family `family`; `queue`, if any, is of that family and not used by anyone else during the call.
unsafe fn work(t: &ash::Device, family: u32, queue: Option<vk::Queue>) -> Result<(), String> {
    let e = |what: &'static str| move |r: vk::Result| format!("{what}: {r:?}");
    let mut m = Made {
        t,
        image: vk::Image::null(),
        memory: vk::DeviceMemory::null(),
        view: vk::ImageView::null(),
        render_pass: vk::RenderPass::null(),
        framebuffer: vk::Framebuffer::null(),
        layout: vk::PipelineLayout::null(),
        module: vk::ShaderModule::null(),
        pipeline: vk::Pipeline::null(),
        pool: vk::CommandPool::null(),
        fence: vk::Fence::null(),
    };
    let format = vk::Format::R8G8B8A8_UNORM;
    let extent = vk::Extent2D { width: 4, height: 4 };
    // SAFETY: valid create infos on the caller's device; every handle used is made just before.
    unsafe {
        let image = vk::ImageCreateInfo::default()
            .image_type(vk::ImageType::TYPE_2D)
            .format(format)
            .extent(vk::Extent3D { width: extent.width, height: extent.height, depth: 1 })
            .mip_levels(1)
            .array_layers(1)
            .samples(vk::SampleCountFlags::TYPE_1)
            .tiling(vk::ImageTiling::OPTIMAL)
            .usage(vk::ImageUsageFlags::COLOR_ATTACHMENT)
            .initial_layout(vk::ImageLayout::UNDEFINED);
        m.image = t.create_image(&image, None).map_err(e("vkCreateImage"))?;
        let req = t.get_image_memory_requirements(m.image);
        // Any type the image allows will do.
        let type_index = req.memory_type_bits.trailing_zeros();
        m.memory = t.allocate_memory(&vk::MemoryAllocateInfo::default().allocation_size(req.size).memory_type_index(type_index), None).map_err(e("vkAllocateMemory"))?;
        t.bind_image_memory(m.image, m.memory, 0).map_err(e("vkBindImageMemory"))?;
        let range = vk::ImageSubresourceRange { aspect_mask: vk::ImageAspectFlags::COLOR, base_mip_level: 0, level_count: 1, base_array_layer: 0, layer_count: 1 };
        m.view = t
            .create_image_view(&vk::ImageViewCreateInfo::default().image(m.image).view_type(vk::ImageViewType::TYPE_2D).format(format).subresource_range(range), None)
            .map_err(e("vkCreateImageView"))?;
        let attachments = [vk::AttachmentDescription::default()
            .format(format)
            .samples(vk::SampleCountFlags::TYPE_1)
            .load_op(vk::AttachmentLoadOp::CLEAR)
            .store_op(vk::AttachmentStoreOp::STORE)
            .stencil_load_op(vk::AttachmentLoadOp::DONT_CARE)
            .stencil_store_op(vk::AttachmentStoreOp::DONT_CARE)
            .initial_layout(vk::ImageLayout::UNDEFINED)
            .final_layout(vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL)];
        let colors = [vk::AttachmentReference { attachment: 0, layout: vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL }];
        let subpasses = [vk::SubpassDescription::default().pipeline_bind_point(vk::PipelineBindPoint::GRAPHICS).color_attachments(&colors)];
        m.render_pass = t.create_render_pass(&vk::RenderPassCreateInfo::default().attachments(&attachments).subpasses(&subpasses), None).map_err(e("vkCreateRenderPass"))?;
        let views = [m.view];
        let fb = vk::FramebufferCreateInfo::default().render_pass(m.render_pass).attachments(&views).width(extent.width).height(extent.height).layers(1);
        m.framebuffer = t.create_framebuffer(&fb, None).map_err(e("vkCreateFramebuffer"))?;
        m.layout = t.create_pipeline_layout(&vk::PipelineLayoutCreateInfo::default(), None).map_err(e("vkCreatePipelineLayout"))?;
        m.module = t.create_shader_module(&vk::ShaderModuleCreateInfo::default().code(&VERT), None).map_err(e("vkCreateShaderModule"))?;
        let stages = [vk::PipelineShaderStageCreateInfo::default().stage(vk::ShaderStageFlags::VERTEX).module(m.module).name(c"main")];
        let vertex_input = vk::PipelineVertexInputStateCreateInfo::default();
        let assembly = vk::PipelineInputAssemblyStateCreateInfo::default().topology(vk::PrimitiveTopology::TRIANGLE_LIST);
        // Rasterization off: viewport, multisample and colour blend state are ignored.
        let raster = vk::PipelineRasterizationStateCreateInfo::default().rasterizer_discard_enable(true).line_width(1.0);
        let pipeline = vk::GraphicsPipelineCreateInfo::default()
            .stages(&stages)
            .vertex_input_state(&vertex_input)
            .input_assembly_state(&assembly)
            .rasterization_state(&raster)
            .layout(m.layout)
            .render_pass(m.render_pass)
            .subpass(0);
        m.pipeline = t.create_graphics_pipelines(vk::PipelineCache::null(), &[pipeline], None).map_err(|(_, r)| format!("vkCreateGraphicsPipelines: {r:?}"))?[0];
        m.pool = t.create_command_pool(&vk::CommandPoolCreateInfo::default().flags(vk::CommandPoolCreateFlags::TRANSIENT).queue_family_index(family), None).map_err(e("vkCreateCommandPool"))?;
        let alloc = vk::CommandBufferAllocateInfo::default().command_pool(m.pool).level(vk::CommandBufferLevel::PRIMARY).command_buffer_count(1);
        let cb = t.allocate_command_buffers(&alloc).map_err(e("vkAllocateCommandBuffers"))?[0];
        t.begin_command_buffer(cb, &vk::CommandBufferBeginInfo::default().flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT)).map_err(e("vkBeginCommandBuffer"))?;
        let clear = [vk::ClearValue { color: vk::ClearColorValue { float32: [0.0; 4] } }];
        let begin = vk::RenderPassBeginInfo::default()
            .render_pass(m.render_pass)
            .framebuffer(m.framebuffer)
            .render_area(vk::Rect2D { offset: vk::Offset2D::default(), extent })
            .clear_values(&clear);
        t.cmd_begin_render_pass(cb, &begin, vk::SubpassContents::INLINE);
        t.cmd_bind_pipeline(cb, vk::PipelineBindPoint::GRAPHICS, m.pipeline);
        t.cmd_draw(cb, 3, 1, 0, 0);
        t.cmd_end_render_pass(cb);
        t.end_command_buffer(cb).map_err(e("vkEndCommandBuffer"))?;
        if let Some(queue) = queue {
            m.fence = t.create_fence(&vk::FenceCreateInfo::default(), None).map_err(e("vkCreateFence"))?;
            let cbs = [cb];
            t.queue_submit(queue, &[vk::SubmitInfo::default().command_buffers(&cbs)], m.fence).map_err(e("vkQueueSubmit"))?;
            // Generous: lavapipe may be busy with the app's frame, but never for this long.
            t.wait_for_fences(&[m.fence], true, 20_000_000_000).map_err(e("vkWaitForFences"))?;
        }
        t.free_command_buffers(m.pool, &[cb]);
    }
    Ok(())
}

/// The next layer's function `i` of [`spec::REENTER_ONLY`] for the device `first` belongs to.
fn next(first: impl Handle, i: usize) -> Option<unsafe extern "system" fn()> {
    crate::device_state::<false>(crate::dispatch_key(first)).and_then(|d| d.reenter_fns[i])
}

/// What a hook returns when it cannot call down (no device state, or a panic).
trait Fallback {
    fn fallback() -> Self;
}

impl Fallback for () {
    fn fallback() {}
}

impl Fallback for vk::Result {
    fn fallback() -> vk::Result {
        vk::Result::ERROR_UNKNOWN
    }
}

/// Hooks of the lower instance for [`spec::REENTER_ONLY`]: re-enter, then call down unchanged.
macro_rules! reenter_hooks {
    ($($hook:ident $name:literal $pfn:ty = ($first:ident : $ft:ty $(, $a:ident : $t:ty)*) $(-> $ret:ty)?;)*) => {
        $(
            unsafe extern "system" fn $hook($first: $ft $(, $a: $t)*) $(-> $ret)? {
                crate::entry($name, Fallback::fallback(), || {
                    let i = spec::reenter_only_index($name).expect("listed in spec::REENTER_ONLY");
                    let Some(f) = next($first, i) else {
                        eprintln!("vk-fault-layer: {} on a device this layer never saw created", $name);
                        return Fallback::fallback();
                    };
                    // SAFETY: the pointer the next layer returned for this command's name has
                    // this command's type.
                    let f: $pfn = unsafe { std::mem::transmute::<unsafe extern "system" fn(), $pfn>(f) };
                    from($name, $first);
                    // SAFETY: the caller's arguments, to the next layer unchanged.
                    unsafe { f($first $(, $a)*) }
                })
            }
        )*

        /// The lower instance's hook for a re-entry-only command that `VK_FAULT_REENTER` names
        /// (aliases included); None for the marker and every other name.
        pub(crate) fn lookup<const U: bool>(name: &[u8]) -> Option<unsafe extern "system" fn()> {
            let name = std::str::from_utf8(name).ok()?;
            let core = spec::REENTER_ONLY[spec::reenter_only_index(name)?][0];
            if U || !wanted(core) {
                return None;
            }
            $(
                if core == $name {
                    return crate::void($hook as $pfn);
                }
            )*
            None
        }
    };
}

reenter_hooks! {
    queue_submit2 "vkQueueSubmit2" vk::PFN_vkQueueSubmit2 = (queue: vk::Queue, count: u32, submits: *const vk::SubmitInfo2<'_>, fence: vk::Fence) -> vk::Result;
    begin_command_buffer "vkBeginCommandBuffer" vk::PFN_vkBeginCommandBuffer = (cb: vk::CommandBuffer, info: *const vk::CommandBufferBeginInfo<'_>) -> vk::Result;
    end_command_buffer "vkEndCommandBuffer" vk::PFN_vkEndCommandBuffer = (cb: vk::CommandBuffer) -> vk::Result;
    cmd_begin_render_pass "vkCmdBeginRenderPass" vk::PFN_vkCmdBeginRenderPass = (cb: vk::CommandBuffer, begin: *const vk::RenderPassBeginInfo<'_>, contents: vk::SubpassContents);
    cmd_begin_render_pass2 "vkCmdBeginRenderPass2" vk::PFN_vkCmdBeginRenderPass2 = (cb: vk::CommandBuffer, begin: *const vk::RenderPassBeginInfo<'_>, info: *const vk::SubpassBeginInfo<'_>);
    cmd_begin_rendering "vkCmdBeginRendering" vk::PFN_vkCmdBeginRendering = (cb: vk::CommandBuffer, info: *const vk::RenderingInfo<'_>);
    cmd_execute_commands "vkCmdExecuteCommands" vk::PFN_vkCmdExecuteCommands = (cb: vk::CommandBuffer, n: u32, cbs: *const vk::CommandBuffer);
    cmd_draw "vkCmdDraw" vk::PFN_vkCmdDraw = (cb: vk::CommandBuffer, vertices: u32, instances: u32, first_vertex: u32, first_instance: u32);
    cmd_draw_indexed "vkCmdDrawIndexed" vk::PFN_vkCmdDrawIndexed = (cb: vk::CommandBuffer, indices: u32, instances: u32, first_index: u32, vertex_offset: i32, first_instance: u32);
    destroy_image "vkDestroyImage" vk::PFN_vkDestroyImage = (device: vk::Device, image: vk::Image, alloc: *const vk::AllocationCallbacks<'_>);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_reenter_only_command_has_a_hook() {
        // Which names are hooked depends on VK_FAULT_REENTER; the table itself must be complete.
        for names in spec::REENTER_ONLY {
            let core = names[0];
            let listed = [
                "vkQueueSubmit2",
                "vkBeginCommandBuffer",
                "vkEndCommandBuffer",
                "vkCmdBeginRenderPass",
                "vkCmdBeginRenderPass2",
                "vkCmdBeginRendering",
                "vkCmdExecuteCommands",
                "vkCmdDraw",
                "vkCmdDrawIndexed",
                "vkDestroyImage",
            ];
            assert!(listed.contains(&core), "{core} has no hook");
        }
        assert_eq!(VERT[0], 0x0723_0203, "SPIR-V magic");
    }
}
