//! The upscale's Vulkan work on the session's device. Two levels of the chain are used, for two
//! kinds of object: what the app sees (the images `xrEnumerateSwapchainImages` hands it, their
//! memory, their first layout) is made through the app's own level (`top`: the Vulkan loader's
//! entry points, as a runtime makes its swapchain images), so every layer above this one knows
//! them; the layer's own objects (pipelines, intermediates, views, descriptors, command buffers)
//! through the layer's counted table below it (`DeviceState::fns`), as every feature's.
//!
//! Per interposed swapchain (`Target`): the app's images and a view per array layer (with a
//! multisampled swapchain, also one single-sample image the frame's samples are resolved into,
//! which the upscale reads), an RGBA16F intermediate of the runtime image's size (EASU's output),
//! where `Output::Copy` applies an image of texels in the runtime image's encoding (RCAS's output,
//! copied into the runtime's image), the descriptor sets (written once: nothing is updated per
//! frame), and for `Output::Fragment` per runtime image and layer a framebuffer. `record` records
//! a frame's upscale; `slots` holds the command buffers. The app's images come back in the layout
//! the OpenXR Vulkan binding names; the runtime's are left in it.

use super::gpu;
use super::lens::Tiles;
use super::Method;
use std::sync::Arc;
use crate::core::rect::PixelRect;
use crate::plugin::vk::DeviceState;
use ash::vk;

/// How a frame finds a target's intermediates (`Target::record_tile_uploads`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct Prep {
    /// In the layouts the last upscale left them in (else UNDEFINED).
    pub defined: bool,
    /// To be cleared black before the passes (they run tile lists, and the tiles outside them
    /// may hold pixels).
    pub clear: bool,
}

/// Tile-class slots per array layer: a layer holds one view, or two side by side.
const TILE_SLOTS_PER_LAYER: u32 = 2;

/// The intermediates' format: what EASU and RCAS store (`rgba16f` in the shaders).
const INTERMEDIATE: vk::Format = vk::Format::R16G16B16A16_SFLOAT;

fn err(what: &'static str) -> impl Fn(vk::Result) -> String {
    move |e| format!("{what}: {e}")
}

/// One view's upscale: `src` of the app image's `layer` becomes `dst` of the runtime image's.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Job {
    pub layer: u32,
    pub src: PixelRect,
    pub dst: PixelRect,
}

/// The pipelines of a session's device: one set layout (the sampled source, the storage
/// destination) and 32 bytes of push constants for every pass; EASU's compute pipeline (the
/// fragment passes' pipelines depend on the runtime image's format: `Target`).
pub(crate) struct Pipelines {
    pub(super) set_layout: vk::DescriptorSetLayout,
    pub(super) layout: vk::PipelineLayout,
    pub(super) easu: vk::Pipeline,
    pub(super) cas: vk::Pipeline,
    /// RCAS as compute, into RGBA16F or into 8-bit texels (`Output::Copy`).
    pub(super) rcas16: vk::Pipeline,
    pub(super) rcas8: vk::Pipeline,
    pub(super) sampler: vk::Sampler,
}

/// How the upscaled pixels reach the runtime's image.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Output {
    /// RCAS (compute) writes texels in the runtime image's own encoding into an image of
    /// `inter`, copied bit for bit into the runtime's (its usage needs TRANSFER_DST): all compute
    /// and copies, no graphics work (on an H100, whose graphics units are few, a fragment pass
    /// over two Index eyes took 1.2 ms, this 0.28). For 8-bit RGBA/BGRA (sRGB or not) and RGBA16F.
    Copy { inter: vk::Format, srgb: bool, swap_rb: bool },
    /// A fragment pass draws the runtime's image as a colour attachment (RCAS, or the bilinear
    /// filter): any colour-attachment format, no transition of the runtime's image.
    Fragment,
}

impl Output {
    /// The output for a runtime image of `format` (either method: the bilinear one runs as EASU's
    /// pass in its bilinear mode, then RCAS at sharpness 0 encodes).
    pub(crate) fn of(format: vk::Format) -> Output {
        use vk::Format as F;
        match format {
            F::R8G8B8A8_UNORM => Output::Copy { inter: F::R8G8B8A8_UNORM, srgb: false, swap_rb: false },
            F::R8G8B8A8_SRGB => Output::Copy { inter: F::R8G8B8A8_UNORM, srgb: true, swap_rb: false },
            F::B8G8R8A8_UNORM => Output::Copy { inter: F::R8G8B8A8_UNORM, srgb: false, swap_rb: true },
            F::B8G8R8A8_SRGB => Output::Copy { inter: F::R8G8B8A8_UNORM, srgb: true, swap_rb: true },
            F::R16G16B16A16_SFLOAT => Output::Copy { inter: F::R16G16B16A16_SFLOAT, srgb: false, swap_rb: false },
            _ => Output::Fragment,
        }
    }
}

/// The stages every push reaches (one range for all passes).
pub(super) const PUSH_STAGES: vk::ShaderStageFlags = vk::ShaderStageFlags::from_raw(vk::ShaderStageFlags::COMPUTE.as_raw() | vk::ShaderStageFlags::FRAGMENT.as_raw());

