//! The measure tables and summaries in an output length unit ([`OutputUnit`]): every quantity with a
//! length dimension scaled from SI (lengths × 1e6, areas × 1e12, volumes × 1e18 for µm) and its column
//! or key renamed with the unit (`volume` → `volume_um3`, `area` → `area_um2`, `centroid_x` →
//! `centroid_x_um`), so that a number and its name never disagree: a table read with the SI names
//! fails loudly instead of mixing units. In SI nothing changes (the names are the stable ones).
//!
//! The tables below are the one list of dimensioned columns; [`cells_in`] and [`contacts_in`] scale
//! the same fields (a unit test checks that they agree).

use crate::geometry::Real;
use crate::io::OutputUnit;
use crate::morphology::{CellMorphology, ContactMorphology};
use serde_json::{Map, Value};

/// The columns of `cells.csv` with a length dimension, and its power (1 length, 2 area, 3 volume).
pub const CELL_LENGTH_COLUMNS: [(&str, i32); 17] = [
    ("volume", 3),
    ("area", 2),
    ("contact_area", 2),
    ("lumen_contact_area", 2),
    ("ecm_contact_area", 2),
    ("free_area", 2),
    ("apical_area", 2),
    ("lateral_area", 2),
    ("basal_area", 2),
    ("semi_axis_1", 1),
    ("semi_axis_2", 1),
    ("semi_axis_3", 1),
    ("centroid_x", 1),
    ("centroid_y", 1),
    ("centroid_z", 1),
    ("nucleus_volume", 3),
    ("nucleus_offset", 1),
];

/// The columns of `contacts.csv` with a length dimension.
pub const CONTACT_LENGTH_COLUMNS: [(&str, i32); 3] = [("area", 2), ("area_a", 2), ("area_b", 2)];

/// The keys of a morphology summary (`summary.json`, `morphology.json`) with a length dimension at
/// its top level, and those of its `statistics` (whose every value but `count` scales).
pub const SUMMARY_LENGTH_KEYS: [(&str, i32); 2] = [("contact_distance", 1), ("normal_smoothing", 1)];
pub const STATISTICS_LENGTH_KEYS: [(&str, i32); 4] =
    [("volume", 3), ("area", 2), ("contact_area", 2), ("nucleus_offset", 1)];

/// The power of `name` in `table`, if it has a length dimension.
fn power(table: &[(&str, i32)], name: &str) -> Option<i32> {
    table.iter().find(|(n, _)| *n == name).map(|(_, p)| *p)
}

/// The header name of column `name` of a table whose dimensioned columns are `table`.
pub fn column_name(table: &[(&str, i32)], unit: OutputUnit, name: &str) -> String {
    match power(table, name) {
        Some(p) => unit.column(name, p),
        None => name.to_string(),
    }
}

/// `cells.csv` rows in `unit`.
pub fn cells_in(rows: &[CellMorphology], unit: OutputUnit) -> Vec<CellMorphology> {
    let (l, a, v) = (unit.factor(1), unit.factor(2), unit.factor(3));
    let opt = |x: Option<Real>, f: Real| x.map(|x| x * f);
    rows.iter()
        .map(|c| CellMorphology {
            volume: c.volume * v,
            area: c.area * a,
            contact_area: c.contact_area * a,
            lumen_contact_area: c.lumen_contact_area * a,
            ecm_contact_area: c.ecm_contact_area * a,
            free_area: c.free_area * a,
            apical_area: opt(c.apical_area, a),
            lateral_area: opt(c.lateral_area, a),
            basal_area: opt(c.basal_area, a),
            semi_axis_1: c.semi_axis_1 * l,
            semi_axis_2: c.semi_axis_2 * l,
            semi_axis_3: c.semi_axis_3 * l,
            centroid_x: c.centroid_x * l,
            centroid_y: c.centroid_y * l,
            centroid_z: c.centroid_z * l,
            nucleus_volume: opt(c.nucleus_volume, v),
            nucleus_offset: opt(c.nucleus_offset, l),
            ..c.clone()
        })
        .collect()
}

/// `contacts.csv` rows in `unit`.
pub fn contacts_in(rows: &[ContactMorphology], unit: OutputUnit) -> Vec<ContactMorphology> {
    let a = unit.factor(2);
    rows.iter()
        .map(|c| ContactMorphology { area: c.area * a, area_a: c.area_a * a, area_b: c.area_b * a, ..c.clone() })
        .collect()
}

