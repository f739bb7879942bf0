//! `wipdr inspect PATH...`: summarise walk files or floor folders with their parse reports.

use anyhow::Context;
use std::collections::HashSet;
use std::path::{Path, PathBuf};
use std::time::Instant;
use wipdr_core::imu::mean_rate_hz;
use wipdr_core::{Bssid, Walk};
use wipdr_io::cache::CacheOutcome;
use wipdr_io::floor::{FloorData, ReadOptions};
use wipdr_io::trace::{self, ParseReport, ParsedWalk};

/// Arguments of `wipdr inspect`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Walk files (`.txt`, `.txt.gz`), floor folders (with `floor_info.json`,
    /// `geojson_map.json` and `path_data_files/`) or site model files (`wipdr fit`).
    #[arg(required = true)]
    pub paths: Vec<PathBuf>,
    /// Only the floor summary, not one line per walk.
    #[arg(long)]
    pub brief: bool,
    /// Resource limits as a TOML file (fields of `wipdr_io::Limits`; missing ones default).
    #[arg(long)]
    pub limits: Option<PathBuf>,
    /// For a site model: draw where it is weak to this PNG, one row per floor (expected
    /// Wi-Fi error from the leave-one-walk-out errors `wipdr fit` saved, distance to the
    /// nearest reference point, APs heard there).
    #[arg(long, value_name = "PNG")]
    pub plot: Option<PathBuf>,
    /// For a site model: the distance (metres) beyond which a place counts as a coverage
    /// gap in the summary (and the top of the distance colour bar is twice it).
    #[arg(long, default_value_t = 10.0, value_name = "M")]
    pub gap_m: f64,
}

/// Runs the subcommand.
pub fn run(args: Args) -> anyhow::Result<()> {
    let mut options = ReadOptions::default();
    if let Some(path) = &args.limits {
        let text =
            std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
        options.limits =
            toml::from_str(&text).with_context(|| format!("parsing {}", path.display()))?;
        if let Err(e) = options.limits.validate() {
            anyhow::bail!("{}: {e}", path.display());
        }
    }
    if !(args.gap_m.is_finite() && args.gap_m > 0.0) {
        anyhow::bail!("--gap-m {}: give a distance > 0 m", args.gap_m);
    }
    if args.plot.is_some() && !args.paths.iter().any(|p| is_site_model(p)) {
        anyhow::bail!("--plot draws a site model: give a model file (`wipdr fit` makes one)");
    }
    if args.plot.is_some() && args.paths.len() > 1 {
        anyhow::bail!("--plot draws one site model: give one path");
    }
    let started = Instant::now();
    for path in &args.paths {
        if path.is_dir() {
            inspect_floor(path, &args, &options)?;
        } else if is_site_model(path) {
            inspect_model(path, &args)?;
        } else {
            inspect_walk(path, &options)?;
        }
    }
    if args.paths.len() > 1 {
        println!(
            "all {} paths in {:.2} s",
            args.paths.len(),
            started.elapsed().as_secs_f64()
        );
    }
    Ok(())
}

/// Whether `path` is (or claims to be) a site model: named `*.wipdr`, or starting with the
/// model file's magic.
fn is_site_model(path: &Path) -> bool {
    use std::io::Read;
    if path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("wipdr"))
    {
        return true;
    }
    let mut head = [0u8; 8];
    std::fs::File::open(path)
        .and_then(|mut f| f.read_exact(&mut head))
        .is_ok_and(|()| &head == wipdr_positioning::site_model::MAGIC)
}

