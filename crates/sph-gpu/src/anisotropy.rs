//! [`GpuAnisotropy`]: Yu & Turk's anisotropic kernels (surfel-extract's
//! `anisotropy::kernels`) as one compute pass over a grid of the
//! neighbourhoods' radius.

use bytemuck::{Pod, Zeroable};
use glam::Vec3;
use surfel_extract::Anisotropy;
use surfel_extract::anisotropy::{Centres, Ellipsoid};

use crate::grid::{GpuError, GpuGrid};
use wgpu_profiler::GpuProfiler;

use crate::passes::{Groups, bind_buffers, buffer, pipeline, read, shader, timed_pass};
use crate::solver::HASH;

/// Mirrors `struct Aniso` in `shaders/anisotropy.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct Uniform {
    r: f32,
    inv_r: f32,
    n: u32,
    table: u32,
    smoothing: f32,
    max_ratio: f32,
    min_neighbours: u32,
    isolated_scale: f32,
    inv_tau: f32,
    layer: u32,
    pad0: u32,
    pad1: u32,
}

/// Bytes of one particle's kernel on the GPU (`struct Kernel`: G²'s six
/// entries, det G, whether it is an isolated sphere).
pub const KERNEL_BYTES: u64 = 32;

/// Each particle's smoothed kernel centre and anisotropic kernel, computed
/// on the GPU with the same sums, clamps and centres as
/// `surfel_extract::anisotropy::kernels` (the eigen-decomposition in f32,
/// there in f64): over the neighbours within `anisotropy.radius` × h, from
/// positions copied into its own grid of that cell size.
pub struct GpuAnisotropy {
    uniform: Uniform,
    uniform_buffer: wgpu::Buffer,
    grid: GpuGrid,
    centres: wgpu::Buffer,
    kernels: wgpu::Buffer,
    pass: (wgpu::ComputePipeline, wgpu::BindGroup),
}

impl GpuAnisotropy {
    /// Kernels for up to `capacity` particles of smoothing length `h`.
    ///
    /// # Errors
    /// [`GpuError::Params`] for an `anisotropy` surfel-extract rejects (its
    /// reason), [`GpuError::Invalid`] for an `h` that is not finite and
    /// positive or a zero capacity, [`GpuError::DeviceLimit`] past the
    /// device's limits.
    pub fn new(
        device: &wgpu::Device,
        capacity: usize,
        h: f32,
        anisotropy: &Anisotropy,
    ) -> Result<Self, GpuError> {
        anisotropy.validate().map_err(GpuError::Params)?;
        sph_core::error::check_kernel_h(h).map_err(GpuError::Params)?;
        let r = anisotropy.radius * h;
        let grid = GpuGrid::new(device, capacity, r, 1)?;
        let (layer, thickness) = match anisotropy.centres {
            Centres::Layer { thickness } => (1, thickness),
            Centres::Mean => (0, 1.0),
        };
        let uniform = Uniform {
            r,
            inv_r: 1.0 / r,
            n: 0,
            table: grid.table_size(),
            smoothing: anisotropy.smoothing,
            max_ratio: anisotropy.max_ratio,
            min_neighbours: anisotropy.min_neighbours,
            isolated_scale: anisotropy.isolated_scale,
            inv_tau: 1.0 / (thickness * h),
            layer,
            pad0: 0,
            pad1: 0,
        };
        use wgpu::BufferUsages as U;
        let buffer = |label, size, usage| buffer(device, label, size, usage);
        let uniform_buffer = buffer(
            "anisotropy params",
            size_of::<Uniform>() as u64,
            U::UNIFORM | U::COPY_DST,
        );
        let n = capacity as u64;
        let centres = buffer("kernel centres", 16 * n, U::STORAGE | U::COPY_SRC);
        let kernels = buffer(
            "kernels",
            KERNEL_BYTES * n,
            U::STORAGE | U::COPY_SRC | U::COPY_DST,
        );
        let module = shader(
            device,
            "anisotropy.wgsl",
            format!("{HASH}{}", include_str!("shaders/anisotropy.wgsl")),
        );
        let kernels_pipeline = pipeline(device, &module, "kernels_pass");
        let group = bind_buffers(
            device,
            "anisotropy",
            &kernels_pipeline.get_bind_group_layout(0),
            &[
                &uniform_buffer,
                grid.positions_buffer(),
                grid.counts_buffer(),
                grid.starts_buffer(),
                grid.sorted_buffer(),
                &centres,
                &kernels,
            ],
        );
        Ok(Self {
            uniform,
            uniform_buffer,
            grid,
            centres,
            kernels,
            pass: (kernels_pipeline, group),
        })
    }

    /// The kernel centres (xyz; w: the particle's w as given, a mass), one
    /// `vec4<f32>` per particle.
    pub fn centres_buffer(&self) -> &wgpu::Buffer {
        &self.centres
    }

    /// The kernels, [`KERNEL_BYTES`] per particle.
    pub fn kernels_buffer(&self) -> &wgpu::Buffer {
        &self.kernels
    }

