//! The `locap` command-line program.
//!
//! Each subcommand lives in `cmd/`, with an `Args` struct that only parses and a `run` that
//! does the work through the library crates. Commands take many files or folders; each take
//! is an independent job run on all cores, and one bad take prints `path: reason` without
//! stopping the others; the exit status says whether any failed (0 = all good, 1 = some take
//! failed, 2 = usage error: a mistake on the command line, see [`inputs::Usage`]).

mod cmd;
mod inputs;
mod training;
mod values;

use clap::{Parser, Subcommand};
use std::process::ExitCode;
use std::sync::atomic::{AtomicUsize, Ordering};

/// locap: automatic optical motion capture clean-up.
///
/// Reads C3D, TRC, BVH and ASF/AMC files; labels, cleans and solves marker data.
#[derive(Parser, Debug)]
#[command(name = "locap", version, about, long_about = None, propagate_version = true)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Describe takes: markers, frames, rate, units, vendor, analog channels and gaps.
    Info(cmd::info::Args),
    /// Convert between formats (chosen from the file extensions).
    Convert(cmd::convert::Args),
    /// Name the points of raw takes from a labeled template, online (soft graph matching).
    Label(cmd::label::Args),
    /// Make labeling benchmark input from a labeled take: shuffled points, ghosts, occlusions.
    Unlabel(cmd::unlabel::Args),
    /// Fill occlusion gaps and remove outliers (LocalMoCap section 3.1).
    Clean(cmd::clean::Args),
    /// Measure accuracy and speed against baselines on real takes.
    Bench(cmd::bench::Args),
    /// Marker layouts: calibrate offsets on real takes with their solved motion, or fit them to
    /// a real take's marker distances.
    Layout(cmd::layout::Args),
    /// Pool the real occlusion statistics of takes into one JSON file (for synth --augment).
    Stats(cmd::stats::Args),
    /// Synthesize training data: markers from skeleton motion, realistic gaps and shifts.
    Synth(cmd::synth::Args),
    /// Hand skeleton motion and the hand marker layout from an ART hand export, plus
    /// procedural finger motion within joint limits.
    Hands(cmd::hands::Args),
    /// Write a self-contained HTML page that plays a take (markers, fills, skeleton).
    View(cmd::view::Args),
    /// Draw PNG/SVG charts: gap lengths, occlusion rates, fill error by gap length.
    Plot(cmd::plot::Args),
    /// Train networks on synth shards: the learned gap-fill refiner (LocalMoCap section 3.1) or
    /// the motion solver (section 3.2).
    Train(cmd::train::Args),
    /// Solve raw takes to skeleton motion (BVH): cleaning, then the learned motion solver
    /// (LocalMoCap section 3.2).
    Solve(cmd::solve::Args),
    /// Compare motion solvers on held-out synthetic data: JOE, JPE, OMPE (LocalMoCap Table 1).
    Eval(cmd::eval::Args),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    remove_temporaries_on_signals();
    let result = match cli.command {
        Command::Info(args) => cmd::info::run(args),
        Command::Convert(args) => cmd::convert::run(args),
        Command::Label(args) => cmd::label::run(args),
        Command::Unlabel(args) => cmd::unlabel::run(args),
        Command::Clean(args) => cmd::clean::run(args),
        Command::Bench(args) => cmd::bench::run(args),
        Command::Layout(args) => cmd::layout::run(args),
        Command::Stats(args) => cmd::stats::run(args),
        Command::Synth(args) => cmd::synth::run(args),
        Command::Hands(args) => cmd::hands::run(args),
        Command::View(args) => cmd::view::run(args),
        Command::Plot(args) => cmd::plot::run(args),
        Command::Train(args) => cmd::train::run(args),
        Command::Solve(args) => cmd::solve::run(args),
        Command::Eval(args) => cmd::eval::run(args),
    };
    match result {
        // A take that failed was reported as it failed; it decides the status even where the
        // command's own summary did not count it (an input that could not be opened at all).
        Ok(code) if code == ExitCode::SUCCESS && FAILURES.load(Ordering::Relaxed) > 0 => ExitCode::from(1),
        Ok(code) => code,
        Err(err) => {
            eprintln!("locap: error: {err:#}");
            if err.downcast_ref::<inputs::Usage>().is_some() { ExitCode::from(2) } else { ExitCode::from(1) }
        }
    }
}

