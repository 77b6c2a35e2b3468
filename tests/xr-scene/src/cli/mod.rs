//! Command-line parsing (clap): the flag set is the test contract of docs/testing.md; the checks of
//! combinations that cannot work live in `parse`.

mod post;
mod swapchain;

use clap::{CommandFactory, Parser, ValueEnum};
use post::check_post;
use swapchain::check_swapchain;
use std::path::PathBuf;

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Layout {
    PerEye,
    Multiview,
    SideBySide,
}

/// `--eye-swapchain`: with `--layout per-eye`, where each eye pass's picture ends up.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum EyeSwapchain {
    /// A swapchain per eye.
    PerEye,
    /// One 2-layer swapchain: eye v's picture is array layer v of its image (`imageArrayIndex`
    /// v), written by eye v's own pass or its copy / post chain, as many engines and xrizer
    /// submit separately rendered eyes.
    Array,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Rendering {
    RenderPass,
    #[value(name = "render-pass2")]
    RenderPass2,
    Dynamic,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum DepthMode {
    Standard,
    Reverse,
}

/// How the depth buffer of an eye pass starts out at its clear value (`--depth-clear`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum DepthClear {
    /// The pass's depth attachment has loadOp CLEAR.
    LoadOp,
    /// loadOp LOAD, then `vkCmdClearAttachments` of the depth aspect as the pass's first command.
    Attachments,
    /// `vkCmdClearDepthStencilImage` before the pass (image in TRANSFER_DST_OPTIMAL), loadOp LOAD.
    Image,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum VulkanPath {
    Enable,
    #[value(name = "enable2")]
    Enable2,
}

/// The Vulkan version the app asks for in `VkApplicationInfo::apiVersion` (`--vulkan-api`), and so
/// the API it may use on its instance and device.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, ValueEnum)]
pub enum VulkanApi {
    /// Vulkan 1.0: no multiview, no dynamic rendering, no 1.1+ structs; render pass 2 through
    /// `VK_KHR_create_renderpass2`.
    #[value(name = "1.0")]
    V1_0,
    /// Vulkan 1.1: multiview core; render pass 2 and dynamic rendering through their KHR extensions.
    #[value(name = "1.1")]
    V1_1,
    #[value(name = "1.3")]
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
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Sky {
    /// A sky dome of far geometry (1500 m) around the stage: every pixel not covered by scenery.
    Geometry,
    /// No sky geometry: what the scenery does not cover keeps the pass's clear colour.
    Clear,
}

/// How a session and its instance are torn down (`--teardown`): every order OpenXR allows, and
/// one it does not that apps use.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Teardown {
    /// Children first: swapchains, session, the Vulkan device, the XR instance.
    Children,
    /// `xrDestroySession` with its swapchains still alive: the runtime destroys them with it.
    Session,
    /// `xrDestroyInstance` with its session and swapchains alive (the last session only), and the
    /// Vulkan device destroyed after the XR instance.
    Instance,
    /// Children first, but after the last frame one more is drawn into newly acquired images,
    /// neither released nor ended, and the swapchains are destroyed while its work may still run;
    /// the app waits for its device only afterwards (Bevy at exit, rendering ahead). Outside what
    /// the spec allows the app; what a runtime, and a layer, must survive.
    InFlight,
}

/// The post-processing chain between the eye pass and the swapchain (`--post`), as engines record
/// it: the eye pass renders into an RGBA16F target and full-screen draws take it from there.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum PostEffect {
    /// One full-screen draw: tonemap the scene target into the swapchain image.
    Tonemap,
    /// A down-sample mip chain (half, quarter, eighth size) and its up-sample, added in the
    /// tonemap draw.
    Bloom,
    /// A history buffer (the previous frame's output) blended into the tonemap draw, then the new
    /// output copied into it.
    Taa,
}

