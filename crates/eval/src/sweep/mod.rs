//! Parameter sweeps: a grid or a random sample over any config field, addressed by a dotted
//! path into the evaluation config (`"fuser.q_heading_turn"`, `"matcher.k"`), evaluated
//! elsewhere; this module expands, shards, records and resumes.
//!
//! - [`spec`](SweepSpec): the sweep file and its expansion, bounded by a config limit;
//! - [`identity`](RunIdentity): what a results file was measured on, and the stable hashes;
//! - [`results`](ResultsFile): the results file, resume and merge;
//! - [`run_sweep`]: running a sweep, and [`best_config`].
//!
//! ## Sweep file (TOML)
//!
//! ```toml
//! scheme = "aekf"          # the scheme every config runs
//! objective = "mean"       # mean | rms | p95 | evaal (IPIN's score): what "best" minimises
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
//! `index % N == I`) lets a batch system spread one sweep over machines. A sweep expanding to
//! more than [`DEFAULT_CONFIG_LIMIT`] configs (checked multiplication, before anything is
//! allocated) is an error unless the limit is raised ([`SweepOptions::config_limit`],
//! `wipdr sweep --config-limit N`).
//!
//! ## Results file (CSV) and run identity
//!
//! One row per finished config: `index, id, config_hash, <param columns...>, count, skipped,
//! mean, rms, p50, p75, p95, max, floor_hit_rate, evaal, radius_95_coverage, objective` (the
//! three optional figures empty where the data has no floors or the scheme no radius). A row is appended and flushed as soon as its
//! config finishes, so a sweep that is stopped keeps all it finished; `resume` skips configs
//! whose index is already in the file (a torn last line is dropped). When a run completes, the
//! file is rewritten sorted by index, so an interrupted-and-resumed sweep ends with the same
//! file as an uninterrupted one. [`SweepOptions::stop`] is a polite stop (`wipdr sweep` sets it
//! on Ctrl-C): no new config starts, running ones finish and are written, and the outcome says
//! [`SweepOutcome::stopped`].
//!
//! Beside `results.csv`, `results.csv.run.json` ([`RunIdentity`]) records the sweep spec, the
//! base config, the data (one content hash per floor) and the shard. `resume` refuses a file
//! whose identity differs from the run's, and `merge` refuses files of different sweeps, with
//! a [`SweepError::Mismatch`] naming what differs; every row carries the hash of the config
//! it measured ([`config_hash`]), checked against this run's config at its index, so a row is
//! never attributed to another config (nor written out as the best one).
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

pub(crate) mod identity;
mod results;
mod run;
mod spec;

pub use identity::{
    DataIdentity, FloorIdentity, IDENTITY_FORMAT, RunIdentity, ShardId, StableHasher,
    canonical_json, config_hash, data_identity, floor_identity, json_hash,
};
pub use results::{ResultsFile, SweepRow, finished_ids, header, merge, param_cells, read_rows};
pub use run::{SweepOptions, SweepOutcome, best_config, config_for, run_sweep};
pub use spec::{
    DEFAULT_CONFIG_LIMIT, Objective, RandomSpec, Range, SweepPoint, SweepSpec, set_path, shard,
};

use std::path::PathBuf;
use thiserror::Error;

