//! Shared fixture of the mock runtime's API tests: loads the real Khronos loader with a manifest
//! pointing at the freshly built runtime, creates instances, Vulkan objects (lavapipe, with the
//! validation layer when installed) and sessions through raw OpenXR calls, so that tests can
//! make exactly the (mis)calls they want.
#![allow(dead_code)]

use std::ffi::{c_char, c_void, CStr, CString};
use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Mutex, MutexGuard, OnceLock};

use ash::vk;
use ash::vk::Handle as _;
use openxr_sys as xr;
use xr::pfn;
use xr::Handle as _;

/// The loader allows one live instance per process: tests of a binary take turns.
pub fn serial() -> MutexGuard<'static, ()> {
    static M: Mutex<()> = Mutex::new(());
    let g = M.lock().unwrap_or_else(|e| e.into_inner());
    for (k, _) in std::env::vars() {
        if k.starts_with("MOCK_XR_") && k != "MOCK_XR_LOG" {
            std::env::remove_var(k);
        }
    }
    g
}

pub fn target_dir() -> PathBuf {
    // target/debug/deps/<test> → target/debug
    let exe = std::env::current_exe().unwrap();
    exe.parent().unwrap().parent().unwrap().to_path_buf()
}

pub fn set_manifest() {
    static DONE: OnceLock<()> = OnceLock::new();
    DONE.get_or_init(|| {
        let lib = target_dir().join("libmock_runtime.so");
        assert!(lib.exists(), "{} missing: run `cargo build -p mock-runtime` first", lib.display());
        let dir = std::env::temp_dir().join(format!("mock-runtime-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let manifest = dir.join("manifest.json");
        let text = serde_json::json!({
            "file_format_version": "1.0.0",
            "runtime": { "name": "mock runtime (tests)", "library_path": lib.to_str().unwrap() }
        });
        std::fs::write(&manifest, text.to_string()).unwrap();
        std::env::set_var("XR_RUNTIME_JSON", &manifest);
    });
}

pub fn scratch_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("mock-runtime-test-{}", std::process::id())).join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

pub fn entry() -> &'static openxr::Entry {
    static E: OnceLock<openxr::Entry> = OnceLock::new();
    set_manifest();
    // SAFETY: loading the system's Khronos loader.
    E.get_or_init(|| unsafe { openxr::Entry::load_from(std::path::Path::new("libopenxr_loader.so.1"), &()) }.expect("libopenxr_loader.so.1"))
}

pub struct Xr {
    pub instance: xr::Instance,
    pub system: xr::SystemId,
    gipa: pfn::GetInstanceProcAddr,
}

pub fn cstr_array(names: &[&str]) -> (Vec<CString>, Vec<*const c_char>) {
    let owned: Vec<CString> = names.iter().map(|n| CString::new(*n).unwrap()).collect();
    let ptrs = owned.iter().map(|c| c.as_ptr()).collect();
    (owned, ptrs)
}

pub fn try_create_instance(exts: &[&str], api: xr::Version) -> Result<Xr, xr::Result> {
    let e = entry();
    let (_keep, ptrs) = cstr_array(exts);
    let mut app = xr::ApplicationInfo {
        application_name: [0; xr::MAX_APPLICATION_NAME_SIZE],
        application_version: 1,
        engine_name: [0; xr::MAX_ENGINE_NAME_SIZE],
        engine_version: 1,
        api_version: api,
    };
    for (d, s) in app.application_name.iter_mut().zip(b"mock-runtime-test") {
        *d = *s as c_char;
    }
    let ci = xr::InstanceCreateInfo {
        ty: xr::InstanceCreateInfo::TYPE,
        next: std::ptr::null(),
        create_flags: xr::InstanceCreateFlags::EMPTY,
        application_info: app,
        enabled_api_layer_count: 0,
        enabled_api_layer_names: std::ptr::null(),
        enabled_extension_count: ptrs.len() as u32,
        enabled_extension_names: ptrs.as_ptr(),
    };
    let mut instance = xr::Instance::NULL;
    // SAFETY: valid create info.
    let r = unsafe { (e.fp().create_instance)(&ci, &mut instance) };
    if r != xr::Result::SUCCESS {
        return Err(r);
    }
    let mut x = Xr { instance, system: xr::SystemId::from_raw(0), gipa: e.fp().get_instance_proc_addr };
    let gi = xr::SystemGetInfo { ty: xr::SystemGetInfo::TYPE, next: std::ptr::null(), form_factor: xr::FormFactor::HEAD_MOUNTED_DISPLAY };
    let get_system: pfn::GetSystem = x.f("xrGetSystem");
    // SAFETY: valid instance and struct.
    assert_eq!(unsafe { get_system(instance, &gi, &mut x.system) }, xr::Result::SUCCESS);
    Ok(x)
}

