//! The organisers' scorer reproduced: the two estimate files published for the IPIN 2023
//! Track 3 scoring trials, scored against their ground truth, give `official_results.txt`
//! (`ipin2023/scoring/` under `$WIPDR_DATA`, else `../shared/data`) in every column to its
//! 0.01 m (skipped without the data).

mod common;

use std::path::Path;
use wipdr_eval::evaal_score::{EVAAL_COLUMNS, EvaalScore, evaal_scoring};
use wipdr_io::Limits;
use wipdr_io::evaal::{read_evaal_estimates, read_evaal_truth};

/// `official_results.txt`: `(file id, [EvAAL, MEAN, RMSE, MEDIAN, P95, FHR(%), MPExy, POINTS])`.
fn official(dir: &Path) -> Vec<(String, Vec<f64>)> {
    let text = std::fs::read_to_string(dir.join("official_results.txt")).expect("results read");
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().expect("header").split_whitespace().collect();
    assert_eq!(
        header[1..],
        EVAAL_COLUMNS,
        "the organisers' columns, in order"
    );
    lines
        .map(|l| {
            let (id, rest) = l.split_once(':').expect("`id:` then figures");
            let figures = rest
                .split_whitespace()
                .map(|v| v.parse().expect("a number"))
                .collect();
            (id.trim().to_string(), figures)
        })
        .collect()
}

fn columns(s: &EvaalScore) -> Vec<f64> {
    let points = u32::try_from(s.points).map(f64::from).expect("few points");
    vec![
        s.evaal,
        s.mean,
        s.rmse,
        s.median,
        s.p95,
        s.fhr_percent,
        s.mpe_xy,
        points,
    ]
}

#[test]
fn the_published_estimates_score_as_the_organisers_printed() {
    let Some(dir) = common::shared_data_dir("ipin2023/scoring") else {
        return;
    };
    let expected = official(&dir);
    assert_eq!(expected.len(), 2);
    let limits = Limits::default();
    for (id, want) in expected {
        // S323ZENODOTS01 -> ScoringTrial01, S323ZENODOTZ02 -> ScoringTrial02.
        let trial = &id[id.len() - 2..];
        let truth = read_evaal_truth(
            dir.join(format!("GT_IPIN2023_T3_ScoringTrial{trial}.csv")),
            &limits,
        )
        .expect("ground truth reads");
        let estimates =
            read_evaal_estimates(dir.join(format!("{id}.est")), &limits).expect("estimates read");
        assert_eq!(truth.len(), 69);
        let r = evaal_scoring(&truth, &estimates).expect("scores");
        assert!(!r.coordinates_swapped);
        let got = columns(&r.score);
        println!("{id}: official {want:?}");
        println!(
            "{id}: ours     {:?}",
            got.iter()
                .map(|v| (v * 1e4).round() / 1e4)
                .collect::<Vec<_>>()
        );
        for ((name, w), g) in EVAAL_COLUMNS.iter().zip(&want).zip(&got) {
            // The official figures are rounded to 0.01: ours must round to the same.
            assert!(
                (g - w).abs() <= 0.005 + 1e-9,
                "{id} {name}: official {w}, ours {g}"
            );
        }
    }
}
