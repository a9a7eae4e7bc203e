//! PNG pictures of particle snapshots drawn with `plotters` (bitmap backend, text through
//! `ab_glyph` with a font bundled in a crate, so no system font is needed): scatter plots
//! projected on a coordinate plane ([`write_png`]), and 3D views, an oblique projection drawn
//! back to front with shading, alone ([`write_png_3d`]) or in a grid of panels
//! ([`write_grid_png_3d`], the paper's Figure 9).
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
/// Registers the bundled font for plotters (once); every PNG writer calls it first.
pub fn ensure_font() -> Result<(), String> {
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
    // A particle's marker shows its volume (bodies filled from shapes): its radius scales as
    // the side of a cell of that volume.
    let d = if snap.position.iter().all(|p| p[2] == 0.0) {
        2
    } else {
        3
    };
    let cell = dp.powi(d);
    let radius = |i: usize| match snap.volume.get(i) {
        Some(&v) if v > 0.0 && cell > 0.0 => {
            ((f64::from(r) * (v / cell).powf(1.0 / f64::from(d))).round() as i32).max(1)
        }
        _ => r,
    };
    let marker = |i: usize, colour: RGBColor| Circle::new(pts[i], radius(i), colour.filled());
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

// ---------------------------------------------------------------------------------------------
// 3D views (the paper's Figure 9): an orthographic oblique projection of the particles, drawn
// back to front, shaded by a light on their normals and by depth, coloured by body, particles
// that lost bonds in red; written as indexed-colour PNGs.

/// The direction a 3D view looks from (orthographic, z up): the camera sits `azimuth_deg` from
/// -y towards +x and `elevation_deg` above the x-y plane. The default (30, 25) sees case 3's
/// block from behind its hit face (-y), x to the right as in the XZ view, with its right face
/// and its top; the cube, in front of the block (+y), shows above and to the right of it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    pub azimuth_deg: f64,
    pub elevation_deg: f64,
}

impl Default for Camera {
    fn default() -> Self {
        Camera {
            azimuth_deg: 30.0,
            elevation_deg: 25.0,
        }
    }
}

impl Camera {
    fn check(&self) -> Result<(), String> {
        if self.azimuth_deg.is_finite()
            && self.elevation_deg.is_finite()
            && self.elevation_deg.abs() < 90.0
        {
            Ok(())
        } else {
            Err(format!(
                "camera azimuth {} and elevation {} (degrees) must be finite with |elevation| < 90",
                self.azimuth_deg, self.elevation_deg
            ))
        }
    }

    /// Unit vectors of the view: screen right, screen up, and towards the camera (a
    /// right-handed frame: right x up = towards the camera).
    pub fn basis(&self) -> [[f64; 3]; 3] {
        let (sa, ca) = self.azimuth_deg.to_radians().sin_cos();
        let (se, ce) = self.elevation_deg.to_radians().sin_cos();
        [
            [ca, sa, 0.0],
            [-sa * se, ca * se, ce],
            [sa * ce, -ca * ce, se],
        ]
    }

    /// A point (m) in view coordinates: (right, up, depth), depth growing towards the camera.
    pub fn project(&self, p: [f64; 3]) -> [f64; 3] {
        let b = self.basis();
        let dot = |a: [f64; 3]| a[0] * p[0] + a[1] * p[1] + a[2] * p[2];
        [dot(b[0]), dot(b[1]), dot(b[2])]
    }
}

/// The framing of one or more 3D panels: the projected box holding every particle of the
/// snapshots it was fitted to (padded by a particle spacing), their depth range (for the
/// shading) and the particle spacing (for the marker size). Panels drawn with one frame share
/// position, scale and shading, so they compare directly.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame3d {
    pub camera: Camera,
    /// Screen-right range (m).
    pub right: [f64; 2],
    /// Screen-up range (m).
    pub up: [f64; 2],
    /// Depth range (m), towards the camera.
    pub depth: [f64; 2],
    /// Particle spacing (m).
    pub spacing: f64,
    /// Only the particles inside this box (min, max corners, m) are framed and drawn (a detail
    /// view); `None`: all.
    pub clip: Option<([f64; 3], [f64; 3])>,
    /// Particles seen outside the frame are left out (and counted in the panel's title) instead
    /// of being an error: frames of [`Frame3d::fit_bulk`], which leave out pieces that fly off.
    pub skip_outside: bool,
}

fn inside(clip: &Option<([f64; 3], [f64; 3])>, p: &[f64; 3]) -> bool {
    clip.as_ref()
        .is_none_or(|(lo, hi)| (0..3).all(|k| p[k] >= lo[k] && p[k] <= hi[k]))
}

/// Checks the arrays of a snapshot for a 3D view: equal lengths, at least one particle, finite
/// positions.
fn check_3d(snap: &ParticleSnapshot) -> Result<(), String> {
    let n = check_lengths(snap)?;
    if n == 0 {
        return Err(format!(
            "the snapshot at t = {} s has no particles: nothing to draw",
            snap.time
        ));
    }
    if !snap.time.is_finite() {
        return Err(format!("snapshot time {} is not finite", snap.time));
    }
    if let Some(i) = snap
        .position
        .iter()
        .position(|p| p.iter().any(|c| !c.is_finite()))
    {
        return Err(format!(
            "particle {i} of the snapshot at t = {} s has a non-finite position {:?}",
            snap.time, snap.position[i]
        ));
    }
    Ok(())
}

