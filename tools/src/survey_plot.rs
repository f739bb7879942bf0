//! `wipdr inspect MODEL --plot coverage.png`: where a site model is weak, floor by floor.
//!
//! One row per floor, three panels: the Wi-Fi error expected there (the leave-one-walk-out
//! errors saved by `wipdr fit`, interpolated), the distance to the nearest measured
//! reference point, and the APs heard at that reference point. Every panel shares one
//! colour convention: red is where more survey data would help (large error, far from
//! data, few APs), green where the model is strong; grey is no data (no leave-one-out scan
//! within the interpolation radius, no reference point within the gap distance for the APs);
//! white lies outside the floor outline.

use crate::plotting::{self, FONT_FAMILY, FloorChart};
use anyhow::{Context, Result, anyhow};
use plotters::prelude::*;
use std::path::Path;
use wipdr_core::FloorPlan;
use wipdr_positioning::site_model::FloorSurvey;

/// Pixels of one panel's width (chart and colour bar).
const PANEL_W: u32 = 620;
/// Pixels of a colour bar's column.
const BAR_W: u32 = 90;
/// Pixels of the figure's title band.
const TITLE_H: u32 = 50;
/// Colour of a cell inside the floor without a value.
const NO_DATA: RGBColor = RGBColor(215, 215, 215);

/// A colour scale from `lo` to `hi`; `good_high` reverses it (many APs is good).
#[derive(Debug, Clone, Copy)]
pub struct Scale {
    /// Value at the scale's low end.
    pub lo: f64,
    /// Value at the scale's high end (larger values take its colour).
    pub hi: f64,
    /// Whether high values are good (green) rather than bad (red).
    pub good_high: bool,
}

impl Scale {
    /// The colour of `v`: green (good) through yellow to red (bad), clamped to the ends.
    pub fn colour(&self, v: f64) -> RGBColor {
        // ColorBrewer RdYlGn, 5 classes, from good to bad.
        const STOPS: [(f64, f64, f64); 5] = [
            (26.0, 150.0, 65.0),
            (166.0, 217.0, 106.0),
            (255.0, 255.0, 191.0),
            (253.0, 174.0, 97.0),
            (215.0, 25.0, 28.0),
        ];
        let span = self.hi - self.lo;
        let mut f = if span > 0.0 && v.is_finite() {
            ((v - self.lo) / span).clamp(0.0, 1.0)
        } else {
            0.0
        };
        if self.good_high {
            f = 1.0 - f;
        }
        let x = f * (STOPS.len() - 1) as f64;
        // In [0, 4]: the cast cannot overflow.
        let i = (x.floor() as usize).min(STOPS.len() - 2);
        let t = x - i as f64;
        let (a, b) = (STOPS[i], STOPS[i + 1]);
        let mix = |p: f64, q: f64| (p + (q - p) * t).round().clamp(0.0, 255.0) as u8;
        RGBColor(mix(a.0, b.0), mix(a.1, b.1), mix(a.2, b.2))
    }
}

/// One panel's content: the cell values and how to show them.
struct Layer<'a> {
    title: String,
    unit: &'static str,
    values: Vec<Option<f64>>,
    scale: Scale,
    survey: &'a FloorSurvey,
}

/// The three colour scales of a figure, shared by every floor so that floors compare.
#[derive(Debug, Clone, Copy)]
pub struct Scales {
    /// Expected Wi-Fi error, metres.
    pub error: Scale,
    /// Distance to the nearest reference point, metres.
    pub distance: Scale,
    /// APs heard.
    pub aps: Scale,
}

/// The figure's pixel size for `surveys`.
pub fn figure_size(surveys: &[FloorSurvey]) -> (u32, u32) {
    let h: u32 = surveys.iter().map(row_height).sum();
    (3 * PANEL_W, TITLE_H + h.max(1))
}

/// Pixels of the row of a floor: the chart keeps the floor's aspect ratio, 250 to 900 px.
fn row_height(s: &FloorSurvey) -> u32 {
    let (cols, rows) = s.grid.dims();
    let aspect = rows as f64 / cols.max(1) as f64;
    let chart_w = f64::from(PANEL_W - BAR_W - 50);
    // Clamped to [250, 900] before the cast.
    (chart_w * aspect + 80.0).clamp(250.0, 900.0) as u32
}

/// Draws the survey figure of `surveys` (one row per floor) to `out` (PNG); the APs heard
/// are shown only within `gap_m` of their reference point.
pub fn draw(
    out: &Path,
    title: &str,
    surveys: &[FloorSurvey],
    plan: Option<&FloorPlan>,
    scales: Scales,
    gap_m: f64,
) -> Result<(u32, u32)> {
    plotting::ensure_parent(out)?;
    plotting::init_fonts();
    let size = figure_size(surveys);
    let root = BitMapBackend::new(out, size).into_drawing_area();
    let e = |e| anyhow!("drawing {}: {e}", out.display());
    root.fill(&WHITE).map_err(e)?;
    let (head, mut rest) = root.split_vertically(TITLE_H);
    head.draw(&Text::new(
        title.to_string(),
        (12, 14),
        (FONT_FAMILY, 20).into_font(),
    ))
    .map_err(e)?;
    for s in surveys {
        let (row, below) = rest.split_vertically(row_height(s));
        rest = below;
        let floor = s.floor.map_or(String::new(), |f| format!("floor {f}: "));
        let panels = row.split_evenly((1, 3));
        let layers = [
            Layer {
                title: format!("{floor}expected Wi-Fi error (leave one walk out)"),
                unit: "m",
                values: s.expected_error_m.clone(),
                scale: scales.error,
                survey: s,
            },
            Layer {
                title: format!("{floor}distance to nearest reference point"),
                unit: "m",
                values: s.distance_m.clone(),
                scale: scales.distance,
                survey: s,
            },
            Layer {
                title: format!("{floor}APs heard (nearest reference point)"),
                unit: "APs",
                // Beyond the gap distance the nearest reference point says nothing of the
                // place: grey, as the error panel's blanks.
                values: s
                    .aps_heard
                    .iter()
                    .zip(&s.distance_m)
                    .map(|(a, d)| match (a, d) {
                        (Some(a), Some(d)) if *d <= gap_m => Some(f64::from(*a)),
                        _ => None,
                    })
                    .collect(),
                scale: scales.aps,
                survey: s,
            },
        ];
        for (panel, layer) in panels.iter().zip(&layers) {
            draw_panel(panel, layer, plan)?;
        }
    }
    root.present()
        .map_err(|e| anyhow!("writing {}: {e}", out.display()))?;
    Ok(size)
}

