//! Monoscopic far field on xr-scene + the mock runtime (lavapipe): the source eye is bit-identical
//! to a run without the layer; in the destination eye everything nearer than the split is
//! bit-identical, the far pixels are close (PSNR) and no pixel is left unrendered; the drop in
//! shaded fragments is counted from xr-scene's per-pixel counters.

mod common;

use common::{Half, Run, RunOutput};

const FRAME: u64 = 1;

fn runs(name: &str, args: &[&str], env: &[(&str, &str)]) -> (RunOutput, RunOutput) {
    let mut base = Run::new(name).args(["--submit-depth"]).args(args.iter().copied()).pixel_stats();
    for (k, v) in env {
        base = base.env(k, v);
    }
    let mut plain = base.clone();
    plain.name = format!("{name}-plain");
    let plain = plain.run();
    plain.assert_ok();
    let mut layered = base.with_layer().env("STEREOSHIM_FAR_FIELD_ENABLED", "1");
    layered.name = format!("{name}-far");
    let layered = layered.run();
    layered.assert_ok();
    layered.assert_layer_loaded(Half::Both);
    (plain, layered)
}

#[test]
fn explore() {
    let (plain, far) = runs("ff-explore", &["--layout", "per-eye"], &[("STEREOSHIM_FAR_FIELD_DEBUG", "1")]);
    eprintln!("{}", far.log);
    for (a, b) in common::views_to_compare("x", &far, FRAME, &plain, FRAME) {
        let (ia, ib) = (far.image(&a.file), plain.image(&b.file));
        eprintln!("view {} differing {}", a.view, ia.count_different(&ib));
        ia.save(&common::image::artifacts_dir("ff-explore").join(format!("far-{}.png", a.view)));
        ib.save(&common::image::artifacts_dir("ff-explore").join(format!("plain-{}.png", a.view)));
    }
    panic!("explore");
}
