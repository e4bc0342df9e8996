//! Smoothing kernels of Müller, Charypar & Gross (2003), thesis eq. 21–23 and
//! Appendix A, with the sign errata of the guide applied: the gradients of poly6 and
//! spiky point *towards* the kernel's centre (they carry a minus sign).
//!
//! Every kernel is normalised, ∫ W dV = 1, and vanishes (with its derivatives) for
//! r > h. Each is a small `Copy` struct holding its precomputed coefficients, so hot
//! loops pay one multiply per term.
//!
//! | kernel | W | ∇W | ∇²W |
//! |---|---|---|---|
//! | [`Poly6`] | 315/(64πh⁹)(h²−r²)³ | −945/(32πh⁹)(h²−r²)² **r** | 945/(32πh⁹)(h²−r²)(7r²−3h²) |
//! | [`Spiky`] | 15/(πh⁶)(h−r)³ | −45/(πh⁶)(h−r)² **r̂** | 90/(πh⁶)(h−r)(2r−h)/r |
//! | [`Viscosity`] | 15/(2πh³)(−q³/2 + q² + 1/2q − 1), q = r/h | −15/(2πh⁴)(1−q)²(3q²+2q+1)/(2q²) **r̂** | 45/(πh⁶)(h−r) |
//! | [`CubicSpline`] (DFSPH) | 8/(πh³)(2a³ − 8b³), a = (1−q)⁺, b = (½−q)⁺ | 8/(πh⁴)(24b² − 6a²) **r̂** | W'' + 2W'/r |
//!
//! [`Neighbourhood::poly6_sums`](crate::Neighbourhood::poly6_sums) sums poly6, its gradient and
//! laplacian over a neighbourhood straight from the grid's candidate rows
//! (`kernels/sums.rs`): the colour field's and WCSPH's density sums.

use glam::Vec3;

use crate::error::{Result, check_kernel_h};

pub(crate) mod sums;
pub use sums::{Poly6Sums, SecondMoment};

/// Σ W(r) over the points r = (i, j, k)·`spacing` of a cubic lattice
/// through the kernel's centre, i and j free and k in `layers` (every point
/// within reach: `-n..=n` for the whole lattice, n = ⌈h/spacing⌉), in f64.
/// What a particle of a lattice sums from its own layers
/// ([`crate::FluidParams::lattice_mass`]) or from those beyond a wall
/// ([`crate::boundary::WallKernel::lattice_layers`]).
pub(crate) fn lattice_sum(
    kernel: &impl Kernel,
    spacing: f32,
    layers: std::ops::RangeInclusive<i32>,
) -> f64 {
    let n = (kernel.h() / spacing).ceil() as i32;
    let mut sum = 0.0f64;
    for k in layers {
        for j in -n..=n {
            for i in -n..=n {
                let r = Vec3::new(i as f32, j as f32, k as f32) * spacing;
                sum += kernel.value(r) as f64;
            }
        }
    }
    sum
}

/// A radially symmetric smoothing kernel with compact support h.
///
/// `r` is always the offset **x − x_j** from the kernel's centre.
pub trait Kernel: Copy + Send + Sync {
    /// Support radius h: the kernel and its derivatives vanish for |r| > h.
    fn h(&self) -> f32;
    /// W(r, h).
    fn value(&self, r: Vec3) -> f32;
    /// ∇W(r, h).
    fn gradient(&self, r: Vec3) -> Vec3;
    /// ∇²W(r, h).
    fn laplacian(&self, r: Vec3) -> f32;
}

/// The poly6 kernel (eq. 21): used for density and the colour field. It depends on
/// r² only, so evaluating it needs no square root.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Poly6 {
    h: f32,
    h2: f32,
    w: f32,
    grad: f32,
}

impl Poly6 {
    /// The kernel for smoothing length `h` (m), within
    /// [`crate::error::KERNEL_H_RANGE`]; other values are an error.
    pub fn new(h: f32) -> Result<Self> {
        check_kernel_h(h)?;
        let h9 = (h as f64).powi(9);
        Ok(Self {
            h,
            h2: h * h,
            w: (315.0 / (64.0 * std::f64::consts::PI * h9)) as f32,
            grad: (945.0 / (32.0 * std::f64::consts::PI * h9)) as f32,
        })
    }

