//! Plots of a sweep's results (plotters, the embedded font): one PNG per numeric output column in
//! `DIR/plots/`. Keys that take the same values in every run (one value set on several face types)
//! make one axis, and keys that never change make none. One axis: the output against it (line and
//! points). Two: every run at its two
//! values, coloured by the output, the value written beside it. A key whose values are all positive
//! numbers spanning more than a decade is drawn on a log10 axis; non-numeric values (strings, booleans)
//! are placed at their position among the distinct values. Failed or missing outputs are left out.

use super::PipelineError;
use super::sweep::{ResultRow, Sweep, show_value};
use crate::files::ensure_font;
use plotters::prelude::*;
use std::path::{Path, PathBuf};
use toml::Value;

fn err(path: &Path, e: impl std::fmt::Display) -> PipelineError {
    PipelineError::Io { path: path.to_path_buf(), message: format!("plotting: {e}") }
}

/// How one swept key maps to an axis coordinate.
struct Axis {
    label: String,
    /// Per run: the coordinate, `None` when the run leaves the key at the base's value.
    coords: Vec<Option<f64>>,
    /// Tick labels of a categorical axis (coordinate i ↔ label i).
    categories: Option<Vec<String>>,
}

fn number(v: &Value) -> Option<f64> {
    match v {
        Value::Integer(i) => Some(*i as f64),
        Value::Float(f) => Some(*f),
        _ => None,
    }
}

fn axis(sweep: &Sweep, k: usize) -> Axis {
    let key = &sweep.keys[k];
    let values: Vec<Option<&Value>> = sweep.runs.iter().map(|r| r.values[k].as_ref()).collect();
    let numbers: Vec<Option<f64>> = values.iter().map(|v| v.and_then(number)).collect();
    if values.iter().flatten().all(|v| number(v).is_some()) {
        let present: Vec<f64> = numbers.iter().flatten().copied().collect();
        let (lo, hi) = present.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| (a.min(x), b.max(x)));
        if lo > 0.0 && hi / lo > 10.0 {
            let coords = numbers.iter().map(|x| x.map(f64::log10)).collect();
            return Axis { label: format!("log10 {key}"), coords, categories: None };
        }
        return Axis { label: key.clone(), coords: numbers, categories: None };
    }
    let mut categories: Vec<String> = Vec::new();
    let coords = values
        .iter()
        .map(|v| {
            v.map(|v| {
                let s = show_value(v);
                let i = categories.iter().position(|c| *c == s).unwrap_or_else(|| {
                    categories.push(s);
                    categories.len() - 1
                });
                i as f64
            })
        })
        .collect();
    Axis { label: key.clone(), coords, categories: Some(categories) }
}

fn range(xs: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = xs.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| (a.min(x), b.max(x)));
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    let pad = if hi > lo { 0.08 * (hi - lo) } else { 0.5 * lo.abs().max(1e-30) };
    (lo - pad, hi + pad)
}

fn file_name(column: &str) -> String {
    let s: String = column.chars().map(|c| if c.is_ascii_alphanumeric() { c } else { '_' }).collect();
    format!("{}.png", s.trim_matches('_'))
}

fn tick(a: &Axis, x: f64) -> String {
    match &a.categories {
        Some(c) => {
            let i = x.round();
            if (x - i).abs() < 1e-6 && i >= 0.0 {
                c.get(i as usize).cloned().unwrap_or_default()
            } else {
                String::new()
            }
        }
        None => compact(x),
    }
}

/// A tick label: plain decimals for 0.01 ≤ |x| < 10⁵ (4 significant digits, trailing zeros dropped),
/// else scientific.
fn compact(x: f64) -> String {
    let a = x.abs();
    if x == 0.0 {
        return "0".into();
    }
    if !(0.01..1e5).contains(&a) {
        return format!("{x:.2e}");
    }
    let decimals = (3 - a.log10().floor() as i32).max(0) as usize;
    let s = format!("{x:.decimals$}");
    if s.contains('.') { s.trim_end_matches('0').trim_end_matches('.').to_string() } else { s }
}

/// The swept keys that make the plot axes, by index: a key that takes the same values as an earlier
/// one in every run (linked keys, e.g. one tension set on three face types) adds no axis, nor does a key
/// with one value in every run while another key varies.
fn axis_keys(sweep: &Sweep) -> Vec<usize> {
    let values =
        |k: usize| -> Vec<Option<String>> { sweep.runs.iter().map(|r| r.values[k].as_ref().map(show_value)).collect() };
    let varies = |v: &[Option<String>]| v.iter().any(|x| *x != v[0]);
    let all: Vec<Vec<Option<String>>> = (0..sweep.keys.len()).map(values).collect();
    let any_varies = all.iter().any(|v| varies(v));
    let mut keys: Vec<usize> = Vec::new();
    for (k, v) in all.iter().enumerate() {
        if (any_varies && !varies(v)) || keys.iter().any(|&j| all[j] == *v) {
            continue;
        }
        keys.push(k);
    }
    keys
}

