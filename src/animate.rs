//! Animations of the motion as GIF files (plotters' GIF back end): in each frame, bodies at
//! given points, arms joining consecutive points, the path of the last body so far as a
//! faint trail, and the time in the top-left corner. The frames are fixed by
//! [`Animation::new`] (times, points, equal-aspect ranges that hold every frame), so
//! [`Animation::describe`] says what the file holds without decoding it.

use std::path::Path;

use plotters::prelude::*;

use crate::plot::{bitmap_error, describe_bitmap_error as describe, ensure_font, FAMILY};

/// One frame: its time and the points `(x, y)` of the bodies (the first is the pivot when
/// the chain starts at a fixed point).
#[derive(Clone, Debug, PartialEq)]
pub struct Frame {
    /// The time shown.
    pub t: f64,
    /// The points, joined by arms in order.
    pub points: Vec<(f64, f64)>,
}

/// An animation ready to draw.
#[derive(Clone, Debug)]
pub struct Animation {
    /// The frames in order.
    pub frames: Vec<Frame>,
    /// Frames per second.
    pub fps: f64,
    /// Width and height in pixels (square).
    pub size: u32,
    /// The x range drawn.
    pub x_range: (f64, f64),
    /// The y range drawn (same scale as x).
    pub y_range: (f64, f64),
}

/// What an animation file holds.
#[derive(Clone, Debug, PartialEq)]
pub struct AnimationDescription {
    /// Number of frames.
    pub frames: usize,
    /// Delay between frames in milliseconds (GIF stores hundredths of a second).
    pub delay_ms: u32,
    /// Size in pixels.
    pub size: (u32, u32),
    /// The time stamp of each frame.
    pub stamps: Vec<String>,
    /// Points per frame (bodies and pivot).
    pub points: usize,
    /// The ranges drawn.
    pub x_range: (f64, f64),
    /// The ranges drawn.
    pub y_range: (f64, f64),
}

const MARGIN: u32 = 8;

impl Animation {
    /// Frames shown at `fps` on a square of `size` pixels; the ranges hold every point of
    /// every frame with equal scales and a little room.
    pub fn new(frames: Vec<Frame>, fps: f64, size: u32) -> Animation {
        let all = frames.iter().flat_map(|f| f.points.iter()).filter(|(x, y)| x.is_finite() && y.is_finite());
        let (mut x0, mut x1, mut y0, mut y1) = (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY);
        for &(x, y) in all {
            (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
        }
        if !x0.is_finite() {
            (x0, x1, y0, y1) = (-1.0, 1.0, -1.0, 1.0);
        }
        let half = 0.5 * (x1 - x0).max(y1 - y0).max(1e-9) * 1.1;
        let (cx, cy) = (0.5 * (x0 + x1), 0.5 * (y0 + y1));
        Animation { frames, fps, size, x_range: (cx - half, cx + half), y_range: (cy - half, cy + half) }
    }

    /// The delay between frames in milliseconds, rounded to the GIF's hundredths.
    pub fn delay_ms(&self) -> u32 {
        ((100.0 / self.fps).round().max(1.0) as u32) * 10
    }

    /// What the file holds.
    pub fn describe(&self) -> AnimationDescription {
        AnimationDescription {
            frames: self.frames.len(),
            delay_ms: self.delay_ms(),
            size: (self.size, self.size),
            stamps: self.frames.iter().map(|f| stamp(f.t)).collect(),
            points: self.frames.first().map_or(0, |f| f.points.len()),
            x_range: self.x_range,
            y_range: self.y_range,
        }
    }
}

/// `t = 1.25`.
pub fn stamp(t: f64) -> String {
    format!("t = {t:.2}")
}

/// Writes the animation as a GIF. Stops before the next frame at Ctrl-C (the process-wide
/// [`crate::cancel`] token) with "interrupted", leaving the frames so far at `path` for the
/// caller to remove. The latency is one frame: its encoding cannot be cut (65 ms at 512²,
/// 0.3 s at the largest size, 1024², in the dev profile).
pub fn draw(anim: &Animation, path: &Path) -> Result<(), String> {
    ensure_font();
    let err = |e: &DrawingAreaErrorKind<_>| describe(e);
    let root = BitMapBackend::gif(path, (anim.size, anim.size), anim.delay_ms())
        .map_err(|e| bitmap_error(&e))?
        .into_drawing_area();
    let (x0, x1) = anim.x_range;
    let (y0, y1) = anim.y_range;
    let radius = (anim.size / 40).max(3) as i32;
    let trail_color = RGBColor(170, 170, 210);
    let arm = BLACK.stroke_width((anim.size / 160).max(1) + 1);
    for (k, frame) in anim.frames.iter().enumerate() {
        crate::plot::stop_if_interrupted()?;
        root.fill(&WHITE).map_err(|e| err(&e))?;
        let mut chart =
            ChartBuilder::on(&root).margin(MARGIN).build_cartesian_2d(x0..x1, y0..y1).map_err(|e| err(&e))?;
        let trail: Vec<(f64, f64)> = anim.frames[..=k].iter().filter_map(|f| f.points.last().copied()).collect();
        chart
            .draw_series(std::iter::once(PathElement::new(trail, trail_color.stroke_width(1))))
            .map_err(|e| err(&e))?;
        chart.draw_series(std::iter::once(PathElement::new(frame.points.clone(), arm))).map_err(|e| err(&e))?;
        for (i, p) in frame.points.iter().enumerate() {
            let (r, c) = if i == 0 && frame.points.len() > 1 {
                ((radius / 2).max(2), BLACK.to_rgba())
            } else {
                (radius, Palette99::pick(i).to_rgba())
            };
            chart.draw_series(std::iter::once(Circle::new(*p, r, c.filled()))).map_err(|e| err(&e))?;
        }
        root.draw(&Text::new(stamp(frame.t), (6, 4), (FAMILY, (anim.size / 16).max(10) as f64)))
            .map_err(|e| err(&e))?;
        root.present().map_err(|e| err(&e))?;
    }
    Ok(())
}
