//! `--post`: the post-processing chain engines put between the eye pass and the swapchain, built
//! so that stereoshim's data-flow walk can be proven on it. The eye pass renders into an RGBA16F
//! target (optionally multisampled, resolved by the pass); then, per slot: bloom's down- and
//! up-sample draws (`--post bloom`), and the tonemap as a full-screen draw into the swapchain
//! image (blending TAA's history with `--post taa`, which is then copied from the output), as a
//! compute dispatch into a storage image copied into it (`--post-compute`), or as the eye pass's
//! second subpass (`--post-subpass`). Images are in `images`, passes and pipelines in `pass`,
//! the recording in `record`.

mod images;
mod pass;
mod record;

pub use images::{PostImages, SlotGeometry, HDR_FORMAT};

use crate::cli::{ColorFamily, Layout, Options, PostEffect};
use crate::error::{Ctx, Result};
use crate::gpu::Gpu;
use crate::targets::Targets;
use ash::vk;
use pass::{fullscreen_pipeline, ColorPass, PipelineTarget};

const FULLSCREEN_VERT: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/fullscreen.vert.spv"));
const POST_FRAG: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/post.frag.spv"));
const POST_MV_FRAG: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/post_mv.frag.spv"));
const POST_COMP: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/post.comp.spv"));
const POST_ARRAY_COMP: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/post_array.comp.spv"));
const POST_SUBPASS_FRAG: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/post_subpass.frag.spv"));

/// The push constants of every post shader (`Push` of shaders/post_common.glsl): rects in pixels
/// and texels, as f32 pairs.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default)]
struct PostPush {
    dst_origin: [f32; 2],
    dst_size: [f32; 2],
    src_origin: [f32; 2],
    src_size: [f32; 2],
    src_scale: [f32; 2],
    src_inv_extent: [f32; 2],
    aux_origin: [f32; 2],
    aux_size: [f32; 2],
    aux_scale: [f32; 2],
    aux_inv_extent: [f32; 2],
    mode: u32,
    flags: u32,
}

const MODE_FINAL: u32 = 0;
const MODE_DOWN: u32 = 1;
const MODE_UP: u32 = 2;
const FLAG_MANUAL_SRGB: u32 = 1;
const FLAG_BGRA: u32 = 2;
const FLAG_BLOOM: u32 = 4;
const FLAG_TAA: u32 = 8;

/// One slot's descriptor sets: they name only images of the slot, never the swapchain's, so they
/// are written once and serve every frame (and `--record-once`'s command buffers).
#[derive(Default)]
struct SlotSets {
    /// The tonemap draw's: the scene, and bloom's result or TAA's history (else the scene again).
    final_set: vk::DescriptorSet,
    down: Vec<vk::DescriptorSet>,
    up: Vec<vk::DescriptorSet>,
    compute: vk::DescriptorSet,
    subpass: vk::DescriptorSet,
}

/// The chain's pipelines, passes and descriptors (its images are the slots'). Created by
/// [`crate::renderer::Renderer`] after its passes, dropped with it after the device is idle.
pub struct PostChain {
    device: ash::Device,
    effect: PostEffect,
    compute: bool,
    subpass: bool,
    /// Flags of every tonemap (draw, dispatch or subpass).
    flags: u32,
    /// The tonemap draw's pass on the swapchain image (or double-wide texture); None with
    /// `--post-compute` / `--post-subpass`.
    final_pass: Option<ColorPass>,
    /// Bloom's passes on its RGBA16F levels.
    bloom_pass: Option<ColorPass>,
    sampler: vk::Sampler,
    set_layouts: [vk::DescriptorSetLayout; 3],
    layouts: [vk::PipelineLayout; 3],
    final_pipeline: vk::Pipeline,
    bloom_pipeline: vk::Pipeline,
    compute_pipeline: vk::Pipeline,
    subpass_pipeline: vk::Pipeline,
    pool: vk::DescriptorPool,
    sets: Vec<SlotSets>,
    /// TAA's history images and their layers: cleared once at start (`record_init`).
    histories: Vec<(vk::Image, u32)>,
    /// The part of each scene eye rect drawn in the frame being recorded (`record`).
    frame_scale: f32,
}

/// `--dynamic-resolution`: the part of its sub-rect an eye pass draws in `frame`, a different
/// one in each of three consecutive frames (as an engine's dynamic resolution moves with load).
pub fn dynamic_scale(frame: u64) -> f32 {
    [1.0, 0.75, 0.875][(frame % 3) as usize]
}

