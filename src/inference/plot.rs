//! PNG plots of a fit (plotters, bitmap backend, DejaVu Sans embedded — no system fonts):
//! `objective.png` (log10 objective per evaluation, numbered from 1 on integer ticks, with the best
//! so far) and `landscape.png` (every evaluated point over the two first fitted parameters, log10
//! axes, coloured by log10 objective, the search bounds dashed; with one fitted parameter, the
//! objective against it). A failed (penalised) evaluation is a cross, never a point on the objective
//! scale: its penalty would squash the usable objectives into a line; the scales span the usable
//! evaluations. `profile.png` shows the profile of each quantity the fit reports a range for.

use super::InferenceError;
use super::forward::Evaluation;
use super::profile::{NoiseFloor, Slice};
use super::space::ParameterSpace;
use crate::files::ensure_font;
use crate::geometry::Real;
use plotters::prelude::*;
use std::path::Path;

fn err(path: &Path, e: impl std::fmt::Display) -> InferenceError {
    InferenceError::Output(format!("{}: {e}", path.display()))
}

fn log10_objective(e: &Evaluation) -> Real {
    e.objective.max(1e-12).log10()
}

fn padded(lo: Real, hi: Real) -> (Real, Real) {
    if hi.is_nan() || lo.is_nan() || hi <= lo {
        return (lo - 0.5, hi + 0.5);
    }
    let pad = 0.05 * (hi - lo);
    (lo - pad, hi + pad)
}

/// The y range of log10 objectives: the usable evaluations' (a failure penalty would squash them
/// into a line), or the penalties' when none is usable.
fn objective_range(trace: &[Evaluation]) -> (Real, Real) {
    let usable: Vec<Real> = trace.iter().filter(|e| e.status.usable()).map(log10_objective).collect();
    let ys = if usable.is_empty() { trace.iter().map(log10_objective).collect() } else { usable };
    padded(ys.iter().copied().fold(Real::INFINITY, Real::min), ys.iter().copied().fold(Real::NEG_INFINITY, Real::max))
}

/// Objective (log10) per evaluation, numbered from 1 on an integer axis, and the best so far;
/// failed evaluations (penalised: failed or unconverged) as red crosses along the top, not as
/// points on the objective scale.
pub fn plot_objective(path: &Path, trace: &[Evaluation]) -> Result<(), InferenceError> {
    ensure_font();
    if trace.is_empty() {
        return Ok(());
    }
    let tmp = path.with_extension("png.tmp.png");
    {
        let root = BitMapBackend::new(&tmp, (800, 500)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| err(path, e))?;
        let (lo, hi) = objective_range(trace);
        let n = trace.len() as i64;
        let mut chart = ChartBuilder::on(&root)
            .caption("objective per evaluation", ("sans-serif", 22))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(0..n + 1, lo..hi)
            .map_err(|e| err(path, e))?;
        chart
            .configure_mesh()
            .x_desc("evaluation")
            .y_desc("log10 objective")
            .x_labels((n + 2).min(12) as usize)
            .x_label_formatter(&|i| format!("{i}"))
            .draw()
            .map_err(|e| err(path, e))?;
        let numbered = || trace.iter().enumerate().map(|(i, e)| (i as i64 + 1, e));
        chart
            .draw_series(
                numbered()
                    .filter(|(_, e)| e.status.usable())
                    .map(|(i, e)| Circle::new((i, log10_objective(e)), 3, BLUE.filled())),
            )
            .map_err(|e| err(path, e))?
            .label("evaluation")
            .legend(|(x, y)| Circle::new((x, y), 3, BLUE.filled()));
        if trace.iter().any(|e| !e.status.usable()) {
            // Along the top, inside the plot: the penalty is off the usable scale.
            let top = hi - 0.03 * (hi - lo);
            chart
                .draw_series(
                    numbered()
                        .filter(|(_, e)| !e.status.usable())
                        .map(|(i, _)| Cross::new((i, top), 6, RED.stroke_width(2))),
                )
                .map_err(|e| err(path, e))?
                .label("failed (penalty, off scale)")
                .legend(|(x, y)| Cross::new((x, y), 5, RED.stroke_width(2)));
        }
        let mut best = Real::INFINITY;
        let running: Vec<(i64, Real)> = numbered()
            .filter_map(|(i, e)| {
                if e.status.usable() {
                    best = best.min(log10_objective(e));
                }
                best.is_finite().then_some((i, best))
            })
            .collect();
        let green = RGBColor(0, 140, 60);
        chart
            .draw_series(LineSeries::new(running, green.stroke_width(2)))
            .map_err(|e| err(path, e))?
            .label("best so far")
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], green.stroke_width(2)));
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(|e| err(path, e))?;
        root.present().map_err(|e| err(path, e))?;
    }
    crate::io::replace_with(&tmp, path).map_err(|e| err(path, e))
}

