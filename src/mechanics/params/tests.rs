use super::reading::to_value;
use super::writing::{config_docs, fmt_real, is_section, unit_of};
use super::*;
use toml::Value;

fn load(text: &str) -> Result<Parameters, ParamError> {
    Parameters::from_toml_str(text, "params.toml")
}

/// The error message of a config that must be rejected.
fn rejection(text: &str) -> String {
    match load(text) {
        Ok(params) => panic!("accepted: {params:?}"),
        Err(error) => error.to_string(),
    }
}

#[test]
fn defaults_validate_without_errors_or_warnings() {
    let params = Parameters::default();
    let warnings = params.validate().expect("defaults are valid");
    assert!(warnings.is_empty(), "{warnings:?}");
    // The paper's defaults sit well inside the dynamic stability limits: ζΔt/m ≈ 0.1.
    let epithelial = &params.time_step_limits()[0];
    assert!((0.05..0.2).contains(&epithelial.damping_ratio), "{epithelial:?}");
    assert!(epithelial.oscillation_ratio < 1.0, "{epithelial:?}");
}

#[test]
fn default_list_follows_cell_kind_codes() {
    let params = Parameters::default();
    for kind in CellKind::ALL {
        let cell_type = params.cell_type(kind.code()).expect("one entry per kind");
        assert_eq!(cell_type.kind, kind);
        assert_eq!(cell_type.name, kind.name());
    }
    assert!(params.cell_type(5).is_none());
    assert_eq!(params.cell_types[1].bulk_modulus, 0.0);
    assert_eq!(params.cell_types[2].faces.lateral.repulsion, 5e9);
    assert_eq!(params.cell_types[3].faces.basal.surface_tension, 0.0);
    assert_eq!(params.cell_types[4].faces.apical.adhesion, 0.0);
}

#[test]
fn commented_defaults_read_back_exactly() {
    let text = Parameters::default_toml_commented();
    assert_eq!(load(&text).expect("commented defaults load"), Parameters::default());
    assert!(text.contains("division_volume = inf"), "{text}");
    let plain = Parameters::default().to_toml_string();
    assert_eq!(load(&plain).expect("plain defaults load"), Parameters::default());
}

#[test]
fn resolved_config_round_trips() {
    let mut params = Parameters::default();
    params.numerics.seed = 42;
    params.numerics.dynamics = Dynamics::Overdamped;
    params.cell_types[0].faces.lateral.surface_tension = 1.234_567_891_234e-4;
    params.cell_types[0].max_pressure = Real::INFINITY;
    assert_eq!(load(&params.to_toml_string()).expect("loads"), params);
}

fn count_leaves(value: &Value) -> usize {
    match value {
        Value::Table(table) => table.values().map(count_leaves).sum(),
        Value::Array(items) if is_section(value) => items.iter().map(count_leaves).sum(),
        _ => 1,
    }
}

#[test]
fn every_default_field_is_documented() {
    let text = Parameters::default_toml_commented();
    let lines: Vec<&str> = text.lines().collect();
    // The comment block directly above line `i`, without the `# ` markers.
    let comment_above = |i: usize| {
        let start = lines[..i].iter().rposition(|line| !line.starts_with('#')).map_or(0, |j| j + 1);
        lines[start..i].iter().map(|line| line.trim_start_matches('#').trim()).collect::<Vec<_>>().join(" ")
    };
    let mut assignments = 0;
    for (i, line) in lines.iter().enumerate() {
        if line.starts_with('#') || line.trim().is_empty() {
            continue;
        }
        let comment = comment_above(i);
        assert!(!comment.is_empty() && !comment.contains("(undocumented)"), "{line:?} has no comment");
        if line.starts_with('[') {
            continue;
        }
        assignments += 1;
        let (key, value) = line.split_once(" = ").expect("a `key = value` line");
        assert!(comment.contains(&format!(": {value}.")), "{key}: comment {comment:?} states no default");
        assert!(comment.len() > key.len() + 20, "{key}: comment {comment:?} explains nothing");
    }
    assert_eq!(assignments, count_leaves(&to_value(&Parameters::default())));
    // Fields are written in the documented (struct) order, not alphabetically.
    let position = |needle: &str| text.find(needle).unwrap_or_else(|| panic!("{needle} missing"));
    assert!(position("min_edge_length =") < position("contact_cutoff ="));
    assert!(position("surface_tension =") < position("adhesion ="));
    // The docs come from the schema of the structs: every field there has a doc comment, written
    // as reference text (no rustdoc links in its first paragraph), and is in the file.
    let docs = &config_docs().fields;
    for (path, doc) in docs {
        assert!(!doc.text.is_empty(), "{path}: no doc comment");
        assert!(!doc.text.contains("[`") && !doc.text.contains("Unit:"), "{path}: {:?}", doc.text);
        let key = path.rsplit('.').next().unwrap_or(path);
        assert!(text.contains(&format!("{key} =")) || text.contains(&format!("{key}]")), "{path} not written");
    }
    // Units come from the `Unit: …` sentence of the doc comments.
    assert_eq!(unit_of("numerics.min_edge_length"), "m");
    assert_eq!(unit_of("cell_types[2].faces.lateral.surface_tension"), "N/m");
    assert_eq!(unit_of("cell_types[0].target_isoperimetric_ratio"), "");
    assert!(text.contains("[dimensionless]") && text.contains("[kg/m³]"), "{text}");
}

