//! Divergence-free SPH (Bender & Koschier 2015, "Divergence-Free Smoothed
//! Particle Hydrodynamics", SCA; 2017, IEEE TVCG): incompressibility by two
//! implicit pressure solves per step, one that makes the velocity field
//! divergence-free and one that brings the predicted density to rest
//! density, at a step set by the flow's speed (a CFL condition), not by a
//! speed of sound. The default solver of SPlisHSPlasH.
//!
//! The paper's Algorithm 1, station by station (in SPlisHSPlasH's order,
//! which starts a step where the paper's loop body ends: the neighbours,
//! densities and factors of the positions the previous step left):
//!
//! | Algorithm 1 | station | processor |
//! |---|---|---|
//! | find neighbours | `grid`, `neighbours` | [`BuildGrid`], [`FindNeighbours`] |
//! | compute ρ_i, α_i | `factors` | [`Factors`] |
//! | correct the divergence error (Algorithm 2) | `divergence` | [`DivergenceSolve`] |
//! | non-pressure forces | `forces`, `surface tension`, `viscosity` | [`BodyForces`], [`SurfaceTension`], [`ImplicitViscosity`] |
//! | Δt by the CFL condition | (the [`crate::World`]'s clock) | [`DfsphParams::cfl`] |
//! | v* ← v + Δt a; correct the density error (Algorithm 3) | `density` | [`DensitySolve`] |
//! | x ← x + Δt v* | `advect`, `boundaries` | [`Advect`], [`Boundaries`] |
//!
//! **Kernel.** Densities and pressure gradients both use the cubic spline
//! ([`CubicSpline`], SPlisHSPlasH's default), so the density change a solve
//! predicts is the change the next density sum measures. Poly6 densities
//! with spiky gradients (PBF's pair) made a resting tank boil at 0.1 m/s;
//! poly6's own gradient, which fades inside h/√5, let particles pair up.
//! Scenes give DFSPH particles the mass at which their lattice sums to ρ0
//! under this kernel ([`crate::Solver::particle_mass`]).
//!
//! **Walls.** The walls' density term f_i = ρ_wall(x_i)/ρ0 is the fluid's
//! own lattice continued behind each wall, in the layers of the lightest
//! particle's lattice ([`crate::boundary::WallKernel::lattice_layers`]),
//! so a lattice filled to the walls starts at rest density. (The continuous
//! half-space integral of WCSPH and PBF starts the layer on a wall 3.8 %
//! compressed under this kernel, and the first step kicked a resting tank
//! to 0.3 m/s.) Meeting walls are united as in PBF.
//!
//! **Contacts.** After the step, the projection keeps particle centres the
//! boundary's clearance from the walls ([`Boundary::clearance`]). Both
//! solves know it: a particle within h/2 of that plane has its velocity
//! into the wall held to what reaches the plane, v* first and then
//! v* + Δt a(κ) at every iteration (projected Jacobi). Without it a solve
//! lets the first layer make way into the wall for the layer above, which
//! the projection then stops: in a 0.5 m pool at rest with a 1 cm
//! clearance the 2–4 cm band stayed 4.6 % compressed and the floor layer
//! moved at 86 mm/s (`cargo run --release -p sph-core --example
//! pool_at_rest -- dfsph --depth 0.5 --clearance 0.01 --bands`; with the
//! contacts 0.08 %, 12 mm/s). Without a clearance the walls' steep density
//! term alone holds particles off, and there are no contacts (holding them
//! at the wall's plane raised the dam break's most compressed particle
//! from 0.66 to 0.83 % at a tight tolerance).
//!
//! **The linear system.** Both solves are one relaxed Jacobi iteration on
//! different right-hand sides (SPlisHSPlasH's, after Ihmsen et al. 2014).
//! With volumes V_j = m_j/ρ0 and the pairs' G_ij = V_j ∇W_ij:
//!
//! - the density rate DS_i/Dt = Σ_j (v_i − v_j)·G_ij + v_i·∇f_i (ρ/ρ0 per s);
//! - a field κ (m²/s², κ = ρ0 p/ρ²) accelerates particle i by
//!   a_i = −(κ_i g_i + Σ_j κ_j G_ij), g_i = Σ_j G_ij + ∇f_i: the symmetric
//!   SPH pressure force −Σ_j V_j (κ_i + κ_j)∇W_ij (momentum conserved pair
//!   by pair) and the walls' push −κ_i ∇f_i, the gradient of their density
//!   term (no energy in or out: pressure mirrored into the wall, 2κ_i,
//!   made a resting tank boil at 0.5 m/s);
//! - (Aκ)_i = Δt² (Σ_j (a_i − a_j)·G_ij + a_i·∇f_i) is the density change
//!   those accelerations make over the step, and its diagonal is
//!   −Δt²/α_i, α_i = 1 / (|g_i|² + Σ_j |G_ij|²) (0 where that vanishes: a
//!   lone particle feels no pressure);
//! - the source b_i is the density change to undo: −Δt DS_i/Dt for the
//!   divergence solve, 1 − (ρ_i/ρ0 + Δt DS_i/Dt) for the density solve;
//! - each iteration moves κ_i ← max(κ_i − ω r_i α_i/Δt², 0) with the residual
//!   r_i = b_i − (Aκ)_i: projected to κ ≥ 0, so a particle below rest
//!   density (the free surface) is not pulled. Its error is
//!   e_i = max(−r_i, 0), the compression (or compressing rate) left.
//! - **Relaxation.** ω = ½ (SPlisHSPlasH's) while the neighbourhood is
//!   small enough for it to converge, less beyond ([`relaxation`]: ½ up to
//!   about h = 2.4 spacings, 0.2 at 3).
//! - Each solve stops when the mean of e_i over all particles is at most its
//!   tolerance ([`DfsphParams::density_tolerance`],
//!   [`DfsphParams::divergence_tolerance`]), after at least two density
//!   iterations (the paper's minimum) and one divergence iteration, or at
//!   [`DfsphParams::max_iterations`] (counted in
//!   [`crate::StepCounters::unconverged`]). A mean error that is not finite,
//!   or above 10 % ([`MAX_MEAN_ERROR`]) and no lower than at the first
//!   iteration, or still above it at the last, stops the run
//!   ([`Error::Unstable`]).
//! - **Warm start.** Each solve starts from half the previous step's κ of
//!   its particle where the source compresses (b_i < 0), 0 elsewhere, as
//!   SPlisHSPlasH does. The κ ride with their particles through the grid's
//!   reordering, as the particle attributes [`KAPPA_DENSITY`] and
//!   [`KAPPA_DIVERGENCE`].
//! - **Pressure.** Both solves' κ act over the step:
//!   p_i = (κ_i^div + κ_i^dens) ρ_i²/ρ0 into [`Particles::pressures`] (Pa).
//!   Away from the walls it is hydrostatic (`tests/dfsph.rs`: slope within
//!   1 % of ρ0 g); the layer on a wall, pushed by its own κ only, holds
//!   twice the hydrostatic pressure.
//! - **Viscosity** is implicit (Weiler et al. 2018,
//!   [`super::viscosity`]) with [`FluidParams::viscosity`] μ in Pa·s and
//!   no-slip walls, so no viscosity limits the step.
//! - **Sleeping** ([`DfsphParams::sleep_speed`], off by default, as PBF's):
//!   water at rest settles towards about 3 mm/s of particle-scale motion
//!   at any tolerance; 1 cm/s stills a 0.2 m pool by 1.5 s and a 0.5 m one
//!   by 2 s, and stops any real motion slower than that with it.
//! - **Surface tension** σ > 0 adds Akinci et al. 2013's cohesion and
//!   curvature accelerations after the body forces
//!   ([`super::surface_tension`], the same forces and σ-to-γ scale as
//!   PBF's, with their measured accuracy).

