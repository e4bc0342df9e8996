//! Efficiency and coverage of the default mode from frame to frame of two dam
//! breaks: how much the figures of one frame (a test's, a bench's) say about
//! the others.
//!
//! ```sh
//! cargo run --release -p surfel-extract --example efficiency_over_frames
//! ```
//!
//! The scenes are the tests' 600-particle slab (`Scene::dam_break(0.2, 0.06,
//! 0.02)`, two to three particles thick) and the `extraction` bench's
//! 2,250-particle dam break (`Scene::dam_break(0.15, 0.05, 0.01)`), each
//! advanced frame by frame. For every frame and 2 and 3 iterations it prints
//! the efficiency (surfels per surfel evaluation) and the coverage of
//! independently found iso-surface points (spacing h/4, within h/10).

use sph_core::Scene;
use surfel_extract::coverage::{covered_fraction, iso_points};
use surfel_extract::{ColourField, ExtractParams, extract_field};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    for (a, depth, spacing) in [(0.2f32, 0.06f32, 0.02f32), (0.15, 0.05, 0.01)] {
        let mut world = Scene::dam_break(a, depth, spacing).build_world()?;
        let h = 2.0 * spacing;
        println!(
            "Scene::dam_break({a}, {depth}, {spacing}), {} particles, h = {h}: efficiency / coverage",
            world.particles.len()
        );
        for t in [0.1f32, 0.2, 0.3, 0.4, 0.5, 0.6, 0.8] {
            world.advance(t - world.time() as f32)?;
            let field = ColourField::from_particles(&world.particles, h)?;
            let points = iso_points(&field, 0.5, 0.25 * h).expect("iso points");
            let mut line = format!("  t = {t:.1} s:");
            for iterations in [2, 3] {
                let params = ExtractParams {
                    iterations,
                    ..ExtractParams::new(h)
                };
                let out = extract_field(&field, &params)?;
                let coverage = covered_fraction(&out.surfels, &points, 0.1 * h)?;
                line += &format!(
                    "  {iterations} iterations {:.3} / {:.2} %",
                    out.stats.efficiency(),
                    100.0 * coverage
                );
            }
            println!("{line}");
        }
    }
    Ok(())
}
