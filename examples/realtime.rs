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
//! The peer, `salva` (dimforge's salva3d 0.9, its DFSPH solver with its own
//! defaults: 0.05 % density and 0.1 % divergence error, its own CFL
//! substeps, no viscosity), runs the same column in the same box, whose
//! walls it samples with one layer of boundary particles at the spacing.
//! Its density error is measured as ours: the cubic spline sum over its
//! fluid and boundary particles with its own volumes. salva 0.9 takes one
//! step per call (its CFL rule is switched off), so the example cuts each
//! frame into steps by our DFSPH's rule over the particles in the box; it
//! keeps no particle in the box by force, and its "clamped" column counts
//! the particles that left it. It has no extraction and no iteration
//! columns (its iterations are not public).
//!
//! `pbf-gpu` (not in the default list; it needs a GPU adapter) runs PBF on
//! the GPU (`sph_gpu::GpuPbf`, a frame per submission) over the same rows
//! and two more, about 333k and 1M particles, without the extraction
//! column, and bisects up to about 3M.
//!
//! ```text
//! cargo run --release --example realtime [-- --seconds S] [--solvers wcsph,pbf,dfsph,salva,pbf-gpu] [--max-particles N]
//!     [--pbf substeps=2,iterations=4] [--sigma N_PER_M]
//! ```
//!
//! `--sigma` gives the fluid a surface tension (WCSPH's colour-field force,
//! PBF's and DFSPH's Akinci forces, on the GPU too), to time what it
//! costs.

use std::time::Instant;

use sph_core::glam::Vec3;
use sph_core::{CubicSpline, Kernel, NeighbourGrid, NeighbourLists, PbfParams, Scene, SolverKind};
use surfel_extract::{ExtractParams, Extractor};

/// Particle spacings (m) of the rows: 1,200, 3,816, 10,000, 33,300 and
/// 103,896 particles.
const SPACINGS: [f32; 5] = [0.02, 0.0133, 0.01, 0.0067, 0.00455];
const FRAME_DT: f32 = 1.0 / 60.0;

/// The GPU's further rows: 331,452 and 1,000,000 particles... about.
const GPU_SPACINGS: [f32; 2] = [0.0031, 0.00215];

