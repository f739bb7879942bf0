//! The `wipdr` program as a subprocess: closed output pipes and the parse cache's location.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use wipdr_core::{FloorPlan, Point2, Walk, Waypoint};
use wipdr_io::{LonLatBox, floor};

fn wipdr() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_wipdr"));
    c.env_remove("WIPDR_CACHE_DIR")
        .env_remove("WIPDR_CACHE_MAX_MB")
        .env_remove("RUST_LOG");
    c
}

/// A small floor folder `root/site/F1` with one walk; returns it and the walk file.
fn make_floor(root: &Path) -> (PathBuf, PathBuf) {
    let dir = root.join("site").join("F1");
    let mut walk = Walk::default();
    walk.meta.id = "w".into();
    for i in 0..3 {
        walk.waypoints
            .push(Waypoint::new(1000 * i, Point2::new(1.0 + i as f64, 5.0)));
    }
    let plan = FloorPlan::rectangle(20.0, 10.0).unwrap();
    floor::write_floor_dir(
        &dir,
        &plan,
        LonLatBox::around(8.0, 47.0, 20.0, 10.0),
        [&walk],
    )
    .unwrap();
    let file = dir.join(floor::WALKS_DIR).join("w.txt.gz");
    (dir, file)
}

#[test]
fn a_closed_stdout_ends_quietly_with_exit_code_0() {
    let tmp = tempfile::tempdir().unwrap();
    let (dir, walk) = make_floor(tmp.path());
    // Far more output than a pipe buffer holds (64 KiB), so writes fail after the reader
    // is gone however fast it closes.
    let mut cmd = wipdr();
    cmd.arg("--no-cache").arg("inspect").arg(&dir);
    for _ in 0..1500 {
        cmd.arg(&walk);
    }
    let mut child = cmd
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take()); // `| head -0`
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert_eq!(out.status.code(), Some(0), "{stderr}");
    assert!(stderr.trim().is_empty(), "quiet: {stderr}");
    // The same through a shell, as a user types it.
    let sh = Command::new("sh")
        .arg("-c")
        .arg(format!(
            "{:?} --no-cache inspect {:?} {} | head -1",
            env!("CARGO_BIN_EXE_wipdr"),
            dir,
            std::iter::repeat_n(format!("{walk:?}"), 1500)
                .collect::<Vec<_>>()
                .join(" ")
        ))
        .env_remove("WIPDR_CACHE_DIR")
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&sh.stderr);
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(
        String::from_utf8_lossy(&sh.stdout).starts_with("floor site/F1"),
        "{:?}",
        sh.stdout
    );
}

/// Runs `wipdr --no-cache ARGS`, asserts that it is refused (exit code 1, no panic) and
/// returns its stderr.
fn refused<I, S>(args: I) -> String
where
    I: IntoIterator<Item = S>,
    S: AsRef<std::ffi::OsStr>,
{
    let out = wipdr().arg("--no-cache").args(args).output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    stderr
}

fn cache_files(dir: &Path) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .map(|d| d.map(|e| e.unwrap().path()).collect())
        .unwrap_or_default();
    files.sort();
    files
}

