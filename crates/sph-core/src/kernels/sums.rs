//! Weighted poly6 sums over a neighbourhood, vectorised: the colour field and
//! the density are Σ_j w_j W(x − x_j) and its derivatives, and computing them
//! straight from the candidate chunks (eight [`F32x8`] lanes at a time, the
//! row's last chunk loaded only up to its end) skips the hit buffer and the
//! per-neighbour scalar loop of [`Neighbourhood::for_each`].
//!
//! Neighbours are exactly [`Neighbourhood::for_each`]'s: the distance test is
//! the scan's (same operations, no fused multiply-add). Each sum is kept in 16
//! lanes, lane l taking the candidates 16m + l of each row, as two halves of
//! eight, and the lanes are reduced by the grid's fixed tree
//! ([`crate::grid::reduce_halves`]). Every kind of lanes does the same
//! operations in the same order, and the tests hold them to a reference that
//! visits the candidates one at a time, so the sums are bitwise the same on
//! every CPU and for any number of threads.

use glam::Vec3;

#[cfg(test)]
use crate::grid::{CHUNK_LANES as LANES, reduce_lanes as reduce};
use crate::grid::{Neighbourhood, SlotRange, reduce_halves};
use crate::simd::{F32x8, LaneFn, with_lanes};
use crate::{Kernel, Poly6};

/// Σ_j w_j W, Σ_j w_j ∇W, Σ_j w_j ∇²W of the poly6 kernel over the neighbours
/// x_j of a centre x (W evaluated at x − x_j), and their count.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Poly6Sums {
    /// Neighbours within h (the centre particle itself included, for a
    /// particle's neighbourhood).
    pub count: u32,
    /// Σ w_j W(x − x_j).
    pub value: f32,
    /// Σ w_j ∇W(x − x_j).
    pub gradient: Vec3,
    /// Σ w_j ∇²W(x − x_j).
    pub laplacian: f32,
}

/// The unweighted second moment Σ_j d_j d_jᵀ of the neighbour offsets
/// d_j = x − x_j, as [xx, xy, xz, yy, yz, zz].
pub type SecondMoment = [f32; 6];

/// Raw sums before the kernel's constants: with t = h² − r²,
/// Σ w t³, Σ w t² d, Σ w t (7r² − 3h²) and Σ d dᵀ.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Raw {
    count: u32,
    t3: f32,
    t2d: [f32; 3],
    lap: f32,
    second: [f32; 6],
}

/// The per-lane sums of the scalar reference, in [`Raw`]'s order.
#[cfg(test)]
struct Lanes {
    t3: [f32; LANES],
    t2d: [[f32; LANES]; 3],
    lap: [f32; LANES],
    second: [[f32; LANES]; 6],
}

impl Raw {
    fn finish(self, kernel: &Poly6) -> Poly6Sums {
        let (w, grad) = kernel.coefficients();
        Poly6Sums {
            count: self.count,
            value: w * self.t3,
            gradient: Vec3::from_array(self.t2d) * -grad,
            laplacian: grad * self.lap,
        }
    }
}

