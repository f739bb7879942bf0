//! `wipdr fingerprint-eval`: fingerprint matchers on the public benchmark datasets
//! (`DIR/train.csv` = radio map, `DIR/test.csv` = queries).
//!
//! ```text
//! wipdr fingerprint-eval --dataset $WIPDR_DATA/fingerprint/DSI1 --matcher nn wknn --k 5
//! wipdr fingerprint-eval --dataset $WIPDR_DATA/fingerprint/* --matcher tuned-cv --json out.json
//! ```
//!
//! Matchers (`--matcher`, several allowed): the presets `nn`, `knn`, `wknn` (1/d), `wknn2`
//! (1/d^2) with `--k`; `apc` (cluster search, paper 001 §2.3), `apindex` (AP-matching index,
//! paper 002 eq. 6) and `med` (single-scan form of paper 004 eq. 11) with the papers'
//! settings; `tuned-cv` picks the literature k-NN configuration by cross-validation on
//! train.csv (honest), `tuned-test` picks it on test.csv (as the papers did: optimistic,
//! labelled so); `--tune-by 2d`, `--tune-floor-first V` and `--tune-code-variants` change the
//! criterion, the matching and the grid. Any other setting is a `wipdr_fingerprint::MatcherConfig`
//! written as an inline TOML table, the same fields as a config file's `[matcher]`:
//!
//! ```text
//! --matcher 'kind = "wknn", k = 13, metric = { kind = "sorensen" }, representation = { kind = "powed", beta = 2.718 }'
//! --matcher 'kind = "apc", similarity = "signal", clusters_searched = 3'
//! --matcher 'kind = "apindex", top_offline = 4, apply_threshold = false'
//! ```
//!
//! A table's missing fields take the kind's paper settings (`MatcherConfig::paper`); an
//! unknown field or kind is an error.

use anyhow::{Context, bail};
use std::path::PathBuf;
use std::sync::Arc;
use wipdr_eval::fingerprint_benchmark::{self as benchmark, Grid, Truth};
use wipdr_fingerprint::{
    FloorFirstMatcher, KnnConfig, KnnMatcher, Matcher, MatcherConfig, Metric, Query, QueryFilter,
    RadioMap, RadioMapConfig, Representation,
};
use wipdr_io::fingerprint_csv::read_dataset;

/// Arguments of `wipdr fingerprint-eval`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Dataset folders, each with train.csv and test.csv.
    #[arg(long, num_args = 1.., required = true)]
    pub dataset: Vec<PathBuf>,
    /// Matchers: nn, knn, wknn, wknn2, NAME:k=..,metric=..,rep=..,w=.., tuned-cv, tuned-test.
    #[arg(long, num_args = 1.., default_values_t = ["nn".to_string(), "knn".to_string(), "wknn".to_string()])]
    pub matcher: Vec<String>,
    /// Number of neighbours for knn / wknn (unless the matcher spec sets k).
    #[arg(long, default_value_t = 5)]
    pub k: usize,
    /// The "not heard" RSS value of the radio map, dBm.
    #[arg(long, default_value_t = -110.0, allow_hyphen_values = true)]
    pub not_heard: f32,
    /// Online RSSI threshold (dBm): weaker readings are dropped.
    #[arg(long, allow_hyphen_values = true)]
    pub min_rssi: Option<f64>,
    /// Folds of the cross-validation of `tuned-cv`.
    #[arg(long, default_value_t = 5)]
    pub folds: usize,
    /// At most this many held-out rows are scored in `tuned-cv` (evenly spaced).
    #[arg(long, default_value_t = 3000)]
    pub tune_max_queries: usize,
    /// Largest k of the tuning grid.
    #[arg(long, default_value_t = 15)]
    pub tune_k_max: usize,
    /// Selection criterion of `tuned-cv` / `tuned-test`: mean `3d` error (default) or mean `2d`
    /// error (the criterion of papers that report 2D error).
    #[arg(long, default_value = "3d", value_parser = ["2d", "3d"])]
    pub tune_by: String,
    /// Tuning with floor-first matching: the floor by majority of this many nearest
    /// neighbours, then the k nearest on that floor only.
    #[arg(long)]
    pub tune_floor_first: Option<usize>,
    /// Add to the tuning grid the variants of the reference code of Montoliu, Pérez-Navarro,
    /// Torres-Sospedra (2022): Neyman divided by the query's value over the query's APs
    /// (`neyman_query`) and the exponential representation with not heard = 0
    /// (`exponential_null0`).
    #[arg(long)]
    pub tune_code_variants: bool,
    /// Batch Euclidean queries through one matrix product (faer) instead of the sparse engine.
    #[arg(long)]
    pub gemm: bool,
    /// Write the results as JSON (`{"results": [...]}`).
    #[arg(long)]
    pub json: Option<PathBuf>,
}

