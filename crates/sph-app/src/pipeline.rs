//! One frame of the demo: scene → simulate → extract → (render), with timings.

use std::time::Instant;

use glam::Vec3;
use sph_core::{Scene, World};
use splat_render::{Camera, GpuContext, Shading, Splat, SplatRenderer};
use surfel_extract::{ExtractParams, Extractor, Surfel};

use crate::error::AppError;
use crate::gpu_extract::GpuExtract;
use crate::gpu_sim::GpuSim;
use crate::playback::Playback;

/// What one frame did (a row of `frames.csv`, the stats panel).
#[derive(Debug, Clone, Copy, Default)]
pub struct FrameStats {
    /// Frames completed.
    pub frame: u64,
    /// Simulated time (s).
    pub time: f64,
    /// Particles.
    pub particles: usize,
    /// Surfels.
    pub surfels: usize,
    /// Field evaluations of the extraction (particles + surfels).
    pub evaluations: u64,
    /// The solver that took the frame's steps.
    pub solver: sph_core::SolverKind,
    /// Solver substeps of the frame.
    pub substeps: u32,
    /// Constraint (PBF) or density-solve (DFSPH) iterations of the frame,
    /// all substeps (0 for WCSPH).
    pub iterations: u32,
    /// Average density error max(ρ/ρ0 − 1, 0) of the frame
    /// ([`sph_core::FrameReport::density_error_avg`]); NaN where WCSPH
    /// stepped on the GPU (it reports no densities per frame), and while
    /// [`Self::pending`].
    pub density_error_avg: f32,
    /// Largest density error ρ/ρ0 − 1 of the frame; NaN as the average.
    pub density_error_max: f32,
    /// Particles the solver's guard slowed in the frame (PBF).
    pub clamped: u64,
    /// The density errors and clamps of this frame are still on their way
    /// back from the GPU (PBF on the GPU): they arrive a frame or two later
    /// as [`LateStats`] ([`Pipeline::take_late`]).
    pub pending: bool,
    /// Divergence-solve iterations of the frame, all substeps (DFSPH).
    pub divergence_iterations: u32,
    /// Implicit-viscosity CG iterations of the frame, all substeps (DFSPH).
    pub viscosity_iterations: u32,
    /// Solves that stopped at their iteration limit above their tolerance
    /// (DFSPH).
    pub unconverged: u32,
    /// Simulation wall time (ms).
    pub step_ms: f64,
    /// Extraction wall time (ms).
    pub extract_ms: f64,
    /// Rendering wall time (ms), filled in by the caller.
    pub render_ms: f64,
}

/// A GPU frame's statistics that came back after the frame
/// ([`FrameStats::pending`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LateStats {
    /// The frame they belong to ([`FrameStats::frame`]).
    pub frame: u64,
    /// Its average density error max(ρ/ρ0 − 1, 0).
    pub density_error_avg: f32,
    /// Its largest density error.
    pub density_error_max: f32,
    /// Particles its guard slowed.
    pub clamped: u64,
}

/// The scene being shown, its world, and the last extracted surfels.
pub struct Pipeline {
    /// Scene name (built-in name or file path).
    pub name: String,
    /// The scene as loaded (used by reset).
    pub scene: Scene,
    /// The simulation. While the SPH step runs on the GPU its particles lag
    /// behind the GPU's: [`Pipeline::particles`] reads them.
    pub world: World,
    /// Extraction parameters.
    pub extract: ExtractParams,
    /// The CPU extractor, its memory kept from frame to frame, and the last
    /// surfels it extracted (none while they are extracted on the GPU).
    extractor: Extractor,
    /// Whether the surfels belong to the current particles.
    extracted: bool,
    /// The last frame's stats.
    pub stats: FrameStats,
    /// The GPU solver when `--gpu-sim` (or the panel) switched it on.
    pub gpu: Option<GpuSim>,
    /// The GPU extractor when `--gpu-extract` (or the panel) switched it on.
    pub gpu_extract: Option<GpuExtract>,
    /// Simulated time spent on the GPU path (s): the world's clock does not see it.
    gpu_time: f64,
    /// The GPU solver has stepped past `world.particles`.
    gpu_ahead: bool,
    /// [`FrameStats::frame`] when the GPU solver started: its frame k is
    /// the pipeline's frame `gpu_start + k + 1`.
    gpu_start: u64,
    /// Statistics of GPU frames that came back, not yet taken.
    late: Vec<LateStats>,
    /// The newest statistics that came back from the GPU (the panel shows
    /// them while a frame's own are pending).
    pub latest_late: Option<LateStats>,
    /// Particle files played instead of the simulation (`--input`): each
    /// frame replaces the world's particles by the next file's.
    pub playback: Option<Playback>,
}

