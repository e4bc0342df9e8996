//! # sph-gpu
//!
//! The GPU compute path (the thesis's future work, section 6) with wgpu compute
//! shaders, beside the CPU reference in `sph-core`. It takes a `wgpu::Device`
//! and `Queue` (e.g. from `splat_render::GpuContext`) and keeps its buffers on
//! the GPU.
//!
//! Built so far: [`GpuGrid`], the uniform-grid neighbour search — cell keys,
//! hashed into a power-of-two table, counting sort (atomic counts, prefix sum,
//! scatter), bucket start table and a deterministic order inside each bucket
//! (a bucket may hold several cells) — all compute passes with no CPU readback; [`GpuDensity`], sph-core's density and pressure (with the walls' and
//! obstacles' density) as a compute pass over it; [`GpuSolver`], the whole step of
//! `sph_core::solver::default_program` (domain walls, box and sphere
//! obstacles) with the particles resident on the GPU, in fixed steps or in
//! adaptive ones whose length the GPU chooses; [`GpuExtractor`], surfel-extract's thesis-mode extraction
//! (initial guess, Newton-Raphson refinement with splitting) with append
//! buffers and an indirect draw that `splat_render::SplatRenderer::use_gpu_splats`
//! draws without a round trip to the CPU. Emitters, sinks and hole closing are
//! not built yet.
//!
//! The solver's steps and the attached extractor's passes can be timed on
//! the GPU: the `_profiled` variants of [`GpuSolver::step`],
//! [`GpuSolver::advance`] and [`GpuExtractor::encode_attached`] take a
//! [`wgpu_profiler::GpuProfiler`] (re-exported), which records timestamps
//! around each pass where the device has `wgpu::Features::TIMESTAMP_QUERY`.

mod density;
mod extract;
mod grid;
mod passes;
mod solver;

pub use density::GpuDensity;
pub use extract::{GpuExtractStats, GpuExtractor, SURFEL_BYTES};
pub use grid::{GpuError, GpuGrid};
pub use solver::{GpuFrame, GpuSolver, GpuState};

/// Re-export of the GPU pass profiler used by the `_profiled` methods.
pub use wgpu_profiler;
