//! `wipdr wifi-stats`: Wi-Fi signals on the move (paper 002 §3.1, eq. 4-5, Fig. 2-3).
//!
//! Per AP and per walk, the refresh rate (from the entries' last-seen times) and the loss rate
//! against the mean RSSI ([`wipdr_analysis::wifi_stats::walk_ap_stats`]); the RR model
//! `eta = eta0 + a / (1 + exp(-(RSSI - RSSI_r) / c))` fitted by least squares per floor and
//! pooled, to the (AP, walk) points and to their binned means. Rates are in percent, as in the
//! paper (`eta0 = 2.16 %`, `a = 82.49 %`, `RSSI_r = -75.0 dBm`, `c = 1.85`). The fitted
//! inflection `RSSI_r` is the candidate moving-state RSSI threshold of paper 002 §3.2.1.

use crate::data::load_floors;
use crate::plotting::{self, FONT_FAMILY};
use anyhow::{Context, Result, anyhow};
use plotters::prelude::*;
use rayon::prelude::*;
use serde::Serialize;
use std::path::PathBuf;
use wipdr_analysis::wifi_stats::{
    Bin, FitConfig, RrFit, RrModel, WalkStatsSkips, WifiStatsConfig, binned_means, fit_rr_model,
    walk_ap_stats,
};

/// Arguments of `wipdr wifi-stats`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Floor folders (ILC layout).
    #[arg(long = "data", required = true, num_args = 1..)]
    pub data: Vec<PathBuf>,
    /// Draw refresh and loss rate against RSSI with the fitted curves (PNG).
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Write the points' summary and the fits as JSON here.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// A last-seen time must advance by more than this (ms) to count as a refresh.
    #[arg(long, default_value_t = WifiStatsConfig::default().refresh_tolerance_ms)]
    pub refresh_tolerance_ms: i64,
    /// Keep (AP, walk) pairs with at least this many scans in their span.
    #[arg(long, default_value_t = WifiStatsConfig::default().min_span_scans)]
    pub min_span_scans: usize,
    /// Width of the RSSI bins of the binned means, dB.
    #[arg(long, default_value_t = 1.0)]
    pub bin_db: f64,
    /// Bins with fewer (AP, walk) points than this are not shown nor fitted.
    #[arg(long, default_value_t = 20)]
    pub min_bin_count: usize,
    /// Most scatter points drawn (an even sample of the pooled points).
    #[arg(long, default_value_t = 4000)]
    pub scatter: usize,
}

/// The (AP, walk) points of one floor.
#[derive(Default)]
struct Points {
    rssi: Vec<f64>,
    refresh_pct: Vec<f64>,
    loss_pct: Vec<f64>,
}

impl Points {
    fn extend(&mut self, o: &Points) {
        self.rssi.extend(&o.rssi);
        self.refresh_pct.extend(&o.refresh_pct);
        self.loss_pct.extend(&o.loss_pct);
    }
}

/// A fit or why there is none.
#[derive(Debug, Clone, Serialize)]
#[serde(untagged)]
enum FitOutcome {
    Fitted(RrFit),
    Failed { error: String },
}

impl FitOutcome {
    fn of(x: &[f64], y: &[f64]) -> Self {
        // Rates in percent: the curve's floor and ceiling are rates.
        let cfg = FitConfig {
            value_bounds: Some([0.0, 100.0]),
            max_iterations: 5000,
            ..Default::default()
        };
        match fit_rr_model(x, y, &cfg) {
            Ok(f) => FitOutcome::Fitted(f),
            Err(e) => FitOutcome::Failed {
                error: e.to_string(),
            },
        }
    }

    fn model(&self) -> Option<RrModel> {
        match self {
            FitOutcome::Fitted(f) => Some(f.model),
            FitOutcome::Failed { .. } => None,
        }
    }

