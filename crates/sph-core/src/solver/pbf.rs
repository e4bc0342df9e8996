//! Position-based fluids (Macklin & Müller 2013, "Position Based Fluids",
//! SIGGRAPH): incompressibility as a density constraint per particle,
//! C_i = ρ_i/ρ0 − 1, solved by a few Jacobi iterations on predicted positions
//! each substep. It stays stable at steps set by the frame rate, not by a
//! speed of sound: NVIDIA FleX runs its dam break at 1/60 s with 2 substeps
//! and 3 iterations.
//!
//! The paper's Algorithm 1, station by station:
//!
//! | Algorithm 1 | station | processor |
//! |---|---|---|
//! | 1–4: v ← v + Δt f_ext, x* ← x + Δt v | `forces`, `predict` | [`BodyForces`], [`Predict`] |
//! | 5–7: find neighbours on x* | `grid`, `neighbours` | [`BuildGrid`], [`FindNeighbours`] |
//! | 8–19: λ_i, Δp_i (with s_corr), collision response, x* ← x* + Δp | `density` | [`SolveDensity`] |
//! | 20–21: v ← (x* − x)/Δt | (kept true by `density`) | [`SolveDensity`] |
//! | 22: vorticity confinement, XSPH viscosity | `viscosity` | [`VorticityXsph`] |
//! | 22: or the implicit viscosity of μ | `implicit_viscosity` | [`ImplicitViscosity`] |
//! | 23: x ← x* | `boundaries` | [`Boundaries`] |
//!
//! Choices the paper leaves open, and what this module does:
//! - **Masses.** Δp_i = (1/ρ0) Σ_j m_j (λ_i + λ_j + s_corr) ∇W_ij (the paper
//!   has equal masses, m_j = 1). Each pair's term is antisymmetric, so
//!   Σ m_i Δp_i = 0: a free cluster keeps its momentum to round-off.
//! - **One-sided constraint.** C_i = max(ρ_i/ρ0 − 1, 0), as SPlisHSPlasH's
//!   PBF does: particles with fewer neighbours than in the bulk (the free
//!   surface, spray) are not pulled together, which is what made the paper
//!   need s_corr against clustering; it is here, off by default
//!   ([`PbfParams::scorr_k`]).
//! - **Units of ε and s_corr.** The paper gives them in its own units. Here
//!   ε = [`PbfParams::relaxation`] / h² (Σ|∇C|² is in 1/m²), and
//!   s_corr = −k (W(r)/W(Δq h))ⁿ · ½(D_i + D_j) with D_i = 1/(Σ_k|∇_k C_i|² + ε):
//!   the correction a density error of k·(W/W(Δq))ⁿ would make, symmetric in
//!   i and j so momentum stays conserved.
//! - **Walls.** The domain walls and obstacles add the analytic density of
//!   the fluid behind them ([`crate::boundary::WallKernel`]), and that term's
//!   gradient enters ∇_i C_i, so particles settle at rest density against a
//!   wall instead of piling into it. Where walls meet, their half-spaces
//!   are united, not added (`Walls::at`). Every iteration projects
//!   positions back out of walls ([`Boundary::project`]): nothing leaks,
//!   whatever the step. Under a [`Boundary::clearance`] the walls' term is
//!   the fluid's lattice continued behind them, in the layers of the
//!   lightest particle's lattice (`Walls::at_layers`,
//!   [`crate::boundary::WallKernel::lattice_layers`], as DFSPH's), so a
//!   lattice's first layer, held at half a spacing, starts at rest density.
//!   The analytic half-space starts it 2.6 % above at h = 2 spacings
//!   (0.216 of ρ0 against the lattice's missing 0.191), and the demo's
//!   1,000 Pa·s slab slump then took a first frame of 1.06 % average
//!   density error against 0.45 % without the clearance.
//! - **Gradient.** ∇W_spiky, as the paper. The exact gradient of the poly6
//!   density (needing Jacobi under-relaxed by 0.75 to stay stable) was
//!   tried in a throwaway patch: it settled a tank ten times tighter and
//!   cost a square root and a division less per pair, but the 10,000-particle
//!   dam break burst into foam filling the tank even at 6 substeps per frame
//!   (rendered frames), the pairing the paper chose spiky against.
//! - **Neighbours** are found once per substep on the predicted positions
//!   and kept through the iterations ([`crate::NeighbourLists`]), as in the
//!   paper; distances use the current positions.
//! - **Velocity.** Every correction Δx of a position (a wall's push
//!   included) also adds Δx/Δt to the velocity, so v = (x* − x)/Δt (line 21)
//!   holds throughout. Adding the corrections rather than recomputing v
//!   from the positions keeps their rounding out of v: at 0.1 ms substeps
//!   an ulp of a position 5 m from the origin is 5 mm/s of velocity, and a
//!   free fall drifted 0.4 m in 10,000 substeps.
//! - **Viscosity** is one of two ([`PbfParams::viscosity`]): XSPH
//!   ([`PbfParams::xsph`], the default: a smoothing of the velocities with
//!   no unit, cheap), or the physical μ of [`FluidParams::viscosity`] in
//!   Pa·s, solved implicitly after the velocity update (Weiler et al. 2018,
//!   [`super::viscosity`], with no-slip walls), which makes a PBF fluid of
//!   a given μ flow as that fluid does (`tests/viscosity.rs`: duct flow).
//!   The stiffness of [`FluidParams`] is WCSPH's.
//! - **Surface tension** σ > 0 adds Akinci et al. 2013's cohesion and
//!   curvature forces after the viscosity station
//!   ([`super::surface_tension`], with its measured accuracy).
//! - **Rest.** PBF's few Jacobi iterations leave water at rest jittering,
//!   about 80 mm/s rms in a still pool at the defaults: each substep's
//!   unconverged solve moves particles, and the spiky gradient on a poly6
//!   density and Jacobi's overshoot keep that motion going (the history of
//!   attempts is in `docs/benchmark-notes.md`, "Water at rest"). Particle
//!   sleeping ([`PbfParams::sleep_speed`], Macklin et al. 2014's and FleX's)
//!   stops it where a scene asks: a particle its substep would move slower
//!   than the threshold stays where it was. It is off by default, because
//!   it also stops any real motion slower than the threshold and needs
//!   damping and more iterations to reach below it (in a 0.2 m pool: XSPH
//!   0.1 and 4 iterations instead of 3, a third more Jacobi passes), which
//!   the dam break does not want. [`PbfSolve::GaussSeidel`] takes away most
//!   of the jitter's source instead: with the cubic spline's density and
//!   its own gradient, solved constraint by constraint (`coloured`), the
//!   same pool keeps 21.6 mm/s at 3 substeps and 10.8 at 4, for about
//!   2.3 times the density station's time.
//! - **Gauss–Seidel** ([`PbfParams::solve`]): the sweeps move particles in
//!   place, so lines 12–21 run per constraint: i and its neighbours move
//!   by the terms of Δp that constraint i gives them, each projected out of
//!   the walls, and their velocities by that motion over Δt.
//! - **Warm start** ([`PbfParams::warm_start`], Gauss–Seidel only, off by
//!   default): a few sweeps carry a correction a few neighbourhoods per
//!   substep, so a deep column's weight is held by compressing it, and each
//!   substep rebuilds that pressure from nothing. Warm-started, the solve
//!   first moves the particles by a share w of the pressure the last
//!   substep ended with (one Jacobi-form correction), and each constraint's
//!   λ then accumulates over the sweeps from that share, clamped as a sum
//!   as contact solvers clamp accumulated impulses. At w = 0.5 a pool
//!   0.5 m deep jitters a third as fast and the dam break's density error
//!   halves. The carried pressure is an explicit force, one substep late,
//!   which only the fresh part of each solve damps, so w is bounded at ½:
//!   at 0.85 a deep pool diverges.
//! - **Guard.** The predicted displacement per substep is limited to
//!   [`PbfParams::max_displacement`] × h (FleX clamps speed the same way);
//!   every clamped particle is counted in [`crate::StepCounters::clamped`].

