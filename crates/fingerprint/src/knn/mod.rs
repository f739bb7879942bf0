//! NN, KNN and WKNN by fast brute force (paper 000 eq. 3-4, paper 001 eq. 7, paper 002
//! eq. 1-3).
//!
//! Two exact engines, picked from the configuration:
//!
//! - **sparse** (Manhattan, Euclidean, squared Euclidean, Sørensen and the shared-AP distance
//!   in the `raw`, `positive` and `powed` representations, where "not heard" is 0): the map is
//!   stored AP-major as lists of the points that heard each AP. A query touches only the
//!   lists of its heard APs and accumulates the shared-AP term; the rest follows from
//!   precomputed per-point norms (`|x - y|^2 = |x|^2 + |y|^2 - 2 x.y`, and
//!   `|x - y|_1 = |x|_1 + |y|_1 - sum_shared(|x| + |y| - |x - y|)`; shared-AP needs only the
//!   shared count and `sum |x - y|` over shared APs).
//!   On UJI1 a query reads ~3 % of the dense matrix. A point-major copy of the same lists
//!   serves searches over a subset of the points ([`KnnMatcher::locate_among`], used by the
//!   indexed matchers).
//! - **dense** (every metric): an f32 row-major matrix padded to 8 lanes, scanned with
//!   auto-vectorised loops.
//!
//! Batches run in parallel with rayon; [`KnnMatcher::locate_batch_gemm`] computes a Euclidean
//! batch as one matrix product `|x|^2 + |y|^2 - 2 X Y^T` with faer. Top-k is
//! `select_nth_unstable_by` on (distance, index), so ties resolve to the lower map index.

use crate::distance::{Metric, Representation, SparseFingerprint, Transform};
use crate::matcher::{Matcher, Weighting, majority, observation_from_neighbours};
use crate::{FingerprintError, Query, RadioMap};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::sync::Arc;
use wipdr_core::WifiObservation;

/// Settings of a brute-force k-NN matcher.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct KnnConfig {
    /// Number of neighbours K (paper 001: 3-5; 1 = NN).
    pub k: usize,
    /// Candidate weighting (uniform = KNN, inverse distance = WKNN).
    pub weighting: Weighting,
    /// Signal distance.
    pub metric: Metric,
    /// Data representation.
    pub representation: Representation,
}

impl Default for KnnConfig {
    fn default() -> Self {
        Self {
            k: 5,
            weighting: Weighting::InverseDistance { power: 1.0 },
            metric: Metric::Euclidean,
            representation: Representation::Raw,
        }
    }
}

impl KnnConfig {
    /// 1-NN, Euclidean, raw.
    pub fn nn() -> Self {
        Self {
            k: 1,
            weighting: Weighting::Uniform,
            ..Self::default()
        }
    }

    /// Plain KNN (uniform weights), Euclidean, raw.
    pub fn knn(k: usize) -> Self {
        Self {
            k,
            weighting: Weighting::Uniform,
            ..Self::default()
        }
    }

    /// WKNN with `1/d^power` weights, Euclidean, raw.
    pub fn wknn(k: usize, power: f64) -> Self {
        Self {
            k,
            weighting: Weighting::InverseDistance { power },
            ..Self::default()
        }
    }

