//! The radio map (paper 000 §2.1 eq. 2, paper 001 §4.1): reference points with the mean RSS
//! per access point, sample counts and spread, and the AP vocabulary.

use crate::FingerprintError;
use serde::{Deserialize, Serialize};
use std::collections::HashMap;
use wipdr_core::fingerprint_table::{FingerprintLabel, FingerprintTable};
use wipdr_core::{Bssid, Point2};

/// Weakest RSSI accepted anywhere in the crate, dBm.
pub const MIN_VALID_RSSI_DBM: f64 = -120.0;
/// Strongest RSSI accepted anywhere in the crate, dBm.
pub const MAX_VALID_RSSI_DBM: f64 = 0.0;

/// Whether an RSSI is finite and within `[-120, 0]` dBm.
pub fn is_valid_rssi(v: f64) -> bool {
    v.is_finite() && (MIN_VALID_RSSI_DBM..=MAX_VALID_RSSI_DBM).contains(&v)
}

/// Settings of a radio map.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RadioMapConfig {
    /// The RSS written for an AP a reference point did not hear, dBm (`docs/algorithms.md`: -110).
    pub not_heard_dbm: f32,
}

impl Default for RadioMapConfig {
    fn default() -> Self {
        Self {
            not_heard_dbm: -110.0,
        }
    }
}

/// The AP vocabulary: column index <-> name and, where known, BSSID.
///
/// Benchmark maps name their columns `ap_000 …` and have no BSSIDs; maps built from walks
/// name each column by its BSSID's text form.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(from = "VocabularyRepr", into = "VocabularyRepr")]
pub struct ApVocabulary {
    names: Vec<String>,
    bssids: Vec<Option<Bssid>>,
    by_name: HashMap<String, usize>,
    by_bssid: HashMap<Bssid, usize>,
}

#[derive(Serialize, Deserialize)]
struct VocabularyRepr {
    names: Vec<String>,
    bssids: Vec<Option<Bssid>>,
}

impl From<VocabularyRepr> for ApVocabulary {
    fn from(r: VocabularyRepr) -> Self {
        let mut v = ApVocabulary::default();
        for (i, name) in r.names.into_iter().enumerate() {
            v.push(name, r.bssids.get(i).copied().flatten());
        }
        v
    }
}

impl From<ApVocabulary> for VocabularyRepr {
    fn from(v: ApVocabulary) -> Self {
        Self {
            names: v.names,
            bssids: v.bssids,
        }
    }
}

impl PartialEq for ApVocabulary {
    fn eq(&self, other: &Self) -> bool {
        self.names == other.names && self.bssids == other.bssids
    }
}

impl ApVocabulary {
    /// A vocabulary of named columns without BSSIDs (benchmark files).
    pub fn from_names<I: IntoIterator<Item = String>>(names: I) -> Self {
        let mut v = Self::default();
        for n in names {
            v.push(n, None);
        }
        v
    }

    /// A vocabulary of BSSIDs, each named by its text form.
    pub fn from_bssids<I: IntoIterator<Item = Bssid>>(bssids: I) -> Self {
        let mut v = Self::default();
        for b in bssids {
            v.push(b.to_string(), Some(b));
        }
        v
    }

    /// Appends a column (or returns the existing column of that name); returns its index.
    pub fn push(&mut self, name: String, bssid: Option<Bssid>) -> usize {
        if let Some(&i) = self.by_name.get(&name) {
            return i;
        }
        let i = self.names.len();
        self.by_name.insert(name.clone(), i);
        if let Some(b) = bssid {
            self.by_bssid.entry(b).or_insert(i);
        }
        self.names.push(name);
        self.bssids.push(bssid);
        i
    }

    /// Number of columns.
    pub fn len(&self) -> usize {
        self.names.len()
    }

    /// Whether there are no columns.
    pub fn is_empty(&self) -> bool {
        self.names.is_empty()
    }

    /// Column of a BSSID.
    pub fn column_of_bssid(&self, b: Bssid) -> Option<usize> {
        self.by_bssid.get(&b).copied()
    }

