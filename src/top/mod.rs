//! `stereoshim top`: a live terminal dashboard for one running app with the layer — its frame
//! time and rate, what each feature did and saved, what was found and why passes were left
//! alone, keys that switch features and presets in the app's config section, and a live A/B
//! of the features in the running app. It talks to the layer through the live folder
//! (`core::live`): a heartbeat keeps the layer streaming each frame's stats line and applying
//! `top`'s live settings (its GPU timer, the A/B's stretches); leaving removes both, so the app
//! runs as its config says again — the config file is only ever changed by the feature keys.
//!
//! `channel` finds apps and reads the stream, `model` and `ab` compute (pure), `config_edit`
//! edits the config file keeping its comments, `state` applies keys, `ui` draws.
#![forbid(unsafe_code)]

pub mod ab;
pub mod channel;
pub mod config_edit;
pub mod model;
pub mod state;
pub mod ui;

use ratatui::crossterm::event::{self, Event, KeyCode, KeyEventKind, KeyModifiers};
use std::time::{Duration, Instant};

/// How `top` was asked to run.
#[derive(Clone, Debug, Default)]
pub struct Options {
    pub pid: Option<u32>,
    pub app: Option<String>,
    pub ab_period: Option<u64>,
    pub ab_cycles: Option<usize>,
}

/// Finds the app, then shows the dashboard until `q` (or the app ends). Returns what to print
/// after the terminal is restored.
pub fn run(env: &dyn Fn(&str) -> Option<String>, opts: &Options) -> Result<String, String> {
    let base = crate::manifests::private_fs::private_base(env).ok_or("none of XDG_RUNTIME_DIR, XDG_STATE_HOME, HOME is set")?;
    let folder = crate::core::live::folder(&base);
    let app = channel::pick(&channel::running(&folder), opts.pid, opts.app.as_deref())?;
    let ch = channel::Channel { folder, pid: app.pid };
    let mut st = state::State::new(app.clone(), ch.clone(), state::app_environment(app.pid));
    if let Some(p) = opts.ab_period {
        st.ab_period = p;
    }
    if let Some(c) = opts.ab_cycles {
        st.ab_cycles = c;
    }
    ch.beat().map_err(|e| format!("{}: {e}", ch.folder.display()))?;
    ch.write_settings(&st.live_settings()).map_err(|e| format!("{}: {e}", ch.folder.display()))?;

    let mut terminal = ratatui::init();
    let result = event_loop(&mut terminal, &mut st, &ch);
    ratatui::restore();
    // Whatever happened: the app runs as its config says again.
    ch.leave();
    result?;
    let mut out = format!("stereoshim top: left {} (pid {}); its live settings are removed", app.app, app.pid);
    for o in &st.outcomes {
        out.push_str(&format!("\nA/B {}", o.line()));
    }
    Ok(out)
}

fn event_loop(terminal: &mut ratatui::DefaultTerminal, st: &mut state::State, ch: &channel::Channel) -> Result<(), String> {
    let mut last_beat = Instant::now();
    let mut last_draw: Option<Instant> = None;
    loop {
        if last_beat.elapsed() >= crate::core::live::HEARTBEAT_EVERY {
            last_beat = Instant::now();
            if let Err(e) = ch.beat() {
                st.message = format!("heartbeat: {e}");
            }
            if !ch.alive() {
                return Err(format!("{} (pid {}) has ended", st.app.app, st.app.pid));
            }
            // A person may edit the file by hand meanwhile.
            st.reload_config();
        }
        let mut live_changed = st.poll_frames();
        if event::poll(Duration::from_millis(50)).map_err(|e| e.to_string())? {
            if let Event::Key(k) = event::read().map_err(|e| e.to_string())? {
                if k.kind == KeyEventKind::Press {
                    let action = match k.code {
                        KeyCode::Char('c') if k.modifiers.contains(KeyModifiers::CONTROL) => Some(state::Action::Quit),
                        KeyCode::Esc => Some(state::Action::Quit),
                        KeyCode::Char(c) => state::Action::of_key(c),
                        _ => None,
                    };
                    if let Some(a) = action {
                        let (_, live, quit) = st.act(a);
                        if quit {
                            return Ok(());
                        }
                        live_changed |= live;
                    }
                }
            }
            last_draw = None;
        }
        if live_changed {
            if let Err(e) = ch.write_settings(&st.live_settings()) {
                st.message = format!("live settings: {e}");
            }
        }
        // Four screens a second: the numbers are per second, and a slow link keeps up.
        if last_draw.is_none_or(|t| t.elapsed() >= Duration::from_millis(250)) {
            last_draw = Some(Instant::now());
            terminal.draw(|f| ui::draw(f, st)).map_err(|e| e.to_string())?;
        }
    }
}
