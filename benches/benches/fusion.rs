//! Fusion benchmarks: one EKF step + Wi-Fi update (goal: well under 1 µs), and `apf` with
//! 1,000 particles and walls per step (synthetic ring-corridor floor plan).
//!
//! ```text
//! cargo bench -p wipdr-benches --bench fusion
//! ```

use std::hint::black_box;

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use wipdr_fusion::synthetic::{SyntheticConfig, SyntheticWalk, obs_at, step};
use wipdr_fusion::{BuildContext, PfConfig, SchemeConfig};

fn ekf_step_and_update(c: &mut Criterion) {
    let mut group = c.benchmark_group("ekf");
    for name in ["ekf", "arkf"] {
        let config = SchemeConfig::default_for(name).unwrap();
        let mut fuser = config.build(&BuildContext::default()).unwrap();
        fuser.on_wifi(&obs_at(0, 0.0, 0.0));
        let mut t = 0;
        group.bench_function(BenchmarkId::new("step+update", name), |b| {
            b.iter(|| {
                t += 500;
                let y = t as f64 * 0.0014;
                fuser.on_step(black_box(&step(t, 0.7, 0.0)));
                fuser.on_wifi(black_box(&obs_at(t, 0.3, y)));
                black_box(fuser.estimate())
            })
        });
        // steps only; a fresh filter every 1,000 steps (without fixes the covariance would
        // grow without bound and every step would take the clamping path)
        group.bench_function(BenchmarkId::new("step", name), |b| {
            let mut steps = 0;
            b.iter(|| {
                steps += 1;
                if steps % 1000 == 0 {
                    fuser = config.build(&BuildContext::default()).unwrap();
                    fuser.on_wifi(&obs_at(t, 0.0, 0.0));
                }
                t += 500;
                fuser.on_step(black_box(&step(t, 0.7, 0.0)));
            })
        });
    }
    group.finish();
}

fn apf_per_step(c: &mut Criterion) {
    let walk = SyntheticWalk::generate(&SyntheticConfig::default());
    let ctx = BuildContext::with_floor_plan(&walk.plan);
    let mut group = c.benchmark_group("apf");
    for n in [100usize, 1000] {
        let config = SchemeConfig::Apf(PfConfig {
            n_particles: n,
            ..PfConfig::default()
        });
        group.bench_function(BenchmarkId::new("step_with_walls", n), |b| {
            let mut fuser = config.build(&ctx).unwrap();
            fuser.on_wifi(&walk.wifi[0]);
            let mut i = 0;
            b.iter(|| {
                // replay the walk's steps; restart the cloud at the end of the walk
                if i == walk.steps.len() {
                    fuser = config.build(&ctx).unwrap();
                    fuser.on_wifi(&walk.wifi[0]);
                    i = 0;
                }
                fuser.on_step(black_box(&walk.steps[i]));
                i += 1;
            })
        });
        group.bench_function(BenchmarkId::new("whole_walk", n), |b| {
            b.iter(|| {
                let mut fuser = config.build(&ctx).unwrap();
                for input in walk.inputs() {
                    match input {
                        wipdr_fusion::synthetic::Input::Step(i) => fuser.on_step(&walk.steps[i]),
                        wipdr_fusion::synthetic::Input::Wifi(j) => fuser.on_wifi(&walk.wifi[j]),
                    }
                }
                black_box(fuser.estimate())
            })
        });
    }
    group.finish();
}

criterion_group!(benches, ekf_step_and_update, apf_per_step);
criterion_main!(benches);
