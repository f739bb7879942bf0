//! Tests of the KNN matcher.

use super::*;
use crate::QueryFilter;
use crate::distance::{Plgd, SharedAp};
use crate::radio_map::{ApVocabulary, RadioMapConfig, ReferencePoint};
use proptest::prelude::*;
use wipdr_core::{Bssid, Point2, WifiEntry, WifiScan};

/// A random map: `n` points, `m` APs, each heard with probability ~0.4.
fn random_map(seed: u64, n: usize, m: usize) -> RadioMap {
    let mut s = seed
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    let mut next = || {
        s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (s >> 33) as f64 / (1u64 << 31) as f64
    };
    let mut map = RadioMap::new(
        ApVocabulary::from_bssids((0..m as u64).map(Bssid)),
        RadioMapConfig::default(),
    );
    for i in 0..n {
        let row: Vec<Option<f32>> = (0..m)
            .map(|_| (next() < 0.4).then(|| (-100.0 + 70.0 * next()).round() as f32))
            .collect();
        let p = ReferencePoint {
            position: Point2::new(next() * 50.0, next() * 30.0),
            z: None,
            floor: Some((i % 3) as i32),
            building: None,
            scans: 1,
        };
        map.push_point(p, &row, None).unwrap();
    }
    map
}

fn all_configs() -> Vec<KnnConfig> {
    let mut out = Vec::new();
    let metrics = [
        Metric::Manhattan,
        Metric::Euclidean,
        Metric::SquaredEuclidean,
        Metric::Sorensen,
        Metric::Neyman,
        Metric::Plgd(Plgd::default()),
        Metric::SharedAp(SharedAp::default()),
    ];
    for metric in metrics {
        for rep in ["raw", "positive", "exponential", "powed"] {
            out.push(KnnConfig {
                k: 4,
                weighting: Weighting::InverseDistance { power: 1.0 },
                metric,
                representation: Representation::parse(rep).unwrap(),
            });
        }
    }
    out
}

#[test]
fn sparse_engine_equals_dense_definition() {
    let map = Arc::new(random_map(3, 60, 23));
    for cfg in all_configs() {
        let m = KnnMatcher::new(map.clone(), cfg).unwrap();
        let t = m.transform;
        for i in [0, 7, 59] {
            let row: Vec<f32> = map
                .filled_row(i)
                .iter()
                .map(|&v| if v == -110.0 { 100.0 } else { v - 3.0 })
                .collect();
            let q = Query::from_row(&row, &map, &QueryFilter::default()).unwrap();
            let got = m.distances(&q).unwrap();
            let qv: Vec<f32> = (0..map.n_aps())
                .map(|j| t.apply(q.heard.iter().find(|h| h.0 as usize == j).map(|h| h.1)))
                .collect();
            for (r, g) in got.iter().enumerate() {
                let refv: Vec<f32> = (0..map.n_aps()).map(|j| t.apply(map.rss(r, j))).collect();
                let want = cfg.metric.eval(&qv, &refv, t.null_value());
                assert!(
                    (g - want).abs() <= 1e-3 * want.abs().max(1.0),
                    "{} point {r}: {g} vs {want}",
                    cfg.describe()
                );
            }
        }
    }
}

#[test]
fn exact_match_is_found_with_zero_distance() {
    let map = random_map(5, 40, 12);
    let m = KnnMatcher::new(map, KnnConfig::wknn(3, 1.0)).unwrap();
    let row: Vec<f32> = m
        .map()
        .filled_row(17)
        .iter()
        .map(|&v| if v == -110.0 { 100.0 } else { v })
        .collect();
    let q = Query::from_row(&row, m.map(), &QueryFilter::default()).unwrap();
    let obs = m.locate(&q).unwrap();
    assert_eq!(obs.candidates[0].index, 17);
    assert_eq!(obs.candidates[0].distance, 0.0);
    assert_eq!(obs.estimate, m.map().point(17).position);
    assert_eq!(obs.visited, 40);
}

#[test]
fn gemm_batch_equals_single_queries() {
    let map = random_map(9, 300, 31);
    let m = KnnMatcher::new(map, KnnConfig::wknn(5, 1.0)).unwrap();
    let queries: Vec<Query> = (0..20)
        .map(|i| {
            let row: Vec<f32> = m
                .map()
                .filled_row(i * 7)
                .iter()
                .map(|&v| if v == -110.0 { 100.0 } else { v + 2.0 })
                .collect();
            Query::from_row(&row, m.map(), &QueryFilter::default()).unwrap()
        })
        .collect();
    let a = m.locate_batch_gemm(&queries);
    let b = m.locate_batch(&queries);
    for (x, y) in a.iter().zip(&b) {
        let (x, y) = (x.as_ref().unwrap(), y.as_ref().unwrap());
        assert!((x.estimate - y.estimate).norm() < 1e-3);
        let ix: Vec<usize> = x.candidates.iter().map(|c| c.index).collect();
        let iy: Vec<usize> = y.candidates.iter().map(|c| c.index).collect();
        assert_eq!(ix, iy);
    }
}

