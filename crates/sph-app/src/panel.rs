//! The demo's egui panel: what it shows of the run (fps, the stage
//! times, the solver's report, the real-time factor) and what it edits
//! (the scene and solver, the GPU paths, the view, the fluid's parameters,
//! the extraction and the shading). Drawing it changes nothing by itself:
//! [`draw`] returns the user's choices, and the window applies them.

use glam::Vec3;
use sph_core::{PbfViscosity, Scene, SolverKind};
use splat_render::Shading;
use surfel_extract::{ExtractParams, Split, Surface};

use crate::error::AppError;
use crate::pipeline::{FrameStats, LateStats};
use crate::scenes;

/// Live settings edited in the panel.
pub(crate) struct Settings {
    pub(crate) shading: Shading,
    /// Debug view index: the renderer's views, then "particles".
    pub(crate) view: usize,
    pub(crate) paused: bool,
    pub(crate) step_once: bool,
    /// The SPH step on the GPU (`--gpu-sim`, the panel).
    pub(crate) gpu_sim: Toggle,
    /// Surfel extraction on the GPU (`--gpu-extract`, the panel).
    pub(crate) gpu_extract: Toggle,
    /// Only front-facing surfels (`--cull`, the panel).
    pub(crate) cull: bool,
    /// Splats drawn by compute shaders (`--splats`, the panel); `None`
    /// until the first frame takes the renderer's choice for its adapter
    /// (`--splats auto`).
    pub(crate) compute_splats: Option<bool>,
    /// The tank, obstacles and ground around the fluid (`--no-scenery`
    /// turns them off, the panel toggles them).
    pub(crate) scenery: bool,
    /// Why the fluid's last edit was refused, shown under its sliders.
    pub(crate) fluid_note: Option<String>,
}

/// A GPU path the panel switches on and off.
pub(crate) struct Toggle {
    /// Whether it should run.
    pub(crate) on: bool,
    /// Why it could not be switched on, shown in the panel.
    pub(crate) note: Option<String>,
}

impl Toggle {
    pub(crate) fn new(on: bool) -> Self {
        Self { on, note: None }
    }

    /// Records the outcome of switching: an error unticks the box and says why.
    pub(crate) fn settle(&mut self, result: Result<(), AppError>) {
        match result {
            Ok(()) => self.note = None,
            Err(e) => {
                log::warn!("{e}");
                self.on = false;
                self.note = Some(e.to_string());
            }
        }
    }

    /// The checkbox and the note under it.
    pub(crate) fn show(&mut self, ui: &mut egui::Ui, label: &str, hover: &str) {
        ui.checkbox(&mut self.on, label).on_hover_text(hover);
        if let Some(note) = &self.note {
            ui.small(note.as_str());
        }
    }
}

pub(crate) const VIEW_NAMES: [&str; 5] = ["shaded", "normals", "weights", "depth", "particles"];

/// What the panel shows of the run.
pub(crate) struct Shown<'a> {
    /// The scene's name.
    pub(crate) name: &'a str,
    /// The last frame's statistics.
    pub(crate) stats: FrameStats,
    /// The newest statistics that came back late from the GPU.
    pub(crate) latest_late: Option<LateStats>,
    /// Simulated seconds per wall second.
    pub(crate) realtime: f64,
    /// Frames drawn per second, and the last one's render time (ms).
    pub(crate) fps: f64,
    pub(crate) render_ms: f64,
    /// The particle files played back, if any.
    pub(crate) playing: Option<usize>,
}

/// What the user chose in the panel this frame.
#[derive(Debug, Default)]
pub(crate) struct Choices {
    /// A fluid slider moved: rebuild the world around its particles.
    pub(crate) fluid_changed: bool,
    /// A built-in scene to switch to.
    pub(crate) scene: Option<usize>,
    /// A solver to switch to (the scene restarts).
    pub(crate) solver: Option<SolverKind>,
}

