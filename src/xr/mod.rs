//! OpenXR API-layer shell: the loader negotiation, `xrCreateApiLayerInstance`, and the one table of
//! intercepted calls. Everything unsafe about the OpenXR side lives under `src/xr/`; what the hooks
//! decide is in the safe modules of the crate.

mod actions;
pub(crate) mod feature;
mod frame;
pub mod headless;
mod instance;
mod overlay;
pub(crate) mod session;
mod swapchain;
pub(crate) mod upscale;
mod upscale_layers;
mod upscale_lens;
pub mod probe;
mod vulkan;

use crate::core::config::Config;
use crate::guard::PassThrough;
use crate::core::handles::HandleMap;
use openxr_sys as xr;
use openxr_sys::Handle as _;
use std::ffi::{c_char, CStr};
use std::sync::{Arc, OnceLock};

/// Declares every intercepted call once: the name, the field of the next layer's dispatch table,
/// its type, and the hook. `Next` and the proc-addr lookup are both generated from this list, so a
/// hook can never be handed out without the dispatch entry it calls.
macro_rules! intercepts {
    (
        hooks { $($name:literal => $field:ident: $pfn:ident = $hook:path,)* }
        calls { $($cname:literal => $cfield:ident: $cpfn:ident,)* }
    ) => {
        /// The next layer's (or the runtime's) functions for one instance: those we intercept and
        /// those the layer calls for its own purposes (`calls`).
        #[derive(Clone, Copy)]
        pub(crate) struct Next {
            pub get_instance_proc_addr: xr::pfn::GetInstanceProcAddr,
            $(pub $field: Option<xr::pfn::$pfn>,)*
            $(pub $cfield: Option<xr::pfn::$cpfn>,)*
        }

        impl Next {
            /// # Safety
            /// `gipa` must be the next layer's `xrGetInstanceProcAddr` and `instance` a live
            /// instance created through it.
            unsafe fn load(gipa: xr::pfn::GetInstanceProcAddr, instance: xr::Instance) -> Next {
                Next {
                    get_instance_proc_addr: gipa,
                    $($field: {
                        let mut f: Option<xr::pfn::VoidFunction> = None;
                        // SAFETY: the name is a NUL-terminated literal and `f` a valid out pointer;
                        // the function returned for this name has the type `$pfn` by the spec.
                        unsafe {
                            let r = gipa(instance, concat!($name, "\0").as_ptr().cast(), &mut f);
                            if r == xr::Result::SUCCESS {
                                f.map(|f| std::mem::transmute::<xr::pfn::VoidFunction, xr::pfn::$pfn>(f))
                            } else {
                                None
                            }
                        }
                    },)*
                    $($cfield: {
                        let mut f: Option<xr::pfn::VoidFunction> = None;
                        // SAFETY: as above, for the functions the layer calls itself.
                        unsafe {
                            let r = gipa(instance, concat!($cname, "\0").as_ptr().cast(), &mut f);
                            if r == xr::Result::SUCCESS {
                                f.map(|f| std::mem::transmute::<xr::pfn::VoidFunction, xr::pfn::$cpfn>(f))
                            } else {
                                None
                            }
                        }
                    },)*
                }
            }

            /// Our hook for `name`, if we intercept it and the next layer has it.
            fn hook(&self, name: &str) -> Option<xr::pfn::VoidFunction> {
                match name {
                    // SAFETY: transmuting between function pointer types; the loader casts the
                    // pointer back to the type the spec gives `name`, which is `$pfn`.
                    $($name => self.$field.map(|_| unsafe {
                        std::mem::transmute::<xr::pfn::$pfn, xr::pfn::VoidFunction>($hook as xr::pfn::$pfn)
                    }),)*
                    _ => None,
                }
            }
        }

        /// Names of all intercepted calls (documentation, `stereoshim status`, tests).
        pub const INTERCEPTED: &[&str] = &[$($name),*];
    };
}

