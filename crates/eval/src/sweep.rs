//! Parameter sweeps: a grid or a random sample over any config field, addressed by a dotted
//! path into the evaluation config (`"fuser.q_heading_turn"`, `"matcher.k"`), evaluated
//! elsewhere; this module expands, shards, records and resumes.
//!
//! ## Sweep file (TOML)
//!
//! ```toml
//! scheme = "aekf"          # the scheme every config runs
//! objective = "mean"       # mean | rms | p95: what "best" minimises
//!
//! [grid]                   # every combination (a cartesian product)
//! "matcher.k" = [3, 5, 8]
//!
//! [random]                 # plus `samples` draws, reproducible from `seed`
//! samples = 50
//! seed = 7
//! [random.ranges]
//! "fuser.r_wifi" = { min = 4.0, max = 400.0, log = true }
//! "fuser.gate" = { min = 2.0, max = 20.0 }
//! "matcher.k" = { min = 2, max = 12, integer = true }
//! ```
//!
//! With both a grid and a random section, each grid point is combined with each draw.
//! Config `i` of the sweep is the same on every machine, so `--shard I/N` (configs with
//! `index % N == I`) lets a batch system spread one sweep over machines.
//!
//! ## Results file (CSV)
//!
//! One row per finished config: `index, id, <param columns...>, count, skipped, mean, rms,
//! p50, p75, p95, max, objective`. A row is appended and flushed as soon as its config
//! finishes, so a sweep that is stopped keeps all it finished; `resume` skips configs whose
//! `id` is already in the file (a torn last line is dropped). When a run completes, the file
//! is rewritten sorted by index, so an interrupted-and-resumed sweep ends with the same file
//! as an uninterrupted one. [`SweepOptions::stop`] is a polite stop (`wipdr sweep` sets it on
//! Ctrl-C): no new config starts, running ones finish and are written, and the outcome says
//! [`SweepOutcome::stopped`].
//!
//! ```
//! use wipdr_eval::sweep::SweepSpec;
//! let spec: SweepSpec = toml::from_str(r#"
//!     scheme = "ekf"
//!     objective = "p95"
//!     [grid]
//!     "fuser.r" = [1.0, 2.0]
//!     "matcher.k" = [3, 5]
//! "#).unwrap();
//! let points = spec.expand().unwrap();
//! assert_eq!(points.len(), 4);
//! assert_eq!(points[0].params.len(), 2);
//! ```

use crate::report::Summary;
use serde::{Deserialize, Serialize};
use serde_json::Value;
use std::collections::{BTreeMap, HashSet};
use std::fs::{File, OpenOptions};
use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};
use thiserror::Error;

/// Errors of sweeps.
#[derive(Debug, Error)]
pub enum SweepError {
    /// The sweep spec is not usable.
    #[error("sweep spec: {0}")]
    Spec(String),
    /// A dotted path does not lead to a field of the config.
    #[error("config path {path:?}: {reason}")]
    Path {
        /// The dotted path.
        path: String,
        /// Why it failed.
        reason: String,
    },
    /// Reading or writing the results file.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// A malformed results file (not a torn last line).
    #[error("{path}, line {line}: {reason}")]
    Results {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// Why.
        reason: String,
    },
}

/// What "best" minimises.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Objective {
    /// Mean error.
    #[default]
    Mean,
    /// RMS error.
    Rms,
    /// 95th percentile.
    P95,
}

impl Objective {
    /// The objective's value of a summary (infinite when nothing was scored).
    pub fn of(self, s: &Summary) -> f64 {
        if s.count == 0 {
            return f64::INFINITY;
        }
        match self {
            Objective::Mean => s.mean,
            Objective::Rms => s.rms,
            Objective::P95 => s.p95,
        }
    }
}

/// A sampled range of one parameter.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Range {
    /// Lower bound.
    pub min: f64,
    /// Upper bound.
    pub max: f64,
    /// Sample uniformly in log space (both bounds must be > 0).
    #[serde(default)]
    pub log: bool,
    /// Round to an integer.
    #[serde(default)]
    pub integer: bool,
}

