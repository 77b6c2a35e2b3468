//! The XrSession and its lifecycle state machine (IDLE → READY → SYNCHRONIZED → VISIBLE →
//! FOCUSED → … → STOPPING → IDLE → EXITING), driven by the app's calls and `MOCK_XR_EXIT_AFTER`.

use std::sync::{Arc, Condvar, Mutex};

use openxr_sys as xr;
use xr::Handle as _;

use crate::capture::CaptureState;
use crate::handles::Registry;
use crate::instance::{self, Event, Instance};
use crate::system::{check_system, check_view_config};
use crate::util::{find_in_chain, guard, input, out_ptr, XrResult};
use crate::vulkan::VkContext;
use crate::{EXT_HEADLESS, EXT_VULKAN_ENABLE, EXT_VULKAN_ENABLE2};

pub static SESSIONS: Registry<Session> = Registry::new();

/// Display time of the first frame; frame n is displayed at BASE + n·period.
pub const BASE_TIME_NS: i64 = 1_000_000_000;

#[derive(Debug)]
pub struct Core {
    pub state: xr::SessionState,
    /// Between a successful xrBeginSession and xrEndSession.
    pub running: bool,
    /// Predicted display time of an xrWaitFrame not yet followed by xrBeginFrame.
    pub waited: Option<i64>,
    /// Display time of the frame begun and not yet ended.
    pub begun: Option<i64>,
    pub waits: u64,
    /// Frames ended successfully: the frame number of the next xrEndFrame.
    pub frames_ended: u64,
    /// Whether the lens masks have switched to their shrunk version.
    pub mask_changed: bool,
    /// `MOCK_XR_PACE_HZ`: the wall-clock instant the next xrWaitFrame may return at.
    pub next_wake: Option<std::time::Instant>,
}

pub struct Session {
    pub handle: u64,
    pub instance: Arc<Instance>,
    /// None: a headless session (XR_MND_headless, created without a graphics binding): no
    /// swapchains, no rendering; views, spaces and visibility masks work.
    pub vk: Option<Arc<VkContext>>,
    pub core: Mutex<Core>,
    /// Signalled when a waited frame is begun or the session starts or stops running: what an
    /// xrWaitFrame blocked on the previous frame's xrBeginFrame waits for.
    pub frame_begun: Condvar,
    pub capture: Mutex<CaptureState>,
    pub actions: Mutex<crate::actions::SessionActions>,
}

impl Session {
    pub fn fail_point(&self, f: &'static str) -> XrResult<()> {
        self.instance.fail_point(f)
    }

    /// The session's Vulkan device; a headless session has none.
    pub fn vk(&self) -> XrResult<&Arc<VkContext>> {
        self.vk.as_ref().ok_or(xr::Result::ERROR_VALIDATION_FAILURE)
    }

    pub fn period(&self) -> i64 {
        self.instance.cfg.hmd.frame_period_ns()
    }

    pub fn now(&self, core: &Core) -> i64 {
        BASE_TIME_NS + core.waits as i64 * self.period()
    }

    pub fn set_state(&self, core: &mut Core, state: xr::SessionState) {
        core.state = state;
        let time = self.now(core);
        self.instance.push_event(Event::SessionState { session: self.handle, state, time });
    }

    /// Walks down the state diagram to STOPPING.
    pub fn stop(&self, core: &mut Core) {
        use xr::SessionState as S;
        if core.state == S::FOCUSED {
            self.set_state(core, S::VISIBLE);
        }
        if core.state == S::VISIBLE {
            self.set_state(core, S::SYNCHRONIZED);
        }
        if core.state == S::SYNCHRONIZED {
            self.set_state(core, S::STOPPING);
        }
    }

    /// `MOCK_XR_VISIBILITY_MASK_CHANGE_AT`: switch masks once `frames_ended` reaches N.
    pub fn maybe_change_mask(&self, core: &mut Core) {
        if !core.mask_changed
            && self.instance.cfg.mask_change_at.is_some_and(|n| core.frames_ended >= n)
            && self.instance.extension_enabled(crate::EXT_VISIBILITY_MASK)
        {
            core.mask_changed = true;
            for view in 0..2 {
                self.instance.push_event(Event::VisibilityMaskChanged { session: self.handle, view });
            }
        }
    }
}

pub fn get(h: xr::Session) -> XrResult<Arc<Session>> {
    SESSIONS.get(h.into_raw())
}

/// Destroys a session and everything created from it.
pub fn destroy(s: &Arc<Session>) {
    for sp in crate::space::SPACES.remove_where(|sp| sp.session == s.handle) {
        drop(sp);
    }
    for sc in crate::swapchain::SWAPCHAINS.remove_where(|sc| sc.session == s.handle) {
        crate::swapchain::destroy(&sc);
    }
    if let Some(vk) = &s.vk {
        vk.destroy_own_objects();
    }
    SESSIONS.remove(s.handle);
    s.instance.events.lock().unwrap().retain(|e| e.session() != s.handle);
}

