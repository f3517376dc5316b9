//! The one way the host tools write files: atomically, and all or none.
//!
//! Every output of every command goes through [`Outputs`]:
//!
//! 1. **Stage.** Each output is written in full to a temporary file in its
//!    target's directory (so the final rename never crosses a file system),
//!    flushed to disk (`fsync`) and given its final permissions: mode 0644
//!    for a new file (a temporary file is created private, 0600), the
//!    current mode for a regular file that is replaced.
//! 2. **Check.** A target that exists and is not a regular file (a
//!    directory, a FIFO, a device, a socket) is refused with an error naming
//!    it: renaming over it would replace the special file with a regular
//!    one. A symbolic link is followed: the file it points to is replaced and
//!    the link kept.
//! 3. **Commit.** Only when every output is staged and every target checked
//!    are the temporary files renamed over their targets. Should a rename
//!    still fail, the targets already replaced are put back (each replaced
//!    file was kept under a hard link until the end), so a failed command
//!    leaves every existing target as it was and no temporary file behind.
//!
//! [`write_atomic`] is the one-output case.
//!
//! A command stopped by a signal (Ctrl-C, `kill`) runs no destructor, so
//! every live [`Outputs`] also lists its temporary files and the
//! directories it made in one registry, which [`remove_staged`] empties
//! from the signal handler ([`crate::interrupt`]); a commit holds the
//! registry while it renames, so a signal waits for it to finish.
//!
//! An output never replaces one of the command's own inputs: the readers
//! note each file they open ([`note_input`]) and staging refuses a target
//! that is one of them (the same file by any path), once `main` has asked
//! for it ([`track_inputs`]; library callers, the tests among them, run
//! several commands' steps in one process and are not tracked).
//!
//! What a command prints on standard output goes through [`stdout!`](crate::stdout) and
//! [`stdoutln!`](crate::stdoutln): a reader that goes away early (`host-sim
//! residual ... | head`) ends the printing, not the command, so the files
//! it was asked for are still written and it exits as it would have.
//!
//! ```
//! use host_sim::output::Outputs;
//! let dir = tempfile::tempdir().unwrap();
//! let mut out = Outputs::new();
//! out.bytes(&dir.path().join("a.txt"), b"a\n").unwrap();
//! // A target that is a directory is refused: nothing is written.
//! assert!(out.bytes(dir.path(), b"b\n").is_err());
//! drop(out);
//! assert!(!dir.path().join("a.txt").exists());
//! ```

use std::fmt;
use std::fs;
use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Mutex;

/// An output that could not be written: which target, and why.
#[derive(Debug)]
pub struct OutputError {
    /// The target as the caller named it.
    pub path: PathBuf,
    /// What went wrong.
    pub error: io::Error,
}

impl OutputError {
    fn new(path: &Path, error: io::Error) -> Self {
        Self {
            path: path.to_owned(),
            error,
        }
    }

    fn refused(path: &Path, what: &str) -> Self {
        Self::new(
            path,
            io::Error::new(
                io::ErrorKind::AlreadyExists,
                format!("exists and is {what}, not a regular file: not replacing it"),
            ),
        )
    }
}

impl fmt::Display for OutputError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.path.display(), self.error)
    }
}

/// The I/O error is part of the message (not a `source`), so that an error
/// chain prints it once.
impl std::error::Error for OutputError {}

/// The files this process has read, once [`track_inputs`] has been
/// called: each as its canonical path and, on Unix, its device and inode
/// (a hard link is the same file by another path).
static INPUTS: Mutex<Option<Vec<FileId>>> = Mutex::new(None);

/// One file, however it is named.
#[derive(Clone, Debug, PartialEq)]
struct FileId {
    canonical: PathBuf,
    #[cfg(unix)]
    inode: (u64, u64),
}

impl FileId {
    /// `None` where `path` does not name an existing file.
    fn of(path: &Path) -> Option<Self> {
        let canonical = fs::canonicalize(path).ok()?;
        #[cfg(unix)]
        let inode = {
            use std::os::unix::fs::MetadataExt;
            let m = fs::metadata(&canonical).ok()?;
            (m.dev(), m.ino())
        };
        Some(Self {
            canonical,
            #[cfg(unix)]
            inode,
        })
    }

    fn same_file(&self, other: &Self) -> bool {
        #[cfg(unix)]
        if self.inode == other.inode {
            return true;
        }
        self.canonical == other.canonical
    }
}