/// The random part of a sweep.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RandomSpec {
    /// Number of draws.
    pub samples: usize,
    /// Seed of the draws.
    #[serde(default)]
    pub seed: u64,
    /// Ranges by dotted path.
    pub ranges: BTreeMap<String, Range>,
}

/// A sweep file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SweepSpec {
    /// The scheme to run.
    pub scheme: String,
    /// What "best" minimises.
    #[serde(default)]
    pub objective: Objective,
    /// Value lists by dotted path (cartesian product).
    #[serde(default)]
    pub grid: BTreeMap<String, Vec<Value>>,
    /// Random draws.
    #[serde(default)]
    pub random: Option<RandomSpec>,
}

/// One config of a sweep: its index and parameter values by dotted path.
#[derive(Debug, Clone, PartialEq)]
pub struct SweepPoint {
    /// Position in the sweep (stable across machines).
    pub index: usize,
    /// Parameter values, in the sweep's column order.
    pub params: Vec<(String, Value)>,
}

impl SweepPoint {
    /// A stable id: the parameters as compact JSON.
    pub fn id(&self) -> String {
        let obj: serde_json::Map<String, Value> = self.params.iter().cloned().collect();
        Value::Object(obj).to_string()
    }
}

/// SplitMix64: a tiny, well-known deterministic mixer (so draw `i` is the same everywhere).
fn splitmix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

fn unit_draw(seed: u64, sample: usize, param: usize) -> f64 {
    let h = splitmix64(seed ^ splitmix64((sample as u64) << 20 ^ param as u64));
    (h >> 11) as f64 / (1u64 << 53) as f64
}

impl SweepSpec {
    /// The parameter columns, in order: grid paths, then random paths not in the grid.
    pub fn columns(&self) -> Vec<String> {
        let mut cols: Vec<String> = self.grid.keys().cloned().collect();
        if let Some(r) = &self.random {
            cols.extend(
                r.ranges
                    .keys()
                    .filter(|k| !self.grid.contains_key(*k))
                    .cloned(),
            );
        }
        cols
    }

    /// Checks the spec and expands it into its configs.
    pub fn expand(&self) -> Result<Vec<SweepPoint>, SweepError> {
        for (k, v) in &self.grid {
            if v.is_empty() {
                return Err(SweepError::Spec(format!("grid {k:?} has no values")));
            }
        }
        let mut grid_points: Vec<Vec<(String, Value)>> = vec![vec![]];
        for (k, vals) in &self.grid {
            let mut next = Vec::with_capacity(grid_points.len() * vals.len());
            for p in &grid_points {
                for v in vals {
                    let mut q = p.clone();
                    q.push((k.clone(), v.clone()));
                    next.push(q);
                }
            }
            grid_points = next;
        }
        let draws: Vec<Vec<(String, Value)>> = match &self.random {
            None => vec![vec![]],
            Some(r) => {
                if r.samples == 0 {
                    return Err(SweepError::Spec("random.samples is 0".into()));
                }
                for (k, rg) in &r.ranges {
                    let ok = rg.min.is_finite()
                        && rg.max.is_finite()
                        && rg.min <= rg.max
                        && (!rg.log || rg.min > 0.0);
                    if !ok {
                        return Err(SweepError::Spec(format!(
                            "range {k:?}: need finite min <= max (and min > 0 with log)"
                        )));
                    }
                    if self.grid.contains_key(k) {
                        return Err(SweepError::Spec(format!(
                            "{k:?} is in both grid and random"
                        )));
                    }
                }
                (0..r.samples)
                    .map(|s| {
                        r.ranges
                            .iter()
                            .enumerate()
                            .map(|(j, (k, rg))| {
                                let u = unit_draw(r.seed, s, j);
                                let x = if rg.log {
                                    (rg.min.ln() + u * (rg.max.ln() - rg.min.ln())).exp()
                                } else {
                                    rg.min + u * (rg.max - rg.min)
                                };
                                let v = if rg.integer {
                                    Value::from(
                                        x.round().clamp(rg.min.ceil(), rg.max.floor()) as i64
                                    )
                                } else {
                                    // Keep 6 significant digits so ids stay readable.
                                    Value::from(format!("{x:.6e}").parse::<f64>().unwrap_or(x))
                                };
                                (k.clone(), v)
                            })
                            .collect()
                    })
                    .collect()
            }
        };
        let mut out = Vec::with_capacity(grid_points.len() * draws.len());
        for g in &grid_points {
            for d in &draws {
                let mut params = g.clone();
                params.extend(d.iter().cloned());
                out.push(SweepPoint {
                    index: out.len(),
                    params,
                });
            }
        }
        Ok(out)
    }
}

