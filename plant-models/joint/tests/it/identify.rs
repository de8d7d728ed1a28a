//! Twin tests of the joint's identification (issue 20): a hidden plant
//! (`identify::hidden`: the defaults moved 20–50 %, a Clausius–Clapeyron
//! slope of 0.08 K/MPa, camera noise 0.1°, jamming with stick events,
//! noisy current and resistance readings) records an excitation plan;
//! identification starts from the defaults and is not told the truth.
//!
//! The debug `cargo test` runs the 60 s compact plan; the 10-minute
//! standard plan with the tolerances of the README is `#[ignore]`d there
//! and run optimised by `scripts/test-all.sh` (profile ci-opt), or:
//! `cargo test --profile ci-opt -p plant-joint --test it identify:: -- --ignored`
//! (`--nocapture` prints every estimate against the truth).

use plant_joint::identify::{
    self, hidden, twin, ElectricalNoise, ExcitationPlan, IdentifyOptions, LmOptions, Param,
    PlaneMap, PlaneModel, PlaneReport,
};
use plant_joint::{Joint2dParams, Joint3dParams, PlaneParams, WireSensorParams};
use std::sync::OnceLock;

const NOISE: ElectricalNoise = ElectricalNoise {
    current_a: 0.002,
    resistance_ohm: 0.02,
};

fn truth(plane: &PlaneParams, wire: &WireSensorParams) -> PlaneModel {
    PlaneModel {
        plane: plane.clone(),
        wires: vec![wire.clone()],
        settle_s: 1.0,
        substep_s: 1e-3,
    }
}

/// Checks `p` against the truth: relative tolerance for scales, absolute
/// for temperatures and the slope. Returns a line for the failure report.
fn check(
    r: &PlaneReport,
    t: &PlaneModel,
    p: Param,
    rel: Option<f64>,
    abs: Option<f64>,
) -> Option<String> {
    let e = r
        .estimate(p)
        .unwrap_or_else(|| panic!("{p:?} not estimated: {:#?}", r.estimates));
    let tv = p.get(t);
    let ok = e.identifiable
        && match (rel, abs) {
            (Some(rel), _) => ((e.value - tv) / tv).abs() <= rel,
            (_, Some(abs)) => (e.value - tv).abs() <= abs,
            _ => true,
        };
    (!ok).then(|| {
        format!(
            "{}: {} ± {} (identifiable {}), true {tv}, prior {}",
            e.field, e.value, e.std, e.identifiable, e.prior
        )
    })
}

/// Prints the estimates against the truth (`--nocapture` shows them).
fn print_estimates(r: &PlaneReport, t: &PlaneModel) {
    for e in &r.estimates {
        let tv = e.param.get(t);
        eprintln!(
            "{} {}: {:.5} (fitted {:.5}) ± {:.2e} (white {:.2e}; identifiable {}), true {tv:.5}, error {:+.1} % = {:+.1} σ",
            r.plane,
            e.field,
            e.value,
            e.fitted,
            e.std,
            e.white_std,
            e.identifiable,
            100.0 * (e.fitted - tv) / tv,
            (e.fitted - tv) / e.std
        );
    }
    for st in &r.stages {
        eprintln!(
            "{} stage {}: {} iterations, {} replays, rms {:.3}, best of {} starts: #{}",
            r.plane,
            st.name,
            st.iterations,
            st.evaluations,
            st.rms_scaled,
            st.starts,
            st.best_start
        );
    }
    let v = &r.validation;
    eprintln!(
        "{}: held-out rms {:.3}°, max {:.3}°, prior held-out rms {:?}°",
        r.plane, v.heldout_rms_deg, v.heldout_max_deg, v.prior_heldout_rms_deg
    );
}

/// The CI form (≈ 15–30 s in a debug build).
#[test]
fn compact_twin_2d_recovers_driver_temperatures_slope_and_sponge() {
    let hidden = hidden::joint_2d(3);
    let plan = ExcitationPlan::compact(1);
    let log = twin::record_2d(&hidden, &plan, true, NOISE).unwrap();
    let opts = IdentifyOptions {
        lm: LmOptions {
            max_iterations: 8,
            ..IdentifyOptions::default().lm
        },
        ..IdentifyOptions::default()
    };
    let (_, reports) = identify::identify_2d(&log, &Joint2dParams::default(), &opts).unwrap();
    let r = &reports[0];
    let t = truth(&hidden.plane, &hidden.wire);
    print_estimates(r, &t);
    let fails: Vec<String> = [
        check(r, &t, Param::Transconductance, Some(0.02), None),
        check(r, &t, Param::AusteniteStart, None, Some(2.0)),
        check(r, &t, Param::SpongeModulus, Some(0.10), None),
    ]
    .into_iter()
    .flatten()
    .collect();
    assert!(fails.is_empty(), "{fails:#?}");
    // The link inertia is not seen by a 30 frames/s camera: named, and
    // left at its prior.
    let inertia = r.estimate(Param::LinkInertia).unwrap();
    assert!(!inertia.identifiable, "{inertia:?}");
    assert_eq!(inertia.value, inertia.prior);
    // The prior mispredicts the held-out quarter by degrees; the
    // identified plant by little more than the camera noise.
    let v = &r.validation;
    assert!(
        v.prior_heldout_rms_deg.unwrap() > 2.0,
        "prior held-out rms {:?}, identified {}",
        v.prior_heldout_rms_deg,
        v.heldout_rms_deg
    );
    assert!(
        v.heldout_rms_deg < 0.3,
        "held-out rms {}",
        v.heldout_rms_deg
    );
}