intercepts! {
    hooks {
    "xrDestroyInstance" => destroy_instance: DestroyInstance = instance::destroy_instance,
    "xrEnumerateViewConfigurationViews" => enumerate_view_configuration_views: EnumerateViewConfigurationViews = instance::enumerate_view_configuration_views,
    "xrPollEvent" => poll_event: PollEvent = instance::poll_event,
    "xrCreateSession" => create_session: CreateSession = session::create_session,
    "xrDestroySession" => destroy_session: DestroySession = session::destroy_session,
    "xrLocateViews" => locate_views: LocateViews = session::locate_views,
    "xrGetVisibilityMaskKHR" => get_visibility_mask: GetVisibilityMaskKHR = session::get_visibility_mask,
    "xrBeginFrame" => begin_frame: BeginFrame = frame::begin_frame,
    "xrEndFrame" => end_frame: EndFrame = frame::end_frame,
    "xrCreateSwapchain" => create_swapchain: CreateSwapchain = swapchain::create_swapchain,
    "xrDestroySwapchain" => destroy_swapchain: DestroySwapchain = swapchain::destroy_swapchain,
    "xrEnumerateSwapchainImages" => enumerate_swapchain_images: EnumerateSwapchainImages = swapchain::enumerate_swapchain_images,
    "xrAcquireSwapchainImage" => acquire_swapchain_image: AcquireSwapchainImage = swapchain::acquire_swapchain_image,
    "xrWaitSwapchainImage" => wait_swapchain_image: WaitSwapchainImage = swapchain::wait_swapchain_image,
    "xrReleaseSwapchainImage" => release_swapchain_image: ReleaseSwapchainImage = swapchain::release_swapchain_image,
    "xrCreateVulkanInstanceKHR" => create_vulkan_instance: CreateVulkanInstanceKHR = vulkan::create_vulkan_instance,
    "xrCreateVulkanDeviceKHR" => create_vulkan_device: CreateVulkanDeviceKHR = vulkan::create_vulkan_device,
    "xrGetVulkanInstanceExtensionsKHR" => get_vulkan_instance_extensions: GetVulkanInstanceExtensionsKHR = vulkan::get_vulkan_instance_extensions,
    "xrGetVulkanDeviceExtensionsKHR" => get_vulkan_device_extensions: GetVulkanDeviceExtensionsKHR = vulkan::get_vulkan_device_extensions,
    "xrAttachSessionActionSets" => attach_session_action_sets: AttachSessionActionSets = actions::attach_session_action_sets,
    "xrSyncActions" => sync_actions: SyncActions = actions::sync_actions,
    }
    calls {
    "xrStringToPath" => string_to_path: StringToPath,
    "xrCreateActionSet" => create_action_set: CreateActionSet,
    "xrDestroyActionSet" => destroy_action_set: DestroyActionSet,
    "xrCreateAction" => create_action: CreateAction,
    "xrSuggestInteractionProfileBindings" => suggest_interaction_profile_bindings: SuggestInteractionProfileBindings,
    "xrCreateActionSpace" => create_action_space: CreateActionSpace,
    "xrLocateSpace" => locate_space: LocateSpace,
    "xrEnumerateSwapchainFormats" => enumerate_swapchain_formats: EnumerateSwapchainFormats,
    "xrCreateReferenceSpace" => create_reference_space: CreateReferenceSpace,
    "xrDestroySpace" => destroy_space: DestroySpace,
    "xrGetSystemProperties" => get_system_properties: GetSystemProperties,
    }
}

/// Per-instance state; creation data is immutable.
pub(crate) struct Instance {
    pub handle: xr::Instance,
    pub next: Next,
    /// The configuration at instance creation: decides what cannot change later (the master
    /// switch: hooks are handed out once; extensions). Features read the live one,
    /// `shared().config()`.
    pub config: Arc<Config>,
    pub pass_through: PassThrough,
    pub app_name: String,
    pub stats: instance::Stats,
    /// Extensions the app enabled.
    pub app_extensions: Vec<String>,
    /// Extensions the layer enabled for itself; their functions and events stay hidden from the app.
    pub layer_extensions: Vec<String>,
    /// The config file, re-read when it changes; feature settings then apply from the next frame.
    pub watch: crate::core::config::Watch,
    /// The upscale's latched sizes (`xrEnumerateViewConfigurationViews`).
    pub upscale: upscale::InstanceUpscale,
    /// The features' per-instance state (made by the registry).
    pub features: crate::registry::XrInstanceFeatures,
}

