//! Geometry of the captured views for the tests' own expectations: where a point of the scene
//! lands in a view's image, which pixels a hidden-area mesh covers, and its edge band.

use super::{Fov, View};

/// Where a point given in the captured view's space lands in its image, in pixels of the image
/// rect (x right, y down), or None when it is behind the eye or outside the FOV.
pub fn project(view: &View, p_stage: [f32; 3]) -> Option<(f32, f32)> {
    let [qx, qy, qz, qw] = view.pose.orientation;
    let d = [
        p_stage[0] - view.pose.position[0],
        p_stage[1] - view.pose.position[1],
        p_stage[2] - view.pose.position[2],
    ];
    // Rotate by the inverse (conjugate) orientation: stage → view.
    let v = rotate([-qx, -qy, -qz, qw], d);
    if v[2] >= 0.0 {
        return None;
    }
    let tx = v[0] / -v[2];
    let ty = v[1] / -v[2];
    let (l, r) = (view.fov.angle_left.tan(), view.fov.angle_right.tan());
    let (u, dn) = (view.fov.angle_up.tan(), view.fov.angle_down.tan());
    let fx = (tx - l) / (r - l);
    let fy = (u - ty) / (u - dn);
    if !(0.0..1.0).contains(&fx) || !(0.0..1.0).contains(&fy) {
        return None;
    }
    Some((fx * view.image_rect.width as f32, fy * view.image_rect.height as f32))
}

/// Tangent-plane point (x right, y up) → pixel position in a view's image rect (x right, y down):
/// px = (tx − tan(left)) / (tan(right) − tan(left)) · width,
/// py = (tan(up) − ty) / (tan(up) − tan(down)) · height, in f64 (tangents of the f32 angles).
pub fn tangent_to_pixel(p: [f32; 2], fov: &Fov, width: u32, height: u32) -> [f64; 2] {
    let (l, r) = ((fov.angle_left as f64).tan(), (fov.angle_right as f64).tan());
    let (u, d) = ((fov.angle_up as f64).tan(), (fov.angle_down as f64).tan());
    [(p[0] as f64 - l) / (r - l) * width as f64, (u - p[1] as f64) / (u - d) * height as f64]
}

/// Which pixels of a `width` × `height` view image (its image rect) a hidden-area mask covers,
/// row-major, y down: `mask` is a view's `hidden_triangles` (tangent plane, 3 points per
/// triangle), mapped with [`tangent_to_pixel`] and rasterized by [`triangle_pixels`].
pub fn hidden_pixels(mask: &[[f32; 2]], fov: &Fov, width: u32, height: u32) -> Vec<bool> {
    let px: Vec<[f64; 2]> = mask.iter().map(|&p| tangent_to_pixel(p, fov, width, height)).collect();
    triangle_pixels(&px, width, height)
}

/// Rasterizes triangles given in pixel coordinates (3 points per triangle, either winding; x right,
/// y down) into a row-major coverage image: pixel (x, y) is covered when its centre
/// (x + 0.5, y + 0.5) is inside a triangle, a centre exactly on an edge counting only for a top
/// edge (horizontal, the triangle below it) or a left edge (the triangle to its right) — the
/// top-left rule of D3D, which Vulkan implementations commonly apply (the Vulkan spec itself only
/// requires that exactly one of two triangles sharing an edge covers a sample on that edge).
/// Zero-area triangles cover nothing.
///
/// Exactness: the rule is applied exactly to the f64 coordinates given. An edge shared by two
/// triangles is evaluated from the same endpoint for both, so a centre on it is covered by exactly
/// one of them (no gaps, no double coverage). Tangent → pixel mapping rounds in f64, so through
/// [`hidden_pixels`] a centre within ~1e-9 px of an edge is decided by that rounding; a GPU snaps
/// vertices to a subpixel grid (lavapipe: 1/256 px) and a layer transforms the mask its own way,
/// so tests comparing a rendered image against this should skip [`mask_edge_pixels`].
pub fn triangle_pixels(triangles: &[[f64; 2]], width: u32, height: u32) -> Vec<bool> {
    assert_eq!(triangles.len() % 3, 0, "3 points per triangle");
    let (w, h) = (width as usize, height as usize);
    let mut out = vec![false; w * h];
    for t in triangles.chunks_exact(3) {
        let (a, mut b, mut c) = (t[0], t[1], t[2]);
        let area = cross2(sub2(b, a), sub2(c, a));
        if area.is_nan() || area == 0.0 {
            continue;
        }
        // Orient so that the inside is where every edge function is positive (clockwise on a
        // y-down screen); then a top edge runs in +x and a left edge runs in −y.
        if area < 0.0 {
            std::mem::swap(&mut b, &mut c);
        }
        let edges = [(a, b), (b, c), (c, a)];
        let top_left = edges.map(|(p, q)| {
            let (dx, dy) = (q[0] - p[0], q[1] - p[1]);
            (dy == 0.0 && dx > 0.0) || dy < 0.0
        });
        let Some((x0, x1)) = centre_range([a[0], b[0], c[0]], w) else { continue };
        let Some((y0, y1)) = centre_range([a[1], b[1], c[1]], h) else { continue };
        for y in y0..=y1 {
            for x in x0..=x1 {
                let p = [x as f64 + 0.5, y as f64 + 0.5];
                if edges.iter().zip(top_left).all(|(&(e0, e1), tl)| {
                    let f = edge_function(e0, e1, p);
                    f > 0.0 || (f == 0.0 && tl)
                }) {
                    out[y * w + x] = true;
                }
            }
        }
    }
    out
}

