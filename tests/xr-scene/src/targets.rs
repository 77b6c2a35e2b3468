//! Render targets: the colour (and depth) swapchains of the chosen layout, their image views, and
//! the app-owned images (multisampled intermediate colour, private depth, `--post`'s chain,
//! `--submit-texture double-wide`'s texture) the passes draw into. Three sets of rects per view:
//! where it is submitted (`views`), where the eye pass draws it (`scene_views`, scaled by
//! `--render-scale` / `--viewport-scale`) and where the last pass before any blit writes it
//! (`final_views`: the double-wide texture's halves, else the submitted rects). The colour
//! swapchain may be multisampled (`--swapchain-samples`: the eye pass renders into it, with depth
//! of the same count) or have a mip chain (`--swapchain-mips`: only level 0 is viewed and drawn).
//! Per eye, the colour swapchain is one per eye, or (`--eye-swapchain array`) one 2-layer
//! swapchain the first slot owns and both slots view a layer of.

use crate::cli::{EyeSwapchain, Layout, Options};
use crate::error::{fail, Ctx, Result};
use crate::gpu::Gpu;
use crate::xr::{pick_color_format, XrInstance, XrSession, DEPTH_FORMATS};
use ash::vk;
use openxr as xr;

/// An image the app allocates itself.
pub struct OwnedImage {
    pub image: vk::Image,
    pub memory: vk::DeviceMemory,
    pub view: vk::ImageView,
}

impl OwnedImage {
    pub fn new(
        gpu: &Gpu,
        format: vk::Format,
        extent: vk::Extent2D,
        layers: u32,
        samples: vk::SampleCountFlags,
        usage: vk::ImageUsageFlags,
        aspect: vk::ImageAspectFlags,
    ) -> Result<OwnedImage> {
        let d = &gpu.device;
        let info = vk::ImageCreateInfo::default()
            .image_type(vk::ImageType::TYPE_2D)
            .format(format)
            .extent(vk::Extent3D { width: extent.width, height: extent.height, depth: 1 })
            .mip_levels(1)
            .array_layers(layers)
            .samples(samples)
            .tiling(vk::ImageTiling::OPTIMAL)
            .usage(usage)
            .initial_layout(vk::ImageLayout::UNDEFINED);
        // SAFETY: valid create info on a live device; on failure nothing leaks beyond what's destroyed here.
        unsafe {
            let image = d.create_image(&info, None).ctx("vkCreateImage")?;
            let req = d.get_image_memory_requirements(image);
            let ty = match gpu.memory_type(req.memory_type_bits, vk::MemoryPropertyFlags::DEVICE_LOCAL) {
                Ok(t) => t,
                Err(e) => {
                    d.destroy_image(image, None);
                    return Err(e);
                }
            };
            let memory = match d.allocate_memory(
                &vk::MemoryAllocateInfo::default().allocation_size(req.size).memory_type_index(ty),
                None,
            ) {
                Ok(m) => m,
                Err(e) => {
                    d.destroy_image(image, None);
                    return Err(e).ctx("vkAllocateMemory");
                }
            };
            let mut img = OwnedImage { image, memory, view: vk::ImageView::null() };
            if let Err(e) = d.bind_image_memory(image, memory, 0) {
                img.destroy(d);
                return Err(e).ctx("vkBindImageMemory");
            }
            match create_view(d, image, format, 0, layers, aspect) {
                Ok(v) => img.view = v,
                Err(e) => {
                    img.destroy(d);
                    return Err(e);
                }
            }
            Ok(img)
        }
    }

    pub fn destroy(&mut self, d: &ash::Device) {
        // SAFETY: the device is idle (callers wait) and these handles are ours.
        unsafe {
            d.destroy_image_view(self.view, None);
            d.destroy_image(self.image, None);
            d.free_memory(self.memory, None);
        }
    }
}

