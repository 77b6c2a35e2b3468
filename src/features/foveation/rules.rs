//! Where the fovea is and how large: ring sizes from presets or explicit angles, and the gaze
//! policy (smoothing, blinks, loss of tracking) that turns raw eye-tracker samples into a centre
//! the rate maps can follow without flicker. Pure; the OpenXR shell feeds it samples.
#![forbid(unsafe_code)]

use crate::core::config::Config;
use crate::core::fovea::{angle_between_deg, Tangent};
use crate::core::views::FoveaView;

/// Full-rate radius and half-rate outer radius, degrees.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rings {
    pub inner_deg: f32,
    pub middle_deg: f32,
}

impl Rings {
    pub fn preset(name: &str) -> Rings {
        match name {
            "subtle" => Rings { inner_deg: 30.0, middle_deg: 45.0 },
            "aggressive" => Rings { inner_deg: 12.0, middle_deg: 25.0 },
            _ => Rings { inner_deg: 20.0, middle_deg: 35.0 },
        }
    }

    /// The preset, with explicit angles taking precedence; the middle ring never ends inside the
    /// inner one.
    pub fn from_config(config: &Config) -> Rings {
        let mut r = Rings::preset(config.choice("foveation.preset"));
        let (inner, middle) = (config.float("foveation.inner_deg") as f32, config.float("foveation.middle_deg") as f32);
        if inner > 0.0 {
            r.inner_deg = inner;
        }
        if middle > 0.0 {
            r.middle_deg = middle;
        }
        r.middle_deg = r.middle_deg.max(r.inner_deg);
        r
    }
}

/// How long a lost gaze (blink, tracking loss) keeps the last centre before falling back to the
/// optical axis.
pub const HOLD_NS: i64 = 300_000_000;
/// A move larger than this is a saccade: the centre jumps at once (smoothing it would leave the
/// new fixation point in the periphery for several frames).
pub const SACCADE_DEG: f32 = 5.0;
/// Fraction of the remaining distance covered per sample for small moves (fixation jitter).
pub const SMOOTHING: f32 = 0.5;

/// Where a centre came from, reported in statistics.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CenterSource {
    /// The optical axis: fixed foveation.
    Fixed,
    Gaze,
    /// The last gaze, held through a short loss of tracking.
    Held,
}

/// The gaze policy of one view.
#[derive(Clone, Debug, Default)]
pub struct GazeFilter {
    center: Option<Tangent>,
    last_valid_ns: Option<i64>,
}

impl GazeFilter {
    /// Feeds one sample (None: no valid gaze) taken at `time_ns`; returns the centre to use.
    pub fn update(&mut self, sample: Option<Tangent>, time_ns: i64) -> (Tangent, CenterSource) {
        match sample {
            Some(g) => {
                let next = match self.center {
                    Some(c) if angle_between_deg(c, g) <= SACCADE_DEG => {
                        [c[0] + (g[0] - c[0]) * SMOOTHING, c[1] + (g[1] - c[1]) * SMOOTHING]
                    }
                    _ => g,
                };
                self.center = Some(next);
                self.last_valid_ns = Some(time_ns);
                (next, CenterSource::Gaze)
            }
            None => match (self.center, self.last_valid_ns) {
                (Some(c), Some(t)) if time_ns - t <= HOLD_NS => (c, CenterSource::Held),
                _ => {
                    self.center = None;
                    ([0.0, 0.0], CenterSource::Fixed)
                }
            },
        }
    }
}

