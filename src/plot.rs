//! Plots with plotters, as SVG or PNG (chosen by the file extension): time series, phase
//! portraits with contours of `H` (fixed points marked O — elliptic — and X — hyperbolic —,
//! and the separatrix through X), configuration-space paths, energy error on a log scale,
//! Poincaré sections, work-precision diagrams (log–log, one marked line per method), and
//! heat maps (a value over a grid of starts, such as a chaos map).
//!
//! Every figure is first reduced to a [`Description`] (title, axis labels, series, ranges,
//! labelled decades of log axes, the legend's corner); the renderer draws exactly that, and
//! tests inspect it, so what a figure shows is checked without reading pixels. Log axes are
//! widened to whole decades and labelled at each one; configuration-space paths get equal
//! scales on both axes; the legend goes to the first corner where it covers no data, or the
//! y range grows to make room for it.
//!
//! Text needs a font for both back ends (plotters measures text with it). The DejaVu Sans
//! font is embedded (`assets/fonts/`, Bitstream Vera licence, which allows redistribution
//! with its notice, in `assets/fonts/LICENSE-DejaVu.txt`), so output does not depend on the
//! fonts of the machine.
//!
//! Drawing stops at Ctrl-C (the process-wide [`crate::cancel`] token): every series, contour
//! level and frame of points is drawn through an iterator that ends once the token is set,
//! and [`draw`] then fails with "interrupted" before the file is finished, so the caller
//! (the scene session, which staged the file) removes it. A check is one relaxed atomic
//! load per point, nothing beside plotters' own work per point.

use plotters_backend::DrawingErrorKind;
use plotters_bitmap::BitMapBackendError;
use std::path::Path;
use std::sync::Once;

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

pub(crate) static FONT: &[u8] = include_bytes!("../assets/fonts/DejaVuSans.ttf");
pub(crate) const FAMILY: &str = "sans-serif";
const SIZE: (u32, u32) = (960, 680);
/// The strip above the chart that holds the title.
const TITLE_H: u32 = 44;
const MARGIN: u32 = 16;
const X_LABEL_AREA: u32 = 48;
const Y_LABEL_AREA: u32 = 80;
/// The plotting area in pixels: the figure less the title strip, margins and label areas.
pub const PLOT_AREA: (u32, u32) = (SIZE.0 - 2 * MARGIN - Y_LABEL_AREA, SIZE.1 - TITLE_H - 2 * MARGIN - X_LABEL_AREA);
/// Series beyond this many (an ensemble's orbits) get no legend entries: the title says what
/// they are.
pub const MAX_LEGEND: usize = 12;

/// Where the legend sits inside the plotting area.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Corner {
    /// Top right.
    UpperRight,
    /// Top left.
    UpperLeft,
    /// Bottom right.
    LowerRight,
    /// Bottom left.
    LowerLeft,
}

/// One drawn series: its legend text and how many finite points it has.
#[derive(Clone, Debug, PartialEq)]
pub struct SeriesInfo {
    /// Legend text.
    pub label: String,
    /// Finite points drawn (before thinning for the screen).
    pub points: usize,
}

/// What a figure shows, as the renderer draws it.
#[derive(Clone, Debug)]
pub struct Description {
    /// The title above the chart.
    pub title: String,
    /// The x axis label.
    pub xlabel: String,
    /// The y axis label.
    pub ylabel: String,
    /// The series, in drawing order.
    pub series: Vec<SeriesInfo>,
    /// The x range drawn (data units).
    pub x_range: (f64, f64),
    /// The y range drawn (data units).
    pub y_range: (f64, f64),
    /// Whether the x axis is logarithmic.
    pub log_x: bool,
    /// Whether the y axis is logarithmic.
    pub log_y: bool,
    /// The exponents of the labelled decades of a logarithmic x axis (every one in range).
    pub x_decades: Vec<i32>,
    /// The same for the y axis.
    pub y_decades: Vec<i32>,
    /// Both axes have the same scale (data units per pixel).
    pub equal_aspect: bool,
    /// The legend's corner, when there is a legend.
    pub legend: Option<Corner>,
    /// Its size in pixels (an upper estimate of what plotters draws).
    pub legend_size: (u32, u32),
    /// Data points under the legend box (zero unless nothing could be moved).
    pub legend_covers: usize,
}

pub(crate) fn ensure_font() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        // The embedded font is valid; if registration failed, plotting reports a font error.
        let _ = plotters::style::register_font(FAMILY, FontStyle::Normal, FONT);
    });
}

/// One named curve or point set.
#[derive(Clone, Debug)]
pub struct Series {
    /// Legend text.
    pub label: String,
    /// Points `(x, y)`.
    pub points: Vec<(f64, f64)>,
}

/// A function of the phase plane whose level sets are drawn (`H(q, p)` or `h(q, q')`).
pub struct Contours {
    f: Box<dyn Fn(f64, f64) -> f64>,
}

impl Contours {
    /// Contours of `f`.
    pub fn new(f: Box<dyn Fn(f64, f64) -> f64>) -> Contours {
        Contours { f }
    }
}

/// How a figure draws its series.
enum Style {
    Lines,
    Scatter,
    LogY,
    LogLog,
    Phase(Option<Contours>),
    Heat(HeatMap),
}

/// Values on a square grid of cells over `x × y` (row `j` is the `j`-th cell along `y`).
struct HeatMap {
    x: (f64, f64),
    y: (f64, f64),
    side: usize,
    values: Vec<f64>,
}

