//! [`GpuSolver`]: sph-core's default program (grid → density/pressure → forces
//! → integrate → walls) as compute passes, particles resident on the GPU.

use bytemuck::{Pod, Zeroable};
use glam::Vec3;
use sph_core::boundary::WallKernel;
use sph_core::solver::MAX_H_OVER_SPACING;
use sph_core::{Boundary, FluidParams, Particles, PressureKernel, TimeStepping};
use wgpu::util::DeviceExt;
use wgpu_profiler::GpuProfiler;

use crate::density::GpuDensity;
use crate::grid::{GpuError, GpuGrid};
use crate::passes::{
    Groups, PassStage, Staging, compute_pass, compute_pass_with, read_vec3s, staged_pass,
    timed_pass,
};
use crate::push::{RayPush, push_uniforms};

/// WGSL of [`Params`], prepended to the forces and integrate shaders.
const PARAMS: &str = include_str!("shaders/solver_params.wgsl");

/// WGSL of the boundary's walls and obstacles, prepended after [`PARAMS`].
pub(crate) const WALLS: &str = include_str!("shaders/walls.wgsl");

/// WGSL of `RayPush::acceleration_at`, after a uniform `f` with the push.
pub(crate) const PUSH: &str = include_str!("shaders/push.wgsl");

/// WGSL of the boundary's projection (`Boundary::resolve`), after [`WALLS`].
pub(crate) const RESOLVE: &str = include_str!("shaders/resolve.wgsl");

/// The grid's cell hash (`shaders/hash.wgsl`), for passes that walk cells.
pub(crate) const HASH: &str = include_str!("shaders/hash.wgsl");

/// Mirrors `struct Params` in `shaders/solver_params.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct Params {
    h: f32,
    inv_h: f32,
    n: u32,
    table: u32,
    rest_density: f32,
    viscosity: f32,
    surface_tension: f32,
    surface_threshold: f32,
    gravity: [f32; 4],
    domain_min: [f32; 4],
    domain_max: [f32; 4],
    poly6_grad: f32,
    visc_lap: f32,
    spiky_grad: f32,
    spiky_pressure: u32,
    dt: f32,
    restitution: f32,
    cfl: f32,
    force_factor: f32,
    max_dt: f32,
    min_dt: f32,
    sound_speed: f32,
    frame_dt: f32,
    push_origin: [f32; 4],
    push_dir: [f32; 4],
    push_accel: [f32; 4],
    layers: [f32; 4],
}

/// Under a clearance, the walls' layers of the lattice of the lightest of
/// `masses` (sph-core's `WallKernel::lattice_layers`) as the shaders'
/// `layers` (spacing, thickness, 0, 0); zeros without a clearance or a
/// particle, where `walls.wgsl` takes the half-space.
pub(crate) fn wall_layers(params: &FluidParams, boundary: &Boundary, masses: &[f32]) -> [f32; 4] {
    let lightest = masses.iter().copied().fold(f32::INFINITY, f32::min);
    if boundary.clearance <= 0.0 || !lightest.is_finite() {
        return [0.0; 4];
    }
    let layers = WallKernel::new(params.h).lattice_layers(lightest, params.rest_density);
    // Layers thinner than h/20 are the continuous half-space, as on the
    // CPU (`WallKernel::layers_fraction_and_density`): the shader sums them
    // one by one, and at a spacing below an ulp of h it would never end.
    if !(layers.spacing > 0.0 && params.h / layers.spacing <= 2.0 * MAX_H_OVER_SPACING) {
        return [0.0; 4];
    }
    [layers.spacing, layers.thickness, 0.0, 0.0]
}

/// The most steps [`GpuSolver::advance`] records in one batch: each is
/// a handful of dispatches held in the encoder until it is submitted, so a
/// batch of billions would exhaust memory before it ran. A frame longer
/// than a batch takes several.
pub const MAX_BATCH: u32 = 1 << 16;

/// Mirrors `struct StepState` in `shaders/timestep.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
struct StepState {
    v_max: u32,
    a_max: u32,
    dt: f32,
    elapsed: f32,
    steps: u32,
    unstable: u32,
    pad: [u32; 2],
}