/// From now on, note the files the readers open and refuse to stage an
/// output over any of them (`main` calls it once, before the command).
pub fn track_inputs() {
    let mut inputs = INPUTS
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    inputs.get_or_insert_with(Vec::new);
}

/// Note that the command reads `path` (every reader of the project's files
/// calls it before opening one); nothing happens unless [`track_inputs`]
/// was called, or where `path` is not an existing file (standard input).
pub fn note_input(path: &Path) {
    let mut inputs = INPUTS
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    if let Some(v) = inputs.as_mut() {
        if let Some(id) = FileId::of(path) {
            if !v.iter().any(|x| x.same_file(&id)) {
                v.push(id);
            }
        }
    }
}

/// An error if `target` is a file the command has read.
fn refuse_input(named: &Path, target: &Path) -> Result<(), OutputError> {
    let inputs = INPUTS
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    let Some(v) = inputs.as_ref() else {
        return Ok(());
    };
    match FileId::of(target) {
        Some(id) if v.iter().any(|x| x.same_file(&id)) => Err(OutputError::new(
            named,
            io::Error::new(
                io::ErrorKind::InvalidInput,
                "is also an input of this command: writing it would replace what was read; \
                 name another output",
            ),
        )),
        _ => Ok(()),
    }
}

/// Every temporary file and every directory made that a live [`Outputs`]
/// holds on disk beside its targets, for [`remove_staged`].
static LIVE: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

/// The registry, whatever a panicking holder left in it.
fn live() -> std::sync::MutexGuard<'static, Vec<PathBuf>> {
    LIVE.lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// Take `paths` out of the registry `live`.
fn forget<'a>(live: &mut Vec<PathBuf>, paths: impl IntoIterator<Item = &'a Path>) {
    for p in paths {
        if let Some(i) = live.iter().rposition(|q| q == p) {
            live.swap_remove(i);
        }
    }
}

/// Remove every temporary file a live [`Outputs`] staged and every
/// directory one made (those left empty), for a process about to exit on
/// a signal. Returns the registry held: no commit starts while the caller
/// holds it, so it exits holding it.
pub fn remove_staged() -> std::sync::MutexGuard<'static, Vec<PathBuf>> {
    let mut held = live();
    // Files first, then directories deepest first (made after their
    // parents, so later in the list).
    for p in held.iter().filter(|p| !p.is_dir()) {
        let _ = fs::remove_file(p);
    }
    for p in held.iter().rev().filter(|p| p.is_dir()) {
        let _ = fs::remove_dir(p);
    }
    held.clear();
    held
}

/// A staged output: the complete temporary file and where it goes.
struct Staged {
    /// The path the caller gave (for messages and the result).
    named: PathBuf,
    /// The file to replace (`named` with a symbolic link followed).
    target: PathBuf,
    tmp: tempfile::NamedTempFile,
}

/// Outputs of one command, written all or none: stage each one, then
/// [`Outputs::commit`]. Dropping an `Outputs` without committing removes
/// every temporary file and every directory it created, and touches no
/// target.
#[derive(Default)]
pub struct Outputs {
    staged: Vec<Staged>,
    /// Directories [`Outputs::create_dir`] created, parents first.
    made_dirs: Vec<PathBuf>,
}

impl Drop for Outputs {
    fn drop(&mut self) {
        // The temporary files first (they sit in the directories), then
        // the directories this value created, deepest first; one that is
        // not empty (something else was written there) stays.
        let mut live = live();
        let temps: Vec<PathBuf> = self
            .staged
            .iter()
            .map(|s| s.tmp.path().to_owned())
            .collect();
        self.staged.clear();
        for d in self.made_dirs.iter().rev() {
            let _ = fs::remove_dir(d);
        }
        forget(&mut live, temps.iter().map(PathBuf::as_path));
        forget(&mut live, self.made_dirs.iter().map(PathBuf::as_path));
    }
}

/// What a target is, if it exists and is not a regular file.
fn not_regular(meta: &fs::Metadata) -> Option<&'static str> {
    let t = meta.file_type();
    if t.is_file() {
        return None;
    }
    if t.is_dir() {
        return Some("a directory");
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if t.is_fifo() {
            return Some("a FIFO");
        }
        if t.is_char_device() {
            return Some("a character device");
        }
        if t.is_block_device() {
            return Some("a block device");
        }
        if t.is_socket() {
            return Some("a socket");
        }
    }
    Some("a special file")
}

