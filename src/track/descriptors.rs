//! Which image views each descriptor set holds: what a draw or dispatch can read (sampled images,
//! combined image samplers, input attachments) and write (storage images). The data-flow walk
//! (`track::flow`) follows a full-screen draw back to the images it samples through these. Only
//! image descriptors are kept; a write of any other type clears the slots it covers. Sets whose
//! layout makes the walk blind (bindless arrays, update-after-bind) are marked, so the walk names
//! the reason instead of guessing.
#![forbid(unsafe_code)]

use ash::vk;
use std::collections::{BTreeMap, HashMap};
use std::sync::{Arc, Mutex, MutexGuard};

/// How a descriptor lets a shader use an image.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ImageAccess {
    /// `SAMPLED_IMAGE`, `COMBINED_IMAGE_SAMPLER`: read through a sampler.
    Sampled,
    /// `INPUT_ATTACHMENT`: read at the fragment's own pixel.
    Input,
    /// `STORAGE_IMAGE`: read and written at any pixel.
    Storage,
}

impl ImageAccess {
    /// The access of a descriptor type; None for types that hold no image view.
    pub fn of(ty: vk::DescriptorType) -> Option<ImageAccess> {
        match ty {
            vk::DescriptorType::SAMPLED_IMAGE | vk::DescriptorType::COMBINED_IMAGE_SAMPLER => Some(ImageAccess::Sampled),
            vk::DescriptorType::INPUT_ATTACHMENT => Some(ImageAccess::Input),
            vk::DescriptorType::STORAGE_IMAGE => Some(ImageAccess::Storage),
            _ => None,
        }
    }
}

/// An image view a descriptor holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct BoundImage {
    pub view: u64,
    pub access: ImageAccess,
}

/// Arrays larger than this are treated as bindless: the walk cannot tell which element a shader
/// reads, so it refuses rather than following hundreds of textures.
pub const BINDLESS_COUNT: u32 = 64;

/// `VkDescriptorSetLayoutBinding`, the parts that place descriptors.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LayoutBinding {
    pub binding: u32,
    pub ty: vk::DescriptorType,
    pub count: u32,
}

/// `VkDescriptorSetLayoutCreateInfo`.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct SetLayout {
    /// By binding number (ordered: consecutive-binding updates run into the next one).
    pub bindings: BTreeMap<u32, LayoutBinding>,
    /// Why the walk cannot see what a set of this layout is read through (bindless arrays,
    /// update-after-bind, push descriptors are fine); None when it can.
    pub blind: Option<&'static str>,
    /// `VK_DESCRIPTOR_SET_LAYOUT_CREATE_PUSH_DESCRIPTOR_BIT_KHR`.
    pub push: bool,
}

impl SetLayout {
    pub fn new(bindings: Vec<LayoutBinding>, flags: vk::DescriptorSetLayoutCreateFlags, binding_flags: &[vk::DescriptorBindingFlags]) -> SetLayout {
        let image_bindings = bindings.iter().filter(|b| ImageAccess::of(b.ty).is_some());
        let blind = if flags.contains(vk::DescriptorSetLayoutCreateFlags::DESCRIPTOR_BUFFER_EXT) {
            Some("descriptor buffers")
        } else if image_bindings.clone().any(|b| b.count > BINDLESS_COUNT) {
            Some("a bindless image array")
        } else if binding_flags.iter().any(|f| f.intersects(vk::DescriptorBindingFlags::VARIABLE_DESCRIPTOR_COUNT)) {
            Some("a variable-count descriptor array")
        } else {
            None
        };
        SetLayout {
            bindings: bindings.into_iter().map(|b| (b.binding, b)).collect(),
            blind,
            push: flags.contains(vk::DescriptorSetLayoutCreateFlags::PUSH_DESCRIPTOR_KHR),
        }
    }

    /// The (binding, element) slots `count` consecutive descriptors starting at
    /// (`binding`, `element`) land in: past a binding's end they run into the next binding
    /// (the spec's consecutive binding updates).
    pub fn slots(&self, binding: u32, element: u32, count: u32) -> Vec<(u32, u32)> {
        let mut out = Vec::with_capacity(count as usize);
        let mut e = element;
        for lb in self.bindings.range(binding..).map(|(_, b)| b) {
            // Bindings with no descriptors are skipped by consecutive updates.
            while e < lb.count && (out.len() as u32) < count {
                out.push((lb.binding, e));
                e += 1;
            }
            if out.len() as u32 >= count {
                break;
            }
            if lb.count > 0 {
                e = 0;
            }
        }
        out
    }
}

/// One descriptor write, as `vkUpdateDescriptorSets`, a template or a push gives it: the image
/// views of image types (None per element for other types or null views).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Write {
    pub binding: u32,
    pub element: u32,
    pub ty: vk::DescriptorType,
    pub views: Vec<Option<u64>>,
}

/// `VkCopyDescriptorSet`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Copy {
    pub src_set: u64,
    pub src_binding: u32,
    pub src_element: u32,
    pub dst_set: u64,
    pub dst_binding: u32,
    pub dst_element: u32,
    pub count: u32,
}

