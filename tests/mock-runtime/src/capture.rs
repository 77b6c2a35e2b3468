//! `MOCK_XR_CAPTURE`: copies what the app submitted in xrEndFrame out of the swapchain images
//! (on the app's queue, fenced) into PNGs plus frames.json, as docs/testing.md specifies. This
//! is how the end-to-end tests see what an app — or a layer in front of it — really rendered.
//! Mip level 0 is what is read; a multisampled swapchain's rect is resolved first.

use std::io::Write;
use std::path::Path;
use std::sync::Arc;

use ash::vk;
use openxr_sys as xr;
use serde_json::{json, Value};

use crate::session::Session;
use crate::swapchain::{attachment_layout, full_aspect, is_depth, Swapchain};
use crate::util::XrResult;
use crate::visibility_mask;
use crate::vulkan::{vk_err, VkContext};

pub struct SubmittedDepth {
    pub swapchain: Arc<Swapchain>,
    pub image_index: u32,
    pub rect: xr::Rect2Di,
    pub array_index: u32,
    pub min_depth: f32,
    pub max_depth: f32,
    pub near_z: f32,
    pub far_z: f32,
}

pub struct SubmittedView {
    pub pose: xr::Posef,
    pub fov: xr::Fovf,
    pub swapchain: Arc<Swapchain>,
    pub image_index: u32,
    pub rect: xr::Rect2Di,
    pub array_index: u32,
    pub depth: Option<SubmittedDepth>,
}

pub struct SubmittedLayer {
    pub kind: &'static str,
    pub flags: u64,
    pub space: &'static str,
    pub views: Vec<SubmittedView>,
    /// A quad layer's own fields (None for projection layers).
    pub quad: Option<SubmittedQuad>,
}

/// What a quad layer showed: its sub-image, pose and size in its space, which eyes see it.
pub struct SubmittedQuad {
    pub pose: xr::Posef,
    pub size: [f32; 2],
    pub eye_visibility: i32,
    pub swapchain: Arc<Swapchain>,
    pub image_index: u32,
    pub rect: xr::Rect2Di,
    pub array_index: u32,
}

#[derive(Debug, Default)]
pub struct CaptureState {
    frames: Vec<Value>,
}

/// Numbers as written: the f32's shortest decimal form; non-finite (an infinite far plane) → null.
fn num(x: f32) -> Value {
    if x.is_finite() {
        x.to_string().parse::<f64>().map(Value::from).unwrap_or(Value::Null)
    } else {
        Value::Null
    }
}

fn rect_json(r: &xr::Rect2Di) -> Value {
    json!({ "x": r.offset.x, "y": r.offset.y, "width": r.extent.width, "height": r.extent.height })
}

pub fn file_name(frame: u64, layer: usize, view: usize, depth: bool) -> String {
    let layer = if layer == 0 { String::new() } else { format!("-layer-{layer}") };
    let suffix = if depth { "-depth" } else { "" };
    format!("frame-{frame:05}{layer}-view-{view}{suffix}.png")
}

/// A quad layer's captured sub-image: `frame-NNNNN-layer-L-quad.png`.
pub fn quad_file_name(frame: u64, layer: usize) -> String {
    format!("frame-{frame:05}-layer-{layer}-quad.png")
}

/// Bytes per texel of what vkCmdCopyImageToBuffer writes for the copied aspect.
fn texel_size(f: vk::Format) -> u64 {
    match f {
        vk::Format::D16_UNORM => 2,
        _ => 4,
    }
}

/// One region to copy: (swapchain, image index, rect, layer, file).
struct Job<'a> {
    sc: &'a Arc<Swapchain>,
    image_index: u32,
    rect: xr::Rect2Di,
    layer: u32,
    file: String,
    offset: u64,
}