#[test]
fn the_cache_moves_turns_off_reports_and_clears() {
    let tmp = tempfile::tempdir().unwrap();
    let (dir, _) = make_floor(tmp.path());
    let work = tmp.path().join("work");
    std::fs::create_dir_all(&work).unwrap();
    let run = |args: &[&str], env: Option<&Path>| {
        let mut c = wipdr();
        c.current_dir(&work).args(args);
        if let Some(e) = env {
            c.env("WIPDR_CACHE_DIR", e);
        }
        let out = c.output().unwrap();
        assert!(out.status.success(), "{args:?}: {out:?}");
        String::from_utf8(out.stdout).unwrap()
    };
    let floor = dir.to_str().unwrap();
    // --no-cache writes nothing anywhere.
    let out = run(&["--no-cache", "inspect", floor], None);
    assert!(out.contains("cache off"), "{out}");
    assert!(!work.join("target").exists());
    // --cache-dir.
    let flag_dir = tmp.path().join("flag-cache");
    let flag = flag_dir.to_str().unwrap();
    let out = run(&["--cache-dir", flag, "inspect", floor], None);
    assert!(out.contains("cached in"), "{out}");
    assert_eq!(cache_files(&flag_dir).len(), 1);
    let out = run(&["inspect", floor, "--cache-dir", flag], None);
    assert!(out.contains("from the cache in"), "{out}");
    // WIPDR_CACHE_DIR, and the flag wins over it.
    let env_dir = tmp.path().join("env-cache");
    run(&["inspect", floor], Some(&env_dir));
    assert_eq!(cache_files(&env_dir).len(), 1);
    assert!(!work.join("target").exists(), "the default is not used");
    let other = tmp.path().join("other");
    run(
        &["--cache-dir", other.to_str().unwrap(), "inspect", floor],
        Some(&env_dir),
    );
    assert_eq!(cache_files(&other).len(), 1);
    // The default, relative to the working directory.
    run(&["inspect", floor], None);
    assert_eq!(cache_files(&work.join("target/wipdr-cache")).len(), 1);
    // info and clear.
    let info = run(&["cache", "info"], Some(&env_dir));
    assert!(
        info.contains(&format!("cache folder {}", env_dir.display())),
        "{info}"
    );
    assert!(info.contains("1 files,"), "{info}");
    let cleared = run(&["cache", "clear"], Some(&env_dir));
    assert!(cleared.starts_with("removed 1 files"), "{cleared}");
    assert!(cache_files(&env_dir).is_empty());
    let info = run(&["--cache-dir", flag, "cache", "info"], None);
    assert!(info.contains("1 files,"), "{info}");
}

#[test]
fn a_bad_cache_file_is_rebuilt_by_the_program() {
    let tmp = tempfile::tempdir().unwrap();
    let (dir, _) = make_floor(tmp.path());
    let cache = tmp.path().join("cache");
    let run = || {
        let out = wipdr()
            .arg("--cache-dir")
            .arg(&cache)
            .arg("inspect")
            .arg(&dir)
            .output()
            .unwrap();
        assert!(out.status.success(), "{out:?}");
        String::from_utf8(out.stdout).unwrap()
    };
    run();
    let file = &cache_files(&cache)[0];
    let mut bytes = std::fs::read(file).unwrap();
    let mid = bytes.len() / 2;
    bytes[mid] ^= 0x10;
    std::fs::write(file, &bytes).unwrap();
    let out = run();
    assert!(out.contains("bad cache file replaced"), "{out}");
    assert!(run().contains("from the cache in"));
}

#[test]
fn eval_with_no_scored_waypoint_fails_instead_of_printing_zero() {
    let tmp = tempfile::tempdir().unwrap();
    let sim = tmp.path().join("sim");
    let out = wipdr()
        .args(["simulate", "--walks", "5", "--duration-s", "30", "--out"])
        .arg(&sim)
        .output()
        .unwrap();
    assert!(out.status.success(), "{out:?}");
    // Scoring only the first -1 m of each walk: no waypoint is scored.
    let cfg = tmp.path().join("cfg.toml");
    std::fs::write(&cfg, "score_first_m = -1.0\n").unwrap();
    let (data, cfg) = (sim.join("F1"), cfg.into_os_string());
    let stderr = refused([
        "eval".as_ref(),
        "--schemes".as_ref(),
        "wifi,pdr".as_ref(),
        "--data".as_ref(),
        data.as_os_str(),
        "--config".as_ref(),
        cfg.as_os_str(),
    ]);
    // A config check of `score_first_m` (another change) may refuse it first; either way
    // no 0.00 m result is reported as a success.
    assert!(
        stderr.contains("no waypoint was scored for wifi, pdr") || stderr.contains("score_first_m"),
        "{stderr}"
    );
}

#[test]
fn bad_pdr_and_calibration_configs_are_refused_naming_file_and_field() {
    let tmp = tempfile::tempdir().unwrap();
    let (dir, _) = make_floor(tmp.path());
    let pdr = tmp.path().join("pdr.toml");
    std::fs::write(
        &pdr,
        "[heading.snap]\nenabled = true\nthreshold_deg = -3.0\n",
    )
    .unwrap();
    let cal = tmp.path().join("cal.toml");
    std::fs::write(&cal, "min_grid_concentration = 2.0\n").unwrap();
    let out_cfg = tmp.path().join("fit.toml");
    let runs = [
        (
            vec!["pdr-eval".as_ref(), "--config".as_ref(), pdr.as_os_str()],
            "heading.snap.threshold_deg",
        ),
        (
            vec![
                "pdr-fit".as_ref(),
                "--calibration".as_ref(),
                cal.as_os_str(),
                "--out".as_ref(),
                out_cfg.as_os_str(),
            ],
            "min_grid_concentration",
        ),
    ];
    for (mut args, field) in runs {
        args.extend(["--data".as_ref(), dir.as_os_str()]);
        let stderr = refused(&args);
        assert!(stderr.contains(field), "{field}: {stderr}");
    }
    assert!(!out_cfg.exists());
}

