//! The radio-map extension: synthesised reference points in the coverage gaps (see the
//! module doc of [`crate::propagation`]).

use super::ap_fit::*;
use super::*;

/// What [`extend_radio_map`] looked at, skipped and added.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
pub struct PropagationReport {
    /// AP models given (`Some`).
    pub models_fitted: usize,
    /// AP columns without a model (`None`).
    pub models_dropped: usize,
    /// Lattice points in the measured points' bounding box plus the margin.
    pub lattice_points: usize,
    /// Lattice points where `allowed` was false.
    pub points_not_allowed: usize,
    /// Lattice points closer than `min_gap_m` to a measured point.
    pub points_too_close: usize,
    /// Lattice points with fewer than `min_aps` trusted APs predicted at or above
    /// `min_predicted_dbm`.
    pub points_skipped_few_aps: usize,
    /// Reference points appended.
    pub points_added: usize,
    /// Heard entries written into the appended points.
    pub entries_added: usize,
    /// Appended points whose heard APs were cut to `max_aps`.
    pub points_capped: usize,
}

/// Appends synthesised reference points in the coverage gaps of `map` (see the module doc)
/// and returns what it did. `models` has one entry per AP column (from [`fit_ap_models`]);
/// `allowed(p)` says where a point may go (e.g. the floor plan's walkability). New points
/// are appended at the end of `map.points()`, so indices `>=` the length before the call are
/// the synthesised ones. A map without measured points is left as it is.
pub fn extend_radio_map(
    map: &mut RadioMap,
    models: &[Option<ApModel>],
    cfg: &PropagationConfig,
    allowed: impl Fn(Point2) -> bool + Sync,
) -> Result<PropagationReport, FingerprintError> {
    cfg.validate()?;
    let m = map.n_aps();
    if models.len() != m {
        return Err(FingerprintError::DimensionMismatch {
            expected: m,
            found: models.len(),
        });
    }
    if let Some(j) = models
        .iter()
        .position(|o| o.as_ref().is_some_and(|x| !x.is_finite()))
    {
        return Err(FingerprintError::InvalidInput(format!(
            "path-loss model of AP {} is not finite",
            map.vocabulary().name(j)
        )));
    }
    let mut report = PropagationReport {
        models_fitted: models.iter().filter(|o| o.is_some()).count(),
        models_dropped: models.iter().filter(|o| o.is_none()).count(),
        ..Default::default()
    };
    let measured: Vec<usize> = (0..map.len())
        .filter(|&i| {
            let p = map.point(i).position;
            map.point(i).scans > 0 && p.x.is_finite() && p.y.is_finite()
        })
        .collect();
    if measured.is_empty() {
        tracing::debug!("no measured reference point: nothing to extend");
        return Ok(report);
    }
    let (lo, hi) = bbox(measured.iter().map(|&i| map.point(i).position));
    let c = cfg.cell_m;
    let (i0, i1) = (
        ((lo.x - cfg.margin_m) / c).floor(),
        ((hi.x + cfg.margin_m) / c).ceil(),
    );
    let (j0, j1) = (
        ((lo.y - cfg.margin_m) / c).floor(),
        ((hi.y + cfg.margin_m) / c).ceil(),
    );
    let (nx, ny) = (i1 - i0 + 1.0, j1 - j0 + 1.0);
    if !(nx * ny).is_finite() || nx * ny > cfg.max_points as f64 {
        return Err(invalid(
            "propagation.max_points",
            format!(
                "the lattice has {} points (cell {c} m), over \
             propagation.max_points = {}",
                nx * ny,
                cfg.max_points
            ),
        ));
    }
    let (i0, j0, nx, ny) = (i0 as i64, j0 as i64, nx as usize, ny as usize);
    report.lattice_points = nx * ny;
    let cell_position = |k: usize| {
        let (i, j) = ((k / ny) as i64 + i0, (k % ny) as i64 + j0);
        Point2::new(i as f64 * c, j as f64 * c)
    };
    // Nearest measured point of each lattice point, by buckets of side `bucket`.
    let positions: Vec<Point2> = measured.iter().map(|&i| map.point(i).position).collect();
    let grid = Buckets::new(&positions, cfg.min_gap_m.max(c));
    #[derive(Clone, Copy)]
    enum Cell {
        NotAllowed,
        TooClose,
        Candidate(usize), // the nearest measured point, index into `measured`
    }
    let cells: Vec<Cell> = (0..nx * ny)
        .into_par_iter()
        .map(|k| {
            let p = cell_position(k);
            if !allowed(p) {
                return Cell::NotAllowed;
            }
            match grid.nearest(&positions, p) {
                Some((_, d)) if d < cfg.min_gap_m => Cell::TooClose,
                Some((nearest, _)) => Cell::Candidate(nearest),
                None => Cell::Candidate(grid.nearest_brute(&positions, p)),
            }
        })
        .collect();
    // Per AP: the candidate cells within max_extrapolation_m of a hearing point, with the
    // prediction where it reaches min_predicted_dbm.
    let hearing = samples_per_ap(map);
    let r = cfg.max_extrapolation_m;
    let per_ap: Vec<Vec<(u32, f32)>> = models
        .par_iter()
        .zip(&hearing)
        .map(|(model, heard_at)| {
            let Some(model) = model else {
                return Vec::new();
            };
            let mut seen = vec![false; nx * ny];
            let mut out = Vec::new();
            for &(p, _) in heard_at {
                let ia = (((p.x - r) / c).ceil() as i64 - i0).max(0);
                let ib = (((p.x + r) / c).floor() as i64 - i0).min(nx as i64 - 1);
                let ja = (((p.y - r) / c).ceil() as i64 - j0).max(0);
                let jb = (((p.y + r) / c).floor() as i64 - j0).min(ny as i64 - 1);
                for i in ia..=ib {
                    for j in ja..=jb {
                        let k = i as usize * ny + j as usize;
                        if seen[k] || !matches!(cells[k], Cell::Candidate(_)) {
                            continue;
                        }
                        let q = cell_position(k);
                        if (q - p).norm() > r {
                            continue;
                        }
                        seen[k] = true;
                        let v = model.predict(q);
                        if v.is_finite() && v >= cfg.min_predicted_dbm {
                            out.push((k as u32, v.min(MAX_VALID_RSSI_DBM) as f32));
                        }
                    }
                }
            }
            out
        })
        .collect();
    // Gather per cell: (column, dBm).
    let mut heard_in: Vec<Vec<(usize, f32)>> = vec![Vec::new(); nx * ny];
    for (j, list) in per_ap.into_iter().enumerate() {
        for (k, v) in list {
            heard_in[k as usize].push((j, v));
        }
    }
    let mut mean = vec![None; m];
    let mut counts = vec![0u16; m];
    let mut spread = vec![0f32; m];
    for (k, cell) in cells.iter().enumerate() {
        let nearest = match *cell {
            Cell::NotAllowed => {
                report.points_not_allowed += 1;
                continue;
            }
            Cell::TooClose => {
                report.points_too_close += 1;
                continue;
            }
            Cell::Candidate(nearest) => nearest,
        };
        let heard = &mut heard_in[k];
        if heard.len() < cfg.min_aps {
            report.points_skipped_few_aps += 1;
            continue;
        }
        if let Some(cap) = cfg.max_aps
            && heard.len() > cap
        {
            // The strongest `cap`, ties by column.
            heard.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
            heard.truncate(cap);
            report.points_capped += 1;
        }
        mean.fill(None);
        counts.fill(0);
        spread.fill(0.0);
        for &(j, v) in heard.iter() {
            mean[j] = Some(v);
            counts[j] = 1;
            spread[j] = models[j].map_or(0.0, |x| x.rmse_db as f32);
        }
        let point = ReferencePoint {
            position: cell_position(k),
            scans: 0,
            ..map.points()[measured[nearest]]
        };
        map.push_point(point, &mean, Some((&counts, &spread)))?;
        report.points_added += 1;
        report.entries_added += heard.len();
    }
    tracing::debug!(?report, "path-loss radio-map extension");
    Ok(report)
}

