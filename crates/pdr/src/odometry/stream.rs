//! The learned odometry of a live stream: IMU samples pushed one at a time, an
//! [`OdometryOutput`] each second, equal to the batch path ([`ImuGrid::from_walk`] +
//! [`ImuGrid::windows`] + [`LearnedOdometry::predict`]) on a recorded walk.
//!
//! A grid sample at time `t` needs the accelerometer sample after `t` (the linear
//! interpolation's right end) and the latest rotation vector at or before `t` (the first one
//! when none is): it is computed once the accelerometer has a sample later than `t` and the
//! stream has a rotation vector. The gyroscope is interpolated the same way; when it has no
//! sample after `t` by the time the accelerometer is [`GYRO_WAIT_MS`] past `t`, its latest
//! value is held (as the batch path holds it at a walk's end), so a phone without a gyroscope
//! still gets outputs. [`OdometryStream::finish`] computes the grid up to the last
//! accelerometer sample with the batch path's end rule (values held), so a whole walk pushed
//! and finished gives exactly the batch outputs (test `stream_equals_batch_on_a_walk`).
//!
//! Memory is bounded: raw samples are dropped once the grid has passed them, the grid keeps
//! the last two windows' samples, and without any rotation vector at most
//! [`MAX_PENDING`] raw samples of a kind wait (older ones are dropped and the grid restarts
//! after them; the batch path would use the first rotation vector for them).

use std::collections::VecDeque;
use std::sync::Arc;

use super::features::{GRID_MS, STRIDE, WINDOW, build_window, finite3, grid_sample};
use super::{LearnedOdometry, OdometryOutput};
use crate::attitude::rotation_vector_quaternion;
use nalgebra::UnitQuaternion;
use wipdr_core::TimestampMs;

/// How long past a grid time the accelerometer runs before a gyroscope without a later
/// sample is held at its latest value, ms. A gyroscope gap shorter than this is
/// interpolated exactly as the batch path does; the gyroscope of the ILC and IPIN phones
/// runs at 50-200 Hz, so this only waits on a phone without one or a dropped stream.
pub const GYRO_WAIT_MS: i64 = 1_000;

/// Most raw samples of one kind kept while the stream waits for its first rotation vector.
pub const MAX_PENDING: usize = 4_096;

/// The streaming learned odometry of one IMU stream.
#[derive(Debug, Clone)]
pub struct OdometryStream {
    model: Arc<LearnedOdometry>,
    acc: Vec<(TimestampMs, [f64; 3])>,
    gyr: Vec<(TimestampMs, [f64; 3])>,
    rv: Vec<(TimestampMs, UnitQuaternion<f64>)>,
    /// Interpolation cursors into `acc`, `gyr` and `rv`.
    cursors: (usize, usize, usize),
    /// Time of grid sample 0 (the first finite accelerometer sample).
    t0: Option<TimestampMs>,
    /// Index of the next grid sample to compute.
    next: usize,
    /// Grid index of `grid_acc[0]`.
    grid_start: usize,
    grid_acc: Vec<[f32; 3]>,
    grid_gyro: Vec<[f32; 3]>,
    grid_heading: Vec<f64>,
    outputs: VecDeque<OdometryOutput>,
    failed: u64,
}

impl OdometryStream {
    /// A stream over `model` (shared between streams).
    pub fn new(model: Arc<LearnedOdometry>) -> Self {
        Self {
            model,
            acc: Vec::new(),
            gyr: Vec::new(),
            rv: Vec::new(),
            cursors: (0, 0, 0),
            t0: None,
            next: 0,
            grid_start: 0,
            grid_acc: Vec::with_capacity(2 * WINDOW),
            grid_gyro: Vec::with_capacity(2 * WINDOW),
            grid_heading: Vec::with_capacity(2 * WINDOW),
            outputs: VecDeque::new(),
            failed: 0,
        }
    }

    /// Feeds an accelerometer sample (m/s², device frame). Non-finite samples and samples
    /// older than the latest one are ignored.
    pub fn push_accelerometer(&mut self, t: TimestampMs, v: [f64; 3]) {
        if !finite3(v) || self.acc.last().is_some_and(|&(last, _)| t < last) {
            return;
        }
        self.t0.get_or_insert(t);
        self.acc.push((t, v));
        self.advance(false);
    }

    /// Feeds a gyroscope sample (rad/s, device frame). Non-finite samples and samples older
    /// than the latest one are ignored.
    pub fn push_gyroscope(&mut self, t: TimestampMs, v: [f64; 3]) {
        if !finite3(v) || self.gyr.last().is_some_and(|&(last, _)| t < last) {
            return;
        }
        self.gyr.push((t, v));
        self.advance(false);
    }

