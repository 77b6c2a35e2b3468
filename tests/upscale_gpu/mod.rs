//! A minimal Vulkan compute harness for the upscale's passes (`features::upscale::gpu`): one
//! device, the input uploaded as RGBA32F, EASU into an RGBA16F image, RCAS into another, read
//! back, with the device's timestamps around each pass; the tile classes of
//! `upscale.skip_hidden` in a storage buffer. Used by tests/features/upscale_filters.rs (against
//! the CPU reference) and examples/upscale_bench.rs (their GPU time at a headset's size).

use ash::vk;
use stereoshim::features::upscale::filter::Image;
use stereoshim::features::upscale::gpu;

/// The two passes' SPIR-V and their workgroup's side (the product's, or variants a benchmark
/// compares with the same interface).
#[derive(Clone, Copy)]
pub struct Shaders<'a> {
    pub easu: &'a [u8],
    pub rcas: &'a [u8],
    pub group: u32,
    /// The input image's format: R32G32B32A32_SFLOAT (exact, for the comparison with the CPU
    /// reference) or R8G8B8A8_UNORM (what apps render).
    pub input: vk::Format,
    /// Per workgroup of the output, row by row, the passes that skip it (`lens` classes): each
    /// pass then runs the list of the others, over outputs cleared black; empty: none skipped.
    pub tiles: &'a [u32],
}

impl Shaders<'static> {
    /// The layer's own passes.
    pub fn product() -> Shaders<'static> {
        Shaders { easu: gpu::EASU, rcas: gpu::RCAS, group: gpu::GROUP, input: vk::Format::R32G32B32A32_SFLOAT, tiles: &[] }
    }
}

/// What a run gives back: the result's texels (RGBA) and the passes' GPU times in ms (EASU,
/// RCAS), when the queue has timestamps.
pub struct Upscaled {
    pub texels: Vec<[f32; 4]>,
    pub times_ms: Option<(f64, f64)>,
}

fn f16_to_f32(h: u16) -> f32 {
    let (s, e, m) = (((h >> 15) & 1) as u32, ((h >> 10) & 0x1f) as u32, (h & 0x3ff) as u32);
    let bits = match (e, m) {
        (0, 0) => s << 31,
        (0, _) => {
            // Subnormal: normalize.
            let (mut e, mut m) = (127 - 15 + 1, m);
            while m & 0x400 == 0 {
                m <<= 1;
                e -= 1;
            }
            (s << 31) | (e << 23) | ((m & 0x3ff) << 13)
        }
        (31, _) => (s << 31) | 0x7f80_0000 | (m << 13),
        _ => (s << 31) | ((e + 127 - 15) << 23) | (m << 13),
    };
    f32::from_bits(bits)
}

/// A buffer or image with its memory.
struct Allocation {
    memory: vk::DeviceMemory,
}

pub struct Gpu {
    _entry: ash::Entry,
    instance: ash::Instance,
    device: ash::Device,
    queue: vk::Queue,
    family: u32,
    memory: vk::PhysicalDeviceMemoryProperties,
    /// Nanoseconds per timestamp tick, when the queue has timestamps.
    timestamp_ns: Option<f64>,
}

impl Gpu {
    pub fn new() -> Gpu {
        // SAFETY: the system's Vulkan loader; every create info below is valid, and the objects
        // are destroyed in `Drop` after the device is idle.
        unsafe {
            let entry = ash::Entry::load().expect("a Vulkan loader");
            let app = vk::ApplicationInfo::default().api_version(vk::API_VERSION_1_0);
            let instance = entry.create_instance(&vk::InstanceCreateInfo::default().application_info(&app), None).expect("vkCreateInstance");
            let pd = instance.enumerate_physical_devices().expect("physical devices")[0];
            let families = instance.get_physical_device_queue_family_properties(pd);
            let family = families.iter().position(|q| q.queue_flags.contains(vk::QueueFlags::COMPUTE)).expect("a compute queue") as u32;
            let props = instance.get_physical_device_properties(pd);
            let timestamp_ns = (families[family as usize].timestamp_valid_bits > 0).then_some(props.limits.timestamp_period as f64);
            let prio = [1.0];
            let queues = [vk::DeviceQueueCreateInfo::default().queue_family_index(family).queue_priorities(&prio)];
            let device = instance.create_device(pd, &vk::DeviceCreateInfo::default().queue_create_infos(&queues), None).expect("vkCreateDevice");
            let queue = device.get_device_queue(family, 0);
            let memory = instance.get_physical_device_memory_properties(pd);
            Gpu { _entry: entry, instance, device, queue, family, memory, timestamp_ns }
        }
    }

