//! [`World`]: particles, the solver's program and the clock.

use glam::Vec3;

use super::params::{FluidParams, TimeStepping, check_viscous_dt};
use super::{Solver, SolverKind};
use crate::boundary::Boundary;
use crate::error::{Error, Result, positive};
use crate::particles::Particles;
use crate::processor::{Context, Processor, Program, StepCounters};
use crate::region;

/// A simulation: particles, the program that advances them, and the clock.
pub struct World {
    /// The particles.
    pub particles: Particles,
    params: FluidParams,
    /// Where fluid may be (the program's stations hold their own copies).
    boundary: Boundary,
    stepping: TimeStepping,
    solver: Solver,
    program: Program,
    time: f64,
    step: u64,
    /// Last step's grid, rebuilt in place by the next step's grid processor.
    recycled_grid: Option<crate::NeighbourGrid>,
    /// Last step's neighbour lists, rebuilt in place.
    recycled_lists: Option<crate::NeighbourLists>,
    /// A pool of [`useful_threads`] threads, for a scene too small to gain
    /// from all of the caller's: made when first needed, kept while the
    /// count stays within two threads of it.
    narrow_pool: Option<rayon::ThreadPool>,
    /// Whether steps use every thread of the caller's pool
    /// ([`World::use_every_thread`]).
    every_thread: bool,
}

/// The most threads a step of `particles` particles gains from: 8, or one
/// per 3,000 particles where that is more. Measured on a 16-core Xeon
/// (`examples/scaling.rs --sweep`, BENCHMARKS.md "Threads"): PBF frames of
/// 4k–20k particles and DFSPH's of 10k were fastest at 6–12 threads and
/// 15–90 % slower at 16 (each of a substep's passes is a fork-join whose
/// cost grows with the threads), 37k gained up to 12–14 threads and 100k
/// up to 16. A [`World`] steps in a pool of this many threads when the
/// caller's has more; its results are the same for any thread count.
pub fn useful_threads(particles: usize) -> usize {
    (particles / 3_000).max(8)
}

/// What one call of [`World::advance`] did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameReport {
    /// The solver that took the steps.
    pub solver: SolverKind,
    /// Substeps taken.
    pub substeps: u32,
    /// Smallest and largest substep (s).
    pub dt_range: (f32, f32),
    /// Constraint iterations over all substeps (0 for WCSPH, which has
    /// none): PBF's density constraint, DFSPH's constant-density solve.
    pub iterations: u32,
    /// DFSPH's divergence-solve iterations over all substeps (0 for the
    /// other solvers).
    pub divergence_iterations: u32,
    /// The implicit viscosity's conjugate-gradient iterations over all
    /// substeps (DFSPH; 0 for the other solvers).
    pub viscosity_iterations: u32,
    /// DFSPH's solves (pressure and viscosity) that stopped at their
    /// iteration limit above their tolerance, over all substeps (0 for the
    /// other solvers).
    pub unconverged: u32,
    /// The density error (compression) max(ρ/ρ0 − 1, 0) averaged over the
    /// particles, then over the frame's substeps: each substep's densities
    /// as the solver left them (WCSPH: at the start of the substep, the ones
    /// its pressure used; PBF: at its end, after the constraint solve).
    /// Particles below rest density (the free surface) count as 0.
    pub density_error_avg: f32,
    /// The largest density error ρ/ρ0 − 1 of any particle in any substep.
    pub density_error_max: f32,
    /// Particles whose motion a guard limited, summed over the substeps
    /// (PBF's displacement guard; 0 for WCSPH).
    pub clamped: u64,
    /// Simulated time after the frame (s).
    pub time: f64,
}

/// What a step left, per block of particles ([`survey`]).
#[derive(Clone, Copy, Default)]
struct BlockSurvey {
    /// The block's first particle that is not finite or faster than the
    /// limit, if any.
    bad: Option<usize>,
    /// Σ max(ρ/ρ0 − 1, 0) over the block, in particle order.
    error_sum: f64,
    /// max ρ/ρ0 − 1 over the block.
    error_max: f32,
}

