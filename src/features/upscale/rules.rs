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


/// One view as the runtime recommends it, and the size the app is told instead.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ViewSizes {
    /// The runtime's recommended size: what the display shows per view.
    pub display: (u32, u32),
    /// The runtime's maximum image rect size for the view.
    pub max: (u32, u32),
    /// What the app is told to render at.
    pub render: (u32, u32),
}

/// A view as the runtime answers it: (recommended size, maximum size).
pub type RuntimeView = ((u32, u32), (u32, u32));

/// The sizes told for the runtime's `views` at `scale` per axis.
pub fn told(views: &[RuntimeView], scale: f32) -> Vec<ViewSizes> {
    views.iter().map(|&(display, max)| ViewSizes { display, max, render: render_size(display, (scale, scale), max) }).collect()
}

/// What `xrCreateSwapchain` asks for, as far as the interposition decision needs it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Ask {
    pub width: u32,
    pub height: u32,
    pub sample_count: u32,
    pub face_count: u32,
    pub mip_count: u32,
    /// A depth or stencil swapchain (usage or format).
    pub depth: bool,
    pub protected: bool,
}

/// Why a swapchain is left to the runtime as the app asked for it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Skip {
    /// The told size equals the display size (scale 1, or a 1-pixel view).
    Unscaled,
    /// Depth stays at the app's size: `XrCompositionLayerDepthInfoKHR::subImage.imageRect` maps
    /// its own rect onto the view, so a depth map at the render size describes the same view.
    Depth,
    /// Several samples and several mip levels: Vulkan makes no such image (VUID-VkImageCreateInfo-samples-02257),
    /// so the runtime refuses it too.
    MultisampledMips,
    /// A cube map: sized by the app for its cube layer (no told size of a view applies) and
    /// sampled by direction.
    Cube(u32),
    Protected,
    /// Not a view's aspect (nor two views' side by side): a quad, a UI panel.
    NotAViewSize,
    /// No view sizes are known for the session.
    NoViews,
}

impl Skip {
    pub fn why(self) -> String {
        match self {
            Skip::Unscaled => "the told size is the display size".into(),
            Skip::Depth => "a depth swapchain (submitted at the app's size: its imageRect maps it onto the view)".into(),
            Skip::MultisampledMips => "several samples per pixel and several mip levels".into(),
            Skip::Cube(n) => format!("{n} faces: a cube map, sized by the app (not from a view's told size)"),
            Skip::Protected => "protected content".into(),
            Skip::NotAViewSize => "not a view's aspect (a panel, not an eye)".into(),
            Skip::NoViews => "no view sizes known".into(),
        }
    }
}

/// How an app swapchain is interposed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plan {
    /// Display pixels per app pixel, per axis (the matched view's display ÷ told size).
    pub k: (f64, f64),
    /// The runtime's swapchain size.
    pub runtime: (u32, u32),
    /// One view's size in the runtime's image (the whole image, or half of a side-by-side one):
    /// what a projection view's rect becomes, whatever smaller rect the app rendered.
    pub view: (u32, u32),
}

/// Whether the aspect `w / h` is `aspect` give or take 2 %.
fn same_aspect(w: u32, h: u32, aspect: f64) -> bool {
    h > 0 && aspect > 0.0 && ((w as f64 / h as f64) / aspect - 1.0).abs() <= 0.02
}

/// Whether and how a swapchain the app asks for is interposed: a single-face colour swapchain (any
/// sample count) with a view's aspect (or two views' side by side). Its size may be the told
/// one or the app's own fraction of it (an engine's render scale): the runtime's image is the
/// app's size times display ÷ told either way, so the app keeps its own scale on top.
pub fn plan(ask: &Ask, views: &[ViewSizes]) -> Result<Plan, Skip> {
    if ask.protected {
        return Err(Skip::Protected);
    }
    if ask.depth {
        return Err(Skip::Depth);
    }
    // A multisampled swapchain is interposed: the app's images keep their samples, each frame's
    // are resolved before the upscale, and the runtime's swapchain is single-sampled.
    if ask.sample_count > 1 && ask.mip_count > 1 {
        return Err(Skip::MultisampledMips);
    }
    if ask.face_count > 1 {
        return Err(Skip::Cube(ask.face_count));
    }
    if views.is_empty() {
        return Err(Skip::NoViews);
    }
    let aspect = |v: &ViewSizes| v.render.0 as f64 / v.render.1.max(1) as f64;
    let v = views.iter().find_map(|v| (1..=2u32).find(|&n| same_aspect(ask.width, ask.height, n as f64 * aspect(v))).map(|n| (v, n)));
    let Some((v, n)) = v else { return Err(Skip::NotAViewSize) };
    if v.render == v.display {
        return Err(Skip::Unscaled);
    }
    let k = factors(v.display, v.render);
    let max = (n * v.max.0.max(v.display.0), v.max.1.max(v.display.1));
    let runtime = runtime_extent((ask.width, ask.height), k, max);
    if runtime == (ask.width, ask.height) {
        return Err(Skip::Unscaled);
    }
    let view = runtime_extent((ask.width / n, ask.height), k, (v.max.0.max(v.display.0), max.1));
    Ok(Plan { k, runtime, view })
}

