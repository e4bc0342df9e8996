//! The SPH solver of Müller, Charypar & Gross (2003) with the symmetric pressure
//! force of thesis eq. 15, as a [`Program`] of built-in [`Processor`]s driven by a
//! [`World`] with an adaptive time step.
//!
//! Per step: [`BuildGrid`] → [`DensityPressure`] (eq. 4, 16) → [`Forces`]
//! (pressure eq. 15, viscosity eq. 17, surface tension eq. 18–20, gravity) →
//! [`Integrate`] (semi-implicit Euler) → [`Boundaries`].

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

use glam::Vec3;
use rayon::prelude::*;

use crate::boundary::{Boundary, WallKernel};
use crate::error::{Error, Result, non_negative, positive};
use crate::grid::{Centre, ForceKernels, ForceSums, SlotFluid};
use crate::kernels::{Kernel, Kernels};
use crate::particles::Particles;
use crate::processor::{Context, Processor, Program};

/// Physical parameters of the fluid.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FluidParams {
    /// Smoothing length h (m): kernel support and neighbour radius.
    pub h: f32,
    /// Rest density ρ0 (kg/m³).
    pub rest_density: f32,
    /// Stiffness k of the equation of state p = k(ρ − ρ0) (eq. 16), in m²/s²; the
    /// speed of sound is √k.
    pub stiffness: f32,
    /// Dynamic viscosity μ (Pa·s), eq. 17.
    pub viscosity: f32,
    /// Surface tension coefficient σ (N/m), eq. 20.
    pub surface_tension: f32,
    /// Surface tension acts where |∇c| exceeds this (1/m).
    pub surface_threshold: f32,
    /// Gravity (m/s²).
    pub gravity: Vec3,
    /// Factor on negative pressures, in [0, 1]: 1 is eq. 16 as written, 0 clamps
    /// p ≥ 0. With eq. 16 as written, free-surface and wall particles (whose
    /// neighbourhoods are incomplete, ρ < ρ0) feel suction of order k/h, tens of
    /// thousands of m/s² at real-time stiffness, which tears the surface apart; the
    /// clamp (0, the default) is the usual remedy (e.g. Becker & Teschner 2007).
    pub negative_pressure_scale: f32,
    /// The kernel whose gradient the pressure force (eq. 15) uses.
    pub pressure_kernel: PressureKernel,
}

/// The kernel gradient in the symmetric pressure force (eq. 15).
///
/// Density is summed with poly6 (eq. 4). The pressure force that conserves
/// energy with that density is the gradient of the pressure energy, which uses
/// the *same* kernel's gradient; Müller et al. (and the thesis) use the spiky
/// gradient instead, which is not a gradient of anything the solver conserves.
/// Measured in a closed tank at rest (`cargo run --release -p sph-core --example
/// energy_drift`), spiky pumps energy in: the total energy rises by ~90 % in
/// 1.5 s and the column never settles, while poly6 loses energy monotonically to
/// viscosity and settles to 0.37 % density error.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum PressureKernel {
    /// ∇W_poly6: consistent with the density summation, energy-conserving (default).
    #[default]
    Poly6,
    /// ∇W_spiky: Müller et al. 2003 and the thesis as written.
    Spiky,
}

impl FluidParams {
    /// Water-like defaults for a real-time simulation at smoothing length `h`:
    /// ρ0 = 1000 kg/m³, k = 200 m²/s² (sound speed ≈ 14 m/s), μ = 0.2 Pa·s,
    /// σ = 0.0728 N/m acting where |∇c| > 0.1/h, gravity 9.81 m/s² down.
    pub fn water(h: f32) -> Self {
        Self {
            h,
            rest_density: 1000.0,
            stiffness: 200.0,
            viscosity: 0.2,
            surface_tension: 0.0728,
            surface_threshold: 0.1 / h,
            gravity: Vec3::new(0.0, -9.81, 0.0),
            negative_pressure_scale: 0.0,
            pressure_kernel: PressureKernel::Poly6,
        }
    }

