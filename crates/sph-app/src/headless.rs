//! Headless mode: simulate, extract, render each frame to PNG, write `frames.csv`
//! and optional particle/surfel exports.

use std::cell::RefCell;
use std::collections::VecDeque;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::Path;
use std::rc::Rc;
use std::time::Instant;

use image::codecs::gif::{GifEncoder, Repeat};
use image::{Delay, Frame};
use indicatif::{ProgressBar, ProgressStyle};
use sph_core::io::{FrameWriter, PointCloud};
use splat_render::wgpu_profiler::{GpuProfiler, GpuProfilerSettings};
use splat_render::{GpuContext, SplatRenderer, wgpu};

use crate::cli::Args;
use crate::error::AppError;
use crate::pipeline::{FrameStats, LateStats, Pipeline};
use crate::playback::Playback;

/// Runs `args.frame_count()` frames of `pipeline` and writes them to `args.out`.
pub fn run(args: &Args, mut pipeline: Pipeline) -> Result<(), AppError> {
    // First of all, so that a GIF path that cannot be written stops the run
    // before anything is written.
    let gif_file = (args.gif.as_ref())
        .map(|path| File::create(path).map_err(|e| AppError::output(path, e)))
        .transpose()?;
    let out = &args.out;
    std::fs::create_dir_all(out).map_err(|e| AppError::output(out, e))?;
    let csv_path = out.join("frames.csv");
    let mut rows = Rows::create(&csv_path, pipeline.playback.is_some())?;

    let gpu = match GpuContext::headless() {
        Ok(ctx) => {
            log::info!("rendering on {}", ctx.adapter_summary());
            Some(ctx)
        }
        // An adapter the user chose (WGPU_BACKEND=gl) that cannot draw the
        // splats: an error, not a run without the images asked for.
        Err(err @ splat_render::RenderError::GlBackend { .. }) => return Err(err.into()),
        Err(err) => {
            eprintln!(
                "{err}\nno images will be written; simulating, extracting and exporting only"
            );
            None
        }
    };
    let adapter = |flag: &str| {
        gpu.as_ref().ok_or_else(|| {
            AppError::Gpu(format!(
                "{flag} needs a GPU adapter, and none was found (see above)"
            ))
        })
    };
    if args.gpu_sim {
        pipeline.set_gpu_sim(Some(adapter("--gpu-sim")?))?;
    }
    if args.gpu_extract {
        pipeline.set_gpu_extract(Some(adapter("--gpu-extract")?))?;
    }
    if let Some(ctx) = gpu
        .as_ref()
        .filter(|c| args.gpu_by_default() && !c.is_software())
    {
        // The whole GPU path on a hardware adapter; a scene whose solver
        // does not run there keeps its simulation on the CPU.
        if pipeline.playback.is_none()
            && let Err(e) = pipeline.set_gpu_sim(Some(ctx))
        {
            println!("{e}: the simulation runs on the CPU");
        }
        pipeline.set_gpu_extract(Some(ctx))?;
    }
    let mut renderer = match &gpu {
        Some(ctx) => {
            let mut renderer =
                SplatRenderer::new(ctx, args.width, args.height, &crate::environment())?;
            if let Some(path) = args.splats.forced() {
                renderer.set_splat_path(ctx, path)?;
            }
            if !args.no_scenery {
                renderer.set_geometry(ctx, &pipeline.scenery()?)?;
            }
            Some(renderer)
        }
        None => None,
    };
    let export = |prefix: &str, format: Option<crate::cli::ExportFormat>| {
        format
            .map(|f| FrameWriter::new(out, prefix, f.into()).map_err(|e| AppError::output(out, e)))
            .transpose()
    };
    let mut gif = match (&args.gif, gif_file) {
        (Some(path), Some(file)) => {
            adapter("--gif")?;
            Some(GifWriter::new(path, file, args.fps)?)
        }
        _ => None,
    };
    let mut particles_out = export("particles", args.export_particles)?;
    let mut surfels_out = export("surfels", args.export_surfels)?;

    let frames = args.frame_count(pipeline.playback.as_ref().map(Playback::len));
    let frame_dt = 1.0 / args.fps;
    let source = match &pipeline.playback {
        Some(playback) => format!("{} files played", playback.len()),
        None => format!("solver {}", pipeline.world.solver().kind()),
    };
    println!(
        "scene `{}`: {} particles, {source}{}{}, {frames} frames at {} fps of simulated time, {}×{} → {}",
        pipeline.name,
        pipeline.world.particles.len(),
        if pipeline.gpu.is_some() {
            " (SPH step on the GPU)"
        } else {
            ""
        },
        if pipeline.gpu_extract.is_some() {
            " (surfels extracted on the GPU)"
        } else {
            ""
        },
        args.fps,
        args.width,
        args.height,
        out.display()
    );
    let bar = ProgressBar::new(u64::from(frames));
    bar.set_style(
        ProgressStyle::with_template(
            "{bar:40} {pos}/{len} frames, {elapsed} elapsed, eta {eta} {msg}",
        )
        .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    // The render passes' GPU time, where the adapter has timestamp queries.
    let mut profiler = match &gpu {
        Some(ctx)
            if ctx
                .device
                .features()
                .contains(wgpu::Features::TIMESTAMP_QUERY) =>
        {
            Some(
                GpuProfiler::new(&ctx.device, GpuProfilerSettings::default())
                    .map_err(|e| AppError::Gpu(e.to_string()))?,
            )
        }
        _ => None,
    };
    let camera = pipeline.camera();
    let shading = pipeline.shading();
    if args.cull {
        pipeline.set_viewpoint(Some(camera.eye))?;
    }
    for frame in 0..frames {
        let result = (|| -> Result<(), AppError> {
            pipeline.advance(frame_dt)?;
            pipeline.extract_surfels()?;
            let (mut render_ms, mut render_gpu_ms) = (0.0, None);
            if let (Some(ctx), Some(renderer)) = (&gpu, renderer.as_mut()) {
                let start = Instant::now();
                pipeline.show_surfels(ctx, renderer)?;
                let mut encoder = ctx.device.create_command_encoder(&Default::default());
                match profiler.as_mut() {
                    Some(p) => {
                        renderer.encode_profiled(ctx, &mut encoder, &camera, &shading, p)?;
                        p.resolve_queries(&mut encoder);
                    }
                    None => renderer.encode(ctx, &mut encoder, &camera, &shading)?,
                }
                ctx.queue.submit([encoder.finish()]);
                let image = renderer.read_image(ctx)?;
                render_ms = start.elapsed().as_secs_f64() * 1e3;
                if let Some(p) = profiler.as_mut() {
                    render_gpu_ms = gpu_span_ms(ctx, p)?;
                }
                let path = out.join(format!("frame_{frame:05}.png"));
                crate::png::save(&image, &path)?;
                if let Some(gif) = gif.as_mut() {
                    gif.push(image)?;
                }
            }
            pipeline.stats.render_ms = render_ms;
            let time = pipeline.stats.time;
            if let Some(w) = particles_out.as_mut() {
                w.write(&PointCloud::from_particles(pipeline.particles()?), time)?;
            }
            if let Some(w) = surfels_out.as_mut() {
                write_surfels(w, &pipeline, time)?;
            }
            // An error the device reported on its own during the frame.
            if let Some(ctx) = &gpu {
                ctx.check()?;
            }
            let s = pipeline.stats;
            let render_gpu = render_gpu_ms.map_or(String::new(), |ms| format!("{ms:.3}"));
            let late = pipeline.take_late();
            rows.push(frame, s, render_gpu, late)?;
            bar.set_message(format!("{} surfels", s.surfels));
            bar.inc(1);
            Ok(())
        })();
        result.map_err(|source| AppError::Incomplete {
            frame,
            csv: csv_path.clone(),
            source: Box::new(source),
        })?;
    }
    // The last GPU frames' statistics, then their rows.
    pipeline
        .finish_gpu()
        .and_then(|()| rows.finish(pipeline.take_late()))
        .map_err(|source| AppError::Incomplete {
            frame: frames,
            csv: csv_path.clone(),
            source: Box::new(source),
        })?;
    bar.finish_and_clear();
    if let Some(gif) = gif {
        gif.finish()?;
    }
    let what = match (&gpu, &args.gif) {
        (Some(_), Some(_)) => "PNG frames, the GIF, ",
        (Some(_), None) => "PNG frames, ",
        _ => "",
    };
    println!(
        "wrote {frames} frames ({what}frames.csv{}{}) to {}",
        if particles_out.is_some() {
            ", particle files"
        } else {
            ""
        },
        if surfels_out.is_some() {
            ", surfel files"
        } else {
            ""
        },
        display(out)
    );
    Ok(())
}

/// The rows of `frames.csv`, each written once its statistics are complete:
/// at once on the CPU path, a frame or two late where PBF runs on the GPU
/// ([`crate::pipeline::FrameStats::pending`]).
struct Rows {
    csv: BufWriter<File>,
    path: std::path::PathBuf,
    /// Whether the frames are played files (solver column `input`).
    input: bool,
    /// Rows waiting for their statistics, in frame order.
    held: VecDeque<(u32, FrameStats, String)>,
}

impl Rows {
    /// Creates `path` and writes the header.
    fn create(path: &Path, input: bool) -> Result<Self, AppError> {
        let file = File::create(path).map_err(|e| AppError::output(path, e))?;
        let mut rows = Self {
            csv: BufWriter::new(file),
            path: path.to_path_buf(),
            input,
            held: VecDeque::new(),
        };
        writeln!(
            rows.csv,
            "frame,time,particles,surfels,evaluations,step_ms,extract_ms,render_ms,render_gpu_ms,\
             solver,substeps,iterations,density_error_avg,density_error_max,clamped,\
             divergence_iterations,viscosity_iterations,unconverged"
        )
        .map_err(|e| AppError::output(path, e))?;
        Ok(rows)
    }

    /// Adds frame `index`'s row and the statistics that came back for
    /// earlier ones, and writes every row that is complete.
    fn push(
        &mut self,
        index: u32,
        stats: FrameStats,
        render_gpu: String,
        late: Vec<LateStats>,
    ) -> Result<(), AppError> {
        self.held.push_back((index, stats, render_gpu));
        self.fill(late);
        self.write(false)
    }

    /// Fills in the last statistics and writes every row left.
    fn finish(&mut self, late: Vec<LateStats>) -> Result<(), AppError> {
        self.fill(late);
        self.write(true)
    }

    fn fill(&mut self, late: Vec<LateStats>) {
        for l in late {
            if let Some((_, s, _)) = self.held.iter_mut().find(|(_, s, _)| s.frame == l.frame) {
                s.density_error_avg = l.density_error_avg;
                s.density_error_max = l.density_error_max;
                s.clamped = l.clamped;
                s.pending = false;
            }
        }
    }

    /// Writes the complete rows at the front (with `all`, every row).
    fn write(&mut self, all: bool) -> Result<(), AppError> {
        // Density errors as fractions; empty where WCSPH ran on the GPU.
        let error = |e: f32| {
            if e.is_finite() {
                format!("{e:.6}")
            } else {
                String::new()
            }
        };
        while let Some((frame, s, render_gpu)) = self.held.front() {
            if s.pending && !all {
                break;
            }
            writeln!(
                self.csv,
                "{frame},{:.6},{},{},{},{:.3},{:.3},{:.3},{render_gpu},{},{},{},{},{},{},{},{},{}",
                s.time,
                s.particles,
                s.surfels,
                s.evaluations,
                s.step_ms,
                s.extract_ms,
                s.render_ms,
                if self.input {
                    "input".to_string()
                } else {
                    s.solver.to_string()
                },
                s.substeps,
                s.iterations,
                error(s.density_error_avg),
                error(s.density_error_max),
                s.clamped,
                s.divergence_iterations,
                s.viscosity_iterations,
                s.unconverged
            )
            .map_err(|e| AppError::output(&self.path, e))?;
            self.held.pop_front();
        }
        self.csv
            .flush()
            .map_err(|e| AppError::output(&self.path, e))
    }
}

/// An animated GIF of the rendered frames, written frame by frame.
struct GifWriter {
    path: std::path::PathBuf,
    encoder: GifEncoder<BufWriter<KeptErrors>>,
    /// Frames per second.
    fps: f64,
    /// Frames written so far.
    frames: u64,
    /// The first error of a write to the file.
    error: Rc<RefCell<Option<std::io::Error>>>,
}

/// The GIF's file, keeping the first write error for [`GifWriter::finish`]:
/// the encoder writes the GIF's trailer and its buffer flushes when they are
/// dropped, and drops cannot report errors (a short GIF, held in the
/// buffer until then, would be lost on a full disk without a word).
struct KeptErrors {
    file: File,
    error: Rc<RefCell<Option<std::io::Error>>>,
}

impl KeptErrors {
    fn kept<T>(&self, result: std::io::Result<T>) -> std::io::Result<T> {
        result.inspect_err(|e| {
            let copy = std::io::Error::new(e.kind(), e.to_string());
            self.error.borrow_mut().get_or_insert(copy);
        })
    }
}

impl Write for KeptErrors {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let result = self.file.write(buf);
        self.kept(result)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        let result = self.file.flush();
        self.kept(result)
    }
}