pub fn create_instance(exts: &[&str]) -> Xr {
    try_create_instance(exts, xr::Version::new(1, 0, 0)).expect("xrCreateInstance")
}

impl Xr {
    pub fn try_f<T: Copy>(&self, name: &str) -> Result<T, xr::Result> {
        assert_eq!(std::mem::size_of::<T>(), std::mem::size_of::<pfn::VoidFunction>());
        let n = CString::new(name).unwrap();
        let mut f: Option<pfn::VoidFunction> = None;
        // SAFETY: valid instance and name.
        let r = unsafe { (self.gipa)(self.instance, n.as_ptr(), &mut f) };
        if r != xr::Result::SUCCESS {
            return Err(r);
        }
        let f = f.expect("non-null on success");
        // SAFETY: the caller names the matching pfn type.
        Ok(unsafe { std::mem::transmute_copy::<pfn::VoidFunction, T>(&f) })
    }

    pub fn f<T: Copy>(&self, name: &str) -> T {
        self.try_f(name).unwrap_or_else(|e| panic!("{name}: {e:?}"))
    }

    /// Drains the event queue: (structure type, session state for state events).
    pub fn events(&self) -> Vec<(xr::StructureType, Option<xr::SessionState>)> {
        let poll: pfn::PollEvent = self.f("xrPollEvent");
        let mut out = Vec::new();
        loop {
            // SAFETY: XrEventDataBuffer is plain data.
            let mut buf: xr::EventDataBuffer = unsafe { std::mem::zeroed() };
            buf.ty = xr::EventDataBuffer::TYPE;
            // SAFETY: valid instance and buffer.
            let r = unsafe { poll(self.instance, &mut buf) };
            if r == xr::Result::EVENT_UNAVAILABLE {
                return out;
            }
            assert_eq!(r, xr::Result::SUCCESS);
            let state = (buf.ty == xr::StructureType::EVENT_DATA_SESSION_STATE_CHANGED)
                // SAFETY: the type says so.
                .then(|| unsafe { (*(&buf as *const _ as *const xr::EventDataSessionStateChanged)).state });
            out.push((buf.ty, state));
        }
    }

    pub fn states(&self) -> Vec<xr::SessionState> {
        self.events().into_iter().filter_map(|(_, s)| s).collect()
    }

    pub fn graphics_requirements(&self, enable2: bool) {
        let mut req = xr::GraphicsRequirementsVulkanKHR {
            ty: xr::GraphicsRequirementsVulkanKHR::TYPE,
            next: std::ptr::null_mut(),
            min_api_version_supported: xr::Version::new(0, 0, 0),
            max_api_version_supported: xr::Version::new(0, 0, 0),
        };
        let name = if enable2 { "xrGetVulkanGraphicsRequirements2KHR" } else { "xrGetVulkanGraphicsRequirementsKHR" };
        let f: pfn::GetVulkanGraphicsRequirementsKHR = self.f(name);
        // SAFETY: valid arguments.
        assert_eq!(unsafe { f(self.instance, self.system, &mut req) }, xr::Result::SUCCESS);
        assert_eq!(req.min_api_version_supported, xr::Version::new(1, 0, 0));
    }
}

impl Drop for Xr {
    fn drop(&mut self) {
        if let Ok(f) = self.try_f::<pfn::DestroyInstance>("xrDestroyInstance") {
            // SAFETY: our instance.
            unsafe { f(self.instance) };
        }
    }
}

