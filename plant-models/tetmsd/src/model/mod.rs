//! The object itself: the tetrahedral mesh, the Voigt network on it, the
//! sub-volume point location and the probe's contact.
pub mod locate;
pub mod mesh;
pub mod probe;
pub mod statics;
pub mod voigt;

/// A 3-vector (position in m, velocity in m/s, force in N).
pub type V3 = nalgebra::Vector3<f64>;

/// The components of a vector by plain field access: the hot loops use
/// these, which stay fast in unoptimised (test) builds, where nalgebra's
/// operator layers are not inlined.
#[inline(always)]
pub(crate) fn c3(v: &V3) -> [f64; 3] {
    v.data.0[0]
}

/// Mutable components of a vector (see [`c3`]).
#[inline(always)]
pub(crate) fn c3_mut(v: &mut V3) -> &mut [f64; 3] {
    &mut v.data.0[0]
}
