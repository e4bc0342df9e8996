//! [`GpuDensity`]: density and pressure as a compute pass over a [`GpuGrid`].

use bytemuck::{Pod, Zeroable};
use sph_core::{Boundary, FluidParams, Obstacle};

use wgpu::util::DeviceExt;
use wgpu_profiler::GpuProfiler;

use crate::grid::{GpuError, GpuGrid};
use crate::passes::{Groups, check_fits, compute_pass, read_floats, timed_pass};

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct Fluid {
    h: f32,
    inv_h: f32,
    n: u32,
    table: u32,
    rest_density: f32,
    stiffness: f32,
    suction: f32,
    poly6: f32,
    domain_min: [f32; 4],
    domain_max: [f32; 4],
    layers: [f32; 4],
}

/// Density by poly6 summation plus the walls' and obstacles' density (eq. 4 and
/// `sph_core::boundary`), pressure by eq. 16 — sph-core's `DensityPressure`
/// on the GPU, reading the grid's buffers and writing its own.
pub struct GpuDensity {
    fluid: Fluid,
    /// The positions of the grid the bind group reads, which every
    /// [`GpuDensity::encode`] must be given.
    grid_positions: wgpu::Buffer,
    uniform: wgpu::Buffer,
    densities: wgpu::Buffer,
    pressures: wgpu::Buffer,
    obstacles: wgpu::Buffer,
    bind_group: wgpu::BindGroup,
    pipeline: wgpu::ComputePipeline,
}

impl GpuDensity {
    /// The pass for `grid`'s particles with these parameters and walls.
    /// Under a clearance the walls continue the lattice of the lightest of
    /// `masses`, the particles' masses.
    ///
    /// # Errors
    /// [`GpuError::Params`] for parameters or a boundary sph-core rejects (its
    /// reason, an `h` outside [`sph_core::error::KERNEL_H_RANGE`] among
    /// them); [`GpuError::Invalid`] for an `h` different
    /// from the grid's, a grid built [`GpuGrid::in_box`] (the pass walks a
    /// hashed grid's buckets, which a box grid's are not), a capacity below
    /// the grid's (the pass writes one
    /// density per grid particle), or a non-finite obstacle; [`GpuError::DeviceLimit`]
    /// for a capacity beyond one dispatch or storage binding of this device.
    pub fn new(
        device: &wgpu::Device,
        grid: &GpuGrid,
        capacity: usize,
        params: &FluidParams,
        boundary: &Boundary,
        masses: &[f32],
    ) -> Result<Self, GpuError> {
        params.validate().map_err(GpuError::Params)?;
        sph_core::error::check_kernel_h(params.h).map_err(GpuError::Params)?;
        boundary.validate().map_err(GpuError::Params)?;
        boundary
            .check_precision(params.h)
            .map_err(GpuError::Params)?;
        if params.h != grid.h() {
            return Err(GpuError::Invalid(
                "the density's h must be the grid's cell size",
            ));
        }
        if grid.is_box() {
            return Err(GpuError::Invalid(
                "the density pass walks a hashed grid (`GpuGrid::new`), not one built `in_box`",
            ));
        }
        if capacity < grid.capacity() {
            return Err(GpuError::Invalid(
                "the density's capacity must be at least the grid's",
            ));
        }
        check_fits(device, "particles", capacity, 64, 4)?;
        let obstacles = obstacles_buffer(device, boundary)?;
        let h = params.h;
        let fluid = Fluid {
            h,
            inv_h: 1.0 / h,
            n: 0,
            table: grid.table_size(),
            rest_density: params.rest_density,
            stiffness: params.stiffness,
            suction: params.negative_pressure_scale,
            poly6: 315.0 / (64.0 * std::f32::consts::PI * h.powi(9)),
            // w: the clearance, under which the walls continue the lattice.
            domain_min: boundary.domain.min.extend(boundary.clearance).to_array(),
            domain_max: boundary.domain.max.extend(0.0).to_array(),
            layers: crate::solver::wall_layers(params, boundary, masses),
        };
        let uniform = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("density params"),
            contents: bytemuck::bytes_of(&fluid),
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        });
        let field = |label| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: (4 * capacity as u64).max(16),
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            })
        };
        let (densities, pressures) = (field("densities"), field("pressures"));
        let buffers = [
            &uniform,
            grid.positions_buffer(),
            grid.counts_buffer(),
            grid.starts_buffer(),
            grid.sorted_buffer(),
            &densities,
            &pressures,
            &obstacles,
        ];
        let (pipeline, bind_group) = compute_pass(
            device,
            "density",
            concat!(
                include_str!("shaders/hash.wgsl"),
                include_str!("shaders/walls.wgsl"),
                include_str!("shaders/density.wgsl")
            )
            .into(),
            &buffers,
        );
        Ok(Self {
            fluid,
            grid_positions: grid.positions_buffer().clone(),
            uniform,
            densities,
            pressures,
            obstacles,
            bind_group,
            pipeline,
        })
    }

    /// Records the pass for the grid's current particles (build the grid first,
    /// in the same or an earlier submission).
    ///
    /// # Errors
    /// [`GpuError::Invalid`] for a grid other than the one the pass was made
    /// for: its buffers are bound, and another grid's count would read past
    /// them.
    pub fn encode(
        &mut self,
        queue: &wgpu::Queue,
        encoder: &mut wgpu::CommandEncoder,
        grid: &GpuGrid,
    ) -> Result<(), GpuError> {
        if *grid.positions_buffer() != self.grid_positions {
            return Err(GpuError::Invalid(
                "the density pass encodes only the grid it was made for",
            ));
        }
        let groups = grid.len().div_ceil(64).max(1) as u32;
        self.encode_with(queue, encoder, grid, Groups::Direct(groups), None);
        Ok(())
    }

    /// The same pass with its workgroups given (one thread per particle).
    pub(crate) fn encode_with(
        &mut self,
        queue: &wgpu::Queue,
        encoder: &mut wgpu::CommandEncoder,
        grid: &GpuGrid,
        groups: Groups<'_>,
        profiler: Option<&GpuProfiler>,
    ) {
        // Written only when the count changes: a batch of steps records this
        // pass many times with the same uniform.
        let n = grid.len() as u32;
        if n != self.fluid.n {
            self.fluid.n = n;
            queue.write_buffer(&self.uniform, 0, bytemuck::bytes_of(&self.fluid));
        }
        timed_pass(encoder, profiler, "density", |pass| {
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &self.bind_group, &[]);
            groups.dispatch(pass);
        });
    }

    /// Densities (storage buffer of `f32`, one per particle).
    pub fn densities_buffer(&self) -> &wgpu::Buffer {
        &self.densities
    }

    /// The boundary's obstacles (`struct Obstacle` of `shaders/walls.wgsl`).
    pub(crate) fn obstacles_buffer(&self) -> &wgpu::Buffer {
        &self.obstacles
    }

    /// Pressures (storage buffer of `f32`, one per particle).
    pub fn pressures_buffer(&self) -> &wgpu::Buffer {
        &self.pressures
    }

    /// Reads densities and pressures back (tests, debugging).
    ///
    /// # Errors
    /// [`GpuError::Readback`].
    pub fn read(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
    ) -> Result<(Vec<f32>, Vec<f32>), GpuError> {
        let n = u64::from(self.fluid.n);
        Ok((
            read_floats(device, queue, &self.densities, n)?,
            read_floats(device, queue, &self.pressures, n)?,
        ))
    }
}

