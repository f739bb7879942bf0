//! Shared plotting helpers (plotters): an embedded font so text renders on machines without
//! fontconfig (CI), a colour palette, and drawing of floor plans in the metre frame.
//!
//! Every plot of the `wipdr` program goes through here, so that they look alike.

use anyhow::{Context, Result};
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use std::path::Path;
use std::sync::Once;
use wipdr_core::{FloorPlan, Point2};

/// DejaVu Sans Condensed (Bitstream Vera / DejaVu licence, see `assets/DejaVu-LICENSE.txt`).
static FONT: &[u8] = include_bytes!("../assets/DejaVuSansCondensed.ttf");
static FONT_INIT: Once = Once::new();

/// The font family name to use in every text style.
pub const FONT_FAMILY: &str = "sans-serif";

/// Registers the embedded font with plotters (idempotent).
pub fn init_fonts() {
    FONT_INIT.call_once(|| {
        for style in [FontStyle::Normal, FontStyle::Bold] {
            if plotters::style::register_font(FONT_FAMILY, style, FONT).is_err() {
                tracing::warn!("embedded font could not be registered; text may be missing");
            }
        }
    });
}

/// A qualitative palette (Tableau 10 plus two), cycled.
pub fn palette(i: usize) -> RGBColor {
    const P: [RGBColor; 12] = [
        RGBColor(31, 119, 180),
        RGBColor(255, 127, 14),
        RGBColor(44, 160, 44),
        RGBColor(214, 39, 40),
        RGBColor(148, 103, 189),
        RGBColor(140, 86, 75),
        RGBColor(227, 119, 194),
        RGBColor(127, 127, 127),
        RGBColor(188, 189, 34),
        RGBColor(23, 190, 207),
        RGBColor(128, 0, 0),
        RGBColor(255, 215, 0),
    ];
    P[i % P.len()]
}

/// A chart with metre (or any f64) axes: floors (x east, y north: north at the top), CDFs.
pub type FloorChart<'a, DB> = ChartContext<'a, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// Pixel size for a floor of `width` x `height` metres with the longer side `long_px`.
pub fn floor_canvas_size(width: f64, height: f64, long_px: u32) -> (u32, u32) {
    let (w, h) = (width.max(1.0), height.max(1.0));
    if w >= h {
        (
            long_px,
            ((long_px as f64) * h / w).round().max(200.0) as u32 + 60,
        )
    } else {
        (
            ((long_px as f64) * w / h).round().max(200.0) as u32,
            long_px + 60,
        )
    }
}

/// Builds a chart over `[0, width] x [0, height]` with a caption and metre axes.
pub fn floor_chart<'a, DB: DrawingBackend>(
    root: &'a DrawingArea<DB, plotters::coord::Shift>,
    plan: &FloorPlan,
    caption: &str,
) -> Result<FloorChart<'a, DB>>
where
    DB::ErrorType: 'static,
{
    floor_chart_in(root, (0.0, plan.width), (0.0, plan.height), caption)
}

/// Like [`floor_chart`] over a window `x` x `y` of the floor (metres), e.g. one walk's extent.
pub fn floor_chart_in<'a, DB: DrawingBackend>(
    root: &'a DrawingArea<DB, plotters::coord::Shift>,
    x: (f64, f64),
    y: (f64, f64),
    caption: &str,
) -> Result<FloorChart<'a, DB>>
where
    DB::ErrorType: 'static,
{
    init_fonts();
    let mut chart = ChartBuilder::on(root)
        .caption(caption, (FONT_FAMILY, 22))
        .margin(10)
        .x_label_area_size(30)
        .y_label_area_size(40)
        .build_cartesian_2d(x.0..x.1, y.0..y.1)
        .map_err(|e| anyhow::anyhow!("chart: {e}"))?;
    chart
        .configure_mesh()
        .disable_mesh()
        .x_desc("x (m)")
        .y_desc("y (m)")
        .label_style((FONT_FAMILY, 13))
        .draw()
        .map_err(|e| anyhow::anyhow!("axes: {e}"))?;
    Ok(chart)
}

/// Draws the floor outline (light fill), units (shops: tan with a darker edge).
pub fn draw_floor_plan<DB: DrawingBackend>(
    chart: &mut FloorChart<'_, DB>,
    plan: &FloorPlan,
) -> Result<()>
where
    DB::ErrorType: 'static,
{
    let ring = |r: &[Point2]| r.iter().map(|p| (p.x, p.y)).collect::<Vec<_>>();
    let err = |e| anyhow::anyhow!("drawing the floor plan: {e}");
    for poly in &plan.outline {
        chart
            .draw_series(std::iter::once(Polygon::new(
                ring(&poly.exterior),
                RGBColor(245, 245, 240).filled(),
            )))
            .map_err(err)?;
    }
    for unit in &plan.units {
        chart
            .draw_series(std::iter::once(Polygon::new(
                ring(&unit.polygon.exterior),
                RGBColor(222, 205, 170).filled(),
            )))
            .map_err(err)?;
    }
    for wall in &plan.walls {
        chart
            .draw_series(std::iter::once(PathElement::new(
                vec![(wall.a.x, wall.a.y), (wall.b.x, wall.b.y)],
                RGBColor(110, 100, 90).stroke_width(1),
            )))
            .map_err(err)?;
    }
    Ok(())
}

/// Creates the parent folder of `out` if needed.
pub fn ensure_parent(out: &Path) -> Result<()> {
    if let Some(parent) = out.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent)
            .with_context(|| format!("creating folder {}", parent.display()))?;
    }
    Ok(())
}
