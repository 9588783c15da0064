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

/// Output paths for a command that writes one file per input take: `output` itself when
/// one file was named, else a mirror of the inputs under the folder `output` (created).
pub fn targets(given: &[PathBuf], files: &[PathBuf], output: &Path) -> Result<Vec<PathBuf>> {
    let single = files.len() == 1 && given.len() == 1 && !given[0].is_dir() && !output.is_dir();
    if single {
        return Ok(vec![output.to_path_buf()]);
    }
    std::fs::create_dir_all(output).with_context(|| format!("{}: cannot create output folder", output.display()))?;
    Ok(output_paths(files, output, None))
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
    if has_extension(path, &["trc"]) {
        Ok(locap_io::trc::read_trc_path(path)?)
    } else {
        Ok(locap_io::c3d::read_path(path)?.to_take().map_err(|e| e.in_file(path))?)
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
