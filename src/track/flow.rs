//! The frame's data flow, and the walk back from the swapchain to the eye passes.
//!
//! Hooks record, per command buffer, what each pass instance writes (colour, resolve and depth
//! attachments), whether its draws test depth, what its other draws sample (the descriptor sets
//! bound at each draw), what each dispatch reads and writes, and every transfer (`Op`). At
//! submission the ops of the frame's command buffers, in order, are walked backwards from each eye's
//! rect in a swapchain image (`walk`): a transfer maps the rect to its source; a pass whose draws
//! never test depth (a post-process pass: tonemap, upscale, TAA resolve) hands the eye on to the
//! images its full-screen draws sample, the rect mapped through the draw's viewport and the
//! image's extent; a compute dispatch to the images it reads; an MSAA resolve to its colour
//! attachment; until a pass that depth-tests against a depth attachment it cleared: the eye pass.
//! Shadow maps and other inputs of the eye pass are never followed. What the walk cannot see
//! (descriptor buffers, bindless arrays, a frame larger than the window) is named, never guessed.
//! Pure: unit-tested without Vulkan.
#![forbid(unsafe_code)]

use super::descriptors::{BoundImage, ImageAccess};
use super::eye_pass::{EyeSource, TransferRegion};
use crate::core::rect::PixelRect;
use std::collections::HashSet;
use std::sync::Arc;

/// A subresource of an image as an attachment or descriptor shows it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct ImageUse {
    pub image: u64,
    pub base_layer: u32,
    pub layers: u32,
    pub mip: u32,
}

impl ImageUse {
    fn holds(&self, image: u64, layer: u32) -> bool {
        self.image == image && layer >= self.base_layer && layer < self.base_layer.saturating_add(self.layers.max(1))
    }
}

/// Draws of a pass that do not test depth, merged while nothing about them changes.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DrawRecord {
    /// Viewport 0 in pixels; None when none was set (the walk then assumes the render area).
    pub viewport: Option<PixelRect>,
    /// The descriptor sets bound at the graphics bind point.
    pub sets: Vec<u64>,
    /// Push descriptors' images.
    pub pushed: Vec<BoundImage>,
}

/// One subpass of a render pass instance, or one dynamic rendering.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct PassRecord {
    pub colors: Vec<ImageUse>,
    /// Per colour attachment: its contents at the start are the image's earlier ones (LOAD).
    pub color_loads: Vec<bool>,
    /// (colour attachment index, resolve target).
    pub resolves: Vec<(usize, ImageUse)>,
    pub depth: Option<ImageUse>,
    /// The depth attachment's contents start here from a clear (load op, explicit clear).
    pub depth_cleared: bool,
    /// Subpass input attachments (read at each fragment's own pixel).
    pub inputs: Vec<ImageUse>,
    pub view_mask: u32,
    pub render_area: PixelRect,
    /// Any draw tested depth (an untracked pipeline counts as testing: scenery does).
    pub depth_tested: bool,
    /// The depth-tested draws' distinct viewports (at most `MAX_DRAWS`; more widen the last).
    pub tested_viewports: Vec<PixelRect>,
    /// The other draws (post-process candidates), merged; at most `MAX_DRAWS`.
    pub draws: Vec<DrawRecord>,
    /// More distinct draws than were kept.
    pub overflow: bool,
}

/// Distinct non-depth-tested draws kept per pass: post passes draw a few full-screen triangles.
pub const MAX_DRAWS: usize = 64;
/// Ops kept per command buffer before the recording is marked incomplete.
pub const MAX_OPS: usize = 4096;

impl PassRecord {
    /// Records a draw: depth-tested ones only widen the tested viewport.
    pub fn draw(&mut self, tested: Option<bool>, draw: DrawRecord) {
        if tested != Some(false) {
            self.depth_tested = true;
            let vp = draw.viewport.unwrap_or(self.render_area);
            if !self.tested_viewports.contains(&vp) {
                if self.tested_viewports.len() < MAX_DRAWS {
                    self.tested_viewports.push(vp);
                } else if let Some(last) = self.tested_viewports.last_mut() {
                    *last = union(last, &vp);
                }
            }
            return;
        }
        if self.draws.contains(&draw) {
            return;
        }
        if self.draws.len() >= MAX_DRAWS {
            self.overflow = true;
            return;
        }
        self.draws.push(draw);
    }
}