fn draw_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    layer: &Layer<'_>,
    plan: Option<&FloorPlan>,
) -> Result<()>
where
    DB::ErrorType: 'static,
{
    let (w, _) = area.dim_in_pixel();
    let (map_area, bar_area) = area.split_horizontally(w.saturating_sub(BAR_W));
    let s = layer.survey;
    let grid = &s.grid;
    let (lo, hi) = (grid.origin(), grid.far_corner());
    let mut chart = plotting::floor_chart_in(&map_area, (lo.x, hi.x), (lo.y, hi.y), &layer.title)
        .context("panel")?;
    let half = grid.cell_m() / 2.0;
    let cells = (0..grid.len()).filter(|&i| s.inside[i]).map(|i| {
        let c = grid.centre_of_index(i);
        let colour = layer.values[i].map_or(NO_DATA, |v| layer.scale.colour(v));
        Rectangle::new(
            [(c.x - half, c.y - half), (c.x + half, c.y + half)],
            colour.filled(),
        )
    });
    let err = |e| anyhow!("drawing the raster: {e}");
    chart.draw_series(cells).map_err(err)?;
    if let Some(plan) = plan {
        draw_outline(&mut chart, plan)?;
        plotting::draw_walls(&mut chart, plan, RGBColor(60, 60, 60).mix(0.6))?;
    }
    chart
        .draw_series(
            s.reference_points
                .iter()
                .map(|p| Circle::new((p.x, p.y), 1, BLACK.mix(0.5).filled())),
        )
        .map_err(err)?;
    draw_colour_bar(&bar_area, layer.scale, layer.unit)
}

fn draw_outline<DB: DrawingBackend>(chart: &mut FloorChart<'_, DB>, plan: &FloorPlan) -> Result<()>
where
    DB::ErrorType: 'static,
{
    chart
        .draw_series(plan.outline.iter().map(|poly| {
            let mut ring: Vec<(f64, f64)> = poly.exterior.iter().map(|p| (p.x, p.y)).collect();
            if let Some(&first) = ring.first() {
                ring.push(first);
            }
            PathElement::new(ring, BLACK.stroke_width(1))
        }))
        .map_err(|e| anyhow!("drawing the outline: {e}"))?;
    Ok(())
}

/// A vertical colour bar with the scale's values and unit (the top end reads "or more").
fn draw_colour_bar<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    scale: Scale,
    unit: &str,
) -> Result<()>
where
    DB::ErrorType: 'static,
{
    let e = |e| anyhow!("drawing the colour bar: {e}");
    let mut chart = ChartBuilder::on(area)
        .margin_top(40)
        .margin_bottom(40)
        .margin_right(8)
        .y_label_area_size(45)
        .build_cartesian_2d(0.0..1.0, scale.lo..scale.hi)
        .map_err(e)?;
    chart
        .configure_mesh()
        .disable_mesh()
        .disable_x_axis()
        .y_labels(6)
        .y_desc(format!("{unit} (top: or more)"))
        .label_style((FONT_FAMILY, 12))
        .axis_desc_style((FONT_FAMILY, 12))
        .draw()
        .map_err(e)?;
    const STEPS: usize = 64;
    let step = (scale.hi - scale.lo) / STEPS as f64;
    chart
        .draw_series((0..STEPS).map(|k| {
            let v0 = scale.lo + step * k as f64;
            Rectangle::new(
                [(0.0, v0), (1.0, v0 + step)],
                scale.colour(v0 + step / 2.0).filled(),
            )
        }))
        .map_err(e)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_scale_runs_from_green_to_red_and_clamps() {
        let bad_high = Scale {
            lo: 0.0,
            hi: 10.0,
            good_high: false,
        };
        assert_eq!(bad_high.colour(0.0), RGBColor(26, 150, 65));
        assert_eq!(bad_high.colour(10.0), RGBColor(215, 25, 28));
        assert_eq!(bad_high.colour(50.0), bad_high.colour(10.0));
        assert_eq!(bad_high.colour(-3.0), bad_high.colour(0.0));
        assert_eq!(bad_high.colour(5.0), RGBColor(255, 255, 191));
        assert_eq!(bad_high.colour(f64::NAN), bad_high.colour(0.0));
        let good_high = Scale {
            good_high: true,
            ..bad_high
        };
        assert_eq!(good_high.colour(10.0), RGBColor(26, 150, 65));
    }
}
