//! [`DfsphParams`]: what a scene's `[solver.dfsph]` table gives divergence-free
//! SPH, with their defaults, their checks and the adaptive step they set.
//! The solver's algorithm is its parent module, [`super`].

use crate::error::{Error, Result};

/// The parameters of DFSPH. Scene files give them under `[solver.dfsph]`; a
/// field left out takes its default.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DfsphParams {
    /// The Courant number λ of the step: Δt = λ h / v_max, with v_max the
    /// largest |v| + |a| max_dt of the particles. Default 0.1: at the
    /// built-in scenes' h = 2 × spacing a particle moves at most 0.2
    /// spacings per step, half of SPlisHSPlasH's 0.4 (λ = 0.2). On the dam
    /// break (`tests/dfsph.rs`) λ = 0.2 took 0.6 × the time but left
    /// 0.099 % average and 4.2 % single-particle compression, against
    /// 0.077 % and 2.3 %.
    pub cfl: f32,
    /// The longest step (s). Default 0.005 (SPlisHSPlasH's).
    pub max_dt: f32,
    /// The density solve's tolerance: the mean compression
    /// max(ρ/ρ0 − 1, 0) over the particles it leaves. Default 0.0005
    /// (0.05 %). The solve stops on the mean, so single particles can stay
    /// above it: on the dam break's first second the largest was 1.06 %
    /// (1,200 particles) and 1.94 % (10,000) at the default, 0.66 % and
    /// 0.64 % at 0.0001, for about 1.8 times the wall time
    /// (`tests/dfsph.rs`, `dam_break_compression_at_a_tight_tolerance`).
    pub density_tolerance: f32,
    /// The divergence solve's tolerance: the mean density change
    /// max(Δt Dρ/Dt, 0)/ρ0 over one step it leaves. Default 0.001 (0.1 %).
    pub divergence_tolerance: f32,
    /// The most iterations of either solve per step; a solve that reaches
    /// it above its tolerance is counted as unconverged. Default 100.
    pub max_iterations: u32,
    /// The implicit viscosity's tolerance: the conjugate gradients stop
    /// when the residual is this fraction of the right-hand side's norm.
    /// Default 0.001.
    pub viscosity_tolerance: f32,
    /// The implicit viscosity's most conjugate-gradient iterations per
    /// step (counted as unconverged when reached). Default 100.
    pub viscosity_max_iterations: u32,
    /// Holds particles at a free surface to the density a lattice's top
    /// layer reads instead of ρ0, as PBF's
    /// ([`PbfParams::surface_target`](crate::solver::pbf::PbfParams::surface_target)):
    /// the density solve's source is that target's. Default false, under
    /// which a pool's top layer packs and its surface sinks: a 0.2 m pool
    /// is 1.71 % low after 2 s, +0.19 % with the target (0.5 m: −0.99 %,
    /// −0.23 %; `docs/benchmark-notes.md`, "The free surface's packed top
    /// layer"). Not the default because a drop under surface tension then
    /// holds less of Laplace's pressure (0.456 of 2σ/R against 0.805): the
    /// target loosens its surface shell, which carries the pull.
    pub surface_target: bool,
    /// Particle sleeping (m/s), as PBF's ([`PbfParams::sleep_speed`](crate::solver::pbf::PbfParams::sleep_speed)):
    /// a particle slower than this at the end of a step does not move, and
    /// its velocity is zero. Default 0: off.
    ///
    /// DFSPH's water at rest settles towards about 3 mm/s of particle-scale
    /// motion, whatever the tolerances (`docs/benchmark-notes.md`, "DFSPH's
    /// solves know the clearance"); 0.01 m/s stills the 0.2 m pool of
    /// `pool_at_rest` from 1.5 s (`tests/pool.rs`) and the 0.5 m pool from
    /// 2 s (`cargo run --release -p sph-core --example pool_at_rest --
    /// dfsph --depth 0.5 --solver-toml 'dfsph = { sleep_speed = 0.01 }'`).
    /// The price is PBF's: motion slower than the threshold stops where it
    /// is.
    ///
    /// Only steps in which gravity alone gives more than the threshold,
    /// |g| Δt above it, put particles to sleep: a shorter one would leave
    /// fluid at rest in the air hanging. A threshold at or above g ×
    /// `max_dt` is refused when the world is built
    /// ([`Self::check_sleep`]), and a scene refuses one at or above g times
    /// its shortest step at rest, the shorter of its frame and `max_dt`/2
    /// (a frame's last two steps share what is left).
    pub sleep_speed: f32,
}

