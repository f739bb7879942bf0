//! Real walks against the floor plans' walkable space: how often the truth lies in walkable
//! space, inside a unit, or outside the outline (what the walkability likelihood of `pmf` and
//! map matching may assume). Skips with a reason when the data root (`$WIPDR_DATA`, else
//! `../shared/data`) lacks the data.

mod common;

use common::{REAL_FLOORS, real_data, real_floor};
use wipdr_fusion::walkable::{CellClass, WalkableGrid};
use wipdr_io::cache::read_floor_dir_cached;
use wipdr_io::floor::ReadOptions;

#[test]
fn truth_is_mostly_walkable_on_the_real_floors() {
    let Some((root, cache)) = real_data() else {
        return;
    };
    for floor in REAL_FLOORS {
        let data =
            read_floor_dir_cached(root.join(floor), &cache, &ReadOptions::default()).unwrap();
        let grid = WalkableGrid::new(&data.plan, 0.5).unwrap();
        let (mut counts, mut total) = ([0usize; 3], 0usize);
        let mut exact_walkable = 0usize;
        for w in &data.walks {
            let wp = &w.walk.waypoints;
            for pair in wp.windows(2) {
                let (a, b) = (pair[0], pair[1]);
                let n = ((b.position - a.position).norm() / 0.5).ceil().max(1.0) as usize;
                for k in 0..n {
                    let f = k as f64 / n as f64;
                    let p = a.position + (b.position - a.position) * f;
                    counts[grid.class_at(p) as usize] += 1;
                    exact_walkable += usize::from(grid.is_walkable(p));
                    total += 1;
                }
            }
        }
        let share = |c: CellClass| counts[c as usize] as f64 / total as f64;
        println!(
            "{floor}: {total} truth points every 0.5 m; walkable {:.3} (exact {:.3}), unit {:.3}, outside {:.3}; walkable cells {:.3}",
            share(CellClass::Walkable),
            exact_walkable as f64 / total as f64,
            share(CellClass::Unit),
            share(CellClass::Outside),
            grid.walkable_fraction()
        );
        assert!(
            share(CellClass::Walkable) > 0.8,
            "{floor}: truth mostly walkable"
        );
    }
}

/// How long walkers stand still at the start: Wi-Fi scans before the first PDR step (what
/// the static start of paper 001 §3.2 can average).
#[test]
fn scans_before_the_first_step_on_the_real_floors() {
    use wipdr_eval::pipeline::{EvalConfig, prepare};
    let Some((root, cache)) = real_data() else {
        return;
    };
    let floor = real_floor(&root, &cache, "site1/F1");
    let prepared = prepare(std::slice::from_ref(&floor), &EvalConfig::default()).unwrap();
    let mut histogram = [0usize; 4];
    let mut standing_s = Vec::new();
    for w in &prepared {
        let first_step = w.steps.first().map_or(i64::MAX, |s| s.t);
        let held = w.observations.iter().filter(|o| o.t < first_step).count();
        histogram[held.min(3)] += 1;
        if let (Some(s), Some(o)) = (w.steps.first(), w.observations.first()) {
            standing_s.push((s.t - o.t) as f64 / 1000.0);
        }
    }
    standing_s.sort_by(f64::total_cmp);
    println!(
        "site1/F1: walks with 0 / 1 / 2 / 3+ fixes before the first step: {histogram:?}; \
         first step minus first fix, median {:.1} s",
        standing_s[standing_s.len() / 2]
    );
    assert_eq!(histogram.iter().sum::<usize>(), prepared.len());
}
