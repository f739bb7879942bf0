//! Figures of an evaluation: per walk, per floor and pooled, per scheme, and their JSON form.
//!
//! JSON schema (written by `wipdr eval --json`):
//!
//! ```text
//! {
//!   "pooled": { "<scheme>": Summary, ... },
//!   "floors": { "<floor folder>": { "<scheme>": Summary, ... }, ... },
//!   "walks":  [ { "floor", "walk", "fold", "scheme", "count", "skipped", "mean", "p95",
//!                 "max", "errors": [[t_ms, metres, floor_error], ...],
//!                 "sd_m": [metres or null, ...] }, ... ],
//!   "schemes": [ "<scheme>", ... ],
//!   "skips": { "<floor>": { "<kind>": count, ... }, ... },   every skip of the run
//!   "skipped_runs": [ { "floor", "walk", "fold", "scheme", "missing" }, ... ],
//!   "mode": "causal" | "offline",
//!   "config": { ...the evaluation config used... }
//! }
//! ```
//!
//! With `wipdr eval --json FILE --json-tracks` (and always in the data of the `--report`
//! page), the drawing data is added ([`crate::drawing`]; the existing fields are unchanged):
//!
//! ```text
//! each entry of "walks" also has
//!   "track": [[t_ms, x, y, sd_m or null], ...]     the scheme's track, downsampled for drawing
//! "walk_data": [ { "floor", "walk", "fold",
//!                  "waypoints": [[t_ms, x, y], ...],   the truth
//!                  "fixes": [[t_ms, x, y], ...] }, ... ]   the walk's Wi-Fi fixes
//! "plans": { "<floor>": { "width", "height", "walls": [[x1, y1, x2, y2], ...],
//!                         "image": "data:image/png;base64,..." or null }, ... }
//! "drawing": { "tolerance_m" }                     the downsampling tolerance
//! ```
//!
//! ```text
//! Summary = { "count", "skipped", "mean", "rms", "p50", "p75", "p95", "max",
//!             "floor_hit_rate", "evaal", "radius_95_coverage", "walks_skipped" }
//! ```
//!
//! `sd_m` (only for schemes with an uncertainty) is aligned with `errors`: the horizontal
//! standard deviation of the estimate scored at each point; `radius_95_coverage` the share
//! of those points inside 2.4477 x `sd_m` (the 95 % circle of an isotropic Gaussian).
//!
//! `floor_error` is the estimated minus the true floor (0 where the walk has no floors;
//! `null` before the stream's first floor estimate); `floor_hit_rate` is over the scored
//! points with a true floor (`null` without any); `evaal` is the IPIN competition's metric,
//! the 75th percentile of 2D error + 15 m x |floor error| ([`crate::scoring::evaal_errors`]),
//! by the competition's quantile rule (MATLAB's, [`crate::evaal_score::evaal_metric`]; the
//! `p50`..`p95` figures use numpy's default rule).
//!
//! ```text
//! ```

use crate::config::EvalConfig;
use crate::scoring::WalkScore;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use wipdr_core::stats::ErrorStats;

/// Summary of one scheme over a set of waypoints.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Summary {
    /// Scored waypoints.
    pub count: usize,
    /// Skipped waypoints (before scoring start or before the scheme's first estimate).
    pub skipped: usize,
    /// Mean error, metres.
    pub mean: f64,
    /// RMS error, metres.
    pub rms: f64,
    /// Median error, metres.
    pub p50: f64,
    /// 75th percentile, metres.
    pub p75: f64,
    /// 95th percentile, metres.
    pub p95: f64,
    /// Maximum error, metres.
    pub max: f64,
    /// Share of the scored points with a true floor whose floor estimate was right; `None`
    /// without such points.
    #[serde(default)]
    pub floor_hit_rate: Option<f64>,
    /// EvAAL metric: 75th percentile (the competition's rule,
    /// [`crate::evaal_score::evaal_metric`]) of 2D error + 15 m x |floor error|, metres; `None`
    /// without scored points or without floors.
    #[serde(default)]
    pub evaal: Option<f64>,
    /// Share of the scored points with an uncertainty whose true position lies inside the
    /// estimate's 95 % radius ([`crate::scoring::RADIUS_95_PER_SD`] x `sd_m`): near 0.95 for
    /// an honest radius; `None` where the scheme reports no uncertainty.
    #[serde(default)]
    pub radius_95_coverage: Option<f64>,
    /// Walks not run for this scheme because they lack a stream it needs
    /// ([`SkippedRun`]); their waypoints are in neither `count` nor `skipped`.
    #[serde(default)]
    pub walks_skipped: usize,
}