/// A view of level 0 of `layers` array layers from `base_layer`.
fn create_view(
    d: &ash::Device,
    image: vk::Image,
    format: vk::Format,
    base_layer: u32,
    layers: u32,
    aspect: vk::ImageAspectFlags,
) -> Result<vk::ImageView> {
    let info = vk::ImageViewCreateInfo::default()
        .image(image)
        .view_type(if layers > 1 { vk::ImageViewType::TYPE_2D_ARRAY } else { vk::ImageViewType::TYPE_2D })
        .format(format)
        .subresource_range(vk::ImageSubresourceRange {
            aspect_mask: aspect,
            base_mip_level: 0,
            level_count: 1,
            base_array_layer: base_layer,
            layer_count: layers,
        });
    // SAFETY: valid image of this device.
    unsafe { d.create_image_view(&info, None) }.ctx("vkCreateImageView")
}

pub fn depth_aspect(format: vk::Format) -> vk::ImageAspectFlags {
    match format {
        vk::Format::D24_UNORM_S8_UINT | vk::Format::D32_SFLOAT_S8_UINT | vk::Format::D16_UNORM_S8_UINT => {
            vk::ImageAspectFlags::DEPTH | vk::ImageAspectFlags::STENCIL
        }
        _ => vk::ImageAspectFlags::DEPTH,
    }
}

pub struct Chain {
    /// None: the images are another slot's swapchain's (`--eye-swapchain array`: the first
    /// slot owns the 2-layer swapchain; this slot acquires and releases nothing of its own).
    pub swapchain: Option<xr::Swapchain<xr::Vulkan>>,
    pub images: Vec<vk::Image>,
    /// This slot's views of each image: all its layers, or with `--eye-swapchain array` the
    /// slot's own layer alone, so that the passes (and their layout transitions) touch only it.
    pub views: Vec<vk::ImageView>,
}

impl Chain {
    /// The swapchain of a chain that owns it, as every depth chain does (`--eye-swapchain
    /// array` shares colour only, and refuses `--submit-depth`).
    pub fn owned(&mut self) -> &mut xr::Swapchain<xr::Vulkan> {
        self.swapchain.as_mut().expect("a depth chain owns its swapchain")
    }
}

/// Everything one render pass instance draws into: one per eye for per-eye, one otherwise.
pub struct Slot {
    /// The colour swapchain's size and array layers (2 for the multiview array and for
    /// `--submit-texture double-wide`, else 1).
    pub extent: vk::Extent2D,
    pub layers: u32,
    /// The first array layer of the colour swapchain's images that this slot writes: eye v's
    /// layer with `--eye-swapchain array` (where `layers` is 1 of the image's 2), else 0.
    pub color_layer: u32,
    /// The eye pass's target: its size (the swapchain's, or the double-wide texture's, times
    /// `--render-scale`) and layers.
    pub scene_extent: vk::Extent2D,
    pub scene_layers: u32,
    /// `--submit-texture double-wide`: the app's own double-wide texture (swapchain format), which
    /// the last pass writes and the blits read.
    pub double_wide: Option<OwnedImage>,
    /// `--post`: the chain's images.
    pub post: Option<crate::post::PostImages>,
    pub color: Chain,
    pub depth: Option<Chain>,
    /// Multisampled (or single-sampled) offscreen colour with `--intermediate` (with
    /// `--one-target` the first slot's only: `Targets::offscreen_of` finds it for both).
    pub offscreen: Option<OwnedImage>,
    /// The app's own depth buffer when depth is not submitted.
    pub own_depth: Option<OwnedImage>,
}

/// Where a view's pixels are: which slot, which array layer, which rectangle.
#[derive(Debug, Clone, Copy)]
pub struct ViewRect {
    pub slot: usize,
    pub array_index: u32,
    pub offset_x: i32,
    pub extent: vk::Extent2D,
}

impl ViewRect {
    /// The same rect, its extent scaled by `f` from its top left (`--dynamic-resolution`).
    pub fn scaled(self, f: f32) -> ViewRect {
        ViewRect { extent: crate::post::scale_extent(self.extent, f), ..self }
    }
}

