//! Signal-space distances and data representations.
//!
//! Distances are unit structs (or small parameter structs) behind one [`Distance`] trait, in
//! the style of geo's metric spaces; [`Metric`] names them for configs and tools. Each works on
//! fingerprints already mapped into a [`Representation`] (Torres-Sospedra et al. 2015):
//!
//! - `raw`: dBm with "not heard" = the map's fill value (default -110 dBm), stored shifted so
//!   that "not heard" is 0 (Minkowski distances are translation invariant, so this is exactly
//!   scikit-learn's Euclidean on `-110`-filled vectors);
//! - `positive`: `v - null` with `null = min RSS - 1` (the weakest heard RSS of the map minus
//!   1 dB); not heard = 0;
//! - `exponential`: `exp(positive / alpha) / exp(-null / alpha)`, `alpha = 24`;
//! - `powed`: `positive^beta / (-null)^beta`, `beta = e`; not heard = 0.
//!
//! Query values weaker than `null` clamp to `null` (not heard) in the non-raw representations.

use serde::{Deserialize, Serialize};

/// A distance between a query and a reference fingerprint in representation space.
///
/// `null` is the representation value of "not heard" (0 except for `exponential`); distances
/// that treat heard and not-heard APs differently (PLGD, shared-AP) use it.
pub trait Distance: Copy + Send + Sync {
    /// Distance between `query` and `reference` (same length).
    fn eval(&self, query: &[f32], reference: &[f32], null: f32) -> f32;
}

/// Manhattan (Minkowski q = 1): `sum |a - b|`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Manhattan;
/// Euclidean (Minkowski q = 2): `sqrt(sum (a - b)^2)` (paper 000 eq. 3, paper 002 eq. 1).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Euclidean;
/// Squared Euclidean: `sum (a - b)^2`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SquaredEuclidean;
/// Sørensen (Bray-Curtis): `sum |a - b| / sum (a + b)`; 0 when both sums are 0.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Sorensen;
/// Neyman chi-square: `sum (a - b)^2 / a` with `a` the reference value, floored at
/// [`NEYMAN_FLOOR`] (so an AP the reference did not hear but the query did is a large term).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Neyman;

/// Smallest denominator of [`Neyman`].
pub const NEYMAN_FLOOR: f32 = 1e-3;

/// Neyman's chi-square as the reference code of Montoliu, Pérez-Navarro, Torres-Sospedra
/// (2022, `distances.py`) computes it: `sum (q - r)^2 / q` over the APs the *query* heard
/// (query value above the null), normalised by the query's value. (Our [`Neyman`] divides by
/// the reference value over every AP.)
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct NeymanQuery;

/// Penalised log-Gaussian distance (after Torres-Sospedra et al. 2015): for an AP heard by
/// both, `min((a - b)^2 / (2 sigma^2), -ln eps)` (the negative log of a Gaussian likelihood,
/// floored at `eps`); for an AP heard by one side only, `-ln eps + alpha * v` with `v` its
/// value above `null` (the penalty term); nothing for an AP heard by neither.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Plgd {
    /// Gaussian width, representation units (5 for dB-like representations).
    pub sigma: f32,
    /// Likelihood floor.
    pub epsilon: f32,
    /// Penalty per unit of an unmatched AP's value.
    pub alpha: f32,
}

impl Default for Plgd {
    fn default() -> Self {
        Self {
            sigma: 5.0,
            epsilon: 1e-3,
            alpha: 0.1,
        }
    }
}

