//! Which of the upscale's workgroup tiles the lens never shows (`upscale.skip_hidden`): from the
//! runtime's hidden-area mesh (`XR_KHR_visibility_mask`), rasterized into the view's display-size
//! rect the way the GPU rasterizes the mask (`core::lens::coverage_bitmap`), each 16×16 tile of a
//! job is classified for the two passes. Pure; the shell fetches the mesh and the Vulkan half
//! uploads the classes, which the shaders read per workgroup.
//!
//! What must stay exact: every pixel within `MARGIN` of a visible pixel (the compositor's filter
//! reads around the pixels it shows). RCAS may skip a tile when no visible pixel lies within
//! `MARGIN` of it; EASU when none lies within `MARGIN` + 1 (RCAS reads EASU's output one pixel
//! around each pixel it sharpens). Each pass is dispatched over the list of tiles it runs (a
//! skipped workgroup that only stored black still cost half a full one on an H100); the skipped
//! tiles keep the black the layer's intermediates are cleared to when the tiles change, so the
//! runtime's image is the same every frame there (what an app that masks its hidden area shows).
#![forbid(unsafe_code)]

use crate::core::lens::hidden_pixels;
use crate::core::views::ViewFov;

/// A tile's class: both passes run.
pub const RUN: u32 = 0;
/// RCAS skips the tile (EASU still runs: RCAS's neighbours read it).
pub const RCAS_SKIPS: u32 = 1;
/// EASU skips the tile (only ever with RCAS).
pub const EASU_SKIPS: u32 = 2;
/// Both passes skip the tile.
pub const BOTH_SKIP: u32 = RCAS_SKIPS | EASU_SKIPS;

/// Pixels around the visible area that are computed as if nothing were skipped.
pub const MARGIN: u32 = 2;

/// A job's tile classes: `cols` × `rows` tiles of `group` pixels over its destination rect, row
/// by row (the shaders' workgroups).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Tiles {
    pub cols: u32,
    pub rows: u32,
    pub classes: Vec<u32>,
    /// The tiles EASU runs and those RCAS runs, each as x | y << 16 (the shaders' lists).
    pub easu: Vec<u32>,
    pub rcas: Vec<u32>,
}

impl Tiles {
    /// The share of tiles RCAS skips (EASU skips a little fewer).
    pub fn skipped_share(&self) -> f64 {
        let n = self.classes.iter().filter(|&&c| c & RCAS_SKIPS != 0).count();
        n as f64 / self.classes.len().max(1) as f64
    }
}

/// Classifies the `group`-sized tiles of a `size` image whose `hidden` pixels the lens never shows.
pub fn classify(hidden: &[bool], size: (u32, u32), group: u32) -> Tiles {
    let (w, h) = (size.0 as usize, size.1 as usize);
    let g = group.max(1) as usize;
    let (cols, rows) = (w.div_ceil(g), h.div_ceil(g));
    // Visible pixels summed over every rectangle from the origin (a summed-area table, one row and
    // column of zeros in front): any rectangle's count in four reads.
    let mut sat = vec![0u32; (w + 1) * (h + 1)];
    for y in 0..h {
        let mut row = 0u32;
        for x in 0..w {
            row += (!hidden.get(y * w + x).copied().unwrap_or(false)) as u32;
            sat[(y + 1) * (w + 1) + x + 1] = sat[y * (w + 1) + x + 1] + row;
        }
    }
    let visible = |x0: usize, y0: usize, x1: usize, y1: usize| {
        let at = |x: usize, y: usize| sat[y * (w + 1) + x] as i64;
        at(x1, y1) - at(x0, y1) - at(x1, y0) + at(x0, y0)
    };
    let around = |tx: usize, ty: usize, m: usize| {
        let (x0, y0) = ((tx * g).saturating_sub(m), (ty * g).saturating_sub(m));
        let (x1, y1) = (((tx + 1) * g + m).min(w), ((ty + 1) * g + m).min(h));
        visible(x0, y0, x1, y1)
    };
    let m = MARGIN as usize;
    let classes: Vec<u32> = (0..rows)
        .flat_map(|ty| (0..cols).map(move |tx| (tx, ty)))
        .map(|(tx, ty)| match (around(tx, ty, m) == 0, around(tx, ty, m + 1) == 0) {
            (true, true) => BOTH_SKIP,
            (true, false) => RCAS_SKIPS,
            _ => RUN,
        })
        .collect();
    let list = |skips: u32| -> Vec<u32> { (0..rows * cols).filter(|&i| classes[i] & skips == 0).map(|i| (i % cols) as u32 | ((i / cols) as u32) << 16).collect() };
    let (easu, rcas) = (list(EASU_SKIPS), list(RCAS_SKIPS));
    Tiles { cols: cols as u32, rows: rows as u32, classes, easu, rcas }
}