use std::ops::Range;

use glam::Vec3;

use super::params::FluidParams;
use super::stations::{Boundaries, BuildGrid};
use crate::NeighbourLists;
use crate::boundary::{Boundary, WallKernel};
use crate::error::{Error, Result};
use crate::kernels::{CubicSpline, Poly6, Spiky};
use crate::particles::Particles;
use crate::processor::{Context, Processor, Program};

use super::free_surface::{SmoothedLengths, SurfaceTarget, TargetCache};
use super::lane_map::{LaneMap, fill_block, par_map};
use super::lanes::{DensitySums, LaneCubic, LaneKernels, Near, rows_of};
use super::stations::lists;
pub use super::stations::{BodyForces, FindNeighbours};
use super::surface_tension::SurfaceTension;
use super::viscosity::{ImplicitViscosity, Update};
use super::walls::{LayersCache, Walls};
use crate::region::{self, Blocks, OwnedPass, Pass};
use crate::simd::{F32x8, Lanes};

mod coloured;
mod params;
use params::check_sleep_at;
pub use params::{FALL_CFL, MAX_DENSITY_ERROR, MAX_PBF_COUNT, PbfParams, PbfSolve, PbfViscosity};

/// The PBF program: forces → predict → grid → neighbours → density →
/// viscosity (vorticity and XSPH) → surface tension (where σ > 0,
/// [`SurfaceTension`]) → implicit viscosity (with
/// [`PbfViscosity::Implicit`]) → boundaries.
///
/// # Errors
/// Parameters or a boundary that do not validate.
pub fn program(params: FluidParams, pbf: PbfParams, boundary: Boundary) -> Result<Program> {
    let model = Model::new(params, pbf, boundary.clone())?;
    let mut program = Program::new("pbf");
    program
        .push(BodyForces::new(params.gravity))
        .push(Predict {
            boundary: boundary.clone(),
            max_displacement: pbf.max_displacement * params.h,
        })
        .push(BuildGrid::new(params.h, 1))
        .push(FindNeighbours::new(params.h))
        .push(SolveDensity::with_model(model.clone()))
        .push(VorticityXsph::with_model(model));
    if params.surface_tension > 0.0 {
        program.push(SurfaceTension::new(&params, Update::Velocities)?);
    }
    if pbf.viscosity == PbfViscosity::Implicit {
        program.push(ImplicitViscosity::new(
            &params,
            boundary.clone(),
            pbf.viscosity_tolerance,
            pbf.viscosity_max_iterations,
            Update::Velocities,
        )?);
    }
    program.push(Boundaries::new(boundary)?);
    Ok(program)
}

/// Lines 1–4: v ← v + Δt a, limited to the guard's displacement, then
/// x* ← x + Δt v, projected out of walls (which changes v to match:
/// v = (x* − x)/Δt).
#[derive(Debug, Clone)]
pub struct Predict {
    boundary: Boundary,
    max_displacement: f32,
}

impl Predict {
    /// Guarding a substep's displacement to `max_displacement` (m) inside
    /// `boundary`.
    ///
    /// # Errors
    /// A boundary that does not validate, or a guard that is not finite and
    /// positive.
    pub fn new(boundary: Boundary, max_displacement: f32) -> Result<Self> {
        boundary.validate()?;
        crate::error::positive("max_displacement", max_displacement)?;
        Ok(Self {
            boundary,
            max_displacement,
        })
    }
}

impl Processor for Predict {
    fn name(&self) -> &str {
        "predict"
    }
    fn runs_in_region(&self) -> bool {
        true
    }
    fn process(&mut self, particles: &mut Particles, ctx: &mut Context) -> Result<()> {
        let dt = ctx.dt;
        let max_speed = self.max_displacement / dt;
        let b = &self.boundary;
        let n = particles.len();
        let f = particles.fields_mut();
        let (xs, vs, accelerations) = (
            Blocks::new(f.positions),
            Blocks::new(f.velocities),
            &*f.accelerations,
        );
        let counts = region::map_blocks(n, |range| {
            // SAFETY: each block writes its own particles; nothing reads
            // them in this pass.
            let (x, v) = unsafe { (xs.block(range.clone()), vs.block(range.clone())) };
            let mut clamped = 0;
            for ((x, v), &a) in x.iter_mut().zip(v).zip(&accelerations[range]) {
                *v += a * dt;
                let speed = v.length();
                let clamp = speed > max_speed;
                if clamp {
                    *v *= max_speed / speed;
                }
                *x += *v * dt;
                // v = (x* − x)/Δt, the wall's push included. Only the push
                // enters v: recomputing v from rounded positions would feed
                // their rounding (an ulp of x over Δt) into it every substep.
                let free = *x;
                b.project(x);
                *v += (*x - free) / dt;
                clamped += u64::from(clamp);
            }
            clamped
        });
        let clamped: u64 = counts.iter().sum();
        ctx.counters.clamped += clamped;
        ctx.invalidate_grid(); // positions moved
        Ok(())
    }
}

/// What the PBF stations share: parameters, kernels, walls.
#[derive(Debug, Clone)]
struct Model {
    params: FluidParams,
    pbf: PbfParams,
    walls: Walls,
    /// ε in 1/m².
    epsilon: f32,
    /// 1 / W(Δq·h).
    inv_w_dq: f32,
    /// 1 / ρ0.
    inv_rho0: f32,
    /// The kernels lane by lane ([`PbfSolve`] picks them).
    lanes: LaneKernels,
    /// W(0), the density's own term.
    w0: f32,
    /// Under a clearance, the layers of the fluid's lattice that the walls
    /// continue behind them ([`Walls::at_layers`]): the lightest
    /// particle's lattice, with the mass they were found for, set by each
    /// station's pass ([`Model::set_layers`]).
    layers: LayersCache,
    /// With [`PbfParams::surface_target`], the free surface's target for
    /// the lightest particle's lattice ([`Model::set_layers`]).
    surface: Option<SurfaceTarget>,
    surface_cache: TargetCache,
}

impl Model {
    /// The walls' density term and its gradient over ρ0 at `x` ([`Walls`]).
    #[inline(always)]
    fn walls_at(&self, x: Vec3) -> (f32, Vec3) {
        self.walls
            .at_either(x, self.layers.map(|(_, layers)| layers))
    }

    /// Under a clearance, the walls' layers of the lattice of the lightest
    /// of `masses` ([`crate::boundary::WallKernel::lattice_layers`]).
    fn set_layers(&mut self, masses: &[f32]) {
        if self.walls.boundary().clearance > 0.0 {
            self.walls.layers(masses, &mut self.layers);
        }
        if self.pbf.surface_target {
            self.surface = SurfaceTarget::lightest(
                self.walls.kernel(),
                &self.lanes,
                self.params.rest_density,
                masses,
                &mut self.surface_cache,
            );
        }
    }

