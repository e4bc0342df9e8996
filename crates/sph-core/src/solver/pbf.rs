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
//!   whatever the step.
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
//!   The stiffness and surface tension of [`FluidParams`] are WCSPH's.
//! - **Guard.** The predicted displacement per substep is limited to
//!   [`PbfParams::max_displacement`] × h (FleX clamps speed the same way);
//!   every clamped particle is counted in [`crate::StepCounters::clamped`].

use glam::Vec3;
use rayon::prelude::*;

use super::params::FluidParams;
use super::stations::{Boundaries, BuildGrid};
use crate::boundary::{Boundary, WallKernel};
use crate::error::{Error, Result};
use crate::kernels::{Poly6, Spiky};
use crate::particles::Particles;
use crate::processor::{Context, Processor, Program};

use super::lanes::{Chunk, LANES, LaneKernels, total};
use super::stations::lists;
pub use super::stations::{BodyForces, FindNeighbours};
use super::viscosity::{ImplicitViscosity, Update};
use super::walls::Walls;

/// The parameters of position-based fluids. Scene files give them under
/// `[solver.pbf]`; a field left out takes its default.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PbfParams {
    /// Substeps per frame ([`crate::World::advance`]); more are taken only
    /// where a frame is longer than `substeps × max_dt`. Default 3.
    ///
    /// The density error falls about as 1/(substeps² × iterations) while
    /// the cost grows as substeps × (2 iterations + 3 passes), so substeps
    /// buy accuracy more cheaply than iterations: in a tank 10 particles
    /// deep at 60 Hz, 2 × 4 leaves 1.09 % average density error, 3 × 3
    /// 0.62 % (`cargo run --release -p sph-core --example pbf_convergence`).
    /// FleX's dam break runs 2 substeps × 3 iterations, with larger
    /// particles for its speeds.
    pub substeps: u32,
    /// Jacobi iterations of the density constraint per substep. Default 3.
    pub iterations: u32,
    /// The longest substep (s): a frame longer than `substeps × max_dt`
    /// takes more substeps, so that the step does not grow with the frame
    /// (a headless run at 5 frames per second steps as finely as one at
    /// 60). Default 1/180 s: 3 substeps per 60 Hz frame.
    pub max_dt: f32,
    /// The relaxation ε of λ_i = −C_i / (Σ_k|∇_k C_i|² + ε), in units of
    /// 1/h² (dimensionless). It keeps λ finite for particles with few
    /// neighbours and softens the constraint: larger values leave the
    /// fluid more compressed. Default 0.01.
    pub relaxation: f32,
    /// s_corr's k: the artificial pressure against particle clustering,
    /// the density error whose correction it equals at distance Δq
    /// (see the module docs). Default 0: the one-sided constraint gives
    /// clustering no pull to start from, and s_corr's push is a
    /// displacement per substep, so it grows with the substep count: with
    /// k = 0.001 a free cube of 216 particles flew apart over 10,000
    /// substeps of 0.1 ms (`tests/pbf.rs`, free fall). Scenes with the
    /// paper's tensile problem can turn it on (the paper: 0.1 in its units).
    pub scorr_k: f32,
    /// s_corr's exponent n. Default 4 (the paper's).
    pub scorr_n: u32,
    /// s_corr's Δq as a fraction of h. Default 0.2 (the paper: 0.1 to 0.3).
    pub scorr_dq: f32,
    /// Vorticity confinement ε (m/s): the acceleration ε N × ω, with ω the
    /// velocity's curl and N the direction towards larger |ω|. It gives back
    /// the rotation the damped solver loses. Default 0.01; 0 turns it off.
    pub vorticity: f32,
    /// XSPH viscosity c in [0, 1]: each substep blends a particle's velocity
    /// by c towards its neighbours' kernel-weighted mean,
    /// v_i += c Σ_j (m_j/ρ0)(v_j − v_i) W_ij. Default 0.01 (the paper's).
    pub xsph: f32,
    /// The guard: the predicted displacement of one substep, |v| Δt, is at
    /// most this fraction of h; faster particles are slowed to it and
    /// counted. Default 1 (neighbours are found on the predicted
    /// positions, so a particle may move up to h; 0.5 h clamped a fifth of
    /// the 10,000-particle dam break's particles at 2 substeps per frame).
    pub max_displacement: f32,
    /// Which viscosity acts: `"xsph"` (default) or `"implicit"`.
    pub viscosity: PbfViscosity,
    /// The implicit viscosity's tolerance: the conjugate gradients stop at
    /// this residual relative to the velocities' norm. Default 1e-3.
    pub viscosity_tolerance: f32,
    /// The implicit viscosity's most conjugate-gradient iterations per
    /// substep. Default 100.
    pub viscosity_max_iterations: u32,
}