use std::ops::Range;
use std::sync::{Arc, Mutex};

use glam::Vec3;

use super::free_surface::{SmoothedLengths, SurfaceTarget, TargetCache};
use super::lane_map::{LaneMap, LaneRowMap, fill_block, par_map, par_map_rows};
use super::lanes::{DensitySums, LANES, LaneCubic, LaneKernels, Near, rows_of};
use super::params::FluidParams;
use super::stations::{BodyForces, Boundaries, BuildGrid, FindNeighbours, lists};
use super::surface_tension::SurfaceTension;
use super::viscosity::{ImplicitViscosity, Update};
use super::walls::{LayersCache, Walls};
use crate::boundary::{Boundary, Layers, WallKernel};
use crate::error::{Error, Result};
use crate::grid::NeighbourLists;
use crate::kernels::{CubicSpline, Kernel};
use crate::particles::Particles;
use crate::processor::{Context, Processor, Program};
use crate::region::{self, Blocks};
use crate::simd::F32x8;

mod params;
pub use params::{DfsphParams, MAX_DFSPH_ITERATIONS};

/// The density solve's fewest iterations (Bender & Koschier 2017).
const MIN_DENSITY_ITERATIONS: u32 = 2;

/// The divergence solve's fewest iterations.
const MIN_DIVERGENCE_ITERATIONS: u32 = 1;

/// The mean error above which a solve has failed and the run stops
/// ([`Error::Unstable`]): a mean compression of 10 %, when it makes no
/// headway over its iterations or is still there at the last.
pub const MAX_MEAN_ERROR: f32 = 0.1;

/// The particle attribute (f32) holding each particle's total κ of the
/// last density solve (m²/s²), its warm start.
pub const KAPPA_DENSITY: &str = "dfsph_kappa";

/// The particle attribute (f32) holding each particle's total κ of the last
/// divergence solve (m²/s²), its warm start.
pub const KAPPA_DIVERGENCE: &str = "dfsph_kappa_divergence";

/// The DFSPH program: grid → neighbours → factors → divergence → forces →
/// (surface tension, where σ > 0) → viscosity → density → advect →
/// boundaries.
///
/// # Errors
/// Parameters or a boundary that do not validate.
pub fn program(params: FluidParams, dfsph: DfsphParams, boundary: Boundary) -> Result<Program> {
    let model = Arc::new(Model::new(params, dfsph, boundary.clone())?);
    let shared = Shared::default();
    let mut program = Program::new("dfsph");
    program
        .push(BuildGrid::new(params.h, 1))
        .push(FindNeighbours::new(params.h))
        .push(Factors {
            model: model.clone(),
            shared: shared.clone(),
            rows: Vec::new(),
            layers: None,
            surface: None,
            lengths: Default::default(),
        })
        .push(DivergenceSolve(Solve::new(
            model.clone(),
            shared.clone(),
            Target::Divergence,
        )))
        .push(BodyForces::new(params.gravity));
    if params.surface_tension > 0.0 {
        program.push(SurfaceTension::new(&params, Update::Accelerations)?);
    }
    program
        .push(ImplicitViscosity::new(
            &params,
            boundary.clone(),
            dfsph.viscosity_tolerance,
            dfsph.viscosity_max_iterations,
            Update::Accelerations,
        )?)
        .push(DensitySolve(Solve::new(model, shared, Target::Density)))
        .push(Advect::new(dfsph.sleep_speed, params.gravity.length()))
        .push(Boundaries::new(boundary)?);
    Ok(program)
}

