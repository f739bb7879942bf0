//! Path-loss radio-map extension on real ILC floors: fit, extension and leave-out checks.
//!
//! ```text
//! cargo run --release -p wipdr-eval --example propagation [FLOOR_DIR ...]
//! ```
//!
//! Default floors: `ilc20/site2/F2` and `site2/F3` under the data root (`$WIPDR_DATA`, else
//! `../shared/data` beside the workspace; `wipdr_io::data_root()`). Skips with a printed
//! reason when the data is absent. Per floor, the radio map is built like the evaluation
//! pipeline's fold 0 (training walks = folds 1-4, `WalkMapConfig::default()`); then:
//!
//! 1. the fit over all APs (counts, median RMSE / exponent, wall time);
//! 2. the extension over the floor plan's walkable area (points added, wall time);
//! 3. leave-out checks: fit on the kept measured points, predict the held-out points' heard
//!    entries (only APs with a model trusted there, i.e. a kept hearing point within
//!    `max_extrapolation_m`), and compare |predicted - measured| with the baseline "value at
//!    the nearest kept point that heard the AP". Hold-outs: every 5th point; and a 20 m
//!    wide band across the floor (a synthetic coverage gap). Errors binned by the distance
//!    to that nearest kept hearing point.

use std::path::{Path, PathBuf};
use std::time::Instant;
use wipdr_core::Point2;
use wipdr_eval::fold_rules::folds_by_name;
use wipdr_fingerprint::RadioMap;
use wipdr_fingerprint::propagation::{
    ApModel, PropagationConfig, extend_radio_map, fit_ap_models_with_report,
};
use wipdr_fingerprint::walk_map::{WalkMapConfig, build_from_walks};
use wipdr_io::floor::{ReadOptions, read_floor_dir};

fn main() {
    let args: Vec<PathBuf> = std::env::args().skip(1).map(PathBuf::from).collect();
    let floors = if args.is_empty() {
        let d = wipdr_io::data_root().join("ilc20/site2");
        vec![d.join("F2"), d.join("F3")]
    } else {
        args
    };
    for dir in floors {
        if !dir.is_dir() {
            println!(
                "skip {}: no such directory (real data absent; set WIPDR_DATA to the data root)",
                dir.display()
            );
            continue;
        }
        if let Err(e) = run(&dir) {
            println!("{}: {e}", dir.display());
        }
    }
}

fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn run(dir: &Path) -> Result<(), Box<dyn std::error::Error>> {
    let floor = read_floor_dir(dir, &ReadOptions::default())?;
    let ids: Vec<&str> = floor
        .walks
        .iter()
        .map(|w| w.walk.meta.id.as_str())
        .collect();
    let folds = folds_by_name(&ids);
    let training = floor
        .walks
        .iter()
        .zip(&folds)
        .filter(|(_, f)| **f != 0)
        .map(|(w, _)| &w.walk);
    let (map, _) = build_from_walks(training, &WalkMapConfig::default())?;
    println!(
        "== {} (fold 0 training map): {} reference points, {} APs",
        floor.name,
        map.len(),
        map.n_aps()
    );
    for censored_weight in [0.0, 1.0] {
        let cfg = PropagationConfig {
            censored_weight,
            ..Default::default()
        };
        println!("-- censored_weight {censored_weight}");
        run_config(&floor, &map, &cfg)?;
    }
    Ok(())
}

