//! A view's hidden triangles on a pixel grid, pure and GPU-free: where they land in an image
//! (tangent plane → NDC through the view's FOV) and which pixels they cover in a viewport, counted
//! the way the rasterizer does (fixed-point vertices, pixel centres, top-left rule), so the mask's
//! "pixels masked" statistics, the upscale's skipped tiles, the view tricks' cut and the tests'
//! predicted savings all match what the GPU rejects. Shared by features, so it is base.
#![forbid(unsafe_code)]

use crate::core::rect::{PixelRect, ViewportRect};
use crate::core::views::ViewFov;

/// Sub-pixel precision of vertex positions: lavapipe (llvmpipe) and most GPUs snap to 1/256 px.
const SUBPIXEL_BITS: u32 = 8;
const ONE: i64 = 1 << SUBPIXEL_BITS;

/// Maps one tangent-plane point (x right, y up) into Vulkan NDC of an image covering `fov`
/// (x right, y down).
pub fn tangent_to_ndc(p: [f32; 2], fov: &ViewFov) -> [f32; 2] {
    let (l, r, u, d) = (fov.tan_left, fov.tan_right, fov.tan_up, fov.tan_down);
    let x = (2.0 * p[0] - (r + l)) / (r - l);
    // Vulkan's y points down: the tangent plane's up is NDC −1.
    let y = -(2.0 * p[1] - (u + d)) / (u - d);
    [x, y]
}

/// A view's hidden triangles (3 points each) in NDC; points of a FOV without extent map nowhere
/// (empty), so a broken FOV never produces a mask.
pub fn triangles_to_ndc(triangles: &[[f32; 2]], fov: &ViewFov) -> Vec<[f32; 2]> {
    if !(fov.tan_right > fov.tan_left && fov.tan_up > fov.tan_down) {
        return Vec::new();
    }
    // A triangle with a point that maps nowhere (NaN, infinite) is dropped whole: dropping single
    // points would splice the next triangles' points together (a malformed runtime mesh must not
    // turn into triangles over the visible image). Dropping hides less, never more.
    triangles
        .chunks_exact(3)
        .map(|t| [tangent_to_ndc(t[0], fov), tangent_to_ndc(t[1], fov), tangent_to_ndc(t[2], fov)])
        .filter(|t| t.iter().all(|p| p[0].is_finite() && p[1].is_finite()))
        .flatten()
        .collect()
}

/// The largest clip area `coverage_bitmap` counts (8192 × 8192): beyond any real eye image, and a
/// bound on what a malformed rect can make the layer allocate.
pub const MAX_COUNTED_PIXELS: u64 = 1 << 26;

/// Vertex positions are clamped to ±2^22 pixels before fixed-point edge math, so the products of
/// two coordinate differences stay within i64 (2^(22+8+1) squared < 2^63) whatever a mesh holds.
const MAX_COORD_PX: f64 = (1u64 << 22) as f64;

