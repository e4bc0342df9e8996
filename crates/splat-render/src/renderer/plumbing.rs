//! What every pass shares, written once: bind group layout entries, bind
//! groups of resources in binding order, shader modules of concatenated WGSL,
//! pipeline layouts, attachments, and passes timed by a profiler.

use wgpu_profiler::GpuProfiler;

/// A uniform buffer at `binding`, seen by `visibility`.
pub(super) fn uniform_entry(
    binding: u32,
    visibility: wgpu::ShaderStages,
) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Uniform,
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

/// A read-only storage buffer at `binding`, seen by `visibility`.
pub(super) fn storage_entry(
    binding: u32,
    visibility: wgpu::ShaderStages,
) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Storage { read_only: true },
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

/// A 2D texture of `sample_type` at `binding`, seen by `visibility`.
pub(super) fn texture_entry(
    binding: u32,
    visibility: wgpu::ShaderStages,
    sample_type: wgpu::TextureSampleType,
) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility,
        ty: wgpu::BindingType::Texture {
            sample_type,
            view_dimension: wgpu::TextureViewDimension::D2,
            multisampled: false,
        },
        count: None,
    }
}

/// A filtering sampler at `binding`, seen by `visibility`.
pub(super) fn sampler_entry(
    binding: u32,
    visibility: wgpu::ShaderStages,
) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility,
        ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
        count: None,
    }
}

/// A bind group layout of `entries`.
pub(super) fn layout(
    device: &wgpu::Device,
    label: &str,
    entries: &[wgpu::BindGroupLayoutEntry],
) -> wgpu::BindGroupLayout {
    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some(label),
        entries,
    })
}

/// A bind group of `resources` at bindings 0, 1, 2, …
pub(super) fn bind_in_order<const N: usize>(
    device: &wgpu::Device,
    label: &str,
    layout: &wgpu::BindGroupLayout,
    resources: [wgpu::BindingResource<'_>; N],
) -> wgpu::BindGroup {
    let entries: Vec<_> = resources
        .into_iter()
        .enumerate()
        .map(|(i, resource)| wgpu::BindGroupEntry {
            binding: i as u32,
            resource,
        })
        .collect();
    device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some(label),
        layout,
        entries: &entries,
    })
}

/// A shader module of the WGSL `sources`, concatenated in order.
pub(super) fn shader(device: &wgpu::Device, label: &str, sources: &[&str]) -> wgpu::ShaderModule {
    device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(label),
        source: wgpu::ShaderSource::Wgsl(sources.concat().into()),
    })
}

/// A pipeline layout of the bind group `layouts`, in group order.
pub(super) fn pipeline_layout(
    device: &wgpu::Device,
    label: &str,
    layouts: &[&wgpu::BindGroupLayout],
) -> wgpu::PipelineLayout {
    let layouts: Vec<Option<&wgpu::BindGroupLayout>> = layouts.iter().copied().map(Some).collect();
    device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some(label),
        bind_group_layouts: &layouts,
        immediate_size: 0,
    })
}

/// A depth attachment loaded by `load` and stored.
pub(super) fn depth_attachment(
    view: &wgpu::TextureView,
    load: wgpu::LoadOp<f32>,
) -> wgpu::RenderPassDepthStencilAttachment<'_> {
    wgpu::RenderPassDepthStencilAttachment {
        view,
        depth_ops: Some(wgpu::Operations {
            load,
            store: wgpu::StoreOp::Store,
        }),
        stencil_ops: None,
    }
}

/// A colour attachment cleared to `clear` and stored.
pub(super) fn cleared(
    view: &wgpu::TextureView,
    clear: wgpu::Color,
) -> Option<wgpu::RenderPassColorAttachment<'_>> {
    Some(wgpu::RenderPassColorAttachment {
        view,
        depth_slice: None,
        resolve_target: None,
        ops: wgpu::Operations {
            load: wgpu::LoadOp::Clear(clear),
            store: wgpu::StoreOp::Store,
        },
    })
}

/// Records a render pass labelled `label` into `encoder` with these
/// attachments, timed by `profiler` where there is one.
pub(super) fn render_pass(
    encoder: &mut wgpu::CommandEncoder,
    profiler: Option<&GpuProfiler>,
    label: &str,
    colour: &[Option<wgpu::RenderPassColorAttachment<'_>>],
    depth: Option<wgpu::RenderPassDepthStencilAttachment<'_>>,
    record: impl FnOnce(&mut wgpu::RenderPass<'_>),
) {
    let query = profiler.map(|p| p.begin_pass_query(label, encoder));
    {
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some(label),
            color_attachments: colour,
            depth_stencil_attachment: depth,
            timestamp_writes: query
                .as_ref()
                .and_then(|q| q.render_pass_timestamp_writes()),
            ..Default::default()
        });
        record(&mut pass);
    }
    if let (Some(p), Some(q)) = (profiler, query) {
        p.end_query(encoder, q);
    }
}

/// Records a compute pass labelled `label` into `encoder`, timed by
/// `profiler` where there is one.
pub(super) fn compute_pass(
    encoder: &mut wgpu::CommandEncoder,
    profiler: Option<&GpuProfiler>,
    label: &str,
    record: impl FnOnce(&mut wgpu::ComputePass<'_>),
) {
    let query = profiler.map(|p| p.begin_pass_query(label, encoder));
    {
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some(label),
            timestamp_writes: query
                .as_ref()
                .and_then(|q| q.compute_pass_timestamp_writes()),
        });
        record(&mut pass);
    }
    if let (Some(p), Some(q)) = (profiler, query) {
        p.end_query(encoder, q);
    }
}
