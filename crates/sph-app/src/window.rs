//! Windowed mode: winit window, wgpu surface, splat renderer, egui panel.
//!
//! Controls: drag to rotate, scroll to zoom, right-drag to pan, Ctrl+drag to
//! push the fluid; Space pause, N single step, R reset, 1–8 built-in scenes,
//! S screenshot, F cycle views, Esc quit.

use std::sync::{Arc, RwLock};
use std::time::Instant;

use glam::{Vec2, Vec3};
use sph_core::SolverKind;
use sph_core::solver::ExternalAcceleration;
use splat_render::{GpuContext, SplatPath, SplatRenderer, View, wgpu};
use winit::application::ApplicationHandler;
use winit::event::{ElementState, MouseButton, MouseScrollDelta, WindowEvent};
use winit::event_loop::{ActiveEventLoop, ControlFlow, EventLoop};
use winit::keyboard::{Key, ModifiersState, NamedKey};
use winit::window::{Window, WindowId};

use crate::cli::Args;
use crate::error::AppError;
use crate::orbit::Orbit;
use crate::panel::{self, Settings, Toggle, VIEW_NAMES};
use crate::pipeline::Pipeline;
use crate::scenes;

/// Whether a window system is reachable.
pub fn display_available() -> bool {
    if cfg!(any(target_os = "windows", target_os = "macos")) {
        return true;
    }
    ["DISPLAY", "WAYLAND_DISPLAY"]
        .iter()
        .any(|v| std::env::var_os(v).is_some_and(|s| !s.is_empty()))
}

/// Opens the window and runs until it is closed.
pub fn run(args: &Args, pipeline: Pipeline) -> Result<(), AppError> {
    let event_loop = EventLoop::new().map_err(|e| AppError::Window(e.to_string()))?;
    event_loop.set_control_flow(ControlFlow::Poll);
    let mut app = App::new(args, pipeline);
    event_loop
        .run_app(&mut app)
        .map_err(|e| AppError::Window(e.to_string()))?;
    app.error.map_or(Ok(()), Err)
}

/// A push of the fluid near the cursor ray (Ctrl+drag): the same field on
/// the CPU (the processor below) and on the GPU (`set_push` of either GPU
/// solver).
type Push = sph_gpu::RayPush;

/// The processor applying [`Push`]: acceleration falling off smoothly with the
/// distance from the cursor ray.
fn push_processor(push: Arc<RwLock<Option<Push>>>) -> impl sph_core::processor::Processor {
    ExternalAcceleration::new("push", move |x: Vec3, _t: f64| {
        match *push.read().unwrap_or_else(|e| e.into_inner()) {
            Some(p) => p.acceleration_at(x),
            None => Vec3::ZERO,
        }
    })
}

/// Adds the push processor after the forces of `pipeline`'s world (every
/// rebuilt world needs it again).
fn install_push(pipeline: &mut Pipeline, push: &Arc<RwLock<Option<Push>>>) {
    pipeline
        .world
        .program_mut()
        .insert_after("forces", push_processor(push.clone()));
}

struct Gfx {
    window: Arc<Window>,
    surface: wgpu::Surface<'static>,
    config: wgpu::SurfaceConfiguration,
    ctx: GpuContext,
    renderer: SplatRenderer,
    egui_state: egui_winit::State,
    egui_renderer: egui_wgpu::Renderer,
}

struct App {
    size: (u32, u32),
    args_screenshot_after: Option<u64>,
    /// Whether a hardware adapter switches the GPU path on
    /// ([`Args::gpu_by_default`]).
    gpu_by_default: bool,
    out: std::path::PathBuf,
    iterations: u32,
    pipeline: Pipeline,
    orbit: Orbit,
    settings: Settings,
    push: Arc<RwLock<Option<Push>>>,
    gfx: Option<Gfx>,
    /// What the renderer holds: `Some(particles_view)` until the next extraction.
    uploaded: Option<bool>,
    /// The scenery the renderer draws: `Some(on)` until the scene or the
    /// toggle changes.
    geometry: Option<bool>,
    egui: egui::Context,
    cursor: Vec2,
    dragging: Option<MouseButton>,
    modifiers: ModifiersState,
    last: Instant,
    sim_debt: f64,
    /// Simulated over wall seconds, smoothed: 1 while the window keeps real
    /// time, below 1 where the machine falls behind.
    realtime: f64,
    fps: f64,
    render_ms: f64,
    screenshots: u32,
    frames_drawn: u64,
    error: Option<AppError>,
}

