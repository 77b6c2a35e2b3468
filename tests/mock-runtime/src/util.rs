//! FFI plumbing shared by every entry point: the panic-proof prologue, reading and type-checking
//! application structs, the two-call idiom and fixed-size string copies. Keeping it in one place
//! means every function validates its inputs the same way.

use std::ffi::{c_char, CStr};
use std::panic::{catch_unwind, AssertUnwindSafe};

use openxr_sys as xr;

pub type XrResult<T = xr::Result> = Result<T, xr::Result>;

/// The prologue of every `extern "system"` function: a panic must never unwind into the loader
/// (that is undefined behaviour), and every error is logged with the function's name.
pub fn guard(name: &'static str, f: impl FnOnce() -> XrResult) -> xr::Result {
    match catch_unwind(AssertUnwindSafe(f)) {
        Ok(Ok(r)) => r,
        Ok(Err(e)) => {
            // The loader probes every known function name; those misses are not news.
            if e != xr::Result::ERROR_FUNCTION_UNSUPPORTED {
                crate::log!("{name} -> {e:?}");
            }
            e
        }
        Err(p) => {
            let msg = p
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| p.downcast_ref::<String>().cloned())
                .unwrap_or_default();
            eprintln!("[mock-runtime] panic in {name}: {msg}");
            xr::Result::ERROR_RUNTIME_FAILURE
        }
    }
}

/// Structs whose first two members are `type` and `next`.
///
/// # Safety
/// Implementors must be `#[repr(C)]` structs starting with `XrStructureType type`.
pub unsafe trait Typed {
    const TYPE: xr::StructureType;
}

macro_rules! typed {
    ($($t:ident),* $(,)?) => {$(
        // SAFETY: every OpenXR struct with a `TYPE` constant starts with `ty` (and `next`).
        unsafe impl Typed for xr::$t { const TYPE: xr::StructureType = xr::$t::TYPE; }
    )*};
}

typed!(
    InstanceCreateInfo, InstanceProperties, SystemGetInfo, SystemProperties, ViewConfigurationProperties,
    ViewConfigurationView, SessionCreateInfo, SessionBeginInfo, EventDataBuffer, ReferenceSpaceCreateInfo,
    ActionSpaceCreateInfo, SpaceLocation, View, ViewState, ViewLocateInfo, FrameWaitInfo, FrameState,
    FrameBeginInfo, FrameEndInfo, SwapchainCreateInfo, SwapchainImageVulkanKHR, SwapchainImageWaitInfo,
    SwapchainImageAcquireInfo, SwapchainImageReleaseInfo, VisibilityMaskKHR, ActionSetCreateInfo,
    ActionCreateInfo, InteractionProfileSuggestedBinding, SessionActionSetsAttachInfo, ActionsSyncInfo,
    ActionStateGetInfo, ActionStateBoolean, ActionStateFloat, ActionStateVector2f, ActionStatePose,
    InteractionProfileState, VulkanInstanceCreateInfoKHR, VulkanDeviceCreateInfoKHR,
    VulkanGraphicsDeviceGetInfoKHR, GraphicsRequirementsVulkanKHR, BoundSourcesForActionEnumerateInfo,
    InputSourceLocalizedNameGetInfo, HapticActionInfo, ExtensionProperties, GraphicsBindingVulkanKHR,
    CompositionLayerProjectionView, CompositionLayerDepthInfoKHR, CompositionLayerProjection,
    CompositionLayerQuad, SystemEyeGazeInteractionPropertiesEXT, SpaceVelocity, HapticVibration,
);