/// The mechanics stage's secant updates between differenced Jacobians
/// (`LmOptions::secant_updates`, 4 by default) against the textbook
/// method (0) on the compact 2D twin, fits run to convergence (and
/// differenced: `derivative_jacobians` off): fewer mechanics replays, the same verdict,
/// the same parameters called identifiable and every estimate within its
/// 1σ of the textbook one. (Timings on longer logs: docs/benchmarks.md,
/// "Identification with secant updates".)
#[test]
#[ignore = "two identifications of the compact twin to convergence (≈ 10 CPU-s in ci-opt); CI runs it with the twins"]
fn secant_updates_save_mechanics_replays_on_the_compact_twin() {
    let hidden = hidden::joint_2d(3);
    let log = twin::record_2d(&hidden, &ExcitationPlan::compact(1), true, NOISE).unwrap();
    let run = |secant_updates| {
        let opts = IdentifyOptions {
            lm: LmOptions {
                secant_updates,
                ..IdentifyOptions::default().lm
            },
            derivative_jacobians: false,
            ..IdentifyOptions::default()
        };
        let (r, (evaluations, derived)) = compact_mechanics(&log, &opts);
        assert_eq!(derived, 0, "differences asked");
        (r, evaluations)
    };
    let (textbook, a) = run(0);
    let (secant, b) = run(IdentifyOptions::default().lm.secant_updates);
    assert_eq!(IdentifyOptions::default().lm.secant_updates, 4);
    eprintln!("mechanics replays: textbook {a}, secant updates {b}");
    assert!(b < a, "mechanics replays: textbook {a}, secant updates {b}");
    same_answers(&textbook, &secant);
}

/// The compact twin's log identified with `opts`, its mechanics fit run to
/// convergence: the plane's report and the mechanics stage's (plain
/// replays, replays with derivatives).
fn compact_mechanics(
    log: &identify::ExcitationLog,
    opts: &IdentifyOptions,
) -> (PlaneReport, (usize, usize)) {
    let (_, mut reports) = identify::identify_2d(log, &Joint2dParams::default(), opts).unwrap();
    let r = reports.remove(0);
    let st = r.stages.iter().find(|s| s.name == "mechanics").unwrap();
    assert!(!st.stopped_by_budget, "{st:?}");
    let counts = (st.evaluations, st.derivative_replays);
    (r, counts)
}

/// The verdict, the parameters called identifiable and every estimate
/// within its 1σ of `reference`'s.
fn same_answers(reference: &PlaneReport, other: &PlaneReport) {
    let (textbook, secant) = (reference, other);
    assert_eq!(textbook.verdict.verified, secant.verdict.verified);
    assert_eq!(textbook.estimates.len(), secant.estimates.len());
    for t in &textbook.estimates {
        let s = secant.estimate(t.param).unwrap();
        assert_eq!(t.identifiable, s.identifiable, "{t:?} / {s:?}");
        if t.identifiable {
            let z = (s.value - t.value) / t.std;
            assert!(
                z.abs() <= 1.0,
                "{}: {} against {} ({z:+.2} σ)",
                t.field,
                s.value,
                t.value
            );
        }
    }
}

/// The mechanics stage's Jacobians from a replay carrying derivatives
/// (`IdentifyOptions::derivative_jacobians`) against forward differences
/// on the compact 2D twin: far fewer plain replays (each Jacobian one
/// replay with derivatives instead of one per parameter), the same
/// verdict, the same parameters called identifiable and every estimate
/// within its 1σ of the differenced fit.
#[test]
#[ignore = "two identifications of the compact twin to convergence (≈ 10 CPU-s in ci-opt); CI runs it with the twins"]
fn derivative_jacobians_reach_the_differenced_fit_on_the_compact_twin() {
    let hidden = hidden::joint_2d(3);
    let log = twin::record_2d(&hidden, &ExcitationPlan::compact(1), true, NOISE).unwrap();
    let run = |derivative_jacobians| {
        let opts = IdentifyOptions {
            derivative_jacobians,
            ..IdentifyOptions::default()
        };
        compact_mechanics(&log, &opts)
    };
    assert!(IdentifyOptions::default().derivative_jacobians);
    let (differenced, a) = run(false);
    let (derived, b) = run(true);
    eprintln!(
        "mechanics (plain replays, replays with derivatives): differences {a:?}, derivatives {b:?}"
    );
    assert_eq!(a.1, 0);
    assert!(
        b.1 > 0 && b.0 < a.0 / 2,
        "differences {a:?}, derivatives {b:?}"
    );
    same_answers(&differenced, &derived);
}

/// The 10-minute standard plan on the hidden 2D joint, electrical columns
/// logged: the plane's report and its truth. Identified once per test
/// process (the ignored tests share it).
fn ten_minute_2d() -> &'static (PlaneReport, PlaneModel) {
    static TWIN: OnceLock<(PlaneReport, PlaneModel)> = OnceLock::new();
    TWIN.get_or_init(|| {
        let hidden = hidden::joint_2d(7);
        let plan = ExcitationPlan::standard(1, 600.0, false);
        let log = twin::record_2d(&hidden, &plan, true, NOISE).unwrap();
        let (_, mut reports) =
            identify::identify_2d(&log, &Joint2dParams::default(), &IdentifyOptions::default())
                .unwrap();
        (reports.remove(0), truth(&hidden.plane, &hidden.wire))
    })
}

