//! Offline (whole-walk) estimation: estimates that may use the inputs after their time.
//!
//! - [`two_filter`]: any scheme run forward and on the time-reversed walk, the two estimates
//!   combined at each time (information-weighted where both have a covariance).
//! - [`native_smooth`]: a scheme's own whole-walk smoother where it has one: `pmf`'s exact
//!   forward-backward product on its lattice ([`crate::PointMassFilter::smooth_walk`]; with
//!   heading hypotheses, each one's, weighed by evidence: [`PointMassMixture::smooth_walk`]).
//!
//! Tried and not kept (`docs/experiments.md`, whole-walk alignment): placing the PDR shape onto all
//! of a walk's Wi-Fi fixes by a locally weighted robust rigid fit: 5.9-6.4 m pooled on the
//! five ILC floors against 5.65 m for the two-filter `pmf` (both with the old defaults).

pub mod two_filter;

use wipdr_core::{StepEvent, WifiObservation};

use crate::point_mass::PointMassMixture;
use crate::{BuildContext, Estimate, FusionError, SchemeConfig};

/// The smoothed estimate after every input of a whole walk by `scheme`'s own smoother:
/// `None` for a scheme without one (smooth it with [`two_filter`]) and for a walk too large
/// for it (logged), `Some(Err)` when the scheme cannot be built. `ctx.start` must be `None`
/// (a known start is a causal baseline's, not smoothed).
///
/// ```
/// use wipdr_core::{MotionState, Point2, StepEvent, WifiObservation};
/// use wipdr_fusion::{BuildContext, SchemeConfig, offline::native_smooth};
/// let fix = |t, x: f64, y: f64| WifiObservation { t, estimate: Point2::new(x, y),
///     candidates: vec![], visited: 0, floor: None, building: None, likelihood: None };
/// let steps: Vec<StepEvent> = (1..=10).map(|k| StepEvent { t: 500 * k, length: 0.7,
///     heading: 0.0, heading_change: 0.0, period_s: 0.5, motion: MotionState::default(), covariance: None })
///     .collect();
/// let fixes = vec![fix(0, 0.0, 0.0), fix(5_000, 0.0, 7.0)];
/// let ctx = BuildContext::default();
/// let pmf = SchemeConfig::default_for("pmf").unwrap();
/// assert_eq!(native_smooth(&pmf, &ctx, &steps, &fixes).unwrap().unwrap().len(), 12);
/// let ekf = SchemeConfig::default_for("ekf").unwrap();
/// assert!(native_smooth(&ekf, &ctx, &steps, &fixes).is_none());
/// ```
pub fn native_smooth(
    scheme: &SchemeConfig,
    ctx: &BuildContext,
    steps: &[StepEvent],
    fixes: &[WifiObservation],
) -> Option<Result<Vec<Estimate>, FusionError>> {
    match scheme {
        SchemeConfig::Pmf(cfg) => {
            let filter = match PointMassMixture::from_context(cfg, ctx) {
                Ok(f) => f,
                Err(e) => return Some(Err(e)),
            };
            match filter.smooth_walk(steps, fixes) {
                Ok(track) => Some(Ok(track)),
                Err(e) => {
                    tracing::warn!("{e}; smoothing with the two-filter instead");
                    None
                }
            }
        }
        _ => None,
    }
}