#[test]
fn partial_cell_type_takes_the_defaults_of_its_kind() {
    let params = load(
        "[numerics]\n\
         time_step = 5e-8\n\
         [[cell_types]]\n\
         kind = \"nucleus\"\n\
         bulk_modulus = 3000\n\
         [cell_types.faces.lateral]\n\
         surface_tension = 2e-4\n",
    )
    .expect("valid partial config");
    let nucleus = CellTypeParams::default_for(CellKind::Nucleus);
    assert_eq!(params.numerics, Numerics { time_step: 5e-8, ..Numerics::default() });
    assert_eq!(params.cell_types.len(), 1);
    let t = &params.cell_types[0];
    assert_eq!(t.name, "nucleus");
    assert_eq!(t.bulk_modulus, 3000.0);
    assert_eq!(t.growth_rate, nucleus.growth_rate);
    assert_eq!(t.division_volume, Real::INFINITY);
    assert_eq!(t.faces.apical, nucleus.faces.apical);
    assert_eq!(t.faces.lateral.surface_tension, 2e-4);
    assert_eq!(t.faces.lateral.repulsion, nucleus.faces.lateral.repulsion);
    assert_eq!(t.faces.lateral.adhesion, 0.0);
    // Without a kind, an entry is epithelial.
    let params = load("[[cell_types]]\nname = \"a\"\n").expect("valid");
    assert_eq!(params.cell_types[0], CellTypeParams { name: "a".into(), ..CellTypeParams::default() });
}

#[test]
fn overdamped_file_gets_the_overdamped_damping() {
    let params = load("[numerics]\ndynamics = \"overdamped\"\n").expect("valid");
    assert_eq!(params.numerics.damping, Numerics::PAPER_OVERDAMPED_DAMPING);
    assert!(params.validate().expect("valid").is_empty());
}

#[test]
fn unknown_keys_are_rejected_with_their_path() {
    let message = rejection("[[cell_types]]\n[cell_types.faces.apical]\nsurface_tenson = 1e-3\n");
    assert!(message.starts_with("params.toml: "), "{message}");
    assert!(message.contains("unknown field `surface_tenson` in cell_types[0].faces.apical"), "{message}");
    assert!(message.contains("did you mean `surface_tension`?"), "{message}");
    let message = rejection("[numerics]\ntimestep = 1e-7\n[solver]\n");
    assert!(message.contains("`timestep` in numerics"), "{message}");
    assert!(message.contains("`solver` at the top level"), "{message}");
}

#[test]
fn wrong_types_and_choices_are_rejected() {
    let message = rejection("[numerics]\ndamping = \"high\"\n");
    assert!(message.contains("numerics.damping = \"high\": expected a number"), "{message}");
    let message = rejection("[[cell_types]]\nkind = \"nucleous\"\n");
    assert!(message.contains("cell_types[0].kind = \"nucleous\": unknown value"), "{message}");
    let message = rejection("[numerics]\ndynamics = \"fast\"\n");
    assert!(message.contains("numerics.dynamics"), "{message}");
    let message = rejection("cell_types = 3\n");
    assert!(message.contains("array of tables"), "{message}");
    assert!(matches!(load("[numerics\n"), Err(ParamError::Syntax { .. })));
}