impl Pipeline {
    /// Builds the world of `scene`, extracting with `iterations` refinement iterations.
    pub fn new(name: String, scene: Scene, iterations: u32) -> Result<Self, AppError> {
        let world = scene.build_world().map_err(|source| AppError::Scene {
            scene: name.clone(),
            source,
        })?;
        Ok(Self::with_world(name, scene, world, iterations))
    }

    /// The pipeline of `world`, built from `scene`.
    fn with_world(name: String, scene: Scene, world: World, iterations: u32) -> Self {
        let extract = ExtractParams {
            iterations,
            ..ExtractParams::new(world.params().h)
        };
        let mut p = Self {
            name,
            scene,
            world,
            extract,
            extractor: Extractor::new(),
            extracted: false,
            stats: FrameStats::default(),
            gpu: None,
            gpu_extract: None,
            gpu_time: 0.0,
            gpu_ahead: false,
            gpu_start: 0,
            late: Vec::new(),
            latest_late: None,
            playback: None,
        };
        p.stats.particles = p.world.particles.len();
        p
    }

    /// Plays `playback`'s files, starting from `particles` (its first file)
    /// in `scene` (its domain and camera), extracting with `iterations`
    /// refinement iterations.
    ///
    /// # Errors
    /// [`AppError::Scene`] where the particles do not make a world.
    pub fn playback(
        name: String,
        scene: Scene,
        particles: sph_core::Particles,
        playback: Playback,
        iterations: u32,
    ) -> Result<Self, AppError> {
        // The world only holds the particles for the extraction: it is
        // never stepped, so the scene needs no fluid of its own.
        let world = World::with_solver(
            particles,
            scene.fluid_params(),
            scene.boundary(),
            sph_core::TimeStepping::default(),
            scene.solver(),
        )
        .map_err(|source| AppError::Scene {
            scene: name.clone(),
            source,
        })?;
        let mut p = Self::with_world(name, scene, world, iterations);
        p.playback = Some(playback);
        Ok(p)
    }

    /// Back to the scene's initial state (a playback's first file).
    pub fn reset(&mut self) -> Result<(), AppError> {
        if let Some(playback) = self.playback.as_mut() {
            playback.rewind();
            let (particles, _) = playback.next_frame()?;
            self.world.particles = particles;
            self.extracted = false;
            self.stats = FrameStats {
                particles: self.world.particles.len(),
                ..Default::default()
            };
            return Ok(());
        }
        self.world = self.scene.build_world()?;
        self.gpu_time = 0.0;
        self.gpu_ahead = false;
        // The old run's statistics belong to frames before the reset.
        self.late.clear();
        self.latest_late = None;
        self.gpu_start = 0;
        if let Some(gpu) = &self.gpu {
            self.gpu = Some(gpu.restart(&self.world, &self.scene)?);
        }
        self.extractor.clear(); // stale: the next frame extracts again
        self.extracted = false;
        self.stats = FrameStats {
            particles: self.world.particles.len(),
            ..Default::default()
        };
        Ok(())
    }

    /// Runs the SPH step on the GPU of `ctx` from the current particles
    /// (`Some`), or back on the CPU from the GPU's last state (`None`).
    ///
    /// # Errors
    /// [`AppError::Gpu`] where the GPU path does not support the scene, or on a
    /// readback failure.
    pub fn set_gpu_sim(&mut self, ctx: Option<&GpuContext>) -> Result<(), AppError> {
        self.finish_gpu()?;
        self.sync_world()?;
        self.gpu = ctx
            .map(|ctx| GpuSim::new(ctx, &self.world, &self.scene))
            .transpose()?;
        self.gpu_start = self.stats.frame;
        Ok(())
    }

