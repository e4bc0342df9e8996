//! What every pass of this crate shares: bind groups of whole buffers, a
//! compute pipeline with its bind group, readback.

use crate::grid::GpuError;

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

/// Submits `encoder` plus a copy of `bytes` of `buffer` and reads them back.
pub(crate) fn read(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    mut encoder: wgpu::CommandEncoder,
    buffer: &wgpu::Buffer,
    bytes: u64,
) -> Result<Vec<u8>, GpuError> {
    let size = bytes.max(4).next_multiple_of(4);
    let staging = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("readback"),
        size,
        usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
        mapped_at_creation: false,
    });
    encoder.copy_buffer_to_buffer(buffer, 0, &staging, 0, Some(size.min(buffer.size())));
    queue.submit([encoder.finish()]);
    let (tx, rx) = std::sync::mpsc::channel();
    staging.map_async(wgpu::MapMode::Read, .., move |r| {
        let _ = tx.send(r);
    });
    device
        .poll(wgpu::PollType::wait_indefinitely())
        .map_err(|e| GpuError::Readback(e.to_string()))?;
    rx.recv()
        .map_err(|e| GpuError::Readback(e.to_string()))?
        .map_err(|e| GpuError::Readback(e.to_string()))?;
    let view = staging
        .get_mapped_range(..)
        .map_err(|e| GpuError::Readback(e.to_string()))?;
    Ok(view[..bytes as usize].to_vec())
}
