//! Entry points of the fuzz targets (`fuzz/`, cargo-fuzz) and of their stable replay
//! (`tests/integration/fuzz_replay.rs`): one function per parser of user files, taking the raw bytes. Each
//! returns `Ok` when the parser returned a result that holds its invariants or an error that names
//! the file, and `Err` with what is wrong otherwise; a panic is a bug in the parser. Nothing is
//! written to disk, so a fuzzer runs them at full speed.

use crate::imaging::{LabelReadOptions, read_label_tiff_bytes};
use crate::inference::FitConfig;
use crate::io::{ReadOptions, read_tissue_bytes};
use crate::mechanics::Parameters;
use crate::pipeline::PipelineConfig;
use std::path::Path;

/// The name every input is given; errors must contain it.
pub const FUZZ_FILE_STEM: &str = "fuzzed";

/// `Ok` when `message` names the file, else `Err` quoting it.
fn names_file(message: &str) -> Result<(), String> {
    if message.contains(FUZZ_FILE_STEM) { Ok(()) } else { Err(format!("an error does not name the file: {message}")) }
}

/// A label TIFF ([`crate::imaging::read_label_tiff`]): a volume read is non-empty and finitely sized.
pub fn label_tiff(bytes: &[u8]) -> Result<(), String> {
    let path = Path::new("fuzzed.tif");
    match read_label_tiff_bytes(bytes, path, &LabelReadOptions::default()) {
        Ok(read) => {
            let volume = &read.volume;
            if volume.labels().is_empty() || !volume.voxel_size().iter().all(|s| s.is_finite() && *s > 0.0) {
                return Err(format!(
                    "read an invalid volume: shape {:?}, voxel size {:?}",
                    volume.shape(),
                    volume.voxel_size()
                ));
            }
            Ok(())
        }
        Err(e) => names_file(&e.to_string()),
    }
}

/// A tissue file ([`crate::io::read_tissue`]) with the extension `ext` (`vtk` or `vtp`), which picks
/// the parser as for a file: what is read has finite coordinates.
pub fn tissue(bytes: &[u8], ext: &str) -> Result<(), String> {
    let path = Path::new(FUZZ_FILE_STEM).with_extension(ext);
    match read_tissue_bytes(&path, bytes, &ReadOptions::default()) {
        Ok(report) => {
            for cell in report.tissue.cells() {
                if !cell.mesh().positions().iter().all(|p| p.iter().all(|v| v.is_finite())) {
                    return Err(format!("cell {} has a non-finite coordinate", cell.id()));
                }
                // Mesh defects are reported by the checker, not fatal: it must not panic either.
                let _ = cell.mesh().validate();
            }
            Ok(())
        }
        Err(e) => names_file(&e.to_string()),
    }
}

/// A model parameter file ([`Parameters::from_toml_str`]): what parses has a usable time step and
/// edge length.
pub fn params(bytes: &[u8]) -> Result<(), String> {
    let text = String::from_utf8_lossy(bytes);
    match Parameters::from_toml_str(&text, "fuzzed.toml") {
        Ok(p) => {
            let (dt, l) = (p.numerics.time_step, p.numerics.min_edge_length);
            if !(dt.is_finite() && dt > 0.0 && l.is_finite() && l > 0.0) {
                return Err(format!("accepted time_step {dt} and min_edge_length {l}"));
            }
            Ok(())
        }
        Err(e) => names_file(&e.to_string()),
    }
}

/// A pipeline file ([`PipelineConfig::from_toml_str`]; paths as written, inputs not opened).
pub fn pipeline(bytes: &[u8]) -> Result<(), String> {
    let text = String::from_utf8_lossy(bytes);
    match PipelineConfig::from_toml_str(&text, Path::new("fuzzed.toml")) {
        Ok(_) => Ok(()),
        Err(e) => names_file(&e.to_string()),
    }
}

/// A fit configuration ([`FitConfig::from_toml_str`]).
pub fn fit_config(bytes: &[u8]) -> Result<(), String> {
    let text = String::from_utf8_lossy(bytes);
    match FitConfig::from_toml_str(&text, "fuzzed.toml") {
        Ok(_) => Ok(()),
        Err(e) => names_file(&e.to_string()),
    }
}

/// A simulation checkpoint ([`crate::io::decode_checkpoint`], then what `simulate --resume` does with
/// it: the saved parameters parsed and the state restored by [`crate::mechanics::Simulation::restore`]).
///
/// Bytes that begin with the checkpoint magic are read as a file. Others are taken as the payload
/// and framed with a valid header and checksum first ([`crate::io::frame_checkpoint`]), so that
/// mutations reach the decoder and the restore, which a byte mutation of a whole file almost never
/// does past the checksum.
pub fn checkpoint(bytes: &[u8]) -> Result<(), String> {
    use crate::io::{decode_checkpoint, frame_checkpoint, is_checkpoint};
    let framed;
    let file = if is_checkpoint(bytes) {
        bytes
    } else {
        framed = frame_checkpoint(bytes);
        &framed
    };
    let path = Path::new("fuzzed.ckpt");
    let (info, state) = match decode_checkpoint(file, path) {
        Ok(read) => read,
        Err(e) => return names_file(&e.to_string()),
    };
    let Ok(params) = Parameters::from_toml_str(&info.parameters, "fuzzed.ckpt") else {
        return Ok(());
    };
    if params.validate().is_err() {
        return Ok(());
    }
    // A restored simulation evaluates its forces once; the state must be refused or made whole.
    let _ = crate::mechanics::Simulation::restore(state, &params);
    Ok(())
}

/// Length units ([`crate::io::LengthScale`] and [`crate::io::parse_lengths`], the `--units`,
/// `--voxel-size` and `units`/`voxel_size` keys): what parses is finite and positive.
pub fn units(bytes: &[u8]) -> Result<(), String> {
    let text = String::from_utf8_lossy(bytes);
    if let Ok(lengths) = crate::io::parse_lengths(&text)
        && let Some(bad) = lengths.iter().find(|l| !(l.is_finite() && **l > 0.0))
    {
        return Err(format!("parse_lengths accepted {bad} from {text:?}"));
    }
    if let Ok(scale) = text.parse::<crate::io::LengthScale>()
        && !scale.0.iter().all(|l| l.is_finite() && *l > 0.0)
    {
        return Err(format!("LengthScale accepted {:?} from {text:?}", scale.0));
    }
    Ok(())
}

/// One entry point: the bytes in, `Err` with what is wrong out.
pub type Target = fn(&[u8]) -> Result<(), String>;

/// The targets by name (the names of `fuzz/fuzz_targets/*.rs` and `fuzz/corpus/*/`).
pub const TARGETS: &[(&str, Target)] = &[
    ("label_tiff", label_tiff),
    ("vtk", |b| tissue(b, "vtk")),
    ("vtp", |b| tissue(b, "vtp")),
    ("params", params),
    ("pipeline", pipeline),
    ("fit_config", fit_config),
    ("checkpoint", checkpoint),
    ("units", units),
];
