//! [`GpuExtractor`]: surfel-extract's thesis-mode extractor (Vesterlund 2004,
//! 4.2.1) as compute passes — the initial guess from the particles, then
//! Newton-Raphson refinement with splitting — writing surfels straight into a
//! buffer that splat-render draws indirectly, with no round trip to the CPU.

use bytemuck::{Pod, Zeroable};
use glam::Vec3;
use surfel_extract::{AllAround, ColourField, ExtractParams, Mode, Split, Surface, Surfel};
use wgpu::util::DeviceExt;
use wgpu_profiler::GpuProfiler;

use crate::GpuParticles;
use crate::anisotropy::{GpuAnisotropy, KERNEL_BYTES};
use crate::grid::{GpuError, GpuGrid};
use crate::passes::{
    Groups, PassStage, Staging, bind_pairs, buffer, pipeline, read, shader, staged_pass, timed_pass,
};

/// Mirrors `struct Extract` in `shaders/extract.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct Uniform {
    h: f32,
    inv_h: f32,
    n: u32,
    table: u32,
    iso: f32,
    interior_step: f32,
    discard_step: f32,
    split_laplacian: f32,
    covariance_threshold: f32,
    all_around: u32,
    radius: f32,
    has_camera: u32,
    camera: [f32; 4],
    poly6: f32,
    poly6_grad: f32,
    work_capacity: u32,
    out_capacity: u32,
    anisotropic: u32,
    fill_cell: f32,
    fill_table: u32,
    first_split: u32,
    fill_capacity: u32,
    fill_thickness: f32,
    pad1: u32,
    pad2: u32,
}

/// Mirrors `struct Stage`.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct Stage {
    src: u32,
    dst: u32,
    last: u32,
    iteration: u32,
    keep: u32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

/// Slots of the counters buffer (see the shader).
const OUT: usize = 2;
const SURFACE_PARTICLES: usize = 3;
const ALL_AROUND: usize = 4;
const LONE: usize = 5;
const DISCARDED: usize = 6;
const EVALUATED: usize = 7;
const DROPPED: usize = 10;
const DROPLETS: usize = 11;
const FILLED: usize = 12;
const COUNTERS: u64 = 16;

/// Bytes of one surfel on the GPU (splat-render's splat layout).
pub const SURFEL_BYTES: u64 = 32;

/// What a GPU extraction did, read back from its counters.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct GpuExtractStats {
    /// Particles in the input.
    pub particles: usize,
    /// Particles that seeded one surfel (four where split).
    pub surface_particles: usize,
    /// Particles surrounded by six or eight surfels (eq. 36).
    pub all_around: usize,
    /// Lone particles given their analytic iso-sphere.
    pub lone: usize,
    /// Particles of droplets too small for anisotropic kernels, seeded on
    /// their spheres (anisotropic field only).
    pub droplets: usize,
    /// Surfels hole closing added ([`Mode::Covered`] only).
    pub filled: usize,
    /// Surfels discarded by the step test.
    pub discarded: usize,
    /// Surfels in the result (at most the capacity).
    pub surfels: usize,
    /// Surfels that did not fit a buffer: non-zero means the result is
    /// incomplete and the extractor needs a larger `max_surfels`.
    pub dropped: usize,
    /// Field evaluations at the particles (one each).
    pub particle_evaluations: u64,
    /// Field evaluations at surfels (one per surfel per iteration).
    pub evaluations: u64,
}

impl GpuExtractStats {
    /// Surfels per surfel evaluation (the thesis's efficiency).
    pub fn efficiency(&self) -> f64 {
        self.surfels as f64 / self.evaluations.max(1) as f64
    }
}

