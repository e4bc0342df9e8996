//! Where a splat frame's GPU time goes, per pass, through the raster and
//! the compute splat paths: the `render` bench's sphere of N surfels at
//! W×H, 7 frames each, the median of each pass's timestamps (where the
//! adapter has timestamp queries).
//!
//! ```text
//! cargo run --release -p splat-render --example splat_passes [-- N W H]
//! ```

use glam::Vec3;
use splat_render::wgpu_profiler::{GpuProfiler, GpuProfilerSettings};
use splat_render::{Camera, Environment, GpuContext, Shading, Splat, SplatPath, SplatRenderer};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1).map(|a| a.parse::<u32>());
    let n = args.next().transpose()?.unwrap_or(100_000) as usize;
    let w = args.next().transpose()?.unwrap_or(1920);
    let h = args.next().transpose()?.unwrap_or(1080);
    let ctx = GpuContext::headless()?;
    println!("{}; {n} surfels at {w}x{h}", ctx.adapter_summary());
    let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
    let spacing = (4.0 * std::f32::consts::PI / n as f32).sqrt();
    let splats: Vec<Splat> = (0..n)
        .map(|i| {
            let y = 1.0 - 2.0 * (i as f32 + 0.5) / n as f32;
            let r = (1.0 - y * y).sqrt();
            let a = golden * i as f32;
            let p = Vec3::new(r * a.cos(), y, r * a.sin());
            Splat::new(p, p, 1.5 * spacing)
        })
        .collect();
    let camera = Camera::looking_at(Vec3::new(0.0, 0.8, 3.2), Vec3::ZERO);
    let shading = Shading {
        depth_epsilon: 0.02,
        ..Default::default()
    };
    for path in [SplatPath::Raster, SplatPath::Compute] {
        let mut renderer = SplatRenderer::new(&ctx, w, h, &Environment::procedural())?;
        renderer.set_splat_path(&ctx, path)?;
        renderer.upload(&ctx, &splats)?;
        let mut profiler = GpuProfiler::new(&ctx.device, GpuProfilerSettings::default())?;
        let mut passes: Vec<(String, Vec<f64>)> = Vec::new();
        for _ in 0..7 {
            let mut encoder = ctx.device.create_command_encoder(&Default::default());
            renderer.encode_profiled(&ctx, &mut encoder, &camera, &shading, &profiler)?;
            profiler.resolve_queries(&mut encoder);
            ctx.queue.submit([encoder.finish()]);
            profiler.end_frame()?;
            ctx.device
                .poll(splat_render::wgpu::PollType::wait_indefinitely())?;
            let Some(results) = profiler.process_finished_frame(ctx.queue.get_timestamp_period())
            else {
                continue;
            };
            for q in results {
                let ms = q.time.map_or(f64::NAN, |t| (t.end - t.start) * 1e3);
                match passes.iter_mut().find(|(l, _)| *l == q.label) {
                    Some((_, v)) => v.push(ms),
                    None => passes.push((q.label, vec![ms])),
                }
            }
        }
        println!("{}:", path.name());
        let mut total = 0.0;
        for (label, mut times) in passes {
            times.sort_by(f64::total_cmp);
            let median = times[times.len() / 2];
            total += median;
            println!("  {label:<22} {median:8.3} ms");
        }
        println!("  {:<22} {total:8.3} ms", "sum of medians");
    }
    Ok(())
}
