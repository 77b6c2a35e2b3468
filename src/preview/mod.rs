//! `stereoshim preview`: what the effective configuration would do on a headset, before it runs.
//! Every decision comes from the features' own pure rules (the mask's geometry and source choice,
//! the foveation rings, the VRS rate map, the RDM skip rule, the far field's split and pixel map),
//! evaluated for the headset's views at its recommended resolution; this module only collects
//! their answers per pixel and counts them. `draw` turns the answers into pictures.
#![forbid(unsafe_code)]

pub mod draw;
pub mod mask_sources;

use crate::features::views::ViewSettings;
use crate::features::upscale::UpscaleSettings;
use crate::features::mask::MaskSettings;
use crate::features::foveation::FoveationSettings;
use crate::features::far_field::FarFieldSettings;
use crate::core::fovea::Ring;
use crate::core::rect::PixelRect;
use crate::features::far_field::rules::{self as far_rules, PixelMap, ViewGeometry};
use crate::features::far_field::Shift;
use crate::features::foveation::rdm::rules::RdmParams;
use crate::features::foveation::rules::fovea_views;
use crate::features::foveation::vrs::rules::{self as vrs, EyeRates, FragmentSize};
use crate::features::mask::{rules as mask_rules, source as mask_source};
use crate::features::views::rules::{self as views_rules, Cut};
use crate::plugin::settings::Settings;
use crate::core::views::{MaskSource, ViewFov, ViewPose};

/// One view of the headset as a runtime reports it.
#[derive(Clone, Debug, PartialEq)]
pub struct View {
    pub fov: ViewFov,
    /// `t_head_view`: orientation (x, y, z, w) and position (metres).
    pub orientation: [f32; 4],
    pub position: [f32; 3],
    /// The runtime's hidden-area mesh expanded to three points per triangle (tangent plane);
    /// None: the runtime offers no visibility mask.
    pub hidden: Option<Vec<[f32; 2]>>,
}

/// The headset: its views and the image size each view is rendered at.
#[derive(Clone, Debug, PartialEq)]
pub struct Headset {
    /// The profile's name, or the runtime's system name.
    pub name: String,
    pub width: u32,
    pub height: u32,
    pub views: Vec<View>,
}

/// A rate map texel's size when none is given: 16×16 pixels, what most desktop GPUs report as
/// `minFragmentShadingRateAttachmentTexelSize` (others report 8×8; `--vrs-texel` changes it).
pub const DEFAULT_VRS_TEXEL: u32 = 16;

impl Headset {
    /// A profile of the shared headset data (the mock runtime serves the same), at `scale` times
    /// its recommended resolution. The hidden mesh is the runtime's indexed mesh, expanded by the
    /// mask source's own rule, as the layer receives it from `xrGetVisibilityMaskKHR`.
    pub fn from_profile(p: &hmd_profiles::profile::HmdProfile, scale: f64) -> Headset {
        let views = (0..2)
            .map(|v| {
                let [l, r, u, d] = p.fov_rad(v);
                let (position, orientation) = p.eye_in_head(v);
                let (hidden, _, _) = hmd_profiles::mask::build(p, v, 1.0);
                View {
                    fov: ViewFov { tan_left: l.tan(), tan_right: r.tan(), tan_up: u.tan(), tan_down: d.tan() },
                    orientation: orientation.to_array(),
                    position: position.to_array(),
                    hidden: Some(mask_source::expand(&hidden.vertices, &hidden.indices)),
                }
            })
            .collect();
        let (w, h) = scaled(p.recommended, scale);
        Headset { name: p.name.to_string(), width: w, height: h, views }
    }
}

/// `size` × `scale`, rounded, at least one pixel.
pub fn scaled(size: (u32, u32), scale: f64) -> (u32, u32) {
    let s = |v: u32| ((v as f64 * scale).round() as u32).max(1);
    (s(size.0), s(size.1))
}