/// The thesis's extractor on the GPU, for a fixed particle capacity and
/// surfel capacity.
///
/// It runs [`Mode::Thesis`] with the same equations, thresholds and decisions
/// as `surfel_extract::extract`, on the thesis's isotropic field or Yu &
/// Turk's anisotropic one ([`Surface::Anisotropic`], whose kernels
/// [`GpuAnisotropy`] computes on the GPU), and [`Mode::Covered`]'s hole
/// closing after the first iteration (`shaders/fill.wgsl`: the same probes
/// and tests; a candidate covered by another is dropped when that one's
/// position hashes lower, where the CPU keeps the first in its order, so a
/// chain of overlapping candidates can lose more than the CPU's would, which
/// the next round's probes make up for), and either first split ([`Split`]).
/// Surfels are appended with atomic counters, so their order varies from run
/// to run (the set does not, up to float rounding). The result buffer holds
/// `vec4(position, radius), vec4(normal, 0)` per surfel — splat-render's splat
/// layout — and [`draw_args_buffer`](Self::draw_args_buffer) the matching
/// indirect draw (4 vertices, one instance per surfel).
pub struct GpuExtractor {
    uniform: Uniform,
    uniform_buffer: wgpu::Buffer,
    grid: GpuGrid,
    volumes: wgpu::Buffer,
    counters: wgpu::Buffer,
    /// Where `read_stats` reads the counters back (every frame in the demo).
    counters_readback: Staging,
    result: wgpu::Buffer,
    dispatch: wgpu::Buffer,
    draw: wgpu::Buffer,
    guess: (wgpu::ComputePipeline, wgpu::BindGroup),
    /// Per iteration: the prepare and refine passes.
    stages: Vec<[(wgpu::ComputePipeline, wgpu::BindGroup); 2]>,
    finish: (wgpu::ComputePipeline, wgpu::BindGroup),
    volumes_pass: wgpu::ComputePipeline,
    /// The anisotropic field's kernels, computed from the attached solver's
    /// particles (`None`: the isotropic field).
    anisotropy: Option<GpuAnisotropy>,
    /// The kernels the field reads (the anisotropy's, or a placeholder).
    kernels: wgpu::Buffer,
    /// Hole closing's passes, in [`Mode::Covered`].
    fill: Option<Fill>,
    /// Whether [`encode`](Self::encode) computes the kernels first (of
    /// particles [`upload`](Self::upload)ed; not of a CPU field's).
    kernels_pending: bool,
    /// The solver this extractor reads from, once [`attach`](Self::attach)ed:
    /// its positions buffer and the bind group of the volumes pass.
    attached: Option<(wgpu::Buffer, wgpu::BindGroup)>,
}

/// Records `pipeline` with its bind group, dispatched over `groups`.
fn run<'a>(
    (pipeline, group): &'a (wgpu::ComputePipeline, wgpu::BindGroup),
    groups: Groups<'a>,
) -> impl Fn(&mut wgpu::ComputePass<'_>) + 'a {
    move |pass| {
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, group, &[]);
        groups.dispatch(pass);
    }
}

/// Workgroups of 64 for `threads`, as an (x, y) grid within the 65,535 limit.
fn groups(threads: u32) -> (u32, u32) {
    let groups = threads.div_ceil(64).max(1);
    let y = groups.div_ceil(65_535);
    (groups.div_ceil(y), y)
}