impl Pipelines {
    pub(crate) fn new(d: &DeviceState) -> Result<Pipelines, String> {
        let mut p = Pipelines {
            set_layout: vk::DescriptorSetLayout::null(),
            layout: vk::PipelineLayout::null(),
            easu: vk::Pipeline::null(),
            cas: vk::Pipeline::null(),
            rcas16: vk::Pipeline::null(),
            rcas8: vk::Pipeline::null(),
            sampler: vk::Sampler::null(),
        };
        // SAFETY: valid create infos on a live device through the layer's counted table; what was
        // made before a failure is destroyed by `destroy`, which skips null handles.
        let made = unsafe { p.make(d) };
        if let Err(e) = made {
            p.destroy(d);
            return Err(e);
        }
        Ok(p)
    }

    unsafe fn make(&mut self, d: &DeviceState) -> Result<(), String> {
        let bindings = [
            vk::DescriptorSetLayoutBinding::default().binding(0).descriptor_type(vk::DescriptorType::COMBINED_IMAGE_SAMPLER).descriptor_count(1).stage_flags(PUSH_STAGES),
            vk::DescriptorSetLayoutBinding::default().binding(1).descriptor_type(vk::DescriptorType::STORAGE_IMAGE).descriptor_count(1).stage_flags(vk::ShaderStageFlags::COMPUTE),
            vk::DescriptorSetLayoutBinding::default().binding(2).descriptor_type(vk::DescriptorType::STORAGE_BUFFER).descriptor_count(1).stage_flags(vk::ShaderStageFlags::COMPUTE),
        ];
        // SAFETY: per `new`'s contract.
        unsafe {
            self.set_layout = d.fns.create_descriptor_set_layout(&vk::DescriptorSetLayoutCreateInfo::default().bindings(&bindings), None).map_err(err("vkCreateDescriptorSetLayout"))?;
            let push = [vk::PushConstantRange { stage_flags: PUSH_STAGES, offset: 0, size: gpu::PUSH_BYTES }];
            let layouts = [self.set_layout];
            self.layout = d.fns.create_pipeline_layout(&vk::PipelineLayoutCreateInfo::default().set_layouts(&layouts).push_constant_ranges(&push), None).map_err(err("vkCreatePipelineLayout"))?;
            self.easu = compute_pipeline(d, self.layout, gpu::EASU)?;
            self.cas = compute_pipeline(d, self.layout, gpu::CAS)?;
            self.rcas16 = compute_pipeline(d, self.layout, gpu::RCAS)?;
            self.rcas8 = compute_pipeline(d, self.layout, gpu::RCAS_RGBA8)?;
            // Linear for the bilinear pass; EASU and RCAS fetch texels and ignore the filter.
            let sci = vk::SamplerCreateInfo::default()
                .mag_filter(vk::Filter::LINEAR)
                .min_filter(vk::Filter::LINEAR)
                .address_mode_u(vk::SamplerAddressMode::CLAMP_TO_EDGE)
                .address_mode_v(vk::SamplerAddressMode::CLAMP_TO_EDGE)
                .address_mode_w(vk::SamplerAddressMode::CLAMP_TO_EDGE);
            self.sampler = d.fns.create_sampler(&sci, None).map_err(err("vkCreateSampler"))?;
        }
        Ok(())
    }

    /// At the session's end (its upscales are complete).
    pub(crate) fn destroy(&self, d: &DeviceState) {
        // SAFETY: the layer's own objects, no longer used by the GPU (the caller waited); null
        // handles are skipped.
        unsafe {
            for p in [self.easu, self.cas, self.rcas16, self.rcas8] {
                if p != vk::Pipeline::null() {
                    d.fns.destroy_pipeline(p, None);
                }
            }
            if self.layout != vk::PipelineLayout::null() {
                d.fns.destroy_pipeline_layout(self.layout, None);
            }
            if self.set_layout != vk::DescriptorSetLayout::null() {
                d.fns.destroy_descriptor_set_layout(self.set_layout, None);
            }
            if self.sampler != vk::Sampler::null() {
                d.fns.destroy_sampler(self.sampler, None);
            }
        }
    }
}

/// # Safety
/// `spirv` is valid SPIR-V (built by build.rs).
unsafe fn module(d: &DeviceState, spirv: &[u8]) -> Result<vk::ShaderModule, String> {
    let code: Vec<u32> = spirv.chunks_exact(4).map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect();
    // SAFETY: per the contract.
    unsafe { d.fns.create_shader_module(&vk::ShaderModuleCreateInfo::default().code(&code), None) }.map_err(err("vkCreateShaderModule"))
}

/// # Safety
/// `layout` is a live pipeline layout of `d`.
unsafe fn compute_pipeline(d: &DeviceState, layout: vk::PipelineLayout, spirv: &[u8]) -> Result<vk::Pipeline, String> {
    // SAFETY: valid SPIR-V built by build.rs; the module is destroyed once the pipeline exists.
    unsafe {
        let module = module(d, spirv)?;
        let stage = vk::PipelineShaderStageCreateInfo::default().stage(vk::ShaderStageFlags::COMPUTE).module(module).name(c"main");
        let ci = vk::ComputePipelineCreateInfo::default().stage(stage).layout(layout);
        let r = d.fns.create_compute_pipelines(vk::PipelineCache::null(), &[ci], None);
        d.fns.destroy_shader_module(module, None);
        r.map(|v| v[0]).map_err(|(_, e)| format!("vkCreateComputePipelines: {e}"))
    }
}

