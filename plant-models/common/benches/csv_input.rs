//! Reading numeric CSV (`csv_input::read_numeric`): files of 10,000 to
//! 1,000,000 rows of four columns, the size of a 1 kHz identification log
//! of 4 to 17 minutes. The time must grow linearly with the rows.
use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use plant_common::csv_input::read_numeric;
use std::hint::black_box;
use std::time::Duration;

fn table(rows: usize) -> String {
    let mut text = String::from("t_s,u_v,d_mm,theta_deg\n");
    for k in 0..rows {
        let t = k as f64 * 1e-3;
        text.push_str(&format!(
            "{t:.3},{:.4},{:.5},{:.4}\n",
            1.7 + (t * 0.7).sin(),
            2.0 * (t * 1.3).cos(),
            10.0 * (t * 0.2).sin()
        ));
    }
    text
}

fn read(c: &mut Criterion) {
    let mut g = c.benchmark_group("csv_read_numeric");
    g.sample_size(10).measurement_time(Duration::from_secs(10));
    for rows in [10_000, 100_000, 1_000_000] {
        let text = table(rows);
        g.throughput(Throughput::Elements(rows as u64));
        g.bench_with_input(BenchmarkId::from_parameter(rows), &text, |b, text| {
            b.iter(|| {
                read_numeric(black_box(text), "bench.csv")
                    .unwrap()
                    .rows
                    .len()
            })
        });
    }
    g.finish();
}

criterion_group!(benches, read);
criterion_main!(benches);