pub static VALIDATION_ERRORS: AtomicUsize = AtomicUsize::new(0);

unsafe extern "system" fn debug_cb(
    severity: vk::DebugUtilsMessageSeverityFlagsEXT,
    _ty: vk::DebugUtilsMessageTypeFlagsEXT,
    data: *const vk::DebugUtilsMessengerCallbackDataEXT<'_>,
    _user: *mut c_void,
) -> vk::Bool32 {
    // SAFETY: the validation layer passes valid callback data.
    let msg = unsafe { (*data).message_as_c_str() }.map(|m| m.to_string_lossy().into_owned()).unwrap_or_default();
    if severity.contains(vk::DebugUtilsMessageSeverityFlagsEXT::ERROR) {
        VALIDATION_ERRORS.fetch_add(1, Ordering::SeqCst);
        eprintln!("VALIDATION ERROR: {msg}");
    }
    vk::FALSE
}

pub struct Gfx {
    pub entry: ash::Entry,
    pub instance: ash::Instance,
    pub phys: vk::PhysicalDevice,
    pub device: ash::Device,
    pub queue: vk::Queue,
    pub family: u32,
    messenger: Option<(ash::ext::debug_utils::Instance, vk::DebugUtilsMessengerEXT)>,
    pub validation: bool,
}

fn validation_available(entry: &ash::Entry) -> bool {
    // SAFETY: plain enumeration.
    unsafe { entry.enumerate_instance_layer_properties() }
        .unwrap_or_default()
        .iter()
        .any(|l| l.layer_name_as_c_str().is_ok_and(|n| n == c"VK_LAYER_KHRONOS_validation"))
}

