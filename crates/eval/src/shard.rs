//! Sharded evaluation: one evaluation spread over machines (Slurm array tasks, Kubernetes
//! indexed jobs, plain processes), then merged into exactly the unsharded result.
//!
//! ## Work items
//!
//! The unit of work is a **work item**: one protocol fold of one floor
//! ([`pipeline::work_items`]: `(floor index, fold)`, floor by floor, folds in order). A work
//! item builds its fold's model (radio map, matcher, calibration) from the floor's *other*
//! folds, prepares the fold's test walks and runs every scheme over them. Shard `I/N` runs the
//! items whose position `k` in that list has `k % N == I` ([`shard_items`]). Floor x fold is
//! the finer split: five floors over four machines would leave one machine two floors while
//! the others wait, whereas their 25 folds deal out 7/6/6/6, and dealing them round-robin
//! spreads each floor's folds (and a large floor's cost) over the shards. A shard still reads
//! every floor (a fold learns from its floor's other walks, and the run identity hashes the
//! whole data), so the parse cache belongs on storage the nodes share.
//!
//! ## Shard file (JSON)
//!
//! `wipdr eval --shard I/N --json PART.json` writes a [`ShardReport`]: the run identity
//! ([`EvalIdentity`]: config, schemes, data, the whole list of work items, the shard), the
//! items this shard ran, and its per-walk results with every scored point. `wipdr eval
//! merge` ([`merge`]) checks that the parts are the `N` shards of one run, each once, and
//! recomputes every figure (pooled, per floor) from the per-point errors with
//! [`EvalReport::from_walks`], walks in the unsharded run's order, so the merged
//! [`EvalReport::json_document`] is byte for byte the unsharded `--json`.
//!
//! ```
//! use wipdr_eval::shard::shard_items;
//! use wipdr_eval::sweep::ShardId;
//! let items = [(0, 0), (0, 1), (0, 2), (1, 0), (1, 1)];
//! let s = ShardId { index: 1, count: 2 };
//! assert_eq!(shard_items(&items, s), vec![(0, 1), (1, 0)]);
//! ```

use crate::config::EvalConfig;
use crate::error::EvalError;
use crate::input::FloorInput;
use crate::pipeline;
use crate::report::{EvalReport, WalkResult};
use crate::sweep::identity::{data_difference, hashed_difference};
use crate::sweep::{DataIdentity, ShardId, data_identity, json_hash};
use serde::{Deserialize, Serialize};
use serde_json::Value;
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use thiserror::Error;

/// The version of the shard file format.
pub const SHARD_FORMAT: u32 = 1;

/// The `kind` field of a shard file (so another JSON file is not read as one).
pub const SHARD_KIND: &str = "wipdr-eval-shard";

/// Errors of sharded evaluation.
#[derive(Debug, Error)]
pub enum ShardError {
    /// The evaluation itself failed.
    #[error(transparent)]
    Eval(#[from] EvalError),
    /// Reading or writing a shard file.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// A file that is not a readable shard file.
    #[error("{path}, line {line}: {reason}")]
    Parse {
        /// The file.
        path: PathBuf,
        /// 1-based line (0: the whole file).
        line: usize,
        /// Why.
        reason: String,
    },
    /// A shard of another run: config, schemes or data differ.
    #[error("{path} is not of the same run as {other} (values: {path} vs {other}): {}", differences.join("; "))]
    Mismatch {
        /// The refused file.
        path: PathBuf,
        /// The file it was compared with.
        other: PathBuf,
        /// One message per part that differs.
        differences: Vec<String>,
    },
    /// The parts are not each shard of one split exactly once.
    #[error("{0}")]
    Shards(String),
    /// Shards are missing: the merge would not be the whole run.
    #[error(
        "incomplete: {given} of {count} shards given, missing shard(s) {}; run them (wipdr eval --shard I/{count}) and merge all {count}",
        missing.iter().map(|i| format!("{i}/{count}")).collect::<Vec<_>>().join(", ")
    )]
    Incomplete {
        /// Shards given.
        given: usize,
        /// Shards in the split.
        count: usize,
        /// The missing shard indices.
        missing: Vec<usize>,
    },
}

