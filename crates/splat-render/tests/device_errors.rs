//! Errors the device reports on its own (wgpu's default handler panics on
//! them) and a lost device are `RenderError::Device` from
//! `GpuContext::check`, not a panic. Each test makes its own context: it
//! breaks it. On lavapipe in CI; skipped without an adapter unless
//! `SPH_REQUIRE_GPU=1`.

use splat_render::{GpuContext, RenderError, wgpu};

fn context() -> Option<GpuContext> {
    // The shared context decides whether this machine must have an adapter.
    GpuContext::headless_or_skip()?;
    Some(GpuContext::headless().expect("a second context on the same adapter"))
}

#[test]
fn an_uncaptured_validation_error_is_an_error_not_a_panic() {
    let Some(ctx) = context() else {
        return;
    };
    ctx.check().unwrap();
    // MAP_READ with STORAGE needs a feature this device was not given: a
    // validation error no call returns.
    let _bad = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("invalid usage"),
        size: 16,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::STORAGE,
        mapped_at_creation: false,
    });
    match ctx.check() {
        Err(RenderError::Device(message)) => {
            println!("{message}");
            assert!(message.contains("invalid usage"), "{message}");
            assert!(!message.contains('\n'), "one line: {message}");
        }
        other => panic!("expected a device error, got {other:?}"),
    }
}

#[test]
fn a_lost_device_is_an_error_not_a_panic() {
    let Some(ctx) = context() else {
        return;
    };
    ctx.device.destroy();
    let _ = ctx.device.poll(wgpu::PollType::Poll);
    match ctx.check() {
        Err(RenderError::Device(message)) => {
            println!("{message}");
            assert!(message.contains("lost"), "{message}");
        }
        other => panic!("expected a device error, got {other:?}"),
    }
}

/// After a fault the device reported on its own (here an invalid buffer;
/// 16384² targets past lavapipe's memory do the same), a renderer is not
/// made, and an image is not read back as if it were the render.
#[test]
fn a_faulted_device_makes_no_renderer_and_reads_back_nothing() {
    use splat_render::{Environment, SplatRenderer};
    let Some(ctx) = context() else {
        return;
    };
    let env = Environment::procedural();
    let renderer = SplatRenderer::new(&ctx, 64, 48, &env).unwrap();
    let _bad = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("invalid usage"),
        size: 16,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::STORAGE,
        mapped_at_creation: false,
    });
    match SplatRenderer::new(&ctx, 64, 48, &env) {
        Err(RenderError::Device(message)) => assert!(message.contains("invalid usage")),
        other => panic!("expected a device error, got {:?}", other.err()),
    }
    match renderer.read_image(&ctx) {
        Err(RenderError::Device(message)) => assert!(message.contains("invalid usage")),
        other => panic!("expected a device error, got {:?}", other.err()),
    }
}
