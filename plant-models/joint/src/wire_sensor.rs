//! Wire length sensor: a SUS304 wire (0.2 mm) fixed to the link and sliding
//! in a tube fixed to the socket, read by a pulse coder (LEVEX).
//!
//! **Conventions.** `d` is the *insertion* in mm: it grows when the wire is
//! pushed into the tube. The wire runs straight from its attachment point on
//! the link (link frame, mm, origin at the centre of the link base, +y along
//! the link) to the tube entry (socket frame, mm). Angles are positive when
//! the link end moves towards +x (clockwise); see `link`. Then
//! `d = d_rest + (L_ref − L(pose))`, with `L` the free wire length and
//! `L_ref` its length at the rest pose where the coder was zeroed to
//! `d_rest`.
//!
//! **Geometry vs the paper's calibrated laws.** The paper calibrated its
//! laws against camera images of the real joint, so they include the link's
//! translation on the cartilage (the base sinks ≈ 0.06 mm per degree as the
//! holding coil pulls harder). The default geometries are estimates fitted
//! so the laws hold on the *simulated* joint's quasi-static path (link held
//! at each angle by one coil, the antagonist cold; `tests/joint_wire.rs`):
//! - 2D (one sensor on the −x side, Eq. 2 θ = 0.349 d² − 5.525 d + 0.753):
//!   attachment (−4, 14.4) mm on the link, tube entry (−24, −7.9) mm,
//!   `d_rest = 0.137` mm (Eq. 2's root at θ = 0): Eq. 2 stays within ≈ 2.1°
//!   of the true angle over ±20° on that path. For a pure rotation about the
//!   origin ([`ideal_insertion_mm`]) the same geometry is off by up to ≈ 7°:
//!   the fit compensates the sink, as the paper's calibration did. With Eq. 2
//!   as printed, `d` *falls* as θ rises, so the 2D wire is **pushed in when
//!   θ decreases**. The paper's prose says the wire is pushed in when the
//!   angle increases; we follow the calibrated equation.
//! - 3D (Eq. 3 α = 2.727 (d3 − d1) + 0.323, β = 2.670 (d4 − d2) + 0.131):
//!   sensors 1/2 on the −side of their plane, 3/4 mirrored on the + side,
//!   attachments (∓7.5, 27) mm (α) and (∓6.5, 27) mm (β) at the link end,
//!   tube entries (∓13.5, −25) mm and (∓15.0, −25) mm; rest offsets make
//!   Eq. 3 give 0 at rest (d1 = d2 = 0, d3 = −0.323/2.727,
//!   d4 = −0.131/2.670). The differential law is insensitive to the sink
//!   (both wires see it alike): within 0.03° for a pure rotation and
//!   ≈ 0.2° (α) / 0.65° (β) on the simulated path. Sensor 3 (4) is pushed in
//!   when α (β) rises, sensor 1 (2) when it falls — consistent with the
//!   paper's threshold law (Eq. 4 uses d3 alone for α < −7.46°, where wire 3
//!   is being pulled out and cannot jam).
//!
//! **Jamming** (pushing only). The wire buckles and drags in the tube, so the
//! coder sees less insertion than the geometry gives: a lag `e ≥ 0`,
//! `d_meas = d_ideal − e`.
//! - pushing by `Δ > 0`: `e += κ Δ (1 − e/e_max)`, with
//!   `e_max = e₀ + e₁ · max(0, d_ideal − d_rest)` (more wire in the tube,
//!   more friction); plus stick-slip: with probability `p·Δ` (seeded RNG) the
//!   tip sticks for a random push length in `[s_min, s_max]`, taking the
//!   whole push as lag, then slips back to the buckling curve;
//! - pulling by `Δ < 0`: tension straightens the wire first: `e` falls by
//!   `|Δ|` (the reading holds still) until it is gone.
//!
//! So the error appears only on the pushing side and is history dependent
//! (pushing and pulling through the same angle read differently), which a
//! fitted single-sensor law cannot absorb and threshold switching avoids.
//!
//! **Quantisation.** The coder counts `round(d / mm_per_count)`; the default
//! 0.01 mm/count is an estimate (≈ 0.055° of link angle).

