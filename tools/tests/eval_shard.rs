//! `wipdr eval --shard I/4` four times, then `wipdr eval merge`, writes byte for byte the JSON
//! of the unsharded `wipdr eval --json`: on the fixture floor, and on a real ILC floor when
//! it is under the data root (`$WIPDR_DATA`, else `../shared/data`). Merges of an incomplete
//! set, a repeated shard or shards of another run are refused.

use std::path::{Path, PathBuf};

mod common;
use common::{wipdr, wipdr_fails as fails};

fn fixture() -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../fixtures/sim/F1"))
}

/// The schemes run: a Wi-Fi-only, the PDR baseline, a Kalman filter and a particle filter
/// (seeded: the same draws in every process).
const SCHEMES: &str = "wifi,pdr,ekf,pf";

/// Runs the four shards and the merge of `data`, returns (unsharded JSON, merged JSON).
fn plain_and_merged(data: &[&Path], cwd: &Path, cache: &Path) -> (Vec<u8>, Vec<u8>) {
    let cache = cache.to_str().expect("utf-8 path");
    let mut base: Vec<String> = vec!["--cache-dir".into(), cache.into(), "eval".into()];
    base.push("--data".into());
    base.extend(data.iter().map(|d| d.display().to_string()));
    base.extend(["--schemes".into(), SCHEMES.into()]);
    let run = |extra: &[&str]| {
        let mut args: Vec<&str> = base.iter().map(String::as_str).collect();
        args.extend(extra);
        wipdr(&args, cwd)
    };
    run(&["--json", "plain.json"]);
    let mut parts = Vec::new();
    for i in 0..4 {
        let part = format!("part{i}.json");
        let out = run(&["--shard", &format!("{i}/4"), "--json", &part]);
        assert!(out.contains(&format!("shard {i}/4: ")), "{out}");
        parts.push(part);
    }
    // Parts in any order.
    parts.reverse();
    let mut args = vec!["eval", "merge"];
    args.extend(parts.iter().map(String::as_str));
    args.extend(["--json", "merged.json"]);
    let out = wipdr(&args, cwd);
    assert!(out.contains("merged 4 shard files"), "{out}");
    let read = |name: &str| std::fs::read(cwd.join(name)).expect("JSON written");
    (read("plain.json"), read("merged.json"))
}

#[test]
fn four_shards_merged_equal_the_unsharded_json_on_the_fixture() {
    let dir = tempfile::tempdir().expect("temp dir");
    let cwd = dir.path();
    let cache = cwd.join("cache");
    let (plain, merged) = plain_and_merged(&[&fixture()], cwd, &cache);
    let value: serde_json::Value = serde_json::from_slice(&plain).expect("JSON");
    // 10 walks x 4 schemes, and every figure there.
    assert_eq!(value["walks"].as_array().map(Vec::len), Some(40));
    assert!(value["pooled"]["pf"]["count"].as_u64().unwrap_or(0) > 0);
    assert!(
        plain == merged,
        "merged JSON differs from the unsharded one"
    );

    // Refused: a missing shard, a shard given twice, a shard of another config.
    let e = fails(
        &[
            "eval",
            "merge",
            "part0.json",
            "part1.json",
            "part3.json",
            "--json",
            "x.json",
        ],
        cwd,
    );
    assert!(
        e.contains("incomplete: 3 of 4 shards given, missing shard(s) 2/4"),
        "{e}"
    );
    let e = fails(
        &[
            "eval",
            "merge",
            "part0.json",
            "part1.json",
            "part1.json",
            "part2.json",
            "part3.json",
            "--json",
            "x.json",
        ],
        cwd,
    );
    assert!(e.contains("are both shard 1/4"), "{e}");
    std::fs::write(cwd.join("seed.toml"), "seed = 9\n").expect("config written");
    let fixture = fixture();
    let cache = cache.display().to_string();
    wipdr(
        &[
            "--cache-dir",
            &cache,
            "eval",
            "--data",
            &fixture.display().to_string(),
            "--schemes",
            SCHEMES,
            "--config",
            "seed.toml",
            "--shard",
            "2/4",
            "--json",
            "other2.json",
        ],
        cwd,
    );
    let e = fails(
        &[
            "eval",
            "merge",
            "part0.json",
            "part1.json",
            "other2.json",
            "part3.json",
            "--json",
            "x.json",
        ],
        cwd,
    );
    assert!(
        e.contains("config differs") && e.contains("seed: 9 vs 1"),
        "{e}"
    );
    // A shard needs its file; a bad shard spec is named.
    let e = fails(
        &[
            "eval",
            "--data",
            &fixture.display().to_string(),
            "--shard",
            "4/4",
            "--json",
            "p.json",
        ],
        cwd,
    );
    assert!(e.contains("need 0 <= I < N"), "{e}");
    assert!(!cwd.join("x.json").exists());
}

#[test]
fn four_shards_merged_equal_the_unsharded_json_on_a_real_floor() {
    let floor = match wipdr_io::real_data("ilc20/site2/F3") {
        Ok(floor) => floor,
        Err(missing) => {
            println!("skipped: {missing}");
            return;
        }
    };
    let dir = tempfile::tempdir().expect("temp dir");
    // The repository's parse cache, shared with the other real-data tests.
    let cache = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../"))
        .join(wipdr_io::cache::DEFAULT_CACHE_DIR);
    let (plain, merged) = plain_and_merged(&[&floor], dir.path(), &cache);
    let value: serde_json::Value = serde_json::from_slice(&plain).expect("JSON");
    assert!(value["walks"].as_array().map_or(0, Vec::len) > 100);
    assert!(
        plain == merged,
        "merged JSON differs from the unsharded one"
    );
}
