//! Swapchains: real VkImages on the app's device, and the acquire → wait → release protocol
//! with the spec's ordering errors, so misuse by an app or a layer is reported, not absorbed.

use std::collections::VecDeque;
use std::sync::{Arc, Mutex};

use ash::vk;
use ash::vk::Handle;
use openxr_sys as xr;
use xr::Handle as _;

use crate::handles::Registry;
use crate::session::{self, Session};
use crate::util::{guard, input, input_opt, out_ptr, output, two_call, two_call_copy, XrResult};
use crate::vulkan::{vk_err, VkContext};

pub static SWAPCHAINS: Registry<Swapchain> = Registry::new();

pub const IMAGE_COUNT: u32 = 3;
pub const MAX_ARRAY_SIZE: u32 = 16;

const COLOR_FORMATS: &[vk::Format] = &[
    vk::Format::R8G8B8A8_SRGB,
    vk::Format::B8G8R8A8_SRGB,
    vk::Format::R8G8B8A8_UNORM,
    vk::Format::B8G8R8A8_UNORM,
];
const DEPTH_FORMATS: &[vk::Format] = &[
    vk::Format::D32_SFLOAT,
    vk::Format::D16_UNORM,
    vk::Format::D24_UNORM_S8_UINT,
    vk::Format::D32_SFLOAT_S8_UINT,
];

pub fn is_depth(f: vk::Format) -> bool {
    DEPTH_FORMATS.contains(&f)
}

pub fn has_stencil(f: vk::Format) -> bool {
    matches!(f, vk::Format::D24_UNORM_S8_UINT | vk::Format::D32_SFLOAT_S8_UINT)
}

/// The layout images are in whenever the app does not hold them (XR_KHR_vulkan_enable).
pub fn attachment_layout(f: vk::Format) -> vk::ImageLayout {
    if is_depth(f) {
        vk::ImageLayout::DEPTH_STENCIL_ATTACHMENT_OPTIMAL
    } else {
        vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL
    }
}

/// Every aspect of the format (layout transitions must name all of them).
pub fn full_aspect(f: vk::Format) -> vk::ImageAspectFlags {
    match (is_depth(f), has_stencil(f)) {
        (false, _) => vk::ImageAspectFlags::COLOR,
        (true, false) => vk::ImageAspectFlags::DEPTH,
        (true, true) => vk::ImageAspectFlags::DEPTH | vk::ImageAspectFlags::STENCIL,
    }
}

/// Formats the device can render to and copy from, sRGB colour first as runtimes prefer.
pub fn supported_formats(vk: &VkContext) -> Vec<vk::Format> {
    COLOR_FORMATS
        .iter()
        .map(|f| (*f, vk::FormatFeatureFlags::COLOR_ATTACHMENT))
        .chain(DEPTH_FORMATS.iter().map(|f| (*f, vk::FormatFeatureFlags::DEPTH_STENCIL_ATTACHMENT)))
        .filter(|(f, need)| {
            // SAFETY: valid physical device of the session.
            let p = unsafe { vk.instance.get_physical_device_format_properties(vk.physical, *f) };
            p.optimal_tiling_features.contains(*need | vk::FormatFeatureFlags::TRANSFER_SRC)
        })
        .map(|(f, _)| f)
        .collect()
}

/// XrSwapchainUsageFlags → VkImageUsageFlags, plus what the runtime itself needs.
pub fn usage_to_vk(u: xr::SwapchainUsageFlags, format: vk::Format) -> vk::ImageUsageFlags {
    use xr::SwapchainUsageFlags as X;
    let map = [
        (X::COLOR_ATTACHMENT, vk::ImageUsageFlags::COLOR_ATTACHMENT),
        (X::DEPTH_STENCIL_ATTACHMENT, vk::ImageUsageFlags::DEPTH_STENCIL_ATTACHMENT),
        (X::UNORDERED_ACCESS, vk::ImageUsageFlags::STORAGE),
        (X::TRANSFER_SRC, vk::ImageUsageFlags::TRANSFER_SRC),
        (X::TRANSFER_DST, vk::ImageUsageFlags::TRANSFER_DST),
        (X::SAMPLED, vk::ImageUsageFlags::SAMPLED),
        (X::INPUT_ATTACHMENT, vk::ImageUsageFlags::INPUT_ATTACHMENT),
    ];
    let mut v = map.iter().filter(|(x, _)| u.contains(*x)).fold(vk::ImageUsageFlags::empty(), |a, (_, v)| a | *v);
    // Capture copies out of the image; the spec's layout guarantee needs the attachment usage.
    v |= vk::ImageUsageFlags::TRANSFER_SRC;
    v |= if is_depth(format) { vk::ImageUsageFlags::DEPTH_STENCIL_ATTACHMENT } else { vk::ImageUsageFlags::COLOR_ATTACHMENT };
    v
}