use rand::Rng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use super::{check_finite, check_positive, PlantError};

/// Where the wire is attached and where its tube starts.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WireGeometry {
    /// Attachment point on the link, link frame (mm).
    pub attach_link_mm: [f64; 2],
    /// Tube entry, socket frame (mm).
    pub tube_entry_mm: [f64; 2],
    /// Reading at the rest pose, where the coder is zeroed (mm).
    pub insertion_at_rest_mm: f64,
}

impl WireGeometry {
    /// The 2D sensor (see the module docs; estimate fitted to Eq. 2 on the
    /// simulated joint's quasi-static path).
    pub fn paper_2d() -> Self {
        Self {
            attach_link_mm: [-4.0, 14.4],
            tube_entry_mm: [-24.0, -7.9],
            insertion_at_rest_mm: EQ2_REST_MM,
        }
    }

    /// The 3D sensor `index` ∈ 1..=4 (see the module docs; estimates fitted
    /// to Eq. 3). Sensors 1, 3 lie in the α plane, 2, 4 in the β plane.
    pub fn paper_3d(index: usize) -> Self {
        let (qx, tx) = if index % 2 == 1 {
            (7.5, 13.5)
        } else {
            (6.5, 15.0)
        };
        match index {
            1 | 2 => Self {
                attach_link_mm: [-qx, 27.0],
                tube_entry_mm: [-tx, -25.0],
                insertion_at_rest_mm: 0.0,
            },
            3 => Self {
                attach_link_mm: [qx, 27.0],
                tube_entry_mm: [tx, -25.0],
                insertion_at_rest_mm: -0.323 / 2.727,
            },
            _ => Self {
                attach_link_mm: [qx, 27.0],
                tube_entry_mm: [tx, -25.0],
                insertion_at_rest_mm: -0.131 / 2.670,
            },
        }
    }

    fn validate(&self, prefix: &str) -> Result<(), PlantError> {
        check_finite(
            &format!("{prefix}attach_link_mm[0]"),
            self.attach_link_mm[0],
        )?;
        check_finite(
            &format!("{prefix}attach_link_mm[1]"),
            self.attach_link_mm[1],
        )?;
        check_finite(&format!("{prefix}tube_entry_mm[0]"), self.tube_entry_mm[0])?;
        check_finite(&format!("{prefix}tube_entry_mm[1]"), self.tube_entry_mm[1])?;
        check_finite(
            &format!("{prefix}insertion_at_rest_mm"),
            self.insertion_at_rest_mm,
        )?;
        if free_length_mm(self, 0.0, 0.0, 0.0) < 1.0 {
            return Err(PlantError::param(
                &format!("{prefix}tube_entry_mm"),
                "wire shorter than 1 mm at rest",
            ));
        }
        Ok(())
    }
}

/// Eq. 2's root at θ = 0: 0.349 d² − 5.525 d + 0.753 = 0, the small root.
pub const EQ2_REST_MM: f64 = 0.137_483_566;

/// Free wire length (mm) with the link base at (`x_mm`, `y_mm`) and angle
/// `theta_rad` (positive: link end towards +x).
#[inline]
pub fn free_length_mm(g: &WireGeometry, x_mm: f64, y_mm: f64, theta_rad: f64) -> f64 {
    let (s, c) = theta_rad.sin_cos();
    free_length_sc_mm(g, x_mm, y_mm, s, c)
}

#[inline]
fn free_length_sc_mm(g: &WireGeometry, x_mm: f64, y_mm: f64, s: f64, c: f64) -> f64 {
    let [qx, qy] = g.attach_link_mm;
    let wx = x_mm + qx * c + qy * s;
    let wy = y_mm - qx * s + qy * c;
    let (dx, dy) = (wx - g.tube_entry_mm[0], wy - g.tube_entry_mm[1]);
    (dx * dx + dy * dy).sqrt()
}

/// Ideal (jam-free, unquantised) insertion (mm) for a pure rotation by
/// `theta_rad` about the joint origin, the coder zeroed at θ = 0:
/// `d = d_rest + L(0) − L(θ)`. This is the rigid-bearing answer; with the
/// cartilage use [`ideal_insertion_at_pose_mm`] with the link base position.
pub fn ideal_insertion_mm(g: &WireGeometry, theta_rad: f64) -> f64 {
    g.insertion_at_rest_mm + free_length_mm(g, 0.0, 0.0, 0.0)
        - free_length_mm(g, 0.0, 0.0, theta_rad)
}