impl Frame3d {
    /// The frame that holds every particle of `snaps` seen by `camera`. Errors: no snapshot, a
    /// snapshot without particles, mismatched arrays, a non-finite position.
    pub fn fit(camera: Camera, snaps: &[&ParticleSnapshot]) -> Result<Self, String> {
        Self::fit_clipped(camera, snaps, None)
    }

    /// The frame of the particles of `snaps` inside the box `clip` (min, max corners, m), which
    /// are then the only ones drawn. Errors as [`Frame3d::fit`], and a box with no particle.
    pub fn fit_clipped(
        camera: Camera,
        snaps: &[&ParticleSnapshot],
        clip: Option<([f64; 3], [f64; 3])>,
    ) -> Result<Self, String> {
        camera.check()?;
        if let Some((lo, hi)) = &clip {
            if !(0..3).all(|k| lo[k].is_finite() && hi[k].is_finite() && lo[k] < hi[k]) {
                return Err(format!(
                    "the detail box {lo:?} - {hi:?} must be finite with min < max"
                ));
            }
        }
        if snaps.is_empty() {
            return Err("no snapshot to frame".into());
        }
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for s in snaps {
            check_3d(s)?;
            for p in s.position.iter().filter(|p| inside(&clip, p)) {
                let q = camera.project(*p);
                for k in 0..3 {
                    lo[k] = lo[k].min(q[k]);
                    hi[k] = hi[k].max(q[k]);
                }
            }
        }
        if lo[0] > hi[0] {
            return Err(format!(
                "no particle inside the detail box {:?}",
                clip.map(|c| [c.0, c.1])
            ));
        }
        let dp = spacing(&snaps[0].position);
        let span = (hi[0] - lo[0]).max(hi[1] - lo[1]);
        let pad = if dp > 0.0 { dp } else { 0.05 * span.max(1.0) };
        Ok(Frame3d {
            camera,
            right: [lo[0] - pad, hi[0] + pad],
            up: [lo[1] - pad, hi[1] + pad],
            depth: [lo[2], hi[2]],
            spacing: if dp > 0.0 { dp } else { pad },
            clip,
            skip_outside: false,
        })
    }

    /// The frame of the bulk of `snaps`: of the particles with at least `BULK_NEIGHBOURS`
    /// others within 1.6 spacings, so that single particles and small pieces thrown far away
    /// by fracture do not shrink the bodies to dots; particles outside it are left out of the
    /// pictures and counted in their titles. Errors as [`Frame3d::fit`].
    pub fn fit_bulk(camera: Camera, snaps: &[&ParticleSnapshot]) -> Result<Self, String> {
        let mut frame = Self::fit(camera, snaps)?;
        let h = 1.6 * frame.spacing;
        let bulk: Vec<ParticleSnapshot> = snaps
            .iter()
            .map(|s| {
                let mut n = vec![0usize; s.position.len()];
                for_each_neighbour(&s.position, h, |i, _, _| n[i] += 1);
                let keep: Vec<usize> = (0..n.len()).filter(|&i| n[i] >= BULK_NEIGHBOURS).collect();
                let pick = |v: &[[f64; 3]]| keep.iter().map(|&i| v[i]).collect::<Vec<_>>();
                ParticleSnapshot {
                    time: s.time,
                    body: keep.iter().map(|&i| s.body[i]).collect(),
                    position: pick(&s.position),
                    displacement: pick(&s.displacement),
                    velocity: pick(&s.velocity),
                    surface: keep.iter().map(|&i| s.surface[i]).collect(),
                    broken_bonds: keep.iter().map(|&i| s.broken_bonds[i]).collect(),
                    fixed: Vec::new(),
                    volume: Vec::new(),
                    normal: Vec::new(),
                    area: Vec::new(),
                }
            })
            .filter(|s| !s.position.is_empty())
            .collect();
        if !bulk.is_empty() {
            let refs: Vec<&ParticleSnapshot> = bulk.iter().collect();
            let spacing = frame.spacing;
            frame = Self::fit(camera, &refs)?;
            frame.spacing = spacing;
        }
        frame.skip_outside = true;
        Ok(frame)
    }

    /// Whether a point in view coordinates is inside the frame.
    fn holds(&self, q: [f64; 3]) -> bool {
        let tol = 1e-9 * (self.width() + self.height());
        q[0] >= self.right[0] - tol
            && q[0] <= self.right[1] + tol
            && q[1] >= self.up[0] - tol
            && q[1] <= self.up[1] + tol
    }

    /// Particles of `snap` (inside the clip box) that the frame leaves out.
    fn left_out(&self, snap: &ParticleSnapshot) -> usize {
        snap.position
            .iter()
            .filter(|p| inside(&self.clip, p) && !self.holds(self.camera.project(**p)))
            .count()
    }

    fn width(&self) -> f64 {
        self.right[1] - self.right[0]
    }
    fn height(&self) -> f64 {
        self.up[1] - self.up[0]
    }
    /// Pixels per metre that fit the frame into `w` x `h` pixels.
    fn scale_into(&self, w: f64, h: f64) -> f64 {
        (w / self.width()).min(h / self.height())
    }
}

/// Titles and names of a 3D panel.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Label3d {
    /// Body names, by body index (legend and colours: `cube` salmon and `block` blue as in the
    /// paper's Figure 9, other names from a palette).
    pub body_names: Vec<String>,
    /// The variant shown (title; empty for none), e.g. "with fractured-surface contact".
    pub variant: String,
    /// A further title line, e.g. the paper's event at this instant, or where the run stopped.
    pub note: Option<String>,
}

