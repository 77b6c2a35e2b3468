//! The hidden-area mask on the OpenXR side: each view's hidden triangles — the runtime's
//! `XR_KHR_visibility_mask` mesh or a synthesized lens (`source`) — published for the
//! Vulkan half at `xrBeginFrame` whenever they are due: at the start, after the runtime says they
//! changed, and after a config reload that touched `mask.*`.

use crate::features::mask::MaskSettings;
use super::source as mask_source;
use crate::plugin::settings::Settings;
use crate::core::views::ViewMask;
use crate::plugin::xr::{settings, Instance, Session, XrFeature, VISIBILITY_MASK_EXT};
use openxr_sys as xr;
use std::sync::atomic::{AtomicBool, Ordering};

/// Views of `XR_VIEW_CONFIGURATION_TYPE_PRIMARY_STEREO`, the only configuration masks are kept for.
const STEREO_VIEWS: u32 = 2;

/// The mask's OpenXR half (stateless; per-session state is `MaskSession`).
pub(crate) struct MaskXr;

/// The mask's per-session state.
#[derive(Debug)]
pub(crate) struct MaskSession {
    /// The masks must be (re)fetched.
    pub dirty: AtomicBool,
}

impl Default for MaskSession {
    fn default() -> Self {
        MaskSession { dirty: AtomicBool::new(true) }
    }
}

impl XrFeature for MaskXr {
    fn id(&self) -> &'static str {
        "mask"
    }
    /// Whenever the layer is on, not only when the mask is on now: the mask can be switched on
    /// while the app runs, and the extension cannot be enabled later.
    fn wanted_extensions(&self, s: &Settings) -> Vec<&'static str> {
        if s.enabled {
            vec![VISIBILITY_MASK_EXT]
        } else {
            Vec::new()
        }
    }
    fn frame_begun(&self, s: &Session) {
        refresh_masks(s);
    }
    /// `XrEventDataVisibilityMaskChangedKHR`: refetch; the app sees the event only if it enabled
    /// the extension itself.
    fn event(&self, inst: &Instance, event: &xr::EventDataBuffer) -> bool {
        if event.ty != xr::StructureType::EVENT_DATA_VISIBILITY_MASK_CHANGED_KHR {
            return false;
        }
        // SAFETY: `ty` says the buffer holds this struct (it fits in XrEventDataBuffer).
        let e = unsafe { &*(event as *const xr::EventDataBuffer as *const xr::EventDataVisibilityMaskChangedKHR) };
        inst.stats.visibility_mask_events.fetch_add(1, Ordering::Relaxed);
        tracing::info!("visibility mask of view {} changed", e.view_index);
        if let Some(s) = Session::find(e.session) {
            s.feature::<MaskSession>().dirty.store(true, Ordering::Release);
        }
        !inst.app_enabled(VISIBILITY_MASK_EXT)
    }
    /// The lens the layer knows — the headset's published one where the runtime names a headset
    /// it has one of, else the synthesized lens (`mask.synthesized.*`) —, whether or not the
    /// layer's own mask is on: an app that draws the hidden area itself gets it where the runtime
    /// has none.
    fn offered_visibility_mask(&self, inst: &Instance, s: Option<&Session>, view: u32, ty: xr::VisibilityMaskTypeKHR) -> Option<Vec<[f32; 2]>> {
        if let Some(p) = s.and_then(published_lens) {
            let (hidden, visible, line) = hmd_profiles::mask::build(p, view as usize, 1.0);
            let mesh = match ty {
                xr::VisibilityMaskTypeKHR::HIDDEN_TRIANGLE_MESH => hidden,
                xr::VisibilityMaskTypeKHR::VISIBLE_TRIANGLE_MESH => visible,
                xr::VisibilityMaskTypeKHR::LINE_LOOP => line,
                _ => return None,
            };
            return Some(mesh.indices.iter().filter_map(|&i| mesh.vertices.get(i as usize).map(|v| [v[0], v[1]])).collect());
        }
        let settings = settings(inst);
        let (_, lens) = mask_source::from_settings(settings.of::<MaskSettings>());
        match ty {
            xr::VisibilityMaskTypeKHR::HIDDEN_TRIANGLE_MESH => Some(lens.hidden_triangles()),
            xr::VisibilityMaskTypeKHR::VISIBLE_TRIANGLE_MESH => Some(lens.visible_triangles()),
            xr::VisibilityMaskTypeKHR::LINE_LOOP => Some(lens.outline()),
            _ => None,
        }
    }
    fn config_reloaded(&self, s: &Session, changed: &[&'static str]) {
        if changed.iter().any(|k| k.starts_with("mask.")) {
            s.feature::<MaskSession>().dirty.store(true, Ordering::Release);
        }
    }
}

/// The headset the runtime names, if the layer knows its published lens (an approximating
/// ellipse is no better than what the runtime says).
fn published_lens(s: &Session) -> Option<&'static hmd_profiles::profile::HmdProfile> {
    s.instance.system_name(s.system_id).and_then(|n| crate::core::hmd::profile_for(&n)).filter(|p| matches!(p.lens, hmd_profiles::profile::Lens::LineLoop(_)))
}

/// (Re)publishes the hidden-area masks of all views when they are due.
fn refresh_masks(s: &Session) {
    let settings = settings(&s.instance);
    if !settings.of::<MaskSettings>().enabled || !s.feature::<MaskSession>().dirty.swap(false, Ordering::AcqRel) {
        return;
    }
    let (policy, lens) = mask_source::from_settings(settings.of::<MaskSettings>());
    let profile = published_lens(s);
    let mut masks = Vec::new();
    for view in 0..STEREO_VIEWS {
        let headset = profile.map(|p| hmd_profiles::mask::hidden_triangle_points(p, view as usize, 1.0).iter().map(|v| [v[0], v[1]]).collect());
        let runtime = s.runtime_mask(view);
        if runtime.as_deref().is_some_and(mask_source::is_generic) {
            tracing::info!("view {view}: the runtime's hidden-area mask is Monado's generic one (the four corners cut), not the lens; {}", match profile {
                Some(p) => format!("the layer knows the {} lens ({})", p.name, p.lens_source),
                None => "the layer knows no published lens for this headset".to_string(),
            });
        }
        match mask_source::choose(policy, runtime, headset, &lens) {
            Some((source, triangles)) => {
                tracing::info!("view {view}: hidden-area mask from {source:?}, {} triangles", triangles.len() / 3);
                masks.push(ViewMask { view, source, triangles });
            }
            None => tracing::info!("view {view}: no hidden-area mask (mask.source = runtime and the runtime has none)"),
        }
    }
    crate::bridge::shared().update_views(Some(masks), None);
}
