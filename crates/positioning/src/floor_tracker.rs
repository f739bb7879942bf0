//! The floor of a stream, from Wi-Fi and the barometer: a discrete Bayes filter over the
//! radio map's floors.
//!
//! - **Wi-Fi**: each fix votes for the majority floor of its candidates. The vote's
//!   likelihood is [`FloorConfig::wifi_hit_probability`] for that floor and the rest shared
//!   by the others. Between fixes the belief leaks [`FloorConfig::change_probability`]
//!   towards uniform, so Wi-Fi alone (a phone without a barometer) changes floor after a run
//!   of consistent votes (about six with the defaults), never on one odd fix.
//! - **Barometer**: only pressure *changes* within a stream count (absolute pressure differs
//!   by day and phone by more than a floor's worth). The pressure is smoothed
//!   ([`FloorConfig::pressure_smoothing_s`]); once it has settled (changed less than
//!   [`FloorConfig::settled_hpa`] over [`FloorConfig::settle_s`]) more than half a floor
//!   away from the reference, the belief is moved by `-(change / hpa_per_floor)` floors
//!   (pressure rises going down), each floor's mass onto the map floor nearest its target,
//!   and the reference is reset. While settled and near the reference, the reference follows
//!   the pressure slowly ([`FloorConfig::reference_follow_s`]) so weather drift over hours is
//!   not taken for a floor change.
//!
//! - **Barometric references** (differential barometry): where training walks recorded by
//!   the same phone model within [`FloorConfig::reference_window_min`] of the stream give
//!   their pressure on a known floor ([`PressureReference`]), each fix also weighs the
//!   floors by how well the stream's smoothed pressure fits `reference floor + (reference
//!   pressure - pressure) / hpa_per_floor` (median over the references, Gaussian with
//!   [`FloorConfig::reference_sigma_floors`]). A phone model's offset cancels (same model);
//!   the window bounds the weather's drift. Without references nothing changes.
//!
//! The floor is the belief's most likely floor; `None` before the first fix.

use serde::{Deserialize, Serialize};
use std::collections::VecDeque;
use std::sync::Arc;
use wipdr_core::{PressureSample, TimestampMs};

/// A training walk's barometer on a known floor: the mean pressure of one stretch of the
/// walk on one floor, at its middle time (Unix ms), recorded by phone `model`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PressureReference {
    /// Phone model (`WalkMeta::model`).
    pub model: String,
    /// Time, Unix ms.
    pub t_unix_ms: TimestampMs,
    /// Mean pressure, hPa.
    pub hpa: f64,
    /// The floor it was recorded on.
    pub floor: i32,
}

/// Who records a stream and when it started: what [`PressureReference`]s are matched on.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct StreamIdentity {
    /// Phone model.
    pub model: String,
    /// Unix ms of the stream's time 0.
    pub start_unix_ms: TimestampMs,
}

/// Settings of the floor estimate ([`FloorTracker`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FloorConfig {
    /// Probability that a fix's majority floor is the true floor (0.5-0.99; default 0.7: the
    /// IPIN 2023 reference WKNN's floor hit rate per fix is 66 %).
    pub wifi_hit_probability: f64,
    /// Probability per fix that the floor changed unseen by the barometer (0-0.5).
    pub change_probability: f64,
    /// Use the barometer (default true).
    pub barometer: bool,
    /// Pressure change per floor, hPa (default 0.3: about 2.5 m of height).
    pub hpa_per_floor: f64,
    /// Time constant of the pressure smoothing, seconds.
    pub pressure_smoothing_s: f64,
    /// Window over which the smoothed pressure must have settled, seconds.
    pub settle_s: f64,
    /// Largest change of the smoothed pressure over [`FloorConfig::settle_s`] that counts as
    /// settled, hPa.
    pub settled_hpa: f64,
    /// Time constant with which the reference follows a settled pressure near it, seconds.
    pub reference_follow_s: f64,
    /// Largest time between a stream and a [`PressureReference`] of the same phone model for
    /// the reference to count, minutes (0 turns references off). Default 60: the weather
    /// moves the pressure by about 0.1-0.3 hPa an hour, a floor is 0.3.
    pub reference_window_min: f64,
    /// Spread of the floor implied by the references, floors.
    pub reference_sigma_floors: f64,
    /// Keep every candidate of a fix for its 2D position, whatever their floor (right when
    /// the floors share one metre frame and lie over each other: a fingerprint above or below
    /// is a 2D hint), instead of restricting the fix to the candidates on the estimated
    /// floor. `None` (default) = auto: the evaluation keeps them where the data's floors share
    /// one WGS84 frame (IPIN logfiles) and restricts them otherwise (ILC sites, whose floors
    /// each have their own frame); a [`crate::Positioner`] built directly restricts them.
    pub fixes_across_floors: Option<bool>,
}

