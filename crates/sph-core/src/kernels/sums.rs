//! Weighted poly6 sums over a neighbourhood, vectorised: the colour field and
//! the density are Σ_j w_j W(x − x_j) and its derivatives, and computing them
//! straight from the candidate chunks (16 lanes with AVX-512, 8 with AVX2,
//! masked at a row's end) skips the hit buffer and the per-neighbour scalar loop of [`Neighbourhood::for_each`].
//!
//! Neighbours are exactly [`Neighbourhood::for_each`]'s: the distance test is
//! the scan's (same operations, no fused multiply-add). Each sum is kept in 16
//! lanes, lane l taking the candidates 16m + l of each row, and the lanes are
//! reduced by a fixed tree. The AVX2 path keeps the 16 lanes as two 8-lane
//! halves, and the scalar path (the baseline) visits them one candidate at a
//! time; both do the same operations in the same order (no fused multiply-add
//! anywhere), so every path gives bitwise the same sums: a simulation or an
//! extraction gives the same result on every CPU and for any number of
//! threads.

use glam::Vec3;

use crate::grid::{CHUNK_LANES as LANES, Neighbourhood, SlotRange, reduce_lanes as reduce};
#[cfg(target_arch = "x86_64")]
use crate::grid::{offsets_avx2, offsets_avx512};
#[cfg(target_arch = "x86_64")]
use crate::simd::{Simd, simd_level};
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

