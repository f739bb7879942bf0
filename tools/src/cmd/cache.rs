//! `wipdr cache info|clear`: where the parse cache is, what it holds, and emptying it.
//!
//! The cache folder is `--cache-dir DIR`, else `$WIPDR_CACHE_DIR`, else
//! `target/wipdr-cache` (relative to the working directory); its size cap is
//! `--cache-max-mb`, else `$WIPDR_CACHE_MAX_MB`, else 2048 MiB. Only the cache's own files
//! (`floor-*.bin`, `floor-*.tmp*`) are listed or removed.

use std::time::SystemTime;
use wipdr_io::cache::{self, CacheSettings};

/// Arguments of `wipdr cache`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// What to do.
    #[command(subcommand)]
    pub action: Action,
}

/// The `wipdr cache` actions.
#[derive(Debug, Clone, Copy, clap::Subcommand)]
pub enum Action {
    /// Print the cache folder, its files (least recently used first) and their total size.
    Info,
    /// Remove every cache file from the folder.
    Clear,
}

fn mib(bytes: u64) -> f64 {
    bytes as f64 / (1024.0 * 1024.0)
}

/// Runs the subcommand.
pub fn run(args: Args) -> anyhow::Result<()> {
    let settings = crate::data::cache_settings();
    for line in lines(args.action, &settings)? {
        println!("{line}");
    }
    Ok(())
}

/// The report of `action` on the cache of `settings`, line by line.
fn lines(action: Action, settings: &CacheSettings) -> anyhow::Result<Vec<String>> {
    let mut out = Vec::new();
    match action {
        Action::Info => {
            let info = cache::info(&settings.dir)?;
            out.push(format!(
                "cache folder {}{}{}",
                settings.dir.display(),
                if info.exists { "" } else { " (does not exist)" },
                if settings.enabled {
                    ""
                } else {
                    " (off for this run: --no-cache)"
                }
            ));
            out.push(format!(
                "{} files, {:.1} MiB of a {:.0} MiB cap",
                info.files.len(),
                mib(info.total_bytes()),
                mib(settings.max_bytes)
            ));
            let now = SystemTime::now();
            for f in &info.files {
                let age = now
                    .duration_since(f.last_used)
                    .map(|d| d.as_secs_f64() / 3600.0)
                    .unwrap_or(0.0);
                out.push(format!(
                    "  {:>9.1} MiB  last used {age:.1} h ago  {}{}",
                    mib(f.bytes),
                    f.path.display(),
                    if f.temporary {
                        "  (leftover temporary file)"
                    } else {
                        ""
                    }
                ));
            }
        }
        Action::Clear => {
            let removed = cache::clear(&settings.dir)?;
            out.push(format!(
                "removed {} files ({:.1} MiB) from {}",
                removed.files.len(),
                mib(removed.bytes),
                settings.dir.display()
            ));
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn info_and_clear_report_the_folder() {
        let tmp = tempfile::tempdir().unwrap();
        let settings = CacheSettings::in_dir(tmp.path().join("c"));
        let info = lines(Action::Info, &settings).unwrap();
        assert!(info[0].ends_with("(does not exist)"), "{info:?}");
        assert_eq!(info[1], "0 files, 0.0 MiB of a 2048 MiB cap");
        std::fs::create_dir_all(&settings.dir).unwrap();
        std::fs::write(settings.dir.join("floor-0123456789abcdef.bin"), [0u8; 1024]).unwrap();
        std::fs::write(settings.dir.join("keep.txt"), "x").unwrap();
        let info = lines(Action::Info, &settings).unwrap();
        assert_eq!(info[1], "1 files, 0.0 MiB of a 2048 MiB cap");
        assert!(info[2].contains("floor-0123456789abcdef.bin"), "{info:?}");
        let cleared = lines(Action::Clear, &settings).unwrap();
        assert!(cleared[0].starts_with("removed 1 files"), "{cleared:?}");
        assert!(settings.dir.join("keep.txt").exists());
    }
}
