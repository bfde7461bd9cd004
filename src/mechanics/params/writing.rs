//! Writing a config as TOML, plain or with every field commented (the config reference). The
//! comments are the doc comments of the parameter structs, read from the JSON schema `schemars`
//! derives from them ([`ConfigDocs`]), so each field is documented once, where it is declared.

use super::reading::to_value;
use super::*;
use serde_json::Value as Json;
use std::collections::HashMap;
use std::fmt::Write as _;
use std::sync::LazyLock;
use toml::{Table, Value};

/// The `$defs` of a schema: the definitions its `$ref`s name.
type Defs = serde_json::Map<String, Json>;

// ---------------------------------------------------------------------------------------------
// Writing.

/// A float as a TOML literal that reads back exactly: exponent form for small and large magnitudes
/// (`2e-7`, `1e9`), decimal otherwise (`2500.0`, `0.001`), `inf`/`nan` as TOML spells them.
pub(super) fn fmt_real(x: Real) -> String {
    if x.is_nan() {
        "nan".to_owned()
    } else if x.is_infinite() {
        if x > 0.0 { "inf" } else { "-inf" }.to_owned()
    } else if x != 0.0 && !(1e-3..1e5).contains(&x.abs()) {
        format!("{x:e}")
    } else {
        format!("{x:?}")
    }
}

/// A float to 3 significant digits, for estimates in messages.
pub(super) fn fmt_real_short(x: Real) -> String {
    if x.is_finite() && x != 0.0 && !(1e-3..1e5).contains(&x.abs()) {
        format!("{x:.2e}")
    } else if x.is_finite() {
        format!("{x:.3}")
    } else {
        fmt_real(x)
    }
}

/// Documentation of one section or field of the config: the first paragraph of the doc comment of
/// its field, which by convention ends with `Unit: <unit>.` for a quantity with a unit
/// (`Unit: dimensionless.` for a pure number that is still a physical quantity). Later paragraphs
/// are for the code's readers (defaults as the code sets them, links) and stay out of the reference.
pub(super) struct FieldDoc {
    /// The first paragraph without the unit sentence, on one line.
    pub(super) text: String,
    /// As written after `Unit:`, e.g. `m`, `N/m`, `dimensionless`; empty when the doc states none.
    pub(super) unit: String,
}

impl FieldDoc {
    fn from_description(description: &str) -> Self {
        let first = description.split("\n\n").next().unwrap_or_default();
        let text = first.split_whitespace().collect::<Vec<_>>().join(" ");
        match text.rsplit_once(" Unit: ") {
            Some((text, unit)) if unit.ends_with('.') && !unit.contains(' ') => {
                Self { text: text.to_owned(), unit: unit.trim_end_matches('.').to_owned() }
            }
            _ => Self { text, unit: String::new() },
        }
    }
}

/// The documentation of every section and field of a parameter file, read from the JSON schema
/// that `schemars` derives from the parameter structs and their doc comments: the doc comments are
/// the one source of the commented config reference.
pub(super) struct ConfigDocs {
    /// By path without list indices, e.g. `cell_types.faces.apical.adhesion`.
    pub(super) fields: HashMap<String, FieldDoc>,
    /// The keys of each table in struct order, by the table's path (`""` for the top level).
    order: HashMap<String, Vec<String>>,
}

/// The documentation of [`Parameters`], built once.
pub(super) fn config_docs() -> &'static ConfigDocs {
    static DOCS: LazyLock<ConfigDocs> = LazyLock::new(|| {
        let schema = serde_json::to_value(schemars::schema_for!(Parameters)).expect("a schema is JSON");
        let defs = schema.get("$defs").and_then(Json::as_object).cloned().unwrap_or_default();
        let mut docs = ConfigDocs { fields: HashMap::new(), order: HashMap::new() };
        collect_docs(&schema, "", &defs, &mut docs);
        docs
    });
    &DOCS
}

