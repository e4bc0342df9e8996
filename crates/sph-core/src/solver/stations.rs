//! The processors every solver's program is built from, whatever its method:
//! the neighbour grid, external accelerations, time integration, boundaries,
//! and particle sources and sinks.

use std::ops::Range;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

use glam::Vec3;
use rayon::prelude::*;

use crate::boundary::Boundary;
use crate::error::{Error, Result, positive};
use crate::grid::NeighbourLists;
use crate::particles::Particles;
#[cfg(doc)]
use crate::processor::Program;
use crate::processor::{Context, Processor};
use crate::region::{self, Blocks};

/// Builds the neighbour grid into [`Context::grid`] and stores the particles in
/// the grid's cell order (every `sort_every` steps), so later gathers walk memory
/// in order. Reordering keeps ids and every attribute with its particle.
#[derive(Debug, Clone)]
pub struct BuildGrid {
    h: f32,
    sort_every: u64,
}

impl BuildGrid {
    /// Grid of cell size `h`, reordering particles every `sort_every` steps (0: never).
    pub fn new(h: f32, sort_every: u64) -> Self {
        Self { h, sort_every }
    }
}

impl Processor for BuildGrid {
    fn name(&self) -> &str {
        "grid"
    }
    fn runs_in_region(&self) -> bool {
        true
    }
    fn process(&mut self, particles: &mut Particles, ctx: &mut Context) -> Result<()> {
        // A large scene's build and reordering split with rayon.
        crate::light::released_if_heavy(particles.len(), || self.build(particles, ctx))
    }
}

impl BuildGrid {
    fn build(&self, particles: &mut Particles, ctx: &mut Context) -> Result<()> {
        // Reuse last step's grid memory when there is one.
        let mut grid = match ctx.take_grid_memory() {
            Some(mut grid) if grid.h() == self.h => {
                grid.rebuild(particles.positions())?;
                grid
            }
            _ => crate::NeighbourGrid::build(particles.positions(), self.h)?,
        };
        if self.sort_every > 0 && ctx.step.is_multiple_of(self.sort_every) {
            particles.permute_unchecked(grid.order());
            grid.renumber_by_slot();
        }
        // Lists over the old positions or order are out of date (their
        // memory is kept); the grid was taken above.
        ctx.invalidate_neighbours();
        ctx.grid = Some(grid);
        Ok(())
    }
}

/// The context's neighbour grid, checked to be over `particles` and for the
/// fluid's smoothing length `h`.
pub(crate) fn grid<'a>(
    ctx: &'a Context,
    particles: &Particles,
    h: f32,
    who: &'static str,
) -> Result<&'a crate::NeighbourGrid> {
    let grid = ctx.grid.as_ref().ok_or(Error::Pipeline {
        processor: who,
        reason: "needs the neighbour grid: put a `grid` processor before it",
    })?;
    if grid.len() != particles.len() {
        return Err(Error::Pipeline {
            processor: who,
            reason: "the neighbour grid is out of date: a processor added or removed particles after `grid` without calling `Context::invalidate_grid`",
        });
    }
    if grid.h() != h {
        return Err(Error::Pipeline {
            processor: who,
            reason: "the neighbour grid was built for another h than the fluid's: give `BuildGrid` the fluid's h",
        });
    }
    Ok(grid)
}

/// Adds a user-defined acceleration field a(x, t) to every particle.
pub struct ExternalAcceleration<F> {
    name: String,
    field: F,
}

impl<F: Fn(Vec3, f64) -> Vec3 + Send + Sync> ExternalAcceleration<F> {
    /// A processor named `name` adding `field(position, time)`.
    pub fn new(name: impl Into<String>, field: F) -> Self {
        Self {
            name: name.into(),
            field,
        }
    }
}

impl<F: Fn(Vec3, f64) -> Vec3 + Send + Sync> Processor for ExternalAcceleration<F> {
    fn name(&self) -> &str {
        &self.name
    }
    fn process(&mut self, particles: &mut Particles, ctx: &mut Context) -> Result<()> {
        let f = particles.fields_mut();
        let time = ctx.time;
        f.accelerations
            .par_iter_mut()
            .zip(f.positions.par_iter())
            .for_each(|(a, &x)| *a += (self.field)(x, time));
        Ok(())
    }
}

/// Semi-implicit (symplectic) Euler: v += a·dt, then x += v·dt.
#[derive(Debug, Clone, Copy, Default)]
pub struct Integrate;

impl Processor for Integrate {
    fn name(&self) -> &str {
        "integrate"
    }
    fn process(&mut self, particles: &mut Particles, ctx: &mut Context) -> Result<()> {
        let dt = ctx.dt;
        let n = particles.len();
        let f = particles.fields_mut();
        let (xs, vs, accelerations) = (
            Blocks::new(f.positions),
            Blocks::new(f.velocities),
            &*f.accelerations,
        );
        let integrate = |range: Range<usize>, _| {
            // SAFETY: each block writes its own particles; nothing reads
            // them in this pass.
            let (x, v) = unsafe { (xs.block(range.clone()), vs.block(range.clone())) };
            for ((x, v), &a) in x.iter_mut().zip(v).zip(&accelerations[range]) {
                *v += a * dt;
                *x += *v * dt;
            }
        };
        region::run(n, &[&integrate]);
        ctx.invalidate_grid(); // positions moved
        Ok(())
    }
    fn runs_in_region(&self) -> bool {
        true
    }
}

