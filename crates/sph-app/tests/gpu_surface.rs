//! The GPU path's surface as a user sees it: the same particles (simulated
//! on the CPU) extracted on the GPU (`--gpu-extract`) and on the CPU with
//! the same parameters (the anisotropic field, hole closing, 3×3 first
//! splits): surfel counts within 10 % and the frames within a FLIP mean of
//! 0.05 of each other.

mod common;
use common::{app, flip, scratch, stderr};

/// The first frame of `scene` after 1 s, 480×270, with `extra` arguments,
/// and its surfel count.
fn frame(scene: &str, extra: &[&str], name: &str) -> (image::RgbaImage, usize) {
    let out = scratch(name);
    let dir = out.to_str().unwrap();
    let mut args = vec![
        "--headless",
        "--scene",
        scene,
        "--seconds",
        "1",
        "--fps",
        "1",
    ];
    args.extend(["--width", "480", "--height", "270", "--out", dir]);
    args.extend(extra);
    let o = app(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    let csv = std::fs::read_to_string(out.join("frames.csv")).unwrap();
    let surfels = csv.lines().nth(1).unwrap().split(',').nth(3).unwrap();
    let image = image::open(out.join("frame_00000.png")).unwrap().to_rgba8();
    (image, surfels.parse().unwrap())
}

#[test]
fn gpu_extraction_draws_the_cpu_paths_surface() {
    if splat_render::GpuContext::headless_or_skip().is_none() {
        return;
    }
    for scene in ["drop", "dam-break-fine"] {
        let (cpu, cpu_surfels) = frame(scene, &[], &format!("surface-cpu-{scene}"));
        let (gpu, gpu_surfels) = frame(scene, &["--gpu-extract"], &format!("surface-gpu-{scene}"));
        let mean = flip(&cpu, &gpu);
        println!("{scene}: FLIP {mean:.4}; surfels: GPU {gpu_surfels}, CPU {cpu_surfels}");
        assert!(mean <= 0.05, "{scene}: FLIP {mean}");
        let diff = (gpu_surfels as f64 - cpu_surfels as f64).abs();
        assert!(diff <= 0.1 * cpu_surfels as f64, "{scene}: surfel counts");
    }
}