    /// Checks every parameter is finite and in range; the error names it.
    pub fn validate(&self) -> Result<()> {
        positive("h", self.h)?;
        positive("rest_density", self.rest_density)?;
        if self.rest_density > MAX_REST_DENSITY {
            return Err(Error::InvalidParameter {
                name: "rest_density",
                value: self.rest_density.to_string(),
                reason: "must be at most 1e6 kg/m³ (40 times osmium's): denser fluids overflow the f32 density sums",
            });
        }
        positive("stiffness", self.stiffness)?;
        non_negative("viscosity", self.viscosity)?;
        non_negative("surface_tension", self.surface_tension)?;
        non_negative("surface_threshold", self.surface_threshold)?;
        if !(0.0..=1.0).contains(&self.negative_pressure_scale) {
            return Err(Error::InvalidParameter {
                name: "negative_pressure_scale",
                value: self.negative_pressure_scale.to_string(),
                reason: "must be in [0, 1]",
            });
        }
        if !self.gravity.is_finite() {
            return Err(Error::InvalidParameter {
                name: "gravity",
                value: format!("{:?}", self.gravity),
                reason: "must be finite",
            });
        }
        Ok(())
    }

    /// Speed of sound √k (m/s).
    pub fn sound_speed(&self) -> f32 {
        self.stiffness.sqrt()
    }

    /// The longest step explicit viscosity stays stable for,
    /// 0.125 h²/ν with ν = μ/ρ0; infinite for μ = 0. This is the form of
    /// Morris, Fox & Zhu (1997), with h here the kernel's support radius
    /// (theirs is a smoothing length of half the support, four times
    /// stricter), so the factor is checked by experiment: the solver test
    /// `very_viscous_fluid_keeps_to_the_viscous_step_limit` (a dam break at
    /// μ = 3000 Pa·s) runs with it, and blew up at t = 0.03 s without it,
    /// its steps then 5.3 times this limit.
    /// It binds only for very viscous fluids: at h = 0.04 m and ρ0 =
    /// 1000 kg/m³ it is 0.2/μ s, below the acoustic step 0.4 h/√k for
    /// k = 2000 m²/s² (0.36 ms) from μ ≈ 560 Pa·s.
    pub fn viscous_dt(&self) -> f32 {
        VISCOUS_FACTOR * self.h * self.h * self.rest_density / self.viscosity
    }

    /// The particle mass for fluid sampled on a cubic lattice of `spacing`: chosen
    /// so that a particle inside the lattice sums to exactly ρ0 with the poly6
    /// kernel, so fluid starts at rest density rather than a few % off.
    pub fn particle_mass(&self, spacing: f32) -> Result<f32> {
        positive("spacing", spacing)?;
        if spacing >= self.h {
            return Err(Error::InvalidParameter {
                name: "spacing",
                value: spacing.to_string(),
                reason: "must be smaller than h (at least one neighbour per axis)",
            });
        }
        if self.h / spacing > MAX_H_OVER_SPACING {
            return Err(Error::InvalidParameter {
                name: "spacing",
                value: spacing.to_string(),
                reason: "h / spacing must be at most 10: beyond, each particle would have thousands of neighbours",
            });
        }
        let poly6 = crate::kernels::Poly6::new(self.h)?;
        let n = (self.h / spacing).ceil() as i32;
        let mut sum = 0.0f64;
        for k in -n..=n {
            for j in -n..=n {
                for i in -n..=n {
                    let r = Vec3::new(i as f32, j as f32, k as f32) * spacing;
                    sum += poly6.value(r) as f64;
                }
            }
        }
        Ok((self.rest_density as f64 / sum) as f32)
    }
}

/// The largest h / spacing [`FluidParams::particle_mass`] (and a scene)
/// accepts: about 4,200 neighbours per particle. Usual values are 2 to 3.
pub const MAX_H_OVER_SPACING: f32 = 10.0;

/// The largest rest density [`FluidParams::validate`] accepts (kg/m³), so that
/// density sums stay finite over all of [`crate::error::KERNEL_H_RANGE`].
pub const MAX_REST_DENSITY: f32 = 1e6;