/// What the walk follows.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Op {
    Pass(PassRecord),
    /// A dispatch, with the compute bind point's sets and push descriptors.
    Dispatch { sets: Vec<u64>, pushed: Vec<BoundImage> },
    /// A copy, blit or resolve.
    Transfer { src: u64, dst: u64, regions: Vec<TransferRegion> },
    /// Something the walk cannot see through (descriptor buffers bound, too many ops).
    Blind(&'static str),
}

/// One command buffer's ops, appended while it records.
#[derive(Clone, Debug, Default)]
pub struct Recorder {
    ops: Vec<Op>,
    /// Index of the open pass's record in `ops`.
    open: Option<usize>,
    /// Draws recorded with no pass open (a secondary continuing its primary's pass).
    loose: Vec<(Option<bool>, DrawRecord)>,
    frozen: Option<Arc<Vec<Op>>>,
}

impl Recorder {
    fn push(&mut self, op: Op) -> bool {
        self.frozen = None;
        if self.ops.len() >= MAX_OPS {
            if !matches!(self.ops.last(), Some(Op::Blind(_))) {
                self.ops.push(Op::Blind("more commands in one command buffer than the layer keeps"));
            }
            return false;
        }
        self.ops.push(op);
        true
    }
    pub fn begin_pass(&mut self, p: PassRecord) {
        self.open = self.push(Op::Pass(p)).then(|| self.ops.len() - 1);
    }
    pub fn end_pass(&mut self) {
        self.open = None;
    }
    /// The open pass's (or subpass's) record, to ask `pass_tested` about later.
    pub fn open_index(&self) -> Option<usize> {
        self.open
    }
    /// Whether pass record `index` has had a draw that tests depth; None if it is no pass.
    pub fn pass_tested(&self, index: usize) -> Option<bool> {
        match self.ops.get(index) {
            Some(Op::Pass(p)) => Some(p.depth_tested),
            _ => None,
        }
    }
    /// The open pass's depth was cleared by a command inside it.
    pub fn depth_cleared(&mut self) {
        if let Some(Op::Pass(p)) = self.open.and_then(|i| self.ops.get_mut(i)) {
            self.frozen = None;
            p.depth_cleared = true;
        }
    }
    pub fn draw(&mut self, tested: Option<bool>, draw: DrawRecord) {
        match self.open.and_then(|i| self.ops.get_mut(i)) {
            Some(Op::Pass(p)) => {
                self.frozen = None;
                p.draw(tested, draw);
            }
            _ if self.loose.len() < MAX_DRAWS => self.loose.push((tested, draw)),
            _ => {}
        }
    }
    pub fn dispatch(&mut self, sets: Vec<u64>, pushed: Vec<BoundImage>) {
        let op = Op::Dispatch { sets, pushed };
        if self.ops.last() != Some(&op) {
            self.push(op);
        }
    }
    pub fn transfer(&mut self, src: u64, dst: u64, regions: Vec<TransferRegion>) {
        self.push(Op::Transfer { src, dst, regions });
    }
    pub fn blind(&mut self, why: &'static str) {
        self.push(Op::Blind(why));
    }
    /// `vkCmdExecuteCommands`: the secondary's ops run here; its loose draws belong to the pass
    /// open in the primary.
    pub fn execute(&mut self, secondary: &Recorder) {
        for (tested, d) in &secondary.loose {
            self.draw(*tested, d.clone());
        }
        for op in &secondary.ops {
            if !self.push(op.clone()) {
                break;
            }
        }
    }
    /// The ops so far, shared (a resubmitted command buffer costs one reference).
    pub fn snapshot(&mut self) -> Arc<Vec<Op>> {
        self.frozen.get_or_insert_with(|| Arc::new(self.ops.clone())).clone()
    }
    pub fn ops(&self) -> &[Op] {
        &self.ops
    }
}

/// What the walk needs to know about the device's objects.
pub trait World {
    /// A descriptor set's images, or why they cannot be seen; None for an unknown set.
    fn set_images(&self, set: u64) -> Option<Result<Vec<BoundImage>, &'static str>>;
    /// An image view: what it shows, and the extent of its base mip level.
    fn view(&self, view: u64) -> Option<(ImageUse, (u32, u32), bool)>;
    /// An image's extent at mip 0.
    fn extent(&self, image: u64) -> Option<(u32, u32)>;
    /// The swapchain an image belongs to.
    fn swapchain_of(&self, image: u64) -> Option<u64>;
}