#[derive(Debug, Default)]
pub struct SwapState {
    /// Acquired and not yet released, oldest first.
    pub acquired: VecDeque<u32>,
    /// Whether the oldest acquired image has been waited on.
    pub waited: bool,
    pub next: u32,
    pub last_released: Option<u32>,
    pub ever_acquired: bool,
    pub initialized: bool,
}

pub struct Swapchain {
    pub handle: u64,
    pub session: u64,
    pub vk: Arc<VkContext>,
    pub format: vk::Format,
    pub width: u32,
    pub height: u32,
    pub array_size: u32,
    /// `sampleCount`: the images' sample count (1 unless the app asked for MSAA).
    pub samples: vk::SampleCountFlags,
    /// `mipCount`: the images' mip levels; the runtime only ever reads level 0.
    pub mip_levels: u32,
    pub static_image: bool,
    pub images: Vec<vk::Image>,
    memories: Vec<vk::DeviceMemory>,
    pub state: Mutex<SwapState>,
}

pub fn get(h: xr::Swapchain) -> XrResult<Arc<Swapchain>> {
    SWAPCHAINS.get(h.into_raw())
}

/// Frees the Vulkan objects of a swapchain already removed from the registry.
pub fn destroy(sc: &Swapchain) {
    sc.vk.queue_wait_idle();
    let d = &sc.vk.device;
    for (&i, &m) in sc.images.iter().zip(&sc.memories) {
        // SAFETY: the queue is idle, so no work uses the images; they belong to this device.
        unsafe {
            d.destroy_image(i, None);
            d.free_memory(m, None);
        }
    }
}

pub unsafe extern "system" fn xr_enumerate_swapchain_formats(
    session: xr::Session,
    capacity: u32,
    count_out: *mut u32,
    formats: *mut i64,
) -> xr::Result {
    guard("xrEnumerateSwapchainFormats", || {
        let s = session::get(session)?;
        s.fail_point("xrEnumerateSwapchainFormats")?;
        // A headless session enumerates no formats (XR_MND_headless).
        let f: Vec<i64> = s.vk.as_ref().map(|vk| supported_formats(vk).iter().map(|f| f.as_raw() as i64).collect()).unwrap_or_default();
        // SAFETY: app array of `capacity` elements.
        unsafe { two_call_copy(capacity, count_out, formats, &f) }?;
        Ok(xr::Result::SUCCESS)
    })
}

fn create_images(vk: &VkContext, ci: &vk::ImageCreateInfo) -> XrResult<(Vec<vk::Image>, Vec<vk::DeviceMemory>)> {
    let d = &vk.device;
    let mut images = Vec::new();
    let mut mems = Vec::new();
    let result = (|| {
        for _ in 0..IMAGE_COUNT {
            // SAFETY: valid device and create info.
            let img = unsafe { d.create_image(ci, None) }.map_err(vk_err("vkCreateImage"))?;
            images.push(img);
            // SAFETY: image of this device.
            let req = unsafe { d.get_image_memory_requirements(img) };
            let ty = vk.memory_type(req.memory_type_bits, vk::MemoryPropertyFlags::DEVICE_LOCAL)?;
            let alloc = vk::MemoryAllocateInfo::default().allocation_size(req.size).memory_type_index(ty);
            // SAFETY: valid allocate info.
            let mem = unsafe { d.allocate_memory(&alloc, None) }.map_err(vk_err("vkAllocateMemory"))?;
            mems.push(mem);
            // SAFETY: fresh image and memory of sufficient size.
            unsafe { d.bind_image_memory(img, mem, 0) }.map_err(vk_err("vkBindImageMemory"))?;
        }
        Ok(())
    })();
    if let Err(e) = result {
        // SAFETY: objects created above, never used.
        unsafe {
            images.iter().for_each(|&i| d.destroy_image(i, None));
            mems.iter().for_each(|&m| d.free_memory(m, None));
        }
        return Err(e);
    }
    Ok((images, mems))
}