/// Converts copied texels to PNG samples: 8-bit RGB for colour, 16-bit grey for depth.
pub fn encode_png(format: vk::Format, width: u32, height: u32, texels: &[u8]) -> Vec<u8> {
    let n = (width * height) as usize;
    let (color, depth16, data): (png::ColorType, bool, Vec<u8>) = match format {
        vk::Format::B8G8R8A8_SRGB | vk::Format::B8G8R8A8_UNORM => {
            (png::ColorType::Rgb, false, texels[..n * 4].chunks_exact(4).flat_map(|p| [p[2], p[1], p[0]]).collect())
        }
        f if !is_depth(f) => (png::ColorType::Rgb, false, texels[..n * 4].chunks_exact(4).flat_map(|p| [p[0], p[1], p[2]]).collect()),
        vk::Format::D16_UNORM => (
            png::ColorType::Grayscale,
            true,
            texels[..n * 2].chunks_exact(2).flat_map(|p| u16::from_le_bytes([p[0], p[1]]).to_be_bytes()).collect(),
        ),
        vk::Format::D24_UNORM_S8_UINT => (
            png::ColorType::Grayscale,
            true,
            texels[..n * 4]
                .chunks_exact(4)
                .flat_map(|p| {
                    let v = u32::from_le_bytes([p[0], p[1], p[2], p[3]]) & 0x00FF_FFFF;
                    let d = v as f64 / 16_777_215.0;
                    ((d * 65535.0).round() as u16).to_be_bytes()
                })
                .collect(),
        ),
        _ => (
            png::ColorType::Grayscale,
            true,
            texels[..n * 4]
                .chunks_exact(4)
                .flat_map(|p| {
                    let d = f32::from_le_bytes([p[0], p[1], p[2], p[3]]);
                    let d = if d.is_nan() { 0.0 } else { d.clamp(0.0, 1.0) };
                    ((d as f64 * 65535.0).round() as u16).to_be_bytes()
                })
                .collect(),
        ),
    };
    let mut out = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut out, width, height);
        enc.set_color(color);
        enc.set_depth(if depth16 { png::BitDepth::Sixteen } else { png::BitDepth::Eight });
        let mut w = enc.write_header().expect("png header to memory");
        w.write_image_data(&data).expect("png data to memory");
    }
    out
}

fn write_atomic(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let tmp = path.with_extension("tmp");
    let mut f = std::fs::File::create(&tmp)?;
    f.write_all(bytes)?;
    drop(f);
    std::fs::rename(tmp, path)
}

fn io_err(e: std::io::Error) -> xr::Result {
    eprintln!("[mock-runtime] capture: {e}");
    xr::Result::ERROR_RUNTIME_FAILURE
}

/// A single-sampled image of one multisampled job's rect: `vkCmdResolveImage` writes the
/// submitted samples' average into it and the copy to the buffer reads it, so a capture of an
/// MSAA swapchain is the resolved picture (what a compositor would show), not one sample.
fn create_resolve_target(vk: &VkContext, format: vk::Format, extent: vk::Extent3D) -> XrResult<(vk::Image, vk::DeviceMemory)> {
    let d = &vk.device;
    let ci = vk::ImageCreateInfo::default()
        .image_type(vk::ImageType::TYPE_2D)
        .format(format)
        .extent(extent)
        .mip_levels(1)
        .array_layers(1)
        .samples(vk::SampleCountFlags::TYPE_1)
        .tiling(vk::ImageTiling::OPTIMAL)
        .usage(vk::ImageUsageFlags::TRANSFER_DST | vk::ImageUsageFlags::TRANSFER_SRC)
        .sharing_mode(vk::SharingMode::EXCLUSIVE)
        .initial_layout(vk::ImageLayout::UNDEFINED);
    // SAFETY: valid device and create info.
    let image = unsafe { d.create_image(&ci, None) }.map_err(vk_err("vkCreateImage"))?;
    let memory = (|| {
        // SAFETY: image of this device.
        let req = unsafe { d.get_image_memory_requirements(image) };
        let ty = vk.memory_type(req.memory_type_bits, vk::MemoryPropertyFlags::DEVICE_LOCAL)?;
        // SAFETY: valid allocate info.
        let mem = unsafe { d.allocate_memory(&vk::MemoryAllocateInfo::default().allocation_size(req.size).memory_type_index(ty), None) }
            .map_err(vk_err("vkAllocateMemory"))?;
        // SAFETY: fresh image and memory of sufficient size.
        if let Err(e) = unsafe { d.bind_image_memory(image, mem, 0) } {
            // SAFETY: never used.
            unsafe { d.free_memory(mem, None) };
            return Err(vk_err("vkBindImageMemory")(e));
        }
        Ok(mem)
    })();
    match memory {
        Ok(m) => Ok((image, m)),
        Err(e) => {
            // SAFETY: never used.
            unsafe { d.destroy_image(image, None) };
            Err(e)
        }
    }
}

