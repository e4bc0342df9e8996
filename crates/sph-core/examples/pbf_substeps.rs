//! PBF's cost, density error and spray against its substeps and iterations
//! per frame: `dam-break-fine` (the slab dam break at 1 cm spacing, 10,000
//! particles) for one simulated second of 60 Hz frames per setting. Spray
//! is the fraction of particles in clusters of at most 10 (linked where
//! closer than h, as in the `spray` example), every 0.1 s: its largest
//! value and the mean.
//!
//! ```text
//! cargo run --release -p sph-core --example pbf_substeps [-- 6x3 4x4 3x6 ...]
//! ```

mod common;

use std::time::Instant;

use common::cluster_sizes;
use sph_core::{PbfParams, Scene, SolverKind};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut settings: Vec<String> = std::env::args().skip(1).collect();
    if settings.is_empty() {
        settings = ["6x3", "4x4", "3x6", "3x3", "2x6"]
            .map(String::from)
            .to_vec();
    }
    println!(
        "{:>9} {:>9} {:>12} {:>10} {:>10} {:>8} {:>13} {:>14}",
        "setting",
        "particles",
        "wall s/s",
        "err avg %",
        "err max %",
        "clamped",
        "spray max %",
        "spray mean %"
    );
    for setting in settings {
        let parse = || -> Option<(u32, u32)> {
            let (s, i) = setting.split_once('x')?;
            Some((s.parse().ok()?, i.parse().ok()?))
        };
        let (substeps, iterations) =
            parse().ok_or(format!("{setting}: expected SUBSTEPSxITERATIONS, e.g. 6x3"))?;
        let mut scene = Scene::dam_break(0.25, 0.08, 0.01).with_solver(SolverKind::Pbf);
        let frame = 1.0 / 60.0;
        scene.solver.pbf = Some(PbfParams {
            substeps,
            iterations,
            max_dt: frame / substeps as f32,
            ..scene.pbf_params()
        });
        let mut world = scene.build_world()?;
        let (mut wall, mut avg, mut max, mut clamped) = (0.0, 0.0f64, 0.0f32, 0);
        let mut spray = Vec::new();
        for frame_number in 1..=60 {
            let start = Instant::now();
            let report = world.advance(frame)?;
            wall += start.elapsed().as_secs_f64();
            avg += f64::from(report.density_error_avg) / 60.0;
            max = max.max(report.density_error_max);
            clamped += report.clamped;
            if frame_number % 6 == 0 {
                let sizes = cluster_sizes(world.particles.positions(), world.params().h)?;
                let small = sizes.iter().filter(|&&s| s <= 10).count();
                spray.push(small as f64 / sizes.len().max(1) as f64);
            }
        }
        println!(
            "{:>9} {:>9} {:>12.3} {:>10.3} {:>10.1} {:>8} {:>13.2} {:>14.2}",
            setting,
            world.particles.len(),
            wall,
            avg * 100.0,
            max * 100.0,
            clamped,
            100.0 * spray.iter().copied().fold(0.0, f64::max),
            100.0 * spray.iter().sum::<f64>() / spray.len() as f64
        );
    }
    Ok(())
}
