//! Writing a generated floor to disk in the ILC layout, so that the real readers read it:
//!
//! ```text
//! <out>/<floor>/path_data_files/<walk id>.txt.gz   walks                 } the ILC layout,
//! <out>/<floor>/floor_info.json                    width and height      } written by
//! <out>/<floor>/geojson_map.json                   the plan in degrees   } wipdr_io::floor::write_floor_dir
//! <out>/<floor>/survey/train.csv, test.csv         survey radio map, benchmark layout
//! <out>/<floor>/truth/<walk id>.json               per-walk truth (WalkTruth)
//! <out>/<floor>/truth/world.json                   seed, config, access points, disturbances
//! ```
//!
//! Everything is deterministic: files are written in a fixed order from sorted data, floats
//! through Rust's shortest round-trip formatting, gzip with a zero modification time, so the
//! same seed and configuration give byte-identical files.

use crate::imu::MagDisturbance;
use crate::radio::AccessPoint;
use crate::survey::SurveyPoint;
use crate::{SimConfig, SimError, SimFloor, SurveyMap};
use serde::Serialize;
use std::path::{Path, PathBuf};
use wipdr_io::LonLatBox;
use wipdr_io::fingerprint_csv::{
    FingerprintLabel, FingerprintTable, NOT_DETECTED, write_fingerprint_csv,
};

/// South-west corner of the synthetic floor's GeoJSON, degrees (an arbitrary place).
pub const GEO_ORIGIN_LON_LAT: (f64, f64) = (120.0, 30.0);

/// The world description written to `truth/world.json`.
#[derive(Debug, Serialize)]
struct WorldFile<'a> {
    seed: u64,
    config: &'a SimConfig,
    access_points: &'a [AccessPoint],
    mag_disturbances: &'a [MagDisturbance],
}

fn io_err(path: &Path) -> impl Fn(std::io::Error) -> SimError + '_ {
    move |source| SimError::Io {
        path: path.to_path_buf(),
        source,
    }
}

fn write_json(path: &Path, value: &impl Serialize) -> Result<(), SimError> {
    let text = serde_json::to_string(value).map_err(|e| SimError::Serialise {
        path: path.to_path_buf(),
        message: e.to_string(),
    })?;
    std::fs::write(path, text + "\n").map_err(io_err(path))
}

fn table(bssid_count: usize, points: &[SurveyPoint]) -> Result<FingerprintTable, SimError> {
    let mut t = FingerprintTable::new((0..bssid_count).map(|j| format!("ap_{j:03}")).collect());
    for p in points {
        let row: Vec<f32> = p
            .rss
            .iter()
            .map(|v| v.map_or(NOT_DETECTED, |v| v as f32))
            .collect();
        let label = FingerprintLabel {
            x: p.position.x,
            y: p.position.y,
            z: 0.0,
            floor: 0,
            building: 0,
        };
        t.push_row(&row, label)
            .map_err(wipdr_io::fingerprint_csv::FingerprintCsvError::from)?;
    }
    Ok(t)
}

/// Writes the survey map as `dir/train.csv` and `dir/test.csv`.
pub fn write_survey(dir: &Path, survey: &SurveyMap) -> Result<(), SimError> {
    std::fs::create_dir_all(dir).map_err(io_err(dir))?;
    let n = survey.bssids.len();
    write_fingerprint_csv(dir.join("train.csv"), &table(n, &survey.train)?)?;
    write_fingerprint_csv(dir.join("test.csv"), &table(n, &survey.test)?)?;
    Ok(())
}

/// Writes the whole floor under `out/<floor name>/` and returns that folder.
pub fn write_floor(sim: &SimFloor, out: &Path) -> Result<PathBuf, SimError> {
    let cfg = &sim.world.config;
    let dir = out.join(&cfg.floor_name);
    let plan = &sim.world.floor.plan;
    let (lon, lat) = GEO_ORIGIN_LON_LAT;
    let bbox = LonLatBox::around(lon, lat, plan.width, plan.height);
    wipdr_io::floor::write_floor_dir(&dir, plan, bbox, sim.walks.iter().map(|w| &w.walk))?;
    let truth_dir = dir.join("truth");
    std::fs::create_dir_all(&truth_dir).map_err(io_err(&truth_dir))?;
    for w in &sim.walks {
        write_json(
            &truth_dir.join(format!("{}.json", w.walk.meta.id)),
            &w.truth,
        )?;
    }
    write_json(
        &truth_dir.join("world.json"),
        &WorldFile {
            seed: sim.world.seed,
            config: cfg,
            access_points: &sim.world.radio.access_points,
            mag_disturbances: &sim.world.disturbances,
        },
    )?;
    write_survey(&dir.join("survey"), &sim.survey)?;
    tracing::info!(dir = %dir.display(), walks = sim.walks.len(), "wrote synthetic floor");
    Ok(dir)
}
