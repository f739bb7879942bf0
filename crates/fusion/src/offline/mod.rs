//! Offline (whole-walk) estimation: estimates that may use the inputs after their time.
//!
//! - [`two_filter`]: any scheme run forward and on the time-reversed walk, the two estimates
//!   combined at each time (information-weighted where both have a covariance).
//!
//! Tried and not kept (session 6, `docs/results/accuracy.md`): placing the PDR shape onto all
//! of a walk's Wi-Fi fixes by a locally weighted robust rigid fit: 5.9-6.4 m pooled on the
//! five ILC floors against 5.65 m for the two-filter `pmf` (both with the old defaults).

pub mod two_filter;
