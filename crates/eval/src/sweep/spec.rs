//! The sweep file and its expansion into configs: grid products and random draws, bounded by
//! a config limit checked before anything is allocated.

use super::SweepError;
use crate::report::Summary;
use serde::{Deserialize, Serialize};
use serde_json::Value;
use std::collections::BTreeMap;

/// The default upper bound on the number of configs a sweep may expand to
/// ([`SweepSpec::expand`]); [`SweepSpec::expand_limited`], `SweepOptions::config_limit` and
/// `wipdr sweep --config-limit N` raise it. A config costs a full evaluation, so 100 000 is
/// already far more than one machine finishes in a day; the bound exists so that a typo
/// (`samples = 1000000000`) is an error, not an abort allocating tens of gigabytes.
pub const DEFAULT_CONFIG_LIMIT: usize = 100_000;

/// The largest integer bound of an `integer = true` range (2^53: every integer up to it is
/// exact in an `f64`).
const MAX_INTEGER_BOUND: f64 = 9_007_199_254_740_992.0;

/// What "best" minimises.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Objective {
    /// Mean error.
    #[default]
    Mean,
    /// RMS error.
    Rms,
    /// 95th percentile.
    P95,
    /// The EvAAL metric (75th percentile of 2D error + 15 m x |floor error|, the IPIN
    /// competition's score); on walks without floors (floor error 0) it is the 75th
    /// percentile of the 2D error.
    Evaal,
}

impl Objective {
    /// The objective's value of a summary (infinite when nothing was scored, and for
    /// [`Objective::Evaal`] when the summary has no EvAAL figure).
    pub fn of(self, s: &Summary) -> f64 {
        if s.count == 0 {
            return f64::INFINITY;
        }
        match self {
            Objective::Mean => s.mean,
            Objective::Rms => s.rms,
            Objective::P95 => s.p95,
            Objective::Evaal => s.evaal.unwrap_or(f64::INFINITY),
        }
    }
}

/// A sampled range of one parameter.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Range {
    /// Lower bound.
    pub min: f64,
    /// Upper bound.
    pub max: f64,
    /// Sample uniformly in log space (both bounds must be > 0).
    #[serde(default)]
    pub log: bool,
    /// Round to an integer.
    #[serde(default)]
    pub integer: bool,
}

/// The random part of a sweep.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RandomSpec {
    /// Number of draws.
    pub samples: usize,
    /// Seed of the draws.
    #[serde(default)]
    pub seed: u64,
    /// Ranges by dotted path.
    pub ranges: BTreeMap<String, Range>,
}

/// A sweep file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SweepSpec {
    /// The scheme to run.
    pub scheme: String,
    /// What "best" minimises.
    #[serde(default)]
    pub objective: Objective,
    /// Value lists by dotted path (cartesian product).
    #[serde(default)]
    pub grid: BTreeMap<String, Vec<Value>>,
    /// Random draws.
    #[serde(default)]
    pub random: Option<RandomSpec>,
}

impl SweepSpec {
    /// Reads a sweep file ([`crate::config::toml_to_json`]: a non-finite number, such as a
    /// `nan` in a grid, is an error naming its path).
    pub fn from_toml(text: &str) -> Result<Self, SweepError> {
        let value = crate::config::toml_to_json(text).map_err(SweepError::Spec)?;
        serde_json::from_value(value).map_err(|e| SweepError::Spec(e.to_string()))
    }
}

/// One config of a sweep: its index and parameter values by dotted path.
#[derive(Debug, Clone, PartialEq)]
pub struct SweepPoint {
    /// Position in the sweep (stable across machines).
    pub index: usize,
    /// Parameter values, in the sweep's column order.
    pub params: Vec<(String, Value)>,
}

impl SweepPoint {
    /// A readable id: the parameters as compact JSON. Two points of one sweep may share it
    /// (integer draws can repeat); a results row is matched by index and config hash.
    pub fn id(&self) -> String {
        let obj: serde_json::Map<String, Value> = self.params.iter().cloned().collect();
        Value::Object(obj).to_string()
    }
}

/// SplitMix64: a tiny, well-known deterministic mixer (so draw `i` is the same everywhere).
fn splitmix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

fn unit_draw(seed: u64, sample: usize, param: usize) -> f64 {
    let h = splitmix64(seed ^ splitmix64((sample as u64) << 20 ^ param as u64));
    (h >> 11) as f64 / (1u64 << 53) as f64
}

impl SweepSpec {
    /// The parameter columns, in order: grid paths, then random paths not in the grid.
    pub fn columns(&self) -> Vec<String> {
        let mut cols: Vec<String> = self.grid.keys().cloned().collect();
        if let Some(r) = &self.random {
            cols.extend(
                r.ranges
                    .keys()
                    .filter(|k| !self.grid.contains_key(*k))
                    .cloned(),
            );
        }
        cols
    }