/// What a shard was measured on: equal (but for the shard) in every part of one run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EvalIdentity {
    /// [`SHARD_FORMAT`].
    pub format: u32,
    /// Hash of the evaluation config's canonical JSON ([`crate::sweep::config_hash`]).
    pub config_hash: String,
    /// The evaluation config (the merged JSON's `"config"`; names a differing field).
    pub config: Value,
    /// The schemes, in the order asked for.
    pub schemes: Vec<String>,
    /// The data: one content hash per floor (the folder path left out).
    pub data: DataIdentity,
    /// Every work item of the whole run, `(floor index, fold)`.
    pub items: Vec<(usize, usize)>,
    /// This shard.
    pub shard: ShardId,
}

impl EvalIdentity {
    /// The identity of shard `shard` of an evaluation of `schemes` under `cfg` on `floors`.
    pub fn new(
        floors: &[FloorInput],
        cfg: &EvalConfig,
        schemes: &[String],
        shard: ShardId,
    ) -> Result<Self, ShardError> {
        let config = serde_json::to_value(cfg).map_err(|e| ShardError::Parse {
            path: PathBuf::from("(config)"),
            line: 0,
            reason: format!("serialising the config: {e}"),
        })?;
        let data = data_identity(floors).map_err(|e| EvalError::Sweep(e.to_string()))?;
        Ok(Self {
            format: SHARD_FORMAT,
            config_hash: json_hash(&config),
            config,
            schemes: schemes.to_vec(),
            data,
            items: pipeline::work_items(floors)?,
            shard,
        })
    }

    /// How `other`'s run differs from this one's (the shard index left out), one message
    /// per part; empty when both are shards of one run.
    pub fn run_differences(&self, other: &Self) -> Vec<String> {
        let mut out = Vec::new();
        if self.format != other.format {
            out.push(format!(
                "shard format differs: {} vs {}",
                self.format, other.format
            ));
        }
        out.extend(hashed_difference(
            "config",
            (&self.config_hash, &self.config),
            (&other.config_hash, &other.config),
        ));
        if self.schemes != other.schemes {
            out.push(format!(
                "schemes differ: {} vs {}",
                self.schemes.join(","),
                other.schemes.join(",")
            ));
        }
        out.extend(data_difference(&self.data, &other.data));
        if out.is_empty() && self.items != other.items {
            out.push(format!(
                "work items differ: {} vs {}",
                self.items.len(),
                other.items.len()
            ));
        }
        if self.shard.count != other.shard.count {
            out.push(format!(
                "shard count differs: shard {} vs shard {}",
                self.shard, other.shard
            ));
        }
        out
    }
}

/// The work items of shard `shard`: those at positions `k` with `k % count == index`.
pub fn shard_items(items: &[(usize, usize)], shard: ShardId) -> Vec<(usize, usize)> {
    items
        .iter()
        .enumerate()
        .filter(|(k, _)| k % shard.count == shard.index)
        .map(|(_, &item)| item)
        .collect()
}

/// A shard file: what one shard ran and its per-walk results.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ShardReport {
    /// [`SHARD_KIND`].
    pub kind: String,
    /// The run and the shard.
    pub identity: EvalIdentity,
    /// The work items this shard ran, `(floor index, fold)`.
    pub ran: Vec<(usize, usize)>,
    /// Its per-walk results (every scored point), in its run's order.
    pub walks: Vec<WalkResult>,
    /// Its runs left out for a missing stream.
    #[serde(default)]
    pub skipped_runs: Vec<crate::report::SkippedRun>,
    /// What the readers skipped, per floor (the same in every shard of a run: each reads
    /// every floor).
    #[serde(default)]
    pub input_skips: BTreeMap<String, crate::report::InputSkips>,
    /// Its walks' motion-source segment errors.
    #[serde(default)]
    pub motion: Vec<crate::report::WalkMotion>,
    /// Its walks' scan likelihood calibration.
    #[serde(default)]
    pub scan_likelihood: Vec<crate::report::WalkScanLikelihood>,
}