impl Slot {
    /// The image the frame's last pass (or copy) writes before any blit, with its view, size and
    /// layers: the double-wide texture, else the acquired swapchain image.
    pub fn final_image(&self, acquired_color: u32) -> (vk::Image, vk::ImageView, vk::Extent2D, u32) {
        match &self.double_wide {
            Some(dw) => (dw.image, dw.view, self.final_extent(), 1),
            None => (self.color.images[acquired_color as usize], self.color.views[acquired_color as usize], self.extent, self.layers),
        }
    }

    pub fn final_extent(&self) -> vk::Extent2D {
        match &self.double_wide {
            Some(_) => vk::Extent2D { width: self.extent.width * 2, height: self.extent.height },
            None => self.extent,
        }
    }

    /// The first array layer of the final image that this slot's `final_layers` start at.
    pub fn final_layer(&self) -> u32 {
        if self.double_wide.is_some() {
            0
        } else {
            self.color_layer
        }
    }

    pub fn final_layers(&self) -> u32 {
        if self.double_wide.is_some() {
            1
        } else {
            self.layers
        }
    }
}

pub struct Targets {
    device: ash::Device,
    pub slots: Vec<Slot>,
    /// Where each view is submitted (`XrSwapchainSubImage`).
    pub views: [ViewRect; 2],
    /// Where the eye pass draws each view (its viewport): `views`, or their place in the double-
    /// wide texture, scaled by `--render-scale` and `--viewport-scale`.
    pub scene_views: [ViewRect; 2],
    /// Where the last pass writes each view: the double-wide texture's halves, else `views`.
    pub final_views: [ViewRect; 2],
    pub color_format: vk::Format,
    pub depth_format: vk::Format,
    pub samples: vk::SampleCountFlags,
    /// The XR swapchains were destroyed with the frame's work in flight
    /// (`destroy_swapchains_in_flight`): only the Vulkan objects are left.
    swapchains_gone: bool,
}

/// What `push_slot` makes: the swapchain's size and layers, the eye pass's target's, and each
/// view's (x offset, size) in that target and in the image the frame's last pass writes (one
/// entry per view drawn separately; multiview's one entry covers both layers).
struct SlotShape {
    extent: vk::Extent2D,
    layers: u32,
    scene_extent: vk::Extent2D,
    scene_layers: u32,
    scene_eyes: Vec<(i32, vk::Extent2D)>,
    final_eyes: Vec<(i32, vk::Extent2D)>,
    /// `--eye-swapchain array`: the layer of the shared 2-layer colour swapchain this slot writes
    /// (layer 0's slot creates it, the next one views the same images).
    array_layer: Option<u32>,
}

/// What a swapchain is made of besides format and usage: size, layers, `sampleCount`, `mipCount`.
#[derive(Debug, Clone, Copy)]
struct ChainShape {
    extent: vk::Extent2D,
    layers: u32,
    samples: u32,
    mips: u32,
}

fn scaled(v: u32, scale: f32, max: u32) -> u32 {
    ((v as f32 * scale).round() as u32).max(16).min(max.max(16))
}

impl Targets {
    pub fn new(opts: &Options, gpu: &Gpu, xri: &XrInstance, xs: &XrSession) -> Result<Targets> {
        let mut t = Targets {
            device: gpu.device.clone(),
            slots: Vec::new(),
            views: [ViewRect { slot: 0, array_index: 0, offset_x: 0, extent: vk::Extent2D::default() }; 2],
            scene_views: [ViewRect { slot: 0, array_index: 0, offset_x: 0, extent: vk::Extent2D::default() }; 2],
            final_views: [ViewRect { slot: 0, array_index: 0, offset_x: 0, extent: vk::Extent2D::default() }; 2],
            color_format: vk::Format::UNDEFINED,
            depth_format: vk::Format::UNDEFINED,
            samples: vk::SampleCountFlags::from_raw(opts.samples),
            swapchains_gone: false,
        };
        t.build(opts, gpu, xri, xs)?;
        Ok(t)
    }