/// What the DFSPH stations share: parameters, kernels, walls.
#[derive(Debug, Clone)]
struct Model {
    params: FluidParams,
    dfsph: DfsphParams,
    walls: Walls,
    lanes: LaneCubic,
    cubic: CubicSpline,
    /// 1 / ρ0.
    inv_rho0: f32,
    /// W_poly6(0).
    w0: f32,
}

impl Model {
    fn new(params: FluidParams, dfsph: DfsphParams, boundary: Boundary) -> Result<Self> {
        params.validate()?;
        dfsph.validate()?;
        boundary.validate()?;
        dfsph.check_sleep(params.gravity.length(), dfsph.max_dt)?;
        let h = params.h;
        let cubic = CubicSpline::new(h)?;
        Ok(Self {
            params,
            dfsph,
            walls: Walls::new(boundary, WallKernel::cubic_spline(h), params.rest_density),
            lanes: LaneCubic::new(&cubic),
            cubic,
            inv_rho0: 1.0 / params.rest_density,
            w0: cubic.coefficient(),
        })
    }

    /// 1/sum, or 0 where the sum is below 1e-6/h²: a particle with (almost)
    /// no neighbours and no walls feels no pressure.
    #[inline]
    fn inverse(&self, sum: f32) -> f32 {
        let tiny = 1e-6 / (self.params.h * self.params.h);
        if sum > tiny { 1.0 / sum } else { 0.0 }
    }

    /// Particle i's density (with the walls), α_i, g_i and the walls'
    /// ∇f_i at the current positions, from `rows` of (x, m); writes each
    /// neighbour's G_ij = (m_j/ρ0)∇W_ij into `pairs` (i's row).
    #[inline(always)]
    fn factor<S: F32x8>(
        &self,
        i: usize,
        rows: &[[f32; 4]],
        lists: &NeighbourLists,
        layers: Option<Layers>,
        pairs: &mut [Vec3],
    ) -> Factor {
        let xi = rows[i];
        let (x, mi) = (Vec3::new(xi[0], xi[1], xi[2]), xi[3]);
        let (rho_wall, wall) = self.walls.at_either(x, layers);
        let inv_rho0 = S::splat(self.inv_rho0);
        let mut sums = DensitySums::new();
        for (chunk, (_, slots, count)) in lists.lanes(i).enumerate() {
            let c = Near::<S>::gather(xi, rows, slots, count);
            let (w, s) = self.lanes.eval(c.r2());
            let [gx, gy, gz] = sums.add(&c, w, s, inv_rho0);
            let (gx, gy, gz) = (gx.to_array(), gy.to_array(), gz.to_array());
            let out = &mut pairs[chunk * LANES..][..count];
            for (l, o) in out.iter_mut().enumerate() {
                *o = Vec3::new(gx[l], gy[l], gz[l]);
            }
        }
        let (rho_sum, grad_sum, squares) = sums.finish();
        let rho = rho_wall + mi * self.w0 + rho_sum;
        let grad = wall + grad_sum;
        let sum = grad.length_squared() + squares;
        Factor {
            rho,
            alpha: self.inverse(sum),
            grad,
            wall,
            fraction: rho_wall * self.inv_rho0,
            pairs: squares,
        }
    }
}

/// Every particle's [`Factor`], each row of G_ij written on the way.
struct FactorPass<'a> {
    model: &'a Model,
    rows: &'a [[f32; 4]],
    lists: &'a NeighbourLists,
    /// The walls' layers (none without a particle).
    layers: Option<Layers>,
}

impl LaneRowMap for FactorPass<'_> {
    type Out = Factor;
    type Pair = Vec3;
    #[inline(always)]
    fn particle<S: F32x8>(&self, i: usize, pairs: &mut [Vec3]) -> Factor {
        (self.model).factor::<S>(i, self.rows, self.lists, self.layers, pairs)
    }
}

/// One particle's share of the step's linear system.
#[derive(Debug, Clone, Copy, Default)]
struct Factor {
    /// ρ_i (kg/m³), the walls' term included.
    rho: f32,
    /// α_i = 1 / (|g_i|² + Σ_j |G_ij|²) (m²).
    alpha: f32,
    /// g_i = Σ_j G_ij + ∇f_i (1/m).
    grad: Vec3,
    /// The walls' ∇f_i (1/m).
    wall: Vec3,
    /// The walls' f_i = ρ_wall/ρ0.
    fraction: f32,
    /// Σ_j |G_ij|² (1/m²).
    pairs: f32,
}

/// Which error a [`Solve`] drives to its tolerance.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Target {
    /// max(Δt DS/Dt, 0).
    Divergence,
    /// max(ρ/ρ0 + Δt DS/Dt − 1, 0).
    Density,
}

impl Target {
    fn name(self) -> &'static str {
        match self {
            Target::Divergence => "divergence",
            Target::Density => "density",
        }
    }
    fn attribute(self) -> &'static str {
        match self {
            Target::Divergence => KAPPA_DIVERGENCE,
            Target::Density => KAPPA_DENSITY,
        }
    }
    fn min_iterations(self) -> u32 {
        match self {
            Target::Divergence => MIN_DIVERGENCE_ITERATIONS,
            Target::Density => MIN_DENSITY_ITERATIONS,
        }
    }
}