/// Viridis at five evenly spaced points (the published colour map of matplotlib's
/// `viridis`), interpolated linearly: perceptually ordered and legible in grey.
const VIRIDIS: [(f64, f64, f64); 5] =
    [(68.0, 1.0, 84.0), (59.0, 82.0, 139.0), (33.0, 145.0, 140.0), (94.0, 201.0, 98.0), (253.0, 231.0, 37.0)];

/// The colour of `s ∈ [0, 1]` (clamped).
fn viridis(s: f64) -> RGBColor {
    let s = s.clamp(0.0, 1.0) * (VIRIDIS.len() - 1) as f64;
    let k = (s.floor() as usize).min(VIRIDIS.len() - 2);
    let f = s - k as f64;
    let (a, b) = (VIRIDIS[k], VIRIDIS[k + 1]);
    let mix = |u: f64, v: f64| (u + (v - u) * f).round() as u8;
    RGBColor(mix(a.0, b.0), mix(a.1, b.1), mix(a.2, b.2))
}

/// The colour scale of a heat map: the smallest finite value to the 95th percentile (a few
/// runaway values, such as strongly chaotic MEGNO, saturate instead of flattening the rest).
pub fn heat_range(values: &[f64]) -> Option<(f64, f64)> {
    let mut v: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let lo = v[0];
    let hi = v[((v.len() - 1) as f64 * 0.95).round() as usize];
    Some(if hi > lo { (lo, hi) } else { (lo, lo + 1.0) })
}

/// A figure ready to draw.
pub struct Figure {
    title: String,
    xlabel: String,
    ylabel: String,
    series: Vec<Series>,
    style: Style,
    /// The phase portrait's coordinate is an angle: its orbits are wrapped to `(−π, π]`.
    periodic: bool,
    /// Equal scales on both axes (a path in configuration space).
    equal_aspect: bool,
}

/// A fixed point of the phase portrait.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FixedPoint {
    /// Its coordinate (the velocity or momentum is zero).
    pub q: f64,
    /// `true` for a centre (O, a minimum of the energy along `p = 0`), `false` for a
    /// saddle (X).
    pub elliptic: bool,
    /// The energy there.
    pub level: f64,
}

impl Figure {
    /// Curves.
    pub fn lines(title: &str, x: &str, y: &str, series: Vec<Series>) -> Figure {
        Figure {
            title: title.into(),
            xlabel: x.into(),
            ylabel: y.into(),
            series,
            style: Style::Lines,
            periodic: false,
            equal_aspect: false,
        }
    }

    /// A path in configuration space: curves drawn with equal scales on both axes, so a
    /// circle looks round.
    pub fn path(title: &str, x: &str, y: &str, series: Vec<Series>) -> Figure {
        Figure { equal_aspect: true, ..Figure::lines(title, x, y, series) }
    }

    /// Points.
    pub fn scatter(title: &str, x: &str, y: &str, series: Vec<Series>) -> Figure {
        Figure {
            title: title.into(),
            xlabel: x.into(),
            ylabel: y.into(),
            series,
            style: Style::Scatter,
            periodic: false,
            equal_aspect: false,
        }
    }

    /// Curves on a logarithmic y axis (non-positive values are left out).
    pub fn log_y(title: &str, x: &str, y: &str, series: Vec<Series>) -> Figure {
        Figure {
            title: title.into(),
            xlabel: x.into(),
            ylabel: y.into(),
            series,
            style: Style::LogY,
            periodic: false,
            equal_aspect: false,
        }
    }

    /// Marked lines on logarithmic x and y axes, the work-precision diagram (points with a
    /// non-positive coordinate are left out).
    pub fn log_log(title: &str, x: &str, y: &str, series: Vec<Series>) -> Figure {
        Figure {
            title: title.into(),
            xlabel: x.into(),
            ylabel: y.into(),
            series,
            style: Style::LogLog,
            periodic: false,
            equal_aspect: false,
        }
    }

    /// A heat map of `values` on a `side × side` grid of cells over `x × y`, row by row
    /// (`values[j·side + i]` is the cell `i` along x, `j` along y); NaN cells are left grey.
    pub fn heat_map(
        title: &str,
        xlabel: &str,
        ylabel: &str,
        x: (f64, f64),
        y: (f64, f64),
        side: usize,
        values: Vec<f64>,
    ) -> Figure {
        Figure {
            title: title.into(),
            xlabel: xlabel.into(),
            ylabel: ylabel.into(),
            series: Vec::new(),
            style: Style::Heat(HeatMap { x, y, side, values }),
            periodic: false,
            equal_aspect: false,
        }
    }

    /// A phase portrait: orbits and, optionally, contours of an energy function.
    ///
    /// When the energy function is 2π-periodic in the coordinate ([`is_angle`]), the
    /// coordinate is an angle: orbits are wrapped to `(−π, π]` (a rotation is drawn as
    /// repeated passes across the frame, cut at the seam), and each equilibrium is marked once.
    pub fn phase(title: &str, q: &str, p: &str, orbits: Vec<Series>, contours: Option<Contours>) -> Figure {
        let periodic = contours.as_ref().is_some_and(|c| is_angle(&*c.f));
        let series = if periodic {
            orbits
                .into_iter()
                .map(|s| {
                    let mut points = Vec::with_capacity(s.points.len());
                    for (k, piece) in split_at_seam(&s.points).into_iter().enumerate() {
                        if k > 0 {
                            points.push((f64::NAN, f64::NAN));
                        }
                        points.extend(piece);
                    }
                    Series { label: s.label, points }
                })
                .collect()
        } else {
            orbits
        };
        Figure {
            title: title.into(),
            xlabel: q.into(),
            ylabel: p.into(),
            series,
            style: Style::Phase(contours),
            periodic,
            equal_aspect: false,
        }
    }

