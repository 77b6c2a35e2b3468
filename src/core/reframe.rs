//! A runtime view's hidden triangles reframed into the view the app renders (pure): the view
//! tricks (docs/views.md) hand the app other angles than the runtime's (symmetric views), or
//! another orientation (parallel views), and what the app's image shows outside the runtime's
//! FOV is never displayed, so it is hidden too. Used by the mask (what it draws), the upscale
//! (which tiles it skips), the view tricks and the tests: base, so no feature imports another.
#![forbid(unsafe_code)]

use crate::core::views::ViewFov;
use glam::{DQuat, DVec2, DVec3};

/// A piece of padding thinner than this (tangent units, about 1/100 pixel at any real density) is
/// a rounding sliver where the two FOVs share an edge, not padding.
const SLIVER: f64 = 1e-5;

/// The runtime view's hidden `triangles` (its tangent plane, three points each; its FOV `runtime`)
/// as the app's view sees them (FOV `app`; `turn`: the runtime view's orientation in the app
/// view's frame, x y z w, None when they look the same way), with the part of the app's FOV that
/// lies outside the runtime's added as triangles. A triangle with a point behind the app's view
/// is dropped (it would hide less, never more); so is the padding when a corner of the runtime's
/// FOV is behind it.
pub fn in_app_view(triangles: &[[f32; 2]], runtime: &ViewFov, turn: Option<[f32; 4]>, app: &ViewFov) -> Vec<[f32; 2]> {
    let q = turn.map(|[x, y, z, w]| DQuat::from_xyzw(x as f64, y as f64, z as f64, w as f64).normalize()).filter(|q| q.is_finite());
    let map = |p: [f64; 2]| -> Option<DVec2> {
        let Some(q) = q else { return Some(DVec2::new(p[0], p[1])) };
        let d = q * DVec3::new(p[0], p[1], -1.0);
        (d.z < -1e-6).then(|| DVec2::new(d.x / -d.z, d.y / -d.z))
    };
    let mut out: Vec<[f32; 2]> = Vec::with_capacity(triangles.len() + 24);
    for t in triangles.chunks_exact(3) {
        let m: Option<Vec<DVec2>> = t.iter().map(|p| map([p[0] as f64, p[1] as f64])).collect();
        if let Some(m) = m {
            out.extend(m.iter().map(|p| [p.x as f32, p.y as f32]));
        }
    }
    let rect = |f: &ViewFov| [[f.tan_left, f.tan_down], [f.tan_right, f.tan_down], [f.tan_right, f.tan_up], [f.tan_left, f.tan_up]].map(|p| [p[0] as f64, p[1] as f64]);
    let Some(quad) = rect(runtime).into_iter().map(map).collect::<Option<Vec<DVec2>>>() else { return out };
    let app_rect: Vec<DVec2> = rect(app).into_iter().map(|p| DVec2::new(p[0], p[1])).collect();
    for piece in outside(&app_rect, &quad) {
        for i in 1..piece.len() - 1 {
            out.extend([piece[0], piece[i], piece[i + 1]].map(|p| [p.x as f32, p.y as f32]));
        }
    }
    out
}

/// Points of the runtime view's tangent plane as the app's view, turned by `turn` from it, sees
/// them, in groups of `group` (3: triangles; the whole list: a line loop); a group with a point
/// behind the app's view is dropped.
pub fn turned(points: &[[f32; 2]], turn: [f32; 4], group: usize) -> Vec<[f32; 2]> {
    let [x, y, z, w] = turn;
    let q = DQuat::from_xyzw(x as f64, y as f64, z as f64, w as f64).normalize();
    let map = |p: &[f32; 2]| {
        let d = q * DVec3::new(p[0] as f64, p[1] as f64, -1.0);
        (d.z < -1e-6).then(|| [(d.x / -d.z) as f32, (d.y / -d.z) as f32])
    };
    points.chunks(group.max(1)).filter_map(|g| g.iter().map(map).collect::<Option<Vec<_>>>()).flatten().collect()
}

/// Twice the signed area of a polygon (counter-clockwise positive).
fn area2(poly: &[DVec2]) -> f64 {
    (0..poly.len()).map(|i| poly[i].perp_dot(poly[(i + 1) % poly.len()])).sum()
}

/// The part of a convex polygon on the inner (left, `inner`) or outer side of the line a→b
/// (Sutherland–Hodgman against one half-plane).
fn clip(poly: &[DVec2], a: DVec2, b: DVec2, inner: bool) -> Vec<DVec2> {
    let side = |p: DVec2| {
        let s = (b - a).perp_dot(p - a);
        if inner { s } else { -s }
    };
    let mut out = Vec::with_capacity(poly.len() + 1);
    for i in 0..poly.len() {
        let (p, q) = (poly[i], poly[(i + 1) % poly.len()]);
        let (sp, sq) = (side(p), side(q));
        if sp >= 0.0 {
            out.push(p);
        }
        if (sp >= 0.0) != (sq >= 0.0) {
            out.push(p + (q - p) * (sp / (sp - sq)));
        }
    }
    out
}

