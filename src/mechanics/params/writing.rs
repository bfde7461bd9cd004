//! Writing a config as TOML, plain or with every field commented (the config reference).

use super::reading::to_value;
use super::*;
use std::fmt::Write as _;
use toml::{Table, Value};

// ---------------------------------------------------------------------------------------------
// Writing.

/// A float as a TOML literal that reads back exactly: exponent form for small and large magnitudes
/// (`2e-7`, `1e9`), decimal otherwise (`2500.0`, `0.001`), `inf`/`nan` as TOML spells them.
pub(super) fn fmt_real(x: Real) -> String {
    if x.is_nan() {
        "nan".to_owned()
    } else if x.is_infinite() {
        if x > 0.0 { "inf" } else { "-inf" }.to_owned()
    } else if x != 0.0 && !(1e-3..1e5).contains(&x.abs()) {
        format!("{x:e}")
    } else {
        format!("{x:?}")
    }
}

/// A float to 3 significant digits, for estimates in messages.
pub(super) fn fmt_real_short(x: Real) -> String {
    if x.is_finite() && x != 0.0 && !(1e-3..1e5).contains(&x.abs()) {
        format!("{x:.2e}")
    } else if x.is_finite() {
        format!("{x:.3}")
    } else {
        fmt_real(x)
    }
}

/// Documentation of one section or field of the config, keyed by its path without list indices;
/// `*` stands for any face type.
pub(super) struct FieldDoc {
    pub(super) path: &'static str,
    unit: &'static str,
    text: &'static str,
}

