//! Checkpoints and resume (`tissuefit simulate --resume`): a run stopped at a step boundary, killed
//! with SIGKILL or interrupted with SIGINT, then resumed, ends with exactly the outputs of an
//! uninterrupted run (final tissue, stats.csv, events.csv, every frame, the .pvd index, and
//! summary.json but for its wall times); a damaged checkpoint is refused with an error naming it.

use crate::support::cli::tissuefit;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::sync::OnceLock;
use std::time::{Duration, Instant};
use tissuefit::io::write_simucell3d;
use tissuefit::mesh::shapes::sphere_for_min_edge;
use tissuefit::mesh::{Cell, CellId, CellKind, Tissue};

fn spawn(args: &[&str]) -> Child {
    Command::new(env!("CARGO_BIN_EXE_tissuefit"))
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("the tissuefit binary starts")
}

fn demo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("data/demo/cell_quartet.vtk")
}

fn growth_config() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("pipelines/growth.toml")
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn ok(out: &Output) {
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
}

/// One 3 µm sphere (l_min 0.6 µm), the set-up of tests/integration/growth_cli.rs: with pipelines/growth.toml
/// it divides first at step ≈ 145 and again at ≈ 273 (coupling contacts, remeshing every step).
fn sphere(dir: &Path) -> PathBuf {
    let path = dir.join("sphere.vtk");
    let mesh = sphere_for_min_edge(3e-6, 6e-7).unwrap();
    let tissue = Tissue::from_cells(vec![Cell::new(CellId(1), CellKind::Epithelial, 0, mesh)]).unwrap();
    write_simucell3d(&path, &tissue, &[]).unwrap();
    path
}

/// Arguments of the growth run: 600 steps (three division waves), two threads.
fn growth_args<'a>(input: &'a Path, out: &'a Path) -> Vec<&'a str> {
    vec![
        "--threads",
        "2",
        "simulate",
        s(input),
        "--config",
        s(growth_config().leak()),
        "--out",
        s(out),
        "--duration",
        "6e-5",
    ]
}

/// The input sphere and the uninterrupted growth run (`run/`), shared by the tests of this file
/// (summary.json names the input, so every run reads the same file).
fn growth_reference() -> &'static Path {
    static DIR: OnceLock<tempfile::TempDir> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let input = sphere(dir.path());
        let out = dir.path().join("run");
        ok(&tissuefit(&growth_args(&input, &out)));
        dir
    })
    .path()
}

/// Every output of two runs is identical, byte for byte, except summary.json's wall times.
fn assert_same_outputs(reference: &Path, resumed: &Path) {
    for name in ["final.vtk", "stats.csv", "events.csv", "frames.pvd", "config.toml"] {
        let a = std::fs::read(reference.join(name)).unwrap_or_else(|e| panic!("{name} of the reference: {e}"));
        let b = std::fs::read(resumed.join(name)).unwrap_or_else(|e| panic!("{name} of the resumed run: {e}"));
        assert!(a == b, "{name} differs between the uninterrupted and the resumed run");
    }
    let frames = |dir: &Path| {
        let mut names: Vec<String> = std::fs::read_dir(dir.join("frames"))
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    };
    let names = frames(reference);
    assert!(names.len() >= 2, "{names:?}");
    assert_eq!(names, frames(resumed), "the frames differ in number or names");
    for name in &names {
        let a = std::fs::read(reference.join("frames").join(name)).unwrap();
        let b = std::fs::read(resumed.join("frames").join(name)).unwrap();
        assert!(a == b, "frame {name} differs");
    }
    let summary = |dir: &Path| {
        let mut v: serde_json::Value =
            serde_json::from_slice(&std::fs::read(dir.join("summary.json")).unwrap()).unwrap();
        let map = v.as_object_mut().unwrap();
        assert!(map.remove("wall_seconds").is_some());
        assert!(map.remove("seconds_per_node_step").is_some());
        v
    };
    assert_eq!(summary(reference), summary(resumed));
    for dir in [reference, resumed] {
        assert!(!dir.join("checkpoint.bin").exists(), "a completed run deletes its checkpoint");
        assert!(!dir.join("stats.csv.partial").exists());
    }
}

