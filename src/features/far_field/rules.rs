//! The far field's pure rules: depth ↔ distance for the app's projection, the split distance from
//! a pixel budget, the per-pixel map from the destination eye's image into the source's, and the
//! schedule (which eye is the source in a frame, which frame a reuse may read).
#![forbid(unsafe_code)]

use crate::core::rect::PixelRect;
use crate::core::views::{DepthRange, ViewFov, ViewPose};
use glam::{DMat3, DQuat, DVec3};

/// The app's depth convention, as `1/z = a + b·depth` (exact for any perspective projection:
/// window depth is affine in 1/z), with the depth the layer writes for the split plane.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InverseDepth {
    pub a: f64,
    pub b: f64,
}

impl InverseDepth {
    /// From `XrCompositionLayerDepthInfoKHR`'s fields (or the configured range). None for a
    /// range that maps no distance (equal or non-positive distances, empty depth range).
    pub fn of(r: &DepthRange) -> Option<InverseDepth> {
        let (n, f) = (r.near_z as f64, r.far_z as f64);
        let (d0, d1) = (r.min_depth as f64, r.max_depth as f64);
        // NaN fails every comparison, so it lands here too.
        // One plane may be at infinity (an infinite projection; reversed Z puts it at min depth).
        let valid = n > 0.0 && f > 0.0 && n != f && (n.is_finite() || f.is_finite()) && d1 > d0 && d0.is_finite() && d1.is_finite();
        if !valid {
            return None;
        }
        let inv = |z: f64| if z.is_infinite() { 0.0 } else { 1.0 / z };
        // depth = d0 + (d1 - d0)·(1/z - 1/n)/(1/f - 1/n)  ⇔  1/z = 1/n + (depth - d0)·k
        let k = (inv(f) - inv(n)) / (d1 - d0);
        Some(InverseDepth { a: inv(n) - d0 * k, b: k })
    }
    /// 1/z of a stored depth value.
    pub fn inv_z(&self, depth: f64) -> f64 {
        self.a + self.b * depth
    }
    /// The stored depth of distance `z` (metres along the view axis).
    pub fn depth_of(&self, z: f64) -> f64 {
        (1.0 / z - self.a) / self.b
    }
    /// Larger depth values are nearer (reversed Z).
    pub fn reversed(&self) -> bool {
        self.b > 0.0
    }
}

/// A documented engine's default projection, used for apps that submit no
/// `XrCompositionLayerDepthInfoKHR` and have no configured range.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EngineDepth {
    /// Near and far plane distances (metres; far may be infinite). The convention (reversed or
    /// not) is read from the pass's depth clear, as for a configured range.
    pub near: f64,
    pub far: f64,
    /// Where the numbers come from (for the log).
    pub source: &'static str,
}

/// The default projection of the engine named in `VkApplicationInfo::pEngineName`; None for an
/// engine without a documented default (its near plane is the app's choice: configure it).
pub fn engine_depth(engine: &str) -> Option<EngineDepth> {
    match engine {
        // wgpu names itself "wgpu-hal"; its VR apps are Bevy + bevy_mod_openxr, whose
        // `XrProjection` defaults to near 0.1 m with an infinite, reversed-Z projection.
        // Through the OpenXR runtime (xrCreateVulkanInstanceKHR) bevy_mod_openxr names the
        // engine "Bevy".
        "wgpu-hal" | "wgpu" | "Bevy" => Some(EngineDepth { near: 0.1, far: f64::INFINITY, source: "wgpu (Bevy + bevy_mod_openxr's XrProjection: near 0.1 m, infinite far)" }),
        _ => None,
    }
}

/// Where the far field's depth range came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RangeSource {
    DepthInfo,
    Config,
    Engine(&'static str),
}

/// `depth_range` with the engine's default as the last resort, and where the range came from.
pub fn depth_range_with_engine(submitted: Option<DepthRange>, configured: Option<(f64, f64)>, engine: Option<EngineDepth>, reversed: bool) -> Option<(DepthRange, RangeSource)> {
    if let Some(r) = submitted {
        return Some((r, RangeSource::DepthInfo));
    }
    if let Some(r) = depth_range(None, configured, reversed) {
        return Some((r, RangeSource::Config));
    }
    let e = engine?;
    depth_range(None, Some((e.near, e.far)), reversed).map(|r| (r, RangeSource::Engine(e.source)))
}

