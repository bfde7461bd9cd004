//! Writing per-label results back into an OME-Zarr label image: the NGFF `image-label` metadata's
//! `properties` list (NGFF 0.4 `.zattrs`, NGFF 0.5 `zarr.json` `attributes.ome`), one object per
//! label, `{"label-value": 3, "volume_um3": 812.5, …}`. napari-ome-zarr turns that list into the
//! Labels layer's features (shown when hovering a cell) and ome-zarr-py reads it. We write into the
//! attributes rather than a sidecar table because they are the standard place those readers look,
//! NGFF has no accepted tables specification yet, and a table of a few hundred cells is small.
//!
//! Merge rule (a re-run replaces, never duplicates): an existing entry whose `label-value` is a
//! written label keeps its other keys (a class name set by hand, say) and gets our keys (those
//! listed by the caller as ours, written or not) replaced; entries of labels we did not write stay
//! as they are; labels without an entry get one, appended in the caller's order. Every other key
//! of the file (multiscales, `image-label.colors`, `source`, `version`, anything foreign) is kept,
//! in its order. A group that has no `image-label` yet gets one (with the NGFF `version` of its
//! multiscales in a v2 store, where NGFF 0.4 puts it). Provenance goes into a sibling `tissuefit`
//! object of the attributes (v2: top level of `.zattrs`; v3: `attributes.tissuefit`, beside `ome`,
//! which is NGFF's namespace), replaced on each write.
//!
//! The file is rewritten pretty-printed (two-space indents, key order kept) through a temporary
//! beside it and a rename ([`write_atomically`]): a reader sees the old file or the new one. A
//! metadata file or group folder without write permission bits is refused by
//! [`properties_target`] before anything is measured, even for a user whose privileges would
//! override the bits: marking a store read-only is taken as the owner's wish.
//!
//! [`metadata_for_hash`] is what a pipeline's input hash covers of such a file: the properties and
//! the provenance are results written back, not input, and leave the hash unchanged.

use super::ImagingError;
use super::zarr_read::label_image_group;
use crate::files::write_atomically;
use serde_json::{Map, Value};
use std::borrow::Cow;
use std::path::{Path, PathBuf};

/// The key of an entry naming its label (NGFF `image-label.properties`).
pub const LABEL_VALUE_KEY: &str = "label-value";

/// The attributes key of the provenance object.
pub const PROVENANCE_KEY: &str = "tissuefit";

/// One label's entry: its label value and the values to set.
#[derive(Clone, Debug, PartialEq)]
pub struct LabelProperties {
    pub label: u32,
    /// Keys and values in the order they are written (a new entry: `label-value` first, then these).
    pub values: Map<String, Value>,
}

/// The metadata file a label image's properties go into, checked to be writable.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PropertiesTarget {
    /// `.zattrs` (Zarr v2) or `zarr.json` (Zarr v3) of the label image group.
    pub file: PathBuf,
    zarr_version: u8,
}

/// The label image `store` names (a `labels` group listing one image is followed, as the reader
/// does) and its metadata file, refused when the file or its folder has no write permission bit.
pub fn properties_target(store: &Path) -> Result<PropertiesTarget, ImagingError> {
    let (root, group) = label_image_group(store, &mut Vec::new())?;
    let file = root.join(if group.zarr_version == 2 { ".zattrs" } else { "zarr.json" });
    let meta = std::fs::metadata(&file).map_err(|source| ImagingError::Open { path: file.clone(), source })?;
    if meta.permissions().readonly() {
        return Err(ImagingError::Write {
            path: file,
            message: "the file is read-only (no write permission); make it writable (chmod u+w) to have the cells \
                      written into its image-label properties"
                .into(),
        });
    }
    match std::fs::metadata(&root) {
        Ok(m) if m.permissions().readonly() => {
            return Err(ImagingError::Write {
                path: file,
                message: format!(
                    "its folder {} is read-only (no write permission), and the file is replaced through a temporary \
                     beside it; make the folder writable (chmod u+w)",
                    root.display()
                ),
            });
        }
        Ok(_) => {}
        Err(source) => return Err(ImagingError::Open { path: root, source }),
    }
    Ok(PropertiesTarget { file, zarr_version: group.zarr_version })
}

