//! The direct tension and pressure estimate (`tissuefit tensions`, `morphology::tensions`): exact on an
//! analytic doublet, recovers the Surface Evolver truths (hetero4: six different interface tensions),
//! same output on 1 and 2 threads, and clear errors on bad input.

use crate::support::analytic_doublet;

use analytic_doublet::cap_cell;
use std::path::{Path, PathBuf};
use std::process::Command;
use tissuefit::geometry::{Real, Vec3};
use tissuefit::imaging::{LabelReadOptions, read_label_tiff};
use tissuefit::io::{LengthScale, ReadOptions, read_tissue};
use tissuefit::mesh::shapes::icosphere;
use tissuefit::mesh::{Cell, CellId, CellKind, CellMesh, Tissue};
use tissuefit::meshing::{LabelMeshingOptions, mesh_labels};
use tissuefit::morphology::tensions::{Gauge, TensionError, TensionMap, TensionSettings, estimate_tensions};

fn tissue(meshes: Vec<CellMesh>) -> Tissue {
    Tissue::from_cells(
        meshes
            .into_iter()
            .enumerate()
            .map(|(i, m)| Cell::new(CellId(i as u32 + 1), CellKind::Epithelial, 0, m))
            .collect(),
    )
    .unwrap()
}

fn tension_of(map: &TensionMap, a: u32, b: u32) -> Real {
    let f = map.interfaces.iter().find(|f| (f.cell_a, f.cell_b) == (a, b)).unwrap();
    f.tension.unwrap_or_else(|| panic!("{a}-{b} undetermined"))
}

/// Two spherical caps of radius R on a disc of radius R·sin β (external angle θ = 2β): Young's
/// balance at the rim gives T_12/γ = 2 cos(θ/2) exactly, and each cell's pressure is 2γ/R.
#[test]
fn an_analytic_doublet_gives_young_dupre_and_laplace_within_one_percent() {
    for beta_deg in [35.0_f64, 50.0, 65.0] {
        let (radius, beta) = (5e-6, beta_deg.to_radians());
        let disc = radius * beta.sin();
        // Different resolutions on the two sides: the interface is seen twice on unshared nodes.
        let t = tissue(vec![cap_cell(radius, disc, 128, 48, 16, false), cap_cell(radius, disc, 96, 40, 12, true)]);
        let map = estimate_tensions(&t, &TensionSettings::default()).unwrap();
        let want = 2.0 * beta.cos();
        let got = tension_of(&map, 1, 2);
        assert!((got / want - 1.0).abs() < 0.01, "β = {beta_deg}°: T12 = {got}, want {want}");
        for c in [1, 2] {
            assert!((tension_of(&map, c, 0) - 1.0).abs() < 0.01, "β = {beta_deg}°: γ_{c} = {}", tension_of(&map, c, 0));
        }
        for c in &map.cells {
            let p = c.pressure.unwrap();
            assert!(
                (p * radius / 2.0 - 1.0).abs() < 0.01,
                "β = {beta_deg}°: cell {} p = {p}, want {}",
                c.cell,
                2.0 / radius
            );
        }
        assert!(map.interfaces.iter().all(|f| f.determined && f.samples > 0));
        assert!(map.warnings.is_empty(), "{:?}", map.warnings);
    }
}

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("validation/evolver/fixtures").join(name)
}

fn truth(name: &str) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(fixture(name).join("truth.json")).unwrap()).unwrap()
}

fn evolver_mesh(name: &str) -> Tissue {
    let options = ReadOptions { length_scale: LengthScale(Vec3::repeat(1e-6)), orient: false };
    read_tissue(&fixture(name).join("cluster.vtk"), &options).unwrap().tissue
}

/// The label volume meshed as `tissuefit mesh` does, each face's neighbour read from the labels, and
/// the settings `tissuefit tensions` uses for it (junctions rounded over a voxel, the imaged box).
fn meshed_labels(name: &str, per_diameter: u32) -> (Tissue, TensionSettings) {
    let path = fixture(name).join(format!("labels_{per_diameter}.tif"));
    let volume = read_label_tiff(&path, &LabelReadOptions::default()).unwrap().volume;
    meshed_volume(&volume)
}

fn meshed_volume(volume: &tissuefit::imaging::LabelVolume) -> (Tissue, TensionSettings) {
    let voxel = volume.grid().voxel_size.iter().copied().fold(0.0, Real::max);
    let settings = TensionSettings {
        rounding_scale: Some(voxel),
        field_of_view: Some(tissuefit::morphology::tensions::FieldOfView::of_volume(volume)),
        ..Default::default()
    };
    let mut tissue = mesh_labels(volume, &LabelMeshingOptions::default()).unwrap().tissue;
    tissuefit::meshing::label_interfaces(&mut tissue, volume).unwrap();
    (tissue, settings)
}

