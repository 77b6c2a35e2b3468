//! Unit tests of the data-flow walk: every frame structure issue 20 names, built from ops.

use super::*;
use std::collections::HashMap;

/// Images by handle: (width, height, layers, swapchain, depth); views = image handle + 1000.
#[derive(Default)]
struct FakeWorld {
    images: HashMap<u64, (u32, u32, u32, Option<u64>, bool)>,
    sets: HashMap<u64, Result<Vec<BoundImage>, &'static str>>,
}

impl FakeWorld {
    fn image(mut self, h: u64, w: u32, height: u32, layers: u32, swapchain: Option<u64>) -> Self {
        self.images.insert(h, (w, height, layers, swapchain, false));
        self
    }
    fn depth(mut self, h: u64, w: u32, height: u32) -> Self {
        self.images.insert(h, (w, height, 1, None, true));
        self
    }
    fn set(mut self, set: u64, images: &[(u64, ImageAccess)]) -> Self {
        self.sets.insert(set, Ok(images.iter().map(|&(i, access)| BoundImage { view: i + 1000, access }).collect()));
        self
    }
}

impl World for FakeWorld {
    fn set_images(&self, set: u64) -> Option<Result<Vec<BoundImage>, &'static str>> {
        self.sets.get(&set).cloned()
    }
    fn view(&self, view: u64) -> Option<(ImageUse, (u32, u32), bool)> {
        let image = view - 1000;
        let &(w, h, layers, _, depth) = self.images.get(&image)?;
        Some((ImageUse { image, base_layer: 0, layers, mip: 0 }, (w, h), depth))
    }
    fn extent(&self, image: u64) -> Option<(u32, u32)> {
        self.images.get(&image).map(|i| (i.0, i.1))
    }
    fn swapchain_of(&self, image: u64) -> Option<u64> {
        self.images.get(&image)?.3
    }
}

fn rect(x: i32, y: i32, w: u32, h: u32) -> PixelRect {
    PixelRect { x, y, width: w, height: h }
}

fn img(image: u64, layers: u32) -> ImageUse {
    ImageUse { image, base_layer: 0, layers, mip: 0 }
}

/// A pass whose draws test depth against a cleared depth buffer (an eye pass).
fn scene(color: u64, depth: u64, w: u32, h: u32) -> PassRecord {
    let mut p = PassRecord { colors: vec![img(color, 1)], color_loads: vec![false], depth: Some(img(depth, 1)), depth_cleared: true, render_area: rect(0, 0, w, h), ..Default::default() };
    p.draw(Some(true), DrawRecord { viewport: Some(rect(0, 0, w, h)), sets: vec![], pushed: vec![] });
    p
}

/// A full-screen post draw into `target` sampling the images of `set`.
fn post(target: u64, w: u32, h: u32, set: u64) -> PassRecord {
    let mut p = PassRecord { colors: vec![img(target, 1)], color_loads: vec![false], render_area: rect(0, 0, w, h), ..Default::default() };
    p.draw(Some(false), DrawRecord { viewport: Some(rect(0, 0, w, h)), sets: vec![set], pushed: vec![] });
    p
}

fn region(image: u64, w: u32, h: u32) -> Region {
    Region { image, layer: 0, rect: rect(0, 0, w, h) }
}

fn run(ops: &[Op], starts: &[(u32, Region)], world: &FakeWorld) -> Walked {
    let refs: Vec<&Op> = ops.iter().collect();
    walk(&refs, starts, world)
}

const S: ImageAccess = ImageAccess::Sampled;

#[test]
fn direct_rendering_finds_the_swapchain_image_itself() {
    let w = FakeWorld::default().image(100, 64, 32, 1, Some(1)).depth(2, 64, 32);
    let r = run(&[Op::Pass(scene(100, 2, 64, 32))], &[(0, region(100, 64, 32))], &w);
    assert_eq!(r.found.len(), 1);
    assert_eq!((r.found[0].image, r.found[0].eye.rect, r.found[0].depth), (100, rect(0, 0, 64, 32), Some(2)));
    assert!(r.post.is_empty() && r.untraced.is_empty());
}

#[test]
fn msaa_resolve_then_tonemap_reaches_the_msaa_eye_pass() {
    let w = FakeWorld::default().image(100, 64, 32, 1, Some(1)).image(10, 64, 32, 1, None).image(11, 64, 32, 1, None).depth(12, 64, 32).set(5, &[(11, S)]);
    let mut main = scene(10, 12, 64, 32);
    main.resolves = vec![(0, img(11, 1))];
    let r = run(&[Op::Pass(main), Op::Pass(post(100, 64, 32, 5))], &[(0, region(100, 64, 32))], &w);
    assert_eq!(r.found.iter().map(|f| (f.image, f.eye.rect)).collect::<Vec<_>>(), vec![(10, rect(0, 0, 64, 32))]);
    assert_eq!(r.found[0].chain, vec!["resolve", "draw"]);
    assert_eq!(r.post, vec![100]);
}

