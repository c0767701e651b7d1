//! `animate [path] (x0, y0), (x1, y1), … [from RUN] to FILE.gif [fps N] [duration S] [size P]`:
//! the motion of a run as a GIF. The run's span is shown in `duration` seconds at `fps`
//! frames per second; each frame's points are the expressions linearly interpolated between
//! stored states at the frame's time (drawing only: the run's numbers are untouched).

use crate::animate::{Animation, Frame};
use crate::print::fmt_num;
use crate::scene::state::{At, Session};
use crate::scene::statements::{Output, Stmt};
use crate::scene::syntax::ast::Src;
use crate::scene::syntax::error::{ErrorKind, SceneError};
use crate::scene::syntax::parser::{Pair, Reader, Rule, Settings};

/// `animate …`.
#[derive(Clone, Debug)]
pub(in crate::scene) struct AnimateSpec {
    /// The points `(x, y)`: bodies, joined by arms in order.
    pub points: Vec<(Src, Src)>,
    /// `from RUN`.
    pub run: Option<Src>,
    /// The GIF file.
    pub path: Src,
    /// `fps N`.
    pub fps: Option<Src>,
    /// `duration SECONDS`.
    pub duration: Option<Src>,
    /// `size PIXELS`.
    pub size: Option<Src>,
}

impl AnimateSpec {
    /// `animate …`: the points drawn, the run, the file and the frame options.
    pub(in crate::scene) fn read(r: &Reader, p: Pair<'_, Rule>) -> Result<AnimateSpec, SceneError> {
        let (span, inner) = (r.span(&p), r.inner(&p));
        let mut points = Vec::new();
        let mut run = None;
        let mut path = None;
        let (mut fps, mut duration, mut size) = (None, None, None);
        let mut given = Settings::default();
        for q in inner {
            match q.as_rule() {
                Rule::anim_point => {
                    let xs: Vec<Src> = q.into_inner().map(|s| r.src(&s)).collect();
                    if let [x, y] = &xs[..] {
                        points.push((x.clone(), y.clone()));
                    }
                }
                Rule::name => run = Some(r.src(&q)),
                Rule::path => path = Some(r.path(q)),
                Rule::anim_option => {
                    let clause = r.src(&q);
                    let parts: Vec<Pair<Rule>> = q.into_inner().collect();
                    if let [key, value] = &parts[..] {
                        let v = Some(r.src(value));
                        let (word, slot) = match key.as_str() {
                            "fps" => ("fps", &mut fps),
                            "duration" => ("duration", &mut duration),
                            _ => ("size", &mut size),
                        };
                        given.give(word, word, clause)?;
                        *slot = v;
                    }
                }
                _ => {}
            }
        }
        let path = path.ok_or_else(|| SceneError::new(ErrorKind::Syntax, "expected `to FILE.gif`").at(span))?;
        Ok(AnimateSpec { points, run, path, fps, duration, size })
    }
}

/// The error hint for a file that is not a GIF.
pub(in crate::scene) const ANIMATION_FORMATS: &str = "animations are written as `.gif`";

/// Limits: frames per second, duration in seconds, size in pixels, frames in all.
const FPS: (f64, f64, f64) = (10.0, 1.0, 50.0);
const DURATION: (f64, f64, f64) = (4.0, 0.1, 60.0);
const SIZE: (f64, f64, f64) = (320.0, 64.0, 1024.0);
const MAX_FRAMES: f64 = 1500.0;

