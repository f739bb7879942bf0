//! `wipdr eval --odometry-holdout DIR`: each floor runs the learned odometry network of
//! `DIR/<site>_<floor>.safetensors` instead of the shipped one (the leave-one-floor-out
//! protocol of `docs/results/odometry.md`). On the fixture floor: the shipped weights under
//! the floor's file name give exactly the run without the flag; a network with one bias
//! changed gives other figures (the file is read, not the shipped bytes); the run is refused
//! without `odometry = "learned"`, without the floor's file, and with `--shard`.

use std::path::{Path, PathBuf};

mod common;
use common::{wipdr, wipdr_fails as fails};

fn fixture() -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../fixtures/sim/F1"))
}

/// The shipped weights' bytes.
fn shipped() -> Vec<u8> {
    std::fs::read(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../crates/pdr/src/odometry/learned.safetensors"
    ))
    .expect("the shipped weights are in the repository")
}

/// `weights` with `delta` added to the first output's bias (the forward displacement of
/// every window, metres).
fn with_forward_bias(weights: &[u8], delta: f32) -> Vec<u8> {
    let n = u64::from_le_bytes(weights[..8].try_into().expect("8 bytes"));
    let n = usize::try_from(n).expect("header length fits");
    let header: serde_json::Value =
        serde_json::from_slice(&weights[8..8 + n]).expect("header is JSON");
    let start = header["fc1.bias"]["data_offsets"][0]
        .as_u64()
        .expect("fc1.bias has offsets");
    let at = 8 + n + usize::try_from(start).expect("offset fits");
    let mut out = weights.to_vec();
    let old = f32::from_le_bytes(out[at..at + 4].try_into().expect("4 bytes"));
    out[at..at + 4].copy_from_slice(&(old + delta).to_le_bytes());
    out
}

/// The JSON document of a run, without `motion.weights`.
fn document(path: &Path) -> (serde_json::Value, Option<serde_json::Value>) {
    let mut v: serde_json::Value =
        serde_json::from_slice(&std::fs::read(path).expect("JSON written")).expect("JSON");
    let weights = v["motion"]
        .as_object_mut()
        .expect("motion section")
        .remove("weights");
    (v, weights)
}

#[test]
fn each_floor_runs_the_network_held_out_on_it() {
    let dir = tempfile::tempdir().expect("temp dir");
    let cwd = dir.path();
    std::fs::write(cwd.join("learned.toml"), "odometry = \"learned\"\n").expect("config");
    std::fs::write(cwd.join("steps.toml"), "odometry = \"steps\"\n").expect("config");
    let same = cwd.join("same");
    let other = cwd.join("other");
    let empty = cwd.join("empty");
    for d in [&same, &other, &empty] {
        std::fs::create_dir(d).expect("dir");
    }
    // The fixture floor's label is `sim/F1`.
    std::fs::write(same.join("sim_F1.safetensors"), shipped()).expect("weights");
    std::fs::write(
        other.join("sim_F1.safetensors"),
        with_forward_bias(&shipped(), 0.5),
    )
    .expect("weights");
    let data = fixture().display().to_string();
    let cache = cwd.join("cache").display().to_string();
    // `wipdr --cache-dir C eval --data FIXTURE --schemes pdr,ekf ARGS...`
    let command = |args: &[&str]| -> Vec<String> {
        [
            "--cache-dir",
            &cache,
            "eval",
            "--data",
            &data,
            "--schemes",
            "pdr,ekf",
        ]
        .iter()
        .chain(args)
        .map(|s| (*s).to_string())
        .collect()
    };
    let eval = |extra: &[&str]| {
        let mut args = vec!["--config", "learned.toml"];
        args.extend(extra);
        let argv = command(&args);
        wipdr(&argv.iter().map(String::as_str).collect::<Vec<_>>(), cwd)
    };

    eval(&["--json", "shipped.json"]);
    let out = eval(&[
        "--json",
        "same.json",
        "--odometry-holdout",
        same.to_str().expect("utf-8"),
    ]);
    assert!(out.contains("learned"), "{out}");
    let (plain, none) = document(&cwd.join("shipped.json"));
    let (held, weights) = document(&cwd.join("same.json"));
    assert_eq!(none, None, "no weights field without the flag");
    assert_eq!(
        plain, held,
        "the shipped bytes under the floor's name give the same run"
    );
    let weights = weights.expect("motion.weights with the flag");
    assert!(
        weights["sim/F1"]
            .as_str()
            .is_some_and(|p| p.ends_with("sim_F1.safetensors")),
        "{weights}"
    );

    eval(&[
        "--json",
        "other.json",
        "--odometry-holdout",
        other.to_str().expect("utf-8"),
    ]);
    let (changed, _) = document(&cwd.join("other.json"));
    let mean = |v: &serde_json::Value| v["motion"]["summaries"]["pooled"]["mean_m"].as_f64();
    assert!(mean(&plain).is_some(), "{}", plain["motion"]);
    assert_ne!(
        mean(&plain),
        mean(&changed),
        "a network with another bias moves the segment error"
    );

    let run_fails = |args: Vec<String>| {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        fails(&args, cwd)
    };
    let same_dir = same.to_str().expect("utf-8");
    let err = run_fails(command(&[
        "--config",
        "steps.toml",
        "--odometry-holdout",
        same_dir,
    ]));
    assert!(err.contains("odometry = \"learned\""), "{err}");
    let err = run_fails(command(&["--odometry-holdout", same_dir]));
    assert!(
        err.contains("odometry = \"learned\""),
        "default config: {err}"
    );
    let err = run_fails(command(&[
        "--config",
        "learned.toml",
        "--odometry-holdout",
        empty.to_str().expect("utf-8"),
    ]));
    assert!(
        err.contains("\"sim/F1\"") && err.contains("sim_F1.safetensors"),
        "{err}"
    );
    let err = run_fails(command(&[
        "--config",
        "learned.toml",
        "--odometry-holdout",
        same_dir,
        "--shard",
        "0/2",
        "--json",
        "p.json",
    ]));
    assert!(err.contains("--shard"), "{err}");
}
