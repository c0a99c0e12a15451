//! Output files, written so that a failed run replaces nothing and leaves nothing behind.
//!
//! What an output path names decides how it is written ([`target`]):
//!
//! - A regular file, or no file yet, is *replaced*: the output is first written to a temporary
//!   file beside it (`.kinecal-tmp-<pid>-<random>-<name>`, created exclusively, never following
//!   an existing file or symlink), flushed to disk (its bytes and what reading them back needs,
//!   its size: `fdatasync`, not its times), and only when every step of the run has
//!   succeeded renamed onto the target: readers see the old file or the new one, never a part.
//!   Symlinks are followed (the folder canonicalised, then each link of the final name), so
//!   `--out link` updates the file the link points to, even a file not written yet, and the
//!   link stays. A new file gets the mode `0o666` less the umask, as any program's new file;
//!   an existing one keeps its mode (and, where allowed, its owner and group).
//! - Anything else is *written into, in place*, never renamed over: a character or block
//!   device (`/dev/null`), a FIFO, a socket, `-` (standard output), and the links to the
//!   process's open files (`/dev/stdout`, `/dev/stderr`, `/dev/fd/N`, `/proc/self/fd/N`: written
//!   through the descriptor itself, so a shell's `> file` or `>> file` gets the bytes after what
//!   was printed there, as it would from `cat`). A device is opened for writing without
//!   truncating it. These bytes are kept in memory until the commit and written first: a write
//!   that fails there (a full device, a reader gone) fails the run before any regular file is
//!   replaced. A FIFO's writer waits, as any writer does, for a reader.
//!
//! Temporary files are removed on every way out: an error or a panic (the temporary file's
//! owner removes it when dropped), and, in a program that asked for it with
//! [`remove_temporaries_on_signals`] (the `kinecal` command does; a Python process keeps its
//! own handlers), SIGINT, SIGTERM and SIGHUP (a handler, installed with the first temporary
//! file, removes them and then ends the process as the signal would; during the renames of a
//! commit it waits for the last; a signal the process was started ignoring, as under `nohup`,
//! stays ignored: see the `files::cleanup` module). A write into a pipe whose
//! reader is gone fails with an error rather than ending the process on SIGPIPE. Only a process
//! killed outright (SIGKILL, a power cut) leaves its temporary files; the next run that writes
//! into the same folder removes those whose process id names no running process and that are
//! older than a minute, and says so on standard error. (Files of this shape are only ever
//! written by kinecal; one named by a process that runs in another PID namespace or on another
//! machine sharing the folder may look dead from here, hence the minute.) Temporary files of
//! earlier kinecal versions (`.NAME.XXXXXX.kinecal-tmp[.ext]`) are removed after a day.
//!
//! An output that would overwrite one of the run's inputs, or another output of the same run,
//! is refused before anything is written ([`check_distinct`]); the comparison is by the
//! resolved path and, on Unix, by device and inode, so `r.json`, `./r.json`, a link to it and
//! a hard link are one file. Outputs written in place are not compared: two outputs into one
//! FIFO or into `/dev/null` do not clash.

use std::ffi::OsString;
use std::fs::{self, Metadata};
use std::io::{self, Read as _, Write as _};
use std::path::{Component, Path, PathBuf};
use std::sync::{Mutex, PoisonError};
use std::time::Duration;

use tempfile::NamedTempFile;

use crate::error::{Error, Result};

/// An output that cannot be written, and why.
fn refuse(path: &Path, message: impl Into<String>) -> Error {
    Error::Output {
        path: path.display().to_string(),
        message: message.into(),
    }
}

/// An I/O failure writing the output `path`.
fn failed(path: &Path, cause: io::Error) -> Error {
    Error::Io {
        path: path.display().to_string(),
        cause,
    }
}

/// Asks that temporary files be removed on SIGINT, SIGTERM and SIGHUP (then the process ends as
/// the signal would): for a program that owns its signals, such as the `kinecal` command. A
/// library host (Python) keeps its own handlers and does not call it.
pub fn remove_temporaries_on_signals() {
    super::cleanup::ask();
}

/// The start of the name of every temporary file kinecal writes.
pub(crate) const TEMP_PREFIX: &str = ".kinecal-tmp-";

/// How old a temporary file of a dead process must be before it is removed.
const STALE_AFTER: Duration = Duration::from_secs(60);

