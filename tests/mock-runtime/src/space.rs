//! Spaces: VIEW / LOCAL / STAGE reference spaces and action spaces, located against a static,
//! deterministic head (STAGE: head at (0, 1.6, 0) looking down −Z; LOCAL's origin at the head).

use std::sync::Arc;

use glam::{Quat, Vec3};
use openxr_sys as xr;
use xr::Handle as _;

use crate::handles::Registry;
use crate::session::{self, Session};
use crate::util::{find_in_chain, guard, input, out_ptr, output, two_call_copy, XrResult};

pub static SPACES: Registry<Space> = Registry::new();

pub const HEAD_HEIGHT: f32 = 1.6;

/// A rigid transform (child → parent).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    pub p: Vec3,
    pub q: Quat,
}

impl Pose {
    pub const IDENTITY: Pose = Pose { p: Vec3::ZERO, q: Quat::IDENTITY };

    pub fn new(p: Vec3, q: Quat) -> Pose {
        Pose { p, q }
    }

    /// `self ∘ other`: other's frame expressed in self's parent.
    pub fn mul(&self, o: &Pose) -> Pose {
        Pose { p: self.p + self.q * o.p, q: (self.q * o.q).normalize() }
    }

    pub fn inverse(&self) -> Pose {
        let qi = self.q.conjugate();
        Pose { p: -(qi * self.p), q: qi }
    }

    /// From an app pose; a non-unit orientation is XR_ERROR_POSE_INVALID.
    pub fn from_xr(p: &xr::Posef) -> XrResult<Pose> {
        let o = p.orientation;
        let q = Quat::from_xyzw(o.x, o.y, o.z, o.w);
        let v = Vec3::new(p.position.x, p.position.y, p.position.z);
        if !q.is_finite() || !v.is_finite() || (q.length() - 1.0).abs() > 1e-3 {
            return Err(xr::Result::ERROR_POSE_INVALID);
        }
        Ok(Pose { p: v, q: q.normalize() })
    }

    pub fn to_xr(&self) -> xr::Posef {
        xr::Posef {
            orientation: xr::Quaternionf { x: self.q.x, y: self.q.y, z: self.q.z, w: self.q.w },
            position: xr::Vector3f { x: self.p.x, y: self.p.y, z: self.p.z },
        }
    }
}

/// The head in STAGE space.
pub fn head_pose() -> Pose {
    Pose::new(Vec3::new(0.0, HEAD_HEIGHT, 0.0), Quat::IDENTITY)
}

/// The head in STAGE space at display time `t_ns`: [`head_pose`] turned about +y (right-handed:
/// a positive rate turns left) by `yaw_deg_per_s` times the display time since the session's
/// first predicted display time. Without a rate, the still head of [`head_pose`].
pub fn head_pose_at(yaw_deg_per_s: Option<f64>, t_ns: i64) -> Pose {
    let Some(rate) = yaw_deg_per_s else { return head_pose() };
    let secs = (t_ns - crate::session::BASE_TIME_NS) as f64 / 1e9;
    // Reduced in f64 so that long runs keep the angle exact to f32 precision.
    let deg = (rate * secs).rem_euclid(360.0);
    let head = head_pose();
    Pose::new(head.p, Quat::from_rotation_y((deg as f32).to_radians()))
}

/// Reference space origins in STAGE space.
pub fn reference_origin(ty: xr::ReferenceSpaceType) -> XrResult<Pose> {
    match ty {
        xr::ReferenceSpaceType::STAGE => Ok(Pose::IDENTITY),
        xr::ReferenceSpaceType::LOCAL | xr::ReferenceSpaceType::VIEW => Ok(head_pose()),
        _ => Err(xr::Result::ERROR_REFERENCE_SPACE_UNSUPPORTED),
    }
}

pub const REFERENCE_SPACES: &[xr::ReferenceSpaceType] =
    &[xr::ReferenceSpaceType::VIEW, xr::ReferenceSpaceType::LOCAL, xr::ReferenceSpaceType::STAGE];

#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SpaceKind {
    Reference(xr::ReferenceSpaceType),
    Action { action: u64, subaction: u64 },
}

pub struct Space {
    pub handle: u64,
    pub session: u64,
    pub kind: SpaceKind,
    /// poseInReferenceSpace / poseInActionSpace.
    pub offset: Pose,
}

impl Space {
    /// This space in STAGE; None when it cannot be located now.
    pub fn in_stage(&self, s: &Session) -> Option<Pose> {
        let origin = match self.kind {
            SpaceKind::Reference(t) => reference_origin(t).ok()?,
            SpaceKind::Action { action, subaction } => crate::actions::action_pose(s, action, subaction)?,
        };
        Some(origin.mul(&self.offset))
    }

