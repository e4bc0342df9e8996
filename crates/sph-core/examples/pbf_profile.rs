use std::time::{Duration, Instant};
use sph_core::*;
use sph_core::solver::pbf::*;
use sph_core::solver::{BuildGrid, Boundaries};
struct Timed<P>(P, std::sync::Arc<std::sync::Mutex<Duration>>);
impl<P: Processor> Processor for Timed<P> {
    fn name(&self) -> &str { self.0.name() }
    fn process(&mut self, p: &mut Particles, c: &mut Context) -> Result<()> {
        let t = Instant::now(); let r = self.0.process(p, c); *self.1.lock().unwrap() += t.elapsed(); r
    }
}
fn main() -> Result<()> {
    let scene = Scene::dam_break(0.25, 0.08, 0.01).with_solver(SolverKind::Pbf);
    let mut world = scene.build_world()?;
    let (params, pbf, b) = (*world.params(), scene.solver.pbf, scene.boundary());
    let names = ["forces","predict","grid","neighbours","density","viscosity","boundaries"];
    let times: Vec<_> = names.iter().map(|_| std::sync::Arc::new(std::sync::Mutex::new(Duration::ZERO))).collect();
    let prog = world.program_mut();
    for n in names { prog.remove(n); }
    prog.push(Timed(BodyForces::new(params.gravity), times[0].clone()))
        .push(Timed(Predict::new(b.clone(), pbf.max_displacement * params.h)?, times[1].clone()))
        .push(Timed(BuildGrid::new(params.h, 1), times[2].clone()))
        .push(Timed(FindNeighbours::new(params.h), times[3].clone()))
        .push(Timed(SolveDensity::new_for(params, pbf, b.clone())?, times[4].clone()))
        .push(Timed(VorticityXsph::new_for(params, pbf, b.clone())?, times[5].clone()))
        .push(Timed(Boundaries::new(b.clone())?, times[6].clone()));
    let t = Instant::now();
    for _ in 0..30 { world.advance(1.0/60.0)?; }
    let total = t.elapsed();
    println!("{} particles, {} substeps, total {:.3} s (sim s/s {:.3})", world.particles.len(), world.steps(), total.as_secs_f64(), total.as_secs_f64()/0.5);
    for (n, t) in names.iter().zip(&times) { let t = *t.lock().unwrap(); println!("{n:<12} {:>8.2} ms/substep {:>5.1} %", t.as_secs_f64()*1e3/world.steps() as f64, 100.0*t.as_secs_f64()/total.as_secs_f64()); }
    Ok(())
}