impl Default for FloorConfig {
    fn default() -> Self {
        Self {
            wifi_hit_probability: 0.7,
            change_probability: 0.01,
            barometer: true,
            hpa_per_floor: 0.3,
            pressure_smoothing_s: 2.0,
            settle_s: 5.0,
            settled_hpa: 0.06,
            reference_follow_s: 600.0,
            reference_window_min: 60.0,
            reference_sigma_floors: 0.35,
            fixes_across_floors: None,
        }
    }
}

impl FloorConfig {
    /// Checks every field's range; the error names the field (`floor.<field>`).
    pub fn validate(&self) -> Result<(), (String, String)> {
        let check = |name: &str, v: f64, lo: f64, hi: f64| {
            if v.is_finite() && v >= lo && v <= hi {
                Ok(())
            } else {
                Err((
                    format!("floor.{name}"),
                    format!("{v} is outside [{lo}, {hi}]"),
                ))
            }
        };
        check("wifi_hit_probability", self.wifi_hit_probability, 0.5, 0.99)?;
        check("change_probability", self.change_probability, 0.0, 0.5)?;
        check("hpa_per_floor", self.hpa_per_floor, 0.01, 5.0)?;
        check("pressure_smoothing_s", self.pressure_smoothing_s, 0.0, 60.0)?;
        check("settle_s", self.settle_s, 0.5, 120.0)?;
        check("settled_hpa", self.settled_hpa, 0.0, 5.0)?;
        check("reference_follow_s", self.reference_follow_s, 1.0, 1e7)?;
        check("reference_window_min", self.reference_window_min, 0.0, 1e6)?;
        check(
            "reference_sigma_floors",
            self.reference_sigma_floors,
            0.05,
            10.0,
        )?;
        Ok(())
    }
}

/// The floor of one stream (see the module docs).
///
/// ```
/// use wipdr_positioning::{FloorConfig, FloorTracker};
/// use wipdr_core::PressureSample;
/// let mut floors = FloorTracker::new(vec![0, -2], FloorConfig::default());
/// assert_eq!(floors.floor(), None);
/// for k in 0..5 { floors.push_fix(k * 2000, Some(0)); }
/// assert_eq!(floors.floor(), Some(0));
/// // Down the stairs: +0.68 hPa over 30 s, then steady.
/// for k in 0..=900 {
///     let t = 10_000 + k * 100;
///     let hpa = 980.1 + 0.68 * ((k as f64 - 100.0) / 300.0).clamp(0.0, 1.0);
///     floors.push_pressure(&PressureSample { t, hpa });
/// }
/// assert_eq!(floors.floor(), Some(-2));
/// ```
#[derive(Debug, Clone)]
pub struct FloorTracker {
    config: FloorConfig,
    /// The map's floors, sorted, distinct.
    levels: Vec<i32>,
    /// Belief over `levels` (sums to 1); all zero before the first fix.
    belief: Vec<f64>,
    started: bool,
    smoothed: Option<(TimestampMs, f64)>,
    recent: VecDeque<(TimestampMs, f64)>,
    reference: Option<f64>,
    /// Barometric floor changes applied.
    changes: u64,
    /// Barometric references and the stream's identity, where given.
    references: Option<(Arc<Vec<PressureReference>>, StreamIdentity)>,
    /// Fixes weighed by the references.
    referenced_fixes: u64,
}