/// Shared-AP distance (docs/experiments.md): mean `|a - b|` over the APs both heard, plus
/// `lambda * (heard by one only) / (heard by either)`. With no shared AP the mean term is
/// [`SHARED_AP_NONE`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SharedAp {
    /// Weight of the non-shared fraction (docs/experiments.md: 40-80).
    pub lambda: f32,
    /// Largest common RSSI offset (dB) removed before the mean difference is taken: the
    /// mean of `a - b` over the shared APs, clamped to `[-max_offset_db, max_offset_db]`, is
    /// subtracted from every difference (a phone's gain differs from the survey phones';
    /// wipdr's own, measured in `docs/experiments.md`, common RSSI offset). 0 (default): off.
    #[serde(default)]
    pub max_offset_db: f32,
    /// Detection weighting of the non-shared fraction (wipdr's own; 0, the default: off).
    /// When > 0, each AP heard by one side only counts `P(heard | v) = 1 / (1 + exp(-(v -
    /// null - detection_mid_db) / DETECTION_WIDTH_DB))` of one, and the union is weighed
    /// alike, so a weak AP the other side missed costs less than a strong one: in the raw
    /// representation with not heard = -110 dBm, 25 puts the midpoint at -85 dBm.
    #[serde(default)]
    pub detection_mid_db: f32,
}

/// Width of [`SharedAp::detection_mid_db`]'s logistic, dB.
pub const DETECTION_WIDTH_DB: f32 = 4.0;

/// Shared APs below which [`SharedAp::max_offset_db`] removes no offset (a mean difference over
/// fewer is mostly the position's, not the phone's).
pub const SHARED_AP_MIN_FOR_OFFSET: u32 = 6;

/// Mean-difference term of [`SharedAp`] when nothing is shared, dB.
pub const SHARED_AP_NONE: f32 = 100.0;

impl Default for SharedAp {
    fn default() -> Self {
        Self {
            lambda: 60.0,
            max_offset_db: 0.0,
            detection_mid_db: 0.0,
        }
    }
}

const LANES: usize = 8;

#[inline]
fn lanes_sum(acc: [f32; LANES]) -> f32 {
    acc.iter().sum()
}

impl Distance for Manhattan {
    #[inline]
    fn eval(&self, a: &[f32], b: &[f32], _null: f32) -> f32 {
        let mut acc = [0f32; LANES];
        let (ca, cb) = (a.chunks_exact(LANES), b.chunks_exact(LANES));
        let tail: f32 = ca
            .remainder()
            .iter()
            .zip(cb.remainder())
            .map(|(x, y)| (x - y).abs())
            .sum();
        for (x, y) in ca.zip(cb) {
            for l in 0..LANES {
                acc[l] += (x[l] - y[l]).abs();
            }
        }
        lanes_sum(acc) + tail
    }
}

impl Distance for SquaredEuclidean {
    #[inline]
    fn eval(&self, a: &[f32], b: &[f32], _null: f32) -> f32 {
        let mut acc = [0f32; LANES];
        let (ca, cb) = (a.chunks_exact(LANES), b.chunks_exact(LANES));
        let tail: f32 = ca
            .remainder()
            .iter()
            .zip(cb.remainder())
            .map(|(x, y)| (x - y) * (x - y))
            .sum();
        for (x, y) in ca.zip(cb) {
            for l in 0..LANES {
                let d = x[l] - y[l];
                acc[l] += d * d;
            }
        }
        lanes_sum(acc) + tail
    }
}

impl Distance for Euclidean {
    #[inline]
    fn eval(&self, a: &[f32], b: &[f32], null: f32) -> f32 {
        SquaredEuclidean.eval(a, b, null).sqrt()
    }
}

impl Distance for Sorensen {
    fn eval(&self, a: &[f32], b: &[f32], _null: f32) -> f32 {
        let (mut num, mut den) = ([0f32; LANES], [0f32; LANES]);
        let (ca, cb) = (a.chunks_exact(LANES), b.chunks_exact(LANES));
        let (mut tn, mut td) = (0f32, 0f32);
        for (x, y) in ca.remainder().iter().zip(cb.remainder()) {
            tn += (x - y).abs();
            td += x + y;
        }
        for (x, y) in ca.zip(cb) {
            for l in 0..LANES {
                num[l] += (x[l] - y[l]).abs();
                den[l] += x[l] + y[l];
            }
        }
        let (num, den) = (lanes_sum(num) + tn, lanes_sum(den) + td);
        if den > 0.0 { num / den } else { 0.0 }
    }
}