    fn build(&mut self, opts: &Options, gpu: &Gpu, xri: &XrInstance, xs: &XrSession) -> Result<()> {
        let offered = xs.session.enumerate_swapchain_formats().ctx("xrEnumerateSwapchainFormats")?;
        let srgb = opts.color_format == crate::cli::ColorFamily::Srgb;
        let color_raw = pick_color_format(&offered, srgb)
            .ok_or_else(|| crate::error::Error(format!("the runtime offers no {:?} colour format in {offered:?}", opts.color_format)))?;
        self.color_format = vk::Format::from_raw(color_raw as i32);

        let attach = vk::FormatFeatureFlags::DEPTH_STENCIL_ATTACHMENT;
        self.depth_format = if opts.submit_depth {
            // D32_SFLOAT if the runtime offers it, else the runtime's first offered depth format.
            let usable = |f: &vk::Format| offered.contains(&(f.as_raw() as u32)) && gpu.format_supports(*f, attach);
            if usable(&vk::Format::D32_SFLOAT) {
                vk::Format::D32_SFLOAT
            } else {
                offered
                    .iter()
                    .map(|f| vk::Format::from_raw(*f as i32))
                    .find(|f| DEPTH_FORMATS.contains(f) && usable(f))
                    .ok_or_else(|| crate::error::Error(format!("the runtime offers no usable depth format in {offered:?}")))?
            }
        } else {
            *DEPTH_FORMATS
                .iter()
                .find(|f| gpu.format_supports(**f, attach))
                .ok_or_else(|| crate::error::Error("no depth format is supported".into()))?
        };

        let limits = &gpu.props.limits;
        let device_has_samples =
            limits.framebuffer_color_sample_counts.contains(self.samples) && limits.framebuffer_depth_sample_counts.contains(self.samples);
        if opts.intermediate && !device_has_samples {
            return fail(format!("--samples {} is not supported by the device", opts.samples));
        }
        let vc = &xri.view_config;
        if opts.swapchain_samples > 1 {
            // The eye pass renders colour and depth at the swapchain's count: both must exist.
            if !device_has_samples {
                return fail(format!(
                    "--swapchain-samples {}: the device renders colour at {:?} and depth at {:?} samples",
                    opts.swapchain_samples, limits.framebuffer_color_sample_counts, limits.framebuffer_depth_sample_counts
                ));
            }
            let max = vc.iter().map(|v| v.max_swapchain_sample_count).min().unwrap_or(1);
            if opts.swapchain_samples > max {
                return fail(format!("--swapchain-samples {}: the runtime's maxSwapchainSampleCount is {max}", opts.swapchain_samples));
            }
        }

        let size = |v: usize| {
            vk::Extent2D {
                width: scaled(vc[v].recommended_image_rect_width, opts.scale, vc[v].max_image_rect_width),
                height: scaled(vc[v].recommended_image_rect_height, opts.scale, vc[v].max_image_rect_height),
            }
        };
        // Layouts that share one image need one size for both eyes.
        let shared = vk::Extent2D {
            width: size(0).width.max(size(1).width),
            height: size(0).height.max(size(1).height),
        };
        // The eye pass's target is the swapchain's size times `--render-scale`, and each view is
        // drawn into `--viewport-scale` of its part of it (top left, as DLSS-style engines do).
        let by = |e: vk::Extent2D, f: f32| vk::Extent2D {
            width: ((e.width as f32 * f).round() as u32).max(1),
            height: ((e.height as f32 * f).round() as u32).max(1),
        };
        let target = |e: vk::Extent2D| by(e, opts.render_scale);
        let drawn = |e: vk::Extent2D| by(target(e), opts.viewport_scale);
        let double_wide = opts.submit_texture == Some(crate::cli::SubmitTexture::DoubleWide);
        match opts.layout {
            Layout::PerEye if opts.eye_swapchain == EyeSwapchain::Array => {
                // One swapchain has one size: both eyes' (as multiview's), each drawn separately.
                for v in 0..2 {
                    let (e, layer) = (shared, v as u32);
                    self.push_slot(opts, gpu, xs, SlotShape { extent: e, layers: 1, scene_extent: target(e), scene_layers: 1, scene_eyes: vec![(0, drawn(e))], final_eyes: vec![(0, e)], array_layer: Some(layer) })?;
                    self.views[v] = ViewRect { slot: v, array_index: layer, offset_x: 0, extent: e };
                    self.scene_views[v] = ViewRect { slot: v, array_index: 0, offset_x: 0, extent: drawn(e) };
                }
            }
            Layout::PerEye => {
                for v in 0..2 {
                    let e = size(v);
                    self.push_slot(opts, gpu, xs, SlotShape { extent: e, layers: 1, scene_extent: target(e), scene_layers: 1, scene_eyes: vec![(0, drawn(e))], final_eyes: vec![(0, e)], array_layer: None })?;
                    self.views[v] = ViewRect { slot: v, array_index: 0, offset_x: 0, extent: e };
                    self.scene_views[v] = ViewRect { slot: v, array_index: 0, offset_x: 0, extent: drawn(e) };
                }
            }
            Layout::Multiview => {
                self.push_slot(opts, gpu, xs, SlotShape { extent: shared, layers: 2, scene_extent: target(shared), scene_layers: 2, scene_eyes: vec![(0, drawn(shared))], final_eyes: vec![(0, shared)], array_layer: None })?;
                for v in 0..2 {
                    self.views[v] = ViewRect { slot: 0, array_index: v as u32, offset_x: 0, extent: shared };
                    self.scene_views[v] = ViewRect { slot: 0, array_index: v as u32, offset_x: 0, extent: drawn(shared) };
                }
            }
            Layout::SideBySide => {
                // Both halves keep one size, so the target is twice one eye's scaled width.
                let eye_target = target(shared);
                let scene_extent = vk::Extent2D { width: eye_target.width * 2, height: eye_target.height };
                let scene_eyes = (0..2).map(|v| (v * eye_target.width as i32, drawn(shared))).collect();
                let final_eyes = (0..2).map(|v| (v * shared.width as i32, shared)).collect();
                let wide = vk::Extent2D { width: shared.width * 2, height: shared.height };
                // Double-wide: the swapchain is a 2-layer array of one eye's size; the texture the
                // passes render is side by side.
                let (extent, layers) = if double_wide { (shared, 2) } else { (wide, 1) };
                self.push_slot(opts, gpu, xs, SlotShape { extent, layers, scene_extent, scene_layers: 1, scene_eyes, final_eyes, array_layer: None })?;
                for v in 0..2 {
                    let offset_x = (v as u32 * shared.width) as i32;
                    self.views[v] = match double_wide {
                        true => ViewRect { slot: 0, array_index: v as u32, offset_x: 0, extent: shared },
                        false => ViewRect { slot: 0, array_index: 0, offset_x, extent: shared },
                    };
                    self.final_views[v] = ViewRect { slot: 0, array_index: 0, offset_x, extent: shared };
                    self.scene_views[v] = ViewRect { slot: 0, array_index: 0, offset_x: v as i32 * eye_target.width as i32, extent: drawn(shared) };
                }
            }
        }
        if !double_wide {
            self.final_views = self.views;
        }
        Ok(())
    }

