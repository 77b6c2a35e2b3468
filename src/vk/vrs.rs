//! Variable-rate shading (foveation method 1) on the Vulkan side: a layer-owned
//! `VK_KHR_fragment_shading_rate` attachment (R8_UINT, one layer per view for multiview) chained
//! into the app's eye passes, and the pipeline state that makes the attachment count. The rate map
//! itself comes from `crate::vrs`; the eye-pass test from `track::eye_pass`.
//!
//! - Pipelines: when the layer enabled `attachmentFragmentShadingRate` on the device, every
//!   graphics pipeline that does not use shading rate itself gets
//!   `VkPipelineFragmentShadingRateStateCreateInfoKHR { 1×1, [KEEP, REPLACE] }` (without it the
//!   attachment is ignored: the default combiner ops are KEEP, KEEP), and dynamic-rendering ones
//!   `VK_PIPELINE_CREATE_RENDERING_FRAGMENT_SHADING_RATE_ATTACHMENT_BIT_KHR` (required of every
//!   pipeline bound in a rendering with a rate attachment). Both are inert in passes without one
//!   (the attachment rate is then 1×1), so foveation can be switched on live.
//! - `vkCmdBeginRendering`: an eye pass goes down with a copy of the app's `VkRenderingInfo`
//!   whose chain starts with `VkRenderingFragmentShadingRateAttachmentInfoKHR`.
//! - Render pass objects (`vkCmdBeginRenderPass(2)`): not implemented; counted as
//!   `vrs_not_applied.render_pass`. The spec's render pass compatibility rules compare subpass
//!   descriptions (and so a subpass's `VkFragmentShadingRateAttachmentInfoKHR`), so a variant
//!   pass with the extra attachment would also need pipeline variants.
//!
//! Rate images are built when a (foveation generation, views generation, extent, eyes) shape is
//! first seen — never per frame — and uploaded by commands recorded into the first command buffer
//! that uses them, before its pass (limit: a command buffer recorded with the same new image but
//! executed before that one would read it uninitialized). Images unused for
//! `mask::RETIRE_AFTER_FRAMES` frames are destroyed.

use super::mask::{FRAMES_ENDED, RETIRE_AFTER_FRAMES};
use super::DeviceState;
use crate::config::Config;
use crate::mask::PixelRect;
use crate::shared::shared;
use crate::track::cmd::{PassInstance, PassKind};
use crate::track::eye_pass::{self, Facts};
use crate::vrs::{self as rule, DeviceRates, EyeRates, NotApplied};
use ash::vk::{self, Handle};
use std::collections::{HashMap, HashSet};
use std::ffi::c_void;
use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex, MutexGuard};

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// What makes one rate image.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
struct MapKey {
    width: u32,
    height: u32,
    layers: u32,
    /// (rate-image layer, view, rect) of every eye.
    eyes: Vec<(u32, u32, PixelRect)>,
    foveation_generation: u64,
    views_generation: u64,
}

struct RateImage {
    image: vk::Image,
    memory: vk::DeviceMemory,
    view: vk::ImageView,
    staging: vk::Buffer,
    staging_memory: vk::DeviceMemory,
    /// Whether the upload has been recorded (into the first command buffer that used it).
    uploaded: bool,
    last_used_frame: u64,
}

#[derive(Default)]
struct Objects {
    images: HashMap<MapKey, RateImage>,
}

#[derive(Default)]
struct Books {
    logged_kinds: HashSet<(PassKind, bool)>,
    logged_reasons: HashSet<NotApplied>,
}

/// Per-device VRS state. Locks are held only around bookkeeping, never while calling down.
pub(crate) struct VrsDevice {
    layer_enabled: bool,
    /// The device's texel size and layering when the layer enabled `attachmentFragmentShadingRate`.
    rates: Option<DeviceRates>,
    memory: vk::PhysicalDeviceMemoryProperties,
    objects: Mutex<Objects>,
    books: Mutex<Books>,
}

/// What `foveation.*` asks of this device now.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Mode {
    Off,
    On,
    /// `foveation.method = vrs` on a device without attachment rates.
    Unsupported,
}