    /// Column of a name.
    pub fn column_of_name(&self, name: &str) -> Option<usize> {
        self.by_name.get(name).copied()
    }

    /// Name of a column.
    pub fn name(&self, column: usize) -> &str {
        &self.names[column]
    }

    /// BSSID of a column, where known.
    pub fn bssid(&self, column: usize) -> Option<Bssid> {
        self.bssids.get(column).copied().flatten()
    }

    /// All names in column order.
    pub fn names(&self) -> &[String] {
        &self.names
    }
}

/// Runs `extend` (an operation that appends points to a map: interpolation, the path-loss
/// extension) on each floor of `map` apart, and appends what it made to `map` on that floor;
/// a map of one floor (or none) is extended in place. Returns each run's result, floors in
/// order. Keeps floors apart: nothing made on one floor is computed from another's points.
pub fn per_floor<R>(
    map: &mut RadioMap,
    mut extend: impl FnMut(&mut RadioMap) -> Result<R, FingerprintError>,
) -> Result<Vec<R>, FingerprintError> {
    let floors = map.floors();
    if floors.len() < 2 {
        return Ok(vec![extend(map)?]);
    }
    let mut out = Vec::with_capacity(floors.len());
    for floor in floors {
        let members: Vec<usize> = (0..map.len())
            .filter(|&i| map.point(i).floor == floor)
            .collect();
        let mut sub = map.subset(&members);
        let before = sub.len();
        out.push(extend(&mut sub)?);
        map.append_points_from(&sub, before, floor)?;
    }
    Ok(out)
}

/// One reference point: where it is and how many scans went into it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ReferencePoint {
    /// Position in the floor frame, metres.
    pub position: Point2,
    /// Height, metres, where known.
    pub z: Option<f64>,
    /// Floor index, where known.
    pub floor: Option<i32>,
    /// Building index, where known.
    pub building: Option<i32>,
    /// Number of scans averaged into this point.
    pub scans: u32,
}

/// A radio map: `n` reference points x `m` APs, stored dense and row-major.
///
/// For each (point, AP): the mean RSS over the scans that heard the AP (paper 000 eq. 2), the
/// number of those scans (0 = never heard) and the standard deviation. Entries never heard
/// hold the configured "not heard" value, so [`RadioMap::filled_row`] is the fingerprint as a
/// matcher sees it.
///
/// ```
/// use wipdr_fingerprint::{RadioMap, RadioMapConfig};
/// use wipdr_core::{FingerprintLabel, FingerprintTable};
/// let mut table = FingerprintTable::new(vec!["ap_000".into(), "ap_001".into()]);
/// table.push_row(&[-60.0, FingerprintTable::NOT_HEARD], FingerprintLabel::at(1.0, 2.0, 0)).unwrap();
/// let map = RadioMap::from_table(&table, RadioMapConfig::default()).unwrap();
/// assert_eq!(map.filled_row(0), &[-60.0, -110.0]);
/// assert_eq!(map.rss(0, 1), None);
/// ```
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct RadioMap {
    /// The AP columns (`n_aps()` of them).
    vocabulary: ApVocabulary,
    /// The reference points, one per row of the parallel arrays below.
    points: Vec<ReferencePoint>,
    config: RadioMapConfig,
    mean_dbm: Vec<f32>,
    counts: Vec<u16>,
    spread_db: Vec<f32>,
    /// The most memory the dense table may take ([`RadioMap::set_table_budget`]); not part
    /// of the map's value (not serialised, not compared).
    #[serde(skip)]
    budget: Option<TableBudget>,
}

/// Bytes one (reference point, AP) cell of the dense table takes: the mean (`f32`), the
/// count (`u16`) and the spread (`f32`).
pub const BYTES_PER_CELL: usize = 10;