/// Sets the field at a dotted `path` of a JSON value; the field must exist (so a typo in a
/// sweep file is an error, not a silently ignored parameter).
pub fn set_path(root: &mut Value, path: &str, value: Value) -> Result<(), SweepError> {
    let err = |reason: &str| SweepError::Path {
        path: path.to_string(),
        reason: reason.to_string(),
    };
    let mut cur = root;
    let parts: Vec<&str> = path.split('.').collect();
    for (i, part) in parts.iter().enumerate() {
        let obj = cur
            .as_object_mut()
            .ok_or_else(|| err(&format!("{:?} is not a table", parts[..i].join("."))))?;
        if !obj.contains_key(*part) {
            let known: Vec<&String> = obj.keys().collect();
            return Err(err(&format!("no field {part:?} (fields: {known:?})")));
        }
        let slot = obj.get_mut(*part).ok_or_else(|| err("field vanished"))?;
        if i + 1 == parts.len() {
            *slot = value;
            return Ok(());
        }
        cur = slot;
    }
    Err(err("empty path"))
}

/// Selects the configs of shard `shard` of `shards` (`index % shards == shard`).
pub fn shard(points: Vec<SweepPoint>, shard: usize, shards: usize) -> Vec<SweepPoint> {
    if shards <= 1 {
        return points;
    }
    points
        .into_iter()
        .filter(|p| p.index % shards == shard)
        .collect()
}

/// One finished config.
#[derive(Debug, Clone, PartialEq)]
pub struct SweepRow {
    /// Sweep index.
    pub index: usize,
    /// Stable id ([`SweepPoint::id`]).
    pub id: String,
    /// Parameter values as written.
    pub params: Vec<String>,
    /// The figures.
    pub summary: Summary,
    /// The objective's value.
    pub objective: f64,
}

const FIGURES: [&str; 9] = [
    "count",
    "skipped",
    "mean",
    "rms",
    "p50",
    "p75",
    "p95",
    "max",
    "objective",
];

/// The results file: appends finished rows at once, resumes, canonicalises.
#[derive(Debug)]
pub struct ResultsFile {
    path: PathBuf,
    columns: Vec<String>,
    file: Mutex<File>,
}

fn io_err(path: &Path) -> impl FnOnce(std::io::Error) -> SweepError + '_ {
    move |source| SweepError::Io {
        path: path.to_path_buf(),
        source,
    }
}

fn header(columns: &[String]) -> Vec<String> {
    let mut h = vec!["index".to_string(), "id".to_string()];
    h.extend(columns.iter().cloned());
    h.extend(FIGURES.iter().map(|s| s.to_string()));
    h
}

fn csv_line(fields: &[String]) -> String {
    let mut w = csv::WriterBuilder::new()
        .has_headers(false)
        .from_writer(vec![]);
    // Writing to a Vec cannot fail.
    let _ = w.write_record(fields);
    let bytes = w.into_inner().unwrap_or_default();
    String::from_utf8_lossy(&bytes).into_owned()
}

fn value_cell(v: &Value) -> String {
    match v {
        Value::String(s) => s.clone(),
        other => other.to_string(),
    }
}