#[test]
fn render_scale_maps_the_rect_into_the_smaller_target() {
    let w = FakeWorld::default().image(100, 100, 50, 1, Some(1)).image(11, 70, 35, 1, None).depth(12, 70, 35).set(5, &[(11, S)]);
    let r = run(&[Op::Pass(scene(11, 12, 70, 35)), Op::Pass(post(100, 100, 50, 5))], &[(0, region(100, 100, 50))], &w);
    assert_eq!(r.found[0].eye.rect, rect(0, 0, 70, 35));
}

#[test]
fn bloom_and_luts_do_not_become_eyes_and_history_is_last_frames() {
    // Scene 11 (64×32); bloom: 13 (32×16) from 11, 14 (16×8) from 13; a 16×16 LUT 15; history 16
    // written only in the previous frame (before that frame's write into swapchain image 101).
    let w = FakeWorld::default()
        .image(100, 64, 32, 1, Some(1))
        .image(101, 64, 32, 1, Some(1))
        .image(11, 64, 32, 1, None)
        .image(13, 32, 16, 1, None)
        .image(14, 16, 8, 1, None)
        .image(15, 16, 16, 1, None)
        .image(16, 64, 32, 1, None)
        .depth(12, 64, 32)
        .set(5, &[(11, S), (13, S), (14, S), (15, S), (16, S)])
        .set(6, &[(11, S)])
        .set(7, &[(13, S)])
        .set(8, &[(11, S)]);
    let ops = vec![
        Op::Pass(post(16, 64, 32, 8)), // last frame's history write
        Op::Pass(post(101, 64, 32, 8)), // last frame's final
        Op::Pass(scene(11, 12, 64, 32)),
        Op::Pass(post(13, 32, 16, 6)),
        Op::Pass(post(14, 16, 8, 7)),
        Op::Pass(post(100, 64, 32, 5)),
    ];
    let r = run(&ops, &[(0, region(100, 64, 32))], &w);
    assert_eq!(r.found.iter().map(|f| (f.image, f.eye.rect)).collect::<Vec<_>>(), vec![(11, rect(0, 0, 64, 32))]);
    assert_eq!(r.found[0].chain, vec!["draw"], "the direct path is kept, not the one through bloom");
    assert!(!r.post.contains(&16), "the history buffer of the last frame is not followed");
    assert!(r.post.contains(&13), "the half-size bloom level keeps the aspect and a quarter of the pixels");
    assert!(!r.post.contains(&14), "a quarter-size mip is too small to show the eye");
}

#[test]
fn compute_tonemap_then_copy() {
    let w = FakeWorld::default()
        .image(100, 64, 32, 1, Some(1))
        .image(11, 64, 32, 1, None)
        .image(16, 64, 32, 1, None)
        .depth(12, 64, 32)
        .set(5, &[(11, S), (16, ImageAccess::Storage)]);
    let whole = rect(0, 0, 64, 32);
    let ops = vec![
        Op::Pass(scene(11, 12, 64, 32)),
        Op::Dispatch { sets: vec![5], pushed: vec![] },
        Op::Transfer { src: 16, dst: 100, regions: vec![TransferRegion { src_layer: 0, dst_layer: 0, layer_count: 1, src: whole, dst: whole }] },
    ];
    let r = run(&ops, &[(0, region(100, 64, 32))], &w);
    assert_eq!(r.found.iter().map(|f| (f.image, f.chain.clone())).collect::<Vec<_>>(), vec![(11, vec!["compute", "copy"])]);
}

#[test]
fn subpass_input_attachment_reaches_the_first_subpass() {
    let w = FakeWorld::default().image(100, 64, 32, 1, Some(1)).image(17, 64, 32, 1, None).depth(12, 64, 32);
    let mut tonemap = post(100, 64, 32, 99);
    tonemap.inputs = vec![img(17, 1)];
    let r = run(&[Op::Pass(scene(17, 12, 64, 32)), Op::Pass(tonemap)], &[(0, region(100, 64, 32))], &w);
    assert_eq!(r.found.iter().map(|f| (f.image, f.chain.clone())).collect::<Vec<_>>(), vec![(17, vec!["input attachment"])]);
}