impl GifWriter {
    /// A looping GIF of frames `fps` per second into `file`, created at
    /// `path`.
    fn new(path: &Path, file: File, fps: f64) -> Result<Self, AppError> {
        let error = Rc::new(RefCell::new(None));
        let file = KeptErrors {
            file,
            error: Rc::clone(&error),
        };
        let mut encoder = GifEncoder::new_with_speed(BufWriter::new(file), 10);
        encoder
            .set_repeat(Repeat::Infinite)
            .map_err(|e| AppError::output(path, e))?;
        Ok(Self {
            path: path.to_path_buf(),
            encoder,
            fps,
            frames: 0,
            error,
        })
    }

    /// Frame `k`'s delay in hundredths of a second, the only unit a GIF
    /// has: the rounded end time of the frame less that of the one before,
    /// so that a clip plays at `fps` on average (at 15 fps 7, 6, 7, 7, 6,
    /// 7, …, where one rounded delay, 6, would play 11 % fast).
    /// `Args::check` keeps fps at most 50, so every delay is at least 2:
    /// browsers show a frame of 1/100 s or none for 1/10 s.
    fn centiseconds(fps: f64, k: u64) -> u32 {
        let end = |k: u64| (k as f64 * 100.0 / fps).round();
        (end(k + 1) - end(k)) as u32
    }

