//! Where the real data sets live: one root folder for the ILC 2.0 walks (`ilc20/`), the IPIN
//! 2023 logfiles (`ipin2023/`) and the fingerprint benchmarks (`fingerprint/`).
//!
//! The root is `$WIPDR_DATA` when that is set and not empty, else `shared/data` in the folder
//! that holds the workspace (`<workspace>/../shared/data`). The default is fixed when this
//! crate is compiled, from its own location in the workspace, so tests (which cargo runs with
//! their crate's folder as the working directory), benches, examples and the program (run from
//! anywhere) all look in the same place. A relative `WIPDR_DATA` is taken relative to the
//! workspace root, the folder the README's commands run in, for the same reason. Being fixed
//! at compile time, the default follows the checkout the crate was compiled in: a build
//! reused from another checkout (a shared `CARGO_TARGET_DIR` that cargo finds fresh) or a
//! checkout moved after building looks beside the old place; set `WIPDR_DATA` then.
//!
//! The commands of the program never read the root themselves: they take the folders and
//! files to read as arguments (`wipdr eval --data $WIPDR_DATA/ilc20/site1/F1`). Tests, benches
//! and examples that need real data use [`real_data`] and skip, printing its reason, when the
//! folder is absent.
//!
//! ```
//! let root = wipdr_io::data_root();
//! assert!(root.ends_with("shared/data") || std::env::var_os("WIPDR_DATA").is_some());
//! match wipdr_io::real_data("ilc20/site1/F1") {
//!     Ok(floor) => assert!(floor.starts_with(&root)),
//!     Err(missing) => eprintln!("skipped: {missing}"),
//! }
//! ```

use std::fmt;
use std::path::{Path, PathBuf};

/// The environment variable that names the data root ([`data_root`]).
pub const DATA_ROOT_ENV: &str = "WIPDR_DATA";

/// The workspace root, from this crate's folder (`<workspace>/crates/io`) at compile time.
fn workspace_root() -> PathBuf {
    let io_dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    io_dir
        .parent()
        .and_then(Path::parent)
        .map_or_else(|| io_dir.join("../.."), Path::to_path_buf)
}

/// The root folder of the real data: `$WIPDR_DATA` when set and not empty (a relative path
/// taken relative to the workspace root), else `<workspace>/../shared/data`.
///
/// Nothing is checked: the folder may not exist (see [`real_data`]).
pub fn data_root() -> PathBuf {
    let workspace = workspace_root();
    match std::env::var_os(DATA_ROOT_ENV) {
        Some(value) if !value.is_empty() => workspace.join(value),
        _ => workspace.parent().map_or_else(
            || workspace.join("../shared/data"),
            |parent| parent.join("shared").join("data"),
        ),
    }
}

/// A path under the data root ([`data_root`]`.join(sub)`, e.g. `"ilc20/site1/F1"` or
/// `"fingerprint/UJI1"`) when it exists, else [`MissingData`], whose message names the path
/// looked at and `WIPDR_DATA`: tests and benches print it and skip.
pub fn real_data(sub: impl AsRef<Path>) -> Result<PathBuf, MissingData> {
    let path = data_root().join(sub);
    if path.exists() {
        Ok(path)
    } else {
        Err(MissingData { path })
    }
}

/// A real-data path that does not exist ([`real_data`]); its message says where it was
/// looked for and how to point the tools at the data.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct MissingData {
    /// The path looked at.
    pub path: PathBuf,
}

impl fmt::Display for MissingData {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "real data not found at {} (set {DATA_ROOT_ENV} to the data root, default \
             ../shared/data beside the workspace; README.md, \"Real data\")",
            self.path.display()
        )
    }
}

impl std::error::Error for MissingData {}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_root_is_beside_the_workspace() {
        let workspace = workspace_root();
        assert!(
            workspace.join("Cargo.toml").is_file(),
            "{}",
            workspace.display()
        );
        assert!(workspace.join("crates/io").is_dir());
        if std::env::var_os(DATA_ROOT_ENV).is_none_or(|v| v.is_empty()) {
            let root = data_root();
            assert_eq!(root.parent().unwrap().parent(), workspace.parent());
            assert!(root.ends_with("shared/data"));
        }
    }

    #[test]
    fn missing_data_names_the_path_and_the_variable() {
        let err = real_data("no/such/folder/here").unwrap_err();
        assert!(err.path.ends_with("no/such/folder/here"));
        let msg = err.to_string();
        assert!(
            msg.contains("no/such/folder/here") && msg.contains("WIPDR_DATA"),
            "{msg}"
        );
    }
}
