//! Scenes: a domain, fluid blocks, obstacles, emitters, physical and time-stepping
//! parameters and rendering hints, as TOML files (`assets/scenes/*.toml`) or built
//! in ([`Scene::dam_break`], [`Scene::drop_into_pool`], [`Scene::double_dam_break`]).
//!
//! Loading rejects syntax errors, unknown and missing fields, and non-finite or
//! out-of-range values with a message naming the field and the reason.
//!
//! [`Scene`] and what it builds (particles, boundary, world) live here; the
//! file's tables in `spec`, the checks in `validate`, the built-in scenes
//! in `built_in`.

mod built_in;
mod spec;
mod validate;

pub use built_in::{BUILT_IN, BuiltIn};
pub use spec::{
    BlockSpec, BoxSpec, EmitterSpec, FluidSpec, ObstacleSpec, RenderSpec, SolverSpec, TimeStepSpec,
    WcsphSpec,
};
pub use validate::MAX_FRAME_DT;

use glam::Vec3;
use serde::{Deserialize, Serialize};

use self::spec::WCSPH_FIELDS;
use self::validate::{check_f32_range, invalid};
use crate::boundary::{Aabb, Boundary, Obstacle};
use crate::error::{Error, Result};
use crate::particles::Particles;
use crate::solver::{
    DfsphParams, Emitter, FluidParams, PbfParams, PbfViscosity, Solver, SolverKind, TimeStepping,
    World,
};

/// A complete scene description.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    /// Human-readable name.
    pub name: String,
    /// The box the fluid stays in.
    pub domain: BoxSpec,
    /// Physical parameters.
    pub fluid: FluidSpec,
    /// Particle spacing of blocks and emitters (m); must be below `fluid.h`.
    pub spacing: f32,
    /// Blocks of fluid at rest, filled on a lattice of `spacing`.
    #[serde(default)]
    pub blocks: Vec<BlockSpec>,
    /// Static obstacles.
    #[serde(default)]
    pub obstacles: Vec<ObstacleSpec>,
    /// How far particle centres stay from the domain walls and the
    /// obstacles (m, [`Boundary::clearance`]); left out, half the
    /// `spacing` ([`Scene::wall_clearance`]). Half the spacing holds the
    /// first layer of particles where a lattice puts it, and the solvers'
    /// walls then continue that lattice behind them: a settled 0.2 m pool
    /// keeps its first layer at 10 mm and loses 1.7 % (DFSPH) to 3 % (PBF)
    /// of its depth, where 0 lets the first layer sink to 1–4 mm and the
    /// pool lose 3–4 % (`cargo run --release -p sph-core --example
    /// pool_at_rest`). 0 lets particles reach the walls, as the thesis's.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub clearance: Option<f32>,
    /// Particle emitters.
    #[serde(default)]
    pub emitters: Vec<EmitterSpec>,
    /// Time stepping.
    pub time_step: TimeStepSpec,
    /// The solver and its parameters (PBF, derived for the scene, when
    /// left out).
    #[serde(default)]
    pub solver: SolverSpec,
    /// Upper bound on the particle count (blocks and emitters together).
    #[serde(default = "default_max_particles")]
    pub max_particles: usize,
    /// Rendering hints. A scene file without a `[render]` table frames its
    /// domain ([`RenderSpec::framing`] at 45°), wherever the domain lies.
    #[serde(default)]
    pub render: RenderSpec,
}

fn default_max_particles() -> usize {
    2_000_000
}

/// Lattice points per axis of a block: its extent over the spacing, rounded
/// down, except that a quotient within 10⁻³ below a whole number counts as
/// that number. In f32, `0.1 / 0.02` is 4.9999981, and the floor alone
/// would drop a whole layer of an extent that the scene file wrote as a
/// whole number of spacings. (The extra layer's centres stay half a spacing
/// inside the block's faces, less the 10⁻³ spacing.)
fn lattice_count(min: Vec3, max: Vec3, spacing: f32) -> [usize; 3] {
    let n = ((max - min) / spacing + 1e-3).floor();
    [n.x as usize, n.y as usize, n.z as usize]
}