/// A ceiling on the memory of a radio map's dense table, and the config field that sets it
/// (named in the error when a push would cross it).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TableBudget {
    /// The most bytes the table may take (`points x APs x` [`BYTES_PER_CELL`]).
    pub max_bytes: usize,
    /// The config field that sets it (`radio_map.max_table_mib`).
    pub limit: &'static str,
    /// How to raise it, for the error message.
    pub hint: &'static str,
}

impl TableBudget {
    /// Checks that a table of `points x aps` fits; the error names the limit.
    pub fn check(&self, points: usize, aps: usize) -> Result<(), FingerprintError> {
        let bytes = points.saturating_mul(aps).saturating_mul(BYTES_PER_CELL);
        if bytes > self.max_bytes {
            return Err(FingerprintError::limit_exceeded(
                format!(
                    "dense table of {points} reference points x {aps} APs ({} MiB)",
                    bytes >> 20
                ),
                self.limit.to_string(),
                format!("{} MiB", self.max_bytes >> 20),
                self.hint.to_string(),
            ));
        }
        Ok(())
    }
}

/// One cell of a radio map's table that differs from "never heard" (mean at the "not heard"
/// value, count 0, spread 0): the sparse form a saved site model stores
/// ([`RadioMap::sparse_cells`], [`RadioMap::from_sparse`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SparseCell {
    /// Row (reference point).
    pub point: u32,
    /// Column (AP).
    pub ap: u32,
    /// Mean RSS, dBm.
    pub mean_dbm: f32,
    /// Scans that heard it.
    pub count: u16,
    /// Spread of the RSS, dB.
    pub spread_db: f32,
}

impl PartialEq for RadioMap {
    /// The map's value: vocabulary, points, config and table; the budget does not count.
    fn eq(&self, other: &Self) -> bool {
        self.vocabulary == other.vocabulary
            && self.points == other.points
            && self.config == other.config
            && self.mean_dbm == other.mean_dbm
            && self.counts == other.counts
            && self.spread_db == other.spread_db
    }
}

impl RadioMap {
    /// An empty map over a vocabulary.
    pub fn new(vocabulary: ApVocabulary, config: RadioMapConfig) -> Self {
        Self {
            vocabulary,
            points: Vec::new(),
            config,
            mean_dbm: Vec::new(),
            counts: Vec::new(),
            spread_db: Vec::new(),
            budget: None,
        }
    }

    /// Bounds the dense table's memory: a push ([`RadioMap::push_point`],
    /// [`RadioMap::append_points_from`]) that would take it over `budget` is an error
    /// ([`FingerprintError::LimitExceeded`]) before anything is allocated. Kept by
    /// [`RadioMap::subset`]; `None` (the default) leaves the table unbounded.
    pub fn set_table_budget(
        &mut self,
        budget: Option<TableBudget>,
    ) -> Result<(), FingerprintError> {
        if let Some(b) = &budget {
            b.check(self.len(), self.n_aps())?;
        }
        self.budget = budget;
        Ok(())
    }

    /// The table budget ([`RadioMap::set_table_budget`]).
    pub fn table_budget(&self) -> Option<TableBudget> {
        self.budget
    }

    fn check_room_for(&self, more_points: usize) -> Result<(), FingerprintError> {
        match &self.budget {
            Some(b) => b.check(self.len().saturating_add(more_points), self.n_aps()),
            None => Ok(()),
        }
    }

    /// Builds a map from a benchmark table: one reference point per row, one sample per heard
    /// AP, spread 0; floor/building from the labels. A table of rows none of which hears any
    /// AP is [`FingerprintError::NothingHeard`] (every query would tie with every point).
    pub fn from_table(
        table: &FingerprintTable,
        config: RadioMapConfig,
    ) -> Result<Self, FingerprintError> {
        let m = table.n_aps();
        if table.rss.len() != m * table.n_rows() {
            return Err(FingerprintError::InvalidInput(format!(
                "table has {} RSS values for {} rows x {m} APs",
                table.rss.len(),
                table.n_rows()
            )));
        }
        let mut map = Self::new(
            ApVocabulary::from_names(table.ap_names.iter().cloned()),
            config,
        );
        if map.vocabulary.len() != m {
            return Err(FingerprintError::InvalidInput(
                "duplicate AP column names".into(),
            ));
        }
        let mut row = vec![None; m];
        for (i, label) in table.labels.iter().enumerate() {
            for (slot, &v) in row.iter_mut().zip(table.row(i)) {
                *slot = (!FingerprintTable::is_not_heard(v)).then_some(v);
            }
            map.push_point(point_of_label(label), &row, None)?;
        }
        if !map.is_empty() && map.counts.iter().all(|&c| c == 0) {
            return Err(FingerprintError::NothingHeard {
                points: map.len(),
                aps: m,
            });
        }
        Ok(map)
    }

