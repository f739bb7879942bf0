//! Trust Chain Positioning Fusion (paper 002 §4.3, eq. 15-19), scheme `tcpf`.
//!
//! # The algorithm
//!
//! Epochs are Wi-Fi fixes. Between epochs the position is dead-reckoned and the TC parameter
//! grows with the distance walked, `lambda += alpha d_PDR` (eq. 17), where
//! `alpha = (PDR error per metre) / (mean Wi-Fi error)`: by default
//! `(0.089675 m / 0.75 m) / 2.68 m` (002 eq. 14, §5.3 and its improved Wi-Fi error).
//!
//! At an epoch, with `Dist_p, Dir_p` the PDR displacement since the latest fused point and
//! `Dist_w, Dir_w` the vector from that point to the Wi-Fi fix, the fix is a *trusted point*
//! when `|Dist_p - Dist_w| <= rho` (2 m) and `|Dir_p - Dir_w| <= beta` (45°) (eq. 15). The
//! direction test is skipped when `Dist_p < rho`: the annular sector then degenerates into a
//! disc (standing still, or a stride too short for a direction).
//!
//! The state machine (figure 8 is missing from the text; this is `docs/algorithms.md`'s reading,
//! implemented by [`next_state`]): a trusted point goes to [`TrustState::TrustedLocked`];
//! otherwise a locked state (TrustedLocked or Locked) goes to Locked while
//! `lambda_{t|t-1} <= epsilon` (1) and to Unlocked when it exceeds it; Unlocked stays
//! Unlocked until the next trusted point. The transition uses `lambda_{t|t-1}`, the value
//! before the epoch's fusion, because the new state decides which candidates are averaged.
//!
//! In locked states only the Wi-Fi candidates inside the trusted area are averaged (by their
//! weights); in Unlocked all are. When no candidate lies inside the area the epoch fuses
//! nothing (the PDR position stands). Fusion: `L = (L_pdr + lambda L_wifi) / (1 + lambda)`
//! (eq. 16), then `lambda = 0` on a trusted point, else `lambda (1 + lambda)` (eq. 18),
//! capped at `lambda_max` so that it stays finite (an Unlocked chain otherwise grows
//! doubly exponentially; at the cap the fusion is the Wi-Fi fix to 1e-6).
//!
//! A chain started from a wrong fix recovers by itself: untrusted epochs unlock it and the
//! Wi-Fi then dominates. The start state is Unlocked with `lambda = epsilon` by default.

use serde::{Deserialize, Serialize};
use wipdr_core::ConfigError;
use wipdr_core::{Point2, StepEvent, TimestampMs, Vector2, WifiObservation, angle};

use crate::fix_error::{GainVariance, RadiusConfig};
use crate::{Diagnostics, Estimate, Fuser, FusionError, InputGuard, usable_candidates};

/// Trust state of the chain (002 §4.3.3).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum TrustState {
    /// The current point is a trusted point.
    TrustedLocked,
    /// Locked to the latest trusted point, candidates filtered.
    Locked,
    /// Unlocked: Wi-Fi relied on, candidates not filtered.
    Unlocked,
}

/// The transition of the trust state machine (see the module docs).
///
/// ```
/// use wipdr_fusion::tcpf::{next_state, TrustState::*};
/// assert_eq!(next_state(Unlocked, true, 5.0, 1.0), TrustedLocked);
/// assert_eq!(next_state(TrustedLocked, false, 0.3, 1.0), Locked);
/// assert_eq!(next_state(Locked, false, 1.2, 1.0), Unlocked);
/// assert_eq!(next_state(Unlocked, false, 0.0, 1.0), Unlocked);
/// ```
pub fn next_state(
    current: TrustState,
    trusted: bool,
    lambda_prior: f64,
    epsilon: f64,
) -> TrustState {
    if trusted {
        return TrustState::TrustedLocked;
    }
    match current {
        TrustState::Unlocked => TrustState::Unlocked,
        TrustState::TrustedLocked | TrustState::Locked => {
            if lambda_prior <= epsilon {
                TrustState::Locked
            } else {
                TrustState::Unlocked
            }
        }
    }
}

