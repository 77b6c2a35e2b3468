//! Where the fovea is and how large: ring sizes from presets or explicit angles, and the gaze
//! policy (smoothing, blinks, loss of tracking) that turns raw eye-tracker samples into a centre
//! the rate maps can follow without flicker. Pure; the OpenXR shell feeds it samples.

use crate::config::Config;
use crate::shared::FoveaView;

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

/// A direction as a tangent-plane point of a view (x right, y up; z = −1).
pub type Tangent = [f32; 2];

/// Angle between two view directions given as tangent-plane points, degrees.
pub fn angle_between_deg(a: Tangent, b: Tangent) -> f32 {
    let (ax, ay, az) = (a[0] as f64, a[1] as f64, -1.0f64);
    let (bx, by, bz) = (b[0] as f64, b[1] as f64, -1.0f64);
    let dot = ax * bx + ay * by + az * bz;
    let n = (ax * ax + ay * ay + az * az).sqrt() * (bx * bx + by * by + bz * bz).sqrt();
    (dot / n).clamp(-1.0, 1.0).acos().to_degrees() as f32
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

/// A gaze direction (in the space the views were located in) as a tangent-plane point of a view
/// with orientation `q_space_view` (x, y, z, w); None when it points behind the view.
pub fn gaze_in_view(q_space_view: [f32; 4], gaze_dir_space: [f32; 3]) -> Option<Tangent> {
    let [x, y, z, w] = q_space_view;
    // Rotate by the inverse (conjugate) orientation: space → view.
    let q = [-x, -y, -z, w];
    let v = gaze_dir_space;
    let c1 = [q[1] * v[2] - q[2] * v[1], q[2] * v[0] - q[0] * v[2], q[0] * v[1] - q[1] * v[0]];
    let c2 = [q[1] * c1[2] - q[2] * c1[1], q[2] * c1[0] - q[0] * c1[2], q[0] * c1[1] - q[1] * c1[0]];
    let d = [v[0] + 2.0 * (q[3] * c1[0] + c2[0]), v[1] + 2.0 * (q[3] * c1[1] + c2[1]), v[2] + 2.0 * (q[3] * c1[2] + c2[2])];
    // Directions more than ~85° off the view axis cannot be a fovea on any HMD.
    (d[2] < -0.08).then(|| [d[0] / -d[2], d[1] / -d[2]])
}

/// The forward direction (−z) of an orientation (x, y, z, w).
pub fn forward(q: [f32; 4]) -> [f32; 3] {
    let [x, y, z, w] = q;
    [-(2.0 * (x * z + w * y)), -(2.0 * (y * z - w * x)), -(1.0 - 2.0 * (x * x + y * y))]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::{Config, Inputs};

    #[test]
    fn presets_and_overrides() {
        let (c, _) = Config::resolve(&Inputs { file: None, app_names: &[], env: &|_| None });
        assert_eq!(Rings::from_config(&c), Rings { inner_deg: 20.0, middle_deg: 35.0 });
        let env = |k: &str| match k {
            "STEREOSHIM_FOVEATION_PRESET" => Some("aggressive".to_string()),
            "STEREOSHIM_FOVEATION_INNER_DEG" => Some("30".to_string()),
            _ => None,
        };
        let (c, d) = Config::resolve(&Inputs { file: None, app_names: &[], env: &env });
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
