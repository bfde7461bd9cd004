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
//! `--method fire|integrate` (fire), `--remesh N` (50). One line per run, `key=value` separated by
//! spaces, so that a shell loop over a grid makes a table (see docs: the Young–Dupré regime note).

use std::time::Instant;
use tissuefit::geometry::{Real, Vec3};
use tissuefit::mechanics::{ContactModel, Observer, Parameters, Polarity, RelaxMethod, Sample, Simulation};
use tissuefit::mechanics::{SimulationMode, SimulationSummary};
use tissuefit::mesh::shapes::icosphere;
use tissuefit::mesh::{Cell, CellId, CellKind, FaceType, Tissue};
use tissuefit::morphology::far_field::fit_sphere;

struct Quiet;
impl Observer for Quiet {
    fn sample(&mut self, _: &Sample<'_>) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
        Ok(())
    }
}

const GAMMA: Real = 1e-3;

struct Args {
    radius: Real,
    lmin: Real,
    cutoff: Real,
    ratio: Real,
    over: bool,
    normal: bool,
    steps: u64,
    settle: u64,
    xi: Real,
    integrate: bool,
    remesh: u64,
}

fn parse() -> Result<Args, String> {
    let mut a = Args {
        radius: 2e-6,
        lmin: 2e-7,
        cutoff: 2e-7,
        ratio: 0.3,
        over: false,
        normal: false,
        steps: 8000,
        settle: 0,
        xi: 1e12,
        integrate: false,
        remesh: 50,
    };
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut i = 0;
    while i < args.len() {
        let flag = args[i].as_str();
        if flag == "--normal" {
            a.normal = true;
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

/// Young–Dupré half-angle (degrees) for w/(2γ) = `ratio`.
fn young_dupre(ratio: Real) -> Real {
    (1.0 - ratio).clamp(-1.0, 1.0).acos().to_degrees()
}

/// An icosphere of radius `r` fine enough for edges near `lmin`, centred at x = `x`; with `flat`,
/// its nodes beyond the plane x = `plane` (on the side away from the centre) are moved onto it.
fn cell(id: u32, r: Real, lmin: Real, x: Real, flat: Option<Real>) -> Cell {
    let subdivisions = ((1.1 * r / lmin).log2().round() as u32).clamp(2, 5);
    let mut mesh = icosphere(r, subdivisions, Vec3::new(x, 0.0, 0.0));
    if let Some(plane) = flat {
        let side = (plane - x).signum();
        for p in mesh.positions_mut() {
            if (p.x - plane) * side > 0.0 {
                p.x = plane;
            }
        }
    }
    let types = vec![FaceType::Basal; mesh.face_count()];
    Cell::new(CellId(id), CellKind::Epithelial, 0, mesh).with_face_types(types).expect("one type per face")
}

fn params(a: &Args) -> Parameters {
    let mut p = Parameters::default();
    p.numerics.contact_model = ContactModel::Spring;
    p.numerics.polarity = Polarity::None;
    p.numerics.min_edge_length = a.lmin;
    p.numerics.contact_cutoff = a.cutoff;
    // Only integration uses it (and validation checks it against the contact stiffness).
    p.numerics.time_step = 2e-8;
    let omega = 4.0 * a.ratio * GAMMA / (a.cutoff * a.cutoff);
    let t = &mut p.cell_types[0];
    for ft in FaceType::ALL {
        let f = t.faces.get_mut(ft);
        f.surface_tension = GAMMA;
        f.adhesion = omega;
        f.repulsion = a.xi;
        f.bending_modulus = 0.0;
    }
    t.area_elasticity = 0.0;
    t.max_pressure = Real::INFINITY;
    t.growth_rate = 0.0;
    t.laplace_target_volume = true;
    let s = &mut p.simulation;
    s.mode = SimulationMode::Equilibrium;
    s.method = if a.integrate { RelaxMethod::Integrate } else { RelaxMethod::Fire };
    s.remesh_every_steps = a.remesh;
    s.max_steps = a.steps;
    s.settle_steps = a.settle;
    s.normal_relaxation = a.normal;
    s.sample_every_steps = a.steps + 1;
    p
}

/// Far-field half-angles of both cells: each free cap (nodes farther than `margin` from the other
/// cell's centre side of the midplane) fitted by a sphere; cos ψ = h/ρ with h the distance from the
/// cap's centre to the midplane (positive on its own side).
fn far_field_half_angles(t: &Tissue, margin: Real) -> [Real; 2] {
    let centroid = |c: &Cell| c.mesh().positions().iter().sum::<Vec3>() / c.mesh().node_count() as Real;
    let [a, b] = [&t.cells()[0], &t.cells()[1]];
    let (ca, cb) = (centroid(a), centroid(b));
    let axis = (cb - ca).normalize();
    let mid = 0.5 * (ca + cb);
    let mut out = [0.0; 2];
    for (k, (cell, towards)) in [(a, -axis), (b, axis)].into_iter().enumerate() {
        let cap: Vec<Vec3> =
            cell.mesh().positions().iter().copied().filter(|p| (p - mid).dot(&towards) > margin).collect();
        let (sphere, _) = fit_sphere(&cap).expect("a free cap fixes a sphere");
        let h = (sphere.centre - mid).dot(&towards);
        out[k] = (h / sphere.radius).clamp(-1.0, 1.0).acos().to_degrees();
    }
    out
}

fn run(a: &Args) -> Result<(), String> {
    let yd = young_dupre(a.ratio);
    let (r, c) = (a.radius, a.cutoff);
    let tissue = if a.over {
        let psi = (yd + 15.0).min(80.0).to_radians();
        let x = r * psi.cos() + 0.25 * c;
        Tissue::from_cells(vec![cell(1, r, a.lmin, -x, Some(-0.25 * c)), cell(2, r, a.lmin, x, Some(0.25 * c))])
    } else {
        let x = r + 0.25 * c;
        Tissue::from_cells(vec![cell(1, r, a.lmin, -x, None), cell(2, r, a.lmin, x, None)])
    }
    .map_err(|e| e.to_string())?;
    let p = params(a);
    for warning in p.validate().map_err(|e| e.to_string())? {
        eprintln!("spring_regime: {warning}");
    }
    let started = Instant::now();
    let mut sim = Simulation::new(tissue, &p).map_err(|e| e.to_string())?;
    let summary: SimulationSummary = sim.run(&mut Quiet).map_err(|e| e.to_string())?;
    let wall = started.elapsed().as_secs_f64();
    let nodes = sim.tissue().cells()[0].mesh().node_count();
    let [ha, hb] = far_field_half_angles(sim.tissue(), 0.3 * r);
    let measured = 0.5 * (ha + hb);
    println!(
        "radius_um={} lmin_um={} cutoff_um={} ratio={} start={} normal={} yd_deg={yd:.2} half_angle_deg={measured:.2} \
         error_deg={:+.2} cells_deg={ha:.2}/{hb:.2} overlap_pct={:.3} nodes_per_cell={nodes} steps={} converged={} \
         residual={:.3e} splits={} collapses={} wall_s={wall:.1} stop={:?}",
        a.radius * 1e6,
        a.lmin * 1e6,
        a.cutoff * 1e6,
        a.ratio,
        if a.over { "over" } else { "touch" },
        a.normal,
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