impl Scene {
    /// Parses and validates a scene from TOML text.
    pub fn from_toml(text: &str) -> Result<Self> {
        let mut scene: Scene = toml::from_str(text).map_err(|e| {
            let mut message = e.to_string();
            // Only where the fields were: [fluid] lists `rest_density`
            // among the fields it expects, [time_step] only `frame_dt`.
            let old_table =
                message.contains("`rest_density`") || message.contains("expected `frame_dt`");
            let moved = (WCSPH_FIELDS.iter())
                .find(|f| old_table && message.contains(&format!("unknown field `{f}`")));
            if let Some(field) = moved {
                message.push_str(&format!(
                    "`{field}` is the thesis's WCSPH's parameter: it lives in [solver.wcsph]\n"
                ));
            }
            Error::SceneSyntax(message)
        })?;
        // No [render]: a camera on the domain, not a fixed one that a
        // domain elsewhere would leave out of the picture.
        let table: toml::Table =
            toml::from_str(text).map_err(|e| Error::SceneSyntax(e.to_string()))?;
        for (key, value) in &table {
            check_f32_range(key.clone(), value)?;
        }
        if !table.contains_key("render") {
            let d = &scene.domain;
            scene.render = RenderSpec::framing(d.min.into(), d.max.into(), 45.0);
        }
        scene.validate()?;
        // A surface tension model in a file without σ is read by no solver.
        // (Only files: the demo's panel may take σ to 0 and back with the
        // model kept, through `validate`.)
        if let Some(model) = scene.fluid.surface_tension_model
            && scene.fluid.surface_tension == 0.0
        {
            return Err(invalid(
                "fluid.surface_tension_model",
                format!(
                    "\"{}\" is read only where surface_tension > 0, and it is 0: leave the \
                     model out, or give σ (N/m)",
                    match model {
                        crate::solver::SurfaceTensionModel::ColourField => "colour-field",
                        crate::solver::SurfaceTensionModel::Akinci => "akinci",
                    }
                ),
            ));
        }
        Ok(scene)
    }

