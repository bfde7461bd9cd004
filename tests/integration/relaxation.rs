//! Relaxation to equilibrium with remeshing: `simulation.settle_steps` (the end of a relaxation on
//! a fixed mesh) and `simulation.normal_relaxation` (nodes move along their normals), on a small
//! adhesive spring aggregate generated from polyhedra.

use tissuefit::geometry::Real;
use tissuefit::mechanics::{ContactModel, NoObserver, Parameters, Simulation, SimulationSummary};
use tissuefit::mesh::Tissue;

use crate::support::cli::tissuefit;
use crate::support::round_trip;
use round_trip::{AGGREGATE_GAMMA, initial_aggregate, round_trip_model};

/// Spring contacts with w/(2γ) = ωc²/(4γ) = 0.1 (c = l_min), remeshing every 50 steps.
fn model(l_min: Real, steps: u64) -> Parameters {
    let omega = 0.1 * 4.0 * AGGREGATE_GAMMA / (l_min * l_min);
    round_trip_model(ContactModel::Spring, l_min, AGGREGATE_GAMMA, AGGREGATE_GAMMA, omega, 1.5e-8, steps)
}

fn relax(tissue: &Tissue, params: &Parameters) -> (Tissue, SimulationSummary) {
    let mut sim = Simulation::new(tissue.clone(), params).unwrap();
    let summary = sim.run(&mut NoObserver).unwrap();
    (sim.into_tissue(), summary)
}

/// With settle_steps = N the last N steps of max_steps remesh nothing: a run of 600 steps settling
/// the last 300 remeshes exactly as a run of 300 steps settling its last one does (bit for bit the
/// same passes: at steps 50 … 250), and one settling all its steps never remeshes.
#[test]
fn settle_steps_end_a_relaxation_on_a_fixed_mesh() {
    let (initial, l_min) = initial_aggregate(8, 100);
    let mut short = model(l_min, 300);
    short.simulation.settle_steps = 1;
    let (_, first) = relax(&initial, &short);
    assert!(first.topology.remesh_passes > 0, "the polyhedra must need remeshing for this test to mean anything");
    let mut long = model(l_min, 600);
    long.simulation.settle_steps = 300;
    let (_, settled) = relax(&initial, &long);
    assert_eq!(settled.topology, first.topology, "remeshing stopped after step 300");
    long.simulation.settle_steps = 600;
    let (tissue, fixed) = relax(&initial, &long);
    assert_eq!(fixed.topology.remesh_passes, 0);
    for (a, b) in tissue.cells().iter().zip(initial.cells()) {
        assert_eq!(a.mesh().triangles(), b.mesh().triangles(), "cell {}: no topology change", a.id());
    }
}

/// Remeshing operations (splits + collapses) of a relaxation continued from `start`.
fn operations(s: &SimulationSummary) -> u64 {
    s.topology.splits + s.topology.collapses
}

/// Moved with the full forces, an adhesive spring aggregate churns: nodes stream out of every
/// contact (the contact energy weights each node by its area), remeshing refills it, and splits and
/// collapses go on at the same pace long after the polyhedra have rounded up. Moved along their
/// normals, the nodes stop: the same continuation needs a small fraction of the operations, and
/// every force left is normal to the surface.
#[test]
fn normal_relaxation_stops_the_remeshing_churn_of_adhesive_contacts() {
    let (initial, l_min) = initial_aggregate(8, 100);
    let run = |normal: bool| {
        let mut p = model(l_min, 2000);
        p.simulation.normal_relaxation = normal;
        let (rounded, _) = relax(&initial, &p);
        let (_, later) = relax(&rounded, &p);
        later
    };
    let (full, normal) = (run(false), run(true));
    eprintln!(
        "steps 2000–4000: full forces {} splits + collapses (residual {:.3}), normal {} (residual {:.3})",
        operations(&full),
        full.residual,
        operations(&normal),
        normal.residual
    );
    assert!(
        4 * operations(&normal) < operations(&full),
        "normal relaxation: {} operations, full forces: {}",
        operations(&normal),
        operations(&full)
    );

    let mut p = model(l_min, 200);
    p.simulation.normal_relaxation = true;
    let mut sim = Simulation::new(initial.clone(), &p).unwrap();
    sim.run(&mut NoObserver).unwrap();
    for (cell, work) in sim.tissue().cells().iter().zip(&sim.forces().cells) {
        // The mesh's own area-weighted node normals (not the projection's arithmetic).
        let (_, normals) = cell.mesh().mean_curvature_and_normals();
        for (f, n) in work.forces.iter().zip(&normals) {
            assert!(f.cross(n).norm() <= 1e-9 * f.norm() * n.norm(), "cell {}: a tangential force {f:?}", cell.id());
        }
    }
}

