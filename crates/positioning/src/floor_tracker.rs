//! The floor of a stream, from Wi-Fi and the barometer: a discrete Bayes filter over the
//! building's floors, which needs evidence to change floor.
//!
//! - **Floors**: those of the radio map, and with [`FloorTracker::with_building`] those of the
//!   building (a site model's floor list, [`crate::site_model::SiteModelData::floors`]), some of
//!   which may have no fingerprint (*unmapped*). Each floor has a height; the heights say how
//!   far apart the floors are in pressure ([`HPA_PER_METRE`]); without heights the floors are
//!   [`FloorConfig::hpa_per_floor`] apart.
//! - **Barometer** (relative): only pressure *changes* within a stream count (absolute
//!   pressure differs by day and phone by more than a floor's worth). The pressure is
//!   smoothed ([`FloorConfig::pressure_smoothing_s`]); once it has settled (changed less than
//!   [`FloorConfig::settled_hpa`] over the last [`FloorConfig::settle_s`], which is how long a
//!   new level must hold) its change from the reference is compared with the floors' heights:
//!   a change of at least [`FloorConfig::min_change_floors`] of the mean gap between floors
//!   moves each floor's belief to the floor whose height is nearest its own plus the change
//!   (when the change is that share of the gap to its next floor that way) and resets the
//!   reference. A smaller change (a door or the
//!   ventilation: 0.1-0.2 hPa; a pause on a stair landing) moves no floor, and the reference
//!   follows a settled pressure with the time constant [`FloorConfig::reference_follow_s`], so
//!   weather drift (up to about 1 hPa an hour) lags it by a tenth of a floor at most.
//! - **Wi-Fi**: each fix votes for the majority floor of its candidates. The vote's likelihood
//!   is [`FloorConfig::wifi_hit_probability`] for that floor, the rest shared by the other
//!   mapped floors; an unmapped floor gets the geometric mean of the two (a fix cannot vote
//!   for it, and a fix voting for a floor next to it is no strong evidence against it). Before
//!   each fix the belief leaks towards uniform: [`FloorConfig::change_probability`] per fix
//!   without a barometer (Wi-Fi alone changes floor after a run of about six consistent
//!   votes), [`FloorConfig::barometer_change_probability`] while the barometer is reading
//!   (a floor change would have shown in the pressure): the floor then changes on Wi-Fi alone
//!   only when it keeps disagreeing, which is how a wrong floor is given up. Time to recover
//!   from a wrong floor the Wi-Fi disagrees with (barometer reading, defaults, every fix voting
//!   for the true floor): 8 fixes with two mapped floors, 5 with three (the test
//!   `a_wrong_floor_is_given_up_when_wifi_keeps_disagreeing`); at the IPIN logfiles' scan
//!   interval (2.9 s on Trial21_repetition01) 15-24 s. Without a barometer: 6 and 4 fixes.
//! - **Barometric references** (absolute, differential barometry): where training walks
//!   recorded by the same phone model within [`FloorConfig::reference_window_min`] of the
//!   stream give their pressure on a known floor ([`PressureReference`]), each fix also weighs
//!   the floors by how well the stream's smoothed pressure fits the reference floor's height
//!   plus the pressure difference (median over the references, Gaussian with
//!   [`FloorConfig::reference_sigma_floors`]). A phone model's offset cancels (same model);
//!   the window bounds the weather's drift. Without references nothing changes.
//!
//! The floor is the belief's most likely floor; `None` before the first fix. The work per
//! pressure sample is a pass over the last [`FloorConfig::settle_s`] of smoothed pressure; per
//! fix, a pass over the floors.

use serde::{Deserialize, Serialize};
use std::collections::VecDeque;
use std::sync::Arc;
use wipdr_core::{PressureSample, TimestampMs};

