//! Files committed to the docs book but generated from the code (the CLI and configuration
//! references): a test compares the committed file with what the code generates now and fails while
//! they differ; run with `TISSUEFIT_BLESS=1` it writes the generated text instead.

use std::path::Path;

/// Checks that the file at `relative` (from the crate root) holds exactly `generated`. With the
/// environment variable `TISSUEFIT_BLESS=1` it (re)writes the file instead (to a temporary name, then
/// renamed). Otherwise it panics with the first differing line and the command that regenerates the
/// file (`test` is the name of the calling test binary).
pub fn check_generated_file(relative: &str, generated: &str, test: &str) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(relative);
    let regenerate = format!("TISSUEFIT_BLESS=1 cargo test --release --test integration {test}::");
    if std::env::var_os("TISSUEFIT_BLESS").is_some_and(|v| v == "1") {
        let tmp = path.with_extension("md.tmp");
        std::fs::write(&tmp, generated).unwrap_or_else(|e| panic!("cannot write {}: {e}", tmp.display()));
        std::fs::rename(&tmp, &path)
            .unwrap_or_else(|e| panic!("cannot rename {} to {}: {e}", tmp.display(), path.display()));
        return;
    }
    let committed = std::fs::read_to_string(&path)
        .unwrap_or_else(|e| panic!("cannot read {}: {e}; generate it with\n    {regenerate}", path.display()));
    if committed != generated {
        let line = committed.lines().zip(generated.lines()).position(|(a, b)| a != b).map_or_else(
            || format!("the end (line {})", committed.lines().count().min(generated.lines().count()) + 1),
            |l| (l + 1).to_string(),
        );
        panic!(
            "{} is out of date with the code (first difference at line {line}); regenerate it with\n    {regenerate}",
            path.display()
        );
    }
}
