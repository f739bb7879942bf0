//! The per-AP fit of the log-distance path-loss model (see the module doc of
//! [`crate::propagation`]).

use super::*;

/// What the fit kept and dropped, per reason.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
pub struct FitReport {
    /// AP columns of the map.
    pub aps: usize,
    /// Models kept.
    pub fitted: usize,
    /// APs heard at fewer than `min_samples` measured points (including never).
    pub too_few_samples: usize,
    /// APs whose hearing points span less than [`MIN_HEARING_SPAN_M`].
    pub degenerate: usize,
    /// Fits that were not finite.
    pub not_finite: usize,
    /// Fits with an RMSE over `max_rmse_db`.
    pub rmse_too_high: usize,
}

/// Fits one model per AP column of `map` (see the module doc); `None` where an AP gets no
/// model. Only measured reference points (`scans > 0`) are used.
pub fn fit_ap_models(
    map: &RadioMap,
    cfg: &PropagationConfig,
) -> Result<Vec<Option<ApModel>>, FingerprintError> {
    fit_ap_models_with_report(map, cfg).map(|(models, _)| models)
}

/// [`fit_ap_models`] with the counts of what was dropped and why.
pub fn fit_ap_models_with_report(
    map: &RadioMap,
    cfg: &PropagationConfig,
) -> Result<(Vec<Option<ApModel>>, FitReport), FingerprintError> {
    cfg.validate()?;
    let samples = samples_per_ap(map);
    let measured: Vec<usize> = (0..map.len())
        .filter(|&i| {
            let p = map.point(i).position;
            map.point(i).scans > 0 && p.x.is_finite() && p.y.is_finite()
        })
        .collect();
    enum Outcome {
        Fitted(ApModel),
        TooFew,
        Degenerate,
        NotFinite,
        RmseTooHigh,
    }
    let outcomes: Vec<Outcome> = samples
        .par_iter()
        .enumerate()
        .map(|(j, s)| {
            if s.len() < cfg.min_samples {
                return Outcome::TooFew;
            }
            let (lo, hi) = bbox(s.iter().map(|x| x.0));
            let span = (hi - lo).norm();
            if span.is_nan() || span < MIN_HEARING_SPAN_M {
                return Outcome::Degenerate;
            }
            let silent = if cfg.censored_weight > 0.0 {
                let r = cfg.max_extrapolation_m;
                measured
                    .iter()
                    .filter(|&&i| map.rss(i, j).is_none())
                    .map(|&i| map.point(i).position)
                    .filter(|p| {
                        p.x >= lo.x - r && p.x <= hi.x + r && p.y >= lo.y - r && p.y <= hi.y + r
                    })
                    .collect()
            } else {
                Vec::new()
            };
            let data = FitData {
                heard: s,
                silent: &silent,
                weight: cfg.censored_weight,
                detection_dbm: cfg.detection_dbm,
            };
            match fit_one(&data, cfg) {
                None => Outcome::NotFinite,
                Some(m) if !m.is_finite() => Outcome::NotFinite,
                Some(m) if m.rmse_db > cfg.max_rmse_db => Outcome::RmseTooHigh,
                Some(m) => Outcome::Fitted(m),
            }
        })
        .collect();
    let mut report = FitReport {
        aps: map.n_aps(),
        ..Default::default()
    };
    let models = outcomes
        .into_iter()
        .map(|o| match o {
            Outcome::Fitted(m) => {
                report.fitted += 1;
                Some(m)
            }
            Outcome::TooFew => {
                report.too_few_samples += 1;
                None
            }
            Outcome::Degenerate => {
                report.degenerate += 1;
                None
            }
            Outcome::NotFinite => {
                report.not_finite += 1;
                None
            }
            Outcome::RmseTooHigh => {
                report.rmse_too_high += 1;
                None
            }
        })
        .collect();
    tracing::debug!(?report, "path-loss fit");
    Ok((models, report))
}