    fn memory_type(&self, bits: u32, flags: vk::MemoryPropertyFlags) -> u32 {
        (0..self.memory.memory_type_count).find(|&i| bits & (1 << i) != 0 && self.memory.memory_types[i as usize].property_flags.contains(flags)).expect("a memory type")
    }

    /// A host-visible buffer of `size` bytes.
    fn buffer(&self, size: u64, usage: vk::BufferUsageFlags) -> (vk::Buffer, Allocation) {
        // SAFETY: valid create / allocate infos on our device.
        unsafe {
            let b = self.device.create_buffer(&vk::BufferCreateInfo::default().size(size).usage(usage), None).unwrap();
            let req = self.device.get_buffer_memory_requirements(b);
            let t = self.memory_type(req.memory_type_bits, vk::MemoryPropertyFlags::HOST_VISIBLE | vk::MemoryPropertyFlags::HOST_COHERENT);
            let memory = self.device.allocate_memory(&vk::MemoryAllocateInfo::default().allocation_size(req.size).memory_type_index(t), None).unwrap();
            self.device.bind_buffer_memory(b, memory, 0).unwrap();
            (b, Allocation { memory })
        }
    }

    /// A 2D image and its view.
    fn image(&self, format: vk::Format, (w, h): (u32, u32), usage: vk::ImageUsageFlags) -> (vk::Image, vk::ImageView, Allocation) {
        // SAFETY: valid create / allocate infos on our device.
        unsafe {
            let info = vk::ImageCreateInfo::default()
                .image_type(vk::ImageType::TYPE_2D)
                .format(format)
                .extent(vk::Extent3D { width: w, height: h, depth: 1 })
                .mip_levels(1)
                .array_layers(1)
                .samples(vk::SampleCountFlags::TYPE_1)
                .usage(usage);
            let i = self.device.create_image(&info, None).unwrap();
            let req = self.device.get_image_memory_requirements(i);
            // Device-local where there is such memory (a discrete GPU's first type may be the
            // host's, which would time the bus, not the passes).
            let local = (0..self.memory.memory_type_count).find(|&i| req.memory_type_bits & (1 << i) != 0 && self.memory.memory_types[i as usize].property_flags.contains(vk::MemoryPropertyFlags::DEVICE_LOCAL));
            let t = local.unwrap_or_else(|| self.memory_type(req.memory_type_bits, vk::MemoryPropertyFlags::empty()));
            let memory = self.device.allocate_memory(&vk::MemoryAllocateInfo::default().allocation_size(req.size).memory_type_index(t), None).unwrap();
            self.device.bind_image_memory(i, memory, 0).unwrap();
            let range = vk::ImageSubresourceRange { aspect_mask: vk::ImageAspectFlags::COLOR, base_mip_level: 0, level_count: 1, base_array_layer: 0, layer_count: 1 };
            let view = self.device.create_image_view(&vk::ImageViewCreateInfo::default().image(i).view_type(vk::ImageViewType::TYPE_2D).format(format).subresource_range(range), None).unwrap();
            (i, view, Allocation { memory })
        }
    }

    fn pipeline(&self, spirv: &[u8], layout: vk::PipelineLayout) -> vk::Pipeline {
        let code = ash::util::read_spv(&mut std::io::Cursor::new(spirv)).unwrap();
        // SAFETY: valid SPIR-V compiled at build time; our layout.
        unsafe {
            let module = self.device.create_shader_module(&vk::ShaderModuleCreateInfo::default().code(&code), None).unwrap();
            let stage = vk::PipelineShaderStageCreateInfo::default().stage(vk::ShaderStageFlags::COMPUTE).module(module).name(c"main");
            let p = self.device.create_compute_pipelines(vk::PipelineCache::null(), &[vk::ComputePipelineCreateInfo::default().stage(stage).layout(layout)], None).unwrap()[0];
            self.device.destroy_shader_module(module, None);
            p
        }
    }

