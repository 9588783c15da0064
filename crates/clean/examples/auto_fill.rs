//! Measures the per-gap automatic fill ([`locap_clean::auto`]) against the single methods on
//! the shared gap-free takes, with the fixed-length protocol of issue 15
//! (`tests/protocol/mod.rs`): RMSE mm over hidden samples per gap length, single and multi
//! inputs.
//!
//! ```text
//! cargo run -p locap-clean --release --example auto_fill -- [--takes 85_02,85_12,135_02,hdm05]
//!     [--seed 0] [--per-length 5] [--blend 2] [--trials 5] [--context 4] [--markers 10]
//!     [--pca-markers 41]
//! ```

#[path = "../tests/protocol/mod.rs"]
mod protocol;

use locap_clean::auto::{self, AutoConfig};
use locap_clean::{FillConfig, FillMethod, Filled, fill_gaps};
use locap_core::Take;
use protocol::{Hidden, Score};
use std::collections::BTreeMap;
use std::time::Instant;

fn path_of(name: &str) -> String {
    match name {
        "hdm05" => "hdm05-c3d/HDM_bd_05-01_01_120.c3d".to_string(),
        other => format!("cmu-c3d/{other}.c3d"),
    }
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let get = |flag: &str| args.iter().position(|a| a == flag).and_then(|k| args.get(k + 1)).cloned();
    let takes = get("--takes").unwrap_or_else(|| "85_02,85_12,135_02,hdm05".into());
    let seed: u64 = get("--seed").map_or(0, |s| s.parse().expect("--seed"));
    let per_length: usize = get("--per-length").map_or(5, |s| s.parse().expect("--per-length"));
    let mut config = AutoConfig::default();
    // Each flag overrides one setting; a value that does not parse stops the run, naming it.
    fn set<T: std::str::FromStr>(value: Option<String>, flag: &str, field: &mut T) {
        if let Some(v) = value {
            *field = v.parse().unwrap_or_else(|_| panic!("{flag}: cannot read `{v}`"));
        }
    }
    set(get("--blend"), "--blend", &mut config.blend);
    if args.iter().any(|a| a == "--least-squares") {
        config.weighting = auto::Weighting::LeastSquares;
    }
    set(get("--trials"), "--trials", &mut config.trials);
    set(get("--context"), "--context", &mut config.context_s);
    set(get("--pca-context"), "--pca-context", &mut config.pca_context_s);
    set(get("--pca-fit"), "--pca-fit", &mut config.pca_fit_frames);
    set(get("--interpolate"), "--interpolate", &mut config.interpolate_s);
    set(get("--markers"), "--markers", &mut config.markers);
    set(get("--pca-markers"), "--pca-markers", &mut config.pca_markers);
    eprintln!("{config:?}, seed {seed}, {per_length} gaps per length");
    for name in takes.split(',') {
        let Some(truth) = protocol::read_take(&path_of(name)) else { return };
        run_take(name, &truth, &config, seed, per_length);
    }
}

type Fill<'a> = Box<dyn Fn(&Take) -> (Filled, Vec<auto::GapChoice>) + 'a>;

