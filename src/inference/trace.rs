//! `trace.csv`: one row per distinct evaluation, in the order the optimiser first asked for it.
//! Floats are written in Rust's shortest round-trip form, so a trace read back gives the exact
//! same points (the `x_*` columns, natural logs of the fitted parameters) and the cache can resume a
//! fit bit for bit.
//!
//! Columns: `evaluation, x_<p>…, <p>… (SI), sphericity, contact_fraction, coordination,
//! contact_angle, shape, objective, status, converged, steps, residual, wall_seconds, elapsed_seconds,
//! reason`. `wall_seconds` is the evaluation's own run; `elapsed_seconds` the fit's wall time (all
//! sessions of a resumed fit) when the row was recorded, so a resumed fit's total wall time goes on
//! from the last row of the sessions before it. Traces written before `elapsed_seconds` existed are
//! read too (the column is then NaN).

use super::InferenceError;
use super::forward::{Evaluation, Metric, Metrics, Status};
use super::space::ParameterSpace;
use crate::geometry::Real;
use std::io::Write;
use std::path::Path;

/// The header of a trace for this space.
pub fn header(space: &ParameterSpace) -> Vec<String> {
    let mut h = vec!["evaluation".to_string()];
    h.extend(space.fitted.iter().map(|p| format!("x_{}", p.name())));
    h.extend(space.fitted.iter().map(|p| p.name().to_string()));
    h.extend(Metrics::NAMES.iter().map(|s| s.to_string()));
    h.extend(
        ["objective", "status", "converged", "steps", "residual", "wall_seconds", "elapsed_seconds", "reason"]
            .iter()
            .map(|s| s.to_string()),
    );
    h
}

fn opt(v: Option<Real>) -> String {
    v.map_or(String::new(), |v| v.to_string())
}

/// Writes the whole trace (atomically).
pub fn write_trace(path: &Path, space: &ParameterSpace, evaluations: &[Evaluation]) -> Result<(), InferenceError> {
    let mut buf = Vec::new();
    {
        let mut w = csv::Writer::from_writer(&mut buf);
        let io = |e: csv::Error| InferenceError::Output(format!("{}: {e}", path.display()));
        w.write_record(header(space)).map_err(io)?;
        for (i, e) in evaluations.iter().enumerate() {
            let mut row = vec![i.to_string()];
            row.extend(e.x.iter().map(|v| v.to_string()));
            row.extend(e.x.iter().map(|v| v.exp().to_string()));
            row.extend(e.metrics.values().iter().map(|v| opt(*v)));
            row.push(e.objective.to_string());
            row.push(e.status.name().to_string());
            row.push((e.status == Status::Converged).to_string());
            row.push(e.steps.to_string());
            row.push(e.residual.to_string());
            row.push(e.wall_seconds.to_string());
            row.push(e.elapsed_seconds.to_string());
            row.push(e.reason.clone());
            w.write_record(&row).map_err(io)?;
        }
        w.flush().map_err(|e| InferenceError::Output(format!("{}: {e}", path.display())))?;
    }
    crate::io::write_atomically(path, |w| w.write_all(&buf)).map_err(|e| InferenceError::Output(e.to_string()))
}

/// Reads a trace written for the same parameter space (resumption).
pub fn read_trace(path: &Path, space: &ParameterSpace) -> Result<Vec<Evaluation>, InferenceError> {
    let bad = |msg: String| InferenceError::Resume(format!("{}: {msg}", path.display()));
    let mut r = csv::Reader::from_path(path).map_err(|e| bad(e.to_string()))?;
    let expected = header(space);
    let found: Vec<String> = r.headers().map_err(|e| bad(e.to_string()))?.iter().map(str::to_string).collect();
    // A trace of an earlier version has no elapsed_seconds column.
    let without_elapsed: Vec<String> = expected.iter().filter(|c| *c != "elapsed_seconds").cloned().collect();
    let has_elapsed = found != without_elapsed;
    if has_elapsed && found != expected {
        return Err(bad(format!(
            "its columns ({}) do not match this fit's ({}); was it written by another config?",
            found.join(","),
            expected.join(",")
        )));
    }
    let n = space.dim();
    let parse = |s: &str, what: &str, row: usize| -> Result<Real, InferenceError> {
        s.parse::<Real>().map_err(|_| bad(format!("row {row}: {what} `{s}` is not a number")))
    };
    let mut out = Vec::new();
    for (row, rec) in r.records().enumerate() {
        let rec = rec.map_err(|e| bad(e.to_string()))?;
        let x = (0..n).map(|i| parse(&rec[1 + i], &expected[1 + i], row)).collect::<Result<Vec<_>, _>>()?;
        let m0 = 1 + 2 * n;
        let mut metrics = Metrics::default();
        for (k, m) in Metric::ALL.into_iter().enumerate() {
            let s = &rec[m0 + k];
            *metrics.get_mut(m) = if s.is_empty() { None } else { Some(parse(s, m.name(), row)?) };
        }
        let o = m0 + Metric::ALL.len();
        let status = Status::from_name(&rec[o + 1])
            .ok_or_else(|| bad(format!("row {row}: unknown status `{}`", &rec[o + 1])))?;
        out.push(Evaluation {
            x,
            metrics,
            objective: parse(&rec[o], "objective", row)?,
            status,
            steps: rec[o + 3].parse().map_err(|_| bad(format!("row {row}: steps `{}`", &rec[o + 3])))?,
            residual: parse(&rec[o + 4], "residual", row)?,
            wall_seconds: parse(&rec[o + 5], "wall_seconds", row)?,
            elapsed_seconds: if has_elapsed { parse(&rec[o + 6], "elapsed_seconds", row)? } else { Real::NAN },
            reason: rec[o + if has_elapsed { 7 } else { 6 }].to_string(),
        });
    }
    Ok(out)
}

/// The fit's wall time recorded in a trace (its latest `elapsed_seconds`): what the sessions that
/// wrote it had spent, up to their last recorded evaluation. 0 for an unreadable trace or one
/// without the column.
pub fn recorded_elapsed_seconds(path: &Path) -> Real {
    let Ok(mut r) = csv::Reader::from_path(path) else { return 0.0 };
    let Some(column) = r.headers().ok().and_then(|h| h.iter().position(|c| c == "elapsed_seconds")) else {
        return 0.0;
    };
    r.records()
        .flatten()
        .filter_map(|rec| rec.get(column)?.parse::<Real>().ok())
        .filter(|s| s.is_finite())
        .fold(0.0, Real::max)
}