    /// EASU of `src` to `w`×`h`, then RCAS with `sharpness`, on the device (`shaders`: the
    /// layer's passes or variants): the result's texels, and each pass's GPU time, the mean of
    /// `repeat` back-to-back runs in one submission (a single run on an idle GPU also times its
    /// clocks ramping up).
    pub fn upscale_with(&self, shaders: Shaders<'_>, src: &Image, (w, h): (u32, u32), sharpness: f32, repeat: u32) -> Upscaled {
        let repeat = repeat.max(1);
        let d = &self.device;
        let fmt_in = shaders.input;
        let fmt = vk::Format::R16G16B16A16_SFLOAT;
        let texels: Vec<u8> = match fmt_in {
            vk::Format::R8G8B8A8_UNORM => src.texels.iter().flat_map(|t| [t.0[0], t.0[1], t.0[2], 1.0].map(|c| (c.clamp(0.0, 1.0) * 255.0).round() as u8)).collect(),
            _ => src.texels.iter().flat_map(|t| [t.0[0], t.0[1], t.0[2], 1.0]).flat_map(f32::to_ne_bytes).collect(),
        };
        let (staging, staging_mem) = self.buffer(texels.len() as u64, vk::BufferUsageFlags::TRANSFER_SRC);
        let (readback, readback_mem) = self.buffer(w as u64 * h as u64 * 8, vk::BufferUsageFlags::TRANSFER_DST);
        let (input, input_view, input_mem) = self.image(fmt_in, (src.width, src.height), vk::ImageUsageFlags::SAMPLED | vk::ImageUsageFlags::TRANSFER_DST);
        let (temp, temp_view, temp_mem) = self.image(fmt, (w, h), vk::ImageUsageFlags::SAMPLED | vk::ImageUsageFlags::STORAGE | vk::ImageUsageFlags::TRANSFER_DST);
        let (out, out_view, out_mem) = self.image(fmt, (w, h), vk::ImageUsageFlags::STORAGE | vk::ImageUsageFlags::TRANSFER_SRC | vk::ImageUsageFlags::TRANSFER_DST);
        let range = vk::ImageSubresourceRange { aspect_mask: vk::ImageAspectFlags::COLOR, base_mip_level: 0, level_count: 1, base_array_layer: 0, layer_count: 1 };
        let layers = vk::ImageSubresourceLayers { aspect_mask: vk::ImageAspectFlags::COLOR, mip_level: 0, base_array_layer: 0, layer_count: 1 };
        let barrier = |image, (old, new), (src, dst)| {
            vk::ImageMemoryBarrier::default()
                .image(image)
                .old_layout(old)
                .new_layout(new)
                .src_access_mask(src)
                .dst_access_mask(dst)
                .src_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
                .dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
                .subresource_range(range)
        };
        // SAFETY: every object is ours and alive until the end of this function, where the
        // device is idle before anything is destroyed; arrays outlive the calls.
        unsafe {
            let p = d.map_memory(staging_mem.memory, 0, vk::WHOLE_SIZE, vk::MemoryMapFlags::empty()).unwrap() as *mut u8;
            std::ptr::copy_nonoverlapping(texels.as_ptr(), p, texels.len());
            d.unmap_memory(staging_mem.memory);
            let sampler = d
                .create_sampler(
                    &vk::SamplerCreateInfo::default()
                        .mag_filter(vk::Filter::NEAREST)
                        .min_filter(vk::Filter::NEAREST)
                        .address_mode_u(vk::SamplerAddressMode::CLAMP_TO_EDGE)
                        .address_mode_v(vk::SamplerAddressMode::CLAMP_TO_EDGE),
                    None,
                )
                .unwrap();
            let bindings = [
                vk::DescriptorSetLayoutBinding::default().binding(0).descriptor_type(vk::DescriptorType::COMBINED_IMAGE_SAMPLER).descriptor_count(1).stage_flags(vk::ShaderStageFlags::COMPUTE),
                vk::DescriptorSetLayoutBinding::default().binding(1).descriptor_type(vk::DescriptorType::STORAGE_IMAGE).descriptor_count(1).stage_flags(vk::ShaderStageFlags::COMPUTE),
                vk::DescriptorSetLayoutBinding::default().binding(2).descriptor_type(vk::DescriptorType::STORAGE_BUFFER).descriptor_count(1).stage_flags(vk::ShaderStageFlags::COMPUTE),
            ];
            // The lists as the layer makes them (`lens::classify`): x | y << 16 of each tile a pass
            // runs, EASU's then RCAS's.
            let cols = w.div_ceil(shaders.group) as usize;
            let list = |skips: u32| -> Vec<u32> { shaders.tiles.iter().enumerate().filter(|(_, &c)| c & skips == 0).map(|(i, _)| (i % cols) as u32 | ((i / cols) as u32) << 16).collect() };
            let (easu_list, rcas_list) = (list(2), list(1));
            let lists = [easu_list.clone(), rcas_list.clone()].concat();
            let (tiles, tiles_mem) = self.buffer(4 * lists.len().max(1) as u64, vk::BufferUsageFlags::STORAGE_BUFFER);
            let t = d.map_memory(tiles_mem.memory, 0, vk::WHOLE_SIZE, vk::MemoryMapFlags::empty()).unwrap() as *mut u32;
            std::ptr::copy_nonoverlapping(lists.as_ptr(), t, lists.len());
            d.unmap_memory(tiles_mem.memory);
            let listed = !shaders.tiles.is_empty();
            let (easu_skip, rcas_skip) = if listed { ([0, 1, 0, 0], [easu_list.len() as i32, 1, 0, 0]) } else { ([0; 4], [0; 4]) };
            let set_layout = d.create_descriptor_set_layout(&vk::DescriptorSetLayoutCreateInfo::default().bindings(&bindings), None).unwrap();
            let ranges = [vk::PushConstantRange { stage_flags: vk::ShaderStageFlags::COMPUTE, offset: 0, size: gpu::PUSH_BYTES }];
            let set_layouts = [set_layout];
            let layout = d.create_pipeline_layout(&vk::PipelineLayoutCreateInfo::default().set_layouts(&set_layouts).push_constant_ranges(&ranges), None).unwrap();
            let (easu, rcas) = (self.pipeline(shaders.easu, layout), self.pipeline(shaders.rcas, layout));
            let sizes = [
                vk::DescriptorPoolSize { ty: vk::DescriptorType::COMBINED_IMAGE_SAMPLER, descriptor_count: 2 },
                vk::DescriptorPoolSize { ty: vk::DescriptorType::STORAGE_IMAGE, descriptor_count: 2 },
                vk::DescriptorPoolSize { ty: vk::DescriptorType::STORAGE_BUFFER, descriptor_count: 2 },
            ];
            let pool = d.create_descriptor_pool(&vk::DescriptorPoolCreateInfo::default().max_sets(2).pool_sizes(&sizes), None).unwrap();
            let sets = d.allocate_descriptor_sets(&vk::DescriptorSetAllocateInfo::default().descriptor_pool(pool).set_layouts(&[set_layout, set_layout])).unwrap();
            for (set, (from, to)) in sets.iter().zip([(input_view, temp_view), (temp_view, out_view)]) {
                let sampled = [vk::DescriptorImageInfo { sampler, image_view: from, image_layout: vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL }];
                let storage = [vk::DescriptorImageInfo { sampler: vk::Sampler::null(), image_view: to, image_layout: vk::ImageLayout::GENERAL }];
                let table = [vk::DescriptorBufferInfo { buffer: tiles, offset: 0, range: vk::WHOLE_SIZE }];
                let writes = [
                    vk::WriteDescriptorSet::default().dst_set(*set).dst_binding(0).descriptor_type(vk::DescriptorType::COMBINED_IMAGE_SAMPLER).image_info(&sampled),
                    vk::WriteDescriptorSet::default().dst_set(*set).dst_binding(1).descriptor_type(vk::DescriptorType::STORAGE_IMAGE).image_info(&storage),
                    vk::WriteDescriptorSet::default().dst_set(*set).dst_binding(2).descriptor_type(vk::DescriptorType::STORAGE_BUFFER).buffer_info(&table),
                ];
                d.update_descriptor_sets(&writes, &[]);
            }
            let cmd_pool = d.create_command_pool(&vk::CommandPoolCreateInfo::default().queue_family_index(self.family), None).unwrap();
            let cb = d.allocate_command_buffers(&vk::CommandBufferAllocateInfo::default().command_pool(cmd_pool).command_buffer_count(1)).unwrap()[0];
            let queries = d.create_query_pool(&vk::QueryPoolCreateInfo::default().query_type(vk::QueryType::TIMESTAMP).query_count(3), None).unwrap();
            d.begin_command_buffer(cb, &vk::CommandBufferBeginInfo::default()).unwrap();
            d.cmd_reset_query_pool(cb, queries, 0, 3);
            let (none, tw, tr, sw, sr) = (vk::AccessFlags::empty(), vk::AccessFlags::TRANSFER_WRITE, vk::AccessFlags::TRANSFER_READ, vk::AccessFlags::SHADER_WRITE, vk::AccessFlags::SHADER_READ);
            let (top, xfer, cs) = (vk::PipelineStageFlags::TOP_OF_PIPE, vk::PipelineStageFlags::TRANSFER, vk::PipelineStageFlags::COMPUTE_SHADER);
            d.cmd_pipeline_barrier(cb, top, xfer, vk::DependencyFlags::empty(), &[], &[], &[barrier(input, (vk::ImageLayout::UNDEFINED, vk::ImageLayout::TRANSFER_DST_OPTIMAL), (none, tw))]);
            let region = vk::BufferImageCopy { buffer_offset: 0, buffer_row_length: 0, buffer_image_height: 0, image_subresource: layers, image_offset: vk::Offset3D::default(), image_extent: vk::Extent3D { width: src.width, height: src.height, depth: 1 } };
            d.cmd_copy_buffer_to_image(cb, staging, input, vk::ImageLayout::TRANSFER_DST_OPTIMAL, &[region]);
            // Both outputs black first, as the layer clears its intermediates: the tiles a list
            // leaves out stay so.
            let to_clear = [barrier(temp, (vk::ImageLayout::UNDEFINED, vk::ImageLayout::TRANSFER_DST_OPTIMAL), (none, tw)), barrier(out, (vk::ImageLayout::UNDEFINED, vk::ImageLayout::TRANSFER_DST_OPTIMAL), (none, tw))];
            d.cmd_pipeline_barrier(cb, top, xfer, vk::DependencyFlags::empty(), &[], &[], &to_clear);
            for image in [temp, out] {
                d.cmd_clear_color_image(cb, image, vk::ImageLayout::TRANSFER_DST_OPTIMAL, &vk::ClearColorValue { float32: [0.0, 0.0, 0.0, 1.0] }, &[range]);
            }
            let to_run = [
                barrier(input, (vk::ImageLayout::TRANSFER_DST_OPTIMAL, vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL), (tw, sr)),
                barrier(temp, (vk::ImageLayout::TRANSFER_DST_OPTIMAL, vk::ImageLayout::GENERAL), (tw, sw)),
                barrier(out, (vk::ImageLayout::TRANSFER_DST_OPTIMAL, vk::ImageLayout::GENERAL), (tw, sw)),
            ];
            d.cmd_pipeline_barrier(cb, xfer, cs, vk::DependencyFlags::empty(), &[], &[], &to_run);
            let whole = (w.div_ceil(shaders.group), h.div_ceil(shaders.group));
            let (easu_groups, rcas_groups) = if listed { ((easu_list.len() as u32, 1), (rcas_list.len() as u32, 1)) } else { (whole, whole) };
            d.cmd_write_timestamp(cb, cs, queries, 0);
            d.cmd_bind_pipeline(cb, vk::PipelineBindPoint::COMPUTE, easu);
            d.cmd_bind_descriptor_sets(cb, vk::PipelineBindPoint::COMPUTE, layout, 0, &sets[..1], &[]);
            let ep = gpu::EasuParams { src_rect: [0, 0, src.width as i32, src.height as i32], dst_rect: [0, 0, w as i32, h as i32], skip: easu_skip, ..Default::default() };
            d.cmd_push_constants(cb, layout, vk::ShaderStageFlags::COMPUTE, 0, &ep.bytes());
            for k in 0..repeat {
                if k > 0 {
                    d.cmd_pipeline_barrier(cb, cs, cs, vk::DependencyFlags::empty(), &[], &[], &[barrier(temp, (vk::ImageLayout::GENERAL, vk::ImageLayout::GENERAL), (sw, sw))]);
                }
                d.cmd_dispatch(cb, easu_groups.0, easu_groups.1, 1);
            }
            d.cmd_pipeline_barrier(cb, cs, cs, vk::DependencyFlags::empty(), &[], &[], &[barrier(temp, (vk::ImageLayout::GENERAL, vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL), (sw, sr))]);
            d.cmd_write_timestamp(cb, cs, queries, 1);
            d.cmd_bind_pipeline(cb, vk::PipelineBindPoint::COMPUTE, rcas);
            d.cmd_bind_descriptor_sets(cb, vk::PipelineBindPoint::COMPUTE, layout, 0, &sets[1..], &[]);
            let rp = gpu::RcasParams { rect: [0, 0, w as i32, h as i32], sharpness: [sharpness, 0.0, 0.0, 0.0], skip: rcas_skip, ..Default::default() };
            d.cmd_push_constants(cb, layout, vk::ShaderStageFlags::COMPUTE, 0, &rp.bytes());
            for k in 0..repeat {
                if k > 0 {
                    d.cmd_pipeline_barrier(cb, cs, cs, vk::DependencyFlags::empty(), &[], &[], &[barrier(out, (vk::ImageLayout::GENERAL, vk::ImageLayout::GENERAL), (sw, sw))]);
                }
                d.cmd_dispatch(cb, rcas_groups.0, rcas_groups.1, 1);
            }
            d.cmd_write_timestamp(cb, cs, queries, 2);
            d.cmd_pipeline_barrier(cb, cs, xfer, vk::DependencyFlags::empty(), &[], &[], &[barrier(out, (vk::ImageLayout::GENERAL, vk::ImageLayout::TRANSFER_SRC_OPTIMAL), (sw, tr))]);
            let back = vk::BufferImageCopy { image_extent: vk::Extent3D { width: w, height: h, depth: 1 }, ..region };
            d.cmd_copy_image_to_buffer(cb, out, vk::ImageLayout::TRANSFER_SRC_OPTIMAL, readback, &[back]);
            d.end_command_buffer(cb).unwrap();
            let cbs = [cb];
            d.queue_submit(self.queue, &[vk::SubmitInfo::default().command_buffers(&cbs)], vk::Fence::null()).unwrap();
            d.device_wait_idle().unwrap();
            let p = d.map_memory(readback_mem.memory, 0, vk::WHOLE_SIZE, vk::MemoryMapFlags::empty()).unwrap() as *const u16;
            let halves = std::slice::from_raw_parts(p, (w * h * 4) as usize).to_vec();
            d.unmap_memory(readback_mem.memory);
            let mut stamps = [0u64; 3];
            let times_ms = match self.timestamp_ns {
                Some(ns) if d.get_query_pool_results(queries, 0, &mut stamps, vk::QueryResultFlags::TYPE_64 | vk::QueryResultFlags::WAIT).is_ok() => {
                    let ms = |a: u64, b: u64| b.saturating_sub(a) as f64 * ns / 1e6 / repeat as f64;
                    Some((ms(stamps[0], stamps[1]), ms(stamps[1], stamps[2])))
                }
                _ => None,
            };
            d.destroy_query_pool(queries, None);
            d.destroy_command_pool(cmd_pool, None);
            d.destroy_descriptor_pool(pool, None);
            d.destroy_pipeline(easu, None);
            d.destroy_pipeline(rcas, None);
            d.destroy_pipeline_layout(layout, None);
            d.destroy_descriptor_set_layout(set_layout, None);
            d.destroy_sampler(sampler, None);
            for (view, image) in [(input_view, input), (temp_view, temp), (out_view, out)] {
                d.destroy_image_view(view, None);
                d.destroy_image(image, None);
            }
            for b in [staging, readback, tiles] {
                d.destroy_buffer(b, None);
            }
            for m in [staging_mem, readback_mem, tiles_mem, input_mem, temp_mem, out_mem] {
                d.free_memory(m.memory, None);
            }
            let texels = halves.chunks_exact(4).map(|c| [f16_to_f32(c[0]), f16_to_f32(c[1]), f16_to_f32(c[2]), f16_to_f32(c[3])]).collect();
            Upscaled { texels, times_ms }
        }
    }
}

impl Drop for Gpu {
    fn drop(&mut self) {
        // SAFETY: every object made from the device was destroyed; nothing is pending.
        unsafe {
            self.device.destroy_device(None);
            self.instance.destroy_instance(None);
        }
    }
}

