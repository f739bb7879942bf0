//! Tests of `pmf`.

use super::*;
use crate::Fuser;
use crate::walkable::CellClass;
use proptest::prelude::*;
use wipdr_core::{FloorPlan, MotionState, Polygon, StepEvent, Unit, WifiObservation, angle};

fn fix(t: TimestampMs, x: f64, y: f64) -> WifiObservation {
    WifiObservation {
        t,
        estimate: Point2::new(x, y),
        candidates: vec![],
        visited: 0,
        floor: None,
        building: None,
        likelihood: None,
    }
}

fn step(t: TimestampMs, heading: f64) -> StepEvent {
    StepEvent {
        t,
        length: 0.7,
        heading,
        heading_change: 0.0,
        period_s: 0.5,
        motion: MotionState::default(),
        covariance: None,
    }
}

fn rect(x0: f64, y0: f64, x1: f64, y1: f64) -> Polygon {
    Polygon::rectangle(x0, y0, x1, y1).unwrap()
}

/// A 60 m x 40 m floor whose only walkable space is a 3 m wide ring corridor around
/// one big unit.
fn ring_plan() -> Arc<WalkableGrid> {
    let plan = FloorPlan::new(
        60.0,
        40.0,
        vec![rect(0.0, 0.0, 60.0, 40.0)],
        vec![Unit {
            name: "block".into(),
            polygon: rect(3.0, 3.0, 57.0, 37.0),
        }],
    )
    .unwrap();
    Arc::new(WalkableGrid::new(&plan, 0.5).unwrap())
}

fn total(f: &PointMassFilter) -> f64 {
    let (x0, x1, y0, y1) = f.active;
    let n_active = (x1 - x0 + 1) * (y1 - y0 + 1);
    let mut s = f.bg * (f.prob.len() - n_active) as f64;
    for r in y0..=y1 {
        for c in x0..=x1 {
            s += f.prob[r * f.lattice.cols() + c];
        }
    }
    s
}

#[test]
fn walls_and_fixes_find_the_corridor() {
    // Walk north along the left corridor (x = 1.5) from y = 5, then east along the top
    // (y = 38.5). Fixes are 4 m off, one of them 40 m off.
    let mut f =
        PointMassFilter::new(PointMassConfig::default(), Some(ring_plan()), None, None).unwrap();
    let mut truth = Point2::new(1.5, 5.0);
    let mut t = 0;
    f.on_wifi(&fix(t, truth.x + 4.0, truth.y));
    for k in 0..90 {
        t += 500;
        let heading = if k < 48 {
            0.0
        } else {
            std::f64::consts::FRAC_PI_2
        };
        truth += angle::step_displacement(0.7, heading);
        f.on_step(&step(t, heading));
        if k % 6 == 5 {
            let gross = if k == 35 { 40.0 } else { 0.0 };
            f.on_wifi(&fix(t, truth.x + 3.0, truth.y - 3.0 + gross));
        }
        assert!((total(&f) - 1.0).abs() < 1e-9);
    }
    let p = f.estimate().unwrap().position;
    assert!((p - truth).norm() < 2.5, "estimate {p:?} truth {truth:?}");
    assert!(f.walkable.as_ref().unwrap().class_at(p) == CellClass::Walkable);
}

/// The x of the estimate after a walk north along the ring's left corridor (x = 1.5) whose
/// every fix lies 7 m east of the walker, inside the block.
fn estimate_x_with_fixes_in_the_block(cfg: PointMassConfig) -> f64 {
    let mut f = PointMassFilter::new(cfg, Some(ring_plan()), None, None).unwrap();
    let mut truth = Point2::new(1.5, 5.0);
    let mut t = 0;
    f.on_wifi(&fix(t, truth.x + 7.0, truth.y));
    for k in 0..40 {
        t += 500;
        truth += angle::step_displacement(0.7, 0.0);
        f.on_step(&step(t, 0.0));
        if k % 4 == 3 {
            f.on_wifi(&fix(t, truth.x + 7.0, truth.y));
        }
    }
    f.estimate().unwrap().position.x
}

#[test]
fn the_shipped_unit_weight_holds_the_corridor_harder_than_the_preset() {
    // The shipped unit weight is 0.65 (the preset keeps 0.8): fixes that keep pointing
    // into a shop pull the estimate less far off the corridor the walker is in.
    let shipped = PointMassConfig::default();
    assert_eq!(shipped.unit_likelihood, 0.65);
    assert_eq!(PointMassConfig::paper().unit_likelihood, 0.8);
    let soft = PointMassConfig {
        unit_likelihood: 0.8,
        ..shipped.clone()
    };
    let (hard_x, soft_x) = (
        estimate_x_with_fixes_in_the_block(shipped),
        estimate_x_with_fixes_in_the_block(soft),
    );
    // Measured: 0.65 ends at x 2.24 (the corridor is 0-3 m), 0.8 at x 6.94 (in the block).
    assert!(hard_x < 3.0, "0.65 leaves the corridor: x {hard_x}");
    assert!(soft_x > 3.0, "0.8 stays in the corridor: x {soft_x}");
}

