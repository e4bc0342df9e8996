//! `--gpu-sim`: the SPH step on the GPU (`sph-gpu`) instead of the CPU world.
//!
//! Each frame advances in adaptive substeps whose length the GPU chooses as
//! `World::advance` does (`GpuSolver::advance`: CFL and force condition,
//! landing on the frame time). The particles stay on the GPU: nothing but the
//! 32-byte step state is read back per batch of steps. [`GpuSim::read_into`]
//! copies the state into the CPU world when something there needs it (CPU
//! extraction, exports, the particles view, switching back to the CPU, a
//! world rebuilt after a parameter change). The CPU world stays the reference:
//! switching back continues from the read-back state.

use sph_core::World;
use sph_gpu::GpuSolver;
use splat_render::GpuContext;

use crate::error::AppError;

/// A GPU solver over a world's particles, with the device it runs on.
pub struct GpuSim {
    solver: GpuSolver,
    device: splat_render::wgpu::Device,
    queue: splat_render::wgpu::Queue,
    /// Simulated time on the GPU (s).
    pub time: f64,
    /// Steps the next frame records per batch: the last frame's substeps and
    /// a quarter more, so a frame usually takes one batch and one readback
    /// (steps past the frame's end dispatch no work).
    batch: u32,
}

impl GpuSim {
    /// Uploads `world`'s particles to the device of `ctx`.
    ///
    /// # Errors
    /// [`AppError::Gpu`] where the GPU path does not support the scene
    /// (emitters, a solver other than WCSPH) or the data is invalid.
    pub fn new(ctx: &GpuContext, world: &World, scene: &sph_core::Scene) -> Result<Self, AppError> {
        Self::on(&ctx.device, &ctx.queue, world, scene)
    }

    /// The same on the device this one runs on (after a reset).
    ///
    /// # Errors
    /// As [`GpuSim::new`].
    pub fn restart(&self, world: &World, scene: &sph_core::Scene) -> Result<Self, AppError> {
        Self::on(&self.device, &self.queue, world, scene)
    }

    fn on(
        device: &splat_render::wgpu::Device,
        queue: &splat_render::wgpu::Queue,
        world: &World,
        scene: &sph_core::Scene,
    ) -> Result<Self, AppError> {
        if !scene.emitters.is_empty() {
            return Err(AppError::Gpu(
                "emitters are not on the GPU path (its particle count is fixed): run this scene on the CPU".into(),
            ));
        }
        if world.solver().kind() != sph_core::SolverKind::Wcsph {
            return Err(AppError::Gpu(format!(
                "the GPU path runs only the thesis's WCSPH, and this scene runs {}: pass --solver wcsph to run WCSPH on the GPU, or leave out --gpu-sim",
                world.solver().kind()
            )));
        }
        let mut solver = GpuSolver::new(
            device,
            queue,
            &world.particles,
            world.params(),
            &scene.boundary(),
        )?;
        solver.set_time_stepping(world.time_stepping())?;
        Ok(Self {
            solver,
            device: device.clone(),
            queue: queue.clone(),
            time: 0.0,
            batch: 0,
        })
    }

    /// The solver (its buffers feed `--gpu-extract`).
    pub fn solver(&self) -> &GpuSolver {
        &self.solver
    }

    /// Advances `frame_dt` seconds on the GPU (the first frame sizes its batches
    /// from `world`'s stable step, later ones from the frame before) and
    /// returns the substeps taken. The world's
    /// particles are left as they were: see [`GpuSim::read_into`].
    ///
    /// # Errors
    /// [`AppError::Gpu`] on a readback failure or a blow-up (a non-finite
    /// velocity or acceleration makes the GPU's stable step vanish).
    pub fn advance(&mut self, world: &World, frame_dt: f64) -> Result<u32, AppError> {
        let with_margin = |substeps: u32| substeps.saturating_add(substeps / 4 + 1);
        if self.batch == 0 {
            let substeps = (frame_dt / f64::from(world.stable_dt())).ceil();
            self.batch = with_margin(substeps.clamp(1.0, 1e4) as u32);
        }
        let frame = self
            .solver
            .advance(&self.device, &self.queue, frame_dt as f32, self.batch)?;
        self.batch = with_margin(frame.substeps);
        self.time += frame_dt;
        Ok(frame.substeps)
    }

    /// Writes the GPU's positions, velocities, densities and pressures into
    /// `world.particles` (the same particles, in the order they were uploaded).
    ///
    /// # Errors
    /// [`AppError::Gpu`] on a readback failure or a non-finite state.
    pub fn read_into(&self, world: &mut World) -> Result<(), AppError> {
        let state = self.solver.read_state(&self.device, &self.queue)?;
        if let Some(i) = (0..state.positions.len())
            .find(|&i| !state.positions[i].is_finite() || !state.velocities[i].is_finite())
        {
            return Err(AppError::Gpu(format!(
                "particle {i} is not finite after {} GPU steps: lower k or the time step",
                self.solver.steps()
            )));
        }
        let f = world.particles.fields_mut();
        f.positions.copy_from_slice(&state.positions);
        f.velocities.copy_from_slice(&state.velocities);
        f.densities.copy_from_slice(&state.densities);
        f.pressures.copy_from_slice(&state.pressures);
        Ok(())
    }
}
