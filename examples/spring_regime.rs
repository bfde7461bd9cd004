//! Spring-contact doublets against Young–Dupré (issue 20): two equal cells with surface tension γ on
//! every face and the spring adhesion ω, relaxed to equilibrium; prints the far-field contact
//! half-angle (sphere fitted to each free cap, interface plane through the midpoint of the two
//! centres) next to Young–Dupré's cos(θ/2) = 1 − w/(2γ) with w = ωc²/2, the overlap, and the cost.
//!
//! ```text
//! cargo run --release --example spring_regime -- --radius 2 --lmin 0.2 --cutoff 0.2 --ratio 0.3 --start touch
//! ```
//!
//! Options (lengths in µm): `--radius R` (2), `--lmin L` (0.2), `--cutoff C` (0.2), `--ratio r`
//! (w/(2γ), 0.3), `--start touch|over` (touch: spheres 0.5·c apart; over: truncated spheres whose
//! flat contact starts 15° beyond Young–Dupré's half-angle), `--normal` (simulation.normal_relaxation),
//! `--steps N` (8000), `--settle N` (0: simulation.settle_steps), `--xi X` (repulsion, Pa/m; 1e12),
//! `--method fire|integrate` (fire), `--remesh N` (50), `--quadrature vertices|faces`
//! (numerics.contact_quadrature, vertices), `--unit-masses` (FIRE without the contact masses,
//! `Simulation::set_fire_contact_masses(false)`), `--measured-masses`
//! (simulation.fire_measured_masses), `--contact-full-forces` (with `--normal`:
//! simulation.full_forces_at_contacts). One line per run, `key=value` separated by spaces, so that a
//! shell loop over a grid makes a table (see docs: the Young–Dupré regime note).

use std::time::Instant;
use tissuefit::geometry::Real;
use tissuefit::mechanics::{ContactQuadrature, NoObserver, Simulation, SimulationSummary};

#[path = "../tests/integration/support/young_dupre.rs"]
mod young_dupre;
use young_dupre::{Doublet, far_field_half_angles, params, start, young_dupre};

fn parse() -> Result<Doublet, String> {
    let mut a = Doublet::default();
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut i = 0;
    while i < args.len() {
        let flag = args[i].as_str();
        if matches!(flag, "--normal" | "--unit-masses" | "--measured-masses" | "--contact-full-forces") {
            match flag {
                "--normal" => a.normal = true,
                "--unit-masses" => a.unit_masses = true,
                "--contact-full-forces" => a.contact_full_forces = true,
                _ => a.measured_masses = true,
            }
            i += 1;
            continue;
        }
        let value = args.get(i + 1).ok_or(format!("{flag} needs a value"))?;
        let number = || value.parse::<Real>().map_err(|e| format!("{flag} {value}: {e}"));
        match flag {
            "--radius" => a.radius = number()? * 1e-6,
            "--lmin" => a.lmin = number()? * 1e-6,
            "--cutoff" => a.cutoff = number()? * 1e-6,
            "--ratio" => a.ratio = number()?,
            "--xi" => a.xi = number()?,
            "--steps" => a.steps = number()? as u64,
            "--settle" => a.settle = number()? as u64,
            "--remesh" => a.remesh = number()? as u64,
            "--start" => {
                a.over = match value.as_str() {
                    "touch" => false,
                    "over" => true,
                    _ => return Err(format!("--start {value}: touch or over")),
                }
            }
            "--quadrature" => {
                a.quadrature = match value.as_str() {
                    "vertices" => ContactQuadrature::Vertices,
                    "faces" => ContactQuadrature::Faces,
                    _ => return Err(format!("--quadrature {value}: vertices or faces")),
                }
            }
            "--method" => {
                a.integrate = match value.as_str() {
                    "fire" => false,
                    "integrate" => true,
                    _ => return Err(format!("--method {value}: fire or integrate")),
                }
            }
            _ => return Err(format!("unknown option {flag}")),
        }
        i += 2;
    }
    Ok(a)
}

fn run(a: &Doublet) -> Result<(), String> {
    let yd = young_dupre(a.ratio);
    let r = a.radius;
    let tissue = start(a);
    let p = params(a);
    for warning in p.validate().map_err(|e| e.to_string())? {
        eprintln!("spring_regime: {warning}");
    }
    let started = Instant::now();
    let mut sim = Simulation::new(tissue, &p).map_err(|e| e.to_string())?;
    // Contact masses as `simulate` chooses them (only where contacts are stiff: R = 5 and 10 µm
    // here), or off with --unit-masses. (Forcing them on everywhere made the R = 2 µm,
    // w/(2γ) = 0.5 doublet churn: 33,844 splits in 15,000 steps instead of 645 in 12,000.)
    if a.unit_masses {
        sim.set_fire_contact_masses(false);
    }
    let summary: SimulationSummary = sim.run(&mut NoObserver).map_err(|e| e.to_string())?;
    let wall = started.elapsed().as_secs_f64();
    let nodes = sim.tissue().cells()[0].mesh().node_count();
    let [ha, hb] = far_field_half_angles(sim.tissue(), 0.3 * r);
    let measured = 0.5 * (ha + hb);
    println!(
        "radius_um={} lmin_um={} cutoff_um={} ratio={} xi={:.2e} start={} normal={} contact_full_forces={} measured_masses={} quadrature={} yd_deg={yd:.2} half_angle_deg={measured:.2} \
         error_deg={:+.2} cells_deg={ha:.2}/{hb:.2} overlap_pct={:.3} nodes_per_cell={nodes} steps={} converged={} \
         residual={:.3e} splits={} collapses={} wall_s={wall:.1} stop={:?}",
        a.radius * 1e6,
        a.lmin * 1e6,
        a.cutoff * 1e6,
        a.ratio,
        a.xi,
        if a.over { "over" } else { "touch" },
        a.normal,
        a.contact_full_forces,
        a.measured_masses,
        if a.quadrature == ContactQuadrature::Faces { "faces" } else { "vertices" },
        measured - yd,
        100.0 * summary.max_overlap_fraction,
        summary.steps,
        summary.converged,
        summary.residual,
        summary.topology.splits,
        summary.topology.collapses,
        summary.stop_reason.as_deref().unwrap_or("")
    );
    Ok(())
}

fn main() {
    let result = parse().and_then(|a| run(&a));
    if let Err(e) = result {
        eprintln!("spring_regime: {e}");
        std::process::exit(1);
    }
}