    /// The push the GPU solver applies from its next frame (`None`: none);
    /// a no-op on the CPU path, whose push is a processor of the world.
    ///
    /// # Errors
    /// [`AppError::Gpu`] for a push that is not finite.
    pub fn set_gpu_push(&mut self, push: Option<sph_gpu::RayPush>) -> Result<(), AppError> {
        match self.gpu.as_mut() {
            Some(gpu) => gpu.set_push(push),
            None => Ok(()),
        }
    }

    /// Waits for the GPU solver and collects the statistics still on their
    /// way ([`take_late`](Self::take_late) returns them).
    ///
    /// # Errors
    /// [`AppError::Gpu`] where they show a failed frame.
    pub fn finish_gpu(&mut self) -> Result<(), AppError> {
        if let Some(gpu) = self.gpu.as_mut() {
            let late = gpu.finish()?;
            self.add_late(late);
        }
        Ok(())
    }

    /// The statistics of GPU frames that came back since the last call,
    /// oldest first.
    pub fn take_late(&mut self) -> Vec<LateStats> {
        std::mem::take(&mut self.late)
    }

    fn add_late(&mut self, stats: Vec<sph_gpu::PbfFrameStats>) {
        for s in stats {
            let late = LateStats {
                frame: self.gpu_start + s.frame + 1,
                density_error_avg: s.density_error_avg,
                density_error_max: s.density_error_max,
                clamped: s.clamped,
            };
            self.latest_late = Some(late);
            self.late.push(late);
        }
    }

    /// Extracts on the GPU of `ctx` (`Some`, thesis mode) or on the CPU (`None`).
    ///
    /// # Errors
    /// [`AppError::Gpu`] where the GPU path rejects the parameters.
    pub fn set_gpu_extract(&mut self, ctx: Option<&GpuContext>) -> Result<(), AppError> {
        self.gpu_extract = ctx
            .map(|ctx| GpuExtract::new(ctx, &self.world, &self.extract))
            .transpose()?;
        self.extracted = false;
        Ok(())
    }

    /// Extracts only the surfels facing an eye at `eye` (thesis 4.2.1: only
    /// front-facing surfels are added), or every surfel for `None`; a new eye
    /// marks the surfels for re-extraction.
    ///
    /// # Errors
    /// [`AppError::Gpu`] for a non-finite eye with GPU extraction on (on the
    /// CPU, the next extraction reports it).
    pub fn set_viewpoint(&mut self, eye: Option<Vec3>) -> Result<(), AppError> {
        if self.extract.camera == eye {
            return Ok(());
        }
        if let Some(gpu) = self.gpu_extract.as_mut() {
            gpu.set_camera(eye)?;
        }
        self.extract.camera = eye;
        self.extracted = false;
        Ok(())
    }

    /// Marks the surfels for re-extraction after [`Pipeline::extract`]
    /// changed (even while paused), and rebuilds the GPU extractor, when it
    /// runs, for the new parameters (it copies them when built).
    ///
    /// # Errors
    /// [`AppError::Gpu`] for parameters the GPU path rejects.
    pub fn extract_params_changed(&mut self, ctx: &GpuContext) -> Result<(), AppError> {
        self.extracted = false;
        if self.gpu_extract.is_some() {
            self.set_gpu_extract(Some(ctx))?;
        }
        Ok(())
    }

    /// The current particles on the CPU: the world's, or, while the GPU
    /// solver runs (it owns them then), a copy read back from it when it has
    /// stepped since the last copy. Everything on the CPU that needs the
    /// particles (the CPU extraction, exports, the particles view, a world
    /// rebuilt after a parameter change) takes them here.
    ///
    /// # Errors
    /// [`AppError::Gpu`] on a readback failure or a non-finite state.
    pub fn particles(&mut self) -> Result<&sph_core::Particles, AppError> {
        self.sync_world()?;
        Ok(&self.world.particles)
    }