/// Who copies the app's eye textures into the swapchain (`--submit-via`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum SubmitVia {
    /// The app, at the end of its own frame's command buffer.
    App,
    /// A second component on the app's device, as xrizer and OpenComposite submit an OpenVR game's
    /// texture: its own command pool and command buffer, its own `vkQueueSubmit` after the app's,
    /// no fence or semaphore.
    Openvr,
}

/// How the app hands its rendered eyes to the runtime (`--submit-texture`), other than the
/// swapchain layout its passes render into.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum SubmitTexture {
    /// Both eyes rendered side by side into one double-wide texture of the app's, then blitted
    /// (`vkCmdBlitImage` with bounds) each half into its layer of a 2-layer swapchain: what
    /// xrizer and OpenComposite do with an OpenVR game's texture.
    DoubleWide,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
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
    /// The eye pass's sample count: `--intermediate`'s or `--post`'s target (`--samples`), or on
    /// the direct path the swapchain's own (`--swapchain-samples`).
    pub samples: u32,
    /// `--swapchain-samples`: the colour swapchain's `sampleCount` (the eye pass renders into it
    /// directly when > 1).
    pub swapchain_samples: u32,
    /// `--swapchain-mips`: the colour swapchain's `mipCount`; only level 0 is rendered.
    pub swapchain_mips: u32,
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
    /// `--dynamic-state`: the scene's pipelines leave nearly all state to commands, as DXVK
    /// records (extended dynamic state 1-3, vertex input), set after each bind.
    pub dynamic_state: bool,
    /// `--pipeline-library`: the scene's pipelines linked from graphics pipeline libraries (one
    /// per state subset), as DXVK builds them.
    pub pipeline_library: bool,
    /// `--shader-object`: the scene drawn with shader objects (`VK_EXT_shader_object`) instead of
    /// pipelines, every state set by commands (implies `dynamic_state`).
    pub shader_object: bool,
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
    /// `--draw-hidden-area`: as `--visibility-mask`, and each eye pass draws its view's mesh
    /// first, black at the near depth, as games do (the app's mask under the layer's).
    pub draw_hidden_area: bool,
    /// `--quad`: a static swapchain of half a view's size, filled once, submitted every frame as a
    /// quad layer after the projection layer (`crate::quad`).
    pub quad: bool,
    /// `--widen-fov DEG`: each located view's four angles widened by DEG before the app renders
    /// and submits it (an app that renders more than the runtime asked, e.g. for its own
    /// reprojection).
    pub widen_fov_deg: f32,
    /// `--assume-symmetric`: the right eye is drawn with the left eye's projection mirrored (its
    /// vertical angles, its horizontal ones swapped), as single-pass-stereo renderers do; each
    /// view is submitted as located.
    pub assume_symmetric: bool,
    /// `--assume-parallel`: both eyes are drawn looking the same way (the mean of the located
    /// orientations), as apps that place each eye at the head's orientation do; each view is
    /// submitted as located.
    pub assume_parallel: bool,
    /// `--post`: the post-processing chain after the eye pass (none: the eye pass renders the
    /// swapchain image, or `--intermediate`'s target).
    pub post: Option<PostEffect>,
    /// `--post-compute`: the tonemap is a compute dispatch into a storage image, copied into the
    /// swapchain image.
    pub post_compute: bool,
    /// `--post-subpass`: the tonemap is a second subpass of the eye pass's render pass, reading
    /// the scene as an input attachment.
    pub post_subpass: bool,
    /// `--post-depth-attachment`: the tonemap pass has a depth attachment (cleared, never tested).
    pub post_depth_attachment: bool,
    /// `--render-scale`: the eye pass's target is this fraction of the swapchain's size.
    pub render_scale: f32,
    /// `--viewport-scale`: the eye pass draws into this fraction of its (full-size) target.
    pub viewport_scale: f32,
    /// `--submit-texture double-wide`.
    pub submit_texture: Option<SubmitTexture>,
    /// `--submit-via`: who copies the eye textures into the swapchain.
    pub submit_via: SubmitVia,
    /// `--one-target`: per eye, with `--intermediate`: one offscreen target for both eyes, each
    /// eye's pass followed by its copy into its swapchain image before the other eye renders;
    /// with `--post tonemap` or `bloom`: one scene target for both eyes, each eye's pass followed
    /// by its post chain into its swapchain image.
    pub one_target: bool,
    /// `--temporary-session`: before the app's own Vulkan instance and device, a session on an
    /// instance and device of their own, made and destroyed (xrizer's "temporary session").
    pub temporary_session: bool,
    /// `--dynamic-resolution`: the eye passes draw into a sub-rect of their target that changes
    /// every frame (`crate::post::dynamic_scale`), read back whole by the tonemap.
    pub dynamic_resolution: bool,
    /// `--eye-swapchain`: with per-eye layout, a swapchain per eye or one 2-layer swapchain.
    pub eye_swapchain: EyeSwapchain,
}

