//! The results file: one CSV row per finished config, appended and flushed at once, read back
//! on resume, sorted when the run completes, joined from shards by [`merge`]; its run identity
//! lives beside it ([`RunIdentity`]).

use super::SweepError;
use super::identity::{RunIdentity, ShardId};
use super::spec::{Objective, SweepPoint};
use crate::report::Summary;
use serde_json::Value;
use std::collections::{BTreeMap, HashSet};
use std::fs::{File, OpenOptions};
use std::io::{BufReader, Write};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// One finished config.
#[derive(Debug, Clone, PartialEq)]
pub struct SweepRow {
    /// Sweep index.
    pub index: usize,
    /// Readable id ([`SweepPoint::id`]).
    pub id: String,
    /// Hash of the config that was measured ([`super::config_hash`]): a row is only ever
    /// attributed to the config with this hash.
    pub config_hash: String,
    /// Parameter values as written.
    pub params: Vec<String>,
    /// The figures.
    pub summary: Summary,
    /// The objective's value.
    pub objective: f64,
}

const FIGURES: [&str; 12] = [
    "count",
    "skipped",
    "mean",
    "rms",
    "p50",
    "p75",
    "p95",
    "max",
    "floor_hit_rate",
    "evaal",
    "radius_95_coverage",
    "objective",
];

/// An optional figure's cell: empty when the summary has none.
fn optional_cell(v: Option<f64>) -> String {
    v.map(|v| format!("{v:.6}")).unwrap_or_default()
}

/// Leading columns: `index, id, config_hash`.
const LEAD: usize = 3;

/// The results file: appends finished rows at once, resumes, canonicalises.
#[derive(Debug)]
pub struct ResultsFile {
    path: PathBuf,
    columns: Vec<String>,
    file: Mutex<File>,
}

pub(crate) fn io_err(path: &Path) -> impl FnOnce(std::io::Error) -> SweepError + '_ {
    move |source| SweepError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// The header of a results file with parameter `columns`.