/// Where a 3D panel landed in its image.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PanelGeometry {
    /// The plot rectangle (pixels): left, top, right, bottom (exclusive).
    pub plot: [i32; 4],
    /// Pixels per metre.
    pub scale: f64,
    /// Marker radius (pixels).
    pub radius: i32,
    frame: Frame3d,
}

impl PanelGeometry {
    /// The pixel (column, row) at which a point (m) is drawn.
    pub fn pixel(&self, p: [f64; 3]) -> (i32, i32) {
        let q = self.frame.camera.project(p);
        (
            self.plot[0] + ((q[0] - self.frame.right[0]) * self.scale).round() as i32,
            self.plot[1] + ((self.frame.up[1] - q[1]) * self.scale).round() as i32,
        )
    }
}

/// A written 3D image: its size (pixels) and its panels, row by row.
#[derive(Clone, Debug, PartialEq)]
pub struct Image3d {
    pub size: (u32, u32),
    pub panels: Vec<PanelGeometry>,
}

/// Body colours of the paper's Figure 9.
pub const SALMON: RGBColor = RGBColor(250, 128, 114);
pub const BLOCK_BLUE: RGBColor = RGBColor(72, 125, 205);
/// Particles that lost bonds: (fewest lost bonds of the class, colour), darker with more.
pub const BROKEN_CLASSES: [(u32, RGBColor); 4] = [
    (1, RGBColor(255, 45, 35)),
    (3, RGBColor(205, 0, 15)),
    (6, RGBColor(150, 0, 10)),
    (10, RGBColor(90, 0, 5)),
];
/// Shading: a light from slightly above left of the camera (view coordinates right, up, towards the
/// camera) on each particle's outward normal, times a depth cue (the farthest particle at
/// `FAR_SHADE` of the lit colour), in `SHADES` steps (few colours keep the PNGs small).
const LIGHT: [f64; 3] = [-0.25, 0.2, 0.95];
const AMBIENT: f64 = 0.4;
const FAR_SHADE: f64 = 0.75;
/// Neighbours within 1.6 spacings that make a particle part of the bulk ([`Frame3d::fit_bulk`]).
const BULK_NEIGHBOURS: usize = 4;
const SHADES: f64 = 16.0;

/// Outward normals (unit, world axes) of the particles from their current neighbourhood: minus
/// the weighted sum of the offsets to the neighbours within 1.6 spacings. `None` inside a body
/// (the sum cancels), where no light direction is defined.
fn normals(pos: &[[f64; 3]], dp: f64) -> Vec<Option<[f64; 3]>> {
    let mut sum = vec![[0.0; 3]; pos.len()];
    for_each_neighbour(pos, 1.6 * dp, |i, d, w| {
        for k in 0..3 {
            sum[i][k] -= w * d[k];
        }
    });
    sum.into_iter()
        .map(|s| {
            let n = (s[0] * s[0] + s[1] * s[1] + s[2] * s[2]).sqrt();
            (n > 0.4 * dp).then(|| s.map(|x| x / n))
        })
        .collect()
}

/// Calls `f(i, x_j - x_i, 1 - r / h)` for every ordered pair of particles closer than `h`
/// (a cell grid of side h). Nothing for h <= 0 or NaN.
fn for_each_neighbour(pos: &[[f64; 3]], h: f64, mut f: impl FnMut(usize, [f64; 3], f64)) {
    if h.is_nan() || h <= 0.0 {
        return;
    }
    let cell = |p: &[f64; 3]| -> [i64; 3] { [0, 1, 2].map(|k| (p[k] / h).floor() as i64) };
    let mut grid: std::collections::HashMap<[i64; 3], Vec<usize>> =
        std::collections::HashMap::new();
    for (i, p) in pos.iter().enumerate() {
        grid.entry(cell(p)).or_default().push(i);
    }
    for (i, p) in pos.iter().enumerate() {
        let c = cell(p);
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    let Some(list) = grid.get(&[c[0] + dx, c[1] + dy, c[2] + dz]) else {
                        continue;
                    };
                    for &j in list {
                        let d = [0, 1, 2].map(|k| pos[j][k] - p[k]);
                        let r = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                        if j != i && r < h {
                            f(i, d, 1.0 - r / h);
                        }
                    }
                }
            }
        }
    }
}

/// The brightness factor of a particle: lit by `LIGHT` on its normal (view coordinates), dimmed
/// with depth `t` (0 farthest, 1 nearest), quantised.
fn shade(normal_view: Option<[f64; 3]>, t: f64) -> f64 {
    let l = LIGHT;
    let ln = (l[0] * l[0] + l[1] * l[1] + l[2] * l[2]).sqrt();
    let lambert = normal_view.map_or(0.5, |n| {
        ((n[0] * l[0] + n[1] * l[1] + n[2] * l[2]) / ln).max(0.0)
    });
    let f = (1.12 * (AMBIENT + (1.0 - AMBIENT) * lambert)).min(1.0)
        * (FAR_SHADE + (1.0 - FAR_SHADE) * t);
    (f * SHADES).round() / SHADES
}

/// Particles held by a boundary (supports, clamps).
pub const FIXED_GREY: RGBColor = RGBColor(165, 165, 165);

