//! [`GpuPbf`]: position-based fluids (sph-core's `solver::pbf`) as compute
//! passes, a whole frame recorded in one command encoder.
//!
//! A substep is the CPU program's stations in the same order, one dispatch
//! each (`shaders/pbf.wgsl`): predict (gravity, the displacement guard, the
//! walls' projection), the grid over the domain's cells
//! ([`GpuGrid::in_box`]) and its neighbour lists on the predicted positions,
//! [`PbfParams::iterations`] Jacobi iterations of λ, Δp and the move,
//! vorticity confinement and XSPH, where σ > 0 Akinci et al.'s surface
//! tension (normals, then forces: sph-core's `surface_tension`, the same γ),
//! the boundary, and the substep's statistics. Between the grid and the boundary the particles are worked
//! on in cell order: a gather copies them into working buffers sorted by
//! cell and a scatter copies them home, so that a warp's threads share
//! neighbourhoods (with the grid over the domain's cells, this took a
//! 1M-particle frame on an H100 from 85.6 to 23.8 ms; BENCHMARKS.md, "PBF
//! frames on the GPU"). All substeps of a frame share one length, so the uniform is
//! written once per frame and nothing is read back inside it: the frame's
//! statistics (density error, guard clamps, the solve's headway) are copied
//! to a mappable buffer at its end and collected by a later frame
//! ([`GpuPbf::encode_frame`]), a frame or two late.
//!
//! Every sum runs over a particle's neighbour list in the grid's fixed order
//! and the statistics are reduced by a fixed tree (integer atomics only for
//! counts and maxima), so two runs give bitwise the same particles. They
//! differ from the CPU's by rounding: the CPU sorts its particles by cell and
//! sums eight lanes at a time.

use std::sync::Arc;
use std::sync::atomic::{AtomicU8, Ordering};

use bytemuck::{Pod, Zeroable};
use sph_core::solver::pbf::MAX_DENSITY_ERROR;
use sph_core::solver::surface_tension;
use sph_core::{
    Boundary, FluidParams, Particles, PbfParams, PbfSolve, PbfViscosity, Poly6, Solver,
};
use wgpu::util::DeviceExt;
use wgpu_profiler::GpuProfiler;

use crate::GpuParticles;
use crate::density::obstacles_buffer;
use crate::grid::{GpuError, GpuGrid};
use crate::passes::{bind_buffers, check_fits, read_floats, read_vec3s, shader, timed_pass};
use crate::push::{RayPush, push_uniforms};
use crate::solver::{GpuState, HASH, PUSH, RESOLVE, WALLS};

/// The shortest frame [`GpuPbf::encode_frame`] takes (s): sph-core's
/// default `min_dt`, the shortest step a CPU run takes with the default
/// time stepping (`World::advance` refuses a frame shorter than its
/// stepping's `min_dt`; the GPU's PBF has no stepping of its own). Far
/// shorter, Δt² underflows in the solve's pressure, which would turn
/// infinite with no error.
pub const MIN_FRAME_DT: f32 = 1e-7;

/// Neighbours a particle's list keeps on the GPU. A lattice at rest has 32
/// within h = 2 spacings; a particle with more than this many is compressed
/// far past anything the solve leaves, and the frame's statistics report it
/// as an error ([`GpuError::Unstable`]).
pub const MAX_NEIGHBOURS: u32 = 96;

/// The most lattice neighbours at rest (within h, on the cubic lattice of
/// the lightest particle's volume) a GPU scene may have: three quarters of
/// a list ([`MAX_NEIGHBOURS`] less the particle itself), leaving the rest
/// for compression. h up to 2.4 spacings passes (56 neighbours; the
/// built-in scenes' 2 spacings: 32); 2.5 (80) would overflow at 19 %
/// compression.
const MAX_NEIGHBOURS_AT_REST: usize = (MAX_NEIGHBOURS as usize - 1) * 3 / 4;

/// Refuses a fluid whose h spans so many of its particles' spacings that
/// the GPU's neighbour lists would overflow ([`MAX_NEIGHBOURS_AT_REST`]),
/// which the CPU path, whose lists have no such bound, runs. Without it
/// such a scene (h = 3.2 spacings: 136 neighbours) passed every check and
/// failed frames later with a hint about iterations.
fn check_lists_hold(particles: &Particles, fluid: &FluidParams) -> Result<(), GpuError> {
    let lightest = particles
        .masses()
        .iter()
        .copied()
        .fold(f32::INFINITY, f32::min);
    if !lightest.is_finite() {
        return Ok(());
    }
    let spacing = f64::from(lightest / fluid.rest_density).cbrt();
    let reach = f64::from(fluid.h) / spacing;
    let r = reach.floor() as i64;
    let at_rest = (-r..=r)
        .flat_map(|i| (-r..=r).flat_map(move |j| (-r..=r).map(move |k| (i, j, k))))
        .filter(|&(i, j, k)| {
            let d2 = (i * i + j * j + k * k) as f64;
            d2 > 0.0 && d2 <= reach * reach
        })
        .count();
    if at_rest > MAX_NEIGHBOURS_AT_REST {
        return Err(GpuError::DeviceLimit(format!(
            "fluid.h is {reach:.2} particle spacings: a particle at rest has {at_rest} neighbours \
             within h, more than the {MAX_NEIGHBOURS_AT_REST} the GPU's neighbour lists hold with \
             room for compression ({} in all); run it on the CPU (--cpu), or take h at most 2.4 \
             spacings",
            MAX_NEIGHBOURS - 1
        )));
    }
    Ok(())
}