/// The command line as clap sees it; `parse` turns it into checked `Options`.
#[derive(Parser, Debug)]
#[command(
    name = "xr-scene",
    about = "An unmodified stereo OpenXR + Vulkan app: the subject of stereoshim's end-to-end tests",
    long_about = None,
    // The harness appends a test's arguments to its defaults: the last value given wins.
    args_override_self = true
)]
struct Args {
    /// Swapchain layout.
    #[arg(long, value_enum, default_value_t = Layout::PerEye)]
    layout: Layout,
    /// How eye passes begin.
    #[arg(long, value_enum, default_value_t = Rendering::RenderPass)]
    rendering: Rendering,
    /// Depth convention.
    #[arg(long, value_enum, default_value_t = DepthMode::Standard)]
    depth: DepthMode,
    /// How depth is cleared: the pass's load op, vkCmdClearAttachments in the pass, or
    /// vkCmdClearDepthStencilImage before it.
    #[arg(long, value_enum, default_value_t = DepthClear::LoadOp)]
    depth_clear: DepthClear,
    /// Render offscreen, then resolve/copy to the swapchain.
    #[arg(long)]
    intermediate: bool,
    /// Offscreen sample count with --intermediate [default: 4].
    #[arg(long, value_parser = parse_samples)]
    samples: Option<u32>,
    /// Colour swapchain sampleCount N in 1, 2, 4, 8; N > 1: the eye pass renders straight into
    /// the multisampled swapchain image (no --intermediate, --post or --submit-depth).
    #[arg(long, value_name = "N", default_value_t = 1, value_parser = parse_swapchain_samples)]
    swapchain_samples: u32,
    /// Colour swapchain mipCount N (>= 1, at most the full chain of its size); only level 0 is
    /// rendered.
    #[arg(long, value_name = "N", default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..))]
    swapchain_mips: u32,
    /// Submit depth swapchains (XR_KHR_composition_layer_depth).
    #[arg(long)]
    submit_depth: bool,
    /// OpenXR Vulkan binding extension.
    #[arg(long, value_enum, default_value_t = VulkanPath::Enable2)]
    vulkan: VulkanPath,
    /// apiVersion of the app's VkInstance/VkDevice. 1.0: per-eye / side-by-side, render-pass /
    /// render-pass2 (VK_KHR_create_renderpass2); 1.1: dynamic rendering through
    /// VK_KHR_dynamic_rendering.
    #[arg(long, value_enum, default_value_t = VulkanApi::V1_3)]
    vulkan_api: VulkanApi,
    /// Record each eye pass's contents into a secondary command buffer run by vkCmdExecuteCommands.
    #[arg(long)]
    secondary: bool,
    /// Destroy swapchains, then the session, the Vulkan device and the XR instance (children);
    /// leave the swapchains to xrDestroySession (session); or leave the last session and its
    /// swapchains to xrDestroyInstance, destroying the Vulkan device after it (instance); or
    /// destroy the swapchains while one more frame's work may still run (in-flight).
    #[arg(long, value_enum, default_value_t = Teardown::Children)]
    teardown: Teardown,
    /// xrWaitFrame on a frame-pacing thread (the next frame's wait overlapping this frame), each
    /// pass's secondary recorded on a worker thread with its own command pool, vkQueueSubmit on a
    /// submit thread; implies --secondary.
    #[arg(long)]
    threads: bool,
    /// Request exit after N frames (of each session).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u64).range(1..))]
    frames: Option<u64>,
    /// End and recreate the session (swapchains, renderer) N times; prints each session's frames
    /// and the process's resident memory to stderr.
    #[arg(long, value_name = "N", default_value_t = 1, value_parser = clap::value_parser!(u64).range(1..))]
    sessions: u64,
    /// Create and destroy the XR instance, Vulkan instance and device (and their sessions) N times.
    #[arg(long, value_name = "N", default_value_t = 1, value_parser = clap::value_parser!(u64).range(1..))]
    instances: u64,
    /// Every K frames destroy the swapchains and make new ones of another size (x1, x0.8, x1.2 of
    /// --scale in turn).
    #[arg(long, value_name = "K", value_parser = clap::value_parser!(u64).range(1..))]
    recreate_swapchains: Option<u64>,
    /// Render at F x the recommended size, F in (0, 4].
    #[arg(long, value_name = "F", default_value_t = 1.0, value_parser = parse_scale)]
    scale: f32,
    /// Swapchain colour format family.
    #[arg(long, value_enum, default_value_t = ColorFamily::Srgb)]
    color_format: ColorFamily,
    /// K-iteration per-pixel busy loop.
    #[arg(long, value_name = "K", default_value_t = 0)]
    shading_cost: u32,
    /// Spin the near cube by frame number.
    #[arg(long)]
    animate: bool,
    /// Set draw state before vkCmdBegin*, not inside the pass.
    #[arg(long)]
    bind_before_pass: bool,
    /// Scene pipelines with nearly every state dynamic (extended dynamic state 1-3, vertex input),
    /// set by commands as DXVK records them (Vulkan 1.3).
    #[arg(long)]
    dynamic_state: bool,
    /// Scene pipelines linked from graphics pipeline libraries, as DXVK builds them (Vulkan 1.3).
    #[arg(long)]
    pipeline_library: bool,
    /// Draw the scene with shader objects (VK_EXT_shader_object), every state from commands;
    /// implies --dynamic-state, needs --rendering dynamic.
    #[arg(long)]
    shader_object: bool,
    /// Passes with their clears but no draws (layer cost benchmarks).
    #[arg(long)]
    empty: bool,
    /// Write per-frame GPU time and shaded fragments as JSON.
    #[arg(long, value_name = "FILE")]
    stats: Option<PathBuf>,
    /// Write per frame and view the shaded fragments of each pixel (DIR/frame-NNNNN-view-V.u32,
    /// raw little-endian u32).
    #[arg(long, value_name = "DIR")]
    pixel_stats: Option<PathBuf>,
    /// Enable VK_LAYER_KHRONOS_validation with synchronization validation (exit 3 on errors).
    #[arg(long)]
    validation: bool,
    /// Also enable the Vulkan layer NAME in the app's instance create info (repeatable; after
    /// validation, in order).
    #[arg(long = "vk-layer", value_name = "NAME")]
    vk_layers: Vec<String>,
    /// Record each combination of acquired swapchain images' command buffers once and resubmit
    /// them every frame (per-frame data in per-frame-in-flight buffers).
    #[arg(long)]
    record_once: bool,
    /// With --record-once: every N-th frame re-records the command buffers it submits (the others
    /// stay as recorded).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u64).range(1..))]
    rerecord_every: Option<u64>,
    /// Leave out one barrier (counters' fill -> fragment shader): a hazard only synchronization
    /// validation reports.
    #[arg(long)]
    sync_hazard: bool,
    /// With --threads: the workers share one command pool, used by two threads at once (only
    /// validation's thread-safety checks report it).
    #[arg(long)]
    thread_hazard: bool,
    /// A sky dome of far geometry or just the clear colour.
    #[arg(long, value_enum, default_value_t = Sky::Geometry)]
    sky: Sky,
    /// Draw the sky first in each eye pass, depth test and depth write off (default: last in the
    /// scene's draw, depth-tested).
    #[arg(long)]
    sky_first: bool,
    /// A translucent near pane blended over the far field, drawn after the opaque geometry, depth
    /// write off.
    #[arg(long)]
    translucent: bool,
    /// A far object (~250 m) that orbits the stage by frame number.
    #[arg(long)]
    far_movers: bool,
    /// Submit frames with vkQueueSubmit2 (needs --vulkan-api 1.3).
    #[arg(long)]
    submit2: bool,
    /// Fetch each view's hidden-area mesh (XR_KHR_visibility_mask).
    #[arg(long)]
    visibility_mask: bool,
    /// Fetch each view's hidden-area mesh and draw it first in every eye pass, black at the
    /// near depth (as games that mask themselves do).
    #[arg(long)]
    draw_hidden_area: bool,
    /// Submit a quad layer every frame from a static swapchain (half a view's size, filled once).
    #[arg(long)]
    quad: bool,
    /// Widen each located view's angles by DEG (0..=20) before rendering and submitting it.
    #[arg(long, value_name = "DEG", default_value_t = 0.0, value_parser = parse_widen)]
    widen_fov: f32,
    /// Draw the right eye with the left eye's projection mirrored (an app assuming symmetric
    /// eyes); submit the views as located.
    #[arg(long)]
    assume_symmetric: bool,
    /// Draw both eyes looking the same way (an app assuming parallel eyes); submit the views as
    /// located.
    #[arg(long)]
    assume_parallel: bool,
    /// Render the eye passes into an RGBA16F target, then post-process into the swapchain with
    /// full-screen draws: tonemap; bloom (down/up-sample chain, then tonemap); taa (history
    /// blended into the tonemap).
    #[arg(long, value_enum)]
    post: Option<PostEffect>,
    /// With --post tonemap: tonemap in a compute dispatch into a storage image, then
    /// vkCmdCopyImage into the swapchain image.
    #[arg(long)]
    post_compute: bool,
    /// With --post tonemap: tonemap in a second subpass of the eye pass's render pass, reading
    /// the scene as an input attachment (render-pass and render-pass2 only).
    #[arg(long)]
    post_subpass: bool,
    /// With --post: the tonemap pass gets a depth attachment, cleared and never tested.
    #[arg(long)]
    post_depth_attachment: bool,
    /// With --post: the eye passes render at F x the swapchain size, F in [0.5, 1]; the tonemap
    /// upscales (bilinear).
    #[arg(long, value_name = "F", default_value_t = 1.0, value_parser = parse_fraction)]
    render_scale: f32,
    /// With --post: the eye passes draw into an F x sub-rect (viewport and scissor) of a
    /// full-size target, F in [0.5, 1]; the tonemap reads only that sub-rect.
    #[arg(long, value_name = "F", default_value_t = 1.0, value_parser = parse_fraction)]
    viewport_scale: f32,
    /// With --layout side-by-side: render into a double-wide texture of the app's and blit each
    /// half into its layer of a 2-layer swapchain.
    #[arg(long, value_enum)]
    submit_texture: Option<SubmitTexture>,
    /// Who copies --intermediate's or --submit-texture's textures into the swapchain: the app at
    /// the end of its frame, or an OpenVR compositor (xrizer, OpenComposite) in a submission of
    /// its own after the app's.
    #[arg(long, value_enum, default_value_t = SubmitVia::App)]
    submit_via: SubmitVia,
    /// With --layout per-eye --intermediate: one offscreen target for both eyes, rendered one
    /// eye after the other, each copied (or resolved) into its swapchain before the next. With
    /// --post tonemap or bloom (drawn): one scene target for both eyes, each eye's pass followed
    /// by its own post chain into its swapchain image before the next eye renders.
    #[arg(long)]
    one_target: bool,
    /// Before the app's own Vulkan instance and device: a session on a Vulkan instance and device
    /// of their own (made through the runtime as the real ones), destroyed at once, as xrizer does
    /// before an OpenVR game's first submission.
    #[arg(long)]
    temporary_session: bool,
    /// With --post tonemap or taa: dynamic resolution, the eye passes' sub-rect of their target
    /// changes every frame (x1, x0.75, x0.875 of it in turn, on top of --viewport-scale); the
    /// tonemap reads each frame's sub-rect.
    #[arg(long)]
    dynamic_resolution: bool,
    /// With --layout per-eye: a swapchain per eye, or one 2-layer swapchain whose layer v eye v's
    /// pass (or its copy, or its post chain) writes.
    #[arg(long, value_enum, default_value_t = EyeSwapchain::PerEye)]
    eye_swapchain: EyeSwapchain,
}

