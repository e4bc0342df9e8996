//! The pair sums of the incompressible solvers, eight neighbours at a time:
//! each chunk of a neighbour list is gathered into per-axis lanes, the
//! kernels are evaluated lane by lane, and the sums are kept per lane and
//! added in a fixed tree at the end, so the result depends on neither
//! threads nor CPU.
//!
//! PBF's sums are written over [`F32x8`] lanes ([`Near`],
//! [`LaneKernels::eval`]) and run through [`super::f32x8::par_map`], which
//! compiles them for AVX2 where the CPU has it; so are DFSPH's solve loops.
//! DFSPH's factor pass, which stores each pair's gradient for its solves,
//! still sums plain arrays ([`Chunk`], [`LaneCubic`]) that the compiler
//! vectorises as it can.

use glam::Vec3;

use super::f32x8::F32x8;

use crate::kernels::{CubicSpline, Kernel, Poly6, Spiky};

/// Neighbours per chunk.
pub(super) const LANES: usize = 8;

/// Up to [`LANES`] neighbours of one particle: offsets x_i − x_j per axis
/// and masses. Unused lanes repeat the chunk's first neighbour with no
/// mass, so every sum weighted by the mass gets exact zeros there.
#[derive(Debug, Clone, Copy)]
pub(super) struct Chunk {
    pub(super) d: [[f32; LANES]; 3],
    pub(super) m: [f32; LANES],
}

impl Chunk {
    /// The neighbours `js` (1 to [`LANES`] of them) of the particle at `xi`.
    ///
    /// The lanes are filled by a loop of fixed length, so the compiler keeps
    /// them in registers and vectorises the arithmetic on them.
    #[inline(always)]
    pub(super) fn gather(xi: Vec3, x: &[Vec3], m: &[f32], js: &[u32]) -> Self {
        let (slots, weight) = lanes_of(js);
        let mut c = Chunk {
            d: [[0.0; LANES]; 3],
            m: [0.0; LANES],
        };
        for l in 0..LANES {
            let j = slots[l] as usize;
            let r = xi - x[j];
            (c.d[0][l], c.d[1][l], c.d[2][l]) = (r.x, r.y, r.z);
            c.m[l] = m[j] * weight[l];
        }
        c
    }

    /// |r|² per lane.
    #[inline(always)]
    pub(super) fn r2(&self) -> [f32; LANES] {
        let [x, y, z] = &self.d;
        std::array::from_fn(|l| x[l] * x[l] + y[l] * y[l] + z[l] * z[l])
    }
}

/// Poly6 W and the spiky gradient's factor s (∇W_spiky = s r) per lane, from
/// |r|²: the same formulas as [`Poly6::value_r2`] and
/// [`Spiky::gradient_len`], written without branches.
#[derive(Debug, Clone, Copy)]
pub(super) struct LaneKernels {
    h: f32,
    h2: f32,
    poly6: f32,
    spiky: f32,
    /// The smallest |r| divided by: 1e-6 h.
    tiny: f32,
}

impl LaneKernels {
    pub(super) fn new(poly6: &Poly6, spiky: &Spiky, h: f32) -> Self {
        Self {
            h,
            h2: h * h,
            poly6: poly6.coefficients().0,
            spiky: spiky.coefficient(),
            tiny: h * 1e-6,
        }
    }

    /// (W, s) per lane. Without branches: beyond h both kernels are 0
    /// through the `max`es, and a coincident pair (r = 0) has a finite s
    /// times a zero offset.
    #[inline(always)]
    pub(super) fn eval<S: F32x8>(&self, r2: S) -> (S, S) {
        let zero = S::splat(0.0);
        let d = (S::splat(self.h2) - r2).max(zero);
        let w = S::splat(self.poly6) * d * d * d;
        let len = r2.sqrt();
        let t = (S::splat(self.h) - len).max(zero);
        let s = S::splat(-self.spiky) * t * t / len.max(S::splat(self.tiny));
        (w, s)
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

/// `rows[i]` = (x_i, y_i, z_i, m_i): what [`Near::gather`] reads, one load
/// per neighbour.
pub(super) fn rows_of(x: &[Vec3], m: &[f32], rows: &mut Vec<[f32; 4]>) {
    use rayon::prelude::*;
    x.par_iter()
        .zip(m)
        .map(|(x, &m)| [x.x, x.y, x.z, m])
        .collect_into_vec(rows);
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
    pub(super) fn eval(&self, r2: &[f32; LANES]) -> ([f32; LANES], [f32; LANES]) {
        let mut w = [0.0; LANES];
        let mut s = [0.0; LANES];
        for l in 0..LANES {
            let len = r2[l].sqrt();
            let q = len * self.inv_h;
            let a = (1.0 - q).max(0.0);
            let b = (0.5 - q).max(0.0);
            w[l] = self.k * (2.0 * a * a * a - 8.0 * b * b * b);
            s[l] = self.k * self.inv_h * (24.0 * b * b - 6.0 * a * a) / len.max(self.tiny);
        }
        (w, s)
    }
}

/// A chunk's neighbours spread over the lanes, the first repeated in the
/// unused ones, and each lane's weight: 1 for a neighbour, 0 for a repeat.
#[inline(always)]
pub(super) fn lanes_of(js: &[u32]) -> ([u32; LANES], [f32; LANES]) {
    let mut slots = [js[0]; LANES];
    let mut weight = [0.0; LANES];
    slots[..js.len()].copy_from_slice(js);
    weight[..js.len()].fill(1.0);
    (slots, weight)
}

/// The lanes' sum, in a fixed tree.
#[inline(always)]
pub(super) fn total(a: &[f32; LANES]) -> f32 {
    ((a[0] + a[1]) + (a[2] + a[3])) + ((a[4] + a[5]) + (a[6] + a[7]))
}