    /// The series as drawn: over-dense lines thinned by [`decimate`] at about a pixel of
    /// `ranges` (scatter plots are drawn point for point).
    pub fn drawn_pieces(&self, ranges: (f64, f64, f64, f64)) -> Vec<Vec<Vec<(f64, f64)>>> {
        let (x0, x1, y0, y1) = ranges;
        let cell = ((x1 - x0) / SIZE.0 as f64, (y1 - y0) / SIZE.1 as f64);
        self.series
            .iter()
            .map(|s| match self.style {
                Style::Scatter => {
                    vec![s.points.iter().copied().filter(|(x, y)| x.is_finite() && y.is_finite()).collect()]
                }
                _ => decimate(&s.points, cell),
            })
            .collect()
    }

    /// The plotted ranges `(x0, x1, y0, y1)`.
    fn ranges(&self) -> (f64, f64, f64, f64) {
        let pts = self.series.iter().flat_map(|s| s.points.iter()).filter(|(x, y)| x.is_finite() && y.is_finite());
        let mut r = (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY);
        for &(x, y) in pts {
            if matches!(self.style, Style::LogY | Style::LogLog) && y <= 0.0 {
                continue;
            }
            if matches!(self.style, Style::LogLog) && x <= 0.0 {
                continue;
            }
            r = (r.0.min(x), r.1.max(x), r.2.min(y), r.3.max(y));
        }
        if let Style::Phase(Some(c)) = &self.style {
            if !r.0.is_finite() {
                // No orbit: frame the fixed points and the separatrix.
                let (q0, q1) = if self.periodic {
                    (-std::f64::consts::PI, std::f64::consts::PI)
                } else {
                    (-1.25 * std::f64::consts::PI, 1.25 * std::f64::consts::PI)
                };
                let fps = fixed_points(&*c.f, q0, q1);
                let centre = fps.iter().find(|f| f.elliptic).map_or(0.0, |f| f.q);
                let base = (c.f)(centre, 0.0);
                let top = match fps.iter().filter(|f| !f.elliptic).map(|f| f.level).reduce(f64::max) {
                    Some(x) => base + 1.6 * (x - base),
                    None => (c.f)(q1, 0.0).max((c.f)(q0, 0.0)),
                };
                let p = momentum_reaching(&*c.f, centre, top).unwrap_or(2.0);
                return (q0, q1, -p, p);
            }
        }
        if !r.0.is_finite() {
            return (0.0, 1.0, 0.0, 1.0);
        }
        if self.periodic {
            let w = if r.3 > r.2 { r.3 - r.2 } else { r.2.abs().max(1.0) };
            return (-std::f64::consts::PI, std::f64::consts::PI, r.2 - 0.05 * w, r.3 + 0.05 * w);
        }
        let pad = |a: f64, b: f64| {
            let w = if b > a { b - a } else { a.abs().max(1.0) };
            (a - 0.05 * w, b + 0.05 * w)
        };
        if matches!(self.style, Style::LogLog) {
            let (y0, y1) = (r.2.max(1e-300), r.3.max(1e-300));
            let x1 = if r.1 > r.0 { r.1 } else { r.0 * 10.0 };
            let y1 = if y1 > y0 { y1 } else { y0 * 10.0 };
            return (r.0 / 1.5, x1 * 1.5, y0 / 3.0, y1 * 3.0);
        }
        if matches!(self.style, Style::LogY) {
            let (x0, x1) = pad(r.0, r.1);
            let y0 = r.2.max(1e-18);
            let y1 = if r.3 > y0 { r.3 } else { y0 * 10.0 };
            return (x0, x1, y0 / 2.0, y1 * 2.0);
        }
        let (x0, x1) = pad(r.0, r.1);
        let (y0, y1) = pad(r.2, r.3);
        (x0, x1, y0, y1)
    }
}

impl Figure {
    /// Whether the axes are logarithmic `(x, y)`.
    fn logs(&self) -> (bool, bool) {
        match self.style {
            Style::LogLog => (true, true),
            Style::LogY => (false, true),
            _ => (false, false),
        }
    }