fn run_config(
    floor: &wipdr_io::floor::FloorData,
    map: &RadioMap,
    cfg: &PropagationConfig,
) -> Result<(), Box<dyn std::error::Error>> {
    let t = Instant::now();
    let (models, fit) = fit_ap_models_with_report(map, cfg)?;
    let fit_s = t.elapsed().as_secs_f64();
    let fitted: Vec<&ApModel> = models.iter().flatten().collect();
    println!(
        "fit: {} models, dropped: {} too few samples, {} degenerate, {} not finite, {} rmse > {} dB; {:.3} s",
        fit.fitted,
        fit.too_few_samples,
        fit.degenerate,
        fit.not_finite,
        fit.rmse_too_high,
        cfg.max_rmse_db,
        fit_s
    );
    println!(
        "     median rmse {:.2} dB, median exponent {:.2}, median p0 {:.1} dBm, median samples {}",
        median(fitted.iter().map(|m| m.rmse_db).collect()),
        median(fitted.iter().map(|m| m.exponent).collect()),
        median(fitted.iter().map(|m| m.p0_dbm).collect()),
        median(fitted.iter().map(|m| m.samples as f64).collect()),
    );
    let at_bound = fitted
        .iter()
        .filter(|m| {
            m.exponent <= cfg.exponent_range[0] + 1e-9 || m.exponent >= cfg.exponent_range[1] - 1e-9
        })
        .count();
    let at_low = fitted
        .iter()
        .filter(|m| m.exponent <= cfg.exponent_range[0] + 1e-9)
        .count();
    println!(
        "     exponent at a bound: {at_bound} ({at_low} at the low bound {})",
        cfg.exponent_range[0]
    );
    let heard_per_point: Vec<f64> = (0..map.len())
        .filter(|&i| map.point(i).scans > 0)
        .map(|i| map.heard(i).count() as f64)
        .collect();
    let typical = median(heard_per_point);
    println!("     measured points hear a median of {typical} APs");

    let mut extended = map.clone();
    let t = Instant::now();
    let report = extend_radio_map(&mut extended, &models, cfg, |p| floor.plan.is_walkable(p))?;
    println!(
        "extend: {report:?}; {:.3} s; mean heard APs per added point {:.1}",
        t.elapsed().as_secs_f64(),
        report.entries_added as f64 / report.points_added.max(1) as f64
    );

    let measured: Vec<usize> = (0..map.len()).filter(|&i| map.point(i).scans > 0).collect();
    let every_fifth: Vec<usize> = measured.iter().copied().filter(|i| i % 5 == 4).collect();
    let capped = PropagationConfig {
        max_aps: Some(typical as usize),
        ..*cfg
    };
    let mut extended = map.clone();
    let report = extend_radio_map(&mut extended, &models, &capped, |p| {
        floor.plan.is_walkable(p)
    })?;
    println!(
        "extend with max_aps = {typical}: {} points added, {} capped, mean heard APs per added point {:.1}",
        report.points_added,
        report.points_capped,
        report.entries_added as f64 / report.points_added.max(1) as f64
    );
    leave_out(map, cfg, "every 5th point", &every_fifth);
    let xs: Vec<f64> = measured.iter().map(|&i| map.point(i).position.x).collect();
    let mid = median(xs);
    let band: Vec<usize> = measured
        .iter()
        .copied()
        .filter(|&i| (map.point(i).position.x - mid).abs() <= 10.0)
        .collect();
    leave_out(map, cfg, &format!("band |x - {mid:.0}| <= 10 m"), &band);
    Ok(())
}

const BINS: [f64; 4] = [3.0, 8.0, 14.0, 20.0];

