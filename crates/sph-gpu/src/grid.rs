//! [`GpuGrid`]: the neighbour grid as compute passes.

use bytemuck::{Pod, Zeroable};
use glam::Vec3;
use thiserror::Error;

use wgpu_profiler::GpuProfiler;

use crate::passes::{Groups, PassStage, bind_buffers, check_fits, read, staged_pass};

/// What can go wrong on the GPU path.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum GpuError {
    /// More positions than the grid was created for.
    #[error("{given} positions exceed the grid's capacity of {capacity}")]
    Capacity {
        /// Positions given.
        given: usize,
        /// Capacity.
        capacity: usize,
    },
    /// A smoothing length that is not finite and positive, or a non-finite position.
    #[error("invalid input: {0}")]
    Invalid(&'static str),
    /// Parameters that sph-core or surfel-extract reject, with their reason.
    #[error("invalid parameters: {0}")]
    Params(sph_core::Error),
    /// The adaptive step fell below its minimum or became NaN (a blow-up).
    #[error("the GPU simulation became unstable: {0}")]
    Unstable(String),
    /// More particles or surfels than this device's dispatch or buffer limits
    /// allow.
    #[error("{0}")]
    DeviceLimit(String),
    /// Reading results back failed.
    #[error("GPU readback failed: {0}")]
    Readback(String),
}

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct Params {
    h: f32,
    inv_h: f32,
    n: u32,
    table: u32,
    max_neighbours: u32,
    pad: [u32; 3],
}

const PASSES: [&str; 7] = [
    "clear_counts",
    "count_cells",
    "scan_blocks",
    "scan_block_sums",
    "add_block_sums",
    "scatter",
    "sort_buckets",
];

/// Which of [`GpuGrid::build_groups`]' kinds each of `PASSES` dispatches.
const KINDS: [usize; 7] = [0, 1, 0, 2, 0, 1, 0];

/// The passes' labels (debug labels and profiler scopes).
const LABELS: [&str; 7] = [
    "grid: clear_counts",
    "grid: count_cells",
    "grid: scan_blocks",
    "grid: scan_block_sums",
    "grid: add_block_sums",
    "grid: scatter",
    "grid: sort_buckets",
];

/// A uniform grid of cell size h over particles kept on the GPU, rebuilt by
/// [`encode_build`](Self::encode_build) without leaving the GPU.
///
/// Cells are hashed into a power-of-two table (≥ 2 × capacity buckets), so an
/// unbounded domain costs no memory, or, for a grid [`in_box`](Self::in_box),
/// laid out one bucket per cell of the box; each bucket's particles are
/// sorted by index, making every later sum over a neighbourhood
/// deterministic.
pub struct GpuGrid {
    capacity: usize,
    n: u32,
    table: u32,
    cells: Option<CellBox>,
    h: f32,
    params: wgpu::Buffer,
    positions: wgpu::Buffer,
    counts: wgpu::Buffer,
    starts: wgpu::Buffer,
    sorted: wgpu::Buffer,
    lists: wgpu::Buffer,
    list_len: wgpu::Buffer,
    max_neighbours: u32,
    bind_group: wgpu::BindGroup,
    pipelines: Vec<wgpu::ComputePipeline>,
    query: wgpu::ComputePipeline,
}

/// The cells of a box, one bucket each (`hash.wgsl`'s `BOX_*` overrides).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct CellBox {
    min: [i32; 3],
    dims: [i32; 3],
}

impl CellBox {
    /// The cells of size h covering `min..=max`, if there are no more than
    /// `most` and the box is finite.
    fn covering(min: Vec3, max: Vec3, h: f32, most: u64) -> Option<Self> {
        if !(min.is_finite() && max.is_finite() && min.cmple(max).all()) {
            return None;
        }
        let lo = (min / h).floor();
        let hi = (max / h).floor();
        let dims = hi - lo + Vec3::ONE;
        let count = f64::from(dims.x) * f64::from(dims.y) * f64::from(dims.z);
        if count > most as f64 || lo.abs().max_element() > 1e9 {
            return None;
        }
        Some(Self {
            min: lo.as_ivec3().to_array(),
            dims: dims.as_ivec3().to_array(),
        })
    }

