//! A real app through the layer: Debian bookworm's Khronos `hello_xr` on the mock runtime. Its
//! own test binary, apart from the Bevy engine's (`real_apps`): each binary's runs share only the
//! machine, as the suite ran them before the tests were grouped, so an engine run's timing does
//! not depend on which `hello_xr` run it shares the process with.

#[path = "../common/mod.rs"]
mod common;

mod hello_xr;
