//! One error type for every failing OpenXR or Vulkan call, so `main` can map any of them to exit code 1
//! with a message that names the call.

use std::fmt;

#[derive(Debug)]
pub struct Error(pub String);

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for Error {}

pub type Result<T> = std::result::Result<T, Error>;

/// Attaches the name of the failing call to an XR / VK / IO error.
pub trait Ctx<T> {
    fn ctx(self, what: &str) -> Result<T>;
}

impl<T, E: fmt::Debug> Ctx<T> for std::result::Result<T, E> {
    fn ctx(self, what: &str) -> Result<T> {
        self.map_err(|e| Error(format!("{what} failed: {e:?}")))
    }
}

pub fn fail<T>(msg: impl Into<String>) -> Result<T> {
    Err(Error(msg.into()))
}

/// A raw OpenXR call's result as this module's error (the text `Ctx` gives the openxr crate's
/// calls), for calls made through the raw entry points.
pub fn check(r: openxr::sys::Result, what: &str) -> Result<()> {
    if r.into_raw() < 0 {
        return fail(format!("{what} failed: {r:?}"));
    }
    Ok(())
}
