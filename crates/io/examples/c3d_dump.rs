//! Prints what the C3D reader sees in a file (debugging aid): `cargo run --example c3d_dump FILE`.
fn main() {
    let Some(path) = std::env::args().nth(1) else {
        eprintln!("usage: c3d_dump FILE");
        std::process::exit(2);
    };
    match locap_io::c3d::read_path(std::path::Path::new(&path)) {
        Ok(f) => {
            println!("{:?} frames={} points={} storage={:?}", f.processor, f.frames, f.point_count, f.storage);
            println!("{:#?}", f.header.events);
            for r in &f.parameters.records {
                match r {
                    locap_io::c3d::Record::Group(g) => println!("GROUP {} {}", g.id, g.name),
                    locap_io::c3d::Record::Parameter(p) => {
                        println!("  {} {:?} {:?}", p.name, p.dims, p.data)
                    }
                }
            }
            for w in &f.warnings {
                println!("warning: {w}");
            }
        }
        Err(e) => {
            eprintln!("{e}");
            std::process::exit(1);
        }
    }
}