/// Keeps particles inside the domain and out of obstacles (see [`crate::boundary`]).
#[derive(Debug, Clone)]
pub struct Boundaries {
    boundary: Boundary,
}

impl Boundaries {
    /// Enforces `boundary`.
    ///
    /// # Errors
    /// A boundary that does not validate ([`Boundary::validate`]).
    pub fn new(boundary: Boundary) -> Result<Self> {
        boundary.validate()?;
        Ok(Self { boundary })
    }
}

impl Processor for Boundaries {
    fn name(&self) -> &str {
        "boundaries"
    }
    fn runs_in_region(&self) -> bool {
        true
    }
    fn process(&mut self, particles: &mut Particles, ctx: &mut Context) -> Result<()> {
        let n = particles.len();
        let f = particles.fields_mut();
        let b = &self.boundary;
        let (xs, vs) = (Blocks::new(f.positions), Blocks::new(f.velocities));
        let resolve = |range: Range<usize>, _| {
            // SAFETY: each block writes its own particles; nothing reads
            // them in this pass.
            let (x, v) = unsafe { (xs.block(range.clone()), vs.block(range)) };
            x.iter_mut().zip(v).for_each(|(x, v)| b.resolve(x, v));
        };
        region::run(n, &[&resolve]);
        ctx.invalidate_grid();
        Ok(())
    }
}

/// Adds particles at a rate: square layers of `n × n` particles at `spacing`
/// around `centre`, in the plane normal to `velocity`, one layer each time the
/// previous one has moved `spacing` on. Only whole layers: it stops at the
/// first that would take the count past `max_particles`. A step long enough
/// at the emitter's speed to carry a layer out of the free space (beyond a
/// wall or into an obstacle) is an error: the boundary would press the
/// layer onto the wall, particles on top of each other.
#[derive(Debug, Clone)]
pub struct Emitter {
    free: Boundary,
    centre: Vec3,
    velocity: Vec3,
    n: u32,
    spacing: f32,
    mass: f32,
    max_particles: usize,
    travelled: f32,
}

impl Emitter {
    /// An emitter in `free` (the scene's boundary); it stops adding
    /// particles once the container holds `max_particles`.
    pub fn new(
        free: Boundary,
        centre: Vec3,
        velocity: Vec3,
        n: u32,
        spacing: f32,
        mass: f32,
        max_particles: usize,
    ) -> Result<Self> {
        positive("emitter.spacing", spacing)?;
        positive("emitter.speed", velocity.length())?;
        positive("emitter.mass", mass)?;
        Ok(Self {
            free,
            centre,
            velocity,
            n,
            spacing,
            mass,
            max_particles,
            travelled: spacing, // emit a layer on the first step
        })
    }
}

impl Processor for Emitter {
    fn name(&self) -> &str {
        "emitter"
    }
    fn process(&mut self, particles: &mut Particles, ctx: &mut Context) -> Result<()> {
        self.travelled += self.velocity.length() * ctx.dt;
        let dir = self.velocity.normalize();
        while self.travelled >= self.spacing {
            self.travelled -= self.spacing;
            let offset = dir * self.travelled; // where this layer is now
            let layer_len = (self.n as usize).pow(2);
            if particles.len() + layer_len > self.max_particles {
                return Ok(());
            }
            let at = self.centre + offset;
            if !nozzle_points(at, self.velocity, self.n, self.spacing).all(|x| self.free.admits(x))
            {
                return Err(Error::InvalidParameter {
                    name: "emitter.velocity",
                    value: format!(
                        "{} m/s over a step of {:e} s",
                        self.velocity.length(),
                        ctx.dt
                    ),
                    reason: "carries a layer out of the domain or into an obstacle within one step: \
                             lower the speed or shorten the step",
                });
            }
            ctx.invalidate_neighbours();
            for x in nozzle_points(at, self.velocity, self.n, self.spacing) {
                particles.push(x, self.velocity, self.mass);
            }
        }
        Ok(())
    }
}

/// The lattice of a square nozzle `n` particles wide at `spacing`, centred
/// on `centre`, in the plane across `velocity`: point (a, b), 0 ≤ a, b < n.
fn nozzle_lattice(
    centre: Vec3,
    velocity: Vec3,
    n: u32,
    spacing: f32,
) -> impl Fn(u32, u32) -> Vec3 + Copy {
    let (u, w) = velocity.normalize().any_orthonormal_pair();
    let half = (n as f32 - 1.0) / 2.0;
    move |a, b| centre + (u * (a as f32 - half) + w * (b as f32 - half)) * spacing
}

/// Every particle position of one layer of an [`Emitter`]'s nozzle.
pub fn nozzle_points(
    centre: Vec3,
    velocity: Vec3,
    n: u32,
    spacing: f32,
) -> impl Iterator<Item = Vec3> {
    let at = nozzle_lattice(centre, velocity, n, spacing);
    (0..n).flat_map(move |b| (0..n).map(move |a| at(a, b)))
}