impl Choices {
    /// Adds what another pass over the panel chose (egui may run a frame's
    /// ui twice, and only the first pass sees the input): a fluid edit in
    /// either, the first scene or solver chosen.
    pub(crate) fn absorb(&mut self, other: Choices) {
        self.fluid_changed |= other.fluid_changed;
        self.scene = self.scene.or(other.scene);
        self.solver = self.solver.or(other.solver);
    }
}

/// Draws the panel: `settings`, `scene`'s fluid and `extract` are edited in
/// place; the rest of what the user chose comes back.
pub(crate) fn draw(
    ctx: &egui::Context,
    shown: &Shown,
    settings: &mut Settings,
    scene: &mut Scene,
    extract: &mut ExtractParams,
) -> Choices {
    let mut choices = Choices::default();
    let Shown {
        name,
        stats,
        latest_late,
        realtime,
        fps,
        render_ms,
        playing,
    } = *shown;
    let mut solver = scene.solver.kind;
    egui::Window::new("sph-splat").default_pos([10.0, 10.0]).show(ctx, |ui| {
        ui.label(format!("scene: {name}"));
        ui.horizontal(|ui| {
            for (i, (n, _, _)) in scenes::BUILT_IN.iter().enumerate() {
                if ui.small_button(format!("{}", i + 1)).on_hover_text(*n).clicked() {
                    choices.scene = Some(i);
                }
            }
        });
        ui.separator();
        ui.label(format!("{fps:.1} fps, t = {:.2} s, frame {}", stats.time, stats.frame));
        ui.label(format!(
            "simulate {:.1} ms ({} substeps), extract {:.1} ms, render {render_ms:.1} ms",
            stats.step_ms, stats.substeps, stats.extract_ms
        ));
        if realtime < 0.99 {
            ui.colored_label(egui::Color32::from_rgb(230, 150, 60), format!(
                "behind real time: {realtime:.2} simulated s per wall s"
            ));
        } else {
            ui.label("real time: simulated time keeps up with the clock");
        }
        if let Some(files) = playing {
            ui.label(format!("playing {files} particle files (R restarts)"));
        } else {
            ui.horizontal(|ui| {
                egui::ComboBox::from_label("solver (resets)")
                    .selected_text(solver.name())
                    .show_ui(ui, |ui| {
                        for kind in SolverKind::ALL {
                            if ui.selectable_value(&mut solver, kind, kind.name()).changed() {
                                choices.solver = Some(kind);
                            }
                        }
                    });
            });
            // A GPU frame's own statistics come back a frame or two
            // later: the newest that came back, and which frame.
            let (errors, clamped, of) = match (stats.pending, latest_late) {
                (true, Some(l)) => (
                    (l.density_error_avg, l.density_error_max),
                    l.clamped,
                    format!(" (frame {}, from the GPU)", l.frame),
                ),
                _ => (
                    (stats.density_error_avg, stats.density_error_max),
                    stats.clamped,
                    String::new(),
                ),
            };
            ui.label(match stats.solver {
                SolverKind::Pbf => format!(
                    "{} iterations per frame, {clamped} clamped{of}",
                    stats.iterations
                ),
                SolverKind::Wcsph => "adaptive step, no iterations".into(),
                SolverKind::Dfsph => format!(
                    "{} steps, {} density + {} divergence + {} viscosity iterations per frame, {} unconverged",
                    stats.substeps,
                    stats.iterations,
                    stats.divergence_iterations,
                    stats.viscosity_iterations,
                    stats.unconverged
                ),
            });
            ui.label(format!(
                "density error {:.2} % avg, {:.1} % max{of}",
                100.0 * errors.0,
                100.0 * errors.1
            ));
        }
        ui.label(format!(
            "{} particles, {} surfels, {} evaluations",
            stats.particles, stats.surfels, stats.evaluations
        ));
        ui.separator();
        ui.checkbox(&mut settings.paused, "paused (space; N steps)");
        settings.gpu_sim.show(ui, "SPH step on the GPU", "wgpu compute (sph-gpu): PBF or WCSPH; ctrl+drag pushes on either path");
        settings.gpu_extract.show(ui, "surfels extracted on the GPU", "wgpu compute (sph-gpu): the same field, hole closing and splits; drawn without a round trip to the CPU");
        if let Some(compute) = &mut settings.compute_splats {
            ui.checkbox(compute, "splats drawn in compute (--splats)")
                .on_hover_text("compute shaders over 8×8-pixel tiles instead of the raster hardware: the same image; the default on a GPU");
        }
        ui.checkbox(&mut settings.cull, "only front-facing surfels (--cull)")
            .on_hover_text("thesis 4.2.1: about half the surfels; re-extracts as the camera turns");
        egui::ComboBox::from_label("view (F)")
            .selected_text(VIEW_NAMES[settings.view])
            .show_ui(ui, |ui| {
                for (i, v) in VIEW_NAMES.iter().enumerate() {
                    ui.selectable_value(&mut settings.view, i, *v);
                }
            });
        ui.collapsing("fluid", |ui| {
            choices.fluid_changed |= fluid_sliders(ui, scene);
            if let Some(note) = &settings.fluid_note {
                ui.colored_label(egui::Color32::from_rgb(230, 150, 60), note.as_str());
            }
        });
        ui.collapsing("extraction", |ui| {
            let mut smooth = extract.surface != Surface::Isotropic;
            if ui
                .checkbox(&mut smooth, "anisotropic kernels (--surface)")
                .on_hover_text("Yu & Turk 2013: smooth water; off: the thesis's isotropic colour field. The GPU extractor uses either.")
                .changed()
            {
                extract.surface = if smooth { Surface::anisotropic() } else { Surface::Isotropic };
            }
            ui.add(slider(&mut extract.iterations, 1..=3).text("iterations"));
            ui.add(slider(&mut extract.iso, 0.2..=0.8).text("iso value"));
            ui.add(slider(&mut extract.radius, 0.2..=1.0).text("initial radius (h)"));
            ui.add(slider(&mut extract.interior_step, 0.3..=1.5).text("interior step (h)"));
            ui.add(slider(&mut extract.discard_step, 0.05..=0.5).text("discard step (h)"));
            let mut nine = extract.first_split == Split::ThreeByThree;
            if ui.checkbox(&mut nine, "3×3 first split (the thesis: 2×2)").changed() {
                extract.first_split = if nine { Split::ThreeByThree } else { Split::TwoByTwo };
            }
        });
        ui.collapsing("shading", |ui| {
            ui.checkbox(&mut settings.scenery, "tank, obstacles and ground (--no-scenery)");
            let mut sigma = settings.shading.absorption.to_array();
            for (value, channel) in sigma.iter_mut().zip(["red", "green", "blue"]) {
                ui.add(slider(value, 0.0..=20.0).text(format!("absorption {channel} (1/m)")));
            }
            settings.shading.absorption = Vec3::from(sigma);
            ui.add(slider(&mut settings.shading.reflectivity, 0.0..=2.0).text("reflectivity (Fresnel ×)"));
            ui.add(slider(&mut settings.shading.refraction, 0.0..=0.2).text("refraction μ"));
            ui.add(slider(&mut settings.shading.depth_epsilon, 0.0..=0.1).text("depth ε (m)"));
            let mut c = settings.shading.fluid_colour.to_array();
            if ui.color_edit_button_rgb(&mut c).changed() {
                settings.shading.fluid_colour = Vec3::from(c);
            }
        });
        ui.small("drag rotate · scroll zoom · right-drag pan · ctrl+drag push · R reset · S screenshot");
    });
    choices
}

