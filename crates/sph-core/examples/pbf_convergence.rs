//! PBF's density error against its substeps and iterations: a tank 0.3 m
//! wide and 8 cm deep, water 10 and 25 particles deep (0.2 and 0.5 m,
//! spacing 0.02 m), settled for 2 s of 60 Hz frames; printed: the average
//! density error over the third second, and the wall time per simulated
//! second.
//!
//! ```text
//! cargo run --release -p sph-core --example pbf_convergence
//! ```

use std::time::Instant;

use sph_core::{PbfParams, Scene, SolverKind};

fn main() -> sph_core::Result<()> {
    println!("depth  substeps × iterations  density error avg  wall s per s");
    for depth in [0.2f32, 0.5] {
        for (substeps, iterations) in [(2, 4), (2, 6), (3, 3), (3, 4), (4, 3), (5, 3)] {
            let mut scene = Scene::dam_break(0.3, 0.08, 0.02).with_solver(SolverKind::Pbf);
            scene.domain.max = [0.3, depth + 0.1, 0.08];
            scene.blocks[0].max = [0.3, depth, 0.08];
            scene.solver.pbf = Some(PbfParams {
                substeps,
                iterations,
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
            println!(
                "{depth:.1} m  {substeps} × {iterations}  {:>8.3} %  {:>8.3}",
                100.0 * error / f64::from(frames),
                start.elapsed().as_secs_f64() / world.time()
            );
        }
    }
    Ok(())
}