fn body_colour_3d(names: &[String], body: u32) -> RGBColor {
    match names.get(body as usize).map(String::as_str) {
        Some("cube") => SALMON,
        Some("block") => BLOCK_BLUE,
        _ => body_colour(body),
    }
}

fn body_name(names: &[String], body: u32) -> String {
    names
        .get(body as usize)
        .cloned()
        .unwrap_or_else(|| format!("body {body}"))
}

/// The class of a particle that lost `k >= 1` bonds.
fn broken_class(k: u32) -> usize {
    BROKEN_CLASSES
        .iter()
        .rposition(|&(lo, _)| k >= lo)
        .unwrap_or(0)
}

fn broken_class_label(c: usize) -> String {
    let lo = BROKEN_CLASSES[c].0;
    match BROKEN_CLASSES.get(c + 1) {
        Some(&(next, _)) if next - 1 == lo => {
            format!("lost {lo} bond{}", if lo == 1 { "" } else { "s" })
        }
        Some(&(next, _)) => format!("lost {lo}-{} bonds", next - 1),
        None => format!("lost >= {lo} bonds"),
    }
}

fn scaled(c: RGBColor, f: f64) -> RGBColor {
    let m = |x: u8| (f64::from(x) * f).round().clamp(0.0, 255.0) as u8;
    RGBColor(m(c.0), m(c.1), m(c.2))
}

/// Broken bond pairs of a snapshot: each broken bond is counted at both its particles.
pub fn broken_pairs(snap: &ParticleSnapshot) -> u64 {
    snap.broken_bonds.iter().map(|&k| u64::from(k)).sum::<u64>() / 2
}

const PANEL_MARGIN: i32 = 14;
const LEGEND3D_W: u32 = 270;
const ROW_H: i32 = 24;

fn text_style(size: f64) -> TextStyle<'static> {
    (FONT, size).into_font().color(&BLACK)
}

/// The monospace font's advance is 0.6 em: the size that fits `text` into `width` pixels.
fn fit_size(text: &str, width: f64, max: f64) -> f64 {
    (width / (0.6 * text.chars().count().max(1) as f64)).min(max)
}

fn fmt_s(t: f64) -> String {
    if t.abs() >= 1e-3 || t == 0.0 {
        format!("{t:.3}")
    } else {
        format!("{t:.3e}")
    }
}

/// The panel's title lines: time, variant and broken bonds, then the note.
fn panel_title(snap: &ParticleSnapshot, label: &Label3d, frame: &Frame3d) -> Vec<String> {
    let pairs = broken_pairs(snap);
    let mut first = format!("t = {} s", fmt_s(snap.time));
    if !label.variant.is_empty() {
        first += &format!(", {}", label.variant);
    }
    first += &format!(", {pairs} broken bond{}", if pairs == 1 { "" } else { "s" });
    let mut lines = vec![first];
    lines.extend(
        label
            .note
            .iter()
            .flat_map(|n| n.lines().map(str::to_string)),
    );
    let out = frame.left_out(snap);
    if out > 0 {
        lines.push(format!(
            "{out} particle{} thrown out of the view, not drawn",
            if out == 1 { "" } else { "s" }
        ));
    }
    lines
}

/// Greedy word wrap to lines of at most `chars` characters (a longer word gets a line).
fn wrap(text: &str, chars: usize) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    let mut line = String::new();
    for word in text.split_whitespace() {
        if !line.is_empty() && line.chars().count() + 1 + word.chars().count() > chars {
            out.push(std::mem::take(&mut line));
        }
        if !line.is_empty() {
            line.push(' ');
        }
        line += word;
    }
    if !line.is_empty() || out.is_empty() {
        out.push(line);
    }
    out
}

/// The title lines of a panel laid out for `width` pixels, with their font sizes: the first
/// line at `first` (shrunk to fit), the notes wrapped at `note`.
fn title_layout(
    snap: &ParticleSnapshot,
    label: &Label3d,
    frame: &Frame3d,
    width: f64,
    first: f64,
    note: f64,
) -> Vec<(String, f64)> {
    let lines = panel_title(snap, label, frame);
    let chars = ((width / (0.6 * note)) as usize).max(8);
    let mut out = vec![(lines[0].clone(), fit_size(&lines[0], width, first))];
    for l in &lines[1..] {
        out.extend(wrap(l, chars).into_iter().map(|w| (w, note)));
    }
    out
}

type DrawResult = Result<(), String>;

fn derr(e: impl std::fmt::Display) -> String {
    e.to_string()
}

