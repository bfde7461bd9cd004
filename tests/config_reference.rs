//! docs/config-reference.md is the output of `tissuefit config reference`, generated from the
//! schemas: a key added, removed or re-documented in the code without regenerating it fails here.

#[test]
fn the_committed_config_reference_is_the_generated_one() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/config-reference.md");
    let committed = std::fs::read_to_string(&path).unwrap_or_default();
    let generated = tissuefit::pipeline::config_reference(None).unwrap();
    if committed != generated {
        let line = committed.lines().zip(generated.lines()).position(|(a, b)| a != b);
        panic!(
            "{} is out of date with the schemas (first difference at line {}); regenerate it with\n    \
             cargo run --release -- config reference > docs/config-reference.md",
            path.display(),
            line.map_or_else(|| "the end".to_string(), |l| (l + 1).to_string())
        );
    }
}
