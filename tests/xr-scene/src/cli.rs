//! Command-line parsing: the flag set is the test contract of docs/testing.md, small enough to parse by hand.

use std::path::PathBuf;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Layout {
    PerEye,
    Multiview,
    SideBySide,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Rendering {
    RenderPass,
    RenderPass2,
    Dynamic,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DepthMode {
    Standard,
    Reverse,
}

/// How the depth buffer of an eye pass starts out at its clear value (`--depth-clear`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DepthClear {
    /// The pass's depth attachment has loadOp CLEAR.
    LoadOp,
    /// loadOp LOAD, then `vkCmdClearAttachments` of the depth aspect as the pass's first command.
    Attachments,
    /// `vkCmdClearDepthStencilImage` before the pass (image in TRANSFER_DST_OPTIMAL), loadOp LOAD.
    Image,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum VulkanPath {
    Enable,
    Enable2,
}

/// The Vulkan version the app asks for in `VkApplicationInfo::apiVersion` (`--vulkan-api`), and so
/// the API it may use on its instance and device.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum VulkanApi {
    /// Vulkan 1.0: no multiview, no dynamic rendering, no 1.1+ structs; render pass 2 through
    /// `VK_KHR_create_renderpass2`.
    V1_0,
    /// Vulkan 1.1: multiview core; render pass 2 and dynamic rendering through their KHR extensions.
    V1_1,
    V1_3,
}

impl VulkanApi {
    pub fn minor(self) -> u32 {
        match self {
            VulkanApi::V1_0 => 0,
            VulkanApi::V1_1 => 1,
            VulkanApi::V1_3 => 3,
        }
    }
}

/// What lies beyond the scenery (`--sky`): far geometry, or nothing but the clear colour.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Sky {
    /// A sky dome of far geometry (1500 m) around the stage: every pixel not covered by scenery.
    Geometry,
    /// No sky geometry: what the scenery does not cover keeps the pass's clear colour.
    Clear,
}

/// How a session and its instance are torn down (`--teardown`): every order OpenXR allows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Teardown {
    /// Children first: swapchains, session, the Vulkan device, the XR instance.
    Children,
    /// `xrDestroySession` with its swapchains still alive: the runtime destroys them with it.
    Session,
    /// `xrDestroyInstance` with its session and swapchains alive (the last session only), and the
    /// Vulkan device destroyed after the XR instance.
    Instance,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ColorFamily {
    Srgb,
    Unorm,
}