fn extent_of(r: &xr::Rect2Di) -> vk::Extent3D {
    vk::Extent3D { width: r.extent.width as u32, height: r.extent.height as u32, depth: 1 }
}

/// Copies every job's region (mip level 0; resolved first where the swapchain is multisampled)
/// into one host-visible buffer and returns its bytes.
fn read_back(s: &Session, jobs: &[Job], size: u64) -> XrResult<Vec<u8>> {
    let vk = s.vk()?;
    let d = &vk.device;
    // One resolve target per multisampled job (None for the others); made before anything is
    // recorded, destroyed after the fence (or at once, on failure).
    let mut resolved: Vec<Option<(vk::Image, vk::DeviceMemory)>> = Vec::new();
    let made = jobs.iter().try_for_each(|j| {
        let target = if j.sc.samples == vk::SampleCountFlags::TYPE_1 {
            None
        } else if is_depth(j.sc.format) {
            // xrCreateSwapchain refuses multisampled depth; never read one sample as if resolved.
            crate::log!("capture: multisampled depth swapchain {} cannot be resolved", j.sc.handle);
            return Err(xr::Result::ERROR_RUNTIME_FAILURE);
        } else {
            Some(create_resolve_target(vk, j.sc.format, extent_of(&j.rect))?)
        };
        resolved.push(target);
        Ok(())
    });
    let destroy_resolved = |resolved: &[Option<(vk::Image, vk::DeviceMemory)>]| {
        for (i, m) in resolved.iter().flatten() {
            // SAFETY: no pending GPU work uses them (fence waited, or never submitted).
            unsafe {
                d.destroy_image(*i, None);
                d.free_memory(*m, None);
            }
        }
    };
    if let Err(e) = made {
        destroy_resolved(&resolved);
        return Err(e);
    }
    let result = read_back_with(vk, jobs, &resolved, size);
    destroy_resolved(&resolved);
    result
}

