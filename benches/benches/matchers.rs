//! Matcher speed: single-query latency and batch throughput of the brute-force matchers on
//! UJI1 (19,861 x 520; skipped with a message when it is not under `$WIPDR_DATA`, else
//! `../shared/data`) and on a small synthetic map (always).
//!
//! `cargo bench -p wipdr-benches --bench matchers`

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use std::hint::black_box;
use std::sync::Arc;
use wipdr_core::Point2;
use wipdr_fingerprint::radio_map::{ApVocabulary, ReferencePoint};
use wipdr_fingerprint::{
    KnnConfig, KnnMatcher, Matcher, Metric, Query, QueryFilter, RadioMap, RadioMapConfig,
    Representation,
};
use wipdr_io::fingerprint_csv::read_dataset;

fn uji1() -> Option<(Arc<RadioMap>, Vec<Query>)> {
    let dir = match wipdr_io::real_data("fingerprint/UJI1") {
        Ok(dir) => dir,
        Err(missing) => {
            eprintln!("matchers bench: UJI1 benches skipped: {missing}");
            return None;
        }
    };
    let (train, test) = read_dataset(&dir).ok()?;
    let map = Arc::new(RadioMap::from_table(&train, RadioMapConfig::default()).ok()?);
    let queries = (0..test.n_rows())
        .filter_map(|i| Query::from_row(test.row(i), &map, &QueryFilter::default()).ok())
        .collect();
    Some((map, queries))
}

/// A deterministic synthetic map: 500 points on a 50 x 20 m grid, 60 APs with log-distance
/// path loss, heard above -95 dBm.
fn small() -> (Arc<RadioMap>, Vec<Query>) {
    let aps: Vec<(f64, f64)> = (0..60)
        .map(|j| ((j % 10) as f64 * 5.5, (j / 10) as f64 * 4.0))
        .collect();
    let rss = |x: f64, y: f64, j: usize| {
        let d = ((x - aps[j].0).powi(2) + (y - aps[j].1).powi(2))
            .sqrt()
            .max(1.0);
        let v = -35.0 - 25.0 * d.log10() - ((j * 7) % 5) as f64;
        (v > -95.0).then_some(v.round() as f32)
    };
    let mut map = RadioMap::new(
        ApVocabulary::from_names((0..60).map(|j| format!("ap_{j:03}"))),
        RadioMapConfig::default(),
    );
    for i in 0..500 {
        let (x, y) = ((i % 50) as f64, (i / 50) as f64 * 2.0);
        let row: Vec<Option<f32>> = (0..60).map(|j| rss(x, y, j)).collect();
        let p = ReferencePoint {
            position: Point2::new(x, y),
            z: None,
            floor: Some(0),
            building: None,
            scans: 1,
        };
        map.push_point(p, &row, None)
            .expect("valid synthetic point");
    }
    let queries = (0..200)
        .map(|i| {
            let (x, y) = (0.37 + (i % 49) as f64, 0.5 + (i % 9) as f64 * 2.1);
            Query {
                t: 0,
                heard: (0..60u32)
                    .filter_map(|j| rss(x, y, j as usize).map(|v| (j, v)))
                    .collect(),
                stats: Default::default(),
            }
        })
        .collect();
    (Arc::new(map), queries)
}

fn configs() -> Vec<(&'static str, KnnConfig)> {
    vec![
        ("nn", KnnConfig::nn()),
        ("knn", KnnConfig::knn(5)),
        ("wknn", KnnConfig::wknn(5, 1.0)),
        (
            "wknn-sorensen-powed",
            KnnConfig {
                k: 13,
                metric: Metric::Sorensen,
                representation: Representation::parse("powed").expect("known"),
                ..KnnConfig::wknn(13, 1.0)
            },
        ),
        (
            "wknn-shared-ap",
            KnnConfig {
                metric: Metric::parse("shared_ap").expect("known"),
                ..KnnConfig::wknn(5, 1.0)
            },
        ),
        (
            "wknn-neyman-dense",
            KnnConfig {
                metric: Metric::Neyman,
                representation: Representation::Positive,
                ..KnnConfig::wknn(5, 1.0)
            },
        ),
    ]
}

fn bench_map(c: &mut Criterion, label: &str, map: Arc<RadioMap>, queries: &[Query]) {
    let mut single = c.benchmark_group(format!("{label}/single"));
    for (name, cfg) in configs() {
        let m = KnnMatcher::new(map.clone(), cfg).expect("valid config");
        let mut i = 0usize;
        single.bench_function(BenchmarkId::from_parameter(name), |b| {
            b.iter(|| {
                i = (i + 1) % queries.len();
                black_box(m.locate(black_box(&queries[i])).expect("locates"))
            })
        });
    }
    single.finish();
    let mut batch = c.benchmark_group(format!("{label}/batch"));
    batch.sample_size(10);
    batch.throughput(Throughput::Elements(queries.len() as u64));
    for (name, cfg) in configs() {
        if name.ends_with("-dense") && map.len() > 5_000 {
            // ~30 s per batch on UJI1: its single-query figure is enough.
            continue;
        }
        let m = KnnMatcher::new(map.clone(), cfg).expect("valid config");
        batch.bench_function(BenchmarkId::from_parameter(name), |b| {
            b.iter(|| black_box(m.locate_batch(black_box(queries))))
        });
    }
    let m = KnnMatcher::new(map.clone(), KnnConfig::wknn(5, 1.0)).expect("valid config");
    batch.bench_function(BenchmarkId::from_parameter("wknn-gemm"), |b| {
        b.iter(|| black_box(m.locate_batch_gemm(black_box(queries))))
    });
    batch.finish();
}

fn matchers(c: &mut Criterion) {
    let (map, queries) = small();
    bench_map(c, "small500x60", map, &queries);
    if let Some((map, queries)) = uji1() {
        bench_map(c, "uji1", map, &queries);
    }
}

criterion_group!(benches, matchers);
criterion_main!(benches);