/// A slider over `range` that clamps what the user enters to it but leaves a
/// value already outside it alone. egui's default clamps every value a
/// slider draws, so opening the panel on honey (μ = 50 Pa·s, the slider
/// reaching 5) would set μ to 5 and rebuild the world, unasked. The
/// extraction's and shading's sliders use it: their ranges are what their
/// validation accepts.
fn slider<N: egui::emath::Numeric>(
    value: &mut N,
    range: std::ops::RangeInclusive<N>,
) -> egui::Slider<'_> {
    egui::Slider::new(value, range).clamping(egui::SliderClamping::Edits)
}

/// A fluid slider over `range` that clamps nothing: its handle stays in the
/// range, but a value typed or dragged on its number beyond it is taken as
/// is (μ = 50 Pa·s, honey's, where [`slider`] would make it 5 without a
/// word). The scene's validation refuses what it must, and
/// `App::apply_fluid_params` then keeps the running world and says why.
fn fluid_slider<N: egui::emath::Numeric>(
    value: &mut N,
    range: std::ops::RangeInclusive<N>,
) -> egui::Slider<'_> {
    egui::Slider::new(value, range).clamping(egui::SliderClamping::Never)
}

/// The panel's sliders for what the scene's solver applies: WCSPH's
/// stiffness, the μ of the solvers that have one (PBF's XSPH blend in its
/// place), σ and gravity. Returns whether any moved.
fn fluid_sliders(ui: &mut egui::Ui, scene: &mut sph_core::Scene) -> bool {
    let mut changed = false;
    let kind = scene.solver.kind;
    if kind == SolverKind::Wcsph {
        let mut wcsph = scene.wcsph_params();
        let k = fluid_slider(&mut wcsph.stiffness, 100.0..=20_000.0).logarithmic(true);
        if ui.add(k.text("k (m²/s²)")).changed() {
            scene.solver.wcsph = Some(wcsph);
            changed = true;
        }
    }
    if kind == SolverKind::Pbf && scene.pbf_params().viscosity == PbfViscosity::Xsph {
        let mut pbf = scene.pbf_params();
        if ui
            .add(fluid_slider(&mut pbf.xsph, 0.0..=1.0).text("XSPH blend (no unit)"))
            .changed()
        {
            scene.solver.pbf = Some(pbf);
            changed = true;
        }
    } else {
        let mut mu = scene.fluid.viscosity();
        if ui
            .add(fluid_slider(&mut mu, 0.0..=5.0).text("μ (Pa·s)"))
            .changed()
        {
            scene.fluid.viscosity = Some(mu);
            changed = true;
        }
    }
    let fluid = &mut scene.fluid;
    changed |= ui
        .add(fluid_slider(&mut fluid.surface_tension, 0.0..=2.0).text("σ (N/m)"))
        .changed();
    changed |= ui
        .add(fluid_slider(&mut fluid.gravity[1], -30.0..=0.0).text("gravity y (m/s²)"))
        .changed();
    changed
}

