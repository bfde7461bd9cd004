//! Where a relaxation's residual force sits (issue 19 diagnosis): relax a tissue with a model file
//! for N steps, then list the nodes with the largest net force (after the coupling's averaging),
//! with their cell, coupled-group size and the face types around them.
//!
//! ```text
//! cargo run --release --example junction_forces -- TISSUE.vtk MODEL.toml STEPS [LENGTH_UNIT_M]
//! ```
use std::collections::HashMap;
use std::path::Path;
use tissuefit::io::{LengthScale, ReadOptions, read_tissue};
use tissuefit::mechanics::{NoObserver, Parameters, Simulation};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 3 {
        return Err("usage: junction_forces TISSUE MODEL.toml STEPS [METRES_PER_UNIT]".into());
    }
    let unit: f64 = args.get(3).map(|s| s.parse()).transpose()?.unwrap_or(1e-6);
    let options = ReadOptions { length_scale: LengthScale(tissuefit::geometry::Vec3::repeat(unit)), orient: false };
    let tissue = read_tissue(Path::new(&args[0]), &options)?.tissue;
    let mut params = Parameters::load(Path::new(&args[1]))?;
    params.simulation.max_steps = args[2].parse()?;
    let mut sim = Simulation::new(tissue, &params)?;
    let summary = sim.run(&mut NoObserver)?;
    println!("steps {} residual {:.3e}", summary.steps, summary.residual);
    let scale = sim.force_scale();
    let group_size: HashMap<(u32, u32), usize> =
        sim.coupled_groups().flat_map(|g| g.iter().map(move |&n| (n, g.len()))).collect();
    let tissue = sim.tissue();
    // Junction candidates: nodes with a node of two other cells within the cutoff.
    let cutoff = params.numerics.contact_cutoff;
    let normals: Vec<Vec<tissuefit::geometry::Vec3>> =
        tissue.cells().iter().map(|c| c.mesh().mean_curvature_and_normals().1).collect();
    let mut shown = 0;
    for (a, ca) in tissue.cells().iter().enumerate() {
        for (n, p) in ca.mesh().positions().iter().enumerate() {
            let mut near = Vec::new();
            for (b, cb) in tissue.cells().iter().enumerate() {
                if b == a {
                    continue;
                }
                let best = cb
                    .mesh()
                    .positions()
                    .iter()
                    .enumerate()
                    .map(|(m, q)| ((q - p).norm(), m))
                    .min_by(|x, y| x.0.total_cmp(&y.0))
                    .unwrap();
                if best.0 < 2.0 * cutoff {
                    near.push((b, best.1, best.0 / cutoff, normals[a][n].dot(&normals[b][best.1])));
                }
            }
            if near.len() >= 2 && shown < 30 {
                shown += 1;
                println!(
                    "junction? cell {a} node {n} group {} near {:?}",
                    group_size.get(&(a as u32, n as u32)).copied().unwrap_or(1),
                    near.iter().map(|x| format!("cell {} d/c {:.2} n·n {:.2}", x.0, x.2, x.3)).collect::<Vec<_>>()
                );
            }
        }
    }
    let mut rows = Vec::new();
    for (c, cf) in sim.forces().cells.iter().enumerate() {
        for (n, f) in cf.forces.iter().enumerate() {
            rows.push((f.norm() / scale, c as u32, n as u32));
        }
    }
    rows.sort_by(|a, b| b.0.total_cmp(&a.0));
    let mut histogram = [0usize; 5];
    for r in &rows {
        let g = group_size.get(&(r.1, r.2)).copied().unwrap_or(1).min(4);
        histogram[g] += 1;
    }
    println!("nodes by group size (1 = untied): {:?}", &histogram[1..]);
    for &(f, c, n) in rows.iter().take(25) {
        let cell = &tissue.cells()[c as usize];
        let p = cell.mesh().positions()[n as usize];
        let mut types = [0usize; 3];
        for (t, ft) in cell.mesh().triangles().iter().zip(cell.face_types()) {
            if t.contains(&n) {
                types[ft.code() as usize] += 1;
            }
        }
        println!(
            "|f| {f:8.3}  cell {c:2} node {n:5}  at ({:7.3} {:7.3} {:7.3}) µm  group {}  faces apical/lateral/basal {:?}",
            p.x * 1e6,
            p.y * 1e6,
            p.z * 1e6,
            group_size.get(&(c, n)).copied().unwrap_or(1),
            types
        );
    }
    Ok(())
}
