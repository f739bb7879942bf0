//! A radio map from real ILC 2.0 walks (site1/F1): built from most walks, queried with the
//! scans of held-out walks, scored at the interpolated waypoint position. Runs only when
//! `ilc20/site1/F1` is under the data root (`$WIPDR_DATA`, else `../shared/data`); uses a
//! subset of walks to stay fast.

use wipdr_core::Walk;
use wipdr_core::walk::interpolate_waypoints;
use wipdr_fingerprint::walk_map::{WalkMapConfig, build_from_walks};
use wipdr_fingerprint::{KnnConfig, KnnMatcher, Matcher, Metric, QueryFilter};
use wipdr_io::floor::walk_files;
use wipdr_io::trace::read_walk;

/// Mean error of WKNN over the held-out walks' scans, and the mean error of always answering
/// the centroid of the map (the trivial baseline).
fn score(
    train: &[Walk],
    test: &[Walk],
    config: &WalkMapConfig,
    metric: Metric,
) -> (f64, f64, usize) {
    let (map, report) = build_from_walks(train, config).unwrap();
    assert_eq!(report.reference_points, map.len());
    assert!(report.scans_used <= report.scans);
    let n = map.len() as f64;
    let centroid = map
        .points()
        .iter()
        .fold(wipdr_core::Point2::origin(), |c, p| {
            c + p.position.coords / n
        });
    let m = KnnMatcher::new(
        map,
        KnnConfig {
            metric,
            ..KnnConfig::wknn(5, 1.0)
        },
    )
    .unwrap();
    let filter = QueryFilter {
        max_age_ms: config.max_entry_age_ms,
        ..Default::default()
    };
    let (mut err, mut base, mut count) = (0.0, 0.0, 0usize);
    for w in test {
        for scan in &w.wifi {
            let Some(truth) = interpolate_waypoints(&w.waypoints, scan.t) else {
                continue;
            };
            let Ok(obs) = m.locate_scan(scan, &filter) else {
                continue;
            };
            err += (obs.estimate - truth).norm();
            base += (centroid - truth).norm();
            count += 1;
        }
    }
    (err / count.max(1) as f64, base / count.max(1) as f64, count)
}

#[test]
fn walk_map_beats_centroid_on_held_out_walks() {
    let dir = match wipdr_io::real_data("ilc20/site1/F1") {
        Ok(dir) => dir,
        Err(missing) => {
            eprintln!("skipped: {missing}");
            return;
        }
    };
    let files = walk_files(&dir).unwrap();
    let walks: Vec<Walk> = files.iter().map(|f| read_walk(f).unwrap().walk).collect();
    // Every fifth walk held out.
    let (mut test, mut train) = (Vec::new(), Vec::new());
    for (i, w) in walks.into_iter().enumerate() {
        if i % 5 == 0 {
            test.push(w)
        } else {
            train.push(w)
        }
    }
    let (test, train) = (&test[..], &train[..]);
    for max_age in [Some(2_000), Some(5_000), Some(10_000), None] {
        let cfg = WalkMapConfig {
            max_entry_age_ms: max_age,
            ..Default::default()
        };
        for metric in [Metric::Euclidean, Metric::parse("shared_ap").unwrap()] {
            let (e, b, n) = score(train, test, &cfg, metric);
            eprintln!(
                "site1/F1, every 5th walk held out, max age {max_age:?} ms, {}: WKNN mean {e:.2} m, centroid {b:.2} m, {n} scans",
                metric.name()
            );
            assert!(n > 200, "too few scored scans: {n}");
            assert!(
                e.is_finite() && e < 0.5 * b,
                "WKNN {e:.2} m not clearly better than centroid {b:.2} m"
            );
        }
    }
}