impl FloorTracker {
    /// A tracker over the floors of a radio map (duplicates removed).
    pub fn new(mut levels: Vec<i32>, config: FloorConfig) -> Self {
        levels.sort_unstable();
        levels.dedup();
        let n = levels.len();
        Self {
            config,
            levels,
            belief: vec![0.0; n],
            started: false,
            smoothed: None,
            recent: VecDeque::new(),
            reference: None,
            changes: 0,
            references: None,
            referenced_fixes: 0,
        }
    }

    /// The tracker with barometric references for a stream of `identity` (module docs).
    pub fn with_references(
        mut self,
        references: Arc<Vec<PressureReference>>,
        identity: StreamIdentity,
    ) -> Self {
        self.references = Some((references, identity));
        self
    }

    /// Fixes whose floor weights used barometric references.
    pub fn referenced_fixes(&self) -> u64 {
        self.referenced_fixes
    }

    /// The floor the references imply for pressure `hpa` at stream time `t` (continuous,
    /// median over the matching references); `None` without a matching reference.
    pub fn referenced_floor(&self, t: TimestampMs, hpa: f64) -> Option<f64> {
        let (refs, id) = self.references.as_ref()?;
        let window_ms = self.config.reference_window_min * 60_000.0;
        let now = id.start_unix_ms.saturating_add(t);
        let mut implied: Vec<f64> = refs
            .iter()
            .filter(|r| r.model == id.model && ((r.t_unix_ms - now) as f64).abs() <= window_ms)
            .map(|r| f64::from(r.floor) + (r.hpa - hpa) / self.config.hpa_per_floor)
            .filter(|v| v.is_finite())
            .collect();
        if implied.is_empty() {
            return None;
        }
        implied.sort_by(f64::total_cmp);
        let n = implied.len();
        Some(if n % 2 == 1 {
            implied[n / 2]
        } else {
            0.5 * (implied[n / 2 - 1] + implied[n / 2])
        })
    }

    /// The floors tracked.
    pub fn levels(&self) -> &[i32] {
        &self.levels
    }

    /// The most likely floor (ties: the lower); `None` before the first fix or without floors.
    pub fn floor(&self) -> Option<i32> {
        if !self.started {
            return None;
        }
        let mut best: Option<(usize, f64)> = None;
        for (i, &b) in self.belief.iter().enumerate() {
            if best.is_none_or(|(_, bb)| b > bb) {
                best = Some((i, b));
            }
        }
        best.map(|(i, _)| self.levels[i])
    }

    /// The belief over [`FloorTracker::levels`].
    pub fn belief(&self) -> &[f64] {
        &self.belief
    }

    /// Barometric floor changes applied so far.
    pub fn barometric_changes(&self) -> u64 {
        self.changes
    }

    /// A fix whose candidates' majority floor is `floor` (`None`: the fix says nothing).
    pub fn push_fix(&mut self, t: TimestampMs, floor: Option<i32>) {
        let n = self.levels.len();
        let Some(k) = floor.and_then(|f| self.levels.iter().position(|&l| l == f)) else {
            return;
        };
        if !self.started {
            self.belief.fill(1.0 / n as f64);
            self.started = true;
        } else {
            let eps = self.config.change_probability;
            for b in &mut self.belief {
                *b = (1.0 - eps) * *b + eps / n as f64;
            }
        }
        if n < 2 {
            return;
        }
        let hit = self.config.wifi_hit_probability;
        let miss = (1.0 - hit) / (n - 1) as f64;
        for (i, b) in self.belief.iter_mut().enumerate() {
            *b *= if i == k { hit } else { miss };
        }
        let implied = self
            .smoothed
            .and_then(|(_, hpa)| self.referenced_floor(t, hpa));
        if let Some(implied) = implied {
            self.referenced_fixes += 1;
            let sigma = self.config.reference_sigma_floors;
            // Floors of the map only: a likelihood floored so that no floor is ever ruled
            // out for good (a wrong reference must stay correctable).
            for (i, b) in self.belief.iter_mut().enumerate() {
                let z = (f64::from(self.levels[i]) - implied) / sigma;
                *b *= (-0.5 * z * z).exp().max(1e-6);
            }
        }
        self.normalise();
    }

