//! The back surface pass (only when the fluid absorbs): the farthest
//! back-facing splat per pixel (depth compare Greater), or the scene's
//! geometry where it is nearer, for the fluid's thickness. It reads the
//! scene's depth, so it has a bind group of its own.

use wgpu_profiler::GpuProfiler;

use super::super::plumbing::{bind_in_order, depth_attachment, layout, texture_entry};
use super::super::targets::Targets;
use super::{Shared, SplatPasses};

/// The pass's pipeline and the scene depth it reads (group 1).
pub(super) struct Back {
    pipeline: wgpu::RenderPipeline,
    layout: wgpu::BindGroupLayout,
    group: wgpu::BindGroup,
}

impl Back {
    /// The pass over `targets`' scene depth.
    pub(super) fn new(shared: &Shared<'_>, targets: &Targets) -> Self {
        let layout = layout(
            shared.device,
            "back surface layout",
            &[texture_entry(
                0,
                wgpu::ShaderStages::FRAGMENT,
                wgpu::TextureSampleType::Depth,
            )],
        );
        let pipeline = shared.pipeline(
            "back surface pass",
            &[&layout],
            "vs_splat_back",
            "fs_back",
            (true, wgpu::CompareFunction::Greater),
            &[],
        );
        let group = bind(shared.device, &layout, targets);
        Self {
            pipeline,
            layout,
            group,
        }
    }

    /// Reads new targets' scene depth.
    pub(super) fn rebind_targets(&mut self, device: &wgpu::Device, targets: &Targets) {
        self.group = bind(device, &self.layout, targets);
    }
}

impl SplatPasses {
    /// Records the back surface pass; `draw` records the splats' draw.
    pub(in crate::renderer) fn record_back(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        profiler: Option<&GpuProfiler>,
        t: &Targets,
        draw: &dyn Fn(&mut wgpu::RenderPass<'_>),
    ) {
        let depth = depth_attachment(&t.back_depth_view, wgpu::LoadOp::Clear(0.0));
        let pass = (&self.back.pipeline, Some(&self.back.group));
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
}

fn bind(device: &wgpu::Device, layout: &wgpu::BindGroupLayout, t: &Targets) -> wgpu::BindGroup {
    bind_in_order(
        device,
        "back surface bind group",
        layout,
        [wgpu::BindingResource::TextureView(&t.depth_view)],
    )
}
