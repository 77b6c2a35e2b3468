//! Descriptor hooks and dispatches, for the data-flow walk (`track::flow`): which image views
//! each descriptor set holds (layouts, allocation, updates, copies, update templates, pushes) and
//! what each compute dispatch reads and writes. Every call goes down unchanged; only image
//! descriptors are recorded (`track::descriptors`).

use crate::plugin::vk::{convert, DeviceState};
use super::{cmd, hook};
use crate::track::descriptors::{self, LayoutBinding, SetLayout, TemplateEntry, UpdateTemplate, Write};
use ash::vk::{self, Handle};
use std::ffi::c_void;

/// The image views of one `VkWriteDescriptorSet` (None per element for other types).
///
/// # Safety
/// `w` is a valid write of the app's, during its call.
unsafe fn write(w: &vk::WriteDescriptorSet<'_>) -> Write {
    let views = if descriptors::ImageAccess::of(w.descriptor_type).is_some() && !w.p_image_info.is_null() {
        // SAFETY: image types carry `descriptorCount` image infos.
        unsafe { convert::slice(w.p_image_info, w.descriptor_count) }.iter().map(|i| Some(i.image_view.as_raw())).collect()
    } else {
        vec![None; w.descriptor_count as usize]
    };
    Write { binding: w.dst_binding, element: w.dst_array_element, ty: w.descriptor_type, views }
}

/// The writes a template applies to `data`.
///
/// # Safety
/// `data` is the app's valid template data for `t`, during its call.
unsafe fn template_writes(t: &UpdateTemplate, data: *const c_void) -> Vec<Write> {
    let mut out = Vec::new();
    for e in &t.entries {
        let views = if descriptors::ImageAccess::of(e.ty).is_some() && !data.is_null() {
            (0..e.count as usize)
                .map(|i| {
                    // SAFETY: the template promises a `VkDescriptorImageInfo` at each
                    // offset + i × stride for image types.
                    let info = unsafe { (data as *const u8).add(e.offset + i * e.stride).cast::<vk::DescriptorImageInfo>().read_unaligned() };
                    Some(info.image_view.as_raw())
                })
                .collect()
        } else {
            vec![None; e.count as usize]
        };
        out.push(Write { binding: e.binding, element: e.element, ty: e.ty, views });
    }
    out
}

pub(in crate::vk) unsafe extern "system" fn create_descriptor_set_layout(
    device: vk::Device,
    ci: *const vk::DescriptorSetLayoutCreateInfo<'_>,
    allocator: *const vk::AllocationCallbacks<'_>,
    out: *mut vk::DescriptorSetLayout,
) -> vk::Result {
    hook(
        "vkCreateDescriptorSetLayout",
        device,
        vk::Result::ERROR_INITIALIZATION_FAILED,
        // SAFETY: forwarding the app's arguments unchanged (uncounted: the app's object).
        |d| unsafe { (d.next.fp_v1_0().create_descriptor_set_layout)(device, ci, allocator, out) },
        |d, r| {
            if r == vk::Result::SUCCESS {
                // SAFETY: on success the handle was written; the info is valid during the call.
                let (h, ci) = unsafe { (*out, &*ci) };
                // SAFETY: the binding array is valid with its count.
                let bindings = unsafe { convert::slice(ci.p_bindings, ci.binding_count) }
                    .iter()
                    .map(|b| LayoutBinding { binding: b.binding, ty: b.descriptor_type, count: b.descriptor_count })
                    .collect();
                // SAFETY: a valid pNext chain.
                let flags = unsafe { binding_flags(ci.p_next) };
                d.track.descriptors.add_layout(h.as_raw(), SetLayout::new(bindings, ci.flags, &flags));
            }
            Ok(())
        },
    )
}

