//! Fault injection (`MOCK_XR_FAIL=xrFunc[@K][=XR_ERROR_…],…`): which call of which function
//! fails, and with which error. Every entry point asks its fail point after validating its handles
//! and before it changes anything, so an injected failure has no side effects, as a runtime's
//! error has none.

use std::collections::HashMap;
use std::sync::Mutex;

use openxr_sys as xr;

/// The error of a fault that names none.
pub const DEFAULT_ERROR: xr::Result = xr::Result::ERROR_RUNTIME_FAILURE;

/// One fault: the 0-based call index it hits (None: every call) and the error it returns.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Fault {
    pub call: Option<u64>,
    pub error: xr::Result,
}

/// `MOCK_XR_FAIL`, parsed: the faults of each function.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct FailSpec(pub HashMap<String, Vec<Fault>>);

/// "XR_" + the name openxr-sys gives `r`, or the spec's fallback for values it does not know.
pub fn result_name(r: xr::Result) -> String {
    let dbg = format!("{r:?}");
    if dbg.chars().all(|c| c.is_ascii_uppercase() || c == '_' || c.is_ascii_digit()) && !dbg.starts_with(|c: char| c.is_ascii_digit()) {
        format!("XR_{dbg}")
    } else if r.into_raw() < 0 {
        format!("XR_UNKNOWN_FAILURE_{}", r.into_raw())
    } else {
        format!("XR_UNKNOWN_SUCCESS_{}", r.into_raw())
    }
}

/// The error code named `name` (`XR_ERROR_SESSION_LOST`; the `XR_` prefix may be left out).
/// The names are openxr-sys's own (its `Debug`), searched over the ranges the registry assigns
/// error codes in: core errors count down from -1, an extension's from
/// -(1e9 + (extension number - 1) × 1000). No table of numbers is kept here, so every error the
/// crate knows can be injected.
pub fn error_named(name: &str) -> Option<xr::Result> {
    let wanted = name.strip_prefix("XR_").unwrap_or(name);
    if !wanted.starts_with("ERROR_") {
        return None;
    }
    let core = (1..1000).map(|n| -n);
    let extensions = (0..2000).flat_map(|ext| (0..100).map(move |off| -(1_000_000_000 + ext * 1000 + off)));
    core.chain(extensions).map(xr::Result::from_raw).find(|r| format!("{r:?}") == wanted)
}

impl FailSpec {
    /// Parses `xrFunc[@K][=XR_ERROR_…]` items separated by commas. Anything malformed is an error
    /// that names the item, rather than a silently different test.
    pub fn parse(s: &str) -> Result<Self, String> {
        let mut map: HashMap<String, Vec<Fault>> = HashMap::new();
        for part in s.split(',').map(str::trim).filter(|p| !p.is_empty()) {
            let (target, error) = match part.split_once('=') {
                Some((t, e)) => {
                    let e = e.trim();
                    let code = error_named(e).ok_or_else(|| {
                        format!("MOCK_XR_FAIL item {part:?}: {e:?} is not an OpenXR error name (e.g. XR_ERROR_SESSION_LOST)")
                    })?;
                    (t.trim(), code)
                }
                None => (part, DEFAULT_ERROR),
            };
            let (name, call) = match target.split_once('@') {
                Some((n, k)) => {
                    let k = k.trim().parse::<u64>().map_err(|_| format!("MOCK_XR_FAIL item {part:?}: bad call index {k:?}"))?;
                    (n.trim(), Some(k))
                }
                None => (target, None),
            };
            if !name.starts_with("xr") || name.len() < 3 || !name.chars().all(|c| c.is_ascii_alphanumeric()) {
                return Err(format!("MOCK_XR_FAIL item {part:?}: bad function name {name:?}"));
            }
            map.entry(name.to_string()).or_default().push(Fault { call, error });
        }
        Ok(FailSpec(map))
    }

    /// Reads `MOCK_XR_FAIL` (unset or blank: no faults).
    pub fn from_env() -> Result<Self, String> {
        match std::env::var("MOCK_XR_FAIL") {
            Ok(v) if !v.trim().is_empty() => FailSpec::parse(&v),
            _ => Ok(FailSpec::default()),
        }
    }

    /// The error the `call`-th (0-based) call of `func` must fail with, if any (the first fault
    /// listed for it that matches).
    pub fn fault(&self, func: &str, call: u64) -> Option<xr::Result> {
        self.0.get(func)?.iter().find(|f| f.call.is_none_or(|k| k == call)).map(|f| f.error)
    }
}