/// Where one eye is: a rect of one layer of an image.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Region {
    pub image: u64,
    pub layer: u32,
    pub rect: PixelRect,
}

/// Where a pass is recorded: the command buffer and the index of its record among that
/// recording's ops (`Recorder::open_index`). An image that shows both eyes one after the other
/// in a frame is tied to an eye per use, by this.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct FlowAt {
    pub cb: u64,
    pub op: usize,
}

/// An eye pass the walk reached.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Found {
    /// The pass's colour attachment image, and the eye in it.
    pub image: u64,
    pub eye: EyeSource,
    /// The pass's index in the walked ops: which use of the image this is.
    pub op: usize,
    /// The pass's depth image (a depth prepass that clears it is an eye pass too).
    pub depth: Option<u64>,
    /// How the walk got there, newest step first (for the log): e.g. "blit", "draw", "resolve".
    pub chain: Vec<&'static str>,
}

/// What one walk learned.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Walked {
    pub found: Vec<Found>,
    /// Images written by passes whose draws never test depth on the way: not eye passes.
    pub post: Vec<u64>,
    /// Why a branch ended without an eye pass (deduplicated).
    pub untraced: Vec<String>,
}

/// Steps one walk may take: a post chain is a handful of passes; bloom's mip chains a few more.
const MAX_STEPS: usize = 256;
const MAX_HOPS: usize = 24;

/// Relative aspect difference an input may have and still show the eye.
const ASPECT_TOLERANCE: f64 = 0.03;

#[derive(Clone, Debug)]
struct State {
    region: Region,
    /// Ops at or after this index are later than the region's contents.
    before: usize,
    /// The first op of this frame for this swapchain.
    frame_start: usize,
    chain: Vec<&'static str>,
}

/// Walks `ops` (the frame's and earlier ones', oldest first) back from each eye `start`
/// (view, region in a swapchain image).
pub fn walk(ops: &[&Op], starts: &[(u32, Region)], world: &dyn World) -> Walked {
    let mut out = Walked::default();
    let mut untraced = HashSet::new();
    for &(view, region) in starts {
        let Some((last, _)) = writer(ops, &region, ops.len(), 0, world) else {
            untraced.insert(format!("nothing in the submitted frames writes view {view}'s swapchain image"));
            continue;
        };
        let frame_start = frame_start(ops, &region, last, world);
        let mut queue = vec![State { region, before: last + 1, frame_start, chain: Vec::new() }];
        let mut steps = 0;
        let mut seen = HashSet::new();
        // Dead ends of this view's walk (a history buffer, a LUT's writer in an earlier frame)
        // are only reasons when the view reached no eye pass at all.
        let mut dead_ends = HashSet::new();
        let found_before = out.found.len();
        while let Some(s) = queue.pop() {
            steps += 1;
            if steps > MAX_STEPS {
                dead_ends.insert("the frame's data flow has more steps than the layer follows".into());
                break;
            }
            if s.chain.len() > MAX_HOPS || !seen.insert((s.region, s.before)) {
                continue;
            }
            step(ops, view, &s, world, &mut queue, &mut out, &mut dead_ends);
        }
        if out.found.len() == found_before {
            untraced.extend(dead_ends);
        }
    }
    out.found.sort_by_key(|f| (f.image, f.eye.layer, f.eye.view, f.chain.len()));
    // One rect per image, layer and view: the shortest chain's (fewest rescalings).
    out.found.dedup_by_key(|f| (f.image, f.eye.layer, f.eye.view));
    out.post.sort_unstable();
    out.post.dedup();
    let mut u: Vec<String> = untraced.into_iter().collect();
    u.sort();
    out.untraced = u;
    out
}

/// The index after the previous frame's last write into another image of the same swapchain:
/// what lies before it cannot feed this frame's image (a history buffer read from there is the
/// previous frame's).
fn frame_start(ops: &[&Op], region: &Region, last: usize, world: &dyn World) -> usize {
    let Some(sc) = world.swapchain_of(region.image) else { return 0 };
    for i in (0..last).rev() {
        if writes_images(ops[i], world).iter().any(|im| *im != region.image && world.swapchain_of(*im) == Some(sc)) {
            return i + 1;
        }
    }
    0
}