/// Draws the particles of `snap` (those inside the frame's clip box) centred in the pixel
/// rectangle `rect` (left, top, right, bottom) of `area`, framed by `frame`: back to front, lit
/// on their normals and dimmed with depth, held particles grey, particles that lost bonds in
/// the (unshaded) red of their class.
fn draw_particles<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    snap: &ParticleSnapshot,
    names: &[String],
    frame: &Frame3d,
    rect: [i32; 4],
) -> Result<PanelGeometry, String> {
    let (w, h) = (f64::from(rect[2] - rect[0]), f64::from(rect[3] - rect[1]));
    let s = frame.scale_into(w, h);
    if !(s.is_finite() && s > 0.0) {
        return Err(format!(
            "a 3D panel of {w} x {h} pixels cannot hold the frame"
        ));
    }
    let pw = (frame.width() * s).round() as i32;
    let ph = (frame.height() * s).round() as i32;
    let x0 = rect[0] + ((rect[2] - rect[0]) - pw) / 2;
    let y0 = rect[1] + ((rect[3] - rect[1]) - ph) / 2;
    let radius = (0.62 * frame.spacing * s).round().clamp(1.0, 20.0) as i32;
    let geom = PanelGeometry {
        plot: [x0, y0, x0 + pw, y0 + ph],
        scale: s,
        radius,
        frame: *frame,
    };
    let cam = frame.camera;
    let q: Vec<[f64; 3]> = snap.position.iter().map(|p| cam.project(*p)).collect();
    let mut order: Vec<usize> = (0..q.len())
        .filter(|&i| inside(&frame.clip, &snap.position[i]) && frame.holds(q[i]))
        .collect();
    order.sort_by(|&a, &b| q[a][2].total_cmp(&q[b][2]).then(a.cmp(&b)));
    let dspan = (frame.depth[1] - frame.depth[0]).max(1e-12);
    let normal = normals(&snap.position, frame.spacing);
    for i in order {
        let (px, py) = geom.pixel(snap.position[i]);
        let (fill, edge) = match snap.broken_bonds[i] {
            0 => {
                let t = ((q[i][2] - frame.depth[0]) / dspan).clamp(0.0, 1.0);
                let f = shade(normal[i].map(|n| cam.project(n)), t);
                let base = if snap.fixed.get(i).copied().unwrap_or(false) {
                    FIXED_GREY
                } else {
                    body_colour_3d(names, snap.body[i])
                };
                let c = scaled(base, f);
                (c, scaled(c, 0.7))
            }
            k => {
                let c = BROKEN_CLASSES[broken_class(k)].1;
                (c, scaled(c, 0.55))
            }
        };
        area.draw(&Circle::new((px, py), radius as u32, fill.filled()))
            .map_err(derr)?;
        if radius >= 3 {
            area.draw(&Circle::new((px, py), radius as u32, edge.stroke_width(1)))
                .map_err(derr)?;
        }
    }
    Ok(geom)
}

/// A scale bar and an x-y-z triad, from (x, y) (the triad's origin) to the right.
fn draw_axes_hint<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    frame: &Frame3d,
    scale: f64,
    (x, y): (i32, i32),
) -> DrawResult {
    let b = frame.camera.basis();
    let len = 34.0;
    let grey = RGBColor(40, 40, 40);
    for (k, name) in ["x", "y", "z"].iter().enumerate() {
        // Screen components of the unit axis k.
        let (r, u) = (b[0][k], b[1][k]);
        let end = (x + (len * r).round() as i32, y - (len * u).round() as i32);
        area.draw(&PathElement::new(vec![(x, y), end], grey.stroke_width(2)))
            .map_err(derr)?;
        let n = (r * r + u * u).sqrt();
        if n > 0.2 {
            // Arrow head: two short strokes back from the tip.
            let (dx, dy) = (r / n, -u / n);
            for side in [-1.0, 1.0] {
                let hx = end.0 as f64 - 7.0 * dx + side * 4.0 * dy;
                let hy = end.1 as f64 - 7.0 * dy - side * 4.0 * dx;
                area.draw(&PathElement::new(
                    vec![end, (hx.round() as i32, hy.round() as i32)],
                    grey.stroke_width(2),
                ))
                .map_err(derr)?;
            }
        }
        let lx = x + (1.3 * len * r).round() as i32 - 4;
        let ly = y - (1.3 * len * u).round() as i32 - 8;
        area.draw_text(name, &text_style(16.0), (lx, ly))
            .map_err(derr)?;
    }
    // Scale bar: the longest round length up to 140 px.
    let nice = [
        0.05, 0.1, 0.2, 0.25, 0.5, 1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0,
    ];
    let metres = nice
        .iter()
        .copied()
        .rfind(|m| m * scale <= 140.0)
        .unwrap_or(nice[0]);
    let bx = x + 70;
    let bl = (metres * scale).round().max(1.0) as i32;
    let by = y + 2;
    let bar = |pts: Vec<(i32, i32)>| PathElement::new(pts, BLACK.stroke_width(2));
    area.draw(&bar(vec![(bx, by), (bx + bl, by)]))
        .map_err(derr)?;
    area.draw(&bar(vec![(bx, by - 5), (bx, by + 5)]))
        .map_err(derr)?;
    area.draw(&bar(vec![(bx + bl, by - 5), (bx + bl, by + 5)]))
        .map_err(derr)?;
    area.draw_text(&format!("{metres} m"), &text_style(15.0), (bx, by - 24))
        .map_err(derr)?;
    Ok(())
}

/// Legend entries of the snapshots: bodies present (with their particle counts in the first
/// snapshot), then the broken-bond classes present in any of them.
fn legend_entries(snaps: &[&ParticleSnapshot], names: &[String]) -> Vec<(RGBColor, String)> {
    let mut bodies: Vec<u32> = snaps.iter().flat_map(|s| s.body.iter().copied()).collect();
    bodies.sort_unstable();
    bodies.dedup();
    let mut out: Vec<(RGBColor, String)> = bodies
        .iter()
        .take(12)
        .map(|&b| {
            let n = snaps[0].body.iter().filter(|&&x| x == b).count();
            (
                body_colour_3d(names, b),
                format!("{} ({n} particles)", body_name(names, b)),
            )
        })
        .collect();
    let held = snaps[0].fixed.iter().filter(|&&f| f).count();
    if held > 0 {
        out.push((FIXED_GREY, format!("held by a support ({held})")));
    }
    for (c, &(_, colour)) in BROKEN_CLASSES.iter().enumerate() {
        let n = snaps
            .iter()
            .map(|s| {
                s.broken_bonds
                    .iter()
                    .filter(|&&k| k > 0 && broken_class(k) == c)
                    .count()
            })
            .max()
            .unwrap_or(0);
        if n > 0 {
            let what = if snaps.len() == 1 {
                format!("{} ({n})", broken_class_label(c))
            } else {
                broken_class_label(c)
            };
            out.push((colour, what));
        }
    }
    out
}

