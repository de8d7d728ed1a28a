//! The firmware's real-time DGFM update (`firmware::viscoelastic`, what a
//! haptic device would run) over a plant object, as a
//! [`TractionModel`](plant_viscoelastic::TractionModel), so the same
//! haptic loop can run it beside the plant's exact reference and the two can
//! be compared.

use firmware::linalg::{Mat3 as CoreMat3, Vec3 as CoreVec3};
use firmware::viscoelastic::{
    ColumnSlot, RayleighColumns, RayleighParams, TensorColumn, TensorColumns, TimeStep, ViscoDgfm,
    ViscoError,
};
use plant_viscoelastic::error::{Result, VeError};
use plant_viscoelastic::object::DEFAULT_REST_THRESHOLD_M;
use plant_viscoelastic::{ColumnParams, Dgfm, Mat3, TractionModel, Vec3};

type Slots = Vec<ColumnSlot<f64>>;
type States = Vec<CoreVec3<f64>>;
type Rayleigh = RayleighColumns<f64, Vec<CoreMat3<f64>>, Vec<RayleighParams<f64>>>;
type Tensor = TensorColumns<f64, Vec<CoreMat3<f64>>, Vec<TensorColumn<f64>>>;

enum Core {
    Rayleigh(ViscoDgfm<f64, Rayleigh, Slots, States>),
    Tensor(ViscoDgfm<f64, Tensor, Slots, States>),
}

/// The firmware's DGFM update over a plant DGFM, f64, every column allowed
/// active at once, the plant's rest threshold.
pub struct CoreObject {
    dgfm: Dgfm,
    core: Core,
    tractions_pa: Vec<Vec3>,
    out: Vec<CoreVec3<f64>>,
}

fn core_mat(m: &Mat3) -> CoreMat3<f64> {
    CoreMat3(core::array::from_fn(|r| {
        core::array::from_fn(|c| m[(r, c)])
    }))
}

fn core_vec(v: &Vec3) -> CoreVec3<f64> {
    CoreVec3([v[0], v[1], v[2]])
}

fn core_error(context: &'static str) -> impl Fn(ViscoError) -> VeError {
    move |e| VeError::InvalidMesh(format!("firmware DGFM update ({context}): {e}"))
}

impl CoreObject {
    /// The firmware's update of `dgfm` with `params`; tensor columns are
    /// precomputed for steps of `h_s`.
    pub fn new(dgfm: Dgfm, params: &ColumnParams, h_s: f64) -> Result<Self> {
        let n = dgfm.len();
        let xi: Vec<CoreMat3<f64>> = (0..n)
            .flat_map(|j| dgfm.xi_column(j).iter().map(core_mat).collect::<Vec<_>>())
            .collect();
        let slots = vec![ColumnSlot::default(); n];
        let states = vec![CoreVec3::zero(); n * n];
        let core = match params {
            ColumnParams::Rayleigh(p) => {
                let params = p
                    .iter()
                    .map(|c| RayleighParams::new(c.ratio(), c.b_s()))
                    .collect::<core::result::Result<Vec<_>, _>>()
                    .map_err(core_error("Rayleigh parameters"))?;
                let update = RayleighColumns::new(xi, params).map_err(core_error("Ξ"))?;
                Core::Rayleigh(
                    ViscoDgfm::new(update, slots, states).map_err(core_error("storage"))?,
                )
            }
            ColumnParams::Tensor {
                ratios,
                damping_n_s_per_m,
            } => {
                let h = TimeStep::new(h_s).map_err(core_error("step"))?;
                let mut columns = Vec::with_capacity(n);
                for j in 0..n {
                    let k = dgfm.stiffness(j, j).ok_or(VeError::InvalidParameter {
                        name: "Ξ_jj",
                        value: j as f64,
                        reason: "singular",
                    })?;
                    columns.push(
                        TensorColumn::new(
                            core_mat(&k),
                            core_mat(&damping_n_s_per_m[j]),
                            ratios[j],
                            h,
                        )
                        .map_err(core_error("tensor column"))?,
                    );
                }
                let update = TensorColumns::new(xi, columns).map_err(core_error("Ξ"))?;
                Core::Tensor(ViscoDgfm::new(update, slots, states).map_err(core_error("storage"))?)
            }
        };
        let mut obj = CoreObject {
            out: vec![CoreVec3::zero(); n],
            tractions_pa: vec![Vec3::zeros(); n],
            dgfm,
            core,
        };
        obj.set_rest_threshold_m(DEFAULT_REST_THRESHOLD_M)?;
        Ok(obj)
    }

    /// Changes the rest threshold (m, finite, ≥ 0), as
    /// `ViscoObject::set_rest_threshold_m`.
    pub fn set_rest_threshold_m(&mut self, threshold_m: f64) -> Result<()> {
        match &mut self.core {
            Core::Rayleigh(m) => m.set_rest_threshold(threshold_m),
            Core::Tensor(m) => m.set_rest_threshold(threshold_m),
        }
        .map_err(core_error("rest threshold"))
    }
}

impl TractionModel for CoreObject {
    fn dgfm(&self) -> &Dgfm {
        &self.dgfm
    }

    fn set_traction(&mut self, j: usize, traction_pa: Vec3) -> Result<()> {
        let n = self.dgfm.len();
        if j >= n {
            return Err(VeError::VertexNotInTractionSet { vertex: j, n });
        }
        let p = core_vec(&traction_pa);
        match &mut self.core {
            Core::Rayleigh(m) => m.set_traction(j, p),
            Core::Tensor(m) => m.set_traction(j, p),
        }
        .map_err(core_error("traction"))?;
        self.tractions_pa[j] = traction_pa;
        Ok(())
    }

    fn traction_pa(&self, j: usize) -> Vec3 {
        self.tractions_pa
            .get(j)
            .copied()
            .unwrap_or_else(Vec3::zeros)
    }

    fn active_count(&self) -> usize {
        match &self.core {
            Core::Rayleigh(m) => m.active_count(),
            Core::Tensor(m) => m.active_count(),
        }
    }

    fn step(&mut self, h_s: f64, out: &mut [Vec3]) -> Result<()> {
        if out.len() != self.dgfm.len() {
            return Err(VeError::LengthMismatch {
                what: "displacement output",
                got: out.len(),
                expected: self.dgfm.len(),
            });
        }
        let h = TimeStep::new(h_s).map_err(core_error("step"))?;
        match &mut self.core {
            Core::Rayleigh(m) => m.step(h, &mut self.out),
            Core::Tensor(m) => m.step(h, &mut self.out),
        }
        .map_err(core_error("step"))?;
        for (o, c) in out.iter_mut().zip(&self.out) {
            *o = Vec3::from(c.0);
        }
        Ok(())
    }
}
