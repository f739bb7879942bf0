//! Radio-map interpolation (paper 004 §5.3) on the committed synthetic floor
//! (`fixtures/sim/F1`): walks 0-7 build the map, walks 8-9 query it. Checks the radius
//! property on a realistic map and that WKNN on the densified map stays sane.

use std::path::PathBuf;
use wipdr_core::Walk;
use wipdr_core::walk::interpolate_waypoints;
use wipdr_fingerprint::interpolate::{AlongWalkConfig, InterpolationConfig, SpatialConfig};
use wipdr_fingerprint::walk_map::{WalkMapConfig, build_from_walks};
use wipdr_fingerprint::{KnnConfig, KnnMatcher, Matcher, QueryFilter, RadioMap};
use wipdr_io::floor::walk_files;
use wipdr_io::trace::read_walk;

fn fixture_walks() -> Vec<Walk> {
    let dir = PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../fixtures/sim/F1"
    ));
    walk_files(&dir)
        .expect("fixtures/sim/F1 exists")
        .iter()
        .map(|f| read_walk(f).expect("fixture walk reads").walk)
        .collect()
}

fn mean_error(map: RadioMap, test: &[Walk]) -> (f64, usize) {
    let m = KnnMatcher::new(map, KnnConfig::wknn(5, 1.0)).unwrap();
    let filter = QueryFilter::default();
    let (mut sum, mut n) = (0.0, 0usize);
    for w in test {
        for scan in &w.wifi {
            let (Some(truth), Ok(obs)) = (
                interpolate_waypoints(&w.waypoints, scan.t),
                m.locate_scan(scan, &filter),
            ) else {
                continue;
            };
            sum += (obs.estimate - truth).norm();
            n += 1;
        }
    }
    (sum / n.max(1) as f64, n)
}

#[test]
fn interpolated_fixture_map_keeps_its_promises() {
    let walks = fixture_walks();
    let (train, test) = walks.split_at(8);
    let plain_cfg = WalkMapConfig::default();
    let (plain, plain_rep) = build_from_walks(train, &plain_cfg).unwrap();
    let along = AlongWalkConfig::default();
    let spatial = SpatialConfig {
        cell_m: 2.0,
        radius_m: 3.0,
        ..Default::default()
    };
    let cfg = WalkMapConfig {
        interpolation: Some(InterpolationConfig {
            along_walk: Some(along),
            spatial: Some(spatial),
        }),
        ..Default::default()
    };
    let (dense, rep) = build_from_walks(train, &cfg).unwrap();
    let measured: Vec<_> = dense.points().iter().filter(|p| p.scans > 0).collect();
    assert_eq!(measured.len(), plain.len());
    let made = dense.len() - plain.len();
    assert_eq!(
        made,
        rep.interpolation.along_walk_points + rep.interpolation.spatial_points
    );
    assert!(rep.interpolation.along_walk_points > 0 && rep.interpolation.spatial_points > 0);
    assert_eq!(rep.scans_used, plain_rep.scans_used);
    // Every created point lies within the larger of the two radii of a measured point, and
    // every heard value is a valid RSSI with count 1.
    let bound = spatial.radius_m.max(along.max_gap_m / 2.0) + 1e-9;
    for (i, p) in dense
        .points()
        .iter()
        .enumerate()
        .filter(|(_, p)| p.scans == 0)
    {
        let nearest = measured
            .iter()
            .map(|q| (q.position - p.position).norm())
            .fold(f64::INFINITY, f64::min);
        assert!(
            nearest <= bound,
            "point {i} is {nearest:.2} m from any scan"
        );
        assert!(dense.heard(i).count() > 0);
        for (j, v) in dense.heard(i) {
            assert!((-120.0..=0.0).contains(&v));
            assert_eq!(dense.count(i, j), 1);
            assert!(dense.spread(i, j).is_finite() && dense.spread(i, j) >= 0.0);
        }
    }
    let n_measured = measured.len();
    let (e_plain, n_plain) = mean_error(plain, test);
    let (e_dense, n_dense) = mean_error(dense, test);
    eprintln!(
        "fixture F1, walks 8-9: WKNN {e_plain:.2} m on {} points, {e_dense:.2} m on {} points \
         ({n_plain} / {n_dense} scans)",
        n_measured,
        n_measured + made
    );
    assert!(n_plain > 50 && n_dense == n_plain);
    assert!(e_dense.is_finite() && e_plain.is_finite());
    // Sanity, not a claim of improvement: interpolation must not wreck the matcher.
    assert!(
        e_dense < 1.25 * e_plain,
        "densified map {e_dense:.2} m vs plain {e_plain:.2} m"
    );
}
