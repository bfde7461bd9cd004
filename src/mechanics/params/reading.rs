//! Reading a config: overlay the user's TOML tables on the defaults of each kind, then deserialise.

use super::writing::fmt_real;
use super::*;
use serde::de::DeserializeOwned;
use toml::{Table, Value};

// ---------------------------------------------------------------------------------------------
// Reading: overlay the user's tables on the defaults of each kind, then deserialise.

/// Serialises a parameter struct to a TOML value. The structs hold only numbers, strings and
/// tables, so this cannot fail.
pub(super) fn to_value<T: Serialize>(value: &T) -> Value {
    Value::try_from(value).expect("parameter structs serialise to TOML")
}

/// Merges a user's file into the defaults and deserialises; Err holds every schema problem found.
pub(super) fn resolve(mut user: Table) -> Result<Parameters, Vec<String>> {
    let mut problems = Vec::new();

    let user_numerics = user.remove("numerics");
    let dynamics = user_numerics
        .as_ref()
        .and_then(|numerics| numerics.get("dynamics"))
        .and_then(|value| parse_choice(value, &Dynamics::ALL, "numerics.dynamics", &mut problems))
        .unwrap_or_default();
    let mut numerics = to_value(&Numerics::default_for(dynamics));
    if let Some(user_numerics) = user_numerics {
        if let Some(value) = user_numerics.get("contact_model") {
            parse_choice(value, &ContactModel::ALL, "numerics.contact_model", &mut problems);
        }
        if let Some(value) = user_numerics.get("contact_quadrature") {
            parse_choice(value, &ContactQuadrature::ALL, "numerics.contact_quadrature", &mut problems);
        }
        if let Some(value) = user_numerics.get("polarity") {
            parse_choice(value, &Polarity::ALL, "numerics.polarity", &mut problems);
        }
        overlay(&mut numerics, user_numerics, "numerics", &mut problems);
    }

    let cell_types = match user.remove("cell_types") {
        None => to_value(&Parameters::default().cell_types),
        Some(Value::Array(entries)) => Value::Array(
            entries
                .into_iter()
                .enumerate()
                .map(|(index, entry)| resolve_cell_type(index, entry, &mut problems))
                .collect(),
        ),
        Some(other) => {
            problems.push(format!(
                "cell_types = {}: expected an array of tables (write each entry as a [[cell_types]] section)",
                show(&other)
            ));
            Value::Array(Vec::new())
        }
    };

    let mut simulation = to_value(&SimulationSettings::default());
    if let Some(user_simulation) = user.remove("simulation") {
        if let Some(value) = user_simulation.get("mode") {
            parse_choice(value, &SimulationMode::ALL, "simulation.mode", &mut problems);
        }
        if let Some(value) = user_simulation.get("method") {
            parse_choice(value, &RelaxMethod::ALL, "simulation.method", &mut problems);
        }
        overlay(&mut simulation, user_simulation, "simulation", &mut problems);
    }

    let cell_overrides = match user.remove("cell_overrides") {
        None => None,
        Some(Value::Array(entries)) => {
            for (index, entry) in entries.iter().enumerate() {
                if let Err(error) = entry.clone().try_into::<CellOverrideConfig>() {
                    let error = error.to_string().replace('\n', " ");
                    problems.push(format!("cell_overrides[{index}]: {}", error.trim()));
                }
            }
            Some(Value::Array(entries))
        }
        Some(other) => {
            problems.push(format!(
                "cell_overrides = {}: expected an array of tables (write each entry as a [[cell_overrides]] section)",
                show(&other)
            ));
            None
        }
    };

    for key in user.keys() {
        problems.push(unknown_field(
            key,
            "at the top level",
            ["cell_types", "numerics", "simulation", "cell_overrides"].iter().copied(),
        ));
    }
    if !problems.is_empty() {
        return Err(problems);
    }
    let mut merged = Table::new();
    merged.insert("numerics".to_owned(), numerics);
    merged.insert("cell_types".to_owned(), cell_types);
    merged.insert("simulation".to_owned(), simulation);
    if let Some(cell_overrides) = cell_overrides {
        merged.insert("cell_overrides".to_owned(), cell_overrides);
    }
    // Every schema problem was caught above; this is the backstop (deny_unknown_fields included).
    Value::Table(merged).try_into().map_err(|error: toml::de::Error| vec![error.to_string().replace('\n', " ")])
}