    /// The points as drawn: finite, and positive on a log axis.
    fn drawable(&self) -> impl Iterator<Item = (usize, (f64, f64))> + '_ {
        let (lx, ly) = self.logs();
        self.series.iter().enumerate().flat_map(move |(i, s)| {
            s.points
                .iter()
                .copied()
                .filter(move |(x, y)| x.is_finite() && y.is_finite() && (!lx || *x > 0.0) && (!ly || *y > 0.0))
                .map(move |p| (i, p))
        })
    }

    /// The legend's entries.
    fn legend_entries(&self) -> Vec<String> {
        if self.series.len() > MAX_LEGEND {
            return Vec::new();
        }
        let mut v: Vec<String> = self.series.iter().map(|s| s.label.clone()).collect();
        if matches!(&self.style, Style::Phase(Some(_))) {
            v.push("separatrix".into());
        }
        v
    }

    /// What the figure shows: the ranges after widening log axes to whole decades, equal
    /// scales and room for the legend, and where the legend goes.
    pub fn describe(&self) -> Description {
        let (log_x, log_y) = self.logs();
        let (mut x0, mut x1, mut y0, mut y1) = self.ranges();
        let decades = |a: f64, b: f64| -> (f64, f64) {
            // Nothing positive to draw (an energy error that is exactly zero): one decade.
            if !(a > 0.0 && b >= a && b.is_finite()) {
                return (0.1, 1.0);
            }
            let lo = a.log10().floor();
            let mut hi = b.log10().ceil();
            if hi <= lo {
                hi = lo + 1.0;
            }
            (10f64.powf(lo), 10f64.powf(hi))
        };
        if log_x {
            (x0, x1) = decades(x0, x1);
        }
        if log_y {
            (y0, y1) = decades(y0, y1);
        }
        let (w, h) = (PLOT_AREA.0 as f64, PLOT_AREA.1 as f64);
        let equal = |x0: &mut f64, x1: &mut f64, y0: &mut f64, y1: &mut f64| {
            let scale = ((*x1 - *x0) / w).max((*y1 - *y0) / h);
            let (cx, cy) = (0.5 * (*x0 + *x1), 0.5 * (*y0 + *y1));
            (*x0, *x1) = (cx - 0.5 * scale * w, cx + 0.5 * scale * w);
            (*y0, *y1) = (cy - 0.5 * scale * h, cy + 0.5 * scale * h);
        };
        if self.equal_aspect && !log_x && !log_y {
            equal(&mut x0, &mut x1, &mut y0, &mut y1);
        }
        let entries = self.legend_entries();
        let legend_size = if entries.is_empty() {
            (0, 0)
        } else {
            let chars = entries.iter().map(|e| e.chars().count()).max().unwrap_or(0) as u32;
            (chars * 9 + 60, entries.len() as u32 * 24 + 16)
        };
        let mut legend = None;
        let mut covers = 0;
        if !entries.is_empty() {
            let corners = [Corner::UpperRight, Corner::UpperLeft, Corner::LowerRight, Corner::LowerLeft];
            let counts: Vec<usize> =
                corners.iter().map(|c| self.covered(*c, legend_size, (x0, x1, y0, y1), (log_x, log_y))).collect();
            match counts.iter().position(|n| *n == 0) {
                Some(i) => legend = Some(corners[i]),
                None => {
                    // Every corner has data: raise the top of the y range until the legend's
                    // height above the highest point is free.
                    let room = h / (h - legend_size.1 as f64 - 12.0).max(h / 4.0);
                    if log_y {
                        let (a, b) = (y0.log10(), y1.log10());
                        y1 = 10f64.powf((a + (b - a) * room).ceil());
                    } else {
                        y1 = y0 + (y1 - y0) * room;
                    }
                    if self.equal_aspect && !log_x && !log_y {
                        // Widen x to keep equal scales; the top band stays free.
                        let scale = (y1 - y0) / h;
                        let cx = 0.5 * (x0 + x1);
                        (x0, x1) = (cx - 0.5 * scale * w, cx + 0.5 * scale * w);
                    }
                    legend = Some(Corner::UpperRight);
                    covers = self.covered(Corner::UpperRight, legend_size, (x0, x1, y0, y1), (log_x, log_y));
                }
            }
        }
        let decade_list = |on: bool, a: f64, b: f64| -> Vec<i32> {
            if !on {
                return Vec::new();
            }
            let (lo, hi) = (a.log10().round() as i32, b.log10().round() as i32);
            let stride = ((hi - lo) / 24 + 1).max(1);
            (lo..=hi).filter(|k| (k - lo) % stride == 0).collect()
        };
        Description {
            title: self.title.clone(),
            xlabel: self.xlabel.clone(),
            ylabel: self.ylabel.clone(),
            series: self
                .series
                .iter()
                .enumerate()
                .map(|(i, s)| SeriesInfo {
                    label: s.label.clone(),
                    points: self.drawable().filter(|(j, _)| *j == i).count(),
                })
                .collect(),
            x_range: (x0, x1),
            y_range: (y0, y1),
            log_x,
            log_y,
            x_decades: decade_list(log_x, x0, x1),
            y_decades: decade_list(log_y, y0, y1),
            equal_aspect: self.equal_aspect,
            legend,
            legend_size,
            legend_covers: covers,
        }
    }

    /// How many drawn points fall under a legend of `size` pixels in `corner` (placed as
    /// plotters places it, 5 pixels in from the corner, plus a few pixels of slack).
    fn covered(&self, corner: Corner, size: (u32, u32), r: (f64, f64, f64, f64), logs: (bool, bool)) -> usize {
        let (w, h) = (PLOT_AREA.0 as f64, PLOT_AREA.1 as f64);
        let (bw, bh) = (size.0 as f64 + 8.0, size.1 as f64 + 8.0);
        let map = |v: f64, a: f64, b: f64, log: bool| {
            if log {
                (v.log10() - a.log10()) / (b.log10() - a.log10())
            } else {
                (v - a) / (b - a)
            }
        };
        let (left, top) = match corner {
            Corner::UpperRight => (true, true),
            Corner::UpperLeft => (false, true),
            Corner::LowerRight => (true, false),
            Corner::LowerLeft => (false, false),
        };
        self.drawable()
            .filter(|(_, (x, y))| {
                let px = map(*x, r.0, r.1, logs.0) * w;
                let py = (1.0 - map(*y, r.2, r.3, logs.1)) * h;
                let in_x = if left { px >= w - 5.0 - bw } else { px <= 5.0 + bw };
                let in_y = if top { py <= 5.0 + bh } else { py >= h - 5.0 - bh };
                in_x && in_y
            })
            .count()
    }
}

/// `10⁻³`: a decade label with a superscript exponent.
pub fn decade_label(k: i32) -> String {
    let sup = |c: char| match c {
        '-' => '⁻',
        '0' => '⁰',
        '1' => '¹',
        '2' => '²',
        '3' => '³',
        '4' => '⁴',
        '5' => '⁵',
        '6' => '⁶',
        '7' => '⁷',
        '8' => '⁸',
        _ => '⁹',
    };
    format!("10{}", k.to_string().chars().map(sup).collect::<String>())
}