/// A Vulkan instance + device on lavapipe, through the runtime (enable2) or directly (enable).
pub fn create_gfx(x: &Xr, enable2: bool) -> Gfx {
    // SAFETY: loading the system Vulkan loader.
    let entry = unsafe { ash::Entry::load() }.expect("libvulkan");
    let validation = validation_available(&entry) && std::env::var("MOCK_TEST_NO_VALIDATION").is_err();
    let layers: Vec<*const c_char> = if validation { vec![c"VK_LAYER_KHRONOS_validation".as_ptr()] } else { vec![] };
    let mut exts: Vec<*const c_char> = if validation { vec![ash::ext::debug_utils::NAME.as_ptr()] } else { vec![] };
    let xr_exts = if enable2 {
        String::new()
    } else {
        let f: pfn::GetVulkanInstanceExtensionsKHR = x.f("xrGetVulkanInstanceExtensionsKHR");
        // SAFETY: valid instance/system; the helper passes matching buffers.
        two_call_string(|c, n, b| unsafe { f(x.instance, x.system, c, n, b) })
    };
    let (_k1, p1) = cstr_array(&xr_exts.split(' ').filter(|s| !s.is_empty()).collect::<Vec<_>>());
    exts.extend(p1);
    let app = vk::ApplicationInfo::default().api_version(vk::make_api_version(0, 1, 3, 0));
    let enables = [vk::ValidationFeatureEnableEXT::SYNCHRONIZATION_VALIDATION];
    let mut features = vk::ValidationFeaturesEXT::default().enabled_validation_features(&enables);
    let mut ci = vk::InstanceCreateInfo::default().application_info(&app).enabled_layer_names(&layers).enabled_extension_names(&exts);
    if validation {
        ci = ci.push_next(&mut features);
    }
    let gipa = entry.static_fn().get_instance_proc_addr;
    // SAFETY: identical ABI of vkGetInstanceProcAddr in both bindings.
    let xr_gipa: xr::platform::VkGetInstanceProcAddr = unsafe { std::mem::transmute(gipa) };
    let raw_instance = if enable2 {
        let f: pfn::CreateVulkanInstanceKHR = x.f("xrCreateVulkanInstanceKHR");
        let info = xr::VulkanInstanceCreateInfoKHR {
            ty: xr::VulkanInstanceCreateInfoKHR::TYPE,
            next: std::ptr::null(),
            system_id: x.system,
            create_flags: xr::VulkanInstanceCreateFlagsKHR::EMPTY,
            pfn_get_instance_proc_addr: Some(xr_gipa),
            vulkan_create_info: &ci as *const _ as *const c_void,
            vulkan_allocator: std::ptr::null(),
        };
        let mut out = std::ptr::null();
        let mut vr = 0;
        // SAFETY: valid arguments.
        assert_eq!(unsafe { f(x.instance, &info, &mut out, &mut vr) }, xr::Result::SUCCESS);
        assert_eq!(vr, 0, "vkCreateInstance");
        vk::Instance::from_raw(out as u64)
    } else {
        // SAFETY: valid create info.
        unsafe { entry.create_instance(&ci, None) }.expect("vkCreateInstance").handle()
    };
    // SAFETY: live instance.
    let instance = unsafe { ash::Instance::load(entry.static_fn(), raw_instance) };
    let messenger = validation.then(|| {
        let du = ash::ext::debug_utils::Instance::new(&entry, &instance);
        let mci = vk::DebugUtilsMessengerCreateInfoEXT::default()
            .message_severity(vk::DebugUtilsMessageSeverityFlagsEXT::ERROR | vk::DebugUtilsMessageSeverityFlagsEXT::WARNING)
            .message_type(vk::DebugUtilsMessageTypeFlagsEXT::VALIDATION | vk::DebugUtilsMessageTypeFlagsEXT::GENERAL | vk::DebugUtilsMessageTypeFlagsEXT::PERFORMANCE)
            .pfn_user_callback(Some(debug_cb));
        // SAFETY: valid create info.
        let m = unsafe { du.create_debug_utils_messenger(&mci, None) }.unwrap();
        (du, m)
    });
    let phys_raw = {
        let mut p = std::ptr::null();
        if enable2 {
            let f: pfn::GetVulkanGraphicsDevice2KHR = x.f("xrGetVulkanGraphicsDevice2KHR");
            let gi = xr::VulkanGraphicsDeviceGetInfoKHR {
                ty: xr::VulkanGraphicsDeviceGetInfoKHR::TYPE,
                next: std::ptr::null(),
                system_id: x.system,
                vulkan_instance: raw_instance.as_raw() as usize as *const c_void,
            };
            // SAFETY: valid arguments.
            assert_eq!(unsafe { f(x.instance, &gi, &mut p) }, xr::Result::SUCCESS);
        } else {
            let f: pfn::GetVulkanGraphicsDeviceKHR = x.f("xrGetVulkanGraphicsDeviceKHR");
            // SAFETY: valid arguments.
            assert_eq!(unsafe { f(x.instance, x.system, raw_instance.as_raw() as usize as *const c_void, &mut p) }, xr::Result::SUCCESS);
        }
        p
    };
    let phys = vk::PhysicalDevice::from_raw(phys_raw as u64);
    // SAFETY: valid physical device.
    let family = unsafe { instance.get_physical_device_queue_family_properties(phys) }
        .iter()
        .position(|f| f.queue_flags.contains(vk::QueueFlags::GRAPHICS))
        .unwrap() as u32;
    let prio = [1.0];
    let qci = [vk::DeviceQueueCreateInfo::default().queue_family_index(family).queue_priorities(&prio)];
    let dev_ext_str: String = if enable2 {
        String::new()
    } else {
        let f: pfn::GetVulkanDeviceExtensionsKHR = x.f("xrGetVulkanDeviceExtensionsKHR");
        // SAFETY: valid instance/system; the helper passes matching buffers.
        two_call_string(|c, n, b| unsafe { f(x.instance, x.system, c, n, b) })
    };
    let (_k2, dev_exts) = cstr_array(&dev_ext_str.split(' ').filter(|s| !s.is_empty()).collect::<Vec<_>>());
    let dci = vk::DeviceCreateInfo::default().queue_create_infos(&qci).enabled_extension_names(&dev_exts);
    let raw_device = if enable2 {
        let f: pfn::CreateVulkanDeviceKHR = x.f("xrCreateVulkanDeviceKHR");
        let info = xr::VulkanDeviceCreateInfoKHR {
            ty: xr::VulkanDeviceCreateInfoKHR::TYPE,
            next: std::ptr::null(),
            system_id: x.system,
            create_flags: xr::VulkanDeviceCreateFlagsKHR::EMPTY,
            pfn_get_instance_proc_addr: Some(xr_gipa),
            vulkan_physical_device: phys_raw,
            vulkan_create_info: &dci as *const _ as *const c_void,
            vulkan_allocator: std::ptr::null(),
        };
        let mut out = std::ptr::null();
        let mut vr = 0;
        // SAFETY: valid arguments.
        assert_eq!(unsafe { f(x.instance, &info, &mut out, &mut vr) }, xr::Result::SUCCESS);
        assert_eq!(vr, 0, "vkCreateDevice");
        vk::Device::from_raw(out as u64)
    } else {
        // SAFETY: valid create info.
        unsafe { instance.create_device(phys, &dci, None) }.expect("vkCreateDevice").handle()
    };
    // SAFETY: live device.
    let device = unsafe { ash::Device::load(instance.fp_v1_0(), raw_device) };
    // SAFETY: queue 0 of the family was created.
    let queue = unsafe { device.get_device_queue(family, 0) };
    Gfx { entry, instance, phys, device, queue, family, messenger, validation }
}