fn read_back_with(vk: &VkContext, jobs: &[Job], resolved: &[Option<(vk::Image, vk::DeviceMemory)>], size: u64) -> XrResult<Vec<u8>> {
    let d = &vk.device;
    let bci = vk::BufferCreateInfo::default().size(size).usage(vk::BufferUsageFlags::TRANSFER_DST).sharing_mode(vk::SharingMode::EXCLUSIVE);
    // SAFETY: valid device and create info.
    let buffer = unsafe { d.create_buffer(&bci, None) }.map_err(vk_err("vkCreateBuffer"))?;
    let mut memory = vk::DeviceMemory::null();
    let result = (|| {
        // SAFETY: buffer of this device.
        let req = unsafe { d.get_buffer_memory_requirements(buffer) };
        let ty = vk.memory_type(req.memory_type_bits, vk::MemoryPropertyFlags::HOST_VISIBLE)?;
        let coherent = vk.mem_props.memory_types[ty as usize].property_flags.contains(vk::MemoryPropertyFlags::HOST_COHERENT);
        // SAFETY: valid allocation info.
        memory = unsafe { d.allocate_memory(&vk::MemoryAllocateInfo::default().allocation_size(req.size).memory_type_index(ty), None) }
            .map_err(vk_err("vkAllocateMemory"))?;
        // SAFETY: fresh buffer and memory.
        unsafe { d.bind_buffer_memory(buffer, memory, 0) }.map_err(vk_err("vkBindBufferMemory"))?;

        // Each distinct image once: (swapchain, image index).
        let mut images: Vec<(&Arc<Swapchain>, u32)> = Vec::new();
        for j in jobs {
            if !images.iter().any(|(sc, i)| sc.handle == j.sc.handle && *i == j.image_index) {
                images.push((j.sc, j.image_index));
            }
        }
        // Every level: the whole image is in its attachment layout whenever the app does not
        // hold it, and goes back there as one.
        let range = |sc: &Swapchain| vk::ImageSubresourceRange {
            aspect_mask: full_aspect(sc.format),
            base_mip_level: 0,
            level_count: sc.mip_levels,
            base_array_layer: 0,
            layer_count: sc.array_size,
        };
        vk.submit_and_wait(|d, cb| {
            // SAFETY: recording into the runtime's command buffer; every handle is of this device.
            unsafe {
                for (sc, i) in &images {
                    // What may have written the image: the app's attachment writes, or copies /
                    // resolves into it (transfer writes).
                    let (src_stage, src_access) = if is_depth(sc.format) {
                        (
                            vk::PipelineStageFlags::EARLY_FRAGMENT_TESTS | vk::PipelineStageFlags::LATE_FRAGMENT_TESTS | vk::PipelineStageFlags::TRANSFER,
                            vk::AccessFlags::DEPTH_STENCIL_ATTACHMENT_WRITE | vk::AccessFlags::TRANSFER_WRITE,
                        )
                    } else {
                        (
                            vk::PipelineStageFlags::COLOR_ATTACHMENT_OUTPUT | vk::PipelineStageFlags::TRANSFER,
                            vk::AccessFlags::COLOR_ATTACHMENT_WRITE | vk::AccessFlags::TRANSFER_WRITE,
                        )
                    };
                    let b = vk::ImageMemoryBarrier::default()
                        .src_access_mask(src_access)
                        .dst_access_mask(vk::AccessFlags::TRANSFER_READ)
                        .old_layout(attachment_layout(sc.format))
                        .new_layout(vk::ImageLayout::TRANSFER_SRC_OPTIMAL)
                        .src_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
                        .dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
                        .image(sc.images[*i as usize])
                        .subresource_range(range(sc));
                    d.cmd_pipeline_barrier(cb, src_stage, vk::PipelineStageFlags::TRANSFER, vk::DependencyFlags::empty(), &[], &[], &[b]);
                }
                record_resolves(d, cb, jobs, resolved);
                for (j, r) in jobs.iter().zip(resolved) {
                    let aspect = if is_depth(j.sc.format) { vk::ImageAspectFlags::DEPTH } else { vk::ImageAspectFlags::COLOR };
                    // The rect of its layer, or all of the resolve target made of it.
                    let (image, layer, offset) = match r {
                        Some((image, _)) => (*image, 0, vk::Offset3D::default()),
                        None => (j.sc.images[j.image_index as usize], j.layer, vk::Offset3D { x: j.rect.offset.x, y: j.rect.offset.y, z: 0 }),
                    };
                    let region = vk::BufferImageCopy {
                        buffer_offset: j.offset,
                        buffer_row_length: 0,
                        buffer_image_height: 0,
                        image_subresource: vk::ImageSubresourceLayers { aspect_mask: aspect, mip_level: 0, base_array_layer: layer, layer_count: 1 },
                        image_offset: offset,
                        image_extent: extent_of(&j.rect),
                    };
                    d.cmd_copy_image_to_buffer(cb, image, vk::ImageLayout::TRANSFER_SRC_OPTIMAL, buffer, &[region]);
                }
                for (sc, i) in &images {
                    // Back to the layout the app gets on acquire; whatever it does next waits.
                    let b = vk::ImageMemoryBarrier::default()
                        .src_access_mask(vk::AccessFlags::empty())
                        .dst_access_mask(vk::AccessFlags::MEMORY_READ | vk::AccessFlags::MEMORY_WRITE)
                        .old_layout(vk::ImageLayout::TRANSFER_SRC_OPTIMAL)
                        .new_layout(attachment_layout(sc.format))
                        .src_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
                        .dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
                        .image(sc.images[*i as usize])
                        .subresource_range(range(sc));
                    d.cmd_pipeline_barrier(cb, vk::PipelineStageFlags::TRANSFER, vk::PipelineStageFlags::ALL_COMMANDS, vk::DependencyFlags::empty(), &[], &[], &[b]);
                }
                let host = vk::BufferMemoryBarrier::default()
                    .src_access_mask(vk::AccessFlags::TRANSFER_WRITE)
                    .dst_access_mask(vk::AccessFlags::HOST_READ)
                    .src_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
                    .dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
                    .buffer(buffer)
                    .offset(0)
                    .size(vk::WHOLE_SIZE);
                d.cmd_pipeline_barrier(cb, vk::PipelineStageFlags::TRANSFER, vk::PipelineStageFlags::HOST, vk::DependencyFlags::empty(), &[], &[host], &[]);
            }
        })?;
        // SAFETY: host-visible memory, the GPU work is complete (fence waited).
        unsafe {
            let p = d.map_memory(memory, 0, vk::WHOLE_SIZE, vk::MemoryMapFlags::empty()).map_err(vk_err("vkMapMemory"))?;
            if !coherent {
                let r = vk::MappedMemoryRange::default().memory(memory).offset(0).size(vk::WHOLE_SIZE);
                d.invalidate_mapped_memory_ranges(&[r]).map_err(vk_err("vkInvalidateMappedMemoryRanges"))?;
            }
            let bytes = std::slice::from_raw_parts(p as *const u8, size as usize).to_vec();
            d.unmap_memory(memory);
            Ok(bytes)
        }
    })();
    // SAFETY: no pending GPU work uses them any more.
    unsafe {
        d.destroy_buffer(buffer, None);
        if memory != vk::DeviceMemory::null() {
            d.free_memory(memory, None);
        }
    }
    result
}