#[test]
fn invalid_values_are_rejected_naming_the_field() {
    let cases = [
        (
            "[[cell_types]]\n[cell_types.faces.apical]\nsurface_tension = -1e-3\n",
            "cell_types[0].faces.apical.surface_tension = -0.001 N/m: must be ≥ 0",
        ),
        ("[[cell_types]]\nbulk_modulus = nan\n", "cell_types[0].bulk_modulus = nan Pa: is NaN"),
        ("[numerics]\ncontact_cutoff = 7e-7\n", "numerics.contact_cutoff = 7e-7 m exceeds 3·numerics.min_edge_length"),
        ("[numerics]\nmax_edge_ratio = 1.5\n", "numerics.max_edge_ratio = 1.5: must be a number of at least 2"),
        ("[numerics]\nmax_edge_ratio = nan\n", "numerics.max_edge_ratio = nan: must be a number of at least 2"),
        (
            "[[cell_types]]\ntarget_isoperimetric_ratio = 100\n",
            "cell_types[0].target_isoperimetric_ratio = 100.0: is below 36π",
        ),
        ("[numerics]\ntime_step = 1e-4\n", "numerics.time_step = 1e-4 s: with numerics.damping"),
        ("[[cell_types]]\nmin_volume = 2e-15\n", "cell_types[0].min_volume = 2e-15 m³ is not below"),
        ("[[cell_types]]\ngrowth_rate = inf\n", "cell_types[0].growth_rate = inf m³/s: must be finite"),
        (
            "[[cell_types]]\n[[cell_types]]\n",
            "cell_types[1].name = \"epithelial\" is already the name of cell_types[0]",
        ),
        ("cell_types = []\n", "cell_types is empty"),
    ];
    for (text, expected) in cases {
        let message = rejection(text);
        assert!(message.contains(expected), "expected {expected:?} in {message:?}");
        assert!(message.starts_with("params.toml: "), "{message}");
    }
}

#[test]
fn every_problem_is_reported_on_its_own_line() {
    let message = rejection("[numerics]\ndamping = -1\n[[cell_types]]\nmass_density = 0\n");
    let lines: Vec<&str> = message.lines().collect();
    assert_eq!(lines.len(), 2, "{message}");
    assert!(lines[0].starts_with("params.toml: numerics.damping = -1.0 kg/s: must be > 0"), "{message}");
    assert!(lines[1].starts_with("params.toml: cell_types[0].mass_density = 0.0 kg/m³"), "{message}");
}

#[test]
fn unstable_time_step_is_reported_beside_other_errors() {
    let message =
        rejection("[numerics]\ntime_step = 1e-4\n[[cell_types]]\ngrowth_rate = nan\n[[cell_types]]\nname = \"b\"\n");
    assert!(message.contains("cell_types[0].growth_rate = nan"), "{message}");
    assert!(message.contains("numerics.time_step = 1e-4 s") && message.contains("cell_types[1] (b)"), "{message}");
    assert!(!message.contains("cell_types[0] (epithelial)"), "{message}");
}

#[test]
fn time_step_limits_flag_unstable_steps() {
    let mut params = Parameters::default();
    params.numerics.time_step = 1e-4;
    let message = params.validate().expect_err("unstable").to_string();
    assert!(message.contains("largest stable time step"), "{message}");
    let limits = params.time_step_limits();
    assert!(limits[0].damping_ratio > TimeStepLimit::LIMIT, "{:?}", limits[0]);
    let max_time_step =
        limits.iter().filter(|limit| !limit.immobile).map(|limit| limit.max_time_step).fold(Real::INFINITY, Real::min);
    assert!(max_time_step < 1e-6 && max_time_step > 1e-8, "{limits:?}");

    // Just below the limit: valid, with a warning.
    params.numerics.time_step = 0.9 * max_time_step;
    let warnings = params.validate().expect("stable");
    assert!(warnings.iter().any(|w| w.contains("half the stability limit")), "{warnings:?}");

    // Overdamped with a damping 300× below the paper's overdamped default is unstable.
    params.numerics = Numerics { dynamics: Dynamics::Overdamped, damping: 1e-11, ..Numerics::default() };
    let message = params.validate().expect_err("unstable").to_string();
    assert!(message.contains("Δt·k/ζ"), "{message}");
    assert!(message.contains("larger damping"), "{message}");
}

#[test]
fn immobile_kinds_have_no_time_step_limit() {
    let mut params = Parameters::default();
    params.cell_types[1].faces.basal.repulsion = 1e15; // ECM: absurdly stiff, but it never moves
    assert!(params.validate().is_ok());
    params.cell_types[2].faces.basal.repulsion = 1e15; // lumen: moves
    let message = params.validate().expect_err("unstable").to_string();
    assert!(message.contains("cell_types[2] (lumen)") && message.contains("contact"), "{message}");
}

