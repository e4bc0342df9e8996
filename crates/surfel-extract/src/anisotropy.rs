//! Anisotropic kernels for the surface field (Yu & Turk 2013, "Reconstructing
//! surfaces of particle-based fluids using anisotropic kernels", ACM TOG
//! 32(1)): each particle's kernel is stretched along its neighbourhood's
//! principal directions, so that a flat surface is drawn by flat kernels
//! and the particle scale's bumps disappear.
//!
//! Per particle i, over its neighbours j within r = 1.5h (itself included),
//! with the paper's weights w_ij = 1 − (|x_i − x_j|/r)³:
//! 1. the weighted mean x_i^w = Σ w_ij x_j / Σ w_ij, and the **smoothed
//!    kernel centre** x̄_i: the paper's (1 − λ) x_i + λ x_i^w (eq. 6), or by
//!    default λ of the way to its own layer's mean height ([`Centres`]);
//! 2. the **weighted covariance** C_i = Σ w_ij (x_j − x_i^w)(x_j − x_i^w)ᵀ /
//!    Σ w_ij (eq. 7), decomposed C_i = R diag(σ₁, σ₂, σ₃) Rᵀ, σ₁ ≥ σ₂ ≥ σ₃;
//! 3. the eigenvalues **clamped** to at least σ₁/k_r, so that no kernel is
//!    thinner than 1/√k_r of its length (eq. 8); with fewer than N_ε
//!    neighbours the covariance says little and the kernel is isotropic,
//!    k_n h in radius;
//! 4. the kernel W(r, G) = det(G) W(|G r|) (eq. 9) with
//!    G = R diag(√(σ₁/σ̃ₖ)) Rᵀ.
//!
//! Three choices differ from the paper, each measured on a settled pool
//! (`cargo run --release -p surfel-extract --example flat_pool`). First, the
//! paper's smoothing moves a surface particle towards its neighbourhood's
//! mean, which lies inside the fluid: the pool's surface moved in and it
//! lost 25 % of its volume. The default [`Centres::Layer`] smooths only
//! across the surface, within the particle's own layer: the enclosed
//! volume stays within 1 % of N m/ρ0, and the top's normals lean 0.89°
//! from vertical at the median (the isotropic field's: 1.49°). Second, the kernel's axes are proportional to
//! the neighbourhood's standard deviations √σ̃ₖ, not to its variances σ̃ₖ:
//! with the paper's G = R diag(σ₁/σ̃ₖ) Rᵀ the top layer of a settled pool
//! (neighbourhoods of radius h = 2 spacings, variances about 3.4 : 1) got
//! kernels a quarter of h thick, and the field rose and fell in bands from
//! layer to layer (c from 0.6 to 2.2 within a spacing; `examples/flat_pool.rs`
//! with that line changed), which sent half the extractor's Newton steps
//! out of range. Third, the paper's Σ̃ = k_s diag(σ̃) scales each
//! kernel by k_s σ₁, a constant in the paper's units that makes a full
//! neighbourhood's kernel about isotropic. Here the longest axis of every
//! kernel is h itself (G's smallest eigenvalue is 1): a bulk particle's
//! kernel is the thesis's isotropic one exactly, whatever the spacing,
//! and every kernel's support stays within h of its centre, so the field
//! is evaluated through the same neighbour grid as the isotropic one.
//! det(G) ≥ 1 keeps each kernel's integral at 1, so the field still sums
//! the particles' volumes.

use glam::{DMat3, DVec3, Mat3, Vec3};
use sph_core::error::positive;
use sph_core::grid::{CHUNK_LANES, reduce_halves};
use sph_core::simd::{F32x8, LaneFn, with_lanes};
use sph_core::{Error, NeighbourGrid, Neighbourhood, Result};