impl Distance for Neyman {
    fn eval(&self, a: &[f32], b: &[f32], _null: f32) -> f32 {
        let term = |q: f32, r: f32| (q - r) * (q - r) / r.max(NEYMAN_FLOOR);
        let mut acc = [0f32; LANES];
        let (ca, cb) = (a.chunks_exact(LANES), b.chunks_exact(LANES));
        let tail: f32 = ca
            .remainder()
            .iter()
            .zip(cb.remainder())
            .map(|(&q, &r)| term(q, r))
            .sum();
        for (x, y) in ca.zip(cb) {
            for l in 0..LANES {
                acc[l] += term(x[l], y[l]);
            }
        }
        lanes_sum(acc) + tail
    }
}

impl Distance for NeymanQuery {
    fn eval(&self, a: &[f32], b: &[f32], null: f32) -> f32 {
        a.iter()
            .zip(b)
            .filter(|&(&q, _)| q > null && q > 0.0)
            .map(|(&q, &r)| (q - r) * (q - r) / q)
            .sum()
    }
}

impl Distance for Plgd {
    fn eval(&self, a: &[f32], b: &[f32], null: f32) -> f32 {
        let cap = -self.epsilon.ln();
        let two_s2 = 2.0 * self.sigma * self.sigma;
        let mut d = 0f32;
        for (&q, &r) in a.iter().zip(b) {
            match (q > null, r > null) {
                (true, true) => d += ((q - r) * (q - r) / two_s2).min(cap),
                (true, false) => d += cap + self.alpha * (q - null),
                (false, true) => d += cap + self.alpha * (r - null),
                (false, false) => {}
            }
        }
        d
    }
}

impl Distance for SharedAp {
    fn eval(&self, a: &[f32], b: &[f32], null: f32) -> f32 {
        let offset = if self.max_offset_db > 0.0 {
            let (mut diff, mut n) = (0f32, 0u32);
            for (&q, &r) in a.iter().zip(b) {
                if q > null && r > null {
                    diff += q - r;
                    n += 1;
                }
            }
            if n >= SHARED_AP_MIN_FOR_OFFSET {
                (diff / n as f32).clamp(-self.max_offset_db, self.max_offset_db)
            } else {
                0.0
            }
        } else {
            0.0
        };
        // An AP heard by one side only counts P(heard | its value) of one (1 without the
        // detection weighting, the plain non-shared fraction); the union alike.
        let heard = |v: f32| self.one_sided_weight(v, null);
        let (mut sum, mut shared, mut union_w, mut alone_w) = (0f32, 0u32, 0f32, 0f32);
        for (&q, &r) in a.iter().zip(b) {
            let alone = match (q > null, r > null) {
                (true, true) => {
                    sum += (q - r - offset).abs();
                    shared += 1;
                    union_w += 1.0;
                    continue;
                }
                (true, false) => heard(q),
                (false, true) => heard(r),
                (false, false) => continue,
            };
            alone_w += alone;
            union_w += alone;
        }
        self.combine(sum, shared, alone_w, union_w)
    }
}

impl SharedAp {
    /// The distance from its sums: the mean difference over the `shared` APs (their
    /// differences summing to `sum`; [`SHARED_AP_NONE`] without any) plus `lambda` times the
    /// non-shared weight `alone_w` over the union's `union_w` (0 for an empty union).
    #[inline]
    fn combine(&self, sum: f32, shared: u32, alone_w: f32, union_w: f32) -> f32 {
        if union_w <= 0.0 {
            return 0.0;
        }
        let mean = if shared > 0 {
            sum / shared as f32
        } else {
            SHARED_AP_NONE
        };
        mean + self.lambda * alone_w / union_w
    }