/// What [`GpuSolver::advance`] did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GpuFrame {
    /// Steps taken (each of the adaptive length chosen on the GPU).
    pub substeps: u32,
    /// Simulated time advanced (s).
    pub elapsed: f32,
}

/// The particle state read back from the GPU.
#[derive(Debug, Clone, Default)]
pub struct GpuState {
    /// Positions.
    pub positions: Vec<Vec3>,
    /// Velocities.
    pub velocities: Vec<Vec3>,
    /// Densities of the last step.
    pub densities: Vec<f32>,
    /// Pressures of the last step.
    pub pressures: Vec<f32>,
}

/// The SPH step on the GPU with the same equations and parameters as
/// `sph_core::solver::default_program`: domain walls and obstacles (boxes,
/// spheres) included; emitters and sinks stay on the CPU path. The GPU
/// solver never reorders its particles: index i of its state is particle i
/// of the `Particles` it was built from. The CPU `World` sorts its
/// particles by cell, so match the two by `Particles::ids` (the original
/// index, for particles built in order).
pub struct GpuSolver {
    params: Params,
    /// [`FluidParams::viscous_dt`]: the adaptive step's `max_dt` is at most this.
    viscous_dt: f32,
    grid: GpuGrid,
    density: GpuDensity,
    uniform: wgpu::Buffer,
    velocities: wgpu::Buffer,
    state: wgpu::Buffer,
    /// Indirect workgroup counts of a step's passes, `[x, y, z]` each: the
    /// grid build's three kinds ([`GpuGrid::build_groups`]) then the
    /// per-particle passes' groups of 64. The first four triples are live,
    /// the last four hold the full counts; `choose_dt` copies them to the
    /// live ones while there is a step to take and zeros after, so steps
    /// recorded past a frame's end dispatch nothing.
    gate: wgpu::Buffer,
    /// The full counts, written to the live triples when a frame starts.
    gate_full: [u32; 12],
    /// Where `advance` reads the step state back after each batch.
    state_readback: Staging,
    reduce: (wgpu::ComputePipeline, wgpu::BindGroup),
    choose: (wgpu::ComputePipeline, wgpu::BindGroup),
    forces: (wgpu::ComputePipeline, wgpu::BindGroup),
    integrate: (wgpu::ComputePipeline, wgpu::BindGroup),
    steps: u64,
}