/// A simulated floor folder `root/sim/F1` with `walks` walks of 30 s.
fn simulated_floor(root: &Path, walks: usize) -> PathBuf {
    let sim = root.join("sim");
    let out = wipdr()
        .args([
            "simulate",
            "--walks",
            &walks.to_string(),
            "--duration-s",
            "30",
            "--out",
        ])
        .arg(&sim)
        .output()
        .unwrap();
    assert!(out.status.success(), "{out:?}");
    sim.join("F1")
}

/// Writes `text` to `root/name` and returns the path.
fn write_file(root: &Path, name: &str, text: &str) -> PathBuf {
    let path = root.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

/// Seen on the old main: one walk whose scans carry 1,000,000 distinct BSSIDs (a 3 MB
/// file) made `eval` abort with `memory allocation of 2147483648 bytes failed` (5.3 GB peak).
#[test]
fn eval_of_a_walk_with_a_million_bssids_is_refused_naming_max_aps() {
    use wipdr_core::{Bssid, WifiEntry, WifiScan};
    let tmp = tempfile::tempdir().unwrap();
    let dir = simulated_floor(tmp.path(), 4);
    let walks_dir = dir.join(floor::WALKS_DIR);
    let first = floor::walk_files(&dir).unwrap()[0].clone();
    let model = wipdr_io::trace::read_walk(&first).unwrap().walk;
    let mut walk = Walk::default();
    walk.meta.id = "hostile".into();
    walk.waypoints = model.waypoints.clone();
    let (t0, t1) = (
        walk.waypoints.first().unwrap().t,
        walk.waypoints.last().unwrap().t,
    );
    let (scans, per_scan) = (1000usize, 1000usize);
    for s in 0..scans {
        let t = t0 + (t1 - t0) * s as i64 / scans as i64;
        let entries = (0..per_scan)
            .map(|k| WifiEntry {
                bssid: Bssid((s * per_scan + k) as u64 + 1),
                ssid: String::new(),
                rssi_dbm: -60.0,
                frequency_mhz: 2412,
                last_seen_ms: t,
            })
            .collect();
        walk.wifi.push(WifiScan { t, entries });
    }
    wipdr_io::trace::write_walk_file(&walk, walks_dir.join("hostile.txt.gz")).unwrap();
    let stderr = refused([
        "eval".as_ref(),
        "--schemes".as_ref(),
        "wifi".as_ref(),
        "--data".as_ref(),
        dir.as_os_str(),
    ]);
    assert!(
        stderr.contains("radio_map.max_aps") && stderr.contains("distinct APs"),
        "{stderr}"
    );
}

/// Seen on the old main: the same floor folder given twice to `eval` counted its walks
/// twice, without a word.
#[test]
fn the_same_floor_given_twice_to_eval_is_read_once_with_a_warning() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = simulated_floor(tmp.path(), 5);
    let walks_in = |json: &Path| -> usize {
        let v: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(json).unwrap()).unwrap();
        v["walks"].as_array().unwrap().len()
    };
    let run = |dirs: &[&Path], json: &Path| {
        let mut c = wipdr();
        c.args(["--no-cache", "eval", "--schemes", "pdr", "--json"])
            .arg(json)
            .arg("--data")
            .args(dirs);
        let out = c.output().unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
        assert!(out.status.success(), "{stderr}");
        stderr
    };
    let (once, twice) = (tmp.path().join("once.json"), tmp.path().join("twice.json"));
    run(&[&dir], &once);
    let same = dir.join(".");
    let stderr = run(&[&dir, &same, &dir], &twice);
    assert!(stderr.contains("given more than once"), "{stderr}");
    assert_eq!(walks_in(&twice), walks_in(&once));
    // A floor inside a site given with the site itself is refused (its walks would count
    // twice).
    let site = dir.parent().unwrap();
    let stderr = refused([
        "eval".as_ref(),
        "--schemes".as_ref(),
        "pdr".as_ref(),
        "--data".as_ref(),
        site.as_os_str(),
        dir.as_os_str(),
    ]);
    assert!(stderr.contains("inside"), "{stderr}");
}

