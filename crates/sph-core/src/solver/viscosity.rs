//! Implicit viscosity (Weiler, Koschier, Brand & Bender 2018, "A Physically
//! Consistent Implicit Viscosity Solver for SPH Fluids", Computer Graphics
//! Forum 37(2)): the viscous step solved for the step's end velocities, so
//! that no viscosity, from water's 1e-3 Pa·s to 1,000 Pa·s and beyond,
//! limits the step.
//!
//! The viscous acceleration is (μ/ρ_i) ∇²v_i with the dynamic viscosity μ
//! in **Pa·s** ([`super::FluidParams::viscosity`]; not the kinematic
//! ν = μ/ρ0 in m²/s), and the laplacian Weiler et al.'s
//!
//! ∇²v_i ≈ 2(d + 2) Σ_j (m_j/ρ_j) (v_ij · x_ij) / (|x_ij|² + 0.01 h²) ∇W_ij,
//!
//! d = 3, which unlike the thesis's term (eq. 17) conserves angular
//! momentum. The factor 2(d + 2) is the continuum's: at h = 2 spacings the
//! sum gives 0.70 of ∇²v on a lattice, so the station uses the factor that
//! is exact there ([`laplacian_factor`]: 14.3 instead of 10). Implicit in the new velocities v,
//!
//! v_i − Δt (μ/ρ_i) ∇²v_i = v*_i = v_i⁰ + Δt a_i
//!
//! (a_i the accelerations before this station: gravity and a user's),
//! a 3n × 3n symmetric positive definite system for particles of equal mass,
//! solved matrix-free by conjugate gradients with a block-Jacobi
//! preconditioner (each particle's 3 × 3 diagonal block inverted), warm
//! started with the last step's viscous velocity change of each particle
//! (the particle attribute [`VISCOUS_CHANGE`]). Where the station writes
//! its result is its [`Update`]: DFSPH's leaves the viscous acceleration
//! (v − v*)/Δt in the accelerations, so that the pressure solves after it
//! see the viscous fluid's forces as any other; PBF's solves from the
//! velocities its density solve left (v* = v) and writes the new
//! velocities, where XSPH would act.
//!
//! **Walls** are no-slip: each wall within h adds the integral of the same
//! pair term over the fluid-filled half-space behind it at rest velocity,
//! −(a(d) n nᵀ + b(d)(I − n nᵀ)) v_i, its normal and tangential parts
//! tabulated at 64 distances once per h ([`WallFriction`]). Weiler et al.
//! sample walls with particles; this is that sampling's continuous limit.

use std::ops::Range;
use std::sync::OnceLock;

use glam::{Mat3, Vec3};

use super::params::FluidParams;
use super::stations::lists;
use crate::boundary::Boundary;
use crate::error::{Error, Result};
use crate::grid::NeighbourLists;
use crate::kernels::CubicSpline;
use crate::particles::Particles;
use crate::processor::{Context, Processor};
use crate::region::{self, Blocks};

/// The particle attribute (Vec3) holding each particle's last viscous
/// velocity change (m/s), the solve's warm start.
pub const VISCOUS_CHANGE: &str = "viscous_change";

/// The laplacian's factor for particles `spacing` apart: 2(d + 2) = 10 in
/// the continuum, but the sum over a lattice at h = 2 spacings gives only
/// 0.70 of ∇²v for v = (y², 0, 0) (0.94 at 3 spacings), so a fluid's
/// viscosity would act as 0.7 μ. The factor is 2 / Σ_j V_j ((v_i −
/// v_j)·x_ij) / (|x_ij|² + 0.01 h²) ∂W_ij/∂x over that lattice, the value
/// that makes the operator exact there, as the particle mass makes the
/// lattice's density exact.
pub fn laplacian_factor(kernel: &CubicSpline, spacing: f32) -> f32 {
    use crate::kernels::Kernel;
    let (h, s) = (f64::from(kernel.h()), f64::from(spacing));
    let eps = 0.01 * h * h;
    let n = (h / s).ceil() as i32;
    let mut sum = 0.0f64;
    for k in -n..=n {
        for j in -n..=n {
            for i in -n..=n {
                // x_ij = x_i − x_j with x_i = 0; v_i − v_j = (−y_j², 0, 0).
                let x = glam::DVec3::new(i.into(), j.into(), k.into()) * -s;
                let r = x.length();
                if r <= 0.0 || r >= h {
                    continue;
                }
                let dw = f64::from(kernel.derivative_len(r as f32));
                let v = -(x.y * x.y);
                sum += s.powi(3) * (v * x.x) / (r * r + eps) * dw * x.x / r;
            }
        }
    }
    if sum > 0.0 { (2.0 / sum) as f32 } else { 10.0 }
}

