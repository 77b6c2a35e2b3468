//! `--stats`: the shaded-fragment counters the fragment shader increments, the frame's GPU time from
//! timestamp queries, and the JSON file of docs/testing.md. These numbers are how tests tell whether
//! the layer under test really made the app shade less.

use crate::error::{Ctx, Error, Result};
use crate::gpu::Gpu;
use ash::vk;
use serde::Serialize;
use std::path::PathBuf;

/// Per-view counters and the frame's two timestamps.
///
/// Each view's counter sits in its own `minStorageBufferOffsetAlignment`-aligned block, bound with a
/// dynamic offset per draw, so draws of different eyes inside one render pass (side-by-side) touch
/// disjoint memory and need no barrier between them. The multiview draw binds offset 0 and indexes
/// both counters of the first block with gl_ViewIndex.
pub struct GpuCounters {
    device: ash::Device,
    pub buffer: vk::Buffer,
    memory: vk::DeviceMemory,
    mapped: *const u8,

    pub block: u64,
    query_pool: vk::QueryPool,
    timestamp_period: f32,
    valid_mask: u64,
}

const QUERY_COUNT: u32 = 4;

/// Bytes the shader may see through one binding: `uint counts[2]`.
pub const BINDING_RANGE: u64 = 8;

impl GpuCounters {
    pub fn new(gpu: &Gpu) -> Result<GpuCounters> {
        let d = &gpu.device;
        let block = gpu.props.limits.min_storage_buffer_offset_alignment.max(BINDING_RANGE);
        let size = block + BINDING_RANGE;
        let mut c = GpuCounters {
            device: d.clone(),
            buffer: vk::Buffer::null(),
            memory: vk::DeviceMemory::null(),
            mapped: std::ptr::null(),

            block,
            query_pool: vk::QueryPool::null(),
            timestamp_period: gpu.props.limits.timestamp_period,
            valid_mask: match gpu.timestamp_valid_bits {
                0 => 0,
                64.. => u64::MAX,
                b => (1u64 << b) - 1,
            },
        };
        (c.buffer, c.memory, c.mapped) = readback_buffer(gpu, size, "counters")?;
        // SAFETY: valid create infos; partial results are destroyed by Drop.
        unsafe {
            if c.valid_mask != 0 {
                // Only queries 0 and 1 are used. The spare two absorb a lavapipe 25.0 defect:
                // a timestamp written after a multiview pass ended is still written to
                // "one query per view" (2), which overran a 2-query pool and crashed the driver.
                c.query_pool = d
                    .create_query_pool(
                        &vk::QueryPoolCreateInfo::default().query_type(vk::QueryType::TIMESTAMP).query_count(QUERY_COUNT),
                        None,
                    )
                    .ctx("vkCreateQueryPool")?;
            }
        }
        Ok(c)
    }

    /// The dynamic offset for the draw of `view` (0 for the multiview draw).
    pub fn dynamic_offset(&self, view: u32, multiview: bool) -> u32 {
        if multiview {
            0
        } else {
            (self.block * view as u64) as u32
        }
    }

    fn byte_offset(&self, view: u32, multiview: bool) -> u64 {
        self.dynamic_offset(view, multiview) as u64 + 4 * view as u64
    }

    /// Start of the frame's command buffer: first timestamp, and counters zeroed and made
    /// visible to the fragment shader.
    pub fn record_start(&self, cmd: vk::CommandBuffer) {
        let d = &self.device;
        // SAFETY: recording state, outside any render pass.
        unsafe {
            if self.query_pool != vk::QueryPool::null() {
                d.cmd_reset_query_pool(cmd, self.query_pool, 0, QUERY_COUNT);
                d.cmd_write_timestamp(cmd, vk::PipelineStageFlags::TOP_OF_PIPE, self.query_pool, 0);
            }
            // The previous frame's shader atomics must be done before the fill overwrites them.
            let before = [self.barrier(vk::AccessFlags::SHADER_WRITE, vk::AccessFlags::TRANSFER_WRITE)];
            d.cmd_pipeline_barrier(
                cmd,
                vk::PipelineStageFlags::FRAGMENT_SHADER,
                vk::PipelineStageFlags::TRANSFER,
                vk::DependencyFlags::empty(),
                &[],
                &before,
                &[],
            );
            d.cmd_fill_buffer(cmd, self.buffer, 0, vk::WHOLE_SIZE, 0);
        }
    }

