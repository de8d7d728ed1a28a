//! Zhang's Table I comparison on a synthetic twin: matching by strength
//! alone, with the direction constraint, and with Eq. 5 as printed, scored
//! against the known field.
//!
//! ```sh
//! cargo run --release -p plant-tissue --example tissue_twin -- 256 256 57 [seed] [n_iv] [n_fv]
//! ```
use plant_tissue::field::matching::Consistency;
use plant_tissue::field::pipeline::FieldParams;
use plant_tissue::field::synth::{make_twin, SynthSpec};
use plant_tissue::field::twin::compare_on_twin;
use std::time::Instant;

fn main() {
    let a: Vec<usize> = std::env::args()
        .skip(1)
        .filter_map(|s| s.parse().ok())
        .collect();
    let dims = [
        *a.first().unwrap_or(&256),
        *a.get(1).unwrap_or(&256),
        *a.get(2).unwrap_or(&57),
    ];
    let seed = *a.get(3).unwrap_or(&1) as u64;
    let env = |k: &str, d: f64| {
        std::env::var(k)
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(d)
    };
    let base = SynthSpec::with_dims(dims);
    let spec = SynthSpec {
        seed,
        noise_sigma: env("NOISE", base.noise_sigma),
        warp_amplitude_mm: env("AMP", base.warp_amplitude_mm),
        ..base
    };
    let t0 = Instant::now();
    let twin = make_twin(&spec).expect("twin");
    let t_twin = t0.elapsed();
    let mut params = FieldParams {
        features_initial: *a.get(4).unwrap_or(&1000),
        features_deformed: *a.get(5).unwrap_or(&5000),
        seed,
        ..FieldParams::default()
    };
    params.matching.min_correlation = env("MINCORR", params.matching.min_correlation);
    params.matching.min_strength = env("MINSM", params.matching.min_strength);
    let t1 = Instant::now();
    let (report, _, _) = compare_on_twin(&twin, &params, &Consistency::ALL).expect("comparison");
    let t_cmp = t1.elapsed();
    println!("{}", serde_json::to_string_pretty(&report).unwrap());
    eprintln!(
        "twin {:.2} s, comparison {:.2} s",
        t_twin.as_secs_f64(),
        t_cmp.as_secs_f64()
    );
}