impl Default for DfsphParams {
    fn default() -> Self {
        Self {
            cfl: 0.1,
            max_dt: 0.005,
            density_tolerance: 5e-4,
            divergence_tolerance: 1e-3,
            max_iterations: 100,
            viscosity_tolerance: 1e-3,
            viscosity_max_iterations: 100,
            surface_target: false,
            sleep_speed: 0.0,
        }
    }
}

/// The most iterations [`DfsphParams::validate`] accepts.
pub const MAX_DFSPH_ITERATIONS: u32 = 10_000;

impl DfsphParams {
    /// Checks every parameter is finite and in range; the error names it
    /// (`dfsph.cfl`, ...).
    pub fn validate(&self) -> Result<()> {
        let check = crate::error::check_param;
        check(
            "dfsph.cfl",
            self.cfl.into(),
            self.cfl > 0.0 && self.cfl <= 1.0,
            "must lie in (0, 1] (a fraction of h per step)",
        )?;
        check(
            "dfsph.max_dt",
            self.max_dt.into(),
            (1e-6..=1.0).contains(&self.max_dt),
            "must lie in [1e-6, 1] s",
        )?;
        check(
            "dfsph.density_tolerance",
            self.density_tolerance.into(),
            self.density_tolerance > 0.0 && self.density_tolerance <= 0.1,
            "must lie in (0, 0.1] (a mean compression: 0.0005 is 0.05 %)",
        )?;
        check(
            "dfsph.divergence_tolerance",
            self.divergence_tolerance.into(),
            self.divergence_tolerance > 0.0 && self.divergence_tolerance <= 0.1,
            "must lie in (0, 0.1] (a mean density change per step: 0.001 is 0.1 %)",
        )?;
        check(
            "dfsph.max_iterations",
            self.max_iterations.into(),
            (super::MIN_DENSITY_ITERATIONS..=MAX_DFSPH_ITERATIONS).contains(&self.max_iterations),
            "must be a whole number from 2 to 10000",
        )?;
        check(
            "dfsph.viscosity_tolerance",
            self.viscosity_tolerance.into(),
            self.viscosity_tolerance > 0.0 && self.viscosity_tolerance <= 0.5,
            "must lie in (0, 0.5] (a relative residual: 0.001 is 0.1 %)",
        )?;
        check(
            "dfsph.viscosity_max_iterations",
            self.viscosity_max_iterations.into(),
            (1..=MAX_DFSPH_ITERATIONS).contains(&self.viscosity_max_iterations),
            "must be a whole number from 1 to 10000",
        )?;
        check(
            "dfsph.sleep_speed",
            self.sleep_speed.into(),
            self.sleep_speed.is_finite() && self.sleep_speed >= 0.0,
            "must be finite and ≥ 0 m/s (0 turns sleeping off)",
        )?;
        Ok(())
    }

    /// Checks [`Self::sleep_speed`] against gravity of magnitude `gravity`
    /// (m/s²) and steps of at least `dt` (s): a threshold must stay below
    /// g Δt, or those steps would leave fluid at rest in the air hanging,
    /// and [`Advect`](super::Advect) would never put a particle to sleep. `dt` is
    /// `max_dt` for a world, and a scene's shortest step at rest for a
    /// scene.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming `dfsph.sleep_speed`.
    pub fn check_sleep(&self, gravity: f32, dt: f32) -> Result<()> {
        let (sleep, fall) = (self.sleep_speed, gravity * dt);
        if sleep > 0.0 && sleep >= fall {
            return Err(Error::InvalidParameter {
                name: "dfsph.sleep_speed",
                value: format!("{sleep} m/s, against g Δt = {fall:.4} m/s at steps of {dt:e} s"),
                reason: "must stay below g Δt, the speed gravity gives in a step at rest, or fluid \
                         at rest in the air would never start to fall",
            });
        }
        Ok(())
    }

    /// The step for particles whose largest |v| + |a| max_dt is `speed`:
    /// λ h / speed, at most `max_dt`.
    pub fn step(&self, h: f32, speed: f32) -> f32 {
        if speed > 0.0 {
            self.max_dt.min(self.cfl * h / speed)
        } else {
            self.max_dt
        }
    }
}