/// The obstacles of `boundary` in the layout of `struct Obstacle`
/// (`shaders/walls.wgsl`), or one entry of kind NONE when there are none.
///
/// # Errors
/// [`GpuError::Invalid`] for a non-finite obstacle or a non-positive radius.
pub(crate) fn obstacles_buffer(
    device: &wgpu::Device,
    boundary: &Boundary,
) -> Result<wgpu::Buffer, GpuError> {
    const BOX: f32 = 0.0;
    const SPHERE: f32 = 1.0;
    const NONE: f32 = 2.0;
    let mut data: Vec<[f32; 8]> = Vec::with_capacity(boundary.obstacles.len().max(1));
    for o in &boundary.obstacles {
        let entry = match *o {
            Obstacle::Box(b) => [
                b.min.x, b.min.y, b.min.z, BOX, b.max.x, b.max.y, b.max.z, 0.0,
            ],
            Obstacle::Sphere { centre, radius } => {
                if !(radius.is_finite() && radius > 0.0) {
                    return Err(GpuError::Invalid(
                        "a sphere obstacle's radius must be finite and > 0",
                    ));
                }
                [centre.x, centre.y, centre.z, SPHERE, radius, 0.0, 0.0, 0.0]
            }
        };
        if entry.iter().any(|v| !v.is_finite()) {
            return Err(GpuError::Invalid("an obstacle is not finite"));
        }
        data.push(entry);
    }
    if data.is_empty() {
        data.push([0.0, 0.0, 0.0, NONE, 0.0, 0.0, 0.0, 0.0]);
    }
    Ok(
        device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("obstacles"),
            contents: bytemuck::cast_slice(&data),
            usage: wgpu::BufferUsages::STORAGE,
        }),
    )
}

#[cfg(test)]
mod tests {
    use super::Fluid;

    #[test]
    fn fluid_matches_its_wgsl() {
        let source = concat!(
            include_str!("shaders/hash.wgsl"),
            include_str!("shaders/walls.wgsl"),
            include_str!("shaders/density.wgsl")
        );
        splat_render::wgsl_layout!(
            source,
            "Fluid",
            Fluid {
                h,
                inv_h,
                n,
                table,
                rest_density,
                stiffness,
                suction,
                poly6,
                domain_min,
                domain_max,
                layers
            }
        )
        .unwrap();
    }
}
