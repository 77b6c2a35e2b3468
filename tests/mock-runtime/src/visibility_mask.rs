//! XR_KHR_visibility_mask: hidden / visible triangle meshes and the line loop of each view,
//! built from the profile's lens outline (a published line loop, or an approximating ellipse:
//! hmd.rs), so a layer that trims rendering by the mask can be
//! checked against geometry with a known area.
//!
//! Geometry lives in the view's z = −1 tangent plane (x = tan of the horizontal angle, y = tan
//! of the vertical angle, y up). The lens outline is star-shaped around the view axis (0, 0), so
//! both meshes are built as fans of angular sectors around it: between two consecutive sector
//! directions the outline and the FOV rectangle are each one straight segment, hence
//! visible ∪ hidden is exactly the rectangle and their areas sum to its area.

use openxr_sys as xr;

use crate::hmd::HmdProfile;
use crate::session;
use crate::system::check_view_config;
use crate::util::{guard, output, two_call_inner, XrResult};

pub type V2 = [f32; 2];

/// Mask geometry of one type: vertices and indices (triangles CCW, or a line loop).
#[derive(Debug, Clone, PartialEq)]
pub struct Mesh {
    pub vertices: Vec<V2>,
    pub indices: Vec<u32>,
}

fn cross(a: V2, b: V2) -> f32 {
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

fn tri_area(a: V2, b: V2, c: V2) -> f32 {
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

/// Outline scale after MOCK_XR_VISIBILITY_MASK_CHANGE_AT.
pub const CHANGED_SCALE: f32 = 0.9;

/// Outline scale of the session's masks now (before or after MOCK_XR_VISIBILITY_MASK_CHANGE_AT).
pub fn current_scale(s: &session::Session) -> f32 {
    if s.core.lock().unwrap().mask_changed {
        CHANGED_SCALE
    } else {
        1.0
    }
}

/// The HIDDEN_TRIANGLE_MESH of `view` expanded to 3 points per triangle (in index order, so each
/// triple is CCW), as capture's frames.json lists it.
pub fn hidden_triangle_points(hmd: &HmdProfile, view: usize, scale: f32) -> Vec<V2> {
    let (hid, _, _) = build(hmd, view, scale);
    hid.indices.iter().map(|&i| hid.vertices[i as usize]).collect()
}

pub unsafe extern "system" fn xr_get_visibility_mask_khr(
    session: xr::Session,
    view_config: xr::ViewConfigurationType,
    view_index: u32,
    mask_type: xr::VisibilityMaskTypeKHR,
    mask: *mut xr::VisibilityMaskKHR,
) -> xr::Result {
    guard("xrGetVisibilityMaskKHR", || {
        let s = session::get(session)?;
        s.fail_point("xrGetVisibilityMaskKHR")?;
        check_view_config(view_config)?;
        if view_index >= 2 {
            return Err(xr::Result::ERROR_VALIDATION_FAILURE);
        }
        // SAFETY: app output struct.
        let m = unsafe { output(mask) }?;
        let (hid, vis, line) = build(s.instance.cfg.hmd, view_index as usize, current_scale(&s));
        let mesh = match mask_type {
            xr::VisibilityMaskTypeKHR::HIDDEN_TRIANGLE_MESH => hid,
            xr::VisibilityMaskTypeKHR::VISIBLE_TRIANGLE_MESH => vis,
            xr::VisibilityMaskTypeKHR::LINE_LOOP => line,
            _ => return Err(xr::Result::ERROR_VALIDATION_FAILURE),
        };
        fill(m, &mesh)?;
        Ok(xr::Result::SUCCESS)
    })
}

/// The two-call idiom applied to both arrays at once: a zero capacity on both only asks for
/// the counts; otherwise both must be large enough.
fn fill(m: &mut xr::VisibilityMaskKHR, mesh: &Mesh) -> XrResult<()> {
    m.vertex_count_output = mesh.vertices.len() as u32;
    m.index_count_output = mesh.indices.len() as u32;
    if m.vertex_capacity_input == 0 && m.index_capacity_input == 0 {
        return Ok(());
    }
    if (m.vertex_capacity_input > 0 && m.vertices.is_null()) || (m.index_capacity_input > 0 && m.indices.is_null()) {
        return Err(xr::Result::ERROR_VALIDATION_FAILURE);
    }
    if (m.vertex_capacity_input as usize) < mesh.vertices.len() || (m.index_capacity_input as usize) < mesh.indices.len() {
        return Err(xr::Result::ERROR_SIZE_INSUFFICIENT);
    }
    let (vp, ip) = (m.vertices, m.indices);
    two_call_inner(m.vertex_capacity_input, mesh.vertices.len(), |i| {
        // SAFETY: the app's array holds vertex_capacity_input >= len elements.
        unsafe { *vp.add(i) = xr::Vector2f { x: mesh.vertices[i][0], y: mesh.vertices[i][1] } };
        Ok(())
    })?;
    two_call_inner(m.index_capacity_input, mesh.indices.len(), |i| {
        // SAFETY: as above for indices.
        unsafe { *ip.add(i) = mesh.indices[i] };
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::hmd::HMD_NAMES;

    fn rect_area(r: &[V2; 4]) -> f32 {
        (r[1][0] - r[0][0]) * (r[2][1] - r[1][1])
    }

    #[test]
    fn areas_sum_to_the_fov_rectangle() {
        for name in HMD_NAMES {
            let hmd = HmdProfile::by_name(name).unwrap();
            for view in 0..2 {
                for scale in [1.0, CHANGED_SCALE] {
                    let (hid, vis, line) = build(hmd, view, scale);
                    let (h, v) = (mesh_area(&hid), mesh_area(&vis));
                    let r = rect_area(&fov_rect(hmd, view));
                    assert!(h > 0.02 * r && v > 0.5 * r, "{name} {view}: {h} {v} {r}");
                    assert!(((h + v) - r).abs() < 1e-3 * r, "{name} {view}: {h}+{v} != {r}");
                    assert_eq!(line.indices.len(), line.vertices.len());
                    // Every triangle CCW (positive area).
                    for m in [&hid, &vis] {
                        for t in m.indices.chunks(3) {
                            let a = tri_area(m.vertices[t[0] as usize], m.vertices[t[1] as usize], m.vertices[t[2] as usize]);
                            assert!(a > 0.0);
                        }
                    }
                    // Inside the rectangle.
                    let fr = fov_rect(hmd, view);
                    for p in hid.vertices.iter().chain(&vis.vertices) {
                        assert!(p[0] >= fr[0][0] - 1e-4 && p[0] <= fr[1][0] + 1e-4 && p[1] >= fr[0][1] - 1e-4 && p[1] <= fr[2][1] + 1e-4);
                    }
                }
            }
        }
    }

    #[test]
    fn expanded_points_are_the_indexed_triangles() {
        let hmd = HmdProfile::by_name("index").unwrap();
        for view in 0..2 {
            let (hid, _, _) = build(hmd, view, CHANGED_SCALE);
            let pts = hidden_triangle_points(hmd, view, CHANGED_SCALE);
            assert_eq!(pts.len(), hid.indices.len());
            assert_eq!(pts.len() % 3, 0);
            for (p, &i) in pts.iter().zip(&hid.indices) {
                assert_eq!(*p, hid.vertices[i as usize]);
            }
            assert!(pts.chunks(3).all(|t| tri_area(t[0], t[1], t[2]) > 0.0));
        }
    }

    #[test]
    fn shrinking_grows_the_hidden_area() {
        let hmd = HmdProfile::by_name("index").unwrap();
        let before = mesh_area(&build(hmd, 0, 1.0).0);
        let after = mesh_area(&build(hmd, 0, CHANGED_SCALE).0);
        assert!(after > before * 1.1);
    }

    #[test]
    fn simple_circle_hides_the_corners_exactly() {
        // 45° circle in angle space inscribed in the ±45° square: the edge midpoints touch.
        let hmd = HmdProfile::by_name("simple").unwrap();
        let (_, vis, _) = build(hmd, 0, 1.0);
        let max_x = vis.vertices.iter().map(|p| p[0]).fold(0.0f32, f32::max);
        assert!((max_x - 1.0).abs() < 1e-3);
    }

    #[test]
    fn index_masks_follow_the_published_line_loop() {
        use crate::hmd::INDEX_LINE_LOOP_LEFT;
        let hmd = HmdProfile::by_name("index").unwrap();
        for view in 0..2 {
            let rect = fov_rect(hmd, view);
            let (hid, vis, line) = build(hmd, view, 1.0);
            // Every published point inside the frustum is on the returned line loop and on the
            // visible mesh (the right eye mirrored); the ones above the top edge are clipped to it.
            for p in INDEX_LINE_LOOP_LEFT {
                let p = if view == 0 { p } else { [-p[0], p[1]] };
                let near = |m: &Mesh| m.vertices.iter().any(|v| (v[0] - p[0]).abs() < 1e-5 && (v[1] - p[1]).abs() < 1e-5);
                if p[1] <= rect[2][1] {
                    assert!(near(&line) && near(&vis), "view {view}: {p:?} not on the masks");
                } else {
                    assert!(p[1] - rect[2][1] < 0.004, "{p:?}");
                }
            }
            // The visible area is the published polygon's (shoelace), less the sliver above the
            // frustum's top edge.
            let n = INDEX_LINE_LOOP_LEFT.len();
            let poly: f32 = (0..n).map(|i| cross(INDEX_LINE_LOOP_LEFT[i], INDEX_LINE_LOOP_LEFT[(i + 1) % n]) / 2.0).sum();
            let v = mesh_area(&vis);
            assert!(v < poly && v > poly * 0.998, "view {view}: visible {v}, polygon {poly}");
            let r = rect_area(&rect);
            let hidden_fraction = mesh_area(&hid) / r;
            // SteamVR's Index mask hides a quarter of the frustum (25.0 % of the tangent plane).
            assert!((0.245..0.255).contains(&hidden_fraction), "view {view}: {hidden_fraction}");
        }
        // Mirror images.
        let (h0, _, _) = build(hmd, 0, 1.0);
        let (h1, _, _) = build(hmd, 1, 1.0);
        assert!((mesh_area(&h0) - mesh_area(&h1)).abs() < 1e-4);
    }
}
