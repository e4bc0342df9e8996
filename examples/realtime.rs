//! The real-time benchmark: the slab dam break (`Scene::dam_break(0.25,
//! 0.08, spacing)`, the demo's `dam-break` at 0.02 m and `dam-break-fine` at
//! 0.01 m) at about 1k, 3k, 10k, 30k and 100k particles, every solver in the
//! same run, for whole simulated seconds of 60 Hz frames.
//!
//! For each row it prints the wall seconds per simulated second of the
//! simulation alone and of simulation + surfel extraction (2 iterations,
//! the demo's default), the substeps and iterations per frame (PBF's
//! constraint iterations; DFSPH's density and divergence solves'),
//! and the average and largest density error, then the largest particle
//! count each solver holds at real time (wall s per simulated s ≤ 1), found
//! by bisection on the spacing (seven runs per solver), and the largest
//! row at real time.
//!
//! ```text
//! cargo run --release --example realtime [-- --seconds S] [--solvers wcsph,pbf,dfsph] [--max-particles N]
//!     [--pbf substeps=2,iterations=4]
//! ```

use std::time::Instant;

use sph_core::{PbfParams, Scene, SolverKind};
use surfel_extract::{ExtractParams, Extractor};

/// Particle spacings (m) of the rows: 1,200, 3,816, 10,000, 33,300 and
/// 103,896 particles.
const SPACINGS: [f32; 5] = [0.02, 0.0133, 0.01, 0.0067, 0.00455];
const FRAME_DT: f32 = 1.0 / 60.0;

struct Row {
    solver: SolverKind,
    particles: usize,
    sim_s: f64,
    extract_s: f64,
    substeps: f64,
    iterations: f64,
    divergence: f64,
    error_avg: f64,
    error_max: f32,
    clamped: u64,
}

fn run(
    kind: SolverKind,
    spacing: f32,
    seconds: f64,
    pbf: Option<&PbfParams>,
) -> Result<Row, Box<dyn std::error::Error>> {
    let mut scene = Scene::dam_break(0.25, 0.08, spacing).with_solver(kind);
    if let Some(pbf) = pbf {
        scene.solver.pbf = Some(*pbf);
    }
    let mut world = scene.build_world()?;
    let mut extractor = Extractor::new();
    let params = ExtractParams {
        iterations: 2,
        ..ExtractParams::new(world.params().h)
    };
    let frames = (seconds / f64::from(FRAME_DT)).round() as u32;
    let mut row = Row {
        solver: kind,
        particles: world.particles.len(),
        sim_s: 0.0,
        extract_s: 0.0,
        substeps: 0.0,
        iterations: 0.0,
        divergence: 0.0,
        error_avg: 0.0,
        error_max: 0.0,
        clamped: 0,
    };
    for _ in 0..frames {
        let start = Instant::now();
        let report = world.advance(FRAME_DT)?;
        row.sim_s += start.elapsed().as_secs_f64();
        let start = Instant::now();
        extractor.extract(&world.particles, &params)?;
        row.extract_s += start.elapsed().as_secs_f64();
        row.substeps += f64::from(report.substeps);
        row.iterations += f64::from(report.iterations);
        row.divergence += f64::from(report.divergence_iterations);
        row.error_avg += f64::from(report.density_error_avg);
        row.error_max = row.error_max.max(report.density_error_max);
        row.clamped += report.clamped;
    }
    let frames = f64::from(frames);
    row.substeps /= frames;
    row.iterations /= frames;
    row.divergence /= frames;
    row.error_avg /= frames;
    Ok(row)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut seconds = 1.0;
    let mut solvers = SolverKind::ALL.to_vec();
    let mut max_particles = usize::MAX;
    let mut pbf = None;
    let mut args = std::env::args().skip(1);
    while let Some(arg) = args.next() {
        let mut value = || args.next().ok_or(format!("{arg} needs a value"));
        match arg.as_str() {
            "--seconds" => seconds = value()?.parse()?,
            "--max-particles" => max_particles = value()?.parse()?,
            "--solvers" => {
                solvers = value()?
                    .split(',')
                    .map(|s| SolverKind::from_name(s).ok_or(format!("unknown solver {s}")))
                    .collect::<Result<_, _>>()?
            }
            // PBF parameters as `key=value` pairs, e.g. `substeps=3,iterations=4`.
            "--pbf" => {
                let table = value()?.replace(',', "\n");
                pbf = Some(toml::from_str::<PbfParams>(&table)?);
            }
            "--bench" => {} // cargo bench passes it
            other => return Err(format!("unknown argument {other}").into()),
        }
    }
    if !(seconds > 0.0 && seconds <= 100.0) {
        return Err("--seconds must lie in (0, 100]".into());
    }
    println!(
        "slab dam break, {seconds} simulated s of 60 Hz frames, {} threads, extraction 2 iterations",
        rayon::current_num_threads()
    );
    println!(
        "{:<6} {:>9} {:>12} {:>14} {:>9} {:>11} {:>8} {:>10} {:>10} {:>8}",
        "solver",
        "particles",
        "sim s/sim s",
        "+extract s/s",
        "substeps",
        "iterations",
        "div it",
        "err avg %",
        "err max %",
        "clamped"
    );
    let mut rows = Vec::new();
    for spacing in SPACINGS {
        for &kind in &solvers {
            let count = Scene::dam_break(0.25, 0.08, spacing).particles()?.len();
            if count > max_particles {
                continue;
            }
            let r = run(kind, spacing, seconds, pbf.as_ref())?;
            let per = |s: f64| s / seconds;
            println!(
                "{:<6} {:>9} {:>12.3} {:>14.3} {:>9.1} {:>11.1} {:>8.1} {:>10.3} {:>10.2} {:>8}",
                r.solver.name(),
                r.particles,
                per(r.sim_s),
                per(r.sim_s + r.extract_s),
                r.substeps,
                r.iterations,
                r.divergence,
                r.error_avg * 100.0,
                r.error_max * 100.0,
                r.clamped
            );
            rows.push(r);
        }
    }
    // The largest count each solver holds at real time, simulation alone:
    // bisection on the spacing between the rows that straddle it.
    for &kind in &solvers {
        let (mut lo, mut hi) = (0.003f32, 0.04f32); // fine (slow) .. coarse (fast)
        let mut best: Option<Row> = None;
        for _ in 0..7 {
            let mid = (lo * hi).sqrt();
            let r = run(kind, mid, seconds, pbf.as_ref())?;
            if r.sim_s <= seconds {
                hi = mid;
                if best.as_ref().is_none_or(|b| r.particles > b.particles) {
                    best = Some(r);
                }
            } else {
                lo = mid;
            }
        }
        match best {
            Some(r) => println!(
                "{}: real time (simulation) up to about {} particles (spacing {hi:.4} m: {:.3} s/s, {:.1} substeps, {:.3} % density error)",
                kind.name(),
                r.particles,
                r.sim_s / seconds,
                r.substeps,
                r.error_avg * 100.0
            ),
            None => println!("{}: not real time even at spacing {hi} m", kind.name()),
        }
    }
    for kind in solvers {
        let best = |f: &dyn Fn(&Row) -> f64| {
            rows.iter()
                .filter(|r| r.solver == kind && f(r) <= seconds)
                .map(|r| r.particles)
                .max()
        };
        let show = |n: Option<usize>| n.map_or("none".to_string(), |n| n.to_string());
        println!(
            "{}: largest count at real time {} (simulation), {} (with extraction)",
            kind.name(),
            show(best(&|r| r.sim_s)),
            show(best(&|r| r.sim_s + r.extract_s))
        );
    }
    Ok(())
}
