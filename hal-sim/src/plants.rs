//! [`Plant`] implementations for the joint models of `plant-models`.
use crate::Plant;
use plant_models::joint::{Joint2d, Joint3d, PlantError};

impl Plant<4, 4, 2> for Joint3d {
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

impl Plant<2, 1, 1> for Joint2d {
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