/// Distances (fractions of h) at which [`WallFriction`] tabulates.
const TABLE: usize = 64;

/// The no-slip walls' share of the viscous operator: for a wall at
/// distance d with normal n, the integral ∫ f(r) r rᵀ dV over the half-space
/// behind it, f(r) = −W'(r) / (r (r² + 0.01 h²)) ≥ 0, is
/// a(d) n nᵀ + b(d)(I − n nᵀ).
#[derive(Debug, Clone)]
pub struct WallFriction {
    h: f32,
    /// (a, b) at d = k h / (TABLE − 1).
    table: Vec<(f32, f32)>,
}

impl WallFriction {
    /// The table for the cubic spline `kernel`, by a midpoint rule in
    /// cylindrical coordinates about the wall's normal (200 × 200 cells).
    pub fn new(kernel: &CubicSpline) -> Self {
        use crate::kernels::Kernel;
        let h = f64::from(kernel.h());
        let eps = 0.01 * h * h;
        let n = 200;
        let table = (0..TABLE)
            .map(|k| {
                let d = h * k as f64 / (TABLE - 1) as f64;
                let (mut a, mut b) = (0.0f64, 0.0f64);
                let dz = (h - d) / n as f64;
                for iz in 0..n {
                    let z = d + (iz as f64 + 0.5) * dz;
                    let rho_max = (h * h - z * z).max(0.0).sqrt();
                    let dr = rho_max / n as f64;
                    for ir in 0..n {
                        let rho = (ir as f64 + 0.5) * dr;
                        let r = (rho * rho + z * z).sqrt();
                        let w = -f64::from(kernel.derivative_len(r as f32)) / (r * (r * r + eps));
                        // ∫ over the ring: 2πρ dρ dz; r rᵀ's normal part z²,
                        // its tangential part averaged over the ring ρ²/2.
                        let ring = 2.0 * std::f64::consts::PI * rho * dr * dz * w;
                        a += ring * z * z;
                        b += ring * 0.5 * rho * rho;
                    }
                }
                (a as f32, b as f32)
            })
            .collect();
        Self {
            h: kernel.h(),
            table,
        }
    }

    /// (a, b) at distance `d` from a wall, interpolated; 0 beyond h.
    pub fn at(&self, d: f32) -> (f32, f32) {
        let u = (d / self.h).clamp(0.0, 1.0) * (TABLE - 1) as f32;
        let k = (u as usize).min(TABLE - 2);
        let t = u - k as f32;
        let (a0, b0) = self.table[k];
        let (a1, b1) = self.table[k + 1];
        (a0 + t * (a1 - a0), b0 + t * (b1 - b0))
    }

    /// The walls' tensor at `x`: Σ over the walls within h of
    /// −(a n nᵀ + b (I − n nᵀ)).
    fn tensor(&self, boundary: &Boundary, x: Vec3) -> Mat3 {
        let mut t = Mat3::ZERO;
        boundary.for_each_wall_within(x, self.h, |d, n| {
            let (a, b) = self.at(d);
            let nn = Mat3::from_cols(n * n.x, n * n.y, n * n.z);
            t -= nn * a + (Mat3::IDENTITY - nn) * b;
        });
        t
    }
}