/// Runs `--resume DIR` and expects it to complete.
fn resume(dir: &Path) {
    let out = tissuefit(&["--threads", "2", "simulate", "--resume", s(dir)]);
    ok(&out);
    assert!(String::from_utf8_lossy(&out.stderr).contains("resuming"));
}

#[test]
fn a_fire_relaxation_stopped_and_resumed_matches_the_uninterrupted_run() {
    let dir = tempfile::tempdir().unwrap();
    let (reference, split) = (dir.path().join("reference"), dir.path().join("split"));
    let input = demo();
    let run = |out: &Path, extra: &[&str]| {
        let mut args = vec!["--threads", "2", "simulate", s(&input), "--out", s(out), "--max-steps", "120"];
        args.extend_from_slice(extra);
        tissuefit(&args)
    };
    let full = run(&reference, &[]);
    assert!(full.status.code() == Some(0) || full.status.code() == Some(1));
    let summary: serde_json::Value =
        serde_json::from_slice(&std::fs::read(reference.join("summary.json")).unwrap()).unwrap();
    // The stop must fall inside the run for the comparison to mean anything.
    assert!(summary["steps"].as_u64().unwrap() > 60, "{summary}");

    let stopped = run(&split, &["--stop-at-step", "60"]);
    assert_eq!(stopped.status.code(), Some(130), "{}", String::from_utf8_lossy(&stopped.stderr));
    let message = String::from_utf8_lossy(&stopped.stderr);
    assert!(message.contains("--resume") && message.contains("step 60"), "{message}");
    assert!(split.join("checkpoint.bin").exists());
    assert!(!split.join("stats.csv").exists(), "an unfinished run has no stats.csv");
    assert!(!split.join("summary.json").exists());
    let out = tissuefit(&["--threads", "2", "simulate", "--resume", s(&split)]);
    assert_eq!(out.status.code(), full.status.code(), "{}", String::from_utf8_lossy(&out.stderr));
    assert_same_outputs(&reference, &split);
}

/// The junction groups that persist from one evaluation to the next
/// (`numerics.coupling_persistent_junctions`) are rebuilt from the checkpoint's ties: a coupled
/// relaxation of a generated 12-cell spheroid stopped at step 60 ends as the uninterrupted one
/// (which differs from a run without the option, so the groups did persist).
#[test]
fn a_coupled_relaxation_with_persistent_junctions_resumed_matches_the_uninterrupted_run() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("spheroid.vtp");
    ok(&tissuefit(&[
        "generate",
        "mesh",
        "--kind",
        "spheroid",
        "--cells",
        "12",
        "--min-edge-length",
        "1.6um",
        "--out",
        s(&input),
        "-q",
    ]));
    let model = "[numerics]\ncontact_model = \"coupling\"\npolarity = \"contacts\"\n";
    let (plain, persistent) = (dir.path().join("plain.toml"), dir.path().join("persistent.toml"));
    std::fs::write(&plain, model).unwrap();
    std::fs::write(&persistent, format!("{model}coupling_persistent_junctions = true\n")).unwrap();
    let run = |config: &Path, out: &Path, extra: &[&str]| {
        let mut args =
            vec!["--threads", "2", "simulate", s(&input), "--config", s(config), "--out", s(out), "--max-steps", "120"];
        args.extend_from_slice(extra);
        tissuefit(&args)
    };
    let (reference, split, other) = (dir.path().join("reference"), dir.path().join("split"), dir.path().join("plain"));
    let full = run(&persistent, &reference, &[]);
    assert!(
        full.status.code() == Some(0) || full.status.code() == Some(1),
        "{}",
        String::from_utf8_lossy(&full.stderr)
    );
    run(&plain, &other, &[]);
    let final_of = |d: &Path| std::fs::read(d.join("final.vtk")).unwrap();
    assert_ne!(final_of(&reference), final_of(&other), "the option changed nothing");
    let stopped = run(&persistent, &split, &["--stop-at-step", "60"]);
    assert_eq!(stopped.status.code(), Some(130), "{}", String::from_utf8_lossy(&stopped.stderr));
    let out = tissuefit(&["--threads", "2", "simulate", "--resume", s(&split)]);
    assert_eq!(out.status.code(), full.status.code(), "{}", String::from_utf8_lossy(&out.stderr));
    assert_same_outputs(&reference, &split);
}

