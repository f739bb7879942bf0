//! PDR pipeline speed: every IMU stream of a walk in, step events out (`Pdr::run_detailed`:
//! step detection, all four heading sources, ZUPT filter, motion state), on the longest
//! walk of `site1/F1` (skipped with a message when it is not under `$WIPDR_DATA`, else
//! `../shared/data`) and on a one-minute synthetic walk (always). Goal: at least 10,000x
//! real time (a one-minute walk in under 6 ms on one core); the walk's duration is printed
//! to turn the time into a ratio.
//!
//! `cargo bench -p wipdr-benches --bench pdr`

use criterion::{Criterion, criterion_group, criterion_main};
use std::hint::black_box;
use std::path::PathBuf;
use wipdr_core::Walk;
use wipdr_pdr::{CheckedPdrConfig, Pdr};

fn real_walk() -> Option<Walk> {
    let dir = match wipdr_io::real_data("ilc20/site1/F1/path_data_files") {
        Ok(dir) => dir,
        Err(missing) => {
            eprintln!("pdr bench: real-walk bench skipped: {missing}");
            return None;
        }
    };
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .ok()?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .collect();
    files.sort();
    files
        .iter()
        .filter_map(|f| wipdr_io::trace::read_walk(f).ok().map(|p| p.walk))
        .max_by(|a, b| a.duration_s().total_cmp(&b.duration_s()))
}

fn synthetic_walk() -> Walk {
    let mut cfg = wipdr_sim::SimConfig {
        walks: 1,
        duration_s: 60.0,
        duration_jitter_s: 0.0,
        ..Default::default()
    };
    cfg.survey.test_points = 5;
    wipdr_sim::generate(&cfg, 1)
        .expect("simulation")
        .walks
        .remove(0)
        .walk
}

fn bench_pdr(c: &mut Criterion) {
    let mut group = c.benchmark_group("pdr_pipeline");
    let mut walks = vec![("synthetic_60s".to_string(), synthetic_walk())];
    if let Some(w) = real_walk() {
        walks.push((format!("site1_F1_{}", w.meta.id), w));
    }
    for (name, walk) in &walks {
        eprintln!(
            "pdr bench: {name}: {:.1} s of walk, {} accelerometer samples",
            walk.duration_s(),
            walk.imu.accelerometer.len()
        );
        let cfg = CheckedPdrConfig::default();
        group.bench_function(name.as_str(), |b| {
            b.iter(|| black_box(Pdr::run_detailed(cfg, black_box(walk))))
        });
    }
    group.finish();
}

criterion_group!(benches, bench_pdr);
criterion_main!(benches);