    fn new(params: FluidParams, pbf: PbfParams, boundary: Boundary) -> Result<Self> {
        params.validate()?;
        pbf.validate()?;
        boundary.validate()?;
        let h = params.h;
        let (poly6, spiky) = (Poly6::new(h)?, Spiky::new(h)?);
        let dq = pbf.scorr_dq * h;
        // Gauss–Seidel's kernel: the cubic spline, its density and its own
        // gradient, and the walls' term of the same kernel.
        let (lanes, wall_kernel, w, w_dq) = match pbf.solve {
            PbfSolve::Jacobi => (
                LaneKernels::poly6_spiky(&poly6, &spiky, h),
                WallKernel::new(h),
                poly6.value_r2(0.0),
                poly6.value_r2(dq * dq),
            ),
            PbfSolve::GaussSeidel => {
                let cubic = CubicSpline::new(h)?;
                (
                    LaneKernels::Cubic(LaneCubic::new(&cubic)),
                    WallKernel::cubic_spline(h),
                    cubic.value_len(0.0),
                    cubic.value_len(dq),
                )
            }
        };
        Ok(Self {
            params,
            pbf,
            walls: Walls::new(boundary, wall_kernel, params.rest_density),
            epsilon: pbf.relaxation / (h * h),
            inv_w_dq: 1.0 / w_dq,
            inv_rho0: 1.0 / params.rest_density,
            lanes,
            w0: w,
            layers: None,
            surface: None,
            surface_cache: None,
        })
    }

    /// Density ρ_i and the constraint's λ_i and D_i = 1/(Σ_k|∇_k C_i|² + ε)
    /// (lines 9–11), from `rows` of (x, m).
    #[inline(always)]
    fn constraint<S: F32x8>(
        &self,
        i: usize,
        rows: &[[f32; 4]],
        lists: &NeighbourLists,
    ) -> Constraint {
        let xi = rows[i];
        let (rho_wall, wall) = self.walls_at(Vec3::new(xi[0], xi[1], xi[2]));
        let inv_rho0 = S::splat(self.inv_rho0);
        // ρ, ∇_i C_i and Σ|∇_j C_i|² (∇_j C_i = −G_ij).
        let mut sums = DensitySums::new();
        for (_, slots, count) in lists.lanes(i) {
            let c = Near::<S>::gather(xi, rows, slots, count);
            let (w, s) = self.lanes.eval(c.r2());
            sums.add(&c, w, s, inv_rho0);
        }
        let (rho_sum, grad_sum, squares) = sums.finish();
        let rho = rho_wall + xi[3] * self.w0 + rho_sum;
        let grad_i = wall + grad_sum;
        let error = rho * self.inv_rho0 - 1.0;
        let d = 1.0 / (grad_i.length_squared() + squares + self.epsilon);
        Constraint {
            rho,
            lambda: -error.max(0.0) * d,
            d,
            wall,
        }
    }

    /// The position correction Δp_i = (1/ρ0) Σ_j m_j (λ_i + λ_j + s_corr)
    /// ∇W_ij plus the walls' λ_i ∇_i(ρ_wall/ρ0) (lines 12–13), from `rows`
    /// of (x, m) at the positions the constraints were taken at.
    #[inline(always)]
    fn correction<S: F32x8>(
        &self,
        i: usize,
        rows: &[[f32; 4]],
        constraints: &[Constraint],
        lists: &NeighbourLists,
    ) -> Vec3 {
        let constraint = &constraints[i];
        // Each constraint's (λ, D) read as the first two floats of a row.
        let coefs: &[[f32; 6]] = bytemuck::cast_slice(constraints);
        let (k, n) = (self.pbf.scorr_k, self.pbf.scorr_n);
        // s_corr off (the default) adds nothing: skip it.
        let scorr_on = k > 0.0;
        let (lambda_i, d_i) = (S::splat(constraint.lambda), S::splat(constraint.d));
        let (inv_rho0, inv_w_dq) = (S::splat(self.inv_rho0), S::splat(self.inv_w_dq));
        let (k, half) = (S::splat(k), S::splat(0.5));
        let mut acc = [S::splat(0.0); 3];
        for (_, slots, count) in lists.lanes(i) {
            let c = Near::<S>::gather(rows[i], rows, slots, count);
            let [lambda_j, d_j, _, _] = S::gather_rows(coefs, &c.slots);
            let (w, s) = self.lanes.eval(c.r2());
            let mut sum = lambda_i + lambda_j;
            if scorr_on {
                // k (W_ij/W(Δq))ⁿ, by n − 1 products; 0 in unused lanes,
                // which may hold a particle at r = 0.
                let q = w * inv_w_dq * S::first(count);
                let mut scorr = q;
                for _ in 1..n {
                    scorr = scorr * q;
                }
                sum = sum - k * scorr * half * (d_i + d_j);
            }
            let f = s * c.m * inv_rho0;
            for (acc, d) in acc.iter_mut().zip(c.d) {
                *acc = *acc + d * f * sum;
            }
        }
        constraint.lambda * constraint.wall + Vec3::new(acc[0].sum(), acc[1].sum(), acc[2].sum())
    }

    /// The viscosity station's sums for particle i at the current positions,
    /// from `rows` of (x, m) and velocity `vrows` of (v, 0): density (with
    /// the walls), curl ω_i = Σ_j (m_j/ρ0)(v_j − v_i) × ∇W_ij and XSPH mean
    /// Σ_j (m_j/ρ0)(v_j − v_i) W_ij.
    #[inline(always)]
    fn curl_and_mean<S: F32x8>(
        &self,
        i: usize,
        rows: &[[f32; 4]],
        vrows: &[[f32; 4]],
        lists: &NeighbourLists,
    ) -> Sums {
        let (xi, vi) = (rows[i], vrows[i]);
        let inv_rho0 = S::splat(self.inv_rho0);
        // Per lane: ρ, curl by axis, mean by axis.
        let mut acc = [S::splat(0.0); 7];
        for (_, slots, count) in lists.lanes(i) {
            let c = Near::<S>::gather(xi, rows, slots, count);
            let (w, s) = self.lanes.eval(c.r2());
            let [vx, vy, vz, _] = S::gather_rows(vrows, &c.slots);
            let u = [
                vx - S::splat(vi[0]),
                vy - S::splat(vi[1]),
                vz - S::splat(vi[2]),
            ];
            let vol = c.m * inv_rho0;
            let f = s * vol;
            let g = [c.d[0] * f, c.d[1] * f, c.d[2] * f];
            acc[0] = acc[0] + c.m * w;
            // v_ij × (m_j/ρ0)∇W_ij
            acc[1] = acc[1] + (u[1] * g[2] - u[2] * g[1]);
            acc[2] = acc[2] + (u[2] * g[0] - u[0] * g[2]);
            acc[3] = acc[3] + (u[0] * g[1] - u[1] * g[0]);
            let vw = vol * w;
            for a in 0..3 {
                acc[4 + a] = acc[4 + a] + u[a] * vw;
            }
        }
        let x = Vec3::new(xi[0], xi[1], xi[2]);
        let curl = Vec3::new(acc[1].sum(), acc[2].sum(), acc[3].sum());
        Sums {
            rho: self.walls_at(x).0 + xi[3] * self.w0 + acc[0].sum(),
            curl,
            curl_len: curl.length(),
            mean: Vec3::new(acc[4].sum(), acc[5].sum(), acc[6].sum()),
        }
    }