impl Summary {
    /// Summarises the scores of several walks (pooled over their waypoints).
    pub fn from_scores<'a>(scores: impl IntoIterator<Item = &'a WalkScore>) -> Self {
        let mut errors = Vec::new();
        let mut evaal = Vec::new();
        let mut skipped = 0;
        let (mut floor_scored, mut floor_hits) = (0usize, 0usize);
        let (mut with_sd, mut inside) = (0usize, 0usize);
        for s in scores {
            let (n, k) = s.radius_95_hits();
            with_sd += n;
            inside += k;
            errors.extend(s.errors.iter().map(|e| e.1));
            evaal.extend(crate::scoring::evaal_errors(&s.errors));
            skipped += s.skipped;
            floor_scored += s.floor_scored;
            floor_hits += s.floor_hits();
        }
        let st = ErrorStats::from_errors(&errors);
        Self {
            count: st.count,
            skipped,
            mean: st.mean,
            rms: st.rms,
            p50: st.p50,
            p75: st.p75,
            p95: st.p95,
            max: st.max,
            floor_hit_rate: (floor_scored > 0).then(|| floor_hits as f64 / floor_scored as f64),
            evaal: crate::evaal_score::evaal_metric(&evaal),
            radius_95_coverage: (with_sd > 0).then(|| inside as f64 / with_sd as f64),
            walks_skipped: 0,
        }
    }
}

/// A walk a scheme was not run on, because the walk lacks a stream the scheme needs
/// ([`crate::streams`]): counted in the tables ([`Summary::walks_skipped`]), never scored.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct SkippedRun {
    /// Floor label.
    pub floor: String,
    /// Walk id.
    pub walk: String,
    /// Protocol fold of the walk.
    pub fold: usize,
    /// Scheme name.
    pub scheme: String,
    /// The stream it lacks.
    pub missing: crate::streams::MissingStream,
}

/// What the readers left out of a floor's input, by kind (`"record: out of physical range"`,
/// `"walk file unreadable"`, `"plan feature unusable"`, ...): counted where the data was
/// read and carried into the report, so that `eval` shows every skip it makes.
pub type InputSkips = BTreeMap<String, usize>;

/// The score of one scheme on one test walk.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WalkResult {
    /// Floor label (the folder as given).
    pub floor: String,
    /// Walk id.
    pub walk: String,
    /// Protocol fold of the walk.
    pub fold: usize,
    /// Scheme name.
    pub scheme: String,
    /// Time of the walk's first Wi-Fi scan, where it has one (for the index table's
    /// "seconds after the first scan").
    #[serde(default)]
    pub first_scan_t: Option<wipdr_core::TimestampMs>,
    /// The scored waypoints.
    pub score: WalkScore,
}

/// The motion source's displacement between consecutive waypoints of one test walk against
/// the truth (the per-segment error of issue 44): scheme-independent, one per walk.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct WalkMotion {
    /// Floor label.
    pub floor: String,
    /// Walk id.
    pub walk: String,
    /// Protocol fold of the walk.
    pub fold: usize,
    /// Per segment: the true displacement's length and the error of the motion events'
    /// summed displacement over the segment, m.
    pub segments: Vec<(f64, f64)>,
    /// Per segment, in the same order: whether the true displacement lies inside the 95 %
    /// ellipse of the events' summed covariance; `None` for a segment with an event without
    /// one (detected steps carry none). Empty in reports written before it was kept.
    #[serde(default)]
    pub inside_95: Vec<Option<bool>>,
}

/// Where the truth falls in each scored scan's likelihood over the floor
/// ([`wipdr_core::WifiLikelihood::rank_and_region`]) for one test walk: scheme-independent,
/// one per walk whose fixes carry a likelihood.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct WalkScanLikelihood {
    /// Floor label.
    pub floor: String,
    /// Walk id.
    pub walk: String,
    /// Protocol fold of the walk.
    pub fold: usize,
    /// Per scan with a likelihood and a truth (the waypoints interpolated at its time): the
    /// number of raster cells more likely than the truth's, and whether the most likely cells
    /// holding 95 % of the likelihood hold it.
    pub scans: Vec<(usize, bool)>,
}

