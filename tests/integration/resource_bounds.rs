//! Resource bounds, through the `tissuefit` binary (issue 23, items 3–5 and 8): sizes that used to
//! panic ("capacity overflow", exit 101), abort (SIGABRT, exit 134) or read until memory ran out
//! must be checked before anything is allocated and refused with exit code 2, a message naming the
//! option or file and what to do, and no output left behind.
//!
//! The crafted TIFFs are built here: many pages whose headers all point at one data strip, so that
//! a small file declares tens of GiB of voxels.

use std::io::Cursor;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::{Duration, Instant};
use tissuefit::geometry::Vec3;
use tissuefit::imaging::{LabelReadOptions, LabelVolume, LabelWriteOptions, read_label_tiff, write_label_tiff};

fn tissuefit(args: &[String], env: &[(&str, &str)]) -> Output {
    let mut command = Command::new(env!("CARGO_BIN_EXE_tissuefit"));
    command.args(args).env_remove("TISSUEFIT_MEMORY_LIMIT");
    for (k, v) in env {
        command.env(k, v);
    }
    command.output().expect("the tissuefit binary runs")
}

fn demo(name: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("data/demo").join(name).to_str().unwrap().to_string()
}

fn path(dir: &Path, name: &str) -> String {
    dir.join(name).to_str().unwrap().to_string()
}

fn args(list: &[&str]) -> Vec<String> {
    list.iter().map(|s| s.to_string()).collect()
}

/// The demo doublet re-saved with another voxel size in its ImageJ metadata.
fn doublet_with_voxel_size(dir: &Path, name: &str, voxel_size: [f64; 3]) -> String {
    let read = read_label_tiff(Path::new(&demo("doublet.tif")), &LabelReadOptions::default()).unwrap();
    let volume = LabelVolume::new(read.volume.labels().clone(), voxel_size, Vec3::zeros()).unwrap();
    let out = dir.join(name);
    write_label_tiff(&out, &volume, &LabelWriteOptions::default()).unwrap();
    out.to_str().unwrap().to_string()
}

/// A little-endian classic TIFF of `pages` 8-bit pages of `width`×`height`, every page one strip
/// pointing at the same `strip` bytes (compression 1 = none, 8 = Deflate).
fn shared_strip_tiff(pages: usize, width: u32, height: u32, compression: u16, strip: &[u8]) -> Vec<u8> {
    let mut b = b"II*\0".to_vec();
    let first_ifd = 8 + strip.len() as u32;
    b.extend_from_slice(&first_ifd.to_le_bytes());
    b.extend_from_slice(strip);
    const SHORT: u16 = 3;
    const LONG: u16 = 4;
    let entries = [
        (256, LONG, width),
        (257, LONG, height),
        (258, SHORT, 8),
        (259, SHORT, compression as u32),
        (262, SHORT, 1),
        (273, LONG, 8),
        (277, SHORT, 1),
        (278, LONG, height),
        (279, LONG, strip.len() as u32),
    ];
    let ifd_len = 2 + 12 * entries.len() as u32 + 4;
    for page in 0..pages {
        b.extend_from_slice(&(entries.len() as u16).to_le_bytes());
        for &(tag, ty, value) in &entries {
            b.extend_from_slice(&(tag as u16).to_le_bytes());
            b.extend_from_slice(&ty.to_le_bytes());
            b.extend_from_slice(&1u32.to_le_bytes());
            b.extend_from_slice(&value.to_le_bytes());
        }
        let next = if page + 1 < pages { first_ifd + (page as u32 + 1) * ifd_len } else { 0 };
        b.extend_from_slice(&next.to_le_bytes());
    }
    b
}