#[test]
fn adhesion_energy_above_the_tension_is_flagged() {
    // Table 2: W = ωc²/4 = 1e9·(2e-7)²/4 = 1e-5 J/m², a hundredth of γ = 1e-3 N/m.
    let mut params = Parameters::default();
    let warnings = params.validate().expect("valid");
    assert!(!warnings.iter().any(|w| w.contains("negative tension")), "{warnings:?}");
    params.cell_types[0].faces.lateral.surface_tension = 5e-6;
    let warnings = params.validate().expect("valid, with a warning");
    let warning = warnings.iter().find(|w| w.contains("negative tension")).expect("flagged");
    assert!(warning.starts_with("cell_types[0].faces.lateral.adhesion = 1e9 Pa/m"), "{warning}");
    assert!(warning.contains("keep adhesion below 3.50e8 Pa/m"), "{warning}");
    // W = 0.6γ passes, 0.71γ is flagged.
    params.cell_types[0].faces.lateral.surface_tension = 1e-5 / 0.6;
    assert!(!params.validate().unwrap().iter().any(|w| w.contains("negative tension")));
    params.cell_types[0].faces.lateral.surface_tension = 1e-5 / 0.71;
    assert!(params.validate().unwrap().iter().any(|w| w.contains("negative tension")));
    // Immobile kinds never crumple.
    params.cell_types[0].faces.lateral.surface_tension = 1e-3;
    params.cell_types[1].faces.basal.adhesion = 1e12;
    let warnings = params.validate().expect("valid");
    assert!(!warnings.iter().any(|w| w.contains("negative tension")), "{warnings:?}");
}

#[test]
fn spring_adhesion_with_the_vertex_quadrature_is_warned_about_from_a_twentieth() {
    let bias = |p: &Parameters| p.validate().expect("valid").into_iter().find(|w| w.contains("settle off Young–Dupré"));
    // Table 2's ω = 1e9 Pa/m at c = 0.2 µm: w/(2γ) = 1e9·(2e-7)²/(4·1e-3) = 0.01, below 0.05.
    let mut params = Parameters::default();
    assert_eq!(bias(&params), None);
    // w/(2γ) = 0.3 on the lateral faces: named, with the value and the remedy.
    params.cell_types[0].faces.lateral.adhesion = 0.3 * 4.0 * 1e-3 / (2e-7 * 2e-7);
    let w = bias(&params).expect("warned");
    assert!(w.contains("cell_types[0].faces.lateral") && w.contains("= 0.300"), "{w}");
    assert!(w.contains("contact_quadrature = \"faces\""), "{w}");
    // Just below a twentieth: not warned; just above: warned.
    params.cell_types[0].faces.lateral.adhesion = 0.049 * 4.0 * 1e-3 / (2e-7 * 2e-7);
    assert_eq!(bias(&params), None);
    params.cell_types[0].faces.lateral.adhesion = 0.051 * 4.0 * 1e-3 / (2e-7 * 2e-7);
    assert!(bias(&params).is_some());
    // Not with the face quadrature, nor with coupling contacts (their cells do not adhere by springs).
    params.numerics.contact_quadrature = ContactQuadrature::Faces;
    assert_eq!(bias(&params), None);
    params.numerics.contact_quadrature = ContactQuadrature::Vertices;
    params.numerics.contact_model = ContactModel::Coupling;
    assert_eq!(bias(&params), None);
    // Nor for an immobile kind's adhesion (the ECM's).
    params.numerics.contact_model = ContactModel::Spring;
    params.cell_types[0].faces.lateral.adhesion = 1e9;
    params.cell_types[1].faces.basal.adhesion = 1e11;
    assert_eq!(bias(&params), None);
}

#[test]
fn pressure_is_capped() {
    let mut cell_type = CellTypeParams::default();
    // Compressed to half its target volume: K ln 2 ≈ 1733 Pa, below the 2500 Pa cap.
    assert!((cell_type.pressure(0.5, 1.0) - 2500.0 * 2.0_f64.ln()).abs() < 1e-9);
    // Compressed to a tenth: K ln 10 ≈ 5756 Pa, capped.
    assert_eq!(cell_type.pressure(0.1, 1.0), 2500.0);
    assert!(cell_type.pressure(2.0, 1.0) < 0.0);
    cell_type.max_pressure = Real::INFINITY;
    assert!((cell_type.pressure(0.1, 1.0) - 2500.0 * 10.0_f64.ln()).abs() < 1e-9);
}

#[test]
fn face_types_index_their_parameters() {
    let mut faces = FaceTypeParams::uniform(FaceParams::default());
    faces.get_mut(FaceType::Basal).adhesion = 7.0;
    assert_eq!(faces.basal.adhesion, 7.0);
    assert_eq!(faces.get(FaceType::Basal).adhesion, 7.0);
    assert_eq!(faces.iter().map(|(t, _)| t).collect::<Vec<_>>(), FaceType::ALL.to_vec());
}