/// Relative errors of the cell–cell tensions, of the cell–medium tensions (truth γ_a) and of the
/// pressures (Evolver's pressure / its length unit in µm is in γ per µm).
fn errors(name: &str, map: &TensionMap) -> (Vec<Real>, Vec<Real>, Vec<Real>) {
    let truth = truth(name);
    let mut cell_cell = Vec::new();
    for (pair, v) in truth["interfaces"].as_object().unwrap() {
        let (a, b) = pair.split_once('-').unwrap();
        let (a, b): (u32, u32) = (a.parse().unwrap(), b.parse().unwrap());
        let want = v["tension"].as_f64().unwrap();
        cell_cell.push((tension_of(map, a.min(b), a.max(b)) / want - 1.0).abs());
    }
    let gamma = truth["gamma_a"].as_f64().unwrap();
    let medium =
        map.interfaces.iter().filter(|f| f.cell_b == 0).map(|f| (f.tension.unwrap() / gamma - 1.0).abs()).collect();
    let unit = truth["evolver_length_to_um"].as_f64().unwrap();
    let pressure = map
        .cells
        .iter()
        .map(|c| {
            let want = truth["pressures"][c.cell.to_string()].as_f64().unwrap() / unit;
            (c.pressure.unwrap() * 1e-6 / want - 1.0).abs()
        })
        .collect();
    (cell_cell, medium, pressure)
}

fn median(v: &[Real]) -> Real {
    let mut v = v.to_vec();
    v.sort_by(|a, b| a.total_cmp(b));
    let n = v.len();
    if n % 2 == 1 { v[n / 2] } else { (v[n / 2 - 1] + v[n / 2]) / 2.0 }
}

fn max(v: &[Real]) -> Real {
    v.iter().copied().fold(0.0, Real::max)
}

/// Evolver's own mesh of the heterogeneous tetrahedral cluster: six interface tensions 0.9–1.7 and
/// four pressures, each within 1 %.
#[test]
fn hetero4_on_the_evolver_mesh_recovers_every_tension_and_pressure() {
    let map = estimate_tensions(&evolver_mesh("hetero4"), &TensionSettings::default()).unwrap();
    let (cell_cell, medium, pressure) = errors("hetero4", &map);
    assert_eq!(cell_cell.len(), 6);
    assert!(max(&cell_cell) < 0.01 && max(&medium) < 0.01, "{cell_cell:?} {medium:?}");
    assert!(max(&pressure) < 0.01, "{pressure:?}");
    assert!(map.condition_number.is_some_and(|c| c < 10.0), "{:?}", map.condition_number);
}