/// The config reference, in the order fields are written. Values are not repeated here: the
/// commented defaults take them from the serialised [`Parameters::default`].
pub(super) static FIELD_DOCS: &[FieldDoc] = &[
    FieldDoc {
        path: "numerics",
        unit: "",
        text: "Numerical parameters shared by all cells (paper Table 2, numerical parameters).",
    },
    FieldDoc {
        path: "numerics.min_edge_length",
        unit: "m",
        text: "Minimum edge length l_min: remeshing collapses shorter edges and splits edges longer than l_max = \
               max_edge_ratio·l_min.",
    },
    FieldDoc {
        path: "numerics.max_edge_ratio",
        unit: "",
        text: "l_max/l_min of the simulation's remeshing, at least 2; 3 as in the paper. Larger values leave more \
               slack between a collapse and the next split (fewer remeshing operations).",
    },
    FieldDoc {
        path: "numerics.contact_cutoff",
        unit: "m",
        text: "Contact cutoff distance c: faces of different cells farther apart do not interact. At most 3·l_min.",
    },
    FieldDoc {
        path: "numerics.damping",
        unit: "kg/s",
        text: "Viscous damping coefficient ζ per node. The paper's overdamped default is 3e-9 kg/s, which a file with \
               dynamics = \"overdamped\" and no damping gets.",
    },
    FieldDoc {
        path: "numerics.time_step",
        unit: "s",
        text: "Time step Δt. Validation estimates its stability limit per cell type.",
    },
    FieldDoc {
        path: "numerics.dynamics",
        unit: "",
        text: "Equation of motion: \"dynamic\" (node mass ρV/N, damping ζ, semi-implicit Euler) or \"overdamped\" (r += Δt·f/ζ).",
    },
    FieldDoc {
        path: "numerics.contact_model",
        unit: "",
        text: "Contact model: \"spring\" (paper Eq. 2: nodes within the cutoff c of another cell's surface adhere with ω \
               and are repelled with ξ) or \"coupling\" (node pairs of two epithelial or static cells closer than c, both with \
               mean curvature below max_coupling_curvature, are tied together; the other nodes are repelled with ξ; ECM, \
               lumen and nuclei use springs).",
    },
    FieldDoc {
        path: "numerics.contact_quadrature",
        unit: "",
        text: "Spring contacts only: how the energy density Φ(d) is integrated over a cell's surface. \"vertices\" (the \
               paper's sampling: each node's area times Φ at the node) or \"faces\" (each face's exact mean of Φ with d \
               linear between its corners; nodes are searched out to c plus the longest edge). With vertices the energy \
               changes when nodes slide along an unchanged surface, which pushes the contact line of adhering cells off \
               Young–Dupré (see the docs book: Design notes, Spring contacts and Young–Dupré).",
    },
    FieldDoc {
        path: "numerics.coupling_junctions",
        unit: "",
        text: "Coupling contacts only: where three or four cells meet (junction lines, quadruple points), tie one node of \
               each into one group that moves as one node, so the interface tensions balance at a shared point as in a \
               foam. false: at most one partner per node, as in the paper, which leaves the third cell's junction node \
               free and opens a channel along every junction (a tetrahedral Surface Evolver cluster lost 31° of rim \
               angle and 19 % of its contact area). The dynamic vesicle model keeps false (see the docs book).",
    },
    FieldDoc {
        path: "numerics.polarity",
        unit: "",
        text: "Face types during the simulation: \"none\" (as in the input file), \"contacts\" (paper mode 1, every step: \
               faces touching another cell lateral, the lumen apical, the ECM or the medium basal) or \"ray_casting\" \
               (paper mode 2: the domain is voxelised, the voxels off the surfaces are clustered into cytoplasm, lumen, \
               exterior and ECM, and a ray cast from each face along its normal types it by the first region it meets: \
               another cell lateral, lumen apical, exterior or ECM basal; at the start, every polarity_interval steps and \
               after every division).",
    },
    FieldDoc {
        path: "numerics.polarity_voxel_size",
        unit: "m",
        text: "Voxel edge of the ray-casting polarisation; 0 = 1.5·min_edge_length. It must exceed the gaps between \
               cells in contact (else they read as lumen pockets) and be small against the cells; a grid above 2^24 \
               voxels is coarsened with a warning.",
    },
    FieldDoc {
        path: "numerics.polarity_interval",
        unit: "",
        text: "Steps between two ray-casting polarisations (also at the start and after every division); at least 1.",
    },
    FieldDoc {
        path: "numerics.polarity_min_lumen_fraction",
        unit: "",
        text: "Ray casting: an enclosed cavity that is no body is a lumen (its faces apical) when it holds at least this \
               fraction of the mean cell volume; smaller cavities (gaps where cells meet) are passed through by the rays.",
    },
    FieldDoc {
        path: "numerics.seed",
        unit: "",
        text: "Seed of every random draw (growth rates, division volumes and planes).",
    },
    FieldDoc {
        path: "cell_types",
        unit: "",
        text: "One parameter set per cell type; a cell's cell_type (SimuCell3D's cell_type_id) indexes this list.",
    },
    FieldDoc { path: "cell_types.name", unit: "", text: "Name of the cell type, unique within the list." },
    FieldDoc {
        path: "cell_types.kind",
        unit: "",
        text: "What the cells are: \"epithelial\", \"ecm\", \"lumen\", \"nucleus\" or \"static\". Omitted fields of the entry \
               take the defaults of this kind.",
    },
    FieldDoc {
        path: "cell_types.mass_density",
        unit: "kg/m³",
        text: "Mass density ρ; node mass m = ρV/N in the dynamic model.",
    },
    FieldDoc { path: "cell_types.bulk_modulus", unit: "Pa", text: "Bulk modulus K: pressure p = −K ln(V/V0)." },
    FieldDoc { path: "cell_types.max_pressure", unit: "Pa", text: "Largest internal pressure p_max; inf for no cap." },
    FieldDoc {
        path: "cell_types.min_volume",
        unit: "m³",
        text: "Volume V_min below which a cell is removed (apoptosis); 0 for never.",
    },
    FieldDoc {
        path: "cell_types.division_volume",
        unit: "m³",
        text: "Mean volume V_max at which a cell divides; inf for never.",
    },
    FieldDoc {
        path: "cell_types.division_volume_std",
        unit: "m³",
        text: "Standard deviation of the division volume drawn per cell.",
    },
    FieldDoc {
        path: "cell_types.division_plane",
        unit: "",
        text: "Orientation of the division plane, which passes through the volume centroid: \"longest_axis\" (Hertwig's \
               rule, perpendicular to the longest principal axis) or \"random\" (uniform, seeded by numerics.seed and \
               the cell id). Daughters get fresh cell ids, V0 = the mother's V0 / 2, new draws of growth rate and \
               division volume; the cut is closed by a lateral cap.",
    },
    FieldDoc {
        path: "cell_types.growth_rate",
        unit: "m³/s",
        text: "Mean volumetric growth rate g = dV0/dt; negative shrinks.",
    },
    FieldDoc {
        path: "cell_types.growth_rate_std",
        unit: "m³/s",
        text: "Standard deviation of the growth rate drawn per cell.",
    },
    FieldDoc {
        path: "cell_types.target_isoperimetric_ratio",
        unit: "1",
        text: "Target isoperimetric ratio Q0 = A³/V², giving the target area A0 = (Q0·V0²)^(1/3); at least 36π ≈ 113.1 (a sphere).",
    },
    FieldDoc {
        path: "cell_types.area_elasticity",
        unit: "J",
        text: "Area elasticity modulus k_a of the energy (k_a/2)(A/A0 − 1)².",
    },
    FieldDoc {
        path: "cell_types.max_coupling_curvature",
        unit: "1/m",
        text: "Largest mean curvature H_max at which a node may be coupled to another cell (paper Table 2; used by the \
               node-coupling contact model, numerics.contact_model = \"coupling\").",
    },
    FieldDoc {
        path: "cell_types.laplace_target_volume",
        unit: "",
        text: "When true, a simulation starts each cell of this type with V0 = V·exp(2γ̄/(K·R)) (R = (3V/4π)^(1/3), γ̄ = \
               its area-weighted mean surface tension): a free sphere of its initial volume is then in pressure \
               balance, so the body keeps its size instead of shrinking under its tension (for nuclei: at γ̃_n = 0.24 a \
               free nucleus would shrink to ≈ 31 % of its volume, whatever K). Needs K > 0 and max_pressure above 2γ̄/R.",
    },
    FieldDoc {
        path: "cell_types.faces",
        unit: "",
        text: "Membrane parameters per face type (apical, lateral, basal); each face of a cell has one type.",
    },
    FieldDoc {
        path: "cell_types.faces.apical",
        unit: "",
        text: "Apical faces: facing a lumen (every face of an unpolarised cell).",
    },
    FieldDoc { path: "cell_types.faces.lateral", unit: "", text: "Lateral faces: facing another cell." },
    FieldDoc { path: "cell_types.faces.basal", unit: "", text: "Basal faces: facing the exterior or the ECM." },
    FieldDoc {
        path: "cell_types.faces.*.surface_tension",
        unit: "N/m",
        text: "Surface tension γ: energy γ·A per face.",
    },
    FieldDoc {
        path: "cell_types.faces.*.bending_modulus",
        unit: "J",
        text: "Bending modulus k_b of the discrete hinge energy.",
    },
    FieldDoc {
        path: "cell_types.faces.*.adhesion",
        unit: "Pa/m",
        text: "Adhesion strength ω: contact stress per unit separation.",
    },
    FieldDoc {
        path: "cell_types.faces.*.repulsion",
        unit: "Pa/m",
        text: "Repulsion strength ξ: contact stress per unit penetration. With the spring contact model and no \
               `repulsion` anywhere in the config, `simulate` and the pipeline derive it per moving cell type from the \
               input tissue: ξ·c = 25 × the largest Laplace pressure 2γ̄/R of its cells (contacts sink c/25), and at least \
               20 × its strongest adhesion ω.",
    },
    FieldDoc {
        path: "simulation",
        unit: "",
        text: "What `tissuefit simulate` runs, with which method, when it stops and how often it saves.",
    },
    FieldDoc {
        path: "simulation.mode",
        unit: "",
        text: "\"equilibrium\" (relax until the stopping criteria hold, or max_steps: not converged) or \"time\" (integrate for duration, with growth).",
    },
    FieldDoc {
        path: "simulation.method",
        unit: "",
        text: "Equilibrium method: \"fire\" (FIRE 2.0 minimiser, adaptive step: far fewer force evaluations) or \"integrate\" (the equations of motion of numerics.dynamics).",
    },
    FieldDoc { path: "simulation.duration", unit: "s", text: "Simulated time span of a \"time\" run." },
    FieldDoc {
        path: "simulation.max_steps",
        unit: "",
        text: "Step budget of an \"equilibrium\" run; reaching it is reported as not converged.",
    },
    FieldDoc {
        path: "simulation.sampling_period",
        unit: "s",
        text: "Simulated time between saved frames (and stats rows) of a \"time\" run.",
    },
    FieldDoc {
        path: "simulation.sample_every_steps",
        unit: "",
        text: "Steps between saved frames (and stats rows) of an \"equilibrium\" run.",
    },
    FieldDoc {
        path: "simulation.checkpoint_every_steps",
        unit: "",
        text: "Steps between checkpoints (OUT/checkpoint.bin, continued by `tissuefit simulate --resume OUT`); 0 = not by step count.",
    },
    FieldDoc {
        path: "simulation.checkpoint_every_seconds",
        unit: "s",
        text: "Wall time between checkpoints; 0 = not by time. Ctrl-C/SIGTERM also saves one.",
    },
    FieldDoc {
        path: "simulation.remesh_every_steps",
        unit: "",
        text: "Steps between local remeshing passes of the moving cells (split edges longer than l_max = numerics.max_edge_ratio·l_min, collapse edges \
               shorter than l_min, flip poor triangles); 0 = never.",
    },
    FieldDoc {
        path: "simulation.remesh_below_edge_fraction",
        unit: "",
        text: "On a fixed mesh (remesh_every_steps = 0), edges of moving cells shorter than this fraction of l_min are \
               still collapsed at the step they appear, and slivers (triangle quality below 0.02) get an edge flipped (no \
               splits, no other flips): an edge that nodes drifting along the surface shrink to ~1 nm otherwise stalls \
               FIRE and folds the surface, and a sliver's swinging normal stalls FIRE; 0 = neither.",
    },
    FieldDoc {
        path: "simulation.settle_steps",
        unit: "",
        text: "Equilibrium mode: no remeshing pass at step max_steps − settle_steps or later, so at least the last \
               settle_steps steps run on a fixed mesh and the minimiser ends on it (with remeshing to the end an adhesive \
               relaxation keeps creeping); 0 = remesh to the end.",
    },
    FieldDoc {
        path: "simulation.normal_relaxation",
        unit: "",
        text: "Equilibrium mode: move nodes along their normals only (forces, and momenta when integrating, projected onto \
               the node normals). Adhesive \
               spring contacts otherwise stream nodes out of every contact and the relaxation churns without settling.",
    },
    FieldDoc {
        path: "simulation.end_at_lowest_residual",
        unit: "",
        text: "Equilibrium mode: a relaxation that does not converge ends at its lowest-residual state since the last \
               remeshing instead of its last step (summary: ended_at_step). A relaxation whose FIRE stalled does so from \
               the stall on whatever this says (the integration it continues with may still ring at the end).",
    },
    FieldDoc {
        path: "simulation.force_tolerance",
        unit: "",
        text: "Equilibrium when the largest nodal force is below this fraction of the typical tension force γ·l_min (γ: mean surface tension of the moving cells' faces) ...",
    },
    FieldDoc {
        path: "simulation.energy_tolerance",
        unit: "",
        text: "... and the total energy changes by less than this fraction per step ...",
    },
    FieldDoc {
        path: "simulation.volume_tolerance",
        unit: "",
        text: "... and no cell volume changes by more than this fraction per step.",
    },
];