#[test]
fn double_wide_texture_blitted_per_layer() {
    // Both eyes in one 128×32 texture, each half blitted into a layer of a 2-layer swapchain.
    let w = FakeWorld::default().image(100, 64, 32, 2, Some(1)).image(18, 128, 32, 1, None).depth(12, 128, 32);
    let mut sbs = scene(18, 12, 128, 32);
    sbs.tested_viewports.clear();
    sbs.draw(Some(true), DrawRecord { viewport: Some(rect(0, 0, 64, 32)), sets: vec![], pushed: vec![] });
    sbs.draw(Some(true), DrawRecord { viewport: Some(rect(64, 0, 64, 32)), sets: vec![], pushed: vec![] });
    let half = |x| TransferRegion { src_layer: 0, dst_layer: 0, layer_count: 1, src: rect(x, 0, 64, 32), dst: rect(0, 0, 64, 32) };
    let ops = vec![
        Op::Pass(sbs),
        Op::Transfer { src: 18, dst: 100, regions: vec![half(0)] },
        Op::Transfer { src: 18, dst: 100, regions: vec![TransferRegion { dst_layer: 1, ..half(64) }] },
    ];
    let starts = [(0, region(100, 64, 32)), (1, Region { layer: 1, ..region(100, 64, 32) })];
    let r = run(&ops, &starts, &w);
    let got: Vec<_> = r.found.iter().map(|f| (f.eye.view, f.eye.layer, f.eye.rect)).collect();
    assert_eq!(got, vec![(0, 0, rect(0, 0, 64, 32)), (1, 0, rect(64, 0, 64, 32))]);
}

#[test]
fn viewport_scale_narrows_the_eye_to_the_drawn_sub_rect() {
    let w = FakeWorld::default().image(100, 64, 32, 1, Some(1)).image(11, 64, 32, 1, None).depth(12, 64, 32).set(5, &[(11, S)]);
    let mut main = scene(11, 12, 64, 32);
    main.tested_viewports = vec![rect(0, 0, 48, 24)];
    let r = run(&[Op::Pass(main), Op::Pass(post(100, 64, 32, 5))], &[(0, region(100, 64, 32))], &w);
    assert_eq!(r.found[0].eye.rect, rect(0, 0, 48, 24));
}

#[test]
fn loaded_passes_lead_back_to_the_pass_that_cleared_depth() {
    let w = FakeWorld::default().image(100, 64, 32, 1, Some(1)).image(11, 64, 32, 1, None).depth(12, 64, 32).set(5, &[(11, S)]);
    let mut transparent = scene(11, 12, 64, 32);
    transparent.depth_cleared = false;
    transparent.color_loads = vec![true];
    let r = run(&[Op::Pass(scene(11, 12, 64, 32)), Op::Pass(transparent), Op::Pass(post(100, 64, 32, 5))], &[(0, region(100, 64, 32))], &w);
    assert_eq!(r.found.iter().map(|f| f.chain.clone()).collect::<Vec<_>>(), vec![vec!["loaded pass", "draw"]]);
}

#[test]
fn what_cannot_be_seen_is_named() {
    let mut w = FakeWorld::default().image(100, 64, 32, 1, Some(1)).image(11, 64, 32, 1, None).depth(12, 64, 32);
    w.sets.insert(5, Err("a bindless image array"));
    let r = run(&[Op::Pass(scene(11, 12, 64, 32)), Op::Pass(post(100, 64, 32, 5))], &[(0, region(100, 64, 32))], &w);
    assert!(r.found.is_empty());
    assert_eq!(r.untraced, vec!["eye passes reached the swapchain through a draw the layer could not trace: it reads through a bindless image array".to_string()]);
    let r = run(&[], &[(0, region(100, 64, 32))], &w);
    assert!(r.untraced[0].contains("nothing in the submitted frames"), "{:?}", r.untraced);
}

#[test]
fn recorder_merges_draws_and_secondaries_join_the_open_pass() {
    let mut rec = Recorder::default();
    rec.begin_pass(post(100, 64, 32, 5));
    let d = DrawRecord { viewport: Some(rect(0, 0, 64, 32)), sets: vec![5], pushed: vec![] };
    rec.draw(Some(false), d.clone());
    let mut secondary = Recorder::default();
    secondary.draw(Some(true), DrawRecord { viewport: Some(rect(0, 0, 8, 8)), sets: vec![], pushed: vec![] });
    rec.execute(&secondary);
    rec.end_pass();
    let snap = rec.snapshot();
    assert!(Arc::ptr_eq(&snap, &rec.snapshot()), "an unchanged recording is shared");
    let Op::Pass(p) = &snap[0] else { panic!() };
    assert_eq!(p.draws.len(), 1, "identical draws merge");
    assert!(p.depth_tested && p.tested_viewports == vec![rect(0, 0, 8, 8)]);
    for _ in 0..MAX_OPS + 10 {
        rec.blind("x");
    }
    assert!(rec.ops().len() <= MAX_OPS + 1);
}

