//! Loading floors for the tools: cached reads with a progress bar, labels for reports.

use crate::progress;
use anyhow::{Context, Result};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use wipdr_eval::pipeline::FloorInput;
use wipdr_io::cache::{self, CacheOutcome, CacheSettings};
use wipdr_io::floor::{FloorData, ReadOptions};

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

/// A one-line note on the walk files of `floor` that could not be read and were skipped:
/// how many, and the first one's error; `None` when every walk file was read.
pub fn skipped_walks_note(floor: &FloorData) -> Option<String> {
    let first = floor.skipped_walks.first()?;
    let skipped = floor.skipped_walks.len();
    Some(format!(
        "{}: {skipped} of {} walk files skipped (unreadable); first: {}",
        floor.name,
        skipped + floor.walks.len(),
        first.error
    ))
}

/// The parse cache chosen on the command line (set once by `main`).
static CACHE: OnceLock<CacheSettings> = OnceLock::new();

/// The environment variable that moves the parse cache (`--cache-dir` wins).
pub const CACHE_DIR_ENV: &str = "WIPDR_CACHE_DIR";
/// The environment variable with the cache's size cap in MiB (`--cache-max-mb` wins).
pub const CACHE_MAX_MB_ENV: &str = "WIPDR_CACHE_MAX_MB";

/// The cache settings from the command line and the environment: `--cache-dir`, else
/// `$WIPDR_CACHE_DIR`, else [`cache::DEFAULT_CACHE_DIR`]; `--no-cache` turns it off;
/// `--cache-max-mb`, else `$WIPDR_CACHE_MAX_MB`, else 2048 MiB.
pub fn resolve_cache(
    dir: Option<PathBuf>,
    no_cache: bool,
    max_mb: Option<u64>,
) -> Result<CacheSettings> {
    let env = |name: &str| std::env::var_os(name).filter(|v| !v.is_empty());
    let dir = dir
        .or_else(|| env(CACHE_DIR_ENV).map(PathBuf::from))
        .unwrap_or_else(|| PathBuf::from(cache::DEFAULT_CACHE_DIR));
    let max_mb = match max_mb {
        Some(mb) => Some(mb),
        None => match env(CACHE_MAX_MB_ENV) {
            Some(v) => Some(v.to_string_lossy().trim().parse::<u64>().with_context(|| {
                format!("{CACHE_MAX_MB_ENV}={v:?}: expected a whole number of MiB")
            })?),
            None => None,
        },
    };
    let max_bytes = match max_mb {
        Some(mb) => mb
            .checked_mul(1024 * 1024)
            .with_context(|| format!("cache size cap of {mb} MiB is too large"))?,
        None => cache::DEFAULT_MAX_BYTES,
    };
    Ok(CacheSettings {
        dir,
        enabled: !no_cache,
        max_bytes,
    })
}

/// Sets the cache settings for this run (first call wins).
pub fn set_cache(settings: CacheSettings) {
    let _ = CACHE.set(settings);
}

/// The cache settings of this run (the defaults when `main` set none, e.g. in tests).
pub fn cache_settings() -> CacheSettings {
    CACHE.get().cloned().unwrap_or_default()
}

/// Makes a write to a closed stdout (`wipdr inspect F | head -1`) end the program quietly
/// with exit code 0 instead of a panic: `println!` panics on a broken pipe, and this panic
/// hook exits before the panic message is printed. Every other panic is reported as before.
pub fn exit_quietly_on_broken_pipe() {
    let default_hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        let payload = info.payload();
        let message = payload
            .downcast_ref::<String>()
            .map(String::as_str)
            .or_else(|| payload.downcast_ref::<&str>().copied())
            .unwrap_or("");
        if message.starts_with("failed printing to stdout") && message.contains("Broken pipe") {
            std::process::exit(0);
        }
        default_hook(info);
    }));
}

/// Whether an error comes from writing to a closed pipe.
pub fn is_broken_pipe(e: &anyhow::Error) -> bool {
    e.chain().any(|c| {
        c.downcast_ref::<std::io::Error>()
            .is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe)
    })
}

/// Reads any floor folder ([`wipdr_io::any::read_any_dir`]: ILC floor, ILC site, folder of
/// IPIN logfiles).
pub use wipdr_io::any::read_any_dir as read_any;

