//! [`PbfParams`]: what a scene's `[solver.pbf]` table gives position-based
//! fluids, with their defaults, their checks and the step they derive for a
//! scene. The solver's algorithm is its parent module, [`super`].

use crate::error::{Error, Result};

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
    /// Iterations of the density constraint per substep (Jacobi sweeps, or
    /// Gauss–Seidel sweeps under [`PbfSolve::GaussSeidel`]). Default 3.
    pub iterations: u32,
    /// How the density constraints are solved: `"jacobi"` (default, the
    /// paper's) or `"gauss-seidel"` (coloured Gauss–Seidel on the cubic
    /// spline, the quieter water at rest; [`PbfSolve`]).
    pub solve: PbfSolve,
    /// Holds particles at a free surface to the density a lattice's top
    /// layer reads instead of ρ0 (the module `free_surface`'s target, by
    /// the length of each constraint's gradient averaged over its
    /// neighbourhood), so that the surface layers do not pack and the free
    /// surface stays at the fluid's height. Default false: the paper's ρ0
    /// everywhere, under which a pool's top layer packs and its surface
    /// sinks (a 0.2 m pool under Gauss–Seidel warm-started by half: 2.16 %
    /// low after 2 s, 0.18 % with the target; `docs/benchmark-notes.md`,
    /// "The free surface's packed top layer"). It costs the density
    /// station about 10 % (two more passes). Read only under
    /// [`PbfSolve::GaussSeidel`]: under Jacobi's jitter the bulk reads as a
    /// surface, and a pool 0.5 m deep blew up. CPU only.
    pub surface_target: bool,
    /// Gauss–Seidel's warm start w in [0, 0.5]: each substep's solve
    /// starts by applying w times the pressure the last substep's solve
    /// ended with ([`Particles::pressures`](crate::Particles::pressures)),
    /// as one Jacobi-form correction with λ_i = −w Δt² p_i/ρ0, and its
    /// sweeps then correct what is left. Each constraint's λ then
    /// accumulates over the sweeps from that share and is clamped as a sum
    /// (it may take back the warm push where the fluid has drawn apart,
    /// never pull), as contact solvers clamp accumulated impulses. Default
    /// 0: off, each substep builds its pressure from nothing. Read only
    /// under [`PbfSolve::GaussSeidel`].
    ///
    /// Few sweeps carry a correction a few neighbourhoods per substep, so
    /// the weight of a deep column is held by compressing it; the last
    /// pressure carries that weight over. At w = 0.5, the 0.5 m pool of
    /// `pool_at_rest` moves at 57 mm/s rms at 2 s against 174 mm/s, its
    /// surface 1.9 % low against 2.4 %, and the 10,000-particle dam
    /// break's average density error at 5 × 3 is 0.47 % against 0.90 %
    /// (`docs/benchmark-notes.md`, "Gauss–Seidel's warm start"). The
    /// carried pressure acts as an explicit force, one substep late, and
    /// only the fresh part of each solve damps: at 0.6 the deep pool's top
    /// rings at 0.2 m/s, and at 0.85 it diverges, hence the bound. The
    /// warm move, like the sweeps' corrections, is not limited by
    /// [`Self::max_displacement`], which guards the prediction.
    pub warm_start: f32,
    /// The over-relaxation ω of the Jacobi iterations: each position
    /// correction moves a particle by ω Δp_i instead of Δp_i (successive
    /// over-relaxation, as in Macklin et al. 2014, "Unified Particle
    /// Physics for Real-Time Applications", §4.2, and FleX's
    /// `relaxationFactor`). Each pair's term stays antisymmetric, so
    /// momentum is kept. Default 1, the paper's plain Jacobi. Under
    /// [`PbfSolve::GaussSeidel`] each constraint's λ_i is scaled by ω
    /// (successive over-relaxation proper).
    ///
    /// PBF's Jacobi iterations undershoot (each corrects a particle as if
    /// its neighbours stood still, while they move too), and ω > 1 makes up
    /// part of that: in a tank 25 particles deep at 3 × 3, ω = 1.25 leaves
    /// 1.08 % average density error against 1.52 % (`pbf_convergence`
    /// below); on `dam-break-fine` at 5 × 3, 0.62 % against 0.90 %
    /// (`pbf_substeps`). The price is jitter of water at rest, which grows
    /// as the iterations get fewer: the rms speed of that settled tank goes
    /// from 0.18 to 0.23 m/s at 3 iterations, and from 0.24 to 0.43 m/s at
    /// 2. So ω stays 1 by default, and buys accuracy where motion hides the
    /// jitter.
    ///
    /// ```text
    /// cargo run --release -p sph-core --example pbf_convergence
    /// cargo run --release -p sph-core --example pbf_substeps -- 5x3 5x3@1.25
    /// ```
    pub over_relaxation: f32,
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
    /// s_corr's exponent n. Default 4 (the paper's). Like
    /// [`Self::scorr_dq`], read only where [`Self::scorr_k`] > 0: a value
    /// away from the default at k = 0 is refused by [`Self::validate`].
    pub scorr_n: u32,
    /// s_corr's Δq as a fraction of h. Default 0.2 (the paper: 0.1 to 0.3).
    /// With [`Self::scorr_n`] it must keep (W(0)/W(Δq h))ⁿ = (1 − Δq²)^(−3n)
    /// below 10³⁰, so that s_corr of a pair at r = 0 stays in f32's range
    /// (every Δq up to 0.99 at the default n = 4).
    pub scorr_dq: f32,
    /// Vorticity confinement ε (m/s): the acceleration ε N × ω, with ω the
    /// velocity's curl and N the direction towards larger |ω|. It gives back
    /// the rotation the damped solver loses. Default 0.01; 0 turns it off.
    pub vorticity: f32,
    /// XSPH viscosity c in [0, 1]: each substep blends a particle's velocity
    /// by c towards its neighbours' kernel-weighted mean,
    /// v_i += c Σ_j (m_j/ρ0)(v_j − v_i) W_ij. Default 0.01 (the paper's).
    /// Read only under [`PbfViscosity::Xsph`]: the implicit viscosity
    /// replaces the blend, and a value away from the default under it is
    /// refused by [`Self::validate`].
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
    /// this residual relative to the velocities' norm. Default 1e-3. Read
    /// only under [`PbfViscosity::Implicit`], as the next: a value away
    /// from the default under XSPH is refused by [`Self::validate`].
    pub viscosity_tolerance: f32,
    /// The implicit viscosity's most conjugate-gradient iterations per
    /// substep. Default 100.
    pub viscosity_max_iterations: u32,
    /// Particle sleeping (m/s; Macklin et al. 2014, "Unified Particle
    /// Physics for Real-Time Applications", and FleX's `sleepThreshold`):
    /// a particle whose substep, solve included, would move it slower than
    /// this stays where it was, and the solve leaves its velocity zero
    /// (PBF's own v = (x* − x)/Δt, with x* = x; XSPH and vorticity may then
    /// give it some back for the next substep). Default 0: off.
    ///
    /// It stops what PBF's few Jacobi iterations leave moving in water at
    /// rest: their residual jitters the particles at 80 mm/s in a still
    /// pool at the defaults (the module docs). It does so only once damping
    /// has brought that jitter below the threshold, and an odd iteration
    /// count keeps the bottom of a pool jittering above it: with
    /// `iterations = 4, xsph = 0.1, sleep_speed = 0.02` the 0.2 m pool of
    /// `pool_at_rest` is still at 2 s (1.13 mm/s at 1.5 s; `tests/pool.rs`).
    ///
    /// The price: any motion slower than the threshold stops where it is.
    /// A slow slosh freezes tilted, a creeping viscous current halts, the
    /// surface keeps whatever shape it had when it fell asleep, and fluid on
    /// a slope is held as by static friction up to asin(S/(g Δt)) (21° at
    /// S = 0.02 m/s and Δt = 1/180 s). It must stay below g Δt, the speed
    /// gravity gives in one substep, or fluid at rest in the air would never
    /// start to fall: a threshold at or above it is refused, naming this
    /// field, by [`Self::check_sleep`] (a scene's validation and each
    /// frame of [`crate::World::advance`]).
    pub sleep_speed: f32,
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
    /// The dynamic viscosity μ of [`FluidParams::viscosity`](crate::FluidParams::viscosity) (Pa·s), solved
    /// implicitly each substep ([`ImplicitViscosity`](crate::solver::viscosity::ImplicitViscosity)); XSPH is off.
    Implicit,
}

