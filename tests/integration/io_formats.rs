//! Reading hand-written files in every supported layout, and clear errors on malformed ones.

use std::path::PathBuf;
use tissuefit::io::{IoError, ReadOptions, TissueFormat, read_tissue};
use tissuefit::mesh::{CellKind, FaceType};

/// A SimuCell3D-style file: a unit cube (6 quads, cell type 0) and a tetrahedron (cell type 4, static).
fn simucell3d_text() -> String {
    let mut s =
        String::from("# vtk DataFile Version 4.2\ntwo cells\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 12 float\n");
    for i in 0..8 {
        s += &format!("{} {} {}\n", i & 1, (i >> 1) & 1, (i >> 2) & 1);
    }
    s += "3 0 0\n4 0 0\n3 1 0\n3 0 1\n";
    // Cube: 1 + 6·5 = 31 ints after the count; tetra: 1 + 4·4 = 17.
    s += "CELLS 2 50\n";
    s += "31 6 4 0 2 3 1 4 4 5 7 6 4 0 1 5 4 4 2 6 7 3 4 0 4 6 2 4 1 3 7 5\n";
    s += "17 4 3 8 10 9 3 8 9 11 3 8 11 10 3 9 10 11\n";
    s += "CELL_TYPES 2\n42\n42\n";
    s += "CELL_DATA 2\nFIELD FieldData 2\ncell_id 1 2 int\n7 9\nMETADATA\nINFORMATION 0\n\ncell_type_id 1 2 int\n0 4\n";
    s
}

fn write(dir: &tempfile::TempDir, name: &str, text: &str) -> PathBuf {
    let p = dir.path().join(name);
    std::fs::write(&p, text).unwrap();
    p
}

#[test]
fn simucell3d_polyhedra_with_polygon_faces_read_and_triangulate() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(&dir, "two.vtk", &simucell3d_text());
    let r = read_tissue(&p, &ReadOptions::default()).unwrap();
    assert_eq!(r.format, TissueFormat::Simucell3d);
    let cells = r.tissue.cells();
    assert_eq!(cells.len(), 2);
    assert_eq!((cells[0].id().0, cells[1].id().0), (7, 9));
    assert_eq!((cells[0].kind(), cells[1].kind()), (CellKind::Epithelial, CellKind::Static));
    assert_eq!(cells[0].mesh().face_count(), 12);
    cells[0].mesh().validate().unwrap();
    assert!((cells[0].mesh().signed_volume() - 1.0).abs() < 1e-12);
    cells[1].mesh().validate().unwrap();
    assert!((cells[1].mesh().signed_volume() - 1.0 / 6.0).abs() < 1e-12);
    assert!(cells.iter().all(|c| c.face_types().iter().all(|&t| t == FaceType::Apical)));
    // Metre-sized cells are suspicious in a tissue: the reader says so.
    let r = read_tissue(&p, &ReadOptions { length_scale: "um".parse().unwrap(), orient: false }).unwrap();
    assert!((r.tissue.cells()[0].mesh().signed_volume() - 1e-18).abs() < 1e-30);
}

