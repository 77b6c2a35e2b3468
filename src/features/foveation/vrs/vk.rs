//! Variable-rate shading (foveation method 1) on the Vulkan side: a layer-owned
//! `VK_KHR_fragment_shading_rate` attachment (R8_UINT, one layer per view for multiview) chained
//! into the app's eye passes. The rate map comes from `rules`; the eye-pass test from
//! `track::eye_pass`; what the app's render passes, framebuffers and pipelines need so that an
//! attachment can be chained at all is `pass`.
//!
//! - `vkCmdBeginRendering`: an eye pass goes down with a copy of the app's `VkRenderingInfo`
//!   whose chain starts with `VkRenderingFragmentShadingRateAttachmentInfoKHR`, naming a rate
//!   image of the map's shape (built when a (foveation generation, views generation, extent,
//!   eyes) shape is first seen — never per frame).
//! - `vkCmdBeginRenderPass(2)` of a pass with the layer's rate attachment: the framebuffer's rate
//!   image gets this pass's map (the eye's rates for an eye pass with VRS on, 1×1 everywhere
//!   otherwise: those passes are unchanged).
//!
//! Uploads cannot be skipped: every command buffer that uses a rate image records the image's
//! upload itself, before its pass (a small buffer-to-image copy behind a barrier that waits for
//! earlier passes' reads), so whichever command buffer runs first, and a command buffer recorded
//! once and resubmitted, always finds the map it was recorded with. Images and staging buffers
//! are held by the recordings that use them (`plugin::vk::lifetime`); the caches keep only the current
//! generations'.

use crate::features::foveation::FoveationSettings;
use super::rules::{self as rule, EyeRates, NotApplied, VrsFrameStats};
use crate::track::caps::DeviceRates;
use super::submission;
use crate::plugin::vk::inject::When;
use crate::core::pass::NotMasked;
use crate::core::rect::PixelRect;
use crate::core::stats::FeatureStats;
use crate::features::foveation::Method;
use crate::plugin::settings::Settings;
use crate::bridge::shared;
use crate::track::cmd::{PassInstance, PassKind};
use crate::track::eye_pass::{self, Facts};
use crate::plugin::vk::feature::{Amended, AmendedRenderPass, Destroyed, DeviceInit, Plugin, RenderPassInfo, VkFeature};
use crate::plugin::vk::lifetime::{self, Garbage};
use crate::plugin::vk::DeviceState;
use ash::vk::{self, Handle};
use std::any::Any;
use std::collections::{HashMap, HashSet};
use std::ffi::c_void;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};

pub(super) fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// What makes one rate image.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub(super) struct MapKey {
    pub width: u32,
    pub height: u32,
    pub layers: u32,
    /// (rate-image layer, view, rect) of every eye.
    pub eyes: Vec<(u32, u32, PixelRect)>,
    pub foveation_generation: u64,
    pub views_generation: u64,
}

/// A rate image of the layer's with the staging buffer holding its map; destroyed (through the
/// device's trash) when the cache and every recording that used it let go.
pub(crate) struct RateImage {
    pub image: vk::Image,
    pub memory: vk::DeviceMemory,
    pub view: vk::ImageView,
    pub staging: vk::Buffer,
    pub staging_memory: vk::DeviceMemory,
    trash: Arc<Mutex<Vec<Garbage>>>,
}

impl RateImage {
    /// No objects yet; whatever is created into it goes to the device's trash when it drops.
    pub(super) fn empty(d: &DeviceState) -> RateImage {
        RateImage {
            image: vk::Image::null(),
            memory: vk::DeviceMemory::null(),
            view: vk::ImageView::null(),
            staging: vk::Buffer::null(),
            staging_memory: vk::DeviceMemory::null(),
            trash: d.lifetime.trash.clone(),
        }
    }
    /// Takes the image objects out (their owner destroys them).
    pub(super) fn take_image(&mut self) -> (vk::Image, vk::DeviceMemory, vk::ImageView) {
        (std::mem::take(&mut self.image), std::mem::take(&mut self.memory), std::mem::take(&mut self.view))
    }
}

