//! `pmf` over several constant PDR heading biases and step-length scales: one lattice per
//! hypothesis ([`PointMassConfig::heading_hypotheses_deg`] x
//! [`PointMassConfig::step_scale_hypotheses`]), weighed by its evidence (Bayesian model
//! averaging over a static parameter, exact given the lattices).
//!
//! A phone's heading is often off by a few degrees for a whole walk (the compass's local
//! field, how the phone sits in the hand); a lattice over the track's placement absorbs that
//! only as drift, so a long straight corridor walked a few degrees off smears the
//! placement. Each hypothesis rotates every step by its offset; the inputs' marginal
//! likelihood ([`PointMassFilter::log_evidence`]: the walls' and the fixes' weights)
//! decides between them as the walk goes on. The causal estimate is the mixture's mean and
//! covariance (the components' estimates weighed by their posterior probability); the
//! offline one ([`PointMassMixture::smooth_walk`]) weighs each component's smoothed track by
//! the evidence of the whole walk.

use nalgebra::Matrix2;
use wipdr_core::{Point2, StepEvent, Vector2, WifiObservation};

use super::{PointMassConfig, PointMassFilter, SmoothError};
use crate::{BuildContext, Estimate, Fuser, FusionError};

/// Most heading hypotheses (each is a lattice as large as the plan's).
pub const MAX_HEADING_HYPOTHESES: usize = 16;

/// `pmf` as a mixture over heading (and step-scale) hypotheses; see the [module docs](self).
///
/// ```
/// use wipdr_core::{MotionState, Point2, StepEvent, WifiObservation};
/// use wipdr_fusion::{BuildContext, Fuser, point_mass::{PointMassConfig, PointMassMixture}};
/// let cfg = PointMassConfig { heading_hypotheses_deg: vec![-10.0, 0.0, 10.0],
///     ..PointMassConfig::default() };
/// let mut f = PointMassMixture::from_context(&cfg, &BuildContext::default()).unwrap();
/// let fix = |t, x: f64, y: f64| WifiObservation { t, estimate: Point2::new(x, y),
///     candidates: vec![], visited: 0, floor: None, building: None, likelihood: None };
/// f.on_wifi(&fix(0, 0.0, 0.0));
/// for k in 1..=40 {
///     // PDR says north; the fixes say the walk heads 10 degrees east of north.
///     f.on_step(&StepEvent { t: 500 * k, length: 0.7, heading: 0.0, heading_change: 0.0,
///         period_s: 0.5, motion: MotionState::default(), covariance: None });
///     if k % 10 == 0 {
///         let d = 0.7 * k as f64;
///         f.on_wifi(&fix(500 * k, d * 10f64.to_radians().sin(), d * 10f64.to_radians().cos()));
///     }
/// }
/// let w = f.weights();
/// assert!(w[2] > w[0] && w[2] > w[1], "{w:?}");
/// assert!(f.estimate().unwrap().position.x > 3.0);
/// ```
#[derive(Debug, Clone)]
pub struct PointMassMixture {
    components: Vec<PointMassFilter>,
}

