//! Eight f32 lanes, written once and compiled three ways: for AVX2 (`Avx2`,
//! one 256-bit register), for any x86-64 CPU (`Sse2`, two 128-bit
//! registers) and for any CPU ([`Scalar`], an array the compiler may or may
//! not vectorise). The solvers' pair sums are generic over [`F32x8`] and
//! run through [`par_map`], which picks the AVX2 lanes where [`simd_level`]
//! allows (compiled with AVX-512VL's 32 registers where the CPU has them:
//! [`wide_registers`]), else SSE2 on x86-64 (`SPH_SIMD=baseline`
//! included), else the plain arrays.
//!
//! Every kind does the same IEEE operations in the same order (add,
//! subtract, multiply, divide and square root are correctly rounded in
//! each, and [`F32x8::max`] is `a > b ? a : b` in each, as `maxps` is), so
//! every CPU gets bitwise the same results. The compiler does not vectorise the
//! scalar kind's square roots and divisions for SSE2, and left the eight
//! lanes in 128-bit halves with AVX2 enabled, so the AVX2 kind is written
//! with intrinsics: the PBF density solve took 2.3 times less time per pair
//! than the same sums as auto-vectorised arrays (`docs/benchmark-notes.md`,
//! "PBF's pair sums in AVX2 lanes").

use std::ops::{Add, Div, Mul, Sub};

use glam::Vec3;
use rayon::prelude::*;

use crate::NeighbourLists;
use crate::grid::{Simd, simd_level};

/// Eight f32 lanes.
pub(super) trait F32x8:
    Copy + Add<Output = Self> + Sub<Output = Self> + Mul<Output = Self> + Div<Output = Self>
{
    /// Every lane `v`.
    fn splat(v: f32) -> Self;
    /// The lanes of an array.
    fn from_array(a: [f32; 8]) -> Self;
    /// The lanes as an array.
    fn to_array(self) -> [f32; 8];
    /// Per lane `self > other ? self : other` (x86's `maxps`).
    fn max(self, other: Self) -> Self;
    /// Per lane √.
    fn sqrt(self) -> Self;
    /// 1 in the first `count` lanes, 0 in the others.
    fn first(count: usize) -> Self;
    /// Four lane sets from eight rows of four floats, lane l of set k
    /// getting `row(l)[k]`: what the gathers below are made of.
    fn transpose<'a>(row: impl Fn(usize) -> &'a [f32; 4]) -> [Self; 4];

    /// Lane l gets `values[slots[l]]`.
    ///
    /// # Panics
    /// If a slot is out of bounds.
    #[inline(always)]
    fn gather(values: &[f32], slots: &[u32; 8]) -> Self {
        let v = |l: usize| values[slots[l] as usize];
        Self::from_array([v(0), v(1), v(2), v(3), v(4), v(5), v(6), v(7)])
    }

    /// Four lane sets, lane l of set k getting `rows[slots[l]][k]`: the
    /// first four floats of rows of `W` ≥ 4.
    ///
    /// # Panics
    /// If a slot is out of bounds.
    #[inline(always)]
    fn gather_rows<const W: usize>(rows: &[[f32; W]], slots: &[u32; 8]) -> [Self; 4] {
        const { assert!(W >= 4) };
        Self::transpose(|l| first_four(&rows[slots[l] as usize]))
    }

    /// Lanes of x, y and z of `v[0..8]`, each vector read as four floats
    /// (its own three and the next one's x).
    ///
    /// # Panics
    /// If `v` holds fewer than 9 vectors.
    #[inline(always)]
    fn load_vec3s(v: &[Vec3]) -> [Self; 3] {
        let floats: &[f32] = bytemuck::cast_slice(&v[..9]);
        let [x, y, z, _] = Self::transpose(|l| first_four(&floats[3 * l..]));
        [x, y, z]
    }

    /// The lanes' sum, in a fixed tree.
    #[inline(always)]
    fn sum(self) -> f32 {
        let a = self.to_array();
        ((a[0] + a[1]) + (a[2] + a[3])) + ((a[4] + a[5]) + (a[6] + a[7]))
    }
}

