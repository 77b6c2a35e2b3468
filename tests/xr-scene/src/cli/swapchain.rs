//! The checks of `--swapchain-samples` and `--swapchain-mips` against the rest of the command line
//! (what `parse` refuses, and why), with their tests.

use super::Args;

/// The combinations of the colour swapchain's sample and mip counts that cannot work, each refused
/// with the reason.
pub(super) fn check_swapchain(a: &Args) -> Result<(), String> {
    let n = a.swapchain_samples;
    if n == 1 {
        return Ok(());
    }
    // A multisampled swapchain is rendered straight into by the eye pass: every path that writes
    // the swapchain image by anything else (a resolve, a copy, a blit, a full-screen draw of a
    // single-sampled pipeline) or needs single-sampled depth is refused.
    // xrizer's swapchain for a multisampled game texture has the texture's sample count, and its
    // compositor resolves into it (which Vulkan forbids: VUID-vkCmdResolveImage-dstImage-00259;
    // lavapipe runs it): reproduced with `--submit-via openvr --intermediate --samples N`.
    let xrizer = a.submit_via == super::SubmitVia::Openvr && a.samples.unwrap_or(4) == n;
    if a.intermediate && !xrizer {
        return Err(format!("--swapchain-samples {n} renders the eye pass straight into the multisampled swapchain image: not with --intermediate (it resolves or copies into a single-sampled one), except with --submit-via openvr and --samples {n} (a compositor resolving into it, as xrizer does)"));
    }
    if a.post.is_some() {
        return Err(format!("--swapchain-samples {n} renders the eye pass straight into the multisampled swapchain image: not with --post (its chain writes a single-sampled one)"));
    }
    if a.submit_depth {
        return Err(format!("--submit-depth needs single-sampled depth (the eye pass's depth has the swapchain's samples): not with --swapchain-samples {n}"));
    }
    if a.submit_texture.is_some() {
        return Err(format!("--submit-texture double-wide blits into the swapchain image, which cannot be multisampled: not with --swapchain-samples {n}"));
    }
    if a.swapchain_mips != 1 {
        return Err(format!("a multisampled Vulkan image has one mip level: --swapchain-samples {n} needs --swapchain-mips 1"));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::super::{parse, Options};

    fn p(args: &[&str]) -> Result<Options, String> {
        parse(args.iter().map(|s| s.to_string())).map_err(|e| e.to_string())
    }

    #[test]
    fn swapchain_defaults_and_values() {
        let o = p(&[]).unwrap();
        assert_eq!((o.swapchain_samples, o.swapchain_mips, o.samples), (1, 1, 1));
        for n in [1, 2, 4, 8] {
            let o = p(&["--swapchain-samples", &n.to_string()]).unwrap();
            // The direct path: the eye pass has the swapchain's samples.
            assert_eq!((o.swapchain_samples, o.samples), (n, n));
        }
        for bad in ["0", "3", "16", "64", "-1", "x", ""] {
            assert!(p(&["--swapchain-samples", bad]).is_err(), "{bad}");
        }
        assert!(p(&["--swapchain-samples"]).is_err());
        assert_eq!(p(&["--swapchain-mips", "3"]).unwrap().swapchain_mips, 3);
        assert_eq!(p(&["--swapchain-mips=12"]).unwrap().swapchain_mips, 12);
        assert!(p(&["--swapchain-mips", "0"]).is_err());
        assert!(p(&["--swapchain-mips", "-2"]).is_err());
        assert!(p(&["--swapchain-mips"]).is_err());
        // The last value wins, as for every option.
        assert_eq!(p(&["--swapchain-samples", "4", "--swapchain-samples", "1"]).unwrap().swapchain_samples, 1);
        // One sample, any mips: combines with the paths that write the swapchain otherwise.
        assert_eq!(p(&["--swapchain-samples", "1", "--intermediate"]).unwrap().samples, 4);
        assert_eq!(p(&["--swapchain-mips", "3", "--intermediate", "--samples", "2"]).unwrap().samples, 2);
    }

    /// Both options in every layout, way of rendering and Vulkan API the direct path has, with the
    /// flags that change what the eye pass records; mips also with the paths that write the
    /// swapchain image by a resolve, copy, blit or draw.
    #[test]
    fn swapchain_options_combine_with_layouts_and_renderings() {
        for layout in ["per-eye", "multiview", "side-by-side"] {
            for rendering in ["render-pass", "render-pass2", "dynamic"] {
                for api in ["1.0", "1.1", "1.3"] {
                    let base = ["--layout", layout, "--rendering", rendering, "--vulkan-api", api];
                    let api_ok = api != "1.0" || (layout != "multiview" && rendering != "dynamic");
                    for extra in [
                        &["--swapchain-samples", "4"][..],
                        &["--swapchain-samples", "8", "--secondary", "--record-once"],
                        &["--swapchain-samples", "2", "--threads", "--depth", "reverse"],
                        &["--swapchain-samples", "4", "--depth-clear", "image", "--bind-before-pass", "--pixel-stats", "/tmp/px"],
                        &["--swapchain-samples", "4", "--depth-clear", "attachments", "--sky-first", "--translucent", "--quad"],
                        &["--swapchain-mips", "3"],
                        &["--swapchain-mips", "2", "--submit-depth"],
                        &["--swapchain-mips", "3", "--intermediate"],
                        &["--swapchain-mips", "3", "--post", "taa"],
                        &["--swapchain-mips", "4", "--post", "tonemap", "--post-compute"],
                    ] {
                        let args = [&base[..], extra].concat();
                        let r = p(&args);
                        assert_eq!(r.is_ok(), api_ok, "{args:?}: {r:?}");
                    }
                }
            }
        }
        let o = p(&["--layout", "side-by-side", "--submit-texture", "double-wide", "--swapchain-mips", "2"]).unwrap();
        assert_eq!(o.swapchain_mips, 2);
    }

    /// Every refused combination names its reason.
    #[test]
    fn swapchain_refusals() {
        let refused = |args: &[&str], needle: &str| {
            let e = p(args).expect_err(&format!("{args:?} was accepted"));
            assert!(e.contains(needle), "{args:?}: {e}");
        };
        refused(&["--swapchain-samples", "4", "--intermediate"], "not with --intermediate");
        refused(&["--swapchain-samples", "4", "--intermediate", "--samples", "1"], "not with --intermediate");
        refused(&["--swapchain-samples", "2", "--post", "tonemap"], "not with --post");
        refused(&["--swapchain-samples", "8", "--post", "bloom", "--samples", "4"], "not with --post");
        refused(&["--swapchain-samples", "4", "--submit-depth"], "--submit-depth needs single-sampled depth");
        refused(&["--swapchain-samples", "4", "--layout", "side-by-side", "--submit-texture", "double-wide"], "blits");
        refused(&["--swapchain-samples", "4", "--swapchain-mips", "2"], "--swapchain-mips 1");
        // `--samples` stays the offscreen targets' option.
        refused(&["--swapchain-samples", "4", "--samples", "4"], "--intermediate or --post");
    }
}
