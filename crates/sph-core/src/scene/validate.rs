//! Scene validation: every value finite and in range, every block, obstacle
//! and emitter inside the domain, and each solver's parameters, each error
//! naming the field as the scene file does.

use glam::Vec3;

use super::spec::WCSPH_FIELDS;
use super::{ObstacleSpec, Scene, lattice_count};
use crate::boundary::Aabb;
use crate::error::{Error, Result, check_kernel_h};
use crate::grid::MAX_PARTICLES;
use crate::solver::{MAX_H_OVER_SPACING, PbfViscosity, SolverKind, nozzle_corners, nozzle_points};

/// Why an obstacle that misses the domain is refused.
const OBSTACLE_OUTSIDE: &str =
    "lies wholly outside the domain: it would hold back no fluid (a typo in its corners?)";

/// The longest simulated time per frame a scene accepts (s).
pub const MAX_FRAME_DT: f32 = 1.0;

pub(super) fn invalid(field: impl Into<String>, reason: impl Into<String>) -> Error {
    Error::Scene {
        field: field.into(),
        reason: reason.into(),
    }
}

/// A parameter error of the library named as the scene file names the
/// field, under `table` (`fluid.h`, `solver.pbf.iterations`).
pub(super) fn in_table(table: &'static str) -> impl Fn(Error) -> Error {
    move |e| match e {
        Error::InvalidParameter {
            name,
            value,
            reason,
        } => invalid(format!("{table}.{name}"), format!("{value} {reason}")),
        e => e,
    }
}

pub(super) fn finite3(field: &str, v: [f32; 3]) -> Result<Vec3> {
    let v = Vec3::from(v);
    if v.is_finite() {
        Ok(v)
    } else {
        Err(invalid(field, format!("{v:?} is not finite")))
    }
}

pub(super) fn positive(field: &str, v: f32) -> Result<()> {
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
pub(super) fn check_f32_range(path: String, value: &toml::Value) -> Result<()> {
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

impl Scene {
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
        for (field, corner) in [("domain.min", dmin), ("domain.max", dmax)] {
            if crate::error::first_imprecise(&[corner], f.h).is_some() {
                return Err(invalid(
                    field,
                    format!("{corner} (h = {}) {}", f.h, crate::error::IMPRECISE),
                ));
            }
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
        (self.pbf_params().check_frame(frame_dt)).map_err(in_table("solver"))?;
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
}