impl App {
    fn new(args: &Args, mut pipeline: Pipeline) -> Self {
        let push = Arc::new(RwLock::new(None));
        install_push(&mut pipeline, &push);
        let mut shading = pipeline.shading();
        shading.view = View::Shaded;
        Self {
            size: (args.width, args.height),
            args_screenshot_after: args.screenshot_after,
            gpu_by_default: args.gpu_by_default(),
            out: args.out.clone(),
            iterations: args.iterations,
            orbit: Orbit::from_camera(&pipeline.camera()),
            pipeline,
            settings: Settings {
                shading,
                view: 0,
                paused: false,
                step_once: false,
                gpu_sim: Toggle::new(args.gpu_sim),
                gpu_extract: Toggle::new(args.gpu_extract),
                cull: args.cull,
                compute_splats: args.splats.forced().map(|path| path == SplatPath::Compute),
                scenery: !args.no_scenery,
                fluid_note: None,
            },
            push,
            gfx: None,
            uploaded: None,
            geometry: None,
            egui: egui::Context::default(),
            cursor: Vec2::ZERO,
            dragging: None,
            modifiers: ModifiersState::empty(),
            last: Instant::now(),
            sim_debt: 0.0,
            realtime: 1.0,
            fps: 0.0,
            render_ms: 0.0,
            screenshots: 0,
            frames_drawn: 0,
            error: None,
        }
    }

    fn fail(&mut self, event_loop: &ActiveEventLoop, err: AppError) {
        self.error = Some(err);
        event_loop.exit();
    }

    fn init_gfx(&mut self, event_loop: &ActiveEventLoop) -> Result<Gfx, AppError> {
        let attrs = Window::default_attributes()
            .with_title("sph-splat")
            .with_inner_size(winit::dpi::PhysicalSize::new(self.size.0, self.size.1));
        let window = Arc::new(
            event_loop
                .create_window(attrs)
                .map_err(|e| AppError::Window(e.to_string()))?,
        );
        let instance = splat_render::instance_from_env();
        let surface = instance
            .create_surface(window.clone())
            .map_err(|e| AppError::Window(e.to_string()))?;
        let ctx = pollster::block_on(GpuContext::for_surface(instance, &surface))?;
        let (width, height) = surface_size(&ctx, window.inner_size());
        let mut config = surface
            .get_default_config(&ctx.adapter, width, height)
            .ok_or_else(|| {
                AppError::Window("the surface is not supported by the adapter".into())
            })?;
        // egui blends in gamma space and wants a non-sRGB target; the splat
        // image's blit encodes sRGB itself for such a format.
        let plain = config.format.remove_srgb_suffix();
        if surface
            .get_capabilities(&ctx.adapter)
            .formats
            .contains(&plain)
        {
            config.format = plain;
        }
        surface.configure(&ctx.device, &config);
        let mut renderer =
            SplatRenderer::new(&ctx, config.width, config.height, &crate::environment())?;
        // A path forced by --splats from the first frame (the adapter's
        // choice otherwise); what the compute path cannot draw is an error.
        if let Some(compute) = self.settings.compute_splats {
            let path = if compute {
                SplatPath::Compute
            } else {
                SplatPath::Raster
            };
            renderer.set_splat_path(&ctx, path)?;
        }
        let egui_state = egui_winit::State::new(
            self.egui.clone(),
            egui::ViewportId::ROOT,
            &window,
            Some(window.scale_factor() as f32),
            None,
            Some(ctx.device.limits().max_texture_dimension_2d as usize),
        );
        let egui_renderer =
            egui_wgpu::Renderer::new(&ctx.device, config.format, Default::default());
        log::info!("window on {}", ctx.adapter_summary());
        Ok(Gfx {
            window,
            surface,
            config,
            ctx,
            renderer,
            egui_state,
            egui_renderer,
        })
    }

    fn switch_scene(&mut self, index: usize) -> Result<(), AppError> {
        let Some((name, _, make)) = scenes::BUILT_IN.get(index) else {
            return Ok(());
        };
        let mut pipeline = Pipeline::new(name.to_string(), make(), self.iterations)?;
        pipeline.extract = self.pipeline.extract;
        pipeline.extract.h = pipeline.world.params().h;
        install_push(&mut pipeline, &self.push);
        self.orbit = Orbit::from_camera(&pipeline.camera());
        self.settings.shading.depth_epsilon = pipeline.shading().depth_epsilon;
        self.pipeline = pipeline;
        self.geometry = None;
        self.settings.fluid_note = None;
        Ok(())
    }