    /// η_i = Σ_j (m_j/ρ0)(|ω_j| − |ω_i|) ∇W_ij, the gradient of |ω| that
    /// vorticity confinement pushes along, from `rows` of (x, m) and each
    /// particle's |ω|.
    #[inline(always)]
    fn curl_gradient<S: F32x8>(
        &self,
        i: usize,
        rows: &[[f32; 4]],
        curl_len: &[f32],
        lists: &NeighbourLists,
    ) -> Vec3 {
        let inv_rho0 = S::splat(self.inv_rho0);
        let wi = S::splat(curl_len[i]);
        let mut acc = [S::splat(0.0); 3];
        for (_, slots, count) in lists.lanes(i) {
            let c = Near::<S>::gather(rows[i], rows, slots, count);
            let (_, s) = self.lanes.eval(c.r2());
            let dw = S::gather(curl_len, &c.slots) - wi;
            let f = s * c.m * inv_rho0;
            for (acc, d) in acc.iter_mut().zip(c.d) {
                *acc = *acc + d * f * dw;
            }
        }
        Vec3::new(acc[0].sum(), acc[1].sum(), acc[2].sum())
    }
}

/// One particle's density constraint. λ and D lead, so that the Δp pass
/// gathers them as a row's first floats.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, bytemuck::Pod, bytemuck::Zeroable)]
struct Constraint {
    lambda: f32,
    d: f32,
    rho: f32,
    /// ∇_i(ρ_wall/ρ0).
    wall: Vec3,
}

/// Lines 8–19 (and 21): [`PbfParams::iterations`] Jacobi iterations of the
/// density constraint. Each computes every λ_i, then every position
/// correction Δp_i = (1/ρ0) Σ_j m_j (λ_i + λ_j + s_corr) ∇W_ij plus the
/// walls' λ_i ∇_i(ρ_wall/ρ0), moves each particle by it and back out of
/// walls, and adds that motion over Δt to its velocity. Under
/// [`PbfSolve::GaussSeidel`] each iteration is instead a sweep of the
/// constraints one by one, in coloured columns (`coloured`).
///
/// Writes the pressure the solve applied into [`Particles::pressures`]:
/// p_i = −ω ρ0 Σ_k λ_i^k / Δt² over the iterations k. A pressure
/// acceleration −Σ_j m_j (p_i/ρ0² + p_j/ρ0²) ∇W_ij acting for Δt moves a
/// particle by Δt² times it, which is the correction above (without
/// s_corr) with λ_i = −Δt² p_i/ρ0. In water at rest its mean grows with
/// depth at about ρ0 g, biased upwards by PBF's rest jitter: the one-sided
/// constraint answers the jitter's compressions and not its rarefactions
/// (`tests/pbf.rs`, the tank: +0.3 % at the defaults, up to +31 % at
/// other gravities and iterations).
///
/// With [`PbfParams::warm_start`] (Gauss–Seidel), the solve starts from a
/// share of the pressures the last substep left in
/// [`Particles::pressures`], and the pressure written is that share plus
/// what the sweeps add or take back.
///
/// With [`PbfParams::sleep_speed`], the last iteration puts back where they
/// were the particles it would move slower than the threshold, with zero
/// velocity; a threshold at or above g Δt is an
/// [`Error::InvalidParameter`].
///
/// Stops the run with [`Error::Unstable`] when the solve diverges: a
/// position becomes non-finite, or the largest density error is above
/// [`MAX_DENSITY_ERROR`] (twice the rest density) at the last iteration and
/// no smaller than at the first (the iterations made no headway). A
/// transient peak that the iterations are bringing down is not a failure:
/// at an impact the next substeps finish the work.
#[derive(Debug, Clone)]
pub struct SolveDensity {
    model: Model,
    /// (x, m) per particle: the positions an iteration reads, and those it
    /// leaves, in turn.
    rows: [Vec<[f32; 4]>; 2],
    constraints: Vec<Constraint>,
    /// The first and the last iteration's largest density, per block.
    densest: Vec<f32>,
    /// Whether a block's final positions are all finite.
    finite: Vec<bool>,
    /// Gauss–Seidel's columns ([`PbfSolve::GaussSeidel`]).
    colouring: coloured::Colouring,
    /// Each particle's farthest neighbour's |r|², Gauss–Seidel's check of
    /// its lists.
    farthest: Vec<f32>,
    /// Each particle's move by Gauss–Seidel's warm start.
    moves: Vec<Vec3>,
    /// Each particle's |∇C|, then averaged ([`PbfParams::surface_target`]).
    lengths: [Vec<f32>; 2],
    /// Each particle's density target over ρ0 (empty without
    /// [`PbfParams::surface_target`]).
    targets: Vec<f32>,
}

/// A solve's headway: the largest density error at its first and last
/// iteration (none without iterations), and whether a position became
/// non-finite.
struct Headway {
    first: Option<f32>,
    worst: f32,
    bad: bool,
}

impl Headway {
    /// From the largest densities of the first `iterations`' and the
    /// last's, a half of `densest` each (per block or column), and
    /// whether each block's final positions are `finite`. A non-finite
    /// state shows in the positions: the largest densities, folded by
    /// `f32::max`, pass a NaN over.
    fn of(densest: &[f32], rho0: f32, iterations: usize, finite: &[bool]) -> Self {
        let (at_first, at_last) = densest.split_at(densest.len() / 2);
        let worst = |row: &[f32]| row.iter().fold(0.0, |m: f32, &rho| m.max(rho)) / rho0 - 1.0;
        let (first, worst) = match iterations {
            0 => (None, 0.0f32),
            _ => (Some(worst(at_first)), worst(at_last)),
        };
        let bad = iterations > 0 && !finite.iter().all(|&f| f);
        Self { first, worst, bad }
    }
}

/// The λ pass: every particle's [`Constraint`].
struct Lambdas<'a> {
    model: &'a Model,
    rows: &'a [[f32; 4]],
    lists: &'a NeighbourLists,
}

impl LaneMap for Lambdas<'_> {
    type Out = Constraint;
    #[inline(always)]
    fn particle<S: F32x8>(&self, i: usize) -> Constraint {
        self.model.constraint::<S>(i, self.rows, self.lists)
    }
}

/// Every particle's |∇_i C_i|, the walls' term included (the free
/// surface's targets read it).
struct GradientLengths<'a> {
    model: &'a Model,
    rows: &'a [[f32; 4]],
    lists: &'a NeighbourLists,
}

impl LaneMap for GradientLengths<'_> {
    type Out = f32;
    #[inline(always)]
    fn particle<S: F32x8>(&self, i: usize) -> f32 {
        let m = self.model;
        let xi = self.rows[i];
        let (_, wall) = m.walls_at(Vec3::new(xi[0], xi[1], xi[2]));
        let inv_rho0 = S::splat(m.inv_rho0);
        let mut sums = DensitySums::new();
        for (_, slots, count) in self.lists.lanes(i) {
            let c = Near::<S>::gather(xi, self.rows, slots, count);
            let (w, s) = m.lanes.eval(c.r2());
            sums.add(&c, w, s, inv_rho0);
        }
        (wall + sums.finish().1).length()
    }
}

