//! Stable replay of the fuzz corpora (`fuzz/corpus/TARGET/*`, see `fuzz/README.md`) through the same
//! entry points as the cargo-fuzz targets (`tissuefit::fuzzing`): every seed and every saved crash
//! must parse or fail with an error naming the file, without a panic.

use std::path::Path;
use tissuefit::fuzzing::TARGETS;

#[test]
fn every_corpus_file_replays_without_a_panic() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz/corpus");
    let mut failures = Vec::new();
    for (name, target) in TARGETS {
        let dir = root.join(name);
        let mut files: Vec<_> = std::fs::read_dir(&dir)
            .unwrap_or_else(|e| panic!("{}: {e} (every target needs seeds)", dir.display()))
            .map(|e| e.unwrap().path())
            .filter(|p| p.is_file())
            .collect();
        files.sort();
        assert!(!files.is_empty(), "{}: no seeds", dir.display());
        for file in files {
            let bytes = std::fs::read(&file).unwrap();
            match std::panic::catch_unwind(|| target(&bytes)) {
                Ok(Ok(())) => {}
                Ok(Err(problem)) => failures.push(format!("{name}: {}: {problem}", file.display())),
                Err(_) => failures.push(format!("{name}: {}: panicked", file.display())),
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// The seeds are valid files: each parses (the crafted ones aside, which must be refused or read
/// without harm), so a mutation starts from a file the parser accepts.
#[test]
fn the_plain_seeds_parse() {
    use tissuefit::imaging::{LabelReadOptions, read_label_tiff};
    use tissuefit::io::{ReadOptions, read_tissue};
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz/corpus");
    for name in ["doublet_u8.tif", "sphere_lzw.tif", "aggregate_deflate_bigtiff.tif", "cube_u32.tif"] {
        let path = root.join("label_tiff").join(name);
        read_label_tiff(&path, &LabelReadOptions::default()).unwrap_or_else(|e| panic!("{e}"));
    }
    for path in ["vtk/sphere_simucell3d.vtk", "vtk/multimaterial_5_1.vtk", "vtk/tetra_polyhedron.vtk", "vtp/sphere.vtp"]
    {
        read_tissue(&root.join(path), &ReadOptions::default()).unwrap_or_else(|e| panic!("{e}"));
    }
    let params = std::fs::read_to_string(root.join("params/defaults.toml")).unwrap();
    tissuefit::mechanics::Parameters::from_toml_str(&params, "defaults.toml").unwrap();
    // The checkpoint seeds: a whole file, and its payload (which the target frames itself). A change of
    // the checkpoint format refuses them: make them again with `tissuefit generate mesh --kind sphere
    // --cell-size 8um --min-edge-length 2um --out s.vtp; tissuefit simulate s.vtp --out run --max-steps
    // 20 --stop-at-step 3`, then run/checkpoint.bin and its bytes after the 28-byte header.
    let file = std::fs::read(root.join("checkpoint/sphere_42_nodes.ckpt")).unwrap();
    let payload = std::fs::read(root.join("checkpoint/sphere_42_nodes.payload")).unwrap();
    assert_eq!(tissuefit::io::frame_checkpoint(&payload), file, "the payload seed is the file's payload");
    let (info, state) = tissuefit::io::decode_checkpoint(&file, Path::new("sphere_42_nodes.ckpt"))
        .unwrap_or_else(|e| panic!("{e}: make the checkpoint seeds again (see above)"));
    let params = tissuefit::mechanics::Parameters::from_toml_str(&info.parameters, "saved").unwrap();
    tissuefit::mechanics::Simulation::restore(state, &params).unwrap();
    let pipeline = std::fs::read_to_string(root.join("pipeline/demo.toml")).unwrap();
    tissuefit::pipeline::PipelineConfig::from_toml_str(&pipeline, Path::new("demo.toml")).unwrap();
}
