//! Columns of the CSVs the program writes, handed to Python as NumPy
//! arrays after the same finite-value check the CSV writers make.

use host_tools::output;
use numpy::{PyArray1, ToPyArray};
use pyo3::prelude::*;
use std::collections::BTreeMap;

use crate::errors::to_py;

/// Columns by name as NumPy arrays.
pub type PyColumns<'py> = BTreeMap<&'static str, Bound<'py, PyArray1<f64>>>;

/// `cols` as NumPy arrays by name; a non-finite value is refused with
/// `what` and the column named, as the program's CSV writers refuse it.
pub fn py_columns<'py>(
    py: Python<'py>,
    what: &str,
    cols: Vec<(&'static str, Vec<f64>)>,
) -> PyResult<PyColumns<'py>> {
    output::check_value(what, &cols).map_err(to_py)?;
    Ok(cols
        .into_iter()
        .map(|(k, v)| (k, v.to_pyarray(py)))
        .collect())
}