/// What the interposition of one swapchain needs from the format: a sampled source (filtered, for
/// bilinear) and a colour attachment for the runtime's image. None: it can; Some: why not.
pub(crate) fn format_refusal(props: vk::FormatProperties, method: Method) -> Option<String> {
    let have = props.optimal_tiling_features;
    let need_src = match method {
        Method::EasuRcas | Method::Cas => vk::FormatFeatureFlags::SAMPLED_IMAGE,
        Method::Bilinear => vk::FormatFeatureFlags::SAMPLED_IMAGE | vk::FormatFeatureFlags::SAMPLED_IMAGE_FILTER_LINEAR,
    };
    let need = need_src | vk::FormatFeatureFlags::COLOR_ATTACHMENT;
    (!have.contains(need)).then(|| format!("the format's optimal-tiling features {have:?} lack {:?}", need & !have))
}

/// An image the app renders into: its handle as the app (`top`) and as this layer (`ours`) name
/// it, its memory, and a 2D view of mip 0 per array layer.
pub(crate) struct AppImage {
    pub top: vk::Image,
    pub ours: vk::Image,
    memory: vk::DeviceMemory,
    views: Vec<vk::ImageView>,
}

/// What `Target::new` needs to know about the app's swapchain.
pub(crate) struct TargetDesc {
    pub format: vk::Format,
    pub extent: (u32, u32),
    pub layers: u32,
    pub mips: u32,
    /// Samples per pixel of the app's images (1: single-sampled). The runtime's are single-sampled.
    pub samples: u32,
    /// The app's usage as Vulkan usage (the layer adds what the upscale reads with).
    pub usage: vk::ImageUsageFlags,
    pub mutable_format: bool,
    pub runtime_extent: (u32, u32),
    pub runtime_images: Vec<vk::Image>,
    /// The method the passes are built for, and how they reach the runtime's image.
    pub method: Method,
    pub output: Output,
}

/// One interposed swapchain's objects.
pub(crate) struct Target {
    pub desc: TargetDesc,
    pub app: Vec<AppImage>,
    /// EASU's output: image, memory, a view per layer.
    pub(super) a: (vk::Image, vk::DeviceMemory, Vec<vk::ImageView>),
    /// RCAS's output, copied into the runtime's image (`Output::Copy`).
    pub(super) b: (vk::Image, vk::DeviceMemory, Vec<vk::ImageView>),
    /// The tile classes of `upscale.skip_hidden` (`lens`), in device memory (every workgroup reads
    /// its entry: host memory across the bus cost more than the skipping saved, on an H100):
    /// `TILE_SLOTS_PER_LAYER` slots per array layer, a frame's job k in slot k: the tiles EASU
    /// runs, then from `tile_slot_len` on those RCAS runs; written by `vkCmdUpdateBuffer` in the
    /// upscale's own command buffer.
    pub(super) tiles: (vk::Buffer, vk::DeviceMemory),
    tile_slot_len: u32,
    /// What each slot holds (or will hold once the recorded upload runs).
    tile_contents: Vec<Option<Arc<Tiles>>>,
    /// The intermediates' contents: their layouts are the ones the last upscale left (else
    /// UNDEFINED), and every tile no pass runs is black (cleared since the tile lists last changed
    /// and no full dispatch since).
    inter_defined: bool,
    inter_black: bool,
    /// A multisampled swapchain's resolved image (the app's size, single-sampled): what the
    /// upscale reads. Null for a single-sampled one, whose app images are read directly.
    pub(super) resolve: (vk::Image, vk::DeviceMemory, Vec<vk::ImageView>),
    pub(super) pool: vk::DescriptorPool,
    /// The app image's set per (app image, layer): EASU's source and output, the bilinear pass's
    /// source. RCAS's per layer (EASU's output as its source).
    pub(super) easu_sets: Vec<Vec<vk::DescriptorSet>>,
    pub(super) rcas_sets: Vec<vk::DescriptorSet>,
    /// The fragment pass: render pass (the runtime's format, loaded and stored in
    /// COLOR_ATTACHMENT_OPTIMAL), its pipeline, and per (runtime image, layer) a view and a
    /// framebuffer.
    pub(super) render_pass: vk::RenderPass,
    pub(super) pipeline: vk::Pipeline,
    pub(super) framebuffers: Vec<Vec<(vk::ImageView, vk::Framebuffer)>>,
}

/// A memory type of `props` among `bits` with `flags`.
fn memory_type(props: &vk::PhysicalDeviceMemoryProperties, bits: u32, flags: vk::MemoryPropertyFlags) -> Result<u32, String> {
    crate::plugin::vk::lifetime::memory_type(props, bits, flags).ok_or_else(|| format!("no memory type of {bits:#x} with {flags:?}"))
}