/// Prints what a site model holds: floors, reference points, APs, config, provenance.
fn inspect_model(path: &Path, args: &Args) -> anyhow::Result<()> {
    let t0 = Instant::now();
    let model = wipdr_positioning::SiteModel::load(path)?;
    let elapsed = t0.elapsed().as_secs_f64();
    let d = model.data();
    let map = model.radio_map();
    let bytes = std::fs::metadata(path).map(|m| m.len()).unwrap_or(0);
    println!(
        "{}: site model {:?}, {:.2} MB, loaded in {:.3} s",
        path.display(),
        d.name,
        bytes as f64 / 1e6,
        elapsed
    );
    println!(
        "  floors: {}",
        if d.floors.is_empty() {
            "one, unnumbered".to_string()
        } else {
            let mapped: std::collections::BTreeSet<i32> =
                map.points().iter().filter_map(|p| p.floor).collect();
            d.floors
                .iter()
                .enumerate()
                .map(|(i, f)| {
                    let height = d
                        .floor_heights_m
                        .get(i)
                        .map_or(String::new(), |h| format!(" at {h:.1} m"));
                    let fingerprints = if mapped.contains(f) {
                        ""
                    } else {
                        " (no fingerprints)"
                    };
                    format!("{f}{height}{fingerprints}")
                })
                .collect::<Vec<_>>()
                .join(", ")
        }
    );
    let mut by_floor: std::collections::BTreeMap<Option<i32>, usize> = Default::default();
    for p in map.points() {
        *by_floor.entry(p.floor).or_default() += 1;
    }
    let per_floor: Vec<String> = by_floor
        .iter()
        .map(|(f, n)| match f {
            Some(f) => format!("{f}: {n}"),
            None => format!("-: {n}"),
        })
        .collect();
    println!(
        "  radio map: {} reference points ({} measured{}), {} APs; by floor {{{}}}",
        map.len(),
        d.measured.len(),
        if d.coverage_includes_extension {
            ", extension counted as coverage"
        } else {
            ""
        },
        map.n_aps(),
        per_floor.join(", ")
    );
    println!(
        "  matcher: {}; trails: {} segments; barometric references: {}",
        model.matcher().name(),
        d.trail_segments.len(),
        d.pressure_references.len()
    );
    match &d.plan {
        Some(p) => println!(
            "  plan: {:.1} x {:.1} m, {} walls, outline {}",
            p.width,
            p.height,
            p.walls.len(),
            if p.outline.is_empty() { "none" } else { "yes" }
        ),
        None => println!("  plan: none"),
    }
    match &d.geo_frame {
        Some(f) => println!(
            "  WGS84 frame: origin {:.7}, {:.7}",
            f.origin_lat_deg, f.origin_lon_deg
        ),
        None => println!("  WGS84 frame: none"),
    }
    let p = &d.provenance;
    println!(
        "  provenance: wipdr {}, created {}, {} training walks ({} waypoints, {} scans), {} survey rows",
        p.wipdr_version,
        p.created_unix_s
            .map_or("(not recorded)".to_string(), |t| format!("at Unix {t} s")),
        p.training_walks,
        p.waypoints,
        p.scans,
        p.survey_rows
    );
    println!(
        "  sources: {} files{}",
        p.sources.len(),
        p.sources_sha256
            .as_ref()
            .map_or(String::new(), |h| format!(", SHA-256 of their digests {h}"))
    );
    println!(
        "  config (the positioner every stream runs; PDR calibrated):\n{}",
        toml::to_string_pretty(&d.config)
            .unwrap_or_else(|e| format!("(not printable as TOML: {e})"))
            .lines()
            .map(|l| format!("    {l}"))
            .collect::<Vec<_>>()
            .join("\n")
    );
    if !d.schemes.is_empty() {
        let names: Vec<&String> = d.schemes.keys().collect();
        println!("  scheme settings: {names:?}");
    }
    survey_guidance(path, &model, args)
}