/// An error when the viscous step limit is below `min_dt`, the step that
/// counts as a blow-up: every run would stop at its first step.
fn check_viscous_dt(params: &FluidParams, stepping: &TimeStepping) -> Result<()> {
    if params.viscous_dt() < stepping.min_dt {
        return Err(Error::InvalidParameter {
            name: "viscosity",
            value: params.viscosity.to_string(),
            reason: "its stable step 0.125 h²ρ0/μ is below time_step's min_dt: lower μ or raise h",
        });
    }
    Ok(())
}

/// The factor of [`FluidParams::viscous_dt`].
const VISCOUS_FACTOR: f32 = 0.125;

/// Adaptive time stepping: dt = min(max_dt, viscous, cfl·h/(c + v_max),
/// force·√(h/a_max)), the viscous limit being [`FluidParams::viscous_dt`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TimeStepping {
    /// Upper bound on a step (s).
    pub max_dt: f32,
    /// Courant factor on h/(c + v_max), c = √k (the acoustic CFL condition).
    pub cfl: f32,
    /// Factor on √(h/a_max) (the force condition).
    pub force_factor: f32,
    /// A step shorter than this is reported as a blow-up (s).
    pub min_dt: f32,
}

impl Default for TimeStepping {
    fn default() -> Self {
        Self {
            max_dt: 2e-3,
            cfl: 0.4,
            force_factor: 0.25,
            min_dt: 1e-7,
        }
    }
}

impl TimeStepping {
    /// Checks every parameter; the error names it.
    pub fn validate(&self) -> Result<()> {
        positive("max_dt", self.max_dt)?;
        positive("cfl", self.cfl)?;
        positive("force_factor", self.force_factor)?;
        positive("min_dt", self.min_dt)?;
        if self.max_dt < self.min_dt {
            return Err(Error::InvalidParameter {
                name: "max_dt",
                value: self.max_dt.to_string(),
                reason: "must be at least min_dt, the step below which a run counts as blown up",
            });
        }
        Ok(())
    }
}

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
    fn process(&mut self, particles: &mut Particles, ctx: &mut Context) -> Result<()> {
        // Reuse last step's grid memory when there is one.
        let mut grid = match ctx.take_grid_memory() {
            Some(mut grid) if grid.h() == self.h => {
                grid.rebuild(particles.positions())?;
                grid
            }
            _ => crate::NeighbourGrid::build(particles.positions(), self.h)?,
        };
        if self.sort_every > 0 && ctx.step.is_multiple_of(self.sort_every) {
            particles.permute(grid.order())?;
            grid.renumber_by_slot();
        }
        ctx.grid = Some(grid);
        Ok(())
    }
}

/// The context's neighbour grid, checked to be over `particles` and for the
/// fluid's smoothing length `h`.
fn grid<'a>(
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

/// Density by poly6 summation (eq. 4) and pressure by the equation of state
/// p = k(ρ − ρ0) (eq. 16), negative values scaled by
/// [`FluidParams::negative_pressure_scale`].
/// Walls within h add the density of the fluid "behind" them (see
/// [`crate::boundary`]).
#[derive(Debug, Clone)]
pub struct DensityPressure(FluidModel);

impl DensityPressure {
    /// For these parameters and walls.
    ///
    /// # Errors
    /// Parameters or a boundary that do not validate.
    pub fn new(params: FluidParams, boundary: Boundary) -> Result<Self> {
        FluidModel::new(params, boundary).map(Self)
    }
}

/// What the density and force processors share: parameters, kernels, walls.
#[derive(Debug, Clone)]
struct FluidModel {
    params: FluidParams,
    kernels: Kernels,
    wall: WallKernel,
    boundary: Boundary,
}

impl FluidModel {
    fn new(params: FluidParams, boundary: Boundary) -> Result<Self> {
        params.validate()?;
        boundary.validate()?;
        Ok(Self {
            params,
            kernels: Kernels::new(params.h)?,
            wall: WallKernel::new(params.h),
            boundary,
        })
    }
}