    /// Reads, parses and validates a scene file.
    pub fn load(path: impl AsRef<std::path::Path>) -> Result<Self> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|e| Error::Io {
            path: path.display().to_string(),
            reason: e.to_string(),
        })?;
        Self::from_toml(&text)
    }

    /// The scene as TOML text.
    pub fn to_toml(&self) -> String {
        toml::to_string_pretty(self).unwrap_or_default()
    }

    /// The fluid parameters: `[fluid]`'s, with WCSPH's own from
    /// `[solver.wcsph]` (which the other solvers do not read).
    pub fn fluid_params(&self) -> FluidParams {
        let (f, w) = (&self.fluid, self.wcsph_params());
        FluidParams {
            h: f.h,
            rest_density: f.rest_density,
            stiffness: w.stiffness,
            viscosity: f.viscosity(),
            surface_tension: f.surface_tension,
            surface_tension_model: f.surface_tension_model,
            surface_threshold: w.surface_threshold.unwrap_or(0.1 / f.h),
            gravity: Vec3::from(f.gravity),
            negative_pressure_scale: w.negative_pressure_scale,
            pressure_kernel: w.pressure_kernel,
        }
    }

    /// WCSPH's adaptive step, from `[solver.wcsph]`.
    pub fn time_stepping(&self) -> TimeStepping {
        let w = self.wcsph_params();
        TimeStepping {
            max_dt: w.max_dt,
            cfl: w.cfl,
            force_factor: w.force_factor,
            ..TimeStepping::default()
        }
    }

    /// The clearance the boundary keeps (m): [`Scene::clearance`], or half
    /// the spacing where the scene leaves it out.
    pub fn wall_clearance(&self) -> f32 {
        self.clearance.unwrap_or(0.5 * self.spacing)
    }

    /// The boundary: domain and obstacles, inelastic walls, particle centres
    /// kept [`Scene::wall_clearance`] from them.
    pub fn boundary(&self) -> Boundary {
        let mut b = Boundary::new(Aabb::new(self.domain.min.into(), self.domain.max.into()))
            .with_clearance(self.wall_clearance());
        b.obstacles = self
            .obstacles
            .iter()
            .map(|o| match *o {
                ObstacleSpec::Box { min, max } => Obstacle::Box(Aabb::new(min.into(), max.into())),
                ObstacleSpec::Sphere { centre, radius } => Obstacle::Sphere {
                    centre: centre.into(),
                    radius,
                },
            })
            .collect();
        b
    }

    /// The particles of the blocks, on a lattice of `spacing` (cell-centred),
    /// skipping lattice points inside obstacles.
    ///
    /// # Errors
    /// A scene that does not validate, or a block whose every lattice point
    /// lies inside an obstacle (named `blocks[i]`).
    pub fn particles(&self) -> Result<Particles> {
        self.validate()?;
        let mass = (self.solver()).particle_mass(&self.fluid_params(), self.spacing)?;
        let boundary = self.boundary();
        let mut p = Particles::new();
        for (index, b) in self.blocks.iter().enumerate() {
            let before = p.len();
            let min = Vec3::from(b.min);
            let n = lattice_count(min, b.max.into(), self.spacing);
            for k in 0..n[2] {
                for j in 0..n[1] {
                    for i in 0..n[0] {
                        let x =
                            min + (Vec3::new(i as f32, j as f32, k as f32) + 0.5) * self.spacing;
                        if boundary.admits(x) {
                            p.push(x, b.velocity.into(), mass);
                        }
                    }
                }
            }
            if p.len() == before {
                // A block the obstacles swallow whole would vanish unseen.
                return Err(invalid(
                    format!("blocks[{index}]"),
                    "every particle of the block lies inside an obstacle (or within the \
                     clearance of one): the block holds no fluid",
                ));
            }
        }
        Ok(p)
    }

    /// A ready-to-run world: particles, the scene's solver's program,
    /// emitters inserted at its start (so new particles are in the step's
    /// grid).
    pub fn build_world(&self) -> Result<World> {
        self.world_with(self.particles()?)
    }

    /// A world of this scene's parameters, boundary, time stepping and emitters
    /// around the given `particles` (e.g. to change parameters mid-run).
    pub fn world_with(&self, particles: Particles) -> Result<World> {
        self.validate()?;
        let stepping = self.time_stepping();
        let mass = (self.solver()).particle_mass(&self.fluid_params(), self.spacing)?;
        let mut world = World::with_solver(
            particles,
            self.fluid_params(),
            self.boundary(),
            stepping,
            self.solver(),
        )?;
        for e in &self.emitters {
            let emitter = Emitter::new(
                world.boundary().clone(),
                e.centre.into(),
                e.velocity.into(),
                e.width,
                self.spacing,
                mass,
                self.max_particles,
            )?;
            // First of all, so new particles are in the step's grid (and,
            // for PBF, are predicted with the others).
            world.program_mut().push_front(emitter);
        }
        Ok(world)
    }

    /// A world of this scene's parameters that continues `old`'s run, built
    /// from the scene `was` (after a parameter changed mid-run, as the
    /// demo's panel does): `old`'s particles, its clock and thread setting,
    /// and, where this scene's emitters are `was`'s (the same emitters,
    /// spacing, particle mass and `max_particles`), `old`'s running
    /// emitters, each at its place in its stream (a fresh one would emit a
    /// layer at once, within a spacing of the last); otherwise this scene's
    /// emitters start afresh, as in [`Scene::world_with`]. Processors
    /// of `old`'s own beyond those are not carried over. `old` is left as
    /// it was unless the new world is built, so a parameter the scene
    /// refuses costs nothing.
    ///
    /// # Errors
    /// As [`Scene::world_with`]: a scene that does not validate.
    pub fn world_continuing(&self, old: &mut World, was: &Scene) -> Result<World> {
        let mut world = self.world_with(old.particles.clone())?;
        let mass = |s: &Scene| s.solver().particle_mass(&s.fluid_params(), s.spacing).ok();
        let same_emitters = self.emitters == was.emitters
            && self.spacing == was.spacing
            && self.max_particles == was.max_particles
            && mass(self) == mass(was);
        let running = (old.program_mut().names())
            .filter(|&n| n == "emitter")
            .count();
        if same_emitters && running == self.emitters.len() && running > 0 {
            let running = old.program_mut().take("emitter");
            let program = world.program_mut();
            program.take("emitter");
            for emitter in running.into_iter().rev() {
                program.push_front(emitter);
            }
        }
        world.continue_from(old);
        Ok(world)
    }

    /// A scene with no fluid of its own in the box `min`–`max`, for
    /// particles that come from elsewhere (other simulators' files, arrays)
    /// through [`World::with_solver`]: the built-in scenes' fluid (h = 2 ×
    /// `spacing`), run by PBF, the camera framing the box. It does not
    /// validate as a scene file ([`Scene::validate`] asks for fluid).
    pub fn empty(name: &str, min: Vec3, max: Vec3, spacing: f32) -> Self {
        let mut scene = Self::base(name, max - min, spacing).with_solver(SolverKind::Pbf);
        scene.domain = BoxSpec {
            min: min.to_array(),
            max: max.to_array(),
        };
        scene.render = RenderSpec::framing(min, max, 45.0);
        scene
    }

    /// The chosen solver with its parameters.
    pub fn solver(&self) -> Solver {
        match self.solver.kind {
            SolverKind::Wcsph => Solver::Wcsph,
            SolverKind::Pbf => Solver::Pbf(self.pbf_params()),
            SolverKind::Dfsph => Solver::Dfsph(self.dfsph_params()),
        }
    }

    /// DFSPH's parameters: the `[solver.dfsph]` table's, or the defaults.
    pub fn dfsph_params(&self) -> DfsphParams {
        self.solver.dfsph.unwrap_or_default()
    }

    /// WCSPH's parameters: the `[solver.wcsph]` table's, or the defaults.
    pub fn wcsph_params(&self) -> WcsphSpec {
        self.solver.wcsph.unwrap_or_default()
    }

    /// PBF's parameters: the `[solver.pbf]` table's, or without one
    /// [`PbfParams::for_fall`] from the highest block top or emitter
    /// above the floor, at the scene's frame rate (what the built-in scenes
    /// run: 3 substeps per 60 Hz frame at h = 0.04 m, 5 for
    /// `dam-break-fine`'s 0.02 m).
    pub fn pbf_params(&self) -> PbfParams {
        self.solver.pbf.unwrap_or_else(|| {
            let tops = self.blocks.iter().map(|b| b.max[1]);
            let emitters = self.emitters.iter().map(|e| e.centre[1]);
            let top = tops.chain(emitters).fold(self.domain.min[1], f32::max);
            PbfParams::for_fall(
                top - self.domain.min[1],
                self.fluid.gravity[1],
                self.fluid.h,
                self.time_step.frame_dt,
            )
        })
    }

    /// This scene run by `kind` (its parameters from `[solver.pbf]` etc.).
    pub fn with_solver(mut self, kind: SolverKind) -> Self {
        self.solver.kind = kind;
        self
    }

    /// Runs this scene with `kind` from now on, as the demo's `--solver`,
    /// its window's switch and Python's `solver=` do, giving way where the
    /// scene has what `kind` would refuse: the thesis's colour-field force
    /// gives way to Akinci et al.'s under PBF and DFSPH, and PBF's XSPH
    /// blend to its implicit viscosity where the scene gives a μ. Returns
    /// a note for each, to tell the user.
    pub fn switch_solver(&mut self, kind: SolverKind) -> Vec<String> {
        use crate::solver::SurfaceTensionModel;
        self.solver.kind = kind;
        let mut notes = Vec::new();
        let fluid = &mut self.fluid;
        if kind != SolverKind::Wcsph
            && fluid.surface_tension_model == Some(SurfaceTensionModel::ColourField)
        {
            notes.push(format!(
                "surface_tension_model \"colour-field\" is WCSPH's: {kind} applies σ by Akinci et al.'s forces"
            ));
            fluid.surface_tension_model = None;
        }
        if kind == SolverKind::Pbf
            && let Some(mu) = fluid.viscosity
            && self.pbf_params().viscosity == PbfViscosity::Xsph
        {
            let blend = self.pbf_params().xsph;
            let dropped = if blend == PbfParams::default().xsph {
                String::new()
            } else {
                format!(" in place of its XSPH blend of {blend}")
            };
            notes.push(format!(
                "PBF's XSPH viscosity has no μ: PBF solves the scene's μ = {mu} Pa·s implicitly{dropped}"
            ));
            self.solve_viscosity_implicitly();
        }
        notes
    }

    /// This scene's fluid with viscosity `mu` (Pa·s), applied by every
    /// solver: PBF solves it implicitly ([`PbfViscosity::Implicit`]) in
    /// place of its XSPH blend, which has no μ. Call it once the blocks are
    /// in: PBF's derived substeps depend on their height.
    pub fn with_viscosity(mut self, mu: f32) -> Self {
        self.fluid.viscosity = Some(mu);
        self.solve_viscosity_implicitly();
        self
    }

    /// PBF's parameters as now, with the implicit viscosity of μ in place
    /// of the XSPH blend (back at its default, which the implicit
    /// viscosity does not read).
    fn solve_viscosity_implicitly(&mut self) {
        self.solver.pbf = Some(PbfParams {
            viscosity: PbfViscosity::Implicit,
            xsph: PbfParams::default().xsph,
            ..self.pbf_params()
        });
    }
}