impl ResultsFile {
    /// Opens `path` for a sweep with parameter `columns`. With `resume`, existing rows are read
    /// back (a torn last line is dropped) and returned; without it, an existing file is an
    /// error unless it is empty (never overwrite finished results by accident).
    pub fn open(
        path: &Path,
        columns: Vec<String>,
        resume: bool,
    ) -> Result<(Self, Vec<SweepRow>), SweepError> {
        let expected = header(&columns);
        let mut rows = Vec::new();
        let exists = path.exists()
            && std::fs::metadata(path)
                .map(|m| m.len() > 0)
                .unwrap_or(false);
        if exists && !resume {
            return Err(SweepError::Spec(format!(
                "{} exists: pass --resume to continue it, or choose another --out",
                path.display()
            )));
        }
        if exists {
            rows = read_rows(path, &expected)?;
            // Rewrite without any torn line, so appends start on a clean line.
            write_rows(path, &expected, &rows)?;
        } else {
            if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
                std::fs::create_dir_all(parent).map_err(io_err(parent))?;
            }
            std::fs::write(path, csv_line(&expected)).map_err(io_err(path))?;
        }
        let file = OpenOptions::new()
            .append(true)
            .open(path)
            .map_err(io_err(path))?;
        Ok((
            Self {
                path: path.to_path_buf(),
                columns,
                file: Mutex::new(file),
            },
            rows,
        ))
    }

    /// Appends and flushes one finished config (thread-safe).
    pub fn append(
        &self,
        point: &SweepPoint,
        summary: &Summary,
        objective: Objective,
    ) -> Result<SweepRow, SweepError> {
        let params: Vec<String> = self
            .columns
            .iter()
            .map(|c| {
                point
                    .params
                    .iter()
                    .find(|(k, _)| k == c)
                    .map(|(_, v)| value_cell(v))
                    .unwrap_or_default()
            })
            .collect();
        let row = SweepRow {
            index: point.index,
            id: point.id(),
            params,
            summary: *summary,
            objective: objective.of(summary),
        };
        let line = csv_line(&row_fields(&row));
        let mut f = self.file.lock().unwrap_or_else(|e| e.into_inner());
        f.write_all(line.as_bytes()).map_err(io_err(&self.path))?;
        f.flush().map_err(io_err(&self.path))?;
        Ok(row)
    }

    /// Rewrites the file sorted by index (call when every config has finished).
    pub fn finish(self) -> Result<Vec<SweepRow>, SweepError> {
        drop(self.file);
        let expected = header(&self.columns);
        let mut rows = read_rows(&self.path, &expected)?;
        rows.sort_by_key(|r| r.index);
        rows.dedup_by_key(|r| r.index);
        write_rows(&self.path, &expected, &rows)?;
        Ok(rows)
    }
}

fn row_fields(r: &SweepRow) -> Vec<String> {
    let s = &r.summary;
    let mut f = vec![r.index.to_string(), r.id.clone()];
    f.extend(r.params.iter().cloned());
    f.extend([
        s.count.to_string(),
        s.skipped.to_string(),
        format!("{:.6}", s.mean),
        format!("{:.6}", s.rms),
        format!("{:.6}", s.p50),
        format!("{:.6}", s.p75),
        format!("{:.6}", s.p95),
        format!("{:.6}", s.max),
        format!("{:.6}", r.objective),
    ]);
    f
}

fn write_rows(path: &Path, header: &[String], rows: &[SweepRow]) -> Result<(), SweepError> {
    let tmp = path.with_extension("csv.tmp");
    let mut text = csv_line(header);
    for r in rows {
        text.push_str(&csv_line(&row_fields(r)));
    }
    std::fs::write(&tmp, text).map_err(io_err(&tmp))?;
    std::fs::rename(&tmp, path).map_err(io_err(path))?;
    Ok(())
}

