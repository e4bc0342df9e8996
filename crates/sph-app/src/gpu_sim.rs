//! `--gpu-sim`: the scene's solver on the GPU (`sph-gpu`) instead of the CPU
//! world: PBF (the default) or the thesis's WCSPH.
//!
//! - PBF records a whole frame (every substep and iteration) in one
//!   submission and reads nothing back inside it; the frame's statistics
//!   (density errors, guard clamps) come back a frame or two later
//!   ([`GpuStep::late`]).
//! - WCSPH advances in adaptive substeps whose length the GPU chooses as
//!   `World::advance` does (`GpuSolver::advance`: CFL and force condition,
//!   landing on the frame time), reading a 32-byte step state back per
//!   batch of steps.
//!
//! The particles stay on the GPU. [`GpuSim::read_into`] copies them into the
//! CPU world when something there needs them (CPU extraction, exports,
//! switching back to the CPU, a world rebuilt after a parameter change). The
//! CPU world stays the reference: switching back continues from the
//! read-back state.

use sph_core::{Solver, SolverKind, World};
use sph_gpu::{GpuParticles, GpuPbf, GpuSolver, GpuState, PbfFrameStats};
use splat_render::GpuContext;

use crate::error::AppError;

/// The solver on the GPU.
enum Stepper {
    Pbf(GpuPbf),
    Wcsph {
        solver: GpuSolver,
        /// Steps the next frame records per batch: the last frame's substeps
        /// and a quarter more, so a frame usually takes one batch and one
        /// readback (steps past the frame's end dispatch no work).
        batch: u32,
    },
}

/// What one GPU frame did.
#[derive(Debug, Clone, PartialEq)]
pub struct GpuStep {
    /// The solver that took the steps.
    pub solver: SolverKind,
    /// Substeps of the frame.
    pub substeps: u32,
    /// Constraint iterations of the frame (PBF; 0 for WCSPH).
    pub iterations: u32,
    /// Statistics of earlier PBF frames that came back during this one,
    /// oldest first; `frame` counts this solver's frames from 0.
    pub late: Vec<PbfFrameStats>,
}

/// A GPU solver over a world's particles, with the device it runs on.
pub struct GpuSim {
    stepper: Stepper,
    device: splat_render::wgpu::Device,
    queue: splat_render::wgpu::Queue,
    /// Simulated time on the GPU (s).
    pub time: f64,
}

