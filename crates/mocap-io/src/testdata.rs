//! Where the shared real captures live, for tests and benchmarks.
//!
//! Real files are never copied into the project: tests read them from
//! `../shared/data` beside the project root, or from `$OSSIFY_SHARED_DATA`.
//! A fresh clone has neither; tests that need them then skip, saying so on stderr.

use std::io::Write as _;
use std::path::PathBuf;

/// Environment variable that overrides the shared data folder.
pub const ENV_VAR: &str = "OSSIFY_SHARED_DATA";

/// The project root (the workspace folder holding `crates/`).
pub fn project_root() -> PathBuf {
    // This file is crates/mocap-io/src/testdata.rs; the manifest dir is crates/mocap-io.
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The shared data folder, or `None` (after a loud note on stderr) when it is absent.
///
/// `what` names the test or benchmark that wanted it, for the skip message.
pub fn shared_data_dir(what: &str) -> Option<PathBuf> {
    let dir = match std::env::var_os(ENV_VAR) {
        Some(v) => PathBuf::from(v),
        None => project_root().join("../shared/data"),
    };
    if dir.join("reference.json").is_file() {
        Some(dir)
    } else {
        // Straight to the stderr handle, not `eprintln!`: the test harness captures the
        // print macros of passing tests, and a skip must be seen.
        let _ = writeln!(
            std::io::stderr().lock(),
            "SKIPPED {what}: shared real-capture data not found at {} (set {ENV_VAR} to its folder)",
            dir.display()
        );
        None
    }
}