/// Seen on the old main: `nan` for an optional number read as "not set" (TOML `nan` became
/// JSON `null`), `max_entry_age_ms = -1` emptied the radio map with an error blaming
/// `matcher.k`, a huge spatial lattice was accepted: each is now refused naming the field.
#[test]
fn bad_eval_config_values_are_refused_naming_file_and_field() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = simulated_floor(tmp.path(), 5);
    for (i, (text, field)) in [
        ("score_first_m = nan\n", "score_first_m"),
        ("[query]\nmin_rssi_dbm = nan\n", "query.min_rssi_dbm"),
        ("[radio_map]\ngrid_cell_m = nan\n", "radio_map.grid_cell_m"),
        (
            "[radio_map]\nmax_entry_age_ms = -1\n",
            "radio_map.max_entry_age_ms",
        ),
        ("[radio_map]\nmax_aps = 0\n", "radio_map.max_aps"),
        (
            "[radio_map.interpolation.spatial]\ncell_m = 0.001\nmax_points = 1000000000\n",
            "max_points",
        ),
        (
            "[schemes.my_ekf]\nq_heading_deg = 3.0\n",
            "scheme = \"ekf\"",
        ),
    ]
    .into_iter()
    .enumerate()
    {
        let cfg = write_file(tmp.path(), &format!("c{i}.toml"), text);
        let stderr = refused([
            "eval".as_ref(),
            "--schemes".as_ref(),
            "wifi".as_ref(),
            "--data".as_ref(),
            dir.as_os_str(),
            "--config".as_ref(),
            cfg.as_os_str(),
        ]);
        assert!(
            stderr.contains(field) && stderr.contains(&format!("c{i}.toml")),
            "{text}: {stderr}"
        );
        assert!(!stderr.contains("matcher.k"), "{text}: {stderr}");
    }
}

/// A benchmark dataset folder with the given CSV texts.
fn dataset(root: &Path, name: &str, train: &str, test: &str) -> PathBuf {
    let dir = root.join(name);
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("train.csv"), train).unwrap();
    std::fs::write(dir.join("test.csv"), test).unwrap();
    dir
}

/// Seen on the old main: `fingerprint-eval` printed `mean2d 0.00` (exit 0) for a test set
/// with nothing to score, a 35.6 m tie result for a training set where no AP is heard, and
/// a finite 2D mean beside an infinite 3D one for a label at x = 1e308.
#[test]
fn degenerate_fingerprint_datasets_are_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let header = "ap_000,ap_001,x,y,z,floor,building\n";
    let train = format!(
        "{header}-60,-70,0,0,0,0,0\n-70,-60,10,0,0,0,0\n-65,-65,5,5,0,0,0\n-80,-50,20,3,0,0,0\n"
    );
    let good_test = format!("{header}-62,-68,1,0,0,0,0\n");
    let deaf = format!("{header}100,100,0,0,0,0,0\n100,100,10,0,0,0,0\n100,100,35,0,0,0,0\n");
    for (name, train, test, want) in [
        (
            "header_only",
            train.clone(),
            header.to_string(),
            "no test query",
        ),
        (
            "not_heard",
            train.clone(),
            format!("{header}100,100,1,0,0,0,0\n100,100,2,0,0,0,0\n"),
            "no test query",
        ),
        (
            "deaf_train",
            deaf,
            good_test.clone(),
            "no access point is heard",
        ),
        (
            "huge_label",
            train.clone(),
            format!("{header}-62,-68,1e308,0,0,0,0\n"),
            "line 2, column 3 (x)",
        ),
        (
            "huge_train_label",
            format!("{header}-60,-70,0,1e200,0,0,0\n"),
            good_test.clone(),
            "line 2, column 4 (y)",
        ),
    ] {
        let dir = dataset(tmp.path(), name, &train, &test);
        let stderr = refused([
            "fingerprint-eval".as_ref(),
            "--matcher".as_ref(),
            "wknn".as_ref(),
            "--dataset".as_ref(),
            dir.as_os_str(),
        ]);
        assert!(stderr.contains(want), "{name}: {stderr}");
    }
    // The good one still runs.
    let dir = dataset(tmp.path(), "good", &train, &good_test);
    let out = wipdr()
        .args(["fingerprint-eval", "--matcher", "wknn", "--dataset"])
        .arg(&dir)
        .output()
        .unwrap();
    assert!(out.status.success(), "{out:?}");
}

