//! The three passes that draw splats (`shaders/splat.wgsl`), each splat the
//! square bounding its disc in the disc's plane, masked per pixel, a file
//! each:
//! - the **back surface pass** (`back.rs`, only when the fluid absorbs):
//!   the farthest back-facing splat, or the geometry where nearer, for the
//!   thickness;
//! - the **visibility pass** (`visibility.rs`): the nearest depth per pixel,
//!   pushed back by ε;
//! - the **attribute pass** (`attribute.rs`): additive sums of the weighted
//!   normals and weights of the splats within ε of it.
//!
//! Here, what they share: one shader module, the splats' bind group, the
//! pipeline shape and the recording of a pass.

mod attribute;
mod back;
mod visibility;

use wgpu_profiler::GpuProfiler;

use super::plumbing::{
    bind_in_order, layout, pipeline_layout, render_pass, shader, storage_entry, uniform_entry,
};
use super::targets::{DEPTH_FORMAT, Targets};

/// The splat passes' pipelines and bind groups.
pub(super) struct SplatPasses {
    layout: wgpu::BindGroupLayout,
    /// The frame uniforms and the splats drawn.
    group: wgpu::BindGroup,
    visibility: wgpu::RenderPipeline,
    attribute: wgpu::RenderPipeline,
    back: back::Back,
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
                include_str!("../../shaders/frame.wgsl"),
                include_str!("../../shaders/disc.wgsl"),
                include_str!("../../shaders/splat.wgsl"),
            ],
        );
        let shared = Shared {
            device,
            module: &module,
            layout: &splat_layout,
        };
        Self {
            group: bind_splats(device, &splat_layout, frame, splats),
            visibility: visibility::pipeline(&shared),
            attribute: attribute::pipeline(&shared, accum_format),
            back: back::Back::new(&shared, targets),
            layout: splat_layout,
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
        self.back.rebind_targets(device, targets);
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

/// What the three passes' pipelines are made from: the splat shader and
/// the splats' bind group layout (group 0).
struct Shared<'a> {
    device: &'a wgpu::Device,
    module: &'a wgpu::ShaderModule,
    layout: &'a wgpu::BindGroupLayout,
}

impl Shared<'_> {
    /// A splat pipeline: triangle strips of 4 vertices per splat from
    /// `vertex`, shaded by `fragment`, with `extra` bind group layouts after
    /// the splats', a depth test `compare` (and depth writes where
    /// `write_depth`), into `targets`.
    #[allow(clippy::too_many_arguments)]
    fn pipeline(
        &self,
        label: &str,
        extra: &[&wgpu::BindGroupLayout],
        vertex: &str,
        fragment: &str,
        (write_depth, compare): (bool, wgpu::CompareFunction),
        targets: &[Option<wgpu::ColorTargetState>],
    ) -> wgpu::RenderPipeline {
        let layouts: Vec<&wgpu::BindGroupLayout> = std::iter::once(self.layout)
            .chain(extra.iter().copied())
            .collect();
        let layout = pipeline_layout(self.device, label, &layouts);
        self.device
            .create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some(label),
                layout: Some(&layout),
                vertex: wgpu::VertexState {
                    module: self.module,
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
                    module: self.module,
                    entry_point: Some(fragment),
                    compilation_options: Default::default(),
                    targets,
                }),
                multiview_mask: None,
                cache: None,
            })
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