    fn push_slot(&mut self, opts: &Options, gpu: &Gpu, xs: &XrSession, shape: SlotShape) -> Result<()> {
        let SlotShape { extent, layers, scene_extent, scene_layers, ref scene_eyes, ref final_eyes, array_layer } = shape;
        let double_wide = opts.submit_texture.is_some();
        let mut usage = xr::SwapchainUsageFlags::COLOR_ATTACHMENT;
        // Written by a resolve, a copy or a blit; read by a copy into the TAA history.
        if opts.intermediate || opts.post_compute || double_wide {
            usage |= xr::SwapchainUsageFlags::TRANSFER_DST;
        }
        if opts.post == Some(crate::cli::PostEffect::Taa) && !double_wide {
            usage |= xr::SwapchainUsageFlags::TRANSFER_SRC;
        }
        // `--swapchain-mips`: the runtime refuses more levels than the size has; say so here.
        let full_chain = 32 - extent.width.max(extent.height).leading_zeros();
        if opts.swapchain_mips > full_chain {
            return fail(format!("--swapchain-mips {}: a {}x{} swapchain has at most {full_chain} levels", opts.swapchain_mips, extent.width, extent.height));
        }
        let color = match (array_layer, self.slots.last()) {
            // Layer 0's slot makes the 2-layer swapchain; its view of each image is layer 0.
            (Some(0), _) | (None, _) => {
                let chain_layers = if array_layer.is_some() { 2 } else { layers };
                let shape = ChainShape { extent, layers: chain_layers, samples: opts.swapchain_samples, mips: opts.swapchain_mips };
                self.chain(xs, self.color_format, usage, shape, vk::ImageAspectFlags::COLOR, 0, layers)?
            }
            // A later eye: the same images, its own views of its layer.
            (Some(layer), Some(first)) => {
                let images = first.color.images.clone();
                let mut chain = Chain { swapchain: None, images, views: Vec::new() };
                for &img in &chain.images {
                    match create_view(&self.device, img, self.color_format, layer, 1, vk::ImageAspectFlags::COLOR) {
                        Ok(v) => chain.views.push(v),
                        Err(e) => {
                            destroy_views(&self.device, &chain.views);
                            return Err(e);
                        }
                    }
                }
                chain
            }
            (Some(_), None) => return fail("internal: an array swapchain's later layer before its first"),
        };
        let mut slot = Slot {
            extent,
            layers,
            color_layer: array_layer.unwrap_or(0),
            scene_extent,
            scene_layers,
            color,
            depth: None,
            offscreen: None,
            own_depth: None,
            double_wide: None,
            post: None,
        };
        let push_and_err = |t: &mut Targets, slot: Slot, e| {
            t.slots.push(slot);
            Err(e)
        };
        // `--depth-clear image` clears the depth image with a transfer command.
        let clear_by_transfer = opts.depth_clear == crate::cli::DepthClear::Image;
        if opts.submit_depth {
            let mut depth_usage = xr::SwapchainUsageFlags::DEPTH_STENCIL_ATTACHMENT;
            if clear_by_transfer {
                depth_usage |= xr::SwapchainUsageFlags::TRANSFER_DST;
            }
            match self.chain(
                xs,
                self.depth_format,
                depth_usage,
                ChainShape { extent, layers, samples: 1, mips: 1 },
                depth_aspect(self.depth_format),
                0,
                layers,
            ) {
                Ok(c) => slot.depth = Some(c),
                Err(e) => return push_and_err(self, slot, e),
            }
        } else if !opts.one_target || self.slots.is_empty() {
            // `--one-target`: the eyes share the first eye's depth too, as engines do.
            match OwnedImage::new(
                gpu,
                self.depth_format,
                scene_extent,
                scene_layers,
                self.samples,
                if clear_by_transfer {
                    vk::ImageUsageFlags::DEPTH_STENCIL_ATTACHMENT | vk::ImageUsageFlags::TRANSFER_DST
                } else {
                    vk::ImageUsageFlags::DEPTH_STENCIL_ATTACHMENT
                },
                depth_aspect(self.depth_format),
            ) {
                Ok(i) => slot.own_depth = Some(i),
                Err(e) => return push_and_err(self, slot, e),
            }
        }
        // `--one-target`: the second eye renders into the first eye's offscreen target.
        let shares_the_first = opts.one_target && !self.slots.is_empty();
        if opts.intermediate && !shares_the_first {
            match OwnedImage::new(
                gpu,
                self.color_format,
                scene_extent,
                scene_layers,
                self.samples,
                vk::ImageUsageFlags::COLOR_ATTACHMENT | vk::ImageUsageFlags::TRANSFER_SRC,
                vk::ImageAspectFlags::COLOR,
            ) {
                Ok(i) => slot.offscreen = Some(i),
                Err(e) => return push_and_err(self, slot, e),
            }
        }
        if double_wide {
            // Rendered (or post-processed, copied, resolved) into, then blitted from; the TAA
            // history is copied from it.
            let wide = vk::Extent2D { width: extent.width * 2, height: extent.height };
            let usage = vk::ImageUsageFlags::COLOR_ATTACHMENT | vk::ImageUsageFlags::TRANSFER_SRC | vk::ImageUsageFlags::TRANSFER_DST;
            match OwnedImage::new(gpu, self.color_format, wide, 1, vk::SampleCountFlags::TYPE_1, usage, vk::ImageAspectFlags::COLOR) {
                Ok(i) => slot.double_wide = Some(i),
                Err(e) => return push_and_err(self, slot, e),
            }
        }
        if let Some(effect) = opts.post {
            let shape = crate::post::SlotGeometry {
                scene_extent,
                layers: scene_layers,
                scene_eyes: scene_eyes.clone(),
                final_extent: slot.final_extent(),
                final_layers: slot.final_layers(),
                final_eyes: final_eyes.clone(),
            };
            match crate::post::PostImages::new(gpu, opts, effect, self.color_format, self.samples, shape) {
                Ok(i) => slot.post = Some(i),
                Err(e) => return push_and_err(self, slot, e),
            }
        }
        self.slots.push(slot);
        Ok(())
    }

