//! Time of a ray-casting polarisation (paper mode 2) on 1 and 2 threads: the SimuCell3D lumen
//! geometry (../shared/data/real/simucell3d__lumen_geometry.vtk, 26 cells, 43k faces; skipped when
//! absent) and a generated aggregate of 4×4×4 packed cells (110k faces).
//! `cargo bench --bench polarity`

use criterion::{Criterion, criterion_group, criterion_main};
use std::hint::black_box;
use std::path::Path;
use tissuefit::geometry::Vec3;
use tissuefit::io::{ReadOptions, read_tissue};
use tissuefit::mechanics::{RayCastSettings, polarize_by_ray_casting};
use tissuefit::mesh::shapes::subdivided_cube;
use tissuefit::mesh::{Cell, CellId, CellKind, Tissue};

/// 64 cubes of edge 6.7 µm on a 7 µm lattice (0.3 µm gaps), 12×12 squares per side (edges ≈ 0.56 µm).
fn aggregate() -> Tissue {
    let cells = (0..64)
        .map(|i| {
            let c = Vec3::new((i % 4) as f64, ((i / 4) % 4) as f64, (i / 16) as f64) * 7e-6;
            Cell::new(CellId(i + 1), CellKind::Epithelial, 0, subdivided_cube(6.7e-6, 12, c))
        })
        .collect();
    Tissue::from_cells(cells).unwrap()
}

fn polarity(c: &mut Criterion) {
    let mut cases = vec![("aggregate_64cells", aggregate(), 0.75e-6)];
    let lumen = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/real/simucell3d__lumen_geometry.vtk");
    if lumen.exists() {
        // l_min of the file 0.5 µm: the default voxel 1.5·l_min.
        cases.insert(0, ("lumen_geometry", read_tissue(&lumen, &ReadOptions::default()).unwrap().tissue, 0.75e-6));
    }
    for (name, tissue, h) in cases {
        let mut g = c.benchmark_group(format!("polarity/{name}/{}faces", tissue.face_count()));
        g.sample_size(10);
        for threads in [1, 2] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            g.bench_function(format!("ray_casting/{threads}threads"), |b| {
                b.iter_batched_ref(
                    || tissue.clone(),
                    |t| pool.install(|| black_box(polarize_by_ray_casting(t, &RayCastSettings::new(h)).unwrap())),
                    criterion::BatchSize::LargeInput,
                )
            });
        }
        g.finish();
    }
}

criterion_group!(benches, polarity);
criterion_main!(benches);