/// The tiles of a job's `size` destination showing `fov`, given the view's hidden triangles.
pub fn tiles(triangles: &[[f32; 2]], fov: &ViewFov, size: (u32, u32), group: u32) -> Option<Tiles> {
    hidden_pixels(triangles, fov, size).map(|hidden| classify(&hidden, size, group))
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn fov() -> ViewFov {
        ViewFov { tan_left: -1.0, tan_right: 1.0, tan_up: 1.0, tan_down: -1.0 }
    }

    #[test]
    fn nothing_hidden_runs_everything() {
        let t = classify(&[false; 40 * 20], (40, 20), 16);
        assert_eq!((t.cols, t.rows), (3, 2));
        assert!(t.classes.iter().all(|&c| c == RUN));
        assert_eq!(t.skipped_share(), 0.0);
        assert_eq!(t.easu, vec![0, 1, 2, 1 << 16, 1 | 1 << 16, 2 | 1 << 16]);
        assert_eq!(t.rcas, t.easu);
    }

    #[test]
    fn the_margins_around_a_visible_pixel() {
        // 64×16 image, one visible pixel at x = 17 (tile 1): tile 0 is 2 pixels away (inside
        // the margin: runs), tile 2 (x ≥ 32) 15 away, tile 3 further: both skip.
        let mut hidden = vec![true; 64 * 16];
        hidden[5 * 64 + 17] = false;
        let t = classify(&hidden, (64, 16), 16);
        assert_eq!(t.classes, vec![RUN, RUN, BOTH_SKIP, BOTH_SKIP]);
        // At x = 29 the next tile (x ≥ 32) is 3 pixels away: outside RCAS's margin (2), inside
        // EASU's (3): RCAS skips it, EASU runs it.
        let mut hidden = vec![true; 64 * 16];
        hidden[5 * 64 + 29] = false;
        let t = classify(&hidden, (64, 16), 16);
        assert_eq!(t.classes, vec![BOTH_SKIP, RUN, RCAS_SKIPS, BOTH_SKIP]);
        assert_eq!((t.easu.clone(), t.rcas.clone()), (vec![1, 2], vec![1]));
    }

    #[test]
    fn a_hidden_ring_skips_the_corners_only() {
        // Everything outside the unit circle of the tangent plane hidden (a fan of triangles out
        // to the FOV's corners): the corner tiles skip, the centre runs.
        let n = 64;
        let mut tris = Vec::new();
        for i in 0..n {
            let a = |k: usize| {
                let t = std::f32::consts::TAU * k as f32 / n as f32;
                (t.cos(), t.sin())
            };
            let ((c0, s0), (c1, s1)) = (a(i), a(i + 1));
            tris.extend([[c0, s0], [c0 * 3.0, s0 * 3.0], [c1 * 3.0, s1 * 3.0], [c0, s0], [c1 * 3.0, s1 * 3.0], [c1, s1]]);
        }
        let t = tiles(&tris, &fov(), (256, 256), 16).unwrap();
        assert_eq!(t.classes[0], BOTH_SKIP);
        assert_eq!(t.classes[(8 * t.cols + 8) as usize], RUN);
        // The circle's complement is 21.5 % of the square; whole 16-pixel tiles with their margins
        // of a 256-pixel image, about 9 %.
        let share = t.skipped_share();
        assert!((0.05..0.215).contains(&share), "{share}");
    }

    #[test]
    fn degenerate_fovs_skip_nothing() {
        let tris = [[-2.0, -2.0], [2.0, -2.0], [2.0, 2.0]];
        assert!(tiles(&tris, &ViewFov { tan_left: 1.0, tan_right: 1.0, ..fov() }, (32, 32), 16).is_none());
        assert!(tiles(&[], &fov(), (32, 32), 16).is_none());
    }

    proptest! {
        /// Whatever is hidden, no tile within the margins of a visible pixel is skipped.
        #[test]
        fn never_skips_near_a_visible_pixel(w in 1u32..70, h in 1u32..70, seed in any::<u64>(), density in 0.0f64..0.02) {
            let mut state = seed | 1;
            let hidden: Vec<bool> = (0..w * h).map(|_| {
                state ^= state << 13; state ^= state >> 7; state ^= state << 17;
                (state % 10_000) as f64 / 10_000.0 >= density
            }).collect();
            let t = classify(&hidden, (w, h), 16);
            for y in 0..h {
                for x in 0..w {
                    if hidden[(y * w + x) as usize] { continue; }
                    for ty in 0..t.rows {
                        for tx in 0..t.cols {
                            let dist = |p: u32, lo: u32, hi: u32| if p < lo { lo - p } else if p >= hi { p + 1 - hi } else { 0 };
                            let d = dist(x, tx * 16, (tx + 1) * 16).max(dist(y, ty * 16, (ty + 1) * 16));
                            let c = t.classes[(ty * t.cols + tx) as usize];
                            if d <= MARGIN { prop_assert_eq!(c & RCAS_SKIPS, 0); }
                            if d <= MARGIN + 1 { prop_assert!(c != BOTH_SKIP); }
                        }
                    }
                }
            }
        }
    }
}
