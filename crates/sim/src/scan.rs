//! Wi-Fi scans as a phone reports them: results cached by the OS, so every entry carries the
//! time its access point was last heard, often seconds before the scan time.
//!
//! Every scan (about every `interval_s`) is a channel sweep: each channel is listened to at one
//! moment in the sweep window, which ends `report_latency_s` before the results are delivered.
//! An access point is heard in a sweep with [`detection_probability`] of its measured power (at
//! the walker's true position at that moment); a heard access point updates the cache. The scan
//! then reports every cached entry younger than `cache_ttl_s`, with its last-seen time and
//! the power measured then. Weak access points are missed, and missed ones show up stale.
//!
//! A gross-error scan (injected with probability `gross_error_rate`, never among the first
//! `gross_error_grace_scans`) is replaced by a fresh sweep at a random walkable point at least
//! `gross_error_min_distance_m` away from the true position; the cache is not touched. The
//! truth records its time and the position used.

use crate::config::ScanConfig;
use crate::floor::SimFloorPlan;
use crate::radio::{RadioModel, detection_probability};
use crate::rng::Draw;
use rand::rngs::ChaCha8Rng;
use wipdr_core::{Point2, TimestampMs, WifiEntry, WifiScan};

/// A scan that was replaced by a gross error.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InjectedGrossError {
    /// Scan time, Unix ms.
    pub t: TimestampMs,
    /// The position the scan was generated at, metres.
    pub position: Point2,
}

/// Scanning of one walk.
pub struct Scanner<'a> {
    /// Scan configuration.
    pub cfg: &'a ScanConfig,
    /// The radio model.
    pub radio: &'a RadioModel,
    /// The floor.
    pub floor: &'a SimFloorPlan,
    /// Walk start, Unix ms.
    pub start_ms: TimestampMs,
    /// Walk duration, seconds.
    pub duration_s: f64,
    /// Probability that a scan is a gross error.
    pub gross_error_rate: f64,
}

impl Scanner<'_> {
    /// Runs the scans of a walk; `position(t)` gives the true position `t` seconds after start.
    pub fn run(
        &self,
        position: &dyn Fn(f64) -> Point2,
        rng: &mut ChaCha8Rng,
    ) -> (Vec<WifiScan>, Vec<InjectedGrossError>) {
        let c = self.cfg;
        let n_ap = self.radio.access_points.len();
        let mut cache: Vec<Option<(TimestampMs, f64)>> = vec![None; n_ap];
        let mut frequencies: Vec<u32> = self
            .radio
            .access_points
            .iter()
            .map(|a| a.frequency_mhz)
            .collect();
        frequencies.sort_unstable();
        frequencies.dedup();
        // Warm-up sweeps before the start (the phone was already scanning).
        for k in (1..=c.warmup_sweeps).rev() {
            let t = -(k as f64) * c.interval_s;
            self.sweep(t, &frequencies, position, &mut cache, rng);
        }
        let mut scans = Vec::new();
        let mut gross = Vec::new();
        let mut t = rng.uniform(0.3 * c.interval_s, c.interval_s);
        while t <= self.duration_s {
            let t_ms = self.start_ms + (t * 1000.0).round() as TimestampMs;
            let is_gross =
                scans.len() >= c.gross_error_grace_scans && rng.chance(self.gross_error_rate);
            let entries = if is_gross {
                let here = position(t);
                let far = self.far_point(here, rng);
                gross.push(InjectedGrossError {
                    t: t_ms,
                    position: far,
                });
                let mut fake: Vec<Option<(TimestampMs, f64)>> = vec![None; n_ap];
                self.sweep(t, &frequencies, &|_| far, &mut fake, rng);
                self.report(t_ms, &fake)
            } else {
                self.sweep(t, &frequencies, position, &mut cache, rng);
                self.report(t_ms, &cache)
            };
            scans.push(WifiScan { t: t_ms, entries });
            t += rng
                .uniform(
                    c.interval_s - c.interval_jitter_s,
                    c.interval_s + c.interval_jitter_s,
                )
                .max(0.2);
        }
        (scans, gross)
    }

    fn sweep(
        &self,
        t: f64,
        frequencies: &[u32],
        position: &dyn Fn(f64) -> Point2,
        cache: &mut [Option<(TimestampMs, f64)>],
        rng: &mut ChaCha8Rng,
    ) {
        let c = self.cfg;
        // One listening moment per channel in the sweep window.
        let moments: Vec<f64> = frequencies
            .iter()
            .map(|_| t - c.report_latency_s - rng.uniform(0.0, c.sweep_duration_s))
            .collect();
        for (j, ap) in self.radio.access_points.iter().enumerate() {
            let ch = frequencies.partition_point(|&f| f < ap.frequency_mhz);
            let tau = moments[ch.min(moments.len() - 1)];
            let p = position(tau.clamp(0.0, self.duration_s));
            let walls = self.floor.walls_crossed(ap.position, p);
            let rss = self.radio.measure(self.radio.mean_rss(j, p, walls), rng);
            if rng.chance(detection_probability(c, rss)) {
                cache[j] = Some((self.start_ms + (tau * 1000.0).round() as TimestampMs, rss));
            }
        }
    }

    fn report(&self, t_ms: TimestampMs, cache: &[Option<(TimestampMs, f64)>]) -> Vec<WifiEntry> {
        let ttl_ms = (self.cfg.cache_ttl_s * 1000.0) as TimestampMs;
        let mut entries: Vec<WifiEntry> = cache
            .iter()
            .zip(&self.radio.access_points)
            .filter_map(|(e, ap)| {
                let (seen, rss) = (*e)?;
                (t_ms - seen <= ttl_ms && seen <= t_ms).then(|| WifiEntry {
                    bssid: ap.bssid,
                    ssid: ap.ssid.clone(),
                    rssi_dbm: rss,
                    frequency_mhz: ap.frequency_mhz,
                    last_seen_ms: seen,
                })
            })
            .collect();
        // Strongest first, as phones list them; ties by BSSID (deterministic).
        entries.sort_by(|a, b| {
            b.rssi_dbm
                .total_cmp(&a.rssi_dbm)
                .then(a.bssid.cmp(&b.bssid))
        });
        entries
    }

    fn far_point(&self, here: Point2, rng: &mut ChaCha8Rng) -> Point2 {
        let g = &self.floor.graph;
        let mut best = here;
        let mut best_d = -1.0;
        for _ in 0..64 {
            let (a, b) = g.edges[rng.index(g.edges.len())];
            let p = g.nodes[a] + (g.nodes[b] - g.nodes[a]) * rng.uniform(0.0, 1.0);
            let d = (p - here).norm();
            if d >= self.cfg.gross_error_min_distance_m {
                return p;
            }
            if d > best_d {
                best = p;
                best_d = d;
            }
        }
        best
    }
}