/// The relaxation ω of the Jacobi iteration for particles `spacing` apart
/// under the cubic spline `cubic`: SPlisHSPlasH's ½ where that converges,
/// less where the neighbourhood is wide.
///
/// Relaxed Jacobi, κ ← κ + ω D⁻¹(b − Aκ), converges while ω < 2/λ, with λ
/// the largest eigenvalue of D⁻¹A. On a lattice in the fluid's bulk A's
/// modes are plane waves e^{iθ·x}, with eigenvalue
/// λ(θ) = |Σ_j G_j sin(θ·r_j)|² / Σ_j |G_j|² over the neighbour offsets
/// r_j (G_j = ∇W(r_j)): 2.8 at h = 2 spacings, 4.4 at 2.5, 7.5 at 3. So
/// ω = ½ diverges beyond about 2.4 spacings (measured: a tank at h = 3
/// spacings stopped as unstable at its first step). ω is
/// min(½, 1.5/λ_max), λ_max the largest λ(θ) over a 13³ grid of the
/// octant θ ∈ [0, π]³ (the other octants mirror it): a quarter below the
/// limit, for packings less regular than the lattice.
pub fn relaxation(cubic: &CubicSpline, spacing: f32) -> f32 {
    const MODES: usize = 13;
    let h = cubic.h() as f64;
    let s = spacing as f64;
    let n = (h / s).ceil() as i32;
    let mut offsets = Vec::new();
    for k in -n..=n {
        for j in -n..=n {
            for i in -n..=n {
                let r = glam::DVec3::new(i.into(), j.into(), k.into()) * s;
                let len = r.length();
                if len > 0.0 && len < h {
                    let g = r * (f64::from(cubic.derivative_len(len as f32)) / len);
                    offsets.push((glam::DVec3::new(i.into(), j.into(), k.into()), g));
                }
            }
        }
    }
    let norm: f64 = offsets.iter().map(|(_, g)| g.length_squared()).sum();
    if norm <= 0.0 {
        return 0.5;
    }
    let step = std::f64::consts::PI / (MODES - 1) as f64;
    let mut largest = 0.0f64;
    for a in 0..MODES {
        for b in 0..MODES {
            for c in 0..MODES {
                let theta = glam::DVec3::new(a as f64, b as f64, c as f64) * step;
                let wave: glam::DVec3 =
                    (offsets.iter()).map(|&(p, g)| g * theta.dot(p).sin()).sum();
                largest = largest.max(wave.length_squared() / norm);
            }
        }
    }
    (0.5f64).min(1.5 / largest) as f32
}

/// The relaxation for the widest neighbourhood of `masses`: the smallest
/// spacing V^⅓ = (m/ρ0)^⅓. Kept in `cache` while that spacing stays the same.
///
/// # Errors
/// A particle added since the world was built that is too light for h
/// ([`FluidParams::check_masses`]): its neighbourhood would take
/// [`relaxation`] (h/V^⅓)³ offsets.
fn cached_relaxation(cache: &mut Option<(f32, f32)>, masses: &[f32], model: &Model) -> Result<f32> {
    let spacing = (super::lanes::lightest(masses) * model.inv_rho0).cbrt();
    match *cache {
        Some((s, omega)) if s == spacing => Ok(omega),
        _ => {
            model.params.check_masses(masses)?;
            let omega = relaxation(&model.cubic, spacing);
            *cache = Some((spacing, omega));
            Ok(omega)
        }
    }
}

/// The factors of the step's positions, which the `factors` station
/// computes and both solves read: per particle, then G_ij per pair in the
/// neighbour lists' order.
#[derive(Debug, Default)]
struct Linearisation {
    factors: Vec<Factor>,
    pairs: Vec<Vec3>,
    /// The particles within reach of a wall's clearance.
    contacts: Vec<Contact>,
    /// The walls' layers of the step ([`Walls::layers`]).
    layers: Option<Layers>,
    /// With [`DfsphParams::surface_target`], each particle's density
    /// target over ρ0 (`free_surface`); empty without.
    targets: Vec<f32>,
}

/// The [`Linearisation`] the stations of one program share.
type Shared = Arc<Mutex<Linearisation>>;

/// Locks the shared factors (a poisoned lock, from a panic elsewhere,
/// still holds whole vectors).
fn lock(shared: &Shared) -> std::sync::MutexGuard<'_, Linearisation> {
    shared
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// Algorithm 1's "compute densities ρ_i and factors α_i": the densities
/// (into [`Particles::densities`]), α_i, g_i, the walls' term and G_ij of
/// the step's positions, and the solves' contacts, once for both solves
/// (nothing between them moves a particle).
#[derive(Debug)]
pub struct Factors {
    model: Arc<Model>,
    shared: Shared,
    /// (x, m) per particle.
    rows: Vec<[f32; 4]>,
    /// The walls' layers, for the lightest particle's lattice.
    layers: LayersCache,
    /// The free surface's target, for the same lattice.
    surface: TargetCache,
    /// Each particle's |∇C|, then averaged (`free_surface`).
    lengths: [Vec<f32>; 2],
}

