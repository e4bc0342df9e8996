//! What every solver shares: the fluid's physical parameters and the rules of
//! the adaptive time step.

use glam::Vec3;

use crate::error::{Error, Result, non_negative, positive};

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
    /// Which force applies σ; `None`, the default: each solver's own
    /// (WCSPH the thesis's colour field, PBF and DFSPH Akinci et al.'s).
    pub surface_tension_model: Option<SurfaceTensionModel>,
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

/// The force that applies the surface tension σ
/// ([`FluidParams::surface_tension_model`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum SurfaceTensionModel {
    /// The thesis's colour-field force (eq. 18–20; Müller et al. 2003):
    /// WCSPH's own, and only WCSPH's.
    ColourField,
    /// Akinci et al. 2013's cohesion and curvature forces
    /// ([`super::surface_tension`]): PBF's and DFSPH's own, and WCSPH's
    /// where a scene asks for it.
    Akinci,
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
            surface_tension_model: None,
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
    /// (DFSPH sums densities with the cubic spline:
    /// [`crate::Solver::particle_mass`] picks the solver's kernel.)
    pub fn particle_mass(&self, spacing: f32) -> Result<f32> {
        self.lattice_mass(&crate::kernels::Poly6::new(self.h)?, spacing)
    }

    /// The particle mass for fluid sampled on a cubic lattice of `spacing`
    /// that sums to exactly ρ0 inside the lattice with `kernel`.
    ///
    /// # Errors
    /// A spacing that is not positive, not below h, or below h/10.
    pub fn lattice_mass(&self, kernel: &impl crate::kernels::Kernel, spacing: f32) -> Result<f32> {
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
        let n = (self.h / spacing).ceil() as i32;
        let sum = crate::kernels::lattice_sum(kernel, spacing, -n..=n);
        Ok((self.rest_density as f64 / sum) as f32)
    }
}

impl FluidParams {
    /// Every one of `masses` is heavy enough for h: its volume m/ρ0 has a
    /// side V^⅓ of at least h/[`MAX_H_OVER_SPACING`] (to a per cent, so
    /// that the lattice mass of that spacing, which a scene's blocks may
    /// have, passes). A lighter particle stands for a lattice with
    /// thousands of neighbours per particle, and what the solvers size by
    /// it would take (h/V^⅓)³ terms (DFSPH's Jacobi relaxation) or h/V^⅓
    /// (the walls' layers under a clearance): at 10⁻²⁰ kg and h = 4 cm a
    /// step never ended.
    ///
    /// # Errors
    /// [`Error::InvalidParticle`] naming the first such particle.
    pub fn check_masses(&self, masses: &[f32]) -> Result<()> {
        let lightest = 0.97 * self.rest_density * (self.h / MAX_H_OVER_SPACING).powi(3);
        match masses.iter().position(|&m| m < lightest) {
            Some(index) => Err(Error::InvalidParticle {
                index,
                what: "mass",
                value: format!("{:e} kg", masses[index]),
                reason: "is too light for h: its volume m/ρ0 has a side under h/10 (each particle \
                         would stand for thousands of neighbours); use the lattice mass of its \
                         spacing (`FluidParams::particle_mass`) or a larger h",
            }),
            None => Ok(()),
        }
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
pub(crate) fn check_viscous_dt(params: &FluidParams, stepping: &TimeStepping) -> Result<()> {
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
