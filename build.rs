//! Build script: records the git commit the binary is built from as `TISSUEFIT_GIT_COMMIT` (read by
//! the pipeline manifest), without running git. It reads `.git/HEAD` and the branch's ref (a loose
//! ref file or `packed-refs`), following a worktree's `.git` file and `commondir`. A commit given in
//! the environment (`TISSUEFIT_GIT_COMMIT=…` at build time, e.g. from a source tarball's packager)
//! wins; without a repository nothing is set and the manifest records `null`.

use std::fs;
use std::path::{Path, PathBuf};

fn main() {
    println!("cargo:rerun-if-env-changed=TISSUEFIT_GIT_COMMIT");
    if std::env::var("TISSUEFIT_GIT_COMMIT").is_ok_and(|c| !c.trim().is_empty()) {
        // rustc sees the variable of the environment itself.
        return;
    }
    let root = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").unwrap_or_else(|_| ".".into()));
    if let Some(commit) = git_commit(&root) {
        println!("cargo:rustc-env=TISSUEFIT_GIT_COMMIT={commit}");
    }
}

/// Watches `path` for changes if it exists (a missing path would make cargo rerun this script on
/// every build).
fn watch(path: &Path) {
    if path.exists() {
        println!("cargo:rerun-if-changed={}", path.display());
    }
}

fn is_hash(s: &str) -> bool {
    (s.len() == 40 || s.len() == 64) && s.bytes().all(|b| b.is_ascii_hexdigit())
}

/// The commit HEAD points at, or `None` when there is no readable repository.
fn git_commit(root: &Path) -> Option<String> {
    let dot_git = root.join(".git");
    // A worktree or submodule has a `.git` file naming its git directory. (A `.git` folder is not
    // watched as a whole: cargo would scan all of it, and every `git add` would rebuild the crate.)
    let git_dir = if dot_git.is_file() {
        watch(&dot_git);
        let text = fs::read_to_string(&dot_git).ok()?;
        let dir = PathBuf::from(text.trim().strip_prefix("gitdir:")?.trim());
        if dir.is_relative() { root.join(dir) } else { dir }
    } else if dot_git.is_dir() {
        dot_git
    } else {
        return None;
    };
    // Shared refs live in the common directory of a worktree.
    let common_dir = match fs::read_to_string(git_dir.join("commondir")) {
        Ok(text) => {
            let dir = PathBuf::from(text.trim());
            if dir.is_relative() { git_dir.join(dir) } else { dir }
        }
        Err(_) => git_dir.clone(),
    };
    let head_path = git_dir.join("HEAD");
    watch(&head_path);
    let head = fs::read_to_string(&head_path).ok()?;
    let head = head.trim();
    if is_hash(head) {
        return Some(head.to_string()); // detached HEAD
    }
    let reference = head.strip_prefix("ref:")?.trim();
    for dir in [&git_dir, &common_dir] {
        let loose = dir.join(reference);
        if let Ok(text) = fs::read_to_string(&loose) {
            watch(&loose);
            let hash = text.trim();
            if is_hash(hash) {
                return Some(hash.to_string());
            }
        }
    }
    // Not yet a loose file: a new commit writes one into the branch's folder, so watch that too.
    if let Some(folder) = common_dir.join(reference).parent() {
        watch(folder);
    }
    let packed = common_dir.join("packed-refs");
    watch(&packed);
    let text = fs::read_to_string(&packed).ok()?;
    text.lines()
        .filter(|l| !l.starts_with('#') && !l.starts_with('^'))
        .filter_map(|l| l.split_once(' '))
        .find(|(_, name)| name.trim() == reference)
        .map(|(hash, _)| hash.to_string())
        .filter(|h| is_hash(h))
}
