//! The exceptions: one base class, `SoftjointError`, and a class per kind
//! of failure a caller may want to catch on its own. Each carries the
//! Rust error's message with its context chain (`{:#}`, as the program
//! prints it on stderr).
use host_tools::output::NonFinite;
use host_tools::run::summary::RunCutShort;
use plant_rheology::RheologyError;
use pyo3::exceptions::PyException;
use pyo3::prelude::*;

pyo3::create_exception!(
    softjoint,
    SoftjointError,
    PyException,
    "Any error of the softjoint package; its message is the Rust error's."
);
pyo3::create_exception!(
    softjoint,
    InputError,
    SoftjointError,
    "A scenario, plant file, measurement or argument was refused (the message names the file, field or argument)."
);
pyo3::create_exception!(
    softjoint,
    NonFiniteError,
    SoftjointError,
    "A result held a NaN or infinite number; the program's output checks refuse it."
);
pyo3::create_exception!(
    softjoint,
    RunCutShortError,
    SoftjointError,
    "A closed-loop run ended before its end (an unstable plant, a fault of the run)."
);
pyo3::create_exception!(
    softjoint,
    UnstableError,
    SoftjointError,
    "A simulation became unstable (the message names the step and the cause)."
);
pyo3::create_exception!(
    softjoint,
    UnverifiedError,
    SoftjointError,
    "A result failed its own checks (a contour fit's frames marked unverified); the result is attached as `.fit`."
);
pyo3::create_exception!(
    softjoint,
    SweepError,
    SoftjointError,
    "A sweep's units or their scores do not fit together, or its objective failed."
);

/// Adds the exception classes to the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("SoftjointError", py.get_type::<SoftjointError>())?;
    m.add("InputError", py.get_type::<InputError>())?;
    m.add("NonFiniteError", py.get_type::<NonFiniteError>())?;
    m.add("RunCutShortError", py.get_type::<RunCutShortError>())?;
    m.add("UnstableError", py.get_type::<UnstableError>())?;
    m.add("SweepError", py.get_type::<SweepError>())?;
    m.add("UnverifiedError", py.get_type::<UnverifiedError>())?;
    Ok(())
}

/// A Rust error as the exception of its kind: a non-finite result, a run
/// cut short and an unstable simulation by their types, anything else as
/// `SoftjointError`.
pub fn to_py(e: anyhow::Error) -> PyErr {
    let msg = format!("{e:#}");
    if e.chain().any(|c| c.downcast_ref::<NonFinite>().is_some()) {
        return NonFiniteError::new_err(msg);
    }
    if e.chain().any(|c| c.downcast_ref::<RunCutShort>().is_some()) {
        return RunCutShortError::new_err(msg);
    }
    rheology_to_py(
        e.chain().find_map(|c| c.downcast_ref::<RheologyError>()),
        msg,
    )
}

/// A rheology error by its kind (`msg` is the whole message).
pub fn rheology_to_py(e: Option<&RheologyError>, msg: String) -> PyErr {
    match e {
        Some(RheologyError::Unstable { .. }) => UnstableError::new_err(msg),
        Some(RheologyError::Evaluation { .. }) => SweepError::new_err(msg),
        Some(_) => InputError::new_err(msg),
        None => SoftjointError::new_err(msg),
    }
}

/// A refused input (a file, a field, an argument) as `InputError`.
pub fn input(e: anyhow::Error) -> PyErr {
    InputError::new_err(format!("{e:#}"))
}
