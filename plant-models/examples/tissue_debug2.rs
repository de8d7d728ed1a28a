use plant_models::tissue::field::harris::{detect, HarrisParams};
use plant_models::tissue::field::volume::Volume;
fn main() {
    let n = 64;
    let mut data = vec![0f32; n * n * n];
    for z in 0..n {
        for y in 0..n {
            for x in 0..n {
                let f = |c: usize| {
                    let d = (c % 8) as f64 - 4.0;
                    d * d
                };
                let r2 = f(x) + f(y) + f(z);
                data[x + n * (y + n * z)] = (100.0 * (-r2 / 4.0).exp()) as f32;
            }
        }
    }
    let v = Volume::new([n; 3], [1.0; 3], data, "blobs").unwrap();
    let p = detect(&v, &HarrisParams::default(), 100000).unwrap();
    println!("maxima {}", p.len());
    for f in p.iter().take(3) {
        println!("{f:?}");
    }
}
