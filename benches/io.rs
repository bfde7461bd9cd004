//! Read and write speed of tissue files. Uses ../shared/data/real/simucell3d__embryo_1.vtk (49k
//! points, 16 cells) when present, else a generated 16-cell tissue of similar size.
//! `cargo bench --bench io`

use criterion::{Criterion, criterion_group, criterion_main};
use std::hint::black_box;
use std::path::{Path, PathBuf};
use tissuefit::geometry::Vec3;
use tissuefit::io::{ReadOptions, read_tissue, read_vtp, write_simucell3d, write_vtp};
use tissuefit::mesh::shapes::icosphere;
use tissuefit::mesh::{Cell, CellId, CellKind, Tissue};

fn input(dir: &Path) -> PathBuf {
    let real = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/real/simucell3d__embryo_1.vtk");
    if real.exists() {
        return real;
    }
    // 16 cells × 2562 nodes ≈ 41k nodes.
    let cells = (0..16)
        .map(|i| {
            let c = Vec3::new((i % 4) as f64, (i / 4) as f64, 0.0) * 2.2e-5;
            Cell::new(CellId(i), CellKind::Epithelial, 0, icosphere(1e-5, 4, c))
        })
        .collect();
    let path = dir.join("generated.vtk");
    write_simucell3d(&path, &Tissue::from_cells(cells).unwrap(), &[]).unwrap();
    path
}

fn io(c: &mut Criterion) {
    let dir = tempfile::tempdir().unwrap();
    let src = input(dir.path());
    let tissue = read_tissue(&src, &ReadOptions::default()).unwrap().tissue;
    let name = src.file_name().unwrap().to_string_lossy().to_string();
    let (legacy, vtp) = (dir.path().join("out.vtk"), dir.path().join("out.vtp"));
    let mut g = c.benchmark_group(format!("io/{name}/{}nodes", tissue.node_count()));
    g.sample_size(20);
    g.bench_function("read_legacy", |b| b.iter(|| black_box(read_tissue(&src, &ReadOptions::default()).unwrap())));
    // The vtkio crate's legacy parser on the same file, for comparison (parse only, no tissue built).
    g.bench_function("vtkio_import", |b| b.iter(|| black_box(vtkio::Vtk::import(&src).unwrap())));
    g.bench_function("write_legacy", |b| b.iter(|| write_simucell3d(&legacy, black_box(&tissue), &[]).unwrap()));
    g.bench_function("write_vtp", |b| b.iter(|| write_vtp(&vtp, black_box(&tissue), &[], None).unwrap()));
    g.bench_function("read_vtp", |b| b.iter(|| black_box(read_vtp(&vtp).unwrap())));
    g.finish();
}

criterion_group!(benches, io);
criterion_main!(benches);
