//! Affinity propagation (paper 001 §2.2) on the side-by-side matrices of
//! `benches/peers/affinity_speed.py`: the first N = 2,000 and 3,951 rows of TUT3's `test.csv`,
//! signal similarity (negative squared Euclidean, not heard = -110 dBm), median preference,
//! damping 0.9, max_iter 200, convergence_iter 15; pruned kernel in `f32` and `f64`, dense
//! kernel in `f32`. The similarity
//! matrix is built once outside the timed loop, as scikit-learn's `fit` receives it.
//!
//! Also the matchers `apc`, `apindex`, `med` on UJI1 beside brute-force WKNN.
//!
//! `cargo bench -p wipdr-benches --bench clustering`. Skips (with a message) when
//! the data root (`$WIPDR_DATA`, else `../shared/data`) lacks the data.

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use std::hint::black_box;
use std::path::PathBuf;
use std::sync::Arc;
use wipdr_core::Point2;
use wipdr_fingerprint::MatcherConfig;
use wipdr_fingerprint::affinity::{
    AffinityConfig, Kernel, Preference, SimilarityMatrix, affinity_propagation,
};
use wipdr_fingerprint::mixdis::{Fingerprints, signal_similarity};
use wipdr_fingerprint::{
    KnnConfig, KnnMatcher, Matcher, Query, QueryFilter, RadioMap, RadioMapConfig,
};
use wipdr_io::fingerprint_csv::{NOT_DETECTED, read_dataset, read_fingerprint_csv};

fn data_dir() -> PathBuf {
    wipdr_io::data_root().join("fingerprint")
}

fn tut3_similarity(rows: usize) -> Option<SimilarityMatrix<f32>> {
    let path = data_dir().join("TUT3/test.csv");
    if !path.exists() {
        eprintln!("skipping: {} not found (WIPDR_DATA)", path.display());
        return None;
    }
    let table = read_fingerprint_csv(&path).ok()?;
    let n = rows.min(table.n_rows());
    let m = table.n_aps();
    let rss: Vec<f32> = table.rss[..n * m]
        .iter()
        .map(|&v| if v == NOT_DETECTED { -110.0 } else { v })
        .collect();
    let pos: Vec<Point2> = table.labels[..n]
        .iter()
        .map(|l| Point2::new(l.x, l.y))
        .collect();
    let fp = Fingerprints::new(&rss, m, &pos, -110.0).ok()?;
    Some(signal_similarity(&fp))
}

fn bench_affinity(c: &mut Criterion) {
    let config = AffinityConfig {
        preference: Preference::GlobalMedian,
        ..AffinityConfig::default()
    };
    let dense = AffinityConfig {
        kernel: Kernel::Dense,
        ..config.clone()
    };
    let mut group = c.benchmark_group("affinity_propagation_tut3");
    group.sample_size(10);
    for n in [2000usize, 3951] {
        let Some(s32) = tut3_similarity(n) else {
            return;
        };
        let s64 = SimilarityMatrix::new(
            s32.len(),
            s32.as_slice().iter().map(|&v| f64::from(v)).collect(),
        )
        .unwrap();
        group.bench_with_input(BenchmarkId::new("pruned_f32", n), &s32, |b, s| {
            b.iter(|| black_box(affinity_propagation(black_box(s), &config).unwrap()))
        });
        group.bench_with_input(BenchmarkId::new("pruned_f64", n), &s64, |b, s| {
            b.iter(|| black_box(affinity_propagation(black_box(s), &config).unwrap()))
        });
        group.bench_with_input(BenchmarkId::new("dense_f32", n), &s32, |b, s| {
            b.iter(|| black_box(affinity_propagation(black_box(s), &dense).unwrap()))
        });
    }
    group.finish();
}

/// Matchers on UJI1 beside brute-force WKNN: one `locate` per test row (first 300 rows),
/// single-threaded, same queries for every matcher.
fn bench_matchers_uji1(c: &mut Criterion) {
    let dir = data_dir().join("UJI1");
    if !dir.join("train.csv").exists() {
        eprintln!("skipping: {} not found (WIPDR_DATA)", dir.display());
        return;
    }
    let (train, test) = read_dataset(&dir).unwrap();
    let map = Arc::new(RadioMap::from_table(&train, RadioMapConfig::default()).unwrap());
    let filter = QueryFilter::default();
    let queries: Vec<Query> = (0..test.n_rows().min(300))
        .filter_map(|i| Query::from_row(test.row(i), &map, &filter).ok())
        .collect();
    let mut matchers: Vec<(String, Box<dyn Matcher>)> = vec![(
        "wknn_brute_force".into(),
        Box::new(KnnMatcher::new(map.clone(), KnnConfig::default()).unwrap()),
    )];
    // Benchmark names kept from the earlier string specs, for comparable criterion history.
    for (name, config) in [
        ("apc", "kind = \"apc\""),
        (
            "apc_sim_signal_clusters_3",
            "kind = \"apc\"\nsimilarity = \"signal\"\nclusters_searched = 3",
        ),
        ("apindex", "kind = \"apindex\""),
        (
            "apindex_top_4_threshold_0",
            "kind = \"apindex\"\ntop_offline = 4\napply_threshold = false",
        ),
        ("med", "kind = \"med\""),
    ] {
        let config: MatcherConfig = toml::from_str(config).unwrap();
        matchers.push((name.into(), config.build_stateless(map.clone()).unwrap()));
    }
    let mut group = c.benchmark_group("matchers_uji1_300_queries");
    group.sample_size(10);
    group.throughput(criterion::Throughput::Elements(queries.len() as u64));
    for (name, m) in &matchers {
        group.bench_function(name.as_str(), |b| {
            b.iter(|| {
                for q in &queries {
                    black_box(m.locate(black_box(q)).unwrap());
                }
            })
        });
    }
    group.finish();
}

criterion_group!(benches, bench_affinity, bench_matchers_uji1);
criterion_main!(benches);