    /// The fill → fragment-shader dependency; merged into the frame's pre-pass barrier.
    pub fn after_fill_barrier(&self) -> vk::BufferMemoryBarrier<'static> {
        self.barrier(vk::AccessFlags::TRANSFER_WRITE, vk::AccessFlags::SHADER_READ | vk::AccessFlags::SHADER_WRITE)
    }

    fn barrier(&self, src: vk::AccessFlags, dst: vk::AccessFlags) -> vk::BufferMemoryBarrier<'static> {
        vk::BufferMemoryBarrier::default()
            .src_access_mask(src)
            .dst_access_mask(dst)
            .src_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
            .dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
            .buffer(self.buffer)
            .offset(0)
            .size(vk::WHOLE_SIZE)
    }

    /// End of the frame's command buffer: counters made visible to the host, second timestamp.
    pub fn record_end(&self, cmd: vk::CommandBuffer) {
        let d = &self.device;
        let b = [self.barrier(vk::AccessFlags::SHADER_WRITE, vk::AccessFlags::HOST_READ)];
        // SAFETY: recording state, outside any render pass.
        unsafe {
            d.cmd_pipeline_barrier(
                cmd,
                vk::PipelineStageFlags::FRAGMENT_SHADER,
                vk::PipelineStageFlags::HOST,
                vk::DependencyFlags::empty(),
                &[],
                &b,
                &[],
            );
            if self.query_pool != vk::QueryPool::null() {
                d.cmd_write_timestamp(cmd, vk::PipelineStageFlags::BOTTOM_OF_PIPE, self.query_pool, 1);
            }
        }
    }

    /// Reads the finished frame's numbers. Call only after its fence signalled.
    pub fn read(&self, multiview: bool) -> Result<(f64, [u64; 2])> {
        let d = &self.device;
        // SAFETY: the fence of the frame that wrote these was waited on; the mapping is live.
        unsafe {
            d.invalidate_mapped_memory_ranges(&[vk::MappedMemoryRange::default()
                .memory(self.memory)
                .offset(0)
                .size(vk::WHOLE_SIZE)])
                .ctx("vkInvalidateMappedMemoryRanges")?;
            let mut counts = [0u64; 2];
            for (v, c) in counts.iter_mut().enumerate() {
                let p = self.mapped.add(self.byte_offset(v as u32, multiview) as usize) as *const u32;
                *c = p.read_volatile() as u64;
            }
            let mut ms = 0.0;
            if self.query_pool != vk::QueryPool::null() {
                let mut ts = [0u64; 2];
                d.get_query_pool_results(self.query_pool, 0, &mut ts, vk::QueryResultFlags::TYPE_64 | vk::QueryResultFlags::WAIT)
                    .ctx("vkGetQueryPoolResults")?;
                let ticks = (ts[1] & self.valid_mask).wrapping_sub(ts[0] & self.valid_mask) & self.valid_mask;
                ms = ticks as f64 * self.timestamp_period as f64 / 1.0e6;
            }
            Ok((ms, counts))
        }
    }
}

impl Drop for GpuCounters {
    fn drop(&mut self) {
        // SAFETY: the owner waited for idle; null handles are ignored by the destroy functions.
        unsafe {
            self.device.destroy_query_pool(self.query_pool, None);
            self.device.destroy_buffer(self.buffer, None);
            if self.memory != vk::DeviceMemory::null() {
                self.device.free_memory(self.memory, None);
            }
        }
    }
}

/// `--pixel-stats`: shaded fragments per pixel of each view's image rect.
///
/// One `minStorageBufferOffsetAlignment`-aligned region per view (row-major, rect-relative, y
/// down). Per-eye and side-by-side draws bind their view's region alone with a dynamic offset, so
/// draws of different eyes in one pass touch disjoint memory; the multiview draw binds both regions
/// at offset 0 and indexes with gl_ViewIndex × `view_stride`.
pub struct PixelCounters {
    device: ash::Device,
    pub buffer: vk::Buffer,
    memory: vk::DeviceMemory,
    mapped: *const u8,
    /// Bytes from one view's region to the next.
    region: u64,
    sizes: [(u32, u32); 2],
}