/// How old a temporary file of an earlier kinecal version (no process id) must be.
const OLD_FORMAT_STALE_AFTER: Duration = Duration::from_secs(24 * 3600);

/// Links followed at most when resolving an output (as the kernel's `ELOOP` limit).
const MAX_LINKS: usize = 40;

/// Where the bytes of an output written in place go.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Sink {
    /// `-`, `/dev/stdout` and descriptor 1.
    Stdout,
    /// `/dev/stderr` and descriptor 2.
    Stderr,
    /// Another descriptor of this process (`/dev/fd/N`).
    Descriptor(i32),
    /// A device, FIFO or socket (or another process's descriptor), opened by its path.
    Path(PathBuf),
}

/// What an output path names.
#[derive(Debug)]
pub enum Target {
    /// A regular file or none yet, at this resolved path (canonical folder, links followed):
    /// replaced by renaming a temporary file written beside it.
    Replace {
        /// The resolved path.
        path: PathBuf,
        /// The file there now (its mode and owner are kept).
        existing: Option<Metadata>,
    },
    /// Written into as it is.
    InPlace(Sink),
}

/// The folder of `path` (`.` for a bare name) and its last component.
fn split(path: &Path) -> Result<(PathBuf, OsString)> {
    let name = match path.components().next_back() {
        Some(Component::Normal(n)) => n.to_os_string(),
        _ => return Err(refuse(path, "not a file path")),
    };
    let dir = match path.parent().filter(|d| !d.as_os_str().is_empty()) {
        Some(d) => d.to_path_buf(),
        None => PathBuf::from("."),
    };
    Ok((dir, name))
}

/// The descriptor a folder of links to open files names: `N` in `/proc/<pid>/fd/N`,
/// `/proc/<pid>/task/<tid>/fd/N` or `/dev/fd/N`, with whether it is this process's own.
fn descriptor_link(dir: &Path, name: &std::ffi::OsStr) -> Option<(bool, Option<i32>)> {
    if dir.file_name()? != "fd" {
        return None;
    }
    let parts: Vec<_> = dir.components().collect();
    let own = if dir == Path::new("/dev/fd") {
        true
    } else if parts.len() >= 4 && parts[1].as_os_str() == "proc" {
        parts[2].as_os_str().to_str() == Some(&std::process::id().to_string())
    } else {
        return None;
    };
    Some((own, name.to_str().and_then(|n| n.parse().ok())))
}

/// What `path` names, for writing an output there (see the module documentation).
pub fn target(path: &Path) -> Result<Target> {
    if path.as_os_str() == "-" {
        return Ok(Target::InPlace(Sink::Stdout));
    }
    let mut current = path.to_path_buf();
    for _ in 0..=MAX_LINKS {
        let (dir, name) = split(&current)?;
        let dir = dir.canonicalize().map_err(|_| {
            refuse(
                path,
                format!("cannot write it: no folder {}", dir.display()),
            )
        })?;
        if let Some((own, fd)) = descriptor_link(&dir, &name) {
            return Ok(Target::InPlace(match (own, fd) {
                (true, Some(1)) => Sink::Stdout,
                (true, Some(2)) => Sink::Stderr,
                (true, Some(n)) => Sink::Descriptor(n),
                _ => Sink::Path(path.to_path_buf()),
            }));
        }
        let full = dir.join(&name);
        let meta = match fs::symlink_metadata(&full) {
            Ok(m) => m,
            Err(e) if e.kind() == io::ErrorKind::NotFound => {
                return Ok(Target::Replace {
                    path: full,
                    existing: None,
                })
            }
            Err(e) => return Err(failed(path, e)),
        };
        let kind = meta.file_type();
        if kind.is_symlink() {
            let link = fs::read_link(&full).map_err(|e| failed(path, e))?;
            current = dir.join(link);
        } else if kind.is_dir() {
            return Err(refuse(path, "is a folder, not a file"));
        } else if kind.is_file() {
            return Ok(Target::Replace {
                path: full,
                existing: Some(meta),
            });
        } else {
            return Ok(Target::InPlace(Sink::Path(full)));
        }
    }
    Err(refuse(path, "cannot write it: too many levels of links"))
}

/// What makes two paths one file: the resolved path and, on Unix, the device and inode.
#[derive(Debug, Clone)]
pub struct Identity {
    path: PathBuf,
    inode: Option<(u64, u64)>,
}