impl Drop for RateImage {
    fn drop(&mut self) {
        let mut t = lock(&self.trash);
        if self.image != vk::Image::null() {
            t.push(Garbage::Image(self.view, self.image, self.memory));
        }
        if self.staging != vk::Buffer::null() {
            t.push(Garbage::Buffer(self.staging, self.staging_memory));
        }
    }
}

#[derive(Default)]
struct Books {
    frame: VrsFrameStats,
    total: VrsFrameStats,
    logged_kinds: HashSet<(PassKind, bool)>,
    logged_reasons: HashSet<NotApplied>,
    logged_submission: HashSet<PassKind>,
    /// Rate images (dynamic rendering) and staging buffers (render pass objects) of the current
    /// generations, by map.
    images: HashMap<MapKey, Arc<RateImage>>,
}

/// Per-device VRS state. Locks are held only around bookkeeping, never while calling down.
pub(crate) struct VrsDevice {
    layer_enabled: bool,
    /// The device's texel size and layering when the layer enabled `attachmentFragmentShadingRate`.
    pub(super) rates: Option<DeviceRates>,
    pub(super) memory: vk::PhysicalDeviceMemoryProperties,
    used: AtomicBool,
    books: Mutex<Books>,
    /// Render pass objects: framebuffers' rate images.
    pub(super) framebuffers: Mutex<HashMap<u64, super::pass::FbRate>>,
    /// Rate images of recordings done with them, by (texels, layers), for later recordings of
    /// passes planned at submission (`submission`): an app that records every frame does not
    /// make an image every frame.
    pub(super) rate_pool: submission::RatePool,
}

impl VrsDevice {
    /// The device's object of this feature (the registry made one for every device).
    pub(crate) fn of(d: &DeviceState) -> &VrsDevice {
        d.features.get::<VrsDevice>()
    }
}

/// What `foveation.*` asks of this device now.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Mode {
    Off,
    On,
    /// `foveation.method = vrs` on a device without attachment rates.
    Unsupported,
}

impl Plugin for VrsDevice {
    /// `foveation.*`, shared with RDM (the registry lists a key once).
    fn new(init: &DeviceInit<'_>) -> VrsDevice {
        VrsDevice {
            layer_enabled: init.settings.enabled,
            rates: init.rates,
            memory: init.memory,
            used: AtomicBool::new(false),
            books: Mutex::default(),
            framebuffers: Mutex::default(),
            rate_pool: Arc::default(),
        }
    }
    fn empty_stats() -> Box<dyn FeatureStats> {
        Box::new(VrsFrameStats::default())
    }
    /// On with VRS as the method in effect: `vrs`, or `auto` where VRS acted this frame.
    fn enabled(s: &Settings, frame: &crate::core::stats::FrameStats) -> bool {
        let active = frame.get::<VrsFrameStats>().is_some_and(|v| v.passes > 0 || !v.not_applied.is_empty());
        s.of::<FoveationSettings>().enabled && (s.of::<FoveationSettings>().method == Method::Vrs || (s.of::<FoveationSettings>().method == Method::Auto && active))
    }
}

impl VrsDevice {
    /// The layer enabled `attachmentFragmentShadingRate` on this device (pipelines get the state).
    pub fn enabled(&self) -> bool {
        self.layer_enabled && self.rates.is_some()
    }

    pub(super) fn mode(&self, s: &Settings) -> Mode {
        if !self.layer_enabled || !s.of::<FoveationSettings>().enabled {
            return Mode::Off;
        }
        // VRS does not depend on the device type: `software` only turns auto's RDM off.
        match s.of::<FoveationSettings>().method.resolve(self.rates.is_some(), false) {
            Some(Method::Vrs) if self.rates.is_some() => Mode::On,
            Some(Method::Vrs) => Mode::Unsupported,
            _ => Mode::Off,
        }
    }
}