impl PixelCounters {
    /// Bytes from one view's region to the next: the larger view's counts, aligned for dynamic
    /// offsets.
    fn region(gpu: &Gpu, sizes: [(u32, u32); 2]) -> u64 {
        let align = gpu.props.limits.min_storage_buffer_offset_alignment.max(4);
        let bytes = sizes.iter().map(|&(w, h)| w as u64 * h as u64 * 4).max().unwrap_or(4).max(4);
        bytes.div_ceil(align) * align
    }

    /// Elements between the views' regions inside the bound range (multiview only; 0 otherwise),
    /// known before any counters exist: the push constants carry it, and each frame set has its
    /// own counters of the same shape.
    pub fn stride_for(gpu: &Gpu, sizes: [(u32, u32); 2], multiview: bool) -> u32 {
        if multiview {
            (Self::region(gpu, sizes) / 4) as u32
        } else {
            0
        }
    }

    pub fn new(gpu: &Gpu, sizes: [(u32, u32); 2]) -> Result<PixelCounters> {
        let d = &gpu.device;
        let region = Self::region(gpu, sizes);
        let mut p = PixelCounters {
            device: d.clone(),
            buffer: vk::Buffer::null(),
            memory: vk::DeviceMemory::null(),
            mapped: std::ptr::null(),
            region,
            sizes,
        };
        (p.buffer, p.memory, p.mapped) = readback_buffer(gpu, 2 * region, "pixel counters")?;
        Ok(p)
    }

    /// The dynamic offset for the draw of `view` (0 for the multiview draw).
    pub fn dynamic_offset(&self, view: u32, multiview: bool) -> u32 {
        if multiview {
            0
        } else {
            (self.region * view as u64) as u32
        }
    }

    /// Bytes the shader may see through the binding: one region, both for multiview.
    pub fn binding_range(&self, multiview: bool) -> u64 {
        if multiview {
            2 * self.region
        } else {
            self.region
        }
    }

    /// Start of the frame: the previous frame's atomics done, then the regions zeroed. The
    /// fill → fragment-shader dependency is `after_fill_barrier`, in the pre-pass barrier.
    pub fn record_start(&self, cmd: vk::CommandBuffer) {
        let d = &self.device;
        let before = [buffer_barrier(self.buffer, vk::AccessFlags::SHADER_WRITE, vk::AccessFlags::TRANSFER_WRITE)];
        // SAFETY: recording state, outside any render pass.
        unsafe {
            d.cmd_pipeline_barrier(
                cmd,
                vk::PipelineStageFlags::FRAGMENT_SHADER,
                vk::PipelineStageFlags::TRANSFER,
                vk::DependencyFlags::empty(),
                &[],
                &before,
                &[],
            );
            d.cmd_fill_buffer(cmd, self.buffer, 0, vk::WHOLE_SIZE, 0);
        }
    }