/// The number of levels of a full mip chain for a `width` × `height` image.
pub fn full_mip_chain(width: u32, height: u32) -> u32 {
    32 - width.max(height).max(1).leading_zeros()
}

/// Checks `faceCount`, `sampleCount` and `mipCount` against what the mock implements and what
/// the device supports for this format and usage; returns the images' sample count. Every
/// refusal says why on the log, since the spec names no error of its own for any of them.
fn check_samples_and_mips(
    vk: &VkContext,
    info: &xr::SwapchainCreateInfo,
    format: vk::Format,
    usage: vk::ImageUsageFlags,
    flags: vk::ImageCreateFlags,
) -> XrResult<vk::SampleCountFlags> {
    // Cube swapchains are not implemented (capture would have to pick a face): refused, never
    // faked. Other counts are invalid (the spec allows 1 or 6).
    if info.face_count != 1 {
        crate::log!("xrCreateSwapchain: faceCount {} refused: only faceCount 1 is implemented (cube swapchains are not)", info.face_count);
        return Err(xr::Result::ERROR_VALIDATION_FAILURE);
    }
    let full = full_mip_chain(info.width, info.height);
    if !(1..=full).contains(&info.mip_count) {
        crate::log!("xrCreateSwapchain: mipCount {} refused: {}x{} has 1..={full} levels", info.mip_count, info.width, info.height);
        return Err(xr::Result::ERROR_VALIDATION_FAILURE);
    }
    let n = info.sample_count;
    if n == 1 {
        return Ok(vk::SampleCountFlags::TYPE_1);
    }
    if !n.is_power_of_two() || n > 64 {
        crate::log!("xrCreateSwapchain: sampleCount {n} refused: not a Vulkan sample count (1, 2, 4, … 64)");
        return Err(xr::Result::ERROR_VALIDATION_FAILURE);
    }
    let samples = vk::SampleCountFlags::from_raw(n);
    // Capture reads what the app submitted by vkCmdResolveImage, which resolves colour only;
    // depth would need VK_KHR_depth_stencil_resolve in a render pass, which the mock does not do.
    if is_depth(format) {
        crate::log!("xrCreateSwapchain: sampleCount {n} refused for depth format {format:?}: multisampled depth swapchains are not implemented (the capture cannot resolve depth)");
        return Err(xr::Result::ERROR_VALIDATION_FAILURE);
    }
    // Vulkan: an image with samples > 1 has exactly one mip level (VUID-VkImageCreateInfo-samples-02257).
    if info.mip_count != 1 {
        crate::log!("xrCreateSwapchain: sampleCount {n} with mipCount {} refused: a multisampled Vulkan image has one mip level", info.mip_count);
        return Err(xr::Result::ERROR_VALIDATION_FAILURE);
    }
    // SAFETY: valid physical device of the session; plain query.
    let props = unsafe {
        vk.instance.get_physical_device_image_format_properties(vk.physical, format, vk::ImageType::TYPE_2D, vk::ImageTiling::OPTIMAL, usage, flags)
    };
    match props {
        Ok(p) if p.sample_counts.contains(samples) => Ok(samples),
        Ok(p) => {
            crate::log!("xrCreateSwapchain: sampleCount {n} refused: the device supports {:?} for {format:?} with usage {usage:?}", p.sample_counts);
            Err(xr::Result::ERROR_VALIDATION_FAILURE)
        }
        Err(e) => {
            crate::log!("xrCreateSwapchain: sampleCount {n} refused: vkGetPhysicalDeviceImageFormatProperties({format:?}, {usage:?}) -> {e:?}");
            Err(xr::Result::ERROR_VALIDATION_FAILURE)
        }
    }
}