    /// Switches the SPH step and the extraction to the GPU or back when their
    /// settings changed; a scene the GPU path cannot run unticks the box and
    /// says why.
    fn sync_gpu(&mut self) {
        let Some(gfx) = self.gfx.as_ref() else {
            return;
        };
        let (sim, extract) = (&mut self.settings.gpu_sim, &mut self.settings.gpu_extract);
        if sim.on != self.pipeline.gpu.is_some() {
            sim.settle(self.pipeline.set_gpu_sim(sim.on.then_some(&gfx.ctx)));
        }
        if extract.on != self.pipeline.gpu_extract.is_some() {
            extract.settle(
                self.pipeline
                    .set_gpu_extract(extract.on.then_some(&gfx.ctx)),
            );
            self.uploaded = None;
        }
    }

    /// Runs the scene from its start with another solver
    /// ([`sph_core::Scene::switch_solver`], whose notes it prints). Where
    /// the GPU step cannot run the new solver's scene (DFSPH, WCSPH with
    /// Akinci et al.'s forces, PBF with its implicit viscosity), it goes
    /// back to the CPU with the GPU path's own reason.
    fn switch_solver(&mut self, kind: SolverKind) -> Result<(), AppError> {
        for note in self.pipeline.scene.switch_solver(kind) {
            println!("{note}");
        }
        match self.reset() {
            Err(e @ AppError::Gpu(_)) if self.pipeline.gpu.is_some() => {
                let refusal = self
                    .pipeline
                    .set_gpu_sim(None)
                    .and(Err(AppError::Gpu(format!("{e}: back on the CPU"))));
                self.settings.gpu_sim.settle(refusal);
                self.reset()
            }
            done => done,
        }
    }

    fn reset(&mut self) -> Result<(), AppError> {
        self.pipeline.reset()?;
        self.settings.fluid_note = None;
        install_push(&mut self.pipeline, &self.push);
        Ok(())
    }

    /// Rebuilds the world around the current particles after a parameter
    /// change ([`sph_core::Scene::world_continuing`]: its clock and
    /// emitters run on). A value the scene refuses (a sleeping threshold
    /// that the gravity now set would leave hanging, ...) goes back to
    /// `applied`, the fluid and solver the world runs, and the panel says
    /// why.
    fn apply_fluid_params(
        &mut self,
        applied: (sph_core::scene::FluidSpec, sph_core::scene::SolverSpec),
    ) -> Result<(), AppError> {
        self.pipeline.particles()?;
        let pipeline = &mut self.pipeline;
        let was = sph_core::Scene {
            fluid: applied.0,
            solver: applied.1,
            ..pipeline.scene.clone()
        };
        match pipeline.scene.world_continuing(&mut pipeline.world, &was) {
            Ok(world) => {
                pipeline.world = world;
                self.settings.fluid_note = None;
            }
            Err(e) => {
                log::warn!("{e}");
                pipeline.scene = was;
                self.settings.fluid_note = Some(format!("not applied: {e}"));
                return Ok(());
            }
        }
        if let Some(gpu) = &self.pipeline.gpu {
            // The GPU solver holds the old parameters: start it again from
            // here, or go on on the CPU with the GPU path's reason.
            match gpu.restart(&self.pipeline.world, &self.pipeline.scene) {
                Ok(gpu) => self.pipeline.gpu = Some(gpu),
                Err(e) => {
                    let refusal = (self.pipeline.set_gpu_sim(None))
                        .and(Err(AppError::Gpu(format!("{e}: back on the CPU"))));
                    self.settings.gpu_sim.settle(refusal);
                }
            }
        }
        install_push(&mut self.pipeline, &self.push);
        Ok(())
    }

    fn key(&mut self, event_loop: &ActiveEventLoop, key: &Key) -> Result<(), AppError> {
        match key {
            Key::Named(NamedKey::Space) => self.settings.paused = !self.settings.paused,
            Key::Named(NamedKey::Escape) => event_loop.exit(),
            Key::Character(c) => match c.as_str() {
                "n" | "N" => self.settings.step_once = true,
                "r" | "R" => self.reset()?,
                "s" | "S" => self.screenshot()?,
                "f" | "F" => self.settings.view = (self.settings.view + 1) % VIEW_NAMES.len(),
                d => {
                    if let Some(n) = d.parse::<usize>().ok().filter(|n| (1..=9).contains(n)) {
                        self.switch_scene(n - 1)?;
                    }
                }
            },
            _ => {}
        }
        Ok(())
    }

