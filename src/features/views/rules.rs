//! The view tricks' geometry, pure (docs/views.md): a view's field of view cut to the lens on
//! whole pixels of the runtime's grid, symmetric angles for apps that assume mirrored eyes, and
//! parallel views for canted displays; with the image sizes that keep the runtime's pixels per
//! unit of tangent, and what each costs or saves.
#![forbid(unsafe_code)]

use glam::{DQuat, DVec3};

/// A view's field of view as the tangents of its four angles (left < right, down < up; OpenXR's
/// `XrFovf` holds the angles).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fov {
    pub left: f64,
    pub right: f64,
    pub up: f64,
    pub down: f64,
}

impl Fov {
    /// From `XrFovf`'s angles (radians): left, right, up, down.
    pub fn from_angles([left, right, up, down]: [f32; 4]) -> Fov {
        Fov { left: (left as f64).tan(), right: (right as f64).tan(), up: (up as f64).tan(), down: (down as f64).tan() }
    }
    /// As `XrFovf`'s angles (radians): left, right, up, down.
    pub fn angles(&self) -> [f32; 4] {
        [self.left.atan() as f32, self.right.atan() as f32, self.up.atan() as f32, self.down.atan() as f32]
    }
    pub fn width(&self) -> f64 {
        self.right - self.left
    }
    pub fn height(&self) -> f64 {
        self.up - self.down
    }
    /// Both extents positive and finite: a FOV an image can show.
    pub fn is_valid(&self) -> bool {
        [self.left, self.right, self.up, self.down].iter().all(|v| v.is_finite()) && self.width() > 0.0 && self.height() > 0.0
    }
    /// The smallest FOV holding both.
    /// The angles of pixels `x0..x1` × `y0..y1` (rows from the top) of a `size` grid showing
    /// this FOV.
    pub fn pixels(&self, size: (u32, u32), (x0, x1, y0, y1): (u32, u32, u32, u32)) -> Fov {
        let (px, py) = (self.width() / size.0 as f64, self.height() / size.1 as f64);
        Fov { left: self.left + x0 as f64 * px, right: self.left + x1 as f64 * px, up: self.up - y0 as f64 * py, down: self.up - y1 as f64 * py }
    }
    pub fn union(&self, o: &Fov) -> Fov {
        Fov { left: self.left.min(o.left), right: self.right.max(o.right), up: self.up.max(o.up), down: self.down.min(o.down) }
    }
}

/// An image size for `to` with the pixels per unit of tangent a `size` image of `from` has
/// (rounded up: never fewer pixels per tangent than the runtime asked for).
pub fn size_for(size: (u32, u32), from: &Fov, to: &Fov) -> (u32, u32) {
    let scale = |n: u32, a: f64, b: f64| ((n as f64 * b / a) - 1e-9).ceil().max(1.0) as u32;
    (scale(size.0, from.width(), to.width()), scale(size.1, from.height(), to.height()))
}

/// A FOV cut to the lens: the columns `x0..x1` and rows `y0..y1` (top first) of the uncut image's
/// pixel grid, and the FOV of exactly those pixels. An app rendering the cut FOV at the cut size
/// draws the same pixels at the same tangents: its image is the crop of the uncut one.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cut {
    pub x0: u32,
    pub x1: u32,
    pub y0: u32,
    pub y1: u32,
    pub fov: Fov,
}

impl Cut {
    pub fn size(&self) -> (u32, u32) {
        (self.x1 - self.x0, self.y1 - self.y0)
    }
    /// The share of the uncut image's pixels the cut leaves out.
    pub fn saved_share(&self, uncut: (u32, u32)) -> f64 {
        let (w, h) = self.size();
        1.0 - (w as f64 * h as f64) / (uncut.0 as f64 * uncut.1 as f64).max(1.0)
    }
}

/// Where a cut starts: on a multiple of this many pixels of the uncut grid, so that what the
/// foveation lays on the image in blocks (VRS's shading-rate texels of up to 16×16 pixels, RDM's
/// pattern) falls on the same pixels with and without the cut.
pub const CUT_ALIGN: u32 = 16;

