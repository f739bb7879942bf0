//! Hostile inputs against the radio map's memory: a vocabulary of very many BSSIDs and
//! user-raised limits end in a typed error naming the limit, before the memory is allocated.

use wipdr_core::{Bssid, Point2, Walk, Waypoint, WifiEntry, WifiScan};
use wipdr_fingerprint::FingerprintError;
use wipdr_fingerprint::interpolate::{InterpolationConfig, SpatialConfig};
use wipdr_fingerprint::walk_map::{
    DEFAULT_MAX_APS, MAX_APS_CEILING, WalkMapConfig, build_from_walks,
};

/// A walk of `scans` scans at 1 s intervals along x, each hearing `per_scan` APs: distinct
/// BSSIDs in every scan when `distinct`, else the same `per_scan` ones.
fn walk(scans: usize, per_scan: usize, distinct: bool) -> Walk {
    let mut w = Walk::default();
    w.meta.id = "hostile".into();
    w.waypoints = vec![
        Waypoint::new(0, Point2::new(0.0, 0.0)),
        Waypoint::new(1000 * (scans as i64 + 1), Point2::new(20.0, 0.0)),
    ];
    for s in 0..scans {
        let t = 1000 * (s as i64 + 1);
        let entries = (0..per_scan)
            .map(|k| WifiEntry {
                bssid: Bssid((if distinct { s * per_scan + k } else { k }) as u64 + 1),
                ssid: String::new(),
                rssi_dbm: -60.0,
                frequency_mhz: 2412,
                last_seen_ms: t,
            })
            .collect();
        w.wifi.push(WifiScan { t, entries });
    }
    w
}

fn limit_of(e: &FingerprintError) -> &str {
    match e {
        FingerprintError::LimitExceeded(e) => &e.limit,
        other => panic!("not a limit error: {other}"),
    }
}

/// Seen on the old main: one walk whose scans carry a million distinct BSSIDs made `eval`
/// allocate a dense table of scans x BSSIDs and abort. Here a vocabulary just over the
/// default limit (on the old main: built, 144 MB of table for 120 scans).
#[test]
fn a_vocabulary_over_max_aps_is_refused_before_the_table_is_allocated() {
    let per_scan = 1000;
    let scans = DEFAULT_MAX_APS / per_scan + 20;
    let w = walk(scans, per_scan, true);
    let e = build_from_walks([&w], &WalkMapConfig::default()).unwrap_err();
    assert_eq!(limit_of(&e), "radio_map.max_aps");
    let msg = e.to_string();
    assert!(
        msg.contains(&format!("{} distinct APs", scans * per_scan))
            && msg.contains("max_aps = N")
            && msg.contains(&MAX_APS_CEILING.to_string()),
        "{msg}"
    );
    // Raised, it builds.
    let raised = WalkMapConfig {
        max_aps: scans * per_scan,
        ..Default::default()
    };
    let (map, _) = build_from_walks([&w], &raised).unwrap();
    assert_eq!(map.n_aps(), scans * per_scan);
    // The ceiling cannot be passed.
    let over = WalkMapConfig {
        max_aps: MAX_APS_CEILING + 1,
        ..Default::default()
    };
    let msg = build_from_walks([&w], &over).unwrap_err().to_string();
    assert!(msg.contains("radio_map.max_aps"), "{msg}");
}

/// Few APs but many scans: the table (points x APs) is bounded too, per scan and per grid
/// cell, before it is allocated.
#[test]
fn a_table_over_max_table_mib_is_refused() {
    // 400 points x 3000 APs x 10 B = 11.4 MiB.
    let w = walk(400, 3000, false);
    let small = WalkMapConfig {
        max_table_mib: 8,
        ..Default::default()
    };
    let e = build_from_walks([&w], &small).unwrap_err();
    assert_eq!(limit_of(&e), "radio_map.max_table_mib");
    assert!(
        e.to_string().contains("400 reference points x 3000 APs"),
        "{e}"
    );
    let gridded = WalkMapConfig {
        grid_cell_m: Some(0.01),
        ..small
    };
    assert_eq!(
        limit_of(&build_from_walks([&w], &gridded).unwrap_err()),
        "radio_map.max_table_mib"
    );
    let (map, _) = build_from_walks(
        [&w],
        &WalkMapConfig {
            max_table_mib: 12,
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!((map.len(), map.n_aps()), (400, 3000));
    let zero = WalkMapConfig {
        max_table_mib: 0,
        ..Default::default()
    };
    assert!(
        build_from_walks([&w], &zero)
            .unwrap_err()
            .to_string()
            .contains("radio_map.max_table_mib")
    );
}

/// Seen on the old main: `[radio_map.interpolation.spatial] cell_m = 0.001, max_points =
/// 1000000000` was accepted and the lattice grew past 13 GB.
#[test]
fn spatial_max_points_has_a_ceiling_and_the_lattice_the_table_budget() {
    let w = walk(10, 50, false);
    let spatial = |cell_m: f64, max_points: usize, max_table_mib: usize| WalkMapConfig {
        interpolation: Some(InterpolationConfig {
            along_walk: None,
            spatial: Some(SpatialConfig {
                cell_m,
                max_points,
                ..Default::default()
            }),
        }),
        max_table_mib,
        ..Default::default()
    };
    let e = build_from_walks([&w], &spatial(0.001, 1_000_000_000, 8192))
        .unwrap_err()
        .to_string();
    assert!(e.contains("spatial.max_points"), "{e}");
    // Within the ceiling, but the lattice's rows would cross the table budget: refused
    // while the lattice grows (a 1 cm lattice 4 m around 10 scans: ~1 M points x 50 APs).
    let e = build_from_walks([&w], &spatial(0.01, 2_000_000, 64)).unwrap_err();
    assert_eq!(limit_of(&e), "radio_map.max_table_mib");
    // A sane lattice builds.
    let (map, rep) = build_from_walks([&w], &spatial(1.0, 200_000, 64)).unwrap();
    assert!(rep.interpolation.spatial_points > 0 && map.len() > 10);
}