impl GpuSolver {
    /// Uploads `particles` (positions, velocities, masses) and prepares the passes.
    ///
    /// # Errors
    /// [`GpuError::Params`] for particles (`Particles::validate`, a mass too
    /// light for h, a position the boundary does not admit), parameters or
    /// a boundary sph-core rejects (its reason: `World::check_inputs`, as
    /// `World::with_solver` refuses them);
    /// [`GpuError::Invalid`] for Akinci et al.'s surface
    /// tension (which the GPU's PBF runs, its WCSPH not);
    /// [`GpuError::DeviceLimit`] for
    /// more particles than one dispatch or storage binding of this device
    /// holds.
    pub fn new(
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        particles: &Particles,
        params: &FluidParams,
        boundary: &Boundary,
    ) -> Result<Self, GpuError> {
        sph_core::World::check_inputs(particles, params, boundary).map_err(GpuError::Params)?;
        if params.surface_tension > 0.0
            && params.surface_tension_model == Some(sph_core::SurfaceTensionModel::Akinci)
        {
            return Err(GpuError::Invalid(
                "fluid.surface_tension_model = \"akinci\" under WCSPH runs only on the CPU: the \
                 GPU's WCSPH applies the thesis's colour-field force (its PBF applies Akinci's); \
                 leave the model out, or choose kind = \"pbf\"",
            ));
        }
        let n = particles.len();
        let capacity = n.max(1);
        let mut grid = GpuGrid::new(device, capacity, params.h, 1)?;
        grid.upload_with_masses(queue, particles.positions(), Some(particles.masses()))?;
        let density = GpuDensity::new(
            device,
            &grid,
            capacity,
            params,
            boundary,
            particles.masses(),
        )?;
        let vec4s = |label, data: &[Vec3]| {
            let buffer = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: (16 * capacity) as u64,
                usage: wgpu::BufferUsages::STORAGE
                    | wgpu::BufferUsages::COPY_DST
                    | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            });
            let v: Vec<[f32; 4]> = data.iter().map(|v| v.extend(0.0).to_array()).collect();
            if !v.is_empty() {
                queue.write_buffer(&buffer, 0, bytemuck::cast_slice(&v));
            }
            buffer
        };
        let velocities = vec4s("velocities", particles.velocities());
        let accelerations = vec4s("accelerations", &vec![Vec3::ZERO; n]);
        let h = params.h;
        let pi = std::f32::consts::PI;
        let p = Params {
            h,
            inv_h: 1.0 / h,
            n: n as u32,
            table: grid.table_size(),
            rest_density: params.rest_density,
            viscosity: params.viscosity,
            surface_tension: params.surface_tension,
            surface_threshold: params.surface_threshold,
            gravity: params.gravity.extend(0.0).to_array(),
            domain_min: boundary.domain.min.extend(boundary.clearance).to_array(),
            domain_max: boundary.domain.max.extend(0.0).to_array(),
            poly6_grad: 945.0 / (32.0 * pi * h.powi(9)),
            visc_lap: 45.0 / (pi * h.powi(6)),
            spiky_grad: 45.0 / (pi * h.powi(6)),
            spiky_pressure: u32::from(params.pressure_kernel == PressureKernel::Spiky),
            dt: 0.0,
            restitution: boundary.restitution,
            cfl: 0.0,
            force_factor: 0.0,
            max_dt: 0.0,
            min_dt: 0.0,
            sound_speed: params.sound_speed(),
            frame_dt: 0.0,
            push_origin: [0.0; 4],
            push_dir: [0.0; 4],
            push_accel: [0.0; 4],
            layers: wall_layers(params, boundary, particles.masses()),
        };
        let uniform = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("solver params"),
            size: size_of::<Params>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let hash = HASH;
        let forces = compute_pass(
            device,
            "forces",
            format!(
                "{hash}{PARAMS}{WALLS}{PUSH}{}",
                include_str!("shaders/forces.wgsl")
            ),
            &[
                &uniform,
                grid.positions_buffer(),
                grid.counts_buffer(),
                grid.starts_buffer(),
                grid.sorted_buffer(),
                density.densities_buffer(),
                density.pressures_buffer(),
                &velocities,
                &accelerations,
                density.obstacles_buffer(),
            ],
        );
        let state = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("step state"),
            size: size_of::<StepState>() as u64,
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_DST
                | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let timestep = format!("{PARAMS}{}", include_str!("shaders/timestep.wgsl"));
        let reduce = compute_pass(
            device,
            "reduce_max",
            timestep.clone(),
            &[&uniform, &velocities, &accelerations, &state],
        );
        let gate_full: [u32; 12] = {
            let [buckets, particles, one] = grid.build_groups();
            let per_particle = n.div_ceil(64).max(1) as u32;
            [buckets, particles, one, per_particle]
                .map(|x| [x, 1, 1])
                .concat()
                .try_into()
                .expect("12")
        };
        let gate = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("step gate"),
            contents: bytemuck::cast_slice(&[gate_full, gate_full]),
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::INDIRECT
                | wgpu::BufferUsages::COPY_DST,
        });
        let choose = compute_pass_with(
            device,
            "choose_dt",
            timestep,
            &[(0, &uniform), (3, &state), (4, &gate)],
        );
        let integrate = compute_pass(
            device,
            "integrate",
            format!(
                "{PARAMS}{WALLS}{RESOLVE}{}",
                include_str!("shaders/integrate.wgsl")
            ),
            &[
                &uniform,
                grid.positions_buffer(),
                &velocities,
                &accelerations,
                density.obstacles_buffer(),
                &state,
            ],
        );
        let mut solver = Self {
            params: p,
            viscous_dt: params.viscous_dt(),
            grid,
            density,
            uniform,
            velocities,
            state,
            gate,
            gate_full,
            state_readback: Staging::new(device, size_of::<StepState>() as u64),
            reduce,
            choose,
            forces,
            integrate,
            steps: 0,
        };
        solver.set_time_stepping(&TimeStepping::default())?;
        // The densities and pressures of the particles as given, so that a
        // readback or an extraction before the first step sees them (the
        // buffers start zeroed: volumes m/0).
        let mut encoder = device.create_command_encoder(&Default::default());
        solver.grid.encode_build_gated(&mut encoder, None, None);
        solver.density.encode(queue, &mut encoder, &solver.grid)?;
        queue.submit([encoder.finish()]);
        Ok(solver)
    }

    /// The adaptive step's parameters (sph-core's defaults until set).
    ///
    /// # Errors
    /// [`GpuError::Params`] for parameters sph-core rejects (its reason).
    pub fn set_time_stepping(&mut self, stepping: &TimeStepping) -> Result<(), GpuError> {
        stepping.validate().map_err(GpuError::Params)?;
        if self.viscous_dt < stepping.min_dt {
            return Err(GpuError::Invalid(
                "the viscous step limit 0.125 h²ρ0/μ is below min_dt: lower μ or raise h",
            ));
        }
        self.params.cfl = stepping.cfl;
        self.params.force_factor = stepping.force_factor;
        // The viscous limit is constant: folded into the largest step, as
        // `World::stable_dt` takes it.
        self.params.max_dt = stepping.max_dt.min(self.viscous_dt);
        self.params.min_dt = stepping.min_dt;
        Ok(())
    }

    /// Pushes the fluid from the next step on (`None` stops): the field of
    /// [`RayPush::acceleration_at`] added after the forces.
    ///
    /// # Errors
    /// As [`crate::GpuPbf::set_push`].
    pub fn set_push(&mut self, push: Option<RayPush>) -> Result<(), GpuError> {
        let [origin, dir, accel] = push_uniforms(push)?;
        self.params.push_origin = origin;
        self.params.push_dir = dir;
        self.params.push_accel = accel;
        Ok(())
    }

    /// Number of particles.
    pub fn len(&self) -> usize {
        self.params.n as usize
    }

    /// Whether there are no particles.
    pub fn is_empty(&self) -> bool {
        self.params.n == 0
    }

    /// Steps taken.
    pub fn steps(&self) -> u64 {
        self.steps
    }

    /// Positions (xyz) and masses (w), `vec4<f32>` per particle: what a
    /// renderer can read without a round trip to the CPU.
    pub fn positions_buffer(&self) -> &wgpu::Buffer {
        self.grid.positions_buffer()
    }

    /// Densities of the last step (of the particles as given before the
    /// first), `f32` per particle.
    pub fn densities_buffer(&self) -> &wgpu::Buffer {
        self.density.densities_buffer()
    }

    /// Smoothing length.
    pub fn h(&self) -> f32 {
        self.params.h
    }

    /// Velocities, `vec4<f32>` per particle.
    pub fn velocities_buffer(&self) -> &wgpu::Buffer {
        &self.velocities
    }

    /// Takes one step of `dt` seconds (submitted; nothing read back).
    ///
    /// # Errors
    /// [`GpuError::Invalid`] for a `dt` that is not finite or is shorter
    /// than the time stepping's `min_dt`, the shortest step a run takes
    /// (`World::step` refuses it likewise).
    pub fn step(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        dt: f32,
    ) -> Result<(), GpuError> {
        self.step_timed(device, queue, dt, None)
    }

    /// [`step`](Self::step) with each of its compute passes timed by
    /// `profiler` (labelled "step length: choose_dt", "grid: …", "density",
    /// "forces", "integrate").
    /// The caller resolves the profiler's queries and ends its frame.
    ///
    /// # Errors
    /// As [`step`](Self::step).
    pub fn step_profiled(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        dt: f32,
        profiler: &GpuProfiler,
    ) -> Result<(), GpuError> {
        self.step_timed(device, queue, dt, Some(profiler))
    }

    fn step_timed(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        dt: f32,
        profiler: Option<&GpuProfiler>,
    ) -> Result<(), GpuError> {
        if !(dt.is_finite() && dt >= self.params.min_dt) {
            return Err(GpuError::Invalid(
                "dt must be finite and at least the time stepping's min_dt",
            ));
        }
        self.params.dt = dt;
        self.params.frame_dt = 0.0;
        queue.write_buffer(&self.uniform, 0, bytemuck::bytes_of(&self.params));
        let mut encoder = device.create_command_encoder(&Default::default());
        self.encode_step(&mut encoder, queue, profiler);
        queue.submit([encoder.finish()]);
        self.steps += 1;
        Ok(())
    }

    /// Records one step: its length (fixed, or chosen on the GPU from the
    /// largest speed and last acceleration), grid, density, forces, integrate.
    /// Every pass but `choose_dt` takes its workgroups from the gate, so a step
    /// whose length is 0 (past the frame's end, or unstable) does no work.
    fn encode_step(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        queue: &wgpu::Queue,
        profiler: Option<&GpuProfiler>,
    ) {
        let per_particle = Groups::Indirect(&self.gate, 36);
        let reduce = |pass: &mut wgpu::ComputePass<'_>| {
            pass.set_pipeline(&self.reduce.0);
            pass.set_bind_group(0, &self.reduce.1, &[]);
            per_particle.dispatch(pass);
        };
        let choose = |pass: &mut wgpu::ComputePass<'_>| {
            pass.set_pipeline(&self.choose.0);
            pass.set_bind_group(0, &self.choose.1, &[]);
            pass.dispatch_workgroups(1, 1, 1);
        };
        let adaptive: [PassStage<'_>; 2] = [
            ("step length: reduce_max", &reduce),
            ("step length: choose_dt", &choose),
        ];
        // A fixed step skips the reduction.
        let stages = if self.params.dt <= 0.0 {
            &adaptive[..]
        } else {
            &adaptive[1..]
        };
        staged_pass(encoder, profiler, "step length", stages);
        self.grid
            .encode_build_gated(encoder, Some(&self.gate), profiler);
        self.density
            .encode_with(queue, encoder, &self.grid, per_particle, profiler);
        for (label, (pipeline, bind_group)) in
            [("forces", &self.forces), ("integrate", &self.integrate)]
        {
            timed_pass(encoder, profiler, label, |pass| {
                pass.set_pipeline(pipeline);
                pass.set_bind_group(0, bind_group, &[]);
                per_particle.dispatch(pass);
            });
        }
    }

    /// Advances `frame_dt` seconds in adaptive steps whose length the GPU
    /// chooses as `World::advance` does (viscous limit, acoustic CFL and force condition, the
    /// last steps landing on the frame time). Steps are recorded `batch` at a
    /// time; steps past the frame's end dispatch no work (their workgroup
    /// counts, chosen on the GPU, are zero), so a batch somewhat larger than
    /// the frame needs costs little. Only a 32-byte state is read back after
    /// each batch, to know whether the frame is done.
    ///
    /// # Errors
    /// [`GpuError::Invalid`] for a `frame_dt` that is not finite or is
    /// shorter than the time stepping's `min_dt` (as `World::advance`
    /// refuses it) or a `batch` of 0 or above [`MAX_BATCH`]; [`GpuError::Unstable`] when the stable step falls
    /// below `min_dt` (a blow-up) or below the f32 resolution of the time
    /// elapsed in the frame (a frame far too long for its steps);
    /// [`GpuError::Readback`].
    pub fn advance(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        frame_dt: f32,
        batch: u32,
    ) -> Result<GpuFrame, GpuError> {
        self.advance_timed(device, queue, frame_dt, batch, None)
    }

    /// [`advance`](Self::advance) with every step's compute passes timed by
    /// `profiler`, as [`step_profiled`](Self::step_profiled) times them, plus
    /// the adaptive step's "step length: reduce_max" before "step length:
    /// choose_dt". Steps recorded past the frame's end are timed too (their
    /// passes dispatch nothing). The caller resolves the profiler's queries and ends
    /// its frame.
    ///
    /// # Errors
    /// As [`advance`](Self::advance).
    pub fn advance_profiled(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        frame_dt: f32,
        batch: u32,
        profiler: &GpuProfiler,
    ) -> Result<GpuFrame, GpuError> {
        self.advance_timed(device, queue, frame_dt, batch, Some(profiler))
    }

    fn advance_timed(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        frame_dt: f32,
        batch: u32,
        profiler: Option<&GpuProfiler>,
    ) -> Result<GpuFrame, GpuError> {
        if !(frame_dt.is_finite()
            && frame_dt >= self.params.min_dt
            && (1..=MAX_BATCH).contains(&batch))
        {
            return Err(GpuError::Invalid(
                "frame_dt must be finite and at least the time stepping's min_dt, batch in \
                 1..=MAX_BATCH (65,536)",
            ));
        }
        self.params.dt = 0.0;
        self.params.frame_dt = frame_dt;
        queue.write_buffer(&self.uniform, 0, bytemuck::bytes_of(&self.params));
        queue.write_buffer(&self.state, 0, bytemuck::bytes_of(&StepState::default()));
        // The first step's speed reduction runs before any `choose_dt`.
        queue.write_buffer(&self.gate, 0, bytemuck::cast_slice(&self.gate_full));
        let mut before = StepState::default();
        loop {
            let mut encoder = device.create_command_encoder(&Default::default());
            for _ in 0..batch {
                self.encode_step(&mut encoder, queue, profiler);
            }
            let bytes = self.state_readback.read(
                device,
                queue,
                encoder,
                &self.state,
                size_of::<StepState>() as u64,
            )?;
            let state: StepState = bytemuck::pod_read_unaligned(&bytes);
            if state.unstable != 0 {
                return Err(GpuError::Unstable(format!(
                    "the stable step fell below min_dt = {:e} s after {} steps of this frame",
                    self.params.min_dt, state.steps
                )));
            }
            if state.elapsed >= frame_dt || state.dt <= 0.0 {
                self.steps += u64::from(state.steps);
                return Ok(GpuFrame {
                    substeps: state.steps,
                    elapsed: state.elapsed,
                });
            }
            // The frame's time is summed in f32 on the GPU: steps below half
            // an ulp of it would leave it where it is, batch after batch.
            if state.steps > before.steps && state.elapsed <= before.elapsed {
                return Err(GpuError::Unstable(format!(
                    "the frame's time stopped at {} s of {frame_dt} s: steps of {:e} s are below its f32 resolution; use shorter frames",
                    state.elapsed, state.dt
                )));
            }
            before = state;
        }
    }

    /// Reads positions, velocities, densities and pressures back (before
    /// the first step, the densities and pressures of the particles as
    /// given).
    ///
    /// # Errors
    /// [`GpuError::Readback`].
    pub fn read_state(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
    ) -> Result<GpuState, GpuError> {
        let n = u64::from(self.params.n);
        let positions = read_vec3s(device, queue, self.grid.positions_buffer(), n)?;
        let velocities = read_vec3s(device, queue, &self.velocities, n)?;
        let (densities, pressures) = self.density.read(device, queue)?;
        Ok(GpuState {
            positions,
            velocities,
            densities,
            pressures,
        })
    }
}

