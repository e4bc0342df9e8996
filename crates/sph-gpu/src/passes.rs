//! What every pass of this crate shares: bind groups of whole buffers, a
//! compute pipeline with its bind group, workgroup counts, timed passes,
//! readback.

use wgpu_profiler::GpuProfiler;

use crate::grid::GpuError;

/// Where a dispatch's workgroup count comes from.
#[derive(Clone, Copy)]
pub(crate) enum Groups<'a> {
    /// This many workgroups along x.
    Direct(u32),
    /// This many along x and y.
    DirectXY(u32, u32),
    /// The `[x, y, z]` at this byte offset of an indirect-arguments buffer,
    /// written by an earlier pass.
    Indirect(&'a wgpu::Buffer, u64),
}

impl Groups<'_> {
    /// Records the dispatch of the pass's current pipeline.
    pub(crate) fn dispatch(self, pass: &mut wgpu::ComputePass<'_>) {
        match self {
            Groups::Direct(x) => pass.dispatch_workgroups(x, 1, 1),
            Groups::DirectXY(x, y) => pass.dispatch_workgroups(x, y, 1),
            Groups::Indirect(buffer, offset) => pass.dispatch_workgroups_indirect(buffer, offset),
        }
    }
}

/// Records a compute pass labelled `label`, timed by `profiler` where there is
/// one (timestamps at the pass's start and end; on a device without
/// `wgpu::Features::TIMESTAMP_QUERY` the profiler's result for the pass has
/// its label and no time).
pub(crate) fn timed_pass<R>(
    encoder: &mut wgpu::CommandEncoder,
    profiler: Option<&GpuProfiler>,
    label: &str,
    record: impl FnOnce(&mut wgpu::ComputePass<'_>) -> R,
) -> R {
    let query = profiler.map(|p| p.begin_pass_query(label, encoder));
    let out = record(
        &mut encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some(label),
            timestamp_writes: query
                .as_ref()
                .and_then(|q| q.compute_pass_timestamp_writes()),
        }),
    );
    if let (Some(p), Some(q)) = (profiler, query) {
        p.end_query(encoder, q);
    }
    out
}

/// One stage of a run of compute passes: its label and what it records.
pub(crate) type PassStage<'a> = (&'a str, &'a dyn Fn(&mut wgpu::ComputePass<'_>));

/// Records `stages` in one compute pass labelled `label`, or, with a
/// profiler, each stage in its own timed pass: timestamps bracket passes, so
/// a profile splits the run where the plain path keeps one pass (a pass
/// costs on the CPU and, on lavapipe, on the device too).
pub(crate) fn staged_pass(
    encoder: &mut wgpu::CommandEncoder,
    profiler: Option<&GpuProfiler>,
    label: &str,
    stages: &[PassStage<'_>],
) {
    if profiler.is_some() {
        for &(stage, record) in stages {
            timed_pass(encoder, profiler, stage, record);
        }
    } else {
        timed_pass(encoder, None, label, |pass| {
            for (_, record) in stages {
                record(pass);
            }
        });
    }
}

/// Checks that `items` fit this device: one thread each in a one-dimensional
/// dispatch of workgroups of `group_size`, and `bytes_each` bytes each in one
/// storage binding.
///
/// # Errors
/// [`GpuError::DeviceLimit`] naming the limit and the most items it allows.
pub(crate) fn check_fits(
    device: &wgpu::Device,
    what: &str,
    items: usize,
    group_size: u32,
    bytes_each: u64,
) -> Result<(), GpuError> {
    let limits = device.limits();
    let max_groups = u64::from(limits.max_compute_workgroups_per_dimension);
    let max_bytes = limits
        .max_storage_buffer_binding_size
        .min(limits.max_buffer_size);
    let by_groups = max_groups * u64::from(group_size);
    let by_bytes = max_bytes / bytes_each.max(1);
    let max = by_groups.min(by_bytes);
    if items as u64 > max {
        let limit = if by_groups <= by_bytes {
            format!("{max_groups} workgroups of {group_size} per dispatch")
        } else {
            format!("{max_bytes}-byte storage bindings")
        };
        return Err(GpuError::DeviceLimit(format!(
            "{items} {what} exceed this device's {limit}: at most {max}"
        )));
    }
    Ok(())
}

/// A bind group binding `buffers[i]` whole at binding `i`.
pub(crate) fn bind_buffers(
    device: &wgpu::Device,
    label: &str,
    layout: &wgpu::BindGroupLayout,
    buffers: &[&wgpu::Buffer],
) -> wgpu::BindGroup {
    let entries: Vec<_> = buffers
        .iter()
        .enumerate()
        .map(|(i, b)| wgpu::BindGroupEntry {
            binding: i as u32,
            resource: b.as_entire_binding(),
        })
        .collect();
    device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some(label),
        layout,
        entries: &entries,
    })
}

/// A shader module from WGSL `source`.
pub(crate) fn shader(device: &wgpu::Device, label: &str, source: String) -> wgpu::ShaderModule {
    device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(label),
        source: wgpu::ShaderSource::Wgsl(source.into()),
    })
}

/// A buffer of `size` bytes (at least 16, the smallest a binding takes) for
/// `usage`, not mapped.
pub(crate) fn buffer(
    device: &wgpu::Device,
    label: &str,
    size: u64,
    usage: wgpu::BufferUsages,
) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: size.max(16),
        usage,
        mapped_at_creation: false,
    })
}