/// The scans' likelihood calibration summarised (a floor or pooled).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct ScanLikelihoodSummary {
    /// Scans scored.
    pub scans: usize,
    /// Share of them whose 95 % likelihood region holds the truth (the band the filters
    /// need: 0.90-0.97).
    pub region_95_holds: f64,
    /// Median rank of the truth's cell (cells more likely than it).
    pub rank_median: f64,
    /// 90th percentile of that rank.
    pub rank_p90: f64,
}

impl ScanLikelihoodSummary {
    /// The summary of `(rank, held)` scans.
    pub fn of<'a>(scans: impl IntoIterator<Item = &'a (usize, bool)>) -> Self {
        let scans: Vec<(usize, bool)> = scans.into_iter().copied().collect();
        if scans.is_empty() {
            return Self::default();
        }
        let ranks: Vec<f64> = scans.iter().map(|&(r, _)| r as f64).collect();
        let stats = ErrorStats::from_errors(&ranks);
        Self {
            scans: scans.len(),
            region_95_holds: scans.iter().filter(|s| s.1).count() as f64 / scans.len() as f64,
            rank_median: stats.p50,
            rank_p90: stats.p90,
        }
    }
}

/// Per-segment displacement errors summarised (a floor or pooled).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct MotionSummary {
    /// Segments scored.
    pub segments: usize,
    /// Mean true segment length, m.
    pub mean_length_m: f64,
    /// Mean displacement error, m.
    pub mean_m: f64,
    /// Median displacement error, m.
    pub median_m: f64,
    /// The share of the segments with a covariance (learned odometry) whose true
    /// displacement lies inside the 95 % ellipse of it; `None` without such segments.
    #[serde(default)]
    pub inside_95: Option<f64>,
}

impl MotionSummary {
    /// The summary of `(length, error)` segments; non-finite errors are left out.
    pub fn of<'a>(segments: impl IntoIterator<Item = &'a (f64, f64)>) -> Self {
        Self::with_ellipses(segments.into_iter().map(|s| (s, None)))
    }

    /// [`MotionSummary::of`] with each segment's ellipse test ([`WalkMotion::inside_95`]).
    pub fn with_ellipses<'a>(
        segments: impl IntoIterator<Item = (&'a (f64, f64), Option<bool>)>,
    ) -> Self {
        let kept: Vec<((f64, f64), Option<bool>)> = segments
            .into_iter()
            .map(|(s, inside)| (*s, inside))
            .filter(|((l, e), _)| l.is_finite() && e.is_finite())
            .collect();
        if kept.is_empty() {
            return Self::default();
        }
        let n = kept.len() as f64;
        let errors: Vec<f64> = kept.iter().map(|&((_, e), _)| e).collect();
        let tested: Vec<bool> = kept.iter().filter_map(|&(_, inside)| inside).collect();
        Self {
            segments: kept.len(),
            mean_length_m: kept.iter().map(|&((l, _), _)| l).sum::<f64>() / n,
            mean_m: errors.iter().sum::<f64>() / n,
            median_m: ErrorStats::from_errors(&errors).p50,
            inside_95: (!tested.is_empty())
                .then(|| tested.iter().filter(|&&b| b).count() as f64 / tested.len() as f64),
        }
    }
}

/// A whole evaluation: per-walk results and their per-floor and pooled summaries.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct EvalReport {
    /// Per scheme, over all floors.
    pub pooled: BTreeMap<String, Summary>,
    /// Per floor, per scheme.
    pub floors: BTreeMap<String, BTreeMap<String, Summary>>,
    /// Scheme names in the order requested.
    pub schemes: Vec<String>,
    /// Floor labels in the order given.
    pub floor_order: Vec<String>,
    /// Every walk result.
    pub walks: Vec<WalkResult>,
    /// The (walk, scheme) runs left out for a missing stream.
    #[serde(default)]
    pub skipped_runs: Vec<SkippedRun>,
    /// Per floor label, what its readers skipped, by kind ([`InputSkips`]).
    #[serde(default)]
    pub input_skips: BTreeMap<String, InputSkips>,
    /// The motion source's per-segment displacement error of every test walk
    /// ([`WalkMotion`]), in the walks' order.
    #[serde(default)]
    pub motion: Vec<WalkMotion>,
    /// Where the truth falls in each scored scan's likelihood, per test walk
    /// ([`WalkScanLikelihood`]; empty when the fixes carry none), in the walks' order.
    #[serde(default)]
    pub scan_likelihood: Vec<WalkScanLikelihood>,
}