/// The cut of a `size` image showing `fov` to the bounding box of its pixels `hidden` says the
/// lens shows (row-major, top row first), widened by `margin_deg` on each side, its start moved
/// out to a multiple of `CUT_ALIGN`, and kept within the image; None when no pixel is visible or
/// the FOV is not valid.
pub fn cut(fov: &Fov, size: (u32, u32), hidden: &[bool], margin_deg: f64) -> Option<Cut> {
    let (w, h) = (size.0 as usize, size.1 as usize);
    if !fov.is_valid() || w == 0 || h == 0 || hidden.len() != w * h {
        return None;
    }
    let (mut x0, mut x1, mut y0, mut y1) = (w, 0, h, 0);
    for y in 0..h {
        let row = &hidden[y * w..(y + 1) * w];
        let (Some(first), Some(last)) = (row.iter().position(|&b| !b), row.iter().rposition(|&b| !b)) else { continue };
        x0 = x0.min(first);
        x1 = x1.max(last + 1);
        y0 = y0.min(y);
        y1 = y1.max(y + 1);
    }
    if x0 >= x1 || y0 >= y1 {
        return None;
    }
    // Tangent of pixel boundary k, and the boundary a tangent falls in (rounded outwards).
    let (px, py) = (fov.width() / w as f64, fov.height() / h as f64);
    let m = margin_deg.max(0.0).to_radians();
    let widen = |t: f64, by: f64| (t.atan() + by).clamp(-1.55, 1.55).tan();
    let x0 = ((widen(fov.left + x0 as f64 * px, -m) - fov.left) / px + 1e-9).floor().clamp(0.0, x0 as f64) as u32;
    let x1 = ((widen(fov.left + x1 as f64 * px, m) - fov.left) / px - 1e-9).ceil().clamp(x1 as f64, w as f64) as u32;
    // Rows run down from the top (up) edge.
    let y0 = ((fov.up - widen(fov.up - y0 as f64 * py, m)) / py + 1e-9).floor().clamp(0.0, y0 as f64) as u32;
    let y1 = ((fov.up - widen(fov.up - y1 as f64 * py, -m)) / py - 1e-9).ceil().clamp(y1 as f64, h as f64) as u32;
    let (x0, y0) = (x0 - x0 % CUT_ALIGN, y0 - y0 % CUT_ALIGN);
    Some(Cut { x0, x1, y0, y1, fov: fov.pixels(size, (x0, x1, y0, y1)) })
}

/// The views' cuts (each on its own `sizes` grid) made one size, the largest width and height:
/// apps render every view at one size (a multiview array, two views side by side, or view 0's
/// size for both). Each cut grows at its end, or moves its start back (to a multiple of
/// `CUT_ALIGN` where the image allows) when its end would leave the image; a view too small for
/// the common size keeps its whole image.
pub fn same_size(cuts: &mut [Cut], sizes: &[(u32, u32)]) {
    let (w, h) = cuts.iter().fold((0, 0), |(w, h), c| (w.max(c.size().0), h.max(c.size().1)));
    for (c, &(sw, sh)) in cuts.iter_mut().zip(sizes) {
        let grow = |a0: u32, full: u32, len: u32| -> (u32, u32) {
            if len >= full {
                return (0, full);
            }
            let a0 = if a0 + len <= full { a0 } else { (full - len) - (full - len) % CUT_ALIGN };
            (a0, a0 + len)
        };
        let (px, py) = (c.fov.width() / c.size().0 as f64, c.fov.height() / c.size().1 as f64);
        let ((x0, x1), (y0, y1)) = (grow(c.x0, sw, w), grow(c.y0, sh, h));
        c.fov = Fov { left: c.fov.left + (x0 as f64 - c.x0 as f64) * px, right: c.fov.left + (x1 as f64 - c.x0 as f64) * px, up: c.fov.up - (y0 as f64 - c.y0 as f64) * py, down: c.fov.up - (y1 as f64 - c.y0 as f64) * py };
        (c.x0, c.x1, c.y0, c.y1) = (x0, x1, y0, y1);
    }
}

/// Every view's cut (`cut` of its FOV, grid size and hidden pixels), made one size (`same_size`);
/// None unless every view has one: a view left whole would need its own size.
pub fn cuts(views: &[(Fov, (u32, u32), Vec<bool>)], margin_deg: f64) -> Option<Vec<Cut>> {
    let mut all: Vec<Cut> = views.iter().map(|(fov, size, hidden)| cut(fov, *size, hidden, margin_deg)).collect::<Option<_>>()?;
    let sizes: Vec<(u32, u32)> = views.iter().map(|v| v.1).collect();
    same_size(&mut all, &sizes);
    Some(all)
}

/// `view.symmetric`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Symmetric {
    Off,
    /// Both eyes the same vertical angles (their union) and mirrored horizontal angles.
    Horizontal,
    /// Each eye symmetric about its own axis, both ways.
    Full,
}