/// The anisotropic kernels' parameters (Yu & Turk 2013's λ, k_r, N_ε, k_n;
/// the paper's k_s is replaced by normalising each kernel's longest axis to
/// h, see the module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Anisotropy {
    /// λ of the kernel centres' smoothing x̄ = (1 − λ)x + λ x^w, in [0, 1]:
    /// 0 keeps the particles' positions. Default 0.9 (the paper's).
    pub smoothing: f32,
    /// k_r: the most the neighbourhood's largest variance may exceed its
    /// smallest in the kernel, ≥ 1 (1 makes every kernel isotropic); the
    /// kernel's axes are in the ratio of the standard deviations, so at
    /// most √k_r : 1. Default 2. The paper's 4 made a little flatter pools
    /// (0.76° against 0.88° at the median on the DFSPH pool) but thin
    /// kernels whose field dipped below the iso value between layers:
    /// 1,341 Newton steps discarded on that pool (2 at k_r = 2), and
    /// internal voids in a slab three particles deep (coverage of the
    /// field's iso-surface 96.6 % on the reference render's dam-break
    /// frame, 98.8 % at k_r = 2; `examples/flat_pool.rs`).
    pub max_ratio: f32,
    /// N_ε: a particle with fewer neighbours than this within h (itself not
    /// counted) gets an isotropic kernel of radius `isolated_scale` × h.
    /// Default 4: the paper's 25 is for a neighbourhood of radius 2h, about
    /// 8 times as many particles as the h of this field holds.
    pub min_neighbours: u32,
    /// k_n: an isolated particle's kernel radius as a fraction of h, in
    /// [0.05, 1]. Default 0.5 (the paper's).
    pub isolated_scale: f32,
    /// The radius r of the neighbourhoods whose mean and covariance shape
    /// the kernels, in units of h, in [1, 4]. Default 1.5. The paper's 2h
    /// is a little flatter on a settled pool (0.82° against 0.89° at the
    /// median) and costs 1.6 times as much (100k particles: the kernel pass
    /// 154 ms against 94 ms on two cores); r = h is less flat (1.31°;
    /// `cargo run --release -p surfel-extract --example flat_pool`,
    /// 2026-11-26).
    pub radius: f32,
    /// Where the smoothing moves the kernel centres.
    pub centres: Centres,
}

/// How [`Anisotropy::smoothing`] moves a kernel centre.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Centres {
    /// The paper's: towards the neighbourhood's weighted mean. At a
    /// surface that mean lies inside the fluid, so the surface moves in:
    /// a settled pool enclosed 0.831 of its volume at r = 1.5h, λ = 0.9.
    Mean,
    /// Across the surface only: along the neighbourhood's normal (its
    /// covariance's smallest axis) towards the weighted mean height of the
    /// neighbours in the particle's own layer, those within `thickness` × h
    /// of its plane (weighted by (1 − (t/τ)²)² besides the paper's weight).
    /// The particle scale's bumps are smoothed away and the layer stays
    /// where it is: the same pool enclosed 0.990 × its volume.
    Layer {
        /// The layer's half-thickness τ, in units of h, in (0, 1]. Default
        /// 0.35 (0.7 spacings at h = 2 spacings): wide enough for a noisy
        /// layer's heights, narrow enough that the layer below (a spacing
        /// down) adds almost nothing. At 0.5 a WCSPH pool's top came out a
        /// little flatter (6.6° against 7.4° at the median) but a lattice's
        /// jittered top layer was pulled towards the layer below it.
        thickness: f32,
    },
}

impl Default for Anisotropy {
    fn default() -> Self {
        Self {
            smoothing: 0.9,
            max_ratio: 2.0,
            min_neighbours: 4,
            isolated_scale: 0.5,
            radius: 1.5,
            centres: Centres::Layer { thickness: 0.35 },
        }
    }
}

impl Anisotropy {
    /// Checks every field; the error names it (`anisotropy.smoothing`, ...).
    pub fn validate(&self) -> Result<()> {
        let bad = |name, value: f32, reason| {
            Err(Error::InvalidParameter {
                name,
                value: value.to_string(),
                reason,
            })
        };
        if !(0.0..=1.0).contains(&self.smoothing) {
            return bad("anisotropy.smoothing", self.smoothing, "must lie in [0, 1]");
        }
        if !(self.max_ratio >= 1.0 && self.max_ratio <= 100.0) {
            return bad(
                "anisotropy.max_ratio",
                self.max_ratio,
                "must lie in [1, 100]",
            );
        }
        if self.min_neighbours > 1000 {
            return bad(
                "anisotropy.min_neighbours",
                self.min_neighbours as f32,
                "must be at most 1000",
            );
        }
        if !(1.0..=4.0).contains(&self.radius) {
            return bad("anisotropy.radius", self.radius, "must lie in [1, 4] (× h)");
        }
        if let Centres::Layer { thickness } = self.centres
            && !(thickness > 0.0 && thickness <= 1.0)
        {
            return bad(
                "anisotropy.centres.thickness",
                thickness,
                "must lie in (0, 1] (× h)",
            );
        }
        positive("anisotropy.isolated_scale", self.isolated_scale)?;
        if !(0.05..=1.0).contains(&self.isolated_scale) {
            return bad(
                "anisotropy.isolated_scale",
                self.isolated_scale,
                "must lie in [0.05, 1] (a fraction of h): a droplet's sphere far smaller than \
                 its particle draws it as a dot, and near 1e-12 det G = 1/k_n³ overflows f32",
            );
        }
        Ok(())
    }
}