    fn screenshot(&mut self) -> Result<(), AppError> {
        let Some(gfx) = &self.gfx else { return Ok(()) };
        std::fs::create_dir_all(&self.out).map_err(|e| AppError::output(&self.out, e))?;
        let path = self
            .out
            .join(format!("screenshot_{:03}.png", self.screenshots));
        crate::png::save(&gfx.renderer.read_image(&gfx.ctx)?, &path)?;
        self.screenshots += 1;
        println!("screenshot: {}", path.display());
        Ok(())
    }

    fn simulate(&mut self) -> Result<(), AppError> {
        let now = Instant::now();
        let real = now.duration_since(self.last).as_secs_f64();
        self.last = now;
        self.fps = 0.9 * self.fps + 0.1 / real.max(1e-6);
        let frame_dt = f64::from(self.pipeline.scene.time_step.frame_dt);
        // The push reaches a GPU solver through its uniforms (the CPU
        // world's through its processor).
        let push = *self.push.read().unwrap_or_else(|e| e.into_inner());
        self.pipeline.set_gpu_push(push)?;
        let mut advanced = false;
        if self.settings.paused {
            self.sim_debt = 0.0;
            if std::mem::take(&mut self.settings.step_once) {
                self.pipeline.advance(frame_dt)?;
                advanced = true;
            }
        } else {
            // Simulated time follows wall time at a fixed simulated rate,
            // independent of the frame rate; at most two frames of catch-up,
            // so a slow machine slows down instead of stalling, and the
            // panel shows by how much (the real-time factor).
            let owed = self.sim_debt + real;
            self.sim_debt = owed.min(2.0 * frame_dt);
            // The wall time dropped by the cap is time not simulated.
            let factor = 1.0 - (owed - self.sim_debt) / real.max(1e-6);
            // Smoothed over about a second of wall time.
            self.realtime += real.min(1.0) * (factor.clamp(0.0, 1.0) - self.realtime);
            while self.sim_debt >= frame_dt {
                self.pipeline.advance(frame_dt)?;
                self.sim_debt -= frame_dt;
                advanced = true;
            }
        }
        if advanced || self.pipeline.needs_extraction() {
            self.pipeline.extract_surfels()?;
            self.uploaded = None;
        }
        Ok(())
    }

