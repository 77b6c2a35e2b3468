//! The post chain's images of one slot (`Slot::post`) and where each view lies in them: the
//! eye pass's RGBA16F target (and its multisampled colour), bloom's down- and up-sample levels,
//! TAA's history, `--post-compute`'s storage image and `--post-depth-attachment`'s depth.

use crate::cli::{Options, PostEffect};
use crate::error::Result;
use crate::gpu::Gpu;
use crate::targets::OwnedImage;
use ash::vk;

/// The eye pass's colour format with `--post`: HDR, as engines render before tonemapping.
pub const HDR_FORMAT: vk::Format = vk::Format::R16G16B16A16_SFLOAT;
/// `--post-compute`'s storage image: plain bytes, copied into the swapchain image as they are.
pub const STORAGE_FORMAT: vk::Format = vk::Format::R8G8B8A8_UNORM;
/// Bloom's down-sample levels: half, quarter and eighth of the eye pass's rect.
pub const BLOOM_LEVELS: usize = 3;

/// A rect of an image: x offset (rects start at y = 0) and size.
pub type EyeRect = (i32, vk::Extent2D);

/// Where one slot's views lie: one entry per draw (per-eye: one; side-by-side: one per eye,
/// left first; multiview: one for both layers).
#[derive(Debug, Clone)]
pub struct SlotGeometry {
    pub scene_extent: vk::Extent2D,
    /// The eye pass's layers (2: multiview), which every image of the chain has too.
    pub layers: u32,
    /// Each view's rect in the eye pass's target (its viewport).
    pub scene_eyes: Vec<EyeRect>,
    /// The image the chain writes last (the swapchain image or the double-wide texture).
    pub final_extent: vk::Extent2D,
    pub final_layers: u32,
    /// Each view's rect in it.
    pub final_eyes: Vec<EyeRect>,
}

/// One bloom level: its image and each view's rect in it (side by side in one image when the
/// eye pass is side by side).
pub struct Level {
    pub image: OwnedImage,
    pub extent: vk::Extent2D,
    pub layers: u32,
    pub eyes: Vec<EyeRect>,
}

pub struct PostImages {
    pub geometry: SlotGeometry,
    /// Single-sampled HDR: the eye pass's colour attachment, or its resolve attachment.
    pub scene: OwnedImage,
    /// `--samples N>1`: the eye pass's multisampled colour.
    pub scene_msaa: Option<OwnedImage>,
    pub down: Vec<Level>,
    pub up: Vec<Level>,
    /// `--post taa`: last frame's output (swapchain format, final size).
    pub history: Option<OwnedImage>,
    pub storage: Option<OwnedImage>,
    pub final_depth: Option<OwnedImage>,
}

impl PostImages {
    pub fn new(gpu: &Gpu, opts: &Options, effect: PostEffect, color_format: vk::Format, samples: vk::SampleCountFlags, geometry: SlotGeometry) -> Result<PostImages> {
        let one = vk::SampleCountFlags::TYPE_1;
        let color = vk::ImageAspectFlags::COLOR;
        let mut scene_usage = vk::ImageUsageFlags::COLOR_ATTACHMENT | vk::ImageUsageFlags::SAMPLED;
        if opts.post_subpass {
            scene_usage |= vk::ImageUsageFlags::INPUT_ATTACHMENT;
        }
        let (g, layers) = (&geometry, geometry.layers);
        let scene = OwnedImage::new(gpu, HDR_FORMAT, g.scene_extent, layers, one, scene_usage, color)?;
        let mut p = PostImages { geometry: g.clone(), scene, scene_msaa: None, down: Vec::new(), up: Vec::new(), history: None, storage: None, final_depth: None };
        if let Err(e) = p.fill(gpu, opts, effect, color_format, samples) {
            p.destroy(&gpu.device);
            return Err(e);
        }
        Ok(p)
    }

