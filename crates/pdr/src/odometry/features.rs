//! IMU windows for learned odometry: the walk resampled at [`RATE_HZ`], every sample rotated
//! into a level frame that turns with the phone's yaw at the window's last sample.
//!
//! The frame. The rotation vector gives the phone's orientation `q` (phone frame to
//! East-North-Up). Each sample's accelerometer and gyroscope vectors are rotated into ENU by
//! their own `q` (gravity then lies on `Up`, so it is removed as a constant), and then the
//! whole window is turned about `Up` by the heading `psi` of the window's last sample
//! ([`crate::attitude::heading_of`], the azimuth of the phone's `+y` axis, the same heading
//! the step model uses): channel 0 is the component along `psi` ("forward"), channel 1 the
//! component to its right, channel 2 `Up`. The network predicts the window's displacement
//! in that frame, and [`local_to_world`] turns it back by `psi`. With 370 training walks
//! this builds yaw invariance into the input instead of asking the network to learn it from
//! augmentation, and the absolute heading comes from the same sensor as the step model's, so
//! a comparison of the two measures what the network adds (the step length and the walking
//! direction relative to the phone), not a different compass.

use crate::attitude::{heading_of, rotation_vector_quaternion};
use nalgebra::{UnitQuaternion, Vector3};
use wipdr_core::{TimestampMs, Walk};

/// Resampling rate of the windows, Hz.
pub const RATE_HZ: usize = 50;
/// Grid step of the resampled streams, ms.
pub const GRID_MS: i64 = 20;
/// Samples in one input window (2 s).
pub const WINDOW: usize = 100;
/// Samples between two consecutive outputs (1 s): each output is the displacement over the
/// last `STRIDE` samples of its window.
pub const STRIDE: usize = 50;
/// Input channels: acceleration forward, right, up (gravity removed, m/s²), angular rate
/// about forward, right, up (rad/s).
pub const CHANNELS: usize = 6;
/// Standard gravity removed from the `Up` acceleration, m/s².
pub const GRAVITY: f64 = 9.80665;

/// A walk's IMU on a regular [`GRID_MS`] grid: acceleration and angular rate in ENU, and the
/// phone heading at each sample.
#[derive(Debug, Clone, Default)]
pub struct ImuGrid {
    /// Time of sample 0, ms.
    pub t0: TimestampMs,
    /// Acceleration in ENU minus gravity on `Up`, m/s², one row per sample.
    pub acc: Vec<[f32; 3]>,
    /// Angular rate in ENU, rad/s, one row per sample.
    pub gyro: Vec<[f32; 3]>,
    /// Phone heading (rad, clockwise from north) at each sample.
    pub heading: Vec<f64>,
}

/// One input window in the yawed level frame, channel-major (`CHANNELS x WINDOW`), with the
/// heading that frame turns by.
#[derive(Debug, Clone, PartialEq)]
pub struct Window {
    /// Time of the window's last sample, ms (the output covers the `STRIDE` samples up to
    /// it).
    pub t_end: TimestampMs,
    /// The heading of the frame, rad (clockwise from north).
    pub heading: f64,
    /// `CHANNELS * WINDOW` values, channel `c` at `c * WINDOW ..`.
    pub data: Vec<f32>,
}

/// Linear interpolation of a sorted 3-vector stream at time `t` (held at the ends); `None`
/// when the stream is empty. `cursor` walks forward with increasing `t`.
pub(crate) fn interp3(
    samples: &[(TimestampMs, [f64; 3])],
    t: TimestampMs,
    cursor: &mut usize,
) -> Option<[f64; 3]> {
    if samples.is_empty() {
        return None;
    }
    while *cursor + 1 < samples.len() && samples[*cursor + 1].0 <= t {
        *cursor += 1;
    }
    let (ta, a) = samples[*cursor];
    if t <= ta || *cursor + 1 >= samples.len() {
        return Some(a);
    }
    let (tb, b) = samples[*cursor + 1];
    if tb <= ta {
        return Some(a);
    }
    let w = (t - ta) as f64 / (tb - ta) as f64;
    Some([
        a[0] + w * (b[0] - a[0]),
        a[1] + w * (b[1] - a[1]),
        a[2] + w * (b[2] - a[2]),
    ])
}