/// Pressure change per metre of height near sea level, hPa (air density 1.2 kg/m³ x g:
/// 11.8 Pa/m); 3 % less at 300 m, which the floor tolerances absorb.
pub const HPA_PER_METRE: f64 = 0.118;
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
    /// Probability per fix that the floor changed unseen, without a barometer (0-0.5).
    pub change_probability: f64,
    /// Probability per fix that the floor changed unseen while the barometer reads (0-0.5;
    /// default 0.001: a change of floor shows in the pressure, so Wi-Fi alone must disagree
    /// eight times in a row with two mapped floors to move the floor, against six at 0.01).
    pub barometer_change_probability: f64,
    /// Use the barometer (default true).
    pub barometer: bool,
    /// Pressure change between two floors where the building's floor heights are not known,
    /// hPa (default 0.4: 3.4 m, the middle of the usual 3-4 m from floor to floor; with
    /// [`FloorConfig::min_change_floors`] single-floor changes of 2.4-5 m are told apart from
    /// a 0.2 hPa door step). The heights a site model learns replace it.
    pub hpa_per_floor: f64,
    /// Smallest settled pressure change, as a share of the gap to the next floor that way,
    /// that moves the floor (default 0.7: a 0.2 hPa door or ventilation step is 0.5 of the
    /// default gap, and of the 0.33 hPa between the IPIN building's floors 0.6).
    pub min_change_floors: f64,
    /// Time constant of the pressure smoothing, seconds.
    pub pressure_smoothing_s: f64,
    /// Window over which the smoothed pressure must have settled, seconds: how long a new
    /// pressure level must hold before it moves the floor.
    pub settle_s: f64,
    /// Largest change of the smoothed pressure over [`FloorConfig::settle_s`] that counts as
    /// settled, hPa.
    pub settled_hpa: f64,
    /// Time constant with which the reference follows a settled pressure that moved no
    /// floor, seconds (default 120: weather drift of 1 hPa an hour lags by 0.03 hPa, a 0.2
    /// hPa step is absorbed within minutes, a 10 s pause on a stair landing moves the
    /// reference by 8 % of the way).
    pub reference_follow_s: f64,
    /// Largest time between a stream and a [`PressureReference`] of the same phone model for
    /// the reference to count, minutes (0 turns references off). Default 60: the weather
    /// moves the pressure by about 0.1-0.3 hPa an hour, a floor is 0.3-0.45.
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
            barometer_change_probability: 0.001,
            barometer: true,
            hpa_per_floor: 0.4,
            min_change_floors: 0.7,
            pressure_smoothing_s: 2.0,
            settle_s: 5.0,
            settled_hpa: 0.06,
            reference_follow_s: 120.0,
            reference_window_min: 60.0,
            reference_sigma_floors: 0.35,
            fixes_across_floors: None,
        }
    }
}