/// The Deflate stream of one all-zero 8-bit `width`×`height` page, as the tiff crate's encoder
/// writes it (one strip).
fn deflated_zero_page(width: u32, height: u32) -> Vec<u8> {
    use tiff::decoder::Decoder;
    use tiff::encoder::{Compression, DeflateLevel, TiffEncoder, colortype};
    use tiff::tags::Tag;
    let mut bytes = Cursor::new(Vec::new());
    let mut encoder =
        TiffEncoder::new(&mut bytes).unwrap().with_compression(Compression::Deflate(DeflateLevel::Balanced));
    let mut image = encoder.new_image::<colortype::Gray8>(width, height).unwrap();
    image.rows_per_strip(height).unwrap();
    image.write_data(&vec![0u8; width as usize * height as usize]).unwrap();
    let bytes = bytes.into_inner();
    let mut decoder = Decoder::new(Cursor::new(&bytes)).unwrap();
    let offsets = decoder.get_tag_u64_vec(Tag::StripOffsets).unwrap();
    let counts = decoder.get_tag_u64_vec(Tag::StripByteCounts).unwrap();
    assert_eq!(offsets.len(), 1, "one strip");
    bytes[offsets[0] as usize..(offsets[0] + counts[0]) as usize].to_vec()
}

fn symlink_to_dev_zero(dir: &Path, name: &str) -> String {
    let link = dir.join(name);
    std::os::unix::fs::symlink("/dev/zero", &link).unwrap();
    link.to_str().unwrap().to_string()
}

/// What a case must produce.
struct Case {
    name: &'static str,
    /// Environment variables set for the run (TISSUEFIT_MEMORY_LIMIT is cleared otherwise).
    env: &'static [(&'static str, &'static str)],
    /// Writes the inputs into the folder and returns the command line.
    setup: fn(&Path) -> Vec<String>,
    /// Every one of these must appear in stderr.
    says: &'static [&'static str],
}

