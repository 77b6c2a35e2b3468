//! The runtime's configuration comes only from `MOCK_XR_*` environment variables (docs/testing.md);
//! they are read once per `xrCreateInstance` so a test can change them between instances.

use std::collections::HashSet;

use crate::fault::FailSpec;
use crate::hmd::{HmdProfile, HMD_NAMES};

/// Which frames are captured: `0,3,10-12`; `None` in [`Config`] means all.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FrameList(pub Vec<(u64, u64)>);

impl FrameList {
    pub fn parse(s: &str) -> Result<Self, String> {
        let mut ranges = Vec::new();
        for part in s.split(',').map(str::trim).filter(|p| !p.is_empty()) {
            let (a, b) = match part.split_once('-') {
                Some((a, b)) => (a.trim(), b.trim()),
                None => (part, part),
            };
            let a: u64 = a.parse().map_err(|_| format!("bad frame number in {part:?}"))?;
            let b: u64 = b.parse().map_err(|_| format!("bad frame number in {part:?}"))?;
            if b < a {
                return Err(format!("empty frame range {part:?}"));
            }
            ranges.push((a, b));
        }
        Ok(FrameList(ranges))
    }

    pub fn contains(&self, frame: u64) -> bool {
        self.0.iter().any(|&(a, b)| (a..=b).contains(&frame))
    }
}

#[derive(Debug, Clone)]
pub struct Config {
    pub hmd: &'static HmdProfile,
    pub capture_dir: Option<std::path::PathBuf>,
    pub capture_frames: Option<FrameList>,
    pub exit_after: Option<u64>,
    /// Where the eyes look (`MOCK_XR_GAZE` or `MOCK_XR_GAZE_PATH`); None: not tracking.
    pub gaze: Option<Gaze>,
    pub eye_tracker: bool,
    pub disabled_extensions: HashSet<String>,
    pub mask_change_at: Option<u64>,
    /// `MOCK_XR_VISIBILITY_MASK=generic`: Monado's generic mask (`u_visibility_mask_get_default`:
    /// the four corners of the FOV rectangle cut) instead of the profile's lens, as Monado
    /// answers for headsets it has no lens of (WiVRn's).
    pub generic_mask: bool,
    pub menu_click_at: Option<u64>,
    pub fail: FailSpec,
    pub log: bool,
    /// `MOCK_XR_PACE_HZ`: xrWaitFrame blocks like a compositor's vsync at this rate (unset: no
    /// sleeping, the display clock only advances per call).
    pub pace: Option<std::time::Duration>,
    /// `MOCK_XR_HEAD_YAW_DEG_PER_S`: the head turns about +y at this rate (degrees per second of
    /// display time), so located views change deterministically from frame to frame; None: still.
    pub head_yaw_deg_per_s: Option<f64>,
    /// `MOCK_XR_REENTER=1`: the runtime calls Vulkan on the app's device from inside its frame
    /// and swapchain calls (`VkContext::reenter`).
    pub reenter: bool,
    /// `maxLayerCount` of the system (`MOCK_XR_MAX_LAYERS`, default 16): xrEndFrame refuses more.
    pub max_layers: u32,
    /// `MOCK_XR_CRASH_AT`: the app's `xrEndFrame` of this frame kills the process with SIGSEGV
    /// (a write through a null pointer), so the harness's crash report can be tested against a
    /// crash whose place is known (tests/crash_report.rs).
    pub crash_at: Option<u64>,
    /// `MOCK_XR_EXIT_ON=FILE`: once FILE exists, the next `xrEndFrame` ends the session as
    /// `MOCK_XR_EXIT_AFTER` does. A test that must act while the app runs (ask for a screenshot)
    /// ends the app when it is done, not after a frame count that a loaded machine may reach
    /// before the test acted.
    pub exit_on: Option<std::path::PathBuf>,
    /// `MOCK_XR_RECOMMENDED_SCALE=F` (0.05..=2): the recommended image size is the profile's × F
    /// per axis, as a runtime's own resolution setting (SteamVR's supersampling) changes it; the
    /// FOVs stay. Tests get small images at the recommended size itself.
    pub recommended_scale: f64,
}