    /// Everything but the scene target, into `self` as it is made (so `destroy` frees a partial
    /// set).
    fn fill(&mut self, gpu: &Gpu, opts: &Options, effect: PostEffect, color_format: vk::Format, samples: vk::SampleCountFlags) -> Result<()> {
        let one = vk::SampleCountFlags::TYPE_1;
        let color = vk::ImageAspectFlags::COLOR;
        let g = self.geometry.clone();
        if samples != one {
            self.scene_msaa = Some(OwnedImage::new(gpu, HDR_FORMAT, g.scene_extent, g.layers, samples, vk::ImageUsageFlags::COLOR_ATTACHMENT, color)?);
        }
        if effect == PostEffect::Bloom {
            let usage = vk::ImageUsageFlags::COLOR_ATTACHMENT | vk::ImageUsageFlags::SAMPLED;
            for k in 0..BLOOM_LEVELS {
                let (extent, eyes) = level_geometry(&g.scene_eyes, k);
                self.down.push(Level { image: OwnedImage::new(gpu, HDR_FORMAT, extent, g.layers, one, usage, color)?, extent, layers: g.layers, eyes: eyes.clone() });
                // The up-sample chain ends one level above the smallest (which it starts from).
                if k + 1 < BLOOM_LEVELS {
                    self.up.push(Level { image: OwnedImage::new(gpu, HDR_FORMAT, extent, g.layers, one, usage, color)?, extent, layers: g.layers, eyes });
                }
            }
        }
        if effect == PostEffect::Taa {
            let usage = vk::ImageUsageFlags::SAMPLED | vk::ImageUsageFlags::TRANSFER_DST;
            self.history = Some(OwnedImage::new(gpu, color_format, g.final_extent, g.final_layers, one, usage, color)?);
        }
        if opts.post_compute {
            let usage = vk::ImageUsageFlags::STORAGE | vk::ImageUsageFlags::TRANSFER_SRC;
            self.storage = Some(OwnedImage::new(gpu, STORAGE_FORMAT, g.final_extent, g.final_layers, one, usage, color)?);
        }
        if opts.post_depth_attachment {
            let f = final_depth_format(gpu);
            let usage = vk::ImageUsageFlags::DEPTH_STENCIL_ATTACHMENT;
            self.final_depth = Some(OwnedImage::new(gpu, f, g.final_extent, g.final_layers, one, usage, vk::ImageAspectFlags::DEPTH)?);
        }
        Ok(())
    }

    /// Every image, for barriers that treat them alike.
    pub fn levels(&self) -> impl Iterator<Item = &Level> {
        self.down.iter().chain(&self.up)
    }

    pub fn destroy(&mut self, d: &ash::Device) {
        self.scene.destroy(d);
        for i in self.scene_msaa.iter_mut().chain(&mut self.history).chain(&mut self.storage).chain(&mut self.final_depth) {
            i.destroy(d);
        }
        for l in self.down.iter_mut().chain(&mut self.up) {
            l.image.destroy(d);
        }
        self.scene_msaa = None;
        self.history = None;
        self.storage = None;
        self.final_depth = None;
        self.down.clear();
        self.up.clear();
    }
}

/// `--post-depth-attachment`: a depth-only format (no stencil aspect to describe): D32_SFLOAT
/// where it can be an attachment, else D16_UNORM, which every device supports.
pub fn final_depth_format(gpu: &Gpu) -> vk::Format {
    if gpu.format_supports(vk::Format::D32_SFLOAT, vk::FormatFeatureFlags::DEPTH_STENCIL_ATTACHMENT) {
        vk::Format::D32_SFLOAT
    } else {
        vk::Format::D16_UNORM
    }
}

/// Bloom level `k` (0: half size) of the eye pass's rects: each view's rect halved k + 1 times
/// (at least 1 pixel), the views side by side when there are two, and the image's extent.
fn level_geometry(scene_eyes: &[EyeRect], k: usize) -> (vk::Extent2D, Vec<EyeRect>) {
    let shrink = |v: u32| (v >> (k + 1)).max(1);
    let sizes: Vec<vk::Extent2D> = scene_eyes.iter().map(|(_, e)| vk::Extent2D { width: shrink(e.width), height: shrink(e.height) }).collect();
    let mut x = 0;
    let mut eyes = Vec::new();
    for s in &sizes {
        eyes.push((x, *s));
        x += s.width as i32;
    }
    let extent = vk::Extent2D { width: x as u32, height: sizes.iter().map(|s| s.height).max().unwrap_or(1) };
    (extent, eyes)
}
