//! `locap bench label` with its defaults, without the CLI:
//! `cargo run --release -p locap-eval --example label_bench -- TAKES...` prints the table
//! (every method from each segment's first frame, then ours with the other half of each take
//! as template).

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut takes = Vec::new();
    for path in std::env::args().skip(1) {
        let take = locap_io::c3d::read_path(std::path::Path::new(&path))?.to_take()?;
        takes.push((path, take));
    }
    let report = locap_eval::label_bench::run(&takes, &locap_eval::label_bench::LabelBenchConfig::default())?;
    print!("{}", report.table());
    Ok(())
}