impl Gfx {
    pub fn binding(&self) -> xr::GraphicsBindingVulkanKHR {
        xr::GraphicsBindingVulkanKHR {
            ty: xr::GraphicsBindingVulkanKHR::TYPE,
            next: std::ptr::null(),
            instance: self.instance.handle().as_raw() as usize as *const c_void,
            physical_device: self.phys.as_raw() as usize as *const c_void,
            device: self.device.handle().as_raw() as usize as *const c_void,
            queue_family_index: self.family,
            queue_index: 0,
        }
    }

    /// Records and runs `f` on the queue, waiting for it.
    pub fn run(&self, f: impl FnOnce(vk::CommandBuffer)) {
        let d = &self.device;
        // SAFETY: plain Vulkan usage on our own objects.
        unsafe {
            let pool = d.create_command_pool(&vk::CommandPoolCreateInfo::default().queue_family_index(self.family), None).unwrap();
            let cb = d
                .allocate_command_buffers(&vk::CommandBufferAllocateInfo::default().command_pool(pool).command_buffer_count(1))
                .unwrap()[0];
            d.begin_command_buffer(cb, &vk::CommandBufferBeginInfo::default()).unwrap();
            f(cb);
            d.end_command_buffer(cb).unwrap();
            let fence = d.create_fence(&vk::FenceCreateInfo::default(), None).unwrap();
            d.queue_submit(self.queue, &[vk::SubmitInfo::default().command_buffers(&[cb])], fence).unwrap();
            d.wait_for_fences(&[fence], true, u64::MAX).unwrap();
            d.destroy_fence(fence, None);
            d.destroy_command_pool(pool, None);
        }
    }

    /// Fills layer `layer` of a colour image (in COLOR_ATTACHMENT_OPTIMAL) with `rgba` and
    /// returns it to that layout, as an app rendering into it would.
    pub fn clear_color(&self, image: vk::Image, layer: u32, rgba: [f32; 4]) {
        self.clear_color_ex(image, layer, rgba, true)
    }