fn var(name: &str) -> Option<String> {
    std::env::var(name).ok().filter(|v| !v.trim().is_empty())
}

/// `MOCK_XR_HEAD_YAW_DEG_PER_S`: a finite rate in degrees per second (negative turns right).
pub fn parse_yaw_rate(v: Option<&str>) -> Result<Option<f64>, String> {
    v.map(|v| {
        v.trim()
            .parse::<f64>()
            .ok()
            .filter(|r| r.is_finite() && r.abs() <= 3600.0)
            .ok_or_else(|| format!("MOCK_XR_HEAD_YAW_DEG_PER_S={v:?}: want degrees per second, |rate| <= 3600"))
    })
    .transpose()
}

fn parse_u64(name: &str) -> Result<Option<u64>, String> {
    var(name)
        .map(|v| v.trim().parse::<u64>().map_err(|_| format!("{name}={v:?} is not a frame number")))
        .transpose()
}

pub fn parse_gaze(s: &str) -> Result<(f32, f32), String> {
    let (y, p) = s.split_once(',').ok_or_else(|| format!("MOCK_XR_GAZE={s:?}: want yaw,pitch"))?;
    let y: f32 = y.trim().parse().map_err(|_| format!("MOCK_XR_GAZE={s:?}: bad yaw"))?;
    let p: f32 = p.trim().parse().map_err(|_| format!("MOCK_XR_GAZE={s:?}: bad pitch"))?;
    if !y.is_finite() || !p.is_finite() || p.abs() >= 90.0 {
        return Err(format!("MOCK_XR_GAZE={s:?}: out of range"));
    }
    Ok((y, p))
}

/// The eye tracker's gaze: fixed (`MOCK_XR_GAZE=yaw,pitch`) or moving deterministically with the
/// frame number (`MOCK_XR_GAZE_PATH=yaw,pitch;yaw,pitch;…`, each point held for
/// `MOCK_XR_GAZE_HOLD` frames, then the next, cycling), so tests know the gaze of every frame.
#[derive(Debug, Clone, PartialEq)]
pub enum Gaze {
    /// (yaw, pitch) in degrees.
    Fixed(f32, f32),
    /// Points (yaw, pitch) in degrees; frame f shows `points[(f / hold) % len]`.
    Path { points: Vec<(f32, f32)>, hold: u64 },
}

impl Gaze {
    /// (yaw, pitch) in degrees while frame `frame` is rendered (the session's count of successful
    /// `xrEndFrame`s).
    pub fn at(&self, frame: u64) -> (f32, f32) {
        match self {
            Gaze::Fixed(y, p) => (*y, *p),
            Gaze::Path { points, hold } => points[((frame / hold) % points.len() as u64) as usize],
        }
    }

    /// Reads `MOCK_XR_GAZE`, `MOCK_XR_GAZE_PATH` and `MOCK_XR_GAZE_HOLD` (given as values, so
    /// tests need not touch the environment). A fixed and a moving gaze together, or a hold
    /// without a path, are errors rather than a silently different test.
    pub fn parse(fixed: Option<&str>, path: Option<&str>, hold: Option<&str>) -> Result<Option<Gaze>, String> {
        let hold = hold
            .map(|h| h.trim().parse::<u64>().ok().filter(|&n| n > 0).ok_or_else(|| format!("MOCK_XR_GAZE_HOLD={h:?}: want a frame count > 0")))
            .transpose()?;
        match (fixed, path, hold) {
            (Some(_), Some(_), _) => Err("MOCK_XR_GAZE and MOCK_XR_GAZE_PATH exclude each other".into()),
            (_, None, Some(_)) => Err("MOCK_XR_GAZE_HOLD needs MOCK_XR_GAZE_PATH".into()),
            (Some(f), None, None) => parse_gaze(f).map(|(y, p)| Some(Gaze::Fixed(y, p))),
            (None, None, None) => Ok(None),
            (None, Some(path), hold) => {
                let points = path
                    .split(';')
                    .map(str::trim)
                    .filter(|p| !p.is_empty())
                    .map(|p| parse_gaze(p).map_err(|e| format!("MOCK_XR_GAZE_PATH={path:?}: {e}")))
                    .collect::<Result<Vec<_>, _>>()?;
                if points.is_empty() {
                    return Err(format!("MOCK_XR_GAZE_PATH={path:?}: no points"));
                }
                Ok(Some(Gaze::Path { points, hold: hold.unwrap_or(1) }))
            }
        }
    }
}

