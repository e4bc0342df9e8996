//! The attribute pass: additive sums of w·(normal, 1), w the alpha mask of
//! eq. 37, over the splats that pass the depth test against the visibility
//! pass's depth.

use wgpu_profiler::GpuProfiler;

use super::super::plumbing::{cleared, depth_attachment};
use super::super::targets::Targets;
use super::{Shared, SplatPasses};

/// Its pipeline: the depth test without writes, blending by addition into
/// the accumulation target of `accum_format`.
pub(super) fn pipeline(
    shared: &Shared<'_>,
    accum_format: wgpu::TextureFormat,
) -> wgpu::RenderPipeline {
    let additive = wgpu::BlendComponent {
        src_factor: wgpu::BlendFactor::One,
        dst_factor: wgpu::BlendFactor::One,
        operation: wgpu::BlendOperation::Add,
    };
    shared.pipeline(
        "attribute pass",
        &[],
        "vs_splat",
        "fs_attribute",
        (false, wgpu::CompareFunction::LessEqual),
        &[Some(wgpu::ColorTargetState {
            format: accum_format,
            blend: Some(wgpu::BlendState {
                color: additive,
                alpha: additive,
            }),
            write_mask: wgpu::ColorWrites::ALL,
        })],
    )
}

impl SplatPasses {
    /// Records the attribute pass into the cleared accumulation target.
    pub(in crate::renderer) fn record_attribute(
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
}