/// Reads the rows of a results file whose header must equal `expected`. A final line without
/// its newline (a run stopped mid-write) is dropped with a warning.
pub fn read_rows(path: &Path, expected: &[String]) -> Result<Vec<SweepRow>, SweepError> {
    let text = std::fs::read_to_string(path).map_err(io_err(path))?;
    let torn = !text.is_empty() && !text.ends_with('\n');
    let complete = if torn {
        tracing::warn!(file = %path.display(), "dropping a torn last line");
        &text[..text.rfind('\n').map(|i| i + 1).unwrap_or(0)]
    } else {
        &text[..]
    };
    let mut rdr = csv::ReaderBuilder::new()
        .has_headers(false)
        .flexible(true)
        .from_reader(BufReader::new(complete.as_bytes()));
    let mut rows = Vec::new();
    let bad = |line: usize, reason: String| SweepError::Results {
        path: path.to_path_buf(),
        line,
        reason,
    };
    let n_params = expected.len() - 2 - FIGURES.len();
    for (i, rec) in rdr.records().enumerate() {
        let line = i + 1;
        let rec = rec.map_err(|e| bad(line, e.to_string()))?;
        let fields: Vec<String> = rec.iter().map(|s| s.to_string()).collect();
        if i == 0 {
            if fields != expected {
                return Err(bad(
                    line,
                    format!("header {fields:?} does not match this sweep's {expected:?}"),
                ));
            }
            continue;
        }
        if fields.len() != expected.len() {
            return Err(bad(
                line,
                format!("{} fields, expected {}", fields.len(), expected.len()),
            ));
        }
        let num = |j: usize| -> Result<f64, SweepError> {
            fields[j]
                .parse::<f64>()
                .map_err(|_| bad(line, format!("field {:?} is not a number", expected[j])))
        };
        let base = 2 + n_params;
        let summary = Summary {
            count: num(base)? as usize,
            skipped: num(base + 1)? as usize,
            mean: num(base + 2)?,
            rms: num(base + 3)?,
            p50: num(base + 4)?,
            p75: num(base + 5)?,
            p95: num(base + 6)?,
            max: num(base + 7)?,
        };
        rows.push(SweepRow {
            index: num(0)? as usize,
            id: fields[1].clone(),
            params: fields[2..base].to_vec(),
            summary,
            objective: num(base + 8)?,
        });
    }
    Ok(rows)
}

/// The ids already finished in `rows`.
pub fn finished_ids(rows: &[SweepRow]) -> HashSet<String> {
    rows.iter().map(|r| r.id.clone()).collect()
}

/// Joins shard files of one sweep into `out`, sorted by index (duplicates dropped).
pub fn merge(shards: &[PathBuf], out: &Path) -> Result<Vec<SweepRow>, SweepError> {
    let first = shards
        .first()
        .ok_or_else(|| SweepError::Spec("nothing to merge".into()))?;
    let head_line = BufReader::new(File::open(first).map_err(io_err(first))?)
        .lines()
        .next()
        .transpose()
        .map_err(io_err(first))?
        .ok_or_else(|| SweepError::Results {
            path: first.clone(),
            line: 1,
            reason: "empty file".into(),
        })?;
    let header: Vec<String> = csv::ReaderBuilder::new()
        .has_headers(false)
        .from_reader(head_line.as_bytes())
        .records()
        .next()
        .and_then(|r| r.ok())
        .map(|r| r.iter().map(|s| s.to_string()).collect())
        .unwrap_or_default();
    if header.len() < 2 + FIGURES.len() {
        return Err(SweepError::Results {
            path: first.clone(),
            line: 1,
            reason: "not a sweep results file".into(),
        });
    }
    let mut rows = Vec::new();
    for s in shards {
        rows.extend(read_rows(s, &header)?);
    }
    rows.sort_by_key(|r| r.index);
    rows.dedup_by_key(|r| r.index);
    write_rows(out, &header, &rows)?;
    Ok(rows)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec() -> SweepSpec {
        toml::from_str(
            r#"
            scheme = "ekf"
            [grid]
            "a.b" = [1, 2]
            [random]
            samples = 3
            seed = 9
            [random.ranges]
            "a.c" = { min = 0.1, max = 10.0, log = true }
            "d" = { min = 1, max = 4, integer = true }
            "#,
        )
        .unwrap()
    }

    #[test]
    fn expansion_is_deterministic_and_in_range() {
        let a = spec().expand().unwrap();
        let b = spec().expand().unwrap();
        assert_eq!(a, b);
        assert_eq!(a.len(), 6);
        for p in &a {
            let c = p.params[1].1.as_f64().unwrap();
            assert!((0.1..=10.0).contains(&c));
            let d = p.params[2].1.as_i64().unwrap();
            assert!((1..=4).contains(&d));
        }
        assert_eq!(spec().columns(), vec!["a.b", "a.c", "d"]);
    }

    #[test]
    fn set_path_rejects_unknown_fields() {
        let mut v = serde_json::json!({"a": {"b": 1}});
        set_path(&mut v, "a.b", Value::from(3)).unwrap();
        assert_eq!(v["a"]["b"], 3);
        assert!(set_path(&mut v, "a.x", Value::from(3)).is_err());
        assert!(set_path(&mut v, "a.b.c", Value::from(3)).is_err());
    }

    #[test]
    fn shards_partition_the_sweep() {
        let all = spec().expand().unwrap();
        let mut seen: Vec<usize> = (0..3)
            .flat_map(|i| shard(all.clone(), i, 3))
            .map(|p| p.index)
            .collect();
        seen.sort();
        assert_eq!(seen, (0..all.len()).collect::<Vec<_>>());
    }

    #[test]
    fn resume_drops_torn_line_and_finish_sorts() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("r.csv");
        let s = spec();
        let pts = s.expand().unwrap();
        let sum = Summary {
            count: 3,
            mean: 1.5,
            ..Default::default()
        };
        {
            let (f, rows) = ResultsFile::open(&path, s.columns(), false).unwrap();
            assert!(rows.is_empty());
            f.append(&pts[2], &sum, Objective::Mean).unwrap();
            f.append(&pts[0], &sum, Objective::Mean).unwrap();
        }
        // A torn write.
        let mut t = OpenOptions::new().append(true).open(&path).unwrap();
        t.write_all(b"5,\"{\\\"a").unwrap();
        drop(t);
        assert!(ResultsFile::open(&path, s.columns(), false).is_err());
        let (f, rows) = ResultsFile::open(&path, s.columns(), true).unwrap();
        assert_eq!(rows.len(), 2);
        let done = finished_ids(&rows);
        assert!(done.contains(&pts[2].id()));
        f.append(&pts[1], &sum, Objective::Mean).unwrap();
        let rows = f.finish().unwrap();
        assert_eq!(
            rows.iter().map(|r| r.index).collect::<Vec<_>>(),
            vec![0, 1, 2]
        );
        let merged = dir.path().join("m.csv");
        let m = merge(&[path.clone(), path], &merged).unwrap();
        assert_eq!(m.len(), 3);
    }
}

