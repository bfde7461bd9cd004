//! Run directories in tests: their data files hashed with the wall times taken out, and a run killed
//! with SIGKILL at chosen moments. Shared by `tests/integration/pipeline.rs` and `tests/slow/kill_resume.rs`.

// Each includer uses its own part.
#![allow(dead_code)]

use std::collections::BTreeMap;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// The rows of a CSV file as (header → value) maps.
pub fn csv_maps(path: &Path) -> Vec<BTreeMap<String, String>> {
    let mut reader = csv::Reader::from_path(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    reader.deserialize().map(|r| r.unwrap_or_else(|e| panic!("{}: {e}", path.display()))).collect()
}

/// The number in column `key` of a row of [`csv_maps`].
pub fn number(row: &BTreeMap<String, String>, key: &str) -> f64 {
    row[key].parse().unwrap_or_else(|e| panic!("{key} = {:?}: {e}", row[key]))
}

pub fn read_json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// Removes the wall-time fields (`wall_seconds`, `session_wall_seconds`, `threads`,
/// `seconds_per_node_step`) at every depth.
pub fn strip_wall_times(v: &mut serde_json::Value) {
    match v {
        serde_json::Value::Object(map) => {
            map.remove("wall_seconds");
            map.remove("session_wall_seconds");
            map.remove("threads");
            map.remove("seconds_per_node_step");
            map.values_mut().for_each(strip_wall_times);
        }
        serde_json::Value::Array(items) => items.iter_mut().for_each(strip_wall_times),
        _ => {}
    }
}

/// blake3 of a data file with its wall times taken out (JSON keys of [`strip_wall_times`], CSV columns `wall_seconds` and `elapsed_seconds`); everything
/// else byte for byte.
pub fn normalised_hash(path: &Path) -> String {
    let name = path.file_name().unwrap().to_string_lossy().into_owned();
    let bytes = std::fs::read(path).unwrap();
    let data = if name.ends_with(".json") {
        let mut v: serde_json::Value = serde_json::from_slice(&bytes).unwrap();
        strip_wall_times(&mut v);
        serde_json::to_vec(&v).unwrap()
    } else if name.ends_with(".csv") {
        let mut r = csv::Reader::from_reader(bytes.as_slice());
        let header = r.headers().unwrap().clone();
        let keep: Vec<usize> =
            (0..header.len()).filter(|&i| !matches!(&header[i], "wall_seconds" | "elapsed_seconds")).collect();
        let mut w = csv::Writer::from_writer(Vec::new());
        w.write_record(keep.iter().map(|&i| &header[i])).unwrap();
        for rec in r.records() {
            let rec = rec.unwrap();
            w.write_record(keep.iter().map(|&i| &rec[i])).unwrap();
        }
        w.into_inner().unwrap()
    } else {
        bytes
    };
    blake3::hash(&data).to_hex().to_string()
}

/// [`normalised_hash`] of every file of the stage folders (`mesh`, `measure`, `simulate`, `fit`, those
/// present) of a run directory, as `stage/file` (`simulate/frames/frame_000000.vtp`).
pub fn data_hashes(run: &Path) -> BTreeMap<String, String> {
    stage_hashes(run, &["mesh", "measure", "simulate", "fit"])
}

/// [`normalised_hash`] of every file under the folders `stages` of `run` (subfolders included), as
/// paths relative to `run` with `/`.
pub fn stage_hashes(run: &Path, stages: &[&str]) -> BTreeMap<String, String> {
    let mut out = BTreeMap::new();
    let mut stack: Vec<String> = stages.iter().map(|s| s.to_string()).collect();
    while let Some(rel) = stack.pop() {
        let Ok(entries) = std::fs::read_dir(run.join(&rel)) else { continue };
        for entry in entries {
            let entry = entry.unwrap();
            let name = format!("{rel}/{}", entry.file_name().to_string_lossy());
            if entry.file_type().unwrap().is_dir() {
                stack.push(name);
            } else {
                out.insert(name, normalised_hash(&entry.path()));
            }
        }
    }
    out
}

/// Fractions in [0, 1) from a seed (splitmix64), the same on every machine.
pub fn fractions(seed: u64, n: usize) -> Vec<f64> {
    let mut state = seed;
    (0..n)
        .map(|_| {
            state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = state;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            z ^= z >> 31;
            (z >> 11) as f64 / (1u64 << 53) as f64
        })
        .collect()
}

/// Runs `tissuefit ARGS` once per delay, killing it with SIGKILL when it has run that long (then
/// calls `after_kill`); a run that ends before its moment ends the series. Returns the moments at
/// which a process was killed.
pub fn kill_at(args: &[&str], delays: &[Duration], mut after_kill: impl FnMut(Duration)) -> Vec<Duration> {
    let mut killed = Vec::new();
    for &delay in delays {
        let mut child = Command::new(env!("CARGO_BIN_EXE_tissuefit"))
            .args(args)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("runs the binary");
        let started = Instant::now();
        let mut ended = false;
        while started.elapsed() < delay {
            if child.try_wait().unwrap().is_some() {
                ended = true;
                break;
            }
            std::thread::sleep(Duration::from_millis(5));
        }
        if ended {
            break;
        }
        child.kill().unwrap();
        child.wait().unwrap();
        after_kill(delay);
        killed.push(delay);
    }
    killed
}
