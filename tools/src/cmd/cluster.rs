//! `wipdr cluster`: affinity-propagation clustering of a fingerprint table (paper 001 §2.1-2.2).
//!
//! Clusters `DIR/train.csv` (or any benchmark CSV with `--csv`, optionally only its first
//! `--rows` rows) with the similarity `-MixDis` (paper 001 eq. 3) or the signal similarity
//! (negative squared Euclidean distance, not heard = -110 dBm), and prints the cluster count,
//! sizes, iterations, convergence and time. The timing line separates building the similarity
//! matrix from affinity propagation itself (the part `benches/peers/affinity_speed.py` compares
//! with scikit-learn's `fit`). `--plot FILE.png` draws the clusters on the map.
//!
//! ```text
//! wipdr cluster --dataset $WIPDR_DATA/fingerprint/DSI1 --similarity mixdis --damping 0.9
//! wipdr cluster --csv $WIPDR_DATA/fingerprint/TUT3/test.csv --rows 2000 \
//!     --similarity signal --preference median --json
//! ```

use crate::plotting::{FONT_FAMILY, ensure_parent, init_fonts, palette};
use anyhow::{Context, Result, bail};
use plotters::prelude::*;
use std::path::PathBuf;
use std::time::Instant;
use wipdr_core::Point2;
use wipdr_fingerprint::affinity::{
    AffinityConfig, Clustering, Kernel, Preference, SimilarityMatrix, TieBreakNoise,
    affinity_propagation_owned,
};
use wipdr_fingerprint::mixdis::{Fingerprints, MixDisConfig, SimilarityKind, similarity};
use wipdr_io::fingerprint_csv::{NOT_DETECTED, read_fingerprint_csv};

/// Similarity choice on the command line.
#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum SimilarityArg {
    /// `-MixDis` (paper 001 eq. 3).
    Mixdis,
    /// Negative squared Euclidean distance of the RSS vectors.
    Signal,
}

/// Matrix element type.
#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum PrecisionArg {
    /// 4-byte floats (half the memory traffic; default).
    F32,
    /// 8-byte floats (scikit-learn's precision).
    F64,
}

/// Message-passing kernel.
#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum KernelArg {
    /// Exact pruned form, only S stored (default).
    Pruned,
    /// Dense R and A, scikit-learn's operations one for one.
    Dense,
}

/// Arguments of `wipdr cluster`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Benchmark folder: clusters its `train.csv`.
    #[arg(long, conflicts_with = "csv", required_unless_present = "csv")]
    pub dataset: Option<PathBuf>,
    /// Any benchmark CSV instead of `DIR/train.csv`.
    #[arg(long)]
    pub csv: Option<PathBuf>,
    /// Use only the first N rows.
    #[arg(long)]
    pub rows: Option<usize>,
    /// Similarity.
    #[arg(long, value_enum, default_value = "mixdis")]
    pub similarity: SimilarityArg,
    /// Damping factor in [0.5, 1).
    #[arg(long, default_value_t = 0.9)]
    pub damping: f64,
    /// Preference: `row-median` (paper 001), `median` (of all similarities, scikit-learn) or a
    /// number.
    #[arg(long, default_value = "row-median")]
    pub preference: String,
    /// Maximum iterations.
    #[arg(long, default_value_t = 200)]
    pub max_iter: usize,
    /// Iterations with unchanged exemplars needed to stop.
    #[arg(long, default_value_t = 15)]
    pub convergence_iter: usize,
    /// Message-passing kernel.
    #[arg(long, value_enum, default_value = "pruned")]
    pub kernel: KernelArg,
    /// Matrix precision.
    #[arg(long, value_enum, default_value = "f32")]
    pub precision: PrecisionArg,
    /// Value used for "not heard" (the CSV's 100).
    #[arg(long, default_value_t = -110.0, allow_negative_numbers = true)]
    pub not_heard: f32,
    /// Print one JSON line instead of text.
    #[arg(long)]
    pub json: bool,
    /// Draw the clusters on the map (PNG).
    #[arg(long)]
    pub plot: Option<PathBuf>,
}

fn parse_preference(s: &str) -> Result<Preference> {
    match s {
        "row-median" => Ok(Preference::RowMedian),
        "median" => Ok(Preference::GlobalMedian),
        v => match v.parse::<f64>() {
            Ok(x) if x.is_finite() => Ok(Preference::Value(x)),
            _ => bail!("--preference must be row-median, median or a finite number, got {v:?}"),
        },
    }
}

