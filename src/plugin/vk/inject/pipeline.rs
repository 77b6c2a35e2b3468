//! The layer's pipelines for injected draws, cached per (feature, variant, pass compatibility) —
//! created on first use, never per draw, and only when the device has what they need. A feature
//! describes its pipeline (`PipelineDesc`: shaders, vertex layout, colour writes); the chassis
//! makes it compatible with the app's pass: the render pass + subpass (render pass objects) or the
//! attachment formats, samples and view mask (dynamic rendering). Depth state is the same for
//! every injected draw: test ALWAYS, write on, the fail depth pinned by the viewport.

use crate::track::caps;
use crate::track::cmd::{AttachmentUse, PassInstance};
use crate::track::eye_pass::{EyeLayout, MaskPlan};
use crate::plugin::vk::{gpu, DeviceState};
use ash::vk::{self, Handle};
use std::collections::HashMap;
use std::sync::{Mutex, MutexGuard};

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// What makes a layer pipeline usable inside an app's pass.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub(crate) enum PassKey {
    /// Compatible with the app's render pass + subpass (the subpass carries its view mask).
    RenderPass { render_pass: u64, subpass: u32, samples: u32, colors: u32, multiview: bool },
    /// `VkPipelineRenderingCreateInfo` for dynamic rendering.
    Dynamic { colors: Vec<vk::Format>, depth: vk::Format, stencil: vk::Format, samples: u32, view_mask: u32 },
}

impl PassKey {
    fn multiview(&self) -> bool {
        match self {
            PassKey::RenderPass { multiview, .. } => *multiview,
            PassKey::Dynamic { view_mask, .. } => *view_mask != 0,
        }
    }
    /// What the device must have been created with for a pipeline in such a pass.
    pub(crate) fn needs(&self) -> caps::Needs {
        match self {
            PassKey::RenderPass { multiview, .. } => caps::Needs { multiview: *multiview, ..Default::default() },
            PassKey::Dynamic { view_mask, .. } => caps::Needs { multiview: *view_mask != 0, dynamic_rendering: true, ..Default::default() },
        }
    }
}

/// A cached pipeline's key: the feature, its variant (e.g. debug tint) and the pass.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub(crate) struct PipelineKey {
    pub feature: &'static str,
    pub variant: u32,
    pub pass: PassKey,
}

/// A feature's injected draw pipeline.
pub(crate) struct PipelineDesc {
    /// SPIR-V 1.0 vertex shader, and its multiview variant (declares the MultiView capability).
    pub vert: &'static [u8],
    pub vert_multiview: &'static [u8],
    /// None: depth-only, no fragment shader (the GPU's depth-only fast path).
    pub frag: Option<&'static [u8]>,
    pub stride: u32,
    pub attributes: Vec<vk::VertexInputAttributeDescription>,
    /// Colour writes to the pass's first attachment (a debug tint); none otherwise.
    pub write_first_color: bool,
    /// Binding 0 advances per instance, not per vertex (per-draw parameters as attributes).
    pub per_instance: bool,
    /// The feature's own pipeline layout (descriptor sets); None: the shared empty one.
    pub layout: Option<vk::PipelineLayout>,
    /// The depth test: ALWAYS replaces the cleared depth whatever the app's compare op is; a
    /// draw that must not cover what the app already drew uses the app's "nearer" op.
    pub depth_compare_op: vk::CompareOp,
}

/// Why the layer has no pipeline for a key.
#[derive(Debug)]
pub(crate) enum PipelineError {
    /// The device was created without a capability the pipeline needs (logged once, by name).
    DeviceLacks,
    /// A Vulkan call failed.
    Vulkan(String),
}

#[derive(Default)]
struct Objects {
    layout: vk::PipelineLayout,
    /// Shader modules by the address of their static SPIR-V.
    modules: HashMap<usize, vk::ShaderModule>,
    pipelines: HashMap<PipelineKey, vk::Pipeline>,
    logged_lacks: std::collections::HashSet<&'static str>,
}

/// Per-device pipeline cache. Its lock guards bookkeeping only; objects are created unlocked.
#[derive(Default)]
pub(crate) struct Cache {
    objects: Mutex<Objects>,
}

