//! `stereoshim stats --plot`: a PNG of a run from its stats file — the frames' GPU time, each
//! feature's savings in pixels and its passes, on one time axis, with a vertical line wherever a
//! live setting changed. Draws `report::series` with plotters into a buffer, encoded with `png`.
#![forbid(unsafe_code)]

use super::series::{self, Series};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::{Path, PathBuf};

/// The GPU time line's colour (tests find the curve by it).
pub const GPU_COLOR: RGBColor = RGBColor(200, 30, 30);
/// The per-phase mean GPU time's colour (a darker red than the frames' line).
pub const MEAN_COLOR: RGBColor = RGBColor(110, 0, 0);
/// The colour of the vertical lines marking a setting change (tests find them by it).
pub const CHANGE_COLOR: RGBColor = RGBColor(120, 60, 170);
/// One colour per feature, the same in the pixel and the pass panels: mask, RDM, far field /
/// VRS (no feature has both a pixel and a pass line in that slot), upscale.
const PIXEL_COLORS: [RGBColor; 4] = [RGBColor(30, 90, 200), RGBColor(20, 150, 60), RGBColor(0, 160, 170), RGBColor(230, 130, 0)];
const PASS_COLORS: [RGBColor; 4] = [RGBColor(30, 90, 200), RGBColor(20, 150, 60), RGBColor(140, 90, 40), RGBColor(230, 130, 0)];
const GRID: RGBColor = RGBColor(225, 225, 225);
const FONT_FAMILY: &str = "sans-serif";

/// Where fonts are commonly found (Debian and Ubuntu, Arch, Fedora), first match wins.
const FONT_PATHS: [&str; 6] = [
    "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/TTF/DejaVuSans.ttf",
    "/usr/share/fonts/dejavu-sans-fonts/DejaVuSans.ttf",
    "/usr/share/fonts/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/truetype/liberation/LiberationSans-Regular.ttf",
    "/usr/share/fonts/truetype/noto/NotoSans-Regular.ttf",
];

/// What to draw and how big.
#[derive(Clone, Debug)]
pub struct Options {
    pub width: u32,
    pub height: u32,
    /// The title's first part (the stats file's name).
    pub title: String,
    /// A TrueType / OpenType font for the text; None: the first of `FONT_PATHS`, else any `.ttf`
    /// under /usr/share/fonts.
    pub font: Option<PathBuf>,
}

impl Default for Options {
    fn default() -> Self {
        Options { width: 1280, height: 720, title: String::new(), font: None }
    }
}

/// Parses `WIDTHxHEIGHT` (each 200–8000 pixels: smaller leaves no room for the panels).
pub fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(|| format!("{s}: not WIDTHxHEIGHT"))?;
    let n = |v: &str| v.trim().parse::<u32>().ok().filter(|n| (200..=8000).contains(n)).ok_or_else(|| format!("{s}: width and height must be 200 to 8000 pixels"));
    Ok((n(w)?, n(h)?))
}

/// The first `.ttf` file under `dir`, depth first in name order (so the choice is stable).
fn any_ttf(dir: &Path, depth: u32) -> Option<PathBuf> {
    let mut entries: Vec<PathBuf> = std::fs::read_dir(dir).ok()?.filter_map(|e| e.ok().map(|e| e.path())).collect();
    entries.sort();
    entries.iter().find(|p| p.extension().is_some_and(|e| e.eq_ignore_ascii_case("ttf")) && p.is_file()).cloned().or_else(|| {
        if depth == 0 {
            return None;
        }
        entries.iter().filter(|p| p.is_dir()).find_map(|d| any_ttf(d, depth - 1))
    })
}

