//! `tissuefit config defaults`, `tissuefit config check FILE` and `tissuefit config reference [--section S]`.

use super::Outcome;
use crate::mechanics::Parameters;
use std::path::PathBuf;

#[derive(clap::Subcommand, Debug)]
pub enum ConfigCommand {
    /// Print a complete default parameter file, every field commented with its meaning, unit and default.
    Defaults,
    /// Validate a parameter file and print the resolved configuration (defaults filled in).
    Check {
        /// Parameter file (TOML).
        file: PathBuf,
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
        ConfigCommand::Reference { section } => {
            let text =
                crate::pipeline::config_reference(section.as_deref()).map_err(|e| anyhow::anyhow!("--section: {e}"))?;
            print!("{text}");
            Ok(Outcome::Success)
        }
        ConfigCommand::Check { file } => {
            let params = Parameters::load(file)?;
            let warnings = params.validate().map_err(anyhow::Error::new)?;
            for w in &warnings {
                tracing::warn!("{}: {w}", file.display());
            }
            print!("{}", params.to_toml_string());
            eprintln!("{}: valid ({} warnings)", file.display(), warnings.len());
            Ok(Outcome::Success)
        }
    }
}
