//! Plots of an evaluation: trajectories against truth over the floor image (or the vector plan
//! when a floor has no image), the error CDF per scheme, and the error against time for a walk.

use crate::plotting::{self, FONT_FAMILY, FloorImage};
use anyhow::{Result, anyhow};
use plotters::prelude::*;
use std::path::Path;
use wipdr_eval::pipeline::{self, EvalConfig, FloorInput, PreparedWalk};
use wipdr_eval::report::EvalReport;

/// How the trajectory plots are drawn.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PlotOptions {
    /// How many walks per floor get a trajectory and an error-against-time plot.
    pub walks_per_floor: usize,
    /// Draw the floor image (`floor_image.png`) as the background when the floor has one.
    pub floor_image: bool,
    /// Lay the vector plan's walls over the image (thin, half transparent).
    pub walls_over_image: bool,
    /// Plot the walks where this scheme's mean error is largest (instead of the first ones).
    pub worst_of: Option<String>,
}

impl Default for PlotOptions {
    fn default() -> Self {
        Self {
            walks_per_floor: 2,
            floor_image: true,
            walls_over_image: true,
            worst_of: None,
        }
    }
}

/// Writes every plot; returns how many files were written.
pub fn write_all(
    dir: &Path,
    floors: &[FloorInput],
    prepared: &[PreparedWalk],
    cfg: &EvalConfig,
    schemes: &[String],
    report: &EvalReport,
    options: &PlotOptions,
) -> Result<usize> {
    std::fs::create_dir_all(dir)?;
    let mut n = 0;
    error_cdf(&dir.join("error-cdf.png"), report, schemes)?;
    n += 1;
    for (fi, floor) in floors.iter().enumerate() {
        let mut walks: Vec<&PreparedWalk> =
            prepared.iter().filter(|p| p.floor_index == fi).collect();
        if let Some(scheme) = &options.worst_of {
            let mean_of = |pw: &PreparedWalk| {
                report
                    .walks
                    .iter()
                    .find(|w| &w.scheme == scheme && w.walk == pw.walk && w.floor == floor.label)
                    .map(|w| wipdr_core::stats::ErrorStats::from_errors(&w.score.values()).mean)
                    .filter(|m| m.is_finite())
                    .unwrap_or(f64::NEG_INFINITY)
            };
            walks.sort_by(|a, b| mean_of(b).total_cmp(&mean_of(a)));
        }
        walks.truncate(options.walks_per_floor);
        if walks.is_empty() {
            continue;
        }
        let background = if options.floor_image {
            floor_image_of(floor)
        } else {
            None
        };
        for pw in walks {
            let tracks = pipeline::tracks_of(floor, pw, cfg, schemes)?;
            let stem = format!("{}-{}", floor.label.replace('/', "-"), pw.walk);
            trajectories(
                &dir.join(format!("{stem}-trajectories.png")),
                floor,
                pw,
                &tracks,
                background.as_ref(),
                options.walls_over_image,
            )?;
            error_over_time(&dir.join(format!("{stem}-error.png")), pw, report, schemes)?;
            n += 2;
        }
    }
    Ok(n)
}

/// The floor's image, or `None` (with a warning when it exists but cannot be used): the
/// plots then fall back to the vector plan.
fn floor_image_of(floor: &FloorInput) -> Option<FloorImage> {
    let plan = &floor.data.plan;
    let dir = floor.dir.as_ref()?;
    match FloorImage::load(dir, plan.width, plan.height) {
        Ok(found) => {
            match &found {
                Some(image) => {
                    tracing::debug!(floor = %floor.label, size_px = ?image.size_px(), "floor image")
                }
                None => {
                    tracing::info!(floor = %floor.label, "no floor image: drawing the vector plan")
                }
            }
            found
        }
        Err(e) => {
            tracing::warn!(floor = %floor.label, "floor image unusable ({e:#}): drawing the vector plan");
            None
        }
    }
}