impl Processor for Factors {
    fn name(&self) -> &str {
        "factors"
    }
    fn runs_in_region(&self) -> bool {
        true
    }
    fn process(&mut self, particles: &mut Particles, ctx: &mut Context) -> Result<()> {
        let lists = lists(ctx, particles, "factors")?;
        let model = &*self.model;
        let mut shared = lock(&self.shared);
        let Linearisation {
            factors,
            pairs,
            contacts,
            layers,
            targets,
        } = &mut *shared;
        let f = particles.fields_mut();
        rows_of(f.positions, f.masses, &mut self.rows);
        pairs.resize(lists.pairs(), Vec3::ZERO);
        factors.resize(f.positions.len(), Factor::default());
        *layers = model.walls.layers(f.masses, &mut self.layers);
        let kernels = LaneKernels::Cubic(model.lanes);
        let surface = if model.dfsph.surface_target {
            SurfaceTarget::lightest(
                model.walls.kernel(),
                &kernels,
                model.params.rest_density,
                f.masses,
                &mut self.surface,
            )
        } else {
            None
        };
        let pass = FactorPass {
            model,
            rows: &self.rows,
            lists,
            layers: *layers,
        };
        par_map_rows(&pass, lists, factors, pairs);
        targets.clear();
        if let Some(surface) = surface {
            let [lengths, smoothed] = &mut self.lengths;
            lengths.resize(factors.len(), 0.0);
            region::for_each(lengths, |i, l| *l = factors[i].grad.length());
            let pass = SmoothedLengths {
                kernels: &kernels,
                rows: &self.rows,
                lists,
                lengths,
                w0: model.w0,
            };
            pass.targets(surface, smoothed, targets);
        }
        // Padding, so that a row's last chunk of G_ij reads as eight lanes.
        pairs.extend([Vec3::ZERO; PAIR_PADDING]);
        region::for_each(f.densities, |i, rho| *rho = factors[i].rho);
        let reach = 0.5 * model.params.h;
        Contact::find(model.walls.boundary(), f.positions, reach, contacts);
        Ok(())
    }
}

/// Particle i's share of a solve: the walls' gradient the solve linearises
/// with, its α, and the source b_i.
#[derive(Debug, Clone, Copy, Default)]
struct Row {
    wall: Vec3,
    alpha: f32,
    source: f32,
}

/// The Jacobi solve both pressure stations run, with its working memory.
#[derive(Debug)]
struct Solve {
    model: Arc<Model>,
    shared: Shared,
    target: Target,
    rows: Vec<Row>,
    /// κ_i (m²/s²), warm start included.
    kappa: Vec<f32>,
    /// The pressure accelerations of κ, as rows (a, 0).
    accelerations: Vec<[f32; 4]>,
    /// Σ_j (u_i − u_j)·G_ij per particle, of the velocities or the
    /// accelerations.
    products: Vec<f32>,
    /// Each iteration's compression left, per block.
    sums: Vec<f64>,
    /// The velocities as rows (v, 0).
    vrows: Vec<[f32; 4]>,
    /// The density solve's record of the divergence solve's κ_i.
    applied: Vec<f32>,
    /// The last spacing and its [`relaxation`].
    relaxation: Option<(f32, f32)>,
}

/// A particle near a wall: the step must not take it closer than the
/// boundary's clearance, where the projection after the step would stop
/// it ([`Boundary::resolve`]). The solves hold its velocity's component
/// into the wall to at least −gap/Δt ([`Contact::least`]), so that they
/// predict the densities the projection will leave, rather than a first
/// layer that makes way into the wall for the layer above.
#[derive(Debug, Clone, Copy)]
struct Contact {
    i: usize,
    /// The wall's normal, into the fluid.
    n: Vec3,
    /// The distance to the clearance plane (m, ≥ 0).
    gap: f32,
}

impl Contact {
    /// The particles within `reach` of a clearance plane of `b`'s walls,
    /// in index order, with one contact per wall; none without a
    /// clearance.
    fn find(b: &Boundary, x: &[Vec3], reach: f32, out: &mut Vec<Contact>) {
        out.clear();
        let c = b.clearance;
        if c <= 0.0 {
            return;
        }
        for (i, &xi) in x.iter().enumerate() {
            b.for_each_wall_within(xi, c + reach, |d, n| {
                let gap = (d - c).max(0.0);
                out.push(Contact { i, n, gap });
            });
        }
    }

    /// The least normal velocity of a step of `dt`: the one that reaches
    /// the clearance plane.
    #[inline]
    fn least(&self, dt: f32) -> f32 {
        -self.gap / dt
    }

    /// Raises `u`'s component into the wall to at least `least`.
    #[inline]
    fn hold(&self, u: &mut Vec3, least: f32) {
        let un = u.dot(self.n);
        if un < least {
            *u += (least - un) * self.n;
        }
    }
}

impl Solve {
    fn new(model: Arc<Model>, shared: Shared, target: Target) -> Self {
        Self {
            model,
            shared,
            target,
            rows: Vec::new(),
            kappa: Vec::new(),
            accelerations: Vec::new(),
            products: Vec::new(),
            vrows: Vec::new(),
            sums: Vec::new(),
            applied: Vec::new(),
            relaxation: None,
        }
    }

