//! The harness's own mask geometry (tests/common): frames.json's `visibility_masks` and the
//! rasterization of hidden triangles into expected hidden pixels. Pure; needs no build artifacts.

use crate::common;

use common::{hidden_pixels, mask_edge_pixels, triangle_pixels, Fov, Frames};

/// Pixels set in a row-major coverage image, as (x, y).
fn set(img: &[bool], w: usize) -> Vec<(usize, usize)> {
    img.iter().enumerate().filter(|(_, &b)| b).map(|(i, _)| (i % w, i / w)).collect()
}

/// Splits a quad (corners in order) into two triangles along the diagonal from corner `k`,
/// reversing the winding when `flip`.
fn quad(c: [[f64; 2]; 4], k: usize, flip: bool) -> Vec<[f64; 2]> {
    let p = |i: usize| c[(k + i) % 4];
    let mut t = vec![p(0), p(1), p(2), p(0), p(2), p(3)];
    if flip {
        t.swap(1, 2);
        t.swap(4, 5);
    }
    t
}

#[test]
fn top_left_rule_on_a_square_with_edges_through_centres() {
    // Square [0.5, 2.5]² in a 4×4 image: its edges run through pixel centres. Left and top edges
    // are in, right and bottom edges out, so exactly the 2×2 pixels of its area are covered —
    // whichever diagonal splits it and whichever winding its triangles have.
    let c = [[0.5, 0.5], [2.5, 0.5], [2.5, 2.5], [0.5, 2.5]];
    for k in 0..2 {
        for flip in [false, true] {
            let tris = quad(c, k, flip);
            assert_eq!(set(&triangle_pixels(&tris, 4, 4), 4), vec![(0, 0), (1, 0), (0, 1), (1, 1)], "diagonal {k} flip {flip}");
            // The diagonal runs through centre (1.5, 1.5): exactly one of the two triangles has it.
            let a = triangle_pixels(&tris[..3], 4, 4);
            let b = triangle_pixels(&tris[3..], 4, 4);
            assert!(a.iter().zip(&b).all(|(x, y)| !(x & y)), "diagonal {k} flip {flip}: double coverage");
        }
    }
}

#[test]
fn a_fan_with_many_centres_on_its_edges_tiles_exactly() {
    // Rectangle [0.5, 6.5] × [0.5, 4.5] as a fan from (3.5, 2.5) over every half-integer point of
    // its perimeter: many pixel centres lie on shared edges. Every pixel with its centre in
    // [0.5, 6.5) × [0.5, 4.5) must be covered by exactly one triangle, and no other pixel.
    let (w, h) = (8usize, 6usize);
    let mut ring = Vec::new();
    for x in 0..6 {
        ring.push([0.5 + x as f64, 0.5]);
    }
    for y in 0..4 {
        ring.push([6.5, 0.5 + y as f64]);
    }
    for x in 0..6 {
        ring.push([6.5 - x as f64, 4.5]);
    }
    for y in 0..4 {
        ring.push([0.5, 4.5 - y as f64]);
    }
    let centre = [3.5, 2.5];
    let mut count = vec![0u32; w * h];
    let mut all = Vec::new();
    for i in 0..ring.len() {
        let (a, b) = (ring[i], ring[(i + 1) % ring.len()]);
        // Alternate the winding.
        let tri = if i % 2 == 0 { [centre, a, b] } else { [centre, b, a] };
        for (n, c) in count.iter_mut().zip(triangle_pixels(&tri, w as u32, h as u32)) {
            *n += c as u32;
        }
        all.extend(tri);
    }
    for y in 0..h {
        for x in 0..w {
            // Centre x + 0.5 ∈ [0.5, 6.5) ⇔ x ∈ 0..6; y likewise.
            let want = u32::from(x < 6 && y < 4);
            assert_eq!(count[y * w + x], want, "pixel ({x}, {y})");
        }
    }
    assert_eq!(set(&triangle_pixels(&all, w as u32, h as u32), w).len(), 24);
}

#[test]
fn degenerate_and_outside_triangles_cover_nothing() {
    let line = [[0.5, 0.5], [3.5, 3.5], [2.5, 2.5]];
    assert!(triangle_pixels(&line, 4, 4).iter().all(|&b| !b));
    let outside = [[-5.0, -5.0], [-1.0, -5.0], [-1.0, -1.0], [10.0, 0.0], [20.0, 0.0], [20.0, 9.0]];
    assert!(triangle_pixels(&outside, 4, 4).iter().all(|&b| !b));
    // Clipped to the image: a triangle larger than it covers all of it.
    let big = [[-100.0, -100.0], [100.0, -100.0], [0.0, 100.0]];
    assert!(triangle_pixels(&big, 4, 4).iter().all(|&b| b));
}