/// The same on the hidden 3D joint of `seed`, whose planes are hidden
/// differently: α's and β's reports with their truths.
fn identify_3d_twin(seed: u64, noise: ElectricalNoise) -> Vec<(PlaneReport, PlaneModel)> {
    let hidden = hidden::joint_3d(seed);
    let plan = ExcitationPlan::standard(2, 600.0, false);
    let log = twin::record_3d(&hidden, &plan, true, noise).unwrap();
    let (_, reports) =
        identify::identify_3d(&log, &Joint3dParams::default(), &IdentifyOptions::default())
            .unwrap();
    let truths = [
        truth(&hidden.alpha, &hidden.wires[0]),
        truth(&hidden.beta, &hidden.wires[1]),
    ];
    reports.into_iter().zip(truths).collect()
}

/// The 3D twin of seed 11 with noisy electrical readings, once per test
/// process.
fn ten_minute_3d() -> &'static [(PlaneReport, PlaneModel)] {
    static TWIN: OnceLock<Vec<(PlaneReport, PlaneModel)>> = OnceLock::new();
    TWIN.get_or_init(|| identify_3d_twin(11, NOISE))
}

/// Tolerances as stated in plant-models/src/joint/README.md, every
/// parameter but the jamming gain (see
/// `ten_minute_twins_recover_the_jamming_gain_or_name_it_not_identifiable`): the failures, one line
/// each.
fn standard_fails(r: &PlaneReport, t: &PlaneModel) -> Vec<String> {
    print_estimates(r, t);
    let mut fails: Vec<String> = [
        check(r, t, Param::Transconductance, Some(0.02), None),
        check(r, t, Param::TurnOn, None, Some(0.02)),
        check(r, t, Param::Convection, Some(0.10), None),
        check(r, t, Param::AusteniteStart, None, Some(1.0)),
        check(r, t, Param::AusteniteFinish, None, Some(2.0)),
        check(r, t, Param::MartensiteStart, None, Some(2.0)),
        check(r, t, Param::MartensiteFinish, None, Some(2.0)),
        check(r, t, Param::StressShift, None, Some(0.02)),
        check(r, t, Param::SpongeModulus, Some(0.05), None),
        check(r, t, Param::SpongeDamping, Some(0.25), None),
        check(r, t, Param::JamMaxLag, Some(0.15), None),
        check(r, t, Param::JamLagPerMm, Some(0.60), None),
    ]
    .into_iter()
    .flatten()
    .map(|f| format!("{}: {f}", r.plane))
    .collect();
    if r.estimate(Param::LinkInertia).unwrap().identifiable {
        fails.push(format!("{}: link inertia called identifiable", r.plane));
    }
    let v = &r.validation;
    if v.heldout_rms_deg >= 0.15 {
        fails.push(format!("{}: held-out rms {}", r.plane, v.heldout_rms_deg));
    }
    if v.heldout_max_deg >= 0.6 {
        fails.push(format!("{}: held-out max {}", r.plane, v.heldout_max_deg));
    }
    fails
}

/// Whether the 1σ of `params` covers the error: |fitted − truth| ≤ `k`σ.
/// For the parameters whose model is right (electrical, thermal, slope,
/// sponge modulus) on the noisy twins; the failures, one line each.
fn coverage_fails(r: &PlaneReport, t: &PlaneModel, params: &[Param], k: f64) -> Vec<String> {
    params
        .iter()
        .filter_map(|&p| {
            let e = r.estimate(p)?;
            let err = e.fitted - p.get(t);
            (err.abs() > k * e.std).then(|| {
                format!(
                    "{}: {} off by {err:.3e}, {:.1} times its 1σ {:.3e}",
                    r.plane,
                    e.field,
                    err.abs() / e.std,
                    e.std
                )
            })
        })
        .collect()
}

/// The parameters whose 1σ must cover the error within 3σ (the model is
/// right for them; see the joint README for the damping and the lag
/// ceilings): the first nine of `Param::ALL`, driver to sponge modulus.
const COVERED: &[Param] = Param::ALL.split_at(9).0;

#[test]
#[ignore = "10-minute log: minutes in a debug build; CI runs it optimised (scripts/test-all.sh, profile ci-opt)"]
fn ten_minute_twin_2d_recovers_each_identifiable_parameter() {
    let (r, t) = ten_minute_2d();
    let mut fails = standard_fails(r, t);
    fails.extend(coverage_fails(r, t, COVERED, 3.0));
    assert!(fails.is_empty(), "{fails:#?}");
}

#[test]
#[ignore = "10-minute log: minutes in a debug build; CI runs it optimised (scripts/test-all.sh, profile ci-opt)"]
fn ten_minute_twin_3d_recovers_both_planes() {
    let fails: Vec<String> = ten_minute_3d()
        .iter()
        .flat_map(|(r, t)| {
            let mut f = standard_fails(r, t);
            f.extend(coverage_fails(r, t, COVERED, 3.0));
            f
        })
        .collect();
    assert!(fails.is_empty(), "{fails:#?}");
}

