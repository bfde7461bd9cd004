//! `tissuefit measure LABELS.zarr --zarr-properties`: the measured cells written back into the label
//! image's NGFF `image-label.properties`, on copies of the Python-written stores of
//! `tests/data/python_zarr` (NGFF 0.4 on Zarr v2, 0.5 on Zarr v3). The pipeline's
//! `[measure] zarr_properties` is tested in `label_readers.rs` beside the other Zarr pipeline runs.

use crate::support::cli::{repo, tissuefit};
use serde_json::{Value, json};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Output;
use tissuefit::geometry::Vec3;
use tissuefit::imaging::{LabelVolume, LabelWriteOptions, write_label_tiff};

/// A copy of the fixture store `name` under `dir`.
fn copy_store(name: &str, dir: &Path) -> PathBuf {
    fn copy(from: &Path, to: &Path) {
        std::fs::create_dir_all(to).unwrap();
        for entry in std::fs::read_dir(from).unwrap() {
            let entry = entry.unwrap();
            let target = to.join(entry.file_name());
            if entry.file_type().unwrap().is_dir() {
                copy(&entry.path(), &target);
            } else {
                std::fs::copy(entry.path(), &target).unwrap();
            }
        }
    }
    let to = dir.join(name);
    copy(&repo().join("tests/data/python_zarr").join(name), &to);
    to
}

fn read_json(path: &Path) -> Value {
    serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap()
}

/// The metadata file of a store and the object holding its OME attributes in it (a JSON pointer).
fn layout(version: u8) -> (&'static str, &'static str) {
    if version == 2 { (".zattrs", "") } else { ("zarr.json", "/attributes/ome") }
}

/// `measure STORE --out OUT --zarr-properties` (every label a cell: the fixture's are small).
fn measure(store: &Path, out: &Path) -> Output {
    tissuefit(&[
        "measure",
        store.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--min-voxels",
        "1",
        "--zarr-properties",
    ])
}