/// Options of [`run_sweep`].
#[derive(Debug, Clone, Default)]
pub struct SweepOptions {
    /// Continue an existing results file (skip finished configs).
    pub resume: bool,
    /// Run only shard `.0` of `.1` (`index % n == i`).
    pub shard: Option<(usize, usize)>,
    /// Stop after this many configs have finished in this run (the rest stays to resume).
    pub max_configs: Option<usize>,
    /// A stop request (e.g. set by a Ctrl-C handler): once it is `true`, no new config starts;
    /// configs already running finish and are written, and the run returns incomplete, ready
    /// to be resumed.
    pub stop: Option<Arc<AtomicBool>>,
}

impl SweepOptions {
    /// Whether a stop was requested.
    pub fn stop_requested(&self) -> bool {
        self.stop
            .as_ref()
            .is_some_and(|flag| flag.load(Ordering::SeqCst))
    }
}

/// The outcome of [`run_sweep`].
#[derive(Debug, Clone)]
pub struct SweepOutcome {
    /// Every finished row in the file, sorted by index (when the run completed) or as far as
    /// it got.
    pub rows: Vec<SweepRow>,
    /// Configs this run evaluated.
    pub ran: usize,
    /// Configs skipped because the file already had them.
    pub skipped: usize,
    /// Whether every config of this (shard of the) sweep is now in the file.
    pub complete: bool,
    /// Whether the run ended early because [`SweepOptions::stop`] was set.
    pub stopped: bool,
}