    /// A descriptive name, e.g. `wknn(k=5,w=1,euclidean,raw)`.
    pub fn describe(&self) -> String {
        let base = match (self.k, self.weighting) {
            (1, _) => "nn".to_string(),
            (k, Weighting::Uniform) => format!("knn(k={k}"),
            (k, Weighting::InverseDistance { power }) => format!("wknn(k={k},w={power}"),
        };
        let sep = if self.k == 1 { "(" } else { "," };
        format!(
            "{base}{sep}{},{})",
            self.metric.name(),
            self.representation.name()
        )
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum SparseKind {
    Euclidean,
    Squared,
    Manhattan,
    Sorensen,
    /// [`SharedAp`](crate::distance::SharedAp) with its `lambda`: per point the shared-AP
    /// count and `sum |q - x|` accumulate over the query's lists; heard = value > 0.
    SharedAp(f32),
    /// [`SharedAp`](crate::distance::SharedAp) with its common-offset removal or detection
    /// weighting on: per point, a merge of the query's and the point's heard lists
    /// ([`SharedAp::eval_sparse`](crate::distance::SharedAp::eval_sparse)), bit-identical to
    /// the dense evaluation.
    SharedApWeighted(crate::distance::SharedAp),
}

#[derive(Debug)]
enum Engine {
    Sparse {
        kind: SparseKind,
        /// CSR over APs: `offsets[j]..offsets[j+1]` index `points` / `values`.
        offsets: Vec<usize>,
        points: Vec<u32>,
        values: Vec<f32>,
        /// Per point: `sum x^2` (Euclidean) or `sum |x|` (Manhattan) or `sum x` (Sørensen).
        norms: Vec<f32>,
        /// Per point `sum |x|`, Sørensen's numerator part.
        abs_norms: Vec<f32>,
        /// The same values point-major (CSR over points: `row_offsets[i]..row_offsets[i+1]`
        /// index `row_columns` / `row_values`), for searches over a subset of the points
        /// ([`KnnMatcher::locate_among`]).
        row_offsets: Vec<usize>,
        row_columns: Vec<u32>,
        row_values: Vec<f32>,
        /// Aligned with `row_values` for [`SparseKind::SharedApWeighted`]: each value's
        /// one-sided weight; empty for the other kinds.
        row_weights: Vec<f32>,
    },
    Dense {
        /// Row-major `n x stride`, padded with 0.
        matrix: Vec<f32>,
        stride: usize,
    },
}

/// A brute-force NN / KNN / WKNN matcher over a shared radio map.
///
/// ```
/// use wipdr_fingerprint::{KnnConfig, KnnMatcher, Matcher, Query, QueryFilter, RadioMap, RadioMapConfig};
/// use wipdr_core::{FingerprintLabel, FingerprintTable};
/// let mut table = FingerprintTable::new(vec!["ap_000".into(), "ap_001".into()]);
/// table.push_row(&[-50.0, -80.0], FingerprintLabel::at(0.0, 0.0, 0)).unwrap();
/// table.push_row(&[-80.0, -50.0], FingerprintLabel::at(10.0, 0.0, 1)).unwrap();
/// let map = RadioMap::from_table(&table, RadioMapConfig::default()).unwrap();
/// let m = KnnMatcher::new(map, KnnConfig::nn()).unwrap();
/// let q = Query::from_row(&[-52.0, -79.0], m.map(), &QueryFilter::default()).unwrap();
/// let obs = m.locate(&q).unwrap();
/// assert_eq!(obs.estimate.x, 0.0);
/// assert_eq!(obs.floor, Some(0));
/// ```
#[derive(Debug)]
pub struct KnnMatcher {
    map: Arc<RadioMap>,
    config: KnnConfig,
    transform: Transform,
    engine: Engine,
}

impl KnnMatcher {
    /// Builds the matcher and its compact layout. Errors on an empty map or `k = 0`.
    pub fn new(map: impl Into<Arc<RadioMap>>, config: KnnConfig) -> Result<Self, FingerprintError> {
        let map = map.into();
        if map.is_empty() {
            return Err(FingerprintError::EmptyMap);
        }
        if config.k == 0 {
            return Err(FingerprintError::InvalidConfig(
                wipdr_core::ConfigError::new("k", "must be >= 1"),
            ));
        }
        if let Weighting::InverseDistance { power } = config.weighting
            && !(power.is_finite() && power >= 0.0)
        {
            return Err(FingerprintError::InvalidConfig(
                wipdr_core::ConfigError::new(
                    "weighting.power",
                    format!("must be finite and >= 0, got {power}"),
                ),
            ));
        }
        if let Metric::SharedAp(d) = config.metric
            && !(d.lambda.is_finite()
                && d.lambda >= 0.0
                && d.max_offset_db.is_finite()
                && d.max_offset_db >= 0.0
                && d.detection_mid_db.is_finite()
                && d.detection_mid_db >= 0.0)
        {
            return Err(FingerprintError::InvalidConfig(
                wipdr_core::ConfigError::new(
                    "distance",
                    format!(
                        "shared_ap lambda, max_offset_db and detection_mid_db must be finite and >= 0, got {}, {} and {}",
                        d.lambda, d.max_offset_db, d.detection_mid_db
                    ),
                ),
            ));
        }
        let transform = Transform::new(
            config.representation,
            map.not_heard_dbm(),
            map.min_heard_rss(),
        );
        let sparse_kind = match (config.metric, transform.null_value() == 0.0) {
            (_, false) => None,
            (Metric::Euclidean, true) => Some(SparseKind::Euclidean),
            (Metric::SquaredEuclidean, true) => Some(SparseKind::Squared),
            (Metric::Manhattan, true) => Some(SparseKind::Manhattan),
            (Metric::Sorensen, true) => Some(SparseKind::Sorensen),
            (Metric::SharedAp(d), true) if d.max_offset_db == 0.0 && d.detection_mid_db == 0.0 => {
                Some(SparseKind::SharedAp(d.lambda))
            }
            // The offset removal and the detection weighting: a merge of heard lists.
            (Metric::SharedAp(d), true) => Some(SparseKind::SharedApWeighted(d)),
            _ => None,
        };
        let engine = match sparse_kind {
            Some(kind) => build_sparse(&map, &transform, kind),
            None => build_dense(&map, &transform),
        };
        Ok(Self {
            map,
            config,
            transform,
            engine,
        })
    }

    /// The configuration.
    pub fn config(&self) -> &KnnConfig {
        &self.config
    }

    /// The shared map.
    pub fn shared_map(&self) -> &Arc<RadioMap> {
        &self.map
    }

    /// Whether the sparse (AP-major) engine is in use.
    pub fn is_sparse(&self) -> bool {
        matches!(self.engine, Engine::Sparse { .. })
    }

    /// The query in representation space, dense over the map's columns (no padding).
    fn transformed_query(&self, query: &Query) -> Result<Vec<f32>, FingerprintError> {
        let m = self.map.n_aps();
        let null = self.transform.null_value();
        let mut v = vec![null; m];
        for &(j, r) in &query.heard {
            let j = j as usize;
            if j >= m {
                return Err(FingerprintError::DimensionMismatch {
                    expected: m,
                    found: j + 1,
                });
            }
            v[j] = self.transform.apply(Some(r));
        }
        Ok(v)
    }

    /// Signal distances from `query` to every reference point, in map order (f32, as computed
    /// by the engine).
    pub fn distances(&self, query: &Query) -> Result<Vec<f32>, FingerprintError> {
        let q = self.transformed_query(query)?;
        let mut out = vec![0f32; self.map.len()];
        self.distances_into(&q, &mut out);
        if self.squared_keys() {
            out.iter_mut().for_each(|d| *d = d.sqrt());
        }
        Ok(out)
    }

    /// Locates `query` among the reference points `candidates` only (map indices), with the
    /// same distances as the brute force (so over the whole map it equals
    /// [`Matcher::locate`]). The sparse engine reads the candidates' rows of a point-major copy
    /// of its compact layout (cost: the candidates' heard APs, not the map); the dense engine
    /// scans the candidates' rows. Ties go to the candidate listed first, so ascending
    /// candidates resolve ties by map index as the brute force does. `visited` is reported as
    /// given (the caller may count more than the rows compared here, e.g. cluster centres).
    ///
    /// Errors: [`FingerprintError::EmptyMap`] for no candidate,
    /// [`FingerprintError::InvalidInput`] for an index outside the map.
    pub fn locate_among(
        &self,
        query: &Query,
        candidates: &[u32],
        visited: usize,
    ) -> Result<WifiObservation, FingerprintError> {
        let mut keys = Vec::with_capacity(candidates.len());
        let q = self.transformed_query(query)?;
        self.candidate_keys(&q, candidates, &mut keys)?;
        let mut nb = top_k(&keys, self.config.k);
        for (i, d) in nb.iter_mut() {
            *i = candidates[*i] as usize;
            if self.squared_keys() {
                *d = d.sqrt();
            }
        }
        observation_from_neighbours(&self.map, query, &nb, self.config.weighting, visited)
    }

    /// Rank keys (as [`Self::distances_into`]) of the `candidates` rows, in candidate order.
    fn candidate_keys(
        &self,
        q: &[f32],
        candidates: &[u32],
        out: &mut Vec<f32>,
    ) -> Result<(), FingerprintError> {
        if candidates.is_empty() {
            return Err(FingerprintError::EmptyMap);
        }
        let n = self.map.len();
        if let Some(&bad) = candidates.iter().find(|&&i| i as usize >= n) {
            return Err(FingerprintError::InvalidInput(format!(
                "candidate {bad} outside a radio map of {n} points"
            )));
        }
        out.clear();
        match &self.engine {
            Engine::Sparse {
                kind: SparseKind::SharedApWeighted(d),
                row_offsets,
                row_columns,
                row_values,
                row_weights,
                ..
            } => {
                let query = SparseQuery::new(q, d);
                let row =
                    |i: usize| sparse_row(row_offsets, row_columns, row_values, row_weights, i);
                out.extend(
                    candidates
                        .iter()
                        .map(|&i| d.eval_sparse(query.side(), row(i as usize))),
                );
            }
            Engine::Sparse {
                kind: SparseKind::SharedAp(lambda),
                norms,
                row_offsets,
                row_columns,
                row_values,
                ..
            } => {
                let q_heard = q.iter().filter(|&&v| v > 0.0).count() as u32;
                for &i in candidates {
                    let i = i as usize;
                    let range = row_offsets[i]..row_offsets[i + 1];
                    let (mut sum, mut shared) = (0f32, 0u32);
                    for (&j, &x) in row_columns[range.clone()].iter().zip(&row_values[range]) {
                        let qv = q[j as usize];
                        if qv > 0.0 {
                            sum += (qv - x).abs();
                            shared += 1;
                        }
                    }
                    out.push(shared_ap_from_counts(
                        *lambda, sum, shared, q_heard, norms[i],
                    ));
                }
            }
            Engine::Sparse {
                kind,
                norms,
                abs_norms,
                row_offsets,
                row_columns,
                row_values,
                ..
            } => {
                let (mut q_norm, mut q_abs) = (0f32, 0f32);
                for &qv in q.iter().filter(|&&v| v != 0.0) {
                    q_abs += qv.abs();
                    q_norm += match kind {
                        SparseKind::Euclidean | SparseKind::Squared => qv * qv,
                        SparseKind::Manhattan => qv.abs(),
                        SparseKind::Sorensen => qv,
                        // Handled by the arms above.
                        SparseKind::SharedAp(_) | SparseKind::SharedApWeighted(_) => 0.0,
                    };
                }
                for &i in candidates {
                    let i = i as usize;
                    let range = row_offsets[i]..row_offsets[i + 1];
                    let (cols, vals) = (&row_columns[range.clone()], &row_values[range]);
                    let key = match kind {
                        SparseKind::Euclidean | SparseKind::Squared => {
                            let dot: f32 = cols
                                .iter()
                                .zip(vals)
                                .map(|(&j, &x)| q[j as usize] * x)
                                .sum();
                            (q_norm + norms[i] - 2.0 * dot).max(0.0)
                        }
                        SparseKind::Manhattan | SparseKind::Sorensen => {
                            // |q| + |x| - |q - x| is 0 where the query did not hear the AP.
                            let shared: f32 = cols
                                .iter()
                                .zip(vals)
                                .map(|(&j, &x)| {
                                    let qv = q[j as usize];
                                    qv.abs() + x.abs() - (qv - x).abs()
                                })
                                .sum();
                            if *kind == SparseKind::Manhattan {
                                (q_norm + norms[i] - shared).max(0.0)
                            } else {
                                sorensen_from_shared(q_norm, q_abs, norms[i], abs_norms[i], shared)
                            }
                        }
                        // Handled by the arms above.
                        SparseKind::SharedAp(_) | SparseKind::SharedApWeighted(_) => 0.0,
                    };
                    out.push(key);
                }
            }
            Engine::Dense { matrix, stride } => {
                let mut qp = vec![0f32; *stride];
                qp[..q.len()].copy_from_slice(q);
                let null = self.transform.null_value();
                let metric = self.config.metric;
                out.extend(candidates.iter().map(|&i| {
                    let start = i as usize * stride;
                    metric.eval(&qp, &matrix[start..start + stride], null)
                }));
            }
        }
        Ok(())
    }

    /// Whether the engine's rank keys are squared Euclidean distances standing for Euclidean
    /// ones (the square root is taken for the K winners only).
    fn squared_keys(&self) -> bool {
        matches!(
            self.engine,
            Engine::Sparse {
                kind: SparseKind::Euclidean,
                ..
            }
        )
    }

    fn distances_into(&self, q: &[f32], out: &mut [f32]) {
        match &self.engine {
            Engine::Sparse {
                kind: SparseKind::SharedApWeighted(d),
                row_offsets,
                row_columns,
                row_values,
                row_weights,
                ..
            } => {
                let query = SparseQuery::new(q, d);
                for (i, o) in out.iter_mut().enumerate() {
                    let row = sparse_row(row_offsets, row_columns, row_values, row_weights, i);
                    *o = d.eval_sparse(query.side(), row);
                }
            }
            Engine::Sparse {
                kind: SparseKind::SharedAp(lambda),
                offsets,
                points,
                values,
                norms,
                ..
            } => {
                out.fill(0.0);
                let mut shared = vec![0u32; out.len()];
                let mut q_heard = 0u32;
                for (j, &qv) in q.iter().enumerate() {
                    if qv <= 0.0 {
                        continue;
                    }
                    q_heard += 1;
                    let range = offsets[j]..offsets[j + 1];
                    for (&i, &x) in points[range.clone()].iter().zip(&values[range]) {
                        out[i as usize] += (qv - x).abs();
                        shared[i as usize] += 1;
                    }
                }
                for ((o, &c), &n) in out.iter_mut().zip(&shared).zip(norms) {
                    *o = shared_ap_from_counts(*lambda, *o, c, q_heard, n);
                }
            }
            Engine::Sparse {
                kind,
                offsets,
                points,
                values,
                norms,
                abs_norms,
                ..
            } => {
                out.fill(0.0);
                let (mut q_norm, mut q_abs) = (0f32, 0f32);
                for (j, &qv) in q.iter().enumerate() {
                    if qv == 0.0 {
                        continue;
                    }
                    q_abs += qv.abs();
                    q_norm += match kind {
                        SparseKind::Euclidean | SparseKind::Squared => qv * qv,
                        SparseKind::Manhattan => qv.abs(),
                        SparseKind::Sorensen => qv,
                        // Handled by the arms above.
                        SparseKind::SharedAp(_) | SparseKind::SharedApWeighted(_) => 0.0,
                    };
                    let range = offsets[j]..offsets[j + 1];
                    let (ps, vs) = (&points[range.clone()], &values[range]);
                    match kind {
                        SparseKind::Euclidean | SparseKind::Squared => {
                            for (&i, &x) in ps.iter().zip(vs) {
                                out[i as usize] += qv * x;
                            }
                        }
                        SparseKind::Manhattan | SparseKind::Sorensen => {
                            for (&i, &x) in ps.iter().zip(vs) {
                                out[i as usize] += qv.abs() + x.abs() - (qv - x).abs();
                            }
                        }
                        SparseKind::SharedAp(_) | SparseKind::SharedApWeighted(_) => {}
                    }
                }
                match kind {
                    SparseKind::Euclidean | SparseKind::Squared => {
                        for (o, &n) in out.iter_mut().zip(norms) {
                            *o = (q_norm + n - 2.0 * *o).max(0.0);
                        }
                    }
                    SparseKind::Manhattan => {
                        for (o, &n) in out.iter_mut().zip(norms) {
                            *o = (q_norm + n - *o).max(0.0);
                        }
                    }
                    SparseKind::Sorensen => {
                        for ((o, &s), &a) in out.iter_mut().zip(norms).zip(abs_norms) {
                            *o = sorensen_from_shared(q_norm, q_abs, s, a, *o);
                        }
                    }
                    SparseKind::SharedAp(_) | SparseKind::SharedApWeighted(_) => {}
                }
            }
            Engine::Dense { matrix, stride } => {
                let mut qp = vec![0f32; *stride];
                qp[..q.len()].copy_from_slice(q);
                let null = self.transform.null_value();
                let metric = self.config.metric;
                for (o, row) in out.iter_mut().zip(matrix.chunks_exact(*stride)) {
                    *o = metric.eval(&qp, row, null);
                }
            }
        }
    }

    /// The `k` nearest `(index, distance)` pairs of a distance vector, sorted by distance
    /// then index. NaN distances (impossible for valid maps) sort last.
    fn top_k(&self, keys: &[f32]) -> Vec<(usize, f64)> {
        let mut nb = top_k(keys, self.config.k);
        if self.squared_keys() {
            nb.iter_mut().for_each(|(_, d)| *d = d.sqrt());
        }
        nb
    }

    /// Locates a batch of Euclidean (raw) queries with one matrix product per chunk of
    /// queries (faer), in parallel. Other configurations fall back to
    /// [`Matcher::locate_batch`].
    pub fn locate_batch_gemm(
        &self,
        queries: &[Query],
    ) -> Vec<Result<WifiObservation, FingerprintError>> {
        if !matches!(
            self.config.metric,
            Metric::Euclidean | Metric::SquaredEuclidean
        ) {
            return self.locate_batch(queries);
        }
        let n = self.map.len();
        let m = self.map.n_aps();
        // Reference matrix in representation space (not heard = 0), f32.
        let reference = self.dense_reference();
        let ref_norms: Vec<f32> = reference
            .chunks_exact(m.max(1))
            .map(|r| r.iter().map(|x| x * x).sum())
            .collect();
        let x = faer::Mat::<f32>::from_fn(n, m, |i, j| reference[i * m + j]);
        const CHUNK: usize = 256;
        let chunks: Vec<&[Query]> = queries.chunks(CHUNK).collect();
        chunks
            .par_iter()
            .flat_map_iter(|chunk| {
                let b = chunk.len();
                let transformed: Vec<Result<Vec<f32>, FingerprintError>> =
                    chunk.iter().map(|q| self.transformed_query(q)).collect();
                let y = faer::Mat::<f32>::from_fn(m, b, |j, c| match &transformed[c] {
                    Ok(v) => v[j],
                    Err(_) => 0.0,
                });
                let mut dots = faer::Mat::<f32>::zeros(n, b);
                faer::linalg::matmul::matmul(
                    dots.as_mut(),
                    faer::Accum::Replace,
                    x.as_ref(),
                    y.as_ref(),
                    1.0f32,
                    faer::Par::Seq,
                );
                let squared = self.config.metric == Metric::SquaredEuclidean;
                let mut out = Vec::with_capacity(b);
                let mut dist = vec![0f32; n];
                for (c, (query, t)) in chunk.iter().zip(&transformed).enumerate() {
                    let qv = match t {
                        Ok(v) => v,
                        Err(e) => {
                            out.push(Err(e.clone()));
                            continue;
                        }
                    };
                    let q_norm: f32 = qv.iter().map(|x| x * x).sum();
                    let col = dots.col(c);
                    for (i, d) in dist.iter_mut().enumerate() {
                        let d2 = (q_norm + ref_norms[i] - 2.0 * col[i]).max(0.0);
                        *d = if squared { d2 } else { d2.sqrt() };
                    }
                    let nb = top_k(&dist, self.config.k);
                    out.push(observation_from_neighbours(
                        &self.map,
                        query,
                        &nb,
                        self.config.weighting,
                        n,
                    ));
                }
                out
            })
            .collect()
    }

    fn dense_reference(&self) -> Vec<f32> {
        let n = self.map.len();
        let m = self.map.n_aps();
        let mut out = Vec::with_capacity(n * m);
        for i in 0..n {
            for j in 0..m {
                out.push(self.transform.apply(self.map.rss(i, j)));
            }
        }
        out
    }
}

/// Floor-first k-NN: the floor by majority of the `votes` nearest reference points (over
/// every floor), then the brute-force k-NN of the inner matcher over the points of that floor
/// only (two-stage floor-then-position matching). Exact: both stages read one distance
/// vector. Maps without floors behave as the plain matcher.
#[derive(Debug)]
pub struct FloorFirstMatcher {
    inner: KnnMatcher,
    votes: usize,
}

impl FloorFirstMatcher {
    /// Wraps `inner`; `votes` (at least 1) neighbours choose the floor.
    pub fn new(inner: KnnMatcher, votes: usize) -> Result<Self, FingerprintError> {
        if votes == 0 {
            return Err(FingerprintError::InvalidConfig(
                wipdr_core::ConfigError::new("floor_votes", "floor-first: votes must be >= 1"),
            ));
        }
        Ok(Self { inner, votes })
    }
}

impl Matcher for FloorFirstMatcher {
    fn name(&self) -> String {
        format!("floor-first(votes={},{})", self.votes, self.inner.name())
    }

    fn map(&self) -> &RadioMap {
        self.inner.map()
    }

    fn locate(&self, query: &Query) -> Result<WifiObservation, FingerprintError> {
        let m = &self.inner;
        let q = m.transformed_query(query)?;
        let mut keys = vec![0f32; m.map.len()];
        m.distances_into(&q, &mut keys);
        let voters = top_k(&keys, self.votes);
        let floor = majority(voters.iter().map(|&(i, _)| m.map.point(i).floor));
        if floor.is_some() {
            for (key, p) in keys.iter_mut().zip(m.map.points()) {
                if p.floor != floor {
                    *key = f32::INFINITY;
                }
            }
        }
        let mut nb = m.top_k(&keys);
        nb.retain(|&(_, d)| d.is_finite());
        observation_from_neighbours(&m.map, query, &nb, m.config.weighting, m.map.len())
    }
}

/// Sørensen (Bray-Curtis) distance `sum |q - x| / sum (q + x)` from the query's and the
/// point's sums and the shared-AP term `sum (|q| + |x| - |q - x|)`; 0 when both are empty.
#[inline]
fn sorensen_from_shared(q_sum: f32, q_abs: f32, x_sum: f32, x_abs: f32, shared: f32) -> f32 {
    let num = (q_abs + x_abs - shared).max(0.0);
    let den = q_sum + x_sum;
    if den > 0.0 { num / den } else { 0.0 }
}

/// [`SharedAp`](crate::distance::SharedAp) from the sparse sums: `sum` of `|q - x|` over the
/// `shared` APs, `q_heard` and `x_heard` APs heard by each side (as the dense definition:
/// mean over shared, [`SHARED_AP_NONE`](crate::distance::SHARED_AP_NONE) when none, plus
/// `lambda * (union - shared) / union`; 0 when neither heard anything).
#[inline]
fn shared_ap_from_counts(lambda: f32, sum: f32, shared: u32, q_heard: u32, x_heard: f32) -> f32 {
    let union = q_heard + x_heard as u32 - shared;
    if union == 0 {
        return 0.0;
    }
    let mean = if shared > 0 {
        sum / shared as f32
    } else {
        crate::distance::SHARED_AP_NONE
    };
    mean + lambda * (union - shared) as f32 / union as f32
}

/// The `k` smallest `(index, distance)` of `dist`, sorted by distance then index.
pub fn top_k(dist: &[f32], k: usize) -> Vec<(usize, f64)> {
    if k <= SMALL_K {
        return top_k_small(dist, k);
    }
    let mut idx: Vec<(f32, u32)> = dist
        .iter()
        .enumerate()
        .map(|(i, &d)| (if d.is_nan() { f32::INFINITY } else { d }, i as u32))
        .collect();
    let k = k.min(idx.len());
    if k == 0 {
        return Vec::new();
    }
    let cmp = |a: &(f32, u32), b: &(f32, u32)| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1));
    if k < idx.len() {
        idx.select_nth_unstable_by(k - 1, cmp);
        idx.truncate(k);
    }
    idx.sort_unstable_by(cmp);
    idx.into_iter()
        .map(|(d, i)| (i as usize, f64::from(d)))
        .collect()
}