impl GpuExtractor {
    /// An extractor for up to `particles` particles (room for one when 0:
    /// an empty set extracts nothing) that keeps up to `max_surfels`
    /// surfels per refinement level and in the result.
    ///
    /// # Errors
    /// [`GpuError::Params`] for parameters surfel-extract rejects (its
    /// reason) and an `h` outside [`sph_core::error::KERNEL_H_RANGE`];
    /// [`GpuError::Invalid`] for a zero `max_surfels`, or buffers beyond the
    /// device's storage binding limit.
    pub fn new(
        device: &wgpu::Device,
        particles: usize,
        max_surfels: usize,
        params: &ExtractParams,
    ) -> Result<Self, GpuError> {
        params.validate().map_err(GpuError::Params)?;
        sph_core::error::check_kernel_h(params.h).map_err(GpuError::Params)?;
        let particles = particles.max(1);
        let covered = params.mode == Mode::Covered;
        if max_surfels == 0 {
            return Err(GpuError::Invalid("max_surfels must be > 0"));
        }
        let limits = device.limits();
        let max_bytes = limits
            .max_storage_buffer_binding_size
            .min(limits.max_buffer_size);
        let surfel_bytes = (max_surfels as u64).saturating_mul(SURFEL_BYTES);
        if surfel_bytes > max_bytes || max_surfels > u32::MAX as usize {
            return Err(GpuError::Invalid(
                "max_surfels exceeds the device's storage buffer limit",
            ));
        }
        let grid = GpuGrid::new(device, particles, params.h, 1)?;
        let anisotropy = match params.surface {
            Surface::Anisotropic(a) => Some(GpuAnisotropy::new(device, particles, params.h, &a)?),
            Surface::Isotropic => None,
        };
        let h = params.h;
        let fill_thickness = surfel_extract::fill::thickness(params.surface) * h;
        let pi = std::f32::consts::PI;
        let uniform = Uniform {
            h,
            inv_h: 1.0 / h,
            n: 0,
            table: grid.table_size(),
            iso: params.iso,
            interior_step: params.interior_step,
            discard_step: params.discard_step,
            split_laplacian: params.split_laplacian,
            covariance_threshold: params.covariance_threshold,
            all_around: match params.all_around {
                AllAround::Six => 6,
                AllAround::Eight => 8,
            },
            radius: params.radius,
            has_camera: u32::from(params.camera.is_some()),
            camera: params.camera.unwrap_or_default().extend(0.0).to_array(),
            poly6: 315.0 / (64.0 * pi * h.powi(9)),
            poly6_grad: 945.0 / (32.0 * pi * h.powi(9)),
            work_capacity: max_surfels as u32,
            out_capacity: max_surfels as u32,
            anisotropic: u32::from(anisotropy.is_some()),
            // A probe is covered by a disc whose centre lies within
            // √(r² + (LOOSE × thickness)²) of it, r at most the guess's
            // radius.
            fill_cell: (params.radius * h).hypot(surfel_extract::fill::LOOSE * fill_thickness),
            fill_table: (2 * particles).next_power_of_two().max(1024) as u32,
            first_split: match params.first_split {
                Split::TwoByTwo => 2,
                Split::ThreeByThree => 3,
            },
            fill_capacity: fill_capacity(max_surfels) as u32,
            fill_thickness,
            pad1: 0,
            pad2: 0,
        };
        use wgpu::BufferUsages as U;
        let buffer = |label, size, usage| buffer(device, label, size, usage);
        let uniform_buffer = buffer(
            "extract params",
            size_of::<Uniform>() as u64,
            U::UNIFORM | U::COPY_DST,
        );
        let volumes = buffer(
            "extract volumes",
            4 * particles as u64,
            U::STORAGE | U::COPY_DST,
        );
        let kernels = match &anisotropy {
            Some(a) => a.kernels_buffer().clone(),
            None => buffer("no kernels", KERNEL_BYTES, U::STORAGE),
        };
        let counters = buffer(
            "extract counters",
            4 * COUNTERS,
            U::STORAGE | U::COPY_DST | U::COPY_SRC,
        );
        let work = [0, 1].map(|_| buffer("extract work", surfel_bytes, U::STORAGE));
        let result = buffer("surfels", surfel_bytes, U::STORAGE | U::COPY_SRC);
        let dispatch = buffer("extract dispatch", 12, U::STORAGE | U::INDIRECT);
        let draw = buffer(
            "surfel draw args",
            16,
            U::STORAGE | U::INDIRECT | U::COPY_SRC,
        );
        // In covered mode the first iteration keeps its refined surfels in
        // work buffer 1 for hole closing, which splits them into buffer 0.
        let stage_of = |i: u32| match (covered, i) {
            (true, 0) => (0, 1, false, true),
            (true, i) => ((i + 1) % 2, i % 2, i + 1 == params.iterations, false),
            (false, i) => (i % 2, (i + 1) % 2, i + 1 == params.iterations, false),
        };
        let stage_buffers: Vec<wgpu::Buffer> = (0..params.iterations)
            .map(|i| {
                let (src, dst, last, keep) = stage_of(i);
                let stage = Stage {
                    src,
                    dst,
                    last: u32::from(last),
                    iteration: i,
                    keep: u32::from(keep),
                    pad0: 0,
                    pad1: 0,
                    pad2: 0,
                };
                device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("extract stage"),
                    contents: bytemuck::bytes_of(&stage),
                    usage: U::UNIFORM,
                })
            })
            .collect();
        let module = shader(
            device,
            "extract.wgsl",
            concat!(
                include_str!("shaders/hash.wgsl"),
                include_str!("shaders/extract.wgsl"),
                include_str!("shaders/fill.wgsl")
            )
            .into(),
        );
        let pipeline = |entry: &str| pipeline(device, &module, entry);
        let field = [
            (0, &uniform_buffer),
            (1, grid.positions_buffer()),
            (2, grid.counts_buffer()),
            (3, grid.starts_buffer()),
            (4, grid.sorted_buffer()),
            (5, &volumes),
            (6, &counters),
            (15, &kernels),
        ];
        let guess_pipeline = pipeline("guess");
        let mut entries = field.to_vec();
        entries.extend([(8, &work[0]), (9, &result)]);
        let guess_group = bind_pairs(device, "guess", &guess_pipeline, &entries);
        let (prepare, refine) = (pipeline("prepare"), pipeline("refine"));
        let stages = (0..params.iterations as usize)
            .map(|i| {
                let stage = &stage_buffers[i];
                let prepare_group = bind_pairs(
                    device,
                    "prepare",
                    &prepare,
                    &[
                        (0, &uniform_buffer),
                        (6, &counters),
                        (10, stage),
                        (11, &dispatch),
                    ],
                );
                let (src, dst, _, _) = stage_of(i as u32);
                let mut entries = field.to_vec();
                entries.extend([
                    (7, &work[src as usize]),
                    (8, &work[dst as usize]),
                    (9, &result),
                    (10, stage),
                ]);
                let refine_group = bind_pairs(device, "refine", &refine, &entries);
                [
                    (prepare.clone(), prepare_group),
                    (refine.clone(), refine_group),
                ]
            })
            .collect();
        let finish_pipeline = pipeline("finish");
        let finish_group = bind_pairs(
            device,
            "finish",
            &finish_pipeline,
            &[(0, &uniform_buffer), (6, &counters), (12, &draw)],
        );
        let volumes_pass = pipeline("volumes_from_densities");
        let fill = covered
            .then(|| {
                Fill::new(
                    device,
                    &pipeline,
                    &field,
                    [&work[0], &work[1], &result],
                    &uniform,
                    params,
                )
            })
            .transpose()?;
        Ok(Self {
            uniform,
            uniform_buffer,
            grid,
            volumes,
            counters,
            counters_readback: Staging::new(device, 4 * COUNTERS),
            result,
            dispatch,
            draw,
            guess: (guess_pipeline, guess_group),
            stages,
            finish: (finish_pipeline, finish_group),
            volumes_pass,
            anisotropy,
            kernels,
            fill,
            kernels_pending: false,
            attached: None,
        })
    }

    /// The most surfels each buffer holds.
    pub fn capacity(&self) -> usize {
        self.uniform.out_capacity as usize
    }

    /// Uploads particle positions and volumes V = m/ρ; on the anisotropic
    /// field the next [`encode`](Self::encode) computes their kernels and
    /// centres first. (A CPU [`ColourField`]'s centres, volumes and kernels:
    /// [`upload_field`](Self::upload_field).)
    ///
    /// # Errors
    /// [`GpuError::Capacity`]; [`GpuError::Invalid`] for a length mismatch, a
    /// non-finite position or a volume that is not finite and positive;
    /// [`GpuError::Params`] for a position more than 2¹⁶ h from the origin
    /// ([`sph_core::error::check_precise`]).
    pub fn upload(
        &mut self,
        queue: &wgpu::Queue,
        positions: &[Vec3],
        volumes: &[f32],
    ) -> Result<(), GpuError> {
        self.upload_particles(queue, positions, volumes, true)
    }

    /// Uploads particles and volumes; with `kernels`, an anisotropic
    /// extractor's positions go to its kernel pass (which the next
    /// [`encode`](Self::encode) runs), else they are the field's centres.
    fn upload_particles(
        &mut self,
        queue: &wgpu::Queue,
        positions: &[Vec3],
        volumes: &[f32],
        kernels: bool,
    ) -> Result<(), GpuError> {
        if volumes.len() != positions.len() {
            return Err(GpuError::Invalid("need one volume per position"));
        }
        if volumes.iter().any(|v| !(v.is_finite() && *v > 0.0)) {
            return Err(GpuError::Invalid("volumes must be finite and > 0"));
        }
        sph_core::error::check_precise(positions, self.uniform.h).map_err(GpuError::Params)?;
        match self.anisotropy.as_mut() {
            Some(anisotropy) if kernels => {
                anisotropy.upload(queue, positions)?;
                self.grid.set_len(queue, positions.len());
            }
            _ => self.grid.upload(queue, positions)?,
        }
        self.kernels_pending = kernels && self.anisotropy.is_some();
        if !volumes.is_empty() {
            queue.write_buffer(&self.volumes, 0, bytemuck::cast_slice(volumes));
        }
        self.set_len(queue, positions.len());
        Ok(())
    }

    /// Uploads the particles (kernel centres) and volumes of a CPU colour
    /// field, and an anisotropic field's kernels: the GPU then extracts from
    /// the same field as `surfel_extract::extract_field`.
    ///
    /// # Errors
    /// As [`upload`](Self::upload), and [`GpuError::Invalid`] for a field of
    /// another smoothing length or of the other kind (isotropic or
    /// anisotropic) than the extractor's parameters.
    pub fn upload_field(
        &mut self,
        queue: &wgpu::Queue,
        field: &ColourField,
    ) -> Result<(), GpuError> {
        if field.h() != self.uniform.h {
            return Err(GpuError::Invalid(
                "the field's h differs from the extractor's",
            ));
        }
        let anisotropic = matches!(field.surface(), Surface::Anisotropic(_));
        if anisotropic != self.anisotropy.is_some() {
            return Err(GpuError::Invalid(
                "the field's surface (isotropic or anisotropic) differs from the extractor's",
            ));
        }
        self.upload_particles(queue, field.positions(), field.volumes(), false)?;
        if anisotropic && !field.is_empty() {
            let rows: Vec<[f32; 8]> = (field.shapes().iter())
                .map(|e| {
                    let [xx, xy, xz, yy, yz, zz] = e.m;
                    [
                        xx,
                        xy,
                        xz,
                        yy,
                        yz,
                        zz,
                        e.det,
                        f32::from(u8::from(e.isolated)),
                    ]
                })
                .collect();
            queue.write_buffer(&self.kernels, 0, bytemuck::cast_slice(&rows));
        }
        Ok(())
    }

    /// Culls back-facing surfels for an eye at `camera` from the next
    /// extraction on (`None`: keeps every surfel), as
    /// [`ExtractParams::camera`] does.
    ///
    /// # Errors
    /// [`GpuError::Invalid`] for a non-finite eye position.
    pub fn set_camera(
        &mut self,
        queue: &wgpu::Queue,
        camera: Option<Vec3>,
    ) -> Result<(), GpuError> {
        if camera.is_some_and(|c| !c.is_finite()) {
            return Err(GpuError::Invalid("the camera position must be finite"));
        }
        self.uniform.has_camera = u32::from(camera.is_some());
        self.uniform.camera = camera.unwrap_or_default().extend(0.0).to_array();
        queue.write_buffer(&self.uniform_buffer, 0, bytemuck::bytes_of(&self.uniform));
        Ok(())
    }

    fn set_len(&mut self, queue: &wgpu::Queue, n: usize) {
        self.uniform.n = n as u32;
        queue.write_buffer(&self.uniform_buffer, 0, bytemuck::bytes_of(&self.uniform));
    }

    /// Reads the particles of `solver` from now on: [`encode_attached`](Self::encode_attached)
    /// copies its positions and computes volumes m/ρ from its densities on the
    /// GPU.
    ///
    /// # Errors
    /// [`GpuError::Capacity`] for more particles than this extractor's capacity,
    /// [`GpuError::Invalid`] for a solver of another smoothing length.
    pub fn attach(
        &mut self,
        device: &wgpu::Device,
        solver: &dyn GpuParticles,
    ) -> Result<(), GpuError> {
        if solver.len() > self.grid.capacity() {
            return Err(GpuError::Capacity {
                given: solver.len(),
                capacity: self.grid.capacity(),
            });
        }
        if solver.h() != self.uniform.h {
            return Err(GpuError::Invalid(
                "the solver's h differs from the extractor's",
            ));
        }
        let group = bind_pairs(
            device,
            "volumes from densities",
            &self.volumes_pass,
            &[
                (0, &self.uniform_buffer),
                (1, self.grid.positions_buffer()),
                (13, solver.densities_buffer()),
                (14, &self.volumes),
            ],
        );
        self.attached = Some((solver.positions_buffer().clone(), group));
        self.uniform.n = solver.len() as u32;
        Ok(())
    }

    /// Records the extraction of the attached solver's current particles: a
    /// copy of its positions, volumes from its densities, then
    /// [`encode`](Self::encode). Nothing is read back.
    ///
    /// # Errors
    /// [`GpuError::Invalid`] when no solver is attached.
    pub fn encode_attached(
        &mut self,
        queue: &wgpu::Queue,
        encoder: &mut wgpu::CommandEncoder,
    ) -> Result<(), GpuError> {
        self.encode_attached_timed(queue, encoder, None)
    }

    /// [`encode_attached`](Self::encode_attached) with each compute pass
    /// timed by `profiler` ("extract: volumes", the grid's "grid: …",
    /// "extract: guess", then per iteration i "extract: prepare i" and
    /// "extract: refine i", "extract: finish"). The caller resolves the
    /// profiler's queries and ends its frame.
    ///
    /// # Errors
    /// As [`encode_attached`](Self::encode_attached).
    pub fn encode_attached_profiled(
        &mut self,
        queue: &wgpu::Queue,
        encoder: &mut wgpu::CommandEncoder,
        profiler: &GpuProfiler,
    ) -> Result<(), GpuError> {
        self.encode_attached_timed(queue, encoder, Some(profiler))
    }

    fn encode_attached_timed(
        &mut self,
        queue: &wgpu::Queue,
        encoder: &mut wgpu::CommandEncoder,
        profiler: Option<&GpuProfiler>,
    ) -> Result<(), GpuError> {
        let Some((positions, group)) = &self.attached else {
            return Err(GpuError::Invalid("no solver attached"));
        };
        let n = self.uniform.n as usize;
        // The field's particles: the solver's, or the anisotropic kernels'
        // centres computed from them (with the masses in w).
        let source = match self.anisotropy.as_mut() {
            Some(anisotropy) => {
                anisotropy.set_len(queue, n)?;
                anisotropy.record(encoder, Some(positions), profiler);
                anisotropy.centres_buffer()
            }
            None => positions,
        };
        self.kernels_pending = false;
        encoder.copy_buffer_to_buffer(
            source,
            0,
            self.grid.positions_buffer(),
            0,
            Some((16 * n as u64).max(16).min(source.size())),
        );
        timed_pass(encoder, profiler, "extract: volumes", |pass| {
            pass.set_pipeline(&self.volumes_pass);
            pass.set_bind_group(0, group, &[]);
            let (x, y) = groups(n as u32);
            pass.dispatch_workgroups(x, y, 1);
        });
        self.grid.set_len(queue, n);
        self.set_len(queue, n);
        self.encode_timed(encoder, profiler);
        Ok(())
    }

    /// Records the extraction of the uploaded particles: grid build, initial
    /// guess, the refinement iterations, the indirect draw arguments.
    pub fn encode(&self, encoder: &mut wgpu::CommandEncoder) {
        self.encode_timed(encoder, None);
    }

    fn encode_timed(&self, encoder: &mut wgpu::CommandEncoder, profiler: Option<&GpuProfiler>) {
        const PREPARE: [&str; 3] = [
            "extract: prepare 1",
            "extract: prepare 2",
            "extract: prepare 3",
        ];
        const REFINE: [&str; 3] = [
            "extract: refine 1",
            "extract: refine 2",
            "extract: refine 3",
        ];
        if let (true, Some(anisotropy)) = (self.kernels_pending, &self.anisotropy) {
            anisotropy.record(encoder, None, profiler);
            let bytes = 16 * u64::from(self.uniform.n);
            if bytes > 0 {
                encoder.copy_buffer_to_buffer(
                    anisotropy.centres_buffer(),
                    0,
                    self.grid.positions_buffer(),
                    0,
                    bytes,
                );
            }
        }
        self.grid.encode_build_gated(encoder, None, profiler);
        encoder.clear_buffer(&self.counters, 0, None);
        let (x, y) = groups(self.uniform.n);
        let guess = run(&self.guess, Groups::DirectXY(x, y));
        let iterations: Vec<_> = self
            .stages
            .iter()
            .map(|[prepare, refine]| {
                (
                    run(prepare, Groups::Direct(1)),
                    run(refine, Groups::Indirect(&self.dispatch, 0)),
                )
            })
            .collect();
        let finish = run(&self.finish, Groups::Direct(1));
        let fill = self.fill.as_ref().map(Fill::records);
        let mut stages: Vec<PassStage<'_>> = vec![("extract: guess", &guess)];
        for (i, (prepare, refine)) in iterations.iter().enumerate() {
            stages.push((PREPARE[i], prepare));
            stages.push((REFINE[i], refine));
            if let (0, Some(fill)) = (i, &fill) {
                for record in fill {
                    stages.push(("extract: fill", record.as_ref()));
                }
            }
        }
        stages.push(("extract: finish", &finish));
        staged_pass(encoder, profiler, "surfel extraction", &stages);
    }

    /// The surfels of the last extraction, [`SURFEL_BYTES`] each:
    /// `vec4(position, radius), vec4(normal, 0)`.
    pub fn surfels_buffer(&self) -> &wgpu::Buffer {
        &self.result
    }

    /// The indirect draw of the last extraction's surfels:
    /// `[4, surfels, 0, 0]` (`wgpu::util::DrawIndirectArgs`).
    pub fn draw_args_buffer(&self) -> &wgpu::Buffer {
        &self.draw
    }

    /// Reads the counters of the last extraction back.
    ///
    /// # Errors
    /// [`GpuError::Readback`].
    pub fn read_stats(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
    ) -> Result<GpuExtractStats, GpuError> {
        let encoder = device.create_command_encoder(&Default::default());
        let bytes =
            (self.counters_readback).read(device, queue, encoder, &self.counters, 4 * COUNTERS)?;
        let c: Vec<u32> = bytemuck::pod_collect_to_vec(&bytes);
        let n = self.uniform.n as usize;
        Ok(GpuExtractStats {
            particles: n,
            surface_particles: c[SURFACE_PARTICLES] as usize,
            all_around: c[ALL_AROUND] as usize,
            lone: c[LONE] as usize,
            droplets: c[DROPLETS] as usize,
            filled: c[FILLED] as usize,
            discarded: c[DISCARDED] as usize,
            surfels: c[OUT].min(self.uniform.out_capacity) as usize,
            dropped: c[DROPPED] as usize,
            particle_evaluations: n as u64,
            evaluations: c[EVALUATED..EVALUATED + self.stages.len()]
                .iter()
                .map(|&k| u64::from(k))
                .sum(),
        })
    }

    /// Reads the last extraction's surfels and counters back (tests, export).
    ///
    /// # Errors
    /// [`GpuError::Readback`].
    pub fn read_surfels(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
    ) -> Result<(Vec<Surfel>, GpuExtractStats), GpuError> {
        let stats = self.read_stats(device, queue)?;
        let encoder = device.create_command_encoder(&Default::default());
        let bytes = read(
            device,
            queue,
            encoder,
            &self.result,
            stats.surfels as u64 * SURFEL_BYTES,
        )?;
        let raw: Vec<[f32; 8]> = bytemuck::pod_collect_to_vec(&bytes);
        let surfels = raw
            .iter()
            .map(|v| Surfel {
                position: Vec3::new(v[0], v[1], v[2]),
                normal: Vec3::new(v[4], v[5], v[6]),
                radius: v[3],
            })
            .collect();
        Ok((surfels, stats))
    }
}