/// The file `path` names (a symbolic link followed) and its metadata if it
/// exists; an error if it exists and is not a regular file.
fn resolve(path: &Path) -> Result<(PathBuf, Option<fs::Metadata>), OutputError> {
    let err = |e| OutputError::new(path, e);
    let target = match fs::symlink_metadata(path) {
        Ok(m) if m.file_type().is_symlink() => fs::canonicalize(path).map_err(|e| {
            err(io::Error::new(
                e.kind(),
                format!("a symbolic link that cannot be followed: {e}"),
            ))
        })?,
        Ok(_) => path.to_owned(),
        Err(e) if e.kind() == io::ErrorKind::NotFound => return Ok((path.to_owned(), None)),
        Err(e) => return Err(err(e)),
    };
    match fs::metadata(&target) {
        Ok(m) => match not_regular(&m) {
            Some(what) => Err(OutputError::refused(path, what)),
            // A file whose owner took its write permission away (a
            // measured run kept safe) is not replaced by a rename, which
            // the directory's permission alone would allow.
            None if m.permissions().readonly() => Err(OutputError::new(
                path,
                io::Error::new(
                    io::ErrorKind::PermissionDenied,
                    "exists and is read-only: not replacing it (make it writable, or \
                     choose another name)",
                ),
            )),
            None => Ok((target, Some(m))),
        },
        Err(e) if e.kind() == io::ErrorKind::NotFound => Ok((target, None)),
        Err(e) => Err(err(e)),
    }
}

fn parent_dir(path: &Path) -> &Path {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    }
}

#[cfg(unix)]
fn new_file_permissions() -> Option<fs::Permissions> {
    use std::os::unix::fs::PermissionsExt;
    Some(fs::Permissions::from_mode(0o644))
}

#[cfg(not(unix))]
fn new_file_permissions() -> Option<fs::Permissions> {
    None
}

impl Outputs {
    /// No output staged yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// Number of outputs staged.
    pub fn len(&self) -> usize {
        self.staged.len()
    }

    /// No output staged.
    pub fn is_empty(&self) -> bool {
        self.staged.is_empty()
    }

    /// Create the directory `dir` (and its missing parents) for outputs to
    /// be staged in. The directories created here are removed again if the
    /// outputs are dropped without a successful commit.
    ///
    /// # Errors
    /// `dir` cannot be created (a file in the way, no permission).
    pub fn create_dir(&mut self, dir: &Path) -> Result<(), OutputError> {
        let missing: Vec<PathBuf> = dir
            .ancestors()
            .take_while(|a| !a.as_os_str().is_empty() && !a.exists())
            .map(Path::to_owned)
            .collect();
        let mut live = live();
        ensure_dir(dir)?;
        live.extend(missing.iter().rev().cloned());
        self.made_dirs.extend(missing.into_iter().rev());
        Ok(())
    }

    /// Stage `bytes` as the content of `path`.
    ///
    /// # Errors
    /// As [`Outputs::with_writer`].
    pub fn bytes(&mut self, path: &Path, bytes: &[u8]) -> Result<(), OutputError> {
        self.with_writer(path, |w| w.write_all(bytes))
    }

    /// Stage the content `write` produces as the content of `path`.
    ///
    /// # Errors
    /// `path` exists and is not a regular file, its directory does not
    /// exist or is not writable, `path` is already staged, or `write` fails;
    /// nothing is staged then.
    pub fn with_writer(
        &mut self,
        path: &Path,
        write: impl FnOnce(&mut dyn Write) -> io::Result<()>,
    ) -> Result<(), OutputError> {
        self.with_file(path, |file| {
            let mut w = io::BufWriter::new(file);
            write(&mut w)?;
            w.flush()
        })
    }

    /// Stage a file that `write` creates at the path it is given (for
    /// writers that insist on opening the file themselves, such as an image
    /// encoder). The path is a temporary file next to `path`.
    ///
    /// # Errors
    /// As [`Outputs::with_writer`].
    pub fn with_temp_path(
        &mut self,
        path: &Path,
        write: impl FnOnce(&Path) -> io::Result<()>,
    ) -> Result<(), OutputError> {
        self.stage(path, |tmp| write(tmp.path()))
    }