/// The projection range to use: the app's depth info, else the configured range (near and far
/// plane distances, stored the other way round when the pass clears depth to 0: reversed Z), else
/// none (the feature is then not applied: a guessed range could reuse near pixels).
pub fn depth_range(submitted: Option<DepthRange>, configured: Option<(f64, f64)>, reversed: bool) -> Option<DepthRange> {
    submitted.or_else(|| {
        configured.map(|(n, f)| {
            let (at_min, at_max) = if reversed { (f, n) } else { (n, f) };
            DepthRange { near_z: at_min as f32, far_z: at_max as f32, min_depth: 0.0, max_depth: 1.0 }
        })
    })
}

/// A view as the far field sees it: where it is, where it looks, its FOV and its pixels.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ViewGeometry {
    /// `t_world_view` rotation.
    pub orientation: DQuat,
    pub position: DVec3,
    pub fov: ViewFov,
    /// The view's pixels in its image (the eye's `imageRect`, or the copy's extent).
    pub rect: PixelRect,
}

impl ViewGeometry {
    pub fn of(pose: &ViewPose, rect: PixelRect) -> ViewGeometry {
        let [x, y, z, w] = pose.orientation.map(f64::from);
        let [px, py, pz] = pose.position.map(f64::from);
        ViewGeometry { orientation: DQuat::from_xyzw(x, y, z, w).normalize(), position: DVec3::new(px, py, pz), fov: pose.fov, rect }
    }
    /// Radians per pixel at the image centre, the smaller of the two axes (the finer one bounds
    /// the disparity a pixel shows).
    pub fn pixel_angle(&self) -> f64 {
        let f = &self.fov;
        let h = (f.tan_right - f.tan_left) as f64 / self.rect.width.max(1) as f64;
        let v = (f.tan_up - f.tan_down) as f64 / self.rect.height.max(1) as f64;
        h.min(v)
    }
    /// `t_view_pixel`: pixel (x, y, 1) → direction in view space (x right, y up, −z forward).
    fn t_view_pixel(&self) -> DMat3 {
        let f = &self.fov;
        let sx = (f.tan_right - f.tan_left) as f64 / self.rect.width as f64;
        let sy = (f.tan_up - f.tan_down) as f64 / self.rect.height as f64;
        // tan_x = tan_left + (x − rx)·sx; tan_y = tan_up − (y − ry)·sy; z = −1.
        DMat3::from_cols(
            DVec3::new(sx, 0.0, 0.0),
            DVec3::new(0.0, -sy, 0.0),
            DVec3::new(f.tan_left as f64 - self.rect.x as f64 * sx, f.tan_up as f64 + self.rect.y as f64 * sy, -1.0),
        )
    }
    /// `t_pixel_view`: direction → homogeneous pixel (u·w, v·w, w) with w = −z (in front: w > 0).
    fn t_pixel_view(&self) -> DMat3 {
        self.t_view_pixel().inverse()
    }
}

/// The split distance in metres: `split_m` when set, else where a point's disparity between the
/// two eyes (baseline / distance, radians) drops to `split_px` pixels of the finer eye.
pub fn split_distance(split_px: f64, split_m: Option<f64>, a: &ViewGeometry, b: &ViewGeometry) -> f64 {
    if let Some(m) = split_m {
        return m;
    }
    let baseline = (a.position - b.position).length();
    let pixel = a.pixel_angle().min(b.pixel_angle());
    if split_px <= 0.0 || pixel <= 0.0 {
        return f64::INFINITY;
    }
    baseline / (split_px * pixel)
}

/// The per-pixel map from a destination pixel into the source's image: for destination pixel
/// `p = (x, y, 1)` at distance z, the source pixel is `(h + k / z).xy / (h + k / z).z` with
/// `h = m·p` (`shift = infinity` uses `k = 0`: directions only).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PixelMap {
    /// `t_srcpixel_dstpixel` at infinity.
    pub m: DMat3,
    /// The destination's position seen from the source, in source pixels (for `shift = depth`).
    pub k: DVec3,
}