impl VrsDevice {
    pub fn new(config: &Config, memory: vk::PhysicalDeviceMemoryProperties, rates: Option<DeviceRates>) -> VrsDevice {
        VrsDevice { layer_enabled: config.enabled(), rates, memory, objects: Mutex::default(), books: Mutex::default() }
    }

    /// The layer enabled `attachmentFragmentShadingRate` on this device (pipelines get the state).
    pub fn enabled(&self) -> bool {
        self.layer_enabled && self.rates.is_some()
    }

    fn mode(&self, device_config: &Arc<Config>) -> Mode {
        let c = shared().config().unwrap_or_else(|| device_config.clone());
        if !self.layer_enabled || !c.bool("foveation.enabled") {
            return Mode::Off;
        }
        let method = c.choice("foveation.method");
        if rule::method_is_vrs(method, self.rates.is_some()) {
            Mode::On
        } else if method == "vrs" {
            Mode::Unsupported
        } else {
            Mode::Off
        }
    }
}

fn count(d: &DeviceState, f: impl Fn(&mut crate::vrs::VrsFrameStats)) {
    d.mask.mark_used();
    d.mask.count(|s| f(&mut s.vrs));
}

fn not_applied(d: &DeviceState, why: NotApplied, kind: PassKind) {
    count(d, |s| s.count_not_applied(why));
    if lock(&d.vrs.books).logged_reasons.insert(why) {
        match why {
            NotApplied::Unsupported => tracing::warn!("vrs unsupported on this device (no attachmentFragmentShadingRate enabled by the layer): foveation.method = vrs does nothing here; auto would use rdm"),
            _ => tracing::info!(?kind, "vrs not applied to an eye pass: {} (logged once per reason)", why.name()),
        }
    }
}

/// `vkCreateGraphicsPipelines`: copies of the create infos with the shading-rate state, kept
/// alive while the call goes down.
pub(super) struct PipelineInfos {
    pub infos: Vec<vk::GraphicsPipelineCreateInfo<'static>>,
    // Boxed: the copies point at them, so they must not move when the vector grows.
    #[allow(clippy::vec_box)]
    _states: Vec<Box<vk::PipelineFragmentShadingRateStateCreateInfoKHR<'static>>>,
    pub changed: usize,
}

