//! The blit (`shaders/blit.wgsl`): the shaded image copied onto a window
//! surface of any format, with the sRGB encoding where the surface wants it.

use super::plumbing::{
    bind_in_order, cleared, layout, pipeline_layout, render_pass, shader, texture_entry,
};
use super::targets::Targets;

/// The blit's layout, bind group and the pipeline of the last surface format.
pub(super) struct Blit {
    layout: wgpu::BindGroupLayout,
    group: wgpu::BindGroup,
    pipeline: Option<(wgpu::TextureFormat, wgpu::RenderPipeline)>,
}

impl Blit {
    /// The blit of `targets`' output.
    pub(super) fn new(device: &wgpu::Device, targets: &Targets) -> Self {
        let layout = layout(
            device,
            "blit layout",
            &[texture_entry(
                0,
                wgpu::ShaderStages::FRAGMENT,
                wgpu::TextureSampleType::Float { filterable: false },
            )],
        );
        let group = bind(device, &layout, targets);
        Self {
            layout,
            group,
            pipeline: None,
        }
    }

    /// Binds new targets.
    pub(super) fn rebind(&mut self, device: &wgpu::Device, targets: &Targets) {
        self.group = bind(device, &self.layout, targets);
    }

    /// Records the copy onto `target`, a view of `format` (its pipeline
    /// made when the format is new).
    pub(super) fn record(
        &mut self,
        device: &wgpu::Device,
        encoder: &mut wgpu::CommandEncoder,
        target: &wgpu::TextureView,
        format: wgpu::TextureFormat,
    ) {
        if self.pipeline.as_ref().is_none_or(|(f, _)| *f != format) {
            self.pipeline = Some((format, self.create(device, format)));
        }
        let Some((_, pipeline)) = &self.pipeline else {
            return;
        };
        render_pass(
            encoder,
            None,
            "blit to surface",
            &[cleared(target, wgpu::Color::BLACK)],
            None,
            |pass| {
                pass.set_pipeline(pipeline);
                pass.set_bind_group(0, &self.group, &[]);
                pass.draw(0..3, 0..1);
            },
        );
    }

    fn create(&self, device: &wgpu::Device, format: wgpu::TextureFormat) -> wgpu::RenderPipeline {
        let module = shader(device, "blit.wgsl", &[include_str!("../shaders/blit.wgsl")]);
        let layout = pipeline_layout(device, "blit pipeline layout", &[&self.layout]);
        device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("blit"),
            layout: Some(&layout),
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("vs_fullscreen"),
                compilation_options: Default::default(),
                buffers: &[],
            },
            primitive: Default::default(),
            depth_stencil: None,
            multisample: Default::default(),
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some(if format.is_srgb() {
                    "fs_blit_srgb"
                } else {
                    "fs_blit"
                }),
                compilation_options: Default::default(),
                targets: &[Some(format.into())],
            }),
            multiview_mask: None,
            cache: None,
        })
    }
}

fn bind(device: &wgpu::Device, layout: &wgpu::BindGroupLayout, t: &Targets) -> wgpu::BindGroup {
    bind_in_order(
        device,
        "blit bind group",
        layout,
        [wgpu::BindingResource::TextureView(&t.output_view)],
    )
}