impl Processor for DensityPressure {
    fn name(&self) -> &str {
        "density"
    }
    fn process(&mut self, particles: &mut Particles, ctx: &mut Context) -> Result<()> {
        let grid = grid(ctx, particles, self.0.params.h, "density")?;
        let masses = particles.masses();
        let FluidModel {
            params,
            kernels,
            wall,
            boundary: b,
        } = &self.0;
        let (poly6, rho0, h) = (kernels.poly6, params.rest_density, params.h);
        let masses = grid.to_slot_order(masses);
        let rho = grid.par_map(|_, nb| {
            let mut rho = nb.poly6_sums(&poly6, &masses).value;
            b.for_each_wall_within(nb.centre(), h, |d, _| rho += rho0 * wall.volume_fraction(d));
            rho
        });
        let (k, suction) = (params.stiffness, params.negative_pressure_scale);
        let f = particles.fields_mut();
        f.densities.copy_from_slice(&rho);
        f.pressures
            .par_iter_mut()
            .zip(rho.par_iter())
            .for_each(|(p, &r)| {
                let eos = k * (r - rho0);
                *p = if eos < 0.0 { suction * eos } else { eos };
            });
        Ok(())
    }
}

/// Accelerations from the symmetric pressure force (eq. 15, with the gradient of
/// [`FluidParams::pressure_kernel`]),
/// viscosity (eq. 17, viscosity laplacian), surface tension from the colour field
/// (eq. 18–20, where |n| > threshold) and gravity. Also stores the colour-field
/// gradient and laplacian. Overwrites accelerations: processors adding external
/// forces go after it.
///
/// Walls within h push back with the gradient of their density term's pressure
/// energy (see [`crate::boundary`]).
#[derive(Debug, Clone)]
pub struct Forces(FluidModel);

impl Forces {
    /// For these parameters and walls.
    ///
    /// # Errors
    /// Parameters or a boundary that do not validate.
    pub fn new(params: FluidParams, boundary: Boundary) -> Result<Self> {
        FluidModel::new(params, boundary).map(Self)
    }
}

