//! Tetrahedral Voigt benchmarks (seed 000, Yamaguchi): one 1 kHz
//! deformation tick (all its substeps) of the cube at every refinement
//! level 3–9 with a node held 4 mm down (the seed: 1000 Hz at level 3 down
//! to 50 Hz at 729 nodes, L2664–2665); Eq. 3 point location in the
//! level-9 mesh; encoding and decoding the 64-byte packet; one tick of the
//! virtual two-site session (both sites' replicas, codec, link, emulator)
//! at level 6 under Table 2's profile.
use criterion::{criterion_group, criterion_main, BatchSize, Criterion, Throughput};
use plant_tetmsd::locate::locate;
use plant_tetmsd::mesh::CubeMesh;
use plant_tetmsd::model::probe::{Grip, Manipulation};
use plant_tetmsd::model::voigt::{Hold, VoigtMaterial, VoigtModel};
use plant_tetmsd::model::V3;
use plant_tetmsd::netem::{Profile, TABLE_2};
use plant_tetmsd::packet::{Acks, Copies, Message, Packet, Stamp};
use plant_tetmsd::pair::run_virtual;
use plant_tetmsd::scenario::Scenario;
use std::hint::black_box;
use std::time::Duration;

const SIDE_M: f64 = 0.06;

fn deformation_tick(c: &mut Criterion) {
    let mut g = c.benchmark_group("tetmsd_deformation_tick");
    g.measurement_time(Duration::from_secs(3));
    for level in 3..=9 {
        let model = VoigtModel::new(
            CubeMesh::new(level, SIDE_M).unwrap(),
            VoigtMaterial::default(),
        )
        .unwrap();
        let node = model.mesh().nearest_node(V3::new(0.03, 0.03, SIDE_M));
        let hold = [Hold {
            node: node as u32,
            target_m: model.mesh().nodes_m[node] - V3::z() * 0.004,
        }];
        // Start from a pressed, moving state: 200 ticks into the press.
        let mut state = model.rest_state();
        let mut scratch = Vec::new();
        for k in 1..=200 {
            let f = f64::from(k) / 200.0;
            let h = [Hold {
                node: node as u32,
                target_m: model.mesh().nodes_m[node] - V3::z() * 0.004 * f,
            }];
            model.step(&mut state, &h, &mut scratch).unwrap();
        }
        let name = format!(
            "level {level} ({} nodes, {} substeps)",
            model.mesh().node_count(),
            model.substeps()
        );
        g.throughput(Throughput::Elements(1));
        g.bench_function(name, |b| {
            b.iter_batched_ref(
                || state.clone(),
                |s| model.step(s, black_box(&hold), &mut scratch).unwrap(),
                BatchSize::SmallInput,
            )
        });
    }
    g.finish();
}

fn point_location(c: &mut Criterion) {
    let mesh = CubeMesh::new(9, SIDE_M).unwrap();
    let mut g = c.benchmark_group("tetmsd_eq3_locate_level9");
    // Just under the top face (found among the last tetrahedra) and outside.
    g.bench_function("inside, under the top face", |b| {
        b.iter(|| {
            locate(
                &mesh.nodes_m,
                &mesh.tets,
                black_box(V3::new(0.0213, 0.0331, 0.0598)),
            )
        })
    });
    g.bench_function("outside the cube", |b| {
        b.iter(|| {
            locate(
                &mesh.nodes_m,
                &mesh.tets,
                black_box(V3::new(0.03, 0.03, 0.0601)),
            )
        })
    });
    g.finish();
}

fn codec(c: &mut Criterion) {
    let p = Packet {
        site: 1,
        message: Message::Input {
            tick: 123_456,
            stamp: Stamp::default(),
            copies: Copies::none(),
            acks: Acks {
                ack: 7,
                sack: 0b1010,
            },
            input: Manipulation {
                tip_m: V3::new(0.021, 0.033, 0.0598),
                grip: Some(Grip {
                    tet: 1234,
                    node: 321,
                    node_m: V3::new(0.0225, 0.03, 0.0598),
                }),
            },
        },
    };
    let bytes = p.encode();
    let mut g = c.benchmark_group("tetmsd_packet");
    g.bench_function("encode", |b| b.iter(|| black_box(&p).encode()));
    g.bench_function("decode", |b| {
        b.iter(|| Packet::decode(black_box(&bytes)).unwrap())
    });
    g.finish();
}

fn session(c: &mut Criterion) {
    let scenario = Scenario {
        duration_s: 1.0,
        ..Scenario::default()
    };
    let mut cfg = scenario.pair_config("bench").unwrap();
    cfg.netem.profile = Profile::Paper(&TABLE_2);
    let mut g = c.benchmark_group("tetmsd_virtual_pair");
    g.sample_size(10);
    g.throughput(Throughput::Elements(cfg.duration_ticks));
    g.bench_function("level 6, table2, 1 s (per tick: both sites)", |b| {
        b.iter(|| run_virtual(black_box(&cfg)).unwrap().completed_tick)
    });
    g.finish();
}

criterion_group!(benches, deformation_tick, point_location, codec, session);
criterion_main!(benches);
