//! Shared plotting helpers (plotters): an embedded font so text renders on machines without
//! fontconfig (CI), a colour palette, and drawing of floor plans in the metre frame: the
//! vector plan (GeoJSON) or the floor's raster image (`floor_image.png`) as a background.
//!
//! Every plot of the `wipdr` program goes through here, so that they look alike.

use anyhow::{Context, Result};
use image::RgbaImage;
use plotters::coord::ReverseCoordTranslate;
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

/// A floor's raster plan (`floor_image.png`) placed in the metre frame of the waypoints.
///
/// The image spans the floor: `[0, width] x [0, height]` metres (`floor_info.json`), the
/// same box the GeoJSON is mapped onto (the data's README, `$WIPDR_DATA/README.md`). Image rows run from
/// north to south, so row 0 is `y = height` (north at the top) and column 0 is `x = 0`.
/// Transparent pixels are composited over white.
#[derive(Debug, Clone)]
pub struct FloorImage {
    pixels: RgbaImage,
    width_m: f64,
    height_m: f64,
}

impl FloorImage {
    /// The file name of the floor image in a floor folder (ILC layout).
    pub const FILE_NAME: &'static str = "floor_image.png";
    /// Longer images are downsampled to this many pixels on their longer side when loaded.
    pub const MAX_SIDE_PX: u32 = 2048;

    /// Loads `dir/floor_image.png` for a floor of `width_m` x `height_m` metres. `Ok(None)`
    /// when the folder has no image (e.g. the synthetic fixtures); an error names the file
    /// when it exists but cannot be decoded.
    pub fn load(dir: &Path, width_m: f64, height_m: f64) -> Result<Option<Self>> {
        let path = dir.join(Self::FILE_NAME);
        if !path.is_file() {
            return Ok(None);
        }
        let decoded = image::open(&path).with_context(|| format!("decoding {}", path.display()))?;
        Self::from_image(decoded.to_rgba8(), width_m, height_m)
            .with_context(|| format!("placing {} on the floor", path.display()))
            .map(Some)
    }

    /// Places an already decoded image on a floor of `width_m` x `height_m` metres
    /// (downsampling it when its longer side exceeds [`Self::MAX_SIDE_PX`]).
    pub fn from_image(pixels: RgbaImage, width_m: f64, height_m: f64) -> Result<Self> {
        let (w, h) = pixels.dimensions();
        if w == 0 || h == 0 {
            anyhow::bail!("the image is empty ({w} x {h} pixels)");
        }
        if !(width_m.is_finite() && height_m.is_finite() && width_m > 0.0 && height_m > 0.0) {
            anyhow::bail!("the floor size {width_m} x {height_m} m is not positive");
        }
        let long = w.max(h);
        let pixels = if long > Self::MAX_SIDE_PX {
            let scale = Self::MAX_SIDE_PX as f64 / long as f64;
            let (nw, nh) = (
                ((w as f64 * scale).round() as u32).max(1),
                ((h as f64 * scale).round() as u32).max(1),
            );
            image::imageops::resize(&pixels, nw, nh, image::imageops::FilterType::Triangle)
        } else {
            pixels
        };
        Ok(Self {
            pixels,
            width_m,
            height_m,
        })
    }

    /// Image size in pixels (after any downsampling).
    pub fn size_px(&self) -> (u32, u32) {
        self.pixels.dimensions()
    }

    /// The colour at `(x, y)` metres, bilinear between pixel centres and composited over
    /// white; white outside the image.
    pub fn colour_at(&self, x: f64, y: f64) -> [u8; 3] {
        let (w, h) = self.pixels.dimensions();
        // Continuous pixel coordinates, pixel centres at integer + 0.5.
        let u = x / self.width_m * w as f64 - 0.5;
        let v = (self.height_m - y) / self.height_m * h as f64 - 0.5;
        if !(u.is_finite() && v.is_finite())
            || u < -0.5
            || v < -0.5
            || u > w as f64 - 0.5
            || v > h as f64 - 0.5
        {
            return [255, 255, 255];
        }
        let (u0, v0) = (u.floor(), v.floor());
        let (fu, fv) = (u - u0, v - v0);
        let clamp_col = |c: f64| c.clamp(0.0, (w - 1) as f64) as u32;
        let clamp_row = |r: f64| r.clamp(0.0, (h - 1) as f64) as u32;
        let mut rgb = [0.0f64; 3];
        for (dc, dr, weight) in [
            (0.0, 0.0, (1.0 - fu) * (1.0 - fv)),
            (1.0, 0.0, fu * (1.0 - fv)),
            (0.0, 1.0, (1.0 - fu) * fv),
            (1.0, 1.0, fu * fv),
        ] {
            let p = self
                .pixels
                .get_pixel(clamp_col(u0 + dc), clamp_row(v0 + dr));
            let alpha = p[3] as f64 / 255.0;
            for (channel, acc) in rgb.iter_mut().enumerate() {
                let over_white = p[channel] as f64 * alpha + 255.0 * (1.0 - alpha);
                *acc += weight * over_white;
            }
        }
        rgb.map(|c| c.round().clamp(0.0, 255.0) as u8)
    }
}

