//! Shared by the eval integration tests: the committed synthetic fixture floor, and the real
//! ILC floors when they are under the data root (`$WIPDR_DATA`, else `../shared/data`). Each
//! test binary uses only some of these.
#![allow(dead_code)]

use std::path::PathBuf;
use wipdr_eval::pipeline::FloorInput;
use wipdr_io::floor::{ReadOptions, read_floor_dir};

/// The first floor under `fixtures/sim/`, labelled "fixture".
pub fn fixture_floor() -> FloorInput {
    let root = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/sim"));
    let mut dirs: Vec<PathBuf> = std::fs::read_dir(&root)
        .expect("fixtures/sim exists")
        .map(|e| e.expect("fixture folder entry").path())
        .filter(|p| p.join("floor_info.json").is_file())
        .collect();
    dirs.sort();
    let data = read_floor_dir(&dirs[0], &ReadOptions::default()).expect("fixture floor reads");
    FloorInput::new("fixture", data.into_floor())
}

/// The five ILC floors of `ilc20/` under the data root, as the protocol lists them.
pub const REAL_FLOORS: [&str; 5] = ["site1/F1", "site1/F2", "site2/F1", "site2/F2", "site2/F3"];

/// One real floor (`name` under the ILC root), read through the cache, labelled `name`.
pub fn real_floor(root: &std::path::Path, cache: &std::path::Path, name: &str) -> FloorInput {
    let data =
        wipdr_io::cache::read_floor_dir_cached(root.join(name), cache, &ReadOptions::default())
            .unwrap_or_else(|e| panic!("{name}: {e}"));
    FloorInput::new(name, data.into_floor())
}

/// The ILC floors' root and the read cache, or `None` (the reason printed) without the data.
pub fn real_data() -> Option<(PathBuf, PathBuf)> {
    let root = shared_data_dir("ilc20")?;
    let cache = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../"))
        .join(wipdr_io::cache::DEFAULT_CACHE_DIR);
    Some((root, cache))
}

/// A folder under the data root (`wipdr_io::data_root()`: `$WIPDR_DATA`, else
/// `../shared/data`; e.g. `ipin2023/scoring`), or `None` (the reason printed) without it.
pub fn shared_data_dir(sub: &str) -> Option<PathBuf> {
    match wipdr_io::real_data(sub) {
        Ok(dir) => Some(dir),
        Err(missing) => {
            println!("skipped: {missing}");
            None
        }
    }
}