    /// (a, b) with W = a (h² − r²)³, ∇W = −b (h² − r²)² r and
    /// ∇²W = b (h² − r²)(7r² − 3h²).
    #[inline]
    pub fn coefficients(&self) -> (f32, f32) {
        (self.w, self.grad)
    }

    /// W from the squared distance r² (no square root).
    #[inline]
    pub fn value_r2(&self, r2: f32) -> f32 {
        if r2 > self.h2 {
            return 0.0;
        }
        let d = self.h2 - r2;
        self.w * d * d * d
    }

    /// ∇W from the offset `r` and its squared length `r2` (no square root).
    #[inline]
    pub fn gradient_r2(&self, r: Vec3, r2: f32) -> Vec3 {
        if r2 > self.h2 {
            return Vec3::ZERO;
        }
        let d = self.h2 - r2;
        r * (-self.grad * d * d)
    }

    /// ∇²W from the squared distance r² (no square root).
    #[inline]
    pub fn laplacian_r2(&self, r2: f32) -> f32 {
        if r2 > self.h2 {
            return 0.0;
        }
        self.grad * (self.h2 - r2) * (7.0 * r2 - 3.0 * self.h2)
    }
}

impl Kernel for Poly6 {
    fn h(&self) -> f32 {
        self.h
    }
    #[inline]
    fn value(&self, r: Vec3) -> f32 {
        self.value_r2(r.length_squared())
    }
    #[inline]
    fn gradient(&self, r: Vec3) -> Vec3 {
        self.gradient_r2(r, r.length_squared())
    }
    #[inline]
    fn laplacian(&self, r: Vec3) -> f32 {
        self.laplacian_r2(r.length_squared())
    }
}

/// The spiky kernel (eq. 22) of Desbrun & Gascuel: its gradient does not vanish at
/// the centre, so the pressure force keeps particles apart.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Spiky {
    h: f32,
    w: f32,
    grad: f32,
}

impl Spiky {
    /// The gradient's coefficient c: ∇W = −c (h − r)² r/|r|.
    #[inline]
    pub fn coefficient(&self) -> f32 {
        self.grad
    }

    /// The kernel for smoothing length `h` (m), within
    /// [`crate::error::KERNEL_H_RANGE`]; other values are an error.
    pub fn new(h: f32) -> Result<Self> {
        check_kernel_h(h)?;
        let h6 = (h as f64).powi(6);
        Ok(Self {
            h,
            w: (15.0 / (std::f64::consts::PI * h6)) as f32,
            grad: (45.0 / (std::f64::consts::PI * h6)) as f32,
        })
    }

    /// ∇W from the offset `r` and its length `len` = |r| (when the caller already has
    /// it). Zero at r = 0, where the direction is undefined.
    #[inline]
    pub fn gradient_len(&self, r: Vec3, len: f32) -> Vec3 {
        if len > self.h || len <= 0.0 {
            return Vec3::ZERO;
        }
        let d = self.h - len;
        r * (-self.grad * d * d / len)
    }
}

impl Kernel for Spiky {
    fn h(&self) -> f32 {
        self.h
    }
    #[inline]
    fn value(&self, r: Vec3) -> f32 {
        let len = r.length();
        if len > self.h {
            return 0.0;
        }
        let d = self.h - len;
        self.w * d * d * d
    }
    #[inline]
    fn gradient(&self, r: Vec3) -> Vec3 {
        self.gradient_len(r, r.length())
    }
    /// Singular (→ −∞) at r = 0; returns 0 there rather than an infinity.
    #[inline]
    fn laplacian(&self, r: Vec3) -> f32 {
        let len = r.length();
        if len > self.h || len <= 0.0 {
            return 0.0;
        }
        2.0 * self.grad * (self.h - len) * (2.0 * len - self.h) / len
    }
}

/// The viscosity kernel (eq. 23): its laplacian is positive everywhere inside the
/// support, so viscous forces only ever damp relative velocities.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Viscosity {
    h: f32,
    w: f32,
    lap: f32,
}

impl Viscosity {
    /// The laplacian's coefficient c: ∇²W = c (h − r).
    #[inline]
    pub fn coefficient(&self) -> f32 {
        self.lap
    }

