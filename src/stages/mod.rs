//! The stages as library functions: typed options in, files and a typed report out. The CLI
//! subcommands (`tissuefit mesh`, `tissuefit measure`) and the pipeline (`tissuefit run`) both call
//! these, so the same settings give the same files whichever way a stage is run, except the
//! wall-time fields (`wall_seconds`, `threads`).
//!
//! Layering: `io ← {inference, render} ← stages ← pipeline ← cli`.

pub mod fit;
pub mod fit_series;
pub mod measure;
pub mod mesh;
pub mod model_tables;
pub mod output_unit;
pub mod simulate;
pub mod tensions;

use crate::io::OutputGroup;
use serde::Serialize;
use std::path::Path;

/// A stage that failed; the message names the file or setting and what to do.
#[derive(Debug, thiserror::Error)]
#[error("{message}")]
pub struct StageError {
    /// `mesh`, `measure`, …
    pub stage: &'static str,
    pub message: String,
}

impl StageError {
    pub(crate) fn new(stage: &'static str, message: impl Into<String>) -> Self {
        Self { stage, message: message.into() }
    }
}

/// How far a map picture pulls cells apart (see [`crate::render::RenderOptions::explode`]): enough to
/// show the faces between cells of a small cluster.
pub const MAP_EXPLODE: crate::geometry::Real = 0.6;

/// A map picture: `tissue` from the iso view, exploded by [`MAP_EXPLODE`] so that the interfaces
/// between cells show, faces coloured by `values` (one per triangle, cells in order; NaN grey) with a
/// colour bar titled `label`, as PNG bytes (`tensions.png`, a per-cell fit's `map.png`).
pub(crate) fn map_png(
    tissue: &crate::mesh::Tissue,
    values: Vec<crate::geometry::Real>,
    label: &str,
) -> Result<Vec<u8>, String> {
    use crate::render::{ColorBy, FaceScalars, RenderOptions, png_bytes, render_tissue};
    let (range, label) = match robust_range(&values) {
        Some((lo, hi)) => (Some((lo, hi)), format!("{label}, clipped 2–98 %")),
        None => (None, label.to_owned()),
    };
    let options = RenderOptions {
        width: 900,
        height: 700,
        color_by: ColorBy::Tension,
        scalars: Some(FaceScalars { label, values, range }),
        explode: MAP_EXPLODE,
        ..RenderOptions::default()
    };
    let img = render_tissue(tissue, &options).map_err(|e| e.to_string())?;
    png_bytes(&img)
}

/// The colour range of a map picture when a few outliers would wash out the rest: the 2nd–98th
/// percentile of the faces' finite values where it spans less than half of their whole range (a real
/// crop with one interface at 16 × the median); `None` otherwise (the whole range).
fn robust_range(values: &[crate::geometry::Real]) -> Option<(crate::geometry::Real, crate::geometry::Real)> {
    let mut finite: Vec<crate::geometry::Real> = values.iter().copied().filter(|v| v.is_finite()).collect();
    if finite.len() < 50 {
        return None;
    }
    finite.sort_by(|a, b| a.total_cmp(b));
    let at = |q: f64| finite[((finite.len() - 1) as f64 * q).round() as usize];
    let (lo, hi, min, max) = (at(0.02), at(0.98), finite[0], finite[finite.len() - 1]);
    (hi > lo && hi - lo < 0.5 * (max - min)).then_some((lo, hi))
}

/// Writes rows under a header of `T`'s serde field names, in field order; the header comes from
/// `example` (not written) so that a file without rows still has its columns (pandas reads it).
pub fn write_csv<T: Serialize>(
    group: &mut OutputGroup,
    path: &Path,
    rows: &[T],
    example: &T,
) -> Result<(), crate::io::FileError> {
    write_csv_renamed(group, path, rows, example, &|name| name.to_string())
}

/// [`write_csv`] with each column of the header renamed by `rename` (e.g. `volume` → `volume_um3`
/// for rows in µm).
pub fn write_csv_renamed<T: Serialize>(
    group: &mut OutputGroup,
    path: &Path,
    rows: &[T],
    example: &T,
    rename: &dyn Fn(&str) -> String,
) -> Result<(), crate::io::FileError> {
    group.write(path, |w| {
        let mut header = csv::Writer::from_writer(Vec::new());
        header.serialize(example).map_err(std::io::Error::other)?;
        let bytes = header.into_inner().map_err(|e| e.into_error())?;
        let first_line = bytes.split(|&b| b == b'\n').next().unwrap_or_default();
        let mut names = csv::ReaderBuilder::new().has_headers(false).from_reader(first_line);
        let names = names.records().next().transpose().map_err(std::io::Error::other)?.unwrap_or_default();
        let mut header = csv::Writer::from_writer(&mut *w);
        header.write_record(names.iter().map(rename)).map_err(std::io::Error::other)?;
        header.flush()?;
        drop(header);
        let mut csv = csv::WriterBuilder::new().has_headers(false).from_writer(&mut *w);
        for row in rows {
            csv.serialize(row).map_err(std::io::Error::other)?;
        }
        csv.flush()
    })
}

/// Writes `value` as pretty JSON with a final newline.
pub fn write_json<T: Serialize>(group: &mut OutputGroup, path: &Path, value: &T) -> Result<(), crate::io::FileError> {
    group.write(path, |w| {
        serde_json::to_writer_pretty(&mut *w, value).map_err(std::io::Error::other)?;
        std::io::Write::write_all(w, b"\n")
    })
}

#[cfg(test)]
mod tests {
    use super::robust_range;

    #[test]
    fn a_map_picture_clips_its_colours_only_where_a_few_outliers_would_wash_out_the_rest() {
        let spread: Vec<f64> = (0..100).map(|i| 0.5 + i as f64 / 100.0).collect();
        assert_eq!(robust_range(&spread), None);
        let mut outliers = spread.clone();
        outliers[3] = 16.0;
        outliers[7] = f64::NAN;
        let (lo, hi) = robust_range(&outliers).unwrap();
        assert!((0.5..0.6).contains(&lo) && (1.4..1.5).contains(&hi), "{lo}..{hi}");
        assert_eq!(robust_range(&outliers[..40]), None, "too few faces to judge");
    }
}