    /// A barometer reading (non-finite readings are ignored).
    pub fn push_pressure(&mut self, p: &PressureSample) {
        if !self.config.barometer || !p.hpa.is_finite() {
            return;
        }
        let c = self.config;
        let smoothed = match self.smoothed {
            Some((t0, s)) if p.t > t0 => {
                let dt = (p.t - t0) as f64 / 1000.0;
                let a = if c.pressure_smoothing_s > 0.0 {
                    1.0 - (-dt / c.pressure_smoothing_s).exp()
                } else {
                    1.0
                };
                s + a * (p.hpa - s)
            }
            Some((_, s)) => s,
            None => p.hpa,
        };
        let last_t = self.smoothed.map_or(p.t, |(t0, _)| t0.max(p.t));
        self.smoothed = Some((last_t, smoothed));
        self.recent.push_back((p.t, smoothed));
        let window_ms = (c.settle_s * 1000.0) as i64;
        while self
            .recent
            .front()
            .is_some_and(|&(t0, _)| p.t - t0 > window_ms)
        {
            self.recent.pop_front();
        }
        let reference = *self.reference.get_or_insert(smoothed);
        let spanned = self
            .recent
            .front()
            .is_some_and(|&(t0, _)| p.t - t0 >= window_ms * 9 / 10);
        let (lo, hi) = self
            .recent
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &(_, v)| {
                (lo.min(v), hi.max(v))
            });
        let settled = spanned && hi - lo <= c.settled_hpa;
        if !settled {
            return;
        }
        let change = smoothed - reference;
        let floors = -change / c.hpa_per_floor;
        if floors.abs() >= 0.5 {
            self.shift(floors);
            self.reference = Some(smoothed);
            self.changes += 1;
            tracing::debug!(t = p.t, change_hpa = change, floors, floor = ?self.floor(), "barometric floor change");
        } else if let Some((t_prev, _)) = self.recent.iter().rev().nth(1).copied() {
            let dt = ((p.t - t_prev) as f64 / 1000.0).max(0.0);
            let a = (dt / c.reference_follow_s).min(1.0);
            self.reference = Some(reference + a * (smoothed - reference));
        }
    }

    /// Moves each floor's belief by `floors` (continuous) onto the nearest map floor.
    fn shift(&mut self, floors: f64) {
        if !self.started || self.levels.len() < 2 {
            return;
        }
        let mut moved = vec![0.0; self.levels.len()];
        for (i, &b) in self.belief.iter().enumerate() {
            let target = f64::from(self.levels[i]) + floors;
            let j = (0..self.levels.len())
                .min_by(|&a, &b| {
                    (f64::from(self.levels[a]) - target)
                        .abs()
                        .total_cmp(&(f64::from(self.levels[b]) - target).abs())
                })
                .unwrap_or(i);
            moved[j] += b;
        }
        self.belief = moved;
        self.normalise();
    }

    fn normalise(&mut self) {
        let sum: f64 = self.belief.iter().sum();
        let n = self.belief.len();
        if sum.is_finite() && sum > 1e-300 {
            for b in &mut self.belief {
                *b /= sum;
            }
        } else if n > 0 {
            self.belief.fill(1.0 / n as f64);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn steady(tracker: &mut FloorTracker, from: TimestampMs, to: TimestampMs, hpa: f64) {
        let mut t = from;
        while t <= to {
            tracker.push_pressure(&PressureSample { t, hpa });
            t += 100;
        }
    }

    #[test]
    fn one_odd_fix_does_not_change_the_floor_but_a_run_does() {
        let mut f = FloorTracker::new(vec![0, -2], FloorConfig::default());
        for k in 0..10 {
            f.push_fix(k, Some(0));
        }
        f.push_fix(11, Some(-2));
        assert_eq!(f.floor(), Some(0));
        for k in 0..12 {
            f.push_fix(20 + k, Some(-2));
        }
        assert_eq!(f.floor(), Some(-2));
    }

    #[test]
    fn weather_drift_is_not_a_floor_change() {
        let mut f = FloorTracker::new(vec![0, 1], FloorConfig::default());
        f.push_fix(0, Some(0));
        // +0.6 hPa over two hours (fast weather), sampled at 10 Hz.
        let mut t = 0;
        while t <= 7_200_000 {
            let hpa = 1000.0 + 0.6 * t as f64 / 7_200_000.0;
            f.push_pressure(&PressureSample { t, hpa });
            t += 100;
        }
        assert_eq!(f.floor(), Some(0));
        assert_eq!(f.barometric_changes(), 0);
    }

    #[test]
    fn up_one_floor_by_the_barometer() {
        let mut f = FloorTracker::new(vec![0, 1, 2], FloorConfig::default());
        f.push_fix(0, Some(1));
        steady(&mut f, 0, 20_000, 1000.0);
        steady(&mut f, 20_100, 40_000, 999.65);
        assert_eq!(f.floor(), Some(2));
        assert_eq!(f.barometric_changes(), 1);
    }

    #[test]
    fn references_of_the_same_phone_and_hour_decide_the_floor() {
        let refs = Arc::new(vec![
            PressureReference {
                model: "A".into(),
                t_unix_ms: 1_000_000,
                hpa: 976.3,
                floor: 0,
            },
            PressureReference {
                model: "B".into(),
                t_unix_ms: 1_000_000,
                hpa: 980.0,
                floor: 0,
            },
        ]);
        let id = StreamIdentity {
            model: "A".into(),
            start_unix_ms: 1_000_000,
        };
        let mut f = FloorTracker::new(vec![0, -2], FloorConfig::default())
            .with_references(refs.clone(), id.clone());
        steady(&mut f, 0, 10_000, 976.98);
        // Wi-Fi says floor 0 four times; the pressure (+0.68 hPa over the reference) says -2.
        for k in 0..4 {
            f.push_fix(10_000 + k, Some(0));
        }
        assert_eq!(f.floor(), Some(-2));
        assert_eq!(f.referenced_fixes(), 4);
        // Another phone model's reference does not count; nor one two hours away.
        let far = StreamIdentity {
            model: "A".into(),
            start_unix_ms: 1_000_000 + 7_200_000,
        };
        let mut g =
            FloorTracker::new(vec![0, -2], FloorConfig::default()).with_references(refs, far);
        steady(&mut g, 0, 10_000, 976.98);
        g.push_fix(10_000, Some(0));
        assert_eq!(g.floor(), Some(0));
        assert_eq!(g.referenced_fixes(), 0);
    }

    #[test]
    fn without_floors_there_is_no_floor() {
        let mut f = FloorTracker::new(vec![], FloorConfig::default());
        f.push_fix(0, Some(3));
        steady(&mut f, 0, 10_000, 1000.0);
        assert_eq!(f.floor(), None);
    }

    #[test]
    fn bad_config_names_the_field() {
        let c = FloorConfig {
            hpa_per_floor: 0.0,
            ..FloorConfig::default()
        };
        assert_eq!(c.validate().unwrap_err().0, "floor.hpa_per_floor");
    }

    proptest! {
        #[test]
        fn belief_stays_a_distribution(votes in prop::collection::vec(prop::option::of(-3i32..3), 0..60),
                                        hpa in prop::collection::vec(900.0..1100.0f64, 0..200)) {
            let mut f = FloorTracker::new(vec![-2, 0, 1], FloorConfig::default());
            for (k, v) in votes.iter().enumerate() {
                f.push_fix(k as i64, *v);
            }
            for (k, p) in hpa.iter().enumerate() {
                f.push_pressure(&PressureSample { t: 1000 * k as i64, hpa: *p });
            }
            if f.floor().is_some() {
                let sum: f64 = f.belief().iter().sum();
                prop_assert!((sum - 1.0).abs() < 1e-9);
                prop_assert!(f.belief().iter().all(|b| b.is_finite() && *b >= 0.0));
                prop_assert!(f.levels().contains(&f.floor().unwrap()));
            }
        }
    }
}
