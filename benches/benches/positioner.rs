//! The online `Positioner` on a real walk (ILC site1/F1, when it is under the data root,
//! `$WIPDR_DATA` else `../shared/data`; else the committed synthetic fixture floor): the
//! walk's raw samples pushed one by one, the site model of the walk's protocol fold (default
//! eval config).
//!
//! - `positioner_sample/{ekf,pmf}`: throughput in samples (criterion's time per element is
//!   the per-sample cost, all sensors and scans averaged).
//! - `positioner_realtime/{ekf,pmf}`: the same run with the walk's duration as the
//!   throughput, in milliseconds of walk: criterion's `Kelem/s` is the real-time factor
//!   (seconds of walk positioned per second of computing).
//!
//! - `pmf-point`: `pmf` with `wifi_likelihood = false` (the Gaussian about each fix only, no
//!   scan likelihood raster).
//! - `{ekf,pmf}-learned`: the same with `odometry = "learned"` (the learned inertial
//!   odometry's network one window a second instead of the steps moving the fuser; the PDR
//!   still runs for the matchers).
//!
//! `cargo bench -p wipdr-benches --bench positioner`

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use std::path::PathBuf;
use wipdr_eval::fold_model::{FoldModel, folds_of};
use wipdr_eval::pipeline::{EvalConfig, FloorInput};
use wipdr_positioning::{Sample, StreamSpec, samples_of};

fn floor() -> FloorInput {
    let dir = match wipdr_io::real_data("ilc20/site1/F1") {
        Ok(real) => real,
        Err(missing) => {
            eprintln!("positioner: using the fixtures: {missing}");
            let root = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../fixtures/sim"));
            let mut dirs: Vec<PathBuf> = std::fs::read_dir(&root)
                .expect("fixtures/sim")
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.join("floor_info.json").is_file())
                .collect();
            dirs.sort();
            dirs.remove(0)
        }
    };
    let data = wipdr_io::floor::read_floor_dir(&dir, &Default::default()).expect("floor reads");
    FloorInput::new(dir.display().to_string(), data.into_floor())
}

fn positioner(c: &mut Criterion) {
    let floor = floor();
    let mut cfg = EvalConfig::default();
    // `pmf` weighing its cells by the Gaussian about each fix only, without the scan's
    // likelihood raster (the shipped `pmf` reads it): the cost the raster adds.
    let mut point = wipdr_fusion::SchemeConfig::default_for("pmf").expect("pmf");
    if let wipdr_fusion::SchemeConfig::Pmf(c) = &mut point {
        c.wifi_likelihood = false;
    }
    cfg.schemes.insert("pmf-point".to_string(), point);
    // The longest walk, positioned with its own fold's model.
    let walks = &floor.data.walks;
    let index = (0..walks.len())
        .max_by(|&a, &b| walks[a].duration_s().total_cmp(&walks[b].duration_s()))
        .expect("a walk");
    let walk = &walks[index];
    let model = FoldModel::build(&floor, folds_of(&floor)[index], &cfg)
        .expect("fold model")
        .model;
    let mut learned_cfg = cfg.clone();
    learned_cfg.positioner.odometry = wipdr_positioning::config::Odometry::Learned;
    let learned = FoldModel::build(&floor, folds_of(&floor)[index], &learned_cfg)
        .expect("fold model")
        .model;
    let samples: Vec<Sample> = samples_of(walk).collect();
    let duration_ms = walk.duration_s() * 1000.0;
    eprintln!(
        "positioner: walk {} ({:.0} s, {} samples, {} scans), map {} points",
        walk.meta.id,
        duration_ms / 1000.0,
        samples.len(),
        walk.wifi.len(),
        model.radio_map().len()
    );
    for (group, throughput) in [
        (
            "positioner_sample",
            Throughput::Elements(samples.len() as u64),
        ),
        (
            "positioner_realtime",
            Throughput::Elements(duration_ms.max(1.0) as u64),
        ),
    ] {
        let mut g = c.benchmark_group(group);
        g.sample_size(10);
        g.throughput(throughput);
        for (id, scheme, model) in [
            ("ekf", "ekf", &model),
            ("pmf", "pmf", &model),
            ("pmf-point", "pmf-point", &model),
            ("ekf-learned", "ekf", &learned),
            ("pmf-learned", "pmf", &learned),
        ] {
            g.bench_with_input(BenchmarkId::from_parameter(id), &scheme, |b, scheme| {
                b.iter(|| {
                    let mut p = model
                        .positioner(scheme, &StreamSpec::default())
                        .expect("builds");
                    let mut estimates = 0usize;
                    for s in &samples {
                        estimates += usize::from(p.push(s).is_some());
                    }
                    estimates
                })
            });
        }
        g.finish();
    }
}

criterion_group!(benches, positioner);
criterion_main!(benches);