impl Config {
    /// The recommended image size (the profile's × `recommended_scale`, at least 1×1).
    pub fn recommended(&self) -> (u32, u32) {
        let s = |n: u32| ((n as f64 * self.recommended_scale).round() as u32).max(1);
        (s(self.hmd.recommended.0), s(self.hmd.recommended.1))
    }

    /// Reads the environment. A malformed variable is an error (xrCreateInstance fails) rather
    /// than a silently different test.
    pub fn from_env() -> Result<Config, String> {
        let hmd_name = var("MOCK_XR_HMD").unwrap_or_else(|| "simple".into());
        let hmd = HmdProfile::by_name(hmd_name.trim()).ok_or_else(|| {
            format!("MOCK_XR_HMD={hmd_name:?}: unknown profile (known: {})", HMD_NAMES.join(", "))
        })?;
        Ok(Config {
            hmd,
            capture_dir: var("MOCK_XR_CAPTURE").map(Into::into),
            capture_frames: var("MOCK_XR_CAPTURE_FRAMES")
                .map(|s| FrameList::parse(&s))
                .transpose()?,
            exit_after: parse_u64("MOCK_XR_EXIT_AFTER")?,
            max_layers: match parse_u64("MOCK_XR_MAX_LAYERS")? {
                None => crate::system::MAX_LAYERS,
                Some(n @ 1..=16) => n as u32,
                Some(n) => return Err(format!("MOCK_XR_MAX_LAYERS={n}: want 1..=16")),
            },
            gaze: Gaze::parse(var("MOCK_XR_GAZE").as_deref(), var("MOCK_XR_GAZE_PATH").as_deref(), var("MOCK_XR_GAZE_HOLD").as_deref())?,
            eye_tracker: var("MOCK_XR_EYE_TRACKER").is_none_or(|v| v.trim() != "0"),
            disabled_extensions: var("MOCK_XR_DISABLE_EXTENSIONS")
                .map(|s| s.split(',').map(|e| e.trim().to_string()).filter(|e| !e.is_empty()).collect())
                .unwrap_or_default(),
            mask_change_at: parse_u64("MOCK_XR_VISIBILITY_MASK_CHANGE_AT")?,
            generic_mask: match var("MOCK_XR_VISIBILITY_MASK").as_deref().map(str::trim) {
                None | Some("profile") => false,
                Some("generic") => true,
                Some(v) => return Err(format!("MOCK_XR_VISIBILITY_MASK={v}: want profile or generic")),
            },
            menu_click_at: parse_u64("MOCK_XR_MENU_CLICK_AT")?,
            fail: FailSpec::from_env()?,
            log: log_enabled(),
            pace: parse_u64("MOCK_XR_PACE_HZ")?
                .filter(|&hz| hz > 0)
                .map(|hz| std::time::Duration::from_nanos(1_000_000_000 / hz)),
            head_yaw_deg_per_s: parse_yaw_rate(var("MOCK_XR_HEAD_YAW_DEG_PER_S").as_deref())?,
            reenter: match var("MOCK_XR_REENTER").as_deref().map(str::trim) {
                None | Some("0") => false,
                Some("1") => true,
                Some(v) => return Err(format!("MOCK_XR_REENTER={v:?}: want 0 or 1")),
            },
            crash_at: parse_u64("MOCK_XR_CRASH_AT")?,
            exit_on: var("MOCK_XR_EXIT_ON").map(Into::into),
            recommended_scale: match var("MOCK_XR_RECOMMENDED_SCALE").map(|v| v.trim().parse::<f64>()) {
                None => 1.0,
                Some(Ok(f)) if (0.05..=2.0).contains(&f) => f,
                Some(_) => return Err("MOCK_XR_RECOMMENDED_SCALE: want a number in 0.05..=2".into()),
            },
        })
    }