    /// The iterations for κ on the shared factors, then the velocities.
    /// The density solve first adds the non-pressure forces (v* = v + Δt a)
    /// and at the end writes the pressures.
    fn run(&mut self, particles: &mut Particles, ctx: &mut Context) -> Result<()> {
        let omega = cached_relaxation(&mut self.relaxation, particles.masses(), &self.model)?;
        let (dt, target) = (ctx.dt, self.target);
        let lists = lists(ctx, particles, target.name())?;
        let model = &*self.model;
        let n = particles.len();
        let shared = lock(&self.shared);
        let (factors, pairs, layers) = (&shared.factors, &shared.pairs, shared.layers);
        let targets = &shared.targets;
        if factors.len() != n || pairs.len() != lists.pairs() + PAIR_PADDING {
            return Err(Error::Pipeline {
                processor: target.name(),
                reason: "needs this step's factors: put the `factors` station after `neighbours` and before it, with no processor between that adds, removes or moves particles",
            });
        }
        if !particles.has_attribute(target.attribute()) {
            particles.add_attribute(target.attribute(), 0.0f32)?;
        }
        self.kappa.clear();
        (self.kappa).extend_from_slice(particles.attribute::<f32>(target.attribute())?);
        // The step's pressure is both solves' κ: the divergence solve's
        // total, already applied, and this one's.
        self.applied.clear();
        if target == Target::Density && particles.has_attribute(KAPPA_DIVERGENCE) {
            (self.applied).extend_from_slice(particles.attribute::<f32>(KAPPA_DIVERGENCE)?);
        }
        self.applied.resize(n, 0.0);
        let f = particles.fields_mut();
        let x = &*f.positions;
        if target == Target::Density {
            // v* = v + Δt a: the non-pressure forces.
            let a = &*f.accelerations;
            region::for_each(f.velocities, |i, v| *v += dt * a[i]);
        }
        // Near a wall, the step ends no closer than the clearance: v* held
        // there, and later each iteration's accelerations.
        let contacts = &shared.contacts;
        for c in contacts {
            c.hold(&mut f.velocities[c.i], c.least(dt));
        }
        // Per particle, the source b_i, the density change to undo:
        // −Δt DS_i/Dt, or 1 − (ρ_i/ρ0 − f_i + f̃_i + Δt Σ_j (v_i − v_j)·G_ij).
        // The walls' term is steep and convex near a wall: linearised where
        // the particle is, it lets a particle that reaches a wall within the
        // step in too far. The density solve takes it where the step would
        // leave the particle, f̃_i = f(x_i + Δt v*_i), and linearises there.
        // The warm start: half the last step's κ where the source
        // compresses, 0 elsewhere.
        let inv_rho0 = model.inv_rho0;
        let v = &*f.velocities;
        self.vrows.resize(n, [0.0; 4]);
        region::for_each(&mut self.vrows, |i, row| {
            *row = [v[i].x, v[i].y, v[i].z, 0.0]
        });
        let products = PairProducts {
            lists,
            pairs,
            values: &self.vrows,
        };
        par_map(&products, n, &mut self.products);
        let rates = &self.products;
        self.rows.resize(n, Row::default());
        region::for_each(&mut self.rows, |i, row| {
            let c = factors[i];
            let vi = v[i];
            let rate = rates[i];
            *row = match target {
                Target::Divergence => Row {
                    wall: c.wall,
                    alpha: c.alpha,
                    source: -dt * (rate + vi.dot(c.wall)),
                },
                Target::Density => {
                    let (rho_wall, wall) = model.walls.at_either(x[i] + dt * vi, layers);
                    let walls = rho_wall * inv_rho0 - c.fraction;
                    let sum = c.grad.dot(c.grad - c.wall + wall) + c.pairs;
                    let rest = targets.get(i).copied().unwrap_or(1.0);
                    Row {
                        wall,
                        alpha: model.inverse(sum),
                        source: rest - (c.rho * inv_rho0 + walls + dt * rate),
                    }
                }
            };
        });
        let rows = &self.rows;
        region::for_each(&mut self.kappa, |i, k| {
            *k = if rows[i].source < 0.0 { 0.5 * *k } else { 0.0 };
        });
        let dfsph = model.dfsph;
        let tolerance = match target {
            Target::Divergence => dfsph.divergence_tolerance,
            Target::Density => dfsph.density_tolerance,
        };
        let (mut iterations, mut first) = (0, None);
        self.accelerations.resize(n, [0.0; 4]);
        self.sums.resize(region::blocks(n), 0.0);
        let error = loop {
            let acceleration = Blocks::new(&mut self.accelerations);
            let (kappa, sums) = (Blocks::new(&mut self.kappa), Blocks::new(&mut self.sums));
            let rows = &self.rows;
            // SAFETY (both passes): each writes only its own block of the
            // slices it owns, and reads whole only the slice the other
            // pass writes.
            // The pressure accelerations of κ, held at the contacts.
            let accelerate = |r: Range<usize>, _| {
                let kappa = unsafe { kappa.all() };
                let out = unsafe { acceleration.block(r.clone()) };
                let pressure = PressureAccelerations {
                    lists,
                    factors,
                    pairs,
                    kappa,
                };
                fill_block(&pressure, r.start, out);
                let held = contacts.partition_point(|c| c.i < r.start)
                    ..contacts.partition_point(|c| c.i < r.end);
                hold_accelerations(&contacts[held], v, dt, r.start, out);
            };
            // (Aκ)_i = Δt² (Σ_j (a_i − a_j)·G_ij + a_i·∇f_i): the density
            // change the pressure accelerations make over the step. Each κ_i
            // moves by ω times its Jacobi step towards (Aκ)_i = b_i,
            // projected to κ_i ≥ 0; e_i = max((Aκ)_i − b_i, 0) is the
            // compression left, summed per block.
            let relax = |r: Range<usize>, block: usize| {
                let a = unsafe { acceleration.all() };
                let mut products = [0.0; region::BLOCK];
                let products = &mut products[..r.len()];
                let map = PairProducts {
                    lists,
                    pairs,
                    values: a,
                };
                fill_block(&map, r.start, products);
                let ks = unsafe { kappa.block(r.clone()) };
                let mut sum = 0.0f64;
                for ((k, i), product) in ks.iter_mut().zip(r).zip(products) {
                    let row = rows[i];
                    let ai = Vec3::new(a[i][0], a[i][1], a[i][2]);
                    let ak = ai.dot(row.wall) + *product;
                    let residual = row.source - dt * dt * ak;
                    sum += f64::from((-residual).max(0.0));
                    *k = (*k - omega * residual * row.alpha / (dt * dt)).max(0.0);
                }
                unsafe { sums.block(block..block + 1)[0] = sum };
            };
            region::run(n, &[&accelerate, &relax]);
            iterations += 1;
            let error = (self.sums.iter().sum::<f64>() / n.max(1) as f64) as f32;
            let first = *first.get_or_insert(error);
            if !error.is_finite() || (error > MAX_MEAN_ERROR && error >= first && iterations > 1) {
                return Err(self.unstable(ctx, error, first, iterations));
            }
            let done = iterations >= target.min_iterations() && error <= tolerance;
            if done {
                break error;
            }
            if iterations >= dfsph.max_iterations {
                if error > MAX_MEAN_ERROR {
                    return Err(self.unstable(ctx, error, first, iterations));
                }
                break error;
            }
        };
        // v ← v + Δt a(κ).
        let kappa = &self.kappa;
        let pressure = PressureAccelerations {
            lists,
            factors,
            pairs,
            kappa,
        };
        par_map(&pressure, n, &mut self.accelerations);
        hold_accelerations(contacts, f.velocities, dt, 0, &mut self.accelerations);
        let a = &self.accelerations;
        region::for_each(f.velocities, |i, v| {
            *v += dt * Vec3::new(a[i][0], a[i][1], a[i][2])
        });
        if error > tolerance {
            ctx.counters.unconverged += 1;
        }
        match target {
            Target::Divergence => ctx.counters.divergence_iterations += iterations,
            Target::Density => {
                ctx.counters.iterations += iterations;
                let rest = model.params.rest_density;
                let applied = &self.applied;
                region::for_each(f.pressures, |i, p| {
                    let rho = factors[i].rho;
                    *p = (applied[i] + kappa[i]) * rho * rho / rest;
                });
            }
        }
        drop(shared);
        particles
            .attribute_mut::<f32>(target.attribute())?
            .copy_from_slice(&self.kappa);
        Ok(())
    }

