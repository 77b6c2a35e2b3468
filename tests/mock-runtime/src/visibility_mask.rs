//! XR_KHR_visibility_mask: hidden / visible triangle meshes and the line loop of each view,
//! built from the profile's lens outline (a published line loop, or an approximating ellipse:
//! hmd.rs), so a layer that trims rendering by the mask can be
//! checked against geometry with a known area. The geometry itself is `hmd_profiles::mask`
//! (shared with `stereoshim preview`); this module serves it through the API.
//!
//! Geometry lives in the view's z = −1 tangent plane (x = tan of the horizontal angle, y = tan
//! of the vertical angle, y up). The lens outline is star-shaped around the view axis (0, 0), so
//! both meshes are built as fans of angular sectors around it: between two consecutive sector
//! directions the outline and the FOV rectangle are each one straight segment, hence
//! visible ∪ hidden is exactly the rectangle and their areas sum to its area.

use openxr_sys as xr;

use crate::session;
use crate::system::check_view_config;
use crate::util::{guard, output, two_call_inner, XrResult};

pub use hmd_profiles::mask::*;
#[cfg(test)]
use crate::hmd::HmdProfile;

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
        let (hid, vis, line) = if s.instance.cfg.generic_mask {
            generic(s.instance.cfg.hmd.fov_rad(view_index as usize))
        } else {
            build(s.instance.cfg.hmd, view_index as usize, current_scale(&s))
        };
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

/// Monado's generic masks (`u_visibility_mask_get_default`) for a view of FOV angles (left,
/// right, up, down in radians): hidden (the four corner triangles), visible (the octagon as a
/// fan) and line loop, in coordinates normalised to the FOV rectangle, then mapped onto it.
pub fn generic(fov: [f32; 4]) -> (Mesh, Mesh, Mesh) {
    let [l, r, u, d] = fov.map(f32::tan);
    let map = |p: &[f32; 2]| [l + (p[0] + 1.0) / 2.0 * (r - l), d + (p[1] + 1.0) / 2.0 * (u - d)];
    let mesh = |v: &[[f32; 2]], i: &[u32]| Mesh { vertices: v.iter().map(map).collect(), indices: i.to_vec() };
    let hidden = [
        [1.0, 0.75], [1.0, 1.0], [0.75, 1.0], [-1.0, 1.0], [-1.0, 0.75], [-0.75, 1.0],
        [-1.0, -0.75], [-1.0, -1.0], [-0.75, -1.0], [0.75, -1.0], [1.0, -1.0], [1.0, -0.75],
    ];
    let visible = [[1.0, -0.75], [0.75, -1.0], [-0.75, -1.0], [-1.0, -0.75], [-1.0, 0.75], [-0.75, 1.0], [0.75, 1.0], [1.0, 0.75], [0.0, 0.0]];
    let visible_indices = [8, 2, 1, 3, 2, 8, 8, 1, 0, 6, 8, 7, 4, 8, 5, 8, 0, 7, 5, 8, 6, 4, 3, 8];
    let line = [[-0.75, -1.0], [0.75, -1.0], [1.0, -0.75], [1.0, 0.75], [0.75, 1.0], [-0.75, 1.0], [-1.0, 0.75], [-1.0, -0.75]];
    (mesh(&hidden, &(0..12).collect::<Vec<_>>()), mesh(&visible, &visible_indices), mesh(&line, &(0..8).collect::<Vec<_>>()))
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