/// Symmetric ±40° × ±30° view: tangent x = 0 maps to exactly width / 2, y = 0 to height / 2.
fn sym_fov() -> Fov {
    let (h, v) = (40f32.to_radians(), 30f32.to_radians());
    Fov { angle_left: -h, angle_right: h, angle_up: v, angle_down: -v }
}

/// The tangent-plane rectangle [x0, x1] × [y0, y1] as two CCW triangles.
fn tan_rect(x0: f32, x1: f32, y0: f32, y1: f32) -> Vec<[f32; 2]> {
    vec![[x0, y0], [x1, y0], [x1, y1], [x0, y0], [x1, y1], [x0, y1]]
}

#[test]
fn tangent_to_pixel_mapping_x_right_y_down() {
    let fov = sym_fov();
    let (l, r) = (fov.angle_left.tan(), fov.angle_right.tan());
    let (u, d) = (fov.angle_up.tan(), fov.angle_down.tan());
    // Odd sizes: the centre column / row lies exactly on x = 0 / y = 0.
    let (w, h) = (5usize, 3usize);
    let left = hidden_pixels(&tan_rect(l, 0.0, d, u), &fov, w as u32, h as u32);
    let right = hidden_pixels(&tan_rect(0.0, r, d, u), &fov, w as u32, h as u32);
    // Column 2's centre is on x = 0: the right half's left edge takes it, not the left half.
    assert!(set(&left, w).iter().all(|&(x, _)| x < 2) && set(&left, w).len() == 2 * h);
    assert!(set(&right, w).iter().all(|&(x, _)| x >= 2) && set(&right, w).len() == 3 * h);
    // y is up in the tangent plane and down in the image; row 1's centre is on y = 0, the lower
    // half's top edge.
    let top = hidden_pixels(&tan_rect(l, r, 0.0, u), &fov, w as u32, h as u32);
    let bottom = hidden_pixels(&tan_rect(l, r, d, 0.0), &fov, w as u32, h as u32);
    assert_eq!(set(&top, w), (0..w).map(|x| (x, 0)).collect::<Vec<_>>());
    assert_eq!(set(&bottom, w).len(), 2 * w);
    assert!(set(&bottom, w).iter().all(|&(_, y)| y >= 1));
    // An asymmetric view: the top-left corner triangle of the FOV rectangle hides pixel (0, 0)
    // and not the far corner.
    let fov = Fov { angle_left: -0.9, angle_right: 0.7, angle_up: 0.8, angle_down: -0.95 };
    let (l, r) = (fov.angle_left.tan(), fov.angle_right.tan());
    let (u, d) = (fov.angle_up.tan(), fov.angle_down.tan());
    let corner = [[l, u - 0.3], [l + 0.3, u], [l, u]];
    let img = hidden_pixels(&corner, &fov, 40, 40);
    assert!(img[0] && !img[40 * 40 - 1]);
    let p = common::tangent_to_pixel([l, d], &fov, 40, 40);
    assert!(p[0].abs() < 1e-5 && (p[1] - 40.0).abs() < 1e-5, "{p:?}");
    let p = common::tangent_to_pixel([0.5 * (l + r), 0.5 * (u + d)], &fov, 40, 40);
    assert!((p[0] - 20.0).abs() < 1e-4 && (p[1] - 20.0).abs() < 1e-4, "{p:?}");
}

