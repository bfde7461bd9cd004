//! `tissuefit config defaults`, `tissuefit config check FILE` and `tissuefit config reference [--section S]`.

use super::Outcome;
use crate::io::{ReadOptions, read_tissue};
use crate::mechanics::{ContactModel, Parameters, REPULSION_PER_PRESSURE, Simulation};
use anyhow::Context;
use std::path::PathBuf;

#[derive(clap::Subcommand, Debug)]
pub enum ConfigCommand {
    /// Print a complete default parameter file, every field commented with its meaning, unit and default.
    Defaults,
    /// Validate a parameter file and print the resolved configuration (defaults filled in).
    Check {
        /// Parameter file (TOML).
        file: PathBuf,
        /// Also check it against this tissue (.vtp/.vtk/.ply…), as `simulate` would run it: derive the
        /// mesh-dependent values the file leaves unset (l_min, contact cutoff, time step, spring
        /// repulsion), warn where the file contradicts the mesh, and where the repulsion cannot hold
        /// the cells' Laplace pressure.
        #[arg(long, value_name = "TISSUE")]
        tissue: Option<PathBuf>,
    },
    /// List the presets for real data (`preset = "NAME"` in a pipeline file), each with what it is for.
    Presets,
    /// Print one preset's TOML (the keys a pipeline file naming it starts from, with comments).
    Preset {
        /// The preset's name (see `tissuefit config presets`).
        name: String,
    },
    /// Print the Markdown reference of every pipeline-file key (type, default, description) and of
    /// the model parameters, generated from the schemas (the docs book's reference/configuration.md is
    /// this output).
    Reference {
        /// Only this section: input, mesh, measure, simulate, fit, demo or model.
        #[arg(long, value_name = "SECTION")]
        section: Option<String>,
    },
}

pub fn run(cmd: &ConfigCommand) -> anyhow::Result<Outcome> {
    match cmd {
        ConfigCommand::Defaults => {
            print!("{}", Parameters::default_toml_commented());
            Ok(Outcome::Success)
        }
        ConfigCommand::Presets => {
            for p in crate::pipeline::preset::PRESETS {
                println!("{:<16}{}", p.name, p.summary);
            }
            println!(
                "\nUse one with `preset = \"NAME\"` at the top of a pipeline file; `tissuefit config preset NAME` prints it."
            );
            Ok(Outcome::Success)
        }
        ConfigCommand::Preset { name } => {
            let preset = crate::pipeline::preset::find(name).map_err(|e| anyhow::anyhow!(e))?;
            print!("{}", preset.text);
            Ok(Outcome::Success)
        }
        ConfigCommand::Reference { section } => {
            let text =
                crate::pipeline::config_reference(section.as_deref()).map_err(|e| anyhow::anyhow!("--section: {e}"))?;
            print!("{text}");
            Ok(Outcome::Success)
        }
        ConfigCommand::Check { file, tissue } => {
            let (mut params, explicit) = Parameters::load_explicit(file)?;
            let mut warnings = params.validate().map_err(anyhow::Error::new)?;
            match tissue {
                Some(path) => {
                    let read = read_tissue(path, &ReadOptions::default())
                        .with_context(|| format!("reading {}", path.display()))?;
                    warnings.extend(read.warnings.iter().map(|w| format!("{}: {w}", path.display())));
                    let fit = params.fit_to_tissue(&explicit, &read.tissue);
                    for line in fit.lines() {
                        eprintln!("note: {line}");
                    }
                    warnings.extend(fit.warnings);
                    let derived = if fit.derived.is_empty() { "" } else { " with the values derived from the tissue" };
                    let again = params
                        .validate()
                        .with_context(|| format!("checking {}{derived} against {}", file.display(), path.display()))?;
                    warnings.extend(again.into_iter().filter(|w| !warnings.contains(w)).collect::<Vec<_>>());
                    let sim = Simulation::new(read.tissue, &params)
                        .with_context(|| format!("checking {} against {}", file.display(), path.display()))?;
                    warnings.extend(sim.repulsion_shortfalls());
                }
                None => {
                    if params.numerics.contact_model == ContactModel::Spring && !explicit.repulsion {
                        eprintln!(
                            "note: no cell type sets the spring repulsion: `simulate` derives it from the input tissue \
                             (ξ·c = {REPULSION_PER_PRESSURE} × the cells' Laplace pressure); pass --tissue to see the values"
                        );
                    }
                }
            }
            for w in &warnings {
                tracing::warn!("{}: {w}", file.display());
            }
            print!("{}", params.to_toml_string());
            let against = tissue.as_ref().map_or(String::new(), |t| format!(" for {}", t.display()));
            eprintln!("{}: valid{against} ({} warnings)", file.display(), warnings.len());
            Ok(Outcome::Success)
        }
    }
}
