//! The docs book's configuration reference (docs/src/reference/configuration.md) is the output of
//! `tissuefit config reference`, generated from the schemas: a key added, removed or re-documented in
//! the code without regenerating it fails here. `TISSUEFIT_BLESS=1` regenerates it.

use crate::support::generated;

#[test]
fn the_committed_config_reference_is_the_generated_one() {
    let reference = tissuefit::pipeline::config_reference(None).unwrap();
    generated::check_generated_file("docs/src/reference/configuration.md", &reference, "config_reference");
}