/// The jamming gain κ on both twins (three planes): where named
/// identifiable, within 30 % of the truth, otherwise kept at the prior;
/// either way the fit's value within 3σ of the truth, so the 1σ covers
/// the error (and the lag ceiling at rest e₀ within 3σ too). The wire
/// stage averages the random stick events over 32 realisations (module
/// docs of `replay`); what it cannot remove is that the log's own sticks
/// are one draw. Measured (joint README): κ −19.5 % ± 16 % (−1.3σ) on θ,
/// +62 % ± 66 % on α, +2 % ± 34 % on β, each named not identifiable (θ
/// by a hair: 1σ 0.055 against 0.05; with other stick streams it was
/// named identifiable at −20 % ± 13 %, so both branches are live).
#[test]
#[ignore = "10-minute logs: minutes in a debug build; CI runs it optimised (scripts/test-all.sh, profile ci-opt)"]
fn ten_minute_twins_recover_the_jamming_gain_or_name_it_not_identifiable() {
    let mut planes = vec![ten_minute_2d()];
    planes.extend(ten_minute_3d());
    let mut fails = Vec::new();
    for (r, t) in planes {
        print_estimates(r, t);
        let k = r.estimate(Param::JamGain).unwrap();
        let truth = Param::JamGain.get(t);
        if k.identifiable && ((k.fitted - truth) / truth).abs() > 0.30 {
            fails.push(format!(
                "{}: κ {} named identifiable, truth {truth}",
                r.plane, k.fitted
            ));
        }
        if !k.identifiable && k.value != k.prior {
            fails.push(format!(
                "{}: κ not identifiable but not at its prior",
                r.plane
            ));
        }
        fails.extend(coverage_fails(
            r,
            t,
            &[Param::JamGain, Param::JamMaxLag],
            2.0,
        ));
    }
    assert!(fails.is_empty(), "{fails:#?}");
}

/// Without current and resistance the thermal parameters come from the
/// angle alone: the driver's turn-on voltage is not fitted, and the
/// prediction still holds.
#[test]
#[ignore = "10-minute log: minutes in a debug build; CI runs it optimised (scripts/test-all.sh, profile ci-opt)"]
fn ten_minute_twin_2d_without_electrical_columns() {
    let hidden = hidden::joint_2d(7);
    let plan = ExcitationPlan::standard(1, 600.0, false);
    let log = twin::record_2d(&hidden, &plan, false, NOISE).unwrap();
    let (_, reports) =
        identify::identify_2d(&log, &Joint2dParams::default(), &IdentifyOptions::default())
            .unwrap();
    let r = &reports[0];
    assert!(r.estimate(Param::TurnOn).is_none());
    let v = &r.validation;
    assert!(
        v.heldout_rms_deg < 0.2,
        "held-out rms {}",
        v.heldout_rms_deg
    );
}

/// The README's twin: the hidden 3D joint of seed 7 with the electrical
/// readings as `softjoint sim --excite` logs them (no noise). β's link
/// inertia comes out 18 times the truth there with a white-noise 1σ of
/// 8.1 %, which passes the 15 % threshold (the call before the
/// block-robust 1σ); the block-robust 1σ is 18.5 %. The README's twin,
/// recorded by `sim`, is alike: 17 times, 8.5 % and 19 %. β alone is
/// identified, as `identify_3d` does it (each plane from the same log on
/// its own): α's is half the CPU of this check and the 3D twin of seed 11
/// holds α to the same tolerances.
#[test]
#[ignore = "10-minute log: minutes in a debug build; CI runs it optimised (scripts/test-all.sh, profile ci-opt)"]
fn ten_minute_twin_3d_seed_7_names_the_inertia_not_identifiable() {
    let hidden = hidden::joint_3d(7);
    let plan = ExcitationPlan::standard(2, 600.0, false);
    let log = twin::record_3d(&hidden, &plan, true, ElectricalNoise::default()).unwrap();
    let beta = identify_beta(&log);
    let beta_truth = truth(&hidden.beta, &hidden.wires[1]);
    let inertia = beta.estimate(Param::LinkInertia).unwrap();
    eprintln!(
        "beta inertia fitted {:.3e} (truth {:.3e}), 1σ {:.3e}, white {:.3e}",
        inertia.fitted,
        Param::LinkInertia.get(&beta_truth),
        inertia.std,
        inertia.white_std
    );
    let fails = standard_fails(&beta, &beta_truth);
    assert!(fails.is_empty(), "{fails:#?}");
}

/// β of a 3D log identified from the defaults as [`identify::identify_3d`]
/// identifies it (each plane from the same log on its own, so β's report
/// is the one `identify_3d` gives) at half its CPU.
fn identify_beta(log: &identify::ExcitationLog) -> PlaneReport {
    let opts = IdentifyOptions::default();
    let model = identify::prior_model_3d(&Joint3dParams::default(), 1, &opts);
    identify::identify_plane(log, PlaneMap::of(2, 1), model, "beta", &opts, None)
        .unwrap()
        .1
}