/// The Δp pass: every particle's position correction.
struct Corrections<'a> {
    model: &'a Model,
    rows: &'a [[f32; 4]],
    constraints: &'a [Constraint],
    lists: &'a NeighbourLists,
}

impl LaneMap for Corrections<'_> {
    type Out = Vec3;
    #[inline(always)]
    fn particle<S: F32x8>(&self, i: usize) -> Vec3 {
        (self.model).correction::<S>(i, self.rows, self.constraints, self.lists)
    }
}

impl SolveDensity {
    /// For this fluid, these PBF parameters and walls.
    ///
    /// # Errors
    /// Parameters or a boundary that do not validate.
    pub fn new(params: FluidParams, pbf: PbfParams, boundary: Boundary) -> Result<Self> {
        Model::new(params, pbf, boundary).map(Self::with_model)
    }

    fn with_model(model: Model) -> Self {
        Self {
            model,
            rows: [Vec::new(), Vec::new()],
            constraints: Vec::new(),
            densest: Vec::new(),
            finite: Vec::new(),
            colouring: coloured::Colouring::default(),
            farthest: Vec::new(),
            moves: Vec::new(),
            lengths: Default::default(),
            targets: Vec::new(),
        }
    }
}

impl Processor for SolveDensity {
    fn name(&self) -> &str {
        "density"
    }
    fn runs_in_region(&self) -> bool {
        true
    }
    fn process(&mut self, particles: &mut Particles, ctx: &mut Context) -> Result<()> {
        let lists = lists(ctx, particles, "density")?;
        self.model.set_layers(particles.masses());
        let (pbf, dt) = (self.model.pbf, ctx.dt);
        // `World::advance` checks each frame before its first substep; this
        // holds for programs that run the station themselves.
        check_sleep_at(pbf.sleep_speed, self.model.params.gravity.length(), dt)?;
        let Headway { first, worst, bad } = match pbf.solve {
            PbfSolve::Jacobi => self.jacobi(particles, lists, dt),
            PbfSolve::GaussSeidel => self.gauss_seidel(particles, lists, dt)?,
        };
        ctx.counters.iterations += pbf.iterations;
        ctx.invalidate_grid(); // positions moved; the lists stay
        let stuck = first.is_some_and(|first| worst >= first);
        if bad || (worst > MAX_DENSITY_ERROR && stuck) {
            return Err(Error::Unstable {
                step: ctx.step,
                time: ctx.time,
                what: if bad {
                    "a position became non-finite in the density constraint solve".into()
                } else {
                    format!(
                        "the density constraint solve diverged: a density error of {:.0} % \
                         after {} iterations, from {:.0} % at the first (above {:.0} %, no headway)",
                        worst * 100.0,
                        pbf.iterations,
                        first.unwrap_or(worst) * 100.0,
                        MAX_DENSITY_ERROR * 100.0
                    )
                },
                hint: format!(
                    "raise solver.pbf.iterations (now {}) or solver.pbf.substeps (now {}), \
                     or lower solver.pbf.max_dt (now {:e} s); check that no particles start on top of each other",
                    pbf.iterations, pbf.substeps, pbf.max_dt
                ),
            });
        }
        Ok(())
    }
}

