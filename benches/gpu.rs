//! `cargo bench --bench gpu`: the CPU path and the GPU path (`sph-gpu`) in the
//! same run, for 100k and 1M particles of a 3D dam break at 1 cm spacing
//! (`SPH_GPU_SIZES`, e.g. `10k,100k`, chooses others):
//!
//! - `pbf_frame`: one whole 1/60 s frame of PBF, the demo's solver
//!   (`World::advance` on all threads, vs `GpuPbf::advance`, one
//!   submission, waiting for the device); the CPU only up to 100k;
//! - `pbf_frame_1080p`: that frame, then the surfels and a 1920×1080 image:
//!   the CPU path extracts in its default covered mode and uploads its
//!   surfels; the GPU path records the frame, the thesis-mode extraction
//!   (thesis mode, isotropic: `gpu`; anisotropic: `gpu_anisotropic`; the
//!   demo's default, covered mode on the anisotropic field: `gpu_demo`)
//!   reading the solver's buffers and the render in one submission, and
//!   nothing leaves the GPU; the splats drawn by the adapter's path
//!   (`SplatPath::for_device`), and `gpu_demo_raster` the demo's frame by
//!   the raster path where that is another (each row continues the dam
//!   break where the last left it: a later state, not like for like);
//! - `wcsph_step`: one step of the thesis's WCSPH (`World::step` vs
//!   `GpuSolver::step`, waiting for the device) — one step, not a frame: a
//!   1/60 s frame of the dam break takes 50–100 of them;
//! - `extraction`: the surfels of that state (a `surfel_extract::Extractor`
//!   kept across iterations, as the demo keeps one, in the default covered
//!   mode, the thesis mode, the thesis mode on the anisotropic field and the
//!   demo's covered mode on it (`*_demo`), vs `GpuExtractor` reading the
//!   solver's buffers in the same modes, waiting for the device);
//! - `wcsph_step_1080p`: one WCSPH step, extraction and splat rendering at
//!   1920×1080 — again one step, not a frame;
//! - `advance_batch`: one adaptive WCSPH frame on the GPU of a small dam
//!   break (8,000 particles) recorded in batches of its substeps + 1 and of
//!   4 × them.
//!
//! Before the timed groups it prints, for each size, the GPU path's time per
//! compute and render pass from timestamp queries (`wgpu_profiler`): medians
//! of `SPH_PROFILE_RUNS` runs (default 10; 0 skips the profiles) of one PBF
//! frame (`GpuPbf::encode_frame_profiled`, each kind of pass summed over
//! the frame's substeps and iterations), one adaptive WCSPH step
//! (`GpuSolver::advance_profiled` over a frame half a stable step long),
//! the extraction and the 1080p render.
//!
//! Without a GPU this runs on lavapipe: software figures, the "GPU" path on the
//! same CPU cores.

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use sph_core::{Scene, SolverKind, World};
use sph_gpu::{GpuExtractor, GpuParticles, GpuPbf, GpuSolver};
use splat_render::wgpu_profiler::{GpuProfiler, GpuProfilerSettings};
use splat_render::{
    Camera, Environment, GpuContext, Shading, Splat, SplatPath, SplatRenderer, wgpu,
};
use surfel_extract::{ExtractParams, Extractor, extract};

/// A 3D dam break of side `a` (m) at 1 cm spacing after one CPU step, and a
/// GPU solver of the same particles after one step.
fn setup(ctx: &GpuContext, a: f32) -> (Scene, World, GpuSolver) {
    let scene = Scene::dam_break(a, a, 0.01);
    let mut world = scene.build_world().expect("scene");
    let mut gpu = GpuSolver::new(
        &ctx.device,
        &ctx.queue,
        &world.particles,
        world.params(),
        &scene.boundary(),
    )
    .expect("GPU solver");
    let dt = world.stable_dt();
    world.step().expect("stable");
    gpu.step(&ctx.device, &ctx.queue, dt).expect("step");
    (scene, world, gpu)
}

fn wait(ctx: &GpuContext) {
    ctx.device
        .poll(wgpu::PollType::wait_indefinitely())
        .expect("GPU finished");
}