#[test]
fn hidden_corners_match_their_area() {
    // A mask like the runtime's: the FOV rectangle minus an ellipse, as a fan of sector quads
    // (each split into two triangles). The hidden pixel count approximates the hidden area and
    // mask_edge_pixels marks only pixels near the ellipse (not the shared sector edges).
    let fov = Fov { angle_left: -0.95, angle_right: 0.85, angle_up: 0.9, angle_down: -0.92 };
    let (l, r) = (fov.angle_left.tan(), fov.angle_right.tan());
    let (u, d) = (fov.angle_up.tan(), fov.angle_down.tan());
    let (w, h) = (180u32, 200u32);
    // Sector directions: uniform, plus the rectangle's corners (so the outer chords follow it).
    let mut angles: Vec<f32> = (0..96).map(|i| i as f32 / 96.0 * std::f32::consts::TAU - std::f32::consts::PI).collect();
    angles.extend([[r, u], [l, u], [l, d], [r, d]].map(|c| c[1].atan2(c[0])));
    angles.sort_by(f32::total_cmp);
    let (ax, ay) = (1.08 * r.max(-l), 1.08 * u.max(-d));
    // (inner, outer): where the ray leaves the ellipse ∩ rectangle, and the rectangle.
    let point = |t: f32| {
        let dir = [t.cos(), t.sin()];
        let tr = [if dir[0] > 0.0 { r / dir[0] } else { l / dir[0] }, if dir[1] > 0.0 { u / dir[1] } else { d / dir[1] }]
            .into_iter()
            .filter(|t| t.is_finite() && *t > 0.0)
            .fold(f32::INFINITY, f32::min);
        let te = 1.0 / ((dir[0] / ax).powi(2) + (dir[1] / ay).powi(2)).sqrt();
        let ti = te.min(tr);
        ([dir[0] * ti, dir[1] * ti], [dir[0] * tr, dir[1] * tr])
    };
    let cross = |a: [f32; 2], b: [f32; 2], c: [f32; 2]| ((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])) as f64 / 2.0;
    let mut mask = Vec::new();
    let mut area = 0.0f64;
    for i in 0..angles.len() {
        let ((a, b), (d2, c)) = (point(angles[i]), point(angles[(i + 1) % angles.len()]));
        // The quad (a, b, c, d2) split along the diagonal that keeps both halves CCW.
        let tris = if cross(a, b, c) >= 0.0 && cross(a, c, d2) >= 0.0 { [[a, b, c], [a, c, d2]] } else { [[a, b, d2], [b, c, d2]] };
        for t in tris {
            let cr = cross(t[0], t[1], t[2]);
            assert!(cr > -1e-9);
            if cr > 1e-12 {
                mask.extend(t);
                area += cr;
            }
        }
    }
    let img = hidden_pixels(&mask, &fov, w, h);
    let px_area = area * (w as f64 / (r - l) as f64) * (h as f64 / (u - d) as f64);
    let hidden = img.iter().filter(|&&b| b).count() as f64;
    assert!(px_area > 1000.0 && (hidden - px_area).abs() < 0.03 * px_area, "{hidden} hidden pixels, area {px_area}");
    // The four corners are hidden, the centre is not.
    let (wu, hu) = (w as usize, h as usize);
    for i in [0, wu - 1, (hu - 1) * wu, hu * wu - 1] {
        assert!(img[i], "corner {i}");
    }
    assert!(!img[hu / 2 * wu + wu / 2]);
    let edge = mask_edge_pixels(&mask, &fov, w, h, 0.75);
    let near = edge.iter().filter(|&&b| b).count();
    assert!(near > 0 && near < hidden as usize, "{near}");
    // No edge pixel in the middle of a hidden corner (where only shared sector edges run).
    assert!(!edge[2 * wu + 2] && !edge[(hu - 3) * wu + wu - 3]);
}

#[test]
fn mask_edge_pixels_marks_the_outline_only() {
    let fov = sym_fov();
    let (l, u) = (fov.angle_left.tan(), fov.angle_up.tan());
    // The left half of the view, top row band of a 5×3 image: x ∈ [l, 0], y ∈ [0, u]. Its edge
    // x = 0 runs through column 2's centres, y = 0 through row 1's; the diagonal does not count.
    let mask = tan_rect(l, 0.0, 0.0, u);
    let e = mask_edge_pixels(&mask, &fov, 5, 3, 1e-4);
    assert_eq!(set(&e, 5), vec![(2, 0), (0, 1), (1, 1), (2, 1)]);
}

#[test]
fn frames_json_visibility_masks_parse_and_default_to_empty() {
    let with: Frames = serde_json::from_str(
        r#"{ "hmd": "index", "frames": [ { "frame": 0, "display_time": 1, "environment_blend_mode": 1, "layers": [],
            "visibility_masks": [ { "view": 0, "hidden_triangles": [[-1.5, 1.25], [-1, 1.25], [-1.5, 0.75]] },
                                  { "view": 1, "hidden_triangles": [] } ] } ] }"#,
    )
    .unwrap();
    let m = &with.frames[0].visibility_masks;
    assert_eq!(m.len(), 2);
    assert_eq!((m[0].view, m[0].hidden_triangles.clone()), (0, vec![[-1.5, 1.25], [-1.0, 1.25], [-1.5, 0.75]]));
    assert!(m[1].hidden_triangles.is_empty());
    let without: Frames = serde_json::from_str(r#"{ "hmd": "simple", "frames": [ { "frame": 3, "layers": [] } ] }"#).unwrap();
    assert!(without.frames[0].visibility_masks.is_empty());
}
