//! bevy-scene: a fixed 3D scene rendered by Bevy through bevy_mod_openxr, as an unmodified app
//! of a real engine for stereoshim's tests (docs/testing.md, "A real engine: Bevy").
//!
//! Everything a frame shows is a function of the views the runtime reports: fixed meshes, fixed
//! lights, no animation, no time-dependent effect, pipelines compiled before the first frame
//! that uses them. So two runs on the same runtime render the same pixels, with the layer or
//! without it, and a difference is the layer's doing.
//!
//! The frame structure is Bevy's own and chosen on the command line (`--help`); the default is
//! what a new Bevy XR app gets: MSAA 4×, no HDR (so TonyMcMapface tonemapping runs in the main
//! pass's shaders), then the upscaling pass into the swapchain.

mod options;
mod scene;

use std::time::Duration;

use bevy::app::ScheduleRunnerPlugin;
use bevy::prelude::*;
use bevy::render::pipelined_rendering::PipelinedRenderingPlugin;
use bevy::window::{ExitCondition, WindowPlugin};
use bevy_mod_openxr::add_xr_plugins;
use bevy_mod_openxr::init::OxrInitPlugin;
use bevy_mod_openxr::resources::OxrSessionConfig;
use bevy_mod_xr::session::{XrRequestExitMessage, XrSessionDestroyedMessage, XrState};

use options::Options;

fn main() -> AppExit {
    let options = match Options::parse(std::env::args().skip(1)) {
        Ok(o) => o,
        Err(e) => {
            eprintln!("bevy-scene: {e}\n\n{}", options::USAGE);
            return AppExit::from_code(2);
        }
    };
    if options.help {
        println!("{}", options::USAGE);
        return AppExit::Success;
    }
    let plugins = DefaultPlugins
        .build()
        // One frame is simulated, extracted and rendered per tick: no frame of latency, and the
        // frame counted is the frame submitted.
        .disable::<PipelinedRenderingPlugin>()
        // No window: the runtime's swapchain is the only target. Without winit nothing would
        // keep the app running, so the schedule runner loops, and the app ends by itself
        // (`exit_when_done`), not when windows close.
        .set(WindowPlugin { primary_window: None, exit_condition: ExitCondition::DontExit, ..default() });
    let plugins = add_xr_plugins(plugins).set(OxrInitPlugin {
        // Bevy compiles pipelines in the background and skips draws whose pipeline is not ready:
        // which frame first shows a mesh would depend on thread timing. Compiled at once, every
        // frame shows everything.
        synchronous_pipeline_compilation: true,
        ..default()
    });
    App::new()
        .add_plugins(plugins)
        .add_plugins(ScheduleRunnerPlugin::run_loop(Duration::from_millis(1)))
        .insert_resource(OxrSessionConfig { resolutions: options.resolution.map(|(w, h)| vec![UVec2::new(w, h)]), ..default() })
        .insert_resource(ClearColor(scene::SKY))
        .insert_resource(options.clone())
        .insert_resource(Progress::default())
        .add_systems(Startup, scene::setup)
        .add_observer(scene::configure_xr_camera)
        .add_systems(Update, exit_when_done)
        .run()
}

/// How far the run is: frames rendered, whether the app asked the runtime to end the session.
#[derive(Resource, Default, Debug)]
struct Progress {
    /// Ticks while the session was running (one frame submitted each).
    frames: u64,
    /// Ticks since the exit was requested (a session that never ends is an error, not a hang).
    since_exit_request: Option<u64>,
    /// Ticks before the session first ran.
    waiting: u64,
    ran: bool,
}

/// Ticks the session may take to start, and to end once asked: far above what a runtime needs
/// (the loop ticks at most once a millisecond), so reaching it means the runtime is stuck.
const MAX_WAIT_TICKS: u64 = 60_000;

/// Ends the app: after `--frames` frames (by asking the runtime to end the session, so it ends
/// cleanly), when the runtime ended and destroyed the session (`MOCK_XR_EXIT_AFTER`, Monado
/// shutting down), or with an error when no XR session can run at all.
fn exit_when_done(
    state: Option<Res<XrState>>,
    options: Res<Options>,
    mut progress: ResMut<Progress>,
    mut destroyed: MessageReader<XrSessionDestroyedMessage>,
    mut request_exit: MessageWriter<XrRequestExitMessage>,
    mut exit: MessageWriter<AppExit>,
) {
    let state = state.map(|s| *s).unwrap_or(XrState::Unavailable);
    if state == XrState::Unavailable {
        eprintln!("bevy-scene: no OpenXR session is available (see the log above)");
        exit.write(AppExit::from_code(3));
        return;
    }
    if destroyed.read().count() > 0 && progress.ran {
        eprintln!("bevy-scene: the session ended after {} frames", progress.frames);
        exit.write(AppExit::Success);
        return;
    }
    if state == XrState::Running {
        progress.ran = true;
        progress.frames += 1;
    } else if !progress.ran {
        progress.waiting += 1;
        if progress.waiting > MAX_WAIT_TICKS {
            eprintln!("bevy-scene: the session did not start (state {state:?})");
            exit.write(AppExit::from_code(4));
        }
    }
    if let Some(n) = progress.since_exit_request.as_mut() {
        *n += 1;
        if *n > MAX_WAIT_TICKS {
            eprintln!("bevy-scene: the runtime did not end the session after it was asked to (state {state:?})");
            exit.write(AppExit::from_code(5));
        }
    } else if options.frames.is_some_and(|n| progress.frames >= n) {
        request_exit.write_default();
        progress.since_exit_request = Some(0);
    }
}
