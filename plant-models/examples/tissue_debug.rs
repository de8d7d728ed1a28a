use plant_models::tissue::field::harris::{detect, HarrisParams};
use plant_models::tissue::field::synth::{make_twin, SynthSpec};
fn main() {
    let a: Vec<usize> = std::env::args()
        .skip(1)
        .filter_map(|s| s.parse().ok())
        .collect();
    let dims = [a[0], a[1], a[2]];
    let mut spec = SynthSpec::with_dims(dims);
    spec.cell_mm = a[3] as f64 / 10.0;
    if a[4] == 1 {
        spec.warp_bumps = 0;
        spec.noise_sigma = 0.0;
    }
    if a[4] == 2 {
        spec.warp_bumps = 0;
        spec.noise_sigma = 0.0;
        spec.rotation_deg = 0.0;
        spec.translation_mm = [0.0; 3];
    }
    let twin = make_twin(&spec).unwrap();
    let hp = HarrisParams::default();
    let r = plant_models::tissue::field::harris::response_volume(&twin.initial, &hp).unwrap();
    let v = &twin.initial;
    let z = dims[2] / 2;
    let y = dims[1] / 2;
    let line: Vec<String> = (20..108)
        .map(|x| format!("{:.0}/{:.1e}", v.at(x, y, z), r[v.index(x, y, z)]))
        .collect();
    println!("{}", line.join(" "));
    let mut raw = Vec::new();
    for y in 0..dims[1] {
        for x in 0..dims[0] {
            raw.extend_from_slice(&v.at(x, y, z).to_le_bytes());
        }
    }
    for y in 0..dims[1] {
        for x in 0..dims[0] {
            raw.extend_from_slice(&(r[v.index(x, y, z)] as f32).to_le_bytes());
        }
    }
    std::fs::write("/tmp/dbg/slice.raw", raw).unwrap();
    let fi = detect(&twin.initial, &hp, 100000).unwrap();
    let ff = detect(&twin.deformed, &hp, 100000).unwrap();
    println!("maxima iv {} fv {}", fi.len(), ff.len());
    let inside = fi
        .iter()
        .filter(|f| twin.tissue.inside_body(f.position_mm))
        .count();
    println!("iv inside body {inside}");
    for n in [100, 300, 1000] {
        let mut hits = [0usize; 4];
        for f in fi.iter().take(n) {
            let q = twin.warp.forward_mm(f.position_mm);
            let d = ff
                .iter()
                .take(5 * n)
                .map(|g| {
                    ((0..3)
                        .map(|k| (g.position_mm[k] - q[k]).powi(2))
                        .sum::<f64>())
                    .sqrt()
                })
                .fold(f64::INFINITY, f64::min);
            for (k, t) in [0.5, 1.0, 2.0, 4.0].iter().enumerate() {
                if d < *t {
                    hits[k] += 1;
                }
            }
        }
        println!("top {n}: repeat within 0.5/1/2/4 mm: {hits:?}");
    }
    for f in fi.iter().take(5) {
        println!("{f:?}");
    }
    for f in fi.iter().skip(200).take(3) {
        println!("{f:?}");
    }
}
#[allow(dead_code)]
fn dump() {}