/// One particle's kernel shape: W(r) = det · W_poly6(√(rᵀ M r)) about its
/// centre, with M = G² (dimensionless, eigenvalues ≥ 1).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ellipsoid {
    /// G², as [xx, xy, xz, yy, yz, zz].
    pub m: [f32; 6],
    /// det G ≥ 1.
    pub det: f32,
    /// Whether this is an isolated particle's sphere (fewer than N_ε
    /// neighbours), which draws a droplet.
    pub isolated: bool,
}

impl Ellipsoid {
    /// The isotropic kernel of radius h.
    pub const ISOTROPIC: Self = Self {
        m: [1.0, 0.0, 0.0, 1.0, 0.0, 1.0],
        det: 1.0,
        isolated: false,
    };

    /// An isolated particle's kernel: isotropic, of radius `scale` × h.
    pub fn sphere(scale: f32) -> Self {
        let s = 1.0 / (scale * scale);
        Self {
            m: [s, 0.0, 0.0, s, 0.0, s],
            det: 1.0 / (scale * scale * scale),
            isolated: true,
        }
    }

    /// M r.
    #[inline]
    pub fn apply(&self, r: Vec3) -> Vec3 {
        let [xx, xy, xz, yy, yz, zz] = self.m;
        Vec3::new(
            xx * r.x + xy * r.y + xz * r.z,
            xy * r.x + yy * r.y + yz * r.z,
            xz * r.x + yz * r.y + zz * r.z,
        )
    }

    /// tr M.
    #[inline]
    pub fn trace(&self) -> f32 {
        self.m[0] + self.m[3] + self.m[5]
    }

    /// The kernel of a neighbourhood with weighted covariance `c` (any
    /// units): its eigenvalues clamped to at least 1/`max_ratio` of the
    /// largest and normalised by it, G = R diag(√(σ₁/σ̃)) Rᵀ. A zero or
    /// non-finite covariance gives `None`.
    pub fn from_covariance(c: Mat3, max_ratio: f32) -> Option<Self> {
        Principal::of(c).map(|p| Self::from_principal(&p, max_ratio))
    }

    /// The kernel of a neighbourhood's principal axes (see
    /// [`Ellipsoid::from_covariance`]).
    fn from_principal(p: &Principal, max_ratio: f32) -> Self {
        let largest = p.variances[0];
        let floor = largest / f64::from(max_ratio);
        // G² = R diag(σ₁/σ̃) Rᵀ.
        let mut g2 = DMat3::ZERO;
        let mut det = 1.0f64;
        for k in 0..3 {
            let g2k = largest / p.variances[k].max(floor);
            det *= g2k.sqrt();
            let v = p.axes[k].as_dvec3();
            g2 += DMat3::from_cols(v * v.x, v * v.y, v * v.z) * g2k;
        }
        Self {
            m: [
                g2.x_axis.x as f32,
                g2.y_axis.x as f32,
                g2.z_axis.x as f32,
                g2.y_axis.y as f32,
                g2.z_axis.y as f32,
                g2.z_axis.z as f32,
            ],
            det: det as f32,
            isolated: false,
        }
    }
}

/// A covariance's eigenvalues, largest first, and their unit axes.
#[derive(Debug, Clone, Copy)]
struct Principal {
    variances: [f64; 3],
    axes: [Vec3; 3],
}

