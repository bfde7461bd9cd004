//! What `tissuefit simulate` writes into its output folder:
//!
//! * `frames/frame_NNNNNN.vtp` + `frames.pvd`: the ParaView series, one frame per sample, with the
//!   per-cell pressure and growth rate as cell data;
//! * `stats.csv`: one row per cell per sample (step, time, cell, kind, volume, target volume, area,
//!   pressure, each energy term, and the `parent` the cell was born from by division, empty for
//!   founders); the number of cells may change from sample to sample (divisions, removals); written as `stats.csv.partial` during the run and renamed when the
//!   run ends, so a crashed run never leaves a file that looks complete;
//! * `final.vtk` (SimuCell3D legacy, re-readable as input) and `summary.json`, written by the caller
//!   at the end.
//!
//! With an [`OutputUnit`] other than metres the frames are written in it (recorded in each frame, see
//! [`super::write_vtp_in`]; the growth rate in unit³/s) and the `volume`, `target_volume` and `area`
//! columns of `stats.csv` become `volume_um3`, `target_volume_um3`, `area_um2`; energies, pressures and
//! times stay SI.

use super::{CellField, IoError, OutputUnit, PvdEntry, write_pvd, write_vtp_in};
use crate::geometry::Real;
use crate::mechanics::{EnergyTerms, Observer, Sample};
use std::fs::File;
use std::io::{BufWriter, Seek, Write};
use std::path::{Path, PathBuf};

/// Records samples of a simulation into an output folder.
pub struct SimulationRecorder {
    dir: PathBuf,
    frames: Vec<PvdEntry>,
    stats: BufWriter<File>,
    /// Label of each frame's time: simulated time, or the step for relaxations without time.
    time_is_step: bool,
    /// Length unit of the frames and of `stats.csv`.
    unit: OutputUnit,
}

/// The header of `stats.csv` with lengths in `unit`.
fn stats_header(unit: OutputUnit) -> String {
    format!(
        "step,time,cell,kind,cell_type,nodes,{},{},{},pressure,{},energy_total,parent",
        unit.column("volume", 3),
        unit.column("target_volume", 3),
        unit.column("area", 2),
        EnergyTerms::NAMES.map(|n| format!("energy_{n}")).join(",")
    )
}

impl SimulationRecorder {
    /// Creates `dir/frames/` and starts `dir/stats.csv.partial`. `time_is_step`: label frames by step
    /// (FIRE relaxations have no physical time); `unit`: of the frames' and statistics' lengths.
    pub fn create(dir: &Path, time_is_step: bool, unit: OutputUnit) -> Result<Self, IoError> {
        let frames_dir = dir.join("frames");
        std::fs::create_dir_all(&frames_dir).map_err(|source| IoError::Write { path: frames_dir.clone(), source })?;
        let partial = dir.join("stats.csv.partial");
        super::check_target("output", &partial)?;
        let file = File::create(&partial).map_err(|source| IoError::Write { path: partial.clone(), source })?;
        let mut stats = BufWriter::new(file);
        writeln!(stats, "{}", stats_header(unit)).map_err(|source| IoError::Write { path: partial, source })?;
        Ok(Self { dir: dir.to_path_buf(), frames: Vec::new(), stats, time_is_step, unit })
    }

