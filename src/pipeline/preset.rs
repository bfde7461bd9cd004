//! Presets: named, documented starting points for real data, chosen with `preset = "NAME"` at the top
//! of a pipeline file. A preset is a partial pipeline file (`src/pipeline/presets/NAME.toml`, compiled
//! into the program): its `[mesh]`, `[measure]` and `[fit]` tables are the base, and the pipeline
//! file's own keys are laid over them key by key (tables merge, any other value — arrays included —
//! replaces the preset's). A section's `model = FILE` replaces the preset's model for that section:
//! the preset's `model_overrides` of that section are then dropped (the file's own
//! `model_overrides` still apply). `tissuefit config presets` lists them; `tissuefit config preset
//! NAME` prints one.

/// One preset: its name, a line saying what it is for, and its TOML text.
#[derive(Clone, Copy, Debug)]
pub struct Preset {
    pub name: &'static str,
    pub summary: &'static str,
    pub text: &'static str,
}

/// Every preset, in the order `tissuefit config presets` lists them.
pub const PRESETS: &[Preset] = &[
    Preset {
        name: "compact-embryo",
        summary: "a few whole cells in a compact cluster (early embryo, organoid); coupled contacts; fits the \
                  cell–cell tension relative to the free-surface tension",
        text: include_str!("presets/compact-embryo.toml"),
    },
    Preset {
        name: "epithelium",
        summary: "a dense tissue or epithelial layer cut by the image border (cut cells static, holding the \
                  whole cells inside); coupled contacts; fits the lateral tension relative to the free one",
        text: include_str!("presets/epithelium.toml"),
    },
    Preset {
        name: "aggregate",
        summary: "whole cells that adhere moderately (aggregate, spheroid; w/(2γ) up to 0.7); spring contacts; fits \
                  the adhesion w/(2γ) relative to the tension (Young–Dupré: cos(θ/2) = 1 − w/(2γ)); strongly \
                  compacted cells: compact-embryo",
        text: include_str!("presets/aggregate.toml"),
    },
];

/// The preset called `name`, or an error listing the names (and the nearest one).
pub fn find(name: &str) -> Result<&'static Preset, String> {
    PRESETS.iter().find(|p| p.name == name).ok_or_else(|| {
        let names: Vec<String> = PRESETS.iter().map(|p| p.name.to_string()).collect();
        let hint = super::nearest(name, &names).map_or(String::new(), |n| format!("; did you mean `{n}`?"));
        format!(
            "preset: unknown preset `{name}`: choose one of {} (`tissuefit config presets` says what each is for){hint}",
            names.join(", ")
        )
    })
}

/// The pipeline table `user` laid over its preset, when it names one (`preset = "…"`); `None` when it
/// names none.
pub fn apply(user: &toml::Table) -> Result<Option<(&'static Preset, toml::Table)>, String> {
    let name = match user.get("preset") {
        None => return Ok(None),
        Some(toml::Value::String(s)) => s.as_str(),
        Some(other) => return Err(format!("preset: must be a name in quotes; got {other}")),
    };
    let preset = find(name)?;
    let mut base: toml::Table = toml::from_str(preset.text)
        .map_err(|e| format!("preset `{name}` (built in) does not parse; please report it: {e}"))?;
    for section in ["simulate", "fit"] {
        let own_model = user.get(section).and_then(|s| s.get("model")).is_some();
        if own_model && let Some(toml::Value::Table(s)) = base.get_mut(section) {
            s.remove("model_overrides");
        }
    }
    merge(&mut base, user.clone());
    Ok(Some((preset, base)))
}

/// `over` laid over `base`: tables merge recursively, every other value (arrays included) replaces.
/// How a preset is laid under a pipeline file; the Python API lays its config overrides the same way.
pub fn merge(base: &mut toml::Table, over: toml::Table) {
    for (key, value) in over {
        match (base.get_mut(&key), value) {
            (Some(toml::Value::Table(b)), toml::Value::Table(o)) => merge(b, o),
            (_, value) => {
                base.insert(key, value);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tables_merge_and_other_values_replace() {
        let mut base: toml::Table = toml::from_str("[a]\nx = 1\ny = [1, 2]\n[a.b]\nz = 3\n[c]\nw = 1").unwrap();
        let over: toml::Table = toml::from_str("[a]\ny = [5]\n[a.b]\nq = 4\n[d]\nv = 2").unwrap();
        merge(&mut base, over);
        let want: toml::Table =
            toml::from_str("[a]\nx = 1\ny = [5]\n[a.b]\nz = 3\nq = 4\n[c]\nw = 1\n[d]\nv = 2").unwrap();
        assert_eq!(base, want);
    }

    #[test]
    fn an_unknown_name_is_refused_with_the_names_and_the_nearest() {
        let e = find("compact_embryo").unwrap_err();
        assert!(e.contains("did you mean `compact-embryo`"), "{e}");
        assert!(e.contains("epithelium"), "{e}");
    }

    #[test]
    fn a_model_file_replaces_the_presets_model() {
        let user: toml::Table = toml::from_str("preset = \"compact-embryo\"\n[fit]\nmodel = \"m.toml\"").unwrap();
        let (_, merged) = apply(&user).unwrap().unwrap();
        let fit = merged["fit"].as_table().unwrap();
        assert!(fit.get("model_overrides").is_none());
        assert_eq!(fit["model"].as_str(), Some("m.toml"));
        assert!(fit.get("parameters").is_some(), "the rest of the preset's fit stays");
    }
}