/// Reads one floor folder through the parse cache of this run ([`cache_settings`]), with a
/// progress bar over the walks read from source; skipped walks are reported.
pub fn load_floor_data(dir: &Path) -> Result<FloorData> {
    let settings = cache_settings();
    let n = wipdr_io::floor::walk_files(wipdr_io::logfile_folder::logfile_dir(dir))
        .map(|f| f.len() as u64)
        .unwrap_or(0);
    let pb = progress::bar(n, &floor_label(dir));
    let (data, outcome) = read_any(dir, &settings, &ReadOptions::default(), &|| pb.inc(1))
        .with_context(|| format!("reading floor {}", dir.display()))?;
    pb.finish_and_clear();
    if let Some(note) = skipped_walks_note(&data) {
        eprintln!("{note}");
    }
    tracing::info!(floor = %dir.display(), walks = data.walks.len(), cached = matches!(outcome, CacheOutcome::Hit), "floor loaded");
    Ok(data)
}

/// The floor folders to read, each once: a folder given again (by the same or another path
/// to it) is left out with a warning, as a duplicate walk file is; a folder inside another
/// one given (a floor and its site) is refused, since its walks would be read twice.
pub fn distinct_floor_dirs(dirs: &[PathBuf]) -> Result<Vec<PathBuf>> {
    let mut kept: Vec<(PathBuf, PathBuf)> = Vec::with_capacity(dirs.len());
    for dir in dirs {
        let real = std::fs::canonicalize(dir)
            .with_context(|| format!("reading floor {}", dir.display()))?;
        if let Some((first, _)) = kept.iter().find(|(_, r)| *r == real) {
            tracing::warn!(floor = %dir.display(), first = %first.display(), "floor folder given more than once: read once");
            continue;
        }
        if let Some((other, _)) = kept
            .iter()
            .find(|(_, r)| real.starts_with(r) || r.starts_with(&real))
        {
            anyhow::bail!(
                "floor folders {} and {}: one is inside the other, so its walks would be read twice; give one of them",
                other.display(),
                dir.display()
            );
        }
        kept.push((dir.clone(), real));
    }
    Ok(kept.into_iter().map(|(d, _)| d).collect())
}

/// Reads floor folders ([`load_floor_data`]) into the evaluation's core vocabulary, each
/// labelled by [`floor_label`] and remembering its folder (for the floor image of plots).
/// Each folder is read once ([`distinct_floor_dirs`]).
pub fn load_floors(dirs: &[PathBuf]) -> Result<Vec<FloorInput>> {
    distinct_floor_dirs(dirs)?
        .iter()
        .map(|dir| {
            let data = load_floor_data(dir)?;
            let skips = data.skip_counts();
            Ok(FloorInput::new(floor_label(dir), data.into_floor())
                .with_dir(dir)
                .with_input_skips(skips))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use wipdr_core::{FloorPlan, Point2, Walk, Waypoint};
    use wipdr_io::{LonLatBox, floor};

    #[test]
    fn notes_skipped_walks_only_when_there_are_some() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().join("site").join("F2");
        let mut walk = Walk::default();
        walk.meta.id = "good".into();
        walk.waypoints
            .push(Waypoint::new(1000, Point2::new(1.0, 5.0)));
        let plan = FloorPlan::rectangle(20.0, 10.0).unwrap();
        let bbox = LonLatBox::around(8.0, 47.0, 20.0, 10.0);
        floor::write_floor_dir(&dir, &plan, bbox, [&walk]).unwrap();
        let read = || floor::read_floor_dir(&dir, &ReadOptions::default()).unwrap();
        assert_eq!(skipped_walks_note(&read()), None);
        // Gzip magic bytes, then garbage: a corrupt stream.
        let bad = dir.join(floor::WALKS_DIR).join("bad.txt.gz");
        std::fs::write(&bad, [0x1f, 0x8b, 0x08, 0x00, 0xAB, 0xCD, 0xEF]).unwrap();
        let note = skipped_walks_note(&read()).unwrap();
        assert!(
            note.starts_with("site/F2: 1 of 2 walk files skipped (unreadable); first: "),
            "{note}"
        );
        assert!(
            note.contains("bad.txt.gz: read failed after line 0"),
            "{note}"
        );
    }
}
