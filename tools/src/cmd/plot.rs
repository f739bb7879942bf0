//! `wipdr plot`: pictures of floors and walks.

use crate::plotting::{self, FONT_FAMILY};
use anyhow::Result;
use plotters::prelude::*;
use std::path::PathBuf;

/// Arguments of `wipdr plot`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// What to draw.
    #[command(subcommand)]
    what: What,
}

#[derive(Debug, clap::Subcommand)]
enum What {
    /// A floor folder: outline and units, with every walk's waypoints and path drawn on it.
    Floor(FloorArgs),
}

/// Arguments of `wipdr plot floor`.
#[derive(Debug, clap::Args)]
struct FloorArgs {
    /// The floor folder (with `path_data_files/`, `floor_info.json`, `geojson_map.json`).
    dir: PathBuf,
    /// Output PNG (or SVG if the name ends in `.svg`).
    #[arg(long)]
    out: PathBuf,
    /// Pixels of the longer side.
    #[arg(long, default_value_t = 1600)]
    size: u32,
}

/// Runs the subcommand.
pub fn run(args: Args) -> Result<()> {
    match args.what {
        What::Floor(a) => plot_floor(a),
    }
}

fn plot_floor(a: FloorArgs) -> Result<()> {
    let floor = crate::data::load_floor_data(&a.dir)?;
    plotting::ensure_parent(&a.out)?;
    let (w, h) = plotting::floor_canvas_size(floor.width, floor.height, a.size);
    let caption = format!(
        "{} — {} walks, waypoints and paths",
        a.dir.display(),
        floor.walks.len()
    );
    let is_svg = a
        .out
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("svg"));
    if is_svg {
        let root = SVGBackend::new(&a.out, (w, h)).into_drawing_area();
        draw(&root, &floor, &caption)?;
        root.present().map_err(|e| anyhow::anyhow!("{e}"))?;
    } else {
        let root = BitMapBackend::new(&a.out, (w, h)).into_drawing_area();
        draw(&root, &floor, &caption)?;
        root.present()
            .map_err(|e| anyhow::anyhow!("writing {}: {e}", a.out.display()))?;
    }
    println!("wrote {}", a.out.display());
    Ok(())
}

fn draw<DB: DrawingBackend>(
    root: &DrawingArea<DB, plotters::coord::Shift>,
    floor: &wipdr_io::floor::FloorData,
    caption: &str,
) -> Result<()>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE).map_err(|e| anyhow::anyhow!("{e}"))?;
    let mut chart = plotting::floor_chart(root, &floor.plan, caption)?;
    plotting::draw_floor_plan(&mut chart, &floor.plan)?;
    let err = |e| anyhow::anyhow!("drawing walks: {e}");
    for (i, pw) in floor.walks.iter().enumerate() {
        let colour = plotting::palette(i);
        let pts: Vec<(f64, f64)> = pw
            .walk
            .waypoints
            .iter()
            .map(|w| (w.position.x, w.position.y))
            .collect();
        chart
            .draw_series(std::iter::once(PathElement::new(
                pts.clone(),
                colour.mix(0.8).stroke_width(2),
            )))
            .map_err(err)?;
        chart
            .draw_series(pts.iter().map(|&p| Circle::new(p, 3, colour.filled())))
            .map_err(err)?;
    }
    let legend = format!(
        "{:.0} x {:.0} m, {} units; lines: waypoint paths, one colour per walk",
        floor.width,
        floor.height,
        floor.plan.units.len()
    );
    root.draw(&Text::new(legend, (60, 40), (FONT_FAMILY, 14).into_font()))
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    Ok(())
}