impl EvalReport {
    /// Builds the summaries from per-walk results.
    pub fn from_walks(
        schemes: Vec<String>,
        floor_order: Vec<String>,
        walks: Vec<WalkResult>,
    ) -> Self {
        let mut pooled = BTreeMap::new();
        let mut floors: BTreeMap<String, BTreeMap<String, Summary>> = BTreeMap::new();
        for s in &schemes {
            pooled.insert(
                s.clone(),
                Summary::from_scores(walks.iter().filter(|w| &w.scheme == s).map(|w| &w.score)),
            );
            for f in &floor_order {
                floors.entry(f.clone()).or_default().insert(
                    s.clone(),
                    Summary::from_scores(
                        walks
                            .iter()
                            .filter(|w| &w.scheme == s && &w.floor == f)
                            .map(|w| &w.score),
                    ),
                );
            }
        }
        Self {
            pooled,
            floors,
            schemes,
            floor_order,
            walks,
            skipped_runs: Vec::new(),
            input_skips: BTreeMap::new(),
            motion: Vec::new(),
            scan_likelihood: Vec::new(),
        }
    }

    /// The report with its walks' scan likelihood calibration.
    pub fn with_scan_likelihood(mut self, scans: Vec<WalkScanLikelihood>) -> Self {
        self.scan_likelihood = scans;
        self
    }

    /// The scan likelihood's calibration per floor (in floor order) and pooled (last,
    /// labelled `pooled`).
    pub fn scan_likelihood_summaries(&self) -> Vec<(String, ScanLikelihoodSummary)> {
        self.per_floor_and_pooled(
            &self.scan_likelihood,
            |m| &m.floor,
            |walks| ScanLikelihoodSummary::of(walks.flat_map(|m| &m.scans)),
        )
    }

    /// `summary` of the `items` of each floor (in floor order, by `floor_of`) and of all of
    /// them (last, labelled `pooled`).
    fn per_floor_and_pooled<'a, T, S>(
        &self,
        items: &'a [T],
        floor_of: impl Fn(&T) -> &String,
        summary: impl Fn(&mut dyn Iterator<Item = &'a T>) -> S,
    ) -> Vec<(String, S)> {
        let mut out: Vec<(String, S)> = self
            .floor_order
            .iter()
            .map(|f| {
                let mut of_floor = items.iter().filter(|m| floor_of(m) == f);
                (f.clone(), summary(&mut of_floor))
            })
            .collect();
        out.push(("pooled".into(), summary(&mut items.iter())));
        out
    }

    /// The scan likelihood's calibration as text, a row per floor and one pooled. Empty
    /// without scored scans.
    pub fn scan_likelihood_table(&self) -> String {
        use std::fmt::Write;
        let rows = self.scan_likelihood_summaries();
        let mut out = String::new();
        if rows.last().is_none_or(|(_, s)| s.scans == 0) {
            return out;
        }
        let _ = writeln!(
            out,
            "scan likelihood: where the truth falls (its 95 % region; the cells more likely than it)"
        );
        let _ = writeln!(
            out,
            "  {:<28} {:>8} {:>10} {:>12} {:>10}",
            "floor", "scans", "95% holds", "rank median", "rank p90"
        );
        for (floor, m) in &rows {
            let _ = writeln!(
                out,
                "  {:<28} {:>8} {:>9.1}% {:>12.0} {:>10.0}",
                floor,
                m.scans,
                100.0 * m.region_95_holds,
                m.rank_median,
                m.rank_p90
            );
        }
        out
    }

    /// The report with the motion source's per-segment errors of its walks.
    pub fn with_motion(mut self, motion: Vec<WalkMotion>) -> Self {
        self.motion = motion;
        self
    }