/// One `[[cell_types]]` entry overlaid on the defaults of its kind.
fn resolve_cell_type(index: usize, entry: Value, problems: &mut Vec<String>) -> Value {
    let path = format!("cell_types[{index}]");
    if !entry.is_table() {
        problems.push(format!("{path} = {}: expected a table", show(&entry)));
        return entry;
    }
    let kind = entry
        .get("kind")
        .and_then(|value| parse_choice(value, &CellKind::ALL, &format!("{path}.kind"), problems))
        .unwrap_or(CellKind::Epithelial);
    if let Some(value) = entry.get("division_plane") {
        parse_choice(value, &DivisionPlaneRule::ALL, &format!("{path}.division_plane"), problems);
    }
    let mut merged = to_value(&CellTypeParams::default_for(kind));
    overlay(&mut merged, entry, &path, problems);
    merged
}

/// Reads an enum given as a string; records a problem naming the choices if it is not one. A
/// non-string is left to [`overlay`]'s type check.
fn parse_choice<T: Serialize + DeserializeOwned + Copy>(
    value: &Value,
    all: &[T],
    path: &str,
    problems: &mut Vec<String>,
) -> Option<T> {
    let text = value.as_str()?;
    if let Some(&choice) = all.iter().find(|choice| to_value(*choice).as_str() == Some(text)) {
        return Some(choice);
    }
    let names: Vec<String> = all.iter().map(|choice| show(&to_value(choice))).collect();
    problems.push(format!("{path} = {}: unknown value, expected one of {}", show(value), names.join(", ")));
    None
}

/// Overlays `user` on `base` recursively: tables key by key, other values replaced. Records unknown
/// keys and values of the wrong type (integers are accepted for floats).
fn overlay(base: &mut Value, user: Value, path: &str, problems: &mut Vec<String>) {
    match (base, user) {
        (Value::Table(base), Value::Table(user)) => {
            for (key, value) in user {
                match base.get_mut(&key) {
                    Some(slot) => overlay(slot, value, &format!("{path}.{key}"), problems),
                    None => problems.push(unknown_field(&key, &format!("in {path}"), base.keys().map(String::as_str))),
                }
            }
        }
        (base, Value::Integer(integer)) if base.is_float() => *base = Value::Float(integer as Real),
        (base, user) if std::mem::discriminant(&*base) == std::mem::discriminant(&user) => *base = user,
        (base, user) => problems.push(format!("{path} = {}: expected {}", show(&user), type_name(base))),
    }
}

/// `location` is "in <path>" or "at the top level".
fn unknown_field<'a>(key: &str, location: &str, expected: impl Iterator<Item = &'a str>) -> String {
    let expected: Vec<&str> = expected.collect();
    let suggestion = expected
        .iter()
        .map(|candidate| (edit_distance(key, candidate), *candidate))
        .filter(|&(distance, _)| distance <= 3)
        .min()
        .map(|(_, candidate)| format!(" (did you mean `{candidate}`?)"))
        .unwrap_or_default();
    let expected = expected.iter().map(|name| format!("`{name}`")).collect::<Vec<_>>().join(", ");
    format!("unknown field `{key}` {location}, expected one of {expected}{suggestion}")
}

/// Levenshtein distance, for "did you mean" hints.
fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut diagonal = row[0];
        row[0] = i + 1;
        for (j, &cb) in b.iter().enumerate() {
            let substitution = diagonal + usize::from(ca != cb);
            diagonal = row[j + 1];
            row[j + 1] = substitution.min(row[j] + 1).min(row[j + 1] + 1);
        }
    }
    row[b.len()]
}

fn type_name(value: &Value) -> &'static str {
    match value {
        Value::String(_) => "a string",
        Value::Integer(_) => "an integer",
        Value::Float(_) => "a number",
        Value::Boolean(_) => "a boolean",
        Value::Datetime(_) => "a date-time",
        Value::Array(_) => "an array",
        Value::Table(_) => "a table",
    }
}

/// A value for a message: scalars as TOML, containers by type.
fn show(value: &Value) -> String {
    match value {
        Value::Float(x) => fmt_real(*x),
        Value::Array(_) | Value::Table(_) => type_name(value).to_owned(),
        scalar => scalar.to_string(),
    }
}
