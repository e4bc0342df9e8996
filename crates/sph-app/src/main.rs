//! The sph-splat demo.
//!
//! Until the extractor and renderer land, it runs the default scene (the slab dam
//! break, or a scene file given as the first argument) headless for two seconds of
//! simulated time and prints what it did.

use std::process::ExitCode;
use std::time::Instant;

use sph_core::Scene;

fn main() -> ExitCode {
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}

fn run() -> Result<(), sph_core::Error> {
    let scene = match std::env::args().nth(1) {
        Some(path) => Scene::load(path)?,
        None => Scene::dam_break(0.25, 0.08, 0.02),
    };
    let mut world = scene.build_world()?;
    println!(
        "scene `{}`: {} particles, h = {} m, spacing = {} m, k = {} m²/s², μ = {} Pa·s",
        scene.name,
        world.particles.len(),
        scene.fluid.h,
        scene.spacing,
        scene.fluid.stiffness,
        scene.fluid.viscosity
    );
    let start = Instant::now();
    let frames = (2.0 / scene.time_step.frame_dt).round() as u32;
    let mut substeps = 0u64;
    for frame in 0..frames {
        let report = world.advance(scene.time_step.frame_dt)?;
        substeps += report.substeps as u64;
        if (frame + 1) % 30 == 0 {
            let front = world
                .particles
                .positions()
                .iter()
                .map(|x| x.x)
                .fold(f32::MIN, f32::max);
            println!(
                "t = {:.2} s: {} substeps so far, dt in [{:.2e}, {:.2e}] s, surge front at x = {front:.3} m",
                report.time, substeps, report.dt_range.0, report.dt_range.1
            );
        }
    }
    let wall = start.elapsed().as_secs_f64();
    println!(
        "simulated {:.2} s in {substeps} steps, {wall:.2} s of wall time ({:.2} M particle-steps/s)",
        world.time(),
        world.particles.len() as f64 * substeps as f64 / wall / 1e6
    );
    println!("surfel extraction and rendering are not implemented yet (see README.md)");
    Ok(())
}