/// Registers a font for plotters' text. plotters' `ab_glyph` renderer knows no system fonts, and
/// its default renderer would need fontconfig and FreeType to build and run; so a font file is
/// looked up here. Err says why there is none (the plot is then drawn without text).
fn load_font(chosen: Option<&Path>) -> Result<PathBuf, String> {
    let path = match chosen {
        Some(p) => p.to_path_buf(),
        None => FONT_PATHS
            .iter()
            .map(PathBuf::from)
            .find(|p| p.is_file())
            .or_else(|| any_ttf(Path::new("/usr/share/fonts"), 4))
            .ok_or("no font found (DejaVu Sans or any .ttf under /usr/share/fonts)")?,
    };
    let bytes = std::fs::read(&path).map_err(|e| format!("font {}: {e}", path.display()))?;
    // plotters keeps fonts for the process's life (`&'static`); one font per command run.
    let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
    plotters::style::register_font(FONT_FAMILY, FontStyle::Normal, bytes).map_err(|_| format!("font {}: not a TrueType or OpenType font", path.display()))?;
    Ok(path)
}

type Area<'a> = DrawingArea<BitMapBackend<'a>, Shift>;

fn err<E: std::fmt::Display>(e: E) -> String {
    format!("drawing the plot: {e}")
}

/// Labels for the change lines, placed in the first of a few rows where they do not overlap the
/// previous label of that row; a label that fits nowhere is left out (its line stays).
struct Labels {
    /// Right end (pixels) of the last label per row.
    rows: Vec<i32>,
}

impl Labels {
    fn place(&mut self, x: i32, width: i32) -> Option<usize> {
        let row = self.rows.iter().position(|end| x > *end + 4)?;
        self.rows[row] = x + width;
        Some(row)
    }
}

/// One line of a panel: its legend, colour and runs of points (`series::runs`).
struct Line<'s> {
    name: &'s str,
    color: RGBColor,
    runs: Vec<Vec<(f64, f64)>>,
}

/// A panel of lines over the run's time.
struct Panel<'s> {
    y_desc: String,
    top: f64,
    lines: Vec<Line<'s>>,
    x_desc: bool,
    legend: bool,
    /// Per-phase means drawn as level segments with their value (the GPU panel's).
    means: Vec<series::Phase>,
}

/// Draws one panel; returns the pixel x of each change line (for their labels) and the top left
/// corner of the panel's plotting area.
fn panel(area: &Area, s: &Series, p: Panel, text: bool) -> Result<(Vec<i32>, (i32, i32)), String> {
    let x_end = s.duration().max(1e-3);
    // A legend goes in one row above the plotting area, where it hides no data.
    let legend = p.legend && text;
    let mut chart = ChartBuilder::on(area)
        .margin_right(20)
        .margin_top(if legend { 24 } else { 8 })
        .x_label_area_size(if !text { 4 } else if p.x_desc { 40 } else { 22 })
        .y_label_area_size(if text { 70 } else { 4 })
        .build_cartesian_2d(0.0..x_end, 0.0..p.top)
        .map_err(err)?;
    let mut mesh = chart.configure_mesh();
    // Only the labelled grid lines: plotters' finer ones crowd a plot this wide.
    mesh.light_line_style(TRANSPARENT).bold_line_style(GRID).axis_style(BLACK);
    if text {
        mesh.label_style((FONT_FAMILY, 13)).axis_desc_style((FONT_FAMILY, 14)).y_desc(p.y_desc.as_str()).x_labels(12).y_labels(5);
        if p.x_desc {
            mesh.x_desc("seconds since the first frame");
        }
    } else {
        // No font: any text would fail to draw.
        mesh.x_labels(0).y_labels(0);
    }
    mesh.draw().map_err(err)?;

    let xs: Vec<i32> = s.changes.iter().map(|c| chart.backend_coord(&(c.x, 0.0)).0).collect();
    for c in &s.changes {
        chart.draw_series(std::iter::once(PathElement::new(vec![(c.x, 0.0), (c.x, p.top)], CHANGE_COLOR.stroke_width(1)))).map_err(err)?;
    }
    // Under the frames' lines, which stay visible where a phase is flat.
    for m in &p.means {
        let Some(mean) = m.gpu_ms else { continue };
        chart.draw_series(std::iter::once(PathElement::new(vec![(m.from, mean), (m.to, mean)], MEAN_COLOR.stroke_width(2)))).map_err(err)?;
        if text {
            let label = EmptyElement::at((m.from, mean)) + Text::new(format!("mean {mean:.1} ms"), (4, -16), (FONT_FAMILY, 13).into_font().color(&MEAN_COLOR));
            chart.draw_series(std::iter::once(label)).map_err(err)?;
        }
    }
    for line in &p.lines {
        for run in &line.runs {
            chart.draw_series(LineSeries::new(run.iter().copied(), line.color.stroke_width(1))).map_err(err)?;
        }
    }
    if legend {
        let (left, _) = chart.backend_coord(&(0.0, p.top));
        let (mut x, y) = (left - area.get_base_pixel().0, 10);
        let style = (FONT_FAMILY, 13).into_font().color(&BLACK);
        for line in &p.lines {
            area.draw(&PathElement::new(vec![(x, y), (x + 18, y)], line.color.stroke_width(3))).map_err(err)?;
            area.draw(&Text::new(line.name, (x + 24, y - 7), style.clone())).map_err(err)?;
            x += 24 + area.estimate_text_size(line.name, &style).map_err(err)?.0 as i32 + 22;
        }
    }
    Ok((xs, chart.backend_coord(&(0.0, p.top))))
}