    /// `restore == false` leaves the image in TRANSFER_DST_OPTIMAL: a buggy app (or layer).
    pub fn clear_color_ex(&self, image: vk::Image, layer: u32, rgba: [f32; 4], restore: bool) {
        let range = vk::ImageSubresourceRange { aspect_mask: vk::ImageAspectFlags::COLOR, base_mip_level: 0, level_count: 1, base_array_layer: layer, layer_count: 1 };
        self.run(|cb| {
            let d = &self.device;
            let to = vk::ImageMemoryBarrier::default()
                .src_access_mask(vk::AccessFlags::COLOR_ATTACHMENT_WRITE)
                .dst_access_mask(vk::AccessFlags::TRANSFER_WRITE)
                .old_layout(vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL)
                .new_layout(vk::ImageLayout::TRANSFER_DST_OPTIMAL)
                .src_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
                .dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
                .image(image)
                .subresource_range(range);
            let back = vk::ImageMemoryBarrier::default()
                .src_access_mask(vk::AccessFlags::TRANSFER_WRITE)
                .dst_access_mask(vk::AccessFlags::COLOR_ATTACHMENT_WRITE | vk::AccessFlags::COLOR_ATTACHMENT_READ)
                .old_layout(vk::ImageLayout::TRANSFER_DST_OPTIMAL)
                .new_layout(vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL)
                .src_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
                .dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
                .image(image)
                .subresource_range(range);
            // SAFETY: recording into our command buffer.
            unsafe {
                d.cmd_pipeline_barrier(cb, vk::PipelineStageFlags::COLOR_ATTACHMENT_OUTPUT, vk::PipelineStageFlags::TRANSFER, vk::DependencyFlags::empty(), &[], &[], &[to]);
                d.cmd_clear_color_image(cb, image, vk::ImageLayout::TRANSFER_DST_OPTIMAL, &vk::ClearColorValue { float32: rgba }, &[range]);
                if restore {
                    d.cmd_pipeline_barrier(cb, vk::PipelineStageFlags::TRANSFER, vk::PipelineStageFlags::COLOR_ATTACHMENT_OUTPUT, vk::DependencyFlags::empty(), &[], &[], &[back]);
                }
            }
        });
    }

    pub fn destroy(&mut self) {
        // SAFETY: tear-down after the OpenXR instance (and with it every session) is gone.
        unsafe {
            let _ = self.device.device_wait_idle();
            self.device.destroy_device(None);
            if let Some((du, m)) = self.messenger.take() {
                du.destroy_debug_utils_messenger(m, None);
            }
            self.instance.destroy_instance(None);
        }
    }
}

pub fn two_call_string(mut f: impl FnMut(u32, *mut u32, *mut c_char) -> xr::Result) -> String {
    let mut n = 0;
    assert_eq!(f(0, &mut n, std::ptr::null_mut()), xr::Result::SUCCESS);
    let mut buf = vec![0 as c_char; n as usize];
    assert_eq!(f(n, &mut n, buf.as_mut_ptr()), xr::Result::SUCCESS);
    // SAFETY: NUL-terminated by the runtime.
    unsafe { CStr::from_ptr(buf.as_ptr()) }.to_string_lossy().into_owned()
}

/// An instance with Vulkan and a session on it; torn down in the right order.
pub struct Fixture {
    pub xr: Option<Xr>,
    pub gfx: Gfx,
    pub session: xr::Session,
}

impl Fixture {
    pub fn xr(&self) -> &Xr {
        self.xr.as_ref().unwrap()
    }
}

impl Drop for Fixture {
    fn drop(&mut self) {
        drop(self.xr.take());
        self.gfx.destroy();
    }
}

pub fn try_create_session(x: &Xr, gfx: &Gfx) -> Result<xr::Session, xr::Result> {
    let binding = gfx.binding();
    let ci = xr::SessionCreateInfo {
        ty: xr::SessionCreateInfo::TYPE,
        next: &binding as *const _ as *const c_void,
        create_flags: xr::SessionCreateFlags::EMPTY,
        system_id: x.system,
    };
    let f: pfn::CreateSession = x.f("xrCreateSession");
    let mut s = xr::Session::NULL;
    // SAFETY: valid arguments.
    let r = unsafe { f(x.instance, &ci, &mut s) };
    if r == xr::Result::SUCCESS {
        Ok(s)
    } else {
        Err(r)
    }
}

pub const ALL_EXTS: &[&str] = &[
    "XR_KHR_vulkan_enable2",
    "XR_KHR_visibility_mask",
    "XR_KHR_composition_layer_depth",
    "XR_EXT_eye_gaze_interaction",
];

