//! The output policy: what tissuefit may write, and how (issue 23). Every file the program writes
//! goes through [`write_atomically`](super::write_atomically) or an [`OutputGroup`], which refuse to
//! replace anything but a regular file; every command checks its outputs up front with an
//! [`OutputPolicy`], before any work, so that a mistake costs nothing and names the option.
//!
//! An output
//! - is absent or a regular file: a directory where a file is meant, a device, a FIFO or a socket is
//!   refused, never replaced (a rename over `/dev/null` would replace it for everyone);
//! - is not an input of the same command: the same canonical path or, on unix, the same
//!   (device, inode), so hard links and symbolic links to an input are caught too;
//! - is not another output of the same command;
//! - has the extension of its format (`.vtp`/`.vtk`, `.tif`/`.tiff`, `.json`, `.csv`, `.toml`, `.png`).
//!
//! An output folder (`measure --out DIR`, `simulate --out DIR`, ...) is absent or a directory, and
//! the files the command writes in it obey the same rules.
//!
//! Files are written to a temporary sibling `NAME.tmp-<pid>`, flushed to disk and renamed over the
//! target, so a crash never leaves a half-written file that looks complete. An [`OutputGroup`] writes
//! files that belong together (measure's `cells.csv`, `contacts.csv`, `summary.json`) all or nothing:
//! every temporary first, then the renames; a failure before the renames removes every temporary and
//! leaves the targets as they were. (A rename within one folder does not fail for lack of space, so
//! a full disk cannot leave half a group.)

use super::FileError;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

/// An output that the policy refuses. Every variant names the option and the path.
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    #[error(
        "{option} {path}: this is also the input {input_option} {input}; writing it would destroy the input. \
         Choose another output path"
    )]
    IsInput { option: String, path: PathBuf, input_option: String, input: PathBuf },
    #[error("{option} {path}: this is also the output {other_option}; give the two outputs different paths")]
    TwoOutputs { option: String, path: PathBuf, other_option: String },
    #[error("{option} {path}: is a directory, where a file is meant; give a file name (e.g. {path}/{example})")]
    Directory { option: String, path: PathBuf, example: String },
    #[error(
        "{option} {path}: is a file, where a folder is meant; give the path of a folder (it is created if missing)"
    )]
    NotAFolder { option: String, path: PathBuf },
    #[error(
        "{option} {path}: is {kind}, not a regular file; tissuefit never replaces it. Give the path of a regular file"
    )]
    NotRegular { option: String, path: PathBuf, kind: &'static str },
    #[error(
        "{option} {path}: the folder {folder} does not exist; create it first (mkdir -p {folder}) or give a path \
         in an existing folder"
    )]
    NoFolder { option: String, path: PathBuf, folder: PathBuf },
    #[error("{option} {path}: {folder} is not a folder; give a path in an existing folder")]
    ParentNotAFolder { option: String, path: PathBuf, folder: PathBuf },
    #[error("{option} {path}: {format} files are written with the extension {expected}; use such a file name")]
    Extension { option: String, path: PathBuf, format: &'static str, expected: String },
}

/// What an output file holds: it fixes the extensions the file name may have.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    /// `.vtp` (ParaView) or `.vtk` (SimuCell3D legacy).
    Tissue,
    /// `.tif` or `.tiff`.
    Tiff,
    Json,
    Csv,
    Toml,
    Png,
}

impl Format {
    /// The extensions (lower case, without the dot) and the format's name.
    pub fn extensions(self) -> (&'static [&'static str], &'static str) {
        match self {
            Format::Tissue => (&["vtp", "vtk"], "tissue"),
            Format::Tiff => (&["tif", "tiff"], "TIFF"),
            Format::Json => (&["json"], "JSON"),
            Format::Csv => (&["csv"], "CSV"),
            Format::Toml => (&["toml"], "TOML"),
            Format::Png => (&["png"], "PNG"),
        }
    }

    /// The format a file name's extension names, if any.
    pub fn of(path: &Path) -> Option<Format> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        [Format::Tissue, Format::Tiff, Format::Json, Format::Csv, Format::Toml, Format::Png]
            .into_iter()
            .find(|f| f.extensions().0.contains(&ext.as_str()))
    }
}