    /// The number of configs the spec expands to (grid product times random draws), computed
    /// with checked multiplication; `None` when it does not fit a `u128`.
    pub fn count(&self) -> Option<u128> {
        let mut n: u128 = 1;
        for vals in self.grid.values() {
            n = n.checked_mul(u128::try_from(vals.len()).ok()?)?;
        }
        if let Some(r) = &self.random {
            n = n.checked_mul(u128::try_from(r.samples).ok()?)?;
        }
        Some(n)
    }

    /// Checks the spec (empty value lists, bad ranges) and its size against `limit`, without
    /// allocating per config; returns the number of configs.
    pub fn check(&self, limit: usize) -> Result<usize, SweepError> {
        for (k, v) in &self.grid {
            if v.is_empty() {
                return Err(SweepError::Spec(format!("grid {k:?} has no values")));
            }
            // A `null` is what a TOML `nan` becomes in JSON: it would set the field to "not
            // set" (or fail late for a required field), never to the value written.
            if let Some(i) = v.iter().position(Value::is_null) {
                return Err(SweepError::Spec(format!(
                    "grid {k:?}[{i}]: null (a nan?) is not a value: write a finite number, or \
                     \"off\" where the field can be turned off"
                )));
            }
        }
        if let Some(r) = &self.random {
            if r.samples == 0 {
                return Err(SweepError::Spec("random.samples is 0".into()));
            }
            for (k, rg) in &r.ranges {
                let ok = rg.min.is_finite()
                    && rg.max.is_finite()
                    && rg.min <= rg.max
                    && (!rg.log || rg.min > 0.0);
                if !ok {
                    return Err(SweepError::Spec(format!(
                        "range {k:?}: need finite min <= max (and min > 0 with log)"
                    )));
                }
                if rg.integer {
                    let (lo, hi) = (rg.min.ceil(), rg.max.floor());
                    if lo > hi {
                        return Err(SweepError::Spec(format!(
                            "range {k:?}: no integer between {} and {}",
                            rg.min, rg.max
                        )));
                    }
                    if lo.abs() > MAX_INTEGER_BOUND || hi.abs() > MAX_INTEGER_BOUND {
                        return Err(SweepError::Spec(format!(
                            "range {k:?}: integer bounds must be within +-2^53"
                        )));
                    }
                }
                if self.grid.contains_key(k) {
                    return Err(SweepError::Spec(format!(
                        "{k:?} is in both grid and random"
                    )));
                }
            }
        }
        let count = self.count();
        match count.and_then(|n| usize::try_from(n).ok()) {
            Some(n) if n <= limit => Ok(n),
            _ => Err(SweepError::TooManyConfigs {
                configs: count.map_or_else(|| "more than 2^128".to_string(), |n| n.to_string()),
                limit,
            }),
        }
    }

    /// Checks the spec and expands it into its configs, at most [`DEFAULT_CONFIG_LIMIT`].
    pub fn expand(&self) -> Result<Vec<SweepPoint>, SweepError> {
        self.expand_limited(DEFAULT_CONFIG_LIMIT)
    }

    /// Checks the spec and expands it into its configs, refusing (before allocating) a spec
    /// that expands to more than `limit`.
    pub fn expand_limited(&self, limit: usize) -> Result<Vec<SweepPoint>, SweepError> {
        let total = self.check(limit)?;
        // Within the limit, so every partial product below is too.
        let mut grid_points: Vec<Vec<(String, Value)>> = vec![vec![]];
        for (k, vals) in &self.grid {
            let mut next = Vec::with_capacity(grid_points.len().saturating_mul(vals.len()));
            for p in &grid_points {
                for v in vals {
                    let mut q = p.clone();
                    q.push((k.clone(), v.clone()));
                    next.push(q);
                }
            }
            grid_points = next;
        }
        let draws: Vec<Vec<(String, Value)>> = match &self.random {
            None => vec![vec![]],
            Some(r) => (0..r.samples)
                .map(|s| {
                    r.ranges
                        .iter()
                        .enumerate()
                        .map(|(j, (k, rg))| (k.clone(), draw(rg, unit_draw(r.seed, s, j))))
                        .collect()
                })
                .collect(),
        };
        let mut out = Vec::with_capacity(total);
        for g in &grid_points {
            for d in &draws {
                let mut params = g.clone();
                params.extend(d.iter().cloned());
                out.push(SweepPoint {
                    index: out.len(),
                    params,
                });
            }
        }
        Ok(out)
    }
}

/// The value of a range at the unit draw `u` (the range is checked by [`SweepSpec::check`]).
fn draw(rg: &Range, u: f64) -> Value {
    let x = if rg.log {
        (rg.min.ln() + u * (rg.max.ln() - rg.min.ln())).exp()
    } else {
        rg.min + u * (rg.max - rg.min)
    };
    if rg.integer {
        // Checked: ceil(min) <= floor(max), both within +-2^53, so the cast is exact.
        let v = x.round().clamp(rg.min.ceil(), rg.max.floor());
        Value::from(v as i64)
    } else {
        // Keep 6 significant digits so ids stay readable.
        Value::from(format!("{x:.6e}").parse::<f64>().unwrap_or(x))
    }
}