/// Runs the subcommand.
pub fn run(args: Args) -> Result<()> {
    let path = match (&args.csv, &args.dataset) {
        (Some(p), _) => p.clone(),
        (None, Some(d)) => d.join("train.csv"),
        (None, None) => bail!("give --dataset DIR or --csv FILE"),
    };
    let table =
        read_fingerprint_csv(&path).with_context(|| format!("reading {}", path.display()))?;
    let n = args.rows.unwrap_or(table.n_rows()).min(table.n_rows());
    if n == 0 {
        bail!("{} has no rows", path.display());
    }
    let m = table.n_aps();
    let mut rss: Vec<f32> = table.rss[..n * m].to_vec();
    for v in &mut rss {
        if *v == NOT_DETECTED {
            *v = args.not_heard;
        }
    }
    let positions: Vec<Point2> = table.labels[..n]
        .iter()
        .map(|l| Point2::new(l.x, l.y))
        .collect();
    let config = AffinityConfig {
        damping: args.damping,
        max_iter: args.max_iter,
        convergence_iter: args.convergence_iter,
        preference: parse_preference(&args.preference)?,
        noise: TieBreakNoise::SklearnCompatible { seed: 0 },
        kernel: match args.kernel {
            KernelArg::Pruned => Kernel::Pruned,
            KernelArg::Dense => Kernel::Dense,
        },
    };
    let kind = match args.similarity {
        SimilarityArg::Mixdis => SimilarityKind::MixDis,
        SimilarityArg::Signal => SimilarityKind::Signal,
    };

    let t0 = Instant::now();
    let fp = Fingerprints::new(&rss, m, &positions, args.not_heard)?;
    let s32 = similarity(&fp, kind, &MixDisConfig::default());
    let similarity_seconds = t0.elapsed().as_secs_f64();

    let t1 = Instant::now();
    let result = match args.precision {
        PrecisionArg::F32 => affinity_propagation_owned(s32, &config),
        PrecisionArg::F64 => {
            let data: Vec<f64> = s32.into_vec().into_iter().map(f64::from).collect();
            affinity_propagation_owned(SimilarityMatrix::new(n, data)?, &config)
        }
    };
    let seconds = t1.elapsed().as_secs_f64();
    let clustering = result?;

    let mut sizes = clustering.sizes();
    if args.json {
        let out = serde_json::json!({
            "file": path.display().to_string(),
            "n": n,
            "similarity": format!("{:?}", args.similarity).to_lowercase(),
            "clusters": clustering.n_clusters(),
            "exemplars": clustering.exemplars,
            "sizes": sizes,
            "iterations": clustering.iterations,
            "converged": clustering.converged(),
            "status": format!("{:?}", clustering.status),
            "seconds": seconds,
            "similarity_seconds": similarity_seconds,
            "threads": rayon::current_num_threads(),
            "kernel": format!("{:?}", args.kernel).to_lowercase(),
        });
        println!("{out}");
    } else {
        println!(
            "{}: {n} fingerprints x {m} APs, similarity {:?}, damping {}, preference {}",
            path.display(),
            args.similarity,
            args.damping,
            args.preference
        );
        println!(
            "{} clusters, {} iterations, {:?}",
            clustering.n_clusters(),
            clustering.iterations,
            clustering.status
        );
        sizes.sort_unstable_by(|a, b| b.cmp(a));
        let mean = n as f64 / sizes.len() as f64;
        println!(
            "sizes: largest {:?}, smallest {}, mean {mean:.1}",
            &sizes[..sizes.len().min(10)],
            sizes.last().copied().unwrap_or(0)
        );
        println!(
            "time: similarity {similarity_seconds:.3} s, affinity propagation {seconds:.3} s ({} threads, {:.1} ms/iteration)",
            rayon::current_num_threads(),
            1e3 * seconds / clustering.iterations.max(1) as f64
        );
    }
    if let Some(out) = &args.plot {
        plot_clusters(out, &positions, &clustering)?;
        if !args.json {
            println!("plot: {}", out.display());
        }
    }
    Ok(())
}

fn plot_clusters(out: &std::path::Path, positions: &[Point2], c: &Clustering) -> Result<()> {
    ensure_parent(out)?;
    init_fonts();
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for p in positions {
        x0 = x0.min(p.x);
        x1 = x1.max(p.x);
        y0 = y0.min(p.y);
        y1 = y1.max(p.y);
    }
    let pad = 0.03 * (x1 - x0).max(y1 - y0).max(1.0);
    let root = BitMapBackend::new(out, (1200, 1000)).into_drawing_area();
    let err = |e| anyhow::anyhow!("plot: {e}");
    root.fill(&WHITE).map_err(err)?;
    let caption = format!(
        "{} clusters of {} points ({} iterations, {:?})",
        c.n_clusters(),
        positions.len(),
        c.iterations,
        c.status
    );
    let mut chart = ChartBuilder::on(&root)
        .caption(caption, (FONT_FAMILY, 22))
        .margin(10)
        .x_label_area_size(30)
        .y_label_area_size(50)
        .build_cartesian_2d((x0 - pad)..(x1 + pad), (y0 - pad)..(y1 + pad))
        .map_err(|e| anyhow::anyhow!("chart: {e}"))?;
    chart
        .configure_mesh()
        .disable_mesh()
        .x_desc("x (m)")
        .y_desc("y (m)")
        .label_style((FONT_FAMILY, 13))
        .draw()
        .map_err(|e| anyhow::anyhow!("axes: {e}"))?;
    chart
        .draw_series(
            positions
                .iter()
                .zip(&c.labels)
                .map(|(p, &l)| Circle::new((p.x, p.y), 3, palette(l).filled())),
        )
        .map_err(err)?;
    chart
        .draw_series(c.exemplars.iter().enumerate().map(|(k, &e)| {
            let p = positions[e];
            Cross::new((p.x, p.y), 7, palette(k).stroke_width(3))
        }))
        .map_err(err)?;
    root.present()
        .map_err(|e| anyhow::anyhow!("writing {}: {e}", out.display()))?;
    Ok(())
}