/// VRS rate classes, finest first.
pub const RATES: [FragmentSize; 3] = [vrs::FULL, vrs::HALF, vrs::QUARTER];

/// A rate's name, `WxH` in pixels.
pub fn rate_name(r: FragmentSize) -> String {
    format!("{}x{}", r.width, r.height)
}

/// What the mask does to one view.
#[derive(Clone, Debug, PartialEq)]
pub struct MaskView {
    /// None: no mask (`mask.source = runtime` and the runtime has none).
    pub source: Option<MaskSource>,
    /// Row-major, one per pixel: the mask covers it.
    pub masked: Vec<bool>,
    pub pixels_masked: u64,
}

/// What VRS does to one view.
#[derive(Clone, Debug, PartialEq)]
pub struct VrsView {
    pub texel: u32,
    /// Row-major, one per pixel: index into `RATES`.
    pub rate: Vec<u8>,
    /// Pixels at each rate of `RATES`.
    pub pixels: [u64; 3],
    /// Fragments shaded at each rate (per map texel: the fragments of that size covering it).
    pub fragments: [u64; 3],
}

impl VrsView {
    /// Fragments not shaded at each rate, against shading every pixel.
    pub fn saved(&self) -> [u64; 3] {
        [0, 1, 2].map(|i| self.pixels[i] - self.fragments[i])
    }
}

/// What RDM does to one view.
#[derive(Clone, Debug, PartialEq)]
pub struct RdmView {
    /// Row-major, one per pixel: its quad's ring (0 inner, 1 middle, 2 outer) and whether the
    /// layer skips it.
    pub ring: Vec<u8>,
    pub skipped: Vec<bool>,
    pub quads: u64,
    pub quads_skipped: u64,
    pub pixels_skipped: u64,
}

/// What the far field does to one view.
#[derive(Clone, Debug, PartialEq)]
pub struct FarFieldView {
    /// The view renders everything (and is copied), or is the one that reuses.
    pub destination: bool,
    /// Row-major, one per pixel: the destination pixel reuses the source's where the scene there
    /// lies beyond the split.
    pub reusable: Vec<bool>,
    pub pixels_reusable: u64,
}

/// Everything the preview found for one view.
#[derive(Clone, Debug, PartialEq)]
pub struct ViewPreview {
    pub mask: MaskView,
    pub vrs: VrsView,
    pub rdm: Option<RdmView>,
    pub far_field: FarFieldView,
}

/// The whole preview.
#[derive(Clone, Debug, PartialEq)]
pub struct Preview {
    pub width: u32,
    pub height: u32,
    pub views: Vec<ViewPreview>,
    /// The far field's split distance, metres (infinite: nothing is far enough).
    pub split_m: f64,
    pub split_px: f64,
    /// Per view, the FOV cut (`view.fov_cut = lens`) on this image's grid, from the runtime's
    /// hidden mesh (None: no mesh, nothing visible); every view one size, as the layer makes it.
    pub cuts: Vec<Option<Cut>>,
}

/// Options that are not configuration keys.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Options {
    /// `far_field.split_px` overridden (`--split-px`).
    pub split_px: Option<f64>,
    pub vrs_texel: u32,
}

impl Default for Options {
    fn default() -> Self {
        Options { split_px: None, vrs_texel: DEFAULT_VRS_TEXEL }
    }
}