/// The pass compatibility of `pass` for `plan`, or None for a shape the layer does not handle.
pub(crate) fn pass_key(d: &DeviceState, pass: &PassInstance, plan: &MaskPlan) -> Option<PassKey> {
    let samples_of_view = |a: &AttachmentUse| {
        let v = a.image_view.as_ref()?;
        d.track.images.get(v.image).map(|i| i.samples.as_raw())
    };
    if let Some(r) = &pass.rendering {
        let fmt = |a: &AttachmentUse| a.image_view.as_ref().map_or(vk::Format::UNDEFINED, |v| v.format);
        let depth = r.depth.as_ref()?;
        let colors = r.color.iter().map(|c| if c.attachment.view == 0 { vk::Format::UNDEFINED } else { fmt(&c.attachment) }).collect();
        let stencil = r.stencil.as_ref().filter(|s| s.attachment.view != 0).map_or(vk::Format::UNDEFINED, |s| fmt(&s.attachment));
        return Some(PassKey::Dynamic { colors, depth: fmt(&depth.attachment), stencil, samples: samples_of_view(&depth.attachment)?, view_mask: r.view_mask });
    }
    let rp = pass.render_pass.as_ref()?;
    let sub = rp.subpasses.get(pass.subpass as usize)?;
    let depth = rp.attachments.get(sub.depth_stencil?.used()? as usize)?;
    let multiview = sub.view_mask != 0;
    if multiview != (plan.layout == EyeLayout::Multiview) {
        return None;
    }
    Some(PassKey::RenderPass { render_pass: rp.handle, subpass: pass.subpass, samples: depth.samples.as_raw(), colors: sub.color.len() as u32, multiview })
}

/// Logs, once per device and capability, that a feature is not applied because the device lacks
/// what its draw needs.
fn log_device_lacks_once(d: &DeviceState, what: &'static str) {
    if lock(&d.inject.pipelines.objects).logged_lacks.insert(what) {
        tracing::warn!(
            "the app's device was created without {what}, which the layer's draw for this pass needs: \
             the mask / foveation is not applied to such passes on this device (logged once)"
        );
    }
}

/// The cached pipeline for `key`, created from `desc` on first use.
pub(crate) fn get(d: &DeviceState, key: &PipelineKey, desc: impl FnOnce() -> PipelineDesc) -> Result<vk::Pipeline, PipelineError> {
    if let Some(lacking) = caps::missing(&d.caps, &key.pass.needs()) {
        log_device_lacks_once(d, lacking);
        return Err(PipelineError::DeviceLacks);
    }
    let cache = &d.inject.pipelines;
    if let Some(p) = lock(&cache.objects).pipelines.get(key) {
        return Ok(*p);
    }
    let desc = desc();
    let layout = match desc.layout {
        Some(l) => l,
        None => layout(d)?,
    };
    let vert = module(d, if key.pass.multiview() { desc.vert_multiview } else { desc.vert })?;
    let frag = desc.frag.map(|f| module(d, f)).transpose()?;
    let (samples, colors) = match &key.pass {
        PassKey::RenderPass { samples, colors, .. } => (*samples, *colors as usize),
        PassKey::Dynamic { colors, samples, .. } => (*samples, colors.len()),
    };
    let bindings = [vk::VertexInputBindingDescription { binding: 0, stride: desc.stride, input_rate: if desc.per_instance { vk::VertexInputRate::INSTANCE } else { vk::VertexInputRate::VERTEX } }];
    let color_writes: Vec<vk::ColorComponentFlags> = (0..colors).map(|i| if desc.write_first_color && i == 0 { vk::ColorComponentFlags::RGBA } else { vk::ColorComponentFlags::empty() }).collect();
    let target = match &key.pass {
        PassKey::RenderPass { render_pass, subpass, .. } => gpu::Target::Subpass(vk::RenderPass::from_raw(*render_pass), *subpass),
        // The pass may carry variable-rate shading's attachment, which every pipeline bound in it
        // must be made for.
        PassKey::Dynamic { colors, depth, stencil, view_mask, .. } => gpu::Target::Rendering {
            info: vk::PipelineRenderingCreateInfo::default().view_mask(*view_mask).color_attachment_formats(colors).depth_attachment_format(*depth).stencil_attachment_format(*stencil),
            fsr_attachment: d.caps.fsr_attachment,
        },
    };
    let draw = gpu::Draw {
        vert,
        frag,
        bindings: &bindings,
        attributes: &desc.attributes,
        samples: vk::SampleCountFlags::from_raw(samples),
        // ALWAYS + write: the draw replaces the cleared depth with the failing value, whatever
        // the app's compare op is.
        depth_compare: Some(desc.depth_compare_op),
        color_writes: &color_writes,
        layout,
        target,
    };
    // SAFETY: every object the draw names is alive (the app's render pass is in use by the pass
    // being recorded).
    let p = unsafe { gpu::graphics_pipeline(&d.fns, draw) }.map_err(|e| PipelineError::Vulkan(e.to_string()))?;
    let mut o = lock(&cache.objects);
    if let Some(existing) = o.pipelines.get(key) {
        let existing = *existing;
        drop(o);
        // SAFETY: ours was just created and never used.
        unsafe { d.fns.destroy_pipeline(p, None) };
        return Ok(existing);
    }
    o.pipelines.insert(key.clone(), p);
    drop(o);
    tracing::debug!(?key, "injection pipeline created");
    Ok(p)
}

