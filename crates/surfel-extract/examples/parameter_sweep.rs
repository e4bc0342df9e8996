//! Efficiency and coverage against the initial guess's two thresholds, on the
//! `extraction` bench's frames: what the thesis's efficiency figure depends on.
//!
//! ```sh
//! cargo run --release -p surfel-extract --example parameter_sweep [-- 100k]
//! ```
//!
//! For each `interior_step` (particles whose Newton-Raphson step is longer are
//! interior) and `discard_step` (surfels whose step is longer are dropped), at
//! 2 and 3 iterations, it prints surfels, surfel evaluations, efficiency
//! (surfels per surfel evaluation) and coverage of independently found
//! iso-surface points, for the default mode (hole closing) and the thesis mode.

use sph_core::{Particles, Scene};
use surfel_extract::coverage::{covered_fraction, iso_points};
use surfel_extract::{ColourField, ExtractParams, Stats, Surfel, extract};

/// The dam break `Scene::dam_break(a, depth, 0.01)` after `t` seconds.
fn frame(a: f32, depth: f32, t: f32) -> Result<Particles, Box<dyn std::error::Error>> {
    let mut world = Scene::dam_break(a, depth, 0.01).build_world()?;
    world.advance(t)?;
    Ok(world.particles)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let (label, particles) = if std::env::args().any(|a| a == "100k") {
        ("100k", frame(0.37, 0.37, 0.1)?)
    } else {
        ("2k", frame(0.15, 0.05, 0.3)?)
    };
    let h = 0.02;
    let field = ColourField::from_particles(&particles, h)?;
    let points = iso_points(&field, 0.5, 0.25 * h).expect("iso points");
    println!(
        "{label} frame: {} particles, {} iso points",
        particles.len(),
        points.len()
    );
    println!(
        "interior_step discard_step iterations | default: surfels evals efficiency coverage | thesis: surfels evals efficiency coverage"
    );
    let defaults = ExtractParams::new(h);
    for interior_step in [0.5, 0.6, defaults.interior_step] {
        for discard_step in [defaults.discard_step, 0.35, 0.5] {
            for iterations in [2, 3] {
                let params = ExtractParams {
                    iterations,
                    interior_step,
                    discard_step,
                    ..defaults
                };
                let row = |p: &ExtractParams| -> Result<String, Box<dyn std::error::Error>> {
                    let out = extract(&particles, p)?;
                    let Stats {
                        surfels,
                        evaluations,
                        ..
                    } = out.stats;
                    let coverage = covered(&out.surfels, &points, h)?;
                    Ok(format!(
                        "{surfels:>7} {evaluations:>7} {:.3} {coverage:6.2} %",
                        out.stats.efficiency()
                    ))
                };
                println!(
                    "{interior_step:>13} {discard_step:>12} {iterations:>10} | {} | {}",
                    row(&params)?,
                    row(&params.thesis())?
                );
            }
        }
    }
    Ok(())
}

/// Per cent of `points` on a surfel disc within h/10 of its plane.
fn covered(
    surfels: &[Surfel],
    points: &[glam::Vec3],
    h: f32,
) -> Result<f64, Box<dyn std::error::Error>> {
    Ok(100.0 * covered_fraction(surfels, points, 0.1 * h)?)
}