    /// What an AP heard by one side only (at value `v`, in the representation whose "not
    /// heard" is `null`) counts in the non-shared fraction: `P(heard | v)` with the
    /// detection weighting ([`Self::detection_mid_db`] > 0), else 1.
    #[inline]
    pub fn one_sided_weight(&self, v: f32, null: f32) -> f32 {
        if self.detection_mid_db > 0.0 {
            1.0 / (1.0 + (-(v - null - self.detection_mid_db) / DETECTION_WIDTH_DB).exp())
        } else {
            1.0
        }
    }

    /// [`SharedAp::eval`] of two sparse fingerprints whose "not heard" is 0: the same
    /// terms added in the same order (by AP column), so the result is bit-identical to the
    /// dense evaluation, at the cost of the two heard lists instead of every AP of the map.
    /// `a` is the query (the side whose offset is removed), `b` the reference; each side's
    /// `weights` hold [`Self::one_sided_weight`] of its values (null 0).
    ///
    /// ```
    /// use wipdr_fingerprint::distance::{Distance, SharedAp, SparseFingerprint};
    /// let d = SharedAp { detection_mid_db: 20.0, ..SharedAp::default() };
    /// let (q, r) = ([30.0f32, 0.0, 12.0, 0.0], [25.0f32, 40.0, 0.0, 0.0]);
    /// let side = |v: &[f32]| {
    ///     let cols: Vec<u32> = (0..v.len() as u32).filter(|&j| v[j as usize] > 0.0).collect();
    ///     let vals: Vec<f32> = cols.iter().map(|&j| v[j as usize]).collect();
    ///     let w: Vec<f32> = vals.iter().map(|&x| d.one_sided_weight(x, 0.0)).collect();
    ///     (cols, vals, w)
    /// };
    /// let ((qc, qv, qw), (rc, rv, rw)) = (side(&q), side(&r));
    /// let sparse = d.eval_sparse(
    ///     SparseFingerprint { columns: &qc, values: &qv, weights: &qw },
    ///     SparseFingerprint { columns: &rc, values: &rv, weights: &rw },
    /// );
    /// assert_eq!(sparse.to_bits(), d.eval(&q, &r, 0.0).to_bits());
    /// ```
    pub fn eval_sparse(&self, a: SparseFingerprint<'_>, b: SparseFingerprint<'_>) -> f32 {
        let offset = if self.max_offset_db > 0.0 {
            let (mut diff, mut n) = (0f32, 0u32);
            for_each_shared(a.columns, b.columns, |i, k| {
                diff += a.values[i] - b.values[k];
                n += 1;
            });
            if n >= SHARED_AP_MIN_FOR_OFFSET {
                (diff / n as f32).clamp(-self.max_offset_db, self.max_offset_db)
            } else {
                0.0
            }
        } else {
            0.0
        };
        // The merge written out (this loop is the matcher's whole cost): in column order,
        // a shared AP adds its difference and 1 to the union, an AP of one side its weight
        // to the non-shared part and the union, as the dense loop does.
        let (mut sum, mut shared, mut union_w, mut alone_w) = (0f32, 0u32, 0f32, 0f32);
        let (ac, av, aw) = (a.columns, a.values, a.weights);
        let (bc, bv, bw) = (b.columns, b.values, b.weights);
        let (mut i, mut k) = (0, 0);
        while i < ac.len() && k < bc.len() {
            let (ja, jb) = (ac[i], bc[k]);
            if ja == jb {
                sum += (av[i] - bv[k] - offset).abs();
                shared += 1;
                union_w += 1.0;
                i += 1;
                k += 1;
            } else if ja < jb {
                alone_w += aw[i];
                union_w += aw[i];
                i += 1;
            } else {
                alone_w += bw[k];
                union_w += bw[k];
                k += 1;
            }
        }
        for &w in &aw[i.min(aw.len())..] {
            alone_w += w;
            union_w += w;
        }
        for &w in &bw[k.min(bw.len())..] {
            alone_w += w;
            union_w += w;
        }
        self.combine(sum, shared, alone_w, union_w)
    }
}