    fn redraw(&mut self, event_loop: &ActiveEventLoop) -> Result<(), AppError> {
        let camera = self.orbit.camera();
        self.pipeline
            .set_viewpoint(self.settings.cull.then_some(camera.eye))?;
        self.simulate()?;
        let Some(gfx) = self.gfx.as_mut() else {
            return Ok(());
        };
        // An error the device reported on its own since the last frame.
        gfx.ctx.check()?;
        let start = Instant::now();
        if self.geometry != Some(self.settings.scenery) {
            let geometry = if self.settings.scenery {
                self.pipeline.scenery()?
            } else {
                Default::default()
            };
            gfx.renderer.set_geometry(&gfx.ctx, &geometry)?;
            self.geometry = Some(self.settings.scenery);
        }
        let particles_view = self.settings.view == 4;
        // Surfels are uploaded once per extraction; particle discs face the
        // camera, so they follow it every frame.
        if particles_view || self.uploaded != Some(particles_view) {
            if particles_view {
                let splats = self.pipeline.particle_splats(camera.eye)?;
                gfx.renderer.upload(&gfx.ctx, &splats)?;
            } else {
                self.pipeline.show_surfels(&gfx.ctx, &mut gfx.renderer)?;
            }
            self.uploaded = Some(particles_view);
        }
        let mut shading = self.settings.shading;
        shading.view = if particles_view {
            View::Normals
        } else {
            View::ALL[self.settings.view]
        };
        let frame = match gfx.surface.get_current_texture() {
            wgpu::CurrentSurfaceTexture::Success(t)
            | wgpu::CurrentSurfaceTexture::Suboptimal(t) => t,
            wgpu::CurrentSurfaceTexture::Outdated | wgpu::CurrentSurfaceTexture::Lost => {
                gfx.surface.configure(&gfx.ctx.device, &gfx.config);
                return Ok(());
            }
            other => {
                log::warn!("surface: {other:?}");
                return Ok(());
            }
        };
        let view = frame.texture.create_view(&Default::default());
        let chosen = gfx.renderer.splat_path() == SplatPath::Compute;
        let path = if *self.settings.compute_splats.get_or_insert(chosen) {
            SplatPath::Compute
        } else {
            SplatPath::Raster
        };
        if gfx.renderer.splat_path() != path
            && let Err(e) = gfx.renderer.set_splat_path(&gfx.ctx, path)
        {
            log::warn!("{e}");
            self.settings.compute_splats = Some(false);
        }
        gfx.renderer
            .render_to_surface(&gfx.ctx, &camera, &shading, &view, gfx.config.format)?;

        // The panel, drawn over the splats.
        let raw = gfx.egui_state.take_egui_input(&gfx.window);
        let extract_before = self.pipeline.extract;
        let shown = panel::Shown {
            name: &self.pipeline.name,
            stats: self.pipeline.stats,
            latest_late: self.pipeline.latest_late,
            realtime: self.realtime,
            fps: self.fps,
            render_ms: self.render_ms,
            playing: (self.pipeline.playback.as_ref()).map(crate::playback::Playback::len),
        };
        // What the world runs of what the sliders edit, for an edit the
        // scene refuses.
        let applied = (self.pipeline.scene.fluid, self.pipeline.scene.solver);
        let (settings, scene, extract) = (
            &mut self.settings,
            &mut self.pipeline.scene,
            &mut self.pipeline.extract,
        );
        let mut choices = panel::Choices::default();
        let full = self.egui.run_pass(raw, |ctx| {
            // egui may run a frame's ui twice (a first pass it discards),
            // and only the first sees the input: keep what either chose.
            choices.absorb(panel::draw(ctx, &shown, settings, scene, extract));
        });
        gfx.egui_state
            .handle_platform_output(&gfx.window, full.platform_output);
        let prims = self.egui.tessellate(full.shapes, full.pixels_per_point);
        let device = &gfx.ctx.device;
        let queue = &gfx.ctx.queue;
        for (id, deltas) in &full.textures_delta.set {
            for delta in deltas {
                gfx.egui_renderer.update_texture(device, queue, *id, delta);
            }
        }
        let screen = egui_wgpu::ScreenDescriptor {
            size_in_pixels: [gfx.config.width, gfx.config.height],
            pixels_per_point: full.pixels_per_point,
        };
        let mut encoder = device.create_command_encoder(&Default::default());
        let extra = gfx
            .egui_renderer
            .update_buffers(device, queue, &mut encoder, &prims, &screen);
        {
            let mut pass = encoder
                .begin_render_pass(&wgpu::RenderPassDescriptor {
                    label: Some("egui"),
                    color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                        view: &view,
                        depth_slice: None,
                        resolve_target: None,
                        ops: wgpu::Operations {
                            load: wgpu::LoadOp::Load,
                            store: wgpu::StoreOp::Store,
                        },
                    })],
                    ..Default::default()
                })
                .forget_lifetime();
            gfx.egui_renderer.render(&mut pass, &prims, &screen);
        }
        queue.submit(extra.into_iter().chain([encoder.finish()]));
        for id in &full.textures_delta.free {
            gfx.egui_renderer.free_texture(id);
        }
        gfx.window.pre_present_notify();
        queue.present(frame);
        self.render_ms = start.elapsed().as_secs_f64() * 1e3;
        self.frames_drawn += 1;

        if choices.fluid_changed {
            self.apply_fluid_params(applied)?;
        }
        if self.pipeline.extract != extract_before
            && let Some(gfx) = self.gfx.as_ref()
        {
            self.pipeline.extract_params_changed(&gfx.ctx)?;
            self.uploaded = None;
        }
        if let Some(i) = choices.scene {
            self.switch_scene(i)?;
        }
        if let Some(kind) = choices.solver {
            self.switch_solver(kind)?;
        }
        self.sync_gpu();
        if self.args_screenshot_after == Some(self.frames_drawn) {
            self.screenshot()?;
            event_loop.exit();
        }
        Ok(())
    }

    fn mouse_moved(&mut self, pos: Vec2) {
        let delta = pos - self.cursor;
        self.cursor = pos;
        let height = self.gfx.as_ref().map_or(1.0, |g| g.config.height as f32);
        match self.dragging {
            Some(MouseButton::Left) if self.modifiers.control_key() => {
                let camera = self.orbit.camera();
                let (w, h) = self
                    .gfx
                    .as_ref()
                    .map_or((1, 1), |g| (g.config.width, g.config.height));
                let (origin, dir) = camera.pixel_ray(pos.x as u32, pos.y as u32, w, h);
                let (right, up) = self.orbit.screen_axes();
                let push = Push {
                    origin,
                    dir,
                    acceleration: (delta.x * right - delta.y * up) * 40.0,
                    radius: 4.0 * self.pipeline.world.params().h,
                };
                // The CPU's push processor reads it unchecked (the GPU's
                // `set_push` checks it): a push NaN would make the fluid NaN.
                match push.validate() {
                    Ok(()) => *self.push.write().unwrap_or_else(|e| e.into_inner()) = Some(push),
                    Err(e) => log::warn!("push ignored: {e}"),
                }
            }
            Some(MouseButton::Left) => self.orbit.rotate(delta),
            Some(MouseButton::Right) => self.orbit.pan(delta, height),
            _ => {}
        }
    }
}

