//! `stereoshim preview --hmd`: which hidden-area mask the layer would use on this headset under
//! each kind of runtime. A runtime may hand over the headset's own mesh (SteamVR; Monado's driver
//! for a headset whose mesh it has), Monado's generic one (`u_visibility_mask_get_default`, the
//! four corners cut: what WiVRn's streamed headsets get) or none; the layer's choice in each case
//! is the mask feature's own rule (`mask::source::choose`, under the configured `mask.source`),
//! with the headset's published lens where the layer knows one. Pure: the answers are counted
//! per pixel at the preview's size.
#![forbid(unsafe_code)]

use crate::core::views::{MaskSource, ViewFov};
use crate::features::mask::{rules as mask_rules, source as mask_source};
use hmd_profiles::profile::{HmdProfile, Lens};

/// What a kind of runtime gives.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RuntimeMask {
    /// The headset's own mesh (here the profile's lens: published for the Index, an approximating
    /// ellipse for the others).
    HeadsetMesh,
    /// Monado's generic mask.
    MonadoGeneric,
    /// No `XR_KHR_visibility_mask`.
    None,
}

impl RuntimeMask {
    pub const ALL: [RuntimeMask; 3] = [RuntimeMask::HeadsetMesh, RuntimeMask::MonadoGeneric, RuntimeMask::None];
    pub fn name(self) -> &'static str {
        match self {
            RuntimeMask::HeadsetMesh => "headset_mesh",
            RuntimeMask::MonadoGeneric => "monado_generic",
            RuntimeMask::None => "none",
        }
    }
    /// Who gives it, in words.
    pub fn who(self) -> &'static str {
        match self {
            RuntimeMask::HeadsetMesh => "a runtime with the headset's own mesh (SteamVR, Monado's driver for it)",
            RuntimeMask::MonadoGeneric => "Monado's generic mask (WiVRn's streamed headsets)",
            RuntimeMask::None => "a runtime without XR_KHR_visibility_mask",
        }
    }
}

/// One view under one kind of runtime.
#[derive(Clone, Debug, PartialEq)]
pub struct Case {
    pub runtime: RuntimeMask,
    /// Hidden share of the view the runtime's own mask gives (None: it gives none).
    pub runtime_fraction: Option<f64>,
    /// What the layer uses, and its hidden share (None: no mask).
    pub used: Option<(MaskSource, f64)>,
}

/// Every kind of runtime for view `view` of `profile`, at `size` pixels, under `mask.source`'s
/// `policy` and the configured lens.
pub fn cases(profile: &HmdProfile, view: usize, fov: &ViewFov, size: (u32, u32), policy: mask_source::SourcePolicy, lens: &mask_source::LensShape) -> Vec<Case> {
    let share = |t: &[[f32; 2]]| -> f64 {
        let n = (size.0 as u64 * size.1 as u64).max(1);
        mask_rules::hidden_pixels(t, fov, size).map_or(0.0, |h| h.iter().filter(|b| **b).count() as f64 / n as f64)
    };
    let mesh: Vec<[f32; 2]> = hmd_profiles::mask::hidden_triangle_points(profile, view, 1.0).iter().map(|v| [v[0], v[1]]).collect();
    let published = matches!(profile.lens, Lens::LineLoop(_)).then(|| mesh.clone());
    RuntimeMask::ALL
        .iter()
        .map(|&runtime| {
            let given = match runtime {
                RuntimeMask::HeadsetMesh => Some(mesh.clone()),
                RuntimeMask::MonadoGeneric => Some(mask_source::generic(fov)),
                RuntimeMask::None => None,
            };
            let runtime_fraction = given.as_deref().map(share);
            let used = mask_source::choose(policy, given, published.clone(), lens).map(|(source, t)| (source, share(&t)));
            Case { runtime, runtime_fraction, used }
        })
        .collect()
}

