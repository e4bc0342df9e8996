//! # surfel-extract
//!
//! Surfels (position, normal, radius) on the colour-field iso-surface
//! c(x) = k_iso (default 0.5) of any particle set, by the method of Vesterlund
//! 2004 (sections 3.2.1 and 4.2.1): an initial guess from surface particles (one
//! Newton-Raphson step each, covariance classification, splitting where the
//! laplacian is large, analytic iso-spheres for lone particles), then 1–3
//! iterations of Newton-Raphson refinement (eq. 33) with splitting; beside it the
//! layered-depth-cube reference extractor ([`ldc`]) and coverage metrics
//! ([`coverage`]).
//!
//! Beyond the thesis, [`Mode::Covered`] (the default) closes the holes a bad
//! initial guess leaves: it probes the rim of every surfel and seeds refined
//! surfels where the surface there is not covered yet ([`fill`]).
//! [`Mode::Thesis`] is the method as published, for comparison.
//!
//! ```
//! use surfel_extract::{extract_points, ExtractParams};
//! use sph_core::glam::Vec3;
//!
//! let points: Vec<Vec3> = (0..125)
//!     .map(|i| Vec3::new((i % 5) as f32, (i / 5 % 5) as f32, (i / 25) as f32) * 0.05)
//!     .collect();
//! let out = extract_points(&points, &ExtractParams::new(0.1)).unwrap();
//! assert!(!out.surfels.is_empty());
//! println!("{} surfels from {} evaluations", out.surfels.len(), out.stats.evaluations);
//! ```
//!
//! Everything runs in parallel with rayon and gives identical output for any
//! number of threads. The crate depends on `sph-core` (grid, kernels) only.

pub mod anisotropy;
pub mod coverage;
mod ellipsoid_sums;
mod extractor;
pub mod field;
pub mod fill;
mod flatten;
pub mod ldc;
pub mod raycast;
pub mod samples;
mod thesis;

use std::time::Duration;

use glam::Vec3;
use sph_core::error::positive;
use sph_core::{Error, Particles, Result};

pub use anisotropy::Anisotropy;
pub use extractor::Extractor;
pub use field::{ColourField, ParticleSample, Sample, Surface};

/// A surface element: a disc on the iso-surface.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Surfel {
    /// Centre (m).
    pub position: Vec3,
    /// Unit normal, pointing out of the fluid (along −∇c).
    pub normal: Vec3,
    /// Disc radius (m).
    pub radius: f32,
}

/// How particles with surface on several sides are surrounded (thesis 4.2.1).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum AllAround {
    /// Six surfels, one per face of a box.
    Six,
    /// Eight surfels, one per corner of a box.
    #[default]
    Eight,
}

/// How a refinement split cuts a surfel (figure 6): the disc's bounding
/// square into cells, one smaller surfel per cell.
///
/// A split replaces one surfel by n² and costs n² evaluations when the
/// children are refined, so it adds surfels at the rate (n² − 1)/n² per
/// evaluation at most (fewer when children are discarded): 3/4 for 2×2, 8/9
/// for 3×3. Refinement with 2×2 splits alone therefore never lifts the
/// efficiency (surfels per evaluation) above 0.75 when the first iteration
/// left it below.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Split {
    /// Four surfels of 0.74 r (the thesis).
    TwoByTwo,
    /// Nine surfels of 0.49 r where the surface is flat enough for them: where
    /// it curves away from the surfel's plane by less than `discard_step` at
    /// the corner children (estimated from the curvature |∇²c|/|∇c|); 2×2
    /// elsewhere.
    ThreeByThree,
}

/// Which extractor runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Mode {
    /// The thesis as published: holes from a bad initial guess stay.
    Thesis,
    /// The thesis plus hole closing ([`fill`]).
    #[default]
    Covered,
}

/// The initial surfel radius [`ExtractParams::radius`] accepts (× h): a
/// bound on how far hole closing can multiply surfels. Surfels smaller than
/// the gaps between them leave most of the surface to hole closing, which
/// adds surfels round after round until it is covered. On a 491-particle
/// sphere (`samples::jittered_lattice(6, 0.02, 0.3, 11, |x| x.length() <
/// 0.1)`, h = 0.04; a throwaway example) the default 0.5 h gives 1,501
/// surfels; 0.05 h gives 45,468 in the default 4 rounds and 105,824 in
/// [`MAX_FILL_ROUNDS`] (168 ms); 0.001 h, no longer accepted, gave 47,084 in
/// 4 rounds and 966,644 in 20 (4.8 s), growing with every round.
pub const RADIUS_RANGE: std::ops::RangeInclusive<f32> = 0.05..=4.0;

/// The range of [`ExtractParams::interior_step`] and
/// [`ExtractParams::discard_step`] (× h).
pub const STEP_RANGE: std::ops::RangeInclusive<f32> = 0.01..=4.0;