/// `--widen-fov`: degrees in 0..=20.
fn parse_widen(v: &str) -> Result<f32, String> {
    v.parse::<f32>().ok().filter(|d| (0.0..=20.0).contains(d)).ok_or_else(|| format!("{v}: want degrees in 0..=20"))
}

/// `--swapchain-samples`: the counts an app asks a runtime for (the device decides which it has).
fn parse_swapchain_samples(v: &str) -> Result<u32, String> {
    match v.parse::<u32>() {
        Ok(n @ (1 | 2 | 4 | 8)) => Ok(n),
        _ => Err(format!("must be 1, 2, 4 or 8, got {v:?}")),
    }
}

fn parse_samples(v: &str) -> Result<u32, String> {
    match v.parse::<u32>() {
        Ok(n @ (1 | 2 | 4 | 8 | 16 | 32 | 64)) => Ok(n),
        _ => Err(format!("must be a power of two 1..64, got {v:?}")),
    }
}

/// `--render-scale`, `--viewport-scale`: what engines' dynamic resolution spans.
fn parse_fraction(v: &str) -> Result<f32, String> {
    v.parse::<f32>().ok().filter(|f| (0.5..=1.0).contains(f)).ok_or_else(|| format!("must be a number in [0.5, 1], got {v:?}"))
}

