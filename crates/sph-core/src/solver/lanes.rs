//! The pair sums of the PBF and DFSPH stations, eight neighbours at a time: each
//! chunk of a neighbour list is gathered into per-axis lanes, the kernels
//! are evaluated lane by lane on whole arrays, and the sums are kept per
//! lane and added in a fixed tree at the end, so the result depends on
//! neither threads nor CPU. (Compiled for AVX2 as well, with a run-time
//! switch like the grid's, the density solve measured no faster:
//! `examples/pbf_stations.rs` at 3.4–3.7 ms per 10k substep either way, so
//! there is one path.)

use glam::Vec3;

use crate::kernels::{CubicSpline, Kernel, Poly6, Spiky};

/// Neighbours per chunk.
pub(super) const LANES: usize = 8;

/// Up to [`LANES`] neighbours of one particle: offsets x_i − x_j per axis
/// and masses. Unused lanes lie beyond h with no mass, so every kernel
/// gives 0 there.
#[derive(Debug, Clone, Copy)]
pub(super) struct Chunk {
    pub(super) d: [[f32; LANES]; 3],
    pub(super) m: [f32; LANES],
}

impl Chunk {
    /// The neighbours `js` (at most [`LANES`]) of the particle at `xi`;
    /// `far` is an offset beyond the kernels' support.
    #[inline(always)]
    pub(super) fn gather(xi: Vec3, x: &[Vec3], m: &[f32], js: &[u32], far: f32) -> Self {
        let mut c = Chunk {
            d: [[far; LANES]; 3],
            m: [0.0; LANES],
        };
        for (l, &j) in js.iter().enumerate() {
            let j = j as usize;
            let r = xi - x[j];
            (c.d[0][l], c.d[1][l], c.d[2][l]) = (r.x, r.y, r.z);
            c.m[l] = m[j];
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

    /// (W, s) per lane.
    #[inline(always)]
    pub(super) fn eval(&self, r2: &[f32; LANES]) -> ([f32; LANES], [f32; LANES]) {
        let mut w = [0.0; LANES];
        let mut s = [0.0; LANES];
        // Without branches, so that the loop is one vector operation per
        // step: beyond h both kernels are 0 through the `max`es, and a
        // coincident pair (r = 0) has a finite s times a zero offset.
        for l in 0..LANES {
            let d = (self.h2 - r2[l]).max(0.0);
            w[l] = self.poly6 * d * d * d;
            let len = r2[l].sqrt();
            let t = (self.h - len).max(0.0);
            s[l] = -self.spiky * t * t / len.max(self.tiny);
        }
        (w, s)
    }
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

/// The lanes' sum, in a fixed tree.
#[inline(always)]
pub(super) fn total(a: &[f32; LANES]) -> f32 {
    ((a[0] + a[1]) + (a[2] + a[3])) + ((a[4] + a[5]) + (a[6] + a[7]))
}