/// One side of [`SharedAp::eval_sparse`]: the heard APs' columns (strictly increasing),
/// their values (> 0) and one-sided weights, aligned.
#[derive(Debug, Clone, Copy)]
pub struct SparseFingerprint<'a> {
    /// AP columns, strictly increasing.
    pub columns: &'a [u32],
    /// Values in the representation, > 0 (heard).
    pub values: &'a [f32],
    /// [`SharedAp::one_sided_weight`] of each value.
    pub weights: &'a [f32],
}

/// Calls `visit(i, k)` for each column in both strictly increasing lists (`a[i] == b[k]`),
/// in increasing order.
#[inline]
fn for_each_shared(a: &[u32], b: &[u32], mut visit: impl FnMut(usize, usize)) {
    let (mut i, mut k) = (0, 0);
    while i < a.len() && k < b.len() {
        match a[i].cmp(&b[k]) {
            std::cmp::Ordering::Equal => {
                visit(i, k);
                i += 1;
                k += 1;
            }
            std::cmp::Ordering::Less => i += 1,
            std::cmp::Ordering::Greater => k += 1,
        }
    }
}

/// A distance by name, for configs and tools.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Metric {
    /// [`Manhattan`].
    Manhattan,
    /// [`Euclidean`].
    #[default]
    Euclidean,
    /// [`SquaredEuclidean`].
    SquaredEuclidean,
    /// [`Sorensen`].
    Sorensen,
    /// [`Neyman`].
    Neyman,
    /// [`NeymanQuery`].
    NeymanQuery,
    /// [`Plgd`].
    Plgd(Plgd),
    /// [`SharedAp`].
    SharedAp(SharedAp),
}

impl Metric {
    /// Short name (`manhattan`, `euclidean`, `sqeuclidean`, `sorensen`, `neyman`,
    /// `neyman_query`, `plgd`, `shared_ap`).
    pub fn name(&self) -> &'static str {
        match self {
            Metric::Manhattan => "manhattan",
            Metric::Euclidean => "euclidean",
            Metric::SquaredEuclidean => "sqeuclidean",
            Metric::Sorensen => "sorensen",
            Metric::Neyman => "neyman",
            Metric::NeymanQuery => "neyman_query",
            Metric::Plgd(_) => "plgd",
            Metric::SharedAp(_) => "shared_ap",
        }
    }

    /// Parses a short name (defaults for parameters).
    pub fn parse(s: &str) -> Option<Self> {
        Some(match s {
            "manhattan" | "l1" => Metric::Manhattan,
            "euclidean" | "l2" => Metric::Euclidean,
            "sqeuclidean" => Metric::SquaredEuclidean,
            "sorensen" => Metric::Sorensen,
            "neyman" => Metric::Neyman,
            "neyman_query" => Metric::NeymanQuery,
            "plgd" => Metric::Plgd(Plgd::default()),
            "shared_ap" => Metric::SharedAp(SharedAp::default()),
            _ => return None,
        })
    }

    /// Evaluates the distance.
    pub fn eval(&self, a: &[f32], b: &[f32], null: f32) -> f32 {
        match self {
            Metric::Manhattan => Manhattan.eval(a, b, null),
            Metric::Euclidean => Euclidean.eval(a, b, null),
            Metric::SquaredEuclidean => SquaredEuclidean.eval(a, b, null),
            Metric::Sorensen => Sorensen.eval(a, b, null),
            Metric::Neyman => Neyman.eval(a, b, null),
            Metric::NeymanQuery => NeymanQuery.eval(a, b, null),
            Metric::Plgd(d) => d.eval(a, b, null),
            Metric::SharedAp(d) => d.eval(a, b, null),
        }
    }
}