impl PartialEq for Identity {
    fn eq(&self, other: &Identity) -> bool {
        self.path == other.path || (self.inode.is_some() && self.inode == other.inode)
    }
}

impl Identity {
    fn of(path: PathBuf, existing: Option<&Metadata>) -> Identity {
        #[cfg(unix)]
        let inode = {
            use std::os::unix::fs::MetadataExt as _;
            existing.map(|m| (m.dev(), m.ino()))
        };
        #[cfg(not(unix))]
        let inode = {
            let _ = existing;
            None
        };
        Identity { path, inode }
    }
}

/// The identity of the file `path` names, for comparing inputs and outputs: `None` for what is
/// written in place (devices, FIFOs, standard output) and for a path whose folder is missing.
pub fn identity(path: &Path) -> Option<Identity> {
    match target(path).ok()? {
        Target::Replace { path, existing } => Some(Identity::of(path, existing.as_ref())),
        Target::InPlace(_) => None,
    }
}

/// Refuses outputs that are inputs of the run, or repeated, or folders, naming both paths (and
/// saying when they are one file under two names: the same device and inode).
pub fn check_distinct(outputs: &[&Path], inputs: &[&Path]) -> Result<()> {
    let inputs: Vec<(&Path, Identity)> = inputs
        .iter()
        .filter_map(|p| identity(p).map(|id| (*p, id)))
        .collect();
    // `out` (whose identity is `id`) and `other` (`its`), one file.
    let both = |out: &Path, id: &Identity, other: &Path, its: &Identity, as_what: &str| {
        let same = if out == other {
            ""
        } else if id.path == its.path {
            " (the same file)"
        } else {
            " (the same file under another name: the same device and inode)"
        };
        format!("{as_what} `{}`{same}", other.display())
    };
    let mut seen: Vec<(&Path, Identity)> = Vec::new();
    for out in outputs {
        let Target::Replace { path, existing } = target(out)? else {
            continue;
        };
        let id = Identity::of(path, existing.as_ref());
        if let Some((input, its)) = inputs.iter().find(|(_, i)| *i == id) {
            return Err(refuse(
                out,
                format!(
                    "refusing to write an output over an input of this run: {}",
                    both(out, &id, input, its, "it is the input")
                ),
            ));
        }
        if let Some((first, its)) = seen.iter().find(|(_, i)| *i == id) {
            return Err(refuse(
                out,
                format!(
                    "named as two outputs of this run: {}",
                    both(out, &id, first, its, "it is also the output")
                ),
            ));
        }
        seen.push((out, id));
    }
    Ok(())
}

/// A temporary file, known to the signal handler while it lives; removed when dropped (then
/// forgotten by the handler).
struct Temp {
    file: Option<NamedTempFile>,
    _known: super::cleanup::Registered,
}

impl Temp {
    /// A fresh temporary file in `dir` for the output `name`, with the mode `mode` (less the
    /// umask). The folder is first cleared of temporary files of killed runs.
    fn create(dir: &Path, name: &std::ffi::OsStr, mode: u32) -> io::Result<Temp> {
        sweep(dir);
        let name = name.to_string_lossy();
        // The target's name ends the temporary one (writers that look at the extension see the
        // target's); a long name is shortened to its extension, within the usual 255 bytes.
        let suffix = if name.len() <= 160 {
            format!("-{name}")
        } else {
            Path::new(&*name)
                .extension()
                .map(|e| format!(".{}", e.to_string_lossy()))
                .filter(|e| e.len() <= 32)
                .unwrap_or_default()
        };
        let prefix = format!("{TEMP_PREFIX}{}-", std::process::id());
        let mut b = tempfile::Builder::new();
        b.prefix(&prefix).suffix(&suffix).rand_bytes(6);
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt as _;
            b.permissions(fs::Permissions::from_mode(mode));
        }
        #[cfg(not(unix))]
        let _ = mode;
        let file = b.tempfile_in(dir)?;
        let registered = super::cleanup::register(file.path());
        Ok(Temp {
            file: Some(file),
            _known: registered,
        })
    }

    fn file(&self) -> &NamedTempFile {
        self.file.as_ref().expect("a live temporary file")
    }
}

impl Drop for Temp {
    fn drop(&mut self) {
        // Removed first, forgotten by the handler after (the field, dropped next).
        drop(self.file.take());
    }
}