    /// The kernel for smoothing length `h` (m), within
    /// [`crate::error::KERNEL_H_RANGE`]; other values are an error.
    pub fn new(h: f32) -> Result<Self> {
        check_kernel_h(h)?;
        let h = h as f64;
        Ok(Self {
            h: h as f32,
            w: (15.0 / (2.0 * std::f64::consts::PI * h.powi(3))) as f32,
            lap: (45.0 / (std::f64::consts::PI * h.powi(6))) as f32,
        })
    }

    /// ∇²W from the distance `len` = |r|.
    #[inline]
    pub fn laplacian_len(&self, len: f32) -> f32 {
        if len > self.h {
            return 0.0;
        }
        self.lap * (self.h - len)
    }
}

impl Kernel for Viscosity {
    fn h(&self) -> f32 {
        self.h
    }
    /// Singular (→ +∞) at r = 0, as in the thesis; returns `f32::INFINITY` there.
    #[inline]
    fn value(&self, r: Vec3) -> f32 {
        let len = r.length();
        if len > self.h {
            return 0.0;
        }
        if len <= 0.0 {
            return f32::INFINITY;
        }
        // −q³/2 + q² + 1/2q − 1 factored as (1−q)³(1+q)/2q: no cancellation near h.
        let q = len / self.h;
        let a = 1.0 - q;
        self.w * a * a * a * (1.0 + q) / (2.0 * q)
    }
    /// Zero at r = 0 by symmetry (the true gradient is singular there).
    #[inline]
    fn gradient(&self, r: Vec3) -> Vec3 {
        let len = r.length();
        if len > self.h || len <= 0.0 {
            return Vec3::ZERO;
        }
        // dW/dr = (w/h)(−3q²/2 + 2q − 1/2q²) = −(w/h)(1−q)²(3q² + 2q + 1)/2q²,
        // factored for accuracy near h; ∇W = (dW/dr / r) r.
        let q = len / self.h;
        let a = 1.0 - q;
        let dw_dr = -self.w / self.h * a * a * (3.0 * q * q + 2.0 * q + 1.0) / (2.0 * q * q);
        r * (dw_dr / len)
    }
    #[inline]
    fn laplacian(&self, r: Vec3) -> f32 {
        self.laplacian_len(r.length())
    }
}

/// The cubic spline kernel (Monaghan 1992) with support radius h, as
/// SPlisHSPlasH writes it: W = k w(q), q = r/h, k = 8/(πh³),
/// w = 6q³ − 6q² + 1 for q ≤ ½ and 2(1 − q)³ for ½ < q ≤ 1. DFSPH sums
/// densities and takes its pressure gradients with it: one kernel for both,
/// so the density change its solves predict is the change the next density
/// sum measures. (Poly6 densities with spiky gradients, PBF's pair, made a
/// resting DFSPH tank boil at 0.1 m/s; poly6's own gradient, which fades
/// inside r = h/√5, let particles pair up under compression.)
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CubicSpline {
    h: f32,
    k: f32,
}

impl CubicSpline {
    /// The kernel for support radius `h` (m), within
    /// [`crate::error::KERNEL_H_RANGE`]; other values are an error.
    pub fn new(h: f32) -> Result<Self> {
        check_kernel_h(h)?;
        Ok(Self {
            h,
            k: (8.0 / (std::f64::consts::PI * (h as f64).powi(3))) as f32,
        })
    }

    /// The coefficient k = 8/(πh³) = W(0).
    #[inline]
    pub fn coefficient(&self) -> f32 {
        self.k
    }

    /// dW/dr at the distance `len`, branch-free in the form the neighbour
    /// sums use: with a = max(1 − q, 0) and b = max(½ − q, 0),
    /// w = 2a³ − 8b³ and dw/dq = −6a² + 24b².
    #[inline]
    pub fn derivative_len(&self, len: f32) -> f32 {
        let q = len / self.h;
        let a = (1.0 - q).max(0.0);
        let b = (0.5 - q).max(0.0);
        self.k / self.h * (24.0 * b * b - 6.0 * a * a)
    }

    /// W at the distance `len`.
    #[inline]
    pub fn value_len(&self, len: f32) -> f32 {
        let q = len / self.h;
        let a = (1.0 - q).max(0.0);
        let b = (0.5 - q).max(0.0);
        self.k * (2.0 * a * a * a - 8.0 * b * b * b)
    }
}