/// Instance (with `exts`), Vulkan via enable2 unless only enable is listed, and a session.
pub fn fixture(exts: &[&str]) -> Fixture {
    let x = create_instance(exts);
    let enable2 = exts.contains(&"XR_KHR_vulkan_enable2");
    x.graphics_requirements(enable2);
    let gfx = create_gfx(&x, enable2);
    let session = try_create_session(&x, &gfx).expect("xrCreateSession");
    Fixture { xr: Some(x), gfx, session }
}

pub fn identity_pose() -> xr::Posef {
    xr::Posef {
        orientation: xr::Quaternionf { x: 0.0, y: 0.0, z: 0.0, w: 1.0 },
        position: xr::Vector3f { x: 0.0, y: 0.0, z: 0.0 },
    }
}

pub fn reference_space(x: &Xr, s: xr::Session, ty: xr::ReferenceSpaceType) -> xr::Space {
    let f: pfn::CreateReferenceSpace = x.f("xrCreateReferenceSpace");
    let ci = xr::ReferenceSpaceCreateInfo { ty: xr::ReferenceSpaceCreateInfo::TYPE, next: std::ptr::null(), reference_space_type: ty, pose_in_reference_space: identity_pose() };
    let mut sp = xr::Space::NULL;
    // SAFETY: valid arguments.
    assert_eq!(unsafe { f(s, &ci, &mut sp) }, xr::Result::SUCCESS);
    sp
}

pub fn begin_session(x: &Xr, s: xr::Session) -> xr::Result {
    let f: pfn::BeginSession = x.f("xrBeginSession");
    let bi = xr::SessionBeginInfo { ty: xr::SessionBeginInfo::TYPE, next: std::ptr::null(), primary_view_configuration_type: xr::ViewConfigurationType::PRIMARY_STEREO };
    // SAFETY: valid arguments.
    unsafe { f(s, &bi) }
}

pub fn swapchain_info(format: vk::Format, w: u32, h: u32, layers: u32) -> xr::SwapchainCreateInfo {
    let depth = matches!(format, vk::Format::D32_SFLOAT | vk::Format::D16_UNORM | vk::Format::D24_UNORM_S8_UINT | vk::Format::D32_SFLOAT_S8_UINT);
    xr::SwapchainCreateInfo {
        ty: xr::SwapchainCreateInfo::TYPE,
        next: std::ptr::null(),
        create_flags: xr::SwapchainCreateFlags::EMPTY,
        usage_flags: if depth {
            xr::SwapchainUsageFlags::DEPTH_STENCIL_ATTACHMENT
        } else {
            xr::SwapchainUsageFlags::COLOR_ATTACHMENT | xr::SwapchainUsageFlags::TRANSFER_DST
        },
        format: format.as_raw() as i64,
        sample_count: 1,
        width: w,
        height: h,
        face_count: 1,
        array_size: layers,
        mip_count: 1,
    }
}

pub fn try_create_swapchain(x: &Xr, s: xr::Session, ci: &xr::SwapchainCreateInfo) -> Result<xr::Swapchain, xr::Result> {
    let f: pfn::CreateSwapchain = x.f("xrCreateSwapchain");
    let mut sc = xr::Swapchain::NULL;
    // SAFETY: valid arguments.
    let r = unsafe { f(s, ci, &mut sc) };
    if r == xr::Result::SUCCESS {
        Ok(sc)
    } else {
        Err(r)
    }
}

pub fn swapchain_images(x: &Xr, sc: xr::Swapchain) -> Vec<vk::Image> {
    let f: pfn::EnumerateSwapchainImages = x.f("xrEnumerateSwapchainImages");
    let mut n = 0;
    // SAFETY: valid arguments.
    assert_eq!(unsafe { f(sc, 0, &mut n, std::ptr::null_mut()) }, xr::Result::SUCCESS);
    let mut imgs = vec![xr::SwapchainImageVulkanKHR { ty: xr::SwapchainImageVulkanKHR::TYPE, next: std::ptr::null_mut(), image: 0 }; n as usize];
    // SAFETY: array of n Vulkan image structs.
    assert_eq!(unsafe { f(sc, n, &mut n, imgs.as_mut_ptr() as *mut _) }, xr::Result::SUCCESS);
    imgs.iter().map(|i| vk::Image::from_raw(i.image)).collect()
}

