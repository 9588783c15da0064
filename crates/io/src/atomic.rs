//! Atomic output: a file appears complete or not at all, and never replaces an input.
//!
//! A crash or a full disk in the middle of writing must never leave a half-written take where
//! a studio expects a good one, nor destroy the previous version. Every writer of this crate
//! writes to a temporary file in the destination folder (same file system, so the rename is
//! atomic), flushes it to disk, then renames it over the destination.
//!
//! Two process-wide registries make this hold for a whole program run, not one call:
//! - **Protected files** ([`protect`]): the inputs of the run. A destination that is the same
//!   file as a protected one, by identity (device and inode on Unix, so `d/t.c3d`, `./d/t.c3d`,
//!   `$PWD/d/t.c3d`, `d/../d/t.c3d`, a symbolic link and a hard link all count), is refused.
//!   Programs check their outputs against their inputs before doing any work; this registry is
//!   the net under those checks, so a path spelling nobody thought of still cannot destroy data.
//! - **Unfinished temporaries** ([`remove_unfinished`]): a signal handler calls it so that
//!   `SIGINT`/`SIGTERM` during a write leaves no `.locap-*.tmp` behind (a write that fails
//!   removes its own temporary; `SIGKILL` cannot be caught by any program).

use crate::{Error, Result};
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// The identity of an existing file, independent of how its path is spelled.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct FileId(Identity);

#[cfg(unix)]
type Identity = (u64, u64);
#[cfg(not(unix))]
type Identity = PathBuf;

impl FileId {
    /// The identity of the file `path` names (following links), or `None` if it does not exist.
    pub fn of(path: &Path) -> Option<FileId> {
        #[cfg(unix)]
        {
            use std::os::unix::fs::MetadataExt;
            let meta = std::fs::metadata(path).ok()?;
            Some(FileId((meta.dev(), meta.ino())))
        }
        #[cfg(not(unix))]
        {
            std::fs::canonicalize(path).ok().map(FileId)
        }
    }
}

/// True if `a` and `b` name the same existing file, however the paths are spelled.
pub fn same_file(a: &Path, b: &Path) -> bool {
    match (FileId::of(a), FileId::of(b)) {
        (Some(x), Some(y)) => x == y,
        _ => false,
    }
}

static PROTECTED: Mutex<Vec<(FileId, PathBuf)>> = Mutex::new(Vec::new());
static UNFINISHED: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

/// Marks `path` as an input of this run: no writer of this crate will replace it. A path
/// that does not exist (yet) is ignored.
pub fn protect(path: &Path) {
    if let Some(id) = FileId::of(path) {
        let mut protected = PROTECTED.lock().unwrap_or_else(|e| e.into_inner());
        if !protected.iter().any(|(known, _)| *known == id) {
            protected.push((id, path.to_path_buf()));
        }
    }
}

/// The protected input that `path` is (by identity), if any, as it was first named.
pub fn protected_input(path: &Path) -> Option<PathBuf> {
    let id = FileId::of(path)?;
    let protected = PROTECTED.lock().unwrap_or_else(|e| e.into_inner());
    protected.iter().find(|(known, _)| *known == id).map(|(_, name)| name.clone())
}

/// Deletes every temporary file a write in progress has open. For signal handlers: the writes
/// themselves then fail, and the program is expected to exit.
pub fn remove_unfinished() {
    let unfinished = UNFINISHED.lock().unwrap_or_else(|e| e.into_inner());
    for path in unfinished.iter() {
        let _ = std::fs::remove_file(path);
    }
}

/// Keeps a temporary's path in [`UNFINISHED`] for as long as the write runs.
struct Unfinished(PathBuf);

impl Unfinished {
    fn register(path: &Path) -> Unfinished {
        UNFINISHED.lock().unwrap_or_else(|e| e.into_inner()).push(path.to_path_buf());
        Unfinished(path.to_path_buf())
    }
}

impl Drop for Unfinished {
    fn drop(&mut self) {
        let mut unfinished = UNFINISHED.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(i) = unfinished.iter().position(|p| *p == self.0) {
            unfinished.swap_remove(i);
        }
    }
}

