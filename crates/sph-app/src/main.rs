//! The sph-splat demo.
//!
//! Until the solver, extractor and renderer land, it sets up the default scene's
//! particles (the dam-break water column), builds the neighbour grid over them and
//! prints what it did.

use std::process::ExitCode;
use std::time::Instant;

use sph_core::{NeighbourGrid, Particles, glam::Vec3};

/// Default scene: a water column of width a = 0.3 m and height 2a, depth 0.15 m, at
/// spacing h/2 with h = 0.02 m (about 33 neighbours per particle).
const A: f32 = 0.3;
const H: f32 = 0.02;
const REST_DENSITY: f32 = 1000.0;

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
    let spacing = H / 2.0;
    let mass = REST_DENSITY * spacing.powi(3);
    let dims = [A, 2.0 * A, A / 2.0].map(|l| (l / spacing).round() as usize);
    let mut particles = Particles::new();
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                let p = (Vec3::new(i as f32, j as f32, k as f32) + 0.5) * spacing;
                particles.push(p, Vec3::ZERO, mass);
            }
        }
    }
    println!(
        "default scene: dam-break column {A} m × {} m × {} m, {} particles at spacing {spacing} m, h = {H} m",
        2.0 * A,
        A / 2.0,
        particles.len()
    );

    let t = Instant::now();
    let grid = NeighbourGrid::build(particles.positions(), H)?;
    let built = t.elapsed();
    let t = Instant::now();
    let counts = grid.par_map(|_, n| n.count() as u32 - 1);
    let queried = t.elapsed();
    let pairs: u64 = counts.iter().map(|&c| c as u64).sum();
    println!(
        "neighbour grid: {} occupied cells, built in {:.2} ms; {pairs} neighbour pairs \
         ({:.1} per particle) enumerated in {:.2} ms",
        grid.cell_count(),
        built.as_secs_f64() * 1e3,
        pairs as f64 / particles.len().max(1) as f64,
        queried.as_secs_f64() * 1e3,
    );
    println!("the solver, surfel extraction and rendering are not implemented yet (see README.md)");
    Ok(())
}