    fn with_file(
        &mut self,
        path: &Path,
        write: impl FnOnce(&fs::File) -> io::Result<()>,
    ) -> Result<(), OutputError> {
        self.stage(path, |tmp| write(tmp.as_file()))
    }

    fn stage(
        &mut self,
        path: &Path,
        write: impl FnOnce(&tempfile::NamedTempFile) -> io::Result<()>,
    ) -> Result<(), OutputError> {
        let err = |e| OutputError::new(path, e);
        let (target, meta) = resolve(path)?;
        refuse_input(path, &target)?;
        if self.staged.iter().any(|s| s.target == target) {
            return Err(err(io::Error::new(
                io::ErrorKind::InvalidInput,
                "named twice as an output of the same command",
            )));
        }
        let tmp = {
            let mut live = live();
            let tmp = temp_beside(path, &target)?;
            live.push(tmp.path().to_owned());
            tmp
        };
        let written = (|| {
            write(&tmp)?;
            // The writer may have replaced the file at the temporary path
            // (an image encoder creates its file): reopen it to be sure
            // what is synced is what will be renamed.
            let file = fs::OpenOptions::new().write(true).open(tmp.path())?;
            file.sync_all()?;
            let perms = match meta {
                Some(m) => Some(m.permissions()),
                None => new_file_permissions(),
            };
            if let Some(p) = perms {
                file.set_permissions(p)?;
            }
            Ok(())
        })();
        if let Err(e) = written {
            let mut live = live();
            let path = tmp.path().to_owned();
            drop(tmp);
            forget(&mut live, [path.as_path()]);
            return Err(err(e));
        }
        self.staged.push(Staged {
            named: path.to_owned(),
            target,
            tmp,
        });
        Ok(())
    }

    /// Take over the outputs `other` staged (e.g. on another thread).
    ///
    /// # Errors
    /// A target staged in both; nothing is taken over then.
    pub fn append(&mut self, mut other: Outputs) -> Result<(), OutputError> {
        if let Some(s) = other
            .staged
            .iter()
            .find(|s| self.staged.iter().any(|t| t.target == s.target))
        {
            return Err(OutputError::new(
                &s.named,
                io::Error::new(
                    io::ErrorKind::InvalidInput,
                    "named twice as an output of the same command",
                ),
            ));
        }
        self.staged.extend(std::mem::take(&mut other.staged));
        self.made_dirs.extend(std::mem::take(&mut other.made_dirs));
        Ok(())
    }

    /// Rename every staged file over its target; returns the targets as
    /// named, in staging order.
    ///
    /// # Errors
    /// A target that became something other than a regular file since it
    /// was staged, or a failed rename: every target is then as it was before
    /// the call, and the temporary files are removed.
    pub fn commit(mut self) -> Result<Vec<PathBuf>, OutputError> {
        let staged = std::mem::take(&mut self.staged);
        // Held to the end: a signal's cleanup waits for the renames (and
        // the backups' removal) to finish. Every staged file is renamed or
        // removed by then.
        let mut live = live();
        let temps: Vec<PathBuf> = staged.iter().map(|s| s.tmp.path().to_owned()).collect();
        let result = Self::rename_all(staged);
        forget(&mut live, temps.iter().map(PathBuf::as_path));
        if result.is_ok() {
            // The directories now hold the outputs: they stay.
            forget(&mut live, self.made_dirs.iter().map(PathBuf::as_path));
            self.made_dirs.clear();
        }
        result
    }

