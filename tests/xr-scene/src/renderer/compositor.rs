//! `--submit-via openvr`: a second component on the app's device that copies the app's textures
//! into the swapchain, as xrizer and OpenComposite do for an OpenVR game — its own command pool and
//! command buffer on the app's queue family, its own `vkQueueSubmit` on the app's queue after the
//! app's frame, no fence and no semaphore.

use crate::error::{Ctx, Result};
use crate::gpu::Gpu;
use ash::vk;

pub(super) struct Compositor {
    device: ash::Device,
    pool: vk::CommandPool,
    cmd: vk::CommandBuffer,
}

impl Compositor {
    pub fn new(gpu: &Gpu) -> Result<Compositor> {
        let d = &gpu.device;
        // SAFETY: plain object creation on a live device; destroyed in Drop.
        unsafe {
            let pool = d.create_command_pool(&vk::CommandPoolCreateInfo::default().queue_family_index(gpu.queue_family), None).ctx("vkCreateCommandPool(compositor)")?;
            let info = vk::CommandBufferAllocateInfo::default().command_pool(pool).level(vk::CommandBufferLevel::PRIMARY).command_buffer_count(1);
            match d.allocate_command_buffers(&info) {
                Ok(c) => Ok(Compositor { device: d.clone(), pool, cmd: c[0] }),
                Err(e) => {
                    d.destroy_command_pool(pool, None);
                    Err(crate::error::Error(format!("vkAllocateCommandBuffers(compositor): {e}")))
                }
            }
        }
    }

    /// Records `copy` into the compositor's command buffer and submits it on its own. Its last
    /// submission is complete: the app waited for its own frame since, which it submitted after
    /// that one (a fence's wait covers everything submitted to the queue before it).
    pub fn submit(&self, gpu: &Gpu, copy: impl FnOnce(vk::CommandBuffer)) -> Result<()> {
        let d = &self.device;
        // SAFETY: the pool's command buffer is not pending (above); the queue is the app's, used
        // on this thread only (`--threads` is refused with this option).
        unsafe {
            d.reset_command_pool(self.pool, vk::CommandPoolResetFlags::empty()).ctx("vkResetCommandPool(compositor)")?;
            d.begin_command_buffer(self.cmd, &vk::CommandBufferBeginInfo::default().flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT)).ctx("vkBeginCommandBuffer(compositor)")?;
            copy(self.cmd);
            d.end_command_buffer(self.cmd).ctx("vkEndCommandBuffer(compositor)")?;
            let cmds = [self.cmd];
            d.queue_submit(gpu.queue, &[vk::SubmitInfo::default().command_buffers(&cmds)], vk::Fence::null()).ctx("vkQueueSubmit(compositor)")
        }
    }
}

impl Drop for Compositor {
    fn drop(&mut self) {
        // SAFETY: the renderer waited for the device before its fields drop; the pool is ours.
        unsafe { self.device.destroy_command_pool(self.pool, None) };
    }
}
