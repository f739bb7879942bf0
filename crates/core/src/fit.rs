//! Bounded Levenberg-Marquardt for small nonlinear least-squares problems (`N` parameters,
//! any number of residuals), shared by the path-loss fit of the radio-map extension and the
//! refresh-rate model fit of the Wi-Fi statistics.
//!
//! The problem is a closure that, at parameters `t`, reports every residual
//! `r_i = y_i - f_i(t)` with its Jacobian row `d f_i / d t` (the model's derivatives, so the
//! Gauss-Newton step is `+(JᵀJ)⁻¹ Jᵀr`). Each iteration solves the damped normal equations
//! `(JᵀJ + λ diag(JᵀJ + 1e-9)) δ = Jᵀr` (Marquardt's scaling) and projects `t + δ` onto the
//! bounds; a trial that lowers the cost `Σ r_i²` is taken and `λ` divided by 3, else `λ` is
//! multiplied by 10 (at most [`LmConfig::max_damping_tries`] trials per iteration). It stops
//! when the cost falls by at most [`LmConfig::cost_tolerance`] `· (1 + cost)`, when the
//! gradient `|Jᵀr|` is at most [`LmConfig::gradient_tolerance`] `· (1 + cost)`, or when no
//! trial lowers the cost (all three: converged), or after [`LmConfig::max_iterations`].
//!
//! ```
//! use wipdr_core::fit::{BoxBounds, LmConfig, levenberg_marquardt};
//! // Fit y = a exp(b x) to exact data; a in [0, 10], b in [-1, 1].
//! let xs = [0.0, 0.5, 1.0, 1.5, 2.0];
//! let ys: Vec<f64> = xs.iter().map(|x: &f64| 2.0 * (0.3 * x).exp()).collect();
//! let bounds = BoxBounds { lo: [0.0, -1.0], hi: [10.0, 1.0] };
//! let out = levenberg_marquardt(
//!     [1.0, 0.0],
//!     |t| bounds.project(t),
//!     &LmConfig::default(),
//!     |t: &[f64; 2], visit: &mut dyn FnMut(f64, &[f64; 2])| {
//!         for (x, y) in xs.iter().zip(&ys) {
//!             let e = (t[1] * x).exp();
//!             visit(y - t[0] * e, &[e, t[0] * x * e]);
//!         }
//!     },
//! );
//! assert!(out.converged);
//! assert!((out.params[0] - 2.0).abs() < 1e-6 && (out.params[1] - 0.3).abs() < 1e-6);
//! ```

use serde::{Deserialize, Serialize};

/// Settings of [`levenberg_marquardt`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct LmConfig {
    /// Most iterations (normal-equation builds).
    pub max_iterations: usize,
    /// Converged when an accepted step lowers the cost by at most this times `1 + cost`.
    pub cost_tolerance: f64,
    /// Converged when `|Jᵀr|` is at most this times `1 + cost` (0: only an exactly zero
    /// gradient).
    pub gradient_tolerance: f64,
    /// Trials (damping increases) per iteration before giving up on a downhill step.
    pub max_damping_tries: usize,
    /// Initial damping `λ`.
    pub initial_lambda: f64,
}

impl Default for LmConfig {
    fn default() -> Self {
        Self {
            max_iterations: 100,
            cost_tolerance: 1e-10,
            gradient_tolerance: 0.0,
            max_damping_tries: 12,
            initial_lambda: 1e-3,
        }
    }
}

/// The result of [`levenberg_marquardt`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LmOutcome<const N: usize> {
    /// Final parameters (within the bounds when the start and the projection are).
    pub params: [f64; N],
    /// Final cost `Σ r_i²`.
    pub cost: f64,
    /// Iterations run.
    pub iterations: usize,
    /// Whether a stopping rule other than the iteration limit ended the run.
    pub converged: bool,
}

/// A box `lo <= t <= hi`, per parameter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BoxBounds<const N: usize> {
    /// Lower bounds.
    pub lo: [f64; N],
    /// Upper bounds.
    pub hi: [f64; N],
}

impl<const N: usize> BoxBounds<N> {
    /// `t` clamped into the box.
    pub fn project(&self, mut t: [f64; N]) -> [f64; N] {
        for ((v, lo), hi) in t.iter_mut().zip(self.lo).zip(self.hi) {
            *v = v.clamp(lo, hi);
        }
        t
    }
}

fn cost_of<const N: usize>(
    residuals: &impl Fn(&[f64; N], &mut dyn FnMut(f64, &[f64; N])),
    t: &[f64; N],
) -> f64 {
    let mut c = 0.0;
    residuals(t, &mut |r, _| c += r * r);
    c
}

