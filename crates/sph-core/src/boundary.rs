//! Boundaries: the box domain and static obstacles (boxes and spheres).
//!
//! Method: wall density plus position projection. Within h of a wall, the solver
//! adds the density the missing fluid beyond the wall would contribute (the wall
//! taken locally as a plane backed by fluid at rest density, integrated
//! analytically: [`WallKernel`]) and the force that is exactly the gradient of
//! that term's pressure energy, so walls neither add nor remove energy (an
//! earlier mirror-pressure force, 2 p/ρ² times the spiky flux, pumped energy into
//! a resting tank). This keeps particles from piling into the wall.
//! After every integration step, position projection with velocity reflection
//! then guarantees containment. A particle found outside the domain or inside an obstacle is
//! moved to the nearest point of the boundary surface and the part of its velocity
//! pointing into the boundary is removed (times `1 + restitution`). We chose it
//! over penalty forces because it needs no stiffness of its own, so it cannot make
//! the step size smaller or go unstable at the stiffness a dam break needs, and
//! because no speed or step can carry a particle through a wall: containment is
//! exact by construction. Without the wall pressure, particles next to a wall
//! see a density deficit, are pushed into it by the fluid behind them and pile up
//! there; the analytic wall term costs nothing per neighbour, unlike boundary
//! particles (Akinci et al. 2012), and needs no sampling of curved obstacles.
//! Under a [`Boundary::clearance`] the solvers take the fluid behind a wall
//! as their lattice continued layer by layer ([`WallKernel::lattice_layers`]),
//! so that a lattice filled to a wall starts its first layer at rest density.
//!
//! Known limitation: where walls meet, each adds its own half-space's fluid,
//! so the region behind both is counted twice. A particle on a box edge gets
//! ρ0 added where 0.75 ρ0 is missing, and on a corner 1.5 ρ0 where 0.875 ρ0 is
//! (exact inclusion–exclusion would need the poly6 integral over a quadrant
//! and an octant, which has no closed form as simple as the plane's). It
//! stays energy-consistent, being the gradient of the same (overestimated)
//! term, and measured small: in the settled tank of the solver test
//! `hydrostatic_tank` (`cargo test --release -p sph-core --test solver
//! hydrostatic -- --nocapture`), a 2h × h channel along the floor–wall edge
//! holds 153 particles at mean ρ 1007.3 kg/m³, one on the floor away from
//! the walls 139 at 1007.1 kg/m³: no void, 0.02 % denser.

use glam::Vec3;

use crate::error::{Error, Result};
use crate::kernels::{CubicSpline, Poly6, lattice_sum};

/// An axis-aligned box.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Aabb {
    /// Minimum corner (m).
    pub min: Vec3,
    /// Maximum corner (m).
    pub max: Vec3,
}

impl Aabb {
    /// The box between two corners (in any order).
    pub fn new(a: Vec3, b: Vec3) -> Self {
        Self {
            min: a.min(b),
            max: a.max(b),
        }
    }

    /// Whether `x` is inside or on the surface.
    pub fn contains(&self, x: Vec3) -> bool {
        x.cmpge(self.min).all() && x.cmple(self.max).all()
    }

    /// Edge lengths.
    pub fn size(&self) -> Vec3 {
        self.max - self.min
    }
}

/// A static obstacle that fluid may not enter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Obstacle {
    /// A solid axis-aligned box.
    Box(Aabb),
    /// A solid sphere.
    Sphere {
        /// Centre (m).
        centre: Vec3,
        /// Radius (m).
        radius: f32,
    },
}

impl Obstacle {
    /// Whether `x` is strictly inside the obstacle.
    pub fn contains(&self, x: Vec3) -> bool {
        match *self {
            Obstacle::Box(b) => x.cmpgt(b.min).all() && x.cmplt(b.max).all(),
            Obstacle::Sphere { centre, radius } => (x - centre).length_squared() < radius * radius,
        }
    }

    /// The obstacle grown by `c` on every side: a sphere's radius, a box's
    /// faces (its edges stay square).
    fn grown(self, c: f32) -> Self {
        match self {
            Obstacle::Box(b) => Obstacle::Box(Aabb {
                min: b.min - c,
                max: b.max + c,
            }),
            Obstacle::Sphere { centre, radius } => Obstacle::Sphere {
                centre,
                radius: radius + c,
            },
        }
    }

    /// If `x` is inside, the nearest surface point and the outward normal there.
    fn project(&self, x: Vec3) -> Option<(Vec3, Vec3)> {
        if !self.contains(x) {
            return None;
        }
        match *self {
            Obstacle::Sphere { centre, radius } => {
                let d = x - centre;
                let n = d.try_normalize().unwrap_or(Vec3::Y);
                // A hair outside, so rounding cannot leave the point inside:
                // growing steps, so it gets out even where a step of a few
                // ulps of the radius is below an ulp of the position.
                let mut p = centre + n * radius;
                let mut step = radius * 4.0 * f32::EPSILON;
                while self.contains(p) {
                    p += n * step;
                    step *= 2.0;
                }
                Some((p, n))
            }
            Obstacle::Box(b) => {
                // Leave through the nearest face.
                let to_min = x - b.min;
                let to_max = b.max - x;
                let mut best = (f32::INFINITY, Vec3::ZERO, x);
                for a in 0..3 {
                    let mut n = Vec3::ZERO;
                    if to_min[a] < best.0 {
                        n[a] = -1.0;
                        let mut p = x;
                        p[a] = b.min[a];
                        best = (to_min[a], n, p);
                    }
                    let mut n = Vec3::ZERO;
                    if to_max[a] < best.0 {
                        n[a] = 1.0;
                        let mut p = x;
                        p[a] = b.max[a];
                        best = (to_max[a], n, p);
                    }
                }
                Some((best.2, best.1))
            }
        }
    }
}

