//! The upscale's Vulkan work on the session's device. Two levels of the chain are used, for two
//! kinds of object: what the app sees (the images `xrEnumerateSwapchainImages` hands it, their
//! memory, their first layout) is made through the app's own level (`top`: the Vulkan loader's
//! entry points, as a runtime makes its swapchain images), so every layer above this one knows
//! them; the layer's own objects (pipelines, intermediates, views, descriptors, command buffers)
//! through the layer's counted table below it (`DeviceState::fns`), as every feature's.
//!
//! Per interposed swapchain (`Target`): the app's images and a view per array layer, two RGBA16F
//! intermediates of the runtime image's size (EASU writes the first, RCAS the second), their
//! descriptor sets (written once: nothing is updated per frame), and the runtime's images. A
//! frame's upscale (`record`) is EASU then RCAS per job (a view's rect in one array layer), then a
//! blit into the runtime's image, which converts to its format (sRGB encodes); `Method::Bilinear`
//! is one filtered blit. Images come back in the layouts the OpenXR Vulkan binding names.

use super::gpu::{self, EasuParams, RcasParams};
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
/// destination) and 32 bytes of push constants for both passes.
pub(crate) struct Pipelines {
    set_layout: vk::DescriptorSetLayout,
    layout: vk::PipelineLayout,
    easu: vk::Pipeline,
    rcas: vk::Pipeline,
    sampler: vk::Sampler,
}