/// Prints where the model is weak per floor (leave-one-walk-out Wi-Fi error, area far from
/// any reference point) and draws it with `--plot`.
fn survey_guidance(
    path: &Path,
    model: &wipdr_positioning::SiteModel,
    args: &Args,
) -> anyhow::Result<()> {
    use wipdr_core::stats::percentile_sorted;
    use wipdr_positioning::site_model::{SurveySettings, floor_survey, survey_floors};
    let d = model.data();
    let settings = SurveySettings::default();
    let surveys = survey_floors(model)
        .into_iter()
        .map(|f| floor_survey(model, f, &settings))
        .collect::<Result<Vec<_>, _>>()
        .with_context(|| format!("survey guidance of {}", path.display()))?;
    match &d.leave_one_out {
        Some(l) => println!(
            "  survey guidance: leave-one-walk-out Wi-Fi errors of {} scans ({} kept) in {} walks left out in {} groups ({} skipped, {} scans unmatched); gaps: farther than {} m from any measured reference point",
            l.scans,
            l.points.len(),
            l.walks,
            l.groups,
            l.skipped_walks,
            l.unmatched_scans,
            args.gap_m
        ),
        None => println!(
            "  survey guidance: no leave-one-walk-out errors in this model (`wipdr fit` measures them unless --no-leave-one-out); gaps: farther than {} m from any measured reference point",
            args.gap_m
        ),
    }
    for s in &surveys {
        let floor = s
            .floor
            .map_or("the floor".to_string(), |f| format!("floor {f}"));
        let errors = d
            .leave_one_out
            .as_ref()
            .map(|l| l.sorted_errors(s.floor))
            .unwrap_or_default();
        let error = if errors.is_empty() {
            "no leave-one-out error".to_string()
        } else {
            format!(
                "Wi-Fi error median {:.1} m, p90 {:.1} m ({} scans)",
                percentile_sorted(&errors, 50.0),
                percentile_sorted(&errors, 90.0),
                errors.len()
            )
        };
        let (share, area) = s.farther_than(args.gap_m);
        let whole = if d.plan.as_ref().is_some_and(|p| !p.outline.is_empty()) {
            "of the floor outline"
        } else {
            "of the box around the data: the model has no floor outline"
        };
        println!(
            "    {floor}: {error}; {} reference points; {area:.0} m² ({:.0} % {whole}) farther than {} m",
            s.reference_points.len(),
            100.0 * share,
            args.gap_m
        );
    }
    if let Some(out) = &args.plot {
        let all_errors = d
            .leave_one_out
            .as_ref()
            .map(|l| l.sorted_errors(None))
            .unwrap_or_default();
        // The error scale ends at the 90th percentile (rounded up to a metre, at least 5 m):
        // the worst tenth of the scans then reads red, and a few gross errors do not wash
        // every other cell out green (on `fixtures/sim/F1` the 95th percentile is about
        // 35 m, the 90th 14 m, the median 5 m: `wipdr inspect f1.wipdr` after
        // `wipdr fit --data fixtures/sim/F1 --out f1.wipdr`).
        let error_top = if all_errors.is_empty() {
            5.0
        } else {
            percentile_sorted(&all_errors, 90.0).ceil().max(5.0)
        };
        let most_aps = surveys
            .iter()
            .flat_map(|s| s.aps_heard.iter().flatten())
            .copied()
            .max()
            .unwrap_or(1)
            .max(1);
        let scales = crate::survey_plot::Scales {
            error: crate::survey_plot::Scale {
                lo: 0.0,
                hi: error_top,
                good_high: false,
            },
            distance: crate::survey_plot::Scale {
                lo: 0.0,
                hi: 2.0 * args.gap_m,
                good_high: false,
            },
            aps: crate::survey_plot::Scale {
                lo: 0.0,
                hi: f64::from(most_aps),
                good_high: true,
            },
        };
        let title = format!(
            "{}: where to survey next (red: large expected error, far from data, few APs; grey: no leave-one-out scan within {} m, no reference point within {} m)",
            d.name, settings.error_radius_m, args.gap_m
        );
        let (w, h) =
            crate::survey_plot::draw(out, &title, &surveys, d.plan.as_ref(), scales, args.gap_m)?;
        println!("  wrote {} ({w} x {h} px)", out.display());
    }
    Ok(())
}