/// Bytes of one hole-closing candidate (`struct Candidate`: a surfel and its
/// key).
const CANDIDATE_BYTES: u64 = 48;

/// Hole closing's candidates per round for buffers of `max_surfels`: a
/// quarter (holes are a small part of a surface; more are counted as
/// dropped, and the app grows its buffers).
fn fill_capacity(max_surfels: usize) -> usize {
    (max_surfels / 4).max(1024)
}

type Bound = (wgpu::ComputePipeline, wgpu::BindGroup);

/// Hole closing's passes ([`Mode::Covered`], `shaders/fill.wgsl`) and
/// buffers: per round, the surfel grid's linked lists built and probed,
/// then the candidates' built and judged; then the split.
struct Fill {
    args: wgpu::Buffer,
    /// Buckets of the lists: `fill_table` of them.
    buckets: u32,
    rounds: u32,
    prepare: Bound,
    clear: Bound,
    insert_kept: Bound,
    probe: Bound,
    prepare_dedup: Bound,
    insert_candidates: Bound,
    dedup: Bound,
    prepare_split: Bound,
    /// `split_kept`, or `kept_to_out` after a single iteration.
    split: Bound,
    /// After a single iteration: the lone particles' surfels into the kept
    /// ones (prepare, move, reset).
    lone: Option<[Bound; 3]>,
}