pub(crate) const VISIBILITY_MASK_EXT: &str = "XR_KHR_visibility_mask";

/// An `XrVisibilityMaskKHR` asking for the counts only (the two-call idiom's first call).
pub(crate) fn empty_visibility_mask() -> xr::VisibilityMaskKHR {
    xr::VisibilityMaskKHR {
        ty: xr::VisibilityMaskKHR::TYPE,
        next: std::ptr::null_mut(),
        vertex_capacity_input: 0,
        vertex_count_output: 0,
        vertices: std::ptr::null_mut(),
        index_capacity_input: 0,
        index_count_output: 0,
        indices: std::ptr::null_mut(),
    }
}
pub(crate) const EYE_GAZE_EXT: &str = "XR_EXT_eye_gaze_interaction";

/// The extension an extension function belongs to, for those the layer may enable for itself.
fn extension_of(function: &str) -> Option<&'static str> {
    match function {
        "xrGetVisibilityMaskKHR" => Some(VISIBILITY_MASK_EXT),
        _ => None,
    }
}

impl Instance {
    /// Whether the app (not only the layer) enabled `ext`.
    pub fn app_enabled(&self, ext: &str) -> bool {
        self.app_extensions.iter().any(|e| e == ext)
    }
    /// Whether the layer enabled `ext` for itself or the app did.
    pub fn has_extension(&self, ext: &str) -> bool {
        self.app_enabled(ext) || self.layer_extensions.iter().any(|e| e == ext)
    }

    /// Layer logic of `call` fails on purpose when the config says so (`debug.fail_in`), to prove
    /// the fallback to pass-through end to end.
    fn check_fault(&self, call: &str) -> Result<(), crate::guard::Fault> {
        if self.config.fails_in(call) {
            return Err(crate::guard::Fault(format!("forced by debug.fail_in for {call}")));
        }
        Ok(())
    }
}

#[derive(Default)]
pub(crate) struct XrState {
    pub instances: HandleMap<u64, Instance>,
    pub sessions: HandleMap<u64, session::Session>,
    pub swapchains: HandleMap<u64, swapchain::Swapchain>,
}

/// The live settings (published with the config at instance creation and on every reload), else
/// those of the instance's own config.
/// Makes `config` the process's live configuration, and its typed settings the live settings
/// (`crate::plugin::settings::current`), in that order of publication.
pub(crate) fn publish_config(config: Arc<Config>) {
    crate::plugin::settings::publish(crate::plugin::settings::Settings::from_config(&config));
    crate::bridge::shared().set_config(config);
}

pub(crate) fn settings(inst: &Instance) -> std::sync::Arc<crate::plugin::settings::Settings> {
    crate::plugin::settings::current().unwrap_or_else(|| std::sync::Arc::new(crate::plugin::settings::Settings::from_config(&inst.config)))
}

pub(crate) fn state() -> &'static XrState {
    static STATE: OnceLock<XrState> = OnceLock::new();
    STATE.get_or_init(XrState::default)
}

/// The instance to call down through for a handle the layer never saw created (the app passed a
/// bad handle): the loader allows one instance per process, so that one is the only candidate,
/// and the runtime gets to report the error the spec asks for.
fn sole_instance() -> Option<Arc<Instance>> {
    let all = state().instances.values();
    match all.as_slice() {
        [(_, only)] => Some(only.clone()),
        _ => None,
    }
}

/// The state of an instance the app passed, or the one to forward an unknown handle through.
fn instance_for(instance: xr::Instance) -> Option<Arc<Instance>> {
    state().instances.get(instance.into_raw()).or_else(sole_instance)
}

