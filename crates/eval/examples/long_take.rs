//! Writes the issue's timing input for `locap clean`: a 10-minute take at 120 Hz (HDM05
//! `bd_05-01_01` played forward and backward in turn, 41 markers) with 2% of its samples
//! hidden in seeded gaps of 1 frame to 2 s ([`locap_eval::fill_lengths::long_take`]).
//!
//! ```text
//! cargo run -p locap-eval --release --example long_take -- /tmp/ten_minutes.c3d [--minutes 10] [--missing 0.02]
//! time locap clean /tmp/ten_minutes.c3d -o /tmp/ten_minutes_clean.c3d
//! time locap clean /tmp/ten_minutes.c3d -o /tmp/ten_minutes_edm.c3d --method edm
//! ```

use locap_eval::fill_lengths;
use std::path::PathBuf;

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let get = |flag: &str| args.iter().position(|a| a == flag).and_then(|k| args.get(k + 1)).cloned();
    let out = PathBuf::from(
        args.first().filter(|a| !a.starts_with("--")).cloned().unwrap_or_else(|| "ten_minutes.c3d".into()),
    );
    let minutes: f64 = get("--minutes").map_or(Ok(10.0), |v| v.parse())?;
    let missing: f64 = get("--missing").map_or(Ok(0.02), |v| v.parse())?;
    let Some(source) = locap_testkit::shared_file("hdm05-c3d/HDM_bd_05-01_01_120.c3d") else {
        anyhow::bail!("the shared data (../shared/data) is not here");
    };
    let take = locap_io::c3d::read_path(&source)?.to_take()?;
    let take = fill_lengths::labeled_only(&take);
    let frames = (minutes * 60.0 * take.frame_rate_hz()).round() as usize;
    let (long, gaps) = fill_lengths::long_take(&take, frames, missing, 7);
    locap_io::c3d::write_path(&locap_io::c3d::C3dFile::from_take(&long)?, &out)?;
    eprintln!("{}: {frames} frames x {} markers, {gaps} gaps hidden", out.display(), long.marker_count());
    Ok(())
}