/// Issue 28's joint (`hidden::off_plan_joint_3d`: α's driver turns on at
/// 2.0 V, above the plan's sustained levels; β's at 1.6 V) on the 240 s
/// standard plan that `softjoint identify plan --duration-s 240` prints,
/// identified from the defaults (or from `prior`): α's and β's reports
/// with their truths. Recorded with the twins' electrical noise.
fn off_plan_240s(prior: Option<&Joint3dParams>) -> Vec<(PlaneReport, PlaneModel)> {
    let hidden = hidden::off_plan_joint_3d(5);
    let plan = ExcitationPlan::standard(2, 240.0, false);
    let log = twin::record_3d(&hidden, &plan, true, NOISE).unwrap();
    let default = Joint3dParams::default();
    let (_, reports) =
        identify::identify_3d(&log, prior.unwrap_or(&default), &IdentifyOptions::default())
            .unwrap();
    let truths = [
        truth(&hidden.alpha, &hidden.wires[0]),
        truth(&hidden.beta, &hidden.wires[1]),
    ];
    reports.into_iter().zip(truths).collect()
}

/// The parameters a plane reports as determined and verified whose fit
/// lies more than `k`σ from the truth, one line each: what a lab would
/// build on and be wrong.
fn wrong_but_called_identifiable(r: &PlaneReport, t: &PlaneModel, k: f64) -> Vec<String> {
    r.estimates
        .iter()
        .filter(|e| e.identifiable && e.verified && r.verdict.verified)
        .filter_map(|e| {
            let err = (e.fitted - e.param.get(t)) / e.std;
            (err.abs() > k)
                .then(|| format!("{}: {} is {err:+.1}σ from the truth", r.plane, e.field))
        })
        .collect()
}

/// Issue 28, first failure: before it, α came out with g +17 %, h +24 %,
/// the temperatures 1–4.4 K low and the slope −74 %, each called
/// identifiable 4.6–25.6σ from the truth, and a held-out rms of 0.062°
/// against 0.05° of camera noise that no check judged. Now the turn-on
/// is named not identifiable with what the currents show (no current up
/// to 1.9 V, a saturated one at 3 V), the driver the fit went through is
/// found to mispredict the logged currents, and the plane is unverified;
/// β, whose driver the plan excites, is verified and right.
#[test]
#[ignore = "a 240 s 3D log: ≈ 15–40 s optimised; CI runs it in the ci-opt build (scripts/test-all.sh)"]
fn off_plan_twin_names_the_turn_on_and_leaves_the_plane_unverified() {
    let planes = off_plan_240s(None);
    for (r, t) in &planes {
        print_estimates(r, t);
        eprintln!("{}: {:?}", r.plane, r.verdict);
    }
    let (alpha, beta) = (&planes[0].0, &planes[1].0);
    let turn_on = alpha.estimate(Param::TurnOn).expect("α's turn-on reported");
    assert!(!turn_on.identifiable, "{turn_on:?}");
    let why = turn_on.reason.as_deref().unwrap_or("");
    assert!(
        why.contains("no current: 1.9 V") && why.contains("with a current: 3 V"),
        "{why}"
    );
    assert!(!alpha.verdict.verified, "{:?}", alpha.verdict);
    assert!(
        alpha.verdict.driver.as_ref().is_some_and(|d| !d.passed),
        "{:?}",
        alpha.verdict
    );
    assert!(beta.verdict.verified, "{:?}", beta.verdict);
    let wrong: Vec<String> = planes
        .iter()
        .flat_map(|(r, t)| wrong_but_called_identifiable(r, t, 3.0))
        .collect();
    assert!(wrong.is_empty(), "{wrong:#?}");
}

/// Issue 28, second failure: `--prior` set to the very truth returned a
/// sponge 27 times too soft with a fit rms of 1.15°. Now the prior is a
/// candidate start of the mechanics stage, so no plane ends worse than
/// its prior (fit and held-out rms within `verify::PRIOR_MARGIN` of the
/// prior's on the same frames), both planes are verified, and the sponge
/// stays within 2 % of the truth.
#[test]
#[ignore = "a 240 s 3D log: ≈ 15–40 s optimised; CI runs it in the ci-opt build (scripts/test-all.sh)"]
fn a_true_prior_is_never_made_worse() {
    let hidden = hidden::off_plan_joint_3d(5);
    let planes = off_plan_240s(Some(&hidden));
    let mut fails = Vec::new();
    for (r, t) in &planes {
        print_estimates(r, t);
        let v = &r.validation;
        let margin = identify::verify::PRIOR_MARGIN;
        if v.fit_rms_deg > margin * v.prior_fit_rms_deg.unwrap() {
            fails.push(format!(
                "{}: fit rms {} vs prior {:?}",
                r.plane, v.fit_rms_deg, v.prior_fit_rms_deg
            ));
        }
        if v.heldout_rms_deg > margin * v.prior_heldout_rms_deg.unwrap() {
            fails.push(format!(
                "{}: held-out {} vs prior {:?}",
                r.plane, v.heldout_rms_deg, v.prior_heldout_rms_deg
            ));
        }
        if !r.verdict.verified {
            fails.push(format!("{}: {:?}", r.plane, r.verdict.failures));
        }
        fails.extend(check(r, t, Param::SpongeModulus, Some(0.02), None));
    }
    assert!(fails.is_empty(), "{fails:#?}");
}