/// The viscosity of a PBF fluid ([`PbfParams::viscosity`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum PbfViscosity {
    /// XSPH's blend of each velocity towards its neighbours' by
    /// [`PbfParams::xsph`] per substep (Macklin & Müller 2013): no physical
    /// unit, its effect depends on the substep count.
    #[default]
    Xsph,
    /// The dynamic viscosity μ of [`FluidParams::viscosity`] (Pa·s), solved
    /// implicitly each substep ([`ImplicitViscosity`]); XSPH is off.
    Implicit,
}

impl Default for PbfParams {
    fn default() -> Self {
        Self {
            substeps: 3,
            iterations: 3,
            max_dt: 1.0 / 180.0,
            relaxation: 0.01,
            scorr_k: 0.0,
            scorr_n: 4,
            scorr_dq: 0.2,
            vorticity: 0.01,
            xsph: 0.01,
            max_displacement: 1.0,
            viscosity: PbfViscosity::Xsph,
            viscosity_tolerance: 1e-3,
            viscosity_max_iterations: 100,
        }
    }
}

impl PbfParams {
    /// The defaults with enough substeps per frame of `frame_dt` (at least
    /// the default 3, and `max_dt` the frame over them) that a particle
    /// falling freely from `height` above the floor, at √(2 g height),
    /// moves at most [`FALL_CFL`] × h per substep: what a scene without a
    /// `[solver.pbf]` table runs ([`crate::Scene::pbf_params`]).
    pub fn for_fall(height: f32, gravity: f32, h: f32, frame_dt: f32) -> Self {
        let d = Self::default();
        let speed = (2.0 * gravity.abs() * height.max(0.0)).sqrt();
        let needed = (speed * frame_dt / (FALL_CFL * h)).ceil();
        let substeps = if needed.is_finite() {
            needed.clamp(d.substeps as f32, MAX_PBF_COUNT as f32) as u32
        } else {
            d.substeps
        };
        Self {
            substeps,
            max_dt: frame_dt / substeps as f32,
            ..d
        }
    }
}

/// The Courant number of [`PbfParams::for_fall`]: a substep's largest
/// expected displacement over h. Looked at in rendered frames of
/// `dam-break-fine` (10,000 particles, h = 0.02 m): at 1 (3 substeps per
/// 60 Hz frame) the flow boiled into spray over the collapsing column and
/// where it met the far wall (neither vorticity confinement off nor a
/// clamp on the solve's velocity change helped: the 2.4 % compression that
/// 3 iterations leave in a column 50 particles deep is the likely cause);
/// at 0.75 (4 substeps) it still threw spray at the wall; at 0.5 (6
/// substeps) it ran up the wall and fell back as one sheet, as WCSPH's does.
pub const FALL_CFL: f32 = 0.5;

/// The most substeps or iterations [`PbfParams::validate`] accepts.
pub const MAX_PBF_COUNT: u32 = 1000;