/// Reads an input struct: NULL or a wrong `type` is XR_ERROR_VALIDATION_FAILURE.
///
/// # Safety
/// `p` must be NULL or point to a readable `T`.
pub unsafe fn input<'a, T: Typed>(p: *const T) -> XrResult<&'a T> {
    if p.is_null() {
        return Err(xr::Result::ERROR_VALIDATION_FAILURE);
    }
    // SAFETY: non-null; the caller guarantees it points to a T, and the type member is first.
    let ty = unsafe { *(p as *const xr::StructureType) };
    if ty != T::TYPE {
        crate::log!("expected {:?}, got {:?}", T::TYPE, ty);
        return Err(xr::Result::ERROR_VALIDATION_FAILURE);
    }
    // SAFETY: as above.
    Ok(unsafe { &*p })
}

/// An optional input struct (NULL allowed; a wrong `type` is still an error).
///
/// # Safety
/// As [`input`].
pub unsafe fn input_opt<'a, T: Typed>(p: *const T) -> XrResult<Option<&'a T>> {
    if p.is_null() {
        Ok(None)
    } else {
        // SAFETY: forwarded contract.
        unsafe { input(p) }.map(Some)
    }
}

/// An output struct: the app fills in `type` (and `next`), the runtime the rest.
///
/// # Safety
/// `p` must be NULL or point to a writable `T`.
pub unsafe fn output<'a, T: Typed>(p: *mut T) -> XrResult<&'a mut T> {
    // SAFETY: forwarded contract; writing through it is allowed by the caller.
    unsafe { input(p as *const T) }?;
    // SAFETY: checked non-null above.
    Ok(unsafe { &mut *p })
}

/// A plain output pointer (not a struct): NULL is XR_ERROR_VALIDATION_FAILURE.
///
/// # Safety
/// `p` must be NULL or point to a writable `T`.
pub unsafe fn out_ptr<'a, T>(p: *mut T) -> XrResult<&'a mut T> {
    if p.is_null() {
        Err(xr::Result::ERROR_VALIDATION_FAILURE)
    } else {
        // SAFETY: non-null and writable per contract.
        Ok(unsafe { &mut *p })
    }
}

/// Walks a `next` chain looking for a struct of type `ty`.
///
/// # Safety
/// `next` must be NULL or a valid chain of OpenXR structs.
pub unsafe fn find_in_chain(mut next: *const std::ffi::c_void, ty: xr::StructureType) -> *const std::ffi::c_void {
    let mut guard = 0;
    while !next.is_null() && guard < 64 {
        // SAFETY: every chained struct starts with (type, next).
        let base = unsafe { &*(next as *const xr::BaseInStructure) };
        if base.ty == ty {
            return next;
        }
        next = base.next as *const _;
        guard += 1;
    }
    std::ptr::null()
}

/// The two-call idiom: always report the count; capacity 0 only asks for it; a too-small
/// capacity is XR_ERROR_SIZE_INSUFFICIENT; otherwise `write(i)` fills element i.
///
/// # Safety
/// `count_out` must be NULL or writable.
pub unsafe fn two_call(
    capacity: u32,
    count_out: *mut u32,
    len: usize,
    write: impl FnMut(usize) -> XrResult<()>,
) -> XrResult<()> {
    // SAFETY: forwarded contract.
    let count = unsafe { out_ptr(count_out) }?;
    *count = len as u32;
    two_call_inner(capacity, len, write)
}

pub fn two_call_inner(capacity: u32, len: usize, mut write: impl FnMut(usize) -> XrResult<()>) -> XrResult<()> {
    if capacity == 0 {
        return Ok(());
    }
    if (capacity as usize) < len {
        return Err(xr::Result::ERROR_SIZE_INSUFFICIENT);
    }
    (0..len).try_for_each(&mut write)
}

/// Two-call idiom for plain arrays of `Copy` values.
///
/// # Safety
/// `buf` must hold `capacity` writable elements when capacity > 0.
pub unsafe fn two_call_copy<T: Copy>(capacity: u32, count_out: *mut u32, buf: *mut T, items: &[T]) -> XrResult<()> {
    if capacity > 0 && buf.is_null() {
        return Err(xr::Result::ERROR_VALIDATION_FAILURE);
    }
    // SAFETY: `buf` has `capacity` >= items.len() elements when written.
    unsafe { two_call(capacity, count_out, items.len(), |i| {
        *buf.add(i) = items[i];
        Ok(())
    }) }
}