    /// The motion source's per-segment error per floor (in floor order) and pooled (last,
    /// labelled `pooled`).
    pub fn motion_summaries(&self) -> Vec<(String, MotionSummary)> {
        self.per_floor_and_pooled(
            &self.motion,
            |m| &m.floor,
            |walks| {
                MotionSummary::with_ellipses(walks.flat_map(|m| {
                    // Reports from before the ellipse test have no `inside_95`.
                    let tests = m.inside_95.iter().copied().chain(std::iter::repeat(None));
                    m.segments.iter().zip(tests)
                }))
            },
        )
    }

    /// The motion source's per-segment displacement error as text, a row per floor and one
    /// pooled; `source` names it (`steps`, `learned`). Empty without segments.
    pub fn motion_table(&self, source: &str) -> String {
        use std::fmt::Write;
        let rows = self.motion_summaries();
        let mut out = String::new();
        if rows.last().is_none_or(|(_, s)| s.segments == 0) {
            return out;
        }
        let _ = writeln!(
            out,
            "motion source `{source}`: displacement error between consecutive waypoints (m)"
        );
        // The ellipse column only for a source with covariances (learned odometry).
        let ellipses = rows.iter().any(|(_, m)| m.inside_95.is_some());
        let _ = write!(
            out,
            "  {:<28} {:>8} {:>10} {:>8} {:>8}",
            "floor", "segments", "length", "mean", "median"
        );
        let _ = writeln!(out, "{}", if ellipses { "  in 95 %" } else { "" });
        for (floor, m) in &rows {
            let _ = write!(
                out,
                "  {:<28} {:>8} {:>10.2} {:>8.3} {:>8.3}",
                floor, m.segments, m.mean_length_m, m.mean_m, m.median_m
            );
            let inside = match (ellipses, m.inside_95) {
                (false, _) => String::new(),
                (true, Some(share)) => format!("  {:>7.1}%", 100.0 * share),
                (true, None) => format!("  {:>8}", "-"),
            };
            let _ = writeln!(out, "{inside}");
        }
        out
    }

    /// The report with the runs left out for a missing stream (counted into each summary's
    /// [`Summary::walks_skipped`]) and what the readers skipped per floor.
    pub fn with_skips(
        mut self,
        skipped_runs: Vec<SkippedRun>,
        input_skips: BTreeMap<String, InputSkips>,
    ) -> Self {
        for run in &skipped_runs {
            if let Some(s) = self.pooled.get_mut(&run.scheme) {
                s.walks_skipped += 1;
            }
            if let Some(s) = self
                .floors
                .get_mut(&run.floor)
                .and_then(|f| f.get_mut(&run.scheme))
            {
                s.walks_skipped += 1;
            }
        }
        self.skipped_runs = skipped_runs;
        self.input_skips = input_skips
            .into_iter()
            .filter(|(_, k)| !k.is_empty())
            .collect();
        self
    }

    /// Every skip of the run, per floor and kind: what the readers left out
    /// ([`Self::input_skips`]) and the runs left out for a missing stream (`"run: pdr: no
    /// accelerometer stream"`, counting walks). Empty when nothing was skipped.
    pub fn skips(&self) -> BTreeMap<String, BTreeMap<String, usize>> {
        let mut out = self.input_skips.clone();
        for run in &self.skipped_runs {
            *out.entry(run.floor.clone())
                .or_default()
                .entry(format!("run: {}: {}", run.scheme, run.missing.label()))
                .or_default() += 1;
        }
        out
    }

    /// The skips as text, a line per floor and kind (empty when nothing was skipped).
    pub fn skips_table(&self) -> String {
        use std::fmt::Write;
        let skips = self.skips();
        let mut out = String::new();
        if skips.is_empty() {
            return out;
        }
        let _ = writeln!(out, "skipped (per floor and kind):");
        for (floor, kinds) in &skips {
            for (kind, count) in kinds {
                let _ = writeln!(out, "  {floor}  {kind}: {count}");
            }
        }
        out
    }