/// `e` scaled by `f`, rounded, at least 1×1.
pub fn scale_extent(e: vk::Extent2D, f: f32) -> vk::Extent2D {
    vk::Extent2D { width: ((e.width as f32 * f).round() as u32).max(1), height: ((e.height as f32 * f).round() as u32).max(1) }
}

/// Indices into `set_layouts` / `layouts`.
const GRAPHICS: usize = 0;
const COMPUTE: usize = 1;
const SUBPASS: usize = 2;

impl PostChain {
    /// `scene_render_pass`: the eye pass's render pass (subpass 1 of it is `--post-subpass`'s
    /// tonemap; null with dynamic rendering).
    pub fn new(gpu: &Gpu, opts: &Options, targets: &Targets, scene_render_pass: vk::RenderPass) -> Result<PostChain> {
        let effect = opts.post.expect("PostChain without --post");
        let mut flags = match effect {
            PostEffect::Tonemap => 0,
            PostEffect::Bloom => FLAG_BLOOM,
            PostEffect::Taa => FLAG_TAA,
        };
        if opts.color_format == ColorFamily::Unorm {
            flags |= FLAG_MANUAL_SRGB;
        }
        if matches!(targets.color_format, vk::Format::B8G8R8A8_SRGB | vk::Format::B8G8R8A8_UNORM) {
            flags |= FLAG_BGRA;
        }
        let mut chain = PostChain {
            device: gpu.device.clone(),
            effect,
            compute: opts.post_compute,
            subpass: opts.post_subpass,
            flags,
            final_pass: None,
            bloom_pass: None,
            sampler: vk::Sampler::null(),
            set_layouts: [vk::DescriptorSetLayout::null(); 3],
            layouts: [vk::PipelineLayout::null(); 3],
            final_pipeline: vk::Pipeline::null(),
            bloom_pipeline: vk::Pipeline::null(),
            compute_pipeline: vk::Pipeline::null(),
            subpass_pipeline: vk::Pipeline::null(),
            pool: vk::DescriptorPool::null(),
            sets: Vec::new(),
            histories: targets.slots.iter().filter_map(|s| s.post.as_ref()?.history.as_ref().map(|h| (h.image, s.final_layers()))).collect(),
            frame_scale: 1.0,
        };
        // On failure `chain` drops here and destroys what was made.
        chain.create_layouts(gpu)?;
        chain.create_pipelines(gpu, opts, targets, scene_render_pass)?;
        chain.write_sets(gpu, targets)?;
        Ok(chain)
    }

    fn create_layouts(&mut self, gpu: &Gpu) -> Result<()> {
        let d = &gpu.device;
        let binding = |b: u32, ty: vk::DescriptorType, stage: vk::ShaderStageFlags| {
            vk::DescriptorSetLayoutBinding::default().binding(b).descriptor_type(ty).descriptor_count(1).stage_flags(stage)
        };
        let fs = vk::ShaderStageFlags::FRAGMENT;
        let cs = vk::ShaderStageFlags::COMPUTE;
        let sets: [Vec<vk::DescriptorSetLayoutBinding>; 3] = [
            vec![binding(0, vk::DescriptorType::COMBINED_IMAGE_SAMPLER, fs), binding(1, vk::DescriptorType::COMBINED_IMAGE_SAMPLER, fs)],
            vec![binding(0, vk::DescriptorType::SAMPLED_IMAGE, cs), binding(1, vk::DescriptorType::STORAGE_IMAGE, cs)],
            vec![binding(0, vk::DescriptorType::INPUT_ATTACHMENT, fs)],
        ];
        let stages = [fs, cs, fs];
        // SAFETY: plain object creation on a live device; `Drop` destroys them.
        unsafe {
            // Linear for bloom's taps; the tonemap's own reads are texelFetch, which ignores it.
            let info = vk::SamplerCreateInfo::default()
                .mag_filter(vk::Filter::LINEAR)
                .min_filter(vk::Filter::LINEAR)
                .mipmap_mode(vk::SamplerMipmapMode::NEAREST)
                .address_mode_u(vk::SamplerAddressMode::CLAMP_TO_EDGE)
                .address_mode_v(vk::SamplerAddressMode::CLAMP_TO_EDGE)
                .address_mode_w(vk::SamplerAddressMode::CLAMP_TO_EDGE)
                .max_lod(0.0);
            self.sampler = d.create_sampler(&info, None).ctx("vkCreateSampler")?;
            for i in 0..3 {
                self.set_layouts[i] = d.create_descriptor_set_layout(&vk::DescriptorSetLayoutCreateInfo::default().bindings(&sets[i]), None).ctx("vkCreateDescriptorSetLayout(post)")?;
                let ranges = [vk::PushConstantRange { stage_flags: stages[i], offset: 0, size: std::mem::size_of::<PostPush>() as u32 }];
                let set_layouts = [self.set_layouts[i]];
                self.layouts[i] = d
                    .create_pipeline_layout(&vk::PipelineLayoutCreateInfo::default().set_layouts(&set_layouts).push_constant_ranges(&ranges), None)
                    .ctx("vkCreatePipelineLayout(post)")?;
            }
        }
        Ok(())
    }