/// Ideal insertion (mm) with the link base at (`x_mm`, `y_mm`) and angle
/// `theta_rad`, the coder zeroed at the pose `zero` = (x, y, θ) (mm, mm,
/// rad): `d = d_rest + L(zero) − L(pose)`. The plant's sensors report this
/// (before jamming and quantisation), zeroed at the settled rest pose.
pub fn ideal_insertion_at_pose_mm(
    g: &WireGeometry,
    zero: (f64, f64, f64),
    x_mm: f64,
    y_mm: f64,
    theta_rad: f64,
) -> f64 {
    g.insertion_at_rest_mm + free_length_mm(g, zero.0, zero.1, zero.2)
        - free_length_mm(g, x_mm, y_mm, theta_rad)
}

/// Paper Eq. 2 (2D single-sensor law), degrees from mm.
pub fn paper_eq2_deg(d_mm: f64) -> f64 {
    0.349 * d_mm * d_mm - 5.525 * d_mm + 0.753
}

/// Paper Eq. 3 (3D differential laws): (α, β) in degrees from d1..d4 (mm).
pub fn paper_eq3_deg(d_mm: [f64; 4]) -> (f64, f64) {
    (
        2.727 * (d_mm[2] - d_mm[0]) + 0.323,
        2.670 * (d_mm[3] - d_mm[1]) + 0.131,
    )
}

/// Jamming (stick and buckling) parameters; all estimates. The defaults
/// give a lag of ≈ 0.2–0.25 mm after pushing a wire ~3.5 mm in (3D, α from
/// 0 to 20°): ≈ 2.4° of error for a single pushed sensor, ≈ 1.2° for the
/// differential law (only the pushed wire of a pair lags), about half of
/// which is hysteresis a least-squares calibration over an up-and-down sweep
/// cannot remove — the regime the paper describes (single sensor > 1°,
/// threshold switching < 1°).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct JamParams {
    /// Buckling lag gain κ (lag per mm pushed, dimensionless). Estimate.
    pub buckling_gain: f64,
    /// Lag ceiling at the rest insertion, e₀ (mm). Estimate.
    pub max_lag_mm: f64,
    /// Extra lag ceiling per mm pushed beyond rest, e₁ (mm/mm). Estimate.
    pub max_lag_per_mm: f64,
    /// Probability of a stick event per mm pushed, p (1/mm). Estimate.
    pub stick_per_mm: f64,
    /// Shortest stick, s_min (mm of push). Estimate.
    pub stick_min_mm: f64,
    /// Longest stick, s_max (mm of push). Estimate.
    pub stick_max_mm: f64,
}

impl Default for JamParams {
    fn default() -> Self {
        Self {
            buckling_gain: 0.25,
            max_lag_mm: 0.05,
            max_lag_per_mm: 0.06,
            stick_per_mm: 1.0,
            stick_min_mm: 0.02,
            stick_max_mm: 0.08,
        }
    }
}

impl JamParams {
    /// No jamming at all (the geometric reading, quantised).
    pub fn none() -> Self {
        Self {
            buckling_gain: 0.0,
            max_lag_mm: 0.0,
            max_lag_per_mm: 0.0,
            stick_per_mm: 0.0,
            stick_min_mm: 0.0,
            stick_max_mm: 0.0,
        }
    }

    /// The buckling lag's ceiling (mm) at the ideal insertion `ideal_mm`,
    /// for a wire whose rest insertion is `rest_mm`: e₀ + e₁·(d − d_rest)⁺.
    #[inline(always)]
    pub fn ceiling_mm(&self, ideal_mm: f64, rest_mm: f64) -> f64 {
        self.max_lag_mm + self.max_lag_per_mm * (ideal_mm - rest_mm).max(0.0)
    }