impl Fill {
    /// The passes over the field's bindings `field` and the work buffers
    /// and result `[work 0, work 1 (the kept surfels), result]`, sized by
    /// `uniform`'s capacities, for `params`' iterations and rounds.
    fn new<'a>(
        device: &wgpu::Device,
        pipeline: &dyn Fn(&str) -> wgpu::ComputePipeline,
        field: &[(u32, &'a wgpu::Buffer)],
        [work0, kept, result]: [&'a wgpu::Buffer; 3],
        uniform: &Uniform,
        params: &ExtractParams,
    ) -> Result<Self, GpuError> {
        let single_iteration = params.iterations == 1;
        use wgpu::BufferUsages as U;
        let limits = device.limits();
        let candidates_cap = u64::from(uniform.fill_capacity);
        if candidates_cap * CANDIDATE_BYTES
            > limits
                .max_storage_buffer_binding_size
                .min(limits.max_buffer_size)
        {
            return Err(GpuError::Invalid(
                "hole closing's candidates exceed the device's storage buffer limit: lower max_surfels",
            ));
        }
        let heads = buffer(
            device,
            "fill heads",
            4 * u64::from(uniform.fill_table),
            U::STORAGE,
        );
        let kept_next = buffer(
            device,
            "fill kept lists",
            4 * u64::from(uniform.work_capacity),
            U::STORAGE,
        );
        let candidates = buffer(
            device,
            "fill candidates",
            candidates_cap * CANDIDATE_BYTES,
            U::STORAGE,
        );
        let candidate_next = buffer(
            device,
            "fill candidate lists",
            4 * candidates_cap,
            U::STORAGE,
        );
        let args = buffer(device, "fill dispatch", 60, U::STORAGE | U::INDIRECT);
        let (e, counters) = (field[0].1, field[6].1);
        let bound = |entry: &str, entries: &[(u32, &wgpu::Buffer)]| {
            let p = pipeline(entry);
            let group = bind_pairs(device, entry, &p, entries);
            (p, group)
        };
        let mut probe_entries = field.to_vec();
        probe_entries.extend([(8, kept), (16, &heads), (17, &kept_next), (18, &candidates)]);
        let (split_entry, split_out) = if single_iteration {
            ("kept_to_out", (9, result))
        } else {
            ("split_kept", (8, work0))
        };
        Ok(Self {
            buckets: uniform.fill_table,
            rounds: params.fill_rounds,
            prepare: bound("fill_prepare", &[(0, e), (6, counters), (20, &args)]),
            clear: bound("clear_heads", &[(0, e), (16, &heads)]),
            insert_kept: bound(
                "insert_kept",
                &[
                    (0, e),
                    (6, counters),
                    (8, kept),
                    (16, &heads),
                    (17, &kept_next),
                ],
            ),
            probe: bound("probe", &probe_entries),
            prepare_dedup: bound("fill_prepare_dedup", &[(0, e), (6, counters), (20, &args)]),
            insert_candidates: bound(
                "insert_candidates",
                &[
                    (0, e),
                    (6, counters),
                    (16, &heads),
                    (18, &candidates),
                    (19, &candidate_next),
                ],
            ),
            dedup: bound(
                "dedup",
                &[
                    (0, e),
                    (6, counters),
                    (8, kept),
                    (16, &heads),
                    (18, &candidates),
                    (19, &candidate_next),
                ],
            ),
            prepare_split: bound("fill_prepare_split", &[(0, e), (6, counters), (20, &args)]),
            split: bound(split_entry, &[(0, e), (6, counters), (7, kept), split_out]),
            lone: single_iteration.then(|| {
                [
                    bound("fill_prepare_lone", &[(0, e), (6, counters), (20, &args)]),
                    bound(
                        "lone_to_kept",
                        &[(0, e), (6, counters), (8, kept), (9, result)],
                    ),
                    bound("lone_reset", &[(6, counters)]),
                ]
            }),
            args,
        })
    }

    /// What the rounds and the split record, in order.
    fn records(&self) -> Vec<Recorder<'_>> {
        let clear_groups = self.buckets.div_ceil(256);
        let args = &self.args;
        let mut out = Vec::new();
        if let Some([prepare, to_kept, reset]) = &self.lone {
            out.push(direct(prepare, 1));
            out.push(indirect(to_kept, args, 48));
            out.push(direct(reset, 1));
        }
        for _ in 0..self.rounds {
            out.push(direct(&self.prepare, 1));
            out.push(direct(&self.clear, clear_groups));
            out.push(indirect(&self.insert_kept, args, 12));
            out.push(indirect(&self.probe, args, 0));
            out.push(direct(&self.prepare_dedup, 1));
            out.push(direct(&self.clear, clear_groups));
            out.push(indirect(&self.insert_candidates, args, 24));
            out.push(indirect(&self.dedup, args, 24));
        }
        out.push(direct(&self.prepare_split, 1));
        out.push(indirect(&self.split, args, 36));
        out
    }
}

/// What one dispatch records into a compute pass.
type Recorder<'a> = Box<dyn for<'p> Fn(&mut wgpu::ComputePass<'p>) + 'a>;

/// `bound`'s dispatch over `x` workgroups.
fn direct(bound: &Bound, x: u32) -> Recorder<'_> {
    let (pipeline, group) = bound;
    Box::new(move |pass| {
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, group, &[]);
        pass.dispatch_workgroups(x, 1, 1);
    })
}

