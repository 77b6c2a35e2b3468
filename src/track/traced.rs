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
use super::flow::{self, FlowAt, ImageUse, Op, Region, Walked, World};
use super::resources::{Image, ImageView};
use crate::core::handles::HandleMap;
use crate::bridge::Shared;
use ash::vk;
use std::collections::{HashMap, HashSet, VecDeque};
use std::sync::{Arc, Mutex, MutexGuard};

/// Ops kept across submissions: a frame of a real engine records a few hundred passes, draws and
/// transfers the walk cares about.
const WINDOW_OPS: usize = 16384;

/// Walks of a swapchain an image's entry survives without being found again: engines that cycle
/// per-frame targets (frames in flight, the ring of swapchain images) reach each one only every
/// few frames; a chain that changed stops being applied after this many frames.
const KEEP_WALKS: u64 = 4;

/// One image's eyes as the walk found them.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TracedEyes {
    pub eyes: Vec<EyeSource>,
    /// The swapchain whose walk found them.
    pub swapchain: u64,
    /// The path from the swapchain, for the log (e.g. "resolve ← draw").
    pub chain: String,
    /// The swapchain's walk that last found it.
    pub walk: u64,
    /// Its rects differ from the previous walk's (dynamic resolution drawing into a changing
    /// sub-rect): what was learned describes last frame, not the one being recorded.
    pub changing: bool,
    /// Its rects changed at some walk since it was first found: they may change again at any
    /// frame, so what was learned is applied only where the walk of the same submission
    /// confirms it (`Traced::fresh`), never at recording.
    pub dynamic: bool,
    /// The submission (`Traced::submitted` call) whose walk last found it.
    pub submission: u64,
    /// One target for both eyes: walks found it showing one eye, then another, at the same
    /// rect (an engine renders each eye into it in turn, each followed by its post chain). Which
    /// eye a pass into it shows is the eye its own use reaches (`Traced::use_eyes`), known only
    /// from the walk of the submission that carries it; `eyes` lists every eye seen.
    pub per_use: bool,
}

/// What the layer logs once about a walk.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Note {
    Traced { image: u64, eyes: Vec<EyeSource>, chain: String, depth: bool },
    Untraced(String),
}