/// Checks an iso value k_iso: finite and in (0, 1), where a colour field
/// that sums the particles' volumes crosses it (c is 0 outside the fluid
/// and about 1 inside). The extraction, the LDC, the coverage lattices and
/// the ray caster check it so; `coverage::residuals`, a measure, gives
/// NaN for a NaN iso.
///
/// # Errors
/// [`Error::InvalidParameter`] naming `iso`.
pub fn check_iso(iso: f32) -> Result<()> {
    if iso.is_finite() && iso > 0.0 && iso < 1.0 {
        Ok(())
    } else {
        Err(Error::InvalidParameter {
            name: "iso",
            value: iso.to_string(),
            reason: "must be in (0, 1)",
        })
    }
}

/// The most rounds of hole closing [`ExtractParams::fill_rounds`] accepts.
pub const MAX_FILL_ROUNDS: u32 = 64;

/// Extraction parameters. Lengths are in units of h unless marked (m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ExtractParams {
    /// Smoothing length h of the colour field (m).
    pub h: f32,
    /// Iso value k_iso (eq. 34).
    pub iso: f32,
    /// Refinement iterations, 1–3; surfels split in every iteration but the last.
    pub iterations: u32,
    /// A particle whose Newton-Raphson step is longer than this (× h) is
    /// interior.
    pub interior_step: f32,
    /// A surfel whose Newton-Raphson step is longer than this (× h) is
    /// discarded.
    pub discard_step: f32,
    /// Initial surfels split where |∇²c|·h² (dimensionless) exceeds this
    /// (figure 6).
    pub split_laplacian: f32,
    /// A particle with P = det C/(tr C/3)³ below this (eq. 36) has surface on
    /// several sides and is surrounded by surfels.
    pub covariance_threshold: f32,
    /// Six or eight surfels around such particles.
    pub all_around: AllAround,
    /// Radius of an initial surfel (× h; `Surfel::radius` is in metres), in
    /// [`RADIUS_RANGE`]: a surfel much smaller than the particle spacing
    /// leaves gaps that hole closing fills with ever more surfels.
    pub radius: f32,
    /// Eye position (m) for front-facing culling; `None` keeps every surfel.
    pub camera: Option<Vec3>,
    /// Thesis as published or with hole closing.
    pub mode: Mode,
    /// Rounds of hole closing in [`Mode::Covered`], at most
    /// [`MAX_FILL_ROUNDS`]; each closes an uncovered band about a surfel
    /// wide around every hole.
    pub fill_rounds: u32,
    /// How the first iteration's surfels split; later splits are 2×2.
    pub first_split: Split,
    /// The field whose iso-surface is extracted: the thesis's isotropic
    /// colour field (the default) or Yu & Turk's anisotropic one.
    pub surface: Surface,
}

impl ExtractParams {
    /// Defaults for smoothing length `h`: iso 0.5, 2 iterations, covered mode,
    /// 3×3 first split.
    pub fn new(h: f32) -> Self {
        Self {
            h,
            iso: 0.5,
            iterations: 2,
            interior_step: 0.75,
            discard_step: 0.25,
            split_laplacian: 40.0,
            covariance_threshold: 0.25,
            all_around: AllAround::Eight,
            radius: 0.5,
            camera: None,
            mode: Mode::Covered,
            fill_rounds: 4,
            first_split: Split::ThreeByThree,
            surface: Surface::Isotropic,
        }
    }

    /// The same parameters on Yu & Turk's anisotropic field, with the
    /// paper's parameters ([`Anisotropy::default`]).
    pub fn anisotropic(self) -> Self {
        Self {
            surface: Surface::anisotropic(),
            ..self
        }
    }

    /// The same parameters in the thesis-faithful mode: no hole closing, 2×2
    /// splits, the isotropic field.
    pub fn thesis(self) -> Self {
        Self {
            mode: Mode::Thesis,
            first_split: Split::TwoByTwo,
            surface: Surface::Isotropic,
            ..self
        }
    }