/// One step's survey in one parallel pass: the first particle that is not
/// finite or moves faster than `limit`, and the density error (Σ max(ρ/ρ0 −
/// 1, 0) / n, max ρ/ρ0 − 1), summed per block in particle order, then over
/// the blocks in block order: the same for any number of threads.
fn survey(particles: &Particles, rest: f32, limit: f32) -> (Option<usize>, (f64, f32)) {
    let n = particles.len();
    if n == 0 {
        return (None, (0.0, 0.0));
    }
    let (x, v, rho) = (
        particles.positions(),
        particles.velocities(),
        particles.densities(),
    );
    let blocks = region::map_blocks(n, |range| {
        let mut s = BlockSurvey {
            bad: None,
            error_sum: 0.0,
            error_max: f32::NEG_INFINITY,
        };
        for i in range {
            if s.bad.is_none() && (!x[i].is_finite() || !v[i].is_finite() || v[i].length() > limit)
            {
                s.bad = Some(i);
            }
            let e = rho[i] / rest - 1.0;
            s.error_sum += f64::from(e.max(0.0));
            s.error_max = s.error_max.max(e);
        }
        s
    });
    let bad = blocks.iter().find_map(|s| s.bad);
    let (sum, max) = (blocks.iter()).fold((0.0f64, f32::NEG_INFINITY), |(s, m), b| {
        (s + b.error_sum, m.max(b.error_max))
    });
    (bad, (sum / n as f64, max))
}

impl World {
    /// A world running the thesis's WCSPH ([`super::wcsph::program`]).
    ///
    /// # Errors
    /// Invalid parameters, boundary ([`Boundary::validate`]) or particles
    /// ([`Particles::validate`]).
    pub fn new(
        particles: Particles,
        params: FluidParams,
        boundary: Boundary,
        stepping: TimeStepping,
    ) -> Result<Self> {
        Self::with_solver(particles, params, boundary, stepping, Solver::Wcsph)
    }

    /// A world running `solver`'s program. `stepping` is the adaptive step
    /// of WCSPH (and its `min_dt`, below which any solver's step counts as
    /// a blow-up); PBF and DFSPH step by their own parameters.
    ///
    /// # Errors
    /// Invalid parameters (the fluid's, the time stepping's or the
    /// solver's), boundary ([`Boundary::validate`]) or particles
    /// ([`Particles::validate`]), a mass too light for h
    /// ([`FluidParams::check_masses`]), or a particle the boundary does not
    /// admit (outside the domain or inside an obstacle,
    /// [`Boundary::admits`]): the first step would move it onto a wall, on
    /// top of its neighbours.
    pub fn with_solver(
        particles: Particles,
        params: FluidParams,
        boundary: Boundary,
        stepping: TimeStepping,
        solver: Solver,
    ) -> Result<Self> {
        params.validate()?;
        stepping.validate()?;
        solver.validate()?;
        if matches!(solver, Solver::Wcsph) {
            check_viscous_dt(&params, &stepping)?;
        }
        Self::check_inputs(&particles, &params, &boundary)?;
        let program = solver.program(params, boundary.clone())?;
        Ok(Self {
            particles,
            params,
            boundary,
            stepping,
            solver,
            program,
            time: 0.0,
            step: 0,
            recycled_grid: None,
            recycled_lists: None,
            narrow_pool: None,
            every_thread: false,
        })
    }

    /// What every world refuses of the particles, fluid and walls it is
    /// built from, whatever runs it: parameters that do not validate or an
    /// h the kernels cannot represent, particles that do not validate or
    /// are too light for h, a boundary that does not validate or reaches
    /// where f32 no longer resolves h, and a particle the boundary does not
    /// admit. [`World::with_solver`] checks it, and so do the GPU's solvers
    /// (`sph-gpu`), so both paths refuse the same input.
    ///
    /// # Errors
    /// The first of those, naming the field or particle.
    pub fn check_inputs(
        particles: &Particles,
        params: &FluidParams,
        boundary: &Boundary,
    ) -> Result<()> {
        params.validate()?;
        crate::error::check_kernel_h(params.h)?;
        particles.validate()?;
        params.check_masses(particles.masses())?;
        boundary.validate()?;
        boundary.check_precision(params.h)?;
        boundary.check_admits(particles.positions())
    }

