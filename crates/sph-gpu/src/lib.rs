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
//! obstacles' density) as a compute pass over it; [`GpuPbf`], sph-core's
//! position-based fluids with a whole frame recorded in one command encoder
//! and its statistics read back asynchronously; [`GpuSolver`], the whole step of
//! `sph_core::solver::default_program` (domain walls, box and sphere
//! obstacles) with the particles resident on the GPU, in fixed steps or in
//! adaptive ones whose length the GPU chooses; [`GpuAnisotropy`], Yu & Turk's
//! anisotropic kernels; [`GpuExtractor`], surfel-extract's thesis-mode extraction
//! (initial guess, Newton-Raphson refinement with splitting) on the isotropic or
//! the anisotropic field with append buffers and an indirect draw that `splat_render::SplatRenderer::use_gpu_splats`
//! draws without a round trip to the CPU, with hole closing (`Mode::Covered`).
//! Emitters and sinks are not built yet.
//!
//! The solver's steps and the attached extractor's passes can be timed on
//! the GPU: the `_profiled` variants of [`GpuSolver::step`],
//! [`GpuSolver::advance`] and [`GpuExtractor::encode_attached`] take a
//! [`wgpu_profiler::GpuProfiler`] (re-exported), which records timestamps
//! around each pass where the device has `wgpu::Features::TIMESTAMP_QUERY`.

mod anisotropy;
mod density;
mod extract;
mod grid;
mod passes;
mod pbf;
mod push;
mod solver;

pub use anisotropy::{GpuAnisotropy, KERNEL_BYTES};
pub use density::GpuDensity;
pub use extract::{GpuExtractStats, GpuExtractor, SURFEL_BYTES};
pub use grid::{GpuError, GpuGrid};
pub use pbf::{GpuPbf, MAX_NEIGHBOURS, MIN_FRAME_DT, PbfFrame, PbfFrameStats};
pub use push::RayPush;
pub use solver::{GpuFrame, GpuSolver, GpuState, MAX_BATCH};

/// A GPU solver's particle buffers, which an extractor or renderer reads in
/// place ([`GpuExtractor::attach`]). Index i of each is particle i of the
/// `Particles` the solver was built from.
pub trait GpuParticles {
    /// Number of particles.
    fn len(&self) -> usize;
    /// Whether there are no particles.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Smoothing length (m).
    fn h(&self) -> f32;
    /// Positions (xyz) and masses (w), `vec4<f32>` per particle.
    fn positions_buffer(&self) -> &wgpu::Buffer;
    /// Velocities, `vec4<f32>` per particle.
    fn velocities_buffer(&self) -> &wgpu::Buffer;
    /// Densities of the last step, `f32` per particle.
    fn densities_buffer(&self) -> &wgpu::Buffer;
}

/// Re-export of the GPU pass profiler used by the `_profiled` methods.
pub use wgpu_profiler;