    /// The JSON document `wipdr eval --json` writes (the schema in the module docs), with
    /// `config` (the evaluation config, serialised) as its `"config"`. `wipdr eval merge`
    /// writes the same document from shard files, so a merged run is byte-identical to the
    /// unsharded one.
    pub fn json_document(&self, config: &serde_json::Value) -> serde_json::Value {
        serde_json::json!({
            "pooled": self.pooled,
            "floors": self.floors,
            "walks": self.walks.iter().map(|w| {
                let s = ErrorStats::from_errors(&w.score.values());
                let mut walk = serde_json::json!({
                    "floor": w.floor, "walk": w.walk, "fold": w.fold, "scheme": w.scheme,
                    "count": s.count, "skipped": w.score.skipped, "mean": s.mean,
                    "p95": s.p95, "max": s.max, "errors": w.score.errors,
                });
                if !w.score.sd_m.is_empty() {
                    walk["sd_m"] = serde_json::json!(w.score.sd_m);
                }
                if !w.score.coverage_m.is_empty() {
                    walk["coverage_m"] = serde_json::json!(w.score.coverage_m);
                }
                walk
            }).collect::<Vec<_>>(),
            "schemes": self.schemes,
            "motion": {
                "source": config.get("odometry").cloned().unwrap_or(serde_json::Value::Null),
                "summaries": self.motion_summaries().into_iter().collect::<BTreeMap<_, _>>(),
            },
            "scan_likelihood": self
                .scan_likelihood_summaries()
                .into_iter()
                .filter(|(_, s)| s.scans > 0)
                .collect::<BTreeMap<_, _>>(),
            "skips": self.skips(),
            "skipped_runs": self.skipped_runs,
            "mode": if config.get("offline").and_then(serde_json::Value::as_bool) == Some(true) {
                "offline"
            } else {
                "causal"
            },
            "config": config,
        })
    }

    /// The JSON document of `wipdr eval --json` for `config` ([`Self::json_document`] of
    /// the serialised config). The Python package's `wipdr.evaluate` returns this document.
    ///
    /// ```
    /// use wipdr_eval::{config::EvalConfig, report::EvalReport};
    /// let json = EvalReport::default().to_json(&EvalConfig::default());
    /// assert!(json["pooled"].is_object() && json["walks"].as_array().unwrap().is_empty());
    /// assert_eq!(json["config"]["seed"], EvalConfig::default().positioner.seed);
    /// assert_eq!(json["mode"], "causal");
    /// ```
    pub fn to_json(&self, config: &EvalConfig) -> serde_json::Value {
        let value = serde_json::to_value(config).unwrap_or(serde_json::Value::Null);
        self.json_document(&value)
    }

    /// The schemes that scored no waypoint (empty test set, no matched query, a scoring
    /// start beyond every waypoint): their figures are no result, and the CLI and the Python
    /// package fail on them.
    pub fn unscored_schemes(&self) -> Vec<&str> {
        self.schemes
            .iter()
            .filter(|s| self.pooled.get(*s).is_none_or(|p| p.count == 0))
            .map(String::as_str)
            .collect()
    }