    /// The program, to add, insert or remove processors.
    pub fn program_mut(&mut self) -> &mut Program {
        &mut self.program
    }

    /// The fluid parameters.
    pub fn params(&self) -> &FluidParams {
        &self.params
    }

    /// The walls and obstacles: where fluid may be ([`Boundary::admits`]).
    pub fn boundary(&self) -> &Boundary {
        &self.boundary
    }

    /// The solver and its parameters.
    pub fn solver(&self) -> &Solver {
        &self.solver
    }

    /// Takes over `old`'s clock (simulated time and step count), its
    /// thread setting ([`World::use_every_thread`]) and its kept grid and
    /// list memory, for a world rebuilt mid-run
    /// ([`crate::Scene::world_continuing`]).
    pub(crate) fn continue_from(&mut self, old: &mut World) {
        (self.time, self.step) = (old.time, old.step);
        self.every_thread = old.every_thread;
        self.recycled_grid = old.recycled_grid.take();
        self.recycled_lists = old.recycled_lists.take();
    }

    /// Simulated time (s).
    pub fn time(&self) -> f64 {
        self.time
    }

    /// Steps taken.
    pub fn steps(&self) -> u64 {
        self.step
    }

    /// The adaptive time-stepping parameters (WCSPH's).
    pub fn time_stepping(&self) -> &TimeStepping {
        &self.stepping
    }

    /// The next step's length. WCSPH: from the viscous, CFL and force
    /// conditions. PBF: its longest substep, [`super::PbfParams::max_dt`].
    /// DFSPH: from the flow's speed alone ([`super::DfsphParams::step`]):
    /// its viscosity is implicit.
    pub fn stable_dt(&self) -> f32 {
        match self.solver {
            Solver::Pbf(pbf) => return pbf.max_dt,
            Solver::Dfsph(dfsph) => {
                let speed = self.largest(|v, a| (v.length() + a.length() * dfsph.max_dt, 0.0));
                return dfsph.step(self.params.h, speed.0);
            }
            Solver::Wcsph => {}
        }
        let (v_max, a_max) = self.largest(|v, a| (v.length(), a.length()));
        let h = self.params.h;
        let s = &self.stepping;
        let mut dt = s
            .max_dt
            .min(self.params.viscous_dt())
            .min(s.cfl * h / (self.params.sound_speed() + v_max));
        if a_max > 0.0 {
            dt = dt.min(s.force_factor * (h / a_max).sqrt());
        }
        dt
    }

    /// The largest of each of the two values `f` gives per particle's
    /// velocity and acceleration, in one parallel pass (0 for none).
    fn largest(&self, f: impl Fn(Vec3, Vec3) -> (f32, f32) + Sync) -> (f32, f32) {
        let (v, a) = (self.particles.velocities(), self.particles.accelerations());
        let most = |x: (f32, f32), y: (f32, f32)| (x.0.max(y.0), x.1.max(y.1));
        let blocks =
            region::map_blocks(v.len(), |r| r.map(|i| f(v[i], a[i])).fold((0.0, 0.0), most));
        blocks.into_iter().fold((0.0, 0.0), most)
    }

    /// Takes one step of the stable length; returns it.
    pub fn step(&mut self) -> Result<f32> {
        self.on_pool(|world| {
            let dt = world.checked_stable_dt()?;
            world.step_by(dt)?;
            Ok(dt)
        })
    }

    /// Lets steps use every thread of the caller's pool (`true`), or at
    /// most [`useful_threads`] of them (`false`, the default): for
    /// measuring how a step scales past what it gains from. The results
    /// are the same either way.
    pub fn use_every_thread(&mut self, every: bool) {
        self.every_thread = every;
    }

    /// Runs `f` on a thread of the pool to step in ([`Self::take_pool`]),
    /// or of rayon's current pool (this one, when it is one), in one
    /// parallel region for all of it (`region::team`): the pool's threads
    /// start once and wait, spinning, for each station's passes, instead of
    /// a fork, a join and a wake-up per pass. Keeps the narrow pool for the
    /// next step. The work and its order are the same either way.
    fn on_pool<R: Send>(&mut self, f: impl FnOnce(&mut Self) -> R + Send) -> R {
        let pool = self.take_pool();
        let result = match &pool {
            Some(pool) => pool.install(|| crate::region::team(|| f(self))),
            None => rayon::scope(|_| crate::region::team(|| f(self))),
        };
        if pool.is_some() {
            self.narrow_pool = pool;
        }
        result
    }

