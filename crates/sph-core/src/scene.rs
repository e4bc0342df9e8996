//! Scenes: a domain, fluid blocks, obstacles, emitters, physical and time-stepping
//! parameters and rendering hints, as TOML files (`assets/scenes/*.toml`) or built
//! in ([`Scene::dam_break`], [`Scene::drop_into_pool`], [`Scene::double_dam_break`]).
//!
//! Loading rejects syntax errors, unknown and missing fields, and non-finite or
//! out-of-range values with a message naming the field and the reason.

use glam::Vec3;
use serde::{Deserialize, Serialize};

use crate::boundary::{Aabb, Boundary, Obstacle};
use crate::error::{Error, Result, check_kernel_h};
use crate::grid::MAX_PARTICLES;
use crate::particles::Particles;
use crate::solver::{
    DfsphParams, Emitter, FluidParams, MAX_H_OVER_SPACING, PbfParams, PbfViscosity, Solver,
    SolverKind, TimeStepping, World, nozzle_corners, nozzle_points,
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

/// An axis-aligned box by its corners.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BoxSpec {
    /// Minimum corner (m).
    pub min: [f32; 3],
    /// Maximum corner (m).
    pub max: [f32; 3],
}

/// A block of fluid.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BlockSpec {
    /// Minimum corner (m).
    pub min: [f32; 3],
    /// Maximum corner (m).
    pub max: [f32; 3],
    /// Initial velocity (m/s).
    #[serde(default)]
    pub velocity: [f32; 3],
}

/// The fluid's physical parameters, see [`FluidParams`]. What only the
/// thesis's WCSPH reads (its stiffness, pressure clamp and kernel, the
/// colour field's threshold and its time step) lives in `[solver.wcsph]`
/// ([`WcsphSpec`]), so a scene gives no solver a parameter it does not
/// apply.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FluidSpec {
    /// Smoothing length h (m).
    pub h: f32,
    /// Rest density ρ0 (kg/m³).
    pub rest_density: f32,
    /// Dynamic viscosity μ (Pa·s), applied by WCSPH, DFSPH and PBF's
    /// implicit viscosity. PBF's default XSPH viscosity has no μ and
    /// refuses one. Left out: [`FluidSpec::DEFAULT_VISCOSITY`] where a
    /// solver applies μ.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub viscosity: Option<f32>,
    /// Surface tension σ (N/m).
    pub surface_tension: f32,
    /// The force that applies σ: `"colour-field"` (the thesis's, WCSPH
    /// only) or `"akinci"` (Akinci et al. 2013's); left out, each solver's
    /// own (WCSPH the thesis's, PBF and DFSPH Akinci's).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub surface_tension_model: Option<crate::solver::SurfaceTensionModel>,
    /// Gravity (m/s²).
    pub gravity: [f32; 3],
}

impl FluidSpec {
    /// The μ (Pa·s) of a scene that gives none, for the solvers that apply
    /// one: the thesis's scenes' 0.5 Pa·s, which keeps WCSPH's pressure
    /// waves damped at real-time stiffness.
    pub const DEFAULT_VISCOSITY: f32 = 0.5;

    /// The viscosity μ (Pa·s) the solvers that apply one use.
    pub fn viscosity(&self) -> f32 {
        self.viscosity.unwrap_or(Self::DEFAULT_VISCOSITY)
    }
}

/// An obstacle.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "shape", rename_all = "lowercase", deny_unknown_fields)]
pub enum ObstacleSpec {
    /// A solid box.
    Box {
        /// Minimum corner (m).
        min: [f32; 3],
        /// Maximum corner (m).
        max: [f32; 3],
    },
    /// A solid sphere.
    Sphere {
        /// Centre (m).
        centre: [f32; 3],
        /// Radius (m).
        radius: f32,
    },
}

/// An emitter of square layers of particles.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EmitterSpec {
    /// Centre of the nozzle (m).
    pub centre: [f32; 3],
    /// Velocity of the emitted particles (m/s).
    pub velocity: [f32; 3],
    /// Particles per side of the square nozzle.
    pub width: u32,
}

/// The frame: how much simulated time each rendered frame advances. The
/// solvers choose their own steps within it (`[solver.*]`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TimeStepSpec {
    /// Simulated time per rendered frame (s).
    pub frame_dt: f32,
}