#[test]
fn locate_among_equals_brute_force_on_the_candidates() {
    let map = Arc::new(random_map(11, 80, 17));
    let all: Vec<u32> = (0..80).collect();
    let odd: Vec<u32> = (0..80).filter(|i| i % 2 == 1).collect();
    for cfg in all_configs() {
        let m = KnnMatcher::new(map.clone(), cfg).unwrap();
        for r in [0, 13, 42] {
            let row: Vec<f32> = map
                .filled_row(r)
                .iter()
                .map(|&v| if v == -110.0 { 100.0 } else { v + 1.5 })
                .collect();
            let q = Query::from_row(&row, &map, &QueryFilter::default()).unwrap();
            let full = m.locate(&q).unwrap();
            let among = m.locate_among(&q, &all, 80).unwrap();
            assert_eq!(full, among, "{}", cfg.describe());
            // Over the odd points: the brute-force distances restricted to them.
            let got = m.locate_among(&q, &odd, odd.len()).unwrap();
            let d = m.distances(&q).unwrap();
            let mut want: Vec<(f32, usize)> =
                odd.iter().map(|&i| (d[i as usize], i as usize)).collect();
            want.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            let wi: Vec<usize> = want.iter().take(cfg.k).map(|w| w.1).collect();
            let gi: Vec<usize> = got.candidates.iter().map(|c| c.index).collect();
            assert_eq!(gi, wi, "{}", cfg.describe());
            assert_eq!(got.visited, odd.len());
        }
    }
    let m = KnnMatcher::new(map.clone(), KnnConfig::default()).unwrap();
    let q = Query::from_row(&[-60.0; 17], &map, &QueryFilter::default()).unwrap();
    assert!(matches!(
        m.locate_among(&q, &[], 0),
        Err(FingerprintError::EmptyMap)
    ));
    assert!(matches!(
        m.locate_among(&q, &[80], 1),
        Err(FingerprintError::InvalidInput(_))
    ));
}

#[test]
fn floor_first_searches_the_majority_floor_only() {
    let map = Arc::new(random_map(21, 90, 15));
    let m = KnnMatcher::new(map.clone(), KnnConfig::wknn(4, 1.0)).unwrap();
    let ff = FloorFirstMatcher::new(
        KnnMatcher::new(map.clone(), KnnConfig::wknn(4, 1.0)).unwrap(),
        7,
    )
    .unwrap();
    for r in [3, 30, 77] {
        let row: Vec<f32> = map
            .filled_row(r)
            .iter()
            .map(|&v| if v == -110.0 { 100.0 } else { v - 2.0 })
            .collect();
        let q = Query::from_row(&row, &map, &QueryFilter::default()).unwrap();
        let d = m.distances(&q).unwrap();
        let mut order: Vec<usize> = (0..90).collect();
        order.sort_by(|&a, &b| d[a].total_cmp(&d[b]).then(a.cmp(&b)));
        let floor = majority(order.iter().take(7).map(|&i| map.point(i).floor));
        let want: Vec<usize> = order
            .into_iter()
            .filter(|&i| map.point(i).floor == floor)
            .take(4)
            .collect();
        let obs = ff.locate(&q).unwrap();
        let got: Vec<usize> = obs.candidates.iter().map(|c| c.index).collect();
        assert_eq!(got, want);
        assert_eq!(obs.floor, floor);
    }
    assert!(FloorFirstMatcher::new(m, 0).is_err());
}

#[test]
fn top_k_small_equals_select() {
    let d: Vec<f32> = (0..500).map(|i| ((i * 37) % 101) as f32).collect();
    for k in [1, 5, 64, 200] {
        let mut want: Vec<(usize, f64)> = d
            .iter()
            .enumerate()
            .map(|(i, &x)| (i, f64::from(x)))
            .collect();
        want.sort_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)));
        want.truncate(k);
        assert_eq!(top_k(&d, k), want);
    }
}

#[test]
fn bad_config_rejected() {
    let map = random_map(1, 5, 3);
    assert!(KnnMatcher::new(map.clone(), KnnConfig::knn(0)).is_err());
    assert!(KnnMatcher::new(map.clone(), KnnConfig::wknn(3, f64::NAN)).is_err());
    let bad_offset = KnnConfig {
        metric: Metric::SharedAp(crate::distance::SharedAp {
            max_offset_db: -1.0,
            ..Default::default()
        }),
        ..KnnConfig::default()
    };
    assert!(matches!(
        KnnMatcher::new(map.clone(), bad_offset),
        Err(FingerprintError::InvalidConfig(m)) if m.reason.contains("max_offset_db")
    ));
    let bad_detection = KnnConfig {
        metric: Metric::SharedAp(crate::distance::SharedAp {
            detection_mid_db: f32::NAN,
            ..Default::default()
        }),
        ..KnnConfig::default()
    };
    assert!(matches!(
        KnnMatcher::new(map.clone(), bad_detection),
        Err(FingerprintError::InvalidConfig(m)) if m.reason.contains("detection_mid_db")
    ));
    let empty = RadioMap::new(map.vocabulary().clone(), RadioMapConfig::default());
    assert!(matches!(
        KnnMatcher::new(empty, KnnConfig::nn()),
        Err(FingerprintError::EmptyMap)
    ));
    // k larger than the map: all points, no panic.
    let m = KnnMatcher::new(map, KnnConfig::knn(50)).unwrap();
    let q = Query::from_row(&[-60.0, 100.0, 100.0], m.map(), &QueryFilter::default()).unwrap();
    assert_eq!(m.locate(&q).unwrap().candidates.len(), 5);
}