    fn row(&self) -> String {
        match self {
            FitOutcome::Fitted(f) => {
                let b = f.at_bound;
                let mut bounds = Vec::new();
                for (on, name) in [
                    (b.floor, "eta0"),
                    (b.ceiling, "eta0+a"),
                    (b.rssi_r, "RSSI_r"),
                    (b.c, "c"),
                ] {
                    if on {
                        bounds.push(name);
                    }
                }
                format!(
                    "{:>7.2} {:>7.2} {:>8.2} {:>6.2} {:>6.3} {:>6.2} {}",
                    f.model.eta0,
                    f.model.a,
                    f.model.rssi_r,
                    f.model.c,
                    f.correlation,
                    f.rmse,
                    if bounds.is_empty() {
                        String::new()
                    } else {
                        format!("on bound: {}", bounds.join(", "))
                    }
                )
            }
            FitOutcome::Failed { error } => format!("not fitted: {error}"),
        }
    }
}

/// Figures of one floor (or the pool).
#[derive(Debug, Serialize)]
struct FloorReport {
    label: String,
    walks: usize,
    pairs: usize,
    /// Mean refresh and loss rate over the pairs, %.
    mean_refresh_pct: f64,
    mean_loss_pct: f64,
    /// Fits to the (AP, walk) points.
    refresh_fit: FitOutcome,
    loss_fit: FitOutcome,
    /// Fits to the binned means (each bin one point, as the paper's per-position means).
    refresh_fit_binned: FitOutcome,
    loss_fit_binned: FitOutcome,
    refresh_bins: Vec<Bin>,
    loss_bins: Vec<Bin>,
    skips: WalkStatsSkips,
}

fn mean(v: &[f64]) -> f64 {
    if v.is_empty() {
        0.0
    } else {
        v.iter().sum::<f64>() / v.len() as f64
    }
}

fn report(
    label: &str,
    walks: usize,
    p: &Points,
    skips: WalkStatsSkips,
    args: &Args,
) -> FloorReport {
    let refresh_bins = binned_means(&p.rssi, &p.refresh_pct, args.bin_db, args.min_bin_count);
    let loss_bins = binned_means(&p.rssi, &p.loss_pct, args.bin_db, args.min_bin_count);
    let xy = |b: &[Bin]| -> (Vec<f64>, Vec<f64>) {
        (
            b.iter().map(|b| b.rssi_dbm).collect(),
            b.iter().map(|b| b.mean).collect(),
        )
    };
    let (rbx, rby) = xy(&refresh_bins);
    let (lbx, lby) = xy(&loss_bins);
    FloorReport {
        label: label.to_string(),
        walks,
        pairs: p.rssi.len(),
        mean_refresh_pct: mean(&p.refresh_pct),
        mean_loss_pct: mean(&p.loss_pct),
        refresh_fit: FitOutcome::of(&p.rssi, &p.refresh_pct),
        loss_fit: FitOutcome::of(&p.rssi, &p.loss_pct),
        refresh_fit_binned: FitOutcome::of(&rbx, &rby),
        loss_fit_binned: FitOutcome::of(&lbx, &lby),
        refresh_bins,
        loss_bins,
        skips,
    }
}

#[derive(Serialize)]
struct Report<'a> {
    config: WifiStatsConfig,
    paper_percent: RrModel,
    floors: &'a [FloorReport],
    pooled: &'a FloorReport,
}