/// Fills the chart's plotting area with the floor image over the window `x` x `y` metres
/// (the chart's axis ranges), resampled to the area's pixel size.
pub fn draw_floor_image<DB: DrawingBackend>(
    chart: &mut FloorChart<'_, DB>,
    floor_image: &FloorImage,
    x: (f64, f64),
    y: (f64, f64),
) -> Result<()>
where
    DB::ErrorType: 'static,
{
    let (cols, rows) = chart.plotting_area().get_pixel_range();
    let (w, h) = (
        (cols.end - cols.start).max(1) as u32,
        (rows.end - rows.start).max(1) as u32,
    );
    // Each pixel takes the colour at the metres the chart itself maps it to, so the
    // background and everything drawn over it agree to the pixel.
    let spec = chart.plotting_area().as_coord_spec();
    let mut buffer = Vec::with_capacity(w as usize * h as usize * 3);
    for row in 0..h as i32 {
        for col in 0..w as i32 {
            let colour = match spec.reverse_translate((cols.start + col, rows.start + row)) {
                Some((xm, ym)) => floor_image.colour_at(xm, ym),
                None => [255, 255, 255],
            };
            buffer.extend_from_slice(&colour);
        }
    }
    let element = BitMapElement::with_owned_buffer((x.0, y.1), (w, h), buffer)
        .context("floor image buffer has the wrong size")?;
    chart
        .plotting_area()
        .draw(&element)
        .map_err(|e| anyhow::anyhow!("drawing the floor image: {e}"))?;
    Ok(())
}