impl ApplicationHandler for App {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.gfx.is_some() {
            return;
        }
        match self.init_gfx(event_loop) {
            Ok(gfx) => {
                if self.gpu_by_default && !gfx.ctx.is_software() {
                    // The whole GPU path on a hardware adapter (`sync_gpu`
                    // switches it on; a scene it cannot run unticks the box).
                    self.settings.gpu_sim.on = self.pipeline.playback.is_none();
                    self.settings.gpu_extract.on = true;
                }
                self.gfx = Some(gfx);
            }
            Err(e) => self.fail(event_loop, e),
        }
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        let consumed = match self.gfx.as_mut() {
            Some(gfx) => gfx.egui_state.on_window_event(&gfx.window, &event).consumed,
            None => false,
        };
        let result = match event {
            WindowEvent::CloseRequested => {
                event_loop.exit();
                Ok(())
            }
            WindowEvent::Resized(size) => {
                if let Some(gfx) = self.gfx.as_mut() {
                    (gfx.config.width, gfx.config.height) = surface_size(&gfx.ctx, size);
                    gfx.surface.configure(&gfx.ctx.device, &gfx.config);
                    gfx.renderer
                        .resize(&gfx.ctx, gfx.config.width, gfx.config.height)
                        .map_err(AppError::from)
                } else {
                    Ok(())
                }
            }
            WindowEvent::RedrawRequested => self.redraw(event_loop),
            WindowEvent::ModifiersChanged(m) => {
                self.modifiers = m.state();
                Ok(())
            }
            WindowEvent::KeyboardInput { event, .. }
                if !consumed && event.state == ElementState::Pressed =>
            {
                self.key(event_loop, &event.logical_key)
            }
            WindowEvent::MouseInput { state, button, .. }
                if !consumed || state == ElementState::Released =>
            {
                self.dragging = (state == ElementState::Pressed).then_some(button);
                if state == ElementState::Released {
                    *self.push.write().unwrap_or_else(|e| e.into_inner()) = None;
                }
                Ok(())
            }
            WindowEvent::CursorMoved { position, .. } => {
                self.mouse_moved(Vec2::new(position.x as f32, position.y as f32));
                Ok(())
            }
            WindowEvent::MouseWheel { delta, .. } if !consumed => {
                let lines = match delta {
                    MouseScrollDelta::LineDelta(_, y) => y,
                    MouseScrollDelta::PixelDelta(p) => p.y as f32 / 40.0,
                };
                self.orbit.zoom(lines);
                Ok(())
            }
            _ => Ok(()),
        };
        if let Err(e) = result {
            self.fail(event_loop, e);
        }
    }

    fn about_to_wait(&mut self, _event_loop: &ActiveEventLoop) {
        if let Some(gfx) = &self.gfx {
            gfx.window.request_redraw();
        }
    }
}

/// A window size as the surface can take it: at least 1 and at most the
/// device's largest texture on each side (a larger surface would be a fatal
/// configuration error; the compositor scales the image up).
fn surface_size(ctx: &GpuContext, size: winit::dpi::PhysicalSize<u32>) -> (u32, u32) {
    let max = ctx.device.limits().max_texture_dimension_2d;
    (size.width.clamp(1, max), size.height.clamp(1, max))
}