/// Where [`ImplicitViscosity`] starts from and what it writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Update {
    /// v* = v + Δt a, and the viscous acceleration (v − v*)/Δt is added to
    /// the accelerations: for a solver that integrates forces after this
    /// station (DFSPH).
    Accelerations,
    /// v* = v, and the solution replaces the velocities: for a solver
    /// whose velocities are final before this station (PBF, after its
    /// velocity update; the accelerations are left alone).
    Velocities,
}

/// The implicit viscosity station ("viscosity"), with its working memory.
#[derive(Debug)]
pub struct ImplicitViscosity {
    update: Update,
    mu: f32,
    h: f32,
    rest_density: f32,
    /// The lattice spacing of the lightest particle and its
    /// [`laplacian_factor`].
    factor: Option<(f32, f32)>,
    kernel: CubicSpline,
    boundary: Boundary,
    walls: WallFriction,
    /// The CG's stop: ‖r‖ ≤ tolerance ‖v*‖.
    tolerance: f32,
    max_iterations: u32,
    /// Per pair, V_j ∇W_ij / (|x_ij|² + 0.01 h²).
    pairs: Vec<Vec3>,
    /// Per particle: Δt (μ/ρ_i) 2(d+2), the walls' tensor, and the inverse
    /// of the diagonal block.
    rows: Vec<(f32, Mat3, Mat3)>,
    b: Vec<Vec3>,
    x: Vec<Vec3>,
    r: Vec<Vec3>,
    z: Vec<Vec3>,
    p: Vec<Vec3>,
    ap: Vec<Vec3>,
    /// A CG iteration's p·Ap, r·z and r·r per block.
    sums: [Vec<f64>; 3],
}

impl ImplicitViscosity {
    /// The station for the fluid `params` (its μ in Pa·s, h and ρ0) with
    /// no-slip `boundary`, solving to the relative residual `tolerance` in
    /// at most `max_iterations` CG iterations, from and into what `update`
    /// says.
    ///
    /// # Errors
    /// Parameters that do not validate, a tolerance outside (0, 0.5] or no
    /// iterations.
    pub fn new(
        params: &FluidParams,
        boundary: Boundary,
        tolerance: f32,
        max_iterations: u32,
        update: Update,
    ) -> Result<Self> {
        params.validate()?;
        boundary.validate()?;
        if !(tolerance > 0.0 && tolerance <= 0.5) {
            return Err(Error::InvalidParameter {
                name: "viscosity_tolerance",
                value: tolerance.to_string(),
                reason: "must lie in (0, 0.5] (a relative residual)",
            });
        }
        if max_iterations == 0 {
            return Err(Error::InvalidParameter {
                name: "viscosity_max_iterations",
                value: "0".into(),
                reason: "must be at least 1",
            });
        }
        let kernel = CubicSpline::new(params.h)?;
        Ok(Self {
            update,
            mu: params.viscosity,
            h: params.h,
            rest_density: params.rest_density,
            factor: None,
            kernel,
            boundary,
            walls: WallFriction::new(&kernel),
            tolerance,
            max_iterations,
            pairs: Vec::new(),
            rows: Vec::new(),
            b: Vec::new(),
            x: Vec::new(),
            r: Vec::new(),
            z: Vec::new(),
            p: Vec::new(),
            ap: Vec::new(),
            sums: Default::default(),
        })
    }
}

/// (A y)_i = y_i − c_i [Σ_j ((y_i − y_j)·x_ij) P_ij + T_i y_i].
#[inline]
fn apply(
    i: usize,
    y: &[Vec3],
    x: &[Vec3],
    lists: &NeighbourLists,
    pairs: &[Vec3],
    rows: &[(f32, Mat3, Mat3)],
) -> Vec3 {
    let (c, t, _) = rows[i];
    let (yi, xi) = (y[i], x[i]);
    let mut sum = t * yi;
    for (&j, g) in lists.of(i).iter().zip(lists.row(i, pairs)) {
        let j = j as usize;
        sum += (yi - y[j]).dot(xi - x[j]) * *g;
    }
    yi - c * sum
}