    fn validate(&self, prefix: &str) -> Result<(), PlantError> {
        for (name, v) in [
            ("buckling_gain", self.buckling_gain),
            ("max_lag_mm", self.max_lag_mm),
            ("max_lag_per_mm", self.max_lag_per_mm),
            ("stick_per_mm", self.stick_per_mm),
            ("stick_min_mm", self.stick_min_mm),
            ("stick_max_mm", self.stick_max_mm),
        ] {
            let field = format!("{prefix}{name}");
            check_finite(&field, v)?;
            if v < 0.0 {
                return Err(PlantError::param(&field, "must be ≥ 0"));
            }
        }
        if self.buckling_gain > 1.0 {
            return Err(PlantError::param(
                &format!("{prefix}buckling_gain"),
                "must be ≤ 1",
            ));
        }
        if self.stick_max_mm < self.stick_min_mm {
            return Err(PlantError::param(
                &format!("{prefix}stick_max_mm"),
                "must be ≥ stick_min_mm",
            ));
        }
        Ok(())
    }
}

/// One sensor's parameters.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WireSensorParams {
    /// Geometry (mm).
    pub geometry: WireGeometry,
    /// Pulse-coder resolution (mm/count). Estimate: 0.01 mm/count.
    #[serde(default = "default_mm_per_count")]
    pub mm_per_count: f64,
    /// Jamming model.
    #[serde(default)]
    pub jam: JamParams,
}

fn default_mm_per_count() -> f64 {
    0.01
}

impl WireSensorParams {
    /// Default quantisation and jamming for `geometry`.
    pub fn with_geometry(geometry: WireGeometry) -> Self {
        Self {
            geometry,
            mm_per_count: default_mm_per_count(),
            jam: JamParams::default(),
        }
    }

    /// Rejects bad values, naming the field.
    pub fn validate(&self, prefix: &str) -> Result<(), PlantError> {
        self.geometry.validate(&format!("{prefix}geometry."))?;
        check_positive(&format!("{prefix}mm_per_count"), self.mm_per_count)?;
        self.jam.validate(&format!("{prefix}jam."))
    }
}

/// Nearest integer, halves away from zero (as `f64::round`), without the
/// libm call `round` costs on baseline x86-64.
#[inline]
fn round_to_count(v: f64) -> i64 {
    (v + 0.5f64.copysign(v)) as i64
}

/// The jamming state of one wire: how far its tip lags the ideal
/// insertion, and how much more push a present stick holds it for. The
/// sensor ([`WireSensor`]) keeps one; identification's wire stage
/// ([`crate::identify`]) replays many side by side along one path,
/// sharing the path's push and lag ceiling at each substep.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct JamState {
    /// Lag of the tip behind the ideal insertion (mm, ≥ 0).
    pub lag_mm: f64,
    /// Push left before a present stick slips (mm; 0 when not stuck).
    pub stick_left_mm: f64,
}

impl JamState {
    /// One push of `delta` mm (negative: a pull) under the jamming `j`,
    /// `e_max` being [`JamParams::ceiling_mm`] at the new insertion.
    /// Stuck, a push all goes into the lag; free, the buckle grows towards
    /// the ceiling and `stick` (called with `j` and `delta` wherever a
    /// stick may start: pushed, not stuck, `stick_per_mm > 0`) says
    /// whether a stick starts and for how much push. A pull unsticks the
    /// tip and takes up the lag first; a slip drops the lag to the ceiling.
    #[inline(always)]
    pub fn advance(
        &mut self,
        j: &JamParams,
        delta: f64,
        e_max: f64,
        stick: impl FnOnce(&JamParams, f64) -> Option<f64>,
    ) {
        if delta > 0.0 {
            if self.stick_left_mm > 0.0 {
                self.lag_mm += delta;
                self.stick_left_mm -= delta;
            } else {
                if e_max > 0.0 {
                    let grow = j.buckling_gain * delta * (1.0 - self.lag_mm / e_max);
                    // Above the ceiling (after a slip from a stick) the
                    // buckle relaxes towards it at the same rate.
                    self.lag_mm = (self.lag_mm + grow).max(0.0);
                }
                if j.stick_per_mm > 0.0 {
                    if let Some(length_mm) = stick(j, delta) {
                        self.stick_left_mm = length_mm;
                    }
                }
            }
        } else if delta < 0.0 {
            self.stick_left_mm = 0.0;
            self.lag_mm = (self.lag_mm + delta).max(0.0);
        }
        if self.stick_left_mm <= 0.0 {
            // Slip: the stuck tip jumps back to the buckling ceiling.
            self.lag_mm = self.lag_mm.min(e_max.max(0.0));
            self.stick_left_mm = 0.0;
        }
    }
}

