//! Issue 23: a `tissuefit run` with a fit, and a sweep whose runs fit, killed with SIGKILL at five
//! moments drawn at random (a fixed seed; the moments are fractions of the uninterrupted run's wall
//! time, see [`moments`]), each time started again with the same command, end with the outputs of an uninterrupted run byte for
//! byte (wall-time fields aside; `simulated_here` counts what the last process simulated).

use crate::support::run_dirs;

use crate::support::cli::{repo, tissuefit};
use run_dirs::{data_hashes, fractions, kill_at, read_json, strip_wall_times};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Output;
use std::time::{Duration, Instant};

fn text(o: &Output) -> String {
    format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr))
}

/// pipelines/demo.toml with absolute data paths, a fit of `evaluations` evaluations and a one-point
/// profile, written as `dir/NAME`.
fn demo_with_fit(dir: &Path, name: &str, evaluations: usize) -> PathBuf {
    let demo = std::fs::read_to_string(repo().join("pipelines/demo.toml")).unwrap();
    let data = repo().join("data/demo");
    let body = demo
        .replace("\"../data/demo/", &format!("\"{}/", data.display()))
        .replace("max_evaluations = 24", &format!("max_evaluations = {evaluations}"))
        .replace("points = 2", "points = 1");
    let path = dir.join(name);
    std::fs::write(&path, body).unwrap();
    path
}

/// The data of a run directory: every stage file's normalised hash, `fit/result.json` compared as
/// JSON without its wall times and `simulated_here`.
fn run_data(run: &Path) -> (BTreeMap<String, String>, serde_json::Value) {
    let mut hashes = data_hashes(run);
    assert!(hashes.remove("fit/result.json").is_some(), "{}: no fit/result.json", run.display());
    let mut result = read_json(&run.join("fit/result.json"));
    result.as_object_mut().unwrap().remove("simulated_here");
    strip_wall_times(&mut result);
    (hashes, result)
}

fn stage_statuses(run: &Path) -> Vec<String> {
    let m = read_json(&run.join("manifest.json"));
    m["stages"].as_array().unwrap().iter().map(|s| format!("{}: {}", s["name"], s["status"])).collect()
}

/// Nothing the program left half-made: no temporary stage folder, no temporary file.
fn assert_no_temporaries(dir: &Path) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        assert!(!name.contains(".tmp"), "{} is left behind", path.display());
        if path.is_dir() {
            assert_no_temporaries(&path);
        }
    }
}

/// The two tests run one after the other: each times its uninterrupted run and kills by that clock,
/// which the other's load would skew.
static ONE_AT_A_TIME: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// Five moments drawn uniformly in [5 %, 80 %] of the uninterrupted wall time and sorted, as the delays
/// after which each successive process is killed: the first at the first moment, each next one after
/// the time between its moment and the one before. A process started again goes on from where the last
/// one got (or from a little before: the work in flight is lost), so it is always still running when
/// its kill comes, and the kills spread over the whole run, not its start. The seed is `seed`, or the
/// environment variable `TISSUEFIT_KILL_SEED` (to try other moments).
fn moments(seed: u64, uninterrupted: Duration) -> Vec<Duration> {
    let seed = std::env::var("TISSUEFIT_KILL_SEED").ok().and_then(|s| s.parse().ok()).unwrap_or(seed);
    let mut at: Vec<f64> = fractions(seed, 5).into_iter().map(|f| 0.05 + 0.75 * f).collect();
    at.sort_by(f64::total_cmp);
    let mut before = 0.0;
    at.into_iter()
        .map(|f| {
            let delay = uninterrupted.mul_f64(f - before);
            before = f;
            delay
        })
        .collect()
}

/// What a kill interrupted: the stages of `run`'s manifest that are not done, and the fit's trace rows.
fn interrupted(run: &Path) -> String {
    let Ok(text) = std::fs::read_to_string(run.join("manifest.json")) else { return "before the manifest".into() };
    let m: serde_json::Value = serde_json::from_str(&text).unwrap();
    let open: Vec<String> = m["stages"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|s| !matches!(s["status"].as_str(), Some("complete" | "skipped")))
        .map(|s| format!("{} {}", s["name"].as_str().unwrap(), s["status"].as_str().unwrap()))
        .collect();
    let rows = std::fs::read_dir(run)
        .unwrap()
        .flatten()
        .find(|e| e.file_name().to_string_lossy().starts_with(".fit.tmp-"))
        .and_then(|e| std::fs::read_to_string(e.path().join("trace.csv")).ok())
        .map_or(0, |t| t.lines().count().saturating_sub(1));
    format!(
        "{} ({rows} fit evaluations in the trace)",
        if open.is_empty() { "between stages".into() } else { open.join(", ") }
    )
}