impl Processor for Forces {
    fn name(&self) -> &str {
        "forces"
    }
    fn process(&mut self, particles: &mut Particles, ctx: &mut Context) -> Result<()> {
        let grid = grid(ctx, particles, self.0.params.h, "forces")?;
        let v = particles.velocities();
        let (m, rho, p) = (
            particles.masses(),
            particles.densities(),
            particles.pressures(),
        );
        let Kernels {
            poly6,
            spiky,
            viscosity,
        } = self.0.kernels;
        let (prm, wall, b) = (self.0.params, self.0.wall, &self.0.boundary);
        // Per-particle factors, so the pair loop has no division but the spiky
        // kernel's 1/r: volume m/ρ and pressure term p/ρ² (eq. 15).
        let (vol, pr): (Vec<f32>, Vec<f32>) = (m.par_iter().zip(rho).zip(p))
            .map(|((&m, &rho), &p)| (m / rho, p / (rho * rho)))
            .unzip();
        // The pair sums read their neighbours' data in slot order (cell by
        // cell), like the grid's coordinates.
        let velocity: [Vec<f32>; 3] = std::array::from_fn(|a| {
            let order = grid.order().par_iter();
            order.map(|&i| v[i as usize][a]).collect()
        });
        let (volume, mass, pressure) = (
            grid.to_slot_order(&vol),
            grid.to_slot_order(m),
            grid.to_slot_order(&pr),
        );
        let fluid = SlotFluid {
            v: [&velocity[0], &velocity[1], &velocity[2]],
            volume: &volume,
            mass: &mass,
            pressure: &pressure,
        };
        let kernels = ForceKernels {
            poly6_grad: poly6.coefficients().1,
            visc_lap: viscosity.coefficient(),
            spiky_grad: match prm.pressure_kernel {
                PressureKernel::Poly6 => None,
                PressureKernel::Spiky => Some(spiky.coefficient()),
            },
        };
        let out = grid.par_map(|i, nb| {
            let pi = pr[i];
            let centre = Centre {
                pressure: pi,
                velocity: v[i],
            };
            let ForceSums {
                pressure: mut a_p,
                viscosity: a_v,
                normal: n,
                laplacian: lap_c,
            } = nb.force_sums(centre, &kernels, &fluid);
            b.for_each_wall_within(nb.centre(), prm.h, |d, normal| {
                // −m_i (p_i/ρ_i²) ∇ρ_wall / m_i: the gradient of the wall term's energy.
                a_p += pi * prm.rest_density * wall.plane_density(d) * normal;
            });
            let mut a = a_p + (prm.viscosity / rho[i]) * a_v + prm.gravity;
            let n_len = n.length();
            if prm.surface_tension > 0.0 && n_len > prm.surface_threshold {
                // eq. 20: f = −σ ∇²c n/|n| per unit volume; a = f/ρ.
                a -= prm.surface_tension * lap_c * n / (n_len * rho[i]);
            }
            (a, n, lap_c)
        });
        let f = particles.fields_mut();
        (f.accelerations.par_iter_mut())
            .zip(f.colour_gradients.par_iter_mut())
            .zip(f.colour_laplacians.par_iter_mut())
            .zip(out.par_iter())
            .for_each(|(((a, n), l), &(a_i, n_i, l_i))| (*a, *n, *l) = (a_i, n_i, l_i));
        Ok(())
    }
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
        let f = particles.fields_mut();
        f.positions
            .par_iter_mut()
            .zip(f.velocities.par_iter_mut())
            .zip(f.accelerations.par_iter())
            .for_each(|((x, v), &a)| {
                *v += a * dt;
                *x += *v * dt;
            });
        ctx.invalidate_grid(); // positions moved
        Ok(())
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
    fn process(&mut self, particles: &mut Particles, ctx: &mut Context) -> Result<()> {
        let f = particles.fields_mut();
        let b = &self.boundary;
        f.positions
            .par_iter_mut()
            .zip(f.velocities.par_iter_mut())
            .for_each(|(x, v)| b.resolve(x, v));
        ctx.invalidate_grid();
        Ok(())
    }
}

/// Adds particles at a rate: square layers of `n × n` particles at `spacing`
/// around `centre`, in the plane normal to `velocity`, one layer each time the
/// previous one has moved `spacing` on.
#[derive(Debug, Clone)]
pub struct Emitter {
    centre: Vec3,
    velocity: Vec3,
    n: u32,
    spacing: f32,
    mass: f32,
    max_particles: usize,
    travelled: f32,
}

impl Emitter {
    /// An emitter; it stops adding particles once the container holds `max_particles`.
    pub fn new(
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
            let layer = nozzle_points(self.centre + offset, self.velocity, self.n, self.spacing);
            for x in layer {
                if particles.len() >= self.max_particles {
                    return Ok(());
                }
                particles.push(x, self.velocity, self.mass);
            }
            ctx.invalidate_grid();
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
            ctx.invalidate_grid();
        }
        Ok(())
    }
}

/// The default solver program: grid → density → forces → integrate → boundaries.
pub fn default_program(params: FluidParams, boundary: Boundary) -> Result<Program> {
    let mut program = Program::new("sph");
    program
        .push(BuildGrid::new(params.h, 1))
        .push(DensityPressure::new(params, boundary.clone())?)
        .push(Forces::new(params, boundary.clone())?)
        .push(Integrate)
        .push(Boundaries::new(boundary)?);
    Ok(program)
}

/// A simulation: particles, the program that advances them, and the clock.
pub struct World {
    /// The particles.
    pub particles: Particles,
    params: FluidParams,
    stepping: TimeStepping,
    program: Program,
    time: f64,
    step: u64,
    /// Last step's grid, rebuilt in place by the next step's grid processor.
    recycled_grid: Option<crate::NeighbourGrid>,
}

