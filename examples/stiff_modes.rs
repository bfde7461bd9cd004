//! What holds FIRE's step down at this state? The stiffest mode of a tissue's energy Hessian, by
//! power iteration on Hessian–vector products (central differences of the forces), with the share
//! of bending and of the contacts in it, the nodes that carry it and their faces, and the largest
//! unit-mass step at which that mode stays stable against FIRE's Δt_max. FIRE restarts whenever
//! the stiffest mode turns, so a mode of stiffness k caps Δt near π/(N_delay·√k) (see the design
//! note "Spring contacts and Young–Dupré", why the SimuCell3D doublet does not converge). Read
//! `simulate`'s `final.vtk` (or a frame) and `config.toml` (the resolved model).
//!
//! ```text
//! cargo run --release --example stiff_modes -- RUN/final.vtk RUN/config.toml [ITERATIONS]
//! ```
use std::path::Path;
use tissuefit::geometry::{Real, Vec3};
use tissuefit::io::{LengthScale, ReadOptions, read_tissue};
use tissuefit::mechanics::{FireSettings, Parameters, Simulation};
use tissuefit::mesh::Tissue;
use tissuefit::mesh::remesh::triangle_quality;

type Error = Box<dyn std::error::Error>;

/// One vector per cell and node.
type Field = Vec<Vec<Vec3>>;

/// Forces of `tissue` as a relaxation starts, and the force scale γ·l_min.
fn forces(tissue: &Tissue, params: &Parameters) -> Result<(Field, Real), Error> {
    let mut sim = Simulation::new(tissue.clone(), params)?;
    sim.start()?;
    Ok((sim.forces().cells.iter().map(|c| c.forces.clone()).collect(), sim.force_scale()))
}

/// H·v ≈ −(F(x + εv) − F(x − εv))/(2ε) over the mobile nodes (immobile ones stay put).
fn hessian_times(tissue: &Tissue, params: &Parameters, v: &Field, eps: Real) -> Result<Field, Error> {
    let shifted = |sign: Real| {
        let mut t = tissue.clone();
        for (cell, v) in t.cells_mut().iter_mut().zip(v) {
            if !cell.kind().is_immobile() {
                for (x, v) in cell.positions_mut().iter_mut().zip(v) {
                    *x += sign * eps * v;
                }
            }
        }
        t
    };
    let (plus, _) = forces(&shifted(1.0), params)?;
    let (minus, _) = forces(&shifted(-1.0), params)?;
    Ok(plus.iter().zip(&minus).map(|(p, m)| p.iter().zip(m).map(|(p, m)| -(p - m) / (2.0 * eps)).collect()).collect())
}

fn dot(a: &Field, b: &Field) -> Real {
    a.iter().flatten().zip(b.iter().flatten()).map(|(x, y)| x.dot(y)).sum()
}

fn normalised(mut v: Field, tissue: &Tissue) -> Field {
    for (cell, v) in tissue.cells().iter().zip(v.iter_mut()) {
        if cell.kind().is_immobile() {
            v.iter_mut().for_each(|x| *x = Vec3::zeros());
        }
    }
    let norm = dot(&v, &v).sqrt();
    v.iter_mut().flatten().for_each(|x| *x /= norm);
    v
}

