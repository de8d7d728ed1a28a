//! What every plant model shares, and nothing a single system owns: the
//! registry of random streams ([`rng`]), the value checks of parameter
//! validation ([`check`]), the one CSV reader ([`csv_input`]), sparse
//! (skyline) linear algebra ([`linalg`]), the small-strain tetrahedral FEM
//! ([`fem`]), the exact 3-element viscoelastic element that the joint's
//! sponge and seed 002's objects both integrate ([`three_element`]), and
//! text helpers for messages ([`strip_bom`], [`short_number`]).
//!
//! Everything here is std and deterministic: random effects take an
//! explicit seeded RNG.
pub mod check;
pub mod csv_input;
pub mod fem;
pub mod linalg;
pub mod scalar;
pub mod three_element;

pub mod rng {
    //! Seeded random streams, and the registry of their numbers.
    //!
    //! Every random effect of a simulation draws from a ChaCha8 stream keyed
    //! by the run's seed and a stream number. Different seeds are different
    //! keys (not shifted positions of one sequence, as `seed + k` would
    //! be), so no stream of one seed overlaps any stream of another, and
    //! each component's draws do not depend on how many draws the others
    //! took. Numbers in use:
    //!
    //! | stream | drawn by |
    //! |---|---|
    //! | [`CAMERA`] | the joint's camera noise and occlusion |
    //! | [`WIRE_BASE`] + k | wire sensor k's stick-slip (k = 0..4) |
    //! | [`HAL_SIM_SENSOR_BASE`] + k | `hal-sim`'s injected dropouts of coder k |
    //! | [`TETMSD_DELAY_BASE`] + s | `tetmsd`: one-way delays of the packets site s sends |
    //! | [`TETMSD_LOSS_BASE`] + s | `tetmsd`: loss and reordering draws of site s's packets |
    //! | [`TETMSD_TEST_BASE`] + k | `tetmsd` tests: random points, states and packets |
    //! | [`CONTOUR_BASE`] + k | contour splines: [`CONTOUR_SYNTH_NOISE`] (`contour synth` data), [`CONTOUR_MONTE_CARLO`] (Theorem 1 replicates), [`CONTOUR_MOVIE_NOISE`] (the deforming-contour movie's tracker noise), [`CONTOUR_CAMPAIGN`] (the random contours of the self-check campaign) |
    //! | [`LINK_FAULTS_BASE`] + d | the lockstep fault campaign's faults, direction d (0 host → board, 1 board → host) |
    //! | [`IDENTIFY_NOISE`] | identification logs: the electrical measurement noise |
    //! | [`IDENTIFY_REPLAY`] | retired: identification replays once held it (never drawn) |
    //! | [`IDENTIFY_SAMPLE`] | `softjoint tune`: plants sampled from the uncertainty |
    //! | [`IDENTIFY_SEARCH`] | `softjoint tune`: the candidate gains |
    //! | [`IDENTIFY_V_OFFSET`] | `softjoint tune --search-v-offset`: the candidates' v_offset |
    //! | [`IDENTIFY_STICKS`] | identification: the stick events averaged over in the wire replays (seed 8r + j: realisation r, sensor j) |
    //! | [`TISSUE_TEXTURE`] | `tissue::field` synthetic calf: compartments, vessels |
    //! | [`TISSUE_WARP`] | `tissue::field` synthetic twin: the non-rigid warp's bumps |
    //! | [`TISSUE_NOISE_INITIAL`] | `tissue::field` noise of the initial volume |
    //! | [`TISSUE_NOISE_DEFORMED`] | `tissue::field` noise of the deformed volume |
    //! | [`TISSUE_DELAUNAY_JITTER`] | `tissue::field` tie-breaking jitter of the Delaunay points |
    //! | [`RHEOLOGY_BASE`]: [`RHEOLOGY_POINTS`] | the rheology reference's surface-point sampling |
    //! | [`RHEOLOGY_POINT_NOISE`] | its surface-point noise |
    //! | [`RHEOLOGY_FORCE_NOISE`] | its force-sensor noise |
    //! | [`RHEOLOGY_SEARCH`] | the rheology calibrations (GA, RA, uniform search) |
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    /// The joint camera's stream.
    pub const CAMERA: u64 = 0;
    /// Wire sensor k's stream is `WIRE_BASE + k`.
    pub const WIRE_BASE: u64 = 1;
    /// `hal-sim`'s simulated coder k draws its dropouts from
    /// `HAL_SIM_SENSOR_BASE + k`.
    pub const HAL_SIM_SENSOR_BASE: u64 = 0x100;
    /// The tetrahedral session's network emulator draws the one-way delays
    /// of the packets site s (0 or 1) sends from `TETMSD_DELAY_BASE + s`.
    pub const TETMSD_DELAY_BASE: u64 = 0x300;
    /// … and their loss and reordering from `TETMSD_LOSS_BASE + s`.
    pub const TETMSD_LOSS_BASE: u64 = 0x302;
    /// Test data of the tetrahedral module (points, states, packets):
    /// `TETMSD_TEST_BASE + k`, k < 16.
    pub const TETMSD_TEST_BASE: u64 = 0x310;
    /// First stream of the contour splines (`plant_contour`).
    pub const CONTOUR_BASE: u64 = 0x500;
    /// Noise of the synthetic contour data `softjoint contour synth` writes.
    pub const CONTOUR_SYNTH_NOISE: u64 = CONTOUR_BASE;
    /// Noise of the Monte-Carlo replicates of Theorem 1.
    pub const CONTOUR_MONTE_CARLO: u64 = CONTOUR_BASE + 1;
    /// Tracker noise of the synthetic deforming-contour movie.
    pub const CONTOUR_MOVIE_NOISE: u64 = CONTOUR_BASE + 2;
    /// Shapes, sampling and noise of the random contours of the
    /// self-check campaign (issue 29).
    pub const CONTOUR_CAMPAIGN: u64 = CONTOUR_BASE + 3;
    /// The fault campaign of the lockstep link (`tests/src/fault_injector.rs`)
    /// draws the faults of direction d from `LINK_FAULTS_BASE + d`.
    pub const LINK_FAULTS_BASE: u64 = 0x200;
    /// Electrical measurement noise of identification logs (issue 20:
    /// 0x1400 + k; the README figures were made when these were 0x600 + k,
    /// which tissue now uses).
    pub const IDENTIFY_NOISE: u64 = 0x1400;
    /// Retired: identification replays once held this stream (never drawn).
    pub const IDENTIFY_REPLAY: u64 = 0x1401;
    /// Plants sampled from an identification's uncertainty.
    pub const IDENTIFY_SAMPLE: u64 = 0x1402;
    /// Candidate gains of a tuning search.
    pub const IDENTIFY_SEARCH: u64 = 0x1403;
    /// The candidates' v_offset when a tuning search includes it (its own
    /// stream, so the other gains are drawn as without it).
    pub const IDENTIFY_V_OFFSET: u64 = 0x1404;
    /// Identification's wire replays: the stick events of realisation r,
    /// sensor j, are `stream(8r + j, IDENTIFY_STICKS)`.
    pub const IDENTIFY_STICKS: u64 = 0x1405;

