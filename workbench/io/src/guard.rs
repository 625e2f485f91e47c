//! Outputs never overwrite inputs. Every command names its inputs and outputs and asks
//! here, before any work, whether an output is one of its inputs: the same file by
//! identity (device and inode on Unix, so hard and symbolic links count), a file of an
//! input data directory, or — for an output directory — a directory that holds an input
//! the command could overwrite.

use std::fs;
use std::path::{Path, PathBuf};

/// Identity of an existing file or directory.
#[derive(Debug, Clone, PartialEq, Eq)]
enum FileId {
    #[cfg(unix)]
    Inode(u64, u64),
    #[cfg(not(unix))]
    Canonical(PathBuf),
}

fn id_of(path: &Path) -> Option<FileId> {
    let meta = fs::metadata(path).ok()?;
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        Some(FileId::Inode(meta.dev(), meta.ino()))
    }
    #[cfg(not(unix))]
    {
        let _ = meta;
        fs::canonicalize(path).ok().map(FileId::Canonical)
    }
}

/// One input: what names it (a flag or an argument), its path and identity.
#[derive(Debug, Clone)]
struct Input {
    what: String,
    path: PathBuf,
    id: FileId,
    /// Identity of the directory holding it.
    parent: Option<FileId>,
}

/// A command's inputs.
#[derive(Debug, Clone, Default)]
pub struct Inputs {
    files: Vec<Input>,
}

impl Inputs {
    /// No inputs yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// An input file named by `what` (a file that does not exist is its reader's
    /// error, not this check's).
    pub fn file(mut self, what: &str, path: Option<&Path>) -> Self {
        if let Some(p) = path {
            self.push(what, p);
        }
        self
    }

    /// Several input files (positional runs).
    pub fn files<'a>(mut self, what: &str, paths: impl IntoIterator<Item = &'a PathBuf>) -> Self {
        for p in paths {
            self.push(what, p);
        }
        self
    }

    /// An input data directory: every file in it and in its `profiles/`.
    pub fn dir(mut self, what: &str, dir: Option<&Path>) -> Self {
        let Some(dir) = dir else { return self };
        for d in [dir.to_path_buf(), dir.join("profiles")] {
            let Ok(entries) = fs::read_dir(&d) else { continue };
            for e in entries.flatten() {
                let p = e.path();
                if p.is_file() {
                    self.push(what, &p);
                }
            }
        }
        self
    }

    fn push(&mut self, what: &str, path: &Path) {
        if let Some(id) = id_of(path) {
            let parent = path.parent().map(|p| if p.as_os_str().is_empty() { Path::new(".") } else { p });
            let parent = parent.and_then(id_of);
            self.files.push(Input { what: what.to_owned(), path: path.to_path_buf(), id, parent });
        }
    }

    /// Refuse output `out` (named by `what`) if it is one of the inputs.
    pub fn check(&self, what: &str, out: &Path) -> Result<(), String> {
        let Some(id) = id_of(out) else { return Ok(()) };
        match self.files.iter().find(|i| i.id == id) {
            Some(i) => Err(format!(
                "{what} {} is the input {} ({}): an output never replaces an input; choose another {what}",
                out.display(),
                i.path.display(),
                i.what
            )),
            None => Ok(()),
        }
    }

    /// Refuse output directory `dir` (named by `what`) if it is a file, or if the command
    /// could overwrite an input in it: an input directly in `dir` or in `dir/profiles`, or
    /// `dir` itself.
    pub fn check_dir(&self, what: &str, dir: &Path) -> Result<(), String> {
        self.check(what, dir)?;
        if dir.is_file() {
            return Err(format!("{what} {}: a file, expected a directory", dir.display()));
        }
        for d in [dir.to_path_buf(), dir.join("profiles")] {
            let Some(id) = id_of(&d) else { continue };
            if let Some(i) = self.files.iter().find(|i| i.parent.as_ref() == Some(&id)) {
                return Err(format!(
                    "{what} {} holds the input {} ({}), which the files written there could replace; \
                     choose another {what}",
                    dir.display(),
                    i.path.display(),
                    i.what
                ));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_same_file_by_any_name_is_refused() {
        let d = tempfile::tempdir().unwrap();
        let run = d.path().join("run.csv");
        fs::write(&run, "t\n").unwrap();
        let inputs = Inputs::new().file("the measurement", Some(&run));
        let e = inputs.check("--plot", &run).unwrap_err();
        assert!(e.contains("is the input") && e.contains("the measurement"), "{e}");
        // A different spelling of the same path.
        let dotted = d.path().join(".").join("run.csv");
        assert!(inputs.check("--out", &dotted).is_err());
        // A hard link and a symbolic link.
        let hard = d.path().join("hard.csv");
        fs::hard_link(&run, &hard).unwrap();
        assert!(inputs.check("--out", &hard).is_err());
        #[cfg(unix)]
        {
            let soft = d.path().join("soft.csv");
            std::os::unix::fs::symlink(&run, &soft).unwrap();
            assert!(inputs.check("--out", &soft).is_err());
        }
        // Another file, or one not there yet, is fine.
        fs::write(d.path().join("other.csv"), "t\n").unwrap();
        assert!(inputs.check("--out", &d.path().join("other.csv")).is_ok());
        assert!(inputs.check("--out", &d.path().join("new.csv")).is_ok());
    }

    #[test]
    fn data_directories_and_output_directories() {
        let d = tempfile::tempdir().unwrap();
        let data = d.path().join("data");
        fs::create_dir_all(data.join("profiles")).unwrap();
        fs::write(data.join("parameters.toml"), "").unwrap();
        fs::write(data.join("profiles").join("TP07.csv"), "").unwrap();
        let inputs = Inputs::new().dir("--data-dir", Some(&data));
        assert!(inputs.check("--out", &data.join("parameters.toml")).is_err());
        assert!(inputs.check("--out", &data.join("profiles").join("TP07.csv")).is_err());
        let e = inputs.check_dir("--out", &data).unwrap_err();
        assert!(e.contains("holds the input"), "{e}");
        assert!(inputs.check_dir("--out", &d.path().join("elsewhere")).is_ok());
        let runs = d.path().join("runs");
        fs::create_dir_all(&runs).unwrap();
        fs::write(runs.join("speed_map_fwd.csv"), "").unwrap();
        let inputs = Inputs::new().files("a run", [runs.join("speed_map_fwd.csv")].iter());
        assert!(inputs.check_dir("--out", &runs).is_err());
        assert!(inputs.check_dir("--out", d.path()).is_ok());
        let e = Inputs::new().check_dir("--out", &runs.join("speed_map_fwd.csv")).unwrap_err();
        assert!(e.contains("a file, expected a directory"), "{e}");
    }
}