/// Parameters of TCPF (002 §4.3).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TcpfConfig {
    /// Step-length tolerance `rho` of the trusted area, metres (2 m).
    pub rho_m: f64,
    /// Direction tolerance `beta` of the trusted area, degrees (45°).
    pub beta_deg: f64,
    /// Determination factor `epsilon` between Locked and Unlocked (1).
    pub epsilon: f64,
    /// Expected PDR error per metre walked (002 eq. 14, §5.3: 0.089675 m per 0.75 m step).
    pub pdr_error_per_metre: f64,
    /// Mean Wi-Fi error, metres (002: 2.68 m, its improved Wi-Fi).
    pub wifi_mean_error_m: f64,
    /// Cap of `lambda` (keeps it finite).
    pub lambda_max: f64,
    /// Start state.
    pub initial_state: TrustState,
    /// Start value of `lambda`.
    pub initial_lambda: f64,
    /// The horizontal uncertainty of the estimate (wipdr's own; the paper gives none):
    /// [`crate::fix_error`], the same in the default and the paper preset.
    pub radius: RadiusConfig,
}

/// The shipped default is tuned for recorded smartphone walks (docs/results/papers.md):
/// `rho_m`, `beta_deg` and `epsilon` from the `tcpf` sweep (`docs/sweeps/tune-tcpf.toml`);
/// `alpha` from the PDR error model of eq. 14 (`wipdr pdr-fit`: 0.2034 m of error per metre
/// walked, heading sigma 14.7 deg) over the measured Wi-Fi mean error (8.09 m), as §5.3
/// derives it. [`TcpfConfig::paper`] holds the paper's values.
impl Default for TcpfConfig {
    fn default() -> Self {
        Self {
            rho_m: 5.6,
            beta_deg: 50.0,
            epsilon: 0.125,
            pdr_error_per_metre: 0.2034,
            wifi_mean_error_m: 8.09,
            ..Self::paper()
        }
    }
}

impl TcpfConfig {
    /// The paper's values (002 §5.3: rho 2 m, beta 45 deg, epsilon 1, 8.9675 cm per 0.75 m
    /// step, Wi-Fi mean error 2.68 m).
    pub fn paper() -> Self {
        Self {
            rho_m: 2.0,
            beta_deg: 45.0,
            epsilon: 1.0,
            pdr_error_per_metre: 0.089675 / 0.75,
            wifi_mean_error_m: 2.68,
            lambda_max: 1e6,
            initial_state: TrustState::Unlocked,
            initial_lambda: 1.0,
            radius: RadiusConfig::default(),
        }
    }
}

impl TcpfConfig {
    /// `alpha` of eq. 17: PDR error per metre over the mean Wi-Fi error (1/m).
    pub fn alpha(&self) -> f64 {
        self.pdr_error_per_metre / self.wifi_mean_error_m
    }

    /// Checks every field.
    pub fn validate(&self) -> Result<(), FusionError> {
        let checks: [(&'static str, f64, bool); 7] = [
            ("rho_m", self.rho_m, self.rho_m > 0.0),
            (
                "beta_deg",
                self.beta_deg,
                self.beta_deg > 0.0 && self.beta_deg <= 180.0,
            ),
            ("epsilon", self.epsilon, self.epsilon >= 0.0),
            (
                "pdr_error_per_metre",
                self.pdr_error_per_metre,
                self.pdr_error_per_metre >= 0.0,
            ),
            (
                "wifi_mean_error_m",
                self.wifi_mean_error_m,
                self.wifi_mean_error_m > 0.0,
            ),
            ("lambda_max", self.lambda_max, self.lambda_max > 0.0),
            (
                "initial_lambda",
                self.initial_lambda,
                self.initial_lambda >= 0.0,
            ),
        ];
        for (field, v, ok) in checks {
            if !(v.is_finite() && ok) {
                return Err(FusionError::InvalidConfig(ConfigError::new(
                    field,
                    format!("out of range: {v}"),
                )));
            }
        }
        self.radius.validate()
    }
}

/// The TCPF fuser.
#[derive(Debug, Clone)]
pub struct Tcpf {
    cfg: TcpfConfig,
    alpha: f64,
    position: Option<Point2>,
    anchor: Point2,
    pdr_since_anchor: Vector2,
    lambda: f64,
    state: TrustState,
    t: TimestampMs,
    last_trusted: Option<bool>,
    variance: GainVariance,
    guard: InputGuard,
}

impl Tcpf {
    /// Builds TCPF; `start` initialises at a known position.
    pub fn new(cfg: TcpfConfig, start: Option<Point2>) -> Result<Self, FusionError> {
        cfg.validate()?;
        let mut variance = GainVariance::new(cfg.radius.clone());
        if start.is_some() {
            variance.start_known(0.0);
        }
        Ok(Self {
            variance,
            alpha: cfg.alpha(),
            position: start,
            anchor: start.unwrap_or_else(Point2::origin),
            pdr_since_anchor: Vector2::zeros(),
            lambda: cfg.initial_lambda,
            state: cfg.initial_state,
            t: 0,
            last_trusted: None,
            guard: InputGuard::default(),
            cfg,
        })
    }