/// What one call of [`World::advance`] did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameReport {
    /// Substeps taken.
    pub substeps: u32,
    /// Smallest and largest substep (s).
    pub dt_range: (f32, f32),
    /// Simulated time after the frame (s).
    pub time: f64,
}

impl World {
    /// A world running the [`default_program`].
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
        params.validate()?;
        stepping.validate()?;
        check_viscous_dt(&params, &stepping)?;
        particles.validate()?;
        let program = default_program(params, boundary)?;
        Ok(Self {
            particles,
            params,
            stepping,
            program,
            time: 0.0,
            step: 0,
            recycled_grid: None,
        })
    }

    /// The program, to add, insert or remove processors.
    pub fn program_mut(&mut self) -> &mut Program {
        &mut self.program
    }

    /// The fluid parameters.
    pub fn params(&self) -> &FluidParams {
        &self.params
    }

    /// Simulated time (s).
    pub fn time(&self) -> f64 {
        self.time
    }

    /// Steps taken.
    pub fn steps(&self) -> u64 {
        self.step
    }

    /// The adaptive time-stepping parameters.
    pub fn time_stepping(&self) -> &TimeStepping {
        &self.stepping
    }

    /// The next step's length from the viscous, CFL and force conditions.
    pub fn stable_dt(&self) -> f32 {
        let (v_max, a_max) = self
            .particles
            .velocities()
            .par_iter()
            .zip(self.particles.accelerations().par_iter())
            .map(|(v, a)| (v.length(), a.length()))
            .reduce(|| (0.0, 0.0), |x, y| (x.0.max(y.0), x.1.max(y.1)));
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

    /// Takes one step of the stable length; returns it.
    pub fn step(&mut self) -> Result<f32> {
        let dt = self.checked_stable_dt()?;
        self.step_by(dt)?;
        Ok(dt)
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

    /// Advances by `frame_dt` in stable substeps (the last one shortened to land
    /// on the frame time).
    pub fn advance(&mut self, frame_dt: f32) -> Result<FrameReport> {
        positive("frame_dt", frame_dt)?;
        let end = self.time + frame_dt as f64;
        let mut report = FrameReport {
            substeps: 0,
            dt_range: (f32::INFINITY, 0.0),
            time: self.time,
        };
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
            self.step_by(dt)?;
            if last {
                self.time = end;
            }
            report.substeps += 1;
            report.dt_range = (report.dt_range.0.min(dt), report.dt_range.1.max(dt));
        }
        report.time = self.time;
        Ok(report)
    }

    fn step_by(&mut self, dt: f32) -> Result<()> {
        let mut ctx = Context::new(dt);
        (ctx.time, ctx.step) = (self.time, self.step);
        ctx.recycle(self.recycled_grid.take());
        self.program.process(&mut self.particles, &mut ctx)?;
        self.recycled_grid = ctx.take_grid_memory();
        self.time += dt as f64;
        self.step += 1;
        self.check()
    }

    /// NaN, infinities and speeds above 5 × the speed of sound end the run.
    fn check(&self) -> Result<()> {
        let limit = 5.0 * self.params.sound_speed();
        let bad = self
            .particles
            .positions()
            .par_iter()
            .zip(self.particles.velocities().par_iter())
            .position_first(|(x, v)| !x.is_finite() || !v.is_finite() || v.length() > limit);
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
        Error::Unstable {
            step: self.step,
            time: self.time,
            what,
            hint: format!(
                "lower time_step.max_dt (now {:e} s) or time_step.cfl (now {}), \
                 or check viscosity μ (now {} Pa·s), stiffness k (now {} m²/s²) and h (now {} m)",
                self.stepping.max_dt,
                self.stepping.cfl,
                self.params.viscosity,
                self.params.stiffness,
                self.params.h
            ),
        }
    }
}

impl std::fmt::Debug for World {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("World")
            .field("particles", &self.particles.len())
            .field("time", &self.time)
            .field("step", &self.step)
            .field("program", &self.program)
            .finish()
    }
}
