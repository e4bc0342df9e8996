//! The normalise-and-shade pass (`shaders/shade.wgsl`), a compute pass
//! over the pixels: the accumulated normal divided by the weight, then
//! lit by the environment, refracting the scene's image with Beer–Lambert
//! absorption through the fluid's thickness, into the output image.
//!
//! It reads the visibility pass's sums and depth from the raster path's
//! targets (`shaders/shade_targets.wgsl`) or, on the compute path, from
//! that path's storage buffers (`shaders/shade_buffers.wgsl`): the same
//! shading, without a full-screen copy between them.

use wgpu_profiler::GpuProfiler;

use super::plumbing::{
    bind_in_order, compute_pass, layout, pipeline_layout, sampler_entry, shader, storage_entry,
    texture_entry, uniform_entry,
};
use super::targets::{OUTPUT_FORMAT, Surroundings, Targets};

/// Where the shade pass reads the sums and the visible depth.
#[derive(Clone, Copy)]
pub(super) enum SumsFrom<'a> {
    /// The raster path's accumulation and depth targets.
    Targets,
    /// The compute path's buffers: four f32 bits per pixel, and the depth
    /// bits.
    Buffers {
        sums: &'a wgpu::Buffer,
        depth: &'a wgpu::Buffer,
    },
}

/// One of the pass's two pipelines, with its bind group.
struct Variant {
    layout: wgpu::BindGroupLayout,
    pipeline: wgpu::ComputePipeline,
    group: wgpu::BindGroup,
}

/// The shade pass's pipelines and bind groups.
pub(super) struct ShadePass {
    targets: Variant,
    /// Made when the compute path first hands over its buffers, with them.
    buffers: Option<(Variant, wgpu::Buffer, wgpu::Buffer)>,
}

impl ShadePass {
    /// The pass over `targets`.
    pub(super) fn new(
        device: &wgpu::Device,
        frame: &wgpu::Buffer,
        targets: &Targets,
        around: &Surroundings,
    ) -> Self {
        Self {
            targets: Variant::new(device, frame, targets, around, SumsFrom::Targets),
            buffers: None,
        }
    }

    /// Binds new targets or surroundings.
    pub(super) fn rebind(
        &mut self,
        device: &wgpu::Device,
        frame: &wgpu::Buffer,
        targets: &Targets,
        around: &Surroundings,
    ) {
        let t = &mut self.targets;
        t.group = bind(device, &t.layout, frame, targets, around, SumsFrom::Targets);
        if let Some((v, sums, depth)) = &mut self.buffers {
            let from = SumsFrom::Buffers { sums, depth };
            v.group = bind(device, &v.layout, frame, targets, around, from);
        }
    }

    /// Reads the compute path's `sums` and `depth` buffers from now on when
    /// recorded with `from_buffers` (binds them again after they change).
    pub(super) fn bind_buffers(
        &mut self,
        device: &wgpu::Device,
        frame: &wgpu::Buffer,
        targets: &Targets,
        around: &Surroundings,
        sums: &wgpu::Buffer,
        depth: &wgpu::Buffer,
    ) {
        if let Some((_, s, d)) = &self.buffers
            && (s, d) == (sums, depth)
        {
            return;
        }
        let from = SumsFrom::Buffers { sums, depth };
        let variant = match self.buffers.take() {
            Some((mut v, ..)) => {
                v.group = bind(device, &v.layout, frame, targets, around, from);
                v
            }
            None => Variant::new(device, frame, targets, around, from),
        };
        self.buffers = Some((variant, sums.clone(), depth.clone()));
    }

    /// Lets go of the compute path's buffers, with their pipeline.
    pub(super) fn release_buffers(&mut self) {
        self.buffers = None;
    }