/// How RSS values are represented before distances are taken (Torres-Sospedra et al. 2015).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Representation {
    /// dBm, not heard = the map's fill value (shifted so that not heard = 0).
    #[default]
    Raw,
    /// `v - null`, `null = min RSS - 1`.
    Positive,
    /// `exp(positive / alpha) / exp(-null / alpha)`.
    Exponential {
        /// Scale, dB (24).
        alpha: f32,
    },
    /// `positive^beta / (-null)^beta`.
    Powed {
        /// Exponent (e).
        beta: f32,
    },
    /// [`Representation::Exponential`] for heard values, exactly 0 for "not heard", as the
    /// reference code of Montoliu, Pérez-Navarro, Torres-Sospedra (2022,
    /// `data_representation.py`) computes it (the formula alone maps "not heard" to
    /// `1 / exp(-null / alpha)`).
    ExponentialNullZero {
        /// Scale, dB (24).
        alpha: f32,
    },
}

impl Representation {
    /// Short name (`raw`, `positive`, `exponential`, `powed`, `exponential_null0`).
    pub fn name(&self) -> &'static str {
        match self {
            Representation::Raw => "raw",
            Representation::Positive => "positive",
            Representation::Exponential { .. } => "exponential",
            Representation::Powed { .. } => "powed",
            Representation::ExponentialNullZero { .. } => "exponential_null0",
        }
    }

    /// Parses a short name with the literature's parameters (`alpha = 24`, `beta = e`).
    pub fn parse(s: &str) -> Option<Self> {
        Some(match s {
            "raw" => Representation::Raw,
            "positive" => Representation::Positive,
            "exponential" => Representation::Exponential { alpha: 24.0 },
            "powed" => Representation::Powed {
                beta: std::f32::consts::E,
            },
            "exponential_null0" => Representation::ExponentialNullZero { alpha: 24.0 },
            _ => return None,
        })
    }
}

/// A representation bound to a map: the reference levels it needs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Transform {
    /// The representation.
    pub representation: Representation,
    /// dBm that maps to "not heard": the fill value for `raw`, `min RSS - 1` otherwise.
    pub null_dbm: f32,
}

impl Transform {
    /// Binds `representation` to a map's fill value and weakest heard RSS.
    pub fn new(representation: Representation, fill_dbm: f32, min_heard_dbm: Option<f32>) -> Self {
        let null_dbm = match representation {
            Representation::Raw => fill_dbm,
            _ => min_heard_dbm.unwrap_or(fill_dbm + 1.0) - 1.0,
        };
        Self {
            representation,
            null_dbm,
        }
    }

    /// The representation value of "not heard".
    pub fn null_value(&self) -> f32 {
        self.apply(None)
    }

