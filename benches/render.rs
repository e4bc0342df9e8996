//! `cargo bench --bench render`: one whole splat frame — upload, visibility
//! pass, attribute pass, normalise-and-shade compute pass, waiting for the GPU to
//! finish (no readback) — for 20k, 100k and 1M surfels at 1280×720 and
//! 1920×1080. Throughput is in surfels. The surfels tile a unit sphere (Fibonacci
//! lattice, radii overlapping their neighbours) that fills about half the frame.
//! On a machine without a GPU this runs on lavapipe: CPU-rasteriser figures.

use std::hint::black_box;

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use glam::Vec3;
use splat_render::{Camera, Environment, GpuContext, Shading, Splat, SplatRenderer, wgpu};

/// `n` surfels on the unit sphere, each with radius 1.5 × the mean spacing.
fn sphere(n: usize) -> Vec<Splat> {
    let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
    let spacing = (4.0 * std::f32::consts::PI / n as f32).sqrt();
    (0..n)
        .map(|i| {
            let y = 1.0 - 2.0 * (i as f32 + 0.5) / n as f32;
            let r = (1.0 - y * y).sqrt();
            let a = golden * i as f32;
            let p = Vec3::new(r * a.cos(), y, r * a.sin());
            Splat::new(p, p, 1.5 * spacing)
        })
        .collect()
}

fn render(c: &mut Criterion) {
    let ctx = match GpuContext::headless() {
        Ok(ctx) => ctx,
        Err(err) => {
            println!("skipped: {err}");
            return;
        }
    };
    println!("adapter: {}", ctx.adapter_summary());
    let env = Environment::procedural();
    let camera = Camera::looking_at(Vec3::new(0.0, 0.8, 3.2), Vec3::ZERO);
    let shading = Shading {
        depth_epsilon: 0.02,
        ..Default::default()
    };
    let mut group = c.benchmark_group("render");
    group.sample_size(10);
    for (w, h) in [(1280, 720), (1920, 1080)] {
        let mut renderer = SplatRenderer::new(&ctx, w, h, &env).expect("renderer");
        for n in [20_000, 100_000, 1_000_000] {
            let splats = sphere(n);
            group.throughput(Throughput::Elements(n as u64));
            group.bench_function(BenchmarkId::new(format!("{w}x{h}"), n), |b| {
                b.iter(|| {
                    renderer.upload(&ctx, black_box(&splats)).expect("upload");
                    renderer.render(&ctx, &camera, &shading).expect("render");
                    ctx.device
                        .poll(wgpu::PollType::wait_indefinitely())
                        .expect("GPU finished");
                })
            });
        }
    }
    group.finish();
}

criterion_group!(benches, render);
criterion_main!(benches);
