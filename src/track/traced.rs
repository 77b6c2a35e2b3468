//! What the data-flow walk learned, per image: the eyes an eye pass's target shows (applied from
//! the next recording on, as learned intermediates are) and the images only post-process passes
//! write. Fed at each submission with the submitted command buffers' ops (`track::flow`), which
//! are kept in a window of recent submissions so a frame spread over several submissions is
//! walked whole. Learned per swapchain: each walk from a swapchain replaces what the last one
//! from it taught, so a chain that changes (dynamic resolution, a toggled effect) is re-learned
//! and an image that no longer leads to an eye is forgotten.
#![forbid(unsafe_code)]

use super::descriptors::{BoundImage, Descriptors};
use super::eye_pass::EyeSource;
use super::flow::{self, ImageUse, Op, Region, Walked, World};
use super::resources::{Image, ImageView};
use crate::registry::HandleMap;
use crate::shared::Shared;
use ash::vk;
use std::collections::{HashMap, HashSet, VecDeque};
use std::sync::{Arc, Mutex, MutexGuard};

/// Ops kept across submissions: a frame of a real engine records a few hundred passes, draws and
/// transfers the walk cares about.
const WINDOW_OPS: usize = 16384;

/// One image's eyes as the walk found them.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TracedEyes {
    pub eyes: Vec<EyeSource>,
    /// The swapchain whose walk found them.
    pub swapchain: u64,
    /// The path from the swapchain, for the log (e.g. "resolve ← draw").
    pub chain: String,
}

/// What the layer logs once about a walk.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Note {
    Traced { image: u64, eyes: Vec<EyeSource>, chain: String, depth: bool },
    Untraced(String),
}

#[derive(Debug, Default)]
struct Books {
    window: VecDeque<Arc<Vec<Op>>>,
    window_ops: usize,
    eyes: HashMap<u64, TracedEyes>,
    /// Image → swapchain whose walk found only post passes writing it.
    post: HashMap<u64, u64>,
    noted: HashSet<String>,
    walks: u64,
}

/// The walk's device-level state.
#[derive(Debug, Default)]
pub struct Traced {
    books: Mutex<Books>,
}

/// The tracker's objects as the walk sees them.
pub struct TrackerWorld<'a> {
    pub descriptors: &'a Descriptors,
    pub views: &'a HandleMap<u64, ImageView>,
    pub images: &'a HandleMap<u64, Image>,
    pub shared: &'a Shared,
}

impl World for TrackerWorld<'_> {
    fn set_images(&self, set: u64) -> Option<Result<Vec<BoundImage>, &'static str>> {
        self.descriptors.images(set)
    }
    fn view(&self, view: u64) -> Option<(ImageUse, (u32, u32), bool)> {
        let v = self.views.get(view)?;
        let image = self.images.get(v.image)?;
        let mip = v.range.base_mip_level;
        let extent = ((image.extent.width >> mip).max(1), (image.extent.height >> mip).max(1));
        let layers = v.range.layers_of(image.array_layers);
        let depth = v.range.aspect_mask.intersects(vk::ImageAspectFlags::DEPTH | vk::ImageAspectFlags::STENCIL);
        Some((ImageUse { image: v.image, base_layer: v.range.base_array_layer, layers, mip }, extent, depth))
    }
    fn extent(&self, image: u64) -> Option<(u32, u32)> {
        self.images.get(image).map(|i| (i.extent.width, i.extent.height))
    }
    fn swapchain_of(&self, image: u64) -> Option<u64> {
        self.shared.images.get(image).map(|s| s.swapchain.handle)
    }
}

fn lock(m: &Mutex<Books>) -> MutexGuard<'_, Books> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