    /// [`Outputs::commit`]'s renames, all or none.
    fn rename_all(staged: Vec<Staged>) -> Result<Vec<PathBuf>, OutputError> {
        // Check every target again (it may have changed while the command
        // worked) before the first rename.
        for s in &staged {
            if let Ok(m) = fs::symlink_metadata(&s.target) {
                if let Some(what) = not_regular(&m) {
                    return Err(OutputError::refused(&s.named, what));
                }
            }
            refuse_input(&s.named, &s.target)?;
        }
        // Keep every file about to be replaced under a hard link, to put it
        // back if a later rename fails.
        let mut backups: Vec<Option<tempfile::TempPath>> = Vec::with_capacity(staged.len());
        for s in &staged {
            let backup = if s.target.exists() {
                tempfile::Builder::new()
                    .prefix(".host-sim-old-")
                    .make_in(parent_dir(&s.target), |p| fs::hard_link(&s.target, p))
                    .ok()
                    .map(tempfile::NamedTempFile::into_temp_path)
            } else {
                None
            };
            backups.push(backup);
        }
        let mut done: Vec<(PathBuf, Option<tempfile::TempPath>)> = Vec::new();
        let mut written = Vec::with_capacity(staged.len());
        for (s, backup) in staged.into_iter().zip(backups) {
            if let Err(e) = s.tmp.persist(&s.target) {
                // Put back what was replaced, remove what was created.
                for (target, backup) in done.into_iter().rev() {
                    let _ = match backup {
                        Some(b) => b.persist(&target).map_err(|e| e.error),
                        None => fs::remove_file(&target),
                    };
                }
                return Err(OutputError::new(&s.named, e.error));
            }
            done.push((s.target.clone(), backup));
            written.push(s.named);
        }
        // The backups (dropped here) are removed; the directories' entries
        // are made durable.
        let mut dirs: Vec<PathBuf> = done.iter().map(|(t, _)| parent_dir(t).to_owned()).collect();
        drop(done);
        dirs.sort();
        dirs.dedup();
        for d in dirs {
            if let Ok(f) = fs::File::open(&d) {
                let _ = f.sync_all();
            }
        }
        Ok(written)
    }
}

/// Create the directory `dir` and its missing parents, for a command's
/// output directory. A file (or anything not a directory) already at `dir`
/// is refused with an error saying so, not the system's "File exists".
///
/// # Errors
/// Something other than a directory at `dir`, or it cannot be created.
pub fn ensure_dir(dir: &Path) -> Result<(), OutputError> {
    check_dir_target(dir)?;
    fs::create_dir_all(dir).map_err(|e| OutputError::new(dir, e))
}

/// Refuse an output directory that is already something else, before a
/// long command does its work (the report, the undeclared-effect
/// programme): the error comes in a second, not after minutes.
///
/// # Errors
/// Something other than a directory at `dir`.
pub fn check_dir_target(dir: &Path) -> Result<(), OutputError> {
    if dir.exists() && !dir.is_dir() {
        return Err(OutputError::new(
            dir,
            io::Error::new(
                io::ErrorKind::AlreadyExists,
                "exists and is not a directory: give a directory for the outputs",
            ),
        ));
    }
    Ok(())
}

/// Refuse an output file that cannot be written, before a command that
/// cannot be repeated (a rig's run) does its work: `path` exists and is not
/// a regular file, is one of the command's inputs, or its directory does
/// not take a new file (it is missing, not a directory, not writable). A
/// probe file is created there and removed again.
///
/// # Errors
/// The first of those found, naming `path`.
pub fn check_file_target(path: &Path) -> Result<(), OutputError> {
    let (target, _) = resolve(path)?;
    refuse_input(path, &target)?;
    temp_beside(path, &target).map(drop)
}

/// A new temporary file in `target`'s directory (so the final rename never
/// crosses a file system), its name ending with the target's: an encoder
/// that picks the format by extension sees the target's. Errors name
/// `named`, the path as the caller gave it.
fn temp_beside(named: &Path, target: &Path) -> Result<tempfile::NamedTempFile, OutputError> {
    let dir = parent_dir(target);
    let suffix = target
        .file_name()
        .map(|n| format!(".{}", n.to_string_lossy()))
        .unwrap_or_default();
    tempfile::Builder::new()
        .prefix(".host-sim-")
        .suffix(&suffix)
        .tempfile_in(dir)
        .map_err(|e| {
            OutputError::new(
                named,
                io::Error::new(
                    e.kind(),
                    format!("cannot create a temporary file in {}: {e}", dir.display()),
                ),
            )
        })
}

/// Write `bytes` to `path` atomically (see the module documentation).
///
/// # Errors
/// As [`Outputs::with_writer`] and [`Outputs::commit`]; the target is then
/// untouched.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), OutputError> {
    let mut out = Outputs::new();
    out.bytes(path, bytes)?;
    out.commit().map(drop)
}

/// Set by the first write to standard output that failed: the reader has
/// gone away (a closed pipe) or the file behind it cannot take more.
static STDOUT_CLOSED: AtomicBool = AtomicBool::new(false);

