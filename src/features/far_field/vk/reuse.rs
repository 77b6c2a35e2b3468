//! The far field's reuse draws filled at each submission: each destination view's instance
//! (where the source eye's pixels map, the split depth, the tiles) for this frame's poses and the
//! source copy that is fresh, or no draw where there is none (`FarFieldDevice::refresh`).

use crate::features::far_field::FarFieldSettings;
use super::{lock, pose_of, FarFieldDevice, ReuseOp, ReuseView};
use crate::features::far_field::rules::{self, InverseDepth, NoSource, PixelMap, ViewGeometry};
use crate::core::rect::PixelRect;
use crate::plugin::settings::Settings;
use crate::core::views::FarFieldViews;
use crate::plugin::vk::inject;
use crate::plugin::vk::DeviceState;
use ash::vk;

/// One destination view's draw parameters (instance attributes, `far_field.vert`).
#[repr(C)]
#[derive(Clone, Copy, Default)]
pub(super) struct Instance {
    pub(super) m: [[f32; 4]; 3],
    pub(super) k: [f32; 4],
    pub(super) depth: [f32; 4],
    pub(super) size: [f32; 4],
    /// (slot read, active, debug tint, view)
    pub(super) flags: [u32; 4],
    /// The destination view's rect in the framebuffer (x, y, width, height).
    pub(super) dst: [f32; 4],
    /// The slots' tile grid (tiles per row, rows, 0, 0).
    pub(super) grid: [u32; 4],
    /// The draw's viewport as recorded (x, y, width, height): `dst`, or, for a pass whose eyes
    /// were known only at submission, the render area the eye's rect lies in.
    pub(super) viewport: [f32; 4],
}

impl FarFieldDevice {
    /// Fills a reuse op's draws for this submission.
    pub(super) fn refresh(&self, d: &DeviceState, op: &ReuseOp, s: &Settings, views: &FarFieldViews, inverse: Option<InverseDepth>) {
        let f = &s.of::<FarFieldSettings>();
        let frame = views.current.as_ref().map_or(0, |c| c.0);
        let copied = *lock(&op.slots.copied);
        let mut args = vec![vk::DrawIndirectCommand::default(); op.views.len()];
        let mut instances = vec![Instance::default(); op.views.len()];
        for (i, guessed) in op.views.iter().enumerate() {
            // A draw recorded before the eyes were known is the eye it turns out to be, or none.
            let view = match &op.awaiting {
                None => Ok((guessed.view, guessed.rect)),
                Some(a) => a.resolve_or_why(d, s.intermediate, (guessed.view, guessed.layer, guessed.rect), false),
            };
            let (view, rect) = match view {
                Ok(v) => v,
                Err(why) => {
                    // A pass awaiting the walk is counted at each submission (`fills_at_submission`).
                    if let (Some(why), Some(a)) = (why, &op.awaiting) {
                        if a.walk {
                            self.not_applied(why);
                        }
                    }
                    continue;
                }
            };
            let v = &ReuseView { view, rect, ..*guessed };
            let slot = copied[v.slot as usize];
            let checked = rules::check_source(frame, v.view, f.source_view, f.alternate, slot.map(|c| c.0));
            let stamp = match checked {
                Ok(st) => st,
                Err(NoSource::NotDestination) => continue,
                Err(NoSource::NoFreshCopy) => {
                    self.count(|st| st.no_fresh_source += 1);
                    continue;
                }
            };
            let src_rect = slot.map_or(PixelRect { x: 0, y: 0, width: 0, height: 0 }, |c| c.1);
            let Some(inverse) = inverse else {
                self.not_applied("no_depth_range");
                continue;
            };
            if inverse.reversed() != op.reversed {
                self.not_applied("depth_range_mismatch");
                continue;
            }
            let (Some(src_pose), Some(dst_pose)) = (pose_of(views, stamp.frame, stamp.view), pose_of(views, frame, v.view)) else {
                self.count(|st| st.no_fresh_source += 1);
                continue;
            };
            let src = ViewGeometry::of(&src_pose, PixelRect { x: 0, y: 0, ..src_rect });
            let dst = ViewGeometry::of(&dst_pose, v.rect);
            let z = rules::split_distance(f.split_px, f.split_m, &src, &dst);
            let map = PixelMap::new(&src, &dst);
            let col = |c: glam::DVec3| [c.x as f32, c.y as f32, c.z as f32, 0.0];
            let with_w = |mut c: [f32; 4], w: f32| {
                c[3] = w;
                c
            };
            let split_depth = inverse.depth_of(z).clamp(0.0, 1.0);
            instances[i] = Instance {
                m: [
                    with_w(col(map.m.x_axis), 1.0 / op.slots.extent.width as f32),
                    with_w(col(map.m.y_axis), 1.0 / op.slots.extent.height as f32),
                    col(map.m.z_axis),
                ],
                k: [map.k.x as f32, map.k.y as f32, map.k.z as f32, if f.shift == crate::features::far_field::Shift::Depth { 1.0 } else { 0.0 }],
                depth: [inverse.a as f32, inverse.b as f32, (1.0 / z) as f32, split_depth as f32],
                size: [src_rect.width as f32, src_rect.height as f32, op.slots.samples.as_raw() as f32, 0.0],
                // The shader's view is the multiview index, the same as the guess there.
                flags: [v.slot, 1, f.debug as u32, guessed.view],
                dst: [v.rect.x as f32, v.rect.y as f32, v.rect.width as f32, v.rect.height as f32],
                grid: [op.slots.grid.0, op.slots.grid.1, 0, 0],
                viewport: [guessed.rect.x as f32, guessed.rect.y as f32, guessed.rect.width as f32, guessed.rect.height as f32],
            };
            args[i] = vk::DrawIndirectCommand { vertex_count: rules::reuse_vertices(v.rect.width, v.rect.height), instance_count: 1, first_vertex: 0, first_instance: i as u32 };
            self.mark_reused(frame, v.view);
            self.count(|st| *st.views_reused.entry(v.view).or_insert(0) += 1);
        }
        if op.multiview {
            // One draw: every active view's instance (inactive ones cull themselves).
            let vertex_count = args.iter().map(|a| a.vertex_count).max().unwrap_or(0);
            args = vec![vk::DrawIndirectCommand { vertex_count, instance_count: instances.len() as u32, first_vertex: 0, first_instance: 0 }];
            args.resize(op.views.len(), vk::DrawIndirectCommand::default());
        }
        op.buffer.write(0, &args);
        op.buffer.write(inject::DRAW_ARGS * op.views.len() as u64, &instances);
    }
}