/// Which pixels of `clip` (viewport ∩ scissor, framebuffer pixels) NDC triangles cover: a
/// row-major bitmap of `clip`, a pixel set when its centre is inside a triangle by the top-left
/// rule. Overlapping triangles count a pixel once.
pub fn coverage_bitmap(ndc: &[[f32; 2]], viewport: ViewportRect, scissor: PixelRect) -> (PixelRect, Vec<bool>) {
    // Pixels whose centres lie inside the viewport (primitives are clipped to it).
    // Within i32 (what a rect holds), whatever the floats: no overflow below.
    let px = |f: f32| (f.ceil() as f64).clamp(i32::MIN as f64, i32::MAX as f64) as i64;
    let vx0 = px(viewport.x - 0.5);
    let vy0 = px(viewport.y - 0.5);
    let vx1 = px(viewport.x + viewport.width - 0.5);
    let vy1 = px(viewport.y + viewport.height - 0.5);
    let vp = PixelRect {
        x: vx0 as i32,
        y: vy0 as i32,
        width: (vx1 - vx0).max(0) as u32,
        height: (vy1 - vy0).max(0) as u32,
    };
    let clip = vp.intersect(&scissor);
    if clip.area() > MAX_COUNTED_PIXELS {
        return (PixelRect { width: 0, height: 0, ..clip }, Vec::new());
    }
    let mut bits = vec![false; clip.area() as usize];
    let to_fixed = |p: [f32; 2]| -> (i64, i64) {
        // f32, as the GPU's viewport transform computes it (the counts must match it exactly).
        let fx = (viewport.x + (p[0] + 1.0) * 0.5 * viewport.width) as f64;
        let fy = (viewport.y + (p[1] + 1.0) * 0.5 * viewport.height) as f64;
        // NaN clamps to NaN and casts to 0; the triangle is then degenerate or harmless.
        let fixed = |f: f64| (f.clamp(-MAX_COORD_PX, MAX_COORD_PX) * ONE as f64).round() as i64;
        (fixed(fx), fixed(fy))
    };
    for tri in ndc.chunks_exact(3) {
        let mut v = [to_fixed(tri[0]), to_fixed(tri[1]), to_fixed(tri[2])];
        let area = (v[1].0 - v[0].0) * (v[2].1 - v[0].1) - (v[1].1 - v[0].1) * (v[2].0 - v[0].0);
        if area == 0 {
            continue;
        }
        if area < 0 {
            v.swap(1, 2);
        }
        // Edge a→b; the interior is where E(p) = dx·(py−ay) − dy·(px−ax) > 0. In y-down pixel
        // space a top edge is horizontal with the interior below (dx > 0), a left edge has the
        // interior to its right (dy < 0); pixel centres exactly on those edges are inside.
        let edges: Vec<(i64, i64, i64, i64, bool)> = (0..3)
            .map(|i| {
                let (a, b) = (v[i], v[(i + 1) % 3]);
                let (dx, dy) = (b.0 - a.0, b.1 - a.1);
                let top_left = (dy == 0 && dx > 0) || dy < 0;
                (a.0, a.1, dx, dy, top_left)
            })
            .collect();
        let min_x = v.iter().map(|p| p.0).min().unwrap_or(0);
        let max_x = v.iter().map(|p| p.0).max().unwrap_or(0);
        let min_y = v.iter().map(|p| p.1).min().unwrap_or(0);
        let max_y = v.iter().map(|p| p.1).max().unwrap_or(0);
        let px0 = (min_x.div_euclid(ONE) - 1).max(clip.x as i64);
        let px1 = (max_x.div_euclid(ONE) + 1).min(clip.x as i64 + clip.width as i64 - 1);
        let py0 = (min_y.div_euclid(ONE) - 1).max(clip.y as i64);
        let py1 = (max_y.div_euclid(ONE) + 1).min(clip.y as i64 + clip.height as i64 - 1);
        for py in py0..=py1 {
            let cy = py * ONE + ONE / 2;
            for px in px0..=px1 {
                let cx = px * ONE + ONE / 2;
                let inside = edges.iter().all(|&(ax, ay, dx, dy, tl)| {
                    let e = dx * (cy - ay) - dy * (cx - ax);
                    e > 0 || (e == 0 && tl)
                });
                if inside {
                    bits[((py - clip.y as i64) as u64 * clip.width as u64 + (px - clip.x as i64) as u64) as usize] = true;
                }
            }
        }
    }
    (clip, bits)
}

/// Which pixels of a whole `size` image showing `fov` a view's hidden triangles (tangent plane,
/// three points each) cover, row-major, as the GPU rasterizes the mask; None when nothing maps
/// (no triangles, a FOV without extent) or the image is too large to count.
pub fn hidden_pixels(triangles: &[[f32; 2]], fov: &ViewFov, size: (u32, u32)) -> Option<Vec<bool>> {
    let rect = PixelRect { x: 0, y: 0, width: size.0, height: size.1 };
    let ndc = triangles_to_ndc(triangles, fov);
    if ndc.is_empty() {
        return None;
    }
    let (clip, bits) = coverage_bitmap(&ndc, rect.viewport(), rect);
    (clip == rect && bits.len() as u64 == rect.area()).then_some(bits)
}

/// How many pixels NDC triangles cover in a viewport, within a scissor.
pub fn coverage(ndc: &[[f32; 2]], viewport: ViewportRect, scissor: PixelRect) -> u64 {
    coverage_bitmap(ndc, viewport, scissor).1.iter().filter(|&&b| b).count() as u64
}

/// How many pixels of an eye's image rect a view's hidden triangles (tangent plane) cover when the
/// image rect shows `fov`: the prediction of what the mask saves per pass.
pub fn masked_pixels(triangles: &[[f32; 2]], fov: &ViewFov, rect: PixelRect) -> u64 {
    coverage(&triangles_to_ndc(triangles, fov), rect.viewport(), rect)
}