/// Fixed points along `v = 0`: zeros of `∂f/∂q` (central differences on a grid, refined by
/// bisection), classified by the sign of the second difference.
pub fn fixed_points(f: &dyn Fn(f64, f64) -> f64, q0: f64, q1: f64) -> Vec<FixedPoint> {
    let n = 400;
    let h = (q1 - q0) / n as f64;
    let e = h * 1e-3;
    let slope = |q: f64| f(q + e, 0.0) - f(q - e, 0.0);
    let mut out = Vec::new();
    let mut prev = slope(q0);
    for i in 1..=n {
        let q = q0 + h * i as f64;
        let cur = slope(q);
        if prev.is_finite() && cur.is_finite() && (prev == 0.0 || prev.signum() != cur.signum()) {
            let (mut a, mut b) = (q - h, q);
            for _ in 0..60 {
                let m = 0.5 * (a + b);
                if slope(a).signum() == slope(m).signum() {
                    a = m;
                } else {
                    b = m;
                }
            }
            let x = 0.5 * (a + b);
            let curv = f(x + h, 0.0) + f(x - h, 0.0) - 2.0 * f(x, 0.0);
            if curv != 0.0 && !out.iter().any(|p: &FixedPoint| (p.q - x).abs() < 2.0 * h) {
                out.push(FixedPoint { q: x, elliptic: curv > 0.0, level: f(x, 0.0) });
            }
        }
        prev = cur;
    }
    out
}

/// The smallest `p > 0` with `f(q, p) = level`, by doubling then bisection.
fn momentum_reaching(f: &dyn Fn(f64, f64) -> f64, q: f64, level: f64) -> Option<f64> {
    let mut hi = 1e-3;
    while f(q, hi) < level {
        hi *= 2.0;
        if hi > 1e9 || !f(q, hi).is_finite() {
            return None;
        }
    }
    let mut lo = 0.0;
    for _ in 0..80 {
        let m = 0.5 * (lo + hi);
        if f(q, m) < level {
            lo = m;
        } else {
            hi = m;
        }
    }
    Some(hi * 1.05)
}

/// Line segments of the level set `f = level` on a grid (marching squares).
#[doc(hidden)]
pub fn contour_segments(values: &[Vec<f64>], xs: &[f64], ys: &[f64], level: f64) -> Vec<((f64, f64), (f64, f64))> {
    let mut segs = Vec::new();
    let lerp = |a: f64, b: f64, fa: f64, fb: f64| {
        if fb == fa {
            0.5 * (a + b)
        } else {
            a + (level - fa) / (fb - fa) * (b - a)
        }
    };
    for j in 0..ys.len() - 1 {
        for i in 0..xs.len() - 1 {
            let f00 = values[j][i];
            let f10 = values[j][i + 1];
            let f01 = values[j + 1][i];
            let f11 = values[j + 1][i + 1];
            if ![f00, f10, f01, f11].iter().all(|v| v.is_finite()) {
                continue;
            }
            let (x0, x1, y0, y1) = (xs[i], xs[i + 1], ys[j], ys[j + 1]);
            let mut pts = Vec::with_capacity(4);
            if (f00 < level) != (f10 < level) {
                pts.push((lerp(x0, x1, f00, f10), y0));
            }
            if (f10 < level) != (f11 < level) {
                pts.push((x1, lerp(y0, y1, f10, f11)));
            }
            if (f11 < level) != (f01 < level) {
                pts.push((lerp(x0, x1, f01, f11), y1));
            }
            if (f01 < level) != (f00 < level) {
                pts.push((x0, lerp(y0, y1, f00, f01)));
            }
            if pts.len() >= 2 {
                segs.push((pts[0], pts[1]));
            }
            if pts.len() == 4 {
                segs.push((pts[2], pts[3]));
            }
        }
    }
    segs
}

/// Joins the two-point segments of a contour into polylines: neighbouring cells compute a
/// shared edge's crossing from the same two values in the same order, so their endpoints are
/// bit-identical and are matched exactly. An SVG then holds one `<polyline>` per contour
/// piece instead of one element per grid cell.
#[doc(hidden)]
pub fn chain_segments(segs: Vec<((f64, f64), (f64, f64))>) -> Vec<Vec<(f64, f64)>> {
    use std::collections::HashMap;
    let key = |p: (f64, f64)| (p.0.to_bits(), p.1.to_bits());
    let mut at: HashMap<(u64, u64), Vec<usize>> = HashMap::new();
    for (i, (a, b)) in segs.iter().enumerate() {
        at.entry(key(*a)).or_default().push(i);
        at.entry(key(*b)).or_default().push(i);
    }
    let mut used = vec![false; segs.len()];
    let mut out = Vec::new();
    // Extends `line` from its last point along unused segments.
    let extend = |line: &mut Vec<(f64, f64)>, used: &mut Vec<bool>| loop {
        let end = *line.last().expect("a line has a point");
        let next = at.get(&key(end)).and_then(|v| v.iter().copied().find(|&j| !used[j]));
        let Some(j) = next else { break };
        used[j] = true;
        let (a, b) = segs[j];
        line.push(if key(a) == key(end) { b } else { a });
    };
    for i in 0..segs.len() {
        if used[i] {
            continue;
        }
        used[i] = true;
        let mut line = vec![segs[i].0, segs[i].1];
        extend(&mut line, &mut used);
        line.reverse();
        extend(&mut line, &mut used);
        out.push(line);
    }
    out
}