pub(crate) fn finite3(v: [f64; 3]) -> bool {
    v.iter().all(|c| c.is_finite())
}

impl ImuGrid {
    /// Resamples a walk's accelerometer, gyroscope and rotation vector on the grid from the
    /// first accelerometer sample to the last. Non-finite samples are dropped; the
    /// orientation is the latest rotation vector at or before each grid time (the first one
    /// before it). A missing gyroscope gives zero rates. `None` when the walk has no
    /// accelerometer or no usable rotation vector.
    pub fn from_walk(walk: &Walk) -> Option<Self> {
        let acc: Vec<_> = walk
            .imu
            .accelerometer
            .iter()
            .filter(|s| finite3(s.v))
            .map(|s| (s.t, s.v))
            .collect();
        let gyr: Vec<_> = walk
            .imu
            .gyroscope
            .iter()
            .filter(|s| finite3(s.v))
            .map(|s| (s.t, s.v))
            .collect();
        let rv: Vec<_> = walk
            .imu
            .rotation_vector
            .iter()
            .filter_map(|s| rotation_vector_quaternion(s.v).map(|q| (s.t, q)))
            .collect();
        let (first, last) = (acc.first()?.0, acc.last()?.0);
        if rv.is_empty() || last <= first {
            return None;
        }
        let n = usize::try_from((last - first) / GRID_MS).ok()? + 1;
        let mut grid = ImuGrid {
            t0: first,
            acc: Vec::with_capacity(n),
            gyro: Vec::with_capacity(n),
            heading: Vec::with_capacity(n),
        };
        let (mut ca, mut cg, mut cr) = (0usize, 0usize, 0usize);
        for i in 0..n {
            let t = first + i as i64 * GRID_MS;
            while cr + 1 < rv.len() && rv[cr + 1].0 <= t {
                cr += 1;
            }
            let (a, g, h) = grid_sample(&rv[cr].1, &acc, &gyr, t, &mut ca, &mut cg);
            grid.acc.push(a);
            grid.gyro.push(g);
            grid.heading.push(h);
        }
        Some(grid)
    }

    /// Number of grid samples.
    pub fn len(&self) -> usize {
        self.acc.len()
    }

    /// Whether the grid is empty.
    pub fn is_empty(&self) -> bool {
        self.acc.is_empty()
    }

    /// Time of grid sample `i`, ms.
    pub fn time(&self, i: usize) -> TimestampMs {
        self.t0 + i as i64 * GRID_MS
    }

    /// The window whose last sample is `end` (inclusive), `None` when it would start before
    /// sample 0 or end past the grid.
    pub fn window(&self, end: usize) -> Option<Window> {
        if end + 1 < WINDOW || end >= self.len() {
            return None;
        }
        let start = end + 1 - WINDOW;
        Some(build_window(
            &self.acc[start..=end],
            &self.gyro[start..=end],
            self.heading[end],
            self.time(end),
        ))
    }

    /// Every window at the output rate: last samples `WINDOW - 1`, `WINDOW - 1 + STRIDE`, ...
    pub fn windows(&self) -> Vec<Window> {
        (WINDOW - 1..self.len())
            .step_by(STRIDE)
            .filter_map(|e| self.window(e))
            .collect()
    }
}

/// One grid sample at time `t`: the acceleration (gravity removed from `Up`) and angular
/// rate interpolated at `t` ([`interp3`]; a missing stream gives gravity alone and zero
/// rates) turned into ENU by the orientation `q`, and the phone heading of `q`. The one
/// computation of [`ImuGrid::from_walk`] and the streaming
/// [`OdometryStream`](super::stream::OdometryStream).
pub(crate) fn grid_sample(
    q: &UnitQuaternion<f64>,
    acc: &[(TimestampMs, [f64; 3])],
    gyr: &[(TimestampMs, [f64; 3])],
    t: TimestampMs,
    ca: &mut usize,
    cg: &mut usize,
) -> ([f32; 3], [f32; 3], f64) {
    let a = interp3(acc, t, ca).unwrap_or([0.0, 0.0, GRAVITY]);
    let g = interp3(gyr, t, cg).unwrap_or([0.0; 3]);
    let ae = q * Vector3::new(a[0], a[1], a[2]);
    let ge = q * Vector3::new(g[0], g[1], g[2]);
    (
        [ae.x as f32, ae.y as f32, (ae.z - GRAVITY) as f32],
        [ge.x as f32, ge.y as f32, ge.z as f32],
        heading_of(q),
    )
}