    fn unstable(&self, ctx: &Context, error: f32, first: f32, iterations: u32) -> Error {
        let dfsph = self.model.dfsph;
        Error::Unstable {
            step: ctx.step,
            time: ctx.time,
            what: format!(
                "the {} solve diverged: a mean error of {:.2} % after {iterations} iterations, \
                 from {:.2} % at the first",
                self.target.name(),
                error * 100.0,
                first * 100.0
            ),
            hint: format!(
                "lower solver.dfsph.cfl (now {}) or solver.dfsph.max_dt (now {:e} s), or raise \
                 solver.dfsph.max_iterations (now {}); check that no particles start on top of \
                 each other",
                dfsph.cfl, dfsph.max_dt, dfsph.max_iterations
            ),
        }
    }
}

/// Rows of G_ij padded at the end, so that a row's last chunk of eight
/// reads whole ([`F32x8::load_vec3s`] reads one vector past the eighth).
const PAIR_PADDING: usize = LANES + 1;

/// Every particle's pressure acceleration under `kappa`, as a row (a, 0):
/// a_i = −(κ_i g_i + Σ_j κ_j G_ij) = −Σ_j V_j (κ_i + κ_j)∇W_ij − κ_i ∇f_i.
struct PressureAccelerations<'a> {
    lists: &'a NeighbourLists,
    factors: &'a [Factor],
    /// G_ij, laid out as the rows, padded.
    pairs: &'a [Vec3],
    kappa: &'a [f32],
}

impl LaneMap for PressureAccelerations<'_> {
    type Out = [f32; 4];
    #[inline(always)]
    fn particle<S: F32x8>(&self, i: usize) -> [f32; 4] {
        let mut sum = [S::splat(0.0); 3];
        for (at, slots, count) in self.lists.lanes(i) {
            let g = S::load_vec3s(&self.pairs[at..]);
            let k = S::gather(self.kappa, slots) * S::first(count);
            for (sum, g) in sum.iter_mut().zip(g) {
                *sum = *sum + k * g;
            }
        }
        let [x, y, z] = sum;
        let a = -(self.kappa[i] * self.factors[i].grad + Vec3::new(x.sum(), y.sum(), z.sum()));
        [a.x, a.y, a.z, 0.0]
    }
}

/// Holds each contact's acceleration a so that v + Δt a keeps to its
/// [`Contact::least`] normal velocity.
/// `a` holds the rows of particles `first..`.
fn hold_accelerations(contacts: &[Contact], v: &[Vec3], dt: f32, first: usize, a: &mut [[f32; 4]]) {
    for c in contacts {
        let row = &mut a[c.i - first];
        let mut ai = Vec3::new(row[0], row[1], row[2]);
        c.hold(&mut ai, (c.least(dt) - v[c.i].dot(c.n)) / dt);
        *row = [ai.x, ai.y, ai.z, 0.0];
    }
}

/// Σ_j (u_i − u_j)·G_ij for every particle, from rows (u, ·) of a vector
/// per particle (velocities or accelerations).
struct PairProducts<'a> {
    lists: &'a NeighbourLists,
    /// G_ij, laid out as the rows, padded.
    pairs: &'a [Vec3],
    values: &'a [[f32; 4]],
}

impl LaneMap for PairProducts<'_> {
    type Out = f32;
    #[inline(always)]
    fn particle<S: F32x8>(&self, i: usize) -> f32 {
        let ui = self.values[i];
        let mut sum = S::splat(0.0);
        for (at, slots, count) in self.lists.lanes(i) {
            let [gx, gy, gz] = S::load_vec3s(&self.pairs[at..]);
            let [ux, uy, uz, _] = S::gather_rows(self.values, slots);
            let dot = (S::splat(ui[0]) - ux) * gx
                + (S::splat(ui[1]) - uy) * gy
                + (S::splat(ui[2]) - uz) * gz;
            sum = sum + dot * S::first(count);
        }
        sum.sum()
    }
}