/// Evaluated points over the first two fitted parameters (log10 SI), coloured by log10 objective.
pub fn plot_landscape(path: &Path, space: &ParameterSpace, trace: &[Evaluation]) -> Result<(), InferenceError> {
    ensure_font();
    if trace.is_empty() {
        return Ok(());
    }
    let ln10 = std::f64::consts::LN_10;
    let objs: Vec<Real> = trace.iter().map(log10_objective).collect();
    // The colour ramp (and the 1-D y axis) spans the usable evaluations; failed ones are crosses.
    let usable: Vec<Real> = trace.iter().filter(|e| e.status.usable()).map(log10_objective).collect();
    let ramp = if usable.is_empty() { &objs } else { &usable };
    let (omin, omax) = (
        ramp.iter().copied().fold(Real::INFINITY, Real::min),
        ramp.iter().copied().fold(Real::NEG_INFINITY, Real::max),
    );
    let colour = |o: Real| {
        let t = if omax > omin { ((o - omin) / (omax - omin)).clamp(0.0, 1.0) } else { 0.0 };
        // Low objective: dark blue; high: yellow (a viridis-like ramp through HSL).
        HSLColor(0.66 - 0.5 * t, 0.9, 0.3 + 0.35 * t)
    };
    let best = trace.iter().min_by(|a, b| a.objective.total_cmp(&b.objective)).expect("non-empty");
    let tmp = path.with_extension("png.tmp.png");
    {
        let root = BitMapBackend::new(&tmp, (800, 650)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| err(path, e))?;
        let p0 = &space.fitted[0];
        let [a0, b0] = p0.log_bounds();
        let xr = padded(a0 / ln10, b0 / ln10);
        let (ylab, yr, ys): (String, (Real, Real), Vec<Real>) = if space.dim() >= 2 {
            let p1 = &space.fitted[1];
            let [a1, b1] = p1.log_bounds();
            (
                format!("log10 {} (SI)", p1.name()),
                padded(a1 / ln10, b1 / ln10),
                trace.iter().map(|e| e.x[1] / ln10).collect(),
            )
        } else {
            let yr = objective_range(trace);
            // Failed evaluations along the top (their penalty is off the usable scale).
            let top = yr.1 - 0.03 * (yr.1 - yr.0);
            let ys = trace.iter().zip(&objs).map(|(e, &o)| if e.status.usable() { o } else { top }).collect();
            ("log10 objective".to_string(), yr, ys)
        };
        let mut chart = ChartBuilder::on(&root)
            .caption(
                format!("evaluated points (colour: log10 objective {omin:.2} … {omax:.2}, blue = low)"),
                ("sans-serif", 18),
            )
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d(xr.0..xr.1, yr.0..yr.1)
            .map_err(|e| err(path, e))?;
        chart
            .configure_mesh()
            .x_desc(format!("log10 {} (SI)", p0.name()))
            .y_desc(ylab)
            .draw()
            .map_err(|e| err(path, e))?;
        // The search bounds: dashed lines at each fitted parameter's bounds.
        let grey = RGBColor(90, 90, 90);
        let mut bounds: Vec<Vec<(Real, Real)>> =
            [a0, b0].iter().map(|&b| vec![(b / ln10, yr.0), (b / ln10, yr.1)]).collect();
        if space.dim() >= 2 {
            let [a1, b1] = space.fitted[1].log_bounds();
            bounds.extend([a1, b1].iter().map(|&b| vec![(xr.0, b / ln10), (xr.1, b / ln10)]));
        }
        for (k, line) in bounds.into_iter().enumerate() {
            let series =
                chart.draw_series(DashedLineSeries::new(line, 6, 4, grey.stroke_width(2))).map_err(|e| err(path, e))?;
            if k == 0 {
                series
                    .label("search bounds")
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], grey.stroke_width(2)));
            }
        }
        chart
            .draw_series(
                trace
                    .iter()
                    .zip(&ys)
                    .zip(&objs)
                    .filter(|((e, _), _)| e.status.usable())
                    .map(|((e, &y), &o)| Circle::new((e.x[0] / ln10, y), 5, colour(o).filled())),
            )
            .map_err(|e| err(path, e))?;
        if trace.iter().any(|e| !e.status.usable()) {
            chart
                .draw_series(
                    trace
                        .iter()
                        .zip(&ys)
                        .filter(|(e, _)| !e.status.usable())
                        .map(|(e, &y)| Cross::new((e.x[0] / ln10, y), 6, BLACK.stroke_width(2))),
                )
                .map_err(|e| err(path, e))?
                .label("failed (penalty)")
                .legend(|(x, y)| Cross::new((x, y), 5, BLACK.stroke_width(2)));
        }
        let by = if space.dim() >= 2 { best.x[1] / ln10 } else { log10_objective(best) };
        chart
            .draw_series(std::iter::once(Cross::new((best.x[0] / ln10, by), 9, RED.stroke_width(3))))
            .map_err(|e| err(path, e))?
            .label("best")
            .legend(|(x, y)| Cross::new((x, y), 6, RED.stroke_width(2)));
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(|e| err(path, e))?;
        root.present().map_err(|e| err(path, e))?;
    }
    crate::io::replace_with(&tmp, path).map_err(|e| err(path, e))
}