fn create(s: &Arc<Session>, info: &xr::SwapchainCreateInfo) -> XrResult<u64> {
    use xr::SwapchainCreateFlags as F;
    if info.create_flags.contains(F::PROTECTED_CONTENT) {
        return Err(xr::Result::ERROR_FEATURE_UNSUPPORTED);
    }
    if !(info.create_flags & !(F::STATIC_IMAGE)).is_empty() {
        return Err(xr::Result::ERROR_VALIDATION_FAILURE);
    }
    let known = xr::SwapchainUsageFlags::COLOR_ATTACHMENT
        | xr::SwapchainUsageFlags::DEPTH_STENCIL_ATTACHMENT
        | xr::SwapchainUsageFlags::UNORDERED_ACCESS
        | xr::SwapchainUsageFlags::TRANSFER_SRC
        | xr::SwapchainUsageFlags::TRANSFER_DST
        | xr::SwapchainUsageFlags::SAMPLED
        | xr::SwapchainUsageFlags::MUTABLE_FORMAT
        | xr::SwapchainUsageFlags::INPUT_ATTACHMENT;
    if !(info.usage_flags & !known).is_empty() {
        return Err(xr::Result::ERROR_VALIDATION_FAILURE);
    }
    let format = i32::try_from(info.format).map(vk::Format::from_raw).map_err(|_| xr::Result::ERROR_SWAPCHAIN_FORMAT_UNSUPPORTED)?;
    // A headless session has no formats, so no swapchain.
    let vk = s.vk.as_ref().ok_or(xr::Result::ERROR_SWAPCHAIN_FORMAT_UNSUPPORTED)?;
    if !supported_formats(vk).contains(&format) {
        return Err(xr::Result::ERROR_SWAPCHAIN_FORMAT_UNSUPPORTED);
    }
    let depth = is_depth(format);
    let u = info.usage_flags;
    if (depth && u.contains(xr::SwapchainUsageFlags::COLOR_ATTACHMENT))
        || (!depth && u.contains(xr::SwapchainUsageFlags::DEPTH_STENCIL_ATTACHMENT))
    {
        crate::log!("xrCreateSwapchain: usage {u:?} does not fit format {format:?}");
        return Err(xr::Result::ERROR_VALIDATION_FAILURE);
    }
    let max = crate::system::MAX_SWAPCHAIN_EXTENT;
    if info.width == 0 || info.height == 0 || info.width > max || info.height > max || !(1..=MAX_ARRAY_SIZE).contains(&info.array_size) {
        crate::log!("xrCreateSwapchain: unsupported size {}x{} with {} layers (max {max}x{max}, 1..={MAX_ARRAY_SIZE} layers)",
            info.width, info.height, info.array_size);
        return Err(xr::Result::ERROR_VALIDATION_FAILURE);
    }
    let mut flags = vk::ImageCreateFlags::empty();
    if u.contains(xr::SwapchainUsageFlags::MUTABLE_FORMAT) {
        flags |= vk::ImageCreateFlags::MUTABLE_FORMAT;
    }
    let usage = usage_to_vk(u, format);
    let samples = check_samples_and_mips(vk, info, format, usage, flags)?;
    let ci = vk::ImageCreateInfo::default()
        .flags(flags)
        .image_type(vk::ImageType::TYPE_2D)
        .format(format)
        .extent(vk::Extent3D { width: info.width, height: info.height, depth: 1 })
        .mip_levels(info.mip_count)
        .array_layers(info.array_size)
        .samples(samples)
        .tiling(vk::ImageTiling::OPTIMAL)
        .usage(usage)
        .sharing_mode(vk::SharingMode::EXCLUSIVE)
        .initial_layout(vk::ImageLayout::UNDEFINED);
    let (images, memories) = create_images(vk, &ci)?;
    let (h, _) = SWAPCHAINS.insert_with(|handle| Swapchain {
        handle,
        session: s.handle,
        vk: vk.clone(),
        format,
        width: info.width,
        height: info.height,
        array_size: info.array_size,
        samples,
        mip_levels: info.mip_count,
        static_image: info.create_flags.contains(F::STATIC_IMAGE),
        images,
        memories,
        state: Mutex::default(),
    });
    crate::log!("xrCreateSwapchain {h}: {format:?} {}x{}x{} samples {} mips {}", info.width, info.height, info.array_size, info.sample_count, info.mip_count);
    Ok(h)
}

pub unsafe extern "system" fn xr_create_swapchain(
    session: xr::Session,
    info: *const xr::SwapchainCreateInfo,
    swapchain: *mut xr::Swapchain,
) -> xr::Result {
    guard("xrCreateSwapchain", || {
        let s = session::get(session)?;
        s.fail_point("xrCreateSwapchain")?;
        // SAFETY: app pointers.
        let (info, out) = unsafe { (input(info)?, out_ptr(swapchain)?) };
        *out = xr::Swapchain::from_raw(create(&s, info)?);
        Ok(xr::Result::SUCCESS)
    })
}