/// How PBF solves its density constraints ([`PbfParams::solve`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum PbfSolve {
    /// Macklin & Müller 2013: poly6 densities, spiky gradients, and each
    /// iteration a Jacobi sweep (every λ_i, then every particle moved by
    /// its correction), with [`PbfParams::over_relaxation`] ω.
    #[default]
    Jacobi,
    /// Every iteration a Gauss–Seidel sweep: each particle's constraint in
    /// turn moves it and its neighbours by the pushes a Jacobi correction
    /// would give them (ω times λ_i), from the positions its predecessors
    /// left. The sweep visits columns along gravity, 2h wide, in four
    /// colours, so that columns of one colour share no particle and run in
    /// parallel, each from the bottom up; odd sweeps go backwards (a
    /// symmetric Gauss–Seidel). The whole PBF step then uses the cubic
    /// spline, DFSPH's kernel, where Jacobi uses poly6 and spiky: the
    /// constraint's density and its own gradient (Jacobi's spiky gradient
    /// of a poly6 density is not one), and also the vorticity station's
    /// curl, XSPH's weights and the densities it reports. Masses are the
    /// cubic spline's lattice masses
    /// ([`crate::solver::Solver::particle_mass`]).
    ///
    /// It is what brings PBF water at rest nearest rest: in the 0.2 m pool
    /// of `pool_at_rest`, 21.6 mm/s rms at 2 s and the free surface 2.4 %
    /// low at the other defaults, 10.8 mm/s at 4 substeps, against
    /// Jacobi's 81.7 mm/s and 3.1 % (`docs/benchmark-notes.md`, "Coloured
    /// Gauss–Seidel on the cubic spline"). Neither half does it alone:
    /// Gauss–Seidel on Jacobi's kernels jitters as Jacobi does, and Jacobi
    /// on the cubic spline needs ω = ½. Its density solve costs about 2.3
    /// times Jacobi's. s_corr is not applied ([`PbfParams::scorr_k`] must
    /// stay 0), and the GPU path runs only Jacobi.
    GaussSeidel,
}