    fn write_sample(&mut self, s: &Sample<'_>) -> Result<(), IoError> {
        let pressure: Vec<Real> = s.forces.cells.iter().map(|w| w.pressure).collect();
        // Lineage as a number for ParaView: the parent's id, −1 for founders.
        let parent: Vec<Real> = s.tissue.cells().iter().map(|c| c.parent().map_or(-1.0, |p| Real::from(p.0))).collect();
        let name = format!("frame_{:06}.vtp", self.frames.len());
        let label = if self.time_is_step { s.step as Real } else { s.time };
        let path = self.dir.join("frames").join(&name);
        let (l3, l2) = (self.unit.factor(3), self.unit.factor(2));
        let growth_rates: Vec<Real> = s.growth_rates.iter().map(|g| g * l3).collect();
        write_vtp_in(
            &path,
            s.tissue,
            &[
                CellField { name: "pressure", values: &pressure },
                CellField { name: "growth_rate", values: &growth_rates },
                CellField { name: "parent", values: &parent },
            ],
            Some(label),
            self.unit,
        )?;
        self.frames.push(PvdEntry { time: label, file: Path::new("frames").join(name) });
        write_pvd(&self.dir.join("frames.pvd"), &self.frames)?;

        let partial = self.dir.join("stats.csv.partial");
        let io = |source| IoError::Write { path: partial.clone(), source };
        for (cell, work) in s.tissue.cells().iter().zip(&s.forces.cells) {
            let e = work.energy;
            write!(
                self.stats,
                "{},{:e},{},{},{},{},{:e},{:e},{:e},{:e}",
                s.step,
                s.time,
                cell.id(),
                cell.kind().name(),
                cell.cell_type(),
                cell.mesh().node_count(),
                work.geometry.volume * l3,
                cell.target_volume() * l3,
                work.geometry.area * l2,
                work.pressure
            )
            .map_err(io)?;
            for v in e.values() {
                write!(self.stats, ",{v:e}").map_err(io)?;
            }
            let parent = cell.parent().map(|p| p.to_string()).unwrap_or_default();
            writeln!(self.stats, ",{:e},{parent}", e.total()).map_err(io)?;
        }
        Ok(())
    }

    /// Continues the outputs of a checkpointed run in `dir`: the series holds the saved frames, and
    /// `stats.csv.partial` is cut back to the saved length (rows a killed run wrote after the
    /// checkpoint are dropped; the resumed run writes them again, identically), and the temporaries
    /// of files a killed run was writing are removed. The run's length unit is its `stats.csv`
    /// header's; a different `unit` asked for is an error (one series never mixes units).
    pub fn resume(
        dir: &Path,
        time_is_step: bool,
        state: &super::OutputState,
        unit: Option<OutputUnit>,
    ) -> Result<Self, IoError> {
        super::remove_stale_temporaries(dir)?;
        super::remove_stale_temporaries(&dir.join("frames"))?;
        let partial = dir.join("stats.csv.partial");
        let io = |source| IoError::Write { path: partial.clone(), source };
        let mut file = std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .open(&partial)
            .map_err(|source| IoError::Open { path: partial.clone(), source })?;
        let mut first_line = String::new();
        std::io::BufRead::read_line(&mut std::io::BufReader::new(&file), &mut first_line).map_err(io)?;
        let found = [OutputUnit::Metre, OutputUnit::Micrometre]
            .into_iter()
            .find(|u| first_line.trim_end() == stats_header(*u))
            .ok_or_else(|| IoError::Unsupported {
                path: partial.clone(),
                message: "its header is not that of a tissuefit simulation's statistics".into(),
            })?;
        if let Some(asked) = unit
            && asked != found
        {
            return Err(IoError::Unsupported {
                path: partial.clone(),
                message: format!(
                    "the run's outputs are in {found}, not {asked}: resume it in {found} (--output-unit {found}), \
                     or start a new run"
                ),
            });
        }
        let unit = found;
        let len = file.metadata().map_err(io)?.len();
        if len < state.stats_bytes {
            return Err(IoError::Unsupported {
                path: partial.clone(),
                message: format!(
                    "holds {len} bytes but the checkpoint recorded {}: the statistics were truncated or replaced",
                    state.stats_bytes
                ),
            });
        }
        file.set_len(state.stats_bytes).map_err(io)?;
        file.seek(std::io::SeekFrom::End(0)).map_err(io)?;
        let frames =
            state.frames.iter().map(|(time, file)| PvdEntry { time: *time, file: PathBuf::from(file) }).collect();
        Ok(Self { dir: dir.to_path_buf(), frames, stats: BufWriter::new(file), time_is_step, unit })
    }

    /// What has been written so far, for a checkpoint; flushes the statistics to disk first, so
    /// every byte the state counts is stored.
    pub fn state(&mut self) -> Result<super::OutputState, IoError> {
        let partial = self.dir.join("stats.csv.partial");
        let io = |source| IoError::Write { path: partial.clone(), source };
        self.stats.flush().map_err(io)?;
        let file = self.stats.get_mut();
        file.sync_data().map_err(io)?;
        let stats_bytes = file.stream_position().map_err(io)?;
        let frames = self.frames.iter().map(|e| (e.time, e.file.to_string_lossy().into_owned())).collect();
        Ok(super::OutputState { frames, stats_bytes })
    }

