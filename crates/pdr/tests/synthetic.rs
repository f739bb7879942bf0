//! Synthetic acceptance (issue 5): on simulated walks with known truth (`wipdr-sim`), the
//! step count is within 1 % of the truth, the step length error is under 5 % after
//! calibration on other walks, and turn detection has precision and recall of at least 95 %.

use wipdr_core::TurnState;
use wipdr_pdr::calibrate::{CalibrationConfig, WalkSteps, fit_step_length};
use wipdr_pdr::{HeadingSource, Pdr, PdrConfig, StepDetail};
use wipdr_sim::{SimConfig, WalkTruth, generate};

fn simulate(seed: u64, walks: usize) -> Vec<(wipdr_core::Walk, WalkTruth)> {
    let mut cfg = SimConfig {
        walks,
        duration_s: 120.0,
        ..Default::default()
    };
    cfg.survey.test_points = 5;
    let sim = generate(&cfg, seed).expect("simulation");
    sim.walks.into_iter().map(|w| (w.walk, w.truth)).collect()
}

/// Detected turn episodes: maximal runs of consecutive `Turning` steps, as time intervals
/// from the step before the run to the run's last step.
fn turn_episodes(steps: &[StepDetail]) -> Vec<(i64, i64)> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < steps.len() {
        if steps[i].event.motion.turn == TurnState::Turning {
            let start = if i > 0 {
                steps[i - 1].event.t
            } else {
                steps[i].event.t - 600
            };
            let mut j = i;
            while j + 1 < steps.len() && steps[j + 1].event.motion.turn == TurnState::Turning {
                j += 1;
            }
            out.push((start, steps[j].event.t));
            i = j + 1;
        } else {
            i += 1;
        }
    }
    out
}

fn overlaps(a: (i64, i64), b: (i64, i64), tol: i64) -> bool {
    a.0 <= b.1 + tol && b.0 <= a.1 + tol
}