/// What a descriptor set holds.
#[derive(Clone, Debug, Default)]
pub struct SetContents {
    pub layout: Arc<SetLayout>,
    pub pool: u64,
    images: BTreeMap<(u32, u32), BoundImage>,
}

impl SetContents {
    /// The image views the set holds, in binding order.
    pub fn images(&self) -> impl Iterator<Item = BoundImage> + '_ {
        self.images.values().copied()
    }

    fn apply(&mut self, w: &Write) {
        let slots = self.layout.slots(w.binding, w.element, w.views.len() as u32);
        for (slot, view) in slots.into_iter().zip(&w.views) {
            match (ImageAccess::of(w.ty), view) {
                (Some(access), Some(view)) if *view != 0 => {
                    self.images.insert(slot, BoundImage { view: *view, access });
                }
                _ => {
                    self.images.remove(&slot);
                }
            }
        }
    }
}

/// The images of a push descriptor write (`vkCmdPushDescriptorSetKHR`): no set to keep them in.
pub fn pushed_images(writes: &[Write]) -> Vec<BoundImage> {
    writes
        .iter()
        .filter_map(|w| ImageAccess::of(w.ty).map(|a| (a, w)))
        .flat_map(|(access, w)| w.views.iter().flatten().filter(|v| **v != 0).map(move |&view| BoundImage { view, access }))
        .collect()
}

/// `VkDescriptorUpdateTemplateEntry`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TemplateEntry {
    pub binding: u32,
    pub element: u32,
    pub count: u32,
    pub ty: vk::DescriptorType,
    pub offset: usize,
    pub stride: usize,
}

/// `VkDescriptorUpdateTemplateCreateInfo`, the parts that place descriptors.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct UpdateTemplate {
    pub entries: Vec<TemplateEntry>,
    /// `PUSH_DESCRIPTORS_KHR` templates: the set number they push to.
    pub push_set: Option<u32>,
    pub bind_point: vk::PipelineBindPoint,
}

/// Every descriptor set, layout and update template of a device. One lock: updates are short
/// map edits and never call down.
#[derive(Debug, Default)]
pub struct Descriptors {
    inner: Mutex<Inner>,
}

#[derive(Debug, Default)]
struct Inner {
    layouts: HashMap<u64, Arc<SetLayout>>,
    sets: HashMap<u64, SetContents>,
    templates: HashMap<u64, Arc<UpdateTemplate>>,
}