/// Two unit tetrahedra sharing the face (1,2,3), as a VTK 5.1 multi-material mesh.
fn multimaterial_51() -> String {
    let pts = "0 0 0  1 0 0  0 1 0  0 0 1  1 1 1";
    // Cell 1: tetra 0,1,2,3 (outward: 0-2-1, 0-1-3, 0-3-2, 1-2-3). Cell 2: tetra 1,2,3,4 on the other
    // side of face 1-2-3. Each triangle's normal points from label1 into label2.
    let tris = [
        ([0, 2, 1], 1, 0),
        ([0, 1, 3], 1, 0),
        ([0, 3, 2], 1, 0),
        ([1, 2, 3], 1, 2),
        ([1, 4, 3], 2, 0),
        ([2, 4, 1], 2, 0),
        ([3, 4, 2], 2, 0),
    ];
    let mut s = format!(
        "# vtk DataFile Version 5.1\nwritten by hand\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 5 double\n{pts}\nCELLS 8 21\nOFFSETS vtktypeint64\n"
    );
    s += &(0..=7).map(|i| (3 * i).to_string()).collect::<Vec<_>>().join(" ");
    s += "\nCONNECTIVITY vtktypeint64\n";
    s += &tris.iter().map(|t| format!("{} {} {}", t.0[0], t.0[1], t.0[2])).collect::<Vec<_>>().join("\n");
    s += "\nCELL_TYPES 7\n5 5 5 5 5 5 5\nCELL_DATA 7\nFIELD FieldData 2\nlabel1 1 7 vtktypeuint64\n";
    s += &tris.iter().map(|t| t.1.to_string()).collect::<Vec<_>>().join(" ");
    s += "\nlabel2 1 7 vtktypeuint64\n";
    s += &tris.iter().map(|t| t.2.to_string()).collect::<Vec<_>>().join(" ");
    s + "\n"
}

#[test]
fn multimaterial_mesh_gives_outward_cells_in_either_label_convention() {
    let dir = tempfile::tempdir().unwrap();
    let text = multimaterial_51();
    let p = write(&dir, "mm.vtk", &text);
    let r = read_tissue(&p, &ReadOptions::default()).unwrap();
    assert_eq!(r.format, TissueFormat::MultiMaterial);
    let cells = r.tissue.cells();
    assert_eq!(cells.iter().map(|c| c.id().0).collect::<Vec<_>>(), [1, 2]);
    for c in cells {
        assert_eq!(c.mesh().validate(), Ok(()), "cell {}", c.id());
        assert_eq!(c.mesh().face_count(), 4);
    }
    // Swap label1 and label2: the opposite convention must give the same outward cells.
    let swapped = text.replacen("label1 1 7", "labelX 1 7", 1).replacen("label2 1 7", "label1 1 7", 1).replacen(
        "labelX 1 7",
        "label2 1 7",
        1,
    );
    let q = write(&dir, "mm_swapped.vtk", &swapped);
    let r2 = read_tissue(&q, &ReadOptions::default()).unwrap();
    for (a, b) in cells.iter().zip(r2.tissue.cells()) {
        assert!((a.mesh().signed_volume() - b.mesh().signed_volume()).abs() < 1e-15);
        assert!(b.mesh().signed_volume() > 0.0);
    }
}

