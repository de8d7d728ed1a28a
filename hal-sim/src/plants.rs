//! [`Plant`]: what the closed loop needs of a plant, and its
//! implementations for the joint models of `plant-models`.
use plant_joint::{Joint2d, Joint3d, LoadId, Plane, PlantError};

/// Weights hung on and cut from a plant's link (the scenario
/// disturbances).
pub trait Loads {
    /// Hangs `mass_kg` from the link end of plane `plane` by a thread led
    /// along `direction` (that plane's socket frame), with the plant's own
    /// gravity and link length.
    fn hang_weight(
        &mut self,
        plane: usize,
        mass_kg: f64,
        direction: [f64; 2],
    ) -> Result<LoadId, PlantError>;
    /// Removes a load (cuts the thread).
    fn remove_load(&mut self, plane: usize, id: LoadId);
}

/// A plant with `P` controlled angles, `S` wire sensors and `C` coils.
pub trait Plant<const P: usize, const S: usize, const C: usize>: Loads {
    /// Advances by `dt_s` with the driver input voltages held (coils in the
    /// paper's numbering, see [`crate::coil_index`]).
    fn advance(&mut self, dt_s: f64, coil_input_volts: &[f64; C]) -> Result<(), PlantError>;
    /// Pulse-coder counts now.
    fn counts(&self) -> [i64; S];
    /// Coder resolution (mm/count) of each sensor.
    fn mm_per_count(&self) -> [f64; S];
    /// True angles (deg).
    fn true_angles_deg(&self) -> [f64; P];
    /// A camera frame that became available since the last call.
    fn take_camera(&mut self) -> Option<[f64; P]>;
    /// Coil temperatures (°C).
    fn coil_temperatures_c(&self) -> [f64; C];
}

fn plane_3d(plane: usize) -> Plane {
    if plane == 1 {
        Plane::Beta
    } else {
        Plane::Alpha
    }
}

impl Plant<2, 4, 4> for Joint3d {
    fn advance(&mut self, dt_s: f64, v: &[f64; 4]) -> Result<(), PlantError> {
        self.step(dt_s, v)
    }
    fn counts(&self) -> [i64; 4] {
        self.wire_counts()
    }
    fn mm_per_count(&self) -> [f64; 4] {
        self.params().wires.each_ref().map(|w| w.mm_per_count)
    }
    fn true_angles_deg(&self) -> [f64; 2] {
        self.angles_deg()
    }
    fn take_camera(&mut self) -> Option<[f64; 2]> {
        self.camera().take_new().and_then(|f| f.angles_deg)
    }
    fn coil_temperatures_c(&self) -> [f64; 4] {
        Joint3d::coil_temperatures_c(self)
    }
}

impl Loads for Joint3d {
    fn hang_weight(
        &mut self,
        plane: usize,
        mass_kg: f64,
        direction: [f64; 2],
    ) -> Result<LoadId, PlantError> {
        self.add_weight_at_end(plane_3d(plane), mass_kg, direction)
    }
    fn remove_load(&mut self, plane: usize, id: LoadId) {
        Joint3d::remove_load(self, plane_3d(plane), id);
    }
}

impl Plant<1, 1, 2> for Joint2d {
    fn advance(&mut self, dt_s: f64, v: &[f64; 2]) -> Result<(), PlantError> {
        self.step(dt_s, v)
    }
    fn counts(&self) -> [i64; 1] {
        [self.wire_counts()]
    }
    fn mm_per_count(&self) -> [f64; 1] {
        [self.params().wire.mm_per_count]
    }
    fn true_angles_deg(&self) -> [f64; 1] {
        [self.angle_deg()]
    }
    fn take_camera(&mut self) -> Option<[f64; 1]> {
        self.camera()
            .take_new()
            .and_then(|f| f.angles_deg)
            .map(|a| [a[0]])
    }
    fn coil_temperatures_c(&self) -> [f64; 2] {
        Joint2d::coil_temperatures_c(self)
    }
}

impl Loads for Joint2d {
    /// The 2D joint has one plane; `plane` is ignored.
    fn hang_weight(
        &mut self,
        _plane: usize,
        mass_kg: f64,
        direction: [f64; 2],
    ) -> Result<LoadId, PlantError> {
        self.add_weight_at_end(mass_kg, direction)
    }
    fn remove_load(&mut self, _plane: usize, id: LoadId) {
        Joint2d::remove_load(self, id);
    }
}