/// Mirrors `struct Pbf` in `shaders/pbf.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct Uniform {
    h: f32,
    inv_h: f32,
    n: u32,
    max_neighbours: u32,
    gravity: [f32; 4],
    domain_min: [f32; 4],
    domain_max: [f32; 4],
    rest_density: f32,
    inv_rho0: f32,
    dt: f32,
    omega: f32,
    epsilon: f32,
    scorr_k: f32,
    scorr_n: u32,
    inv_w_dq: f32,
    vorticity: f32,
    xsph: f32,
    max_speed: f32,
    restitution: f32,
    poly6: f32,
    spiky: f32,
    w0: f32,
    max_error: f32,
    /// The push's ray origin (xyz) and radius (w; 0: no push).
    push_origin: [f32; 4],
    /// The push's ray direction (unit).
    push_dir: [f32; 4],
    /// The push's acceleration on the ray (m/s²).
    push_accel: [f32; 4],
    /// The grid's hash buckets.
    table: u32,
    /// Akinci et al.'s γ (0: no surface tension).
    gamma: f32,
    /// Their cohesion spline's 32/(πh⁹) times `surface_tension::COHESION_WEIGHT`.
    cohesion: f32,
    pad0: u32,
    /// The walls' layers under a clearance: spacing, thickness.
    layers: [f32; 4],
}

/// Mirrors `struct Stats` in `shaders/pbf.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
struct Stats {
    error_sum: f32,
    substeps: u32,
    unstable: u32,
    unstable_substep: u32,
    first_error: f32,
    last_error: f32,
    error_max: u32,
    clamped: u32,
    most_neighbours: u32,
    nonfinite: u32,
    first_max: u32,
    last_max: u32,
}

/// A frame's statistics as the GPU summed them: what `sph_core::FrameReport`
/// reports for a CPU frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PbfFrameStats {
    /// Which frame of this solver (0 for the first) they belong to.
    pub frame: u64,
    /// Substeps the frame took.
    pub substeps: u32,
    /// max(ρ/ρ0 − 1, 0) averaged over the particles, then over the substeps.
    pub density_error_avg: f32,
    /// The largest ρ/ρ0 − 1 of any particle in any substep (at least 0).
    pub density_error_max: f32,
    /// Particles the displacement guard slowed, summed over the substeps.
    pub clamped: u64,
    /// The most neighbours within h any particle had.
    pub most_neighbours: u32,
}

/// What [`GpuPbf::encode_frame`] recorded, and the newest statistics that had
/// come back by then.
#[derive(Debug, Clone, PartialEq)]
pub struct PbfFrame {
    /// Substeps recorded for this frame (the CPU's rule,
    /// [`PbfParams::substeps_for`]).
    pub substeps: u32,
    /// Constraint iterations recorded for this frame.
    pub iterations: u32,
    /// The statistics of earlier frames that have come back since the last
    /// call, oldest first (usually one: the frame before).
    pub stats: Vec<PbfFrameStats>,
}

/// The pipelines of one substep's passes (all bind the working buffers as
/// group 0; predict, gather, lists and scatter the home buffers as group 2).
struct Passes {
    predict: Pass,
    gather: Pass,
    lists: Pass,
    scatter: Pass,
    /// λ by headway: plain, first iteration, last, both (one iteration).
    lambda: [Pass; 4],
    correct: Pass,
    apply: Pass,
    curl: Pass,
    confine: Pass,
    /// Akinci et al.'s surface tension: normals, then forces.
    normals: Pass,
    tension: Pass,
    boundaries: Pass,
    reduce: Pass,
    open_gate: Pass,
}

type Pass = wgpu::ComputePipeline;

