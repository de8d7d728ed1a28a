//! The lattice's effective stiffness against its closed-form derivation
//! (issue 29; the rheology README's "Effective stiffness of the lattice"):
//! under a uniaxial stress σ a block of any size, spacing and voxel shape
//! strains as one basic element with E = (144/19)·K/a, η1 = (144/19)·C1/a,
//! η2 = (144/19)·C2/(1 − a), sideways by −ν = −5/19 times that. The
//! numbers 144/19 and 5/19 are written here from the hand derivation
//! (C11 = 28/3, C12 = 10/3 in units of K/a), not taken from the crate.
use plant_rheology::effective::uniaxial_creep;
use plant_rheology::lattice::{Lattice, VolumeMode};
use plant_rheology::params::{ElementParams, PA_PER_GF_PER_CM2};
use rand::{Rng, SeedableRng};

/// The closed form: axial creep strain of the block under `stress_pa`.
fn closed_form_strain(p: &ElementParams, stress_pa: f64, t_s: f64) -> f64 {
    let s = 144.0 / 19.0 * PA_PER_GF_PER_CM2;
    let (e, eta1, eta2) = (
        s * p.k_gf_per_cm2 / p.a,
        s * p.c1_gfs_per_cm2 / p.a,
        s * p.c2_gfs_per_cm2 / (1.0 - p.a),
    );
    stress_pa / e * (1.0 - (-t_s * e / eta1).exp()) + stress_pa * t_s / eta2
}

/// Runs the block to 0.25, 1 and 3 retardation times (C1/K) at a strain
/// of about 1e-4 and returns the worst relative error of the axial strain
/// and of the Poisson ratio against the closed forms.
fn check_block(
    grid: [usize; 3],
    size_cm: [f64; 3],
    volume: VolumeMode,
    p: &ElementParams,
) -> (f64, f64) {
    let lat = Lattice::grid(grid, size_cm.map(|c| c * 0.01), volume).unwrap();
    let tau = p.c1_gfs_per_cm2 / p.k_gf_per_cm2;
    // A strain of 1e-4 at the last time (creep included): linear geometry.
    let stress = 1e-4 / closed_form_strain(p, 1.0, 3.0 * tau);
    let times = [0.25 * tau, tau, 3.0 * tau];
    let got = uniaxial_creep(&lat, p, stress, tau / 400.0, &times).unwrap();
    let (mut axial, mut poisson) = (0.0f64, 0.0f64);
    for s in &got {
        let want = closed_form_strain(p, stress, s.t_s);
        axial = axial.max((s.axial / want - 1.0).abs());
        for l in s.lateral {
            poisson = poisson.max((-l / s.axial / (5.0 / 19.0) - 1.0).abs());
        }
    }
    (axial, poisson)
}

#[test]
fn blocks_of_several_sizes_and_spacings_creep_as_the_derived_modulus_and_poisson_ratio() {
    let p = ElementParams::PAPER_DEFAULT;
    let stiff_c2 = ElementParams {
        c2_gfs_per_cm2: 1e6,
        ..p
    };
    for (grid, size, volume, params) in [
        ([2, 2, 2], [1.0, 1.0, 1.0], VolumeMode::None, p),
        ([6, 4, 6], [10.0, 6.0, 10.0], VolumeMode::None, p),
        ([4, 5, 3], [4.5, 6.0, 3.0], VolumeMode::Local, stiff_c2),
        // Non-cubic voxels: the 1.43 × 1 × 1.43 cm (0.50× as stiff
        // vertically before issue 29) and the GA/RA experiment's 1.5 × 2 ×
        // 1.5 cm (1.76×).
        ([8, 7, 8], [10.0, 6.0, 10.0], VolumeMode::None, p),
        ([5, 4, 5], [6.0, 4.0, 6.0], VolumeMode::Local, p),
    ] {
        let (axial, poisson) = check_block(grid, size, volume, &params);
        // Backward Euler at τ/400 and the 1e-4 strain's geometric terms.
        assert!(
            axial < 5e-3,
            "{grid:?} on {size:?} cm: axial strain off by {axial:.2e}"
        );
        assert!(
            poisson < 5e-3,
            "{grid:?} on {size:?} cm: Poisson ratio off by {poisson:.2e}"
        );
    }
}

#[test]
fn voxels_too_far_from_cubic_are_refused_by_name() {
    // 1.25 × 1.5 × 0.83 cm (the issue's [9, 5, 13], 2.1× as stiff before).
    let e = Lattice::grid([9, 5, 13], [0.10, 0.06, 0.10], VolumeMode::None).unwrap_err();
    let text = e.to_string();
    assert!(
        text.contains("block.grid") && text.contains("cubic"),
        "{text}"
    );
}

/// The short form of the randomised campaign (the example
/// `stiffness_campaign` runs 500 cases): random element constants in the
/// paper's ranges, random spacings with aspect ratios up to 1.6, random
/// grids and volume modes. Every accepted lattice creeps as the closed
/// form within 0.5 %; the refused ones are counted, and only shapes far
/// from cubic are refused.
#[test]
fn a_randomised_campaign_of_constants_spacings_and_aspect_ratios_meets_the_closed_form() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(29);
    let (mut accepted, mut refused) = (0, 0);
    for _ in 0..12 {
        let p = ElementParams {
            k_gf_per_cm2: rng.gen_range(100.0..3000.0),
            c1_gfs_per_cm2: rng.gen_range(500.0..1e5),
            c2_gfs_per_cm2: rng.gen_range(500.0..2e5),
            a: rng.gen_range(0.3..0.7),
        };
        let base = rng.gen_range(0.5..2.0);
        let grid: [usize; 3] = std::array::from_fn(|_| rng.gen_range(2..5));
        let spacing: [f64; 3] = std::array::from_fn(|_| base * rng.gen_range(1.0..1.6));
        let size = std::array::from_fn(|i| spacing[i] * (grid[i] - 1) as f64);
        let volume = if rng.gen_bool(0.5) {
            VolumeMode::None
        } else {
            VolumeMode::Local
        };
        let aspect = spacing.iter().cloned().fold(0.0, f64::max)
            / spacing.iter().cloned().fold(f64::INFINITY, f64::min);
        match Lattice::grid(grid, size.map(|c: f64| c * 0.01), volume) {
            Ok(_) => {
                accepted += 1;
                let (axial, poisson) = check_block(grid, size, volume, &p);
                assert!(
                    axial < 5e-3 && poisson < 5e-3,
                    "{grid:?} spacing {spacing:?} cm, {p:?}: axial {axial:.2e}, ν {poisson:.2e}"
                );
            }
            Err(e) => {
                refused += 1;
                assert!(aspect > 1.15, "refused a near-cubic voxel {spacing:?}: {e}");
            }
        }
    }
    assert!(accepted >= 6, "accepted {accepted}, refused {refused}");
}
