//! Rust errors as Python exceptions: the classes of `wipdr/errors.py` (`DataError` is an
//! `OSError`, `ConfigError` and `InputError` are `ValueError`s, all are `WipdrError`s), with
//! the Rust error's message and its causes.

use pyo3::prelude::*;
use std::error::Error;

/// The Python exception class of a [`PyErrorKind`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PyErrorKind {
    /// A file or folder could not be read (`wipdr.DataError`, an `OSError`).
    Data,
    /// A config could not be read or has a bad value (`wipdr.ConfigError`, a `ValueError`).
    Config,
    /// Bad arguments or data given from Python, or an evaluation that cannot run on them
    /// (`wipdr.InputError`, a `ValueError`).
    Input,
}

impl PyErrorKind {
    fn class_name(self) -> &'static str {
        match self {
            PyErrorKind::Data => "DataError",
            PyErrorKind::Config => "ConfigError",
            PyErrorKind::Input => "InputError",
        }
    }
}

/// An error's message followed by each cause (`message: cause: cause`), as the CLI prints.
pub fn chain(e: &dyn Error) -> String {
    let mut out = e.to_string();
    let mut source = e.source();
    while let Some(s) = source {
        let text = s.to_string();
        if !out.contains(&text) {
            out.push_str(": ");
            out.push_str(&text);
        }
        source = s.source();
    }
    out
}

/// A Python exception of class `kind` with `message`.
pub fn py_error(kind: PyErrorKind, message: impl Into<String>) -> PyErr {
    let message = message.into();
    Python::attach(|py| {
        let class = py
            .import("wipdr.errors")
            .and_then(|m| m.getattr(kind.class_name()));
        match class {
            Ok(class) => match class.call1((message.clone(),)) {
                Ok(value) => PyErr::from_value(value),
                Err(e) => e,
            },
            // The package's errors module is missing (the extension imported on its own).
            Err(_) => pyo3::exceptions::PyValueError::new_err(message),
        }
    })
}

/// A `wipdr.InputError` with `message`.
pub fn input_error(message: impl Into<String>) -> PyErr {
    py_error(PyErrorKind::Input, message)
}

/// A reader's error as a `wipdr.DataError`.
pub fn io_error(e: &wipdr_io::IoError) -> PyErr {
    py_error(PyErrorKind::Data, e.full_message())
}

/// An evaluation error: config errors as `wipdr.ConfigError`, the rest as `wipdr.InputError`.
pub fn eval_error(e: &wipdr_eval::pipeline::EvalError) -> PyErr {
    use wipdr_eval::pipeline::EvalError;
    let kind = match e {
        EvalError::Config { .. } | EvalError::InvalidConfig { .. } => PyErrorKind::Config,
        EvalError::Positioning {
            source:
                wipdr_positioning::PositioningError::InvalidConfig { .. }
                | wipdr_positioning::PositioningError::Parse(_),
            ..
        } => PyErrorKind::Config,
        _ => PyErrorKind::Input,
    };
    py_error(kind, chain(e))
}
