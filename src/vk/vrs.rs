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
//! - Render pass objects: render pass compatibility compares subpass descriptions (and so a
//!   subpass's `VkFragmentShadingRateAttachmentInfoKHR`), so a variant pass with the attachment
//!   would need pipeline variants. Instead the app's own pass gets it: `vkCreateRenderPass(2)`
//!   goes down as `vkCreateRenderPass2` with one more attachment (R8_UINT, LOAD / DONT_CARE,
//!   `FRAGMENT_SHADING_RATE_ATTACHMENT_OPTIMAL` throughout; index = the app's attachment count,
//!   recorded as `RenderPass::layer_rate_attachment`; the tracked description stays the app's)
//!   referenced from every graphics subpass, so the app's pipelines are made against it.
//!   Passes with their own rate attachment or a density map are left alone. Each framebuffer of
//!   such a pass gets a layer rate image (`ceil(extent / texel)`, one layer per view when
//!   multiview and layered, else 1) appended — imageless: its image info at creation, its view
//!   at each begin — destroyed with the framebuffer. At `vkCmdBeginRenderPass(2)` (before it
//!   goes down) the image is rewritten when it holds another map than the pass needs: the eye's
//!   rates for an eye pass with VRS on, 1×1 everywhere otherwise (those passes are unchanged).
//!   Limits: an imageless framebuffer's chain must start with its attachments struct (create and
//!   begin); contents are tracked in recording order (as below).
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
    /// Render pass objects: framebuffers' rate images and the maps' staging buffers.
    pass_objects: Mutex<PassObjects>,
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
        VrsDevice { layer_enabled: config.enabled(), rates, memory, objects: Mutex::default(), pass_objects: Mutex::default(), books: Mutex::default() }
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

/// `vkCmdBeginRenderPass(2)` (after it went down, the pass tracked) of a pass without the
/// layer's rate attachment: counts an eye pass VRS would apply to as not applied.
pub(super) fn on_render_pass_begin(d: &DeviceState, cb: vk::CommandBuffer, secondary: bool) {
    let mode = d.vrs.mode(&d.config);
    if mode == Mode::Off {
        return;
    }
    let Some(Some(pass)) = d.track.with_cb(cb.as_raw(), |s| s.pass.clone()) else { return };
    if pass.render_pass.as_ref().is_some_and(|rp| rp.layer_rate_attachment.is_some()) {
        // Handled before it went down (`for_render_pass_begin`).
        return;
    }
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
        // A layered pass without multiview: one rate layer (the spec's only choice for a render
        // pass object) cannot carry per-layer eyes.
        if pass.rendering.as_ref().is_some_and(|r| r.layer_count > 1) || pass.framebuffer.as_ref().is_some_and(|f| f.layers > 1) {
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
    record_rate_content(d, cb, image, key.layers, (key.width, key.height), Some(staging));
    if let Some(img) = lock(&d.vrs.objects).images.get_mut(key) {
        img.uploaded = true;
    }
    Ok(view)
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
    image_objects(d, key, img)?;
    staging_objects(d, data, img)
}

/// The rate image (`key`'s extent and layers) and its view, into `img`.
fn image_objects(d: &DeviceState, key: &MapKey, img: &mut RateImage) -> Result<(), String> {
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
    }
    Ok(())
}