/// The density error (ρ/ρ0 − 1) above which a constraint solve that makes no
/// headway over its iterations has failed, and the run stops
/// ([`Error::Unstable`], see [`SolveDensity`]).
pub const MAX_DENSITY_ERROR: f32 = 1.0;

impl PbfParams {
    /// Checks every parameter is finite and in range; the error names it
    /// (`pbf.iterations`, ...).
    pub fn validate(&self) -> Result<()> {
        let check = |name: &'static str, value: f64, ok: bool, reason: &'static str| {
            if ok {
                Ok(())
            } else {
                Err(Error::InvalidParameter {
                    name,
                    value: value.to_string(),
                    reason,
                })
            }
        };
        let count = |name, n: u32| {
            check(
                name,
                f64::from(n),
                (1..=MAX_PBF_COUNT).contains(&n),
                "must be a whole number from 1 to 1000",
            )
        };
        count("pbf.substeps", self.substeps)?;
        count("pbf.iterations", self.iterations)?;
        let dt = self.max_dt;
        check(
            "pbf.max_dt",
            dt.into(),
            (1e-6..=1.0).contains(&dt),
            "must lie in [1e-6, 1] s",
        )?;
        let r = self.relaxation;
        check(
            "pbf.relaxation",
            r.into(),
            r.is_finite() && r > 0.0 && r <= 1e6,
            "must be > 0 and at most 1e6 (in units of 1/h²)",
        )?;
        let k = self.scorr_k;
        check(
            "pbf.scorr_k",
            k.into(),
            (0.0..=1.0).contains(&k),
            "must lie in [0, 1] (a density error)",
        )?;
        check(
            "pbf.scorr_n",
            self.scorr_n.into(),
            (1..=16).contains(&self.scorr_n),
            "must be a whole number from 1 to 16",
        )?;
        let dq = self.scorr_dq;
        check(
            "pbf.scorr_dq",
            dq.into(),
            dq > 0.0 && dq < 1.0,
            "must lie in (0, 1) (a fraction of h)",
        )?;
        let v = self.vorticity;
        check(
            "pbf.vorticity",
            v.into(),
            v.is_finite() && (0.0..=100.0).contains(&v),
            "must lie in [0, 100] m/s",
        )?;
        check(
            "pbf.xsph",
            self.xsph.into(),
            (0.0..=1.0).contains(&self.xsph),
            "must lie in [0, 1]",
        )?;
        let g = self.max_displacement;
        check(
            "pbf.max_displacement",
            g.into(),
            g > 0.0 && g <= 1.0,
            "must lie in (0, 1] (a fraction of h per substep)",
        )?;
        let t = self.viscosity_tolerance;
        check(
            "pbf.viscosity_tolerance",
            t.into(),
            t > 0.0 && t <= 0.5,
            "must lie in (0, 0.5] (a relative residual)",
        )?;
        count(
            "pbf.viscosity_max_iterations",
            self.viscosity_max_iterations,
        )?;
        Ok(())
    }
}

/// The PBF program: forces → predict → grid → neighbours → density →
/// viscosity (vorticity and XSPH) → implicit viscosity (with
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
    fn process(&mut self, particles: &mut Particles, ctx: &mut Context) -> Result<()> {
        let dt = ctx.dt;
        let max_speed = self.max_displacement / dt;
        let b = &self.boundary;
        let f = particles.fields_mut();
        let clamped = (f.positions.par_iter_mut())
            .zip(f.velocities.par_iter_mut())
            .zip(f.accelerations.par_iter())
            .map(|((x, v), &a)| {
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
                u64::from(clamp)
            })
            .sum::<u64>();
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
    /// 1 / W_poly6(Δq·h).
    inv_w_dq: f32,
    /// 1 / ρ0.
    inv_rho0: f32,
    /// The kernels lane by lane.
    lanes: LaneKernels,
    /// W_poly6(0).
    w0: f32,
    /// An offset beyond the kernels' support, for unused lanes.
    far: f32,
}