#[cfg(test)]
mod tests {
    /// Drawing the fluid's sliders changes nothing, even where a scene's
    /// value lies outside a slider's range (honey's μ, a strong gravity, a
    /// large σ or stiffness), under every solver.
    #[test]
    fn sliders_leave_values_outside_their_range_alone() {
        use sph_core::{Scene, SolverKind};
        let honey = Scene::built_in("honey").unwrap();
        assert!(honey.fluid.viscosity() > 5.0, "{}", honey.fluid.viscosity());
        let mut strong = Scene::built_in("dam-break").unwrap();
        strong.fluid.gravity[1] = -40.0;
        strong.fluid.surface_tension = 3.0;
        let mut scenes = vec![honey.with_solver(SolverKind::Pbf), strong.clone()];
        for kind in [SolverKind::Dfsph, SolverKind::Wcsph] {
            scenes.push(Scene::built_in("honey").unwrap().with_solver(kind));
            scenes.push(strong.clone().with_solver(kind));
        }
        let mut wcsph = scenes[5].wcsph_params();
        wcsph.stiffness = 50_000.0;
        scenes[5].solver.wcsph = Some(wcsph);
        let ctx = egui::Context::default();
        for mut scene in scenes {
            let before = scene.clone();
            let mut changed = true;
            let _ = ctx.run_ui(egui::RawInput::default(), |ui| {
                changed = super::fluid_sliders(ui, &mut scene);
            });
            assert!(!changed, "{}", before.name);
            assert_eq!(scene, before);
        }
    }

