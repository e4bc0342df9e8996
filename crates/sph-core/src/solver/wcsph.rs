//! The thesis's weakly compressible SPH (Müller, Charypar & Gross 2003, thesis
//! section 3.1): density by summation (eq. 4), pressure from the equation of
//! state p = k(ρ − ρ0) (eq. 16), then the symmetric pressure force (eq. 15),
//! viscosity (eq. 17) and surface tension (eq. 18–20), integrated explicitly
//! with a step bound by the speed of sound (see [`super::TimeStepping`]).
//!
//! Per step: [`BuildGrid`] → [`DensityPressure`] → [`Forces`] →
//! [`Integrate`] (semi-implicit Euler) → [`Boundaries`].
//!
//! A fluid whose [`FluidParams::surface_tension_model`] is
//! [`SurfaceTensionModel::Akinci`] takes σ out of the force sums and adds
//! Akinci et al. 2013's forces after them instead ([`FindNeighbours`],
//! [`SurfaceTension`]), as PBF and DFSPH apply it: the thesis's colour
//! field stays the reference, and the two can be compared on one solver.

use crate::region;

use super::force_sums::{Centre, ForceKernels, ForceSums, SlotFluid, force_sums};
use super::params::{FluidParams, PressureKernel, SurfaceTensionModel};
use super::stations::{Boundaries, BuildGrid, FindNeighbours, Integrate, grid};
use super::surface_tension::{SurfaceTension, Update};
use super::walls::{LayersCache, lightest_layers};
use crate::boundary::{Boundary, Layers, WallKernel};
use crate::error::Result;
use crate::kernels::Kernels;
use crate::particles::Particles;
use crate::processor::{Context, Processor, Program};

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
    /// The walls' layers and the mass they were found for.
    layers: LayersCache,
}

impl FluidModel {
    /// A wall's density term at distance `d`, as a fraction of ρ0, and its
    /// slope −d/dd: the analytic half-space, or in `layers` (under a
    /// clearance) the fluid's lattice continued behind the wall
    /// ([`WallKernel::layers_fraction_and_density`]), with which a
    /// lattice's first layer held at half a spacing starts at rest density.
    #[inline]
    fn wall_term(&self, d: f32, layers: Option<Layers>) -> (f32, f32) {
        match layers {
            Some(layers) => self.wall.layers_fraction_and_density(d, layers),
            None => (self.wall.volume_fraction(d), self.wall.plane_density(d)),
        }
    }

    /// Under a clearance, the walls' layers of the lattice of the lightest
    /// of `masses` ([`WallKernel::lattice_layers`]).
    fn layers(&mut self, masses: &[f32]) -> Option<Layers> {
        if self.boundary.clearance > 0.0 {
            lightest_layers(
                &self.wall,
                self.params.rest_density,
                masses,
                &mut self.layers,
            )
        } else {
            None
        }
    }

    fn new(params: FluidParams, boundary: Boundary) -> Result<Self> {
        params.validate()?;
        boundary.validate()?;
        Ok(Self {
            params,
            kernels: Kernels::new(params.h)?,
            wall: WallKernel::new(params.h),
            boundary,
            layers: None,
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
        let layers = self.0.layers(masses);
        let model = &self.0;
        let FluidModel {
            params,
            kernels,
            boundary: b,
            ..
        } = model;
        let (poly6, rho0, h) = (kernels.poly6, params.rest_density, params.h);
        let slot_masses = grid.to_slot_order(masses);
        let rho = grid.par_map(|_, nb| {
            let mut rho = nb.poly6_sums(&poly6, &slot_masses).value;
            b.for_each_wall_within(nb.centre(), h, |d, _| {
                rho += rho0 * model.wall_term(d, layers).0;
            });
            rho
        });
        let (k, suction) = (params.stiffness, params.negative_pressure_scale);
        let f = particles.fields_mut();
        f.densities.copy_from_slice(&rho);
        region::for_each(f.pressures, |i, p| {
            let eos = k * (rho[i] - rho0);
            *p = if eos < 0.0 { suction * eos } else { eos };
        });
        Ok(())
    }
    fn runs_in_region(&self) -> bool {
        true
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
        let layers = self.0.layers(particles.masses());
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
        let (model, prm, b) = (&self.0, self.0.params, &self.0.boundary);
        // Per-particle factors, so the pair loop has no division but the spiky
        // kernel's 1/r: volume m/ρ and pressure term p/ρ² (eq. 15).
        let n = m.len();
        let (mut vol, mut pr) = (vec![0.0; n], vec![0.0; n]);
        region::for_each(&mut vol, |i, vol| *vol = m[i] / rho[i]);
        region::for_each(&mut pr, |i, pr| *pr = p[i] / (rho[i] * rho[i]));
        // The pair sums read their neighbours' data in slot order (cell by
        // cell), like the grid's coordinates.
        let velocity: [Vec<f32>; 3] = std::array::from_fn(|a| {
            let order = grid.order();
            let mut slots = vec![0.0; n];
            region::for_each(&mut slots, |s, u| *u = v[order[s] as usize][a]);
            slots
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
            } = force_sums(&nb, centre, &kernels, &fluid);
            b.for_each_wall_within(nb.centre(), prm.h, |d, normal| {
                // −m_i (p_i/ρ_i²) ∇ρ_wall / m_i: the gradient of the wall term's energy.
                a_p += pi * prm.rest_density * model.wall_term(d, layers).1 * normal;
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
        region::for_each(f.accelerations, |i, a| *a = out[i].0);
        region::for_each(f.colour_gradients, |i, n| *n = out[i].1);
        region::for_each(f.colour_laplacians, |i, l| *l = out[i].2);
        Ok(())
    }
    fn runs_in_region(&self) -> bool {
        true
    }
}

/// The WCSPH program: grid → density → forces → integrate → boundaries.
///
/// # Errors
/// Parameters or a boundary that do not validate.
pub fn program(params: FluidParams, boundary: Boundary) -> Result<Program> {
    let akinci = params.surface_tension > 0.0
        && params.surface_tension_model == Some(SurfaceTensionModel::Akinci);
    let force_sums = FluidParams {
        surface_tension: if akinci { 0.0 } else { params.surface_tension },
        ..params
    };
    let mut program = Program::new("sph");
    program
        .push(BuildGrid::new(params.h, 1))
        .push(DensityPressure::new(params, boundary.clone())?)
        .push(Forces::new(force_sums, boundary.clone())?);
    if akinci {
        program
            .push(FindNeighbours::new(params.h))
            .push(SurfaceTension::new(&params, Update::Accelerations)?);
    }
    program.push(Integrate).push(Boundaries::new(boundary)?);
    Ok(program)
}
