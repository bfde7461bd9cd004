//! PNG plots of a fit (plotters, bitmap backend, DejaVu Sans embedded — no system fonts):
//! `objective.png` (log10 objective per evaluation, with the best so far) and `landscape.png` (every
//! evaluated point over the two first fitted parameters, log10 axes, coloured by log10 objective;
//! with one fitted parameter, the objective against it).

use super::InferenceError;
use super::forward::Evaluation;
use super::space::ParameterSpace;
use crate::geometry::Real;
use plotters::prelude::*;
use plotters::style::{FontStyle, register_font};
use std::path::Path;
use std::sync::Once;

static FONT: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");
static REGISTER: Once = Once::new();

/// Registers the embedded font as "sans-serif" (once per process).
pub(crate) fn ensure_font() {
    REGISTER.call_once(|| {
        // The embedded file is a valid TrueType font; a failure would only lose the labels.
        if register_font("sans-serif", FontStyle::Normal, FONT).is_err() {
            tracing::warn!("could not register the embedded font; plots will lack text");
        }
    });
}

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

/// Objective (log10) per evaluation, and the best so far.
pub fn plot_objective(path: &Path, trace: &[Evaluation]) -> Result<(), InferenceError> {
    ensure_font();
    if trace.is_empty() {
        return Ok(());
    }
    let tmp = path.with_extension("png.tmp.png");
    {
        let root = BitMapBackend::new(&tmp, (800, 500)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| err(path, e))?;
        let ys: Vec<Real> = trace.iter().map(log10_objective).collect();
        let (lo, hi) = padded(
            ys.iter().copied().fold(Real::INFINITY, Real::min),
            ys.iter().copied().fold(Real::NEG_INFINITY, Real::max),
        );
        let mut chart = ChartBuilder::on(&root)
            .caption("objective per evaluation", ("sans-serif", 22))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(0.0..(trace.len() as Real).max(1.0), lo..hi)
            .map_err(|e| err(path, e))?;
        chart.configure_mesh().x_desc("evaluation").y_desc("log10 objective").draw().map_err(|e| err(path, e))?;
        chart
            .draw_series(ys.iter().enumerate().map(|(i, &y)| Circle::new((i as Real, y), 3, BLUE.filled())))
            .map_err(|e| err(path, e))?
            .label("evaluation")
            .legend(|(x, y)| Circle::new((x, y), 3, BLUE.filled()));
        let mut best = Real::INFINITY;
        let running: Vec<(Real, Real)> = ys
            .iter()
            .enumerate()
            .map(|(i, &y)| {
                best = best.min(y);
                (i as Real, best)
            })
            .collect();
        chart
            .draw_series(LineSeries::new(running, RED.stroke_width(2)))
            .map_err(|e| err(path, e))?
            .label("best so far")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], RED.stroke_width(2)));
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
    let (omin, omax) = (
        objs.iter().copied().fold(Real::INFINITY, Real::min),
        objs.iter().copied().fold(Real::NEG_INFINITY, Real::max),
    );
    let colour = |o: Real| {
        let t = if omax > omin { (o - omin) / (omax - omin) } else { 0.0 };
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
            ("log10 objective".to_string(), padded(omin, omax), objs.clone())
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
        chart
            .draw_series(
                trace
                    .iter()
                    .zip(&ys)
                    .zip(&objs)
                    .map(|((e, &y), &o)| Circle::new((e.x[0] / ln10, y), 5, colour(o).filled())),
            )
            .map_err(|e| err(path, e))?;
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