#[test]
fn trails_pull_the_placement_onto_where_training_walks_went() {
    // No plan: one fix 4 m north of the truth, then a walk east along y = 0, where a
    // training trail runs. Without trails the estimate stays near the fix's y; with the
    // trail prior it moves onto the trail; with `trail_sd_m = 0` the prior is off.
    let trail = [wipdr_core::Segment {
        a: Point2::new(-50.0, 0.0),
        b: Point2::new(50.0, 0.0),
    }];
    let raster = Arc::new(TrailRaster::new(&trail, 0.5, 10.0).unwrap());
    let run = |cfg: PointMassConfig, trails: Option<Arc<TrailRaster>>| {
        let mut f = PointMassFilter::new(cfg, None, None, None)
            .unwrap()
            .with_trails(trails);
        f.on_wifi(&fix(0, 0.0, 4.0));
        for k in 1..=30 {
            f.on_step(&step(500 * k, std::f64::consts::FRAC_PI_2));
            assert!((total(&f) - 1.0).abs() < 1e-9);
        }
        f.estimate().unwrap().position
    };
    let on = PointMassConfig {
        trail_sd_m: 1.0,
        off_trail_likelihood: 0.5,
        ..PointMassConfig::default()
    };
    let without = run(on.clone(), None);
    let with = run(on.clone(), Some(raster.clone()));
    let off = run(
        PointMassConfig {
            trail_sd_m: 0.0,
            planless_trail_sd_m: 0.0,
            ..on.clone()
        },
        Some(raster.clone()),
    );
    // `trail_sd_m` 0 on a filter without walls: the planless width (default 6 m) applies.
    let planless = run(
        PointMassConfig {
            trail_sd_m: 0.0,
            ..on
        },
        Some(raster),
    );
    assert!(without.y > 3.0, "{without:?}");
    assert!(with.y.abs() < 1.0, "{with:?}");
    assert_eq!(off, without);
    assert!((with.x - 21.0).abs() < 1.0, "{with:?}");
    assert!(planless.y < without.y - 0.5, "{planless:?} {without:?}");
}

#[test]
fn planless_trails_are_not_used_where_the_plan_has_walls() {
    // The ring plan has walls: with `trail_sd_m` 0 the planless width must not switch the
    // trail prior on, so a trail along the bottom corridor changes nothing.
    let trail = [wipdr_core::Segment {
        a: Point2::new(1.5, 1.5),
        b: Point2::new(58.5, 1.5),
    }];
    let raster = Arc::new(TrailRaster::new(&trail, 0.5, 10.0).unwrap());
    let run = |trails: Option<Arc<TrailRaster>>| {
        let cfg = PointMassConfig::default();
        assert!(cfg.trail_sd_m == 0.0 && cfg.planless_trail_sd_m > 0.0);
        let mut f = PointMassFilter::new(cfg, Some(ring_plan()), None, None)
            .unwrap()
            .with_trails(trails);
        f.on_wifi(&fix(0, 10.0, 35.0));
        for k in 1..=20 {
            f.on_step(&step(500 * k, std::f64::consts::FRAC_PI_2));
        }
        f.estimate().unwrap().position
    };
    assert_eq!(run(Some(raster)), run(None));
}

#[test]
fn gap_raster_marks_cells_beyond_the_distance() {
    let points = vec![Point2::new(10.0, 10.0), Point2::new(40.0, 10.0)];
    let g = GapRaster::new(
        &points,
        1.0,
        8.0,
        (Point2::new(0.0, 0.0), Point2::new(60.0, 30.0)),
    )
    .unwrap();
    for (x, y, gap) in [
        (10.0, 10.0, false),
        (16.0, 12.0, false),
        (40.0, 17.0, false),
        (25.0, 10.0, true),
        (10.0, 25.0, true),
        (-5.0, 10.0, true),
    ] {
        assert_eq!(g.is_gap(Point2::new(x, y)), gap, "({x}, {y})");
    }
    assert!(GapRaster::new(&[], 1.0, 8.0, (Point2::origin(), Point2::new(1.0, 1.0))).is_none());
}