    /// Feeds a rotation-vector sample (`x, y, z` of Android's attitude quaternion). Samples
    /// that are not a rotation and samples older than the latest one are ignored.
    pub fn push_rotation_vector(&mut self, t: TimestampMs, v: [f64; 3]) {
        if self.rv.last().is_some_and(|&(last, _)| t < last) {
            return;
        }
        if let Some(q) = rotation_vector_quaternion(v) {
            self.rv.push((t, q));
            self.advance(false);
        }
    }

    /// The end of the stream: the grid computed up to the last accelerometer sample, the
    /// streams held at their latest values (the batch path's end rule).
    pub fn finish(&mut self) {
        self.advance(true);
    }

    /// The oldest output not yet taken.
    pub fn pop(&mut self) -> Option<OdometryOutput> {
        self.outputs.pop_front()
    }

    /// Windows whose network output was not usable (skipped, logged).
    pub fn failed_windows(&self) -> u64 {
        self.failed
    }

    /// Computes every grid sample that is ready (all of them up to the last accelerometer
    /// sample when `end`), and the outputs of the windows they complete.
    fn advance(&mut self, end: bool) {
        let Some(t0) = self.t0 else { return };
        if self.rv.is_empty() {
            self.bound_pending(t0);
            return;
        }
        let Some(&(last_acc, _)) = self.acc.last() else {
            return;
        };
        loop {
            let Some(t) = i64::try_from(self.next)
                .ok()
                .and_then(|i| i.checked_mul(GRID_MS))
                .and_then(|dt| t0.checked_add(dt))
            else {
                return;
            };
            let ready = if end {
                t <= last_acc
            } else {
                last_acc > t
                    && (self.gyr.last().is_some_and(|&(tg, _)| tg > t)
                        || last_acc - t > GYRO_WAIT_MS)
            };
            if !ready {
                break;
            }
            let (ca, cg, cr) = &mut self.cursors;
            while *cr + 1 < self.rv.len() && self.rv[*cr + 1].0 <= t {
                *cr += 1;
            }
            let (a, g, h) = grid_sample(&self.rv[*cr].1, &self.acc, &self.gyr, t, ca, cg);
            self.grid_acc.push(a);
            self.grid_gyro.push(g);
            self.grid_heading.push(h);
            let index = self.next;
            self.next += 1;
            if index + 1 >= WINDOW && (index + 1 - WINDOW).is_multiple_of(STRIDE) {
                self.emit(index, t);
            }
        }
        self.trim();
    }

    /// The output of the window ending at grid sample `index` (time `t`).
    fn emit(&mut self, index: usize, t: TimestampMs) {
        let Some(start) = (index + 1).checked_sub(WINDOW + self.grid_start) else {
            return;
        };
        let end = start + WINDOW;
        let w = build_window(
            &self.grid_acc[start..end],
            &self.grid_gyro[start..end],
            self.grid_heading[end - 1],
            t,
        );
        match self.model.predict(&w) {
            Ok(o) => self.outputs.push_back(o),
            Err(e) => {
                self.failed += 1;
                tracing::debug!(t, error = %e, "odometry window skipped");
            }
        }
    }

    /// Drops raw samples the grid has passed and grid samples no window needs any more.
    fn trim(&mut self) {
        let (ca, cg, cr) = &mut self.cursors;
        for (buf, c) in [(&mut self.acc, ca), (&mut self.gyr, cg)] {
            if *c > 0 {
                buf.drain(..*c);
                *c = 0;
            }
        }
        if *cr > 0 {
            self.rv.drain(..*cr);
            *cr = 0;
        }
        if self.grid_acc.len() >= 2 * WINDOW {
            let drop = self.grid_acc.len() - WINDOW;
            self.grid_acc.drain(..drop);
            self.grid_gyro.drain(..drop);
            self.grid_heading.drain(..drop);
            self.grid_start += drop;
        }
    }