impl Target {
    /// Makes the app's images through `top` (`capture` tells each one's handle at this layer's
    /// level) and the layer's objects through `d`. On failure everything made is destroyed.
    ///
    /// # Safety
    /// `top` is the app-level table of `d`'s device; the runtime images in `desc` are live images
    /// of the device.
    pub(crate) unsafe fn new(
        d: &DeviceState,
        top: &ash::Device,
        p: &Pipelines,
        desc: TargetDesc,
        count: usize,
        capture: &dyn Fn(&mut dyn FnMut()) -> Option<vk::Image>,
    ) -> Result<Target, String> {
        let mut t = Target {
            desc,
            app: Vec::new(),
            a: (vk::Image::null(), vk::DeviceMemory::null(), Vec::new()),
            b: (vk::Image::null(), vk::DeviceMemory::null(), Vec::new()),
            resolve: (vk::Image::null(), vk::DeviceMemory::null(), Vec::new()),
            tiles: (vk::Buffer::null(), vk::DeviceMemory::null()),
            tile_slot_len: 0,
            tile_contents: Vec::new(),
            inter_defined: false,
            inter_black: false,
            pool: vk::DescriptorPool::null(),
            easu_sets: Vec::new(),
            rcas_sets: Vec::new(),
            render_pass: vk::RenderPass::null(),
            pipeline: vk::Pipeline::null(),
            framebuffers: Vec::new(),
        };
        // SAFETY: per the caller's contract.
        let made = unsafe { t.make(d, top, p, count, capture) };
        if let Err(e) = made {
            // SAFETY: nothing made has been used by the GPU.
            unsafe { t.destroy(d, top) };
            return Err(e);
        }
        Ok(t)
    }