const CASES: &[Case] = &[
    Case {
        name: "item 3: --voxel-size with one axis 10²⁰ times the others (mesh panicked: capacity overflow): refused as implausible",
        env: &[],
        setup: |d| {
            let mut a = args(&["mesh", &demo("doublet.tif"), "--voxel-size", "1e14,4e-7,4e-7", "--out"]);
            a.push(path(d, "out.vtp"));
            a
        },
        says: &["--voxel-size", "1e14", "plausible range"],
    },
    Case {
        name: "item 3: a plausible --voxel-size 2,500 times finer on two axes (mesh): refused as too anisotropic",
        env: &[],
        setup: |d| {
            let mut a = args(&["mesh", &demo("doublet.tif"), "--voxel-size", "1e-3,4e-7,4e-7", "--out"]);
            a.push(path(d, "out.vtp"));
            a
        },
        says: &["doublet.tif", "--voxel-size", "times the smallest"],
    },
    Case {
        name: "item 3: --voxel-size with one axis 10²⁰ times the others (measure): refused as implausible",
        env: &[],
        setup: |d| {
            let mut a = args(&["measure", &demo("doublet.tif"), "--voxel-size", "1e14,4e-7,4e-7", "--out"]);
            a.push(path(d, "measured"));
            a
        },
        says: &["--voxel-size", "1e14", "plausible range"],
    },
    Case {
        name: "item 3: a plausible --voxel-size 2,500 times finer on two axes (measure): refused as too anisotropic",
        env: &[],
        setup: |d| {
            let mut a = args(&["measure", &demo("doublet.tif"), "--voxel-size", "1e-3,4e-7,4e-7", "--out"]);
            a.push(path(d, "measured"));
            a
        },
        says: &["doublet.tif", "--voxel-size", "times the smallest"],
    },
    Case {
        name: "item 3: a TIFF's own ImageJ spacing=1e30 µm (mesh)",
        env: &[],
        setup: |d| {
            let tif = doublet_with_voxel_size(d, "huge_spacing.tif", [1e24, 4e-7, 4e-7]);
            vec!["mesh".into(), tif, "--out".into(), path(d, "out.vtp")]
        },
        says: &["huge_spacing.tif", "TIFF's metadata"],
    },
    Case {
        name: "item 3: a TIFF's own ImageJ spacing=1e30 µm (measure)",
        env: &[],
        setup: |d| {
            let tif = doublet_with_voxel_size(d, "huge_spacing.tif", [1e24, 4e-7, 4e-7]);
            vec!["measure".into(), tif, "--out".into(), path(d, "measured")]
        },
        says: &["huge_spacing.tif", "TIFF's metadata"],
    },
    Case {
        name: "item 8: measure at z/xy = 50 reported sphericity > 1 with exit 0",
        env: &[],
        setup: |d| {
            let tif = doublet_with_voxel_size(d, "anisotropic.tif", [2e-5, 4e-7, 4e-7]);
            vec!["measure".into(), tif, "--out".into(), path(d, "measured")]
        },
        says: &["anisotropic.tif", "50.0 times the smallest", "more than the 20", "resample"],
    },
    Case {
        name: "item 8: mesh refuses z/xy = 50 with the same check",
        env: &[],
        setup: |d| {
            let tif = doublet_with_voxel_size(d, "anisotropic.tif", [2e-5, 4e-7, 4e-7]);
            vec!["mesh".into(), tif, "--out".into(), path(d, "out.vtp")]
        },
        says: &["anisotropic.tif", "50.0 times the smallest", "more than the 20"],
    },
    Case {
        name: "item 4: 600 pages of 4096² sharing one 16 MiB strip (aborted at 4.1 GB)",
        env: &[],
        setup: |d| {
            let tif = d.join("shared_strip.tif");
            std::fs::write(&tif, shared_strip_tiff(600, 4096, 4096, 1, &vec![0u8; 4096 * 4096])).unwrap();
            vec!["mesh".into(), tif.to_str().unwrap().into(), "--out".into(), path(d, "out.vtp")]
        },
        says: &["shared_strip.tif", "600 pages of 4096 × 4096", "memory limit", "TISSUEFIT_MEMORY_LIMIT"],
    },
    Case {
        name: "item 4: 2000 Deflate pages of 4096² sharing one small strip",
        env: &[],
        setup: |d| {
            let tif = d.join("deflate_pages.tif");
            std::fs::write(&tif, shared_strip_tiff(2000, 4096, 4096, 8, &deflated_zero_page(4096, 4096))).unwrap();
            vec!["measure".into(), tif.to_str().unwrap().into(), "--out".into(), path(d, "measured")]
        },
        says: &["deflate_pages.tif", "2000 pages of 4096 × 4096", "memory limit", "TISSUEFIT_MEMORY_LIMIT"],
    },
    Case {
        name: "item 8: measure's memory (13 bytes/voxel) is checked against the limit before reading",
        env: &[("TISSUEFIT_MEMORY_LIMIT", "100KiB")],
        setup: |d| args(&["measure", &demo("doublet.tif"), "--out", &path(d, "measured")]),
        says: &["doublet.tif", "13 bytes per voxel", "memory limit of 100.0 KiB", "TISSUEFIT_MEMORY_LIMIT"],
    },
    Case {
        name: "an unreadable TISSUEFIT_MEMORY_LIMIT",
        env: &[("TISSUEFIT_MEMORY_LIMIT", "lots")],
        setup: |d| args(&["mesh", &demo("doublet.tif"), "--out", &path(d, "out.vtp")]),
        says: &["TISSUEFIT_MEMORY_LIMIT=\"lots\"", "64GiB"],
    },
    Case {
        name: "item 5: voxelize --voxel-size 1nm (SIGABRT)",
        env: &[],
        setup: |d| {
            args(&["voxelize", &demo("cell_quartet.vtk"), "--voxel-size", "1nm", "--out", &path(d, "labels.tif")])
        },
        says: &["--voxel-size", "memory limit", "TISSUEFIT_MEMORY_LIMIT"],
    },
    Case {
        name: "item 5: voxelize --shape 100000,100000,100000 (SIGABRT)",
        env: &[],
        setup: |d| {
            args(&[
                "voxelize",
                &demo("cell_quartet.vtk"),
                "--voxel-size",
                "1um",
                "--shape",
                "100000,100000,100000",
                "--out",
                &path(d, "labels.tif"),
            ])
        },
        says: &["--shape", "100000 × 100000 × 100000", "memory limit"],
    },
    Case {
        name: "item 5: generate labels --shape 2000 (SIGABRT)",
        env: &[],
        setup: |d| args(&["generate", "labels", "--kind", "sphere", "--shape", "2000", "--out", &path(d, "g.tif")]),
        says: &["--shape", "2000 × 2000 × 2000", "memory limit"],
    },
    Case {
        name: "item 5: a tissue file that is a symlink to /dev/zero (read until memory ran out)",
        env: &[],
        setup: |d| {
            let tissue = symlink_to_dev_zero(d, "zero.vtk");
            args(&["simulate", &tissue, "--out", &path(d, "run"), "--max-steps", "1"])
        },
        says: &["zero.vtk", "not a regular file"],
    },
    Case {
        name: "item 5: a --config that is a symlink to /dev/zero",
        env: &[],
        setup: |d| {
            let config = symlink_to_dev_zero(d, "zero.toml");
            args(&["simulate", &demo("cell_quartet.vtk"), "--config", &config, "--out", &path(d, "run")])
        },
        says: &["zero.toml", "not a regular file"],
    },
];