#[test]
fn floats_print_as_exact_toml() {
    for x in [2e-7, 1e9, 2500.0, 0.001, 250.0, 0.0, 1.4e-15, 3e-9, 12345.678, -0.001, 1e5, 0.1 + 0.2] {
        let text = format!("x = {}", fmt_real(x));
        let table: Table = toml::from_str(&text).expect("valid TOML float");
        assert_eq!(table["x"].as_float(), Some(x), "{text}");
    }
    assert_eq!(fmt_real(Real::INFINITY), "inf");
}

#[test]
fn ray_casting_polarity_reads_with_its_keys_and_rejects_bad_values() {
    let params = load("[numerics]\npolarity = \"ray_casting\"\npolarity_voxel_size = 5e-7\npolarity_interval = 20\n")
        .expect("loads");
    assert_eq!(params.numerics.polarity, Polarity::RayCasting);
    assert_eq!((params.numerics.polarity_voxel_size, params.numerics.polarity_interval), (5e-7, 20));
    // Files without the keys (older configs, checkpoints' resolved configs) get the defaults.
    let params = load("[numerics]\npolarity = \"contacts\"\n").expect("loads");
    assert_eq!((params.numerics.polarity_voxel_size, params.numerics.polarity_interval), (0.0, 100));
    assert_eq!(params.numerics.polarity_min_lumen_fraction, 0.25);
    let message = rejection("[numerics]\npolarity = \"rays\"\n");
    assert!(
        message.contains(
            "numerics.polarity = \"rays\": unknown value, expected one of \"none\", \"contacts\", \"ray_casting\""
        ),
        "{message}"
    );
    let message = rejection("[numerics]\npolarity_interval = 0\n");
    assert!(message.contains("numerics.polarity_interval = 0: must be at least 1"), "{message}");
    let message = rejection("[numerics]\npolarity_voxel_size = -1e-6\n");
    assert!(message.contains("numerics.polarity_voxel_size = -1e-6 m: must be ≥ 0 m"), "{message}");
    let message = rejection("[numerics]\npolarity_interval = -3\n");
    assert!(message.contains("numerics.polarity_interval"), "{message}");
    let message = rejection("[numerics]\npolarity_min_lumen_fraction = -0.5\n");
    assert!(message.contains("numerics.polarity_min_lumen_fraction = -0.5: must be ≥ 0"), "{message}");
    let message = rejection("[numerics]\npolarity_voxelsize = 1e-6\n");
    assert!(message.contains("did you mean `polarity_voxel_size`?"), "{message}");
}

#[test]
fn lengths_and_tensions_typed_in_the_wrong_unit_are_warned_with_a_hint() {
    // l_min typed as µm (0.3 m) and a tension typed as mN/m (0.5 N/m): valid numbers, named in warnings.
    let params = load(
        "[numerics]\nmin_edge_length = 0.3\ncontact_cutoff = 0.3\ntime_step = 1e-17\n[[cell_types]]\nkind = \"epithelial\"\n\
         [cell_types.faces.lateral]\nsurface_tension = 0.5\n",
    )
    .expect("loads");
    let warnings = params.validate().unwrap_or_else(|e| panic!("only warned: {e}"));
    let says = |needle: &str| warnings.iter().any(|w| w.contains(needle));
    assert!(says("numerics.min_edge_length = 3e-1 m") && says("did you mean 0.3um?"), "{warnings:?}");
    assert!(says("cell_types[0].faces.lateral.surface_tension") && says("did you mean 0.5e-3 N/m?"), "{warnings:?}");
}