/// Failures reported by [`report_failure`] in this run.
static FAILURES: AtomicUsize = AtomicUsize::new(0);

/// Removes the temporary files of writes in progress when the user interrupts the program
/// (`SIGINT`, `SIGTERM`, `SIGHUP`), then exits as a shell expects of a killed program.
fn remove_temporaries_on_signals() {
    let installed = ctrlc::set_handler(|| {
        locap_io::atomic::remove_unfinished();
        eprintln!("locap: interrupted; unfinished output removed");
        std::process::exit(130);
    });
    if let Err(err) = installed {
        eprintln!(
            "locap: warning: cannot catch interrupts ({err}); an interrupted write may leave a .locap-*.tmp file"
        );
    }
}

/// Writes `text` to standard output. A closed pipe (`locap info ... | head`) is a normal way
/// for a reader to stop, so it ends the program quietly instead of failing.
pub fn emit(text: &str) -> anyhow::Result<()> {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    match out.write_all(text.as_bytes()).and_then(|_| out.flush()) {
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => std::process::exit(0),
        other => Ok(other?),
    }
}

/// Reports a failed take on standard error without stopping the batch. Library errors name
/// their file already; others get the path in front.
pub fn report_failure(path: &std::path::Path, err: &anyhow::Error) {
    FAILURES.fetch_add(1, Ordering::Relaxed);
    let text = format!("{err:#}");
    if text.contains(&path.display().to_string()) {
        eprintln!("locap: {text}");
    } else {
        eprintln!("locap: {}: {text}", path.display());
    }
}

/// A progress bar over `len` takes on standard error; for a single take, a spinner that shows
/// the work is alive. indicatif draws nothing when standard error is not a terminal (CI logs,
/// render-farm jobs).
pub fn progress(len: usize, what: &str) -> indicatif::ProgressBar {
    if len < 2 {
        let spinner = indicatif::ProgressBar::new_spinner();
        spinner.set_message(format!("{what}..."));
        spinner.enable_steady_tick(std::time::Duration::from_millis(120));
        return spinner;
    }
    let bar = indicatif::ProgressBar::new(len as u64);
    let style = indicatif::ProgressStyle::with_template("{msg} [{bar:40}] {pos}/{len} ({eta})")
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar())
        .progress_chars("=> ");
    bar.set_style(style);
    bar.set_message(what.to_string());
    bar
}

/// Runs `job` on every take in parallel (one take = one job) behind a progress bar, reports
/// each failure as `path: reason` without stopping the others, and returns the successes in
/// input order with the number of failures.
pub fn run_takes<T: Send>(
    files: &[std::path::PathBuf],
    what: &str,
    job: impl Fn(usize, &std::path::Path) -> anyhow::Result<T> + Sync,
) -> (Vec<(std::path::PathBuf, T)>, usize) {
    use rayon::prelude::*;
    let bar = progress(files.len(), what);
    let results: Vec<anyhow::Result<T>> = files
        .par_iter()
        .enumerate()
        .map(|(i, path)| {
            let result = job(i, path);
            bar.inc(1);
            result
        })
        .collect();
    bar.finish_and_clear();
    let mut failed = 0;
    let mut done = Vec::new();
    for (path, result) in files.iter().zip(results) {
        match result {
            Ok(value) => done.push((path.clone(), value)),
            Err(err) => {
                failed += 1;
                report_failure(path, &err);
            }
        }
    }
    (done, failed)
}
