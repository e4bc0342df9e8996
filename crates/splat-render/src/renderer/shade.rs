//! The normalise-and-shade pass (`shaders/shade.wgsl`), a compute pass
//! over the pixels: the accumulated normal divided by the weight, then
//! lit by the environment, refracting the scene's image with Beer–Lambert
//! absorption through the fluid's thickness, into the output image.

use wgpu_profiler::GpuProfiler;

use super::plumbing::{
    bind_in_order, compute_pass, layout, pipeline_layout, sampler_entry, shader, texture_entry,
    uniform_entry,
};
use super::targets::{OUTPUT_FORMAT, Surroundings, Targets};

/// The shade pass's pipeline and bind group.
pub(super) struct ShadePass {
    layout: wgpu::BindGroupLayout,
    pipeline: wgpu::ComputePipeline,
    group: wgpu::BindGroup,
}

impl ShadePass {
    /// The pass over `targets`.
    pub(super) fn new(
        device: &wgpu::Device,
        frame: &wgpu::Buffer,
        targets: &Targets,
        around: &Surroundings,
    ) -> Self {
        let compute = wgpu::ShaderStages::COMPUTE;
        let float = |filterable| wgpu::TextureSampleType::Float { filterable };
        let depth = wgpu::TextureSampleType::Depth;
        let layout = layout(
            device,
            "shade layout",
            &[
                uniform_entry(0, compute),
                texture_entry(1, compute, float(false)),
                texture_entry(2, compute, depth),
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
            "shade.wgsl",
            &[
                include_str!("../shaders/frame.wgsl"),
                include_str!("../shaders/shade.wgsl"),
            ],
        );
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("normalise and shade"),
            layout: Some(&pipeline_layout(
                device,
                "shade pipeline layout",
                &[&layout],
            )),
            module: &module,
            entry_point: Some("cs_shade"),
            compilation_options: Default::default(),
            cache: None,
        });
        let group = bind(device, &layout, frame, targets, around);
        Self {
            layout,
            pipeline,
            group,
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
        self.group = bind(device, &self.layout, frame, targets, around);
    }

    /// Records the pass, 8 × 8 pixels a workgroup.
    pub(super) fn record(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        profiler: Option<&GpuProfiler>,
        t: &Targets,
    ) {
        compute_pass(encoder, profiler, "normalise and shade", |pass| {
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &self.group, &[]);
            pass.dispatch_workgroups(t.width.div_ceil(8), t.height.div_ceil(8), 1);
        });
    }
}

fn bind(
    device: &wgpu::Device,
    layout: &wgpu::BindGroupLayout,
    frame: &wgpu::Buffer,
    t: &Targets,
    around: &Surroundings,
) -> wgpu::BindGroup {
    use wgpu::BindingResource::{Sampler, TextureView};
    bind_in_order(
        device,
        "shade bind group",
        layout,
        [
            frame.as_entire_binding(),
            TextureView(&t.accum_view),
            TextureView(&t.depth_view),
            TextureView(&around.environment),
            Sampler(&around.env_sampler),
            TextureView(&t.scene_view),
            Sampler(&around.back_sampler),
            TextureView(&t.output_view),
            TextureView(&t.back_depth_view),
        ],
    )
}