fn draw_swatch<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    (x, y): (i32, i32),
    colour: RGBColor,
    label: &str,
    size: f64,
) -> DrawResult {
    area.draw(&Circle::new((x + 7, y + 8), 7, colour.filled()))
        .map_err(derr)?;
    area.draw_text(label, &text_style(size), (x + 20, y))
        .map_err(derr)
}

/// Writes a 3D view of `snap` to `path` (PNG): an oblique orthographic projection (`frame`'s
/// camera) of the particles drawn back to front, shaded by depth (nearer is lighter), coloured
/// by body (cube salmon, block blue), particles that lost bonds in red (darker with more lost
/// bonds, not shaded). Title: time, variant, broken bonds, note; at the right a legend, an x-y-z
/// triad and a scale bar. `frame` fixes position and scale (fit it to several snapshots to
/// compare them). Errors: an empty snapshot, mismatched arrays, a non-finite position, a
/// particle outside the frame, a path that cannot be written.
pub fn write_png_3d(
    path: &Path,
    snap: &ParticleSnapshot,
    label: &Label3d,
    frame: &Frame3d,
) -> Result<Image3d, String> {
    check_3d(snap)?;
    frame.camera.check()?;
    check_inside(snap, frame)?;
    ensure_font()?;
    let err = |e: String| format!("drawing {}: {e}", path.display());
    let s = frame.scale_into(640.0, 640.0);
    let (pw, ph) = (
        (frame.width() * s).round() as u32,
        (frame.height() * s).round() as u32,
    );
    let entries = legend_entries(&[snap], &label.body_names);
    let legend_h = ROW_H as u32 * (entries.len() as u32 + 2) + 130;
    let m = PANEL_MARGIN as u32;
    let width = m + pw.max(300) + m + LEGEND3D_W;
    let lines = title_layout(snap, label, frame, f64::from(width - 2 * m), 20.0, 16.0);
    let title_h = ROW_H as u32 * lines.len() as u32 + 14;
    let height = title_h + (ph + 2 * m).max(legend_h);
    let mut buf = white_image(path, width, height)?;
    let root = BitMapBackend::with_buffer(&mut buf, (width, height)).into_drawing_area();
    for (k, (line, size)) in lines.iter().enumerate() {
        root.draw_text(line, &text_style(*size), (m as i32, 8 + ROW_H * k as i32))
            .map_err(|e| err(derr(e)))?;
    }
    let top = title_h as i32;
    let plot_right = (m + pw.max(300)) as i32;
    let geom = draw_particles(
        &root,
        snap,
        &label.body_names,
        frame,
        [
            m as i32,
            top + m as i32,
            plot_right,
            top + m as i32 + ph as i32,
        ],
    )
    .map_err(err)?;
    let lx = plot_right + m as i32;
    let mut y = top + m as i32;
    for (colour, text) in &entries {
        draw_swatch(&root, (lx, y), *colour, text, 15.0).map_err(err)?;
        y += ROW_H;
    }
    root.draw_text("shade: lighter = nearer", &text_style(14.0), (lx, y + 4))
        .map_err(|e| err(derr(e)))?;
    let (ca, ce) = (frame.camera.azimuth_deg, frame.camera.elevation_deg);
    root.draw_text(
        &format!("view: azimuth {ca} deg, elevation {ce} deg"),
        &text_style(12.0),
        (lx, y + 4 + ROW_H),
    )
    .map_err(|e| err(derr(e)))?;
    draw_axes_hint(&root, frame, geom.scale, (lx + 40, y + 3 * ROW_H + 60)).map_err(err)?;
    root.present().map_err(|e| err(derr(e)))?;
    drop(root);
    write_indexed_png(path, (width, height), &buf, &key_colours(&label.body_names))?;
    Ok(Image3d {
        size: (width, height),
        panels: vec![geom],
    })
}

/// Every particle of `snap` inside the frame (a frame fitted to other snapshots may miss it).
fn check_inside(snap: &ParticleSnapshot, frame: &Frame3d) -> DrawResult {
    if frame.skip_outside {
        return Ok(());
    }
    for (i, p) in snap.position.iter().enumerate() {
        if inside(&frame.clip, p) && !frame.holds(frame.camera.project(*p)) {
            return Err(format!(
                "particle {i} of the snapshot at t = {} s is outside the frame of the view",
                snap.time
            ));
        }
    }
    Ok(())
}

/// A grid of 3D panels, e.g. the paper's Figure 9: columns are variants, rows instants.
#[derive(Clone, Debug)]
pub struct Grid3d<'a> {
    /// The title, and smaller lines under it (`subtitle`, split at line breaks; empty: none).
    pub title: String,
    pub subtitle: String,
    /// One heading per column.
    pub columns: Vec<String>,
    /// Rows of cells (one per column): a snapshot and its label (its `variant` usually empty:
    /// the column heading names it). Body names for the legend come from the first cell.
    pub cells: Vec<Vec<(&'a ParticleSnapshot, Label3d)>>,
}

