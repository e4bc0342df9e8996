//! The demo's error type: every failure is a message naming the problem and a
//! non-zero exit, never a panic.

use std::path::PathBuf;

use thiserror::Error;

/// Everything that stops the demo.
#[derive(Debug, Error)]
pub enum AppError {
    /// `--scene` is neither a built-in name nor a file.
    #[error("unknown scene `{0}` (try --list-scenes, or give a .toml file)")]
    UnknownScene(String),
    /// The scene file could not be read, parsed or validated.
    #[error("scene `{scene}`: {source}")]
    Scene {
        /// What was asked for.
        scene: String,
        /// sph-core's reason (names the field, line and column).
        source: sph_core::Error,
    },
    /// The simulation stopped (blow-up, NaN) or export failed.
    #[error("{0}")]
    Simulation(#[from] sph_core::Error),
    /// The output folder cannot be created or written.
    #[error("cannot write to {path}: {reason}")]
    Output {
        /// The path.
        path: PathBuf,
        /// The OS's reason.
        reason: String,
    },
    /// The renderer failed.
    #[error("{0}")]
    Render(#[from] splat_render::RenderError),
    /// The GPU path (`--gpu-sim`, `--gpu-extract`) failed or does not support the scene.
    #[error("GPU path: {0}")]
    Gpu(String),
    /// The window could not be created.
    #[error("window: {0}")]
    Window(String),
    /// A headless run stopped part-way; the files of earlier frames are complete.
    #[error("frame {frame} failed: {source} ({frame} complete frames are listed in {})", csv.display())]
    Incomplete {
        /// The failing frame (0-based) = number of complete frames.
        frame: u32,
        /// The `frames.csv` listing the complete frames.
        csv: PathBuf,
        /// What went wrong.
        source: Box<AppError>,
    },
    /// `--input` found no file, or a file it found cannot be read.
    #[error("--input `{input}`: {reason}")]
    Input {
        /// The pattern or file.
        input: String,
        /// What is wrong.
        reason: String,
    },
    /// A flag that only headless runs read, given to a window.
    #[error("--{0} applies to headless runs only: add --headless, or leave it out")]
    HeadlessOnly(&'static str),
    /// The thread pool could not be built.
    #[error("--threads: {0}")]
    Threads(String),
}

impl AppError {
    /// An output error for `path`.
    pub fn output(path: impl Into<PathBuf>, err: impl std::fmt::Display) -> Self {
        Self::Output {
            path: path.into(),
            reason: err.to_string(),
        }
    }
}

impl From<sph_gpu::GpuError> for AppError {
    fn from(e: sph_gpu::GpuError) -> Self {
        Self::Gpu(e.to_string())
    }
}
