//! Output files, written so that a failed run replaces nothing and leaves nothing behind.
//!
//! Every output of a run is first written to a temporary file beside its target, created
//! exclusively under a random name (never following an existing file or symlink), flushed to
//! disk; only when every step of the run has succeeded are the temporary files renamed onto
//! their targets. A temporary file is removed on any failure. An output that would overwrite
//! one of the run's inputs, or another output of the same run, is refused before anything is
//! written.

use std::io::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{anyhow, bail, Context as _, Result};
use tempfile::NamedTempFile;

/// The outputs of one run, written but not yet in place.
#[derive(Default)]
pub struct Staged {
    files: Vec<(PathBuf, NamedTempFile)>,
}

/// `path` made absolute with its folder resolved (the file itself need not exist).
fn resolved(path: &Path) -> Result<PathBuf> {
    let dir = match path.parent().filter(|d| !d.as_os_str().is_empty()) {
        Some(d) => d.to_path_buf(),
        None => PathBuf::from("."),
    };
    let name = path
        .file_name()
        .ok_or_else(|| anyhow!("{}: not a file path", path.display()))?;
    let dir = dir.canonicalize().with_context(|| {
        format!(
            "cannot write {}: no folder {}",
            path.display(),
            dir.display()
        )
    })?;
    Ok(dir.join(name))
}

/// Refuses outputs that are inputs of the run, or repeated.
pub fn check_distinct(outputs: &[&Path], inputs: &[&Path]) -> Result<()> {
    let inputs: Vec<PathBuf> = inputs
        .iter()
        .filter_map(|p| p.canonicalize().ok())
        .collect();
    let mut seen: Vec<PathBuf> = Vec::new();
    for out in outputs {
        let r = resolved(out)?;
        // A symlink at the output names its target: compare that too.
        let target = r.canonicalize().unwrap_or_else(|_| r.clone());
        if inputs.contains(&r) || inputs.contains(&target) {
            bail!(
                "{}: refusing to write an output over an input of this run",
                out.display()
            );
        }
        if seen.contains(&r) {
            bail!("{}: named as two outputs of this run", out.display());
        }
        if r.is_dir() {
            bail!("{}: is a folder, not a file", out.display());
        }
        seen.push(r);
    }
    Ok(())
}

impl Staged {
    /// Nothing staged.
    pub fn new() -> Self {
        Staged::default()
    }

    /// Writes `contents` for `path` into a fresh temporary file beside it.
    pub fn text(&mut self, path: &Path, contents: &str) -> Result<()> {
        self.with(path, |f| {
            f.write_all(contents.as_bytes())?;
            Ok(())
        })
    }

    /// Creates a fresh temporary file for `path` and lets `write` fill it by its path (for
    /// writers that open files themselves).
    pub fn by_path(&mut self, path: &Path, write: impl FnOnce(&Path) -> Result<()>) -> Result<()> {
        let file = self.temp(path)?;
        write(file.path())?;
        file.as_file()
            .sync_all()
            .with_context(|| format!("cannot write {}", path.display()))?;
        self.files.push((path.to_path_buf(), file));
        Ok(())
    }

    fn temp(&self, path: &Path) -> Result<NamedTempFile> {
        let target = resolved(path)?;
        let dir = target.parent().expect("resolved paths have a folder");
        let name = target
            .file_name()
            .map(|n| n.to_string_lossy().to_string())
            .unwrap_or_default();
        let ext = target
            .extension()
            .map(|e| format!(".{}", e.to_string_lossy()))
            .unwrap_or_default();
        tempfile::Builder::new()
            .prefix(&format!(".{name}."))
            .suffix(&format!(".kinecal-tmp{ext}"))
            .tempfile_in(dir)
            .with_context(|| format!("cannot write {}", path.display()))
    }

    fn with(
        &mut self,
        path: &Path,
        write: impl FnOnce(&mut std::fs::File) -> std::io::Result<()>,
    ) -> Result<()> {
        let mut file = self.temp(path)?;
        write(file.as_file_mut())
            .and_then(|()| file.as_file().sync_all())
            .with_context(|| format!("cannot write {}", path.display()))?;
        self.files.push((path.to_path_buf(), file));
        Ok(())
    }

    /// Moves every staged file onto its target. On a failure, the files not yet moved are
    /// removed.
    pub fn commit(self) -> Result<()> {
        if let Some((path, _)) = self.files.iter().find(|(p, _)| p.is_dir()) {
            bail!("cannot write {}: it is a folder", path.display());
        }
        for (path, file) in self.files {
            file.persist(&path)
                .map_err(|e| anyhow!("cannot write {}: {}", path.display(), e.error))?;
        }
        Ok(())
    }
}

/// Writes one file atomically (see the module documentation).
pub fn write_file(path: &Path, contents: &str) -> Result<()> {
    let mut s = Staged::new();
    s.text(path, contents)?;
    s.commit()
}