#[derive(Debug, Clone, PartialEq)]
pub struct Options {
    pub layout: Layout,
    pub rendering: Rendering,
    pub depth: DepthMode,
    pub depth_clear: DepthClear,
    pub intermediate: bool,
    pub samples: u32,
    pub submit_depth: bool,
    pub vulkan: VulkanPath,
    /// `--vulkan-api`: the apiVersion of the app's instance and device.
    pub vulkan_api: VulkanApi,
    /// `--secondary`: every eye pass's contents are recorded into a secondary command buffer.
    pub secondary: bool,
    /// `--threads`: xrWaitFrame on a frame-pacing thread, each pass's secondary recorded on a
    /// worker thread, submission on a submit thread (implies `secondary`; `crate::threads`).
    pub threads: bool,
    /// `--teardown`: the order sessions and instances are destroyed in.
    pub teardown: Teardown,
    pub frames: Option<u64>,
    /// `--sessions N`: end and create the session (swapchains, renderer) N times in one process.
    pub sessions: u64,
    /// `--instances N`: the whole app (XR instance, Vulkan instance and device, sessions) N times
    /// in one process.
    pub instances: u64,
    /// `--recreate-swapchains K`: every K frames, new swapchains of another size (and a new
    /// renderer for them) within the session.
    pub recreate_swapchains: Option<u64>,
    pub scale: f32,
    pub color_format: ColorFamily,
    pub shading_cost: u32,
    pub animate: bool,
    /// Bind pipeline, buffers, descriptor set, push constants and (one draw per pass) viewport and
    /// scissor before beginning each pass, not inside it.
    pub bind_before_pass: bool,
    /// Begin and end every pass (clears included) but draw nothing: isolates the cost of what a
    /// layer adds to a pass.
    pub empty: bool,
    pub stats: Option<PathBuf>,
    /// `--pixel-stats DIR`: per frame and view, shaded fragments per pixel of the view's rect.
    pub pixel_stats: Option<PathBuf>,
    pub validation: bool,
    /// `--vk-layer NAME` (repeatable): more layers enabled in the app's `VkInstanceCreateInfo`,
    /// after validation, in the order given (the last one nearest the driver).
    pub vk_layers: Vec<String>,
    /// `--record-once`: each combination of acquired swapchain images gets its command buffers
    /// recorded the first time it is needed and resubmitted unchanged ever after; per-frame data
    /// reaches them only through memory they read.
    pub record_once: bool,
    /// `--rerecord-every N` (with `--record-once`): every N-th frame (N, 2N, …) re-records the
    /// frame set it submits, as engines do that re-record when something changed; the other sets
    /// keep running what they were recorded with.
    pub rerecord_every: Option<u64>,
    /// `--sync-hazard`: leave out the barrier between the counters' fill and the fragment shader's
    /// atomics, a hazard only synchronization validation reports (proves that it is on).
    pub sync_hazard: bool,
    /// `--thread-hazard`: with `--threads`, the workers' secondaries all come from one command
    /// pool, which two threads then use at once: a violation of the pool's external
    /// synchronization that only the validation layer's thread-safety checks report (proves that
    /// they are on).
    pub thread_hazard: bool,
    /// `--sky`: the sky dome of far geometry (default) or just the clear colour.
    pub sky: Sky,
    /// `--sky-first`: the sky dome gets its own draw, first in each eye pass, with depth test and
    /// depth write off (as engines draw skyboxes), instead of last in the scene's one draw.
    pub sky_first: bool,
    /// `--translucent`: a translucent near pane, blended over the far field after the opaque
    /// geometry with depth write off.
    pub translucent: bool,
    /// `--far-movers`: a far object that orbits the stage with the frame number.
    pub far_movers: bool,
    /// `--submit2`: frames go down with vkQueueSubmit2 (Vulkan 1.3, synchronization2).
    pub submit2: bool,
    /// `--visibility-mask`: enable XR_KHR_visibility_mask and fetch each view's hidden-area mesh
    /// once after creating the session, as apps that draw their own mask do.
    pub visibility_mask: bool,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            layout: Layout::PerEye,
            rendering: Rendering::RenderPass,
            depth: DepthMode::Standard,
            depth_clear: DepthClear::LoadOp,
            intermediate: false,
            samples: 4,
            submit_depth: false,
            vulkan: VulkanPath::Enable2,
            vulkan_api: VulkanApi::V1_3,
            secondary: false,
            threads: false,
            teardown: Teardown::Children,
            frames: None,
            sessions: 1,
            instances: 1,
            recreate_swapchains: None,
            scale: 1.0,
            color_format: ColorFamily::Srgb,
            shading_cost: 0,
            animate: false,
            bind_before_pass: false,
            empty: false,
            stats: None,
            pixel_stats: None,
            validation: false,
            vk_layers: Vec::new(),
            record_once: false,
            rerecord_every: None,
            sync_hazard: false,
            thread_hazard: false,
            sky: Sky::Geometry,
            sky_first: false,
            translucent: false,
            far_movers: false,
            submit2: false,
            visibility_mask: false,
        }
    }
}