/// Acquire + wait; returns the index.
pub fn acquire_wait(x: &Xr, sc: xr::Swapchain) -> u32 {
    let acq: pfn::AcquireSwapchainImage = x.f("xrAcquireSwapchainImage");
    let wait: pfn::WaitSwapchainImage = x.f("xrWaitSwapchainImage");
    let mut i = 0;
    let wi = xr::SwapchainImageWaitInfo { ty: xr::SwapchainImageWaitInfo::TYPE, next: std::ptr::null(), timeout: xr::Duration::INFINITE };
    // SAFETY: valid arguments.
    unsafe {
        assert_eq!(acq(sc, std::ptr::null(), &mut i), xr::Result::SUCCESS);
        assert_eq!(wait(sc, &wi), xr::Result::SUCCESS);
    }
    i
}

pub fn release(x: &Xr, sc: xr::Swapchain) -> xr::Result {
    let rel: pfn::ReleaseSwapchainImage = x.f("xrReleaseSwapchainImage");
    // SAFETY: valid arguments (release info is optional).
    unsafe { rel(sc, std::ptr::null()) }
}

pub fn wait_frame(x: &Xr, s: xr::Session) -> (xr::Result, xr::FrameState) {
    let f: pfn::WaitFrame = x.f("xrWaitFrame");
    let mut st = xr::FrameState {
        ty: xr::FrameState::TYPE,
        next: std::ptr::null_mut(),
        predicted_display_time: xr::Time::from_nanos(0),
        predicted_display_period: xr::Duration::from_nanos(0),
        should_render: xr::FALSE,
    };
    // SAFETY: valid arguments.
    let r = unsafe { f(s, std::ptr::null(), &mut st) };
    (r, st)
}

pub fn begin_frame(x: &Xr, s: xr::Session) -> xr::Result {
    let f: pfn::BeginFrame = x.f("xrBeginFrame");
    // SAFETY: valid arguments.
    unsafe { f(s, std::ptr::null()) }
}

pub fn end_frame(x: &Xr, s: xr::Session, time: xr::Time, layers: &[*const xr::CompositionLayerBaseHeader]) -> xr::Result {
    let f: pfn::EndFrame = x.f("xrEndFrame");
    let info = xr::FrameEndInfo {
        ty: xr::FrameEndInfo::TYPE,
        next: std::ptr::null(),
        display_time: time,
        environment_blend_mode: xr::EnvironmentBlendMode::OPAQUE,
        layer_count: layers.len() as u32,
        layers: layers.as_ptr(),
    };
    // SAFETY: valid arguments.
    unsafe { f(s, &info) }
}

pub fn projection_view(sc: xr::Swapchain, x0: i32, w: i32, h: i32, layer: u32) -> xr::CompositionLayerProjectionView {
    xr::CompositionLayerProjectionView {
        ty: xr::CompositionLayerProjectionView::TYPE,
        next: std::ptr::null(),
        pose: identity_pose(),
        fov: xr::Fovf { angle_left: -0.7, angle_right: 0.7, angle_up: 0.7, angle_down: -0.7 },
        sub_image: xr::SwapchainSubImage {
            swapchain: sc,
            image_rect: xr::Rect2Di { offset: xr::Offset2Di { x: x0, y: 0 }, extent: xr::Extent2Di { width: w, height: h } },
            image_array_index: layer,
        },
    }
}

pub fn projection_layer(space: xr::Space, views: &[xr::CompositionLayerProjectionView]) -> xr::CompositionLayerProjection {
    xr::CompositionLayerProjection {
        ty: xr::CompositionLayerProjection::TYPE,
        next: std::ptr::null(),
        layer_flags: xr::CompositionLayerFlags::EMPTY,
        space,
        view_count: views.len() as u32,
        views: views.as_ptr(),
    }
}
