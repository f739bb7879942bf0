//! Loading floors for the tools: cached reads with a progress bar, labels for reports.

use crate::progress;
use anyhow::{Context, Result};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use wipdr_eval::pipeline::FloorInput;
use wipdr_io::cache::{self, CacheOutcome};
use wipdr_io::floor::ReadOptions;

/// A short label for a floor folder: its parent's name and its own (`site1/F1`).
pub fn floor_label(dir: &Path) -> String {
    let name = dir.file_name().map(|s| s.to_string_lossy().into_owned());
    let parent = dir
        .parent()
        .and_then(|p| p.file_name())
        .map(|s| s.to_string_lossy().into_owned());
    match (parent, name) {
        (Some(p), Some(n)) => format!("{p}/{n}"),
        (None, Some(n)) => n,
        _ => dir.display().to_string(),
    }
}

/// Reads floor folders through the binary cache (`target/wipdr-cache`), with a progress bar
/// over the walks read from source.
pub fn load_floors(dirs: &[PathBuf]) -> Result<Vec<FloorInput>> {
    let mut out = Vec::with_capacity(dirs.len());
    for dir in dirs {
        let n = wipdr_io::floor::walk_files(dir)
            .map(|f| f.len() as u64)
            .unwrap_or(0);
        let pb = progress::bar(n, &floor_label(dir));
        let (data, outcome) = cache::read_floor_dir_cached_with(
            dir,
            cache::DEFAULT_CACHE_DIR,
            &ReadOptions::default(),
            &|| pb.inc(1),
        )
        .with_context(|| format!("reading floor {}", dir.display()))?;
        pb.finish_and_clear();
        tracing::info!(floor = %dir.display(), walks = data.walks.len(), cached = matches!(outcome, CacheOutcome::Hit), "floor loaded");
        out.push(FloorInput {
            label: floor_label(dir),
            data: Arc::new(data),
        });
    }
    Ok(out)
}
