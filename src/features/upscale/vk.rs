//! The upscale's Vulkan work on the session's device. Two levels of the chain are used, for two
//! kinds of object: what the app sees (the images `xrEnumerateSwapchainImages` hands it, their
//! memory, their first layout) is made through the app's own level (`top`: the Vulkan loader's
//! entry points, as a runtime makes its swapchain images), so every layer above this one knows
//! them; the layer's own objects (pipelines, intermediates, views, descriptors, command buffers)
//! through the layer's counted table below it (`DeviceState::fns`), as every feature's.
//!
//! Per interposed swapchain (`Target`): the app's images and a view per array layer, an RGBA16F
//! intermediate of the runtime image's size (EASU's output), the descriptor sets (written once:
//! nothing is updated per frame), and per runtime image and layer a framebuffer. A frame's upscale
//! (`record::record_frame`) is EASU per job (a view's rect in one array layer) as compute, then RCAS as a
//! fragment pass drawing the job's rect of the runtime's image as a colour attachment;
//! `Method::Bilinear` is that fragment pass alone, sampling the app's image. Why fragment and not
//! compute or a blit for the last step: the runtime's image stays in COLOR_ATTACHMENT_OPTIMAL
//! (the layout it is acquired and released in, so no transition, which can cost a decompression)
//! and its format's encoding (sRGB) is done by the output merger. A blit with its two transitions
//! cost 0.67 ms per frame for two Index eyes on an H100, the whole EASU + RCAS pass 0.24 ms
//! (docs/benchmarks.md). The app's images come back in the layout the OpenXR Vulkan binding
//! names, the runtime's never leave it.

