//! Helpers shared by the binary's integration tests (each test binary uses some of them).
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::Command;

/// Runs the `wipdr` binary in `cwd` with `args`, asserts success, returns its stdout.
pub fn wipdr(args: &[&str], cwd: &Path) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_wipdr"))
        .args(args)
        .current_dir(cwd)
        .output()
        .expect("wipdr runs");
    assert!(
        out.status.success(),
        "wipdr {args:?} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// Runs the `wipdr` binary in `cwd` with `args`, asserts that it fails, returns its stderr.
pub fn wipdr_fails(args: &[&str], cwd: &Path) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_wipdr"))
        .args(args)
        .current_dir(cwd)
        .output()
        .expect("wipdr runs");
    assert!(!out.status.success(), "wipdr {args:?} succeeded");
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// The browser: `$WIPDR_CHROMIUM`, else the first of the usual names on `PATH`.
pub fn chromium() -> Option<PathBuf> {
    if let Some(p) = std::env::var_os("WIPDR_CHROMIUM") {
        return Some(PathBuf::from(p));
    }
    let path = std::env::var_os("PATH")?;
    [
        "chromium",
        "chromium-browser",
        "google-chrome",
        "google-chrome-stable",
    ]
    .iter()
    .flat_map(|name| std::env::split_paths(&path).map(move |dir| dir.join(name)))
    .find(|p| p.is_file())
}
