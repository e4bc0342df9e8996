//! WCSPH's force sums over a particle's neighbours (eq. 15, 17, 19–20) in
//! 16 lanes: hit m of a neighbourhood goes to lane m mod 16
//! (`Neighbourhood::hit_chunks`), and the lanes are reduced by the
//! grid's fixed tree ([`crate::grid::reduce_halves`]). The 16 lanes are two halves of
//! [`F32x8`] (`crate::simd`), with the same operations in the same order on
//! every kind (Rust contracts nothing into FMAs), so every CPU gets bitwise
//! the same forces.

use glam::Vec3;

use crate::grid::{CHUNK_LANES as LANES, Neighbourhood, reduce_halves};
use crate::simd::{F32x8, LaneFn, with_lanes};

/// Per-particle data of the force sums, in slot order (see
/// [`crate::NeighbourGrid::to_slot_order`]).
#[derive(Debug, Clone, Copy)]
pub(crate) struct SlotFluid<'a> {
    /// Velocity components.
    pub v: [&'a [f32]; 3],
    /// Volume m/ρ.
    pub volume: &'a [f32],
    /// Mass.
    pub mass: &'a [f32],
    /// Pressure term p/ρ².
    pub pressure: &'a [f32],
}

/// The kernels' constants the force sums use (all for the grid's h).
#[derive(Debug, Clone, Copy)]
pub(crate) struct ForceKernels {
    /// Poly6 gradient and laplacian coefficient.
    pub poly6_grad: f32,
    /// Viscosity laplacian coefficient.
    pub visc_lap: f32,
    /// Spiky gradient coefficient, or `None` for the poly6 pressure gradient.
    pub spiky_grad: Option<f32>,
}

/// The particle whose force sums are taken (particle i of the sums), beyond
/// its position, which the neighbourhood has.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Centre {
    /// Its pressure term p/ρ².
    pub pressure: f32,
    /// Its velocity.
    pub velocity: Vec3,
}

/// Sums over the neighbours j of particle i (the centre).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct ForceSums {
    /// −Σ m_j (p_i/ρ_i² + p_j/ρ_j²) ∇W(x_i − x_j) (eq. 15 divided by m_i).
    pub pressure: Vec3,
    /// Σ V_j ∇²W_visc (v_j − v_i) (eq. 17 divided by m_i, without 1/ρ_i).
    pub viscosity: Vec3,
    /// Σ V_j ∇W_poly6: the colour field's gradient n (eq. 19).
    pub normal: Vec3,
    /// Σ V_j ∇²W_poly6: the colour field's laplacian.
    pub laplacian: f32,
}

/// The force sums of the neighbourhood `nb`'s `centre`. The centre itself
/// adds to `normal` and `laplacian` only (its pressure and viscosity terms
/// are exact zeros).
///
/// Panics if a slice of `fluid` is shorter than the grid.
#[inline]
pub(crate) fn force_sums(
    nb: &Neighbourhood<'_>,
    centre: Centre,
    kernels: &ForceKernels,
    fluid: &SlotFluid<'_>,
) -> ForceSums {
    let n = nb.slots();
    assert!(
        [fluid.volume, fluid.mass, fluid.pressure]
            .iter()
            .chain(&fluid.v)
            .all(|s| s.len() >= n),
        "one value per slot"
    );
    with_lanes(Sums {
        nb,
        centre,
        kernels,
        fluid,
    })
}

/// [`force_sums`]' work, for [`with_lanes`].
struct Sums<'a> {
    nb: &'a Neighbourhood<'a>,
    centre: Centre,
    kernels: &'a ForceKernels,
    fluid: &'a SlotFluid<'a>,
}

/// Per half of the 16 lanes: pressure (3), viscosity (3), normal (3),
/// laplacian.
type Acc<S> = [[S; 10]; 2];

impl LaneFn for Sums<'_> {
    type Out = ForceSums;

    /// The force sums with hit m of the neighbourhood (in slot order, row
    /// by row) in lane m mod 16.
    #[inline(always)]
    fn call<S: F32x8>(self) -> ForceSums {
        let mut acc: Acc<S> = [[S::splat(0.0); 10]; 2];
        let mut hits = self.nb.hit_chunks();
        while let Some(fill) = hits.next_fill() {
            for chunk in fill.chunks(LANES) {
                add_chunk(&self, &mut acc, chunk);
            }
        }
        finish(&acc)
    }
}