impl Model {
    fn new(params: FluidParams, pbf: PbfParams, boundary: Boundary) -> Result<Self> {
        params.validate()?;
        pbf.validate()?;
        boundary.validate()?;
        let h = params.h;
        let (poly6, spiky) = (Poly6::new(h)?, Spiky::new(h)?);
        let dq = pbf.scorr_dq * h;
        Ok(Self {
            params,
            pbf,
            walls: Walls::new(boundary, WallKernel::new(h), params.rest_density),
            epsilon: pbf.relaxation / (h * h),
            inv_w_dq: 1.0 / poly6.value_r2(dq * dq),
            inv_rho0: 1.0 / params.rest_density,
            lanes: LaneKernels::new(&poly6, &spiky, h),
            w0: poly6.value_r2(0.0),
            far: 2.0 * h,
        })
    }

    /// Density ρ_i and the constraint's λ_i and D_i = 1/(Σ_k|∇_k C_i|² + ε)
    /// (lines 9–11); writes each neighbour's (m_j/ρ0)∇W_ij and s_corr
    /// weight into `pairs` (one per neighbour in `list`) for the
    /// correction, which sees the same positions.
    #[inline]
    fn constraint(
        &self,
        i: usize,
        x: &[Vec3],
        m: &[f32],
        list: &[u32],
        pairs: &mut [Pair],
    ) -> Constraint {
        let xi = x[i];
        let (rho_wall, wall) = self.walls.at(xi);
        // Per lane: ρ, ∇_i C_i by axis, Σ|∇_j C_i|².
        let mut acc = [[0.0f32; LANES]; 5];
        let (k, n) = (self.pbf.scorr_k, self.pbf.scorr_n);
        for (js, out) in list.chunks(LANES).zip(pairs.chunks_mut(LANES)) {
            let c = Chunk::gather(xi, x, m, js, self.far);
            let (w, s) = self.lanes.eval(&c.r2());
            let mut g = [[0.0f32; LANES]; 3];
            for l in 0..LANES {
                let f = s[l] * c.m[l] * self.inv_rho0;
                for a in 0..3 {
                    g[a][l] = c.d[a][l] * f;
                    acc[1 + a][l] += g[a][l];
                }
                acc[0][l] += c.m[l] * w[l];
                acc[4][l] += g[0][l] * g[0][l] + g[1][l] * g[1][l] + g[2][l] * g[2][l];
            }
            for (l, pair) in out.iter_mut().enumerate() {
                let q = w[l] * self.inv_w_dq;
                *pair = Pair {
                    g: Vec3::new(g[0][l], g[1][l], g[2][l]),
                    scorr: if k > 0.0 {
                        k * (1..n).fold(q, |p, _| p * q)
                    } else {
                        0.0
                    },
                };
            }
        }
        let rho = rho_wall + m[i] * self.w0 + total(&acc[0]);
        let grad_i = wall + Vec3::new(total(&acc[1]), total(&acc[2]), total(&acc[3]));
        let error = rho * self.inv_rho0 - 1.0;
        let d = 1.0 / (grad_i.length_squared() + total(&acc[4]) + self.epsilon);
        Constraint {
            rho,
            lambda: -error.max(0.0) * d,
            d,
            wall,
        }
    }
}