#[test]
fn a_growth_run_stopped_after_a_division_and_resumed_matches_the_uninterrupted_run() {
    let reference = growth_reference().join("run");
    let events = std::fs::read_to_string(reference.join("events.csv")).unwrap();
    assert!(events.lines().count() >= 3, "the reference divides: {events}");
    let input = growth_reference().join("sphere.vtk");
    let dir = tempfile::tempdir().unwrap();
    let split = dir.path().join("run");
    // Step 200: after the first division, before the second wave; not a sampling step.
    let mut args = growth_args(&input, &split);
    args.extend_from_slice(&["--stop-at-step", "200"]);
    let stopped = tissuefit(&args);
    assert_eq!(stopped.status.code(), Some(130), "{}", String::from_utf8_lossy(&stopped.stderr));
    resume(&split);
    assert_same_outputs(&reference, &split);
}

/// Waits until `path` exists while `child` runs; fails if the child exits first.
fn wait_for(path: &Path, child: &mut Child) {
    let start = Instant::now();
    while !path.exists() {
        if let Some(status) = child.try_wait().unwrap() {
            panic!("the run ended ({status}) before {} appeared", path.display());
        }
        assert!(start.elapsed() < Duration::from_secs(300), "no checkpoint after 5 minutes");
        std::thread::sleep(Duration::from_millis(2));
    }
}

#[test]
fn a_growth_run_killed_with_sigkill_and_resumed_matches_the_uninterrupted_run() {
    let reference = growth_reference().join("run");
    let input = growth_reference().join("sphere.vtk");
    let dir = tempfile::tempdir().unwrap();
    let split = dir.path().join("run");
    let mut args = growth_args(&input, &split);
    args.extend_from_slice(&["--checkpoint-every-steps", "100"]);
    let mut child = spawn(&args);
    wait_for(&split.join("checkpoint.bin"), &mut child);
    // Let it run on past the checkpoint (frames and statistics rows after it get written).
    std::thread::sleep(Duration::from_millis(20));
    let still_running = child.try_wait().unwrap().is_none();
    child.kill().unwrap();
    let status = child.wait().unwrap();
    assert!(still_running, "the run finished before it could be killed");
    assert_eq!(status.code(), None, "killed by a signal");
    assert!(!split.join("summary.json").exists());
    // A kill in the middle of writing a frame leaves its temporary (it happened in CI): the resumed
    // run removes it. Make sure there is one, whenever the kill came.
    std::fs::write(split.join("frames").join("frame_000099.vtp.tmp-4242"), b"half a frame").unwrap();
    std::fs::write(split.join("frames.pvd.tmp-4242"), b"half an index").unwrap();
    resume(&split);
    assert_same_outputs(&reference, &split);
    assert!(!split.join("frames.pvd.tmp-4242").exists(), "the stale temporary of frames.pvd is left");
}

#[test]
fn sigint_saves_a_resumable_checkpoint_and_exits_cleanly() {
    let reference = growth_reference().join("run");
    let input = growth_reference().join("sphere.vtk");
    let dir = tempfile::tempdir().unwrap();
    let split = dir.path().join("run");
    let mut args = growth_args(&input, &split);
    // The first periodic checkpoint shows that the run (and its signal handler) is up.
    args.extend_from_slice(&["--checkpoint-every-steps", "100"]);
    let mut child = spawn(&args);
    wait_for(&split.join("checkpoint.bin"), &mut child);
    let sent = Command::new("kill").args(["-INT", &child.id().to_string()]).status().unwrap();
    assert!(sent.success());
    let out = child.wait_with_output().unwrap();
    let message = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(130), "{message}");
    assert!(message.contains("tissuefit simulate --resume"), "{message}");
    assert!(split.join("checkpoint.bin").exists());
    assert!(split.join("stats.csv.partial").exists() && !split.join("stats.csv").exists());
    resume(&split);
    assert_same_outputs(&reference, &split);
}

