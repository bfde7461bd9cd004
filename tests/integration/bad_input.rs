//! Bad input tried on purpose, through the `tissuefit` binary: a table of malformed files, configs and
//! output locations. Each must give exit code 2 and a message naming the file (or key) and the
//! problem, never a panic, and leave no output that looks complete.
//!
//! Malformed bytes in general are covered by `fuzz_inputs.rs`; this table holds the cases a user
//! meets: truncated and corrupted files, non-finite coordinates, open and inside-out cells, bad
//! parameter values, missing files, an output folder that cannot be created, and a full disk.

use crate::support::cli::tissuefit;
use std::path::{Path, PathBuf};
use std::process::Command;

fn demo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("data/demo/cell_quartet.vtk")
}

fn demo_text() -> String {
    std::fs::read_to_string(demo()).unwrap()
}

/// A one-cell SimuCell3D file whose only cell is the tetrahedron given by `faces` (triangles).
fn tetra_file(faces: &[[u32; 3]]) -> String {
    let stream: Vec<String> = std::iter::once(faces.len().to_string())
        .chain(faces.iter().map(|f| format!("3 {} {} {}", f[0], f[1], f[2])))
        .collect();
    let record = stream.join(" ");
    let k = 1 + 4 * faces.len();
    format!(
        "# vtk DataFile Version 4.2\ntetra\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 4 float\n\
         0 0 0 1e-6 0 0 0 1e-6 0 0 0 1e-6\nCELLS 1 {}\n{k} {record}\nCELL_TYPES 1\n42\n",
        k + 1
    )
}

const OUTWARD: [[u32; 3]; 4] = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];

/// What a bad-input case must produce.
struct Case {
    name: &'static str,
    /// Writes the inputs into the folder and returns the command line; `{dir}` is the folder.
    setup: fn(&Path) -> Vec<String>,
    /// Every one of these must appear in stderr.
    says: &'static [&'static str],
}

fn write(dir: &Path, name: &str, text: &str) -> String {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p.to_str().unwrap().to_string()
}

fn simulate(tissue: String, dir: &Path, extra: &[&str]) -> Vec<String> {
    let mut args = vec!["simulate".to_string(), tissue, "--out".into(), dir.join("run").to_str().unwrap().into()];
    args.extend(extra.iter().map(|s| s.to_string()));
    args
}

fn simulate_with_config(dir: &Path, config: &str) -> Vec<String> {
    let c = write(dir, "params.toml", config);
    simulate(demo().to_str().unwrap().into(), dir, &["--config", &c, "--max-steps", "10"])
}