fn assert_ok(o: &Output) {
    assert!(o.status.success(), "{}\n{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr));
}

/// cells.csv as label → volume (m³).
fn csv_volumes(path: &Path) -> BTreeMap<u64, f64> {
    let mut reader = csv::Reader::from_path(path).unwrap();
    let headers = reader.headers().unwrap().clone();
    let cell = headers.iter().position(|h| h == "cell").unwrap();
    let volume = headers.iter().position(|h| h == "volume").unwrap();
    reader.records().map(|r| r.unwrap()).map(|r| (r[cell].parse().unwrap(), r[volume].parse().unwrap())).collect()
}

/// The document without what `--zarr-properties` writes (the properties list and the provenance).
fn without_ours(mut doc: Value, version: u8) -> Value {
    let (_, ome) = layout(version);
    doc.pointer_mut(&format!("{ome}/image-label")).unwrap().as_object_mut().unwrap().remove("properties");
    let attributes = if version == 2 { "" } else { "/attributes" };
    doc.pointer_mut(attributes).unwrap().as_object_mut().unwrap().remove("tissuefit");
    doc
}

/// Both fixture stores: one entry per measured cell whose `volume_um3` is cells.csv's volume in
/// µm³; an entry of a label not measured (999) and a hand-set key of a measured one (`class` of
/// label 1) kept, its stale `volume_um3` replaced; every other attribute (colors, source, foreign
/// keys, multiscales) unchanged; the provenance names the version and the settings; a second run
/// replaces the entries rather than adding to them.
#[test]
fn measured_cells_go_into_image_label_properties_of_v2_and_v3_stores() {
    for version in [2u8, 3] {
        let dir = tempfile::tempdir().unwrap();
        let store = copy_store(&format!("cells_v{version}.zarr"), dir.path());
        let (file, ome) = layout(version);
        let meta = store.join(file);
        let mut doc = read_json(&meta);
        let attrs = doc.pointer_mut(ome).unwrap().as_object_mut().unwrap();
        attrs.insert(
            "image-label".into(),
            json!({"colors": [{"label-value": 1, "rgba": [255, 0, 0, 255]}], "source": {"image": "../../"},
                   "properties": [{"label-value": 999, "class": "not in the image"},
                                  {"label-value": 1, "class": "keep me", "volume_um3": -1.0}]}),
        );
        attrs.insert("foreign-tool".into(), json!({"note": [1, 2, 3]}));
        std::fs::write(&meta, serde_json::to_vec_pretty(&doc).unwrap()).unwrap();
        let before = doc;

        let out = dir.path().join("out");
        assert_ok(&measure(&store, &out));
        let volumes = csv_volumes(&out.join("cells.csv"));
        assert_eq!(volumes.len(), 15, "the fixture's 15 labels");
        let after = read_json(&meta);
        let list = after.pointer(&format!("{ome}/image-label/properties")).unwrap().as_array().unwrap();
        assert_eq!(list.len(), volumes.len() + 1, "one entry per cell, plus label 999's: {list:?}");
        assert_eq!(list[0], json!({"label-value": 999, "class": "not in the image"}), "v{version}");
        for (label, volume) in &volumes {
            let entries: Vec<&Value> = list.iter().filter(|e| e["label-value"] == json!(label)).collect();
            assert_eq!(entries.len(), 1, "label {label}: {entries:?}");
            // The only difference is the unit conversion (× 1e18, one rounding).
            let um3 = entries[0]["volume_um3"].as_f64().unwrap();
            assert!((um3 - volume * 1e18).abs() <= 1e-12 * um3.abs(), "label {label}: {um3} vs {volume} m³");
            assert!(entries[0].get("volume").is_none() && entries[0].get("cell").is_none());
            assert!(entries[0]["sphericity"].as_f64().is_some() && entries[0]["centroid_x_um"].as_f64().is_some());
        }
        let one = list.iter().find(|e| e["label-value"] == 1).unwrap();
        assert_eq!(one["class"], "keep me");
        assert_eq!(list[1]["label-value"], 1, "an updated entry keeps its place");
        assert_eq!(without_ours(after.clone(), version), without_ours(before, version), "v{version}");
        let provenance = if version == 2 { &after["tissuefit"] } else { &after["attributes"]["tissuefit"] };
        assert_eq!(provenance["version"], env!("CARGO_PKG_VERSION"));
        assert_eq!(provenance["settings"]["measure"]["zarr_properties"], true);
        assert_eq!(provenance["settings"]["labels"]["min_voxels"], 1);
        assert_eq!(provenance["length_unit"], "um");
        assert_eq!(provenance["cells"], 15);
        assert!(provenance["written"].as_str().unwrap().ends_with('Z'), "{provenance}");
        let text = String::from_utf8(std::fs::read(&meta).unwrap()).unwrap();
        assert!(text.starts_with("{\n  \""), "pretty-printed: {}", &text[..40]);

        // Again, into another folder: the same entries, replaced, not duplicated.
        assert_ok(&measure(&store, &dir.path().join("again")));
        let again = read_json(&meta);
        assert_eq!(again.pointer(&format!("{ome}/image-label")), after.pointer(&format!("{ome}/image-label")));
        assert_eq!(without_ours(again, version), without_ours(after, version));
    }
}

/// A `labels` group listing one image is followed, as when reading: the entries go to that image,
/// and the labels group's own metadata is left alone.
#[test]
fn properties_of_a_labels_group_go_to_the_one_image_it_lists() {
    let dir = tempfile::tempdir().unwrap();
    let labels = dir.path().join("image.zarr").join("labels");
    std::fs::create_dir_all(&labels).unwrap();
    let group =
        json!({"zarr_format": 3, "node_type": "group", "attributes": {"ome": {"version": "0.5", "labels": ["cells"]}}});
    std::fs::write(labels.join("zarr.json"), serde_json::to_vec_pretty(&group).unwrap()).unwrap();
    std::fs::rename(copy_store("cells_v3.zarr", dir.path()), labels.join("cells")).unwrap();
    assert_ok(&measure(&labels, &dir.path().join("out")));
    assert_eq!(read_json(&labels.join("zarr.json")), group);
    let image = read_json(&labels.join("cells").join("zarr.json"));
    assert_eq!(image["attributes"]["ome"]["image-label"]["properties"].as_array().unwrap().len(), 15);
}

/// `--zarr-properties` on a TIFF or a tissue mesh: an error naming the flag and the file, before
/// anything is measured or written.
#[test]
fn zarr_properties_on_a_tiff_or_a_mesh_is_an_error_naming_the_flag() {
    let dir = tempfile::tempdir().unwrap();
    let volume = LabelVolume::new(ndarray::Array3::from_elem((4, 4, 4), 1u32), [1e-6; 3], Vec3::zeros()).unwrap();
    let tif = dir.path().join("cells.tif");
    write_label_tiff(&tif, &volume, &LabelWriteOptions::default()).unwrap();
    let vtp = dir.path().join("tissue.vtp");
    std::fs::write(&vtp, "<VTKFile type=\"PolyData\"></VTKFile>\n").unwrap();
    for (input, what) in [(&tif, "a TIFF file"), (&vtp, "a tissue mesh")] {
        let out = dir.path().join("out");
        let o = measure(input, &out);
        let e = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{e}");
        assert!(e.contains("--zarr-properties") && e.contains(what) && e.contains(input.to_str().unwrap()), "{e}");
        assert!(!out.exists(), "nothing written");
    }
}

/// A store whose metadata file, or whose label image folder, has no write permission: refused
/// before measuring, naming the file, so the outputs stay consistent: no `--out` folder is made
/// (no measurement without its write-back) and the store is byte for byte as it was. The check reads
/// the permission bits, so it holds for root too.
#[test]
fn a_read_only_store_is_refused_before_anything_is_written() {
    use std::os::unix::fs::PermissionsExt;
    let dir = tempfile::tempdir().unwrap();
    let store = copy_store("cells_v2.zarr", dir.path());
    let meta = store.join(".zattrs");
    let bytes = std::fs::read(&meta).unwrap();
    let set = |path: &Path, mode: u32| std::fs::set_permissions(path, std::fs::Permissions::from_mode(mode)).unwrap();
    let out = dir.path().join("out");

    set(&meta, 0o444);
    let o = measure(&store, &out);
    let e = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{e}");
    assert!(e.contains("--zarr-properties") && e.contains(meta.to_str().unwrap()) && e.contains("read-only"), "{e}");
    assert!(!out.exists());
    set(&meta, 0o644);

    set(&store, 0o555);
    let o = measure(&store, &out);
    set(&store, 0o755);
    let e = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{e}");
    assert!(e.contains(meta.to_str().unwrap()) && e.contains("folder") && e.contains("read-only"), "{e}");
    assert!(!out.exists());
    assert_eq!(std::fs::read(&meta).unwrap(), bytes, "the store is unchanged");

    // A path that is no store at all.
    let o = measure(&dir.path().join("missing.zarr"), &out);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("missing.zarr"));
    assert!(!out.exists());
}