fn parse_scale(v: &str) -> Result<f32, String> {
    v.parse::<f32>().ok().filter(|f| f.is_finite() && *f > 0.0 && *f <= 4.0).ok_or_else(|| format!("must be a number in (0, 4], got {v:?}"))
}

/// Parses the arguments after the program name into checked `Options`. `Err` is clap's: a usage
/// error, or the help text (`--help`), which `Error::exit` prints and exits with.
pub fn parse<I: IntoIterator<Item = String>>(args: I) -> Result<Options, clap::Error> {
    let a = Args::try_parse_from(std::iter::once("xr-scene".to_string()).chain(args))?;
    let usage = |msg: &str| Args::command().error(clap::error::ErrorKind::ArgumentConflict, msg);
    if a.samples.is_some() && !a.intermediate && a.post.is_none() {
        return Err(usage("--samples only applies with --intermediate or --post"));
    }
    check_swapchain(&a).map_err(|m| usage(&m))?;
    // `--intermediate` has always meant 4 samples unless told; the post chain's scene target is
    // single-sampled unless told (Bevy's MSAA is one option among several). On the direct path
    // the eye pass has the swapchain's samples.
    let samples = match (a.intermediate, a.post.is_some()) {
        (true, _) => a.samples.unwrap_or(4),
        (false, true) => a.samples.unwrap_or(1),
        (false, false) => a.swapchain_samples,
    };
    check_post(&a, samples).map_err(|m| usage(&m))?;
    // Depth rendered at N samples cannot simply be submitted: resolving it needs
    // VK_KHR_depth_stencil_resolve and a choice of resolve mode, which this app does not make.
    if a.submit_depth && samples > 1 {
        return Err(usage("--submit-depth needs single-sampled depth: use --samples 1 with --intermediate"));
    }
    if a.vulkan_api == VulkanApi::V1_0 {
        if a.layout == Layout::Multiview {
            return Err(usage("--layout multiview needs Vulkan 1.1 (multiview); use --vulkan-api 1.1 or 1.3"));
        }
        if a.rendering == Rendering::Dynamic {
            return Err(usage("--rendering dynamic needs Vulkan 1.1 (VK_KHR_dynamic_rendering) or 1.3"));
        }
    }
    if (a.dynamic_state || a.pipeline_library || a.shader_object) && a.vulkan_api != VulkanApi::V1_3 {
        return Err(usage("--dynamic-state, --pipeline-library and --shader-object need Vulkan 1.3 (extended dynamic state is core there)"));
    }
    if a.shader_object && (a.rendering != Rendering::Dynamic || a.pipeline_library) {
        return Err(usage("--shader-object draws without pipelines, in dynamic rendering only: it needs --rendering dynamic and excludes --pipeline-library"));
    }
    let drawn_post = matches!(a.post, Some(PostEffect::Tonemap | PostEffect::Bloom)) && !a.post_compute && !a.post_subpass;
    let one_target_fits = (a.intermediate || drawn_post) && a.layout == Layout::PerEye && a.submit_via == SubmitVia::App && a.submit_texture.is_none();
    // One depth image too, cleared by each eye's pass (a clear by transfer would need its own
    // barriers between the eyes).
    let records_simply = !(a.secondary || a.threads || a.record_once || a.depth_clear == DepthClear::Image || a.submit_depth);
    if a.one_target && !(one_target_fits && records_simply) {
        return Err(usage("--one-target shares one target between the two per-eye passes, carried into each eye's swapchain image by the app between them: it needs --layout per-eye with --intermediate (copied) or --post tonemap / bloom (drawn, not --post-compute or --post-subpass), without --submit-via openvr, --submit-texture, --submit-depth, --depth-clear image, --secondary, --threads or --record-once"));
    }
    check_eye_swapchain(&a).map_err(|m| usage(&m))?;
    if a.submit_via == SubmitVia::Openvr && !(a.intermediate || a.submit_texture.is_some()) {
        return Err(usage("--submit-via openvr copies the app's textures: it needs --intermediate or --submit-texture"));
    }
    if a.submit_via == SubmitVia::Openvr && (a.record_once || a.threads || a.post.is_some()) {
        return Err(usage("--submit-via openvr records its copy every frame on the render thread, after the app's own: not with --record-once, --threads or --post"));
    }
    if a.submit2 && a.vulkan_api != VulkanApi::V1_3 {
        return Err(usage("--submit2 needs Vulkan 1.3 (vkQueueSubmit2, synchronization2)"));
    }
    if a.thread_hazard && !a.threads {
        return Err(usage("--thread-hazard shares one command pool between the recording workers: it needs --threads"));
    }
    // State bound in a primary command buffer is not inherited by secondaries.
    if a.threads && a.bind_before_pass {
        return Err(usage("--bind-before-pass cannot be combined with --threads: --threads records each pass into a secondary command buffer (on a worker thread), which inherits no state bound in the primary"));
    }
    if a.secondary && a.bind_before_pass {
        return Err(usage("--bind-before-pass and --secondary exclude each other: a secondary command buffer inherits no bound state"));
    }
    // Without --record-once every frame is re-recorded anyway.
    if a.rerecord_every.is_some() && !a.record_once {
        return Err(usage("--rerecord-every only applies with --record-once"));
    }
    // The left-out barrier guards the fragment shader's counter writes: without draws there is
    // no hazard to report, and the flag would prove nothing.
    if a.sync_hazard && a.empty {
        return Err(usage("--sync-hazard needs draws: it cannot be combined with --empty"));
    }
    // Without sky geometry there is nothing to draw first.
    if a.sky_first && a.sky == Sky::Clear {
        return Err(usage("--sky-first needs sky geometry: it cannot be combined with --sky clear"));
    }
    Ok(Options {
        layout: a.layout,
        rendering: a.rendering,
        depth: a.depth,
        depth_clear: a.depth_clear,
        intermediate: a.intermediate,
        samples,
        swapchain_samples: a.swapchain_samples,
        swapchain_mips: a.swapchain_mips,
        submit_depth: a.submit_depth,
        vulkan: a.vulkan,
        vulkan_api: a.vulkan_api,
        secondary: a.secondary || a.threads,
        threads: a.threads,
        teardown: a.teardown,
        frames: a.frames,
        sessions: a.sessions,
        instances: a.instances,
        recreate_swapchains: a.recreate_swapchains,
        scale: a.scale,
        color_format: a.color_format,
        shading_cost: a.shading_cost,
        animate: a.animate,
        bind_before_pass: a.bind_before_pass,
        dynamic_state: a.dynamic_state || a.shader_object,
        pipeline_library: a.pipeline_library,
        shader_object: a.shader_object,
        empty: a.empty,
        stats: a.stats,
        pixel_stats: a.pixel_stats,
        validation: a.validation,
        vk_layers: a.vk_layers,
        record_once: a.record_once,
        rerecord_every: a.rerecord_every,
        sync_hazard: a.sync_hazard,
        thread_hazard: a.thread_hazard,
        sky: a.sky,
        sky_first: a.sky_first,
        translucent: a.translucent,
        far_movers: a.far_movers,
        submit2: a.submit2,
        visibility_mask: a.visibility_mask || a.draw_hidden_area,
        draw_hidden_area: a.draw_hidden_area,
        quad: a.quad,
        widen_fov_deg: a.widen_fov,
        assume_symmetric: a.assume_symmetric,
        assume_parallel: a.assume_parallel,
        post: a.post,
        post_compute: a.post_compute,
        post_subpass: a.post_subpass,
        post_depth_attachment: a.post_depth_attachment,
        render_scale: a.render_scale,
        viewport_scale: a.viewport_scale,
        submit_texture: a.submit_texture,
        submit_via: a.submit_via,
        one_target: a.one_target,
        temporary_session: a.temporary_session,
        dynamic_resolution: a.dynamic_resolution,
        eye_swapchain: a.eye_swapchain,
    })
}