/// What a path is now.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Kind {
    Absent,
    Regular,
    Directory,
    /// A device, FIFO, socket, ...: never replaced.
    Other(&'static str),
}

/// Follows symbolic links: a link to a FIFO is a FIFO, a dangling link is absent.
fn kind_of(path: &Path) -> Kind {
    let Ok(meta) = std::fs::metadata(path) else { return Kind::Absent };
    if meta.is_file() {
        return Kind::Regular;
    }
    if meta.is_dir() {
        return Kind::Directory;
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        let t = meta.file_type();
        if t.is_fifo() {
            return Kind::Other("a FIFO (named pipe)");
        }
        if t.is_char_device() {
            return Kind::Other("a character device");
        }
        if t.is_block_device() {
            return Kind::Other("a block device");
        }
        if t.is_socket() {
            return Kind::Other("a socket");
        }
    }
    Kind::Other("not a regular file")
}

fn directory_error(option: &str, path: &Path, example: &str) -> OutputError {
    OutputError::Directory { option: option.to_string(), path: path.to_path_buf(), example: example.to_string() }
}

/// Refuses a target that exists and is not a regular file (`option` names it in the message).
pub fn check_target(option: &str, path: &Path) -> Result<(), OutputError> {
    match kind_of(path) {
        Kind::Absent | Kind::Regular => Ok(()),
        Kind::Directory => Err(directory_error(option, path, "out.vtp")),
        Kind::Other(kind) => {
            Err(OutputError::NotRegular { option: option.to_string(), path: path.to_path_buf(), kind })
        }
    }
}

/// Who a file is, to compare paths that differ but name the same file.
#[derive(Clone, Debug, PartialEq, Eq)]
struct Identity {
    canonical: Option<PathBuf>,
    #[cfg(unix)]
    dev_ino: Option<(u64, u64)>,
}

impl Identity {
    fn of(path: &Path) -> Identity {
        Identity {
            canonical: std::fs::canonicalize(path).ok(),
            #[cfg(unix)]
            dev_ino: {
                use std::os::unix::fs::MetadataExt;
                std::fs::metadata(path).ok().map(|m| (m.dev(), m.ino()))
            },
        }
    }

    fn same(&self, other: &Identity) -> bool {
        #[cfg(unix)]
        if let (Some(a), Some(b)) = (self.dev_ino, other.dev_ino) {
            return a == b;
        }
        matches!((&self.canonical, &other.canonical), (Some(a), Some(b)) if a == b)
    }
}

/// Where a path would be: its folder made canonical (when it exists) and its name; for telling two
/// outputs that do not exist yet apart.
fn location(path: &Path) -> PathBuf {
    let absolute = std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf());
    match (absolute.parent(), absolute.file_name()) {
        (Some(parent), Some(name)) => std::fs::canonicalize(parent).map_or(absolute.clone(), |p| p.join(name)),
        _ => absolute,
    }
}

/// A command's inputs and the outputs checked so far; see the module doc for the rules.
#[derive(Debug, Default)]
pub struct OutputPolicy {
    inputs: Vec<(String, PathBuf, Identity)>,
    outputs: Vec<(String, PathBuf)>,
}

impl OutputPolicy {
    pub fn new() -> Self {
        Self::default()
    }

    /// Registers an input; `option` names it in messages (`TISSUE`, `--like`).
    pub fn input(mut self, option: &str, path: &Path) -> Self {
        self.inputs.push((option.to_string(), path.to_path_buf(), Identity::of(path)));
        self
    }

