//! The scene file's tables: the domain, the fluid, blocks, obstacles,
//! emitters, the frame, the solvers' parameters and the camera.

use glam::Vec3;
use serde::{Deserialize, Serialize};

use super::validate::{finite3, invalid};
use crate::error::Result;
use crate::solver::{DfsphParams, PbfParams, SolverKind, TimeStepping};

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

/// The fluid's physical parameters, see [`FluidParams`](crate::FluidParams). What only the
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
/// See [`FluidParams`](crate::FluidParams) for the equation of state and the pressure force,
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
pub(super) const WCSPH_FIELDS: [&str; 7] = [
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
/// Without its table PBF takes [`Scene::pbf_params`](super::Scene::pbf_params): enough substeps for
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
    /// table): [`Scene::pbf_params`](super::Scene::pbf_params) derives them.
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
        if dir == Vec3::ZERO {
            return Err(invalid("render.look_at", "must differ from render.camera"));
        }
        if !dir.is_finite() {
            return Err(invalid(
                "render.look_at",
                "is so far from render.camera that their difference overflows f32",
            ));
        }
        // Scaled to its largest component first: |dir|² overflows beyond
        // about 1e19 m.
        let unit = (dir / dir.abs().max_element()).normalize();
        if unit.cross(Vec3::Y).length_squared() < 1e-12 {
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
        // As the renderer's camera: a focal length 1/tan(fov/2) outside
        // [1e-4, 1e4] draws nothing.
        let focal = 1.0 / (0.5 * self.fov_y.to_radians()).tan();
        if !(1e-4..=1e4).contains(&focal) {
            return Err(invalid(
                "render.fov_y",
                format!(
                    "{} degrees is within 0.011° of 0 or 180: the projection would draw nothing",
                    self.fov_y
                ),
            ));
        }
        Ok(())
    }
}
