//! The one list of OpenXR calls the layer touches, and the next layer's dispatch table made from
//! it. The list is a macro that hands it to another (`xr_calls!(then)` expands `then! { hooks {..}
//! calls {..} }`): this module expands it into `Next`, the shell into its hook lookup (naming the
//! hook of each `hooks` entry by its field), so a hook can never be handed out without the
//! dispatch entry it calls, and this contract never names the shell.

use openxr_sys as xr;

/// Every call the layer intercepts (`hooks`: the name, the field of the next layer's dispatch
/// table, its function type; the shell's hook has the field's name) and every call the layer makes
/// for its own purposes (`calls`), handed to the macro `$then`.
macro_rules! xr_calls {
    ($then:ident) => {
        $then! {
            hooks {
            "xrDestroyInstance" => destroy_instance: DestroyInstance,
            "xrEnumerateViewConfigurationViews" => enumerate_view_configuration_views: EnumerateViewConfigurationViews,
            "xrPollEvent" => poll_event: PollEvent,
            "xrCreateSession" => create_session: CreateSession,
            "xrDestroySession" => destroy_session: DestroySession,
            "xrLocateViews" => locate_views: LocateViews,
            "xrGetVisibilityMaskKHR" => get_visibility_mask: GetVisibilityMaskKHR,
            "xrBeginFrame" => begin_frame: BeginFrame,
            "xrEndFrame" => end_frame: EndFrame,
            "xrCreateSwapchain" => create_swapchain: CreateSwapchain,
            "xrDestroySwapchain" => destroy_swapchain: DestroySwapchain,
            "xrEnumerateSwapchainImages" => enumerate_swapchain_images: EnumerateSwapchainImages,
            "xrAcquireSwapchainImage" => acquire_swapchain_image: AcquireSwapchainImage,
            "xrWaitSwapchainImage" => wait_swapchain_image: WaitSwapchainImage,
            "xrReleaseSwapchainImage" => release_swapchain_image: ReleaseSwapchainImage,
            "xrCreateVulkanInstanceKHR" => create_vulkan_instance: CreateVulkanInstanceKHR,
            "xrCreateVulkanDeviceKHR" => create_vulkan_device: CreateVulkanDeviceKHR,
            "xrGetVulkanInstanceExtensionsKHR" => get_vulkan_instance_extensions: GetVulkanInstanceExtensionsKHR,
            "xrGetVulkanDeviceExtensionsKHR" => get_vulkan_device_extensions: GetVulkanDeviceExtensionsKHR,
            "xrAttachSessionActionSets" => attach_session_action_sets: AttachSessionActionSets,
            "xrSyncActions" => sync_actions: SyncActions,
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
    };
}
pub(crate) use xr_calls;

/// The dispatch table of the list's calls.
macro_rules! next_table {
    (
        hooks { $($name:literal => $field:ident: $pfn:ident,)* }
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
            pub(crate) unsafe fn load(gipa: xr::pfn::GetInstanceProcAddr, instance: xr::Instance) -> Next {
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
        }
    };
}

xr_calls!(next_table);
