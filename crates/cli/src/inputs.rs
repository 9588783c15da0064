//! Turning command-line paths (files and folders) into the list of takes to process.

use anyhow::{Context, Result, bail};
use std::path::{Path, PathBuf};

/// Expands `paths`: files are kept as given; folders are searched recursively for files
/// whose extension (case-insensitive) is one of `extensions`, sorted for a stable order.
pub fn expand(paths: &[PathBuf], extensions: &[&str]) -> Result<Vec<PathBuf>> {
    let mut out = Vec::new();
    for path in paths {
        let meta = std::fs::metadata(path).with_context(|| format!("{}: cannot open", path.display()))?;
        if meta.is_dir() {
            let before = out.len();
            walk(path, extensions, &mut out)?;
            out[before..].sort();
        } else {
            out.push(path.clone());
        }
    }
    if out.is_empty() {
        bail!("no input files found (looked for {} files)", extensions.join(", "));
    }
    Ok(out)
}

fn walk(dir: &Path, extensions: &[&str], out: &mut Vec<PathBuf>) -> Result<()> {
    for entry in std::fs::read_dir(dir).with_context(|| format!("{}: cannot list folder", dir.display()))? {
        let path = entry?.path();
        if path.is_dir() {
            walk(&path, extensions, out)?;
        } else if has_extension(&path, extensions) {
            out.push(path);
        }
    }
    Ok(())
}

/// True if `path`'s extension is one of `extensions` (case-insensitive).
pub fn has_extension(path: &Path, extensions: &[&str]) -> bool {
    path.extension().and_then(|e| e.to_str()).is_some_and(|e| extensions.iter().any(|x| x.eq_ignore_ascii_case(e)))
}