/// The three panels' lines: GPU time (ms), pixels saved (in a unit that suits their size) and
/// passes per frame.
fn panels(s: &Series) -> [Panel<'static>; 3] {
    let some = |v: &[f64]| v.iter().map(|y| Some(*y)).collect::<Vec<_>>();
    let gpu_max = s.gpu_ms.iter().flatten().copied().fold(0.0, f64::max);
    let px_max = s.pixels.iter().flatten().copied().fold(0.0, f64::max);
    let (div, unit) = series::pixel_unit(px_max);
    let pass_max = s.passes.iter().flatten().copied().fold(0.0, f64::max);
    let scaled = |v: &[f64]| v.iter().map(|y| Some(y / div)).collect::<Vec<_>>();
    [
        Panel {
            y_desc: "GPU busy, ms/frame".into(),
            top: series::axis_top(gpu_max),
            lines: vec![Line { name: "GPU busy (stats.gpu_time)", color: GPU_COLOR, runs: series::runs(&s.x, &s.gpu_ms) }],
            x_desc: false,
            legend: false,
            means: s.phases(),
        },
        Panel {
            y_desc: format!("saved, {unit}/frame"),
            top: series::axis_top(px_max / div),
            lines: series::PIXEL_LINES.iter().zip(PIXEL_COLORS).zip(&s.pixels).map(|((name, color), v)| Line { name, color, runs: series::runs(&s.x, &scaled(v)) }).collect(),
            x_desc: false,
            legend: true,
            means: Vec::new(),
        },
        Panel {
            y_desc: "passes/frame".into(),
            top: series::axis_top(pass_max),
            lines: series::PASS_LINES.iter().zip(PASS_COLORS).zip(&s.passes).map(|((name, color), v)| Line { name, color, runs: series::runs(&s.x, &some(v)) }).collect(),
            x_desc: true,
            legend: true,
            means: Vec::new(),
        },
    ]
}