    /// Length unit of the frames and statistics.
    pub fn unit(&self) -> OutputUnit {
        self.unit
    }

    /// Number of frames written.
    pub fn frames(&self) -> usize {
        self.frames.len()
    }

    /// Flushes the statistics and gives them their final name `stats.csv` (completed runs only).
    pub fn finish(mut self) -> Result<(), IoError> {
        let partial = self.dir.join("stats.csv.partial");
        self.stats.flush().map_err(|source| IoError::Write { path: partial.clone(), source })?;
        let done = self.dir.join("stats.csv");
        super::check_target("output", &done)?;
        std::fs::rename(&partial, &done).map_err(|source| IoError::Write { path: done, source })
    }

    /// Flushes what was recorded, keeping the `.partial` name (failed runs).
    pub fn abandon(mut self) {
        let _ = self.stats.flush();
    }
}

impl Observer for SimulationRecorder {
    fn sample(&mut self, sample: &Sample<'_>) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
        self.write_sample(sample).map_err(|e| Box::new(e) as Box<dyn std::error::Error + Send + Sync>)
    }
}

/// `events.csv`: one row per division or removal (`step,time,event,cell,daughter_a,daughter_b,volume`,
/// the volume in `unit`³ and its column `volume_um3` in µm), written atomically.
pub fn write_events(path: &Path, events: &[crate::mechanics::TopologyEvent], unit: OutputUnit) -> Result<(), IoError> {
    use std::fmt::Write as _;
    let mut text = format!("step,time,event,cell,daughter_a,daughter_b,{}\n", unit.column("volume", 3));
    for e in events {
        let (a, b) = e.daughters.map_or((String::new(), String::new()), |[a, b]| (a.to_string(), b.to_string()));
        let kind = match e.kind {
            crate::mechanics::TopologyEventKind::Division => "division",
            crate::mechanics::TopologyEventKind::Removal => "removal",
        };
        let _ = writeln!(text, "{},{:e},{kind},{},{a},{b},{:e}", e.step, e.time, e.cell, e.volume * unit.factor(3));
    }
    super::write_bytes_atomically(path, text.as_bytes()).map_err(IoError::from)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A run's statistics header names its length unit; a resume keeps it, or refuses another one.
    #[test]
    fn a_resumed_recorder_keeps_the_runs_unit_and_refuses_another() {
        let dir = tempfile::tempdir().unwrap();
        let mut recorder = SimulationRecorder::create(dir.path(), true, OutputUnit::Micrometre).unwrap();
        let state = recorder.state().unwrap();
        recorder.abandon();
        let header = std::fs::read_to_string(dir.path().join("stats.csv.partial")).unwrap();
        assert!(
            header.starts_with("step,time,cell,kind,cell_type,nodes,volume_um3,target_volume_um3,area_um2,pressure,")
        );
        let resumed = SimulationRecorder::resume(dir.path(), true, &state, None).unwrap();
        assert_eq!(resumed.unit(), OutputUnit::Micrometre);
        resumed.abandon();
        let same = SimulationRecorder::resume(dir.path(), true, &state, Some(OutputUnit::Micrometre)).unwrap();
        same.abandon();
        let Err(e) = SimulationRecorder::resume(dir.path(), true, &state, Some(OutputUnit::Metre)) else {
            panic!("a resume in metres of a µm run was accepted")
        };
        assert!(e.to_string().contains("the run's outputs are in um, not m"), "{e}");
        // In SI the header is the one it always was.
        let si = tempfile::tempdir().unwrap();
        SimulationRecorder::create(si.path(), true, OutputUnit::Metre).unwrap().abandon();
        let header = std::fs::read_to_string(si.path().join("stats.csv.partial")).unwrap();
        assert!(header.starts_with("step,time,cell,kind,cell_type,nodes,volume,target_volume,area,pressure,"));
    }
}