/// Writes `DIR/plots/<column>.png` for every numeric output column, with one or two swept axes
/// ([`axis_keys`]: linked and constant keys count once or not at all); returns the files written (none
/// for three axes or more).
pub fn plot_results(sweep: &Sweep, rows: &[ResultRow], out: &Path) -> Result<Vec<PathBuf>, PipelineError> {
    let keys = axis_keys(sweep);
    if keys.is_empty() || keys.len() > 2 {
        return Ok(Vec::new());
    }
    ensure_font();
    let dir = out.join("plots");
    std::fs::create_dir_all(&dir).map_err(|e| err(&dir, e))?;
    let axes: Vec<Axis> = keys.iter().map(|&k| axis(sweep, k)).collect();
    let mut written = Vec::new();
    for (c, column) in sweep.columns.iter().enumerate() {
        let name = column.name();
        // (x, y, output) of the runs that have every coordinate and a numeric output.
        let points: Vec<(f64, f64, f64)> = rows
            .iter()
            .filter_map(|r| {
                let v = r.outputs[c].as_ref()?;
                let o = v.as_f64().or_else(|| v.as_bool().map(|b| if b { 1.0 } else { 0.0 }))?;
                let x = axes[0].coords[r.index]?;
                let y = if axes.len() == 2 { axes[1].coords[r.index]? } else { o };
                Some((x, y, o))
            })
            .collect();
        if points.is_empty() {
            continue;
        }
        let path = dir.join(file_name(&name));
        let tmp = path.with_extension("png.tmp.png");
        {
            let root = BitMapBackend::new(&tmp, (800, 600)).into_drawing_area();
            root.fill(&WHITE).map_err(|e| err(&path, e))?;
            let xr = range(points.iter().map(|p| p.0));
            let yr = range(points.iter().map(|p| p.1));
            let (omin, omax) =
                points.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| (a.min(p.2), b.max(p.2)));
            let caption =
                if axes.len() == 1 { name.clone() } else { format!("{name}: {omin:.4} (blue) … {omax:.4} (yellow)") };
            let mut chart = ChartBuilder::on(&root)
                .caption(caption, ("sans-serif", 16))
                .margin(14)
                .x_label_area_size(45)
                .y_label_area_size(85)
                .build_cartesian_2d(xr.0..xr.1, yr.0..yr.1)
                .map_err(|e| err(&path, e))?;
            let (ax, ay) = (&axes[0], axes.get(1));
            let ylabel = ay.map_or(name.clone(), |a| a.label.clone());
            chart
                .configure_mesh()
                .x_desc(ax.label.clone())
                .y_desc(ylabel)
                .x_label_formatter(&|x| tick(ax, *x))
                .y_label_formatter(&|y| ay.map_or(compact(*y), |a| tick(a, *y)))
                .draw()
                .map_err(|e| err(&path, e))?;
            if axes.len() == 1 {
                let mut line = points.iter().map(|p| (p.0, p.1)).collect::<Vec<_>>();
                line.sort_by(|a, b| a.0.total_cmp(&b.0));
                chart.draw_series(LineSeries::new(line, BLUE.stroke_width(2))).map_err(|e| err(&path, e))?;
                chart
                    .draw_series(points.iter().map(|p| Circle::new((p.0, p.1), 5, BLUE.filled())))
                    .map_err(|e| err(&path, e))?;
            } else {
                let colour = |o: f64| {
                    let t = if omax > omin { (o - omin) / (omax - omin) } else { 0.0 };
                    HSLColor(0.66 - 0.5 * t, 0.9, 0.3 + 0.35 * t)
                };
                chart
                    .draw_series(points.iter().map(|p| Circle::new((p.0, p.1), 14, colour(p.2).filled())))
                    .map_err(|e| err(&path, e))?;
                chart
                    .draw_series(points.iter().map(|p| {
                        Text::new(format!("{:.4}", p.2), (p.0, p.1), ("sans-serif", 14).into_font().color(&BLACK))
                    }))
                    .map_err(|e| err(&path, e))?;
            }
            root.present().map_err(|e| err(&path, e))?;
        }
        crate::io::replace_with(&tmp, &path).map_err(|e| err(&path, e))?;
        written.push(path);
    }
    Ok(written)
}