    /// Maps a heard value (dBm) or "not heard" (`None`) into the representation.
    pub fn apply(&self, v: Option<f32>) -> f32 {
        let null = self.null_dbm;
        match self.representation {
            Representation::Raw => v.map_or(0.0, |v| v - null),
            Representation::Positive => v.map_or(0.0, |v| (v - null).max(0.0)),
            Representation::Exponential { alpha } => {
                let pos = v.map_or(0.0, |v| (v - null).max(0.0));
                (pos / alpha).exp() / (-null / alpha).exp()
            }
            Representation::Powed { beta } => {
                let pos = v.map_or(0.0, |v| (v - null).max(0.0));
                let scale = (-null).max(1.0);
                (pos / scale).powf(beta)
            }
            Representation::ExponentialNullZero { alpha } => match v {
                None => 0.0,
                Some(v) => ((v - null).max(0.0) / alpha).exp() / (-null / alpha).exp(),
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reference_code_variants() {
        // Neyman over the query's APs, divided by the query's value.
        let q = [2.0, 0.0, 4.0];
        let r = [1.0, 5.0, 0.0];
        assert_eq!(NeymanQuery.eval(&q, &r, 0.0), 1.0 / 2.0 + 16.0 / 4.0);
        assert_eq!(Metric::parse("neyman_query"), Some(Metric::NeymanQuery));
        // Exponential with not heard = 0; heard as the exponential formula.
        let rep = Representation::parse("exponential_null0").unwrap();
        let t = Transform::new(rep, -110.0, Some(-101.0));
        assert_eq!(t.null_value(), 0.0);
        let e = Transform::new(
            Representation::parse("exponential").unwrap(),
            -110.0,
            Some(-101.0),
        );
        assert_eq!(t.apply(Some(-60.0)), e.apply(Some(-60.0)));
        assert!(e.null_value() > 0.0);
        assert_eq!(rep.name(), "exponential_null0");
    }

    #[test]
    fn basic_values() {
        let a = [1.0, 0.0, 3.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 2.0];
        let b = [0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 4.0];
        assert_eq!(Manhattan.eval(&a, &b, 0.0), 5.0);
        assert_eq!(SquaredEuclidean.eval(&a, &b, 0.0), 9.0);
        assert_eq!(Euclidean.eval(&a, &b, 0.0), 3.0);
        assert_eq!(Sorensen.eval(&a, &b, 0.0), 5.0 / 11.0);
        assert_eq!(Sorensen.eval(&[0.0], &[0.0], 0.0), 0.0);
        assert!(Neyman.eval(&a, &b, 0.0) > 1000.0); // AP 0 unheard by the reference
        let s = SharedAp {
            lambda: 10.0,
            ..SharedAp::default()
        }
        .eval(&a, &b, 0.0);
        assert!((s - (2.0 + 10.0 / 3.0)).abs() < 1e-6, "{s}");
        assert_eq!(
            SharedAp {
                lambda: 10.0,
                ..SharedAp::default()
            }
            .eval(&[1.0, 0.0], &[0.0, 1.0], 0.0),
            SHARED_AP_NONE + 10.0
        );
        let p = Plgd::default();
        assert_eq!(p.eval(&a, &a, 0.0), 0.0);
        assert!(p.eval(&a, &b, 0.0) > p.eval(&a, &a, 0.0));
    }

    #[test]
    fn the_shared_ap_offset_removes_a_phones_gain_only_with_enough_shared_aps() {
        let reference = [30.0, 25.0, 20.0, 15.0, 10.0, 5.0, 0.0];
        let louder: Vec<f32> = reference
            .iter()
            .map(|&v| if v > 0.0 { v + 8.0 } else { 0.0 })
            .collect();
        let plain = SharedAp::default();
        let offset = SharedAp {
            max_offset_db: 10.0,
            ..SharedAp::default()
        };
        assert!((plain.eval(&louder, &reference, 0.0) - 8.0).abs() < 1e-5);
        assert!(offset.eval(&louder, &reference, 0.0).abs() < 1e-5);
        // clamped: a 15 dB gain leaves 5 dB
        let much: Vec<f32> = reference
            .iter()
            .map(|&v| if v > 0.0 { v + 15.0 } else { 0.0 })
            .collect();
        assert!((offset.eval(&much, &reference, 0.0) - 5.0).abs() < 1e-5);
        // fewer shared APs than SHARED_AP_MIN_FOR_OFFSET: no offset removed
        let few_ref = [30.0, 25.0, 20.0, 0.0, 0.0, 0.0, 0.0];
        let few: Vec<f32> = few_ref
            .iter()
            .map(|&v| if v > 0.0 { v + 8.0 } else { 0.0 })
            .collect();
        assert!((offset.eval(&few, &few_ref, 0.0) - 8.0).abs() < 1e-5);
    }

    #[test]
    fn the_detection_weighting_charges_a_missed_weak_ap_less_than_a_missed_strong_one() {
        // raw representation, not heard = 0; 25 = -85 dBm when not heard is -110 dBm
        let detect = SharedAp {
            detection_mid_db: 25.0,
            ..SharedAp::default()
        };
        let scan = [50.0, 40.0, 0.0];
        let weak_missing = [50.0, 40.0, 20.0]; // the reference also hears an AP at -90 dBm
        let strong_missing = [50.0, 40.0, 50.0]; // ... or at -60 dBm
        let (weak, strong) = (
            detect.eval(&scan, &weak_missing, 0.0),
            detect.eval(&scan, &strong_missing, 0.0),
        );
        assert!(weak < strong, "{weak} {strong}");
        // each missing AP counts P(heard) = 1 / (1 + e^(-(v - 25) / 4)), over a union of
        // 2 + that: a strong one almost one (the plain distance, 20), a weak one far less
        let fraction = |v: f32| {
            let w = 1.0 / (1.0 + (-(v - 25.0) / DETECTION_WIDTH_DB).exp());
            60.0 * w / (2.0 + w)
        };
        assert!((strong - fraction(50.0)).abs() < 1e-4, "{strong}");
        assert!((weak - fraction(20.0)).abs() < 1e-4, "{weak}");
        let plain = SharedAp::default().eval(&scan, &strong_missing, 0.0);
        assert!(
            (plain - 20.0).abs() < 1e-5 && strong > 19.9 && weak < 10.0,
            "{plain}"
        );
        // nothing heard on either side: 0, as the plain distance
        assert_eq!(detect.eval(&[0.0, 0.0], &[0.0, 0.0], 0.0), 0.0);
    }

    #[test]
    fn representations() {
        let t = Transform::new(Representation::Raw, -110.0, Some(-100.0));
        assert_eq!(t.apply(Some(-60.0)), 50.0);
        assert_eq!(t.null_value(), 0.0);
        let t = Transform::new(Representation::Positive, -110.0, Some(-100.0));
        assert_eq!(t.null_dbm, -101.0);
        assert_eq!(t.apply(Some(-100.0)), 1.0);
        assert_eq!(t.apply(Some(-105.0)), 0.0);
        let t = Transform::new(
            Representation::parse("powed").unwrap(),
            -110.0,
            Some(-100.0),
        );
        assert_eq!(t.null_value(), 0.0);
        assert!((t.apply(Some(0.0)) - 1.0).abs() < 1e-6);
        let t = Transform::new(
            Representation::parse("exponential").unwrap(),
            -110.0,
            Some(-100.0),
        );
        assert!(t.null_value() > 0.0 && t.apply(Some(-50.0)) > t.null_value());
    }

    mod sparse_shared_ap {
        use super::*;
        use proptest::prelude::*;

        /// A dense fingerprint over `m` APs, not heard = 0, and its sparse side.
        fn sides(values: &[f32], d: &SharedAp) -> (Vec<u32>, Vec<f32>, Vec<f32>) {
            let cols: Vec<u32> = (0..values.len() as u32)
                .filter(|&j| values[j as usize] > 0.0)
                .collect();
            let vals: Vec<f32> = cols.iter().map(|&j| values[j as usize]).collect();
            let w = vals.iter().map(|&x| d.one_sided_weight(x, 0.0)).collect();
            (cols, vals, w)
        }

        fn fingerprint(m: usize) -> impl Strategy<Value = Vec<f32>> {
            // Half the APs unheard (0), the rest a representation value in (0, 60].
            proptest::collection::vec(prop_oneof![Just(0.0f32), (0.01f32..60.0f32)], m)
        }

        proptest! {
            /// The sparse evaluation adds the same terms in the same order as the dense
            /// one, so the two are bit-identical, for every setting of the distance.
            #[test]
            fn sparse_equals_dense_bit_for_bit(
                (q, r) in (1usize..200).prop_flat_map(|m| (fingerprint(m), fingerprint(m))),
                lambda in 0.0f32..100.0,
                max_offset_db in prop_oneof![Just(0.0f32), 0.1f32..15.0],
                detection_mid_db in prop_oneof![Just(0.0f32), 1.0f32..40.0],
            ) {
                let d = SharedAp { lambda, max_offset_db, detection_mid_db };
                let ((qc, qv, qw), (rc, rv, rw)) = (sides(&q, &d), sides(&r, &d));
                let sparse = d.eval_sparse(
                    SparseFingerprint { columns: &qc, values: &qv, weights: &qw },
                    SparseFingerprint { columns: &rc, values: &rv, weights: &rw },
                );
                prop_assert_eq!(sparse.to_bits(), d.eval(&q, &r, 0.0).to_bits());
            }
        }
    }
}