    /// The pool to step in, taken out of `narrow_pool`: about
    /// [`useful_threads`] threads where the caller's pool has more, else
    /// none (the caller's; a kept pool stays kept).
    fn take_pool(&mut self) -> Option<rayon::ThreadPool> {
        let want = useful_threads(self.particles.len());
        let caller = rayon::current_num_threads();
        if self.every_thread || caller <= want {
            return None;
        }
        match self.narrow_pool.take() {
            // Within two threads of the count: a scene whose count hovers
            // about a multiple of 3,000 particles does not remake it.
            Some(pool)
                if pool.current_num_threads().abs_diff(want) <= 2
                    && pool.current_num_threads() < caller =>
            {
                Some(pool)
            }
            // A pool that cannot be made leaves the step on the caller's,
            // with the same results.
            _ => rayon::ThreadPoolBuilder::new()
                .num_threads(want)
                .thread_name(|i| format!("sph-step-{i}"))
                .build()
                .ok(),
        }
    }

    /// [`stable_dt`](Self::stable_dt), or the blow-up error when it is NaN or
    /// below `min_dt`.
    fn checked_stable_dt(&self) -> Result<f32> {
        let dt = self.stable_dt();
        if dt.is_nan() || dt < self.stepping.min_dt {
            return Err(self.unstable(format!(
                "the stable step fell to {dt:e} s, below min_dt = {:e} s",
                self.stepping.min_dt
            )));
        }
        Ok(dt)
    }

    /// Advances by `frame_dt`. WCSPH and DFSPH take stable substeps, the last one
    /// shortened to land on the frame time; PBF takes
    /// [`super::PbfParams::substeps`] equal substeps, more only where they
    /// would be longer than its `max_dt`.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming `frame_dt` where it is not finite
    /// and at least [`TimeStepping::min_dt`]: a shorter frame counts as no
    /// step, and added to a clock of seconds in f64 it could leave the
    /// clock where it was, so a loop to a time would never end. Otherwise
    /// what a step returns ([`Error::Unstable`], ...).
    pub fn advance(&mut self, frame_dt: f32) -> Result<FrameReport> {
        positive("frame_dt", frame_dt)?;
        if frame_dt < self.stepping.min_dt {
            return Err(Error::InvalidParameter {
                name: "frame_dt",
                value: format!("{frame_dt:e}"),
                reason: "is shorter than time_step's min_dt, the shortest step a run takes",
            });
        }
        self.on_pool(|world| world.advance_by(frame_dt))
    }

    /// [`Self::advance`], on a thread of rayon's pool.
    fn advance_by(&mut self, frame_dt: f32) -> Result<FrameReport> {
        let end = self.time + frame_dt as f64;
        let mut report = FrameReport {
            solver: self.solver.kind(),
            substeps: 0,
            dt_range: (f32::INFINITY, 0.0),
            iterations: 0,
            divergence_iterations: 0,
            viscosity_iterations: 0,
            unconverged: 0,
            density_error_avg: 0.0,
            density_error_max: 0.0,
            clamped: 0,
            time: self.time,
        };
        let mut error_sum = 0.0f64;
        let mut take = |world: &mut Self, dt: f32, last: bool| -> Result<()> {
            let (counters, (avg, max)) = world.step_by(dt)?;
            if last {
                world.time = end;
            }
            report.substeps += 1;
            report.dt_range = (report.dt_range.0.min(dt), report.dt_range.1.max(dt));
            report.iterations += counters.iterations;
            report.divergence_iterations += counters.divergence_iterations;
            report.viscosity_iterations += counters.viscosity_iterations;
            report.unconverged += counters.unconverged;
            report.clamped += counters.clamped;
            error_sum += avg;
            report.density_error_max = report.density_error_max.max(max);
            Ok(())
        };
        if let Solver::Pbf(pbf) = self.solver {
            // Refused before any substep moves a particle.
            let n = pbf.check_frame(frame_dt)?;
            pbf.check_sleep(self.params.gravity.length(), frame_dt)?;
            let dt = frame_dt / n as f32;
            for k in 0..n {
                take(self, dt, k + 1 == n)?;
            }
        } else {
            while self.time < end {
                let stable = self.checked_stable_dt()?;
                let remaining = (end - self.time) as f32;
                // Land on the frame time without a sliver step: the last two steps
                // share what is left when it is under two stable steps.
                let last = remaining <= stable;
                let dt = if last {
                    remaining
                } else if remaining < 2.0 * stable {
                    0.5 * remaining
                } else {
                    stable
                };
                take(self, dt, last)?;
            }
        }
        report.density_error_avg = (error_sum / f64::from(report.substeps.max(1))) as f32;
        report.time = self.time;
        Ok(report)
    }