/// Per-view foveation for the Vulkan half.
pub fn fovea_views(centers: &[Tangent], rings: Rings) -> Vec<FoveaView> {
    centers
        .iter()
        .enumerate()
        .map(|(view, c)| FoveaView { view: view as u32, center: *c, inner_deg: rings.inner_deg, middle_deg: rings.middle_deg })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::config::{Config, Inputs};
    use crate::core::fovea::{forward, gaze_in_view};

    #[test]
    fn presets_and_overrides() {
        // The chassis' keys and the foveation's own: the test needs no other feature's.
        let keys: &'static [crate::core::config::KeySpec] = Box::leak(crate::core::config::join_keys(&[crate::core::config::CORE_KEYS, crate::features::foveation::KEYS]).into_boxed_slice());
        let (c, _) = Config::resolve(&Inputs { keys, file: None, app_names: &[], env: &|_| None });
        assert_eq!(Rings::from_config(&c), Rings { inner_deg: 20.0, middle_deg: 35.0 });
        let env = |k: &str| match k {
            "STEREOSHIM_FOVEATION_PRESET" => Some("aggressive".to_string()),
            "STEREOSHIM_FOVEATION_INNER_DEG" => Some("30".to_string()),
            _ => None,
        };
        let (c, d) = Config::resolve(&Inputs { keys, file: None, app_names: &[], env: &env });
        assert!(d.is_empty());
        // The explicit inner radius wins and the middle ring grows to stay outside it.
        assert_eq!(Rings::from_config(&c), Rings { inner_deg: 30.0, middle_deg: 30.0 });
    }

    #[test]
    fn angles() {
        assert!((angle_between_deg([0.0, 0.0], [1.0, 0.0]) - 45.0).abs() < 1e-4);
        assert!(angle_between_deg([0.3, 0.2], [0.3, 0.2]) < 1e-3);
    }

    #[test]
    fn gaze_policy_smooths_jitter_jumps_on_saccades_and_holds_through_blinks() {
        let mut f = GazeFilter::default();
        assert_eq!(f.update(None, 0), ([0.0, 0.0], CenterSource::Fixed));
        assert_eq!(f.update(Some([0.2, 0.0]), 10), ([0.2, 0.0], CenterSource::Gaze));
        // Jitter of ~0.6° is smoothed.
        let (c, _) = f.update(Some([0.21, 0.0]), 20);
        assert!((c[0] - 0.205).abs() < 1e-6);
        // A saccade of ~20° jumps.
        assert_eq!(f.update(Some([-0.2, 0.1]), 30).0, [-0.2, 0.1]);
        // A blink shorter than HOLD_NS keeps the centre; a longer loss falls back to the axis.
        assert_eq!(f.update(None, 30 + HOLD_NS / 2), ([-0.2, 0.1], CenterSource::Held));
        assert_eq!(f.update(None, 31 + HOLD_NS), ([0.0, 0.0], CenterSource::Fixed));
        assert_eq!(f.update(Some([0.1, 0.1]), 32 + HOLD_NS).0, [0.1, 0.1]);
    }

    #[test]
    fn gaze_into_views() {
        let ahead = forward([0.0, 0.0, 0.0, 1.0]);
        assert_eq!(ahead, [0.0, 0.0, -1.0]);
        assert_eq!(gaze_in_view([0.0, 0.0, 0.0, 1.0], ahead), Some([0.0, 0.0]));
        // A view canted 10° outward to the left (rotation about +y) sees straight ahead to its right.
        let half = 10f32.to_radians() / 2.0;
        let t = gaze_in_view([0.0, half.sin(), 0.0, half.cos()], ahead).unwrap();
        assert!((t[0] - 10f32.to_radians().tan()).abs() < 1e-5 && t[1].abs() < 1e-6, "{t:?}");
        // Looking 20° up (rotation about +x) from an unrotated view.
        let up = 20f32.to_radians() / 2.0;
        let g = forward([up.sin(), 0.0, 0.0, up.cos()]);
        let t = gaze_in_view([0.0, 0.0, 0.0, 1.0], g).unwrap();
        assert!((t[1] - 20f32.to_radians().tan()).abs() < 1e-5, "{t:?}");
        assert!(gaze_in_view([0.0, 0.0, 0.0, 1.0], [0.0, 0.0, 1.0]).is_none());
    }
}