fn run_take(name: &str, truth: &Take, config: &AutoConfig, seed: u64, per_length: usize) {
    let gaps = protocol::gaps(truth, per_length, seed);
    let limb = protocol::limb(truth, &gaps, seed);
    let mut methods: Vec<(&str, Fill)> = vec![(
        "auto",
        Box::new(move |t: &Take| {
            let a = auto::fill(t, config);
            (a.filled, a.choices)
        }),
    )];
    for m in [FillMethod::Edm, FillMethod::Pca, FillMethod::Rigid, FillMethod::Spline, FillMethod::Linear] {
        methods.push((
            m.name(),
            Box::new(move |t: &Take| (fill_gaps(t, &FillConfig { method: m, ..FillConfig::default() }), Vec::new())),
        ));
    }
    println!(
        "\n## {name}: {} frames, {} markers, {} gaps + {} limb markers",
        truth.frame_count(),
        truth.marker_count(),
        gaps.len(),
        limb.len()
    );
    let mut table: Vec<(String, Score, Score, f64)> = Vec::new();
    let mut chosen: BTreeMap<String, usize> = BTreeMap::new();
    for (method, fill) in &methods {
        let started = Instant::now();
        let mut single = Score::default();
        for h in &gaps {
            let input = protocol::holed(truth, std::slice::from_ref(h));
            let (filled, choices) = fill(&input);
            if *method == "auto" {
                for c in choices.iter().filter(|c| c.marker == h.marker && c.frames == h.frames) {
                    *chosen
                        .entry(format!("single {} {}", h.bucket, c.method().split(' ').next().unwrap_or("")))
                        .or_default() += 1;
                }
            }
            protocol::score(truth, &filled, &protocol::linear(&input), std::slice::from_ref(h), &mut single);
        }
        let all: Vec<Hidden> = gaps.iter().chain(&limb).cloned().collect();
        let input = protocol::holed(truth, &all);
        let (filled, choices) = fill(&input);
        if *method == "auto" {
            if std::env::var_os("AUTO_VERBOSE").is_some() {
                for c in choices.iter().filter(|c| limb.iter().any(|h| h.marker == c.marker && h.frames == c.frames)) {
                    let rmse: Vec<String> =
                        c.trial_rmse_mm.iter().map(|(m, e)| format!("{} {e:.1}", m.name())).collect();
                    println!(
                        "limb {} {:?}: {} ({} trials: {})",
                        truth.markers()[c.marker],
                        c.frames,
                        c.method(),
                        c.trials,
                        rmse.join(", ")
                    );
                }
            }
            for c in &choices {
                *chosen.entry(format!("multi {}", c.method().split(' ').next().unwrap_or(""))).or_default() += 1;
            }
        }
        let mut multi = Score::default();
        protocol::score(truth, &filled, &protocol::linear(&input), &all, &mut multi);
        table.push((method.to_string(), single, multi, started.elapsed().as_secs_f64()));
    }
    let mut header = String::from("| method |");
    for b in protocol::LENGTHS_S {
        header += &format!(" single {b}s |");
    }
    header += " **single** |";
    for b in protocol::LENGTHS_S {
        header += &format!(" multi {b}s |");
    }
    header += " multi limb | **multi** | missing | time s |";
    println!("{header}");
    println!("|{}", "---|".repeat(header.matches('|').count() - 1));
    for (method, single, multi, time) in &table {
        let mut row = format!("| {method} |");
        for b in protocol::LENGTHS_S {
            row += &format!(" {:.1} |", single.rmse(&format!("{b}s")).unwrap_or(f64::NAN));
        }
        row += &format!(" **{:.1}** |", single.overall());
        for b in protocol::LENGTHS_S {
            row += &format!(" {:.1} |", multi.rmse(&format!("{b}s")).unwrap_or(f64::NAN));
        }
        row += &format!(
            " {:.1} | **{:.1}** | {}/{} | {time:.1} |",
            multi.rmse("limb").unwrap_or(f64::NAN),
            multi.overall(),
            single.missing(),
            multi.missing()
        );
        println!("{row}");
    }
    let best = |f: &dyn Fn(&Score) -> f64, pick: fn(&(String, Score, Score, f64)) -> &Score| {
        table.iter().skip(1).map(|r| f(pick(r))).fold(f64::INFINITY, f64::min)
    };
    let single_ratio = table[0].1.overall() / best(&|s| s.overall(), |r| &r.1);
    let multi_ratio = table[0].2.overall() / best(&|s| s.overall(), |r| &r.2);
    println!("auto / best baseline: single {single_ratio:.3}, multi {multi_ratio:.3}");
    println!("auto's choices (first method of the blend): {chosen:?}");
}