/// An extent too large (1e20, 1e308 apart) or non-finite gives no gap raster, not a panic
/// (the old `ceil() as usize + 1` overflowed, or wrapped to an empty raster in release).
#[test]
fn a_gap_raster_over_an_absurd_extent_is_none() {
    let points = [Point2::new(1.0, 1.0)];
    for (lo, hi) in [
        (Point2::new(0.0, 0.0), Point2::new(1e20, 1.0)),
        (Point2::new(0.0, -1e308), Point2::new(1.0, 1e308)),
        (Point2::new(-f64::MAX, 0.0), Point2::new(f64::MAX, 1.0)),
        (Point2::new(f64::NAN, 0.0), Point2::new(1.0, 1.0)),
        (Point2::new(0.0, 0.0), Point2::new(f64::INFINITY, 1.0)),
    ] {
        assert!(
            GapRaster::new(&points, 1.0, 8.0, (lo, hi)).is_none(),
            "{lo:?} {hi:?}"
        );
    }
    // Far reference points are simply outside a sane raster.
    let far = [
        Point2::new(1e20, 1.0),
        Point2::new(f64::NAN, 1.0),
        Point2::new(2.0, 2.0),
    ];
    let g = GapRaster::new(&far, 1.0, 3.0, (Point2::origin(), Point2::new(10.0, 10.0))).unwrap();
    assert!(!g.is_gap(Point2::new(2.5, 2.5)) && g.is_gap(Point2::new(9.5, 9.5)));
}

#[test]
fn the_radius_adds_the_bias_share_of_the_learned_fix_error() {
    let mut f = PointMassFilter::new(PointMassConfig::default(), None, None, None).unwrap();
    for k in 0..6 {
        f.on_wifi(&fix(k * 2000, (k % 2) as f64 * 8.0, 0.0));
    }
    let (_, lattice) = f.lattice_estimate().unwrap();
    let p = f.estimate().unwrap().covariance.unwrap();
    let share = f.cfg.radius.bias_share * f.fix_error.variance();
    assert!(share > 0.0);
    assert!((p[(0, 0)] - lattice[(0, 0)] - share).abs() < 1e-6);
    assert!((p[(1, 1)] - lattice[(1, 1)] - share).abs() < 1e-6);
}

#[test]
fn the_gap_raster_holds_the_distance_to_the_nearest_point_up_to_its_reach() {
    let points = vec![Point2::new(10.5, 10.5)];
    let g = GapRaster::new(
        &points,
        1.0,
        5.0,
        (Point2::new(0.0, 0.0), Point2::new(40.0, 20.0)),
    )
    .unwrap();
    // Cell centres: (10.5, 10.5) itself, 3 and 4 cells away, and beyond the search
    // (5 m + two cells), where the cap answers.
    assert_eq!(g.distance_at(Point2::new(10.5, 10.5), 100.0), 0.0);
    assert!((g.distance_at(Point2::new(13.5, 10.5), 100.0) - 3.0).abs() < 1e-6);
    assert!((g.distance_at(Point2::new(13.5, 14.5), 100.0) - 5.0).abs() < 1e-6);
    assert_eq!(g.distance_at(Point2::new(30.5, 10.5), 7.0), 7.0);
    assert_eq!(g.distance_at(Point2::new(-50.0, 10.0), 7.0), 7.0);
    assert!((g.distance_at(Point2::new(13.5, 10.5), 2.0) - 2.0).abs() < 1e-12);
}

/// The gap term adds `(k d)^2` per axis, d the estimate's distance to coverage: nothing on
/// a reference point, more the farther the estimate is, nothing when off or without a
/// coverage raster; the estimate itself never moves.
#[test]
fn the_radius_grows_with_the_estimates_distance_from_coverage() {
    let coverage = Arc::new(vec![Point2::new(0.0, 0.0)]);
    let run = |k: f64, coverage: Option<Arc<Vec<Point2>>>, x: f64| {
        let cfg = PointMassConfig {
            gap_radius_sd_per_m: k,
            ..PointMassConfig::default()
        };
        let mut f = PointMassFilter::new(cfg, None, coverage, None).unwrap();
        for t in 0..4 {
            f.on_wifi(&fix(t * 2000, x, 0.0));
        }
        let (p, lattice) = f.lattice_estimate().unwrap();
        let e = f.estimate().unwrap();
        assert_eq!(e.position, p);
        let c = e.covariance.unwrap();
        let bias = f.cfg.radius.bias_share * f.fix_error.variance();
        (p, c[(0, 0)] - lattice[(0, 0)] - bias, f.gap_sd_m_at(p))
    };
    let (p_near, added_near, _) = run(0.5, Some(coverage.clone()), 0.0);
    let (p_far, added_far, sd_far) = run(0.5, Some(coverage.clone()), 8.0);
    let (p_off, added_off, _) = run(0.0, Some(coverage.clone()), 8.0);
    let (_, added_none, _) = run(0.5, None, 8.0);
    assert!(added_near.abs() < 0.5 * 0.5 * 2.0, "{added_near}");
    let d = (p_far - Point2::origin()).norm();
    assert!(d > 5.0, "{p_far:?}");
    assert!((sd_far - 0.5 * d).abs() < 1.0, "{sd_far} vs {d}");
    assert!(
        (added_far - sd_far * sd_far).abs() < 1e-6,
        "{added_far} {sd_far}"
    );
    assert!(added_off.abs() < 1e-9 && added_none.abs() < 1e-9);
    assert_eq!(p_far, p_off);
    assert!(p_near.coords.norm() < 1.0);
}