/// Coupling contacts tie node pairs that share one force; projected onto each node's own normal the
/// two forces would differ and the pair would drift apart between evaluations. Under normal
/// relaxation a tied pair still gets one force (the mean of the two projections).
#[test]
fn normal_relaxation_keeps_one_force_per_coupled_pair() {
    let (initial, l_min) = initial_aggregate(8, 100);
    let mut p =
        round_trip_model(ContactModel::Coupling, l_min, AGGREGATE_GAMMA, 0.5 * AGGREGATE_GAMMA, 0.0, 1.5e-8, 300);
    p.simulation.normal_relaxation = true;
    let mut sim = Simulation::new(initial, &p).unwrap();
    sim.run(&mut NoObserver).unwrap();
    let pairs = sim.coupled_pairs();
    assert!(!pairs.is_empty(), "the aggregate's cells must be coupled for this test to mean anything");
    let force = |(c, n): (u32, u32)| sim.forces().cells[c as usize].forces[n as usize];
    for pair in pairs {
        let (fa, fb) = (force(pair.a), force(pair.b));
        assert!((fa - fb).norm() <= 1e-12 * fa.norm().max(fb.norm()), "pair {pair:?}: {fa:?} vs {fb:?}");
    }
}

/// Moved along their normals by integrating the equations of motion (`--method integrate`, and what
/// a relaxation does after FIRE stalls), the nodes keep no tangential momentum: a momentum gathered
/// along earlier normals would move them where the projected forces do no work and the energy
/// could rise unpaid. Before the momenta were projected too, this two-cell spheroid (no adhesion)
/// grew spikes and folded through itself at step 276, 5× below the estimated stability limit; now
/// it runs its 400 steps and ends lower in energy than it started.
#[test]
fn normal_relaxation_by_integration_descends_without_folding() {
    let dir = tempfile::tempdir().unwrap();
    let path = |name: &str| dir.path().join(name).to_str().unwrap().to_string();
    let made = tissuefit(&[
        "generate",
        "mesh",
        "--kind",
        "spheroid",
        "--cells",
        "2",
        "--min-edge-length",
        "1.4e-6",
        "--out",
        &path("spheroid.vtk"),
    ]);
    assert!(made.status.success(), "{}", String::from_utf8_lossy(&made.stderr));
    let faces = ["apical", "lateral", "basal"].map(|t| format!("[cell_types.faces.{t}]\nadhesion = 0.0\n")).concat();
    let config = format!(
        "[simulation]\nnormal_relaxation = true\n\n[[cell_types]]\nname = \"epithelial\"\nkind = \"epithelial\"\n{faces}"
    );
    std::fs::write(path("config.toml"), config).unwrap();
    let run = tissuefit(&[
        "simulate",
        &path("spheroid.vtk"),
        "--config",
        &path("config.toml"),
        "--method",
        "integrate",
        "--max-steps",
        "400",
        "--threads",
        "1",
        "--out",
        &path("run"),
    ]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(!stderr.contains("folded"), "{stderr}");
    assert!(matches!(run.status.code(), Some(0 | 1)), "converged or not, but no error: {stderr}");
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(path("run/summary.json")).unwrap()).unwrap();
    assert_eq!(summary["steps"], 400);
    let end = summary["energy_total"].as_f64().unwrap();
    // stats.csv: the first rows (step 0) carry each cell's total energy.
    let stats = std::fs::read_to_string(path("run/stats.csv")).unwrap();
    let mut lines = stats.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let column = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let (step, energy) = (column("step"), column("energy_total"));
    let start: f64 = lines
        .map(|l| l.split(',').collect::<Vec<_>>())
        .filter(|f| f[step] == "0")
        .map(|f| f[energy].parse::<f64>().unwrap())
        .sum();
    assert!(end < start, "the energy rose from {start:e} J to {end:e} J");
}
