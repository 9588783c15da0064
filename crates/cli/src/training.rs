//! Where `locap train` and `locap eval` meet the files: finding and reading training shards
//! and C3D takes for locap-nn (which never sees a file), keeping checkpoints in a folder, and
//! drawing the loss curves the training reports give as data.

use anyhow::{Context, Result, bail};
use locap_nn::harness::{Checkpointer, LossCurve};
use locap_nn::refiner::{TrainingData, shard_take};
use locap_nn::solver::{SolverData, solver_shard};
use locap_synth::shard::ShardReader;
use rayon::prelude::*;
use std::fs::File;
use std::io::BufReader;
use std::path::{Path, PathBuf};

/// Checkpoints in a folder (`OUT.checkpoints/`), each entry a file written atomically: a run
/// killed while saving leaves the previous checkpoint whole.
#[derive(Debug, Clone)]
pub struct FolderCheckpointer {
    dir: PathBuf,
}

impl FolderCheckpointer {
    /// Checkpoints in `dir`, created if it does not exist.
    pub fn new(dir: PathBuf) -> Result<FolderCheckpointer> {
        std::fs::create_dir_all(&dir).with_context(|| format!("{}: cannot create the folder", dir.display()))?;
        Ok(FolderCheckpointer { dir })
    }
}

impl Checkpointer for FolderCheckpointer {
    fn load(&self, name: &str) -> std::io::Result<Option<Vec<u8>>> {
        match std::fs::read(self.dir.join(name)) {
            Ok(bytes) => Ok(Some(bytes)),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
            Err(e) => Err(e),
        }
    }

    fn save(&self, name: &str, bytes: &[u8]) -> std::io::Result<()> {
        locap_io::atomic::write_atomically(&self.dir.join(name), |w| Ok(w.write_all(bytes)?))
            .map_err(std::io::Error::other)
    }

    fn location(&self, name: &str) -> String {
        self.dir.join(name).display().to_string()
    }
}

/// Writes `curve` as an SVG chart titled `title` to `path`.
pub fn write_loss_curve(curve: LossCurve, title: &str, path: &Path) -> Result<()> {
    let chart = locap_view::plot::Chart::loss_curve(curve.series, curve.loss, title)?;
    crate::inputs::write_bytes(path, &chart.render(locap_view::plot::Format::Svg, (800, 480))?)
}

/// Opens the shard file at `path`, its header checked against the file's length (see
/// [`ShardReader::with_len`]): a truncated file or one whose header lies about its frame
/// count is an error naming the file before anything is allocated from the header.
pub fn open_shard(path: &Path) -> Result<ShardReader<BufReader<File>>> {
    let file = File::open(path).with_context(|| format!("{}: cannot open", path.display()))?;
    let len = file.metadata().with_context(|| format!("{}: cannot open", path.display()))?.len();
    Ok(ShardReader::with_len(BufReader::new(file), len)
        .map_err(|source| locap_nn::NnError::ShardFile { path: path.display().to_string(), source })?)
}

/// Every file with extension `ext` (any case) under the folder `dir`, searched recursively,
/// sorted by path.
fn files_under(dir: &Path, ext: &str) -> Result<Vec<PathBuf>> {
    let mut found = Vec::new();
    let mut folders = vec![dir.to_path_buf()];
    while let Some(folder) = folders.pop() {
        let listing = || format!("{}: cannot list the folder", folder.display());
        for entry in std::fs::read_dir(&folder).with_context(listing)? {
            let path = entry.with_context(listing)?.path();
            if path.is_dir() {
                folders.push(path);
            } else if path.extension().is_some_and(|e| e.eq_ignore_ascii_case(ext)) {
                found.push(path);
            }
        }
    }
    found.sort();
    Ok(found)
}

/// The refiner's training takes from `paths`: shard files (`locap synth`: clean synthetic
/// markers) and labeled C3D takes (real markers; their own gaps are simply not scored), given
/// as files or folders searched recursively for `*.shard`, or for `*.c3d` when a folder holds
/// no shard (`locap synth` writes C3D copies beside its shards). Shards come first, each group
/// sorted by path; the markers are the first take's (see [`TrainingData::new`]).
pub fn fill_data(paths: &[PathBuf]) -> Result<TrainingData> {
    let is_c3d = |p: &Path| p.extension().is_some_and(|e| e.eq_ignore_ascii_case("c3d"));
    let (mut shards, mut c3ds): (Vec<PathBuf>, Vec<PathBuf>) = (Vec::new(), Vec::new());
    for path in paths {
        if !path.is_dir() {
            if is_c3d(path) {
                c3ds.push(path.clone())
            } else {
                shards.push(path.clone())
            }
            continue;
        }
        let found_shards = files_under(path, "shard")?;
        // `locap synth` writes STEM.c3d and STEM.clean.c3d beside STEM.shard: a folder with
        // shards gives its shards only, so no take is read twice.
        if found_shards.is_empty() {
            c3ds.extend(files_under(path, "c3d")?);
        } else {
            shards.extend(found_shards);
        }
    }
    shards.sort();
    c3ds.sort();
    if shards.is_empty() && c3ds.is_empty() {
        let shown: Vec<String> = paths.iter().map(|p| p.display().to_string()).collect();
        bail!("{}: no .shard files (write them with `locap synth`) and no .c3d takes", shown.join(", "));
    }
    let read = |p: &PathBuf| -> Result<locap_core::Take> {
        if is_c3d(p) {
            let file = locap_io::c3d::read_path(p)?;
            Ok(file.to_take().map_err(|e| e.in_file(p))?)
        } else {
            Ok(shard_take(open_shard(p)?, &p.display().to_string())?)
        }
    };
    let all: Vec<PathBuf> = shards.into_iter().chain(c3ds).collect();
    let takes = all.par_iter().map(read).collect::<Result<Vec<_>>>()?;
    Ok(TrainingData::new(takes, all.iter().map(|p| p.display().to_string()).collect())?)
}

