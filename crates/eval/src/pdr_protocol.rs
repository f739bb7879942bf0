//! PDR under the protocol folds: the runs, the one calibration and the scoring that
//! `wipdr pdr-eval` and `wipdr pdr-fit` report.
//!
//! Each walk is run once per PDR configuration ([`run_walks`]); the calibration of a fold
//! ([`calibrate_steps`]) fits the step-length coefficients and the heading offset on the
//! training walks' waypoint legs exactly as the evaluation pipeline does
//! ([`crate::pipeline::calibrate_pdr`], which runs PDR itself first); the test walks are then
//! scored per leg (relative length error, heading error) and as PDR-only positions started at
//! the true first waypoint, scored after the walk's first Wi-Fi scan ([`score_schemes`]).

use crate::fold_rules::folds_of_walk_refs;
use rayon::prelude::*;
use wipdr_core::{TimestampMs, Walk, Waypoint};
use wipdr_pdr::calibrate::{
    CalibrationConfig, WalkSteps, dead_reckon_at_waypoints, leg_errors, track,
};
use wipdr_pdr::{CheckedPdrConfig, HeadingSource, Pdr, PdrConfig, StepDetail, StepLengthConfig};

/// One walk run through the PDR pipeline.
#[derive(Debug, Clone)]
pub struct WalkRun {
    /// Walk id.
    pub id: String,
    /// Protocol fold.
    pub fold: usize,
    /// Steps under the configuration of the run.
    pub steps: Vec<StepDetail>,
    /// Waypoints.
    pub waypoints: Vec<Waypoint>,
    /// First Wi-Fi scan time.
    pub first_wifi: Option<TimestampMs>,
}

/// Runs `cfg` over the walks of one floor (parallel); folds as the evaluation's
/// ([`crate::fold_rules::folds_of_walk_refs`]: by route where walks have routes, else by id).
pub fn run_walks(walks: &[&Walk], cfg: &CheckedPdrConfig) -> Vec<WalkRun> {
    let (folds, _) = folds_of_walk_refs(walks);
    walks
        .par_iter()
        .zip(folds)
        .map(|(walk, fold)| {
            let (steps, diag) = Pdr::run_detailed(*cfg, walk);
            if diag != Default::default() {
                tracing::debug!(walk = %walk.meta.id, ?diag, "PDR input diagnostics");
            }
            WalkRun {
                id: walk.meta.id.clone(),
                fold,
                steps,
                waypoints: walk.waypoints.clone(),
                first_wifi: walk.wifi.first().map(|s| s.t),
            }
        })
        .collect()
}

/// The runs that `keep` accepts, as calibration input.
pub fn walk_steps(runs: &[WalkRun], keep: impl Fn(&WalkRun) -> bool) -> Vec<WalkSteps<'_>> {
    runs.iter()
        .filter(|r| keep(r))
        .map(|r| WalkSteps {
            steps: &r.steps,
            waypoints: &r.waypoints,
        })
        .collect()
}