    /// Records the pass, 8 × 8 pixels a workgroup, reading the compute
    /// path's buffers when `from_buffers` (and they are bound), the
    /// targets otherwise.
    pub(super) fn record(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        profiler: Option<&GpuProfiler>,
        t: &Targets,
        from_buffers: bool,
    ) {
        let v = match &self.buffers {
            Some((v, ..)) if from_buffers => v,
            _ => &self.targets,
        };
        compute_pass(encoder, profiler, "normalise and shade", |pass| {
            pass.set_pipeline(&v.pipeline);
            pass.set_bind_group(0, &v.group, &[]);
            pass.dispatch_workgroups(t.width.div_ceil(8), t.height.div_ceil(8), 1);
        });
    }
}

impl Variant {
    fn new(
        device: &wgpu::Device,
        frame: &wgpu::Buffer,
        targets: &Targets,
        around: &Surroundings,
        from: SumsFrom<'_>,
    ) -> Self {
        let compute = wgpu::ShaderStages::COMPUTE;
        let float = |filterable| wgpu::TextureSampleType::Float { filterable };
        let depth = wgpu::TextureSampleType::Depth;
        let (inputs, source, name) = match from {
            SumsFrom::Targets => (
                [
                    texture_entry(1, compute, float(false)),
                    texture_entry(2, compute, depth),
                ],
                include_str!("../shaders/shade_targets.wgsl"),
                "shade",
            ),
            SumsFrom::Buffers { .. } => (
                [storage_entry(1, compute), storage_entry(2, compute)],
                include_str!("../shaders/shade_buffers.wgsl"),
                "shade from buffers",
            ),
        };
        let [sums_entry, depth_entry] = inputs;
        let layout = layout(
            device,
            &format!("{name} layout"),
            &[
                uniform_entry(0, compute),
                sums_entry,
                depth_entry,
                texture_entry(3, compute, float(true)),
                sampler_entry(4, compute),
                texture_entry(5, compute, float(true)),
                sampler_entry(6, compute),
                wgpu::BindGroupLayoutEntry {
                    binding: 7,
                    visibility: compute,
                    ty: wgpu::BindingType::StorageTexture {
                        access: wgpu::StorageTextureAccess::WriteOnly,
                        format: OUTPUT_FORMAT,
                        view_dimension: wgpu::TextureViewDimension::D2,
                    },
                    count: None,
                },
                texture_entry(8, compute, depth),
            ],
        );
        let module = shader(
            device,
            &format!("{name}.wgsl"),
            &[
                include_str!("../shaders/frame.wgsl"),
                source,
                include_str!("../shaders/shade.wgsl"),
            ],
        );
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("normalise and shade"),
            layout: Some(&pipeline_layout(
                device,
                &format!("{name} pipeline layout"),
                &[&layout],
            )),
            module: &module,
            entry_point: Some("cs_shade"),
            compilation_options: Default::default(),
            cache: None,
        });
        let group = bind(device, &layout, frame, targets, around, from);
        Self {
            layout,
            pipeline,
            group,
        }
    }
}

fn bind(
    device: &wgpu::Device,
    layout: &wgpu::BindGroupLayout,
    frame: &wgpu::Buffer,
    t: &Targets,
    around: &Surroundings,
    from: SumsFrom<'_>,
) -> wgpu::BindGroup {
    use wgpu::BindingResource::{Sampler, TextureView};
    let (sums, depth) = match from {
        SumsFrom::Targets => (TextureView(&t.accum_view), TextureView(&t.depth_view)),
        SumsFrom::Buffers { sums, depth } => (sums.as_entire_binding(), depth.as_entire_binding()),
    };
    bind_in_order(
        device,
        "shade bind group",
        layout,
        [
            frame.as_entire_binding(),
            sums,
            depth,
            TextureView(&around.environment),
            Sampler(&around.env_sampler),
            TextureView(&t.scene_view),
            Sampler(&around.back_sampler),
            TextureView(&t.output_view),
            TextureView(&t.back_depth_view),
        ],
    )
}