/// Thins an over-dense path for drawing, keeping its look at the figure's resolution: a point
/// is kept when it moves to another cell of a grid `cell` wide (in data units, about a pixel),
/// and stretches that only retrace cells this path has already drawn are cut out, so an orbit
/// that goes round the same curve a hundred times is drawn about once. The result is the
/// pieces to draw as polylines, in order (cut short at Ctrl-C, when nothing is drawn).
pub fn decimate(points: &[(f64, f64)], cell: (f64, f64)) -> Vec<Vec<(f64, f64)>> {
    use std::collections::HashSet;
    let (cx, cy) = (cell.0.max(f64::MIN_POSITIVE), cell.1.max(f64::MIN_POSITIVE));
    let index = |p: (f64, f64)| ((p.0 / cx).floor() as i64, (p.1 / cy).floor() as i64);
    let mut seen: HashSet<(i64, i64)> = HashSet::new();
    let mut pieces: Vec<Vec<(f64, f64)>> = Vec::new();
    let mut current: Vec<(f64, f64)> = Vec::new();
    let mut last_cell = None;
    let mut prev: Option<(f64, f64)> = None;
    // At Ctrl-C the pass ends early (its caller stops drawing at the same check).
    for &p in points.iter().take_while(go_on) {
        if !(p.0.is_finite() && p.1.is_finite()) {
            if current.len() > 1 {
                pieces.push(std::mem::take(&mut current));
            }
            current.clear();
            last_cell = None;
            prev = None;
            continue;
        }
        let c = index(p);
        if last_cell == Some(c) {
            prev = Some(p);
            continue;
        }
        let fresh = seen.insert(c);
        if fresh {
            if current.is_empty() {
                // Re-enter at the last point on the old track, so no gap opens.
                if let Some(q) = prev {
                    current.push(q);
                }
            }
            current.push(p);
        } else if !current.is_empty() {
            current.push(p);
            pieces.push(std::mem::take(&mut current));
        }
        last_cell = Some(c);
        prev = Some(p);
    }
    // A lone point is kept only when it is all there is (a path at rest).
    if current.len() > 1 || (current.len() == 1 && pieces.is_empty()) {
        pieces.push(current);
    }
    pieces
}

/// Wraps `q` into `(−π, π]`.
pub fn wrap_angle(q: f64) -> f64 {
    use std::f64::consts::PI;
    let w = (q + PI).rem_euclid(2.0 * PI) - PI;
    if w <= -PI {
        w + 2.0 * PI
    } else {
        w
    }
}

/// Whether `f(q, p)` is 2π-periodic in `q` (an angle): compared at a few fixed points, to
/// rounding.
pub fn is_angle(f: &dyn Fn(f64, f64) -> f64) -> bool {
    let samples = [(0.3, 0.0), (-1.1, 0.7), (2.5, -1.3), (0.05, 2.1)];
    samples.iter().all(|&(q, p)| {
        let (a, b) = (f(q, p), f(q + 2.0 * std::f64::consts::PI, p));
        a.is_finite() && b.is_finite() && (a - b).abs() <= 1e-9 * (1.0 + a.abs())
    }) && samples.iter().any(|&(q, p)| (f(q, p) - f(q + 1.0, p)).abs() > 1e-9)
}

/// Splits a path whose `x` was wrapped to `(−π, π]` where it jumps across the seam.
#[doc(hidden)]
pub fn split_at_seam(points: &[(f64, f64)]) -> Vec<Vec<(f64, f64)>> {
    let mut out: Vec<Vec<(f64, f64)>> = Vec::new();
    for &(x, y) in points {
        let w = wrap_angle(x);
        match out.last_mut() {
            Some(line) if !line.last().is_some_and(|&(px, _)| (w - px).abs() > std::f64::consts::PI) => {
                line.push((w, y))
            }
            _ => out.push(vec![(w, y)]),
        }
    }
    out
}

/// What went wrong while drawing, in the operating system's words when it was the disk
/// (`No space left on device (os error 28)`): the back end's own `Display` is Rust's `Debug`.
#[doc(hidden)]
pub fn describe_bitmap_error(e: &DrawingAreaErrorKind<BitMapBackendError>) -> String {
    match e {
        DrawingAreaErrorKind::BackendError(DrawingErrorKind::DrawingError(b)) => bitmap_error(b),
        other => other.to_string(),
    }
}

pub(crate) fn bitmap_error(b: &BitMapBackendError) -> String {
    match b {
        BitMapBackendError::IOError(io) => io.to_string(),
        BitMapBackendError::GifEncodingError(g) => g.to_string(),
        BitMapBackendError::ImageError(i) => i.to_string(),
        other => format!("the image encoder failed ({other})"),
    }
}

/// Draws `fig` into `path` (SVG or PNG by extension). Fails with "interrupted" at Ctrl-C,
/// leaving whatever the back end wrote at `path` for the caller to remove.
pub fn draw(fig: &Figure, path: &Path) -> Result<(), String> {
    ensure_font();
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
    if ext == "png" {
        let root = BitMapBackend::new(path, SIZE).into_drawing_area();
        render(fig, &root)?;
        stop_if_interrupted()?;
        root.present().map_err(|e| describe_bitmap_error(&e))
    } else {
        let root = SVGBackend::new(path, SIZE).into_drawing_area();
        render(fig, &root)?;
        stop_if_interrupted()?;
        root.present().map_err(|e| e.to_string())
    }
}

/// `Err("interrupted")` once Ctrl-C was pressed.
pub(crate) fn stop_if_interrupted() -> Result<(), String> {
    crate::cancel::check().map_err(|e| e.to_string())
}

/// Whether drawing may go on: the condition of the `take_while` on every drawn sequence.
pub(crate) fn go_on<T>(_: &T) -> bool {
    !crate::cancel::interrupted()
}