    /// The tissue module's streams start here (seed 000, Zhang and Kita).
    pub const TISSUE_BASE: u64 = 0x600;
    /// Texture of the synthetic calf volumes.
    pub const TISSUE_TEXTURE: u64 = TISSUE_BASE;
    /// Bumps of the synthetic twin's non-rigid warp.
    pub const TISSUE_WARP: u64 = TISSUE_BASE + 1;
    /// Noise of the synthetic initial volume.
    pub const TISSUE_NOISE_INITIAL: u64 = TISSUE_BASE + 2;
    /// Noise of the synthetic deformed volume.
    pub const TISSUE_NOISE_DEFORMED: u64 = TISSUE_BASE + 3;
    /// Sub-micrometre jitter that breaks ties of co-spherical Delaunay points.
    pub const TISSUE_DELAUNAY_JITTER: u64 = TISSUE_BASE + 4;

    /// The rheology module's streams start here (seed 000, Noborio; issue
    /// 14's number × 0x100).
    pub const RHEOLOGY_BASE: u64 = 0xE00;
    /// The rheology reference block's choice of surface points.
    pub const RHEOLOGY_POINTS: u64 = RHEOLOGY_BASE;
    /// The rheology reference block's surface-point noise.
    pub const RHEOLOGY_POINT_NOISE: u64 = RHEOLOGY_BASE + 1;
    /// The rheology reference block's force-sensor noise.
    pub const RHEOLOGY_FORCE_NOISE: u64 = RHEOLOGY_BASE + 2;
    /// The rheology calibrations' random draws (GA, RA, uniform search).
    pub const RHEOLOGY_SEARCH: u64 = RHEOLOGY_BASE + 3;

    /// Stream `stream` of seed `seed`.
    pub fn stream(seed: u64, stream: u64) -> ChaCha8Rng {
        let mut r = ChaCha8Rng::seed_from_u64(seed);
        r.set_stream(stream);
        r
    }

    #[cfg(test)]
    mod tests {
        use rand::RngCore;

        #[test]
        fn neighbouring_seeds_and_streams_do_not_overlap() {
            // The first 1024 words of streams 0..8 of seeds 1 and 2: no word
            // sequence of one appears shifted in another (as with `seed + k`,
            // where seed 1's stream 1 would be seed 2's stream 0).
            let words = |seed: u64, s: u64| {
                let mut r = super::stream(seed, s);
                (0..1024).map(|_| r.next_u64()).collect::<Vec<_>>()
            };
            let all: Vec<Vec<u64>> = (1..=2)
                .flat_map(|seed| (0..8).map(move |s| (seed, s)))
                .map(|(seed, s)| words(seed, s))
                .collect();
            for (i, a) in all.iter().enumerate() {
                for b in &all[i + 1..] {
                    assert!(!b.contains(&a[0]) && !a.contains(&b[0]), "streams overlap");
                }
            }
        }
    }
}

/// `text` without a leading UTF-8 byte-order mark, which Windows editors
/// and Excel write at the start of text files (the CSV reader drops it
/// itself; JSON parsers and line-based formats do not).
pub fn strip_bom(text: &str) -> &str {
    text.strip_prefix('\u{feff}').unwrap_or(text)
}

/// A number for an error message: as `{}` prints it, or in exponent form
/// when that would be a long run of digits (1e308 has 309).
pub fn short_number(v: f64) -> String {
    let a = v.abs();
    if a != 0.0 && a.is_finite() && !(1e-4..1e15).contains(&a) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}