#[test]
fn the_median_stays_on_a_heavy_mode_that_the_mean_leaves() {
    let mut f = PointMassFilter::new(PointMassConfig::default(), None, None, None).unwrap();
    f.lattice = GridSpec::new(Point2::origin(), 1.0, 30, 10, usize::MAX).unwrap();
    f.prob = vec![0.0; 300];
    f.active = (0, 29, 0, 9);
    // 60 % of the mass in one cell, 20 % each in two cells 20 and 25 m away.
    let (heavy, b, c) = (5 * 30 + 2, 5 * 30 + 22, 5 * 30 + 27);
    (f.prob[heavy], f.prob[b], f.prob[c]) = (0.6, 0.2, 0.2);
    let mean = f.mean_near(heavy, 0.0);
    let median = f.median_near(heavy, 0.0, mean);
    assert!((mean - f.offset_of(heavy)).norm() > 8.0, "{mean:?}");
    assert!((median - f.offset_of(heavy)).norm() < 0.05, "{median:?}");
    // The radius leaves the far cells out: both are the heavy cell then.
    let near = f.median_near(heavy, 10.0, f.mean_near(heavy, 10.0));
    assert!((near - f.offset_of(heavy)).norm() < 1e-9, "{near:?}");
}

#[test]
fn a_given_start_is_kept_by_a_pdr_walk() {
    let mut f = PointMassFilter::new(
        PointMassConfig::default(),
        None,
        None,
        Some(Point2::new(5.0, 5.0)),
    )
    .unwrap();
    for k in 1..=10 {
        f.on_step(&step(k * 500, 0.0));
    }
    let p = f.estimate().unwrap().position;
    assert!((p - Point2::new(5.0, 12.0)).norm() < 1.0, "{p:?}");
}

#[test]
fn invalid_configs_are_rejected() {
    for cfg in [
        PointMassConfig {
            cell_m: 0.0,
            ..Default::default()
        },
        PointMassConfig {
            unit_likelihood: 0.0,
            ..Default::default()
        },
        PointMassConfig {
            wifi_outlier: f64::NAN,
            ..Default::default()
        },
        PointMassConfig {
            cell_m: 0.001,
            ..Default::default()
        },
    ] {
        let with_plan = PointMassFilter::new(cfg, Some(ring_plan()), None, None);
        assert!(with_plan.is_err());
    }
}