struct Row {
    /// The solver's name: ours, or `salva` for the peer.
    solver: &'static str,
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

impl Row {
    /// A row for `solver` on `particles` particles, nothing measured yet.
    fn new(solver: &'static str, particles: usize) -> Self {
        Self {
            solver,
            particles,
            sim_s: 0.0,
            extract_s: 0.0,
            substeps: 0.0,
            iterations: 0.0,
            divergence: 0.0,
            error_avg: 0.0,
            error_max: 0.0,
            clamped: 0,
        }
    }
}

/// What the command line changes in every row's scene.
#[derive(Debug, Clone, Copy, Default)]
struct Options {
    /// `--pbf`: PBF's parameters instead of the scene's.
    pbf: Option<PbfParams>,
    /// `--sigma`: the fluid's surface tension (N/m; 0 in the scene).
    sigma: f32,
}

fn run(
    kind: SolverKind,
    spacing: f32,
    seconds: f64,
    options: &Options,
) -> Result<Row, Box<dyn std::error::Error>> {
    let mut scene = Scene::dam_break(0.25, 0.08, spacing).with_solver(kind);
    if let Some(pbf) = options.pbf {
        scene.solver.pbf = Some(pbf);
    }
    scene.fluid.surface_tension = options.sigma;
    let mut world = scene.build_world()?;
    let mut extractor = Extractor::new();
    let params = ExtractParams {
        iterations: 2,
        ..ExtractParams::new(world.params().h)
    };
    let frames = (seconds / f64::from(FRAME_DT)).round() as u32;
    let mut row = Row::new(kind.name(), world.particles.len());
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

/// The boundary particles of salva: each face of the box `min`..`max`
/// sampled on a square grid of `spacing`, in two layers (on the face and a
/// spacing behind it; one layer let the surge through the far wall).
fn box_walls(min: Vec3, max: Vec3, spacing: f32) -> Vec<Vec3> {
    let mut points = Vec::new();
    let (lo, hi) = (min - Vec3::splat(spacing), max + Vec3::splat(spacing));
    let count = |a: f32, b: f32| ((b - a) / spacing).round() as i32;
    for axis in 0..3 {
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        for (side, out) in [(min[axis], -spacing), (max[axis], spacing)] {
            for layer in 0..2 {
                for i in 0..=count(lo[u], hi[u]) {
                    for j in 0..=count(lo[v], hi[v]) {
                        let mut p = Vec3::ZERO;
                        p[axis] = side + layer as f32 * out;
                        p[u] = lo[u] + i as f32 * spacing;
                        p[v] = lo[v] + j as f32 * spacing;
                        points.push(p);
                    }
                }
            }
        }
    }
    points.sort_by(|a, b| a.to_array().partial_cmp(&b.to_array()).unwrap());
    points.dedup();
    points
}

/// The density error of salva's fluid, measured as ours: ρ_i = Σ ρ0 V_j
/// W(x_i − x_j) over its fluid and boundary particles, cubic spline of
/// support h; (average of max(ρ/ρ0 − 1, 0), largest ρ/ρ0 − 1).
fn salva_density_error(
    fluid: &[Vec3],
    volumes: &[f32],
    walls: &[Vec3],
    wall_volumes: &[f32],
    h: f32,
) -> (f64, f32) {
    let kernel = CubicSpline::new(h).unwrap();
    let all: Vec<Vec3> = fluid.iter().chain(walls).copied().collect();
    let volume: Vec<f32> = volumes.iter().chain(wall_volumes).copied().collect();
    let grid = NeighbourGrid::build(&all, h).unwrap();
    let lists = NeighbourLists::build(&grid).unwrap();
    let (mut sum, mut max) = (0.0f64, f32::MIN);
    for i in 0..fluid.len() {
        let mut rho = volume[i] * kernel.value(Vec3::ZERO);
        for &j in lists.of(i) {
            let j = j as usize;
            rho += volume[j] * kernel.value(all[i] - all[j]);
        }
        let e = rho - 1.0;
        sum += f64::from(e.max(0.0));
        max = max.max(e);
    }
    (sum / fluid.len() as f64, max)
}

/// The slab dam break at `spacing` run by salva3d's DFSPH for `seconds`.
fn run_salva(spacing: f32, seconds: f64) -> Result<Row, Box<dyn std::error::Error>> {
    use salva3d::LiquidWorld;
    use salva3d::math::{Point, Vector};
    use salva3d::object::{Boundary, Fluid};
    use salva3d::solver::DFSPHSolver;
    let scene = Scene::dam_break(0.25, 0.08, spacing);
    let particles = scene.particles()?;
    let radius = spacing / 2.0;
    // Kernel support 2 × radius × 2 = 2 spacings: the scene's h.
    let mut world = LiquidWorld::new(
        DFSPHSolver::<salva3d::kernel::CubicSplineKernel>::new(),
        radius,
        2.0,
    );
    let points = |xs: &[Vec3]| {
        xs.iter()
            .map(|x| Point::new(x.x, x.y, x.z))
            .collect::<Vec<_>>()
    };
    let fluid = world.add_fluid(Fluid::new(points(particles.positions()), radius, 1000.0));
    let walls = box_walls(scene.domain.min.into(), scene.domain.max.into(), spacing);
    let boundary = world.add_boundary(Boundary::new(points(&walls)));
    let gravity = Vector::new(0.0, -9.81, 0.0);
    let dfsph = sph_core::DfsphParams::default();
    let domain = scene.boundary();
    let inside = |p: &Point<f32>| domain.admits(Vec3::new(p.x, p.y, p.z));
    let frames = (seconds / f64::from(FRAME_DT)).round() as u32;
    let mut row = Row {
        extract_s: f64::NAN,
        ..Row::new("salva", particles.len())
    };
    let to_vec3 = |ps: &[Point<f32>]| {
        ps.iter()
            .map(|p| Vec3::new(p.x, p.y, p.z))
            .collect::<Vec<_>>()
    };
    let wall_positions = to_vec3(&world.boundaries()[boundary].positions);
    for _ in 0..frames {
        // salva takes one substep per call (its CFL is switched off in
        // 0.9): the frame is cut into steps by our DFSPH's rule, λ h / v_max
        // with v_max = max |v| + g max_dt, at most max_dt.
        let start = Instant::now();
        let mut left = FRAME_DT;
        while left > 0.0 {
            // The flow's speed in the box: particles that leaked out fall
            // on without end and would shrink the step to nothing.
            let f = &world.fluids()[fluid];
            let fastest = (f.positions.iter().zip(&f.velocities))
                .filter(|(p, _)| inside(p))
                .map(|(_, v)| v.norm())
                .fold(0.0f32, f32::max);
            let step = dfsph.step(scene.fluid.h, fastest + 9.81 * dfsph.max_dt);
            let dt = if left <= step {
                left
            } else if left < 2.0 * step {
                0.5 * left
            } else {
                step
            };
            world.step(dt, &gravity);
            left -= dt;
            row.substeps += 1.0;
        }
        row.sim_s += start.elapsed().as_secs_f64();
        let f = &world.fluids()[fluid];
        let (avg, max) = salva_density_error(
            &to_vec3(&f.positions),
            &f.volumes,
            &wall_positions,
            &world.boundaries()[boundary].volumes,
            scene.fluid.h,
        );
        row.error_avg += avg;
        row.error_max = row.error_max.max(max);
    }
    row.substeps /= f64::from(frames);
    row.error_avg /= f64::from(frames);
    // Its "clamped" column: the particles that left the box.
    row.clamped = world.fluids()[fluid]
        .positions
        .iter()
        .filter(|p| !inside(p))
        .count() as u64;
    Ok(row)
}

/// The slab dam break at `spacing` run by PBF on the GPU of `ctx`
/// (`sph_gpu::GpuPbf`) for `seconds`: each frame one submission, the wall
/// time from the first frame's recording to the device finishing the last
/// (frames overlap: the CPU records frame k + 1 while the GPU runs frame
/// k), the density errors from the frames' statistics read back late. No
/// extraction column: the `gpu` bench times the whole GPU frame.
fn run_gpu_pbf(
    ctx: &splat_render::GpuContext,
    spacing: f32,
    seconds: f64,
    pbf: Option<&PbfParams>,
    sigma: f32,
) -> Result<Row, Box<dyn std::error::Error>> {
    let mut scene = Scene::dam_break(0.25, 0.08, spacing).with_solver(SolverKind::Pbf);
    if let Some(pbf) = pbf {
        scene.solver.pbf = Some(*pbf);
    }
    scene.fluid.surface_tension = sigma;
    let particles = scene.particles()?;
    let mut gpu = sph_gpu::GpuPbf::new(
        &ctx.device,
        &ctx.queue,
        &particles,
        &scene.fluid_params(),
        &scene.pbf_params(),
        &scene.boundary(),
    )?;
    let frames = (seconds / f64::from(FRAME_DT)).round() as u32;
    let mut row = Row {
        extract_s: f64::NAN,
        ..Row::new("pbf-gpu", particles.len())
    };
    let mut stats = Vec::new();
    let start = Instant::now();
    for _ in 0..frames {
        let frame = gpu.advance(&ctx.device, &ctx.queue, FRAME_DT)?;
        row.substeps += f64::from(frame.substeps);
        row.iterations += f64::from(frame.iterations);
        stats.extend(frame.stats);
    }
    stats.extend(gpu.finish(&ctx.device)?);
    row.sim_s = start.elapsed().as_secs_f64();
    for s in &stats {
        row.error_avg += f64::from(s.density_error_avg);
        row.error_max = row.error_max.max(s.density_error_max);
        row.clamped += s.clamped;
    }
    let frames = f64::from(frames);
    row.substeps /= frames;
    row.iterations /= frames;
    row.error_avg /= frames;
    Ok(row)
}

/// One of the compared solvers: ours on the CPU or on the GPU, or salva.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Runner {
    Ours(SolverKind),
    GpuPbf,
    Salva,
}

impl Runner {
    fn name(self) -> &'static str {
        match self {
            Runner::Ours(kind) => kind.name(),
            Runner::GpuPbf => "pbf-gpu",
            Runner::Salva => "salva",
        }
    }

