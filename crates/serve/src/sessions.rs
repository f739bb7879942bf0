//! Sessions: one [`Positioner`] per phone stream, owned by the token that opened it, fed
//! sample batches in stream order under a sample-rate budget; the registry of open sessions.
//!
//! A batch is checked whole before any of it reaches the positioner (every sample converted
//! and checked, the stream order, the rate budget): a refused batch changes nothing, and
//! nothing a request sends touches another session. Samples become [`Sample`]s exactly as
//! `wipdr locate` reads a plain sample stream ([`PlainSample::add_to`], then
//! [`wipdr_positioning::samples_of`]), and each estimate takes the time of the sample that
//! made it (as [`wipdr_positioning::track_of`] does), so a walk replayed in stream order gives
//! the track `wipdr locate --model` gives, at any batch size.

use crate::auth::Owner;
use crate::db::{SessionRecord, StoredEstimate};
use crate::errors::ApiError;
use std::collections::{HashMap, VecDeque};
use std::sync::{Arc, Mutex};
use std::time::Instant;
use wipdr_core::Walk;
use wipdr_io::sample_stream::PlainSample;
use wipdr_positioning::{Positioner, Sample};

/// Estimates kept in memory per session for the live map (the whole track is in the
/// database).
pub const RECENT: usize = 64;

/// The sensor name of a sample kind (as the plain stream format names it).
pub fn sensor_name(s: &Sample) -> &'static str {
    match s {
        Sample::Accelerometer(_) => "accelerometer",
        Sample::Gyroscope(_) => "gyroscope",
        Sample::Magnetometer(_) => "magnetometer",
        Sample::RotationVector(_) => "rotation_vector",
        Sample::Pressure(_) => "pressure",
        Sample::Wifi(_) => "wifi",
    }
}

fn rank_name(rank: u8) -> &'static str {
    match rank {
        0 => "rotation_vector",
        1 => "gyroscope",
        2 => "magnetometer",
        3 => "accelerometer",
        4 => "pressure",
        _ => "wifi",
    }
}

/// One plain sample as the positioner's [`Sample`], through the conversion the plain stream
/// reader uses (the same checks: finite numbers, times in range, BSSIDs, RSSI range). `meta`
/// belongs to the session's creation, not to a batch. Errors are `(field, message)`.
pub fn to_sample(p: &PlainSample, max_scan_entries: usize) -> Result<Sample, (String, String)> {
    if let PlainSample::Meta { .. } = p {
        return Err((
            "sensor".into(),
            "meta belongs to the session's creation (phone_model, start_unix_ms), not to a batch"
                .into(),
        ));
    }
    if let PlainSample::Wifi { aps, .. } = p
        && aps.len() > max_scan_entries
    {
        return Err((
            "aps".into(),
            format!(
                "{} access points in one scan, more than {max_scan_entries}",
                aps.len()
            ),
        ));
    }
    let mut walk = Walk::default();
    p.add_to(&mut walk)?;
    wipdr_positioning::samples_of(&walk)
        .next()
        .ok_or_else(|| ("sensor".into(), "no sample".into()))
}

/// A token bucket of samples: `rate` a second, holding at most `burst`.
#[derive(Debug, Clone)]
pub struct Bucket {
    rate: f64,
    burst: f64,
    level: f64,
    at: Instant,
}

impl Bucket {
    /// A full bucket.
    pub fn new(rate: f64, burst: f64, now: Instant) -> Self {
        Self {
            rate,
            burst,
            level: burst,
            at: now,
        }
    }

    /// Takes `n` samples if the bucket holds them; else the error with the wait.
    pub fn take(&mut self, n: usize, now: Instant) -> Result<(), ApiError> {
        let dt = now.saturating_duration_since(self.at).as_secs_f64();
        self.level = (self.level + dt * self.rate).min(self.burst);
        self.at = now;
        let n = n as f64;
        if n <= self.level {
            self.level -= n;
            return Ok(());
        }
        let wait = if n > self.burst {
            f64::INFINITY
        } else {
            (n - self.level) / self.rate
        };
        Err(ApiError::RateLimited {
            rate: self.rate,
            burst: self.burst,
            retry_after_s: if wait.is_finite() {
                wait.ceil().max(1.0) as u64
            } else {
                u64::MAX
            },
        })
    }
}