/// Writes a grid of 3D panels to `path` (PNG), every panel drawn with `frame` (one position,
/// scale and shading for all), each with its title lines; a shared legend, triad and scale bar
/// at the bottom. Errors as [`write_png_3d`], and for an empty or ragged grid.
pub fn write_grid_png_3d(path: &Path, grid: &Grid3d, frame: &Frame3d) -> Result<Image3d, String> {
    let cols = grid.columns.len();
    if cols == 0 || grid.cells.is_empty() {
        return Err("a grid of 3D panels needs at least one row and one column".into());
    }
    if let Some(r) = grid.cells.iter().position(|row| row.len() != cols) {
        return Err(format!(
            "row {r} of the grid has {} cells for {cols} columns",
            grid.cells[r].len()
        ));
    }
    frame.camera.check()?;
    for (snap, _) in grid.cells.iter().flatten() {
        check_3d(snap)?;
        check_inside(snap, frame)?;
    }
    ensure_font()?;
    let err = |e: String| format!("drawing {}: {e}", path.display());
    let rows = grid.cells.len();
    let m = PANEL_MARGIN;
    let s = frame.scale_into(540.0, 480.0);
    let (pw, ph) = (
        (frame.width() * s).round() as i32,
        (frame.height() * s).round() as i32,
    );
    let cell_w = pw.max(380) + 2 * m;
    let text_w = f64::from(cell_w - 2 * m);
    let layouts: Vec<Vec<(String, f64)>> = grid
        .cells
        .iter()
        .flatten()
        .map(|(snap, l)| title_layout(snap, l, frame, text_w, 16.0, 13.0))
        .collect();
    let title_lines = layouts.iter().map(Vec::len).max().unwrap_or(1) as i32;
    let cell_h = 20 * title_lines + 10 + ph + m;
    let sub_lines: Vec<&str> = grid.subtitle.lines().filter(|l| !l.is_empty()).collect();
    let title_rows = wrap(
        &grid.title,
        (f64::from(cols as i32 * cell_w - 2 * m) / (0.6 * 22.0)) as usize,
    );
    let header_h = 14 + 30 * title_rows.len() as i32 + 22 * sub_lines.len() as i32 + 36;
    let names = &grid.cells[0][0].1.body_names;
    let snaps: Vec<&ParticleSnapshot> = grid.cells.iter().flatten().map(|(s, _)| *s).collect();
    let entries = legend_entries(&snaps, names);
    let footer_h = 120;
    let width = (cols as i32 * cell_w) as u32;
    let height = (header_h + rows as i32 * cell_h + footer_h) as u32;
    let mut buf = white_image(path, width, height)?;
    let root = BitMapBackend::with_buffer(&mut buf, (width, height)).into_drawing_area();
    let w = f64::from(width) - 2.0 * f64::from(m);
    for (k, line) in title_rows.iter().enumerate() {
        root.draw_text(line, &text_style(22.0), (m, 10 + 30 * k as i32))
            .map_err(|e| err(derr(e)))?;
    }
    for (k, line) in sub_lines.iter().enumerate() {
        root.draw_text(
            line,
            &text_style(fit_size(line, w, 16.0)),
            (m, 10 + 30 * title_rows.len() as i32 + 22 * k as i32),
        )
        .map_err(|e| err(derr(e)))?;
    }
    let heading_y = header_h - 30;
    for (c, heading) in grid.columns.iter().enumerate() {
        let size = fit_size(heading, f64::from(cell_w - 2 * m), 20.0);
        let x = c as i32 * cell_w + m;
        root.draw_text(heading, &text_style(size), (x, heading_y))
            .map_err(|e| err(derr(e)))?;
        if c > 0 {
            let xl = c as i32 * cell_w;
            root.draw(&PathElement::new(
                vec![(xl, heading_y - 4), (xl, header_h + rows as i32 * cell_h)],
                RGBColor(190, 190, 190).stroke_width(1),
            ))
            .map_err(|e| err(derr(e)))?;
        }
    }
    let mut panels = Vec::with_capacity(rows * cols);
    for (r, row) in grid.cells.iter().enumerate() {
        let y = header_h + r as i32 * cell_h;
        root.draw(&PathElement::new(
            vec![(0, y), (width as i32, y)],
            RGBColor(190, 190, 190).stroke_width(1),
        ))
        .map_err(|e| err(derr(e)))?;
        for (c, (snap, label)) in row.iter().enumerate() {
            let x = c as i32 * cell_w;
            for (k, (line, size)) in layouts[r * cols + c].iter().enumerate() {
                root.draw_text(line, &text_style(*size), (x + m, y + 6 + 20 * k as i32))
                    .map_err(|e| err(derr(e)))?;
            }
            let top = y + 20 * title_lines + 10;
            let geom = draw_particles(
                &root,
                snap,
                &label.body_names,
                frame,
                [x + m, top, x + cell_w - m, top + ph],
            )
            .map_err(err)?;
            panels.push(geom);
        }
    }
    // Footer: legend entries in two columns, then the triad and the scale bar.
    let fy = header_h + rows as i32 * cell_h;
    root.draw(&PathElement::new(
        vec![(0, fy), (width as i32, fy)],
        RGBColor(190, 190, 190).stroke_width(1),
    ))
    .map_err(|e| err(derr(e)))?;
    let half = entries.len().div_ceil(2).max(1);
    let col_w = 300;
    for (k, (colour, text)) in entries.iter().enumerate() {
        let (ex, ey) = (
            m + col_w * (k / half) as i32,
            fy + 12 + ROW_H * (k % half) as i32,
        );
        draw_swatch(&root, (ex, ey), *colour, text, 14.0).map_err(err)?;
    }
    let note_y = fy + 12 + ROW_H * half as i32;
    root.draw_text("shade: lighter = nearer", &text_style(14.0), (m, note_y))
        .map_err(|e| err(derr(e)))?;
    let ax = (m + 2 * col_w + 40).min(width as i32 - 260);
    draw_axes_hint(&root, frame, s, (ax, fy + 70)).map_err(err)?;
    root.present().map_err(|e| err(derr(e)))?;
    drop(root);
    write_indexed_png(path, (width, height), &buf, &key_colours(names))?;
    Ok(Image3d {
        size: (width, height),
        panels,
    })
}