impl Session {
    pub(in crate::scene) fn animate(&mut self, at: At, spec: &AnimateSpec) -> Result<(), SceneError> {
        let (path, pspan, _) =
            self.out_file(at.span, Some(&spec.path), "animation", "animation", &["gif"], ANIMATION_FORMATS)?;
        let fps = self.setting(at, spec.fps.as_ref(), "fps", FPS)?;
        let duration = self.setting(at, spec.duration.as_ref(), "duration", DURATION)?;
        let size = self.setting(at, spec.size.as_ref(), "size", SIZE)?.round() as u32;
        let n = (fps * duration).round().max(2.0);
        if n > MAX_FRAMES {
            return Err(SceneError::new(
                ErrorKind::BadNumber,
                format!("{n:.0} frames (fps × duration) is more than the limit of {MAX_FRAMES:.0}"),
            )
            .at(pspan)
            .hint("lower `fps` or `duration`"));
        }
        let id = self.run_ids(at, &spec.run.clone().into_iter().collect::<Vec<_>>())?[0];
        let r = self.demand_run(at, id)?;
        let mut coords: Vec<(Vec<f64>, Vec<f64>)> = Vec::new();
        for (x, y) in &spec.points {
            let ex = self.resolved(at, x)?;
            let ey = self.resolved(at, y)?;
            let (xs, ys) = (self.along(at, &r, &ex, x.span)?, self.along(at, &r, &ey, y.span)?);
            let run = self.runs[id].name.clone();
            self.drawable(&xs, &x.text, &run, &r.traj.t, x.span)?;
            self.drawable(&ys, &y.text, &run, &r.traj.t, y.span)?;
            coords.push((xs, ys));
        }
        let ts = &r.traj.t;
        let (Some(&t0), Some(&t1)) = (ts.first(), ts.last()) else {
            return Err(SceneError::new(ErrorKind::Undeclared, "the run has no states to animate").at(pspan));
        };
        let n = n as usize;
        let frames = (0..n)
            .map(|k| {
                let t = t0 + (t1 - t0) * k as f64 / (n - 1) as f64;
                // The stored interval holding t, and the fraction of the way through it.
                let j = ts.partition_point(|s| *s <= t).clamp(1, ts.len().max(2) - 1).min(ts.len() - 1);
                let (i, w) = if ts.len() < 2 {
                    (0, 0.0)
                } else {
                    let (a, b) = (ts[j - 1], ts[j]);
                    (j - 1, if b > a { ((t - a) / (b - a)).clamp(0.0, 1.0) } else { 0.0 })
                };
                let at = |v: &[f64]| if ts.len() < 2 { v[0] } else { v[i] + w * (v[i + 1] - v[i]) };
                Frame { t, points: coords.iter().map(|(xs, ys)| (at(xs), at(ys))).collect() }
            })
            .collect();
        let anim = Animation::new(frames, fps, size);
        let tmp = self.staging.stage(&path).map_err(|e| e.at(pspan))?;
        crate::animate::draw(&anim, &tmp).map_err(|e| {
            SceneError::new(ErrorKind::Io, format!("cannot write the animation `{}`: {e}", path.display())).at(pspan)
        })?;
        self.output.push(format!(
            "animation of {}: {n} frames at {} fps, t = {}..{}",
            self.runs[id].name,
            fmt_num(fps),
            fmt_num(t0),
            fmt_num(t1)
        ));
        self.wrote(&path);
        Ok(())
    }

    /// An animation setting: its value, or the default, within limits.
    fn setting(
        &mut self,
        at: At,
        src: Option<&Src>,
        what: &str,
        (default, lo, hi): (f64, f64, f64),
    ) -> Result<f64, SceneError> {
        let Some(src) = src else { return Ok(default) };
        let x = self.bound(at, src)?;
        if !(lo..=hi).contains(&x) {
            return Err(SceneError::new(
                ErrorKind::BadNumber,
                format!("`{what}` must be between {} and {}, found {}", fmt_num(lo), fmt_num(hi), fmt_num(x)),
            )
            .at(src.span));
        }
        Ok(x)
    }
}

impl Stmt for AnimateSpec {
    fn run(&self, s: &mut Session, at: At) -> Result<(), SceneError> {
        s.animate(at, self)
    }

    fn output(&self) -> Option<Output<'_>> {
        Some(Output {
            path: Some(&self.path),
            default: "animation",
            what: "animation",
            formats: &["gif"],
            hint: ANIMATION_FORMATS,
        })
    }
}