const CASES: &[Case] = &[
    Case {
        name: "missing tissue file",
        setup: |d| simulate(d.join("nowhere.vtk").to_str().unwrap().into(), d, &[]),
        says: &["nowhere.vtk"],
    },
    Case {
        name: "truncated tissue file",
        setup: |d| {
            let text = demo_text();
            simulate(write(d, "truncated.vtk", &text[..text.len() / 2]), d, &[])
        },
        says: &["truncated.vtk", "truncated"],
    },
    Case {
        name: "NaN coordinate",
        setup: |d| {
            let text = demo_text();
            let points = text.find("POINTS").unwrap();
            let line = text[points..].find('\n').unwrap() + points + 1;
            let first = text[line..].find(' ').unwrap() + line;
            let broken = format!("{}nan{}", &text[..line], &text[first..]);
            simulate(write(d, "nan.vtk", &broken), d, &[])
        },
        says: &["nan.vtk", "non-finite"],
    },
    Case {
        name: "open cell (a face missing)",
        setup: |d| simulate(write(d, "open.vtk", &tetra_file(&OUTWARD[..3])), d, &[]),
        says: &["not a valid closed surface"],
    },
    Case {
        name: "inside-out cell",
        setup: |d| {
            let inward: Vec<[u32; 3]> = OUTWARD.iter().map(|f| [f[0], f[2], f[1]]).collect();
            simulate(write(d, "inverted.vtk", &tetra_file(&inward)), d, &[])
        },
        says: &["--orient"],
    },
    Case {
        name: "not a tissue file",
        setup: |d| simulate(write(d, "notes.txt", "hello"), d, &[]),
        says: &["notes.txt", "unknown file type"],
    },
    Case {
        name: "missing config file",
        setup: |d| {
            let c = d.join("missing.toml");
            simulate(demo().to_str().unwrap().into(), d, &["--config", c.to_str().unwrap()])
        },
        says: &["missing.toml"],
    },
    Case {
        name: "unknown config key",
        setup: |d| simulate_with_config(d, "[numerics]\ntime_stepp = 1e-7\n"),
        says: &["params.toml", "time_stepp"],
    },
    Case {
        name: "wrong value type",
        setup: |d| simulate_with_config(d, "[numerics]\ntime_step = \"fast\"\n"),
        says: &["params.toml", "time_step"],
    },
    Case {
        name: "NaN parameter",
        setup: |d| simulate_with_config(d, "[numerics]\ntime_step = nan\n"),
        says: &["params.toml", "time_step"],
    },
    Case {
        name: "zero time step",
        setup: |d| simulate_with_config(d, "[numerics]\ntime_step = 0.0\n"),
        says: &["params.toml", "time_step"],
    },
    Case {
        name: "negative edge length",
        setup: |d| simulate_with_config(d, "[numerics]\nmin_edge_length = -1e-7\n"),
        says: &["params.toml", "min_edge_length"],
    },
    Case {
        name: "step budget beyond a TOML integer (panicked when writing config.toml)",
        setup: |d| simulate(demo().to_str().unwrap().into(), d, &["--max-steps", "18446744073709551615"]),
        says: &["simulation.max_steps", "largest TOML integer"],
    },
    Case {
        name: "output folder under a regular file",
        setup: |d| {
            let file = write(d, "plain", "x");
            vec![
                "simulate".into(),
                demo().to_str().unwrap().into(),
                "--out".into(),
                format!("{file}/run"),
                "--max-steps".into(),
                "10".into(),
            ]
        },
        says: &["plain/run"],
    },
    Case {
        name: "convert to a folder that does not exist",
        setup: |d| {
            vec![
                "convert".into(),
                demo().to_str().unwrap().into(),
                d.join("no/such/dir/out.vtp").to_str().unwrap().into(),
            ]
        },
        says: &["out.vtp", "does not exist", "mkdir -p"],
    },
    Case {
        // Refused before the meshing, not when saving its result.
        name: "mesh into a folder that does not exist",
        setup: |d| {
            let labels = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/demo/doublet.tif");
            vec![
                "mesh".into(),
                labels.to_str().unwrap().into(),
                "--out".into(),
                d.join("missing/t.vtp").to_str().unwrap().into(),
            ]
        },
        says: &["--out", "missing", "does not exist"],
    },
    Case {
        name: "inspect a folder",
        setup: |d| vec!["inspect".into(), d.to_str().unwrap().into()],
        says: &["cannot open"],
    },
];

/// Every regular file under `dir`, relative, sorted.
fn files(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                out.push(p.strip_prefix(dir).unwrap().to_path_buf());
            }
        }
    }
    out.sort();
    out
}

#[test]
fn every_bad_input_gives_a_clear_error_and_no_outputs() {
    let mut failures = Vec::new();
    for case in CASES {
        let dir = tempfile::tempdir().unwrap();
        let args = (case.setup)(dir.path());
        let before = files(dir.path());
        let refs: Vec<&str> = args.iter().map(String::as_str).collect();
        let out = tissuefit(&refs);
        let err = String::from_utf8_lossy(&out.stderr);
        let mut problems = Vec::new();
        if out.status.code() != Some(2) {
            problems.push(format!("exit code {:?}, expected 2", out.status.code()));
        }
        if err.contains("panicked") {
            problems.push("panicked".into());
        }
        if err.matches("(os error").count() > 1 {
            problems.push("the message repeats its cause".into());
        }
        for s in case.says {
            if !err.contains(s) {
                problems.push(format!("stderr lacks `{s}`"));
            }
        }
        let after = files(dir.path());
        if after != before {
            problems.push(format!(
                "left files behind: {:?}",
                after.iter().filter(|f| !before.contains(f)).collect::<Vec<_>>()
            ));
        }
        if !problems.is_empty() {
            failures.push(format!("{}: {}\n  stderr: {}", case.name, problems.join("; "), err.trim()));
        }
    }
    assert!(failures.is_empty(), "{} of {} cases failed:\n{}", failures.len(), CASES.len(), failures.join("\n"));
}

/// A tmpfs of 64 KiB, unmounted on drop; `None` where mounting is not allowed (not root, no tmpfs).
struct TinyDisk(tempfile::TempDir);

impl TinyDisk {
    fn mount() -> Option<Self> {
        let dir = tempfile::tempdir().ok()?;
        let ok = Command::new("mount")
            .args(["-t", "tmpfs", "-o", "size=64k", "tmpfs"])
            .arg(dir.path())
            .output()
            .is_ok_and(|o| o.status.success());
        ok.then_some(TinyDisk(dir))
    }
}

impl Drop for TinyDisk {
    fn drop(&mut self) {
        let _ = Command::new("umount").arg(self.0.path()).output();
    }
}

