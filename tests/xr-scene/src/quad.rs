//! `--quad`: a quad layer from a static swapchain (`XR_SWAPCHAIN_CREATE_STATIC_IMAGE_BIT`), what
//! apps use for menus and splash panels: half a view's size (so it has a view's aspect), filled
//! once after creation with a pattern (four coloured quadrants split by a white diagonal, uploaded
//! from a buffer), acquired and released once, and submitted every frame after the projection
//! layer, 1.5 m ahead in the stage space.

use crate::error::{Ctx, Result};
use crate::gpu::Gpu;
use crate::xr::XrSession;
use ash::vk;
use openxr as xr;

pub struct Quad {
    pub swapchain: xr::Swapchain<xr::Vulkan>,
    pub width: u32,
    pub height: u32,
}

/// The pattern's texel at (x, y) of a `w`×`h` image, RGBA8.
fn texel(x: u32, y: u32, w: u32, h: u32) -> [u8; 4] {
    let (u, v) = (x as f32 / w as f32, y as f32 / h as f32);
    if (u - v).abs() < 0.02 {
        return [255, 255, 255, 255];
    }
    match (u < 0.5, v < 0.5) {
        (true, true) => [220, 40, 40, 255],
        (false, true) => [40, 200, 60, 255],
        (true, false) => [40, 80, 220, 255],
        (false, false) => [230, 200, 40, 255],
    }
}

impl Quad {
    pub fn new(gpu: &Gpu, xs: &XrSession, format: vk::Format, view: vk::Extent2D) -> Result<Quad> {
        let (width, height) = ((view.width / 2).max(1), (view.height / 2).max(1));
        let mut swapchain = xs
            .session
            .create_swapchain(&xr::SwapchainCreateInfo {
                create_flags: xr::SwapchainCreateFlags::STATIC_IMAGE,
                usage_flags: xr::SwapchainUsageFlags::COLOR_ATTACHMENT | xr::SwapchainUsageFlags::TRANSFER_DST,
                format: format.as_raw() as u32,
                sample_count: 1,
                width,
                height,
                face_count: 1,
                array_size: 1,
                mip_count: 1,
            })
            .ctx("xrCreateSwapchain(quad)")?;
        let images = swapchain.enumerate_images().ctx("xrEnumerateSwapchainImages(quad)")?;
        let index = swapchain.acquire_image().ctx("xrAcquireSwapchainImage(quad)")?;
        swapchain.wait_image(xr::Duration::INFINITE).ctx("xrWaitSwapchainImage(quad)")?;
        let image = vk::Image::from_raw(images[index as usize]);
        fill(gpu, image, width, height)?;
        swapchain.release_image().ctx("xrReleaseSwapchainImage(quad)")?;
        Ok(Quad { swapchain, width, height })
    }
}

use ash::vk::Handle as _;

/// Uploads the pattern into `image` (acquired, in COLOR_ATTACHMENT_OPTIMAL, which it is left in).
fn fill(gpu: &Gpu, image: vk::Image, w: u32, h: u32) -> Result<()> {
    let d = &gpu.device;
    let bytes: Vec<u8> = (0..h).flat_map(|y| (0..w).flat_map(move |x| texel(x, y, w, h))).collect();
    // SAFETY: objects made, used and destroyed here on the app's device; the queue is idle
    // before and after (waited), and nothing else records on this thread meanwhile.
    unsafe {
        let buffer = d.create_buffer(&vk::BufferCreateInfo::default().size(bytes.len() as u64).usage(vk::BufferUsageFlags::TRANSFER_SRC), None).ctx("vkCreateBuffer")?;
        let req = d.get_buffer_memory_requirements(buffer);
        let ty = gpu.memory_type(req.memory_type_bits, vk::MemoryPropertyFlags::HOST_VISIBLE | vk::MemoryPropertyFlags::HOST_COHERENT)?;
        let memory = d.allocate_memory(&vk::MemoryAllocateInfo::default().allocation_size(req.size).memory_type_index(ty), None).ctx("vkAllocateMemory")?;
        d.bind_buffer_memory(buffer, memory, 0).ctx("vkBindBufferMemory")?;
        let ptr = d.map_memory(memory, 0, vk::WHOLE_SIZE, vk::MemoryMapFlags::empty()).ctx("vkMapMemory")?;
        std::ptr::copy_nonoverlapping(bytes.as_ptr(), ptr as *mut u8, bytes.len());
        d.unmap_memory(memory);
        let pool = d.create_command_pool(&vk::CommandPoolCreateInfo::default().queue_family_index(gpu.queue_family), None).ctx("vkCreateCommandPool")?;
        let cb = d.allocate_command_buffers(&vk::CommandBufferAllocateInfo::default().command_pool(pool).level(vk::CommandBufferLevel::PRIMARY).command_buffer_count(1)).ctx("vkAllocateCommandBuffers")?[0];
        d.begin_command_buffer(cb, &vk::CommandBufferBeginInfo::default().flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT)).ctx("vkBeginCommandBuffer")?;
        let range = vk::ImageSubresourceRange { aspect_mask: vk::ImageAspectFlags::COLOR, base_mip_level: 0, level_count: 1, base_array_layer: 0, layer_count: 1 };
        let barrier = |old, new, src, dst| {
            vk::ImageMemoryBarrier::default().old_layout(old).new_layout(new).src_access_mask(src).dst_access_mask(dst).image(image).subresource_range(range).src_queue_family_index(vk::QUEUE_FAMILY_IGNORED).dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
        };
        let to_dst = barrier(vk::ImageLayout::UNDEFINED, vk::ImageLayout::TRANSFER_DST_OPTIMAL, vk::AccessFlags::empty(), vk::AccessFlags::TRANSFER_WRITE);
        d.cmd_pipeline_barrier(cb, vk::PipelineStageFlags::TOP_OF_PIPE, vk::PipelineStageFlags::TRANSFER, vk::DependencyFlags::empty(), &[], &[], &[to_dst]);
        let region = vk::BufferImageCopy {
            image_subresource: vk::ImageSubresourceLayers { aspect_mask: vk::ImageAspectFlags::COLOR, mip_level: 0, base_array_layer: 0, layer_count: 1 },
            image_extent: vk::Extent3D { width: w, height: h, depth: 1 },
            ..Default::default()
        };
        d.cmd_copy_buffer_to_image(cb, buffer, image, vk::ImageLayout::TRANSFER_DST_OPTIMAL, &[region]);
        let back = barrier(vk::ImageLayout::TRANSFER_DST_OPTIMAL, vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL, vk::AccessFlags::TRANSFER_WRITE, vk::AccessFlags::COLOR_ATTACHMENT_WRITE);
        d.cmd_pipeline_barrier(cb, vk::PipelineStageFlags::TRANSFER, vk::PipelineStageFlags::COLOR_ATTACHMENT_OUTPUT, vk::DependencyFlags::empty(), &[], &[], &[back]);
        d.end_command_buffer(cb).ctx("vkEndCommandBuffer")?;
        let cbs = [cb];
        d.queue_submit(gpu.queue, &[vk::SubmitInfo::default().command_buffers(&cbs)], vk::Fence::null()).ctx("vkQueueSubmit")?;
        d.queue_wait_idle(gpu.queue).ctx("vkQueueWaitIdle")?;
        d.destroy_command_pool(pool, None);
        d.destroy_buffer(buffer, None);
        d.free_memory(memory, None);
    }
    Ok(())
}