impl SolveDensity {
    /// Lines 8–19 as the paper has them: Jacobi iterations, each every λ_i
    /// and then every particle moved.
    fn jacobi(&mut self, particles: &mut Particles, lists: &NeighbourLists, dt: f32) -> Headway {
        let model = &self.model;
        let (rho0, pbf) = (model.params.rest_density, model.pbf);
        let sleep = pbf.sleep_speed;
        let n = particles.len();
        let (iterations, per_pass) = (pbf.iterations as usize, region::blocks(n));
        for rows in &mut self.rows {
            rows.resize(n, [0.0; 4]);
        }
        self.constraints.resize(n, Constraint::default());
        self.densest.resize(2 * per_pass, 0.0);
        self.finite.resize(per_pass, true);
        {
            let f = particles.fields_mut();
            let [rows_a, rows_b] = &mut self.rows;
            let rows = [Blocks::new(rows_a), Blocks::new(rows_b)];
            let constraints = Blocks::new(&mut self.constraints);
            let densest = Blocks::new(&mut self.densest);
            let finite = Blocks::new(&mut self.finite);
            let (positions, velocities) = (Blocks::new(f.positions), Blocks::new(f.velocities));
            let (pressures, densities) = (Blocks::new(f.pressures), Blocks::new(f.densities));
            let masses = &*f.masses;
            let (b, omega) = (model.walls.boundary(), pbf.over_relaxation);
            let to_pressure = -omega * rho0 / (dt * dt);
            // SAFETY (every pass below): each writes only its own block of the
            // slices it owns, and reads whole only slices no pass writes
            // meanwhile; iteration k reads `rows[k % 2]` and writes the other.
            let start = |r: Range<usize>, _| {
                let (x, out) = unsafe { (positions.all(), rows[0].block(r.clone())) };
                for (row, i) in out.iter_mut().zip(r) {
                    *row = [x[i].x, x[i].y, x[i].z, masses[i]];
                }
            };
            // Lines 9–11: every λ_i, and the iteration's largest density.
            let lambdas = |k: usize| {
                let (rows, constraints, densest) = (&rows, &constraints, &densest);
                move |r: Range<usize>, block: usize| {
                    let rows = unsafe { rows[k % 2].all() };
                    let out = unsafe { constraints.block(r.clone()) };
                    fill_block(&Lambdas { model, rows, lists }, r.start, out);
                    let rho = out.iter().fold(0.0, |m: f32, c| m.max(c.rho));
                    // Row 0 keeps the first iteration's, row 1 the last's.
                    let keep = |row: usize| {
                        let at = row * per_pass + block;
                        unsafe { densest.block(at..at + 1)[0] = rho };
                    };
                    if k == 0 {
                        keep(0);
                    }
                    if k + 1 == iterations {
                        keep(1);
                    }
                }
            };
            // Lines 12–21: each particle moves by its correction and out of
            // walls, its velocity by that motion over Δt; its row for the next
            // iteration follows, and its pressure gains −ω ρ0 λ_i/Δt².
            let moves = |k: usize| {
                let (rows, constraints, finite) = (&rows, &constraints, &finite);
                let (positions, velocities) = (&positions, &velocities);
                let (pressures, densities) = (&pressures, &densities);
                move |r: Range<usize>, block: usize| {
                    let (now, c) = unsafe { (rows[k % 2].all(), constraints.all()) };
                    let mut dps = [Vec3::ZERO; region::BLOCK];
                    let dps = &mut dps[..r.len()];
                    let corrections = Corrections {
                        model,
                        rows: now,
                        constraints: c,
                        lists,
                    };
                    fill_block(&corrections, r.start, dps);
                    let (x, v) =
                        unsafe { (positions.block(r.clone()), velocities.block(r.clone())) };
                    let (p, next) =
                        unsafe { (pressures.block(r.clone()), rows[1 - k % 2].block(r.clone())) };
                    for (j, i) in r.clone().enumerate() {
                        let dp = omega * dps[j];
                        let x = &mut x[j];
                        *x += dp;
                        let free = *x;
                        b.project(x);
                        v[j] += (dp + (*x - free)) / dt;
                        next[j] = [x.x, x.y, x.z, now[i][3]];
                        let applied = to_pressure * c[i].lambda;
                        p[j] = if k == 0 { applied } else { p[j] + applied };
                    }
                    // Sleeping: a particle the substep moves slower than the
                    // threshold goes back to where it was.
                    if k + 1 == iterations && sleep > 0.0 {
                        for (x, v) in x.iter_mut().zip(v.iter_mut()) {
                            if v.length() < sleep {
                                *x -= *v * dt;
                                *v = Vec3::ZERO;
                            }
                        }
                    }
                    if k + 1 == iterations {
                        let rho = unsafe { densities.block(r.clone()) };
                        for (rho, c) in rho.iter_mut().zip(&c[r]) {
                            *rho = c.rho;
                        }
                        unsafe {
                            finite.block(block..block + 1)[0] = x.iter().all(|x| x.is_finite())
                        };
                    }
                }
            };
            let steps: Vec<OwnedPass<'_>> = (0..iterations)
                .flat_map(|k| -> [OwnedPass<'_>; 2] { [Box::new(lambdas(k)), Box::new(moves(k))] })
                .collect();
            let passes: Vec<Pass<'_>> = std::iter::once(&start as Pass<'_>)
                .chain(steps.iter().map(|p| &**p as Pass<'_>))
                .collect();
            region::run(n, &passes);
        }
        Headway::of(&self.densest, rho0, iterations, &self.finite)
    }

    /// Lines 8–19 as sweeps of Gauss–Seidel ([`PbfSolve::GaussSeidel`],
    /// `coloured`): each constraint in turn moves its particle and the
    /// neighbours from the positions the ones before it left.
    ///
    /// # Errors
    /// [`Error::Pipeline`] where a pair of `lists` is farther apart than h:
    /// lists that the colouring cannot keep apart ([`coloured::check_lists`]).
    fn gauss_seidel(
        &mut self,
        particles: &mut Particles,
        lists: &NeighbourLists,
        dt: f32,
    ) -> Result<Headway> {
        let model = &self.model;
        let (rho0, pbf) = (model.params.rest_density, model.pbf);
        let (n, iterations) = (particles.len(), pbf.iterations as usize);
        let rows = &mut self.rows[0];
        rows_of(particles.positions(), particles.masses(), rows);
        coloured::check_lists(rows, lists, model.params.h, &mut self.farthest)?;
        let colouring = &mut self.colouring;
        colouring.build(rows, model.params.h, model.params.gravity);
        let colouring = &*colouring;
        let f = particles.fields_mut();
        // After the colouring: it and the lists' check must see the same
        // positions, those the sweeps' particles were grouped by.
        if pbf.warm_start > 0.0 {
            let warm = Warm {
                model,
                lists,
                dt,
                constraints: &mut self.constraints,
                moves: &mut self.moves,
            };
            warm.apply(rows, f.pressures, f.velocities);
        }
        // The free surface's targets, from the positions the sweeps start
        // at.
        self.targets.clear();
        if let Some(surface) = model.surface {
            let [lengths, smoothed] = &mut self.lengths;
            par_map(&GradientLengths { model, rows, lists }, n, lengths);
            let pass = SmoothedLengths {
                kernels: &model.lanes,
                rows,
                lists,
                lengths,
                w0: model.w0,
            };
            pass.targets(surface, smoothed, &mut self.targets);
        }
        let columns = colouring.columns();
        self.densest.resize(2 * columns, 0.0);
        let per_pass = region::blocks(n);
        self.finite.resize(per_pass, true);
        // The sweeps, in a scope of their own: `Shared` borrows what they write.
        {
            let sweep = coloured::Sweep {
                model,
                lists,
                dt,
                warm: pbf.warm_start > 0.0,
                targets: &self.targets,
                rows: coloured::Shared::new(rows),
                velocities: coloured::Shared::new(f.velocities),
                pressures: coloured::Shared::new(f.pressures),
                densities: coloured::Shared::new(f.densities),
            };
            let densest = coloured::Shared::new(&mut self.densest);
            let lanes = Lanes::best();
            // Sweep k's pass over colour c: item t is the colour's t-th column.
            let pass = |k: usize, c: usize| {
                let (sweep, densest) = (&sweep, &densest);
                move |items: Range<usize>, _| {
                    let of_colour = colouring.colour(c);
                    for t in items.filter(|&t| t < of_colour.len()) {
                        let t = of_colour.start + t;
                        // SAFETY: the columns of colour c share no particle
                        // (`coloured`), and each column is one item; the first
                        // and last sweeps' densities are kept per column.
                        let rho = unsafe { sweep.column(colouring, t, k, lanes) };
                        if k == 0 {
                            unsafe { densest.set(t, rho) };
                        }
                        if k + 1 == iterations {
                            unsafe { densest.set(columns + t, rho) };
                        }
                    }
                }
            };
            let steps: Vec<OwnedPass<'_>> = (0..iterations)
                .flat_map(|k| {
                    let colours: [usize; 4] =
                        std::array::from_fn(|c| if k % 2 == 0 { c } else { 3 - c });
                    colours.map(|c| Box::new(pass(k, c)) as OwnedPass<'_>)
                })
                .collect();
            let passes: Vec<Pass<'_>> = steps.iter().map(|p| &**p as Pass<'_>).collect();
            if n > 0 {
                region::run_by(colouring.widest(), 1, &passes);
            }
        }
        // Sleeping, and the solved positions back from the rows.
        let sleep = pbf.sleep_speed;
        let (positions, velocities) = (Blocks::new(f.positions), Blocks::new(f.velocities));
        let finite = Blocks::new(&mut self.finite);
        let rows = &self.rows[0];
        let finish = |r: Range<usize>, block: usize| {
            // SAFETY: each block writes its own particles.
            let (x, v) = unsafe { (positions.block(r.clone()), velocities.block(r.clone())) };
            for ((x, v), row) in x.iter_mut().zip(v.iter_mut()).zip(&rows[r]) {
                *x = Vec3::new(row[0], row[1], row[2]);
                if sleep > 0.0 && v.length() < sleep {
                    *x -= *v * dt;
                    *v = Vec3::ZERO;
                }
            }
            unsafe { finite.block(block..block + 1)[0] = x.iter().all(|x| x.is_finite()) };
        };
        region::run(n, &[&finish]);
        // The first sweep's largest density is taken as each constraint
        // is, after those before it have moved its neighbours: below
        // Jacobi's first reading, so a solve that makes no headway is
        // caught a little sooner.
        Ok(Headway::of(&self.densest, rho0, iterations, &self.finite))
    }
}

/// Gauss–Seidel's warm start ([`PbfParams::warm_start`]): the last
/// substep's pressures, a share w of them, applied as one Jacobi-form
/// correction before the sweeps.
struct Warm<'a> {
    model: &'a Model,
    lists: &'a NeighbourLists,
    dt: f32,
    constraints: &'a mut Vec<Constraint>,
    moves: &'a mut Vec<Vec3>,
}

impl Warm<'_> {
    /// Moves each particle of `rows` (x, m) by the correction Δp_i of
    /// λ_i = −w Δt² p_i/ρ0 with `pressures` p, and out of the walls, and
    /// its velocity by that motion over Δt, as a Jacobi iteration does;
    /// leaves w p_i in `pressures`, the λ the sweeps accumulate from.
    fn apply(self, rows: &mut [[f32; 4]], pressures: &mut [f32], velocities: &mut [Vec3]) {
        let Self {
            model,
            lists,
            dt,
            constraints,
            moves,
        } = self;
        let w = model.pbf.warm_start;
        let to_lambda = -w * dt * dt * model.inv_rho0;
        let n = rows.len();
        constraints.resize(n, Constraint::default());
        {
            let (rows, pressures) = (&*rows, &*pressures);
            region::for_each(constraints, |i, c| {
                let x = rows[i];
                // The sweeps leave no pressure below 0; another program's
                // particles might carry one, which must not pull.
                *c = Constraint {
                    lambda: to_lambda * pressures[i].max(0.0),
                    d: 0.0,
                    rho: 0.0,
                    wall: model.walls_at(Vec3::new(x[0], x[1], x[2])).1,
                };
            });
        }
        let corrections = Corrections {
            model,
            rows,
            constraints,
            lists,
        };
        par_map(&corrections, n, moves);
        let (rows, velocities) = (Blocks::new(rows), Blocks::new(velocities));
        let pressures = Blocks::new(pressures);
        let b = model.walls.boundary();
        let moved = |r: Range<usize>, _| {
            // SAFETY: each block writes its own particles.
            let (x, v) = unsafe { (rows.block(r.clone()), velocities.block(r.clone())) };
            let p = unsafe { pressures.block(r.clone()) };
            for (((row, v), p), &dx) in x.iter_mut().zip(v).zip(p).zip(&moves[r]) {
                let free = Vec3::new(row[0], row[1], row[2]) + dx;
                let mut x = free;
                b.project(&mut x);
                *v += (dx + (x - free)) / dt;
                *row = [x.x, x.y, x.z, row[3]];
                *p = w * p.max(0.0);
            }
        };
        region::run(n, &[&moved]);
    }
}

/// Line 22: vorticity confinement and XSPH viscosity, from the velocities
/// the solve left. Also sums the density at the final positions (with the
/// walls' term) into [`Particles::densities`], which the report's density
/// error and the surface extraction's particle volumes read.
///
/// With the curl ω_i = Σ_j (m_j/ρ0)(v_j − v_i) × ∇W_ij, each velocity gains
/// Δt ε (η_i/|η_i|) × ω_i, where
/// η_i = Σ_j (m_j/ρ0)(|ω_j| − |ω_i|) ∇W_ij approximates ∇|ω|, and c Σ_j (m_j/ρ0)(v_j − v_i) W_ij.
#[derive(Debug, Clone)]
pub struct VorticityXsph {
    model: Model,
    /// (x, m) per particle.
    rows: Vec<[f32; 4]>,
    /// (v, 0) per particle.
    vrows: Vec<[f32; 4]>,
    first: Vec<Sums>,
    /// |ω| per particle.
    curl_len: Vec<f32>,
}

/// The viscosity station's first pass: every particle's [`Sums`].
struct CurlSums<'a> {
    model: &'a Model,
    rows: &'a [[f32; 4]],
    vrows: &'a [[f32; 4]],
    lists: &'a NeighbourLists,
}