    unsafe fn make(&mut self, d: &DeviceState, top: &ash::Device, p: &Pipelines, count: usize, capture: &dyn Fn(&mut dyn FnMut()) -> Option<vk::Image>) -> Result<(), String> {
        let desc = &self.desc;
        let msaa = desc.samples > 1;
        // A multisampled image is resolved (its transfer source), a single-sampled one sampled.
        let read = if msaa { vk::ImageUsageFlags::TRANSFER_SRC } else { vk::ImageUsageFlags::SAMPLED | vk::ImageUsageFlags::TRANSFER_SRC };
        let usage = desc.usage | vk::ImageUsageFlags::COLOR_ATTACHMENT | read;
        let flags = if desc.mutable_format { vk::ImageCreateFlags::MUTABLE_FORMAT } else { vk::ImageCreateFlags::empty() };
        let ci = vk::ImageCreateInfo::default()
            .flags(flags)
            .image_type(vk::ImageType::TYPE_2D)
            .format(desc.format)
            .extent(vk::Extent3D { width: desc.extent.0, height: desc.extent.1, depth: 1 })
            .mip_levels(desc.mips.max(1))
            .array_layers(desc.layers.max(1))
            .samples(vk::SampleCountFlags::from_raw(desc.samples.max(1)))
            .tiling(vk::ImageTiling::OPTIMAL)
            .usage(usage)
            .sharing_mode(vk::SharingMode::EXCLUSIVE)
            .initial_layout(vk::ImageLayout::UNDEFINED);
        // SAFETY: per `new`'s contract: valid create infos; each object is recorded in `self` as
        // soon as it exists, so a failure destroys it.
        unsafe {
            for _ in 0..count {
                let mut made = Err(String::new());
                let ours = capture(&mut || made = top.create_image(&ci, None).map_err(err("vkCreateImage (app level)")));
                let image = made?;
                self.app.push(AppImage { top: image, ours: ours.unwrap_or(image), memory: vk::DeviceMemory::null(), views: Vec::new() });
                let img = self.app.last_mut().expect("just pushed");
                let req = top.get_image_memory_requirements(img.top);
                let ty = memory_type(&d.memory, req.memory_type_bits, vk::MemoryPropertyFlags::DEVICE_LOCAL)?;
                img.memory = top.allocate_memory(&vk::MemoryAllocateInfo::default().allocation_size(req.size).memory_type_index(ty), None).map_err(err("vkAllocateMemory (app level)"))?;
                top.bind_image_memory(img.top, img.memory, 0).map_err(err("vkBindImageMemory (app level)"))?;
                // A multisampled image is never sampled: its resolve is.
                for layer in 0..desc.layers.max(1) {
                    if !msaa {
                        let v = view(d, img.ours, desc.format, layer)?;
                        img.views.push(v);
                    }
                }
            }
            let (rw, rh) = desc.runtime_extent;
            let mut inter = Vec::new();
            if msaa {
                // Read by the upscale as a single-sampled app image is; it passes through
                // COLOR_ATTACHMENT_OPTIMAL as one does (`record::record_resolves`).
                inter.push((2, desc.format, desc.extent, vk::ImageUsageFlags::TRANSFER_DST | vk::ImageUsageFlags::SAMPLED | vk::ImageUsageFlags::COLOR_ATTACHMENT));
            }
            if desc.method != Method::Bilinear || desc.output != Output::Fragment {
                // TRANSFER_DST: cleared black where `upscale.skip_hidden` runs no tile.
                inter.push((0, INTERMEDIATE, (rw, rh), vk::ImageUsageFlags::STORAGE | vk::ImageUsageFlags::SAMPLED | vk::ImageUsageFlags::TRANSFER_DST));
            }
            if let Output::Copy { inter: format, .. } = desc.output {
                inter.push((1, format, (rw, rh), vk::ImageUsageFlags::STORAGE | vk::ImageUsageFlags::TRANSFER_SRC | vk::ImageUsageFlags::TRANSFER_DST));
            }
            for (which, format, (w, h), usage) in inter {
                let ci = vk::ImageCreateInfo::default()
                    .image_type(vk::ImageType::TYPE_2D)
                    .format(format)
                    .extent(vk::Extent3D { width: w, height: h, depth: 1 })
                    .mip_levels(1)
                    .array_layers(desc.layers.max(1))
                    .samples(vk::SampleCountFlags::TYPE_1)
                    .tiling(vk::ImageTiling::OPTIMAL)
                    .usage(usage)
                    .sharing_mode(vk::SharingMode::EXCLUSIVE)
                    .initial_layout(vk::ImageLayout::UNDEFINED);
                let image = d.fns.create_image(&ci, None).map_err(err("vkCreateImage (intermediate)"))?;
                let slot = match which {
                    0 => &mut self.a,
                    1 => &mut self.b,
                    _ => &mut self.resolve,
                };
                slot.0 = image;
                let req = d.fns.get_image_memory_requirements(image);
                let ty = memory_type(&d.memory, req.memory_type_bits, vk::MemoryPropertyFlags::DEVICE_LOCAL)?;
                slot.1 = d.fns.allocate_memory(&vk::MemoryAllocateInfo::default().allocation_size(req.size).memory_type_index(ty), None).map_err(err("vkAllocateMemory (intermediate)"))?;
                d.fns.bind_image_memory(image, slot.1, 0).map_err(err("vkBindImageMemory (intermediate)"))?;
                for layer in 0..desc.layers.max(1) {
                    let v = view(d, image, format, layer)?;
                    slot.2.push(v);
                }
            }
            let layers = desc.layers.max(1);
            // Each job's tiles cover at most the runtime image.
            let (cols, rows) = gpu::groups(rw, rh);
            self.tile_slot_len = cols * rows;
            self.tile_contents = vec![None; (TILE_SLOTS_PER_LAYER * layers) as usize];
            let bytes = 2 * 4 * self.tile_slot_len as u64 * self.tile_contents.len() as u64;
            let usage = vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::TRANSFER_DST;
            self.tiles.0 = d.fns.create_buffer(&vk::BufferCreateInfo::default().size(bytes).usage(usage), None).map_err(err("vkCreateBuffer (tiles)"))?;
            let req = d.fns.get_buffer_memory_requirements(self.tiles.0);
            let ty = memory_type(&d.memory, req.memory_type_bits, vk::MemoryPropertyFlags::DEVICE_LOCAL)?;
            self.tiles.1 = d.fns.allocate_memory(&vk::MemoryAllocateInfo::default().allocation_size(req.size).memory_type_index(ty), None).map_err(err("vkAllocateMemory (tiles)"))?;
            d.fns.bind_buffer_memory(self.tiles.0, self.tiles.1, 0).map_err(err("vkBindBufferMemory (tiles)"))?;
            let sets = (count as u32 + 1) * layers;
            let sizes = [
                vk::DescriptorPoolSize { ty: vk::DescriptorType::COMBINED_IMAGE_SAMPLER, descriptor_count: sets },
                vk::DescriptorPoolSize { ty: vk::DescriptorType::STORAGE_IMAGE, descriptor_count: sets },
                vk::DescriptorPoolSize { ty: vk::DescriptorType::STORAGE_BUFFER, descriptor_count: sets },
            ];
            self.pool = d.fns.create_descriptor_pool(&vk::DescriptorPoolCreateInfo::default().max_sets(sets).pool_sizes(&sizes), None).map_err(err("vkCreateDescriptorPool"))?;
            let alloc = |n: u32| -> Result<Vec<vk::DescriptorSet>, String> {
                let layouts = vec![p.set_layout; n as usize];
                d.fns.allocate_descriptor_sets(&vk::DescriptorSetAllocateInfo::default().descriptor_pool(self.pool).set_layouts(&layouts)).map_err(err("vkAllocateDescriptorSets"))
            };
            let write = |set: vk::DescriptorSet, src: vk::ImageView, src_layout: vk::ImageLayout, dst: Option<vk::ImageView>| {
                let s = [vk::DescriptorImageInfo { sampler: p.sampler, image_view: src, image_layout: src_layout }];
                let o = [vk::DescriptorImageInfo { sampler: vk::Sampler::null(), image_view: dst.unwrap_or_default(), image_layout: vk::ImageLayout::GENERAL }];
                let b = [vk::DescriptorBufferInfo { buffer: self.tiles.0, offset: 0, range: vk::WHOLE_SIZE }];
                let mut writes = vec![
                    vk::WriteDescriptorSet::default().dst_set(set).dst_binding(0).descriptor_type(vk::DescriptorType::COMBINED_IMAGE_SAMPLER).image_info(&s),
                    vk::WriteDescriptorSet::default().dst_set(set).dst_binding(2).descriptor_type(vk::DescriptorType::STORAGE_BUFFER).buffer_info(&b),
                ];
                if dst.is_some() {
                    writes.push(vk::WriteDescriptorSet::default().dst_set(set).dst_binding(1).descriptor_type(vk::DescriptorType::STORAGE_IMAGE).image_info(&o));
                }
                d.fns.update_descriptor_sets(&writes, &[]);
            };
            let easu = desc.method != Method::Bilinear || desc.output != Output::Fragment;
            for img in &self.app {
                let sets = alloc(layers)?;
                // Every app image's sets read the resolved image when there is one.
                let source = if msaa { &self.resolve.2 } else { &img.views };
                for (l, &set) in sets.iter().enumerate() {
                    // The bilinear pass reads only binding 0: the storage binding is left empty.
                    match easu {
                        true => write(set, source[l], vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL, Some(self.a.2[l])),
                        false => write(set, source[l], vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL, None),
                    }
                }
                self.easu_sets.push(sets);
            }
            if easu {
                self.rcas_sets = alloc(layers)?;
                for (l, &set) in self.rcas_sets.iter().enumerate() {
                    write(set, self.a.2[l], vk::ImageLayout::GENERAL, self.b.2.get(l).copied());
                }
            }
            if desc.output == Output::Fragment {
                self.fragment_pass(d, p)?;
            }
        }
        Ok(())
    }

