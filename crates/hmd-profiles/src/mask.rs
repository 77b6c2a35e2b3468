//! XR_KHR_visibility_mask geometry of a profile: hidden / visible triangle meshes and the line
//! loop of each view, built from the profile's lens outline (a published line loop, or an
//! approximating ellipse: profile.rs). The mock runtime returns them from
//! `xrGetVisibilityMaskKHR`; `stereoshim preview --hmd` uses them as that runtime's masks.
//!
//! Geometry lives in the view's z = −1 tangent plane (x = tan of the horizontal angle, y = tan
//! of the vertical angle, y up). The lens outline is star-shaped around the view axis (0, 0), so
//! both meshes are built as fans of angular sectors around it: between two consecutive sector
//! directions the outline and the FOV rectangle are each one straight segment, hence
//! visible ∪ hidden is exactly the rectangle and their areas sum to its area.
#![forbid(unsafe_code)]

use crate::profile::HmdProfile;

pub type V2 = [f32; 2];

/// Mask geometry of one type: vertices and indices (triangles CCW, or a line loop).
#[derive(Debug, Clone, PartialEq)]
pub struct Mesh {
    pub vertices: Vec<V2>,
    pub indices: Vec<u32>,
}

pub fn cross(a: V2, b: V2) -> f32 {
    a[0] * b[1] - a[1] * b[0]
}

fn sub(a: V2, b: V2) -> V2 {
    [a[0] - b[0], a[1] - b[1]]
}

/// Distance along the unit direction `d` from the origin to where it leaves `poly` (the polygon
/// is closed and contains the origin).
fn ray_exit(poly: &[V2], d: V2) -> f32 {
    let mut best = f32::INFINITY;
    for i in 0..poly.len() {
        let a = poly[i];
        let b = poly[(i + 1) % poly.len()];
        let e = sub(b, a);
        let den = cross(d, e);
        if den.abs() < 1e-12 {
            continue;
        }
        // origin + t·d = a + u·e
        let t = cross(a, e) / den;
        let u = cross(a, d) / den;
        if t > 0.0 && (-1e-6..=1.0 + 1e-6).contains(&u) {
            best = best.min(t);
        }
    }
    best
}

fn seg_intersection(p: V2, q: V2, a: V2, b: V2) -> Option<V2> {
    let r = sub(q, p);
    let s = sub(b, a);
    let den = cross(r, s);
    if den.abs() < 1e-12 {
        return None;
    }
    let t = cross(sub(a, p), s) / den;
    let u = cross(sub(a, p), r) / den;
    ((0.0..=1.0).contains(&t) && (0.0..=1.0).contains(&u)).then(|| [p[0] + t * r[0], p[1] + t * r[1]])
}

/// The lens outline of `view` in the tangent plane.
pub fn outline_tangent(hmd: &HmdProfile, view: usize, scale: f32) -> Vec<V2> {
    hmd.lens_outline_tangent(view, scale, 64)
}

pub fn fov_rect(hmd: &HmdProfile, view: usize) -> [V2; 4] {
    let [l, r, u, d] = hmd.fov_rad(view);
    let (l, r, u, d) = (l.tan(), r.tan(), u.tan(), d.tan());
    [[l, d], [r, d], [r, u], [l, u]]
}

/// Visible polygon (outline ∩ rectangle) and rectangle boundary points on shared directions.
fn sectors(outline: &[V2], rect: &[V2; 4]) -> (Vec<V2>, Vec<V2>) {
    let mut angles: Vec<f32> = outline.iter().chain(rect.iter()).map(|p| p[1].atan2(p[0])).collect();
    for i in 0..outline.len() {
        for j in 0..4 {
            if let Some(x) = seg_intersection(outline[i], outline[(i + 1) % outline.len()], rect[j], rect[(j + 1) % 4]) {
                angles.push(x[1].atan2(x[0]));
            }
        }
    }
    angles.sort_by(f32::total_cmp);
    angles.dedup_by(|a, b| (*a - *b).abs() < 1e-6);
    let mut inner = Vec::new();
    let mut outer = Vec::new();
    for a in angles {
        let d = [a.cos(), a.sin()];
        let tr = ray_exit(rect, d);
        let tl = ray_exit(outline, d).min(tr);
        inner.push([d[0] * tl, d[1] * tl]);
        outer.push([d[0] * tr, d[1] * tr]);
    }
    (inner, outer)
}

pub fn tri_area(a: V2, b: V2, c: V2) -> f32 {
    cross(sub(b, a), sub(c, a)) / 2.0
}

/// All three mask types for one view.
pub fn build(hmd: &HmdProfile, view: usize, scale: f32) -> (Mesh, Mesh, Mesh) {
    let rect = fov_rect(hmd, view);
    let (inner, outer) = sectors(&outline_tangent(hmd, view, scale), &rect);
    let n = inner.len();
    // Visible: fan from the view axis over the clipped outline.
    let mut vis = Mesh { vertices: vec![[0.0, 0.0]], indices: Vec::new() };
    vis.vertices.extend(&inner);
    for i in 0..n {
        let (a, b) = (1 + i as u32, 1 + ((i + 1) % n) as u32);
        if tri_area([0.0, 0.0], inner[i], inner[(i + 1) % n]) > 1e-9 {
            vis.indices.extend([0, a, b]);
        }
    }
    // Hidden: per sector, the quad between the outline and the rectangle (inner i, outer i,
    // outer i+1, inner i+1), split along whichever diagonal keeps both triangles CCW.
    let mut hid = Mesh { vertices: Vec::new(), indices: Vec::new() };
    for i in 0..n {
        let j = (i + 1) % n;
        let (a, b, c, d) = (inner[i], outer[i], outer[j], inner[j]);
        let base = hid.vertices.len() as u32;
        hid.vertices.extend([a, b, c, d]);
        let tris: [[usize; 3]; 2] =
            if tri_area(a, b, c) >= -1e-9 && tri_area(a, c, d) >= -1e-9 { [[0, 1, 2], [0, 2, 3]] } else { [[0, 1, 3], [1, 2, 3]] };
        let pts = [a, b, c, d];
        for t in tris {
            if tri_area(pts[t[0]], pts[t[1]], pts[t[2]]) > 1e-9 {
                hid.indices.extend(t.map(|k| base + k as u32));
            }
        }
    }
    let line = Mesh { vertices: inner.clone(), indices: (0..n as u32).collect() };
    (hid, vis, line)
}

pub fn mesh_area(m: &Mesh) -> f32 {
    m.indices.chunks(3).map(|t| tri_area(m.vertices[t[0] as usize], m.vertices[t[1] as usize], m.vertices[t[2] as usize])).sum()
}

/// The HIDDEN_TRIANGLE_MESH of `view` expanded to 3 points per triangle (in index order, so each
/// triple is CCW), as the mock runtime's frames.json lists it and the layer expands it.
pub fn hidden_triangle_points(hmd: &HmdProfile, view: usize, scale: f32) -> Vec<V2> {
    let (hid, _, _) = build(hmd, view, scale);
    hid.indices.iter().map(|&i| hid.vertices[i as usize]).collect()
}