/// The shared empty pipeline layout: injected draws use no descriptor sets and no push constants.
fn layout(d: &DeviceState) -> Result<vk::PipelineLayout, PipelineError> {
    let cache = &d.inject.pipelines;
    if let Some(l) = Some(lock(&cache.objects).layout).filter(|l| *l != vk::PipelineLayout::null()) {
        return Ok(l);
    }
    // SAFETY: a valid, empty create info.
    let layout = unsafe { d.fns.create_pipeline_layout(&vk::PipelineLayoutCreateInfo::default(), None) }.map_err(|e| PipelineError::Vulkan(e.to_string()))?;
    let mut o = lock(&cache.objects);
    if o.layout != vk::PipelineLayout::null() {
        let existing = o.layout;
        drop(o);
        // SAFETY: ours, never used (another thread made one meanwhile).
        unsafe { d.fns.destroy_pipeline_layout(layout, None) };
        return Ok(existing);
    }
    o.layout = layout;
    Ok(layout)
}

/// The shader module of static SPIR-V, created once per device.
fn module(d: &DeviceState, bytes: &'static [u8]) -> Result<vk::ShaderModule, PipelineError> {
    let cache = &d.inject.pipelines;
    let id = bytes.as_ptr() as usize;
    if let Some(m) = lock(&cache.objects).modules.get(&id) {
        return Ok(*m);
    }
    let words = ash::util::read_spv(&mut std::io::Cursor::new(bytes)).map_err(|e| PipelineError::Vulkan(e.to_string()))?;
    // SAFETY: valid SPIR-V compiled at build time (multiview variants are only requested for
    // multiview passes, which `needs` checked the device enabled); a valid create info.
    let m = unsafe { d.fns.create_shader_module(&vk::ShaderModuleCreateInfo::default().code(&words), None) }.map_err(|e| PipelineError::Vulkan(e.to_string()))?;
    let mut o = lock(&cache.objects);
    if let Some(existing) = o.modules.get(&id) {
        let existing = *existing;
        drop(o);
        // SAFETY: ours, never used.
        unsafe { d.fns.destroy_shader_module(m, None) };
        return Ok(existing);
    }
    o.modules.insert(id, m);
    Ok(m)
}

/// The app destroyed a render pass: pipelines made against it go too (its handle may be reused).
/// Every command buffer that used them also used the render pass, and the app must have waited
/// for those before destroying it.
pub(crate) fn forget_render_pass(d: &DeviceState, render_pass: u64) {
    let gone: Vec<vk::Pipeline> = {
        let mut o = lock(&d.inject.pipelines.objects);
        let keys: Vec<PipelineKey> = o.pipelines.keys().filter(|k| matches!(k.pass, PassKey::RenderPass { render_pass: r, .. } if r == render_pass)).cloned().collect();
        keys.iter().filter_map(|k| o.pipelines.remove(k)).collect()
    };
    for p in gone {
        // SAFETY: our pipeline; its command buffers completed (see above).
        unsafe { d.fns.destroy_pipeline(p, None) };
    }
}

/// Destroys every cached object (at vkDestroyDevice; the device is idle).
pub(crate) fn destroy(d: &DeviceState) {
    let o = std::mem::take(&mut *lock(&d.inject.pipelines.objects));
    // SAFETY: our objects; the device is idle.
    unsafe {
        for p in o.pipelines.values() {
            d.fns.destroy_pipeline(*p, None);
        }
        if o.layout != vk::PipelineLayout::null() {
            d.fns.destroy_pipeline_layout(o.layout, None);
        }
        for m in o.modules.values() {
            d.fns.destroy_shader_module(*m, None);
        }
    }
}