impl Default for PbfParams {
    fn default() -> Self {
        Self {
            substeps: 3,
            iterations: 3,
            solve: PbfSolve::Jacobi,
            surface_target: false,
            warm_start: 0.0,
            over_relaxation: 1.0,
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
            sleep_speed: 0.0,
        }
    }
}

impl PbfParams {
    /// The defaults with enough substeps per frame of `frame_dt` (at least
    /// the default 3, and `max_dt` the frame over them) that a particle
    /// falling freely from `height` above the floor, at √(2 g height),
    /// moves at most [`FALL_CFL`] × h per substep: what a scene without a
    /// `[solver.pbf]` table runs ([`crate::Scene::pbf_params`]). The count
    /// is not capped: one above [`MAX_PBF_COUNT`] fails
    /// [`PbfParams::validate`] rather than letting every particle be
    /// slowed by the displacement guard.
    pub fn for_fall(height: f32, gravity: f32, h: f32, frame_dt: f32) -> Self {
        let d = Self::default();
        let speed = (2.0 * gravity.abs() * height.max(0.0)).sqrt();
        let needed = (speed * frame_dt / (FALL_CFL * h)).ceil();
        let substeps = if needed.is_finite() {
            // `as` saturates: 1e12 substeps become u32::MAX, still refused.
            needed.max(d.substeps as f32) as u32
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

impl PbfParams {
    /// Checks [`Self::sleep_speed`] against gravity of magnitude `gravity`
    /// (m/s²) for frames of `frame_dt`: a threshold must stay below g Δt at
    /// their substep Δt, or fluid at rest in the air would never start to
    /// fall.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming `pbf.sleep_speed`.
    pub fn check_sleep(&self, gravity: f32, frame_dt: f32) -> Result<()> {
        let dt = frame_dt / self.substeps_for(frame_dt) as f32;
        check_sleep_at(self.sleep_speed, gravity, dt)
    }

    /// The substeps a frame of `frame_dt` takes ([`Self::substeps_for`]),
    /// refused above [`MAX_PBF_COUNT`]: a `max_dt` far below the frame
    /// would otherwise run thousands of substeps a frame (a run that looks
    /// hung), or, past `u32::MAX`, substeps longer than `max_dt`.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming `pbf.max_dt`.
    pub fn check_frame(&self, frame_dt: f32) -> Result<u32> {
        let n = self.substeps_for(frame_dt);
        if n > MAX_PBF_COUNT {
            return Err(Error::InvalidParameter {
                name: "pbf.max_dt",
                value: format!(
                    "{} s, against frames of {frame_dt} s ({:.0} substeps a frame)",
                    self.max_dt,
                    f64::from(frame_dt) / f64::from(self.max_dt)
                ),
                reason: "a frame takes at most 1000 substeps of at most max_dt: lengthen \
                         solver.pbf.max_dt, or advance by shorter frames (a scene's \
                         time_step.frame_dt, the frame given to World::advance)",
            });
        }
        Ok(n)
    }

    /// The substeps a frame of `frame_dt` takes: [`Self::substeps`], more
    /// only where they would be longer than [`Self::max_dt`] (what
    /// [`crate::World::advance`] takes, each `frame_dt` over this).
    pub fn substeps_for(&self, frame_dt: f32) -> u32 {
        // A hair under, so that a frame of exactly k × max_dt takes k
        // substeps despite rounding.
        let needed = (frame_dt / self.max_dt * (1.0 - 1e-6)).ceil();
        needed.max(self.substeps as f32) as u32
    }
}

/// Refuses a sleeping threshold `sleep` (m/s) at or above g Δt for substeps
/// of `dt` under gravity of magnitude `gravity`.
pub(super) fn check_sleep_at(sleep: f32, gravity: f32, dt: f32) -> Result<()> {
    let fall = gravity * dt;
    if sleep > 0.0 && sleep >= fall {
        return Err(Error::InvalidParameter {
            name: "pbf.sleep_speed",
            value: format!("{sleep} m/s, against g Δt = {fall:.4} m/s at substeps of {dt:e} s"),
            reason: "must stay below g Δt, the speed gravity gives in one substep, or fluid at rest \
                     in the air would never start to fall: lower it, or take fewer, longer substeps \
                     (solver.pbf.substeps, solver.pbf.max_dt, time_step.frame_dt)",
        });
    }
    Ok(())
}

/// The Courant number of [`PbfParams::for_fall`]: a substep's largest
/// expected displacement over h. Looked at in rendered frames of
/// `dam-break-fine` (10,000 particles, h = 0.02 m): at 1 (3 substeps per
/// 60 Hz frame) the flow boiled into spray over the collapsing column and
/// where it met the far wall (neither vorticity confinement off nor a
/// clamp on the solve's velocity change helped: the 2.4 % compression that
/// 3 iterations leave in a column 50 particles deep is the likely cause);
/// at 0.75 (4 substeps) it still threw spray at the wall; at 0.5 (6
/// substeps) it ran up the wall and fell back as one sheet, as WCSPH's does,
/// and so it does at 0.6 (5 substeps), for a sixth less time: the average
/// density error is 0.90 % against 0.62 % at 0.5, the largest share of
/// spray 2.8 % against 3.2 % (`cargo run --release -p sph-core --example
/// pbf_substeps -- 6x3 5x3`).
pub const FALL_CFL: f32 = 0.6;

/// The largest [`PbfParams::warm_start`].
pub const MAX_WARM_START: f32 = 0.5;

/// The most substeps or iterations [`PbfParams::validate`] accepts.
pub const MAX_PBF_COUNT: u32 = 1000;

/// The density error (ρ/ρ0 − 1) above which a constraint solve that makes no
/// headway over its iterations has failed, and the run stops
/// ([`Error::Unstable`], see [`SolveDensity`](super::SolveDensity)).
pub const MAX_DENSITY_ERROR: f32 = 1.0;

impl PbfParams {
    /// Checks every parameter is finite and in range, and that none is
    /// given where the others leave it unread; the error names it
    /// (`pbf.iterations`, ...).
    pub fn validate(&self) -> Result<()> {
        let check = crate::error::check_param;
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
        let w = self.over_relaxation;
        check(
            "pbf.over_relaxation",
            w.into(),
            w > 0.0 && w < 2.0,
            "must lie in (0, 2): 1 is plain Jacobi or Gauss–Seidel, 2 and above diverge",
        )?;
        let warm = self.warm_start;
        check(
            "pbf.warm_start",
            warm.into(),
            (0.0..=MAX_WARM_START).contains(&warm),
            "must lie in [0, 0.5] (a share of the last substep's pressure; above it the carried \
             pressure rings, and at 0.85 a pool 0.5 m deep diverged)",
        )?;
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
        // s_corr's largest ratio W(0)/W(Δq h) = 1/(1 − Δq²)³, raised to the
        // n, must stay far inside f32 (a pair at r = 0 reaches it).
        let largest = (f64::from(self.scorr_n) * -3.0 * (1.0 - f64::from(dq).powi(2)).ln()).exp();
        if largest >= 1e30 {
            return Err(Error::InvalidParameter {
                name: "pbf.scorr_dq",
                value: format!(
                    "{dq} (with scorr_n = {}: (W(0)/W(Δq h))ⁿ = {largest:.1e})",
                    self.scorr_n
                ),
                reason: "with scorr_n makes s_corr overflow f32 for close pairs: lower scorr_dq or scorr_n",
            });
        }
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
        let s = self.sleep_speed;
        check(
            "pbf.sleep_speed",
            s.into(),
            s.is_finite() && s >= 0.0,
            "must be finite and ≥ 0 m/s (0 turns sleeping off)",
        )?;
        self.check_read()
    }

    /// Refuses a field the other settings leave unread, set away from its
    /// default: nothing a scene gives is silently dropped. s_corr is
    /// applied only by [`PbfSolve::Jacobi`], the warm start and the surface
    /// target only by [`PbfSolve::GaussSeidel`], XSPH's blend is
    /// read only under [`PbfViscosity::Xsph`], the implicit viscosity's
    /// tolerance and iterations only under [`PbfViscosity::Implicit`], and
    /// s_corr's n and Δq only where its k is above 0. A field written out
    /// at its default (as the shipped scene files do) is accepted.
    fn check_read(&self) -> Result<()> {
        const IMPLICIT_ONLY: &str = "is read only under viscosity = \"implicit\", and this is \
            \"xsph\": leave it out, or set viscosity = \"implicit\" (with fluid.viscosity)";
        const SCORR_ONLY: &str = "is read only where scorr_k > 0, and scorr_k = 0 turns s_corr \
            off: leave it out, or give scorr_k";
        let d = Self::default();
        let xsph = self.viscosity == PbfViscosity::Xsph;
        let scorr_off = self.scorr_k == 0.0;
        let unread = [
            (
                "pbf.scorr_k",
                self.solve == PbfSolve::GaussSeidel && !scorr_off,
                f64::from(self.scorr_k),
                "is not applied by solve = \"gauss-seidel\", whose sweeps move particles by \
                 their constraints alone: leave it out, or set solve = \"jacobi\"",
            ),
            (
                "pbf.surface_target",
                self.solve == PbfSolve::Jacobi && self.surface_target,
                1.0,
                "is read only under solve = \"gauss-seidel\": Jacobi's jitter reads as a surface \
                 in the bulk, and a pool 0.5 m deep blew up within 1 s (docs/benchmark-notes.md): \
                 leave it out, or set solve = \"gauss-seidel\"",
            ),
            (
                "pbf.warm_start",
                self.solve == PbfSolve::Jacobi && self.warm_start != 0.0,
                f64::from(self.warm_start),
                "is read only under solve = \"gauss-seidel\": Jacobi's overshoot, carried over, \
                 rings (docs/benchmark-notes.md): leave it out, or set solve = \"gauss-seidel\"",
            ),
            (
                "pbf.xsph",
                !xsph && self.xsph != d.xsph,
                f64::from(self.xsph),
                "is not read under viscosity = \"implicit\", which replaces XSPH's blend: \
                 leave it out, or set viscosity = \"xsph\"",
            ),
            (
                "pbf.viscosity_tolerance",
                xsph && self.viscosity_tolerance != d.viscosity_tolerance,
                f64::from(self.viscosity_tolerance),
                IMPLICIT_ONLY,
            ),
            (
                "pbf.viscosity_max_iterations",
                xsph && self.viscosity_max_iterations != d.viscosity_max_iterations,
                f64::from(self.viscosity_max_iterations),
                IMPLICIT_ONLY,
            ),
            (
                "pbf.scorr_n",
                scorr_off && self.scorr_n != d.scorr_n,
                f64::from(self.scorr_n),
                SCORR_ONLY,
            ),
            (
                "pbf.scorr_dq",
                scorr_off && self.scorr_dq != d.scorr_dq,
                f64::from(self.scorr_dq),
                SCORR_ONLY,
            ),
        ];
        match unread.into_iter().find(|&(_, given, _, _)| given) {
            Some((name, _, value, reason)) => Err(Error::InvalidParameter {
                name,
                value: value.to_string(),
                reason,
            }),
            None => Ok(()),
        }
    }
}