    /// Registers an input when there is one.
    pub fn input_opt(self, option: &str, path: Option<&Path>) -> Self {
        match path {
            Some(p) => self.input(option, p),
            None => self,
        }
    }

    /// Checks an output file: kind, not an input, not another output, extension for `format`.
    pub fn file(&mut self, option: &str, path: &Path, format: Format) -> Result<(), OutputError> {
        let (extensions, name) = format.extensions();
        if kind_of(path) == Kind::Directory {
            return Err(directory_error(option, path, &format!("out.{}", extensions[0])));
        }
        check_target(option, path)?;
        // Checked here, not when writing: a command that meshes or relaxes for minutes must not fail
        // only when it saves.
        if let Some(folder) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
            let kind = kind_of(folder);
            if kind != Kind::Directory {
                let (option, path, folder) = (option.to_string(), path.to_path_buf(), folder.to_path_buf());
                return Err(if kind == Kind::Absent {
                    OutputError::NoFolder { option, path, folder }
                } else {
                    OutputError::ParentNotAFolder { option, path, folder }
                });
            }
        }
        let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
        if !ext.as_deref().is_some_and(|e| extensions.contains(&e)) {
            let expected = extensions.iter().map(|e| format!(".{e}")).collect::<Vec<_>>().join(" or ");
            return Err(OutputError::Extension {
                option: option.to_string(),
                path: path.to_path_buf(),
                format: name,
                expected,
            });
        }
        self.not_an_input_nor_twice(option, path)
    }

    /// Checks an output folder (absent or a directory) and what the command writes in it: `files`,
    /// and subfolders named with a trailing `/` (`frames/`).
    pub fn folder(&mut self, option: &str, dir: &Path, files: &[&str]) -> Result<(), OutputError> {
        let folder = |path: &Path| match kind_of(path) {
            Kind::Absent | Kind::Directory => Ok(()),
            Kind::Regular => Err(OutputError::NotAFolder { option: option.to_string(), path: path.to_path_buf() }),
            Kind::Other(kind) => {
                Err(OutputError::NotRegular { option: option.to_string(), path: path.to_path_buf(), kind })
            }
        };
        folder(dir)?;
        for name in files {
            match name.strip_suffix('/') {
                Some(sub) => folder(&dir.join(sub))?,
                None => {
                    let path = dir.join(name);
                    check_target(option, &path)?;
                    self.not_an_input_nor_twice(option, &path)?;
                }
            }
        }
        Ok(())
    }

    fn not_an_input_nor_twice(&mut self, option: &str, path: &Path) -> Result<(), OutputError> {
        let id = Identity::of(path);
        let exists = id.canonical.is_some();
        for (input_option, input, input_id) in &self.inputs {
            let same = if exists { id.same(input_id) } else { location(path) == location(input) };
            if same {
                return Err(OutputError::IsInput {
                    option: option.to_string(),
                    path: path.to_path_buf(),
                    input_option: input_option.clone(),
                    input: input.clone(),
                });
            }
        }
        let here = location(path);
        if let Some((other, _)) = self.outputs.iter().find(|(_, p)| location(p) == here) {
            return Err(OutputError::TwoOutputs {
                option: option.to_string(),
                path: path.to_path_buf(),
                other_option: other.clone(),
            });
        }
        self.outputs.push((option.to_string(), path.to_path_buf()));
        Ok(())
    }
}

/// The temporary sibling a file is written to: `NAME.tmp-<process id>`.
pub(super) fn temporary_name(path: &Path) -> PathBuf {
    let mut name = path.file_name().map(|n| n.to_os_string()).unwrap_or_default();
    name.push(format!(".tmp-{}", std::process::id()));
    path.with_file_name(name)
}