fn error_cdf(path: &Path, report: &EvalReport, schemes: &[String]) -> Result<()> {
    plotting::init_fonts();
    let root = BitMapBackend::new(path, (1000, 700)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| anyhow!("{e}"))?;
    let mut curves = Vec::new();
    let mut xmax: f64 = 1.0;
    for s in schemes {
        let mut e: Vec<f64> = report
            .walks
            .iter()
            .filter(|w| &w.scheme == s)
            .flat_map(|w| w.score.values())
            .filter(|v| v.is_finite())
            .collect();
        e.sort_by(f64::total_cmp);
        if let Some(p95) = e.get(e.len() * 95 / 100) {
            xmax = xmax.max(*p95 * 1.3);
        }
        curves.push((s.clone(), e));
    }
    let mut chart = ChartBuilder::on(&root)
        .caption("Error CDF at waypoints (pooled)", (FONT_FAMILY, 22))
        .margin(15)
        .x_label_area_size(40)
        .y_label_area_size(50)
        .build_cartesian_2d(0.0..xmax, 0.0..1.0)
        .map_err(|e| anyhow!("{e}"))?;
    chart
        .configure_mesh()
        .x_desc("error (m)")
        .y_desc("fraction of waypoints")
        .label_style((FONT_FAMILY, 14))
        .draw()
        .map_err(|e| anyhow!("{e}"))?;
    for (i, (name, e)) in curves.iter().enumerate() {
        if e.is_empty() {
            continue;
        }
        let n = e.len() as f64;
        let colour = plotting::palette(i);
        chart
            .draw_series(LineSeries::new(
                e.iter()
                    .enumerate()
                    .map(|(k, &v)| (v.min(xmax), (k + 1) as f64 / n)),
                colour.stroke_width(2),
            ))
            .map_err(|e| anyhow!("{e}"))?
            .label(name.clone())
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(3))
            });
    }
    finish(chart, &root, path, SeriesLabelPosition::LowerRight)
}

fn trajectories(
    path: &Path,
    floor: &FloorInput,
    walk: &PreparedWalk,
    tracks: &[(String, wipdr_eval::scoring::Track)],
    background: Option<&FloorImage>,
    walls_over_image: bool,
) -> Result<()> {
    let plan = &floor.data.plan;
    // Zoom to the walk: its waypoints and fixes, with a margin, inside the floor.
    let (mut lo, mut hi) = ((f64::MAX, f64::MAX), (f64::MIN, f64::MIN));
    let pts = walk
        .waypoints
        .iter()
        .map(|w| w.position)
        .chain(walk.observations.iter().map(|o| o.estimate));
    for p in pts.filter(|p| p.x.is_finite() && p.y.is_finite()) {
        lo = (lo.0.min(p.x), lo.1.min(p.y));
        hi = (hi.0.max(p.x), hi.1.max(p.y));
    }
    let margin = 10.0;
    let (x0, x1) = window_of(lo.0 - margin, hi.0 + margin, plan.width);
    let (y0, y1) = window_of(lo.1 - margin, hi.1 + margin, plan.height);
    let (x0, x1, y0, y1) = if x1 > x0 && y1 > y0 {
        (x0, x1, y0, y1)
    } else {
        (0.0, plan.width, 0.0, plan.height)
    };
    let (w, h) = plotting::floor_canvas_size(x1 - x0, y1 - y0, 1400);
    let root = BitMapBackend::new(path, (w, h)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| anyhow!("{e}"))?;
    let caption = format!("{} {} — schemes against truth", floor.label, walk.walk);
    let mut chart = plotting::floor_chart_in(&root, (x0, x1), (y0, y1), &caption)?;
    match background {
        Some(image) => {
            plotting::draw_floor_image(&mut chart, image, (x0, x1), (y0, y1))?;
            if walls_over_image {
                plotting::draw_walls(&mut chart, plan, RGBColor(60, 60, 60).mix(0.45))?;
            }
        }
        None => plotting::draw_floor_plan(&mut chart, plan)?,
    }
    let truth: Vec<(f64, f64)> = walk
        .waypoints
        .iter()
        .map(|p| (p.position.x, p.position.y))
        .collect();
    chart
        .draw_series(std::iter::once(PathElement::new(
            truth.clone(),
            BLACK.stroke_width(3),
        )))
        .map_err(|e| anyhow!("{e}"))?
        .label("truth (waypoints)")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK.stroke_width(3)));
    chart
        .draw_series(truth.iter().map(|&p| Circle::new(p, 4, BLACK.filled())))
        .map_err(|e| anyhow!("{e}"))?;
    for (i, (name, track)) in tracks.iter().enumerate() {
        let colour = plotting::palette(i);
        let pts: Vec<(f64, f64)> = track
            .iter()
            .map(|tp| tp.position)
            .filter(|p| p.x.is_finite() && p.y.is_finite())
            .map(|p| {
                (
                    p.x.clamp(-50.0, plan.width + 50.0),
                    p.y.clamp(-50.0, plan.height + 50.0),
                )
            })
            .collect();
        chart
            .draw_series(std::iter::once(PathElement::new(
                pts,
                colour.stroke_width(2),
            )))
            .map_err(|e| anyhow!("{e}"))?
            .label(name.clone())
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(3))
            });
    }
    finish(chart, &root, path, SeriesLabelPosition::UpperRight)
}