    /// One step of `dt`: what its processors counted and its density error.
    fn step_by(&mut self, dt: f32) -> Result<(StepCounters, (f64, f32))> {
        let mut ctx = Context::new(dt);
        (ctx.time, ctx.step) = (self.time, self.step);
        ctx.recycle(self.recycled_grid.take(), self.recycled_lists.take());
        self.program.process(&mut self.particles, &mut ctx)?;
        self.recycled_grid = ctx.take_grid_memory();
        self.recycled_lists = ctx.take_lists_memory();
        self.time += dt as f64;
        self.step += 1;
        // NaN, infinities and speeds above 5 × the speed of sound end the
        // run, WCSPH only: there is no speed of sound in PBF or DFSPH, whose
        // solves check themselves.
        let limit = match self.solver {
            Solver::Wcsph => 5.0 * self.params.sound_speed(),
            Solver::Pbf(_) | Solver::Dfsph(_) => f32::INFINITY,
        };
        let (bad, error) = survey(&self.particles, self.params.rest_density, limit);
        self.check(bad)?;
        Ok((ctx.counters, error))
    }

    /// The error ending the run at particle `bad`, found by [`survey`].
    fn check(&self, bad: Option<usize>) -> Result<()> {
        match bad {
            None => Ok(()),
            Some(i) => {
                let (x, v) = (
                    self.particles.positions()[i],
                    self.particles.velocities()[i],
                );
                let what = if !x.is_finite() || !v.is_finite() {
                    format!("particle {i} became non-finite (x = {x}, v = {v})")
                } else {
                    format!(
                        "particle {i} moves at {:.3} m/s, above 5 × the speed of sound √k = {:.3} m/s",
                        v.length(),
                        self.params.sound_speed()
                    )
                };
                Err(self.unstable(what))
            }
        }
    }

    fn unstable(&self, what: String) -> Error {
        let hint = match self.solver {
            Solver::Pbf(pbf) => format!(
                "raise solver.pbf.substeps (now {}) or solver.pbf.iterations (now {}), \
                 or lower solver.pbf.max_dt (now {:e} s)",
                pbf.substeps, pbf.iterations, pbf.max_dt
            ),
            Solver::Dfsph(dfsph) => format!(
                "lower solver.dfsph.cfl (now {}) or solver.dfsph.max_dt (now {:e} s), \
                 or raise solver.dfsph.max_iterations (now {})",
                dfsph.cfl, dfsph.max_dt, dfsph.max_iterations
            ),
            Solver::Wcsph => format!(
                "lower solver.wcsph.max_dt (now {:e} s) or solver.wcsph.cfl (now {}), \
                 or check viscosity μ (now {} Pa·s), stiffness k (now {} m²/s²) and h (now {} m)",
                self.stepping.max_dt,
                self.stepping.cfl,
                self.params.viscosity,
                self.params.stiffness,
                self.params.h
            ),
        };
        Error::Unstable {
            step: self.step,
            time: self.time,
            what,
            hint,
        }
    }
}

impl std::fmt::Debug for World {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("World")
            .field("particles", &self.particles.len())
            .field("time", &self.time)
            .field("step", &self.step)
            .field("solver", &self.solver)
            .field("program", &self.program)
            .finish()
    }
}
