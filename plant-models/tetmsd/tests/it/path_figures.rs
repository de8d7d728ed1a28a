//! The CI form of the path table (`examples/path_table.rs`, the full
//! table and its figures in plant-models/tetmsd/README.md): 2 s of session
//! at level 3 on the corners of the issue-30 grid. Each figure the link
//! measures is checked against what the emulators did (`paths`): the
//! mean round trip within 10 % of the path's, resends at most 1.2 × the
//! inputs really dropped, the replicas bit-identical; the committed lag's
//! p99 within one round trip + 50 ms on the paths where no input is lost
//! and on the short lossy path. (On long lossy paths the lag criterion is
//! not met — a lost input holds the committed replica a round trip plus a
//! one-way trip behind, see `paths` — and the table shows by how much.)
use plant_tetmsd::netem::{Profile, TABLE_4};
use plant_tetmsd::paths::{run_case, PathCase};

fn case(profile: Profile, loss: f64, reorder: f64) -> PathCase {
    PathCase {
        profile,
        loss,
        reorder,
    }
}

#[test]
fn round_trips_resends_lag_and_replicas_on_the_grid_corners() {
    let ms = |v: u64| Profile::Constant(v * 1000);
    let cases = [
        (case(ms(10), 0.10, 0.10), true),
        (case(ms(10), 0.01, 0.0), true),
        (case(ms(200), 0.0, 0.10), true),
        (case(ms(200), 0.10, 0.0), false),
        (case(ms(50), 0.05, 0.05), false),
        (case(Profile::Paper(&TABLE_4), 0.05, 0.05), true),
    ];
    for (c, lag_checked) in cases {
        let f = run_case(c, 3, 2.0, 1).unwrap();
        let name = c.label();
        assert!(f.identical, "{name}");
        for (s, site) in f.sites.iter().enumerate() {
            assert!(site.rtt_samples > 1000, "{name}: site {s}");
            let err = (site.rtt_measured_ms - site.rtt_path_ms).abs() / site.rtt_path_ms;
            assert!(err <= 0.10, "{name}: site {s}: {site:?}");
            assert!(
                site.resends as f64 <= 1.2 * site.lost as f64,
                "{name}: site {s}: {site:?}"
            );
            if c.loss > 0.0 {
                assert!(
                    site.lost > 0 && site.resends >= site.lost,
                    "{name}: {site:?}"
                );
            }
            if lag_checked {
                assert!(
                    site.lag_p99_ms <= f.lag_bound_ms(s),
                    "{name}: site {s}: {site:?}"
                );
            }
        }
        // Where the lag is not checked, it is the only criterion missed.
        for m in f.failures() {
            assert!(!lag_checked && m.contains("committed lag"), "{name}: {m}");
        }
    }
}