/// Up to this k, top-k keeps a sorted array while scanning once (one comparison per point).
const SMALL_K: usize = 64;

fn top_k_small(dist: &[f32], k: usize) -> Vec<(usize, f64)> {
    let mut best: Vec<(f32, u32)> = Vec::with_capacity(k + 1);
    if k == 0 {
        return Vec::new();
    }
    let mut worst = f32::INFINITY;
    for (i, &d) in dist.iter().enumerate() {
        let d = if d.is_nan() { f32::INFINITY } else { d };
        // Strictly smaller than the current k-th: equal keys keep the lower index.
        if best.len() < k || d < worst {
            let pos = best.partition_point(|&(b, _)| b <= d);
            best.insert(pos, (d, i as u32));
            if best.len() > k {
                best.pop();
            }
            if best.len() == k {
                worst = best[k - 1].0;
            }
        }
    }
    best.into_iter()
        .map(|(d, i)| (i as usize, f64::from(d)))
        .collect()
}

fn build_sparse(map: &RadioMap, t: &Transform, kind: SparseKind) -> Engine {
    let (n, m) = (map.len(), map.n_aps());
    let mut per_ap: Vec<Vec<(u32, f32)>> = vec![Vec::new(); m];
    let mut norms = vec![0f32; n];
    let mut abs_norms = vec![0f32; n];
    for i in 0..n {
        for (j, v) in map.heard(i) {
            let x = t.apply(Some(v));
            // Shared-AP's "heard" is a value above the null (0); other kinds keep any non-zero.
            let shared_ap = matches!(
                kind,
                SparseKind::SharedAp(_) | SparseKind::SharedApWeighted(_)
            );
            if x == 0.0 || (shared_ap && x < 0.0) {
                continue;
            }
            per_ap[j].push((i as u32, x));
            norms[i] += match kind {
                SparseKind::Euclidean | SparseKind::Squared => x * x,
                SparseKind::Manhattan => x.abs(),
                SparseKind::Sorensen => x,
                SparseKind::SharedAp(_) | SparseKind::SharedApWeighted(_) => 1.0,
            };
            abs_norms[i] += x.abs();
        }
    }
    let mut offsets = Vec::with_capacity(m + 1);
    let mut points = Vec::new();
    let mut values = Vec::new();
    offsets.push(0);
    let mut per_point: Vec<Vec<(u32, f32)>> = vec![Vec::new(); n];
    for (j, list) in per_ap.into_iter().enumerate() {
        for (i, x) in list {
            points.push(i);
            values.push(x);
            per_point[i as usize].push((j as u32, x));
        }
        offsets.push(points.len());
    }
    let weight = |x: f32| match kind {
        SparseKind::SharedApWeighted(d) => Some(d.one_sided_weight(x, 0.0)),
        _ => None,
    };
    let mut row_weights = Vec::new();
    let mut row_offsets = Vec::with_capacity(n + 1);
    let mut row_columns = Vec::with_capacity(points.len());
    let mut row_values = Vec::with_capacity(points.len());
    row_offsets.push(0);
    for list in per_point {
        for (j, x) in list {
            row_columns.push(j);
            row_values.push(x);
            row_weights.extend(weight(x));
        }
        row_offsets.push(row_columns.len());
    }
    Engine::Sparse {
        kind,
        offsets,
        points,
        values,
        norms,
        abs_norms,
        row_offsets,
        row_columns,
        row_values,
        row_weights,
    }
}