/// The schema a `$ref` points to (the schema itself when it is none).
fn resolve_ref<'a>(schema: &'a Json, defs: &'a Defs) -> &'a Json {
    match schema.get("$ref").and_then(Json::as_str) {
        Some(r) => defs.get(r.rsplit('/').next().unwrap_or(r)).map_or(schema, |def| resolve_ref(def, defs)),
        None => schema,
    }
}

/// Records the doc of every property of the table `schema` at `path`, in declaration order (the
/// schema's property order: `schemars` keeps it with its `preserve_order` feature), and descends
/// into sub-tables and lists of tables. A field's doc is its own doc comment only, never its type's.
fn collect_docs(schema: &Json, path: &str, defs: &Defs, docs: &mut ConfigDocs) {
    let table = resolve_ref(schema, defs);
    let Some(properties) = table.get("properties").and_then(Json::as_object) else { return };
    let mut keys = Vec::with_capacity(properties.len());
    for (key, property) in properties {
        let full = join_path(path, key);
        let description = property.get("description").and_then(Json::as_str).unwrap_or_default();
        docs.fields.insert(full.clone(), FieldDoc::from_description(description));
        keys.push(key.clone());
        let inner = resolve_ref(property, defs);
        collect_docs(inner.get("items").unwrap_or(inner), &full, defs, docs);
    }
    docs.order.insert(path.to_owned(), keys);
}

const HEADER: &str = "\
tissuefit simulation parameters. SI units; every value below is the default.

A config file may be partial:
- a missing [numerics] field takes its default (damping: 3e-9 kg/s if dynamics = \"overdamped\");
- a given list of [[cell_types]] replaces the default list; a cell's cell_type (SimuCell3D's
  cell_type_id) indexes it, in file order;
- a missing field of a [[cell_types]] entry, including single fields of its
  [cell_types.faces.apical|lateral|basal] tables, takes the default of the entry's kind
  (epithelial if kind is omitted). The five entries below are the defaults of the five kinds.
Unknown keys are errors. inf is allowed for max_pressure and division_volume.";

/// The doc entry of a path like `cell_types.faces.apical.adhesion` (indices already stripped).
fn field_doc(path: &str) -> Option<&'static FieldDoc> {
    config_docs().fields.get(path).filter(|doc| !doc.text.is_empty())
}

/// The unit of a path with list indices (`cell_types[0].bulk_modulus`), for messages; empty for
/// none and for dimensionless quantities.
pub(super) fn unit_of(path: &str) -> &'static str {
    let mut plain = String::with_capacity(path.len());
    let mut in_index = false;
    for c in path.chars() {
        match c {
            '[' => in_index = true,
            ']' => in_index = false,
            c if !in_index => plain.push(c),
            _ => {}
        }
    }
    field_doc(&plain).map_or("", |doc| match doc.unit.as_str() {
        "dimensionless" => "",
        unit => unit,
    })
}

fn join_path(parent: &str, key: &str) -> String {
    if parent.is_empty() { key.to_owned() } else { format!("{parent}.{key}") }
}

/// Keys of a table in declaration order; keys the structs do not declare (none) last.
fn ordered_keys<'a>(table: &'a Table, doc_path: &str) -> Vec<&'a str> {
    let declared = config_docs().order.get(doc_path).map_or(&[][..], Vec::as_slice);
    let mut keys: Vec<&str> =
        declared.iter().filter_map(|key| table.get_key_value(key)).map(|(k, _)| k.as_str()).collect();
    keys.extend(table.keys().map(String::as_str).filter(|key| !keys.contains(key)).collect::<Vec<_>>());
    keys
}

pub(super) fn is_section(value: &Value) -> bool {
    match value {
        Value::Table(_) => true,
        Value::Array(items) => !items.is_empty() && items.iter().all(Value::is_table),
        _ => false,
    }
}

fn format_value(value: &Value) -> String {
    match value {
        Value::Float(x) => fmt_real(*x),
        Value::Array(items) => format!("[{}]", items.iter().map(format_value).collect::<Vec<_>>().join(", ")),
        other => other.to_string(),
    }
}

