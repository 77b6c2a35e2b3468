//! The size-based fallback (`eyes.fallback = size`, off by default): for what the data-flow walk
//! cannot see (descriptor buffers, bindless arrays), a depth-tested pass into an image of an eye's
//! aspect and size (the rule Direct3D layers use) is taken as an eye pass, the eye by the order such
//! passes come in a frame (`eyes.fallback_order`). A guess by construction, so it is opt-in,
//! per app, and every decision is logged with its reason.
#![forbid(unsafe_code)]

use super::eye_pass::EyeSource;
use crate::core::rect::PixelRect;

/// `eyes.fallback_order`: which view the first eye-sized pass of a frame shows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Order {
    /// Left (view 0) first.
    LeftRight,
    /// Right (view 1) first.
    RightLeft,
}

impl Order {
    fn view(self, nth: usize) -> u32 {
        let v = (nth % 2) as u32;
        match self {
            Order::LeftRight => v,
            Order::RightLeft => 1 - v,
        }
    }
}

/// An image's aspect may differ from the eye's by this much (the peers' 0.01).
const ASPECT_TOLERANCE: f64 = 0.01;
/// Render scales the fallback accepts, relative to the eye's swapchain rect.
const MIN_SCALE: f64 = 0.5;
const MAX_SCALE: f64 = 2.0;

/// The eyes an image of `extent` with `layers` array layers shows when its pass is the `nth`
/// eye-sized pass of the frame, given the eye's size in the swapchain (`eye`: width, height);
/// Err says why it is no eye.
pub fn eyes_by_size(extent: (u32, u32), layers: u32, multiview: bool, eye: (u32, u32), nth: usize, order: Order) -> Result<Vec<EyeSource>, String> {
    let (w, h) = (extent.0 as f64, extent.1 as f64);
    let (ew, eh) = (eye.0 as f64, eye.1 as f64);
    if w <= 0.0 || h <= 0.0 || ew <= 0.0 || eh <= 0.0 {
        return Err("no size".into());
    }
    let eye_aspect = ew / eh;
    let same = |aspect: f64| ((aspect - eye_aspect) / eye_aspect).abs() <= ASPECT_TOLERANCE;
    let scale = h / eh;
    if !(MIN_SCALE..=MAX_SCALE).contains(&scale) {
        return Err(format!("{}x{} is {scale:.2} of the eye's height {}", extent.0, extent.1, eye.1));
    }
    let whole = PixelRect { x: 0, y: 0, width: extent.0, height: extent.1 };
    if same(w / h) {
        if multiview && layers >= 2 {
            return Ok((0..2).map(|l| EyeSource { view: l, layer: l, rect: whole }).collect());
        }
        return Ok(vec![EyeSource { view: order.view(nth), layer: 0, rect: whole }]);
    }
    if same(w / 2.0 / h) {
        let half = extent.0 / 2;
        let left = PixelRect { width: half, ..whole };
        let right = PixelRect { x: half as i32, width: extent.0 - half, ..whole };
        let (a, b) = (order.view(0), order.view(1));
        return Ok(vec![EyeSource { view: a, layer: 0, rect: left }, EyeSource { view: b, layer: 0, rect: right }]);
    }
    Err(format!("{}x{} has neither the eye's aspect {:.3} nor twice it", extent.0, extent.1, eye_aspect))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn eye_sized_passes_take_their_eye_by_order() {
        let eye = (1000, 1100);
        let one = eyes_by_size((1000, 1100), 1, false, eye, 0, Order::LeftRight).unwrap();
        assert_eq!((one.len(), one[0].view), (1, 0));
        assert_eq!(eyes_by_size((800, 880), 1, false, eye, 1, Order::LeftRight).unwrap()[0].view, 1, "render scale 0.8, second pass");
        assert_eq!(eyes_by_size((1000, 1100), 1, false, eye, 0, Order::RightLeft).unwrap()[0].view, 1);
        let mv = eyes_by_size((1000, 1100), 2, true, eye, 0, Order::LeftRight).unwrap();
        assert_eq!(mv.iter().map(|e| (e.view, e.layer)).collect::<Vec<_>>(), vec![(0, 0), (1, 1)]);
        let sbs = eyes_by_size((2000, 1100), 1, false, eye, 0, Order::LeftRight).unwrap();
        assert_eq!(sbs.iter().map(|e| (e.view, e.rect.x, e.rect.width)).collect::<Vec<_>>(), vec![(0, 0, 1000), (1, 1000, 1000)]);
    }

    #[test]
    fn other_shapes_are_refused_with_a_reason() {
        let eye = (1000, 1100);
        assert!(eyes_by_size((256, 256), 1, false, eye, 0, Order::LeftRight).unwrap_err().contains("of the eye's height"));
        assert!(eyes_by_size((1100, 1100), 1, false, eye, 0, Order::LeftRight).unwrap_err().contains("aspect"));
        assert!(eyes_by_size((0, 0), 1, false, eye, 0, Order::LeftRight).is_err());
    }
}
