//! The upscale's view of a frame's composition layers: each layer's sub-images (which swapchain,
//! which rect, which projection view with its angles), and the frame handed down with every
//! interposed sub-image's rect in the runtime image's pixels (the app's structs copied, never
//! written).

use crate::core::rect::PixelRect;
use crate::plugin::xr::AmendedFrameEnd;
use openxr_sys as xr;

/// An OpenXR rect as pixels (a negative extent as empty).
pub(super) fn pixel_rect(r: &xr::Rect2Di) -> PixelRect {
    PixelRect { x: r.offset.x, y: r.offset.y, width: r.extent.width.max(0) as u32, height: r.extent.height.max(0) as u32 }
}

/// Pixels as an OpenXR rect.
fn xr_rect(r: PixelRect) -> xr::Rect2Di {
    xr::Rect2Di { offset: xr::Offset2Di { x: r.x, y: r.y }, extent: xr::Extent2Di { width: r.width as i32, height: r.height as i32 } }
}

/// A sub-image of a frame's layer, with its view index and angles when it is a projection view.
pub(super) type SubImage = (xr::SwapchainSubImage, Option<(u32, xr::Fovf)>);

/// A layer's sub-images, whether they are projection views.
///
/// # Safety
/// `layer` points to a valid composition layer of the app's frame.
pub(super) unsafe fn sub_images(layer: *const xr::CompositionLayerBaseHeader) -> Option<(bool, Vec<SubImage>)> {
    // SAFETY: per the contract; the type tells the layout.
    unsafe {
        let base = layer.as_ref()?;
        let one = |s: xr::SwapchainSubImage| vec![(s, None)];
        Some(match base.ty {
            xr::StructureType::COMPOSITION_LAYER_PROJECTION => {
                let p = &*(layer as *const xr::CompositionLayerProjection);
                (true, crate::plugin::vk::convert::slice(p.views, p.view_count).iter().enumerate().map(|(i, v)| (v.sub_image, Some((i as u32, v.fov)))).collect())
            }
            xr::StructureType::COMPOSITION_LAYER_QUAD => (false, one((*(layer as *const xr::CompositionLayerQuad)).sub_image)),
            xr::StructureType::COMPOSITION_LAYER_CYLINDER_KHR => (false, one((*(layer as *const xr::CompositionLayerCylinderKHR)).sub_image)),
            xr::StructureType::COMPOSITION_LAYER_EQUIRECT_KHR => (false, one((*(layer as *const xr::CompositionLayerEquirectKHR)).sub_image)),
            xr::StructureType::COMPOSITION_LAYER_EQUIRECT2_KHR => (false, one((*(layer as *const xr::CompositionLayerEquirect2KHR)).sub_image)),
            _ => return None,
        })
    }
}

/// The frame with every interposed sub-image's rect mapped to the runtime's image.
/// `rect_of(swapchain, rect, projection)` is a sub-image's new rect (None: unchanged).
pub(super) fn rewrite(info: &xr::FrameEndInfo, layers: &[*const xr::CompositionLayerBaseHeader], rect_of: &dyn Fn(xr::Swapchain, PixelRect, bool) -> Option<PixelRect>) -> AmendedFrameEnd {
    // Boxed: the pointers handed down must not move while later layers are pushed.
    #[allow(clippy::vec_box)]
    struct Keep {
        projections: Vec<Box<xr::CompositionLayerProjection>>,
        views: Vec<Vec<xr::CompositionLayerProjectionView>>,
        quads: Vec<Box<xr::CompositionLayerQuad>>,
        cylinders: Vec<Box<xr::CompositionLayerCylinderKHR>>,
        equirects: Vec<Box<xr::CompositionLayerEquirectKHR>>,
        equirects2: Vec<Box<xr::CompositionLayerEquirect2KHR>>,
        layers: Vec<*const xr::CompositionLayerBaseHeader>,
    }
    let map = |sub: &mut xr::SwapchainSubImage, projection: bool| {
        if let Some(dst) = rect_of(sub.swapchain, pixel_rect(&sub.image_rect), projection) {
            sub.image_rect = xr_rect(dst);
        }
    };
    let mut keep = Keep { projections: Vec::new(), views: Vec::new(), quads: Vec::new(), cylinders: Vec::new(), equirects: Vec::new(), equirects2: Vec::new(), layers: Vec::new() };
    for &l in layers {
        // SAFETY: the app's layers, valid for this call; each copied by its type.
        let out: *const xr::CompositionLayerBaseHeader = unsafe {
            match l.as_ref().map(|b| b.ty) {
                Some(xr::StructureType::COMPOSITION_LAYER_PROJECTION) => {
                    let mut p = Box::new(*(l as *const xr::CompositionLayerProjection));
                    let mut views = crate::plugin::vk::convert::slice(p.views, p.view_count).to_vec();
                    for v in &mut views {
                        map(&mut v.sub_image, true);
                    }
                    p.views = views.as_ptr();
                    keep.views.push(views);
                    let ptr = (&*p as *const xr::CompositionLayerProjection).cast();
                    keep.projections.push(p);
                    ptr
                }
                Some(xr::StructureType::COMPOSITION_LAYER_QUAD) => {
                    let mut q = Box::new(*(l as *const xr::CompositionLayerQuad));
                    map(&mut q.sub_image, false);
                    let ptr = (&*q as *const xr::CompositionLayerQuad).cast();
                    keep.quads.push(q);
                    ptr
                }
                Some(xr::StructureType::COMPOSITION_LAYER_CYLINDER_KHR) => {
                    let mut c = Box::new(*(l as *const xr::CompositionLayerCylinderKHR));
                    map(&mut c.sub_image, false);
                    let ptr = (&*c as *const xr::CompositionLayerCylinderKHR).cast();
                    keep.cylinders.push(c);
                    ptr
                }
                Some(xr::StructureType::COMPOSITION_LAYER_EQUIRECT_KHR) => {
                    let mut e = Box::new(*(l as *const xr::CompositionLayerEquirectKHR));
                    map(&mut e.sub_image, false);
                    let ptr = (&*e as *const xr::CompositionLayerEquirectKHR).cast();
                    keep.equirects.push(e);
                    ptr
                }
                Some(xr::StructureType::COMPOSITION_LAYER_EQUIRECT2_KHR) => {
                    let mut e = Box::new(*(l as *const xr::CompositionLayerEquirect2KHR));
                    map(&mut e.sub_image, false);
                    let ptr = (&*e as *const xr::CompositionLayerEquirect2KHR).cast();
                    keep.equirects2.push(e);
                    ptr
                }
                _ => l,
            }
        };
        keep.layers.push(out);
    }
    let keep = Box::new(keep);
    let info = xr::FrameEndInfo { layer_count: keep.layers.len() as u32, layers: if keep.layers.is_empty() { info.layers } else { keep.layers.as_ptr() }, ..*info };
    AmendedFrameEnd { info, _keep: keep }
}
