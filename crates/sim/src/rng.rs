//! Seeded random streams: one ChaCha8 stream per purpose, so that adding a walk does not
//! change the floor, and walk `i` is the same whatever the number of walks.

use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use rand_distr::StandardNormal;

/// The stream of the floor's radio environment (access points).
pub(crate) const STREAM_WORLD: u64 = 0;
/// The stream of the survey radio map.
pub(crate) const STREAM_SURVEY: u64 = 1;
/// The stream of the magnetic disturbances.
pub(crate) const STREAM_MAGNETIC: u64 = 2;
/// Walk `i` uses streams `STREAM_WALK0 + WALK_STREAMS * i + c`, one per component `c`
/// (route and gait, IMU, Wi-Fi, waypoints), so that changing one model (say the IMU noise)
/// leaves the others' draws, and thus their output, unchanged.
pub(crate) const STREAM_WALK0: u64 = 1_000;
/// Number of streams reserved per walk.
pub(crate) const WALK_STREAMS: u64 = 8;
/// Component: route, timeline, phone pose.
pub(crate) const WALK_MOTION: u64 = 0;
/// Component: IMU synthesis.
pub(crate) const WALK_IMU: u64 = 1;
/// Component: Wi-Fi scans.
pub(crate) const WALK_WIFI: u64 = 2;
/// Component: waypoints.
pub(crate) const WALK_WAYPOINTS: u64 = 3;

/// The stream of component `component` of walk `index`.
pub(crate) fn walk_stream(seed: u64, index: usize, component: u64) -> ChaCha8Rng {
    stream(seed, STREAM_WALK0 + WALK_STREAMS * index as u64 + component)
}

/// A ChaCha8 generator for `seed` on `stream`.
pub(crate) fn stream(seed: u64, stream: u64) -> ChaCha8Rng {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(stream);
    rng
}

/// Convenience draws on top of [`RngExt`].
pub(crate) trait Draw {
    /// A standard normal draw.
    fn normal(&mut self) -> f64;
    /// Uniform in `[lo, hi)`; `lo` when the range is empty.
    fn uniform(&mut self, lo: f64, hi: f64) -> f64;
    /// `true` with probability `p`.
    fn chance(&mut self, p: f64) -> bool;
    /// Uniform index below `n` (`n > 0`).
    fn index(&mut self, n: usize) -> usize;
}

impl Draw for ChaCha8Rng {
    fn normal(&mut self) -> f64 {
        self.sample(StandardNormal)
    }
    fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        if hi > lo {
            lo + (hi - lo) * self.random::<f64>()
        } else {
            lo
        }
    }
    fn chance(&mut self, p: f64) -> bool {
        self.random::<f64>() < p
    }
    fn index(&mut self, n: usize) -> usize {
        if n <= 1 { 0 } else { self.random_range(0..n) }
    }
}
