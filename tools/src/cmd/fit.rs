//! `wipdr fit`: learn a site once and save it as a site model file.
//!
//! ```text
//! wipdr fit --data $WIPDR_DATA/ilc20/site1 --out site1.wipdr
//! wipdr locate --model site1.wipdr WALK_FILE --out track.csv
//! ```
//!
//! `--data` is one place: an ILC floor folder, an ILC site folder (its floors as one
//! building) or a folder of IPIN logfiles. Every walk with waypoints is training data (the
//! radio map, the PDR calibration, the barometric references, the trails); `--config` is an
//! evaluation config (the same file `wipdr eval --config` takes): its radio-map,
//! extension, calibration, positioner and scheme settings are what the model is fit and run
//! with. `--leave-out-fold-of WALK` fits on the training folds of that walk's protocol fold
//! instead (what `wipdr eval` does for it: the model then positions that walk exactly as
//! the evaluation does).
//!
//! The fit also measures the Wi-Fi error of every training scan with its walk left out of
//! the radio map (`leave_one_walk_out`: the radio map and matcher fit again without each
//! walk, in parallel; beyond `--leave-out-groups` walks, without each of that many
//! interleaved groups of walks) and saves it in the model for `wipdr inspect MODEL --plot`;
//! `--no-leave-one-out` skips it.

use crate::cmd::eval::load_config;
use crate::data;
use anyhow::{Context, Result, bail};
use sha2::{Digest, Sha256};
use std::path::{Path, PathBuf};
use std::time::Instant;
use wipdr_core::Walk;
use wipdr_eval::fold_model::folds_of;
use wipdr_positioning::site_model::{
    DEFAULT_LEAVE_OUT_GROUPS, SiteModel, SourceFile, TrainingData, leave_one_walk_out,
};

/// Arguments of `wipdr fit`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The place: an ILC floor folder, an ILC site folder or a folder of IPIN logfiles.
    #[arg(long)]
    pub data: PathBuf,
    /// The site model file to write (conventionally `NAME.wipdr`).
    #[arg(long)]
    pub out: PathBuf,
    /// Evaluation config (TOML) whose settings the model is fit and run with; defaults
    /// otherwise.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Fit on the walks outside this walk's protocol fold only (as `wipdr eval` does for
    /// it), instead of on every walk.
    #[arg(long, value_name = "WALK_ID")]
    pub leave_out_fold_of: Option<String>,
    /// Do not measure the leave-one-walk-out Wi-Fi errors (survey guidance of
    /// `wipdr inspect --plot`); the model positions exactly the same either way.
    #[arg(long)]
    pub no_leave_one_out: bool,
    /// Most radio maps the leave-one-out errors fit: a site with more walks has them left
    /// out in this many interleaved groups (at least 2).
    #[arg(long, default_value_t = DEFAULT_LEAVE_OUT_GROUPS, value_name = "N")]
    pub leave_out_groups: usize,
}

/// Runs the subcommand.
pub fn run(args: Args) -> Result<()> {
    let started = Instant::now();
    let cfg = load_config(args.config.as_deref())?;
    if !args.data.is_dir() {
        bail!(
            "--data {}: give a folder (an ILC floor or site folder, or a folder of IPIN logfiles)",
            args.data.display()
        );
    }
    let floors = data::load_floors(std::slice::from_ref(&args.data))?;
    let Some(floor) = floors.first() else {
        bail!("no floor read from {}", args.data.display());
    };
    let walks = &floor.data.walks;
    let training: Vec<&Walk> = match &args.leave_out_fold_of {
        None => walks.iter().collect(),
        Some(id) => {
            let Some(index) = walks.iter().position(|w| &w.meta.id == id) else {
                bail!(
                    "--leave-out-fold-of {id}: no such walk in {}",
                    args.data.display()
                );
            };
            let folds = folds_of(floor);
            let fold = folds[index];
            walks
                .iter()
                .zip(&folds)
                .filter(|&(_, &f)| f != fold)
                .map(|(w, _)| w)
                .collect()
        }
    };
    let training: Vec<&Walk> = training
        .into_iter()
        .filter(|w| !w.waypoints.is_empty())
        .collect();
    if training.is_empty() {
        bail!(
            "{}: no walk with waypoints to learn from",
            args.data.display()
        );
    }
    let data = TrainingData {
        name: &floor.label,
        walks: &training,
        survey: None,
        plan: Some(&floor.data.plan),
        geo_frame: floor.data.geo_frame,
    };
    let site_config = cfg.site_config();
    let mut model = SiteModel::fit(&data, &site_config)
        .with_context(|| format!("fitting {}", args.data.display()))?;
    let fitted_s = started.elapsed().as_secs_f64();
    if !args.no_leave_one_out {
        let t0 = Instant::now();
        let loo = leave_one_walk_out(&data, &site_config, args.leave_out_groups)
            .with_context(|| format!("leave-one-walk-out errors of {}", args.data.display()))?;
        eprintln!(
            "leave-one-walk-out Wi-Fi errors: {} walks in {} groups ({} skipped), {} scans located ({} unmatched), {} kept, in {:.1} s",
            loo.walks,
            loo.groups,
            loo.skipped_walks,
            loo.scans,
            loo.unmatched_scans,
            loo.points.len(),
            t0.elapsed().as_secs_f64()
        );
        model.set_leave_one_out(Some(loo))?;
    }
    let sources = source_files(&args.data)?;
    let mut all = Sha256::new();
    for s in &sources {
        all.update(s.sha256.as_bytes());
    }
    let provenance = model.provenance_mut();
    provenance.sources_sha256 = Some(hex(&all.finalize()));
    provenance.sources = sources;
    provenance.created_unix_s = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .ok()
        .and_then(|d| i64::try_from(d.as_secs()).ok());
    model
        .save(&args.out)
        .with_context(|| format!("saving {}", args.out.display()))?;
    let bytes = std::fs::metadata(&args.out).map(|m| m.len()).unwrap_or(0);
    let p = &model.data().provenance;
    eprintln!(
        "{}: {} training walks, {} reference points, {} APs, floors {:?} -> {} ({:.1} MB) in {:.1} s (read and fit {:.1} s)",
        floor.label,
        p.training_walks,
        p.reference_points,
        p.aps,
        model.data().floors,
        args.out.display(),
        bytes as f64 / 1e6,
        started.elapsed().as_secs_f64(),
        fitted_s
    );
    Ok(())
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// Every regular file below `dir` (sorted, hidden entries skipped) with its size and
/// SHA-256: the model's provenance.
pub fn source_files(dir: &Path) -> Result<Vec<SourceFile>> {
    let mut files = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        let entries = std::fs::read_dir(&d).with_context(|| format!("listing {}", d.display()))?;
        for e in entries {
            let e = e.with_context(|| format!("listing {}", d.display()))?;
            if e.file_name().to_string_lossy().starts_with('.') {
                continue;
            }
            let ty = e.file_type()?;
            if ty.is_dir() {
                stack.push(e.path());
            } else if ty.is_file() {
                files.push(e.path());
            }
        }
    }
    files.sort();
    files
        .iter()
        .map(|f| {
            let mut hasher = Sha256::new();
            let mut file =
                std::fs::File::open(f).with_context(|| format!("reading {}", f.display()))?;
            let bytes = std::io::copy(&mut file, &mut hasher)
                .with_context(|| format!("reading {}", f.display()))?;
            Ok(SourceFile {
                path: f.display().to_string(),
                bytes,
                sha256: hex(&hasher.finalize()),
            })
        })
        .collect()
}
