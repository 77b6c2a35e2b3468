//! The procedural test scene: built once on the CPU, deterministic, so captured frames can be judged
//! by position (red cube straight ahead, sky above, ground below). Pure and unit-tested.

use glam::Vec3;
use std::f32::consts::TAU;

/// Lambert-lit with the sun.
pub const FLAG_LIT: u32 = 1;
/// Transformed by the per-frame cube matrix (`--animate`).
pub const FLAG_ANIMATED: u32 = 2;
/// Colour replaced by a 1 m world-space checker.
pub const FLAG_CHECKER: u32 = 4;
/// Blended towards the haze colour with distance.
pub const FLAG_FOG: u32 = 8;
/// Transformed by the per-frame far-mover matrix (`--far-movers`).
pub const FLAG_MOVER: u32 = 16;
/// `--draw-hidden-area`: a vertex of a view's hidden-area mesh, as an app that draws the runtime's
/// mask itself has it: `pos` is the point in the view's tangent plane (x, y) and the view (z),
/// `normal.x` the near depth; the vertex shader places it, and clips it away in the other view.
pub const FLAG_HIDDEN_AREA: u32 = 32;

pub const CUBE_CENTRE: Vec3 = Vec3::new(0.0, 1.45, -1.5);
pub const CUBE_SIZE: f32 = 0.4;
pub const CUBE_COLOR: [f32; 3] = [0.85, 0.1, 0.1];
pub const SKY_RADIUS: f32 = 1500.0;
pub const GROUND_RADIUS: f32 = 1400.0;

/// `--translucent`: an unlit pane 2.5 m ahead, left of the red cube (never behind it), spanning
/// the horizon so that it lies over the far field (buildings, mountains, sky) and a little ground.
pub const PANE_MIN: Vec3 = Vec3::new(-1.4, 1.25, -2.5);
pub const PANE_MAX: Vec3 = Vec3::new(-0.55, 1.95, -2.5);
pub const PANE_COLOR: [f32; 3] = [0.1, 0.85, 0.55];
/// The pane's opacity: blend constant alpha of the translucent pipeline (the vertex format has
/// no alpha).
pub const PANE_ALPHA: f32 = 0.5;
/// `--far-movers`: a box ahead and above the horizon at frame 0, orbiting the stage's +y axis.
pub const MOVER_CENTRE: Vec3 = Vec3::new(0.0, 40.0, -250.0);
pub const MOVER_SIZE: f32 = 20.0;
pub const MOVER_COLOR: [f32; 3] = [0.95, 0.6, 0.1];
/// Radians per frame of the mover's orbit (2.5 m per frame at 250 m: about 0.6 degrees).
pub const MOVER_RAD_PER_FRAME: f32 = 0.01;

/// Which optional parts the scene has (the `--sky`, `--translucent` and `--far-movers` options).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Parts {
    pub sky: bool,
    pub translucent: bool,
    pub far_mover: bool,
}

impl Default for Parts {
    /// The scene every existing test captures: sky dome, no pane, no mover.
    fn default() -> Self {
        Parts { sky: true, translucent: false, far_mover: false }
    }
}

/// The mesh and its index ranges, in draw order of the default scene: `opaque` (everything but
/// the sky), then `sky`, then `translucent`. Opaque and sky are adjacent so that the scene can
/// still be drawn in one draw with the sky last, as before these options existed.
#[derive(Debug)]
pub struct Scene {
    pub mesh: Mesh,
    /// Indices `0..opaque`.
    pub opaque: u32,
    /// Indices `opaque..opaque + sky` (0 without sky geometry).
    pub sky: u32,
    /// Indices `opaque + sky..opaque + sky + translucent` (0 without `--translucent`).
    pub translucent: u32,
    /// `--draw-hidden-area`: the last `hidden_area` indices (after the translucent range, so the
    /// other ranges stay where they are), both views' hidden-area triangles.
    pub hidden_area: u32,
}

/// One view's hidden-area mesh as `xrGetVisibilityMaskKHR` gives it: points in the view's
/// tangent plane and triangles indexing them.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct HiddenAreaMesh {
    pub vertices: Vec<[f32; 2]>,
    pub indices: Vec<u32>,
}

/// The far mover's model matrix at `frame`: deterministic in the frame number, not in time.
pub fn mover_model(frame: u64) -> glam::Mat4 {
    glam::Mat4::from_rotation_y((frame % 100_000) as f32 * MOVER_RAD_PER_FRAME)
}

/// Matches the vertex input layout of the scene pipeline (40 bytes).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Vertex {
    pub pos: [f32; 3],
    pub normal: [f32; 3],
    pub color: [f32; 3],
    pub flags: u32,
}

#[derive(Debug, Default)]
pub struct Mesh {
    pub vertices: Vec<Vertex>,
    pub indices: Vec<u32>,
}