impl ShardReport {
    /// The shard file of `report`, the result of running `ran` under `identity`.
    pub fn new(identity: EvalIdentity, ran: Vec<(usize, usize)>, report: EvalReport) -> Self {
        Self {
            kind: SHARD_KIND.into(),
            identity,
            ran,
            walks: report.walks,
            skipped_runs: report.skipped_runs,
            input_skips: report.input_skips,
            motion: report.motion,
            scan_likelihood: report.scan_likelihood,
        }
    }

    /// Writes the file (a temporary file, then a rename: a killed task leaves no half file).
    pub fn write(&self, path: &Path) -> Result<(), ShardError> {
        let io = |path: &Path| {
            let path = path.to_path_buf();
            move |source| ShardError::Io { path, source }
        };
        let mut text = serde_json::to_string(self).map_err(|e| ShardError::Parse {
            path: path.to_path_buf(),
            line: 0,
            reason: format!("serialising: {e}"),
        })?;
        text.push('\n');
        if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
            std::fs::create_dir_all(parent).map_err(io(parent))?;
        }
        let mut tmp = path.as_os_str().to_owned();
        tmp.push(".tmp");
        let tmp = PathBuf::from(tmp);
        std::fs::write(&tmp, text).map_err(io(&tmp))?;
        std::fs::rename(&tmp, path).map_err(io(path))
    }

    /// Reads a shard file. JSON has no NaN: a non-finite error is written as `null`, and read
    /// back as NaN (every figure leaves non-finite errors out alike, and the merged JSON
    /// writes `null` again).
    pub fn read(path: &Path) -> Result<Self, ShardError> {
        let bad = |line: usize, reason: String| ShardError::Parse {
            path: path.to_path_buf(),
            line,
            reason,
        };
        let text = std::fs::read_to_string(path).map_err(|source| ShardError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        let mut value: Value =
            serde_json::from_str(&text).map_err(|e| bad(e.line(), e.to_string()))?;
        if value.get("kind").and_then(Value::as_str) != Some(SHARD_KIND) {
            return Err(bad(
                0,
                format!(
                    "not a shard file (no \"kind\": \"{SHARD_KIND}\"; write one with wipdr eval --shard I/N --json)"
                ),
            ));
        }
        let non_finite = take_null_errors(&mut value);
        let mut report: Self = serde_json::from_value(value).map_err(|e| bad(0, e.to_string()))?;
        for (w, p) in non_finite {
            if let Some(point) = report
                .walks
                .get_mut(w)
                .and_then(|w| w.score.errors.get_mut(p))
            {
                point.1 = f64::NAN;
            }
        }
        if report.identity.format != SHARD_FORMAT {
            return Err(bad(
                0,
                format!(
                    "shard format {} (this wipdr reads {SHARD_FORMAT})",
                    report.identity.format
                ),
            ));
        }
        Ok(report)
    }
}

/// Replaces each `null` error value (`walks[w].score.errors[p][1]`, a non-finite error as
/// JSON writes it) with 0 and returns its `(w, p)`.
fn take_null_errors(value: &mut Value) -> Vec<(usize, usize)> {
    let mut found = Vec::new();
    let Some(walks) = value.get_mut("walks").and_then(Value::as_array_mut) else {
        return found;
    };
    for (w, walk) in walks.iter_mut().enumerate() {
        let Some(errors) = walk
            .pointer_mut("/score/errors")
            .and_then(Value::as_array_mut)
        else {
            continue;
        };
        for (p, point) in errors.iter_mut().enumerate() {
            if let Some(e) = point.get_mut(1).filter(|e| e.is_null()) {
                *e = Value::from(0.0);
                found.push((w, p));
            }
        }
    }
    found
}