#[test]
fn a_damaged_checkpoint_is_refused_with_an_error_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("run");
    let stopped = tissuefit(&["simulate", s(&demo()), "--out", s(&run), "--max-steps", "50", "--stop-at-step", "5"]);
    assert_eq!(stopped.status.code(), Some(130), "{}", String::from_utf8_lossy(&stopped.stderr));
    let path = run.join("checkpoint.bin");
    // Starting afresh into the folder of an unfinished run is refused, pointing at --resume.
    let again = tissuefit(&["simulate", s(&demo()), "--out", s(&run)]);
    assert_eq!(again.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&again.stderr).contains("--resume"), "{}", String::from_utf8_lossy(&again.stderr));
    let good = std::fs::read(&path).unwrap();
    let stats = std::fs::read(run.join("stats.csv.partial")).unwrap();

    let mut flipped = good.clone();
    let middle = flipped.len() / 2;
    flipped[middle] ^= 0x10;
    let mut version = good.clone();
    version[8] = version[8].wrapping_add(1);
    let cases: [(&str, Vec<u8>, &str); 5] = [
        ("truncated", good[..good.len() - 100].to_vec(), "truncated"),
        ("header only", good[..10].to_vec(), "truncated"),
        ("bit flip", flipped, "corrupt"),
        ("version", version, "version"),
        ("not a checkpoint", b"# vtk DataFile Version 4.2\n".to_vec(), "not a tissuefit checkpoint"),
    ];
    for (case, bytes, expected) in cases {
        std::fs::write(&path, &bytes).unwrap();
        let out = tissuefit(&["simulate", "--resume", s(&run)]);
        let message = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{case}: {message}");
        assert!(message.contains(s(&path)), "{case}: the error names the file: {message}");
        assert!(message.contains(expected), "{case}: {message}");
        assert!(!message.contains("panicked"), "{case}: {message}");
        // Nothing was touched.
        assert_eq!(std::fs::read(run.join("stats.csv.partial")).unwrap(), stats, "{case}");
        assert!(!run.join("summary.json").exists(), "{case}");
    }
    // The intact checkpoint still resumes.
    std::fs::write(&path, &good).unwrap();
    let out = tissuefit(&["simulate", "--resume", s(&run)]);
    assert!(out.status.code() == Some(0) || out.status.code() == Some(1), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(run.join("summary.json").exists() && !path.exists());

    // A folder without a checkpoint: a clear error.
    let out = tissuefit(&["simulate", "--resume", s(dir.path())]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("checkpoint.bin does not exist"));
}

#[test]
fn the_config_sets_the_checkpoint_period_and_the_command_line_overrides_it() {
    let dir = tempfile::tempdir().unwrap();
    let config = dir.path().join("c.toml");
    std::fs::write(&config, "[simulation]\ncheckpoint_every_steps = 5\ncheckpoint_every_seconds = 0\n").unwrap();
    let run = |out: &str, extra: &[&str]| {
        let out = dir.path().join(out);
        let input = demo();
        let mut args = vec!["-v", "simulate", s(&input), "--config", s(&config), "--out", s(&out), "--max-steps", "12"];
        args.extend_from_slice(extra);
        let o = tissuefit(&args);
        assert!(o.status.code() == Some(0) || o.status.code() == Some(1), "{}", String::from_utf8_lossy(&o.stderr));
        assert!(!out.join("checkpoint.bin").exists(), "a completed run deletes its checkpoint");
        String::from_utf8_lossy(&o.stderr).into_owned()
    };
    let log = run("config", &[]);
    let saved: Vec<&str> = log.lines().filter(|l| l.contains("checkpoint at step")).collect();
    assert_eq!(saved.len(), 2, "{log}");
    assert!(saved[0].contains("step 5:") && saved[1].contains("step 10:"), "{log}");
    let log = run("cli", &["--checkpoint-every-steps", "4"]);
    assert_eq!(log.lines().filter(|l| l.contains("checkpoint at step")).count(), 3, "{log}");

    std::fs::write(&config, "[simulation]\ncheckpoint_every_seconds = -1\n").unwrap();
    let o = tissuefit(&["simulate", s(&demo()), "--config", s(&config), "--out", s(&dir.path().join("bad"))]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("simulation.checkpoint_every_seconds"));
}

