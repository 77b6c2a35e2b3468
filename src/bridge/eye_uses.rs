//! What an `xrEndFrame` says about eyes: the layer learns which swapchain (and which rectangle and
//! array layer of it) shows which view only from the app's submission, so it turns the submitted
//! projection layers into per-swapchain eye uses here, away from the FFI shell.

use crate::core::views::{EyeUse, ImageRect};
use std::collections::BTreeMap;

/// One sub-image reference of a projection view, as read from the app's structs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SubImage {
    pub swapchain: u64,
    pub image_rect: ImageRect,
    pub image_array_index: u32,
}

/// A projection view as submitted.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SubmittedView {
    pub color: SubImage,
    pub depth: Option<SubImage>,
}

/// Groups the views of all projection layers of one frame by swapchain. Only the first projection
/// layer's views are eyes: further projection layers (rare: overlays, quad-views insets) reuse view
/// indices for other purposes, and treating them as eyes would mask the wrong images.
pub fn eye_uses(projection_layers: &[Vec<SubmittedView>]) -> BTreeMap<u64, Vec<EyeUse>> {
    let mut uses: BTreeMap<u64, Vec<EyeUse>> = BTreeMap::new();
    let Some(views) = projection_layers.first() else { return uses };
    for (view, v) in views.iter().enumerate() {
        let mut add = |sub: &SubImage, depth: bool| {
            let e = EyeUse { view: view as u32, image_rect: sub.image_rect, image_array_index: sub.image_array_index, depth };
            let list = uses.entry(sub.swapchain).or_default();
            if !list.contains(&e) {
                list.push(e);
            }
        };
        add(&v.color, false);
        if let Some(d) = &v.depth {
            add(d, true);
        }
    }
    uses
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sub(swapchain: u64, x: i32, layer: u32) -> SubImage {
        SubImage { swapchain, image_rect: ImageRect { x, y: 0, width: 100, height: 80 }, image_array_index: layer }
    }

    #[test]
    fn per_eye_multiview_and_side_by_side() {
        let per_eye = eye_uses(&[vec![
            SubmittedView { color: sub(1, 0, 0), depth: Some(sub(3, 0, 0)) },
            SubmittedView { color: sub(2, 0, 0), depth: Some(sub(4, 0, 0)) },
        ]]);
        assert_eq!(per_eye.len(), 4);
        assert_eq!(per_eye[&2][0].view, 1);
        assert!(per_eye[&4][0].depth);

        let multiview = eye_uses(&[vec![
            SubmittedView { color: sub(1, 0, 0), depth: None },
            SubmittedView { color: sub(1, 0, 1), depth: None },
        ]]);
        let uses = &multiview[&1];
        assert_eq!(uses.iter().map(|u| (u.view, u.image_array_index)).collect::<Vec<_>>(), vec![(0, 0), (1, 1)]);

        let sbs = eye_uses(&[vec![
            SubmittedView { color: sub(1, 0, 0), depth: None },
            SubmittedView { color: sub(1, 100, 0), depth: None },
        ]]);
        assert_eq!(sbs[&1].iter().map(|u| u.image_rect.x).collect::<Vec<_>>(), vec![0, 100]);
    }

    #[test]
    fn only_the_first_projection_layer_names_eyes() {
        let uses = eye_uses(&[
            vec![SubmittedView { color: sub(1, 0, 0), depth: None }, SubmittedView { color: sub(2, 0, 0), depth: None }],
            vec![SubmittedView { color: sub(9, 0, 0), depth: None }, SubmittedView { color: sub(9, 0, 1), depth: None }],
        ]);
        assert!(!uses.contains_key(&9));
        assert!(eye_uses(&[]).is_empty());
    }
}