    /// Current trust state.
    pub fn state(&self) -> TrustState {
        self.state
    }

    /// Current TC parameter.
    pub fn lambda(&self) -> f64 {
        self.lambda
    }

    /// Whether `p` lies in the trusted area (eq. 15) around the latest fused point.
    fn in_trusted_area(&self, p: Point2) -> bool {
        let dist_p = self.pdr_since_anchor.norm();
        let w = p - self.anchor;
        let dist_w = w.norm();
        if (dist_p - dist_w).abs() > self.cfg.rho_m {
            return false;
        }
        if dist_p < self.cfg.rho_m {
            return true;
        }
        let dir_p = angle::heading_of(self.pdr_since_anchor);
        let dir_w = angle::heading_of(w);
        angle::diff(dir_p, dir_w).abs() <= self.cfg.beta_deg.to_radians()
    }
}

impl Fuser for Tcpf {
    fn name(&self) -> &'static str {
        "tcpf"
    }

    fn on_step(&mut self, step: &StepEvent) {
        if !self.guard.accept_step(step) {
            return;
        }
        if let Some(p) = &mut self.position {
            let d = angle::step_displacement(step.length, step.heading);
            *p += d;
            self.pdr_since_anchor += d;
            self.variance.step(step.length);
            // eq. 17, accumulated per step
            self.lambda = (self.lambda + self.alpha * step.length).min(self.cfg.lambda_max);
            self.t = step.t;
        }
    }

    fn on_wifi(&mut self, obs: &WifiObservation) {
        if !self.guard.accept_wifi(obs) {
            return;
        }
        self.t = obs.t;
        let Some(pdr) = self.position else {
            self.position = Some(obs.estimate);
            self.anchor = obs.estimate;
            self.pdr_since_anchor = Vector2::zeros();
            self.variance.start();
            return;
        };
        let trusted = self.in_trusted_area(obs.estimate);
        let lambda_prior = self.lambda;
        self.state = next_state(self.state, trusted, lambda_prior, self.cfg.epsilon);
        let candidates = usable_candidates(obs);
        let selected: Vec<(Point2, f64)> = match self.state {
            TrustState::Unlocked => candidates,
            TrustState::TrustedLocked | TrustState::Locked => {
                let mut inside: Vec<(Point2, f64)> = candidates
                    .into_iter()
                    .filter(|(p, _)| self.in_trusted_area(*p))
                    .collect();
                if inside.is_empty() && trusted {
                    inside.push((obs.estimate, 1.0));
                }
                inside
            }
        };
        let wsum: f64 = selected.iter().map(|(_, w)| w).sum();
        let fused = if selected.is_empty() {
            self.variance.fix(obs.estimate - pdr, 0.0);
            pdr
        } else {
            let n = selected.len() as f64;
            let wifi = selected.iter().fold(Vector2::zeros(), |acc, (p, w)| {
                acc + p.coords * if wsum > 0.0 { w / wsum } else { 1.0 / n }
            });
            // the gain of eq. 16 on the averaged candidates
            self.variance
                .fix(wifi - pdr.coords, lambda_prior / (1.0 + lambda_prior));
            // eq. 16
            Point2::from((pdr.coords + wifi * lambda_prior) / (1.0 + lambda_prior))
        };
        // eq. 18
        self.lambda = if trusted {
            0.0
        } else {
            (lambda_prior * (1.0 + lambda_prior)).min(self.cfg.lambda_max)
        };
        self.last_trusted = Some(trusted);
        self.position = Some(fused);
        self.anchor = fused;
        self.pdr_since_anchor = Vector2::zeros();
    }