/// What one stage of a substep records into a compute pass.
type Record<'a> = &'a dyn Fn(&mut wgpu::ComputePass<'_>);

/// A slot's map: not back yet.
const PENDING: u8 = 0;
/// A slot's map: readable.
const MAPPED: u8 = 1;
/// A slot's map: failed (a lost device).
const FAILED: u8 = 2;

/// One frame in flight: its uniforms, copied into the passes' uniform
/// buffer by the frame's own commands (so that frames recorded before one
/// submission each run with their own substep), and a mappable copy of its
/// statistics on their way back.
struct Slot {
    uniform: wgpu::Buffer,
    buffer: wgpu::Buffer,
    /// The frame whose statistics it holds, while it holds any.
    frame: Option<u64>,
    /// Set by the map callback: [`PENDING`], [`MAPPED`] or [`FAILED`].
    mapped: Arc<AtomicU8>,
}

/// Position-based fluids on the GPU with the same equations, parameters and
/// walls as `sph_core::solver::pbf` (domain walls, boxes and spheres, the
/// clearance, s_corr, vorticity confinement, XSPH). Index i of the state it
/// shows ([`GpuParticles`], [`read_state`](Self::read_state)) is particle i of
/// the `Particles` it was built from; inside a substep it works on a copy
/// sorted by cell.
pub struct GpuPbf {
    uniform: Uniform,
    pbf: PbfParams,
    grid: GpuGrid,
    uniform_buffer: wgpu::Buffer,
    velocities: wgpu::Buffer,
    pressures: wgpu::Buffer,
    densities: wgpu::Buffer,
    stats: wgpu::Buffer,
    passes: Passes,
    /// The working buffers (cell order) and the rest of the solve's state.
    group: wgpu::BindGroup,
    /// The home buffers (particle order) and the grid's sort.
    home_group: wgpu::BindGroup,
    /// Workgroup counts the dispatches read (see `pbf.wgsl`'s gate).
    gate: wgpu::Buffer,
    /// The gate and the halted flag, for `open_gate` and `reduce`.
    gate_group: wgpu::BindGroup,
    slots: Vec<Slot>,
    /// The first failure statistics showed: every later call returns it.
    failure: Option<String>,
    frames: u64,
    substeps: u64,
}

impl GpuPbf {
    /// Uploads `particles` (positions, velocities, masses) and prepares the
    /// passes.
    ///
    /// # Errors
    /// [`GpuError::Params`] for particles, parameters or a boundary sph-core
    /// rejects (the colour-field surface tension among them, WCSPH's only;
    /// a mass too light for h and a position the boundary does not admit:
    /// `World::check_inputs`, as `World::with_solver` refuses them);
    /// [`GpuError::Invalid`] for `pbf.viscosity = "implicit"`, for
    /// `pbf.sleep_speed` > 0 and for `pbf.solve = "gauss-seidel"`, which
    /// run only on the CPU;
    /// [`GpuError::DeviceLimit`] for more particles than one dispatch or
    /// storage binding of this device holds, or for an h of more than 2.4
    /// particle spacings, whose neighbours would overflow the GPU's lists.
    pub fn new(
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        particles: &Particles,
        fluid: &FluidParams,
        pbf: &PbfParams,
        boundary: &Boundary,
    ) -> Result<Self, GpuError> {
        sph_core::World::check_inputs(particles, fluid, boundary).map_err(GpuError::Params)?;
        pbf.validate().map_err(GpuError::Params)?;
        Solver::Pbf(*pbf)
            .check_applies(fluid)
            .map_err(GpuError::Params)?;
        if pbf.viscosity == PbfViscosity::Implicit {
            return Err(GpuError::Invalid(
                "solver.pbf.viscosity = \"implicit\" runs only on the CPU: on the GPU use \"xsph\" and leave out fluid.viscosity, which XSPH does not apply",
            ));
        }
        if pbf.sleep_speed > 0.0 {
            return Err(GpuError::Invalid(
                "solver.pbf.sleep_speed > 0 (particle sleeping) runs only on the CPU: on the GPU leave it out or set it to 0",
            ));
        }
        if pbf.solve == PbfSolve::GaussSeidel {
            return Err(GpuError::Invalid(
                "solver.pbf.solve = \"gauss-seidel\" runs only on the CPU: on the GPU leave it out or set \"jacobi\"",
            ));
        }
        check_lists_hold(particles, fluid)?;
        let n = particles.len();
        let capacity = n.max(1);
        check_fits(device, "particles", capacity, 64, 32)?;
        let domain = &boundary.domain;
        let mut grid = GpuGrid::in_box(
            device,
            capacity,
            fluid.h,
            MAX_NEIGHBOURS,
            domain.min,
            domain.max,
        )?;
        grid.upload_with_masses(queue, particles.positions(), Some(particles.masses()))?;
        let h = fluid.h;
        let poly6 = Poly6::new(h).map_err(GpuError::Params)?;
        let dq = pbf.scorr_dq * h;
        let uniform = Uniform {
            h,
            inv_h: 1.0 / h,
            n: n as u32,
            max_neighbours: MAX_NEIGHBOURS,
            gravity: fluid.gravity.extend(0.0).to_array(),
            domain_min: boundary.domain.min.extend(boundary.clearance).to_array(),
            domain_max: boundary.domain.max.extend(0.0).to_array(),
            rest_density: fluid.rest_density,
            inv_rho0: 1.0 / fluid.rest_density,
            dt: 0.0,
            omega: pbf.over_relaxation,
            epsilon: pbf.relaxation / (h * h),
            scorr_k: pbf.scorr_k,
            scorr_n: pbf.scorr_n,
            inv_w_dq: 1.0 / poly6.value_r2(dq * dq),
            vorticity: pbf.vorticity,
            xsph: pbf.xsph,
            max_speed: 0.0,
            restitution: boundary.restitution,
            poly6: poly6.coefficients().0,
            spiky: sph_core::Spiky::new(h)
                .map_err(GpuError::Params)?
                .coefficient(),
            w0: poly6.value_r2(0.0),
            max_error: MAX_DENSITY_ERROR,
            push_origin: [0.0; 4],
            push_dir: [0.0; 4],
            push_accel: [0.0; 4],
            table: grid.table_size(),
            gamma: surface_tension::gamma(fluid),
            cohesion: surface_tension::cohesion_coefficient(h),
            pad0: 0,
            layers: crate::solver::wall_layers(fluid, boundary, particles.masses()),
        };
        let uniform_buffer = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("pbf params"),
            size: size_of::<Uniform>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let storage = |label, bytes_each: u64| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: (bytes_each * capacity as u64).max(16),
                usage: wgpu::BufferUsages::STORAGE
                    | wgpu::BufferUsages::COPY_DST
                    | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            })
        };
        let velocities = storage("pbf velocities", 16);
        let v: Vec<[f32; 4]> = (particles.velocities().iter())
            .map(|v| v.extend(0.0).to_array())
            .collect();
        if !v.is_empty() {
            queue.write_buffer(&velocities, 0, bytemuck::cast_slice(&v));
        }
        let work_positions = storage("pbf working positions", 16);
        let work_velocities = storage("pbf working velocities", 16);
        let work_pressures = storage("pbf working pressures", 4);
        let work_densities = storage("pbf working densities", 4);
        let lambdas = storage("pbf lambdas", 8);
        let corrections = storage("pbf corrections", 16);
        let pressures = storage("pbf pressures", 4);
        let densities = storage("pbf densities", 4);
        let curls = storage("pbf curls", 16);
        let means = storage("pbf means", 16);
        let partials = storage("pbf partial sums", 4);
        let weighted = storage("pbf weighted positions", 16);
        let stats = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("pbf stats"),
            size: size_of::<Stats>() as u64,
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_DST
                | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let obstacles = obstacles_buffer(device, boundary)?;
        let buffers: [&wgpu::Buffer; 15] = [
            &uniform_buffer,
            &work_positions,
            &work_velocities,
            grid.lists_buffer(),
            grid.list_len_buffer(),
            &lambdas,
            &corrections,
            &work_pressures,
            &work_densities,
            &curls,
            &means,
            &stats,
            &obstacles,
            &partials,
            &weighted,
        ];
        let home_buffers: [&wgpu::Buffer; 7] = [
            grid.positions_buffer(),
            &velocities,
            &densities,
            &pressures,
            grid.sorted_buffer(),
            grid.starts_buffer(),
            grid.counts_buffer(),
        ];
        let storage_buffers = (buffers.len() + home_buffers.len()) as u32 - 1;
        if device.limits().max_storage_buffers_per_shader_stage < storage_buffers {
            return Err(GpuError::DeviceLimit(format!(
                "GPU PBF binds {storage_buffers} storage buffers per pass; this device allows {}",
                device.limits().max_storage_buffers_per_shader_stage
            )));
        }
        // Group 0, for every pass: the uniform, then storage buffers, the
        // obstacles read-only. Group 2: the home buffers, then the grid's
        // sort read-only.
        let entries = |count: usize, uniform: Option<u32>, read_only: &[u32]| -> Vec<_> {
            (0..count as u32)
                .map(|binding| wgpu::BindGroupLayoutEntry {
                    binding,
                    visibility: wgpu::ShaderStages::COMPUTE,
                    ty: wgpu::BindingType::Buffer {
                        ty: if uniform == Some(binding) {
                            wgpu::BufferBindingType::Uniform
                        } else {
                            wgpu::BufferBindingType::Storage {
                                read_only: read_only.contains(&binding),
                            }
                        },
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                })
                .collect()
        };
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("pbf layout"),
            entries: &entries(buffers.len(), Some(0), &[12]),
        });
        let group = bind_buffers(device, "pbf", &layout, &buffers);
        let home_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("pbf home layout"),
            entries: &entries(home_buffers.len(), None, &[4, 5, 6]),
        });
        let home_group = bind_buffers(device, "pbf home", &home_layout, &home_buffers);
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("pbf pipeline layout"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let home_pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("pbf home pipeline layout"),
            bind_group_layouts: &[Some(&layout), None, Some(&home_layout)],
            immediate_size: 0,
        });
        // The gate (see pbf.wgsl): the live triples, then the full ones,
        // read by the gated dispatches and written only by `open_gate` and
        // `reduce`, which bind it as group 1 and are dispatched directly.
        let full: Vec<u32> = {
            let [buckets, particles, one] = grid.build_groups();
            let per_particle = capacity.div_ceil(64) as u32;
            [buckets, particles, one, per_particle]
                .iter()
                .flat_map(|&x| [x, 1, 1])
                .collect()
        };
        let gate = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("pbf gate"),
            contents: bytemuck::cast_slice(&[&full[..], &full[..]].concat()),
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::INDIRECT,
        });
        let halted = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("pbf halted"),
            contents: bytemuck::bytes_of(&0u32),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let gate_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("pbf gate layout"),
            entries: &[0, 1].map(|binding| wgpu::BindGroupLayoutEntry {
                binding,
                visibility: wgpu::ShaderStages::COMPUTE,
                ty: wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Storage { read_only: false },
                    has_dynamic_offset: false,
                    min_binding_size: None,
                },
                count: None,
            }),
        });
        let gate_group = bind_buffers(device, "pbf gate", &gate_layout, &[&gate, &halted]);
        let gated_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("pbf gate pipeline layout"),
            bind_group_layouts: &[Some(&layout), Some(&gate_layout)],
            immediate_size: 0,
        });
        let module = shader(
            device,
            "pbf.wgsl",
            format!(
                "{}{HASH}{WALLS}{RESOLVE}{PUSH}",
                include_str!("shaders/pbf.wgsl")
            ),
        );
        let mut constants = grid.bucket_constants();
        constants.push(("HEADWAY", 0.0));
        let pass = |entry: &str, headway: u32| {
            let mut constants = constants.clone();
            if let Some(last) = constants.last_mut() {
                last.1 = f64::from(headway);
            }
            device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(entry),
                layout: Some(match entry {
                    "open_gate" | "reduce" => &gated_layout,
                    "predict" | "gather" | "neighbour_lists" | "scatter" => &home_pipeline_layout,
                    _ => &pipeline_layout,
                }),
                module: &module,
                entry_point: Some(entry),
                compilation_options: wgpu::PipelineCompilationOptions {
                    constants: &constants,
                    ..Default::default()
                },
                cache: None,
            })
        };
        let passes = Passes {
            predict: pass("predict", 0),
            gather: pass("gather", 0),
            lists: pass("neighbour_lists", 0),
            scatter: pass("scatter", 0),
            lambda: std::array::from_fn(|k| pass("lambda", k as u32)),
            correct: pass("correct", 0),
            apply: pass("apply", 0),
            curl: pass("curl", 0),
            confine: pass("confine", 0),
            normals: pass("surface_normals", 0),
            tension: pass("surface_tension", 0),
            boundaries: pass("boundaries", 0),
            reduce: pass("reduce", 0),
            open_gate: pass("open_gate", 0),
        };
        let slots = (0..3)
            .map(|_| Slot {
                uniform: device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("pbf frame params"),
                    size: size_of::<Uniform>() as u64,
                    usage: wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
                    mapped_at_creation: false,
                }),
                buffer: device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("pbf stats readback"),
                    size: size_of::<Stats>() as u64,
                    usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
                    mapped_at_creation: false,
                }),
                frame: None,
                mapped: Arc::new(AtomicU8::new(PENDING)),
            })
            .collect();
        let solver = Self {
            uniform,
            pbf: *pbf,
            grid,
            uniform_buffer,
            velocities,
            pressures,
            densities,
            stats,
            passes,
            group,
            home_group,
            gate,
            gate_group,
            slots,
            failure: None,
            frames: 0,
            substeps: 0,
        };
        solver.prime_densities(device, queue);
        Ok(solver)
    }

    /// Pushes the fluid from the next frame recorded on (`None` stops).
    ///
    /// # Errors
    /// [`GpuError::Invalid`] for a push that is not finite, a direction
    /// that is not unit length or a radius that is not positive.
    pub fn set_push(&mut self, push: Option<RayPush>) -> Result<(), GpuError> {
        let [origin, dir, accel] = push_uniforms(push)?;
        let u = &mut self.uniform;
        u.push_origin = origin;
        u.push_dir = dir;
        u.push_accel = accel;
        Ok(())
    }

    /// The parameters it runs.
    pub fn params(&self) -> &PbfParams {
        &self.pbf
    }

    /// Frames encoded so far.
    pub fn frames(&self) -> u64 {
        self.frames
    }

    /// Substeps encoded so far.
    pub fn substeps(&self) -> u64 {
        self.substeps
    }

    /// Records one frame of `frame_dt` seconds into `encoder`: the frame's
    /// uniforms copied in, every substep and iteration in one compute pass,
    /// then a copy of the frame's statistics to a buffer mapped when the
    /// encoder is submitted. Nothing is submitted or waited for: submit
    /// `encoder` with whatever else the frame records (extraction,
    /// rendering). Frames may be recorded into one encoder or several before
    /// a submission; each runs with its own substep. Also collects the
    /// statistics of earlier frames that have come back, waiting only when
    /// three frames' statistics are still on their way.
    ///
    /// # Errors
    /// [`GpuError::Invalid`] for a `frame_dt` that is not finite or is
    /// shorter than [`MIN_FRAME_DT`]; [`GpuError::Params`] for one that
    /// would take more than 1000 substeps
    /// ([`PbfParams::check_frame`]);
    /// [`GpuError::Unstable`] when statistics that came back show a frame
    /// whose state became non-finite, whose constraint solve diverged (as
    /// `SolveDensity` judges it on the CPU), or one of whose particles had
    /// more neighbours than its list holds ([`MAX_NEIGHBOURS`]), and from
    /// then on (the statistics of the frames before it are returned first);
    /// [`GpuError::Readback`], also for statistics that never come back
    /// (an encoder recorded and dropped unsubmitted).
    pub fn encode_frame(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        encoder: &mut wgpu::CommandEncoder,
        frame_dt: f32,
    ) -> Result<PbfFrame, GpuError> {
        self.encode_frame_timed(device, queue, encoder, frame_dt, None)
    }

    /// [`encode_frame`](Self::encode_frame) with each kind of pass in its
    /// own compute pass, timed by `profiler`: "pbf: predict", "pbf: grid",
    /// "pbf: gather", "pbf: lists", "pbf: lambda", "pbf: correct", "pbf:
    /// apply", "pbf: curl", "pbf: confine", where σ > 0 "pbf: surface
    /// normals" and "pbf: surface tension", "pbf: boundaries", "pbf:
    /// scatter", "pbf: reduce", once per substep (and iteration). The caller resolves the profiler's queries
    /// and ends its frame. The split costs pass boundaries the plain path
    /// does not have.
    ///
    /// # Errors
    /// As [`encode_frame`](Self::encode_frame).
    pub fn encode_frame_profiled(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        encoder: &mut wgpu::CommandEncoder,
        frame_dt: f32,
        profiler: &GpuProfiler,
    ) -> Result<PbfFrame, GpuError> {
        self.encode_frame_timed(device, queue, encoder, frame_dt, Some(profiler))
    }

    fn encode_frame_timed(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        encoder: &mut wgpu::CommandEncoder,
        frame_dt: f32,
        profiler: Option<&GpuProfiler>,
    ) -> Result<PbfFrame, GpuError> {
        if !(frame_dt.is_finite() && frame_dt >= MIN_FRAME_DT) {
            return Err(GpuError::Invalid(
                "frame_dt must be finite and at least 1e-7 s (sph-core's default min_dt)",
            ));
        }
        let substeps = self.pbf.check_frame(frame_dt).map_err(GpuError::Params)?;
        self.failed()?;
        let mut stats = self.collect(device, false)?;
        let slot = match self.slots.iter().position(|s| s.frame.is_none()) {
            Some(free) => free,
            None => {
                // Three frames in flight: wait for the oldest.
                stats.extend(self.collect(device, true)?);
                (self.slots.iter().position(|s| s.frame.is_none()))
                    .ok_or_else(|| GpuError::Readback("no statistics came back".into()))?
            }
        };
        if stats.is_empty() {
            self.failed()?;
        }
        let dt = frame_dt / substeps as f32;
        self.uniform.dt = dt;
        self.uniform.max_speed = self.pbf.max_displacement * self.uniform.h / dt;
        // The frame's own uniforms, copied in by its commands: a later
        // frame's write cannot overtake them before a shared submission.
        let uniform = &self.slots[slot].uniform;
        queue.write_buffer(uniform, 0, bytemuck::bytes_of(&self.uniform));
        encoder.copy_buffer_to_buffer(
            uniform,
            0,
            &self.uniform_buffer,
            0,
            Some(size_of::<Uniform>() as u64),
        );
        encoder.clear_buffer(&self.stats, 0, None);
        let open = |pass: &mut wgpu::ComputePass<'_>| {
            pass.set_pipeline(&self.passes.open_gate);
            pass.set_bind_group(0, &self.group, &[]);
            pass.set_bind_group(1, &self.gate_group, &[]);
            pass.dispatch_workgroups(1, 1, 1);
        };
        match profiler {
            None => {
                let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("pbf frame"),
                    timestamp_writes: None,
                });
                open(&mut pass);
                for _ in 0..substeps {
                    self.record_substep(&mut |_, record| record(&mut pass));
                }
            }
            Some(profiler) => {
                timed_pass(encoder, Some(profiler), "pbf: open gate", open);
                for _ in 0..substeps {
                    self.record_substep(&mut |label, record| {
                        timed_pass(encoder, Some(profiler), label, record);
                    });
                }
            }
        }
        let slot = &mut self.slots[slot];
        encoder.copy_buffer_to_buffer(
            &self.stats,
            0,
            &slot.buffer,
            0,
            Some(size_of::<Stats>() as u64),
        );
        let mapped = Arc::clone(&slot.mapped);
        encoder.map_buffer_on_submit(&slot.buffer, wgpu::MapMode::Read, .., move |r| {
            mapped.store(if r.is_ok() { MAPPED } else { FAILED }, Ordering::Release);
        });
        slot.frame = Some(self.frames);
        self.frames += 1;
        self.substeps += u64::from(substeps);
        Ok(PbfFrame {
            substeps,
            iterations: substeps * self.pbf.iterations,
            stats,
        })
    }

    /// The failure statistics showed, if any.
    fn failed(&self) -> Result<(), GpuError> {
        match &self.failure {
            Some(message) => Err(GpuError::Unstable(message.clone())),
            None => Ok(()),
        }
    }

    /// Advances one frame of `frame_dt` seconds: [`encode_frame`](Self::encode_frame)
    /// in an encoder of its own, submitted once.
    ///
    /// # Errors
    /// As [`encode_frame`](Self::encode_frame).
    pub fn advance(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        frame_dt: f32,
    ) -> Result<PbfFrame, GpuError> {
        let mut encoder = device.create_command_encoder(&Default::default());
        let frame = self.encode_frame(device, queue, &mut encoder, frame_dt)?;
        queue.submit([encoder.finish()]);
        Ok(frame)
    }

    /// Waits for every frame submitted so far and returns the statistics
    /// that had not come back yet, oldest first.
    ///
    /// # Errors
    /// As [`encode_frame`](Self::encode_frame).
    pub fn finish(&mut self, device: &wgpu::Device) -> Result<Vec<PbfFrameStats>, GpuError> {
        self.failed()?;
        let mut all = Vec::new();
        while self.failure.is_none() && self.slots.iter().any(|s| s.frame.is_some()) {
            all.extend(self.collect(device, true)?);
        }
        if all.is_empty() {
            self.failed()?;
        }
        Ok(all)
    }

    /// Reads the statistics that have come back, oldest first; with `wait`,
    /// first waits for the oldest frame still on its way. A frame whose
    /// statistics show a failure is kept in [`Self::failure`] and ends the
    /// reading: the frames before it are returned.
    fn collect(
        &mut self,
        device: &wgpu::Device,
        wait: bool,
    ) -> Result<Vec<PbfFrameStats>, GpuError> {
        let poll = |kind| {
            device
                .poll(kind)
                .map(|_| ())
                .map_err(|e| GpuError::Readback(e.to_string()))
        };
        // In frame order: a later frame's map can come back before an
        // earlier one's.
        let mut waiting: Vec<usize> = (0..self.slots.len())
            .filter(|&k| self.slots[k].frame.is_some())
            .collect();
        waiting.sort_by_key(|&k| self.slots[k].frame);
        match waiting.first() {
            Some(&k) if wait => {
                // The map callback runs in whichever thread's poll finds it
                // done: on a device shared by threads it may still be on its
                // way when this thread's wait returns.
                let start = std::time::Instant::now();
                loop {
                    poll(wgpu::PollType::wait_indefinitely())?;
                    if self.slots[k].mapped.load(Ordering::Acquire) != PENDING {
                        break;
                    }
                    if start.elapsed() > std::time::Duration::from_secs(10) {
                        return Err(GpuError::Readback(
                            "a frame's statistics did not come back within 10 s of the device's \
                             idle: was its encoder submitted?"
                                .into(),
                        ));
                    }
                    std::thread::sleep(std::time::Duration::from_micros(200));
                }
            }
            _ => poll(wgpu::PollType::Poll)?,
        }
        if (waiting.iter()).any(|&k| self.slots[k].mapped.load(Ordering::Acquire) == FAILED) {
            return Err(GpuError::Readback(
                "mapping a frame's statistics failed (is the device lost?)".into(),
            ));
        }
        let mut out = Vec::new();
        for k in waiting {
            let slot = &mut self.slots[k];
            if slot.mapped.load(Ordering::Acquire) != MAPPED {
                break;
            }
            let stats: Stats = {
                let view = slot
                    .buffer
                    .get_mapped_range(..)
                    .map_err(|e| GpuError::Readback(e.to_string()))?;
                bytemuck::pod_read_unaligned(&view[..size_of::<Stats>()])
            };
            slot.buffer.unmap();
            slot.mapped.store(PENDING, Ordering::Release);
            let frame = slot.frame.take().unwrap_or(0);
            if let Err(e) = check(&stats, frame, &self.pbf) {
                self.failure = Some(e);
                break;
            }
            out.push(PbfFrameStats {
                frame,
                substeps: stats.substeps,
                density_error_avg: stats.error_sum / stats.substeps.max(1) as f32,
                density_error_max: f32::from_bits(stats.error_max),
                clamped: u64::from(stats.clamped),
                // The lists count the particle itself.
                most_neighbours: stats.most_neighbours.saturating_sub(1),
            });
        }
        Ok(out)
    }

    /// A dispatch of `pipeline` over the working buffers' group (and the
    /// home group, with `home`), one thread per particle, its workgroups
    /// read from the gate.
    fn dispatch<'a>(
        &'a self,
        pipeline: &'a Pass,
        home: bool,
    ) -> impl Fn(&mut wgpu::ComputePass<'_>) + 'a {
        /// The gate's triple of particles in 64s.
        const PER_PARTICLE: u64 = 3;
        move |pass| {
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, &self.group, &[]);
            if home {
                pass.set_bind_group(2, &self.home_group, &[]);
            }
            pass.dispatch_workgroups_indirect(&self.gate, 12 * PER_PARTICLE);
        }
    }

    /// Computes the densities of the particles as given, so that a readback
    /// or an extraction before the first frame sees them (the buffer starts
    /// zeroed: volumes m/0): a substep's grid, lists and density pass
    /// (`curl`, which also writes the curl and XSPH means the next substep
    /// recomputes) and its scatter home, without the prediction or the
    /// solve, so positions and velocities stay as they are.
    fn prime_densities(&self, device: &wgpu::Device, queue: &wgpu::Queue) {
        queue.write_buffer(&self.uniform_buffer, 0, bytemuck::bytes_of(&self.uniform));
        let mut encoder = device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("pbf initial densities"),
                timestamp_writes: None,
            });
            let p = &self.passes;
            self.grid.record_build(&mut pass, Some(&self.gate));
            for (pipeline, home) in [
                (&p.gather, true),
                (&p.lists, true),
                (&p.curl, false),
                (&p.scatter, true),
            ] {
                self.dispatch(pipeline, home)(&mut pass);
            }
        }
        queue.submit([encoder.finish()]);
    }

    /// Records one substep, each stage handed to `stage` with its label.
    /// Every dispatch but `reduce` (one workgroup, which writes the gate)
    /// reads its workgroups from the gate.
    fn record_substep(&self, stage: &mut dyn FnMut(&str, Record<'_>)) {
        let run = |pipeline| self.dispatch(pipeline, false);
        let home = |pipeline| self.dispatch(pipeline, true);
        let p = &self.passes;
        stage("pbf: predict", &home(&p.predict));
        stage("pbf: grid", &|pass| {
            self.grid.record_build(pass, Some(&self.gate))
        });
        stage("pbf: gather", &home(&p.gather));
        stage("pbf: lists", &home(&p.lists));
        let iterations = self.pbf.iterations;
        for k in 0..iterations {
            let headway = usize::from(k == 0) | (usize::from(k + 1 == iterations) << 1);
            stage("pbf: lambda", &run(&p.lambda[headway]));
            stage("pbf: correct", &run(&p.correct));
            stage("pbf: apply", &run(&p.apply));
        }
        stage("pbf: curl", &run(&p.curl));
        stage("pbf: confine", &run(&p.confine));
        if self.uniform.gamma > 0.0 {
            stage("pbf: surface normals", &run(&p.normals));
            stage("pbf: surface tension", &run(&p.tension));
        }
        stage("pbf: boundaries", &run(&p.boundaries));
        stage("pbf: scatter", &home(&p.scatter));
        stage("pbf: reduce", &|pass| {
            pass.set_pipeline(&p.reduce);
            pass.set_bind_group(0, &self.group, &[]);
            pass.set_bind_group(1, &self.gate_group, &[]);
            pass.dispatch_workgroups(1, 1, 1);
        });
    }

    /// Reads positions, velocities, densities and pressures back (waits for
    /// the device; before the first frame, the densities of the particles
    /// as given and zero pressures).
    ///
    /// # Errors
    /// [`GpuError::Readback`].
    pub fn read_state(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
    ) -> Result<GpuState, GpuError> {
        let n = u64::from(self.uniform.n);
        Ok(GpuState {
            positions: read_vec3s(device, queue, self.grid.positions_buffer(), n)?,
            velocities: read_vec3s(device, queue, &self.velocities, n)?,
            densities: read_floats(device, queue, &self.densities, n)?,
            pressures: read_floats(device, queue, &self.pressures, n)?,
        })
    }
}