impl LaneMap for CurlSums<'_> {
    type Out = Sums;
    #[inline(always)]
    fn particle<S: F32x8>(&self, i: usize) -> Sums {
        (self.model).curl_and_mean::<S>(i, self.rows, self.vrows, self.lists)
    }
}

/// The second pass: every particle's η, the gradient of |ω|.
struct CurlGradients<'a> {
    model: &'a Model,
    rows: &'a [[f32; 4]],
    curl_len: &'a [f32],
    lists: &'a NeighbourLists,
}

impl LaneMap for CurlGradients<'_> {
    type Out = Vec3;
    #[inline(always)]
    fn particle<S: F32x8>(&self, i: usize) -> Vec3 {
        (self.model).curl_gradient::<S>(i, self.rows, self.curl_len, self.lists)
    }
}

/// A particle's sums of the viscosity station's first pass.
#[derive(Debug, Clone, Copy, Default)]
struct Sums {
    rho: f32,
    curl: Vec3,
    curl_len: f32,
    mean: Vec3,
}

impl VorticityXsph {
    /// For this fluid, these PBF parameters and walls.
    ///
    /// # Errors
    /// Parameters or a boundary that do not validate.
    pub fn new(params: FluidParams, pbf: PbfParams, boundary: Boundary) -> Result<Self> {
        Model::new(params, pbf, boundary).map(Self::with_model)
    }

    fn with_model(model: Model) -> Self {
        Self {
            model,
            rows: Vec::new(),
            vrows: Vec::new(),
            first: Vec::new(),
            curl_len: Vec::new(),
        }
    }
}