/// The domain box, the obstacles in it and how walls reflect velocity.
#[derive(Debug, Clone, PartialEq)]
pub struct Boundary {
    /// Fluid stays inside this box.
    pub domain: Aabb,
    /// Fluid stays outside these.
    pub obstacles: Vec<Obstacle>,
    /// Fraction of the normal velocity reflected at a wall: 0 = inelastic, 1 = elastic.
    pub restitution: f32,
    /// How far (m) the projection keeps particle centres from the domain
    /// walls and the obstacles' surfaces. A particle stands for a cube of
    /// fluid one spacing wide, so the first layer of a lattice filled to a
    /// wall lies half a spacing from it, which is where the wall density
    /// terms (measured from the surfaces themselves) expect it. Without the
    /// clearance, that layer is free to sink towards the wall: its density
    /// deficit is made up by the wall term growing as it nears the surface,
    /// so a settled pool lost 2–9 mm of its 10 mm first layer and 2–13 % of
    /// its depth (issue 41; `cargo run --release -p sph-core --example
    /// pool_at_rest`). FleX's `collisionDistance` is the same idea.
    /// [`Boundary::new`] gives 0, and so do scenes unless they set
    /// [`crate::Scene::clearance`] (half the spacing holds a lattice's
    /// first layer where it was put).
    pub clearance: f32,
}

impl Boundary {
    /// A closed box with no obstacles, inelastic walls and no clearance.
    pub fn new(domain: Aabb) -> Self {
        Self {
            domain,
            obstacles: Vec::new(),
            restitution: 0.0,
            clearance: 0.0,
        }
    }

    /// This boundary with particle centres kept `clearance` (m) from its
    /// walls ([`Boundary::clearance`]).
    pub fn with_clearance(mut self, clearance: f32) -> Self {
        self.clearance = clearance;
        self
    }

    /// Checks that the domain lies within [`crate::error::MAX_PRECISE_EXTENT`]
    /// × `h` of the origin, where f32 resolves the positions of particles
    /// of smoothing length `h` to h/128 or finer.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming `boundary.domain` and the corner.
    pub fn check_precision(&self, h: f32) -> Result<()> {
        let corners = [self.domain.min, self.domain.max];
        match crate::error::first_imprecise(&corners, h) {
            Some(k) => Err(Error::InvalidParameter {
                name: "boundary.domain",
                value: format!("corner {} with h = {h}", corners[k]),
                reason: crate::error::IMPRECISE,
            }),
            None => Ok(()),
        }
    }

    /// Checks the domain (finite corners, min below max on every axis), the
    /// obstacles (finite; boxes with min below max, spheres of radius > 0),
    /// `restitution` (in [0, 1]: more would add energy at every bounce) and
    /// `clearance` (finite, ≥ 0 and less than half the domain's narrowest
    /// side, so that some of the domain admits particle centres).
    pub fn validate(&self) -> Result<()> {
        let invalid = |name, value: String, reason| {
            Err(Error::InvalidParameter {
                name,
                value,
                reason,
            })
        };
        let a = self.domain;
        if !(a.min.is_finite() && a.max.is_finite() && a.min.cmplt(a.max).all()) {
            return invalid(
                "boundary.domain",
                format!("{a:?}"),
                "corners must be finite, min below max on every axis",
            );
        }
        for o in &self.obstacles {
            let ok = match *o {
                Obstacle::Box(b) => {
                    b.min.is_finite() && b.max.is_finite() && b.min.cmplt(b.max).all()
                }
                Obstacle::Sphere { centre, radius } => {
                    centre.is_finite() && radius.is_finite() && radius > 0.0
                }
            };
            if !ok {
                return invalid(
                    "boundary.obstacles",
                    format!("{o:?}"),
                    "must be finite, a box with min below max, a sphere with radius > 0",
                );
            }
        }
        if !(0.0..=1.0).contains(&self.restitution) {
            return invalid(
                "boundary.restitution",
                self.restitution.to_string(),
                "must be in [0, 1]",
            );
        }
        let c = self.clearance;
        if !(c >= 0.0 && 2.0 * c < a.size().min_element()) {
            return invalid(
                "boundary.clearance",
                c.to_string(),
                "must be ≥ 0 (m) and less than half the domain's narrowest side",
            );
        }
        Ok(())
    }

    /// Whether `x` is a valid fluid position: inside the domain, outside obstacles.
    pub fn admits(&self, x: Vec3) -> bool {
        self.domain.contains(x) && !self.obstacles.iter().any(|o| o.contains(x))
    }