    fn count(&self) -> u64 {
        self.dims.iter().map(|&d| d as u64).product()
    }
}

fn storage(
    device: &wgpu::Device,
    label: &str,
    bytes: u64,
    extra: wgpu::BufferUsages,
) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: bytes.max(16),
        usage: wgpu::BufferUsages::STORAGE | extra,
        mapped_at_creation: false,
    })
}

impl GpuGrid {
    /// A grid for up to `capacity` particles with cell size (and search radius) `h`;
    /// [`neighbour_lists`](Self::neighbour_lists) keeps up to `max_neighbours` per particle.
    ///
    /// # Errors
    /// [`GpuError::Invalid`] for a non-finite or non-positive `h` or a zero
    /// capacity; [`GpuError::DeviceLimit`] for more particles than one
    /// dispatch or storage binding of this device covers.
    pub fn new(
        device: &wgpu::Device,
        capacity: usize,
        h: f32,
        max_neighbours: u32,
    ) -> Result<Self, GpuError> {
        Self::build(device, capacity, h, max_neighbours, None)
    }

    /// [`new`](Self::new) for particles that stay inside `min..=max` (a
    /// solver's domain): one bucket per cell of the box, in x-fastest order,
    /// so that a sweep in bucket order walks space (neighbouring particles
    /// are neighbours in memory) and no two cells of the box share a bucket.
    /// A box of more than 8 × `capacity` cells (a domain far larger than
    /// its fluid) is hashed as by [`new`](Self::new). A particle outside the
    /// box is still found: its cell wraps onto one inside.
    ///
    /// # Errors
    /// As [`new`](Self::new).
    pub fn in_box(
        device: &wgpu::Device,
        capacity: usize,
        h: f32,
        max_neighbours: u32,
        min: Vec3,
        max: Vec3,
    ) -> Result<Self, GpuError> {
        let most = (capacity.max(32) as u64).saturating_mul(8);
        let cells = (h.is_finite() && h > 0.0)
            .then(|| CellBox::covering(min, max, h, most))
            .flatten();
        Self::build(device, capacity, h, max_neighbours, cells)
    }