/// An open session.
pub struct Session {
    /// Its metadata.
    pub record: SessionRecord,
    positioner: Positioner,
    /// (time, tie rank) of the latest accepted sample.
    last: Option<(i64, u8)>,
    next_seq: i64,
    latest: Option<StoredEstimate>,
    recent: VecDeque<StoredEstimate>,
    samples: u64,
    bucket: Bucket,
    last_activity: Instant,
}

impl std::fmt::Debug for Session {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Session")
            .field("record", &self.record)
            .field("samples", &self.samples)
            .finish_non_exhaustive()
    }
}

/// What a batch did.
#[derive(Debug, Clone, PartialEq)]
pub struct BatchOutcome {
    /// Samples accepted.
    pub accepted: usize,
    /// Sequence number of the first new estimate.
    pub first_seq: i64,
    /// The estimates the batch made, in order.
    pub estimates: Vec<StoredEstimate>,
    /// The session's current estimate.
    pub estimate: Option<StoredEstimate>,
}

impl Session {
    /// A session on a built positioner.
    pub fn new(record: SessionRecord, positioner: Positioner, bucket: Bucket) -> Self {
        Self {
            record,
            positioner,
            last: None,
            next_seq: 0,
            latest: None,
            recent: VecDeque::with_capacity(RECENT),
            samples: 0,
            bucket,
            last_activity: Instant::now(),
        }
    }

    /// Feeds a checked batch: refused whole when out of stream order or over the rate
    /// budget; else every sample goes to the positioner, in order.
    pub fn push_batch(&mut self, batch: &[Sample], now: Instant) -> Result<BatchOutcome, ApiError> {
        let mut last = self.last;
        for (index, s) in batch.iter().enumerate() {
            let key = (s.t(), s.tie_rank());
            if let Some(l) = last
                && key < l
            {
                return Err(ApiError::OutOfOrder {
                    index,
                    sensor: sensor_name(s),
                    t_ms: key.0,
                    last_sensor: rank_name(l.1),
                    last_t_ms: l.0,
                });
            }
            last = Some(key);
        }
        self.bucket.take(batch.len(), now)?;
        self.last_activity = now;
        let first_seq = self.next_seq;
        let mut estimates = Vec::new();
        for s in batch {
            if let Some(e) = self.positioner.push(s) {
                estimates.push(StoredEstimate {
                    t_ms: s.t(),
                    x: e.position.x,
                    y: e.position.y,
                    floor: e.floor,
                    sd_m: e.sd_m(),
                });
            }
        }
        self.last = last;
        self.samples += batch.len() as u64;
        self.next_seq += estimates.len() as i64;
        if let Some(e) = estimates.last() {
            self.latest = Some(*e);
        }
        for e in &estimates {
            if self.recent.len() == RECENT {
                self.recent.pop_front();
            }
            self.recent.push_back(*e);
        }
        Ok(BatchOutcome {
            accepted: batch.len(),
            first_seq,
            estimates,
            estimate: self.latest,
        })
    }

    /// The latest estimate.
    pub fn latest(&self) -> Option<StoredEstimate> {
        self.latest
    }

    /// The latest estimates (at most [`RECENT`]).
    pub fn recent(&self) -> Vec<StoredEstimate> {
        self.recent.iter().copied().collect()
    }

    /// Samples accepted.
    pub fn samples(&self) -> u64 {
        self.samples
    }

    /// Estimates made.
    pub fn estimates(&self) -> i64 {
        self.next_seq
    }

    /// Time of the latest accepted sample.
    pub fn last_sample_t(&self) -> Option<i64> {
        self.last.map(|l| l.0)
    }

    /// When the session last accepted a batch (or was opened).
    pub fn last_activity(&self) -> Instant {
        self.last_activity
    }
}

/// A shared open session.
pub type SessionRef = Arc<Mutex<Session>>;

/// Locks a session (a panic inside a positioner poisons nothing that matters here: the
/// session is closed by the caller).
pub fn lock(s: &SessionRef) -> std::sync::MutexGuard<'_, Session> {
    s.lock().unwrap_or_else(|p| p.into_inner())
}

#[derive(Debug, Default)]
struct Inner {
    open: HashMap<String, SessionRef>,
    per_owner: HashMap<Owner, usize>,
}

