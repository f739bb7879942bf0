//! The floor tracker on a real barometer (when `ipin2023/` is under `$WIPDR_DATA`, else
//! `../shared/data`): the IPIN walk that changes floors (0 -> -2 -> 0 -> -2 -> 0 by the
//! stairs) with weather drift of 1 hPa an hour and door steps of 0.15 hPa (on a floor)
//! injected into its pressure keeps every floor the clean stream finds, and spends no more
//! than 10 s on a wrong floor. The fixes vote for the true floor, every third one for the
//! other mapped floor (the IPIN reference WKNN's floor hit rate per fix is 66 %); floor -1
//! is in the building but has no fingerprint.

mod common;

use wipdr_core::TimestampMs;
use wipdr_core::walk::floor_of_waypoints;
use wipdr_io::Limits;
use wipdr_io::logfile::read_logfile;
use wipdr_positioning::{FloorConfig, FloorTracker, PressureSample};

const WALK: &str = "IPIN2023_T3_TrainingTrial52_repetition01.txt.gz";

/// Per POSI span `[t_i, t_{i+1})`, the longest stretch (ms) the tracker spent off that span's
/// floor; and the floor at each waypoint time.
fn run(walk: &wipdr_core::Walk, inject: impl Fn(TimestampMs) -> f64) -> (i64, Vec<Option<i32>>) {
    let mut f =
        FloorTracker::new(vec![-2, 0], FloorConfig::default()).with_building(&[-2, -1, 0], &[]);
    let start = walk.waypoints[0].t;
    let mut events: Vec<(TimestampMs, Option<f64>)> = walk
        .pressure
        .iter()
        .map(|p| (p.t, Some(p.hpa + inject(p.t))))
        .chain(walk.wifi.iter().map(|s| (s.t, None)))
        .collect();
    events.sort_by_key(|e| e.0);
    let mut fixes = 0usize;
    let mut worst = 0i64;
    let mut wrong_since: Option<TimestampMs> = None;
    let mut at_waypoints = Vec::new();
    let mut next_wp = 0usize;
    for (t, hpa) in events {
        while next_wp < walk.waypoints.len() && walk.waypoints[next_wp].t <= t {
            at_waypoints.push(f.floor());
            next_wp += 1;
        }
        match hpa {
            Some(hpa) => f.push_pressure(&PressureSample { t, hpa }),
            None => {
                let truth = floor_of_waypoints(&walk.waypoints, t).unwrap_or(0);
                fixes += 1;
                let vote = if fixes.is_multiple_of(3) {
                    if truth == 0 { -2 } else { 0 }
                } else {
                    truth
                };
                f.push_fix(t, Some(vote));
            }
        }
        if t < start {
            continue;
        }
        let truth = floor_of_waypoints(&walk.waypoints, t);
        if f.floor() != truth {
            let since = *wrong_since.get_or_insert(t);
            worst = worst.max(t - since);
        } else {
            wrong_since = None;
        }
    }
    (worst, at_waypoints)
}

#[test]
fn drift_and_door_steps_on_a_real_walk_move_no_floor() {
    let Some(dir) = common::shared_data_dir("ipin2023/trials") else {
        return;
    };
    let log = read_logfile(dir.join(WALK), &Limits::default()).unwrap();
    let frame = wipdr_core::GeoFrame::new(49.46, 11.11).unwrap();
    let walk = log.into_walk(&frame).walk;
    let floors: Vec<i32> = walk.waypoints.iter().filter_map(|w| w.floor).collect();
    assert!(
        floors.contains(&0) && floors.contains(&-2),
        "{WALK} changes floors"
    );

    let (clean_worst, clean) = run(&walk, |_| 0.0);
    // 1 hPa an hour both ways, and 0.15 hPa door steps held for 15-30 s while the walk is
    // on a floor (its stairs: 62-88, 118-145, 158-184 and 218-244 s). A step during the
    // stairs can change how many floors the stairs count (docs/results/floors.md).
    for rate in [1.0, -1.0] {
        let (worst, injected) = run(&walk, |t| {
            let step = match t {
                20_000..50_000 | 190_000..210_000 => 0.15,
                95_000..110_000 => -0.15,
                _ => 0.0,
            };
            rate * t as f64 / 3_600_000.0 + step
        });
        println!(
            "{WALK}: longest time on a wrong floor {:.1} s clean, {:.1} s with {rate} hPa/h and 0.15 hPa steps",
            clean_worst as f64 / 1000.0,
            worst as f64 / 1000.0
        );
        assert_eq!(injected, clean, "floors at the POSI points, {rate} hPa/h");
        assert!(
            worst <= 10_000,
            "{:.1} s on a wrong floor",
            worst as f64 / 1000.0
        );
    }
    let truth: Vec<Option<i32>> = walk.waypoints.iter().map(|w| w.floor).collect();
    let hits = clean.iter().zip(&truth).filter(|(a, b)| a == b).count();
    println!(
        "{WALK}: {hits} of {} POSI points on the true floor",
        truth.len()
    );
    assert!(
        clean_worst <= 10_000,
        "{:.1} s on a wrong floor",
        clean_worst as f64 / 1000.0
    );
}