/// One wire sensor's state.
#[derive(Clone, Debug)]
pub struct WireSensor {
    params: WireSensorParams,
    ref_length_mm: f64,
    ideal_mm: f64,
    jam: JamState,
    counts: i64,
}

impl WireSensor {
    /// A sensor zeroed at the pose (`x_mm`, `y_mm`, `theta_rad`): the reading
    /// there is `insertion_at_rest_mm`.
    pub fn new(
        params: WireSensorParams,
        x_mm: f64,
        y_mm: f64,
        theta_rad: f64,
    ) -> Result<Self, PlantError> {
        params.validate("wire.")?;
        let ref_length_mm = free_length_mm(&params.geometry, x_mm, y_mm, theta_rad);
        let ideal_mm = params.geometry.insertion_at_rest_mm;
        let counts = (ideal_mm / params.mm_per_count).round() as i64;
        Ok(Self {
            params,
            ref_length_mm,
            ideal_mm,
            jam: JamState::default(),
            counts,
        })
    }

    /// Parameters.
    pub fn params(&self) -> &WireSensorParams {
        &self.params
    }

    /// Updates the reading for the link pose; `rng` drives stick events.
    pub fn update(&mut self, x_mm: f64, y_mm: f64, theta_rad: f64, rng: &mut ChaCha8Rng) {
        let (s, c) = theta_rad.sin_cos();
        self.update_sin_cos(x_mm, y_mm, s, c, rng);
    }

    /// [`Self::update`] with (sin θ, cos θ) already known.
    #[inline(always)]
    pub fn update_sin_cos(
        &mut self,
        x_mm: f64,
        y_mm: f64,
        sin_t: f64,
        cos_t: f64,
        rng: &mut ChaCha8Rng,
    ) {
        let ideal = self.ideal_insertion_at_mm(x_mm, y_mm, sin_t, cos_t);
        self.advance_to_ideal(ideal, rng);
    }

    /// The geometric insertion (mm) at the link pose (base at `x_mm`,
    /// `y_mm`; sin θ, cos θ), the coder zeroed where this sensor was made;
    /// the state does not change.
    #[inline(always)]
    pub fn ideal_insertion_at_mm(&self, x_mm: f64, y_mm: f64, sin_t: f64, cos_t: f64) -> f64 {
        let g = &self.params.geometry;
        g.insertion_at_rest_mm + self.ref_length_mm - free_length_sc_mm(g, x_mm, y_mm, sin_t, cos_t)
    }

    /// Updates the reading for a geometric insertion `ideal` (mm) found
    /// by [`Self::ideal_insertion_at_mm`] (identification replays a
    /// recorded path of them many times with other stick events);
    /// `rng` drives stick events.
    #[inline(always)]
    pub fn advance_to_ideal(&mut self, ideal: f64, rng: &mut ChaCha8Rng) {
        self.advance_to_ideal_with(ideal, |j, delta| {
            if rng.gen::<f64>() < j.stick_per_mm * delta {
                Some(rng.gen_range(j.stick_min_mm..=j.stick_max_mm))
            } else {
                None
            }
        });
    }

    /// [`Self::advance_to_ideal`] with the stick events from `stick`,
    /// called (with the jamming parameters and the push `delta` in mm)
    /// wherever the tip may start to stick: pushed, not stuck, and
    /// `stick_per_mm > 0`; it returns the stick's push length (mm) if one
    /// starts. Where it is called depends only on the path and on the
    /// sticks before, not on the buckling gain or the lag ceilings, so
    /// the sticks of one run along a path, recorded, replay that run
    /// along the same path with other values of those
    /// (identification's wire stage does).
    #[inline(always)]
    pub fn advance_to_ideal_with(
        &mut self,
        ideal: f64,
        stick: impl FnMut(&JamParams, f64) -> Option<f64>,
    ) {
        let delta = ideal - self.ideal_mm;
        self.ideal_mm = ideal;
        let j = &self.params.jam;
        let e_max = j.ceiling_mm(ideal, self.params.geometry.insertion_at_rest_mm);
        self.jam.advance(j, delta, e_max, stick);
        self.counts = round_to_count((self.ideal_mm - self.jam.lag_mm) / self.params.mm_per_count);
    }