pub unsafe extern "system" fn xr_destroy_swapchain(swapchain: xr::Swapchain) -> xr::Result {
    guard("xrDestroySwapchain", || {
        let sc = get(swapchain)?;
        session::get(xr::Session::from_raw(sc.session))?.fail_point("xrDestroySwapchain")?;
        if let Some(sc) = SWAPCHAINS.remove(sc.handle) {
            destroy(&sc);
        }
        Ok(xr::Result::SUCCESS)
    })
}

pub unsafe extern "system" fn xr_enumerate_swapchain_images(
    swapchain: xr::Swapchain,
    capacity: u32,
    count_out: *mut u32,
    images: *mut xr::SwapchainImageBaseHeader,
) -> xr::Result {
    guard("xrEnumerateSwapchainImages", || {
        let sc = get(swapchain)?;
        session::get(xr::Session::from_raw(sc.session))?.fail_point("xrEnumerateSwapchainImages")?;
        if capacity > 0 && images.is_null() {
            return Err(xr::Result::ERROR_VALIDATION_FAILURE);
        }
        let arr = images as *mut xr::SwapchainImageVulkanKHR;
        if capacity as usize >= sc.images.len() {
            // Check every element's type before writing any (no partial output on failure).
            for i in 0..sc.images.len() {
                // SAFETY: the app's array has `capacity` elements of the Vulkan image struct.
                unsafe { output(arr.add(i)) }?;
            }
        }
        // SAFETY: as above.
        unsafe {
            two_call(capacity, count_out, sc.images.len(), |i| {
                output(arr.add(i))?.image = sc.images[i].as_raw();
                Ok(())
            })
        }?;
        Ok(xr::Result::SUCCESS)
    })
}

/// First acquire: bring all images from UNDEFINED to their attachment layout (a function the
/// Vulkan binding lets touch the queue; xrCreateSwapchain is not one).
fn initialize_layouts(sc: &Swapchain) -> XrResult<()> {
    let layout = attachment_layout(sc.format);
    let (stage, access) = if is_depth(sc.format) {
        (
            vk::PipelineStageFlags::EARLY_FRAGMENT_TESTS | vk::PipelineStageFlags::LATE_FRAGMENT_TESTS,
            vk::AccessFlags::DEPTH_STENCIL_ATTACHMENT_READ | vk::AccessFlags::DEPTH_STENCIL_ATTACHMENT_WRITE,
        )
    } else {
        (
            vk::PipelineStageFlags::COLOR_ATTACHMENT_OUTPUT,
            vk::AccessFlags::COLOR_ATTACHMENT_READ | vk::AccessFlags::COLOR_ATTACHMENT_WRITE,
        )
    };
    let barriers: Vec<vk::ImageMemoryBarrier> = sc
        .images
        .iter()
        .map(|&image| {
            vk::ImageMemoryBarrier::default()
                .src_access_mask(vk::AccessFlags::empty())
                .dst_access_mask(access)
                .old_layout(vk::ImageLayout::UNDEFINED)
                .new_layout(layout)
                .src_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
                .dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
                .image(image)
                .subresource_range(vk::ImageSubresourceRange {
                    aspect_mask: full_aspect(sc.format),
                    base_mip_level: 0,
                    level_count: sc.mip_levels,
                    base_array_layer: 0,
                    layer_count: sc.array_size,
                })
        })
        .collect();
    sc.vk.submit_and_wait(|d, cb| {
        // SAFETY: recording into the runtime's command buffer; images of this device.
        unsafe {
            d.cmd_pipeline_barrier(cb, vk::PipelineStageFlags::TOP_OF_PIPE, stage, vk::DependencyFlags::empty(), &[], &[], &barriers)
        }
    })
}