/// The first four floats of `values`.
///
/// # Panics
/// If there are fewer than four.
#[inline(always)]
fn first_four(values: &[f32]) -> &[f32; 4] {
    values[..4].try_into().expect("four floats")
}

/// Eight lanes as an array: the lanes of CPUs other than x86-64, and the
/// reference the tests hold the other kinds to (on x86-64 only they use it).
#[derive(Debug, Clone, Copy)]
#[cfg_attr(all(target_arch = "x86_64", not(test)), allow(dead_code))]
pub(super) struct Scalar([f32; 8]);

macro_rules! scalar_op {
    ($trait:ident, $fn:ident, $op:tt) => {
        impl $trait for Scalar {
            type Output = Self;
            #[inline(always)]
            fn $fn(self, o: Self) -> Self {
                Scalar(std::array::from_fn(|l| self.0[l] $op o.0[l]))
            }
        }
    };
}
scalar_op!(Add, add, +);
scalar_op!(Sub, sub, -);
scalar_op!(Mul, mul, *);
scalar_op!(Div, div, /);

impl F32x8 for Scalar {
    #[inline(always)]
    fn splat(v: f32) -> Self {
        Scalar([v; 8])
    }
    #[inline(always)]
    fn from_array(a: [f32; 8]) -> Self {
        Scalar(a)
    }
    #[inline(always)]
    fn to_array(self) -> [f32; 8] {
        self.0
    }
    #[inline(always)]
    fn max(self, o: Self) -> Self {
        Scalar(std::array::from_fn(|l| {
            if self.0[l] > o.0[l] {
                self.0[l]
            } else {
                o.0[l]
            }
        }))
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        Scalar(self.0.map(f32::sqrt))
    }
    #[inline(always)]
    fn first(count: usize) -> Self {
        Scalar(std::array::from_fn(|l| if l < count { 1.0 } else { 0.0 }))
    }
    #[inline(always)]
    fn transpose<'a>(row: impl Fn(usize) -> &'a [f32; 4]) -> [Self; 4] {
        let rows: [[f32; 4]; 8] = std::array::from_fn(|l| *row(l));
        std::array::from_fn(|k| Scalar(std::array::from_fn(|l| rows[l][k])))
    }
}

#[cfg(target_arch = "x86_64")]
use avx2::Avx2;

#[cfg(target_arch = "x86_64")]
mod avx2 {
    use std::arch::x86_64::*;
    use std::ops::{Add, Div, Mul, Sub};

    use super::F32x8;

    /// Eight lanes in one AVX2 register. Only code compiled with AVX2
    /// enabled (under [`super::par_map`]'s dispatch) makes one.
    #[derive(Debug, Clone, Copy)]
    pub(super) struct Avx2(__m256);

    macro_rules! avx_op {
        ($trait:ident, $fn:ident, $intrinsic:ident) => {
            impl $trait for Avx2 {
                type Output = Self;
                #[inline(always)]
                fn $fn(self, o: Self) -> Self {
                    // SAFETY: an `Avx2` exists only where AVX2 is available.
                    Avx2(unsafe { $intrinsic(self.0, o.0) })
                }
            }
        };
    }
    avx_op!(Add, add, _mm256_add_ps);
    avx_op!(Sub, sub, _mm256_sub_ps);
    avx_op!(Mul, mul, _mm256_mul_ps);
    avx_op!(Div, div, _mm256_div_ps);