/// Every image an op writes (frame boundaries; the swapchain images a submission writes).
pub fn writes_images(op: &Op, world: &dyn World) -> Vec<u64> {
    match op {
        Op::Pass(p) => p.colors.iter().chain(p.resolves.iter().map(|(_, r)| r)).map(|u| u.image).collect(),
        Op::Transfer { dst, .. } => vec![*dst],
        Op::Dispatch { sets, pushed } => storage_images(sets, pushed, world).into_iter().map(|u| u.image).collect(),
        Op::Blind(_) => Vec::new(),
    }
}

fn storage_images(sets: &[u64], pushed: &[BoundImage], world: &dyn World) -> Vec<ImageUse> {
    bound(sets, pushed, world).0.into_iter().filter(|(b, _)| b.access == ImageAccess::Storage).map(|(_, u)| u).collect()
}

/// The images bound through `sets` and `pushed` with their views, and why some could not be seen.
fn bound(sets: &[u64], pushed: &[BoundImage], world: &dyn World) -> (Vec<(BoundImage, ImageUse)>, Vec<&'static str>) {
    let mut out = Vec::new();
    let mut blind = Vec::new();
    let mut all: Vec<BoundImage> = pushed.to_vec();
    for s in sets {
        match world.set_images(*s) {
            Some(Ok(images)) => all.extend(images),
            Some(Err(why)) => blind.push(why),
            None => {}
        }
    }
    for b in all {
        if let Some((u, _, _)) = world.view(b.view) {
            out.push((b, u));
        }
    }
    (out, blind)
}

/// The latest op before `before` (and at or after `from`) that writes `region`.
fn writer(ops: &[&Op], region: &Region, before: usize, from: usize, world: &dyn World) -> Option<(usize, Writes)> {
    (from..before.min(ops.len())).rev().find_map(|i| writes(ops[i], region, world).map(|w| (i, w)))
}

/// How an op writes a region.
#[derive(Clone, Debug)]
enum Writes {
    Color(usize),
    Resolve(usize),
    Storage,
    Transfer(Vec<TransferRegion>),
}

fn writes(op: &Op, r: &Region, world: &dyn World) -> Option<Writes> {
    match op {
        Op::Pass(p) => {
            if let Some((ci, _)) = p.resolves.iter().find(|(_, u)| u.holds(r.image, r.layer)) {
                return Some(Writes::Resolve(*ci));
            }
            p.colors.iter().position(|u| u.holds(r.image, r.layer)).map(Writes::Color)
        }
        Op::Transfer { dst, regions, .. } if *dst == r.image => {
            let hit: Vec<TransferRegion> = regions
                .iter()
                .filter(|t| r.layer >= t.dst_layer && r.layer < t.dst_layer + t.layer_count && t.dst.intersect(&r.rect).area() > 0)
                .copied()
                .collect();
            (!hit.is_empty()).then_some(Writes::Transfer(hit))
        }
        Op::Dispatch { sets, pushed } => storage_images(sets, pushed, world).iter().any(|u| u.holds(r.image, r.layer)).then_some(Writes::Storage),
        _ => None,
    }
}

/// Maps `rect` (inside `from`) proportionally into `to`.
pub fn map_rect(rect: &PixelRect, from: &PixelRect, to: &PixelRect) -> PixelRect {
    let sx = to.width as f64 / from.width.max(1) as f64;
    let sy = to.height as f64 / from.height.max(1) as f64;
    let x0 = to.x as f64 + (rect.x - from.x) as f64 * sx;
    let y0 = to.y as f64 + (rect.y - from.y) as f64 * sy;
    let x1 = to.x as f64 + (rect.x as f64 + rect.width as f64 - from.x as f64) * sx;
    let y1 = to.y as f64 + (rect.y as f64 + rect.height as f64 - from.y as f64) * sy;
    let (x0, y0, x1, y1) = (x0.round() as i64, y0.round() as i64, x1.round() as i64, y1.round() as i64);
    PixelRect { x: x0 as i32, y: y0 as i32, width: (x1 - x0).max(0) as u32, height: (y1 - y0).max(0) as u32 }
}

pub fn union(a: &PixelRect, b: &PixelRect) -> PixelRect {
    let x0 = a.x.min(b.x);
    let y0 = a.y.min(b.y);
    let x1 = (a.x as i64 + a.width as i64).max(b.x as i64 + b.width as i64);
    let y1 = (a.y as i64 + a.height as i64).max(b.y as i64 + b.height as i64);
    PixelRect { x: x0, y: y0, width: (x1 - x0 as i64) as u32, height: (y1 - y0 as i64) as u32 }
}

