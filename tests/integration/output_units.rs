//! Outputs in micrometres (issue 22, "lengths in outputs"): `--output-unit um` of `mesh`, `measure`
//! and `simulate`, and `[output] length_unit = "um"` of a pipeline, write the SI numbers scaled (the
//! tissue's points × 1e6, volumes × 1e18 under `volume_um3`, …) with the unit recorded, and a µm
//! `.vtp` reads back as the SI tissue. Tolerance 1e-12 relative: scaling by 1e6 and back by 1e-6 is
//! two roundings (~2e-16 each); anything near 1e-12 would be a wrong factor or a lost unit.

use crate::support::cli::{ok, repo, short_demo_fit_pipeline, tissuefit};
use crate::support::run_dirs::{normalised_hash, read_json};
use std::path::{Path, PathBuf};
use tissuefit::geometry::{Vec3, bounding_box};
use tissuefit::io::{LENGTH_UNIT_FIELD, ReadOptions, read_tissue, read_tissue_bytes};
use tissuefit::mesh::Tissue;

const TOL: f64 = 1e-12;

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= TOL * b.abs().max(a.abs())
}

fn read(path: &Path) -> Tissue {
    read_tissue(path, &ReadOptions::default()).unwrap().tissue
}

/// The tissue as the file's numbers are, with its `length_unit` field taken out of the XML header
/// (the appended data's offsets count from its own start, so they still hold): the raw coordinates.
fn raw(path: &Path) -> Tissue {
    let bytes = std::fs::read(path).unwrap();
    let text = String::from_utf8_lossy(&bytes);
    let start = text.find(&format!("<DataArray type=\"String\" Name=\"{LENGTH_UNIT_FIELD}\"")).expect("length_unit");
    let end = start + text[start..].find("</DataArray>").unwrap() + "</DataArray>".len();
    let mut stripped = bytes[..start].to_vec();
    stripped.extend_from_slice(&bytes[end..]);
    read_tissue_bytes(path, &stripped, &ReadOptions::default()).unwrap().tissue
}

fn bbox(t: &Tissue) -> (Vec3, Vec3) {
    let points: Vec<Vec3> = t.cells().iter().flat_map(|c| c.mesh().positions().iter().copied()).collect();
    bounding_box(&points).unwrap()
}

fn assert_same_tissue(a: &Tissue, b: &Tissue) {
    assert_eq!(a.len(), b.len());
    for (x, y) in a.cells().iter().zip(b.cells()) {
        assert_eq!((x.id(), x.kind(), x.face_types()), (y.id(), y.kind(), y.face_types()));
        assert_eq!(x.mesh().triangles(), y.mesh().triangles());
        for (p, q) in x.mesh().positions().iter().zip(y.mesh().positions()) {
            assert!((p - q).norm() <= TOL * q.norm(), "{p} vs {q}");
        }
        assert!(close(x.target_volume(), y.target_volume()));
    }
}

/// `cells.csv` as rows of `name → value` (empty cells left out).
fn table(path: &Path) -> (Vec<String>, Vec<std::collections::HashMap<String, f64>>) {
    let mut r = csv::Reader::from_path(path).unwrap();
    let header: Vec<String> = r.headers().unwrap().iter().map(str::to_string).collect();
    let rows = r
        .records()
        .map(|rec| {
            let rec = rec.unwrap();
            header.iter().zip(rec.iter()).filter_map(|(h, v)| v.parse::<f64>().ok().map(|v| (h.clone(), v))).collect()
        })
        .collect();
    (header, rows)
}

