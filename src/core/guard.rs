//! The prologue every exported entry point runs: a layer loaded into someone else's process must
//! never be the reason it crashes, so layer logic runs behind `catch_unwind`, and any failure
//! switches that instance to pass-through instead of reaching the app.

use std::cell::Cell;
use std::panic::{self, AssertUnwindSafe};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Once;

/// An internal failure of layer logic (never an error of the app or the runtime: those are
/// returned unchanged from the call down).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Fault(pub String);

impl<E: std::fmt::Display> From<E> for Fault {
    fn from(e: E) -> Fault {
        Fault(e.to_string())
    }
}

/// Per-instance switch: once layer logic failed, every later call of that instance goes straight
/// down the chain.
#[derive(Debug, Default)]
pub struct PassThrough(AtomicBool);

impl PassThrough {
    pub fn new(on: bool) -> PassThrough {
        PassThrough(AtomicBool::new(on))
    }
    pub fn is_on(&self) -> bool {
        self.0.load(Ordering::Acquire)
    }
    /// Turns pass-through on; true only for the call that turned it on, so the fault is logged once.
    pub fn engage(&self) -> bool {
        !self.0.swap(true, Ordering::AcqRel)
    }
}

/// The result of the call down, kept as soon as it exists: a failure while recording afterwards
/// must return it rather than call down a second time.
#[derive(Debug)]
pub struct Down<R>(Option<R>);

impl<R: Copy> Down<R> {
    /// Calls down once and keeps the result.
    pub fn call(&mut self, f: impl FnOnce() -> R) -> R {
        let r = f();
        self.0 = Some(r);
        r
    }
}

thread_local! {
    static IN_LAYER: Cell<u32> = const { Cell::new(0) };
}

/// Keeps panics raised inside layer logic out of the app's stderr: they are logged, then caught.
/// Panics anywhere else go to the hook that was installed before ours, unchanged.
fn install_panic_hook() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        let previous = panic::take_hook();
        panic::set_hook(Box::new(move |info| {
            if IN_LAYER.with(Cell::get) > 0 {
                tracing::error!(target: "stereoshim::panic", "{info}");
            } else {
                previous(info);
            }
        }));
    });
}

/// Runs the layer logic of one intercepted call. `layered` decides, calls down through `Down`, and
/// records; `plain` is the bare call down. If pass-through is on, only `plain` runs. If `layered`
/// fails or panics, pass-through is engaged (logged once) and the app still gets a result: the one
/// of the call down if it happened, else that of `plain`.
pub fn run<R: Copy>(
    call: &'static str,
    pass_through: &PassThrough,
    layered: impl FnOnce(&mut Down<R>) -> Result<R, Fault>,
    plain: impl FnOnce() -> R,
) -> R {
    if pass_through.is_on() {
        return plain();
    }
    install_panic_hook();
    let mut down = Down(None);
    IN_LAYER.with(|c| c.set(c.get() + 1));
    let outcome = panic::catch_unwind(AssertUnwindSafe(|| layered(&mut down)));
    IN_LAYER.with(|c| c.set(c.get() - 1));
    let fault = match outcome {
        Ok(Ok(r)) => return r,
        Ok(Err(fault)) => fault.0,
        Err(payload) => panic_message(payload.as_ref()),
    };
    if pass_through.engage() {
        tracing::error!(call, "internal failure: {fault}; this instance continues in pass-through");
    }
    match down.0 {
        Some(r) => r,
        None => plain(),
    }
}

fn panic_message(payload: &(dyn std::any::Any + Send)) -> String {
    if let Some(s) = payload.downcast_ref::<&str>() {
        format!("panic: {s}")
    } else if let Some(s) = payload.downcast_ref::<String>() {
        format!("panic: {s}")
    } else {
        "panic".into()
    }
}

/// For entry points that have no call down to fall back on (negotiation, proc-addr lookups):
/// a panic becomes `on_panic`.
pub fn catch<R>(call: &'static str, on_panic: R, f: impl FnOnce() -> R) -> R {
    install_panic_hook();
    IN_LAYER.with(|c| c.set(c.get() + 1));
    let outcome = panic::catch_unwind(AssertUnwindSafe(f));
    IN_LAYER.with(|c| c.set(c.get() - 1));
    outcome.unwrap_or_else(|payload| {
        tracing::error!(call, "internal failure: {}", panic_message(payload.as_ref()));
        on_panic
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::cell::RefCell;

    #[test]
    fn success_returns_layered_result() {
        let pt = PassThrough::default();
        let r = run("t", &pt, |d| Ok(d.call(|| 7) + 1), || 0);
        assert_eq!(r, 8);
        assert!(!pt.is_on());
    }

    #[test]
    fn fault_before_call_down_calls_plain_and_engages() {
        let pt = PassThrough::default();
        let plain_calls = RefCell::new(0);
        let r = run("t", &pt, |_| Err(Fault("decide failed".into())), || {
            *plain_calls.borrow_mut() += 1;
            5
        });
        assert_eq!((r, *plain_calls.borrow()), (5, 1));
        assert!(pt.is_on());
        // Afterwards only the plain path runs.
        let r = run("t", &pt, |_| panic!("must not run"), || 6);
        assert_eq!(r, 6);
    }

    #[test]
    fn panic_after_call_down_returns_down_result_without_calling_again() {
        let pt = PassThrough::default();
        let downs = RefCell::new(0);
        let r = run(
            "t",
            &pt,
            |d| {
                d.call(|| {
                    *downs.borrow_mut() += 1;
                    42
                });
                panic!("record failed");
            },
            || {
                *downs.borrow_mut() += 1;
                0
            },
        );
        assert_eq!((r, *downs.borrow()), (42, 1));
        assert!(pt.is_on());
    }

    #[test]
    fn engage_reports_only_the_first_time() {
        let pt = PassThrough::default();
        assert!(pt.engage());
        assert!(!pt.engage());
    }

    #[test]
    fn catch_maps_panics() {
        assert_eq!(catch("t", -1, || panic!("boom")), -1);
        assert_eq!(catch("t", -1, || 3), 3);
    }
}
