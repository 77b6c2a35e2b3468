//! Lets the binary find the OpenXR loader where Debian installs it.
//!
//! bevy_mod_openxr loads the loader with `openxr::Entry::load()`, which opens
//! `libopenxr_loader.so`: the unversioned name only a -dev package installs. Debian's
//! `libopenxr-loader1` ships `libopenxr_loader.so.1`. scripts/engine-bevy puts a
//! `libopenxr_loader.so` link to it next to the binary, and this run path (searched by `dlopen`
//! for the calling executable) finds it there, so no -dev package is needed on the host or in the
//! trixie root.

fn main() {
    println!("cargo:rustc-link-arg-bins=-Wl,-rpath,$ORIGIN");
}