/// The mode as `choose_mode` chose it before it was split into rows and lanes: a
/// summed-area table and a cell-by-cell scan with clipped squares (no hysteresis).
fn mode_cell_by_cell(f: &PointMassFilter) -> usize {
    let (x0, x1, y0, y1) = f.active;
    let (w, h) = (x1 - x0 + 1, y1 - y0 + 1);
    let mut sat = vec![0.0; (w + 1) * (h + 1)];
    for r in 0..h {
        let mut row = 0.0;
        for c in 0..w {
            row += f.prob[(y0 + r) * f.lattice.cols() + x0 + c];
            sat[(r + 1) * (w + 1) + c + 1] = sat[r * (w + 1) + c + 1] + row;
        }
    }
    let k = (f.cfg.mode_radius_m / f.cfg.cell_m).round() as usize;
    let mut best = (0usize, 0usize, f64::NEG_INFINITY);
    for r in 0..h {
        for c in 0..w {
            let (a0, a1) = (c.saturating_sub(k), (c + k).min(w - 1) + 1);
            let (b0, b1) = (r.saturating_sub(k), (r + k).min(h - 1) + 1);
            let m = sat[b1 * (w + 1) + a1] - sat[b0 * (w + 1) + a1] - sat[b1 * (w + 1) + a0]
                + sat[b0 * (w + 1) + a0];
            if m > best.2 {
                best = (c, r, m);
            }
        }
    }
    (y0 + best.1) * f.lattice.cols() + x0 + best.0
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    /// The row-wise mode search picks the very cell of the cell-by-cell scan, for windows
    /// narrower and wider than the mode's square, ties included (coarse values).
    #[test]
    fn mode_search_matches_the_cell_by_cell_scan(
        (nx, ny, values) in (1usize..40, 1usize..30).prop_flat_map(|(nx, ny)| {
            (Just(nx), Just(ny), proptest::collection::vec(0u8..6, nx * ny))
        }),
        window in (0.0f64..1.0, 0.0f64..1.0, 0.0f64..1.0, 0.0f64..1.0),
        radius in 0usize..8,
    ) {
        let cfg = PointMassConfig { mode_radius_m: radius as f64, ..Default::default() };
        let mut f = PointMassFilter::new(cfg, None, None, None).unwrap();
        f.lattice = GridSpec::new(Point2::origin(), 1.0, nx, ny, usize::MAX).unwrap();
        f.prob = values.iter().map(|&v| f64::from(v) / 7.0).collect();
        let pick = |a: f64, b: f64, n: usize| {
            let (a, b) = ((a * n as f64) as usize, (b * n as f64) as usize);
            (a.min(b).min(n - 1), a.max(b).min(n - 1))
        };
        let ((x0, x1), (y0, y1)) = (pick(window.0, window.1, nx), pick(window.2, window.3, ny));
        f.active = (x0, x1, y0, y1);
        f.mode = None;
        f.choose_mode();
        prop_assert_eq!(f.mode, Some(mode_cell_by_cell(&f)));
    }

    /// The geometric median is never worse than the mean it starts from in expected
    /// Euclidean distance (what `estimate_median` reports), within and beyond the radius.
    #[test]
    fn the_median_has_no_larger_expected_distance_than_the_mean(
        (nx, ny, values) in (1usize..25, 1usize..20).prop_flat_map(|(nx, ny)| {
            (Just(nx), Just(ny), proptest::collection::vec(0u8..6, nx * ny))
        }),
        centre in 0.0f64..1.0,
        radius in prop_oneof![Just(0.0f64), 1.0f64..12.0],
    ) {
        let mut f = PointMassFilter::new(PointMassConfig::default(), None, None, None).unwrap();
        f.lattice = GridSpec::new(Point2::origin(), 1.0, nx, ny, usize::MAX).unwrap();
        f.prob = values.iter().map(|&v| f64::from(v) / 7.0).collect();
        f.active = (0, nx - 1, 0, ny - 1);
        let centre = ((centre * (nx * ny) as f64) as usize).min(nx * ny - 1);
        let expected_distance = |m: Vector2| {
            let mut d = 0.0;
            f.for_each_near(centre, radius, |o, p| d += p * (o - m).norm());
            d
        };
        let mean = f.mean_near(centre, radius);
        let median = f.median_near(centre, radius, mean);
        prop_assert!(median.x.is_finite() && median.y.is_finite());
        prop_assert!(expected_distance(median) <= expected_distance(mean) + 1e-9);
    }

    /// Looking a point's raster row and column up separately finds the raster's own cell,
    /// and both are the hand-written `floor((v - origin) / cell)` the filter used before the
    /// grid type (so the lattice's look-ups kept their bits).
    #[test]
    fn split_lookups_match_the_raster(
        points in proptest::collection::vec((-20.0f64..80.0, -20.0f64..60.0), 1..200),
        shift in (-1.0f64..1.0, -1.0f64..1.0),
    ) {
        let walkable = ring_plan();
        let grid = *walkable.grid();
        let (lo, cell, (gnx, gny)) = (grid.origin(), grid.cell_m(), grid.dims());
        let by_hand = |v: f64, origin: f64, n: usize| {
            let c = ((v - origin) / cell).floor();
            (c >= 0.0 && c < n as f64).then_some(c as usize)
        };
        let odd = [Point2::new(f64::NAN, 1.0), Point2::new(1.0, f64::INFINITY)];
        let all = points.iter().map(|&(x, y)| Point2::new(x + shift.0, y + shift.1));
        for p in all.chain(odd) {
            let (column, row) = (grid.col_of(p.x), grid.row_of(p.y));
            prop_assert_eq!(column, by_hand(p.x, lo.x, gnx));
            prop_assert_eq!(row, by_hand(p.y, lo.y, gny));
            let split = row.zip(column).map(|(r, c)| r * gnx + c);
            prop_assert_eq!(split, walkable.cell_of(p), "{:?}", p);
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]
    /// Whatever the inputs (huge, far, out of the plan, into walls), the probabilities
    /// stay a distribution and the estimate stays finite.
    #[test]
    fn probabilities_stay_a_distribution(
        inputs in proptest::collection::vec((any::<bool>(), -1e4f64..1e4, -1e4f64..1e4, -10.0f64..10.0), 1..60),
        with_plan in any::<bool>(),
    ) {
        let plan = with_plan.then(ring_plan);
        let mut f = PointMassFilter::new(PointMassConfig::default(), plan, None, None).unwrap();
        for (k, (is_fix, x, y, h)) in inputs.into_iter().enumerate() {
            let t = k as TimestampMs * 300;
            if is_fix {
                f.on_wifi(&fix(t, x / 100.0, y / 100.0));
            } else {
                f.on_step(&step(t, h));
            }
            if f.initialised {
                prop_assert!((total(&f) - 1.0).abs() < 1e-9, "total {}", total(&f));
                prop_assert!(f.prob.iter().all(|v| v.is_finite() && *v >= 0.0));
            }
            if let Some(e) = f.estimate() {
                prop_assert!(e.position.x.is_finite() && e.position.y.is_finite());
            }
        }
    }
}

/// North 21 m then east 21 m; fixes every 5 s along the truth, 4 m off to alternating sides.
fn l_walk() -> (Vec<StepEvent>, Vec<WifiObservation>) {
    let steps = (1..=60)
        .map(|k| {
            step(
                500 * k,
                if k <= 30 {
                    0.0
                } else {
                    std::f64::consts::FRAC_PI_2
                },
            )
        })
        .collect();
    let fixes = (0..=6)
        .map(|k| {
            let t = 5_000 * k;
            let s = 0.7 * (t / 500) as f64;
            let (x, y) = if s <= 21.0 {
                (0.0, s)
            } else {
                (s - 21.0, 21.0)
            };
            fix(t, x + if k % 2 == 0 { 4.0 } else { -4.0 }, y)
        })
        .collect();
    (steps, fixes)
}

#[test]
fn the_last_smoothed_estimate_is_the_forward_filters() {
    let (steps, fixes) = l_walk();
    let new = || PointMassFilter::new(PointMassConfig::default(), None, None, None).unwrap();
    let track = new().smooth_walk(&steps, &fixes).unwrap();
    let mut forward = new();
    for input in crate::replay::merged(&steps, &fixes) {
        match input {
            crate::replay::FusionInput::Step(i) => forward.on_step(&steps[i]),
            crate::replay::FusionInput::Wifi(j) => forward.on_wifi(&fixes[j]),
        }
    }
    let (a, b) = (track.last().unwrap(), forward.estimate().unwrap());
    assert!((a.position - b.position).norm() < 0.5, "{a:?} vs {b:?}");
}

#[test]
fn a_mixture_of_one_hypothesis_is_the_filter() {
    let (steps, fixes) = l_walk();
    let cfg = PointMassConfig::default();
    let ctx = crate::BuildContext::default();
    let mut filter = PointMassFilter::from_context(&cfg, &ctx).unwrap();
    let mut mixture = PointMassMixture::from_context(&cfg, &ctx).unwrap();
    for input in crate::replay::merged(&steps, &fixes) {
        match input {
            crate::replay::FusionInput::Step(i) => {
                filter.on_step(&steps[i]);
                mixture.on_step(&steps[i]);
            }
            crate::replay::FusionInput::Wifi(j) => {
                filter.on_wifi(&fixes[j]);
                mixture.on_wifi(&fixes[j]);
            }
        }
        assert_eq!(
            filter.estimate().map(|e| e.position),
            mixture.estimate().map(|e| e.position)
        );
    }
    assert_eq!(mixture.weights(), vec![1.0]);
    let smoothed = |m: PointMassMixture| m.smooth_walk(&steps, &fixes).unwrap();
    let one = PointMassFilter::from_context(&cfg, &ctx).unwrap();
    let a: Vec<Point2> = one
        .smooth_walk(&steps, &fixes)
        .unwrap()
        .iter()
        .map(|e| e.position)
        .collect();
    let b: Vec<Point2> = smoothed(PointMassMixture::from_context(&cfg, &ctx).unwrap())
        .iter()
        .map(|e| e.position)
        .collect();
    assert_eq!(a, b);
}

#[test]
fn the_walls_pick_the_heading_hypothesis() {
    // The ring corridor walked north then east while PDR reports every heading 8 degrees
    // short: only the +8 hypothesis keeps the track inside the 3 m corridor.
    let cfg = PointMassConfig {
        heading_hypotheses_deg: vec![-8.0, 0.0, 8.0],
        ..PointMassConfig::default()
    };
    let ctx = crate::BuildContext {
        walkable: Some(ring_plan()),
        ..crate::BuildContext::default()
    };
    let mut f = PointMassMixture::from_context(&cfg, &ctx).unwrap();
    let bias = 8f64.to_radians();
    let (steps, fixes, truths) = ring_walk(3.0);
    for input in crate::replay::merged(&steps, &fixes) {
        match input {
            crate::replay::FusionInput::Step(i) => f.on_step(&StepEvent {
                heading: steps[i].heading - bias,
                ..steps[i]
            }),
            crate::replay::FusionInput::Wifi(j) => f.on_wifi(&fixes[j]),
        }
    }
    let truth = *truths.last().unwrap();
    let w = f.weights();
    assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-12);
    assert!(w[2] > 0.9, "weights {w:?}");
    let p = f.estimate().unwrap().position;
    assert!((p - truth).norm() < 3.0, "estimate {p:?} truth {truth:?}");
}