    fn build(
        device: &wgpu::Device,
        capacity: usize,
        h: f32,
        max_neighbours: u32,
        cells: Option<CellBox>,
    ) -> Result<Self, GpuError> {
        if !(h.is_finite() && h > 0.0) {
            return Err(GpuError::Invalid("h must be finite and > 0"));
        }
        if capacity == 0 || max_neighbours == 0 {
            return Err(GpuError::Invalid("capacity and max_neighbours must be > 0"));
        }
        let per_particle = (4 * u64::from(max_neighbours)).max(16);
        check_fits(device, "particles", capacity, 64, per_particle)?;
        let table = match cells {
            Some(cells) => (cells.count() as usize).next_multiple_of(256),
            None => (2 * capacity).next_power_of_two().max(256),
        };
        check_fits(device, "hash buckets", table, 256, 4)?;
        let table = table as u32;
        let n_bytes = 4 * capacity as u64;
        let t_bytes = 4 * u64::from(table);
        use wgpu::BufferUsages as U;
        let params = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("grid params"),
            size: size_of::<Params>() as u64,
            usage: U::UNIFORM | U::COPY_DST,
            mapped_at_creation: false,
        });
        let positions = storage(
            device,
            "grid positions",
            16 * capacity as u64,
            U::COPY_DST | U::COPY_SRC,
        );
        let keys = storage(device, "grid keys", n_bytes, U::empty());
        let ranks = storage(device, "grid ranks", n_bytes, U::empty());
        let counts = storage(device, "grid counts", t_bytes, U::COPY_SRC);
        let starts = storage(device, "grid starts", t_bytes, U::COPY_SRC);
        let block_sums = storage(device, "grid block sums", t_bytes / 256, U::empty());
        let sorted = storage(device, "grid sorted", n_bytes, U::COPY_SRC);
        let lists = storage(
            device,
            "neighbour lists",
            n_bytes * u64::from(max_neighbours),
            U::COPY_SRC,
        );
        let list_len = storage(device, "neighbour counts", n_bytes, U::COPY_SRC);

        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("grid.wgsl"),
            source: wgpu::ShaderSource::Wgsl(
                concat!(
                    include_str!("shaders/hash.wgsl"),
                    include_str!("shaders/grid.wgsl")
                )
                .into(),
            ),
        });
        let entry = |binding, read_only| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Buffer {
                ty: if binding == 0 {
                    wgpu::BufferBindingType::Uniform
                } else {
                    wgpu::BufferBindingType::Storage { read_only }
                },
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        };
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("grid layout"),
            entries: &(0..10).map(|b| entry(b, b == 1)).collect::<Vec<_>>(),
        });
        let buffers = [
            &params,
            &positions,
            &keys,
            &ranks,
            &counts,
            &starts,
            &block_sums,
            &sorted,
            &lists,
            &list_len,
        ];
        let bind_group = bind_buffers(device, "grid bind group", &layout, &buffers);
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("grid pipeline layout"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let constants = box_constants(cells);
        let pipeline = |entry: &str| {
            device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(entry),
                layout: Some(&pipeline_layout),
                module: &module,
                entry_point: Some(entry),
                compilation_options: wgpu::PipelineCompilationOptions {
                    constants: &constants,
                    ..Default::default()
                },
                cache: None,
            })
        };
        Ok(Self {
            capacity,
            n: 0,
            table,
            cells,
            h,
            params,
            positions,
            counts,
            starts,
            sorted,
            lists,
            list_len,
            max_neighbours,
            bind_group,
            pipelines: PASSES.iter().map(|e| pipeline(e)).collect(),
            query: pipeline("neighbour_lists"),
        })
    }

    /// Hash buckets in the table.
    pub fn table_size(&self) -> u32 {
        self.table
    }

    /// Whether its buckets are the cells of a box ([`in_box`](Self::in_box)).
    pub fn is_box(&self) -> bool {
        self.cells.is_some()
    }

    /// The pipeline constants that make `hash.wgsl`'s `bucket_of` this
    /// grid's, for passes of other modules that walk its cells.
    pub(crate) fn bucket_constants(&self) -> Vec<(&'static str, f64)> {
        box_constants(self.cells)
    }

    /// Uploads particle positions (up to the capacity).
    ///
    /// # Errors
    /// [`GpuError::Capacity`], or [`GpuError::Invalid`] for a non-finite position.
    pub fn upload(&mut self, queue: &wgpu::Queue, positions: &[Vec3]) -> Result<(), GpuError> {
        self.upload_with_masses(queue, positions, None)
    }

    /// Uploads positions and, for the SPH passes, masses (stored in the
    /// position's w; 1 without masses).
    ///
    /// # Errors
    /// [`GpuError::Capacity`], or [`GpuError::Invalid`] for a non-finite
    /// position, a mass that is not finite and positive, or a mass count
    /// that differs from the positions'.
    pub fn upload_with_masses(
        &mut self,
        queue: &wgpu::Queue,
        positions: &[Vec3],
        masses: Option<&[f32]>,
    ) -> Result<(), GpuError> {
        if masses.is_some_and(|m| {
            m.len() != positions.len() || m.iter().any(|m| !(m.is_finite() && *m > 0.0))
        }) {
            return Err(GpuError::Invalid(
                "need one finite, positive mass per position",
            ));
        }
        if positions.len() > self.capacity {
            return Err(GpuError::Capacity {
                given: positions.len(),
                capacity: self.capacity,
            });
        }
        if positions.iter().any(|x| !x.is_finite()) {
            return Err(GpuError::Invalid("a position is not finite"));
        }
        let data: Vec<[f32; 4]> = positions
            .iter()
            .enumerate()
            .map(|(i, x)| x.extend(masses.map_or(1.0, |m| m[i])).to_array())
            .collect();
        if !data.is_empty() {
            queue.write_buffer(&self.positions, 0, bytemuck::cast_slice(&data));
        }
        self.set_len(queue, positions.len());
        Ok(())
    }

    /// Sets the particle count of the positions buffer (filled on the GPU).
    pub(crate) fn set_len(&mut self, queue: &wgpu::Queue, n: usize) {
        self.n = n as u32;
        let params = Params {
            h: self.h,
            inv_h: 1.0 / self.h,
            n: self.n,
            table: self.table,
            max_neighbours: self.max_neighbours,
            pad: [0; 3],
        };
        queue.write_buffer(&self.params, 0, bytemuck::bytes_of(&params));
    }

    /// The most particles the grid holds.
    pub fn capacity(&self) -> usize {
        self.capacity
    }

    /// Records the build: clear, count, scan, scatter, per-bucket sort.
    pub fn encode_build(&self, encoder: &mut wgpu::CommandEncoder) {
        self.encode_build_gated(encoder, None, None);
    }

    /// Workgroups of the build's three kinds of pass: over the hash buckets,
    /// over the particles, and one.
    pub(crate) fn build_groups(&self) -> [u32; 3] {
        [self.table / 256, self.n.div_ceil(256).max(1), 1]
    }

    /// The build, its workgroup counts given here or, with `gate`, read from
    /// its first three `[x, y, z]` triples (in [`build_groups`](Self::build_groups)'
    /// order): a pass that writes zeros there turns the build off on the GPU.
    /// One compute pass, or one timed pass per stage with a `profiler`.
    pub(crate) fn encode_build_gated(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        gate: Option<&wgpu::Buffer>,
        profiler: Option<&GpuProfiler>,
    ) {
        let counts = self.build_groups();
        let record = |k: usize| {
            move |pass: &mut wgpu::ComputePass<'_>| {
                pass.set_bind_group(0, &self.bind_group, &[]);
                pass.set_pipeline(&self.pipelines[k]);
                match gate {
                    None => Groups::Direct(counts[KINDS[k]]),
                    Some(buffer) => Groups::Indirect(buffer, 12 * KINDS[k] as u64),
                }
                .dispatch(pass);
            }
        };
        let records: [_; 7] = std::array::from_fn(record);
        let stages: [PassStage<'_>; 7] = std::array::from_fn(|k| (LABELS[k], &records[k] as _));
        staged_pass(encoder, profiler, "grid build", &stages);
    }

    /// Records the build's passes into an open compute pass (each dispatch
    /// sees the one before: wgpu orders a pass's dispatches over the buffers
    /// they share).
    /// With `gate`, the workgroup counts are read from its first three
    /// `[x, y, z]` triples, as [`encode_build_gated`](Self::encode_build_gated)
    /// reads them.
    pub(crate) fn record_build(
        &self,
        pass: &mut wgpu::ComputePass<'_>,
        gate: Option<&wgpu::Buffer>,
    ) {
        let counts = self.build_groups();
        pass.set_bind_group(0, &self.bind_group, &[]);
        for (pipeline, kind) in self.pipelines.iter().zip(KINDS) {
            pass.set_pipeline(pipeline);
            match gate {
                None => Groups::Direct(counts[kind]),
                Some(buffer) => Groups::Indirect(buffer, 12 * kind as u64),
            }
            .dispatch(pass);
        }
    }

    /// The neighbour lists, `max_neighbours` slots of `u32` per particle.
    pub(crate) fn lists_buffer(&self) -> &wgpu::Buffer {
        &self.lists
    }

    /// Per particle: how many neighbours the list pass found (possibly more
    /// than it kept).
    pub(crate) fn list_len_buffer(&self) -> &wgpu::Buffer {
        &self.list_len
    }

    /// Particles in the last upload.
    pub fn len(&self) -> usize {
        self.n as usize
    }

    /// Whether the last upload was empty.
    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// Smoothing length (cell size).
    pub fn h(&self) -> f32 {
        self.h
    }

    /// Positions (xyz) and masses (w), `vec4<f32>` per particle.
    pub fn positions_buffer(&self) -> &wgpu::Buffer {
        &self.positions
    }

    /// The particle indices sorted by bucket (a storage buffer of `u32`).
    pub fn sorted_buffer(&self) -> &wgpu::Buffer {
        &self.sorted
    }

    /// Per bucket: the first slot in [`sorted_buffer`](Self::sorted_buffer).
    pub fn starts_buffer(&self) -> &wgpu::Buffer {
        &self.starts
    }

    /// Per bucket: how many particles it holds (`atomic<u32>` on the GPU).
    pub fn counts_buffer(&self) -> &wgpu::Buffer {
        &self.counts
    }

    /// Builds the grid and returns, per particle, every j with |x_i − x_j| ≤ h
    /// (i included) in the grid's deterministic order, and how many there were
    /// in all (more than `max_neighbours` means the list was cut). For tests and
    /// debugging: it reads back to the CPU.
    ///
    /// # Errors
    /// [`GpuError::Readback`].
    pub fn neighbour_lists(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
    ) -> Result<Vec<(u32, Vec<u32>)>, GpuError> {
        let mut encoder = device.create_command_encoder(&Default::default());
        self.encode_build(&mut encoder);
        {
            let mut pass = encoder.begin_compute_pass(&Default::default());
            pass.set_bind_group(0, &self.bind_group, &[]);
            pass.set_pipeline(&self.query);
            pass.dispatch_workgroups(self.n.div_ceil(64).max(1), 1, 1);
        }
        let n = self.n as u64;
        let k = u64::from(self.max_neighbours);
        let lens = read(device, queue, encoder, &self.list_len, 4 * n)?;
        let encoder = device.create_command_encoder(&Default::default());
        let lists = read(device, queue, encoder, &self.lists, 4 * n * k)?;
        let lens: Vec<u32> = bytemuck::pod_collect_to_vec(&lens);
        let lists: Vec<u32> = bytemuck::pod_collect_to_vec(&lists);
        Ok(lens
            .iter()
            .enumerate()
            .map(|(i, &len)| {
                let start = i * k as usize;
                (
                    len,
                    lists[start..start + (len as usize).min(k as usize)].to_vec(),
                )
            })
            .collect())
    }
}

/// `hash.wgsl`'s `BOX_*` overrides for `cells` (none: hashed).
fn box_constants(cells: Option<CellBox>) -> Vec<(&'static str, f64)> {
    let Some(CellBox { min, dims }) = cells else {
        return Vec::new();
    };
    vec![
        ("BOX_CELLS", 1.0),
        ("BOX_MIN_X", f64::from(min[0])),
        ("BOX_MIN_Y", f64::from(min[1])),
        ("BOX_MIN_Z", f64::from(min[2])),
        ("BOX_DIM_X", f64::from(dims[0])),
        ("BOX_DIM_Y", f64::from(dims[1])),
        ("BOX_DIM_Z", f64::from(dims[2])),
    ]
}

#[cfg(test)]
mod tests {
    use super::Params;

    #[test]
    fn params_match_their_wgsl() {
        let source = concat!(
            include_str!("shaders/hash.wgsl"),
            include_str!("shaders/grid.wgsl")
        );
        splat_render::wgsl_layout!(
            source,
            "Params",
            Params {
                h,
                inv_h,
                n,
                table,
                max_neighbours,
                pad
            }
        )
        .unwrap();
    }
}