/// Issue 25, the map as per-cell parameters: hetero4's six tensions are additive (T_ij = a_i + a_j
/// with a = 0.29, 0.61, 0.77, 0.93), so the per-cell decomposition finds each a_i (within 1 %, the
/// tolerance of the tensions themselves above) with an additive residual near 0; a doublet's one
/// cell–cell interface cannot fix two lateral tensions, which stay undetermined. Through the CLI with
/// `--gauge-tension`, `cell_overrides.toml` holds them in N/m and loads as part of a model.
#[test]
fn per_cell_tensions_of_hetero4_are_its_additive_truth_and_load_as_a_model() {
    let map = estimate_tensions(&evolver_mesh("hetero4"), &TensionSettings::default()).unwrap();
    let per_cell = tissuefit::morphology::tensions::per_cell_tensions(&map);
    let want = [0.29, 0.61, 0.77, 0.93];
    for (c, want) in per_cell.cells.iter().zip(want) {
        let got = c.lateral.unwrap_or_else(|| panic!("cell {}: lateral undetermined", c.cell));
        assert!((got / want - 1.0).abs() < 0.01, "cell {}: a = {got}, want {want}", c.cell);
        assert!((c.free.unwrap() - 1.0).abs() < 0.01, "cell {}: free {:?}", c.cell, c.free);
    }
    assert!(per_cell.additive_residual_rms.unwrap() < 1e-3, "{per_cell:?}");

    let (radius, beta) = (5e-6, 50f64.to_radians());
    let disc = radius * beta.sin();
    let doublet = tissue(vec![cap_cell(radius, disc, 96, 40, 12, false), cap_cell(radius, disc, 96, 40, 12, true)]);
    let map = estimate_tensions(&doublet, &TensionSettings::default()).unwrap();
    let per_cell = tissuefit::morphology::tensions::per_cell_tensions(&map);
    assert!(per_cell.cells.iter().all(|c| c.lateral.is_none() && c.free.is_some()), "{per_cell:?}");
    assert_eq!(per_cell.additive_residual_rms, None);

    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("map");
    let mesh = fixture("hetero4").join("cluster.vtk");
    let o = Command::new(env!("CARGO_BIN_EXE_tissuefit"))
        .args(["tensions", mesh.to_str().unwrap(), "--length-unit", "um", "--gauge-tension", "1"])
        .args(["--out", out.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let snippet = std::fs::read_to_string(out.join("cell_overrides.toml")).unwrap();
    let model = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("validation/evolver/model.toml"))
        .unwrap()
        + "\n"
        + &snippet;
    let params = tissuefit::mechanics::Parameters::from_toml_str(&model, "model + cell_overrides.toml").unwrap();
    assert_eq!(params.cell_overrides.len(), 4, "{snippet}");
    for (entry, want) in params.cell_overrides.iter().zip(want) {
        let lateral = entry.surface_tension.lateral.unwrap();
        assert!((lateral / (want * 1e-3) - 1.0).abs() < 0.01, "cell {}: {lateral} N/m", entry.id);
        assert!(entry.adhesion.is_empty());
    }
    // Without an absolute gauge the file says how to get values and holds none.
    let relative = dir.path().join("relative");
    let o = Command::new(env!("CARGO_BIN_EXE_tissuefit"))
        .args(["tensions", mesh.to_str().unwrap(), "--length-unit", "um", "--out", relative.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let snippet = std::fs::read_to_string(relative.join("cell_overrides.toml")).unwrap();
    assert!(snippet.contains("--gauge-tension") && !snippet.contains("[[cell_overrides]]"), "{snippet}");
}

/// The committed label volumes, meshed as `tissuefit mesh` does: the targets, median
/// per-interface error ≤ 10 % at 10 voxels per diameter and ≤ 5 % at 20 (measured: see
/// docs/src/generated/direct-tensions.md).
#[test]
fn label_volumes_meet_the_median_targets_at_10_and_20_voxels_per_diameter() {
    for (name, per_diameter, target) in [
        ("hetero4", 10, 0.10),
        ("hetero4", 20, 0.05),
        ("tetra", 10, 0.10),
        ("triplet", 20, 0.05),
        ("doublet", 10, 0.10),
        // Twelve cells around a buried one: with each face's neighbour read from the labels, also at
        // 10 voxels per diameter (a contact distance read gaps between the meshes as free surface
        // there: 22 % median, one interface undetermined).
        ("ball12", 10, 0.10),
        ("ball12", 20, 0.05),
    ] {
        let (tissue, settings) = meshed_labels(name, per_diameter);
        let map = estimate_tensions(&tissue, &settings).unwrap();
        let (cell_cell, medium, pressure) = errors(name, &map);
        let all: Vec<Real> = cell_cell.iter().chain(&medium).copied().collect();
        assert!(median(&all) <= target, "{name} at {per_diameter}: median {} > {target}: {all:?}", median(&all));
        assert!(median(&pressure) <= target, "{name} at {per_diameter}: pressures {pressure:?}");
        assert!(!map.warnings.iter().any(|w| w.contains("poorly determined")), "{name}: {:?}", map.warnings);
    }
}

/// Cell 12 of the ball is buried (no free surface): it is said, and its tensions and pressure are
/// still estimated from the junctions.
#[test]
fn a_buried_cell_is_reported_and_still_solved() {
    let map = estimate_tensions(&evolver_mesh("ball12"), &TensionSettings::default()).unwrap();
    assert!(map.warnings.iter().any(|w| w.contains("cell(s) 12 have no free surface")), "{:?}", map.warnings);
    assert!(!map.interfaces.iter().any(|f| (f.cell_a, f.cell_b) == (12, 0)));
    let buried = map.cells.iter().find(|c| c.cell == 12).unwrap();
    assert!(buried.determined && buried.free_mean_curvature.is_none());
    let (cell_cell, _, _) = errors("ball12", &map);
    assert!(median(&cell_cell) < 0.10, "{cell_cell:?}");
}

/// The gauge only scales: fixing interface 1-2 to 0.9 (its truth) gives the same ratios.
#[test]
fn another_gauge_rescales_without_changing_ratios() {
    let t = evolver_mesh("hetero4");
    let medium = estimate_tensions(&t, &TensionSettings::default()).unwrap();
    let settings = TensionSettings { gauge: Gauge::Interface(2, 1), gauge_value: 0.9, ..Default::default() };
    let fixed = estimate_tensions(&t, &settings).unwrap();
    assert!((tension_of(&fixed, 1, 2) - 0.9).abs() < 1e-12);
    let scale = tension_of(&fixed, 1, 2) / tension_of(&medium, 1, 2);
    for (a, b) in medium.interfaces.iter().zip(&fixed.interfaces) {
        assert!((b.tension.unwrap() / a.tension.unwrap() / scale - 1.0).abs() < 1e-9);
    }
    let shared = TensionSettings { one_medium_tension: true, ..Default::default() };
    let one = estimate_tensions(&t, &shared).unwrap();
    let gammas: Vec<Real> = one.interfaces.iter().filter(|f| f.cell_b == 0).map(|f| f.tension.unwrap()).collect();
    assert!(gammas.iter().all(|g| *g == 1.0), "{gammas:?}");
    assert_eq!(one.unknowns, 7);
}

#[test]
fn bad_input_gives_clear_errors() {
    let one = tissue(vec![icosphere(3e-6, 2, Vec3::zeros())]);
    assert_eq!(estimate_tensions(&one, &TensionSettings::default()), Err(TensionError::TooFewCells { cells: 1 }));
    let apart = tissue(vec![icosphere(3e-6, 2, Vec3::zeros()), icosphere(3e-6, 2, Vec3::new(1e-5, 0.0, 0.0))]);
    assert!(matches!(estimate_tensions(&apart, &TensionSettings::default()), Err(TensionError::NoJunctions { .. })));
    let mut nan = icosphere(3e-6, 2, Vec3::new(5.9e-6, 0.0, 0.0));
    nan.positions_mut()[3].x = Real::NAN;
    let bad = tissue(vec![icosphere(3e-6, 2, Vec3::zeros()), nan]);
    assert_eq!(estimate_tensions(&bad, &TensionSettings::default()), Err(TensionError::NonFinite { cell: 2 }));
    let t = evolver_mesh("doublet");
    let wrong = TensionSettings { gauge: Gauge::Interface(1, 7), ..Default::default() };
    let message = estimate_tensions(&t, &wrong).unwrap_err().to_string();
    assert!(message.contains("1-7") && message.contains("labels present: 1, 2"), "{message}");
    let zero = TensionSettings { gauge_value: 0.0, ..Default::default() };
    assert!(matches!(estimate_tensions(&t, &zero), Err(TensionError::InvalidGaugeValue { .. })));
}

fn run_cli(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_tissuefit")).args(args).output().unwrap()
}

/// The README's demo volume (a coupled doublet voxelised at 0.31 µm, about 9 voxels per cell
/// diameter; truth γ_lateral/γ_apical = 0.5, data/demo/README.md): every interface determined, and
/// the wall's tension over the mean cell–medium tension is 2·γ_lateral/γ_apical = 1. With each face's
/// neighbour read from the labels, the wall there lies half a voxel off the caps' mid-plane; before
/// the junction tolerance allowed that (half a scale length), every one of its 69 junction samples was
/// dropped and the command failed. Measured 1.007 (0.7 %); bound 5 %, half the 10-voxel
/// target (one interface of a symmetric doublet, no vertex or small patch to excuse more).
#[test]
fn the_demo_doublet_gives_its_wall_tension_at_nine_voxels_per_diameter() {
    let dir = tempfile::tempdir().unwrap();
    let demo = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/demo/doublet.tif");
    let out = dir.path().join("map");
    let o = run_cli(&["tensions", demo.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let summary: serde_json::Value = serde_json::from_slice(&std::fs::read(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["contact_rule"], "interface_labels");
    assert_eq!(summary["determined_interfaces"], 3, "{summary}");
    let mut reader = csv::Reader::from_path(out.join("interfaces.csv")).unwrap();
    let headers = reader.headers().unwrap().clone();
    let column = |name: &str| headers.iter().position(|h| h == name).unwrap();
    let (a, b, t) = (column("cell_a"), column("cell_b"), column("tension"));
    let wall = reader
        .records()
        .map(|r| r.unwrap())
        .find(|r| r[a].parse::<u32>().unwrap() != 0 && r[b].parse::<u32>().unwrap() != 0)
        .expect("the wall 1-2")[t]
        .parse::<Real>()
        .unwrap();
    assert!((wall - 1.0).abs() < 0.05, "wall tension {wall} (truth 1)");
}

/// The command writes its four files, identical on 1 and 2 threads (summary.json up to timing and
/// thread count), and refuses a lone cell with a message naming the file.
#[test]
fn the_command_writes_the_same_map_on_one_and_two_threads() {
    let dir = tempfile::tempdir().unwrap();
    let labels = fixture("hetero4").join("labels_20.tif");
    let mut outputs = Vec::new();
    for threads in ["1", "2"] {
        let out = dir.path().join(format!("t{threads}"));
        let o = run_cli(&["tensions", labels.to_str().unwrap(), "--out", out.to_str().unwrap(), "--threads", threads]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let read = |f: &str| std::fs::read(out.join(f)).unwrap();
        let mut summary: serde_json::Value = serde_json::from_slice(&read("summary.json")).unwrap();
        summary["wall_seconds"] = 0.into();
        summary["threads"] = 0.into();
        outputs.push((read("interfaces.csv"), read("cells.csv"), read("tensions.vtp"), summary));
    }
    assert!(outputs[0] == outputs[1], "1 and 2 threads differ");
    let header = String::from_utf8(outputs[0].0.clone()).unwrap();
    assert!(header.starts_with("cell_a,cell_b,tension,tension_sd,determined,area_um2,samples"), "{header}");
    let vtp = String::from_utf8_lossy(&outputs[0].2).into_owned();
    assert!(vtp.contains("Name=\"tension\"") && vtp.contains("Name=\"pressure\""));

    // A known tension sets the unit: interface 1-2 = 0.5 mN/m, pressures in kPa.
    let cluster = fixture("hetero4").join("cluster.vtk");
    let out = dir.path().join("mn");
    let o = run_cli(&[
        "tensions",
        cluster.to_str().unwrap(),
        "--length-unit",
        "um",
        "--gauge",
        "1-2",
        "--gauge-tension",
        "0.5mN/m",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let summary: serde_json::Value = serde_json::from_slice(&std::fs::read(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!((summary["tension_unit"].as_str(), summary["pressure_unit"].as_str()), (Some("mN/m"), Some("kPa")));
    let csv = std::fs::read_to_string(out.join("interfaces.csv")).unwrap();
    let row = csv.lines().find(|l| l.starts_with("1,2,")).unwrap();
    assert!(row.starts_with("1,2,0.5,"), "{row}");
    let o = run_cli(&["tensions", cluster.to_str().unwrap(), "--gauge", "3-3", "--out", out.to_str().unwrap()]);
    assert!(!o.status.success() && String::from_utf8_lossy(&o.stderr).contains("two different labels"));

    let single = dir.path().join("one.vtp");
    let o = run_cli(&["generate", "mesh", "--kind", "sphere", "--out", single.to_str().unwrap(), "-q"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let out = dir.path().join("single");
    let o = run_cli(&["tensions", single.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    assert!(!o.status.success());
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(stderr.contains("one.vtp") && stderr.contains("at least two cells"), "{stderr}");
    assert!(!out.join("interfaces.csv").exists());
}

/// A segmentation cut by the image border: hetero4 at 20 voxels per diameter, the last 40 % of the
/// volume along x cropped away so that cells end on the border. Given the field of view, the cut
/// faces are no interface (said in a warning) and the cell–cell tensions that remain are as right as
/// before the crop (gauge: interface 1-2 at its truth, since the cut free surfaces are not a gauge);
/// without it the cut faces read as free surface and their junctions bend the map.
#[test]
fn faces_cut_by_the_image_border_are_no_interface() {
    use tissuefit::imaging::LabelVolume;
    use tissuefit::morphology::tensions::FieldOfView;
    let path = fixture("hetero4").join("labels_20.tif");
    let volume = read_label_tiff(&path, &LabelReadOptions::default()).unwrap().volume;
    let [_, _, nx] = volume.shape();
    let kept = volume.labels().slice(ndarray::s![.., .., ..nx * 6 / 10]).to_owned();
    let cropped = LabelVolume::new(kept, volume.voxel_size(), volume.origin()).unwrap();
    let (tissue, labelled) = meshed_volume(&cropped);
    let truth = truth("hetero4");
    let gauge = truth["interfaces"]["1-2"]["tension"].as_f64().unwrap();
    let run = |field_of_view: Option<FieldOfView>| {
        let settings =
            TensionSettings { gauge: Gauge::Interface(1, 2), gauge_value: gauge, field_of_view, ..labelled.clone() };
        let map = estimate_tensions(&tissue, &settings).unwrap();
        let mut errors = Vec::new();
        for (pair, v) in truth["interfaces"].as_object().unwrap() {
            let (a, b) = pair.split_once('-').unwrap();
            let (a, b): (u32, u32) = (a.parse().unwrap(), b.parse().unwrap());
            if (a.min(b), a.max(b)) == (1, 2) {
                continue; // the gauge: exact by construction
            }
            let found = map.interfaces.iter().find(|f| (f.cell_a, f.cell_b) == (a.min(b), a.max(b)));
            if let Some(t) = found.and_then(|f| f.tension) {
                errors.push((t / v["tension"].as_f64().unwrap() - 1.0).abs());
            }
        }
        (map, errors)
    };
    let (with, errors_with) = run(Some(FieldOfView::of_volume(&cropped)));
    let (without, errors_without) = run(None);
    eprintln!("with the field of view: {errors_with:?}\nwithout: {errors_without:?}");
    assert!(with.warnings.iter().any(|w| w.contains("lie on the image border")), "{:?}", with.warnings);
    assert!(!without.warnings.iter().any(|w| w.contains("image border")));
    // Every face on the cut plane (the outer side of the last voxel column, within half a voxel) that
    // faces out through it belongs to no interface. (Faces there that face a neighbour are the ends of
    // the walls between cells, which reach the cut.)
    let sx = cropped.voxel_size()[2];
    let cut_x = cropped.origin().x + ((nx * 6 / 10) as Real - 0.5) * sx;
    let (mut on_cut, mut with_interface) = (0, 0);
    for (cell, faces) in tissue.cells().iter().zip(&with.face_interface) {
        let p = cell.mesh().positions();
        let normals = cell.mesh().face_area_vectors();
        for ((t, k), n) in cell.mesh().triangles().iter().zip(faces).zip(&normals) {
            let x = (p[t[0] as usize].x + p[t[1] as usize].x + p[t[2] as usize].x) / 3.0;
            if x > cut_x - 0.5 * sx && n.x > 0.7 * n.norm() {
                on_cut += 1;
                with_interface += usize::from(k.is_some());
            }
        }
    }
    // A few, where the mesh rounds the corner between the cut and a wall, see the neighbour's voxels.
    assert!(on_cut > 50 && with_interface * 20 <= on_cut, "{with_interface} of {on_cut} faces on the cut");
    // Measured: 0.2–6.0 % on the five interfaces besides the gauge with the field of view; without,
    // 22–327 % and one undetermined. The crop shortens the junction lines (fewer samples per interface), so the bound is
    // the 10-voxel target (10 % median) rather than the uncropped 20-voxel one, with every interface
    // within 10 %; the cut read as free surface must be clearly worse.
    assert_eq!(errors_with.len(), 5, "{errors_with:?}");
    assert!(median(&errors_with) <= 0.10 && max(&errors_with) <= 0.10, "{errors_with:?}");
    assert!(median(&errors_without) > 1.5 * median(&errors_with), "{errors_with:?} vs {errors_without:?}");
}

/// A tissue without free surface (every free face cut by a field of view that covers it all, as in a
/// dense crop): the gauge falls back to the mean cell–cell tension, said in a warning, and the ratios
/// between cell–cell tensions are those of the truth (Evolver's hetero4 mesh, exact to 1 %).
#[test]
fn without_free_surface_the_gauge_is_the_mean_cell_cell_tension() {
    use tissuefit::morphology::tensions::FieldOfView;
    let tissue = evolver_mesh("hetero4");
    let field_of_view =
        Some(FieldOfView { lo: Vec3::zeros(), hi: Vec3::zeros(), margin: Vec3::repeat(1.0), cut_cells: None });
    let map = estimate_tensions(&tissue, &TensionSettings { field_of_view, ..Default::default() }).unwrap();
    assert!(map.warnings.iter().any(|w| w.contains("mean cell–cell tension")), "{:?}", map.warnings);
    assert_eq!(map.gauge, "the mean cell–cell tension");
    assert!(map.interfaces.iter().all(|f| f.cell_b != 0), "no cell–medium interface is left");
    let tensions: Vec<Real> = map.interfaces.iter().filter_map(|f| f.tension).collect();
    assert_eq!(tensions.len(), 6);
    let mean = tensions.iter().sum::<Real>() / 6.0;
    assert!((mean - 1.0).abs() < 1e-9, "mean {mean}");
    let truth = truth("hetero4");
    let want: Vec<Real> = map
        .interfaces
        .iter()
        .map(|f| truth["interfaces"][format!("{}-{}", f.cell_a, f.cell_b)]["tension"].as_f64().unwrap())
        .collect();
    let want_mean = want.iter().sum::<Real>() / 6.0;
    for (t, w) in tensions.iter().zip(&want) {
        assert!((t / (w / want_mean) - 1.0).abs() < 0.01, "{t} vs {}", w / want_mean);
    }
}

/// `far_field = auto` is the global fit wherever the three global surfaces meet at a junction (Evolver's
/// own mesh of hetero4: every sample, identical map) and fits the interfaces near the sample where they
/// do not (hetero4's 10-voxel label volume, whose coarse interfaces miss each other at some junctions):
/// there it uses more samples and is no less accurate (measured: cell–cell median / max 2.4 / 8.1 %
/// against 3.4 / 8.8 % with the global fit alone).
#[test]
fn the_auto_far_field_is_the_global_fit_where_it_meets_and_fits_locally_where_it_misses() {
    use tissuefit::morphology::tensions::FarField;
    let with = |far_field| TensionSettings { far_field, ..Default::default() };
    let mesh = evolver_mesh("hetero4");
    let global = estimate_tensions(&mesh, &with(FarField::Global)).unwrap();
    let auto = estimate_tensions(&mesh, &with(FarField::Auto)).unwrap();
    assert_eq!(auto.samples_local, 0);
    assert_eq!(auto, global);

    let (tissue, settings) = meshed_labels("hetero4", 10);
    let global =
        estimate_tensions(&tissue, &TensionSettings { far_field: FarField::Global, ..settings.clone() }).unwrap();
    let auto = estimate_tensions(&tissue, &TensionSettings { far_field: FarField::Auto, ..settings.clone() }).unwrap();
    let local = estimate_tensions(&tissue, &TensionSettings { far_field: FarField::Local, ..settings }).unwrap();
    assert_eq!(global.samples_local, 0);
    assert!(auto.samples_local > 0 && auto.samples > global.samples, "{} vs {}", auto.samples, global.samples);
    assert_eq!(local.samples_local, local.samples);
    let (g, _, _) = errors("hetero4", &global);
    let (a, _, _) = errors("hetero4", &auto);
    let (l, _, _) = errors("hetero4", &local);
    eprintln!(
        "cell–cell median / max: global {:?} auto {:?} local {:?}",
        (median(&g), max(&g)),
        (median(&a), max(&a)),
        (median(&l), max(&l))
    );
    assert!(median(&a) <= median(&g) && max(&a) <= max(&g), "auto {a:?} vs global {g:?}");
    assert!(median(&l) <= 0.05 && max(&l) <= 0.10, "local {l:?}");
}

/// A cell that stops short of the image border has no cut face, however close to the border the
/// mesh's edge length brings its faces: only labels with a voxel on the border are cut. (The C.
/// elegans volume's cells stop 8 voxels from its sides, within one of its ~13-voxel mesh edges: 48
/// of their free faces were read as cut before.)
#[test]
fn only_cells_that_reach_the_image_border_have_cut_faces() {
    use tissuefit::morphology::tensions::FieldOfView;
    let (tissue, settings) = meshed_labels("hetero4", 10);
    let fov = settings.field_of_view.clone().unwrap();
    assert_eq!(fov.cut_cells.as_ref().map(|c| c.len()), Some(0), "no hetero4 cell reaches its volume's border");
    // The same box with every face counted as near a side: nothing is cut unless the cell reaches it.
    let everywhere = FieldOfView { lo: fov.hi, hi: fov.lo, ..fov.clone() };
    let map =
        estimate_tensions(&tissue, &TensionSettings { field_of_view: Some(everywhere.clone()), ..settings.clone() })
            .unwrap();
    assert!(map.face_interface.iter().flatten().all(|k| k.is_some()));
    let cut_one = FieldOfView { cut_cells: Some([1].into()), ..everywhere };
    let map = estimate_tensions(&tissue, &TensionSettings { field_of_view: Some(cut_one), ..settings }).unwrap();
    for (cell, faces) in tissue.cells().iter().zip(&map.face_interface) {
        let cut = faces.iter().filter(|k| k.is_none()).count();
        assert_eq!(cut > 0, cell.id().0 == 1, "cell {}: {cut} cut faces", cell.id().0);
    }
}

/// The real C. elegans 4-cell embryo (CShaper via foambryo, ../shared/data/real): its cells are pressed
/// by the eggshell, so some interfaces are not one sphere and their global fits miss each other at
/// the junctions. The map is whole (all nine interfaces determined, none cut: no cell reaches the
/// image border), the same from the label volume and from foambryo's mesh of the same embryo, and
/// steady across mesh resolutions. Measured (labels at 400 nodes per cell / foambryo's mesh / labels
/// at 800 / 1,600 / 200): 1-0 1.72/1.73/1.69/1.66/1.54, 3-4 0.63/0.62/0.61/0.57/0.73, 4-0
/// 0.35/0.35/0.40/0.43/0.38, largest change mesh vs labels 3 %, across resolutions 23 % (4-0 at
/// 1,600); with the global fit alone 3-4 (at 400) or 4-0 (at 800 and 1,600) came out undetermined and
/// 1-0 moved from 1.75 to 1.41; at 200 nodes the robust pass dropped every 4-0 sample (4 of 9
/// undetermined) until an interface was made to keep its last samples.
#[test]
#[ignore = "needs ../shared/data/real"]
fn real_c_elegans_map_is_whole_and_the_same_from_labels_and_mesh_and_across_resolutions() {
    let real = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/real");
    let options = LabelReadOptions { voxel_size: Some([1e-6; 3]), ..Default::default() };
    let volume = read_label_tiff(&real.join("DERIVED_cshaper_4cells_labels_from_mesh.tif"), &options).unwrap().volume;
    let labels_map = |target_nodes| {
        let settings = TensionSettings {
            rounding_scale: Some(1e-6),
            field_of_view: Some(tissuefit::morphology::tensions::FieldOfView::of_volume(&volume)),
            ..Default::default()
        };
        let meshing = LabelMeshingOptions { target_nodes, ..Default::default() };
        let mut tissue = mesh_labels(&volume, &meshing).unwrap().tissue;
        tissuefit::meshing::label_interfaces(&mut tissue, &volume).unwrap();
        estimate_tensions(&tissue, &settings).unwrap()
    };
    let mesh = read_tissue(&real.join("foambryo-runner__Cshaper_4_cells_min-d-3.vtk"), &ReadOptions::default())
        .unwrap()
        .tissue;
    let maps = [
        ("labels, 400 nodes", labels_map(400)),
        ("foambryo's mesh", estimate_tensions(&mesh, &TensionSettings::default()).unwrap()),
        ("labels, 800 nodes", labels_map(800)),
        ("labels, 1600 nodes", labels_map(1600)),
        ("labels, 200 nodes", labels_map(200)),
    ];
    let pairs = [(1, 0), (1, 2), (1, 3), (2, 0), (2, 3), (2, 4), (3, 0), (3, 4), (4, 0)];
    for (what, map) in &maps {
        let got: Vec<(u32, u32)> = map.interfaces.iter().map(|f| (f.cell_a, f.cell_b)).collect();
        assert_eq!(got, pairs, "{what}");
        assert!(map.interfaces.iter().all(|f| f.determined && f.tension.is_some_and(|t| t > 0.0)), "{what}");
        assert!(!map.warnings.iter().any(|w| w.contains("image border")), "{what}: {:?}", map.warnings);
        eprintln!("{what}: {:?}", map.interfaces.iter().map(|f| f.tension.unwrap()).collect::<Vec<_>>());
    }
    let change = |a: &TensionMap, b: &TensionMap| {
        pairs.iter().map(|&(x, y)| (tension_of(a, x, y) / tension_of(b, x, y) - 1.0).abs()).fold(0.0, Real::max)
    };
    let mesh_vs_labels = change(&maps[1].1, &maps[0].1);
    let across = [change(&maps[2].1, &maps[0].1), change(&maps[3].1, &maps[0].1), change(&maps[4].1, &maps[0].1)];
    eprintln!("largest change: mesh vs labels {mesh_vs_labels:.3}, 800 / 1600 / 200 vs 400 nodes {across:.3?}");
    assert!(mesh_vs_labels <= 0.05, "mesh vs labels: {mesh_vs_labels}");
    assert!(across.iter().all(|&c| c <= 0.30), "across resolutions: {across:?}");
}

/// The PlantSeg ovule crop (../shared/data/real; 44 cells, every one cut by the crop, no free
/// surface): the junctions do not balance exactly (residual rms ≈ 0.2), and the best-balancing unit
/// vector concentrated on five weakly tied interfaces (25–33 × the mean, the median at 0.05 of it).
/// The mean-constrained solve spreads the map over the tissue: most interfaces determined, few ≤ 0,
/// the median within a factor 2 of the mean, no interface above 20 × the mean. With no free surface no
/// pressure is known relative to the medium, but every linked cell's relative to its group.
/// Measured: 170 of 180 determined, 6 ≤ 0, median 0.70, largest 15.9, spectral gap 3.0; 43 relative
/// pressures.
#[test]
#[ignore = "needs ../shared/data/real"]
fn real_ovule_crop_map_is_spread_over_the_tissue_with_relative_pressures() {
    let real = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/real");
    let volume =
        read_label_tiff(&real.join("plant-seg__sample_ovule_labels.tif"), &LabelReadOptions::default()).unwrap().volume;
    let mut tissue = mesh_labels(&volume, &LabelMeshingOptions::default()).unwrap().tissue;
    tissuefit::meshing::label_interfaces(&mut tissue, &volume).unwrap();
    let voxel = volume.voxel_size().iter().copied().fold(0.0, Real::max);
    let settings = TensionSettings {
        rounding_scale: Some(voxel),
        field_of_view: Some(tissuefit::morphology::tensions::FieldOfView::of_volume(&volume)),
        ..Default::default()
    };
    let map = estimate_tensions(&tissue, &settings).unwrap();
    let tensions: Vec<Real> = map.interfaces.iter().filter_map(|f| f.tension).collect();
    let non_positive = tensions.iter().filter(|&&t| t <= 0.0).count();
    let largest = tensions.iter().copied().fold(Real::MIN, Real::max);
    eprintln!(
        "{} of {} determined, {non_positive} ≤ 0, median {:.3}, largest {largest:.1}, spectral gap {:?}",
        tensions.len(),
        map.interfaces.len(),
        median(&tensions),
        map.spectral_gap
    );
    assert!(tensions.len() * 10 >= map.interfaces.len() * 9, "{} of {}", tensions.len(), map.interfaces.len());
    assert!(non_positive * 20 <= tensions.len(), "{non_positive} ≤ 0 of {}", tensions.len());
    assert!(median(&tensions) >= 0.5, "median {}", median(&tensions));
    assert!(largest <= 20.0, "largest {largest}");
    // Yet it is weak evidence, and said to be (median relative sd 21 %).
    assert!(map.warnings.iter().any(|w| w.contains("poorly determined")), "{:?}", map.warnings);
    assert!(map.cells.iter().all(|c| c.pressure.is_none()));
    let relative = map.cells.iter().filter(|c| c.pressure_relative.is_some()).count();
    assert!(relative * 10 >= map.cells.len() * 9, "{relative} relative pressures of {}", map.cells.len());
}

/// Relative pressures where the medium is known: each cell's pressure minus its group's mean, and
/// Evolver's own differences on ball12 (twelve cells around a buried one: one group) within 3 % of the
/// mean pressure at the median and 15 % at most (measured 1.7 % and 12.2 %: the buried cell, whose
/// absolute pressure errs by 12 % as well, shifts the others' by its share of the mean).
#[test]
fn relative_pressures_are_the_pressures_about_their_mean_and_match_evolvers_differences() {
    let name = "ball12";
    let map = estimate_tensions(&evolver_mesh(name), &TensionSettings::default()).unwrap();
    let truth = truth(name);
    let unit = truth["evolver_length_to_um"].as_f64().unwrap();
    let want: Vec<Real> =
        map.cells.iter().map(|c| truth["pressures"][c.cell.to_string()].as_f64().unwrap() / unit * 1e6).collect();
    let got: Vec<Real> = map.cells.iter().map(|c| c.pressure.unwrap()).collect();
    let n = got.len() as Real;
    let (mean_got, mean_want) = (got.iter().sum::<Real>() / n, want.iter().sum::<Real>() / n);
    let mut errors = Vec::new();
    for (k, c) in map.cells.iter().enumerate() {
        let relative = c.pressure_relative.unwrap();
        assert!((relative - (got[k] - mean_got)).abs() <= 1e-9 * mean_got, "cell {}", c.cell);
        assert!(c.pressure_relative_sd.is_some_and(|sd| sd > 0.0 && sd <= c.pressure_sd.unwrap() * 1.5));
        errors.push((relative - (want[k] - mean_want)).abs() / mean_want);
    }
    eprintln!("relative pressure errors (fraction of the mean pressure): {errors:.4?}");
    assert!(median(&errors) < 0.03 && max(&errors) < 0.15, "{errors:?}");
}

/// A file that numbers its cells from 0 (SimuCell3D's convention, e.g. its lumen geometry) is mapped
/// with every id shifted by one, and says so, instead of failing on "cell id 0 is reserved".
#[test]
fn cells_numbered_from_zero_are_mapped_shifted_by_one() {
    let (radius, disc) = (5e-6, 5e-6 * 50.0_f64.to_radians().sin());
    let cells = vec![
        Cell::new(CellId(0), CellKind::Epithelial, 0, cap_cell(radius, disc, 96, 40, 12, false)),
        Cell::new(CellId(1), CellKind::Epithelial, 0, cap_cell(radius, disc, 96, 40, 12, true)),
    ];
    let t = Tissue::from_cells(cells).unwrap();
    assert!(estimate_tensions(&t, &TensionSettings::default()).is_err_and(|e| matches!(e, TensionError::CellIdZero)));
    let dir = tempfile::tempdir().unwrap();
    let input =
        tissuefit::stages::tensions::TensionsInput { file: "doublet.vtk", kind: "tissue", gauge_in_mn_per_m: false };
    let outcome = tissuefit::stages::tensions::run(&t, &TensionSettings::default(), &input, dir.path()).unwrap();
    let pairs: Vec<(u32, u32)> = outcome.map.interfaces.iter().map(|f| (f.cell_a, f.cell_b)).collect();
    assert_eq!(pairs, [(1, 0), (1, 2), (2, 0)]);
    assert!((tension_of(&outcome.map, 1, 2) / (2.0 * 50.0_f64.to_radians().cos()) - 1.0).abs() < 0.01);
    assert!(outcome.summary.warnings[0].contains("numbers its cells from 0"), "{:?}", outcome.summary.warnings);
    let cells = std::fs::read_to_string(dir.path().join("cells.csv")).unwrap();
    assert!(
        cells.lines().nth(1).unwrap().starts_with("1,") && cells.lines().nth(2).unwrap().starts_with("2,"),
        "{cells}"
    );
}