    // SAFETY (every `unsafe` block below): an `Avx2` exists only where AVX2
    // is available. The type is private to `f32x8.rs`, and the only code
    // that names it is `fill_avx2`, `row_avx2`, `fill_avx512vl` and
    // `row_avx512vl` (`unsafe fn`s that `par_map`, `par_map_rows`,
    // `every_kind` and `every_kind_rows` call after checking for AVX2, or
    // for AVX-512VL with [`wide_registers`]) and a test that checks first,
    // so the functions that make one
    // from nothing (`splat`, `from_array`, `first`, `transpose`) run only
    // there. The loads read whole `[f32; 4]`s and arrays of eight.
    impl F32x8 for Avx2 {
        #[inline(always)]
        fn splat(v: f32) -> Self {
            Avx2(unsafe { _mm256_set1_ps(v) })
        }
        #[inline(always)]
        fn from_array(a: [f32; 8]) -> Self {
            Avx2(unsafe { _mm256_loadu_ps(a.as_ptr()) })
        }
        #[inline(always)]
        fn to_array(self) -> [f32; 8] {
            let mut a = [0.0; 8];
            unsafe { _mm256_storeu_ps(a.as_mut_ptr(), self.0) };
            a
        }
        #[inline(always)]
        fn max(self, o: Self) -> Self {
            Avx2(unsafe { _mm256_max_ps(self.0, o.0) })
        }
        #[inline(always)]
        fn sqrt(self) -> Self {
            Avx2(unsafe { _mm256_sqrt_ps(self.0) })
        }
        #[inline(always)]
        fn first(count: usize) -> Self {
            const LANE: [f32; 8] = [0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0];
            // Lane l < count, as floats (exact for these small integers).
            let below = unsafe {
                _mm256_cmp_ps::<_CMP_LT_OQ>(
                    _mm256_loadu_ps(LANE.as_ptr()),
                    _mm256_set1_ps(count.min(8) as f32),
                )
            };
            Avx2(unsafe { _mm256_and_ps(below, _mm256_set1_ps(1.0)) })
        }
        #[inline(always)]
        fn transpose<'a>(row: impl Fn(usize) -> &'a [f32; 4]) -> [Self; 4] {
            // SAFETY: each row holds four floats.
            let row = |l: usize| unsafe { _mm_loadu_ps(row(l).as_ptr()) };
            // Rows l and l + 4 share a register (low and high half), then a
            // 4×4 transpose in each half.
            let pair = |l: usize| unsafe {
                _mm256_insertf128_ps::<1>(_mm256_castps128_ps256(row(l)), row(l + 4))
            };
            let (r0, r1, r2, r3) = (pair(0), pair(1), pair(2), pair(3));
            unsafe {
                let (t0, t1) = (_mm256_unpacklo_ps(r0, r1), _mm256_unpacklo_ps(r2, r3));
                let (t2, t3) = (_mm256_unpackhi_ps(r0, r1), _mm256_unpackhi_ps(r2, r3));
                [
                    Avx2(_mm256_shuffle_ps::<0x44>(t0, t1)),
                    Avx2(_mm256_shuffle_ps::<0xEE>(t0, t1)),
                    Avx2(_mm256_shuffle_ps::<0x44>(t2, t3)),
                    Avx2(_mm256_shuffle_ps::<0xEE>(t2, t3)),
                ]
            }
        }
    }
}

#[cfg(target_arch = "x86_64")]
use sse2::Sse2;

#[cfg(target_arch = "x86_64")]
mod sse2 {
    use std::arch::x86_64::*;
    use std::ops::{Add, Div, Mul, Sub};

    use super::F32x8;

    /// Eight lanes in two SSE2 registers: the lanes of every x86-64 CPU
    /// without AVX2 (SSE2 is part of x86-64, so no check is needed).
    #[derive(Debug, Clone, Copy)]
    pub(super) struct Sse2([__m128; 2]);

    macro_rules! sse_op {
        ($trait:ident, $fn:ident, $intrinsic:ident) => {
            impl $trait for Sse2 {
                type Output = Self;
                #[inline(always)]
                fn $fn(self, o: Self) -> Self {
                    let [a, b] = self.0;
                    let [c, d] = o.0;
                    // SAFETY: see the impl below.
                    Sse2(unsafe { [$intrinsic(a, c), $intrinsic(b, d)] })
                }
            }
        };
    }
    sse_op!(Add, add, _mm_add_ps);
    sse_op!(Sub, sub, _mm_sub_ps);
    sse_op!(Mul, mul, _mm_mul_ps);
    sse_op!(Div, div, _mm_div_ps);