/// Every `*.shard` under `path` (searched recursively, sorted), or `path` itself if it is a
/// file.
pub fn shard_paths(path: &Path) -> Result<Vec<PathBuf>> {
    let paths = if path.is_dir() { files_under(path, "shard")? } else { vec![path.to_path_buf()] };
    if paths.is_empty() {
        bail!("{}: no .shard files (write them with `locap synth`)", path.display());
    }
    Ok(paths)
}

/// The solver's training (or evaluation) shards: every shard under `path` (see
/// [`shard_paths`]), with its motion and skeleton.
pub fn solver_data(path: &Path) -> Result<SolverData> {
    let shards = shard_paths(path)?
        .par_iter()
        .map(|p| Ok(solver_shard(open_shard(p)?, &p.display().to_string())?))
        .collect::<Result<Vec<_>>>()?;
    Ok(SolverData::new(shards)?)
}

#[cfg(test)]
mod tests {
    use super::*;
    use locap_core::{MarkerName, Take, Vec3};
    use locap_synth::shard::write_shard;
    use locap_synth::synthesize::LabFrame;

    /// A rigid little body moving along x: the waist markers the local frame needs and two more.
    fn take(frames: usize) -> Take {
        let labels = ["LFWT", "RFWT", "LBWT", "RBWT", "LELB", "RELB"];
        let at = [[100.0, 80.0], [-100.0, 80.0], [100.0, -80.0], [-100.0, -80.0], [300.0, 0.0], [-300.0, 0.0]];
        let names: Vec<MarkerName> = labels.iter().map(|l| MarkerName::parse(l)).collect();
        let samples: Vec<Option<Vec3>> =
            (0..frames).flat_map(|f| at.iter().map(move |p| Some(Vec3::new(p[0] + f as f64, p[1], 1000.0)))).collect();
        Take::from_samples(names, &samples, 120.0).unwrap()
    }

    #[test]
    fn training_data_mixes_shards_and_real_c3d_takes() {
        let dir = tempfile::tempdir().unwrap();
        let synthetic = dir.path().join("synthetic");
        std::fs::create_dir(&synthetic).unwrap();
        let clean = take(200);
        let mut file = File::create(synthetic.join("a.shard")).unwrap();
        write_shard(&mut file, &clean, &clean, None, LabFrame::ZUpFromYUp).unwrap();
        drop(file);
        // `locap synth` leaves a C3D copy beside each shard: it must not be read a second time.
        let c3d = |take: &Take, path: &Path| {
            locap_io::c3d::write_path(&locap_io::c3d::C3dFile::from_take(take).unwrap(), path).unwrap()
        };
        c3d(&clean, &synthetic.join("a.c3d"));
        // A "real" take: another marker order, an unlabeled point, a real gap.
        let real = dir.path().join("real");
        std::fs::create_dir(&real).unwrap();
        let mut names = clean.markers().to_vec();
        names.reverse();
        names.push(MarkerName::parse("*3"));
        let samples: Vec<Option<Vec3>> = (0..150)
            .flat_map(|f| {
                let clean = &clean;
                names.iter().map(move |n| match clean.marker_index(&n.label) {
                    Some(k) if !(n.label == "LELB" && (50..80).contains(&f)) => clean.position_mm(f, k),
                    _ => n.is_unlabeled().then(|| Vec3::new(1.0, 2.0, 3.0)),
                })
            })
            .collect();
        c3d(&Take::from_samples(names, &samples, 120.0).unwrap(), &real.join("b.c3d"));

        let data = fill_data(&[real.clone(), synthetic.clone()]).unwrap();
        assert_eq!((data.takes.len(), data.markers.len(), data.frames()), (2, 6, 350), "{:?}", data.names);
        assert!(data.names[0].ends_with("a.shard") && data.names[1].ends_with("b.c3d"), "{:?}", data.names);
        let (shard, real_take) = (&data.takes[0], &data.takes[1]);
        let lelb = real_take.marker_index("LELB").unwrap();
        assert_eq!(real_take.marker_index("LELB"), shard.marker_index("LELB"));
        let near = |p: Option<Vec3>| p.map(|p| (p - clean.position_mm(10, lelb).unwrap()).norm() < 0.1);
        assert_eq!(near(real_take.position_mm(10, lelb)), Some(true));
        assert!(!real_take.is_valid(60, lelb));
        let empty = tempfile::tempdir().unwrap();
        let e = fill_data(&[empty.path().to_path_buf()]).unwrap_err().to_string();
        assert!(e.contains("no .shard files"), "{e}");
        let e = shard_paths(empty.path()).unwrap_err().to_string();
        assert!(e.contains("no .shard files"), "{e}");
    }

    #[test]
    fn folder_checkpoints_round_trip_and_say_where_they_are() {
        let dir = tempfile::tempdir().unwrap();
        let store = FolderCheckpointer::new(dir.path().join("run.checkpoints")).unwrap();
        assert_eq!(store.load("optimizer.bin").unwrap(), None);
        store.save("optimizer.bin", b"state").unwrap();
        store.save("optimizer.bin", b"later").unwrap();
        assert_eq!(store.load("optimizer.bin").unwrap().as_deref(), Some(&b"later"[..]));
        assert!(store.location("optimizer.bin").ends_with("run.checkpoints/optimizer.bin"));
    }
}