/// Writes `# ` comment lines, wrapped at about 100 columns.
fn write_comment(out: &mut String, text: &str) {
    for paragraph in text.lines() {
        let mut line = String::from("#");
        for word in paragraph.split_whitespace() {
            if line.len() > 1 && line.chars().count() + 1 + word.chars().count() > 100 {
                out.push_str(&line);
                out.push('\n');
                line = String::from("#");
            }
            line.push(' ');
            line.push_str(word);
        }
        out.push_str(&line);
        out.push('\n');
    }
}

pub(super) fn write_toml(params: &Parameters, comments: bool) -> String {
    let Value::Table(root) = to_value(params) else { unreachable!("a struct serialises to a table") };
    let mut out = String::new();
    if comments {
        write_comment(&mut out, HEADER);
    }
    write_table(&mut out, &root, "", "", None, comments);
    if comments && params.cell_overrides.is_empty() {
        write_override_example(&mut out);
    }
    out.trim_start().to_owned()
}

/// The `[[cell_overrides]]` section, which has no default entries, as a commented-out example.
fn write_override_example(out: &mut String) {
    let doc = |path: &str| field_doc(path).map_or("(undocumented)", |doc| doc.text.as_str());
    out.push('\n');
    write_comment(out, doc("cell_overrides"));
    write_comment(out, "Example (remove the leading `# ` to use it):");
    let _ = writeln!(out, "# [[cell_overrides]]");
    let _ = writeln!(out, "# id = 3  # {}", doc("cell_overrides.id"));
    let _ = writeln!(out, "# surface_tension = {{ apical = 1.2e-3, lateral = 4e-4 }}  # N/m");
    let _ = writeln!(out, "# adhesion = {{ basal = 0.0 }}  # Pa/m");
}

/// Writes a table's plain fields, then its sub-tables and arrays of tables.
/// `doc_path` is the path without indices, `header` the TOML section name, `kind` the kind of the
/// enclosing cell type (for "default for kind" comments).
fn write_table(out: &mut String, table: &Table, doc_path: &str, header: &str, kind: Option<&str>, comments: bool) {
    let keys = ordered_keys(table, doc_path);
    for &key in &keys {
        let value = &table[key];
        if is_section(value) {
            continue;
        }
        let path = join_path(doc_path, key);
        let formatted = format_value(value);
        if comments {
            let doc = field_doc(&path);
            let unit = match doc.map_or("", |doc| doc.unit.as_str()) {
                "" => String::new(),
                unit => format!(" [{unit}]"),
            };
            let default = match kind {
                Some(kind) => format!("Default for kind {kind}: {formatted}."),
                None => format!("Default: {formatted}."),
            };
            write_comment(out, &format!("{}{unit} {default}", doc.map_or("(undocumented)", |doc| doc.text.as_str())));
        }
        let _ = writeln!(out, "{key} = {formatted}");
    }
    for &key in &keys {
        let path = join_path(doc_path, key);
        let section = join_path(header, key);
        let section_doc = field_doc(&path).map_or("(undocumented)", |doc| doc.text.as_str());
        match &table[key] {
            Value::Table(sub) => {
                out.push('\n');
                if comments {
                    write_comment(out, section_doc);
                }
                let _ = writeln!(out, "[{section}]");
                write_table(out, sub, &path, &section, kind, comments);
            }
            Value::Array(items) if is_section(&table[key]) => {
                for (index, item) in items.iter().enumerate() {
                    let Value::Table(item) = item else { continue };
                    let item_kind = item.get("kind").and_then(Value::as_str);
                    out.push('\n');
                    if comments {
                        if index == 0 {
                            write_comment(out, section_doc);
                        }
                        if key == "cell_types" {
                            let kind_note = item_kind.map(|kind| format!(", kind {kind}")).unwrap_or_default();
                            write_comment(
                                out,
                                &format!("{key}[{index}]{kind_note}: used by cells with cell_type = {index}."),
                            );
                        }
                    }
                    let _ = writeln!(out, "[[{section}]]");
                    write_table(out, item, &path, &section, item_kind, comments);
                }
            }
            _ => {}
        }
    }
}