use super::gpu;
use super::Method;
use crate::core::rect::PixelRect;
use crate::vk::DeviceState;
use ash::vk;
use ash::vk::Handle as _;

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
    crate::vk::lifetime::memory_type(props, bits, flags).ok_or_else(|| format!("no memory type of {bits:#x} with {flags:?}"))
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
        let usage = desc.usage | vk::ImageUsageFlags::COLOR_ATTACHMENT | vk::ImageUsageFlags::SAMPLED | vk::ImageUsageFlags::TRANSFER_SRC;
        let flags = if desc.mutable_format { vk::ImageCreateFlags::MUTABLE_FORMAT } else { vk::ImageCreateFlags::empty() };
        let ci = vk::ImageCreateInfo::default()
            .flags(flags)
            .image_type(vk::ImageType::TYPE_2D)
            .format(desc.format)
            .extent(vk::Extent3D { width: desc.extent.0, height: desc.extent.1, depth: 1 })
            .mip_levels(desc.mips.max(1))
            .array_layers(desc.layers.max(1))
            .samples(vk::SampleCountFlags::TYPE_1)
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
                for layer in 0..desc.layers.max(1) {
                    let v = view(d, img.ours, desc.format, layer)?;
                    img.views.push(v);
                }
            }
            let (rw, rh) = desc.runtime_extent;
            let mut inter = Vec::new();
            if desc.method != Method::Bilinear || desc.output != Output::Fragment {
                inter.push((0, INTERMEDIATE));
            }
            if let Output::Copy { inter: format, .. } = desc.output {
                inter.push((1, format));
            }
            for (which, format) in inter {
                let usage = if which == 0 { vk::ImageUsageFlags::STORAGE | vk::ImageUsageFlags::SAMPLED } else { vk::ImageUsageFlags::STORAGE | vk::ImageUsageFlags::TRANSFER_SRC };
                let ci = vk::ImageCreateInfo::default()
                    .image_type(vk::ImageType::TYPE_2D)
                    .format(format)
                    .extent(vk::Extent3D { width: rw, height: rh, depth: 1 })
                    .mip_levels(1)
                    .array_layers(desc.layers.max(1))
                    .samples(vk::SampleCountFlags::TYPE_1)
                    .tiling(vk::ImageTiling::OPTIMAL)
                    .usage(usage)
                    .sharing_mode(vk::SharingMode::EXCLUSIVE)
                    .initial_layout(vk::ImageLayout::UNDEFINED);
                let image = d.fns.create_image(&ci, None).map_err(err("vkCreateImage (intermediate)"))?;
                let slot = if which == 0 { &mut self.a } else { &mut self.b };
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
            let sets = (count as u32 + 1) * layers;
            let sizes = [
                vk::DescriptorPoolSize { ty: vk::DescriptorType::COMBINED_IMAGE_SAMPLER, descriptor_count: sets },
                vk::DescriptorPoolSize { ty: vk::DescriptorType::STORAGE_IMAGE, descriptor_count: sets },
            ];
            self.pool = d.fns.create_descriptor_pool(&vk::DescriptorPoolCreateInfo::default().max_sets(sets).pool_sizes(&sizes), None).map_err(err("vkCreateDescriptorPool"))?;
            let alloc = |n: u32| -> Result<Vec<vk::DescriptorSet>, String> {
                let layouts = vec![p.set_layout; n as usize];
                d.fns.allocate_descriptor_sets(&vk::DescriptorSetAllocateInfo::default().descriptor_pool(self.pool).set_layouts(&layouts)).map_err(err("vkAllocateDescriptorSets"))
            };
            let write = |set: vk::DescriptorSet, src: vk::ImageView, src_layout: vk::ImageLayout, dst: Option<vk::ImageView>| {
                let s = [vk::DescriptorImageInfo { sampler: p.sampler, image_view: src, image_layout: src_layout }];
                let o = [vk::DescriptorImageInfo { sampler: vk::Sampler::null(), image_view: dst.unwrap_or_default(), image_layout: vk::ImageLayout::GENERAL }];
                let mut writes = vec![vk::WriteDescriptorSet::default().dst_set(set).dst_binding(0).descriptor_type(vk::DescriptorType::COMBINED_IMAGE_SAMPLER).image_info(&s)];
                if dst.is_some() {
                    writes.push(vk::WriteDescriptorSet::default().dst_set(set).dst_binding(1).descriptor_type(vk::DescriptorType::STORAGE_IMAGE).image_info(&o));
                }
                d.fns.update_descriptor_sets(&writes, &[]);
            };
            let easu = desc.method != Method::Bilinear || desc.output != Output::Fragment;
            for img in &self.app {
                let sets = alloc(layers)?;
                for (l, &set) in sets.iter().enumerate() {
                    // The bilinear pass reads only binding 0: the storage binding is left empty.
                    match easu {
                        true => write(set, img.views[l], vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL, Some(self.a.2[l])),
                        false => write(set, img.views[l], vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL, None),
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
            let stages = [
                vk::PipelineShaderStageCreateInfo::default().stage(vk::ShaderStageFlags::VERTEX).module(vert).name(c"main"),
                vk::PipelineShaderStageCreateInfo::default().stage(vk::ShaderStageFlags::FRAGMENT).module(frag).name(c"main"),
            ];
            let vertex_input = vk::PipelineVertexInputStateCreateInfo::default();
            let assembly = vk::PipelineInputAssemblyStateCreateInfo::default().topology(vk::PrimitiveTopology::TRIANGLE_LIST);
            let viewport = vk::PipelineViewportStateCreateInfo::default().viewport_count(1).scissor_count(1);
            let raster = vk::PipelineRasterizationStateCreateInfo::default().polygon_mode(vk::PolygonMode::FILL).cull_mode(vk::CullModeFlags::NONE).line_width(1.0);
            let multisample = vk::PipelineMultisampleStateCreateInfo::default().rasterization_samples(vk::SampleCountFlags::TYPE_1);
            let blend_attachment = [vk::PipelineColorBlendAttachmentState::default().color_write_mask(vk::ColorComponentFlags::RGBA)];
            let blend = vk::PipelineColorBlendStateCreateInfo::default().attachments(&blend_attachment);
            let dynamic_states = [vk::DynamicState::VIEWPORT, vk::DynamicState::SCISSOR];
            let dynamic = vk::PipelineDynamicStateCreateInfo::default().dynamic_states(&dynamic_states);
            let ci = vk::GraphicsPipelineCreateInfo::default()
                .stages(&stages)
                .vertex_input_state(&vertex_input)
                .input_assembly_state(&assembly)
                .viewport_state(&viewport)
                .rasterization_state(&raster)
                .multisample_state(&multisample)
                .color_blend_state(&blend)
                .dynamic_state(&dynamic)
                .layout(p.layout)
                .render_pass(self.render_pass)
                .subpass(0);
            let r = d.fns.create_graphics_pipelines(vk::PipelineCache::null(), &[ci], None);
            d.fns.destroy_shader_module(vert, None);
            d.fns.destroy_shader_module(frag, None);
            self.pipeline = r.map(|v| v[0]).map_err(|(_, e)| format!("vkCreateGraphicsPipelines: {e}"))?;
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
            for slot in [&mut self.a, &mut self.b] {
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
            self.easu_sets.clear();
            self.rcas_sets.clear();
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

pub(super) fn image_barrier(image: vk::Image, old: vk::ImageLayout, new: vk::ImageLayout, src: vk::AccessFlags, dst: vk::AccessFlags, layers: u32, mips: u32) -> vk::ImageMemoryBarrier<'static> {
    vk::ImageMemoryBarrier::default()
        .src_access_mask(src)
        .dst_access_mask(dst)
        .old_layout(old)
        .new_layout(new)
        .src_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
        .dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
        .image(image)
        .subresource_range(vk::ImageSubresourceRange { aspect_mask: vk::ImageAspectFlags::COLOR, base_mip_level: 0, level_count: mips.max(1), base_array_layer: 0, layer_count: layers.max(1) })
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

/// The command buffers of one session's upscales: reused once their fence signalled, at most
/// `MAX` in flight (then the oldest is waited for).
pub(crate) struct Slots {
    pool: vk::CommandPool,
    ring: std::collections::VecDeque<(vk::CommandBuffer, vk::Fence)>,
    pub queue: vk::Queue,
    /// Two timestamps per slot (`MAX` slots), around each upscale's commands: its own GPU time,
    /// read back when the slot is reused (`take`). None where the queue has no timestamps.
    queries: Option<(vk::QueryPool, f64)>,
    /// Which query pair each ring entry wrote (by its command buffer).
    query_of: std::collections::HashMap<vk::CommandBuffer, u32>,
    /// The GPU time of the last upscale read back, ms, and its phases (`MARKS` - 1 intervals:
    /// barriers in, EASU, RCAS and the copy (or the fragment pass), barriers out) of the
    /// submission's last swapchain; the first interval also holds the earlier swapchains' work.
    pub last_gpu_ms: Option<f64>,
    pub last_phases_ms: Vec<f64>,
}

/// Timestamps per upscale: start, after the barriers in, after EASU, after the fragment pass, end.
pub(crate) const MARKS: u32 = 5;

/// Upscales in flight before an `xrEndFrame` waits: a frame submits one per swapchain (two for
/// per-eye apps), and runtimes let an app run up to about three frames ahead.
const MAX: usize = 8;
/// How long `xrEndFrame` waits for an old upscale before giving up on this one.
const WAIT_NS: u64 = 2_000_000_000;

impl Slots {
    /// `timestamp_period`: ns per tick, 0 where the queue family has no timestamps.
    pub(crate) fn new(d: &DeviceState, family: u32, queue_index: u32, timestamp_period: f32) -> Result<Slots, String> {
        // SAFETY: a valid create info for the session's queue family on a live device.
        let pool = unsafe { d.fns.create_command_pool(&vk::CommandPoolCreateInfo::default().queue_family_index(family).flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER), None) }.map_err(err("vkCreateCommandPool"))?;
        // SAFETY: the binding's queue exists (the runtime accepted the binding).
        let queue = unsafe { d.fns.get_device_queue(family, queue_index) };
        let queries = (timestamp_period > 0.0).then(|| {
            let ci = vk::QueryPoolCreateInfo::default().query_type(vk::QueryType::TIMESTAMP).query_count(MARKS * MAX as u32);
            // SAFETY: a valid create info; without the pool the upscale is only untimed.
            unsafe { d.fns.create_query_pool(&ci, None) }.ok().map(|q| (q, timestamp_period as f64 / 1e6))
        });
        Ok(Slots { pool, ring: Default::default(), queue, queries: queries.flatten(), query_of: Default::default(), last_gpu_ms: None, last_phases_ms: Vec::new() })
    }

    /// Records timestamp `k` (0: start, `MARKS` - 1: end) of `cb`'s upscale. Each is written once
    /// every earlier command on the queue completed: from the first on, the time is the
    /// upscale's, its layout transitions included.
    ///
    /// # Safety
    /// `cb` is recording, and was handed out by `take`.
    pub(crate) unsafe fn mark(&self, d: &DeviceState, cb: vk::CommandBuffer, k: u32) {
        let (Some((pool, _)), Some(&pair)) = (self.queries, self.query_of.get(&cb)) else { return };
        // SAFETY: per the contract; the queries belong to this buffer alone.
        unsafe {
            if k == 0 {
                d.fns.cmd_reset_query_pool(cb, pool, MARKS * pair, MARKS);
            }
            d.fns.cmd_write_timestamp(cb, vk::PipelineStageFlags::ALL_COMMANDS, pool, MARKS * pair + k.min(MARKS - 1));
        }
    }

    /// Reads the timestamps of a completed buffer.
    fn read(&mut self, d: &DeviceState, cb: vk::CommandBuffer) {
        let (Some((pool, ms_per_tick)), Some(&pair)) = (self.queries, self.query_of.get(&cb)) else { return };
        let mut t = [0u64; MARKS as usize];
        // SAFETY: the buffer completed (its fence signalled), so every query it wrote is written;
        // marks a recording skipped (no EASU) read as unavailable and fail the whole read.
        let r = unsafe { d.fns.get_query_pool_results(pool, MARKS * pair, &mut t, vk::QueryResultFlags::TYPE_64) };
        if r.is_ok() && t[MARKS as usize - 1] >= t[0] {
            self.last_gpu_ms = Some((t[MARKS as usize - 1] - t[0]) as f64 * ms_per_tick);
            self.last_phases_ms = t.windows(2).map(|w| w[1].saturating_sub(w[0]) as f64 * ms_per_tick).collect();
        }
    }

    /// A command buffer to record into (reset), with its fence (unsignalled).
    pub(crate) fn take(&mut self, d: &DeviceState) -> Result<(vk::CommandBuffer, vk::Fence), String> {
        // SAFETY: the layer's own objects of a live device; a fence is reset only once signalled
        // (its command buffer is then no longer in use).
        unsafe {
            let ready = self.ring.front().is_some_and(|&(_, f)| d.fns.get_fence_status(f).unwrap_or(false));
            let (cb, fence) = if ready || self.ring.len() >= MAX {
                let (cb, fence) = self.ring.pop_front().expect("checked non-empty");
                if !ready {
                    d.fns.wait_for_fences(&[fence], true, WAIT_NS).map_err(err("waiting for an earlier upscale"))?;
                }
                self.read(d, cb);
                d.fns.reset_fences(&[fence]).map_err(err("vkResetFences"))?;
                d.fns.reset_command_buffer(cb, vk::CommandBufferResetFlags::empty()).map_err(err("vkResetCommandBuffer"))?;
                (cb, fence)
            } else {
                let alloc = vk::CommandBufferAllocateInfo::default().command_pool(self.pool).level(vk::CommandBufferLevel::PRIMARY).command_buffer_count(1);
                let cb = d.fns.allocate_command_buffers(&alloc).map_err(err("vkAllocateCommandBuffers"))?[0];
                // The loader sets the dispatch word only on objects handed out through it.
                if let Some(set) = d.set_loader_data {
                    let r = set(d.handle, cb.as_raw() as usize as *mut std::ffi::c_void);
                    if r != vk::Result::SUCCESS {
                        d.fns.free_command_buffers(self.pool, &[cb]);
                        return Err(format!("vkSetDeviceLoaderData: {r:?}"));
                    }
                }
                let fence = match d.fns.create_fence(&vk::FenceCreateInfo::default(), None) {
                    Ok(f) => f,
                    Err(e) => {
                        d.fns.free_command_buffers(self.pool, &[cb]);
                        return Err(format!("vkCreateFence: {e}"));
                    }
                };
                let pair = self.query_of.len() as u32;
                self.query_of.insert(cb, pair);
                (cb, fence)
            };
            self.ring.push_back((cb, fence));
            Ok((cb, fence))
        }
    }

    /// Waits for every upscale in flight (before their objects are destroyed).
    pub(crate) fn wait_all(&self, d: &DeviceState) {
        let fences: Vec<vk::Fence> = self.ring.iter().map(|&(_, f)| f).collect();
        if fences.is_empty() {
            return;
        }
        // SAFETY: the layer's own fences. A fence never submitted (its recording failed) was
        // taken out of the ring by `abandon`, so every fence here will signal.
        if let Err(e) = unsafe { d.fns.wait_for_fences(&fences, true, WAIT_NS) } {
            tracing::warn!("upscale: waiting for the last upscales failed ({e}); destroying their objects anyway");
        }
    }

    /// `cb` (handed out by `take`) was not submitted: its fence would never signal.
    pub(crate) fn abandon(&mut self, d: &DeviceState, cb: vk::CommandBuffer) {
        let Some(at) = self.ring.iter().position(|&(c, _)| c == cb) else { return };
        let (cb, fence) = self.ring.remove(at).expect("found");
        // Its query pair goes with it; the buffer holding the highest pair takes it over, so the
        // pairs stay 0..len.
        if let Some(freed) = self.query_of.remove(&cb) {
            let top = self.query_of.len() as u32;
            if let Some((_, last)) = self.query_of.iter_mut().find(|(_, p)| **p == top) {
                *last = freed;
            }
        }
        // SAFETY: never submitted, so not in use.
        unsafe {
            d.fns.destroy_fence(fence, None);
            d.fns.free_command_buffers(self.pool, &[cb]);
        }
    }

    pub(crate) fn destroy(&mut self, d: &DeviceState) {
        self.wait_all(d);
        // SAFETY: idle (waited above); the pool frees its command buffers.
        unsafe {
            for (_, f) in self.ring.drain(..) {
                d.fns.destroy_fence(f, None);
            }
            d.fns.destroy_command_pool(self.pool, None);
            if let Some((q, _)) = self.queries.take() {
                d.fns.destroy_query_pool(q, None);
            }
        }
    }
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