    /// Every one of `positions` lies where the boundary admits fluid
    /// ([`Self::admits`]): a solver refuses particles outside the domain or
    /// inside an obstacle, which its first step would move onto a wall, on
    /// top of their neighbours.
    ///
    /// # Errors
    /// [`Error::InvalidParticle`] naming the first such particle.
    pub fn check_admits(&self, positions: &[Vec3]) -> Result<()> {
        match positions.iter().position(|&x| !self.admits(x)) {
            Some(index) => Err(Error::InvalidParticle {
                index,
                what: "position",
                value: format!("{}", positions[index]),
                reason: "lies outside the domain or inside an obstacle",
            }),
            None => Ok(()),
        }
    }

    /// Moves `x` to the nearest position at least [`Boundary::clearance`]
    /// from every wall and obstacle (when it is not one) and reflects the
    /// velocity component into the boundary there by `restitution` (0
    /// removes it).
    #[inline]
    pub fn resolve(&self, x: &mut Vec3, v: &mut Vec3) {
        // Most particles of most scenes: nothing to do, said in two compares.
        let c = Vec3::splat(self.clearance);
        let inside = x.cmpge(self.domain.min + c).all() && x.cmple(self.domain.max - c).all();
        if !inside || !self.obstacles.is_empty() {
            self.resolve_slow(x, v);
        }
    }

    /// [`Self::resolve`] for a point outside the domain, or any point when
    /// there are obstacles.
    #[inline(never)]
    fn resolve_slow(&self, x: &mut Vec3, v: &mut Vec3) {
        // The walls and obstacles moved into the fluid by the clearance.
        let c = self.clearance;
        let (min, max) = (self.domain.min + c, self.domain.max - c);
        // A few rounds settle corners where an obstacle meets a wall.
        for _ in 0..3 {
            let mut moved = false;
            for o in &self.obstacles {
                if let Some((p, n)) = o.grown(c).project(*x) {
                    *x = p;
                    self.reflect(v, n);
                    moved = true;
                }
            }
            for a in 0..3 {
                if x[a] < min[a] {
                    x[a] = min[a];
                    let mut n = Vec3::ZERO;
                    n[a] = 1.0;
                    self.reflect(v, n);
                    moved = true;
                } else if x[a] > max[a] {
                    x[a] = max[a];
                    let mut n = Vec3::ZERO;
                    n[a] = -1.0;
                    self.reflect(v, n);
                    moved = true;
                }
            }
            if !moved {
                break;
            }
        }
    }

    /// Moves `x` to the nearest admitted position when it is not one, as
    /// [`Boundary::resolve`] does, without a velocity to reflect (position-based
    /// solvers derive the velocity from the motion afterwards).
    #[inline]
    pub fn project(&self, x: &mut Vec3) {
        if self.obstacles.is_empty() {
            // The walls alone: each axis back inside, as the first round of
            // `resolve_slow` does (a second finds nothing to move), without
            // its call for the particles on a wall's clearance plane that
            // every push into the wall sends there.
            let c = self.clearance;
            let (min, max) = (self.domain.min + c, self.domain.max - c);
            for a in 0..3 {
                if x[a] < min[a] {
                    x[a] = min[a];
                } else if x[a] > max[a] {
                    x[a] = max[a];
                }
            }
            return;
        }
        let mut v = Vec3::ZERO;
        self.resolve(x, &mut v);
    }

    /// Calls `f(d, n)` for each wall surface within `h` of the admitted point `x`:
    /// its distance `d` and its normal `n` pointing into the fluid. Curved and
    /// box obstacles are taken locally as the plane at their nearest point.
    #[inline(always)]
    pub fn for_each_wall_within(&self, x: Vec3, h: f32, mut f: impl FnMut(f32, Vec3)) {
        for a in 0..3 {
            let mut n = Vec3::ZERO;
            let d = x[a] - self.domain.min[a];
            if d < h {
                n[a] = 1.0;
                f(d.max(0.0), n);
            }
            let d = self.domain.max[a] - x[a];
            if d < h {
                n[a] = -1.0;
                f(d.max(0.0), n);
            }
        }
        for o in &self.obstacles {
            match *o {
                Obstacle::Sphere { centre, radius } => {
                    let r = x - centre;
                    let d = r.length() - radius;
                    if d < h {
                        f(d.max(0.0), r.try_normalize().unwrap_or(Vec3::Y));
                    }
                }
                Obstacle::Box(b) => {
                    // Nearest point of the box; outside it, the offset gives the normal.
                    let q = x.clamp(b.min, b.max);
                    let r = x - q;
                    let d = r.length();
                    if let Some(n) = r.try_normalize().filter(|_| d < h) {
                        f(d, n);
                    }
                }
            }
        }
    }

    /// Removes (1 + restitution) × the velocity component against the normal `n`.
    fn reflect(&self, v: &mut Vec3, n: Vec3) {
        let vn = v.dot(n);
        if vn < 0.0 {
            *v -= (1.0 + self.restitution) * vn * n;
        }
    }
}