/// A log the model cannot fit (the compact 2D twin's camera angles moved
/// by +1° over every other 5 s, as a slipping camera mount would): the
/// verdict says the fit does not fit its own data and the plane is
/// unverified, whatever the 1σ say.
#[test]
#[ignore = "identification of a 60 s log: ≈ 5 s optimised, a minute in a debug build; CI runs it in the ci-opt build"]
fn a_fit_far_above_the_noise_is_unverified() {
    let hidden = hidden::joint_2d(3);
    let mut log = twin::record_2d(&hidden, &ExcitationPlan::compact(1), true, NOISE).unwrap();
    for k in 0..log.len() {
        if (log.t_s[k] / 5.0).floor() as usize % 2 == 1 {
            log.cam_deg[k][0] += 1.0;
        }
    }
    let opts = IdentifyOptions {
        lm: LmOptions {
            max_iterations: 8,
            ..IdentifyOptions::default().lm
        },
        ..IdentifyOptions::default()
    };
    let (_, reports) = identify::identify_2d(&log, &Joint2dParams::default(), &opts).unwrap();
    let r = &reports[0];
    eprintln!("{:?}", r.verdict);
    let noise = r.verdict.camera_noise_deg.unwrap();
    assert!(
        r.validation.fit_rms_deg > 3.0 * noise,
        "{:?}",
        r.validation.fit_rms_deg
    );
    assert!(!r.verdict.verified);
    assert!(
        r.verdict
            .failures
            .iter()
            .any(|f| f.contains("does not fit its own data")),
        "{:?}",
        r.verdict.failures
    );
}

/// Issue 28's campaign distribution (`hidden::campaign_joint_3d`), twin
/// 107 — outside the campaign's twins 0..20, which no test uses. β's
/// driver turns on at 1.835 V, so the 240 s plan's 1.9 V level carries
/// only ≈ 0.08 A and its 1.85 V level ≈ 0.02 A, right at the
/// regression's lower cut. Before the regression chose its rows by the
/// input (`identify::regression`), it chose them by the noisy current:
/// of the 1.85 V rows it kept those whose noise lifted them above 20 mA,
/// and β's g came out 1.137 against 1.187 A/V (−4.2 %), **−28σ** by its
/// own 1σ, on a plane called verified with g identifiable. Now every
/// parameter a verified plane calls identifiable lies within 3σ of the
/// truth, and β's g is among them (the plane stays verified: the fix
/// corrects the estimate instead of giving up on it). β alone is
/// identified (as `identify_3d` does it, [`identify_beta`]): the failure
/// was β's, and α's side of the same rule is what the campaign example
/// checks on its 40 planes (`identify_campaign`, docs/experiments.md);
/// α was half this check's CPU.
#[test]
#[ignore = "a 240 s 3D log: ≈ 10–20 s optimised; CI runs it in the ci-opt build (scripts/test-all.sh)"]
fn a_campaign_twin_whose_g_was_28_sigma_off_is_now_within_its_sigma() {
    let hidden = hidden::campaign_joint_3d(107);
    let plan = ExcitationPlan::standard(2, 240.0, false);
    let log = twin::record_3d(&hidden, &plan, true, NOISE).unwrap();
    let beta = &identify_beta(&log);
    let t = truth(&hidden.beta, &hidden.wires[1]);
    print_estimates(beta, &t);
    eprintln!("{}: {:?}", beta.plane, beta.verdict.failures);
    let wrong = wrong_but_called_identifiable(beta, &t, 3.0);
    assert!(wrong.is_empty(), "{wrong:#?}");
    assert!(beta.verdict.verified, "{:?}", beta.verdict.failures);
    let g = beta.estimate(Param::Transconductance).unwrap();
    assert!(g.identifiable && g.verified, "{g:?}");
    let z = (g.fitted - hidden.beta.driver.transconductance_a_v) / g.std;
    assert!(
        z.abs() <= 3.0,
        "g {} ± {} is {z:+.1}σ from the truth",
        g.fitted,
        g.std
    );
}