/// The faces of a multi-material mesh name the cell on their other side; `measure` takes the contacts
/// from those labels: the shared face's exact area on both sides, no face near it counted. The two
/// tetrahedra are a case where the distance rule is badly off: every face of tetrahedron 1 has its
/// centroid 0.19 from the shared face's plane, inside the default δ = mean edge / 4 ≈ 0.33, so the
/// rule counts the whole of it as contact (checked below, so the test tells the rules apart).
#[test]
fn multimaterial_contacts_come_from_the_interface_labels_and_survive_a_vtp_round_trip() {
    use tissuefit::io::write_tissue;
    use tissuefit::morphology::{ContactRule, MeasureSettings, measure_tissue};
    let dir = tempfile::tempdir().unwrap();
    let p = write(&dir, "mm.vtk", &multimaterial_51());
    let tissue = read_tissue(&p, &ReadOptions::default()).unwrap().tissue;
    for c in tissue.cells() {
        let labels = c.interface_labels().expect("a multi-material cell carries its interface labels");
        let other = if c.id().0 == 1 { 2 } else { 1 };
        assert_eq!(labels.iter().filter(|&&l| l == other).count(), 1, "cell {}: {labels:?}", c.id());
        assert_eq!(labels.iter().filter(|&&l| l == 0).count(), 3, "cell {}: {labels:?}", c.id());
    }
    let shared = 3.0_f64.sqrt() / 2.0;
    let check = |tissue: &tissuefit::mesh::Tissue| {
        let m = measure_tissue(tissue, &MeasureSettings::default()).unwrap();
        assert_eq!(m.summary.contact_rule, ContactRule::InterfaceLabels);
        assert_eq!(m.summary.contact_distance, None);
        assert_eq!(m.contacts.len(), 1);
        let c = &m.contacts[0];
        for area in [c.area, c.area_a, c.area_b] {
            assert!((area - shared).abs() < 1e-12, "contact area {area}, exact {shared}");
        }
        assert!((m.cells[0].free_area - 1.5).abs() < 1e-12, "free area of tetrahedron 1: {}", m.cells[0].free_area);
        // A comparison (`measure --compare`) recomputes the summary: the rule stays the one used.
        let mut compared = m.clone();
        compared.set_overlap(&[]);
        assert_eq!(compared.summary.contact_rule, ContactRule::InterfaceLabels);
        assert_eq!(compared.summary.contact_distance, None);
    };
    check(&tissue);
    let by_distance =
        measure_tissue(&tissue, &MeasureSettings { interface_labels: false, ..Default::default() }).unwrap();
    assert_eq!(by_distance.summary.contact_rule, ContactRule::Distance);
    assert!(
        by_distance.contacts[0].area_a > 2.0 * shared,
        "the distance rule should count tetrahedron 1's other faces here: {}",
        by_distance.contacts[0].area_a
    );
    // The labels travel through .vtp (`interface_label`), and moving a node drops them.
    let vtp = dir.path().join("mm.vtp");
    write_tissue(&vtp, &tissue, &[]).unwrap();
    let back = read_tissue(&vtp, &ReadOptions::default()).unwrap().tissue;
    for (a, b) in tissue.cells().iter().zip(back.cells()) {
        assert_eq!(a.interface_labels(), b.interface_labels(), "cell {}", a.id());
    }
    check(&back);
    let mut moved = back.clone();
    moved.cells_mut()[0].positions_mut()[0].x += 1e-3;
    assert_eq!(moved.cells()[0].interface_labels(), None);
    let m = measure_tissue(&moved, &MeasureSettings::default()).unwrap();
    assert_eq!(m.summary.contact_rule, ContactRule::Distance, "one cell without labels: the distance rule for all");
}

/// Reads `text` as a file and returns the error message, which must name the file.
fn error_of(text: &str) -> String {
    let dir = tempfile::tempdir().unwrap();
    let p = write(&dir, "broken.vtk", text);
    let e: IoError = read_tissue(&p, &ReadOptions::default()).expect_err("a malformed file must not read");
    let msg = e.to_string();
    assert!(msg.contains("broken.vtk"), "error does not name the file: {msg}");
    msg
}

#[test]
fn truncated_file_is_an_error_naming_file_and_problem() {
    let text = simucell3d_text();
    for cut in [text.len() / 10, text.len() / 3, text.find("CELL_TYPES").unwrap() + 13, text.len() - 4] {
        let msg = error_of(&text[..cut]);
        assert!(msg.contains("truncated") || msg.contains("must be") || msg.contains("without"), "cut at {cut}: {msg}");
    }
}

#[test]
fn wrong_counts_are_errors() {
    let text = simucell3d_text();
    assert!(error_of(&text.replace("CELLS 2 50", "CELLS 2 51")).contains("announces 51 integers"));
    assert!(error_of(&text.replace("CELL_TYPES 2\n42\n42", "CELL_TYPES 3\n42\n42\n42")).contains("CELL_TYPES lists 3"));
    assert!(error_of(&text.replace("CELL_DATA 2", "CELL_DATA 5")).contains("CELL_DATA has 5"));
    assert!(error_of(&text.replace("cell_id 1 2 int", "cell_id 1 3 int")).contains("has 3 tuples"));
    let msg = error_of(&text.replace("17 4 3 8 10 9", "17 5 3 8 10 9"));
    assert!(msg.contains("announces 5 faces"), "{msg}");
}