/// Two-call idiom for strings (count includes the terminating NUL).
///
/// # Safety
/// `buf` must hold `capacity` writable chars when capacity > 0.
pub unsafe fn two_call_str(capacity: u32, count_out: *mut u32, buf: *mut c_char, s: &str) -> XrResult<()> {
    let mut bytes: Vec<c_char> = s.bytes().map(|b| b as c_char).collect();
    bytes.push(0);
    // SAFETY: forwarded contract.
    unsafe { two_call_copy(capacity, count_out, buf, &bytes) }
}

/// Copies `s` into a fixed-size C string member, truncating.
pub fn write_fixed(dst: &mut [c_char], s: &str) {
    let n = s.len().min(dst.len() - 1);
    for (d, b) in dst.iter_mut().zip(s.bytes().take(n)) {
        *d = b as c_char;
    }
    dst[n] = 0;
}

/// Reads a fixed-size C string member; unterminated is a validation failure.
pub fn read_fixed(src: &[c_char]) -> XrResult<String> {
    let end = src.iter().position(|&c| c == 0).ok_or(xr::Result::ERROR_VALIDATION_FAILURE)?;
    let bytes: Vec<u8> = src[..end].iter().map(|&c| c as u8).collect();
    String::from_utf8(bytes).map_err(|_| xr::Result::ERROR_VALIDATION_FAILURE)
}

/// Reads a NUL-terminated C string argument.
///
/// # Safety
/// `p` must be NULL or a NUL-terminated string.
pub unsafe fn read_cstr(p: *const c_char) -> XrResult<String> {
    if p.is_null() {
        return Err(xr::Result::ERROR_VALIDATION_FAILURE);
    }
    // SAFETY: non-null and NUL-terminated per contract.
    let s = unsafe { CStr::from_ptr(p) };
    s.to_str().map(str::to_owned).map_err(|_| xr::Result::ERROR_VALIDATION_FAILURE)
}

/// # Safety
/// `p` must point to `n` readable elements when n > 0.
pub unsafe fn slice<'a, T>(p: *const T, n: u32) -> XrResult<&'a [T]> {
    if n == 0 {
        return Ok(&[]);
    }
    if p.is_null() {
        return Err(xr::Result::ERROR_VALIDATION_FAILURE);
    }
    // SAFETY: per contract.
    Ok(unsafe { std::slice::from_raw_parts(p, n as usize) })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn two_call_semantics() {
        let mut count = 0u32;
        let mut buf = [0u32; 4];
        let items = [1, 2, 3];
        // SAFETY: local buffers of the stated sizes.
        unsafe {
            assert_eq!(two_call_copy(0, &mut count, std::ptr::null_mut(), &items), Ok(()));
            assert_eq!(count, 3);
            assert_eq!(two_call_copy(2, &mut count, buf.as_mut_ptr(), &items), Err(xr::Result::ERROR_SIZE_INSUFFICIENT));
            assert_eq!(count, 3);
            assert_eq!(two_call_copy(4, &mut count, buf.as_mut_ptr(), &items), Ok(()));
            assert_eq!(&buf[..3], &items);
            assert_eq!(two_call_copy(4, std::ptr::null_mut(), buf.as_mut_ptr(), &items), Err(xr::Result::ERROR_VALIDATION_FAILURE));
        }
    }

    #[test]
    fn fixed_strings() {
        let mut b = [1 as c_char; 4];
        write_fixed(&mut b, "abcdef");
        assert_eq!(read_fixed(&b).unwrap(), "abc");
        assert!(read_fixed(&[1 as c_char; 3]).is_err());
    }
}
