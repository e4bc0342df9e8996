//! PBF's cost, density error and spray against its substeps and iterations
//! per frame: `dam-break-fine` (the slab dam break at 1 cm spacing, 10,000
//! particles) for one simulated second of 60 Hz frames per setting. Spray
//! is the fraction of particles in clusters of at most 10 (linked where
//! closer than h, as in the `spray` example), every 0.1 s: its largest
//! value and the mean.
//!
//! A setting is SUBSTEPSxITERATIONS, optionally followed by `@ω` (the
//! over-relaxation) and `/c` (XSPH's c), and `+gs` for the Gauss–Seidel
//! solve ([`sph_core::PbfSolve::GaussSeidel`]), `+gsW` with the warm start
//! W ([`sph_core::PbfParams::warm_start`]); what it leaves out takes the
//! defaults ([`sph_core::PbfParams`]). `5x2@1/0.01` is the paper's plain
//! Jacobi and XSPH at 5 substeps of 2 iterations, `5x3+gs` Gauss–Seidel at
//! 5 substeps of 3 sweeps, `5x3+gs0.5` the same warm-started by half.
//!
//! ```text
//! cargo run --release -p sph-core --example pbf_substeps [-- 5x2 6x3@1/0.01 5x2@1.3 ...]
//! ```

mod common;

use std::time::Instant;

use common::cluster_sizes;
use sph_core::{PbfParams, PbfSolve, Scene, SolverKind};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut settings: Vec<String> = std::env::args().skip(1).collect();
    if settings.is_empty() {
        settings = ["6x3@1/0.01", "5x2@1/0.01", "5x2@1.3", "5x2", "4x2", "3x3"]
            .map(String::from)
            .to_vec();
    }
    println!(
        "{:>12} {:>9} {:>12} {:>10} {:>10} {:>8} {:>13} {:>14}",
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
        let mut scene = Scene::dam_break(0.25, 0.08, 0.01).with_solver(SolverKind::Pbf);
        let frame = 1.0 / 60.0;
        let defaults = scene.pbf_params();
        let parse = || -> Option<PbfParams> {
            let (body, solve, warm) = match setting.split_once("+gs") {
                Some((body, "")) => (body, PbfSolve::GaussSeidel, 0.0),
                Some((body, warm)) => (body, PbfSolve::GaussSeidel, warm.parse().ok()?),
                None => (setting.as_str(), PbfSolve::Jacobi, 0.0),
            };
            let (counts, rest) = body.split_once('@').unwrap_or((body, ""));
            let (omega, c) = rest.split_once('/').unwrap_or((rest, ""));
            let (s, i) = counts.split_once('x')?;
            let substeps: u32 = s.parse().ok()?;
            let value = |v: &str, default: f32| match v {
                "" => Some(default),
                v => v.parse().ok(),
            };
            Some(PbfParams {
                substeps,
                iterations: i.parse().ok()?,
                solve,
                warm_start: warm,
                over_relaxation: value(omega, defaults.over_relaxation)?,
                xsph: value(c, defaults.xsph)?,
                max_dt: frame / substeps as f32,
                ..defaults
            })
        };
        let pbf = parse().ok_or(format!(
            "{setting}: expected SUBSTEPSxITERATIONS[@OMEGA][/XSPH][+gs[WARM]], e.g. 5x2@1.4/0.05"
        ))?;
        scene.solver.pbf = Some(pbf);
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
            "{:>12} {:>9} {:>12.3} {:>10.3} {:>10.1} {:>8} {:>13.2} {:>14.2}",
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