/// Runs every feature's rules over every view of `headset`.
pub fn compute(headset: &Headset, settings: &Settings, options: &Options) -> Preview {
    let (w, h) = (headset.width, headset.height);
    let rect = PixelRect { x: 0, y: 0, width: w, height: h };
    let (policy, lens) = mask_source::from_settings(settings.of::<MaskSettings>());
    // Fixed foveation (no gaze in a preview): every centre on the optical axis.
    let foveae = fovea_views(&vec![[0.0, 0.0]; headset.views.len()], settings.of::<FoveationSettings>().rings);
    let ff = &settings.of::<FarFieldSettings>();
    let split_px = options.split_px.unwrap_or(ff.split_px);
    let geometry: Vec<ViewGeometry> = headset.views.iter().map(|v| ViewGeometry::of(&pose(v), rect)).collect();
    let source = (ff.source_view as usize).min(geometry.len().saturating_sub(1));
    let split_m = match geometry.len() {
        2 => far_rules::split_distance(split_px, ff.split_m, &geometry[0], &geometry[1]),
        _ => f64::INFINITY,
    };
    let views = headset
        .views
        .iter()
        .enumerate()
        .map(|(i, v)| {
            let mask = mask_view(v, policy, &lens, rect);
            let eye = EyeRates { layer: 0, rect, fov: v.fov, fovea: foveae[i] };
            let vrs = vrs_view(&eye, options.vrs_texel.max(1));
            let rdm = RdmParams::new(&v.fov, &foveae[i], rect).map(|p| rdm_view(&p));
            let destination = geometry.len() == 2 && i != source;
            let far_field = if destination {
                far_field_view(&PixelMap::new(&geometry[source], &geometry[i]), ff.shift, split_m, w, h)
            } else {
                FarFieldView { destination: false, reusable: vec![false; rect.area() as usize], pixels_reusable: 0 }
            };
            ViewPreview { mask, vrs, rdm, far_field }
        })
        .collect();
    let cuts = fov_cuts(headset, settings.of::<ViewSettings>().fov_cut_margin_deg);
    Preview { width: w, height: h, views, split_m, split_px, cuts }
}

/// The FOV cut of every view (`features::views::rules`), from the runtime's hidden meshes as the
/// layer decides it; none at all when a view has no mesh.
fn fov_cuts(headset: &Headset, margin_deg: f64) -> Vec<Option<Cut>> {
    let size = (headset.width, headset.height);
    let lenses: Option<Vec<_>> = headset
        .views
        .iter()
        .map(|v| {
            let fov = views_rules::Fov { left: v.fov.tan_left as f64, right: v.fov.tan_right as f64, up: v.fov.tan_up as f64, down: v.fov.tan_down as f64 };
            Some((fov, size, mask_rules::hidden_pixels(v.hidden.as_ref()?, &v.fov, size)?))
        })
        .collect();
    match lenses.and_then(|l| views_rules::cuts(&l, margin_deg)) {
        Some(c) => c.into_iter().map(Some).collect(),
        None => vec![None; headset.views.len()],
    }
}

fn pose(v: &View) -> ViewPose {
    ViewPose { orientation: v.orientation, position: v.position, fov: v.fov }
}

fn mask_view(v: &View, policy: mask_source::SourcePolicy, lens: &mask_source::LensShape, rect: PixelRect) -> MaskView {
    // The headset's own lens is what `--hmd` shows as the runtime's mask already.
    match mask_source::choose(policy, v.hidden.clone(), None, lens) {
        Some((source, triangles)) => {
            let ndc = mask_rules::triangles_to_ndc(&triangles, &v.fov);
            let (_, masked) = mask_rules::coverage_bitmap(&ndc, rect.viewport(), rect);
            let pixels_masked = masked.iter().filter(|&&b| b).count() as u64;
            MaskView { source: Some(source), masked, pixels_masked }
        }
        None => MaskView { source: None, masked: vec![false; rect.area() as usize], pixels_masked: 0 },
    }
}