    /// Reads the GPU solver's particles back into `world` if it has stepped
    /// past them (a no-op on the CPU path, or when they are up to date).
    fn sync_world(&mut self) -> Result<(), AppError> {
        if let (true, Some(gpu)) = (self.gpu_ahead, &self.gpu) {
            gpu.read_into(&mut self.world)?;
        }
        self.gpu_ahead = false;
        Ok(())
    }

    /// Whether the surfels are stale (particles moved, reset, mode switched).
    pub fn needs_extraction(&self) -> bool {
        !self.extracted
    }

    /// Advances the simulation by `frame_dt` seconds (on the GPU solver when
    /// it runs) and marks the surfels for re-extraction.
    pub fn advance(&mut self, frame_dt: f64) -> Result<(), AppError> {
        let start = Instant::now();
        if let Some(playback) = self.playback.as_mut() {
            let (particles, time) = playback.next_frame()?;
            self.world.particles = particles;
            self.stats = FrameStats {
                frame: self.stats.frame + 1,
                time,
                particles: self.world.particles.len(),
                step_ms: start.elapsed().as_secs_f64() * 1e3,
                // No solver ran: no density errors to report.
                density_error_avg: f32::NAN,
                density_error_max: f32::NAN,
                ..Default::default()
            };
            self.extracted = false;
            return Ok(());
        }
        let s = &mut self.stats;
        match self.gpu.as_mut() {
            Some(gpu) => {
                let step = gpu.advance(&self.world, frame_dt)?;
                self.gpu_time += frame_dt;
                self.gpu_ahead = true;
                // PBF's density errors and clamps come later (`take_late`);
                // WCSPH on the GPU reports none.
                *s = FrameStats {
                    solver: step.solver,
                    substeps: step.substeps,
                    iterations: step.iterations,
                    density_error_avg: f32::NAN,
                    density_error_max: f32::NAN,
                    clamped: 0,
                    pending: step.solver == sph_core::SolverKind::Pbf,
                    divergence_iterations: 0,
                    viscosity_iterations: 0,
                    unconverged: 0,
                    time: self.world.time() + self.gpu_time,
                    ..*s
                };
                self.add_late(step.late);
            }
            None => {
                let r = self.world.advance(frame_dt as f32)?;
                *s = FrameStats {
                    solver: r.solver,
                    substeps: r.substeps,
                    iterations: r.iterations,
                    density_error_avg: r.density_error_avg,
                    density_error_max: r.density_error_max,
                    clamped: r.clamped,
                    pending: false,
                    divergence_iterations: r.divergence_iterations,
                    viscosity_iterations: r.viscosity_iterations,
                    unconverged: r.unconverged,
                    time: r.time + self.gpu_time,
                    ..*s
                };
            }
        }
        self.stats.step_ms = start.elapsed().as_secs_f64() * 1e3;
        self.stats.frame += 1;
        self.stats.particles = self.world.particles.len();
        self.extracted = false;
        Ok(())
    }

    /// Extracts the surfels of the current particles, on the GPU when
    /// [`set_gpu_extract`](Self::set_gpu_extract) switched it on (the time then
    /// includes waiting for the GPU).
    pub fn extract_surfels(&mut self) -> Result<(), AppError> {
        let start = Instant::now();
        if let Some(gpu) = self.gpu_extract.as_mut() {
            let solver = self.gpu.as_ref().map(GpuSim::particles);
            let stats = gpu.run(&self.world, solver)?;
            self.stats.surfels = stats.surfels;
            self.stats.evaluations = stats.evaluations + stats.particle_evaluations;
            self.extractor.clear();
        } else {
            self.sync_world()?;
            let out = (self.extractor).extract(&self.world.particles, &self.extract)?;
            self.stats.surfels = out.surfels.len();
            self.stats.evaluations = out.stats.evaluations + out.stats.particle_evaluations;
        }
        self.stats.extract_ms = start.elapsed().as_secs_f64() * 1e3;
        self.extracted = true;
        Ok(())
    }