fn inspect_walk(path: &Path, options: &ReadOptions) -> anyhow::Result<()> {
    let t0 = Instant::now();
    let parsed = wipdr_io::any::read_walk_file(path, &options.limits)?;
    let elapsed = t0.elapsed().as_secs_f64();
    let w = &parsed.walk;
    println!(
        "walk {} ({}), read in {elapsed:.3} s",
        w.meta.id,
        path.display()
    );
    let meta = &w.meta;
    let opt = |v: &Option<String>| v.clone().unwrap_or_else(|| "-".into());
    println!(
        "  site {} / floor {}   phone {} {} (Android {})",
        opt(&meta.site_name),
        opt(&meta.floor_name),
        opt(&meta.brand),
        opt(&meta.model),
        opt(&meta.android)
    );
    print_walk_table(std::slice::from_ref(&parsed));
    print_floors(std::slice::from_ref(&parsed));
    print_report(&parsed.report, true);
    Ok(())
}

fn inspect_floor(dir: &Path, args: &Args, options: &ReadOptions) -> anyhow::Result<()> {
    let n_files = wipdr_io::floor::walk_files(wipdr_io::logfile_folder::logfile_dir(dir))?.len();
    let bar = crate::progress::bar(n_files as u64, "walks");
    let on_walk = || bar.inc(1);
    let t0 = Instant::now();
    let settings = crate::data::cache_settings();
    let (floor, outcome): (FloorData, CacheOutcome) =
        crate::data::read_any(dir, &settings, options, &on_walk)?;
    let elapsed = t0.elapsed().as_secs_f64();
    bar.finish_and_clear();
    let at = settings.dir.display();
    let how = match outcome {
        CacheOutcome::Disabled => "from source, cache off".to_string(),
        CacheOutcome::Hit => format!("from the cache in {at}"),
        CacheOutcome::Miss => format!("from source, cached in {at}"),
        CacheOutcome::Rebuilt => format!("from source, bad cache file replaced in {at}"),
        CacheOutcome::MissNotStored => "from source, cache not written".to_string(),
    };
    println!("floor {} ({})", floor.name, floor.dir.display());
    println!("  read in {elapsed:.3} s ({how})");
    println!(
        "  {:.1} x {:.1} m, outline {} polygon(s), {} units, {} walls, {} GeoJSON features skipped",
        floor.width,
        floor.height,
        floor.plan.outline.len(),
        floor.plan.units.len(),
        floor.plan.walls.len(),
        floor.skipped_features
    );
    if let Some(note) = crate::data::skipped_walks_note(&floor) {
        println!("  {note}");
        if !args.brief {
            for skip in floor.skipped_walks.iter().skip(1) {
                println!("    also skipped: {}", skip.error);
            }
        }
    }
    if !args.brief {
        print_walk_table(&floor.walks);
    }
    let walks: Vec<&Walk> = floor.walks.iter().map(|p| &p.walk).collect();
    let durations: Vec<f64> = walks.iter().map(|w| w.duration_s()).collect();
    let total: f64 = durations.iter().sum();
    let (min, max) = durations
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(lo, hi), d| {
            (lo.min(*d), hi.max(*d))
        });
    let waypoints: usize = walks.iter().map(|w| w.waypoints.len()).sum();
    let inside: usize = walks
        .iter()
        .flat_map(|w| &w.waypoints)
        .filter(|p| floor.plan.inside_outline(p.position))
        .count();
    let scans: usize = walks.iter().map(|w| w.wifi.len()).sum();
    let aps: HashSet<Bssid> = walks
        .iter()
        .flat_map(|w| {
            w.wifi
                .iter()
                .flat_map(|s| s.entries.iter().map(|e| e.bssid))
        })
        .collect();
    println!(
        "  {} walks, total {:.1} min (each {:.1}-{:.1} s, mean {:.1} s)",
        walks.len(),
        total / 60.0,
        if walks.is_empty() { 0.0 } else { min },
        max,
        if walks.is_empty() {
            0.0
        } else {
            total / walks.len() as f64
        }
    );
    println!(
        "  {waypoints} waypoints ({}), {scans} Wi-Fi scans, {} distinct APs",
        if floor.plan.outline.is_empty() {
            "the plan has no outline".to_string()
        } else if waypoints == 0 {
            "- inside the outline".to_string()
        } else {
            format!(
                "{:.1} % inside the outline",
                100.0 * inside as f64 / waypoints as f64
            )
        },
        aps.len()
    );
    let rates = mean_rates(&walks);
    println!(
        "  mean rates (Hz): accelerometer {}, gyroscope {}, magnetometer {}, rotation vector {}, Wi-Fi scans {}",
        fmt_rate(rates[0]),
        fmt_rate(rates[1]),
        fmt_rate(rates[2]),
        fmt_rate(rates[3]),
        fmt_rate(rates[4])
    );
    print_floors(&floor.walks);
    let report = floor.total_report();
    print_report(&report, false);
    // Where to look: the first walks with skips of each kind.
    let mut shown = HashSet::new();
    for p in &floor.walks {
        for (kind, s) in &p.report.skipped {
            if *kind != trace::SkipKind::UnknownType && shown.insert(*kind) {
                println!(
                    "    first {}: walk {} lines {:?}",
                    kind.label(),
                    p.walk.meta.id,
                    s.first_lines
                );
            }
        }
    }
    println!();
    Ok(())
}