    pub fn after_fill_barrier(&self) -> vk::BufferMemoryBarrier<'static> {
        buffer_barrier(self.buffer, vk::AccessFlags::TRANSFER_WRITE, vk::AccessFlags::SHADER_READ | vk::AccessFlags::SHADER_WRITE)
    }

    /// End of the frame: the counts made visible to the host.
    pub fn record_end(&self, cmd: vk::CommandBuffer) {
        let b = [buffer_barrier(self.buffer, vk::AccessFlags::SHADER_WRITE, vk::AccessFlags::HOST_READ)];
        // SAFETY: recording state, outside any render pass.
        unsafe {
            self.device.cmd_pipeline_barrier(
                cmd,
                vk::PipelineStageFlags::FRAGMENT_SHADER,
                vk::PipelineStageFlags::HOST,
                vk::DependencyFlags::empty(),
                &[],
                &b,
                &[],
            );
        }
    }

    /// Writes the finished frame's counts as `dir/frame-NNNNN-view-V.u32`. Call only after the
    /// frame's fence signalled.
    pub fn write(&self, dir: &std::path::Path, frame: u64) -> Result<()> {
        // SAFETY: the fence of the frame that wrote these was waited on; the mapping is live and
        // each region holds w × h u32s.
        let views: Vec<Vec<u8>> = unsafe {
            self.device
                .invalidate_mapped_memory_ranges(&[vk::MappedMemoryRange::default().memory(self.memory).offset(0).size(vk::WHOLE_SIZE)])
                .ctx("vkInvalidateMappedMemoryRanges")?;
            self.sizes
                .iter()
                .enumerate()
                .map(|(v, &(w, h))| {
                    let n = w as usize * h as usize * 4;
                    std::slice::from_raw_parts(self.mapped.add(v * self.region as usize), n).to_vec()
                })
                .collect()
        };
        for (v, bytes) in views.iter().enumerate() {
            // The buffer holds native-endian u32s; the file is little-endian.
            let le: Vec<u8> = bytes.chunks_exact(4).flat_map(|c| u32::from_ne_bytes([c[0], c[1], c[2], c[3]]).to_le_bytes()).collect();
            let path = dir.join(format!("frame-{frame:05}-view-{v}.u32"));
            std::fs::write(&path, le).map_err(|e| Error(format!("writing {}: {e}", path.display())))?;
        }
        Ok(())
    }
}

impl Drop for PixelCounters {
    fn drop(&mut self) {
        // SAFETY: the owner waited for idle; null handles are ignored by the destroy functions.
        unsafe {
            self.device.destroy_buffer(self.buffer, None);
            if self.memory != vk::DeviceMemory::null() {
                self.device.free_memory(self.memory, None);
            }
        }
    }
}

fn buffer_barrier(buffer: vk::Buffer, src: vk::AccessFlags, dst: vk::AccessFlags) -> vk::BufferMemoryBarrier<'static> {
    vk::BufferMemoryBarrier::default()
        .src_access_mask(src)
        .dst_access_mask(dst)
        .src_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
        .dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
        .buffer(buffer)
        .offset(0)
        .size(vk::WHOLE_SIZE)
}

#[derive(Debug, Serialize)]
pub struct ViewStats {
    pub view: u32,
    pub shaded_fragments: u64,
}

#[derive(Debug, Serialize)]
pub struct FrameStats {
    pub frame: u64,
    pub gpu_time_ms: f64,
    /// CPU time inside the frame's OpenXR calls (wait, begin, input sync, locate views, swapchain
    /// acquire/wait/release, end), in µs.
    pub cpu_xr_us: f64,
    /// CPU time recording the frame's command buffer, in µs.
    pub cpu_record_us: f64,
    /// CPU time per kind of call the layer intercepts (the OpenXR calls above one by one, and
    /// `vkQueueSubmit`): what the layer's overhead per call is measured on (examples/overhead.rs).
    pub cpu_calls: CallTimes,
    pub views: Vec<ViewStats>,
}

/// CPU time of one kind of call in one frame.
#[derive(Debug, Default, Clone, Copy, Serialize)]
pub struct CallTime {
    /// Summed over the frame's calls, µs.
    pub us: f64,
    pub calls: u32,
}

/// CPU time per kind of call in one frame, by the call's name.
#[derive(Debug, Default, Clone, Serialize)]
#[serde(transparent)]
pub struct CallTimes(std::collections::BTreeMap<&'static str, CallTime>);

impl CallTimes {
    /// Runs `f` (one call of `name`) and adds its time.
    pub fn time<T>(&mut self, name: &'static str, f: impl FnOnce() -> T) -> T {
        let start = std::time::Instant::now();
        let r = f();
        self.add(name, start.elapsed().as_secs_f64() * 1e6);
        r
    }
    pub fn add(&mut self, name: &'static str, us: f64) {
        let t = self.0.entry(name).or_default();
        t.us += us;
        t.calls += 1;
    }
    /// The sum over every call, µs.
    pub fn total_us(&self) -> f64 {
        self.0.values().map(|t| t.us).sum()
    }
}

#[derive(Debug, Serialize)]
struct StatsFile<'a> {
    frames: &'a [FrameStats],
}

/// The `--stats` file, rewritten after every frame so a run cut short still leaves valid JSON.
pub struct StatsLog {
    path: PathBuf,
    frames: Vec<FrameStats>,
}