/// Shortest side of a trajectory window, metres: a short walk still shows its surroundings
/// (and the floor image is not blown up past recognition).
const MIN_WINDOW_M: f64 = 50.0;

/// The window `[lo, hi]` widened about its centre to [`MIN_WINDOW_M`] and kept inside
/// `[0, extent]` (as far as the floor is large enough).
fn window_of(lo: f64, hi: f64, extent: f64) -> (f64, f64) {
    let want = MIN_WINDOW_M.min(extent);
    let (mut lo, mut hi) = (lo, hi);
    if hi - lo < want {
        let centre = 0.5 * (lo + hi);
        lo = centre - 0.5 * want;
        hi = centre + 0.5 * want;
    }
    // Shift back inside the floor before clipping, so the window keeps its size.
    if lo < 0.0 {
        hi -= lo;
        lo = 0.0;
    }
    if hi > extent {
        lo -= hi - extent;
        hi = extent;
    }
    (lo.max(0.0), hi.min(extent))
}

fn error_over_time(
    path: &Path,
    walk: &PreparedWalk,
    report: &EvalReport,
    schemes: &[String],
) -> Result<()> {
    plotting::init_fonts();
    let t0 = walk.waypoints.first().map(|w| w.t).unwrap_or(0);
    let series: Vec<(String, Vec<(f64, f64)>)> = schemes
        .iter()
        .filter_map(|s| {
            report
                .walks
                .iter()
                .find(|w| &w.scheme == s && w.walk == walk.walk && w.floor == walk.floor)
                .map(|w| {
                    (
                        s.clone(),
                        w.score
                            .errors
                            .iter()
                            .map(|&(t, e, _)| ((t - t0) as f64 / 1000.0, e))
                            .collect(),
                    )
                })
        })
        .collect();
    let tmax = series
        .iter()
        .flat_map(|s| s.1.iter().map(|p| p.0))
        .fold(1.0, f64::max);
    let emax = series
        .iter()
        .flat_map(|s| s.1.iter().map(|p| p.1))
        .fold(1.0, f64::max);
    let root = BitMapBackend::new(path, (1000, 600)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| anyhow!("{e}"))?;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            format!("{} {} — error at waypoints", walk.floor, walk.walk),
            (FONT_FAMILY, 20),
        )
        .margin(15)
        .x_label_area_size(40)
        .y_label_area_size(50)
        .build_cartesian_2d(0.0..tmax * 1.02, 0.0..emax * 1.05)
        .map_err(|e| anyhow!("{e}"))?;
    chart
        .configure_mesh()
        .x_desc("time since the first waypoint (s)")
        .y_desc("error (m)")
        .label_style((FONT_FAMILY, 14))
        .draw()
        .map_err(|e| anyhow!("{e}"))?;
    for (i, (name, pts)) in series.iter().enumerate() {
        let colour = plotting::palette(i);
        chart
            .draw_series(LineSeries::new(pts.clone(), colour.stroke_width(2)).point_size(3))
            .map_err(|e| anyhow!("{e}"))?
            .label(name.clone())
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(3))
            });
    }
    finish(chart, &root, path, SeriesLabelPosition::UpperLeft)
}

/// Draws the legend and writes the picture.
fn finish<'a, DB: DrawingBackend + 'a>(
    mut chart: plotting::FloorChart<'a, DB>,
    root: &DrawingArea<DB, plotters::coord::Shift>,
    path: &Path,
    position: SeriesLabelPosition,
) -> Result<()>
where
    DB::ErrorType: 'static,
{
    chart
        .configure_series_labels()
        .position(position)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font((FONT_FAMILY, 14))
        .draw()
        .map_err(|e| anyhow!("{e}"))?;
    root.present()
        .map_err(|e| anyhow!("writing {}: {e}", path.display()))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn windows_keep_a_minimum_size_inside_the_floor() {
        // A short walk in the middle: widened about its centre.
        assert_eq!(window_of(90.0, 110.0, 200.0), (75.0, 125.0));
        // Near an edge: shifted inside, same size.
        assert_eq!(window_of(-10.0, 10.0, 200.0), (0.0, 50.0));
        assert_eq!(window_of(190.0, 210.0, 200.0), (150.0, 200.0));
        // A long walk keeps its extent, clipped to the floor.
        assert_eq!(window_of(-5.0, 120.0, 100.0), (0.0, 100.0));
        // A floor smaller than the minimum: the whole floor.
        assert_eq!(window_of(10.0, 12.0, 30.0), (0.0, 30.0));
    }
}