/// The window over `WINDOW` consecutive grid samples (`acc`, `gyro` of that length) turned
/// about `Up` by the heading `psi` of its last one (see the module docs); the one
/// computation of [`ImuGrid::window`] and the streaming path.
pub(crate) fn build_window(
    acc: &[[f32; 3]],
    gyro: &[[f32; 3]],
    psi: f64,
    t_end: TimestampMs,
) -> Window {
    let (s, c) = (psi.sin() as f32, psi.cos() as f32);
    let mut data = vec![0.0f32; CHANNELS * WINDOW];
    for (k, (a, g)) in acc.iter().zip(gyro).take(WINDOW).enumerate() {
        for (off, v) in [(0usize, a), (3, g)] {
            // forward = (sin psi, cos psi), right = (cos psi, -sin psi) in (E, N)
            data[off * WINDOW + k] = v[0] * s + v[1] * c;
            data[(off + 1) * WINDOW + k] = v[0] * c - v[1] * s;
            data[(off + 2) * WINDOW + k] = v[2];
        }
    }
    Window {
        t_end,
        heading: psi,
        data,
    }
}

/// A displacement `(forward, right)` in the frame of heading `psi` turned into `(east,
/// north)`, plus the covariance `diag(var_f, var_r)` turned the same way as `(xx, xy, yy)`.
pub fn local_to_world(psi: f64, d: [f64; 2], var: [f64; 2]) -> ([f64; 2], [f64; 3]) {
    let (s, c) = psi.sin_cos();
    // world = F * (s, c) + R * (c, -s)
    let dx = d[0] * s + d[1] * c;
    let dy = d[0] * c - d[1] * s;
    let xx = var[0] * s * s + var[1] * c * c;
    let yy = var[0] * c * c + var[1] * s * s;
    let xy = (var[0] - var[1]) * s * c;
    ([dx, dy], [xx, xy, yy])
}

#[cfg(test)]
mod tests {
    use super::*;
    use wipdr_core::{RotationVectorSample, Vec3Sample};

    #[test]
    fn flat_phone_facing_east_maps_east_to_forward() {
        let mut walk = Walk::default();
        let half = -std::f64::consts::FRAC_PI_4; // yaw -90 deg: phone +y points east
        for i in 0..200 {
            let t = i * 20;
            walk.imu.rotation_vector.push(RotationVectorSample {
                t,
                v: [0.0, 0.0, half.sin()],
                accuracy: 3,
            });
            // phone +y axis = east: acceleration 1 m/s² along +y is 1 m/s² forward
            walk.imu.accelerometer.push(Vec3Sample {
                t,
                v: [0.0, 1.0, GRAVITY],
                accuracy: 3,
            });
        }
        let grid = ImuGrid::from_walk(&walk).unwrap();
        assert_eq!(grid.len(), 200);
        let w = grid.window(WINDOW - 1).unwrap();
        assert!((w.heading - std::f64::consts::FRAC_PI_2).abs() < 1e-9);
        assert!((w.data[0] - 1.0).abs() < 1e-5, "forward {}", w.data[0]);
        assert!(w.data[WINDOW].abs() < 1e-5, "right {}", w.data[WINDOW]);
        assert!(w.data[2 * WINDOW].abs() < 1e-5, "up {}", w.data[2 * WINDOW]);
        // forward displacement while facing east is an eastward displacement
        let (d, cov) = local_to_world(w.heading, [2.0, 0.0], [1.0, 0.25]);
        assert!((d[0] - 2.0).abs() < 1e-9 && d[1].abs() < 1e-9);
        assert!((cov[0] - 1.0).abs() < 1e-9 && (cov[2] - 0.25).abs() < 1e-9);
        assert_eq!(grid.windows().len(), 3);
    }

    #[test]
    fn no_rotation_vector_no_grid() {
        let mut walk = Walk::default();
        walk.imu.accelerometer.push(Vec3Sample {
            t: 0,
            v: [0.0, 0.0, GRAVITY],
            accuracy: 3,
        });
        assert!(ImuGrid::from_walk(&walk).is_none());
    }
}
