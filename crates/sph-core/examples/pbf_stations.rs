//! Where a PBF substep's time goes: `dam-break-fine` (the slab dam break at
//! 1 cm spacing, 10,000 particles) for 0.5 simulated s, its program rebuilt
//! from the public stations with each one timed, printed per substep.
//!
//! ```text
//! cargo run --release -p sph-core --example pbf_stations
//! SPH_SIMD=baseline cargo run --release -p sph-core --example pbf_stations
//! cargo run --release -p sph-core --example pbf_stations -- --gauss-seidel
//! cargo run --release -p sph-core --example pbf_stations -- --gauss-seidel --warm 0.5 --surface-target
//! ```
//!
//! `--warm W` and `--surface-target` (with `--gauss-seidel`) set
//! [`PbfParams::warm_start`] and [`PbfParams::surface_target`].

use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use sph_core::solver::pbf::{BodyForces, FindNeighbours, Predict, SolveDensity, VorticityXsph};
use sph_core::solver::{Boundaries, BuildGrid};
use sph_core::{Context, Particles, PbfParams, PbfSolve, Processor, Result, Scene, SolverKind};

/// A station and the wall time it took, summed.
struct Timed<P> {
    inner: P,
    total: Arc<Mutex<Duration>>,
}

impl<P: Processor> Processor for Timed<P> {
    fn name(&self) -> &str {
        self.inner.name()
    }
    fn process(&mut self, particles: &mut Particles, ctx: &mut Context) -> Result<()> {
        let start = Instant::now();
        let result = self.inner.process(particles, ctx);
        *self.total.lock().unwrap_or_else(|e| e.into_inner()) += start.elapsed();
        result
    }
    fn runs_in_region(&self) -> bool {
        self.inner.runs_in_region()
    }
}

fn main() -> Result<()> {
    let mut scene = Scene::dam_break(0.25, 0.08, 0.01).with_solver(SolverKind::Pbf);
    let args: Vec<String> = std::env::args().collect();
    if args.iter().any(|a| a == "--gauss-seidel") {
        let warm = match args.iter().position(|a| a == "--warm") {
            Some(k) => {
                let value = args.get(k + 1).and_then(|w| w.parse().ok());
                value.ok_or_else(|| sph_core::Error::InvalidParameter {
                    name: "--warm",
                    value: args.get(k + 1).cloned().unwrap_or_default(),
                    reason: "expected a share of the last pressure, e.g. --warm 0.5",
                })?
            }
            None => 0.0,
        };
        scene.solver.pbf = Some(PbfParams {
            solve: PbfSolve::GaussSeidel,
            warm_start: warm,
            surface_target: args.iter().any(|a| a == "--surface-target"),
            ..scene.pbf_params()
        });
    }
    let mut world = scene.build_world()?;
    let (params, pbf, boundary) = (*world.params(), scene.pbf_params(), scene.boundary());
    let stations: Vec<Box<dyn Processor>> = vec![
        Box::new(BodyForces::new(params.gravity)),
        Box::new(Predict::new(
            boundary.clone(),
            pbf.max_displacement * params.h,
        )?),
        Box::new(BuildGrid::new(params.h, 1)),
        Box::new(FindNeighbours::new(params.h)),
        Box::new(SolveDensity::new(params, pbf, boundary.clone())?),
        Box::new(VorticityXsph::new(params, pbf, boundary.clone())?),
        Box::new(Boundaries::new(boundary)?),
    ];
    let names: Vec<String> = world.program_mut().names().map(str::to_owned).collect();
    let program = world.program_mut();
    for name in &names {
        program.remove(name);
    }
    let mut totals = Vec::new();
    for inner in stations {
        let total = Arc::new(Mutex::new(Duration::ZERO));
        totals.push((inner.name().to_owned(), total.clone()));
        program.push(Timed { inner, total });
    }
    let start = Instant::now();
    for _ in 0..30 {
        world.advance(1.0 / 60.0)?;
    }
    let wall = start.elapsed().as_secs_f64();
    let steps = world.steps() as f64;
    println!(
        "{} particles, {} substeps of {} iterations, {} path: {:.3} wall s per simulated s, {:.2} ms per substep",
        world.particles.len(),
        world.steps(),
        pbf.iterations,
        sph_core::simd_level().name(),
        wall / world.time(),
        wall * 1e3 / steps
    );
    for (name, total) in totals {
        let t = total
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .as_secs_f64();
        println!(
            "  {name:<11} {:>6.2} ms per substep {:>5.1} %",
            t * 1e3 / steps,
            100.0 * t / wall
        );
    }
    Ok(())
}