fn refuse_input(path: &Path) -> Result<()> {
    match protected_input(path) {
        Some(input) => {
            Err(Error::Unwritable(format!("it is the input {}; locap never overwrites its input", input.display()))
                .in_file(path))
        }
        None => Ok(()),
    }
}

/// Writes a file atomically: `write` fills a buffered temporary file, which replaces `path`
/// only if `write` and the flush succeed, and only if `path` is not a [`protect`]ed input.
pub fn write_atomically(path: &Path, write: impl FnOnce(&mut dyn Write) -> Result<()>) -> Result<()> {
    refuse_input(path)?;
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let tmp = tempfile::Builder::new()
        .prefix(".locap-")
        .suffix(".tmp")
        .tempfile_in(dir)
        .map_err(|e| Error::from(e).in_file(path))?;
    let unfinished = Unfinished::register(tmp.path());
    {
        let mut out = BufWriter::new(tmp.as_file());
        write(&mut out).map_err(|e| e.in_file(path))?;
        out.flush().map_err(|e| Error::from(e).in_file(path))?;
    }
    // Temporary files are created private (0600); the result should look like any other
    // file the user writes: the old file's permissions if it is being replaced, else 0644.
    if let Some(permissions) = permissions_for(path) {
        tmp.as_file().set_permissions(permissions).map_err(|e| Error::from(e).in_file(path))?;
    }
    tmp.as_file().sync_all().map_err(|e| Error::from(e).in_file(path))?;
    // Checked again: the destination may have been linked to an input while we wrote.
    refuse_input(path)?;
    tmp.persist(path).map_err(|e| Error::from(e.error).in_file(path))?;
    drop(unfinished);
    Ok(())
}

fn permissions_for(path: &Path) -> Option<std::fs::Permissions> {
    if let Ok(meta) = std::fs::metadata(path) {
        return Some(meta.permissions());
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        Some(std::fs::Permissions::from_mode(0o644))
    }
    #[cfg(not(unix))]
    {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn failed_write_keeps_the_old_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("take.txt");
        write_atomically(&path, |w| Ok(w.write_all(b"good")?)).unwrap();
        let err = write_atomically(&path, |w| {
            w.write_all(b"half")?;
            Err(Error::Unwritable("simulated failure".into()))
        });
        assert!(err.is_err());
        assert_eq!(std::fs::read(&path).unwrap(), b"good");
        // No temporary file is left behind.
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            assert_eq!(std::fs::metadata(&path).unwrap().permissions().mode() & 0o777, 0o644);
        }
    }

    #[test]
    fn a_protected_input_is_refused_under_every_spelling() {
        let dir = tempfile::tempdir().unwrap();
        let sub = dir.path().join("d");
        std::fs::create_dir(&sub).unwrap();
        let input = sub.join("t.c3d");
        std::fs::write(&input, b"input").unwrap();
        protect(&input);
        let mut spellings = vec![
            sub.join(".").join("t.c3d"),
            sub.join("..").join("d").join("t.c3d"),
            std::fs::canonicalize(&input).unwrap(),
        ];
        #[cfg(unix)]
        {
            std::os::unix::fs::symlink(&input, dir.path().join("link.c3d")).unwrap();
            std::fs::hard_link(&input, dir.path().join("hard.c3d")).unwrap();
            spellings.push(dir.path().join("link.c3d"));
            spellings.push(dir.path().join("hard.c3d"));
        }
        for spelling in spellings {
            let err = write_atomically(&spelling, |w| Ok(w.write_all(b"output")?)).unwrap_err();
            assert!(err.to_string().contains("never overwrites its input"), "{}: {err}", spelling.display());
            assert_eq!(std::fs::read(&input).unwrap(), b"input");
        }
        // Another file in the same folder is written as usual.
        write_atomically(&sub.join("other.c3d"), |w| Ok(w.write_all(b"output")?)).unwrap();
        assert!(same_file(&input, &sub.join("./t.c3d")));
        assert!(!same_file(&input, &sub.join("other.c3d")));
    }
}