/// The four corner particles of an [`Emitter`]'s nozzle (see [`Emitter::new`]).
pub fn nozzle_corners(centre: Vec3, velocity: Vec3, n: u32, spacing: f32) -> [Vec3; 4] {
    let at = nozzle_lattice(centre, velocity, n, spacing);
    let last = n.saturating_sub(1);
    [(0, 0), (last, 0), (0, last), (last, last)].map(|(a, b)| at(a, b))
}

/// Removes the particles inside a box.
///
/// Once the sink is in a [`Program`], read its count through
/// [`Sink::counter`], taken before:
///
/// ```
/// use std::sync::atomic::Ordering;
/// use sph_core::{Aabb, Scene, glam::Vec3, solver::Sink};
///
/// let mut world = Scene::dam_break(0.1, 0.04, 0.02).build_world()?;
/// let start = world.particles.len() as u64;
/// // Over the foot of the column.
/// let sink = Sink::new(Aabb::new(Vec3::ZERO, Vec3::splat(0.05)));
/// let removed = sink.counter();
/// world.program_mut().push(sink);
/// world.advance(0.01)?;
/// let removed = removed.load(Ordering::Relaxed);
/// assert!(removed > 0);
/// assert_eq!(world.particles.len() as u64 + removed, start);
/// # Ok::<(), sph_core::Error>(())
/// ```
#[derive(Debug, Clone)]
pub struct Sink {
    region: crate::boundary::Aabb,
    removed: Arc<AtomicU64>,
}

impl Sink {
    /// A sink over `region`.
    pub fn new(region: crate::boundary::Aabb) -> Self {
        Self {
            region,
            removed: Default::default(),
        }
    }

    /// Particles removed so far.
    pub fn removed(&self) -> u64 {
        self.removed.load(Ordering::Relaxed)
    }

    /// A handle on the count of removed particles that stays readable after
    /// the sink moved into a program.
    pub fn counter(&self) -> Arc<AtomicU64> {
        self.removed.clone()
    }
}

impl Processor for Sink {
    fn name(&self) -> &str {
        "sink"
    }
    fn process(&mut self, particles: &mut Particles, ctx: &mut Context) -> Result<()> {
        let keep: Vec<bool> = particles
            .positions()
            .iter()
            .map(|&x| !self.region.contains(x))
            .collect();
        let removed = particles.retain(&keep)?;
        if removed > 0 {
            self.removed.fetch_add(removed as u64, Ordering::Relaxed);
            ctx.invalidate_neighbours();
        }
        Ok(())
    }
}

/// Sets every particle's acceleration to gravity. Processors that add accelerations of their own go
/// right after it (its station is named `forces`, as WCSPH's is). Used by
/// PBF (Algorithm 1's line 2) and DFSPH.
#[derive(Debug, Clone, Copy)]
pub struct BodyForces {
    gravity: Vec3,
}

impl BodyForces {
    /// Gravity `gravity` (m/s²).
    pub fn new(gravity: Vec3) -> Self {
        Self { gravity }
    }
}

impl Processor for BodyForces {
    fn name(&self) -> &str {
        "forces"
    }
    fn runs_in_region(&self) -> bool {
        true
    }
    fn process(&mut self, particles: &mut Particles, _: &mut Context) -> Result<()> {
        let g = self.gravity;
        region::for_each(particles.accelerations_mut(), |_, a| *a = g);
        Ok(())
    }
}

/// Each particle's neighbours on the current positions, into
/// [`Context::neighbours`], kept for the rest of the step (PBF: lines 5–7,
/// on the predicted positions; DFSPH).
#[derive(Debug, Clone, Copy)]
pub struct FindNeighbours {
    h: f32,
}

impl FindNeighbours {
    /// Lists over the grid of search radius `h`.
    pub fn new(h: f32) -> Self {
        Self { h }
    }
}

impl Processor for FindNeighbours {
    fn name(&self) -> &str {
        "neighbours"
    }
    fn runs_in_region(&self) -> bool {
        true
    }
    fn process(&mut self, particles: &mut Particles, ctx: &mut Context) -> Result<()> {
        let mut lists = ctx.take_lists_memory().unwrap_or_default();
        lists.rebuild(grid(ctx, particles, self.h, "neighbours")?)?;
        ctx.neighbours = Some(lists);
        Ok(())
    }
}

/// The context's neighbour lists, checked to be over `particles`.
pub(crate) fn lists<'a>(
    ctx: &'a Context,
    particles: &Particles,
    who: &'static str,
) -> Result<&'a NeighbourLists> {
    let lists = ctx.neighbours.as_ref().ok_or(Error::Pipeline {
        processor: who,
        reason: "needs the neighbour lists: put `grid` and `neighbours` processors before it",
    })?;
    if lists.len() != particles.len() {
        return Err(Error::Pipeline {
            processor: who,
            reason: "the neighbour lists are out of date: a processor added or removed particles after `neighbours` without calling `Context::invalidate_neighbours`",
        });
    }
    Ok(lists)
}