impl Model {
    /// The viscosity station's sums for particle i at the current positions:
    /// density (with the walls), curl ω_i = Σ_j (m_j/ρ0)(v_j − v_i) × ∇W_ij
    /// and XSPH mean Σ_j (m_j/ρ0)(v_j − v_i) W_ij; writes each neighbour's
    /// (m_j/ρ0)∇W_ij into `grads`.
    #[inline]
    fn curl_and_mean(
        &self,
        i: usize,
        x: &[Vec3],
        v: &[Vec3],
        m: &[f32],
        list: &[u32],
        grads: &mut [Vec3],
    ) -> Sums {
        let (xi, vi) = (x[i], v[i]);
        // Per lane: ρ, curl by axis, mean by axis.
        let mut acc = [[0.0f32; LANES]; 7];
        for (js, out) in list.chunks(LANES).zip(grads.chunks_mut(LANES)) {
            let c = Chunk::gather(xi, x, m, js, self.far);
            let (w, s) = self.lanes.eval(&c.r2());
            let mut u = [[0.0f32; LANES]; 3];
            for (l, &j) in js.iter().enumerate() {
                let vij = v[j as usize] - vi;
                (u[0][l], u[1][l], u[2][l]) = (vij.x, vij.y, vij.z);
            }
            let mut g = [[0.0f32; LANES]; 3];
            for l in 0..LANES {
                let vol = c.m[l] * self.inv_rho0;
                let f = s[l] * vol;
                for (g, d) in g.iter_mut().zip(&c.d) {
                    g[l] = d[l] * f;
                }
                acc[0][l] += c.m[l] * w[l];
                // v_ij × (m_j/ρ0)∇W_ij
                acc[1][l] += u[1][l] * g[2][l] - u[2][l] * g[1][l];
                acc[2][l] += u[2][l] * g[0][l] - u[0][l] * g[2][l];
                acc[3][l] += u[0][l] * g[1][l] - u[1][l] * g[0][l];
                for a in 0..3 {
                    acc[4 + a][l] += u[a][l] * (vol * w[l]);
                }
            }
            for (l, o) in out.iter_mut().enumerate() {
                *o = Vec3::new(g[0][l], g[1][l], g[2][l]);
            }
        }
        let curl = Vec3::new(total(&acc[1]), total(&acc[2]), total(&acc[3]));
        Sums {
            rho: self.walls.at(xi).0 + m[i] * self.w0 + total(&acc[0]),
            curl,
            curl_len: curl.length(),
            mean: Vec3::new(total(&acc[4]), total(&acc[5]), total(&acc[6])),
        }
    }
}

/// One particle's density constraint.
#[derive(Debug, Clone, Copy, Default)]
struct Constraint {
    rho: f32,
    lambda: f32,
    d: f32,
    /// ∇_i(ρ_wall/ρ0).
    wall: Vec3,
}

/// What the correction needs of a neighbour pair: (m_j/ρ0)∇W_ij and
/// k (W_ij/W(Δq))ⁿ.
#[derive(Debug, Clone, Copy, Default)]
struct Pair {
    g: Vec3,
    scorr: f32,
}

/// Lines 8–19 (and 21): [`PbfParams::iterations`] Jacobi iterations of the
/// density constraint. Each computes every λ_i, then every position
/// correction Δp_i = (1/ρ0) Σ_j m_j (λ_i + λ_j + s_corr) ∇W_ij plus the
/// walls' λ_i ∇_i(ρ_wall/ρ0), moves each particle by it and back out of
/// walls, and adds that motion over Δt to its velocity.
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
    constraints: Vec<Constraint>,
    pairs: Vec<Pair>,
    corrections: Vec<Vec3>,
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
            constraints: Vec::new(),
            pairs: Vec::new(),
            corrections: Vec::new(),
        }
    }
}

