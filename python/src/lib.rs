//! # wipdr-python — the `wipdr` Python package's extension module (`wipdr._wipdr`)
//!
//! Conversions only: every behaviour is the Rust crates'. Walks and floors are read by
//! `wipdr-io` ([`wipdr_io::any`], as the CLI reads paths), evaluated by `wipdr-eval`'s
//! protocol (the dict of `wipdr.evaluate` is [`wipdr_eval::report::EvalReport::to_json`],
//! the document `wipdr eval --json` writes), and streams run through
//! [`wipdr_positioning::Positioner`]. numpy arrays in and out; errors as the exception
//! classes of `wipdr/errors.py`; the GIL is released during reads, evaluations and
//! locates. Built with maturin (`pip install ./python`); tested with pytest
//! (`python/tests`).

mod convert;
mod errors;
mod eval;
mod floor;
mod positioner;
mod walk;

use pyo3::prelude::*;

/// The extension module: classes and functions re-exported by `wipdr/__init__.py`.
#[pymodule]
fn _wipdr(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<walk::PyWalk>()?;
    m.add_class::<floor::PyFloorPlan>()?;
    m.add_class::<floor::PyFloor>()?;
    m.add_class::<positioner::PySiteModel>()?;
    m.add_class::<positioner::PyPositioner>()?;
    m.add_class::<positioner::PyEstimate>()?;
    m.add_function(wrap_pyfunction!(walk::read_walk, m)?)?;
    m.add_function(wrap_pyfunction!(floor::read_floor, m)?)?;
    m.add_function(wrap_pyfunction!(eval::evaluate, m)?)?;
    m.add_function(wrap_pyfunction!(eval::locate, m)?)?;
    m.add("SCHEMES", wipdr_fusion::scheme_names().to_vec())?;
    Ok(())
}