/// `preview.json`'s `mask_sources`: per view, each kind of runtime, what it gives and what the
/// layer uses (hidden shares of the view at the preview's size).
pub fn report(profile: &HmdProfile, headset: &super::Headset, settings: &crate::plugin::settings::Settings) -> serde_json::Value {
    use serde_json::json;
    let (policy, lens) = mask_source::from_settings(settings.of::<crate::features::mask::MaskSettings>());
    let views: Vec<_> = headset
        .views
        .iter()
        .enumerate()
        .map(|(i, v)| {
            let rows: Vec<_> = cases(profile, i, &v.fov, (headset.width, headset.height), policy, &lens)
                .into_iter()
                .map(|c| {
                    json!({
                        "runtime": c.runtime.name(),
                        "who": c.runtime.who(),
                        "runtime_fraction": c.runtime_fraction,
                        "layer_uses": c.used.map(|u| source_name(u.0)),
                        "fraction": c.used.map(|u| u.1),
                    })
                })
                .collect();
            json!({ "view": i, "cases": rows })
        })
        .collect();
    json!({ "published_lens": matches!(profile.lens, Lens::LineLoop(_)), "lens_source": profile.lens_source, "views": views })
}

/// `mask_sources` in lines for a person (view 0; the other eye is its mirror image).
pub fn summary(r: &serde_json::Value) -> String {
    let pct = |v: &serde_json::Value| v.as_f64().map_or("none".to_string(), |f| format!("{:.1}% hidden", f * 100.0));
    let mut s = String::new();
    for c in r["views"][0]["cases"].as_array().into_iter().flatten() {
        s += &format!(
            "mask under {}: it gives {}; the layer uses {} ({})\n",
            c["who"].as_str().unwrap_or("?"),
            pct(&c["runtime_fraction"]),
            c["layer_uses"].as_str().unwrap_or("no mask"),
            pct(&c["fraction"])
        );
    }
    s
}

pub fn source_name(s: MaskSource) -> &'static str {
    match s {
        MaskSource::Runtime => "runtime",
        MaskSource::Synthesized => "synthesized",
        MaskSource::Headset => "headset",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fov_of(p: &HmdProfile, v: usize) -> ViewFov {
        let [l, r, u, d] = p.fov_rad(v);
        ViewFov { tan_left: l.tan(), tan_right: r.tan(), tan_up: u.tan(), tan_down: d.tan() }
    }

    /// On the Index the layer replaces Monado's generic corners (~3 %) by the published lens
    /// (~20 %+), and uses it where the runtime has none; on a headset without a published lens the
    /// generic mask is kept (an ellipse guessed by the layer is no better) and a runtime without a
    /// mask gets the configured lens shape.
    #[test]
    fn the_layer_uses_the_published_lens_over_a_generic_mask() {
        let (policy, lens) = (mask_source::SourcePolicy::Auto, mask_source::LensShape { horizontal_deg: 50.0, vertical_deg: 50.0 });
        let index = HmdProfile::by_name("index").unwrap();
        let c = cases(index, 0, &fov_of(index, 0), (200, 220), policy, &lens);
        assert!(mask_source::is_generic(&mask_source::generic(&fov_of(index, 0))), "the generic mask is recognised as such");
        let generic = &c[1];
        assert!(generic.runtime_fraction.unwrap() < 0.05, "{c:?}");
        let (source, used) = generic.used.unwrap();
        assert_eq!(source, MaskSource::Headset);
        assert!((used - c[0].runtime_fraction.unwrap()).abs() < 1e-9 && used > 0.15, "{c:?}");
        assert_eq!(c[0].used.map(|u| u.0), Some(MaskSource::Runtime));
        assert_eq!(c[2].used.map(|u| u.0), Some(MaskSource::Headset));
        let quest = HmdProfile::by_name("quest3").unwrap();
        let c = cases(quest, 1, &fov_of(quest, 1), (200, 200), policy, &lens);
        assert_eq!(c[1].used.map(|u| u.0), Some(MaskSource::Runtime), "no published lens: the generic mask stays");
        assert_eq!(c[2].used.map(|u| u.0), Some(MaskSource::Synthesized));
        // mask.source = runtime keeps whatever the runtime gives, and nothing without one.
        let c = cases(index, 0, &fov_of(index, 0), (200, 220), mask_source::SourcePolicy::Runtime, &lens);
        assert_eq!(c[1].used.map(|u| u.0), Some(MaskSource::Runtime));
        assert_eq!(c[2].used, None);
    }
}