/// The calibration of the protocol on steps already run under `base`: the step-length
/// coefficients fitted on the training legs, then (when `cal.fit_heading_offset`) the heading
/// offset of `base.heading.source`, added to `base`'s, and (when heading snapping is on) the
/// grid orientation of the training legs, snapping turned off where they follow no grid
/// ([`wipdr_pdr::calibrate::fit_heading_snap`]). Returns `base` with the fitted values;
/// unchanged where there is nothing to fit on. Equal to
/// [`crate::pipeline::calibrate_pdr`] on the same walks (tested).
pub fn calibrate_steps(
    base: &PdrConfig,
    cal: &CalibrationConfig,
    walks: &[WalkSteps<'_>],
) -> PdrConfig {
    calibrate_steps_with_grid(base, cal, walks).0
}

/// [`calibrate_steps`], with the training legs' grid fit it made, `(orientation rad,
/// concentration)` (`None` when snapping is off in `base` or there are no legs), for tools
/// that report it (`wipdr pdr-fit`).
pub fn calibrate_steps_with_grid(
    base: &PdrConfig,
    cal: &CalibrationConfig,
    walks: &[WalkSteps<'_>],
) -> (PdrConfig, Option<(f64, f64)>) {
    wipdr_pdr::calibrate::calibrate_config(base, cal, walks)
}

fn source_slot(s: &mut StepDetail, source: HeadingSource) -> &mut Option<f64> {
    let h = &mut s.headings;
    match source {
        HeadingSource::RotationVector => &mut h.rotation_vector,
        HeadingSource::Gyro => &mut h.gyro,
        HeadingSource::GyroCompassKf => &mut h.gyro_compass_kf,
        HeadingSource::Compass => &mut h.compass,
    }
}

/// A step with the heading of `source` turned by `offset` (rad).
pub fn shift_heading(s: &StepDetail, source: HeadingSource, offset: f64) -> StepDetail {
    let mut s = *s;
    if let Some(v) = source_slot(&mut s, source).as_mut() {
        *v = wipdr_core::angle::wrap_pi(*v + offset);
    }
    s
}

/// The headings of `source` snapped in step order as the PDR pipeline snaps them
/// ([`wipdr_pdr::snap::HeadingSnap`]); unchanged when `snap` is off.
pub fn snap_headings(
    steps: &mut [StepDetail],
    source: HeadingSource,
    snap: &wipdr_pdr::snap::HeadingSnapConfig,
) {
    let mut state = wipdr_pdr::snap::HeadingSnap::default();
    for s in steps {
        if let Some(v) = source_slot(s, source).as_mut() {
            *v = state.apply(*v, snap);
        }
    }
}

/// A walk's steps as `(t, length, heading)`.
pub type Track = Vec<(TimestampMs, f64, f64)>;

/// Errors collected for one scheme.
#[derive(Debug, Default, Clone)]
pub struct SchemeErrors {
    /// PDR-only position errors at the waypoints, m.
    pub positions: Vec<f64>,
    /// Relative errors of the legs' summed step lengths.
    pub leg_length_rel: Vec<f64>,
    /// Heading errors of the legs' PDR displacement, degrees.
    pub leg_heading_deg: Vec<f64>,
    /// The heading offset fitted per fold, degrees.
    pub offsets_deg: Vec<f64>,
}

impl SchemeErrors {
    /// Appends another set.
    pub fn extend(&mut self, o: &SchemeErrors) {
        self.positions.extend(&o.positions);
        self.leg_length_rel.extend(&o.leg_length_rel);
        self.leg_heading_deg.extend(&o.leg_heading_deg);
        self.offsets_deg.extend(&o.offsets_deg);
    }
}

/// A PDR scheme to score: a step-length model and heading source, calibrated or not.
#[derive(Debug, Clone)]
pub struct PdrScheme {
    /// Name in the report.
    pub name: String,
    /// The step-length model (its coefficients are the prior of the fit).
    pub model: StepLengthConfig,
    /// The heading source.
    pub source: HeadingSource,
    /// Whether the model and offset are calibrated per fold ([`calibrate_steps`]).
    pub calibrate: bool,
    /// Whether the calibration fits the heading offset.
    pub fit_offset: bool,
    /// Whether it runs on the sample-code run (heading at step time) instead of the
    /// configured one.
    pub on_baseline_run: bool,
}

/// Scores `schemes` over one floor's runs under the protocol folds: per scheme the errors and
/// the test track of every walk (in run order). `base_runs` are the runs under `base_cfg`
/// (the sample code), `runs` under `cfg`.
pub fn score_schemes(
    (base_runs, base_cfg): (&[WalkRun], &PdrConfig),
    (runs, cfg): (&[WalkRun], &PdrConfig),
    schemes: &[PdrScheme],
    cal: &CalibrationConfig,
) -> Vec<(SchemeErrors, Vec<Track>)> {
    schemes
        .par_iter()
        .map(|sc| {
            let (runs, run_cfg) = if sc.on_baseline_run {
                (base_runs, base_cfg)
            } else {
                (runs, cfg)
            };
            let (min_len, max_len) = if sc.on_baseline_run {
                (0.0, 10.0)
            } else {
                (cfg.min_step_length, cfg.max_step_length)
            };
            let mut col = SchemeErrors::default();
            let mut tracks = vec![Vec::new(); runs.len()];
            let fold_count = runs.iter().map(|r| r.fold + 1).max().unwrap_or(0);
            for fold in 0..fold_count {
                let train = walk_steps(runs, |r| r.fold != fold);
                let (model, offset, snap) = if sc.calibrate {
                    let mut base = *run_cfg;
                    base.step_length = sc.model;
                    base.heading.source = sc.source;
                    let c = CalibrationConfig {
                        fit_heading_offset: sc.fit_offset,
                        ..*cal
                    };
                    let out = calibrate_steps(&base, &c, &train);
                    (
                        out.step_length,
                        out.heading.map_offset_rad - base.heading.map_offset_rad,
                        out.heading.snap,
                    )
                } else {
                    (sc.model, 0.0, run_cfg.heading.snap)
                };
                col.offsets_deg.push(offset.to_degrees());
                for (i, r) in runs.iter().enumerate().filter(|(_, r)| r.fold == fold) {
                    let mut shifted: Vec<StepDetail> = r
                        .steps
                        .iter()
                        .map(|s| shift_heading(s, sc.source, offset))
                        .collect();
                    // The legs see the headings the track below uses.
                    snap_headings(&mut shifted, sc.source, &snap);
                    let ws = WalkSteps {
                        steps: &shifted,
                        waypoints: &r.waypoints,
                    };
                    for e in leg_errors(&ws, &model, sc.source, cal) {
                        col.leg_length_rel.push(e.length_rel);
                        col.leg_heading_deg.push(e.heading.to_degrees());
                    }
                    let mut tr = track(&r.steps, &model, sc.source, offset, min_len, max_len);
                    wipdr_pdr::snap::snap_track(&mut tr, &snap);
                    col.positions.extend(
                        dead_reckon_at_waypoints(&tr, &r.waypoints, r.first_wifi)
                            .iter()
                            .map(|s| s.error),
                    );
                    tracks[i] = tr;
                }
            }
            (col, tracks)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fixture_walks() -> Vec<Walk> {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/sim/F1");
        let floor = wipdr_io::floor::read_floor_dir(&dir, &Default::default()).expect("fixture");
        floor.walks.into_iter().map(|w| w.walk).collect()
    }

    #[test]
    fn calibration_on_runs_equals_the_pipeline_calibration() {
        let walks = fixture_walks();
        let refs: Vec<&Walk> = walks.iter().collect();
        let base = CheckedPdrConfig::default();
        let cal = CalibrationConfig::default();
        let runs = run_walks(&refs, &base);
        let train: Vec<&Walk> = refs
            .iter()
            .zip(&runs)
            .filter(|(_, r)| r.fold != 0)
            .map(|(w, _)| *w)
            .collect();
        let ours = calibrate_steps(&base, &cal, &walk_steps(&runs, |r| r.fold != 0));
        let pipeline = crate::pipeline::calibrate_pdr(&base, &cal, &train);
        assert_eq!(ours, pipeline);
        assert_ne!(ours.step_length, base.step_length);
    }

    #[test]
    fn snapped_headings_match_the_snapped_track() {
        let walks = fixture_walks();
        let runs = run_walks(&[&walks[0]], &CheckedPdrConfig::default());
        let snap = wipdr_pdr::snap::HeadingSnapConfig {
            enabled: true,
            threshold_deg: 45.0,
            ..Default::default()
        };
        let source = HeadingSource::RotationVector;
        let mut steps = runs[0].steps.clone();
        snap_headings(&mut steps, source, &snap);
        let model = StepLengthConfig::default();
        let mut tr = track(&runs[0].steps, &model, source, 0.0, 0.0, 10.0);
        wipdr_pdr::snap::snap_track(&mut tr, &snap);
        let mut changed = 0;
        for ((s, t), raw) in steps.iter().zip(&tr).zip(&runs[0].steps) {
            if let Some(h) = s.headings.get(source) {
                assert!((h - t.2).abs() < 1e-12);
                changed += usize::from(Some(h) != raw.headings.get(source));
            }
        }
        assert!(changed > 0, "nothing snapped");
    }

    #[test]
    fn shift_turns_only_the_chosen_source() {
        let walks = fixture_walks();
        let runs = run_walks(&[&walks[0]], &CheckedPdrConfig::default());
        let s = runs[0].steps[0];
        let t = shift_heading(&s, HeadingSource::Gyro, 0.5);
        assert_eq!(t.headings.rotation_vector, s.headings.rotation_vector);
        if let (Some(a), Some(b)) = (s.headings.gyro, t.headings.gyro) {
            assert!((wipdr_core::angle::diff(b, a) - 0.5).abs() < 1e-12);
        }
    }
}