pub unsafe extern "system" fn xr_acquire_swapchain_image(
    swapchain: xr::Swapchain,
    info: *const xr::SwapchainImageAcquireInfo,
    index: *mut u32,
) -> xr::Result {
    guard("xrAcquireSwapchainImage", || {
        let sc = get(swapchain)?;
        let s = session::get(xr::Session::from_raw(sc.session))?;
        s.fail_point("xrAcquireSwapchainImage")?;
        if s.instance.cfg.reenter {
            sc.vk.reenter("xrAcquireSwapchainImage", true)?;
        }
        // SAFETY: app pointers.
        let (_, out) = unsafe { (input_opt(info)?, out_ptr(index)?) };
        let needs_init = {
            let st = sc.state.lock().unwrap();
            if st.acquired.len() as u32 >= IMAGE_COUNT || (sc.static_image && st.ever_acquired) {
                return Err(xr::Result::ERROR_CALL_ORDER_INVALID);
            }
            !st.initialized
        };
        if needs_init {
            initialize_layouts(&sc)?;
        }
        let mut st = sc.state.lock().unwrap();
        if st.acquired.len() as u32 >= IMAGE_COUNT {
            return Err(xr::Result::ERROR_CALL_ORDER_INVALID);
        }
        st.initialized = true;
        let i = st.next;
        st.next = (st.next + 1) % IMAGE_COUNT;
        st.acquired.push_back(i);
        st.ever_acquired = true;
        *out = i;
        Ok(xr::Result::SUCCESS)
    })
}

pub unsafe extern "system" fn xr_wait_swapchain_image(swapchain: xr::Swapchain, info: *const xr::SwapchainImageWaitInfo) -> xr::Result {
    guard("xrWaitSwapchainImage", || {
        let sc = get(swapchain)?;
        let s = session::get(xr::Session::from_raw(sc.session))?;
        s.fail_point("xrWaitSwapchainImage")?;
        if s.instance.cfg.reenter {
            sc.vk.reenter("xrWaitSwapchainImage", false)?;
        }
        // SAFETY: app input struct.
        unsafe { input(info) }?;
        let mut st = sc.state.lock().unwrap();
        if st.acquired.is_empty() || st.waited {
            return Err(xr::Result::ERROR_CALL_ORDER_INVALID);
        }
        // The runtime never reads images asynchronously: the image is ready at once.
        st.waited = true;
        Ok(xr::Result::SUCCESS)
    })
}

pub unsafe extern "system" fn xr_release_swapchain_image(
    swapchain: xr::Swapchain,
    info: *const xr::SwapchainImageReleaseInfo,
) -> xr::Result {
    guard("xrReleaseSwapchainImage", || {
        let sc = get(swapchain)?;
        let s = session::get(xr::Session::from_raw(sc.session))?;
        s.fail_point("xrReleaseSwapchainImage")?;
        if s.instance.cfg.reenter {
            sc.vk.reenter("xrReleaseSwapchainImage", true)?;
        }
        // SAFETY: app input struct (optional per the spec).
        unsafe { input_opt(info) }?;
        let mut st = sc.state.lock().unwrap();
        if !st.waited {
            return Err(xr::Result::ERROR_CALL_ORDER_INVALID);
        }
        let i = st.acquired.pop_front().expect("waited implies acquired");
        st.waited = false;
        st.last_released = Some(i);
        Ok(xr::Result::SUCCESS)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn usage_mapping_adds_runtime_needs() {
        let u = usage_to_vk(xr::SwapchainUsageFlags::SAMPLED, vk::Format::R8G8B8A8_SRGB);
        assert!(u.contains(vk::ImageUsageFlags::SAMPLED | vk::ImageUsageFlags::TRANSFER_SRC | vk::ImageUsageFlags::COLOR_ATTACHMENT));
        let d = usage_to_vk(xr::SwapchainUsageFlags::DEPTH_STENCIL_ATTACHMENT, vk::Format::D32_SFLOAT);
        assert!(d.contains(vk::ImageUsageFlags::DEPTH_STENCIL_ATTACHMENT) && !d.contains(vk::ImageUsageFlags::COLOR_ATTACHMENT));
        assert_eq!(full_aspect(vk::Format::D24_UNORM_S8_UINT), vk::ImageAspectFlags::DEPTH | vk::ImageAspectFlags::STENCIL);
    }

    #[test]
    fn full_mip_chains() {
        assert_eq!(full_mip_chain(1, 1), 1);
        assert_eq!(full_mip_chain(8, 8), 4);
        assert_eq!(full_mip_chain(64, 32), 7);
        assert_eq!(full_mip_chain(65, 2), 7);
        assert_eq!(full_mip_chain(3, 1000), 10);
        assert_eq!(full_mip_chain(16384, 16384), 15);
    }
}