/// Runs the subcommand.
pub fn run(args: Args) -> Result<()> {
    let cfg = WifiStatsConfig {
        refresh_tolerance_ms: args.refresh_tolerance_ms,
        min_span_scans: args.min_span_scans,
    };
    cfg.validate()?;
    if !(args.bin_db > 0.0 && args.bin_db.is_finite()) {
        anyhow::bail!("--bin-db must be > 0");
    }
    let floors = load_floors(&args.data)?;
    let mut reports = Vec::new();
    let mut pooled = Points::default();
    let mut pooled_skips = WalkStatsSkips::default();
    let mut pooled_walks = 0;
    for f in &floors {
        let per_walk: Vec<(Points, WalkStatsSkips)> = f
            .data
            .walks
            .par_iter()
            .map(|pw| {
                let mut skips = WalkStatsSkips::default();
                let stats = walk_ap_stats(&pw.wifi, &cfg, &mut skips);
                let mut p = Points::default();
                for s in stats {
                    p.rssi.push(s.mean_rssi_dbm);
                    p.refresh_pct.push(100.0 * s.refresh_rate);
                    p.loss_pct.push(100.0 * s.loss_rate);
                }
                (p, skips)
            })
            .collect();
        let mut points = Points::default();
        let mut skips = WalkStatsSkips::default();
        for (p, s) in &per_walk {
            points.extend(p);
            skips.add(s);
        }
        tracing::info!(floor = %f.label, pairs = points.rssi.len(), ?skips, "refresh / loss points");
        reports.push(report(&f.label, f.data.walks.len(), &points, skips, &args));
        pooled.extend(&points);
        pooled_skips.add(&skips);
        pooled_walks += f.data.walks.len();
    }
    let pooled_report = report("pooled", pooled_walks, &pooled, pooled_skips, &args);

    println!(
        "RR model eta = eta0 + a / (1 + exp(-(RSSI - RSSI_r) / c)), rates in %, fitted by least squares\n\
         to the (AP, walk) points; paper 002: eta0 2.16, a 82.49, RSSI_r -75.01 dBm, c 1.85 (r 0.9285)"
    );
    let header = format!(
        "{:<10} {:>5} {:>7} {:>6} {:>6} | {:>7} {:>7} {:>8} {:>6} {:>6} {:>6}",
        "floor", "walks", "pairs", "RR %", "LR %", "eta0", "a", "RSSI_r", "c", "r", "rmse"
    );
    for (what, pick) in [
        ("refresh rate", 0usize),
        ("loss rate", 1),
        ("refresh rate, binned means", 2),
        ("loss rate, binned means", 3),
    ] {
        println!("\n{what}:\n{header}");
        for r in reports.iter().chain(std::iter::once(&pooled_report)) {
            let fit = match pick {
                0 => &r.refresh_fit,
                1 => &r.loss_fit,
                2 => &r.refresh_fit_binned,
                _ => &r.loss_fit_binned,
            };
            println!(
                "{:<10} {:>5} {:>7} {:>6.1} {:>6.1} | {}",
                r.label,
                r.walks,
                r.pairs,
                r.mean_refresh_pct,
                r.mean_loss_pct,
                fit.row()
            );
        }
    }
    let s = &pooled_report.skips;
    println!(
        "\nskipped: {} walks with < 2 scans, {} (AP, walk) pairs with a span < {} scans, {} non-finite RSSI",
        s.walks_too_short, s.short_spans, cfg.min_span_scans, s.non_finite_rssi
    );
    if let Some(m) = pooled_report.refresh_fit.model() {
        println!(
            "fitted inflection (pooled, points): RSSI_r = {:.1} dBm (candidate moving-state threshold)",
            m.rssi_r
        );
    }

    if let Some(path) = &args.json {
        plotting::ensure_parent(path)?;
        let rep = Report {
            config: cfg,
            paper_percent: RrModel::PAPER_PERCENT,
            floors: &reports,
            pooled: &pooled_report,
        };
        std::fs::write(path, serde_json::to_string_pretty(&rep)?)
            .with_context(|| format!("writing {}", path.display()))?;
        println!("saved {}", path.display());
    }
    if let Some(path) = &args.plot {
        draw(
            path,
            &pooled,
            &reports,
            &pooled_report,
            args.scatter,
            args.bin_db,
        )?;
        println!("saved {}", path.display());
    }
    Ok(())
}