/// The compute pipeline of entry point `entry` in `module`, its layout derived
/// from the shader (only the bindings the entry point uses).
pub(crate) fn pipeline(
    device: &wgpu::Device,
    module: &wgpu::ShaderModule,
    entry: &str,
) -> wgpu::ComputePipeline {
    device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some(entry),
        layout: None,
        module,
        entry_point: Some(entry),
        compilation_options: Default::default(),
        cache: None,
    })
}

/// The compute pipeline of entry point `entry` in WGSL `source` and its bind
/// group 0 with `buffers[i]` at binding `i`.
pub(crate) fn compute_pass(
    device: &wgpu::Device,
    entry: &str,
    source: String,
    buffers: &[&wgpu::Buffer],
) -> (wgpu::ComputePipeline, wgpu::BindGroup) {
    let pipeline = pipeline(device, &shader(device, entry, source), entry);
    let bind_group = bind_buffers(device, entry, &pipeline.get_bind_group_layout(0), buffers);
    (pipeline, bind_group)
}

/// The same with `(binding, buffer)` pairs, for entry points that use only
/// some of the module's bindings.
pub(crate) fn compute_pass_with(
    device: &wgpu::Device,
    entry: &str,
    source: String,
    buffers: &[(u32, &wgpu::Buffer)],
) -> (wgpu::ComputePipeline, wgpu::BindGroup) {
    let pipeline = pipeline(device, &shader(device, entry, source), entry);
    let group = bind_pairs(device, entry, &pipeline, buffers);
    (pipeline, group)
}

/// A bind group of `(binding, buffer)` pairs for `pipeline`'s group 0.
pub(crate) fn bind_pairs(
    device: &wgpu::Device,
    label: &str,
    pipeline: &wgpu::ComputePipeline,
    buffers: &[(u32, &wgpu::Buffer)],
) -> wgpu::BindGroup {
    let entries: Vec<_> = buffers
        .iter()
        .map(|&(binding, b)| wgpu::BindGroupEntry {
            binding,
            resource: b.as_entire_binding(),
        })
        .collect();
    device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some(label),
        layout: &pipeline.get_bind_group_layout(0),
        entries: &entries,
    })
}

/// Submits `encoder` plus a copy of `bytes` of `buffer` and reads them back
/// through a staging buffer made for the purpose (see [`Staging`] for reads
/// repeated every frame).
pub(crate) fn read(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    encoder: wgpu::CommandEncoder,
    buffer: &wgpu::Buffer,
    bytes: u64,
) -> Result<Vec<u8>, GpuError> {
    Staging::new(device, bytes).read(device, queue, encoder, buffer, bytes)
}

/// The first `n` `vec4<f32>` of `buffer`, read back as `Vec3` (w dropped).
pub(crate) fn read_vec3s(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    buffer: &wgpu::Buffer,
    n: u64,
) -> Result<Vec<glam::Vec3>, GpuError> {
    let encoder = device.create_command_encoder(&Default::default());
    let bytes = read(device, queue, encoder, buffer, 16 * n)?;
    Ok(bytemuck::pod_collect_to_vec::<u8, [f32; 4]>(&bytes)
        .into_iter()
        .map(|v| glam::Vec3::new(v[0], v[1], v[2]))
        .collect())
}

/// The first `n` `f32` of `buffer`, read back.
pub(crate) fn read_floats(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    buffer: &wgpu::Buffer,
    n: u64,
) -> Result<Vec<f32>, GpuError> {
    let encoder = device.create_command_encoder(&Default::default());
    Ok(bytemuck::pod_collect_to_vec(&read(
        device,
        queue,
        encoder,
        buffer,
        4 * n,
    )?))
}

/// A mappable buffer for reading back at most its size, kept and reused, so a
/// readback every frame (a step state, the extractor's counters) allocates no
/// GPU buffer.
pub(crate) struct Staging {
    buffer: wgpu::Buffer,
}

impl Staging {
    /// Room for `bytes` (rounded up to 4).
    pub(crate) fn new(device: &wgpu::Device, bytes: u64) -> Self {
        Self {
            buffer: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("readback"),
                size: bytes.max(4).next_multiple_of(4),
                usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
                mapped_at_creation: false,
            }),
        }
    }

    /// Submits `encoder` plus a copy of the first `bytes` of `source` (at
    /// most this buffer's size) and reads them back.
    pub(crate) fn read(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        mut encoder: wgpu::CommandEncoder,
        source: &wgpu::Buffer,
        bytes: u64,
    ) -> Result<Vec<u8>, GpuError> {
        let staging = &self.buffer;
        let size = bytes.max(4).next_multiple_of(4);
        if size > staging.size() {
            return Err(GpuError::Readback(format!(
                "{bytes} bytes do not fit a {}-byte staging buffer",
                staging.size()
            )));
        }
        encoder.copy_buffer_to_buffer(source, 0, staging, 0, Some(size.min(source.size())));
        queue.submit([encoder.finish()]);
        let (tx, rx) = std::sync::mpsc::channel();
        staging.map_async(wgpu::MapMode::Read, ..size, move |r| {
            let _ = tx.send(r);
        });
        device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| GpuError::Readback(e.to_string()))?;
        rx.recv()
            .map_err(|e| GpuError::Readback(e.to_string()))?
            .map_err(|e| GpuError::Readback(e.to_string()))?;
        let out = staging
            .get_mapped_range(..size)
            .map_err(|e| GpuError::Readback(e.to_string()))?[..bytes as usize]
            .to_vec();
        staging.unmap();
        Ok(out)
    }
}