    // SAFETY (every `unsafe` block of this module): SSE and SSE2 are part
    // of every x86-64 target, and the loads and stores touch only the
    // arrays and rows named, as in the AVX2 kind.
    impl F32x8 for Sse2 {
        #[inline(always)]
        fn splat(v: f32) -> Self {
            Sse2([unsafe { _mm_set1_ps(v) }; 2])
        }
        #[inline(always)]
        fn from_array(a: [f32; 8]) -> Self {
            let (lo, hi) = a.split_at(4);
            unsafe { Sse2([_mm_loadu_ps(lo.as_ptr()), _mm_loadu_ps(hi.as_ptr())]) }
        }
        #[inline(always)]
        fn to_array(self) -> [f32; 8] {
            let mut a = [0.0; 8];
            let (lo, hi) = a.split_at_mut(4);
            unsafe {
                _mm_storeu_ps(lo.as_mut_ptr(), self.0[0]);
                _mm_storeu_ps(hi.as_mut_ptr(), self.0[1]);
            }
            a
        }
        #[inline(always)]
        fn max(self, o: Self) -> Self {
            Sse2(unsafe { [_mm_max_ps(self.0[0], o.0[0]), _mm_max_ps(self.0[1], o.0[1])] })
        }
        #[inline(always)]
        fn sqrt(self) -> Self {
            Sse2(self.0.map(|r| unsafe { _mm_sqrt_ps(r) }))
        }
        #[inline(always)]
        fn first(count: usize) -> Self {
            unsafe {
                let lane = |l: f32| _mm_setr_ps(l, l + 1.0, l + 2.0, l + 3.0);
                let n = _mm_set1_ps(count.min(8) as f32);
                let one = _mm_set1_ps(1.0);
                Sse2([0.0, 4.0].map(|l| _mm_and_ps(_mm_cmplt_ps(lane(l), n), one)))
            }
        }
        #[inline(always)]
        fn transpose<'a>(row: impl Fn(usize) -> &'a [f32; 4]) -> [Self; 4] {
            // SAFETY: each row holds four floats.
            let row = |l: usize| unsafe { _mm_loadu_ps(row(l).as_ptr()) };
            let half = |base: usize| unsafe {
                let (r0, r1, r2, r3) = (row(base), row(base + 1), row(base + 2), row(base + 3));
                let (t0, t1) = (_mm_unpacklo_ps(r0, r1), _mm_unpacklo_ps(r2, r3));
                let (t2, t3) = (_mm_unpackhi_ps(r0, r1), _mm_unpackhi_ps(r2, r3));
                [
                    _mm_movelh_ps(t0, t1),
                    _mm_movehl_ps(t1, t0),
                    _mm_movelh_ps(t2, t3),
                    _mm_movehl_ps(t3, t2),
                ]
            };
            let (lo, hi) = (half(0), half(4));
            std::array::from_fn(|k| Sse2([lo[k], hi[k]]))
        }
    }
}

/// A per-particle computation written over lanes of any kind.
pub(super) trait LaneMap: Sync {
    /// What it gives per particle.
    type Out: Send + Copy + Default;
    /// Particle `i`'s value, computed with lanes `S`.
    fn particle<S: F32x8>(&self, i: usize) -> Self::Out;
}

/// Particles per parallel task: a fixed size, so that nothing depends on the
/// number of threads.
const BLOCK: usize = 256;

/// Sets `out` to `map`'s value for each of `n` particles, in parallel, with
/// the AVX2 lanes where [`simd_level`] allows (every kind gives bitwise the
/// same values).
pub(super) fn par_map<M: LaneMap>(map: &M, n: usize, out: &mut Vec<M::Out>) {
    // Every value is written below; the memory is only sized here.
    out.resize(n, M::Out::default());
    out.par_chunks_mut(BLOCK)
        .enumerate()
        .for_each(|(b, block)| fill_block(map, b * BLOCK, block));
}