    /// Checks every field; the error names it.
    pub fn validate(&self) -> Result<()> {
        positive("h", self.h)?;
        for (name, step) in [
            ("interior_step", self.interior_step),
            ("discard_step", self.discard_step),
        ] {
            if !STEP_RANGE.contains(&step) {
                return Err(Error::InvalidParameter {
                    name,
                    value: step.to_string(),
                    reason: "must be in [0.01, 4] (× h): below, f32's Newton steps never \
                             come that short and every surfel is discarded or interior",
                });
            }
        }
        positive("split_laplacian", self.split_laplacian)?;
        if !RADIUS_RANGE.contains(&self.radius) {
            return Err(Error::InvalidParameter {
                name: "radius",
                value: self.radius.to_string(),
                reason: "must be in [0.05, 4] (× h)",
            });
        }
        if self.fill_rounds > MAX_FILL_ROUNDS {
            return Err(Error::InvalidParameter {
                name: "fill_rounds",
                value: self.fill_rounds.to_string(),
                reason: "must be at most 64",
            });
        }
        if !(self.radius * self.h).is_finite() {
            return Err(Error::InvalidParameter {
                name: "radius",
                value: self.radius.to_string(),
                reason: "radius · h, the surfels' radius, must be finite",
            });
        }
        check_iso(self.iso)?;
        if !(1..=3).contains(&self.iterations) {
            return Err(Error::InvalidParameter {
                name: "iterations",
                value: self.iterations.to_string(),
                reason: "must be 1, 2 or 3",
            });
        }
        if !(self.covariance_threshold.is_finite()
            && (0.0..=1.0).contains(&self.covariance_threshold))
        {
            return Err(Error::InvalidParameter {
                name: "covariance_threshold",
                value: self.covariance_threshold.to_string(),
                reason: "must be in [0, 1]",
            });
        }
        self.surface.validate()?;
        if let Some(c) = self.camera.filter(|c| !c.is_finite()) {
            return Err(Error::InvalidParameter {
                name: "camera",
                value: format!("{c}"),
                reason: "must be finite",
            });
        }
        Ok(())
    }
}

/// What an extraction did.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Stats {
    /// Particles in the input.
    pub particles: usize,
    /// Particles that seeded the initial guess with their own surfel (four
    /// where the laplacian splits it).
    pub surface_particles: usize,
    /// Particles surrounded by six or eight surfels (eq. 36).
    pub all_around: usize,
    /// Lone particles given their analytic iso-sphere.
    pub lone: usize,
    /// Particles of droplets too small for anisotropic kernels, each
    /// surrounded by surfels on its sphere (the anisotropic field only).
    pub droplets: usize,
    /// Surfels in the initial guess.
    pub initial: usize,
    /// Surfels discarded by the step test.
    pub discarded: usize,
    /// Surfels added by hole closing.
    pub filled: usize,
    /// Surfels in the result.
    pub surfels: usize,
    /// Field evaluations at the particles for the initial guess (a simulation
    /// that keeps c, ∇c, ∇²c per particle would have them for free).
    pub particle_evaluations: u64,
    /// Field evaluations at surfels: refinement and hole closing.
    pub evaluations: u64,
    /// Time building the field (grid, volumes).
    pub field_time: Duration,
    /// Time for the initial guess.
    pub initial_time: Duration,
    /// Time for refinement.
    pub refine_time: Duration,
    /// Time for hole closing.
    pub fill_time: Duration,
}

impl Stats {
    /// Surfels per surfel evaluation (the thesis's efficiency).
    pub fn efficiency(&self) -> f64 {
        self.surfels as f64 / self.evaluations.max(1) as f64
    }

    /// Total time.
    pub fn total_time(&self) -> Duration {
        self.field_time + self.initial_time + self.refine_time + self.fill_time
    }
}

/// Surfels and what it took to make them.
#[derive(Debug, Clone, Default)]
pub struct Surfels {
    /// The surfels, in a deterministic order.
    pub surfels: Vec<Surfel>,
    /// Counts and timings.
    pub stats: Stats,
}

/// Extracts surfels from simulated particles (volumes m/ρ). For one frame
/// after another, [`Extractor`] keeps its memory between calls.
pub fn extract(particles: &Particles, params: &ExtractParams) -> Result<Surfels> {
    let mut extractor = Extractor::new();
    extractor.extract(particles, params)?;
    Ok(extractor.take())
}

/// Extracts surfels from bare points (Shepard volumes, see
/// [`ColourField::from_positions`]).
pub fn extract_points(positions: &[Vec3], params: &ExtractParams) -> Result<Surfels> {
    let mut extractor = Extractor::new();
    extractor.extract_points(positions, params)?;
    Ok(extractor.take())
}

/// Extracts surfels from a prepared field (its h is used; `params.h` is ignored).
pub fn extract_field(field: &ColourField, params: &ExtractParams) -> Result<Surfels> {
    let mut extractor = Extractor::new();
    extractor.extract_field(field, params)?;
    Ok(extractor.take())
}

/// Runs `op` on a rayon worker: `rayon::scope` runs it in place on a worker
/// thread and hands it to the global pool from any other thread. Called from
/// outside the pool, every parallel pass would otherwise be handed over and
/// waited for separately, and the extraction makes a few dozen of them.
fn on_pool<T: Send>(op: impl FnOnce() -> T + Send) -> T {
    rayon::scope(|_| sph_core::region::team(op))
}

/// Two unit vectors spanning the plane normal to the unit vector `n`.
pub(crate) fn tangent_basis(n: Vec3) -> (Vec3, Vec3) {
    let helper = if n.x.abs() < 0.6 { Vec3::X } else { Vec3::Y };
    let t = n.cross(helper).normalize();
    (t, n.cross(t))
}