    /// The render pass, pipeline and framebuffers of the pass that writes the runtime's images.
    ///
    /// # Safety
    /// As for `new`.
    unsafe fn fragment_pass(&mut self, d: &DeviceState, p: &Pipelines) -> Result<(), String> {
        let desc = &self.desc;
        let attachment = [vk::AttachmentDescription::default()
            .format(desc.format)
            .samples(vk::SampleCountFlags::TYPE_1)
            .load_op(vk::AttachmentLoadOp::LOAD)
            .store_op(vk::AttachmentStoreOp::STORE)
            .stencil_load_op(vk::AttachmentLoadOp::DONT_CARE)
            .stencil_store_op(vk::AttachmentStoreOp::DONT_CARE)
            .initial_layout(vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL)
            .final_layout(vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL)];
        let color = [vk::AttachmentReference { attachment: 0, layout: vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL }];
        let subpass = [vk::SubpassDescription::default().pipeline_bind_point(vk::PipelineBindPoint::GRAPHICS).color_attachments(&color)];
        // SAFETY: valid create infos (per `new`'s contract); each object lands in `self` at once.
        unsafe {
            self.render_pass = d.fns.create_render_pass(&vk::RenderPassCreateInfo::default().attachments(&attachment).subpasses(&subpass), None).map_err(err("vkCreateRenderPass"))?;
            let vert = module(d, gpu::VERT)?;
            let frag = match module(d, if desc.method == Method::Bilinear { gpu::BILINEAR_FRAG } else { gpu::RCAS_FRAG }) {
                Ok(m) => m,
                Err(e) => {
                    d.fns.destroy_shader_module(vert, None);
                    return Err(e);
                }
            };
            let draw = crate::plugin::vk::gpu::Draw {
                vert,
                frag: Some(frag),
                bindings: &[],
                attributes: &[],
                samples: vk::SampleCountFlags::TYPE_1,
                depth_compare: None,
                color_writes: &[vk::ColorComponentFlags::RGBA],
                layout: p.layout,
                target: crate::plugin::vk::gpu::Target::Subpass(self.render_pass, 0),
            };
            let r = crate::plugin::vk::gpu::graphics_pipeline(&d.fns, draw);
            d.fns.destroy_shader_module(vert, None);
            d.fns.destroy_shader_module(frag, None);
            self.pipeline = r.map_err(|e| format!("vkCreateGraphicsPipelines: {e}"))?;
            let (w, h) = desc.runtime_extent;
            for &image in &desc.runtime_images {
                let mut per_layer = Vec::new();
                for layer in 0..desc.layers.max(1) {
                    let v = view(d, image, desc.format, layer)?;
                    let views = [v];
                    let fb = d.fns.create_framebuffer(&vk::FramebufferCreateInfo::default().render_pass(self.render_pass).attachments(&views).width(w).height(h).layers(1), None);
                    match fb {
                        Ok(fb) => per_layer.push((v, fb)),
                        Err(e) => {
                            d.fns.destroy_image_view(v, None);
                            self.framebuffers.push(per_layer);
                            return Err(format!("vkCreateFramebuffer: {e}"));
                        }
                    }
                }
                self.framebuffers.push(per_layer);
            }
        }
        Ok(())
    }