#[test]
fn the_fixes_pick_the_step_scale_hypothesis() {
    // A straight walk north whose PDR steps are 20 % short; exact fixes every 5 steps. The
    // fixes' evidence favours the scale that undoes the shortening (1.25), and the mixture's
    // estimate stays near the truth.
    let cfg = PointMassConfig {
        step_scale_hypotheses: vec![0.8, 1.0, 1.25],
        ..PointMassConfig::default()
    };
    let mut f = PointMassMixture::from_context(&cfg, &crate::BuildContext::default()).unwrap();
    let mut truth = Point2::new(0.0, 0.0);
    f.on_wifi(&fix(0, truth.x, truth.y));
    for k in 1..=100 {
        truth.y += 0.7;
        f.on_step(&StepEvent {
            length: 0.56,
            ..step(500 * k, 0.0)
        });
        if k % 5 == 0 {
            f.on_wifi(&fix(500 * k, truth.x, truth.y));
        }
    }
    let w = f.weights();
    assert!(w[2] > w[1] && w[2] > w[0], "weights {w:?}");
    let p = f.estimate().unwrap().position;
    assert!((p - truth).norm() < 2.0, "estimate {p:?} truth {truth:?}");
}

#[test]
fn too_many_hypotheses_are_refused_naming_the_field() {
    let cfg = PointMassConfig {
        heading_hypotheses_deg: vec![-3.0, 0.0, 3.0],
        step_scale_hypotheses: vec![0.9, 0.95, 1.0, 1.05, 1.1, 1.15],
        ..PointMassConfig::default()
    };
    match cfg.validate() {
        Err(FusionError::InvalidConfig(e)) => assert_eq!(e.path, "step_scale_hypotheses"),
        other => panic!("{other:?}"),
    }
    let cfg = PointMassConfig {
        step_scale_hypotheses: vec![0.0],
        ..PointMassConfig::default()
    };
    assert!(cfg.validate().is_err());
}

