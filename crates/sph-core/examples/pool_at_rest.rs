//! Water at rest, per solver: issue 41's pool (0.6 × 0.2 × 0.6 m at 2 cm,
//! h = 4 cm, 9,000 particles, still from the start) after 2 s of 60 Hz
//! frames, and the same pool 25 layers (0.5 m) deep. Printed, away from the
//! side walls (more than 2h): the rms speed of every particle, the first
//! layer's mean height above the floor against half a spacing, and the
//! free surface (the mean over columns h square of their highest particle
//! plus half a spacing) against the filled height.
//!
//! ```text
//! cargo run --release -p sph-core --example pool_at_rest
//! ```

use std::collections::HashMap;

use sph_core::{Scene, SolverKind};

fn main() -> sph_core::Result<()> {
    let (side, s) = (0.6f32, 0.02f32);
    println!(
        "depth  solver  rms speed (mm/s)  first layer (mm, ½ spacing = {:.0})  free surface (m)",
        500.0 * s
    );
    for depth in [0.2f32, 0.5] {
        for kind in [SolverKind::Dfsph, SolverKind::Pbf, SolverKind::Wcsph] {
            let mut scene = Scene::dam_break(0.15, side, s).with_solver(kind);
            scene.domain.min = [0.0; 3];
            scene.domain.max = [side, depth + 0.2, side];
            scene.blocks[0].min = [0.0; 3];
            scene.blocks[0].max = [side, depth, side];
            let h = scene.fluid.h;
            let mut world = scene.build_world()?;
            for _ in 0..120 {
                world.advance(1.0 / 60.0)?;
            }
            let p = &world.particles;
            let rms = (p.velocities().iter())
                .map(|v| f64::from(v.length_squared()))
                .sum::<f64>()
                / p.len() as f64;
            let inside = |c: f32| c > 2.0 * h && c < side - 2.0 * h;
            let (mut first, mut count) = (0.0f64, 0usize);
            let mut tops: HashMap<(i32, i32), f32> = HashMap::new();
            for x in p.positions().iter().filter(|x| inside(x.x) && inside(x.z)) {
                if x.y < s {
                    first += f64::from(x.y);
                    count += 1;
                }
                let cell = ((x.x / h) as i32, (x.z / h) as i32);
                let top = tops.entry(cell).or_insert(f32::MIN);
                *top = top.max(x.y);
            }
            let surface =
                tops.values().map(|&y| f64::from(y + 0.5 * s)).sum::<f64>() / tops.len() as f64;
            println!(
                "{depth:5.2}  {kind:6}  {:16.1}  {:>34.2}  {surface:.4} ({:+.2} %)",
                1e3 * rms.sqrt(),
                1e3 * first / count.max(1) as f64,
                100.0 * (surface / f64::from(depth) - 1.0)
            );
        }
    }
    Ok(())
}