    fn push(&mut self, image: image::RgbaImage) -> Result<(), AppError> {
        let cs = Self::centiseconds(self.fps, self.frames);
        self.frames += 1;
        let frame = Frame::from_parts(image, 0, 0, Delay::from_numer_denom_ms(10 * cs, 1));
        self.encoder
            .encode_frame(frame)
            .map_err(|e| AppError::output(&self.path, e))
    }

    /// Writes the trailer, flushes, and reports the first write that failed.
    fn finish(self) -> Result<(), AppError> {
        drop(self.encoder);
        match self.error.borrow_mut().take() {
            Some(e) => Err(AppError::output(&self.path, e)),
            None => Ok(()),
        }
    }
}

/// Ends the profiler's frame and returns its GPU span, first pass start to
/// last pass end (ms), once the device has finished it (the image read-back
/// waited for it); `None` when its queries are not back.
fn gpu_span_ms(ctx: &GpuContext, profiler: &mut GpuProfiler) -> Result<Option<f64>, AppError> {
    profiler
        .end_frame()
        .map_err(|e| AppError::Gpu(e.to_string()))?;
    ctx.device
        .poll(wgpu::PollType::wait_indefinitely())
        .map_err(|e| AppError::Gpu(e.to_string()))?;
    let Some(results) = profiler.process_finished_frame(ctx.queue.get_timestamp_period()) else {
        return Ok(None);
    };
    let times = results.iter().filter_map(|r| r.time.clone());
    let (first, last) = times.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), t| {
        (a.min(t.start), b.max(t.end))
    });
    Ok((last >= first).then_some((last - first) * 1e3))
}

fn write_surfels(w: &mut FrameWriter, pipeline: &Pipeline, time: f64) -> Result<(), AppError> {
    let s = pipeline.surfels_on_cpu()?;
    let positions: Vec<_> = s.iter().map(|s| s.position).collect();
    let normals: Vec<_> = s.iter().map(|s| s.normal).collect();
    let radii: Vec<_> = s.iter().map(|s| s.radius).collect();
    let cloud = PointCloud {
        positions: &positions,
        vectors: vec![("normal", &normals)],
        scalars: vec![("radius", &radii)],
    };
    w.write(&cloud, time)?;
    Ok(())
}

fn display(p: &Path) -> String {
    std::fs::canonicalize(p)
        .unwrap_or_else(|_| p.to_path_buf())
        .display()
        .to_string()
}