    /// Records the kernels of the first `n` particles of `positions` (one
    /// `vec4<f32>` each): a copy into the grid, its build, the kernel pass.
    ///
    /// # Errors
    /// [`GpuError::Capacity`] for more than the capacity;
    /// [`GpuError::Invalid`] for a `positions` buffer shorter than `n`
    /// `vec4<f32>`s or one that cannot be copied from (`COPY_SRC`).
    pub fn encode(
        &mut self,
        queue: &wgpu::Queue,
        encoder: &mut wgpu::CommandEncoder,
        positions: &wgpu::Buffer,
        n: usize,
    ) -> Result<(), GpuError> {
        if positions.size() < 16 * n as u64 {
            return Err(GpuError::Invalid(
                "the positions buffer holds fewer than n vec4<f32>s",
            ));
        }
        if !positions.usage().contains(wgpu::BufferUsages::COPY_SRC) {
            return Err(GpuError::Invalid(
                "the positions buffer needs COPY_SRC usage (it is copied into the grid)",
            ));
        }
        self.set_len(queue, n)?;
        self.record(encoder, Some(positions), None);
        Ok(())
    }

    /// Uploads `positions` into the grid, for a [`record`](Self::record)
    /// without a source buffer.
    pub(crate) fn upload(
        &mut self,
        queue: &wgpu::Queue,
        positions: &[Vec3],
    ) -> Result<(), GpuError> {
        self.grid.upload(queue, positions)?;
        self.set_len(queue, positions.len())
    }

    /// Makes the next [`record`](Self::record) compute `n` kernels.
    pub(crate) fn set_len(&mut self, queue: &wgpu::Queue, n: usize) -> Result<(), GpuError> {
        if n > self.grid.capacity() {
            return Err(GpuError::Capacity {
                given: n,
                capacity: self.grid.capacity(),
            });
        }
        self.grid.set_len(queue, n);
        self.uniform.n = n as u32;
        queue.write_buffer(&self.uniform_buffer, 0, bytemuck::bytes_of(&self.uniform));
        Ok(())
    }

    /// Records the kernels of the particles [`set_len`](Self::set_len)
    /// counted: copied from `positions` (else those uploaded), the grid's
    /// build and the kernel pass ("extract: kernels"), timed by `profiler`
    /// where there is one.
    pub(crate) fn record(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        positions: Option<&wgpu::Buffer>,
        profiler: Option<&GpuProfiler>,
    ) {
        let n = self.uniform.n;
        if let Some(positions) = positions {
            let bytes = (16 * u64::from(n)).min(positions.size());
            if bytes > 0 {
                encoder.copy_buffer_to_buffer(positions, 0, self.grid.positions_buffer(), 0, bytes);
            }
        }
        self.grid.encode_build_gated(encoder, None, profiler);
        let (pipeline, group) = &self.pass;
        timed_pass(encoder, profiler, "extract: kernels", |pass| {
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, group, &[]);
            Groups::Direct(n.div_ceil(64).max(1)).dispatch(pass);
        });
    }

    /// The kernels of `positions`, computed on the GPU and read back (for
    /// tests and comparisons with the CPU's).
    ///
    /// # Errors
    /// [`GpuError::Capacity`], [`GpuError::Invalid`] for a non-finite
    /// position, [`GpuError::Readback`].
    pub fn kernels_of(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        positions: &[Vec3],
    ) -> Result<Vec<(Vec3, Ellipsoid)>, GpuError> {
        self.upload(queue, positions)?;
        let n = positions.len();
        let mut encoder = device.create_command_encoder(&Default::default());
        self.record(&mut encoder, None, None);
        let centres = read(device, queue, encoder, &self.centres, 16 * n as u64)?;
        let encoder = device.create_command_encoder(&Default::default());
        let kernels = read(
            device,
            queue,
            encoder,
            &self.kernels,
            KERNEL_BYTES * n as u64,
        )?;
        let centres: Vec<[f32; 4]> = bytemuck::pod_collect_to_vec(&centres);
        let kernels: Vec<[f32; 8]> = bytemuck::pod_collect_to_vec(&kernels);
        Ok(centres
            .iter()
            .zip(&kernels)
            .map(|(c, k)| {
                let shape = Ellipsoid {
                    m: [k[0], k[1], k[2], k[3], k[4], k[5]],
                    det: k[6],
                    isolated: k[7] != 0.0,
                };
                (Vec3::new(c[0], c[1], c[2]), shape)
            })
            .collect())
    }
}

#[cfg(test)]
mod tests {
    use super::{HASH, Uniform};

    #[test]
    fn layout_matches_its_wgsl() {
        let source = format!("{HASH}{}", include_str!("shaders/anisotropy.wgsl"));
        splat_render::wgsl_layout!(
            &source,
            "Aniso",
            Uniform {
                r,
                inv_r,
                n,
                table,
                smoothing,
                max_ratio,
                min_neighbours,
                isolated_scale,
                inv_tau,
                layer,
                pad0,
                pad1
            }
        )
        .unwrap();
    }
}
