//! The survey radio map: reference points on a grid along the corridor centre lines and in the
//! hall (`train`), each the mean of `samples_per_point` sweeps, and held-out single-sweep
//! queries at random walkable positions (`test`), in the fingerprint-benchmark layout
//! (one column per BSSID, `None` = not heard, written as 100).

use crate::config::{ScanConfig, SurveyConfig};
use crate::floor::SimFloorPlan;
use crate::radio::{RadioModel, detection_probability};
use crate::rng::Draw;
use rand::rngs::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use std::collections::BTreeSet;
use wipdr_core::{Bssid, Point2, Vector2};

/// One fingerprint: a position and one RSS per BSSID column.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SurveyPoint {
    /// Position, metres.
    pub position: Point2,
    /// Mean RSS per BSSID column (dBm, 0.1 dB resolution), `None` when not heard.
    pub rss: Vec<Option<f64>>,
}

/// The survey radio map of a floor.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SurveyMap {
    /// The BSSID of each column (`ap_000`, `ap_001`, …).
    pub bssids: Vec<Bssid>,
    /// Reference points.
    pub train: Vec<SurveyPoint>,
    /// Held-out queries.
    pub test: Vec<SurveyPoint>,
}

fn fingerprint(
    radio: &RadioModel,
    floor: &SimFloorPlan,
    scan: &ScanConfig,
    p: Point2,
    samples: usize,
    rng: &mut ChaCha8Rng,
) -> Vec<Option<f64>> {
    let samples = samples.max(1);
    radio
        .mean_rss_all(floor, p)
        .into_iter()
        .map(|mean| {
            let mut sum = 0.0;
            let mut heard = 0usize;
            for _ in 0..samples {
                let v = radio.measure(mean, rng);
                if rng.chance(detection_probability(scan, v)) {
                    sum += v;
                    heard += 1;
                }
            }
            (heard * 2 >= samples && heard > 0).then(|| (sum / heard as f64 * 10.0).round() / 10.0)
        })
        .collect()
}

impl SurveyMap {
    /// Surveys the floor.
    pub fn survey(
        cfg: &SurveyConfig,
        scan: &ScanConfig,
        radio: &RadioModel,
        floor: &SimFloorPlan,
        rng: &mut ChaCha8Rng,
    ) -> Self {
        let g = &floor.graph;
        // Points along every edge; dedupe shared nodes on a centimetre key; sorted order.
        let mut keys = BTreeSet::new();
        for &(a, b) in &g.edges {
            let (pa, pb) = (g.nodes[a], g.nodes[b]);
            let n = ((pb - pa).norm() / cfg.spacing_m).ceil().max(1.0) as usize;
            for k in 0..=n {
                let p = pa + (pb - pa) * (k as f64 / n as f64);
                keys.insert(((p.x * 100.0).round() as i64, (p.y * 100.0).round() as i64));
            }
        }
        // A grid in the hall.
        let hall = floor.hall;
        let nx = ((hall.x1 - hall.x0) / cfg.spacing_m).floor() as usize;
        let ny = ((hall.y1 - hall.y0) / cfg.spacing_m).floor() as usize;
        for i in 0..nx {
            for j in 0..ny {
                let p = Point2::new(
                    hall.x0 + cfg.spacing_m * (i as f64 + 0.5),
                    hall.y0 + cfg.spacing_m * (j as f64 + 0.5),
                );
                keys.insert(((p.x * 100.0).round() as i64, (p.y * 100.0).round() as i64));
            }
        }
        let train = keys
            .into_iter()
            .map(|(x, y)| Point2::new(x as f64 / 100.0, y as f64 / 100.0))
            .filter(|&p| floor.is_walkable(p))
            .map(|p| SurveyPoint {
                position: p,
                rss: fingerprint(radio, floor, scan, p, cfg.samples_per_point, rng),
            })
            .collect();
        let test = (0..cfg.test_points)
            .map(|_| {
                let (a, b) = g.edges[rng.index(g.edges.len())];
                let mut p = g.nodes[a] + (g.nodes[b] - g.nodes[a]) * rng.uniform(0.0, 1.0);
                let off = Vector2::new(rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0));
                if floor.is_walkable(p + off) {
                    p += off;
                }
                let p = Point2::new((p.x * 100.0).round() / 100.0, (p.y * 100.0).round() / 100.0);
                SurveyPoint {
                    position: p,
                    rss: fingerprint(radio, floor, scan, p, 1, rng),
                }
            })
            .collect();
        Self {
            bssids: radio.access_points.iter().map(|a| a.bssid).collect(),
            train,
            test,
        }
    }
}