fn draw(root: &Area, s: &Series, o: &Options, text: bool) -> Result<(), String> {
    root.fill(&WHITE).map_err(err)?;
    let (w, h) = (o.width as i32, o.height as i32);
    let title_h = if text { 34 } else { 6 };
    let (title, body) = root.split_vertically(title_h);
    // GPU time gets the most room: it is what the features are for.
    let gpu_h = title_h + (h - title_h) * 42 / 100;
    let pixels_h = gpu_h + (h - title_h) * 31 / 100;
    let areas = body.split_by_breakpoints([] as [i32; 0], [gpu_h - title_h, pixels_h - title_h]);
    let [gpu, pixels, passes] = panels(s);
    let has_gpu = s.gpu_ms.iter().any(Option::is_some);
    let (change_xs, (gpu_left, gpu_top)) = panel(&areas[0], s, gpu, text)?;
    panel(&areas[1], s, pixels, text)?;
    panel(&areas[2], s, passes, text)?;
    if !text {
        return Ok(());
    }

    let fps = if s.duration() > 0.0 { format!(", {:.1} frames/s", (s.len() - 1) as f64 / s.duration()) } else { String::new() };
    let caption = format!("{}: {} frames over {:.1} s{fps}, {} setting change(s)", o.title, s.len(), s.duration(), s.changes.len());
    title.draw(&Text::new(caption, (12, 8), (FONT_FAMILY, 20).into_font().color(&BLACK))).map_err(err)?;
    if !has_gpu {
        let note = "no GPU time in this file (stats.gpu_time = true records it)";
        areas[0].draw(&Text::new(note, (w / 2 - 200, (gpu_h - title_h) / 2), (FONT_FAMILY, 15).into_font().color(&RGBColor(110, 110, 110)))).map_err(err)?;
    }
    // The change labels, in the GPU panel just under its top, beside their lines.
    let style = (FONT_FAMILY, 13).into_font().color(&CHANGE_COLOR);
    let mut labels = Labels { rows: vec![i32::MIN / 2; 3] };
    let start = if s.start_on.is_empty() { "start: all off".to_string() } else { format!("start: {} on", s.start_on.join(", ")) };
    let mut placed = vec![(gpu_left + 3, start)];
    placed.extend(s.changes.iter().zip(&change_xs).map(|(c, x)| (*x + 3, c.label.clone())));
    for (x, label) in placed {
        let (lw, lh) = root.estimate_text_size(&label, &style).map_err(err)?;
        if x + lw as i32 > w {
            // Past the right edge: left of the line instead, when that fits in the row.
            if let Some(row) = labels.place(x - 6 - lw as i32, lw as i32) {
                root.draw(&Text::new(label, (x - 6 - lw as i32, gpu_top + 4 + row as i32 * (lh as i32 + 3)), style.clone())).map_err(err)?;
            }
        } else if let Some(row) = labels.place(x, lw as i32) {
            root.draw(&Text::new(label, (x, gpu_top + 4 + row as i32 * (lh as i32 + 3)), style.clone())).map_err(err)?;
        }
    }
    Ok(())
}

/// Draws the series into `out` as a PNG. Text needs a font file (`Options::font`, else one found
/// on the system): without one the plot is drawn without text, and the returned note says why.
pub fn write(s: &Series, o: &Options, out: &Path) -> Result<Option<String>, String> {
    if s.is_empty() {
        return Err("no frames to plot".into());
    }
    let font = load_font(o.font.as_deref());
    let text = font.is_ok();
    let mut rgb = vec![0u8; o.width as usize * o.height as usize * 3];
    {
        let root = BitMapBackend::with_buffer(&mut rgb, (o.width, o.height)).into_drawing_area();
        draw(&root, s, o, text)?;
        root.present().map_err(err)?;
    }
    let file = std::fs::File::create(out).map_err(|e| format!("{}: {e}", out.display()))?;
    let mut enc = png::Encoder::new(std::io::BufWriter::new(file), o.width, o.height);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    let mut w = enc.write_header().map_err(|e| format!("{}: {e}", out.display()))?;
    w.write_image_data(&rgb).map_err(|e| format!("{}: {e}", out.display()))?;
    w.finish().map_err(|e| format!("{}: {e}", out.display()))?;
    Ok(font.err().map(|why| format!("{why}; the plot is drawn without text")))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes() {
        assert_eq!(parse_size("1280x720"), Ok((1280, 720)));
        assert_eq!(parse_size("640X480"), Ok((640, 480)));
        assert!(parse_size("1280").unwrap_err().contains("WIDTHxHEIGHT"));
        assert!(parse_size("100x720").unwrap_err().contains("200 to 8000"));
    }

    #[test]
    fn labels_take_the_first_free_row() {
        let mut l = Labels { rows: vec![i32::MIN / 2; 2] };
        assert_eq!(l.place(10, 50), Some(0));
        assert_eq!(l.place(30, 50), Some(1), "overlaps row 0's label");
        assert_eq!(l.place(40, 50), None, "no row free");
        assert_eq!(l.place(70, 50), Some(0));
    }
}