/// Reads a fixed-size, NUL-terminated C string field.
fn fixed_str(chars: &[c_char]) -> String {
    let bytes: Vec<u8> = chars.iter().take_while(|&&c| c != 0).map(|&c| c as u8).collect();
    String::from_utf8_lossy(&bytes).into_owned()
}

/// The loader's first call into the layer.
///
/// # Safety
/// Called by the OpenXR loader with pointers valid per the loader interface.
#[no_mangle]
pub unsafe extern "system" fn xrNegotiateLoaderApiLayerInterface(
    loader_info: *const xr::NegotiateLoaderInfo,
    _layer_name: *const c_char,
    request: *mut xr::NegotiateApiLayerRequest,
) -> xr::Result {
    crate::guard::catch("xrNegotiateLoaderApiLayerInterface", xr::Result::ERROR_INITIALIZATION_FAILED, || {
        // SAFETY: the loader passes valid pointers or null; null is rejected before use.
        let (Some(info), Some(req)) = (unsafe { loader_info.as_ref() }, unsafe { request.as_mut() }) else {
            return xr::Result::ERROR_INITIALIZATION_FAILED;
        };
        if info.struct_type != xr::NegotiateLoaderInfo::TYPE
            || info.struct_version != xr::NegotiateLoaderInfo::VERSION
            || info.struct_size != std::mem::size_of::<xr::NegotiateLoaderInfo>()
            || req.struct_type != xr::NegotiateApiLayerRequest::TYPE
            || req.struct_version != xr::NegotiateApiLayerRequest::VERSION
            || req.struct_size != std::mem::size_of::<xr::NegotiateApiLayerRequest>()
            || !(info.min_interface_version..=info.max_interface_version).contains(&1)
        {
            return xr::Result::ERROR_INITIALIZATION_FAILED;
        }
        req.layer_interface_version = 1;
        req.layer_api_version = xr::CURRENT_API_VERSION;
        req.get_instance_proc_addr = Some(get_instance_proc_addr);
        req.create_api_layer_instance = Some(instance::create_api_layer_instance);
        xr::Result::SUCCESS
    })
}

/// Our hooks for intercepted names, the next layer's functions for everything else.
unsafe extern "system" fn get_instance_proc_addr(
    instance: xr::Instance,
    name: *const c_char,
    function: *mut Option<xr::pfn::VoidFunction>,
) -> xr::Result {
    crate::guard::catch("xrGetInstanceProcAddr", xr::Result::ERROR_RUNTIME_FAILURE, || {
        if name.is_null() || function.is_null() {
            return xr::Result::ERROR_VALIDATION_FAILURE;
        }
        // SAFETY: non-null, NUL-terminated per the spec.
        let name_str = unsafe { CStr::from_ptr(name) }.to_str().unwrap_or("");
        if name_str == "xrGetInstanceProcAddr" {
            // SAFETY: `function` checked non-null above.
            unsafe { *function = Some(std::mem::transmute::<xr::pfn::GetInstanceProcAddr, xr::pfn::VoidFunction>(get_instance_proc_addr)) };
            return xr::Result::SUCCESS;
        }
        let Some(inst) = state().instances.get(instance.into_raw()) else {
            return xr::Result::ERROR_HANDLE_INVALID;
        };
        // Functions of extensions only the layer enabled do not exist for the app.
        if extension_of(name_str).is_some_and(|ext| !inst.app_enabled(ext)) {
            // SAFETY: `function` checked non-null above.
            unsafe { *function = None };
            return xr::Result::ERROR_FUNCTION_UNSUPPORTED;
        }
        // SAFETY: forwarding the caller's valid arguments to the next layer.
        let r = unsafe { (inst.next.get_instance_proc_addr)(instance, name, function) };
        if r == xr::Result::SUCCESS && inst.config.enabled() {
            if let Some(hook) = inst.next.hook(name_str) {
                // SAFETY: `function` checked non-null above.
                unsafe { *function = Some(hook) };
            }
        }
        r
    })
}