/// Per-function call counters of one scope (an instance, or the process for the functions that
/// run before any instance exists).
#[derive(Debug, Default)]
pub struct FailCounters(Mutex<HashMap<&'static str, u64>>);

impl FailCounters {
    /// Counts this call of `func` and says which error it must fail with, if any.
    pub fn hit(&self, spec: &FailSpec, func: &'static str) -> Option<xr::Result> {
        if spec.0.is_empty() {
            return None;
        }
        let mut m = self.0.lock().unwrap_or_else(|e| e.into_inner());
        let n = m.entry(func).or_insert(0);
        let call = *n;
        *n += 1;
        spec.fault(func, call)
    }
}

/// Calls counted per process: the loader negotiation, `xrEnumerateInstanceExtensionProperties`,
/// `xrCreateInstance` and `xrGetInstanceProcAddr` without an instance run before (or without)
/// any instance, so `@K` counts them across the process.
static GLOBAL: std::sync::OnceLock<FailCounters> = std::sync::OnceLock::new();

/// The last `MOCK_XR_FAIL` text the global fail point parsed, with its result: the loader looks
/// functions up without an instance several times, and a name search is not free.
static GLOBAL_SPEC: Mutex<Option<(String, Result<FailSpec, String>)>> = Mutex::new(None);

/// The fail point of a function that has no instance: the spec is read from the environment at
/// each call (as `xrCreateInstance` reads its configuration). A malformed spec fails the call with
/// XR_ERROR_INITIALIZATION_FAILED and says why on stderr.
pub fn global_fail_point(func: &'static str) -> Result<(), xr::Result> {
    let text = std::env::var("MOCK_XR_FAIL").unwrap_or_default();
    let spec = {
        let mut cached = GLOBAL_SPEC.lock().unwrap_or_else(|e| e.into_inner());
        match cached.as_ref() {
            Some((t, spec)) if *t == text => spec.clone(),
            _ => {
                let spec = FailSpec::parse(&text);
                *cached = Some((text, spec.clone()));
                spec
            }
        }
    };
    let spec = spec.map_err(|e| {
        eprintln!("[mock-runtime] configuration error: {e}");
        xr::Result::ERROR_INITIALIZATION_FAILED
    })?;
    match GLOBAL.get_or_init(FailCounters::default).hit(&spec, func) {
        Some(e) => {
            crate::log!("{func}: injected {}", result_name(e));
            Err(e)
        }
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_calls_and_errors() {
        let f = FailSpec::parse("xrEndFrame@2,xrWaitFrame=XR_ERROR_INSTANCE_LOST, xrEndFrame@4=ERROR_SESSION_LOST").unwrap();
        assert_eq!(f.fault("xrEndFrame", 0), None);
        assert_eq!(f.fault("xrEndFrame", 2), Some(xr::Result::ERROR_RUNTIME_FAILURE), "no error named: the default");
        assert_eq!(f.fault("xrEndFrame", 4), Some(xr::Result::ERROR_SESSION_LOST), "the XR_ prefix may be left out");
        assert_eq!(f.fault("xrWaitFrame", 0), Some(xr::Result::ERROR_INSTANCE_LOST));
        assert_eq!(f.fault("xrWaitFrame", 7), Some(xr::Result::ERROR_INSTANCE_LOST), "no index: every call");
        assert_eq!(f.fault("xrBeginFrame", 0), None);
        assert_eq!(FailSpec::parse("").unwrap(), FailSpec::default());
        assert_eq!(FailSpec::parse(" , ").unwrap(), FailSpec::default());
    }

    #[test]
    fn every_error_the_tests_use_has_its_name() {
        for r in [
            xr::Result::ERROR_RUNTIME_FAILURE,
            xr::Result::ERROR_SESSION_LOST,
            xr::Result::ERROR_INSTANCE_LOST,
            xr::Result::ERROR_OUT_OF_MEMORY,
            xr::Result::ERROR_VALIDATION_FAILURE,
            xr::Result::ERROR_HANDLE_INVALID,
            xr::Result::ERROR_SWAPCHAIN_RECT_INVALID,
            xr::Result::ERROR_CALL_ORDER_INVALID,
            xr::Result::ERROR_SIZE_INSUFFICIENT,
            xr::Result::ERROR_FUNCTION_UNSUPPORTED,
            // Extension errors live in their own ranges.
            xr::Result::ERROR_GRAPHICS_REQUIREMENTS_CALL_MISSING,
            xr::Result::ERROR_RENDER_MODEL_ID_INVALID_EXT,
            xr::Result::ERROR_PERMISSION_INSUFFICIENT,
        ] {
            assert_eq!(error_named(&result_name(r)), Some(r), "{r:?}");
        }
    }

    #[test]
    fn bad_input_says_what_is_wrong() {
        let err = |s: &str| FailSpec::parse(s).unwrap_err();
        assert!(err("xrEndFrame@x").contains("bad call index \"x\""), "{}", err("xrEndFrame@x"));
        assert!(err("xrEndFrame@-1").contains("bad call index"));
        assert!(err("endframe").contains("bad function name \"endframe\""));
        assert!(err("xr End").contains("bad function name"));
        assert!(err("xrEndFrame=XR_ERROR_NO_SUCH_THING").contains("\"XR_ERROR_NO_SUCH_THING\" is not an OpenXR error name"));
        assert!(err("xrEndFrame=42").contains("not an OpenXR error name"), "numbers are not names");
        // Success codes are not faults: a fail point returns an error.
        assert!(err("xrEndFrame=XR_SUCCESS").contains("not an OpenXR error name"));
        assert!(err("xrEndFrame=XR_SESSION_LOSS_PENDING").contains("not an OpenXR error name"));
        assert!(err("xrEndFrame=").contains("not an OpenXR error name"));
        assert!(err("xrEndFrame@1=XR_ERROR_SESSION_LOST,xrWaitFrame@y").contains("xrWaitFrame@y"), "the bad item is named");
    }

    #[test]
    fn counters_count_per_function() {
        let spec = FailSpec::parse("xrBeginFrame@1=XR_ERROR_SESSION_LOST").unwrap();
        let c = FailCounters::default();
        assert_eq!(c.hit(&spec, "xrBeginFrame"), None);
        assert_eq!(c.hit(&spec, "xrEndFrame"), None, "another function has its own count");
        assert_eq!(c.hit(&spec, "xrBeginFrame"), Some(xr::Result::ERROR_SESSION_LOST));
        assert_eq!(c.hit(&spec, "xrBeginFrame"), None);
    }

    #[test]
    fn names() {
        assert_eq!(result_name(xr::Result::ERROR_VALIDATION_FAILURE), "XR_ERROR_VALIDATION_FAILURE");
        assert_eq!(result_name(xr::Result::from_raw(-999_999)), "XR_UNKNOWN_FAILURE_-999999");
    }
}