/// Every file under `dir`, relative, sorted.
fn files(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() && !p.is_symlink() {
                stack.push(p.clone());
            }
            out.push(p.strip_prefix(dir).unwrap().to_path_buf());
        }
    }
    out.sort();
    out
}

#[test]
fn every_oversized_input_is_refused_before_allocation_with_a_clear_error() {
    let mut failures = Vec::new();
    for case in CASES {
        let dir = tempfile::tempdir().unwrap();
        let args = (case.setup)(dir.path());
        let before = files(dir.path());
        let started = Instant::now();
        let out = tissuefit(&args, case.env);
        let seconds = started.elapsed().as_secs_f64();
        let err = String::from_utf8_lossy(&out.stderr);
        let mut problems = Vec::new();
        // 2 = error; never 0 (silent success), 101 (panic) or 134 (abort), nor killed by a signal.
        if out.status.code() != Some(2) {
            problems.push(format!("exit code {:?}, expected 2", out.status.code()));
        }
        if err.contains("panicked") || err.contains("memory allocation") {
            problems.push("panicked or failed to allocate".into());
        }
        for s in case.says {
            if !err.contains(s) {
                problems.push(format!("stderr lacks `{s}`"));
            }
        }
        // Refused from the declared sizes, not after allocating: seconds, not minutes. (Reading a
        // capped 256 MiB from /dev/zero is the slowest case.)
        if seconds > 20.0 {
            problems.push(format!("took {seconds:.1} s"));
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

/// `--threads 100000` hung; it is capped at 4 per core with a warning and the command runs.
#[test]
fn absurd_thread_counts_are_capped_with_a_warning() {
    let started = Instant::now();
    let out = tissuefit(&args(&["--threads", "100000", "inspect", &demo("cell_quartet.vtk")]), &[]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{err}");
    assert!(err.contains("--threads 100000: using") && err.contains("per available core"), "{err}");
    assert!(started.elapsed() < Duration::from_secs(30), "took {:?}", started.elapsed());
}

/// The limit is a limit, not a guess: a volume just under it reads, the same volume with the
/// limit one byte lower does not (4 bytes per voxel for the volume itself).
#[test]
fn the_memory_limit_is_exact_at_the_declared_size() {
    let dir = tempfile::tempdir().unwrap();
    let tif = doublet_with_voxel_size(dir.path(), "doublet.tif", [5e-7; 3]);
    let read = read_label_tiff(Path::new(&tif), &LabelReadOptions::default()).unwrap();
    let bytes = 4 * read.volume.labels().len();
    for (limit, ok) in [(bytes, true), (bytes - 1, false)] {
        let out = tissuefit(
            &args(&["mesh", &tif, "--out", &path(dir.path(), &format!("{limit}.vtp"))]),
            &[("TISSUEFIT_MEMORY_LIMIT", &limit.to_string())],
        );
        let err = String::from_utf8_lossy(&out.stderr);
        if ok {
            assert!(!err.contains("memory limit"), "limit {limit}: {err}");
        } else {
            assert_eq!(out.status.code(), Some(2), "limit {limit}: {err}");
            assert!(err.contains("memory limit") && err.contains("doublet.tif"), "limit {limit}: {err}");
        }
    }
}