/// Whether the app's pipeline uses shading rate itself, or is a library (left alone).
///
/// # Safety
/// `ci` must be a valid create info.
unsafe fn leave_alone(ci: &vk::GraphicsPipelineCreateInfo<'_>) -> bool {
    use vk::StructureType as S;
    let in_chain = |t: S| {
        // SAFETY: a valid chain (the caller's contract).
        unsafe { super::convert::find_in_chain::<vk::BaseInStructure<'_>>(ci.p_next, t) }.is_some()
    };
    if in_chain(S::PIPELINE_FRAGMENT_SHADING_RATE_STATE_CREATE_INFO_KHR)
        || in_chain(S::GRAPHICS_PIPELINE_LIBRARY_CREATE_INFO_EXT)
        || in_chain(S::PIPELINE_LIBRARY_CREATE_INFO_KHR)
        || ci.flags.contains(vk::PipelineCreateFlags::LIBRARY_KHR)
    {
        return true;
    }
    // SAFETY: null or a valid dynamic state info with its array.
    let dynamic = unsafe { ci.p_dynamic_state.as_ref() }.map_or(&[][..], |ds| unsafe { super::convert::slice(ds.p_dynamic_states, ds.dynamic_state_count) });
    dynamic.contains(&vk::DynamicState::FRAGMENT_SHADING_RATE_KHR)
}

/// The app's pipeline create infos with the shading-rate state added where it applies; None when
/// the device has no layer-enabled attachment rates (the app's infos go down untouched).
///
/// # Safety
/// `infos` must be `count` valid create infos, alive while the result is used.
pub(super) unsafe fn pipeline_infos(d: &DeviceState, infos: *const vk::GraphicsPipelineCreateInfo<'_>, count: u32) -> Option<PipelineInfos> {
    if !d.vrs.enabled() {
        return None;
    }
    // SAFETY: the caller's contract.
    let app = unsafe { super::convert::slice(infos, count) };
    let mut out = PipelineInfos { infos: Vec::with_capacity(app.len()), _states: Vec::new(), changed: 0 };
    for ci in app {
        // SAFETY: lifetimes erased: the copies live only during the app's call.
        let mut copy: vk::GraphicsPipelineCreateInfo<'static> = unsafe { std::mem::transmute(*ci) };
        // SAFETY: a valid create info.
        if !unsafe { leave_alone(ci) } {
            let mut state = Box::new(vk::PipelineFragmentShadingRateStateCreateInfoKHR {
                fragment_size: vk::Extent2D { width: 1, height: 1 },
                combiner_ops: [vk::FragmentShadingRateCombinerOpKHR::KEEP, vk::FragmentShadingRateCombinerOpKHR::REPLACE],
                ..Default::default()
            });
            state.p_next = ci.p_next;
            copy.p_next = &*state as *const _ as *const c_void;
            if ci.render_pass == vk::RenderPass::null() {
                copy.flags |= vk::PipelineCreateFlags::RENDERING_FRAGMENT_SHADING_RATE_ATTACHMENT_KHR;
            }
            out._states.push(state);
            out.changed += 1;
        }
        out.infos.push(copy);
    }
    Some(out)
}

/// `vkCmdBeginRendering` with the rate attachment: a copy of the app's info whose chain starts
/// with ours; both live while the call goes down.
pub(super) struct Rendering {
    pub info: vk::RenderingInfo<'static>,
    _fsr: Box<vk::RenderingFragmentShadingRateAttachmentInfoKHR<'static>>,
}

/// Decides whether this rendering is an eye pass that gets a rate attachment; records the rate
/// image's upload into `cb` (before the pass) when it is new.
///
/// # Safety
/// `info` must be the app's valid rendering info, alive while the result is used; `cb` recording
/// outside a render pass instance.
pub(super) unsafe fn for_rendering(d: &DeviceState, cb: vk::CommandBuffer, info: *const vk::RenderingInfo<'_>) -> Option<Rendering> {
    let mode = d.vrs.mode(&d.config);
    if mode == Mode::Off {
        return None;
    }
    // SAFETY: the caller's contract.
    let app = unsafe { &*info };
    // SAFETY: as above.
    let (area, rendering) = unsafe { super::convert::rendering(&d.track, app) };
    let resuming = rendering.resuming();
    let pass = PassInstance {
        kind: PassKind::Dynamic,
        render_area: area,
        subpass: 0,
        render_pass: None,
        framebuffer: None,
        attachments: Vec::new(),
        clear_values: Vec::new(),
        rendering: Some(rendering),
    };
    let r = plan(d, mode, &pass, app.flags.contains(vk::RenderingFlags::CONTENTS_SECONDARY_COMMAND_BUFFERS), || {
        // SAFETY: a valid chain.
        unsafe { super::convert::find_in_chain::<vk::BaseInStructure<'_>>(app.p_next, vk::StructureType::RENDERING_FRAGMENT_SHADING_RATE_ATTACHMENT_INFO_KHR) }.is_some()
    });
    let (key, eyes, rates) = match r {
        Ok(Some(p)) => p,
        Ok(None) => return None,
        Err(why) => {
            if !resuming {
                not_applied(d, why, PassKind::Dynamic);
            }
            return None;
        }
    };
    let view = match image_for(d, cb, &key, &eyes, rates) {
        Ok(v) => v,
        Err(e) => {
            tracing::warn!("vrs rate image: {e}");
            if !resuming {
                not_applied(d, NotApplied::LayerError, PassKind::Dynamic);
            }
            return None;
        }
    };
    let mut fsr = Box::new(vk::RenderingFragmentShadingRateAttachmentInfoKHR {
        image_view: view,
        image_layout: vk::ImageLayout::FRAGMENT_SHADING_RATE_ATTACHMENT_OPTIMAL_KHR,
        shading_rate_attachment_texel_size: vk::Extent2D { width: rates.texel_width, height: rates.texel_height },
        ..Default::default()
    });
    fsr.p_next = app.p_next;
    // SAFETY: lifetimes erased: the copy lives only during the app's call.
    let mut copy: vk::RenderingInfo<'static> = unsafe { std::mem::transmute(*app) };
    copy.p_next = &*fsr as *const _ as *const c_void;
    if !resuming {
        count(d, |s| s.passes += 1);
        log_kind_once(d, PassKind::Dynamic, key.layers > 1 || pass.view_mask() != 0, &key);
    }
    Some(Rendering { info: copy, _fsr: fsr })
}

/// `vkCmdBeginRenderPass(2)` (after it went down, the pass tracked): counts an eye pass VRS
/// would apply to as not applied (render pass objects are not implemented).
pub(super) fn on_render_pass_begin(d: &DeviceState, cb: vk::CommandBuffer, secondary: bool) {
    let mode = d.vrs.mode(&d.config);
    if mode == Mode::Off {
        return;
    }
    let Some(Some(pass)) = d.track.with_cb(cb.as_raw(), |s| s.pass.clone()) else { return };
    match plan(d, mode, &pass, secondary, || false) {
        Ok(None) => {}
        Ok(Some(_)) => not_applied(d, NotApplied::RenderPass, pass.kind),
        Err(why) => not_applied(d, why, pass.kind),
    }
}

type Plan = (MapKey, Vec<EyeRates>, DeviceRates);

/// The rate image an eye pass needs; Ok(None) for a pass that is no eye pass.
fn plan(d: &DeviceState, mode: Mode, pass: &PassInstance, secondary: bool, app_fsr: impl Fn() -> bool) -> Result<Option<Plan>, NotApplied> {
    let c = shared().config().unwrap_or_else(|| d.config.clone());
    let intermediate = c.choice("mask.intermediate") != "off";
    let eyes_fn = |a: &crate::track::cmd::AttachmentUse| super::mask::eyes_of(d, a, intermediate);
    let facts = Facts { secondary_contents: false, intermediate_enabled: intermediate, eyes: &eyes_fn, explicit_clear: None };
    let (att, sources, _) = match eye_pass::find_eyes(pass, &facts) {
        Ok(f) => f,
        Err(n) => return NotApplied::from_not_masked(n).map_or(Ok(None), Err),
    };
    if mode == Mode::Unsupported {
        return Err(NotApplied::Unsupported);
    }
    if app_fsr() {
        return Err(NotApplied::AppUsesFsr);
    }
    if secondary {
        return Err(NotApplied::Secondary);
    }
    if pass.kind != PassKind::Dynamic {
        return Ok(Some((MapKey { width: 0, height: 0, layers: 0, eyes: vec![], foveation_generation: 0, views_generation: 0 }, vec![], DeviceRates { texel_width: 1, texel_height: 1, layered: false })));
    }
    let rates = d.vrs.rates.ok_or(NotApplied::Unsupported)?;
    let (views, fovea) = (shared().views(), shared().foveation());
    let base_layer = att.image_view.as_ref().map_or(0, |v| v.range.base_array_layer);
    let view_mask = pass.view_mask();
    let mut eyes = Vec::new();
    let eye = |layer: u32, s: &eye_pass::EyeSource| -> Result<EyeRates, NotApplied> {
        let fov = *views.fovs.get(s.view as usize).ok_or(NotApplied::NoFovea)?;
        let f = *fovea.views.iter().find(|f| f.view == s.view).ok_or(NotApplied::NoFovea)?;
        Ok(EyeRates { layer, rect: s.rect, fov, fovea: f })
    };
    let layers = if view_mask != 0 {
        if !rates.layered {
            return Err(NotApplied::MultiviewNotLayered);
        }
        for i in (0..32).filter(|i| view_mask & (1 << i) != 0) {
            for s in sources.iter().filter(|s| s.layer == base_layer + i) {
                eyes.push(eye(i, s)?);
            }
        }
        32 - view_mask.leading_zeros()
    } else {
        if pass.rendering.as_ref().is_some_and(|r| r.layer_count > 1) {
            return Err(NotApplied::Layered);
        }
        for s in sources.iter().filter(|s| s.layer == base_layer) {
            eyes.push(eye(0, s)?);
        }
        1
    };
    if eyes.is_empty() {
        return Err(NotApplied::EyeUnknown);
    }
    // Cover the whole attachment (so one image serves every pass on images of that size), at
    // least the render area.
    let image = att.image_view.as_ref().and_then(|v| d.track.images.get(v.image));
    let area = pass.render_area;
    let w = image.as_ref().map_or(0, |i| i.extent.width).max((area.x.max(0) as u32).saturating_add(area.width));
    let h = image.as_ref().map_or(0, |i| i.extent.height).max((area.y.max(0) as u32).saturating_add(area.height));
    let key = MapKey {
        width: rule::texels(w, rates.texel_width),
        height: rule::texels(h, rates.texel_height),
        layers,
        eyes: eyes.iter().map(|e| (e.layer, e.fovea.view, e.rect)).collect(),
        foveation_generation: fovea.generation,
        views_generation: views.generation,
    };
    Ok(Some((key, eyes, rates)))
}

fn log_kind_once(d: &DeviceState, kind: PassKind, multiview: bool, key: &MapKey) {
    if lock(&d.vrs.books).logged_kinds.insert((kind, multiview)) {
        tracing::info!(
            "vrs on {kind:?}{} pass: rate attachment {}x{} texels x {} layer(s), eyes (layer, view, rect) {:?}",
            if multiview { " multiview" } else { "" },
            key.width,
            key.height,
            key.layers,
            key.eyes
        );
    }
}

/// The view of the rate image for `key`, built and its upload recorded into `cb` when new.
fn image_for(d: &DeviceState, cb: vk::CommandBuffer, key: &MapKey, eyes: &[EyeRates], rates: DeviceRates) -> Result<vk::ImageView, String> {
    let now = FRAMES_ENDED.load(Ordering::Relaxed);
    let existing = lock(&d.vrs.objects).images.get_mut(key).map(|img| {
        img.last_used_frame = now;
        (img.view, img.uploaded, img.image, img.staging)
    });
    let (view, image, staging) = match existing {
        Some((view, true, _, _)) => return Ok(view),
        Some((view, false, image, staging)) => (view, image, staging),
        None => {
            retire(d, now);
            let data: Vec<u8> = (0..key.layers).flat_map(|l| rule::rate_layer(key.width, key.height, rates.texel_width, rates.texel_height, l, eyes)).collect();
            let created = create(d, key, &data)?;
            let mut o = lock(&d.vrs.objects);
            if o.images.contains_key(key) {
                // Another thread built the same map first: ours was never used.
                drop(o);
                destroy_image(d, &created);
                return image_for(d, cb, key, eyes, rates);
            }
            let r = (created.view, created.image, created.staging);
            o.images.insert(key.clone(), created);
            drop(o);
            count(d, |s| s.maps_built += 1);
            tracing::debug!(w = key.width, h = key.height, layers = key.layers, "vrs rate image built");
            r
        }
    };
    record_upload(d, cb, image, staging, key);
    if let Some(img) = lock(&d.vrs.objects).images.get_mut(key) {
        img.uploaded = true;
    }
    Ok(view)
}

fn record_upload(d: &DeviceState, cb: vk::CommandBuffer, image: vk::Image, staging: vk::Buffer, key: &MapKey) {
    let range = vk::ImageSubresourceRange { aspect_mask: vk::ImageAspectFlags::COLOR, base_mip_level: 0, level_count: 1, base_array_layer: 0, layer_count: key.layers };
    let to_dst = vk::ImageMemoryBarrier::default()
        .src_access_mask(vk::AccessFlags::empty())
        .dst_access_mask(vk::AccessFlags::TRANSFER_WRITE)
        .old_layout(vk::ImageLayout::UNDEFINED)
        .new_layout(vk::ImageLayout::TRANSFER_DST_OPTIMAL)
        .src_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
        .dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
        .image(image)
        .subresource_range(range);
    let to_fsr = vk::ImageMemoryBarrier::default()
        .src_access_mask(vk::AccessFlags::TRANSFER_WRITE)
        .dst_access_mask(vk::AccessFlags::FRAGMENT_SHADING_RATE_ATTACHMENT_READ_KHR)
        .old_layout(vk::ImageLayout::TRANSFER_DST_OPTIMAL)
        .new_layout(vk::ImageLayout::FRAGMENT_SHADING_RATE_ATTACHMENT_OPTIMAL_KHR)
        .src_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
        .dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
        .image(image)
        .subresource_range(range);
    let region = vk::BufferImageCopy {
        buffer_offset: 0,
        buffer_row_length: 0,
        buffer_image_height: 0,
        image_subresource: vk::ImageSubresourceLayers { aspect_mask: vk::ImageAspectFlags::COLOR, mip_level: 0, base_array_layer: 0, layer_count: key.layers },
        image_offset: vk::Offset3D::default(),
        image_extent: vk::Extent3D { width: key.width, height: key.height, depth: 1 },
    };
    let f = d.fns.fp_v1_0();
    // SAFETY: `cb` is recording outside a render pass instance (the app is about to begin one);
    // our image and buffer are alive until retired frames after their last use.
    unsafe {
        (f.cmd_pipeline_barrier)(cb, vk::PipelineStageFlags::TOP_OF_PIPE, vk::PipelineStageFlags::TRANSFER, vk::DependencyFlags::empty(), 0, std::ptr::null(), 0, std::ptr::null(), 1, &to_dst);
        (f.cmd_copy_buffer_to_image)(cb, staging, image, vk::ImageLayout::TRANSFER_DST_OPTIMAL, 1, &region);
        (f.cmd_pipeline_barrier)(
            cb,
            vk::PipelineStageFlags::TRANSFER,
            vk::PipelineStageFlags::FRAGMENT_SHADING_RATE_ATTACHMENT_KHR,
            vk::DependencyFlags::empty(),
            0,
            std::ptr::null(),
            0,
            std::ptr::null(),
            1,
            &to_fsr,
        );
    }
}

fn memory_type(d: &DeviceState, bits: u32, wanted: vk::MemoryPropertyFlags) -> Option<u32> {
    let mem = &d.vrs.memory;
    (0..mem.memory_type_count).find(|&i| bits & (1 << i) != 0 && mem.memory_types[i as usize].property_flags.contains(wanted))
}

fn create(d: &DeviceState, key: &MapKey, data: &[u8]) -> Result<RateImage, String> {
    let mut img = RateImage {
        image: vk::Image::null(),
        memory: vk::DeviceMemory::null(),
        view: vk::ImageView::null(),
        staging: vk::Buffer::null(),
        staging_memory: vk::DeviceMemory::null(),
        uploaded: false,
        last_used_frame: FRAMES_ENDED.load(Ordering::Relaxed),
    };
    let r = fill(d, key, data, &mut img);
    if let Err(e) = r {
        destroy_image(d, &img);
        return Err(e);
    }
    Ok(img)
}

fn fill(d: &DeviceState, key: &MapKey, data: &[u8], img: &mut RateImage) -> Result<(), String> {
    let e = |e: vk::Result| e.to_string();
    let ci = vk::ImageCreateInfo::default()
        .image_type(vk::ImageType::TYPE_2D)
        .format(vk::Format::R8_UINT)
        .extent(vk::Extent3D { width: key.width, height: key.height, depth: 1 })
        .mip_levels(1)
        .array_layers(key.layers)
        .samples(vk::SampleCountFlags::TYPE_1)
        .tiling(vk::ImageTiling::OPTIMAL)
        .usage(vk::ImageUsageFlags::FRAGMENT_SHADING_RATE_ATTACHMENT_KHR | vk::ImageUsageFlags::TRANSFER_DST)
        .sharing_mode(vk::SharingMode::EXCLUSIVE)
        .initial_layout(vk::ImageLayout::UNDEFINED);
    // SAFETY: valid create / allocate infos; every object is ours and destroyed by the caller on error.
    unsafe {
        img.image = d.fns.create_image(&ci, None).map_err(e)?;
        let req = d.fns.get_image_memory_requirements(img.image);
        let t = memory_type(d, req.memory_type_bits, vk::MemoryPropertyFlags::DEVICE_LOCAL)
            .or_else(|| memory_type(d, req.memory_type_bits, vk::MemoryPropertyFlags::empty()))
            .ok_or("no memory type for the rate image")?;
        img.memory = d.fns.allocate_memory(&vk::MemoryAllocateInfo::default().allocation_size(req.size).memory_type_index(t), None).map_err(e)?;
        d.fns.bind_image_memory(img.image, img.memory, 0).map_err(e)?;
        let view = vk::ImageViewCreateInfo::default()
            .image(img.image)
            .view_type(if key.layers > 1 { vk::ImageViewType::TYPE_2D_ARRAY } else { vk::ImageViewType::TYPE_2D })
            .format(vk::Format::R8_UINT)
            .subresource_range(vk::ImageSubresourceRange { aspect_mask: vk::ImageAspectFlags::COLOR, base_mip_level: 0, level_count: 1, base_array_layer: 0, layer_count: key.layers });
        img.view = d.fns.create_image_view(&view, None).map_err(e)?;
        let bi = vk::BufferCreateInfo::default().size(data.len() as u64).usage(vk::BufferUsageFlags::TRANSFER_SRC).sharing_mode(vk::SharingMode::EXCLUSIVE);
        img.staging = d.fns.create_buffer(&bi, None).map_err(e)?;
        let req = d.fns.get_buffer_memory_requirements(img.staging);
        let t = memory_type(d, req.memory_type_bits, vk::MemoryPropertyFlags::HOST_VISIBLE | vk::MemoryPropertyFlags::HOST_COHERENT).ok_or("no host-visible coherent memory type")?;
        img.staging_memory = d.fns.allocate_memory(&vk::MemoryAllocateInfo::default().allocation_size(req.size).memory_type_index(t), None).map_err(e)?;
        d.fns.bind_buffer_memory(img.staging, img.staging_memory, 0).map_err(e)?;
        let p = d.fns.map_memory(img.staging_memory, 0, data.len() as u64, vk::MemoryMapFlags::empty()).map_err(e)? as *mut u8;
        std::ptr::copy_nonoverlapping(data.as_ptr(), p, data.len());
        d.fns.unmap_memory(img.staging_memory);
    }
    Ok(())
}

fn destroy_image(d: &DeviceState, img: &RateImage) {
    // SAFETY: our objects (null handles are ignored); no pending GPU use (see callers).
    unsafe {
        d.fns.destroy_image_view(img.view, None);
        d.fns.destroy_image(img.image, None);
        d.fns.free_memory(img.memory, None);
        d.fns.destroy_buffer(img.staging, None);
        d.fns.free_memory(img.staging_memory, None);
    }
}

/// Destroys images unused for `RETIRE_AFTER_FRAMES` frames (their command buffers completed).
fn retire(d: &DeviceState, now: u64) {
    let old: Vec<RateImage> = {
        let mut o = lock(&d.vrs.objects);
        let keys: Vec<MapKey> = o.images.iter().filter(|(_, i)| now >= i.last_used_frame + RETIRE_AFTER_FRAMES).map(|(k, _)| k.clone()).collect();
        keys.iter().filter_map(|k| o.images.remove(k)).collect()
    };
    for img in &old {
        destroy_image(d, img);
    }
}

/// At vkDestroyDevice (the app waited for the device to go idle).
pub(crate) fn destroy(d: &DeviceState) {
    let all = std::mem::take(&mut lock(&d.vrs.objects).images);
    for img in all.values() {
        destroy_image(d, img);
    }
}