    /// Appends a reference point. `mean` has one entry per AP column (`None` = not heard);
    /// `counts` (optional) the number of scans per AP and `spread` the standard deviation.
    /// Means must be valid RSSI values.
    pub fn push_point(
        &mut self,
        point: ReferencePoint,
        mean: &[Option<f32>],
        stats: Option<(&[u16], &[f32])>,
    ) -> Result<(), FingerprintError> {
        let m = self.n_aps();
        if mean.len() != m {
            return Err(FingerprintError::DimensionMismatch {
                expected: m,
                found: mean.len(),
            });
        }
        if let Some((c, s)) = stats
            && (c.len() != m || s.len() != m)
        {
            return Err(FingerprintError::DimensionMismatch {
                expected: m,
                found: c.len().min(s.len()),
            });
        }
        self.check_room_for(1)?;
        if !(point.position.x.is_finite() && point.position.y.is_finite()) {
            return Err(FingerprintError::InvalidInput(format!(
                "reference point {} has a non-finite position",
                self.points.len()
            )));
        }
        for (j, v) in mean.iter().enumerate() {
            if let Some(v) = v
                && !is_valid_rssi(f64::from(*v))
            {
                return Err(FingerprintError::InvalidRssi {
                    ap: self.vocabulary.name(j).to_string(),
                    value: f64::from(*v),
                });
            }
            self.mean_dbm.push(v.unwrap_or(self.config.not_heard_dbm));
            let (c, s) = match (v, stats) {
                (None, _) => (0, 0.0),
                (Some(_), None) => (1, 0.0),
                (Some(_), Some((c, s))) => (c[j].max(1), s[j].max(0.0)),
            };
            self.counts.push(c);
            self.spread_db.push(c.min(1) as f32 * s);
        }
        self.points.push(point);
        Ok(())
    }

    /// The cells of the table that differ from "never heard", row by row: with the
    /// vocabulary, the points and the config, the whole map ([`RadioMap::from_sparse`]).
    /// Most of a building's table is never heard, so this is a fraction of its size.
    pub fn sparse_cells(&self) -> Vec<SparseCell> {
        let m = self.n_aps();
        let nh = self.config.not_heard_dbm;
        let mut out = Vec::new();
        for (k, ((&mean, &count), &spread)) in self
            .mean_dbm
            .iter()
            .zip(&self.counts)
            .zip(&self.spread_db)
            .enumerate()
        {
            if count != 0 || mean.to_bits() != nh.to_bits() || spread.to_bits() != 0 {
                // k < points x APs, each of which fits in u32 (a map saved this way is far
                // below 2^32 rows and columns); checked, never truncated.
                let (Ok(point), Ok(ap)) =
                    (u32::try_from(k / m.max(1)), u32::try_from(k % m.max(1)))
                else {
                    continue;
                };
                out.push(SparseCell {
                    point,
                    ap,
                    mean_dbm: mean,
                    count,
                    spread_db: spread,
                });
            }
        }
        out
    }