impl Principal {
    /// `None` for a zero or non-finite covariance.
    ///
    /// Eberly's non-iterative solver for symmetric 3 × 3 matrices ("A
    /// Robust Eigensolver for 3 × 3 Symmetric Matrices", Geometric Tools,
    /// 2014), in f64: the eigenvalues in closed form (the trigonometric
    /// solution of the characteristic cubic), the eigenvector of the
    /// eigenvalue farthest from the other two from cross products of
    /// (C − σI)'s rows, the middle one in that vector's orthogonal
    /// complement, the third their cross product.
    fn of(c: Mat3) -> Option<Self> {
        let c = c.as_dmat3();
        let a = [
            c.x_axis.x, c.y_axis.x, c.z_axis.x, c.y_axis.y, c.z_axis.y, c.z_axis.z,
        ];
        let scale = a.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        if !scale.is_finite() || scale == 0.0 {
            return None;
        }
        // Scaled to entries of at most 1, against overflow and underflow.
        let [a00, a01, a02, a11, a12, a22] = a.map(|v| v / scale);
        let m = DMat3::from_cols(
            DVec3::new(a00, a01, a02),
            DVec3::new(a01, a11, a12),
            DVec3::new(a02, a12, a22),
        );
        let q = (a00 + a11 + a22) / 3.0;
        let (b00, b11, b22) = (a00 - q, a11 - q, a22 - q);
        let off = a01 * a01 + a02 * a02 + a12 * a12;
        let p = ((b00 * b00 + b11 * b11 + b22 * b22 + 2.0 * off) / 6.0).sqrt();
        let (values, axes) = if p == 0.0 {
            // A multiple of the identity: any axes.
            ([q; 3], [DVec3::X, DVec3::Y, DVec3::Z])
        } else {
            // cos 3θ = det((C − qI)/p)/2.
            let c00 = b11 * b22 - a12 * a12;
            let c01 = a01 * b22 - a12 * a02;
            let c02 = a01 * a12 - b11 * a02;
            let det = (b00 * c00 - a01 * c01 + a02 * c02) / (p * p * p);
            let half_det = (0.5 * det).clamp(-1.0, 1.0);
            let angle = half_det.acos() / 3.0;
            // β0 ≤ β1 ≤ β2.
            let beta2 = 2.0 * angle.cos();
            let beta0 = 2.0 * (angle + 2.0 * std::f64::consts::FRAC_PI_3).cos();
            let beta1 = -(beta0 + beta2);
            let values = [q + p * beta0, q + p * beta1, q + p * beta2];
            // The best separated eigenvalue's vector first.
            let axes = if half_det >= 0.0 {
                let e2 = eigenvector_of_simple(&m, values[2]);
                let e1 = eigenvector_in_complement(&m, e2, values[1]);
                [e1.cross(e2), e1, e2]
            } else {
                let e0 = eigenvector_of_simple(&m, values[0]);
                let e1 = eigenvector_in_complement(&m, e0, values[1]);
                [e0, e1, e0.cross(e1)]
            };
            (values, axes)
        };
        let variances = [values[2], values[1], values[0]].map(|v| v * scale);
        if !variances[0].is_finite() || variances[0] <= 0.0 {
            return None;
        }
        let axes = [axes[2], axes[1], axes[0]].map(|v| v.as_vec3());
        Some(Self { variances, axes })
    }
}

/// The unit eigenvector of the symmetric `m` for its simple eigenvalue
/// `value`: the longest cross product of two rows of m − value I.
fn eigenvector_of_simple(m: &DMat3, value: f64) -> DVec3 {
    let rows = [
        m.x_axis - DVec3::X * value,
        m.y_axis - DVec3::Y * value,
        m.z_axis - DVec3::Z * value,
    ];
    let crosses = [
        rows[0].cross(rows[1]),
        rows[0].cross(rows[2]),
        rows[1].cross(rows[2]),
    ];
    let longest = (crosses.into_iter())
        .max_by(|a, b| a.length_squared().total_cmp(&b.length_squared()))
        .unwrap_or(DVec3::X);
    longest.try_normalize().unwrap_or(DVec3::X)
}

/// The unit eigenvector of the symmetric `m` for `value` orthogonal to its
/// unit eigenvector `w`: the null vector of m − value I restricted to w's
/// orthogonal complement (a 2 × 2 problem).
fn eigenvector_in_complement(m: &DMat3, w: DVec3, value: f64) -> DVec3 {
    let u = if w.x.abs() > w.y.abs() {
        DVec3::new(-w.z, 0.0, w.x) / (w.x * w.x + w.z * w.z).sqrt()
    } else {
        DVec3::new(0.0, w.z, -w.y) / (w.y * w.y + w.z * w.z).sqrt()
    };
    let v = w.cross(u);
    let (mu, mv) = (*m * u, *m * v);
    // The 2 × 2 matrix [[m00, m01], [m01, m11]] in the basis (u, v).
    let (m00, m01, m11) = (u.dot(mu) - value, u.dot(mv), v.dot(mv) - value);
    // Its null vector from the row with the larger diagonal, normalised
    // without overflow.
    let (d, across) = if m00.abs() >= m11.abs() {
        (m00, 1.0)
    } else {
        (m11, -1.0)
    };
    if d.abs().max(m01.abs()) == 0.0 {
        return u;
    }
    let (s, c) = if d.abs() >= m01.abs() {
        let t = m01 / d;
        let c = 1.0 / (1.0 + t * t).sqrt();
        (t * c, c)
    } else {
        let t = d / m01;
        let s = 1.0 / (1.0 + t * t).sqrt();
        (s, t * s)
    };
    // Row (m00, m01): the null vector is (m01, −m00) ∝ (s, −c) in (u, v);
    // row (m01, m11): (m11, −m01) ∝ (c, −s).
    if across > 0.0 {
        s * u - c * v
    } else {
        c * u - s * v
    }
}

