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
//! The neighbour grid's scan (its hits packed by [`F32x8::pack_le`]), the
//! solvers' pair sums (WCSPH's 16-lane force sums as two halves), the poly6
//! sums ([`crate::Neighbourhood::poly6_sums`]) and surfel-extract's
//! anisotropic kernels and field sums are written over [`F32x8`]. One path
//! stays outside: at the AVX-512 level the scan keeps its own 16-lane
//! intrinsics, whose compress made the neighbour search 8 % faster than
//! the AVX2 lanes on the one AVX-512 machine measured.
//!
//! # Example
//!
//! A sum written once over lanes, run with the best kind and checked
//! against every kind this CPU runs:
//!
//! ```
//! use sph_core::simd::{F32x8, LaneFn, Lanes, with_lanes};
//!
//! /// Σ x² over a slice, eight at a time.
//! struct SumOfSquares<'a>(&'a [f32]);
//!
//! impl LaneFn for SumOfSquares<'_> {
//!     type Out = f32;
//!     #[inline(always)]
//!     fn call<S: F32x8>(self) -> f32 {
//!         let mut acc = S::splat(0.0);
//!         // A loop, not a closure: see `LaneFn`.
//!         for chunk in self.0.chunks(8) {
//!             let mut lanes = [0.0; 8];
//!             lanes[..chunk.len()].copy_from_slice(chunk);
//!             let x = S::from_array(lanes);
//!             acc = acc + x * x;
//!         }
//!         acc.sum()
//!     }
//! }
//!
//! let x: Vec<f32> = (0..100).map(|i| i as f32 * 0.1).collect();
//! let best = with_lanes(SumOfSquares(&x));
//! assert!((best - 3283.5).abs() < 1e-2);
//! for lanes in Lanes::every() {
//!     let sum = lanes.run(SumOfSquares(&x));
//!     assert_eq!(sum.to_bits(), best.to_bits(), "{}", lanes.name());
//! }
//! ```

mod f32x8;
mod level;

pub use f32x8::{F32x8, LaneFn, Lanes, Scalar, with_lanes};
pub use level::{Simd, simd_level};
