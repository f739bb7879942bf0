//! Running a sweep: configs built from the base config and each point, grouped by what their
//! preparation depends on, evaluated in parallel, every finished one recorded at once; and
//! the best config, taken only from rows measured for this sweep's configs.

use super::SweepError;
use super::identity::{RunIdentity, config_hash};
use super::results::{ResultsFile, SweepRow, header, param_cells, read_rows};
use super::spec::{DEFAULT_CONFIG_LIMIT, SweepPoint, SweepSpec, set_path, shard};
use crate::config::EvalConfig;
use crate::error::EvalError;
use crate::input::FloorInput;
use crate::pipeline;
use rayon::prelude::*;
use std::collections::{HashMap, HashSet};
use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

/// Options of [`run_sweep`].
#[derive(Debug, Clone, Default)]
pub struct SweepOptions {
    /// Continue an existing results file (skip finished configs).
    pub resume: bool,
    /// Run only shard `.0` of `.1` (`index % n == i`).
    pub shard: Option<(usize, usize)>,
    /// Stop after this many configs have finished in this run (the rest stays to resume).
    pub max_configs: Option<usize>,
    /// The most configs the sweep may expand to (all shards); `None`:
    /// [`DEFAULT_CONFIG_LIMIT`].
    pub config_limit: Option<usize>,
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
    base: &EvalConfig,
    scheme: &str,
    point: &SweepPoint,
) -> Result<EvalConfig, SweepError> {
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

/// Checks rows read back from `path` against this run's configs: each must be of a config of
/// this (shard of the) sweep, with that config's id and hash.
fn verify_rows(
    rows: &[SweepRow],
    points: &HashMap<usize, (&SweepPoint, &String)>,
    path: &Path,
) -> Result<(), SweepError> {
    for r in rows {
        let reason = match points.get(&r.index) {
            None => Some(format!("config {} is not in this run", r.index)),
            Some((p, hash)) if r.config_hash != **hash || r.id != p.id() => Some(format!(
                "config {} was measured for {} (hash {}), this run's config {} is {} (hash {})",
                r.index,
                r.id,
                r.config_hash,
                r.index,
                p.id(),
                hash
            )),
            Some(_) => None,
        };
        if let Some(reason) = reason {
            return Err(SweepError::Spec(format!("{}: {reason}", path.display())));
        }
    }
    Ok(())
}

/// Runs a sweep over prepared floors: configs grouped by what [`pipeline::prepare`]
/// depends on (so fusion-only sweeps prepare once), each group's configs in parallel, every
/// finished config appended to `out` at once. `on_done` is called after each config.
///
/// The run identity (spec, base config, data, shard) is written beside `out` when the file
/// is new; a resumed file must have been written by the same run, and each of its rows must
/// carry the hash of this run's config at its index, else nothing runs and the error names
/// what differs. A spec expanding to more than [`SweepOptions::config_limit`] configs is
/// refused before anything is allocated for them.
pub fn run_sweep(
    spec: &SweepSpec,
    base: &EvalConfig,
    floors: &[FloorInput],
    out: &Path,
    options: &SweepOptions,
    on_done: &(dyn Fn() + Sync),
) -> Result<SweepOutcome, EvalError> {
    let to_eval = |e: SweepError| EvalError::Sweep(e.to_string());
    base.scheme(&spec.scheme)?;
    let limit = options.config_limit.unwrap_or(DEFAULT_CONFIG_LIMIT);
    let mut points = spec.expand_limited(limit).map_err(to_eval)?;
    let total = points.len();
    if let Some((i, n)) = options.shard {
        if n == 0 || i >= n {
            return Err(to_eval(SweepError::Spec(format!(
                "shard {i}/{n}: need I < N"
            ))));
        }
        points = shard(points, i, n);
    }
    let identity = RunIdentity::new(spec, base, floors, options.shard, total).map_err(to_eval)?;
    let hashes: Vec<String> = points
        .par_iter()
        .map(|p| config_for(base, &spec.scheme, p).and_then(|c| config_hash(&c)))
        .collect::<Result<_, _>>()
        .map_err(to_eval)?;
    let by_index: HashMap<usize, (&SweepPoint, &String)> = points
        .iter()
        .zip(&hashes)
        .map(|(p, h)| (p.index, (p, h)))
        .collect();
    let (file, done_rows) = ResultsFile::open(out, &identity, options.resume).map_err(to_eval)?;
    verify_rows(&done_rows, &by_index, out).map_err(to_eval)?;
    let done: HashSet<usize> = done_rows.iter().map(|r| r.index).collect();
    let todo: Vec<usize> = (0..points.len())
        .filter(|&j| !done.contains(&points[j].index))
        .collect();
    let skipped = points.len() - todo.len();
    let budget = options.max_configs.unwrap_or(usize::MAX).min(todo.len());
    let todo = &todo[..budget];
    // Group by preparation key, keeping sweep order inside groups; the configs themselves
    // are rebuilt when they run, so memory stays one config per worker.
    let mut group_of: HashMap<String, usize> = HashMap::new();
    let mut groups: Vec<Vec<usize>> = Vec::new();
    for &j in todo {
        let key = config_for(base, &spec.scheme, &points[j])
            .map_err(to_eval)?
            .preparation_key();
        let g = *group_of.entry(key).or_insert_with(|| {
            groups.push(Vec::new());
            groups.len() - 1
        });
        groups[g].push(j);
    }
    drop(group_of);
    let schemes = vec![spec.scheme.clone()];
    let mut ran = 0;
    for group in &groups {
        if options.stop_requested() {
            break;
        }
        let first = config_for(base, &spec.scheme, &points[group[0]]).map_err(to_eval)?;
        let prepared = pipeline::prepare(floors, &first)?;
        drop(first);
        // Each config reports whether it ran (false: skipped because a stop was requested
        // before it started).
        let results: Vec<Result<bool, EvalError>> = group
            .par_iter()
            .map(|&j| {
                if options.stop_requested() {
                    return Ok(false);
                }
                let p = &points[j];
                let cfg = config_for(base, &spec.scheme, p).map_err(to_eval)?;
                let report = pipeline::run_prepared(floors, &prepared, &cfg, &schemes, &|| {})?;
                let summary = report.pooled.get(&spec.scheme).copied().unwrap_or_default();
                file.append(p, &hashes[j], &summary, spec.objective)
                    .map_err(to_eval)?;
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

/// The best measured config of `rows` (the lowest finite objective; ties: the lowest index)
/// and its evaluation config, or `None` when no row has a finite objective. Refused when the
/// row is not of this sweep: its index is beyond it, or its config hash or parameters are not
/// those of the config `spec` and `base` give at that index. So a best config is only ever
/// written with the parameters that were measured.
pub fn best_config(
    spec: &SweepSpec,
    base: &EvalConfig,
    rows: &[SweepRow],
    config_limit: Option<usize>,
) -> Result<Option<(SweepRow, EvalConfig)>, SweepError> {
    let Some(top) = rows
        .iter()
        .filter(|r| r.objective.is_finite())
        .min_by(|a, b| {
            a.objective
                .total_cmp(&b.objective)
                .then(a.index.cmp(&b.index))
        })
    else {
        return Ok(None);
    };
    let points = spec.expand_limited(config_limit.unwrap_or(DEFAULT_CONFIG_LIMIT))?;
    let point = points.get(top.index).ok_or_else(|| {
        SweepError::Spec(format!(
            "best row: config {} is beyond this sweep's {} configs",
            top.index,
            points.len()
        ))
    })?;
    let cfg = config_for(base, &spec.scheme, point)?;
    let hash = config_hash(&cfg)?;
    if hash != top.config_hash || top.params != param_cells(&spec.columns(), point) {
        return Err(SweepError::Spec(format!(
            "best row: config {} was measured for {} (hash {}), not for this sweep's {} (hash {})",
            top.index,
            top.id,
            top.config_hash,
            point.id(),
            hash
        )));
    }
    Ok(Some((top.clone(), cfg)))
}
