//! The link against bursty loss (issue 30): the emulator's Gilbert chain
//! (`NetemConfig::burst_len`, runs of lost packets of that mean length,
//! long-run loss unchanged) on two long paths, with K = 3 (the default)
//! and K = 8 copies per input packet: whether the committed lag's p99
//! stays within one round trip + 50 ms once runs of losses outlast the
//! copies. 10 s per row at level 3, seed 1; about 20 s in all. Figures in
//! plant-models/tetmsd/README.md ("Link figures on every path").
//!
//! `cargo run --release -p plant-tetmsd --example burst_table`
use plant_tetmsd::netem::{NetemConfig, Profile};
use plant_tetmsd::pair::run_virtual;
use plant_tetmsd::paths::{PathCase, PathFigures};
use plant_tetmsd::scenario::Scenario;
fn main() {
    for (rtt, loss) in [(100u64, 0.05f64), (200, 0.01)] {
        for burst in [1.0f64, 2.0, 4.0, 8.0] {
            for k in [3usize, 8] {
                let s = Scenario {
                    level: 3,
                    duration_s: 10.0,
                    seed: 1,
                    ..Scenario::default()
                };
                let mut cfg = s.pair_config("burst table").unwrap();
                let profile = Profile::Constant(rtt * 1000);
                cfg.netem = NetemConfig {
                    profile,
                    loss,
                    reorder: 0.0,
                    burst_len: burst,
                    ..cfg.netem
                };
                cfg.session.link.redundancy = k;
                let r = run_virtual(&cfg).unwrap();
                let f = PathFigures::of(
                    PathCase {
                        profile,
                        loss,
                        reorder: 0.0,
                    },
                    cfg.duration_ticks,
                    &r,
                );
                println!("rtt {rtt} loss {loss} burst {burst} K {k}: lag p99 {:.0}/{:.0} (bound {:.0}), resends {}/{} for lost {}/{}, rtt {:.1}",
                    f.sites[0].lag_p99_ms, f.sites[1].lag_p99_ms, f.lag_bound_ms(0), f.sites[0].resends, f.sites[1].resends, f.sites[0].lost, f.sites[1].lost, f.sites[0].rtt_measured_ms);
            }
        }
    }
}