    /// Destroys everything (the GPU no longer uses it: the caller waited).
    ///
    /// # Safety
    /// As for `new`; the objects are idle.
    pub(crate) unsafe fn destroy(&mut self, d: &DeviceState, top: &ash::Device) {
        // SAFETY: per the contract; null handles are skipped.
        unsafe {
            for img in self.app.drain(..) {
                for v in img.views {
                    d.fns.destroy_image_view(v, None);
                }
                top.destroy_image(img.top, None);
                if img.memory != vk::DeviceMemory::null() {
                    top.free_memory(img.memory, None);
                }
            }
            for (v, fb) in self.framebuffers.drain(..).flatten() {
                d.fns.destroy_framebuffer(fb, None);
                d.fns.destroy_image_view(v, None);
            }
            if self.pipeline != vk::Pipeline::null() {
                d.fns.destroy_pipeline(std::mem::take(&mut self.pipeline), None);
            }
            if self.render_pass != vk::RenderPass::null() {
                d.fns.destroy_render_pass(std::mem::take(&mut self.render_pass), None);
            }
            for slot in [&mut self.a, &mut self.b, &mut self.resolve] {
                for v in slot.2.drain(..) {
                    d.fns.destroy_image_view(v, None);
                }
                if slot.0 != vk::Image::null() {
                    d.fns.destroy_image(std::mem::take(&mut slot.0), None);
                }
                if slot.1 != vk::DeviceMemory::null() {
                    d.fns.free_memory(std::mem::take(&mut slot.1), None);
                }
            }
            if self.pool != vk::DescriptorPool::null() {
                d.fns.destroy_descriptor_pool(std::mem::take(&mut self.pool), None);
            }
            if self.tiles.0 != vk::Buffer::null() {
                d.fns.destroy_buffer(std::mem::take(&mut self.tiles.0), None);
            }
            if self.tiles.1 != vk::DeviceMemory::null() {
                d.fns.free_memory(std::mem::take(&mut self.tiles.1), None);
            }
            self.tile_contents.clear();
            self.easu_sets.clear();
            self.rcas_sets.clear();
        }
    }

    fn fits(&self, t: &Tiles) -> bool {
        t.easu.len().max(t.rcas.len()) <= self.tile_slot_len as usize
    }

    /// Records the upload of the tile lists of a frame's `jobs` (in the frame's order) that its
    /// slots do not hold yet (rare: a view's first frame, a changed mask or rect), and returns how
    /// the frame finds the intermediates. The barrier before the upload waits for the earlier
    /// upscales on the queue still reading the buffer.
    ///
    /// # Safety
    /// `cb` is recording, for the queue every upscale of this target is submitted to.
    pub(crate) unsafe fn record_tile_uploads(&mut self, d: &DeviceState, cb: vk::CommandBuffer, jobs: &[Option<Arc<Tiles>>]) -> Prep {
        // SAFETY: per the contract.
        let uploaded = unsafe { self.upload(d, cb, jobs) };
        let compact = !jobs.is_empty() && (0..jobs.len()).all(|k| self.tile_params(k, jobs[k].as_ref(), false).is_some());
        let prep = Prep { defined: self.inter_defined, clear: compact && (uploaded || !self.inter_black) };
        self.inter_defined = true;
        self.inter_black = compact;
        prep
    }

    /// # Safety
    /// As for `record_tile_uploads`.
    unsafe fn upload(&mut self, d: &DeviceState, cb: vk::CommandBuffer, jobs: &[Option<Arc<Tiles>>]) -> bool {
        let changed: Vec<(usize, Arc<Tiles>)> = jobs
            .iter()
            .enumerate()
            .filter_map(|(k, t)| {
                let (t, held) = (t.as_ref()?, self.tile_contents.get(k)?);
                (!held.as_ref().is_some_and(|h| Arc::ptr_eq(h, t)) && self.fits(t)).then(|| (k, t.clone()))
            })
            .collect();
        if changed.is_empty() {
            return false;
        }
        let barrier = |src, dst| [vk::BufferMemoryBarrier::default().src_access_mask(src).dst_access_mask(dst).src_queue_family_index(vk::QUEUE_FAMILY_IGNORED).dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED).buffer(self.tiles.0).offset(0).size(vk::WHOLE_SIZE)];
        let (compute, transfer) = (vk::PipelineStageFlags::COMPUTE_SHADER, vk::PipelineStageFlags::TRANSFER);
        // SAFETY: per the contract; the buffer is ours, each write inside it (`fits`), each
        // update at most 65536 bytes and a multiple of 4 (VUID-vkCmdUpdateBuffer-dataSize-00037).
        unsafe {
            d.fns.cmd_pipeline_barrier(cb, compute, transfer, vk::DependencyFlags::empty(), &[], &barrier(vk::AccessFlags::SHADER_READ, vk::AccessFlags::TRANSFER_WRITE), &[]);
            for (k, t) in &changed {
                for (list, at) in [(&t.easu, 0), (&t.rcas, self.tile_slot_len as u64)] {
                    let bytes: Vec<u8> = list.iter().flat_map(|c| c.to_ne_bytes()).collect();
                    let base = 4 * (2 * *k as u64 * self.tile_slot_len as u64 + at);
                    for (n, chunk) in bytes.chunks(65536).enumerate() {
                        d.fns.cmd_update_buffer(cb, self.tiles.0, base + 65536 * n as u64, chunk);
                    }
                }
                self.tile_contents[*k] = Some(t.clone());
            }
            d.fns.cmd_pipeline_barrier(cb, transfer, compute, vk::DependencyFlags::empty(), &[], &barrier(vk::AccessFlags::TRANSFER_WRITE, vk::AccessFlags::SHADER_READ), &[]);
        }
        true
    }

    /// The recorded upload did not reach the GPU (the submission failed): upload again next time,
    /// and take nothing for granted about the intermediates.
    pub(crate) fn forget_tiles(&mut self) {
        self.tile_contents.iter_mut().for_each(|t| *t = None);
        self.inter_defined = false;
        self.inter_black = false;
    }

    /// A frame's job `k` with tiles `t`, for EASU's pass or RCAS's: the push constants' `skip`
    /// (where its list starts) and the list's length (its workgroups); None when it has none (or
    /// they are not uploaded): the pass runs over the whole rect.
    pub(crate) fn tile_params(&self, k: usize, t: Option<&Arc<Tiles>>, rcas: bool) -> Option<([i32; 4], u32)> {
        match (t, self.tile_contents.get(k)) {
            (Some(t), Some(Some(held))) if Arc::ptr_eq(held, t) => {
                let (list, at) = if rcas { (&t.rcas, self.tile_slot_len) } else { (&t.easu, 0) };
                Some(([(2 * k as u32 * self.tile_slot_len + at) as i32, 1, 0, 0], list.len() as u32))
            }
            _ => None,
        }
    }

    /// The first layout of every app image (UNDEFINED → COLOR_ATTACHMENT_OPTIMAL, what the binding
    /// promises the app at acquire), as barriers on the app's handles (recorded through the
    /// app-level table, from TOP_OF_PIPE to COLOR_ATTACHMENT_OUTPUT).
    pub(crate) fn first_layout_barriers(&self) -> Vec<vk::ImageMemoryBarrier<'static>> {
        self.app
            .iter()
            .map(|i| image_barrier(i.top, vk::ImageLayout::UNDEFINED, vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL, vk::AccessFlags::empty(), vk::AccessFlags::COLOR_ATTACHMENT_WRITE | vk::AccessFlags::COLOR_ATTACHMENT_READ, self.desc.layers, self.desc.mips))
            .collect()
    }
}

