//! `wipdr score` through the binary: the organisers' published estimates files give their
//! printed table (when `ipin2023/scoring` is under `$WIPDR_DATA`, else `../shared/data`),
//! `--json`, and a malformed estimates line fails with the file, line and field named.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

fn scoring_dir() -> Option<PathBuf> {
    match wipdr_io::real_data("ipin2023/scoring") {
        Ok(dir) => Some(dir),
        Err(missing) => {
            println!("skipped: {missing}");
            None
        }
    }
}

#[test]
fn the_published_estimates_print_the_official_table() {
    let Some(dir) = scoring_dir() else {
        return;
    };
    let official = std::fs::read_to_string(dir.join("official_results.txt")).unwrap();
    let mut lines = official.lines();
    let header = lines.next().unwrap();
    for (trial, row) in ["01", "02"].into_iter().zip(lines) {
        let id = row.trim_start().split(':').next().unwrap();
        let truth = dir.join(format!("GT_IPIN2023_T3_ScoringTrial{trial}.csv"));
        let est = dir.join(format!("{id}.est"));
        let out = common::wipdr(
            &[
                "score",
                "--truth",
                truth.to_str().unwrap(),
                est.to_str().unwrap(),
            ],
            Path::new("."),
        );
        assert_eq!(out, format!("{header}\n{row}\n"));
    }
    let json = common::wipdr(
        &[
            "score",
            "--truth",
            dir.join("GT_IPIN2023_T3_ScoringTrial01.csv")
                .to_str()
                .unwrap(),
            dir.join("S323ZENODOTS01.est").to_str().unwrap(),
            "--json",
        ],
        Path::new("."),
    );
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    let score = &v["results"][0]["score"];
    assert_eq!(v["results"][0]["id"], "S323ZENODOTS01");
    assert!(
        (score["evaal"].as_f64().unwrap() - 5.75).abs() <= 0.005,
        "{score}"
    );
    assert_eq!(score["points"], 69);
    assert_eq!(v["columns"][0], "EvAAL");
}

#[test]
fn a_malformed_estimates_line_is_an_error_naming_file_line_and_field() {
    let tmp = tempfile::tempdir().unwrap();
    let truth = tmp.path().join("gt.csv");
    std::fs::write(&truth, "0010.0,11.1110,49.4610,00,001\n").unwrap();
    let est = tmp.path().join("bad.est");
    std::fs::write(
        &est,
        "0.0,0,0,45,11.111,49.461,0\n0.5,1,0.5,45,11.111,49.461,0\n1.0,2,0.5,45,11.111,north,0\n",
    )
    .unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_wipdr"))
        .args(["score", "--truth"])
        .arg(&truth)
        .arg(&est)
        .output()
        .unwrap();
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("bad.est: line 3: field latitude: \"north\" is not a finite number"),
        "{stderr}"
    );
}