#[test]
fn rects_map_proportionally() {
    assert_eq!(map_rect(&rect(32, 0, 32, 32), &rect(0, 0, 64, 32), &rect(0, 0, 32, 16)), rect(16, 0, 16, 16));
    assert_eq!(union(&rect(0, 0, 2, 2), &rect(4, 4, 2, 2)), rect(0, 0, 6, 6));
    assert!(shows_eye(&rect(0, 0, 32, 16), &rect(0, 0, 64, 32)));
    assert!(!shows_eye(&rect(0, 0, 31, 8), &rect(0, 0, 64, 32)));
}

#[test]
fn per_eye_post_draws_over_a_double_wide_image_map_by_extent() {
    // Side by side: scene and post target both 128×32; one post draw per eye rect samples the
    // whole scene image with UVs of its half (the viewport alone would say "the whole image").
    let w = FakeWorld::default().image(100, 128, 32, 1, Some(1)).image(11, 128, 32, 1, None).depth(12, 128, 32).set(5, &[(11, S)]);
    let mut post = post(100, 128, 32, 5);
    post.draws.clear();
    post.draw(Some(false), DrawRecord { viewport: Some(rect(0, 0, 64, 32)), sets: vec![5], pushed: vec![] });
    post.draw(Some(false), DrawRecord { viewport: Some(rect(64, 0, 64, 32)), sets: vec![5], pushed: vec![] });
    let starts = [(0, Region { image: 100, layer: 0, rect: rect(0, 0, 64, 32) }), (1, Region { image: 100, layer: 0, rect: rect(64, 0, 64, 32) })];
    let r = run(&[Op::Pass(scene(11, 12, 128, 32)), Op::Pass(post)], &starts, &w);
    let got: Vec<_> = r.found.iter().map(|f| (f.eye.view, f.eye.rect)).collect();
    assert_eq!(got, vec![(0, rect(0, 0, 64, 32)), (1, rect(64, 0, 64, 32))]);
}

#[test]
fn dead_ends_are_reasons_only_for_views_that_found_nothing() {
    // A TAA-like history written last frame: a dead end, but the view found its eye pass.
    let w = FakeWorld::default().image(100, 64, 32, 1, Some(1)).image(101, 64, 32, 1, Some(1)).image(11, 64, 32, 1, None).image(16, 64, 32, 1, None).depth(12, 64, 32).set(5, &[(11, S), (16, S)]);
    let whole = rect(0, 0, 64, 32);
    let copy = |src, dst| Op::Transfer { src, dst, regions: vec![TransferRegion { src_layer: 0, dst_layer: 0, layer_count: 1, src: whole, dst: whole }] };
    let ops = vec![Op::Pass(post(101, 64, 32, 5)), copy(101, 16), Op::Pass(scene(11, 12, 64, 32)), Op::Pass(post(100, 64, 32, 5))];
    let r = run(&ops, &[(0, region(100, 64, 32))], &w);
    assert_eq!(r.found.len(), 1);
    assert!(r.untraced.is_empty(), "{:?}", r.untraced);
}

#[test]
fn side_by_side_sub_rects_narrow_each_eye_to_its_own() {
    // Each eye drawn into the top-left 48×24 of its 64×32 half; the tonemap draws each half.
    let w = FakeWorld::default().image(100, 128, 32, 1, Some(1)).image(11, 128, 32, 1, None).depth(12, 128, 32).set(5, &[(11, S)]);
    let mut sbs = scene(11, 12, 128, 32);
    sbs.tested_viewports = vec![rect(0, 0, 48, 24), rect(64, 0, 48, 24)];
    let starts = [(0, Region { image: 100, layer: 0, rect: rect(0, 0, 64, 32) }), (1, Region { image: 100, layer: 0, rect: rect(64, 0, 64, 32) })];
    let r = run(&[Op::Pass(sbs), Op::Pass(post(100, 128, 32, 5))], &starts, &w);
    let got: Vec<_> = r.found.iter().map(|f| (f.eye.view, f.eye.rect)).collect();
    assert_eq!(got, vec![(0, rect(0, 0, 48, 24)), (1, rect(64, 0, 48, 24))]);
}
