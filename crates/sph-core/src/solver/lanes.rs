//! The pair sums of the incompressible solvers, eight neighbours at a time:
//! each chunk of a neighbour list is gathered into per-axis lanes, the
//! kernels are evaluated lane by lane, and the sums are kept per lane and
//! added in a fixed tree at the end, so the result depends on neither
//! threads nor CPU.
//!
//! The sums are written over [`F32x8`] lanes: here the chunk's gather
//! ([`Near`]) and the kernels per lane ([`LaneKernels`] for PBF,
//! [`LaneCubic`] for DFSPH); the passes run through
//! [`super::lane_map::par_map`] and [`super::lane_map::par_map_rows`], which pick
//! the lanes the CPU has.

use glam::Vec3;

use super::free_surface::SurfaceTarget;
use crate::simd::{F32x8, Scalar};

use crate::kernels::{CubicSpline, Kernel, Poly6, Spiky};

/// Neighbours per chunk.
pub(super) const LANES: usize = 8;

/// PBF's pair kernels per lane, from |r|²: W and the gradient's factor s
/// (∇W = s r).
#[derive(Debug, Clone, Copy)]
pub(super) enum LaneKernels {
    /// Poly6 W and spiky's s, the same formulas as [`Poly6::value_r2`] and
    /// [`Spiky::gradient_len`] written without branches (Jacobi's pair).
    Poly6Spiky {
        h: f32,
        h2: f32,
        poly6: f32,
        spiky: f32,
        /// The smallest |r| divided by: 1e-6 h.
        tiny: f32,
    },
    /// The cubic spline's W and its own gradient (Gauss–Seidel's).
    Cubic(LaneCubic),
}

impl LaneKernels {
    pub(super) fn poly6_spiky(poly6: &Poly6, spiky: &Spiky, h: f32) -> Self {
        Self::Poly6Spiky {
            h,
            h2: h * h,
            poly6: poly6.coefficients().0,
            spiky: spiky.coefficient(),
            tiny: h * 1e-6,
        }
    }

    /// The free surface's target for a cubic lattice of `spacing` and
    /// particles of volume `volume` under these kernels
    /// ([`SurfaceTarget::lattice`]).
    pub(super) fn surface_target(&self, h: f32, spacing: f32, volume: f32) -> SurfaceTarget {
        // W and dW/dr = s r from the lanes' own formulas, one lane used.
        let at = |r: f32| {
            let (w, s) = self.eval(Scalar::splat(r * r));
            (w.to_array()[0], s.to_array()[0] * r)
        };
        SurfaceTarget::lattice(h, spacing, volume, |r| at(r).0, |r| at(r).1)
    }

    /// (W, s) per lane. Without branches within a kind: beyond h both
    /// kernels are 0 through the `max`es, and a coincident pair (r = 0)
    /// has a finite s times a zero offset.
    #[inline(always)]
    pub(super) fn eval<S: F32x8>(&self, r2: S) -> (S, S) {
        match self {
            Self::Cubic(cubic) => cubic.eval(r2),
            &Self::Poly6Spiky {
                h,
                h2,
                poly6,
                spiky,
                tiny,
            } => {
                let zero = S::splat(0.0);
                let d = (S::splat(h2) - r2).max(zero);
                let w = S::splat(poly6) * d * d * d;
                let len = r2.sqrt();
                let t = (S::splat(h) - len).max(zero);
                let s = S::splat(-spiky) * t * t / len.max(S::splat(tiny));
                (w, s)
            }
        }
    }
}

/// Up to eight neighbours of one particle in lanes: offsets x_i − x_j per
/// axis, masses, and the neighbours' indices. Unused lanes hold other
/// particles with no mass, so every sum weighted by the mass gets exact
/// zeros there.
#[derive(Debug, Clone, Copy)]
pub(super) struct Near<S> {
    pub(super) d: [S; 3],
    pub(super) m: S,
    pub(super) slots: [u32; LANES],
}

impl<S: F32x8> Near<S> {
    /// A chunk of neighbours of the particle at `xi`, from `rows` of
    /// (x, y, z, m) per particle ([`rows_of`]): `slots` as
    /// [`crate::NeighbourLists::lanes`] gives them, the first `count` of
    /// them the particle's (the others get no mass).
    #[inline(always)]
    pub(super) fn gather(
        xi: [f32; 4],
        rows: &[[f32; 4]],
        slots: &[u32; LANES],
        count: usize,
    ) -> Self {
        let [x, y, z, m] = S::gather_rows(rows, slots);
        Near {
            d: [
                S::splat(xi[0]) - x,
                S::splat(xi[1]) - y,
                S::splat(xi[2]) - z,
            ],
            m: m * S::first(count),
            slots: *slots,
        }
    }

    /// |r|² per lane.
    #[inline(always)]
    pub(super) fn r2(&self) -> S {
        let [x, y, z] = self.d;
        x * x + y * y + z * z
    }
}

/// The per-lane sums of a density constraint over a particle's neighbours
/// j (PBF's λ pass, DFSPH's factors): ρ = Σ m_j W_ij, the gradient
/// Σ G_ij and Σ |G_ij|², with G_ij = (m_j/ρ0)∇W_ij.
#[derive(Debug, Clone, Copy)]
pub(super) struct DensitySums<S> {
    /// ρ, G by axis, |G|², per lane.
    acc: [S; 5],
}

