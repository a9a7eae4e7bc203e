//! PNG scatter plots of a particle snapshot projected on a coordinate plane, drawn with
//! `plotters` (bitmap backend, text through `ab_glyph` with a font bundled in a crate, so no
//! system font is needed).
use std::path::Path;
use std::sync::OnceLock;

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::{register_font, FontStyle};

use super::vtk::check_lengths;
use crate::sim::ParticleSnapshot;

/// The projection plane of a PNG: horizontal axis first.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum View {
    /// x right, y up: the plane of 2D scenes, or a 3D scene seen from +z.
    XY,
    /// x right, z up: a 3D scene seen from -y.
    XZ,
    /// y right, z up: a 3D scene seen from +x.
    YZ,
}

impl View {
    /// Indices of the horizontal and vertical coordinates.
    pub fn axes(self) -> (usize, usize) {
        match self {
            View::XY => (0, 1),
            View::XZ => (0, 2),
            View::YZ => (1, 2),
        }
    }
    fn names(self) -> (&'static str, &'static str) {
        match self {
            View::XY => ("x", "y"),
            View::XZ => ("x", "z"),
            View::YZ => ("y", "z"),
        }
    }
}

impl std::str::FromStr for View {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s.to_ascii_lowercase().as_str() {
            "xy" => Ok(View::XY),
            "xz" => Ok(View::XZ),
            "yz" => Ok(View::YZ),
            _ => Err(format!("unknown view `{s}` (expected xy, xz or yz)")),
        }
    }
}

/// Largest plotting area (pixels) and the smallest side it may have.
const MAX_PLOT: (f64, f64) = (900.0, 700.0);
const MIN_PLOT_SIDE: f64 = 240.0;
const MARGIN: u32 = 20;
const X_LABEL_AREA: u32 = 55;
const Y_LABEL_AREA: u32 = 85;
const LEGEND_W: u32 = 190;
const TITLE_H: u32 = 44;
const FONT: &str = "sans-serif";

/// Body colours (a colour-blind friendly set), cycled by body index.
const BODY_COLOURS: [RGBColor; 8] = [
    RGBColor(86, 180, 233),
    RGBColor(230, 159, 0),
    RGBColor(0, 158, 115),
    RGBColor(204, 121, 167),
    RGBColor(240, 228, 66),
    RGBColor(0, 114, 178),
    RGBColor(153, 153, 153),
    RGBColor(120, 94, 240),
];
const BROKEN: RGBColor = RGBColor(220, 20, 30);

fn body_colour(body: u32) -> RGBColor {
    BODY_COLOURS[body as usize % BODY_COLOURS.len()]
}

/// The body colour darkened: surface particles.
fn surface_colour(body: u32) -> RGBColor {
    let RGBColor(r, g, b) = body_colour(body);
    let d = |c: u8| (f64::from(c) * 0.45) as u8;
    RGBColor(d(r), d(g), d(b))
}

/// Registers the bundled font with plotters once per process.
fn ensure_font() -> Result<(), String> {
    static FONT_OK: OnceLock<Result<(), String>> = OnceLock::new();
    FONT_OK
        .get_or_init(|| {
            register_font(FONT, FontStyle::Normal, epaint_default_fonts::HACK_REGULAR)
                .map_err(|_| "the bundled font failed to load".to_string())
        })
        .clone()
}

/// Median nearest-neighbour distance (3D) over a sample of at most 256 particles: the particle
/// spacing, for the marker size. 0 with fewer than two distinct positions.
fn spacing(pos: &[[f64; 3]]) -> f64 {
    let n = pos.len();
    let stride = n.div_ceil(256).max(1);
    let mut nn: Vec<f64> = (0..n)
        .step_by(stride)
        .filter_map(|i| {
            let p = pos[i];
            pos.iter()
                .map(|q| (0..3).map(|k| (q[k] - p[k]).powi(2)).sum::<f64>())
                .filter(|&d2| d2 > 0.0)
                .min_by(f64::total_cmp)
        })
        .map(f64::sqrt)
        .collect();
    if nn.is_empty() {
        return 0.0;
    }
    nn.sort_by(f64::total_cmp);
    nn[nn.len() / 2]
}