    /// A swapchain and a view of each image's level 0 (`view_layers` of its layers from
    /// `base_layer`): what the passes render.
    #[allow(clippy::too_many_arguments)]
    fn chain(&self, xs: &XrSession, format: vk::Format, usage: xr::SwapchainUsageFlags, shape: ChainShape, aspect: vk::ImageAspectFlags, base_layer: u32, view_layers: u32) -> Result<Chain> {
        let ChainShape { extent, layers, samples, mips } = shape;
        let swapchain = xs
            .session
            .create_swapchain(&xr::SwapchainCreateInfo {
                create_flags: xr::SwapchainCreateFlags::EMPTY,
                usage_flags: usage,
                format: format.as_raw() as u32,
                sample_count: samples,
                width: extent.width,
                height: extent.height,
                face_count: 1,
                array_size: layers,
                mip_count: mips,
            })
            .ctx("xrCreateSwapchain")?;
        let images: Vec<vk::Image> = swapchain
            .enumerate_images()
            .ctx("xrEnumerateSwapchainImages")?
            .into_iter()
            .map(ash::vk::Handle::from_raw)
            .collect();
        let mut chain = Chain { swapchain: Some(swapchain), images, views: Vec::new() };
        for &img in &chain.images {
            match create_view(&self.device, img, format, base_layer, view_layers, aspect) {
                Ok(v) => chain.views.push(v),
                Err(e) => {
                    destroy_views(&self.device, &chain.views);
                    return Err(e);
                }
            }
        }
        Ok(chain)
    }
}