fn leave_out(map: &RadioMap, cfg: &PropagationConfig, what: &str, held: &[usize]) {
    let held_set: std::collections::HashSet<usize> = held.iter().copied().collect();
    let kept: Vec<usize> = (0..map.len())
        .filter(|&i| map.point(i).scans > 0 && !held_set.contains(&i))
        .collect();
    let sub = map.subset(&kept);
    let models = match fit_ap_models_with_report(&sub, cfg) {
        Ok((m, _)) => m,
        Err(e) => {
            println!("leave-out {what}: {e}");
            return;
        }
    };
    // Per AP, the kept points that heard it.
    let mut hearing: Vec<Vec<(Point2, f32)>> = vec![Vec::new(); map.n_aps()];
    for i in 0..sub.len() {
        for (j, v) in sub.heard(i) {
            hearing[j].push((sub.point(i).position, v));
        }
    }
    // (model abs error, baseline abs error) per distance bin; plus untrusted entries.
    let mut bins: Vec<(f64, f64, usize)> = vec![(0.0, 0.0, 0); BINS.len()];
    let (mut no_model, mut untrusted, mut total) = (0usize, 0usize, 0usize);
    for &i in held {
        let p = map.point(i).position;
        for (j, v) in map.heard(i) {
            total += 1;
            let Some(model) = &models[j] else {
                no_model += 1;
                continue;
            };
            let nearest = hearing[j]
                .iter()
                .map(|&(q, w)| ((q - p).norm(), w))
                .min_by(|a, b| a.0.total_cmp(&b.0));
            let Some((d, base)) = nearest else {
                no_model += 1;
                continue;
            };
            if d > cfg.max_extrapolation_m {
                untrusted += 1;
                continue;
            }
            let b = BINS
                .iter()
                .position(|&edge| d <= edge)
                .unwrap_or(BINS.len() - 1);
            bins[b].0 += (model.predict(p) - f64::from(v)).abs();
            bins[b].1 += f64::from(base - v).abs();
            bins[b].2 += 1;
        }
    }
    let (sm, sb, n) = bins
        .iter()
        .fold((0.0, 0.0, 0), |a, b| (a.0 + b.0, a.1 + b.1, a.2 + b.2));
    println!(
        "leave-out {what}: {} held points, {total} heard entries: {no_model} without model, \
         {untrusted} beyond max_extrapolation_m, {n} compared",
        held.len()
    );
    println!(
        "     mean |err| model {:.2} dB, nearest-kept-hearing-point baseline {:.2} dB",
        sm / n.max(1) as f64,
        sb / n.max(1) as f64
    );
    // Heard-set agreement: at the held points, APs with a trusted model predicted at or above
    // a threshold vs APs actually heard.
    for threshold in [-90.0, -85.0, -80.0] {
        let (mut predicted, mut both, mut actual) = (0usize, 0usize, 0usize);
        for &i in held {
            let p = map.point(i).position;
            for (j, model) in models.iter().enumerate() {
                let Some(model) = model else { continue };
                let trusted = hearing[j]
                    .iter()
                    .any(|&(q, _)| (q - p).norm() <= cfg.max_extrapolation_m);
                if !trusted {
                    continue;
                }
                let heard = map.rss(i, j).is_some();
                actual += usize::from(heard);
                if model.predict(p) >= threshold {
                    predicted += 1;
                    both += usize::from(heard);
                }
            }
        }
        println!(
            "     heard set at >= {threshold} dBm: {:.1} predicted / {:.1} heard APs per point \
             (trusted models), precision {:.2}, recall {:.2}",
            predicted as f64 / held.len().max(1) as f64,
            actual as f64 / held.len().max(1) as f64,
            both as f64 / predicted.max(1) as f64,
            both as f64 / actual.max(1) as f64
        );
    }
    // The same with the strongest K predicted only, K = the kept points' median heard count.
    let mut counts: Vec<usize> = (0..sub.len()).map(|i| sub.heard(i).count()).collect();
    counts.sort_unstable();
    let k = counts.get(counts.len() / 2).copied().unwrap_or(0);
    let (mut predicted, mut both, mut actual) = (0usize, 0usize, 0usize);
    for &i in held {
        let p = map.point(i).position;
        let mut pred: Vec<(usize, f64)> = models
            .iter()
            .enumerate()
            .filter_map(|(j, m)| m.as_ref().map(|m| (j, m.predict(p))))
            .filter(|&(j, v)| {
                v >= cfg.min_predicted_dbm
                    && hearing[j]
                        .iter()
                        .any(|&(q, _)| (q - p).norm() <= cfg.max_extrapolation_m)
            })
            .collect();
        pred.sort_by(|a, b| b.1.total_cmp(&a.1));
        pred.truncate(k);
        predicted += pred.len();
        both += pred
            .iter()
            .filter(|&&(j, _)| map.rss(i, j).is_some())
            .count();
        actual += map.heard(i).count();
    }
    println!(
        "     strongest {k} predicted (>= {} dBm, trusted): {:.1} per point, precision {:.2}, \
         recall {:.2} of all {:.1} heard APs",
        cfg.min_predicted_dbm,
        predicted as f64 / held.len().max(1) as f64,
        both as f64 / predicted.max(1) as f64,
        both as f64 / actual.max(1) as f64,
        actual as f64 / held.len().max(1) as f64
    );
    let mut lo = 0.0;
    for (edge, (m, b, k)) in BINS.iter().zip(&bins) {
        if *k > 0 {
            println!(
                "     nearest kept hearing point {lo:>4.0}-{edge:<4.0} m: {k:>6} entries, model {:.2} dB, baseline {:.2} dB",
                m / *k as f64,
                b / *k as f64
            );
        }
        lo = *edge;
    }
}
