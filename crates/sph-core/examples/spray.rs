//! Spray: the fraction of particles in small clusters (at most 10 particles,
//! linked where closer than h) of the `drop` scene (the demo's key 4,
//! `Scene::drop_into_pool(0.2, 0.02)`) at t = 0.5 s, for each solver.
//!
//! ```text
//! cargo run --release -p sph-core --example spray
//! ```

mod common;

use common::cluster_sizes;
use sph_core::{Scene, SolverKind};

fn main() -> sph_core::Result<()> {
    for kind in SolverKind::ALL {
        let scene = Scene::drop_into_pool(0.2, 0.02).with_solver(kind);
        let mut world = scene.build_world()?;
        let mut substeps = 0;
        for _ in 0..30 {
            substeps += world.advance(1.0 / 60.0)?.substeps;
        }
        let sizes = cluster_sizes(world.particles.positions(), world.params().h)?;
        let n = sizes.len();
        let small = sizes.iter().filter(|&&s| s <= 10).count();
        let lone = sizes.iter().filter(|&&s| s == 1).count();
        println!(
            "{kind:<6} t = {:.2} s ({substeps} substeps): {small} of {n} particles in clusters of ≤ 10 ({:.1} %), {lone} alone",
            world.time(),
            100.0 * small as f64 / n as f64
        );
    }
    Ok(())
}