    /// A plain-text table: one block per floor and one pooled, a row per scheme.
    pub fn table(&self) -> String {
        use std::fmt::Write;
        let mut out = String::new();
        // Scheme labels may be longer than the built-in names (`[schemes.my_label]`).
        let width = self
            .schemes
            .iter()
            .map(String::len)
            .max()
            .unwrap_or(0)
            .max(8);
        // Floor hits and EvAAL only where some walk has floors (IPIN logfiles, buildings).
        let floors = self
            .floors
            .values()
            .flat_map(|r| r.values())
            .chain(self.pooled.values())
            .any(|r| r.floor_hit_rate.is_some());
        // The 95 % radius coverage where some scheme reports an uncertainty.
        let radius = self.pooled.values().any(|r| r.radius_95_coverage.is_some());
        // Walks left out for a missing stream, where some were.
        let runs_skipped = !self.skipped_runs.is_empty();
        let mut block = |title: &str, rows: &BTreeMap<String, Summary>| {
            let _ = writeln!(out, "{title}");
            let _ = write!(
                out,
                "  {:<width$} {:>6} {:>7} {:>7} {:>7} {:>7} {:>7} {:>7} {:>8}",
                "scheme", "count", "skipped", "mean", "rms", "p50", "p75", "p95", "max"
            );
            if floors {
                let _ = write!(out, " {:>7} {:>7}", "floor%", "evaal");
            }
            if radius {
                let _ = write!(out, " {:>6}", "r95%");
            }
            if runs_skipped {
                let _ = write!(out, " {:>7}", "walks-");
            }
            let _ = writeln!(out);
            for s in &self.schemes {
                if let Some(r) = rows.get(s) {
                    let _ = write!(
                        out,
                        "  {:<width$} {:>6} {:>7} {:>7.2} {:>7.2} {:>7.2} {:>7.2} {:>7.2} {:>8.2}",
                        s, r.count, r.skipped, r.mean, r.rms, r.p50, r.p75, r.p95, r.max
                    );
                    if floors {
                        let hits = r
                            .floor_hit_rate
                            .map_or("-".to_string(), |h| format!("{:.1}", 100.0 * h));
                        let evaal = r.evaal.map_or("-".to_string(), |e| format!("{e:.2}"));
                        let _ = write!(out, " {hits:>7} {evaal:>7}");
                    }
                    if radius {
                        let c = r
                            .radius_95_coverage
                            .map_or("-".to_string(), |c| format!("{:.1}", 100.0 * c));
                        let _ = write!(out, " {c:>6}");
                    }
                    if runs_skipped {
                        let _ = write!(out, " {:>7}", r.walks_skipped);
                    }
                    let _ = writeln!(out);
                }
            }
        };
        for f in &self.floor_order {
            if let Some(rows) = self.floors.get(f) {
                block(f, rows);
            }
        }
        block("pooled", &self.pooled);
        if runs_skipped {
            let _ = writeln!(
                out,
                "  (walks-: walks not run for the scheme, lacking a stream it needs; see \"skipped\")"
            );
        }
        if floors {
            let worst = self.worst_wrong_floor();
            for s in &self.schemes {
                if let Some((seconds, walk)) = worst.get(s) {
                    let _ = writeln!(
                        out,
                        "  worst time on a wrong floor, {s:<width$} {seconds:>7.1} s ({walk})"
                    );
                }
            }
        }
        out
    }

    /// Per scheme, the longest time any walk spent on a wrong floor (seconds, at the scored
    /// waypoints' sampling: [`crate::scoring::WalkScore::longest_wrong_floor_ms`]) and that
    /// walk; schemes without floors scored are left out.
    pub fn worst_wrong_floor(&self) -> BTreeMap<String, (f64, String)> {
        let mut out: BTreeMap<String, (f64, String)> = BTreeMap::new();
        for w in self.walks.iter().filter(|w| w.score.floor_scored > 0) {
            let seconds = w.score.longest_wrong_floor_ms() as f64 / 1000.0;
            let entry = out
                .entry(w.scheme.clone())
                .or_insert_with(|| (seconds, w.walk.clone()));
            if seconds > entry.0 {
                *entry = (seconds, w.walk.clone());
            }
        }
        out
    }

    /// Pooled errors by the index of the scored waypoint within its walk (0 = the first
    /// waypoint a scheme is scored at, i.e. the first after its first estimate), indices from
    /// `last` on pooled into the last row: per scheme, one `(count, sum of errors)` per row.
    /// Shows how fast a scheme settles, and where its total error comes from.
    pub fn by_waypoint_index(&self, last: usize) -> BTreeMap<String, Vec<(usize, f64)>> {
        let mut out: BTreeMap<String, Vec<(usize, f64)>> = BTreeMap::new();
        for s in &self.schemes {
            let rows = out
                .entry(s.clone())
                .or_insert_with(|| vec![(0, 0.0); last + 1]);
            for w in self.walks.iter().filter(|w| &w.scheme == s) {
                for (i, (_, e, _)) in w.score.errors.iter().enumerate() {
                    if e.is_finite() {
                        let row = &mut rows[i.min(last)];
                        row.0 += 1;
                        row.1 += e;
                    }
                }
            }
        }
        out
    }