#[test]
fn smoothing_on_a_plan_places_the_walk_start_by_the_later_evidence() {
    // The ring corridor walked north then east; every fix 3 m off, the first one 15 m off
    // (the start a causal filter gets wrong). The smoothed start uses the later fixes and
    // the turn the walls pin down; the smoothed track stays in walkable space.
    let plan = ring_plan();
    let (steps, fixes, truths) = ring_walk(15.0);
    let new = || PointMassFilter::new(PointMassConfig::default(), Some(plan.clone()), None, None);
    let track = new().unwrap().smooth_walk(&steps, &fixes).unwrap();
    assert_eq!(track.len(), steps.len() + fixes.len());
    let first = track[0].position;
    assert!((first - truths[0]).norm() < 3.0, "smoothed start {first:?}");
    let mut causal = new().unwrap();
    causal.on_wifi(&fixes[0]);
    let causal_first = causal.estimate().unwrap().position;
    assert!((causal_first - truths[0]).norm() > (first - truths[0]).norm() + 5.0);
    for e in &track {
        assert!(
            plan.class_at(e.position) != CellClass::Outside,
            "{:?}",
            e.position
        );
    }
}

/// The ring corridor of [`ring_plan`] walked north from (1.5, 5) for 48 steps, then east (90
/// steps of 0.7 m, 0.5 s apart): the steps, the fixes (the first `first_offset_m` east of the
/// start, then one every 6 steps 3 m east and 3 m south of the truth) and the truth after
/// each step (the start first).
fn ring_walk(first_offset_m: f64) -> (Vec<StepEvent>, Vec<WifiObservation>, Vec<Point2>) {
    let mut truth = Point2::new(1.5, 5.0);
    let (mut steps, mut fixes, mut truths) = (Vec::new(), Vec::new(), vec![truth]);
    fixes.push(fix(0, truth.x + first_offset_m, truth.y));
    for k in 0..90 {
        let t = 500 * (k + 1);
        let heading = if k < 48 {
            0.0
        } else {
            std::f64::consts::FRAC_PI_2
        };
        truth += angle::step_displacement(0.7, heading);
        truths.push(truth);
        steps.push(step(t, heading));
        if k % 6 == 5 {
            fixes.push(fix(t, truth.x + 3.0, truth.y - 3.0));
        }
    }
    (steps, fixes, truths)
}