/// Resolves each multisampled job's rect (mip level 0 of its layer; the swapchain image already
/// in TRANSFER_SRC_OPTIMAL) into its resolve target and leaves that in TRANSFER_SRC_OPTIMAL for
/// the copy to the buffer.
///
/// # Safety
/// `cb` is recording, outside a render pass; every image is of `d`.
unsafe fn record_resolves(d: &ash::Device, cb: vk::CommandBuffer, jobs: &[Job], resolved: &[Option<(vk::Image, vk::DeviceMemory)>]) {
    let barrier = |image, old, new, src, dst| {
        vk::ImageMemoryBarrier::default()
            .src_access_mask(src)
            .dst_access_mask(dst)
            .old_layout(old)
            .new_layout(new)
            .src_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
            .dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
            .image(image)
            .subresource_range(vk::ImageSubresourceRange { aspect_mask: vk::ImageAspectFlags::COLOR, base_mip_level: 0, level_count: 1, base_array_layer: 0, layer_count: 1 })
    };
    type L = vk::ImageLayout;
    type A = vk::AccessFlags;
    let targets: Vec<vk::Image> = resolved.iter().flatten().map(|(i, _)| *i).collect();
    if targets.is_empty() {
        return;
    }
    let to_dst: Vec<_> = targets.iter().map(|&i| barrier(i, L::UNDEFINED, L::TRANSFER_DST_OPTIMAL, A::empty(), A::TRANSFER_WRITE)).collect();
    let to_src: Vec<_> = targets.iter().map(|&i| barrier(i, L::TRANSFER_DST_OPTIMAL, L::TRANSFER_SRC_OPTIMAL, A::TRANSFER_WRITE, A::TRANSFER_READ)).collect();
    let color = |layer| vk::ImageSubresourceLayers { aspect_mask: vk::ImageAspectFlags::COLOR, mip_level: 0, base_array_layer: layer, layer_count: 1 };
    // SAFETY: per the contract; the images are in the layouts named.
    unsafe {
        d.cmd_pipeline_barrier(cb, vk::PipelineStageFlags::TOP_OF_PIPE, vk::PipelineStageFlags::TRANSFER, vk::DependencyFlags::empty(), &[], &[], &to_dst);
        for (j, r) in jobs.iter().zip(resolved) {
            let Some((target, _)) = r else { continue };
            let region = vk::ImageResolve {
                src_subresource: color(j.layer),
                src_offset: vk::Offset3D { x: j.rect.offset.x, y: j.rect.offset.y, z: 0 },
                dst_subresource: color(0),
                dst_offset: vk::Offset3D::default(),
                extent: extent_of(&j.rect),
            };
            d.cmd_resolve_image(cb, j.sc.images[j.image_index as usize], L::TRANSFER_SRC_OPTIMAL, *target, L::TRANSFER_DST_OPTIMAL, &[region]);
        }
        d.cmd_pipeline_barrier(cb, vk::PipelineStageFlags::TRANSFER, vk::PipelineStageFlags::TRANSFER, vk::DependencyFlags::empty(), &[], &[], &to_src);
    }
}

/// The runtime's hidden-area mask of each view for this frame: the HIDDEN_TRIANGLE_MESH exactly as
/// xrGetVisibilityMaskKHR returns it now (tangent plane, CCW), expanded to 3 points per triangle;
/// `[]` for every view when XR_KHR_visibility_mask is not offered (MOCK_XR_DISABLE_EXTENSIONS).
fn visibility_masks_json(s: &Session) -> Value {
    let cfg = &s.instance.cfg;
    let offered = !cfg.disabled_extensions.contains(crate::EXT_VISIBILITY_MASK);
    let scale = visibility_mask::current_scale(s);
    let masks: Vec<Value> = (0..2)
        .map(|view| {
            let points: Vec<Value> = if offered {
                visibility_mask::hidden_triangle_points(cfg.hmd, view, scale).iter().map(|p| json!([num(p[0]), num(p[1])])).collect()
            } else {
                Vec::new()
            };
            json!({ "view": view, "hidden_triangles": points })
        })
        .collect();
    Value::Array(masks)
}

