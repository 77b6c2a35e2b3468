//! Action entry points: features may attach and sync action sets of their own next to the app's
//! (`XrFeature::action_sets`, `active_action_sets`); the app's sets and actions are untouched, and
//! an attach that fails with the layer's sets leaves nothing of the layer's behind.

use super::session;
use crate::core::guard;
use openxr_sys as xr;

/// The app's array of `n` elements (empty when null or zero).
///
/// # Safety
/// `p` must point to `n` valid elements when non-null.
unsafe fn app_array<T: Copy>(p: *const T, n: u32) -> Vec<T> {
    if n == 0 || p.is_null() {
        return Vec::new();
    }
    // SAFETY: the caller's contract.
    unsafe { std::slice::from_raw_parts(p, n as usize) }.to_vec()
}

pub(super) unsafe extern "system" fn attach_session_action_sets(
    session: xr::Session,
    attach_info: *const xr::SessionActionSetsAttachInfo,
) -> xr::Result {
    let (inst, sess) = match session::lookup(session) {
        Ok(s) => (s.instance.clone(), Some(s)),
        Err(Some(inst)) => (inst, None),
        Err(None) => return xr::Result::ERROR_HANDLE_INVALID,
    };
    let Some(next) = inst.next.attach_session_action_sets else { return xr::Result::ERROR_FUNCTION_UNSUPPORTED };
    // SAFETY: forwarding the app's arguments unchanged.
    let plain = || unsafe { next(session, attach_info) };
    guard::run("xrAttachSessionActionSets", &inst.pass_through, |down| {
        inst.check_fault("xrAttachSessionActionSets")?;
        // SAFETY: the app's attach info, valid for this call (null goes down for the runtime).
        let Some((s, info)) = sess.as_ref().zip(unsafe { attach_info.as_ref() }) else { return Ok(down.call(plain)) };
        let ours: Vec<(usize, Vec<xr::ActionSet>)> = crate::registry::XR_FEATURES.iter().map(|f| f.action_sets(s)).enumerate().filter(|(_, v)| !v.is_empty()).collect();
        if ours.is_empty() {
            return Ok(down.call(plain));
        }
        // SAFETY: the app's array of `count_action_sets` handles.
        let mut sets = unsafe { app_array(info.action_sets, info.count_action_sets) };
        sets.extend(ours.iter().flat_map(|(_, v)| v.iter().copied()));
        let mut with = *info;
        with.count_action_sets = sets.len() as u32;
        with.action_sets = sets.as_ptr();
        // SAFETY: the copy and the array live until the call returns.
        let r = down.call(|| unsafe { next(session, &with) });
        for (i, _) in &ours {
            crate::registry::XR_FEATURES[*i].action_sets_attached(s, r);
        }
        Ok(r)
    }, plain)
}

pub(super) unsafe extern "system" fn sync_actions(session: xr::Session, sync_info: *const xr::ActionsSyncInfo) -> xr::Result {
    let (inst, sess) = match session::lookup(session) {
        Ok(s) => (s.instance.clone(), Some(s)),
        Err(Some(inst)) => (inst, None),
        Err(None) => return xr::Result::ERROR_HANDLE_INVALID,
    };
    let Some(next) = inst.next.sync_actions else { return xr::Result::ERROR_FUNCTION_UNSUPPORTED };
    // SAFETY: forwarding the app's arguments unchanged.
    let plain = || unsafe { next(session, sync_info) };
    guard::run("xrSyncActions", &inst.pass_through, |down| {
        inst.check_fault("xrSyncActions")?;
        let ours: Vec<xr::ActiveActionSet> = sess.as_ref().map(|s| crate::registry::XR_FEATURES.iter().flat_map(|f| f.active_action_sets(s)).collect()).unwrap_or_default();
        // SAFETY: the app's sync info, valid for this call.
        let (false, Some(info)) = (ours.is_empty(), unsafe { sync_info.as_ref() }) else { return Ok(down.call(plain)) };
        // SAFETY: the app's array of `count_active_action_sets` entries.
        let mut active = unsafe { app_array(info.active_action_sets, info.count_active_action_sets) };
        active.extend(ours);
        let mut with = *info;
        with.count_active_action_sets = active.len() as u32;
        with.active_action_sets = active.as_ptr();
        // SAFETY: the copy and the array live until the call returns.
        Ok(down.call(|| unsafe { next(session, &with) }))
    }, plain)
}