/// Merges `rows` into the target's `image-label.properties` (see the module documentation for the
/// rule; `ours` lists every key we own in an entry) and sets the `tissuefit` provenance object.
pub fn write_label_properties(
    target: &PropertiesTarget,
    rows: &[LabelProperties],
    ours: &[String],
    provenance: Value,
) -> Result<(), ImagingError> {
    let file = &target.file;
    let bytes = std::fs::read(file).map_err(|source| ImagingError::Open { path: file.clone(), source })?;
    let mut doc: Value = serde_json::from_slice(&bytes)
        .map_err(|e| ImagingError::Zarr { path: file.clone(), message: format!("not valid JSON: {e}") })?;
    merge_properties(&mut doc, target.zarr_version, rows, ours, provenance)
        .map_err(|message| ImagingError::Zarr { path: file.clone(), message })?;
    let mut text = serde_json::to_vec_pretty(&doc)
        .map_err(|e| ImagingError::Write { path: file.clone(), message: e.to_string() })?;
    if bytes.ends_with(b"\n") {
        text.push(b'\n');
    }
    write_atomically(file, |w| std::io::Write::write_all(w, &text))
        .map_err(|e| ImagingError::Write { path: file.clone(), message: e.to_string() })
}

/// The object holding the OME metadata in `doc` (v2: the whole `.zattrs`; v3: `attributes.ome`, or
/// `attributes` for a store without the `ome` key, as the reader takes it), and the one that gets
/// the provenance (v2: the whole `.zattrs`; v3: `attributes`).
fn merge_properties(
    doc: &mut Value,
    zarr_version: u8,
    rows: &[LabelProperties],
    ours: &[String],
    provenance: Value,
) -> Result<(), String> {
    let (where_, attributes) = if zarr_version == 2 {
        (".zattrs", doc.as_object_mut().ok_or(".zattrs is not a JSON object")?)
    } else {
        let root = doc.as_object_mut().ok_or("zarr.json is not a JSON object")?;
        let attributes = root.entry("attributes").or_insert_with(|| Value::Object(Map::new()));
        ("zarr.json attributes", attributes.as_object_mut().ok_or("zarr.json: `attributes` is not an object")?)
    };
    let ngff_version = if zarr_version == 2 {
        attributes
            .get("multiscales")
            .and_then(|m| m.get(0))
            .and_then(|m| m.get("version"))
            .and_then(Value::as_str)
            .map(str::to_string)
    } else {
        None
    };
    {
        let ome = if zarr_version == 3 && attributes.contains_key("ome") {
            attributes
                .get_mut("ome")
                .and_then(Value::as_object_mut)
                .ok_or("zarr.json: `attributes.ome` is not an object")?
        } else {
            &mut *attributes
        };
        let label = ome.entry("image-label").or_insert_with(|| {
            let mut m = Map::new();
            if let Some(v) = ngff_version {
                m.insert("version".into(), Value::String(v));
            }
            Value::Object(m)
        });
        let label = label.as_object_mut().ok_or(format!("{where_}: `image-label` is not an object"))?;
        let list = label.entry("properties").or_insert_with(|| Value::Array(Vec::new()));
        let list = list.as_array_mut().ok_or(format!("{where_}: `image-label.properties` is not a list"))?;
        merge_entries(list, rows, ours);
    }
    attributes.insert(PROVENANCE_KEY.into(), provenance);
    Ok(())
}