/// The thesis's weakly compressible SPH's own parameters, the
/// `[solver.wcsph]` table: every field optional (the defaults below), kept
/// when another solver runs the scene, as the other solvers' tables are.
/// See [`FluidParams`] for the equation of state and the pressure force,
/// [`TimeStepping`] for the adaptive step.
///
/// ```toml
/// [solver.wcsph]
/// stiffness = 2000.0
/// max_dt = 0.002
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct WcsphSpec {
    /// Stiffness k of p = k(ρ − ρ0) (m²/s²); the speed of sound is √k.
    /// Default 2000: about 10 × the fastest flow of a 1 m fall.
    pub stiffness: f32,
    /// Factor on negative pressures in [0, 1] (default 0: clamped).
    pub negative_pressure_scale: f32,
    /// Kernel of the pressure force: `"poly6"` (default) or `"spiky"`.
    pub pressure_kernel: crate::solver::PressureKernel,
    /// |∇c| above which the thesis's colour-field surface tension acts
    /// (1/m); left out, 0.1 / h. Only the colour-field force reads it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub surface_threshold: Option<f32>,
    /// Largest step (s); default 0.002.
    pub max_dt: f32,
    /// Courant factor of the adaptive step.
    pub cfl: f32,
    /// Force-condition factor of the adaptive step.
    pub force_factor: f32,
}

impl Default for WcsphSpec {
    fn default() -> Self {
        let t = TimeStepping::default();
        Self {
            stiffness: 2000.0,
            negative_pressure_scale: 0.0,
            pressure_kernel: Default::default(),
            surface_threshold: None,
            max_dt: t.max_dt,
            cfl: t.cfl,
            force_factor: t.force_factor,
        }
    }
}

/// Fields that moved from `[fluid]` and `[time_step]` to `[solver.wcsph]`:
/// a file that still has them is told where they went.
const WCSPH_FIELDS: [&str; 7] = [
    "stiffness",
    "negative_pressure_scale",
    "pressure_kernel",
    "surface_threshold",
    "max_dt",
    "cfl",
    "force_factor",
];

/// Which solver runs the scene, and the parameters of each: `[solver]` with
/// `kind = "pbf"` (the default, also without the table), `"dfsph"` or
/// `"wcsph"` (the thesis's), and
/// optional `[solver.pbf]`, `[solver.dfsph]` and `[solver.wcsph]` tables
/// ([`PbfParams`], [`DfsphParams`], [`WcsphSpec`], every field optional).
/// Without its table PBF takes [`Scene::pbf_params`]: enough substeps for
/// the scene's fluid height and particle size; DFSPH and WCSPH take their
/// defaults. The parameters of a solver not chosen are kept, so switching
/// solver (the demo's `--solver`) finds them.
///
/// ```toml
/// [solver]
/// kind = "pbf"
///
/// [solver.pbf]
/// substeps = 2
/// iterations = 4
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SolverSpec {
    /// The solver.
    #[serde(default)]
    pub kind: SolverKind,
    /// Position-based fluids' parameters; `None` (no `[solver.pbf]`
    /// table): [`Scene::pbf_params`] derives them.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pbf: Option<PbfParams>,
    /// DFSPH's parameters; `None` (no `[solver.dfsph]` table): the
    /// defaults.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dfsph: Option<DfsphParams>,
    /// The thesis's WCSPH's parameters; `None` (no `[solver.wcsph]`
    /// table): [`WcsphSpec::default`].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub wcsph: Option<WcsphSpec>,
}

/// Hints for the renderer and the demo.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RenderSpec {
    /// Camera position (m).
    pub camera: [f32; 3],
    /// Point the camera looks at (m).
    pub look_at: [f32; 3],
    /// Vertical field of view (degrees).
    pub fov_y: f32,
}

impl Default for RenderSpec {
    fn default() -> Self {
        Self {
            camera: [0.5, 0.6, 2.0],
            look_at: [0.5, 0.2, 0.0],
            fov_y: 45.0,
        }
    }
}