impl Mesh {
    fn vertex(&mut self, pos: Vec3, normal: Vec3, color: [f32; 3], flags: u32) -> u32 {
        let i = self.vertices.len() as u32;
        self.vertices.push(Vertex { pos: pos.into(), normal: normal.into(), color, flags });
        i
    }

    /// A flat-shaded quad `a b c d` (counter-clockwise seen from outside).
    fn quad(&mut self, a: Vec3, b: Vec3, c: Vec3, d: Vec3, color: [f32; 3], flags: u32) {
        let n = (b - a).cross(d - a).normalize_or_zero();
        let i = [a, b, c, d].map(|p| self.vertex(p, n, color, flags));
        self.indices.extend_from_slice(&[i[0], i[1], i[2], i[0], i[2], i[3]]);
    }

    fn tri(&mut self, a: Vec3, b: Vec3, c: Vec3, color: [f32; 3], flags: u32) {
        let n = (b - a).cross(c - a).normalize_or_zero();
        let i = [a, b, c].map(|p| self.vertex(p, n, color, flags));
        self.indices.extend_from_slice(&i);
    }

    /// Axis-aligned box given its centre and full size.
    pub fn add_box(&mut self, centre: Vec3, size: Vec3, color: [f32; 3], flags: u32) {
        let h = size * 0.5;
        let p = |x: f32, y: f32, z: f32| centre + Vec3::new(x * h.x, y * h.y, z * h.z);
        // +Z, −Z, +X, −X, +Y, −Y
        self.quad(p(-1., -1., 1.), p(1., -1., 1.), p(1., 1., 1.), p(-1., 1., 1.), color, flags);
        self.quad(p(1., -1., -1.), p(-1., -1., -1.), p(-1., 1., -1.), p(1., 1., -1.), color, flags);
        self.quad(p(1., -1., 1.), p(1., -1., -1.), p(1., 1., -1.), p(1., 1., 1.), color, flags);
        self.quad(p(-1., -1., -1.), p(-1., -1., 1.), p(-1., 1., 1.), p(-1., 1., -1.), color, flags);
        self.quad(p(-1., 1., 1.), p(1., 1., 1.), p(1., 1., -1.), p(-1., 1., -1.), color, flags);
        self.quad(p(-1., -1., -1.), p(1., -1., -1.), p(1., -1., 1.), p(-1., -1., 1.), color, flags);
    }

    /// An n-sided pyramid standing on `base` (its side faces only: the base is never seen).
    pub fn add_pyramid(&mut self, base: Vec3, radius: f32, height: f32, sides: u32, color: [f32; 3], flags: u32) {
        let apex = base + Vec3::Y * height;
        for s in 0..sides {
            let a0 = s as f32 / sides as f32 * TAU;
            let a1 = (s + 1) as f32 / sides as f32 * TAU;
            let p0 = base + Vec3::new(a0.cos(), 0.0, a0.sin()) * radius;
            let p1 = base + Vec3::new(a1.cos(), 0.0, a1.sin()) * radius;
            self.tri(p0, apex, p1, color, flags);
        }
    }

    /// The sky: a full sphere around the stage origin, coloured by elevation. The lower half is
    /// a blue-grey haze so that nothing below the ground's far edge is left black.
    fn add_sky(&mut self, radius: f32, rings: u32, segments: u32) {
        let color_at = |dir: Vec3| -> [f32; 3] {
            let horizon = Vec3::new(0.55, 0.70, 0.95);
            let zenith = Vec3::new(0.12, 0.30, 0.80);
            let below = Vec3::new(0.30, 0.36, 0.45);
            if dir.y >= 0.0 {
                horizon.lerp(zenith, dir.y.sqrt()).into()
            } else {
                horizon.lerp(below, (-dir.y * 8.0).min(1.0)).into()
            }
        };
        let base = self.vertices.len() as u32;
        for r in 0..=rings {
            let theta = r as f32 / rings as f32 * std::f32::consts::PI; // 0 = zenith
            for s in 0..=segments {
                let phi = s as f32 / segments as f32 * TAU;
                let dir = Vec3::new(theta.sin() * phi.cos(), theta.cos(), theta.sin() * phi.sin());
                self.vertex(dir * radius, -dir, color_at(dir), 0);
            }
        }
        let row = segments + 1;
        for r in 0..rings {
            for s in 0..segments {
                let a = base + r * row + s;
                let b = a + row;
                self.indices.extend_from_slice(&[a, b, a + 1, a + 1, b, b + 1]);
            }
        }
    }
}

/// Builds the default scene (see [`build_parts`]); the renderer calls `build_parts` itself.
#[cfg(test)]
pub fn build() -> Mesh {
    build_parts(Parts::default(), &[], 0.0).mesh
}