/// `region` (convex) minus the convex polygon `hole`, as disjoint convex pieces: the piece outside
/// the hole's first edge, then what is inside it and outside the second, and so on. Slivers of a
/// shared edge are left out.
fn outside(region: &[DVec2], hole: &[DVec2]) -> Vec<Vec<DVec2>> {
    let mut hole = hole.to_vec();
    if area2(&hole) < 0.0 {
        hole.reverse();
    }
    let mut rest = region.to_vec();
    let mut pieces = Vec::new();
    for i in 0..hole.len() {
        if rest.len() < 3 {
            break;
        }
        let (a, b) = (hole[i], hole[(i + 1) % hole.len()]);
        let piece = clip(&rest, a, b, false);
        if piece.len() >= 3 {
            let perimeter: f64 = (0..piece.len()).map(|k| (piece[(k + 1) % piece.len()] - piece[k]).length()).sum();
            if area2(&piece).abs() / perimeter.max(f64::MIN_POSITIVE) > SLIVER {
                pieces.push(piece);
            }
        }
        rest = clip(&rest, a, b, true);
    }
    pieces
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::lens::hidden_pixels;
    use proptest::prelude::*;

    fn fov(l: f32, r: f32, u: f32, d: f32) -> ViewFov {
        ViewFov { tan_left: l, tan_right: r, tan_up: u, tan_down: d }
    }

    #[test]
    fn turned_points_keep_their_directions() {
        let turn = DQuat::from_rotation_y(10f64.to_radians());
        let t = [turn.x as f32, turn.y as f32, turn.z as f32, turn.w as f32];
        let out = turned(&[[0.0, 0.0], [0.5, 0.2], [-0.3, 0.1]], t, 3);
        // The runtime's axis seen 10° to the left in the app's view.
        assert!((out[0][0] as f64 + 10f64.to_radians().tan()).abs() < 1e-6 && out[0][1].abs() < 1e-6);
        for (p, q) in [[0.5f64, 0.2], [-0.3, 0.1]].iter().zip(&out[1..]) {
            let d = turn * DVec3::new(p[0], p[1], -1.0);
            assert!((q[0] as f64 - d.x / -d.z).abs() < 1e-6 && (q[1] as f64 - d.y / -d.z).abs() < 1e-6);
        }
        // A point that turns behind the view drops its triangle.
        let far = DQuat::from_rotation_y(80f64.to_radians());
        assert!(turned(&[[0.0, 0.0], [-9.0, 0.0], [0.0, 1.0]], [far.x as f32, far.y as f32, far.z as f32, far.w as f32], 3).is_empty());
    }

    #[test]
    fn a_view_inside_the_runtimes_gets_its_triangles_unchanged() {
        let tris = [[-1.0, -1.0], [0.0, -1.0], [-1.0, 0.0]];
        let runtime = fov(-1.2, 1.0, 1.1, -1.1);
        assert_eq!(in_app_view(&tris, &runtime, None, &runtime), tris.to_vec());
        // The cut: inside, one edge shared.
        assert_eq!(in_app_view(&tris, &runtime, None, &fov(-1.0, 1.0, 1.0, -1.1)), tris.to_vec());
    }

    /// Symmetric padding: the band above the runtime's FOV is hidden, pixel for pixel.
    #[test]
    fn the_padding_of_a_wider_view_is_hidden() {
        let (runtime, app) = (fov(-1.2, 1.0, 1.0, -1.1), fov(-1.2, 1.2, 1.2, -1.1));
        let (w, h) = (240, 230);
        let bits = hidden_pixels(&in_app_view(&[], &runtime, None, &app), &app, (w, h)).unwrap();
        for y in 0..h {
            for x in 0..w {
                let (tx, ty) = (-1.2 + (x as f64 + 0.5) * 2.4 / w as f64, 1.2 - (y as f64 + 0.5) * 2.3 / h as f64);
                let outside = tx > 1.0 || ty > 1.0;
                assert_eq!(bits[(y * w + x) as usize], outside, "({x}, {y}) at ({tx}, {ty})");
            }
        }
    }

    proptest! {
        /// A turned runtime view (a canted display): every pixel of the app's view whose direction
        /// is outside the runtime's FOV is hidden, none inside it is (but for pixels within a
        /// hundredth of a pixel of its edge).
        #[test]
        fn a_turned_views_outside_is_hidden(yaw in -15.0f64..15.0, pitch in -5.0f64..5.0, l in 0.8f32..1.5, r in 0.8f32..1.5, u in 0.8f32..1.4, d in 0.8f32..1.4) {
            let runtime = fov(-l, r, u, -d);
            let turn = DQuat::from_rotation_y(yaw.to_radians()) * DQuat::from_rotation_x(pitch.to_radians());
            let app = fov(-1.8, 1.8, 1.7, -1.7);
            let (w, h) = (90, 85);
            let t = [turn.x as f32, turn.y as f32, turn.z as f32, turn.w as f32];
            let bits = hidden_pixels(&in_app_view(&[], &runtime, Some(t), &app), &app, (w, h)).unwrap();
            let back = turn.inverse();
            for y in 0..h {
                for x in 0..w {
                    let (tx, ty) = (-1.8 + (x as f64 + 0.5) * 3.6 / w as f64, 1.7 - (y as f64 + 0.5) * 3.4 / h as f64);
                    let v = back * DVec3::new(tx, ty, -1.0);
                    let (rx, ry) = (v.x / -v.z, v.y / -v.z);
                    let margin = (rx + l as f64).abs().min((rx - r as f64).abs()).min((ry - u as f64).abs()).min((ry + d as f64).abs());
                    if margin < 1e-3 {
                        continue;
                    }
                    let outside = v.z >= 0.0 || rx < -l as f64 || rx > r as f64 || ry > u as f64 || ry < -d as f64;
                    prop_assert_eq!(bits[(y * w + x) as usize], outside, "({}, {})", x, y);
                }
            }
        }
    }
}