impl<S: F32x8> DensitySums<S> {
    #[inline(always)]
    pub(super) fn new() -> Self {
        Self {
            acc: [S::splat(0.0); 5],
        }
    }

    /// Adds a chunk of neighbours `c` with its kernel values `w` and
    /// gradient factors `s` (∇W = s r); returns its G_ij by axis.
    #[inline(always)]
    pub(super) fn add(&mut self, c: &Near<S>, w: S, s: S, inv_rho0: S) -> [S; 3] {
        let acc = &mut self.acc;
        let f = s * c.m * inv_rho0;
        // Element by element, not `array::map`: the closure it takes is
        // compiled apart from the caller's target features and `map` is not
        // inlined, so the lanes' intrinsics would become calls.
        let g = [c.d[0] * f, c.d[1] * f, c.d[2] * f];
        acc[0] = acc[0] + c.m * w;
        acc[1] = acc[1] + g[0];
        acc[2] = acc[2] + g[1];
        acc[3] = acc[3] + g[2];
        acc[4] = acc[4] + (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]);
        g
    }

    /// (Σ m_j W_ij, Σ G_ij, Σ |G_ij|²), each lane sum in the fixed tree.
    #[inline(always)]
    pub(super) fn finish(self) -> (f32, Vec3, f32) {
        let [rho, x, y, z, squares] = self.acc;
        (
            rho.sum(),
            Vec3::new(x.sum(), y.sum(), z.sum()),
            squares.sum(),
        )
    }
}

/// `rows[i]` = (x_i, y_i, z_i, m_i): what [`Near::gather`] reads, one load
/// per neighbour.
pub(super) fn rows_of(x: &[Vec3], m: &[f32], rows: &mut Vec<[f32; 4]>) {
    rows.resize(x.len(), [0.0; 4]);
    crate::region::for_each(rows, |i, row| *row = [x[i].x, x[i].y, x[i].z, m[i]]);
}

/// The smallest of `masses` (∞ for none), in one parallel pass: what the
/// widest neighbourhood's spacing is taken from.
pub(super) fn lightest(masses: &[f32]) -> f32 {
    let min = |m: &[f32]| m.iter().copied().fold(f32::INFINITY, f32::min);
    min(&crate::region::map_blocks(
        masses.len(),
        |r| min(&masses[r]),
    ))
}

/// The cubic spline's W and gradient factor s (∇W = s r) per lane, from
/// |r|²: the formulas of [`CubicSpline`], without branches (DFSPH's pair
/// sums).
#[derive(Debug, Clone, Copy)]
pub(super) struct LaneCubic {
    inv_h: f32,
    /// 8/(πh³).
    k: f32,
    /// The smallest |r| divided by: 1e-6 h.
    tiny: f32,
}

impl LaneCubic {
    pub(super) fn new(cubic: &CubicSpline) -> Self {
        let h = cubic.h();
        Self {
            inv_h: 1.0 / h,
            k: cubic.coefficient(),
            tiny: h * 1e-6,
        }
    }

    /// (W, s) per lane. Beyond h both are 0 through the `max`es; a
    /// coincident pair (r = 0) has a finite s times a zero offset.
    #[inline(always)]
    pub(super) fn eval<S: F32x8>(&self, r2: S) -> (S, S) {
        let zero = S::splat(0.0);
        let len = r2.sqrt();
        let q = len * S::splat(self.inv_h);
        let a = (S::splat(1.0) - q).max(zero);
        let b = (S::splat(0.5) - q).max(zero);
        let w = S::splat(self.k) * (S::splat(2.0) * a * a * a - S::splat(8.0) * b * b * b);
        let s = S::splat(self.k * self.inv_h) * (S::splat(24.0) * b * b - S::splat(6.0) * a * a)
            / len.max(S::splat(self.tiny));
        (w, s)
    }
}

/// The lane passes' test block: 9 × 7 × 8 particles at 0.02 m, each
/// jittered by up to ±0.002 m, its corner 0.002 m from the origin (so the
/// walls of a domain from the origin count); masses 0.008 kg ± 5 % and
/// velocities in [−0.5, 0.5)³ m/s, all from a fixed hash.
#[cfg(test)]
pub(super) fn jittered_block() -> (Vec<Vec3>, Vec<f32>, Vec<Vec3>) {
    let hash = |i: u32, k: u32| {
        ((i.wrapping_mul(2_654_435_761) ^ k.wrapping_mul(40_503)) % 1000) as f32 / 1000.0
    };
    let mut x = Vec::new();
    for i in 0..9u32 {
        for j in 0..7u32 {
            for k in 0..8u32 {
                let n = x.len() as u32;
                let jitter = Vec3::new(hash(n, 1), hash(n, 2), hash(n, 3)) - 0.5;
                x.push(Vec3::new(i as f32, j as f32, k as f32) * 0.02 + 0.004 * jitter + 0.002);
            }
        }
    }
    let m = (0..x.len() as u32)
        .map(|i| 0.008 * (1.0 + 0.1 * hash(i, 4)))
        .collect();
    let v = (0..x.len() as u32)
        .map(|i| Vec3::new(hash(i, 5), hash(i, 6), hash(i, 7)) - 0.5)
        .collect();
    (x, m, v)
}
