//! What the GPU test binaries share.

use std::sync::OnceLock;

use splat_render::GpuContext;

/// One device per test binary (lavapipe starts slowly), or `None` with a
/// "skipped" line when there is no adapter (a failure with
/// `SPH_REQUIRE_GPU=1`).
pub fn gpu() -> Option<&'static GpuContext> {
    static CTX: OnceLock<Option<GpuContext>> = OnceLock::new();
    CTX.get_or_init(GpuContext::headless_or_skip).as_ref()
}