/// The per-lane sums of the scalar path, in [`Raw`]'s order.
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
        #[cfg(target_arch = "x86_64")]
        match simd_level() {
            // SAFETY: `simd_level` never exceeds what the CPU supports.
            Simd::Avx512 => return unsafe { self.raw_avx512::<SECOND>(weights) },
            // SAFETY: as above.
            Simd::Avx2 => return unsafe { self.raw_avx2::<SECOND>(weights) },
            Simd::Baseline => {}
        }
        self.raw_scalar::<SECOND>(weights)
    }

    /// The AVX-512 path's lanes and operations, one candidate at a time.
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

    /// The AVX-512 path's 16 lanes as two 8-lane halves: lanes 0–7 and 8–15 of
    /// each chunk, every sum kept per half and lane and reduced at the end by
    /// the same tree. Masked loads at a row's end (the weights are not padded).
    ///
    /// # Safety
    /// The CPU must support AVX2 and POPCNT.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,popcnt")]
    unsafe fn raw_avx2<const SECOND: bool>(&self, weights: &[f32]) -> Raw {
        use std::arch::x86_64::*;
        let [xs, ys, zs] = self.slot_coords();
        let (c, h2) = (self.centre(), self.radius().1);
        let cs = [
            _mm256_set1_ps(c.x),
            _mm256_set1_ps(c.y),
            _mm256_set1_ps(c.z),
        ];
        let lim = _mm256_set1_ps(h2);
        let (seven, three_h2) = (_mm256_set1_ps(7.0), _mm256_set1_ps(3.0 * h2));
        let lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
        let zero = _mm256_setzero_ps();
        // [half][sum]: t3, t2d x/y/z, lap, then the second moment's six.
        let mut acc = [[zero; 11]; 2];
        let mut count = 0u32;
        for &SlotRange { start, end } in self.rows() {
            let (mut k, end) = (start as usize, end as usize);
            let mut half = 0;
            while k < end {
                // The lanes before the row's end, as a mask.
                let valid = _mm256_cmpgt_epi32(_mm256_set1_epi32((end - k).min(8) as i32), lane);
                // SAFETY: full chunks lie inside the arrays; a row's last chunk
                // loads only the lanes before `end`. Its other lanes take the
                // centre (weight 0), as on the AVX-512 path: d = 0 there, so
                // they add exact zeros even where |c|² would overflow.
                let (x, y, z, w) = unsafe {
                    if end - k >= 8 {
                        (
                            _mm256_loadu_ps(xs.as_ptr().add(k)),
                            _mm256_loadu_ps(ys.as_ptr().add(k)),
                            _mm256_loadu_ps(zs.as_ptr().add(k)),
                            _mm256_loadu_ps(weights.as_ptr().add(k)),
                        )
                    } else {
                        let at = |c, a: &[f32]| {
                            _mm256_blendv_ps(
                                c,
                                _mm256_maskload_ps(a.as_ptr().add(k), valid),
                                _mm256_castsi256_ps(valid),
                            )
                        };
                        (
                            at(cs[0], xs),
                            at(cs[1], ys),
                            at(cs[2], zs),
                            _mm256_maskload_ps(weights.as_ptr().add(k), valid),
                        )
                    }
                };
                // The scan's distance test, operation for operation. Lanes past
                // `end` hold the centre and are masked out.
                let ([dx, dy, dz], r2) = offsets_avx2(cs, [x, y, z]);
                let hit = _mm256_and_ps(
                    _mm256_castsi256_ps(valid),
                    _mm256_cmp_ps::<_CMP_LE_OQ>(r2, lim),
                );
                count += (_mm256_movemask_ps(hit) as u32).count_ones();
                let t = _mm256_sub_ps(lim, r2);
                // As the AVX-512 path: zero outside the hits, no fused multiply-add.
                let wt = _mm256_and_ps(hit, _mm256_mul_ps(w, t));
                let wt2 = _mm256_mul_ps(wt, t);
                let a = &mut acc[half];
                let add = |acc: &mut __m256, p, q| *acc = _mm256_add_ps(*acc, _mm256_mul_ps(p, q));
                add(&mut a[0], wt2, t);
                add(&mut a[1], wt2, dx);
                add(&mut a[2], wt2, dy);
                add(&mut a[3], wt2, dz);
                add(
                    &mut a[4],
                    wt,
                    _mm256_sub_ps(_mm256_mul_ps(seven, r2), three_h2),
                );
                if SECOND {
                    let (dx, dy, dz) = (
                        _mm256_and_ps(hit, dx),
                        _mm256_and_ps(hit, dy),
                        _mm256_and_ps(hit, dz),
                    );
                    add(&mut a[5], dx, dx);
                    add(&mut a[6], dx, dy);
                    add(&mut a[7], dx, dz);
                    add(&mut a[8], dy, dy);
                    add(&mut a[9], dy, dz);
                    add(&mut a[10], dz, dz);
                }
                half ^= 1;
                k += 8;
            }
        }
        let r: [f32; 11] = std::array::from_fn(|i| reduce_avx2(acc[0][i], acc[1][i]));
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

    /// Sixteen candidates at a time: masked loads at a row's end, every sum
    /// kept per lane and reduced once at the end.
    ///
    /// # Safety
    /// The CPU must support AVX-512F and POPCNT.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,popcnt")]
    unsafe fn raw_avx512<const SECOND: bool>(&self, weights: &[f32]) -> Raw {
        use std::arch::x86_64::*;
        let [xs, ys, zs] = self.slot_coords();
        let (c, h2) = (self.centre(), self.radius().1);
        let (cx, cy, cz) = (
            _mm512_set1_ps(c.x),
            _mm512_set1_ps(c.y),
            _mm512_set1_ps(c.z),
        );
        let lim = _mm512_set1_ps(h2);
        let (seven, three_h2) = (_mm512_set1_ps(7.0), _mm512_set1_ps(3.0 * h2));
        let zero = _mm512_setzero_ps();
        let (mut t3, mut gx, mut gy, mut gz, mut lap) = (zero, zero, zero, zero, zero);
        let mut second = [zero; 6];
        let mut count = 0u32;
        for &SlotRange { start, end } in self.rows() {
            let (mut k, end) = (start as usize, end as usize);
            while k < end {
                let valid: __mmask16 = if end - k >= 16 {
                    u16::MAX
                } else {
                    (1u16 << (end - k)) - 1
                };
                // SAFETY: the masked loads touch only lanes k..end, and every
                // row lies inside the coordinate arrays and, as the grid has
                // `weights.len()` or fewer slots (asserted), inside `weights`.
                // Lanes past `end` take the centre (weight 0): d = 0 there, so
                // they add exact zeros even where |c|² would overflow.
                let (x, y, z, w) = unsafe {
                    (
                        _mm512_mask_loadu_ps(cx, valid, xs.as_ptr().add(k)),
                        _mm512_mask_loadu_ps(cy, valid, ys.as_ptr().add(k)),
                        _mm512_mask_loadu_ps(cz, valid, zs.as_ptr().add(k)),
                        _mm512_maskz_loadu_ps(valid, weights.as_ptr().add(k)),
                    )
                };
                // The scan's distance test, operation for operation.
                let ([dx, dy, dz], r2) = offsets_avx512([cx, cy, cz], [x, y, z]);
                let hit = _mm512_mask_cmp_ps_mask::<_CMP_LE_OQ>(valid, r2, lim);
                count += hit.count_ones();
                let t = _mm512_sub_ps(lim, r2);
                // Zero outside the hits, so every product below is too, and
                // adding it leaves a lane as the scalar path leaves it. No
                // fused multiply-add: the scalar path has none to match.
                let wt = _mm512_maskz_mul_ps(hit, w, t);
                let wt2 = _mm512_mul_ps(wt, t);
                let add = |acc, a, b| _mm512_add_ps(acc, _mm512_mul_ps(a, b));
                t3 = add(t3, wt2, t);
                gx = add(gx, wt2, dx);
                gy = add(gy, wt2, dy);
                gz = add(gz, wt2, dz);
                lap = add(lap, wt, _mm512_sub_ps(_mm512_mul_ps(seven, r2), three_h2));
                if SECOND {
                    let (dx, dy, dz) = (
                        _mm512_maskz_mov_ps(hit, dx),
                        _mm512_maskz_mov_ps(hit, dy),
                        _mm512_maskz_mov_ps(hit, dz),
                    );
                    second[0] = add(second[0], dx, dx);
                    second[1] = add(second[1], dx, dy);
                    second[2] = add(second[2], dx, dz);
                    second[3] = add(second[3], dy, dy);
                    second[4] = add(second[4], dy, dz);
                    second[5] = add(second[5], dz, dz);
                }
                k += 16;
            }
        }
        Raw {
            count,
            t3: reduce_avx512(t3),
            t2d: [reduce_avx512(gx), reduce_avx512(gy), reduce_avx512(gz)],
            lap: reduce_avx512(lap),
            second: [
                reduce_avx512(second[0]),
                reduce_avx512(second[1]),
                reduce_avx512(second[2]),
                reduce_avx512(second[3]),
                reduce_avx512(second[4]),
                reduce_avx512(second[5]),
            ],
        }
    }
}