    /// Without a rotation vector nothing is computed: keeps at most [`MAX_PENDING`] raw
    /// samples of a kind, restarting the grid after the dropped ones.
    fn bound_pending(&mut self, t0: TimestampMs) {
        if self.acc.len() <= MAX_PENDING && self.gyr.len() <= MAX_PENDING {
            return;
        }
        for buf in [&mut self.acc, &mut self.gyr] {
            if buf.len() > MAX_PENDING {
                buf.drain(..buf.len() - MAX_PENDING / 2);
            }
        }
        self.cursors = (0, 0, 0);
        let Some(&(first, _)) = self.acc.first() else {
            return;
        };
        let skip = usize::try_from((first - t0 + GRID_MS - 1) / GRID_MS).unwrap_or(0);
        if skip > self.next {
            self.next = skip;
            self.grid_acc.clear();
            self.grid_gyro.clear();
            self.grid_heading.clear();
            self.grid_start = skip;
            tracing::debug!(
                dropped_until = first,
                "no rotation vector yet: oldest IMU samples dropped"
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::odometry::features::{GRAVITY, ImuGrid};
    use wipdr_core::{RotationVectorSample, Vec3Sample, Walk};

    /// A synthetic walk: a phone turning slowly while swaying, accelerometer 100 Hz,
    /// gyroscope 50 Hz with a gap, rotation vector 50 Hz starting late.
    fn walk(seconds: i64) -> Walk {
        let mut w = Walk::default();
        for i in 0..seconds * 100 {
            let t = 1_000 + i * 10 + (i % 3);
            let s = t as f64 / 1000.0;
            w.imu.accelerometer.push(Vec3Sample {
                t,
                v: [
                    0.3 * (3.0 * s).sin(),
                    1.2 * (11.0 * s).cos(),
                    GRAVITY + (7.0 * s).sin(),
                ],
                accuracy: 3,
            });
        }
        for i in 0..seconds * 50 {
            let t = 1_003 + i * 20;
            if (200..230).contains(&i) {
                continue;
            }
            let s = t as f64 / 1000.0;
            w.imu.gyroscope.push(Vec3Sample {
                t,
                v: [0.1 * s.sin(), 0.05, 0.2 * (0.5 * s).cos()],
                accuracy: 3,
            });
        }
        for i in 0..seconds * 50 - 10 {
            let t = 1_150 + i * 20;
            let half = 0.05 * (t as f64 / 1000.0) / 2.0;
            w.imu.rotation_vector.push(RotationVectorSample {
                t,
                v: [0.01, 0.02, half.sin()],
                accuracy: 3,
            });
        }
        w
    }

    /// The walk's samples pushed in time order (accelerometer, gyroscope, rotation vector at
    /// equal times), then finished.
    fn streamed(stream: &mut OdometryStream, w: &Walk) -> Vec<OdometryOutput> {
        let mut all: Vec<(TimestampMs, u8, [f64; 3])> = Vec::new();
        all.extend(w.imu.accelerometer.iter().map(|s| (s.t, 0, s.v)));
        all.extend(w.imu.gyroscope.iter().map(|s| (s.t, 1, s.v)));
        all.extend(w.imu.rotation_vector.iter().map(|s| (s.t, 2, s.v)));
        all.sort_by_key(|&(t, k, _)| (t, k));
        let mut out = Vec::new();
        for (t, k, v) in all {
            match k {
                0 => stream.push_accelerometer(t, v),
                1 => stream.push_gyroscope(t, v),
                _ => stream.push_rotation_vector(t, v),
            }
            while let Some(o) = stream.pop() {
                assert!(o.t_end <= t, "output at {} before its data ({t})", o.t_end);
                out.push(o);
            }
        }
        stream.finish();
        out.extend(std::iter::from_fn(|| stream.pop()));
        out
    }

    #[test]
    fn stream_equals_batch_on_a_synthetic_walk() {
        let model = Arc::new(LearnedOdometry::shipped().unwrap());
        let w = walk(30);
        let batch = model.run(&w).unwrap();
        assert_eq!(batch.len(), ImuGrid::from_walk(&w).unwrap().windows().len());
        assert!(batch.len() >= 25, "{} outputs", batch.len());
        let mut stream = OdometryStream::new(model);
        let got = streamed(&mut stream, &w);
        assert_eq!(got, batch);
        assert_eq!(stream.failed_windows(), 0);
        // bounded buffers
        assert!(stream.grid_acc.len() < 2 * WINDOW && stream.acc.len() < 8);
    }

    #[test]
    fn without_a_gyroscope_outputs_still_come_and_equal_the_batch() {
        let model = Arc::new(LearnedOdometry::shipped().unwrap());
        let mut w = walk(12);
        w.imu.gyroscope.clear();
        let batch = model.run(&w).unwrap();
        let mut stream = OdometryStream::new(model);
        let got = streamed(&mut stream, &w);
        assert_eq!(got, batch);
        assert!(got.len() >= 9);
    }

    #[test]
    fn without_a_rotation_vector_nothing_comes_and_memory_stays_bounded() {
        let model = Arc::new(LearnedOdometry::shipped().unwrap());
        let mut stream = OdometryStream::new(model);
        for i in 0..20_000 {
            stream.push_accelerometer(i * 10, [0.0, 0.0, GRAVITY]);
            stream.push_gyroscope(i * 10, [0.0; 3]);
            stream.push_accelerometer(i * 10, [f64::NAN, 0.0, 0.0]);
        }
        assert!(stream.pop().is_none());
        assert!(stream.acc.len() <= MAX_PENDING && stream.gyr.len() <= MAX_PENDING);
        // a rotation vector now: outputs start from the kept samples
        for i in 20_000..20_400 {
            stream.push_rotation_vector(i * 10, [0.0, 0.0, 0.0]);
            stream.push_accelerometer(i * 10, [0.0, 0.0, GRAVITY]);
            stream.push_gyroscope(i * 10, [0.0; 3]);
        }
        let o = stream.pop().unwrap();
        assert!(o.displacement.iter().all(|d| d.is_finite()));
    }
}