/// A host-visible staging buffer holding `data`, into `img`.
fn staging_objects(d: &DeviceState, data: &[u8], img: &mut RateImage) -> Result<(), String> {
    let e = |e: vk::Result| e.to_string();
    // SAFETY: valid create / allocate infos; every object is ours and destroyed by the caller on error.
    unsafe {
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
    let old: Vec<Staging> = {
        let mut o = lock(&d.vrs.pass_objects);
        let keys: Vec<MapKey> = o.stagings.iter().filter(|(_, s)| now >= s.last_used_frame + RETIRE_AFTER_FRAMES).map(|(k, _)| k.clone()).collect();
        keys.iter().filter_map(|k| o.stagings.remove(k)).collect()
    };
    for st in &old {
        destroy_staging(d, st);
    }
}

fn destroy_staging(d: &DeviceState, st: &Staging) {
    // SAFETY: ours; its command buffers completed (retired) or the device is idle.
    unsafe {
        d.fns.destroy_buffer(st.buffer, None);
        d.fns.free_memory(st.memory, None);
    }
}

/// At vkDestroyDevice (the app waited for the device to go idle).
pub(crate) fn destroy(d: &DeviceState) {
    let all = std::mem::take(&mut lock(&d.vrs.objects).images);
    for img in all.values() {
        destroy_image(d, img);
    }
    let p = std::mem::take(&mut *lock(&d.vrs.pass_objects));
    for r in p.framebuffers.values() {
        destroy_fb_rate(d, r);
    }
    for st in p.stagings.values() {
        destroy_staging(d, st);
    }
}

// ---------------------------------------------------------------------------------------------
// Render pass objects: the layer's rate attachment is part of the app's own render pass (so the
// app's pipelines, created against that very pass, are compatible with it), its image part of
// each framebuffer of the pass. Non-eye passes read an all-1×1 image (unchanged output).

/// What a framebuffer's rate image holds now (as recorded: the command buffers run in the order
/// they were recorded in, the same limit as the dynamic-rendering images).
#[derive(Clone, Debug, PartialEq, Eq)]
enum Content {
    Undefined,
    /// Rate 0 (1×1) everywhere.
    Neutral,
    Map(MapKey),
}

#[derive(Clone, Debug)]
struct FbRate {
    image: vk::Image,
    memory: vk::DeviceMemory,
    view: vk::ImageView,
    width: u32,
    height: u32,
    layers: u32,
    /// The rate attachment's index in the render pass (the app's attachment count).
    index: u32,
    content: Content,
}

struct Staging {
    buffer: vk::Buffer,
    memory: vk::DeviceMemory,
    last_used_frame: u64,
}

#[derive(Default)]
pub(super) struct PassObjects {
    framebuffers: HashMap<u64, FbRate>,
    /// Immutable per map; kept until unused for `RETIRE_AFTER_FRAMES` frames (their command
    /// buffers completed).
    stagings: HashMap<MapKey, Staging>,
}

/// The parts of a `VkRenderPassCreateInfo2`, owned (the arrays the pointers lead to live here).
struct Owned2 {
    flags: vk::RenderPassCreateFlags,
    p_next: *const c_void,
    attachments: Vec<vk::AttachmentDescription2<'static>>,
    subpasses: Vec<vk::SubpassDescription2<'static>>,
    /// What the subpasses' pointers lead to (v1 translations).
    _refs: Vec<Vec<vk::AttachmentReference2<'static>>>,
    dependencies: Vec<vk::SubpassDependency2<'static>>,
    correlation: Vec<u32>,
}

/// `vkCreateRenderPass(2)` with the rate attachment: a `VkRenderPassCreateInfo2` whose arrays
/// live here while the call goes down.
pub(super) struct RatePass {
    pub info: vk::RenderPassCreateInfo2<'static>,
    /// The rate attachment's index (the app's attachment count).
    pub index: u32,
    _owned: Owned2,
    #[allow(clippy::vec_box)]
    _fsr: Vec<Box<vk::FragmentShadingRateAttachmentInfoKHR<'static>>>,
    _fsr_ref: Box<vk::AttachmentReference2<'static>>,
}

fn ptr_or_null<T>(v: &[T]) -> *const T {
    if v.is_empty() {
        std::ptr::null()
    } else {
        v.as_ptr()
    }
}

/// The aspects a v1 input attachment reads when the app chains no
/// `VkRenderPassInputAttachmentAspectCreateInfo`: all of its format's.
fn format_aspects(f: vk::Format) -> vk::ImageAspectFlags {
    use vk::{Format as F, ImageAspectFlags as A};
    match f {
        F::D16_UNORM | F::X8_D24_UNORM_PACK32 | F::D32_SFLOAT => A::DEPTH,
        F::S8_UINT => A::STENCIL,
        F::D16_UNORM_S8_UINT | F::D24_UNORM_S8_UINT | F::D32_SFLOAT_S8_UINT => A::DEPTH | A::STENCIL,
        _ => A::COLOR,
    }
}

/// A `VkRenderPassCreateInfo` as the equivalent `VkRenderPassCreateInfo2` (multiview and input
/// aspects translated); None when its chain holds anything else.
///
/// # Safety
/// `ci` and everything it points to must be valid; the result is used while they are.
unsafe fn owned_from_v1(ci: &vk::RenderPassCreateInfo<'_>) -> Option<Owned2> {
    let mut multiview: Option<&vk::RenderPassMultiviewCreateInfo<'_>> = None;
    let mut aspects: &[vk::InputAttachmentAspectReference] = &[];
    let mut p = ci.p_next as *const vk::BaseInStructure<'_>;
    // SAFETY: a valid chain; each struct is read as the type its sType names.
    unsafe {
        while let Some(b) = p.as_ref() {
            match b.s_type {
                vk::StructureType::RENDER_PASS_MULTIVIEW_CREATE_INFO => multiview = Some(&*(p as *const vk::RenderPassMultiviewCreateInfo<'_>)),
                vk::StructureType::RENDER_PASS_INPUT_ATTACHMENT_ASPECT_CREATE_INFO => {
                    let a = &*(p as *const vk::RenderPassInputAttachmentAspectCreateInfo<'_>);
                    aspects = super::convert::slice(a.p_aspect_references, a.aspect_reference_count);
                }
                _ => return None,
            }
            p = b.p_next;
        }
    }
    // SAFETY: arrays valid with their counts (the caller's contract).
    let (atts, subs, deps) = unsafe {
        (
            super::convert::slice(ci.p_attachments, ci.attachment_count),
            super::convert::slice(ci.p_subpasses, ci.subpass_count),
            super::convert::slice(ci.p_dependencies, ci.dependency_count),
        )
    };
    // SAFETY: the multiview struct's arrays, valid with their counts.
    let (view_masks, view_offsets, correlation) = multiview.map_or((&[][..], &[][..], &[][..]), |m| unsafe {
        (
            super::convert::slice(m.p_view_masks, m.subpass_count),
            super::convert::slice(m.p_view_offsets, m.dependency_count),
            super::convert::slice(m.p_correlation_masks, m.correlation_mask_count),
        )
    });
    let attachments: Vec<vk::AttachmentDescription2<'static>> = atts
        .iter()
        .map(|a| vk::AttachmentDescription2 {
            flags: a.flags,
            format: a.format,
            samples: a.samples,
            load_op: a.load_op,
            store_op: a.store_op,
            stencil_load_op: a.stencil_load_op,
            stencil_store_op: a.stencil_store_op,
            initial_layout: a.initial_layout,
            final_layout: a.final_layout,
            ..Default::default()
        })
        .collect();
    let r2 = |r: &vk::AttachmentReference, aspect: vk::ImageAspectFlags| vk::AttachmentReference2 { attachment: r.attachment, layout: r.layout, aspect_mask: aspect, ..Default::default() };
    let mut refs = Vec::new();
    // Per subpass: indices into `refs` of (input, color, resolve, depth).
    let mut at = Vec::new();
    for (i, s) in subs.iter().enumerate() {
        // SAFETY: the subpass's arrays are valid with its counts; resolve has color_count entries.
        let (input, color, resolve, depth) = unsafe {
            (
                super::convert::slice(s.p_input_attachments, s.input_attachment_count),
                super::convert::slice(s.p_color_attachments, s.color_attachment_count),
                super::convert::slice(s.p_resolve_attachments, s.color_attachment_count),
                s.p_depth_stencil_attachment.as_ref(),
            )
        };
        let input: Vec<_> = input
            .iter()
            .enumerate()
            .map(|(j, r)| {
                let aspect = if r.attachment == vk::ATTACHMENT_UNUSED {
                    vk::ImageAspectFlags::empty()
                } else {
                    aspects
                        .iter()
                        .find(|a| a.subpass as usize == i && a.input_attachment_index as usize == j)
                        .map(|a| a.aspect_mask)
                        .unwrap_or_else(|| atts.get(r.attachment as usize).map_or(vk::ImageAspectFlags::COLOR, |a| format_aspects(a.format)))
                };
                r2(r, aspect)
            })
            .collect();
        let none = vk::ImageAspectFlags::empty();
        at.push(refs.len());
        refs.push(input);
        refs.push(color.iter().map(|r| r2(r, none)).collect());
        refs.push(resolve.iter().map(|r| r2(r, none)).collect());
        refs.push(depth.iter().map(|r| r2(r, none)).collect());
    }
    let subpasses = subs
        .iter()
        .enumerate()
        .map(|(i, s)| {
            let k = at[i];
            vk::SubpassDescription2 {
                flags: s.flags,
                pipeline_bind_point: s.pipeline_bind_point,
                view_mask: view_masks.get(i).copied().unwrap_or(0),
                input_attachment_count: refs[k].len() as u32,
                p_input_attachments: ptr_or_null(&refs[k]),
                color_attachment_count: refs[k + 1].len() as u32,
                p_color_attachments: ptr_or_null(&refs[k + 1]),
                p_resolve_attachments: ptr_or_null(&refs[k + 2]),
                p_depth_stencil_attachment: ptr_or_null(&refs[k + 3]),
                preserve_attachment_count: s.preserve_attachment_count,
                p_preserve_attachments: s.p_preserve_attachments,
                ..Default::default()
            }
        })
        .collect();
    let dependencies = deps
        .iter()
        .enumerate()
        .map(|(i, d)| vk::SubpassDependency2 {
            src_subpass: d.src_subpass,
            dst_subpass: d.dst_subpass,
            src_stage_mask: d.src_stage_mask,
            dst_stage_mask: d.dst_stage_mask,
            src_access_mask: d.src_access_mask,
            dst_access_mask: d.dst_access_mask,
            dependency_flags: d.dependency_flags,
            view_offset: view_offsets.get(i).copied().unwrap_or(0),
            ..Default::default()
        })
        .collect();
    Some(Owned2 { flags: ci.flags, p_next: std::ptr::null(), attachments, subpasses, _refs: refs, dependencies, correlation: correlation.to_vec() })
}

/// A `VkRenderPassCreateInfo2`'s arrays, copied (its chains are kept as the app wrote them).
///
/// # Safety
/// `ci` and everything it points to must be valid; the result is used while they are.
unsafe fn owned_from_v2(ci: &vk::RenderPassCreateInfo2<'_>) -> Owned2 {
    // SAFETY: arrays valid with their counts; lifetimes erased: used only during the app's call.
    unsafe {
        Owned2 {
            flags: ci.flags,
            p_next: ci.p_next,
            attachments: super::convert::slice(ci.p_attachments, ci.attachment_count).iter().map(|a| std::mem::transmute_copy(a)).collect(),
            subpasses: super::convert::slice(ci.p_subpasses, ci.subpass_count).iter().map(|s| std::mem::transmute_copy(s)).collect(),
            _refs: Vec::new(),
            dependencies: super::convert::slice(ci.p_dependencies, ci.dependency_count).iter().map(|d| std::mem::transmute_copy(d)).collect(),
            correlation: super::convert::slice(ci.p_correlated_view_masks, ci.correlated_view_mask_count).to_vec(),
        }
    }
}

/// Whether the app's pass has its own rate attachment or a density map (left alone).
///
/// # Safety
/// As `owned_from_v2`.
unsafe fn v2_leave_alone(o: &Owned2) -> bool {
    use vk::StructureType as S;
    // SAFETY: valid chains.
    let in_chain = |p: *const c_void, t: S| unsafe { super::convert::find_in_chain::<vk::BaseInStructure<'_>>(p, t) }.is_some();
    in_chain(o.p_next, S::RENDER_PASS_FRAGMENT_DENSITY_MAP_CREATE_INFO_EXT) || o.subpasses.iter().any(|s| in_chain(s.p_next, S::FRAGMENT_SHADING_RATE_ATTACHMENT_INFO_KHR))
}

/// Appends the rate attachment (index = the app's count) and references it from every graphics
/// subpass with the device's finest texel.
fn with_rate(mut o: Owned2, texel: vk::Extent2D) -> RatePass {
    let index = o.attachments.len() as u32;
    let layout = vk::ImageLayout::FRAGMENT_SHADING_RATE_ATTACHMENT_OPTIMAL_KHR;
    o.attachments.push(vk::AttachmentDescription2 {
        format: vk::Format::R8_UINT,
        samples: vk::SampleCountFlags::TYPE_1,
        load_op: vk::AttachmentLoadOp::LOAD,
        store_op: vk::AttachmentStoreOp::DONT_CARE,
        stencil_load_op: vk::AttachmentLoadOp::DONT_CARE,
        stencil_store_op: vk::AttachmentStoreOp::DONT_CARE,
        initial_layout: layout,
        final_layout: layout,
        ..Default::default()
    });
    let fsr_ref = Box::new(vk::AttachmentReference2 { attachment: index, layout, ..Default::default() });
    let mut fsr = Vec::new();
    for s in o.subpasses.iter_mut().filter(|s| s.pipeline_bind_point == vk::PipelineBindPoint::GRAPHICS) {
        let f = Box::new(vk::FragmentShadingRateAttachmentInfoKHR {
            p_next: s.p_next,
            p_fragment_shading_rate_attachment: &*fsr_ref,
            shading_rate_attachment_texel_size: texel,
            ..Default::default()
        });
        s.p_next = &*f as *const _ as *const c_void;
        fsr.push(f);
    }
    let info = vk::RenderPassCreateInfo2 {
        p_next: o.p_next,
        flags: o.flags,
        attachment_count: o.attachments.len() as u32,
        p_attachments: ptr_or_null(&o.attachments),
        subpass_count: o.subpasses.len() as u32,
        p_subpasses: ptr_or_null(&o.subpasses),
        dependency_count: o.dependencies.len() as u32,
        p_dependencies: ptr_or_null(&o.dependencies),
        correlated_view_mask_count: o.correlation.len() as u32,
        p_correlated_view_masks: ptr_or_null(&o.correlation),
        ..Default::default()
    };
    RatePass { info, index, _owned: o, _fsr: fsr, _fsr_ref: fsr_ref }
}

fn texel(d: &DeviceState) -> Option<vk::Extent2D> {
    d.vrs.rates.filter(|_| d.vrs.enabled()).map(|r| vk::Extent2D { width: r.texel_width, height: r.texel_height })
}

fn adds(d: &DeviceState, o: &Owned2, app_fsr_or_fdm: bool) -> bool {
    let graphics = o.subpasses.iter().filter(|s| s.pipeline_bind_point == vk::PipelineBindPoint::GRAPHICS).count();
    rule::adds_rate_attachment(d.vrs.enabled(), app_fsr_or_fdm, false, graphics)
}

/// `vkCreateRenderPass`: the app's pass as `vkCreateRenderPass2` info with the rate attachment;
/// None where the layer leaves it alone.
///
/// # Safety
/// `ci` must be the app's valid create info, alive while the result is used.
pub(super) unsafe fn render_pass_v1(d: &DeviceState, ci: *const vk::RenderPassCreateInfo<'_>) -> Option<RatePass> {
    let texel = texel(d)?;
    // SAFETY: the caller's contract.
    let o = unsafe { owned_from_v1(&*ci) }?;
    adds(d, &o, false).then(|| with_rate(o, texel))
}

/// `vkCreateRenderPass2`: as `render_pass_v1`.
///
/// # Safety
/// As `render_pass_v1`.
pub(super) unsafe fn render_pass_v2(d: &DeviceState, ci: *const vk::RenderPassCreateInfo2<'_>) -> Option<RatePass> {
    let texel = texel(d)?;
    // SAFETY: the caller's contract.
    let o = unsafe { owned_from_v2(&*ci) };
    // SAFETY: as above.
    let alone = unsafe { v2_leave_alone(&o) };
    adds(d, &o, alone).then(|| with_rate(o, texel))
}

/// `vkCreateFramebuffer` for a pass with the layer's rate attachment: the app's info with the
/// rate image's view (or, imageless, its image info) appended.
pub(super) struct RateFramebuffer {
    pub info: vk::FramebufferCreateInfo<'static>,
    _views: Vec<vk::ImageView>,
    _image_infos: Vec<vk::FramebufferAttachmentImageInfo<'static>>,
    _attachments: Option<Box<vk::FramebufferAttachmentsCreateInfo<'static>>>,
    _format: Box<vk::Format>,
}

/// The rate image objects made for a framebuffer being created (registered once it exists).
pub(super) struct PendingRate(FbRate);

/// Builds the rate image for a framebuffer of a pass with the layer's rate attachment; None for
/// other passes. Err: the framebuffer cannot be given its rate image.
///
/// # Safety
/// `ci` must be the app's valid create info, alive while the result is used.
pub(super) unsafe fn framebuffer_info(d: &DeviceState, ci: *const vk::FramebufferCreateInfo<'_>) -> Result<Option<(RateFramebuffer, PendingRate)>, String> {
    // SAFETY: the caller's contract.
    let app = unsafe { &*ci };
    let Some(rp) = d.track.render_passes.get(app.render_pass.as_raw()) else { return Ok(None) };
    let (Some(index), Some(rates)) = (rp.layer_rate_attachment, d.vrs.rates) else { return Ok(None) };
    let masks: Vec<u32> = rp.subpasses.iter().map(|s| s.view_mask).collect();
    let (width, height, layers) = rule::pass_rate_extent(app.width, app.height, &masks, rates);
    let imageless = app.flags.contains(vk::FramebufferCreateFlags::IMAGELESS);
    // SAFETY: lifetimes erased: the copy lives only during the app's call.
    let mut info: vk::FramebufferCreateInfo<'static> = unsafe { std::mem::transmute(*app) };
    let format = Box::new(vk::Format::R8_UINT);
    let mut out = RateFramebuffer { info, _views: Vec::new(), _image_infos: Vec::new(), _attachments: None, _format: format };
    let key = MapKey { width, height, layers, eyes: vec![], foveation_generation: 0, views_generation: 0 };
    let mut img = RateImage {
        image: vk::Image::null(),
        memory: vk::DeviceMemory::null(),
        view: vk::ImageView::null(),
        staging: vk::Buffer::null(),
        staging_memory: vk::DeviceMemory::null(),
        uploaded: false,
        last_used_frame: 0,
    };
    if let Err(e) = image_objects(d, &key, &mut img) {
        destroy_image(d, &img);
        return Err(e);
    }
    if imageless {
        // SAFETY: a valid chain: the attachments info must come first (we replace it by a copy).
        let first = unsafe { (app.p_next as *const vk::BaseInStructure<'_>).as_ref() };
        if first.map(|b| b.s_type) != Some(vk::StructureType::FRAMEBUFFER_ATTACHMENTS_CREATE_INFO) {
            destroy_image(d, &img);
            return Err("imageless framebuffer whose chain does not start with VkFramebufferAttachmentsCreateInfo".into());
        }
        // SAFETY: the sType names this struct; its array is valid with its count.
        let a = unsafe { &*(app.p_next as *const vk::FramebufferAttachmentsCreateInfo<'static>) };
        // SAFETY: as above; lifetimes erased (used only during the app's call).
        out._image_infos = unsafe { super::convert::slice(a.p_attachment_image_infos, a.attachment_image_info_count) }.iter().map(|i| unsafe { std::mem::transmute_copy(i) }).collect();
        out._image_infos.push(vk::FramebufferAttachmentImageInfo {
            usage: vk::ImageUsageFlags::FRAGMENT_SHADING_RATE_ATTACHMENT_KHR | vk::ImageUsageFlags::TRANSFER_DST,
            width,
            height,
            layer_count: layers,
            view_format_count: 1,
            p_view_formats: &*out._format,
            ..Default::default()
        });
        let mut copy = Box::new(*a);
        copy.attachment_image_info_count = out._image_infos.len() as u32;
        copy.p_attachment_image_infos = out._image_infos.as_ptr();
        info.p_next = &*copy as *const _ as *const c_void;
        info.attachment_count = out._image_infos.len() as u32;
        out._attachments = Some(copy);
    } else {
        // SAFETY: valid with its count.
        out._views = unsafe { super::convert::slice(app.p_attachments, app.attachment_count) }.to_vec();
        out._views.push(img.view);
        info.p_attachments = out._views.as_ptr();
        info.attachment_count = out._views.len() as u32;
    }
    out.info = info;
    let rate = FbRate { image: img.image, memory: img.memory, view: img.view, width, height, layers, index, content: Content::Undefined };
    Ok(Some((out, PendingRate(rate))))
}

/// After `vkCreateFramebuffer`: keeps the rate image with the framebuffer, or destroys it when
/// the call failed.
pub(super) fn framebuffer_created(d: &DeviceState, fb: Option<vk::Framebuffer>, pending: PendingRate) {
    match fb {
        Some(fb) => {
            lock(&d.vrs.pass_objects).framebuffers.insert(fb.as_raw(), pending.0);
        }
        None => destroy_fb_rate(d, &pending.0),
    }
}

fn destroy_fb_rate(d: &DeviceState, r: &FbRate) {
    // SAFETY: our objects; the framebuffer (and so every command buffer using them) is done.
    unsafe {
        d.fns.destroy_image_view(r.view, None);
        d.fns.destroy_image(r.image, None);
        d.fns.free_memory(r.memory, None);
    }
}

/// `vkDestroyFramebuffer` (after it went down).
pub(super) fn forget_framebuffer(d: &DeviceState, fb: u64) {
    let r = lock(&d.vrs.pass_objects).framebuffers.remove(&fb);
    if let Some(r) = r {
        destroy_fb_rate(d, &r);
    }
}

/// `vkCmdBeginRenderPass(2)` of an imageless framebuffer: the app's begin info with the rate
/// view appended to `VkRenderPassAttachmentBeginInfo`.
pub(super) struct RateBegin {
    pub info: vk::RenderPassBeginInfo<'static>,
    _attachments: Box<vk::RenderPassAttachmentBeginInfo<'static>>,
    _views: Vec<vk::ImageView>,
}

/// Before `vkCmdBeginRenderPass(2)` goes down: for a pass with the layer's rate attachment,
/// records into `cb` what makes the framebuffer's rate image hold this pass's map (the eye's
/// rates for an eye pass with VRS on, else 1×1 everywhere) when it holds another. Some: the
/// begin info to use instead of the app's (imageless framebuffers).
///
/// # Safety
/// `info` must be the app's valid begin info, alive while the result is used; `cb` recording
/// outside a render pass instance.
pub(super) unsafe fn for_render_pass_begin(d: &DeviceState, cb: vk::CommandBuffer, kind: PassKind, info: *const vk::RenderPassBeginInfo<'_>) -> Option<RateBegin> {
    if !d.vrs.enabled() {
        return None;
    }
    // SAFETY: the caller's contract.
    let app = unsafe { &*info };
    let rp = d.track.render_passes.get(app.render_pass.as_raw())?;
    rp.layer_rate_attachment?;
    let fb = lock(&d.vrs.pass_objects).framebuffers.get(&app.framebuffer.as_raw()).cloned()?;
    let rates = d.vrs.rates?;
    // SAFETY: as above.
    let begin = unsafe { super::convert::render_pass_begin(app) };
    let imageless_views = begin.attachment_views.clone();
    let mode = d.vrs.mode(&d.config);
    let mut eyes = Vec::new();
    let want = if mode == Mode::Off {
        Content::Neutral
    } else {
        let pass = d.track.render_pass_instance(shared(), kind, begin);
        // Secondary command buffers inherit the render pass, rate attachment included.
        match plan(d, mode, &pass, false, || false) {
            Ok(None) => Content::Neutral,
            Ok(Some((mut key, e, _))) => {
                key.width = fb.width;
                key.height = fb.height;
                key.layers = fb.layers;
                eyes = e.into_iter().filter(|e| e.layer < fb.layers).collect();
                key.eyes.retain(|(l, _, _)| *l < fb.layers);
                count(d, |s| s.passes += 1);
                log_kind_once(d, kind, pass.view_mask() != 0, &key);
                Content::Map(key)
            }
            Err(why) => {
                not_applied(d, why, kind);
                Content::Neutral
            }
        }
    };
    if want != fb.content {
        let r = match &want {
            Content::Map(key) => staging_for(d, key, &eyes, rates).map(|buffer| record_fb_upload(d, cb, &fb, Some(buffer))),
            _ => {
                record_fb_upload(d, cb, &fb, None);
                Ok(())
            }
        };
        match r {
            Ok(()) => {
                if let Some(f) = lock(&d.vrs.pass_objects).framebuffers.get_mut(&app.framebuffer.as_raw()) {
                    f.content = want;
                }
            }
            Err(e) => {
                tracing::warn!("vrs rate map for a render pass: {e}");
                if fb.content == Content::Undefined {
                    record_fb_upload(d, cb, &fb, None);
                    if let Some(f) = lock(&d.vrs.pass_objects).framebuffers.get_mut(&app.framebuffer.as_raw()) {
                        f.content = Content::Neutral;
                    }
                }
            }
        }
    }
    let views = imageless_views?;
    // SAFETY: a valid chain: the attachment begin info must come first (we replace it by a copy).
    let first = unsafe { (app.p_next as *const vk::BaseInStructure<'_>).as_ref() };
    if first.map(|b| b.s_type) != Some(vk::StructureType::RENDER_PASS_ATTACHMENT_BEGIN_INFO) {
        tracing::warn!("imageless framebuffer begun with a chain that does not start with VkRenderPassAttachmentBeginInfo: no rate view");
        return None;
    }
    // SAFETY: the sType names this struct.
    let a = unsafe { *(app.p_next as *const vk::RenderPassAttachmentBeginInfo<'static>) };
    let mut out_views: Vec<vk::ImageView> = views.iter().map(|&v| vk::ImageView::from_raw(v)).collect();
    out_views.truncate(fb.index as usize);
    out_views.push(fb.view);
    let mut copy = Box::new(a);
    copy.attachment_count = out_views.len() as u32;
    copy.p_attachments = out_views.as_ptr();
    // SAFETY: lifetimes erased: the copy lives only during the app's call.
    let mut bi: vk::RenderPassBeginInfo<'static> = unsafe { std::mem::transmute(*app) };
    bi.p_next = &*copy as *const _ as *const c_void;
    Some(RateBegin { info: bi, _attachments: copy, _views: out_views })
}

/// The immutable staging buffer holding `key`'s map, made when first needed.
fn staging_for(d: &DeviceState, key: &MapKey, eyes: &[EyeRates], rates: DeviceRates) -> Result<vk::Buffer, String> {
    let now = FRAMES_ENDED.load(Ordering::Relaxed);
    if let Some(s) = lock(&d.vrs.pass_objects).stagings.get_mut(key) {
        s.last_used_frame = now;
        return Ok(s.buffer);
    }
    retire(d, now);
    let data: Vec<u8> = (0..key.layers).flat_map(|l| rule::rate_layer(key.width, key.height, rates.texel_width, rates.texel_height, l, eyes)).collect();
    let mut img = RateImage {
        image: vk::Image::null(),
        memory: vk::DeviceMemory::null(),
        view: vk::ImageView::null(),
        staging: vk::Buffer::null(),
        staging_memory: vk::DeviceMemory::null(),
        uploaded: false,
        last_used_frame: now,
    };
    if let Err(e) = staging_objects(d, &data, &mut img) {
        destroy_image(d, &img);
        return Err(e);
    }
    let mut o = lock(&d.vrs.pass_objects);
    if let Some(s) = o.stagings.get_mut(key) {
        // Another thread made the same map first: ours was never used.
        let b = s.buffer;
        drop(o);
        destroy_image(d, &img);
        return Ok(b);
    }
    o.stagings.insert(key.clone(), Staging { buffer: img.staging, memory: img.staging_memory, last_used_frame: now });
    drop(o);
    count(d, |s| s.maps_built += 1);
    Ok(img.staging)
}

/// Records the framebuffer rate image's new content: `staging`'s map, or 1×1 (0) everywhere.
fn record_fb_upload(d: &DeviceState, cb: vk::CommandBuffer, fb: &FbRate, staging: Option<vk::Buffer>) {
    record_rate_content(d, cb, fb.image, fb.layers, (fb.width, fb.height), staging);
}

/// Records new content for a rate image, outside a render pass instance: `staging`'s map, or 1×1
/// (0) everywhere. Every texel is rewritten, so the old content (and layout) need not be kept; the
/// first barrier waits for earlier passes' reads of the image (none for a new one).
fn record_rate_content(d: &DeviceState, cb: vk::CommandBuffer, image: vk::Image, layers: u32, extent: (u32, u32), staging: Option<vk::Buffer>) {
    let range = vk::ImageSubresourceRange { aspect_mask: vk::ImageAspectFlags::COLOR, base_mip_level: 0, level_count: 1, base_array_layer: 0, layer_count: layers };
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
    let f = d.fns.fp_v1_0();
    let fsr = vk::PipelineStageFlags::FRAGMENT_SHADING_RATE_ATTACHMENT_KHR;
    // SAFETY: `cb` is recording outside a render pass instance (the app is about to begin one);
    // the image lives until retired frames after its last use (or with its framebuffer), the
    // staging buffer until frames after its last use.
    unsafe {
        (f.cmd_pipeline_barrier)(cb, fsr, vk::PipelineStageFlags::TRANSFER, vk::DependencyFlags::empty(), 0, std::ptr::null(), 0, std::ptr::null(), 1, &to_dst);
        match staging {
            Some(buffer) => {
                let region = vk::BufferImageCopy {
                    buffer_offset: 0,
                    buffer_row_length: 0,
                    buffer_image_height: 0,
                    image_subresource: vk::ImageSubresourceLayers { aspect_mask: vk::ImageAspectFlags::COLOR, mip_level: 0, base_array_layer: 0, layer_count: layers },
                    image_offset: vk::Offset3D::default(),
                    image_extent: vk::Extent3D { width: extent.0, height: extent.1, depth: 1 },
                };
                (f.cmd_copy_buffer_to_image)(cb, buffer, image, vk::ImageLayout::TRANSFER_DST_OPTIMAL, 1, &region);
            }
            None => {
                let zero = vk::ClearColorValue { uint32: [0; 4] };
                (f.cmd_clear_color_image)(cb, image, vk::ImageLayout::TRANSFER_DST_OPTIMAL, &zero, 1, &range);
            }
        }
        (f.cmd_pipeline_barrier)(cb, vk::PipelineStageFlags::TRANSFER, fsr, vk::DependencyFlags::empty(), 0, std::ptr::null(), 0, std::ptr::null(), 1, &to_fsr);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn reference(attachment: u32, layout: vk::ImageLayout) -> vk::AttachmentReference {
        vk::AttachmentReference { attachment, layout }
    }

    /// Reads a v2 subpass's array (test helper over the rewrite's own pointers).
    fn refs(p: *const vk::AttachmentReference2<'_>, n: u32) -> Vec<(u32, vk::ImageLayout, vk::ImageAspectFlags)> {
        // SAFETY: the rewrite's arrays, alive with it.
        unsafe { super::super::convert::slice(p, n) }.iter().map(|r| (r.attachment, r.layout, r.aspect_mask)).collect()
    }

    #[test]
    fn v1_pass_is_translated_and_gets_the_rate_attachment_last() {
        use vk::ImageLayout as L;
        let atts = [
            vk::AttachmentDescription { format: vk::Format::R8G8B8A8_SRGB, samples: vk::SampleCountFlags::TYPE_1, load_op: vk::AttachmentLoadOp::CLEAR, ..Default::default() },
            vk::AttachmentDescription { format: vk::Format::D24_UNORM_S8_UINT, samples: vk::SampleCountFlags::TYPE_1, ..Default::default() },
        ];
        let color = [reference(0, L::COLOR_ATTACHMENT_OPTIMAL)];
        let depth = reference(1, L::DEPTH_STENCIL_ATTACHMENT_OPTIMAL);
        let input = [reference(1, L::DEPTH_STENCIL_READ_ONLY_OPTIMAL)];
        let subs = [
            vk::SubpassDescription::default().pipeline_bind_point(vk::PipelineBindPoint::GRAPHICS).color_attachments(&color).depth_stencil_attachment(&depth),
            vk::SubpassDescription::default().pipeline_bind_point(vk::PipelineBindPoint::GRAPHICS).input_attachments(&input).color_attachments(&color),
        ];
        let deps = [vk::SubpassDependency { src_subpass: 0, dst_subpass: 1, dependency_flags: vk::DependencyFlags::VIEW_LOCAL, ..Default::default() }];
        let masks = [0b11u32, 0b11];
        let offsets = [0i32];
        let corr = [0b11u32];
        let mut mv = vk::RenderPassMultiviewCreateInfo::default().view_masks(&masks).view_offsets(&offsets).correlation_masks(&corr);
        let ci = vk::RenderPassCreateInfo::default().attachments(&atts).subpasses(&subs).dependencies(&deps).push_next(&mut mv);
        // SAFETY: a valid create info built above.
        let o = unsafe { owned_from_v1(&ci) }.expect("multiview is translated");
        let rp = with_rate(o, vk::Extent2D { width: 16, height: 16 });
        assert_eq!(rp.index, 2, "appended after the app's attachments");
        let i = &rp.info;
        assert_eq!(i.attachment_count, 3);
        assert!(i.p_next.is_null(), "v1 chain translated, not forwarded");
        // SAFETY: the rewrite's arrays.
        let (a, s, dep, c) = unsafe {
            (
                super::super::convert::slice(i.p_attachments, i.attachment_count),
                super::super::convert::slice(i.p_subpasses, i.subpass_count),
                super::super::convert::slice(i.p_dependencies, i.dependency_count),
                super::super::convert::slice(i.p_correlated_view_masks, i.correlated_view_mask_count),
            )
        };
        assert_eq!(a[0].format, vk::Format::R8G8B8A8_SRGB);
        assert_eq!(a[0].load_op, vk::AttachmentLoadOp::CLEAR);
        assert_eq!((a[2].format, a[2].load_op, a[2].samples), (vk::Format::R8_UINT, vk::AttachmentLoadOp::LOAD, vk::SampleCountFlags::TYPE_1));
        assert_eq!((a[2].initial_layout, a[2].final_layout), (L::FRAGMENT_SHADING_RATE_ATTACHMENT_OPTIMAL_KHR, L::FRAGMENT_SHADING_RATE_ATTACHMENT_OPTIMAL_KHR));
        assert_eq!((s[0].view_mask, s[1].view_mask), (0b11, 0b11));
        assert_eq!(refs(s[0].p_color_attachments, s[0].color_attachment_count)[0].0, 0);
        assert!(s[0].p_resolve_attachments.is_null());
        // SAFETY: as above.
        assert_eq!(unsafe { (*s[0].p_depth_stencil_attachment).attachment }, 1);
        assert!(s[1].p_depth_stencil_attachment.is_null());
        // A v1 input attachment reads all of its format's aspects.
        assert_eq!(refs(s[1].p_input_attachments, 1)[0].2, vk::ImageAspectFlags::DEPTH | vk::ImageAspectFlags::STENCIL);
        assert_eq!((dep[0].view_offset, dep[0].dependency_flags), (0, vk::DependencyFlags::VIEW_LOCAL));
        assert_eq!(c, &[0b11]);
        for sub in s {
            // SAFETY: the chain the rewrite built.
            let f = unsafe { super::super::convert::find_in_chain::<vk::FragmentShadingRateAttachmentInfoKHR<'_>>(sub.p_next, vk::StructureType::FRAGMENT_SHADING_RATE_ATTACHMENT_INFO_KHR) }.expect("every graphics subpass");
            // SAFETY: as above.
            let f = unsafe { &*f };
            assert_eq!(f.shading_rate_attachment_texel_size, vk::Extent2D { width: 16, height: 16 });
            // SAFETY: as above.
            let r = unsafe { &*f.p_fragment_shading_rate_attachment };
            assert_eq!((r.attachment, r.layout), (2, L::FRAGMENT_SHADING_RATE_ATTACHMENT_OPTIMAL_KHR));
        }
    }

    #[test]
    fn v1_chains_with_unknown_structs_are_left_alone() {
        let mut fdm = vk::RenderPassFragmentDensityMapCreateInfoEXT::default();
        let ci = vk::RenderPassCreateInfo::default().push_next(&mut fdm);
        // SAFETY: a valid create info built above.
        assert!(unsafe { owned_from_v1(&ci) }.is_none());
    }

    #[test]
    fn v2_pass_keeps_its_chains_and_own_rate_attachments_are_left_alone() {
        let atts = [vk::AttachmentDescription2::default().format(vk::Format::B8G8R8A8_SRGB).samples(vk::SampleCountFlags::TYPE_4)];
        let color = [vk::AttachmentReference2::default().attachment(0).layout(vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL)];
        let mut dsr = vk::SubpassDescriptionDepthStencilResolve::default();
        let subs = [
            vk::SubpassDescription2::default().pipeline_bind_point(vk::PipelineBindPoint::GRAPHICS).color_attachments(&color).push_next(&mut dsr),
            vk::SubpassDescription2::default().pipeline_bind_point(vk::PipelineBindPoint::COMPUTE),
        ];
        let ci = vk::RenderPassCreateInfo2::default().attachments(&atts).subpasses(&subs);
        // SAFETY: a valid create info built above.
        let o = unsafe { owned_from_v2(&ci) };
        // SAFETY: as above.
        assert!(!unsafe { v2_leave_alone(&o) });
        let rp = with_rate(o, vk::Extent2D { width: 8, height: 8 });
        assert_eq!(rp.index, 1);
        // SAFETY: the rewrite's arrays.
        let s = unsafe { super::super::convert::slice(rp.info.p_subpasses, rp.info.subpass_count) };
        // SAFETY: the chain the rewrite built: ours first, then the app's.
        let first = unsafe { &*(s[0].p_next as *const vk::BaseInStructure<'_>) };
        assert_eq!(first.s_type, vk::StructureType::FRAGMENT_SHADING_RATE_ATTACHMENT_INFO_KHR);
        // SAFETY: as above.
        assert_eq!(unsafe { (*first.p_next).s_type }, vk::StructureType::SUBPASS_DESCRIPTION_DEPTH_STENCIL_RESOLVE);
        assert!(s[1].p_next.is_null(), "compute subpasses get none");

        let fsr_ref = vk::AttachmentReference2::default().attachment(0).layout(vk::ImageLayout::FRAGMENT_SHADING_RATE_ATTACHMENT_OPTIMAL_KHR);
        let mut own = vk::FragmentShadingRateAttachmentInfoKHR::default().fragment_shading_rate_attachment(&fsr_ref);
        let subs = [vk::SubpassDescription2::default().pipeline_bind_point(vk::PipelineBindPoint::GRAPHICS).push_next(&mut own)];
        let ci = vk::RenderPassCreateInfo2::default().attachments(&atts).subpasses(&subs);
        // SAFETY: as above.
        assert!(unsafe { v2_leave_alone(&owned_from_v2(&ci)) });
    }

    #[test]
    fn input_aspects_by_format() {
        assert_eq!(format_aspects(vk::Format::D32_SFLOAT), vk::ImageAspectFlags::DEPTH);
        assert_eq!(format_aspects(vk::Format::S8_UINT), vk::ImageAspectFlags::STENCIL);
        assert_eq!(format_aspects(vk::Format::R16G16B16A16_SFLOAT), vk::ImageAspectFlags::COLOR);
    }
}