impl Kernel for CubicSpline {
    fn h(&self) -> f32 {
        self.h
    }
    #[inline]
    fn value(&self, r: Vec3) -> f32 {
        self.value_len(r.length())
    }
    /// Zero at r = 0, where dW/dr vanishes.
    #[inline]
    fn gradient(&self, r: Vec3) -> Vec3 {
        let len = r.length();
        if len <= 0.0 {
            return Vec3::ZERO;
        }
        r * (self.derivative_len(len) / len)
    }
    /// ∇²W = W'' + 2W'/r, with d²w/dq² = 12a − 48b (continuous at q = ½).
    #[inline]
    fn laplacian(&self, r: Vec3) -> f32 {
        let len = r.length();
        if len > self.h || len <= 0.0 {
            return 0.0;
        }
        let q = len / self.h;
        let a = (1.0 - q).max(0.0);
        let b = (0.5 - q).max(0.0);
        let second = self.k / (self.h * self.h) * (12.0 * a - 48.0 * b);
        second + 2.0 * self.derivative_len(len) / len
    }
}

/// The three kernels of the solver for one smoothing length.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Kernels {
    /// Density, colour field and its derivatives.
    pub poly6: Poly6,
    /// Pressure gradient with [`crate::PressureKernel::Spiky`] (the thesis's
    /// choice; poly6 is the default).
    pub spiky: Spiky,
    /// Viscosity laplacian.
    pub viscosity: Viscosity,
}

