//! The checks of `--post`, its variants, `--render-scale`, `--viewport-scale` and
//! `--submit-texture` against the rest of the command line (what `parse` refuses, and why), with
//! their tests.

use super::{Args, Layout, PostEffect, Rendering, SubmitTexture};

/// The combinations of the post-chain and submit-texture options that cannot work, each refused
/// with the reason.
pub(super) fn check_post(a: &Args, samples: u32) -> Result<(), String> {
    let tonemap_only = a.post == Some(PostEffect::Tonemap);
    for (given, flag) in [
        (a.post_compute, "--post-compute"),
        (a.post_subpass, "--post-subpass"),
        (a.post_depth_attachment, "--post-depth-attachment"),
        (a.render_scale != 1.0, "--render-scale"),
        (a.viewport_scale != 1.0, "--viewport-scale"),
    ] {
        if given && a.post.is_none() {
            return Err(format!("{flag} needs a post chain: add --post tonemap (or bloom, taa)"));
        }
    }
    if a.post.is_some() && a.intermediate {
        return Err("--post and --intermediate exclude each other: the post chain's scene target is the intermediate".into());
    }
    if a.post_compute && !tonemap_only {
        return Err("--post-compute replaces the tonemap draw: use it with --post tonemap".into());
    }
    if a.post_subpass {
        if !tonemap_only {
            return Err("--post-subpass replaces the tonemap draw: use it with --post tonemap".into());
        }
        if a.post_compute {
            return Err("--post-subpass and --post-compute are two ways of the same tonemap: give one".into());
        }
        if a.rendering == Rendering::Dynamic {
            return Err("--post-subpass needs a render pass object (subpasses): use --rendering render-pass or render-pass2".into());
        }
        if samples > 1 {
            return Err("--post-subpass reads the scene as a single-sampled input attachment: use --samples 1".into());
        }
        if a.render_scale != 1.0 || a.viewport_scale != 1.0 {
            return Err("--post-subpass reads each pixel's own input attachment value: it cannot scale (no --render-scale or --viewport-scale)".into());
        }
    }
    if a.post_depth_attachment && (a.post_compute || a.post_subpass) {
        return Err("--post-depth-attachment belongs to the tonemap draw's own pass: not with --post-compute or --post-subpass".into());
    }
    // Submitted depth must be the eye pass's depth at the swapchain's size, for every sample.
    if a.submit_depth && a.post.is_some() && (samples > 1 || a.render_scale != 1.0 || a.viewport_scale != 1.0) {
        return Err("--submit-depth with --post needs the eye pass's depth at the swapchain's size: --samples 1, no --render-scale or --viewport-scale".into());
    }
    // Per-pixel counts are per pixel of the swapchain's view rect.
    if a.pixel_stats.is_some() && (a.render_scale != 1.0 || a.viewport_scale != 1.0) {
        return Err("--pixel-stats counts per swapchain pixel: not with --render-scale or --viewport-scale".into());
    }
    if a.dynamic_resolution {
        if !matches!(a.post, Some(PostEffect::Tonemap | PostEffect::Taa)) {
            return Err("--dynamic-resolution needs --post tonemap or taa (bloom's mip chain has fixed rects)".into());
        }
        if a.post_subpass {
            return Err("--dynamic-resolution scales the eye pass's sub-rect: --post-subpass reads each pixel's own value and cannot".into());
        }
        if a.record_once {
            return Err("--dynamic-resolution changes the eye passes' viewport every frame: the command buffers are recorded every frame (no --record-once)".into());
        }
        if a.submit_depth || a.pixel_stats.is_some() {
            return Err("--dynamic-resolution: not with --submit-depth or --pixel-stats (both need the eye at the swapchain's size)".into());
        }
    }
    if a.submit_texture == Some(SubmitTexture::DoubleWide) {
        if a.layout != Layout::SideBySide {
            return Err("--submit-texture double-wide renders both eyes side by side into one texture: it needs --layout side-by-side".into());
        }
        if a.submit_depth {
            return Err("--submit-texture double-wide blits colour only: not with --submit-depth".into());
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::super::{parse, Options, PostEffect, SubmitTexture};

    fn p(args: &[&str]) -> Result<Options, String> {
        parse(args.iter().map(|s| s.to_string())).map_err(|e| e.to_string())
    }

    #[test]
    fn post_defaults_and_values() {
        let o = p(&[]).unwrap();
        assert_eq!((o.post, o.post_compute, o.post_subpass, o.post_depth_attachment), (None, false, false, false));
        assert_eq!((o.render_scale, o.viewport_scale, o.submit_texture), (1.0, 1.0, None));
        assert_eq!(p(&["--post", "tonemap"]).unwrap().post, Some(PostEffect::Tonemap));
        assert_eq!(p(&["--post=bloom"]).unwrap().post, Some(PostEffect::Bloom));
        assert_eq!(p(&["--post", "taa"]).unwrap().post, Some(PostEffect::Taa));
        assert!(p(&["--post", "fxaa"]).is_err());
        assert!(p(&["--post"]).is_err());
        // The post chain's scene target is single-sampled unless told.
        assert_eq!(p(&["--post", "bloom"]).unwrap().samples, 1);
        assert_eq!(p(&["--post", "bloom", "--samples", "4"]).unwrap().samples, 4);
        let o = p(&["--post", "taa", "--render-scale", "0.5", "--viewport-scale", "0.75"]).unwrap();
        assert_eq!((o.render_scale, o.viewport_scale), (0.5, 0.75));
        for bad in ["0.49", "1.01", "0", "-1", "x", "NaN"] {
            assert!(p(&["--post", "tonemap", "--render-scale", bad]).is_err(), "{bad}");
            assert!(p(&["--post", "tonemap", "--viewport-scale", bad]).is_err(), "{bad}");
        }
        let o = p(&["--layout", "side-by-side", "--submit-texture", "double-wide"]).unwrap();
        assert_eq!(o.submit_texture, Some(SubmitTexture::DoubleWide));
        assert!(p(&["--layout", "side-by-side", "--submit-texture", "quad"]).is_err());
        assert!(p(&["--post", "tonemap", "--dynamic-resolution"]).unwrap().dynamic_resolution);
        assert!(p(&["--post", "taa", "--post-compute", "--dynamic-resolution"]).is_err(), "compute is tonemap only");
        assert!(p(&["--post", "tonemap", "--post-compute", "--dynamic-resolution"]).unwrap().dynamic_resolution);
        for bad in [&["--dynamic-resolution"][..], &["--post", "bloom", "--dynamic-resolution"], &["--post", "tonemap", "--dynamic-resolution", "--record-once"], &["--post", "tonemap", "--post-subpass", "--dynamic-resolution"]] {
            assert!(p(bad).is_err(), "{bad:?}");
        }
    }

    /// Each option in every layout and way of rendering where it applies.
    #[test]
    fn post_combines_with_layouts_and_renderings() {
        for layout in ["per-eye", "multiview", "side-by-side"] {
            for rendering in ["render-pass", "render-pass2", "dynamic"] {
                let base = ["--layout", layout, "--rendering", rendering];
                for extra in [
                    &["--post", "tonemap"][..],
                    &["--post", "bloom", "--samples", "4"],
                    &["--post", "taa", "--depth", "reverse"],
                    &["--post", "tonemap", "--post-compute", "--samples", "4"],
                    &["--post", "tonemap", "--post-depth-attachment"],
                    &["--post", "bloom", "--render-scale", "0.5", "--viewport-scale", "0.8"],
                    &["--post", "tonemap", "--submit-depth"],
                    &["--post", "taa", "--record-once", "--secondary"],
                ] {
                    let args = [&base[..], extra].concat();
                    p(&args).unwrap_or_else(|e| panic!("{args:?}: {e}"));
                }
                let subpass = p(&[&base[..], &["--post", "tonemap", "--post-subpass"]].concat());
                assert_eq!(subpass.is_ok(), rendering != "dynamic", "{layout} {rendering}: {subpass:?}");
                let dw = p(&[&base[..], &["--submit-texture", "double-wide", "--post", "bloom"]].concat());
                assert_eq!(dw.is_ok(), layout == "side-by-side", "{layout} {rendering}: {dw:?}");
            }
        }
    }

    /// Every refused combination names its reason.
    #[test]
    fn post_refusals() {
        let refused = |args: &[&str], needle: &str| {
            let e = p(args).expect_err(&format!("{args:?} was accepted"));
            assert!(e.contains(needle), "{args:?}: {e}");
        };
        for flag in [&["--post-compute"][..], &["--post-subpass"], &["--post-depth-attachment"], &["--render-scale", "0.5"], &["--viewport-scale", "0.5"]] {
            refused(flag, "needs a post chain");
        }
        refused(&["--post", "tonemap", "--intermediate"], "--intermediate");
        refused(&["--post", "bloom", "--post-compute"], "--post tonemap");
        refused(&["--post", "taa", "--post-subpass"], "--post tonemap");
        refused(&["--post", "tonemap", "--post-subpass", "--post-compute"], "give one");
        refused(&["--post", "tonemap", "--post-subpass", "--rendering", "dynamic"], "render pass object");
        refused(&["--post", "tonemap", "--post-subpass", "--samples", "4"], "--samples 1");
        refused(&["--post", "tonemap", "--post-subpass", "--render-scale", "0.5"], "cannot scale");
        refused(&["--post", "tonemap", "--post-subpass", "--viewport-scale", "0.5"], "cannot scale");
        refused(&["--post", "tonemap", "--post-compute", "--post-depth-attachment"], "own pass");
        refused(&["--post", "tonemap", "--submit-depth", "--samples", "4"], "swapchain's size");
        refused(&["--post", "tonemap", "--submit-depth", "--render-scale", "0.5"], "swapchain's size");
        refused(&["--post", "tonemap", "--pixel-stats", "/tmp/x", "--viewport-scale", "0.5"], "--pixel-stats");
        refused(&["--submit-texture", "double-wide"], "--layout side-by-side");
        refused(&["--layout", "side-by-side", "--submit-texture", "double-wide", "--submit-depth"], "colour only");
        // `--samples` now also applies to the post chain, still not alone.
        refused(&["--samples", "4"], "--intermediate or --post");
    }
}