#[test]
fn the_mesh_dependent_numerics_a_model_and_its_overrides_set_are_told_apart_from_defaults() {
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("model.toml");
    std::fs::write(&model, "[numerics]\nmin_edge_length = 5e-7\ncontact_cutoff = 5e-7\n").unwrap();
    let (params, explicit) = Parameters::load_explicit(&model).unwrap();
    assert_eq!(params.numerics.min_edge_length, 5e-7);
    assert_eq!(
        explicit,
        ExplicitNumerics { min_edge_length: true, contact_cutoff: true, time_step: false, repulsion: false }
    );
    // A value equal to its default still counts as set: it is the user's choice.
    let overrides: Table = toml::from_str("[numerics]\ntime_step = 1e-7\n[simulation]\nmax_steps = 10\n").unwrap();
    let (_, explicit) = Parameters::load_with_overrides_explicit(None, Some(&overrides)).unwrap();
    assert_eq!(
        explicit,
        ExplicitNumerics { min_edge_length: false, contact_cutoff: false, time_step: true, repulsion: false }
    );
    let (_, explicit) = Parameters::load_with_overrides_explicit(Some(&model), Some(&overrides)).unwrap();
    assert_eq!(explicit, ExplicitNumerics { repulsion: false, ..ExplicitNumerics::ALL });
    // Nothing set: everything is derived from the mesh; the cutoff follows l_min.
    let mut params = Parameters::default();
    let scale = MeshScale { mean_edge: 1.4e-6, min_edge_length: 1e-6 };
    let fit = params.fit_to_mesh(&ExplicitNumerics::default(), &scale);
    assert_eq!((params.numerics.min_edge_length, params.numerics.contact_cutoff), (1e-6, 1e-6));
    assert!(fit.warnings.is_empty() && fit.lines().len() == 2, "{fit:?}");
    assert!(fit.lines()[0].contains("1.000 µm (default 0.200 µm)"), "{:?}", fit.lines());
    // The derived spring cutoff says what it does to the adhesion energy: w/(2γ) = ωc²/(4γ) with
    // Table 2's ω = 1e9 Pa/m and γ = 1 mN/m is 0.25 at c = 1 µm, 0.01 at 0.2 µm.
    let note = &fit.lines()[1];
    assert!(
        note.contains("w/(2γ) = ωc²/(4γ) = 0.250 on") && note.contains("0.010 at the default cutoff 0.200 µm"),
        "{note}"
    );
    // Everything set: nothing changes, whatever the mesh.
    let mut params = Parameters::default();
    let before = params.clone();
    let fit = params.fit_to_mesh(&ExplicitNumerics::ALL, &scale);
    assert_eq!(params, before);
    assert!(fit.derived.is_empty());
    assert_eq!(fit.warnings.len(), 2, "Table 2's 0.2 µm on a 1 µm mesh: {fit:?}");
}

#[test]
fn contact_quadrature_reads_defaults_to_vertices_and_rejects_bad_values() {
    assert_eq!(load("").expect("loads").numerics.contact_quadrature, ContactQuadrature::Vertices);
    let params = load("[numerics]\ncontact_quadrature = \"faces\"\n").expect("loads");
    assert_eq!(params.numerics.contact_quadrature, ContactQuadrature::Faces);
    let message = rejection("[numerics]\ncontact_quadrature = \"face\"\n");
    assert!(
        message
            .contains("numerics.contact_quadrature = \"face\": unknown value, expected one of \"vertices\", \"faces\""),
        "{message}"
    );
}

