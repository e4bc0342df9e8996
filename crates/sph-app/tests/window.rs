//! The windowed mode starts and draws under Xvfb (lavapipe in CI): it runs a few
//! frames, takes its `S` screenshot (`--screenshot-after`) and quits; the
//! screenshot must show the fluid. Skipped when `xvfb-run` is missing unless
//! `SPH_REQUIRE_GPU=1`.

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use glam::Vec2;
use splat_render::textures::{procedural_background, sample_bilinear};

#[test]
fn window_draws_under_xvfb() {
    let Some((shot, log)) = window(
        "window",
        &["--scene", "dam-break", "--width", "480", "--height", "270"],
    ) else {
        return;
    };
    let (w, h) = shot.dimensions();
    let back = procedural_background(1024, 1024);
    let differing = shot
        .enumerate_pixels()
        .filter(|(x, y, p)| {
            let uv = Vec2::new((*x as f32 + 0.5) / w as f32, (*y as f32 + 0.5) / h as f32);
            let b = sample_bilinear(&back, uv, false) * 255.0;
            (0..3).any(|c| (f32::from(p.0[c]) - b[c]).abs() > 12.0)
        })
        .count();
    assert!(
        differing > (w * h) as usize / 50,
        "screenshot shows only {differing} fluid pixels: {log}"
    );
}

/// The window plays other simulators' files (`--input`) as it runs a
/// scene: it draws them on their ground and takes its screenshot.
#[test]
fn window_plays_input_files_under_xvfb() {
    let data = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../tests/data/splashsurf/dam_break_frame_9_6859_particles.bgeo");
    let Some((shot, log)) = window(
        "window-input",
        &[
            "--input",
            data.to_str().unwrap(),
            "--particle-radius",
            "0.025",
            "--width",
            "320",
            "--height",
            "180",
        ],
    ) else {
        return;
    };
    // The water's blue, which neither the sky nor the grey ground has.
    let blue = (shot.pixels())
        .filter(|p| i32::from(p.0[2]) > i32::from(p.0[0]) + 40)
        .count();
    let (w, h) = shot.dimensions();
    assert!(blue > (w * h) as usize / 50, "{blue} blue pixels: {log}");
}

/// A window refuses the flags only a headless run reads, naming the
/// first, rather than ignore them.
#[test]
fn a_window_refuses_headless_flags() {
    if !xvfb_available() {
        return;
    }
    let output = Command::new("xvfb-run")
        .args(["-a", env!("CARGO_BIN_EXE_sph-app")])
        .args([
            "--scene",
            "dam-break",
            "--frames",
            "3",
            "--export-surfels",
            "ply",
        ])
        .env("XDG_RUNTIME_DIR", std::env::temp_dir())
        .output()
        .expect("xvfb-run starts");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(!output.status.success(), "{stderr}");
    assert!(
        stderr.contains("--frames applies to headless runs only"),
        "{stderr}"
    );
}

/// Whether `xvfb-run` is installed; without it a skip, unless
/// `SPH_REQUIRE_GPU=1` (CI), where it is a failure.
fn xvfb_available() -> bool {
    let has_xvfb = Command::new("sh")
        .args(["-c", "command -v xvfb-run"])
        .output()
        .is_ok_and(|o| o.status.success());
    if !has_xvfb {
        assert!(
            std::env::var("SPH_REQUIRE_GPU").as_deref() != Ok("1"),
            "SPH_REQUIRE_GPU=1 but xvfb-run is missing (apt-get install -y xvfb xauth)"
        );
        eprintln!("skipped: xvfb-run not installed");
    }
    has_xvfb
}

/// `sph-app ARGS` in a window under Xvfb for 5 frames and its screenshot,
/// with the run's output; `None` (skipped) without xvfb-run unless
/// `SPH_REQUIRE_GPU=1`.
fn window(name: &str, args: &[&str]) -> Option<(image::RgbaImage, String)> {
    if !xvfb_available() {
        return None;
    }
    let out = Path::new(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&out);
    let mut child = Command::new("xvfb-run")
        .args([
            "-a",
            "-s",
            "-screen 0 1280x800x24",
            env!("CARGO_BIN_EXE_sph-app"),
        ])
        .args(args)
        .args(["--screenshot-after", "5", "--out", out.to_str().unwrap()])
        .env("XDG_RUNTIME_DIR", std::env::temp_dir())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("xvfb-run starts");
    let start = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        if start.elapsed() > Duration::from_secs(300) {
            let _ = child.kill();
            panic!("the window did not quit within 300 s");
        }
        std::thread::sleep(Duration::from_millis(200));
    };
    let output = child.wait_with_output().unwrap();
    let log = format!(
        "{}{}",
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    );
    assert!(status.success(), "{log}");
    assert!(
        !log.contains("rendering headless"),
        "fell back to headless: {log}"
    );
    let shot = image::open(out.join("screenshot_000.png"))
        .unwrap_or_else(|e| panic!("{e}: {log}"))
        .into_rgba8();
    Some((shot, log))
}
