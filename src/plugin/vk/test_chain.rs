//! Test support: Vulkan `pNext` chains of boxed structs built from a list, for the property tests
//! of the create infos the layer rewrites (`vk::chain`, `features::foveation::vrs::pass`).

use ash::vk;
use std::any::Any;
use std::ffi::c_void;

/// A chain of structs, each boxed so that the pointers linking them stay put; `head` is the
/// first (null when empty).
#[derive(Default)]
pub(crate) struct Chain {
    keep: Vec<Box<dyn Any>>,
    pub head: *const c_void,
}

impl Chain {
    /// Appends `s` (its `pNext` is overwritten) at the end of the chain.
    pub fn push<T: 'static>(&mut self, s: T) {
        let mut b: Box<T> = Box::new(s);
        let p = &mut *b as *mut T as *mut c_void;
        // SAFETY: every Vulkan struct chained by pNext starts with sType, pNext.
        unsafe { (*(p as *mut vk::BaseOutStructure<'_>)).p_next = std::ptr::null_mut() };
        match self.keep.last_mut() {
            None => self.head = p,
            Some(last) => {
                let last = &mut **last as *mut dyn Any as *mut vk::BaseOutStructure<'_>;
                // SAFETY: as above; the previous struct is boxed and alive in `keep`.
                unsafe { (*last).p_next = p as *mut vk::BaseOutStructure<'_> };
            }
        }
        self.keep.push(b);
    }
}

/// The `(sType, address)` of every struct of a chain, in order.
pub(crate) fn walk(mut p: *const c_void) -> Vec<(vk::StructureType, *const c_void)> {
    let mut out = Vec::new();
    while !p.is_null() {
        // SAFETY: test chains are made of valid structs.
        let b = unsafe { &*(p as *const vk::BaseInStructure<'_>) };
        out.push((b.s_type, p));
        p = b.p_next as *const c_void;
        assert!(out.len() < 64, "chain does not end");
    }
    out
}

/// Whether a structure type appears more than once in a chain (the specs' `sType-unique` rule).
pub(crate) fn has_duplicates(p: *const c_void) -> bool {
    let types: Vec<vk::StructureType> = walk(p).into_iter().map(|(t, _)| t).collect();
    types.iter().enumerate().any(|(i, t)| types[..i].contains(t))
}