impl Kernels {
    /// All three kernels for smoothing length `h` (m), within
    /// [`crate::error::KERNEL_H_RANGE`]; other values are an error.
    pub fn new(h: f32) -> Result<Self> {
        Ok(Self {
            poly6: Poly6::new(h)?,
            spiky: Spiky::new(h)?,
            viscosity: Viscosity::new(h)?,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Outside [1e-4, 1e3] m the coefficients or sums are not finite, normal f32
    /// values: such an h is an error, not a run that blows up at step 1.
    #[test]
    fn h_outside_the_representable_range_is_an_error() {
        for h in [1e-4, 0.02, 1e3] {
            let k = Kernels::new(h).unwrap();
            let (w, grad) = k.poly6.coefficients();
            for c in [w, grad, k.spiky.coefficient(), k.viscosity.coefficient()] {
                assert!(c.is_normal(), "h = {h}: coefficient {c}");
            }
        }
        for h in [6.5e-5, 2e3, 0.0, f32::NAN] {
            assert!(Kernels::new(h).is_err(), "h = {h}");
        }
    }

    /// ∫ W dV by composite Simpson on the radial integral 4π ∫₀ʰ r² W(r) dr, in f64
    /// over the f32 kernel.
    fn radial_integral(k: &impl Kernel) -> f64 {
        let n = 20_000; // even
        let h = k.h() as f64;
        let dr = h / n as f64;
        let mut sum = 0.0;
        for i in 0..=n {
            let r = i as f64 * dr;
            let f = if i == 0 {
                0.0 // r² W(r) → 0 for every kernel here (viscosity: r²·h/2r → 0)
            } else {
                r * r * k.value(Vec3::new(r as f32, 0.0, 0.0)) as f64
            };
            let w = if i == 0 || i == n {
                1.0
            } else if i % 2 == 1 {
                4.0
            } else {
                2.0
            };
            sum += w * f;
        }
        4.0 * std::f64::consts::PI * sum * dr / 3.0
    }

    /// ∫ W dV by a 3D midpoint rule on a cartesian grid over [−h, h]³ (no use of
    /// symmetry), to check the radial quadrature independently.
    fn cartesian_integral(k: &impl Kernel, n: usize) -> f64 {
        let h = k.h() as f64;
        let d = 2.0 * h / n as f64;
        let mut sum = 0.0;
        for i in 0..n {
            for j in 0..n {
                for l in 0..n {
                    let p = [i, j, l].map(|a| (-h + (a as f64 + 0.5) * d) as f32);
                    sum += k.value(Vec3::from(p)) as f64;
                }
            }
        }
        sum * d * d * d
    }

    const HS: [f32; 4] = [0.01, 0.1, 1.0, 3.7];

    #[test]
    fn kernels_are_normalised() {
        for h in HS {
            let k = Kernels::new(h).unwrap();
            for (name, integral) in [
                ("poly6", radial_integral(&k.poly6)),
                ("spiky", radial_integral(&k.spiky)),
                ("viscosity", radial_integral(&k.viscosity)),
            ] {
                assert!(
                    (integral - 1.0).abs() < 1e-3,
                    "{name} h={h}: ∫W dV = {integral}"
                );
            }
            // Smooth kernels converge fast on a cartesian grid too; the viscosity
            // kernel's 1/r singularity at the centre is left to the radial rule.
            let cubic = CubicSpline::new(h).unwrap();
            let radial = radial_integral(&cubic);
            assert!((radial - 1.0).abs() < 1e-3, "cubic h={h}: ∫W dV = {radial}");
            for (name, integral) in [
                ("poly6", cartesian_integral(&k.poly6, 120)),
                ("spiky", cartesian_integral(&k.spiky, 120)),
                ("cubic", cartesian_integral(&cubic, 120)),
            ] {
                assert!(
                    (integral - 1.0).abs() < 1e-3,
                    "{name} h={h}: cartesian ∫W dV = {integral}"
                );
            }
        }
    }

    /// Offsets inside the support, away from r = 0 and r = h.
    fn sample_offsets(h: f32) -> Vec<Vec3> {
        let mut v = Vec::new();
        for &q in &[0.15f32, 0.3, 0.5, 0.7, 0.9] {
            for dir in [
                Vec3::X,
                Vec3::new(0.3, -0.5, 0.81).normalize(),
                Vec3::new(-0.7, 0.2, -0.1).normalize(),
            ] {
                v.push(dir * (q * h));
            }
        }
        v
    }

    /// Central finite differences of `k.value` (f32 kernel, f64 arithmetic): the
    /// gradient with step 1e-3 h; the laplacian by Richardson extrapolation of the
    /// second difference at steps 2e-2 h and 1e-2 h (error O(step⁴)), since the
    /// viscosity kernel's h/2r term is harmonic: its large per-axis second
    /// derivatives cancel, and plain O(step²) truncation would swamp the sum.
    fn finite_differences(k: &impl Kernel, r: Vec3) -> (Vec3, f32) {
        let f = |p: Vec3| k.value(p) as f64;
        let eg = 1e-3 * k.h();
        let f0 = f(r);
        let second = |e: f32| {
            (0..3)
                .map(|a| {
                    let mut d = Vec3::ZERO;
                    d[a] = e;
                    (f(r + d) - 2.0 * f0 + f(r - d)) / (e as f64 * e as f64)
                })
                .sum::<f64>()
        };
        let (l1, l2) = (second(2e-2 * k.h()), second(1e-2 * k.h()));
        let lap = (4.0 * l2 - l1) / 3.0;
        let mut g = [0.0; 3];
        for (a, ga) in g.iter_mut().enumerate() {
            let mut d = Vec3::ZERO;
            d[a] = eg;
            *ga = (f(r + d) - f(r - d)) / (2.0 * eg as f64);
        }
        (Vec3::new(g[0] as f32, g[1] as f32, g[2] as f32), lap as f32)
    }

    fn check_derivatives(name: &str, k: &impl Kernel) {
        let h = k.h();
        // The cubic spline's third derivative jumps at q = ½, where the
        // extrapolated second differences lose their order: sample beside it.
        let offsets = sample_offsets(h).into_iter().filter(|r| {
            let q = r.length() / h;
            !(name == "cubic" && (q - 0.5).abs() < 0.05)
        });
        for r in offsets.chain([0.45, 0.55].map(|q| Vec3::Y * (q * h))) {
            let (g_fd, l_fd) = finite_differences(k, r);
            let g = k.gradient(r);
            // Scale tolerances by the kernel's magnitude at this h.
            let scale_g = k.gradient(r).length().max(g_fd.length()).max(1e-30);
            assert!(
                (g - g_fd).length() <= 2e-3 * scale_g,
                "{name} h={h} r={r}: ∇W = {g}, finite differences {g_fd}"
            );
            let l = k.laplacian(r);
            // The laplacian crosses zero (spiky at r = h/2): scale by the gradient / h too.
            let scale_l = l.abs().max(l_fd.abs()).max(scale_g / h);
            assert!(
                (l - l_fd).abs() <= 1e-2 * scale_l,
                "{name} h={h} r={r}: ∇²W = {l}, finite differences {l_fd}"
            );
        }
    }

    #[test]
    fn derivatives_match_finite_differences() {
        for h in [0.1f32, 1.0, 2.5] {
            let k = Kernels::new(h).unwrap();
            check_derivatives("poly6", &k.poly6);
            check_derivatives("spiky", &k.spiky);
            check_derivatives("viscosity", &k.viscosity);
            check_derivatives("cubic", &CubicSpline::new(h).unwrap());
        }
    }

    #[test]
    fn gradients_point_to_the_centre() {
        // The errata: ∇W_poly6 and ∇W_spiky are anti-parallel to r.
        let k = Kernels::new(1.0).unwrap();
        let r = Vec3::new(0.3, 0.2, -0.1);
        assert!(k.poly6.gradient(r).dot(r) < 0.0);
        assert!(k.spiky.gradient(r).dot(r) < 0.0);
        assert!(k.viscosity.gradient(r).dot(r) < 0.0);
        assert!(k.viscosity.laplacian(r) > 0.0);
        assert!(CubicSpline::new(1.0).unwrap().gradient(r).dot(r) < 0.0);
    }

    #[test]
    fn everything_vanishes_beyond_h() {
        for h in HS {
            let k = Kernels::new(h).unwrap();
            for q in [1.0001f32, 1.5, 10.0] {
                let r = Vec3::new(0.6, -0.48, 0.64) * (q * h);
                assert_eq!(k.poly6.value(r), 0.0);
                assert_eq!(k.poly6.gradient(r), Vec3::ZERO);
                assert_eq!(k.poly6.laplacian(r), 0.0);
                assert_eq!(k.spiky.value(r), 0.0);
                assert_eq!(k.spiky.gradient(r), Vec3::ZERO);
                assert_eq!(k.spiky.laplacian(r), 0.0);
                assert_eq!(k.viscosity.value(r), 0.0);
                assert_eq!(k.viscosity.gradient(r), Vec3::ZERO);
                assert_eq!(k.viscosity.laplacian(r), 0.0);
                let cubic = CubicSpline::new(h).unwrap();
                assert_eq!(cubic.value(r), 0.0);
                assert_eq!(cubic.gradient(r), Vec3::ZERO);
                assert_eq!(cubic.laplacian(r), 0.0);
            }
            // Continuity at the support edge: values go to zero at r = h.
            let edge = Vec3::X * h;
            assert!(k.poly6.value(edge).abs() < 1e-6 * k.poly6.value(Vec3::ZERO));
            assert!(k.spiky.value(edge).abs() < 1e-6 * k.spiky.value(Vec3::ZERO));
            assert!(k.viscosity.value(edge).abs() < 1e-5 * k.viscosity.value(edge * 0.1));
        }
    }

    #[test]
    fn poly6_r_squared_forms_match_the_closed_form() {
        // The |r|²-only entry points the neighbour sums use, against
        // W = 315/(64π h⁹)(h² − r²)³ and ∇W = −945/(32π h⁹)(h² − r²)² r in f64.
        let h = 0.7f64;
        let k = Poly6::new(h as f32).unwrap();
        for r in sample_offsets(h as f32) {
            let r2 = r.as_dvec3().length_squared();
            let t = (h * h - r2).max(0.0);
            let w = 315.0 / (64.0 * std::f64::consts::PI * h.powi(9)) * t.powi(3);
            let g = -945.0 / (32.0 * std::f64::consts::PI * h.powi(9)) * t * t * r.as_dvec3();
            let got = k.value_r2(r.length_squared()) as f64;
            assert!(
                (got - w).abs() <= 1e-5 * w.abs().max(1e-3),
                "{r}: {got} vs {w}"
            );
            let got = k.gradient_r2(r, r.length_squared()).as_dvec3();
            assert!(
                (got - g).length() <= 1e-5 * g.length().max(1e-3),
                "{r}: {got} vs {g}"
            );
        }
    }

    #[test]
    fn bad_h_is_an_error() {
        for h in [0.0, -1.0, f32::NAN, f32::INFINITY] {
            let e = Kernels::new(h).unwrap_err();
            assert!(e.to_string().contains("`h`"), "{e}");
        }
    }
}