/// Two panels: refresh and loss rate against mean RSSI.
fn draw(
    path: &std::path::Path,
    pooled: &Points,
    floors: &[FloorReport],
    pool: &FloorReport,
    scatter: usize,
    bin_db: f64,
) -> Result<()> {
    plotting::init_fonts();
    plotting::ensure_parent(path)?;
    let root = BitMapBackend::new(path, (1400, 620)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| anyhow!("{e}"))?;
    let panels = root.split_evenly((1, 2));
    let n = pooled.rssi.len();
    let stride = n.div_ceil(scatter.max(1)).max(1);
    let (xmin, xmax) = (-100.0, -30.0);
    for (pi, panel) in panels.iter().enumerate() {
        let (title, values, bins, fit_of): (_, _, _, fn(&FloorReport) -> Option<RrModel>) =
            if pi == 0 {
                (
                    "Refresh rate (%) against mean RSSI",
                    &pooled.refresh_pct,
                    &pool.refresh_bins,
                    |r| r.refresh_fit.model(),
                )
            } else {
                (
                    "Loss rate (%) against mean RSSI",
                    &pooled.loss_pct,
                    &pool.loss_bins,
                    |r| r.loss_fit.model(),
                )
            };
        // The loss rate is small on these walks: zoom on the binned means.
        let ymax = if pi == 0 {
            105.0
        } else {
            (2.5 * bins.iter().map(|b| b.mean).fold(0.0, f64::max)).clamp(5.0, 105.0)
        };
        let mut chart = ChartBuilder::on(panel)
            .caption(title, (FONT_FAMILY, 22))
            .margin(15)
            .x_label_area_size(40)
            .y_label_area_size(50)
            .build_cartesian_2d(xmin..xmax, 0.0..ymax)
            .map_err(|e| anyhow!("{e}"))?;
        chart
            .configure_mesh()
            .x_desc("mean RSSI of the AP over the walk (dBm)")
            .y_desc(if pi == 0 {
                "%"
            } else {
                "% (zoomed; points above not drawn)"
            })
            .label_style((FONT_FAMILY, 14))
            .draw()
            .map_err(|e| anyhow!("{e}"))?;
        chart
            .draw_series(
                pooled
                    .rssi
                    .iter()
                    .zip(values.iter())
                    .step_by(stride)
                    .filter(|(x, y)| (xmin..xmax).contains(*x) && (0.0..ymax).contains(*y))
                    .map(|(&x, &y)| Circle::new((x, y), 1, RGBColor(190, 190, 190).filled())),
            )
            .map_err(|e| anyhow!("{e}"))?
            .label(format!("(AP, walk) points, 1 in {stride}"))
            .legend(|(x, y)| Circle::new((x + 10, y), 3, RGBColor(190, 190, 190).filled()));
        let curve = |m: RrModel| {
            (0..=280).map(move |i| {
                let x = xmin + (xmax - xmin) * i as f64 / 280.0;
                (x, m.eval(x))
            })
        };
        for (i, r) in floors.iter().enumerate() {
            if let Some(m) = fit_of(r) {
                let colour = plotting::palette(i);
                chart
                    .draw_series(LineSeries::new(curve(m), colour.stroke_width(2)))
                    .map_err(|e| anyhow!("{e}"))?
                    .label(format!("{} fit (RSSI_r {})", r.label, minus(m.rssi_r, 1)))
                    .legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(3))
                    });
            }
        }
        if let Some(m) = fit_of(pool) {
            chart
                .draw_series(LineSeries::new(curve(m), BLACK.stroke_width(3)))
                .map_err(|e| anyhow!("{e}"))?
                .label(format!(
                    "pooled fit (RSSI_r {}, c {:.2})",
                    minus(m.rssi_r, 1),
                    m.c
                ))
                .legend(|(x, y)| {
                    PathElement::new(vec![(x, y), (x + 20, y)], BLACK.stroke_width(3))
                });
        }
        chart
            .draw_series(
                bins.iter()
                    .map(|b| Circle::new((b.rssi_dbm, b.mean), 4, BLACK.filled())),
            )
            .map_err(|e| anyhow!("{e}"))?
            .label(format!("pooled mean per {bin_db} dB bin"))
            .legend(|(x, y)| Circle::new((x + 10, y), 4, BLACK.filled()));
        if pi == 0 {
            let paper = RGBColor(214, 39, 40);
            chart
                .draw_series(DashedLineSeries::new(
                    curve(RrModel::PAPER_PERCENT),
                    8,
                    5,
                    paper.stroke_width(2),
                ))
                .map_err(|e| anyhow!("{e}"))?
                .label("paper 002 Fig. 3 (RSSI_r \u{2212}75.0, c 1.85)")
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 20, y)], paper.stroke_width(2))
                });
        }
        chart
            .configure_series_labels()
            .position(if pi == 0 {
                SeriesLabelPosition::UpperLeft
            } else {
                SeriesLabelPosition::UpperRight
            })
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .label_font((FONT_FAMILY, 13))
            .draw()
            .map_err(|e| anyhow!("{e}"))?;
    }
    root.present().map_err(|e| anyhow!("{e}"))?;
    Ok(())
}

/// `v` with `decimals` and a typographic minus (the hyphen renders as a dot in the legend).
fn minus(v: f64, decimals: usize) -> String {
    format!("{v:.decimals$}").replace('-', "\u{2212}")
}