/// Whether `src` can show the eye `eye` shows: the same aspect, at least a quarter of its pixels
/// (bloom mips, LUTs and small inputs are not the eye).
fn shows_eye(src: &PixelRect, eye: &PixelRect) -> bool {
    if src.area() == 0 || eye.area() == 0 || src.area() * 4 < eye.area() {
        return false;
    }
    let a = src.width as f64 / src.height as f64;
    let b = eye.width as f64 / eye.height as f64;
    ((a - b) / b).abs() <= ASPECT_TOLERANCE
}

#[allow(clippy::too_many_arguments)]
fn step(ops: &[&Op], view: u32, s: &State, world: &dyn World, queue: &mut Vec<State>, out: &mut Walked, untraced: &mut HashSet<String>) {
    let Some((i, how)) = writer(ops, &s.region, s.before, s.frame_start, world) else {
        if s.chain.is_empty() {
            untraced.insert(format!("nothing in this frame writes view {view}'s swapchain image"));
        } else {
            untraced.insert(format!("view {view}: an image on the way ({:#x}) is not written in this frame", s.region.image));
        }
        return;
    };
    let next = |region: Region, what: &'static str| {
        let mut chain = vec![what];
        chain.extend(&s.chain);
        State { region, before: i, frame_start: s.frame_start, chain }
    };
    match (ops[i], how) {
        (Op::Transfer { src, .. }, Writes::Transfer(regions)) => {
            for t in regions {
                let dst = t.dst.intersect(&s.region.rect);
                let rect = map_rect(&dst, &t.dst, &t.src);
                let what = if (t.src.width, t.src.height) == (t.dst.width, t.dst.height) { "copy" } else { "scaled blit" };
                queue.push(next(Region { image: *src, layer: s.region.layer - t.dst_layer + t.src_layer, rect }, what));
            }
        }
        (Op::Pass(p), Writes::Resolve(ci)) => {
            let Some(color) = p.colors.get(ci) else { return };
            let layer = color.base_layer + (s.region.layer - resolve_base(p, ci));
            // The resolve happens at the end of this very pass: its colour attachment, same rect.
            let mut st = next(Region { image: color.image, layer, rect: s.region.rect }, "resolve");
            st.before = i + 1;
            queue.push(st);
        }
        (Op::Pass(p), Writes::Color(ci)) => pass_writes(ops, view, s, i, p, ci, world, queue, out, untraced),
        (Op::Dispatch { sets, pushed }, Writes::Storage) => {
            let dst_extent = world.extent(s.region.image).unwrap_or((0, 0));
            let whole = PixelRect { x: 0, y: 0, width: dst_extent.0, height: dst_extent.1 };
            let (reads, blind) = bound(sets, pushed, world);
            for why in blind {
                untraced.insert(format!("view {view}: a compute pass on the way reads through {why}"));
            }
            let mut any = false;
            for (b, u) in reads {
                if u.image == s.region.image || b.access == ImageAccess::Input {
                    continue;
                }
                let Some((_, extent, depth)) = world.view(b.view) else { continue };
                if depth {
                    continue;
                }
                let rect = map_rect(&s.region.rect, &whole, &PixelRect { x: 0, y: 0, width: extent.0, height: extent.1 });
                any |= follow(ops, s, i, Region { image: u.image, layer: input_layer(&u, s.region.layer), rect }, "compute", world, queue);
            }
            if !any {
                untraced.insert(format!("view {view}: a compute pass on the way reads no eye-sized image written in this frame"));
            }
        }
        _ => {}
    }
}

/// The base layer of a resolve target (its layers mirror the colour attachment's).
fn resolve_base(p: &PassRecord, ci: usize) -> u32 {
    p.resolves.iter().find(|(c, _)| *c == ci).map_or(0, |(_, u)| u.base_layer)
}

/// The layer of a read image that shows the eye in `layer` of the written one: the same layer
/// when the read view has it (multiview arrays), else the view's base layer.
fn input_layer(read: &ImageUse, layer: u32) -> u32 {
    if read.layers > 1 && layer >= read.base_layer && layer < read.base_layer + read.layers {
        layer
    } else {
        read.base_layer
    }
}

/// Queues `region` when it can show the eye and an op of this frame writes it.
fn follow(ops: &[&Op], s: &State, i: usize, region: Region, what: &'static str, world: &dyn World, queue: &mut Vec<State>) -> bool {
    if !shows_eye(&region.rect, &s.region.rect) || writer(ops, &region, i, s.frame_start, world).is_none() {
        return false;
    }
    let mut chain = vec![what];
    chain.extend(&s.chain);
    queue.push(State { region, before: i, frame_start: s.frame_start, chain });
    true
}