    fn run(
        self,
        gpu: Option<&splat_render::GpuContext>,
        spacing: f32,
        seconds: f64,
        options: &Options,
    ) -> Result<Row, Box<dyn std::error::Error>> {
        match self {
            Runner::Ours(kind) => run(kind, spacing, seconds, options),
            Runner::GpuPbf => run_gpu_pbf(
                gpu.ok_or("pbf-gpu needs a GPU adapter")?,
                spacing,
                seconds,
                options.pbf.as_ref(),
                options.sigma,
            ),
            Runner::Salva => run_salva(spacing, seconds),
        }
    }

    /// The rows' spacings: the GPU's go on to 333k and 1M particles.
    fn spacings(self) -> Vec<f32> {
        let mut all = SPACINGS.to_vec();
        if self == Runner::GpuPbf {
            all.extend(GPU_SPACINGS);
        }
        all
    }

    /// The bisection's finest spacing.
    fn finest(self) -> f32 {
        if self == Runner::GpuPbf {
            0.0012
        } else {
            0.003
        }
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut seconds = 1.0;
    let mut solvers: Vec<Runner> = SolverKind::ALL.into_iter().map(Runner::Ours).collect();
    solvers.push(Runner::Salva);
    let mut max_particles = usize::MAX;
    let mut options = Options::default();
    let mut args = std::env::args().skip(1);
    while let Some(arg) = args.next() {
        let mut value = || args.next().ok_or(format!("{arg} needs a value"));
        match arg.as_str() {
            "--seconds" => seconds = value()?.parse()?,
            "--max-particles" => max_particles = value()?.parse()?,
            "--solvers" => {
                solvers = value()?
                    .split(',')
                    .map(|s| match s {
                        "salva" => Ok(Runner::Salva),
                        "pbf-gpu" => Ok(Runner::GpuPbf),
                        _ => SolverKind::from_name(s)
                            .map(Runner::Ours)
                            .ok_or(format!("unknown solver {s}")),
                    })
                    .collect::<Result<_, _>>()?
            }
            // PBF parameters as `key=value` pairs, e.g. `substeps=3,iterations=4`.
            "--pbf" => {
                let table = value()?.replace(',', "\n");
                options.pbf = Some(toml::from_str::<PbfParams>(&table)?);
            }
            "--sigma" => options.sigma = value()?.parse()?,
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
    let gpu = if solvers.contains(&Runner::GpuPbf) {
        let ctx = splat_render::GpuContext::headless()?;
        println!("pbf-gpu on {}", ctx.adapter_summary());
        Some(ctx)
    } else {
        None
    };
    let mut rows = Vec::new();
    let mut spacings: Vec<f32> = solvers.iter().flat_map(|s| s.spacings()).collect();
    spacings.sort_by(|a, b| b.total_cmp(a));
    spacings.dedup();
    for spacing in spacings {
        for &kind in &solvers {
            let count = Scene::dam_break(0.25, 0.08, spacing).particles()?.len();
            if count > max_particles || !kind.spacings().contains(&spacing) {
                continue;
            }
            let r = kind.run(gpu.as_ref(), spacing, seconds, &options)?;
            let per = |s: f64| s / seconds;
            println!(
                "{:<6} {:>9} {:>12.3} {:>14.3} {:>9.1} {:>11.1} {:>8.1} {:>10.3} {:>10.2} {:>8}",
                r.solver,
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
        if kind == Runner::Salva {
            // Over ten times DFSPH's time per row: bisecting would take
            // minutes for a count far below the rows'.
            println!("salva: no bisection (see its rows)");
            continue;
        }
        let (mut lo, mut hi) = (kind.finest(), 0.04f32); // fine (slow) .. coarse (fast)
        let mut best: Option<Row> = None;
        for _ in 0..7 {
            let mid = (lo * hi).sqrt();
            let r = kind.run(gpu.as_ref(), mid, seconds, &options)?;
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
                .filter(|r| r.solver == kind.name() && f(r) <= seconds)
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
