//! Kita's phantom experiment on the twin: the 286 markers compressed to
//! 100 and 80 mm by the FEM and the geometric model.
//!
//! ```sh
//! cargo run --release -p plant-tissue --example tissue_compress -- [mesh_divisions] [step_mm]
//! ```
use plant_tissue::compress::compare::{run, CompressionSpec};
use std::time::Instant;

fn main() {
    let a: Vec<f64> = std::env::args()
        .skip(1)
        .filter_map(|s| s.parse().ok())
        .collect();
    let spec = CompressionSpec {
        mesh_divisions: a.first().map_or(6, |v| *v as usize),
        step_mm: *a.get(1).unwrap_or(&1.0),
        ..CompressionSpec::default()
    };
    let t = Instant::now();
    let out = run(&spec).expect("compression");
    let dt = t.elapsed();
    println!("{}", serde_json::to_string_pretty(&out.report).unwrap());
    eprintln!(
        "{} nodes, {} increments: {:.2} s",
        out.report.nodes,
        out.report.stages.last().map_or(0, |s| s.increments),
        dt.as_secs_f64()
    );
}
