//! Per-cell tensions and adhesions through the command line (issue 25): `[[cell_overrides]]` in a
//! model file reach the simulation, the final tissue carries them, and `model_cells.csv` /
//! `model_interfaces.csv` report each cell's parameters and each interface's tension T_ab.

use crate::support::cli::tissuefit;
use crate::support::run_dirs::csv_maps as rows;
use tissuefit::geometry::{Real, Vec3};
use tissuefit::io::{ReadOptions, read_tissue, write_tissue};
use tissuefit::mechanics::{CellOverrideConfig, ContactModel, Parameters, PerFaceType, Polarity};
use tissuefit::mesh::shapes::icosphere;
use tissuefit::mesh::{Cell, CellId, CellKind, FaceType, Tissue};

/// Two touching R = 2 µm cells (ids 1 and 2) and a coupled model with polarity from contacts: free
/// faces γ = 1 mN/m, lateral 0.6 mN/m; cell 2 has its own free 0.8 and lateral 0.4 mN/m.
fn doublet_and_model(dir: &std::path::Path) -> (String, String) {
    let r = 2e-6;
    let cells = [-1.0, 1.0]
        .iter()
        .enumerate()
        .map(|(i, s)| {
            let m = icosphere(r, 2, Vec3::new(s * (r + 5e-8), 0.0, 0.0));
            let types = vec![FaceType::Basal; m.face_count()];
            Cell::new(CellId(i as u32 + 1), CellKind::Epithelial, 0, m).with_face_types(types).unwrap()
        })
        .collect();
    let tissue_path = dir.join("doublet.vtp");
    write_tissue(&tissue_path, &Tissue::from_cells(cells).unwrap(), &[]).unwrap();
    let mut p = Parameters::default();
    p.numerics.contact_model = ContactModel::Coupling;
    p.numerics.polarity = Polarity::Contacts;
    // The icosphere's edges are ≈ 0.6 µm: l_min = mean edge / 1.4, as the mesh check asks.
    p.numerics.min_edge_length = 4e-7;
    p.numerics.contact_cutoff = 4e-7;
    let t = &mut p.cell_types[0];
    for ft in FaceType::ALL {
        t.faces.get_mut(ft).surface_tension = if ft == FaceType::Lateral { 0.6e-3 } else { 1e-3 };
        t.faces.get_mut(ft).bending_modulus = 0.0;
    }
    t.area_elasticity = 0.0;
    t.growth_rate = 0.0;
    p.simulation.max_steps = 300;
    let own = PerFaceType { apical: Some(0.8e-3), lateral: Some(0.4e-3), basal: Some(0.8e-3) };
    p.cell_overrides.push(CellOverrideConfig { id: 2, surface_tension: own, adhesion: PerFaceType::default() });
    let model_path = dir.join("model.toml");
    std::fs::write(&model_path, p.to_toml_string()).unwrap();
    (tissue_path.to_str().unwrap().to_owned(), model_path.to_str().unwrap().to_owned())
}

#[test]
fn cell_overrides_in_a_model_file_reach_the_run_its_tissue_and_its_tables() {
    let dir = tempfile::tempdir().unwrap();
    let (tissue, model) = doublet_and_model(dir.path());
    let out = dir.path().join("run");
    let o = tissuefit(&["simulate", &tissue, "--config", &model, "--out", out.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    // 300 steps need not reach equilibrium: then the run says so with exit 1 and still writes its
    // files.
    match o.status.code() {
        Some(0) => {}
        Some(1) => assert!(stderr.contains("NOT converged"), "{stderr}"),
        code => panic!("exit {code:?}: {stderr}"),
    }

    let cells = rows(&out.join("model_cells.csv"));
    assert_eq!(cells.len(), 2);
    let value = |row: &std::collections::BTreeMap<String, String>, key: &str| row[key].parse::<Real>().unwrap();
    assert_eq!(cells[0]["own_values"], "false");
    assert_eq!(cells[1]["own_values"], "true");
    assert_eq!(value(&cells[0], "surface_tension_lateral_n_per_m"), 0.6e-3);
    assert_eq!(value(&cells[1], "surface_tension_lateral_n_per_m"), 0.4e-3);
    assert_eq!(value(&cells[1], "surface_tension_basal_mn_per_m"), 0.8);
    assert!(value(&cells[1], "pressure_pa") > 0.0);
    // The coupled interface pulls with both cells' lateral tensions.
    let interfaces = rows(&out.join("model_interfaces.csv"));
    assert_eq!(interfaces.len(), 1, "{interfaces:?}");
    assert_eq!((interfaces[0]["cell_a"].as_str(), interfaces[0]["cell_b"].as_str()), ("1", "2"));
    assert!((value(&interfaces[0], "tension_mn_per_m") - 1.0).abs() < 1e-12, "{interfaces:?}");
    assert_eq!(interfaces[0]["contact_model"], "coupling");
    assert!(value(&interfaces[0], "area_um2") > 0.0);

    // The final tissue carries cell 2's own values, so a rerun from it needs no model entry.
    for name in ["final.vtp", "final.vtk"] {
        let back = read_tissue(&out.join(name), &ReadOptions::default()).unwrap().tissue;
        let own = back.cell(CellId(2)).unwrap().overrides();
        assert_eq!(own.surface_tension, [Some(0.8e-3), Some(0.4e-3), Some(0.8e-3)], "{name}");
        assert!(back.cell(CellId(1)).unwrap().overrides().is_empty(), "{name}");
    }

    // `config check` accepts the model; an entry naming a cell the tissue lacks is refused before
    // anything is written, naming the entry and the ids there are.
    let check = tissuefit(&["config", "check", &model]);
    assert_eq!(check.status.code(), Some(0), "{}", String::from_utf8_lossy(&check.stderr));
    let wrong = std::fs::read_to_string(&model).unwrap().replace("id = 2", "id = 9");
    let wrong_path = dir.path().join("wrong.toml");
    std::fs::write(&wrong_path, wrong).unwrap();
    let out = dir.path().join("wrong-run");
    let o = tissuefit(&["simulate", &tissue, "--config", wrong_path.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_ne!(o.status.code(), Some(0));
    assert!(stderr.contains("cell_overrides[0]: the tissue has no cell with id 9 (its ids: 1, 2)"), "{stderr}");
    assert!(!out.join("summary.json").exists() && !out.join("final.vtp").exists());
}