#[allow(clippy::too_many_arguments)]
fn pass_writes(ops: &[&Op], view: u32, s: &State, i: usize, p: &PassRecord, ci: usize, world: &dyn World, queue: &mut Vec<State>, out: &mut Walked, untraced: &mut HashSet<String>) {
    let color = p.colors[ci];
    if p.depth_tested {
        if p.depth_cleared {
            // The eye pass. Its own draws' viewports inside the eye's rect narrow it when the
            // scene is drawn into a sub-rect of the target (dynamic resolution, DLSS-style); side
            // by side, each eye's draws lie in its own half.
            let drawn = p.tested_viewports.iter().filter(|v| v.intersect(&s.region.rect).area() * 2 > v.area()).fold(None, |u: Option<PixelRect>, v| Some(u.map_or(*v, |u| union(&u, v))));
            let rect = match drawn.map(|v| v.intersect(&s.region.rect)) {
                Some(v) if v.area() > 0 && v.area() * 4 >= s.region.rect.area() => v,
                _ => s.region.rect,
            };
            let eye = EyeSource { view, layer: s.region.layer, rect };
            out.found.push(Found { image: color.image, eye, op: i, depth: p.depth.map(|d| d.image), chain: s.chain.clone() });
            return;
        }
        // Depth loaded (a later pass of the eye: transparents, a pass after a depth prepass): the
        // eye pass is further back, on the same colour image.
        let mut st = s.clone();
        st.before = i;
        st.chain = std::iter::once("loaded pass").chain(s.chain.iter().copied()).collect();
        queue.push(st);
        return;
    }
    out.post.push(color.image);
    let mut any = false;
    let mut blind_seen = Vec::new();
    for d in &p.draws {
        let vp = d.viewport.unwrap_or(p.render_area);
        if vp.intersect(&s.region.rect).area() * 2 < s.region.rect.area() {
            continue;
        }
        let (reads, blind) = bound(&d.sets, &d.pushed, world);
        blind_seen.extend(blind);
        let target = world.extent(color.image).map(|(w, h)| PixelRect { x: 0, y: 0, width: w, height: h });
        for (b, u) in reads {
            if u.image == color.image {
                continue;
            }
            let Some((_, extent, depth)) = world.view(b.view) else { continue };
            if depth || b.access == ImageAccess::Storage {
                continue;
            }
            let input = PixelRect { x: 0, y: 0, width: extent.0, height: extent.1 };
            // The draw samples the whole input over its viewport (a full-screen pass), or the
            // input lines up with the target scaled by their extents (one draw per eye rect
            // into a same-shaped image, e.g. side by side): the first mapping that can show the
            // eye is followed.
            let by_viewport = map_rect(&s.region.rect, &vp, &input);
            let by_extent = target.map(|t| map_rect(&s.region.rect, &t, &input));
            let rect = [Some(by_viewport), by_extent].into_iter().flatten().find(|r| input.contains(r) && shows_eye(r, &s.region.rect));
            if let Some(rect) = rect {
                any |= follow(ops, s, i, Region { image: u.image, layer: input_layer(&u, s.region.layer), rect }, "draw", world, queue);
            }
        }
    }
    for u in &p.inputs {
        if u.image != color.image {
            any |= follow(ops, s, i, Region { image: u.image, layer: input_layer(u, s.region.layer), rect: s.region.rect }, "input attachment", world, queue);
        }
    }
    if p.color_loads.get(ci).copied().unwrap_or(false) {
        // Drawn over the image's earlier contents (an overlay): they still show the eye.
        let mut st = s.clone();
        st.before = i;
        queue.push(st);
        any = true;
    }
    if !any {
        let why = match (blind_seen.first(), p.overflow) {
            (Some(b), _) => format!("eye passes reached the swapchain through a draw the layer could not trace: it reads through {b}"),
            (None, true) => "eye passes reached the swapchain through a draw the layer could not trace: a pass with more distinct draws than the layer keeps".to_string(),
            (None, false) => format!("view {view}: a pass on the way (no depth-tested draw) samples no eye-sized image written in this frame"),
        };
        untraced.insert(why);
    }
}

#[cfg(test)]
#[path = "flow_tests.rs"]
mod tests;