/// The smoothed kernel centre and the kernel of each particle at
/// `positions`, from its neighbours within `params.radius` (the grid built
/// over `positions` with that radius), into `out` (index order, replaced).
pub fn kernels(
    grid: &NeighbourGrid,
    positions: &[Vec3],
    params: &Anisotropy,
    out: &mut Vec<(Vec3, Ellipsoid)>,
) {
    let pass = Pass {
        params,
        h: grid.h() / params.radius,
        inv_r: 1.0 / grid.h(),
        isolated: Ellipsoid::sphere(params.isolated_scale),
    };
    thread_local! {
        /// One particle's neighbours in lanes, gathered in one scan of the
        /// grid and read by both passes.
        static NEAR: std::cell::RefCell<Vec<Near>> = const { std::cell::RefCell::new(Vec::new()) };
    }
    grid.par_map_into(
        |i, nb| {
            let xi = positions[i];
            NEAR.with_borrow_mut(|near| {
                with_lanes(KernelOf {
                    nb,
                    xi,
                    near,
                    pass: &pass,
                })
            })
        },
        out,
    );
}

/// The kernel pass's parameters: the anisotropy's, the smoothing length h,
/// 1/r for the neighbourhood's radius r, and an isolated particle's kernel.
struct Pass<'a> {
    params: &'a Anisotropy,
    h: f32,
    inv_r: f32,
    isolated: Ellipsoid,
}

/// Up to 16 neighbours of a particle, one per lane: offsets x_j − x_i and
/// weights w_ij (0 in the lanes past the chunk's neighbours).
struct Near {
    o: [[f32; CHUNK_LANES]; 3],
    w: [f32; CHUNK_LANES],
}

/// The smoothed centre and the kernel of the particle at `xi`, whose
/// neighbours (itself included) within the pass's r are `nb`'s. Each sum is
/// kept in 16 lanes (`sph-core`'s chunks of neighbours, as two halves of
/// [`F32x8`]) and reduced by the grid's fixed tree, so every kind of lanes
/// gives bitwise the same kernels.
struct KernelOf<'a> {
    nb: Neighbourhood<'a>,
    xi: Vec3,
    near: &'a mut Vec<Near>,
    pass: &'a Pass<'a>,
}