#[derive(Debug, serde::Serialize)]
struct Row {
    dataset: String,
    matcher: String,
    config: String,
    selection: String,
    mean_2d: f64,
    mean_3d: f64,
    p50: f64,
    p75: f64,
    p95: f64,
    floor_hit: f64,
    visited_fraction: f64,
    queries_per_second: f64,
    queries: usize,
    failed: usize,
}

/// What one `--matcher` value asks for.
#[derive(Debug, Clone, PartialEq)]
enum Choice {
    /// A brute-force k-NN (the sparse or GEMM engine of this tool).
    Knn(KnnConfig),
    /// Another matcher of [`MatcherConfig`] (cluster search, AP index, single-scan MED).
    Other(MatcherConfig),
    /// The literature k-NN picked by cross-validation on train.csv (`tuned-cv`) or on
    /// test.csv (`tuned-test`, optimistic).
    Tuned,
}

/// Parses a `--matcher` value: a preset name (`nn`, `knn`, `wknn`, `wknn2` with `--k`;
/// `apc`, `apindex`, `med` with the papers' settings; `tuned-cv`, `tuned-test`) or a
/// [`MatcherConfig`] as an inline TOML table (`'kind = "apindex", top_offline = 4'`, braces
/// optional). A table's missing fields take the kind's paper settings (`k` of `wknn`: `--k`);
/// an unknown field or kind is an error naming it.
fn parse_matcher(spec: &str, default_k: usize) -> anyhow::Result<Choice> {
    let knn = |c: KnnConfig| Choice::Knn(c);
    Ok(match spec {
        "nn" => knn(KnnConfig::nn()),
        "knn" => knn(KnnConfig::knn(default_k)),
        "wknn" => knn(KnnConfig::wknn(default_k, 1.0)),
        "wknn2" => knn(KnnConfig::wknn(default_k, 2.0)),
        "tuned-cv" | "tuned-test" => Choice::Tuned,
        "apc" | "apindex" | "med" => Choice::Other(MatcherConfig::paper(spec)?),
        table if table.contains('=') => {
            let inline = if table.trim_start().starts_with('{') {
                table.to_string()
            } else {
                format!("{{ {table} }}")
            };
            let doc: toml::Table = toml::from_str(&format!("matcher = {inline}"))
                .with_context(|| format!("--matcher {spec:?}: not a TOML inline table"))?;
            let user = serde_json::to_value(&doc["matcher"])?;
            let kind = user
                .get("kind")
                .and_then(serde_json::Value::as_str)
                .with_context(|| format!("--matcher {spec:?}: needs kind = \"wknn\" | \"apc\" | \"apindex\" | \"med\""))?;
            let base = match MatcherConfig::paper(kind)? {
                MatcherConfig::Wknn(c) => MatcherConfig::Wknn(KnnConfig { k: default_k, ..c }),
                other => other,
            };
            let cfg: MatcherConfig = wipdr_positioning::merge::from_value_onto(user, &base)
                .with_context(|| format!("--matcher {spec:?}"))?;
            cfg.validate()?;
            match cfg {
                MatcherConfig::Wknn(c) => knn(c),
                other => Choice::Other(other),
            }
        }
        other => bail!(
            "unknown matcher {other:?}; available: nn, knn, wknn, wknn2, apc, apindex, med, tuned-cv, tuned-test, or a TOML table such as 'kind = \"wknn\", k = 13, metric = {{ kind = \"sorensen\" }}'"
        ),
    })
}