    /// [`Self::by_waypoint_index`] as a plain-text table: a row per index with the median
    /// time of its waypoints after their walk's first Wi-Fi scan (`s_median`, seconds), and
    /// per scheme the mean error at that index and its share of the scheme's summed error.
    pub fn index_table(&self, last: usize) -> String {
        use std::fmt::Write;
        let rows = self.by_waypoint_index(last);
        let mut out = String::new();
        // Median time of the index's waypoints after their walk's first scan (first scheme).
        let mut seconds: Vec<Vec<f64>> = vec![Vec::new(); last + 1];
        if let Some(first) = self.schemes.first() {
            for w in self.walks.iter().filter(|w| &w.scheme == first) {
                if let Some(t0) = w.first_scan_t {
                    for (i, (t, _, _)) in w.score.errors.iter().enumerate() {
                        seconds[i.min(last)].push((t - t0) as f64 / 1000.0);
                    }
                }
            }
        }
        let _ = write!(out, "  {:<6} {:>6} {:>10}", "index", "count", "s_median");
        for s in &self.schemes {
            let _ = write!(out, " {:>15}", format!("{s} mean/share"));
        }
        let _ = writeln!(out);
        for i in 0..=last {
            let label = if i == last {
                format!("{i}+")
            } else {
                i.to_string()
            };
            let count = self
                .schemes
                .first()
                .and_then(|s| rows.get(s))
                .map_or(0, |r| r[i].0);
            let median = if seconds[i].is_empty() {
                "-".to_string()
            } else {
                format!(
                    "{:.1}",
                    wipdr_core::stats::ErrorStats::from_errors(&seconds[i]).p50
                )
            };
            let _ = write!(out, "  {label:<6} {count:>6} {median:>10}");
            for s in &self.schemes {
                let r = &rows[s];
                let total: f64 = r.iter().map(|x| x.1).sum();
                let (n, sum) = r[i];
                let mean = if n > 0 { sum / n as f64 } else { f64::NAN };
                let share = if total > 0.0 {
                    100.0 * sum / total
                } else {
                    0.0
                };
                let _ = write!(out, " {:>15}", format!("{mean:.2} / {share:.0}%"));
            }
            let _ = writeln!(out);
        }
        out
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A walk's result with `errs` as its scored errors (floor error 0, one per index) and
    /// `skipped` waypoints without an estimate: the fixture of the report and coverage tests.
    pub(crate) fn result_skipping(
        floor: &str,
        walk: &str,
        scheme: &str,
        errs: &[f64],
        skipped: usize,
    ) -> WalkResult {
        WalkResult {
            floor: floor.into(),
            walk: walk.into(),
            fold: 0,
            scheme: scheme.into(),
            first_scan_t: Some(0),
            score: WalkScore {
                errors: errs
                    .iter()
                    .enumerate()
                    .map(|(i, &e)| (i as i64, e, Some(0)))
                    .collect(),
                skipped,
                ..WalkScore::default()
            },
        }
    }

    fn result(floor: &str, walk: &str, scheme: &str, errs: &[f64]) -> WalkResult {
        result_skipping(floor, walk, scheme, errs, 1)
    }

    #[test]
    fn pooled_agrees_with_walks() {
        let walks = vec![
            result("A", "w1", "ekf", &[1.0, 2.0]),
            result("B", "w2", "ekf", &[3.0]),
            result("A", "w1", "pdr", &[5.0]),
        ];
        let r = EvalReport::from_walks(
            vec!["ekf".into(), "pdr".into()],
            vec!["A".into(), "B".into()],
            walks,
        );
        let p = r.pooled["ekf"];
        assert_eq!(p.count, 3);
        assert_eq!(p.skipped, 2);
        assert!((p.mean - 2.0).abs() < 1e-12);
        assert_eq!(r.floors["A"]["ekf"].count, 2);
        assert_eq!(r.floors["B"]["pdr"].count, 0);
        assert!(r.table().contains("pooled"));
    }

    #[test]
    fn by_index_rows_add_up_to_the_pooled_figures() {
        let walks = vec![
            result("A", "w1", "ekf", &[1.0, 2.0, 4.0]),
            result("B", "w2", "ekf", &[3.0]),
        ];
        let r = EvalReport::from_walks(vec!["ekf".into()], vec!["A".into(), "B".into()], walks);
        let rows = &r.by_waypoint_index(1)["ekf"];
        assert_eq!(rows, &vec![(2, 4.0), (2, 6.0)]);
        let n: usize = rows.iter().map(|x| x.0).sum();
        let sum: f64 = rows.iter().map(|x| x.1).sum();
        assert_eq!(n, r.pooled["ekf"].count);
        assert!((sum / n as f64 - r.pooled["ekf"].mean).abs() < 1e-12);
        let t = r.index_table(1);
        assert!(t.contains("1+") && t.contains("2.00 / 40%"), "{t}");
    }
}