fn vrs_view(eye: &EyeRates, texel: u32) -> VrsView {
    let (w, h) = (eye.rect.width, eye.rect.height);
    let (tw, th) = (vrs::texels(w, texel), vrs::texels(h, texel));
    let map = vrs::rate_layer(tw, th, texel, texel, 0, std::slice::from_ref(eye));
    let class = |t: u8| RATES.iter().position(|r| *r == vrs::decode(t)).unwrap_or(0) as u8;
    let mut rate = vec![0u8; (w * h) as usize];
    let (mut pixels, mut fragments) = ([0u64; 3], [0u64; 3]);
    for ty in 0..th {
        for tx in 0..tw {
            let c = class(map[(ty * tw + tx) as usize]);
            let (x0, y0) = (tx * texel, ty * texel);
            let (x1, y1) = ((x0 + texel).min(w), (y0 + texel).min(h));
            let f = RATES[c as usize];
            pixels[c as usize] += ((x1 - x0) * (y1 - y0)) as u64;
            // Fragments of a rate tile the texel from its corner (texels are multiples of every
            // fragment size); a clipped texel still shades its partial fragments.
            fragments[c as usize] += ((x1 - x0).div_ceil(f.width) * (y1 - y0).div_ceil(f.height)) as u64;
            for y in y0..y1 {
                rate[(y * w + x0) as usize..(y * w + x1) as usize].fill(c);
            }
        }
    }
    VrsView { texel, rate, pixels, fragments }
}

fn rdm_view(p: &RdmParams) -> RdmView {
    let (w, h) = (p.rect.width, p.rect.height);
    let mut ring = vec![0u8; (w * h) as usize];
    let mut skipped = vec![false; (w * h) as usize];
    for y in 0..h {
        for x in 0..w {
            let i = (y * w + x) as usize;
            ring[i] = match p.ring(x / 2, y / 2) {
                Ring::Inner => 0,
                Ring::Middle => 1,
                Ring::Outer => 2,
            };
            skipped[i] = p.pixel_skipped(p.rect.x + x as i32, p.rect.y + y as i32);
        }
    }
    let n = p.count(p.rect);
    RdmView { ring, skipped, quads: n.quads, quads_skipped: n.quads_skipped, pixels_skipped: n.pixels_skipped }
}

fn far_field_view(map: &PixelMap, shift: Shift, split_m: f64, w: u32, h: u32) -> FarFieldView {
    // Directions only, or shifted by the disparity of the nearest depth that still counts as far.
    let inv_z = match shift {
        Shift::Infinity => 0.0,
        Shift::Depth if split_m.is_finite() && split_m > 0.0 => 1.0 / split_m,
        Shift::Depth => 0.0,
    };
    let mut reusable = vec![false; (w * h) as usize];
    for y in 0..h {
        for x in 0..w {
            reusable[(y * w + x) as usize] = split_m.is_finite() && far_rules::footprint_inside(map, x, y, inv_z, w, h);
        }
    }
    let pixels_reusable = reusable.iter().filter(|&&b| b).count() as u64;
    FarFieldView { destination: true, reusable, pixels_reusable }
}

