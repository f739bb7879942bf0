//! The evaluation report page (`wipdr eval --report`, `wipdr report`): the drawing data a
//! run adds to its results JSON ([`data`]) and the self-contained HTML page rendered from
//! that JSON value ([`page`]). Both commands build the page from the same value, so a page
//! made from a saved `--json --json-tracks` file equals the one the run wrote.

pub mod data;
pub mod page;

use anyhow::{Context, Result};
use std::path::Path;

pub use data::{TrackStore, add_drawing};

/// The top-level fields of the results JSON that [`add_drawing`] adds (besides each walk
/// result's `"track"`).
pub const DRAWING_FIELDS: &[&str] = &["walk_data", "plans", "drawing"];

/// Renders the page of the results `value` (from `source`, for errors) and writes it to
/// `out`, printing its size.
pub fn write_page(value: &serde_json::Value, source: &str, out: &Path) -> Result<()> {
    let started = std::time::Instant::now();
    let html = page::render(value, source)?;
    crate::plotting::ensure_parent(out)?;
    std::fs::write(out, &html).with_context(|| format!("writing {}", out.display()))?;
    println!(
        "wrote {} ({:.1} MB, {:.1} s)",
        out.display(),
        html.len() as f64 / 1e6,
        started.elapsed().as_secs_f64()
    );
    Ok(())
}