/// Whether `pid` names a running process (on doubt, yes).
fn alive(pid: u32) -> bool {
    #[cfg(unix)]
    {
        let Ok(pid) = libc::pid_t::try_from(pid) else {
            return true;
        };
        if pid <= 0 {
            return true;
        }
        // SAFETY: signal 0 only checks that the process exists.
        if unsafe { libc::kill(pid, 0) } == 0 {
            return true;
        }
        io::Error::last_os_error().raw_os_error() != Some(libc::ESRCH)
    }
    #[cfg(not(unix))]
    {
        let _ = pid;
        true
    }
}

/// Whether `name` is a temporary file of an earlier kinecal version.
fn old_format(name: &str) -> bool {
    name.starts_with('.')
        && !name.starts_with(TEMP_PREFIX)
        && (name.ends_with(".kinecal-tmp")
            || name
                .rsplit_once(".kinecal-tmp.")
                .is_some_and(|(_, ext)| !ext.is_empty() && !ext.contains('.')))
}

/// Removes, once per folder and process, the temporary files that killed kinecal runs left in
/// `dir` (see the module documentation), with a note on standard error.
fn sweep(dir: &Path) {
    static SWEPT: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());
    {
        let mut swept = SWEPT.lock().unwrap_or_else(PoisonError::into_inner);
        if swept.iter().any(|d| d == dir) {
            return;
        }
        swept.push(dir.to_path_buf());
    }
    let Ok(entries) = fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(name) = name.to_str() else { continue };
        let stale = if let Some(rest) = name.strip_prefix(TEMP_PREFIX) {
            match rest.split('-').next().and_then(|p| p.parse::<u32>().ok()) {
                Some(pid) => (pid != std::process::id() && !alive(pid)).then_some(STALE_AFTER),
                None => None,
            }
        } else if old_format(name) {
            Some(OLD_FORMAT_STALE_AFTER)
        } else {
            None
        };
        let Some(after) = stale else { continue };
        // The entry's own metadata: a link is judged (and removed) as a link.
        let old = entry
            .metadata()
            .ok()
            .and_then(|m| m.modified().ok())
            .and_then(|t| t.elapsed().ok())
            .is_some_and(|age| age > after);
        if old && fs::remove_file(entry.path()).is_ok() {
            eprintln!(
                "note: removed {}, a temporary file left by a kinecal run that was stopped",
                entry.path().display()
            );
        }
    }
}

/// A regular output waiting to be renamed onto its target.
struct Replacement {
    shown: PathBuf,
    target: PathBuf,
    temp: Temp,
}

/// An output to write in place, its bytes kept until the commit.
struct InPlace {
    shown: PathBuf,
    sink: Sink,
    bytes: Vec<u8>,
}

/// The outputs of one run, written but not yet in place.
#[derive(Default)]
pub struct Staged {
    replace: Vec<Replacement>,
    in_place: Vec<InPlace>,
}

/// Gives the temporary file of an existing target that target's owner, group and mode.
fn keep_mode(file: &fs::File, existing: &Metadata) -> io::Result<()> {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt as _;
        let now = file.metadata()?;
        if (now.uid(), now.gid()) != (existing.uid(), existing.gid()) {
            // Only root may give a file away; a group the user is in works too. Otherwise the
            // new file is the user's, as any editor's would be.
            let _ = std::os::unix::fs::fchown(file, Some(existing.uid()), Some(existing.gid()))
                .or_else(|_| std::os::unix::fs::fchown(file, None, Some(existing.gid())));
        }
    }
    file.set_permissions(existing.permissions())
}

impl Staged {
    /// Nothing staged.
    pub fn new() -> Self {
        Staged::default()
    }

    /// Stages `contents` for `path`.
    pub fn text(&mut self, path: &Path, contents: &str) -> Result<()> {
        self.bytes(path, contents.as_bytes())
    }

    /// Stages `contents` for `path`.
    pub fn bytes(&mut self, path: &Path, contents: &[u8]) -> Result<()> {
        match target(path)? {
            Target::InPlace(sink) => {
                self.in_place.push(InPlace {
                    shown: path.to_path_buf(),
                    sink,
                    bytes: contents.to_vec(),
                });
                Ok(())
            }
            Target::Replace { path: to, existing } => {
                let temp = self.temp(path, &to, existing.as_ref())?;
                let mut file = temp.file().as_file();
                file.write_all(contents)
                    .and_then(|()| file.sync_data())
                    .map_err(|e| failed(path, e))?;
                self.replace.push(Replacement {
                    shown: path.to_path_buf(),
                    target: to,
                    temp,
                });
                Ok(())
            }
        }
    }

