//! The OpenXR side: instance, system, session, actions, reference space, swapchains and the frame
//! loop's calls, written the way an ordinary app writes them.

use crate::cli::{Options, VulkanPath};
use crate::error::{fail, Ctx, Result};
use openxr as xr;
use std::path::Path;

pub struct XrInstance {
    pub instance: xr::Instance,
    pub system: xr::SystemId,
    pub view_config: Vec<xr::ViewConfigurationView>,
    pub blend_mode: xr::EnvironmentBlendMode,
    // Keeps the loader library mapped for as long as the instance lives.
    _entry: xr::Entry,
}

impl XrInstance {
    pub fn new(opts: &Options) -> Result<XrInstance> {
        // SAFETY: loading the Khronos OpenXR loader; only libopenxr_loader.so.1 exists on Debian.
        let entry = unsafe { xr::Entry::load_from(Path::new("libopenxr_loader.so.1"), &()) }
            .ctx("loading libopenxr_loader.so.1")?;
        let available = entry.enumerate_extensions().ctx("xrEnumerateInstanceExtensionProperties")?;
        let mut exts = xr::ExtensionSet::default();
        match opts.vulkan {
            VulkanPath::Enable2 if available.khr_vulkan_enable2 => exts.khr_vulkan_enable2 = true,
            VulkanPath::Enable if available.khr_vulkan_enable => exts.khr_vulkan_enable = true,
            VulkanPath::Enable2 => return fail("the runtime does not offer XR_KHR_vulkan_enable2"),
            VulkanPath::Enable => return fail("the runtime does not offer XR_KHR_vulkan_enable"),
        }
        if opts.visibility_mask {
            if !available.khr_visibility_mask {
                return fail("--visibility-mask: the runtime does not offer XR_KHR_visibility_mask");
            }
            exts.khr_visibility_mask = true;
        }
        if opts.submit_depth {
            if !available.khr_composition_layer_depth {
                return fail("--submit-depth: the runtime does not offer XR_KHR_composition_layer_depth");
            }
            exts.khr_composition_layer_depth = true;
        }
        let instance = entry
            .create_instance(
                &xr::ApplicationInfo {
                    application_name: "xr-scene",
                    application_version: 1,
                    engine_name: "xr-scene",
                    engine_version: 1,
                    api_version: xr::Version::new(1, 0, 0),
                },
                &exts,
                &[],
                &(),
            )
            .ctx("xrCreateInstance")?;
        let system = instance.system(xr::FormFactor::HEAD_MOUNTED_DISPLAY).ctx("xrGetSystem")?;
        let view_config = instance
            .enumerate_view_configuration_views(system, xr::ViewConfigurationType::PRIMARY_STEREO)
            .ctx("xrEnumerateViewConfigurationViews")?;
        if view_config.len() != 2 {
            return fail(format!("PRIMARY_STEREO has {} views, expected 2", view_config.len()));
        }
        let blends = instance
            .enumerate_environment_blend_modes(system, xr::ViewConfigurationType::PRIMARY_STEREO)
            .ctx("xrEnumerateEnvironmentBlendModes")?;
        let blend_mode = if blends.contains(&xr::EnvironmentBlendMode::OPAQUE) {
            xr::EnvironmentBlendMode::OPAQUE
        } else {
            *blends.first().ok_or_else(|| crate::error::Error("no environment blend modes".into()))?
        };
        Ok(XrInstance { instance, system, view_config, blend_mode, _entry: entry })
    }

    /// `xrDestroyInstance` through the raw entry point, so its failure is reported (the openxr
    /// crate's `Drop` ignores the result).
    pub fn destroy(self) -> Result<()> {
        let XrInstance { instance, _entry: entry, .. } = self;
        // SAFETY: every child object was destroyed before; the wrapper is forgotten so its `Drop`
        // does not destroy the handle again; the loader stays mapped until `entry` drops below.
        let r = unsafe { (instance.fp().destroy_instance)(instance.as_raw()) };
        std::mem::forget(instance);
        drop(entry);
        crate::error::check(r, "xrDestroyInstance")
    }
}

/// What the event loop tells the frame loop.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Flow {
    Continue,
    /// The session reached EXITING: shut down cleanly.
    Exit,
}

pub struct XrSession {
    // Field order is drop order: spaces and actions before the session they belong to.
    grip_space: xr::Space,
    pub stage: xr::Space,
    quit: xr::Action<bool>,
    _pose: xr::Action<xr::Posef>,
    action_set: xr::ActionSet,
    /// None while `--threads`' frame-pacing thread has it ([`crate::threads::Pacer`]).
    pub waiter: Option<xr::FrameWaiter>,
    pub stream: xr::FrameStream<xr::Vulkan>,
    pub session: xr::Session<xr::Vulkan>,
    left_hand: xr::Path,
    pub running: bool,
    exit_requested: bool,
}