/// [`reduce`]'s tree on a vector's 16 lanes.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
#[inline]
fn reduce_avx512(v: std::arch::x86_64::__m512) -> f32 {
    use std::arch::x86_64::*;
    // a[i] = l[i] + l[i + 8], as two 4-lane halves.
    let a_lo = _mm_add_ps(
        _mm512_extractf32x4_ps::<0>(v),
        _mm512_extractf32x4_ps::<2>(v),
    );
    let a_hi = _mm_add_ps(
        _mm512_extractf32x4_ps::<1>(v),
        _mm512_extractf32x4_ps::<3>(v),
    );
    let b = _mm_add_ps(a_lo, a_hi);
    let c = _mm_add_ps(b, _mm_movehl_ps(b, b));
    _mm_cvtss_f32(_mm_add_ss(c, _mm_shuffle_ps::<0b01>(c, c)))
}

/// [`reduce`]'s tree on 16 lanes held as two 8-lane halves.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn reduce_avx2(lo: std::arch::x86_64::__m256, hi: std::arch::x86_64::__m256) -> f32 {
    use std::arch::x86_64::*;
    // a[i] = l[i] + l[i + 8].
    let a = _mm256_add_ps(lo, hi);
    let b = _mm_add_ps(_mm256_castps256_ps128(a), _mm256_extractf128_ps::<1>(a));
    let c = _mm_add_ps(b, _mm_movehl_ps(b, b));
    _mm_cvtss_f32(_mm_add_ss(c, _mm_shuffle_ps::<0b01>(c, c)))
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
            // Bitwise the path this CPU runs, and every vector path it can
            // run: results do not depend on the CPU.
            let scalar = nb.raw_scalar::<true>(&by_slot);
            assert_eq!(scalar, nb.raw::<true>(&kernel, &by_slot));
            #[cfg(target_arch = "x86_64")]
            {
                if Simd::detect() >= Simd::Avx2 {
                    // SAFETY: AVX2 and POPCNT were detected.
                    let avx2 = unsafe { nb.raw_avx2::<true>(&by_slot) };
                    assert_eq!(avx2, scalar, "AVX2");
                    let avx2 = unsafe { nb.raw_avx2::<false>(&by_slot) };
                    assert_eq!(avx2.t2d, scalar.t2d, "AVX2");
                }
                if Simd::detect() >= Simd::Avx512 {
                    // SAFETY: AVX-512F and POPCNT were detected.
                    let avx512 = unsafe { nb.raw_avx512::<true>(&by_slot) };
                    assert_eq!(avx512, scalar, "AVX-512");
                }
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