    /// A map from its sparse form ([`RadioMap::sparse_cells`]): the dense table filled with
    /// "never heard", then the cells written. `max_cells` bounds `points x APs` before the
    /// table is allocated (a decoded file could announce any shape); a cell outside the
    /// table, given twice or out of row order is an error.
    pub fn from_sparse(
        vocabulary: ApVocabulary,
        points: Vec<ReferencePoint>,
        config: RadioMapConfig,
        cells: &[SparseCell],
        max_cells: usize,
    ) -> Result<Self, FingerprintError> {
        let bad = |what: String| FingerprintError::InvalidInput(format!("radio map: {what}"));
        let m = vocabulary.len();
        let n = points.len();
        let total = n
            .checked_mul(m)
            .filter(|&c| c <= max_cells)
            .ok_or_else(|| {
                bad(format!(
                    "{n} points x {m} APs is more than the {max_cells} cells a map may have"
                ))
            })?;
        let mut map = Self {
            vocabulary,
            points,
            config,
            mean_dbm: vec![config.not_heard_dbm; total],
            counts: vec![0; total],
            spread_db: vec![0.0; total],
            budget: None,
        };
        let mut last: Option<usize> = None;
        for c in cells {
            let (i, j) = (c.point as usize, c.ap as usize);
            if i >= n || j >= m {
                return Err(bad(format!(
                    "cell ({i}, {j}) outside the table of {n} points x {m} APs"
                )));
            }
            let k = i * m + j;
            if last.is_some_and(|l| k <= l) {
                return Err(bad(format!("cell ({i}, {j}) given twice or out of order")));
            }
            last = Some(k);
            map.mean_dbm[k] = c.mean_dbm;
            map.counts[k] = c.count;
            map.spread_db[k] = c.spread_db;
        }
        Ok(map)
    }

    /// Checks that a map decoded from outside (a saved site model) is one this crate could
    /// have built: its parallel arrays are `len() x n_aps()` long, every position, RSS and
    /// spread is finite, the "not heard" value is finite and the vocabulary names each column
    /// once. A map that fails would panic or give NaN when matched; it is refused instead.
    pub fn check_consistent(&self) -> Result<(), FingerprintError> {
        let bad = |what: String| Err(FingerprintError::InvalidInput(format!("radio map: {what}")));
        let cells = self.points.len().checked_mul(self.n_aps());
        if cells.is_none_or(|c| {
            c != self.mean_dbm.len() || c != self.counts.len() || c != self.spread_db.len()
        }) {
            return bad(format!(
                "{} points x {} APs, but {} / {} / {} values (mean / count / spread)",
                self.points.len(),
                self.n_aps(),
                self.mean_dbm.len(),
                self.counts.len(),
                self.spread_db.len()
            ));
        }
        if self.vocabulary.by_name.len() != self.vocabulary.names.len()
            || self.vocabulary.bssids.len() != self.vocabulary.names.len()
        {
            return bad("the AP vocabulary names a column twice".into());
        }
        if !self.config.not_heard_dbm.is_finite() {
            return bad(format!("not_heard_dbm {}", self.config.not_heard_dbm));
        }
        if let Some(i) = self.points.iter().position(|p| {
            !(p.position.x.is_finite() && p.position.y.is_finite())
                || p.z.is_some_and(|z| !z.is_finite())
        }) {
            return bad(format!("reference point {i} has a non-finite position"));
        }
        if let Some(k) = self
            .mean_dbm
            .iter()
            .zip(&self.spread_db)
            .position(|(m, s)| !m.is_finite() || !s.is_finite())
        {
            return bad(format!("value {k} is not finite"));
        }
        Ok(())
    }

    /// Number of reference points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// Whether the map has no reference points.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// The reference points, one per row, in the order they were pushed.
    ///
    /// ```
    /// use wipdr_core::{Bssid, Point2};
    /// use wipdr_fingerprint::{RadioMap, RadioMapConfig};
    /// let map = RadioMap::from_records(
    ///     [(Point2::new(0.0, 0.0), vec![(Bssid(7), -50.0)]),
    ///      (Point2::new(5.0, 0.0), vec![(Bssid(7), -70.0)])],
    ///     RadioMapConfig::default(),
    /// ).unwrap();
    /// let xs: Vec<f64> = map.points().iter().map(|p| p.position.x).collect();
    /// assert_eq!(xs, [0.0, 5.0]);
    /// assert_eq!(map.points().len(), map.len());
    /// ```
    pub fn points(&self) -> &[ReferencePoint] {
        &self.points
    }