    /// Creates a fresh temporary file for `path` and lets `write` fill it by its path (for
    /// writers that open files themselves). For an output written in place, the temporary file
    /// is in the system's temporary folder and its bytes are kept for the commit.
    pub(crate) fn by_path<E: From<Error>>(
        &mut self,
        path: &Path,
        write: impl FnOnce(&Path) -> std::result::Result<(), E>,
    ) -> std::result::Result<(), E> {
        match target(path)? {
            Target::InPlace(sink) => {
                let (_, name) = split(path)?;
                let temp = Temp::create(&std::env::temp_dir(), &name, 0o600)
                    .map_err(|e| failed(path, e))?;
                write(temp.file().path())?;
                let mut bytes = Vec::new();
                temp.file()
                    .reopen()
                    .and_then(|mut f| f.read_to_end(&mut bytes))
                    .map_err(|e| failed(path, e))?;
                self.in_place.push(InPlace {
                    shown: path.to_path_buf(),
                    sink,
                    bytes,
                });
                Ok(())
            }
            Target::Replace { path: to, existing } => {
                let temp = self.temp(path, &to, existing.as_ref())?;
                write(temp.file().path())?;
                temp.file()
                    .as_file()
                    .sync_data()
                    .map_err(|e| failed(path, e))?;
                self.replace.push(Replacement {
                    shown: path.to_path_buf(),
                    target: to,
                    temp,
                });
                Ok(())
            }
        }
    }

    /// A temporary file beside the resolved target `to`, with the mode the target will have.
    fn temp(&self, shown: &Path, to: &Path, existing: Option<&Metadata>) -> Result<Temp> {
        let dir = to.parent().expect("resolved paths have a folder");
        let name = to.file_name().expect("resolved paths have a name");
        // A new file as any program creates one (the umask applies); an existing one's mode is
        // set below, once the file is private to its owner.
        let mode = if existing.is_some() { 0o600 } else { 0o666 };
        let temp = Temp::create(dir, name, mode).map_err(|e| failed(shown, e))?;
        if let Some(m) = existing {
            keep_mode(temp.file().as_file(), m).map_err(|e| failed(shown, e))?;
        }
        Ok(temp)
    }

    /// Puts every staged output in place: first the ones written in place (a failure there
    /// replaces nothing), then the renames, during which a signal waits. On a failure, the
    /// files not yet renamed are removed.
    pub fn commit(self) -> Result<()> {
        if let Some(r) = self.replace.iter().find(|r| r.target.is_dir()) {
            return Err(refuse(&r.shown, "cannot write it: it is a folder"));
        }
        for o in &self.in_place {
            write_in_place(&o.sink, &o.bytes).map_err(|e| failed(&o.shown, e))?;
        }
        let mut pending = self.replace.into_iter();
        let result = {
            // A signal now waits for the last rename.
            let _committing = super::cleanup::committing();
            let mut result = Ok(());
            for mut r in pending.by_ref() {
                let file = r.temp.file.take().expect("a live temporary file");
                // The handler forgets the file when `r` is dropped, after the rename.
                let done = file.persist(&r.target);
                if let Err(e) = done {
                    drop(e.file);
                    result = Err(failed(&r.shown, e.error));
                    break;
                }
            }
            result
        };
        // The rest are removed.
        drop(pending);
        result
    }
}

/// Writes `bytes` into `sink` (see the module documentation), a broken pipe being an error.
fn write_in_place(sink: &Sink, bytes: &[u8]) -> io::Result<()> {
    without_sigpipe(|| match sink {
        Sink::Stdout => {
            let mut out = io::stdout().lock();
            out.write_all(bytes)?;
            out.flush()
        }
        Sink::Stderr => {
            let mut err = io::stderr().lock();
            err.write_all(bytes)?;
            err.flush()
        }
        Sink::Descriptor(fd) => descriptor(*fd)?.write_all(bytes),
        Sink::Path(p) => fs::OpenOptions::new().write(true).open(p)?.write_all(bytes),
    })
}