    fn create_pipelines(&mut self, gpu: &Gpu, opts: &Options, targets: &Targets, scene_render_pass: vk::RenderPass) -> Result<()> {
        let d = &gpu.device;
        let multiview = opts.layout == Layout::Multiview;
        let view_mask = if multiview { 0b11 } else { 0 };
        let clear_depth = if opts.depth == crate::cli::DepthMode::Reverse { 0.0 } else { 1.0 };
        let module = |bytes| crate::renderer::shader_module(d, bytes, opts.vulkan_api);
        if self.compute {
            let cs = module(if multiview { POST_ARRAY_COMP } else { POST_COMP })?;
            let stage = vk::PipelineShaderStageCreateInfo::default().stage(vk::ShaderStageFlags::COMPUTE).module(cs).name(c"main");
            let info = vk::ComputePipelineCreateInfo::default().stage(stage).layout(self.layouts[COMPUTE]);
            // SAFETY: valid create info; the module is destroyed once the pipeline exists.
            let r = unsafe { d.create_compute_pipelines(vk::PipelineCache::null(), &[info], None) };
            // SAFETY: no longer needed by anything.
            unsafe { d.destroy_shader_module(cs, None) };
            self.compute_pipeline = r.map_err(|(_, e)| e).ctx("vkCreateComputePipelines(post)")?[0];
        }
        let vert = module(FULLSCREEN_VERT)?;
        let result = (|| -> Result<()> {
            if self.subpass {
                let frag = module(POST_SUBPASS_FRAG)?;
                let target = PipelineTarget { render_pass: scene_render_pass, subpass: 1, color: targets.color_format, depth: None, view_mask };
                let r = fullscreen_pipeline(d, self.layouts[SUBPASS], vert, frag, &target);
                // SAFETY: no longer needed by anything.
                unsafe { d.destroy_shader_module(frag, None) };
                self.subpass_pipeline = r?;
            }
            let needs_draws = !self.compute && !self.subpass;
            if needs_draws || self.effect == PostEffect::Bloom {
                let frag = module(if multiview { POST_MV_FRAG } else { POST_FRAG })?;
                let r = (|| -> Result<()> {
                    if needs_draws {
                        let depth = opts.post_depth_attachment.then(|| images::final_depth_format(gpu));
                        let p = self.final_pass.insert(ColorPass::new(gpu, opts.rendering, targets.color_format, depth, clear_depth, view_mask)?);
                        self.final_pipeline = p.pipeline(self.layouts[GRAPHICS], vert, frag)?;
                    }
                    if self.effect == PostEffect::Bloom {
                        let p = self.bloom_pass.insert(ColorPass::new(gpu, opts.rendering, HDR_FORMAT, None, clear_depth, view_mask)?);
                        self.bloom_pipeline = p.pipeline(self.layouts[GRAPHICS], vert, frag)?;
                    }
                    Ok(())
                })();
                // SAFETY: no longer needed by anything.
                unsafe { d.destroy_shader_module(frag, None) };
                r?;
            }
            Ok(())
        })();
        // SAFETY: no longer needed by anything.
        unsafe { d.destroy_shader_module(vert, None) };
        result
    }