const HEADER: &str = "\
tissuefit simulation parameters. SI units; every value below is the default.

A config file may be partial:
- a missing [numerics] field takes its default (damping: 3e-9 kg/s if dynamics = \"overdamped\");
- a given list of [[cell_types]] replaces the default list; a cell's cell_type (SimuCell3D's
  cell_type_id) indexes it, in file order;
- a missing field of a [[cell_types]] entry, including single fields of its
  [cell_types.faces.apical|lateral|basal] tables, takes the default of the entry's kind
  (epithelial if kind is omitted). The five entries below are the defaults of the five kinds.
Unknown keys are errors. inf is allowed for max_pressure and division_volume.";

/// The doc entry of a path like `cell_types.faces.apical.adhesion` (indices already stripped).
fn field_doc(path: &str) -> Option<&'static FieldDoc> {
    let starred = star_face_type(path);
    FIELD_DOCS.iter().find(|doc| doc.path == path).or_else(|| FIELD_DOCS.iter().find(|doc| doc.path == starred))
}

/// `cell_types.faces.<type>.<field>` → `cell_types.faces.*.<field>`; other paths unchanged.
fn star_face_type(path: &str) -> String {
    match path.strip_prefix("cell_types.faces.").and_then(|rest| rest.split_once('.')) {
        Some((_, field)) => format!("cell_types.faces.*.{field}"),
        None => path.to_owned(),
    }
}