fn fmt_rate(r: Option<f64>) -> String {
    r.map_or("-".into(), |r| format!("{r:.1}"))
}

/// Mean over walks of each stream's rate: accelerometer, gyroscope, magnetometer, rotation
/// vector, Wi-Fi scans.
fn mean_rates(walks: &[&Walk]) -> [Option<f64>; 5] {
    let mut out = [None; 5];
    for (i, slot) in out.iter_mut().enumerate() {
        let rates: Vec<f64> = walks.iter().filter_map(|w| walk_rates(w)[i]).collect();
        if !rates.is_empty() {
            *slot = Some(rates.iter().sum::<f64>() / rates.len() as f64);
        }
    }
    out
}

fn walk_rates(w: &Walk) -> [Option<f64>; 5] {
    let imu = &w.imu;
    [
        mean_rate_hz(imu.accelerometer.iter().map(|s| s.t)),
        mean_rate_hz(imu.gyroscope.iter().map(|s| s.t)),
        mean_rate_hz(imu.magnetometer.iter().map(|s| s.t)),
        mean_rate_hz(imu.rotation_vector.iter().map(|s| s.t)),
        mean_rate_hz(w.wifi.iter().map(|s| s.t)),
    ]
}

fn print_walk_table(walks: &[ParsedWalk]) {
    println!(
        "  {:<26} {:>7} {:>5} {:>6} {:>5} {:>7} {:>7} {:>7} {:>7} {:>8} {:>8}",
        "walk",
        "dur s",
        "wpts",
        "scans",
        "APs",
        "acc Hz",
        "gyr Hz",
        "mag Hz",
        "rot Hz",
        "kept",
        "skipped"
    );
    for p in walks {
        let w = &p.walk;
        let aps: HashSet<Bssid> = w
            .wifi
            .iter()
            .flat_map(|s| s.entries.iter().map(|e| e.bssid))
            .collect();
        let r = walk_rates(w);
        println!(
            "  {:<26} {:>7.1} {:>5} {:>6} {:>5} {:>7} {:>7} {:>7} {:>7} {:>8} {:>8}",
            w.meta.id,
            w.duration_s(),
            w.waypoints.len(),
            w.wifi.len(),
            aps.len(),
            fmt_rate(r[0]),
            fmt_rate(r[1]),
            fmt_rate(r[2]),
            fmt_rate(r[3]),
            p.report.records_kept(),
            p.report.records_skipped()
        );
    }
}

