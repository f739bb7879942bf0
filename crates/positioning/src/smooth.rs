//! Offline estimates of a whole recorded stream: the scheme's own whole-walk smoother where
//! it has one (`pmf`, [`wipdr_fusion::offline::native_smooth`]), else the fusion stage run
//! forward and on the time-reversed stream, combined ([`wipdr_fusion::offline::two_filter`]).

use crate::positioner::FusionStage;
use crate::{PositionEstimate, PositionerConfig, PositioningError, Site};
use wipdr_core::{Point2, StepEvent, WifiObservation};
use wipdr_fusion::SchemeConfig;
use wipdr_fusion::offline::native_smooth;
use wipdr_fusion::offline::two_filter::{self, TimedEstimate};

/// Mixed into the seed of the backward run (random schemes draw other particles backward).
const BACKWARD_SEED: u64 = 0x6261_636b_7761_7264;

/// The smoothed track of `scheme` over a whole stream's steps and fixes: one estimate at each
/// input time (and before the forward run's first estimate, wherever the backward run has
/// one), each from the inputs before and after it. The floor is the forward run's latest
/// (the fixes' floors are the front end's, scheme-independent). A scheme with its own
/// whole-walk smoother (`pmf`) uses it unless a static start is configured (then, and for
/// a walk too large for it, the two-filter).
///
/// ```
/// use wipdr_core::{Candidate, MotionState, Point2, StepEvent, WifiObservation};
/// use wipdr_fusion::SchemeConfig;
/// use wipdr_positioning::{PositionerConfig, Site, smooth::smooth_fusion};
/// let fix = |t, x: f64, y: f64| WifiObservation { t, estimate: Point2::new(x, y),
///     candidates: vec![Candidate { position: Point2::new(x, y), distance: 1.0, weight: 1.0,
///     index: 0, floor: None }], visited: 1, floor: None, building: None, likelihood: None };
/// let steps: Vec<StepEvent> = (1..=20).map(|k| StepEvent { t: 500 * k, length: 0.7,
///     heading: 0.0, heading_change: 0.0, period_s: 0.5, motion: MotionState::default(), covariance: None })
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
    if config.static_start.is_none()
        && let Some(native) = native_smooth(scheme, &site.build_context(seed, None), steps, fixes)
    {
        let track = native.map_err(|source| PositioningError::Scheme {
            scheme: scheme.name().to_string(),
            source,
        })?;
        let walkable = site.walkable.as_ref().filter(|_| config.map_matching);
        let mut k = 0usize;
        let mut floor = None;
        return Ok(track
            .into_iter()
            .map(|e| {
                while k < fixes.len() && fixes[k].t <= e.t {
                    floor = fixes[k].floor.or(floor);
                    k += 1;
                }
                PositionEstimate {
                    t: e.t,
                    position: walkable.map_or(e.position, |g| g.map_match(e.position)),
                    floor,
                    covariance: e.covariance,
                }
            })
            .collect());
    }
    let mut forward_stage = FusionStage::with_scheme(site, scheme, config, seed, None)?;
    let forward = forward_stage.replay(steps, fixes, None);
    let (back_steps, back_fixes, end) = two_filter::reversed(steps, fixes);
    let mut backward_stage =
        FusionStage::with_scheme(site, scheme, config, seed ^ BACKWARD_SEED, None)?;
    let backward = backward_stage.replay(&back_steps, &back_fixes, None);
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