/// Renames `tmp` over `target` after checking that `target` may be replaced (absent or a regular
/// file). For writers that must produce their temporary themselves (plots); the others use
/// [`write_atomically`](super::write_atomically) or [`OutputGroup`].
pub fn replace_with(tmp: &Path, target: &Path) -> std::io::Result<()> {
    if let Err(e) = check_target("output", target) {
        let _ = std::fs::remove_file(tmp);
        return Err(std::io::Error::other(e.to_string()));
    }
    std::fs::rename(tmp, target)
}

/// Files written together, all or nothing: [`OutputGroup::write`] each to its temporary, then
/// [`OutputGroup::commit`] renames them all into place. Dropped without a commit (an error on the
/// way), it removes its temporaries and the targets are untouched.
#[derive(Debug, Default)]
pub struct OutputGroup {
    staged: Vec<(PathBuf, PathBuf)>,
}

impl OutputGroup {
    pub fn new() -> Self {
        Self::default()
    }

    /// Writes `path`'s future content through `write` into its temporary, flushed to disk.
    pub fn write<F>(&mut self, path: &Path, write: F) -> Result<(), FileError>
    where
        F: FnOnce(&mut BufWriter<File>) -> std::io::Result<()>,
    {
        check_target("output", path).map_err(FileError::Output)?;
        let tmp = temporary_name(path);
        let result = (|| {
            let file = File::create(&tmp)?;
            let mut w = BufWriter::with_capacity(1 << 20, file);
            write(&mut w)?;
            let file = w.into_inner().map_err(|e| e.into_error())?;
            file.sync_all()
        })();
        match result {
            Ok(()) => {
                self.staged.push((tmp, path.to_path_buf()));
                Ok(())
            }
            Err(source) => {
                let _ = std::fs::remove_file(&tmp);
                Err(FileError::Write { path: path.to_path_buf(), source })
            }
        }
    }

    /// Writes `bytes` as `path`'s future content.
    pub fn write_bytes(&mut self, path: &Path, bytes: &[u8]) -> Result<(), FileError> {
        self.write(path, |w| w.write_all(bytes))
    }

    /// Renames every temporary over its target (each target checked again first: nothing is renamed
    /// when one of them became something else than a regular file meanwhile).
    pub fn commit(mut self) -> Result<(), FileError> {
        for (_, target) in &self.staged {
            check_target("output", target).map_err(FileError::Output)?;
        }
        let staged = std::mem::take(&mut self.staged);
        let mut pending = staged.iter();
        for (tmp, target) in pending.by_ref() {
            if let Err(source) = std::fs::rename(tmp, target) {
                let _ = std::fs::remove_file(tmp);
                for (rest, _) in pending {
                    let _ = std::fs::remove_file(rest);
                }
                return Err(FileError::Write { path: target.clone(), source });
            }
        }
        Ok(())
    }
}

