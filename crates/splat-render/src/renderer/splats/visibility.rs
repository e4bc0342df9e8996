//! The visibility pass: each pixel's nearest splat depth, pushed back by ε
//! along the view ray, over the scene's depth.

use wgpu_profiler::GpuProfiler;

use super::super::plumbing::depth_attachment;
use super::super::targets::Targets;
use super::{Shared, SplatPasses};

/// Its pipeline: depth written, nothing else.
pub(super) fn pipeline(shared: &Shared<'_>) -> wgpu::RenderPipeline {
    shared.pipeline(
        "visibility pass",
        &[],
        "vs_splat_visibility",
        "fs_visibility",
        (true, wgpu::CompareFunction::LessEqual),
        &[],
    )
}

impl SplatPasses {
    /// Records the visibility pass over the scene's depth.
    pub(in crate::renderer) fn record_visibility(
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
}