/// A serialised morphology summary (a JSON object) in `unit`: `length_unit` first, then the keys in
/// their order, the dimensioned ones scaled and renamed. In SI the value is returned unchanged.
pub fn summary_in(value: Value, unit: OutputUnit) -> Value {
    let Value::Object(map) = value else { return value };
    if unit.is_si() {
        return Value::Object(map);
    }
    let scale = |v: Value, f: Real| match v {
        Value::Number(n) => {
            n.as_f64().and_then(|x| serde_json::Number::from_f64(x * f)).map_or(Value::Null, Value::Number)
        }
        other => other,
    };
    let mut out = Map::new();
    out.insert("length_unit".into(), Value::String(unit.name().into()));
    for (key, v) in map {
        if let Some(p) = power(&SUMMARY_LENGTH_KEYS, &key) {
            out.insert(unit.column(&key, p), scale(v, unit.factor(p)));
        } else if key == "statistics"
            && let Value::Object(stats) = v
        {
            let stats = stats
                .into_iter()
                .map(|(name, d)| match (power(&STATISTICS_LENGTH_KEYS, &name), d) {
                    (Some(p), Value::Object(d)) => {
                        let d = d
                            .into_iter()
                            .map(|(k, x)| if k == "count" { (k, x) } else { (k, scale(x, unit.factor(p))) })
                            .collect();
                        (unit.column(&name, p), Value::Object(d))
                    }
                    (_, d) => (name, d),
                })
                .collect();
            out.insert(key, Value::Object(stats));
        } else {
            out.insert(key, v);
        }
    }
    Value::Object(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::CellKind;

    /// Every real field set to 1: scaled by µm, exactly the fields the table names change.
    #[test]
    fn the_tables_name_exactly_the_fields_that_scale() {
        let mut c = CellMorphology::example();
        c.volume = 1.0;
        c.area = 1.0;
        c.contact_area = 1.0;
        c.lumen_contact_area = 1.0;
        c.ecm_contact_area = 1.0;
        c.free_area = 1.0;
        c.apical_area = Some(1.0);
        c.lateral_area = Some(1.0);
        c.basal_area = Some(1.0);
        c.semi_axis_1 = 1.0;
        c.semi_axis_2 = 1.0;
        c.semi_axis_3 = 1.0;
        c.centroid_x = 1.0;
        c.centroid_y = 1.0;
        c.centroid_z = 1.0;
        c.nucleus_volume = Some(1.0);
        c.nucleus_offset = Some(1.0);
        c.sphericity = 1.0;
        c.contact_fraction = 1.0;
        c.elongation = 1.0;
        c.nucleus_sphericity = Some(1.0);
        c.iou = Some(1.0);
        c.chi = Some(1.0);
        let before = serde_json::to_value(&c).unwrap();
        let after = serde_json::to_value(&cells_in(std::slice::from_ref(&c), OutputUnit::Micrometre)[0]).unwrap();
        for (name, b) in before.as_object().unwrap() {
            let a = &after[name];
            match power(&CELL_LENGTH_COLUMNS, name) {
                Some(p) => assert_eq!(a.as_f64(), b.as_f64().map(|x| x * OutputUnit::Micrometre.factor(p)), "{name}"),
                None => assert_eq!(a, b, "{name} changed but is not in CELL_LENGTH_COLUMNS"),
            }
        }
        assert!(CELL_LENGTH_COLUMNS.iter().all(|(n, _)| before.get(*n).is_some()));

        let contact = ContactMorphology {
            cell_a: 1,
            cell_b: 2,
            area: 1.0,
            contact_angle_deg: Some(1.0),
            kind_a: CellKind::Epithelial,
            kind_b: CellKind::Epithelial,
            area_a: 1.0,
            area_b: 1.0,
            rim_edges: 1,
            far_field_angle_deg: Some(1.0),
        };
        let before = serde_json::to_value(&contact).unwrap();
        let after = serde_json::to_value(&contacts_in(&[contact], OutputUnit::Micrometre)[0]).unwrap();
        for (name, b) in before.as_object().unwrap() {
            let changed = &after[name] != b;
            assert_eq!(changed, power(&CONTACT_LENGTH_COLUMNS, name).is_some(), "{name}");
        }
    }

    #[test]
    fn summaries_carry_the_unit_and_rename_dimensioned_keys() {
        let json = serde_json::json!({
            "cells": 2, "contact_distance": 1e-7,
            "statistics": {"volume": {"count": 2, "mean": 2e-16}, "sphericity": {"count": 2, "mean": 0.9}}
        });
        assert_eq!(summary_in(json.clone(), OutputUnit::Metre), json);
        let um = summary_in(json, OutputUnit::Micrometre);
        let keys: Vec<&String> = um.as_object().unwrap().keys().collect();
        assert_eq!(keys, ["length_unit", "cells", "contact_distance_um", "statistics"]);
        assert_eq!(um["length_unit"], "um");
        assert!((um["contact_distance_um"].as_f64().unwrap() - 0.1).abs() < 1e-15);
        assert_eq!(um["statistics"]["volume_um3"]["count"], 2);
        assert!((um["statistics"]["volume_um3"]["mean"].as_f64().unwrap() - 200.0).abs() < 1e-12);
        assert_eq!(um["statistics"]["sphericity"]["mean"], 0.9);
        assert_eq!(column_name(&CELL_LENGTH_COLUMNS, OutputUnit::Micrometre, "volume"), "volume_um3");
        assert_eq!(column_name(&CELL_LENGTH_COLUMNS, OutputUnit::Micrometre, "sphericity"), "sphericity");
    }
}
