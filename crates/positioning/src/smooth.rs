//! Offline estimates of a whole recorded stream: the fusion stage run forward and on the
//! time-reversed stream, combined ([`wipdr_fusion::offline::two_filter`]).

use crate::positioner::FusionStage;
use crate::{PositionEstimate, PositionerConfig, PositioningError, Site};
use wipdr_core::{Point2, StepEvent, WifiObservation};
use wipdr_fusion::SchemeConfig;
use wipdr_fusion::offline::two_filter::{self, TimedEstimate};
use wipdr_fusion::replay::{FusionInput, merged};

/// Mixed into the seed of the backward run (random schemes draw other particles backward).
const BACKWARD_SEED: u64 = 0x6261_636b_7761_7264;

/// Feeds steps and fixes (time-sorted) through `stage`; the estimate after every input.
fn replay(
    stage: &mut FusionStage,
    steps: &[StepEvent],
    fixes: &[WifiObservation],
) -> Vec<PositionEstimate> {
    let mut out = Vec::with_capacity(steps.len() + fixes.len());
    for input in merged(steps, fixes) {
        let estimate = match input {
            FusionInput::Step(i) => stage.push_step(&steps[i]),
            FusionInput::Wifi(j) => stage.push_fix(&fixes[j]),
        };
        let t = match input {
            FusionInput::Step(i) => steps[i].t,
            FusionInput::Wifi(j) => fixes[j].t,
        };
        if let Some(e) = estimate {
            out.push(PositionEstimate { t, ..e });
        }
    }
    out
}

/// The smoothed track of `scheme` over a whole stream's steps and fixes: one estimate at each
/// input time (and before the forward run's first estimate, wherever the backward run has
/// one), each from the inputs before and after it. The floor is the forward run's latest
/// (the fixes' floors are the front end's, scheme-independent).
///
/// ```
/// use wipdr_core::{Candidate, MotionState, Point2, StepEvent, WifiObservation};
/// use wipdr_fusion::SchemeConfig;
/// use wipdr_positioning::{PositionerConfig, Site, smooth::smooth_fusion};
/// let fix = |t, x: f64, y: f64| WifiObservation { t, estimate: Point2::new(x, y),
///     candidates: vec![Candidate { position: Point2::new(x, y), distance: 1.0, weight: 1.0,
///     index: 0, floor: None }], visited: 1, floor: None, building: None };
/// let steps: Vec<StepEvent> = (1..=20).map(|k| StepEvent { t: 500 * k, length: 0.7,
///     heading: 0.0, heading_change: 0.0, period_s: 0.5, motion: MotionState::default() })
///     .collect();
/// let fixes = vec![fix(0, 0.0, 0.0), fix(5_000, 0.0, 7.0), fix(10_000, 0.0, 14.0)];
/// let scheme = SchemeConfig::default_for("ekf").unwrap();
/// let track = smooth_fusion(&Site::default(), &scheme, &PositionerConfig::default(), 7,
///     &steps, &fixes).unwrap();
/// assert_eq!(track.first().unwrap().t, 0);
/// assert!((track.last().unwrap().position.y - 14.0).abs() < 1.0);
/// ```
pub fn smooth_fusion(
    site: &Site,
    scheme: &SchemeConfig,
    config: &PositionerConfig,
    seed: u64,
    steps: &[StepEvent],
    fixes: &[WifiObservation],
) -> Result<Vec<PositionEstimate>, PositioningError> {
    let mut forward_stage = FusionStage::with_scheme(site, scheme, config, seed, None)?;
    let forward = replay(&mut forward_stage, steps, fixes);
    let (back_steps, back_fixes, end) = two_filter::reversed(steps, fixes);
    let mut backward_stage =
        FusionStage::with_scheme(site, scheme, config, seed ^ BACKWARD_SEED, None)?;
    let backward = replay(&mut backward_stage, &back_steps, &back_fixes);
    let timed = |e: &PositionEstimate| -> TimedEstimate { (e.t, e.position, e.covariance) };
    let joined = two_filter::combine(
        &forward.iter().map(timed).collect::<Vec<_>>(),
        &backward.iter().map(timed).collect::<Vec<_>>(),
        end,
    );
    let mut k = 0usize;
    let mut floor = None;
    Ok(joined
        .into_iter()
        .map(|(t, position, covariance): (_, Point2, _)| {
            while k < forward.len() && forward[k].t <= t {
                floor = forward[k].floor.or(floor);
                k += 1;
            }
            PositionEstimate {
                t,
                position,
                floor,
                covariance,
            }
        })
        .collect())
}