impl Processor for VorticityXsph {
    fn name(&self) -> &str {
        "viscosity"
    }
    fn runs_in_region(&self) -> bool {
        true
    }
    fn process(&mut self, particles: &mut Particles, ctx: &mut Context) -> Result<()> {
        let lists = lists(ctx, particles, "viscosity")?;
        self.model.set_layers(particles.masses());
        let model = &self.model;
        let dt = ctx.dt;
        let c = match model.pbf.viscosity {
            PbfViscosity::Xsph => model.pbf.xsph,
            PbfViscosity::Implicit => 0.0,
        };
        let eps = model.pbf.vorticity;
        let n = particles.len();
        self.rows.resize(n, [0.0; 4]);
        self.vrows.resize(n, [0.0; 4]);
        self.first.resize(n, Sums::default());
        self.curl_len.resize(n, 0.0);
        let f = particles.fields_mut();
        let (rows, vrows) = (Blocks::new(&mut self.rows), Blocks::new(&mut self.vrows));
        let (first, curl_len) = (
            Blocks::new(&mut self.first),
            Blocks::new(&mut self.curl_len),
        );
        let (velocities, densities) = (Blocks::new(f.velocities), Blocks::new(f.densities));
        let (positions, masses) = (&*f.positions, &*f.masses);
        // SAFETY (every pass below): each writes only its own block of the
        // slices it owns, and reads whole only slices no pass writes
        // meanwhile.
        let start = |r: Range<usize>, _| {
            let v = unsafe { velocities.all() };
            let (out, vout) = unsafe { (rows.block(r.clone()), vrows.block(r.clone())) };
            for ((row, vrow), i) in out.iter_mut().zip(vout).zip(r) {
                let (x, v) = (positions[i], v[i]);
                *row = [x.x, x.y, x.z, masses[i]];
                *vrow = [v.x, v.y, v.z, 0.0];
            }
        };
        // Density, curl and XSPH mean at once.
        let sums = |r: Range<usize>, _| {
            let (rows, vrows) = unsafe { (rows.all(), vrows.all()) };
            let out = unsafe { first.block(r.clone()) };
            let map = CurlSums {
                model,
                rows,
                vrows,
                lists,
            };
            fill_block(&map, r.start, out);
            let len = unsafe { curl_len.block(r) };
            for (len, s) in len.iter_mut().zip(out) {
                *len = s.curl_len;
            }
        };
        // η, then each particle's velocity change, which reads only the
        // sums above, so it is added in place, with the density.
        let apply = |r: Range<usize>, _| {
            let (rows, first, curl_len) = unsafe { (rows.all(), first.all(), curl_len.all()) };
            let mut eta = [Vec3::ZERO; region::BLOCK];
            let eta = &mut eta[..r.len()];
            if eps > 0.0 {
                let map = CurlGradients {
                    model,
                    rows,
                    curl_len,
                    lists,
                };
                fill_block(&map, r.start, eta);
            }
            let (v, rho) = unsafe { (velocities.block(r.clone()), densities.block(r.clone())) };
            for (j, i) in r.enumerate() {
                let Sums { curl, mean, .. } = first[i];
                let mut dv = c * mean;
                if let Some(n) = eta[j].try_normalize() {
                    dv += dt * eps * n.cross(curl);
                }
                v[j] += dv;
                rho[j] = first[i].rho;
            }
        };
        region::run(n, &[&start, &sums, &apply]);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::NeighbourGrid;
    use crate::boundary::Aabb;
    use crate::kernels::Kernel;
    use crate::solver::lane_map::every_kind;
    use crate::solver::lanes::{jittered_block, rows_of};

    /// The lane passes give bitwise the same values with every kind of
    /// lanes (plain, SSE2, AVX2), the λ pass's density is the plain sum
    /// Σ m_j W(x_i − x_j) plus the walls' term, and the free surface's
    /// |∇C| and its average are their plain sums.
    #[test]
    fn lane_passes_agree_across_kinds_and_with_plain_sums() {
        let h = 0.04;
        let params = FluidParams::water(h);
        let pbf = PbfParams {
            scorr_k: 0.1,
            ..PbfParams::default()
        };
        // A jittered block resting on the domain's floor, so walls count.
        let boundary = Boundary::new(Aabb::new(Vec3::ZERO, Vec3::splat(0.3)));
        let model = Model::new(params, pbf, boundary).unwrap();
        let (x, m, v) = jittered_block();
        let n = x.len();
        let grid = NeighbourGrid::build(&x, h).unwrap();
        let lists = NeighbourLists::build(&grid).unwrap();
        let (mut rows, mut vrows) = (Vec::new(), Vec::new());
        rows_of(&x, &m, &mut rows);
        rows_of(&v, &m, &mut vrows);
        let (rows, vrows, lists) = (&rows[..], &vrows[..], &lists);
        let bits = |v: &[f32]| v.iter().map(|f| f.to_bits()).collect::<Vec<_>>();
        // Every kind's values, bit for bit those of the plain arrays.
        fn agreed<T>(kinds: Vec<(&str, Vec<T>)>, bits: impl Fn(&[T]) -> Vec<u32>) -> Vec<T> {
            let mut kinds = kinds.into_iter();
            let (_, plain) = kinds.next().expect("the plain kind");
            for (name, values) in kinds {
                assert!(
                    bits(&values) == bits(&plain),
                    "{name} differs from the plain lanes"
                );
            }
            plain
        }

        let flat = |c: &[Constraint]| {
            bits(
                &c.iter()
                    .flat_map(|c| [c.rho, c.lambda, c.d, c.wall.x, c.wall.y, c.wall.z])
                    .collect::<Vec<_>>(),
            )
        };
        let lambdas = Lambdas {
            model: &model,
            rows,
            lists,
        };
        let constraints = agreed(every_kind(&lambdas, n), flat);
        let poly6 = Poly6::new(h).unwrap();
        for (i, c) in constraints.iter().enumerate() {
            let plain: f32 = (0..n)
                .map(|j| m[j] * poly6.value_r2((x[i] - x[j]).length_squared()))
                .sum();
            let expected = plain + model.walls_at(x[i]).0;
            assert!(
                (c.rho - expected).abs() <= 1e-5 * expected,
                "particle {i}: {} against {expected}",
                c.rho
            );
        }
        assert!(
            constraints.iter().any(|c| c.lambda < 0.0),
            "some particles compressed"
        );

        let corrections = Corrections {
            model: &model,
            rows,
            constraints: &constraints,
            lists,
        };
        let vecs = |v: &[Vec3]| bits(&v.iter().flat_map(|v| v.to_array()).collect::<Vec<_>>());
        let dp = agreed(every_kind(&corrections, n), vecs);
        assert!(dp.iter().any(|d| d.length() > 0.0));

        let flat = |s: &[Sums]| {
            bits(
                &s.iter()
                    .flat_map(|s| {
                        [
                            s.rho, s.curl.x, s.curl.y, s.curl.z, s.mean.x, s.mean.y, s.mean.z,
                        ]
                    })
                    .collect::<Vec<_>>(),
            )
        };
        let curl_sums = CurlSums {
            model: &model,
            rows,
            vrows,
            lists,
        };
        let sums = agreed(every_kind(&curl_sums, n), flat);
        for (s, c) in sums.iter().zip(&constraints) {
            assert_eq!(
                s.rho.to_bits(),
                c.rho.to_bits(),
                "both passes sum the same density"
            );
        }
        let curl_len: Vec<f32> = sums.iter().map(|s| s.curl_len).collect();
        let gradients = CurlGradients {
            model: &model,
            rows,
            curl_len: &curl_len,
            lists,
        };
        let eta = agreed(every_kind(&gradients, n), vecs);
        assert!(eta.iter().any(|e| e.length() > 0.0));

        // The free surface's passes, on Gauss–Seidel's kernels: each |∇C|
        // (the length of Jacobi's ∇_i C_i, summed in another order), then
        // its average.
        let cubic = Model::new(
            params,
            PbfParams {
                solve: PbfSolve::GaussSeidel,
                ..PbfParams::default()
            },
            Boundary::new(Aabb::new(Vec3::ZERO, Vec3::splat(0.3))),
        )
        .unwrap();
        let lengths = GradientLengths {
            model: &cubic,
            rows,
            lists,
        };
        let lengths = agreed(every_kind(&lengths, n), |v| bits(v));
        assert!(lengths.iter().any(|&l| l > 0.0));
        // Each against the plain |Σ_j (m_j/ρ0) ∇W_ij + the walls' ∇f|, to a
        // part in 10⁵ of the sum of the terms' sizes (the bulk's cancel).
        let spline = CubicSpline::new(h).unwrap();
        for (i, &length) in lengths.iter().enumerate() {
            let terms: Vec<Vec3> = (0..n)
                .map(|j| (m[j] / params.rest_density) * spline.gradient(x[i] - x[j]))
                .collect();
            let wall = cubic.walls_at(x[i]).1;
            let plain = (terms.iter().sum::<Vec3>() + wall).length();
            let size = terms.iter().map(|t| t.length()).sum::<f32>() + wall.length();
            assert!(
                (length - plain).abs() <= 1e-5 * size,
                "particle {i}: |∇C| {length} against {plain}"
            );
        }
        let smoothed = crate::solver::free_surface::SmoothedLengths {
            kernels: &cubic.lanes,
            rows,
            lists,
            lengths: &lengths,
            w0: cubic.w0,
        };
        let smoothed = agreed(every_kind(&smoothed, n), |v| bits(v));
        // Each the plain Σ_j m_j W_ij l_j / Σ_j m_j W_ij, its own term in.
        for (i, &average) in smoothed.iter().enumerate() {
            let weights: Vec<f32> = (0..n)
                .map(|j| m[j] * spline.value_len((x[i] - x[j]).length()))
                .collect();
            let num: f32 = weights.iter().zip(&lengths).map(|(w, l)| w * l).sum();
            let plain = num / weights.iter().sum::<f32>();
            assert!(
                (average - plain).abs() <= 1e-5 * plain.max(1.0),
                "particle {i}: averaged {average} against {plain}"
            );
        }
    }
}