/// The lanes reduced by the grid's tree ([`reduce_halves`]), each sum's halves as lanes
/// 0–7 and 8–15.
#[inline(always)]
fn finish<S: F32x8>(acc: &Acc<S>) -> ForceSums {
    let mut r = [0.0f32; 10];
    for (e, sum) in r.iter_mut().enumerate() {
        *sum = reduce_halves(acc[0][e], acc[1][e]);
    }
    ForceSums {
        pressure: Vec3::new(r[0], r[1], r[2]),
        viscosity: Vec3::new(r[3], r[4], r[5]),
        normal: Vec3::new(r[6], r[7], r[8]),
        laplacian: r[9],
    }
}

/// Adds up to 16 hits (slots), hit k to lane k, to the lanes.
// Loops over halves and axes, not closures: see `LaneFn`.
#[allow(clippy::needless_range_loop)]
#[inline(always)]
fn add_chunk<S: F32x8>(sums: &Sums<'_>, acc: &mut Acc<S>, chunk: &[u32]) {
    let Sums {
        nb,
        centre,
        kernels,
        fluid,
    } = sums;
    let [xs, ys, zs] = nb.slot_coords();
    let c = nb.centre();
    let (h, h2) = nb.radius();
    // Lanes past the hits repeat the chunk's first hit with weight 0: its
    // values are finite (it lies within h), and finite values times 0 add
    // exact zeros.
    let mut slot = [chunk[0]; LANES];
    let mut weight = [0.0f32; LANES];
    slot[..chunk.len()].copy_from_slice(chunk);
    weight[..chunk.len()].fill(1.0);
    // Gather the lanes' data, then compute on whole lanes.
    let mut g = [[0.0f32; LANES]; 9];
    for k in 0..LANES {
        let s = slot[k] as usize;
        // SAFETY: hits are slots of the grid; coords have a value per slot
        // (and padding), and `force_sums` checked the fluid's slices.
        unsafe {
            g[0][k] = *xs.get_unchecked(s);
            g[1][k] = *ys.get_unchecked(s);
            g[2][k] = *zs.get_unchecked(s);
            g[3][k] = *fluid.volume.get_unchecked(s);
            g[4][k] = *fluid.mass.get_unchecked(s);
            g[5][k] = *fluid.pressure.get_unchecked(s);
            g[6][k] = *fluid.v[0].get_unchecked(s);
            g[7][k] = *fluid.v[1].get_unchecked(s);
            g[8][k] = *fluid.v[2].get_unchecked(s);
        }
    }
    let (hv, h2v, three_h2) = (S::splat(h), S::splat(h2), S::splat(3.0 * h2));
    let (poly6_grad, visc_lap) = (S::splat(kernels.poly6_grad), S::splat(kernels.visc_lap));
    let minus_poly6_grad = S::splat(-kernels.poly6_grad);
    let centre_pressure = S::splat(centre.pressure);
    let v_i = [
        S::splat(centre.velocity.x),
        S::splat(centre.velocity.y),
        S::splat(centre.velocity.z),
    ];
    let cs = [S::splat(c.x), S::splat(c.y), S::splat(c.z)];
    for half in 0..2 {
        let w = S::half(&weight, half);
        let vol = w * S::half(&g[3], half);
        let m = w * S::half(&g[4], half);
        let pr = S::half(&g[5], half);
        // The scan's arithmetic, so r² is the value it tested.
        let d = [
            cs[0] - S::half(&g[0], half),
            cs[1] - S::half(&g[1], half),
            cs[2] - S::half(&g[2], half),
        ];
        let r2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
        let t = h2v - r2;
        let g6 = minus_poly6_grad * t * t;
        let len = r2.sqrt();
        let gp = match kernels.spiky_grad {
            None => g6,
            Some(spiky) => {
                let e = hv - len;
                len.where_positive(S::splat(-spiky) * e * e / len)
            }
        };
        let fp = m * (centre_pressure + pr) * gp;
        let fv = vol * (visc_lap * (hv - len));
        let a = &mut acc[half];
        for axis in 0..3 {
            let dv = S::half(&g[6 + axis], half) - v_i[axis];
            a[axis] = a[axis] - fp * d[axis];
            a[3 + axis] = a[3 + axis] + fv * dv;
            a[6 + axis] = a[6 + axis] + vol * (g6 * d[axis]);
        }
        a[9] = a[9] + vol * (poly6_grad * t * (S::splat(7.0) * r2 - three_h2));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::NeighbourGrid;
    use crate::kernels::sums::tests::cloud;
    use crate::kernels::{Kernel, Poly6, Spiky, Viscosity};
    use crate::simd::Lanes;

    /// The sums term by term with the kernels' own functions, and the scale
    /// of their terms (Σ |term| per sum) for the rounding tolerance.
    #[allow(clippy::too_many_arguments)]
    fn brute(
        x: &[Vec3],
        v: &[Vec3],
        vol: &[f32],
        m: &[f32],
        pr: &[f32],
        i: usize,
        spiky: bool,
        h: f32,
    ) -> (ForceSums, [f32; 4]) {
        let (poly6, sp, visc) = (
            Poly6::new(h).unwrap(),
            Spiky::new(h).unwrap(),
            Viscosity::new(h).unwrap(),
        );
        let (mut s, mut scale) = (ForceSums::default(), [0.0f32; 4]);
        for j in 0..x.len() {
            let d = x[i] - x[j];
            let r2 = d.length_squared();
            if r2 > h * h {
                continue;
            }
            let n = vol[j] * poly6.gradient_r2(d, r2);
            let l = vol[j] * poly6.laplacian_r2(r2);
            let grad = if spiky {
                sp.gradient(d)
            } else {
                poly6.gradient(d)
            };
            let p = -m[j] * (pr[i] + pr[j]) * grad;
            let f = vol[j] * visc.laplacian_len(d.length()) * (v[j] - v[i]);
            (s.normal, s.laplacian) = (s.normal + n, s.laplacian + l);
            (s.pressure, s.viscosity) = (s.pressure + p, s.viscosity + f);
            let terms = [p.abs().max_element(), f.abs().max_element()];
            let terms = [terms[0], terms[1], n.abs().max_element(), l.abs()];
            for (s, t) in scale.iter_mut().zip(terms) {
                *s += t;
            }
        }
        (s, scale)
    }

    /// Made-up fluid values for the particles at `x`, by particle and in the
    /// grid's slot order.
    struct Fluid {
        v: Vec<Vec3>,
        m: Vec<f32>,
        vol: Vec<f32>,
        pr: Vec<f32>,
        /// Velocity components, volume, mass, pressure term in slot order.
        slots: [Vec<f32>; 6],
    }

    impl Fluid {
        fn new(grid: &NeighbourGrid, n: usize) -> Self {
            let f = |i: usize, k: usize| ((i * 7919 + k * 104_729) % 1000) as f32 / 1000.0;
            let v: Vec<Vec3> = (0..n)
                .map(|i| Vec3::new(f(i, 1), f(i, 2), f(i, 3)) - 0.5)
                .collect();
            let m: Vec<f32> = (0..n).map(|i| 0.5 + f(i, 4)).collect();
            let vol: Vec<f32> = (0..n).map(|i| m[i] / (900.0 + 200.0 * f(i, 5))).collect();
            let pr: Vec<f32> = (0..n).map(|i| f(i, 6) * 1e-3).collect();
            let slot = |x: &[f32]| grid.to_slot_order(x).into_owned();
            let va = |a: usize| slot(&v.iter().map(|v| v[a]).collect::<Vec<_>>());
            let slots = [va(0), va(1), va(2), slot(&vol), slot(&m), slot(&pr)];
            Self {
                v,
                m,
                vol,
                pr,
                slots,
            }
        }

        fn by_slot(&self) -> SlotFluid<'_> {
            let s = &self.slots;
            SlotFluid {
                v: [&s[0], &s[1], &s[2]],
                volume: &s[3],
                mass: &s[4],
                pressure: &s[5],
            }
        }

        fn centre(&self, i: usize) -> Centre {
            Centre {
                pressure: self.pr[i],
                velocity: self.v[i],
            }
        }
    }

    fn kernels(h: f32, spiky: bool) -> ForceKernels {
        ForceKernels {
            poly6_grad: Poly6::new(h).unwrap().coefficients().1,
            visc_lap: Viscosity::new(h).unwrap().coefficient(),
            spiky_grad: spiky.then(|| Spiky::new(h).unwrap().coefficient()),
        }
    }

    /// The sums over a list of hits cut into chunks of 16 here.
    struct ByChunks<'a> {
        sums: Sums<'a>,
        hits: &'a [u32],
    }

    impl LaneFn for ByChunks<'_> {
        type Out = ForceSums;
        #[inline(always)]
        fn call<S: F32x8>(self) -> ForceSums {
            let mut acc: Acc<S> = [[S::splat(0.0); 10]; 2];
            for chunk in self.hits.chunks(LANES) {
                add_chunk(&self.sums, &mut acc, chunk);
            }
            finish(&acc)
        }
    }

    /// Hit m of a neighbourhood goes to lane m mod 16 however the scan's
    /// fills (whose lengths depend on the SIMD path) cut the hits: the sums
    /// of neighbourhoods of up to some 600 hits, more than two buffers, equal
    /// bitwise the sums over the whole hit list in chunks of 16.
    #[test]
    fn lanes_follow_the_hit_order_across_fills() {
        let x = cloud();
        let h = 0.55;
        let grid = NeighbourGrid::build(&x, h).unwrap();
        let fluid = Fluid::new(&grid, x.len());
        let by_slot = fluid.by_slot();
        let mut most = 0;
        for spiky in [false, true] {
            let kernels = kernels(h, spiky);
            for i in (0..x.len()).step_by(17) {
                let nb = grid.neighbourhood(i);
                let mut hits = Vec::new();
                nb.for_each_slot(|k, _, _| hits.push(k as u32));
                let sums = Sums {
                    nb: &nb,
                    centre: fluid.centre(i),
                    kernels: &kernels,
                    fluid: &by_slot,
                };
                let by_chunks = Lanes::best().run(ByChunks { sums, hits: &hits });
                let got = force_sums(&nb, fluid.centre(i), &kernels, &by_slot);
                assert_eq!(got, by_chunks, "particle {i}, {} hits", hits.len());
                most = most.max(hits.len());
            }
        }
        assert!(most > 2 * crate::grid::HIT_CAPACITY, "{most} hits at most");
    }

    /// The sums agree with term-by-term sums to rounding for both pressure
    /// kernels, and every vector path this CPU can run gives bitwise the
    /// plain path's sums.
    #[test]
    fn force_sums_match_term_by_term_sums() {
        let x = cloud();
        let n = x.len();
        let h = 0.23;
        let grid = NeighbourGrid::build(&x, h).unwrap();
        let data = Fluid::new(&grid, n);
        let (v, m, vol, pr) = (&data.v, &data.m, &data.vol, &data.pr);
        let fluid = data.by_slot();
        let mut found = 0;
        for spiky in [false, true] {
            let kernels = kernels(h, spiky);
            for i in (0..n).step_by(23) {
                let nb = grid.neighbourhood(i);
                let (want, scale) = brute(&x, v, vol, m, pr, i, spiky, h);
                let centre = data.centre(i);
                let got = force_sums(&nb, centre, &kernels, &fluid);
                let tol = |s: f32| 1e-5 * s + 1e-30;
                let close = |a: Vec3, b: Vec3, s: f32| (a - b).abs().max_element() <= tol(s);
                assert!(
                    close(got.pressure, want.pressure, scale[0]),
                    "{got:?} vs {want:?}"
                );
                assert!(
                    close(got.viscosity, want.viscosity, scale[1]),
                    "{got:?} vs {want:?}"
                );
                assert!(
                    close(got.normal, want.normal, scale[2]),
                    "{got:?} vs {want:?}"
                );
                assert!(
                    (got.laplacian - want.laplacian).abs() <= tol(scale[3]),
                    "{got:?} vs {want:?}"
                );
                found += nb.count();
                for lanes in Lanes::every() {
                    let sums = Sums {
                        nb: &nb,
                        centre,
                        kernels: &kernels,
                        fluid: &fluid,
                    };
                    assert_eq!(lanes.run(sums), got, "{}", lanes.name());
                }
            }
        }
        assert!(found > 2000, "the queries must find neighbours: {found}");
    }
}