impl RenderSpec {
    /// A camera that frames the box (`min`, `max`), the scene's tank: it
    /// looks at the box from the front (+z) and 27° above, at a point a
    /// third of the way up, from the distance at which all eight corners
    /// fill at most 90 % of a 16:9 image with a vertical field of view of
    /// `fov_y` degrees.
    pub fn framing(min: Vec3, max: Vec3, fov_y: f32) -> Self {
        let target = Vec3::new(
            0.5 * (min.x + max.x),
            min.y + (max.y - min.y) / 3.0,
            0.5 * (min.z + max.z),
        );
        let back = Vec3::new(0.0, 0.5, 1.0).normalize();
        let forward = -back;
        let right = forward.cross(Vec3::Y).normalize();
        let up = right.cross(forward);
        let tan_y = 0.9 * (0.5 * fov_y.to_radians()).tan();
        let tan_x = tan_y * 16.0 / 9.0;
        let fits = |d: f32| {
            let eye = target + d * back;
            (0..8).all(|k| {
                let corner = Vec3::new(
                    if k & 1 == 0 { min.x } else { max.x },
                    if k & 2 == 0 { min.y } else { max.y },
                    if k & 4 == 0 { min.z } else { max.z },
                );
                let v = corner - eye;
                let z = v.dot(forward);
                z > 0.0 && v.dot(right).abs() <= tan_x * z && v.dot(up).abs() <= tan_y * z
            })
        };
        // Bisection between a distance too close and one that fits.
        let size = (max - min).length().max(f32::MIN_POSITIVE);
        let (mut near, mut far) = (0.0, 100.0 * size);
        for _ in 0..40 {
            let mid = 0.5 * (near + far);
            if fits(mid) {
                far = mid;
            } else {
                near = mid;
            }
        }
        Self {
            camera: (target + far * back).to_array(),
            look_at: target.to_array(),
            fov_y,
        }
    }

    /// Checks the camera: finite, distinct points, a view direction that is
    /// not vertical (+y is up), a field of view in (0°, 180°).
    pub fn validate(&self) -> Result<()> {
        let camera = finite3("render.camera", self.camera)?;
        let look_at = finite3("render.look_at", self.look_at)?;
        let dir = look_at - camera;
        if dir.length_squared() <= 0.0 {
            return Err(invalid("render.look_at", "must differ from render.camera"));
        }
        if dir.normalize().cross(Vec3::Y).length_squared() < 1e-12 {
            return Err(invalid(
                "render.look_at",
                "the view direction is vertical: +y is up, so the camera cannot look straight up or down",
            ));
        }
        if !(self.fov_y > 0.0 && self.fov_y < 180.0) {
            return Err(invalid(
                "render.fov_y",
                format!("{} must lie in (0, 180) degrees", self.fov_y),
            ));
        }
        Ok(())
    }
}

/// Why an obstacle that misses the domain is refused.
const OBSTACLE_OUTSIDE: &str =
    "lies wholly outside the domain: it would hold back no fluid (a typo in its corners?)";

/// The longest simulated time per frame a scene accepts (s).
pub const MAX_FRAME_DT: f32 = 1.0;

fn invalid(field: impl Into<String>, reason: impl Into<String>) -> Error {
    Error::Scene {
        field: field.into(),
        reason: reason.into(),
    }
}

/// A parameter error of the library named as the scene file names the
/// field, under `table` (`fluid.h`, `solver.pbf.iterations`).
fn in_table(table: &'static str) -> impl Fn(Error) -> Error {
    move |e| match e {
        Error::InvalidParameter {
            name,
            value,
            reason,
        } => invalid(format!("{table}.{name}"), format!("{value} {reason}")),
        e => e,
    }
}

fn finite3(field: &str, v: [f32; 3]) -> Result<Vec3> {
    let v = Vec3::from(v);
    if v.is_finite() {
        Ok(v)
    } else {
        Err(invalid(field, format!("{v:?} is not finite")))
    }
}

fn positive(field: &str, v: f32) -> Result<()> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(invalid(field, format!("{v} must be finite and > 0")))
    }
}