/// A file of its own on this process's descriptor `fd` (closed when dropped, `fd` stays).
#[cfg(unix)]
fn descriptor(fd: i32) -> io::Result<fs::File> {
    use std::os::fd::{BorrowedFd, OwnedFd};
    // SAFETY: `fd` is checked to be open before it is borrowed for the duplication.
    if unsafe { libc::fcntl(fd, libc::F_GETFD) } == -1 {
        return Err(io::Error::last_os_error());
    }
    let owned: OwnedFd = unsafe { BorrowedFd::borrow_raw(fd) }.try_clone_to_owned()?;
    Ok(fs::File::from(owned))
}

#[cfg(not(unix))]
fn descriptor(_fd: i32) -> io::Result<fs::File> {
    Err(io::Error::new(
        io::ErrorKind::Unsupported,
        "descriptors are written only on Unix",
    ))
}

/// Runs `f` with SIGPIPE held back in this thread, so that a write into a pipe whose reader is
/// gone returns an error (the run fails, its temporary files removed) instead of ending the
/// process; a SIGPIPE raised meanwhile is taken off before the mask is restored.
#[cfg(unix)]
fn without_sigpipe<T>(f: impl FnOnce() -> io::Result<T>) -> io::Result<T> {
    // SAFETY: signal sets are initialised by sigemptyset before use; the thread's mask is
    // restored before returning.
    unsafe {
        let mut pipe: libc::sigset_t = std::mem::zeroed();
        libc::sigemptyset(&mut pipe);
        libc::sigaddset(&mut pipe, libc::SIGPIPE);
        let mut old: libc::sigset_t = std::mem::zeroed();
        libc::pthread_sigmask(libc::SIG_BLOCK, &pipe, &mut old);
        let result = f();
        let mut pending: libc::sigset_t = std::mem::zeroed();
        libc::sigemptyset(&mut pending);
        if libc::sigpending(&mut pending) == 0
            && libc::sigismember(&pending, libc::SIGPIPE) == 1
            && libc::sigismember(&old, libc::SIGPIPE) == 0
        {
            let mut sig = 0;
            libc::sigwait(&pipe, &mut sig);
        }
        libc::pthread_sigmask(libc::SIG_SETMASK, &old, std::ptr::null_mut());
        result
    }
}

#[cfg(not(unix))]
fn without_sigpipe<T>(f: impl FnOnce() -> io::Result<T>) -> io::Result<T> {
    f()
}

/// Writes one file (see the module documentation).
pub fn write_file(path: &Path, contents: &str) -> Result<()> {
    let mut s = Staged::new();
    s.text(path, contents)?;
    s.commit()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn earlier_temporary_names_are_recognised() {
        assert!(old_format(".out.toml.a1B2c3.kinecal-tmp.toml"));
        assert!(old_format(".out.a1B2c3.kinecal-tmp"));
        assert!(!old_format("out.toml"));
        assert!(!old_format(".kinecal-tmp-12-abcdef-out.toml"));
        assert!(!old_format(".x.kinecal-tmp.toml.bak"));
    }

    #[test]
    fn standard_output_and_descriptors_are_written_in_place() {
        assert!(matches!(
            target(Path::new("-")).unwrap(),
            Target::InPlace(Sink::Stdout)
        ));
        #[cfg(target_os = "linux")]
        {
            assert!(matches!(
                target(Path::new("/dev/stdout")).unwrap(),
                Target::InPlace(Sink::Stdout)
            ));
            assert!(matches!(
                target(Path::new("/dev/fd/2")).unwrap(),
                Target::InPlace(Sink::Stderr)
            ));
            assert!(matches!(
                target(Path::new("/dev/null")).unwrap(),
                Target::InPlace(Sink::Path(_))
            ));
        }
    }

    #[test]
    fn one_file_by_any_name() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        fs::write(d.join("r.json"), "x").unwrap();
        let a = identity(&d.join("r.json")).unwrap();
        assert_eq!(a, identity(&d.join("./r.json")).unwrap());
        #[cfg(unix)]
        {
            fs::hard_link(d.join("r.json"), d.join("h.json")).unwrap();
            assert_eq!(a, identity(&d.join("h.json")).unwrap());
        }
        assert_ne!(a, identity(&d.join("other.json")).unwrap());
    }
}