/// The unit of a path with list indices (`cell_types[0].bulk_modulus`), for messages.
pub(super) fn unit_of(path: &str) -> &'static str {
    let mut plain = String::with_capacity(path.len());
    let mut in_index = false;
    for c in path.chars() {
        match c {
            '[' => in_index = true,
            ']' => in_index = false,
            c if !in_index => plain.push(c),
            _ => {}
        }
    }
    field_doc(&plain).map_or("", |doc| match doc.unit {
        "1" => "",
        unit => unit,
    })
}

fn join_path(parent: &str, key: &str) -> String {
    if parent.is_empty() { key.to_owned() } else { format!("{parent}.{key}") }
}

/// Keys of a table in documentation order; undocumented keys (none, if FIELD_DOCS is complete) last.
fn ordered_keys<'a>(table: &'a Table, doc_path: &str) -> Vec<&'a str> {
    let mut keys: Vec<&str> = Vec::with_capacity(table.len());
    for doc in FIELD_DOCS {
        if let Some((key, _)) = table.get_key_value(doc.path.rsplit('.').next().unwrap_or(doc.path))
            && field_doc(&join_path(doc_path, key)).is_some_and(|found| found.path == doc.path)
            && !keys.contains(&key.as_str())
        {
            keys.push(key);
        }
    }
    keys.extend(table.keys().map(String::as_str).filter(|key| !keys.contains(key)).collect::<Vec<_>>());
    keys
}