impl Descriptors {
    fn lock(&self) -> MutexGuard<'_, Inner> {
        self.inner.lock().unwrap_or_else(|e| e.into_inner())
    }

    pub fn add_layout(&self, handle: u64, layout: SetLayout) {
        self.lock().layouts.insert(handle, Arc::new(layout));
    }
    pub fn destroy_layout(&self, handle: u64) {
        // Sets keep their own reference: a layout may be destroyed while its sets live.
        self.lock().layouts.remove(&handle);
    }
    pub fn layout(&self, handle: u64) -> Option<Arc<SetLayout>> {
        self.lock().layouts.get(&handle).cloned()
    }

    /// `vkAllocateDescriptorSets`: `sets[i]` has `layouts[i]`.
    pub fn allocate(&self, pool: u64, sets: &[u64], layouts: &[u64]) {
        let mut g = self.lock();
        for (set, layout) in sets.iter().zip(layouts) {
            let layout = g.layouts.get(layout).cloned().unwrap_or_default();
            g.sets.insert(*set, SetContents { layout, pool, images: BTreeMap::new() });
        }
    }
    pub fn free(&self, sets: &[u64]) {
        let mut g = self.lock();
        for s in sets {
            g.sets.remove(s);
        }
    }
    /// `vkResetDescriptorPool` / `vkDestroyDescriptorPool`: every set of the pool is gone.
    pub fn reset_pool(&self, pool: u64) {
        self.lock().sets.retain(|_, s| s.pool != pool);
    }

    /// `vkUpdateDescriptorSets`: writes in order, then copies (the spec's order).
    pub fn update(&self, writes: &[(u64, Write)], copies: &[Copy]) {
        let mut g = self.lock();
        for (set, w) in writes {
            if let Some(s) = g.sets.get_mut(set) {
                s.apply(w);
            }
        }
        for c in copies {
            let Some(src) = g.sets.get(&c.src_set) else { continue };
            let from = src.layout.slots(c.src_binding, c.src_element, c.count);
            let values: Vec<Option<BoundImage>> = from.iter().map(|slot| src.images.get(slot).copied()).collect();
            let Some(dst) = g.sets.get_mut(&c.dst_set) else { continue };
            for (slot, v) in dst.layout.slots(c.dst_binding, c.dst_element, c.count).into_iter().zip(values) {
                match v {
                    Some(v) => dst.images.insert(slot, v),
                    None => dst.images.remove(&slot),
                };
            }
        }
    }

    pub fn add_template(&self, handle: u64, t: UpdateTemplate) {
        self.lock().templates.insert(handle, Arc::new(t));
    }
    pub fn destroy_template(&self, handle: u64) {
        self.lock().templates.remove(&handle);
    }
    pub fn template(&self, handle: u64) -> Option<Arc<UpdateTemplate>> {
        self.lock().templates.get(&handle).cloned()
    }

    /// The images a set holds, or why the walk cannot see them; None for an unknown set.
    pub fn images(&self, set: u64) -> Option<Result<Vec<BoundImage>, &'static str>> {
        let g = self.lock();
        let s = g.sets.get(&set)?;
        Some(match s.layout.blind {
            Some(why) => Err(why),
            None => Ok(s.images().collect()),
        })
    }

    /// Live sets (for the layer's tables line and tests).
    pub fn set_count(&self) -> usize {
        self.lock().sets.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const SAMPLED: vk::DescriptorType = vk::DescriptorType::COMBINED_IMAGE_SAMPLER;
    const UBO: vk::DescriptorType = vk::DescriptorType::UNIFORM_BUFFER;

    fn layout(bindings: &[(u32, vk::DescriptorType, u32)]) -> SetLayout {
        let b = bindings.iter().map(|&(binding, ty, count)| LayoutBinding { binding, ty, count }).collect();
        SetLayout::new(b, vk::DescriptorSetLayoutCreateFlags::empty(), &[])
    }

    fn write(binding: u32, element: u32, ty: vk::DescriptorType, views: &[u64]) -> Write {
        Write { binding, element, ty, views: views.iter().map(|v| Some(*v)).collect() }
    }

    #[test]
    fn consecutive_binding_updates_run_into_the_next_binding() {
        let l = layout(&[(0, SAMPLED, 2), (1, SAMPLED, 1), (3, SAMPLED, 2)]);
        assert_eq!(l.slots(0, 1, 3), vec![(0, 1), (1, 0), (3, 0)]);
        assert_eq!(l.slots(3, 1, 5), vec![(3, 1)], "nothing past the last binding");
        assert_eq!(l.slots(2, 0, 1), vec![(3, 0)], "a missing binding number runs into the next");
    }

    #[test]
    fn writes_copies_and_frees() {
        let d = Descriptors::default();
        d.add_layout(1, layout(&[(0, SAMPLED, 1), (1, vk::DescriptorType::STORAGE_IMAGE, 1), (2, UBO, 1)]));
        d.allocate(7, &[10, 11], &[1, 1]);
        d.update(&[(10, write(0, 0, SAMPLED, &[100, 101]))], &[]);
        // The second view ran into binding 1, but with the write's type (sampled).
        assert_eq!(
            d.images(10),
            Some(Ok(vec![BoundImage { view: 100, access: ImageAccess::Sampled }, BoundImage { view: 101, access: ImageAccess::Sampled }]))
        );
        // A non-image write clears what it covers; a copy moves what the source holds.
        d.update(&[(10, write(1, 0, UBO, &[0]))], &[Copy { src_set: 10, src_binding: 0, src_element: 0, dst_set: 11, dst_binding: 0, dst_element: 0, count: 1 }]);
        assert_eq!(d.images(10).unwrap().unwrap().len(), 1);
        assert_eq!(d.images(11), Some(Ok(vec![BoundImage { view: 100, access: ImageAccess::Sampled }])));
        d.free(&[10]);
        assert_eq!(d.images(10), None);
        d.reset_pool(7);
        assert_eq!(d.set_count(), 0);
    }

    #[test]
    fn bindless_and_descriptor_buffer_layouts_are_blind() {
        let d = Descriptors::default();
        d.add_layout(1, layout(&[(0, SAMPLED, 4096)]));
        d.allocate(7, &[10], &[1]);
        assert_eq!(d.images(10), Some(Err("a bindless image array")));
        let l = SetLayout::new(vec![], vk::DescriptorSetLayoutCreateFlags::DESCRIPTOR_BUFFER_EXT, &[]);
        assert_eq!(l.blind, Some("descriptor buffers"));
        let l = SetLayout::new(vec![LayoutBinding { binding: 0, ty: SAMPLED, count: 8 }], vk::DescriptorSetLayoutCreateFlags::empty(), &[vk::DescriptorBindingFlags::VARIABLE_DESCRIPTOR_COUNT]);
        assert!(l.blind.is_some());
        // A small array is followed.
        assert_eq!(layout(&[(0, SAMPLED, 8)]).blind, None);
    }

    #[test]
    fn pushed_images_keep_only_image_types() {
        let w = [write(0, 0, SAMPLED, &[5]), write(1, 0, UBO, &[6]), Write { binding: 2, element: 0, ty: vk::DescriptorType::STORAGE_IMAGE, views: vec![None, Some(7)] }];
        assert_eq!(pushed_images(&w), vec![BoundImage { view: 5, access: ImageAccess::Sampled }, BoundImage { view: 7, access: ImageAccess::Storage }]);
    }
}