/// The preview's numbers as JSON (`preview.json`; `pngs` names each view's pictures).
pub fn report(headset: &Headset, settings: &Settings, p: &Preview, pngs: &dyn Fn(&str, usize) -> String) -> serde_json::Value {
    use serde_json::json;
    let area = p.width as u64 * p.height as u64;
    let frac = |n: u64| if area == 0 { 0.0 } else { n as f64 / area as f64 };
    let views: Vec<_> = p
        .views
        .iter()
        .enumerate()
        .map(|(i, v)| {
            let fov = &headset.views[i].fov;
            let per_rate = |a: [u64; 3]| {
                let mut m = serde_json::Map::new();
                for (r, n) in RATES.iter().zip(a) {
                    m.insert(rate_name(*r), n.into());
                }
                serde_json::Value::Object(m)
            };
            let fractions = {
                let mut m = serde_json::Map::new();
                for (r, n) in RATES.iter().zip(v.vrs.pixels) {
                    m.insert(rate_name(*r), frac(n).into());
                }
                serde_json::Value::Object(m)
            };
            json!({
                "view": i,
                "fov": { "tan_left": fov.tan_left, "tan_right": fov.tan_right, "tan_up": fov.tan_up, "tan_down": fov.tan_down },
                "pixels": area,
                "mask": {
                    "source": v.mask.source.map(|s| match s { MaskSource::Runtime => "runtime", MaskSource::Synthesized => "synthesized", MaskSource::Headset => "headset" }),
                    "pixels_masked": v.mask.pixels_masked,
                    "fraction": frac(v.mask.pixels_masked),
                    "png": pngs("mask", i),
                },
                "vrs": {
                    "texel": v.vrs.texel,
                    "pixels": per_rate(v.vrs.pixels),
                    "fractions": fractions,
                    "fragments": per_rate(v.vrs.fragments),
                    "fragments_saved": per_rate(v.vrs.saved()),
                    "fragments_saved_total": v.vrs.saved().iter().sum::<u64>(),
                    "png": pngs("vrs", i),
                },
                "rdm": v.rdm.as_ref().map(|r| json!({
                    "quads": r.quads,
                    "quads_skipped": r.quads_skipped,
                    "pixels_skipped": r.pixels_skipped,
                    "skipped_fraction": frac(r.pixels_skipped),
                    "png": pngs("rdm", i),
                })),
                "far_field": {
                    "role": if v.far_field.destination { "destination" } else { "source" },
                    "pixels_reusable": v.far_field.pixels_reusable,
                    "share": frac(v.far_field.pixels_reusable),
                    "png": pngs("far_field", i),
                },
                "fov_cut": p.cuts.get(i).copied().flatten().map(|c| json!({
                    "x0": c.x0, "x1": c.x1, "y0": c.y0, "y1": c.y1,
                    "width": c.size().0, "height": c.size().1,
                    "saved_fraction": c.saved_share((p.width, p.height)),
                    "png": pngs("fov_cut", i),
                })),
            })
        })
        .collect();
    let rings = settings.of::<FoveationSettings>().rings;
    // The upscale's sizes: what the app would be told, its pixels and the display's.
    let up = &settings.of::<UpscaleSettings>();
    let told = crate::features::upscale::rules::render_size((p.width, p.height), (up.scale, up.scale), (u32::MAX, u32::MAX));
    let (rendered, display) = (told.0 as u64 * told.1 as u64, area);
    let upscale = json!({
        "scale": up.scale,
        "method": format!("{:?}", up.method),
        "told": [told.0, told.1],
        "rendered_px": rendered,
        "display_px": display,
        "rendered_fraction": if display == 0 { 0.0 } else { rendered as f64 / display as f64 },
        "mip_bias": up.sampler_bias(),
    });
    json!({
        "headset": headset.name,
        "width": p.width,
        "height": p.height,
        "enabled": {
            "mask": settings.of::<MaskSettings>().enabled,
            "foveation": settings.of::<FoveationSettings>().enabled,
            "far_field": settings.of::<FarFieldSettings>().enabled,
            "upscale": settings.of::<UpscaleSettings>().enabled,
            "fov_cut": settings.of::<ViewSettings>().fov_cut,
        },
        "upscale": upscale,
        "foveation": { "inner_deg": rings.inner_deg, "middle_deg": rings.middle_deg, "center": "optical axis (fixed foveation)" },
        "far_field": {
            "split_px": p.split_px,
            "split_m": if p.split_m.is_finite() { json!(p.split_m) } else { json!(null) },
            "shift": match settings.of::<FarFieldSettings>().shift { Shift::Infinity => "infinity", Shift::Depth => "depth" },
            "source_view": settings.of::<FarFieldSettings>().source_view,
        },
        "legend": draw::legend_json(),
        "views": views,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::config::{Config, Inputs};

    fn settings(env: &dyn Fn(&str) -> Option<String>) -> Settings {
        let (c, d) = Config::resolve(&Inputs { keys: crate::registry::keys(), file: None, app_names: &[], env });
        assert!(d.is_empty(), "{d:?}");
        Settings::from_config(&c)
    }

    fn simple(scale: f64) -> Headset {
        Headset::from_profile(hmd_profiles::profile::HmdProfile::by_name("simple").unwrap(), scale)
    }

    #[test]
    fn the_upscale_counts_the_told_pixels() {
        let h = simple(0.125);
        let env = |k: &str| match k {
            "STEREOSHIM_UPSCALE_ENABLED" => Some("true".to_string()),
            "STEREOSHIM_UPSCALE_SCALE" => Some("0.7".to_string()),
            _ => None,
        };
        let s = settings(&env);
        let r = report(&h, &s, &compute(&h, &s, &Options::default()), &|_, _| String::new());
        assert_eq!(r["enabled"]["upscale"], true);
        assert_eq!(r["upscale"]["told"], serde_json::json!([90, 90]));
        assert_eq!(r["upscale"]["rendered_px"], 8100);
        assert_eq!(r["upscale"]["display_px"], 128 * 128);
        assert!((r["upscale"]["mip_bias"].as_f64().unwrap() - 0.7f64.log2()).abs() < 1e-6);
    }

    #[test]
    fn the_fov_cut_as_the_layer_decides_it() {
        // The Index's published mask at a quarter of its size: as tests/features/views.rs measures with
        // the mock runtime (484x560 of 504x560, view 1 from pixel 16).
        let h = Headset::from_profile(hmd_profiles::profile::HmdProfile::by_name("index").unwrap(), 0.25);
        let s = settings(&|k| (k == "STEREOSHIM_VIEW_FOV_CUT").then(|| "lens".to_string()));
        let p = compute(&h, &s, &Options::default());
        let cuts: Vec<Cut> = p.cuts.iter().map(|c| c.expect("a cut per view")).collect();
        assert_eq!(cuts.iter().map(|c| (c.x0, c.x1, c.y0, c.y1)).collect::<Vec<_>>(), vec![(0, 484, 0, 560), (16, 500, 0, 560)]);
        let r = report(&h, &s, &p, &|f, i| format!("{f}-{i}.png"));
        assert_eq!(r["enabled"]["fov_cut"], true);
        assert_eq!((r["views"][1]["fov_cut"]["width"].clone(), r["views"][1]["fov_cut"]["png"].clone()), (serde_json::json!(484), serde_json::json!("fov_cut-1.png")));
        let pictures = draw::view_pictures(&p, 1, &draw::Canvas::grid(p.width, p.height, &h.views[1].fov));
        let (_, cut) = pictures.iter().find(|(f, _)| *f == "fov_cut").expect("a picture of the cut");
        // The columns left of the cut are painted, those inside are not.
        let painted = |x: u32, y: u32| cut.pixels[(y * cut.width + x) as usize] == draw::blend(draw::GRID_BACKGROUND, &draw::CUT_OFF);
        assert!(painted(3, 200) && !painted(250, 201));
        // Without a mesh, no cut.
        let mut bare = h.clone();
        bare.views[0].hidden = None;
        assert!(compute(&bare, &s, &Options::default()).cuts.iter().all(Option::is_none));
    }

    #[test]
    fn numbers_are_the_rules_own() {
        let h = simple(0.125);
        assert_eq!((h.width, h.height), (128, 128));
        let s = settings(&|_| None);
        let p = compute(&h, &s, &Options::default());
        assert_eq!(p.views.len(), 2);
        let rect = PixelRect { x: 0, y: 0, width: 128, height: 128 };
        for (i, v) in p.views.iter().enumerate() {
            // The runtime's mesh (auto), counted by the mask rules directly.
            let tris = h.views[i].hidden.clone().unwrap();
            assert_eq!(v.mask.source, Some(MaskSource::Runtime));
            assert_eq!(v.mask.pixels_masked, mask_rules::masked_pixels(&tris, &h.views[i].fov, rect));
            // The circle of 45° (per axis, in angle space) inscribed in the ±45° frustum hides its
            // corners: more than the tangent-plane circle's 1 − π/4, as the outline's diagonal
            // points lie at tan 31.8° per axis, inside the unit circle.
            let f = v.mask.pixels_masked as f64 / rect.area() as f64;
            assert!((0.25..0.40).contains(&f), "{f}");
            // RDM equals the rule's own count.
            let fovea = fovea_views(&[[0.0, 0.0]], s.of::<FoveationSettings>().rings)[0];
            let n = RdmParams::new(&h.views[i].fov, &fovea, rect).unwrap().count(rect);
            let r = v.rdm.as_ref().unwrap();
            assert_eq!((r.quads_skipped, r.pixels_skipped), (n.quads_skipped, n.pixels_skipped));
            assert_eq!(r.skipped.iter().filter(|&&b| b).count() as u64, n.pixels_skipped);
            // VRS: every pixel has one rate; full rate at the centre, quarter at the corner.
            assert_eq!(v.vrs.pixels.iter().sum::<u64>(), rect.area());
            assert_eq!(v.vrs.rate[(64 * 128 + 64) as usize], 0);
            assert_eq!(v.vrs.rate[0], 2);
            assert_eq!(v.vrs.saved()[0], 0);
            assert_eq!(v.vrs.saved()[2], v.vrs.pixels[2] * 3 / 4, "16-pixel texels hold whole 2×2 fragments");
        }
        // The far field: view 1 reuses; parallel views overlap almost entirely.
        assert!(!p.views[0].far_field.destination && p.views[0].far_field.pixels_reusable == 0);
        let share = p.views[1].far_field.pixels_reusable as f64 / rect.area() as f64;
        assert!(share > 0.9, "{share}");
        assert!(p.split_m > 1.0 && p.split_m.is_finite());
    }

    #[test]
    fn config_changes_the_answers() {
        let s = settings(&|k| match k {
            "STEREOSHIM_MASK_SOURCE" => Some("synthesized".into()),
            "STEREOSHIM_MASK_SYNTHESIZED_RADIUS_DEG" => Some("30".into()),
            "STEREOSHIM_FOVEATION_PRESET" => Some("aggressive".into()),
            _ => None,
        });
        let h = simple(0.125);
        let p = compute(&h, &s, &Options { split_px: Some(4.0), vrs_texel: 8 });
        let v = &p.views[0];
        assert_eq!(v.mask.source, Some(MaskSource::Synthesized));
        let (_, lens) = mask_source::from_settings(s.of::<MaskSettings>());
        let rect = PixelRect { x: 0, y: 0, width: 128, height: 128 };
        assert_eq!(v.mask.pixels_masked, mask_rules::masked_pixels(&lens.hidden_triangles(), &h.views[0].fov, rect));
        let base = compute(&h, &settings(&|_| None), &Options::default());
        assert!(v.mask.pixels_masked > base.views[0].mask.pixels_masked, "a 30° lens hides more");
        assert!(v.vrs.pixels[0] < base.views[0].vrs.pixels[0], "aggressive rings: less at full rate");
        assert_eq!(v.vrs.texel, 8);
        assert!((p.split_m - base.split_m / 4.0).abs() < 1e-9 * base.split_m);
        // No runtime mask and `runtime` only: no mask at all.
        let mut none = h.clone();
        none.views.iter_mut().for_each(|v| v.hidden = None);
        let only_runtime = settings(&|k| (k == "STEREOSHIM_MASK_SOURCE").then(|| "runtime".into()));
        let q = compute(&none, &only_runtime, &Options::default());
        assert_eq!((q.views[0].mask.source, q.views[0].mask.pixels_masked), (None, 0));
    }

    #[test]
    fn canted_views_reuse_less() {
        let s = settings(&|_| None);
        let pimax = Headset::from_profile(hmd_profiles::profile::HmdProfile::by_name("pimax").unwrap(), 0.03);
        let p = compute(&pimax, &s, &Options::default());
        let area = (p.width * p.height) as f64;
        let share = p.views[1].far_field.pixels_reusable as f64 / area;
        // 20° between the views of a ~115° frustum: a large part of each has no counterpart.
        assert!((0.3..0.9).contains(&share), "{share}");
    }
}