impl PixelMap {
    pub fn new(src: &ViewGeometry, dst: &ViewGeometry) -> PixelMap {
        let t_src_dst = src.orientation.inverse() * dst.orientation;
        let m = src.t_pixel_view() * DMat3::from_quat(t_src_dst) * dst.t_view_pixel();
        let t = src.orientation.inverse() * (dst.position - src.position);
        PixelMap { m, k: src.t_pixel_view() * t }
    }
    /// The source pixel of destination pixel `(x, y)` (pixel centres at .5) at `inv_z` = 1/z
    /// (0: infinity); None behind the source.
    pub fn map(&self, x: f64, y: f64, inv_z: f64) -> Option<(f64, f64)> {
        let h = self.m * DVec3::new(x, y, 1.0) + self.k * inv_z;
        (h.z > 1e-9).then(|| (h.x / h.z, h.y / h.z))
    }
}

/// Whether destination pixel (x, y) (its centre) can take the source's colour where the scene
/// there lies beyond the split: its bilinear footprint in the source's `width`×`height` copy, at
/// `inv_z` (0 for `shift = infinity`; the split's 1/z for `shift = depth`, the largest shift a far
/// sample gets), lies inside the copy. `shaders/far_field.frag` makes the same test (`inside` of
/// `floor(uv − 0.5)` and the texel after it) before it looks at the source's depth.
pub fn footprint_inside(map: &PixelMap, x: u32, y: u32, inv_z: f64, width: u32, height: u32) -> bool {
    let Some((u, v)) = map.map(x as f64 + 0.5, y as f64 + 0.5, inv_z) else { return false };
    let (t0x, t0y) = ((u - 0.5).floor(), (v - 0.5).floor());
    t0x >= 0.0 && t0y >= 0.0 && t0x + 1.0 < width as f64 && t0y + 1.0 < height as f64
}

/// Which eye renders everything in `frame` (the source): fixed, or alternating every frame.
pub fn source_view(frame: u64, source_view: u32, alternate: bool) -> u32 {
    if alternate {
        (source_view + (frame % 2) as u32) % 2
    } else {
        source_view
    }
}

/// The destination eye of a frame (the other of two views).
pub fn dest_view(frame: u64, source: u32, alternate: bool) -> u32 {
    1 - source_view(frame, source, alternate)
}

/// A copy of an eye's pixels the layer made at the end of its pass: which view, in which frame,
/// and whether the app rendered all of it that frame (the eye was the source).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Stamp {
    pub view: u32,
    pub frame: u64,
    pub rendered: bool,
}

/// Why a destination pass reuses nothing this frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum NoSource {
    /// The pass is not the destination this frame (the source eye renders everything).
    NotDestination,
    /// No copy rendered by the app in this or the previous frame is there to read.
    NoFreshCopy,
}

/// What a destination pass reads, decided at submission: the copy in `slot` must be this
/// frame's of the source eye (`same_frame`) or the previous frame's of the eye that was the
/// source then (`previous_frame`); anything older, or a copy of an eye that itself reused pixels,
/// is refused, so a far field can never freeze or be a copy of a copy.
pub fn check_source(frame: u64, dst: u32, source: u32, alternate: bool, slot: Option<Stamp>) -> Result<Stamp, NoSource> {
    if dest_view(frame, source, alternate) != dst {
        return Err(NoSource::NotDestination);
    }
    let s = slot.ok_or(NoSource::NoFreshCopy)?;
    let this_frame = s.frame == frame && s.view == source_view(frame, source, alternate);
    let last_frame = frame > 0 && s.frame == frame - 1 && s.view == source_view(frame - 1, source, alternate);
    if s.rendered && (this_frame || last_frame) {
        Ok(s)
    } else {
        Err(NoSource::NoFreshCopy)
    }
}

/// The slot (view whose copy) a destination pass of `dst` reads: the other eye's when its copy
/// precedes the pass in the same recording (same frame), else the eye that was the source in the
/// previous frame — with alternation that is the destination's own previous image.
pub fn slot_to_read(dst: u32, other_copied_before: bool, timing: super::SourceTiming, source: u32, alternate: bool) -> u32 {
    let same = match timing {
        super::SourceTiming::SameFrame => true,
        super::SourceTiming::PreviousFrame => false,
        super::SourceTiming::Auto => other_copied_before,
    };
    if same || !alternate {
        if same {
            1 - dst
        } else {
            source
        }
    } else {
        // Alternating: the previous frame's source is this frame's destination.
        dst
    }
}