/// The profile (`profile.png`): one panel per profiled quantity (a fitted parameter, the scale, a
/// ratio), its objective (log10) against log10(value / best value) along the profile, the
/// acceptance threshold (dashed) and the acceptable range (the closed sides, dotted; an open side is
/// named in the panel's title). Points more than 100× above the threshold (failure penalties, far
/// misfits) are drawn as crosses along the top, off scale.
pub fn plot_profiles(path: &Path, slices: &[Slice], noise: &NoiseFloor) -> Result<(), InferenceError> {
    ensure_font();
    if slices.is_empty() {
        return Ok(());
    }
    let ln10 = std::f64::consts::LN_10;
    let cols = slices.len().min(2);
    let rows = slices.len().div_ceil(cols);
    let tmp = path.with_extension("png.tmp.png");
    {
        let root = BitMapBackend::new(&tmp, (520 * cols as u32, 380 * rows as u32)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| err(path, e))?;
        let panels = root.split_evenly((rows, cols));
        let threshold = noise.threshold.max(1e-12).log10();
        for (slice, panel) in slices.iter().zip(panels.iter()) {
            let on_scale = |o: Real| o.is_finite() && o <= 100.0 * noise.threshold.max(1e-12);
            let xs: Vec<Real> = slice.offsets.iter().map(|o| o / ln10).collect();
            let ys: Vec<Real> = slice.objectives.iter().map(|o| o.max(1e-12).log10()).collect();
            let mut y_lo = threshold;
            let mut y_hi = threshold;
            for (&y, &o) in ys.iter().zip(&slice.objectives) {
                if on_scale(o) {
                    y_lo = y_lo.min(y);
                    y_hi = y_hi.max(y);
                }
            }
            let (y_lo, y_hi) = padded(y_lo, y_hi);
            let mut x_lo = xs.iter().copied().fold(0.0, Real::min);
            let mut x_hi = xs.iter().copied().fold(0.0, Real::max);
            for side in [slice.lower, slice.upper].into_iter().flatten() {
                x_lo = x_lo.min(side / ln10);
                x_hi = x_hi.max(side / ln10);
            }
            let (x_lo, x_hi) = padded(x_lo, x_hi);
            let open: Vec<&str> = [(slice.lower, "lower"), (slice.upper, "upper")]
                .iter()
                .filter(|(side, _)| side.is_none())
                .map(|(_, name)| *name)
                .collect();
            let title = if open.is_empty() {
                format!("{}: determined", slice.name)
            } else {
                format!("{}: {} side open", slice.name, open.join(" and "))
            };
            let mut chart = ChartBuilder::on(panel)
                .caption(title, ("sans-serif", 16))
                .margin(10)
                .x_label_area_size(36)
                .y_label_area_size(56)
                .build_cartesian_2d(x_lo..x_hi, y_lo..y_hi)
                .map_err(|e| err(path, e))?;
            chart
                .configure_mesh()
                .x_desc(format!("log10({} / best)", slice.name))
                .y_desc("log10 objective")
                .draw()
                .map_err(|e| err(path, e))?;
            let grey = RGBColor(90, 90, 90);
            chart
                .draw_series(DashedLineSeries::new(
                    vec![(x_lo, threshold), (x_hi, threshold)],
                    6,
                    4,
                    grey.stroke_width(2),
                ))
                .map_err(|e| err(path, e))?;
            let green = RGBColor(0, 140, 60);
            for side in [slice.lower, slice.upper].into_iter().flatten() {
                let x = side / ln10;
                chart
                    .draw_series(DashedLineSeries::new(vec![(x, y_lo), (x, y_hi)], 2, 4, green.stroke_width(2)))
                    .map_err(|e| err(path, e))?;
            }
            let top = y_hi - 0.03 * (y_hi - y_lo);
            let mut points: Vec<(Real, Real, Real)> = xs
                .iter()
                .zip(&ys)
                .zip(&slice.objectives)
                .map(|((&x, &y), &o)| (x, y, o))
                .filter(|p| on_scale(p.2))
                .collect();
            points.sort_by(|a, b| a.0.total_cmp(&b.0));
            chart
                .draw_series(LineSeries::new(points.iter().map(|p| (p.0, p.1)), BLUE.stroke_width(1)))
                .map_err(|e| err(path, e))?;
            chart
                .draw_series(points.iter().map(|p| Circle::new((p.0, p.1), 4, BLUE.filled())))
                .map_err(|e| err(path, e))?;
            chart
                .draw_series(
                    xs.iter()
                        .zip(&slice.objectives)
                        .filter(|(_, o)| !on_scale(**o))
                        .map(|(&x, _)| Cross::new((x, top), 6, RED.stroke_width(2))),
                )
                .map_err(|e| err(path, e))?;
        }
        root.present().map_err(|e| err(path, e))?;
    }
    crate::io::replace_with(&tmp, path).map_err(|e| err(path, e))
}