/// Draws the walls of the vector plan only (thin, half transparent), to lay over an image.
pub fn draw_walls<DB: DrawingBackend>(
    chart: &mut FloorChart<'_, DB>,
    plan: &FloorPlan,
    colour: RGBAColor,
) -> Result<()>
where
    DB::ErrorType: 'static,
{
    chart
        .draw_series(plan.walls.iter().map(|wall| {
            PathElement::new(
                vec![(wall.a.x, wall.a.y), (wall.b.x, wall.b.y)],
                colour.stroke_width(1),
            )
        }))
        .map_err(|e| anyhow::anyhow!("drawing the walls: {e}"))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use image::Rgba;

    impl FloorImage {
        /// The pixel (column, row) that covers the floor point `(x, y)` metres, if inside.
        pub fn pixel_of(&self, x: f64, y: f64) -> Option<(u32, u32)> {
            let (w, h) = self.pixels.dimensions();
            let col = (x / self.width_m * w as f64).floor();
            let row = ((self.height_m - y) / self.height_m * h as f64).floor();
            let inside = col >= 0.0 && row >= 0.0 && col < w as f64 && row < h as f64;
            inside.then_some((col as u32, row as u32))
        }

        /// The RGBA pixel that covers `(x, y)` metres (no interpolation), if inside the image.
        pub fn pixel_at(&self, x: f64, y: f64) -> Option<Rgba<u8>> {
            self.pixel_of(x, y)
                .map(|(col, row)| *self.pixels.get_pixel(col, row))
        }
    }

    /// A 4 x 2 image: top-left red, top-right green, bottom row blue, one transparent pixel.
    fn tiny() -> RgbaImage {
        let mut img = RgbaImage::from_pixel(4, 2, Rgba([0, 0, 255, 255]));
        img.put_pixel(0, 0, Rgba([255, 0, 0, 255]));
        img.put_pixel(3, 0, Rgba([0, 255, 0, 255]));
        img.put_pixel(3, 1, Rgba([0, 0, 0, 0]));
        img
    }

    #[test]
    fn image_rows_are_flipped_so_north_is_row_zero() {
        // Floor 40 m x 20 m: each pixel is 10 m square.
        let f = FloorImage::from_image(tiny(), 40.0, 20.0).unwrap();
        // North-west corner (small x, large y) is the top-left pixel.
        assert_eq!(f.pixel_of(1.0, 19.0), Some((0, 0)));
        assert_eq!(f.colour_at(5.0, 15.0), [255, 0, 0]);
        // North-east is the top-right pixel.
        assert_eq!(f.colour_at(35.0, 15.0), [0, 255, 0]);
        // The south row is blue; its transparent pixel is white.
        assert_eq!(f.colour_at(5.0, 5.0), [0, 0, 255]);
        assert_eq!(f.colour_at(35.0, 5.0), [255, 255, 255]);
        // Outside the floor: white, no pixel.
        assert_eq!(f.pixel_of(-1.0, 5.0), None);
        assert_eq!(f.pixel_of(5.0, 20.5), None);
        assert_eq!(f.colour_at(50.0, 5.0), [255, 255, 255]);
        // Halfway between the red and blue centres: a blend.
        let mid = f.colour_at(5.0, 10.0);
        assert!(mid[0] > 100 && mid[2] > 100, "{mid:?}");
    }

    /// End to end through plotters: the drawn background has the image's top-left (red)
    /// pixel at the north-west of the chart and its top-right (green) at the north-east.
    #[test]
    fn the_drawn_background_has_north_at_the_top() {
        let f = FloorImage::from_image(tiny(), 40.0, 20.0).unwrap();
        let (w, h) = (420u32, 260u32);
        let mut buf = vec![0u8; (w * h * 3) as usize];
        let probes = {
            let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
            root.fill(&WHITE).unwrap();
            let mut chart = floor_chart_in(&root, (0.0, 40.0), (0.0, 20.0), "t").unwrap();
            draw_floor_image(&mut chart, &f, (0.0, 40.0), (0.0, 20.0)).unwrap();
            let probes = [(5.0, 15.0), (35.0, 15.0), (5.0, 5.0)].map(|p| chart.backend_coord(&p));
            root.present().unwrap();
            probes
        };
        let rgb = |(x, y): (i32, i32)| {
            let i = (y as usize * w as usize + x as usize) * 3;
            [buf[i], buf[i + 1], buf[i + 2]]
        };
        // A probe lands on the pixel nearest to its point, a fraction of a pixel off the
        // image pixel's centre, so bilinear sampling may blend in a few levels; a flipped or
        // shifted image would give another colour altogether.
        let near =
            |got: [u8; 3], want: [u8; 3]| got.iter().zip(want).all(|(g, w)| g.abs_diff(w) <= 4);
        for (probe, want, what) in [
            (probes[0], [255, 0, 0], "north-west"),
            (probes[1], [0, 255, 0], "north-east"),
            (probes[2], [0, 0, 255], "south-west"),
        ] {
            assert!(near(rgb(probe), want), "{what}: {:?}", rgb(probe));
        }
    }

    #[test]
    fn a_folder_without_an_image_gives_none_and_a_broken_one_an_error() {
        let dir = tempfile::tempdir().unwrap();
        assert!(FloorImage::load(dir.path(), 10.0, 10.0).unwrap().is_none());
        std::fs::write(dir.path().join(FloorImage::FILE_NAME), b"not a png").unwrap();
        let err = FloorImage::load(dir.path(), 10.0, 10.0).unwrap_err();
        assert!(
            format!("{err:#}").contains(FloorImage::FILE_NAME),
            "{err:#}"
        );
    }

    #[test]
    fn large_images_are_downsampled_and_bad_sizes_rejected() {
        let big = RgbaImage::from_pixel(4096, 1024, Rgba([9, 9, 9, 255]));
        let f = FloorImage::from_image(big, 100.0, 25.0).unwrap();
        assert_eq!(f.size_px(), (FloorImage::MAX_SIDE_PX, 512));
        assert_eq!(f.colour_at(50.0, 12.0), [9, 9, 9]);
        assert!(FloorImage::from_image(tiny(), 0.0, 1.0).is_err());
        assert!(FloorImage::from_image(RgbaImage::new(0, 0), 1.0, 1.0).is_err());
    }

    /// On the real floors the waypoints (surveyed in corridors) must land on the image's
    /// corridors (transparent pixels; units are opaque) far more often with the rows flipped than without: the check that the
    /// image is aligned with the metre frame.
    #[test]
    fn real_waypoints_fall_in_the_image_corridors() {
        let data = match wipdr_io::real_data("ilc20") {
            Ok(data) => data,
            Err(missing) => {
                eprintln!("skipped: {missing}");
                return;
            }
        };
        for floor in ["site1/F1", "site2/F2"] {
            let dir = data.join(floor);
            let (width, height) =
                wipdr_io::floor::read_floor_info(dir.join("floor_info.json"), &Default::default())
                    .unwrap();
            let img = FloorImage::load(&dir, width, height).unwrap().unwrap();
            let mut waypoints = Vec::new();
            for file in wipdr_io::floor::walk_files(&dir).unwrap().iter().take(12) {
                let walk = wipdr_io::trace::read_walk(file).unwrap();
                waypoints.extend(walk.walk.waypoints.iter().map(|w| w.position));
            }
            assert!(
                waypoints.len() > 30,
                "{floor}: {} waypoints",
                waypoints.len()
            );
            // Shops and other units are opaque; corridors are transparent in these images.
            let corridor = |p: Option<Rgba<u8>>| p.is_some_and(|p| p[3] < 128);
            let share = |flip: bool| {
                let hits = waypoints
                    .iter()
                    .filter(|p| {
                        let y = if flip { p.y } else { height - p.y };
                        corridor(img.pixel_at(p.x, y))
                    })
                    .count();
                hits as f64 / waypoints.len() as f64
            };
            let (aligned, unflipped) = (share(true), share(false));
            eprintln!("{floor}: corridor share {aligned:.3} aligned, {unflipped:.3} unflipped");
            assert!(
                aligned > 0.8,
                "{floor}: only {aligned:.3} of waypoints in corridors"
            );
            assert!(
                aligned > unflipped + 0.3,
                "{floor}: {aligned:.3} vs {unflipped:.3}"
            );
        }
    }
}
