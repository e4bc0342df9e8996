//! Boundaries: the box domain and static obstacles (boxes and spheres).
//!
//! Method: position projection with velocity reflection, applied after every
//! integration step. A particle found outside the domain or inside an obstacle is
//! moved to the nearest point of the boundary surface and the part of its velocity
//! pointing into the boundary is removed (times `1 + restitution`). We chose it
//! over penalty forces because it needs no stiffness of its own, so it cannot make
//! the step size smaller or go unstable at the stiffness a dam break needs, and
//! because no speed or step can carry a particle through a wall: containment is
//! exact by construction. The price is a density deficit within h of walls (no
//! boundary particles contribute there, unlike Akinci et al. 2012); the
//! hydrostatic test measures density away from the walls for that reason.

use glam::Vec3;

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

    /// If `x` is inside, the nearest surface point and the outward normal there.
    fn project(&self, x: Vec3) -> Option<(Vec3, Vec3)> {
        if !self.contains(x) {
            return None;
        }
        match *self {
            Obstacle::Sphere { centre, radius } => {
                let d = x - centre;
                let n = d.try_normalize().unwrap_or(Vec3::Y);
                Some((centre + n * radius, n))
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
}

impl Boundary {
    /// A closed box with no obstacles and inelastic walls.
    pub fn new(domain: Aabb) -> Self {
        Self {
            domain,
            obstacles: Vec::new(),
            restitution: 0.0,
        }
    }

    /// Whether `x` is a valid fluid position: inside the domain, outside obstacles.
    pub fn admits(&self, x: Vec3) -> bool {
        self.domain.contains(x) && !self.obstacles.iter().any(|o| o.contains(x))
    }

    /// Moves `x` to the nearest admitted position (when it is not one) and removes
    /// the velocity component into the boundary there.
    pub fn resolve(&self, x: &mut Vec3, v: &mut Vec3) {
        // A few rounds settle corners where an obstacle meets a wall.
        for _ in 0..3 {
            let mut moved = false;
            for o in &self.obstacles {
                if let Some((p, n)) = o.project(*x) {
                    *x = p;
                    self.reflect(v, n);
                    moved = true;
                }
            }
            for a in 0..3 {
                if x[a] < self.domain.min[a] {
                    x[a] = self.domain.min[a];
                    let mut n = Vec3::ZERO;
                    n[a] = 1.0;
                    self.reflect(v, n);
                    moved = true;
                } else if x[a] > self.domain.max[a] {
                    x[a] = self.domain.max[a];
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

    /// Removes (1 + restitution) × the velocity component against the normal `n`.
    fn reflect(&self, v: &mut Vec3, n: Vec3) {
        let vn = v.dot(n);
        if vn < 0.0 {
            *v -= (1.0 + self.restitution) * vn * n;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
