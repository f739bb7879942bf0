//! Helpers shared by the binary's integration tests.

use std::path::Path;
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
