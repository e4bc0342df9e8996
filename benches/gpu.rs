//! `cargo bench --bench gpu`: one SPH step on the CPU (`World::step`, all
//! threads) and on the GPU (`sph_gpu::GpuSolver::step`, waiting for the device)
//! in the same run, for 100k and 1M particles of a 3D dam break at 1 cm
//! spacing. Without a GPU this runs on lavapipe: CPU-rasteriser figures.

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use sph_core::Scene;
use sph_gpu::GpuSolver;
use splat_render::{GpuContext, wgpu};

fn steps(c: &mut Criterion) {
    let ctx = match GpuContext::headless() {
        Ok(ctx) => ctx,
        Err(err) => {
            println!("skipped: {err}");
            return;
        }
    };
    println!("adapter: {}", ctx.adapter_summary());
    let mut group = c.benchmark_group("sph_step");
    group.sample_size(10);
    // a = 0.37 → 37 × 74 × 37 ≈ 101k particles; a = 0.8 → 80 × 160 × 80 ≈ 1.02M.
    for (label, a) in [("100k", 0.37f32), ("1M", 0.8)] {
        let scene = Scene::dam_break(a, a, 0.01);
        let mut world = scene.build_world().expect("scene");
        let n = world.particles.len();
        println!("{label}: {n} particles");
        let dt = world.stable_dt();
        let mut gpu = GpuSolver::new(
            &ctx.device,
            &ctx.queue,
            &world.particles,
            world.params(),
            &scene.boundary(),
        )
        .expect("GPU solver");
        group.throughput(Throughput::Elements(n as u64));
        group.bench_function(BenchmarkId::new("cpu", label), |b| {
            b.iter(|| world.step().expect("stable"))
        });
        group.bench_function(BenchmarkId::new("gpu", label), |b| {
            b.iter(|| {
                gpu.step(&ctx.device, &ctx.queue, dt).expect("step");
                ctx.device
                    .poll(wgpu::PollType::wait_indefinitely())
                    .expect("GPU finished");
            })
        });
    }
    group.finish();
}

criterion_group!(benches, steps);
criterion_main!(benches);