/// Issue 28, the probe: on the off-plan twin, where the standard plan
/// leaves α unverified with its turn-on unknown (the test above), the
/// probe (each coil alone up a 1.4–2.6 V staircase, then a 3 V pulse)
/// finds α's drivers turning on at 2.0 V and β's at 1.6 V from the
/// logged currents. The plan adapted to it keeps inside the firmware's
/// default budget by pulsing α's levels (1 s on, 2 s off) at √3 times
/// their distance above the turn-on, the held level's mean power — and
/// that plan identifies α: verified, every parameter it calls
/// identifiable within 3σ of the truth. Before (pulses at the held
/// levels, 2.25 and 2.3 V), α moved 0.19° and nothing was determined.
#[test]
#[ignore = "a 194 s probe and a 240 s plan on the 3D twin, identified: ≈ 25 s optimised; CI runs it in the ci-opt build (scripts/test-all.sh)"]
fn the_probe_places_a_plan_that_identifies_the_off_plan_plane() {
    let hidden = hidden::off_plan_joint_3d(5);
    let probe_log = twin::record_3d(&hidden, &ExcitationPlan::probe(2), true, NOISE).unwrap();
    let found = identify::probe::analyse(&probe_log).unwrap();
    let on: Vec<f64> = found.coils.iter().map(|c| c.turn_on_v.unwrap()).collect();
    assert!(
        (on[0] - 2.0).abs() < 0.02 && (on[2] - 2.0).abs() < 0.02,
        "{on:?}"
    );
    assert!(
        (on[1] - 1.6).abs() < 0.02 && (on[3] - 1.6).abs() < 0.02,
        "{on:?}"
    );
    let plan = ExcitationPlan::adapted(2, 240.0, &found, false);
    plan.validate(2).unwrap();
    let mut alpha_levels: Vec<f64> = plan
        .drive
        .iter()
        .filter(|d| d.coil == 1 && d.volts.is_some_and(|v| v < 2.9))
        .map(|d| d.volts.unwrap())
        .collect();
    alpha_levels.sort_by(f64::total_cmp);
    alpha_levels.dedup();
    // 2.0 + √3 × 0.25 and 2.0 + √3 × 0.3 V.
    assert_eq!(alpha_levels, vec![2.43, 2.52]);
    // Above the default budget's sustained limit: 1 s pieces.
    assert!(plan
        .drive
        .iter()
        .filter(|d| d.coil == 1 && d.peak_v() < 2.9)
        .all(|d| d.to_s - d.from_s <= identify::probe::CHOP_ON_S + 1e-9));
    // β turns on inside the standard range: its levels are held.
    assert!(plan
        .drive
        .iter()
        .any(|d| d.coil == 2 && d.peak_v() < 2.5 && d.to_s - d.from_s > 10.0));

    let log = twin::record_3d(&hidden, &plan, true, NOISE).unwrap();
    let (_, reports) =
        identify::identify_3d(&log, &Joint3dParams::default(), &IdentifyOptions::default())
            .unwrap();
    for (p, r) in reports.iter().enumerate() {
        assert!(r.verdict.verified, "{}: {:?}", r.plane, r.verdict.failures);
        let truth = hidden::plane_truth(&hidden, p);
        for e in r.estimates.iter().filter(|e| e.identifiable) {
            let z = (e.fitted - e.param.get(&truth)) / e.std;
            assert!(
                z.abs() < 3.0,
                "{} {}: {z:+.2}σ from the truth",
                r.plane,
                e.field
            );
        }
    }
    // α's thermal stage is determined, not left at the prior.
    let alpha = &reports[0];
    for field in [
        "coil.convection_w_m2_k",
        "coil.austenite_start_c",
        "coil.stress_shift_k_per_mpa",
    ] {
        let e = alpha.estimates.iter().find(|e| e.field == field).unwrap();
        assert!(e.identifiable, "α {field}: {:?}", e.reason);
    }
}

/// A plane the log never moves (its coils left off all session, the
/// other plane recorded as usual) determines none of its thermal and
/// mechanical parameters. Before, it was reported verified while every one
/// of them was named not identifiable: a prior passed off as identified.
/// Now it is unverified by name; the plane that was driven stays verified.
#[test]
#[ignore = "a 3D twin of 120 s: run with --ignored in CI"]
fn a_plane_the_log_never_moves_is_not_called_identified() {
    let hidden = hidden::off_plan_joint_3d(5);
    let mut plan = ExcitationPlan::standard(2, 120.0, false);
    // Coils 1 and 3 are α's ((coil − 1) mod planes).
    plan.drive.retain(|d| (d.coil - 1) % 2 == 1);
    plan.hold.retain(|h| h.plane != 0);
    let log = twin::record_3d(&hidden, &plan, true, NOISE).unwrap();
    let (_, reports) =
        identify::identify_3d(&log, &Joint3dParams::default(), &IdentifyOptions::default())
            .unwrap();
    let (alpha, beta) = (&reports[0], &reports[1]);
    assert!(
        alpha
            .estimates
            .iter()
            .filter(|e| e.stage == "thermal" || e.stage == "mechanics")
            .all(|e| !e.identifiable),
        "{:?}",
        alpha.estimates
    );
    assert!(!alpha.verdict.verified, "{:?}", alpha.verdict);
    assert!(
        alpha
            .verdict
            .failures
            .iter()
            .any(|f| f.contains("determines none of the plane's")),
        "{:?}",
        alpha.verdict.failures
    );
    assert!(beta.verdict.verified, "{:?}", beta.verdict.failures);
}