/// Expands an indexed mesh (as `xrGetVisibilityMaskKHR` returns it) into a triangle list; indices
/// out of range drop their triangle (a malformed runtime mesh must not take the app down).
pub fn expand(vertices: &[[f32; 2]], indices: &[u32]) -> Vec<[f32; 2]> {
    indices
        .chunks_exact(3)
        .filter(|tri| tri.iter().all(|&i| (i as usize) < vertices.len()))
        .flat_map(|tri| tri.iter().map(|&i| vertices[i as usize]))
        .collect()
}

#[cfg(test)]
mod hostile {
    //! Malformed runtime meshes, FOVs and rects (issue 11): the geometry never panics, never
    //! allocates beyond `MAX_COUNTED_PIXELS`, and never makes a triangle out of points of
    //! different input triangles.
    use super::*;
    use proptest::prelude::*;

    fn any_f32() -> impl Strategy<Value = f32> {
        prop_oneof![
            4 => -4.0f32..4.0,
            1 => Just(f32::NAN),
            1 => Just(f32::INFINITY),
            1 => Just(f32::NEG_INFINITY),
            1 => Just(0.0f32),
            1 => any::<f32>(),
        ]
    }

    fn fov() -> impl Strategy<Value = ViewFov> {
        (any_f32(), any_f32(), any_f32(), any_f32()).prop_map(|(l, r, u, d)| ViewFov { tan_left: l, tan_right: r, tan_up: u, tan_down: d })
    }

    fn rect() -> impl Strategy<Value = PixelRect> {
        (prop_oneof![-100i32..100, any::<i32>()], prop_oneof![-100i32..100, any::<i32>()], 0u32..200, 0u32..200)
            .prop_map(|(x, y, width, height)| PixelRect { x, y, width, height })
    }

    proptest! {
        #[test]
        fn malformed_meshes_fovs_and_rects_are_harmless(points in prop::collection::vec((any_f32(), any_f32()), 0..40), fov in fov(), rect in rect()) {
            let tris: Vec<[f32; 2]> = points.iter().map(|&(x, y)| [x, y]).collect();
            let ndc = triangles_to_ndc(&tris, &fov);
            prop_assert_eq!(ndc.len() % 3, 0);
            prop_assert!(ndc.iter().all(|p| p[0].is_finite() && p[1].is_finite()));
            // Every output triangle is the image of one input triangle, in order.
            let mapped: Vec<[[f32; 2]; 3]> = tris.chunks_exact(3).map(|t| [tangent_to_ndc(t[0], &fov), tangent_to_ndc(t[1], &fov), tangent_to_ndc(t[2], &fov)]).collect();
            let mut next = mapped.iter();
            for t in ndc.chunks_exact(3) {
                prop_assert!(next.any(|m| m[..] == *t), "triangle {:?} is no input triangle's image", t);
            }
            let masked = masked_pixels(&tris, &fov, rect);
            prop_assert!(masked <= rect.area());
        }

        #[test]
        fn huge_and_non_finite_viewports_are_bounded(x in any_f32(), y in any_f32(), w in any_f32(), h in any_f32(), scissor in rect()) {
            let ndc = [[-1.0, -1.0], [3.0, -1.0], [-1.0, 3.0], [f32::MAX, 0.0], [0.0, -f32::MAX], [1.0e30, 1.0e30]];
            let (clip, bits) = coverage_bitmap(&ndc, ViewportRect { x: x * 1.0e6, y: y * 1.0e6, width: w * 1.0e6, height: h * 1.0e6 }, scissor);
            prop_assert_eq!(bits.len() as u64, clip.area());
            prop_assert!(clip.area() <= MAX_COUNTED_PIXELS);
        }
    }

    #[test]
    fn a_rect_beyond_any_eye_is_not_counted() {
        let huge = PixelRect { x: 0, y: 0, width: u32::MAX, height: u32::MAX };
        let tris = [[-10.0, -10.0], [10.0, -10.0], [-10.0, 10.0]];
        let fov = ViewFov { tan_left: -1.0, tan_right: 1.0, tan_up: 1.0, tan_down: -1.0 };
        assert_eq!(masked_pixels(&tris, &fov, huge), 0);
    }

