//! The one room for SIMD: which vector instructions this CPU has (detected
//! once per process, [`simd_level`]) and eight f32 lanes written once for
//! all of them ([`F32x8`], run through [`with_lanes`]).
//!
//! Every level and every kind of lanes gives bitwise the same results: the
//! same IEEE operations in the same order, no fused multiply-add. So the
//! choice changes only the speed, and the tests compare the kinds bit for
//! bit ([`Lanes::every`]). `SPH_SIMD=baseline|avx2|avx512` lowers the level
//! to measure the paths side by side on one machine.
//!
//! The solvers' pair sums and the surface field's anisotropic sums are
//! written over [`F32x8`]. The neighbour grid's scan and its poly6 sums
//! (`grid`), WCSPH's force sums and the anisotropic kernels' covariances
//! are still 16-lane plain Rust compiled per [`Simd`] level.

mod f32x8;
mod level;

pub use f32x8::{F32x8, LaneFn, Lanes, Scalar, with_lanes};
pub use level::{Simd, simd_level};
