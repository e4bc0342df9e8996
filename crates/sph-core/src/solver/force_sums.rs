//! WCSPH's force sums over a particle's neighbours (eq. 15, 17, 19–20) in
//! 16 lanes: hit m of a neighbourhood goes to lane m mod 16
//! (`Neighbourhood::hit_chunks`), and the lanes are reduced by the
//! grid's fixed tree ([`reduce_lanes`]). The per-lane code is plain Rust
//! compiled three times — for AVX-512 (where the compiler vectorises the 16
//! lanes), for AVX2 and without target features — with the same operations
//! in the same order (Rust contracts nothing into FMAs), so every CPU gets
//! bitwise the same forces.

use glam::Vec3;

use crate::grid::{CHUNK_LANES as LANES, Neighbourhood, reduce_lanes as reduce};
#[cfg(target_arch = "x86_64")]
use crate::simd::{Simd, simd_level};

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

/// The sums' 16 lanes.
struct Lanes {
    pressure: [[f32; LANES]; 3],
    viscosity: [[f32; LANES]; 3],
    normal: [[f32; LANES]; 3],
    laplacian: [f32; LANES],
}

/// Defines `$name`: [`force_sums_lanes`] compiled with the target
/// features `$features` (the same code, vectorised for them).
macro_rules! force_sums_with {
    ($name:ident, $features:literal) => {
        /// # Safety
        /// The CPU must support the target features this function enables.
        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = $features)]
        unsafe fn $name(
            nb: &Neighbourhood<'_>,
            centre: Centre,
            kernels: &ForceKernels,
            fluid: &SlotFluid<'_>,
        ) -> ForceSums {
            force_sums_lanes(nb, centre, kernels, fluid)
        }
    };
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
    #[cfg(target_arch = "x86_64")]
    match simd_level() {
        // SAFETY: `simd_level` never exceeds what the CPU supports.
        Simd::Avx512 => unsafe {
            return force_sums_avx512(nb, centre, kernels, fluid);
        },
        // SAFETY: as above.
        Simd::Avx2 => unsafe {
            return force_sums_avx2(nb, centre, kernels, fluid);
        },
        Simd::Baseline => {}
    }
    force_sums_lanes(nb, centre, kernels, fluid)
}

force_sums_with!(force_sums_avx2, "avx2");
force_sums_with!(force_sums_avx512, "avx512f,avx2");

/// The force sums with hit m of the neighbourhood (in slot order, row by
/// row) in lane m mod 16.
#[inline(always)]
fn force_sums_lanes(
    nb: &Neighbourhood<'_>,
    centre: Centre,
    kernels: &ForceKernels,
    fluid: &SlotFluid<'_>,
) -> ForceSums {
    let mut l = Lanes::new();
    let mut hits = nb.hit_chunks();
    while let Some(fill) = hits.next_fill() {
        for chunk in fill.chunks(LANES) {
            add_chunk(nb, &mut l, chunk, centre, kernels, fluid);
        }
    }
    l.finish()
}

/// Adds up to 16 hits (slots), hit k to lane k, to the lanes.
#[inline(always)]
fn add_chunk(
    nb: &Neighbourhood<'_>,
    l: &mut Lanes,
    chunk: &[u32],
    centre: Centre,
    kernels: &ForceKernels,
    fluid: &SlotFluid<'_>,
) {
    let [xs, ys, zs] = nb.slot_coords();
    let c = nb.centre();
    let (h, h2) = nb.radius();
    let three_h2 = 3.0 * h2;
    // Lanes past the hits repeat the chunk's first hit with weight 0: its
    // values are finite (it lies within h), and finite values times 0 add
    // exact zeros.
    let mut slot = [chunk[0]; LANES];
    let mut weight = [0.0f32; LANES];
    slot[..chunk.len()].copy_from_slice(chunk);
    weight[..chunk.len()].fill(1.0);
    // Gather the lanes' data, then compute on whole arrays: the second
    // loop has no indexing by slot, so the compiler vectorises it.
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
    for k in 0..LANES {
        let (vol, m, pr) = (weight[k] * g[3][k], weight[k] * g[4][k], g[5][k]);
        // The scan's arithmetic, so r² is the value it tested.
        let d = [c.x - g[0][k], c.y - g[1][k], c.z - g[2][k]];
        let r2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
        let t = h2 - r2;
        let g6 = -kernels.poly6_grad * t * t;
        let len = r2.sqrt();
        let gp = match kernels.spiky_grad {
            None => g6,
            Some(spiky) => {
                let e = h - len;
                let q = -spiky * e * e / len;
                if len > 0.0 { q } else { 0.0 }
            }
        };
        let fp = m * (centre.pressure + pr) * gp;
        let fv = vol * (kernels.visc_lap * (h - len));
        let v_i = centre.velocity;
        let dv = [g[6][k] - v_i.x, g[7][k] - v_i.y, g[8][k] - v_i.z];
        for a in 0..3 {
            l.normal[a][k] += vol * (g6 * d[a]);
            l.pressure[a][k] -= fp * d[a];
            l.viscosity[a][k] += fv * dv[a];
        }
        l.laplacian[k] += vol * (kernels.poly6_grad * t * (7.0 * r2 - three_h2));
    }
}

impl Lanes {
    fn new() -> Self {
        Self {
            pressure: [[0.0; LANES]; 3],
            viscosity: [[0.0; LANES]; 3],
            normal: [[0.0; LANES]; 3],
            laplacian: [0.0; LANES],
        }
    }

    /// The lanes reduced by [`reduce`]'s tree.
    fn finish(&self) -> ForceSums {
        let v3 = |a: &[[f32; LANES]; 3]| Vec3::new(reduce(&a[0]), reduce(&a[1]), reduce(&a[2]));
        ForceSums {
            pressure: v3(&self.pressure),
            viscosity: v3(&self.viscosity),
            normal: v3(&self.normal),
            laplacian: reduce(&self.laplacian),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::NeighbourGrid;
    use crate::kernels::sums::tests::cloud;
    use crate::kernels::{Kernel, Poly6, Spiky, Viscosity};

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
                let mut lanes = Lanes::new();
                for chunk in hits.chunks(LANES) {
                    add_chunk(&nb, &mut lanes, chunk, fluid.centre(i), &kernels, &by_slot);
                }
                let got = force_sums(&nb, fluid.centre(i), &kernels, &by_slot);
                assert_eq!(got, lanes.finish(), "particle {i}, {} hits", hits.len());
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
                let plain = force_sums_lanes(&nb, centre, &kernels, &fluid);
                assert_eq!(got, plain, "the path this CPU runs");
                #[cfg(target_arch = "x86_64")]
                {
                    if Simd::detect() >= Simd::Avx2 {
                        // SAFETY: AVX2 was detected.
                        let avx2 = unsafe { force_sums_avx2(&nb, centre, &kernels, &fluid) };
                        assert_eq!(avx2, plain, "AVX2");
                    }
                    if Simd::detect() >= Simd::Avx512 {
                        // SAFETY: AVX-512F and AVX2 were detected.
                        let avx512 = unsafe { force_sums_avx512(&nb, centre, &kernels, &fluid) };
                        assert_eq!(avx512, plain, "AVX-512");
                    }
                }
            }
        }
        assert!(found > 2000, "the queries must find neighbours: {found}");
    }
}