/// Issue 20 item 3: with the spring model and no `repulsion` in the config, each moving cell type's ξ
/// holds 25 × the Laplace pressure of its cells at depth c; a config's own ξ, or the coupling model,
/// keeps the values it has.
#[test]
fn spring_repulsion_is_derived_from_the_laplace_pressure_unless_the_config_sets_it() {
    use crate::geometry::Vec3;
    use crate::mesh::{Cell, CellId, CellKind, Tissue, shapes::icosphere};
    let cell = |id: u32, x: Real| {
        let mesh = icosphere(3e-6, 3, Vec3::new(x, 0.0, 0.0));
        Cell::new(CellId(id), CellKind::Epithelial, 0, mesh)
    };
    let tissue = Tissue::from_cells(vec![cell(1, -3.05e-6), cell(2, 3.05e-6)]).unwrap();
    let table: Table = toml::from_str("[[cell_types]]\n[cell_types.faces.basal]\nrepulsion = 2e10\n").unwrap();
    assert!(ExplicitNumerics::of_table(&table).repulsion);
    let mut params = Parameters::default();
    let explicit = ExplicitNumerics { min_edge_length: true, contact_cutoff: true, ..ExplicitNumerics::default() };
    let fit = params.fit_to_tissue(&explicit, &tissue);
    let xi = fit.derived_value("cell_types[0].faces.*.repulsion").expect("derived");
    // The icosphere's volume is a little below the sphere's: R from the volume, 2γ/R ≈ 670 Pa.
    let radius = (3.0 * tissue.cells()[0].mesh().signed_volume() / (4.0 * std::f64::consts::PI)).cbrt();
    let expected = 25.0 * 2.0 * 1e-3 / radius / params.numerics.contact_cutoff;
    assert!((xi / expected - 1.0).abs() < 1e-12, "{xi:e} vs {expected:e}");
    for ft in FaceType::ALL {
        assert_eq!(params.cell_types[0].faces.get(ft).repulsion, xi);
    }
    assert!(fit.lines().iter().any(|l| l.contains("Pa/m (default 1.000e9 Pa/m)")), "{:?}", fit.lines());
    // A strong adhesion raises it to 20·ω (the barrier ξc²/2 then 40× the well ωc²/4).
    let mut strong = Parameters::default();
    strong.cell_types[0].faces.get_mut(FaceType::Lateral).adhesion = 1e12;
    let fit = strong.fit_to_tissue(&explicit, &tissue);
    assert_eq!(fit.derived_value("cell_types[0].faces.*.repulsion"), Some(2e13), "{fit:?}");
    // Set by the config, or the coupling model: nothing derived.
    for (explicit, model) in
        [(ExplicitNumerics { repulsion: true, ..explicit }, ContactModel::Spring), (explicit, ContactModel::Coupling)]
    {
        let mut params = Parameters::default();
        params.numerics.contact_model = model;
        let before = params.clone();
        let fit = params.fit_to_tissue(&explicit, &tissue);
        assert!(fit.derived.is_empty(), "{fit:?}");
        assert_eq!(params, before);
    }
    // A cell's own adhesion (cell_overrides) counts like its type's: derived from, and raised to by
    // raise_repulsion_for_overrides, which never lowers a larger value.
    let mut own = Parameters {
        cell_overrides: vec![CellOverrideConfig {
            id: 2,
            surface_tension: PerFaceType::default(),
            adhesion: PerFaceType { lateral: Some(1e12), ..PerFaceType::default() },
        }],
        ..Parameters::default()
    };
    let fit = own.clone().fit_to_tissue(&explicit, &tissue);
    assert_eq!(fit.derived_value("cell_types[0].faces.*.repulsion"), Some(2e13), "{fit:?}");
    let raised = own.raise_repulsion_for_overrides(&tissue);
    assert!(raised.iter().any(|d| d.key == "cell_types[0].faces.*.repulsion" && d.value == 2e13), "{raised:?}");
    assert!(FaceType::ALL.iter().all(|&ft| own.cell_types[0].faces.get(ft).repulsion == 2e13));
    own.cell_types[0].faces.get_mut(FaceType::Basal).repulsion = 5e13;
    own.cell_types[0].faces.get_mut(FaceType::Apical).repulsion = 5e13;
    own.cell_types[0].faces.get_mut(FaceType::Lateral).repulsion = 5e13;
    assert!(own.raise_repulsion_for_overrides(&tissue).is_empty(), "a larger repulsion is kept");
    assert_eq!(own.cell_types[0].faces.get(FaceType::Lateral).repulsion, 5e13);
    own.numerics.contact_model = ContactModel::Coupling;
    own.cell_types[0].faces.get_mut(FaceType::Lateral).repulsion = 1.0;
    assert!(own.raise_repulsion_for_overrides(&tissue).is_empty(), "coupled contacts are not springs");
}

#[test]
fn cell_overrides_read_validate_and_apply_to_the_cells_they_name() {
    let params = load(
        "[[cell_overrides]]\n\
         id = 2\n\
         surface_tension = { lateral = 4e-4, basal = 2e-3 }\n\
         [[cell_overrides]]\n\
         id = 5\n\
         adhesion.apical = 0\n",
    )
    .expect("loads");
    assert_eq!(params.cell_overrides.len(), 2);
    assert_eq!(params.cell_overrides[0].surface_tension.to_array(), [None, Some(4e-4), Some(2e-3)]);
    assert_eq!(params.cell_overrides[1].adhesion.apical, Some(0.0));
    // Written and read back as it is; the commented defaults show an example, commented out.
    assert_eq!(load(&params.to_toml_string()).expect("round trip"), params);
    assert!(Parameters::default_toml_commented().contains("# [[cell_overrides]]"));

    let sphere = |id: u32| {
        crate::mesh::Cell::new(
            crate::mesh::CellId(id),
            CellKind::Epithelial,
            0,
            crate::mesh::shapes::icosphere(1e-6, 1, crate::geometry::Vec3::zeros()),
        )
    };
    // The config wins over the file's values for the face types it names; the others stay.
    let from_file =
        crate::mesh::CellOverrides { surface_tension: [Some(7e-4), Some(9e-4), None], ..Default::default() };
    let mut tissue =
        crate::mesh::Tissue::from_cells(vec![sphere(2).with_overrides(from_file), sphere(5), sphere(6)]).unwrap();
    assert_eq!(params.apply_cell_overrides(&mut tissue), Ok(2));
    let [two, five, six] = [2, 5, 6].map(|id| *tissue.cell(crate::mesh::CellId(id)).unwrap().overrides());
    assert_eq!(two.surface_tension, [Some(7e-4), Some(4e-4), Some(2e-3)]);
    assert_eq!(five.adhesion, [Some(0.0), None, None]);
    assert!(six.is_empty());
    // The effective parameters of cell 2: its values, the type's elsewhere.
    let effective = params.cell_types[0].with_overrides(&two);
    assert_eq!(effective.faces.lateral.surface_tension, 4e-4);
    assert_eq!(effective.faces.apical.adhesion, params.cell_types[0].faces.apical.adhesion);

    // An id that is not a cell names the entry and the ids there are.
    let mut other = crate::mesh::Tissue::from_cells(vec![sphere(1), sphere(3)]).unwrap();
    let error = params.apply_cell_overrides(&mut other).unwrap_err().to_string();
    assert!(
        error.contains("cell_overrides[0]") && error.contains("no cell with id 2") && error.contains("1, 3"),
        "{error}"
    );

    // Bad values, repeated ids and misspelt keys are refused naming the entry.
    let negative = rejection("[[cell_overrides]]\nid = 1\nsurface_tension = { lateral = -1e-3 }\n");
    assert!(
        negative.contains("cell_overrides[0].surface_tension.lateral = -0.001: must be a finite number ≥ 0"),
        "{negative}"
    );
    let twice = rejection("[[cell_overrides]]\nid = 1\n[[cell_overrides]]\nid = 1\n");
    assert!(twice.contains("cell_overrides[1].id = 1: cell_overrides[0] already names this cell"), "{twice}");
    let misspelt = rejection("[[cell_overrides]]\nid = 1\nsurface_tension = { lateal = 1e-3 }\n");
    assert!(misspelt.contains("cell_overrides[0]") && misspelt.contains("lateal"), "{misspelt}");
    let not_a_list = rejection("cell_overrides = 3\n");
    assert!(not_a_list.contains("[[cell_overrides]]"), "{not_a_list}");
    // A value far above every type's is allowed with a warning about the time step.
    let strong = load("[[cell_overrides]]\nid = 1\nsurface_tension = { basal = 1e-2 }\n").unwrap();
    let warnings = strong.validate().unwrap();
    assert!(
        warnings.iter().any(|w| w.contains("cell_overrides[0].surface_tension.basal") && w.contains("time_step")),
        "{warnings:?}"
    );
}