impl XrSession {
    /// # Safety
    /// The Vulkan handles must be the ones created through / for this XR system, and must outlive
    /// the session.
    pub unsafe fn new(xri: &XrInstance, binding: xr::vulkan::SessionCreateInfo) -> Result<XrSession> {
        let inst = &xri.instance;
        // Actions: a real app defines them before the session and attaches them once.
        let action_set = inst.create_action_set("gameplay", "Gameplay", 0).ctx("xrCreateActionSet")?;
        let left_hand = inst.string_to_path("/user/hand/left").ctx("xrStringToPath")?;
        let quit = action_set
            .create_action::<bool>("quit", "Quit", &[left_hand])
            .ctx("xrCreateAction(quit)")?;
        let pose = action_set
            .create_action::<xr::Posef>("hand_pose", "Hand pose", &[left_hand])
            .ctx("xrCreateAction(hand_pose)")?;
        let profile = inst
            .string_to_path("/interaction_profiles/khr/simple_controller")
            .ctx("xrStringToPath")?;
        let menu = inst.string_to_path("/user/hand/left/input/menu/click").ctx("xrStringToPath")?;
        let grip = inst.string_to_path("/user/hand/left/input/grip/pose").ctx("xrStringToPath")?;
        inst.suggest_interaction_profile_bindings(
            profile,
            &[xr::Binding::new(&quit, menu), xr::Binding::new(&pose, grip)],
        )
        .ctx("xrSuggestInteractionProfileBindings")?;

        // SAFETY: forwarded to the caller.
        let (session, waiter, stream) =
            unsafe { inst.create_session::<xr::Vulkan>(xri.system, &binding) }.ctx("xrCreateSession")?;
        session.attach_action_sets(&[&action_set]).ctx("xrAttachSessionActionSets")?;
        let stage = session
            .create_reference_space(xr::ReferenceSpaceType::STAGE, xr::Posef::IDENTITY)
            .ctx("xrCreateReferenceSpace(STAGE)")?;
        let grip_space = pose
            .create_space(&session, left_hand, xr::Posef::IDENTITY)
            .ctx("xrCreateActionSpace")?;
        Ok(XrSession {
            grip_space,
            stage,
            quit,
            _pose: pose,
            action_set,
            waiter: Some(waiter),
            stream,
            session,
            left_hand,
            running: false,
            exit_requested: false,
        })
    }

    /// `--visibility-mask`: each view's hidden-area mesh, fetched once, as an app that draws its
    /// own mask would (xr-scene checks that the call succeeds and returns triangles, and prints
    /// their area in the view's tangent plane); `--draw-hidden-area` draws what it returns.
    pub fn fetch_visibility_masks(&self) -> Result<Vec<crate::scene::HiddenAreaMesh>> {
        let mut meshes = Vec::new();
        for view in 0..2 {
            let mask = self
                .session
                .get_visibility_mask_khr(xr::ViewConfigurationType::PRIMARY_STEREO, view, xr::VisibilityMaskTypeKHR::HIDDEN_TRIANGLE_MESH)
                .ctx("xrGetVisibilityMaskKHR")?;
            if mask.indices.len() % 3 != 0 {
                return fail(format!("xrGetVisibilityMaskKHR: view {view}: {} indices, not whole triangles", mask.indices.len()));
            }
            // What the tests read: the hidden area in the view's tangent plane.
            let v = |i: &u32| mask.vertices.get(*i as usize).map(|p| (p.x as f64, p.y as f64));
            let mut area = 0.0;
            for t in mask.indices.chunks_exact(3) {
                let (Some(a), Some(b), Some(c)) = (v(&t[0]), v(&t[1]), v(&t[2])) else {
                    return fail(format!("xrGetVisibilityMaskKHR: view {view}: an index past the {} vertices", mask.vertices.len()));
                };
                area += ((b.0 - a.0) * (c.1 - a.1) - (b.1 - a.1) * (c.0 - a.0)).abs() / 2.0;
            }
            eprintln!("xr-scene: visibility mask view {view}: {} triangles, hidden area {area:.6}", mask.indices.len() / 3);
            meshes.push(crate::scene::HiddenAreaMesh { vertices: mask.vertices.iter().map(|p| [p.x, p.y]).collect(), indices: mask.indices });
        }
        Ok(meshes)
    }

