//! Never silent, end to end: when a feature the user enabled is not applied, the log says so at
//! WARN level once per reason with what to do, the per-frame stats carry the reason, and a session
//! in which it applied to no pass ends with a WARN summary. A normal run warns about nothing.

use crate::common;

use common::{Half, Run};

fn warnings(out: &common::RunOutput) -> Vec<&str> {
    out.log.lines().filter(|l| l.contains(" WARN ")).collect()
}

#[test]
fn a_feature_that_applies_nowhere_is_reported_once_and_summarized() {
    // The runtime has no hidden-area mask and the user allows only the runtime's.
    let out = Run::new("notices-no-mask")
        .with_layer()
        .env("STEREOSHIM_MASK_ENABLED", "1")
        .env("STEREOSHIM_MASK_SOURCE", "runtime")
        .env("MOCK_XR_DISABLE_EXTENSIONS", "XR_KHR_visibility_mask")
        .env("MOCK_XR_EXIT_AFTER", "4")
        .run();
    out.assert_ok();
    out.assert_layer_loaded(Half::Both);
    let w = warnings(&out);
    let reason: Vec<_> = w.iter().filter(|l| l.contains("hidden-area mask not applied to a pass: no_mask")).collect();
    assert_eq!(reason.len(), 1, "one warning for the reason, over 4 frames:\n{}", out.log);
    assert!(reason[0].contains("mask.source"), "the warning says what to do: {}", reason[0]);
    let summary: Vec<_> = w.iter().filter(|l| l.contains("was enabled but applied to no pass in this session")).collect();
    assert_eq!(summary.len(), 1, "{}", out.log);
    assert!(summary[0].contains("no_mask"), "{}", summary[0]);
}

#[test]
fn a_working_feature_warns_about_nothing() {
    let out = Run::new("notices-working").with_layer().env("STEREOSHIM_MASK_ENABLED", "1").env("MOCK_XR_EXIT_AFTER", "3").run();
    out.assert_ok();
    assert!(!out.log_lines("masking ").is_empty(), "the layer never masked a pass:\n{}", out.log);
    out.assert_log_lacks(Half::Both, " WARN ");
}