impl Pipelines {
    pub(crate) fn new(d: &DeviceState) -> Result<Pipelines, String> {
        let mut p = Pipelines {
            set_layout: vk::DescriptorSetLayout::null(),
            layout: vk::PipelineLayout::null(),
            easu: vk::Pipeline::null(),
            rcas: vk::Pipeline::null(),
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
            vk::DescriptorSetLayoutBinding::default().binding(0).descriptor_type(vk::DescriptorType::COMBINED_IMAGE_SAMPLER).descriptor_count(1).stage_flags(vk::ShaderStageFlags::COMPUTE),
            vk::DescriptorSetLayoutBinding::default().binding(1).descriptor_type(vk::DescriptorType::STORAGE_IMAGE).descriptor_count(1).stage_flags(vk::ShaderStageFlags::COMPUTE),
        ];
        // SAFETY: per `new`'s contract.
        unsafe {
            self.set_layout = d.fns.create_descriptor_set_layout(&vk::DescriptorSetLayoutCreateInfo::default().bindings(&bindings), None).map_err(err("vkCreateDescriptorSetLayout"))?;
            let push = [vk::PushConstantRange { stage_flags: vk::ShaderStageFlags::COMPUTE, offset: 0, size: 32 }];
            let layouts = [self.set_layout];
            self.layout = d.fns.create_pipeline_layout(&vk::PipelineLayoutCreateInfo::default().set_layouts(&layouts).push_constant_ranges(&push), None).map_err(err("vkCreatePipelineLayout"))?;
            self.easu = compute_pipeline(d, self.layout, gpu::EASU)?;
            self.rcas = compute_pipeline(d, self.layout, gpu::RCAS)?;
            let sci = vk::SamplerCreateInfo::default()
                .mag_filter(vk::Filter::NEAREST)
                .min_filter(vk::Filter::NEAREST)
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
            for p in [self.easu, self.rcas] {
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
/// `layout` is a live pipeline layout of `d`.
unsafe fn compute_pipeline(d: &DeviceState, layout: vk::PipelineLayout, spirv: &[u8]) -> Result<vk::Pipeline, String> {
    let code: Vec<u32> = spirv.chunks_exact(4).map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect();
    // SAFETY: valid SPIR-V built by build.rs; the module is destroyed once the pipeline exists.
    unsafe {
        let module = d.fns.create_shader_module(&vk::ShaderModuleCreateInfo::default().code(&code), None).map_err(err("vkCreateShaderModule"))?;
        let stage = vk::PipelineShaderStageCreateInfo::default().stage(vk::ShaderStageFlags::COMPUTE).module(module).name(c"main");
        let ci = vk::ComputePipelineCreateInfo::default().stage(stage).layout(layout);
        let r = d.fns.create_compute_pipelines(vk::PipelineCache::null(), &[ci], None);
        d.fns.destroy_shader_module(module, None);
        r.map(|v| v[0]).map_err(|(_, e)| format!("vkCreateComputePipelines: {e}"))
    }
}

/// What the interposition of one swapchain needs from the format: a sampled (EASU) or filtered
/// blit (bilinear) source, a blit destination for the runtime's image. None: it can; Some: why not.
pub(crate) fn format_refusal(props: vk::FormatProperties, method: Method) -> Option<String> {
    let have = props.optimal_tiling_features;
    let need_src = match method {
        Method::EasuRcas => vk::FormatFeatureFlags::SAMPLED_IMAGE,
        Method::Bilinear => vk::FormatFeatureFlags::BLIT_SRC | vk::FormatFeatureFlags::SAMPLED_IMAGE_FILTER_LINEAR,
    };
    let need = need_src | vk::FormatFeatureFlags::BLIT_DST | vk::FormatFeatureFlags::COLOR_ATTACHMENT;
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
}

/// One interposed swapchain's objects.
pub(crate) struct Target {
    pub desc: TargetDesc,
    pub app: Vec<AppImage>,
    /// The intermediates (EASU → `a`, RCAS → `b`): image, memory, a view per layer.
    a: (vk::Image, vk::DeviceMemory, Vec<vk::ImageView>),
    b: (vk::Image, vk::DeviceMemory, Vec<vk::ImageView>),
    pool: vk::DescriptorPool,
    /// EASU's set per (app image, layer), RCAS's per layer.
    easu_sets: Vec<Vec<vk::DescriptorSet>>,
    rcas_sets: Vec<vk::DescriptorSet>,
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
            for which in [0, 1] {
                let ci = vk::ImageCreateInfo::default()
                    .image_type(vk::ImageType::TYPE_2D)
                    .format(INTERMEDIATE)
                    .extent(vk::Extent3D { width: rw, height: rh, depth: 1 })
                    .mip_levels(1)
                    .array_layers(desc.layers.max(1))
                    .samples(vk::SampleCountFlags::TYPE_1)
                    .tiling(vk::ImageTiling::OPTIMAL)
                    .usage(vk::ImageUsageFlags::STORAGE | vk::ImageUsageFlags::SAMPLED | vk::ImageUsageFlags::TRANSFER_SRC)
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
                    let v = view(d, image, INTERMEDIATE, layer)?;
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
            let write = |set: vk::DescriptorSet, src: vk::ImageView, src_layout: vk::ImageLayout, dst: vk::ImageView| {
                let s = [vk::DescriptorImageInfo { sampler: p.sampler, image_view: src, image_layout: src_layout }];
                let o = [vk::DescriptorImageInfo { sampler: vk::Sampler::null(), image_view: dst, image_layout: vk::ImageLayout::GENERAL }];
                let writes = [
                    vk::WriteDescriptorSet::default().dst_set(set).dst_binding(0).descriptor_type(vk::DescriptorType::COMBINED_IMAGE_SAMPLER).image_info(&s),
                    vk::WriteDescriptorSet::default().dst_set(set).dst_binding(1).descriptor_type(vk::DescriptorType::STORAGE_IMAGE).image_info(&o),
                ];
                d.fns.update_descriptor_sets(&writes, &[]);
            };
            for img in &self.app {
                let sets = alloc(layers)?;
                for (l, &set) in sets.iter().enumerate() {
                    write(set, img.views[l], vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL, self.a.2[l]);
                }
                self.easu_sets.push(sets);
            }
            self.rcas_sets = alloc(layers)?;
            for (l, &set) in self.rcas_sets.iter().enumerate() {
                write(set, self.a.2[l], vk::ImageLayout::GENERAL, self.b.2[l]);
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

    /// Records the first layout of every app image (UNDEFINED → COLOR_ATTACHMENT_OPTIMAL, what the
    /// binding promises the app at acquire) into `cb`, through the app-level table.
    ///
    /// # Safety
    /// `cb` is recording, allocated through `top`.
    pub(crate) unsafe fn record_first_layouts(&self, top: &ash::Device, cb: vk::CommandBuffer) {
        let barriers: Vec<_> = self
            .app
            .iter()
            .map(|i| image_barrier(i.top, vk::ImageLayout::UNDEFINED, vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL, vk::AccessFlags::empty(), vk::AccessFlags::COLOR_ATTACHMENT_WRITE | vk::AccessFlags::COLOR_ATTACHMENT_READ, self.desc.layers, self.desc.mips))
            .collect();
        // SAFETY: per the contract.
        unsafe { top.cmd_pipeline_barrier(cb, vk::PipelineStageFlags::TOP_OF_PIPE, vk::PipelineStageFlags::COLOR_ATTACHMENT_OUTPUT, vk::DependencyFlags::empty(), &[], &[], &barriers) };
    }

    /// Records the upscale of app image `index` into the runtime's image of the same index (the
    /// runtime's acquire picks both) for `jobs`, by `method` with RCAS `sharpness`.
    ///
    /// # Safety
    /// `cb` is recording (allocated through `d.fns`, for the session's queue family); the app's
    /// image was released by the app (its rendering submitted before) and the runtime's image is
    /// acquired and waited for.
    pub(crate) unsafe fn record(&self, d: &DeviceState, p: &Pipelines, cb: vk::CommandBuffer, index: usize, jobs: &[Job], (method, sharpness): (Method, f32)) {
        let app_index = index;
        let (Some(app), Some(&runtime)) = (self.app.get(index), self.desc.runtime_images.get(index)) else { return };
        let layers = self.desc.layers.max(1);
        let mips = self.desc.mips.max(1);
        let f = &d.fns;
        let color = vk::AccessFlags::COLOR_ATTACHMENT_WRITE | vk::AccessFlags::COLOR_ATTACHMENT_READ;
        let any = vk::PipelineStageFlags::ALL_COMMANDS;
        // SAFETY: per the contract; every handle is a live object of `d`'s device.
        unsafe {
            match method {
                Method::Bilinear => {
                    let pre = [
                        image_barrier(app.ours, vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL, vk::ImageLayout::TRANSFER_SRC_OPTIMAL, color, vk::AccessFlags::TRANSFER_READ, layers, mips),
                        image_barrier(runtime, vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL, vk::ImageLayout::TRANSFER_DST_OPTIMAL, color, vk::AccessFlags::TRANSFER_WRITE, layers, 1),
                    ];
                    f.cmd_pipeline_barrier(cb, any, vk::PipelineStageFlags::TRANSFER, vk::DependencyFlags::empty(), &[], &[], &pre);
                    let regions: Vec<vk::ImageBlit> = jobs.iter().map(|j| blit(j.src, j.dst, j.layer)).collect();
                    f.cmd_blit_image(cb, app.ours, vk::ImageLayout::TRANSFER_SRC_OPTIMAL, runtime, vk::ImageLayout::TRANSFER_DST_OPTIMAL, &regions, vk::Filter::LINEAR);
                    let post = [
                        image_barrier(app.ours, vk::ImageLayout::TRANSFER_SRC_OPTIMAL, vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL, vk::AccessFlags::empty(), color, layers, mips),
                        image_barrier(runtime, vk::ImageLayout::TRANSFER_DST_OPTIMAL, vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL, vk::AccessFlags::TRANSFER_WRITE, vk::AccessFlags::MEMORY_READ | color, layers, 1),
                    ];
                    f.cmd_pipeline_barrier(cb, vk::PipelineStageFlags::TRANSFER, any, vk::DependencyFlags::empty(), &[], &[], &post);
                }
                Method::EasuRcas => {
                    let compute = vk::PipelineStageFlags::COMPUTE_SHADER;
                    let pre = [
                        image_barrier(app.ours, vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL, vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL, color, vk::AccessFlags::SHADER_READ, layers, mips),
                        // The intermediates' old contents are not needed (earlier upscales on
                        // this queue finished with them: the barrier waits for all commands).
                        image_barrier(self.a.0, vk::ImageLayout::UNDEFINED, vk::ImageLayout::GENERAL, vk::AccessFlags::SHADER_READ, vk::AccessFlags::SHADER_WRITE, layers, 1),
                        image_barrier(self.b.0, vk::ImageLayout::UNDEFINED, vk::ImageLayout::GENERAL, vk::AccessFlags::TRANSFER_READ, vk::AccessFlags::SHADER_WRITE, layers, 1),
                    ];
                    f.cmd_pipeline_barrier(cb, any, compute, vk::DependencyFlags::empty(), &[], &[], &pre);
                    f.cmd_bind_pipeline(cb, vk::PipelineBindPoint::COMPUTE, p.easu);
                    for j in jobs {
                        let l = (j.layer.min(layers - 1)) as usize;
                        f.cmd_bind_descriptor_sets(cb, vk::PipelineBindPoint::COMPUTE, p.layout, 0, &[self.easu_sets[app_index][l]], &[]);
                        let params = EasuParams { src_rect: rect4(j.src), dst_rect: rect4(j.dst) };
                        f.cmd_push_constants(cb, p.layout, vk::ShaderStageFlags::COMPUTE, 0, &params.bytes());
                        let (gx, gy) = gpu::groups(j.dst.width, j.dst.height);
                        f.cmd_dispatch(cb, gx, gy, 1);
                    }
                    let mid = [image_barrier(self.a.0, vk::ImageLayout::GENERAL, vk::ImageLayout::GENERAL, vk::AccessFlags::SHADER_WRITE, vk::AccessFlags::SHADER_READ, layers, 1)];
                    f.cmd_pipeline_barrier(cb, compute, compute, vk::DependencyFlags::empty(), &[], &[], &mid);
                    f.cmd_bind_pipeline(cb, vk::PipelineBindPoint::COMPUTE, p.rcas);
                    for j in jobs {
                        let l = (j.layer.min(layers - 1)) as usize;
                        f.cmd_bind_descriptor_sets(cb, vk::PipelineBindPoint::COMPUTE, p.layout, 0, &[self.rcas_sets[l]], &[]);
                        let params = RcasParams { rect: rect4(j.dst), sharpness: [sharpness, 0.0, 0.0, 0.0] };
                        f.cmd_push_constants(cb, p.layout, vk::ShaderStageFlags::COMPUTE, 0, &params.bytes());
                        let (gx, gy) = gpu::groups(j.dst.width, j.dst.height);
                        f.cmd_dispatch(cb, gx, gy, 1);
                    }
                    let to_copy = [
                        image_barrier(self.b.0, vk::ImageLayout::GENERAL, vk::ImageLayout::TRANSFER_SRC_OPTIMAL, vk::AccessFlags::SHADER_WRITE, vk::AccessFlags::TRANSFER_READ, layers, 1),
                        image_barrier(runtime, vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL, vk::ImageLayout::TRANSFER_DST_OPTIMAL, color, vk::AccessFlags::TRANSFER_WRITE, layers, 1),
                    ];
                    f.cmd_pipeline_barrier(cb, compute | any, vk::PipelineStageFlags::TRANSFER, vk::DependencyFlags::empty(), &[], &[], &to_copy);
                    // Same size: a copy that converts the format (an sRGB image encodes).
                    let regions: Vec<vk::ImageBlit> = jobs.iter().map(|j| blit(j.dst, j.dst, j.layer)).collect();
                    f.cmd_blit_image(cb, self.b.0, vk::ImageLayout::TRANSFER_SRC_OPTIMAL, runtime, vk::ImageLayout::TRANSFER_DST_OPTIMAL, &regions, vk::Filter::NEAREST);
                    let post = [
                        image_barrier(runtime, vk::ImageLayout::TRANSFER_DST_OPTIMAL, vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL, vk::AccessFlags::TRANSFER_WRITE, vk::AccessFlags::MEMORY_READ | color, layers, 1),
                        image_barrier(app.ours, vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL, vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL, vk::AccessFlags::empty(), color, layers, mips),
                    ];
                    f.cmd_pipeline_barrier(cb, vk::PipelineStageFlags::TRANSFER | compute, any, vk::DependencyFlags::empty(), &[], &[], &post);
                }
            }
        }
    }
}

fn rect4(r: PixelRect) -> [i32; 4] {
    [r.x, r.y, r.width as i32, r.height as i32]
}

fn blit(src: PixelRect, dst: PixelRect, layer: u32) -> vk::ImageBlit {
    let corners = |r: PixelRect| [vk::Offset3D { x: r.x, y: r.y, z: 0 }, vk::Offset3D { x: r.x + r.width as i32, y: r.y + r.height as i32, z: 1 }];
    let sub = vk::ImageSubresourceLayers { aspect_mask: vk::ImageAspectFlags::COLOR, mip_level: 0, base_array_layer: layer, layer_count: 1 };
    vk::ImageBlit { src_subresource: sub, src_offsets: corners(src), dst_subresource: sub, dst_offsets: corners(dst) }
}

fn image_barrier(image: vk::Image, old: vk::ImageLayout, new: vk::ImageLayout, src: vk::AccessFlags, dst: vk::AccessFlags, layers: u32, mips: u32) -> vk::ImageMemoryBarrier<'static> {
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
}

/// Upscales in flight before an `xrEndFrame` waits: a frame submits one per swapchain (two for
/// per-eye apps), and runtimes let an app run up to about three frames ahead.
const MAX: usize = 8;
/// How long `xrEndFrame` waits for an old upscale before giving up on this one.
const WAIT_NS: u64 = 2_000_000_000;

impl Slots {
    pub(crate) fn new(d: &DeviceState, family: u32, queue_index: u32) -> Result<Slots, String> {
        // SAFETY: a valid create info for the session's queue family on a live device.
        let pool = unsafe { d.fns.create_command_pool(&vk::CommandPoolCreateInfo::default().queue_family_index(family).flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER), None) }.map_err(err("vkCreateCommandPool"))?;
        // SAFETY: the binding's queue exists (the runtime accepted the binding).
        let queue = unsafe { d.fns.get_device_queue(family, queue_index) };
        Ok(Slots { pool, ring: Default::default(), queue })
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

    /// The last `take`n buffer was not submitted: its fence would never signal.
    pub(crate) fn abandon(&mut self, d: &DeviceState) {
        if let Some((cb, fence)) = self.ring.pop_back() {
            // SAFETY: never submitted, so not in use.
            unsafe {
                d.fns.destroy_fence(fence, None);
                d.fns.free_command_buffers(self.pool, &[cb]);
            }
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
        }
    }
}