    /// Drains the event queue, following the session lifecycle. `before_end` runs before
    /// `xrEndSession` (`--threads`: the frame-pacing thread's wait in flight is collected first).
    pub fn poll_events(&mut self, inst: &xr::Instance, before_end: &mut dyn FnMut() -> Result<()>) -> Result<Flow> {
        let mut buf = xr::EventDataBuffer::new();
        while let Some(event) = inst.poll_event(&mut buf).ctx("xrPollEvent")? {
            match event {
                xr::Event::SessionStateChanged(e) => match e.state() {
                    xr::SessionState::READY => {
                        self.session
                            .begin(xr::ViewConfigurationType::PRIMARY_STEREO)
                            .ctx("xrBeginSession")?;
                        self.running = true;
                    }
                    xr::SessionState::STOPPING => {
                        before_end()?;
                        self.session.end().ctx("xrEndSession")?;
                        self.running = false;
                    }
                    xr::SessionState::EXITING => return Ok(Flow::Exit),
                    xr::SessionState::LOSS_PENDING => {
                        return fail("the session is being lost (XR_SESSION_STATE_LOSS_PENDING)")
                    }
                    _ => {}
                },
                xr::Event::InstanceLossPending(_) => {
                    return fail("the OpenXR instance is being lost (XrEventDataInstanceLossPending)")
                }
                _ => {}
            }
        }
        Ok(Flow::Continue)
    }

    /// Reads the controller like a game would; the quit button asks the runtime to end the session.
    pub fn sync_input(&mut self, display_time: xr::Time) -> Result<()> {
        self.session
            .sync_actions(&[xr::ActiveActionSet::new(&self.action_set)])
            .ctx("xrSyncActions")?;
        let quit = self.quit.state(&self.session, self.left_hand).ctx("xrGetActionStateBoolean")?;
        // A real app would place a controller model here; we only exercise the call.
        let _ = self.grip_space.locate(&self.stage, display_time).ctx("xrLocateSpace")?;
        if quit.is_active && quit.current_state {
            self.request_exit()?;
        }
        Ok(())
    }

    /// Destroys the spaces and actions (their `Drop`), then the session through the raw entry
    /// point, so a failing `xrDestroySession` is reported (the openxr crate's `Drop` ignores it).
    pub fn destroy(self) -> Result<()> {
        let XrSession { grip_space, stage, quit, _pose, action_set, waiter, stream, session, .. } = self;
        drop((grip_space, stage, quit, _pose, action_set, waiter, stream));
        // SAFETY: the session's swapchains and spaces are gone; the wrapper is forgotten so its
        // `Drop` does not destroy the handle again.
        let r = unsafe { (session.instance().fp().destroy_session)(session.as_raw()) };
        std::mem::forget(session);
        crate::error::check(r, "xrDestroySession")
    }

    /// Destroys the session's spaces and actions and leaves the session itself (and its
    /// swapchains) to `xrDestroyInstance` (`--teardown instance`).
    pub fn leave(self) {
        let XrSession { grip_space, stage, quit, _pose, action_set, waiter, stream, session, .. } = self;
        drop((grip_space, stage, quit, _pose, action_set, waiter, stream));
        // Forgotten: its `Drop` would destroy it.
        std::mem::forget(session);
    }

    pub fn request_exit(&mut self) -> Result<()> {
        if !self.exit_requested && self.running {
            self.session.request_exit().ctx("xrRequestExitSession")?;
            self.exit_requested = true;
        }
        Ok(())
    }
}

/// The swapchain formats for colour. `srgb` picks the first runtime-offered 8-bit sRGB format,
/// `unorm` the first 8-bit UNORM one (runtimes list their preference first).
pub fn pick_color_format(offered: &[u32], srgb: bool) -> Option<u32> {
    use ash::vk::Format as F;
    let family: &[F] = if srgb {
        &[F::R8G8B8A8_SRGB, F::B8G8R8A8_SRGB]
    } else {
        &[F::R8G8B8A8_UNORM, F::B8G8R8A8_UNORM]
    };
    offered.iter().copied().find(|f| family.iter().any(|x| x.as_raw() as u32 == *f))
}

/// Depth formats in the app's order of preference.
pub const DEPTH_FORMATS: &[ash::vk::Format] = &[
    ash::vk::Format::D32_SFLOAT,
    ash::vk::Format::D24_UNORM_S8_UINT,
    ash::vk::Format::D32_SFLOAT_S8_UINT,
    ash::vk::Format::X8_D24_UNORM_PACK32,
    ash::vk::Format::D16_UNORM,
];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn color_format_follows_runtime_order() {
        let offered = [44u32, 50, 43, 37];
        assert_eq!(pick_color_format(&offered, true), Some(50));
        assert_eq!(pick_color_format(&offered, false), Some(44));
        assert_eq!(pick_color_format(&[97], true), None);
    }
}