/// Builds the evaluation config of one sweep point: `fuser.` paths address the scheme's
/// config (`schemes.<scheme>.`), other paths the evaluation config itself.
pub fn config_for(
    base: &crate::pipeline::EvalConfig,
    scheme: &str,
    point: &SweepPoint,
) -> Result<crate::pipeline::EvalConfig, SweepError> {
    let mut cfg = base.clone();
    if !cfg.schemes.contains_key(scheme) {
        let d = cfg
            .scheme(scheme)
            .map_err(|e| SweepError::Spec(e.to_string()))?;
        cfg.schemes.insert(scheme.to_string(), d);
    }
    let mut v = serde_json::to_value(&cfg).map_err(|e| SweepError::Spec(e.to_string()))?;
    for (path, value) in &point.params {
        let full = match path.strip_prefix("fuser.") {
            Some(rest) => format!("schemes.{scheme}.{rest}"),
            None => path.clone(),
        };
        set_path(&mut v, &full, value.clone())?;
    }
    serde_json::from_value(v)
        .map_err(|e| SweepError::Spec(format!("config of sweep point {}: {e}", point.index)))
}

/// Runs a sweep over prepared floors: configs grouped by what [`crate::pipeline::prepare`]
/// depends on (so fusion-only sweeps prepare once), each group's configs in parallel, every
/// finished config appended to `out` at once. `on_done` is called after each config.
pub fn run_sweep(
    spec: &SweepSpec,
    base: &crate::pipeline::EvalConfig,
    floors: &[crate::pipeline::FloorInput],
    out: &Path,
    options: &SweepOptions,
    on_done: &(dyn Fn() + Sync),
) -> Result<SweepOutcome, crate::pipeline::EvalError> {
    use rayon::prelude::*;
    let to_eval = |e: SweepError| crate::pipeline::EvalError::Sweep(e.to_string());
    base.scheme(&spec.scheme)?;
    let mut points = spec.expand().map_err(to_eval)?;
    if let Some((i, n)) = options.shard {
        if n == 0 || i >= n {
            return Err(to_eval(SweepError::Spec(format!(
                "shard {i}/{n}: need I < N"
            ))));
        }
        points = shard(points, i, n);
    }
    let (file, done_rows) =
        ResultsFile::open(out, spec.columns(), options.resume).map_err(to_eval)?;
    let done = finished_ids(&done_rows);
    let todo: Vec<SweepPoint> = points
        .iter()
        .filter(|p| !done.contains(&p.id()))
        .cloned()
        .collect();
    let skipped = points.len() - todo.len();
    let budget = options.max_configs.unwrap_or(usize::MAX).min(todo.len());
    let todo = &todo[..budget];
    // Group by preparation key, keeping sweep order inside groups.
    let mut groups: Vec<(String, Vec<(SweepPoint, crate::pipeline::EvalConfig)>)> = Vec::new();
    for p in todo {
        let cfg = config_for(base, &spec.scheme, p).map_err(to_eval)?;
        let key = cfg.preparation_key();
        match groups.iter_mut().find(|g| g.0 == key) {
            Some(g) => g.1.push((p.clone(), cfg)),
            None => groups.push((key, vec![(p.clone(), cfg)])),
        }
    }
    let schemes = vec![spec.scheme.clone()];
    let mut ran = 0;
    for (_, group) in &groups {
        if options.stop_requested() {
            break;
        }
        let prepared = crate::pipeline::prepare(floors, &group[0].1)?;
        // Each config reports whether it ran (false: skipped because a stop was requested
        // before it started).
        let results: Vec<Result<bool, crate::pipeline::EvalError>> = group
            .par_iter()
            .map(|(p, cfg)| {
                if options.stop_requested() {
                    return Ok(false);
                }
                let report =
                    crate::pipeline::run_prepared(floors, &prepared, cfg, &schemes, &|| {})?;
                let summary = report.pooled.get(&spec.scheme).copied().unwrap_or_default();
                file.append(p, &summary, spec.objective).map_err(to_eval)?;
                on_done();
                Ok(true)
            })
            .collect();
        for r in results {
            if r? {
                ran += 1;
            }
        }
    }
    let stopped = options.stop_requested() && skipped + ran < points.len();
    let complete = skipped + ran == points.len();
    let rows = if complete {
        file.finish().map_err(to_eval)?
    } else {
        drop(file);
        read_rows(out, &header(&spec.columns())).map_err(to_eval)?
    };
    Ok(SweepOutcome {
        rows,
        ran,
        skipped,
        complete,
        stopped,
    })
}