/// Errors of sweeps.
#[derive(Debug, Error)]
pub enum SweepError {
    /// The sweep spec is not usable.
    #[error("sweep spec: {0}")]
    Spec(String),
    /// The sweep expands to more configs than allowed.
    #[error(
        "sweep spec: expands to {configs} configs, over the limit of {limit}: shrink the grid \
         or random.samples, or raise the limit (wipdr sweep --config-limit N; \
         SweepOptions::config_limit)"
    )]
    TooManyConfigs {
        /// The number of configs (a text: it may not fit an integer).
        configs: String,
        /// The limit.
        limit: usize,
    },
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
    /// A results file without its run identity (written by a wipdr before run identities,
    /// or copied without its sidecar): it cannot be checked, so it is not resumed or merged.
    #[error(
        "{results}: no run identity {sidecar} beside it (results from an older wipdr, or \
         copied without it), so they cannot be checked against this run: start a new --out"
    )]
    MissingIdentity {
        /// The results file.
        results: PathBuf,
        /// The sidecar looked for.
        sidecar: PathBuf,
    },
    /// A results file of another run: spec, base config, data or shard differ.
    #[error("{path} is not of the same run as {other} (values: {path} vs {other}): {}", differences.join("; "))]
    Mismatch {
        /// The refused file.
        path: PathBuf,
        /// What it was compared with (`this run`, or another file).
        other: String,
        /// One message per part that differs (`spec differs ...`, `data differs ...`).
        differences: Vec<String>,
    },
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::EvalConfig;
    use crate::report::Summary;
    use std::fs::OpenOptions;
    use std::io::Write;

    /// Every sweep file in `docs/sweeps` parses, and every config it expands to is a valid
    /// evaluation config (a renamed field would otherwise fail only when someone reruns it);
    /// the base configs there (`*-base.toml`, for `--base`) read as evaluation configs.
    #[test]
    fn every_shipped_sweep_expands_to_valid_configs() {
        let files = crate::config::tests::shipped_toml_files("sweeps");
        for (path, text) in &files {
            if path.to_string_lossy().ends_with("-base.toml") {
                EvalConfig::from_toml(text, &path.display().to_string()).unwrap();
                continue;
            }
            let spec: SweepSpec =
                toml::from_str(text).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            let points = spec
                .expand_limited(100_000)
                .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            let base = EvalConfig::default();
            for p in &points {
                let cfg = run::config_for(&base, &spec.scheme, p)
                    .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
                cfg.validate()
                    .unwrap_or_else(|e| panic!("{}: point {}: {e}", path.display(), p.index));
            }
        }
        assert!(files.len() >= 10, "{} sweep files", files.len());
    }

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

    fn identity(s: &SweepSpec, shard: Option<(usize, usize)>) -> RunIdentity {
        RunIdentity::new(s, &EvalConfig::default(), &[], shard, 6).unwrap()
    }

    #[test]
    fn resume_drops_torn_line_and_finish_sorts() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("r.csv");
        let s = spec();
        let id = identity(&s, None);
        let pts = s.expand().unwrap();
        let sum = Summary {
            count: 3,
            mean: 1.5,
            ..Default::default()
        };
        {
            let (f, rows) = ResultsFile::open(&path, &id, false).unwrap();
            assert!(rows.is_empty());
            f.append(&pts[2], "h2", &sum, Objective::Mean).unwrap();
            f.append(&pts[0], "h0", &sum, Objective::Mean).unwrap();
        }
        // A torn write.
        let mut t = OpenOptions::new().append(true).open(&path).unwrap();
        t.write_all(b"5,\"{\\\"a").unwrap();
        drop(t);
        assert!(ResultsFile::open(&path, &id, false).is_err());
        let (f, rows) = ResultsFile::open(&path, &id, true).unwrap();
        assert_eq!(rows.len(), 2);
        assert_eq!(rows[0].config_hash, "h2");
        let done = finished_ids(&rows);
        assert!(done.contains(&pts[2].id()));
        f.append(&pts[1], "h1", &sum, Objective::Mean).unwrap();
        let rows = f.finish().unwrap();
        assert_eq!(
            rows.iter().map(|r| r.index).collect::<Vec<_>>(),
            vec![0, 1, 2]
        );
        let merged = dir.path().join("m.csv");
        let m = merge(&[path.clone(), path.clone()], &merged).unwrap();
        assert_eq!(m.len(), 3);
        assert_eq!(
            std::fs::read_to_string(RunIdentity::sidecar_path(&merged)).unwrap(),
            std::fs::read_to_string(RunIdentity::sidecar_path(&path)).unwrap()
        );
    }

    #[test]
    fn floor_evaal_and_radius_figures_survive_the_results_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("r.csv");
        let s = spec();
        let id = identity(&s, None);
        let pts = s.expand().unwrap();
        let with_floors = Summary {
            count: 4,
            mean: 2.0,
            p75: 3.0,
            floor_hit_rate: Some(0.75),
            evaal: Some(18.0),
            radius_95_coverage: Some(0.5),
            ..Default::default()
        };
        let without = Summary {
            count: 4,
            mean: 2.5,
            ..Default::default()
        };
        {
            let (f, _) = ResultsFile::open(&path, &id, false).unwrap();
            let row = f
                .append(&pts[0], "h0", &with_floors, Objective::Evaal)
                .unwrap();
            assert_eq!(row.objective, 18.0);
            let row = f.append(&pts[1], "h1", &without, Objective::Evaal).unwrap();
            assert!(row.objective.is_infinite());
        }
        let (_, rows) = ResultsFile::open(&path, &id, true).unwrap();
        assert_eq!(rows[0].summary, with_floors);
        assert_eq!(rows[0].objective, 18.0);
        assert_eq!(rows[1].summary.evaal, None);
        assert_eq!(rows[1].summary.floor_hit_rate, None);
        assert!(rows[1].objective.is_infinite());
        let spec: SweepSpec = toml::from_str("scheme = \"ekf\"\nobjective = \"evaal\"").unwrap();
        assert_eq!(spec.objective, Objective::Evaal);
    }

    #[test]
    fn resume_refuses_another_identity_and_names_the_difference() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("r.csv");
        let s = spec();
        {
            let (f, _) = ResultsFile::open(&path, &identity(&s, None), false).unwrap();
            f.append(
                &s.expand().unwrap()[0],
                "h",
                &Summary::default(),
                Objective::Mean,
            )
            .unwrap();
        }
        let mut t = s.clone();
        if let Some(r) = t.random.as_mut() {
            r.seed = 10;
        }
        let e = ResultsFile::open(&path, &identity(&t, None), true)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("spec differs") && e.contains("random.seed: 9 vs 10"),
            "{e}"
        );
        let e = ResultsFile::open(&path, &identity(&s, Some((1, 2))), true)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("shard differs: the whole sweep vs shard 1/2"),
            "{e}"
        );
        let mut base = EvalConfig::default();
        base.positioner.seed = 99;
        let other = RunIdentity::new(&s, &base, &[], None, 6).unwrap();
        let e = ResultsFile::open(&path, &other, true)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("base config differs") && e.contains("seed: 1 vs 99"),
            "{e}"
        );
        // Without its sidecar a file is not resumed.
        std::fs::remove_file(RunIdentity::sidecar_path(&path)).unwrap();
        let e = ResultsFile::open(&path, &identity(&s, None), true)
            .unwrap_err()
            .to_string();
        assert!(e.contains("no run identity"), "{e}");
    }

    #[test]
    fn canonical_json_sorts_keys_at_every_level() {
        let a = serde_json::json!({"b": 1, "a": {"y": [1, {"q": 2, "p": 1}], "x": null}});
        assert_eq!(
            canonical_json(&a),
            r#"{"a":{"x":null,"y":[1,{"p":1,"q":2}]},"b":1}"#
        );
        // FNV-1a 64 of "a" (the published test vector).
        let mut h = StableHasher::default();
        h.update(b"a");
        assert_eq!(h.hex(), "af63dc4c8601ec8c");
    }
}
