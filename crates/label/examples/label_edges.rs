//! Prints each marker's ranked neighbours with their distance spread, for a labeled C3D
//! take: `cargo run --release -p locap-label --example label_edges -- TAKE.c3d`.
fn main() -> Result<(), Box<dyn std::error::Error>> {
    let path = std::env::args().nth(1).ok_or("usage: label_edges TAKE.c3d")?;
    let take = locap_io::c3d::read_path(std::path::Path::new(&path))?.to_take()?;
    let template = locap_label::Template::from_take(&take, None)?;
    for (name, edges) in template.names().iter().zip(template.edges()) {
        let list: Vec<String> = edges
            .iter()
            .map(|e| format!("{}({:.0}mm ±{:.1})", template.names()[e.neighbour].label, e.length_mm, e.std_mm))
            .collect();
        println!("{:6} {}", name.label, list.join(" "));
    }
    Ok(())
}