impl PointMassMixture {
    /// One component per pair of an entry of `cfg.heading_hypotheses_deg` (each added to
    /// `cfg.heading_offset_deg`) and one of `cfg.step_scale_hypotheses` (each multiplying
    /// `cfg.step_scale`), heading-major, built as [`PointMassFilter::from_context`] builds
    /// `pmf`.
    pub fn from_context(cfg: &PointMassConfig, ctx: &BuildContext) -> Result<Self, FusionError> {
        cfg.validate()?;
        let or_one = |v: &[f64], none: f64| if v.is_empty() { vec![none] } else { v.to_vec() };
        let headings = or_one(&cfg.heading_hypotheses_deg, 0.0);
        let scales = or_one(&cfg.step_scale_hypotheses, 1.0);
        let components = headings
            .iter()
            .flat_map(|h| scales.iter().map(move |k| (*h, *k)))
            .map(|(h, k)| {
                let c = PointMassConfig {
                    heading_offset_deg: cfg.heading_offset_deg + h,
                    heading_hypotheses_deg: Vec::new(),
                    step_scale: cfg.step_scale * k,
                    step_scale_hypotheses: Vec::new(),
                    ..cfg.clone()
                };
                PointMassFilter::from_context(&c, ctx)
            })
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Self { components })
    }

    /// The components' posterior probabilities (summing to 1), in the order of the hypotheses.
    pub fn weights(&self) -> Vec<f64> {
        normalised_weights(self.components.iter().map(PointMassFilter::log_evidence))
    }

    /// The smoothed estimate after every input of a whole walk: each component smoothed on its
    /// lattice ([`PointMassFilter::smooth_walk`]), the tracks combined by the components'
    /// whole-walk evidence.
    pub fn smooth_walk(
        self,
        steps: &[StepEvent],
        fixes: &[WifiObservation],
    ) -> Result<Vec<Estimate>, SmoothError> {
        if self.components.len() == 1 {
            let only = self.components.into_iter().next();
            return only.map_or(Ok(Vec::new()), |c| c.smooth_walk(steps, fixes));
        }
        let mut tracks = Vec::with_capacity(self.components.len());
        let mut evidence = Vec::with_capacity(self.components.len());
        for c in self.components {
            let (track, e) = c.smooth_walk_with_evidence(steps, fixes)?;
            tracks.push(track);
            evidence.push(e);
        }
        let weights = normalised_weights(evidence.iter().copied());
        let n = tracks.first().map_or(0, Vec::len);
        if tracks.iter().any(|t| t.len() != n) {
            // The components see the same inputs, so this does not happen; if it did, the
            // most probable component's track is still a whole answer.
            tracing::warn!("pmf mixture: smoothed tracks of unequal length; the best one kept");
            let best = (0..weights.len())
                .max_by(|&a, &b| weights[a].total_cmp(&weights[b]))
                .unwrap_or(0);
            return Ok(tracks.swap_remove(best));
        }
        Ok((0..n)
            .filter_map(|i| combine(tracks.iter().map(|t| &t[i]).zip(weights.iter().copied())))
            .collect())
    }
}

/// `exp(l - max)` normalised; uniform when the evidence is not finite anywhere.
fn normalised_weights(log_evidence: impl Iterator<Item = f64>) -> Vec<f64> {
    let l: Vec<f64> = log_evidence.collect();
    let max = l
        .iter()
        .copied()
        .filter(|v| v.is_finite())
        .fold(f64::NEG_INFINITY, f64::max);
    let w: Vec<f64> = l
        .iter()
        .map(|&v| {
            if v.is_finite() && max.is_finite() {
                (v - max).exp()
            } else {
                0.0
            }
        })
        .collect();
    let sum: f64 = w.iter().sum();
    if sum > 0.0 && sum.is_finite() {
        w.iter().map(|v| v / sum).collect()
    } else {
        vec![1.0 / l.len().max(1) as f64; l.len()]
    }
}

/// The weighted mixture of estimates: the mean, and the covariance of the mixture (each
/// component's covariance plus its mean's spread about the mixture's). `None` without weight.
fn combine<'a>(parts: impl Iterator<Item = (&'a Estimate, f64)> + Clone) -> Option<Estimate> {
    let total: f64 = parts.clone().map(|(_, w)| w).sum();
    let first = parts.clone().max_by(|a, b| a.1.total_cmp(&b.1))?.0;
    if !(total > 0.0 && total.is_finite()) {
        return Some(first.clone());
    }
    let mean: Vector2 = parts
        .clone()
        .map(|(e, w)| e.position.coords * (w / total))
        .sum();
    let mut covariance = Matrix2::zeros();
    for (e, w) in parts {
        let d = e.position.coords - mean;
        covariance +=
            (e.covariance.unwrap_or_else(Matrix2::zeros) + d * d.transpose()) * (w / total);
    }
    crate::kalman::enforce_symmetric_pd(&mut covariance);
    Some(Estimate {
        position: Point2::from(mean),
        covariance: Some(covariance),
        ..first.clone()
    })
}

impl Fuser for PointMassMixture {
    fn name(&self) -> &'static str {
        "pmf"
    }

    fn on_step(&mut self, step: &StepEvent) {
        for c in &mut self.components {
            c.on_step(step);
        }
    }

    fn on_wifi(&mut self, obs: &WifiObservation) {
        for c in &mut self.components {
            c.on_wifi(obs);
        }
    }

    fn estimate(&self) -> Option<Estimate> {
        if let [only] = self.components.as_slice() {
            return only.estimate();
        }
        let estimates: Vec<Option<Estimate>> =
            self.components.iter().map(Fuser::estimate).collect();
        let weights = self.weights();
        combine(
            estimates
                .iter()
                .zip(weights)
                .filter_map(|(e, w)| e.as_ref().map(|e| (e, w))),
        )
    }
}