/// The open sessions.
#[derive(Debug, Default)]
pub struct Registry {
    inner: Mutex<Inner>,
}

impl Registry {
    fn inner(&self) -> std::sync::MutexGuard<'_, Inner> {
        self.inner.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Adds a session unless its owner has `cap` open already.
    pub fn insert(&self, session: Session, cap: usize) -> Result<SessionRef, ApiError> {
        let mut inner = self.inner();
        let owner = session.record.owner;
        let n = inner.per_owner.get(&owner).copied().unwrap_or(0);
        if n >= cap {
            return Err(ApiError::TooManySessions { limit: cap });
        }
        let id = session.record.id.clone();
        let s = Arc::new(Mutex::new(session));
        inner.open.insert(id, s.clone());
        *inner.per_owner.entry(owner).or_default() += 1;
        Ok(s)
    }

    /// The open session `id` if `owner` owns it.
    pub fn get(&self, owner: Owner, id: &str) -> Option<SessionRef> {
        let s = self.inner().open.get(id).cloned()?;
        let owned = lock(&s).record.owner == owner;
        owned.then_some(s)
    }

    /// The open session `id`, whoever owns it (for the server's own jobs).
    pub fn get_any(&self, id: &str) -> Option<SessionRef> {
        self.inner().open.get(id).cloned()
    }

    /// Removes a session; `true` when it was open.
    pub fn remove(&self, id: &str) -> bool {
        let mut inner = self.inner();
        let Some(s) = inner.open.remove(id) else {
            return false;
        };
        let owner = lock(&s).record.owner;
        if let Some(n) = inner.per_owner.get_mut(&owner) {
            *n = n.saturating_sub(1);
            if *n == 0 {
                inner.per_owner.remove(&owner);
            }
        }
        true
    }

    /// Open sessions.
    pub fn len(&self) -> usize {
        self.inner().open.len()
    }

    /// Whether no session is open.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Every open session (of `owner`, when given).
    pub fn all(&self, owner: Option<Owner>) -> Vec<SessionRef> {
        let all: Vec<SessionRef> = self.inner().open.values().cloned().collect();
        all.into_iter()
            .filter(|s| owner.is_none_or(|o| lock(s).record.owner == o))
            .collect()
    }

    /// The ids of the sessions idle since before `cutoff`.
    pub fn idle_since(&self, cutoff: Instant) -> Vec<String> {
        self.all(None)
            .into_iter()
            .filter_map(|s| {
                let s = lock(&s);
                (s.last_activity < cutoff).then(|| s.record.id.clone())
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_bucket_refills_at_its_rate_and_refuses_what_it_cannot_hold() {
        let t0 = Instant::now();
        let mut b = Bucket::new(100.0, 200.0, t0);
        assert!(b.take(150, t0).is_ok());
        let Err(ApiError::RateLimited { retry_after_s, .. }) = b.take(100, t0) else {
            panic!("expected a refusal");
        };
        assert_eq!(retry_after_s, 1);
        assert!(
            b.take(100, t0 + std::time::Duration::from_millis(500))
                .is_ok()
        );
        assert!(matches!(
            b.take(201, t0 + std::time::Duration::from_secs(100)),
            Err(ApiError::RateLimited { .. })
        ));
    }

    #[test]
    fn plain_samples_convert_as_the_stream_reader_does_and_bad_ones_name_the_field() {
        let p: PlainSample = serde_json::from_str(
            r#"{"t_ms":5,"sensor":"wifi","aps":[{"bssid":"aa:bb:cc:dd:ee:01","rssi_dbm":-61}]}"#,
        )
        .unwrap();
        let Sample::Wifi(scan) = to_sample(&p, 10).unwrap() else {
            panic!("a scan");
        };
        assert_eq!(scan.t, 5);
        assert_eq!(scan.entries.len(), 1);
        let bad = PlainSample::Accelerometer {
            t_ms: 0,
            x: f64::NAN,
            y: 0.0,
            z: 0.0,
        };
        assert_eq!(to_sample(&bad, 10).unwrap_err().0, "x");
        let meta = PlainSample::Meta {
            phone_model: None,
            start_unix_ms: None,
        };
        assert_eq!(to_sample(&meta, 10).unwrap_err().0, "sensor");
        assert_eq!(to_sample(&p, 0).unwrap_err().0, "aps");
    }
}