/// The merge rule of the module documentation on one `properties` list.
fn merge_entries(list: &mut Vec<Value>, rows: &[LabelProperties], ours: &[String]) {
    let mut found = vec![false; rows.len()];
    for entry in list.iter_mut() {
        let Some(map) = entry.as_object_mut() else { continue };
        let Some(label) = map.get(LABEL_VALUE_KEY).and_then(Value::as_u64) else { continue };
        let Some(i) = rows.iter().position(|r| u64::from(r.label) == label) else { continue };
        found[i] = true;
        map.retain(|k, _| !ours.contains(k));
        for (k, v) in &rows[i].values {
            map.insert(k.clone(), v.clone());
        }
    }
    for (row, _) in rows.iter().zip(&found).filter(|(_, f)| !**f) {
        let mut map = Map::new();
        map.insert(LABEL_VALUE_KEY.into(), Value::from(row.label));
        map.extend(row.values.clone());
        list.push(Value::Object(map));
    }
}

/// What a pipeline's input hash covers of the file `name` of a store: a Zarr metadata file
/// (`.zattrs`, `zarr.json`) that is JSON is hashed in a canonical form without the
/// `image-label.properties` lists and the `tissuefit` provenance (results written back, which must
/// not make the pipeline re-run its stages); any other file, or one that is not JSON, as it is.
pub fn metadata_for_hash<'a>(name: &str, bytes: &'a [u8]) -> Cow<'a, [u8]> {
    let file = name.rsplit('/').next().unwrap_or(name);
    if file != ".zattrs" && file != "zarr.json" {
        return Cow::Borrowed(bytes);
    }
    let Ok(mut doc) = serde_json::from_slice::<Value>(bytes) else { return Cow::Borrowed(bytes) };
    fn strip_attributes(a: &mut Map<String, Value>) {
        a.remove(PROVENANCE_KEY);
        if let Some(l) = a.get_mut("image-label").and_then(Value::as_object_mut) {
            l.remove("properties");
        }
        if let Some(ome) = a.get_mut("ome").and_then(Value::as_object_mut)
            && let Some(l) = ome.get_mut("image-label").and_then(Value::as_object_mut)
        {
            l.remove("properties");
        }
    }
    if let Some(root) = doc.as_object_mut() {
        strip_attributes(root);
        if let Some(a) = root.get_mut("attributes").and_then(Value::as_object_mut) {
            strip_attributes(a);
        }
    }
    serde_json::to_vec(&doc).map_or(Cow::Borrowed(bytes), Cow::Owned)
}

/// Now as an RFC 3339 UTC time to the second (`2026-11-30T04:41:07Z`).
pub fn utc_now() -> String {
    let secs = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_secs());
    utc_time(secs)
}