/// Issue 28's campaign in short form, as a user runs it on a joint nobody
/// has characterised: two hidden twins of the campaign's distribution
/// (`hidden::campaign_joint_3d`, twins 200 and 201: chosen before they were
/// run, outside the campaign's 0..20 and 120..140 and every other test's),
/// each probed, recorded on the plan adapted to its probe, identified from
/// the defaults. No verified plane may call a parameter identifiable more
/// than 3σ from its truth (the campaign's "wrong but called identifiable",
/// goal 0), and at least three of the four planes must be verified (the
/// full campaigns verified 77 of 80: a check that all planes refused
/// would pass vacuously). The full campaign: `CAMPAIGN_PLAN=adapted cargo
/// run --profile ci-opt -p plant-joint --example identify_campaign -- 20
/// 240 FIRST` (joint README, "Probe and adapted plan").
#[test]
#[ignore = "two 3D twins, each a 194 s probe and a 240 s plan identified: ≈ 80 s optimised; CI runs it in the ci-opt build (scripts/test-all.sh)"]
fn the_campaign_in_short_form_calls_nothing_wrong_identifiable() {
    let mut verified = 0;
    let mut wrong = Vec::new();
    for k in [200, 201] {
        let h = hidden::campaign_joint_3d(k);
        let plan = twin::adapted_plan_3d(&h, 240.0, NOISE).unwrap();
        let log = twin::record_3d(&h, &plan, true, NOISE).unwrap();
        let (_, reports) =
            identify::identify_3d(&log, &Joint3dParams::default(), &IdentifyOptions::default())
                .unwrap();
        for (p, r) in reports.iter().enumerate() {
            if !r.verdict.verified {
                eprintln!(
                    "twin {k} {}: unverified ({:?})",
                    r.plane, r.verdict.failures
                );
                continue;
            }
            verified += 1;
            let truth = hidden::plane_truth(&h, p);
            for e in r.estimates.iter().filter(|e| e.identifiable && e.verified) {
                let z = (e.fitted - e.param.get(&truth)) / e.std;
                if z.abs() > 3.0 {
                    wrong.push(format!("twin {k} {} {}: {z:+.1}σ", r.plane, e.field));
                }
            }
        }
    }
    assert!(
        wrong.is_empty(),
        "called identifiable, more than 3σ off: {wrong:?}"
    );
    assert!(verified >= 3, "{verified} of 4 planes verified");
}

/// Runs the mechanics stage's starts "elsewhere": each unit goes through
/// its JSON text and runs on another thread against its own copy of the
/// log and of the prior's plane model, as a Ray worker would (issue 33).
struct Elsewhere {
    log: identify::ExcitationLog,
    prior: PlaneModel,
    units_run: std::sync::atomic::AtomicUsize,
    /// A start whose answered cost is one unit in the last place off (a
    /// worker that computed something else for that start alone).
    tamper: Option<usize>,
}

impl identify::StartFits for Elsewhere {
    fn fit(
        &self,
        units: &[identify::StartUnit],
    ) -> Result<Vec<Result<identify::StartFit, String>>, identify::IdentifyError> {
        let texts: Vec<String> = units
            .iter()
            .map(|u| serde_json::to_string(u).unwrap())
            .collect();
        std::thread::scope(|s| {
            let runs: Vec<_> = texts
                .iter()
                .map(|t| {
                    s.spawn(move || {
                        let unit: identify::StartUnit = serde_json::from_str(t).unwrap();
                        let mut fit = unit.run(&self.log, &self.prior).map_err(|e| e.to_string());
                        if let (Some(k), Ok(f)) = (self.tamper, fit.as_mut()) {
                            if k == unit.start {
                                f.cost += 1;
                            }
                        }
                        // Back through text too.
                        fit.map(|f| {
                            serde_json::from_str(&serde_json::to_string(&f).unwrap()).unwrap()
                        })
                    })
                })
                .collect();
            self.units_run
                .fetch_add(runs.len(), std::sync::atomic::Ordering::Relaxed);
            Ok(runs.into_iter().map(|r| r.join().unwrap()).collect())
        })
    }
}

#[test]
fn the_mechanics_starts_run_as_units_elsewhere_give_the_same_identification() {
    let hidden = hidden::joint_2d(3);
    let log = twin::record_2d(&hidden, &ExcitationPlan::compact(1), true, NOISE).unwrap();
    let opts = IdentifyOptions {
        lm: LmOptions {
            max_iterations: 8,
            ..IdentifyOptions::default().lm
        },
        ..IdentifyOptions::default()
    };
    let prior = Joint2dParams::default();
    let here = identify::identify_2d(&log, &prior, &opts).unwrap();
    let elsewhere = Elsewhere {
        log: log.clone(),
        prior: identify::prior_model_2d(&prior, &opts),
        units_run: 0.into(),
        tamper: None,
    };
    let there = identify::identify_2d_with(&log, &prior, &opts, Some(&elsewhere)).unwrap();
    let units = elsewhere.units_run.into_inner();
    assert!(
        units >= 2,
        "the mechanics stage's starts ran elsewhere: {units}"
    );
    assert_eq!(here.0, there.0, "the identified plant");
    assert_eq!(here.1, there.1, "the reports, evaluations and 1σ included");
    // A worker with another prior (its link 10 % heavier, a parameter
    // never fitted) computes another cost: refused, named.
    let mut other = Joint2dParams::default();
    other.plane.link.mass_kg *= 1.1;
    let wrong = Elsewhere {
        log: log.clone(),
        prior: identify::prior_model_2d(&other, &opts),
        units_run: 0.into(),
        tamper: None,
    };
    let e = identify::identify_2d_with(&log, &prior, &opts, Some(&wrong)).unwrap_err();
    assert!(e.to_string().contains("does not reproduce here"), "{e}");
    // One start answered wrong, not the one kept: its cost would still
    // steer the starts check, so it is refused too.
    let mech = here.1[0]
        .stages
        .iter()
        .find(|s| s.name == "mechanics")
        .unwrap();
    let other_start = (mech.best_start + 1) % mech.starts;
    let tampered = Elsewhere {
        log: log.clone(),
        prior: identify::prior_model_2d(&prior, &opts),
        units_run: 0.into(),
        tamper: Some(other_start),
    };
    let e = identify::identify_2d_with(&log, &prior, &opts, Some(&tampered)).unwrap_err();
    assert!(e.to_string().contains("does not reproduce here"), "{e}");
}