fn main() -> Result<(), Error> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if !(2..=3).contains(&args.len()) {
        return Err("usage: stiff_modes TISSUE CONFIG.toml [ITERATIONS] (simulate's final.vtk and config.toml)".into());
    }
    let iterations: usize = args.get(2).map(|s| s.parse()).transpose()?.unwrap_or(60);
    let options = ReadOptions { length_scale: LengthScale(Vec3::repeat(1.0)), orient: false };
    let tissue = read_tissue(Path::new(&args[0]), &options)?.tissue;
    let mut params = Parameters::load(Path::new(&args[1]))?;
    params.simulation.normal_relaxation = false;
    let l_min = params.numerics.min_edge_length;
    let eps = 1e-4 * l_min;

    // A deterministic start with a component along every node.
    let start: Field = tissue
        .cells()
        .iter()
        .map(|c| {
            (0..c.mesh().node_count())
                .map(|i| {
                    let h = |m: usize| ((i * m) % 17) as Real - 8.0 + 0.5;
                    Vec3::new(h(7919), h(104_729), h(31))
                })
                .collect()
        })
        .collect();
    let mut v = normalised(start, &tissue);
    let (mut k, mut previous) = (0.0, 0.0);
    for _ in 0..iterations {
        let hv = hessian_times(&tissue, &params, &v, eps)?;
        previous = k;
        k = dot(&v, &hv);
        v = normalised(hv, &tissue);
    }
    let (_, force_scale) = forces(&tissue, &params)?;
    let gamma = force_scale / l_min;
    println!(
        "stiffest mode: k = {k:.4e} N/m = {:.1} γ (γ = {gamma:.3e} N/m; last iteration changed k by {:.1e})",
        k / gamma,
        ((k - previous) / k).abs()
    );
    let fire = FireSettings::for_scales(l_min, force_scale);
    let stable = 2.0 / k.sqrt();
    println!(
        "unit masses: stable for Δt < 2/√k = {:.3}·Δt_max (FIRE's Δt_max = {:.3e}); restarts every ~π/(√k·Δt) steps",
        stable / fire.dt_max,
        fire.dt_max
    );

    // The mode's stiffness per term: its Rayleigh quotient with bending, then contacts, switched off.
    let quotient = |p: &Parameters| -> Result<Real, Error> { Ok(dot(&v, &hessian_times(&tissue, p, &v, eps)?)) };
    let mut no_bending = params.clone();
    let mut no_contacts = params.clone();
    for (b, c) in no_bending.cell_types.iter_mut().zip(no_contacts.cell_types.iter_mut()) {
        for t in tissuefit::mesh::FaceType::ALL {
            b.faces.get_mut(t).bending_modulus = 0.0;
            c.faces.get_mut(t).adhesion = 0.0;
            c.faces.get_mut(t).repulsion = 0.0;
        }
    }
    let (kb, kc) = (quotient(&no_bending)?, quotient(&no_contacts)?);
    println!(
        "its stiffness without bending {kb:.3e} N/m (bending {:.0} %), without contacts {kc:.3e} N/m (contacts {:.0} %)",
        100.0 * (k - kb) / k,
        100.0 * (k - kc) / k
    );

    let mut nodes: Vec<(Real, usize, usize)> =
        v.iter().enumerate().flat_map(|(c, v)| v.iter().enumerate().map(move |(i, x)| (x.norm(), c, i))).collect();
    nodes.sort_by(|a, b| b.0.total_cmp(&a.0));
    println!("nodes carrying it (share of the mode's norm, cell id, node):");
    for &(share, c, i) in nodes.iter().take(4) {
        println!("  {:.3}  cell {} node {i}", share, tissue.cells()[c].id().0);
    }
    let (_, c, i) = nodes[0];
    let cell = &tissue.cells()[c];
    let x = cell.mesh().positions();
    println!("faces around the first (edge lengths / l_min, area / l_min², quality 12√3·A/P²):");
    for t in cell.mesh().triangles().iter().filter(|t| t.contains(&(i as u32))) {
        let [a, b, d] = t.map(|k| x[k as usize]);
        let edges = [(b - a).norm(), (d - b).norm(), (a - d).norm()].map(|e| e / l_min);
        let area = 0.5 * (b - a).cross(&(d - a)).norm() / (l_min * l_min);
        println!(
            "  {t:?}: {:.3} {:.3} {:.3}, {area:.4}, {:.3}",
            edges[0],
            edges[1],
            edges[2],
            triangle_quality(&a, &b, &d)
        );
    }
    Ok(())
}