pub unsafe extern "system" fn xr_create_session(
    instance: xr::Instance,
    info: *const xr::SessionCreateInfo,
    session: *mut xr::Session,
) -> xr::Result {
    guard("xrCreateSession", || {
        let inst = instance::get(instance)?;
        inst.fail_point("xrCreateSession")?;
        // SAFETY: app pointers, checked by the helpers.
        let (info, out) = unsafe { (input(info)?, out_ptr(session)?) };
        check_system(info.system_id)?;
        if info.create_flags != xr::SessionCreateFlags::EMPTY {
            return Err(xr::Result::ERROR_VALIDATION_FAILURE);
        }
        // SAFETY: the app's input chain.
        let binding = unsafe { find_in_chain(info.next, xr::GraphicsBindingVulkanKHR::TYPE) } as *const xr::GraphicsBindingVulkanKHR;
        // XR_MND_headless: without a graphics binding, a session that does not interact with
        // the display (no swapchains, nothing rendered).
        let headless = binding.is_null() && inst.extension_enabled(EXT_HEADLESS);
        if !headless {
            if !inst.extension_enabled(EXT_VULKAN_ENABLE) && !inst.extension_enabled(EXT_VULKAN_ENABLE2) {
                crate::log!("xrCreateSession: no graphics extension enabled");
                return Err(xr::Result::ERROR_GRAPHICS_DEVICE_INVALID);
            }
            if !inst.vk.lock().unwrap().requirements_called {
                return Err(xr::Result::ERROR_GRAPHICS_REQUIREMENTS_CALL_MISSING);
            }
            if binding.is_null() {
                crate::log!("xrCreateSession: no XrGraphicsBindingVulkanKHR");
                return Err(xr::Result::ERROR_GRAPHICS_DEVICE_INVALID);
            }
        }
        if !SESSIONS.find(|s| s.instance.handle == inst.handle).is_empty() {
            return Err(xr::Result::ERROR_LIMIT_REACHED);
        }
        let vk = if headless {
            crate::log!("xrCreateSession: headless (XR_MND_headless)");
            None
        } else {
            // SAFETY: found in the chain with the binding's type (non-null: checked above).
            Some(Arc::new(VkContext::new(&inst, unsafe { &*binding })?))
        };
        let (h, s) = SESSIONS.insert_with(|handle| Session {
            handle,
            instance: inst.clone(),
            vk,
            core: Mutex::new(Core {
                state: xr::SessionState::UNKNOWN,
                running: false,
                waited: None,
                begun: None,
                waits: 0,
                frames_ended: 0,
                mask_changed: false,
                next_wake: None,
            }),
            frame_begun: Condvar::new(),
            capture: Mutex::new(CaptureState::default()),
            actions: Mutex::default(),
        });
        {
            let mut core = s.core.lock().unwrap();
            s.set_state(&mut core, xr::SessionState::IDLE);
            s.set_state(&mut core, xr::SessionState::READY);
        }
        crate::log!("xrCreateSession -> {h}");
        *out = xr::Session::from_raw(h);
        Ok(xr::Result::SUCCESS)
    })
}

pub unsafe extern "system" fn xr_destroy_session(session: xr::Session) -> xr::Result {
    guard("xrDestroySession", || {
        let s = get(session)?;
        s.fail_point("xrDestroySession")?;
        destroy(&s);
        if s.instance.cfg.reenter {
            crate::vulkan::report_reentries();
        }
        Ok(xr::Result::SUCCESS)
    })
}

pub unsafe extern "system" fn xr_begin_session(session: xr::Session, info: *const xr::SessionBeginInfo) -> xr::Result {
    guard("xrBeginSession", || {
        let s = get(session)?;
        s.fail_point("xrBeginSession")?;
        // SAFETY: app input struct.
        let info = unsafe { input(info) }?;
        // A headless session ignores the view configuration (it may be 0).
        if s.vk.is_some() {
            check_view_config(info.primary_view_configuration_type)?;
        }
        let mut core = s.core.lock().unwrap();
        if core.running {
            return Err(xr::Result::ERROR_SESSION_RUNNING);
        }
        if core.state != xr::SessionState::READY {
            return Err(xr::Result::ERROR_SESSION_NOT_READY);
        }
        core.running = true;
        core.waited = None;
        core.begun = None;
        s.frame_begun.notify_all();
        s.set_state(&mut core, xr::SessionState::SYNCHRONIZED);
        s.set_state(&mut core, xr::SessionState::VISIBLE);
        s.set_state(&mut core, xr::SessionState::FOCUSED);
        s.maybe_change_mask(&mut core);
        Ok(xr::Result::SUCCESS)
    })
}

pub unsafe extern "system" fn xr_end_session(session: xr::Session) -> xr::Result {
    guard("xrEndSession", || {
        let s = get(session)?;
        s.fail_point("xrEndSession")?;
        let mut core = s.core.lock().unwrap();
        if !core.running {
            return Err(xr::Result::ERROR_SESSION_NOT_RUNNING);
        }
        if core.state != xr::SessionState::STOPPING {
            return Err(xr::Result::ERROR_SESSION_NOT_STOPPING);
        }
        core.running = false;
        core.waited = None;
        core.begun = None;
        s.frame_begun.notify_all();
        s.set_state(&mut core, xr::SessionState::IDLE);
        // The mock never comes back to READY: the "user" has left; the app should exit.
        s.set_state(&mut core, xr::SessionState::EXITING);
        Ok(xr::Result::SUCCESS)
    })
}

pub unsafe extern "system" fn xr_request_exit_session(session: xr::Session) -> xr::Result {
    guard("xrRequestExitSession", || {
        let s = get(session)?;
        s.fail_point("xrRequestExitSession")?;
        let mut core = s.core.lock().unwrap();
        if !core.running {
            return Err(xr::Result::ERROR_SESSION_NOT_RUNNING);
        }
        s.stop(&mut core);
        Ok(xr::Result::SUCCESS)
    })
}
