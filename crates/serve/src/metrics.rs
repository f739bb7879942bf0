//! Prometheus metrics, in the text exposition format (`GET /metrics`): open sessions,
//! samples (a counter and a samples-a-second gauge), request latency histograms by route,
//! rejected requests by reason, and the process's resident memory.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};

/// Upper bounds of the latency histogram's buckets, seconds.
pub const LATENCY_BUCKETS_S: [f64; 12] = [
    0.0005, 0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5,
];

#[derive(Debug, Default, Clone)]
struct Histogram {
    counts: [u64; LATENCY_BUCKETS_S.len()],
    count: u64,
    sum: f64,
}

/// The server's counters.
#[derive(Debug, Default)]
pub struct Metrics {
    /// Sessions opened since start.
    pub sessions_opened: AtomicU64,
    /// Sessions closed since start.
    pub sessions_closed: AtomicU64,
    /// Samples accepted since start.
    pub samples: AtomicU64,
    /// Estimates made since start.
    pub estimates: AtomicU64,
    /// Samples a second over the last completed second (updated by [`Metrics::tick`]).
    samples_per_s_bits: AtomicU64,
    last_tick: Mutex<Option<(std::time::Instant, u64)>>,
    latency: Mutex<BTreeMap<(String, String), Histogram>>,
    rejected: Mutex<BTreeMap<&'static str, u64>>,
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

impl Metrics {
    /// Records a request's latency under its method and route template.
    pub fn observe(&self, method: &str, route: &str, seconds: f64) {
        let mut map = lock(&self.latency);
        let h = map
            .entry((method.to_string(), route.to_string()))
            .or_default();
        for (c, b) in h.counts.iter_mut().zip(LATENCY_BUCKETS_S) {
            if seconds <= b {
                *c += 1;
            }
        }
        h.count += 1;
        h.sum += seconds;
    }

    /// Counts a refused request by its error code.
    pub fn reject(&self, code: &'static str) {
        *lock(&self.rejected).entry(code).or_default() += 1;
    }

    /// The refused requests of one reason so far.
    pub fn rejected(&self, code: &str) -> u64 {
        lock(&self.rejected).get(code).copied().unwrap_or(0)
    }

    /// Updates the samples-a-second gauge (called about once a second).
    pub fn tick(&self) {
        let now = std::time::Instant::now();
        let total = self.samples.load(Ordering::Relaxed);
        let mut last = lock(&self.last_tick);
        if let Some((t, n)) = *last {
            let dt = now.duration_since(t).as_secs_f64();
            if dt > 0.0 {
                let rate = total.saturating_sub(n) as f64 / dt;
                self.samples_per_s_bits
                    .store(rate.to_bits(), Ordering::Relaxed);
            }
        }
        *last = Some((now, total));
    }

    /// The text exposition, with `open_sessions` (a gauge the registry knows).
    pub fn render(&self, open_sessions: usize) -> String {
        let mut s = String::new();
        let counter = |s: &mut String, name: &str, help: &str, kind: &str, v: String| {
            let _ = writeln!(s, "# HELP {name} {help}\n# TYPE {name} {kind}\n{name} {v}");
        };
        counter(
            &mut s,
            "wipdr_serve_sessions_open",
            "Sessions open now.",
            "gauge",
            open_sessions.to_string(),
        );
        counter(
            &mut s,
            "wipdr_serve_sessions_opened_total",
            "Sessions opened since start.",
            "counter",
            self.sessions_opened.load(Ordering::Relaxed).to_string(),
        );
        counter(
            &mut s,
            "wipdr_serve_sessions_closed_total",
            "Sessions closed since start (by clients, idleness, shutdown).",
            "counter",
            self.sessions_closed.load(Ordering::Relaxed).to_string(),
        );
        counter(
            &mut s,
            "wipdr_serve_samples_total",
            "Samples accepted since start.",
            "counter",
            self.samples.load(Ordering::Relaxed).to_string(),
        );
        counter(
            &mut s,
            "wipdr_serve_samples_per_second",
            "Samples accepted per second, over the last second.",
            "gauge",
            f64::from_bits(self.samples_per_s_bits.load(Ordering::Relaxed)).to_string(),
        );
        counter(
            &mut s,
            "wipdr_serve_estimates_total",
            "Estimates made since start.",
            "counter",
            self.estimates.load(Ordering::Relaxed).to_string(),
        );
        let _ = writeln!(
            s,
            "# HELP wipdr_serve_rejected_requests_total Requests refused, by reason (the error code).\n# TYPE wipdr_serve_rejected_requests_total counter"
        );
        for (code, n) in lock(&self.rejected).iter() {
            let _ = writeln!(
                s,
                "wipdr_serve_rejected_requests_total{{reason=\"{code}\"}} {n}"
            );
        }
        let _ = writeln!(
            s,
            "# HELP wipdr_serve_request_duration_seconds Request latency, by method and route.\n# TYPE wipdr_serve_request_duration_seconds histogram"
        );
        for ((method, route), h) in lock(&self.latency).iter() {
            let labels = format!("method=\"{method}\",route=\"{}\"", escape(route));
            for (c, b) in h.counts.iter().zip(LATENCY_BUCKETS_S) {
                let _ = writeln!(
                    s,
                    "wipdr_serve_request_duration_seconds_bucket{{{labels},le=\"{b}\"}} {c}"
                );
            }
            let _ = writeln!(
                s,
                "wipdr_serve_request_duration_seconds_bucket{{{labels},le=\"+Inf\"}} {}\nwipdr_serve_request_duration_seconds_sum{{{labels}}} {}\nwipdr_serve_request_duration_seconds_count{{{labels}}} {}",
                h.count, h.sum, h.count
            );
        }
        if let Some(rss) = resident_bytes() {
            counter(
                &mut s,
                "process_resident_memory_bytes",
                "Resident memory of the server process, bytes.",
                "gauge",
                rss.to_string(),
            );
        }
        s
    }
}

fn escape(v: &str) -> String {
    v.replace('\\', "\\\\")
        .replace('"', "\\\"")
        .replace('\n', "\\n")
}

/// The process's resident memory, bytes (Linux: `/proc/self/statm`; `None` elsewhere).
pub fn resident_bytes() -> Option<u64> {
    let statm = std::fs::read_to_string("/proc/self/statm").ok()?;
    let pages: u64 = statm.split_whitespace().nth(1)?.parse().ok()?;
    Some(pages * 4096)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_exposition_has_every_family_and_cumulative_buckets() {
        let m = Metrics::default();
        m.observe("POST", "/v1/sessions/{id}/samples", 0.003);
        m.observe("POST", "/v1/sessions/{id}/samples", 0.2);
        m.reject("rate_limited");
        let text = m.render(3);
        assert!(text.contains("wipdr_serve_sessions_open 3"));
        assert!(text.contains("wipdr_serve_rejected_requests_total{reason=\"rate_limited\"} 1"));
        assert!(text.contains(
            "wipdr_serve_request_duration_seconds_bucket{method=\"POST\",route=\"/v1/sessions/{id}/samples\",le=\"0.005\"} 1"
        ));
        assert!(text.contains(
            "wipdr_serve_request_duration_seconds_bucket{method=\"POST\",route=\"/v1/sessions/{id}/samples\",le=\"0.25\"} 2"
        ));
        assert!(text.contains("wipdr_serve_request_duration_seconds_count{method=\"POST\",route=\"/v1/sessions/{id}/samples\"} 2"));
    }
}
