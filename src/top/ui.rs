//! `stereoshim top`'s screen, drawn with ratatui from a [`State`]: the frame's GPU time and rate
//! with a scrolling graph, what each feature did and saved in the last second, what the layer
//! found this frame and why passes were left alone (in words), the features with their keys, and
//! the A/B. Laid out for a plain 80×24 terminal; wider ones get a longer graph.
#![forbid(unsafe_code)]

use super::state::State;
use ratatui::layout::{Constraint, Layout, Rect};
use ratatui::style::{Modifier, Style};
use ratatui::text::{Line, Span};
use ratatui::widgets::{Block, Borders, Paragraph, Sparkline, Wrap};
use ratatui::Frame;

// Counts with a thousands unit (k, M, G), as the overlay writes them.
use crate::features::overlay::rules::short_count as human;

fn on(b: bool) -> &'static str {
    if b {
        "ON "
    } else {
        "off"
    }
}

/// The screen's lines outside the graph, top to bottom (also what tests read).
pub fn text_lines(s: &State) -> Vec<String> {
    let mut out = Vec::new();
    let sec = s.recent.last_second();
    let latest = s.recent.latest();
    out.push(format!(
        "stereoshim top - {} (pid {}) - frame {}",
        s.app.app,
        s.app.pid,
        latest.map_or("-".to_string(), |f| f.frame.to_string())
    ));
    out.push(format!(
        "GPU {} ms/frame  {} fps",
        sec.gpu_ms.map_or("-".to_string(), |g| format!("{g:.3}")),
        sec.fps.map_or("-".to_string(), |f| format!("{f:.1}"))
    ));
    out.push(format!(
        "masked {} px/s  RDM skipped {} px/s  VRS {} passes/s  far field reused {} px/s",
        human(sec.pixels_masked),
        human(sec.rdm_pixels_skipped),
        sec.vrs_passes,
        human(sec.far_field_pixels_reused)
    ));
    out.push(match sec.upscale_px {
        Some((r, d)) if d > 0 => format!("upscale: rendered {} of {} px/s displayed ({:.0} %)", human(r), human(d), 100.0 * r as f64 / d as f64),
        _ => "upscale: off (the app renders what it displays)".to_string(),
    });
    match latest {
        None => out.push("waiting for the app's frames (the layer streams while top watches)".to_string()),
        Some(f) => {
            let by: Vec<String> = f.masked_by.iter().filter(|(_, n)| **n > 0).map(|(k, n)| format!("{n} by {k}")).collect();
            let views: Vec<String> = f.pixels_masked.iter().map(|(v, n)| format!("view {v} {}", human(*n))).collect();
            out.push(format!(
                "this frame: {} eye passes masked{}{}, {} RDM, {} VRS",
                f.passes_masked,
                if by.is_empty() { String::new() } else { format!(" ({})", by.join(", ")) },
                if views.is_empty() { String::new() } else { format!(" [{}]", views.join(", ")) },
                f.rdm_passes,
                f.vrs_passes
            ));
            if f.not_applied.is_empty() {
                out.push("left alone: none".to_string());
            }
            for (k, n) in &f.not_applied {
                out.push(format!("left alone: {n} x {}", super::model::reason_in_words(k)));
            }
        }
    }
    let c = &s.config;
    let env = |k: &str| if s.env_override(k).is_some() { "(env)" } else { "" };
    out.push(format!(
        "[m] mask {}{}  [f] foveation {}{} [p] {} [r] {}  [d] far field {}{}",
        on(c.bool("mask.enabled")),
        env("mask.enabled"),
        on(c.bool("foveation.enabled")),
        env("foveation.enabled"),
        c.choice("foveation.preset"),
        c.choice("foveation.method"),
        on(c.bool("far_field.enabled")),
        env("far_field.enabled"),
    ));
    out.push(format!(
        "[u] upscale {}  [o] overlay {}  [b] A/B  [e] A/B each  [k] keep what pays  [x] stop  [q] quit",
        if c.bool("upscale.enabled") { format!("{:.2}", c.float("upscale.scale")) } else { "off".to_string() },
        on(c.bool("overlay.enabled")).trim_end()
    ));
    match &s.ab {
        Some(ab) => out.push(ab.status()),
        None if s.outcomes.is_empty() => out.push("A/B: none yet (b: the features on, off against on; e: each on top of the others)".to_string()),
        None => out.extend(s.outcomes.iter().map(|o| format!("A/B {}{}", o.line(), if o.pays() { "" } else { "  (does not pay)" }))),
    }
    if !s.message.is_empty() {
        out.push(s.message.clone());
    }
    out
}

/// Draws the screen.
pub fn draw(frame: &mut Frame, s: &State) {
    let lines = text_lines(s);
    let area = frame.area();
    let [title, graph, rest] = Layout::vertical([Constraint::Length(1), Constraint::Length(7), Constraint::Min(0)]).areas(area);
    frame.render_widget(Paragraph::new(Line::from(Span::styled(lines[0].clone(), Style::default().add_modifier(Modifier::BOLD)))), title);

    let [numbers, spark] = Layout::horizontal([Constraint::Length(24), Constraint::Min(10)]).areas(graph);
    let sec = s.recent.last_second();
    let number_lines = vec![
        Line::from(format!("GPU {}", sec.gpu_ms.map_or("-".to_string(), |g| format!("{g:.3} ms")))),
        Line::from(format!("    {}", sec.fps.map_or("- fps".to_string(), |f| format!("{f:.1} fps")))),
        Line::from(format!("    {} frames/s", sec.frames)),
    ];
    frame.render_widget(Paragraph::new(number_lines).block(Block::default().borders(Borders::ALL).title("frame")), numbers);
    let width = spark.width.saturating_sub(2) as usize;
    let series = s.recent.gpu_series(width.max(1));
    let max = series.iter().copied().fold(0.0f64, f64::max);
    // Hundredths of a millisecond: the sparkline takes integers.
    let data: Vec<u64> = series.iter().map(|v| (v * 100.0).round() as u64).collect();
    let title = format!("GPU ms, last {} frames (max {:.2})", data.len(), max);
    frame.render_widget(Sparkline::default().block(Block::default().borders(Borders::ALL).title(title)).data(&data), spark);

    let body: Vec<Line> = lines[2..].iter().map(|l| Line::from(l.clone())).collect();
    frame.render_widget(Paragraph::new(body).wrap(Wrap { trim: true }), Rect { height: rest.height, ..rest });
}