pub(super) fn is_section(value: &Value) -> bool {
    match value {
        Value::Table(_) => true,
        Value::Array(items) => !items.is_empty() && items.iter().all(Value::is_table),
        _ => false,
    }
}

fn format_value(value: &Value) -> String {
    match value {
        Value::Float(x) => fmt_real(*x),
        Value::Array(items) => format!("[{}]", items.iter().map(format_value).collect::<Vec<_>>().join(", ")),
        other => other.to_string(),
    }
}

/// Writes `# ` comment lines, wrapped at about 100 columns.
fn write_comment(out: &mut String, text: &str) {
    for paragraph in text.lines() {
        let mut line = String::from("#");
        for word in paragraph.split_whitespace() {
            if line.len() > 1 && line.chars().count() + 1 + word.chars().count() > 100 {
                out.push_str(&line);
                out.push('\n');
                line = String::from("#");
            }
            line.push(' ');
            line.push_str(word);
        }
        out.push_str(&line);
        out.push('\n');
    }
}

pub(super) fn write_toml(params: &Parameters, comments: bool) -> String {
    let Value::Table(root) = to_value(params) else { unreachable!("a struct serialises to a table") };
    let mut out = String::new();
    if comments {
        write_comment(&mut out, HEADER);
    }
    write_table(&mut out, &root, "", "", None, comments);
    out.trim_start().to_owned()
}

/// Writes a table's plain fields, then its sub-tables and arrays of tables.
/// `doc_path` is the path without indices, `header` the TOML section name, `kind` the kind of the
/// enclosing cell type (for "default for kind" comments).
fn write_table(out: &mut String, table: &Table, doc_path: &str, header: &str, kind: Option<&str>, comments: bool) {
    let keys = ordered_keys(table, doc_path);
    for &key in &keys {
        let value = &table[key];
        if is_section(value) {
            continue;
        }
        let path = join_path(doc_path, key);
        let formatted = format_value(value);
        if comments {
            let doc = field_doc(&path);
            let unit = doc.map_or("", |doc| doc.unit);
            let unit = match unit {
                "" => String::new(),
                "1" => " [dimensionless]".to_owned(),
                unit => format!(" [{unit}]"),
            };
            let default = match kind {
                Some(kind) => format!("Default for kind {kind}: {formatted}."),
                None => format!("Default: {formatted}."),
            };
            write_comment(out, &format!("{}{unit} {default}", doc.map_or("(undocumented)", |doc| doc.text)));
        }
        let _ = writeln!(out, "{key} = {formatted}");
    }
    for &key in &keys {
        let path = join_path(doc_path, key);
        let section = join_path(header, key);
        let section_doc = field_doc(&path).map_or("(undocumented)", |doc| doc.text);
        match &table[key] {
            Value::Table(sub) => {
                out.push('\n');
                if comments {
                    write_comment(out, section_doc);
                }
                let _ = writeln!(out, "[{section}]");
                write_table(out, sub, &path, &section, kind, comments);
            }
            Value::Array(items) if is_section(&table[key]) => {
                for (index, item) in items.iter().enumerate() {
                    let Value::Table(item) = item else { continue };
                    let item_kind = item.get("kind").and_then(Value::as_str);
                    out.push('\n');
                    if comments {
                        if index == 0 {
                            write_comment(out, section_doc);
                        }
                        let kind_note = item_kind.map(|kind| format!(", kind {kind}")).unwrap_or_default();
                        write_comment(
                            out,
                            &format!("{key}[{index}]{kind_note}: used by cells with cell_type = {index}."),
                        );
                    }
                    let _ = writeln!(out, "[[{section}]]");
                    write_table(out, item, &path, &section, item_kind, comments);
                }
            }
            _ => {}
        }
    }
}