/// The app image's rect clamped to its `extent`; None when nothing of it is inside.
pub fn clamp_to(rect: PixelRect, extent: (u32, u32)) -> Option<PixelRect> {
    let r = rect.intersect(&PixelRect { x: 0, y: 0, width: extent.0, height: extent.1 });
    (r.area() > 0).then_some(r)
}

/// The runtime rect of a non-projection layer's `rect` (a quad's, a cylinder's) in an app image of
/// `app` size: the same part of the image, scaled by `k`, inside `runtime`; an edge on the app
/// image's edge stays on the runtime image's (whose size is rounded up).
pub fn scaled_rect(rect: PixelRect, k: (f64, f64), app: (u32, u32), runtime: (u32, u32)) -> Option<PixelRect> {
    let edge = |a: i64, size: u32, k: f64, runtime: u32| if a >= size as i64 { runtime as i64 } else { ((a as f64 * k).round() as i64).min(runtime as i64) };
    let x0 = (rect.x.max(0) as f64 * k.0).round() as i64;
    let y0 = (rect.y.max(0) as f64 * k.1).round() as i64;
    let x1 = edge(rect.x.max(0) as i64 + rect.width as i64, app.0, k.0, runtime.0);
    let y1 = edge(rect.y.max(0) as i64 + rect.height as i64, app.1, k.1, runtime.1);
    (x1 > x0 && y1 > y0).then_some(PixelRect { x: x0 as i32, y: y0 as i32, width: (x1 - x0) as u32, height: (y1 - y0) as u32 })
}

/// The foveal ellipse of a view (`upscale.fovea_only`): centre and radii in the runtime image's
/// pixels, for the fovea's direction `center` (a tangent-plane point: x right, y up), its angular
/// radius `inner_deg`, the view's tangents `tan` (left, right, up, down) and its rect `dst`. The
/// radius is the tangent span on the fovea's outer side (the larger one), so the ellipse holds the
/// whole inner region. Zero radii where the view's angles are degenerate (EASU everywhere).
pub fn fovea_ellipse(center: [f32; 2], inner_deg: f32, tan: [f32; 4], dst: PixelRect) -> [f32; 4] {
    let [l, r, u, d] = tan;
    if !(r > l && u > d && inner_deg.is_finite() && inner_deg > 0.0) {
        return [0.0; 4];
    }
    let (w, h) = (dst.width as f32, dst.height as f32);
    let cx = dst.x as f32 + (center[0] - l) / (r - l) * w;
    let cy = dst.y as f32 + (u - center[1]) / (u - d) * h;
    let at = (center[0].hypot(center[1])).atan();
    let outer = (at + inner_deg.to_radians()).min(89f32.to_radians());
    let span = outer.tan() - at.tan();
    [cx, cy, span * w / (r - l), span * h / (u - d)]
}

/// Every device allows LOD biases of at least ±2 (`maxSamplerLodBias`).
pub const SAFE_LOD_BIAS: f32 = 2.0;