/// Draws `fig` as [`Figure::describe`] lays it out: the title in a strip above the chart,
/// then the chart.
fn render<DB: DrawingBackend>(fig: &Figure, root: &DrawingArea<DB, Shift>) -> Result<(), String>
where
    DB::ErrorType: 'static,
{
    let err = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    root.fill(&WHITE).map_err(err)?;
    if let Style::Heat(h) = &fig.style {
        return render_heat(fig, h, root);
    }
    let d = fig.describe();
    let (top, body) = root.split_vertically(TITLE_H);
    top.draw(&Text::new(
        d.title.clone(),
        (SIZE.0 as i32 / 2, 12),
        TextStyle::from((FAMILY, 24).into_font()).pos(Pos::new(HPos::Center, VPos::Top)),
    ))
    .map_err(err)?;
    let mut builder = ChartBuilder::on(&body);
    builder.margin(MARGIN).x_label_area_size(X_LABEL_AREA).y_label_area_size(Y_LABEL_AREA);
    let ((x0, x1), (y0, y1)) = (d.x_range, d.y_range);
    let decade_points = |ks: &[i32]| ks.iter().map(|k| 10f64.powi(*k)).collect::<Vec<f64>>();
    let decade_text = |v: &f64| decade_label(v.log10().round() as i32);
    match fig.style {
        Style::LogY => {
            let mut chart = builder
                .build_cartesian_2d(x0..x1, (y0..y1).log_scale().with_key_points(decade_points(&d.y_decades)))
                .map_err(err)?;
            chart
                .configure_mesh()
                .x_desc(&d.xlabel)
                .y_desc(&d.ylabel)
                .label_style((FAMILY, 15))
                .y_label_formatter(&decade_text)
                .draw()
                .map_err(err)?;
            for (i, s) in fig.series.iter().enumerate() {
                let color = Palette99::pick(i).to_rgba();
                let pts: Vec<(f64, f64)> =
                    s.points.iter().copied().filter(|(x, y)| *y > 0.0 && y.is_finite() && x.is_finite()).collect();
                let drawn = chart
                    .draw_series(LineSeries::new(pts.into_iter().take_while(go_on), color.stroke_width(2)))
                    .map_err(err)?;
                if d.legend.is_some() {
                    drawn
                        .label(s.label.clone())
                        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2)));
                }
                stop_if_interrupted()?;
            }
            draw_legend(&mut chart, &d).map_err(err)
        }
        Style::LogLog => {
            let mut chart = builder
                .build_cartesian_2d(
                    (x0..x1).log_scale().with_key_points(decade_points(&d.x_decades)),
                    (y0..y1).log_scale().with_key_points(decade_points(&d.y_decades)),
                )
                .map_err(err)?;
            chart
                .configure_mesh()
                .x_desc(&d.xlabel)
                .y_desc(&d.ylabel)
                .label_style((FAMILY, 15))
                .x_label_formatter(&decade_text)
                .y_label_formatter(&decade_text)
                .draw()
                .map_err(err)?;
            for (i, s) in fig.series.iter().enumerate() {
                let color = Palette99::pick(i).to_rgba();
                let pts: Vec<(f64, f64)> = s
                    .points
                    .iter()
                    .copied()
                    .filter(|(x, y)| *x > 0.0 && *y > 0.0 && x.is_finite() && y.is_finite())
                    .collect();
                chart
                    .draw_series(pts.iter().take_while(go_on).map(|p| Circle::new(*p, 4, color.filled())))
                    .map_err(err)?;
                let drawn = chart
                    .draw_series(LineSeries::new(pts.into_iter().take_while(go_on), color.stroke_width(2)))
                    .map_err(err)?;
                if d.legend.is_some() {
                    drawn
                        .label(s.label.clone())
                        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2)));
                }
                stop_if_interrupted()?;
            }
            draw_legend(&mut chart, &d).map_err(err)
        }
        _ => {
            let mut chart = builder.build_cartesian_2d(x0..x1, y0..y1).map_err(err)?;
            chart.configure_mesh().x_desc(&d.xlabel).y_desc(&d.ylabel).label_style((FAMILY, 15)).draw().map_err(err)?;
            if let Style::Phase(Some(c)) = &fig.style {
                draw_contours(&mut chart, fig, c, (x0, x1, y0, y1), d.legend.is_some()).map_err(err)?;
                stop_if_interrupted()?;
            }
            let scatter = matches!(fig.style, Style::Scatter);
            let pieces = fig.drawn_pieces((x0, x1, y0, y1));
            stop_if_interrupted()?;
            for (i, (s, lines)) in fig.series.iter().zip(pieces).enumerate() {
                let color = Palette99::pick(i + 1).to_rgba();
                let drawn = if scatter {
                    let pts = lines.into_iter().flatten().take_while(go_on);
                    chart.draw_series(pts.map(|p| Circle::new(p, 2, color.filled()))).map_err(err)?
                } else {
                    // One polyline per piece (a single element when nothing was cut).
                    chart
                        .draw_series(
                            lines.into_iter().take_while(go_on).map(|l| PathElement::new(l, color.stroke_width(2))),
                        )
                        .map_err(err)?
                };
                if d.legend.is_some() {
                    drawn
                        .label(s.label.clone())
                        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2)));
                }
                stop_if_interrupted()?;
            }
            draw_legend(&mut chart, &d).map_err(err)
        }
    }
}

/// The legend box in the corner [`Figure::describe`] chose.
fn draw_legend<'a, DB: DrawingBackend + 'a, CT: plotters::coord::CoordTranslate>(
    chart: &mut ChartContext<'a, DB, CT>,
    d: &Description,
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    let Some(corner) = d.legend else { return Ok(()) };
    let position = match corner {
        Corner::UpperRight => SeriesLabelPosition::UpperRight,
        Corner::UpperLeft => SeriesLabelPosition::UpperLeft,
        Corner::LowerRight => SeriesLabelPosition::LowerRight,
        Corner::LowerLeft => SeriesLabelPosition::LowerLeft,
    };
    chart
        .configure_series_labels()
        .position(position)
        .border_style(BLACK)
        .background_style(WHITE.mix(0.85))
        .label_font((FAMILY, 15))
        .draw()
}