    /// Allocates and writes every slot's descriptor sets.
    fn write_sets(&mut self, gpu: &Gpu, targets: &Targets) -> Result<()> {
        let d = &gpu.device;
        let n = targets.slots.len() as u32;
        let size = |ty, count: u32| vk::DescriptorPoolSize { ty, descriptor_count: count.max(1) };
        let sizes = [
            size(vk::DescriptorType::COMBINED_IMAGE_SAMPLER, n * 2 * (1 + 2 * images::BLOOM_LEVELS as u32)),
            size(vk::DescriptorType::SAMPLED_IMAGE, n),
            size(vk::DescriptorType::STORAGE_IMAGE, n),
            size(vk::DescriptorType::INPUT_ATTACHMENT, n),
        ];
        // SAFETY: plain object creation; the sets are written with views of live images in the
        // layouts the recorded barriers put them in when they are read.
        unsafe {
            self.pool = d
                .create_descriptor_pool(&vk::DescriptorPoolCreateInfo::default().max_sets(n * (4 + 2 * images::BLOOM_LEVELS as u32)).pool_sizes(&sizes), None)
                .ctx("vkCreateDescriptorPool(post)")?;
            for slot in &targets.slots {
                let p = slot.post.as_ref().expect("a slot without post images");
                let mut sets = SlotSets::default();
                let alloc = |layout: vk::DescriptorSetLayout| -> Result<vk::DescriptorSet> {
                    let layouts = [layout];
                    Ok(d.allocate_descriptor_sets(&vk::DescriptorSetAllocateInfo::default().descriptor_pool(self.pool).set_layouts(&layouts))
                        .ctx("vkAllocateDescriptorSets(post)")?[0])
                };
                let pair = |src: vk::ImageView, aux: vk::ImageView| -> Result<vk::DescriptorSet> {
                    let set = alloc(self.set_layouts[GRAPHICS])?;
                    let info = |v| [vk::DescriptorImageInfo { sampler: self.sampler, image_view: v, image_layout: vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL }];
                    let (a, b) = (info(src), info(aux));
                    let writes = [
                        vk::WriteDescriptorSet::default().dst_set(set).dst_binding(0).descriptor_type(vk::DescriptorType::COMBINED_IMAGE_SAMPLER).image_info(&a),
                        vk::WriteDescriptorSet::default().dst_set(set).dst_binding(1).descriptor_type(vk::DescriptorType::COMBINED_IMAGE_SAMPLER).image_info(&b),
                    ];
                    d.update_descriptor_sets(&writes, &[]);
                    Ok(set)
                };
                let scene = p.scene.view;
                for k in 0..p.down.len() {
                    let src = if k == 0 { scene } else { p.down[k - 1].image.view };
                    sets.down.push(pair(src, src)?);
                }
                for k in 0..p.up.len() {
                    let src = if k + 1 == p.up.len() { p.down[k + 1].image.view } else { p.up[k + 1].image.view };
                    sets.up.push(pair(src, p.down[k].image.view)?);
                }
                if self.final_pass.is_some() {
                    let aux = match self.effect {
                        PostEffect::Bloom => p.up[0].image.view,
                        PostEffect::Taa => p.history.as_ref().expect("history").view,
                        PostEffect::Tonemap => scene,
                    };
                    sets.final_set = pair(scene, aux)?;
                }
                if let Some(storage) = &p.storage {
                    let set = alloc(self.set_layouts[COMPUTE])?;
                    let a = [vk::DescriptorImageInfo { sampler: vk::Sampler::null(), image_view: scene, image_layout: vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL }];
                    let b = [vk::DescriptorImageInfo { sampler: vk::Sampler::null(), image_view: storage.view, image_layout: vk::ImageLayout::GENERAL }];
                    let writes = [
                        vk::WriteDescriptorSet::default().dst_set(set).dst_binding(0).descriptor_type(vk::DescriptorType::SAMPLED_IMAGE).image_info(&a),
                        vk::WriteDescriptorSet::default().dst_set(set).dst_binding(1).descriptor_type(vk::DescriptorType::STORAGE_IMAGE).image_info(&b),
                    ];
                    d.update_descriptor_sets(&writes, &[]);
                    sets.compute = set;
                }
                if self.subpass {
                    let set = alloc(self.set_layouts[SUBPASS])?;
                    let a = [vk::DescriptorImageInfo { sampler: vk::Sampler::null(), image_view: scene, image_layout: vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL }];
                    let writes = [vk::WriteDescriptorSet::default().dst_set(set).dst_binding(0).descriptor_type(vk::DescriptorType::INPUT_ATTACHMENT).image_info(&a)];
                    d.update_descriptor_sets(&writes, &[]);
                    sets.subpass = set;
                }
                self.sets.push(sets);
            }
        }
        Ok(())
    }
}

impl Drop for PostChain {
    fn drop(&mut self) {
        let d = &self.device;
        // SAFETY: the owner waited for the device to go idle; null handles are ignored; sets go
        // with their pool.
        unsafe {
            for p in [self.final_pipeline, self.bloom_pipeline, self.compute_pipeline, self.subpass_pipeline] {
                d.destroy_pipeline(p, None);
            }
            for l in self.layouts {
                d.destroy_pipeline_layout(l, None);
            }
            for l in self.set_layouts {
                d.destroy_descriptor_set_layout(l, None);
            }
            d.destroy_descriptor_pool(self.pool, None);
            d.destroy_sampler(self.sampler, None);
        }
    }
}