    fn estimate(&self) -> Option<Estimate> {
        self.position.map(|position| Estimate {
            t: self.t,
            position,
            covariance: Some(self.variance.covariance()),
            diagnostics: Diagnostics {
                trust_state: Some(self.state),
                tc_lambda: Some(self.lambda),
                wifi_flagged: self.last_trusted.map(|t| !t),
                ..self.guard.diagnostics()
            },
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synthetic::{obs_at, step};
    use proptest::prelude::*;

    #[test]
    fn the_radius_grows_by_dead_reckoning_and_shrinks_at_a_fix() {
        let mut f = Tcpf::new(TcpfConfig::default(), None).unwrap();
        // the second fix is a trusted point after 14 m: lambda > 0
        let [at_fix, walked, after] = crate::synthetic::variance_at_fix_walk_fix(&mut f).unwrap();
        assert!(walked > at_fix, "{walked} <= {at_fix}");
        assert!(after < walked);
    }

    #[test]
    fn trusted_point_resets_lambda_and_locks() {
        let mut f = Tcpf::new(TcpfConfig::default(), None).unwrap();
        f.on_wifi(&obs_at(0, 0.0, 0.0));
        for k in 1..=4 {
            f.on_step(&step(500 * k, 0.75, 0.0));
        }
        f.on_wifi(&obs_at(2000, 0.3, 3.2)); // 3 m north by PDR, fix 3.2 m north: trusted
        assert_eq!(f.state(), TrustState::TrustedLocked);
        assert_eq!(f.lambda(), 0.0);
        for k in 5..=8 {
            f.on_step(&step(500 * k, 0.75, 0.0));
        }
        f.on_wifi(&obs_at(4000, 40.0, 3.0)); // far off: untrusted, lambda small -> Locked
        assert_eq!(f.state(), TrustState::Locked);
        let p = f.estimate().unwrap().position;
        // no candidate inside the area: the PDR position stands
        assert!(p.x.abs() < 0.5 && (p.y - 6.0).abs() < 0.6, "{p:?}");
    }

    #[test]
    fn recovers_from_a_wrong_start() {
        let mut f = Tcpf::new(TcpfConfig::default(), None).unwrap();
        f.on_wifi(&obs_at(0, 60.0, 0.0)); // wrong start
        let mut t = 0;
        for k in 0..30 {
            for _ in 0..3 {
                t += 500;
                f.on_step(&step(t, 0.7, 0.0));
            }
            f.on_wifi(&obs_at(t, 0.0, 2.1 * (k + 1) as f64));
        }
        let p = f.estimate().unwrap().position;
        assert!((p - Point2::new(0.0, 63.0)).norm() < 3.0, "{p:?}");
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        #[test]
        fn lambda_finite_and_transitions_documented(
            inputs in prop::collection::vec(
                (any::<bool>(), 0.0f64..3.0, -4.0f64..4.0, -1e6f64..1e6, -1e6f64..1e6), 1..120)
        ) {
            let cfg = TcpfConfig::default();
            let mut f = Tcpf::new(cfg.clone(), None).unwrap();
            let mut t = 0;
            for (is_step, len, heading, x, y) in inputs {
                t += 200;
                if is_step {
                    f.on_step(&step(t, len, heading));
                } else {
                    let before = f.state();
                    let lambda_before = f.lambda();
                    let initialised = f.estimate().is_some();
                    f.on_wifi(&obs_at(t, x, y));
                    if initialised {
                        let d = f.estimate().unwrap().diagnostics;
                        let trusted = !d.wifi_flagged.unwrap();
                        prop_assert_eq!(f.state(), next_state(before, trusted, lambda_before, cfg.epsilon));
                        if trusted { prop_assert_eq!(f.lambda(), 0.0); }
                    }
                }
                prop_assert!(f.lambda().is_finite() && f.lambda() >= 0.0);
                prop_assert!(f.lambda() <= cfg.lambda_max);
                if let Some(e) = f.estimate() {
                    prop_assert!(e.position.x.is_finite() && e.position.y.is_finite());
                }
            }
        }
    }
}