    #[test]
    fn a_bad_point_drops_its_own_triangle_only() {
        let fov = ViewFov { tan_left: -1.0, tan_right: 1.0, tan_up: 1.0, tan_down: -1.0 };
        let tris = [[0.0, 0.0], [f32::NAN, 0.0], [0.0, 1.0], [0.0, 0.0], [1.0, 0.0], [0.0, 1.0]];
        assert_eq!(triangles_to_ndc(&tris, &fov), vec![[0.0, 0.0], [1.0, 0.0], [0.0, -1.0]]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const FOV: ViewFov = ViewFov { tan_left: -1.0, tan_right: 1.0, tan_up: 1.0, tan_down: -1.0 };

    #[test]
    fn tangent_plane_maps_to_vulkan_ndc() {
        assert_eq!(tangent_to_ndc([-1.0, 1.0], &FOV), [-1.0, -1.0], "top left");
        assert_eq!(tangent_to_ndc([1.0, -1.0], &FOV), [1.0, 1.0], "bottom right");
        let asym = ViewFov { tan_left: -2.0, tan_right: 1.0, tan_up: 0.5, tan_down: -1.5 };
        assert_eq!(tangent_to_ndc([-2.0, 0.5], &asym), [-1.0, -1.0]);
        assert_eq!(tangent_to_ndc([1.0, -1.5], &asym), [1.0, 1.0]);
        let c = tangent_to_ndc([-0.5, -0.5], &asym);
        assert!((c[0] - 0.0).abs() < 1e-6 && (c[1] - 0.0).abs() < 1e-6, "{c:?}");
        assert!(triangles_to_ndc(&[[0.0, 0.0]; 3], &ViewFov { tan_left: 1.0, ..FOV }).is_empty());
        assert_eq!(triangles_to_ndc(&[[0.0, 0.0]; 5], &FOV).len(), 3, "a partial triangle is dropped");
    }

    fn full_quad() -> Vec<[f32; 2]> {
        vec![[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]]
    }

    #[test]
    fn a_full_screen_quad_covers_every_pixel_once() {
        let r = PixelRect { x: 0, y: 0, width: 37, height: 23 };
        assert_eq!(coverage(&full_quad(), r.viewport(), r), 37 * 23);
        // The shared diagonal is counted once (top-left rule and the bitmap).
        let scissor = PixelRect { x: 5, y: 5, width: 10, height: 100 };
        assert_eq!(coverage(&full_quad(), r.viewport(), scissor), 10 * 18);
    }

    #[test]
    fn top_left_rule_on_pixel_centres() {
        // A triangle whose left edge runs through pixel centres x = 2.5 and whose top edge runs
        // through y = 1.5: those centres are inside; the right/bottom ones on edges are not.
        let vp = ViewportRect { x: 0.0, y: 0.0, width: 10.0, height: 10.0 };
        let to_ndc = |x: f32, y: f32| [x / 5.0 - 1.0, y / 5.0 - 1.0];
        // Rectangle [2.5, 6.5] × [1.5, 4.5] as two triangles, both windings.
        let rect = vec![
            to_ndc(2.5, 1.5),
            to_ndc(6.5, 1.5),
            to_ndc(6.5, 4.5),
            to_ndc(2.5, 1.5),
            to_ndc(2.5, 4.5),
            to_ndc(6.5, 4.5),
        ];
        let (clip, bits) = coverage_bitmap(&rect, vp, PixelRect { x: 0, y: 0, width: 10, height: 10 });
        let at = |x: usize, y: usize| bits[y * clip.width as usize + x];
        // Columns 2..=5 (centres 2.5..5.5; 6.5 is on the right edge), rows 1..=3.
        for y in 0..10 {
            for x in 0..10 {
                assert_eq!(at(x, y), (2..=5).contains(&x) && (1..=3).contains(&y), "pixel {x},{y}");
            }
        }
    }

    #[test]
    fn masked_pixels_of_a_corner_triangle() {
        // The top-left half of the image above the anti-diagonal: (0,0), (w,0), (0,h).
        let tris = vec![[-1.0, 1.0], [1.0, 1.0], [-1.0, -1.0]];
        let rect = PixelRect { x: 100, y: 0, width: 100, height: 100 };
        let n = masked_pixels(&tris, &FOV, rect);
        // Pixel centres with x + y < 100 (exclusive diagonal) plus the diagonal by the rule.
        assert!((4950..=5050).contains(&n), "{n}");
    }

    #[test]
    fn expand_drops_bad_indices() {
        let v = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]];
        assert_eq!(expand(&v, &[0, 1, 2, 0, 1, 7, 2]), vec![[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]);
    }
}