impl Drop for OutputGroup {
    fn drop(&mut self) {
        for (tmp, _) in &self.staged {
            let _ = std::fs::remove_file(tmp);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_input_a_folder_a_fifo_and_a_wrong_extension_are_refused_by_name() {
        let dir = tempfile::tempdir().unwrap();
        let input = dir.path().join("seg.tif");
        std::fs::write(&input, b"labels").unwrap();
        let mut policy = OutputPolicy::new().input("LABELS", &input);
        let e = policy.file("--report", &input, Format::Json).unwrap_err().to_string();
        assert!(e.contains("--report") && e.contains("seg.tif") && e.contains("extension .json"), "{e}");
        let e = policy.file("--out", &input, Format::Tiff).unwrap_err().to_string();
        assert!(e.contains("also the input LABELS"), "{e}");
        // The same file by another name: a hard link and a path with `..` in it.
        let link = dir.path().join("link.tif");
        std::fs::hard_link(&input, &link).unwrap();
        let e = policy.file("--out", &link, Format::Tiff).unwrap_err().to_string();
        assert!(e.contains("also the input LABELS"), "{e}");
        std::fs::create_dir(dir.path().join("sub")).unwrap();
        let dotted = dir.path().join("sub/../seg.tif");
        assert!(policy.file("--out", &dotted, Format::Tiff).unwrap_err().to_string().contains("also the input"));
        let e = policy.file("--out", dir.path(), Format::Tissue).unwrap_err().to_string();
        assert!(e.contains("is a directory") && e.contains("out.vtp"), "{e}");
        // Two outputs at one path.
        policy.file("--out", &dir.path().join("t.vtp"), Format::Tissue).unwrap();
        let e = policy.file("--report", &dir.path().join("sub/../t.vtp"), Format::Tissue).unwrap_err().to_string();
        assert!(e.contains("also the output --out"), "{e}");
        // A missing folder is refused before any work, and a file where the folder should be.
        let e = policy.file("--out", &dir.path().join("no/such/t.vtp"), Format::Tissue).unwrap_err().to_string();
        assert!(e.contains("--out") && e.contains("does not exist") && e.contains("mkdir -p"), "{e}");
        let e = policy.file("--out", &input.join("t.vtp"), Format::Tissue).unwrap_err().to_string();
        assert!(e.contains("is not a folder"), "{e}");
        // Upper-case extensions are fine.
        policy.file("--nuclei", &dir.path().join("N.TIFF"), Format::Tiff).unwrap();
        #[cfg(unix)]
        {
            let fifo = dir.path().join("pipe.json");
            assert!(std::process::Command::new("mkfifo").arg(&fifo).status().unwrap().success());
            let e = policy.file("--report", &fifo, Format::Json).unwrap_err().to_string();
            assert!(e.contains("FIFO") && e.contains("never replaces"), "{e}");
            // The writer itself refuses too, and leaves the FIFO a FIFO.
            let e = crate::files::write_bytes_atomically(&fifo, b"{}").unwrap_err().to_string();
            assert!(e.contains("FIFO"), "{e}");
            use std::os::unix::fs::FileTypeExt;
            assert!(std::fs::metadata(&fifo).unwrap().file_type().is_fifo());
        }
    }

    #[test]
    fn an_output_folder_is_a_folder_and_its_files_are_not_inputs() {
        let dir = tempfile::tempdir().unwrap();
        let input = dir.path().join("cells.csv");
        std::fs::write(&input, b"x").unwrap();
        let mut policy = OutputPolicy::new().input("TISSUE", &input);
        let e = policy.folder("--out", dir.path(), &["cells.csv", "summary.json"]).unwrap_err().to_string();
        assert!(e.contains("--out") && e.contains("also the input TISSUE"), "{e}");
        let e = OutputPolicy::new().folder("--out", &input, &[]).unwrap_err().to_string();
        assert!(e.contains("where a folder is meant"), "{e}");
        OutputPolicy::new().folder("--out", &dir.path().join("new"), &["summary.json"]).unwrap();
    }

    #[test]
    fn a_group_is_written_all_or_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b) = (dir.path().join("a.csv"), dir.path().join("b.json"));
        std::fs::write(&a, b"old a").unwrap();
        {
            let mut group = OutputGroup::new();
            group.write_bytes(&a, b"new a").unwrap();
            let e = group.write(&b, |_| Err(std::io::Error::other("disk full"))).unwrap_err().to_string();
            assert!(e.contains("disk full") && e.contains("b.json"), "{e}");
        }
        assert_eq!(std::fs::read(&a).unwrap(), b"old a");
        assert!(!b.exists());
        let names: Vec<_> = std::fs::read_dir(dir.path()).unwrap().map(|e| e.unwrap().file_name()).collect();
        assert_eq!(names.len(), 1, "temporaries left: {names:?}");
        let mut group = OutputGroup::new();
        group.write_bytes(&a, b"new a").unwrap();
        group.write_bytes(&b, b"{}").unwrap();
        group.commit().unwrap();
        assert_eq!((std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap()), (b"new a".to_vec(), b"{}".to_vec()));
    }
}