/// Print `args` on standard output, flushed. Once a write has failed
/// nothing more is printed, and nothing panics: `println!` would panic on
/// the closed pipe of `host-sim ... | head` before the command wrote its
/// files. Through [`stdout!`](crate::stdout) and [`stdoutln!`](crate::stdoutln).
pub fn print_stdout(args: fmt::Arguments<'_>) {
    if STDOUT_CLOSED.load(Ordering::Relaxed) {
        return;
    }
    let mut out = io::stdout().lock();
    if out.write_fmt(args).and_then(|()| out.flush()).is_err() {
        STDOUT_CLOSED.store(true, Ordering::Relaxed);
    }
}

/// `print!` for the commands' standard output, which a closed pipe does
/// not stop ([`print_stdout`]).
#[macro_export]
macro_rules! stdout {
    ($($arg:tt)*) => {
        $crate::output::print_stdout(format_args!($($arg)*))
    };
}

/// `println!` for the commands' standard output, which a closed pipe does
/// not stop ([`print_stdout`]).
#[macro_export]
macro_rules! stdoutln {
    ($($arg:tt)*) => {
        $crate::output::print_stdout(format_args!("{}\n", format_args!($($arg)*)))
    };
}

#[cfg(test)]
mod tests {
    use super::*;

    fn entries(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    #[cfg(unix)]
    fn mode(p: &Path) -> u32 {
        use std::os::unix::fs::PermissionsExt;
        fs::metadata(p).unwrap().permissions().mode() & 0o777
    }

    #[test]
    fn directories_created_for_outputs_go_with_them_unless_committed() {
        let dir = tempfile::tempdir().unwrap();
        let sub = dir.path().join("a").join("b");
        // Dropped without a commit: the file and both new directories go.
        let mut out = Outputs::new();
        out.create_dir(&sub).unwrap();
        out.bytes(&sub.join("x.txt"), b"x\n").unwrap();
        drop(out);
        assert!(entries(dir.path()).is_empty());
        // A failed commit (a target that became a directory) too.
        let mut out = Outputs::new();
        out.create_dir(&sub).unwrap();
        out.bytes(&sub.join("x.txt"), b"x\n").unwrap();
        let blocked = dir.path().join("y.txt");
        out.bytes(&blocked, b"y\n").unwrap();
        fs::create_dir(&blocked).unwrap();
        assert!(out.commit().is_err());
        assert_eq!(entries(dir.path()), ["y.txt"]);
        fs::remove_dir(&blocked).unwrap();
        // Committed: they stay, with the file; a directory that already
        // existed is never removed.
        let mut out = Outputs::new();
        out.create_dir(&sub).unwrap();
        out.bytes(&sub.join("x.txt"), b"x\n").unwrap();
        out.commit().unwrap();
        assert_eq!(entries(&sub), ["x.txt"]);
        let mut out = Outputs::new();
        out.create_dir(&sub).unwrap();
        drop(out);
        assert_eq!(entries(&sub), ["x.txt"]);
    }

    #[cfg(unix)]
    #[test]
    fn new_files_are_0644_and_replaced_files_keep_their_mode() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let new = dir.path().join("new.txt");
        write_atomic(&new, b"new\n").unwrap();
        assert_eq!(mode(&new), 0o644);
        assert_eq!(fs::read(&new).unwrap(), b"new\n");
        let old = dir.path().join("old.txt");
        fs::write(&old, "old\n").unwrap();
        fs::set_permissions(&old, fs::Permissions::from_mode(0o640)).unwrap();
        write_atomic(&old, b"replaced\n").unwrap();
        assert_eq!(mode(&old), 0o640);
        assert_eq!(fs::read(&old).unwrap(), b"replaced\n");
        assert_eq!(entries(dir.path()), ["new.txt", "old.txt"]);
    }