/// `VkDescriptorSetLayoutBindingFlagsCreateInfo::pBindingFlags`, if chained.
///
/// # Safety
/// `p_next` is a valid chain.
unsafe fn binding_flags(p_next: *const c_void) -> Vec<vk::DescriptorBindingFlags> {
    let mut p = p_next as *const vk::BaseInStructure<'_>;
    // SAFETY: walking a valid chain; the matching sType identifies the struct.
    unsafe {
        while let Some(s) = p.as_ref() {
            if s.s_type == vk::StructureType::DESCRIPTOR_SET_LAYOUT_BINDING_FLAGS_CREATE_INFO {
                let f = &*(p as *const vk::DescriptorSetLayoutBindingFlagsCreateInfo<'_>);
                return convert::slice(f.p_binding_flags, f.binding_count).to_vec();
            }
            p = s.p_next;
        }
    }
    Vec::new()
}

pub(in crate::vk) unsafe extern "system" fn destroy_descriptor_set_layout(device: vk::Device, layout: vk::DescriptorSetLayout, allocator: *const vk::AllocationCallbacks<'_>) {
    hook(
        "vkDestroyDescriptorSetLayout",
        device,
        (),
        // SAFETY: forwarding the app's arguments unchanged.
        |d| unsafe { (d.next.fp_v1_0().destroy_descriptor_set_layout)(device, layout, allocator) },
        |d, ()| {
            d.track.descriptors.destroy_layout(layout.as_raw());
            Ok(())
        },
    )
}

pub(in crate::vk) unsafe extern "system" fn allocate_descriptor_sets(device: vk::Device, info: *const vk::DescriptorSetAllocateInfo<'_>, out: *mut vk::DescriptorSet) -> vk::Result {
    hook(
        "vkAllocateDescriptorSets",
        device,
        vk::Result::ERROR_INITIALIZATION_FAILED,
        // SAFETY: forwarding the app's arguments unchanged.
        |d| unsafe { (d.next.fp_v1_0().allocate_descriptor_sets)(device, info, out) },
        |d, r| {
            if r == vk::Result::SUCCESS {
                // SAFETY: on success `descriptorSetCount` sets were written; the info is valid.
                let (info, sets) = unsafe { (&*info, convert::slice(out, (*info).descriptor_set_count)) };
                // SAFETY: the layout array has the same count.
                let layouts: Vec<u64> = unsafe { convert::slice(info.p_set_layouts, info.descriptor_set_count) }.iter().map(|l| l.as_raw()).collect();
                let sets: Vec<u64> = sets.iter().map(|s| s.as_raw()).collect();
                d.track.descriptors.allocate(info.descriptor_pool.as_raw(), &sets, &layouts);
            }
            Ok(())
        },
    )
}

pub(in crate::vk) unsafe extern "system" fn free_descriptor_sets(device: vk::Device, pool: vk::DescriptorPool, n: u32, sets: *const vk::DescriptorSet) -> vk::Result {
    hook(
        "vkFreeDescriptorSets",
        device,
        vk::Result::ERROR_INITIALIZATION_FAILED,
        // SAFETY: forwarding the app's arguments unchanged.
        |d| unsafe { (d.next.fp_v1_0().free_descriptor_sets)(device, pool, n, sets) },
        |d, _| {
            // SAFETY: `n` handles (some may be null) during the app's call.
            let sets: Vec<u64> = unsafe { convert::slice(sets, n) }.iter().map(|s| s.as_raw()).collect();
            d.track.descriptors.free(&sets);
            Ok(())
        },
    )
}

pub(in crate::vk) unsafe extern "system" fn reset_descriptor_pool(device: vk::Device, pool: vk::DescriptorPool, flags: vk::DescriptorPoolResetFlags) -> vk::Result {
    hook(
        "vkResetDescriptorPool",
        device,
        vk::Result::ERROR_INITIALIZATION_FAILED,
        // SAFETY: forwarding the app's arguments unchanged.
        |d| unsafe { (d.next.fp_v1_0().reset_descriptor_pool)(device, pool, flags) },
        |d, _| {
            d.track.descriptors.reset_pool(pool.as_raw());
            Ok(())
        },
    )
}

pub(in crate::vk) unsafe extern "system" fn destroy_descriptor_pool(device: vk::Device, pool: vk::DescriptorPool, allocator: *const vk::AllocationCallbacks<'_>) {
    hook(
        "vkDestroyDescriptorPool",
        device,
        (),
        // SAFETY: forwarding the app's arguments unchanged (uncounted: the app's object).
        |d| unsafe { (d.next.fp_v1_0().destroy_descriptor_pool)(device, pool, allocator) },
        |d, ()| {
            d.track.descriptors.reset_pool(pool.as_raw());
            Ok(())
        },
    )
}

pub(in crate::vk) unsafe extern "system" fn update_descriptor_sets(
    device: vk::Device,
    nw: u32,
    writes: *const vk::WriteDescriptorSet<'_>,
    nc: u32,
    copies: *const vk::CopyDescriptorSet<'_>,
) {
    hook(
        "vkUpdateDescriptorSets",
        device,
        (),
        // SAFETY: forwarding the app's arguments unchanged.
        |d| unsafe { (d.next.fp_v1_0().update_descriptor_sets)(device, nw, writes, nc, copies) },
        |d, ()| {
            // SAFETY: arrays valid with their counts during the app's call.
            let (w, c) = unsafe { (convert::slice(writes, nw), convert::slice(copies, nc)) };
            // SAFETY: each write is valid.
            let w: Vec<(u64, Write)> = w.iter().map(|w| (w.dst_set.as_raw(), unsafe { write(w) })).collect();
            let c: Vec<descriptors::Copy> = c
                .iter()
                .map(|c| descriptors::Copy {
                    src_set: c.src_set.as_raw(),
                    src_binding: c.src_binding,
                    src_element: c.src_array_element,
                    dst_set: c.dst_set.as_raw(),
                    dst_binding: c.dst_binding,
                    dst_element: c.dst_array_element,
                    count: c.descriptor_count,
                })
                .collect();
            d.track.descriptors.update(&w, &c);
            Ok(())
        },
    )
}

pub(in crate::vk) unsafe extern "system" fn create_descriptor_update_template(
    device: vk::Device,
    ci: *const vk::DescriptorUpdateTemplateCreateInfo<'_>,
    allocator: *const vk::AllocationCallbacks<'_>,
    out: *mut vk::DescriptorUpdateTemplate,
) -> vk::Result {
    hook(
        "vkCreateDescriptorUpdateTemplate",
        device,
        vk::Result::ERROR_INITIALIZATION_FAILED,
        // SAFETY: forwarding the app's arguments unchanged (`fns` resolves the KHR alias).
        |d| unsafe { (d.fns.fp_v1_1().create_descriptor_update_template)(device, ci, allocator, out) },
        |d, r| {
            if r == vk::Result::SUCCESS {
                // SAFETY: on success the handle was written; the info and its entries are valid.
                let (h, ci) = unsafe { (*out, &*ci) };
                // SAFETY: see above.
                let entries = unsafe { convert::slice(ci.p_descriptor_update_entries, ci.descriptor_update_entry_count) }
                    .iter()
                    .map(|e| TemplateEntry { binding: e.dst_binding, element: e.dst_array_element, count: e.descriptor_count, ty: e.descriptor_type, offset: e.offset, stride: e.stride })
                    .collect();
                let push = ci.template_type == vk::DescriptorUpdateTemplateType::PUSH_DESCRIPTORS_KHR;
                d.track.descriptors.add_template(h.as_raw(), UpdateTemplate { entries, push_set: push.then_some(ci.set), bind_point: ci.pipeline_bind_point });
            }
            Ok(())
        },
    )
}

pub(in crate::vk) unsafe extern "system" fn destroy_descriptor_update_template(device: vk::Device, t: vk::DescriptorUpdateTemplate, allocator: *const vk::AllocationCallbacks<'_>) {
    hook(
        "vkDestroyDescriptorUpdateTemplate",
        device,
        (),
        // SAFETY: forwarding the app's arguments unchanged.
        |d| unsafe { (d.fns.fp_v1_1().destroy_descriptor_update_template)(device, t, allocator) },
        |d, ()| {
            d.track.descriptors.destroy_template(t.as_raw());
            Ok(())
        },
    )
}

pub(in crate::vk) unsafe extern "system" fn update_descriptor_set_with_template(device: vk::Device, set: vk::DescriptorSet, t: vk::DescriptorUpdateTemplate, data: *const c_void) {
    hook(
        "vkUpdateDescriptorSetWithTemplate",
        device,
        (),
        // SAFETY: forwarding the app's arguments unchanged.
        |d| unsafe { (d.fns.fp_v1_1().update_descriptor_set_with_template)(device, set, t, data) },
        |d, ()| {
            if let Some(tpl) = d.track.descriptors.template(t.as_raw()) {
                // SAFETY: the app's data for this template, valid during its call.
                let writes = unsafe { template_writes(&tpl, data) };
                let w: Vec<(u64, Write)> = writes.into_iter().map(|w| (set.as_raw(), w)).collect();
                d.track.descriptors.update(&w, &[]);
            }
            Ok(())
        },
    )
}

pub(in crate::vk) unsafe extern "system" fn cmd_push_descriptor_set(
    cb: vk::CommandBuffer,
    bind_point: vk::PipelineBindPoint,
    layout: vk::PipelineLayout,
    set: u32,
    n: u32,
    writes: *const vk::WriteDescriptorSet<'_>,
) {
    cmd(
        "vkCmdPushDescriptorSetKHR",
        cb,
        (),
        |d| {
            if let Some(f) = d.ext.cmd_push_descriptor_set {
                // SAFETY: forwarding the app's arguments unchanged (handed out only when the
                // next layer has the command).
                unsafe { f(cb, bind_point, layout, set, n, writes) }
            }
        },
        |d, raw| {
            // SAFETY: `n` valid writes during the app's call.
            let w: Vec<Write> = unsafe { convert::slice(writes, n) }.iter().map(|w| unsafe { write(w) }).collect();
            let images = descriptors::pushed_images(&w);
            d.track.with_cb(raw, |s| s.push_descriptors(bind_point, set, images));
        },
    )
}

pub(in crate::vk) unsafe extern "system" fn cmd_push_descriptor_set_with_template(
    cb: vk::CommandBuffer,
    t: vk::DescriptorUpdateTemplate,
    layout: vk::PipelineLayout,
    set: u32,
    data: *const c_void,
) {
    cmd(
        "vkCmdPushDescriptorSetWithTemplateKHR",
        cb,
        (),
        |d| {
            if let Some(f) = d.ext.cmd_push_descriptor_set_with_template {
                // SAFETY: forwarding the app's arguments unchanged.
                unsafe { f(cb, t, layout, set, data) }
            }
        },
        |d, raw| {
            let Some(tpl) = d.track.descriptors.template(t.as_raw()) else { return };
            // SAFETY: the app's data for this template, valid during its call.
            let images = descriptors::pushed_images(&unsafe { template_writes(&tpl, data) });
            d.track.with_cb(raw, |s| s.push_descriptors(tpl.bind_point, set, images));
        },
    )
}

pub(in crate::vk) unsafe extern "system" fn cmd_bind_descriptor_buffers(cb: vk::CommandBuffer, n: u32, infos: *const vk::DescriptorBufferBindingInfoEXT<'_>) {
    cmd(
        "vkCmdBindDescriptorBuffersEXT",
        cb,
        (),
        |d| {
            if let Some(f) = d.ext.cmd_bind_descriptor_buffers {
                // SAFETY: forwarding the app's arguments unchanged.
                unsafe { f(cb, n, infos) }
            }
        },
        |d, raw| {
            d.track.with_cb(raw, |s| {
                if s.flow_on {
                    s.flow.blind("descriptor buffers");
                }
            });
        },
    )
}

/// Records a dispatch for the walk.
fn dispatched(d: &DeviceState, cb: u64) {
    d.track.with_cb(cb, |s| s.flow_dispatch());
}

pub(in crate::vk) unsafe extern "system" fn cmd_dispatch(cb: vk::CommandBuffer, x: u32, y: u32, z: u32) {
    // SAFETY: forwarding the app's arguments unchanged.
    cmd("vkCmdDispatch", cb, (), |d| unsafe { (d.fns.fp_v1_0().cmd_dispatch)(cb, x, y, z) }, dispatched)
}

pub(in crate::vk) unsafe extern "system" fn cmd_dispatch_indirect(cb: vk::CommandBuffer, buffer: vk::Buffer, offset: vk::DeviceSize) {
    // SAFETY: forwarding the app's arguments unchanged.
    cmd("vkCmdDispatchIndirect", cb, (), |d| unsafe { (d.fns.fp_v1_0().cmd_dispatch_indirect)(cb, buffer, offset) }, dispatched)
}

pub(in crate::vk) unsafe extern "system" fn cmd_dispatch_base(cb: vk::CommandBuffer, bx: u32, by: u32, bz: u32, x: u32, y: u32, z: u32) {
    // SAFETY: forwarding the app's arguments unchanged (`fns` resolves the KHR alias).
    cmd("vkCmdDispatchBase", cb, (), |d| unsafe { (d.fns.fp_v1_1().cmd_dispatch_base)(cb, bx, by, bz, x, y, z) }, dispatched)
}