fn destroy_views(d: &ash::Device, views: &[vk::ImageView]) {
    for v in views {
        // SAFETY: our views; the device is idle when targets are torn down.
        unsafe { d.destroy_image_view(*v, None) };
    }
}

impl Targets {
    /// Destroys the Vulkan objects, then each XR swapchain through the raw entry point, so that a
    /// failing `xrDestroySwapchain` is reported like any other failing call (the openxr crate's
    /// `Drop` ignores its result). Every swapchain is destroyed even after a failure; the error
    /// names every failed call.
    /// Destroys the app's own Vulkan objects and leaves the swapchains to the runtime, for
    /// `xrDestroySession` or `xrDestroyInstance` to destroy with their parent (`--teardown`).
    pub fn leave_swapchains(mut self) {
        self.destroy_vulkan_objects();
        self.leave_swapchains_now();
    }

    fn leave_swapchains_now(&mut self) {
        for slot in std::mem::take(&mut self.slots) {
            for chain in std::iter::once(slot.color).chain(slot.depth) {
                // Forgotten: its `Drop` would destroy it.
                std::mem::forget(chain.swapchain);
            }
        }
    }

    /// `--teardown in-flight`: each XR swapchain is destroyed at once, while the last frames'
    /// GPU work may still use its images (nothing is waited for), as Bevy does at exit. The
    /// spec asks the app to finish that work first; runtimes tolerate it by waiting themselves.
    /// The Vulkan objects go later, with `destroy`.
    pub fn destroy_swapchains_in_flight(&mut self) -> Result<()> {
        let mut errors = Vec::new();
        for slot in &self.slots {
            for sc in std::iter::once(&slot.color).chain(&slot.depth).filter_map(|c| c.swapchain.as_ref()) {
                // SAFETY: the app's own swapchain, destroyed once (`swapchains_gone` keeps
                // `destroy` and `Drop` from destroying it again).
                let r = unsafe { (sc.instance().fp().destroy_swapchain)(sc.as_raw()) };
                if let Err(e) = crate::error::check(r, "xrDestroySwapchain") {
                    errors.push(e.0);
                }
            }
        }
        self.swapchains_gone = true;
        if errors.is_empty() { Ok(()) } else { crate::error::fail(errors.join("; ")) }
    }