impl crate::GpuParticles for GpuSolver {
    fn len(&self) -> usize {
        GpuSolver::len(self)
    }
    fn h(&self) -> f32 {
        GpuSolver::h(self)
    }
    fn positions_buffer(&self) -> &wgpu::Buffer {
        GpuSolver::positions_buffer(self)
    }
    fn velocities_buffer(&self) -> &wgpu::Buffer {
        GpuSolver::velocities_buffer(self)
    }
    fn densities_buffer(&self) -> &wgpu::Buffer {
        GpuSolver::densities_buffer(self)
    }
}

#[cfg(test)]
mod tests {
    use super::{PARAMS, Params, StepState};

    /// The Rust uniform and state structs match their WGSL declarations.
    #[test]
    fn layouts_match_their_wgsl() {
        splat_render::wgsl_layout!(
            PARAMS,
            "Params",
            Params {
                h,
                inv_h,
                n,
                table,
                rest_density,
                viscosity,
                surface_tension,
                surface_threshold,
                gravity,
                domain_min,
                domain_max,
                poly6_grad,
                visc_lap,
                spiky_grad,
                spiky_pressure,
                dt,
                restitution,
                cfl,
                force_factor,
                max_dt,
                min_dt,
                sound_speed,
                frame_dt,
                push_origin,
                push_dir,
                push_accel,
                layers
            }
        )
        .unwrap();
        let timestep = format!("{PARAMS}{}", include_str!("shaders/timestep.wgsl"));
        splat_render::wgsl_layout!(
            &timestep,
            "StepState",
            StepState {
                v_max,
                a_max,
                dt,
                elapsed,
                steps,
                unstable,
                pad
            }
        )
        .unwrap();
    }
}