/// Issue 23, item 6: `--resume` dropped `--checkpoint-every-steps` (the resumed run fell back to one
/// checkpoint per 600 s). The checkpoint now holds the run's settings: a run killed with SIGKILL
/// goes on checkpointing every 100 steps and still stops at its `--stop-at-step`; an option given
/// again on the resume command line replaces the saved one, with a note; the outputs stay those of
/// the uninterrupted run, and the wall time sums the sessions.
#[test]
fn a_resumed_run_keeps_its_checkpoint_period_and_stop_step_and_sums_its_wall_time() {
    let reference = growth_reference().join("run");
    let input = growth_reference().join("sphere.vtk");
    let dir = tempfile::tempdir().unwrap();
    let split = dir.path().join("run");
    let mut args = growth_args(&input, &split);
    args.extend_from_slice(&["--checkpoint-every-steps", "100", "--checkpoint-every-seconds", "0"]);
    args.extend_from_slice(&["--stop-at-step", "500"]);
    let mut child = spawn(&args);
    wait_for(&split.join("checkpoint.bin"), &mut child);
    let still_running = child.try_wait().unwrap().is_none();
    child.kill().unwrap();
    child.wait().unwrap();
    assert!(still_running, "the run finished before it could be killed");

    // Resumed without options: checkpoints every 100 steps, then the saved stop at step 500.
    let out = tissuefit(&["-v", "--threads", "2", "simulate", "--resume", s(&split)]);
    let log = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(130), "{log}");
    for step in [200, 300, 400] {
        assert!(log.contains(&format!("checkpoint at step {step}:")), "no checkpoint at step {step}: {log}");
    }
    assert!(log.contains("stops at step 500") && log.contains("stopped at step 500"), "{log}");

    // An explicit period on the resume command line wins, and says so.
    let started = Instant::now();
    let out = tissuefit(&["-v", "--threads", "2", "simulate", "--resume", s(&split), "--checkpoint-every-steps", "30"]);
    let last_session = started.elapsed().as_secs_f64();
    let log = String::from_utf8_lossy(&out.stderr).into_owned();
    ok(&out);
    assert!(log.contains("--checkpoint-every-steps 30 replaces the run's 100"), "{log}");
    assert!(log.contains("checkpoint at step 510:") && log.contains("checkpoint at step 540:"), "{log}");
    assert_same_outputs(&reference, &split);
    // 500 of the 600 steps ran in the earlier sessions: the wall time is theirs plus this one's.
    let summary: serde_json::Value =
        serde_json::from_slice(&std::fs::read(split.join("summary.json")).unwrap()).unwrap();
    let wall = summary["wall_seconds"].as_f64().unwrap();
    assert!(wall > last_session, "wall_seconds {wall} s counts only the last session ({last_session} s)");
}

#[test]
fn stop_at_step_zero_or_before_the_checkpoint_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    let o = tissuefit(&["simulate", s(&demo()), "--out", s(&out), "--stop-at-step", "0"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--stop-at-step 0"), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(!out.exists(), "a refused run wrote {}", out.display());
    let o = tissuefit(&["simulate", s(&demo()), "--out", s(&out), "--max-steps", "40", "--stop-at-step", "20"]);
    assert_eq!(o.status.code(), Some(130), "{}", String::from_utf8_lossy(&o.stderr));
    let o = tissuefit(&["simulate", "--resume", s(&out), "--stop-at-step", "20"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("--stop-at-step 20") && err.contains("at step 20 already"), "{err}");
    assert!(out.join("checkpoint.bin").exists(), "the refused resume removed the checkpoint");
    // A later stop is honoured; the saved one (20) has happened and is not repeated.
    let o = tissuefit(&["simulate", "--resume", s(&out), "--stop-at-step", "30"]);
    assert_eq!(o.status.code(), Some(130), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stderr).contains("stopped at step 30"));
    let o = tissuefit(&["simulate", "--resume", s(&out)]);
    assert!(o.status.code() == Some(0) || o.status.code() == Some(1), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(out.join("summary.json").exists() && !out.join("checkpoint.bin").exists());
}