pub fn header(columns: &[String]) -> Vec<String> {
    let mut h = vec![
        "index".to_string(),
        "id".to_string(),
        "config_hash".to_string(),
    ];
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

fn non_empty(path: &Path) -> bool {
    std::fs::metadata(path).is_ok_and(|m| m.len() > 0)
}

impl ResultsFile {
    /// Opens `path` for the run `identity`. With `resume`, an existing file must have been
    /// written by the same run (spec, base config, data and shard, checked against its
    /// sidecar: [`SweepError::Mismatch`] names what differs), and its rows are read back (a
    /// torn last line is dropped) and returned; without it, an existing file is an error
    /// unless it is empty (never overwrite finished results by accident). A new file gets
    /// its sidecar first, then its header.
    pub fn open(
        path: &Path,
        identity: &RunIdentity,
        resume: bool,
    ) -> Result<(Self, Vec<SweepRow>), SweepError> {
        let columns = identity.columns.clone();
        let expected = header(&columns);
        let mut rows = Vec::new();
        let exists = non_empty(path);
        if exists && !resume {
            return Err(SweepError::Spec(format!(
                "{} exists: pass --resume to continue it, or choose another --out",
                path.display()
            )));
        }
        if exists {
            let stored = RunIdentity::read(path)?;
            let differences = stored.differences(identity);
            if !differences.is_empty() {
                return Err(SweepError::Mismatch {
                    path: path.to_path_buf(),
                    other: "this run".into(),
                    differences,
                });
            }
            rows = read_rows(path, &expected)?;
            // Rewrite without any torn line, so appends start on a clean line.
            write_rows(path, &expected, &rows)?;
        } else {
            if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
                std::fs::create_dir_all(parent).map_err(io_err(parent))?;
            }
            identity.write(path)?;
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

    /// Appends and flushes one finished config, measured with the config of hash
    /// `config_hash` (thread-safe).
    pub fn append(
        &self,
        point: &SweepPoint,
        config_hash: &str,
        summary: &Summary,
        objective: Objective,
    ) -> Result<SweepRow, SweepError> {
        let row = SweepRow {
            index: point.index,
            id: point.id(),
            config_hash: config_hash.to_string(),
            params: param_cells(&self.columns, point),
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

/// The parameter cells of `point` in `columns` order, as the results file writes them.
pub fn param_cells(columns: &[String], point: &SweepPoint) -> Vec<String> {
    columns
        .iter()
        .map(|c| {
            point
                .params
                .iter()
                .find(|(k, _)| k == c)
                .map(|(_, v)| value_cell(v))
                .unwrap_or_default()
        })
        .collect()
}

fn row_fields(r: &SweepRow) -> Vec<String> {
    let s = &r.summary;
    let mut f = vec![r.index.to_string(), r.id.clone(), r.config_hash.clone()];
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
        optional_cell(s.floor_hit_rate),
        optional_cell(s.evaal),
        optional_cell(s.radius_95_coverage),
        format!("{:.6}", r.objective),
    ]);
    f
}

fn write_rows(path: &Path, header: &[String], rows: &[SweepRow]) -> Result<(), SweepError> {
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(".tmp");
    let tmp = PathBuf::from(tmp);
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
    let bad = |line: usize, reason: String| SweepError::Results {
        path: path.to_path_buf(),
        line,
        reason,
    };
    let n_params = expected
        .len()
        .checked_sub(LEAD + FIGURES.len())
        .ok_or_else(|| bad(1, format!("header {expected:?} is not a results header")))?;
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
        let int = |j: usize| -> Result<usize, SweepError> {
            fields[j].parse::<usize>().map_err(|_| {
                bad(
                    line,
                    format!("field {:?} is not a whole number", expected[j]),
                )
            })
        };
        let optional = |j: usize| -> Result<Option<f64>, SweepError> {
            if fields[j].is_empty() {
                Ok(None)
            } else {
                num(j).map(Some)
            }
        };
        let base = LEAD + n_params;
        let summary = Summary {
            count: int(base)?,
            skipped: int(base + 1)?,
            mean: num(base + 2)?,
            rms: num(base + 3)?,
            p50: num(base + 4)?,
            p75: num(base + 5)?,
            p95: num(base + 6)?,
            max: num(base + 7)?,
            floor_hit_rate: optional(base + 8)?,
            evaal: optional(base + 9)?,
            radius_95_coverage: optional(base + 10)?,
            walks_skipped: 0,
        };
        rows.push(SweepRow {
            index: int(0)?,
            id: fields[1].clone(),
            config_hash: fields[2].clone(),
            params: fields[LEAD..base].to_vec(),
            summary,
            objective: num(base + 11)?,
        });
    }
    Ok(rows)
}

/// The ids already finished in `rows`.
pub fn finished_ids(rows: &[SweepRow]) -> HashSet<String> {
    rows.iter().map(|r| r.id.clone()).collect()
}

/// Joins shard files of one sweep into `out` (and its sidecar, as the whole sweep's), sorted
/// by index. Refused ([`SweepError::Mismatch`]) when the files are not of one sweep (spec,
/// base config or data differ), when one shard is given twice or shards of different counts
/// are mixed, or when a row is not of its file's shard; a config present in two files must
/// have the same config hash in both (then one copy is kept). Shards may be missing: the
/// merged file is then incomplete, and `resume` on it runs the rest.
pub fn merge(shards: &[PathBuf], out: &Path) -> Result<Vec<SweepRow>, SweepError> {
    let first = shards
        .first()
        .ok_or_else(|| SweepError::Spec("nothing to merge".into()))?;
    let ids: Vec<RunIdentity> = shards
        .iter()
        .map(|s| RunIdentity::read(s))
        .collect::<Result<_, _>>()?;
    let reference = &ids[0];
    let mismatch = |path: &Path, differences: Vec<String>| SweepError::Mismatch {
        path: path.to_path_buf(),
        other: first.display().to_string(),
        differences,
    };
    let mut seen: BTreeMap<usize, (&PathBuf, ShardId)> = BTreeMap::new();
    for (path, id) in shards.iter().zip(&ids) {
        // Same sweep as the first file ("the file vs the first file").
        let differences = id.sweep_differences(reference);
        if !differences.is_empty() {
            return Err(mismatch(path, differences));
        }
        if let Some(s) = id.shard {
            if let Some((other, t)) = seen.values().find(|(_, t)| t.count != s.count) {
                return Err(SweepError::Mismatch {
                    path: path.clone(),
                    other: other.display().to_string(),
                    differences: vec![format!(
                        "shard differs: shard {s} vs shard {t}: shards of different counts"
                    )],
                });
            }
            if let Some((other, _)) = seen.get(&s.index) {
                return Err(SweepError::Mismatch {
                    path: path.clone(),
                    other: other.display().to_string(),
                    differences: vec![format!("shard differs: both are shard {s}")],
                });
            }
            seen.insert(s.index, (path, s));
        }
    }
    let expected = header(&reference.columns);
    let mut rows: Vec<SweepRow> = Vec::new();
    for (path, id) in shards.iter().zip(&ids) {
        for r in read_rows(path, &expected)? {
            let wrong_shard = id
                .shard
                .filter(|s| r.index % s.count != s.index)
                .map(|s| format!("config {} is not of shard {s}", r.index));
            let out_of_range = (r.index >= id.configs)
                .then(|| format!("config {} beyond the sweep's {}", r.index, id.configs));
            if let Some(reason) = wrong_shard.or(out_of_range) {
                return Err(SweepError::Spec(format!("{}: {reason}", path.display())));
            }
            rows.push(r);
        }
    }
    rows.sort_by_key(|r| r.index);
    for w in rows.windows(2) {
        if w[0].index == w[1].index && w[0].config_hash != w[1].config_hash {
            return Err(SweepError::Spec(format!(
                "config {} appears with two config hashes ({} and {}): the files are not of one sweep",
                w[0].index, w[0].config_hash, w[1].config_hash
            )));
        }
    }
    rows.dedup_by_key(|r| r.index);
    let mut whole = reference.clone();
    whole.shard = None;
    if let Some(parent) = out.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent).map_err(io_err(parent))?;
    }
    whole.write(out)?;
    write_rows(out, &expected, &rows)?;
    Ok(rows)
}