impl FloorConfig {
    /// Checks every field's range; the error names the field (`floor.<field>`).
    pub fn validate(&self) -> Result<(), wipdr_core::ConfigError> {
        let check = |name: &str, v: f64, lo: f64, hi: f64| {
            if v.is_finite() && v >= lo && v <= hi {
                Ok(())
            } else {
                Err(wipdr_core::ConfigError::new(
                    format!("floor.{name}"),
                    format!("{v} is outside [{lo}, {hi}]"),
                ))
            }
        };
        check("wifi_hit_probability", self.wifi_hit_probability, 0.5, 0.99)?;
        check("change_probability", self.change_probability, 0.0, 0.5)?;
        check(
            "barometer_change_probability",
            self.barometer_change_probability,
            0.0,
            0.5,
        )?;
        check("hpa_per_floor", self.hpa_per_floor, 0.01, 5.0)?;
        check("min_change_floors", self.min_change_floors, 0.5, 1.0)?;
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
/// // Down the stairs: +0.8 hPa (two default floors) over 30 s, then steady.
/// for k in 0..=900 {
///     let t = 10_000 + k * 100;
///     let hpa = 980.1 + 0.8 * ((k as f64 - 100.0) / 300.0).clamp(0.0, 1.0);
///     floors.push_pressure(&PressureSample { t, hpa });
/// }
/// assert_eq!(floors.floor(), Some(-2));
/// ```
#[derive(Debug, Clone)]
pub struct FloorTracker {
    config: FloorConfig,
    /// The floors, sorted, distinct.
    levels: Vec<i32>,
    /// Whether each floor has fingerprints (Wi-Fi can vote for it).
    mapped: Vec<bool>,
    /// Height of each floor as a pressure drop from the lowest floor, hPa (increasing).
    alt_hpa: Vec<f64>,
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
    /// A tracker over the floors of a radio map (duplicates removed), all mapped,
    /// [`FloorConfig::hpa_per_floor`] apart.
    pub fn new(mut levels: Vec<i32>, config: FloorConfig) -> Self {
        levels.sort_unstable();
        levels.dedup();
        let n = levels.len();
        let alt_hpa = levels
            .iter()
            .map(|&l| f64::from(l) * config.hpa_per_floor)
            .collect();
        Self {
            config,
            levels,
            mapped: vec![true; n],
            alt_hpa,
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

    /// The tracker over the building's floors: `floors` are added to the radio map's (those
    /// not in the map are unmapped), `heights_m[i]` is the height of `floors[i]` (metres,
    /// any origin; missing or non-finite heights: [`FloorConfig::hpa_per_floor`] per floor
    /// from the nearest known one). Call before the first sample.
    pub fn with_building(mut self, floors: &[i32], heights_m: &[f64]) -> Self {
        let known: Vec<(i32, f64)> = floors
            .iter()
            .zip(heights_m)
            .filter(|(_, h)| h.is_finite())
            .map(|(&f, &h)| (f, h * HPA_PER_METRE))
            .collect();
        let mapped_levels = self.levels.clone();
        let mut levels: Vec<i32> = mapped_levels.iter().chain(floors).copied().collect();
        levels.sort_unstable();
        levels.dedup();
        let gap = self.config.hpa_per_floor;
        let alt_hpa: Vec<f64> = levels
            .iter()
            .map(|&l| {
                known
                    .iter()
                    .min_by_key(|(f, _)| (i64::from(*f) - i64::from(l)).abs())
                    .map_or(f64::from(l) * gap, |&(f, a)| a + f64::from(l - f) * gap)
            })
            .collect();
        let increasing = alt_hpa.windows(2).all(|w| w[1] > w[0]);
        let n = levels.len();
        self.alt_hpa = if increasing {
            alt_hpa
        } else {
            tracing::warn!(
                ?levels,
                "floor heights not increasing with the floor: default heights"
            );
            levels.iter().map(|&l| f64::from(l) * gap).collect()
        };
        self.mapped = levels.iter().map(|l| mapped_levels.contains(l)).collect();
        self.levels = levels;
        self.belief = vec![0.0; n];
        self.started = false;
        self
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

    /// Mean pressure gap between adjacent floors, hPa ([`FloorConfig::hpa_per_floor`] with
    /// fewer than two floors).
    fn mean_gap_hpa(&self) -> f64 {
        match (self.levels.first(), self.levels.last()) {
            (Some(&lo), Some(&hi)) if hi > lo => {
                (self.alt_hpa[self.alt_hpa.len() - 1] - self.alt_hpa[0]) / f64::from(hi - lo)
            }
            _ => self.config.hpa_per_floor,
        }
    }

    /// The height (as a pressure drop, hPa, on the scale of the floors' heights) the
    /// references imply for pressure `hpa` at stream time `t` (median over the matching
    /// references); `None` without a matching reference.
    fn referenced_alt(&self, t: TimestampMs, hpa: f64) -> Option<f64> {
        let (refs, id) = self.references.as_ref()?;
        let window_ms = self.config.reference_window_min * 60_000.0;
        let now = id.start_unix_ms.saturating_add(t);
        let gap = self.mean_gap_hpa();
        let mut implied: Vec<f64> = refs
            .iter()
            .filter(|r| r.model == id.model && ((r.t_unix_ms - now) as f64).abs() <= window_ms)
            .map(|r| {
                let base = match self.levels.binary_search(&r.floor) {
                    Ok(i) => self.alt_hpa[i],
                    Err(_) => f64::from(r.floor) * gap,
                };
                base + (r.hpa - hpa)
            })
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

    /// The floor the references imply for pressure `hpa` at stream time `t`, in floors
    /// (continuous: the implied height over the mean gap between floors); `None` without a
    /// matching reference.
    pub fn referenced_floor(&self, t: TimestampMs, hpa: f64) -> Option<f64> {
        let alt = self.referenced_alt(t, hpa)?;
        let gap = self.mean_gap_hpa();
        let offset = match (self.levels.first(), self.alt_hpa.first()) {
            (Some(&l), Some(&a)) => f64::from(l) - a / gap,
            _ => 0.0,
        };
        Some(alt / gap + offset)
    }

    /// The floors tracked.
    pub fn levels(&self) -> &[i32] {
        &self.levels
    }

    /// Whether each of [`FloorTracker::levels`] has fingerprints.
    pub fn mapped(&self) -> &[bool] {
        &self.mapped
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

    /// Whether the barometer has read within the last two settle windows before `t`.
    fn barometer_reading(&self, t: TimestampMs) -> bool {
        let window_ms = (2.0 * self.config.settle_s * 1000.0) as i64;
        self.config.barometer
            && self
                .smoothed
                .is_some_and(|(t0, _)| t.saturating_sub(t0) <= window_ms)
    }

    /// A fix whose candidates' majority floor is `floor` (`None`: the fix says nothing).
    pub fn push_fix(&mut self, t: TimestampMs, floor: Option<i32>) {
        let n = self.levels.len();
        let Some(k) = floor.and_then(|f| self.levels.binary_search(&f).ok()) else {
            return;
        };
        if !self.mapped[k] {
            return;
        }
        if !self.started {
            let mapped = self.mapped.iter().filter(|&&m| m).count().max(1);
            for (b, &m) in self.belief.iter_mut().zip(&self.mapped) {
                *b = if m { 1.0 / mapped as f64 } else { 0.0 };
            }
            self.started = true;
        } else {
            let eps = if self.barometer_reading(t) {
                self.config.barometer_change_probability
            } else {
                self.config.change_probability
            };
            for b in &mut self.belief {
                *b = (1.0 - eps) * *b + eps / n as f64;
            }
        }
        let mapped = self.mapped.iter().filter(|&&m| m).count();
        if mapped >= 2 {
            let hit = self.config.wifi_hit_probability;
            let miss = (1.0 - hit) / (mapped - 1) as f64;
            let unmapped = (hit * miss).sqrt();
            for (i, b) in self.belief.iter_mut().enumerate() {
                *b *= if i == k {
                    hit
                } else if self.mapped[i] {
                    miss
                } else {
                    unmapped
                };
            }
        }
        let implied = self
            .smoothed
            .and_then(|(_, hpa)| self.referenced_alt(t, hpa));
        if let Some(implied) = implied {
            self.referenced_fixes += 1;
            let sigma = self.config.reference_sigma_floors * self.mean_gap_hpa();
            // A likelihood floored so that no floor is ever ruled out for good (a wrong
            // reference must stay correctable).
            for (b, &alt) in self.belief.iter_mut().zip(&self.alt_hpa) {
                let z = (alt - implied) / sigma;
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
        if !spanned {
            return;
        }
        let (lo, hi) = self
            .recent
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &(_, v)| {
                (lo.min(v), hi.max(v))
            });
        if hi - lo > c.settled_hpa {
            return;
        }
        if !self.started {
            // The first fix decides the floor: the pressure then is its reference.
            self.reference = Some(smoothed);
            return;
        }
        let change = smoothed - reference;
        // Pressure rises going down: the height changes by -change. A floor's worth of change
        // moves each floor's mass where it leads and resets the reference even when the most
        // likely floor stays (the fixes or the references may have moved it first: the top
        // floor after climbing); less than that is followed.
        if change.abs() >= c.min_change_floors * self.mean_gap_hpa() {
            let from = self.floor();
            self.shift(-change);
            self.reference = Some(smoothed);
            if self.floor() != from {
                self.changes += 1;
                tracing::debug!(t = p.t, change_hpa = change, floor = ?self.floor(), "barometric floor change");
            }
        } else if let Some((t_prev, _)) = self.recent.iter().rev().nth(1).copied() {
            let dt = ((p.t - t_prev) as f64 / 1000.0).max(0.0);
            let a = (dt / c.reference_follow_s).min(1.0);
            self.reference = Some(reference + a * (smoothed - reference));
        }
    }

    /// Where a height change of `rise_hpa` takes floor `i`: the floor whose height is nearest
    /// its own plus the change, when that is another floor and the change is at least
    /// [`FloorConfig::min_change_floors`] of the gap to the next floor that way.
    fn target(&self, i: usize, rise_hpa: f64) -> Option<usize> {
        let next = if rise_hpa > 0.0 {
            self.alt_hpa.get(i + 1)
        } else {
            i.checked_sub(1).and_then(|j| self.alt_hpa.get(j))
        }?;
        let gap = (next - self.alt_hpa[i]).abs();
        if rise_hpa.abs() < self.config.min_change_floors * gap {
            return None;
        }
        let target = self.alt_hpa[i] + rise_hpa;
        let j = (0..self.alt_hpa.len()).min_by(|&a, &b| {
            (self.alt_hpa[a] - target)
                .abs()
                .total_cmp(&(self.alt_hpa[b] - target).abs())
        })?;
        (j != i).then_some(j)
    }

    /// Moves the belief by a height change of `rise_hpa`: each floor's mass to its own target
    /// ([`FloorTracker::target`]), or where it is when it has none.
    fn shift(&mut self, rise_hpa: f64) {
        let mut moved = vec![0.0; self.levels.len()];
        for (i, &b) in self.belief.iter().enumerate() {
            moved[self.target(i, rise_hpa).unwrap_or(i)] += b;
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

    /// Feeds `hpa(t)` at 10 Hz over `[from, to]` ms, and a fix voting `vote(t)` every 4 s
    /// from `from` (a slower scan rate than the IPIN logfiles' 2.9 s).
    fn feed(
        f: &mut FloorTracker,
        from: TimestampMs,
        to: TimestampMs,
        hpa: impl Fn(TimestampMs) -> f64,
        vote: impl Fn(TimestampMs) -> Option<i32>,
    ) {
        let mut t = from;
        while t <= to {
            f.push_pressure(&PressureSample { t, hpa: hpa(t) });
            if (t - from) % 4000 == 0 {
                f.push_fix(t, vote(t));
            }
            t += 100;
        }
    }

    /// A small deterministic noise (xorshift, explicit seed), ±0.01 hPa: a phone
    /// barometer's jitter after its own filtering.
    fn noise(t: TimestampMs) -> f64 {
        let mut x = (t as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ 42;
        x ^= x >> 33;
        x = x.wrapping_mul(0xff51_afd7_ed55_8ccd);
        x ^= x >> 33;
        0.02 * ((x % 1000) as f64 / 1000.0 - 0.5)
    }

    /// `floors` floors from 0 up, all mapped, started on floor `start` by Wi-Fi.
    fn tracker_on(floors: i32, start: i32) -> FloorTracker {
        let mut f = FloorTracker::new((0..floors).collect(), FloorConfig::default());
        for k in 0..5 {
            f.push_fix(k, Some(start));
        }
        f
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
    fn weather_drift_of_one_hpa_an_hour_moves_no_floor() {
        for rate in [1.0, -1.0, 2.0] {
            let mut f = tracker_on(4, 1);
            // Two hours at `rate` hPa an hour (2 to 4 floors' worth), fixes saying nothing.
            feed(
                &mut f,
                10,
                7_200_000,
                |t| 1000.0 + rate * t as f64 / 3_600_000.0 + noise(t),
                |_| None,
            );
            assert_eq!(f.floor(), Some(1), "{rate} hPa/h");
            assert_eq!(f.barometric_changes(), 0, "{rate} hPa/h");
        }
    }

    #[test]
    fn door_and_ventilation_steps_move_no_floor() {
        for step in [0.1, 0.15, 0.2, -0.2] {
            let mut f = tracker_on(3, 1);
            // A step every minute for half an hour, each undone half a minute later, then
            // one left in place for the next half hour; drift of 1 hPa an hour on top.
            feed(
                &mut f,
                10,
                3_600_000,
                |t| {
                    let open = t < 1_800_000 && (t % 60_000) >= 30_000;
                    let held = t >= 1_800_000;
                    1000.0
                        + t as f64 / 3_600_000.0
                        + if open || held { step } else { 0.0 }
                        + noise(t)
                },
                |_| None,
            );
            assert_eq!(f.floor(), Some(1), "step {step} hPa");
            assert_eq!(f.barometric_changes(), 0, "step {step} hPa");
        }
    }

    #[test]
    fn stairs_with_landings_move_one_floor_each() {
        let gap = FloorConfig::default().hpa_per_floor;
        let mut f = tracker_on(5, 0);
        // Three floors up the stairs: 20 s a floor with a 10 s pause on each half landing,
        // then a minute on the floor.
        let leg = 20_000 + 10_000 + 60_000;
        let hpa = |t: TimestampMs| {
            let (floor, s) = ((t - 10_000) / leg, (t - 10_000) % leg);
            let within = if s < 10_000 {
                0.5 * s as f64 / 10_000.0
            } else if s < 20_000 {
                0.5
            } else if s < 30_000 {
                0.5 + 0.5 * (s - 20_000) as f64 / 10_000.0
            } else {
                1.0
            };
            let floors = if t < 10_000 {
                0.0
            } else {
                (floor as f64 + within).min(3.0)
            };
            1000.0 - gap * floors + noise(t)
        };
        feed(&mut f, 10, 10_000 + 3 * leg, hpa, |_| None);
        assert_eq!(f.floor(), Some(3));
        assert_eq!(f.barometric_changes(), 3);
    }

    #[test]
    fn an_elevator_moves_several_floors_at_once() {
        let gap = FloorConfig::default().hpa_per_floor;
        let mut f = tracker_on(6, 4);
        // Down three floors in 8 s.
        let hpa = |t: TimestampMs| {
            1000.0 + 3.0 * gap * ((t - 30_000) as f64 / 8_000.0).clamp(0.0, 1.0) + noise(t)
        };
        feed(&mut f, 10, 60_000, hpa, |_| None);
        assert_eq!(f.floor(), Some(1));
        assert_eq!(f.barometric_changes(), 1);
    }

    #[test]
    fn a_real_floor_change_is_seen_through_drift() {
        let gap = FloorConfig::default().hpa_per_floor;
        let mut f = tracker_on(3, 0);
        // Half an hour of 1 hPa/h drift, then one floor up in 15 s.
        let hpa = |t: TimestampMs| {
            1000.0 + t as f64 / 3_600_000.0
                - gap * ((t - 1_800_000) as f64 / 15_000.0).clamp(0.0, 1.0)
                + noise(t)
        };
        feed(&mut f, 10, 1_900_000, hpa, |_| None);
        assert_eq!(f.floor(), Some(1));
        assert_eq!(f.barometric_changes(), 1);
    }

    #[test]
    fn a_floor_the_fixes_found_first_still_resets_the_reference() {
        let gap = FloorConfig::default().hpa_per_floor;
        let mut f = tracker_on(3, 1);
        // Up to the top floor by the stairs (20-45 s); the fixes see it before the pressure
        // settles, so the barometer finds the belief already there.
        let up = |t: TimestampMs| {
            1000.0 - gap * ((t - 20_000) as f64 / 25_000.0).clamp(0.0, 1.0) + noise(t)
        };
        feed(&mut f, 10, 60_000, up, |t| (t >= 20_000).then_some(2));
        assert_eq!(f.floor(), Some(2));
        // Down two floors (70-110 s), the fixes saying nothing: measured from the top floor's
        // pressure, not from where the climb began.
        feed(
            &mut f,
            60_010,
            140_000,
            |t| {
                1000.0 - gap
                    + 2.0 * gap * ((t - 70_000) as f64 / 40_000.0).clamp(0.0, 1.0)
                    + noise(t)
            },
            |_| None,
        );
        assert_eq!(f.floor(), Some(0));
    }

    #[test]
    fn learned_heights_decide_how_many_floors_a_change_is() {
        // Floors 0-2 of 5 m each (0.59 hPa): a change of 0.6 hPa is one floor, not two
        // default ones.
        let mut f = FloorTracker::new(vec![0, 1, 2], FloorConfig::default())
            .with_building(&[0, 1, 2], &[0.0, 5.0, 10.0]);
        for k in 0..5 {
            f.push_fix(k, Some(0));
        }
        feed(
            &mut f,
            10,
            60_000,
            |t| 1000.0 - 0.6 * ((t - 20_000) as f64 / 15_000.0).clamp(0.0, 1.0),
            |_| None,
        );
        assert_eq!(f.floor(), Some(1));
    }

    #[test]
    fn the_barometer_moves_onto_a_floor_without_fingerprints() {
        let gap = FloorConfig::default().hpa_per_floor;
        // Fingerprints on 0 and 2 only; the building has 0, 1, 2.
        let mut f =
            FloorTracker::new(vec![0, 2], FloorConfig::default()).with_building(&[0, 1, 2], &[]);
        assert_eq!(f.mapped(), &[true, false, true]);
        for k in 0..5 {
            f.push_fix(k, Some(0));
        }
        assert_eq!(f.floor(), Some(0));
        // Up one floor by the stairs; on floor 1 the fixes vote for the floors next to it.
        let hpa = |t: TimestampMs| {
            1000.0 - gap * ((t - 20_000) as f64 / 15_000.0).clamp(0.0, 1.0) + noise(t)
        };
        feed(&mut f, 10, 45_000, hpa, |_| None);
        assert_eq!(f.floor(), Some(1));
        // Ten fixes (40 s) voting for floor 0 or 2 keep it there (the barometer holds).
        feed(&mut f, 45_100, 85_000, hpa, |t| {
            Some(if (t / 4000) % 2 == 0 { 0 } else { 2 })
        });
        assert_eq!(f.floor(), Some(1));
        // Wi-Fi alone never takes the floor to an unmapped one.
        let mut g =
            FloorTracker::new(vec![0, 2], FloorConfig::default()).with_building(&[0, 1, 2], &[]);
        for k in 0..40 {
            g.push_fix(k, Some(if k % 2 == 0 { 0 } else { 2 }));
            assert_ne!(g.floor(), Some(1));
        }
    }

    /// Fixes voting for `truth` needed to give up a wrong floor `wrong` held by the belief.
    fn fixes_to_recover(floors: i32, barometer: bool) -> usize {
        let (wrong, truth) = (0, 1);
        let config = FloorConfig {
            barometer,
            ..FloorConfig::default()
        };
        let mut f = FloorTracker::new((0..floors).collect(), config);
        for k in 0..5 {
            f.push_fix(k, Some(wrong));
        }
        // Settle into the wrong floor for a minute of agreeing fixes (15, one every 4 s).
        feed(&mut f, 10, 60_000, |_| 1000.0, |_| Some(wrong));
        let mut t = 60_000;
        for k in 1..=100 {
            for _ in 0..40 {
                t += 100;
                f.push_pressure(&PressureSample { t, hpa: 1000.0 });
            }
            f.push_fix(t, Some(truth));
            if f.floor() == Some(truth) {
                return k;
            }
        }
        usize::MAX
    }

    #[test]
    fn a_wrong_floor_is_given_up_when_wifi_keeps_disagreeing() {
        // The recovery times the module docs state.
        assert_eq!(fixes_to_recover(2, true), 8);
        assert_eq!(fixes_to_recover(3, true), 5);
        assert_eq!(fixes_to_recover(2, false), 6);
        assert_eq!(fixes_to_recover(3, false), 4);
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
        feed(&mut f, 1, 10_000, |_| 977.1, |_| None);
        // Wi-Fi says floor 0 four times; the pressure (+0.8 hPa over the reference) says -2.
        for k in 0..4 {
            f.push_fix(10_000 + k, Some(0));
        }
        assert_eq!(f.floor(), Some(-2));
        assert_eq!(f.referenced_fixes(), 4);
        assert!((f.referenced_floor(10_000, 977.1).unwrap() + 2.0).abs() < 1e-9);
        // Another phone model's reference does not count; nor one two hours away.
        let far = StreamIdentity {
            model: "A".into(),
            start_unix_ms: 1_000_000 + 7_200_000,
        };
        let mut g =
            FloorTracker::new(vec![0, -2], FloorConfig::default()).with_references(refs, far);
        feed(&mut g, 1, 10_000, |_| 977.1, |_| None);
        g.push_fix(10_000, Some(0));
        assert_eq!(g.floor(), Some(0));
        assert_eq!(g.referenced_fixes(), 0);
    }

    #[test]
    fn without_floors_there_is_no_floor() {
        let mut f = FloorTracker::new(vec![], FloorConfig::default());
        f.push_fix(0, Some(3));
        feed(&mut f, 1, 10_000, |_| 1000.0, |_| None);
        assert_eq!(f.floor(), None);
    }

    #[test]
    fn bad_config_names_the_field() {
        let c = FloorConfig {
            hpa_per_floor: 0.0,
            ..FloorConfig::default()
        };
        assert_eq!(c.validate().unwrap_err().path, "floor.hpa_per_floor");
        let c = FloorConfig {
            min_change_floors: 0.2,
            ..FloorConfig::default()
        };
        assert_eq!(c.validate().unwrap_err().path, "floor.min_change_floors");
    }

    proptest! {
        #[test]
        fn belief_stays_a_distribution(votes in prop::collection::vec(prop::option::of(-3i32..3), 0..60),
                                        hpa in prop::collection::vec(900.0..1100.0f64, 0..200),
                                        heights in prop::collection::vec(-20.0..20.0f64, 0..4)) {
            let mut f = FloorTracker::new(vec![-2, 0, 1], FloorConfig::default())
                .with_building(&[-2, -1, 0, 1], &heights);
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

    proptest! {
        // Each case streams 20 minutes at 10 Hz: fewer cases than the default 256.
        #![proptest_config(ProptestConfig::with_cases(24))]

        #[test]
        fn slow_drift_and_small_steps_never_move_the_floor(rate in -1.0..1.0f64,
                                                           step in -0.2..0.2f64,
                                                           at in 0i64..600_000) {
            let mut f = tracker_on(3, 1);
            feed(&mut f, 10, 1_200_000,
                 |t| 990.0 + rate * t as f64 / 3_600_000.0 + if t >= at { step } else { 0.0 } + noise(t),
                 |_| None);
            prop_assert_eq!(f.floor(), Some(1));
            prop_assert_eq!(f.barometric_changes(), 0);
        }
    }
}
