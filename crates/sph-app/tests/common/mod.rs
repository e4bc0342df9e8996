//! What the binary's end-to-end tests share.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Runs `sph-app` with `args` (lavapipe's runtime-dir warning silenced).
pub fn app(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_sph-app"))
        .args(args)
        .env("XDG_RUNTIME_DIR", std::env::temp_dir())
        .output()
        .expect("the binary runs")
}

/// A fresh path `name` under the tests' scratch folder (removed, not made).
pub fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

/// A run's standard error.
pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}