/// A motion event with a covariance blurs the lattice by its mean per-axis variance, not by
/// the step model's drift: `apply_step` reports the blurs it did (0.5 cell² each).
#[test]
fn a_displacement_with_covariance_blurs_by_its_variance() {
    let run = |covariance: Option<[f64; 3]>| {
        let mut f = PointMassFilter::new(PointMassConfig::default(), None, None, None).unwrap();
        f.on_wifi(&fix(0, 0.0, 0.0));
        let event = StepEvent {
            covariance,
            ..step(1000, 0.0)
        };
        f.apply_step(&event).unwrap()
    };
    // default drift 0.05 m² a step: no blur yet on a 1 m lattice
    assert_eq!(run(None), 0);
    // mean variance (2.2 + 1.8) / 2 = 2 m²: four blurs of 0.5 m²
    assert_eq!(run(Some([2.2, 0.1, 1.8])), 4);
    // the largest usable covariance: at most MAX_EVENT_BLURS passes
    assert_eq!(run(Some([1e6, 0.0, 1e6])), 64);
}

/// A scan likelihood over an 80 m x 30 m raster (2 m cells) with a Gaussian bump of 3 m at
/// each of `peaks` (log-likelihood `-d² / 2 sd²` to the nearest peak).
fn bumps(peaks: &[(f64, f64)]) -> Arc<wipdr_core::WifiLikelihood> {
    let grid = GridSpec::new(Point2::origin(), 2.0, 40, 15, 10_000).unwrap();
    let values: Vec<Option<f64>> = (0..grid.len())
        .map(|i| {
            let c = grid.centre_of_index(i);
            let d2 = peaks
                .iter()
                .map(|&(x, y)| (c - Point2::new(x, y)).norm_squared())
                .fold(f64::INFINITY, f64::min);
            Some(-d2 / (2.0 * 9.0))
        })
        .collect();
    Arc::new(wipdr_core::WifiLikelihood::from_log(grid, &values, 0.0).unwrap())
}

/// A scan that fits two places keeps both: the matcher's point picks the wrong place at
/// each scan (10 m west of it, consistently), the walk moves 7 m north, and only the truth's
/// place fits both scans' likelihoods. With the likelihood alone `pmf` ends at the truth;
/// with the Gaussian about the points it follows them; with `wifi_likelihood` off the
/// likelihood a fix carries is not read.
#[test]
fn a_scan_that_fits_two_places_keeps_both_until_the_walk_chooses() {
    let truth = Point2::new(40.0, 17.0);
    let run = |cfg: PointMassConfig| {
        let mut f = PointMassFilter::new(cfg, None, None, None).unwrap();
        // The truth starts at (40, 10); the scan fits (10, 10) as well, and the point is there.
        let mut first = fix(0, 10.0, 10.0);
        first.likelihood = Some(bumps(&[(10.0, 10.0), (40.0, 10.0)]));
        f.on_wifi(&first);
        for k in 1..=10 {
            f.on_step(&step(500 * k, 0.0));
        }
        // At (40, 17) the scan fits (70, 17) too; the point is at (10, 17), where the first
        // wrong place would have walked.
        let mut second = fix(6000, 10.0, 17.0);
        second.likelihood = Some(bumps(&[(40.0, 17.0), (70.0, 17.0)]));
        f.on_wifi(&second);
        f.estimate().unwrap().position
    };
    let likelihood = run(PointMassConfig {
        wifi_likelihood: true,
        likelihood_share: 1.0,
        ..PointMassConfig::default()
    });
    assert!((likelihood - truth).norm() < 3.0, "{likelihood:?}");
    let off = PointMassConfig {
        wifi_likelihood: false,
        ..PointMassConfig::default()
    };
    let gaussian = run(off.clone());
    assert!(
        (gaussian - Point2::new(10.0, 17.0)).norm() < 3.0,
        "{gaussian:?}"
    );
    assert!((gaussian - truth).norm() > 20.0, "{gaussian:?}");
}

/// With `likelihood_share` 0 the likelihood a fix carries changes nothing (the same bits as
/// without it).
#[test]
fn a_zero_likelihood_share_gives_the_gaussian_bit_for_bit() {
    let cfg = PointMassConfig {
        wifi_likelihood: true,
        likelihood_share: 0.0,
        ..PointMassConfig::default()
    };
    let mut with = PointMassFilter::new(cfg.clone(), None, None, None).unwrap();
    let mut without = PointMassFilter::new(cfg, None, None, None).unwrap();
    let mut carrying = fix(0, 10.0, 10.0);
    carrying.likelihood = Some(bumps(&[(30.0, 10.0)]));
    with.on_wifi(&carrying);
    without.on_wifi(&fix(0, 10.0, 10.0));
    for k in 1..=6 {
        with.on_step(&step(500 * k, 0.5));
        without.on_step(&step(500 * k, 0.5));
    }
    assert_eq!(with.prob, without.prob);
    assert_eq!(with.estimate(), without.estimate());
}