/// Row `i` of the point-major CSR as a sparse side of
/// [`SharedAp::eval_sparse`](crate::distance::SharedAp::eval_sparse).
fn sparse_row<'a>(
    offsets: &[usize],
    columns: &'a [u32],
    values: &'a [f32],
    weights: &'a [f32],
    i: usize,
) -> SparseFingerprint<'a> {
    let range = offsets[i]..offsets[i + 1];
    SparseFingerprint {
        columns: &columns[range.clone()],
        values: &values[range.clone()],
        weights: &weights[range],
    }
}

/// A query's heard APs (value > 0, the sparse engines' null) as a sorted sparse side of
/// [`SharedAp::eval_sparse`](crate::distance::SharedAp::eval_sparse).
struct SparseQuery {
    columns: Vec<u32>,
    values: Vec<f32>,
    weights: Vec<f32>,
}

impl SparseQuery {
    fn new(q: &[f32], d: &crate::distance::SharedAp) -> Self {
        let mut out = Self {
            columns: Vec::new(),
            values: Vec::new(),
            weights: Vec::new(),
        };
        for (j, &v) in q.iter().enumerate() {
            if v > 0.0 {
                // Columns fit u32: the radio map's vocabulary is capped far below.
                out.columns.push(u32::try_from(j).unwrap_or(u32::MAX));
                out.values.push(v);
                out.weights.push(d.one_sided_weight(v, 0.0));
            }
        }
        out
    }

