//! The three passes that draw splats (`shaders/splat.wgsl`), each splat the
//! square bounding its disc in the disc's plane, masked per pixel:
//! - the **back surface pass** (only when the fluid absorbs): the farthest
//!   back-facing splat, or the geometry where nearer, for the thickness;
//! - the **visibility pass**: the nearest depth per pixel, pushed back by ε;
//! - the **attribute pass**: additive sums of the weighted normals and
//!   weights of the splats within ε of it.

use wgpu_profiler::GpuProfiler;

use super::plumbing::{
    bind_in_order, cleared, depth_attachment, layout, pipeline_layout, render_pass, shader,
    storage_entry, texture_entry, uniform_entry,
};
use super::targets::{DEPTH_FORMAT, Targets};

/// The splat passes' pipelines and bind groups.
pub(super) struct SplatPasses {
    layout: wgpu::BindGroupLayout,
    /// The frame uniforms and the splats drawn.
    group: wgpu::BindGroup,
    visibility: wgpu::RenderPipeline,
    attribute: wgpu::RenderPipeline,
    back: wgpu::RenderPipeline,
    back_layout: wgpu::BindGroupLayout,
    /// The scene's depth, for the back surface pass.
    back_group: wgpu::BindGroup,
}

impl SplatPasses {
    /// The passes drawing `splats`, accumulating attributes in `accum_format`.
    pub(super) fn new(
        device: &wgpu::Device,
        accum_format: wgpu::TextureFormat,
        frame: &wgpu::Buffer,
        splats: &wgpu::Buffer,
        targets: &Targets,
    ) -> Self {
        let visible = wgpu::ShaderStages::VERTEX | wgpu::ShaderStages::FRAGMENT;
        let splat_layout = layout(
            device,
            "splat layout",
            &[
                uniform_entry(0, visible),
                storage_entry(1, wgpu::ShaderStages::VERTEX),
            ],
        );
        let module = shader(
            device,
            "splat.wgsl",
            &[
                include_str!("../shaders/frame.wgsl"),
                include_str!("../shaders/disc.wgsl"),
                include_str!("../shaders/splat.wgsl"),
            ],
        );
        let back_layout = layout(
            device,
            "back surface layout",
            &[texture_entry(
                0,
                wgpu::ShaderStages::FRAGMENT,
                wgpu::TextureSampleType::Depth,
            )],
        );
        let splat_pipeline_layout =
            pipeline_layout(device, "splat pipeline layout", &[&splat_layout]);
        let back_pipeline_layout = pipeline_layout(
            device,
            "back surface pipeline layout",
            &[&splat_layout, &back_layout],
        );
        let pipeline = |label,
                        layout: &wgpu::PipelineLayout,
                        vertex: &str,
                        fragment: &str,
                        (write_depth, compare),
                        targets: &[Option<wgpu::ColorTargetState>]| {
            device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some(label),
                layout: Some(layout),
                vertex: wgpu::VertexState {
                    module: &module,
                    entry_point: Some(vertex),
                    compilation_options: Default::default(),
                    buffers: &[],
                },
                primitive: wgpu::PrimitiveState {
                    topology: wgpu::PrimitiveTopology::TriangleStrip,
                    ..Default::default()
                },
                depth_stencil: Some(wgpu::DepthStencilState {
                    format: DEPTH_FORMAT,
                    depth_write_enabled: Some(write_depth),
                    depth_compare: Some(compare),
                    stencil: Default::default(),
                    bias: Default::default(),
                }),
                multisample: Default::default(),
                fragment: Some(wgpu::FragmentState {
                    module: &module,
                    entry_point: Some(fragment),
                    compilation_options: Default::default(),
                    targets,
                }),
                multiview_mask: None,
                cache: None,
            })
        };
        let less_equal = wgpu::CompareFunction::LessEqual;
        let visibility = pipeline(
            "visibility pass",
            &splat_pipeline_layout,
            "vs_splat_visibility",
            "fs_visibility",
            (true, less_equal),
            &[],
        );
        let additive = wgpu::BlendComponent {
            src_factor: wgpu::BlendFactor::One,
            dst_factor: wgpu::BlendFactor::One,
            operation: wgpu::BlendOperation::Add,
        };
        let attribute = pipeline(
            "attribute pass",
            &splat_pipeline_layout,
            "vs_splat",
            "fs_attribute",
            (false, less_equal),
            &[Some(wgpu::ColorTargetState {
                format: accum_format,
                blend: Some(wgpu::BlendState {
                    color: additive,
                    alpha: additive,
                }),
                write_mask: wgpu::ColorWrites::ALL,
            })],
        );
        let back = pipeline(
            "back surface pass",
            &back_pipeline_layout,
            "vs_splat_back",
            "fs_back",
            (true, wgpu::CompareFunction::Greater),
            &[],
        );
        let group = bind_splats(device, &splat_layout, frame, splats);
        let back_group = bind_back(device, &back_layout, targets);
        Self {
            layout: splat_layout,
            group,
            visibility,
            attribute,
            back,
            back_layout,
            back_group,
        }
    }

    /// Draws `splats` (a storage buffer of 32-byte splats) from now on.
    pub(super) fn bind(
        &mut self,
        device: &wgpu::Device,
        frame: &wgpu::Buffer,
        splats: &wgpu::Buffer,
    ) {
        self.group = bind_splats(device, &self.layout, frame, splats);
    }

    /// Binds new targets.
    pub(super) fn rebind_targets(&mut self, device: &wgpu::Device, targets: &Targets) {
        self.back_group = bind_back(device, &self.back_layout, targets);
    }

    /// Records the back surface pass; `draw` records the splats' draw.
    pub(super) fn record_back(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        profiler: Option<&GpuProfiler>,
        t: &Targets,
        draw: &dyn Fn(&mut wgpu::RenderPass<'_>),
    ) {
        let depth = depth_attachment(&t.back_depth_view, wgpu::LoadOp::Clear(0.0));
        let pass = (&self.back, Some(&self.back_group));
        self.record(
            encoder,
            profiler,
            "back surface pass",
            pass,
            &[],
            depth,
            draw,
        );
    }

    /// Records the visibility pass over the scene's depth.
    pub(super) fn record_visibility(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        profiler: Option<&GpuProfiler>,
        t: &Targets,
        draw: &dyn Fn(&mut wgpu::RenderPass<'_>),
    ) {
        let depth = depth_attachment(&t.depth_view, wgpu::LoadOp::Load);
        let pass = (&self.visibility, None);
        self.record(encoder, profiler, "visibility pass", pass, &[], depth, draw);
    }

    /// Records the attribute pass into the cleared accumulation target.
    pub(super) fn record_attribute(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        profiler: Option<&GpuProfiler>,
        t: &Targets,
        draw: &dyn Fn(&mut wgpu::RenderPass<'_>),
    ) {
        let colour = [cleared(&t.accum_view, wgpu::Color::TRANSPARENT)];
        let depth = depth_attachment(&t.depth_view, wgpu::LoadOp::Load);
        let pass = (&self.attribute, None);
        self.record(
            encoder,
            profiler,
            "attribute pass",
            pass,
            &colour,
            depth,
            draw,
        );
    }

    /// One splat pass: `pipeline` with the splats' group (and `extra` as
    /// group 1), into these attachments.
    #[allow(clippy::too_many_arguments)]
    fn record(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        profiler: Option<&GpuProfiler>,
        label: &str,
        (pipeline, extra): (&wgpu::RenderPipeline, Option<&wgpu::BindGroup>),
        colour: &[Option<wgpu::RenderPassColorAttachment<'_>>],
        depth: wgpu::RenderPassDepthStencilAttachment<'_>,
        draw: &dyn Fn(&mut wgpu::RenderPass<'_>),
    ) {
        render_pass(encoder, profiler, label, colour, Some(depth), |pass| {
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, &self.group, &[]);
            if let Some(extra) = extra {
                pass.set_bind_group(1, extra, &[]);
            }
            draw(pass);
        });
    }
}

fn bind_splats(
    device: &wgpu::Device,
    layout: &wgpu::BindGroupLayout,
    frame: &wgpu::Buffer,
    splats: &wgpu::Buffer,
) -> wgpu::BindGroup {
    bind_in_order(
        device,
        "splat bind group",
        layout,
        [frame.as_entire_binding(), splats.as_entire_binding()],
    )
}

fn bind_back(
    device: &wgpu::Device,
    layout: &wgpu::BindGroupLayout,
    t: &Targets,
) -> wgpu::BindGroup {
    bind_in_order(
        device,
        "back surface bind group",
        layout,
        [wgpu::BindingResource::TextureView(&t.depth_view)],
    )
}