/// Refuses a number of a scene file that f32, which every field is, does
/// not hold: a non-zero value that rounds to 0 (`surface_tension = 1e-50`)
/// or beyond f32's range (`1e39`, infinite) would otherwise be read as 0 or
/// infinity without a word. `path` names the value (`fluid.h`,
/// `blocks[0].min[1]`).
fn check_f32_range(path: String, value: &toml::Value) -> Result<()> {
    match value {
        toml::Value::Float(x) => {
            let single = *x as f32;
            if (*x != 0.0 && single == 0.0) || (x.is_finite() && !single.is_finite()) {
                return Err(invalid(
                    path,
                    format!(
                        "{x:e} lies outside f32's range (about 1e-45 to 3.4e38 in magnitude), \
                         which every scene value is read as: it would become {single}"
                    ),
                ));
            }
            Ok(())
        }
        toml::Value::Table(t) => t
            .iter()
            .try_for_each(|(k, v)| check_f32_range(format!("{path}.{k}"), v)),
        toml::Value::Array(a) => {
            (a.iter().enumerate()).try_for_each(|(i, v)| check_f32_range(format!("{path}[{i}]"), v))
        }
        _ => Ok(()),
    }
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

    /// Checks every value; the error names the field and the reason.
    pub fn validate(&self) -> Result<()> {
        let f = &self.fluid;
        // The solver's own checks, named as the file names the fields:
        // WCSPH's own under [solver.wcsph], the others under [fluid].
        (self.fluid_params().validate()).map_err(|e| match &e {
            Error::InvalidParameter { name, .. } if WCSPH_FIELDS.contains(name) => {
                in_table("solver.wcsph")(e)
            }
            _ => in_table("fluid")(e),
        })?;
        // The kernels' own check: h must keep their coefficients finite f32.
        check_kernel_h(f.h).map_err(|e| invalid("fluid.h", e.to_string()))?;
        positive("spacing", self.spacing)?;
        if self.spacing >= f.h {
            return Err(invalid(
                "spacing",
                format!("{} must be smaller than fluid.h = {}", self.spacing, f.h),
            ));
        }
        if f.h / self.spacing > MAX_H_OVER_SPACING {
            return Err(invalid(
                "spacing",
                format!(
                    "fluid.h / spacing = {} exceeds {MAX_H_OVER_SPACING}: each particle would have thousands of neighbours",
                    f.h / self.spacing
                ),
            ));
        }
        let dmin = finite3("domain.min", self.domain.min)?;
        let dmax = finite3("domain.max", self.domain.max)?;
        if !dmin.cmplt(dmax).all() {
            return Err(invalid("domain", "min must be below max on every axis"));
        }
        let domain = Aabb::new(dmin, dmax);
        let c = self.wall_clearance();
        if !(c >= 0.0 && c <= self.spacing && 2.0 * c < domain.size().min_element()) {
            let given = if self.clearance.is_some() {
                ""
            } else {
                " (left out: half the spacing)"
            };
            return Err(invalid(
                "clearance",
                format!(
                    "{c} m{given}: must be ≥ 0, at most the spacing ({} m) and less than half the domain's narrowest side",
                    self.spacing
                ),
            ));
        }
        let mut count = 0usize;
        for (k, b) in self.blocks.iter().enumerate() {
            let field = format!("blocks[{k}]");
            let (min, max) = (
                finite3(&format!("{field}.min"), b.min)?,
                finite3(&format!("{field}.max"), b.max)?,
            );
            finite3(&format!("{field}.velocity"), b.velocity)?;
            if !min.cmplt(max).all() {
                return Err(invalid(&field, "min must be below max on every axis"));
            }
            if !domain.contains(min) || !domain.contains(max) {
                return Err(invalid(
                    &field,
                    "the block lies (partly) outside the domain",
                ));
            }
            let n = lattice_count(min, max, self.spacing);
            if let Some(axis) = n.iter().position(|&n| n == 0) {
                return Err(invalid(
                    &field,
                    format!(
                        "is {} m thick along {}, less than one spacing ({} m): it would hold no particle",
                        (max - min)[axis],
                        ["x", "y", "z"][axis],
                        self.spacing
                    ),
                ));
            }
            count = count.saturating_add(n[0].saturating_mul(n[1]).saturating_mul(n[2]));
            // Overlapping blocks would put two particles on one lattice point
            // (or nearly), which pressure cannot separate.
            for (j, other) in self.blocks[..k].iter().enumerate() {
                let (omin, omax) = (Vec3::from(other.min), Vec3::from(other.max));
                if min.cmplt(omax).all() && omin.cmplt(max).all() {
                    return Err(invalid(
                        &field,
                        format!("overlaps blocks[{j}]: their particles would be placed twice"),
                    ));
                }
            }
        }
        for (k, o) in self.obstacles.iter().enumerate() {
            let field = format!("obstacles[{k}]");
            match *o {
                ObstacleSpec::Box { min, max } => {
                    let (min, max) = (
                        finite3(&format!("{field}.min"), min)?,
                        finite3(&format!("{field}.max"), max)?,
                    );
                    if !min.cmplt(max).all() {
                        return Err(invalid(&field, "min must be below max on every axis"));
                    }
                    if !(min.cmplt(domain.max).all() && domain.min.cmplt(max).all()) {
                        return Err(invalid(&field, OBSTACLE_OUTSIDE));
                    }
                }
                ObstacleSpec::Sphere { centre, radius } => {
                    let c = finite3(&format!("{field}.centre"), centre)?;
                    positive(&format!("{field}.radius"), radius)?;
                    if c.clamp(domain.min, domain.max).distance(c) >= radius {
                        return Err(invalid(&field, OBSTACLE_OUTSIDE));
                    }
                }
            }
        }
        let free = self.boundary();
        for (k, e) in self.emitters.iter().enumerate() {
            let field = format!("emitters[{k}]");
            let c = finite3(&format!("{field}.centre"), e.centre)?;
            let v = finite3(&format!("{field}.velocity"), e.velocity)?;
            if v.length() <= 0.0 {
                return Err(invalid(format!("{field}.velocity"), "must be non-zero"));
            }
            if !domain.contains(c) {
                return Err(invalid(
                    format!("{field}.centre"),
                    "lies outside the domain",
                ));
            }
            if e.width == 0 {
                return Err(invalid(format!("{field}.width"), "must be at least 1"));
            }
            let layer = u64::from(e.width) * u64::from(e.width);
            if layer > self.max_particles as u64 {
                return Err(invalid(
                    format!("{field}.width"),
                    format!(
                        "the nozzle's layer of {layer} particles is more than max_particles = {}",
                        self.max_particles
                    ),
                ));
            }
            // An emitter adds whole layers only: one must fit beside the
            // blocks (their lattice points, counted before obstacles).
            if count as u64 + layer > self.max_particles as u64 {
                return Err(invalid(
                    format!("{field}.width"),
                    format!(
                        "the blocks hold up to {count} particles, so the nozzle's layer of {layer} \
                         does not fit under max_particles = {}: the emitter would add nothing",
                        self.max_particles
                    ),
                ));
            }
            // The whole nozzle, not only its centre, must lie in free space:
            // particles emitted into a wall or an obstacle would be projected
            // onto each other.
            let corners = nozzle_corners(c, v, e.width, self.spacing);
            // The corners first: they bound the nozzle's size, and so the
            // cost of checking each of its points.
            let fits = corners.iter().all(|&x| free.admits(x))
                && nozzle_points(c, v, e.width, self.spacing).all(|x| free.admits(x));
            if !fits {
                return Err(invalid(
                    &field,
                    format!(
                        "the nozzle ({} particles wide at spacing {}) reaches outside the domain or into an obstacle",
                        e.width, self.spacing
                    ),
                ));
            }
        }
        let t = &self.time_step;
        positive("time_step.frame_dt", t.frame_dt)?;
        let min_dt = self.time_stepping().min_dt;
        if t.frame_dt < min_dt {
            return Err(invalid(
                "time_step.frame_dt",
                format!(
                    "{:e} s is shorter than {min_dt:e} s, the shortest step a run takes",
                    t.frame_dt
                ),
            ));
        }
        if t.frame_dt > MAX_FRAME_DT {
            return Err(invalid(
                "time_step.frame_dt",
                format!(
                    "{} s is longer than {MAX_FRAME_DT} s of simulation per frame",
                    t.frame_dt
                ),
            ));
        }
        self.validate_wcsph()?;
        // Every solver's parameters, chosen or not: switching must not find
        // bad ones.
        let pbf = self.pbf_params();
        (pbf.validate()).map_err(|e| match self.solver.pbf {
            Some(_) => in_table("solver")(e),
            // Derived from the scene: name what they were derived from.
            None => invalid(
                "solver.pbf",
                format!(
                    "is not given, and the defaults derived from this scene ({} substeps of {:e} s a frame, \
                     so that fluid falling from its highest block or emitter under fluid.gravity moves \
                     at most {} h a substep at time_step.frame_dt = {} s) fail: {}; \
                     give [solver.pbf] substeps and max_dt",
                    pbf.substeps, pbf.max_dt, crate::solver::pbf::FALL_CFL, t.frame_dt, in_table("solver")(e)
                ),
            ),
        })?;
        (self.dfsph_params().validate()).map_err(in_table("solver"))?;
        // Sleeping thresholds that this scene's own steps at rest could not
        // apply: PBF's substep, and DFSPH's shortest step at rest (a
        // frame's last two steps share what is left of it).
        let (gravity, frame_dt) = (Vec3::from(self.fluid.gravity).length(), t.frame_dt);
        (self.pbf_params().check_sleep(gravity, frame_dt)).map_err(in_table("solver"))?;
        let dfsph = self.dfsph_params();
        let shortest = frame_dt.min(0.5 * dfsph.max_dt);
        (dfsph.check_sleep(gravity, shortest)).map_err(in_table("solver"))?;
        // The chosen solver applies every fluid parameter as given.
        (self.solver().check_applies(&self.fluid_params())).map_err(in_table("fluid"))?;
        self.check_viscosity_applies()?;
        self.render.validate()?;
        if self.max_particles > MAX_PARTICLES {
            return Err(invalid(
                "max_particles",
                format!(
                    "{} exceeds the neighbour grid's limit of {MAX_PARTICLES}",
                    self.max_particles
                ),
            ));
        }
        if count > self.max_particles {
            return Err(invalid(
                "max_particles",
                format!(
                    "the blocks hold {count} particles, more than max_particles = {}",
                    self.max_particles
                ),
            ));
        }
        if count == 0 && self.emitters.is_empty() {
            return Err(invalid(
                "blocks",
                "the scene has no fluid: add a block or an emitter",
            ));
        }
        Ok(())
    }

    /// `[solver.wcsph]`'s values: the step's bounds, and a colour-field
    /// threshold only where the colour field runs (a WCSPH scene with
    /// Akinci et al.'s forces would not read it).
    fn validate_wcsph(&self) -> Result<()> {
        (self.time_stepping().validate()).map_err(in_table("solver.wcsph"))?;
        let w = self.wcsph_params();
        let model = self.fluid.surface_tension_model;
        let colour_field =
            model.is_none_or(|m| m == crate::solver::SurfaceTensionModel::ColourField);
        if let (Some(threshold), false) = (w.surface_threshold, colour_field) {
            return Err(invalid(
                "solver.wcsph.surface_threshold",
                format!(
                    "{threshold} 1/m applies to the thesis's colour-field force only, and \
                     fluid.surface_tension_model is \"akinci\": leave it out"
                ),
            ));
        }
        Ok(())
    }

    /// PBF's default XSPH viscosity has no μ: a scene run by it that gives
    /// `fluid.viscosity` is refused rather than run without it.
    fn check_viscosity_applies(&self) -> Result<()> {
        let xsph = self.solver.kind == SolverKind::Pbf
            && self.pbf_params().viscosity == PbfViscosity::Xsph;
        match self.fluid.viscosity {
            Some(mu) if xsph => Err(invalid(
                "fluid.viscosity",
                format!(
                    "{mu} Pa·s is not applied by PBF with XSPH viscosity (its default, a blend \
                     with no unit): leave it out, set [solver.pbf] viscosity = \"implicit\" to \
                     solve this μ, or run another solver"
                ),
            )),
            _ => Ok(()),
        }
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
    pub fn particles(&self) -> Result<Particles> {
        self.validate()?;
        let mass = (self.solver()).particle_mass(&self.fluid_params(), self.spacing)?;
        let boundary = self.boundary();
        let mut p = Particles::new();
        for b in &self.blocks {
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
        }
        if p.is_empty() && self.emitters.is_empty() {
            return Err(invalid(
                "blocks",
                "every block particle lies inside an obstacle: the scene has no fluid",
            ));
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

    /// Common parameters of the built-in scenes: h = 2 × spacing, run by
    /// the thesis's WCSPH (the constructors build the thesis's scenes;
    /// [`Scene::with_solver`] picks another, as the demo picks PBF).
    fn base(name: &str, domain: Vec3, spacing: f32) -> Self {
        let h = 2.0 * spacing;
        Scene {
            name: name.into(),
            domain: BoxSpec {
                min: [0.0; 3],
                max: domain.to_array(),
            },
            fluid: FluidSpec {
                h,
                rest_density: 1000.0,
                viscosity: None,
                surface_tension: 0.0,
                surface_tension_model: None,
                gravity: [0.0, -9.81, 0.0],
            },
            spacing,
            blocks: Vec::new(),
            obstacles: Vec::new(),
            clearance: None,
            emitters: Vec::new(),
            time_step: TimeStepSpec {
                frame_dt: 1.0 / 60.0,
            },
            max_particles: default_max_particles(),
            solver: SolverSpec {
                kind: SolverKind::Wcsph,
                ..SolverSpec::default()
            },
            render: RenderSpec::framing(Vec3::ZERO, domain, 45.0),
        }
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

    /// The dam break: a water column of width `a` and height 2a at the left of a
    /// tank 4a long and 2.5a high, `depth` deep (a thin slab when depth is a few
    /// spacings, full 3D when depth ≈ a); lengths in metres, particles on a
    /// lattice of `spacing`, h = 2 × spacing.
    pub fn dam_break(a: f32, depth: f32, spacing: f32) -> Self {
        let mut s = Self::base("dam break", Vec3::new(4.0 * a, 2.5 * a, depth), spacing);
        s.blocks.push(BlockSpec {
            min: [0.0; 3],
            max: [a, 2.0 * a, depth],
            velocity: [0.0; 3],
        });
        s
    }

    /// Two columns released from both ends of the tank.
    pub fn double_dam_break(a: f32, depth: f32, spacing: f32) -> Self {
        let mut s = Self::base(
            "double dam break",
            Vec3::new(5.0 * a, 2.5 * a, depth),
            spacing,
        );
        for x0 in [0.0, 4.0 * a] {
            s.blocks.push(BlockSpec {
                min: [x0, 0.0, 0.0],
                max: [x0 + a, 2.0 * a, depth],
                velocity: [0.0; 3],
            });
        }
        s
    }

    /// A cube of honey (side `a`, ρ0 = 1,400 kg/m³, μ = 50 Pa·s: 50,000 ×
    /// water) let go a/2 above the floor of a tank 4a wide: it slumps and
    /// spreads slowly, run by DFSPH (whose viscosity is implicit); run by
    /// PBF, its `[solver.pbf]` solves the same μ implicitly
    /// ([`PbfViscosity::Implicit`]) instead of XSPH.
    pub fn honey(a: f32, spacing: f32) -> Self {
        let w = 4.0 * a;
        let mut s = Self::base("honey", Vec3::new(w, 2.5 * a, w), spacing);
        s.fluid.rest_density = 1400.0;
        s.blocks.push(BlockSpec {
            min: [1.5 * a, 0.5 * a, 1.5 * a],
            max: [2.5 * a, 1.5 * a, 2.5 * a],
            velocity: [0.0; 3],
        });
        s.solver.kind = SolverKind::Dfsph;
        s.with_viscosity(50.0)
    }

    /// A cube of water of side `a` falling into a pool of depth a/2 in a tank 3a
    /// wide and deep.
    pub fn drop_into_pool(a: f32, spacing: f32) -> Self {
        let w = 3.0 * a;
        let mut s = Self::base("drop into pool", Vec3::new(w, 3.0 * a, w), spacing);
        s.blocks.push(BlockSpec {
            min: [0.0; 3],
            max: [w, 0.5 * a, w],
            velocity: [0.0; 3],
        });
        s.blocks.push(BlockSpec {
            min: [a, 1.6 * a, a],
            max: [2.0 * a, 2.6 * a, 2.0 * a],
            velocity: [0.0, -1.0, 0.0],
        });
        s
    }
}

impl Scene {
    /// Two weightless cubes of water (side 13 spacings, 6.5 cm at 5 mm)
    /// drifting towards each other at 5 cm/s each, a third of a side off
    /// centre, in a box 0.36 × 0.2 × 0.2 m: surface tension (water's σ =
    /// 0.0728 N/m) rounds each into a drop, and the drops merge into one
    /// that spins and wobbles. Without σ nothing pulls them round or holds
    /// them together. h = 2 × spacing, as the other scenes. No μ is given:
    /// PBF, which runs it (on the GPU too), damps by its XSPH blend, and
    /// the other solvers take [`FluidSpec::DEFAULT_VISCOSITY`].
    pub fn weightless_drops(spacing: f32) -> Self {
        let (w, d) = (0.36, 0.2);
        let mut s = Self::base("weightless drops", Vec3::new(w, d, d), spacing);
        s.fluid.gravity = [0.0; 3];
        s.fluid.surface_tension = 0.0728;
        // 13 lattice points a side. The extent is a quarter spacing over
        // 13 from when the lattice rounded 12.999998 spacings (13 × 0.005
        // in f32) down to 12; it is kept so the scene's particles stay
        // where its measurements put them.
        let side = 13.25 * spacing;
        let offset = side / 3.0;
        for (cx, cy, vx) in [
            (0.3 * w, 0.5 * d + 0.5 * offset, 0.05),
            (0.7 * w, 0.5 * d - 0.5 * offset, -0.05),
        ] {
            s.blocks.push(BlockSpec {
                min: [cx - 0.5 * side, cy - 0.5 * side, 0.5 * d - 0.5 * side],
                max: [cx + 0.5 * side, cy + 0.5 * side, 0.5 * d + 0.5 * side],
                velocity: [vx, 0.0, 0.0],
            });
        }
        s.render = RenderSpec {
            camera: [0.5 * w, 0.6 * d, 0.5 * d + 0.32],
            look_at: [0.5 * w, 0.5 * d, 0.5 * d],
            fov_y: 45.0,
        };
        s
    }
}

/// A built-in scene: name, description, constructor.
pub type BuiltIn = (&'static str, &'static str, fn() -> Scene);

/// The demo's built-in scenes (`sph-app --scene NAME`, keys 1–8 in its
/// window; `sph_splat.World(NAME)` in Python), in key order: name,
/// description, constructor ([`Scene::built_in`]). The first five run PBF, the
/// real-time solver, with the parameters `Scene::pbf_params` derives (3
/// iterations, and 3 substeps per 60 Hz frame, 5 for `dam-break-fine`, so
/// that a fall through the fluid's height moves at most 0.6 h per substep);
/// the next two DFSPH, the accurate one, with physical viscosities: water
/// (1e-3 Pa·s) and honey (50 Pa·s); `drops`, water's surface tension in
/// zero gravity, PBF again (with no μ: run by another solver it takes
/// [`FluidSpec::DEFAULT_VISCOSITY`]). `--solver` runs any with another.
pub const BUILT_IN: [BuiltIn; 8] = [
    ("dam-break", "thin-slab dam break", || {
        Scene::dam_break(0.25, 0.08, 0.02).with_solver(SolverKind::Pbf)
    }),
    (
        "dam-break-3d",
        "full 3D dam break around a sphere and a low wall",
        || {
            // The obstacles of assets/scenes/dam_break_3d.toml.
            let mut scene = Scene::dam_break(0.25, 0.25, 0.02).with_solver(SolverKind::Pbf);
            scene.obstacles = vec![
                ObstacleSpec::Sphere {
                    centre: [0.6, 0.0, 0.125],
                    radius: 0.1,
                },
                ObstacleSpec::Box {
                    min: [0.85, 0.0, 0.0],
                    max: [0.9, 0.1, 0.25],
                },
            ];
            scene
        },
    ),
    (
        "double-dam-break",
        "two columns released from both ends",
        || Scene::double_dam_break(0.2, 0.08, 0.02).with_solver(SolverKind::Pbf),
    ),
    ("drop", "a cube of water falling into a pool", || {
        Scene::drop_into_pool(0.2, 0.02).with_solver(SolverKind::Pbf)
    }),
    (
        "dam-break-fine",
        "thin-slab dam break at 1 cm spacing",
        || Scene::dam_break(0.25, 0.08, 0.01).with_solver(SolverKind::Pbf),
    ),
    (
        "dam-break-water",
        "thin-slab dam break of water (μ = 1e-3 Pa·s), DFSPH",
        || {
            Scene::dam_break(0.25, 0.08, 0.02)
                .with_solver(SolverKind::Dfsph)
                .with_viscosity(1e-3)
        },
    ),
    (
        "honey",
        "a cube of honey (μ = 50 Pa·s) slumping, DFSPH",
        || Scene::honey(0.2, 0.02),
    ),
    (
        "drops",
        "two weightless cubes of water rounded and merged by surface tension",
        || Scene::weightless_drops(0.005).with_solver(SolverKind::Pbf),
    ),
];

impl Scene {
    /// The built-in scene called `name` ([`BUILT_IN`]), or `None`.
    pub fn built_in(name: &str) -> Option<Scene> {
        (BUILT_IN.iter())
            .find(|(n, _, _)| *n == name)
            .map(|(_, _, make)| make())
    }
}