#[derive(Debug, Default)]
struct Books {
    /// Recent submissions' command buffers and their ops, oldest first.
    window: VecDeque<(u64, Arc<Vec<Op>>)>,
    window_ops: usize,
    eyes: HashMap<u64, TracedEyes>,
    /// Image → (swapchain, its walk) whose walk found only post passes writing it.
    post: HashMap<u64, (u64, u64)>,
    /// Walks per swapchain.
    walks_of: HashMap<u64, u64>,
    /// Swapchains whose images only post passes write (every image of the ring: the walk of one
    /// speaks for all, which are written the same way), with the walk that saw it.
    post_swapchains: HashMap<u64, u64>,
    noted: HashSet<String>,
    walks: u64,
    /// `submitted` calls so far: the current submission's number while its features run.
    submissions: u64,
    /// The eyes each eye pass of the latest walked submission showed, by where it is recorded.
    uses: HashMap<FlowAt, Vec<EyeSource>>,
    /// The submission `uses` describes.
    uses_submission: u64,
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
    /// A submission's command buffers (handle, ops), in submission order: kept, and every
    /// swapchain image they write whose eyes are known is walked back. Returns what to log (each
    /// note once).
    pub fn submitted(&self, world: &TrackerWorld<'_>, submitted: Vec<(u64, Arc<Vec<Op>>)>) -> Vec<Note> {
        // Swapchain images written by this submission, by swapchain: (image, eye starts).
        let mut starts: HashMap<u64, Vec<(u32, Region)>> = HashMap::new();
        for (_, ops) in &submitted {
            for op in ops.iter() {
                for image in flow::writes_images(op, world) {
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
        b.submissions += 1;
        let new = submitted.len();
        for entry in submitted {
            b.window_ops += entry.1.len();
            b.window.push_back(entry);
        }
        while b.window_ops > WINDOW_OPS && b.window.len() > 1 {
            let old = b.window.pop_front().map_or(0, |(_, o)| o.len());
            b.window_ops -= old;
        }
        if starts.is_empty() {
            return Vec::new();
        }
        let window: Vec<(u64, Arc<Vec<Op>>)> = b.window.iter().cloned().collect();
        drop(b);
        // The walk runs without the lock: it only reads the ops and the tracker's maps.
        let all: Vec<&Op> = window.iter().flat_map(|(_, o)| o.iter()).collect();
        // Where a walked op of this submission is recorded (earlier submissions' command buffers
        // may have been recorded again since): the window entry it falls in, by the entries' starts.
        let first_new = window.len().saturating_sub(new);
        let starts_at: Vec<usize> = window.iter().scan(0, |n, (_, o)| Some(std::mem::replace(n, *n + o.len()))).collect();
        let at_of = |op: usize| -> Option<FlowAt> {
            let k = starts_at.partition_point(|s| *s <= op).checked_sub(1)?;
            (k >= first_new).then(|| FlowAt { cb: window[k].0, op: op - starts_at[k] })
        };
        let mut results = Vec::new();
        let mut swapchains: Vec<_> = starts.into_iter().collect();
        swapchains.sort_by_key(|(sc, _)| *sc);
        for (sc, mut s) in swapchains {
            s.sort_by_key(|(v, _)| *v);
            results.push((sc, flow::walk(&all, &s, world)));
        }
        let mut b = lock(&self.books);
        let mut notes = Vec::new();
        let submission = b.submissions;
        if b.uses_submission != submission {
            b.uses.clear();
            b.uses_submission = submission;
        }
        for (sc, walked) in results {
            b.walks += 1;
            for f in &walked.found {
                if let Some(at) = at_of(f.op) {
                    let eyes = b.uses.entry(at).or_default();
                    if !eyes.contains(&f.eye) {
                        eyes.push(f.eye);
                    }
                }
            }
            learn(&mut b, sc, walked, world, submission, &mut notes);
        }
        notes
    }

    /// The eyes the pass recorded at `at` shows, as the walk of the latest submission found them:
    /// None when that walk did not reach it (or it is not in that submission).
    pub fn use_eyes(&self, at: FlowAt) -> Option<Vec<EyeSource>> {
        let b = lock(&self.books);
        (b.uses_submission == b.submissions).then(|| b.uses.get(&at).cloned()).flatten()
    }

    /// The eyes the walk found `image` to show.
    pub fn eyes(&self, image: u64) -> Option<TracedEyes> {
        lock(&self.books).eyes.get(&image).cloned()
    }

    /// Whether the walk of the latest submission found `t` (what it says describes the frame
    /// being submitted, not a previous one).
    pub fn fresh(&self, t: &TracedEyes) -> bool {
        t.submission == lock(&self.books).submissions
    }

    /// Whether only post-process passes were seen writing `image` (of `swapchain`, if it is a
    /// swapchain image: then any image of its ring).
    pub fn is_post(&self, image: u64, swapchain: Option<u64>) -> bool {
        let b = lock(&self.books);
        b.post.contains_key(&image) || swapchain.is_some_and(|sc| b.post_swapchains.contains_key(&sc))
    }

    /// Whether the walk has traced eyes to any intermediate (the frame's structure is known).
    pub fn has_eyes(&self) -> bool {
        !lock(&self.books).eyes.is_empty()
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

fn learn(b: &mut Books, sc: u64, walked: Walked, world: &TrackerWorld<'_>, submission: u64, notes: &mut Vec<Note>) {
    // Per image: each eye found with the walked op (the use of the image) that shows it, the
    // chain to it and whether it is a depth image.
    type Uses = (Vec<(EyeSource, usize)>, String, bool);
    let mut eyes: HashMap<u64, Uses> = HashMap::new();
    for f in &walked.found {
        // A swapchain image's eyes come from the OpenXR half; the walk adds nothing there.
        if world.shared.images.get(f.image).is_some() {
            continue;
        }
        let chain = if f.chain.is_empty() { "direct".to_string() } else { f.chain.join(" ← ") };
        let e = eyes.entry(f.image).or_insert_with(|| (Vec::new(), chain.clone(), false));
        e.0.push((f.eye, f.op));
        if let Some(depth) = f.depth {
            let d = eyes.entry(depth).or_insert_with(|| (Vec::new(), chain, true));
            d.0.push((f.eye, f.op));
        }
    }
    let eye_images: HashSet<u64> = walked.found.iter().map(|f| f.image).collect();
    let walk = {
        let n = b.walks_of.entry(sc).or_insert(0);
        *n += 1;
        *n
    };
    let stale = |s: u64, w: u64| s == sc && w + KEEP_WALKS <= walk;
    b.eyes.retain(|_, t| !stale(t.swapchain, t.walk));
    b.post.retain(|_, (s, w)| !stale(*s, *w));
    for image in &eye_images {
        b.post.remove(image);
    }
    b.post_swapchains.retain(|s, w| !stale(*s, *w));
    if eye_images.iter().any(|i| world.swapchain_of(*i) == Some(sc)) {
        b.post_swapchains.remove(&sc);
    } else if walked.post.iter().any(|i| world.swapchain_of(*i) == Some(sc)) {
        b.post_swapchains.insert(sc, walk);
    }
    for (image, (uses, chain, depth)) in eyes {
        // Two eyes at the same pixels of one image, each from a use of its own: one walk saw the
        // eyes take turns in it (their swapchain images are one image's layers, or one
        // swapchain's rects, so a single walk reaches both uses).
        let within = uses.iter().any(|(a, op_a)| uses.iter().any(|(b, op_b)| op_a != op_b && a.view != b.view && (a.layer, a.rect) == (b.layer, b.rect)));
        let mut list: Vec<EyeSource> = uses.into_iter().map(|(e, _)| e).collect();
        list.sort_by_key(|s| (s.layer, s.rect.x, s.rect.y, s.view));
        list.dedup();
        let key = format!("traced {image:#x} {list:?}");
        // Bounded: dynamic resolution changes the rects every frame.
        if b.noted.len() < 256 && b.noted.insert(key) {
            notes.push(Note::Traced { image, eyes: list.clone(), chain: chain.clone(), depth });
        }
        b.post.remove(&image);
        let rects = |l: &[EyeSource]| {
            let mut r: Vec<_> = l.iter().map(|e| (e.layer, e.rect)).collect();
            r.sort();
            r.dedup();
            r
        };
        let old = b.eyes.get(&image);
        let changing = old.is_some_and(|old| rects(&old.eyes) != rects(&list));
        let dynamic = changing || old.is_some_and(|old| old.dynamic);
        // Another eye than last time at the same rects: one target the eyes take turns in.
        let views = |l: &[EyeSource]| l.iter().map(|e| e.view).collect::<HashSet<u32>>();
        let turns = within || old.is_some_and(|old| !changing && views(&old.eyes) != views(&list));
        let per_use = turns || old.is_some_and(|old| old.per_use);
        if per_use {
            if let Some(old) = old {
                for e in &old.eyes {
                    if !list.contains(e) {
                        list.push(*e);
                    }
                }
                list.sort_by_key(|s| (s.layer, s.rect.x, s.rect.y, s.view));
            }
        }
        if turns && !old.is_some_and(|old| old.per_use) && b.noted.insert(format!("per use {image:#x}")) {
            notes.push(Note::Untraced(format!(
                "{image:#x} shows one eye, then another, in the same frame (one target the eyes take turns in): each pass into it gets the eye its own use reaches, from the walk of the submission that carries it"
            )));
        }
        if changing && b.noted.insert(format!("changing {image:#x}")) {
            notes.push(Note::Untraced(format!(
                "the eye rect in {image:#x} changes from frame to frame (dynamic resolution into a sub-rect): its passes get the layer's draws filled at each submission from that submission's walk, or nothing (rect_changing) where the walk cannot confirm the rect"
            )));
        }
        b.eyes.insert(image, TracedEyes { eyes: list, swapchain: sc, chain, walk, changing, dynamic, submission, per_use });
    }
    for image in walked.post {
        if !eye_images.contains(&image) {
            b.eyes.remove(&image);
            b.post.insert(image, (sc, walk));
        }
    }
    for why in walked.untraced {
        if b.noted.len() < 256 && b.noted.insert(why.clone()) {
            notes.push(Note::Untraced(why));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::rect::PixelRect;
    use crate::core::views::{EyeUse, ImageRect, SwapchainDesc};
use crate::bridge::Swapchain;
    use crate::track::flow::{DrawRecord, PassRecord};

    fn image(h: u64, w: u32) -> Image {
        Image {
            handle: h,
            image_type: vk::ImageType::TYPE_2D,
            format: vk::Format::R8G8B8A8_UNORM,
            extent: vk::Extent3D { width: w, height: 32, depth: 1 },
            mip_levels: 1,
            array_layers: 1,
            samples: vk::SampleCountFlags::TYPE_1,
            usage: vk::ImageUsageFlags::empty(),
            flags: vk::ImageCreateFlags::empty(),
        }
    }

    /// One swapchain (handle 77, view 0 over the whole 64×32 image) with the ring `ring`, the
    /// intermediates 10 (colour) and 12 (depth), view `h + 1000` of every image, and descriptor
    /// set 5 sampling image 10.
    struct Fixture {
        shared: Shared,
        descriptors: Descriptors,
        views: HandleMap<u64, ImageView>,
        images: HandleMap<u64, Image>,
    }

    impl Fixture {
        fn new(ring: &[u64]) -> Fixture {
            let f = Fixture { shared: Shared::default(), descriptors: Descriptors::default(), views: HandleMap::default(), images: HandleMap::default() };
            let desc = SwapchainDesc { usage_flags: 0, format: 43, sample_count: 1, width: 64, height: 32, array_size: 1 };
            let sc = Arc::new(Swapchain::new(77, desc, ring.to_vec()));
            f.shared.add_swapchain(sc.clone());
            sc.set_uses(vec![EyeUse { view: 0, image_rect: ImageRect { x: 0, y: 0, width: 64, height: 32 }, image_array_index: 0, depth: false }]);
            for &h in ring.iter().chain(&[10, 12]) {
                f.images.insert(h, Arc::new(image(h, 64)));
                let range = crate::track::resources::SubresourceRange { aspect_mask: vk::ImageAspectFlags::COLOR, base_mip_level: 0, level_count: 1, base_array_layer: 0, layer_count: 1 };
                f.views.insert(h + 1000, Arc::new(ImageView { handle: h + 1000, image: h, view_type: vk::ImageViewType::TYPE_2D, format: vk::Format::UNDEFINED, range }));
            }
            let sampled = vk::DescriptorType::COMBINED_IMAGE_SAMPLER;
            f.descriptors.add_layout(1, crate::track::descriptors::SetLayout::new(vec![crate::track::descriptors::LayoutBinding { binding: 0, ty: sampled, count: 1 }], vk::DescriptorSetLayoutCreateFlags::empty(), &[]));
            f.descriptors.allocate(9, &[5], &[1]);
            f.descriptors.update(&[(5, crate::track::descriptors::Write { binding: 0, element: 0, ty: sampled, views: vec![Some(1010)] })], &[]);
            f
        }
        fn world(&self) -> TrackerWorld<'_> {
            TrackerWorld { descriptors: &self.descriptors, views: &self.views, images: &self.images, shared: &self.shared }
        }
    }

    fn pass(color: u64, depth: Option<u64>, tested: bool, set: u64) -> Op {
        let u = |image| ImageUse { image, base_layer: 0, layers: 1, mip: 0 };
        let mut p = PassRecord { colors: vec![u(color)], color_loads: vec![false], depth: depth.map(u), depth_cleared: depth.is_some(), render_area: PixelRect { x: 0, y: 0, width: 64, height: 32 }, ..Default::default() };
        p.draw(Some(tested), DrawRecord { viewport: None, sets: vec![set], pushed: vec![] });
        Op::Pass(p)
    }

    /// Three swapchain images in a ring, each frame: scene into 10 (depth 12), tonemap into the
    /// frame's swapchain image sampling 10 through set 5.
    #[test]
    fn a_ring_of_swapchain_images_keeps_every_post_mark_and_the_eyes() {
        let f = Fixture::new(&[100, 101, 102]);
        let world = f.world();
        let t = Traced::default();
        for frame in 0..6u64 {
            let target = 100 + frame % 3;
            let notes = t.submitted(&world, vec![(1, Arc::new(vec![pass(10, Some(12), true, 0), pass(target, None, false, 5)]))]);
            if frame == 0 {
                assert!(notes.iter().any(|n| matches!(n, Note::Traced { image: 10, .. })), "{notes:?}");
            }
        }
        assert!(t.is_post(100, Some(77)) && t.is_post(101, None) && t.is_post(102, None), "every ring image keeps its mark");
        let unseen_ring_image = 103;
        assert!(t.is_post(unseen_ring_image, Some(77)), "the swapchain's mark covers images not walked yet");
        assert_eq!(t.eyes(10).map(|e| (e.eyes.len(), e.changing)), Some((1, false)));
        assert_eq!(t.eyes(12).map(|e| e.eyes.len()), Some(1), "the depth image too");
        // The chain changes: the scene now renders straight into the swapchain; the old
        // intermediate is forgotten after a few walks.
        for frame in 0..(KEEP_WALKS + 1) {
            let target = 100 + frame % 3;
            t.submitted(&world, vec![(1, Arc::new(vec![pass(target, Some(12), true, 0)]))]);
        }
        assert_eq!(t.eyes(10), None);
        assert!(!t.is_post(100, Some(77)) && !t.is_post(101, Some(77)), "a swapchain image an eye pass writes is no post target");
        t.forget_image(12);
        assert_eq!(t.eyes(12), None);
    }

    #[test]
    fn a_rect_that_changes_between_walks_is_marked_changing() {
        let f = Fixture::new(&[100]);
        let world = f.world();
        let t = Traced::default();
        let frame = |w: u32| {
            let Op::Pass(mut scene) = pass(10, Some(12), true, 0) else { unreachable!() };
            scene.tested_viewports = vec![PixelRect { x: 0, y: 0, width: w, height: w / 2 }];
            Arc::new(vec![Op::Pass(scene), pass(100, None, false, 5)])
        };
        t.submitted(&world, vec![(1, frame(48))]);
        assert_eq!(t.eyes(10).map(|e| e.changing), Some(false));
        let notes = t.submitted(&world, vec![(1, frame(56))]);
        assert_eq!(t.eyes(10).map(|e| (e.changing, e.eyes[0].rect.width)), Some((true, 56)));
        assert!(notes.iter().any(|n| matches!(n, Note::Untraced(w) if w.contains("changes from frame to frame"))), "{notes:?}");
        let still = t.eyes(10).unwrap();
        assert!(t.fresh(&still), "found by the latest submission's walk");
        t.submitted(&world, vec![(1, frame(56))]);
        let e = t.eyes(10).unwrap();
        assert_eq!((e.changing, e.dynamic), (false, true), "held still, but it has changed once: it may again");
        assert!(t.fresh(&e));
        t.submitted(&world, vec![(1, Arc::new(vec![pass(10, Some(12), true, 0)]))]);
        assert!(!t.fresh(&t.eyes(10).unwrap()), "a submission without the post pass: what was learned is a frame old");
    }

    /// One target the eyes take turns in: per-eye swapchains 77 (view 0, image 100) and 78
    /// (view 1, image 200); each frame renders the scene into 10 (depth 12) and tonemaps it into
    /// 100, then renders the other eye into 10 again and tonemaps it into 200.
    #[test]
    fn one_target_the_eyes_take_turns_in_is_tied_to_an_eye_per_use() {
        let f = Fixture::new(&[100]);
        let desc = SwapchainDesc { usage_flags: 0, format: 43, sample_count: 1, width: 64, height: 32, array_size: 1 };
        let right = Arc::new(Swapchain::new(78, desc, vec![200]));
        f.shared.add_swapchain(right.clone());
        right.set_uses(vec![EyeUse { view: 1, image_rect: ImageRect { x: 0, y: 0, width: 64, height: 32 }, image_array_index: 0, depth: false }]);
        f.images.insert(200, Arc::new(image(200, 64)));
        let world = f.world();
        let t = Traced::default();
        let views = |e: Option<Vec<EyeSource>>| e.map(|e| e.iter().map(|s| s.view).collect::<Vec<_>>());
        let scene = || pass(10, Some(12), true, 0);
        let notes = t.submitted(&world, vec![(7, Arc::new(vec![scene(), pass(100, None, false, 5), scene(), pass(200, None, false, 5)]))]);
        let e = t.eyes(10).unwrap();
        assert!(e.per_use && !e.changing, "{e:?}");
        assert_eq!(views(Some(e.eyes)), Some(vec![0, 1]), "every eye seen");
        assert!(t.eyes(12).unwrap().per_use, "its depth too");
        assert!(notes.iter().any(|n| matches!(n, Note::Untraced(w) if w.contains("takes turns") || w.contains("take turns in"))), "{notes:?}");
        assert_eq!(views(t.use_eyes(FlowAt { cb: 7, op: 0 })), Some(vec![0]), "the first use is the left eye's");
        assert_eq!(views(t.use_eyes(FlowAt { cb: 7, op: 2 })), Some(vec![1]), "the second the right eye's");
        assert_eq!(t.use_eyes(FlowAt { cb: 7, op: 1 }), None, "a post pass is no eye pass");
        assert_eq!(t.use_eyes(FlowAt { cb: 8, op: 0 }), None, "another command buffer");
        // Each eye in its own command buffer, the right one first this time: still per use.
        t.submitted(&world, vec![(8, Arc::new(vec![scene(), pass(200, None, false, 5)])), (7, Arc::new(vec![scene(), pass(100, None, false, 5)]))]);
        assert_eq!(views(t.use_eyes(FlowAt { cb: 8, op: 0 })), Some(vec![1]));
        assert_eq!(views(t.use_eyes(FlowAt { cb: 7, op: 0 })), Some(vec![0]));
        assert!(t.eyes(10).unwrap().per_use, "it stays so");
        // A submission that reaches no swapchain: what the last walk said is not about it.
        t.submitted(&world, vec![(7, Arc::new(vec![scene()]))]);
        assert_eq!(t.use_eyes(FlowAt { cb: 7, op: 0 }), None);
    }

    /// One target the eyes take turns in, each eye's post pass writing its layer of ONE 2-layer
    /// swapchain image (79: view v at layer v of image 300), so that a single walk reaches both
    /// uses: still one eye per use, never both eyes on every pass into it.
    #[test]
    fn one_target_into_the_layers_of_one_array_swapchain_is_tied_to_an_eye_per_use() {
        let f = Fixture::new(&[100]);
        let desc = SwapchainDesc { usage_flags: 0, format: 43, sample_count: 1, width: 64, height: 32, array_size: 2 };
        let array = Arc::new(Swapchain::new(79, desc.clone(), vec![300]));
        f.shared.add_swapchain(array.clone());
        let whole = ImageRect { x: 0, y: 0, width: 64, height: 32 };
        array.set_uses((0..2).map(|v| EyeUse { view: v, image_rect: whole, image_array_index: v, depth: false }).collect());
        f.images.insert(300, Arc::new(Image { array_layers: 2, ..image(300, 64) }));
        let world = f.world();
        let t = Traced::default();
        let views = |e: Option<Vec<EyeSource>>| e.map(|e| e.iter().map(|s| (s.view, s.layer)).collect::<Vec<_>>());
        let scene = || pass(10, Some(12), true, 0);
        // The tonemap of eye v: a pass whose colour attachment is layer v of image 300.
        let tonemap = |layer: u32| {
            let Op::Pass(mut p) = pass(300, None, false, 5) else { unreachable!() };
            p.colors[0].base_layer = layer;
            Op::Pass(p)
        };
        let notes = t.submitted(&world, vec![(7, Arc::new(vec![scene(), tonemap(0), scene(), tonemap(1)]))]);
        let e = t.eyes(10).unwrap();
        assert!(e.per_use && !e.changing, "{e:?}");
        assert_eq!(views(Some(e.eyes)), Some(vec![(0, 0), (1, 0)]), "every eye seen, at layer 0 of the target");
        assert!(t.eyes(12).unwrap().per_use, "its depth too");
        assert!(notes.iter().any(|n| matches!(n, Note::Untraced(w) if w.contains("take turns in"))), "{notes:?}");
        assert_eq!(views(t.use_eyes(FlowAt { cb: 7, op: 0 })), Some(vec![(0, 0)]), "the first use is the left eye's");
        assert_eq!(views(t.use_eyes(FlowAt { cb: 7, op: 2 })), Some(vec![(1, 0)]), "the second the right eye's");
        // One scene pass whose picture both eyes' post passes read (the same pixels for both):
        // a single use, which shows both eyes; no turn-taking.
        let t2 = Traced::default();
        t2.submitted(&world, vec![(7, Arc::new(vec![scene(), tonemap(0), tonemap(1)]))]);
        let e = t2.eyes(10).unwrap();
        assert!(!e.per_use && e.eyes.len() == 2, "{e:?}");
        assert_eq!(views(t2.use_eyes(FlowAt { cb: 7, op: 0 })), Some(vec![(0, 0), (1, 0)]), "the one use shows both");
    }
}
