//! `locap convert`: between formats, chosen from the file extensions.

use anyhow::Result;
use clap::Parser;
use std::path::PathBuf;
use std::process::ExitCode;

/// Arguments of `locap convert`.
#[derive(Parser, Debug)]
pub struct Args {
    /// Input file.
    input: PathBuf,
    /// Output file.
    output: PathBuf,
}

/// Runs `locap convert`.
pub fn run(args: Args) -> Result<ExitCode> {
    let _ = args;
    anyhow::bail!("convert is not available yet")
}