    /// Reference point `i`. Panics if `i >= len()`, like slice indexing.
    pub fn point(&self, i: usize) -> &ReferencePoint {
        &self.points[i]
    }

    /// The AP columns.
    pub fn vocabulary(&self) -> &ApVocabulary {
        &self.vocabulary
    }

    /// Number of AP columns.
    pub fn n_aps(&self) -> usize {
        self.vocabulary.len()
    }

    /// The configuration.
    pub fn config(&self) -> RadioMapConfig {
        self.config
    }

    /// The "not heard" value, dBm.
    pub fn not_heard_dbm(&self) -> f32 {
        self.config.not_heard_dbm
    }

    /// Changes the "not heard" value, rewriting the never-heard entries.
    pub fn set_not_heard_dbm(&mut self, v: f32) -> Result<(), FingerprintError> {
        if !v.is_finite() {
            return Err(FingerprintError::InvalidConfig(
                wipdr_core::ConfigError::new("not_heard_dbm", format!("must be finite, got {v}")),
            ));
        }
        self.config.not_heard_dbm = v;
        for (x, &c) in self.mean_dbm.iter_mut().zip(&self.counts) {
            if c == 0 {
                *x = v;
            }
        }
        Ok(())
    }

    /// The fingerprint of point `i` with never-heard APs at the "not heard" value.
    pub fn filled_row(&self, i: usize) -> &[f32] {
        let m = self.n_aps();
        &self.mean_dbm[i * m..(i + 1) * m]
    }

    /// The whole dense matrix, row-major `len() x n_aps()`.
    pub fn filled_matrix(&self) -> &[f32] {
        &self.mean_dbm
    }

    /// Mean RSS of AP `j` at point `i`, `None` if never heard there.
    pub fn rss(&self, i: usize, j: usize) -> Option<f32> {
        let k = i * self.n_aps() + j;
        (self.counts[k] > 0).then_some(self.mean_dbm[k])
    }

    /// Number of scans that heard AP `j` at point `i`.
    pub fn count(&self, i: usize, j: usize) -> u16 {
        self.counts[i * self.n_aps() + j]
    }

    /// Standard deviation of AP `j`'s RSS at point `i` (0 with fewer than two samples).
    pub fn spread(&self, i: usize, j: usize) -> f32 {
        self.spread_db[i * self.n_aps() + j]
    }

