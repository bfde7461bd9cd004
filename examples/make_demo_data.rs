//! Regenerates the embedded demo tissue in `data/demo/` (committed; run this only to change it):
//! `cargo run --release --example make_demo_data`.
//!
//! `cell_quartet.vtk`: four cells of a 4-cell embryo-like cluster, 5 µm radius ellipsoids packed in a
//! tetrahedron, in the SimuCell3D legacy format (metres).

use tissuefit::geometry::Vec3;
use tissuefit::io::write_simucell3d;
use tissuefit::mesh::shapes::ellipsoid;
use tissuefit::mesh::{Cell, CellId, CellKind, Tissue};

fn main() -> anyhow::Result<()> {
    let r = 5e-6;
    let d = 1.05 * r; // centres on a tetrahedron, neighbours 2.1 r apart: the cells do not overlap
    let centres = [Vec3::new(d, d, d), Vec3::new(d, -d, -d), Vec3::new(-d, d, -d), Vec3::new(-d, -d, d)];
    let centres = centres.map(|c| c * (2.1 * r) / (2.0 * 2f64.sqrt() * d));
    let semi =
        [Vec3::new(1.0, 0.95, 0.9), Vec3::new(0.9, 1.0, 0.95), Vec3::new(0.95, 0.9, 1.0), Vec3::new(1.0, 1.0, 0.9)];
    let cells = centres
        .iter()
        .zip(semi)
        .enumerate()
        .map(|(i, (c, s))| Cell::new(CellId(i as u32 + 1), CellKind::Epithelial, 0, ellipsoid(s * r, 3, *c)))
        .collect();
    let tissue = Tissue::from_cells(cells)?;
    std::fs::create_dir_all("data/demo")?;
    write_simucell3d("data/demo/cell_quartet.vtk".as_ref(), &tissue, &[])?;
    println!("wrote data/demo/cell_quartet.vtk: {} cells, {} nodes", tissue.len(), tissue.node_count());
    Ok(())
}