/// Algorithm 2: velocities corrected until the density would change by at
/// most [`DfsphParams::divergence_tolerance`] over the step on average.
#[derive(Debug)]
pub struct DivergenceSolve(Solve);

impl Processor for DivergenceSolve {
    fn name(&self) -> &str {
        "divergence"
    }
    fn runs_in_region(&self) -> bool {
        true
    }
    fn process(&mut self, particles: &mut Particles, ctx: &mut Context) -> Result<()> {
        self.0.run(particles, ctx)
    }
}

/// Algorithm 3: v* ← v + Δt a (the non-pressure forces), then velocities
/// corrected until the density they predict for the step's end is at most
/// [`DfsphParams::density_tolerance`] above rest on average. The total κ is
/// the pressure, p = κ ρ²/ρ0, into [`Particles::pressures`].
#[derive(Debug)]
pub struct DensitySolve(Solve);

impl Processor for DensitySolve {
    fn name(&self) -> &str {
        "density"
    }
    fn runs_in_region(&self) -> bool {
        true
    }
    fn process(&mut self, particles: &mut Particles, ctx: &mut Context) -> Result<()> {
        self.0.run(particles, ctx)
    }
}

/// x ← x + Δt v: the positions of the step's end, from the velocities the
/// density solve left. With particle sleeping
/// ([`DfsphParams::sleep_speed`]), a particle slower than the threshold
/// stays and its velocity becomes zero, in steps where gravity alone would
/// give more than the threshold (|g| Δt above it).
#[derive(Debug, Clone, Copy, Default)]
pub struct Advect {
    sleep: f32,
    gravity: f32,
}

impl Advect {
    /// With particles slower than `sleep_speed` (m/s; 0 for none) put to
    /// sleep, under gravity of magnitude `gravity` (m/s²).
    pub fn new(sleep_speed: f32, gravity: f32) -> Self {
        Self {
            sleep: sleep_speed,
            gravity,
        }
    }
}

impl Processor for Advect {
    fn name(&self) -> &str {
        "advect"
    }
    fn runs_in_region(&self) -> bool {
        true
    }
    fn process(&mut self, particles: &mut Particles, ctx: &mut Context) -> Result<()> {
        let dt = ctx.dt;
        let f = particles.fields_mut();
        let sleep = self.sleep;
        if sleep > 0.0 && sleep < self.gravity * dt {
            region::for_each(f.velocities, |_, v| {
                if v.length() < sleep {
                    *v = Vec3::ZERO;
                }
            });
        }
        let v = &*f.velocities;
        region::for_each(f.positions, |i, x| *x += dt * v[i]);
        ctx.invalidate_grid(); // positions moved
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::NeighbourGrid;
    use crate::boundary::Aabb;
    use crate::solver::lane_map::every_kind_rows;
    use crate::solver::lanes::jittered_block;

    /// The factor pass gives bitwise the same factors and G_ij with every
    /// kind of lanes (plain arrays, SSE2, AVX2, AVX2 with AVX-512VL's
    /// registers), on a jittered block with unequal masses resting on the
    /// floor, so the walls count.
    #[test]
    fn factor_pass_agrees_across_kinds() {
        let h = 0.04;
        let params = FluidParams::water(h);
        let boundary = Boundary::new(Aabb::new(Vec3::ZERO, Vec3::splat(0.3)));
        let model = Model::new(params, DfsphParams::default(), boundary).unwrap();
        let (x, m, _) = jittered_block();
        let grid = NeighbourGrid::build(&x, h).unwrap();
        let lists = NeighbourLists::build(&grid).unwrap();
        let mut rows = Vec::new();
        rows_of(&x, &m, &mut rows);
        let pass = FactorPass {
            model: &model,
            rows: &rows,
            lists: &lists,
            layers: Some(WallKernel::cubic_spline(h).lattice_layers(m[0], params.rest_density)),
        };
        let kinds = every_kind_rows(&pass, &lists);
        assert!(kinds.len() >= 2, "at least the plain and one vector kind");
        let bits = |factors: &[Factor], pairs: &[Vec3]| {
            let mut b: Vec<u32> = Vec::new();
            for f in factors {
                b.extend([f.rho, f.alpha, f.fraction, f.pairs].map(f32::to_bits));
                b.extend(f.grad.to_array().map(f32::to_bits));
                b.extend(f.wall.to_array().map(f32::to_bits));
            }
            b.extend(pairs.iter().flat_map(|g| g.to_array().map(f32::to_bits)));
            b
        };
        let (_, plain_factors, plain_pairs) = &kinds[0];
        let plain = bits(plain_factors, plain_pairs);
        assert!(plain_pairs.iter().any(|g| g.length() > 0.0));
        for (name, factors, pairs) in &kinds[1..] {
            assert!(
                bits(factors, pairs) == plain,
                "{name} differs from the plain lanes"
            );
        }
    }

    /// λ_max of the lattice's Jacobi matrix, against the values of an
    /// independent sweep (a 24³ grid over [0, 2π)³, in Python): 2.81 at
    /// h = 2 spacings, 4.37 at 2.5, 7.45 at 3; ω = min(½, 1.5/λ).
    #[test]
    fn relaxation_follows_the_neighbourhood() {
        let h = 0.04;
        let cubic = CubicSpline::new(h).unwrap();
        for (ratio, lambda) in [(2.0f32, 2.814f32), (2.5, 4.374), (3.0, 7.451)] {
            let omega = relaxation(&cubic, h / ratio);
            let expected = (0.5f32).min(1.5 / lambda);
            assert!(
                (omega - expected).abs() < 0.01 * expected,
                "h/s {ratio}: ω {omega}, expected {expected}"
            );
        }
    }
}