    /// Drawing the whole panel with nothing pressed chooses nothing and
    /// leaves every value it edits as it was, on every built-in scene (the
    /// window rebuilds the world, switches scene or solver, or
    /// re-extracts on what it returns).
    #[test]
    fn drawing_the_panel_chooses_nothing() {
        use sph_core::Scene;
        let ctx = egui::Context::default();
        for (key, _, make) in crate::scenes::BUILT_IN {
            let mut scene: Scene = make();
            let before = scene.clone();
            let mut extract = surfel_extract::ExtractParams::new(scene.fluid.h);
            let extract_before = extract;
            let mut settings = super::Settings {
                shading: splat_render::Shading::default(),
                view: 0,
                paused: false,
                step_once: false,
                gpu_sim: super::Toggle::new(false),
                gpu_extract: super::Toggle::new(false),
                cull: false,
                compute_splats: Some(true),
                scenery: true,
                fluid_note: Some("a note".into()),
            };
            let shown = super::Shown {
                name: key,
                stats: crate::pipeline::FrameStats::default(),
                latest_late: None,
                realtime: 1.0,
                fps: 60.0,
                render_ms: 1.0,
                playing: None,
            };
            let mut choices = super::Choices::default();
            let _ = ctx.run_ui(egui::RawInput::default(), |ui| {
                choices = super::draw(ui.ctx(), &shown, &mut settings, &mut scene, &mut extract);
            });
            assert!(
                !choices.fluid_changed && choices.scene.is_none() && choices.solver.is_none(),
                "{key}: {choices:?}"
            );
            assert_eq!(scene, before, "{key}");
            assert_eq!(extract, extract_before, "{key}");
            assert_eq!(settings.shading, splat_render::Shading::default(), "{key}");
        }
    }

    /// A second pass over the panel, which sees no input, keeps what the
    /// first chose.
    #[test]
    fn a_second_pass_keeps_the_first_ones_choices() {
        let mut first = super::Choices {
            fluid_changed: true,
            scene: Some(2),
            solver: None,
        };
        first.absorb(super::Choices::default());
        assert!(first.fluid_changed && first.scene == Some(2) && first.solver.is_none());
        let mut none = super::Choices::default();
        none.absorb(super::Choices {
            fluid_changed: false,
            scene: None,
            solver: Some(sph_core::SolverKind::Dfsph),
        });
        assert_eq!(none.solver, Some(sph_core::SolverKind::Dfsph));
    }

    /// The panel's labels can be drawn: egui 0.37 bundles no font unless its
    /// `default_fonts` feature is on, and without one every label was blank
    /// ("No font provider has any font"). The characters are the panel's own,
    /// Greek letters and symbols included.
    #[test]
    fn panel_fonts_have_the_labels_glyphs() {
        let ctx = egui::Context::default();
        // The font atlas it builds is not uploaded anywhere: dropped on
        // purpose (epaint's debug builds check that deltas are handled).
        ctx.run_pass(egui::RawInput::default(), |_| {})
            .textures_delta
            .clear();
        let text = "simulate 12.3 ms, k (m²/s²) μ (Pa·s) σ (N/m) ε Σw 3×3 –";
        for font in [egui::FontId::default(), egui::FontId::monospace(12.0)] {
            let ok = ctx.fonts_mut(|f| f.has_glyphs(&font, text));
            assert!(ok, "{font:?} lacks glyphs of {text:?}");
        }
    }
}