/// Builds the whole scene. Nearest objects come first in the index buffer so that the depth test
/// rejects most of what is behind them (primitives rasterize in order within the single draw).
/// The optional parts go where they leave the default scene's buffers unchanged: the far mover
/// at the end of the opaque range, the pane after the sky.
pub fn build_parts(parts: Parts, hidden_area: &[HiddenAreaMesh], near_depth: f32) -> Scene {
    let mut m = Mesh::default();
    let lit_fog = FLAG_LIT | FLAG_FOG;

    // The red near cube, straight ahead and slightly below eye height.
    m.add_box(CUBE_CENTRE, Vec3::splat(CUBE_SIZE), CUBE_COLOR, FLAG_LIT | FLAG_ANIMATED);

    // Mid-range objects (4–20 m), none of them red.
    m.add_box(Vec3::new(-3.0, 0.5, -5.0), Vec3::splat(1.0), [0.15, 0.3, 0.85], lit_fog);
    m.add_box(Vec3::new(3.5, 1.25, -7.0), Vec3::new(0.6, 2.5, 0.6), [0.9, 0.8, 0.2], lit_fog);
    m.add_pyramid(Vec3::new(-7.0, 0.0, -11.0), 1.5, 3.0, 4, [0.55, 0.3, 0.7], lit_fog);
    m.add_box(Vec3::new(6.0, 1.0, -15.0), Vec3::splat(2.0), [0.2, 0.7, 0.7], lit_fog);
    m.add_box(Vec3::new(-10.0, 1.5, -16.0), Vec3::new(1.5, 3.0, 1.5), [0.75, 0.75, 0.78], lit_fog);
    m.add_box(Vec3::new(5.0, 0.5, 8.0), Vec3::new(1.0, 1.0, 2.0), [0.5, 0.4, 0.25], lit_fog);

    // Buildings, 150–400 m away, mostly ahead.
    for i in 0..10u32 {
        let angle = -2.4 + i as f32 * 0.43; // radians around the stage, 0 = +X
        let dist = 150.0 + (i * 37 % 250) as f32;
        let height = 20.0 + (i * 23 % 60) as f32;
        let width = 12.0 + (i * 7 % 15) as f32;
        let c = Vec3::new(angle.cos() * dist, height * 0.5, angle.sin() * dist);
        let shade = 0.55 + (i % 3) as f32 * 0.1;
        m.add_box(c, Vec3::new(width, height, width), [shade * 0.8, shade * 0.8, shade * 0.75], lit_fog);
    }

    // Mountains, 300–900 m away, all around; their bases sink below the ground to hide seams.
    for i in 0..12u32 {
        let angle = i as f32 / 12.0 * TAU + 0.2;
        let dist = 300.0 + (i * 211 % 600) as f32;
        let height = 60.0 + (i * 53 % 130) as f32;
        let base = Vec3::new(angle.cos() * dist, -5.0, angle.sin() * dist);
        m.add_pyramid(base, height * 1.6, height + 5.0, 7, [0.40, 0.34, 0.27], lit_fog);
    }

    // The ground: a checkered disc reaching almost to the sky sphere (corners of a square would
    // poke through it).
    let centre = m.vertex(Vec3::ZERO, Vec3::Y, [0.3, 0.5, 0.3], FLAG_LIT | FLAG_FOG | FLAG_CHECKER);
    let segments = 64u32;
    for s in 0..=segments {
        let a = s as f32 / segments as f32 * TAU;
        let p = Vec3::new(a.cos(), 0.0, a.sin()) * GROUND_RADIUS;
        m.vertex(p, Vec3::Y, [0.3, 0.5, 0.3], FLAG_LIT | FLAG_FOG | FLAG_CHECKER);
    }
    for s in 0..segments {
        m.indices.extend_from_slice(&[centre, centre + 1 + s, centre + 2 + s]);
    }

    if parts.far_mover {
        m.add_box(MOVER_CENTRE, Vec3::splat(MOVER_SIZE), MOVER_COLOR, FLAG_LIT | FLAG_MOVER);
    }
    let opaque = m.indices.len() as u32;
    if parts.sky {
        m.add_sky(SKY_RADIUS, 24, 48);
    }
    let sky = m.indices.len() as u32 - opaque;
    if parts.translucent {
        let (a, b) = (PANE_MIN, PANE_MAX);
        m.quad(Vec3::new(a.x, a.y, a.z), Vec3::new(b.x, a.y, a.z), Vec3::new(b.x, b.y, a.z), Vec3::new(a.x, b.y, a.z), PANE_COLOR, 0);
    }
    let translucent = m.indices.len() as u32 - opaque - sky;
    for (view, mesh) in hidden_area.iter().enumerate() {
        let first = m.vertices.len() as u32;
        for p in &mesh.vertices {
            m.vertices.push(Vertex { pos: [p[0], p[1], view as f32], normal: [near_depth, 0.0, 0.0], color: [0.0; 3], flags: FLAG_HIDDEN_AREA });
        }
        m.indices.extend(mesh.indices.iter().map(|i| first + i));
    }
    let hidden_area = m.indices.len() as u32 - opaque - sky - translucent;
    Scene { mesh: m, opaque, sky, translucent, hidden_area }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn indices_are_valid_triangles() {
        let m = build();
        assert_eq!(m.indices.len() % 3, 0);
        assert!(m.indices.iter().all(|&i| (i as usize) < m.vertices.len()));
        assert_eq!(std::mem::size_of::<Vertex>(), 40);
    }

    #[test]
    fn deterministic() {
        let (a, b) = (build(), build());
        assert_eq!(a.vertices, b.vertices);
        assert_eq!(a.indices, b.indices);
    }

    #[test]
    fn red_cube_is_first_and_in_place() {
        let m = build();
        let cube: Vec<_> = m.vertices.iter().filter(|v| v.flags & FLAG_ANIMATED != 0).collect();
        assert_eq!(cube.len(), 24);
        for v in &cube {
            assert_eq!(v.color, CUBE_COLOR);
            let d = Vec3::from(v.pos) - CUBE_CENTRE;
            assert!((d.abs().max_element() - CUBE_SIZE / 2.0).abs() < 1e-6);
        }
        assert_eq!(m.vertices[m.indices[0] as usize].flags & FLAG_ANIMATED, FLAG_ANIMATED);
    }

    #[test]
    fn nothing_else_is_red() {
        for v in build().vertices.iter().filter(|v| v.flags & FLAG_ANIMATED == 0) {
            let [r, g, b] = v.color;
            assert!(!(r > 0.5 && r > 2.0 * g && r > 2.0 * b), "reddish vertex {v:?}");
        }
    }

    #[test]
    fn everything_inside_far_plane() {
        let eye = Vec3::new(0.0, 1.6, 0.0);
        for v in build().vertices {
            assert!((Vec3::from(v.pos) - eye).length() < crate::camera::FAR * 0.9);
        }
    }

    #[test]
    fn parts_leave_the_default_scene_alone() {
        let d = build();
        let s = build_parts(Parts::default(), &[], 0.0);
        assert_eq!((s.mesh.vertices.clone(), s.mesh.indices.clone()), (d.vertices.clone(), d.indices.clone()));
        assert_eq!(s.opaque + s.sky, d.indices.len() as u32);
        assert_eq!(s.translucent, 0);
        // The sky is the last part of the default draw and nothing else has flags 0 there.
        assert!(s.mesh.indices[s.opaque as usize..].iter().all(|&i| s.mesh.vertices[i as usize].flags == 0));

        let all = build_parts(Parts { sky: true, translucent: true, far_mover: true }, &[], 0.0);
        assert_eq!(all.translucent, 6);
        assert_eq!(all.sky, s.sky);
        assert_eq!(all.opaque, s.opaque + 36, "the mover is one box at the end of the opaque range");
        // Everything of the default scene keeps its index position.
        assert_eq!(&all.mesh.indices[..s.opaque as usize], &s.mesh.indices[..s.opaque as usize]);
        let movers = all.mesh.vertices.iter().filter(|v| v.flags & FLAG_MOVER != 0).count();
        assert_eq!(movers, 24);

        let clear = build_parts(Parts { sky: false, ..Parts::default() }, &[], 0.0);
        assert_eq!((clear.opaque, clear.sky), (s.opaque, 0));
        assert!(clear.mesh.vertices.iter().all(|v| v.flags != 0), "no sky vertices left");
    }

    #[test]
    fn pane_is_near_left_of_the_cube_and_mover_is_far() {
        const { assert!(PANE_MAX.x < CUBE_CENTRE.x - CUBE_SIZE, "left of the cube") };
        const { assert!(PANE_MIN.y < 1.6 && PANE_MAX.y > 1.6, "spans eye height, so the horizon") };
        for f in [0u64, 1, 57, 1000] {
            let c = mover_model(f).transform_point3(MOVER_CENTRE);
            assert!((c.length() - MOVER_CENTRE.length()).abs() < 1e-2, "orbits the stage's y axis");
            assert_eq!(c, mover_model(f).transform_point3(MOVER_CENTRE), "deterministic");
        }
        assert_ne!(mover_model(0).transform_point3(MOVER_CENTRE), mover_model(1).transform_point3(MOVER_CENTRE));
    }

    #[test]
    fn sky_is_blue_dominant_above_the_horizon() {
        let m = build();
        for v in m.vertices.iter().filter(|v| v.flags == 0 && v.pos[1] >= 0.0) {
            let [r, g, b] = v.color;
            assert!(b > r && b > g, "{v:?}");
        }
    }
}