    /// The heard APs of point `i` as `(column, mean dBm)`, in column order.
    pub fn heard(&self, i: usize) -> impl Iterator<Item = (usize, f32)> + '_ {
        let m = self.n_aps();
        let row = &self.mean_dbm[i * m..(i + 1) * m];
        let counts = &self.counts[i * m..(i + 1) * m];
        row.iter()
            .zip(counts)
            .enumerate()
            .filter(|(_, (_, c))| **c > 0)
            .map(|(j, (v, _))| (j, *v))
    }

    /// Weakest heard RSS in the map (dBm); `None` if nothing is heard.
    pub fn min_heard_rss(&self) -> Option<f32> {
        self.mean_dbm
            .iter()
            .zip(&self.counts)
            .filter(|(_, c)| **c > 0)
            .map(|(v, _)| *v)
            .min_by(f32::total_cmp)
    }

    /// A map with only the points `indices` (in that order), same vocabulary.
    pub fn subset(&self, indices: &[usize]) -> Self {
        let m = self.n_aps();
        let mut out = Self::new(self.vocabulary.clone(), self.config);
        out.budget = self.budget;
        for &i in indices {
            out.points.push(self.points[i]);
            out.mean_dbm
                .extend_from_slice(&self.mean_dbm[i * m..(i + 1) * m]);
            out.counts
                .extend_from_slice(&self.counts[i * m..(i + 1) * m]);
            out.spread_db
                .extend_from_slice(&self.spread_db[i * m..(i + 1) * m]);
        }
        out
    }

    /// Appends the points of `other` from index `from` on (same vocabulary and layout), with
    /// their floor set to `floor`.
    pub fn append_points_from(
        &mut self,
        other: &RadioMap,
        from: usize,
        floor: Option<i32>,
    ) -> Result<(), FingerprintError> {
        let m = self.n_aps();
        if other.n_aps() != m {
            return Err(FingerprintError::DimensionMismatch {
                expected: m,
                found: other.n_aps(),
            });
        }
        self.check_room_for(other.len().saturating_sub(from))?;
        for i in from..other.len() {
            let mut p = other.points[i];
            p.floor = floor;
            self.points.push(p);
            self.mean_dbm
                .extend_from_slice(&other.mean_dbm[i * m..(i + 1) * m]);
            self.counts
                .extend_from_slice(&other.counts[i * m..(i + 1) * m]);
            self.spread_db
                .extend_from_slice(&other.spread_db[i * m..(i + 1) * m]);
        }
        Ok(())
    }

    /// The distinct floors of the points (`None` for points without one), sorted.
    pub fn floors(&self) -> Vec<Option<i32>> {
        let mut floors: Vec<Option<i32>> = self.points.iter().map(|p| p.floor).collect();
        floors.sort_unstable();
        floors.dedup();
        floors
    }

    /// Serialises the map with bincode (standard configuration).
    pub fn to_bincode(&self) -> Result<Vec<u8>, FingerprintError> {
        bincode::serde::encode_to_vec(self, bincode::config::standard())
            .map_err(|e| FingerprintError::InvalidInput(format!("bincode encode: {e}")))
    }

    /// Reads a map written by [`RadioMap::to_bincode`].
    pub fn from_bincode(bytes: &[u8]) -> Result<Self, FingerprintError> {
        let (map, _) = bincode::serde::decode_from_slice(bytes, bincode::config::standard())
            .map_err(|e| FingerprintError::InvalidInput(format!("bincode decode: {e}")))?;
        Ok(map)
    }
}

