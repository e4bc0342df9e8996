//! `--gpu-extract`: surfel extraction on the GPU (`sph_gpu::GpuExtractor`,
//! with the CPU path's parameters: its field, hole closing, splits), drawn
//! by the renderer straight from the GPU buffer.
//!
//! With `--gpu-sim` the extractor reads the GPU solver's buffers; otherwise it
//! uploads the world's positions and volumes. Each frame reads back the
//! counters only (64 bytes): the stats, and whether a buffer overflowed, in
//! which case the capacity doubles and the frame is extracted again, so no
//! surfel is ever silently lost.

use sph_core::World;
use sph_gpu::{GpuExtractStats, GpuExtractor, GpuParticles, SURFEL_BYTES};
use splat_render::{GpuContext, SplatRenderer, wgpu};
use surfel_extract::{ColourField, ExtractParams, Surfel};

use crate::error::AppError;

/// A GPU extractor with the device it runs on and the solver it reads, if any.
pub struct GpuExtract {
    extractor: GpuExtractor,
    params: ExtractParams,
    particles: usize,
    device: wgpu::Device,
    queue: wgpu::Queue,
    /// Volumes uploaded from the CPU world, kept between frames.
    volumes: Vec<f32>,
    /// The positions buffer of the GPU solver the extractor reads, if any.
    attached: Option<wgpu::Buffer>,
}

impl GpuExtract {
    /// An extractor on the device of `ctx` for `world`'s particles.
    ///
    /// # Errors
    /// [`AppError::Gpu`] for parameters the GPU path rejects.
    pub fn new(ctx: &GpuContext, world: &World, params: &ExtractParams) -> Result<Self, AppError> {
        let params = *params;
        let particles = world.particles.len().max(1);
        // A first guess; grows on overflow.
        let capacity = ((2 * particles) << (2 * (params.iterations - 1))).max(1 << 12);
        let extractor = Self::create(&ctx.device, particles, capacity, &params)?;
        Ok(Self {
            extractor,
            params,
            particles,
            device: ctx.device.clone(),
            queue: ctx.queue.clone(),
            volumes: Vec::new(),
            attached: None,
        })
    }

    fn create(
        device: &wgpu::Device,
        particles: usize,
        capacity: usize,
        params: &ExtractParams,
    ) -> Result<GpuExtractor, AppError> {
        let limit = device.limits().max_storage_buffer_binding_size / SURFEL_BYTES;
        Ok(GpuExtractor::new(
            device,
            particles,
            capacity.min(limit as usize),
            params,
        )?)
    }

    /// Extracts the current particles — from `solver` when the SPH step runs on
    /// the GPU, else from `world` — and returns the counters.
    ///
    /// # Errors
    /// [`AppError::Gpu`] on a readback failure, or when even the device's
    /// largest buffers cannot hold the surfels.
    pub fn run(
        &mut self,
        world: &World,
        solver: Option<&dyn GpuParticles>,
    ) -> Result<GpuExtractStats, AppError> {
        let n = world.particles.len();
        if n > self.particles {
            self.particles = n;
            self.extractor =
                Self::create(&self.device, n, self.extractor.capacity(), &self.params)?;
            self.attached = None;
        }
        loop {
            let mut encoder = self.device.create_command_encoder(&Default::default());
            match solver {
                Some(solver) => {
                    // A restarted solver has new buffers.
                    if self.attached.as_ref() != Some(solver.positions_buffer()) {
                        self.extractor.attach(&self.device, solver)?;
                        self.attached = Some(solver.positions_buffer().clone());
                    }
                    self.extractor.encode_attached(&self.queue, &mut encoder)?;
                }
                None => {
                    self.attached = None;
                    volumes_into(&mut self.volumes, world, self.params.h)?;
                    let positions = world.particles.positions();
                    self.extractor
                        .upload(&self.queue, positions, &self.volumes)?;
                    self.extractor.encode(&mut encoder);
                }
            }
            self.queue.submit([encoder.finish()]);
            let stats = self.extractor.read_stats(&self.device, &self.queue)?;
            if stats.dropped == 0 {
                return Ok(stats);
            }
            let capacity = 2 * self.extractor.capacity();
            let grown = Self::create(&self.device, self.particles, capacity, &self.params)?;
            if grown.capacity() <= self.extractor.capacity() {
                return Err(AppError::Gpu(format!(
                    "{} surfels do not fit the device's largest storage buffer ({} surfels)",
                    stats.surfels + stats.dropped,
                    self.extractor.capacity()
                )));
            }
            log::info!("GPU surfel buffers grow to {} surfels", grown.capacity());
            self.extractor = grown;
            self.attached = None;
        }
    }

    /// Culls back-facing surfels for an eye at `camera` (`None`: keeps every
    /// surfel) from the next extraction on.
    ///
    /// # Errors
    /// [`AppError::Gpu`] for a non-finite position.
    pub fn set_camera(&mut self, camera: Option<glam::Vec3>) -> Result<(), AppError> {
        self.extractor.set_camera(&self.queue, camera)?;
        self.params.camera = camera;
        Ok(())
    }

    /// Makes `renderer` draw the last extraction's surfels from the GPU.
    ///
    /// # Errors
    /// [`AppError::Render`] (not expected: the buffers are made for it).
    pub fn show(&self, ctx: &GpuContext, renderer: &mut SplatRenderer) -> Result<(), AppError> {
        renderer.use_gpu_splats(
            ctx,
            self.extractor.surfels_buffer(),
            self.extractor.draw_args_buffer(),
        )?;
        Ok(())
    }

    /// Reads the last extraction's surfels back (for exports).
    ///
    /// # Errors
    /// [`AppError::Gpu`] on a readback failure.
    pub fn read_surfels(&self) -> Result<Vec<Surfel>, AppError> {
        Ok(self.extractor.read_surfels(&self.device, &self.queue)?.0)
    }
}

/// The volumes m/ρ of the world's particles into `out` (its memory kept
/// between frames), recomputed as surfel-extract does where densities are not
/// known yet.
fn volumes_into(out: &mut Vec<f32>, world: &World, h: f32) -> Result<(), AppError> {
    let p = &world.particles;
    out.clear();
    if p.densities().iter().all(|r| r.is_finite() && *r > 0.0) {
        out.extend(p.masses().iter().zip(p.densities()).map(|(m, r)| m / r));
    } else {
        out.extend_from_slice(ColourField::from_particles(p, h)?.volumes());
    }
    Ok(())
}
