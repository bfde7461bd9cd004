//! Running the `tissuefit` binary from the tests.

use std::path::PathBuf;
use std::process::{Command, Output};

/// The repository root (where `pipelines/` and `tests/data/` are).
pub fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Runs the `tissuefit` binary with `args` and returns its output (whatever its exit status).
pub fn tissuefit(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_tissuefit")).args(args).output().expect("the tissuefit binary runs")
}

/// Runs the `tissuefit` binary with `args` and asserts it exits 0, printing its output if not.
pub fn ok(args: &[&str]) {
    let o = tissuefit(args);
    assert_eq!(
        o.status.code(),
        Some(0),
        "tissuefit {args:?}\n{}\n{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
}