/// Per AP column, `(position, dBm)` of the measured points that heard it (finite only).
pub(super) fn samples_per_ap(map: &RadioMap) -> Vec<Vec<(Point2, f64)>> {
    let mut out = vec![Vec::new(); map.n_aps()];
    for (i, point) in map.points().iter().enumerate() {
        let p = point.position;
        if point.scans == 0 || !(p.x.is_finite() && p.y.is_finite()) {
            continue;
        }
        for (j, v) in map.heard(i) {
            let v = f64::from(v);
            if v.is_finite() {
                out[j].push((p, v));
            }
        }
    }
    out
}

/// Lower-left and upper-right corners of the points (NaN-free input assumed).
pub(super) fn bbox(points: impl Iterator<Item = Point2>) -> (Point2, Point2) {
    let mut lo = Point2::new(f64::INFINITY, f64::INFINITY);
    let mut hi = Point2::new(f64::NEG_INFINITY, f64::NEG_INFINITY);
    for p in points {
        lo = Point2::new(lo.x.min(p.x), lo.y.min(p.y));
        hi = Point2::new(hi.x.max(p.x), hi.y.max(p.y));
    }
    (lo, hi)
}

/// Parameters `[qx, qy, p0, n]` and the box they are projected onto.
pub(super) type Bounds = BoxBounds<4>;

pub(super) fn log_distance(q: Point2, p: Point2) -> (f64, f64) {
    let d = (p - q).norm().max(REFERENCE_DISTANCE_M);
    (d, d.log10())
}

/// What one AP's fit sees: the readings, and the non-detections (censored below
/// `detection_dbm`, weighted by `weight`).
pub(super) struct FitData<'a> {
    heard: &'a [(Point2, f64)],
    silent: &'a [Point2],
    weight: f64,
    detection_dbm: f64,
}

impl FitData<'_> {
    /// Every active term as `(position, target, weight)`: readings always, a non-detection
    /// when predicted above the detection level.
    fn terms<'s>(&'s self, t: &'s [f64; 4]) -> impl Iterator<Item = (Point2, f64, f64)> + 's {
        let q = Point2::new(t[0], t[1]);
        let heard = self.heard.iter().map(|&(p, y)| (p, y, 1.0));
        let silent = self
            .silent
            .iter()
            .filter(move |&&p| t[2] - 10.0 * t[3] * log_distance(q, p).1 > self.detection_dbm)
            .map(|&p| (p, self.detection_dbm, self.weight));
        heard.chain(silent)
    }

    /// Calls `visit(r, J)` for every active term: the weighted residual
    /// `w (y - (p0 - 10 n log10 d))` and the derivatives of the weighted prediction.
    fn residuals(&self, t: &[f64; 4], visit: &mut dyn FnMut(f64, &[f64; 4])) {
        let ln10 = std::f64::consts::LN_10;
        let q = Point2::new(t[0], t[1]);
        for (p, y, w) in self.terms(t) {
            let raw = (p - q).norm();
            let (d, l) = log_distance(q, p);
            let r = y - (t[2] - 10.0 * t[3] * l);
            // d pred / d q = -10 n / ln 10 * (q - p) / d^2 (zero inside the reference distance).
            let (jx, jy) = if raw > REFERENCE_DISTANCE_M {
                let f = -10.0 * t[3] / (ln10 * d * d);
                (f * (q.x - p.x), f * (q.y - p.y))
            } else {
                (0.0, 0.0)
            };
            visit(w * r, &[w * jx, w * jy, w, -10.0 * w * l]);
        }
    }

    fn cost(&self, t: &[f64; 4]) -> f64 {
        let mut c = 0.0;
        self.residuals(t, &mut |r, _| c += r * r);
        c
    }

    /// Sum of squared residuals of the readings alone.
    fn heard_cost(&self, t: &[f64; 4]) -> f64 {
        FitData {
            heard: self.heard,
            silent: &[],
            weight: 0.0,
            detection_dbm: 0.0,
        }
        .cost(t)
    }
}