/// Sets `block[k]` to `map`'s value for particle `first + k`, on this
/// thread, with the lanes [`par_map`] picks.
#[inline]
pub(super) fn fill_block<M: LaneMap>(map: &M, first: usize, block: &mut [M::Out]) {
    #[cfg(target_arch = "x86_64")]
    {
        if wide_registers() {
            // SAFETY: checked by `wide_registers`.
            unsafe { fill_avx512vl(map, first, block) };
        } else if simd_level() >= Simd::Avx2 {
            // SAFETY: `simd_level` never exceeds what the CPU supports.
            unsafe { fill_avx2(map, first, block) };
        } else {
            fill::<Sse2, M>(map, first, block);
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    fill::<Scalar, M>(map, first, block);
}

/// A per-particle computation over lanes of any kind that also writes a
/// value per neighbour pair, into the particle's row (laid out as
/// [`NeighbourLists::row`] lays them out).
pub(super) trait LaneRowMap: Sync {
    /// What it gives per particle.
    type Out: Send;
    /// What it writes per pair.
    type Pair: Send;
    /// Particle `i`'s value, computed with lanes `S`; `pairs` is its row.
    fn particle<S: F32x8>(&self, i: usize, pairs: &mut [Self::Pair]) -> Self::Out;
}

/// Sets `out[i]` and row i of `pairs` by `map` for every particle of
/// `lists`, in parallel ([`NeighbourLists::par_map_rows`]), with the best
/// lanes as [`par_map`] picks them, chosen per particle.
///
/// # Panics
/// As [`NeighbourLists::par_map_rows`]: unless `out` holds a value per
/// particle and `pairs` one per pair.
pub(super) fn par_map_rows<M: LaneRowMap>(
    map: &M,
    lists: &NeighbourLists,
    out: &mut [M::Out],
    pairs: &mut [M::Pair],
) {
    #[cfg(target_arch = "x86_64")]
    let (avx2, wide) = (simd_level() >= Simd::Avx2, wide_registers());
    lists.par_map_rows(out, pairs, |i, _, row| {
        #[cfg(target_arch = "x86_64")]
        {
            if wide {
                // SAFETY: checked by `wide_registers`.
                return unsafe { row_avx512vl(map, i, row) };
            }
            if avx2 {
                // SAFETY: `simd_level` never exceeds what the CPU supports.
                return unsafe { row_avx2(map, i, row) };
            }
            map.particle::<Sse2>(i, row)
        }
        #[cfg(not(target_arch = "x86_64"))]
        map.particle::<Scalar>(i, row)
    });
}

/// [`LaneRowMap::particle`] with the AVX2 lanes, compiled with AVX2.
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn row_avx2<M: LaneRowMap>(map: &M, i: usize, row: &mut [M::Pair]) -> M::Out {
    map.particle::<Avx2>(i, row)
}

/// [`LaneRowMap::particle`] with the AVX2 lanes, compiled with AVX-512VL
/// as well (see [`wide_registers`]).
///
/// # Safety
/// The CPU must support AVX2, AVX-512F and AVX-512VL.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,avx512f,avx512vl")]
unsafe fn row_avx512vl<M: LaneRowMap>(map: &M, i: usize, row: &mut [M::Pair]) -> M::Out {
    map.particle::<Avx2>(i, row)
}

/// Whether to compile the AVX2 lanes' passes with AVX-512VL too: the same
/// 8-lane instructions, but with 32 vector registers instead of 16, so the
/// sums of a pass stay in registers instead of spilling to the stack
/// (AVX-512's own 16-lane registers were slower on Zen 4, which splits
/// them in two). The results are bitwise the same: the compiler may encode
/// an operation differently, not change it.
#[cfg(target_arch = "x86_64")]
fn wide_registers() -> bool {
    use std::arch::is_x86_feature_detected as has;
    // AVX-512F implies FMA and F16C to the compiler: a VM could hide them.
    simd_level() >= Simd::Avx512 && has!("avx512vl") && has!("fma") && has!("f16c")
}

/// `block[k]` = particle `first + k`'s value, with lanes `S`.
#[inline(always)]
fn fill<S: F32x8, M: LaneMap>(map: &M, first: usize, block: &mut [M::Out]) {
    for (k, out) in block.iter_mut().enumerate() {
        *out = map.particle::<S>(first + k);
    }
}

/// [`fill`] with the AVX2 lanes, compiled with AVX2.
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn fill_avx2<M: LaneMap>(map: &M, first: usize, block: &mut [M::Out]) {
    fill::<Avx2, M>(map, first, block);
}

/// [`fill`] with the AVX2 lanes, compiled with AVX-512VL as well (see
/// [`wide_registers`]).
///
/// # Safety
/// The CPU must support AVX2, AVX-512F and AVX-512VL.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,avx512f,avx512vl")]
unsafe fn fill_avx512vl<M: LaneMap>(map: &M, first: usize, block: &mut [M::Out]) {
    fill::<Avx2, M>(map, first, block);
}

/// `map`'s values for `n` particles with every kind of lanes this CPU
/// runs, the plain arrays first: what the solvers' tests compare.
#[cfg(test)]
pub(super) fn every_kind<M: LaneMap>(map: &M, n: usize) -> Vec<(&'static str, Vec<M::Out>)> {
    let run = |fill: &dyn Fn(&mut [M::Out])| {
        let mut out = vec![M::Out::default(); n];
        fill(&mut out);
        out
    };
    #[allow(unused_mut)]
    let mut kinds = vec![("plain", run(&|out| fill::<Scalar, M>(map, 0, out)))];
    #[cfg(target_arch = "x86_64")]
    {
        kinds.push(("sse2", run(&|out| fill::<Sse2, M>(map, 0, out))));
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: checked just above.
            kinds.push(("avx2", run(&|out| unsafe { fill_avx2(map, 0, out) })));
        }
        if wide_registers() {
            // SAFETY: checked just above.
            kinds.push((
                "avx2+avx512vl",
                run(&|out| unsafe { fill_avx512vl(map, 0, out) }),
            ));
        }
    }
    kinds
}

/// One kind of lanes' run of a [`LaneRowMap`]: its name, the values per
/// particle and the rows of per-pair values.
#[cfg(test)]
pub(super) type KindRows<M> = (
    &'static str,
    Vec<<M as LaneRowMap>::Out>,
    Vec<<M as LaneRowMap>::Pair>,
);

/// `map`'s values and rows for every particle of `lists` with every kind
/// of lanes this CPU runs, the plain arrays first: what the solvers' tests
/// compare for the passes that write per-pair data.
#[cfg(test)]
pub(super) fn every_kind_rows<M: LaneRowMap>(map: &M, lists: &NeighbourLists) -> Vec<KindRows<M>>
where
    M::Pair: Clone + Default,
{
    type Particle<'a, M> =
        &'a dyn Fn(usize, &mut [<M as LaneRowMap>::Pair]) -> <M as LaneRowMap>::Out;
    let run = |particle: Particle<'_, M>| {
        let mut pairs = vec![M::Pair::default(); lists.pairs()];
        let mut out = Vec::with_capacity(lists.len());
        let mut rest = &mut pairs[..];
        for i in 0..lists.len() {
            let (row, tail) = std::mem::take(&mut rest).split_at_mut(lists.of(i).len());
            out.push(particle(i, row));
            rest = tail;
        }
        (out, pairs)
    };
    let mut kinds = Vec::new();
    let (out, pairs) = run(&|i, row| map.particle::<Scalar>(i, row));
    kinds.push(("plain", out, pairs));
    #[cfg(target_arch = "x86_64")]
    {
        let (out, pairs) = run(&|i, row| map.particle::<Sse2>(i, row));
        kinds.push(("sse2", out, pairs));
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: checked just above.
            let (out, pairs) = run(&|i, row| unsafe { row_avx2(map, i, row) });
            kinds.push(("avx2", out, pairs));
        }
        if wide_registers() {
            // SAFETY: checked just above.
            let (out, pairs) = run(&|i, row| unsafe { row_avx512vl(map, i, row) });
            kinds.push(("avx2+avx512vl", out, pairs));
        }
    }
    kinds
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Both kinds give bitwise the same lanes for each operation, signed
    /// zeros, NaNs and infinities in `max` included.
    #[test]
    fn both_kinds_agree_bit_for_bit() {
        let a = [1.5, -0.0, 0.0, f32::NAN, 3.0, -2.0, f32::INFINITY, 1e-30];
        let b = [0.25, 0.0, -0.0, 1.0, f32::NAN, 7.0, 2.0, 3e-38];
        let rows: Vec<[f32; 4]> = (0..20)
            .map(|i| std::array::from_fn(|k| i as f32 * 0.37 + k as f32))
            .collect();
        let values: Vec<f32> = (0..20).map(|i| i as f32 * 1.1).collect();
        let slots = [3, 19, 0, 7, 7, 12, 5, 1];
        fn run<S: F32x8>(
            a: [f32; 8],
            b: [f32; 8],
            rows: &[[f32; 4]],
            values: &[f32],
            slots: &[u32; 8],
        ) -> Vec<[f32; 8]> {
            let (a, b) = (S::from_array(a), S::from_array(b));
            let mut out = vec![
                (a + b).to_array(),
                (a - b).to_array(),
                (a * b).to_array(),
                (a / b).to_array(),
                a.max(b).to_array(),
                b.max(a).to_array(),
                a.sqrt().to_array(),
                S::gather(values, slots).to_array(),
                S::first(3).to_array(),
                S::first(8).to_array(),
                S::first(1).to_array(),
                [
                    S::splat(2.5).sum(),
                    a.sum(),
                    b.sum(),
                    0.0,
                    0.0,
                    0.0,
                    0.0,
                    0.0,
                ],
            ];
            out.extend(S::gather_rows(rows, slots).map(S::to_array));
            let v: Vec<Vec3> = rows.iter().map(|r| Vec3::new(r[0], r[1], r[2])).collect();
            out.extend(S::load_vec3s(&v[5..]).map(S::to_array));
            out
        }
        // Bits, with every NaN one pattern: a NaN's sign and payload are
        // not results (the compiler folds 0/0 to a different one than the
        // CPU makes).
        let bits = |v: Vec<[f32; 8]>| -> Vec<[u32; 8]> {
            let bits = |x: f32| if x.is_nan() { u32::MAX } else { x.to_bits() };
            v.into_iter().map(|l| l.map(bits)).collect()
        };
        let scalar = run::<Scalar>(a, b, &rows, &values, &slots);
        assert_eq!(scalar[4][0], 1.5);
        assert_eq!(
            scalar[4][1].to_bits(),
            0.0f32.to_bits(),
            "max(-0, +0) is the second"
        );
        assert!(scalar[4][4].is_nan(), "max(3, NaN) is the second");
        assert_eq!(scalar[4][3], 1.0, "max(NaN, 1) is the second");
        assert_eq!(scalar[8], [1.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
        assert_eq!(scalar[9], [1.0; 8]);
        assert_eq!(scalar[12][1], 19.0 * 0.37, "gathered row 19, first entry");
        assert_eq!(scalar[16][0], 5.0 * 0.37, "vector 5's x in lane 0");
        assert_eq!(scalar[18][7], 12.0 * 0.37 + 2.0, "vector 12's z in lane 7");
        assert_eq!(
            scalar[15][0],
            3.0 * 0.37 + 3.0,
            "gathered row 3, last entry"
        );
        #[cfg(target_arch = "x86_64")]
        assert_eq!(
            bits(run::<Sse2>(a, b, &rows, &values, &slots)),
            bits(scalar.clone())
        );
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            #[target_feature(enable = "avx2")]
            fn run_avx2(
                a: [f32; 8],
                b: [f32; 8],
                rows: &[[f32; 4]],
                values: &[f32],
                slots: &[u32; 8],
            ) -> Vec<[f32; 8]> {
                run::<Avx2>(a, b, rows, values, slots)
            }
            // SAFETY: checked just above.
            let avx = unsafe { run_avx2(a, b, &rows, &values, &slots) };
            assert_eq!(bits(avx), bits(scalar));
        }
    }

    /// `par_map` fills every particle's value, whatever the block split.
    #[test]
    fn par_map_fills_every_particle() {
        struct Square;
        impl LaneMap for Square {
            type Out = f32;
            fn particle<S: F32x8>(&self, i: usize) -> f32 {
                (S::splat(i as f32) * S::splat(i as f32)).to_array()[3]
            }
        }
        let mut out = vec![7.0; 3];
        par_map(&Square, 1000, &mut out);
        assert_eq!(out.len(), 1000);
        assert!(out.iter().enumerate().all(|(i, &v)| v == (i * i) as f32));
    }
}
