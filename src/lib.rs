//! # sph-splat
//!
//! Real-time viscous fluid after Vesterlund (2004): an SPH simulation
//! ([`sph_core`]), surfel extraction on its colour-field surface
//! ([`surfel_extract`]) and point-splat rendering ([`splat_render`]); the GPU
//! compute path grows in [`sph_gpu`].
//!
//! This root package re-exports the workspace crates and owns the cross-crate
//! tests (`tests/`) and benchmarks (`benches/`). See `ARCHITECTURE.md`.

pub use sph_core;
pub use sph_gpu;
pub use splat_render;
pub use surfel_extract;

/// The README's Rust examples, compiled and run as doctests so they stay true.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeDoctests;
