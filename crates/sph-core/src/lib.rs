//! # sph-core
//!
//! A pure-Rust Smoothed Particle Hydrodynamics core after Müller, Charypar & Gross
//! (2003) as used in Vesterlund's 2004 thesis: the smoothing [`kernels`], a
//! parallel uniform-grid neighbour search over an unbounded domain
//! ([`NeighbourGrid`]), the extensible struct-of-arrays particle container
//! ([`Particles`]), the solver ([`World`]: the thesis's "conveyor belt" of
//! [`Processor`]s in a [`Program`], adaptive time stepping), domain walls and
//! obstacles ([`boundary`]), TOML scene files ([`Scene`]) and particle export
//! (PLY/VTK, [`io`]).
//!
//! Everything here is independent of rendering: downstream crates (the surfel
//! extractor, user simulations) use the neighbour grid and the kernels directly.
//!
//! Units are SI (m, kg, s); +y is up.

pub mod boundary;
pub mod error;
pub mod grid;
pub mod io;
pub mod kernels;
mod light;
pub mod particles;
pub mod processor;
pub mod region;
pub mod scene;
pub mod simd;
pub mod solver;

pub use boundary::{Aabb, Boundary, Obstacle};
pub use error::{Error, Result};
pub use grid::{NeighbourGrid, NeighbourLists, Neighbourhood};
pub use io::{FrameWriter, PointCloud};
pub use kernels::{CubicSpline, Kernel, Kernels, Poly6, Poly6Sums, Spiky, Viscosity};
pub use particles::{FieldsMut, Particles};
pub use processor::{Context, Processor, Program, StepCounters};
pub use scene::Scene;
pub use simd::{Simd, simd_level};
pub use solver::{
    DfsphParams, FluidParams, FrameReport, PbfParams, PbfSolve, PbfViscosity, PressureKernel,
    Solver, SolverKind, SurfaceTensionModel, TimeStepping, World, useful_threads,
};

/// Re-export of the vector maths crate used in the public API.
pub use glam;