fn scan_of(pairs: &[(u64, f64)]) -> WifiScan {
    WifiScan {
        t: 5,
        entries: pairs
            .iter()
            .map(|&(b, r)| WifiEntry {
                bssid: Bssid(b),
                ssid: String::new(),
                rssi_dbm: r,
                frequency_mhz: 2412,
                last_seen_ms: 5,
            })
            .collect(),
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    #[test]
    fn wknn_invariants(
        seed in 0u64..1000,
        cfg_index in 0usize..28,
        k in 1usize..8,
        scan in prop::collection::vec((0u64..20, -100.0f64..-30.0), 1..15),
        rotate in 0usize..15,
    ) {
        let map = random_map(seed, 40, 20);
        let mut cfg = all_configs()[cfg_index];
        cfg.k = k;
        let m = KnnMatcher::new(map, cfg).unwrap();
        let s = scan_of(&scan);
        let obs = m.locate_scan(&s, &QueryFilter::default()).unwrap();
        // Candidates ordered by distance, weights sum to 1.
        for w in obs.candidates.windows(2) {
            prop_assert!(w[0].distance <= w[1].distance);
        }
        let wsum: f64 = obs.candidates.iter().map(|c| c.weight).sum();
        prop_assert!((wsum - 1.0).abs() < 1e-9);
        // Estimate in the convex hull: a convex combination, so inside the bounding box
        // and every half-plane test; check the box and the weights' non-negativity.
        prop_assert!(obs.candidates.iter().all(|c| c.weight >= 0.0));
        let (minx, maxx) = obs.candidates.iter().fold((f64::MAX, f64::MIN), |a, c| (a.0.min(c.position.x), a.1.max(c.position.x)));
        let (miny, maxy) = obs.candidates.iter().fold((f64::MAX, f64::MIN), |a, c| (a.0.min(c.position.y), a.1.max(c.position.y)));
        prop_assert!(obs.estimate.x >= minx - 1e-9 && obs.estimate.x <= maxx + 1e-9);
        prop_assert!(obs.estimate.y >= miny - 1e-9 && obs.estimate.y <= maxy + 1e-9);
        prop_assert!(in_hull(&obs));
        // Independent of the AP order in the scan.
        let mut s2 = s.clone();
        let r = rotate % s2.entries.len();
        s2.entries.rotate_left(r);
        s2.entries.reverse();
        let obs2 = m.locate_scan(&s2, &QueryFilter::default()).unwrap();
        prop_assert_eq!(obs, obs2);
    }
}

/// Whether the estimate is inside the convex hull of the candidates (monotone chain hull,
/// point-in-convex-polygon with a small tolerance; degenerate hulls checked on segments).
fn in_hull(obs: &WifiObservation) -> bool {
    let mut pts: Vec<Point2> = obs.candidates.iter().map(|c| c.position).collect();
    pts.sort_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
    pts.dedup();
    let p = obs.estimate;
    let tol = 1e-7;
    if pts.len() == 1 {
        return (pts[0] - p).norm() < tol;
    }
    let cross = |o: Point2, a: Point2, b: Point2| (a - o).perp(&(b - o));
    let mut hull: Vec<Point2> = Vec::new();
    for pass in 0..2 {
        let start = hull.len();
        let iter: Box<dyn Iterator<Item = &Point2>> = if pass == 0 {
            Box::new(pts.iter())
        } else {
            Box::new(pts.iter().rev())
        };
        for &q in iter {
            while hull.len() >= start + 2
                && cross(hull[hull.len() - 2], hull[hull.len() - 1], q) <= 0.0
            {
                hull.pop();
            }
            hull.push(q);
        }
        hull.pop();
    }
    if hull.len() < 3 {
        // Collinear: within the segment between the extremes.
        let (a, b) = (pts[0], pts[pts.len() - 1]);
        let ab = b - a;
        let t = (p - a).dot(&ab) / ab.norm_squared();
        let closest = a + ab * t.clamp(0.0, 1.0);
        return (closest - p).norm() < tol * (1.0 + ab.norm());
    }
    (0..hull.len()).all(|i| {
        let (a, b) = (hull[i], hull[(i + 1) % hull.len()]);
        cross(a, b, p) >= -tol * (1.0 + (b - a).norm())
    })
}