impl StatsLog {
    pub fn new(path: PathBuf) -> StatsLog {
        StatsLog { path, frames: Vec::new() }
    }

    /// Adds a frame's numbers in frame order (`--record-once` measures frames when their GPU
    /// work is found finished, which need not be the order they were submitted in).
    pub fn push(&mut self, f: FrameStats) -> Result<()> {
        let at = self.frames.partition_point(|g| g.frame < f.frame);
        self.frames.insert(at, f);
        self.write()
    }

    /// Written beside the file and renamed over it, so a crash in the middle (a driver fault in
    /// another thread) leaves the previous complete file, never a truncated one.
    pub fn write(&self) -> Result<()> {
        let json = to_json(&self.frames);
        let mut tmp = self.path.clone().into_os_string();
        tmp.push(".new");
        let err = |e: std::io::Error| Error(format!("writing {}: {e}", self.path.display()));
        std::fs::write(&tmp, json).map_err(err)?;
        std::fs::rename(&tmp, &self.path).map_err(err)
    }
}

pub fn to_json(frames: &[FrameStats]) -> String {
    serde_json::to_string_pretty(&StatsFile { frames }).expect("stats serialize")
}

/// A mapped storage buffer the GPU writes counters into and the CPU reads back after the frame's
/// fence. Cached memory reads back faster; invalidation before reading makes it correct either
/// way. On failure, whatever was made is destroyed again.
fn readback_buffer(gpu: &Gpu, size: u64, what: &str) -> Result<(vk::Buffer, vk::DeviceMemory, *const u8)> {
    let d = &gpu.device;
    let info = vk::BufferCreateInfo::default()
        .size(size)
        .usage(vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::TRANSFER_DST);
    // SAFETY: valid create infos; on any error the objects made so far are destroyed before
    // returning, and nothing else refers to them yet.
    unsafe {
        let buffer = d.create_buffer(&info, None).ctx(&format!("vkCreateBuffer({what})"))?;
        let made = (|| {
            let req = d.get_buffer_memory_requirements(buffer);
            let ty = gpu
                .memory_type(req.memory_type_bits, vk::MemoryPropertyFlags::HOST_VISIBLE | vk::MemoryPropertyFlags::HOST_CACHED)
                .or_else(|_| gpu.memory_type(req.memory_type_bits, vk::MemoryPropertyFlags::HOST_VISIBLE))?;
            let memory = d
                .allocate_memory(&vk::MemoryAllocateInfo::default().allocation_size(req.size).memory_type_index(ty), None)
                .ctx(&format!("vkAllocateMemory({what})"))?;
            let mapped = d
                .bind_buffer_memory(buffer, memory, 0)
                .ctx("vkBindBufferMemory")
                .and_then(|_| d.map_memory(memory, 0, vk::WHOLE_SIZE, vk::MemoryMapFlags::empty()).ctx(&format!("vkMapMemory({what})")));
            match mapped {
                Ok(m) => Ok((memory, m as *const u8)),
                Err(e) => {
                    d.free_memory(memory, None);
                    Err(e)
                }
            }
        })();
        match made {
            Ok((memory, mapped)) => Ok((buffer, memory, mapped)),
            Err(e) => {
                d.destroy_buffer(buffer, None);
                Err(e)
            }
        }
    }
}


#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn json_shape_matches_contract() {
        let frames = [FrameStats {
            frame: 0,
            gpu_time_ms: 1.5,
            cpu_xr_us: 10.0,
            cpu_record_us: 20.0,
            cpu_calls: CallTimes::default(),
            views: vec![ViewStats { view: 0, shaded_fragments: 12345 }, ViewStats { view: 1, shaded_fragments: 12001 }],
        }];
        let v: serde_json::Value = serde_json::from_str(&to_json(&frames)).unwrap();
        assert_eq!(v["frames"][0]["frame"], 0);
        assert_eq!(v["frames"][0]["gpu_time_ms"], 1.5);
        assert_eq!(v["frames"][0]["views"][1]["view"], 1);
        assert_eq!(v["frames"][0]["views"][1]["shaded_fragments"], 12001);
    }
}