#[test]
fn limits_raised_past_their_ceiling_are_refused_naming_the_field() {
    let tmp = tempfile::tempdir().unwrap();
    let limits = tmp.path().join("limits.toml");
    std::fs::write(&limits, "max_scan_entries = 100000000\n").unwrap();
    let walk = PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../fixtures/sim/F1/path_data_files/sim_F1_w0000.txt.gz"
    ));
    let err = refused([
        "inspect".as_ref(),
        "--limits".as_ref(),
        limits.as_os_str(),
        walk.as_os_str(),
    ]);
    assert!(
        err.contains("limits.toml: max_scan_entries: 100000000 is above the ceiling 1000000"),
        "{err}"
    );
}

/// Seen on the old main: a walk whose accelerometer samples were all rejected (out of
/// physical range) was still scored for `pdr` and the fused schemes, PDR standing still with
/// plausible-looking errors; and `eval` said nothing of the records its readers skipped.
/// Now the walk is left out of every scheme that needs steps (counted in the table's
/// `walks-` column and the JSON's `skipped_runs`), still scored for `wifi`, and every skip
/// is listed per floor and kind.
#[test]
fn a_walk_without_usable_accelerometer_is_skipped_per_scheme_and_every_skip_reported() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = simulated_floor(tmp.path(), 5);
    let files = floor::walk_files(&dir).unwrap();
    let mut deaf = wipdr_io::trace::read_walk(&files[0]).unwrap().walk;
    let rejected = deaf.imu.accelerometer.len();
    assert!(
        rejected > 100,
        "the simulated walk has an accelerometer stream"
    );
    for s in &mut deaf.imu.accelerometer {
        s.v = [1e300, 0.0, 9.8];
    }
    wipdr_io::trace::write_walk_file(&deaf, &files[0]).unwrap();
    // Another walk with one waypoint far off any floor: skipped as out of range.
    let mut off = wipdr_io::trace::read_walk(&files[1]).unwrap().walk;
    off.waypoints[1].position.x = 5e6;
    wipdr_io::trace::write_walk_file(&off, &files[1]).unwrap();

    let json = tmp.path().join("e.json");
    let out = wipdr()
        .args(["--no-cache", "eval", "--schemes", "wifi,pdr,ekf", "--json"])
        .arg(&json)
        .arg("--data")
        .arg(&dir)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{out:?}");
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let id = deaf.meta.id.as_str();
    let runs: Vec<(&str, &str, &str)> = v["skipped_runs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| {
            (
                r["walk"].as_str().unwrap(),
                r["scheme"].as_str().unwrap(),
                r["missing"].as_str().unwrap(),
            )
        })
        .collect();
    assert_eq!(
        runs,
        vec![(id, "pdr", "accelerometer"), (id, "ekf", "accelerometer")]
    );
    let scored: Vec<&str> = v["walks"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|w| w["walk"] == id)
        .map(|w| w["scheme"].as_str().unwrap())
        .collect();
    assert_eq!(
        scored,
        vec!["wifi"],
        "the walk is still scored for Wi-Fi only"
    );
    for (scheme, n) in [("wifi", 0), ("pdr", 1), ("ekf", 1)] {
        assert_eq!(v["pooled"][scheme]["walks_skipped"], n, "{scheme}");
    }
    let label = v["floors"].as_object().unwrap().keys().next().unwrap();
    let skips = &v["skips"][label.as_str()];
    assert_eq!(
        skips["record: out of physical range"].as_u64(),
        Some(rejected as u64 + 1),
        "{skips}"
    );
    assert_eq!(skips["run: pdr: no accelerometer stream (under 10 Hz)"], 1);
    assert!(stdout.contains("walks-"), "{stdout}");
    assert!(stdout.contains("skipped (per floor and kind):"), "{stdout}");
    assert!(
        stdout.contains(&format!("record: out of physical range: {}", rejected + 1)),
        "{stdout}"
    );
}