impl Processor for SolveDensity {
    fn name(&self) -> &str {
        "density"
    }
    fn process(&mut self, particles: &mut Particles, ctx: &mut Context) -> Result<()> {
        let lists = lists(ctx, particles, "density")?;
        let model = &self.model;
        let (rho0, pbf, dt) = (model.params.rest_density, model.pbf, ctx.dt);
        let (mut first, mut worst) = (None, 0.0f32);
        let n_particles = particles.len();
        self.pairs.resize(lists.pairs(), Pair::default());
        self.constraints.resize(n_particles, Constraint::default());
        for _ in 0..pbf.iterations {
            let f = particles.fields_mut();
            let (x, m) = (&*f.positions, &*f.masses);
            lists.par_map_rows(&mut self.constraints, &mut self.pairs, |i, list, pairs| {
                model.constraint(i, x, m, list, pairs)
            });
            let (c, pairs) = (&self.constraints, &self.pairs);
            worst = c.par_iter().map(|c| c.rho).reduce(|| 0.0, f32::max) / rho0 - 1.0;
            first.get_or_insert(worst);
            (0..n_particles)
                .into_par_iter()
                .map(|i| {
                    let ci = c[i];
                    let row = lists.row(i, pairs);
                    let mut dp = ci.lambda * ci.wall;
                    for (&j, p) in lists.of(i).iter().zip(row) {
                        let cj = c[j as usize];
                        let s = ci.lambda + cj.lambda - p.scorr * 0.5 * (ci.d + cj.d);
                        dp += p.g * s;
                    }
                    dp
                })
                .collect_into_vec(&mut self.corrections);
            let b = model.walls.boundary();
            (f.positions.par_iter_mut())
                .zip(f.velocities.par_iter_mut())
                .zip(self.corrections.par_iter())
                .for_each(|((x, v), &dp)| {
                    *x += dp;
                    let free = *x;
                    b.project(x);
                    *v += (dp + (*x - free)) / dt;
                });
        }
        (particles.densities_mut().par_iter_mut())
            .zip(self.constraints.par_iter())
            .for_each(|(rho, c)| *rho = c.rho);
        ctx.counters.iterations += pbf.iterations;
        ctx.invalidate_grid(); // positions moved; the lists stay
        let bad = particles.positions().par_iter().any(|x| !x.is_finite());
        let stuck = first.is_some_and(|first| worst >= first);
        if bad || worst.is_nan() || (worst > MAX_DENSITY_ERROR && stuck) {
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
    first: Vec<Sums>,
    grads: Vec<Vec3>,
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
            first: Vec::new(),
            grads: Vec::new(),
        }
    }
}

impl Processor for VorticityXsph {
    fn name(&self) -> &str {
        "viscosity"
    }
    fn process(&mut self, particles: &mut Particles, ctx: &mut Context) -> Result<()> {
        let lists = lists(ctx, particles, "viscosity")?;
        let model = &self.model;
        let dt = ctx.dt;
        let c = match model.pbf.viscosity {
            PbfViscosity::Xsph => model.pbf.xsph,
            PbfViscosity::Implicit => 0.0,
        };
        let eps = model.pbf.vorticity;
        let f = particles.fields_mut();
        let (x, v, m) = (&*f.positions, &*f.velocities, &*f.masses);
        // Density, curl and XSPH mean at once; each pair's (m_j/ρ0)∇W_ij
        // kept for the vorticity's gradient of |ω|.
        self.grads.resize(lists.pairs(), Vec3::ZERO);
        self.first.resize(x.len(), Default::default());
        lists.par_map_rows(&mut self.first, &mut self.grads, |i, list, grads| {
            model.curl_and_mean(i, x, v, m, list, grads)
        });
        let (first, grads) = (&self.first, &self.grads);
        // Each particle's velocity change reads only the first pass's sums,
        // so it is added in place, with the density.
        (f.velocities.par_iter_mut())
            .zip(f.densities.par_iter_mut())
            .enumerate()
            .for_each(|(i, (v, rho))| {
                let Sums { curl, mean, .. } = first[i];
                let mut dv = c * mean;
                if eps > 0.0 {
                    let row = lists.row(i, grads);
                    let wi = first[i].curl_len;
                    let mut eta = Vec3::ZERO;
                    for (&j, &g) in lists.of(i).iter().zip(row) {
                        eta += g * (first[j as usize].curl_len - wi);
                    }
                    if let Some(n) = eta.try_normalize() {
                        dv += dt * eps * n.cross(curl);
                    }
                }
                *v += dv;
                *rho = first[i].rho;
            });
        Ok(())
    }
}