#[test]
fn a_full_disk_is_a_clear_error_and_leaves_nothing_that_looks_complete() {
    let Some(disk) = TinyDisk::mount() else {
        eprintln!("skipped: cannot mount a tmpfs here (needs root)");
        return;
    };
    let run = disk.0.path().join("run");
    let out = tissuefit(&["simulate", demo().to_str().unwrap(), "--out", run.to_str().unwrap(), "--max-steps", "50"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("No space left on device") && !err.contains("panicked"), "{err}");
    // The demo's outputs are ~1 MB: what was written before the disk filled must not look finished.
    assert!(!run.join("summary.json").exists(), "a summary.json claims a finished run");
    for f in files(disk.0.path()) {
        let name = f.to_string_lossy();
        assert!(!name.contains(".tmp") && !name.starts_with('.'), "a temporary file was left behind: {name}");
    }
}

/// Every subcommand that reads a file, given a missing file and then a file of garbage with the
/// right extension: exit 2, a message naming the file, and nothing written where its outputs go (an
/// output folder is not even made; the folder of an output file, which must exist, stays empty).
#[test]
fn every_subcommand_refuses_a_missing_or_garbage_input_naming_it_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    // (what the argument is, its extension, the command line with FILE for it and OUT for an output
    // folder (or OUT/... for an output file); TISSUE is the demo tissue)
    let commands: &[(&str, &[&str])] = &[
        ("vtk", &["inspect", "FILE"]),
        ("vtk", &["convert", "FILE", "OUT/t.vtp"]),
        ("vtk", &["measure", "FILE", "--out", "OUT"]),
        ("tif", &["mesh", "FILE", "--out", "OUT/t.vtp"]),
        ("vtk", &["simulate", "FILE", "--out", "OUT", "--max-steps", "5"]),
        ("vtk", &["polarize", "FILE", "--out", "OUT/p.vtp"]),
        ("vtk", &["voxelize", "FILE", "--voxel-size", "1um", "--out", "OUT/v.tif"]),
        ("vtk", &["render", "FILE", "--out", "OUT/v.png"]),
        ("vtk", &["tensions", "FILE", "--out", "OUT"]),
        ("tif", &["tensions", "FILE", "--out", "OUT"]),
        ("npy", &["mesh", "FILE", "--out", "OUT/t.vtp"]),
        ("npy", &["measure", "FILE", "--out", "OUT"]),
        ("zarr", &["mesh", "FILE", "--out", "OUT/t.vtp"]),
        ("zarr", &["measure", "FILE", "--out", "OUT"]),
        ("zarr", &["tensions", "FILE", "--out", "OUT"]),
        ("h5", &["mesh", "FILE", "--out", "OUT/t.vtp"]),
        ("h5", &["measure", "FILE", "--out", "OUT"]),
        ("h5", &["tensions", "FILE", "--out", "OUT"]),
        ("npy", &["voxelize", "TISSUE", "--like", "FILE", "--out", "OUT/v.tif"]),
        ("vtk", &["bench", "forces-tissue", "FILE", "--repeat", "1"]),
        ("toml", &["config", "check", "FILE"]),
        ("toml", &["fit", "--config", "FILE", "--out", "OUT"]),
        ("toml", &["run", "FILE", "--out", "OUT"]),
        ("toml", &["sweep", "FILE", "--out", "OUT"]),
    ];
    let garbage: &[u8] = b"\x00\x01\x02 not a file of this kind [[[ = \xff\xfe\n";
    let mut failures = Vec::new();
    for (k, (ext, line)) in commands.iter().enumerate() {
        for kind in ["missing", "garbage"] {
            let case = dir.path().join(format!("{k}-{kind}"));
            std::fs::create_dir_all(&case).unwrap();
            let file = case.join(format!("{kind}_input.{ext}"));
            if kind == "garbage" {
                std::fs::write(&file, garbage).unwrap();
            }
            let out = case.join("out");
            let file_output = line.iter().any(|a| a.starts_with("OUT/"));
            if file_output {
                std::fs::create_dir(&out).unwrap();
            }
            let args: Vec<String> = line
                .iter()
                .map(|a| {
                    a.replace("FILE", file.to_str().unwrap())
                        .replace("OUT", out.to_str().unwrap())
                        .replace("TISSUE", demo().to_str().unwrap())
                })
                .collect();
            let args: Vec<&str> = args.iter().map(String::as_str).collect();
            let o = tissuefit(&args);
            let err = String::from_utf8_lossy(&o.stderr).into_owned();
            let name = format!("{kind}_input.{ext}");
            if o.status.code() != Some(2) || !err.contains(&name) {
                failures.push(format!("{} ({kind}): exit {:?}, stderr: {err}", line[0], o.status.code()));
            }
            if out.exists() && (!file_output || !files(&out).is_empty()) {
                failures.push(format!("{} ({kind}): wrote {:?}", line[0], files(&out)));
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