/// A per-cell fit's `tension_histogram.png`: how many interfaces have each tension (mN/m), the
/// refined map (blue) over the direct estimate it started from (grey outline); cell–medium and
/// cell–cell interfaces together.
pub fn plot_tension_histogram(path: &Path, direct: &[Real], refined: &[Real]) -> Result<(), InferenceError> {
    ensure_font();
    let finite = |v: &[Real]| v.iter().copied().filter(|x| x.is_finite()).collect::<Vec<Real>>();
    let (direct, refined) = (finite(direct), finite(refined));
    let all: Vec<Real> = direct.iter().chain(&refined).copied().collect();
    if all.is_empty() {
        return Ok(());
    }
    let (min, max) =
        (all.iter().copied().fold(Real::INFINITY, Real::min), all.iter().copied().fold(Real::NEG_INFINITY, Real::max));
    let pad = if max > min { 0.02 * (max - min) } else { 0.05 * max.abs().max(1e-9) };
    let (lo, hi) = (min - pad, max + pad);
    let bins = ((all.len() as Real / 2.0).sqrt().ceil() as usize * 2).clamp(8, 40);
    let width = (hi - lo) / bins as Real;
    let count = |v: &[Real]| {
        let mut c = vec![0u32; bins];
        for &x in v {
            c[(((x - lo) / width) as usize).min(bins - 1)] += 1;
        }
        c
    };
    let (cd, cr) = (count(&direct), count(&refined));
    let top = cd.iter().chain(&cr).copied().max().unwrap_or(1).max(1);
    let tmp = path.with_extension("png.tmp.png");
    {
        let root = BitMapBackend::new(&tmp, (800, 500)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| err(path, e))?;
        let mut chart = ChartBuilder::on(&root)
            .caption("interface tensions", ("sans-serif", 22))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(50)
            .build_cartesian_2d(lo..lo + width * bins as Real, 0u32..top + 1)
            .map_err(|e| err(path, e))?;
        chart
            .configure_mesh()
            .x_desc("tension (mN/m)")
            .y_desc("interfaces")
            .y_labels((top as usize + 2).min(11))
            .y_label_formatter(&|n| format!("{n}"))
            .light_line_style(WHITE)
            .draw()
            .map_err(|e| err(path, e))?;
        let bar = |i: usize| (lo + i as Real * width, lo + (i + 1) as Real * width);
        let blue = RGBColor(40, 90, 200);
        chart
            .draw_series(cr.iter().enumerate().filter(|(_, n)| **n > 0).map(|(i, &n)| {
                let (a, b) = bar(i);
                Rectangle::new([(a + 0.06 * width, 0), (b - 0.06 * width, n)], blue.mix(0.6).filled())
            }))
            .map_err(|e| err(path, e))?
            .label(format!("refined map ({} interfaces)", refined.len()))
            .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 14, y + 5)], blue.mix(0.6).filled()));
        chart
            .draw_series(cd.iter().enumerate().filter(|(_, n)| **n > 0).map(|(i, &n)| {
                let (a, b) = bar(i);
                Rectangle::new([(a + 0.06 * width, 0), (b - 0.06 * width, n)], BLACK.mix(0.7).stroke_width(2))
            }))
            .map_err(|e| err(path, e))?
            .label(format!("direct estimate ({} interfaces)", direct.len()))
            .legend(|(x, y)| Rectangle::new([(x, y - 5), (x + 14, y + 5)], BLACK.mix(0.7).stroke_width(2)));
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(|e| err(path, e))?;
        root.present().map_err(|e| err(path, e))?;
    }
    crate::io::replace_with(&tmp, path).map_err(|e| err(path, e))
}