/// The app's sampler LOD bias `app` with the upscale's `bias` added, kept within what every device
/// allows unless the app's own bias was already beyond it.
pub fn biased(app: f32, bias: f32) -> f32 {
    let limit = SAFE_LOD_BIAS.max(app.abs());
    (app + bias).clamp(-limit, limit)
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


    #[test]
    fn which_swapchains_are_interposed() {
        let views = told(&[((2016, 2240), (4096, 4096)), ((2016, 2240), (4096, 4096))], 0.77);
        let ask = |w, h| Ask { width: w, height: h, sample_count: 1, face_count: 1, mip_count: 1, depth: false, protected: false };
        let p = plan(&ask(1552, 1725), &views).unwrap();
        assert_eq!((p.runtime, p.view), ((2016, 2240), (2016, 2240)));
        // The app's own render scale on top of the told size: scaled up by the same factors.
        let quarter = plan(&ask(388, 431), &views).unwrap();
        assert_eq!((quarter.runtime, quarter.view), ((504, 560), (504, 560)));
        assert_eq!(plan(&ask(3104, 1725), &views).unwrap().runtime, (4032, 2240));
        // Rounded by the engine to a multiple of 16.
        assert_eq!(plan(&ask(1552, 1728), &views).unwrap().runtime.0, 2016);
        assert_eq!(plan(&ask(512, 512), &views), Err(Skip::NotAViewSize));
        assert_eq!(plan(&Ask { depth: true, ..ask(1552, 1725) }, &views), Err(Skip::Depth));
        assert_eq!(plan(&Ask { sample_count: 4, ..ask(1552, 1725) }, &views).unwrap().runtime, (2016, 2240));
        assert_eq!(plan(&Ask { mip_count: 3, ..ask(1552, 1725) }, &views).unwrap().runtime, (2016, 2240));
        assert_eq!(plan(&Ask { sample_count: 4, mip_count: 3, ..ask(1552, 1725) }, &views), Err(Skip::MultisampledMips));
        assert_eq!(plan(&Ask { face_count: 6, ..ask(1552, 1725) }, &views), Err(Skip::Cube(6)));
        assert_eq!(plan(&ask(1552, 1725), &[]), Err(Skip::NoViews));
        let one = told(&[((1, 1), (1, 1))], 0.5);
        assert_eq!(plan(&ask(1, 1), &one), Err(Skip::Unscaled));
        assert_eq!(plan(&ask(2016, 2240), &told(&[((2016, 2240), (4096, 4096))], 1.0)), Err(Skip::Unscaled));
    }

    #[test]
    fn the_fovea_in_pixels() {
        let rect = PixelRect { x: 100, y: 0, width: 200, height: 100 };
        // A symmetric 90° view: the optical axis is the rect's centre; 45° reaches its edge.
        let e = fovea_ellipse([0.0, 0.0], 45.0, [-1.0, 1.0, 1.0, -1.0], rect);
        assert!((e[0] - 200.0).abs() < 1e-3 && (e[1] - 50.0).abs() < 1e-3, "{e:?}");
        assert!((e[2] - 100.0).abs() < 1e-3 && (e[3] - 50.0).abs() < 1e-3, "{e:?}");
        assert_eq!(fovea_ellipse([0.0, 0.0], 20.0, [1.0, -1.0, 1.0, -1.0], rect), [0.0; 4]);
        assert_eq!(fovea_ellipse([0.0, 0.0], 0.0, [-1.0, 1.0, 1.0, -1.0], rect), [0.0; 4]);
    }

    #[test]
    fn lod_bias_adds_within_the_safe_range() {
        assert_eq!(biased(0.0, -0.5), -0.5);
        assert_eq!(biased(-1.8, -0.5), -2.0);
        assert_eq!(biased(-3.0, -0.5), -3.0);
    }

    #[test]
    fn rects_of_other_layers_scale() {
        let k = (1.3, 1.3);
        assert_eq!(scaled_rect(PixelRect { x: 10, y: 0, width: 100, height: 50 }, k, (700, 700), (1000, 1000)), Some(PixelRect { x: 13, y: 0, width: 130, height: 65 }));
        assert_eq!(scaled_rect(PixelRect { x: 900, y: 0, width: 100, height: 50 }, k, (1000, 1000), (1000, 1000)), None);
        // The whole image maps to the whole runtime image (rounded up), not one pixel short.
        assert_eq!(scaled_rect(PixelRect { x: 0, y: 0, width: 98, height: 98 }, (1.2995, 1.2995), (98, 98), (128, 128)), Some(PixelRect { x: 0, y: 0, width: 128, height: 128 }));
        assert_eq!(clamp_to(PixelRect { x: -5, y: 0, width: 20, height: 20 }, (10, 10)), Some(PixelRect { x: 0, y: 0, width: 10, height: 10 }));
        assert_eq!(clamp_to(PixelRect { x: 20, y: 0, width: 20, height: 20 }, (10, 10)), None);
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