/// Contours of the phase portrait's energy, its fixed points (O, X) and the separatrix.
fn draw_contours<'a, DB: DrawingBackend + 'a>(
    chart: &mut ChartContext<
        'a,
        DB,
        Cartesian2d<plotters::coord::types::RangedCoordf64, plotters::coord::types::RangedCoordf64>,
    >,
    fig: &Figure,
    c: &Contours,
    (x0, x1, y0, y1): (f64, f64, f64, f64),
    legend: bool,
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    let (nx, ny) = (120, 96);
    let xs: Vec<f64> = (0..=nx).map(|i| x0 + (x1 - x0) * i as f64 / nx as f64).collect();
    let ys: Vec<f64> = (0..=ny).map(|j| y0 + (y1 - y0) * j as f64 / ny as f64).collect();
    let values: Vec<Vec<f64>> = ys.iter().map(|&y| xs.iter().map(|&x| (c.f)(x, y)).collect()).collect();
    let finite = values.iter().flatten().copied().filter(|v| v.is_finite());
    let (lo, hi) = finite.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)));
    if !(lo.is_finite() && hi > lo) {
        return Ok(());
    }
    let grey = RGBColor(150, 150, 170);
    let levels = 14;
    for k in (1..levels).take_while(go_on) {
        let level = lo + (hi - lo) * k as f64 / levels as f64;
        let lines = chain_segments(contour_segments(&values, &xs, &ys, level));
        chart.draw_series(lines.into_iter().map(|l| PathElement::new(l, grey.stroke_width(1))))?;
    }
    let mut fps = fixed_points(&*c.f, x0, x1);
    if fig.periodic {
        // One mark per equilibrium: −π and π are the same point of the circle.
        let tol = 1e-6;
        let mut kept: Vec<FixedPoint> = Vec::new();
        for mut fp in fps {
            fp.q = wrap_angle(fp.q);
            if (fp.q + std::f64::consts::PI).abs() < tol {
                fp.q = std::f64::consts::PI;
            }
            if !kept.iter().any(|k| (wrap_angle(k.q - fp.q)).abs() < tol) {
                kept.push(fp);
            }
        }
        fps = kept;
    }
    let mut labelled = !legend;
    for fp in fps.iter().filter(|f| !f.elliptic) {
        let lines = chain_segments(contour_segments(&values, &xs, &ys, fp.level));
        let red = RGBColor(200, 30, 30);
        let drawn = chart.draw_series(lines.into_iter().map(|l| PathElement::new(l, red.stroke_width(2))))?;
        if !labelled {
            drawn
                .label("separatrix")
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], red.stroke_width(2)));
            labelled = true;
        }
    }
    for fp in &fps {
        let name = if fp.elliptic { "O" } else { "X" };
        let style = ShapeStyle::from(&BLACK).filled();
        chart.draw_series(std::iter::once(
            EmptyElement::at((fp.q, 0.0))
                + Circle::new((0, 0), 4, style)
                + Text::new(name.to_string(), (6, -18), (FAMILY, 18)),
        ))?;
    }
    Ok(())
}

fn render_heat<DB: DrawingBackend>(fig: &Figure, h: &HeatMap, root: &DrawingArea<DB, Shift>) -> Result<(), String>
where
    DB::ErrorType: 'static,
{
    let err = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    let (x0, x1) = h.x;
    let (y0, y1) = h.y;
    let mut chart = ChartBuilder::on(root)
        .caption(&fig.title, (FAMILY, 24))
        .margin(16)
        .x_label_area_size(48)
        .y_label_area_size(80)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(err)?;
    chart
        .configure_mesh()
        .disable_mesh()
        .x_desc(&fig.xlabel)
        .y_desc(&fig.ylabel)
        .label_style((FAMILY, 15))
        .draw()
        .map_err(err)?;
    let (lo, hi) = heat_range(&h.values).unwrap_or((0.0, 1.0));
    let n = h.side;
    let (dx, dy) = ((x1 - x0) / n as f64, (y1 - y0) / n as f64);
    let grey = RGBColor(190, 190, 190);
    chart
        .draw_series(h.values.iter().enumerate().take_while(go_on).map(|(k, &v)| {
            let (i, j) = ((k % n) as f64, (k / n) as f64);
            let color = if v.is_finite() { viridis((v - lo) / (hi - lo)) } else { grey };
            Rectangle::new([(x0 + i * dx, y0 + j * dy), (x0 + (i + 1.0) * dx, y0 + (j + 1.0) * dy)], color.filled())
        }))
        .map_err(err)?;
    stop_if_interrupted()?;
    // The colour scale as a legend of five levels.
    for k in 0..5 {
        let s = k as f64 / 4.0;
        let color = viridis(s);
        chart
            .draw_series(std::iter::empty::<Rectangle<(f64, f64)>>())
            .map_err(err)?
            .label(format!("{:.3}{}", lo + s * (hi - lo), if k == 4 { " and above" } else { "" }))
            .legend(move |(x, y)| Rectangle::new([(x, y - 6), (x + 16, y + 6)], color.filled()));
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .border_style(BLACK)
        .background_style(WHITE.mix(0.85))
        .label_font((FAMILY, 15))
        .draw()
        .map_err(err)?;
    Ok(())
}
