//! Reads a C3D file and writes it back through a Take (debugging aid):
//! `cargo run --example c3d_roundtrip IN OUT`.
fn main() {
    let args: Vec<String> = std::env::args().collect();
    if args.len() != 3 {
        eprintln!("usage: c3d_roundtrip IN OUT");
        std::process::exit(2);
    }
    let run = || -> locap_io::Result<()> {
        let mut file = locap_io::c3d::read_path(std::path::Path::new(&args[1]))?;
        let take = file.to_take()?;
        file.set_take(&take)?;
        locap_io::c3d::write_path(&file, std::path::Path::new(&args[2]))
    };
    if let Err(e) = run() {
        eprintln!("{e}");
        std::process::exit(1);
    }
}