pub(super) fn rect4(r: PixelRect) -> [i32; 4] {
    [r.x, r.y, r.width as i32, r.height as i32]
}

/// A colour barrier over `layers` layers and `mips` levels of `image` (`gpu::image_barrier`).
pub(super) fn image_barrier(image: vk::Image, old: vk::ImageLayout, new: vk::ImageLayout, src: vk::AccessFlags, dst: vk::AccessFlags, layers: u32, mips: u32) -> vk::ImageMemoryBarrier<'static> {
    crate::plugin::vk::gpu::image_barrier(image, crate::plugin::vk::gpu::color_range(0, layers.max(1), mips.max(1)), (old, new), (src, dst))
}

/// # Safety
/// `image` is a live image of `d` with `layer` and the format's view compatibility.
unsafe fn view(d: &DeviceState, image: vk::Image, format: vk::Format, layer: u32) -> Result<vk::ImageView, String> {
    let ci = vk::ImageViewCreateInfo::default()
        .image(image)
        .view_type(vk::ImageViewType::TYPE_2D)
        .format(format)
        .subresource_range(vk::ImageSubresourceRange { aspect_mask: vk::ImageAspectFlags::COLOR, base_mip_level: 0, level_count: 1, base_array_layer: layer, layer_count: 1 });
    // SAFETY: per the contract.
    unsafe { d.fns.create_image_view(&ci, None) }.map_err(err("vkCreateImageView"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn formats_the_upscale_refuses_and_how_it_writes_the_others() {
        let all = vk::FormatProperties { optimal_tiling_features: vk::FormatFeatureFlags::SAMPLED_IMAGE | vk::FormatFeatureFlags::SAMPLED_IMAGE_FILTER_LINEAR | vk::FormatFeatureFlags::COLOR_ATTACHMENT, ..Default::default() };
        assert_eq!(format_refusal(all, Method::EasuRcas), None);
        assert_eq!(format_refusal(all, Method::Bilinear), None);
        let unfiltered = vk::FormatProperties { optimal_tiling_features: vk::FormatFeatureFlags::SAMPLED_IMAGE | vk::FormatFeatureFlags::COLOR_ATTACHMENT, ..Default::default() };
        assert_eq!(format_refusal(unfiltered, Method::EasuRcas), None);
        assert!(format_refusal(unfiltered, Method::Bilinear).is_some_and(|w| w.contains("FILTER_LINEAR")));
        let unsampled = vk::FormatProperties { optimal_tiling_features: vk::FormatFeatureFlags::COLOR_ATTACHMENT, ..Default::default() };
        assert!(format_refusal(unsampled, Method::EasuRcas).is_some());
        assert_eq!(Output::of(vk::Format::B8G8R8A8_SRGB), Output::Copy { inter: vk::Format::R8G8B8A8_UNORM, srgb: true, swap_rb: true });
        assert_eq!(Output::of(vk::Format::R16G16B16A16_SFLOAT), Output::Copy { inter: vk::Format::R16G16B16A16_SFLOAT, srgb: false, swap_rb: false });
        assert_eq!(Output::of(vk::Format::A2B10G10R10_UNORM_PACK32), Output::Fragment);
    }
}
