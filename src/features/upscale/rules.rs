//! The upscale's geometry, pure: what size the app is told to render at, which rect of the
//! runtime's (display-size) image an app's `imageRect` becomes, and the texture LOD bias that
//! keeps textures as sharp as at the display size.
//!
//! Sizes: the recommended size the app sees is the runtime's recommended (display) size times
//! `upscale.scale` per axis, rounded, at least 1 pixel, at most the runtime's maximum; the
//! runtime's swapchain behind an app swapchain of any size is that size times the same factors
//! (display ÷ render), so a side-by-side or otherwise packed app image keeps its layout. An
//! `imageRect` keeps its origin mapped by those factors; its size is the whole view's display size
//! (the upscale fills the view at display resolution even when the app, with dynamic resolution,
//! rendered a smaller rect), clamped to the runtime image.
#![forbid(unsafe_code)]

use crate::core::rect::PixelRect;

/// The smallest and largest scale per axis (`upscale.scale`).
pub const SCALE_RANGE: (f32, f32) = (0.5, 1.0);

/// `scale` made usable: inside `SCALE_RANGE`; 1 where it is not a number.
pub fn clamp_scale(scale: f32) -> f32 {
    if scale.is_finite() {
        scale.clamp(SCALE_RANGE.0, SCALE_RANGE.1)
    } else {
        1.0
    }
}

/// The size the app is told to render a view of `display` size at (`scale` per axis), at least
/// 1 pixel and at most `max` (the runtime's maximum image size for the view) per axis.
pub fn render_size(display: (u32, u32), scale: (f32, f32), max: (u32, u32)) -> (u32, u32) {
    let axis = |d: u32, s: f32, m: u32| ((d as f64 * clamp_scale(s) as f64).round() as u32).clamp(1, m.max(1));
    (axis(display.0, scale.0, max.0), axis(display.1, scale.1, max.1))
}

/// Display pixels per rendered pixel, per axis, for a view recommended at `display` and told to
/// render at `render`.
pub fn factors(display: (u32, u32), render: (u32, u32)) -> (f64, f64) {
    (display.0 as f64 / render.0.max(1) as f64, display.1 as f64 / render.1.max(1) as f64)
}

/// The runtime's image size behind an app image of `app` size: scaled by `k`, rounded up, at
/// most `max`.
pub fn runtime_extent(app: (u32, u32), k: (f64, f64), max: (u32, u32)) -> (u32, u32) {
    // Less a hair before rounding up: a × (d ÷ a) is d, give or take the last bit.
    let axis = |a: u32, k: f64, m: u32| ((a as f64 * k - 1e-6).ceil() as u32).clamp(1, m.max(1));
    (axis(app.0, k.0, max.0), axis(app.1, k.1, max.1))
}

/// The runtime image's rect for the app's `rect` (an `imageRect` in an app image): its origin
/// scaled by `k`, the view's `display` size, clamped inside `runtime` (the runtime image's size).
/// None when nothing of it is inside.
pub fn runtime_rect(rect: PixelRect, k: (f64, f64), display: (u32, u32), runtime: (u32, u32)) -> Option<PixelRect> {
    let x = (rect.x.max(0) as f64 * k.0).round() as i64;
    let y = (rect.y.max(0) as f64 * k.1).round() as i64;
    let (rw, rh) = (runtime.0 as i64, runtime.1 as i64);
    if x >= rw || y >= rh || rect.width == 0 || rect.height == 0 {
        return None;
    }
    let w = (display.0 as i64).min(rw - x);
    let h = (display.1 as i64).min(rh - y);
    (w > 0 && h > 0).then_some(PixelRect { x: x as i32, y: y as i32, width: w as u32, height: h as u32 })
}

/// The LOD bias that makes textures sampled at `render` size pick the mip level they would at
/// `display` size: log2 of the rendered pixels' linear size ratio (negative: sharper), over both
/// axes.
pub fn auto_mip_bias(render: (u32, u32), display: (u32, u32)) -> f32 {
    let area = |s: (u32, u32)| s.0.max(1) as f64 * s.1.max(1) as f64;
    (0.5 * (area(render) / area(display)).log2()) as f32
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn the_index_at_the_default_scale() {
        let display = (2016, 2240);
        let render = render_size(display, (0.77, 0.77), (4096, 4096));
        assert_eq!(render, (1552, 1725));
        let k = factors(display, render);
        // An app swapchain of one view, and a side-by-side one of two.
        assert_eq!(runtime_extent(render, k, (16384, 16384)), (2016, 2240));
        assert_eq!(runtime_extent((2 * render.0, render.1), k, (16384, 16384)), (4032, 2240));
        let right = PixelRect { x: 1552, y: 0, width: 1552, height: 1725 };
        assert_eq!(runtime_rect(right, k, display, (4032, 2240)), Some(PixelRect { x: 2016, y: 0, width: 2016, height: 2240 }));
        // Dynamic resolution: a smaller rect still fills the view at display size.
        let small = PixelRect { x: 0, y: 0, width: 1200, height: 1300 };
        assert_eq!(runtime_rect(small, k, display, (2016, 2240)), Some(PixelRect { x: 0, y: 0, width: 2016, height: 2240 }));
        let bias = auto_mip_bias(render, display);
        assert!((bias - (0.77f32).log2()).abs() < 0.01, "{bias}");
    }

    #[test]
    fn hostile_sizes_and_scales() {
        assert_eq!(render_size((1, 1), (0.5, 0.5), (1, 1)), (1, 1));
        assert_eq!(render_size((3, 5), (0.5, 0.5), (100, 100)), (2, 3));
        assert_eq!(render_size((100, 100), (f32::NAN, 0.0), (100, 100)), (100, 50));
        assert_eq!(render_size((100, 100), (7.0, -1.0), (60, 100)), (60, 50));
        assert_eq!(render_size((0, 0), (0.77, 0.77), (0, 0)), (1, 1));
        assert_eq!(runtime_rect(PixelRect { x: 5000, y: 0, width: 10, height: 10 }, (1.0, 1.0), (10, 10), (100, 100)), None);
        assert_eq!(runtime_rect(PixelRect { x: 0, y: 0, width: 0, height: 10 }, (1.0, 1.0), (10, 10), (100, 100)), None);
        assert_eq!(auto_mip_bias((100, 100), (100, 100)), 0.0);
    }

    proptest! {
        /// Every size the app may be told is within [1, max], and the runtime's image of the
        /// app's whole image covers every view's display-size rect.
        #[test]
        fn sizes_stay_in_bounds(dw in 1u32..8192, dh in 1u32..8192, sx in 0.0f32..2.0, sy in 0.0f32..2.0) {
            let max = (8192, 8192);
            let r = render_size((dw, dh), (sx, sy), max);
            prop_assert!(r.0 >= 1 && r.1 >= 1 && r.0 <= max.0 && r.1 <= max.1);
            let k = factors((dw, dh), r);
            let e = runtime_extent(r, k, (16384, 16384));
            prop_assert!(e.0 >= dw && e.1 >= dh);
            let rect = runtime_rect(PixelRect { x: 0, y: 0, width: r.0, height: r.1 }, k, (dw, dh), e).unwrap();
            prop_assert_eq!((rect.width, rect.height), (dw, dh));
        }
    }
}