/// Decimals for tick labels on an axis spanning `span`.
fn decimals(span: f64) -> usize {
    if span > 0.0 && span.is_finite() {
        (-(span / 8.0).log10()).ceil().clamp(0.0, 8.0) as usize
    } else {
        2
    }
}

fn fmt_time(t: f64) -> String {
    if t == 0.0 || (t.abs() >= 1e-3 && t.abs() < 1e5) {
        format!("{t:.6}")
    } else {
        format!("{t:.4e}")
    }
}

/// Writes a scatter plot of `snap` projected on `view` to `path` (PNG): particles coloured by
/// body, surface particles in a darker shade of their body's colour, particles with broken bonds
/// in red (drawn last, on top); equal scales on both axes (m), the time in the title, a legend
/// to the right of the plot.
pub fn write_png(path: &Path, snap: &ParticleSnapshot, view: View) -> Result<(), String> {
    check_lengths(snap)?;
    ensure_font()?;
    let (h, v) = view.axes();
    let pts: Vec<(f64, f64)> = snap.position.iter().map(|p| (p[h], p[v])).collect();

    // Data bounds, padded by a particle spacing so markers at the edge stay inside.
    let dp = spacing(&snap.position);
    let bounds = |f: fn(&(f64, f64)) -> f64| {
        let (lo, hi) = pts
            .iter()
            .map(f)
            .filter(|x| x.is_finite())
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), x| {
                (lo.min(x), hi.max(x))
            });
        if lo > hi {
            (-0.5, 0.5)
        } else {
            (lo, hi)
        }
    };
    let (x0, x1) = bounds(|p| p.0);
    let (y0, y1) = bounds(|p| p.1);
    let pad = dp.max(0.02 * (x1 - x0).max(y1 - y0)).max(1e-9);
    let (x0, x1, y0, y1) = (x0 - pad, x1 + pad, y0 - pad, y1 + pad);
    let (dx, dy) = (x1 - x0, y1 - y0);

    // Plot area of the data's aspect within MAX_PLOT, each side at least MIN_PLOT_SIDE.
    let scale = (MAX_PLOT.0 / dx).min(MAX_PLOT.1 / dy);
    let pw = (dx * scale).max(MIN_PLOT_SIDE).round() as u32;
    let ph = (dy * scale).max(MIN_PLOT_SIDE).round() as u32;
    let width = pw + Y_LABEL_AREA + 2 * MARGIN + LEGEND_W;
    let height = ph + X_LABEL_AREA + 2 * MARGIN + TITLE_H;

    let (hn, vn) = view.names();
    let title = format!(
        "t = {} s  ({}{} view, {} particles)",
        fmt_time(snap.time),
        hn.to_uppercase(),
        vn.to_uppercase(),
        pts.len()
    );
    // The monospace font's advance is 0.6 em: shrink the title to fit the width.
    let title_size = (f64::from(width) / (0.6 * title.len() as f64 + 2.0)).min(24.0);
    let err = |e: &dyn std::fmt::Display| format!("drawing {}: {e}", path.display());

    let root = BitMapBackend::new(path, (width, height)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let body_area = root
        .titled(&title, (FONT, title_size).into_font().color(&BLACK))
        .map_err(|e| err(&e))?;
    let (aw, ah) = body_area.dim_in_pixel();
    let (plot_area, legend_area) = body_area.split_horizontally(aw.saturating_sub(LEGEND_W));

    // The plotting rectangle that ChartBuilder will leave, and ranges widened so that one metre
    // is the same number of pixels on both axes.
    let real_w = f64::from((aw.saturating_sub(LEGEND_W + Y_LABEL_AREA + 2 * MARGIN)).max(1));
    let real_h = f64::from((ah.saturating_sub(X_LABEL_AREA + 2 * MARGIN)).max(1));
    let s = (real_w / dx).min(real_h / dy);
    let (cx, cy) = (0.5 * (x0 + x1), 0.5 * (y0 + y1));
    let (hx, hy) = (0.5 * real_w / s, 0.5 * real_h / s);
    let (x0, x1, y0, y1) = (cx - hx, cx + hx, cy - hy, cy + hy);

    let mut chart = ChartBuilder::on(&plot_area)
        .margin(MARGIN)
        .x_label_area_size(X_LABEL_AREA)
        .y_label_area_size(Y_LABEL_AREA)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(|e| err(&e))?;
    let (xd, yd) = (decimals(x1 - x0), decimals(y1 - y0));
    // Snap round-off around zero, so that no tick reads "-0.00".
    let tick = |v: f64, span: f64, d: usize| {
        let v = if v.abs() < 1e-9 * span { 0.0 } else { v };
        format!("{v:.d$}")
    };
    let x_fmt = |x: &f64| tick(*x, x1 - x0, xd);
    let y_fmt = |y: &f64| tick(*y, y1 - y0, yd);
    // Roughly one tick label per 80 px across, per 60 px up.
    let x_ticks = ((real_w / 80.0) as usize).clamp(3, 10);
    let y_ticks = ((real_h / 60.0) as usize).clamp(3, 12);
    chart
        .configure_mesh()
        .x_desc(format!("{hn} [m]"))
        .y_desc(format!("{vn} [m]"))
        .x_labels(x_ticks)
        .y_labels(y_ticks)
        .x_label_formatter(&x_fmt)
        .y_label_formatter(&y_fmt)
        .label_style((FONT, 16))
        .axis_desc_style((FONT, 18))
        .light_line_style(RGBColor(240, 240, 240))
        .bold_line_style(RGBColor(215, 215, 215))
        .draw()
        .map_err(|e| err(&e))?;

    let r = (0.4 * dp * s).round().clamp(1.0, 12.0) as i32;
    let r = if dp > 0.0 { r } else { 3 };
    let marker = |i: usize, colour: RGBColor| Circle::new(pts[i], r, colour.filled());
    let broken = |i: usize| snap.broken_bonds[i] > 0;
    let interior = (0..pts.len()).filter(|&i| !snap.surface[i] && !broken(i));
    chart
        .draw_series(interior.map(|i| marker(i, body_colour(snap.body[i]))))
        .map_err(|e| err(&e))?;
    let surface = (0..pts.len()).filter(|&i| snap.surface[i] && !broken(i));
    chart
        .draw_series(surface.map(|i| marker(i, surface_colour(snap.body[i]))))
        .map_err(|e| err(&e))?;
    chart
        .draw_series(
            (0..pts.len())
                .filter(|&i| broken(i))
                .map(|i| marker(i, BROKEN)),
        )
        .map_err(|e| err(&e))?;

    draw_legend(&legend_area, snap).map_err(|e| err(&e))?;
    root.present().map_err(|e| err(&e))
}

