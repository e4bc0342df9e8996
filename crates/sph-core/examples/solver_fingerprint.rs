//! A fingerprint of each solver's state after a few frames of
//! `dam-break-fine` (the slab dam break at 1 cm spacing, 10,000 particles):
//! a hash of every particle's position, velocity, density and pressure
//! bits, with the last frame's report. Refactors that must leave the
//! results bitwise as they were (a change of threading, of SIMD lanes, of
//! how passes are cut) print the same line before and after, at any
//! `RAYON_NUM_THREADS` and `SPH_SIMD` level.
//!
//! ```text
//! cargo run --release -p sph-core --example solver_fingerprint
//! ```
//!
//! The hash is std's `DefaultHasher`: compare binaries built with one
//! toolchain.

use std::hash::{DefaultHasher, Hash, Hasher};

use sph_core::{Result, Scene, SolverKind};

fn main() -> Result<()> {
    // WCSPH takes about 100 substeps a frame: fewer frames.
    for (kind, frames) in [
        (SolverKind::Pbf, 30),
        (SolverKind::Dfsph, 30),
        (SolverKind::Wcsph, 5),
    ] {
        let scene = Scene::dam_break(0.25, 0.08, 0.01).with_solver(kind);
        let mut world = scene.build_world()?;
        let mut report = None;
        for _ in 0..frames {
            report = Some(world.advance(1.0 / 60.0)?);
        }
        let mut hash = DefaultHasher::new();
        let p = &world.particles;
        for v in p.positions().iter().chain(p.velocities()) {
            v.to_array().map(f32::to_bits).hash(&mut hash);
        }
        for x in p.densities().iter().chain(p.pressures()) {
            x.to_bits().hash(&mut hash);
        }
        let Some(r) = report else { continue };
        println!(
            "{:<6} after {frames} frames: {:016x}; last frame: {} substeps, {} + {} + {} iterations, density error {:e} average, {:e} largest",
            kind.name(),
            hash.finish(),
            r.substeps,
            r.iterations,
            r.divergence_iterations,
            r.viscosity_iterations,
            r.density_error_avg,
            r.density_error_max
        );
    }
    Ok(())
}