#[test]
fn point_index_out_of_range_is_an_error() {
    let msg = error_of(&simucell3d_text().replace("3 9 10 11\n", "3 9 10 12\n"));
    assert!(msg.contains("refers to point 12") && msg.contains("12 points"), "{msg}");
}

#[test]
fn nan_coordinate_is_an_error() {
    let msg = error_of(&simucell3d_text().replace("3 0 0\n", "3 nan 0\n"));
    assert!(msg.contains("non-finite") && msg.contains("point 8"), "{msg}");
    let msg = error_of(&simucell3d_text().replace("3 0 0\n", "3 abc 0\n"));
    assert!(msg.contains("`abc`"), "{msg}");
}

#[test]
fn unknown_cell_type_is_an_error() {
    let msg = error_of(&simucell3d_text().replace("CELL_TYPES 2\n42\n42", "CELL_TYPES 2\n42\n12"));
    assert!(msg.contains("VTK type 12"), "{msg}");
}

#[test]
fn other_garbage_is_an_error() {
    assert!(error_of("").contains("not a legacy VTK file"));
    assert!(error_of("hello\nworld\n").contains("not a legacy VTK file"));
    assert!(
        error_of("# vtk DataFile Version 4.2\nx\nBINARY\nDATASET UNSTRUCTURED_GRID\n").contains("binary legacy VTK")
    );
    assert!(error_of("# vtk DataFile Version 4.2\nx\nASCII\nDATASET STRUCTURED_POINTS\n").contains("not supported"));
    assert!(error_of(&simucell3d_text().replace("cell_type_id 1 2 int", "cell_type_id 1 2 string")).contains("string"));
    assert!(error_of(&simucell3d_text().replace("0 4\n", "0 -4\n")).contains("non-negative integer"));
    // A surface mesh with no labels cannot be split into cells.
    let unlabeled = multimaterial_51().replace("label1", "foo").replace("label2", "bar");
    assert!(error_of(&unlabeled).contains("cannot tell which cell"));
    // Random bytes (a TIFF header, say).
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("broken.vtk");
    std::fs::write(&p, [0x49u8, 0x49, 0x2a, 0x00, 0xff, 0xfe, 0x00, 0x10]).unwrap();
    assert!(read_tissue(&p, &ReadOptions::default()).unwrap_err().to_string().contains("broken.vtk"));
    // A missing file.
    let e = read_tissue(&dir.path().join("nope.vtk"), &ReadOptions::default()).unwrap_err().to_string();
    assert!(e.contains("nope.vtk") && e.contains("cannot open"), "{e}");
}

#[test]
fn target_volumes_in_other_units_than_the_coordinates_are_warned_about() {
    // Coordinates in µm (read with --length-unit um) but target volumes in m³: the cells would be driven
    // towards 1e-18 of their size. The reader names each cell; consistent files get no such warning.
    let dir = tempfile::tempdir().unwrap();
    let um = ReadOptions { length_scale: "um".parse().unwrap(), orient: false };
    let with_targets = |a: &str, b: &str| {
        simucell3d_text().replace("FIELD FieldData 2", "FIELD FieldData 3")
            + &format!("cell_target_volume 1 2 double\n{a} {b}\n")
    };
    let warned = |r: &tissuefit::io::ReadReport| r.warnings.iter().filter(|w| w.contains("target volume")).count();
    let p = write(&dir, "mixed.vtk", &with_targets("1e-18", "1.6667e-19"));
    let r = read_tissue(&p, &um).unwrap();
    assert_eq!(warned(&r), 2, "{:?}", r.warnings);
    assert!(r.warnings.iter().any(|w| w.starts_with("cell 7:") && w.contains("--length-unit")), "{:?}", r.warnings);
    let p = write(&dir, "consistent.vtk", &with_targets("1.1", "0.15"));
    assert_eq!(warned(&read_tissue(&p, &um).unwrap()), 0);
}