/// The legend panel: one entry per body present, then surface and broken-bond markers.
fn draw_legend<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    snap: &ParticleSnapshot,
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    let mut bodies: Vec<u32> = snap.body.clone();
    bodies.sort_unstable();
    bodies.dedup();
    let count = |f: &dyn Fn(usize) -> bool| (0..snap.body.len()).filter(|&i| f(i)).count();
    let mut entries: Vec<(RGBColor, String)> = bodies
        .iter()
        .take(12)
        .map(|&b| {
            let n = count(&|i| snap.body[i] == b);
            (body_colour(b), format!("body {b} ({n})"))
        })
        .collect();
    let first = bodies.first().copied().unwrap_or(0);
    let n_surf = count(&|i| snap.surface[i]);
    entries.push((surface_colour(first), format!("surface ({n_surf})")));
    let n_broken = count(&|i| snap.broken_bonds[i] > 0);
    entries.push((BROKEN, format!("broken bonds ({n_broken})")));
    let style = (FONT, 16).into_font().color(&BLACK);
    for (k, (colour, label)) in entries.into_iter().enumerate() {
        let y = MARGIN as i32 + 10 + 26 * k as i32;
        area.draw(
            &(EmptyElement::at((12, y))
                + Circle::new((0, 0), 6, colour.filled())
                + Text::new(label, (14, -9), style.clone())),
        )?;
    }
    Ok(())
}