impl LaneFn for KernelOf<'_> {
    type Out = (Vec3, Ellipsoid);

    // Loops over halves, not closures: see `LaneFn`.
    #[allow(clippy::needless_range_loop)]
    #[inline(always)]
    fn call<S: F32x8>(self) -> (Vec3, Ellipsoid) {
        let KernelOf { nb, xi, near, pass } = self;
        let &Pass {
            params,
            h,
            inv_r,
            isolated,
        } = pass;
        let (zero, one, minus) = (S::splat(0.0), S::splat(1.0), S::splat(-1.0));
        let inv_r = S::splat(inv_r);
        // Weighted mean and second moment about x_i (offsets are at most r,
        // so f32 sums of a few hundred terms are exact enough), the second
        // moment as its 6 distinct entries: [w, w o (3), w o oᵀ (6)], per
        // half.
        let mut acc = [[zero; 10]; 2];
        let mut count = 0;
        near.clear();
        for ch in nb.chunks() {
            count += ch.len;
            let mut n = Near {
                o: [[0.0; CHUNK_LANES]; 3],
                w: [0.0; CHUNK_LANES],
            };
            for k in 0..2 {
                let q = S::half(&ch.r2, k).sqrt() * inv_r;
                let w = S::half(&ch.weight, k) * (one - q * q * q);
                // d = x_i − x_j: the offset of x_j from x_i is −d (−1 · d
                // is exactly −d, signed zeros included).
                let o = [
                    minus * S::half(&ch.d[0], k),
                    minus * S::half(&ch.d[1], k),
                    minus * S::half(&ch.d[2], k),
                ];
                let wo = [w * o[0], w * o[1], w * o[2]];
                let a = &mut acc[k];
                a[0] = a[0] + w;
                a[1] = a[1] + wo[0];
                a[2] = a[2] + wo[1];
                a[3] = a[3] + wo[2];
                a[4] = a[4] + wo[0] * o[0];
                a[5] = a[5] + wo[0] * o[1];
                a[6] = a[6] + wo[0] * o[2];
                a[7] = a[7] + wo[1] * o[1];
                a[8] = a[8] + wo[1] * o[2];
                a[9] = a[9] + wo[2] * o[2];
                w.store_half(&mut n.w, k);
                for axis in 0..3 {
                    o[axis].store_half(&mut n.o[axis], k);
                }
            }
            near.push(n);
        }
        let mut sums = [0.0f32; 10];
        for e in 0..10 {
            sums[e] = reduce_halves(acc[0][e], acc[1][e]);
        }
        let [sw, mx, my, mz, xx, xy, xz, yy, yz, zz] = sums;
        let neighbours = count.saturating_sub(1);
        let inv = 1.0 / sw;
        let mean = Vec3::new(mx, my, mz) * inv;
        let c = Mat3::from_cols(
            Vec3::new(xx, xy, xz) * inv - mean * mean.x,
            Vec3::new(xy, yy, yz) * inv - mean * mean.y,
            Vec3::new(xz, yz, zz) * inv - mean * mean.z,
        );
        let principal = (neighbours >= params.min_neighbours as usize)
            .then(|| Principal::of(c))
            .flatten();
        let shape = principal.map_or(isolated, |p| {
            Ellipsoid::from_principal(&p, params.max_ratio)
        });
        let centre = match (params.centres, principal) {
            (Centres::Layer { thickness }, Some(p)) => {
                // The mean height over the neighbours in x_i's own layer
                // across the normal n (the smallest axis).
                let n = p.axes[2];
                let (nx, ny, nz) = (S::splat(n.x), S::splat(n.y), S::splat(n.z));
                let inv_tau = S::splat(1.0 / (thickness * h));
                let (mut sw, mut sum) = ([zero; 2], [zero; 2]);
                for chunk in near.iter() {
                    for k in 0..2 {
                        let t = S::half(&chunk.o[0], k) * nx
                            + S::half(&chunk.o[1], k) * ny
                            + S::half(&chunk.o[2], k) * nz;
                        let u = t * inv_tau;
                        // 0 outside the layer, |u| ≥ 1, without a branch.
                        let a = (one - u * u).max(zero);
                        let wg = S::half(&chunk.w, k) * (a * a);
                        sw[k] = sw[k] + wg;
                        sum[k] = sum[k] + wg * t;
                    }
                }
                xi + params.smoothing
                    * (reduce_halves(sum[0], sum[1]) / reduce_halves(sw[0], sw[1]))
                    * n
            }
            _ => xi + params.smoothing * mean,
        };
        (centre, shape)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lattice(n: i32, s: f32) -> Vec<Vec3> {
        let mut x = Vec::new();
        for k in 0..n {
            for j in 0..n {
                for i in 0..n {
                    x.push(Vec3::new(i as f32, j as f32, k as f32) * s);
                }
            }
        }
        x
    }

    /// The kernels of `x` with `params` for h = 2 × `s`.
    fn kernels_of(x: &[Vec3], s: f32, params: &Anisotropy) -> (Vec<Vec3>, Vec<Ellipsoid>) {
        let grid = NeighbourGrid::build(x, params.radius * 2.0 * s).unwrap();
        let mut out = Vec::new();
        kernels(&grid, x, params, &mut out);
        out.into_iter().unzip()
    }

    /// Every kind of lanes gives bitwise the same centres and kernels, on
    /// a jittered block with faces, edges and corners (partial chunks).
    #[test]
    fn every_kind_of_lanes_gives_the_same_kernels() {
        use sph_core::simd::Lanes;
        let s = 0.02;
        let mut x = lattice(7, s);
        for (i, p) in x.iter_mut().enumerate() {
            let f = (i as f32 * 0.618).fract() - 0.5;
            *p += Vec3::new(f, -0.7 * f, 0.3 * f) * 0.2 * s;
        }
        let params = Anisotropy::default();
        let grid = NeighbourGrid::build(&x, params.radius * 2.0 * s).unwrap();
        let pass = Pass {
            params: &params,
            h: 2.0 * s,
            inv_r: 1.0 / grid.h(),
            isolated: Ellipsoid::sphere(params.isolated_scale),
        };
        let kinds = Lanes::every();
        let mut flattened = 0;
        for (i, &xi) in x.iter().enumerate() {
            let bits = |lanes: Lanes| {
                let mut near = Vec::new();
                let (c, e) = lanes.run(KernelOf {
                    nb: grid.neighbourhood(i),
                    xi,
                    near: &mut near,
                    pass: &pass,
                });
                (
                    c.to_array().map(f32::to_bits),
                    e.m.map(f32::to_bits),
                    e.det.to_bits(),
                )
            };
            let plain = bits(kinds[0]);
            flattened += usize::from(f32::from_bits(plain.2) > 1.01);
            for &kind in &kinds[1..] {
                assert_eq!(bits(kind), plain, "particle {i}, {}", kind.name());
            }
        }
        // The faces' kernels are flattened: the sums are not all trivial.
        assert!(flattened > 100, "{flattened} flattened kernels");
    }

    /// In a lattice's interior the kernel is the isotropic one and the centre
    /// stays put; on a face the kernel is flattened along the face's normal
    /// (its M's normal eigenvalue the largest). The layer smoothing leaves
    /// the face's centres in the face; the paper's mean moves them in.
    #[test]
    fn bulk_is_isotropic_and_faces_flatten() {
        let s = 0.02;
        let x = lattice(9, s);
        let (centres, shapes) = kernels_of(&x, s, &Anisotropy::default());
        let middle = 4 + 9 * 4 + 81 * 4;
        let e = shapes[middle];
        for (got, want) in e.m.iter().zip(Ellipsoid::ISOTROPIC.m) {
            assert!((got - want).abs() < 1e-4, "{:?}", e.m);
        }
        assert!((e.det - 1.0).abs() < 1e-4);
        assert!(centres[middle].distance(x[middle]) < 1e-6);
        // The middle of the top face (y = 8 s).
        let top = 4 + 9 * 8 + 81 * 4;
        let e = shapes[top];
        let along_normal = e.apply(Vec3::Y).dot(Vec3::Y);
        let along_face = e.apply(Vec3::X).dot(Vec3::X);
        assert!(along_normal > 1.2 * along_face, "{:?}", e.m);
        assert!((along_face - 1.0).abs() < 0.05, "{:?}", e.m);
        assert!(e.det > 1.0);
        assert!(centres[top].distance(x[top]) < 1e-6, "{}", centres[top]);
        let mean = Anisotropy {
            centres: Centres::Mean,
            ..Anisotropy::default()
        };
        let (centres, _) = kernels_of(&x, s, &mean);
        assert!(centres[top].y < x[top].y - 0.3 * s, "{}", centres[top]);
    }

    /// A lattice whose top layer's heights are jittered by ±s/5: the layer
    /// smoothing cuts the top centres' spread about their mean height by
    /// more than half and leaves that mean within s/50.
    #[test]
    fn layer_smoothing_flattens_without_moving_the_layer() {
        let s = 0.02;
        let mut x = lattice(12, s);
        let top = 11.0 * s;
        let mut k = 0u32;
        for p in x.iter_mut().filter(|p| p.y > top - 0.5 * s) {
            k = k.wrapping_mul(1_103_515_245).wrapping_add(12_345);
            p.y += 0.2 * s * ((k >> 16) as f32 / 32_768.0 - 1.0);
        }
        let (centres, _) = kernels_of(&x, s, &Anisotropy::default());
        // The top layer away from the sides (the middle 4 × 4).
        let inner =
            |p: &Vec3| (4.0 * s..=7.0 * s).contains(&p.x) && (4.0 * s..=7.0 * s).contains(&p.z);
        let stats = |ys: Vec<f32>| {
            let n = ys.len() as f32;
            let mean = ys.iter().sum::<f32>() / n;
            let spread = (ys.iter().map(|y| (y - mean).powi(2)).sum::<f32>() / n).sqrt();
            (mean, spread)
        };
        let (before_mean, before) = stats(
            (x.iter().filter(|p| p.y > top - 0.5 * s && inner(p)))
                .map(|p| p.y)
                .collect(),
        );
        let (after_mean, after) = stats(
            (x.iter().zip(&centres))
                .filter(|(p, _)| p.y > top - 0.5 * s && inner(p))
                .map(|(_, c)| c.y)
                .collect(),
        );
        assert!(after < 0.5 * before, "spread {after} from {before}");
        assert!(
            (after_mean - before_mean).abs() < 0.02 * s,
            "mean {after_mean} from {before_mean}"
        );
    }

    /// The clamp: a neighbourhood on a line (a rank-1 covariance) gives a
    /// kernel √max_ratio times thinner across than along; det G its
    /// volume's inverse.
    #[test]
    fn clamped_to_the_ratio() {
        let c = Mat3::from_diagonal(Vec3::new(0.0, 2.0, 0.0));
        let e = Ellipsoid::from_covariance(c, 4.0).unwrap();
        let g2 = Vec3::new(e.m[0], e.m[3], e.m[5]);
        assert!((g2 - Vec3::new(4.0, 1.0, 4.0)).length() < 1e-4, "{g2}");
        assert!((e.det - 4.0).abs() < 1e-4);
        assert_eq!(Ellipsoid::from_covariance(Mat3::ZERO, 4.0), None);
    }

    /// The eigen solver on random symmetric positive semi-definite
    /// matrices and on the degenerate ones (a multiple of the identity, a
    /// double eigenvalue, rank one, rank two): C v_k = σ_k v_k to 1e-5 of
    /// σ₁, the axes orthonormal, the variances largest first and summing to
    /// the trace.
    #[test]
    fn principal_axes_are_eigenvectors() {
        let mut k = 7u32;
        let mut random = move || {
            k = k.wrapping_mul(1_103_515_245).wrapping_add(12_345);
            (k >> 8) as f32 / (1u32 << 24) as f32 - 0.5
        };
        let mut cases = vec![
            Mat3::IDENTITY * 3.0,
            Mat3::from_diagonal(Vec3::new(1.0, 1.0, 0.25)),
            Mat3::from_diagonal(Vec3::new(0.0, 2.0, 0.0)),
            Mat3::from_diagonal(Vec3::new(1.0, 0.0, 1.0)),
        ];
        // A double eigenvalue in rotated axes.
        let r = Mat3::from_axis_angle(Vec3::new(1.0, 2.0, 3.0).normalize(), 0.7);
        cases.push(r * Mat3::from_diagonal(Vec3::new(2.0, 0.5, 0.5)) * r.transpose());
        for _ in 0..1000 {
            let a = Mat3::from_cols_array(&std::array::from_fn(|_| random()));
            cases.push(a * a.transpose() * 1e-4);
        }
        for c in cases {
            let p = Principal::of(c).expect("a non-zero covariance");
            let largest = p.variances[0] as f32;
            assert!(p.variances[0] >= p.variances[1] && p.variances[1] >= p.variances[2]);
            let trace = p.variances.iter().sum::<f64>() as f32;
            let want = c.x_axis.x + c.y_axis.y + c.z_axis.z;
            assert!((trace - want).abs() <= 1e-5 * largest, "{c:?}");
            for (kk, &v) in p.axes.iter().enumerate() {
                let residual = c * v - v * p.variances[kk] as f32;
                assert!(residual.length() <= 1e-5 * largest, "{c:?}: axis {kk} {v}");
                for &w in &p.axes[kk + 1..] {
                    assert!(v.dot(w).abs() < 1e-5, "{c:?}: {v} · {w}");
                }
                assert!((v.length() - 1.0).abs() < 1e-5);
            }
        }
        assert!(Principal::of(Mat3::ZERO).is_none());
        assert!(Principal::of(Mat3::IDENTITY * f32::NAN).is_none());
    }

    #[test]
    fn bad_parameters_name_themselves() {
        let d = Anisotropy::default();
        assert!(d.validate().is_ok());
        for (name, p) in [
            (
                "anisotropy.smoothing",
                Anisotropy {
                    smoothing: -0.1,
                    ..d
                },
            ),
            (
                "anisotropy.smoothing",
                Anisotropy {
                    smoothing: f32::NAN,
                    ..d
                },
            ),
            (
                "anisotropy.max_ratio",
                Anisotropy {
                    max_ratio: 0.5,
                    ..d
                },
            ),
            (
                "anisotropy.min_neighbours",
                Anisotropy {
                    min_neighbours: 5000,
                    ..d
                },
            ),
            (
                "anisotropy.isolated_scale",
                Anisotropy {
                    isolated_scale: 0.0,
                    ..d
                },
            ),
            (
                "anisotropy.isolated_scale",
                Anisotropy {
                    isolated_scale: 2.0,
                    ..d
                },
            ),
            // det G = 1e39: every sample of the field would be NaN.
            (
                "anisotropy.isolated_scale",
                Anisotropy {
                    isolated_scale: 1e-13,
                    ..d
                },
            ),
        ] {
            match p.validate() {
                Err(Error::InvalidParameter { name: got, .. }) => assert_eq!(got, name),
                other => panic!("{p:?}: {other:?}"),
            }
        }
    }
}
