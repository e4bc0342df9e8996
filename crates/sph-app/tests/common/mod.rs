//! What the binary's end-to-end tests share (each test binary uses some).
#![allow(dead_code)]

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

/// The FLIP mean between two images (nv-flip: NVIDIA's perceptual
/// difference).
pub fn flip(reference: &image::RgbaImage, test: &image::RgbaImage) -> f32 {
    let rgb = |i: &image::RgbaImage| {
        let rgb = image::DynamicImage::ImageRgba8(i.clone()).to_rgb8();
        nv_flip::FlipImageRgb8::with_data(rgb.width(), rgb.height(), &rgb)
    };
    let error = nv_flip::flip(
        rgb(reference),
        rgb(test),
        nv_flip::DEFAULT_PIXELS_PER_DEGREE,
    );
    nv_flip::FlipPool::from_image(&error).mean()
}