/// `--eye-swapchain array`: the shapes whose every write of a final image addresses one eye's
/// layer through a single-layer view or subresource. Refused: what writes the swapchain image
/// whole or per slot in other ways (a compositor's copy, a double-wide blit, TAA's history copy
/// and the compute tonemap's copy, the tonemap subpass), submitted depth (a depth swapchain per
/// eye), and the recording variants this shape was not built for.
fn check_eye_swapchain(a: &Args) -> Result<(), String> {
    if a.eye_swapchain == EyeSwapchain::PerEye {
        return Ok(());
    }
    if a.layout != Layout::PerEye {
        return Err("--eye-swapchain array puts per-eye passes' pictures into the layers of one swapchain: it needs --layout per-eye (multiview and side-by-side already have one swapchain)".into());
    }
    let refused = [
        (a.submit_via == SubmitVia::Openvr, "--submit-via openvr"),
        (a.submit_texture.is_some(), "--submit-texture"),
        (a.submit_depth, "--submit-depth"),
        (a.post == Some(PostEffect::Taa), "--post taa"),
        (a.post_compute, "--post-compute"),
        (a.post_subpass, "--post-subpass"),
        (a.threads, "--threads"),
        (a.secondary, "--secondary"),
        (a.record_once, "--record-once"),
        (a.swapchain_samples > 1, "--swapchain-samples"),
        (a.swapchain_mips > 1, "--swapchain-mips"),
    ];
    match refused.iter().filter(|(on, _)| *on).map(|(_, name)| *name).collect::<Vec<_>>() {
        names if names.is_empty() => Ok(()),
        names => Err(format!(
            "--eye-swapchain array writes each eye's picture into its layer of one swapchain image through per-layer views; not supported with {}",
            names.join(", ")
        )),
    }
}

#[cfg(test)]
mod tests;
