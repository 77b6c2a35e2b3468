//! Where the hidden-area mask comes from, end to end: the runtime's `XR_KHR_visibility_mask`
//! (enabled by the layer for itself, hidden from the app), a synthesized lens when the runtime has
//! none, and a re-fetch when the runtime says the mask changed.

mod common;

use common::Run;

fn masked(name: &str) -> Run {
    Run::new(name).with_layer().env("STEREOSHIM_MASK_ENABLED", "1").env("MOCK_XR_EXIT_AFTER", "3")
}

#[test]
fn runtime_mask_is_used_when_present() {
    let out = masked("mask-source-runtime").run();
    out.assert_ok();
    assert_eq!(out.log_lines("enabled [\"XR_KHR_visibility_mask\"] for the layer's own use").len(), 1, "{}", out.log);
    assert_eq!(out.log_lines("hidden-area mask from Runtime").len(), 2, "{}", out.log);
}

#[test]
fn synthesized_mask_when_the_runtime_has_none() {
    let out = masked("mask-source-synthesized").env("MOCK_XR_DISABLE_EXTENSIONS", "XR_KHR_visibility_mask").run();
    out.assert_ok();
    assert_eq!(out.log_lines("runtime lacks [\"XR_KHR_visibility_mask\"]").len(), 1, "{}", out.log);
    assert_eq!(out.log_lines("hidden-area mask from Synthesized").len(), 2, "{}", out.log);

    let out = masked("mask-source-forced-synthesized").env("STEREOSHIM_MASK_SOURCE", "synthesized").run();
    out.assert_ok();
    assert_eq!(out.log_lines("hidden-area mask from Synthesized").len(), 2, "{}", out.log);

    let out = masked("mask-source-runtime-only")
        .env("MOCK_XR_DISABLE_EXTENSIONS", "XR_KHR_visibility_mask")
        .env("STEREOSHIM_MASK_SOURCE", "runtime")
        .run();
    out.assert_ok();
    assert_eq!(out.log_lines("no hidden-area mask").len(), 2, "{}", out.log);
}

#[test]
fn mask_change_event_refetches_and_stays_hidden() {
    let out = masked("mask-source-change").env("MOCK_XR_VISIBILITY_MASK_CHANGE_AT", "1").run();
    out.assert_ok();
    assert_eq!(out.log_lines("visibility mask of view").len(), 2, "{}", out.log);
    // Fetched at the start and once more after the change.
    assert_eq!(out.log_lines("hidden-area mask from Runtime").len(), 4, "{}", out.log);
    let stats = out.log_lines("openxr stats:");
    assert!(stats[0].contains("visibility_mask_events=2"), "{}", stats[0]);
}

/// With the mask off nothing is fetched; the extension is still enabled (hidden), so the mask can
/// be switched on while the app runs.
#[test]
fn mask_disabled_fetches_nothing() {
    let out = Run::new("mask-source-off").with_layer().run();
    out.assert_ok();
    assert_eq!(out.log_lines("for the layer's own use").len(), 1, "{}", out.log);
    assert!(out.log_lines("hidden-area mask").is_empty(), "{}", out.log);
}