/// Integrals of the solver's kernels over the half-space beyond a plane wall at
/// distance d: the density and pressure contributions of fluid "behind" the wall.
/// For the poly6 kernel (WCSPH, PBF: [`WallKernel::new`]) or the cubic spline
/// (DFSPH: [`WallKernel::cubic_spline`]), whichever sums the fluid's density.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WallKernel {
    h: f32,
    shape: Shape,
}

/// The kernel a [`WallKernel`] integrates.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Shape {
    Poly6,
    CubicSpline,
}

/// The layers in which a wall continues the fluid's lattice behind it
/// ([`WallKernel::layers_fraction_and_density`]), from
/// [`WallKernel::lattice_layers`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Layers {
    /// The distance between layers, the lattice's spacing (m).
    pub spacing: f32,
    /// Each layer's fluid volume per unit area (m): V/s² on a lattice
    /// of spacing s, corrected for the in-plane sum.
    pub thickness: f32,
}

impl WallKernel {
    /// For the poly6 kernel of smoothing length `h`.
    pub fn new(h: f32) -> Self {
        Self {
            h,
            shape: Shape::Poly6,
        }
    }

    /// For the cubic spline of support radius `h`
    /// ([`crate::kernels::CubicSpline`]).
    pub fn cubic_spline(h: f32) -> Self {
        Self {
            h,
            shape: Shape::CubicSpline,
        }
    }

    /// The kernel's support radius h.
    pub fn h(&self) -> f32 {
        self.h
    }

    /// ∫ W dV over the half-space beyond a plane at distance `d` (½ at d = 0,
    /// 0 for d ≥ h), in f64.
    pub fn volume_fraction(&self, d: f32) -> f32 {
        let (h, d) = (self.h as f64, d.clamp(0.0, self.h) as f64);
        match self.shape {
            Shape::Poly6 => {
                // ∫_d^h 315/(256 h⁹) (h² − z²)⁴ dz, antiderivative expanded.
                let f = |z: f64| {
                    let (h2, z2) = (h * h, z * z);
                    z * (h2.powi(4) - 4.0 * h2.powi(3) * z2 / 3.0 + 6.0 * h2 * h2 * z2 * z2 / 5.0
                        - 4.0 * h2 * z2.powi(3) / 7.0
                        + z2.powi(4) / 9.0)
                };
                (315.0 / (256.0 * h.powi(9)) * (f(h) - f(d))) as f32
            }
            Shape::CubicSpline => {
                let (a, b) = (1.0 - d / h, (0.5 - d / h).max(0.0));
                (16.0
                    * ((a.powi(5) / 10.0 - a.powi(6) / 15.0)
                        - (b.powi(5) / 5.0 - 4.0 * b.powi(6) / 15.0))) as f32
            }
        }
    }

    /// [`Self::volume_fraction`] and [`Self::plane_density`] at once, in
    /// f32 from the dimensionless form u = d/h (a few ulps from the f64
    /// evaluation): what a solver that needs them every iteration uses.
    #[inline]
    pub fn fraction_and_density(&self, d: f32) -> (f32, f32) {
        let u = (d / self.h).clamp(0.0, 1.0);
        match self.shape {
            Shape::Poly6 => {
                let u2 = u * u;
                // ∫_u^1 (1 − z²)⁴ dz = F(1) − F(u), F(z) = z − 4z³/3 + 6z⁵/5 − 4z⁷/7 + z⁹/9.
                let f =
                    u * (1.0 + u2 * (-4.0 / 3.0 + u2 * (6.0 / 5.0 + u2 * (-4.0 / 7.0 + u2 / 9.0))));
                const F1: f32 = 1.0 - 4.0 / 3.0 + 6.0 / 5.0 - 4.0 / 7.0 + 1.0 / 9.0;
                const C: f32 = 315.0 / 256.0;
                let w = 1.0 - u2;
                let w2 = w * w;
                (C * (F1 - f), C / self.h * w2 * w2)
            }
            Shape::CubicSpline => {
                // With a = 1 − u and b = (½ − u)⁺ (W = 8/(πh³)(2a³ − 8b³)):
                // the plane's integral 2π∫_d^h W r dr = (16/h) G, G = a⁴/2 −
                // 2a⁵/5 − b⁴ + 8b⁵/5, and the half-space's 16 ∫_u^1 G =
                // 16 (a⁵/10 − a⁶/15 − b⁵/5 + 4b⁶/15).
                let (a, b) = (1.0 - u, (0.5 - u).max(0.0));
                let (a4, b4) = (a * a * a * a, b * b * b * b);
                let g = a4 * (0.5 - 0.4 * a) - b4 * (1.0 - 1.6 * b);
                let f = a4 * a * (0.1 - a / 15.0) - b4 * b * (0.2 - 4.0 * b / 15.0);
                (16.0 * f, 16.0 / self.h * g)
            }
        }
    }