    fn side(&self) -> SparseFingerprint<'_> {
        SparseFingerprint {
            columns: &self.columns,
            values: &self.values,
            weights: &self.weights,
        }
    }
}

fn build_dense(map: &RadioMap, t: &Transform) -> Engine {
    let (n, m) = (map.len(), map.n_aps());
    let stride = m.div_ceil(8) * 8;
    let mut matrix = vec![0f32; n * stride];
    let null = t.null_value();
    for i in 0..n {
        let row = &mut matrix[i * stride..i * stride + m];
        row.fill(null);
        for (j, v) in map.heard(i) {
            row[j] = t.apply(Some(v));
        }
    }
    Engine::Dense { matrix, stride }
}

impl Matcher for KnnMatcher {
    fn name(&self) -> String {
        self.config.describe()
    }

    fn map(&self) -> &RadioMap {
        &self.map
    }

    fn locate(&self, query: &Query) -> Result<WifiObservation, FingerprintError> {
        let q = self.transformed_query(query)?;
        let mut dist = vec![0f32; self.map.len()];
        self.distances_into(&q, &mut dist);
        let nb = self.top_k(&dist);
        observation_from_neighbours(&self.map, query, &nb, self.config.weighting, self.map.len())
    }

    fn locate_batch(&self, queries: &[Query]) -> Vec<Result<WifiObservation, FingerprintError>> {
        queries
            .par_iter()
            .map_init(
                || vec![0f32; self.map.len()],
                |dist, query| {
                    let q = self.transformed_query(query)?;
                    self.distances_into(&q, dist);
                    let nb = self.top_k(dist);
                    observation_from_neighbours(
                        &self.map,
                        query,
                        &nb,
                        self.config.weighting,
                        self.map.len(),
                    )
                },
            )
            .collect()
    }
}

#[cfg(test)]
mod tests;