    pub fn captures(&self, frame: u64) -> bool {
        self.capture_dir.is_some() && self.capture_frames.as_ref().is_none_or(|f| f.contains(frame))
    }
}

pub fn log_enabled() -> bool {
    var("MOCK_XR_LOG").is_some_and(|v| v.trim() != "0")
}

/// Diagnostics go to stderr only: stdout belongs to the app.
#[macro_export]
macro_rules! log {
    ($($arg:tt)*) => {
        if $crate::config::log_enabled() {
            eprintln!("[mock-runtime] {}", format_args!($($arg)*));
        }
    };
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn yaw_rate() {
        assert_eq!(parse_yaw_rate(None), Ok(None));
        assert_eq!(parse_yaw_rate(Some("30")), Ok(Some(30.0)));
        assert_eq!(parse_yaw_rate(Some(" -12.5 ")), Ok(Some(-12.5)));
        assert!(parse_yaw_rate(Some("fast")).is_err());
        assert!(parse_yaw_rate(Some("inf")).is_err());
        assert!(parse_yaw_rate(Some("5000")).is_err());
    }

    #[test]
    fn frame_list() {
        let f = FrameList::parse("0,3, 10-12").unwrap();
        assert!(f.contains(0) && f.contains(3) && f.contains(10) && f.contains(12));
        assert!(!f.contains(1) && !f.contains(13));
        assert!(FrameList::parse("3-1").is_err());
        assert!(FrameList::parse("a").is_err());
        assert_eq!(FrameList::parse("").unwrap().0, vec![]);
    }

    #[test]
    fn gaze() {
        assert_eq!(parse_gaze("10,-5").unwrap(), (10.0, -5.0));
        assert!(parse_gaze("10").is_err());
        assert!(parse_gaze("0,95").is_err());
        assert_eq!(Gaze::parse(Some("10,-5"), None, None).unwrap(), Some(Gaze::Fixed(10.0, -5.0)));
        assert_eq!(Gaze::parse(None, None, None).unwrap(), None);
    }

    #[test]
    fn gaze_path_moves_with_the_frame_number() {
        let g = Gaze::parse(None, Some("0,0; 12,-6 ;-10,8"), Some("3")).unwrap().unwrap();
        let seen: Vec<(f32, f32)> = (0..10).map(|f| g.at(f)).collect();
        let (a, b, c) = ((0.0, 0.0), (12.0, -6.0), (-10.0, 8.0));
        assert_eq!(seen, [a, a, a, b, b, b, c, c, c, a], "each point held 3 frames, then the next, cycling");
        // Hold defaults to one frame; a fixed gaze never moves.
        let g = Gaze::parse(None, Some("1,2;3,4"), None).unwrap().unwrap();
        assert_eq!((0..4).map(|f| g.at(f)).collect::<Vec<_>>(), [(1.0, 2.0), (3.0, 4.0), (1.0, 2.0), (3.0, 4.0)]);
        assert_eq!(Gaze::Fixed(5.0, 6.0).at(1234), (5.0, 6.0));
        // Misuse is an error, not a different gaze.
        assert!(Gaze::parse(Some("1,2"), Some("1,2;3,4"), None).is_err(), "fixed and moving together");
        assert!(Gaze::parse(Some("1,2"), None, Some("3")).is_err(), "hold without a path");
        assert!(Gaze::parse(None, Some("1,2;3"), None).is_err(), "a point without pitch");
        assert!(Gaze::parse(None, Some("1,2;0,95"), None).is_err(), "pitch out of range");
        assert!(Gaze::parse(None, Some(" ; "), None).is_err(), "no points");
        assert!(Gaze::parse(None, Some("1,2"), Some("0")).is_err(), "hold 0");
        assert!(Gaze::parse(None, Some("1,2"), Some("x")).is_err(), "hold not a number");
    }
}
