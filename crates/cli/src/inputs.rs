//! Turning command-line paths (files and folders) into the list of takes to process, and
//! making sure no output of a run is one of its inputs.
//!
//! Inputs are recognised by identity ([`locap_io::atomic::FileId`]: device and inode), never
//! by how their path is spelled: every input a command reads is [`protect`]ed, so the atomic
//! writers of `locap_io` refuse to replace it, and [`check_outputs`] refuses a run whose
//! outputs name an input or each other before any work is done.
//!
//! Folder walks do not follow links to folders (a link loop, or `up -> ..`, would walk
//! forever or outside the folder the user named); links to files are followed, so a folder of
//! links to takes elsewhere works. Anything that is not a regular file (a named pipe, a device)
//! is refused before it is opened: opening a named pipe blocks until someone writes to it.

use anyhow::{Context, Result, bail};
use locap_io::atomic::FileId;
use std::path::{Component, Path, PathBuf};

/// A mistake on the command line (exit status 2), as opposed to a take or file that failed
/// (exit status 1).
#[derive(Debug)]
pub struct Usage(pub String);

impl std::fmt::Display for Usage {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for Usage {}

/// A usage error with `message`.
pub fn usage(message: impl Into<String>) -> anyhow::Error {
    Usage(message.into()).into()
}

/// Expands `paths`: files are kept as given; folders are searched recursively for files
/// whose extension (case-insensitive) is one of `extensions`, sorted for a stable order. A path
/// that cannot be read is reported as `path: reason` (counted as a failed take) and the others
/// go on; the same file reached twice (two spellings, a link) is kept once. Every file returned
/// is [`protect`]ed.
pub fn expand(paths: &[PathBuf], extensions: &[&str]) -> Result<Vec<PathBuf>> {
    let mut out = Vec::new();
    let mut failed = 0;
    for path in paths {
        let meta = match std::fs::metadata(path) {
            Ok(meta) => meta,
            Err(err) => {
                crate::report_failure(path, &anyhow::Error::new(err).context("cannot open"));
                failed += 1;
                continue;
            }
        };
        if meta.is_dir() {
            let before = out.len();
            walk(path, extensions, &mut out, &mut failed)?;
            out[before..].sort();
        } else if meta.is_file() {
            out.push(path.clone());
        } else {
            crate::report_failure(path, &anyhow::anyhow!("not a regular file (a pipe or device?); not read"));
            failed += 1;
        }
    }
    let mut seen = std::collections::HashSet::new();
    out.retain(|file| FileId::of(file).is_none_or(|id| seen.insert(id)));
    if out.is_empty() {
        if failed > 0 {
            bail!("no input could be read");
        }
        bail!("no input files found (looked for {} files)", extensions.join(", "));
    }
    for file in &out {
        locap_io::atomic::protect(file);
    }
    Ok(out)
}

fn walk(dir: &Path, extensions: &[&str], out: &mut Vec<PathBuf>, failed: &mut usize) -> Result<()> {
    let entries = match std::fs::read_dir(dir) {
        Ok(entries) => entries,
        Err(err) => {
            crate::report_failure(dir, &anyhow::Error::new(err).context("cannot list folder"));
            *failed += 1;
            return Ok(());
        }
    };
    for entry in entries {
        let entry = entry.with_context(|| format!("{}: cannot list folder", dir.display()))?;
        let path = entry.path();
        // `file_type` does not follow links: a linked folder is never entered.
        let Ok(kind) = entry.file_type() else { continue };
        if kind.is_dir() {
            walk(&path, extensions, out, failed)?;
        } else if has_extension(&path, extensions) {
            match std::fs::metadata(&path) {
                Ok(meta) if meta.is_file() => out.push(path),
                Ok(meta) if meta.is_dir() => {}
                Ok(_) => {
                    crate::report_failure(&path, &anyhow::anyhow!("not a regular file (a pipe or device?); not read"));
                    *failed += 1;
                }
                Err(err) => {
                    crate::report_failure(&path, &anyhow::Error::new(err).context("cannot open"));
                    *failed += 1;
                }
            }
        }
    }
    Ok(())
}

/// Marks auxiliary inputs (templates, models, layouts, motions, ...) as inputs of this run,
/// refusing ones that are not regular files before anything opens them.
pub fn protect(paths: &[&Path]) -> Result<()> {
    for path in paths {
        if let Ok(meta) = std::fs::metadata(path)
            && !meta.is_file()
            && !meta.is_dir()
        {
            bail!("{}: not a regular file (a pipe or device?); not read", path.display());
        }
        locap_io::atomic::protect(path);
    }
    Ok(())
}

/// Refuses, before any work, a run where an output is one of its inputs (by identity, however
/// spelled: [`protect`] and [`expand`] register them) or two outputs are the same file (in a
/// batch: `take.c3d` and `take.trc` both converted to `out/take.csv`).
pub fn check_outputs(outputs: &[PathBuf]) -> Result<()> {
    for output in outputs {
        if let Some(input) = locap_io::atomic::protected_input(output) {
            return Err(usage(format!(
                "{}: this output is the input {}; locap never overwrites its input",
                output.display(),
                input.display()
            )));
        }
    }
    let mut seen = std::collections::HashMap::new();
    for output in outputs {
        if let Some(first) = seen.insert(normalized(output), output) {
            return Err(usage(format!(
                "{} and {} would be written to the same file; nothing was done",
                first.display(),
                output.display()
            )));
        }
    }
    Ok(())
}

/// `path` made absolute with `.` and `..` resolved (on the real folder where it exists, so
/// links are followed), for comparing files that do not exist yet.
fn normalized(path: &Path) -> PathBuf {
    if let Ok(real) = std::fs::canonicalize(path) {
        return real;
    }
    if let (Some(parent), Some(name)) = (path.parent(), path.file_name())
        && let Ok(real) = std::fs::canonicalize(if parent.as_os_str().is_empty() { Path::new(".") } else { parent })
    {
        return real.join(name);
    }
    let absolute = std::env::current_dir().unwrap_or_default().join(path);
    let mut out = PathBuf::new();
    for part in absolute.components() {
        match part {
            Component::CurDir => {}
            Component::ParentDir => {
                out.pop();
            }
            other => out.push(other),
        }
    }
    out
}

/// True if `path`'s extension is one of `extensions` (case-insensitive).
pub fn has_extension(path: &Path, extensions: &[&str]) -> bool {
    path.extension().and_then(|e| e.to_str()).is_some_and(|e| extensions.iter().any(|x| x.eq_ignore_ascii_case(e)))
}

/// Output paths for a command that writes one file per input take: `output` itself when
/// one file was named, else a mirror of the inputs under the folder `output` (created), checked
/// with [`check_outputs`].
pub fn targets(given: &[PathBuf], files: &[PathBuf], output: &Path) -> Result<Vec<PathBuf>> {
    let single = files.len() == 1 && given.len() == 1 && !given[0].is_dir() && !output.is_dir();
    let targets = if single { vec![output.to_path_buf()] } else { output_paths(files, output, None) };
    check_outputs(&targets)?;
    if !single {
        std::fs::create_dir_all(output)
            .with_context(|| format!("{}: cannot create output folder", output.display()))?;
    }
    Ok(targets)
}

/// Where each of `files` goes under `out_dir`: its path relative to the folder all inputs
/// share, so takes with the same name in different folders (`hands/x.c3d`, `sample_37/x.c3d`)
/// never overwrite each other. `extension` replaces the file's own when given.
pub fn output_paths(files: &[PathBuf], out_dir: &Path, extension: Option<&str>) -> Vec<PathBuf> {
    let parents: Vec<PathBuf> = files.iter().map(|f| f.parent().map(Path::to_path_buf).unwrap_or_default()).collect();
    let mut common = parents.first().cloned().unwrap_or_default();
    for p in &parents[1.min(parents.len())..] {
        while !p.starts_with(&common) {
            if !common.pop() {
                break;
            }
        }
    }
    files
        .iter()
        .map(|f| {
            let relative = f
                .strip_prefix(&common)
                .map(Path::to_path_buf)
                .unwrap_or_else(|_| f.file_name().map(PathBuf::from).unwrap_or_default());
            let target = out_dir.join(relative);
            match extension {
                Some(ext) => target.with_extension(ext),
                None => target,
            }
        })
        .collect()
}

/// Reads a marker take from a C3D or TRC file (chosen by extension; anything else is read as
/// C3D, whose reader says clearly when it is not).
pub fn read_take(path: &Path) -> Result<locap_core::Take> {
    protect(&[path])?;
    if has_extension(path, &["trc"]) {
        read_trc(path)
    } else {
        Ok(read_c3d(path)?.to_take().map_err(|e| e.in_file(path))?)
    }
}

/// Reads a whole C3D file, printing what the reader noticed but could read past (an empty
/// POINT:UNITS read as mm, an invalid POINT:RATE, ...) as `path: warning: ...`.
pub fn read_c3d(path: &Path) -> Result<locap_io::c3d::C3dFile> {
    let file = locap_io::c3d::read_path(path)?;
    warn(path, &file.warnings);
    Ok(file)
}

/// Reads a TRC file's take, printing the reader's notes as warnings.
pub fn read_trc(path: &Path) -> Result<locap_core::Take> {
    let file = locap_io::trc::read_trc_file_path(path)?;
    warn(path, &file.notes);
    Ok(file.take)
}

fn warn(path: &Path, warnings: &[String]) {
    for warning in warnings {
        eprintln!("locap: {}: warning: {warning}", path.display());
    }
}

/// How skeleton motion files are read.
#[derive(Debug, Clone, Default)]
pub struct MotionOptions {
    /// The ASF skeleton of AMC files; `None`: the only `.asf` file in the AMC's folder.
    pub asf: Option<PathBuf>,
    /// Millimetres per BVH length unit (BVH does not say; CMU BVH uses ASF units,
    /// 25.4 / 0.45 mm).
    pub bvh_mm_per_unit: f64,
    /// Frame rate of AMC files, Hz (AMC does not say; CMU is 120 Hz).
    pub amc_rate_hz: f64,
}

/// Reads skeleton motion from a BVH file or an AMC file (with its ASF skeleton).
pub fn read_motion(path: &Path, options: &MotionOptions) -> Result<locap_core::Motion> {
    protect(&[path])?;
    if has_extension(path, &["bvh"]) {
        let motion = locap_io::bvh::read_bvh_path(path, locap_core::LengthUnit::Millimetre)?;
        let s = options.bvh_mm_per_unit;
        if !(s.is_finite() && s > 0.0) {
            bail!("--bvh-mm-per-unit {s} is not a positive number");
        }
        return Ok(locap_synth::synthesize::scale_motion(&motion, &vec![s; motion.skeleton.len()], s)?);
    }
    if !has_extension(path, &["amc"]) {
        bail!("{}: not a motion file (expected .bvh or .amc)", path.display());
    }
    let asf_path = match &options.asf {
        Some(p) => p.clone(),
        None => {
            let dir = path.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(Path::new("."));
            let mut found = Vec::new();
            walk_flat(dir, &mut found)?;
            match found.as_slice() {
                [one] => one.clone(),
                [] => bail!("{}: no .asf skeleton next to it; give --asf", path.display()),
                _ => bail!("{}: several .asf files next to it; give --asf", path.display()),
            }
        }
    };
    protect(&[&asf_path])?;
    let asf = locap_io::asf_amc::read_asf_path(&asf_path)?;
    Ok(locap_io::asf_amc::read_amc_path(path, &asf, options.amc_rate_hz)?)
}

/// The `.asf` files directly in `dir`.
fn walk_flat(dir: &Path, out: &mut Vec<PathBuf>) -> Result<()> {
    for entry in std::fs::read_dir(dir).with_context(|| format!("{}: cannot list folder", dir.display()))? {
        let path = entry?.path();
        if path.is_file() && has_extension(&path, &["asf"]) {
            out.push(path);
        }
    }
    Ok(())
}

/// `path` with `suffix` appended to its file name (`m.locapnn` -> `m.locapnn.loss.svg`).
pub fn with_suffix(path: &Path, suffix: &str) -> PathBuf {
    let mut name = path.file_name().map(|n| n.to_os_string()).unwrap_or_default();
    name.push(suffix);
    path.with_file_name(name)
}

/// Writes `value` as pretty JSON to `path`, atomically.
pub fn write_json(path: &Path, value: &impl serde::Serialize) -> Result<()> {
    let text = serde_json::to_string_pretty(value)?;
    locap_io::atomic::write_atomically(path, |w| Ok(w.write_all(text.as_bytes())?))?;
    Ok(())
}

/// Writes `bytes` to `path`, atomically; the error names the file.
pub fn write_bytes(path: &Path, bytes: &[u8]) -> Result<()> {
    locap_io::atomic::write_atomically(path, |w| Ok(w.write_all(bytes)?))
        .with_context(|| format!("{}", path.display()))?;
    Ok(())
}

/// Creates the folder a batch output goes into (it mirrors the input's subfolder).
pub fn create_parent(target: &Path) -> Result<()> {
    if let Some(dir) = target.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("{}: cannot create folder", dir.display()))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn same_names_in_different_folders_do_not_collide() {
        let files = vec![PathBuf::from("data/hands/x.c3d"), PathBuf::from("data/c3d/s37/x.c3d")];
        let out = output_paths(&files, Path::new("out"), None);
        assert_eq!(out, vec![PathBuf::from("out/hands/x.c3d"), PathBuf::from("out/c3d/s37/x.c3d")]);
        let one = output_paths(&[PathBuf::from("a/b/take.c3d")], Path::new("o"), Some("trc"));
        assert_eq!(one, vec![PathBuf::from("o/take.trc")]);
    }
}