/// A GPU extractor attached to `gpu`, sized after a first run.
fn gpu_extractor(ctx: &GpuContext, gpu: &dyn GpuParticles, params: &ExtractParams) -> GpuExtractor {
    let limit = ctx.device.limits().max_storage_buffer_binding_size / sph_gpu::SURFEL_BYTES;
    let capacity = (1usize << 23).min(limit as usize);
    let mut x = GpuExtractor::new(&ctx.device, gpu.len(), capacity, params).expect("extractor");
    x.attach(&ctx.device, gpu).expect("attach");
    let mut encoder = ctx.device.create_command_encoder(&Default::default());
    x.encode_attached(&ctx.queue, &mut encoder).expect("encode");
    ctx.queue.submit([encoder.finish()]);
    let stats = x.read_stats(&ctx.device, &ctx.queue).expect("stats");
    println!(
        "  GPU extraction: {} surfels, {} evaluations (efficiency {:.2}), dropped {}",
        stats.surfels,
        stats.evaluations,
        stats.efficiency(),
        stats.dropped
    );
    assert_eq!(stats.dropped, 0, "capacity {capacity} too small");
    x
}

/// Runs `record` (which submits its own work, timed by the profiler it is
/// given) `runs` times and prints, per pass in the order the passes first
/// ran, the medians of two GPU times:
///
/// - `pass`: from the pass's start timestamp to its end timestamp;
/// - `from prev`: from the previous pass's end (the first pass: its start) to
///   its end, so that in each run the column adds up to the GPU's whole span
///   and counts the gaps between passes (their medians need not add up to
///   the median span). Lavapipe writes a pass's start timestamp only
///   after the dispatch's work on large grids, so there only this column
///   holds the pass's cost.
///
/// A label that runs several times in one run (a frame's substeps, the steps
/// recorded past its end) counts its sum. Then the span from the first start
/// to the last end, and the wall time from recording to idle.
fn print_profile(ctx: &GpuContext, title: &str, mut record: impl FnMut(&GpuProfiler)) -> bool {
    let runs: usize = std::env::var("SPH_PROFILE_RUNS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(10);
    if runs == 0 {
        return false;
    }
    if !ctx
        .device
        .features()
        .contains(wgpu::Features::TIMESTAMP_QUERY)
    {
        println!("  profile {title}: skipped, the adapter has no timestamp queries");
        return false;
    }
    let mut profiler =
        GpuProfiler::new(&ctx.device, GpuProfilerSettings::default()).expect("profiler");
    let mut labels: Vec<String> = Vec::new();
    // Per label, per run: [pass, from prev] in ms.
    let mut times: Vec<[Vec<f64>; 2]> = Vec::new();
    let (mut spans, mut walls) = (Vec::new(), Vec::new());
    for _ in 0..runs {
        wait(ctx);
        let start = std::time::Instant::now();
        record(&profiler);
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        profiler.resolve_queries(&mut encoder);
        ctx.queue.submit([encoder.finish()]);
        profiler.end_frame().expect("profiler frame");
        wait(ctx);
        walls.push(start.elapsed().as_secs_f64() * 1e3);
        let results = profiler
            .process_finished_frame(ctx.queue.get_timestamp_period())
            .expect("the profiler's frame is done after the wait");
        let mut run = vec![[0.0; 2]; labels.len()];
        let (mut first, mut prev) = (None, None);
        for r in results {
            let Some(t) = r.time else { continue };
            let k = labels
                .iter()
                .position(|l| *l == r.label)
                .unwrap_or_else(|| {
                    labels.push(r.label);
                    times.push([Vec::new(), Vec::new()]);
                    run.push([0.0; 2]);
                    labels.len() - 1
                });
            run[k][0] += (t.end - t.start) * 1e3;
            run[k][1] += (t.end - prev.unwrap_or(t.start)) * 1e3;
            first.get_or_insert(t.start);
            prev = Some(t.end);
        }
        if let (Some(first), Some(last)) = (first, prev) {
            spans.push((last - first) * 1e3);
        }
        for (k, [pass, from_prev]) in run.into_iter().enumerate() {
            times[k][0].push(pass);
            times[k][1].push(from_prev);
        }
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
    };
    println!("  profile {title}: GPU ms, medians of {runs} runs");
    println!("    {:<28} {:>10} {:>10}", "", "pass", "from prev");
    for (label, [pass, from_prev]) in labels.iter().zip(&mut times) {
        println!(
            "    {label:<28} {:>10.3} {:>10.3}",
            median(pass),
            median(from_prev)
        );
    }
    println!("    {:<28} {:>21.3}", "GPU span", median(&mut spans));
    println!(
        "    {:<28} {:>21.3}",
        "wall: record to idle",
        median(&mut walls)
    );
    true
}

/// The sizes to run: `SPH_GPU_SIZES` (comma-separated counts such as `10k`,
/// `100k`, `1M`), by default 100k and 1M; each as the label and the side a
/// of a dam break a × 2a × a at 1 cm (a = 0.37: 37 × 74 × 37 ≈ 101k
/// particles; 0.8: 80 × 160 × 80 ≈ 1.02M).
fn sizes() -> Vec<(String, f32)> {
    let list = std::env::var("SPH_GPU_SIZES").unwrap_or_else(|_| "100k,1M".into());
    list.split(',')
        .map(|label| {
            let label = label.trim();
            let count: f32 = match label.to_ascii_lowercase() {
                l if l.ends_with('k') => l[..l.len() - 1].parse::<f32>().map(|n| n * 1e3),
                l if l.ends_with('m') => l[..l.len() - 1].parse::<f32>().map(|n| n * 1e6),
                l => l.parse(),
            }
            .unwrap_or_else(|_| panic!("SPH_GPU_SIZES: `{label}` is not a count such as 100k"));
            let a = match label {
                "100k" => 0.37,
                "1M" => 0.8,
                _ => (count * 0.5e-6).cbrt(),
            };
            (label.to_string(), a)
        })
        .collect()
}

/// A camera and shading for `scene`'s 1080p frames.
fn view(scene: &Scene, h: f32) -> (Camera, Shading) {
    let r = &scene.render;
    let camera = Camera {
        fov_y: r.fov_y.to_radians(),
        ..Camera::looking_at(r.camera.into(), r.look_at.into())
    };
    let shading = Shading {
        depth_epsilon: 0.5 * h,
        ..Default::default()
    };
    (camera, shading)
}

/// `pbf_frame` and `pbf_frame_1080p` for a dam break of side `a`, after its
/// profile.
fn pbf_frames(c: &mut Criterion, ctx: &GpuContext, label: &str, a: f32) {
    const FRAME: f32 = 1.0 / 60.0;
    let scene = Scene::dam_break(a, a, 0.01).with_solver(SolverKind::Pbf);
    let mut world = scene.build_world().expect("scene");
    let n = world.particles.len();
    let h = world.params().h;
    let mut gpu = GpuPbf::new(
        &ctx.device,
        &ctx.queue,
        &world.particles,
        world.params(),
        &scene.pbf_params(),
        &scene.boundary(),
    )
    .expect("GPU PBF");
    // A first frame, so that the profile and the extractor see a flow.
    gpu.advance(&ctx.device, &ctx.queue, FRAME).expect("frame");
    gpu.finish(&ctx.device).expect("frame");
    let pbf = scene.pbf_params();
    println!(
        "{label}: {n} particles, PBF {} substeps × {} iterations per 1/60 s frame",
        pbf.substeps_for(FRAME),
        pbf.iterations
    );
    print_profile(ctx, &format!("{label} PBF frame"), |profiler| {
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        gpu.encode_frame_profiled(&ctx.device, &ctx.queue, &mut encoder, FRAME, profiler)
            .expect("frame");
        ctx.queue.submit([encoder.finish()]);
    });
    // The CPU's share of a frame: recording its passes (wgpu's checks and
    // the driver's command buffer) and submitting them, without the GPU's run.
    let (mut records, mut submits) = (Vec::new(), Vec::new());
    for _ in 0..5 {
        wait(ctx);
        let start = std::time::Instant::now();
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        gpu.encode_frame(&ctx.device, &ctx.queue, &mut encoder, FRAME)
            .expect("frame");
        let commands = encoder.finish();
        records.push(start.elapsed().as_secs_f64() * 1e3);
        let start = std::time::Instant::now();
        ctx.queue.submit([commands]);
        submits.push(start.elapsed().as_secs_f64() * 1e3);
    }
    wait(ctx);
    records.sort_by(f64::total_cmp);
    submits.sort_by(f64::total_cmp);
    println!(
        "  {label} PBF frame on the CPU: recording {:.3} ms, submitting {:.3} ms (medians of 5)",
        records[2], submits[2]
    );
    let cpu_too = n <= 200_000;
    let mut group = c.benchmark_group("pbf_frame");
    group.sample_size(10);
    group.throughput(Throughput::Elements(n as u64));
    if cpu_too {
        group.bench_function(BenchmarkId::new("cpu", label), |b| {
            b.iter(|| world.advance(FRAME).expect("frame").substeps)
        });
    }
    group.bench_function(BenchmarkId::new("gpu", label), |b| {
        b.iter(|| {
            gpu.advance(&ctx.device, &ctx.queue, FRAME).expect("frame");
            wait(ctx);
        })
    });
    group.finish();

    let covered = ExtractParams::new(h);
    let thesis = covered.thesis();
    let mut extractor = gpu_extractor(ctx, &gpu, &thesis);
    let mut renderer =
        SplatRenderer::new(ctx, 1920, 1080, &Environment::procedural()).expect("renderer");
    let (camera, shading) = view(&scene, h);
    let mut group = c.benchmark_group("pbf_frame_1080p");
    group.sample_size(10);
    group.throughput(Throughput::Elements(n as u64));
    if cpu_too {
        let mut cpu = Extractor::new();
        group.bench_function(BenchmarkId::new("cpu_covered", label), |b| {
            b.iter(|| {
                world.advance(FRAME).expect("frame");
                let out = cpu.extract(&world.particles, &covered).expect("extract");
                let splats: Vec<Splat> = (out.surfels.iter())
                    .map(|s| Splat::new(s.position, s.normal, s.radius))
                    .collect();
                renderer.upload(ctx, &splats).expect("upload");
                renderer.render(ctx, &camera, &shading).expect("render");
                wait(ctx);
            })
        });
    }
    let mut anisotropic = gpu_extractor(ctx, &gpu, &thesis.anisotropic());
    let mut demo = gpu_extractor(ctx, &gpu, &covered.anisotropic());
    let adapters_path = renderer.splat_path();
    for (name, path) in [
        ("gpu", adapters_path),
        ("gpu_anisotropic", adapters_path),
        ("gpu_demo", adapters_path),
        // The demo's frame with the raster splat path, beside the adapter's
        // (compute on a GPU, `SplatPath::for_device`).
        ("gpu_demo_raster", SplatPath::Raster),
    ] {
        if name == "gpu_demo_raster" && path == adapters_path {
            continue;
        }
        let extractor = match name {
            "gpu" => &mut extractor,
            "gpu_anisotropic" => &mut anisotropic,
            _ => &mut demo,
        };
        renderer.set_splat_path(ctx, path).expect("splat path");
        renderer
            .use_gpu_splats(
                ctx,
                extractor.surfels_buffer(),
                extractor.draw_args_buffer(),
            )
            .expect("GPU splats");
        group.bench_function(BenchmarkId::new(name, label), |b| {
            b.iter(|| {
                let mut encoder = ctx.device.create_command_encoder(&Default::default());
                gpu.encode_frame(&ctx.device, &ctx.queue, &mut encoder, FRAME)
                    .expect("frame");
                extractor
                    .encode_attached(&ctx.queue, &mut encoder)
                    .expect("encode");
                renderer
                    .encode(ctx, &mut encoder, &camera, &shading)
                    .expect("render");
                ctx.queue.submit([encoder.finish()]);
                wait(ctx);
            })
        });
    }
    group.finish();
}

fn gpu_vs_cpu(c: &mut Criterion) {
    let ctx = match GpuContext::headless() {
        Ok(ctx) => ctx,
        Err(err) => {
            println!("skipped: {err}");
            return;
        }
    };
    println!("adapter: {}", ctx.adapter_summary());
    for (label, a) in sizes() {
        pbf_frames(c, &ctx, &label, a);
        let label = &label;
        let (scene, mut world, mut gpu) = setup(&ctx, a);
        let n = world.particles.len();
        let dt = world.stable_dt();
        let h = world.params().h;
        let covered = ExtractParams::new(h);
        let thesis = covered.thesis();
        let cpu_out = extract(&world.particles, &covered).expect("extract");
        let cpu_thesis = extract(&world.particles, &thesis).expect("extract");
        println!(
            "{label}: {n} particles; CPU extraction: {} surfels (covered), {} (thesis, efficiency {:.2})",
            cpu_out.surfels.len(),
            cpu_thesis.surfels.len(),
            cpu_thesis.stats.efficiency()
        );
        let mut extractor = gpu_extractor(&ctx, &gpu, &thesis);
        let anisotropic = thesis.anisotropic();
        let mut gpu_anisotropic = gpu_extractor(&ctx, &gpu, &anisotropic);
        // The demo's: covered mode (hole closing, 3×3 first splits) on the
        // anisotropic field.
        let demo = covered.anisotropic();
        let mut gpu_demo = gpu_extractor(&ctx, &gpu, &demo);
        // A frame half a stable step long: the GPU chooses its step as the
        // CPU does, so it lands on the frame's end in one adaptive step,
        // recorded alone (a batch of one). These frames move the GPU
        // simulation on a few steps before the timed groups.
        let mut substeps = 0;
        let profiled = print_profile(&ctx, &format!("{label} adaptive step"), |profiler| {
            let frame = gpu
                .advance_profiled(&ctx.device, &ctx.queue, 0.5 * dt, 1, profiler)
                .expect("frame");
            substeps = substeps.max(frame.substeps);
        });
        if profiled {
            println!(
                "    (at most {substeps} substeps per frame; a pass's time is its sum over them)"
            );
        }
        print_profile(&ctx, &format!("{label} extraction"), |profiler| {
            let mut encoder = ctx.device.create_command_encoder(&Default::default());
            extractor
                .encode_attached_profiled(&ctx.queue, &mut encoder, profiler)
                .expect("encode");
            ctx.queue.submit([encoder.finish()]);
        });
        print_profile(
            &ctx,
            &format!("{label} anisotropic extraction"),
            |profiler| {
                let mut encoder = ctx.device.create_command_encoder(&Default::default());
                gpu_anisotropic
                    .encode_attached_profiled(&ctx.queue, &mut encoder, profiler)
                    .expect("encode");
                ctx.queue.submit([encoder.finish()]);
            },
        );

        let mut group = c.benchmark_group("wcsph_step");
        group.sample_size(10);
        group.throughput(Throughput::Elements(n as u64));
        group.bench_function(BenchmarkId::new("cpu", label), |b| {
            b.iter(|| world.step().expect("stable"))
        });
        group.bench_function(BenchmarkId::new("gpu", label), |b| {
            b.iter(|| {
                gpu.step(&ctx.device, &ctx.queue, dt).expect("step");
                wait(&ctx);
            })
        });
        group.finish();

        let mut group = c.benchmark_group("extraction");
        group.sample_size(10);
        group.throughput(Throughput::Elements(n as u64));
        let mut cpu = Extractor::new();
        group.bench_function(BenchmarkId::new("cpu_covered", label), |b| {
            b.iter(|| {
                cpu.extract(&world.particles, &covered)
                    .expect("extract")
                    .stats
                    .surfels
            })
        });
        group.bench_function(BenchmarkId::new("cpu_thesis", label), |b| {
            b.iter(|| {
                cpu.extract(&world.particles, &thesis)
                    .expect("extract")
                    .stats
                    .surfels
            })
        });
        group.bench_function(BenchmarkId::new("cpu_anisotropic_thesis", label), |b| {
            b.iter(|| {
                cpu.extract(&world.particles, &anisotropic)
                    .expect("extract")
                    .stats
                    .surfels
            })
        });
        group.bench_function(BenchmarkId::new("cpu_demo", label), |b| {
            b.iter(|| {
                cpu.extract(&world.particles, &demo)
                    .expect("extract")
                    .stats
                    .surfels
            })
        });
        for (name, extractor) in [
            ("gpu_thesis", &mut extractor),
            ("gpu_anisotropic_thesis", &mut gpu_anisotropic),
            ("gpu_demo", &mut gpu_demo),
        ] {
            group.bench_function(BenchmarkId::new(name, label), |b| {
                b.iter(|| {
                    let mut encoder = ctx.device.create_command_encoder(&Default::default());
                    extractor
                        .encode_attached(&ctx.queue, &mut encoder)
                        .expect("encode");
                    ctx.queue.submit([encoder.finish()]);
                    wait(&ctx);
                })
            });
        }
        group.finish();

        let mut renderer =
            SplatRenderer::new(&ctx, 1920, 1080, &Environment::procedural()).expect("renderer");
        let (camera, shading) = view(&scene, h);
        let mut group = c.benchmark_group("wcsph_step_1080p");
        group.sample_size(10);
        group.throughput(Throughput::Elements(n as u64));
        // The CPU frame in both modes: covered is the demo's default, thesis
        // the GPU extractor's, so `cpu_thesis` against `gpu` is like for like.
        for (name, params) in [("cpu_covered", &covered), ("cpu_thesis", &thesis)] {
            group.bench_function(BenchmarkId::new(name, label), |b| {
                b.iter(|| {
                    world.step().expect("stable");
                    let out = cpu.extract(&world.particles, params).expect("extract");
                    let splats: Vec<Splat> = out
                        .surfels
                        .iter()
                        .map(|s| Splat::new(s.position, s.normal, s.radius))
                        .collect();
                    renderer.upload(&ctx, &splats).expect("upload");
                    renderer.render(&ctx, &camera, &shading).expect("render");
                    wait(&ctx);
                })
            });
        }
        renderer
            .use_gpu_splats(
                &ctx,
                extractor.surfels_buffer(),
                extractor.draw_args_buffer(),
            )
            .expect("GPU splats");
        print_profile(&ctx, &format!("{label} render 1080p"), |profiler| {
            let mut encoder = ctx.device.create_command_encoder(&Default::default());
            renderer
                .encode_profiled(&ctx, &mut encoder, &camera, &shading, profiler)
                .expect("render");
            ctx.queue.submit([encoder.finish()]);
        });
        group.bench_function(BenchmarkId::new("gpu", label), |b| {
            b.iter(|| {
                gpu.step(&ctx.device, &ctx.queue, dt).expect("step");
                let mut encoder = ctx.device.create_command_encoder(&Default::default());
                extractor
                    .encode_attached(&ctx.queue, &mut encoder)
                    .expect("encode");
                renderer
                    .encode(&ctx, &mut encoder, &camera, &shading)
                    .expect("render");
                ctx.queue.submit([encoder.finish()]);
                wait(&ctx);
            })
        });
        group.finish();
    }
}

/// `advance_batch`: one adaptive frame of 1/60 s (`GpuSolver::advance`) of a
/// small dam break, its steps recorded in batches of the frame's substeps + 1
/// and of 4 × its substeps: the steps past the frame's end dispatch no work,
/// so the two should cost about the same.
fn advance_batch(c: &mut Criterion) {
    let Ok(ctx) = GpuContext::headless() else {
        return;
    };
    let scene = Scene::dam_break(0.2, 0.1, 0.01);
    let world = scene.build_world().expect("scene");
    let frame_dt = 1.0 / 60.0;
    let mut group = c.benchmark_group("advance_batch");
    group.sample_size(10);
    for (label, factor) in [("substeps+1", None), ("4x_substeps", Some(4))] {
        let (device, queue) = (&ctx.device, &ctx.queue);
        let mut gpu = GpuSolver::new(
            device,
            queue,
            &world.particles,
            world.params(),
            &scene.boundary(),
        )
        .expect("GPU solver");
        gpu.set_time_stepping(world.time_stepping())
            .expect("time stepping");
        let first = gpu.advance(device, queue, frame_dt, 1000).expect("frame");
        let batch = factor.map_or(first.substeps + 1, |f| f * first.substeps);
        println!(
            "advance_batch/{label}: {} particles, {} substeps in the first frame, batch {batch}",
            gpu.len(),
            first.substeps
        );
        group.bench_function(label, |b| {
            b.iter(|| gpu.advance(device, queue, frame_dt, batch).expect("frame"))
        });
    }
    group.finish();
}

criterion_group!(benches, gpu_vs_cpu, advance_batch);
criterion_main!(benches);