impl Traced {
    /// A submission's command buffers' ops, in submission order: kept, and every swapchain image
    /// they write whose eyes are known is walked back. Returns what to log (each note once).
    pub fn submitted(&self, world: &TrackerWorld<'_>, submitted: Vec<Arc<Vec<Op>>>) -> Vec<Note> {
        // Swapchain images written by this submission, by swapchain: (image, eye starts).
        let mut starts: HashMap<u64, Vec<(u32, Region)>> = HashMap::new();
        for ops in &submitted {
            for op in ops.iter() {
                for image in written(op) {
                    let Some(sc) = world.shared.images.get(image) else { continue };
                    let entry = starts.entry(sc.swapchain.handle).or_default();
                    for u in sc.swapchain.uses() {
                        let rect = super::eye_pass::rect(u.image_rect);
                        let start = (u.view, Region { image, layer: u.image_array_index, rect });
                        if !u.depth && !entry.contains(&start) {
                            entry.retain(|(v, _)| *v != u.view);
                            entry.push(start);
                        }
                    }
                }
            }
        }
        let mut b = lock(&self.books);
        for ops in submitted {
            b.window_ops += ops.len();
            b.window.push_back(ops);
        }
        while b.window_ops > WINDOW_OPS && b.window.len() > 1 {
            let old = b.window.pop_front().map_or(0, |o| o.len());
            b.window_ops -= old;
        }
        if starts.is_empty() {
            return Vec::new();
        }
        let window: Vec<Arc<Vec<Op>>> = b.window.iter().cloned().collect();
        drop(b);
        // The walk runs without the lock: it only reads the ops and the tracker's maps.
        let all: Vec<&Op> = window.iter().flat_map(|o| o.iter()).collect();
        let mut results = Vec::new();
        let mut swapchains: Vec<_> = starts.into_iter().collect();
        swapchains.sort_by_key(|(sc, _)| *sc);
        for (sc, mut s) in swapchains {
            s.sort_by_key(|(v, _)| *v);
            results.push((sc, flow::walk(&all, &s, world)));
        }
        let mut b = lock(&self.books);
        let mut notes = Vec::new();
        for (sc, walked) in results {
            b.walks += 1;
            learn(&mut b, sc, walked, world, &mut notes);
        }
        notes
    }

    /// The eyes the walk found `image` to show.
    pub fn eyes(&self, image: u64) -> Option<TracedEyes> {
        lock(&self.books).eyes.get(&image).cloned()
    }

    /// Whether only post-process passes were seen writing `image`.
    pub fn is_post(&self, image: u64) -> bool {
        lock(&self.books).post.contains_key(&image)
    }

    pub fn forget_image(&self, image: u64) {
        let mut b = lock(&self.books);
        b.eyes.remove(&image);
        b.post.remove(&image);
    }

    /// (walks run, images with traced eyes, post-only images) for the stats line.
    pub fn counts(&self) -> (u64, usize, usize) {
        let b = lock(&self.books);
        (b.walks, b.eyes.len(), b.post.len())
    }
}

/// Images an op writes (colour, resolve, transfer destination; storage writes are resolved in
/// the walk, which knows the descriptor sets).
fn written(op: &Op) -> Vec<u64> {
    match op {
        Op::Pass(p) => p.colors.iter().chain(p.resolves.iter().map(|(_, r)| r)).map(|u| u.image).collect(),
        Op::Transfer { dst, .. } => vec![*dst],
        _ => Vec::new(),
    }
}

fn learn(b: &mut Books, sc: u64, walked: Walked, world: &TrackerWorld<'_>, notes: &mut Vec<Note>) {
    let mut eyes: HashMap<u64, (Vec<EyeSource>, String, bool)> = HashMap::new();
    for f in &walked.found {
        // A swapchain image's eyes come from the OpenXR half; the walk adds nothing there.
        if world.shared.images.get(f.image).is_some() {
            continue;
        }
        let chain = if f.chain.is_empty() { "direct".to_string() } else { f.chain.join(" ← ") };
        let e = eyes.entry(f.image).or_insert_with(|| (Vec::new(), chain.clone(), false));
        e.0.push(f.eye);
        if let Some(depth) = f.depth {
            let d = eyes.entry(depth).or_insert_with(|| (Vec::new(), chain, true));
            d.0.push(f.eye);
        }
    }
    let eye_images: HashSet<u64> = walked.found.iter().map(|f| f.image).collect();
    b.eyes.retain(|_, t| t.swapchain != sc);
    b.post.retain(|_, s| *s != sc);
    for (image, (mut list, chain, depth)) in eyes {
        list.sort_by_key(|s| (s.layer, s.rect.x, s.rect.y, s.view));
        list.dedup();
        let key = format!("traced {image:#x} {list:?}");
        if b.noted.insert(key) {
            notes.push(Note::Traced { image, eyes: list.clone(), chain: chain.clone(), depth });
        }
        b.eyes.insert(image, TracedEyes { eyes: list, swapchain: sc, chain });
    }
    for image in walked.post {
        if !eye_images.contains(&image) {
            b.post.insert(image, sc);
        }
    }
    for why in walked.untraced {
        if b.noted.len() < 256 && b.noted.insert(why.clone()) {
            notes.push(Note::Untraced(why));
        }
    }
}