impl Symmetric {
    /// The config's name of the mode (`view.symmetric`).
    pub fn name(self) -> &'static str {
        match self {
            Symmetric::Off => "off",
            Symmetric::Horizontal => "horizontal",
            Symmetric::Full => "full",
        }
    }
}

/// The two views' FOVs (left eye, right eye) made symmetric as `mode` says; each contains the
/// eye's own.
pub fn symmetric(fovs: [Fov; 2], mode: Symmetric) -> [Fov; 2] {
    match mode {
        Symmetric::Off => fovs,
        Symmetric::Horizontal => {
            let [a, b] = fovs;
            let (up, down) = (a.up.max(b.up), a.down.min(b.down));
            // The left eye's left is the right eye's right, mirrored.
            let (left, right) = (a.left.min(-b.right), a.right.max(-b.left));
            [Fov { left, right, up, down }, Fov { left: -right, right: -left, up, down }]
        }
        Symmetric::Full => fovs.map(|f| {
            let (hx, hy) = ((-f.left).max(f.right), f.up.max(-f.down));
            Fov { left: -hx, right: hx, up: hy, down: -hy }
        }),
    }
}

/// The horizontal overlap of two parallel views (left eye, right eye), as a share of their union's
/// angle: what multiview's shared work and the far field can reuse.
pub fn overlap(fovs: &[Fov; 2]) -> f64 {
    let [a, b] = fovs;
    let (l, r) = (a.left.atan().max(b.left.atan()), a.right.atan().min(b.right.atan()));
    let union = a.right.atan().max(b.right.atan()) - a.left.atan().min(b.left.atan());
    ((r - l).max(0.0) / union).clamp(0.0, 1.0)
}

/// A view's FOV (`fov`, oriented `view` in the head's frame) as seen from orientation `to` (the
/// head's): the smallest FOV there that contains it. A projective map sends the FOV's rectangle
/// to a quadrilateral, so its corners bound it. None when a corner is not in front of `to`.
pub fn contained_fov(fov: &Fov, view: DQuat, to: DQuat) -> Option<Fov> {
    let rel = to.inverse() * view;
    let mut out: Option<Fov> = None;
    for (x, y) in [(fov.left, fov.up), (fov.right, fov.up), (fov.left, fov.down), (fov.right, fov.down)] {
        let d = rel * DVec3::new(x, y, -1.0);
        if d.z >= -1e-6 {
            return None;
        }
        let (tx, ty) = (d.x / -d.z, d.y / -d.z);
        let p = Fov { left: tx, right: tx, up: ty, down: ty };
        out = Some(out.map_or(p, |o| o.union(&p)));
    }
    out
}

/// Parallel views for two canted ones (orientations in the head's frame, left eye first): both
/// oriented as the mean of the two (the head's, for a symmetric cant), each FOV widened to contain
/// its canted one.
pub fn parallel(fovs: [Fov; 2], orientations: [DQuat; 2]) -> Option<(DQuat, [Fov; 2])> {
    let mean = orientations[0].slerp(orientations[1], 0.5).normalize();
    Some((mean, [contained_fov(&fovs[0], orientations[0], mean)?, contained_fov(&fovs[1], orientations[1], mean)?]))
}

/// Below this angle (radians) two views count as parallel: tracking noise, not a cant.
const PARALLEL_EPS: f64 = 1e-5;

/// The views the app is given for symmetric and parallel views: the two views (left eye first; FOVs
/// and orientations in one frame) turned parallel when `parallel` and they are not (both the mean
/// orientation, returned, each FOV the smallest holding its canted one), then made symmetric as
/// `mode` says. None when a canted view's corner is not in front of the mean.
pub fn widen(fovs: [Fov; 2], orientations: [DQuat; 2], mode: Symmetric, parallel_views: bool) -> Option<(Option<DQuat>, [Fov; 2])> {
    let canted = orientations[0].angle_between(orientations[1]) > PARALLEL_EPS;
    let (turn, fovs) = if parallel_views && canted {
        let (mean, f) = parallel(fovs, orientations)?;
        (Some(mean), f)
    } else {
        (None, fovs)
    };
    Some((turn, symmetric(fovs, mode)))
}