    /// The plane's integral ∫ W dA at distance `d` and its slope −d/dd, in
    /// f32: for the radial W, 2π∫_d^h W r dr and 2π d W(d).
    #[inline]
    fn plane_and_slope(&self, d: f32) -> (f32, f32) {
        let inv_h = 1.0 / self.h;
        let u = (d * inv_h).clamp(0.0, 1.0);
        match self.shape {
            Shape::Poly6 => {
                const C: f32 = 315.0 / 256.0;
                let w = 1.0 - u * u;
                let w3 = w * w * w;
                (C * inv_h * w3 * w, 8.0 * C * inv_h * inv_h * u * w3)
            }
            Shape::CubicSpline => {
                let (a, b) = (1.0 - u, (0.5 - u).max(0.0));
                let (a3, b3) = (a * a * a, b * b * b);
                let g = a3 * a * (0.5 - 0.4 * a) - b3 * b * (1.0 - 1.6 * b);
                let w = 2.0 * a3 - 8.0 * b3;
                (16.0 * inv_h * g, 16.0 * inv_h * inv_h * u * w)
            }
        }
    }

    /// The wall as the fluid's own lattice continued behind it: the
    /// kernel-weighted volume fraction of `layers` of fluid, the first half
    /// a spacing behind the plane, at distance `d` from it (each layer
    /// integrated in its plane: t Σ_k ∫ W dA at d + (k + ½) s), and its
    /// slope −d/dd. With the layers of [`Self::lattice_layers`], a particle
    /// of a cubic lattice filled to the wall, half a spacing from it, sums
    /// to the density of the lattice inside, where the continuous half-space
    /// ([`Self::fraction_and_density`]) starts it a few % compressed at h = 2
    /// spacings.
    ///
    /// Layers thinner than h/(2 × [`MAX_H_OVER_SPACING`]) (or of no
    /// positive spacing), which no particle a world accepts has, are the
    /// continuous half-space, [`Self::fraction_and_density`]: the layers'
    /// sum tends to it as they thin, and summing them one by one would take
    /// h/s terms (none at all once s is below an ulp of h, a loop that
    /// never ends).
    ///
    /// [`MAX_H_OVER_SPACING`]: crate::solver::MAX_H_OVER_SPACING
    #[inline]
    pub fn layers_fraction_and_density(&self, d: f32, layers: Layers) -> (f32, f32) {
        let most = 2.0 * crate::solver::MAX_H_OVER_SPACING;
        if !(layers.spacing > 0.0 && self.h / layers.spacing <= most) {
            return self.fraction_and_density(d);
        }
        let (mut f, mut slope) = (0.0, 0.0);
        let mut z = d.max(0.0) + 0.5 * layers.spacing;
        while z < self.h {
            let (p, dp) = self.plane_and_slope(z);
            (f, slope) = (f + p, slope + dp);
            z += layers.spacing;
        }
        (layers.thickness * f, layers.thickness * slope)
    }

    /// The layers of the cubic lattice whose particles weigh `mass` at
    /// `rest_density` with this kernel ([`crate::FluidParams::lattice_mass`]):
    /// - the spacing s is that lattice's, found from the mass by the fixed
    ///   point s ← s (m Σ W / ρ0)^⅓ over the lattice's kernel sum Σ W (a few
    ///   iterations: the sum is about 1/s³ times a slowly varying factor).
    ///   The particle's V^⅓, V = m/ρ0, is 0.3 % short of it for poly6 at
    ///   h = 2 spacings, 3·10⁻⁵ for the cubic spline;
    /// - the thickness t makes the layers' plane integrals sum what the
    ///   lattice's discrete layers sum for a particle half a spacing from
    ///   the wall: t = V Σ_{k≥1} Σ_ij W(i s, j s, k s) / Σ_{k≥1} ∫ W dA at
    ///   k s. It is within a few tenths of a % of V/s², each layer's
    ///   volume per unit area, by which the plane integral over-counts the
    ///   in-plane sum (0.19 % for poly6 at h = 2 spacings).
    ///
    /// So a lattice filled to a wall starts its first layer at the lattice's
    /// density, to rounding. Layers deeper than h/2 see the wall's layers at
    /// distances where t's calibration is approximate (h > 2 spacings).
    /// Where no lattice of that mass is within [`MAX_H_OVER_SPACING`]
    /// (a mass far lighter than any scene's), the layers are V^⅓ apart and
    /// V^⅓ thick, the same volume per particle without the lattice's sums:
    /// layers that thin sum as the continuous half-space
    /// ([`Self::layers_fraction_and_density`]).
    ///
    /// [`MAX_H_OVER_SPACING`]: crate::solver::MAX_H_OVER_SPACING
    pub fn lattice_layers(&self, mass: f32, rest_density: f32) -> Layers {
        let volume = f64::from(mass) / f64::from(rest_density);
        let side = volume.cbrt() as f32;
        let cubes = Layers {
            spacing: side,
            thickness: side,
        };
        if !(side > 0.0 && side.is_finite()) || self.h / side > crate::solver::MAX_H_OVER_SPACING {
            return cubes;
        }
        let sum = |s: f32, layers| match self.shape {
            Shape::Poly6 => Poly6::new(self.h).map(|k| lattice_sum(&k, s, layers)),
            Shape::CubicSpline => CubicSpline::new(self.h).map(|k| lattice_sum(&k, s, layers)),
        };
        let reach = |s: f32| (self.h / s).ceil() as i32;
        let mut s = side;
        for _ in 0..32 {
            let Ok(total) = sum(s, -reach(s)..=reach(s)) else {
                return cubes;
            };
            let next = s * (volume * total).cbrt() as f32;
            let done = (next - s).abs() <= 1e-6 * s;
            s = next;
            if done {
                break;
            }
        }
        if !(s > 0.0 && s.is_finite()) || self.h / s > crate::solver::MAX_H_OVER_SPACING {
            return cubes;
        }
        let Ok(beyond) = sum(s, 1..=reach(s)) else {
            return cubes;
        };
        let planes: f64 = (1..=reach(s))
            .map(|k| f64::from(self.plane_and_slope(k as f32 * s).0))
            .sum();
        let thickness = if planes > 0.0 {
            (volume * beyond / planes) as f32
        } else {
            s
        };
        Layers {
            spacing: s,
            thickness,
        }
    }

