//! Scoring on held-out walks through the library's inference (`wipdr_pdr::odometry`): the
//! per-segment displacement error of the learned source and of the step model on the same
//! segments, the learned 95 % ellipse coverage, and PDR from the true start.

use crate::data::WalkRec;
use anyhow::Result;
use serde::Serialize;
use wipdr_pdr::odometry::features::{CHANNELS, WINDOW, Window};
use wipdr_pdr::odometry::{
    CHI2_2_95, LearnedOdometry, OdometryOutput, mahalanobis2, rotate_heading, span_displacement,
};

/// Errors gathered over walks.
#[derive(Debug, Default, Clone, Serialize)]
pub struct Scores {
    /// Learned per-segment displacement errors, m.
    pub learned: Vec<f64>,
    /// Step-model per-segment displacement errors on the same segments, m.
    pub steps: Vec<f64>,
    /// Learned segments inside their 95 % ellipse.
    pub inside95: usize,
    /// Segment lengths, m.
    pub lengths: Vec<f64>,
    /// Learned PDR-from-the-true-start errors at waypoints after the first Wi-Fi scan, m.
    pub pdr_learned: Vec<f64>,
    /// The step model's, same waypoints, m.
    pub pdr_steps: Vec<f64>,
    /// |length error| of the learned segment displacement, m.
    pub len_learned: Vec<f64>,
    /// |length error| of the step model's, m.
    pub len_steps: Vec<f64>,
    /// |direction error| of the learned segment displacement, degrees (segments >= 2 m).
    pub dir_learned: Vec<f64>,
    /// |direction error| of the step model's, degrees (segments >= 2 m).
    pub dir_steps: Vec<f64>,
    /// Error of the hybrid "learned length along the step model's direction", m.
    pub hybrid_len: Vec<f64>,
    /// Error of the hybrid "step model's length along the learned direction", m.
    pub hybrid_dir: Vec<f64>,
    /// Per segment: truth, steps, learned displacement (m) and learned covariance (m²).
    pub vectors: Vec<[f64; 9]>,
}

fn along(len: f64, dir: [f64; 2]) -> [f64; 2] {
    let n = dir[0].hypot(dir[1]);
    if n > 0.0 {
        [len * dir[0] / n, len * dir[1] / n]
    } else {
        [0.0; 2]
    }
}

/// |direction difference| of two displacements, degrees.
pub fn dir_err(a: [f64; 2], b: [f64; 2]) -> f64 {
    let d = a[0].atan2(a[1]) - b[0].atan2(b[1]);
    wipdr_core::angle::wrap_pi(d).abs().to_degrees()
}

fn rotate_cov(c: [f64; 3], off: f64) -> [f64; 3] {
    // R C R^T with R the heading rotation of `rotate_heading`
    let (s, co) = off.sin_cos();
    let r = [[co, s], [-s, co]];
    let m = [[c[0], c[1]], [c[1], c[2]]];
    let mut o = [[0.0; 2]; 2];
    for i in 0..2 {
        for j in 0..2 {
            for k in 0..2 {
                for l in 0..2 {
                    o[i][j] += r[i][k] * m[k][l] * r[j][l];
                }
            }
        }
    }
    [o[0][0], o[0][1], o[1][1]]
}

/// The learned outputs of a cached walk.
pub fn outputs(model: &LearnedOdometry, w: &WalkRec) -> Result<Vec<OdometryOutput>> {
    let per = CHANNELS * WINDOW;
    Ok(w.t_end
        .iter()
        .enumerate()
        .map(|(k, &t)| {
            model.predict(&Window {
                t_end: t,
                heading: w.heading[k],
                data: w.data[k * per..(k + 1) * per].to_vec(),
            })
        })
        .collect::<Result<_, _>>()?)
}