    pub fn name(&self) -> &'static str {
        match self.kind {
            SpaceKind::Reference(xr::ReferenceSpaceType::STAGE) => "STAGE",
            SpaceKind::Reference(xr::ReferenceSpaceType::LOCAL) => "LOCAL",
            SpaceKind::Reference(xr::ReferenceSpaceType::VIEW) => "VIEW",
            SpaceKind::Reference(_) => "REFERENCE",
            SpaceKind::Action { .. } => "ACTION",
        }
    }
}

pub fn get(h: xr::Space) -> XrResult<Arc<Space>> {
    SPACES.get(h.into_raw())
}

/// A space that must belong to `s` (a space of another session is not a valid handle here).
pub fn get_in(s: &Session, h: xr::Space) -> XrResult<Arc<Space>> {
    let sp = get(h)?;
    if sp.session != s.handle {
        return Err(xr::Result::ERROR_HANDLE_INVALID);
    }
    Ok(sp)
}

pub fn create_space(s: &Session, kind: SpaceKind, offset: Pose) -> u64 {
    SPACES.insert_with(|handle| Space { handle, session: s.handle, kind, offset }).0
}

pub unsafe extern "system" fn xr_enumerate_reference_spaces(
    session: xr::Session,
    capacity: u32,
    count_out: *mut u32,
    spaces: *mut xr::ReferenceSpaceType,
) -> xr::Result {
    guard("xrEnumerateReferenceSpaces", || {
        let s = session::get(session)?;
        s.fail_point("xrEnumerateReferenceSpaces")?;
        // SAFETY: app array of `capacity` elements.
        unsafe { two_call_copy(capacity, count_out, spaces, REFERENCE_SPACES) }?;
        Ok(xr::Result::SUCCESS)
    })
}

pub unsafe extern "system" fn xr_create_reference_space(
    session: xr::Session,
    info: *const xr::ReferenceSpaceCreateInfo,
    space: *mut xr::Space,
) -> xr::Result {
    guard("xrCreateReferenceSpace", || {
        let s = session::get(session)?;
        s.fail_point("xrCreateReferenceSpace")?;
        // SAFETY: app pointers.
        let (info, out) = unsafe { (input(info)?, out_ptr(space)?) };
        reference_origin(info.reference_space_type)?;
        let offset = Pose::from_xr(&info.pose_in_reference_space)?;
        *out = xr::Space::from_raw(create_space(&s, SpaceKind::Reference(info.reference_space_type), offset));
        Ok(xr::Result::SUCCESS)
    })
}

pub unsafe extern "system" fn xr_get_reference_space_bounds_rect(
    session: xr::Session,
    ty: xr::ReferenceSpaceType,
    bounds: *mut xr::Extent2Df,
) -> xr::Result {
    guard("xrGetReferenceSpaceBoundsRect", || {
        let s = session::get(session)?;
        s.fail_point("xrGetReferenceSpaceBoundsRect")?;
        reference_origin(ty)?;
        // SAFETY: app output pointer.
        let b = unsafe { out_ptr(bounds) }?;
        if ty == xr::ReferenceSpaceType::STAGE {
            *b = xr::Extent2Df { width: 3.0, height: 3.0 };
            Ok(xr::Result::SUCCESS)
        } else {
            *b = xr::Extent2Df { width: 0.0, height: 0.0 };
            Ok(xr::Result::SPACE_BOUNDS_UNAVAILABLE)
        }
    })
}

pub unsafe extern "system" fn xr_create_action_space(
    session: xr::Session,
    info: *const xr::ActionSpaceCreateInfo,
    space: *mut xr::Space,
) -> xr::Result {
    guard("xrCreateActionSpace", || {
        let s = session::get(session)?;
        // SAFETY: app pointers.
        let (info, out) = unsafe { (input(info)?, out_ptr(space)?) };
        let action = crate::actions::get_action(info.action)?;
        s.fail_point("xrCreateActionSpace")?;
        crate::actions::check_pose_action(&s, &action, info.subaction_path)?;
        let offset = Pose::from_xr(&info.pose_in_action_space)?;
        let kind = SpaceKind::Action { action: action.handle, subaction: info.subaction_path.into_raw() };
        *out = xr::Space::from_raw(create_space(&s, kind, offset));
        Ok(xr::Result::SUCCESS)
    })
}