#[test]
fn measured_fire_masses_are_warned_about_without_normal_relaxation_or_fire() {
    let warning = |p: &Parameters| {
        p.validate().expect("valid").into_iter().find(|w| w.contains("simulation.fire_measured_masses"))
    };
    let mut params = Parameters::default();
    assert_eq!(warning(&params), None);
    params.simulation.fire_measured_masses = true;
    let w = warning(&params).expect("full forces warned");
    assert!(w.contains("normal_relaxation = true") && w.contains("wrinkles"), "{w}");
    params.simulation.normal_relaxation = true;
    assert_eq!(warning(&params), None);
    params.simulation.method = RelaxMethod::Integrate;
    assert!(warning(&params).expect("integration warned").contains("ignores it"));
    params.simulation.method = RelaxMethod::Fire;
    params.simulation.mode = SimulationMode::Time;
    assert!(warning(&params).expect("time run warned").contains("ignores it"));
}

#[test]
fn normal_relaxation_of_adhering_springs_is_warned_about_and_full_forces_at_contacts_where_they_do_nothing() {
    let warning = |p: &Parameters, key: &str| p.validate().expect("valid").into_iter().find(|w| w.starts_with(key));
    let mut params = Parameters::default();
    params.numerics.contact_model = ContactModel::Spring;
    params.simulation.normal_relaxation = true;
    // No adhesion: nothing to pin.
    for ft in FaceType::ALL {
        params.cell_types[0].faces.get_mut(ft).adhesion = 0.0;
    }
    assert_eq!(warning(&params, "simulation.normal_relaxation"), None);
    params.cell_types[0].faces.lateral.adhesion = 1e9;
    let w = warning(&params, "simulation.normal_relaxation").expect("pinned contact lines warned");
    assert!(w.contains("full_forces_at_contacts = true") && w.contains("Young–Dupré"), "{w}");
    params.simulation.full_forces_at_contacts = true;
    assert_eq!(warning(&params, "simulation.normal_relaxation"), None);
    assert_eq!(warning(&params, "simulation.full_forces_at_contacts"), None);
    // Where the setting does nothing: without the normal relaxation, or with coupled contacts.
    params.simulation.normal_relaxation = false;
    let w = warning(&params, "simulation.full_forces_at_contacts").expect("without normal relaxation");
    assert!(w.contains("ignores it"), "{w}");
    params.simulation.normal_relaxation = true;
    params.numerics.contact_model = ContactModel::Coupling;
    let w = warning(&params, "simulation.full_forces_at_contacts").expect("coupled contacts");
    assert!(w.contains("spring") && w.contains("ignores it"), "{w}");
}
