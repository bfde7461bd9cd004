//! Are a tissue's forces the gradient of its energy, at this state? (Why FIRE stalls: it counts a
//! step as uphill when the forces after a small move along them point against the forces before.)
//! Moves every mobile node along its force F (full forces, as the relaxation's minimiser sees them
//! without `normal_relaxation`) by steps whose largest displacement is a fraction of l_min, and
//! prints, for each step, the energy drop over ε·|F|² (→ 1 for a smooth energy, per term too) and
//! F₀·F₁/|F₀|² (→ 1 for continuous forces), plus the worst triangle qualities (slivers swing their
//! normals with tiny moves). Read `simulate`'s `final.vtk` and `config.toml` (the resolved model).
//!
//! ```text
//! cargo run --release --example force_consistency -- RUN/final.vtk RUN/config.toml
//! ```
use std::path::Path;
use tissuefit::geometry::{Real, Vec3};
use tissuefit::io::{LengthScale, ReadOptions, read_tissue};
use tissuefit::mechanics::{EnergyTerms, Parameters, Simulation};
use tissuefit::mesh::Tissue;
use tissuefit::mesh::remesh::triangle_quality;

type Error = Box<dyn std::error::Error>;

/// Forces per cell and node, and the energy terms.
type State = (Vec<Vec<Vec3>>, [Real; EnergyTerms::COUNT]);

/// Forces and energy terms of `tissue`, evaluated as a relaxation starts.
fn evaluate(tissue: Tissue, params: &Parameters) -> Result<State, Error> {
    let mut sim = Simulation::new(tissue, params)?;
    sim.start()?;
    let forces = sim.forces().cells.iter().map(|c| c.forces.clone()).collect();
    Ok((forces, sim.forces().energy().values()))
}

fn main() -> Result<(), Error> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() != 2 {
        return Err("usage: force_consistency TISSUE.vtk CONFIG.toml (simulate's final.vtk and config.toml)".into());
    }
    let options = ReadOptions { length_scale: LengthScale(Vec3::repeat(1.0)), orient: false };
    let tissue = read_tissue(Path::new(&args[0]), &options)?.tissue;
    let mut params = Parameters::load(Path::new(&args[1]))?;
    params.simulation.normal_relaxation = false;

    let mut qualities: Vec<(Real, u32)> = tissue
        .cells()
        .iter()
        .flat_map(|cell| {
            let x = cell.mesh().positions();
            cell.mesh().triangles().iter().map(move |t| {
                let [a, b, c] = t.map(|i| x[i as usize]);
                (triangle_quality(&a, &b, &c), cell.id().0)
            })
        })
        .collect();
    qualities.sort_by(|a, b| a.0.total_cmp(&b.0));
    let worst: Vec<String> = qualities.iter().take(5).map(|(q, c)| format!("{q:.1e} (cell {c})")).collect();
    println!("worst triangle qualities: {}", worst.join(", "));
    for threshold in [0.3, 0.1, 0.03, 0.01] {
        println!("  triangles below {threshold}: {}", qualities.iter().filter(|q| q.0 < threshold).count());
    }

    let (forces, terms0) = evaluate(tissue.clone(), &params)?;
    let ff: Real = forces.iter().flatten().map(|f| f.norm_squared()).sum();
    let largest = forces.iter().flatten().map(|f| f.norm()).fold(0.0, Real::max);
    println!("energy {:.6e} J, |F|² {ff:.3e} N², largest force {largest:.3e} N", terms0.iter().sum::<Real>());
    println!("move/l_min  drop/(ε|F|²)  F0·F1/|F0|²  per term ({})", EnergyTerms::NAMES.join(", "));
    let l_min = params.numerics.min_edge_length;
    for fraction in [1e-2, 1e-3, 1e-4, 1e-5] {
        let eps = fraction * l_min / largest;
        let mut moved = tissue.clone();
        for (cell, f) in moved.cells_mut().iter_mut().zip(&forces) {
            if !cell.kind().is_immobile() {
                for (x, f) in cell.positions_mut().iter_mut().zip(f) {
                    *x += eps * f;
                }
            }
        }
        let (forces1, terms1) = evaluate(moved, &params)?;
        let dot: Real = forces.iter().flatten().zip(forces1.iter().flatten()).map(|(a, b)| a.dot(b)).sum();
        let per_term: Vec<String> =
            terms0.iter().zip(terms1).map(|(a, b)| format!("{:.3}", (a - b) / (eps * ff))).collect();
        let drop = (terms0.iter().sum::<Real>() - terms1.iter().sum::<Real>()) / (eps * ff);
        println!("{fraction:>10.0e}  {drop:>12.4}  {:>11.4}  {}", dot / ff, per_term.join(", "));
    }
    Ok(())
}