/// Ground-truth floors and barometer readings, where the walks have them (IPIN logfiles).
fn print_floors(walks: &[ParsedWalk]) {
    let mut floors: std::collections::BTreeMap<i32, usize> = Default::default();
    for w in walks.iter().flat_map(|p| &p.walk.waypoints) {
        if let Some(f) = w.floor {
            *floors.entry(f).or_default() += 1;
        }
    }
    let pressure: usize = walks.iter().map(|p| p.walk.pressure.len()).sum();
    let beacons: usize = walks.iter().map(|p| p.walk.beacons.len()).sum();
    if floors.is_empty() && pressure == 0 && beacons == 0 {
        return;
    }
    let listed: Vec<String> = floors.iter().map(|(f, n)| format!("{f}: {n}")).collect();
    let changing = walks
        .iter()
        .filter(|p| {
            let mut fs = p.walk.waypoints.iter().filter_map(|w| w.floor);
            fs.next().is_some_and(|first| fs.any(|f| f != first))
        })
        .count();
    println!(
        "  waypoints by floor {{{}}}, {changing} walk(s) changing floor; {pressure} barometer readings, {beacons} BLE readings",
        listed.join(", ")
    );
}

fn print_report(r: &ParseReport, with_lines: bool) {
    println!(
        "  parse report: {} lines, {} headers, {} records kept, {} skipped",
        r.lines,
        r.header_lines,
        r.records_kept(),
        r.records_skipped()
    );
    let kept: Vec<String> = r.records.iter().map(|(k, v)| format!("{k} {v}")).collect();
    println!("    kept by type: {}", kept.join(", "));
    for (kind, s) in &r.skipped {
        if with_lines {
            println!(
                "    skipped {}: {} (first lines {:?})",
                kind.label(),
                s.count,
                s.first_lines
            );
        } else {
            println!("    skipped {}: {}", kind.label(), s.count);
        }
    }
    if !r.unknown_types.is_empty() {
        let unknown: Vec<String> = r
            .unknown_types
            .iter()
            .map(|(k, v)| format!("{k} {v}"))
            .collect();
        println!("    unknown types: {}", unknown.join(", "));
    }
    if !r.ignored.is_empty() {
        let ignored: Vec<String> = r.ignored.iter().map(|(k, v)| format!("{k} {v}")).collect();
        println!("    known, not needed (counted): {}", ignored.join(", "));
    }
    if r.sensor_clock_outliers > 0 {
        println!(
            "    sensor samples timed by the app clock (sensor clock disagreed): {}",
            r.sensor_clock_outliers
        );
    }
    println!(
        "    duplicate BSSIDs removed {}, run-on lines split {}{}, out-of-order records {} (latest by {:.1} s)",
        r.duplicate_bssids_removed,
        r.run_on_lines_split,
        if with_lines && !r.run_on_first_lines.is_empty() {
            format!(" (lines {:?})", r.run_on_first_lines)
        } else {
            String::new()
        },
        r.out_of_order,
        r.max_lateness_ms as f64 / 1000.0
    );
}

#[cfg(test)]
mod tests {
    use super::*;
    use wipdr_core::{FloorPlan, Point2, Waypoint};
    use wipdr_io::{LonLatBox, floor};

    #[test]
    fn inspects_a_floor_and_a_walk() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().join("site").join("F1");
        let mut walk = Walk::default();
        walk.meta.id = "w".into();
        for i in 0..3 {
            walk.waypoints
                .push(Waypoint::new(1000 * i, Point2::new(1.0 + i as f64, 5.0)));
        }
        let plan = FloorPlan::rectangle(20.0, 10.0).unwrap();
        let bbox = LonLatBox::around(8.0, 47.0, 20.0, 10.0);
        floor::write_floor_dir(&dir, &plan, bbox, [&walk]).unwrap();
        let walk_file = dir.join(floor::WALKS_DIR).join("w.txt.gz");
        let args = |paths: Vec<PathBuf>| Args {
            paths,
            brief: false,
            limits: None,
            plot: None,
            gap_m: 10.0,
        };
        crate::data::set_cache(wipdr_io::cache::CacheSettings::in_dir(
            tmp.path().join("cache"),
        ));
        run(args(vec![dir.clone()])).unwrap();
        run(args(vec![dir.clone(), walk_file])).unwrap();
        assert!(run(args(vec![tmp.path().join("missing.txt")])).is_err());
    }
}