#[test]
fn mesh_and_measure_in_micrometres_write_the_si_numbers_scaled_and_read_back_in_metres() {
    let tmp = tempfile::tempdir().unwrap();
    let labels = repo().join("data/demo/doublet.tif");
    let (si, um) = (tmp.path().join("si.vtp"), tmp.path().join("um.vtp"));
    let mesh = ["--seed", "3", "--target-nodes", "150"];
    ok(&[&["mesh", labels.to_str().unwrap(), "--out", si.to_str().unwrap()][..], &mesh].concat());
    ok(&[&["mesh", labels.to_str().unwrap(), "--out", um.to_str().unwrap(), "--output-unit", "um"][..], &mesh]
        .concat());

    // The file's coordinates are the SI ones × 1e6: ParaView's axes read µm.
    let (tissue_si, file_um) = (read(&si), raw(&um));
    let ((lo, hi), (lo_um, hi_um)) = (bbox(&tissue_si), bbox(&file_um));
    for k in 0..3 {
        assert!(close(lo_um[k], lo[k] * 1e6) && close(hi_um[k], hi[k] * 1e6), "axis {k}: {lo_um} {hi_um} vs {lo} {hi}");
    }
    assert!(hi_um.x - lo_um.x > 1.0, "a cell spans micrometres, not {}", hi_um.x - lo_um.x);
    // Read by tissuefit, the µm file is the SI tissue: the reader finds the unit itself.
    assert_same_tissue(&read(&um), &tissue_si);
    // The same unit given again is accepted; another is refused (the file says what it is).
    let again = read_tissue(&um, &ReadOptions { length_scale: "um".parse().unwrap(), orient: false }).unwrap();
    assert_same_tissue(&again.tissue, &tissue_si);
    let e = read_tissue(&um, &ReadOptions { length_scale: "nm".parse().unwrap(), orient: false }).unwrap_err();
    assert!(e.to_string().contains("records its length unit (um)"), "{e}");
    // The report stays in metres and says the tissue is not.
    let (report_si, report_um) =
        (read_json(&tmp.path().join("si.report.json")), read_json(&tmp.path().join("um.report.json")));
    assert_eq!(report_um["tissue_length_unit"], "um");
    assert!(report_si.get("tissue_length_unit").is_none());
    assert_eq!(report_um["l_min"], report_si["l_min"]);
    // A SimuCell3D legacy file is in metres: µm is refused before anything is meshed.
    let vtk = tmp.path().join("um.vtk");
    let o = tissuefit(&["mesh", labels.to_str().unwrap(), "--out", vtk.to_str().unwrap(), "--output-unit", "um"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("legacy .vtk is in metres"));
    assert!(!vtk.exists());

    // measure: SI tissue in SI, the same tissue in µm, and the µm file in SI.
    let (m_si, m_um, m_back) = (tmp.path().join("m_si"), tmp.path().join("m_um"), tmp.path().join("m_back"));
    ok(&["measure", si.to_str().unwrap(), "--out", m_si.to_str().unwrap()]);
    ok(&["measure", si.to_str().unwrap(), "--out", m_um.to_str().unwrap(), "--output-unit", "um"]);
    ok(&["measure", um.to_str().unwrap(), "--out", m_back.to_str().unwrap()]);
    let ((h_si, rows_si), (h_um, rows_um)) = (table(&m_si.join("cells.csv")), table(&m_um.join("cells.csv")));
    assert_eq!(h_si.len(), h_um.len());
    for name in ["volume_um3", "area_um2", "contact_area_um2", "semi_axis_1_um", "centroid_x_um"] {
        assert!(h_um.iter().any(|h| h == name), "{name} not in {h_um:?}");
    }
    assert!(!h_um.iter().any(|h| h == "volume") && h_si.iter().any(|h| h == "volume"));
    assert_eq!(rows_si.len(), 2);
    for (s, u) in rows_si.iter().zip(&rows_um) {
        assert!(close(u["volume_um3"], s["volume"] * 1e18), "{} vs {}", u["volume_um3"], s["volume"]);
        assert!(close(u["area_um2"], s["area"] * 1e12));
        assert!(close(u["centroid_x_um"], s["centroid_x"] * 1e6));
        assert!(close(u["semi_axis_1_um"], s["semi_axis_1"] * 1e6));
        assert_eq!(u["sphericity"], s["sphericity"]);
        assert_eq!(u["cell"], s["cell"]);
        assert!(u["volume_um3"] > 1.0 && s["volume"] < 1e-12, "µm³ volumes are cell-sized numbers");
    }
    let (c_si, c_um) = (table(&m_si.join("contacts.csv")), table(&m_um.join("contacts.csv")));
    assert!(c_um.0.iter().any(|h| h == "area_um2") && !c_um.1.is_empty());
    assert!(close(c_um.1[0]["area_um2"], c_si.1[0]["area"] * 1e12));
    let (j_si, j_um) = (read_json(&m_si.join("summary.json")), read_json(&m_um.join("summary.json")));
    assert_eq!(j_um["length_unit"], "um");
    assert!(j_si.get("length_unit").is_none());
    let (v_si, v_um) = (&j_si["statistics"]["volume"], &j_um["statistics"]["volume_um3"]);
    assert!(close(v_um["mean"].as_f64().unwrap(), v_si["mean"].as_f64().unwrap() * 1e18));
    assert_eq!(v_um["count"], v_si["count"]);
    assert_eq!(j_um["mean_sphericity"], j_si["mean_sphericity"]);
    // The µm tissue measured in SI gives the SI numbers.
    let (_, rows_back) = table(&m_back.join("cells.csv"));
    for (s, b) in rows_si.iter().zip(&rows_back) {
        assert!(close(b["volume"], s["volume"]) && close(b["area"], s["area"]), "{b:?} vs {s:?}");
    }
}

/// `[output] length_unit = "um"`: the user-facing files in µm, the stage-to-stage `mesh/tissue.vtp`
/// in metres (the same file as without the key), so measure and simulate get the SI tissue: their
/// numbers are the SI run's × the unit's powers, and the simulation itself (its SI `summary.json`)
/// is the same.
/// Runs the pipeline `body` into `dir/run_si`, and with `[output] length_unit = "um"` added (written
/// to `dir/um.toml`) into `dir/run_um`; either may end unconverged (exit 1), not fail. Returns both
/// run folders and the µm pipeline file.
fn run_in_metres_and_micrometres(dir: &Path, body: &str) -> (PathBuf, PathBuf, PathBuf) {
    let (p_si, p_um) = (dir.join("si.toml"), dir.join("um.toml"));
    std::fs::write(&p_si, body).unwrap();
    std::fs::write(&p_um, format!("{body}\n[output]\nlength_unit = \"um\"\n")).unwrap();
    let (r_si, r_um) = (dir.join("run_si"), dir.join("run_um"));
    for (p, r) in [(&p_si, &r_si), (&p_um, &r_um)] {
        let o = tissuefit(&["run", p.to_str().unwrap(), "--out", r.to_str().unwrap()]);
        assert!(o.status.code().is_some_and(|c| c <= 1), "{}", String::from_utf8_lossy(&o.stderr));
    }
    (r_si, r_um, p_um)
}

#[test]
fn a_pipeline_in_micrometres_writes_micrometre_outputs_and_its_stages_read_si() {
    let tmp = tempfile::tempdir().unwrap();
    let labels = repo().join("data/demo/doublet.tif");
    let model = repo().join("data/demo/doublet_truth.toml");
    let body = format!(
        "[input]\nlabels = {labels:?}\nseed = 3\n\n[mesh]\ntarget_nodes = 120\n\n[simulate]\nmodel = {model:?}\n\
         [simulate.model_overrides.simulation]\nmax_steps = 200\n",
        labels = labels.display().to_string(),
        model = model.display().to_string()
    );
    let (r_si, r_um, _) = run_in_metres_and_micrometres(tmp.path(), &body);
    // The stage-to-stage files are SI and identical; the µm copy is for people.
    for file in ["mesh/tissue.vtp", "mesh/report.json", "simulate/summary.json", "simulate/final.vtk"] {
        assert_eq!(normalised_hash(&r_si.join(file)), normalised_hash(&r_um.join(file)), "{file}");
    }
    assert!(!r_si.join("mesh/tissue_um.vtp").exists());
    let tissue = read(&r_si.join("mesh/tissue.vtp"));
    assert_same_tissue(&read(&r_um.join("mesh/tissue_um.vtp")), &tissue);
    let (lo, hi) = bbox(&tissue);
    let (lo_um, hi_um) = bbox(&raw(&r_um.join("mesh/tissue_um.vtp")));
    assert!(close(lo_um.x, lo.x * 1e6) && close(hi_um.z, hi.z * 1e6));
    // The µm copy is the file `tissuefit mesh --output-unit um` writes with the same settings.
    let cli = tmp.path().join("cli_um.vtp");
    let flags = ["--output-unit", "um", "--seed", "3", "--target-nodes", "120"];
    ok(&[&["mesh", labels.to_str().unwrap(), "--out", cli.to_str().unwrap()][..], &flags].concat());
    assert_eq!(std::fs::read(&cli).unwrap(), std::fs::read(r_um.join("mesh/tissue_um.vtp")).unwrap());

    // measure: µm columns, the SI run's numbers scaled.
    for (dir, file) in [("measure", "cells.csv"), ("simulate", "cells.csv")] {
        let ((_, s), (h, u)) = (table(&r_si.join(dir).join(file)), table(&r_um.join(dir).join(file)));
        assert!(h.iter().any(|c| c == "volume_um3"), "{dir}/{file}: {h:?}");
        for (s, u) in s.iter().zip(&u) {
            assert!(close(u["volume_um3"], s["volume"] * 1e18), "{dir}: {} vs {}", u["volume_um3"], s["volume"]);
            assert!(close(u["area_um2"], s["area"] * 1e12), "{dir}");
        }
    }
    assert_eq!(read_json(&r_um.join("measure/summary.json"))["length_unit"], "um");
    assert_eq!(read_json(&r_um.join("simulate/morphology.json"))["length_unit"], "um");
    // simulate: frames and final.vtp in µm, read back as the SI run's; stats.csv renamed and scaled.
    assert_same_tissue(&read(&r_um.join("simulate/final.vtp")), &read(&r_si.join("simulate/final.vtp")));
    assert_same_tissue(
        &read(&r_um.join("simulate/frames/frame_000000.vtp")),
        &read(&r_si.join("simulate/frames/frame_000000.vtp")),
    );
    let ((_, s), (h, u)) = (table(&r_si.join("simulate/stats.csv")), table(&r_um.join("simulate/stats.csv")));
    assert!(h.iter().any(|c| c == "target_volume_um3") && h.iter().any(|c| c == "area_um2"), "{h:?}");
    assert_eq!(s.len(), u.len());
    for (s, u) in s.iter().zip(&u) {
        assert!(close(u["volume_um3"], s["volume"] * 1e18) && close(u["target_volume_um3"], s["target_volume"] * 1e18));
        assert_eq!(u["energy_total"], s["energy_total"]);
    }
}

/// The fit's best tissue follows the output unit: a pipeline with `[output] length_unit = "um"`
/// writes `fit/best.vtp` in µm (the unit recorded, read back as the SI fit's tissue), `tissuefit fit
/// --config` of that pipeline takes its unit (the same bytes), `--output-unit m` overrides it back to
/// the SI file, and the files the fit reads back (trace, result, best model) do not change.
#[test]
fn a_fit_in_micrometres_writes_its_best_tissue_in_micrometres_and_the_rest_si() {
    let tmp = tempfile::tempdir().unwrap();
    let body = short_demo_fit_pipeline(5, 8e-4, 2);
    let (r_si, r_um, p_um) = run_in_metres_and_micrometres(tmp.path(), &body);
    let (best_si, best_um) = (r_si.join("fit/best.vtp"), r_um.join("fit/best.vtp"));
    assert_same_tissue(&read(&best_um), &read(&best_si));
    let (lo, hi) = bbox(&read(&best_si));
    let (lo_um, hi_um) = bbox(&raw(&best_um));
    assert!(close(lo_um.x, lo.x * 1e6) && close(hi_um.z, hi.z * 1e6), "{lo_um} vs {lo}");
    for file in ["fit/trace.csv", "fit/best.toml", "fit/residuals.csv"] {
        assert_eq!(normalised_hash(&r_si.join(file)), normalised_hash(&r_um.join(file)), "{file}");
    }
    let (h, rows) = table(&r_um.join("fit/residuals.csv"));
    assert!(h.iter().any(|c| c == "free_area_um2_observed"), "{h:?}");
    for row in &rows {
        assert!(close(row["free_area_um2_observed"], row["free_area_m2_observed"] * 1e12));
        assert!(close(row["volume_um3_observed"], row["volume_m3_observed"] * 1e18));
    }
    // `tissuefit fit --config PIPELINE` takes the pipeline's unit; --output-unit overrides it.
    let cli = |dir: &str, extra: &[&str]| {
        let out = tmp.path().join(dir);
        let args = [&["fit", "--config", p_um.to_str().unwrap(), "--out", out.to_str().unwrap()][..], extra].concat();
        let o = tissuefit(&args);
        assert!(o.status.code().is_some_and(|c| c <= 1), "{}", String::from_utf8_lossy(&o.stderr));
        std::fs::read(out.join("best.vtp")).unwrap()
    };
    assert_eq!(cli("cli_um", &[]), std::fs::read(&best_um).unwrap());
    assert_eq!(cli("cli_m", &["--output-unit", "m"]), std::fs::read(&best_si).unwrap());
}