    /// Puts the last surfels in `renderer`: uploaded, or drawn from the GPU
    /// extractor's buffer.
    ///
    /// # Errors
    /// [`AppError::Render`] for an invalid surfel.
    pub fn show_surfels(
        &self,
        ctx: &GpuContext,
        renderer: &mut SplatRenderer,
    ) -> Result<(), AppError> {
        match &self.gpu_extract {
            Some(gpu) => gpu.show(ctx, renderer),
            None => Ok(renderer.upload(ctx, &self.splats())?),
        }
    }

    /// The last surfels on the CPU (read back from the GPU extractor).
    ///
    /// # Errors
    /// [`AppError::Gpu`] on a readback failure.
    pub fn surfels_on_cpu(&self) -> Result<std::borrow::Cow<'_, [Surfel]>, AppError> {
        Ok(match &self.gpu_extract {
            Some(gpu) => gpu.read_surfels()?.into(),
            None => self.extractor.surfels().surfels.as_slice().into(),
        })
    }

    /// The surfels as splats.
    pub fn splats(&self) -> Vec<Splat> {
        self.extractor
            .surfels()
            .surfels
            .iter()
            .map(|s| Splat::new(s.position, s.normal, s.radius))
            .collect()
    }

    /// The particles as small discs facing `eye` (the "particles" debug view),
    /// read back from the GPU solver first if it runs.
    ///
    /// # Errors
    /// As [`Pipeline::particles`].
    pub fn particle_splats(&mut self, eye: Vec3) -> Result<Vec<Splat>, AppError> {
        let r = 0.5 * self.scene.spacing;
        Ok(self
            .particles()?
            .positions()
            .iter()
            .map(|&x| Splat::new(x, (eye - x).try_normalize().unwrap_or(Vec3::Y), r))
            .collect())
    }

    /// The scene's camera hint.
    pub fn camera(&self) -> Camera {
        let r = &self.scene.render;
        Camera {
            fov_y: r.fov_y.to_radians(),
            ..Camera::looking_at(Vec3::from(r.camera), Vec3::from(r.look_at))
        }
        .with_planes_for_distance()
    }

    /// The demo's water scaled to the scene ([`Shading::water`]).
    pub fn shading(&self) -> Shading {
        Shading::water(self.world.params().h)
    }

    /// The tank, obstacles and ground drawn around the fluid
    /// ([`crate::scenery::scenery`]).
    ///
    /// # Errors
    /// As [`crate::scenery::scenery`].
    pub fn scenery(&self) -> Result<splat_render::SceneGeometry, AppError> {
        match self.playback {
            // Nothing is known of another simulator's tank: the ground only.
            Some(_) => crate::scenery::ground(&self.scene),
            None => crate::scenery::scenery(&self.scene),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// With the step and the extraction on the GPU, frames read no particle
    /// back; whatever needs them on the CPU gets the GPU's current state.
    #[test]
    fn gpu_frames_leave_the_particles_on_the_gpu_until_needed() {
        let Some(ctx) = GpuContext::headless_or_skip() else {
            return;
        };
        for kind in [sph_core::SolverKind::Wcsph, sph_core::SolverKind::Pbf] {
            gpu_frames_leave_the_particles(ctx, kind);
        }
    }

    fn gpu_frames_leave_the_particles(ctx: &GpuContext, kind: sph_core::SolverKind) {
        let scene = Scene::dam_break(0.2, 0.06, 0.02).with_solver(kind);
        let mut p = Pipeline::new("dam".into(), scene, 2).unwrap();
        let start = p.world.particles.positions().to_vec();
        p.set_gpu_sim(Some(ctx)).unwrap();
        p.set_gpu_extract(Some(ctx)).unwrap();
        let gpu_positions = |p: &Pipeline| p.gpu.as_ref().unwrap().read_state().unwrap().positions;
        for _ in 0..3 {
            p.advance(1.0 / 60.0).unwrap();
            p.extract_surfels().unwrap();
        }
        assert!(p.stats.surfels > 0);
        assert_eq!(p.stats.solver, kind);
        assert_eq!(p.world.particles.positions(), &start[..], "read back");
        let moved = gpu_positions(&p)
            .iter()
            .zip(&start)
            .map(|(a, b)| (*a - *b).length())
            .fold(0f32, f32::max);
        assert!(moved > 1e-4, "the fluid did not move on the GPU: {moved}");

        // The particles view reads the current state.
        let discs = p.particle_splats(Vec3::new(0.0, 0.5, 2.0)).unwrap();
        assert_eq!(discs.len(), start.len());
        assert_eq!(p.world.particles.positions(), &gpu_positions(&p)[..]);

        // CPU extraction of a GPU-simulated frame sees that frame.
        p.set_gpu_extract(None).unwrap();
        p.advance(1.0 / 60.0).unwrap();
        p.extract_surfels().unwrap();
        assert_eq!(p.world.particles.positions(), &gpu_positions(&p)[..]);
        assert_eq!(p.stats.surfels, p.surfels_on_cpu().unwrap().len());

        // Back on the CPU, the world continues from the GPU's last state.
        p.advance(1.0 / 60.0).unwrap();
        let last = gpu_positions(&p);
        p.set_gpu_sim(None).unwrap();
        assert_eq!(p.world.particles.positions(), &last[..]);
        p.advance(1.0 / 60.0).unwrap();
        assert_ne!(p.world.particles.positions(), &last[..]);
    }

    /// Changing the extraction parameters re-extracts without a simulation
    /// step (as while paused), on the CPU and on the GPU, with the new
    /// parameters: one iteration gives fewer surfels than two.
    #[test]
    fn new_extraction_parameters_apply_without_a_step() {
        let Some(ctx) = GpuContext::headless_or_skip() else {
            return;
        };
        let scene = Scene::dam_break(0.2, 0.06, 0.02);
        for gpu in [false, true] {
            let mut p = Pipeline::new("dam".into(), scene.clone(), 2).unwrap();
            p.set_gpu_extract(gpu.then_some(ctx)).unwrap();
            p.extract_surfels().unwrap();
            let two = p.stats.surfels;
            assert!(!p.needs_extraction());
            p.extract.iterations = 1;
            p.extract_params_changed(ctx).unwrap();
            assert!(p.needs_extraction());
            p.extract_surfels().unwrap();
            let one = p.stats.surfels;
            assert!(0 < one && one < two, "GPU {gpu}: {one} vs {two} surfels");
        }
    }

    /// With a viewpoint, only surfels facing it are extracted, on the CPU and
    /// on the GPU: fewer of them, every one front-facing; a new eye
    /// re-extracts without a step, and `None` brings every surfel back.
    #[test]
    fn a_viewpoint_culls_back_facing_surfels() {
        let Some(ctx) = GpuContext::headless_or_skip() else {
            return;
        };
        let scene = Scene::dam_break(0.2, 0.2, 0.02);
        let eye = scene.render.camera.into();
        for gpu in [false, true] {
            let mut p = Pipeline::new("dam".into(), scene.clone(), 2).unwrap();
            p.set_gpu_extract(gpu.then_some(ctx)).unwrap();
            p.extract_surfels().unwrap();
            let all = p.stats.surfels;
            p.set_viewpoint(Some(eye)).unwrap();
            assert!(p.needs_extraction());
            p.extract_surfels().unwrap();
            let front = p.surfels_on_cpu().unwrap();
            assert_eq!(front.len(), p.stats.surfels);
            assert!(
                front.iter().all(|s| (eye - s.position).dot(s.normal) > 0.0),
                "GPU {gpu}: a back-facing surfel"
            );
            println!(
                "GPU {gpu}: {} of {all} surfels face the camera",
                front.len()
            );
            assert!(
                front.len() < 3 * all / 4,
                "GPU {gpu}: {} of {all} surfels kept",
                front.len()
            );
            p.set_viewpoint(None).unwrap();
            p.extract_surfels().unwrap();
            assert_eq!(p.stats.surfels, all, "GPU {gpu}");
        }
    }
}