pub(super) fn count(d: &DeviceState, f: impl Fn(&mut VrsFrameStats)) {
    let me = VrsDevice::of(d);
    me.used.store(true, Ordering::Relaxed);
    let mut b = lock(&me.books);
    f(&mut b.frame);
    f(&mut b.total);
}

pub(super) fn not_applied(d: &DeviceState, why: NotApplied, kind: PassKind) {
    count(d, |s| s.count_not_applied(why));
    if lock(&VrsDevice::of(d).books).logged_reasons.insert(why) {
        match why {
            NotApplied::Unsupported => tracing::warn!("vrs unsupported on this device (no attachmentFragmentShadingRate enabled by the layer): foveation.method = vrs does nothing here; auto would use rdm"),
            _ => tracing::info!(?kind, "vrs not applied to an eye pass: {} (logged once per reason)", why.name()),
        }
    }
}

/// `vkCmdBeginRendering` with the rate attachment: a copy of the app's info whose chain starts
/// with ours; both live while the call goes down.
struct Rendering {
    pub info: vk::RenderingInfo<'static>,
    _fsr: Box<vk::RenderingFragmentShadingRateAttachmentInfoKHR<'static>>,
}

/// Decides whether this rendering is an eye pass that gets a rate attachment; records the rate
/// image's upload into `cb` (before the pass) when it is new.
///
/// # Safety
/// `info` must be the app's valid rendering info, alive while the result is used; `cb` recording
/// outside a render pass instance.
unsafe fn for_rendering(d: &DeviceState, cb: vk::CommandBuffer, info: *const vk::RenderingInfo<'_>) -> Option<Rendering> {
    let mode = VrsDevice::of(d).mode(&d.settings());
    if mode == Mode::Off {
        return None;
    }
    // SAFETY: the caller's contract.
    let app = unsafe { &*info };
    // SAFETY: as above.
    let (area, rendering) = unsafe { crate::plugin::vk::convert::rendering(&d.track, app) };
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
        flow_at: None,
    };
    let secondary = app.flags.contains(vk::RenderingFlags::CONTENTS_SECONDARY_COMMAND_BUFFERS);
    let app_fsr = || {
        // SAFETY: a valid chain.
        unsafe { crate::plugin::vk::convert::find_in_chain::<vk::BaseInStructure<'_>>(app.p_next, vk::StructureType::RENDERING_FRAGMENT_SHADING_RATE_ATTACHMENT_INFO_KHR) }.is_some()
    };
    let r = plan(d, mode, &pass, secondary, app_fsr, When::Recording);
    // The view of the rate image, and the map to log (None: filled at each submission).
    let made = match r {
        // A target the walk tied to its eyes: its rect may move before the recording is
        // submitted (dynamic resolution), so its map is that submission's (`submission`).
        Ok(Some((_, _, _, eye_pass::Via::Walk))) if !resuming => match submission_rendering(d, cb, &pass) {
            Ok(made) => made.map(|(v, rates)| (v, rates, None)),
            Err(why) => {
                not_applied(d, why, PassKind::Dynamic);
                return None;
            }
        },
        Ok(Some((key, eyes, rates, _))) => image_for(d, cb, &key, &eyes, rates).map(|v| (v, rates, Some(key))),
        Ok(None) => return None,
        // Eyes the walk of each submission gives (`submission`).
        Err(NotApplied::EyeUnknown) if !resuming && !app_fsr() && submission::awaits_walk(d, &pass, secondary) => match submission_rendering(d, cb, &pass) {
            Ok(made) => made.map(|(v, rates)| (v, rates, None)),
            Err(why) => {
                not_applied(d, why, PassKind::Dynamic);
                return None;
            }
        },
        Err(why) => {
            if !resuming {
                not_applied(d, why, PassKind::Dynamic);
            }
            return None;
        }
    };
    let (view, rates, key) = match made {
        Ok(v) => v,
        Err(e) => {
            d.warn_repeated("vrs rate image", &e);
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
    if let (false, Some(key)) = (resuming, key) {
        count(d, |s| s.passes += 1);
        log_kind_once(d, PassKind::Dynamic, key.layers > 1 || pass.view_mask() != 0, &key);
    }
    Some(Rendering { info: copy, _fsr: fsr })
}

/// A rendering whose eyes each submission's walk gives: a rate image and staging buffer of the
/// recording's own (`submission::SubmissionMap`), its upload recorded into `cb` now.
fn submission_rendering(d: &DeviceState, cb: vk::CommandBuffer, pass: &PassInstance) -> Result<Result<(vk::ImageView, DeviceRates), String>, NotApplied> {
    let rates = VrsDevice::of(d).rates.ok_or(NotApplied::Unsupported)?;
    let layers = submission::layers(d, pass)?;
    let color = pass.rendering.as_ref().and_then(|r| r.color.first()).and_then(|c| c.attachment.image_view.as_ref());
    let image = color.and_then(|v| d.track.images.get(v.image)).map(|i| (i.extent.width, i.extent.height));
    let a = pass.render_area;
    let (width, height) = rule::map_extent(image, PixelRect { x: a.x, y: a.y, width: a.width, height: a.height }, rates);
    let (fovea, views) = (shared().foveation(), shared().views());
    let key = MapKey { width, height, layers, eyes: Vec::new(), foveation_generation: fovea.generation, views_generation: views.generation };
    let shape = (width, height, layers);
    let img = match submission::take_pooled(d, shape) {
        Some(img) => img,
        None => {
            let mut img = RateImage::empty(d);
            if let Err(e) = image_objects(d, &key, &mut img) {
                return Ok(Err(e));
            }
            img
        }
    };
    let (image, view) = (img.image, img.view);
    let map = match submission::SubmissionMap::new(d, pass.clone(), PassKind::Dynamic, shape, Some(img)) {
        Ok(m) => m,
        Err(e) => return Ok(Err(e)),
    };
    record_rate_content(d, cb, image, layers, (width, height), Some(map.staging.buffer));
    log_submission_once(d, PassKind::Dynamic, &key);
    lifetime::hold(d, cb.as_raw(), Arc::new(map));
    Ok(Ok((view, rates)))
}

fn log_submission_once(d: &DeviceState, kind: PassKind, key: &MapKey) {
    if lock(&VrsDevice::of(d).books).logged_submission.insert(kind) {
        tracing::info!("vrs on {kind:?} passes whose eyes are known only at each submission (recorded before the data-flow walk knew their target, or dynamic resolution): rate attachment {}x{} texels x {} layer(s), its map written at every submission", key.width, key.height, key.layers);
    }
}

/// `vkCmdBeginRenderPass(2)` (after it went down, the pass tracked) of a pass without the
/// layer's rate attachment: counts an eye pass VRS would apply to as not applied.
fn on_render_pass_begin(d: &DeviceState, cb: vk::CommandBuffer, secondary: bool) {
    let mode = VrsDevice::of(d).mode(&d.settings());
    if mode == Mode::Off {
        return;
    }
    let Some(Some(pass)) = d.track.with_cb(cb.as_raw(), |s| s.pass.clone()) else { return };
    if pass.render_pass.as_ref().is_some_and(|rp| rp.layer_rate_attachment.is_some()) {
        // Handled before it went down (`for_render_pass_begin`).
        return;
    }
    match plan(d, mode, &pass, secondary, || false, When::Recording) {
        Ok(None) => {}
        Ok(Some(_)) => not_applied(d, NotApplied::RenderPass, pass.kind),
        Err(why) => not_applied(d, why, pass.kind),
    }
}

/// The map, its eyes, the device's rates, and how the pass was tied to its eyes.
type Plan = (MapKey, Vec<EyeRates>, DeviceRates, eye_pass::Via);

/// The rate image an eye pass needs; Ok(None) for a pass that is no eye pass. `when`: its eyes
/// as known while it is recorded, or at a submission (`submission`).
pub(super) fn plan(d: &DeviceState, mode: Mode, pass: &PassInstance, secondary: bool, app_fsr: impl Fn() -> bool, when: When) -> Result<Option<Plan>, NotApplied> {
    let intermediate = d.settings().intermediate;
    let eyes_fn = |a: &crate::track::cmd::AttachmentUse| crate::plugin::vk::inject::eyes_at(d, a, intermediate, when, pass.flow_at);
    let facts = Facts { secondary_contents: false, intermediate_enabled: intermediate, eyes: &eyes_fn, explicit_clear: None };
    let (att, sources, via) = match eye_pass::find_eyes(pass, &facts) {
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
    let rates = VrsDevice::of(d).rates.ok_or(NotApplied::Unsupported)?;
    let (views, fovea) = (shared().views(), shared().foveation());
    let shape = rule::PassShape {
        base_layer: att.image_view.as_ref().map_or(0, |v| v.range.base_array_layer),
        view_mask: pass.view_mask(),
        layered: pass.rendering.as_ref().is_some_and(|r| r.layer_count > 1) || pass.framebuffer.as_ref().is_some_and(|f| f.layers > 1),
    };
    let fov_of = |view: u32| views.app_fovs.get(view as usize).copied();
    let fovea_of = |view: u32| fovea.views.iter().find(|f| f.view == view).copied();
    let (eyes, layers) = rule::pass_eyes(&sources, shape, rates, &fov_of, &fovea_of)?;
    let image = att.image_view.as_ref().and_then(|v| d.track.images.get(v.image)).map(|i| (i.extent.width, i.extent.height));
    let a = pass.render_area;
    let (width, height) = rule::map_extent(image, PixelRect { x: a.x, y: a.y, width: a.width, height: a.height }, rates);
    let key = MapKey {
        width,
        height,
        layers,
        eyes: eyes.iter().map(|e| (e.layer, e.fovea.view, e.rect)).collect(),
        foveation_generation: fovea.generation,
        views_generation: views.generation,
    };
    Ok(Some((key, eyes, rates, via)))
}

fn log_kind_once(d: &DeviceState, kind: PassKind, multiview: bool, key: &MapKey) {
    if lock(&VrsDevice::of(d).books).logged_kinds.insert((kind, multiview)) {
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

/// The view of the rate image for `key`, built when new; its upload is recorded into `cb` (before
/// the pass) and the recording holds the image.
fn image_for(d: &DeviceState, cb: vk::CommandBuffer, key: &MapKey, eyes: &[EyeRates], rates: DeviceRates) -> Result<vk::ImageView, String> {
    let img = cached_map(d, key, eyes, rates, true)?;
    record_rate_content(d, cb, img.image, key.layers, (key.width, key.height), Some(img.staging));
    let view = img.view;
    lifetime::hold(d, cb.as_raw(), img);
    Ok(view)
}

/// The cached rate image (`with_image`) or staging buffer alone holding `key`'s map, made when
/// first needed. The cache keeps the current generations' maps only (at most 16).
fn cached_map(d: &DeviceState, key: &MapKey, eyes: &[EyeRates], rates: DeviceRates, with_image: bool) -> Result<Arc<RateImage>, String> {
    let me = VrsDevice::of(d);
    let mut cache_key = key.clone();
    if !with_image {
        // Staging-only maps (render pass objects) are told apart from images of the same shape.
        cache_key.layers |= 1 << 31;
    }
    {
        let mut b = lock(&me.books);
        if let Some(i) = b.images.get(&cache_key) {
            return Ok(i.clone());
        }
        b.images.retain(|k, _| (k.foveation_generation, k.views_generation) == (key.foveation_generation, key.views_generation));
        if b.images.len() >= 16 {
            b.images.clear();
        }
    }
    let data: Vec<u8> = (0..key.layers).flat_map(|l| rule::rate_layer(key.width, key.height, rates.texel_width, rates.texel_height, l, eyes)).collect();
    let mut img = RateImage::empty(d);
    if with_image {
        image_objects(d, key, &mut img)?;
    }
    staging_objects(d, &data, &mut img)?;
    let img = Arc::new(img);
    let mut b = lock(&me.books);
    if let Some(existing) = b.images.get(&cache_key) {
        // Another thread built the same map first: ours goes to the trash unused.
        return Ok(existing.clone());
    }
    b.images.insert(cache_key, img.clone());
    drop(b);
    count(d, |s| s.maps_built += 1);
    tracing::debug!(w = key.width, h = key.height, layers = key.layers, with_image, "vrs rate map built");
    Ok(img)
}

fn memory_type(d: &DeviceState, bits: u32, wanted: vk::MemoryPropertyFlags) -> Option<u32> {
    lifetime::memory_type(&VrsDevice::of(d).memory, bits, wanted)
}

/// The rate image (`key`'s extent and layers) and its view, into `img`.
pub(super) fn image_objects(d: &DeviceState, key: &MapKey, img: &mut RateImage) -> Result<(), String> {
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
    // SAFETY: valid create / allocate infos; every object is ours, released through the trash by `img`'s owner on error.
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
pub(super) fn staging_objects(d: &DeviceState, data: &[u8], img: &mut RateImage) -> Result<(), String> {
    let e = |e: vk::Result| e.to_string();
    // SAFETY: valid create / allocate infos; every object is ours, released through the trash
    // by `img`'s owner on error.
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

/// `vkCmdBeginRenderPass(2)` of an imageless framebuffer: the app's begin info with the rate
/// view appended to `VkRenderPassAttachmentBeginInfo`.
struct RateBegin {
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
unsafe fn for_render_pass_begin(d: &DeviceState, cb: vk::CommandBuffer, kind: PassKind, info: *const vk::RenderPassBeginInfo<'_>) -> Option<RateBegin> {
    if !VrsDevice::of(d).enabled() {
        return None;
    }
    // SAFETY: the caller's contract.
    let app = unsafe { &*info };
    let rp = d.track.render_passes.get(app.render_pass.as_raw())?;
    rp.layer_rate_attachment?;
    let fb = lock(&VrsDevice::of(d).framebuffers).get(&app.framebuffer.as_raw()).cloned()?;
    let rates = VrsDevice::of(d).rates?;
    // SAFETY: as above.
    let begin = unsafe { crate::plugin::vk::convert::render_pass_begin(app) };
    let imageless_views = begin.attachment_views.clone();
    let mode = VrsDevice::of(d).mode(&d.settings());
    let mut submitted = false;
    // Every begin records the framebuffer's rate content it needs (never "already there": another
    // command buffer may run in between, or this one may be resubmitted after others).
    let map = if mode == Mode::Off {
        None
    } else {
        let pass = d.track.render_pass_instance(shared(), kind, begin);
        // Secondary command buffers inherit the render pass, rate attachment included.
        let planned = plan(d, mode, &pass, false, || false, When::Recording);
        let walked = matches!(planned, Ok(Some((_, _, _, eye_pass::Via::Walk))));
        match planned {
            Ok(None) => None,
            // Eyes the walk of each submission gives (a target the walk tied to its eyes: its rect
            // may move before the recording is submitted): the framebuffer's rate image is
            // uploaded from a staging buffer of the recording's own, written then (`submission`).
            _ if walked || matches!(planned, Err(NotApplied::EyeUnknown)) && submission::awaits_walk(d, &pass, false) => {
                let made = submission::layers(d, &pass).map_err(|why| why.name().to_string()).and_then(|_| submission::SubmissionMap::new(d, pass.clone(), kind, (fb.width, fb.height, fb.layers), None));
                match made {
                    Ok(m) => {
                        let key = MapKey { width: fb.width, height: fb.height, layers: fb.layers, eyes: Vec::new(), foveation_generation: 0, views_generation: 0 };
                        log_submission_once(d, kind, &key);
                        record_rate_content(d, cb, fb.image, fb.layers, (fb.width, fb.height), Some(m.staging.buffer));
                        lifetime::hold(d, cb.as_raw(), Arc::new(m));
                        submitted = true;
                    }
                    Err(e) => {
                        d.warn_repeated("vrs rate map filled at submission", &e);
                        not_applied(d, NotApplied::LayerError, kind);
                    }
                }
                None
            }
            Ok(Some((mut key, e, _, _))) => {
                key.width = fb.width;
                key.height = fb.height;
                key.layers = fb.layers;
                let eyes: Vec<EyeRates> = e.into_iter().filter(|e| e.layer < fb.layers).collect();
                key.eyes.retain(|(l, _, _)| *l < fb.layers);
                count(d, |s| s.passes += 1);
                log_kind_once(d, kind, pass.view_mask() != 0, &key);
                Some((key, eyes))
            }
            Err(why) => {
                not_applied(d, why, kind);
                None
            }
        }
    };
    let staging = match map {
        Some((key, eyes)) => match cached_map(d, &key, &eyes, rates, false) {
            Ok(m) => Some(m),
            Err(e) => {
                d.warn_repeated("vrs rate map for a render pass", &e);
                None
            }
        },
        None => None,
    };
    if !submitted {
        record_rate_content(d, cb, fb.image, fb.layers, (fb.width, fb.height), staging.as_ref().map(|m| m.staging));
    }
    if let Some(m) = staging {
        lifetime::hold(d, cb.as_raw(), m);
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

/// Records new content for a rate image, outside a render pass instance: `staging`'s map, or 1×1
/// (0) everywhere. Every texel is rewritten, so the old content (and layout) need not be kept; the
/// first barrier waits for earlier passes' reads of the image (none for a new one).
fn record_rate_content(d: &DeviceState, cb: vk::CommandBuffer, image: vk::Image, layers: u32, extent: (u32, u32), staging: Option<vk::Buffer>) {
    let range = vk::ImageSubresourceRange { aspect_mask: vk::ImageAspectFlags::COLOR, base_mip_level: 0, level_count: 1, base_array_layer: 0, layer_count: layers };
    let to_dst = crate::plugin::vk::gpu::image_barrier(image, range, (vk::ImageLayout::UNDEFINED, vk::ImageLayout::TRANSFER_DST_OPTIMAL), (vk::AccessFlags::empty(), vk::AccessFlags::TRANSFER_WRITE));
    let to_fsr = crate::plugin::vk::gpu::image_barrier(image, range, (vk::ImageLayout::TRANSFER_DST_OPTIMAL, vk::ImageLayout::FRAGMENT_SHADING_RATE_ATTACHMENT_OPTIMAL_KHR), (vk::AccessFlags::TRANSFER_WRITE, vk::AccessFlags::FRAGMENT_SHADING_RATE_ATTACHMENT_READ_KHR));
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


impl VkFeature for VrsDevice {
    fn id(&self) -> &'static str {
        "vrs"
    }
    fn take_frame(&self) -> Box<dyn FeatureStats> {
        Box::new(std::mem::take(&mut lock(&self.books).frame))
    }
    fn summary(&self) -> Option<String> {
        self.used.load(Ordering::Relaxed).then(|| lock(&self.books).total.summary())
    }
    unsafe fn amend_render_pass(&self, d: &DeviceState, ci: RenderPassInfo) -> Option<AmendedRenderPass> {
        // SAFETY: the app's valid create info (the trait's contract).
        let rp = unsafe {
            match ci {
                RenderPassInfo::V1(ci) => super::pass::render_pass_v1(d, ci),
                RenderPassInfo::V2(ci) => super::pass::render_pass_v2(d, ci),
            }
        }?;
        let (info, index) = (rp.info, rp.index);
        Some(AmendedRenderPass { amended: Amended { info, _keep: Box::new(rp) }, appended_attachment: index })
    }
    unsafe fn amend_framebuffer(&self, d: &DeviceState, ci: *const vk::FramebufferCreateInfo<'_>, pending: &mut Option<Box<dyn Any>>) -> Option<Amended<vk::FramebufferCreateInfo<'static>>> {
        // SAFETY: the app's valid create info (the trait's contract).
        match unsafe { super::pass::framebuffer_info(d, ci) } {
            Ok(Some((f, rate))) => {
                *pending = Some(Box::new(rate));
                let info = f.info;
                Some(Amended { info, _keep: Box::new(f) })
            }
            Ok(None) => None,
            Err(e) => {
                d.warn_repeated("vrs rate image for a framebuffer", &e);
                None
            }
        }
    }
    fn framebuffer_created(&self, d: &DeviceState, fb: Option<vk::Framebuffer>, pending: Box<dyn Any>) {
        if let Ok(rate) = pending.downcast::<super::pass::PendingRate>() {
            super::pass::framebuffer_created(d, fb, *rate);
        }
    }
    unsafe fn amend_pipelines(&self, d: &DeviceState, infos: *const vk::GraphicsPipelineCreateInfo<'_>, count: u32) -> Option<Amended<Vec<vk::GraphicsPipelineCreateInfo<'static>>>> {
        // SAFETY: the app's valid create infos (the trait's contract).
        let mut m = unsafe { super::pass::pipeline_infos(d, infos, count) }.filter(|m| m.changed > 0)?;
        let info = std::mem::take(&mut m.infos);
        Some(Amended { info, _keep: Box::new(m) })
    }
    fn destroyed(&self, d: &DeviceState, what: Destroyed) {
        if let Destroyed::Framebuffer(fb) = what {
            super::pass::forget_framebuffer(d, fb);
        }
    }
    unsafe fn amend_render_pass_begin(&self, d: &DeviceState, cb: vk::CommandBuffer, kind: PassKind, info: *const vk::RenderPassBeginInfo<'_>) -> Option<Amended<vk::RenderPassBeginInfo<'static>>> {
        // SAFETY: the trait's contract.
        let b = unsafe { for_render_pass_begin(d, cb, kind, info) }?;
        let info = b.info;
        Some(Amended { info, _keep: Box::new(b) })
    }
    unsafe fn amend_rendering(&self, d: &DeviceState, cb: vk::CommandBuffer, info: *const vk::RenderingInfo<'_>) -> Option<Amended<vk::RenderingInfo<'static>>> {
        // SAFETY: the trait's contract.
        let r = unsafe { for_rendering(d, cb, info) }?;
        let info = r.info;
        Some(Amended { info, _keep: Box::new(r) })
    }
    fn pass_begun(&self, d: &DeviceState, cb: vk::CommandBuffer, secondary: bool) {
        on_render_pass_begin(d, cb, secondary);
    }
    fn not_injected(&self, _d: &DeviceState, _s: &Settings, _why: NotMasked) {}
    /// Maps of passes whose eyes each submission's walk gives (`submission`).
    fn before_submit(&self, d: &DeviceState, cbs: &[u64]) {
        submission::before_submit(d, cbs);
    }
    fn destroy(&self, d: &DeviceState) {
        lock(&self.books).images.clear();
        lock(&self.rate_pool).clear();
        let fbs = std::mem::take(&mut *lock(&self.framebuffers));
        for r in fbs.values() {
            super::pass::destroy_fb_rate(d, r);
        }
    }
}
