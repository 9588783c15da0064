//! Per gap of the fixed-length protocol's single inputs ([`locap_eval::fill_lengths`]): what
//! auto's trials measured for each candidate, what it chose, and each candidate's real error on
//! that gap, so a wrong choice can be traced to its trials.
//!
//! ```text
//! cargo run -p locap-eval --release --example auto_diag -- TAKE.c3d|TAKE.trc [--seed 0] [--per-length 5] [--only 1s] [--multi]
//!     [--neighbour-trials 2] [--trial-time 0.5] [--no-shorter-trials] [--no-second-pass]
//! ```
//!
//! `--multi`: the protocol's multi input instead (every gap and the limb gap at once, each
//! method run once on it).

use locap_clean::auto::{self, AutoConfig};
use locap_clean::{FillConfig, fill_gaps};
use locap_eval::fill_lengths::{self, LengthsConfig};

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let path = args
        .first()
        .ok_or_else(|| anyhow::anyhow!("usage: auto_diag TAKE.c3d [--seed N] [--per-length N] [--only BUCKET]"))?;
    let option = |name: &str| args.iter().position(|a| a == name).and_then(|k| args.get(k + 1));
    let seed = option("--seed").map_or(Ok(0), |v| v.parse())?;
    let per_length = option("--per-length").map_or(Ok(5), |v| v.parse())?;
    let only = option("--only");
    let path = std::path::Path::new(path);
    let take = if path.extension().is_some_and(|e| e.eq_ignore_ascii_case("trc")) {
        locap_io::trc::read_trc_path(path)?
    } else {
        locap_io::c3d::read_path(path)?.to_take()?
    };
    let truth = fill_lengths::labeled_only(&take);
    let config = LengthsConfig { seed, per_length, ..LengthsConfig::default() };
    let methods = locap_clean::auto::CANDIDATES;
    println!(
        "| gap | marker | frames | chose | auto | {} | trials: {} |",
        methods.map(|m| m.name()).join(" | "),
        methods.map(|m| m.name()).join(" | ")
    );
    let multi = args.iter().any(|a| a == "--multi");
    let mut auto_config = AutoConfig::default();
    if let Some(t) = option("--trial-time") {
        auto_config.trial_time_s = t.parse()?;
    }
    if args.iter().any(|a| a == "--no-shorter-trials") {
        auto_config.shorter_trials = false;
    }
    if args.iter().any(|a| a == "--no-second-pass") {
        auto_config.second_pass = false;
    }
    if let Some(n) = option("--neighbour-trials") {
        auto_config.neighbour_trials = n.parse()?;
    }
    let gaps = fill_lengths::length_gaps(&truth, &config);
    // The multi input adds the simultaneous limb gap; a single input has no use for it.
    let mut all = gaps.clone();
    if multi {
        all.extend(fill_lengths::limb_gap(&truth, &gaps, config.seed));
    }
    // The multi input is filled once by each method; a single input once per gap.
    let fill_all = |holed: &locap_core::Take| {
        let auto = auto::fill(holed, &auto_config);
        let each: Vec<locap_core::Take> = methods
            .iter()
            .map(|m| fill_gaps(holed, &FillConfig { method: *m, ..FillConfig::default() }).take)
            .collect();
        (auto, each)
    };
    let shared = multi.then(|| fill_all(&fill_lengths::holed(&truth, &all)));
    for gap in if multi { all.clone() } else { gaps } {
        if only.is_some_and(|b| *b != gap.bucket) {
            continue;
        }
        let own = if multi { None } else { Some(fill_all(&fill_lengths::holed(&truth, std::slice::from_ref(&gap)))) };
        let Some((out, each)) = own.as_ref().or(shared.as_ref()) else { continue };
        let rmse = |take: &locap_core::Take| -> f64 {
            let sq: f64 = gap
                .frames
                .clone()
                .filter_map(|f| {
                    Some((take.position_mm(f, gap.marker)? - truth.position_mm(f, gap.marker)?).norm_squared())
                })
                .sum();
            (sq / gap.frames.len() as f64).sqrt()
        };
        let choice = out.choices.iter().find(|c| c.marker == gap.marker && c.frames.contains(&gap.frames.start));
        let real: Vec<String> = each.iter().map(|take| format!("{:.1}", rmse(take))).collect();
        let trials: Vec<String> = methods
            .iter()
            .map(|m| {
                choice
                    .and_then(|c| c.trial_rmse_mm.iter().find(|(t, _)| t == m))
                    .map_or("-".into(), |(_, e)| format!("{e:.1}"))
            })
            .collect();
        println!(
            "| {} | {} | {:?} | {} ({} trials, {} implausible) | {:.1} | {} | {} |",
            gap.bucket,
            truth.markers()[gap.marker],
            gap.frames,
            choice.map_or("-".into(), |c| c.method()),
            choice.map_or(0, |c| c.trials),
            choice.map_or(0, |c| c.implausible),
            rmse(&out.filled.take),
            real.join(" | "),
            trials.join(" | ")
        );
    }
    Ok(())
}