/// The colours that must stay exact in an indexed PNG: those of the legend swatches.
fn key_colours(names: &[String]) -> Vec<[u8; 3]> {
    let mut keys: Vec<RGBColor> = vec![WHITE, BLACK, FIXED_GREY];
    keys.extend((0..names.len().max(1) as u32).map(|b| body_colour_3d(names, b)));
    keys.extend(BROKEN_CLASSES.iter().map(|c| c.1));
    keys.into_iter()
        .map(|RGBColor(r, g, b)| [r, g, b])
        .collect()
}

/// Largest image drawn (pixels): 40 million, an RGB buffer of 120 MB plus its 40 MB of palette
/// indices (a Figure 9 of the paper's five instants is 3.6 million).
pub const MAX_IMAGE_PIXELS: u64 = 40_000_000;

/// A white RGB buffer of `width` x `height` pixels for `path`: refused beyond
/// [`MAX_IMAGE_PIXELS`], and allocated fallibly (an error, not an abort, when the memory is not
/// there).
fn white_image(path: &Path, width: u32, height: u32) -> Result<Vec<u8>, String> {
    let pixels = u64::from(width) * u64::from(height);
    if pixels > MAX_IMAGE_PIXELS {
        return Err(format!(
            "{} would be {width} x {height} pixels, more than the {MAX_IMAGE_PIXELS} an image may \
             have",
            path.display()
        ));
    }
    let bytes = pixels as usize * 3;
    let mut buf = Vec::new();
    buf.try_reserve_exact(bytes).map_err(|e| {
        format!(
            "{}: no memory for its {width} x {height} pixels ({} MB): {e}",
            path.display(),
            bytes / 1_000_000
        )
    })?;
    buf.resize(bytes, 255u8);
    Ok(buf)
}

/// Writes an RGB buffer (`size` pixels, rows top down) as an 8-bit indexed PNG: the palette is
/// the `keep` colours that occur, then the most frequent others up to 256; the rarer ones
/// (anti-aliased edges and text) take the nearest entry. The 3D views have few colours
/// (quantised shading), so their files are several times smaller than RGB.
fn write_indexed_png(
    path: &Path,
    size: (u32, u32),
    rgb: &[u8],
    keep: &[[u8; 3]],
) -> Result<(), String> {
    use std::collections::HashMap;
    let mut counts: HashMap<[u8; 3], u64> = HashMap::new();
    for p in rgb.chunks_exact(3) {
        *counts.entry([p[0], p[1], p[2]]).or_default() += 1;
    }
    let mut by_count: Vec<([u8; 3], u64)> = counts.into_iter().collect();
    // Kept colours first, then the most frequent, ties by colour: the same image gives the same
    // file.
    let kept = |c: &[u8; 3]| keep.contains(c);
    by_count.sort_by(|a, b| {
        kept(&b.0)
            .cmp(&kept(&a.0))
            .then(b.1.cmp(&a.1))
            .then(a.0.cmp(&b.0))
    });
    let palette: Vec<[u8; 3]> = by_count.iter().take(256).map(|c| c.0).collect();
    let dist = |a: [u8; 3], b: [u8; 3]| -> i32 {
        (0..3)
            .map(|k| (i32::from(a[k]) - i32::from(b[k])).pow(2))
            .sum()
    };
    let index: HashMap<[u8; 3], u8> = by_count
        .iter()
        .enumerate()
        .map(|(k, &(c, _))| {
            let i = if k < palette.len() {
                k
            } else {
                (0..palette.len())
                    .min_by_key(|&j| dist(c, palette[j]))
                    .unwrap_or(0)
            };
            (c, i as u8)
        })
        .collect();
    let data: Vec<u8> = rgb
        .chunks_exact(3)
        .map(|p| index[&[p[0], p[1], p[2]]])
        .collect();
    let err = |e: &dyn std::fmt::Display| format!("writing {}: {e}", path.display());
    let file = std::fs::File::create(path).map_err(|e| err(&e))?;
    let mut enc = ::png::Encoder::new(std::io::BufWriter::new(file), size.0, size.1);
    enc.set_color(::png::ColorType::Indexed);
    enc.set_depth(::png::BitDepth::Eight);
    enc.set_palette(palette.concat());
    enc.set_compression(::png::Compression::Best);
    let mut w = enc.write_header().map_err(|e| err(&e))?;
    w.write_image_data(&data).map_err(|e| err(&e))?;
    w.finish().map_err(|e| err(&e))
}