impl Neighbourhood<'_> {
    /// Poly6 sums over the neighbours, neighbour j weighted by
    /// `weights_by_slot[k]` where slot k holds j (see
    /// [`crate::NeighbourGrid::to_slot_order`]). `kernel` must have the grid's h.
    ///
    /// # Panics
    /// If `weights_by_slot` is shorter than the grid or the kernel's h is not
    /// the grid's.
    #[inline]
    pub fn poly6_sums(&self, kernel: &Poly6, weights_by_slot: &[f32]) -> Poly6Sums {
        self.raw::<false>(kernel, weights_by_slot).finish(kernel)
    }

    /// [`Neighbourhood::poly6_sums`] and the second moment of the neighbour
    /// offsets, from one scan. Panics as `poly6_sums` does.
    #[inline]
    pub fn poly6_sums_and_second_moment(
        &self,
        kernel: &Poly6,
        weights_by_slot: &[f32],
    ) -> (Poly6Sums, SecondMoment) {
        let raw = self.raw::<true>(kernel, weights_by_slot);
        (raw.finish(kernel), raw.second)
    }

    #[inline]
    fn raw<const SECOND: bool>(&self, kernel: &Poly6, weights: &[f32]) -> Raw {
        assert!(
            weights.len() >= self.slots(),
            "one weight per particle, in slot order"
        );
        assert_eq!(
            kernel.h(),
            self.radius().0,
            "the kernel's h must be the grid's"
        );
        with_lanes(RawSums::<SECOND> { nb: self, weights })
    }

    /// The lanes' sums one candidate at a time: the reference the lane
    /// kinds are tested against.
    #[cfg(test)]
    fn raw_scalar<const SECOND: bool>(&self, weights: &[f32]) -> Raw {
        let [xs, ys, zs] = self.slot_coords();
        let (c, h2) = (self.centre(), self.radius().1);
        let three_h2 = 3.0 * h2;
        let mut l = Lanes {
            t3: [0.0; LANES],
            t2d: [[0.0; LANES]; 3],
            lap: [0.0; LANES],
            second: [[0.0; LANES]; 6],
        };
        let mut count = 0;
        for &SlotRange { start, end } in self.rows() {
            for k in start as usize..end as usize {
                let lane = (k - start as usize) % LANES;
                // The scan's distance test, operation for operation.
                let d = [c.x - xs[k], c.y - ys[k], c.z - zs[k]];
                let r2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
                // NaN is no hit, as in the vector compare.
                if r2.partial_cmp(&h2).is_none_or(|o| o.is_gt()) {
                    continue;
                }
                count += 1;
                let t = h2 - r2;
                let wt = weights[k] * t;
                let wt2 = wt * t;
                l.t3[lane] += wt2 * t;
                for (sum, da) in l.t2d.iter_mut().zip(d) {
                    sum[lane] += wt2 * da;
                }
                l.lap[lane] += wt * (7.0 * r2 - three_h2);
                if SECOND {
                    for (e, (a, b)) in [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)]
                        .into_iter()
                        .enumerate()
                    {
                        l.second[e][lane] += d[a] * d[b];
                    }
                }
            }
        }
        Raw {
            count,
            t3: reduce(&l.t3),
            t2d: l.t2d.map(|v| reduce(&v)),
            lap: reduce(&l.lap),
            second: if SECOND {
                l.second.map(|v| reduce(&v))
            } else {
                [0.0; 6]
            },
        }
    }
}

/// The raw sums of a neighbourhood over [`F32x8`] lanes: each row's
/// candidates eight at a time, alternating between the two halves of the
/// 16 lanes (lane l of a row's chunk m taking candidate 16m + l), and the
/// halves reduced by the grid's tree at the end.
struct RawSums<'a, const SECOND: bool> {
    nb: &'a Neighbourhood<'a>,
    weights: &'a [f32],
}