    pub fn destroy(mut self) -> Result<()> {
        self.destroy_vulkan_objects();
        if self.swapchains_gone {
            self.leave_swapchains_now();
            return Ok(());
        }
        let mut errors = Vec::new();
        for slot in std::mem::take(&mut self.slots) {
            for sc in std::iter::once(slot.color).chain(slot.depth).filter_map(|c| c.swapchain) {
                // SAFETY: the app's own swapchain, no longer used by any GPU work (the device is
                // idle); the wrapper is forgotten so its `Drop` does not destroy it again.
                let r = unsafe { (sc.instance().fp().destroy_swapchain)(sc.as_raw()) };
                std::mem::forget(sc);
                if let Err(e) = crate::error::check(r, "xrDestroySwapchain") {
                    errors.push(e.0);
                }
            }
        }
        if errors.is_empty() {
            Ok(())
        } else {
            crate::error::fail(errors.join("; "))
        }
    }

    fn destroy_vulkan_objects(&mut self) {
        // SAFETY: wait for all GPU work before destroying what it may use.
        unsafe {
            let _ = self.device.device_wait_idle();
        }
        for s in &mut self.slots {
            destroy_views(&self.device, &s.color.views);
            if let Some(d) = &s.depth {
                destroy_views(&self.device, &d.views);
            }
            if let Some(i) = &mut s.offscreen {
                i.destroy(&self.device);
            }
            if let Some(i) = &mut s.own_depth {
                i.destroy(&self.device);
            }
            if let Some(i) = &mut s.double_wide {
                i.destroy(&self.device);
            }
            if let Some(p) = &mut s.post {
                p.destroy(&self.device);
            }
        }
    }
}

impl Targets {
    /// The offscreen target slot `i`'s eye pass renders into (`--intermediate`): its own, or with
    /// `--one-target` the one the slots share.
    pub fn offscreen_of(&self, i: usize) -> Option<&OwnedImage> {
        self.slots.get(i).and_then(|s| s.offscreen.as_ref()).or_else(|| self.slots.first().and_then(|s| s.offscreen.as_ref()))
    }

    /// The XR swapchain slot `i`'s colour images belong to: its own, or with `--eye-swapchain
    /// array` the first slot's, whose layers both eyes write.
    pub fn color_swapchain(&self, i: usize) -> &xr::Swapchain<xr::Vulkan> {
        self.slots[..=i].iter().rev().find_map(|s| s.color.swapchain.as_ref()).expect("a slot owns the colour swapchain")
    }

    /// The private depth slot `i`'s eye pass uses: its own, or with `--one-target` the first
    /// slot's, which the slots share.
    pub fn own_depth_of(&self, i: usize) -> Option<&OwnedImage> {
        self.slots.get(i).and_then(|s| s.own_depth.as_ref()).or_else(|| self.slots.first().and_then(|s| s.own_depth.as_ref()))
    }
}

impl Drop for Targets {
    /// The error path (`destroy` leaves no slot behind): the XR swapchains are destroyed when
    /// `slots` drops, after their views.
    fn drop(&mut self) {
        self.destroy_vulkan_objects();
        if self.swapchains_gone {
            self.leave_swapchains_now();
        }
    }
}