impl GpuParticles for GpuPbf {
    fn len(&self) -> usize {
        self.uniform.n as usize
    }
    fn h(&self) -> f32 {
        self.uniform.h
    }
    fn positions_buffer(&self) -> &wgpu::Buffer {
        self.grid.positions_buffer()
    }
    fn velocities_buffer(&self) -> &wgpu::Buffer {
        &self.velocities
    }
    fn densities_buffer(&self) -> &wgpu::Buffer {
        &self.densities
    }
}

/// The failure a frame's statistics show, if any.
fn check(stats: &Stats, frame: u64, pbf: &PbfParams) -> Result<(), String> {
    let hint = || {
        format!(
            "raise solver.pbf.iterations (now {}) or solver.pbf.substeps (now {}), \
             or lower solver.pbf.max_dt (now {:e} s)",
            pbf.iterations, pbf.substeps, pbf.max_dt
        )
    };
    let at = format!("frame {frame}, substep {}", stats.unstable_substep);
    // The lists count the particle itself.
    let neighbours = stats.most_neighbours.saturating_sub(1);
    match stats.unstable {
        0 => {}
        3 => {
            return Err(format!(
                "a particle had {neighbours} neighbours within h ({at}), more than the {} a GPU \
                 neighbour list holds besides itself: the fluid is compressed far past rest \
                 density; {}",
                MAX_NEIGHBOURS - 1,
                hint()
            ));
        }
        1 => {
            return Err(format!(
                "a position, velocity or density became non-finite ({at}); {}",
                hint()
            ));
        }
        _ => {
            return Err(format!(
                "the density constraint solve diverged ({at}): a density error of {:.0} % \
                 after {} iterations, from {:.0} % at the first (above {:.0} %, no headway); {}",
                stats.last_error * 100.0,
                pbf.iterations,
                stats.first_error * 100.0,
                MAX_DENSITY_ERROR * 100.0,
                hint()
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::{HASH, PUSH, RESOLVE, Stats, Uniform, WALLS};

    #[test]
    fn layouts_match_their_wgsl() {
        let source = format!(
            "{}{HASH}{WALLS}{RESOLVE}{PUSH}",
            include_str!("shaders/pbf.wgsl")
        );
        splat_render::wgsl_layout!(
            &source,
            "Pbf",
            Uniform {
                h,
                inv_h,
                n,
                max_neighbours,
                gravity,
                domain_min,
                domain_max,
                rest_density,
                inv_rho0,
                dt,
                omega,
                epsilon,
                scorr_k,
                scorr_n,
                inv_w_dq,
                vorticity,
                xsph,
                max_speed,
                restitution,
                poly6,
                spiky,
                w0,
                max_error,
                push_origin,
                push_dir,
                push_accel,
                table,
                gamma,
                cohesion,
                pad0,
                layers
            }
        )
        .unwrap();
        splat_render::wgsl_layout!(
            &source,
            "Stats",
            Stats {
                error_sum,
                substeps,
                unstable,
                unstable_substep,
                first_error,
                last_error,
                error_max,
                clamped,
                most_neighbours,
                nonfinite,
                first_max,
                last_max
            }
        )
        .unwrap();
    }
}