#[test]
fn synthetic_acceptance() {
    let cfg = PdrConfig::default();
    let train = simulate(7, 6);
    let test = simulate(8, 10);

    // Calibrate the step length on the training walks' waypoints.
    let train_runs: Vec<(Vec<StepDetail>, &wipdr_core::Walk)> = train
        .iter()
        .map(|(w, _)| (Pdr::run_detailed(cfg.check().unwrap(), w).0, w))
        .collect();
    let walks: Vec<WalkSteps<'_>> = train_runs
        .iter()
        .map(|(s, w)| WalkSteps {
            steps: s,
            waypoints: &w.waypoints,
        })
        .collect();
    let cal = CalibrationConfig {
        heading_source: HeadingSource::RotationVector,
        ..Default::default()
    };
    let model = fit_step_length(cfg.step_length, &walks, &cal);
    let cfg = PdrConfig {
        step_length: model,
        ..cfg
    };

    let (mut n_true, mut n_det) = (0usize, 0usize);
    let (mut len_true, mut len_est) = (0.0, 0.0);
    let (mut tp_det, mut n_eps, mut tp_truth, mut n_turns) = (0usize, 0usize, 0usize, 0usize);
    let mut worst_count = 0.0f64;
    let mut per_step_rel = Vec::new();
    for (walk, truth) in &test {
        let (steps, diag) = Pdr::run_detailed(cfg.check().unwrap(), walk);
        assert_eq!(diag.steps_without_heading, 0);
        n_true += truth.steps.len();
        n_det += steps.len();
        worst_count = worst_count
            .max((steps.len() as f64 - truth.steps.len() as f64).abs() / truth.steps.len() as f64);
        len_true += truth.steps.iter().map(|s| s.length).sum::<f64>();
        len_est += steps.iter().map(|s| s.event.length).sum::<f64>();
        // Per step: the nearest true heel strike within 300 ms.
        for s in &steps {
            let i = truth.steps.partition_point(|x| x.t < s.event.t);
            let best = [i.wrapping_sub(1), i]
                .into_iter()
                .filter_map(|j| truth.steps.get(j))
                .min_by_key(|x| (x.t - s.event.t).abs());
            if let Some(x) = best.filter(|x| (x.t - s.event.t).abs() <= 300) {
                per_step_rel.push((s.event.length - x.length).abs() / x.length);
            }
        }
        let eps = turn_episodes(&steps);
        let turns: Vec<(i64, i64)> = truth.turns.iter().map(|t| (t.t_start, t.t_end)).collect();
        n_eps += eps.len();
        n_turns += turns.len();
        tp_det += eps
            .iter()
            .filter(|e| turns.iter().any(|t| overlaps(**e, *t, 500)))
            .count();
        tp_truth += turns
            .iter()
            .filter(|t| eps.iter().any(|e| overlaps(*e, **t, 500)))
            .count();
    }
    let count_err = (n_det as f64 - n_true as f64).abs() / n_true as f64;
    let mean_len_true = len_true / n_true as f64;
    let mean_len_est = len_est / n_det as f64;
    let len_err = (mean_len_est - mean_len_true).abs() / mean_len_true;
    let per_step = per_step_rel.iter().sum::<f64>() / per_step_rel.len().max(1) as f64;
    println!(
        "per matched step: mean |relative length error| {:.2} % over {} steps",
        100.0 * per_step,
        per_step_rel.len()
    );
    let precision = tp_det as f64 / n_eps.max(1) as f64;
    let recall = tp_truth as f64 / n_turns.max(1) as f64;
    println!(
        "steps {n_det} / {n_true} ({:.2} %, worst walk {:.2} %); mean step length {mean_len_est:.3} vs {mean_len_true:.3} m ({:.2} %); turns: {tp_det}/{n_eps} precision {:.3}, {tp_truth}/{n_turns} recall {:.3}",
        100.0 * count_err,
        100.0 * worst_count,
        100.0 * len_err,
        precision,
        recall
    );
    assert!(count_err < 0.01, "step count error {count_err}");
    assert!(len_err < 0.05, "step length error {len_err}");
    assert!(precision >= 0.95, "turn precision {precision}");
    assert!(recall >= 0.95, "turn recall {recall}");
}

/// Calibration of the turn threshold `T` (paper 001 eq. 17) on synthetic walks other than
/// the acceptance set: `cargo test -p wipdr-pdr --test synthetic -- --ignored --nocapture`.
#[test]
#[ignore = "calibration sweep, run by hand"]
fn turn_threshold_sweep() {
    let walks = simulate(11, 10);
    for t in [0.05, 0.1, 0.15, 0.2, 0.25, 0.3, 0.4, 0.5] {
        let mut cfg = PdrConfig::default();
        cfg.motion.turn_threshold_rad = t;
        let (mut tp_det, mut n_eps, mut tp_truth, mut n_turns) = (0, 0, 0, 0);
        for (walk, truth) in &walks {
            let steps = Pdr::run_detailed(cfg.check().unwrap(), walk).0;
            let eps = turn_episodes(&steps);
            let turns: Vec<(i64, i64)> = truth.turns.iter().map(|t| (t.t_start, t.t_end)).collect();
            n_eps += eps.len();
            n_turns += turns.len();
            tp_det += eps
                .iter()
                .filter(|e| turns.iter().any(|t| overlaps(**e, *t, 500)))
                .count();
            tp_truth += turns
                .iter()
                .filter(|t| eps.iter().any(|e| overlaps(*e, **t, 500)))
                .count();
        }
        println!(
            "T = {t:.2} rad: precision {:.3} ({tp_det}/{n_eps}), recall {:.3} ({tp_truth}/{n_turns})",
            tp_det as f64 / n_eps.max(1) as f64,
            tp_truth as f64 / n_turns.max(1) as f64
        );
    }
}
