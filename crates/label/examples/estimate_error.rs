//! How far the labeler's missing-marker estimates (paper section 4) are from the truth, next
//! to the offline gap fills of `locap-clean` on the same gaps: gaps are cut into gap-free
//! takes, the take is labeled online from its first frame's labels, and every estimate the
//! labeler makes inside a gap is compared with the hidden sample.
//!
//! Run: `cargo run --release -p locap-label --example estimate_error -- TAKE.c3d...`
//! (e.g. `../shared/data/cmu-c3d/85_12.c3d ../shared/data/hdm05-c3d/*.c3d`).

use locap_clean::{FillConfig, FillMethod, fill_gaps};
use locap_core::{Take, Vec3};
use locap_label::{LabelConfig, Labeler, PointFrames, Template};

/// Gaps cut per marker, and their shortest and longest length (s).
const GAPS_PER_MARKER: usize = 3;
const GAP_S: (f64, f64) = (0.1, 2.0);

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let paths: Vec<String> = std::env::args().skip(1).collect();
    if paths.is_empty() {
        return Err("usage: estimate_error TAKE.c3d...".into());
    }
    println!("take | hidden samples | estimated | online estimate mean / median / p95 mm | edm | rigid | linear");
    for path in &paths {
        let take = locap_io::c3d::read_path(std::path::Path::new(path))?.to_take()?;
        let (gapped, hidden) = cut_gaps(&take, 1);
        let template = Template::from_take(&take, Some(0))?;
        let online = online_errors(&take, &gapped, &template, &hidden)?;
        let offline = |method| {
            let filled = fill_gaps(&gapped, &FillConfig { method, ..FillConfig::default() });
            let errors: Vec<f64> = hidden
                .iter()
                .filter_map(|&(f, m)| Some((filled.take.position_mm(f, m)? - take.position_mm(f, m)?).norm()))
                .collect();
            summary(errors)
        };
        let name = std::path::Path::new(path).file_name().map_or(path.clone(), |n| n.to_string_lossy().into());
        println!(
            "{name} | {} | {:.1}% | {} | {} | {} | {}",
            hidden.len(),
            100.0 * online.len() as f64 / hidden.len().max(1) as f64,
            summary(online),
            offline(FillMethod::Edm),
            offline(FillMethod::Rigid),
            offline(FillMethod::Linear)
        );
    }
    Ok(())
}

/// `take` with gaps cut into every marker (never in frame 0, which starts the labeling), and
/// the hidden samples `(frame, marker)`.
fn cut_gaps(take: &Take, seed: u64) -> (Take, Vec<(usize, usize)>) {
    let mut state = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    let mut next = move || {
        // xorshift64*: a fixed, dependency-free sequence, so the measurement reproduces.
        state ^= state >> 12;
        state ^= state << 25;
        state ^= state >> 27;
        (state.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64
    };
    let (t, rate) = (take.frame_count(), take.frame_rate_hz());
    let mut gapped = take.clone();
    let mut hidden = Vec::new();
    for m in 0..take.marker_count() {
        for _ in 0..GAPS_PER_MARKER {
            let length = ((GAP_S.0 + next() * (GAP_S.1 - GAP_S.0)) * rate) as usize;
            let start = 1 + (next() * t.saturating_sub(length + 1) as f64) as usize;
            for f in start..(start + length).min(t) {
                if gapped.position_mm(f, m).is_some() {
                    let _ = gapped.set_position_mm(f, m, None);
                    hidden.push((f, m));
                }
            }
        }
    }
    (gapped, hidden)
}

/// Errors of the labeler's estimates at the hidden samples it estimated (mm).
fn online_errors(
    truth: &Take,
    gapped: &Take,
    template: &Template,
    hidden: &[(usize, usize)],
) -> Result<Vec<f64>, Box<dyn std::error::Error>> {
    let frames = PointFrames::from_take(gapped);
    let mut labeler = Labeler::new(template, LabelConfig::default(), frames.frame_rate_hz())?;
    let columns = frames.columns(0);
    let initial: Vec<Option<usize>> =
        (0..template.marker_count()).map(|m| columns.iter().position(|&c| c as usize == m)).collect();
    labeler.start(template, frames.frame(0), &initial)?;
    let m = truth.marker_count();
    let mut estimates: Vec<Option<Vec3>> = vec![None; truth.frame_count() * m];
    for f in 1..frames.frame_count() {
        labeler.step(frames.frame(f));
        for (k, (p, &e)) in labeler.positions_mm().iter().zip(labeler.estimated()).enumerate() {
            if e {
                estimates[f * m + k] = *p;
            }
        }
    }
    Ok(hidden.iter().filter_map(|&(f, k)| Some((estimates[f * m + k]? - truth.position_mm(f, k)?).norm())).collect())
}

fn summary(mut errors: Vec<f64>) -> String {
    if errors.is_empty() {
        return "-".into();
    }
    errors.sort_by(f64::total_cmp);
    let at = |q: f64| errors[((errors.len() - 1) as f64 * q).round() as usize];
    format!("{:.1} / {:.1} / {:.1}", errors.iter().sum::<f64>() / errors.len() as f64, at(0.5), at(0.95))
}