/// A merged run: the report and the config it ran under.
#[derive(Debug, Clone, PartialEq)]
pub struct Merged {
    /// The whole run's report, every figure recomputed from the per-point errors.
    pub report: EvalReport,
    /// The evaluation config (serialised), for [`EvalReport::json_document`].
    pub config: Value,
    /// The shards merged.
    pub count: usize,
}

/// Merges the shard files `parts` into the whole run. Refused when a file is not a shard
/// file, when the parts are of different runs (config, schemes or data: named), when a
/// shard is given twice or one is missing, or when a part holds results outside its work
/// items.
pub fn merge(parts: &[PathBuf]) -> Result<Merged, ShardError> {
    let first = parts
        .first()
        .ok_or_else(|| ShardError::Shards("nothing to merge: give the shard files".into()))?;
    let reports: Vec<ShardReport> = parts
        .iter()
        .map(|p| ShardReport::read(p))
        .collect::<Result<_, _>>()?;
    let reference = &reports[0].identity;
    let count = reference.shard.count;
    let mut seen: BTreeMap<usize, &PathBuf> = BTreeMap::new();
    for (path, r) in parts.iter().zip(&reports) {
        let differences = r.identity.run_differences(reference);
        if !differences.is_empty() {
            return Err(ShardError::Mismatch {
                path: path.clone(),
                other: first.clone(),
                differences,
            });
        }
        let index = r.identity.shard.index;
        if let Some(other) = seen.insert(index, path) {
            return Err(ShardError::Shards(format!(
                "{} and {} are both shard {}",
                other.display(),
                path.display(),
                r.identity.shard
            )));
        }
        check_part(path, r)?;
    }
    let missing: Vec<usize> = (0..count).filter(|i| !seen.contains_key(i)).collect();
    if !missing.is_empty() {
        return Err(ShardError::Incomplete {
            given: seen.len(),
            count,
            missing,
        });
    }
    let labels: Vec<String> = reference
        .data
        .floors
        .iter()
        .map(|f| f.label.clone())
        .collect();
    let schemes = reference.schemes.clone();
    let config = reference.config.clone();
    let input_skips = reports[0].input_skips.clone();
    let mut skipped_runs: Vec<crate::report::SkippedRun> = reports
        .iter()
        .flat_map(|r| r.skipped_runs.iter().cloned())
        .collect();
    let mut motion: Vec<crate::report::WalkMotion> = reports
        .iter()
        .flat_map(|r| r.motion.iter().cloned())
        .collect();
    let mut scan_likelihood: Vec<crate::report::WalkScanLikelihood> = reports
        .iter()
        .flat_map(|r| r.scan_likelihood.iter().cloned())
        .collect();
    let mut walks: Vec<WalkResult> = reports.into_iter().flat_map(|r| r.walks).collect();
    // The unsharded order: walks by (floor, walk id) as `pipeline::prepare` sorts them
    // (ties by fold), each walk's schemes in the order asked for.
    let position = |names: &[String], name: &str| names.iter().position(|n| n == name);
    walks.sort_by_cached_key(|w| {
        (
            position(&labels, &w.floor),
            w.walk.clone(),
            w.fold,
            position(&schemes, &w.scheme),
        )
    });
    // The unsharded order of the skipped runs: pipeline order (floor, walk, fold, scheme).
    skipped_runs.sort_by_cached_key(|r| {
        (
            position(&labels, &r.floor),
            r.walk.clone(),
            r.fold,
            position(&schemes, &r.scheme),
        )
    });
    // The unsharded order of the motion rows: the prepared walks' (floor, walk, fold).
    motion.sort_by_cached_key(|m| (position(&labels, &m.floor), m.walk.clone(), m.fold));
    scan_likelihood.sort_by_cached_key(|m| (position(&labels, &m.floor), m.walk.clone(), m.fold));
    Ok(Merged {
        report: EvalReport::from_walks(schemes, labels, walks)
            .with_skips(skipped_runs, input_skips)
            .with_motion(motion)
            .with_scan_likelihood(scan_likelihood),
        config,
        count,
    })
}