/// `p0` and `n` by linear least squares given the AP position (n clamped, p0 refitted).
pub(super) fn linear_p0_n(samples: &[(Point2, f64)], q: Point2, b: &Bounds) -> (f64, f64) {
    let k = samples.len() as f64;
    let xs: Vec<f64> = samples
        .iter()
        .map(|&(p, _)| -10.0 * log_distance(q, p).1)
        .collect();
    let mx = xs.iter().sum::<f64>() / k;
    let my = samples.iter().map(|s| s.1).sum::<f64>() / k;
    let sxx: f64 = xs.iter().map(|x| (x - mx).powi(2)).sum();
    let sxy: f64 = xs
        .iter()
        .zip(samples)
        .map(|(x, s)| (x - mx) * (s.1 - my))
        .sum();
    let n = if sxx > 1e-9 {
        sxy / sxx
    } else {
        0.5 * (b.lo[3] + b.hi[3])
    };
    let n = if n.is_finite() { n } else { b.lo[3] };
    let n = n.clamp(b.lo[3], b.hi[3]);
    let p0 = (my - n * mx).clamp(b.lo[2], b.hi[2]);
    (p0, n)
}

/// Levenberg-Marquardt from `t`, projected onto the bounds; returns the parameters and cost.
pub(super) fn levenberg_marquardt(
    data: &FitData<'_>,
    t: [f64; 4],
    b: &Bounds,
    max_iterations: usize,
) -> ([f64; 4], f64) {
    let cfg = LmConfig {
        max_iterations,
        ..LmConfig::default()
    };
    let out = fit::levenberg_marquardt(
        t,
        |t| b.project(t),
        &cfg,
        |t, visit| data.residuals(t, visit),
    );
    (out.params, out.cost)
}

pub(super) fn fit_one(data: &FitData<'_>, cfg: &PropagationConfig) -> Option<ApModel> {
    let samples = data.heard;
    let (lo, hi) = bbox(samples.iter().map(|s| s.0));
    let out = cfg.max_ap_outside_m;
    let bounds = Bounds {
        lo: [
            lo.x - out,
            lo.y - out,
            MIN_VALID_RSSI_DBM,
            cfg.exponent_range[0],
        ],
        hi: [
            hi.x + out,
            hi.y + out,
            MAX_VALID_RSSI_DBM,
            cfg.exponent_range[1],
        ],
    };
    // Starts: the power-weighted centroid of the strongest readings, and the strongest one.
    let mut by_strength: Vec<&(Point2, f64)> = samples.iter().collect();
    by_strength.sort_by(|a, b| b.1.total_cmp(&a.1));
    let strongest = &by_strength[..cfg.init_strongest.min(by_strength.len())];
    let top = strongest[0].1;
    let (mut wx, mut wy, mut ws) = (0.0, 0.0, 0.0);
    for &&(p, v) in strongest {
        // Relative to the strongest reading: no underflow, weight 1 for the strongest.
        let w = 10f64.powf((v - top) / 10.0);
        wx += w * p.x;
        wy += w * p.y;
        ws += w;
    }
    let centroid = Point2::new(wx / ws, wy / ws);
    let o = cfg.start_offset_m;
    let starts = [
        centroid,
        strongest[0].0,
        centroid + wipdr_core::Vector2::new(o, 0.0),
        centroid + wipdr_core::Vector2::new(-o, 0.0),
        centroid + wipdr_core::Vector2::new(0.0, o),
        centroid + wipdr_core::Vector2::new(0.0, -o),
    ];
    let mut best: Option<([f64; 4], f64)> = None;
    for q in starts {
        if !(q.x.is_finite() && q.y.is_finite()) {
            continue;
        }
        let (p0, n) = linear_p0_n(samples, q, &bounds);
        let t0 = bounds.project([q.x, q.y, p0, n]);
        let (t, c) = levenberg_marquardt(data, t0, &bounds, cfg.max_iterations);
        if c.is_finite() && best.is_none_or(|(_, bc)| c < bc) {
            best = Some((t, c));
        }
    }
    let (t, _) = best?;
    let c = data.heard_cost(&t);
    let model = ApModel {
        position: Point2::new(t[0], t[1]),
        p0_dbm: t[2],
        exponent: t[3],
        rmse_db: (c / samples.len() as f64).sqrt(),
        samples: samples.len(),
    };
    model.is_finite().then_some(model)
}