/// Seconds since 1970 as an RFC 3339 UTC time (the proleptic Gregorian calendar; H. Hinnant's
/// days-to-civil algorithm).
fn utc_time(secs: u64) -> String {
    let days = (secs / 86_400) as i64;
    let rem = secs % 86_400;
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!("{year:04}-{month:02}-{day:02}T{:02}:{:02}:{:02}Z", rem / 3600, rem / 60 % 60, rem % 60)
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn row(label: u32, volume: f64) -> LabelProperties {
        let Value::Object(values) = json!({"volume_um3": volume, "sphericity": 0.9}) else { unreachable!() };
        LabelProperties { label, values }
    }

    #[test]
    fn entries_of_written_labels_are_replaced_keeping_foreign_keys_and_other_labels() {
        let ours: Vec<String> = ["volume_um3", "sphericity", "nucleus_volume_um3"].map(String::from).to_vec();
        let mut doc = json!({"multiscales": [{"version": "0.4"}], "image-label": {"colors": [{"label-value": 1}],
            "properties": [{"label-value": 2, "class": "A", "nucleus_volume_um3": 3.0, "volume_um3": 1.0},
                           {"label-value": 9, "class": "B"}]}, "foreign": true});
        merge_properties(&mut doc, 2, &[row(2, 10.0), row(3, 20.0)], &ours, json!({"version": "x"})).unwrap();
        let list = doc["image-label"]["properties"].as_array().unwrap();
        assert_eq!(list.len(), 3);
        assert_eq!(list[0], json!({"label-value": 2, "class": "A", "volume_um3": 10.0, "sphericity": 0.9}));
        assert_eq!(list[1], json!({"label-value": 9, "class": "B"}));
        assert_eq!(list[2], json!({"label-value": 3, "volume_um3": 20.0, "sphericity": 0.9}));
        assert_eq!(doc["image-label"]["colors"], json!([{"label-value": 1}]));
        assert_eq!(doc["foreign"], true);
        assert_eq!(doc["tissuefit"], json!({"version": "x"}));
        let keys: Vec<&String> = doc.as_object().unwrap().keys().collect();
        assert_eq!(keys, ["multiscales", "image-label", "foreign", "tissuefit"], "order kept");
        // Again: replaced, not duplicated.
        let before = doc.clone();
        merge_properties(&mut doc, 2, &[row(2, 10.0), row(3, 20.0)], &ours, json!({"version": "x"})).unwrap();
        assert_eq!(doc, before);
    }

    #[test]
    fn a_group_without_image_label_gets_one_in_the_right_place() {
        let mut v2 = json!({"multiscales": [{"version": "0.4"}]});
        merge_properties(&mut v2, 2, &[row(1, 1.0)], &[], json!({})).unwrap();
        assert_eq!(v2["image-label"]["version"], "0.4");
        assert_eq!(v2["image-label"]["properties"][0]["label-value"], 1);
        let mut v3 = json!({"zarr_format": 3, "node_type": "group", "attributes": {"ome": {"version": "0.5"}}});
        merge_properties(&mut v3, 3, &[row(1, 1.0)], &[], json!({"v": 1})).unwrap();
        assert_eq!(
            v3["attributes"]["ome"]["image-label"],
            json!({"properties": [
            {"label-value": 1, "volume_um3": 1.0, "sphericity": 0.9}]})
        );
        assert_eq!(v3["attributes"]["tissuefit"], json!({"v": 1}));
        let mut bad = json!({"image-label": {"properties": {"1": 2}}});
        let e = merge_properties(&mut bad, 2, &[row(1, 1.0)], &[], json!({})).unwrap_err();
        assert!(e.contains("`image-label.properties` is not a list"), "{e}");
    }

    #[test]
    fn the_hash_view_leaves_out_properties_and_provenance_only() {
        let plain = br#"{"multiscales": []}"#;
        let with = br#"{"multiscales": [], "image-label": {"properties": [{"label-value": 1}]}, "tissuefit": {}}"#;
        let empty_label = br#"{"multiscales": [], "image-label": {}}"#;
        assert_eq!(metadata_for_hash(".zattrs", plain), metadata_for_hash("labels/x/.zattrs", plain));
        assert_eq!(metadata_for_hash(".zattrs", with), metadata_for_hash(".zattrs", empty_label));
        assert_ne!(metadata_for_hash(".zattrs", plain), metadata_for_hash(".zattrs", empty_label));
        let v3 = br#"{"attributes": {"ome": {"image-label": {"properties": [1]}}, "tissuefit": 1}}"#;
        let v3_bare = br#"{"attributes": {"ome": {"image-label": {}}}}"#;
        assert_eq!(metadata_for_hash("zarr.json", v3), metadata_for_hash("zarr.json", v3_bare));
        assert_eq!(metadata_for_hash("0/0.0.0", with).as_ref(), with.as_slice(), "chunks as they are");
        assert_eq!(metadata_for_hash(".zattrs", b"{oops").as_ref(), b"{oops".as_slice());
    }

    #[test]
    fn utc_times_are_civil_dates() {
        assert_eq!(utc_time(0), "1970-01-01T00:00:00Z");
        assert_eq!(utc_time(951_782_400), "2000-02-29T00:00:00Z");
        assert_eq!(utc_time(1_796_013_667), "2026-11-30T04:41:07Z");
    }
}