/// A part ran exactly its shard's items, and holds results of those items and schemes only.
fn check_part(path: &Path, r: &ShardReport) -> Result<(), ShardError> {
    let id = &r.identity;
    let refuse = |why: String| ShardError::Shards(format!("{}: {why}", path.display()));
    let expected = shard_items(&id.items, id.shard);
    if r.ran != expected {
        return Err(refuse(format!(
            "ran {} work items, shard {} has {}: not a finished shard of this run",
            r.ran.len(),
            id.shard,
            expected.len()
        )));
    }
    let ran: BTreeSet<(usize, usize)> = r.ran.iter().copied().collect();
    for w in &r.walks {
        let floor = id.data.floors.iter().position(|f| f.label == w.floor);
        let ok =
            floor.is_some_and(|fi| ran.contains(&(fi, w.fold))) && id.schemes.contains(&w.scheme);
        if !ok {
            return Err(refuse(format!(
                "result of floor {:?} fold {} scheme {:?} (walk {:?}) is not of this shard's work items",
                w.floor, w.fold, w.scheme, w.walk
            )));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scoring::WalkScore;
    use crate::sweep::{FloorIdentity, StableHasher};

    fn identity(index: usize, count: usize) -> EvalIdentity {
        let floor = FloorIdentity {
            label: "s/F1".into(),
            walks: 2,
            hash: StableHasher::default().hex(),
        };
        EvalIdentity {
            format: SHARD_FORMAT,
            config_hash: json_hash(&serde_json::json!({"seed": 1})),
            config: serde_json::json!({"seed": 1}),
            schemes: vec!["wifi".into(), "ekf".into()],
            data: DataIdentity {
                hash: "d".into(),
                floors: vec![floor],
            },
            items: vec![(0, 0), (0, 1), (0, 2)],
            shard: ShardId { index, count },
        }
    }

    fn result(walk: &str, fold: usize, scheme: &str, error: f64) -> WalkResult {
        WalkResult {
            floor: "s/F1".into(),
            walk: walk.into(),
            fold,
            scheme: scheme.into(),
            first_scan_t: Some(5),
            score: WalkScore {
                errors: vec![(10, error, Some(0)), (20, 2.0 * error, Some(0))],
                skipped: 1,
                floor_scored: 0,
                sd_m: vec![Some(1.0), None],
                coverage_m: vec![Some(3.0), Some(40.0)],
            },
        }
    }

    fn part(dir: &Path, name: &str, index: usize, count: usize, walks: Vec<WalkResult>) -> PathBuf {
        let id = identity(index, count);
        let ran = shard_items(&id.items, id.shard);
        let path = dir.join(name);
        let report = EvalReport::from_walks(vec![], vec![], walks);
        ShardReport::new(id, ran, report).write(&path).unwrap();
        path
    }

    #[test]
    fn shards_deal_every_item_once() {
        let items: Vec<(usize, usize)> = (0..3).flat_map(|f| (0..5).map(move |k| (f, k))).collect();
        for count in 1..=20 {
            let mut all: Vec<(usize, usize)> = (0..count)
                .flat_map(|index| shard_items(&items, ShardId { index, count }))
                .collect();
            all.sort_unstable();
            assert_eq!(all, items, "count {count}");
        }
    }

    #[test]
    fn merge_restores_order_and_recomputes_pooled() {
        let dir = tempfile::tempdir().unwrap();
        // Shard 0 ran folds 0 and 2, shard 1 fold 1.
        let p0 = part(
            dir.path(),
            "p0.json",
            0,
            2,
            vec![
                result("c", 2, "wifi", 3.0),
                result("c", 2, "ekf", 1.0),
                result("a", 0, "wifi", 1.0),
                result("a", 0, "ekf", f64::NAN),
            ],
        );
        let p1 = part(
            dir.path(),
            "p1.json",
            1,
            2,
            vec![result("b", 1, "wifi", 2.0), result("b", 1, "ekf", 4.0)],
        );
        let m = merge(&[p1.clone(), p0.clone()]).unwrap();
        let order: Vec<(&str, &str)> = m
            .report
            .walks
            .iter()
            .map(|w| (w.walk.as_str(), w.scheme.as_str()))
            .collect();
        assert_eq!(
            order,
            [
                ("a", "wifi"),
                ("a", "ekf"),
                ("b", "wifi"),
                ("b", "ekf"),
                ("c", "wifi"),
                ("c", "ekf")
            ]
        );
        // Pooled from the points: wifi errors 1,2,2,4,3,6.
        assert_eq!(m.report.pooled["wifi"].count, 6);
        assert!((m.report.pooled["wifi"].mean - 3.0).abs() < 1e-12);
        // The NaN came back as NaN (left out of the figures, as unsharded).
        assert!(m.report.walks[1].score.errors[0].1.is_nan());
        assert!(m.report.walks[1].score.errors[1].1.is_nan());
        assert_eq!(m.report.pooled["ekf"].count, 4);
        assert_eq!(m.report.walks[0].first_scan_t, Some(5));
    }

    #[test]
    fn merge_refuses_missing_duplicate_and_foreign_shards() {
        let dir = tempfile::tempdir().unwrap();
        let p0 = part(
            dir.path(),
            "p0.json",
            0,
            2,
            vec![result("a", 0, "wifi", 1.0)],
        );
        let p1 = part(
            dir.path(),
            "p1.json",
            1,
            2,
            vec![result("b", 1, "wifi", 1.0)],
        );
        let e = merge(std::slice::from_ref(&p0)).unwrap_err().to_string();
        assert!(
            e.contains("incomplete: 1 of 2 shards given, missing shard(s) 1/2"),
            "{e}"
        );
        let e = merge(&[p0.clone(), p0.clone()]).unwrap_err().to_string();
        assert!(e.contains("are both shard 0/2"), "{e}");
        // A result outside the shard's items.
        let bad = part(
            dir.path(),
            "bad.json",
            1,
            2,
            vec![result("a", 0, "wifi", 1.0)],
        );
        let e = merge(&[p0.clone(), bad]).unwrap_err().to_string();
        assert!(e.contains("is not of this shard's work items"), "{e}");
        // Another config.
        let mut id = identity(1, 2);
        id.config = serde_json::json!({"seed": 2});
        id.config_hash = json_hash(&id.config);
        let other = dir.path().join("other.json");
        let ran = shard_items(&id.items, id.shard);
        ShardReport::new(id, ran, EvalReport::default())
            .write(&other)
            .unwrap();
        let e = merge(&[p0.clone(), other]).unwrap_err().to_string();
        assert!(
            e.contains("config differs") && e.contains("seed: 2 vs 1"),
            "{e}"
        );
        // Another split.
        let q = part(dir.path(), "q.json", 2, 3, vec![]);
        let e = merge(&[p0.clone(), q]).unwrap_err().to_string();
        assert!(e.contains("shard count differs"), "{e}");
        // Not a shard file.
        let plain = dir.path().join("plain.json");
        std::fs::write(&plain, "{\"pooled\": {}}").unwrap();
        let e = merge(&[plain]).unwrap_err().to_string();
        assert!(e.contains("not a shard file"), "{e}");
        assert!(merge(&[p0, p1]).is_ok());
    }
}