/// Σ_i a_i · b_i in f64, per region block ([`region::map_blocks`]) and
/// then over the blocks in order: as the CG iterations' sums add.
fn dot(a: &[Vec3], b: &[Vec3]) -> f64 {
    debug_assert_eq!(a.len(), b.len());
    let sums = region::map_blocks(a.len(), |r| {
        (a[r.clone()].iter().zip(&b[r]))
            .map(|(a, b)| f64::from(a.dot(*b)))
            .sum::<f64>()
    });
    sums.iter().sum()
}

impl Processor for ImplicitViscosity {
    /// "viscosity", or "implicit_viscosity" on [`Update::Velocities`] (PBF,
    /// whose "viscosity" station is the vorticity and XSPH before it).
    fn name(&self) -> &str {
        match self.update {
            Update::Accelerations => "viscosity",
            Update::Velocities => "implicit_viscosity",
        }
    }

    fn runs_in_region(&self) -> bool {
        true
    }

    fn process(&mut self, particles: &mut Particles, ctx: &mut Context) -> Result<()> {
        if self.mu == 0.0 || particles.is_empty() {
            return Ok(());
        }
        let lists = lists(ctx, particles, "viscosity")?;
        let dt = ctx.dt;
        let n = particles.len();
        if !particles.has_attribute(VISCOUS_CHANGE) {
            particles.add_attribute(VISCOUS_CHANGE, Vec3::ZERO)?;
        }
        self.x.clear();
        (self.x).extend_from_slice(particles.attribute::<Vec3>(VISCOUS_CHANGE)?);
        let (mu, eps) = (self.mu, 0.01 * self.h * self.h);
        let lightest = super::lanes::lightest(particles.masses());
        let spacing = (lightest / self.rest_density).cbrt();
        let factor = match self.factor {
            Some((s, factor)) if s == spacing => factor,
            _ => {
                let factor = laplacian_factor(&self.kernel, spacing);
                self.factor = Some((spacing, factor));
                factor
            }
        };
        let (kernel, walls, boundary) = (&self.kernel, &self.walls, &self.boundary);
        let f = particles.fields_mut();
        let (pos, m, rho) = (&*f.positions, &*f.masses, &*f.densities);
        if rho.iter().any(|&r| r.is_nan() || r <= 0.0) {
            return Err(Error::Pipeline {
                processor: "viscosity",
                reason: "needs the step's densities: put it after the station that computes them (DFSPH's `factors`, PBF's `viscosity`)",
            });
        }
        // Per pair V_j ∇W_ij / (r² + ε); per particle the factor, the
        // walls' tensor and the inverse diagonal block.
        self.pairs.resize(lists.pairs(), Vec3::ZERO);
        self.rows.resize(n, (0.0, Mat3::ZERO, Mat3::ZERO));
        lists.region_map_rows(&mut self.rows, &mut self.pairs, |i, list, out| {
            let xi = pos[i];
            let c = dt * mu / rho[i] * factor;
            let t = walls.tensor(boundary, xi);
            let mut block = t;
            for (&j, o) in list.iter().zip(out.iter_mut()) {
                let j = j as usize;
                let r = xi - pos[j];
                let len2 = r.length_squared();
                let len = len2.sqrt();
                let g = if len > 0.0 {
                    r * (m[j] / rho[j] * kernel.derivative_len(len) / (len * (len2 + eps)))
                } else {
                    Vec3::ZERO
                };
                *o = g;
                block += Mat3::from_cols(g * r.x, g * r.y, g * r.z);
            }
            let diagonal = Mat3::IDENTITY - block * c;
            (c, t, diagonal.inverse())
        });
        // b = v* (v + Δt a, or v); the warm start x = b + the last change.
        match self.update {
            Update::Accelerations => {
                let (v, a) = (&*f.velocities, &*f.accelerations);
                self.b.resize(n, Vec3::ZERO);
                region::for_each(&mut self.b, |i, b| *b = v[i] + dt * a[i]);
            }
            Update::Velocities => {
                self.b.clear();
                self.b.extend_from_slice(f.velocities);
            }
        }
        let b = &self.b;
        region::for_each(&mut self.x, |i, x| *x += b[i]);
        let (pairs, rows, x) = (&self.pairs, &self.rows, &self.x);
        // r = b − A x, z = M⁻¹ r, p = z.
        self.r.resize(n, Vec3::ZERO);
        region::for_each(&mut self.r, |i, r| {
            *r = b[i] - apply(i, x, pos, lists, pairs, rows);
        });
        let r = &self.r;
        self.z.resize(n, Vec3::ZERO);
        region::for_each(&mut self.z, |i, z| *z = rows[i].2 * r[i]);
        self.p.clone_from(&self.z);
        let norm_b = dot(&self.b, &self.b).sqrt();
        let stop = f64::from(self.tolerance) * norm_b.max(f64::MIN_POSITIVE);
        let mut rz = dot(&self.r, &self.z);
        let mut iterations = 0;
        let mut residual = dot(&self.r, &self.r).sqrt();
        let per_pass = region::blocks(n);
        self.ap.resize(n, Vec3::ZERO);
        for sums in &mut self.sums {
            sums.resize(per_pass, 0.0);
        }
        while residual > stop && iterations < self.max_iterations {
            let (x, r, z) = (&mut self.x, &mut self.r, &mut self.z);
            let (x, r, z) = (Blocks::new(x), Blocks::new(r), Blocks::new(z));
            let (p, ap) = (Blocks::new(&mut self.p), Blocks::new(&mut self.ap));
            let [pap, rz_new, rr] = &mut self.sums;
            let (pap, rz_new, rr_new) = (Blocks::new(pap), Blocks::new(rz_new), Blocks::new(rr));
            let total = |sums: &[f64]| sums.iter().sum::<f64>();
            // Σ p·Ap and Σ r·z, each summed once, by the first block that
            // needs it, in block order.
            let (pap_total, rz_total) = (OnceLock::new(), OnceLock::new());
            let pap_sum = || *pap_total.get_or_init(|| total(unsafe { pap.all() }));
            // p·Ap ≤ 0 (or NaN): p is 0, converged to round-off; the
            // passes after it leave everything as it is.
            let stalled = |pap: f64| pap.is_nan() || pap <= 0.0;
            // SAFETY (every pass below): each writes only its own block of
            // the slices it owns, and reads whole only slices no pass writes
            // meanwhile.
            // Ap, and p·Ap per block.
            let multiply = |range: Range<usize>, block: usize| {
                let p = unsafe { p.all() };
                let out = unsafe { ap.block(range.clone()) };
                let mut sum = 0.0f64;
                for (ap, i) in out.iter_mut().zip(range) {
                    *ap = apply(i, p, pos, lists, pairs, rows);
                    sum += f64::from(p[i].dot(*ap));
                }
                unsafe { pap.block(block..block + 1)[0] = sum };
            };
            // x += αp, r −= αAp, z = M⁻¹r, and r·z and r·r per block.
            let descend = |range: Range<usize>, block: usize| {
                let pap = pap_sum();
                if stalled(pap) {
                    return;
                }
                let alpha = (rz / pap) as f32;
                let (p, ap) = unsafe { (p.all(), ap.all()) };
                let (x, r) = unsafe { (x.block(range.clone()), r.block(range.clone())) };
                let z = unsafe { z.block(range.clone()) };
                let (mut rz, mut rr) = (0.0f64, 0.0f64);
                for (k, i) in range.enumerate() {
                    x[k] += alpha * p[i];
                    r[k] -= alpha * ap[i];
                    z[k] = rows[i].2 * r[k];
                    rz += f64::from(r[k].dot(z[k]));
                    rr += f64::from(r[k].dot(r[k]));
                }
                unsafe {
                    rz_new.block(block..block + 1)[0] = rz;
                    rr_new.block(block..block + 1)[0] = rr;
                }
            };
            // p = z + βp.
            let turn = |range: Range<usize>, _| {
                if stalled(pap_sum()) {
                    return;
                }
                let rz_new = *rz_total.get_or_init(|| total(unsafe { rz_new.all() }));
                let beta = (rz_new / rz) as f32;
                let z = unsafe { z.all() };
                let p = unsafe { p.block(range.clone()) };
                for (p, i) in p.iter_mut().zip(range) {
                    *p = z[i] + beta * *p;
                }
            };
            region::run(n, &[&multiply, &descend, &turn]);
            if stalled(total(&self.sums[0])) {
                break;
            }
            rz = total(&self.sums[1]);
            iterations += 1;
            residual = total(&self.sums[2]).sqrt();
        }
        if !residual.is_finite() {
            return Err(Error::Unstable {
                step: ctx.step,
                time: ctx.time,
                what: "the implicit viscosity solve produced a non-finite velocity".into(),
                hint: "check for particles on top of each other, or lower the step".into(),
            });
        }
        ctx.counters.viscosity_iterations += iterations;
        if residual > stop {
            ctx.counters.unconverged += 1;
        }
        // The viscous acceleration (x − b)/Δt joins the others, or x
        // replaces the velocities; the change x − b is the next step's warm
        // start.
        match self.update {
            Update::Accelerations => {
                let inv_dt = 1.0 / dt;
                let b = &self.b;
                region::for_each(&mut self.x, |i, x| *x -= b[i]);
                let x = &self.x;
                region::for_each(f.accelerations, |i, a| *a += x[i] * inv_dt);
            }
            Update::Velocities => {
                let x = &self.x;
                region::for_each(f.velocities, |i, v| *v = x[i]);
                let b = &self.b;
                region::for_each(&mut self.x, |i, x| *x -= b[i]);
            }
        }
        particles
            .attribute_mut::<Vec3>(VISCOUS_CHANGE)?
            .copy_from_slice(&self.x);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The lattice factor against an independent sum (Python, over the same
    /// lattice): the plain 2(d + 2) = 10 gives 1.3962 of ∇²v = 2 at
    /// h = 2 spacings and 1.8763 at 3, so the factors are 14.32 and 10.66.
    #[test]
    fn laplacian_factor_makes_the_lattice_exact() {
        let kernel = CubicSpline::new(0.04).unwrap();
        for (ratio, expected) in [(2.0f32, 10.0 * 2.0 / 1.3962f32), (3.0, 10.0 * 2.0 / 1.8763)] {
            let got = laplacian_factor(&kernel, 0.04 / ratio);
            assert!(
                (got / expected - 1.0).abs() < 1e-3,
                "h/s {ratio}: {got} vs {expected}"
            );
        }
    }

    /// The walls' table: a whole space's integral of f r rᵀ is isotropic,
    /// so a particle on the wall (d = 0) sees half of it, equally in the
    /// normal and the tangential directions (a = b); both fade to 0 at h,
    /// monotonically.
    #[test]
    fn wall_friction_is_isotropic_on_the_wall_and_fades() {
        let kernel = CubicSpline::new(0.04).unwrap();
        let walls = WallFriction::new(&kernel);
        let (a0, b0) = walls.at(0.0);
        assert!(a0 > 0.0 && (a0 / b0 - 1.0).abs() < 0.01, "a {a0}, b {b0}");
        assert_eq!(walls.at(0.04), (0.0, 0.0));
        let mut last = (a0, b0);
        for k in 1..=20 {
            let now = walls.at(0.04 * k as f32 / 20.0);
            assert!(
                now.0 <= last.0 && now.1 <= last.1,
                "{k}: {now:?} after {last:?}"
            );
            last = now;
        }
    }
}