    /// Pulse-coder count (signed; grows as the wire goes in).
    pub fn counts(&self) -> i64 {
        self.counts
    }

    /// Measured insertion (mm) = counts × mm/count.
    pub fn insertion_mm(&self) -> f64 {
        self.counts as f64 * self.params.mm_per_count
    }

    /// Geometric insertion without jamming or quantisation (mm).
    pub fn ideal_insertion_mm(&self) -> f64 {
        self.ideal_mm
    }

    /// Present jamming lag (mm).
    pub fn lag_mm(&self) -> f64 {
        self.jam.lag_mm
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn eq2_slope_and_sign_match_geometry() {
        // The full Eq. 2 check needs the cartilage's translation
        // (tests/joint_wire.rs); for a pure rotation the slope at rest must
        // still agree with Eq. 2's (−5.43 °/mm) to within the sink
        // compensation (±40 %), and the sign must.
        let g = WireGeometry::paper_2d();
        let h = 0.5f64.to_radians();
        let dd = ideal_insertion_mm(&g, h) - ideal_insertion_mm(&g, -h);
        let slope_deg_per_mm = 1.0 / dd;
        let eq2_slope = 2.0 * 0.349 * EQ2_REST_MM - 5.525;
        assert!(
            (slope_deg_per_mm / eq2_slope - 1.0).abs() < 0.4,
            "{slope_deg_per_mm} vs {eq2_slope}"
        );
        assert!((paper_eq2_deg(EQ2_REST_MM)).abs() < 1e-6);
        // Pushed in (d grows) when θ falls.
        assert!(ideal_insertion_mm(&g, -0.1) > ideal_insertion_mm(&g, 0.0));
        // The pose form reduces to the rotation form at zero translation.
        let a = ideal_insertion_at_pose_mm(&g, (0.0, 0.0, 0.0), 0.0, 0.0, 0.2);
        assert_eq!(a, ideal_insertion_mm(&g, 0.2));
    }

    #[test]
    fn eq3_matches_geometry() {
        let g: Vec<WireGeometry> = (1..=4).map(WireGeometry::paper_3d).collect();
        let mut worst: f64 = 0.0;
        for i in -200..=200 {
            let a = (i as f64 * 0.1).to_radians();
            let b = (-(i as f64) * 0.07).to_radians();
            let d = [
                ideal_insertion_mm(&g[0], a),
                ideal_insertion_mm(&g[1], b),
                ideal_insertion_mm(&g[2], a),
                ideal_insertion_mm(&g[3], b),
            ];
            let (ae, be) = paper_eq3_deg(d);
            worst = worst
                .max((ae - a.to_degrees()).abs())
                .max((be - b.to_degrees()).abs());
        }
        assert!(worst < 0.1, "Eq. 3 vs geometry: worst {worst}°");
        // Sensor 3 is pushed in when α rises, sensor 1 when it falls.
        assert!(ideal_insertion_mm(&g[2], 0.1) > ideal_insertion_mm(&g[2], 0.0));
        assert!(ideal_insertion_mm(&g[0], -0.1) > ideal_insertion_mm(&g[0], 0.0));
    }

    #[test]
    fn quantisation_and_no_jam_follow_geometry() {
        let g = WireGeometry::paper_2d();
        let p = WireSensorParams {
            geometry: g,
            mm_per_count: 0.01,
            jam: JamParams::none(),
        };
        let mut s = WireSensor::new(p, 0.0, 0.0, 0.0).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        for i in -300..=300 {
            let th = (i as f64 * 0.05).to_radians();
            s.update(0.0, 0.0, th, &mut rng);
            let ideal = ideal_insertion_mm(&g, th);
            assert!((s.insertion_mm() - ideal).abs() <= 0.005 + 1e-12);
            assert_eq!(s.counts(), (ideal / 0.01).round() as i64);
        }
    }

    #[test]
    fn jamming_lags_only_when_pushing_and_holds_on_reversal() {
        let g = WireGeometry::paper_2d();
        let mut s = WireSensor::new(WireSensorParams::with_geometry(g), 0.0, 0.0, 0.0).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        // Pull out (θ up to +15°): no lag.
        for i in 0..=1500 {
            s.update(0.0, 0.0, (i as f64 * 0.01).to_radians(), &mut rng);
            assert!(s.lag_mm() < 1e-9);
        }
        // Push in (θ down to −15°): reading falls behind the geometry.
        for i in (-1500..=1500).rev() {
            s.update(0.0, 0.0, (i as f64 * 0.01).to_radians(), &mut rng);
        }
        let lag = s.ideal_insertion_mm() - s.insertion_mm();
        assert!(lag > 0.1, "lag {lag}");
        // Reverse a little: the reading holds (the buckle straightens first).
        let before = s.counts();
        s.update(0.0, 0.0, (-14.9f64).to_radians(), &mut rng);
        assert_eq!(s.counts(), before);
    }

    /// The jamming law as it was written inside the sensor before it
    /// moved into [`JamState::advance`] (the ceiling computed where it is
    /// used, twice): the moved law must give the same lag to the bit.
    fn jam_law_inline(
        j: &JamParams,
        rest_mm: f64,
        ideal: f64,
        delta: f64,
        lag_mm: &mut f64,
        stick_left_mm: &mut f64,
        stick: Option<f64>,
    ) {
        if delta > 0.0 {
            if *stick_left_mm > 0.0 {
                *lag_mm += delta;
                *stick_left_mm -= delta;
            } else {
                let e_max = j.max_lag_mm + j.max_lag_per_mm * (ideal - rest_mm).max(0.0);
                if e_max > 0.0 {
                    let grow = j.buckling_gain * delta * (1.0 - *lag_mm / e_max);
                    *lag_mm = (*lag_mm + grow).max(0.0);
                }
                if j.stick_per_mm > 0.0 {
                    if let Some(length_mm) = stick {
                        *stick_left_mm = length_mm;
                    }
                }
            }
        } else if delta < 0.0 {
            *stick_left_mm = 0.0;
            *lag_mm = (*lag_mm + delta).max(0.0);
        }
        if *stick_left_mm <= 0.0 {
            let e_max = j.max_lag_mm + j.max_lag_per_mm * (ideal - rest_mm).max(0.0);
            *lag_mm = lag_mm.min(e_max.max(0.0));
            *stick_left_mm = 0.0;
        }
    }

    #[test]
    fn moved_jam_law_changes_no_bit() {
        let g = WireGeometry::paper_2d();
        let rest_mm = g.insertion_at_rest_mm;
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        for jam in [
            JamParams::default(),
            JamParams {
                stick_per_mm: 20.0,
                ..JamParams::default()
            },
            JamParams {
                max_lag_mm: 0.0,
                max_lag_per_mm: 0.0,
                ..JamParams::default()
            },
        ] {
            let mut s = WireSensor::new(WireSensorParams::with_geometry(g), 0.0, 0.0, 0.0).unwrap();
            s.params.jam = jam.clone();
            let (mut ideal, mut lag, mut left) = (rest_mm, 0.0, 0.0);
            let mut steps = 0;
            for i in 0..20_000 {
                // Pushes and pulls of varied sizes, around and below rest.
                let next = rest_mm + 1.5 * (i as f64 * 0.003).sin() + 0.01 * rng.gen::<f64>();
                let stick = (rng.gen::<f64>() < 0.05).then(|| rng.gen_range(0.02..0.3));
                jam_law_inline(
                    &jam,
                    rest_mm,
                    next,
                    next - ideal,
                    &mut lag,
                    &mut left,
                    stick,
                );
                ideal = next;
                s.advance_to_ideal_with(next, |_, _| stick);
                assert_eq!(s.lag_mm().to_bits(), lag.to_bits(), "step {i}");
                steps += usize::from(lag > 0.0);
            }
            assert!(steps > 500, "the lag was non-zero in {steps} steps only");
        }
    }
}