    #[cfg(unix)]
    #[test]
    fn a_read_only_file_is_not_replaced() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let kept = dir.path().join("run.csv");
        fs::write(&kept, "measured\n").unwrap();
        fs::set_permissions(&kept, fs::Permissions::from_mode(0o444)).unwrap();
        let e = write_atomic(&kept, b"replaced\n").unwrap_err();
        assert!(
            e.to_string().contains("run.csv: exists and is read-only"),
            "{e}"
        );
        let e = check_file_target(&kept).unwrap_err();
        assert!(e.to_string().contains("read-only"), "{e}");
        assert_eq!(fs::read(&kept).unwrap(), b"measured\n");
        assert_eq!(mode(&kept), 0o444);
        assert_eq!(entries(dir.path()), ["run.csv"]);
    }

    #[cfg(unix)]
    #[test]
    fn fifos_devices_and_directories_are_refused_and_left_alone() {
        let dir = tempfile::tempdir().unwrap();
        let fifo = dir.path().join("pipe");
        let status = std::process::Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .unwrap();
        assert!(status.success());
        let sub = dir.path().join("sub");
        fs::create_dir(&sub).unwrap();
        for (path, what) in [
            (fifo.as_path(), "a FIFO"),
            (sub.as_path(), "a directory"),
            (Path::new("/dev/null"), "a character device"),
        ] {
            let e = write_atomic(path, b"x").unwrap_err().to_string();
            assert!(e.contains(what) && e.contains("not replacing"), "{e}");
            assert!(e.starts_with(&path.display().to_string()), "{e}");
        }
        use std::os::unix::fs::FileTypeExt;
        assert!(fs::metadata(&fifo).unwrap().file_type().is_fifo());
        assert!(fs::metadata("/dev/null")
            .unwrap()
            .file_type()
            .is_char_device());
        assert_eq!(entries(dir.path()), ["pipe", "sub"]);
    }

    #[cfg(unix)]
    #[test]
    fn a_symbolic_link_is_followed_and_kept() {
        let dir = tempfile::tempdir().unwrap();
        let real = dir.path().join("real.toml");
        fs::write(&real, "old").unwrap();
        let link = dir.path().join("link.toml");
        std::os::unix::fs::symlink(&real, &link).unwrap();
        write_atomic(&link, b"new").unwrap();
        assert!(fs::symlink_metadata(&link)
            .unwrap()
            .file_type()
            .is_symlink());
        assert_eq!(fs::read(&real).unwrap(), b"new");
    }

    #[test]
    fn a_failed_stage_writes_none_of_the_outputs() {
        let dir = tempfile::tempdir().unwrap();
        let a = dir.path().join("a.toml");
        fs::write(&a, "old").unwrap();
        let mut out = Outputs::new();
        out.bytes(&a, b"new").unwrap();
        let missing = dir.path().join("nodir").join("x.json");
        let e = out.bytes(&missing, b"{}").unwrap_err().to_string();
        assert!(e.starts_with(&missing.display().to_string()), "{e}");
        drop(out);
        assert_eq!(fs::read(&a).unwrap(), b"old");
        assert_eq!(entries(dir.path()), ["a.toml"]);
    }

    #[test]
    fn a_target_that_changed_after_staging_is_refused_before_any_rename() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b) = (dir.path().join("a.txt"), dir.path().join("b.txt"));
        fs::write(&a, "old a").unwrap();
        let mut out = Outputs::new();
        out.bytes(&a, b"new a").unwrap();
        out.bytes(&b, b"new b").unwrap();
        fs::create_dir(&b).unwrap();
        let e = out.commit().unwrap_err().to_string();
        assert!(e.contains("a directory"), "{e}");
        assert_eq!(fs::read(&a).unwrap(), b"old a");
        assert_eq!(entries(dir.path()), ["a.txt", "b.txt"]);
    }

    #[test]
    fn a_failed_rename_puts_back_every_target_already_replaced() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b, c) = (
            dir.path().join("a.txt"),
            dir.path().join("b.txt"),
            dir.path().join("c.txt"),
        );
        fs::write(&a, "old a").unwrap();
        let mut out = Outputs::new();
        out.bytes(&a, b"new a").unwrap();
        out.bytes(&b, b"new b").unwrap();
        out.bytes(&c, b"new c").unwrap();
        // c's temporary file disappears after staging: its rename fails
        // after a's and b's.
        let tmp_c = fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().path())
            .find(|p| fs::read(p).is_ok_and(|t| t == b"new c"))
            .unwrap();
        fs::remove_file(tmp_c).unwrap();
        let e = out.commit().unwrap_err().to_string();
        assert!(e.starts_with(&c.display().to_string()), "{e}");
        assert_eq!(fs::read(&a).unwrap(), b"old a");
        assert_eq!(entries(dir.path()), ["a.txt"]);
    }

    #[test]
    fn a_writer_error_stages_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let a = dir.path().join("a.csv");
        let mut out = Outputs::new();
        let e = out
            .with_writer(&a, |_| Err(io::Error::other("disk full")))
            .unwrap_err();
        assert!(e.to_string().ends_with("disk full"), "{e}");
        assert!(out.is_empty());
        drop(out);
        assert!(entries(dir.path()).is_empty());
    }
}