/// The reference point of a benchmark label.
pub fn point_of_label(label: &FingerprintLabel) -> ReferencePoint {
    ReferencePoint {
        position: Point2::new(label.x, label.y),
        z: Some(label.z),
        floor: Some(label.floor),
        building: Some(label.building),
        scans: 1,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn small() -> RadioMap {
        let mut map = RadioMap::new(
            ApVocabulary::from_names(["a".to_string(), "b".to_string()]),
            RadioMapConfig::default(),
        );
        let p = ReferencePoint {
            position: Point2::new(1.0, 2.0),
            z: None,
            floor: Some(1),
            building: None,
            scans: 3,
        };
        map.push_point(p, &[Some(-50.0), None], Some((&[3, 0], &[2.0, 0.0])))
            .unwrap();
        map
    }

    #[test]
    fn fill_and_stats() {
        let mut map = small();
        assert_eq!(map.filled_row(0), &[-50.0, -110.0]);
        assert_eq!(map.count(0, 0), 3);
        assert_eq!(map.spread(0, 0), 2.0);
        assert_eq!(map.count(0, 1), 0);
        map.set_not_heard_dbm(-100.0).unwrap();
        assert_eq!(map.filled_row(0), &[-50.0, -100.0]);
        assert!(map.set_not_heard_dbm(f32::NAN).is_err());
        assert_eq!(map.heard(0).collect::<Vec<_>>(), vec![(0, -50.0)]);
    }

    #[test]
    fn rejects_bad_points() {
        let mut map = small();
        let p = map.points[0];
        assert!(matches!(
            map.push_point(p, &[Some(f32::NAN), None], None),
            Err(FingerprintError::InvalidRssi { .. })
        ));
        assert!(matches!(
            map.push_point(p, &[Some(-50.0)], None),
            Err(FingerprintError::DimensionMismatch { .. })
        ));
        let mut q = p;
        q.position.x = f64::INFINITY;
        assert!(map.push_point(q, &[None, None], None).is_err());
        assert_eq!(map.len(), 1);
    }

    /// Every view of the map agrees with the private parallel arrays: one row of `n_aps()`
    /// entries per point, and `rss`/`count`/`heard`/`filled_row` telling the same story.
    fn assert_invariants(map: &RadioMap) {
        let m = map.n_aps();
        assert_eq!(map.points().len(), map.len());
        assert_eq!(map.vocabulary().len(), m);
        assert_eq!(map.filled_matrix().len(), map.len() * m);
        assert_eq!(map.counts.len(), map.len() * m);
        assert_eq!(map.spread_db.len(), map.len() * m);
        for i in 0..map.len() {
            assert_eq!(map.point(i), &map.points()[i]);
            let row = map.filled_row(i);
            assert_eq!(row.len(), m);
            for (j, &v) in row.iter().enumerate() {
                match map.rss(i, j) {
                    Some(r) => {
                        assert!(map.count(i, j) > 0);
                        assert_eq!(r.to_bits(), v.to_bits());
                    }
                    None => {
                        assert_eq!(map.count(i, j), 0);
                        assert_eq!(map.spread(i, j), 0.0);
                        assert_eq!(v, map.not_heard_dbm());
                    }
                }
            }
            let heard: Vec<(usize, f32)> = (0..m)
                .filter_map(|j| map.rss(i, j).map(|r| (j, r)))
                .collect();
            assert_eq!(map.heard(i).collect::<Vec<_>>(), heard);
        }
    }

    #[test]
    fn a_map_from_records_keeps_its_invariants() {
        let mut map = RadioMap::from_records(
            [
                (Point2::new(0.0, 0.0), vec![(Bssid(7), -50.0)]),
                (
                    Point2::new(5.0, 0.0),
                    vec![(Bssid(9), -60.0), (Bssid(7), -70.0)],
                ),
                (Point2::new(5.0, 4.0), vec![]),
                (
                    Point2::new(1.0, 4.0),
                    vec![(Bssid(3), -80.0), (Bssid(3), -90.0)],
                ),
            ],
            RadioMapConfig::default(),
        )
        .unwrap();
        assert_eq!((map.len(), map.n_aps()), (4, 3));
        assert_invariants(&map);
        let xs: Vec<f64> = map.points().iter().map(|p| p.position.x).collect();
        assert_eq!(xs, [0.0, 5.0, 5.0, 1.0]);
        let col = |b| map.vocabulary().column_of_bssid(Bssid(b)).unwrap();
        let (c3, c7, c9) = (col(3), col(7), col(9));
        assert_eq!(map.rss(0, c7), Some(-50.0));
        assert_eq!(map.rss(1, c7), Some(-70.0));
        assert_eq!(map.rss(1, c9), Some(-60.0));
        assert_eq!(map.rss(3, c3), Some(-85.0));
        assert_eq!(map.heard(2).count(), 0);
        assert_invariants(&map.subset(&[3, 1]));
        assert_eq!(map.subset(&[3, 1]).point(0), map.point(3));
        map.set_not_heard_dbm(-100.0).unwrap();
        assert_invariants(&map);
        let back = RadioMap::from_bincode(&map.to_bincode().unwrap()).unwrap();
        assert_invariants(&back);
    }

    #[test]
    fn bincode_and_json_roundtrip() {
        let map = small();
        let back = RadioMap::from_bincode(&map.to_bincode().unwrap()).unwrap();
        assert_eq!(back, map);
        assert_eq!(back.vocabulary.column_of_name("b"), Some(1));
        let v = ApVocabulary::from_bssids([Bssid(7)]);
        let json = serde_json::to_string(&v).unwrap();
        let v2: ApVocabulary = serde_json::from_str(&json).unwrap();
        assert_eq!(v2.column_of_bssid(Bssid(7)), Some(0));
    }
}