pub const USAGE: &str = "\
usage: xr-scene [options]
  --layout per-eye|multiview|side-by-side   swapchain layout (default per-eye)
  --rendering render-pass|render-pass2|dynamic  (default render-pass)
  --depth standard|reverse                  depth convention (default standard)
  --depth-clear load-op|attachments|image   how depth is cleared: pass load op, vkCmdClearAttachments
                                            in the pass, or vkCmdClearDepthStencilImage before it
  --intermediate                            render offscreen, then resolve/copy to the swapchain
  --samples N                               offscreen sample count with --intermediate (default 4)
  --submit-depth                            submit depth swapchains (XR_KHR_composition_layer_depth)
  --vulkan enable|enable2                   OpenXR Vulkan binding extension (default enable2)
  --vulkan-api 1.0|1.1|1.3                  apiVersion of the app's VkInstance/VkDevice (default 1.3);
                                            1.0: per-eye / side-by-side, render-pass / render-pass2
                                            (VK_KHR_create_renderpass2); 1.1: dynamic rendering
                                            through VK_KHR_dynamic_rendering
  --secondary                               record each eye pass's contents into a secondary command
                                            buffer run by vkCmdExecuteCommands
  --teardown children|session|instance      destroy swapchains, then the session, the Vulkan device and
                                            the XR instance (children); leave the swapchains to
                                            xrDestroySession (session); or leave the last session and
                                            its swapchains to xrDestroyInstance, destroying the Vulkan
                                            device after it (instance)
  --threads                                 xrWaitFrame on a frame-pacing thread (the next frame's
                                            wait overlapping this frame), each pass's secondary
                                            recorded on a worker thread with its own command pool,
                                            vkQueueSubmit on a submit thread; implies --secondary
  --frames N                                request exit after N frames (of each session)
  --sessions N                              end and recreate the session (swapchains, renderer)
                                            N times; prints each session's frames and the
                                            process's resident memory to stderr
  --instances N                             create and destroy the XR instance, Vulkan instance and
                                            device (and their sessions) N times
  --recreate-swapchains K                   every K frames destroy the swapchains and make new
                                            ones of another size (x1, x0.8, x1.2 of --scale in
                                            turn)
  --scale F                                 render at F x the recommended size (default 1)
  --color-format srgb|unorm                 swapchain colour format family (default srgb)
  --shading-cost K                          K-iteration per-pixel busy loop (default 0)
  --animate                                 spin the near cube by frame number
  --bind-before-pass                        set draw state before vkCmdBegin*, not inside the pass
  --empty                                   passes with their clears but no draws (layer cost benchmarks)
  --stats FILE                              write per-frame GPU time and shaded fragments as JSON
  --pixel-stats DIR                         write per frame and view the shaded fragments of each pixel
                                            (DIR/frame-NNNNN-view-V.u32, raw little-endian u32)
  --validation                              enable VK_LAYER_KHRONOS_validation with synchronization
                                            validation (exit 3 on errors)
  --vk-layer NAME                           also enable the Vulkan layer NAME in the app's instance
                                            create info (repeatable; after validation, in order)
  --record-once                             record each combination of acquired swapchain images'
                                            command buffers once and resubmit them every frame
                                            (per-frame data in per-frame-in-flight buffers)
  --rerecord-every N                        with --record-once: every N-th frame re-records the
                                            command buffers it submits (the others stay as recorded)
  --sync-hazard                             leave out one barrier (counters' fill -> fragment shader):
                                            a hazard only synchronization validation reports
  --thread-hazard                           with --threads: the workers share one command pool, used
                                            by two threads at once (only validation's thread-safety
                                            checks report it)
  --sky geometry|clear                      a sky dome of far geometry (default) or the clear colour
  --sky-first                               draw the sky first in each eye pass, depth test and depth
                                            write off (default: last in the scene's draw, depth-tested)
  --translucent                             a translucent near pane blended over the far field, drawn
                                            after the opaque geometry, depth write off
  --far-movers                              a far object (~250 m) that orbits the stage by frame number
  --submit2                                 submit frames with vkQueueSubmit2 (needs --vulkan-api 1.3)
  --visibility-mask                         fetch each view's hidden-area mesh (XR_KHR_visibility_mask)
  --help                                    show this text";

/// Parses the arguments after the program name. `Err` carries the message for a usage error;
/// `Ok(None)` means `--help` was asked for.
pub fn parse<I: IntoIterator<Item = String>>(args: I) -> Result<Option<Options>, String> {
    let mut o = Options::default();
    let mut samples_given = false;
    let mut it = args.into_iter();
    while let Some(arg) = it.next() {
        // Accept both `--flag value` and `--flag=value`.
        let (flag, inline) = match arg.split_once('=') {
            Some((f, v)) if f.starts_with("--") => (f.to_string(), Some(v.to_string())),
            _ => (arg.clone(), None),
        };
        let mut value = |name: &str| -> Result<String, String> {
            match inline.clone() {
                Some(v) => Ok(v),
                None => it.next().ok_or_else(|| format!("{name} needs a value")),
            }
        };
        match flag.as_str() {
            "--help" | "-h" => return Ok(None),
            "--layout" => {
                o.layout = match value("--layout")?.as_str() {
                    "per-eye" => Layout::PerEye,
                    "multiview" => Layout::Multiview,
                    "side-by-side" => Layout::SideBySide,
                    v => return Err(format!("unknown --layout {v:?}")),
                }
            }
            "--rendering" => {
                o.rendering = match value("--rendering")?.as_str() {
                    "render-pass" => Rendering::RenderPass,
                    "render-pass2" => Rendering::RenderPass2,
                    "dynamic" => Rendering::Dynamic,
                    v => return Err(format!("unknown --rendering {v:?}")),
                }
            }
            "--depth" => {
                o.depth = match value("--depth")?.as_str() {
                    "standard" => DepthMode::Standard,
                    "reverse" => DepthMode::Reverse,
                    v => return Err(format!("unknown --depth {v:?}")),
                }
            }
            "--depth-clear" => {
                o.depth_clear = match value("--depth-clear")?.as_str() {
                    "load-op" => DepthClear::LoadOp,
                    "attachments" => DepthClear::Attachments,
                    "image" => DepthClear::Image,
                    v => return Err(format!("unknown --depth-clear {v:?}")),
                }
            }
            "--vulkan" => {
                o.vulkan = match value("--vulkan")?.as_str() {
                    "enable" => VulkanPath::Enable,
                    "enable2" => VulkanPath::Enable2,
                    v => return Err(format!("unknown --vulkan {v:?}")),
                }
            }
            "--vulkan-api" => {
                o.vulkan_api = match value("--vulkan-api")?.as_str() {
                    "1.0" => VulkanApi::V1_0,
                    "1.1" => VulkanApi::V1_1,
                    "1.3" => VulkanApi::V1_3,
                    v => return Err(format!("unknown --vulkan-api {v:?} (1.0, 1.1 or 1.3)")),
                }
            }
            "--teardown" => {
                o.teardown = match value("--teardown")?.as_str() {
                    "children" => Teardown::Children,
                    "session" => Teardown::Session,
                    "instance" => Teardown::Instance,
                    v => return Err(format!("unknown --teardown {v:?} (children, session or instance)")),
                }
            }
            "--sky" => {
                o.sky = match value("--sky")?.as_str() {
                    "geometry" => Sky::Geometry,
                    "clear" => Sky::Clear,
                    v => return Err(format!("unknown --sky {v:?} (geometry or clear)")),
                }
            }
            "--color-format" => {
                o.color_format = match value("--color-format")?.as_str() {
                    "srgb" => ColorFamily::Srgb,
                    "unorm" => ColorFamily::Unorm,
                    v => return Err(format!("unknown --color-format {v:?}")),
                }
            }
            "--samples" => {
                let v = value("--samples")?;
                o.samples = match v.parse::<u32>() {
                    Ok(n @ (1 | 2 | 4 | 8 | 16 | 32 | 64)) => n,
                    _ => return Err(format!("--samples must be a power of two 1..64, got {v:?}")),
                };
                samples_given = true;
            }
            "--frames" => {
                let v = value("--frames")?;
                o.frames = Some(
                    v.parse::<u64>()
                        .ok()
                        .filter(|n| *n > 0)
                        .ok_or_else(|| format!("--frames must be a positive integer, got {v:?}"))?,
                );
            }
            "--sessions" => {
                let v = value("--sessions")?;
                o.sessions = v.parse::<u64>().ok().filter(|n| *n > 0).ok_or_else(|| format!("--sessions must be a positive integer, got {v:?}"))?;
            }
            "--instances" => {
                let v = value("--instances")?;
                o.instances = v.parse::<u64>().ok().filter(|n| *n > 0).ok_or_else(|| format!("--instances must be a positive integer, got {v:?}"))?;
            }
            "--recreate-swapchains" => {
                let v = value("--recreate-swapchains")?;
                o.recreate_swapchains = Some(v.parse::<u64>().ok().filter(|n| *n > 0).ok_or_else(|| format!("--recreate-swapchains must be a positive integer, got {v:?}"))?);
            }
            "--scale" => {
                let v = value("--scale")?;
                o.scale = v
                    .parse::<f32>()
                    .ok()
                    .filter(|f| f.is_finite() && *f > 0.0 && *f <= 4.0)
                    .ok_or_else(|| format!("--scale must be a number in (0, 4], got {v:?}"))?;
            }
            "--shading-cost" => {
                let v = value("--shading-cost")?;
                o.shading_cost = v
                    .parse::<u32>()
                    .map_err(|_| format!("--shading-cost must be a non-negative integer, got {v:?}"))?;
            }
            "--rerecord-every" => {
                let v = value("--rerecord-every")?;
                o.rerecord_every = Some(
                    v.parse::<u64>()
                        .ok()
                        .filter(|n| *n > 0)
                        .ok_or_else(|| format!("--rerecord-every must be a positive integer, got {v:?}"))?,
                );
            }
            "--stats" => o.stats = Some(PathBuf::from(value("--stats")?)),
            "--vk-layer" => o.vk_layers.push(value("--vk-layer")?),
            "--pixel-stats" => o.pixel_stats = Some(PathBuf::from(value("--pixel-stats")?)),
            "--intermediate" | "--submit-depth" | "--animate" | "--bind-before-pass" | "--empty" | "--validation" | "--secondary"
            | "--threads" | "--record-once" | "--sync-hazard" | "--thread-hazard" | "--sky-first" | "--translucent" | "--far-movers" | "--submit2"
            | "--visibility-mask"
                if inline.is_some() =>
            {
                return Err(format!("{flag} takes no value"))
            }
            "--intermediate" => o.intermediate = true,
            "--submit-depth" => o.submit_depth = true,
            "--animate" => o.animate = true,
            "--bind-before-pass" => o.bind_before_pass = true,
            "--empty" => o.empty = true,
            "--validation" => o.validation = true,
            "--secondary" => o.secondary = true,
            "--threads" => {
                o.threads = true;
                o.secondary = true;
            }
            "--record-once" => o.record_once = true,
            "--sync-hazard" => o.sync_hazard = true,
            "--thread-hazard" => o.thread_hazard = true,
            "--sky-first" => o.sky_first = true,
            "--translucent" => o.translucent = true,
            "--far-movers" => o.far_movers = true,
            "--submit2" => o.submit2 = true,
            "--visibility-mask" => o.visibility_mask = true,
            _ => return Err(format!("unknown argument {arg:?}")),
        }
    }
    if samples_given && !o.intermediate {
        return Err("--samples only applies with --intermediate".into());
    }
    if !o.intermediate {
        o.samples = 1;
    }
    // Depth rendered at N samples cannot simply be submitted: resolving it needs
    // VK_KHR_depth_stencil_resolve and a choice of resolve mode, which this app does not make.
    if o.submit_depth && o.samples > 1 {
        return Err("--submit-depth needs single-sampled depth: use --samples 1 with --intermediate".into());
    }
    if o.vulkan_api == VulkanApi::V1_0 {
        if o.layout == Layout::Multiview {
            return Err("--layout multiview needs Vulkan 1.1 (multiview); use --vulkan-api 1.1 or 1.3".into());
        }
        if o.rendering == Rendering::Dynamic {
            return Err("--rendering dynamic needs Vulkan 1.1 (VK_KHR_dynamic_rendering) or 1.3".into());
        }
    }
    if o.submit2 && o.vulkan_api != VulkanApi::V1_3 {
        return Err("--submit2 needs Vulkan 1.3 (vkQueueSubmit2, synchronization2)".into());
    }
    // State bound in a primary command buffer is not inherited by secondaries.
    if o.thread_hazard && !o.threads {
        return Err("--thread-hazard shares one command pool between the recording workers: it needs --threads".into());
    }
    if o.threads && o.bind_before_pass {
        return Err("--bind-before-pass cannot be combined with --threads: --threads records each pass into a secondary command buffer (on a worker thread), which inherits no state bound in the primary".into());
    }
    if o.secondary && o.bind_before_pass {
        return Err("--bind-before-pass and --secondary exclude each other: a secondary command buffer inherits no bound state".into());
    }
    // Without --record-once every frame is re-recorded anyway.
    if o.rerecord_every.is_some() && !o.record_once {
        return Err("--rerecord-every only applies with --record-once".into());
    }
    // The left-out barrier guards the fragment shader's counter writes: without draws there is
    // no hazard to report, and the flag would prove nothing.
    if o.sync_hazard && o.empty {
        return Err("--sync-hazard needs draws: it cannot be combined with --empty".into());
    }
    // Without sky geometry there is nothing to draw first.
    if o.sky_first && o.sky == Sky::Clear {
        return Err("--sky-first needs sky geometry: it cannot be combined with --sky clear".into());
    }
    Ok(Some(o))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(args: &[&str]) -> Result<Option<Options>, String> {
        parse(args.iter().map(|s| s.to_string()))
    }

    #[test]
    fn defaults() {
        let o = p(&[]).unwrap().unwrap();
        assert_eq!(o.layout, Layout::PerEye);
        assert_eq!(o.vulkan, VulkanPath::Enable2);
        assert_eq!(o.samples, 1, "no intermediate target means single-sampled");
        assert_eq!(o.color_format, ColorFamily::Srgb);
        assert_eq!(o.depth_clear, DepthClear::LoadOp);
        assert_eq!(o.vulkan_api, VulkanApi::V1_3);
        assert!(!o.secondary);
    }

    #[test]
    fn vulkan_api_and_secondary() {
        assert_eq!(p(&["--vulkan-api", "1.0"]).unwrap().unwrap().vulkan_api, VulkanApi::V1_0);
        assert_eq!(p(&["--vulkan-api=1.1"]).unwrap().unwrap().vulkan_api, VulkanApi::V1_1);
        assert!(p(&["--vulkan-api", "1.2"]).is_err());
        assert!(p(&["--vulkan-api", "1.0", "--layout", "multiview"]).is_err());
        assert!(p(&["--vulkan-api", "1.0", "--rendering", "dynamic"]).is_err());
        assert!(p(&["--vulkan-api", "1.0", "--rendering", "render-pass2", "--layout", "side-by-side"]).is_ok());
        assert!(p(&["--vulkan-api", "1.1", "--rendering", "dynamic", "--layout", "multiview"]).is_ok());
        assert!(p(&["--secondary"]).unwrap().unwrap().secondary);
        assert!(p(&["--submit2"]).unwrap().unwrap().submit2);
        assert!(p(&["--submit2", "--vulkan-api", "1.1"]).is_err());
        assert!(p(&["--secondary=1"]).is_err());
        assert!(p(&["--secondary", "--bind-before-pass"]).is_err());
    }

    /// `--teardown`: the three orders, nothing else.
    #[test]
    fn teardown_orders() {
        assert_eq!(p(&[]).unwrap().unwrap().teardown, Teardown::Children);
        assert_eq!(p(&["--teardown", "session"]).unwrap().unwrap().teardown, Teardown::Session);
        assert_eq!(p(&["--teardown=instance"]).unwrap().unwrap().teardown, Teardown::Instance);
        assert!(p(&["--teardown", "device"]).is_err());
    }

    /// `--threads` implies `--secondary` and combines with what matters for threading, but not
    /// with state bound before the pass (secondaries inherit none).
    #[test]
    fn threads_imply_secondary() {
        let o = p(&["--threads"]).unwrap().unwrap();
        assert!(o.threads && o.secondary);
        assert!(!p(&[]).unwrap().unwrap().threads);
        assert!(p(&["--threads=1"]).is_err());
        assert!(p(&["--threads", "--thread-hazard"]).unwrap().unwrap().thread_hazard);
        assert!(p(&["--thread-hazard"]).is_err());
        let e = p(&["--threads", "--bind-before-pass"]).unwrap_err();
        assert!(e.contains("--threads"), "{e}");
        for layout in ["per-eye", "multiview", "side-by-side"] {
            let o = p(&["--threads", "--layout", layout, "--record-once", "--sessions", "2", "--frames", "5"]).unwrap().unwrap();
            assert!(o.threads && o.record_once && o.secondary);
        }
    }

    /// `--record-once` works with every layout, way of starting a pass, secondary contents,
    /// intermediate target, animation and Vulkan binding (nothing it needs varies per frame
    /// except through memory); only the flag's own misuse is refused.
    #[test]
    fn record_once_combines_with_everything() {
        assert!(!p(&[]).unwrap().unwrap().record_once);
        for layout in ["per-eye", "multiview", "side-by-side"] {
            for rendering in ["render-pass", "render-pass2", "dynamic"] {
                for extra in [&[][..], &["--secondary"], &["--intermediate"], &["--intermediate", "--samples", "1", "--submit-depth"], &["--animate", "--vulkan", "enable"], &["--bind-before-pass", "--depth-clear", "image"]] {
                    let args = [&["--record-once", "--layout", layout, "--rendering", rendering][..], extra].concat();
                    let o = p(&args).unwrap_or_else(|e| panic!("{args:?}: {e}")).unwrap();
                    assert!(o.record_once, "{args:?}");
                }
            }
        }
        assert!(p(&["--record-once", "--vulkan-api", "1.0", "--secondary"]).unwrap().unwrap().record_once);
        assert!(p(&["--record-once=1"]).is_err());
        assert_eq!(p(&["--record-once", "--rerecord-every", "7"]).unwrap().unwrap().rerecord_every, Some(7));
        assert_eq!(p(&["--record-once"]).unwrap().unwrap().rerecord_every, None);
        let e = p(&["--rerecord-every", "7"]).unwrap_err();
        assert!(e.contains("--record-once"), "{e}");
        assert!(p(&["--record-once", "--rerecord-every", "0"]).is_err());
        assert!(p(&["--record-once", "--rerecord-every"]).is_err());
    }

    #[test]
    fn sync_hazard_needs_draws() {
        assert!(p(&["--sync-hazard"]).unwrap().unwrap().sync_hazard);
        assert!(!p(&[]).unwrap().unwrap().sync_hazard);
        let e = p(&["--sync-hazard", "--empty"]).unwrap_err();
        assert!(e.contains("--empty"), "{e}");
        assert!(p(&["--sync-hazard=yes"]).is_err());
    }

    #[test]
    fn far_field_scene_options() {
        let o = p(&[]).unwrap().unwrap();
        assert_eq!(o.sky, Sky::Geometry);
        assert!(!o.sky_first && !o.translucent && !o.far_movers);
        let o = p(&["--sky", "geometry", "--sky-first", "--translucent", "--far-movers"]).unwrap().unwrap();
        assert_eq!(o.sky, Sky::Geometry);
        assert!(o.sky_first && o.translucent && o.far_movers);
        assert_eq!(p(&["--sky=clear"]).unwrap().unwrap().sky, Sky::Clear);
        assert!(p(&["--sky", "box"]).is_err());
        assert!(p(&["--sky"]).is_err());
        let e = p(&["--sky", "clear", "--sky-first"]).unwrap_err();
        assert!(e.contains("--sky clear"), "{e}");
        assert!(p(&["--translucent=1"]).is_err());
        assert!(p(&["--far-movers=yes"]).is_err());
        assert!(p(&["--sky-first=1"]).is_err());
    }

    #[test]
    fn visibility_mask_flag() {
        assert!(!p(&[]).unwrap().unwrap().visibility_mask);
        assert!(p(&["--visibility-mask"]).unwrap().unwrap().visibility_mask);
        assert!(p(&["--visibility-mask=1"]).is_err());
    }

    #[test]
    fn depth_clear() {
        assert_eq!(p(&["--depth-clear", "attachments"]).unwrap().unwrap().depth_clear, DepthClear::Attachments);
        assert_eq!(p(&["--depth-clear=image"]).unwrap().unwrap().depth_clear, DepthClear::Image);
        assert_eq!(p(&["--depth-clear", "load-op"]).unwrap().unwrap().depth_clear, DepthClear::LoadOp);
        assert!(p(&["--depth-clear", "shader"]).is_err());
        assert!(p(&["--depth-clear"]).is_err());
    }

    #[test]
    fn full_set() {
        let o = p(&[
            "--layout", "multiview", "--rendering=dynamic", "--depth", "reverse", "--intermediate",
            "--vulkan", "enable", "--frames", "5", "--scale", "0.25", "--color-format", "unorm",
            "--shading-cost", "10", "--animate", "--stats", "/tmp/s.json", "--validation",
            "--pixel-stats", "/tmp/px",
        ])
        .unwrap()
        .unwrap();
        assert_eq!(o.layout, Layout::Multiview);
        assert_eq!(o.rendering, Rendering::Dynamic);
        assert_eq!(o.depth, DepthMode::Reverse);
        assert!(o.intermediate && o.animate && o.validation);
        let layers = p(&["--vk-layer", "A", "--vk-layer=B"]).unwrap().unwrap();
        assert_eq!(layers.vk_layers, ["A", "B"]);
        assert_eq!(o.samples, 4);
        assert_eq!(o.vulkan, VulkanPath::Enable);
        assert_eq!(o.frames, Some(5));
        assert_eq!(o.scale, 0.25);
        assert_eq!(o.shading_cost, 10);
        assert_eq!(o.stats.as_deref(), Some(std::path::Path::new("/tmp/s.json")));
        assert_eq!(o.pixel_stats.as_deref(), Some(std::path::Path::new("/tmp/px")));
        assert_eq!(p(&[]).unwrap().unwrap().pixel_stats, None);
    }

    #[test]
    fn errors() {
        assert!(p(&["--layout", "quad"]).is_err());
        assert!(p(&["--layout"]).is_err());
        assert!(p(&["--bogus"]).is_err());
        assert!(p(&["--scale", "-1"]).is_err());
        assert!(p(&["--frames", "0"]).is_err());
        assert!(p(&["--sessions", "0"]).is_err());
        assert_eq!(p(&["--sessions", "3"]).unwrap().map(|o| o.sessions), Some(3));
        assert!(p(&["--samples", "3", "--intermediate"]).is_err());
        assert!(p(&["--samples", "4"]).is_err());
        assert!(p(&["--submit-depth", "--intermediate"]).is_err());
        assert!(p(&["--submit-depth", "--intermediate", "--samples", "1"]).is_ok());
        assert!(p(&["--submit-depth"]).is_ok());
        assert_eq!(p(&["--help"]).unwrap(), None);
    }
}
