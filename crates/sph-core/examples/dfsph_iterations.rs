//! DFSPH's work and accuracy over the dam break: for each tenth of a
//! second of the demo's slab dam break (`Scene::dam_break(0.25, 0.08,
//! spacing)`), the steps, the density, divergence and viscosity solves'
//! iterations per step, unconverged solves, and the average and largest
//! density error.
//!
//! ```text
//! cargo run --release -p sph-core --example dfsph_iterations [-- SPACING [SECONDS]]
//! ```

use sph_core::{Scene, SolverKind};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let spacing: f32 = args.next().map_or(Ok(0.02), |s| s.parse())?;
    let seconds: f32 = args.next().map_or(Ok(2.0), |s| s.parse())?;
    if !(spacing > 0.0 && seconds > 0.0 && seconds <= 100.0) {
        return Err("SPACING must be positive and SECONDS in (0, 100]".into());
    }
    let scene = Scene::dam_break(0.25, 0.08, spacing).with_solver(SolverKind::Dfsph);
    let mut world = scene.build_world()?;
    println!(
        "DFSPH slab dam break, {} particles, spacing {spacing} m, μ = {} Pa·s",
        world.particles.len(),
        scene.fluid.viscosity()
    );
    println!(
        "{:>6} {:>6} {:>9} {:>9} {:>9} {:>12} {:>10} {:>10}",
        "t (s)", "steps", "density", "diverg.", "viscos.", "unconverged", "err avg %", "err max %"
    );
    let frame = 1.0 / 60.0;
    let frames_per_row = 6;
    let rows = (seconds / (frame * frames_per_row as f32)).round() as u32;
    for _ in 0..rows {
        let (mut steps, mut density, mut divergence, mut viscosity) = (0u32, 0u32, 0u32, 0u32);
        let (mut unconverged, mut avg, mut max) = (0u32, 0.0f64, 0.0f32);
        for _ in 0..frames_per_row {
            let r = world.advance(frame)?;
            steps += r.substeps;
            density += r.iterations;
            divergence += r.divergence_iterations;
            viscosity += r.viscosity_iterations;
            unconverged += r.unconverged;
            avg += f64::from(r.density_error_avg) * f64::from(r.substeps);
            max = max.max(r.density_error_max);
        }
        let per = |n: u32| f64::from(n) / f64::from(steps);
        println!(
            "{:>6.2} {:>6} {:>9.2} {:>9.2} {:>9.2} {:>12} {:>10.4} {:>10.3}",
            world.time(),
            steps,
            per(density),
            per(divergence),
            per(viscosity),
            unconverged,
            100.0 * avg / f64::from(steps),
            100.0 * max
        );
    }
    Ok(())
}