/// Minimises `Σ r_i(t)²` from `t0` (see the module doc). `project` maps a trial point onto
/// the feasible set (e.g. [`BoxBounds::project`]); `residuals(t, visit)` calls
/// `visit(r_i, &J_i)` once per residual. Non-finite trial costs are rejected, so a finite
/// start gives a finite result.
pub fn levenberg_marquardt<const N: usize>(
    t0: [f64; N],
    project: impl Fn([f64; N]) -> [f64; N],
    cfg: &LmConfig,
    residuals: impl Fn(&[f64; N], &mut dyn FnMut(f64, &[f64; N])),
) -> LmOutcome<N> {
    let mut t = t0;
    let mut c = cost_of(&residuals, &t);
    let mut lambda = cfg.initial_lambda;
    let mut iterations = 0;
    while iterations < cfg.max_iterations {
        iterations += 1;
        let mut a = [[0.0; N]; N];
        let mut g = [0.0; N];
        residuals(&t, &mut |r, j| {
            for u in 0..N {
                g[u] += j[u] * r;
                for v in 0..N {
                    a[u][v] += j[u] * j[v];
                }
            }
        });
        let grad = g.iter().map(|v| v * v).sum::<f64>().sqrt();
        if grad <= cfg.gradient_tolerance * (1.0 + c) {
            return LmOutcome {
                params: t,
                cost: c,
                iterations,
                converged: true,
            };
        }
        let mut accepted = false;
        for _ in 0..cfg.max_damping_tries {
            let mut m = a;
            for (k, row) in m.iter_mut().enumerate() {
                row[k] += lambda * (a[k][k] + 1e-9);
            }
            let Some(step) = solve(m, g) else {
                lambda *= 10.0;
                continue;
            };
            let mut trial = t;
            for (v, s) in trial.iter_mut().zip(step) {
                *v += s;
            }
            let cand = project(trial);
            let cc = cost_of(&residuals, &cand);
            if cc.is_finite() && cc < c {
                let gain = c - cc;
                t = cand;
                c = cc;
                lambda = (lambda / 3.0).max(1e-12);
                accepted = true;
                if gain <= cfg.cost_tolerance * (1.0 + c) {
                    return LmOutcome {
                        params: t,
                        cost: c,
                        iterations,
                        converged: true,
                    };
                }
                break;
            }
            lambda *= 10.0;
        }
        if !accepted {
            // No downhill step at any damping tried: a minimum to the precision reached.
            return LmOutcome {
                params: t,
                cost: c,
                iterations,
                converged: true,
            };
        }
    }
    LmOutcome {
        params: t,
        cost: c,
        iterations,
        converged: false,
    }
}

/// Solves `a x = g` by Gaussian elimination with partial pivoting; `None` when (nearly)
/// singular relative to the largest entry, or not finite.
pub fn solve<const N: usize>(mut a: [[f64; N]; N], mut g: [f64; N]) -> Option<[f64; N]> {
    let scale = a
        .iter()
        .flat_map(|r| r.iter())
        .fold(0f64, |m, v| m.max(v.abs()));
    if !(scale.is_finite() && scale > 0.0) {
        return None;
    }
    for c in 0..N {
        let pivot = (c..N).max_by(|&i, &j| a[i][c].abs().total_cmp(&a[j][c].abs()))?;
        if a[pivot][c].abs() <= 1e-13 * scale {
            return None;
        }
        a.swap(c, pivot);
        g.swap(c, pivot);
        for r in c + 1..N {
            let f = a[r][c] / a[c][c];
            let pivot_row = a[c];
            for (v, p) in a[r].iter_mut().zip(pivot_row).skip(c) {
                *v -= f * p;
            }
            g[r] -= f * g[c];
        }
    }
    let mut x = [0.0; N];
    for c in (0..N).rev() {
        let s: f64 = (c + 1..N).map(|k| a[c][k] * x[k]).sum();
        x[c] = (g[c] - s) / a[c][c];
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn solve_matches_a_known_system_and_rejects_singular() {
        let a = [[4.0, 1.0, 0.0], [1.0, 3.0, 1.0], [0.0, 1.0, 2.0]];
        let x = solve(a, [1.0, 2.0, 3.0]).unwrap();
        for (row, b) in a.iter().zip([1.0, 2.0, 3.0]) {
            let lhs: f64 = row.iter().zip(x).map(|(a, x)| a * x).sum();
            assert!((lhs - b).abs() < 1e-12);
        }
        assert_eq!(solve([[1.0, 2.0], [2.0, 4.0]], [1.0, 1.0]), None);
        assert_eq!(solve([[0.0, 0.0], [0.0, 0.0]], [1.0, 1.0]), None);
        assert_eq!(solve([[f64::NAN, 0.0], [0.0, 1.0]], [1.0, 1.0]), None);
    }

    #[test]
    fn bounds_hold_and_the_constrained_minimum_is_found() {
        // Minimum of (t - 5)^2 at 5, but t <= 2: ends on the bound.
        let b = BoxBounds {
            lo: [-1.0],
            hi: [2.0],
        };
        let out = levenberg_marquardt(
            [0.0],
            |t| b.project(t),
            &LmConfig::default(),
            |t: &[f64; 1], visit: &mut dyn FnMut(f64, &[f64; 1])| visit(5.0 - t[0], &[1.0]),
        );
        assert!(out.converged);
        assert_eq!(out.params, [2.0]);
        assert_eq!(out.cost, 9.0);
    }

    #[test]
    fn iteration_limit_is_reported() {
        let cfg = LmConfig {
            max_iterations: 1,
            cost_tolerance: 0.0,
            ..LmConfig::default()
        };
        let out = levenberg_marquardt(
            [0.0, 0.0],
            |t| t,
            &cfg,
            |t: &[f64; 2], visit: &mut dyn FnMut(f64, &[f64; 2])| {
                // Rosenbrock as residuals: 10 (y - x^2), 1 - x.
                visit(-10.0 * (t[1] - t[0] * t[0]), &[-20.0 * t[0], 10.0]);
                visit(1.0 - t[0], &[1.0, 0.0]);
            },
        );
        assert_eq!(out.iterations, 1);
        assert!(!out.converged);
        assert!(out.cost < 1.0);
    }
}