/// Tiles are `TILE`×`TILE` pixels: the source's depth is reduced per tile
/// (`shaders/far_field_tiles.comp`), the reuse draw is a grid of destination tiles
/// (`shaders/far_field.vert`). Both shaders hard-code the same size.
pub const TILE: u32 = 16;

/// Tiles per row and rows of tiles covering `width`×`height` pixels (partial tiles at the edges).
pub fn tile_grid(width: u32, height: u32) -> (u32, u32) {
    (width.div_ceil(TILE), height.div_ceil(TILE))
}

/// Vertices of the reuse draw over a `width`×`height` destination view: two triangles per tile.
pub fn reuse_vertices(width: u32, height: u32) -> u32 {
    let (x, y) = tile_grid(width, height);
    6 * x * y
}

/// Which of a pass's eyes (`eyes`: view, layer, viewport, known at submission) a draw or copy
/// recorded before they were known is: it was guessed as `guess` (view, layer, rect: the render
/// area), one guess per view, so the eye is the guessed view's in the guessed layer. Its rect must
/// lie in the guess: a reuse draw over the guess then covers it wherever it is (two eyes side by
/// side included); a copy of the guess (`at_origin`: into a slot at the origin) must find it at
/// the guess's origin, so that the slot holds it at its own origin (dynamic resolution shrinks the
/// viewport at the target's origin). Err(None): the pass has no eye of that view (the guess is
/// another pass's); Err(Some(why)): it has, elsewhere.
pub fn resolve_guess(eyes: &[(u32, u32, PixelRect)], (view, layer, rect): (u32, u32, PixelRect), at_origin: bool) -> Result<(u32, PixelRect), Option<&'static str>> {
    let &(v, _, r) = eyes.iter().find(|(v, l, _)| *l == layer && *v == view).ok_or(None)?;
    let inside = r.x >= rect.x && r.y >= rect.y && r.x + r.width as i32 <= rect.x + rect.width as i32 && r.y + r.height as i32 <= rect.y + rect.height as i32 && r.area() > 0;
    let placed = !at_origin || (r.x == rect.x && r.y == rect.y);
    if inside && placed {
        Ok((v, r))
    } else {
        Err(Some("rect_changing"))
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn tiles_cover_the_view_with_partial_edges() {
        assert_eq!(super::tile_grid(16, 16), (1, 1));
        assert_eq!(super::tile_grid(17, 33), (2, 3));
        assert_eq!(super::tile_grid(2016, 2240), (126, 140));
        assert_eq!(super::tile_grid(0, 5), (0, 1));
        assert_eq!(super::reuse_vertices(2016, 2240), 6 * 126 * 140);
        assert_eq!(super::reuse_vertices(0, 100), 0);
    }

    use super::*;
    use proptest::prelude::*;

    fn fov() -> ViewFov {
        ViewFov { tan_left: -1.0, tan_right: 0.9, tan_up: 1.0, tan_down: -1.1 }
    }
    fn rect() -> PixelRect {
        PixelRect { x: 0, y: 0, width: 1000, height: 1000 }
    }
    fn eye(x: f64, yaw_deg: f64) -> ViewGeometry {
        ViewGeometry { orientation: DQuat::from_rotation_y(yaw_deg.to_radians()), position: DVec3::new(x, 1.6, 0.0), fov: fov(), rect: rect() }
    }

    #[test]
    fn inverse_depth_standard_reversed_and_infinite() {
        let std = InverseDepth::of(&DepthRange { near_z: 0.05, far_z: 2000.0, min_depth: 0.0, max_depth: 1.0 }).unwrap();
        // The fields are f32, as in XrCompositionLayerDepthInfoKHR.
        assert!((std.depth_of(0.05f32 as f64)).abs() < 1e-9 && (std.depth_of(2000.0) - 1.0).abs() < 1e-9);
        assert!((1.0 / std.inv_z(std.depth_of(37.0)) - 37.0).abs() < 1e-6);
        assert!(!std.reversed());
        let rev = InverseDepth::of(&DepthRange { near_z: 2000.0, far_z: 0.05, min_depth: 0.0, max_depth: 1.0 }).unwrap();
        assert!((rev.depth_of(0.05f32 as f64) - 1.0).abs() < 1e-9 && rev.depth_of(2000.0).abs() < 1e-9 && rev.reversed());
        // Reversed infinite (Bevy): depth 1 at 0.1 m, 0 at infinity; 1/z = depth / 0.1.
        let rev_inf = InverseDepth::of(&DepthRange { near_z: f32::INFINITY, far_z: 0.1, min_depth: 0.0, max_depth: 1.0 }).unwrap();
        assert!(rev_inf.reversed());
        assert!((rev_inf.depth_of(10.0) - 0.01).abs() < 1e-6 && rev_inf.depth_of(0.1) > 0.999);
        assert!(InverseDepth::of(&DepthRange { near_z: f32::INFINITY, far_z: f32::INFINITY, min_depth: 0.0, max_depth: 1.0 }).is_none());
        let inf = InverseDepth::of(&DepthRange { near_z: 0.1, far_z: f32::INFINITY, min_depth: 0.0, max_depth: 1.0 }).unwrap();
        assert!((inf.depth_of(0.1f32 as f64)).abs() < 1e-9 && inf.inv_z(1.0).abs() < 1e-12);
        let ranged = InverseDepth::of(&DepthRange { near_z: 1.0, far_z: 100.0, min_depth: 0.25, max_depth: 0.75 }).unwrap();
        assert!((ranged.depth_of(1.0) - 0.25).abs() < 1e-9 && (ranged.depth_of(100.0) - 0.75).abs() < 1e-9);
        assert!(InverseDepth::of(&DepthRange { near_z: 1.0, far_z: 1.0, min_depth: 0.0, max_depth: 1.0 }).is_none());
    }

    #[test]
    fn configured_range_only_without_depth_info() {
        let info = DepthRange { near_z: 0.1, far_z: 100.0, min_depth: 0.0, max_depth: 1.0 };
        assert_eq!(depth_range(Some(info), Some((1.0, 2.0)), true), Some(info));
        assert_eq!(depth_range(None, Some((1.0, 2.0)), false).unwrap().far_z, 2.0);
        let rev = depth_range(None, Some((1.0, 2.0)), true).unwrap();
        assert_eq!((rev.near_z, rev.far_z), (2.0, 1.0));
        assert!(InverseDepth::of(&rev).unwrap().reversed());
        assert_eq!(depth_range(None, None, false), None);
        // The engine default comes last, and says so.
        let wgpu = engine_depth("wgpu-hal");
        let (r, src) = depth_range_with_engine(None, None, wgpu, true).unwrap();
        assert!(matches!(src, RangeSource::Engine(s) if s.contains("Bevy")));
        assert_eq!((r.near_z, r.far_z), (f32::INFINITY, 0.1));
        assert_eq!(depth_range_with_engine(None, Some((1.0, 2.0)), wgpu, false).unwrap().1, RangeSource::Config);
        assert_eq!(depth_range_with_engine(Some(info), None, wgpu, false).unwrap().1, RangeSource::DepthInfo);
        assert_eq!(engine_depth("Unity"), None, "no documented default: the app's own choice");
    }

    #[test]
    fn split_distance_from_the_pixel_budget() {
        let (a, b) = (eye(-0.032, 0.0), eye(0.032, 0.0));
        // 1.9 / 1000 rad per pixel, 64 mm baseline: 33.7 m for one pixel, a quarter for four.
        let one = split_distance(1.0, None, &a, &b);
        assert!((one - 0.064 / 0.0019).abs() < 1e-6, "{one}");
        assert!((split_distance(4.0, None, &a, &b) - one / 4.0).abs() < 1e-6);
        assert_eq!(split_distance(1.0, Some(12.0), &a, &b), 12.0);
        // The disparity of a point at the split distance is the budget, in pixels.
        let map = PixelMap::new(&a, &b);
        let at_inf = map.map(500.5, 500.5, 0.0).unwrap();
        let at_split = map.map(500.5, 500.5, 1.0 / one).unwrap();
        assert!(((at_split.0 - at_inf.0).hypot(at_split.1 - at_inf.1) - 1.9 / 1.9).abs() < 0.01, "{at_inf:?} {at_split:?}");
    }

    #[test]
    fn footprints_inside_the_copy() {
        let a = eye(0.0, 0.0);
        let m = PixelMap::new(&a, &a);
        // The same view: every pixel but the last row and column (their footprint's second texel
        // lies outside) is inside.
        assert!(footprint_inside(&m, 0, 0, 0.0, 1000, 1000));
        assert!(footprint_inside(&m, 998, 998, 0.0, 1000, 1000));
        assert!(!footprint_inside(&m, 999, 5, 0.0, 1000, 1000));
        // Turned 20° left: the destination's left edge has no counterpart in the source.
        let m = PixelMap::new(&a, &eye(0.0, 20.0));
        assert!(!footprint_inside(&m, 0, 500, 0.0, 1000, 1000) && footprint_inside(&m, 900, 500, 0.0, 1000, 1000));
        let back = ViewGeometry { orientation: DQuat::from_rotation_y(std::f64::consts::PI), ..a };
        assert!(!footprint_inside(&PixelMap::new(&a, &back), 500, 500, 0.0, 1000, 1000));
    }

    #[test]
    fn same_view_maps_to_itself() {
        let a = eye(0.0, 10.0);
        let m = PixelMap::new(&a, &a);
        for (x, y) in [(0.5, 0.5), (999.5, 10.5), (321.5, 654.5)] {
            let (u, v) = m.map(x, y, 0.3).unwrap();
            assert!((u - x).abs() < 1e-9 && (v - y).abs() < 1e-9);
        }
    }

    #[test]
    fn rotation_and_rects_map_like_the_projection() {
        // Destination turned 5° left of the source, its eye rect at x = 1000 of a side-by-side image.
        let src = eye(0.0, 0.0);
        let mut dst = eye(0.0, 5.0);
        dst.rect = PixelRect { x: 1000, y: 0, width: 1000, height: 1000 };
        let m = PixelMap::new(&src, &dst);
        // The destination's optical axis (tan 0, 0) is 5° left in the source.
        let x0 = 1000.0 + 1.0 / 1.9 * 1000.0;
        let y0 = 1.0 / 2.1 * 1000.0;
        let (u, v) = m.map(x0, y0, 0.0).unwrap();
        let expect_u = (-(5f64.to_radians().tan()) + 1.0) / 1.9 * 1000.0;
        assert!((u - expect_u).abs() < 1e-6 && (v - y0).abs() < 1e-6, "{u} {v} vs {expect_u} {y0}");
        // Behind the source: no pixel.
        let back = ViewGeometry { orientation: DQuat::from_rotation_y(std::f64::consts::PI), ..src };
        assert!(PixelMap::new(&src, &back).map(500.0, 500.0, 0.0).is_none());
    }

    #[test]
    fn depth_shift_is_exact_for_a_fronto_parallel_plane() {
        let (s, d) = (eye(-0.032, 0.0), eye(0.032, 0.0));
        let m = PixelMap::new(&s, &d);
        // A point 3 m ahead, seen by the destination at pixel p, lands in the source where the
        // source's own projection puts it.
        let world = DVec3::new(0.2, 1.7, -3.0);
        let project = |g: &ViewGeometry| {
            let v = g.orientation.inverse() * (world - g.position);
            let h = g.t_pixel_view() * v;
            (h.x / h.z, h.y / h.z)
        };
        let (x, y) = project(&d);
        let (u, v) = m.map(x, y, 1.0 / 3.0).unwrap();
        let (eu, ev) = project(&s);
        assert!((u - eu).abs() < 1e-6 && (v - ev).abs() < 1e-6, "{u},{v} vs {eu},{ev}");
    }

    #[test]
    fn schedule_alternates_and_refuses_stale_copies() {
        assert_eq!((source_view(4, 0, false), dest_view(4, 0, false)), (0, 1));
        assert_eq!((source_view(5, 0, true), dest_view(5, 0, true)), (1, 0));
        let fresh = Stamp { view: 0, frame: 10, rendered: true };
        assert_eq!(check_source(10, 1, 0, false, Some(fresh)), Ok(fresh));
        assert_eq!(check_source(11, 1, 0, false, Some(fresh)), Ok(fresh), "previous frame's source");
        assert_eq!(check_source(12, 1, 0, false, Some(fresh)), Err(NoSource::NoFreshCopy), "two frames old");
        assert_eq!(check_source(10, 0, 0, false, Some(fresh)), Err(NoSource::NotDestination));
        assert_eq!(check_source(10, 1, 0, false, Some(Stamp { rendered: false, ..fresh })), Err(NoSource::NoFreshCopy));
        assert_eq!(check_source(10, 1, 0, false, None), Err(NoSource::NoFreshCopy));
        // Alternating, frame 11: destination 0 reads its own frame-10 image (rendered: the source then).
        assert_eq!(check_source(11, 0, 0, true, Some(fresh)), Ok(fresh));
        assert_eq!(slot_to_read(0, false, super::super::SourceTiming::Auto, 0, true), 0);
        assert_eq!(slot_to_read(1, true, super::super::SourceTiming::Auto, 0, true), 0);
        assert_eq!(slot_to_read(1, false, super::super::SourceTiming::Auto, 0, false), 0);
        assert_eq!(slot_to_read(0, false, super::super::SourceTiming::Auto, 1, false), 1);
    }

    proptest! {
        /// Simulates frames of a two-eye app (either pass order, or both eyes in one pass) under
        /// every setting: each eye renders its whole far field at least every second frame, and
        /// every reused pixel was rendered by the app at most one frame earlier.
        #[test]
        fn no_frozen_far_field(frames in 2u64..40, source in 0u32..2, alternate: bool, order in 0usize..3, timing in 0usize..3) {
            let timing = [super::super::SourceTiming::Auto, super::super::SourceTiming::SameFrame, super::super::SourceTiming::PreviousFrame][timing];
            // slots[v]: the copy of view v, with the frame whose app-rendered pixels it holds.
            let mut slots: [Option<Stamp>; 2] = [None, None];
            let mut last_full = [None::<u64>; 2];
            for frame in 0..frames {
                let passes: Vec<Vec<u32>> = match order { 0 => vec![vec![0], vec![1]], 1 => vec![vec![1], vec![0]], _ => vec![vec![0, 1]] };
                let mut copied: Vec<u32> = Vec::new();
                let mut reused_this_frame = [false; 2];
                for pass in passes {
                    for &v in &pass {
                        let other_before = copied.contains(&(1 - v));
                        let slot = slot_to_read(v, other_before, timing, source, alternate);
                        if let Ok(s) = check_source(frame, v, source, alternate, slots[slot as usize]) {
                            prop_assert!(frame - s.frame <= 1 && s.rendered);
                            reused_this_frame[v as usize] = true;
                        }
                    }
                    for &v in &pass {
                        let rendered = !reused_this_frame[v as usize];
                        slots[v as usize] = Some(Stamp { view: v, frame, rendered });
                        copied.push(v);
                        if rendered {
                            last_full[v as usize] = Some(frame);
                        }
                    }
                }
                // Alternating, no eye carries the reuse for more than one frame in a row.
                if alternate {
                    for (v, last) in last_full.iter().enumerate() {
                        prop_assert!(last.map_or(frame == 0, |f| frame - f <= 1), "view {v} last rendered in full at {last:?}, now {frame}");
                    }
                }
            }
        }
    }

    #[test]
    fn a_guess_resolves_to_the_eye_of_its_view() {
        let area = PixelRect { x: 0, y: 0, width: 100, height: 80 };
        let small = PixelRect { x: 0, y: 0, width: 45, height: 60 };
        let right = PixelRect { x: 50, ..small };
        // The guessed view's eye in the guessed layer, the whole area or a smaller rect.
        assert_eq!(resolve_guess(&[(1, 0, area)], (1, 0, area), true), Ok((1, area)));
        assert_eq!(resolve_guess(&[(0, 0, small)], (0, 0, area), true), Ok((0, small)));
        // Side by side: each view its own eye; a copy needs it at the guess's origin.
        let sbs = [(0, 0, small), (1, 0, right)];
        assert_eq!(resolve_guess(&sbs, (1, 0, area), false), Ok((1, right)));
        assert_eq!(resolve_guess(&sbs, (1, 0, area), true), Err(Some("rect_changing")));
        assert_eq!(resolve_guess(&sbs, (0, 0, area), true), Ok((0, small)));
        // Outside the guess: named; no eye of that view (another pass's guess): None.
        assert_eq!(resolve_guess(&[(1, 0, PixelRect { width: 101, ..area })], (1, 0, area), false), Err(Some("rect_changing")));
        assert_eq!(resolve_guess(&[(0, 0, small)], (1, 0, area), false), Err(None));
        assert_eq!(resolve_guess(&[(1, 1, small)], (1, 0, area), false), Err(None));
    }
}