#[test]
fn a_run_with_a_fit_killed_at_five_random_moments_ends_with_the_uninterrupted_outputs() {
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let tmp = tempfile::tempdir().unwrap();
    let p = demo_with_fit(tmp.path(), "demo.toml", 14);
    let p = p.to_str().unwrap();
    let reference = tmp.path().join("reference");
    let started = Instant::now();
    let o = tissuefit(&["--threads", "2", "run", p, "--out", reference.to_str().unwrap()]);
    let wall = started.elapsed();
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));

    let run = tmp.path().join("run");
    let args = ["--threads", "2", "run", p, "--out", run.to_str().unwrap()];
    let delays = moments(23, wall);
    let killed = kill_at(&args, &delays, |at| eprintln!("killed at {at:?}: {}", interrupted(&run)));
    assert_eq!(killed.len(), 5, "killed at {killed:?} of {delays:?}; the uninterrupted run took {wall:?}");
    let o = tissuefit(&args);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    // Stages an earlier (killed) process completed are skipped; none is left running or interrupted.
    let statuses = stage_statuses(&run);
    assert!(statuses.iter().all(|s| s.ends_with("\"complete\"") || s.ends_with("\"skipped\"")), "{statuses:?}");
    assert_no_temporaries(&run);
    assert_eq!(run_data(&run), run_data(&reference), "killed at {killed:?}");
}

#[test]
fn a_sweep_with_fits_killed_at_five_random_moments_ends_with_the_uninterrupted_results() {
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let tmp = tempfile::tempdir().unwrap();
    demo_with_fit(tmp.path(), "base.toml", 8);
    let sweep = tmp.path().join("sweep.toml");
    std::fs::write(&sweep, "base = \"base.toml\"\n[grid]\n\"fit.optimizer.max_evaluations\" = [6, 8]\n").unwrap();
    let s = sweep.to_str().unwrap();
    let reference = tmp.path().join("reference");
    let started = Instant::now();
    let o = tissuefit(&["--threads", "2", "sweep", s, "--out", reference.to_str().unwrap()]);
    let wall = started.elapsed();
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));

    let out = tmp.path().join("out");
    let args = ["--threads", "2", "sweep", s, "--out", out.to_str().unwrap()];
    let delays = moments(2326, wall);
    let killed = kill_at(&args, &delays, |at| {
        let runs: Vec<String> = ["run-0000", "run-0001"]
            .iter()
            .map(|r| {
                format!("{r}: {}", if out.join(r).is_dir() { interrupted(&out.join(r)) } else { "not begun".into() })
            })
            .collect();
        eprintln!("killed at {at:?}: {}", runs.join("; "))
    });
    assert_eq!(killed.len(), 5, "killed at {killed:?} of {delays:?}; the uninterrupted sweep took {wall:?}");
    let o = tissuefit(&args);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    assert_no_temporaries(&out);
    for run in ["run-0000", "run-0001"] {
        assert!(!out.join(run).join("failed.txt").exists(), "{run} recorded as failed");
        assert_eq!(run_data(&out.join(run)), run_data(&reference.join(run)), "{run}, killed at {killed:?}");
    }
    let results = |dir: &Path| {
        let mut r = csv::Reader::from_path(dir.join("results.csv")).unwrap();
        let header = r.headers().unwrap().clone();
        let wall = header.iter().position(|h| h == "wall_seconds").unwrap();
        let rows: Vec<Vec<String>> = r
            .records()
            .map(|rec| {
                rec.unwrap().iter().enumerate().filter(|(i, _)| *i != wall).map(|(_, v)| v.to_string()).collect()
            })
            .collect();
        rows
    };
    assert_eq!(results(&out), results(&reference));
}
