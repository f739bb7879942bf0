//! Fusion benchmarks: one EKF step + Wi-Fi update (goal: well under 1 µs), and `apf` with
//! 1,000 particles and walls per step, on a synthetic ring-corridor floor plan and, when
//! `ilc20/site1/F1` is under the data root (`$WIPDR_DATA`, else `../shared/data`), on the
//! real floor plan of ILC site1/F1 (1,000+ wall segments) with a real walk's PDR steps and
//! Wi-Fi fixes (throughput in steps per second).
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

/// A floor plan, a walk's steps and fixes, and the radio map's reference-point positions.
type RealWalk = (
    wipdr_core::FloorPlan,
    Vec<wipdr_core::StepEvent>,
    Vec<wipdr_core::WifiObservation>,
    Vec<wipdr_core::Point2>,
);

/// One real walk of site1/F1 as fusion inputs: PDR steps (default config) and WKNN fixes on a
/// radio map of the floor's other walks. `None` (with a printed reason) without the data.
fn real_walk() -> Option<RealWalk> {
    use wipdr_fingerprint::{KnnConfig, KnnMatcher, Matcher, QueryFilter, walk_map};
    let dir = match wipdr_io::real_data("ilc20/site1/F1") {
        Ok(dir) => dir,
        Err(missing) => {
            eprintln!("apf_real skipped: {missing}");
            return None;
        }
    };
    let floor = wipdr_io::floor::read_floor_dir(&dir, &Default::default()).ok()?;
    // The longest walk is the test walk; the others make the radio map.
    let longest = (0..floor.walks.len()).max_by(|&a, &b| {
        floor.walks[a]
            .walk
            .duration_s()
            .total_cmp(&floor.walks[b].walk.duration_s())
    })?;
    let test = &floor.walks[longest];
    let train = floor
        .walks
        .iter()
        .enumerate()
        .filter(|(i, _)| *i != longest)
        .map(|(_, w)| &w.walk);
    let cfg = walk_map::WalkMapConfig::default();
    let (map, _) = walk_map::build_from_walks(train, &cfg).ok()?;
    let coverage = map.points().iter().map(|p| p.position).collect();
    let matcher = KnnMatcher::new(map, KnnConfig::default()).ok()?;
    let query = QueryFilter {
        max_age_ms: cfg.max_entry_age_ms,
        ..QueryFilter::default()
    };
    let steps = wipdr_pdr::Pdr::run(wipdr_pdr::CheckedPdrConfig::default(), &test.walk);
    let obs = test
        .walk
        .wifi
        .iter()
        .filter_map(|s| matcher.locate_scan(s, &query).ok())
        .collect();
    Some((floor.plan, steps, obs, coverage))
}

/// Feeds a whole walk to a fresh fuser (steps before a fix of the same millisecond).
fn run_walk(
    config: &SchemeConfig,
    ctx: &BuildContext,
    steps: &[wipdr_core::StepEvent],
    obs: &[wipdr_core::WifiObservation],
) -> Option<wipdr_fusion::Estimate> {
    let mut fuser = config.build(ctx).unwrap();
    let (mut i, mut j) = (0, 0);
    while i < steps.len() || j < obs.len() {
        if j >= obs.len() || (i < steps.len() && steps[i].t <= obs[j].t) {
            fuser.on_step(&steps[i]);
            i += 1;
        } else {
            fuser.on_wifi(&obs[j]);
            j += 1;
        }
    }
    fuser.estimate()
}

/// `pmf` over the same real walk: the walkable raster (0.5 m, built once per floor, as the
/// eval does) and the radio map's reference points are shared inputs, not timed.
fn pmf_on_a_real_floor(c: &mut Criterion) {
    let Some((plan, steps, obs, coverage)) = real_walk() else {
        return;
    };
    let ctx = BuildContext {
        walkable: Some(std::sync::Arc::new(
            wipdr_fusion::WalkableGrid::new(&plan, 0.5).unwrap(),
        )),
        coverage: Some(std::sync::Arc::new(coverage)),
        ..BuildContext::default()
    };
    let config = SchemeConfig::default_for("pmf").unwrap();
    let mut group = c.benchmark_group("pmf_real");
    group.throughput(criterion::Throughput::Elements(steps.len() as u64));
    group.sample_size(10);
    group.bench_function("whole_walk_site1F1", |b| {
        b.iter(|| black_box(run_walk(&config, &ctx, &steps, &obs)))
    });
    group.finish();
}

fn apf_on_a_real_floor(c: &mut Criterion) {
    let Some((plan, steps, obs, _)) = real_walk() else {
        return;
    };
    let ctx = BuildContext::with_floor_plan(&plan);
    let config = SchemeConfig::Apf(PfConfig {
        n_particles: 1000,
        ..PfConfig::default()
    });
    eprintln!(
        "apf_real: {} steps, {} Wi-Fi fixes, {} walls",
        steps.len(),
        obs.len(),
        plan.walls.len()
    );
    let mut group = c.benchmark_group("apf_real");
    group.throughput(criterion::Throughput::Elements(steps.len() as u64));
    group.sample_size(10);
    group.bench_function(
        BenchmarkId::new("whole_walk_site1F1", plan.walls.len()),
        |b| b.iter(|| black_box(run_walk(&config, &ctx, &steps, &obs))),
    );
    group.finish();
}

criterion_group!(
    benches,
    ekf_step_and_update,
    apf_per_step,
    apf_on_a_real_floor,
    pmf_on_a_real_floor
);
criterion_main!(benches);