impl GpuSim {
    /// Uploads `world`'s particles to the device of `ctx`.
    ///
    /// # Errors
    /// [`AppError::Gpu`] where the GPU path does not support the scene
    /// (emitters, DFSPH, PBF's implicit viscosity) or the data is invalid.
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
        let boundary = scene.boundary();
        let stepper = match world.solver() {
            Solver::Pbf(pbf) => Stepper::Pbf(GpuPbf::new(
                device,
                queue,
                &world.particles,
                world.params(),
                pbf,
                &boundary,
            )?),
            Solver::Wcsph => {
                let mut solver =
                    GpuSolver::new(device, queue, &world.particles, world.params(), &boundary)?;
                solver.set_time_stepping(world.time_stepping())?;
                Stepper::Wcsph { solver, batch: 0 }
            }
            other => {
                return Err(AppError::Gpu(format!(
                    "the GPU path runs PBF and the thesis's WCSPH, and this scene runs {}: pass --solver pbf or --solver wcsph, or leave out --gpu-sim",
                    other.kind()
                )));
            }
        };
        Ok(Self {
            stepper,
            device: device.clone(),
            queue: queue.clone(),
            time: 0.0,
        })
    }

    /// The solver's particle buffers (they feed `--gpu-extract`).
    pub fn particles(&self) -> &dyn GpuParticles {
        match &self.stepper {
            Stepper::Pbf(pbf) => pbf,
            Stepper::Wcsph { solver, .. } => solver,
        }
    }

    /// Advances `frame_dt` seconds on the GPU. The world's particles are
    /// left as they were (see [`GpuSim::read_into`]); WCSPH's first frame
    /// sizes its batches from `world`'s stable step.
    ///
    /// # Errors
    /// [`AppError::Gpu`] on a readback failure or a blow-up (WCSPH: the
    /// stable step vanished; PBF: statistics that came back show a
    /// non-finite state or a diverged solve).
    pub fn advance(&mut self, world: &World, frame_dt: f64) -> Result<GpuStep, AppError> {
        let step = match &mut self.stepper {
            Stepper::Pbf(pbf) => {
                let frame = pbf.advance(&self.device, &self.queue, frame_dt as f32)?;
                GpuStep {
                    solver: SolverKind::Pbf,
                    substeps: frame.substeps,
                    iterations: frame.iterations,
                    late: frame.stats,
                }
            }
            Stepper::Wcsph { solver, batch } => {
                // A frame longer than the largest batch takes several.
                let with_margin = |substeps: u32| {
                    (substeps.saturating_add(substeps / 4 + 1)).min(sph_gpu::MAX_BATCH)
                };
                if *batch == 0 {
                    let substeps = (frame_dt / f64::from(world.stable_dt())).ceil();
                    *batch = with_margin(substeps.clamp(1.0, 1e4) as u32);
                }
                let frame = solver.advance(&self.device, &self.queue, frame_dt as f32, *batch)?;
                *batch = with_margin(frame.substeps);
                GpuStep {
                    solver: SolverKind::Wcsph,
                    substeps: frame.substeps,
                    iterations: 0,
                    late: Vec::new(),
                }
            }
        };
        self.time += frame_dt;
        Ok(step)
    }

    /// The push the solver applies from its next frame (the demo's
    /// Ctrl+drag).
    ///
    /// # Errors
    /// [`AppError::Gpu`] for a push that is not finite.
    pub fn set_push(&mut self, push: Option<sph_gpu::RayPush>) -> Result<(), AppError> {
        match &mut self.stepper {
            Stepper::Pbf(pbf) => Ok(pbf.set_push(push)?),
            Stepper::Wcsph { solver, .. } => Ok(solver.set_push(push)?),
        }
    }

    /// Waits for the GPU and returns the PBF statistics still on their way,
    /// oldest first (none for WCSPH).
    ///
    /// # Errors
    /// As [`GpuSim::advance`].
    pub fn finish(&mut self) -> Result<Vec<PbfFrameStats>, AppError> {
        Ok(match &mut self.stepper {
            Stepper::Pbf(pbf) => pbf.finish(&self.device)?,
            Stepper::Wcsph { .. } => Vec::new(),
        })
    }

    /// The GPU's positions, velocities, densities and pressures (waits for
    /// the device).
    ///
    /// # Errors
    /// [`AppError::Gpu`] on a readback failure.
    pub fn read_state(&self) -> Result<GpuState, AppError> {
        Ok(match &self.stepper {
            Stepper::Pbf(pbf) => pbf.read_state(&self.device, &self.queue)?,
            Stepper::Wcsph { solver, .. } => solver.read_state(&self.device, &self.queue)?,
        })
    }

    /// Writes the GPU's positions, velocities, densities and pressures into
    /// `world.particles` (the same particles, in the order they were uploaded).
    ///
    /// # Errors
    /// [`AppError::Gpu`] on a readback failure or a non-finite state.
    pub fn read_into(&self, world: &mut World) -> Result<(), AppError> {
        let state = self.read_state()?;
        if let Some(i) = (0..state.positions.len())
            .find(|&i| !state.positions[i].is_finite() || !state.velocities[i].is_finite())
        {
            let steps = match &self.stepper {
                Stepper::Pbf(pbf) => pbf.substeps(),
                Stepper::Wcsph { solver, .. } => solver.steps(),
            };
            return Err(AppError::Gpu(format!(
                "particle {i} is not finite after {steps} GPU steps: lower the time step"
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