/// Sets the field at a dotted `path` of a JSON value; the field must exist (so a typo in a
/// sweep file is an error, not a silently ignored parameter).
pub fn set_path(root: &mut Value, path: &str, value: Value) -> Result<(), SweepError> {
    let err = |reason: &str| SweepError::Path {
        path: path.to_string(),
        reason: reason.to_string(),
    };
    let mut cur = root;
    let parts: Vec<&str> = path.split('.').collect();
    for (i, part) in parts.iter().enumerate() {
        let obj = cur
            .as_object_mut()
            .ok_or_else(|| err(&format!("{:?} is not a table", parts[..i].join("."))))?;
        if !obj.contains_key(*part) {
            let known: Vec<&String> = obj.keys().collect();
            return Err(err(&format!("no field {part:?} (fields: {known:?})")));
        }
        let slot = obj.get_mut(*part).ok_or_else(|| err("field vanished"))?;
        if i + 1 == parts.len() {
            *slot = value;
            return Ok(());
        }
        cur = slot;
    }
    Err(err("empty path"))
}

/// Selects the configs of shard `shard` of `shards` (`index % shards == shard`).
pub fn shard(points: Vec<SweepPoint>, shard: usize, shards: usize) -> Vec<SweepPoint> {
    if shards <= 1 {
        return points;
    }
    points
        .into_iter()
        .filter(|p| p.index % shards == shard)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec() -> SweepSpec {
        toml::from_str(
            r#"
            scheme = "ekf"
            [grid]
            "a.b" = [1, 2]
            [random]
            samples = 3
            seed = 9
            [random.ranges]
            "a.c" = { min = 0.1, max = 10.0, log = true }
            "d" = { min = 1, max = 4, integer = true }
            "#,
        )
        .unwrap()
    }

    /// Seen on the old main: a `nan` in a grid became `null`: the row's config was the base
    /// config (same hash), the value silently dropped.
    #[test]
    fn a_nan_in_a_grid_is_refused_naming_it() {
        let e = SweepSpec::from_toml("scheme = \"ekf\"\n[grid]\nscore_first_m = [10.0, nan]\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("grid.score_first_m[1]") && e.contains("NaN"),
            "{e}"
        );
        let parsed: SweepSpec =
            toml::from_str("scheme = \"ekf\"\n[grid]\nscore_first_m = [10.0, nan]\n").unwrap();
        let e = parsed.check(100).unwrap_err().to_string();
        assert!(e.contains("score_first_m") && e.contains("[1]"), "{e}");
        let ok = SweepSpec::from_toml("scheme = \"ekf\"\n[grid]\nscore_first_m = [10.0, 20.0]\n")
            .unwrap();
        assert_eq!(ok.check(100).unwrap(), 2);
    }

    #[test]
    fn expansion_is_deterministic_and_in_range() {
        let a = spec().expand().unwrap();
        let b = spec().expand().unwrap();
        assert_eq!(a, b);
        assert_eq!(a.len(), 6);
        for p in &a {
            let c = p.params[1].1.as_f64().unwrap();
            assert!((0.1..=10.0).contains(&c));
            let d = p.params[2].1.as_i64().unwrap();
            assert!((1..=4).contains(&d));
        }
        assert_eq!(spec().columns(), vec!["a.b", "a.c", "d"]);
    }

    #[test]
    fn set_path_rejects_unknown_fields() {
        let mut v = serde_json::json!({"a": {"b": 1}});
        set_path(&mut v, "a.b", Value::from(3)).unwrap();
        assert_eq!(v["a"]["b"], 3);
        assert!(set_path(&mut v, "a.x", Value::from(3)).is_err());
        assert!(set_path(&mut v, "a.b.c", Value::from(3)).is_err());
    }

    #[test]
    fn shards_partition_the_sweep() {
        let all = spec().expand().unwrap();
        let mut seen: Vec<usize> = (0..3)
            .flat_map(|i| shard(all.clone(), i, 3))
            .map(|p| p.index)
            .collect();
        seen.sort();
        assert_eq!(seen, (0..all.len()).collect::<Vec<_>>());
    }

    #[test]
    fn the_config_count_is_bounded_before_allocating() {
        let mut s = spec();
        assert_eq!(s.count(), Some(6));
        assert_eq!(s.check(6).unwrap(), 6);
        let e = s.check(5).unwrap_err().to_string();
        assert!(e.contains("6 configs") && e.contains("limit of 5"), "{e}");
        // A grid whose product overflows: checked, not wrapped.
        for i in 0..40 {
            s.grid
                .insert(format!("g{i}"), (0..100).map(Value::from).collect());
        }
        assert_eq!(s.count(), None);
        let e = s.expand().unwrap_err().to_string();
        assert!(e.contains("more than 2^128"), "{e}");
    }

    #[test]
    fn an_integer_range_without_an_integer_is_an_error() {
        let mut s = spec();
        if let Some(r) = s.random.as_mut() {
            r.ranges.insert(
                "e".into(),
                Range {
                    min: 1.2,
                    max: 1.8,
                    log: false,
                    integer: true,
                },
            );
        }
        let e = s.expand().unwrap_err().to_string();
        assert!(e.contains("no integer between 1.2 and 1.8"), "{e}");
    }
}