/// Runs the subcommand.
pub fn run(args: Args) -> anyhow::Result<()> {
    let filter = QueryFilter {
        min_rssi_dbm: args.min_rssi,
        ..Default::default()
    };
    // Validate every spec before any work.
    let choices: Vec<Choice> = args
        .matcher
        .iter()
        .map(|spec| parse_matcher(spec, args.k))
        .collect::<anyhow::Result<_>>()?;
    let mut rows: Vec<Row> = Vec::new();
    let bar = crate::progress::bar(
        (args.dataset.len() * args.matcher.len()) as u64,
        "fingerprint-eval",
    );
    for dir in &args.dataset {
        let name = dir
            .file_name()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| dir.display().to_string());
        let (train, test) = read_dataset(dir)?;
        let map = Arc::new(
            RadioMap::from_table(
                &train,
                RadioMapConfig {
                    not_heard_dbm: args.not_heard,
                },
            )
            .with_context(|| format!("{name}: train.csv"))?,
        );
        let mut queries = Vec::with_capacity(test.n_rows());
        let mut truth = Vec::with_capacity(test.n_rows());
        let mut skipped = 0usize;
        for (i, label) in test.labels.iter().enumerate() {
            match Query::from_row(test.row(i), &map, &filter) {
                Ok(q) => {
                    queries.push(q);
                    truth.push(Truth {
                        position: wipdr_core::Point2::new(label.x, label.y),
                        floor: Some(label.floor),
                    });
                }
                Err(e) => {
                    skipped += 1;
                    tracing::warn!(dataset = %name, row = i + 2, "test row skipped: {e}");
                }
            }
        }
        if skipped > 0 {
            eprintln!("{name}: {skipped} test rows without usable APs skipped");
        }
        if queries.is_empty() {
            bail!(
                "{name}: no test query to score: test.csv has {} rows, {skipped} of them without a usable AP (an empty test set scores nothing, not 0 m)",
                test.n_rows()
            );
        }
        for (spec, choice) in args.matcher.iter().zip(&choices) {
            // Cluster search, AP index, single-scan MED.
            if let Choice::Other(config) = choice {
                let m = config.build_stateless(map.clone())?;
                let (score, qps) = benchmark::evaluate(m.as_ref(), &queries, &truth);
                rows.push(Row {
                    dataset: name.clone(),
                    matcher: spec.clone(),
                    config: m.name(),
                    selection: "fixed".to_string(),
                    mean_2d: score.error_2d.mean,
                    mean_3d: score.mean_3d,
                    p50: score.error_2d.p50,
                    p75: score.error_2d.p75,
                    p95: score.error_2d.p95,
                    floor_hit: score.floor_hit,
                    visited_fraction: score.visited_fraction,
                    queries_per_second: qps,
                    queries: queries.len(),
                    failed: score.failed,
                });
                bar.inc(1);
                continue;
            }
            let (cfg, selection) = match choice {
                Choice::Knn(cfg) => (*cfg, "fixed".to_string()),
                Choice::Other(_) => unreachable!("handled above"),
                Choice::Tuned => {
                    let mut grid = Grid {
                        k_max: args.tune_k_max,
                        floor_votes: args.tune_floor_first,
                        ..Grid::default()
                    };
                    if args.tune_code_variants {
                        grid.metrics.push(Metric::NeymanQuery);
                        grid.representations
                            .push(Representation::ExponentialNullZero { alpha: 24.0 });
                    }
                    let points = if spec == "tuned-cv" {
                        benchmark::grid_cross_validated(
                            &map,
                            &grid,
                            args.folds,
                            args.tune_max_queries,
                        )?
                    } else {
                        benchmark::grid_on_test(&map, &queries, &truth, &grid)?
                    };
                    let best = if args.tune_by == "2d" {
                        benchmark::best_2d(&points)
                    } else {
                        benchmark::best(&points)
                    }
                    .context("empty tuning grid")?;
                    let mut how = if spec == "tuned-cv" {
                        format!(
                            "{}-fold CV on train.csv (cv mean_{} {:.2})",
                            args.folds,
                            args.tune_by,
                            if args.tune_by == "2d" {
                                best.mean_2d
                            } else {
                                best.mean_3d
                            }
                        )
                    } else {
                        format!(
                            "chosen on test.csv by mean {} (optimistic): {:.3} 2D / {:.3} 3D",
                            args.tune_by, best.mean_2d, best.mean_3d
                        )
                    };
                    if let Some(v) = args.tune_floor_first {
                        how += &format!("; floor-first (floor of the {v} nearest)");
                    }
                    (best.config, how)
                }
            };
            let matcher = KnnMatcher::new(map.clone(), cfg)?;
            let tuned = matches!(spec.as_str(), "tuned-cv" | "tuned-test");
            let floor_first = match args.tune_floor_first {
                Some(v) if tuned => Some(FloorFirstMatcher::new(
                    KnnMatcher::new(map.clone(), cfg)?,
                    v,
                )?),
                _ => None,
            };
            let (score, qps) = if let Some(ff) = &floor_first {
                benchmark::evaluate(ff, &queries, &truth)
            } else if args.gemm {
                let start = std::time::Instant::now();
                let results = matcher.locate_batch_gemm(&queries);
                let secs = start.elapsed().as_secs_f64();
                (
                    benchmark::score(&results, &truth, map.len()),
                    queries.len() as f64 / secs.max(1e-12),
                )
            } else {
                benchmark::evaluate(&matcher, &queries, &truth)
            };
            rows.push(Row {
                dataset: name.clone(),
                matcher: spec.clone(),
                config: floor_first
                    .as_ref()
                    .map_or_else(|| matcher.name(), |ff| ff.name()),
                selection,
                mean_2d: score.error_2d.mean,
                mean_3d: score.mean_3d,
                p50: score.error_2d.p50,
                p75: score.error_2d.p75,
                p95: score.error_2d.p95,
                floor_hit: score.floor_hit,
                visited_fraction: score.visited_fraction,
                queries_per_second: qps,
                queries: queries.len(),
                failed: score.failed,
            });
            bar.inc(1);
        }
    }
    bar.finish_and_clear();
    println!(
        "{:<8} {:<12} {:>8} {:>8} {:>7} {:>7} {:>7} {:>6} {:>7} {:>10}  config",
        "dataset", "matcher", "mean2d", "mean3d", "p50", "p75", "p95", "floor", "visited", "q/s"
    );
    for r in &rows {
        println!(
            "{:<8} {:<12} {:>8.2} {:>8.2} {:>7.2} {:>7.2} {:>7.2} {:>6.3} {:>7.3} {:>10.0}  {}{}",
            r.dataset,
            r.matcher.chars().take(12).collect::<String>(),
            r.mean_2d,
            r.mean_3d,
            r.p50,
            r.p75,
            r.p95,
            r.floor_hit,
            r.visited_fraction,
            r.queries_per_second,
            r.config,
            if r.selection == "fixed" {
                String::new()
            } else {
                format!(" [{}]", r.selection)
            }
        );
    }
    if let Some(path) = &args.json {
        let text = serde_json::to_string_pretty(&serde_json::json!({ "results": rows }))?;
        std::fs::write(path, text).with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use wipdr_fingerprint::Weighting;

    #[test]
    fn matcher_values_parse() {
        let c = parse_matcher(
            "kind = \"wknn\", k = 13, metric = { kind = \"sorensen\" }, weighting = { kind = \"inverse_distance\", power = 2.0 }",
            5,
        )
        .unwrap();
        let Choice::Knn(c) = c else { panic!("{c:?}") };
        assert_eq!(c.k, 13);
        assert_eq!(c.metric, Metric::Sorensen);
        assert_eq!(c.weighting, Weighting::InverseDistance { power: 2.0 });
        assert_eq!(c.representation, Representation::Raw);
        // A table without k takes --k.
        let Choice::Knn(c) = parse_matcher("{ kind = \"wknn\" }", 7).unwrap() else {
            panic!()
        };
        assert_eq!(c.k, 7);
        assert_eq!(
            parse_matcher("nn", 5).unwrap(),
            Choice::Knn(KnnConfig::nn())
        );
        assert_eq!(parse_matcher("tuned-cv", 5).unwrap(), Choice::Tuned);
        let Choice::Other(MatcherConfig::Apindex(a)) = parse_matcher(
            "kind = \"apindex\", top_offline = 4, apply_threshold = false",
            5,
        )
        .unwrap() else {
            panic!()
        };
        assert!(a.top_offline == 4 && !a.apply_threshold);
        assert_eq!(a.metric, Metric::Euclidean); // the paper's, in the benchmark context
        // The documented tables of docs/results/clustering.md parse.
        for table in [
            "kind = \"apc\", similarity = \"signal\", clusters_searched = 3",
            "kind = \"apc\", method = { k_means = { mean_size = 10 } }, clusters_searched = 3",
            "kind = \"wknn\", k = 13, metric = { kind = \"sorensen\" }, representation = { kind = \"powed\", beta = 2.718 }",
        ] {
            assert!(parse_matcher(table, 5).is_ok(), "{table}");
        }
        assert!(parse_matcher("bogus", 5).is_err());
        assert!(parse_matcher("kind = \"wknn\", metric = { kind = \"nope\" }", 5).is_err());
        assert!(parse_matcher("kind = \"wknn\", kk = 3", 5).is_err());
        assert!(parse_matcher("k = 3", 5).is_err());
        assert!(parse_matcher("kind = \"med\", window = 0", 5).is_err());
    }
}