impl Scores {
    /// Adds a walk.
    pub fn add(&mut self, model: &LearnedOdometry, w: &WalkRec) -> Result<()> {
        let outs = outputs(model, w)?;
        for s in &w.segments {
            let Some((d, c)) = span_displacement(&outs, s.t_a, s.t_b) else {
                continue;
            };
            let d = rotate_heading(d, w.offset_fold);
            let c = rotate_cov(c, w.offset_fold);
            let r = [s.truth[0] - d[0], s.truth[1] - d[1]];
            self.vectors.push([
                s.truth[0], s.truth[1], s.steps[0], s.steps[1], d[0], d[1], c[0], c[1], c[2],
            ]);
            self.learned.push(r[0].hypot(r[1]));
            self.steps
                .push((s.truth[0] - s.steps[0]).hypot(s.truth[1] - s.steps[1]));
            let len = s.truth[0].hypot(s.truth[1]);
            self.lengths.push(len);
            self.len_learned.push((d[0].hypot(d[1]) - len).abs());
            self.len_steps
                .push((s.steps[0].hypot(s.steps[1]) - len).abs());
            let hl = along(d[0].hypot(d[1]), s.steps);
            self.hybrid_len
                .push((s.truth[0] - hl[0]).hypot(s.truth[1] - hl[1]));
            let hd = along(s.steps[0].hypot(s.steps[1]), d);
            self.hybrid_dir
                .push((s.truth[0] - hd[0]).hypot(s.truth[1] - hd[1]));
            if len >= 2.0 {
                self.dir_learned.push(dir_err(d, s.truth));
                self.dir_steps.push(dir_err(s.steps, s.truth));
            }
            if mahalanobis2(r, c).is_some_and(|m| m <= CHI2_2_95) {
                self.inside95 += 1;
            }
        }
        let (t0, p0) = w.first_waypoint;
        for ((t, p), sp) in w.waypoints.iter().zip(&w.steps_positions) {
            if w.first_wifi.is_some_and(|f| *t <= f) {
                continue;
            }
            let Some((d, _)) = span_displacement(&outs, t0, *t) else {
                continue;
            };
            let d = rotate_heading(d, w.offset_fold);
            self.pdr_learned
                .push((p0[0] + d[0] - p[0]).hypot(p0[1] + d[1] - p[1]));
            self.pdr_steps.push((sp[0] - p[0]).hypot(sp[1] - p[1]));
        }
        Ok(())
    }

    /// Adds another set.
    pub fn extend(&mut self, o: &Scores) {
        self.learned.extend(&o.learned);
        self.steps.extend(&o.steps);
        self.inside95 += o.inside95;
        self.lengths.extend(&o.lengths);
        self.pdr_learned.extend(&o.pdr_learned);
        self.pdr_steps.extend(&o.pdr_steps);
        self.len_learned.extend(&o.len_learned);
        self.len_steps.extend(&o.len_steps);
        self.dir_learned.extend(&o.dir_learned);
        self.dir_steps.extend(&o.dir_steps);
        self.hybrid_len.extend(&o.hybrid_len);
        self.hybrid_dir.extend(&o.hybrid_dir);
        self.vectors.extend(&o.vectors);
    }

    /// A one-line summary.
    pub fn summary(&self) -> String {
        format!(
            "segments {:>5} (mean length {:.2} m) | learned mean {:.3} median {:.3} | steps mean {:.3} median {:.3} | 95% ellipse holds {:.1} % | PDR from true start: learned {:.3} steps {:.3} ({} waypoints) | |length err| learned {:.3} steps {:.3} | |direction err| deg learned {:.1} steps {:.1} | hybrids: learned length + steps direction {:.3}, steps length + learned direction {:.3}",
            self.learned.len(),
            mean(&self.lengths),
            mean(&self.learned),
            median(&self.learned),
            mean(&self.steps),
            median(&self.steps),
            100.0 * self.inside95 as f64 / self.learned.len().max(1) as f64,
            mean(&self.pdr_learned),
            mean(&self.pdr_steps),
            self.pdr_learned.len(),
            mean(&self.len_learned),
            mean(&self.len_steps),
            mean(&self.dir_learned),
            mean(&self.dir_steps),
            mean(&self.hybrid_len),
            mean(&self.hybrid_dir),
        )
    }
}

/// Mean (NaN for none).
pub fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len() as f64
}

/// Median (NaN for none).
pub fn median(v: &[f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let n = s.len();
    if n % 2 == 1 {
        s[n / 2]
    } else {
        0.5 * (s[n / 2 - 1] + s[n / 2])
    }
}