/// The overlap of two views (orientations in the head's frame, left eye first) as the head sees
/// them: each turned into the head's frame first.
pub fn seen_overlap(fovs: &[Fov; 2], orientations: [DQuat; 2]) -> Option<f64> {
    let seen = [contained_fov(&fovs[0], orientations[0], DQuat::IDENTITY)?, contained_fov(&fovs[1], orientations[1], DQuat::IDENTITY)?];
    Some(overlap(&seen))
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn deg(l: f64, r: f64, u: f64, d: f64) -> Fov {
        Fov { left: l.to_radians().tan(), right: r.to_radians().tan(), up: u.to_radians().tan(), down: d.to_radians().tan() }
    }

    /// A ring: visible inside the ellipse of the image's half extents, like a lens.
    fn ellipse_hidden(w: u32, h: u32, k: f64) -> Vec<bool> {
        (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .map(|(x, y)| {
                let (u, v) = ((x as f64 + 0.5) / w as f64 * 2.0 - 1.0, (y as f64 + 0.5) / h as f64 * 2.0 - 1.0);
                (u / k).powi(2) + (v / k).powi(2) > 1.0
            })
            .collect()
    }

    #[test]
    fn a_cut_is_whole_pixels_of_the_uncut_grid() {
        let fov = deg(-50.0, 45.0, 48.0, -52.0);
        let (w, h) = (400, 440);
        // Visible inside 0.8 of the half extents: the cut leaves out about 10 % per side.
        let c = cut(&fov, (w, h), &ellipse_hidden(w, h, 0.8), 0.0).unwrap();
        // The start moved out to a multiple of 16 (40 → 32, 44 → 32), the end where it was.
        assert_eq!((c.x0, c.x1, c.y0, c.y1), (32, 360, 32, 396));
        let px = fov.width() / w as f64;
        assert!((c.fov.left - (fov.left + 32.0 * px)).abs() < 1e-12);
        assert!((c.fov.width() / c.size().0 as f64 - px).abs() < 1e-12, "pixels per tangent kept");
        assert!((c.saved_share((w, h)) - (1.0 - 328.0 * 364.0 / (400.0 * 440.0))).abs() < 1e-12);
        // A margin widens it, on whole pixels, within the image.
        let m = cut(&fov, (w, h), &ellipse_hidden(w, h, 0.8), 2.0).unwrap();
        assert!(m.x0 <= c.x0 && m.x1 > c.x1 && m.y0 <= c.y0 && m.y1 > c.y1);
        let wide = cut(&fov, (w, h), &ellipse_hidden(w, h, 0.8), 40.0).unwrap();
        assert_eq!((wide.x0, wide.x1, wide.y0, wide.y1), (0, w, 0, h));
    }

    #[test]
    fn the_views_get_one_size() {
        let fov = deg(-50.0, 45.0, 48.0, -52.0);
        let mk = |x0, x1, y0, y1| {
            let (px, py) = (fov.width() / 504.0, fov.height() / 560.0);
            Cut { x0, x1, y0, y1, fov: Fov { left: fov.left + x0 as f64 * px, right: fov.left + x1 as f64 * px, up: fov.up - y0 as f64 * py, down: fov.up - y1 as f64 * py } }
        };
        let mut cuts = [mk(0, 484, 0, 560), mk(16, 490, 32, 500)];
        same_size(&mut cuts, &[(504, 560), (504, 560)]);
        assert_eq!(cuts.map(|c| (c.x0, c.x1, c.y0, c.y1)), [(0, 484, 0, 560), (16, 500, 0, 560)]);
        // The second's FOV is that of its new pixels on its grid.
        assert!((cuts[1].fov.right - mk(16, 500, 0, 560).fov.right).abs() < 1e-12 && (cuts[1].fov.up - fov.up).abs() < 1e-12);
        // An end past the image moves the start back, to a multiple of 16 where it can.
        let mut cuts = [mk(0, 480, 0, 560), mk(48, 500, 0, 560)];
        same_size(&mut cuts, &[(504, 560), (504, 560)]);
        assert_eq!((cuts[1].x0, cuts[1].x1), (16, 496));
    }

    #[test]
    fn nothing_visible_or_a_broken_fov_cuts_nothing() {
        let fov = deg(-45.0, 45.0, 45.0, -45.0);
        assert!(cut(&fov, (4, 4), &[true; 16], 0.0).is_none());
        assert!(cut(&Fov { right: fov.left, ..fov }, (4, 4), &[false; 16], 0.0).is_none());
        assert!(cut(&fov, (4, 4), &[false; 15], 0.0).is_none());
        let all = cut(&fov, (4, 4), &[false; 16], 0.0).unwrap();
        assert_eq!((all.size(), all.saved_share((4, 4))), ((4, 4), 0.0));
    }

    #[test]
    fn symmetric_views() {
        // An Index-like pair: the right eye mirrors the left horizontally, the vertical angles differ.
        let (a, b) = (deg(-55.0, 43.0, 51.0, -55.0), deg(-44.0, 54.0, 55.0, -51.0));
        let [h0, h1] = symmetric([a, b], Symmetric::Horizontal);
        assert_eq!((h0.up, h0.down), (h1.up, h1.down));
        assert_eq!((h0.left, h0.right), (-h1.right, -h1.left));
        assert!(h0.left <= a.left && h0.right >= a.right && h1.left <= b.left && h1.right >= b.right);
        assert_eq!((h0.up, h0.down), (b.up, a.down));
        let [f0, f1] = symmetric([a, b], Symmetric::Full);
        for (f, o) in [(f0, a), (f1, b)] {
            assert_eq!((f.left, f.down), (-f.right, -f.up));
            assert!(f.left <= o.left && f.right >= o.right && f.up >= o.up && f.down <= o.down);
        }
        assert_eq!(symmetric([a, b], Symmetric::Off), [a, b]);
        // Sizes keep the pixels per tangent.
        let s = size_for((2016, 2240), &a, &h0);
        assert_eq!(s.1, (2240.0 * h0.height() / a.height()).ceil() as u32);
        assert_eq!(size_for((2016, 2240), &a, &a), (2016, 2240));
    }

    #[test]
    fn overlap_of_parallel_views() {
        let (a, b) = (deg(-50.0, 40.0, 45.0, -45.0), deg(-40.0, 50.0, 45.0, -45.0));
        assert!((overlap(&[a, b]) - 80.0 / 100.0).abs() < 1e-9);
        assert_eq!(overlap(&[deg(-50.0, -10.0, 1.0, -1.0), deg(10.0, 50.0, 1.0, -1.0)]), 0.0);
    }

    #[test]
    fn parallel_views_contain_the_canted_ones() {
        // Pimax-like: each view canted 10° outward about +y.
        let fov = deg(-60.0, 45.0, 50.0, -50.0);
        let mirror = Fov { left: -fov.right, right: -fov.left, ..fov };
        let (ql, qr) = (DQuat::from_rotation_y(10f64.to_radians()), DQuat::from_rotation_y(-10f64.to_radians()));
        let (mean, [pl, pr]) = parallel([fov, mirror], [ql, qr]).unwrap();
        assert!(mean.angle_between(DQuat::IDENTITY) < 1e-9);
        // Yaw adds to the horizontal angles; the vertical ones widen at the far corners.
        assert!((pl.left.atan().to_degrees() - -70.0).abs() < 1e-9);
        assert!((pl.right.atan().to_degrees() - 35.0).abs() < 1e-9);
        assert!(pl.up > fov.up && pl.down < fov.down);
        assert_eq!((pr.left, pr.right), (-pl.right, -pl.left));
        // Uncanted: unchanged.
        assert_eq!(contained_fov(&fov, DQuat::IDENTITY, DQuat::IDENTITY).map(|f| f.angles()), Some(fov.angles()));
        // A corner behind the new orientation: no parallel view.
        assert!(contained_fov(&deg(-80.0, 80.0, 10.0, -10.0), DQuat::from_rotation_y(30f64.to_radians()), DQuat::IDENTITY).is_none());
    }

    #[test]
    fn widen_turns_parallel_first_then_makes_symmetric() {
        let (a, b) = (deg(-60.0, 45.0, 50.0, -50.0), deg(-45.0, 60.0, 48.0, -52.0));
        let cant = [DQuat::from_rotation_y(10f64.to_radians()), DQuat::from_rotation_y(-10f64.to_radians())];
        // Parallel views of parallel eyes: nothing to turn.
        let (t, f) = widen([a, b], [DQuat::IDENTITY; 2], Symmetric::Off, true).unwrap();
        assert!(t.is_none() && f == [a, b]);
        // Canted: both turned to the mean, then symmetric.
        let (t, f) = widen([a, b], cant, Symmetric::Horizontal, true).unwrap();
        assert!(t.unwrap().angle_between(DQuat::IDENTITY) < 1e-12);
        let (_, p) = parallel([a, b], cant).unwrap();
        assert_eq!(f, symmetric(p, Symmetric::Horizontal));
        assert!((f[0].up - f[1].up).abs() < 1e-15 && (f[0].left + f[1].right).abs() < 1e-15);
        // Symmetric alone keeps the cant.
        let (t, f) = widen([a, b], cant, Symmetric::Full, false).unwrap();
        assert!(t.is_none() && f == symmetric([a, b], Symmetric::Full));
        assert!(seen_overlap(&[a, b], cant).unwrap() < seen_overlap(&[a, b], [DQuat::IDENTITY; 2]).unwrap());
    }

    /// What symmetric and parallel views cost on each of the mock's headsets (docs/views.md's
    /// table, printed with `--nocapture`): the extra pixels at the runtime's density, both views,
    /// and the horizontal overlap of the two views.
    #[test]
    fn costs_per_headset() {
        use hmd_profiles::profile::{HmdProfile, HMD_NAMES};
        let pixels = |fovs: &[Fov; 2], base: &[Fov; 2], size: (u32, u32)| -> f64 {
            let n = |f: &Fov, b: &Fov| {
                let (w, h) = size_for(size, b, f);
                w as f64 * h as f64
            };
            (n(&fovs[0], &base[0]) + n(&fovs[1], &base[1])) / (2.0 * size.0 as f64 * size.1 as f64) - 1.0
        };
        for name in HMD_NAMES.iter().filter(|n| **n != "simple") {
            let p = HmdProfile::by_name(name).unwrap();
            let base = [Fov::from_angles(p.fov_rad(0)), Fov::from_angles(p.fov_rad(1))];
            let (h, f) = (symmetric(base, Symmetric::Horizontal), symmetric(base, Symmetric::Full));
            let q = |v: usize| {
                let r = p.eye_in_head(v).1;
                DQuat::from_xyzw(r.x as f64, r.y as f64, r.z as f64, r.w as f64)
            };
            let (_, par) = parallel(base, [q(0), q(1)]).unwrap();
            // Overlap of the views as the head sees them: a canted view's angles turn with it.
            let turned = |fov: &Fov, v: usize| contained_fov(fov, q(v), DQuat::IDENTITY).unwrap();
            let seen = [turned(&base[0], 0), turned(&base[1], 1)];
            eprintln!(
                "{name}: symmetric horizontal +{:.1} % pixels, overlap {:.1} -> {:.1} %; full +{:.1} %, overlap {:.1} %; parallel (cant {}°) +{:.1} % pixels",
                100.0 * pixels(&h, &base, p.recommended),
                100.0 * overlap(&seen),
                100.0 * overlap(&h),
                100.0 * pixels(&f, &base, p.recommended),
                100.0 * overlap(&f),
                p.cant_deg,
                100.0 * pixels(&par, &base, p.recommended)
            );
            assert!(pixels(&h, &base, p.recommended) >= 0.0 && pixels(&f, &base, p.recommended) >= pixels(&h, &base, p.recommended) - 1e-9);
            assert!(overlap(&h) >= overlap(&seen) - 1e-9 || p.cant_deg != 0.0);
            assert_eq!(pixels(&par, &base, p.recommended) > 1e-6, p.cant_deg != 0.0, "{name}: parallel views cost only with a cant");
        }
    }

    proptest! {
        /// The cut always holds every visible pixel, on whole pixels, and keeps pixels per tangent.
        #[test]
        fn the_cut_holds_every_visible_pixel(w in 1u32..60, h in 1u32..60, seed in any::<u64>(), margin in 0.0f64..5.0) {
            let fov = deg(-50.0, 45.0, 48.0, -52.0);
            let mut state = seed | 1;
            let hidden: Vec<bool> = (0..w * h).map(|_| { state ^= state << 13; state ^= state >> 7; state ^= state << 17; state % 7 != 0 }).collect();
            if let Some(c) = cut(&fov, (w, h), &hidden, margin) {
                for y in 0..h {
                    for x in 0..w {
                        if !hidden[(y * w + x) as usize] {
                            prop_assert!((c.x0..c.x1).contains(&x) && (c.y0..c.y1).contains(&y));
                        }
                    }
                }
                prop_assert!(c.x1 <= w && c.y1 <= h && c.x0 % CUT_ALIGN == 0 && c.y0 % CUT_ALIGN == 0);
                prop_assert!((c.fov.width() / c.size().0 as f64 - fov.width() / w as f64).abs() < 1e-9);
            } else {
                prop_assert!(hidden.iter().all(|&b| b));
            }
        }
    }
}
