//! The solvers: each a [`Program`] of [`Processor`](crate::Processor)s over the same particles,
//! neighbour grid, kernels and boundaries, driven by one [`World`].
//!
//! - [`wcsph`]: the thesis's weakly compressible SPH (Müller, Charypar & Gross
//!   2003, thesis eq. 4 and 15–20), the reference. Its adaptive step is bound
//!   by the speed of sound √k ([`TimeStepping`]).
//! - [`pbf`]: position-based fluids (Macklin & Müller 2013), the real-time
//!   solver: a fixed number of substeps per frame and of constraint
//!   iterations per substep ([`PbfParams`]).
//! - [`dfsph`]: divergence-free SPH (Bender & Koschier 2015, 2017), the
//!   accurate incompressible solver: two pressure solves per step to a
//!   tolerance, at a step set by the flow's speed ([`DfsphParams`]).
//!
//! A scene picks one (`[solver] kind = "wcsph" | "pbf" | "dfsph"`, see
//! [`crate::scene::SolverSpec`]); [`Solver`] is that choice with its
//! parameters. What they share lives once: the fluid's parameters and the
//! step rules ([`params`]), the grid, integration, boundary, emitter and sink
//! processors ([`stations`]), and the clock and reports ([`World`]). Users'
//! processors plug into either program by name: both have a `forces` station
//! after which external accelerations are added (see
//! [`ExternalAcceleration`]).

pub mod dfsph;
mod force_sums;
mod free_surface;
mod lane_map;
mod lanes;
pub mod params;
pub mod pbf;
pub mod stations;
pub mod surface_tension;
pub mod viscosity;
mod walls;
pub mod wcsph;
mod world;

pub use dfsph::DfsphParams;
pub use params::{
    FluidParams, MAX_H_OVER_SPACING, MAX_REST_DENSITY, PressureKernel, SurfaceTensionModel,
    TimeStepping,
};
pub use pbf::{PbfParams, PbfSolve, PbfViscosity};
pub use stations::{
    BodyForces, Boundaries, BuildGrid, Emitter, ExternalAcceleration, FindNeighbours, Integrate,
    Sink, nozzle_corners, nozzle_points,
};
pub use wcsph::{DensityPressure, Forces};
pub use world::{FrameReport, World, useful_threads};

use crate::boundary::Boundary;
use crate::error::{Error, Result};
use crate::processor::Program;

/// Which solver advances a [`World`], with the parameters of its own.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum Solver {
    /// The thesis's weakly compressible SPH ([`wcsph`]): its stiffness and
    /// viscosity are [`FluidParams`]'s, its step [`TimeStepping`]'s.
    #[default]
    Wcsph,
    /// Position-based fluids ([`pbf`]).
    Pbf(PbfParams),
    /// Divergence-free SPH ([`dfsph`]): its step by [`DfsphParams::cfl`],
    /// its viscosity [`FluidParams`]'s μ.
    Dfsph(DfsphParams),
}

/// A solver's name, as scene files and the command line give it. The
/// default is PBF, the real-time solver: what a scene file without a
/// `[solver]` table (or without its `kind`) runs, as the demo's built-in
/// scenes do.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Hash, Default, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "lowercase")]
pub enum SolverKind {
    /// [`Solver::Wcsph`].
    Wcsph,
    /// [`Solver::Pbf`], the default.
    #[default]
    Pbf,
    /// [`Solver::Dfsph`].
    Dfsph,
}

impl SolverKind {
    /// Every solver, in the order the demo lists them.
    pub const ALL: [SolverKind; 3] = [SolverKind::Wcsph, SolverKind::Pbf, SolverKind::Dfsph];

    /// The name scene files and the command line use: `wcsph`, `pbf`,
    /// `dfsph`.
    pub fn name(self) -> &'static str {
        match self {
            SolverKind::Wcsph => "wcsph",
            SolverKind::Pbf => "pbf",
            SolverKind::Dfsph => "dfsph",
        }
    }

    /// The solver of this name, or `None`.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|k| k.name() == name)
    }
}

impl std::fmt::Display for SolverKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl Solver {
    /// Its name.
    pub fn kind(&self) -> SolverKind {
        match self {
            Solver::Wcsph => SolverKind::Wcsph,
            Solver::Pbf(_) => SolverKind::Pbf,
            Solver::Dfsph(_) => SolverKind::Dfsph,
        }
    }

    /// Checks the solver's own parameters; the error names the field.
    pub fn validate(&self) -> Result<()> {
        match self {
            Solver::Wcsph => Ok(()),
            Solver::Pbf(p) => p.validate(),
            Solver::Dfsph(p) => p.validate(),
        }
    }

    /// Checks that the solver applies `params` as given: a surface tension
    /// model it does not have is refused, naming the field, instead of
    /// running a fluid other than the one asked for. PBF and DFSPH apply σ
    /// only by Akinci et al.'s forces ([`surface_tension`]); WCSPH by
    /// either.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming `surface_tension_model`.
    pub fn check_applies(&self, params: &FluidParams) -> Result<()> {
        let colour_field = params.surface_tension_model == Some(SurfaceTensionModel::ColourField);
        match self {
            Solver::Pbf(_) | Solver::Dfsph(_) if colour_field => Err(Error::InvalidParameter {
                name: "surface_tension_model",
                value: "colour-field".into(),
                reason: "is WCSPH's only: PBF and DFSPH apply σ by Akinci et al.'s forces; \
                         leave it out, set \"akinci\", or choose kind = \"wcsph\"",
            }),
            _ => Ok(()),
        }
    }

    /// The particle mass for fluid sampled on a cubic lattice of `spacing`
    /// that starts at rest density with the kernel this solver sums
    /// densities with: poly6 for WCSPH and PBF's Jacobi solve
    /// ([`FluidParams::particle_mass`]), the cubic spline for DFSPH and
    /// PBF's Gauss–Seidel ([`PbfSolve::GaussSeidel`]).
    ///
    /// # Errors
    /// A spacing [`FluidParams::lattice_mass`] refuses.
    pub fn particle_mass(&self, params: &FluidParams, spacing: f32) -> Result<f32> {
        match self {
            Solver::Wcsph => params.particle_mass(spacing),
            Solver::Pbf(p) if p.solve == PbfSolve::Jacobi => params.particle_mass(spacing),
            Solver::Pbf(_) | Solver::Dfsph(_) => {
                params.lattice_mass(&crate::kernels::CubicSpline::new(params.h)?, spacing)
            }
        }
    }

    /// The solver's program for this fluid and these walls.
    ///
    /// # Errors
    /// Parameters or a boundary that do not validate, or a parameter the
    /// solver does not apply ([`Solver::check_applies`]).
    pub fn program(&self, params: FluidParams, boundary: Boundary) -> Result<Program> {
        self.check_applies(&params)?;
        match self {
            Solver::Wcsph => wcsph::program(params, boundary),
            Solver::Pbf(p) => pbf::program(params, *p, boundary),
            Solver::Dfsph(p) => dfsph::program(params, *p, boundary),
        }
    }
}

/// The WCSPH program ([`wcsph::program`]), the one [`World::new`] runs.
///
/// # Errors
/// Parameters or a boundary that do not validate.
pub fn default_program(params: FluidParams, boundary: Boundary) -> Result<Program> {
    wcsph::program(params, boundary)
}