    /// −d/dd of [`Self::volume_fraction`]: ∫ W over the plane at distance
    /// `d` (for poly6, 315/(256 h⁹)·(h² − d²)⁴), in f64. The wall force that
    /// conserves energy with the wall density term is m (p/ρ²) ρ0 times this,
    /// along the wall normal.
    pub fn plane_density(&self, d: f32) -> f32 {
        let (h, d) = (self.h as f64, d.clamp(0.0, self.h) as f64);
        match self.shape {
            Shape::Poly6 => (315.0 / (256.0 * h.powi(9)) * (h * h - d * d).powi(4)) as f32,
            Shape::CubicSpline => {
                let (a, b) = (1.0 - d / h, (0.5 - d / h).max(0.0));
                (16.0 / h
                    * ((a.powi(4) / 2.0 - 2.0 * a.powi(5) / 5.0)
                        - (b.powi(4) - 8.0 * b.powi(5) / 5.0))) as f32
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// With a clearance c, the projection leaves every point at least c
    /// from each wall and obstacle surface (a box's faces grown by c), takes
    /// the velocity into them away, and leaves points already clear alone.
    #[test]
    fn the_clearance_keeps_centres_off_walls_and_obstacles() {
        let c = 0.05;
        let mut b = Boundary::new(Aabb::new(Vec3::ZERO, Vec3::ONE)).with_clearance(c);
        let (centre, radius) = (Vec3::splat(0.5), 0.1);
        b.obstacles.push(Obstacle::Sphere { centre, radius });
        let block = Aabb::new(Vec3::new(0.0, 0.0, 0.8), Vec3::new(0.3, 0.3, 1.0));
        b.obstacles.push(Obstacle::Box(block));
        b.validate().unwrap();
        let clear = |x: Vec3| {
            let walls = (x - b.domain.min).min(b.domain.max - x).min_element();
            let sphere = (x - centre).length() - radius;
            let q = x.clamp(block.min, block.max);
            let faces = (x - q).abs().max_element();
            walls.min(sphere).min(faces)
        };
        let points = [
            Vec3::new(0.5, -0.2, 0.5),  // below the floor
            Vec3::new(0.5, 0.01, 0.5),  // inside the floor's clearance
            Vec3::new(0.99, 0.99, 0.5), // an edge
            Vec3::new(0.5, 0.5, 0.62),  // just off the sphere
            Vec3::new(0.5, 0.5, 0.5),   // its centre
            Vec3::new(0.32, 0.1, 0.9),  // just off the box's face
            Vec3::new(0.1, 0.1, 0.9),   // inside the box
        ];
        for x0 in points {
            let (mut x, mut v) = (x0, Vec3::new(0.3, -1.0, 0.2));
            b.resolve(&mut x, &mut v);
            assert!(
                clear(x) >= c - 1e-6,
                "{x0} → {x}: {} from a surface",
                clear(x)
            );
            assert_ne!(x, x0, "{x0} was within the clearance");
        }
        // The floor: pushed to c, the velocity into it gone.
        let (mut x, mut v) = (Vec3::new(0.5, 0.01, 0.5), Vec3::new(0.3, -1.0, 0.2));
        b.resolve(&mut x, &mut v);
        assert_eq!((x, v), (Vec3::new(0.5, c, 0.5), Vec3::new(0.3, 0.0, 0.2)));
        // Clear points stay.
        for x0 in [Vec3::new(0.5, c, 0.5), Vec3::new(0.2, 0.7, 0.3)] {
            let mut x = x0;
            b.project(&mut x);
            assert_eq!(x, x0);
        }
        // A clearance that is negative, not finite or leaves no room.
        for bad in [-0.01, f32::NAN, f32::INFINITY, 0.5] {
            let err = b.clone().with_clearance(bad).validate().unwrap_err();
            assert!(err.to_string().contains("boundary.clearance"), "{err}");
        }
    }

    /// Far from the origin, a few ulps of a small radius are below an ulp of
    /// the position: the projection still gets out of the sphere.
    #[test]
    fn sphere_projection_terminates_far_from_the_origin() {
        let centre = Vec3::new(1e5, 0.0, 0.0);
        let mut b = Boundary::new(Aabb::new(Vec3::splat(-2e5), Vec3::splat(2e5)));
        b.obstacles.push(Obstacle::Sphere {
            centre,
            radius: 0.1,
        });
        let (mut x, mut v) = (centre + Vec3::new(0.05, 0.0, 0.0), Vec3::X);
        b.resolve(&mut x, &mut v);
        assert!(b.admits(x), "{x}");
        assert!((x - centre).length() < 0.12, "{x}");
    }

    /// The half-space integrals of both kernels against a midpoint rule,
    /// their f32 forms against the f64 ones, and the plane density against
    /// the fraction's derivative.
    fn check_wall_kernel(w: WallKernel, kernel: &impl crate::kernels::Kernel) {
        let h = kernel.h();
        assert!((w.volume_fraction(0.0) - 0.5).abs() < 1e-6);
        assert_eq!(w.volume_fraction(h), 0.0);
        for d in [0.0f32, 0.1, 0.2, 0.3] {
            let n = 80;
            let step = 2.0 * h / n as f32;
            let mut vol = 0.0f64;
            for i in 0..n {
                for j in 0..n {
                    for k in 0..n {
                        let p = Vec3::new(i as f32, j as f32, k as f32) * step
                            + Vec3::splat(-h + step / 2.0);
                        if p.y > d {
                            vol += kernel.value(p) as f64;
                        }
                    }
                }
            }
            let dv = (step as f64).powi(3);
            assert!(
                (vol * dv - w.volume_fraction(d) as f64).abs() < 2e-3,
                "d={d}: {}",
                vol * dv
            );
            // The f32 form agrees.
            let (f, p) = w.fraction_and_density(d);
            assert!((f - w.volume_fraction(d)).abs() < 1e-6, "d={d}: {f}");
            let rel = (p - w.plane_density(d)).abs() / w.plane_density(0.0);
            assert!(rel < 1e-6, "d={d}: {p}");
            // The wall force's factor is the derivative of the wall density.
            let e = 1e-3f32;
            let fd =
                (w.volume_fraction(d.max(e) - e) - w.volume_fraction(d.max(e) + e)) / (2.0 * e);
            assert!(
                (fd - w.plane_density(d.max(e))).abs() < 1e-3 * w.plane_density(0.0),
                "d={d}: {fd} vs {}",
                w.plane_density(d.max(e))
            );
        }
    }

    #[test]
    fn wall_kernel_integrals() {
        use crate::kernels::{CubicSpline, Poly6};
        let h = 0.5f32;
        check_wall_kernel(WallKernel::new(h), &Poly6::new(h).unwrap());
        check_wall_kernel(WallKernel::cubic_spline(h), &CubicSpline::new(h).unwrap());
    }

    /// A particle of a cubic lattice half a spacing from a wall, the lattice
    /// filled up to the wall: the layers [`WallKernel::lattice_layers`]
    /// finds from the particles' mass alone are the lattice's spacing, and
    /// the particle's fluid neighbours and the layered wall sum to the
    /// lattice's interior density to rounding (where the continuous
    /// half-space gives 3.8 % more for the cubic spline at h = 2 spacings,
    /// and layers V^⅓ apart and V^⅓ thick 0.40 % more for poly6). The
    /// second layer, which at h > 2 spacings reaches the wall's layers too,
    /// within 0.05 %. The layers' slope is their fraction's derivative.
    #[test]
    fn layered_walls_continue_a_lattice() {
        use crate::kernels::{CubicSpline, Kernel, Poly6};
        let (s, rho0) = (0.02f32, 1000.0f32);
        for (name, h) in [
            ("cubic", 2.0 * s),
            ("cubic", 2.5 * s),
            ("cubic", 3.0 * s),
            ("poly6", 2.0 * s),
            ("poly6", 2.5 * s),
            ("poly6", 3.0 * s),
        ] {
            let (kernel, wall): (Box<dyn Fn(Vec3) -> f32>, _) = if name == "cubic" {
                let k = CubicSpline::new(h).unwrap();
                (Box::new(move |r| k.value(r)), WallKernel::cubic_spline(h))
            } else {
                let k = Poly6::new(h).unwrap();
                (Box::new(move |r| k.value(r)), WallKernel::new(h))
            };
            let n = 4;
            let sum = |layers: std::ops::RangeInclusive<i32>| {
                let mut sum = 0.0f64;
                for i in -n..=n {
                    for j in layers.clone() {
                        for k in -n..=n {
                            sum += kernel(Vec3::new(i as f32, j as f32, k as f32) * s) as f64;
                        }
                    }
                }
                sum
            };
            let inside = sum(-n..=n);
            let mass = (rho0 as f64 / inside) as f32;
            let layers = wall.lattice_layers(mass, rho0);
            assert!(
                (layers.spacing / s - 1.0).abs() < 1e-5,
                "{name} h/s {}: spacing {} for {s}",
                h / s,
                layers.spacing
            );
            let volume = mass as f64 / rho0 as f64;
            let cubes = Layers {
                spacing: volume.cbrt() as f32,
                thickness: volume.cbrt() as f32,
            };
            // Rows j ≥ 0 of the lattice, the wall half a spacing below row 0;
            // rows j ≥ 1 for the second layer.
            for (row, beside, tolerance) in [(0, sum(0..=n), 1e-5), (1, sum(-1..=n), 5e-4)] {
                let d = (row as f32 + 0.5) * s;
                let (f, _) = wall.layers_fraction_and_density(d, layers);
                let rel = (beside * volume + f as f64) / (inside * volume) - 1.0;
                let (old, _) = wall.layers_fraction_and_density(d, cubes);
                let (continuous, _) = wall.fraction_and_density(d);
                println!(
                    "{name} h/s {}, layer {}: layered {:+.4} %, V^⅓ layers {:+.4} %, continuous {:+.4} %",
                    h / s,
                    row + 1,
                    100.0 * rel,
                    100.0 * ((beside * volume + old as f64) / (inside * volume) - 1.0),
                    100.0 * ((beside * volume + continuous as f64) / (inside * volume) - 1.0)
                );
                assert!(
                    rel.abs() < tolerance,
                    "{name} h/s {}, layer {}: {rel}",
                    h / s,
                    row + 1
                );
            }
            for d in [0.0f32, 0.3, 0.9, 1.7] {
                let d = d * s;
                let e = 1e-4 * s;
                let fd = (wall.layers_fraction_and_density(d.max(e) - e, layers).0
                    - wall.layers_fraction_and_density(d.max(e) + e, layers).0)
                    / (2.0 * e);
                let slope = wall.layers_fraction_and_density(d.max(e), layers).1;
                assert!(
                    (fd - slope).abs() < 2e-3 * slope.abs().max(1.0 / h),
                    "{name} d {d}: {fd} vs {slope}"
                );
            }
        }
    }

    /// A mass with no lattice within reach of h gets layers V^⅓ apart and
    /// V^⅓ thick, and so does a mass that is not a positive number.
    #[test]
    fn layers_of_a_mass_without_a_lattice_are_cubes() {
        let wall = WallKernel::new(0.04);
        let tiny = wall.lattice_layers(1e-12, 1000.0);
        assert_eq!(tiny.spacing, tiny.thickness);
        assert!((tiny.spacing - 1e-5).abs() < 1e-9);
        for m in [0.0, -1.0, f32::NAN, f32::INFINITY] {
            let l = wall.lattice_layers(m, 1000.0);
            assert!(!(l.spacing > 0.0 && l.spacing.is_finite()), "{m}: {l:?}");
        }
    }

    /// Layers thinner than h/20 (a particle far lighter than its h's
    /// lattice, 10⁻²⁰ kg at h = 4 cm) are the continuous half-space, where
    /// summing them one by one never ended: 2 × 10⁻⁸ m is below an ulp of
    /// the distances summed.
    #[test]
    fn layers_thinner_than_the_neighbourhood_are_the_half_space() {
        for wall in [WallKernel::new(0.04), WallKernel::cubic_spline(0.04)] {
            for mass in [1e-20f32, 1e-12] {
                let layers = wall.lattice_layers(mass, 1000.0);
                for d in [0.0, 0.005, 0.02, 0.039] {
                    assert_eq!(
                        wall.layers_fraction_and_density(d, layers),
                        wall.fraction_and_density(d),
                        "mass {mass}, d {d}"
                    );
                }
            }
            // Layers within h/20 still sum one by one, close to it.
            let s = 0.04 / 9.5;
            let layers = Layers {
                spacing: s,
                thickness: s,
            };
            let (f, g) = wall.layers_fraction_and_density(0.01, layers);
            let (f0, g0) = wall.fraction_and_density(0.01);
            assert!(
                (f - f0).abs() < 0.02 && (g - g0).abs() < 0.05 * g0,
                "{f} {f0} {g} {g0}"
            );
        }
    }

    #[test]
    fn projection_contains_and_reflects() {
        let mut b = Boundary::new(Aabb::new(Vec3::ZERO, Vec3::ONE));
        b.obstacles.push(Obstacle::Sphere {
            centre: Vec3::splat(0.5),
            radius: 0.2,
        });
        b.obstacles.push(Obstacle::Box(Aabb::new(
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::splat(0.1),
        )));
        for (x0, v0) in [
            (Vec3::new(1.5, 0.5, 0.5), Vec3::X),
            (Vec3::new(0.5, 0.45, 0.5), -Vec3::Y),
            (Vec3::new(0.05, 0.02, 0.05), -Vec3::Y),
            (Vec3::new(-3.0, -2.0, 0.05), Vec3::new(-1.0, -1.0, 0.0)),
        ] {
            let (mut x, mut v) = (x0, v0);
            b.resolve(&mut x, &mut v);
            assert!(b.admits(x), "{x0} → {x}");
            assert!(v.length() <= v0.length() + 1e-6);
        }
        // Inelastic floor: the downward velocity is removed, the tangential kept.
        let (mut x, mut v) = (Vec3::new(0.5, -0.1, 0.5), Vec3::new(1.0, -2.0, 0.0));
        b.resolve(&mut x, &mut v);
        assert_eq!((x.y, v), (0.0, Vec3::new(1.0, 0.0, 0.0)));
    }
}
