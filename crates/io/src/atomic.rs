//! Atomic output: a file appears complete or not at all.
//!
//! A crash or a full disk in the middle of writing must never leave a half-written take where
//! a studio expects a good one, nor destroy the previous version. Every writer of this crate
//! writes to a temporary file in the destination folder (same file system, so the rename is
//! atomic), flushes it to disk, then renames it over the destination.

use crate::{Error, Result};
use std::io::{BufWriter, Write};
use std::path::Path;

/// Writes a file atomically: `write` fills a buffered temporary file, which replaces `path`
/// only if `write` and the flush succeed.
pub fn write_atomically(path: &Path, write: impl FnOnce(&mut dyn Write) -> Result<()>) -> Result<()> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let tmp = tempfile::Builder::new()
        .prefix(".locap-")
        .suffix(".tmp")
        .tempfile_in(dir)
        .map_err(|e| Error::from(e).in_file(path))?;
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
    tmp.persist(path).map_err(|e| Error::from(e.error).in_file(path))?;
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
}