impl<const SECOND: bool> LaneFn for RawSums<'_, SECOND> {
    type Out = Raw;

    #[inline(always)]
    fn call<S: F32x8>(self) -> Raw {
        let (nb, weights) = (self.nb, self.weights);
        let [xs, ys, zs] = nb.slot_coords();
        let (c, h2) = (nb.centre(), nb.radius().1);
        let cs = [S::splat(c.x), S::splat(c.y), S::splat(c.z)];
        let lim = S::splat(h2);
        let (seven, three_h2) = (S::splat(7.0), S::splat(3.0 * h2));
        let zero = S::splat(0.0);
        // [half][sum]: t3, t2d x/y/z, lap, then the second moment's six.
        let mut acc = [[zero; 11]; 2];
        let mut count = 0u32;
        for &SlotRange { start, end } in nb.rows() {
            let (mut k, end) = (start as usize, end as usize);
            let mut half = 0;
            while k < end {
                let n = end - k;
                // A row's last chunk loads only the candidates before `end`
                // (the weights are not padded); its other lanes take the
                // centre with weight 0: d = 0 there, so they add exact
                // zeros even where |c|² would overflow.
                let (x, y, z, w) = if n >= 8 {
                    (
                        S::load(xs, k),
                        S::load(ys, k),
                        S::load(zs, k),
                        S::load(weights, k),
                    )
                } else {
                    (
                        S::load_first(xs, k, n, cs[0]),
                        S::load_first(ys, k, n, cs[1]),
                        S::load_first(zs, k, n, cs[2]),
                        S::load_first(weights, k, n, zero),
                    )
                };
                // The scan's distance test, operation for operation.
                let (dx, dy, dz) = (cs[0] - x, cs[1] - y, cs[2] - z);
                let r2 = dx * dx + dy * dy + dz * dz;
                count += r2.count_le(lim, n);
                let t = lim - r2;
                // Zero outside the hits, so every product below is too, and
                // adding it leaves a lane as the scalar sums leave it. No
                // fused multiply-add: the reference has none to match.
                let wt = r2.where_le(lim, w * t);
                let wt2 = wt * t;
                let a = &mut acc[half];
                a[0] = a[0] + wt2 * t;
                a[1] = a[1] + wt2 * dx;
                a[2] = a[2] + wt2 * dy;
                a[3] = a[3] + wt2 * dz;
                a[4] = a[4] + wt * (seven * r2 - three_h2);
                if SECOND {
                    let (dx, dy, dz) = (
                        r2.where_le(lim, dx),
                        r2.where_le(lim, dy),
                        r2.where_le(lim, dz),
                    );
                    a[5] = a[5] + dx * dx;
                    a[6] = a[6] + dx * dy;
                    a[7] = a[7] + dx * dz;
                    a[8] = a[8] + dy * dy;
                    a[9] = a[9] + dy * dz;
                    a[10] = a[10] + dz * dz;
                }
                half ^= 1;
                k += 8;
            }
        }
        let mut r = [0.0; 11];
        for (i, r) in r.iter_mut().enumerate() {
            *r = reduce_halves(acc[0][i], acc[1][i]);
        }
        Raw {
            count,
            t3: r[0],
            t2d: [r[1], r[2], r[3]],
            lap: r[4],
            second: if SECOND {
                [r[5], r[6], r[7], r[8], r[9], r[10]]
            } else {
                [0.0; 6]
            },
        }
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::NeighbourGrid;

    /// A jittered cloud with a dense core and a few strays, deterministic.
    pub(crate) fn cloud() -> Vec<Vec3> {
        let mut state = 0x2545_F491u32;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            state as f32 / u32::MAX as f32
        };
        let mut x: Vec<Vec3> = (0..1500)
            .map(|_| Vec3::new(next(), next(), next()) * 1.2)
            .collect();
        x.extend([Vec3::splat(5.0), Vec3::new(-3.0, 0.2, 0.4)]);
        x
    }

    /// The sums term by term with the kernel's own functions, and the scale of
    /// their terms (Σ |term|) for the rounding tolerance.
    fn brute(x: &[Vec3], w: &[f32], k: &Poly6, c: Vec3) -> (Poly6Sums, SecondMoment, [f32; 3]) {
        let h2 = k.h() * k.h();
        let (mut s, mut m, mut scale) = (Poly6Sums::default(), [0.0f32; 6], [0.0f32; 3]);
        for (xj, wj) in x.iter().zip(w) {
            let d = Vec3::new(c.x - xj.x, c.y - xj.y, c.z - xj.z);
            let r2 = d.x * d.x + d.y * d.y + d.z * d.z;
            if r2 > h2 {
                continue;
            }
            s.count += 1;
            s.value += wj * k.value_r2(r2);
            s.gradient += *wj * k.gradient_r2(d, r2);
            s.laplacian += wj * k.laplacian_r2(r2);
            scale[0] += (wj * k.value_r2(r2)).abs();
            scale[1] += (*wj * k.gradient_r2(d, r2)).abs().element_sum();
            scale[2] += (wj * k.laplacian_r2(r2)).abs();
            for (e, v) in m.iter_mut().zip([
                d.x * d.x,
                d.x * d.y,
                d.x * d.z,
                d.y * d.y,
                d.y * d.z,
                d.z * d.z,
            ]) {
                *e += v;
            }
        }
        (s, m, scale)
    }

    fn assert_close(got: (Poly6Sums, SecondMoment), want: (Poly6Sums, SecondMoment, [f32; 3])) {
        let ((g, gm), (w, wm, scale)) = (got, want);
        assert_eq!(g.count, w.count);
        let tol = |s: f32| 1e-5 * s + 1e-30;
        assert!((g.value - w.value).abs() <= tol(scale[0]), "{g:?} vs {w:?}");
        assert!(
            (g.gradient - w.gradient).abs().max_element() <= tol(scale[1]),
            "{g:?} vs {w:?}"
        );
        assert!(
            (g.laplacian - w.laplacian).abs() <= tol(scale[2]),
            "{g:?} vs {w:?}"
        );
        for (a, b) in gm.iter().zip(wm) {
            assert!((a - b).abs() <= 1e-5 * (1.0 + b.abs()), "{gm:?} vs {wm:?}");
        }
    }

    /// The sums agree with a term-by-term sum to rounding and find exactly its
    /// neighbours, around particles, at arbitrary points, far away and for
    /// NaN; the scalar path gives bitwise the sums of the path this CPU runs.
    #[test]
    fn sums_match_term_by_term_sums() {
        let x = cloud();
        let h = 0.23;
        let grid = NeighbourGrid::build(&x, h).unwrap();
        let kernel = Poly6::new(h).unwrap();
        let weights: Vec<f32> = (0..x.len()).map(|i| 0.5 + (i % 7) as f32 * 0.1).collect();
        let by_slot = grid.to_slot_order(&weights);
        let mut queries: Vec<_> = (0..x.len())
            .step_by(37)
            .map(|i| grid.neighbourhood(i))
            .collect();
        for p in [
            Vec3::splat(0.6),
            Vec3::new(1.3, 0.1, -0.1),
            Vec3::splat(9.0),
        ] {
            queries.push(grid.neighbourhood_of_point(p));
        }
        let mut found = 0;
        for nb in &queries {
            let want = brute(&x, &weights, &kernel, nb.centre());
            found += want.0.count;
            let got = nb.poly6_sums_and_second_moment(&kernel, &by_slot);
            assert_close(got, want);
            assert_eq!(nb.poly6_sums(&kernel, &by_slot), got.0);
            assert_eq!(got.0.count as usize, nb.count());
            // Bitwise the scalar reference on every kind of lanes this CPU
            // runs: results do not depend on the CPU.
            let scalar = nb.raw_scalar::<true>(&by_slot);
            assert_eq!(scalar, nb.raw::<true>(&kernel, &by_slot));
            for lanes in crate::simd::Lanes::every() {
                let bits = |r: Raw| {
                    let mut v = vec![r.count, r.t3.to_bits(), r.lap.to_bits()];
                    v.extend(r.t2d.map(f32::to_bits));
                    v.extend(r.second.map(f32::to_bits));
                    v
                };
                let sums = |second| {
                    let (nb, weights) = (nb, &by_slot[..]);
                    if second {
                        lanes.run(RawSums::<true> { nb, weights })
                    } else {
                        lanes.run(RawSums::<false> { nb, weights })
                    }
                };
                assert_eq!(bits(sums(true)), bits(scalar), "{}", lanes.name());
                let first = sums(false);
                assert_eq!(
                    bits(Raw {
                        second: [0.0; 6],
                        ..scalar
                    }),
                    bits(first),
                    "{}",
                    lanes.name()
                );
            }
            assert_eq!((scalar.finish(&kernel), scalar.second), got);
        }
        assert!(found > 1000, "the queries must find neighbours: {found}");
        let none = grid.neighbourhood_of_point(Vec3::NAN);
        assert_eq!(none.poly6_sums(&kernel, &by_slot), Poly6Sums::default());
    }

    #[test]
    #[should_panic(expected = "the kernel's h must be the grid's")]
    fn a_kernel_of_another_h_panics() {
        let grid = NeighbourGrid::build(&[Vec3::ZERO, Vec3::X], 1.0).unwrap();
        grid.neighbourhood(0)
            .poly6_sums(&Poly6::new(0.5).unwrap(), &[1.0, 1.0]);
    }

    #[test]
    #[should_panic(expected = "one weight per particle")]
    fn too_few_weights_panic() {
        let grid = NeighbourGrid::build(&[Vec3::ZERO, Vec3::X], 1.0).unwrap();
        grid.neighbourhood(0)
            .poly6_sums(&Poly6::new(1.0).unwrap(), &[1.0]);
    }
}
