//! PBF's density error against its substeps, iterations and
//! over-relaxation ω: a tank 0.3 m wide and 8 cm deep, water 10 and 25
//! particles deep (0.2 and 0.5 m, spacing 0.02 m), settled for 2 s of 60 Hz
//! frames; printed: the average density error over the third second, the
//! rms speed at its end (the jitter of water at rest), and the wall time
//! per simulated second.
//!
//! ```text
//! cargo run --release -p sph-core --example pbf_convergence
//! ```

use std::time::Instant;

use sph_core::{PbfParams, Scene, SolverKind};

fn main() -> sph_core::Result<()> {
    println!("depth  substeps × iterations @ ω  density error avg  rms speed m/s  wall s per s");
    let settings = [
        (2, 4, 1.0),
        (2, 6, 1.0),
        (3, 2, 1.0),
        (3, 2, 1.25),
        (3, 3, 1.0),
        (3, 3, 1.25),
        (3, 4, 1.0),
        (4, 3, 1.0),
        (5, 3, 1.0),
        (5, 3, 1.25),
    ];
    for depth in [0.2f32, 0.5] {
        for (substeps, iterations, over_relaxation) in settings {
            let mut scene = Scene::dam_break(0.3, 0.08, 0.02).with_solver(SolverKind::Pbf);
            scene.domain.max = [0.3, depth + 0.1, 0.08];
            scene.blocks[0].max = [0.3, depth, 0.08];
            scene.solver.pbf = Some(PbfParams {
                substeps,
                iterations,
                over_relaxation,
                max_dt: 1.0,
                ..PbfParams::default()
            });
            let mut world = scene.build_world()?;
            let (mut error, mut frames) = (0.0f64, 0);
            let start = Instant::now();
            for frame in 0..180 {
                let r = world.advance(1.0 / 60.0)?;
                if frame >= 120 {
                    error += f64::from(r.density_error_avg);
                    frames += 1;
                }
            }
            let wall = start.elapsed().as_secs_f64() / world.time();
            let v = world.particles.velocities();
            let squares: f64 = v.iter().map(|v| f64::from(v.length_squared())).sum();
            let rms = (squares / v.len() as f64).sqrt();
            println!(
                "{depth:.1} m  {substeps} × {iterations} @ {over_relaxation:<4}  {:>8.3} %  {rms:>8.3}  {wall:>8.3}",
                100.0 * error / f64::from(frames),
            );
        }
    }
    Ok(())
}