pub unsafe extern "system" fn xr_locate_space(
    space: xr::Space,
    base: xr::Space,
    time: xr::Time,
    location: *mut xr::SpaceLocation,
) -> xr::Result {
    guard("xrLocateSpace", || {
        let sp = get(space)?;
        let s = session::get(xr::Session::from_raw(sp.session))?;
        let base = get_in(&s, base)?;
        s.fail_point("xrLocateSpace")?;
        // SAFETY: app output struct.
        let loc = unsafe { output(location) }?;
        if time.as_nanos() <= 0 {
            return Err(xr::Result::ERROR_TIME_INVALID);
        }
        let rel = match (sp.in_stage(&s), base.in_stage(&s)) {
            (Some(a), Some(b)) => Some(b.inverse().mul(&a)),
            _ => None,
        };
        use xr::SpaceLocationFlags as L;
        // SAFETY: the app's output chain.
        let vel = unsafe { find_in_chain(loc.next, xr::SpaceVelocity::TYPE) } as *mut xr::SpaceVelocity;
        match rel {
            Some(p) => {
                loc.pose = p.to_xr();
                loc.location_flags = L::ORIENTATION_VALID | L::POSITION_VALID | L::ORIENTATION_TRACKED | L::POSITION_TRACKED;
            }
            None => {
                loc.pose = Pose::IDENTITY.to_xr();
                loc.location_flags = L::EMPTY;
            }
        }
        if !vel.is_null() {
            // SAFETY: found in the app's writable chain; the static head does not move.
            let v = unsafe { &mut *vel };
            let z = xr::Vector3f { x: 0.0, y: 0.0, z: 0.0 };
            v.linear_velocity = z;
            v.angular_velocity = z;
            v.velocity_flags = if rel.is_some() {
                xr::SpaceVelocityFlags::LINEAR_VALID | xr::SpaceVelocityFlags::ANGULAR_VALID
            } else {
                xr::SpaceVelocityFlags::EMPTY
            };
        }
        Ok(xr::Result::SUCCESS)
    })
}

pub unsafe extern "system" fn xr_destroy_space(space: xr::Space) -> xr::Result {
    guard("xrDestroySpace", || {
        let sp = get(space)?;
        session::get(xr::Session::from_raw(sp.session))?.fail_point("xrDestroySpace")?;
        SPACES.remove(sp.handle);
        Ok(xr::Result::SUCCESS)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `MOCK_XR_HEAD_YAW_DEG_PER_S`: still without a rate; with one, the head turns about +y by
    /// rate × display time since the first frame, in place, deterministically.
    #[test]
    fn head_yaw_follows_display_time() {
        let t0 = crate::session::BASE_TIME_NS;
        let still = head_pose();
        for t in [t0, t0 + 11_111_111, t0 + 5_000_000_000] {
            let h = head_pose_at(None, t);
            assert_eq!((h.p, h.q), (still.p, still.q));
        }
        let at = |t: i64| head_pose_at(Some(90.0), t);
        assert!(at(t0).q.angle_between(Quat::IDENTITY) < 1e-6, "no turn at the first display time");
        let half = at(t0 + 500_000_000);
        assert!(half.q.angle_between(Quat::from_rotation_y(45f32.to_radians())) < 1e-5);
        assert_eq!(half.p, still.p, "turns in place");
        // Positive turns left: the forward direction (-z) goes towards -x.
        let fwd = half.q * Vec3::NEG_Z;
        assert!(fwd.x < -0.7 && fwd.z < -0.7, "{fwd:?}");
        // Frame to frame (90 Hz period) the located yaw differs by rate × period.
        let period = 11_111_111i64;
        let a = at(t0 + 7 * period);
        let b = at(t0 + 8 * period);
        let step = a.q.angle_between(b.q).to_degrees();
        assert!((step - 90.0 * period as f32 / 1e9).abs() < 1e-3, "{step}");
        assert_eq!(at(t0 + 8 * period).q, b.q, "deterministic");
        // Negative rates turn right; long runs stay exact (reduced mod 360 in f64).
        let r = head_pose_at(Some(-30.0), t0 + 1_000_000_000);
        assert!(r.q.angle_between(Quat::from_rotation_y(-30f32.to_radians())) < 1e-5);
        let long = head_pose_at(Some(90.0), t0 + 3_600 * 1_000_000_000 + 500_000_000);
        assert!(long.q.angle_between(Quat::from_rotation_y(45f32.to_radians())) < 1e-4);
    }

    #[test]
    fn pose_algebra() {
        let a = Pose::new(Vec3::new(1.0, 2.0, 3.0), Quat::from_rotation_y(0.7));
        let b = Pose::new(Vec3::new(-0.5, 0.1, 0.0), Quat::from_rotation_x(0.3));
        let r = a.inverse().mul(&a.mul(&b));
        assert!((r.p - b.p).length() < 1e-5 && r.q.angle_between(b.q) < 1e-3);
        let bad = xr::Posef {
            orientation: xr::Quaternionf { x: 0.0, y: 0.0, z: 0.0, w: 0.0 },
            position: xr::Vector3f { x: 0.0, y: 0.0, z: 0.0 },
        };
        assert_eq!(Pose::from_xr(&bad), Err(xr::Result::ERROR_POSE_INVALID));
    }

    #[test]
    fn local_is_at_the_head() {
        let local = reference_origin(xr::ReferenceSpaceType::LOCAL).unwrap();
        let stage = reference_origin(xr::ReferenceSpaceType::STAGE).unwrap();
        let rel = stage.inverse().mul(&local);
        assert_eq!(rel.p, Vec3::new(0.0, 1.6, 0.0));
    }
}