/// `bound`'s dispatch over the workgroups at byte `at` of `args`.
fn indirect<'a>(bound: &'a Bound, args: &'a wgpu::Buffer, at: u64) -> Recorder<'a> {
    let (pipeline, group) = bound;
    Box::new(move |pass| {
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, group, &[]);
        pass.dispatch_workgroups_indirect(args, at);
    })
}

#[cfg(test)]
mod tests {
    use super::{Stage, Uniform};

    #[test]
    fn layouts_match_their_wgsl() {
        let source = concat!(
            include_str!("shaders/hash.wgsl"),
            include_str!("shaders/extract.wgsl"),
            include_str!("shaders/fill.wgsl")
        );
        splat_render::wgsl_layout!(
            source,
            "Extract",
            Uniform {
                h,
                inv_h,
                n,
                table,
                iso,
                interior_step,
                discard_step,
                split_laplacian,
                covariance_threshold,
                all_around,
                radius,
                has_camera,
                camera,
                poly6,
                poly6_grad,
                work_capacity,
                out_capacity,
                anisotropic,
                fill_cell,
                fill_table,
                first_split,
                fill_capacity,
                fill_thickness,
                pad1,
                pad2
            }
        )
        .unwrap();
        splat_render::wgsl_layout!(
            source,
            "Stage",
            Stage {
                src,
                dst,
                last,
                iteration,
                keep,
                pad0,
                pad1,
                pad2
            }
        )
        .unwrap();
    }
}
