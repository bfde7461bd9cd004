//! Internal-force evaluation and full dynamic steps, per node, on 1 and 2 threads:
//! one ~1,000-node cell, and the 16 cells of simucell3d__embryo_1.vtk (49k nodes; a generated
//! 16-cell tissue of 2,562-node spheres when ../shared/data/real is absent). No contacts.
//! `cargo bench --bench forces`; divide the reported time by the node count for s per node-step.

use criterion::{Criterion, criterion_group, criterion_main};
use std::path::Path;
use tissuefit::geometry::Vec3;
use tissuefit::io::{ReadOptions, read_tissue};
use tissuefit::mechanics::{Parameters, TermSet, TissueForces, cell_parameters, integrate_step};
use tissuefit::mesh::shapes::{cube_sphere, icosphere};
use tissuefit::mesh::{Cell, CellId, CellKind, Tissue};

fn embryo() -> (String, Tissue) {
    let real = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/real/simucell3d__embryo_1.vtk");
    let cells: Vec<Cell> = if real.exists() {
        let t = read_tissue(&real, &ReadOptions::default()).unwrap().tissue;
        // One parameter set for every cell (the file stores per-cell ids in cell_type_id).
        t.cells().iter().map(|c| Cell::new(c.id(), CellKind::Epithelial, 0, c.mesh().clone())).collect()
    } else {
        (0..16)
            .map(|i| {
                let c = Vec3::new((i % 4) as f64, (i / 4) as f64, 0.0) * 2.2e-5;
                Cell::new(CellId(i), CellKind::Epithelial, 0, icosphere(1e-5, 4, c))
            })
            .collect()
    };
    let name = if real.exists() { "embryo_1" } else { "generated16" };
    (name.to_string(), Tissue::from_cells(cells).unwrap())
}

fn forces(c: &mut Criterion) {
    let params = Parameters::default();
    let one =
        Tissue::from_cells(vec![Cell::new(CellId(1), CellKind::Epithelial, 0, cube_sphere(5e-6, 13, Vec3::zeros()))])
            .unwrap();
    let (embryo_name, embryo) = embryo();
    for (name, tissue) in [("cell1016".to_string(), one), (embryo_name, embryo)] {
        let cell_params = cell_parameters(&tissue, &params).unwrap();
        for threads in [1, 2] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            let mut g = c.benchmark_group(format!("forces/{name}/{}nodes/{threads}threads", tissue.node_count()));
            g.sample_size(20);
            let mut work = TissueForces::default();
            g.bench_function("force_evaluation", |b| {
                b.iter(|| pool.install(|| work.compute(&tissue, &cell_params, TermSet::ALL)))
            });
            let mut moving = tissue.clone();
            let mut momenta: Vec<Vec<Vec3>> =
                moving.cells().iter().map(|c| vec![Vec3::zeros(); c.mesh().node_count()]).collect();
            g.bench_function("full_dynamic_step", |b| {
                b.iter(|| {
                    pool.install(|| {
                        work.compute(&moving, &cell_params, TermSet::ALL);
                        integrate_step(&mut moving, &work.cells, &cell_params, &mut momenta, &params.numerics);
                    })
                })
            });
            g.finish();
        }
    }
}

criterion_group!(benches, forces);
criterion_main!(benches);