/// Square buckets of points, for nearest-point queries within a few buckets.
pub(super) struct Buckets {
    side: f64,
    map: std::collections::HashMap<(i64, i64), Vec<usize>>,
}

impl Buckets {
    fn new(points: &[Point2], side: f64) -> Self {
        let mut map: std::collections::HashMap<(i64, i64), Vec<usize>> = Default::default();
        for (i, &p) in points.iter().enumerate() {
            map.entry(Self::key(side, p)).or_default().push(i);
        }
        Self { side, map }
    }

    fn key(side: f64, p: Point2) -> (i64, i64) {
        ((p.x / side).floor() as i64, (p.y / side).floor() as i64)
    }

    /// The nearest point among the 3x3 buckets around `p` (exact for distances < `side`),
    /// with its distance; `None` if those buckets are empty (then every point is >= `side`
    /// away).
    fn nearest(&self, points: &[Point2], p: Point2) -> Option<(usize, f64)> {
        let (bi, bj) = Self::key(self.side, p);
        let mut best: Option<(usize, f64)> = None;
        for di in -1..=1 {
            for dj in -1..=1 {
                for &k in self.map.get(&(bi + di, bj + dj)).into_iter().flatten() {
                    let d = (points[k] - p).norm();
                    if best.is_none_or(|(_, bd)| d < bd) {
                        best = Some((k, d));
                    }
                }
            }
        }
        // A point found farther than `side` may not be the nearest: fall back to brute force.
        match best {
            Some((_, d)) if d >= self.side => Some((self.nearest_brute(points, p), d)),
            b => b,
        }
    }

    fn nearest_brute(&self, points: &[Point2], p: Point2) -> usize {
        (0..points.len())
            .min_by(|&a, &b| (points[a] - p).norm().total_cmp(&(points[b] - p).norm()))
            .unwrap_or(0)
    }
}