/// Pixels whose centre lies within `margin_px` of the outline of a hidden-area mask (an edge of
/// one triangle that no other triangle shares, endpoints compared exactly): where a rasterizer
/// with other rounding may decide differently from [`hidden_pixels`]. Same layout as its result.
pub fn mask_edge_pixels(mask: &[[f32; 2]], fov: &Fov, width: u32, height: u32, margin_px: f64) -> Vec<bool> {
    assert_eq!(mask.len() % 3, 0, "3 points per triangle");
    let key = |p: [f32; 2]| (p[0].to_bits(), p[1].to_bits());
    let mut count: std::collections::HashMap<_, u32> = std::collections::HashMap::new();
    let edges: Vec<([f32; 2], [f32; 2])> = mask.chunks_exact(3).flat_map(|t| [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])]).collect();
    let undirected = |(p, q): ([f32; 2], [f32; 2])| if key(p) <= key(q) { (key(p), key(q)) } else { (key(q), key(p)) };
    for &e in &edges {
        *count.entry(undirected(e)).or_default() += 1;
    }
    let (w, h) = (width as usize, height as usize);
    let mut out = vec![false; w * h];
    for &(p, q) in edges.iter().filter(|&&e| count[&undirected(e)] == 1) {
        let (a, b) = (tangent_to_pixel(p, fov, width, height), tangent_to_pixel(q, fov, width, height));
        let Some((x0, x1)) = centre_range([a[0] - margin_px, a[0] + margin_px, b[0] - margin_px, b[0] + margin_px], w) else { continue };
        let Some((y0, y1)) = centre_range([a[1] - margin_px, a[1] + margin_px, b[1] - margin_px, b[1] + margin_px], h) else { continue };
        for y in y0..=y1 {
            for x in x0..=x1 {
                if segment_distance([x as f64 + 0.5, y as f64 + 0.5], a, b) <= margin_px {
                    out[y * w + x] = true;
                }
            }
        }
    }
    out
}

fn sub2(a: [f64; 2], b: [f64; 2]) -> [f64; 2] {
    [a[0] - b[0], a[1] - b[1]]
}

fn cross2(a: [f64; 2], b: [f64; 2]) -> f64 {
    a[0] * b[1] - a[1] * b[0]
}

/// cross(q − p, x − p), always computed from the lexicographically smaller endpoint, so that the
/// edge (q, p) of a neighbouring triangle gets exactly the negated value.
fn edge_function(p: [f64; 2], q: [f64; 2], x: [f64; 2]) -> f64 {
    if (p[0], p[1]) <= (q[0], q[1]) {
        cross2(sub2(q, p), sub2(x, p))
    } else {
        -cross2(sub2(p, q), sub2(x, q))
    }
}

/// Indices i in 0..n whose centre i + 0.5 lies in [min(v), max(v)]; None when there are none.
fn centre_range<const N: usize>(v: [f64; N], n: usize) -> Option<(usize, usize)> {
    if v.iter().any(|x| !x.is_finite()) || n == 0 {
        return None;
    }
    let lo = v.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let first = (lo - 0.5).ceil().max(0.0);
    let last = (hi - 0.5).floor().min(n as f64 - 1.0);
    (first <= last).then_some((first as usize, last as usize))
}

fn segment_distance(x: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    let (ab, ax) = (sub2(b, a), sub2(x, a));
    let len2 = ab[0] * ab[0] + ab[1] * ab[1];
    let t = if len2 > 0.0 { ((ax[0] * ab[0] + ax[1] * ab[1]) / len2).clamp(0.0, 1.0) } else { 0.0 };
    let d = [ax[0] - t * ab[0], ax[1] - t * ab[1]];
    (d[0] * d[0] + d[1] * d[1]).sqrt()
}

fn rotate(q: [f32; 4], v: [f32; 3]) -> [f32; 3] {
    let [x, y, z, w] = q;
    // v' = v + 2w (q×v) + 2 q×(q×v)
    let c1 = [y * v[2] - z * v[1], z * v[0] - x * v[2], x * v[1] - y * v[0]];
    let c2 = [y * c1[2] - z * c1[1], z * c1[0] - x * c1[2], x * c1[1] - y * c1[0]];
    [v[0] + 2.0 * (w * c1[0] + c2[0]), v[1] + 2.0 * (w * c1[1] + c2[1]), v[2] + 2.0 * (w * c1[2] + c2[2])]
}