pub fn capture_frame(s: &Session, frame: u64, display_time: i64, blend: i32, layers: &[SubmittedLayer]) -> XrResult<()> {
    let cfg = &s.instance.cfg;
    let dir = cfg.capture_dir.as_ref().expect("capture only when configured");
    std::fs::create_dir_all(dir).map_err(io_err)?;
    let mut jobs = Vec::new();
    let mut size = 0u64;
    for (li, layer) in layers.iter().enumerate() {
        for (vi, v) in layer.views.iter().enumerate() {
            let push = |sc: &'_ Arc<Swapchain>, image_index: u32, rect: xr::Rect2Di, layer_ix: u32, depth: bool| {
                let bytes = rect.extent.width as u64 * rect.extent.height as u64 * texel_size(sc.format);
                (image_index, rect, layer_ix, file_name(frame, li, vi, depth), bytes)
            };
            let (i, r, l, f, b) = push(&v.swapchain, v.image_index, v.rect, v.array_index, false);
            jobs.push(Job { sc: &v.swapchain, image_index: i, rect: r, layer: l, file: f, offset: size });
            size += b.div_ceil(16) * 16;
            if let Some(dp) = &v.depth {
                let (i, r, l, f, b) = push(&dp.swapchain, dp.image_index, dp.rect, dp.array_index, true);
                jobs.push(Job { sc: &dp.swapchain, image_index: i, rect: r, layer: l, file: f, offset: size });
                size += b.div_ceil(16) * 16;
            }
        }
        if let Some(q) = &layer.quad {
            let bytes = q.rect.extent.width as u64 * q.rect.extent.height as u64 * texel_size(q.swapchain.format);
            jobs.push(Job { sc: &q.swapchain, image_index: q.image_index, rect: q.rect, layer: q.array_index, file: quad_file_name(frame, li), offset: size });
            size += bytes.div_ceil(16) * 16;
        }
    }
    if !jobs.is_empty() {
        let bytes = read_back(s, &jobs, size)?;
        for j in &jobs {
            let n = j.rect.extent.width as u64 * j.rect.extent.height as u64 * texel_size(j.sc.format);
            let png = encode_png(j.sc.format, j.rect.extent.width as u32, j.rect.extent.height as u32, &bytes[j.offset as usize..(j.offset + n) as usize]);
            write_atomic(&dir.join(&j.file), &png).map_err(io_err)?;
        }
    }
    let layers_json: Vec<Value> = layers
        .iter()
        .enumerate()
        .map(|(li, l)| {
            let views: Vec<Value> = l
                .views
                .iter()
                .enumerate()
                .map(|(vi, v)| {
                    let o = v.pose.orientation;
                    let p = v.pose.position;
                    let depth = v.depth.as_ref().map_or(Value::Null, |d| {
                        json!({
                            "swapchain": d.swapchain.handle, "format": d.swapchain.format.as_raw(),
                            "image_rect": rect_json(&d.rect), "image_array_index": d.array_index,
                            "image_index": d.image_index,
                            "min_depth": num(d.min_depth), "max_depth": num(d.max_depth),
                            "near_z": num(d.near_z), "far_z": num(d.far_z),
                            "file": file_name(frame, li, vi, true),
                        })
                    });
                    json!({
                        "view": vi,
                        "pose": { "orientation": [num(o.x), num(o.y), num(o.z), num(o.w)], "position": [num(p.x), num(p.y), num(p.z)] },
                        "fov": { "angle_left": num(v.fov.angle_left), "angle_right": num(v.fov.angle_right),
                                 "angle_up": num(v.fov.angle_up), "angle_down": num(v.fov.angle_down) },
                        "swapchain": v.swapchain.handle, "format": v.swapchain.format.as_raw(),
                        "image_rect": rect_json(&v.rect), "image_array_index": v.array_index,
                        "image_index": v.image_index, "file": file_name(frame, li, vi, false),
                        "depth": depth,
                    })
                })
                .collect();
            let quad = l.quad.as_ref().map_or(Value::Null, |q| {
                let o = q.pose.orientation;
                let p = q.pose.position;
                json!({
                    "pose": { "orientation": [num(o.x), num(o.y), num(o.z), num(o.w)], "position": [num(p.x), num(p.y), num(p.z)] },
                    "size": [num(q.size[0]), num(q.size[1])],
                    "eye_visibility": q.eye_visibility,
                    "swapchain": q.swapchain.handle, "format": q.swapchain.format.as_raw(),
                    "image_rect": rect_json(&q.rect), "image_array_index": q.array_index,
                    "image_index": q.image_index, "file": quad_file_name(frame, li),
                })
            });
            json!({ "type": l.kind, "layer_flags": l.flags, "space": l.space, "views": views, "quad": quad })
        })
        .collect();
    let masks = visibility_masks_json(s);
    let mut st = s.capture.lock().unwrap();
    st.frames.push(json!({
        "frame": frame, "display_time": display_time, "environment_blend_mode": blend, "layers": layers_json,
        "visibility_masks": masks,
    }));
    let doc = json!({ "hmd": cfg.hmd.name, "lens": cfg.hmd.lens_source, "frames": st.frames });
    let text = serde_json::to_vec_pretty(&doc).expect("json");
    write_atomic(&dir.join("frames.json"), &text).map_err(io_err)?;
    crate::log!("captured frame {frame} ({} regions)", jobs.len());
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names() {
        assert_eq!(file_name(3, 0, 1, false), "frame-00003-view-1.png");
        assert_eq!(file_name(12, 0, 0, true), "frame-00012-view-0-depth.png");
        assert_eq!(file_name(0, 2, 0, false), "frame-00000-layer-2-view-0.png");
        assert_eq!(quad_file_name(7, 1), "frame-00007-layer-1-quad.png");
    }

    fn decode(bytes: &[u8]) -> (png::ColorType, png::BitDepth, Vec<u8>) {
        let dec = png::Decoder::new(std::io::Cursor::new(bytes));
        let mut r = dec.read_info().unwrap();
        let mut buf = vec![0; r.output_buffer_size().unwrap()];
        let info = r.next_frame(&mut buf).unwrap();
        (info.color_type, info.bit_depth, buf[..info.buffer_size()].to_vec())
    }

    #[test]
    fn bgra_becomes_rgb() {
        let png = encode_png(vk::Format::B8G8R8A8_SRGB, 1, 1, &[10, 20, 30, 255]);
        let (c, d, px) = decode(&png);
        assert_eq!((c, d), (png::ColorType::Rgb, png::BitDepth::Eight));
        assert_eq!(px, vec![30, 20, 10]);
        let png = encode_png(vk::Format::R8G8B8A8_UNORM, 1, 1, &[10, 20, 30, 255]);
        assert_eq!(decode(&png).2, vec![10, 20, 30]);
    }

    #[test]
    fn depth_encodings() {
        let f = |x: f32| x.to_le_bytes();
        let texels: Vec<u8> = [f(0.0), f(0.5), f(1.0), f(2.0)].concat();
        let (c, d, px) = decode(&encode_png(vk::Format::D32_SFLOAT, 4, 1, &texels));
        assert_eq!((c, d), (png::ColorType::Grayscale, png::BitDepth::Sixteen));
        let v: Vec<u16> = px.chunks(2).map(|p| u16::from_be_bytes([p[0], p[1]])).collect();
        assert_eq!(v, vec![0, 32768, 65535, 65535]);
        let d24 = [0x00FF_FFFF_u32 | 0xAB00_0000, 0x0080_0000].iter().flat_map(|v| v.to_le_bytes()).collect::<Vec<_>>();
        let px = decode(&encode_png(vk::Format::D24_UNORM_S8_UINT, 2, 1, &d24)).2;
        let v: Vec<u16> = px.chunks(2).map(|p| u16::from_be_bytes([p[0], p[1]])).collect();
        assert_eq!(v, vec![65535, 32768]);
        let px = decode(&encode_png(vk::Format::D16_UNORM, 1, 1, &1234u16.to_le_bytes())).2;
        assert_eq!(u16::from_be_bytes([px[0], px[1]]), 1234);
    }
}
